//! The ledger of align (`OUT/align/align.json`): per session and accelerometer, the
//! observations used and excluded by reason, and the settings used; and the values of the
//! observation table's `excluded` and `sigma_dz_source` columns.

use crate::contract::custody::{Custody, Folders, check_dataset};
use crate::contract::manifest::{AlignConfig, Dataset};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Exclusion reasons, as written in `observations.parquet` and `align.json`.
pub mod reason {
    /// A sample in the window is flagged not connected.
    pub const NOT_CONNECTED: &str = "not_connected";
    /// A sample in the window is over range.
    pub const SATURATED: &str = "saturated";
    /// The window holds fewer than `min_window_fill` of the expected samples.
    pub const WINDOW_UNDERFILLED: &str = "window_underfilled";
    /// No temperature of this channel in the session.
    pub const NO_TEMPERATURE: &str = "no_temperature";
    /// The nearest temperature sample is further than `max_temperature_gap_s`.
    pub const TEMPERATURE_GAP: &str = "temperature_gap";
    /// The counts in the window trend (|t| > [`super::DRIFT_T_LIMIT`]): the platform was not still.
    pub const WINDOW_DRIFT: &str = "window_drift";
}

/// A window whose linear trend has |t| above this is flagged as drifting. For white noise the
/// chance of that is below 1e-6 per window, so a flag means the platform moved.
pub const DRIFT_T_LIMIT: f64 = 5.0;

/// File name of the ledger.
pub const LEDGER_FILE: &str = "align.json";
/// Format tag of the ledger.
pub const LEDGER_FORMAT: &str = "gravcal-align/1";

/// Where a station's sigma_Dz comes from, as written in `sigma_dz_source`.
pub mod sigma_source {
    /// The sample sd of the station's readings (eq. 4).
    pub const STATION_SD: &str = "station_sd";
    /// The manifest's `theodolite_sigma_arcsec` (no station of the session has 2 readings,
    /// or, with eq. 4, this one has fewer).
    pub const MANIFEST: &str = "manifest";
    /// The station's variance moderated toward the session's (docs/model.md 6.1; the default).
    pub const MODERATED: &str = "moderated";
    /// The floor: the quantisation of the readings as logged, step / sqrt(12), because the
    /// station's sd was smaller (readings logged coarsely can all be equal).
    pub const RESOLUTION: &str = "resolution";
}

/// One point of an Allan deviation curve, in counts.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AllanRow {
    /// Averaging time, s.
    pub tau_s: f64,
    /// Overlapping Allan deviation, counts (a multi-position session's: its reading unit).
    pub adev: f64,
    /// 68.3 % confidence interval.
    pub lower: f64,
    /// 68.3 % confidence interval.
    pub upper: f64,
    /// Equivalent degrees of freedom.
    pub edf: f64,
}

/// An accelerometer's ADC noise, from the overlapping Allan deviation of its counts pooled
/// over the still intervals (the platform at rest at a station, from the first reading's
/// window to the last's), and the three terms fitted to it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AdcNoise {
    /// Accelerometer id.
    pub accelerometer: String,
    /// Still intervals used (every sample valid).
    pub still_intervals: usize,
    /// Samples in them.
    pub samples: usize,
    /// The Allan deviation, counts.
    pub allan: Vec<AllanRow>,
    /// White-noise density N, counts / sqrt(Hz).
    pub white_density_counts_per_sqrt_hz: f64,
    /// Bias instability B, counts.
    pub bias_instability_counts: f64,
    /// Random walk K, counts * sqrt(Hz).
    pub random_walk_counts_sqrt_hz: f64,
    /// Degrees of freedom of B^2 as the Allan curve determines it (absent: B not kept, or
    /// a ledger written before it was recorded, when B is taken as known).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_instability_dof: Option<f64>,
    /// Degrees of freedom of K^2, alike.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub random_walk_dof: Option<f64>,
}

