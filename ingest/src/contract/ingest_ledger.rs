//! The ledger of ingest (`OUT/ingest/ingest.json`): per input file, what was read, accepted and rejected
//! by reason, so that nothing is lost silently. Accepted plus rejected equals read; for a
//! binary log the bytes add up too.

use crate::contract::custody;
use crate::contract::manifest::Dataset;
use crate::error::{Error, Result};
use crate::read_json;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Rejection reasons, as they appear in `ingest.json`.
pub mod reason {
    /// A frame whose CRC does not match.
    pub const BAD_CRC: &str = "bad_crc";
    /// A frame of a type other than acceleration or temperature.
    pub const UNKNOWN_TYPE: &str = "unknown_type";
    /// A frame whose length byte is not 19.
    pub const WRONG_LENGTH: &str = "wrong_length";
    /// A frame with reserved status bits (3, 7) set.
    pub const RESERVED_STATUS_BITS: &str = "reserved_status_bits";
    /// A frame whose time of week is not below one week.
    pub const BAD_TIME_OF_WEEK: &str = "bad_time_of_week";
    /// A count outside the 24-bit range on a connected channel.
    pub const COUNT_OUT_OF_RANGE: &str = "count_out_of_range";
    /// The same type and time as the frame or line accepted before it.
    pub const DUPLICATE: &str = "duplicate";
    /// A time earlier than the frame or line accepted before it.
    pub const TIME_BACKWARDS: &str = "time_backwards";
    /// The last frame of the file, cut off.
    pub const TRUNCATED_TAIL: &str = "truncated_tail";
    /// A text line that does not parse (only with skip-bad-lines; otherwise it is an error).
    pub const MALFORMED: &str = "malformed";
    /// A record timed outside its session's range (`ResolvedSession::gps_range_ns`: from 00:00
    /// UTC of its date for `days` days).
    pub const OUTSIDE_SESSION: &str = "outside_session";
    /// A record whose time jumps ahead of its neighbours and back ([`crate::base::timegate`]).
    pub const TIME_OUTLIER: &str = "time_outlier";
    /// A temperature outside [-100, 200] degC on a connected channel.
    pub const TEMPERATURE_OUT_OF_RANGE: &str = "temperature_out_of_range";
    /// A lab stream's reading outside what the instrument can produce in its declared
    /// `reading_unit` ([`crate::readers::labstream::reading_limits`]).
    pub const READING_OUT_OF_RANGE: &str = "reading_out_of_range";
}

/// How the bytes of a binary log were spent: they add up to the file size.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ByteLedger {
    /// Bytes of accepted frames.
    pub in_accepted_frames: u64,
    /// Bytes of well-formed frames rejected after parsing (duplicate, time going backwards, ...).
    pub in_rejected_frames: u64,
    /// Bytes passed over while looking for the next sync word: damaged frames and junk.
    pub skipped_resynchronising: u64,
    /// Bytes of a cut-off last frame.
    pub truncated_tail: u64,
}

impl ByteLedger {
    /// Sum of all parts.
    pub fn total(&self) -> u64 {
        self.in_accepted_frames
            + self.in_rejected_frames
            + self.skipped_resynchronising
            + self.truncated_tail
    }
}

/// One rejection, where it happened.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rejection {
    /// `byte N` (offset of the frame or of the skipped stretch) or `line N`.
    pub at: String,
    /// A reason from [`reason`].
    pub reason: String,
    /// Details, e.g. the field and value.
    pub detail: String,
}

/// At most this many rejections are listed per file (all are counted).
pub const MAX_LISTED: usize = 100;

/// What one input file gave.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct FileLedger {
    /// Path relative to the dataset folder.
    pub path: String,
    /// Session id.
    pub session: String,
    /// `acquisition`, `adc_csv`, `temperature_csv` or `theodolite`.
    pub role: String,
    /// SHA-256 of the file's bytes, hex.
    pub sha256: String,
    /// File size.
    pub bytes: u64,
    /// `frames` or `lines`.
    pub unit: String,
    /// Frames found (sync word seen), or data lines (not comment, blank or header).
    pub read: u64,
    /// Frames or lines accepted.
    pub accepted: u64,
    /// Rejected, by reason.
    pub rejected: BTreeMap<String, u64>,
    /// Accepted, by kind (`acceleration`, `temperature`, `reading`).
    pub accepted_by_kind: BTreeMap<String, u64>,
    /// Text logs: comment and blank lines, and the header line.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub comment_blank_or_header_lines: Option<u64>,
    /// Binary logs: where every byte went.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub byte_ledger: Option<ByteLedger>,
    /// Lab streams ("seconds" layout): what the reader found in the file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lab_stream: Option<LabStreamReport>,
    /// Values stored as null in accepted records, by channel and reason (e.g. `ch2 not connected`).
    pub null_values: BTreeMap<String, u64>,
    /// The first [`MAX_LISTED`] rejections.
    pub rejections: Vec<Rejection>,
}

