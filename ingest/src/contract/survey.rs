//! The manifest's moving-gravimetry keys (docs/formats.md 10): a survey session's trajectory
//! and the `[survey]` table (lever arm, mounting, filter, static ties), parsed with the
//! manifest and validated here, every error naming the key.

use super::manifest::{Session, SessionKind, TimeScale};
use crate::base::time::TimeForm;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// How a trajectory file is written (docs/formats.md 10.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
pub enum TrajectoryFormat {
    /// RTKLIB's solution file (`.pos`): its header says its times.
    #[serde(rename = "rtklib")]
    Rtklib,
    /// `time,lat_deg,lon_deg,h_m[,sd_n_m,sd_e_m,sd_u_m]`, the time in `trajectory_time`.
    #[serde(rename = "csv")]
    Csv,
    /// A DGS marine gravimeter's laptop file: the meter's own navigation columns (latitude and
    /// longitude, no height: the sea surface, height 0, and said so; docs/formats.md 11.1).
    #[serde(rename = "dgs-laptop")]
    DgsLaptop,
    /// NMEA 0183 sentences as a ship's logger writes them (GGA, else RMC; dates from ZDA or
    /// RMC, else the session's; docs/formats.md 10.1).
    #[serde(rename = "nmea")]
    Nmea,
}

impl TrajectoryFormat {
    /// What the format's heights are measured from: a GNSS solution's from the ellipsoid, a
    /// ship's meter's navigation (no height) from the sea surface; None where the file says
    /// (NMEA: its GGA's geoid separation, or none).
    pub fn heights(self) -> Option<Heights> {
        match self {
            TrajectoryFormat::Rtklib | TrajectoryFormat::Csv => Some(Heights::Ellipsoidal),
            TrajectoryFormat::DgsLaptop => Some(Heights::SeaLevel),
            TrajectoryFormat::Nmea => None,
        }
    }
}

/// What a trajectory's heights are measured from (docs/formats.md 10.3): it decides which
/// quantity gravity less normal gravity at those heights is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
pub enum Heights {
    /// Above the ellipsoid: gravity less normal gravity there is the gravity disturbance.
    #[serde(rename = "ellipsoidal")]
    Ellipsoidal,
    /// Above sea level (the geoid): gravity less normal gravity there is the free-air
    /// anomaly.
    #[serde(rename = "sea level")]
    SeaLevel,
}

/// The geoid's height above the ellipsoid the manifest may state, m: the Earth's geoid lies
/// within about -107 and +86 m of GRS80.
pub const GEOID_HEIGHT_BOUND_M: f64 = 120.0;

/// `[survey]`: what turns a survey's calibrated accelerations into gravity (docs/formats.md 10).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SurveyConfig {
    /// From the GNSS antenna's reference point to the accelerometers, vehicle frame (x forward,
    /// y right, z down), m.
    pub lever_arm_m: [f64; 3],
    /// Roll, pitch, yaw of the accelerometers' body frame in the vehicle frame, deg:
    /// C_b^v = Rz(yaw) Ry(pitch) Rx(roll).
    pub mounting_deg: [f64; 3],
    /// The low-pass filter's cut-off period, s: its zero-phase amplitude response is 0.5 at
    /// 1 / filter_s.
    pub filter_s: f64,
    /// The low-pass filter's kind (Butterworth by default).
    pub filter: FilterKind,
    /// What the attitude file's sds say over time (docs/formats.md 10.2): its errors are
    /// white, correlated or systematic.
    pub attitude_errors: ErrorKind,
    /// With `attitude_errors = "correlated"`: the first-order Gauss-Markov correlation
    /// time, s (default [`DEFAULT_ATTITUDE_CORRELATION_S`]).
    pub attitude_correlation_s: Option<f64>,
    /// What the trajectory's sds say over time (docs/formats.md 10.1).
    pub position_errors: ErrorKind,
    /// With `position_errors = "correlated"`: the correlation time, s (no default: a
    /// position's correlation depends on the solution).
    pub position_correlation_s: Option<f64>,
    /// The white noise of one sample of the specific force down, mGal at the stream's rate,
    /// as the instrument's maker or the user's own still record states it: taken instead of
    /// the record's spectral floor (docs/model.md 7), and needed where the record has none
    /// (a meter that filters its own output before writing it).
    pub sample_noise_mgal: Option<f64>,
    /// Static ties at known gravity.
    pub tie: Vec<TieDecl>,
    /// The ellipsoid whose normal gravity the disturbance is held to (GRS80 by default).
    pub normal_gravity: crate::contract::normal::NormalGravity,
    /// The geoid's height above the ellipsoid over the survey, m (one value: the survey's
    /// area small against the geoid's wavelengths), from a geoid model the user names in
    /// their report. With it both the gravity disturbance and the free-air anomaly are
    /// formed; without it only the one the trajectory's heights give (docs/formats.md 10.3).
    pub geoid_height_m: Option<f64>,
    /// The solid Earth's body tide removed at every epoch (align's model, docs/model.md
    /// 6.3), and written as `tide_mgal`; default true (ties are tide-free values).
    pub earth_tide: bool,
    /// A platform meter's cross-coupling (docs/formats.md 11.1): `"none"` (the default),
    /// `"fit"` (LaCoste's regression per session), or the four coefficients given.
    pub cross_coupling: CrossCoupling,
    /// Which ties level a stretch (docs/formats.md 10): every tie of its session, one drift
    /// across the gaps (`"session"`, the default), or only those inside it (`"stretch"`).
    pub tie_level: TieLevel,
    /// The bits of a platform meter's status word (0 the least significant) that flag an
    /// epoch `meter_status` when set in it (docs/formats.md 11.1): the meter's map of them
    /// is the user's to know; none by default.
    pub meter_status_flag_bits: Vec<u8>,
    /// An antenna array's baseline check (docs/formats.md 10.2.1): a baseline whose measured
    /// length departs from its declared one by more than this many sds sets an antenna
    /// aside for the epoch.
    pub baseline_length_sigmas: f64,
    /// How an antenna array's session forms its down component (docs/formats.md 10.2.1):
    /// the force turned by the array's attitude (the default), or from its magnitude.
    pub array_down: ArrayDown,
}

