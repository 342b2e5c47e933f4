//! The tables ingest writes (OUT/ingest/), in one place: file names, column names, types and
//! units. Downstream stages read them through these constants.
//!
//! | table | column | type | unit / meaning |
//! |---|---|---|---|
//! | acceleration.parquet | session_index | uint16 | position of the session in dataset.toml (ids in the schema metadata `gravcal.sessions`) |
//! | | time_gps_ns | int64 | GPS time, ns since 1980-01-06 |
//! | | counts_ch1..3 | int32, null | ADC counts; null where not connected or over range |
//! | | status | uint8 | status bits as logged (bit n-1 over range, bit n+3 not connected) |
//! | temperature.parquet | session_index, time_gps_ns, status | as above | |
//! | | temperature_ch1..3_c | float64, null | degC; null where not connected |
//! | theodolite.parquet | session | utf8 (dictionary) | session id |
//! | | station | utf8 | tilt position id |
//! | | time_gps_ns | int64 | GPS time of the reading, ns |
//! | | dz_rad | float64 | zenith distance, rad, in [0, 2 pi) |
//! | | dz_value | float64 | zenith distance as read |
//! | | dz_unit | utf8 | unit as read: deg, gon or rad |
//! | | time_as_read | utf8 | the time field as written in the log |
//! | | time_scale | utf8 | UTC, GPST or TAI |
//! | | line | uint32 | line number in the log |
//!
//! Rows are in session order (as in the manifest), then time order. The two large tables
//! carry the session as an index rather than a string: a string per sample costs more to
//! write than the sample itself.

use arrow_schema::{DataType, Field, Schema, SchemaRef};
use std::sync::Arc;

/// Session id column (all tables).
pub const SESSION: &str = "session";
/// GPS time column (all tables), i64 ns.
pub const TIME_GPS_NS: &str = "time_gps_ns";
/// Status bits column (acceleration, temperature).
pub const STATUS: &str = "status";
/// Session index column (acceleration, temperature): position in the manifest's sessions.
pub const SESSION_INDEX: &str = "session_index";
/// Schema metadata key holding the session ids, in index order, as a JSON array.
pub const SESSIONS_METADATA: &str = "gravcal.sessions";

fn with_sessions(fields: Vec<Field>, sessions: &[String]) -> SchemaRef {
    let ids = serde_json::to_string(sessions).expect("strings serialise");
    Arc::new(Schema::new_with_metadata(
        fields,
        arrow_schema::Metadata::new().with(SESSIONS_METADATA, ids),
    ))
}

/// Data type of the session column.
pub fn session_type() -> DataType {
    DataType::Dictionary(Box::new(DataType::Int32), Box::new(DataType::Utf8))
}

/// `acceleration.parquet`.
pub mod acceleration {
    use super::{DataType, Field, SESSION_INDEX, STATUS, SchemaRef, TIME_GPS_NS, with_sessions};
    /// File name.
    pub const FILE: &str = "acceleration.parquet";
    /// Counts of channels 1..3.
    pub const COUNTS: [&str; 3] = ["counts_ch1", "counts_ch2", "counts_ch3"];
    /// The Arrow schema, for the dataset's `sessions` (ids in manifest order).
    pub fn schema(sessions: &[String]) -> SchemaRef {
        with_sessions(
            vec![
                Field::new(SESSION_INDEX, DataType::UInt16, false),
                Field::new(TIME_GPS_NS, DataType::Int64, false),
                Field::new(COUNTS[0], DataType::Int32, true),
                Field::new(COUNTS[1], DataType::Int32, true),
                Field::new(COUNTS[2], DataType::Int32, true),
                Field::new(STATUS, DataType::UInt8, false),
            ],
            sessions,
        )
    }
}

