//! `OUT/apply/acceleration.parquet` (docs/formats.md 8.5): the survey's samples calibrated, one
//! row per row of ingest's acceleration table, in its order; per accelerometer four columns
//! named after its id.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session_index | uint16 | as in ingest's tables (ids in `gravcal.sessions`) |
//! | time_gps_ns | int64 | GPS time, ns |
//! | `<id>_acceleration_mgal` | float64, null | specific force along the axis, c(Ng, T), mGal; null when `<id>_flags` has a bit of [`applied::NO_VALUE`] |
//! | `<id>_sigma_mgal` | float64, null | its sd from the calibration's covariance, mGal |
//! | `<id>_temperature_c` | float64, null | the temperature used (interpolated as align does), degC |
//! | `<id>_flags` | uint8 | the bits of [`applied`]'s flags, or-ed |
//!
//! With a triad model the table has instead the vector `triad_x/y/z_mgal` in the body frame,
//! the six elements of its covariance `triad_cov_xx..zz_mgal2`, and `triad_flags`.

use super::{Arc, DataType, Field, SESSION_INDEX, Schema, SchemaRef, TIME_GPS_NS, with_sessions};
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
