//! `OUT/gravity/gravity.parquet` (docs/formats.md 10.3): one row per trajectory epoch used,
//! in time order per session.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session_index | uint16 | as in ingest's tables (ids in `gravcal.sessions`) |
//! | time_gps_ns | int64 | GPS time of the epoch, ns |
//! | stretch | uint32 | the stretch of track (cut at gaps) the epoch belongs to, from 0 per session |
//! | latitude_deg, longitude_deg | float64 | the accelerometers' position, deg |
//! | height_m | float64 | their ellipsoidal height (the antenna's with the lever arm), m |
//! | speed_m_s | float64 | speed over ground, m/s |
//! | eotvos_mgal, normal_mgal | float64 | the Eotvos term and normal gravity (`[survey] normal_gravity`'s ellipsoid), mGal |
//! | tide_mgal | float64 | the body tide's effect on gravity, removed (0 with `earth_tide = false`), mGal |
//! | cross_coupling_mgal | float64 | a platform meter's cross-coupling correction, added (0 without `cross_coupling`), mGal |
//! | down_mgal | float64 | the gravity disturbance down, unfiltered (ties applied), mGal |
//! | down_filtered_mgal | float64 | the same after the low-pass filter, mGal; NaN within a filter period of its stretch's ends (flag 4), as its sigma and parts, north's and east's |
//! | sigma_down_mgal | float64 | the filtered value's sigma: the six below in quadrature, mGal |
//! | sigma_calibration_mgal, sigma_positions_mgal, sigma_noise_mgal, sigma_tie_mgal, sigma_attitude_mgal, sigma_coupling_mgal | float64 | its parts, mGal (the attitude's 0 without attitude, the cross-coupling's without a fitted correction) |
//! | height_antenna_m | float64 | the antenna's height as the trajectory gives it, m |
//! | north_mgal, north_filtered_mgal, sigma_north_mgal | float64, null without attitude | the disturbance north, unfiltered and filtered, and the filtered value's sigma: the four below in quadrature |
//! | sigma_north_calibration_mgal, sigma_north_positions_mgal, sigma_north_noise_mgal, sigma_north_attitude_mgal | float64, null without attitude | its parts |
//! | east_... | float64, null without attitude | the same seven east |
//! | flags | uint8 | the bits of this module's flags, or-ed |
//! | meter_status | uint32, null | a platform meter's status word at the epoch (its lines' within half an epoch interval, or-ed; docs/formats.md 11.1), null where the session's samples carry none |

