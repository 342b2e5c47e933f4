//! Row-group buffers the sample-stream writers share (`streams` for acceleration and
//! temperature, `labstream` for lab loggers' streams): a row group's columns as arrays of
//! [`STREAM_ROWS_PER_GROUP`] values filled in place, and the buffers of written row groups
//! kept for the next ones.

use crate::parquet_io::table::{ColumnValues, STREAM_ROWS_PER_GROUP};

/// Rows of a stream row group.
pub(crate) const N: usize = STREAM_ROWS_PER_GROUP;

/// A row group's array from a buffer of a written one (or a new one); what it holds is
/// overwritten before it is read.
pub(crate) fn whole<T: Copy + Default>(mut v: Vec<T>) -> Box<[T; N]> {
    if v.capacity() == 0 {
        // A new one zeroed by the allocator: its pages are mapped as they are written, so
        // a table that is never written to (no lab stream in the dataset) costs no memory.
        v = vec![T::default(); N];
    }
    // A buffer back from the writer holds N values already: nothing to fill.
    v.resize(N, T::default());
    v.into_boxed_slice()
        .try_into()
        .unwrap_or_else(|_| unreachable!("resized to N"))
}

/// The first `n` values of a row group's array, as a column.
pub(crate) fn column<T>(values: Box<[T; N]>, n: usize) -> Vec<T> {
    let mut v = (values as Box<[T]>).into_vec();
    v.truncate(n);
    v
}

/// A nullable column from all its values and their validity: the non-null values and the
/// definition levels (none if every value is valid).
pub(crate) fn nullable<T: Copy>(values: Vec<T>, valid: &[bool]) -> (Vec<T>, Option<Vec<i16>>) {
    if valid.iter().all(|&v| v) {
        return (values, None);
    }
    let levels = valid.iter().map(|&v| i16::from(v)).collect();
    let kept = values
        .into_iter()
        .zip(valid)
        .filter_map(|(x, &v)| v.then_some(x))
        .collect();
    (kept, Some(levels))
}

/// The session index of `n` rows, stored as Parquet INT32 (UInt16 in the Arrow schema), in
/// `buf` (whatever it held).
pub(crate) fn session_values(session: u16, n: usize, mut buf: Vec<i32>) -> Vec<i32> {
    buf.clear();
    buf.resize(n, i32::from(session));
    buf
}

/// Buffers of written row groups, as they came back, for the next ones: fresh buffers for
/// every row group cost a page fault per 4 KiB written to them.
#[derive(Default)]
pub(crate) struct Spare {
    int32: Vec<Vec<i32>>,
    int64: Vec<Vec<i64>>,
    double: Vec<Vec<f64>>,
}

impl Spare {
    /// At most this many buffers of each kind are kept: a row group's worth for each queued
    /// and each written group.
    const KEEP: usize = 24;

    /// Keeps the buffers of a written row group, as they are (callers clear or overwrite).
    pub(crate) fn keep(&mut self, columns: Vec<ColumnValues>) {
        fn put<T>(pool: &mut Vec<Vec<T>>, v: Vec<T>) {
            if pool.len() < Spare::KEEP && v.capacity() >= N {
                pool.push(v);
            }
        }
        for c in columns {
            match c {
                ColumnValues::Int32(v, _) => put(&mut self.int32, v),
                ColumnValues::Int64(v, _) => put(&mut self.int64, v),
                ColumnValues::Double(v, _) => put(&mut self.double, v),
            }
        }
    }

    pub(crate) fn int32(&mut self) -> Vec<i32> {
        self.int32.pop().unwrap_or_else(|| Vec::with_capacity(N))
    }

    pub(crate) fn int64(&mut self) -> Vec<i64> {
        self.int64.pop().unwrap_or_else(|| Vec::with_capacity(N))
    }

    pub(crate) fn double(&mut self) -> Vec<f64> {
        self.double.pop().unwrap_or_else(|| Vec::with_capacity(N))
    }
}
