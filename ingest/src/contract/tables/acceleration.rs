//! `acceleration.parquet`.

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
