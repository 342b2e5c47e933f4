//! The readers of the raw logs, each through the time gate with its ledger: the binary
//! acquisition log ([`gcb`]), the CSV pair (`csvlog`), lab streams ([`labstream`]), the
//! theodolite log ([`theodolite`]), platform meters' files ([`dgs`], [`meter_serial`]),
//! NMEA 0183 navigation ([`nmea`]), and the chunked line reader they share (`lines`).

pub(crate) mod csvlog;
pub mod dgs;
pub mod gcb;
pub mod labstream;
pub(crate) mod lines;
pub mod meter_serial;
pub mod nmea;
pub mod theodolite;
