//! `OUT/gravity/gravity.json` (docs/formats.md 10.3): what the gravity stage read (each
//! input's SHA-256), the calibration and model it used, the filter and the resolution it
//! gives, per session the stretches of track with the ties and drift fitted on each, the
//! crossover differences where the track crosses itself, and every epoch of the trajectories accounted for: used, or dropped by reason.

use crate::contract::apply_ledger::CalibrationUsed;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The stage's folder in OUT.
pub const STAGE_DIR: &str = "gravity";
/// The ledger's file name.
pub const LEDGER_FILE: &str = "gravity.json";
/// The ledger's format tag.
pub const LEDGER_FORMAT: &str = "gravcal-gravity/6";

/// The error models the sigmas were propagated with.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ErrorModelsUsed {
    /// The attitude's (used only where a session has an attitude).
    pub attitude: crate::contract::survey::ErrorModel,
    /// The positions'.
    pub positions: crate::contract::survey::ErrorModel,
}

/// Why an epoch of a trajectory was not used.
pub mod dropped {
    /// No calibrated sample (or under half the expected number) within the epoch's interval.
    pub const NO_SPECIFIC_FORCE: &str = "no_specific_force";
    /// The epoch's samples carry no value (saturated, not connected, no temperature).
    pub const NO_CALIBRATED_VALUE: &str = "no_calibrated_value";
    /// A stretch between gaps too short for the filter.
    pub const STRETCH_TOO_SHORT: &str = "stretch_too_short";
    /// Its time repeats or goes back from the epoch before.
    pub const NOT_INCREASING: &str = "time_not_increasing";
    /// Its time jumps away from its neighbours' (the time gate of every log: a jump ahead
    /// that the epochs after it do not follow).
    pub const TIME_OUTLIER: &str = "time_outlier";
    /// Its line breaks the format, set aside under `--skip-bad-lines` (listed in the
    /// session's `bad_lines`).
    pub const BAD_LINE: &str = "bad_line";
    /// Its time lies outside the session's days (the time gate of every log).
    pub const OUTSIDE_SESSION: &str = "outside_session";
    /// The session gives an attitude, and none can be interpolated at the epoch (outside
    /// the attitude file's span, or in a gap of it).
    pub const NO_ATTITUDE: &str = "no_attitude";
    /// Its position failed the outlier test against its neighbours' prediction as the
    /// third or later of a run (one or two in a row are replaced by the prediction and
    /// flagged `position_outlier` instead).
    pub const POSITION_OUTLIER: &str = "position_outlier";
    /// An antenna array's epoch with fewer than three usable antennas not in a line (after
    /// those whose baselines' lengths were off were set aside), or three whose baselines
    /// disagree (which of them is off cannot be told).
    pub const TOO_FEW_ANTENNAS: &str = "too_few_antennas";
}

/// An antenna array's session: what its antennas gave (docs/formats.md 10.2.1).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct AntennasUsed {
    /// The antennas, in the manifest's order (bit k of attitude.parquet's masks).
    pub ids: Vec<String>,
    /// Each antenna's epochs after its own time gate.
    pub epochs_read: Vec<u64>,
    /// Each antenna's epochs its time gate dropped, by ingest's reason, and its lines set
    /// aside (`bad_line`), which cost that antenna the epoch, not the epoch (absent when
    /// none).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub dropped: BTreeMap<String, BTreeMap<String, u64>>,
    /// Epochs the array gave an attitude and a position at.
    pub epochs_solved: u64,
    /// Per antenna, the epochs it was set aside at, its baselines' lengths off by more
    /// than `[survey] baseline_length_sigmas` (`baseline_length`).
    pub set_aside: BTreeMap<String, u64>,
    /// The solved epochs' median sds of heading, pitch and roll, deg (None for an angle
    /// the array does not give).
    pub median_sd_hpr_deg: [Option<f64>; 3],
    /// The angles the array does not give, with why (two antennas: roll).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub not_given: BTreeMap<String, String>,
    /// Their median sds of the accelerometers' position north, east, down, m.
    pub median_sd_position_m: [f64; 3],
    /// The antennas whose positions were estimated (`position_m = "estimate"`), by id
    /// (absent when none was).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub estimated: BTreeMap<String, EstimatedPosition>,
}