/// What a lab stream's reader found (docs/formats.md 8.3): its layout and its time stamps.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LabStreamReport {
    /// Fields were separated by commas (else by white space).
    pub comma_separated: bool,
    /// A header line came before the data.
    pub header: bool,
    /// Values written in scientific notation.
    pub scientific_notation_values: u64,
    /// Samples whose time stamp equals the one before: the stamps are coarser than the
    /// sample interval. Their times are spread evenly up to the next stamp.
    pub samples_sharing_a_stamp: u64,
    /// The most common step between distinct stamps, ns.
    pub stamp_step_ns: Option<i64>,
    /// The median interval between samples after spreading, ns (the measured rate's).
    pub median_interval_ns: Option<i64>,
}

impl FileLedger {
    /// `N lines read, M accepted[, rejected: k reason, ...]`: the file's counts in a line.
    pub fn counts_line(&self) -> String {
        let rejected: Vec<String> = self
            .rejected
            .iter()
            .map(|(r, n)| format!("{n} {r}"))
            .collect();
        format!(
            "{} {} read, {} accepted{}",
            self.read,
            self.unit,
            self.accepted,
            if rejected.is_empty() {
                String::new()
            } else {
                format!(", rejected: {}", rejected.join(", "))
            }
        )
    }

    /// Counts a rejection and lists it if there is room.
    pub fn reject(&mut self, at: String, reason: &str, detail: String) {
        *self.rejected.entry(reason.to_owned()).or_default() += 1;
        self.read += 1;
        if self.rejections.len() < MAX_LISTED {
            self.rejections.push(Rejection {
                at,
                reason: reason.to_owned(),
                detail,
            });
        }
    }

    /// Counts `n` accepted records of `kind` (readers count locally and call this once).
    pub fn accept(&mut self, kind: &str, n: u64) {
        if n > 0 {
            self.read += n;
            self.accepted += n;
            *self.accepted_by_kind.entry(kind.to_owned()).or_default() += n;
        }
    }

    /// Total rejected.
    pub fn rejected_total(&self) -> u64 {
        self.rejected.values().sum()
    }
}

/// File name of the ledger.
pub const LEDGER_FILE: &str = "ingest.json";
/// The stage's folder in OUT.
pub const STAGE_DIR: &str = "ingest";
/// The manifest's file name in a dataset folder.
pub const MANIFEST_FILE: &str = "dataset.toml";
/// Format tag of the ledger.
pub const LEDGER_FORMAT: &str = "gravcal-ingest/1";

/// What a session gave.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SessionSummary {
    /// Session id.
    pub id: String,
    /// Tilt-table or survey.
    #[serde(default)]
    pub kind: crate::contract::manifest::SessionKind,
    /// Acceleration samples accepted.
    pub acceleration_samples: u64,
    /// Temperature samples accepted.
    pub temperature_samples: u64,
    /// Theodolite readings accepted.
    pub readings: u64,
    /// GPS time of the first accepted acceleration sample, ns.
    pub first_gps_ns: Option<i64>,
    /// GPS time of the last accepted acceleration sample, ns.
    pub last_gps_ns: Option<i64>,
    /// Channels (1..3) flagged not connected in every accepted acceleration sample.
    pub channels_never_connected: Vec<u8>,
    /// Acceleration sample rate measured from the accepted samples (the median interval), Hz.
    pub measured_sample_rate_hz: Option<f64>,
}

/// `ingest.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct IngestReport {
    /// [`LEDGER_FORMAT`].
    pub format: String,
    /// Dataset name.
    pub dataset: String,
    /// Software and version.
    pub software: String,
    /// Per input file, in manifest order.
    pub files: Vec<FileLedger>,
    /// Per session.
    pub sessions: Vec<SessionSummary>,
    /// Rows written per table file.
    pub tables: BTreeMap<String, u64>,
    /// Every file ingest read (the manifest and the raw logs) and wrote, with its SHA-256.
    pub custody: custody::Custody,
    /// What makes the run fail although every table was written (a session that gave no
    /// data, a sample rate off the declared one); downstream stages refuse a ledger with any.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub errors: Vec<String>,
}

impl IngestReport {
    /// Reads OUT/ingest/ingest.json and checks it is this dataset's and still true: written
    /// for `ds`, without errors, and every file it records (manifest, raw logs, tables)
    /// unchanged on disk. What every downstream stage calls before it reads ingest's tables.
    pub fn load_verified(ds: &Dataset, out: &Path) -> Result<Self> {
        let dir = out.join("ingest");
        let report = IngestReport::load(&dir)?;
        let path = dir.join(LEDGER_FILE);
        custody::check_dataset(&path, &report.dataset, &ds.manifest.name)?;
        if !report.errors.is_empty() {
            return Err(Error::Unusable {
                path,
                errors: report.errors,
            });
        }
        let folders = custody::Folders {
            dataset: &ds.dir,
            out,
        };
        folders.verify(&report.custody, "ingest", "ingest")?;
        Ok(report)
    }

    /// Reads `dir/ingest.json` (`dir` being OUT/ingest).
    pub fn load(dir: &Path) -> Result<Self> {
        let path = dir.join(LEDGER_FILE);
        let invalid = |m: String| {
            Error::io(
                &path,
                std::io::Error::new(std::io::ErrorKind::InvalidData, m),
            )
        };
        let report: IngestReport = read_json(&path)?;
        if report.format != LEDGER_FORMAT {
            return Err(invalid(format!(
                "format `{}`, expected `{LEDGER_FORMAT}`",
                report.format
            )));
        }
        Ok(report)
    }
}
