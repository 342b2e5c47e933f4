//! `temperature.parquet`.

use super::{DataType, Field, GroupWriter, SESSION_INDEX, STATUS, SchemaRef, TIME_GPS_NS};
use crate::parquet_io::table::{
    ColumnTableWriter, ColumnValues, Encodings, INGEST_GROUPS_PER_SYNC,
};
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
    let status = Field::new(STATUS, DataType::UInt8, false);
    super::three_channels(TEMPERATURE_C, DataType::Float64, status, sessions)
}

/// A row group of the table, a field per column.
pub struct RowGroup {
    /// Session index per row (UInt16, stored as INT32).
    pub session_index: Vec<i32>,
    /// GPS time per row, ns.
    pub time_gps_ns: Vec<i64>,
    /// Temperatures of channels 1..3, degC, null where not connected.
    pub temperature_c: [super::Nullable<f64>; 3],
    /// Status bits per row (UInt8, stored as INT32).
    pub status: Vec<i32>,
}

impl super::RowGroup for RowGroup {
    type Name = &'static str;
    fn rows(&self) -> usize {
        self.time_gps_ns.len()
    }
    fn named(self) -> Vec<(&'static str, ColumnValues)> {
        let [t1, t2, t3] = self.temperature_c;
        vec![
            (SESSION_INDEX, ColumnValues::Int32(self.session_index, None)),
            (TIME_GPS_NS, ColumnValues::Int64(self.time_gps_ns, None)),
            (TEMPERATURE_C[0], ColumnValues::Double(t1.0, t1.1)),
            (TEMPERATURE_C[1], ColumnValues::Double(t2.0, t2.1)),
            (TEMPERATURE_C[2], ColumnValues::Double(t3.0, t3.1)),
            (STATUS, ColumnValues::Int32(self.status, None)),
        ]
    }
}

/// Starts the table in `dir` for the dataset's `sessions`, written as ingest writes it:
/// one column after another on the writer's thread, synced every few row groups.
pub fn writer(dir: &std::path::Path, sessions: &[String]) -> crate::Result<GroupWriter<RowGroup>> {
    let table = ColumnTableWriter::create(dir, FILE, schema(sessions), Encodings::default())?
        .one_column_at_a_time()
        .sync_every(INGEST_GROUPS_PER_SYNC);
    Ok(GroupWriter::new(table))
}

/// Temperature series per (session index, channel 1..3): times (ns) and degC, non-null
/// samples only.
pub type Temperatures = std::collections::BTreeMap<(u16, u8), (Vec<i64>, Vec<f64>)>;

/// `dir`'s temperature table, by session and channel.
pub fn read(dir: &std::path::Path) -> crate::Result<Temperatures> {
    use super::read::{batches_of, floats, session_and_time};
    use arrow_array::Array;
    let path = dir.join(FILE);
    let mut out = Temperatures::new();
    for b in batches_of(&path, 1 << 16)? {
        let b = b?;
        let (session, time) = session_and_time(&path, &b)?;
        for (ch, name) in (1u8..).zip(TEMPERATURE_C) {
            let v = floats(&path, &b, name)?;
            for i in 0..b.num_rows() {
                if v.is_valid(i) {
                    let e = out.entry((session[i], ch)).or_default();
                    e.0.push(time[i]);
                    e.1.push(v.value(i));
                }
            }
        }
    }
    Ok(out)
}