/// An antenna's position on the vehicle estimated from the data (docs/formats.md 10.2.1).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EstimatedPosition {
    /// x, y, z in the vehicle frame, m, from the accelerometers' origin.
    pub position_m: [f64; 3],
    /// Their sds, m: the weighted mean's, scaled by sigma0 where that is above 1.
    pub sd_m: [f64; 3],
    /// Epochs it rests on.
    pub epochs: u64,
    /// Epochs screened out (further than `[survey] baseline_length_sigmas` from the mean).
    pub screened: u64,
    /// sqrt(chi-square / (3 n - 3)) of the epochs kept about the mean.
    pub sigma0: f64,
}

/// A file read, with its hash.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Input {
    /// What it is (`trajectory of <session>`, `calibrated samples`).
    pub role: String,
    /// Its path.
    pub path: String,
    /// SHA-256, hex.
    pub sha256: String,
}

/// The zero-phase low-pass filter and what it resolves.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FilterUsed {
    /// The filter's name (`[survey] filter`).
    #[serde(default)]
    pub name: crate::contract::survey::FilterKind,
    /// What it is, e.g. `Butterworth, order 4 each way (zero phase, forward and backward)`.
    pub kind: String,
    /// Cut-off period (amplitude response 0.5), s.
    pub filter_s: f64,
    /// Median speed over the epochs used, m/s.
    pub median_speed_m_s: f64,
    /// Half the wavelength at the cut-off at the median speed, m: the spatial resolution.
    pub resolution_m: f64,
}

/// The drift fitted to a stretch's ties and removed.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DriftFitted {
    /// The misfit (measured minus known) at the first tie, mGal.
    pub offset_mgal: f64,
    /// Its sigma.
    pub sigma_offset_mgal: f64,
    /// Rate, mGal/h (0 with one tie).
    pub rate_mgal_per_h: f64,
    /// Its sigma, none with one tie.
    pub sigma_rate_mgal_per_h: Option<f64>,
    /// Ties used.
    pub ties: usize,
}

/// A stretch of track between gaps.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StretchSummary {
    /// First and last epoch, UTC ISO 8601.
    pub first: String,
    /// Last epoch.
    pub last: String,
    /// Epochs.
    pub epochs: u64,
    /// The drift removed, none when no tie lies inside it (the level is then the
    /// calibration's, its sigma counted in full).
    pub drift: Option<DriftFitted>,
}

/// One survey session reduced.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SessionGravity {
    /// Session id.
    pub id: String,
    /// Epochs in the trajectory file.
    pub epochs_read: u64,
    /// Epochs written.
    pub epochs_used: u64,
    /// Epochs not used, by reason ([`dropped`]).
    pub dropped: BTreeMap<String, u64>,
    /// Epochs written with a flag, by flag name (an epoch may carry several).
    pub flagged: BTreeMap<String, u64>,
    /// Gaps that cut the track (intervals over 1.5 times the median).
    pub gaps: u64,
    /// Lines of the trajectory and attitude files set aside under `--skip-bad-lines`, as
    /// `path:line: field: message` (the first [`crate::contract::ingest_ledger::MAX_LISTED`] of
    /// each file; a trajectory's are also counted in `dropped` as `bad_line`).
    #[serde(default)]
    pub bad_lines: Vec<String>,
    /// Samples of the attitude file the time gate dropped, by ingest's reason
    /// (`duplicate`, `time_backwards`, `time_outlier`, `outside_session`; absent when none).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub attitude_dropped: BTreeMap<String, u64>,
    /// The positions' white noise north, east, up, m, from their third differences (the
    /// median over blocks of 1024): an epoch's sd is the larger of the trajectory's (none
    /// counting as 0) and this.
    #[serde(default)]
    pub position_noise_m: [f64; 3],
    /// The median of the trajectory's own sds north, east, up, m (none where it gives
    /// none), to be read beside `position_noise_m`.
    #[serde(default)]
    pub position_sd_given_m: Option<[f64; 3]>,
    /// The white noise of one sample of f_D the sigmas carry, mGal.
    #[serde(default)]
    pub sample_noise_mgal: f64,
    /// Where [`SessionGravity::sample_noise_mgal`] comes from: the record's spectral floor,
    /// its third differences (a record shorter than a segment), or `[survey]
    /// sample_noise_mgal` (with the record's own floor beside it, or why it has none).
    #[serde(default)]
    pub sample_noise_from: String,
    /// A platform meter's cross-coupling correction, when `[survey] cross_coupling` asks
    /// for one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cross_coupling: Option<CouplingUsed>,
    /// A platform meter's status words over the epochs written, when its own file gives
    /// them (docs/formats.md 11.1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub meter_status: Option<MeterStatus>,
    /// An antenna array's session: what its antennas gave.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub antennas: Option<AntennasUsed>,
    /// What the trajectory's heights are measured from, and so which quantity `down_mgal`
    /// is, and which of the named columns are formed (docs/formats.md 10.3).
    pub quantities: Quantities,
    /// The stretches.
    pub stretches: Vec<StretchSummary>,
}

