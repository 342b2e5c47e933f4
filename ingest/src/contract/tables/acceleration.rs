//! `acceleration.parquet`.

use super::{DataType, Field, GroupWriter, SESSION_INDEX, STATUS, SchemaRef};
use crate::parquet_io::table::Encodings;
/// File name.
pub const FILE: &str = "acceleration.parquet";
/// A row group of the table: its channels are [`COUNTS`], its last column `status`.
pub type RowGroup = super::StreamRows<i32, i32>;
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
    use super::read::{column, stream_batches};
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Int32Type, UInt8Type};
    let path = dir.join(FILE);
    stream_batches(&path, batch_rows, |b, session, time_ns| {
        let status = column(&path, b, STATUS, &DataType::UInt8)?
            .as_primitive::<UInt8Type>()
            .values();
        let c: Vec<_> = COUNTS
            .iter()
            .map(|n| column(&path, b, n, &DataType::Int32).map(|c| c.as_primitive::<Int32Type>()))
            .collect::<crate::Result<Vec<_>>>()?;
        f(Batch {
            session,
            time_ns,
            counts: [c[0], c[1], c[2]],
            status,
        })
    })
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

/// Starts the table in `dir` for the dataset's `sessions`, as ingest writes its streams
/// ([`super::write::stream_writer`]).
pub fn writer(dir: &std::path::Path, sessions: &[String]) -> crate::Result<GroupWriter<RowGroup>> {
    super::write::stream_writer(
        dir,
        (FILE, schema(sessions), (COUNTS, STATUS)),
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
    )
}