/// `[survey] array_down` (docs/model.md 7, "An antenna array").
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ArrayDown {
    /// The specific force turned into the navigation frame by the array's attitude: its
    /// tilt error, a few mrad an epoch, enters down (g eps^2 / 2 and eps times the
    /// horizontal force), which down's sigma carries, conservatively.
    #[default]
    Attitude,
    /// f_D = -sqrt(|f|^2 - |h|^2), |f| each sample's own and h the horizontal force the
    /// track gives, low-passed (the lag at a sharp change, a turn's onset or end, taken
    /// out): no tilt enters it, but a horizontal force faster than the low-pass that is no
    /// sharp change (a vehicle's sway or turbulence) is not seen, and down's sigma does not
    /// say so. For a vehicle whose horizontal force is slow (a ship on its lines).
    Magnitude,
}

/// `[survey] filter`: the zero-phase low-pass filter's kind (docs/model.md 7, "The
/// filters"); whichever, its amplitude response is 0.5 at 1 / `filter_s`.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum FilterKind {
    /// Butterworth of order 4, forward and backward (scipy's `sosfiltfilt`).
    #[default]
    Butterworth,
    /// A Gaussian kernel (NAVO's and LDEO's), applied once, centred.
    Gaussian,
    /// A windowed-sinc FIR with a Blackman window (scipy's `firwin`), applied once, centred.
    Blackman,
    /// The same with a Hamming window.
    Hamming,
}

impl FilterKind {
    /// The manifest's word for it.
    pub fn name(self) -> &'static str {
        match self {
            FilterKind::Butterworth => "butterworth",
            FilterKind::Gaussian => "gaussian",
            FilterKind::Blackman => "blackman",
            FilterKind::Hamming => "hamming",
        }
    }
}

/// `[survey] tie_level`.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum TieLevel {
    /// One offset and drift per session, from all its ties, for every stretch: the
    /// instrument drifts on through a gap in the navigation (dock ties at a cruise's ends).
    #[default]
    Session,
    /// Each stretch by the ties inside it alone (untied without any).
    Stretch,
}

/// `[survey] cross_coupling`: the correction `sum c_i m_i` of a meter's monitors (VE, VCC,
/// AL, AX), added to its gravity.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum CrossCoupling {
    /// `"none"` or `"fit"`.
    Word(CouplingWord),
    /// `{ ve = ..., vcc = ..., al = ..., ax = ... }`: coefficients known, exact.
    Given(GivenCoupling),
}

/// A word or a table, the error naming what either may be.
impl<'de> Deserialize<'de> for CrossCoupling {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = CrossCoupling;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("\"none\", \"fit\" or { ve = ..., vcc = ..., al = ..., ax = ... }")
            }
            fn visit_str<E: serde::de::Error>(
                self,
                v: &str,
            ) -> std::result::Result<Self::Value, E> {
                match v {
                    "none" => Ok(CrossCoupling::Word(CouplingWord::None)),
                    "fit" => Ok(CrossCoupling::Word(CouplingWord::Fit)),
                    other => Err(E::custom(format!(
                        "`{other}`: expected \"none\", \"fit\" or {{ ve = ..., vcc = ..., al = \
                         ..., ax = ... }}"
                    ))),
                }
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                GivenCoupling::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(CrossCoupling::Given)
            }
        }
        d.deserialize_any(Visitor)
    }
}

impl Default for CrossCoupling {
    fn default() -> Self {
        CrossCoupling::Word(CouplingWord::None)
    }
}

impl CrossCoupling {
    /// Whether a correction is asked for.
    pub fn is_some(self) -> bool {
        self != CrossCoupling::Word(CouplingWord::None)
    }
}

/// `"none"` or `"fit"`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum CouplingWord {
    /// No correction.
    None,
    /// Coefficients fitted to each session (LaCoste's method, as shipgrav).
    Fit,
}

/// The four coefficients, as a meter's maker or an earlier fit states them.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GivenCoupling {
    /// VE's.
    pub ve: f64,
    /// VCC's.
    pub vcc: f64,
    /// AL's.
    pub al: f64,
    /// AX's.
    pub ax: f64,
}

impl GivenCoupling {
    /// In the order of the monitors: VE, VCC, AL, AX.
    pub fn values(self) -> [f64; 4] {
        [self.ve, self.vcc, self.al, self.ax]
    }
}

/// How the errors an input's sds state behave over time (docs/model.md 7, "Error models").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
pub enum ErrorKind {
    /// Independent from one sample to the next: the filter averages them down.
    #[serde(rename = "white")]
    White,
    /// A first-order Gauss-Markov process with the declared correlation time: the filter
    /// averages them down only over times longer than it.
    #[serde(rename = "correlated")]
    Correlated,
    /// One error over a stretch: the filter does not reduce it.
    #[serde(rename = "systematic")]
    Systematic,
}

impl ErrorKind {
    /// Its name in the manifest.
    pub fn name(self) -> &'static str {
        match self {
            ErrorKind::White => "white",
            ErrorKind::Correlated => "correlated",
            ErrorKind::Systematic => "systematic",
        }
    }
}