/// `temperature.parquet`.
pub mod temperature {
    use super::{DataType, Field, SESSION_INDEX, STATUS, SchemaRef, TIME_GPS_NS, with_sessions};
    /// File name.
    pub const FILE: &str = "temperature.parquet";
    /// Temperatures of channels 1..3, degC.
    pub const TEMPERATURE_C: [&str; 3] = [
        "temperature_ch1_c",
        "temperature_ch2_c",
        "temperature_ch3_c",
    ];
    /// The Arrow schema, for the dataset's `sessions` (ids in manifest order).
    pub fn schema(sessions: &[String]) -> SchemaRef {
        with_sessions(
            vec![
                Field::new(SESSION_INDEX, DataType::UInt16, false),
                Field::new(TIME_GPS_NS, DataType::Int64, false),
                Field::new(TEMPERATURE_C[0], DataType::Float64, true),
                Field::new(TEMPERATURE_C[1], DataType::Float64, true),
                Field::new(TEMPERATURE_C[2], DataType::Float64, true),
                Field::new(STATUS, DataType::UInt8, false),
            ],
            sessions,
        )
    }
}

/// `lab.parquet`: the samples of lab loggers' "seconds" streams (docs/formats.md 8.3), decimal
/// readings in the instrument's `reading_unit`.
///
/// | column | type | unit / meaning |
/// |---|---|---|
/// | session_index | uint16 | as in acceleration.parquet |
/// | time_gps_ns | int64 | GPS time, ns (samples that shared a time stamp spread to the next) |
/// | value_ch1..3 | float64, null | the reading; null where the line gave `nan` |
/// | line | uint64 | the sample's line in its stream |
pub mod lab {
    use super::{DataType, Field, SESSION_INDEX, SchemaRef, TIME_GPS_NS, with_sessions};
    /// File name.
    pub const FILE: &str = "lab.parquet";
    /// Readings of channels 1..3.
    pub const VALUES: [&str; 3] = ["value_ch1", "value_ch2", "value_ch3"];
    /// Line in the stream.
    pub const LINE: &str = "line";
    /// The Arrow schema, for the dataset's `sessions`.
    pub fn schema(sessions: &[String]) -> SchemaRef {
        with_sessions(
            vec![
                Field::new(SESSION_INDEX, DataType::UInt16, false),
                Field::new(TIME_GPS_NS, DataType::Int64, false),
                Field::new(VALUES[0], DataType::Float64, true),
                Field::new(VALUES[1], DataType::Float64, true),
                Field::new(VALUES[2], DataType::Float64, true),
                Field::new(LINE, DataType::UInt64, false),
            ],
            sessions,
        )
    }
}