use super::{DataType, Field, SESSION_INDEX, SchemaRef, TIME_GPS_NS, with_sessions};
/// File name.
pub const FILE: &str = "gravity.parquet";
/// The epoch's specific force was extrapolated beyond the calibration's range.
pub const OUTSIDE_CALIBRATION: u8 = 1;
/// The vehicle was turning (course changing faster than [`TURN_DEG_PER_S`]).
pub const TURN: u8 = 2;
/// Within one filter period of its stretch's ends, where the filter sees only one side.
pub const EDGE: u8 = 4;
/// The attitude file gives no sd at the epoch: north's and east's sigmas (and their
/// attitude parts) are null, not known; down's attitude part is taken as 0 (it is
/// second order but in turns).
pub const ATTITUDE_SD_UNKNOWN: u8 = 8;
/// The epoch's position failed the outlier test against its neighbours: it was
/// replaced by their prediction, with the prediction's sd (docs/formats.md 10.1).
pub const POSITION_OUTLIER: u8 = 16;
/// The meter's status word has a bit set that `[survey] meter_status_flag_bits`
/// declares.
pub const METER_STATUS: u8 = 32;
/// The course rate above which an epoch is flagged [`TURN`], deg/s.
pub const TURN_DEG_PER_S: f64 = 0.5;
/// Every flag with its name in gravity.json, in bit order.
pub const FLAG_NAMES: [(u8, &str); 6] = [
    (OUTSIDE_CALIBRATION, "outside_calibration"),
    (TURN, "turn"),
    (EDGE, "edge"),
    (ATTITUDE_SD_UNKNOWN, "attitude_sd_unknown"),
    (POSITION_OUTLIER, "position_outlier"),
    (METER_STATUS, "meter_status"),
];
/// The columns of [`HORIZONTAL`] null where [`ATTITUDE_SD_UNKNOWN`] is set.
pub const NEEDS_ATTITUDE_SD: [&str; 4] = [
    "sigma_north_mgal",
    "sigma_north_attitude_mgal",
    "sigma_east_mgal",
    "sigma_east_attitude_mgal",
];
/// Column `latitude_deg`.
pub const LATITUDE_DEG: &str = "latitude_deg";
/// Column `longitude_deg`.
pub const LONGITUDE_DEG: &str = "longitude_deg";
/// Column `height_m`.
pub const HEIGHT_M: &str = "height_m";
/// Column `speed_m_s`.
pub const SPEED_M_S: &str = "speed_m_s";
/// Column `eotvos_mgal`.
pub const EOTVOS_MGAL: &str = "eotvos_mgal";
/// Column `normal_mgal`.
pub const NORMAL_MGAL: &str = "normal_mgal";
/// Column `tide_mgal`.
pub const TIDE_MGAL: &str = "tide_mgal";
/// Column `cross_coupling_mgal`.
pub const CROSS_COUPLING_MGAL: &str = "cross_coupling_mgal";
/// Column `sigma_coupling_mgal`.
pub const SIGMA_COUPLING_MGAL: &str = "sigma_coupling_mgal";
/// Column `down_mgal`.
pub const DOWN_MGAL: &str = "down_mgal";
/// Column `down_filtered_mgal`.
pub const DOWN_FILTERED_MGAL: &str = "down_filtered_mgal";
/// Column `sigma_down_mgal`.
pub const SIGMA_DOWN_MGAL: &str = "sigma_down_mgal";
/// Column `sigma_calibration_mgal`.
pub const SIGMA_CALIBRATION_MGAL: &str = "sigma_calibration_mgal";
/// Column `sigma_positions_mgal`.
pub const SIGMA_POSITIONS_MGAL: &str = "sigma_positions_mgal";
/// Column `sigma_noise_mgal`.
pub const SIGMA_NOISE_MGAL: &str = "sigma_noise_mgal";
/// Column `sigma_tie_mgal`.
pub const SIGMA_TIE_MGAL: &str = "sigma_tie_mgal";
/// Column `sigma_attitude_mgal`.
pub const SIGMA_ATTITUDE_MGAL: &str = "sigma_attitude_mgal";
/// Column `height_antenna_m`.
pub const HEIGHT_ANTENNA_M: &str = "height_antenna_m";
/// The Float64 columns after session_index, time_gps_ns and stretch, in order.
pub const FLOATS: [&str; 18] = [
    LATITUDE_DEG,
    LONGITUDE_DEG,
    HEIGHT_M,
    SPEED_M_S,
    EOTVOS_MGAL,
    NORMAL_MGAL,
    TIDE_MGAL,
    CROSS_COUPLING_MGAL,
    DOWN_MGAL,
    DOWN_FILTERED_MGAL,
    SIGMA_DOWN_MGAL,
    SIGMA_CALIBRATION_MGAL,
    SIGMA_POSITIONS_MGAL,
    SIGMA_NOISE_MGAL,
    SIGMA_TIE_MGAL,
    SIGMA_ATTITUDE_MGAL,
    SIGMA_COUPLING_MGAL,
    HEIGHT_ANTENNA_M,
];
/// The nullable Float64 columns of north and east (docs/formats.md 10.3), after
/// [`FLOATS`]: values only with attitude and a triad model, null elsewhere.
pub const HORIZONTAL: [&str; 14] = [
    "north_mgal",
    "north_filtered_mgal",
    "sigma_north_mgal",
    "sigma_north_calibration_mgal",
    "sigma_north_positions_mgal",
    "sigma_north_noise_mgal",
    "sigma_north_attitude_mgal",
    "east_mgal",
    "east_filtered_mgal",
    "sigma_east_mgal",
    "sigma_east_calibration_mgal",
    "sigma_east_positions_mgal",
    "sigma_east_noise_mgal",
    "sigma_east_attitude_mgal",
];
/// The nullable Float64 columns of the named quantities (docs/formats.md 10.3), after
/// [`HORIZONTAL`]: the filtered gravity disturbance and free-air anomaly, each null in a
/// session that cannot form it (`quantities` in gravity.json), NaN where
/// `down_filtered_mgal` is.
pub const NAMED: [&str; 2] = [
    "disturbance_filtered_mgal",
    "free_air_anomaly_filtered_mgal",
];
/// The stretch column.
pub const STRETCH: &str = "stretch";
/// The flags column.
pub const FLAGS: &str = "flags";
/// The meter's status column, after [`FLAGS`].
pub const METER_STATUS_WORD: &str = "meter_status";

/// The Arrow schema for the dataset's `sessions`.
pub fn schema(sessions: &[String]) -> SchemaRef {
    let mut fields = vec![
        Field::new(SESSION_INDEX, DataType::UInt16, false),
        Field::new(TIME_GPS_NS, DataType::Int64, false),
        Field::new(STRETCH, DataType::UInt32, false),
    ];
    for name in FLOATS {
        fields.push(Field::new(name, DataType::Float64, false));
    }
    for name in HORIZONTAL.iter().chain(&NAMED) {
        fields.push(Field::new(*name, DataType::Float64, true));
    }
    fields.push(Field::new(FLAGS, DataType::UInt8, false));
    fields.push(Field::new(METER_STATUS_WORD, DataType::UInt32, true));
    with_sessions(fields, sessions)
}
