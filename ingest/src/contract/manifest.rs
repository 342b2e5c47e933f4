//! The dataset manifest, `dataset.toml` (docs/formats.md section 2): parsed strictly (unknown keys
//! are errors) and validated, with every error naming the key and the file.

pub use crate::base::time::TimeForm;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The whole manifest.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Dataset name, `[a-z0-9._-]+`.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: Option<String>,
    /// The gravity benchmark.
    pub site: Site,
    /// The acquisition system.
    pub instrument: Instrument,
    /// How observations are formed.
    #[serde(default)]
    pub align: AlignConfig,
    /// Acquisition sessions.
    pub session: Vec<Session>,
    /// What to adjust.
    #[serde(default)]
    pub adjust: AdjustConfig,
    /// What turns survey sessions into gravity (docs/formats.md 10); absent: no reduction
    /// asked for beyond the trajectories' defaults.
    #[serde(default)]
    pub survey: Option<crate::contract::survey::SurveyConfig>,
}

/// `[site]`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Site {
    /// Absolute gravity at the benchmark, mGal.
    pub g_abs_mgal: f64,
    /// Vertical gradient, mGal/m (default: normal free-air gradient).
    #[serde(default = "default_gradient")]
    pub gradient_mgal_per_m: f64,
    /// Proof masses above the benchmark, m.
    #[serde(default)]
    pub sensor_height_m: f64,
    /// Geodetic latitude of the benchmark, deg, north positive (docs/formats.md 8.1).
    #[serde(default)]
    pub latitude_deg: Option<f64>,
    /// Longitude, deg, east positive.
    #[serde(default)]
    pub longitude_deg: Option<f64>,
    /// Ellipsoidal height of the benchmark, m (default 0).
    #[serde(default)]
    pub height_m: Option<f64>,
    /// Apply the body tide to g per observation (default: when the location is given).
    #[serde(default)]
    pub earth_tide: Option<bool>,
}

fn default_gradient() -> f64 {
    -0.3086
}

/// Where the benchmark is, when the manifest says, and whether to apply the tide there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Location {
    /// Geodetic latitude, deg.
    pub latitude_deg: f64,
    /// Longitude, deg, east positive.
    pub longitude_deg: f64,
    /// Ellipsoidal height, m.
    pub height_m: f64,
}

impl Site {
    /// The benchmark's location when the body tide is to be applied (a location given and
    /// `earth_tide` not false); `None` otherwise.
    pub fn tide_location(&self) -> Option<Location> {
        match (self.latitude_deg, self.longitude_deg, self.earth_tide) {
            (Some(latitude_deg), Some(longitude_deg), None | Some(true)) => Some(Location {
                latitude_deg,
                longitude_deg,
                height_m: self.height_m.unwrap_or(0.0),
            }),
            _ => None,
        }
    }

    /// Gravity used in the model: `g_abs + gradient * sensor_height`, mGal.
    pub fn gravity_mgal(&self) -> f64 {
        self.g_abs_mgal + self.gradient_mgal_per_m * self.sensor_height_m
    }
}

/// `[instrument]`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Instrument {
    /// Accelerometer sampling rate, Hz.
    pub sample_rate_hz: f64,
    /// ADC resolution.
    #[serde(default = "default_adc_bits")]
    pub adc_bits: u32,
    /// Range is +/- this, in g.
    #[serde(default = "default_full_scale")]
    pub full_scale_g: f64,
    /// The accelerometers, 1..=3.
    pub accelerometer: Vec<Accelerometer>,
    /// Unit of the readings (docs/formats.md 8.3).
    #[serde(default)]
    pub reading_unit: ReadingUnit,
    /// The thermometer's white noise per reading, degC (a datasheet's or a test's), used
    /// instead of align's estimate from the temperature log (docs/model.md 6.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermometer_sd_c: Option<f64>,
}

fn default_adc_bits() -> u32 {
    24
}
fn default_full_scale() -> f64 {
    2.0
}

/// `[[instrument.accelerometer]]`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Accelerometer {
    /// Identifier, unique.
    pub id: String,
    /// Position in the acquisition record, 1..=3.
    pub channel: u8,
    /// Serial number.
    #[serde(default)]
    pub serial: Option<String>,
    /// The scale and offset its maker states (a platform gravimeter's; docs/formats.md 11.1),
    /// applied with `--calibration vendor`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vendor_calibration: Option<VendorCalibration>,
}

/// A calibration its maker states: the meter's gravity is `offset_mgal + scale * reading`,
/// mGal, with the sds the maker gives (none: taken as exact, its sigma 0). Not a fit: it
/// has no observations, residuals or tests. Apply gives it in the axis models' convention,
/// minus the specific force along an axis pointing up (`adjust::survey::apply`).
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VendorCalibration {
    /// mGal per reading unit.
    pub scale: f64,
    /// mGal.
    pub offset_mgal: f64,
    /// The stated sd of the offset, mGal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sd_offset_mgal: Option<f64>,
    /// The stated sd of the scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sd_scale: Option<f64>,
}

/// `[align]`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct AlignConfig {
    /// ADC averaging window centred on each reading, s.
    pub window_s: f64,
    /// Fraction of the expected samples a window must hold.
    pub min_window_fill: f64,
    /// Furthest temperature sample usable for interpolation, s.
    pub max_temperature_gap_s: f64,
    /// Sd of one reading where a station has fewer than 2 readings, arcsec.
    pub theodolite_sigma_arcsec: f64,
    /// How sigma_Dz per station is formed.
    pub sigma_dz: SigmaDzMethod,
}

/// How sigma_Dz per station is formed (docs/model.md 6.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SigmaDzMethod {
    /// Each station's variance moderated toward the session's (empirical Bayes): the default.
    #[default]
    Moderated,
    /// Each station's own sample sd (eq. 4 of the paper).
    Station,
}

impl Default for AlignConfig {
    fn default() -> Self {
        AlignConfig {
            window_s: 2.56,
            min_window_fill: 0.8,
            max_temperature_gap_s: 10.0,
            theodolite_sigma_arcsec: 1.0,
            sigma_dz: SigmaDzMethod::default(),
        }
    }
}

/// Time scale of the theodolite log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
pub enum TimeScale {
    /// UTC (GPST = UTC + leap seconds).
    #[default]
    #[serde(rename = "UTC")]
    Utc,
    /// GPS time.
    #[serde(rename = "GPST")]
    Gpst,
    /// International Atomic Time.
    #[serde(rename = "TAI")]
    Tai,
}

/// Unit of the theodolite's zenith distance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AngleUnit {
    /// Degrees.
    #[default]
    Deg,
    /// Gon.
    Gon,
    /// Radians.
    Rad,
}

impl AngleUnit {
    /// The angle `value` in this unit, in radians.
    pub fn to_rad(self, value: f64) -> f64 {
        match self {
            AngleUnit::Deg => value.to_radians(),
            AngleUnit::Gon => value * std::f64::consts::PI / 200.0,
            AngleUnit::Rad => value,
        }
    }

    /// A full turn in this unit.
    pub fn full_turn(self) -> f64 {
        match self {
            AngleUnit::Deg => 360.0,
            AngleUnit::Gon => 400.0,
            AngleUnit::Rad => std::f64::consts::TAU,
        }
    }

    /// The unit's name as in the manifest.
    pub fn name(self) -> &'static str {
        match self {
            AngleUnit::Deg => "deg",
            AngleUnit::Gon => "gon",
            AngleUnit::Rad => "rad",
        }
    }
}