/// `theodolite.parquet`.
pub mod theodolite {
    use super::{Arc, DataType, Field, SESSION, Schema, SchemaRef, TIME_GPS_NS, session_type};
    /// File name.
    pub const FILE: &str = "theodolite.parquet";
    /// Station id.
    pub const STATION: &str = "station";
    /// Zenith distance, rad.
    pub const DZ_RAD: &str = "dz_rad";
    /// Zenith distance as read.
    pub const DZ_VALUE: &str = "dz_value";
    /// Unit as read.
    pub const DZ_UNIT: &str = "dz_unit";
    /// Time field as written.
    pub const TIME_AS_READ: &str = "time_as_read";
    /// Time scale of the log.
    pub const TIME_SCALE: &str = "time_scale";
    /// Line number in the log.
    pub const LINE: &str = "line";
    /// The Arrow schema.
    pub fn schema() -> SchemaRef {
        Arc::new(Schema::new(vec![
            Field::new(SESSION, session_type(), false),
            Field::new(STATION, DataType::Utf8, false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
            Field::new(DZ_RAD, DataType::Float64, false),
            Field::new(DZ_VALUE, DataType::Float64, false),
            Field::new(DZ_UNIT, DataType::Utf8, false),
            Field::new(TIME_AS_READ, DataType::Utf8, false),
            Field::new(TIME_SCALE, DataType::Utf8, false),
            Field::new(LINE, DataType::UInt32, false),
        ]))
    }
}

/// `observations.parquet`, written by align (OUT/align/): one row per (theodolite reading,
/// accelerometer), in session, accelerometer, time order.
///
/// | column | type | unit / meaning |
/// |---|---|---|
/// | session | utf8 (dictionary) | session id |
/// | accelerometer | utf8 (dictionary) | accelerometer id |
/// | channel | uint8 | 1..3 |
/// | station | utf8 | tilt position id |
/// | line | uint32 | line of the reading in the theodolite log |
/// | time_gps_ns | int64 | GPS time of the reading, ns |
/// | dz_rad | float64 | zenith distance, rad |
/// | sigma_dz_rad | float64 | sd of one reading at this station, rad (eq. 4) |
/// | sigma_dz_source | utf8 | `moderated`, `station_sd`, `manifest` or `resolution` ([`super::align_ledger::sigma_source`]) |
/// | sigma_dz_dof | float64, null | degrees of freedom of sigma_dz when estimated from readings (moderated: prior + own); null when taken as known |
/// | sigma_dz_loo_rad | float64 | sigma_dz of the station formed as above without this reading, rad: the reference of its w-test |
/// | sigma_dz_loo_dof | float64, null | its degrees of freedom; null when taken as known |
/// | sigma_am_mgal | float64 | g sin(Dz) sigma_Dz, mGal |
/// | ng | float64, null | mean counts in the window |
/// | sigma_ng | float64, null | sd of that mean, counts |
/// | sigma_ng_dof | float64, null | degrees of freedom of sigma_ng (the window's own sample variance, n - 1, Satterthwaite's with the coloured noise's known part); null when taken as known (the quantisation floor) |
/// | n_samples | uint32 | samples in the window |
/// | expected_samples | float64 | window_s x sample_rate_hz |
/// | temperature_c | float64, null | accelerometer temperature at the reading, degC |
/// | sigma_temperature_c | float64, null | its sd from the thermometer's noise (the session's estimate for the channel times the root of the interpolation weights' squares), degC; null when there is no temperature or no estimate |
/// | drift_t | float64, null | t statistic of a linear trend of the counts in the window |
/// | tide_mgal | float64, null | body tide at the reading's time, mGal; null when none is applied |
/// | gravity_mgal | float64 | gravity at the proof masses at the reading: g (+ tide), mGal |
/// | excluded | utf8, null | why the observation is not used; null when used |
pub mod observations {
    use super::{Arc, DataType, Field, SESSION, Schema, SchemaRef, TIME_GPS_NS, session_type};
    /// File name.
    pub const FILE: &str = "observations.parquet";
    /// Accelerometer id.
    pub const ACCELEROMETER: &str = "accelerometer";
    /// Channel 1..3.
    pub const CHANNEL: &str = "channel";
    /// Station id.
    pub const STATION: &str = "station";
    /// Line in the theodolite log.
    pub const LINE: &str = "line";
    /// Zenith distance, rad.
    pub const DZ_RAD: &str = "dz_rad";
    /// Sd of one reading, rad.
    pub const SIGMA_DZ_RAD: &str = "sigma_dz_rad";
    /// Where sigma_dz comes from.
    pub const SIGMA_DZ_SOURCE: &str = "sigma_dz_source";
    /// Degrees of freedom of sigma_dz (null: known).
    pub const SIGMA_DZ_DOF: &str = "sigma_dz_dof";
    /// sigma_dz without the reading, rad.
    pub const SIGMA_DZ_LOO_RAD: &str = "sigma_dz_loo_rad";
    /// Its degrees of freedom (null: known).
    pub const SIGMA_DZ_LOO_DOF: &str = "sigma_dz_loo_dof";
    /// Acceleration sd implied by sigma_dz, mGal.
    pub const SIGMA_AM_MGAL: &str = "sigma_am_mgal";
    /// Mean counts.
    pub const NG: &str = "ng";
    /// Sd of the mean counts.
    pub const SIGMA_NG: &str = "sigma_ng";
    /// Degrees of freedom of sigma_ng (null: known).
    pub const SIGMA_NG_DOF: &str = "sigma_ng_dof";
    /// Samples in the window.
    pub const N_SAMPLES: &str = "n_samples";
    /// Samples a full window holds.
    pub const EXPECTED_SAMPLES: &str = "expected_samples";
    /// Temperature, degC.
    pub const TEMPERATURE_C: &str = "temperature_c";
    /// Its sd from the thermometer's noise, degC.
    pub const SIGMA_TEMPERATURE_C: &str = "sigma_temperature_c";
    /// Trend t statistic.
    pub const DRIFT_T: &str = "drift_t";
    /// Body tide, mGal.
    pub const TIDE_MGAL: &str = "tide_mgal";
    /// Gravity at the reading, mGal.
    pub const GRAVITY_MGAL: &str = "gravity_mgal";
    /// Exclusion reason.
    pub const EXCLUDED: &str = "excluded";
    /// The Arrow schema.
    pub fn schema() -> SchemaRef {
        Arc::new(Schema::new(vec![
            Field::new(SESSION, session_type(), false),
            Field::new(ACCELEROMETER, session_type(), false),
            Field::new(CHANNEL, DataType::UInt8, false),
            Field::new(STATION, DataType::Utf8, false),
            Field::new(LINE, DataType::UInt32, false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
            Field::new(DZ_RAD, DataType::Float64, false),
            Field::new(SIGMA_DZ_RAD, DataType::Float64, false),
            Field::new(SIGMA_DZ_SOURCE, DataType::Utf8, false),
            Field::new(SIGMA_DZ_DOF, DataType::Float64, true),
            Field::new(SIGMA_DZ_LOO_RAD, DataType::Float64, false),
            Field::new(SIGMA_DZ_LOO_DOF, DataType::Float64, true),
            Field::new(SIGMA_AM_MGAL, DataType::Float64, false),
            Field::new(NG, DataType::Float64, true),
            Field::new(SIGMA_NG, DataType::Float64, true),
            Field::new(SIGMA_NG_DOF, DataType::Float64, true),
            Field::new(N_SAMPLES, DataType::UInt32, false),
            Field::new(EXPECTED_SAMPLES, DataType::Float64, false),
            Field::new(TEMPERATURE_C, DataType::Float64, true),
            Field::new(SIGMA_TEMPERATURE_C, DataType::Float64, true),
            Field::new(DRIFT_T, DataType::Float64, true),
            Field::new(EXCLUDED, DataType::Utf8, true),
            Field::new(TIDE_MGAL, DataType::Float64, true),
            Field::new(GRAVITY_MGAL, DataType::Float64, false),
        ]))
    }
}

/// `residuals.parquet`, written by adjust (OUT/adjust/): one row per observation and fit.
///
/// | column | type | unit / meaning |
/// |---|---|---|
/// | model | utf8 (dictionary) | model name |
/// | accelerometer | utf8 (dictionary) | accelerometer id |
/// | fit_session | utf8 (dictionary) | the fit's session id, or `all` |
/// | session | utf8 (dictionary) | the observation's session |
/// | station | utf8 | tilt position |
/// | line | uint32 | line in the theodolite log |
/// | time_gps_ns | int64 | GPS time, ns |
/// | dz_rad, sigma_dz_rad | float64 | zenith distance and its sd, rad |
/// | ng, sigma_ng | float64 | mean counts and its sd |
/// | temperature_c | float64 | degC |
/// | v_dz_rad | float64, null | residual of Dz, rad (null when removed) |
/// | v_ng | float64, null | residual of Ng, counts |
/// | residual_mgal | float64, null | condition residual B v, mGal |
/// | redundancy | float64, null | redundancy number |
/// | w | float64 | normalised residual, its Dz referred to the station's sigma_dz without it, as the normal quantile of its tail (at removal, for a removed observation) |
/// | removed | boolean | removed by data snooping |
pub mod residuals {
    use super::{Arc, DataType, Field, SESSION, Schema, SchemaRef, TIME_GPS_NS, session_type};
    /// File name.
    pub const FILE: &str = "residuals.parquet";
    /// Model name.
    pub const MODEL: &str = "model";
    /// Accelerometer id.
    pub const ACCELEROMETER: &str = "accelerometer";
    /// The fit's session id, or `all`.
    pub const FIT_SESSION: &str = "fit_session";
    /// Station id.
    pub const STATION: &str = "station";
    /// Line in the theodolite log.
    pub const LINE: &str = "line";
    /// Zenith distance, rad.
    pub const DZ_RAD: &str = "dz_rad";
    /// Its sd, rad.
    pub const SIGMA_DZ_RAD: &str = "sigma_dz_rad";
    /// Mean counts.
    pub const NG: &str = "ng";
    /// Their sd.
    pub const SIGMA_NG: &str = "sigma_ng";
    /// Temperature, degC.
    pub const TEMPERATURE_C: &str = "temperature_c";
    /// Residual of Dz, rad.
    pub const V_DZ_RAD: &str = "v_dz_rad";
    /// Residual of Ng, counts.
    pub const V_NG: &str = "v_ng";
    /// Condition residual, mGal.
    pub const RESIDUAL_MGAL: &str = "residual_mgal";
    /// Redundancy number.
    pub const REDUNDANCY: &str = "redundancy";
    /// Normalised residual.
    pub const W: &str = "w";
    /// Removed by data snooping.
    pub const REMOVED: &str = "removed";
    /// The Arrow schema.
    pub fn schema() -> SchemaRef {
        let dict = session_type;
        Arc::new(Schema::new(vec![
            Field::new(MODEL, dict(), false),
            Field::new(ACCELEROMETER, dict(), false),
            Field::new(FIT_SESSION, dict(), false),
            Field::new(SESSION, dict(), false),
            Field::new(STATION, DataType::Utf8, false),
            Field::new(LINE, DataType::UInt32, false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
            Field::new(DZ_RAD, DataType::Float64, false),
            Field::new(SIGMA_DZ_RAD, DataType::Float64, false),
            Field::new(NG, DataType::Float64, false),
            Field::new(SIGMA_NG, DataType::Float64, false),
            Field::new(TEMPERATURE_C, DataType::Float64, false),
            Field::new(V_DZ_RAD, DataType::Float64, true),
            Field::new(V_NG, DataType::Float64, true),
            Field::new(RESIDUAL_MGAL, DataType::Float64, true),
            Field::new(REDUNDANCY, DataType::Float64, true),
            Field::new(W, DataType::Float64, false),
            Field::new(REMOVED, DataType::Boolean, false),
        ]))
    }
}

/// `OUT/apply/acceleration.parquet` (docs/formats.md 8.5): the survey's samples calibrated, one
/// row per row of ingest's acceleration table, in its order; per accelerometer four columns
/// named after its id.
///
/// | column | type | unit / meaning |
/// |---|---|---|
/// | session_index | uint16 | as in ingest's tables (ids in `gravcal.sessions`) |
/// | time_gps_ns | int64 | GPS time, ns |
/// | `<id>_acceleration_mgal` | float64, null | specific force along the axis, c(Ng, T), mGal; null when `<id>_flags` has a bit of [`applied::NO_VALUE`] |
/// | `<id>_sigma_mgal` | float64, null | its sd from the calibration's covariance, mGal |
/// | `<id>_temperature_c` | float64, null | the temperature used (interpolated as align does), degC |
/// | `<id>_flags` | uint8 | the bits of [`applied`]'s flags, or-ed |
///
/// With a triad model the table has instead the vector `triad_x/y/z_mgal` in the body frame,
/// the six elements of its covariance `triad_cov_xx..zz_mgal2`, and `triad_flags`.
pub mod applied {
    use super::{
        Arc, DataType, Field, SESSION_INDEX, Schema, SchemaRef, TIME_GPS_NS, with_sessions,
    };
    /// File name.
    pub const FILE: &str = "acceleration.parquet";
    /// Schema metadata key holding the accelerometer ids, in column order, as a JSON array.
    pub const ACCELEROMETERS_METADATA: &str = "gravcal.accelerometers";