/// Counts for one (session, accelerometer).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Counts {
    /// Session id.
    pub session: String,
    /// Accelerometer id.
    pub accelerometer: String,
    /// Theodolite readings.
    pub readings: u64,
    /// Observations usable.
    pub used: u64,
    /// Excluded, by reason.
    pub excluded: BTreeMap<String, u64>,
    /// The white noise sd of the accelerometer's temperature log over the session, degC:
    /// the manifest's `instrument.thermometer_sd_c` when given, else estimated from the log's
    /// second differences (docs/model.md 6.5); none without a log of at least 22
    /// temperatures.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermometer_sd_c: Option<f64>,
}

/// An accelerometer that gave no observations in a session.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Disconnected {
    /// Session id.
    pub session: String,
    /// Accelerometer id.
    pub accelerometer: String,
    /// Channel 1..3.
    pub channel: u8,
    /// Why.
    pub reason: String,
}

/// `align.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AlignReport {
    /// [`LEDGER_FORMAT`].
    pub format: String,
    /// Dataset name.
    pub dataset: String,
    /// Software and version.
    pub software: String,
    /// The settings used.
    pub config: AlignConfig,
    /// Gravity at the proof masses, mGal.
    pub gravity_mgal: f64,
    /// Per (session, accelerometer).
    pub counts: Vec<Counts>,
    /// Accelerometers without observations in a session.
    pub disconnected: Vec<Disconnected>,
    /// Rows in observations.parquet.
    pub observations: u64,
    /// Every file align read (the manifest, ingest's ledger and tables) and wrote.
    pub custody: Custody,
    /// The ADC noise of each accelerometer, from the Allan deviation of its counts over the
    /// still intervals (docs/model.md 6.2).
    #[serde(default)]
    pub noise: Vec<AdcNoise>,
    /// Whether each observation's gravity includes the body tide (the site's location is
    /// given and `earth_tide` is not false).
    #[serde(default)]
    pub earth_tide_applied: bool,
    /// Multi-position sessions: their static intervals, found or listed (docs/formats.md 8.4).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub multi_position: Vec<MultiPosition>,
    /// Survey sessions: no theodolite, so nothing to align; left to `apply`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub surveys: Vec<String>,
    /// Sessions that gave no usable observation (and were not declared `expect_empty`):
    /// the run fails, and downstream stages refuse this ledger.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub errors: Vec<String>,
}

/// One multi-position session's static intervals.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MultiPosition {
    /// Session id.
    pub session: String,
    /// How the intervals were had: `listed` (the manifest's static_s) or `detected`.
    pub method: String,
    /// Detection: the quiet start the noise was measured on, s from the first sample.
    pub quiet_start_s: Option<f64>,
    /// Detection: each axis's sample sd over the quiet start, in the reading unit.
    pub quiet_sd: Option<[f64; 3]>,
    /// Detection: each axis's noise sd inside the still stretches (windows pooled), in the
    /// reading unit: what the quiet start's is checked against.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub still_sd: Option<[f64; 3]>,
    /// What the detector had to say: a quiet start at odds with the still stretches' noise
    /// (then their noise is the reference), naming both figures.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Detection: the moving-variance window, s.
    pub window_s: f64,
    /// Detection: the threshold of the window statistic (sum over axes of the window's
    /// variance over the quiet start's), its 99.9 % chi-square quantile for a still block.
    pub threshold: Option<f64>,
    /// Intervals found (or listed).
    pub found: u64,
    /// Intervals used as positions.
    pub used: u64,
    /// Intervals not used, by reason (`too_short`, `saturated`, `no_samples`: an axis with
    /// fewer than three values).
    pub rejected: BTreeMap<String, u64>,
    /// Each axis's noise over the static intervals used (docs/model.md 6.2), when an interval
    /// had enough samples: a bias instability or random walk found here adds its Allan
    /// variance at a position's duration to the position's sigma.
    #[serde(default)]
    pub noise: Vec<StaticNoise>,
    /// The white noise sd of the temperature log's channels 1..3 over the session, degC:
    /// the manifest's `instrument.thermometer_sd_c` when given, else estimated from its
    /// second differences (docs/model.md 6.5); none for a channel with fewer than 22
    /// temperatures.
    #[serde(default)]
    pub thermometer_sd_c: [Option<f64>; 3],
    /// The positions: the static intervals used.
    pub positions: Vec<StaticPosition>,
}

