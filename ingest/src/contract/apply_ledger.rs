//! `OUT/apply/apply.json` (docs/formats.md 8.5): which calibration was applied, from which file
//! (its SHA-256), with which model, and what became of every sample: rows read and written,
//! and per accelerometer the samples flagged, by reason.

use crate::contract::custody::Custody;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The stage's folder in OUT.
pub const STAGE_DIR: &str = "apply";
/// The ledger's file name.
pub const LEDGER_FILE: &str = "apply.json";
/// The ledger's format tag.
pub const LEDGER_FORMAT: &str = "gravcal-apply/1";

/// The calibration file and the part of it applied.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CalibrationUsed {
    /// The calibration.json as given on the command line.
    pub path: String,
    /// Its SHA-256, hex.
    pub sha256: String,
    /// The dataset it calibrated.
    pub dataset: String,
    /// The model applied.
    pub model: String,
    /// The model's fits: per session (the one named) or `all`.
    pub session: String,
}

/// One accelerometer of the survey and what it was calibrated with.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AppliedAccelerometer {
    /// Id (as in both manifests).
    pub id: String,
    /// Channel in the survey's acquisition record.
    pub channel: u8,
    /// Serial, as in both manifests.
    pub serial: Option<String>,
    /// Why the model gives no calibration for it (its columns are then null, flagged
    /// `not_calibrated`), or None.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_calibrated: Option<String>,
    /// Counts range the calibration saw.
    pub counts_range: Option<[f64; 2]>,
    /// Temperature range it saw, degC.
    pub temperature_range_c: Option<[f64; 2]>,
    /// Samples with a value.
    pub with_value: u64,
    /// Samples flagged, by flag name (a sample may carry several flags).
    pub flagged: BTreeMap<String, u64>,
}

/// `apply.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ApplyReport {
    /// [`LEDGER_FORMAT`].
    pub format: String,
    /// The survey dataset's name.
    pub dataset: String,
    /// Software and version.
    pub software: String,
    /// The calibration applied.
    pub calibration: CalibrationUsed,
    /// What the acceleration is: the calibration function's value, its sign convention.
    pub quantity: String,
    /// Rows of ingest's acceleration table read.
    pub rows_read: u64,
    /// Rows of acceleration.parquet written (one per row read).
    pub rows_written: u64,
    /// Per accelerometer.
    pub accelerometers: Vec<AppliedAccelerometer>,
    /// Largest gap to a temperature sample used for interpolation, s (align's setting).
    pub max_temperature_gap_s: f64,
    /// Every file apply read (the manifest, ingest's ledger and tables, the calibration)
    /// and wrote.
    pub custody: Custody,
}

impl ApplyReport {
    /// Reads `dir/apply.json` (`dir` being OUT/apply).
    pub fn load(dir: &std::path::Path) -> crate::Result<Self> {
        crate::read_json(&dir.join(LEDGER_FILE))
    }
}