/// Layout of an ADC text log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AdcFormat {
    /// `gps_week,tow_s,c1,c2,c3` (docs/formats.md section 4).
    #[default]
    Gps,
    /// `t x y z`: seconds, then one decimal reading a channel, separated by commas or white
    /// space (docs/formats.md 8.3; imu_tk's ASCII layout).
    Seconds,
    /// A DGS marine gravimeter's "laptop" file: 26 fields a line, the raw gravity (mGal) the
    /// reading of channel 1, its own UTC calendar time (docs/formats.md 11.1, `crate::readers::dgs`).
    #[serde(rename = "dgs-laptop")]
    DgsLaptop,
    /// A DGS meter's raw serial output as a ship's logger writes it: the logger's time stamp,
    /// then the meter's `$AT1M` record, its gravity in AD units the reading of channel 1
    /// (docs/formats.md 11.2, `crate::readers::meter_serial`).
    #[serde(rename = "dgs-raw")]
    DgsRaw,
    /// A BGM-3 meter's serial output as a ship's logger writes it: the logger's time stamp,
    /// then `PP:CCCCCC SS`, the counts the reading of channel 1 (docs/formats.md 11.2,
    /// `crate::readers::meter_serial`).
    #[serde(rename = "bgm3")]
    Bgm3,
}

impl AdcFormat {
    /// Read by the lab-stream reader into the lab table (decimal readings in the
    /// instrument's `reading_unit`), not as counts.
    pub fn is_lab_stream(self) -> bool {
        matches!(self, AdcFormat::Seconds) || self.is_meter_file()
    }

    /// A platform meter's own file: one reading a line, its time in the line as the meter
    /// or its logger writes it (no `adc_time`), on channel 1.
    pub fn is_meter_file(self) -> bool {
        matches!(
            self,
            AdcFormat::DgsLaptop | AdcFormat::DgsRaw | AdcFormat::Bgm3
        )
    }

    /// The name as in the manifest.
    pub fn name(self) -> &'static str {
        match self {
            AdcFormat::Gps => "gps",
            AdcFormat::Seconds => "seconds",
            AdcFormat::DgsLaptop => "dgs-laptop",
            AdcFormat::DgsRaw => "dgs-raw",
            AdcFormat::Bgm3 => "bgm3",
        }
    }
}

/// Unit of a "seconds" stream's times.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
pub enum TimeUnit {
    /// Seconds since the session's `start`.
    #[default]
    #[serde(rename = "s")]
    Seconds,
    /// Seconds since 1970-01-01 UTC (Unix time).
    #[serde(rename = "unix_s")]
    UnixSeconds,
}

/// The unit of the instrument's readings (docs/formats.md 8.3): k is in mGal per this unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
pub enum ReadingUnit {
    /// ADC counts.
    #[default]
    #[serde(rename = "count")]
    Count,
    /// m/s^2.
    #[serde(rename = "m/s^2")]
    MetrePerSecond2,
    /// mGal.
    #[serde(rename = "mGal")]
    MilliGal,
    /// Standard gravity.
    #[serde(rename = "g")]
    StandardGravity,
    /// Volts.
    #[serde(rename = "V")]
    Volt,
}

impl ReadingUnit {
    /// The unit as the manifest writes it.
    pub fn name(self) -> &'static str {
        match self {
            ReadingUnit::Count => "count",
            ReadingUnit::MetrePerSecond2 => "m/s^2",
            ReadingUnit::MilliGal => "mGal",
            ReadingUnit::StandardGravity => "g",
            ReadingUnit::Volt => "V",
        }
    }
}

/// What a session is for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SessionKind {
    /// The block tilted over the benchmark, read by the theodolite: calibrated.
    #[default]
    TiltTable,
    /// Acquisition logs only (a survey): ingested, passed by align, adjust and report, and
    /// calibrated by `apply`.
    Survey,
    /// The block put in many static orientations, no theodolite (docs/formats.md 8.4): the
    /// triad's static intervals.
    MultiPosition,
}

impl SessionKind {
    /// The kind's name as in the manifest.
    pub fn name(self) -> &'static str {
        match self {
            SessionKind::TiltTable => "tilt-table",
            SessionKind::Survey => "survey",
            SessionKind::MultiPosition => "multi-position",
        }
    }
}

/// `[[session]]`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Session {
    /// Identifier, unique.
    pub id: String,
    /// UTC date the session starts, `YYYY-MM-DD`.
    pub date: String,
    /// Binary acquisition log.
    #[serde(default)]
    pub acquisition: Option<String>,
    /// CSV ADC log.
    #[serde(default)]
    pub adc_csv: Option<String>,
    /// CSV temperature log.
    #[serde(default)]
    pub temperature_csv: Option<String>,
    /// Layout of `adc_csv` (docs/formats.md 8.3): GPS week and time of week (default), or a lab
    /// logger's seconds.
    #[serde(default)]
    pub adc_format: AdcFormat,
    /// Start of a "seconds" stream whose times are relative, `YYYY-MM-DDTHH:MM:SS[.f]` in
    /// `theodolite_time_scale`.
    #[serde(default)]
    pub start: Option<String>,
    /// Unit of a "seconds" stream's times.
    #[serde(default)]
    pub time_unit: TimeUnit,
    /// Static intervals of a multi-position session, seconds since its start; without them
    /// they are found in the stream.
    #[serde(default)]
    pub static_s: Option<Vec<[f64; 2]>>,
    /// The still stretch at the start of a multi-position session the detector takes its
    /// noise reference from, s (default 10).
    #[serde(default)]
    pub quiet_start_s: Option<f64>,
    /// What the session is for (docs/formats.md 8.4, 8.5): a tilt-table calibration (default)
    /// or a survey, which the calibration is applied to.
    #[serde(default)]
    pub kind: SessionKind,
    /// Theodolite log: required for a tilt-table session, absent from a survey.
    #[serde(default)]
    pub theodolite: Option<String>,
    /// Time scale of the theodolite log.
    #[serde(default)]
    pub theodolite_time_scale: TimeScale,
    /// Unit of the theodolite log.
    #[serde(default)]
    pub theodolite_unit: AngleUnit,
    /// UTC days the session spans from 00:00 of its date (default 2: the date and the day
    /// after); records timed outside are rejected as `outside_session`.
    #[serde(default = "default_days")]
    pub days: u32,
    /// The session is expected to give no data (e.g. a logger known to have failed): its
    /// emptiness is then not an error.
    #[serde(default)]
    pub expect_empty: bool,
    /// Roll of the accelerometer block about its mirror axis for this whole session, deg,
    /// relative to its reference position (docs/formats.md 8.2).
    #[serde(default)]
    pub roll_deg: f64,
    /// How `adc_csv` writes its times (docs/formats.md 9.1); default: GPS week + tow for the
    /// counts CSV, `time_unit` for a lab stream.
    #[serde(default)]
    pub adc_time: Option<TimeForm>,
    /// How `temperature_csv` writes its times; default as `adc_time`'s.
    #[serde(default)]
    pub temperature_time: Option<TimeForm>,
    /// How the theodolite log writes its times; default `iso`.
    #[serde(default)]
    pub theodolite_time: Option<TimeForm>,
    /// The scale of calendar times without a zone, in every log of the session (and of
    /// `start`); `theodolite_time_scale` is its older name.
    #[serde(default)]
    pub time_scale: Option<TimeScale>,
    /// A survey session's GNSS trajectory (docs/formats.md 10.1).
    #[serde(default)]
    pub trajectory: Option<String>,
    /// Its layout: "rtklib" or "csv".
    #[serde(default)]
    pub trajectory_format: Option<crate::contract::survey::TrajectoryFormat>,
    /// How a CSV trajectory writes its times.
    #[serde(default)]
    pub trajectory_time: Option<TimeForm>,
    /// A survey session's attitude CSV (docs/formats.md 10.2).
    #[serde(default)]
    pub attitude: Option<String>,
    /// How the attitude file writes its times.
    #[serde(default)]
    pub attitude_time: Option<TimeForm>,
    /// A survey session's GNSS antennas on the vehicle, instead of one `trajectory` and an
    /// `attitude` (docs/formats.md 11.1): the attitude and the accelerometers' position
    /// come from their baselines.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub antenna: Vec<crate::contract::survey::AntennaDecl>,
    /// The instrument channels (1..=3) the counts CSV's or lab stream's value columns hold,
    /// in their order, 0 for a column to skip (docs/formats.md 9.4); default `[1, 2, 3]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adc_columns: Option<Vec<u8>>,
    /// The session's thermometers: one per accelerometer (default), one for all, or none.
    #[serde(default, skip_serializing_if = "Thermometers::is_each")]
    pub thermometers: Thermometers,
    /// With a thermometer each: the channel (1..=3) of each of the temperature log's value
    /// columns, 0 for a column to skip (docs/formats.md 9.4); default the channels of
    /// `adc_columns`, in order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_columns: Option<Vec<u8>>,
}

