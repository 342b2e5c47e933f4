//! `acceleration.parquet`.

use super::{DataType, Field, GroupWriter, SESSION_INDEX, STATUS, SchemaRef, TIME_GPS_NS};
use crate::parquet_io::table::{
    ColumnTableWriter, ColumnValues, Encodings, INGEST_GROUPS_PER_SYNC,
};
/// File name.
pub const FILE: &str = "acceleration.parquet";
/// Counts of channels 1..3.
pub const COUNTS: [&str; 3] = ["counts_ch1", "counts_ch2", "counts_ch3"];
/// The Arrow schema, for the dataset's `sessions` (ids in manifest order).
pub fn schema(sessions: &[String]) -> SchemaRef {
    let status = Field::new(STATUS, DataType::UInt8, false);
    super::three_channels(COUNTS, DataType::Int32, status, sessions)
}

/// One batch of the acceleration table, as stored: per row the session index, GPS time
/// (ns), the counts of channels 1..3 (null where not connected or over range) and the status.
pub struct Batch<'a> {
    /// Session index per row.
    pub session: &'a [u16],
    /// GPS time per row, ns.
    pub time_ns: &'a [i64],
    /// Counts of channels 1..3.
    pub counts: [&'a arrow_array::Int32Array; 3],
    /// Status bits per row.
    pub status: &'a [u8],
}

/// Streams `dir`'s acceleration table in file order, a batch of `batch_rows` rows at a time.
/// The callback stops with an error of its own, `E`, into which the table's convert.
pub fn batches<E: From<crate::Error>>(
    dir: &std::path::Path,
    batch_rows: usize,
    mut f: impl FnMut(Batch<'_>) -> Result<(), E>,
) -> Result<(), E> {
    use super::read::{batches_of, column, session_and_time};
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Int32Type, UInt8Type};
    let path = dir.join(FILE);
    for b in batches_of(&path, batch_rows)? {
        let b = b?;
        let (session, time) = session_and_time(&path, &b)?;
        let status = column(&path, &b, STATUS, &DataType::UInt8)?
            .as_primitive::<UInt8Type>()
            .values();
        let c: Vec<_> = COUNTS
            .iter()
            .map(|n| column(&path, &b, n, &DataType::Int32).map(|c| c.as_primitive::<Int32Type>()))
            .collect::<crate::Result<Vec<_>>>()?;
        f(Batch {
            session,
            time_ns: time,
            counts: [c[0], c[1], c[2]],
            status,
        })?;
    }
    Ok(())
}

/// Streams `dir`'s acceleration table in file order, a row at a time:
/// `f(session index, time_ns, counts, status)`.
pub fn for_each(
    dir: &std::path::Path,
    mut f: impl FnMut(u16, i64, [Option<i32>; 3], u8),
) -> crate::Result<()> {
    use arrow_array::Array;
    batches(dir, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            let counts = b.counts.map(|c| c.is_valid(i).then(|| c.value(i)));
            f(b.session[i], b.time_ns[i], counts, b.status[i]);
        }
        Ok(())
    })
}

/// A row group of the table, a field per column.
pub struct RowGroup {
    /// Session index per row (UInt16, stored as INT32).
    pub session_index: Vec<i32>,
    /// GPS time per row, ns.
    pub time_gps_ns: Vec<i64>,
    /// Counts of channels 1..3, null where not connected or over range.
    pub counts: [super::Nullable<i32>; 3],
    /// Status bits per row (UInt8, stored as INT32).
    pub status: Vec<i32>,
}

impl super::RowGroup for RowGroup {
    type Name = &'static str;
    fn rows(&self) -> usize {
        self.time_gps_ns.len()
    }
    fn named(self) -> Vec<(&'static str, ColumnValues)> {
        let [c1, c2, c3] = self.counts;
        vec![
            (SESSION_INDEX, ColumnValues::Int32(self.session_index, None)),
            (TIME_GPS_NS, ColumnValues::Int64(self.time_gps_ns, None)),
            (COUNTS[0], ColumnValues::Int32(c1.0, c1.1)),
            (COUNTS[1], ColumnValues::Int32(c2.0, c2.1)),
            (COUNTS[2], ColumnValues::Int32(c3.0, c3.1)),
            (STATUS, ColumnValues::Int32(self.status, None)),
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
        // Measured on a 250 Hz day (`cargo run --release -p ingest --example encodings`):
        // the counts cost least delta-encoded and not compressed. Session and status, nearly
        // constant, are delta-encoded too, by ingest's own encoder
        // (`table::encode_delta_column`), which costs less than parquet-rs's plain encoding
        // and zstd on 4 bytes a row; zstd then shrinks them to almost nothing.
        Encodings {
            delta: &[SESSION_INDEX, COUNTS[0], COUNTS[1], COUNTS[2], STATUS],
            uncompressed: &COUNTS,
            no_statistics: &COUNTS,
            ..Encodings::default()
        },
    )?
    .one_column_at_a_time()
    .sync_every(INGEST_GROUPS_PER_SYNC);
    Ok(GroupWriter::new(table))
}
