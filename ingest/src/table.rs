//! Writing the Parquet tables: zstd, written under a temporary name and renamed when
//! complete, so an interrupted run never leaves a half file under a final name.

use crate::error::{Error, Result};
use arrow::array::{ArrayRef, DictionaryArray, Int32Array, RecordBatch, StringArray};
use arrow::datatypes::{Int32Type, SchemaRef};
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::file::properties::WriterProperties;
use parquet::schema::types::ColumnPath;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Rows per Parquet row group.
pub const ROWS_PER_GROUP: usize = 1 << 20;
/// Rows per Arrow batch handed to the writer (small enough to stay in cache).
pub const ROWS_PER_BATCH: usize = 1 << 16;

/// A Parquet table being written.
pub struct TableWriter {
    table: &'static str,
    path: PathBuf,
    tmp: PathBuf,
    schema: SchemaRef,
    writer: Option<ArrowWriter<BufWriter<File>>>,
    rows: u64,
}

/// Column encodings besides the defaults (plain, zstd; time columns delta-encoded).
#[derive(Clone, Copy, Debug, Default)]
pub struct Encodings<'a> {
    /// Columns with few distinct values: dictionary-encoded.
    pub dictionary: &'a [&'a str],
    /// Integer columns that change little from row to row: delta-encoded.
    pub delta: &'a [&'a str],
}

fn properties(enc: Encodings<'_>) -> WriterProperties {
    let mut b = WriterProperties::builder()
        .set_compression(Compression::ZSTD(
            ZstdLevel::try_new(1).expect("level 1 is valid"),
        ))
        .set_dictionary_enabled(false)
        .set_max_row_group_row_count(Some(ROWS_PER_GROUP))
        .set_column_encoding(
            ColumnPath::from(crate::schema::TIME_GPS_NS),
            Encoding::DELTA_BINARY_PACKED,
        );
    for c in enc.dictionary {
        b = b.set_column_dictionary_enabled(ColumnPath::from(*c), true);
    }
    for c in enc.delta {
        b = b.set_column_encoding(ColumnPath::from(*c), Encoding::DELTA_BINARY_PACKED);
    }
    b.build()
}

impl TableWriter {
    /// Starts `dir/file` (written as `dir/.file.partial` until [`TableWriter::finish`]).
    pub fn create(
        dir: &Path,
        file: &str,
        table: &'static str,
        schema: SchemaRef,
        encodings: Encodings<'_>,
    ) -> Result<Self> {
        let path = dir.join(file);
        let tmp = dir.join(format!(".{file}.partial"));
        let f = File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        let writer = ArrowWriter::try_new(
            BufWriter::with_capacity(1 << 20, f),
            schema.clone(),
            Some(properties(encodings)),
        )
        .map_err(|source| Error::Parquet {
            path: path.clone(),
            source,
        })?;
        Ok(TableWriter {
            table,
            path,
            tmp,
            schema,
            writer: Some(writer),
            rows: 0,
        })
    }

    /// Appends one batch built from `columns` (in schema order).
    pub fn write(&mut self, columns: Vec<ArrayRef>) -> Result<()> {
        let batch =
            RecordBatch::try_new(self.schema.clone(), columns).map_err(|source| Error::Arrow {
                table: self.table,
                source,
            })?;
        self.rows += batch.num_rows() as u64;
        if let Some(w) = self.writer.as_mut() {
            w.write(&batch).map_err(|source| Error::Parquet {
                path: self.path.clone(),
                source,
            })?;
        }
        Ok(())
    }

    /// Closes the file and renames it to its final name; returns the rows written.
    pub fn finish(mut self) -> Result<u64> {
        if let Some(w) = self.writer.take() {
            let inner = w.into_inner().map_err(|source| Error::Parquet {
                path: self.path.clone(),
                source,
            })?;
            let f = inner
                .into_inner()
                .map_err(|e| Error::io(&self.tmp, e.into_error()))?;
            f.sync_all().map_err(|e| Error::io(&self.tmp, e))?;
        }
        std::fs::rename(&self.tmp, &self.path).map_err(|e| Error::io(&self.path, e))?;
        Ok(self.rows)
    }
}

impl Drop for TableWriter {
    fn drop(&mut self) {
        if self.writer.is_some() {
            // Not finished: leave no partial file behind.
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// A session column of `n` rows, dictionary-encoded.
pub fn session_column(session: &str, n: usize) -> ArrayRef {
    let keys = Int32Array::from(vec![0i32; n]);
    let values = Arc::new(StringArray::from(vec![session]));
    Arc::new(DictionaryArray::<Int32Type>::try_new(keys, values).expect("key 0 is in range"))
}

/// A dictionary-encoded string column of `values` (distinct values sorted).
pub fn dictionary_column<'a>(values: impl Iterator<Item = &'a str>) -> ArrayRef {
    let values: Vec<&str> = values.collect();
    let mut distinct = values.clone();
    distinct.sort_unstable();
    distinct.dedup();
    let keys: Vec<i32> = values
        .iter()
        .map(|v| {
            distinct
                .binary_search(v)
                .map_or(0, |k| i32::try_from(k).unwrap_or(i32::MAX))
        })
        .collect();
    Arc::new(
        DictionaryArray::<Int32Type>::try_new(
            Int32Array::from(keys),
            Arc::new(StringArray::from(distinct)),
        )
        .expect("keys index the distinct values"),
    )
}