/// A session's thermometers (docs/formats.md 9.4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Thermometers {
    /// One per accelerometer: the temperature log has a value column for each channel the
    /// counts log holds, in the same order, or as `temperature_columns` maps them.
    #[default]
    Each,
    /// One for all: the temperature log's single value column is the temperature of every
    /// accelerometer the counts log holds.
    One,
    /// None: no temperature log. Observations carry no temperature, and a model with
    /// temperature terms is named as not estimable.
    None,
}

impl Thermometers {
    /// The default: one per accelerometer.
    pub fn is_each(&self) -> bool {
        *self == Thermometers::Each
    }

    /// The name as in the manifest.
    pub fn name(self) -> &'static str {
        match self {
            Thermometers::Each => "each",
            Thermometers::One => "one",
            Thermometers::None => "none",
        }
    }
}

/// Which instrument channels a text log's value columns hold: `width` columns after the
/// time, and for each channel the column it is read from (None: the log has none for it,
/// and the channel is stored as not connected). One column may feed several channels (one
/// thermometer for all); a column that feeds none is skipped unread (a gyro's, a
/// counter's).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ValueColumns {
    /// Value columns after the time, 1..=[`MAX_VALUE_COLUMNS`].
    pub width: usize,
    /// Channel `ch` (0-based) is read from column `column_of[ch]`.
    pub column_of: [Option<usize>; 3],
}

impl ValueColumns {
    /// Three columns, channels 1, 2 and 3 in order: the layout of docs/formats.md 4.
    pub const EVERY_CHANNEL: ValueColumns = ValueColumns {
        width: 3,
        column_of: [Some(0), Some(1), Some(2)],
    };

    /// The channel (0-based) column `k` is named after: the first it feeds (the last
    /// channel for a column that feeds none, which no value of is read).
    pub fn channel_of(&self, k: usize) -> usize {
        self.column_of
            .iter()
            .position(|c| *c == Some(k))
            .unwrap_or(2)
    }

    /// `v` on every channel of `feeds` (bit `ch` for channel `ch`, as [`Self::feeds`]
    /// gives): what a reader does with a column's value.
    #[inline]
    pub fn place<T: Copy>(feeds: u8, values: &mut [T; 3], v: T) {
        for (ch, value) in values.iter_mut().enumerate() {
            if feeds >> ch & 1 == 1 {
                *value = v;
            }
        }
    }

    /// The channels column `k` feeds, bit `ch` for channel `ch` (0-based); 0 for a column
    /// skipped.
    #[inline]
    pub fn feeds(&self, k: usize) -> u8 {
        let mut bits = 0;
        for (ch, c) in self.column_of.iter().enumerate() {
            if *c == Some(k) {
                bits |= 1 << ch;
            }
        }
        bits
    }
}

/// The most value columns a text log may have after its time (channels and skipped ones).
pub const MAX_VALUE_COLUMNS: usize = 16;

/// How a session's counts and temperature logs lay out their channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogColumns {
    /// The counts log's (or lab stream's).
    pub adc: ValueColumns,
    /// The temperature log's.
    pub temperature: ValueColumns,
}

/// How each text log of a session writes its times, resolved (docs/formats.md 9.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SessionTimes {
    /// The ADC CSV's (or lab stream's).
    pub adc: TimeForm,
    /// The temperature CSV's (or log's).
    pub temperature: TimeForm,
    /// The theodolite log's.
    pub theodolite: TimeForm,
    /// The scale of calendar times without a zone.
    pub scale: TimeScale,
    /// GPS time of the session's `start`, when given.
    pub start_gps_ns: Option<i64>,
}

impl SessionTimes {
    /// A reader of times in `form`, as this session gives them.
    pub fn reader(&self, form: TimeForm) -> crate::base::time::TimeReader {
        crate::base::time::TimeReader::new(form, self.scale, self.start_gps_ns)
    }
}

fn default_days() -> u32 {
    2
}

/// `[adjust]`.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AdjustConfig {
    /// Models to fit; empty means the defaults of docs/formats.md section 2.
    #[serde(default)]
    pub model: Vec<ModelDecl>,
}

/// Over which observations a model is fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Per {
    /// One fit per (accelerometer, session).
    Session,
    /// One fit per accelerometer over all sessions.
    All,
}

/// `[[adjust.model]]`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ModelDecl {
    /// Label, unique.
    pub name: String,
    /// One accelerometer at a time (default), or the three as a triad (docs/formats.md 8.4).
    #[serde(default)]
    pub kind: ModelKind,
    /// Polynomial order 1..=3.
    #[serde(default = "default_order")]
    pub order: u8,
    /// Fit per session or over all sessions.
    #[serde(default = "default_per")]
    pub per: Per,
    /// Bias and scale depend linearly on temperature.
    #[serde(default)]
    pub temperature: bool,
    /// The misalignment of the sensitive axis: none, its part in the tilt plane (beta), or
    /// the vector (theta_x, theta_y) over sessions at different rolls (docs/formats.md 8.2).
    #[serde(default)]
    pub misalignment: Misalignment,
    /// A triad model's error of each position beyond its own scatter (docs/formats.md 8.4):
    /// none (default), a number in mGal, or `"estimate"`.
    #[serde(default, skip_serializing_if = "PositionFloor::is_none")]
    pub position_floor: PositionFloor,
}

/// What a triad fit adds to each position's variance beyond its samples' scatter (a block
/// placed by hand does not return the same mean twice: docs/model.md 6.5): nothing, a
/// declared sd in mGal, or one estimated from the positions' residuals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub enum PositionFloor {
    /// Each position's sigma is its scatter's (default).
    #[default]
    None,
    /// A declared sd, mGal, added in quadrature to every position's.
    Mgal(f64),
    /// Estimated when the positions scatter beyond their sigmas (the fit's sigma0 above 1).
    Estimate,
}

impl PositionFloor {
    /// Whether none is added.
    pub fn is_none(&self) -> bool {
        *self == PositionFloor::None
    }
}

impl<'de> Deserialize<'de> for PositionFloor {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(f64),
            Name(String),
        }
        match Raw::deserialize(d)? {
            Raw::Number(v) => Ok(PositionFloor::Mgal(v)),
            Raw::Name(n) if n == "estimate" => Ok(PositionFloor::Estimate),
            Raw::Name(n) if n == "none" => Ok(PositionFloor::None),
            Raw::Name(n) => Err(serde::de::Error::custom(format!(
                "`{n}` is not \"none\", \"estimate\" or a number of mGal"
            ))),
        }
    }
}

impl ModelDecl {
    /// Checks the declaration on its own (the manifest and the planner alike): its name, its
    /// order, and the combinations no fit can take. The error is (the key, what is wrong).
    pub fn check(&self) -> std::result::Result<(), (&'static str, String)> {
        check_name(&self.name, &[]).map_err(|e| ("name", e))?;
        if !(1..=3).contains(&self.order) {
            return Err(("order", format!("{} is out of range [1, 3]", self.order)));
        }
        match (self.kind, self.position_floor) {
            (ModelKind::Axis, f) if !f.is_none() => {
                return Err((
                    "position_floor",
                    "a position floor belongs to a triad model (an axis model's readings are \
                     weighed by its variance components)"
                        .to_owned(),
                ));
            }
            (_, PositionFloor::Mgal(v)) if !(v.is_finite() && v > 0.0 && v <= 1e6) => {
                return Err((
                    "position_floor",
                    format!("{v} is not a sd in mGal within (0, 1000000]"),
                ));
            }
            _ => {}
        }
        if self.kind == ModelKind::Triad && self.misalignment != Misalignment::None {
            return Err((
                "misalignment",
                "a triad model has no misalignment: T holds the axes' non-orthogonality".to_owned(),
            ));
        }
        if self.misalignment == Misalignment::Vector && self.per != Per::All {
            return Err((
                "misalignment",
                "\"vector\" combines sessions at different rolls: it needs per = \"all\""
                    .to_owned(),
            ));
        }
        Ok(())
    }
}

