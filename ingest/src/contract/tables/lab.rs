//! `lab.parquet`: the samples of lab loggers' "seconds" streams (docs/formats.md 8.3), decimal
//! readings in the instrument's `reading_unit`.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session_index | uint16 | as in acceleration.parquet |
//! | time_gps_ns | int64 | GPS time, ns (samples that shared a time stamp spread to the next) |
//! | value_ch1..3 | float64, null | the reading; null where the line gave `nan` |
//! | line | uint64 | the sample's line in its stream |

use super::{DataType, Field, GroupWriter, SESSION_INDEX, SchemaRef, TIME_GPS_NS};
use crate::parquet_io::table::{
    ColumnTableWriter, ColumnValues, Encodings, INGEST_GROUPS_PER_SYNC,
};
/// File name.
pub const FILE: &str = "lab.parquet";
/// Readings of channels 1..3.
pub const VALUES: [&str; 3] = ["value_ch1", "value_ch2", "value_ch3"];
/// Line in the stream.
pub const LINE: &str = "line";
/// The Arrow schema, for the dataset's `sessions`.
pub fn schema(sessions: &[String]) -> SchemaRef {
    let line = Field::new(LINE, DataType::UInt64, false);
    super::three_channels(VALUES, DataType::Float64, line, sessions)
}

/// A row group of the table, a field per column.
pub struct RowGroup {
    /// Session index per row (UInt16, stored as INT32).
    pub session_index: Vec<i32>,
    /// GPS time per row, ns.
    pub time_gps_ns: Vec<i64>,
    /// Readings of channels 1..3, null where the line gave `nan`.
    pub values: [super::Nullable<f64>; 3],
    /// Line in the stream per row (UInt64, stored as INT64).
    pub line: Vec<i64>,
}

impl super::RowGroup for RowGroup {
    type Name = &'static str;
    fn rows(&self) -> usize {
        self.time_gps_ns.len()
    }
    fn named(self) -> Vec<(&'static str, ColumnValues)> {
        let [v1, v2, v3] = self.values;
        vec![
            (SESSION_INDEX, ColumnValues::Int32(self.session_index, None)),
            (TIME_GPS_NS, ColumnValues::Int64(self.time_gps_ns, None)),
            (VALUES[0], ColumnValues::Double(v1.0, v1.1)),
            (VALUES[1], ColumnValues::Double(v2.0, v2.1)),
            (VALUES[2], ColumnValues::Double(v3.0, v3.1)),
            (LINE, ColumnValues::Int64(self.line, None)),
        ]
    }
}

/// Starts the table in `dir` for the dataset's `sessions`, written as ingest writes it:
/// one column after another on the writer's thread, synced every few row groups.
pub fn writer(dir: &std::path::Path, sessions: &[String]) -> crate::Result<GroupWriter<RowGroup>> {
    let table = ColumnTableWriter::create(
        dir,
        FILE,
        schema(sessions),
        // Chosen by measurement (`cargo xtask bench ingest`, docs/benchmarks.md): the
        // session, time and line columns by ingest's own delta encoder; the readings split
        // by byte stream, which lets a compressor find what their high bytes share,
        // compressed with LZ4 (zstd cost 9 % more of the run's CPU, for a table 27 %
        // smaller), and without min/max statistics (a tenth of their writing, and nobody
        // filters on them).
        Encodings {
            delta: &[SESSION_INDEX, LINE],
            byte_stream_split: &VALUES,
            lz4: &VALUES,
            no_statistics: &VALUES,
            ..Encodings::default()
        },
    )?
    .one_column_at_a_time()
    .sync_every(INGEST_GROUPS_PER_SYNC);
    Ok(GroupWriter::new(table))
}

/// One batch of the lab table: per row the session index, GPS time (ns), and the readings
/// of channels 1..3 (null where the line gave `nan`).
pub struct Batch<'a> {
    /// Session index per row.
    pub session: &'a [u16],
    /// GPS time per row, ns.
    pub time_ns: &'a [i64],
    /// Readings of channels 1..3.
    pub values: [&'a arrow_array::Float64Array; 3],
}

/// Streams `dir`'s lab table in file order, a batch of `batch_rows` rows at a time.
/// The callback stops with an error of its own, `E`, into which the table's convert.
pub fn batches<E: From<crate::Error>>(
    dir: &std::path::Path,
    batch_rows: usize,
    mut f: impl FnMut(Batch<'_>) -> Result<(), E>,
) -> Result<(), E> {
    use super::read::{batches_of, floats, session_and_time};
    let path = dir.join(FILE);
    for b in batches_of(&path, batch_rows)? {
        let b = b?;
        let (session, time) = session_and_time(&path, &b)?;
        let v: Vec<_> = VALUES
            .iter()
            .map(|n| floats(&path, &b, n))
            .collect::<crate::Result<Vec<_>>>()?;
        f(Batch {
            session,
            time_ns: time,
            values: [v[0], v[1], v[2]],
        })?;
    }
    Ok(())
}