/// One axis's noise over a multi-position session's static intervals: the overlapping
/// Allan deviation of each interval's readings less their straight line, pooled, and the
/// three terms fitted to it, in the session's reading unit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StaticNoise {
    /// Channel 1..3 (the triad's x, y, z).
    pub channel: u8,
    /// The reading unit of the deviation and the terms.
    pub unit: String,
    /// Intervals used (every sample valid, at least 64).
    pub intervals: usize,
    /// Samples in them.
    pub samples: usize,
    /// The Allan deviation, in `unit`.
    pub allan: Vec<AllanRow>,
    /// White-noise density N, unit / sqrt(Hz).
    pub white_density_per_sqrt_hz: f64,
    /// Bias instability B, unit (0 when not significant).
    pub bias_instability: f64,
    /// Random walk K, unit * sqrt(Hz) (0 when not significant).
    pub random_walk_sqrt_hz: f64,
    /// The samples' lag-one autocorrelation where significantly above 0 (a logger holding
    /// its last value): the positions' white sigmas are widened by sqrt((1 + rho) /
    /// (1 - rho)) and the Allan curve starts where rho^lag is below 5 % (docs/triad.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lag_one_correlation: Option<f64>,
}

/// One static position: the three mean readings over its interval.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StaticPosition {
    /// First sample's GPS time, ns.
    pub start_gps_ns: i64,
    /// Last sample's GPS time, ns.
    pub end_gps_ns: i64,
    /// Samples averaged.
    pub samples: u64,
    /// Mean reading of channels 1..3.
    pub mean: [f64; 3],
    /// Sd of each mean: the white part (see `sigma_white`) and the Allan variance at the
    /// interval's duration of any bias instability or random walk the session's noise shows.
    pub sigma: [f64; 3],
    /// The white part: the samples' scatter about a straight line in time over sqrt(n) (a
    /// drift while still is not noise).
    #[serde(default)]
    pub sigma_white: Option<[f64; 3]>,
    /// Gravity during the position, mGal (with the body tide when the site is located).
    pub gravity_mgal: f64,
    /// Temperature of channels 1..3 over the interval, degC: the mean over its samples of the
    /// temperature interpolated as for a window; absent when the session logged none or the
    /// log has a gap there.
    #[serde(default)]
    pub temperature_c: Option<[f64; 3]>,
    /// The sd of each of those temperatures from the thermometer's noise (the session's
    /// `thermometer_sd_c` times the root of the sum of the squared weights the mean gives
    /// the log's samples); absent when the temperature is, or the noise could not be
    /// estimated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_sd_c: Option<[f64; 3]>,
}

impl AlignReport {
    /// Reads `dir/align.json` (`dir` being OUT/align).
    pub fn load(dir: &Path) -> Result<Self> {
        crate::read_json(&dir.join(LEDGER_FILE))
    }

    /// Reads OUT/align/align.json and checks it is this dataset's and still true: every file
    /// it records (manifest, ingest's ledger and tables, observations.parquet) unchanged.
    pub fn load_verified(ds: &Dataset, out: &Path) -> Result<Self> {
        let dir = out.join(STAGE_DIR);
        let report = AlignReport::load(&dir)?;
        check_dataset(&dir.join(LEDGER_FILE), &report.dataset, &ds.manifest.name)?;
        if !report.errors.is_empty() {
            return Err(Error::Unusable {
                path: dir.join(LEDGER_FILE),
                errors: report.errors,
            });
        }
        let folders = Folders {
            dataset: &ds.dir,
            out,
        };
        folders.verify(&report.custody, STAGE_DIR, STAGE_DIR)?;
        Ok(report)
    }
}

/// The stage's folder in OUT.
pub const STAGE_DIR: &str = "align";