/// What a model calibrates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Each accelerometer's axis from tilt-table sessions.
    #[default]
    Axis,
    /// The three accelerometers together from multi-position sessions (docs/model.md 6.5).
    Triad,
}

/// How a model treats the misalignment of the sensitive axis: `false`, `true` or `"plane"`
/// (beta, the part in the tilt plane), `"vector"` (theta_x, theta_y in the block's frame).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Misalignment {
    /// Not estimated.
    #[default]
    None,
    /// beta: the sensitive axis's angle in the tilt plane.
    Plane,
    /// theta_x, theta_y: the sensitive axis's components along the block's x (the tilt axis
    /// at roll 0) and y axes.
    Vector,
}

impl Misalignment {
    /// Whether any misalignment is estimated.
    pub fn any(self) -> bool {
        self != Misalignment::None
    }
}

impl<'de> Deserialize<'de> for Misalignment {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Flag(bool),
            Name(String),
        }
        match Raw::deserialize(d)? {
            Raw::Flag(false) => Ok(Misalignment::None),
            Raw::Flag(true) => Ok(Misalignment::Plane),
            Raw::Name(n) if n == "plane" => Ok(Misalignment::Plane),
            Raw::Name(n) if n == "vector" => Ok(Misalignment::Vector),
            Raw::Name(n) => Err(serde::de::Error::custom(format!(
                "`{n}` is not false, true, \"plane\" or \"vector\""
            ))),
        }
    }
}

fn default_order() -> u8 {
    1
}
fn default_per() -> Per {
    Per::Session
}

/// Where a session's acquisition data comes from, resolved against the dataset folder.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Acquisition {
    /// A binary `.gcb` log.
    Binary(PathBuf),
    /// A lab logger's stream in the "seconds" layout (docs/formats.md 8.3), and its temperature
    /// log in the same layout when there is one.
    Lab {
        /// The stream.
        stream: PathBuf,
        /// `t T1 T2 T3`, degC.
        temperature: Option<PathBuf>,
        /// GPS time of its time 0, ns: the session's `start`, or the Unix epoch.
        zero_gps_ns: i64,
        /// The temperature log's, which may count its seconds otherwise (9.1).
        temperature_zero_gps_ns: i64,
    },
    /// The CSV pair.
    Csv {
        /// ADC counts.
        adc: PathBuf,
        /// Temperatures (none when the session declares `thermometers = "none"`).
        temperature: Option<PathBuf>,
    },
}

/// A session with its paths resolved and its date parsed.
#[derive(Clone, Debug)]
pub struct ResolvedSession {
    /// The manifest's entry.
    pub session: Session,
    /// UTC date (year, month, day).
    pub date: (i32, u8, u8),
    /// GPS time of 00:00 UTC of `date`, ns.
    pub start_gps_ns: i64,
    /// Acquisition logs.
    pub acquisition: Acquisition,
    /// Theodolite log (none for a survey session).
    pub theodolite: Option<PathBuf>,
    /// How its text logs write their times.
    pub times: SessionTimes,
    /// A survey session's trajectory.
    pub trajectory: Option<crate::contract::survey::TrajectorySource>,
    /// The channels of its text logs' value columns.
    pub columns: LogColumns,
}

/// A validated dataset: the manifest, its folder, and its sessions resolved.
#[derive(Clone, Debug)]
pub struct Dataset {
    /// The dataset folder.
    pub dir: PathBuf,
    /// The manifest file.
    pub manifest_path: PathBuf,
    /// The manifest as parsed.
    pub manifest: Manifest,
    /// Sessions, in manifest order.
    pub sessions: Vec<ResolvedSession>,
    /// `[survey]`'s ties, their times resolved (empty without the table).
    pub ties: Vec<crate::contract::survey::ResolvedTie>,
}

impl ResolvedSession {
    /// A survey session: acquisition logs only, not calibrated.
    pub fn is_survey(&self) -> bool {
        self.session.kind == SessionKind::Survey
    }

    /// A tilt-table session: theodolite readings, one observation per reading and
    /// accelerometer (the axis calibration's).
    pub fn is_tilt_table(&self) -> bool {
        self.session.kind == SessionKind::TiltTable
    }

    /// The session's range of GPS time, `[00:00 UTC of its date, + days)`, ns: every
    /// record of the session must lie inside it.
    pub fn gps_range_ns(&self) -> (i64, i64) {
        let span = i64::from(self.session.days) * 86_400 * 1_000_000_000;
        (self.start_gps_ns, self.start_gps_ns.saturating_add(span))
    }
}

/// The acquisition of a session whose `adc_csv` is a lab logger's "seconds" stream: its
/// path and the GPS time of its time 0: `start` in the session's time scale, or for Unix
/// times the Unix epoch with the leap seconds of the session's date (a leap second inside
/// a session would shift the rest of it by a second: none is expected in a lab day).
/// A `temperature_csv` beside it is read in the same layout (`t T1 T2 T3`, degC) when its
/// times are seconds (`temperature_time`, by default the stream's form), from a time 0 of
/// its own; in another form of 9.1, as a temperature CSV.
fn lab_acquisition(
    i: usize,
    s: &Session,
    (date, midnight): ((i32, u8, u8), i64),
    times: &SessionTimes,
    file: &impl Fn(String, &str) -> Result<PathBuf>,
    err: &impl Fn(String, String) -> Error,
) -> Result<Acquisition> {
    if s.acquisition.is_some() {
        return Err(err(
            format!("session[{i}].acquisition"),
            format!(
                "adc_format = \"{}\" describes `adc_csv`; give the stream there",
                s.adc_format.name()
            ),
        ));
    }
    let Some(stream) = &s.adc_csv else {
        return Err(err(
            format!("session[{i}].adc_csv"),
            format!(
                "missing: adc_format = \"{}\" needs the stream in `adc_csv`",
                s.adc_format.name()
            ),
        ));
    };
    let stream = file(format!("session[{i}].adc_csv"), stream)?;
    let zero_of = |form: TimeForm| match (form, times.start_gps_ns) {
        (TimeForm::S, Some(start)) => start,
        // Unix times: the epoch, with the leap seconds of the session's date.
        _ => midnight - crate::base::time::days_from_civil(date) * 86_400_000_000_000,
    };
    let temperature = s
        .temperature_csv
        .as_ref()
        .map(|t| file(format!("session[{i}].temperature_csv"), t))
        .transpose()?;
    Ok(Acquisition::Lab {
        stream,
        temperature,
        zero_gps_ns: zero_of(times.adc),
        temperature_zero_gps_ns: zero_of(times.temperature),
    })
}

/// How session `i`'s text logs write their times (docs/formats.md 9.1): the 1.2 keys, with
/// the 1.1 defaults (GPS week + tow for the counts CSV pair, `time_unit` for a lab stream,
/// ISO calendar times for the theodolite log), the scale of zone-less calendar times, and
/// `start` when some log counts seconds from it.
fn session_times(
    i: usize,
    s: &Session,
    err: &impl Fn(String, String) -> Error,
) -> Result<SessionTimes> {
    let key = |k: &str| format!("session[{i}].{k}");
    let scale = match s.time_scale {
        Some(t) if s.theodolite_time_scale != TimeScale::Utc && s.theodolite_time_scale != t => {
            return Err(err(
                key("time_scale"),
                format!(
                    "{t:?} but theodolite_time_scale is {:?}: give one (time_scale)",
                    s.theodolite_time_scale
                ),
            ));
        }
        Some(t) => t,
        None => s.theodolite_time_scale,
    };
    let (adc, temperature) = log_time_forms(s, &key, err)?;
    let theodolite = s.theodolite_time.unwrap_or(TimeForm::Iso);
    let uses_start = [adc, temperature, theodolite].contains(&TimeForm::S)
        || s.trajectory_time == Some(TimeForm::S)
        || s.attitude_time == Some(TimeForm::S);
    Ok(SessionTimes {
        adc,
        temperature,
        theodolite,
        scale,
        start_gps_ns: start_gps_ns(s.start.as_deref(), uses_start, scale, &key, err)?,
    })
}