/// The attitude's error model when none is declared: correlated over five minutes, since
/// an INS's or a GNSS/INS's attitude errors wander over minutes (a multi-antenna GNSS
/// attitude alone is close to white: declare it).
pub const DEFAULT_ATTITUDE_CORRELATION_S: f64 = 300.0;

/// An error model resolved: its kind and, correlated, its correlation time.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ErrorModel {
    /// Independent per sample.
    White,
    /// First-order Gauss-Markov.
    Correlated {
        /// Its correlation time, s.
        correlation_s: f64,
    },
    /// Constant over a stretch.
    Systematic,
}

impl SurveyConfig {
    /// The attitude's error model as declared (or by default).
    pub fn attitude_error_model(&self) -> ErrorModel {
        resolved(
            self.attitude_errors,
            self.attitude_correlation_s
                .unwrap_or(DEFAULT_ATTITUDE_CORRELATION_S),
        )
    }

    /// The positions' error model as declared (or by default: white).
    pub fn position_error_model(&self) -> ErrorModel {
        resolved(
            self.position_errors,
            self.position_correlation_s.unwrap_or(f64::NAN),
        )
    }
}

fn resolved(kind: ErrorKind, correlation_s: f64) -> ErrorModel {
    match kind {
        ErrorKind::White => ErrorModel::White,
        ErrorKind::Correlated => ErrorModel::Correlated { correlation_s },
        ErrorKind::Systematic => ErrorModel::Systematic,
    }
}

impl Default for SurveyConfig {
    fn default() -> Self {
        SurveyConfig {
            lever_arm_m: [0.0; 3],
            mounting_deg: [0.0; 3],
            filter_s: 100.0,
            filter: FilterKind::Butterworth,
            attitude_errors: ErrorKind::Correlated,
            attitude_correlation_s: None,
            position_errors: ErrorKind::White,
            position_correlation_s: None,
            sample_noise_mgal: None,
            tie: Vec::new(),
            normal_gravity: crate::contract::normal::NormalGravity::Grs80,
            geoid_height_m: None,
            earth_tide: true,
            cross_coupling: CrossCoupling::default(),
            tie_level: TieLevel::default(),
            meter_status_flag_bits: Vec::new(),
            baseline_length_sigmas: 5.0,
            array_down: ArrayDown::default(),
        }
    }
}

impl SurveyConfig {
    /// [`SurveyConfig::meter_status_flag_bits`] as a mask.
    pub fn meter_status_mask(&self) -> u32 {
        self.meter_status_flag_bits
            .iter()
            .filter(|&&b| b < 32)
            .fold(0, |m, &b| m | 1 << b)
    }
}

/// `[[survey.tie]]`: a still window at a point of known gravity.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TieDecl {
    /// The centre of the still window: ISO 8601, with `Z` or an offset, or zone-less in UTC.
    pub time: String,
    /// The window's length, s.
    pub duration_s: f64,
    /// Absolute gravity at the accelerometers there, mGal.
    pub g_mgal: f64,
}

/// A tie resolved: its centre in GPS time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResolvedTie {
    /// The still window's centre, GPS ns.
    pub time_gps_ns: i64,
    /// The window's length, s.
    pub duration_s: f64,
    /// Absolute gravity at the accelerometers, mGal.
    pub g_mgal: f64,
}

/// A survey session's trajectory, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct TrajectorySource {
    /// The file.
    pub path: PathBuf,
    /// Its layout.
    pub format: TrajectoryFormat,
    /// For a CSV, how it writes its times.
    pub time: Option<TimeForm>,
    /// The attitude file (docs/formats.md 10.2), if any, and how it writes its times.
    pub attitude: Option<(PathBuf, TimeForm)>,
    /// The session's antennas (docs/formats.md 10.2.1), when it lists them: the attitude and
    /// the accelerometers' position come from their baselines, and `path`, `format` and
    /// `time` above are the first antenna's, the session's reference (empty: one
    /// trajectory at the antenna the lever arm starts from).
    pub antennas: Vec<Antenna>,
}

/// `[[session.antenna]]`: one GNSS antenna of an array on the vehicle.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AntennaDecl {
    /// Its name.
    pub id: String,
    /// Its trajectory (docs/formats.md 10.1).
    pub trajectory: String,
    /// Its layout.
    pub trajectory_format: TrajectoryFormat,
    /// How a CSV trajectory writes its times.
    #[serde(default)]
    pub trajectory_time: Option<TimeForm>,
    /// Its phase centre in the vehicle frame (x forward, y right, z down), m, from the
    /// accelerometers' origin to the antenna; or `"estimate"`.
    pub position_m: PositionDecl,
}

/// An antenna's `position_m` as written: metres, or a word (only `"estimate"` is one).
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum PositionDecl {
    /// x, y, z in the vehicle frame, m.
    Metres([f64; 3]),
    /// A word.
    Word(String),
}

impl<'de> Deserialize<'de> for PositionDecl {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        /// Three numbers or a word, anything else refused saying which is wanted.
        struct Either;
        impl<'de> serde::de::Visitor<'de> for Either {
            type Value = PositionDecl;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "three numbers [x, y, z] in metres, or \"{ESTIMATE}\"")
            }
            fn visit_str<E: serde::de::Error>(
                self,
                v: &str,
            ) -> std::result::Result<Self::Value, E> {
                Ok(PositionDecl::Word(v.to_owned()))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                let mut xyz = [0.0; 3];
                for (k, v) in xyz.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| serde::de::Error::invalid_length(k, &self))?;
                }
                if seq.next_element::<f64>()?.is_some() {
                    return Err(serde::de::Error::invalid_length(4, &self));
                }
                Ok(PositionDecl::Metres(xyz))
            }
        }
        d.deserialize_any(Either)
    }
}

