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

use super::{
    Arc, DataType, Field, GroupWriter, Nullable, SESSION_INDEX, Schema, SchemaRef, TIME_GPS_NS,
    with_sessions,
};
use crate::parquet_io::table::{ColumnTableWriter, ColumnValues, Encodings};
use std::path::Path;
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

/// One accelerometer's four columns of a row group.
pub struct Accelerometer {
    /// Its id: the columns' names follow from it ([`columns`]).
    pub id: String,
    /// Specific force along the axis, mGal, null where there is none.
    pub acceleration_mgal: Nullable<f64>,
    /// Its sd, mGal, null where the acceleration is.
    pub sigma_mgal: Nullable<f64>,
    /// The temperature used, degC, null where there was none.
    pub temperature_c: Nullable<f64>,
    /// Flags per row (UInt8, stored as INT32).
    pub flags: Vec<i32>,
}

/// A row group of the table, a field per column.
pub struct RowGroup {
    /// Session index per row (UInt16, stored as INT32).
    pub session_index: Vec<i32>,
    /// GPS time per row, ns.
    pub time_gps_ns: Vec<i64>,
    /// The accelerometers' columns, in the table's order.
    pub accelerometers: Vec<Accelerometer>,
}

impl super::RowGroup for RowGroup {
    type Name = String;
    /// Each accelerometer's id comes with its columns.
    type Names = ();
    fn rows(&self) -> usize {
        self.time_gps_ns.len()
    }
    fn named(self, (): &()) -> Vec<(String, ColumnValues)> {
        let mut named = vec![
            (
                SESSION_INDEX.to_owned(),
                ColumnValues::Int32(self.session_index, None),
            ),
            (
                TIME_GPS_NS.to_owned(),
                ColumnValues::Int64(self.time_gps_ns, None),
            ),
        ];
        for a in self.accelerometers {
            let [acc, sigma, temp, flags] = columns(&a.id);
            let (acc_values, acc_levels) = a.acceleration_mgal;
            let (sigma_values, sigma_levels) = a.sigma_mgal;
            let (temp_values, temp_levels) = a.temperature_c;
            named.extend([
                (acc, ColumnValues::Double(acc_values, acc_levels)),
                (sigma, ColumnValues::Double(sigma_values, sigma_levels)),
                (temp, ColumnValues::Double(temp_values, temp_levels)),
                (flags, ColumnValues::Int32(a.flags, None)),
            ]);
        }
        named
    }
}

/// Starts the table in `dir` for the dataset's `sessions` and the accelerometers `ids`,
/// with the encodings chosen by measurement on the 250 Hz benchmark day (`cargo xtask
/// bench apply`).
pub fn writer(
    dir: &Path,
    sessions: &[String],
    ids: &[String],
) -> crate::Result<GroupWriter<RowGroup>> {
    let names: Vec<[String; 4]> = ids.iter().map(|id| columns(id)).collect();
    let mut delta: Vec<&str> = vec![SESSION_INDEX, TIME_GPS_NS];
    delta.extend(names.iter().map(|c| c[3].as_str()));
    // The acceleration and its sigma vary in their low bytes only, so split into byte
    // streams zstd shrinks them where plain it gained a fifth.
    let split: Vec<&str> = names
        .iter()
        .flat_map(|c| [c[0].as_str(), c[1].as_str()])
        .collect();
    // Nobody filters on a sigma: its min/max statistics were a twentieth of the time.
    let sigmas: Vec<&str> = names.iter().map(|c| c[1].as_str()).collect();
    let table = ColumnTableWriter::create(
        dir,
        FILE,
        schema(sessions, ids),
        Encodings {
            delta: &delta,
            byte_stream_split: &split,
            no_statistics: &sigmas,
            ..Encodings::default()
        },
    )?;
    Ok(GroupWriter::new(table, ()))
}

/// A row group of a triad model's table, a field per column.
pub struct TriadRowGroup {
    /// Session index per row (UInt16, stored as INT32).
    pub session_index: Vec<i32>,
    /// GPS time per row, ns.
    pub time_gps_ns: Vec<i64>,
    /// The vector's x, y and z in the body frame, mGal, null where there is none.
    pub vector_mgal: [Nullable<f64>; 3],
    /// Its covariance's xx, xy, xz, yy, yz, zz, mGal^2, null where the vector is.
    pub covariance_mgal2: [Nullable<f64>; 6],
    /// Flags per row (UInt8, stored as INT32).
    pub flags: Vec<i32>,
}

impl super::RowGroup for TriadRowGroup {
    type Name = &'static str;
    /// The names are [`TRIAD_COLUMNS`].
    type Names = ();
    fn rows(&self) -> usize {
        self.time_gps_ns.len()
    }
    fn named(self, (): &()) -> Vec<(&'static str, ColumnValues)> {
        let mut named = vec![
            (SESSION_INDEX, ColumnValues::Int32(self.session_index, None)),
            (TIME_GPS_NS, ColumnValues::Int64(self.time_gps_ns, None)),
        ];
        let floats = self.vector_mgal.into_iter().chain(self.covariance_mgal2);
        for (&name, (values, levels)) in TRIAD_COLUMNS[..9].iter().zip(floats) {
            named.push((name, ColumnValues::Double(values, levels)));
        }
        named.push((TRIAD_COLUMNS[9], ColumnValues::Int32(self.flags, None)));
        named
    }
}

/// Starts a triad model's table in `dir` for the dataset's `sessions`.
pub fn triad_writer(dir: &Path, sessions: &[String]) -> crate::Result<GroupWriter<TriadRowGroup>> {
    let names = TRIAD_COLUMNS;
    let table = ColumnTableWriter::create(
        dir,
        FILE,
        triad_schema(sessions),
        Encodings {
            delta: &[SESSION_INDEX, TIME_GPS_NS, names[9]],
            byte_stream_split: &names[..9],
            ..Encodings::default()
        },
    )?;
    Ok(GroupWriter::new(table, ()))
}
