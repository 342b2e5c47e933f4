//! `lab.parquet`: the samples of lab loggers' "seconds" streams (docs/formats.md 8.3), decimal
//! readings in the instrument's `reading_unit`.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session_index | uint16 | as in acceleration.parquet |
//! | time_gps_ns | int64 | GPS time, ns (samples that shared a time stamp spread to the next) |
//! | value_ch1..3 | float64, null | the reading; null where the line gave `nan` |
//! | line | uint64 | the sample's line in its stream |

use super::{DataType, Field, GroupWriter, SESSION_INDEX, SchemaRef};
use crate::parquet_io::table::Encodings;
/// File name.
pub const FILE: &str = "lab.parquet";
/// A row group of the table: its channels are [`VALUES`], its last column `line`.
pub type RowGroup = super::StreamRows<f64, i64>;
/// Readings of channels 1..3.
pub const VALUES: [&str; 3] = ["value_ch1", "value_ch2", "value_ch3"];
/// Line in the stream.
pub const LINE: &str = "line";
/// The Arrow schema, for the dataset's `sessions`.
pub fn schema(sessions: &[String]) -> SchemaRef {
    let line = Field::new(LINE, DataType::UInt64, false);
    super::three_channels(VALUES, DataType::Float64, line, sessions)
}

/// Starts the table in `dir` for the dataset's `sessions`, as ingest writes its streams
/// ([`super::write::stream_writer`]).
pub fn writer(dir: &std::path::Path, sessions: &[String]) -> crate::Result<GroupWriter<RowGroup>> {
    super::write::stream_writer(
        dir,
        (FILE, schema(sessions), (VALUES, LINE)),
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
    )
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
    use super::read::{floats, stream_batches};
    let path = dir.join(FILE);
    stream_batches(&path, batch_rows, |b, session, time_ns| {
        let v: Vec<_> = VALUES
            .iter()
            .map(|n| floats(&path, b, n))
            .collect::<crate::Result<Vec<_>>>()?;
        f(Batch {
            session,
            time_ns,
            values: [v[0], v[1], v[2]],
        })
    })
}