/// The time forms of a session's ADC and temperature logs: a lab stream's seconds (its
/// temperature log in the same form), the binary log's GPS week and milliseconds (no key
/// applies), or the CSV logs' declared forms (GPS week + tow by default).
fn log_time_forms(
    s: &Session,
    key: &impl Fn(&str) -> String,
    err: &impl Fn(String, String) -> Error,
) -> Result<(TimeForm, TimeForm)> {
    if s.adc_format.is_meter_file() {
        if s.adc_time.is_some() {
            return Err(err(
                key("adc_time"),
                format!(
                    "a {} file writes its own time on every line (docs/formats.md 11.1, 11.2): this \
                     key has nothing to describe",
                    s.adc_format.name()
                ),
            ));
        }
        return Ok((TimeForm::Iso, s.temperature_time.unwrap_or(TimeForm::Iso)));
    }
    if s.adc_format == AdcFormat::Seconds {
        let unit = match s.time_unit {
            TimeUnit::Seconds => TimeForm::S,
            TimeUnit::UnixSeconds => TimeForm::UnixS,
        };
        let adc = s.adc_time.unwrap_or(unit);
        if !matches!(adc, TimeForm::S | TimeForm::UnixS) {
            return Err(err(
                key("adc_time"),
                format!(
                    "\"{}\": a lab stream (adc_format = \"seconds\") writes seconds: \"s\" \
                     (since `start`) or \"unix_s\"",
                    adc.name()
                ),
            ));
        }
        // In seconds it is read in the stream's layout; in another form as a temperature
        // CSV of that form.
        return Ok((adc, s.temperature_time.unwrap_or(adc)));
    }
    if s.acquisition.is_some() {
        if let Some(k) = [
            ("adc_time", s.adc_time),
            ("temperature_time", s.temperature_time),
        ]
        .iter()
        .find_map(|(k, v)| v.map(|_| *k))
        {
            return Err(err(
                key(k),
                "the binary log's times are GPS week and milliseconds (section 3): this key is \
                 for the CSV logs"
                    .to_owned(),
            ));
        }
        return Ok((TimeForm::GpsWeekTow, TimeForm::GpsWeekTow));
    }
    Ok((
        s.adc_time.unwrap_or(TimeForm::GpsWeekTow),
        s.temperature_time.unwrap_or(TimeForm::GpsWeekTow),
    ))
}

/// The GPS time of the session's `start` (in `scale` unless it carries an offset), which
/// must be given exactly when a log counts seconds since it (`uses_start`).
fn start_gps_ns(
    start: Option<&str>,
    uses_start: bool,
    scale: TimeScale,
    key: &impl Fn(&str) -> String,
    err: &impl Fn(String, String) -> Error,
) -> Result<Option<i64>> {
    match (start, uses_start) {
        (None, true) => Err(err(
            key("start"),
            "missing: a log of this session counts seconds since `start` (\"s\")".to_owned(),
        )),
        (Some(_), false) => Err(err(
            key("start"),
            "no log of this session counts seconds since a start (a time form \"s\")".to_owned(),
        )),
        (None, false) => Ok(None),
        (Some(start), true) => {
            let t =
                crate::base::time::iso_gps_ns(start, scale).map_err(|m| err(key("start"), m))?;
            Ok(Some(t))
        }
    }
}

/// Reads and parses `dataset.toml` (UTF-8, a byte-order mark allowed): TOML's error names
/// the line.
fn parse(manifest_path: &Path) -> Result<Manifest> {
    let bytes = std::fs::read(manifest_path).map_err(|e| Error::io(manifest_path, e))?;
    let bytes = bytes
        .strip_prefix(crate::readers::lines::BOM)
        .unwrap_or(&bytes);
    let text = std::str::from_utf8(bytes).map_err(|e| Error::Manifest {
        path: manifest_path.to_path_buf(),
        key: format!("byte {}", e.valid_up_to()),
        message: "not UTF-8 text (a manifest is UTF-8 TOML)".to_owned(),
    })?;
    toml::from_str(text).map_err(|e| {
        // toml names the key (unknown field `x`, missing field `y`) and the line.
        let key = e
            .span()
            .map(|s| {
                let line = text[..s.start].matches('\n').count() + 1;
                format!("line {line}")
            })
            .unwrap_or_else(|| "document".to_owned());
        Error::Manifest {
            path: manifest_path.to_path_buf(),
            key,
            message: e.message().trim().to_owned(),
        }
    })
}

/// A number of the manifest within [lo, hi], or the error naming its key.
fn in_range(
    err: &impl Fn(String, String) -> Error,
    key: &str,
    v: f64,
    (lo, hi): (f64, f64),
) -> Result<()> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(err(
            key.to_owned(),
            format!("{v} is out of range [{lo}, {hi}]"),
        ))
    }
}

/// The manifest's name, site, instrument and align settings checked, and that it has
/// sessions.
fn check_globals(m: &Manifest, err: &impl Fn(String, String) -> Error) -> Result<()> {
    check_name(&m.name, &[]).map_err(|e| err("name".into(), e))?;
    if m.name.bytes().any(|c| c.is_ascii_uppercase()) {
        return Err(err(
            "name".into(),
            format!("`{}` must match [a-z0-9._-]+", m.name),
        ));
    }
    check_site(&m.site, err)?;
    check_instrument(&m.instrument, err)?;
    let a = &m.align;
    in_range(err, "align.window_s", a.window_s, (1e-3, 600.0))?;
    in_range(err, "align.min_window_fill", a.min_window_fill, (1e-6, 1.0))?;
    in_range(
        err,
        "align.max_temperature_gap_s",
        a.max_temperature_gap_s,
        (1e-3, 3600.0),
    )?;
    in_range(
        err,
        "align.theodolite_sigma_arcsec",
        a.theodolite_sigma_arcsec,
        (1e-6, 3600.0),
    )?;
    if m.session.is_empty() {
        return Err(err(
            "session".into(),
            "at least one [[session]] is required".into(),
        ));
    }
    Ok(())
}

/// `[site]`: gravity, gradient, height, and a location given whole.
fn check_site(site: &Site, err: &impl Fn(String, String) -> Error) -> Result<()> {
    in_range(
        err,
        "site.g_abs_mgal",
        site.g_abs_mgal,
        (900_000.0, 1_000_000.0),
    )?;
    in_range(
        err,
        "site.gradient_mgal_per_m",
        site.gradient_mgal_per_m,
        (-5.0, 5.0),
    )?;
    in_range(
        err,
        "site.sensor_height_m",
        site.sensor_height_m,
        (-10.0, 10.0),
    )?;
    for (key, value, limits) in [
        ("site.latitude_deg", site.latitude_deg, (-90.0, 90.0)),
        ("site.longitude_deg", site.longitude_deg, (-180.0, 360.0)),
        ("site.height_m", site.height_m, (-500.0, 9000.0)),
    ] {
        if let Some(v) = value {
            in_range(err, key, v, limits)?;
        }
    }
    if site.latitude_deg.is_some() != site.longitude_deg.is_some() {
        return Err(err(
            "site.latitude_deg".into(),
            "give latitude_deg and longitude_deg together".into(),
        ));
    }
    if site.earth_tide == Some(true) && site.latitude_deg.is_none() {
        return Err(err(
            "site.earth_tide".into(),
            "the body tide needs the site's latitude_deg and longitude_deg".into(),
        ));
    }
    if let Some(latitude_deg) = site.latitude_deg {
        use crate::contract::normal::{GRS80, MAX_DISTURBANCE_MGAL};
        let height_m = site.height_m.unwrap_or(0.0);
        let normal = GRS80.normal_gravity_mgal(latitude_deg, height_m);
        if (site.g_abs_mgal - normal).abs() > MAX_DISTURBANCE_MGAL {
            return Err(err(
                "site.g_abs_mgal".into(),
                format!(
                    "{} mGal is {:.0} mGal from normal gravity at latitude {latitude_deg} deg and \
                     height {height_m} m ({normal:.0} mGal, GRS80), where no place on the \
                     Earth is farther than {MAX_DISTURBANCE_MGAL} mGal: is it this \
                     benchmark's gravity, in mGal, and its latitude?",
                    site.g_abs_mgal,
                    site.g_abs_mgal - normal
                ),
            ));
        }
    }
    Ok(())
}

