//! `lab.parquet`: the samples of lab loggers' "seconds" streams (docs/formats.md 8.3), decimal
//! readings in the instrument's `reading_unit`.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session_index | uint16 | as in acceleration.parquet |
//! | time_gps_ns | int64 | GPS time, ns (samples that shared a time stamp spread to the next) |
//! | value_ch1..3 | float64, null | the reading; null where the line gave `nan` |
//! | line | uint64 | the sample's line in its stream |

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