/// A meter's status words over a session's epochs written: each epoch's word is its
/// lines' or-ed (bits numbered from the least significant, 0; gravcal names none).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct MeterStatus {
    /// Epochs with a word (an epoch without a line of the meter's file in its window has
    /// none).
    pub epochs: u64,
    /// Each bit set at some epoch, with the epochs it is set at, by bit.
    pub bits_set: BTreeMap<u8, u64>,
    /// The bits `[survey] meter_status_flag_bits` declares: an epoch with one set is
    /// flagged `meter_status`.
    pub flag_bits: Vec<u8>,
}

impl MeterStatus {
    /// None counted yet, with the survey's declared flag bits.
    pub fn declared(survey: &crate::contract::survey::SurveyConfig) -> Self {
        MeterStatus {
            flag_bits: survey.meter_status_flag_bits.clone(),
            ..MeterStatus::default()
        }
    }
}

/// A session's named quantities: gravity less normal gravity at the trajectory's heights is
/// the quantity those heights give; the other needs the geoid's height.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Quantities {
    /// What the heights are measured from.
    pub heights: crate::contract::survey::Heights,
    /// `disturbance_filtered_mgal` formed.
    pub disturbance: bool,
    /// `free_air_anomaly_filtered_mgal` formed.
    pub free_air_anomaly: bool,
}

impl Quantities {
    /// A session's quantities with its `heights` and the survey's geoid height.
    pub fn new(heights: crate::contract::survey::Heights, geoid_height_m: Option<f64>) -> Self {
        use crate::contract::survey::Heights;
        Quantities {
            heights,
            disturbance: heights == Heights::Ellipsoidal || geoid_height_m.is_some(),
            free_air_anomaly: heights == Heights::SeaLevel || geoid_height_m.is_some(),
        }
    }

    /// One sentence of what the session gives, and what it cannot and why.
    pub fn describe(&self) -> String {
        let give = match (self.disturbance, self.free_air_anomaly) {
            (true, true) => "the gravity disturbance and the free-air anomaly".to_owned(),
            (true, false) => "the gravity disturbance".to_owned(),
            _ => "the free-air anomaly".to_owned(),
        };
        let heights = match self.heights {
            crate::contract::survey::Heights::Ellipsoidal => "above the ellipsoid",
            crate::contract::survey::Heights::SeaLevel => "above sea level",
        };
        let missing = match (self.disturbance, self.free_air_anomaly) {
            (true, false) => "; the free-air anomaly needs [survey] geoid_height_m",
            (false, true) => "; the gravity disturbance needs [survey] geoid_height_m",
            _ => "",
        };
        format!("heights {heights}: {give}{missing}")
    }
}

/// The cross-coupling correction of a session: `sum c_i m_i` of the monitors VE, VCC, AL,
/// AX (in that order), added to the meter's gravity.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CouplingUsed {
    /// `"fit"` (LaCoste's regression on this session) or `"given"` (the manifest's).
    pub how: String,
    /// mGal per unit of each monitor.
    pub coefficients: [f64; 4],
    /// Their sds by the frequency-domain jackknife (the ones the output's sigma carries;
    /// docs/model.md 7); 0 when given.
    pub sigma: [f64; 4],
    /// Their sds as ordinary least squares gives them (independent residuals assumed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ols_sigma: Option<[f64; 4]>,
    /// The regression's rows (samples left after the derivatives' and the filter's ends).
    #[serde(default)]
    pub rows: u64,
}

