//! `temperature.parquet`.

use super::{DataType, Field, GroupWriter, STATUS, SchemaRef};
use crate::parquet_io::table::Encodings;
/// File name.
pub const FILE: &str = "temperature.parquet";
/// A row group of the table: its channels are [`TEMPERATURE_C`], its last column `status`.
pub type RowGroup = super::StreamRows<f64, i32>;
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

/// Starts the table in `dir` for the dataset's `sessions`, as ingest writes its streams
/// ([`super::write::stream_writer`]).
pub fn writer(dir: &std::path::Path, sessions: &[String]) -> crate::Result<GroupWriter<RowGroup>> {
    let names = (TEMPERATURE_C, STATUS);
    super::write::stream_writer(dir, (FILE, schema(sessions), names), Encodings::default())
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