/// The word that has an antenna's position estimated from the data.
pub const ESTIMATE: &str = "estimate";

/// An antenna of a session's array, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Antenna {
    /// Its name.
    pub id: String,
    /// Its trajectory file.
    pub path: PathBuf,
    /// Its layout.
    pub format: TrajectoryFormat,
    /// For a CSV, how it writes its times.
    pub time: Option<TimeForm>,
    /// Its phase centre in the vehicle frame, m, from the accelerometers; None: estimated
    /// from the data, in the frame the declared antennas fix (docs/formats.md 10.2.1).
    pub position_m: Option<[f64; 3]>,
}

/// The first of the keys that describe a `trajectory` (its format and time, the attitude
/// and its time) that session `s` gives.
fn track_key_given(s: &Session) -> Option<&'static str> {
    [
        ("trajectory_format", s.trajectory_format.is_some()),
        ("trajectory_time", s.trajectory_time.is_some()),
        ("attitude", s.attitude.is_some()),
        ("attitude_time", s.attitude_time.is_some()),
    ]
    .iter()
    .find_map(|(k, given)| given.then_some(*k))
}

/// The most antennas an array may list.
pub const MAX_ANTENNAS: usize = 8;

/// Session `i`'s antennas resolved: on a survey session, instead of `trajectory` and
/// `attitude`; two to [`MAX_ANTENNAS`] of them, their ids distinct, their positions within
/// 100 m; two only fore and aft (their baseline within 0.5 deg of the vehicle's x axis:
/// they give heading and pitch), three or more not in a line.
fn antennas(
    i: usize,
    s: &Session,
    file: &impl Fn(String, &str) -> Result<PathBuf>,
    err: &impl Fn(String, String) -> Error,
) -> Result<TrajectorySource> {
    let key = |k: &str| format!("session[{i}].{k}");
    let trajectory = s.trajectory.is_some().then_some("trajectory");
    if let Some(k) = trajectory.or_else(|| track_key_given(s)) {
        return Err(err(
            key(k),
            "a session with `[[session.antenna]]` takes its track and attitude from the \
             antennas"
                .to_owned(),
        ));
    }
    if s.kind != SessionKind::Survey {
        return Err(err(
            key("antenna"),
            format!(
                "a {} session has no antennas: only a survey session",
                s.kind.name()
            ),
        ));
    }
    if !(2..=MAX_ANTENNAS).contains(&s.antenna.len()) {
        return Err(err(
            key("antenna"),
            format!(
                "{} antenna(s): an array has 2 to {MAX_ANTENNAS} (one antenna is a `trajectory` \
                 with `[survey] lever_arm_m`)",
                s.antenna.len()
            ),
        ));
    }
    let mut out = Vec::new();
    for (k, a) in s.antenna.iter().enumerate() {
        let key = |f: &str| format!("session[{i}].antenna[{k}].{f}");
        if out.iter().any(|o: &Antenna| o.id == a.id) {
            return Err(err(key("id"), format!("`{}` is listed twice", a.id)));
        }
        let position_m = antenna_position(&a.position_m).map_err(|m| err(key("position_m"), m))?;
        let time = trajectory_time(a.trajectory_format, a.trajectory_time, &key, err)?;
        out.push(Antenna {
            id: a.id.clone(),
            path: file(key("trajectory"), &a.trajectory)?,
            format: a.trajectory_format,
            time,
            position_m,
        });
    }
    estimated_positions(&out, &key, err)?;
    array_geometry(&out, &key, err)?;
    Ok(TrajectorySource {
        path: out[0].path.clone(),
        format: out[0].format,
        time: out[0].time,
        attitude: None,
        antennas: out,
    })
}

/// An antenna's `position_m` resolved: a position on the vehicle (within 100 m), or None
/// for `"estimate"`; else why not.
fn antenna_position(p: &PositionDecl) -> std::result::Result<Option<[f64; 3]>, String> {
    match p {
        PositionDecl::Word(w) if w == ESTIMATE => Ok(None),
        PositionDecl::Word(w) => Err(format!(
            "`{w}` is not a position [x, y, z] in metres or \"{ESTIMATE}\""
        )),
        PositionDecl::Metres(m) if m.iter().any(|v| !v.is_finite() || v.abs() > 100.0) => Err(
            format!("{m:?} is not a position on a vehicle (within 100 m)"),
        ),
        PositionDecl::Metres(m) => Ok(Some(*m)),
    }
}

/// An array with antennas to estimate checked: three or more declared beside them (their
/// geometry is checked as an array's), which fix the vehicle frame and the accelerometers'
/// origin that the estimated positions are in; GNSS alone gives neither.
fn estimated_positions(
    antennas: &[Antenna],
    key: &impl Fn(&str) -> String,
    err: &impl Fn(String, String) -> Error,
) -> Result<()> {
    let declared = antennas.iter().filter(|a| a.position_m.is_some()).count();
    if declared == antennas.len() || declared >= 3 {
        return Ok(());
    }
    let estimated: Vec<&str> = antennas
        .iter()
        .filter(|a| a.position_m.is_none())
        .map(|a| a.id.as_str())
        .collect();
    Err(err(
        key("antenna"),
        format!(
            "{} to estimate ({}) beside {declared} declared: an estimated position is found in \
             the vehicle frame that three or more declared antennas, not in a line, fix (the \
             antennas alone tell neither where the accelerometers are nor which way their \
             axes point)",
            estimated.len(),
            estimated.join(", ")
        ),
    ))
}