/// A survey session not reduced, and why.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct NotReduced {
    /// Session id.
    pub session: String,
    /// Why.
    pub why: String,
}

/// A tie and where it was used.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TieUsed {
    /// The window's centre, UTC ISO 8601.
    pub time: String,
    /// Gravity there, mGal.
    pub g_mgal: f64,
    /// The session and stretch whose drift it fixes, or none.
    pub used_in: Option<(String, u32)>,
}

/// One pass over a crossover point.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Pass {
    /// Session id.
    pub session: String,
    /// Its stretch (the `stretch` column).
    pub stretch: u32,
    /// When, UTC ISO 8601 (interpolated between the two epochs either side).
    pub time: String,
    /// The same, GPS ns (gravity.parquet's `time_ns`).
    pub time_gps_ns: i64,
    /// The filtered disturbance down there, mGal.
    pub filtered_mgal: f64,
    /// Its sigma (all parts), mGal.
    pub sigma_mgal: f64,
}

/// Where the track crosses itself: two passes, at least twice the filter's period apart,
/// over one point, both moving, neither turning nor near a stretch's end nor outside the
/// calibration (docs/model.md 7).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Crossover {
    /// The point, deg.
    pub latitude_deg: f64,
    /// Longitude, deg.
    pub longitude_deg: f64,
    /// The angle between the two courses, deg (0-90).
    pub angle_deg: f64,
    /// The earlier pass.
    pub first: Pass,
    /// The later pass.
    pub second: Pass,
    /// Second minus first, mGal.
    pub difference_mgal: f64,
    /// Its sigma, mGal: the parts independent between the passes (noise, positions, and
    /// the tie's: its rate's over the time between them on one stretch, both passes' in
    /// full on two); the calibration's part is common to both and cancels.
    pub sigma_mgal: f64,
}

/// `gravity.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GravityReport {
    /// [`LEDGER_FORMAT`].
    pub format: String,
    /// The survey dataset's name.
    pub dataset: String,
    /// The calibration applied.
    pub calibration: CalibrationUsed,
    /// How the specific force down was formed (the triad's vector through the mounting, or
    /// one axis taken as vertical).
    pub specific_force: String,
    /// The files read.
    pub inputs: Vec<Input>,
    /// The lever arm (antenna to accelerometers, vehicle frame, m) and mounting (deg) used.
    pub lever_arm_m: [f64; 3],
    /// Roll, pitch, yaw.
    pub mounting_deg: [f64; 3],
    /// The filter.
    pub filter: FilterUsed,
    /// How the inputs' errors were taken to behave over time (`[survey] attitude_errors`,
    /// `position_errors`; docs/formats.md 10).
    pub error_models: ErrorModelsUsed,
    /// The ellipsoid of normal gravity (`[survey] normal_gravity`).
    #[serde(default)]
    pub normal_gravity: crate::contract::normal::NormalGravity,
    /// The geoid's height the named quantities were converted with (`[survey]
    /// geoid_height_m`), m; absent when not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geoid_height_m: Option<f64>,
    /// Whether the body tide was removed (`[survey] earth_tide`).
    #[serde(default)]
    pub earth_tide: bool,
    /// Per session.
    pub sessions: Vec<SessionGravity>,
    /// The ties.
    pub ties: Vec<TieUsed>,
    /// Where the track crosses itself.
    #[serde(default)]
    pub crossovers: Vec<Crossover>,
    /// Survey sessions of the dataset the stage could not reduce, each with why (one
    /// without a `trajectory`); absent when none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_reduced: Vec<NotReduced>,
    /// Rows of gravity.parquet.
    pub rows_written: u64,
    /// Its SHA-256.
    pub sha256: String,
    /// attitude.parquet's rows and SHA-256, when a session lists its antennas.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attitude_table: Option<(u64, String)>,
}