/// `[instrument]`: rate, converter, and 1 to 3 accelerometers with distinct ids and channels.
fn check_instrument(ins: &Instrument, err: &impl Fn(String, String) -> Error) -> Result<()> {
    in_range(
        err,
        "instrument.sample_rate_hz",
        ins.sample_rate_hz,
        (0.01, 10_000.0),
    )?;
    if !(8..=32).contains(&ins.adc_bits) {
        return Err(err(
            "instrument.adc_bits".into(),
            format!("{} is out of range [8, 32]", ins.adc_bits),
        ));
    }
    in_range(
        err,
        "instrument.full_scale_g",
        ins.full_scale_g,
        (0.001, 100.0),
    )?;
    if let Some(sd) = ins.thermometer_sd_c {
        in_range(err, "instrument.thermometer_sd_c", sd, (0.0, 1.0))?;
    }
    let accs = &ins.accelerometer;
    if accs.is_empty() || accs.len() > 3 {
        return Err(err(
            "instrument.accelerometer".into(),
            format!("{} accelerometers declared; 1 to 3 are allowed", accs.len()),
        ));
    }
    let mut ids = Names::default();
    let mut channels = BTreeSet::new();
    for (i, a) in accs.iter().enumerate() {
        let key = |k: &str| format!("instrument.accelerometer[{i}].{k}");
        check_name(&a.id, RESERVED_ACCELEROMETER_IDS).map_err(|e| err(key("id"), e))?;
        ids.insert(&a.id, "id").map_err(|e| err(key("id"), e))?;
        if !(1..=3).contains(&a.channel) {
            return Err(err(
                key("channel"),
                format!("{} is out of range [1, 3]", a.channel),
            ));
        }
        if !channels.insert(a.channel) {
            return Err(err(
                key("channel"),
                format!("channel {} is used twice", a.channel),
            ));
        }
        if let Some(v) = &a.vendor_calibration {
            check_vendor(v, &|k, m| err(key(&format!("vendor_calibration.{k}")), m))?;
        }
    }
    Ok(())
}

/// A stated calibration's numbers: a scale finite and not 0, an offset within +/-2 g, sds
/// finite and not negative.
fn check_vendor(v: &VendorCalibration, err: &impl Fn(&str, String) -> Error) -> Result<()> {
    if !(v.scale.is_finite() && v.scale != 0.0) {
        return Err(err(
            "scale",
            format!("{} is not a scale: a finite number, not 0", v.scale),
        ));
    }
    if !(v.offset_mgal.is_finite() && v.offset_mgal.abs() <= 2.0 * 980_665.0) {
        return Err(err(
            "offset_mgal",
            format!("{} is not an offset in mGal within +/-2 g", v.offset_mgal),
        ));
    }
    for (k, sd) in [
        ("sd_offset_mgal", v.sd_offset_mgal),
        ("sd_scale", v.sd_scale),
    ] {
        if let Some(sd) = sd
            && !(sd.is_finite() && sd >= 0.0)
        {
            return Err(err(k, format!("{sd} is not an sd")));
        }
    }
    Ok(())
}

/// `rel` resolved in the dataset folder `dir` (canonical `root`): a file that stays inside it
/// (no absolute path, no `..` out of it, no symbolic link that leads out).
fn dataset_file(
    dir: &Path,
    root: &Path,
    key: String,
    rel: &str,
    err: &impl Fn(String, String) -> Error,
) -> Result<PathBuf> {
    let p = dir.join(rel);
    // A path must stay inside the dataset folder: no absolute path, no `..` out of it,
    // no symbolic link that leads out.
    let inside =
        Path::new(rel).is_relative() && p.canonicalize().is_ok_and(|c| c.starts_with(root));
    if p.is_file() && !inside {
        Err(err(
            key,
            format!("`{rel}` is outside the dataset folder {}", dir.display()),
        ))
    } else if p.is_file() {
        Ok(p)
    } else if p.is_dir() {
        Err(err(
            key,
            format!("`{rel}` is a folder in {}, not a file", dir.display()),
        ))
    } else {
        Err(err(
            key,
            format!("file `{rel}` not found in {}", dir.display()),
        ))
    }
}

/// Session `i` validated and resolved: its date, times, acquisition and theodolite logs.
fn resolve_session(
    i: usize,
    s: &Session,
    m: &Manifest,
    file: &impl Fn(String, &str) -> Result<PathBuf>,
    err: &impl Fn(String, String) -> Error,
) -> Result<ResolvedSession> {
    let date = parse_date(&s.date).ok_or_else(|| {
        err(
            format!("session[{i}].date"),
            format!("`{}` is not a date YYYY-MM-DD", s.date),
        )
    })?;
    let start_gps_ns =
        crate::base::time::gps_ns(crate::base::time::Calendar::midnight(date), TimeScale::Utc)
            .ok_or_else(|| {
                err(
                    format!("session[{i}].date"),
                    format!("`{}` is before the GPS epoch (1980-01-06)", s.date),
                )
            })?;
    let (unit, what) = match s.adc_format {
        AdcFormat::DgsLaptop => (
            ReadingUnit::MilliGal,
            "a DGS laptop file's raw gravity is in mGal",
        ),
        AdcFormat::DgsRaw => (
            ReadingUnit::Count,
            "a DGS raw record's gravity is in AD units",
        ),
        AdcFormat::Bgm3 => (ReadingUnit::Count, "a BGM-3's reading is its counts"),
        _ => (m.instrument.reading_unit, ""),
    };
    if m.instrument.reading_unit != unit {
        return Err(err(
            format!("session[{i}].adc_format"),
            format!(
                "{what}, and the instrument's reading_unit is \"{}\": set reading_unit = \"{}\"",
                m.instrument.reading_unit.name(),
                unit.name()
            ),
        ));
    }
    if !s.adc_format.is_lab_stream() && m.instrument.reading_unit != ReadingUnit::Count {
        // One fit takes every session's readings: they must share a unit.
        return Err(err(
            format!("session[{i}].adc_format"),
            format!(
                "session `{}` is logged in ADC counts, and the instrument's \
                 reading_unit is \"{}\": log every session as a lab stream \
                 (adc_format = \"seconds\") in that unit, or set reading_unit = \"count\"",
                s.id,
                m.instrument.reading_unit.name()
            ),
        ));
    }
    let times = session_times(i, s, &err)?;
    let acquisition = if s.adc_format.is_lab_stream() {
        lab_acquisition(i, s, (date, start_gps_ns), &times, &file, &err)?
    } else {
        counts_acquisition(i, s, file, err)?
    };
    let theodolite = theodolite_log(i, s, file, err)?;
    check_session_keys(i, s, err)?;
    let trajectory = crate::contract::survey::trajectory(i, s, file, err)?;
    let columns = log_columns(i, s, err)?;
    Ok(ResolvedSession {
        columns,
        trajectory,
        times,
        session: s.clone(),
        date,
        start_gps_ns,
        acquisition,
        theodolite,
    })
}