    /// Counts outside the range the calibration saw (the value is given, extrapolated).
    pub const COUNTS_OUT_OF_RANGE: u8 = 1;
    /// Temperature outside the calibration's (the value is given, extrapolated).
    pub const TEMPERATURE_OUT_OF_RANGE: u8 = 2;
    /// The model has temperature terms and no temperature lies within the gap limit: no value.
    pub const NO_TEMPERATURE: u8 = 4;
    /// The channel was over range (saturated): no value.
    pub const SATURATED: u8 = 8;
    /// The channel was not connected: no value.
    pub const NOT_CONNECTED: u8 = 16;
    /// The model has no result for this accelerometer (apply.json says why): no value.
    pub const NOT_CALIBRATED: u8 = 32;
    /// The flags that leave a sample without a value.
    pub const NO_VALUE: u8 = NO_TEMPERATURE | SATURATED | NOT_CONNECTED | NOT_CALIBRATED;
    /// Every flag with its name in apply.json, in bit order.
    pub const FLAG_NAMES: [(u8, &str); 6] = [
        (COUNTS_OUT_OF_RANGE, "counts_out_of_range"),
        (TEMPERATURE_OUT_OF_RANGE, "temperature_out_of_range"),
        (NO_TEMPERATURE, "no_temperature"),
        (SATURATED, "saturated"),
        (NOT_CONNECTED, "not_connected"),
        (NOT_CALIBRATED, "not_calibrated"),
    ];

