//! Reading the tables back: batches, columns by name and type, and the float tables that
//! apply and gravity write. Every error names the table's file and the column.

use super::{SESSION, SESSION_INDEX, TIME_GPS_NS, session_type};
use crate::{Error, Result};
use arrow_array::types::{Float64Type, Int32Type, Int64Type, UInt8Type, UInt16Type};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch, cast::AsArray};
use arrow_schema::DataType;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::path::Path;

/// A table's error at `path`.
pub(super) fn bad(path: &Path, message: String) -> Error {
    Error::Table {
        path: path.to_path_buf(),
        message,
    }
}

/// The record batches of a table, `rows` at a time.
pub(super) fn batches_of(
    path: &Path,
    rows: usize,
) -> Result<impl Iterator<Item = Result<RecordBatch>>> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let parquet = |source| Error::Parquet {
        path: path.to_path_buf(),
        source,
    };
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .map_err(parquet)?
        .with_batch_size(rows)
        .build()
        .map_err(parquet)?;
    let p = path.to_path_buf();
    Ok(reader.map(move |b| b.map_err(|e| bad(&p, e.to_string()))))
}

/// The column `name` of a batch, which must be of type `ty`.
pub(super) fn column<'a>(
    path: &Path,
    batch: &'a RecordBatch,
    name: &str,
    ty: &DataType,
) -> Result<&'a ArrayRef> {
    let c = batch
        .column_by_name(name)
        .ok_or_else(|| bad(path, format!("no column `{name}`")))?;
    if c.data_type() != ty {
        return Err(bad(
            path,
            format!("column `{name}` is {}, expected {ty}", c.data_type()),
        ));
    }
    Ok(c)
}

/// The Float64 column `name` of a batch.
pub(super) fn floats<'a>(path: &Path, b: &'a RecordBatch, name: &str) -> Result<&'a Float64Array> {
    Ok(column(path, b, name, &DataType::Float64)?.as_primitive::<Float64Type>())
}

/// A nullable float's value at row `i`.
pub(super) fn opt(a: &Float64Array, i: usize) -> Option<f64> {
    a.is_valid(i).then(|| a.value(i))
}

/// Session index of every row of a batch of a stream table.
pub(super) fn session_index<'a>(path: &Path, batch: &'a RecordBatch) -> Result<&'a [u16]> {
    Ok(column(path, batch, SESSION_INDEX, &DataType::UInt16)?
        .as_primitive::<UInt16Type>()
        .values())
}

/// The values of the dictionary column `name` of a batch, one per row.
pub(super) fn dictionary(path: &Path, batch: &RecordBatch, name: &str) -> Result<Vec<String>> {
    let (ids, keys) = dictionary_keys(path, batch, name)?;
    Ok(keys.into_iter().map(|k| ids[k].clone()).collect())
}

/// The dictionary column `name` of a batch: (distinct values, index into them per row).
pub(super) fn dictionary_keys(
    path: &Path,
    batch: &RecordBatch,
    name: &str,
) -> Result<(Vec<String>, Vec<usize>)> {
    let c = column(path, batch, name, &session_type())?;
    let d = c.as_dictionary::<Int32Type>();
    let values = d.values().as_string::<i32>();
    let ids = (0..values.len())
        .map(|i| values.value(i).to_owned())
        .collect();
    let keys = d
        .keys()
        .values()
        .iter()
        .map(|&k| usize::try_from(k).unwrap_or(0))
        .collect();
    Ok((ids, keys))
}

/// The session column of a batch: (distinct ids, index into them per row).
pub(super) fn sessions(path: &Path, batch: &RecordBatch) -> Result<(Vec<String>, Vec<usize>)> {
    dictionary_keys(path, batch, SESSION)
}

/// The batches of a sample stream's table (acceleration, lab) at `path` in file order,
/// `rows` at a time, each handed to `f` with its session index and GPS time columns.
pub(super) fn stream_batches<E: From<Error>>(
    path: &Path,
    rows: usize,
    mut f: impl FnMut(&RecordBatch, &[u16], &[i64]) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    for b in batches_of(path, rows)? {
        let b = b?;
        let (session, time) = session_and_time(path, &b)?;
        f(&b, session, time)?;
    }
    Ok(())
}

/// A stream table's session index and GPS time columns.
pub(super) fn session_and_time<'b>(
    path: &Path,
    b: &'b RecordBatch,
) -> Result<(&'b [u16], &'b [i64])> {
    Ok((
        session_index(path, b)?,
        column(path, b, TIME_GPS_NS, &DataType::Int64)?
            .as_primitive::<Int64Type>()
            .values(),
    ))
}

/// One batch of a table with per row a session index, a GPS time, some nullable Float64
/// columns and a UInt8 flags column: apply's `acceleration.parquet` ([`super::applied`]),
/// gravity.parquet and attitude.parquet.
pub struct FloatBatch<'a> {
    /// Session index per row.
    pub session: &'a [u16],
    /// GPS time per row, ns.
    pub time_ns: &'a [i64],
    /// The columns asked for, in the order asked.
    pub values: Vec<&'a Float64Array>,
    /// The flags column (empty for a table without one).
    pub flags: &'a [u8],
}

/// Streams the table at `path` in file order, `batch_rows` at a time, reading the Float64
/// columns `names` and the UInt8 column `flags`.
pub fn float_batches(
    path: &Path,
    names: &[&str],
    flags: &str,
    batch_rows: usize,
    f: impl FnMut(FloatBatch<'_>) -> Result<()>,
) -> Result<()> {
    float_batches_with(path, names, flags, batch_rows, f)
}

/// [`float_batches`] with a callback that stops with an error of its own, `E` (the
/// table's errors converted into it): a stage's error comes out as itself, not dressed as
/// a table's.
pub fn float_batches_with<E: From<Error>>(
    path: &Path,
    names: &[&str],
    flags: &str,
    batch_rows: usize,
    f: impl FnMut(FloatBatch<'_>) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    float_batches_of(path, names, Some(flags), batch_rows, f)
}

/// [`float_batches`] of a table without a flags column (attitude.parquet): `flags` empty,
/// the columns nullable.
pub fn float_batches_unflagged(
    path: &Path,
    names: &[&str],
    batch_rows: usize,
    f: impl FnMut(FloatBatch<'_>) -> Result<()>,
) -> Result<()> {
    float_batches_of(path, names, None, batch_rows, f)
}

/// The batches of [`float_batches_with`], with a flags column or none.
fn float_batches_of<E: From<Error>>(
    path: &Path,
    names: &[&str],
    flags: Option<&str>,
    batch_rows: usize,
    mut f: impl FnMut(FloatBatch<'_>) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    for b in batches_of(path, batch_rows)? {
        let b = b?;
        let (session, time) = session_and_time(path, &b)?;
        let values: Vec<_> = names
            .iter()
            .map(|n| floats(path, &b, n))
            .collect::<Result<_>>()?;
        let flags: &[u8] = match flags {
            Some(name) => column(path, &b, name, &DataType::UInt8)?
                .as_primitive::<UInt8Type>()
                .values(),
            None => &[],
        };
        f(FloatBatch {
            session,
            time_ns: time,
            values,
            flags,
        })?;
    }
    Ok(())
}