/// An array's geometry checked on its declared antennas (those to estimate have none yet):
/// two antennas fore and aft, three or more not in a line.
fn array_geometry(
    antennas: &[Antenna],
    key: &impl Fn(&str) -> String,
    err: &impl Fn(String, String) -> Error,
) -> Result<()> {
    let (ids, p): (Vec<&str>, Vec<[f64; 3]>) = antennas
        .iter()
        .filter_map(|a| a.position_m.map(|p| (a.id.as_str(), p)))
        .unzip();
    let d = |a: [f64; 3], b: [f64; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let base = d(p[0], p[1]);
    if norm(base) < 0.1 {
        return Err(err(
            key("antenna"),
            format!(
                "antennas `{}` and `{}` are {:.3} m apart: a baseline needs 0.1 m at least",
                ids[0],
                ids[1],
                norm(base)
            ),
        ));
    }
    if p.len() == 2 {
        let off_axis = (base[1].hypot(base[2]) / base[0].abs()).atan().to_degrees();
        if base[0] == 0.0 || off_axis > 0.5 {
            return Err(err(
                key("antenna"),
                "two antennas give heading and pitch only when their baseline lies along the \
                 vehicle's x axis (within 0.5 deg); across it, roll turns it: add a third \
                 antenna"
                    .to_owned(),
            ));
        }
        return Ok(());
    }
    let area = p[2..]
        .iter()
        .map(|q| {
            let o = d(p[0], *q);
            norm([
                base[1] * o[2] - base[2] * o[1],
                base[2] * o[0] - base[0] * o[2],
                base[0] * o[1] - base[1] * o[0],
            ])
        })
        .fold(0.0, f64::max);
    if area <= 1e-3 * norm(base).powi(2) {
        return Err(err(
            key("antenna"),
            "the antennas lie in a line: roll about it is not seen; place one off the line"
                .to_owned(),
        ));
    }
    Ok(())
}

/// Session `i`'s trajectory keys checked and its files resolved: only on a survey session;
/// `trajectory_format` required with `trajectory`; `trajectory_time` for a CSV only;
/// `attitude` only with a trajectory, with its `attitude_time`. (A `"s"` time form without
/// the session's `start` was refused with the session's times, which count these keys.)
pub fn trajectory(
    i: usize,
    s: &Session,
    file: &impl Fn(String, &str) -> Result<PathBuf>,
    err: &impl Fn(String, String) -> Error,
) -> Result<Option<TrajectorySource>> {
    let key = |k: &str| format!("session[{i}].{k}");
    if !s.antenna.is_empty() {
        return antennas(i, s, file, err).map(Some);
    }
    let Some(rel) = &s.trajectory else {
        if let Some(k) = track_key_given(s) {
            return Err(err(
                key(k),
                "describes `trajectory`, which is not given".to_owned(),
            ));
        }
        return Ok(None);
    };
    if s.kind != SessionKind::Survey {
        return Err(err(
            key("trajectory"),
            format!(
                "a {} session has no trajectory: the gravity stage reduces kind = \"survey\" \
                 sessions",
                s.kind.name()
            ),
        ));
    }
    let path = file(key("trajectory"), rel)?;
    let format = s.trajectory_format.ok_or_else(|| {
        err(
            key("trajectory_format"),
            "missing: \"rtklib\" (a .pos solution file), \"csv\", \"dgs-laptop\" or \"nmea\""
                .to_owned(),
        )
    })?;
    let time = trajectory_time(format, s.trajectory_time, &key, err)?;
    let attitude = match (&s.attitude, s.attitude_time) {
        (None, None) => None,
        (None, Some(_)) => {
            return Err(err(
                key("attitude_time"),
                "describes `attitude`, which is not given".to_owned(),
            ));
        }
        (Some(_), None) => {
            return Err(err(
                key("attitude_time"),
                "missing: how the attitude CSV writes its times (\"gps_week_tow\", \"iso\", \
                 \"unix_s\" or \"s\")"
                    .to_owned(),
            ));
        }
        (Some(rel), Some(t)) => Some((file(key("attitude"), rel)?, t)),
    };
    Ok(Some(TrajectorySource {
        path,
        format,
        time,
        attitude,
        antennas: Vec::new(),
    }))
}

/// A trajectory's time form checked against its format (a `"s"` without the session's
/// `start` is refused with the session's times, before this).
fn trajectory_time(
    format: TrajectoryFormat,
    time: Option<TimeForm>,
    key: &impl Fn(&str) -> String,
    err: &impl Fn(String, String) -> Error,
) -> Result<Option<TimeForm>> {
    Ok(match (format, time) {
        (TrajectoryFormat::Rtklib, Some(_)) => {
            return Err(err(
                key("trajectory_time"),
                "an RTKLIB solution file says its own times in its header: remove the key"
                    .to_owned(),
            ));
        }
        (TrajectoryFormat::Rtklib, None) => None,
        (TrajectoryFormat::DgsLaptop, Some(_)) => {
            return Err(err(
                key("trajectory_time"),
                "a DGS laptop file writes its own UTC calendar time on every line: remove the \
                 key"
                .to_owned(),
            ));
        }
        (TrajectoryFormat::DgsLaptop, None) => None,
        (TrajectoryFormat::Nmea, Some(_)) => {
            return Err(err(
                key("trajectory_time"),
                "NMEA sentences carry their own UTC time: remove the key".to_owned(),
            ));
        }
        (TrajectoryFormat::Nmea, None) => None,
        (TrajectoryFormat::Csv, None) => {
            return Err(err(
                key("trajectory_time"),
                "missing: how the CSV writes its times (\"gps_week_tow\", \"iso\", \"unix_s\" \
                 or \"s\")"
                    .to_owned(),
            ));
        }
        (TrajectoryFormat::Csv, Some(t)) => Some(t),
    })
}

/// No lever arm beside an antenna array (its antennas' positions are from the
/// accelerometers), its baselines' check in range, and `array_down = "magnitude"` only
/// where an array gives a roll.
fn check_array(
    survey: &SurveyConfig,
    sessions: &[super::manifest::ResolvedSession],
    err: &impl Fn(String, String) -> Error,
) -> Result<()> {
    if let Some(s) = sessions.iter().find(|s| {
        s.trajectory
            .as_ref()
            .is_some_and(|t| !t.antennas.is_empty())
    }) && survey.lever_arm_m.iter().any(|v| *v != 0.0)
    {
        return Err(err(
            "survey.lever_arm_m".to_owned(),
            format!(
                "session `{}` lists its antennas, each with its position from the \
                 accelerometers (`position_m`): a lever arm has nothing to add",
                s.session.id
            ),
        ));
    }
    let arrays = sessions
        .iter()
        .any(|s| s.trajectory.as_ref().is_some_and(|t| t.antennas.len() >= 3));
    if survey.array_down == ArrayDown::Magnitude && !arrays {
        return Err(err(
            "survey.array_down".to_owned(),
            "\"magnitude\" is for a session with three or more antennas, and none lists them"
                .to_owned(),
        ));
    }
    if !(survey.baseline_length_sigmas >= 2.0 && survey.baseline_length_sigmas <= 1e3) {
        return Err(err(
            "survey.baseline_length_sigmas".to_owned(),
            format!(
                "{}: a baseline's length is checked at 2 to 1000 of its sds",
                survey.baseline_length_sigmas
            ),
        ));
    }
    Ok(())
}

/// `meter_status_flag_bits`: a 32-bit word's bits, declared only where a meter's own file
/// carries a status word.
fn check_meter_status(
    survey: &SurveyConfig,
    sessions: &[super::manifest::ResolvedSession],
    err: &impl Fn(String, String) -> Error,
) -> Result<()> {
    if let Some(b) = survey.meter_status_flag_bits.iter().find(|&&b| b >= 32) {
        return Err(err(
            "survey.meter_status_flag_bits".to_owned(),
            format!("bit {b}: a status word's bits are 0 (the least significant) to 31"),
        ));
    }
    if !survey.meter_status_flag_bits.is_empty()
        && let Some(s) = sessions.iter().find(|s| {
            s.trajectory.is_some()
                && !matches!(
                    s.session.adc_format,
                    super::manifest::AdcFormat::DgsLaptop
                        | super::manifest::AdcFormat::DgsRaw
                        | super::manifest::AdcFormat::Bgm3
                )
        })
    {
        return Err(err(
            "survey.meter_status_flag_bits".to_owned(),
            format!(
                "session `{}` has no meter status: only a meter's own file (adc_format = \
                 \"dgs-laptop\", \"dgs-raw\" or \"bgm3\") carries one",
                s.session.id
            ),
        ));
    }
    Ok(())
}

/// `[survey]` checked against the sessions: [`check_array`], [`check_meter_status`], and
/// `cross_coupling`: only a DGS meter's own file carries monitors; given coefficients are
/// numbers.
pub fn check_against_sessions(
    survey: &SurveyConfig,
    sessions: &[super::manifest::ResolvedSession],
    err: &impl Fn(String, String) -> Error,
) -> Result<()> {
    check_array(survey, sessions, err)?;
    check_meter_status(survey, sessions, err)?;
    if survey.cross_coupling.is_some()
        && let Some(s) = sessions.iter().find(|s| {
            s.trajectory.is_some()
                && !matches!(
                    s.session.adc_format,
                    super::manifest::AdcFormat::DgsLaptop | super::manifest::AdcFormat::DgsRaw
                )
        })
    {
        return Err(err(
            "survey.cross_coupling".to_owned(),
            format!(
                "session `{}` has no cross-coupling monitors: only a DGS meter's own file \
                 (adc_format = \"dgs-laptop\" or \"dgs-raw\") carries them",
                s.session.id
            ),
        ));
    }
    if let CrossCoupling::Given(g) = survey.cross_coupling
        && let Some(v) = g.values().iter().find(|v| !v.is_finite())
    {
        return Err(err(
            "survey.cross_coupling".to_owned(),
            format!("{v} is not a coefficient"),
        ));
    }
    Ok(())
}

/// `[survey]` checked against the sessions: it describes trajectories, so some session must
/// have one; every number in range; every tie's time parsed.
pub fn check(
    survey: &SurveyConfig,
    any_trajectory: bool,
    err: &impl Fn(String, String) -> Error,
) -> Result<Vec<ResolvedTie>> {
    if !any_trajectory {
        return Err(err(
            "survey".to_owned(),
            "[survey] reduces survey sessions to gravity, and no session has a `trajectory`"
                .to_owned(),
        ));
    }
    for (k, v) in survey.lever_arm_m.iter().enumerate() {
        if !(v.is_finite() && v.abs() <= 100.0) {
            return Err(err(
                format!("survey.lever_arm_m[{k}]"),
                format!("{v} is not a lever arm in m within [-100, 100]"),
            ));
        }
    }
    for (k, v) in survey.mounting_deg.iter().enumerate() {
        if !(v.is_finite() && v.abs() <= 360.0) {
            return Err(err(
                format!("survey.mounting_deg[{k}]"),
                format!("{v} is not an angle in deg within [-360, 360]"),
            ));
        }
    }
    let f = survey.filter_s;
    if !(f.is_finite() && (1.0..=100_000.0).contains(&f)) {
        return Err(err(
            "survey.filter_s".to_owned(),
            format!("{f} is out of range [1, 100000] s"),
        ));
    }
    let (attitude, position) = (survey.attitude_errors, survey.position_errors);
    error_model(
        "attitude",
        attitude,
        survey.attitude_correlation_s,
        true,
        err,
    )?;
    error_model(
        "position",
        position,
        survey.position_correlation_s,
        false,
        err,
    )?;
    if let Some(v) = survey.sample_noise_mgal
        && !(v.is_finite() && v > 0.0 && v <= 1e5)
    {
        return Err(err(
            "survey.sample_noise_mgal".to_owned(),
            format!("{v} is not a sample's noise in mGal within (0, 100000]"),
        ));
    }
    geoid_height(survey.geoid_height_m, err)?;
    let ties: Vec<ResolvedTie> = survey
        .tie
        .iter()
        .enumerate()
        .map(|(k, t)| tie(k, t, err))
        .collect::<Result<_>>()?;
    no_overlap(&ties, err)?;
    Ok(ties)
}

/// `[survey] geoid_height_m`: within [`GEOID_HEIGHT_BOUND_M`].
fn geoid_height(v: Option<f64>, err: &impl Fn(String, String) -> Error) -> Result<()> {
    match v {
        Some(v) if !(v.is_finite() && v.abs() <= GEOID_HEIGHT_BOUND_M) => Err(err(
            "survey.geoid_height_m".to_owned(),
            format!(
                "{v} is not a geoid height in m within +/-{GEOID_HEIGHT_BOUND_M} (the geoid \
                 lies within about -107 and +86 m of the ellipsoid)"
            ),
        )),
        _ => Ok(()),
    }
}

/// An error model's keys: a correlation time only with `"correlated"`, in (0, 1e6] s, and
/// required there unless it has a default.
fn error_model(
    what: &str,
    kind: ErrorKind,
    correlation_s: Option<f64>,
    has_default: bool,
    err: &impl Fn(String, String) -> Error,
) -> Result<()> {
    let key = format!("survey.{what}_correlation_s");
    match (kind, correlation_s) {
        (ErrorKind::Correlated, Some(c)) if !(c.is_finite() && c > 0.0 && c <= 1e6) => Err(err(
            key,
            format!("{c} is not a correlation time in s within (0, 1000000]"),
        )),
        (ErrorKind::Correlated, None) if !has_default => Err(err(
            key,
            format!(
                "missing: survey.{what}_errors = \"correlated\" needs the errors' correlation \
                 time in s"
            ),
        )),
        (ErrorKind::White | ErrorKind::Systematic, Some(_)) => Err(err(
            key,
            format!(
                "a correlation time goes with survey.{what}_errors = \"correlated\" only \
                 (it is \"{}\")",
                kind.name()
            ),
        )),
        _ => Ok(()),
    }
}

/// Two ties whose still windows overlap would count the same epochs twice (a tie repeated
/// by mistake would halve the drift's variance).
fn no_overlap(ties: &[ResolvedTie], err: &impl Fn(String, String) -> Error) -> Result<()> {
    let half = |t: &ResolvedTie| (t.duration_s * 0.5e9) as i64;
    for (j, b) in ties.iter().enumerate() {
        for (k, a) in ties[..j].iter().enumerate() {
            if (a.time_gps_ns - b.time_gps_ns).abs() <= half(a) + half(b) {
                return Err(err(
                    format!("survey.tie[{j}]"),
                    format!(
                        "its still window overlaps survey.tie[{k}]'s: each window's epochs \
                         can tie once"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Tie `k` resolved.
fn tie(k: usize, t: &TieDecl, err: &impl Fn(String, String) -> Error) -> Result<ResolvedTie> {
    let key = |f: &str| format!("survey.tie[{k}].{f}");
    let gps =
        crate::base::time::iso_gps_ns(&t.time, TimeScale::Utc).map_err(|m| err(key("time"), m))?;
    if !(t.duration_s.is_finite() && (1.0..=86_400.0).contains(&t.duration_s)) {
        return Err(err(
            key("duration_s"),
            format!("{} is out of range [1, 86400] s", t.duration_s),
        ));
    }
    if !(t.g_mgal.is_finite() && (976_000.0..=984_000.0).contains(&t.g_mgal)) {
        return Err(err(
            key("g_mgal"),
            format!(
                "{} is not gravity on the Earth in mGal (976000 to 984000)",
                t.g_mgal
            ),
        ));
    }
    Ok(ResolvedTie {
        time_gps_ns: gps,
        duration_s: t.duration_s,
        g_mgal: t.g_mgal,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `position_m` is three numbers or a word; anything else is refused saying which is
    /// wanted, with its line and column.
    #[test]
    fn an_antennas_position_is_three_numbers_or_a_word() {
        let decl = |v: &str| {
            let t = format!(
                "id = 'a'\ntrajectory = 'x'\ntrajectory_format = 'rtklib'\nposition_m = {v}\n"
            );
            toml::from_str::<AntennaDecl>(&t).map(|a| a.position_m)
        };
        assert_eq!(
            decl("[1.0, -2, 0.5]").expect("numbers"),
            PositionDecl::Metres([1.0, -2.0, 0.5])
        );
        assert_eq!(
            decl("\"estimate\"").expect("a word"),
            PositionDecl::Word("estimate".to_owned())
        );
        let e = decl("['a', 'b', 'c']").expect_err("words").to_string();
        assert!(e.contains("line 4") && e.contains("expected f64"), "{e}");
        for bad in ["[1.0, 2.0]", "[1.0, 2.0, 3.0, 4.0]", "3"] {
            let e = decl(bad).expect_err(bad).to_string();
            assert!(
                e.contains("line 4") && e.contains("[x, y, z] in metres, or \"estimate\""),
                "{bad}: {e}"
            );
        }
    }

    /// A tie at UTC's leap second 23:59:60 lies between 23:59:59 and the next day's
    /// midnight, through the same leap-second-aware path the logs' times take (it was read
    /// a second early).
    #[test]
    fn a_tie_at_the_leap_second_is_read_in_its_place() {
        let at = |time: &str| {
            let t = TieDecl {
                time: time.to_owned(),
                duration_s: 60.0,
                g_mgal: 980_000.0,
            };
            tie(0, &t, &|k, m| Error::Manifest {
                path: "dataset.toml".into(),
                key: k,
                message: m,
            })
            .expect("tie")
            .time_gps_ns
        };
        let before = at("2016-12-31T23:59:59Z");
        let leap = at("2016-12-31T23:59:60Z");
        let after = at("2017-01-01T00:00:00Z");
        assert_eq!(leap - before, 1_000_000_000);
        assert_eq!(after - leap, 1_000_000_000);
        assert_eq!(at("2017-01-01T09:00:00+09:00"), after);
    }

    /// The error models' keys: a correlation time only with "correlated", the positions'
    /// required there, the attitude's defaulted.
    #[test]
    fn error_models_are_checked_by_key() {
        let err = |k: String, m: String| Error::Manifest {
            path: "dataset.toml".into(),
            key: k,
            message: m,
        };
        let checked = |a: (ErrorKind, Option<f64>), p: (ErrorKind, Option<f64>)| {
            let s = SurveyConfig {
                attitude_errors: a.0,
                attitude_correlation_s: a.1,
                position_errors: p.0,
                position_correlation_s: p.1,
                ..SurveyConfig::default()
            };
            check(&s, true, &err).map(|_| s)
        };
        let s = checked((ErrorKind::Correlated, None), (ErrorKind::White, None)).expect("defaults");
        assert_eq!(
            s.attitude_error_model(),
            ErrorModel::Correlated {
                correlation_s: DEFAULT_ATTITUDE_CORRELATION_S
            }
        );
        for (a, p, key) in [
            (
                (ErrorKind::White, Some(10.0)),
                (ErrorKind::White, None),
                "survey.attitude_correlation_s",
            ),
            (
                (ErrorKind::Correlated, None),
                (ErrorKind::Correlated, None),
                "survey.position_correlation_s",
            ),
            (
                (ErrorKind::Correlated, Some(-1.0)),
                (ErrorKind::White, None),
                "survey.attitude_correlation_s",
            ),
        ] {
            let e = checked(a, p).expect_err("refused").to_string();
            assert!(e.contains(key), "{e}");
        }
        for v in [0.0, -1.0, f64::NAN, 2e5] {
            let s = SurveyConfig {
                sample_noise_mgal: Some(v),
                ..SurveyConfig::default()
            };
            let e = check(&s, true, &err).expect_err("refused").to_string();
            assert!(e.contains("survey.sample_noise_mgal"), "{v}: {e}");
        }
        for v in [f64::NAN, 130.0, -500.0] {
            let s = SurveyConfig {
                geoid_height_m: Some(v),
                ..SurveyConfig::default()
            };
            let e = check(&s, true, &err).expect_err("refused").to_string();
            assert!(e.contains("survey.geoid_height_m"), "{v}: {e}");
        }
        let s = SurveyConfig {
            geoid_height_m: Some(-106.0),
            ..SurveyConfig::default()
        };
        assert!(check(&s, true, &err).is_ok());
    }

    /// An array's geometry: two antennas only fore and aft (within 0.5 deg), three or more
    /// not in a line, no baseline under 0.1 m; each refused naming the session's antennas.
    #[test]
    fn an_arrays_geometry_is_checked() {
        let array = |p: &[[f64; 3]]| -> Vec<Antenna> {
            p.iter()
                .enumerate()
                .map(|(k, q)| Antenna {
                    id: format!("a{k}"),
                    path: "a.pos".into(),
                    format: TrajectoryFormat::Rtklib,
                    time: None,
                    position_m: Some(*q),
                })
                .collect()
        };
        let err = |k: String, m: String| Error::Manifest {
            path: "dataset.toml".into(),
            key: k,
            message: m,
        };
        let key = |k: &str| format!("session[0].{k}");
        let check = |p: &[[f64; 3]]| array_geometry(&array(p), &key, &err);
        assert!(check(&[[1.5, 0.0, -2.0], [-1.5, 0.0, -2.0]]).is_ok());
        assert!(check(&[[1.5, 0.0, -2.0], [-1.5, 0.0, -2.0], [0.0, 1.2, -2.0]]).is_ok());
        for (p, why) in [
            (vec![[1.5, 0.0, -2.0], [-1.5, 0.1, -2.0]], "x axis"),
            (vec![[1.0, 0.0, -2.0], [1.05, 0.0, -2.0]], "0.1 m"),
            (
                vec![[1.0, 0.0, -2.0], [0.0, 0.0, -2.0], [-1.0, 0.0, -2.0]],
                "in a line",
            ),
        ] {
            let e = check(&p).expect_err(why).to_string();
            assert!(e.contains(why) && e.contains("session[0].antenna"), "{e}");
        }
    }
}