    /// A triad model's columns: the calibrated vector in the body frame (mGal), the six
    /// elements of its covariance (mGal^2), and the flags.
    pub const TRIAD_COLUMNS: [&str; 10] = [
        "triad_x_mgal",
        "triad_y_mgal",
        "triad_z_mgal",
        "triad_cov_xx_mgal2",
        "triad_cov_xy_mgal2",
        "triad_cov_xz_mgal2",
        "triad_cov_yy_mgal2",
        "triad_cov_yz_mgal2",
        "triad_cov_zz_mgal2",
        "triad_flags",
    ];

    /// The Arrow schema of a triad model's table, for the dataset's `sessions`.
    pub fn triad_schema(sessions: &[String]) -> SchemaRef {
        let mut fields = vec![
            Field::new(SESSION_INDEX, DataType::UInt16, false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
        ];
        for name in &TRIAD_COLUMNS[..9] {
            fields.push(Field::new(*name, DataType::Float64, true));
        }
        fields.push(Field::new(TRIAD_COLUMNS[9], DataType::UInt8, false));
        with_sessions(fields, sessions)
    }

    /// The four column names of accelerometer `id`: acceleration, sigma, temperature, flags.
    pub fn columns(id: &str) -> [String; 4] {
        [
            format!("{id}_acceleration_mgal"),
            format!("{id}_sigma_mgal"),
            format!("{id}_temperature_c"),
            format!("{id}_flags"),
        ]
    }

    /// The Arrow schema for the dataset's `sessions` and the accelerometers `ids`.
    pub fn schema(sessions: &[String], ids: &[String]) -> SchemaRef {
        let mut fields = vec![
            Field::new(SESSION_INDEX, DataType::UInt16, false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
        ];
        for id in ids {
            let [a, s, t, f] = columns(id);
            fields.extend([
                Field::new(a, DataType::Float64, true),
                Field::new(s, DataType::Float64, true),
                Field::new(t, DataType::Float64, true),
                Field::new(f, DataType::UInt8, false),
            ]);
        }
        let schema = with_sessions(fields, sessions);
        let ids = serde_json::to_string(ids).expect("strings serialise");
        let mut metadata = schema.metadata().clone();
        metadata.insert(ACCELEROMETERS_METADATA.to_owned(), ids);
        Arc::new(Schema::new_with_metadata(schema.fields().clone(), metadata))
    }
}

/// `OUT/gravity/gravity.parquet` (docs/formats.md 10.3): one row per trajectory epoch used,
/// in time order per session.
///
/// | column | type | unit / meaning |
/// |---|---|---|
/// | session_index | uint16 | as in ingest's tables (ids in `gravcal.sessions`) |
/// | time_gps_ns | int64 | GPS time of the epoch, ns |
/// | stretch | uint32 | the stretch of track (cut at gaps) the epoch belongs to, from 0 per session |
/// | latitude_deg, longitude_deg | float64 | the accelerometers' position, deg |
/// | height_m | float64 | their ellipsoidal height (the antenna's with the lever arm), m |
/// | speed_m_s | float64 | speed over ground, m/s |
/// | eotvos_mgal, normal_mgal | float64 | the Eotvos term and normal gravity (`[survey] normal_gravity`'s ellipsoid), mGal |
/// | tide_mgal | float64 | the body tide's effect on gravity, removed (0 with `earth_tide = false`), mGal |
/// | cross_coupling_mgal | float64 | a platform meter's cross-coupling correction, added (0 without `cross_coupling`), mGal |
/// | down_mgal | float64 | the gravity disturbance down, unfiltered (ties applied), mGal |
/// | down_filtered_mgal | float64 | the same after the low-pass filter, mGal; NaN within a filter period of its stretch's ends (flag 4), as its sigma and parts, north's and east's |
/// | sigma_down_mgal | float64 | the filtered value's sigma: the six below in quadrature, mGal |
/// | sigma_calibration_mgal, sigma_positions_mgal, sigma_noise_mgal, sigma_tie_mgal, sigma_attitude_mgal, sigma_coupling_mgal | float64 | its parts, mGal (the attitude's 0 without attitude, the cross-coupling's without a fitted correction) |
/// | height_antenna_m | float64 | the antenna's height as the trajectory gives it, m |
/// | north_mgal, north_filtered_mgal, sigma_north_mgal | float64, null without attitude | the disturbance north, unfiltered and filtered, and the filtered value's sigma: the four below in quadrature |
/// | sigma_north_calibration_mgal, sigma_north_positions_mgal, sigma_north_noise_mgal, sigma_north_attitude_mgal | float64, null without attitude | its parts |
/// | east_... | float64, null without attitude | the same seven east |
/// | flags | uint8 | the bits of this module's flags, or-ed |
/// | meter_status | uint32, null | a platform meter's status word at the epoch (its lines' within half an epoch interval, or-ed; docs/formats.md 11.1), null where the session's samples carry none |
pub mod gravity {
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
}

/// `OUT/gravity/attitude.parquet` (docs/formats.md 10.2.1): the attitude an antenna array
/// gives, one row per epoch solved, in time order per session:
///
/// | column | type | unit / meaning |
/// |---|---|---|
/// | session_index | uint16 | as in ingest's tables (ids in `gravcal.sessions`) |
/// | time_gps_ns | int64 | GPS time of the epoch, ns |
/// | heading_deg, pitch_deg, roll_deg | float64 | C_v^n = Rz(heading) Ry(pitch) Rx(roll), deg |
/// | sd_heading_deg, sd_pitch_deg, sd_roll_deg | float64 | their sds, deg |
/// | corr_heading_pitch, corr_heading_roll, corr_pitch_roll | float64 | their correlations |
///
/// A value the array does not give is null: two antennas' roll, its sd and correlations
/// (gravity.json's `antennas.not_given` says why).
/// | antennas_used | uint32 | bit k: the session's k-th antenna in the fit |
/// | antennas_set_aside | uint32 | bit k: set aside, its baselines' lengths off |
pub mod attitude {
    use super::{DataType, Field, SESSION_INDEX, SchemaRef, TIME_GPS_NS, with_sessions};
    /// File name.
    pub const FILE: &str = "attitude.parquet";
    /// The Float64 columns after session_index and time_gps_ns, in order.
    pub const FLOATS: [&str; 9] = [
        "heading_deg",
        "pitch_deg",
        "roll_deg",
        "sd_heading_deg",
        "sd_pitch_deg",
        "sd_roll_deg",
        "corr_heading_pitch",
        "corr_heading_roll",
        "corr_pitch_roll",
    ];
    /// The antennas' masks, after [`FLOATS`].
    pub const MASKS: [&str; 2] = ["antennas_used", "antennas_set_aside"];

    /// The Arrow schema for the dataset's `sessions`.
    pub fn schema(sessions: &[String]) -> SchemaRef {
        let mut fields = vec![
            Field::new(SESSION_INDEX, DataType::UInt16, false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
        ];
        for name in FLOATS {
            fields.push(Field::new(name, DataType::Float64, true));
        }
        for name in MASKS {
            fields.push(Field::new(name, DataType::UInt32, false));
        }
        with_sessions(fields, sessions)
    }
}
