//! The contract between the stages, in one home: everything one stage writes and another
//! reads. Every stage imports it by this name (`ingest::contract::...`); no column name,
//! ledger field or status bit is written as a literal anywhere else.
//!
//! | module | what |
//! |---|---|
//! | [`manifest`] | `dataset.toml`: the dataset every stage reads (docs/formats.md section 2) |
//! | [`status`] | the status bits of a sample, as logged and as stored |
//! | [`survey`] | `dataset.toml`'s moving-gravimetry keys: trajectories, `[survey]` (docs/formats.md 10) |
//! | [`tables`] | the Parquet tables: file names, columns, types, units |
//! | [`ingest_ledger`] | `ingest.json`: per input file, what was read, accepted and rejected |
//! | [`align_ledger`] | `align.json`: observations used and excluded, by reason |
//! | [`calibration`] | `calibration.json`: the results (docs/formats.md section 6) |
//! | [`apply_ledger`] | `apply.json`: the calibration applied to a survey, rows and flags |
//! | [`gravity_ledger`] | `gravity.json`: the survey reduced to gravity, epochs used and dropped |
//! | [`normal`] | normal gravity of GRS80 and WGS84, which the stages hold values to |
//! | [`precision`] | a value with its sigma, printed to the sigma's precision (GUM 7.2.6) |
//! | [`custody`] | the SHA-256 of every file each stage read and wrote, and its check |
//!
//! Outputs live under `OUT/<stage>/`, the stage folders named by each ledger module's
//! `STAGE_DIR`.

pub mod align_ledger;
pub mod apply_ledger;
pub mod calibration;
pub mod custody;
pub mod gravity_ledger;
pub mod ingest_ledger;
pub mod manifest;
pub mod normal;
pub mod precision;
pub mod status;
pub mod survey;
pub mod tables;