/// The channels of session `i`'s value columns (docs/formats.md 9.4): `adc_columns` for the
/// counts CSV or lab stream, and the temperature log's after `thermometers`. The binary log
/// holds three channels a frame.
fn log_columns(
    i: usize,
    s: &Session,
    err: &impl Fn(String, String) -> Error,
) -> Result<LogColumns> {
    let key = |k: &str| format!("session[{i}].{k}");
    let text_logs = s.acquisition.is_none();
    let channels = match &s.adc_columns {
        // The meter's one reading.
        None if s.adc_format.is_meter_file() => vec![1],
        Some(_) if s.adc_format.is_meter_file() => {
            return Err(err(
                key("adc_columns"),
                format!(
                    "a {} file has one reading, the meter's, on channel 1",
                    s.adc_format.name()
                ),
            ));
        }
        None => vec![1, 2, 3],
        Some(_) if !text_logs => {
            return Err(err(
                key("adc_columns"),
                "describes `adc_csv` (a counts CSV or a lab stream): the binary log holds \
                 three channels a frame"
                    .to_owned(),
            ));
        }
        Some(c) => c.clone(),
    };
    let adc = value_columns(&channels).map_err(|m| err(key("adc_columns"), m))?;
    let column_of = adc.column_of;
    if s.acquisition.is_some() && !s.thermometers.is_each() {
        return Err(err(
            key("thermometers"),
            "describes text logs: the binary log's frames carry a temperature per channel"
                .to_owned(),
        ));
    }
    if s.thermometers == Thermometers::None && s.temperature_csv.is_some() {
        return Err(err(
            key("temperature_csv"),
            "given, and thermometers = \"none\": give one of them".into(),
        ));
    }
    let temperature = match s.thermometers {
        Thermometers::One => ValueColumns {
            width: 1,
            column_of: column_of.map(|c| c.map(|_| 0)),
        },
        // A thermometer per channel: as declared, or in the channels' order, no column
        // skipped.
        Thermometers::Each | Thermometers::None => {
            let listed: Vec<u8> = match &s.temperature_columns {
                Some(t) => t.clone(),
                None => channels.iter().copied().filter(|&c| c != 0).collect(),
            };
            value_columns(&listed).map_err(|m| err(key("temperature_columns"), m))?
        }
    };
    if s.temperature_columns.is_some() && !(text_logs && s.thermometers.is_each()) {
        return Err(err(
            key("temperature_columns"),
            "maps a temperature log of a thermometer each (thermometers = \"each\") beside \
             `adc_csv`"
                .to_owned(),
        ));
    }
    Ok(LogColumns { adc, temperature })
}

/// The value columns a list of channels gives (each 1 to 3 once, or 0 for a column to
/// skip), or what is wrong with it.
fn value_columns(channels: &[u8]) -> std::result::Result<ValueColumns, String> {
    if channels.len() > MAX_VALUE_COLUMNS || channels.iter().all(|&c| c == 0) {
        return Err(format!(
            "{} columns, {} of them a channel's: give 1 to {MAX_VALUE_COLUMNS} columns, 1 to 3 \
             of them channels",
            channels.len(),
            channels.iter().filter(|&&c| c != 0).count()
        ));
    }
    let mut column_of = [None; 3];
    for (k, &c) in channels.iter().enumerate().filter(|(_, c)| **c != 0) {
        if !(1..=3).contains(&c) {
            return Err(format!(
                "channel {c} is out of range [1, 3] (0 skips a column)"
            ));
        }
        if column_of[usize::from(c) - 1].replace(k).is_some() {
            return Err(format!("channel {c} is given twice"));
        }
    }
    Ok(ValueColumns {
        width: channels.len(),
        column_of,
    })
}

/// Session `i`'s acquisition in counts: the binary log, or the CSV pair.
fn counts_acquisition(
    i: usize,
    s: &Session,
    file: &impl Fn(String, &str) -> Result<PathBuf>,
    err: &impl Fn(String, String) -> Error,
) -> Result<Acquisition> {
    let none = s.thermometers == Thermometers::None;
    Ok(match (&s.acquisition, &s.adc_csv, &s.temperature_csv) {
        (Some(a), None, None) => Acquisition::Binary(file(format!("session[{i}].acquisition"), a)?),
        (None, Some(_), None) if !none => {
            return Err(err(
                format!("session[{i}].temperature_csv"),
                "adc_csv needs temperature_csv (or thermometers = \"none\" for a session \
                 without a thermometer)"
                    .into(),
            ));
        }
        (None, Some(a), t) => Acquisition::Csv {
            adc: file(format!("session[{i}].adc_csv"), a)?,
            temperature: t
                .as_ref()
                .map(|t| file(format!("session[{i}].temperature_csv"), t))
                .transpose()?,
        },
        (None, None, Some(_)) => {
            return Err(err(
                format!("session[{i}].adc_csv"),
                "temperature_csv needs adc_csv".into(),
            ));
        }
        (None, None, None) => {
            return Err(err(
                format!("session[{i}].acquisition"),
                "missing: give `acquisition` or `adc_csv` and `temperature_csv`".into(),
            ));
        }
        (Some(_), _, _) => {
            return Err(err(
                format!("session[{i}].acquisition"),
                "give `acquisition` or the CSV pair, not both".into(),
            ));
        }
    })
}

/// Session `i`'s theodolite log: required for a tilt table, refused elsewhere.
fn theodolite_log(
    i: usize,
    s: &Session,
    file: &impl Fn(String, &str) -> Result<PathBuf>,
    err: &impl Fn(String, String) -> Error,
) -> Result<Option<PathBuf>> {
    Ok(match (s.kind, &s.theodolite) {
        (SessionKind::TiltTable, Some(t)) => Some(file(format!("session[{i}].theodolite"), t)?),
        (SessionKind::TiltTable, None) => {
            return Err(err(
                format!("session[{i}].theodolite"),
                "missing: a tilt-table session needs its theodolite log (a session \
             without one is `kind = \"survey\"`)"
                    .to_owned(),
            ));
        }
        (SessionKind::Survey, Some(_)) => {
            return Err(err(
                format!("session[{i}].theodolite"),
                "a survey session has no theodolite log (it is calibrated, not a \
             calibration)"
                    .to_owned(),
            ));
        }
        (SessionKind::Survey, None) => None,
        (SessionKind::MultiPosition, Some(_)) => {
            return Err(err(
                format!("session[{i}].theodolite"),
                "a multi-position session has no theodolite log (its positions are \
             the block's static intervals)"
                    .to_owned(),
            ));
        }
        (SessionKind::MultiPosition, None) => None,
    })
}

/// Session `i`'s keys that belong to one kind (static intervals, the quiet start) and its
/// span in days.
fn check_session_keys(i: usize, s: &Session, err: &impl Fn(String, String) -> Error) -> Result<()> {
    if s.static_s.is_some() && s.kind != SessionKind::MultiPosition {
        return Err(err(
            format!("session[{i}].static_s"),
            "static intervals are for kind = \"multi-position\" sessions".to_owned(),
        ));
    }
    if let Some(q) = s.quiet_start_s {
        if s.kind != SessionKind::MultiPosition || s.static_s.is_some() {
            return Err(err(
                format!("session[{i}].quiet_start_s"),
                "the quiet start is the detector's, in a kind = \"multi-position\" \
                 session without static_s"
                    .to_owned(),
            ));
        }
        if !(q.is_finite() && (1.0..=3600.0).contains(&q)) {
            return Err(err(
                format!("session[{i}].quiet_start_s"),
                format!("{q} is out of range [1, 3600] s"),
            ));
        }
    }
    for (k, [t0, t1]) in s.static_s.iter().flatten().enumerate() {
        if !(t0.is_finite() && t1.is_finite() && *t0 >= 0.0 && t1 > t0) {
            return Err(err(
                format!("session[{i}].static_s[{k}]"),
                format!("[{t0}, {t1}] is not an interval of seconds from the start"),
            ));
        }
    }
    if !(1..=366).contains(&s.days) {
        return Err(err(
            format!("session[{i}].days"),
            format!("{} is out of range [1, 366]", s.days),
        ));
    }
    Ok(())
}

/// The models' declarations and the sessions' rolls checked.
fn check_models(m: &Manifest, err: &impl Fn(String, String) -> Error) -> Result<()> {
    let mut names = Names::default();
    for (i, model) in m.adjust.model.iter().enumerate() {
        let key = format!("adjust.model[{i}]");
        model
            .check()
            .map_err(|(k, e)| err(format!("{key}.{k}"), e))?;
        names
            .insert(&model.name, "name")
            .map_err(|e| err(format!("{key}.name"), e))?;
        let declared = m.instrument.accelerometer.len();
        if model.kind == ModelKind::Triad && declared != 3 {
            return Err(err(
                format!("{key}.kind"),
                format!(
                    "a triad model calibrates three accelerometers together (channels x, y, \
                     z), and [[instrument.accelerometer]] declares {declared}: declare the \
                     three, or fit \"axis\" models"
                ),
            ));
        }
    }
    for (i, s) in m.session.iter().enumerate() {
        if !s.roll_deg.is_finite() {
            return Err(err(
                format!("session[{i}].roll_deg"),
                format!("{} is not a finite angle", s.roll_deg),
            ));
        }
    }
    Ok(())
}

/// Parses `YYYY-MM-DD` into a valid calendar date.
pub fn parse_date(s: &str) -> Option<(i32, u8, u8)> {
    let b = s.as_bytes();
    if b.len() != 10 || b[4] != b'-' || b[7] != b'-' {
        return None;
    }
    let y: i32 = s[0..4].parse().ok()?;
    let m: u8 = s[5..7].parse().ok()?;
    let d: u8 = s[8..10].parse().ok()?;
    calendar_date(y, m, d)
}

/// `(y, m, d)` when it is a date of the calendar from 1980 (GPS's epoch) to 2200.
pub fn calendar_date(y: i32, m: u8, d: u8) -> Option<(i32, u8, u8)> {
    (1980..=2200).contains(&y).then_some(())?;
    let days = match m {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if (y % 4 == 0 && y % 100 != 0) || y % 400 == 0 => 29,
        2 => 28,
        _ => return None,
    };
    (1..=days).contains(&d).then_some((y, m, d))
}

/// The longest id or name: it becomes part of file names (`<model>-<session>.calib`, the
/// report's plots), which must stay well inside any file system's 255 bytes.
pub const MAX_NAME_LEN: usize = 64;

/// Words a fit's scope or a triad's identity stands for in the outputs: a session id
/// `all` would be pooled with every session, an accelerometer id `triad` read as a triad.
pub const RESERVED_SESSION_IDS: &[&str] = &[super::calibration::ALL_SESSIONS];
/// See [`RESERVED_SESSION_IDS`].
pub const RESERVED_ACCELEROMETER_IDS: &[&str] =
    &[super::calibration::ALL_SESSIONS, super::calibration::TRIAD];

/// A file name made of checked names: at most 200 bytes of `A-Z a-z 0-9 . _ -`, beginning
/// with a letter or a digit (one plain file in the folder it is joined to).
pub fn is_plain_file_name(name: &str) -> bool {
    (1..=200).contains(&name.len())
        && name.starts_with(|c: char| c.is_ascii_alphanumeric())
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'))
}

/// Names of one kind (sessions, accelerometers, models) seen so far, by their lower case:
/// outputs are named by them (`triad-lab.calib`, a report's plots), and the file systems of
/// macOS and Windows do not tell `Lab` from `lab`, so two names that differ only in case
/// would write one file over the other.
#[derive(Default)]
pub struct Names(std::collections::BTreeMap<String, String>);

impl Names {
    /// Adds `name` (its `what`: "id", "name"); an error if it, or a name differing only in
    /// case, was seen.
    pub fn insert(&mut self, name: &str, what: &str) -> std::result::Result<(), String> {
        match self.0.insert(name.to_ascii_lowercase(), name.to_owned()) {
            None => Ok(()),
            Some(seen) if seen == name => Err(format!("duplicate {what} `{name}`")),
            Some(seen) => Err(format!(
                "`{name}` and `{seen}` differ only in case: outputs are named by them, and \
                 the file systems of macOS and Windows do not tell them apart"
            )),
        }
    }
}

/// Checks an id or a name a user gives (a session, an accelerometer, a model, a dataset):
/// 1 to [`MAX_NAME_LEN`] characters of `A-Z a-z 0-9 . _ -`, beginning with a letter or a
/// digit (so never `.`, `..` or an option), not one of `reserved`. Every output path built
/// from names is then one plain file name inside the output folder.
pub fn check_name(name: &str, reserved: &[&str]) -> std::result::Result<(), String> {
    if name.is_empty() {
        return Err("is empty".to_owned());
    }
    if name.chars().count() > MAX_NAME_LEN {
        return Err(format!(
            "`{}...` is {} characters long; at most {MAX_NAME_LEN} are allowed",
            name.chars().take(16).collect::<String>(),
            name.chars().count()
        ));
    }
    if let Some(c) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-')))
    {
        return Err(format!(
            "`{name}` holds {c:?}: only letters, digits, `.`, `_` and `-` are allowed"
        ));
    }
    if !name.starts_with(|c: char| c.is_ascii_alphanumeric()) {
        return Err(format!("`{name}` must begin with a letter or a digit"));
    }
    if let Some(r) = reserved.iter().find(|r| r.eq_ignore_ascii_case(name)) {
        return Err(format!(
            "`{name}` is reserved (`{r}` names a fit over all sessions or a triad in the \
             outputs); choose another"
        ));
    }
    Ok(())
}

impl Dataset {
    /// Reads and validates `<dir>/dataset.toml`.
    pub fn load(dir: &Path) -> Result<Dataset> {
        let manifest_path = dir.join(crate::contract::ingest_ledger::MANIFEST_FILE);
        let manifest = parse(&manifest_path)?;
        let err = |key: String, message: String| Error::Manifest {
            path: manifest_path.clone(),
            key,
            message,
        };
        let m = &manifest;
        check_globals(m, &err)?;
        let mut sids = Names::default();
        let mut sessions = Vec::new();
        let root = dir.canonicalize().map_err(|e| Error::io(dir, e))?;
        let file = |key: String, rel: &str| dataset_file(dir, &root, key, rel, &err);
        for (i, s) in m.session.iter().enumerate() {
            check_name(&s.id, RESERVED_SESSION_IDS)
                .map_err(|e| err(format!("session[{i}].id"), e))?;
            sids.insert(&s.id, "id")
                .map_err(|e| err(format!("session[{i}].id"), e))?;
            sessions.push(resolve_session(i, s, m, &file, &err)?);
        }
        check_models(m, &err)?;
        let ties = match &m.survey {
            Some(survey) => {
                let any = sessions.iter().any(|s| s.trajectory.is_some());
                crate::contract::survey::check_against_sessions(survey, &sessions, &err)?;
                crate::contract::survey::check(survey, any, &err)?
            }
            None => Vec::new(),
        };
        Ok(Dataset {
            dir: dir.to_path_buf(),
            manifest_path: manifest_path.clone(),
            manifest,
            sessions,
            ties,
        })
    }

    /// The accelerometer on `channel` (1..=3), if any.
    pub fn accelerometer_on(&self, channel: u8) -> Option<&Accelerometer> {
        self.manifest
            .instrument
            .accelerometer
            .iter()
            .find(|a| a.channel == channel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(toml_text: &str) -> std::result::Result<ModelDecl, String> {
        let m: ModelDecl = toml::from_str(toml_text).map_err(|e| e.to_string())?;
        m.check().map_err(|(k, e)| format!("{k}: {e}"))?;
        Ok(m)
    }

    /// `position_floor`: a number of mGal, "estimate" or "none", on a triad model only; a
    /// floor out of range, another word, or a floor on an axis model is refused by key.
    #[test]
    fn a_position_floor_is_read_and_checked() {
        let triad = "name = \"t\"\nkind = \"triad\"\n";
        for (v, want) in [
            ("400.0", PositionFloor::Mgal(400.0)),
            ("\"estimate\"", PositionFloor::Estimate),
            ("\"none\"", PositionFloor::None),
        ] {
            let m = model(&format!("{triad}position_floor = {v}\n")).expect(v);
            assert_eq!(m.position_floor, want);
        }
        assert_eq!(
            model(triad).expect("default").position_floor,
            PositionFloor::None
        );
        for (text, says) in [
            (
                format!("{triad}position_floor = -1.0\n"),
                "position_floor: -1",
            ),
            (
                format!("{triad}position_floor = 0.0\n"),
                "position_floor: 0",
            ),
            (
                format!("{triad}position_floor = \"guess\"\n"),
                "`guess` is not",
            ),
            (
                "name = \"a\"\nposition_floor = \"estimate\"\n".to_owned(),
                "position_floor: a position floor belongs to a triad model",
            ),
        ] {
            let e = model(&text).expect_err(&text);
            assert!(e.contains(says), "{text}: {e}");
        }
    }
}
