//! Writing the Parquet tables: zstd, written under a temporary name and renamed when
//! complete, so an interrupted run never leaves a half file under a final name.
//!
//! Two writers: [`TableWriter`] takes Arrow batches (Parquet's `ArrowWriter`), for the small
//! tables; [`ColumnTableWriter`] takes whole row groups as plain vectors in Parquet's
//! physical types and hands them to Parquet's column writers directly, for the two sample
//! streams, where the Arrow path's per-value index lists and casts cost a third of the
//! writing. It encodes a row group's columns in parallel, into memory, and then appends
//! them to the file in schema order, so the bytes do not depend on the threads.
//! Delta-encoded integer columns it encodes itself ([`crate::parquet_io::encoding`]), pages, offset
//! index, statistics and column index as parquet-rs's column writer makes them
//! (`tests/delta_columns.rs` compares the two); parquet-rs's delta encoder was a quarter of
//! ingest's CPU time.

use crate::error::{Error, Result};
use crate::parquet_io::encoding::{self, DeltaValue};
use arrow_array::types::Int32Type;
use arrow_array::{ArrayRef, DictionaryArray, Int32Array, RecordBatch, StringArray};
use arrow_schema::SchemaRef;
use parquet::arrow::{ArrowSchemaConverter, ArrowWriter, add_encoded_arrow_schema_to_metadata};
use parquet::basic::{
    BoundaryOrder, Compression, Encoding, EncodingMask, PageType, Type, ZstdLevel,
};
use parquet::column::page::{CompressedPage, Page, PageWriter};
use parquet::column::writer::{ColumnCloseResult, ColumnWriter, get_column_writer};
use parquet::errors::ParquetError;
use parquet::file::metadata::{
    ColumnChunkMetaData, ColumnIndexBuilder, OffsetIndexBuilder, PageEncodingStats,
};
use parquet::file::properties::{
    EnabledStatistics, WriterProperties, WriterPropertiesPtr, WriterVersion,
};
use parquet::file::statistics::{Statistics, ValueStatistics};
use parquet::file::writer::{SerializedFileWriter, SerializedPageWriter, TrackedWrite};
use parquet::schema::types::ColumnDescPtr;
use parquet::schema::types::ColumnPath;
use rayon::prelude::*;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Rows per Parquet row group.
pub const ROWS_PER_GROUP: usize = 1 << 20;
/// Rows per row group of the sample streams ([`ColumnTableWriter`]), which are buffered
/// whole: about 3 MB of acceleration samples. Timing the release binary on the 250 Hz
/// benchmark day (best of 7; runs here scatter by about 15 %), 2^16 lost about a fifth of
/// the speed to per-column overheads and 2^19 about a tenth, to page faults and to the
/// writer starting late and finishing alone.
pub const STREAM_ROWS_PER_GROUP: usize = 1 << 17;

/// A table's file while it is written: under `.name.partial`, renamed into place by
/// [`PartialFile::commit`], removed if dropped before.
struct PartialFile {
    path: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

impl PartialFile {
    /// Creates `dir/.file.partial`; returns it and a buffered writer to it.
    fn create(dir: &Path, file: &str) -> Result<(Self, BufWriter<HashingFile>)> {
        let tmp = dir.join(format!(".{file}.partial"));
        let f = HashingFile {
            file: crate::create_new(&tmp).map_err(|e| Error::io(&tmp, e))?,
            hasher: sha2::Sha256::default(),
        };
        let partial = PartialFile {
            path: dir.join(file),
            tmp,
            committed: false,
        };
        Ok((partial, BufWriter::with_capacity(1 << 20, f)))
    }

    fn parquet_error(&self, source: ParquetError) -> Error {
        Error::Parquet {
            path: self.path.clone(),
            source,
        }
    }

    /// Flushes what the Parquet writer handed back (after writing the footer), syncs it to
    /// disk and renames it into place; returns the SHA-256 of its bytes, hex.
    fn commit(&mut self, inner: parquet::errors::Result<BufWriter<HashingFile>>) -> Result<String> {
        let f = inner
            .map_err(|e| self.parquet_error(e))?
            .into_inner()
            .map_err(|e| Error::io(&self.tmp, e.into_error()))?;
        f.file.sync_all().map_err(|e| Error::io(&self.tmp, e))?;
        std::fs::rename(&self.tmp, &self.path).map_err(|e| Error::io(&self.path, e))?;
        self.committed = true;
        use sha2::Digest;
        Ok(f.hasher
            .finalize()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect())
    }
}

/// A table's file that hashes what is written to it, in order, as it is written: the
/// SHA-256 of a table comes without reading it back.
struct HashingFile {
    file: File,
    hasher: sha2::Sha256,
}

impl std::io::Write for HashingFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.file.write(buf)?;
        sha2::Digest::update(&mut self.hasher, &buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl Drop for PartialFile {
    fn drop(&mut self) {
        if !self.committed {
            // Not finished: leave no partial file behind.
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// A Parquet table being written.
pub struct TableWriter {
    file: PartialFile,
    schema: SchemaRef,
    writer: ArrowWriter<BufWriter<HashingFile>>,
    rows: u64,
}

/// Column encodings besides the defaults (plain, zstd; time columns delta-encoded).
#[derive(Clone, Copy, Debug, Default)]
pub struct Encodings<'a> {
    /// Columns with few distinct values: dictionary-encoded.
    pub dictionary: &'a [&'a str],
    /// Integer columns that change little from row to row: delta-encoded.
    pub delta: &'a [&'a str],
    /// Float columns whose high bytes change little (a calibrated acceleration, a sigma):
    /// BYTE_STREAM_SPLIT, which lets zstd find what they share.
    pub byte_stream_split: &'a [&'a str],
    /// Columns left uncompressed: delta-encoded noisy counts, which zstd shrinks by 2% at
    /// a quarter of their encoding time (`examples/encodings.rs`).
    pub uncompressed: &'a [&'a str],
    /// Columns compressed with LZ4 (Parquet's LZ4_RAW) instead of zstd: where zstd's time
    /// is what a run waits for and the table is an intermediate one (the lab table's
    /// readings). Only for the columns ingest encodes itself (delta, byte stream split).
    pub lz4: &'a [&'a str],
    /// Columns without min/max statistics: raw counts, on which nobody filters, where
    /// computing them is a tenth of the writing.
    pub no_statistics: &'a [&'a str],
}

fn properties(enc: Encodings<'_>) -> WriterProperties {
    let mut b = WriterProperties::builder()
        .set_compression(Compression::ZSTD(
            ZstdLevel::try_new(1).expect("level 1 is valid"),
        ))
        .set_dictionary_enabled(false)
        .set_max_row_group_row_count(Some(ROWS_PER_GROUP))
        .set_column_encoding(
            ColumnPath::from(crate::contract::tables::TIME_GPS_NS),
            Encoding::DELTA_BINARY_PACKED,
        );
    for c in enc.dictionary {
        b = b.set_column_dictionary_enabled(ColumnPath::from(*c), true);
    }
    for c in enc.delta {
        b = b.set_column_encoding(ColumnPath::from(*c), Encoding::DELTA_BINARY_PACKED);
    }
    for c in enc.byte_stream_split {
        b = b.set_column_encoding(ColumnPath::from(*c), Encoding::BYTE_STREAM_SPLIT);
    }
    for c in enc.uncompressed {
        b = b.set_column_compression(ColumnPath::from(*c), Compression::UNCOMPRESSED);
    }
    for c in enc.lz4 {
        b = b.set_column_compression(ColumnPath::from(*c), Compression::LZ4_RAW);
    }
    for c in enc.no_statistics {
        b = b.set_column_statistics_enabled(ColumnPath::from(*c), EnabledStatistics::None);
    }
    b.build()
}

impl TableWriter {
    /// Starts `dir/file` (written as `dir/.file.partial` until [`TableWriter::finish`]).
    pub fn create(dir: &Path, file: &str, schema: SchemaRef, enc: Encodings<'_>) -> Result<Self> {
        let (file, f) = PartialFile::create(dir, file)?;
        let writer = ArrowWriter::try_new(f, schema.clone(), Some(properties(enc)))
            .map_err(|e| file.parquet_error(e))?;
        Ok(TableWriter {
            file,
            schema,
            writer,
            rows: 0,
        })
    }

    /// Appends one batch built from `columns`, in schema order, each with its name: one
    /// under another name than the schema's at its place is an error naming both (a column
    /// count that differs is Arrow's error).
    pub fn write<S: AsRef<str>>(&mut self, columns: Vec<(S, ArrayRef)>) -> Result<()> {
        let schema_names = self.schema.fields().iter().map(|f| f.name().as_str());
        if let Some(message) = misnamed(&columns, schema_names) {
            return Err(Error::Table {
                path: self.file.path.clone(),
                message,
            });
        }
        let columns = unnamed(columns);
        let batch =
            RecordBatch::try_new(self.schema.clone(), columns).map_err(|source| Error::Arrow {
                path: self.file.path.clone(),
                source,
            })?;
        self.rows += batch.num_rows() as u64;
        self.writer
            .write(&batch)
            .map_err(|e| self.file.parquet_error(e))
    }

    /// Ends the row group being written with the rows given so far: a table written in
    /// parts then holds one part in memory, not a row group of [`ROWS_PER_GROUP`].
    pub fn flush(&mut self) -> Result<()> {
        self.writer.flush().map_err(|e| self.file.parquet_error(e))
    }

    /// Closes the file and renames it to its final name; returns the rows written.
    pub fn finish(self) -> Result<u64> {
        self.finish_hashed().map(|(rows, _)| rows)
    }

    /// [`TableWriter::finish`], also returning the SHA-256 of the file (hashed as it was
    /// written, not read back).
    pub fn finish_hashed(mut self) -> Result<Written> {
        let sha256 = self.file.commit(self.writer.into_inner())?;
        Ok((self.rows, sha256))
    }
}

/// One column of a row group in the type Parquet stores it as (`UInt8`, `UInt16` and
/// `Int32` as `Int32`), with definition levels if the column is nullable and has nulls: one
/// per row, 1 where there is a value and 0 where it is null, `values` holding the non-null
/// values only. `None` for a nullable column: every row has a value.
#[derive(Clone, Debug)]
pub enum ColumnValues {
    /// INT32 values.
    Int32(Vec<i32>, Option<Vec<i16>>),
    /// INT64 values.
    Int64(Vec<i64>, Option<Vec<i16>>),
    /// DOUBLE values.
    Double(Vec<f64>, Option<Vec<i16>>),
}

/// A table closed and renamed into place: its rows and the SHA-256 of its bytes (hex),
/// hashed as they were written.
pub type Written = (u64, String);

/// A Parquet table written a row group at a time from [`ColumnValues`]. The Arrow schema is
/// stored in the file as `ArrowWriter` stores it, so Arrow readers see the same types.
pub struct ColumnTableWriter {
    file: PartialFile,
    writer: SerializedFileWriter<BufWriter<HashingFile>>,
    rows: u64,
    groups: u64,
    /// Whether a row group's columns are encoded on the rayon pool (or one after another on
    /// the caller's thread, [`ColumnTableWriter::one_column_at_a_time`]).
    parallel: bool,
    /// Row groups between syncs ([`GROUPS_PER_SYNC`], or [`ColumnTableWriter::sync_every`]).
    groups_per_sync: u64,
}

/// Row groups between syncs of what is written so far, on the writer's thread while the
/// reader goes on: the sync before the rename then waits only for the rest (on the 250 Hz
/// day about 2 ms where it had been 35-60 ms for the whole 68 MB; `strace -f -T -e
/// trace=fsync,fdatasync`). Ingest's tables sync more often
/// ([`ColumnTableWriter::sync_every`]).
const GROUPS_PER_SYNC: u64 = 16;

/// Row groups between syncs of ingest's stream and lab tables: 4 (35 minutes of 250 Hz
/// samples) rather than [`GROUPS_PER_SYNC`]. A two-hour log, which had had one sync of
/// everything at the end, ran 0.011-0.014 s (5-6 %) faster, the 250 Hz day no slower;
/// apply's 192 MB table, synced every 4 of its row groups, ran slower (2.47 against 2.08 s
/// on the 6 h log), so apply keeps the default (docs/benchmarks.md).
pub(crate) const INGEST_GROUPS_PER_SYNC: u64 = 4;

impl ColumnTableWriter {
    /// Starts `dir/file` (written as `dir/.file.partial` until
    /// [`ColumnTableWriter::finish`]).
    pub fn create(dir: &Path, file: &str, schema: SchemaRef, enc: Encodings<'_>) -> Result<Self> {
        let (file, f) = PartialFile::create(dir, file)?;
        let mut props = properties(enc);
        add_encoded_arrow_schema_to_metadata(&schema, &mut props);
        let descriptor = ArrowSchemaConverter::new()
            .convert(&schema)
            .map_err(|e| file.parquet_error(e))?;
        let writer = SerializedFileWriter::new(f, descriptor.root_schema_ptr(), Arc::new(props))
            .map_err(|e| file.parquet_error(e))?;
        Ok(ColumnTableWriter {
            file,
            writer,
            rows: 0,
            groups: 0,
            parallel: true,
            groups_per_sync: GROUPS_PER_SYNC,
        })
    }

    /// Syncs what is written every `groups` row groups (at least 1) instead of every
    /// [`GROUPS_PER_SYNC`] (ingest's tables: [`INGEST_GROUPS_PER_SYNC`]).
    pub fn sync_every(mut self, groups: u64) -> Self {
        self.groups_per_sync = groups.max(1);
        self
    }

    /// Encodes each row group's columns one after another on the thread that writes it,
    /// not on the rayon pool: for a writer with a thread of its own beside a parser that
    /// sets the run's pace on two cores (ingest's), where the pool's two workers waking and
    /// spinning for every row group take the parser's core (`cargo xtask bench ingest`,
    /// docs/benchmarks.md).
    pub fn one_column_at_a_time(mut self) -> Self {
        self.parallel = false;
        self
    }

    /// Writes one row group of `rows` rows; `columns` in schema order, each with its name:
    /// a column given under another name than the schema's at its place is an error naming
    /// both (every column of a table of doubles is a double, so an order slipped between
    /// the producer and the schema would otherwise write wrong data without a word). A group
    /// of no rows is not written.
    pub fn write_row_group<S: AsRef<str> + Sync>(
        &mut self,
        rows: usize,
        columns: &[(S, ColumnValues)],
    ) -> Result<()> {
        let parquet_error = |e| self.file.parquet_error(e);
        let w = &mut self.writer;
        let schema = w.schema_descr();
        if columns.len() != schema.num_columns() {
            return Err(parquet_error(ParquetError::General(format!(
                "{} columns given, the schema has {}",
                columns.len(),
                schema.num_columns()
            ))));
        }
        let schema_names = schema.columns().iter().map(|c| c.name());
        if let Some(message) = misnamed(columns, schema_names) {
            return Err(parquet_error(ParquetError::General(message)));
        }
        if rows == 0 {
            return Ok(());
        }
        let props = w.properties().clone();
        let encode = |(index, (_, values)): (usize, &(S, ColumnValues))| {
            encode_column(schema.column(index), props.clone(), values)
                .map_err(|e| ParquetError::General(format!("column {index}: {e}")))
        };
        let encoded: Vec<_> = if self.parallel {
            columns.par_iter().enumerate().map(encode).collect()
        } else {
            columns.iter().enumerate().map(encode).collect()
        };
        // Every column checked before the row group is opened: an error leaves the file as
        // it was, ready for the next row group.
        let encoded = encoded
            .into_iter()
            .collect::<parquet::errors::Result<Vec<_>>>()
            .map_err(parquet_error)?;
        if let Some((index, (_, close))) = encoded
            .iter()
            .enumerate()
            .find(|(_, (_, close))| close.rows_written != rows as u64)
        {
            return Err(parquet_error(ParquetError::General(format!(
                "column {index} has {} rows, the row group {rows}",
                close.rows_written
            ))));
        }
        let mut group = w.next_row_group().map_err(parquet_error)?;
        for (bytes, close) in encoded {
            group.append_column(&bytes, close).map_err(parquet_error)?;
        }
        group.close().map_err(parquet_error)?;
        self.rows += rows as u64;
        self.groups += 1;
        if self.groups.is_multiple_of(self.groups_per_sync) {
            w.flush().map_err(|e| Error::io(&self.file.tmp, e))?;
            w.inner()
                .get_ref()
                .file
                .sync_data()
                .map_err(|e| Error::io(&self.file.tmp, e))?;
        }
        Ok(())
    }

    /// Closes the file and renames it to its final name; returns the rows written.
    pub fn finish(self) -> Result<u64> {
        self.finish_hashed().map(|(rows, _)| rows)
    }

    /// [`ColumnTableWriter::finish`], also returning the SHA-256 of the file (hashed as it
    /// was written, not read back).
    pub fn finish_hashed(mut self) -> Result<Written> {
        let sha256 = self.file.commit(self.writer.into_inner())?;
        Ok((self.rows, sha256))
    }
}

/// A row group's columns with their names, as [`ColumnTableWriter::write_row_group`] takes
/// them.
pub type Named = Vec<(&'static str, ColumnValues)>;

/// Columns without their names (a row group's buffers, for the next row group).
pub fn unnamed<S, T>(columns: Vec<(S, T)>) -> Vec<T> {
    columns.into_iter().map(|(_, c)| c).collect()
}

/// The first of `columns` whose name is not the schema's at its place (`schema_names` in
/// order), as the writers' error says it; None when every name is the schema's.
fn misnamed<'a, S: AsRef<str>, T>(
    columns: &[(S, T)],
    mut schema_names: impl Iterator<Item = &'a str>,
) -> Option<String> {
    columns.iter().enumerate().find_map(|(index, (given, _))| {
        let expected = schema_names.next();
        (expected != Some(given.as_ref())).then(|| {
            format!(
                "column {index} is given as {}, the schema's is {}",
                given.as_ref(),
                expected.unwrap_or("none")
            )
        })
    })
}

/// Rows per data page of the columns ingest encodes itself (`encode_own_pages`): a
/// multiple of the delta encoding's 128-value block, near parquet-rs's default of 20 000
/// rows.
pub const OWN_PAGE_ROWS: usize = 1 << 14;

/// Encodes one column chunk into memory: its bytes and what closing its writer reported.
/// Delta-encoded integer columns and byte-stream-split doubles without statistics are
/// encoded here ([`encode_delta_column`], [`encode_split_column`]), the others by
/// parquet-rs's column writers.
fn encode_column(
    descr: ColumnDescPtr,
    props: WriterPropertiesPtr,
    values: &ColumnValues,
) -> parquet::errors::Result<(bytes::Bytes, ColumnCloseResult)> {
    let encoding = own_encoding(&descr, &props);
    match (encoding, values, descr.physical_type()) {
        (Some(Encoding::DELTA_BINARY_PACKED), ColumnValues::Int32(v, d), Type::INT32) => {
            return encode_delta_column(&descr, &props, v, d.as_deref());
        }
        (Some(Encoding::DELTA_BINARY_PACKED), ColumnValues::Int64(v, d), Type::INT64) => {
            return encode_delta_column(&descr, &props, v, d.as_deref());
        }
        (Some(Encoding::BYTE_STREAM_SPLIT), ColumnValues::Double(v, d), Type::DOUBLE)
            if props.statistics_enabled(descr.path()) == EnabledStatistics::None =>
        {
            return encode_split_column(&descr, &props, v, d.as_deref());
        }
        _ => {}
    }
    // parquet-rs wants a level per row of a nullable column, also where all are 1.
    let nullable = descr.max_def_level() > 0;
    let ones: Vec<i16> = match values {
        ColumnValues::Int32(v, None) if nullable => vec![1; v.len()],
        ColumnValues::Int64(v, None) if nullable => vec![1; v.len()],
        ColumnValues::Double(v, None) if nullable => vec![1; v.len()],
        _ => Vec::new(),
    };
    let ones = nullable.then_some(&ones[..]);
    let mut sink = TrackedWrite::new(Vec::new());
    let pages = Box::new(SerializedPageWriter::new(&mut sink));
    let close = match (get_column_writer(descr.clone(), props, pages), values) {
        (ColumnWriter::Int32ColumnWriter(mut c), ColumnValues::Int32(v, d)) => {
            c.write_batch(v, d.as_deref().or(ones), None)?;
            c.close()?
        }
        (ColumnWriter::Int64ColumnWriter(mut c), ColumnValues::Int64(v, d)) => {
            c.write_batch(v, d.as_deref().or(ones), None)?;
            c.close()?
        }
        (ColumnWriter::DoubleColumnWriter(mut c), ColumnValues::Double(v, d)) => {
            c.write_batch(v, d.as_deref().or(ones), None)?;
            c.close()?
        }
        _ => {
            return Err(ParquetError::General(
                "the values are not of the column's type".to_owned(),
            ));
        }
    };
    Ok((sink.into_inner()?.into(), close))
}

/// The column's encoding if ingest's own encoders may write it: flat (definition level at
/// most 1), no dictionary or bloom filter, uncompressed, zstd or LZ4_RAW, version 1 pages.
fn own_encoding(descr: &ColumnDescPtr, props: &WriterPropertiesPtr) -> Option<Encoding> {
    let path = descr.path();
    let own = !props.dictionary_enabled(path)
        && props.bloom_filter_properties(path).is_none()
        && props.writer_version() == WriterVersion::PARQUET_1_0
        && descr.max_rep_level() == 0
        && descr.max_def_level() <= 1
        && matches!(
            props.compression(path),
            Compression::UNCOMPRESSED | Compression::ZSTD(_) | Compression::LZ4_RAW
        );
    own.then(|| props.encoding(path)).flatten()
}

/// An integer column type [`encode_delta_column`] writes: its statistics and its plain bytes.
trait DeltaColumn: DeltaValue + Ord {
    /// Chunk statistics: min and max (none if every value is null) and the null count.
    fn statistics(min_max: Option<(Self, Self)>, nulls: u64) -> Statistics;
    /// The value's PLAIN encoding, as the column index stores min and max.
    fn plain(self) -> Vec<u8>;
}

macro_rules! delta_column {
    ($($t:ty),*) => {$(
        impl DeltaColumn for $t {
            fn statistics(min_max: Option<(Self, Self)>, nulls: u64) -> Statistics {
                let (min, max) = min_max.unzip();
                ValueStatistics::new(min, max, None, Some(nulls), false)
                    .with_backwards_compatible_min_max(true)
                    .into()
            }
            fn plain(self) -> Vec<u8> {
                self.to_le_bytes().to_vec()
            }
        }
    )*};
}

delta_column!(i32, i64);

/// The number of levels of 1 among levels that are 0 or 1.
fn ones(levels: &[i16]) -> usize {
    levels.iter().map(|&l| l as usize).sum()
}

/// Writes a delta-encoded integer column chunk as parquet-rs's column writer would, with
/// ingest's own encoders ([`crate::parquet_io::encoding`]): version 1 data pages of
/// [`OWN_PAGE_ROWS`] rows, definition levels RLE-encoded, values DELTA_BINARY_PACKED,
/// zstd-compressed if the column is; the offset index; and, where statistics are enabled,
/// the chunk's min, max and null count and a column index of each page's. Not written (they
/// are optional): page header statistics and level histograms.
fn encode_delta_column<T: DeltaColumn>(
    descr: &ColumnDescPtr,
    props: &WriterPropertiesPtr,
    values: &[T],
    levels: Option<&[i16]>,
) -> parquet::errors::Result<(bytes::Bytes, ColumnCloseResult)> {
    let statistics = props.statistics_enabled(descr.path());
    let mut bounds = PageBounds::<T>::new(descr, statistics);
    let (bytes, mut close, nulls) = encode_own_pages(
        descr,
        props,
        values.len(),
        levels,
        Encoding::DELTA_BINARY_PACKED,
        |range, nulls, buf| {
            let page_values = &values[range];
            encoding::put_delta(page_values, buf);
            bounds.page(page_values, nulls);
        },
    )?;
    let (chunk, column_index) = bounds.finish()?;
    if statistics != EnabledStatistics::None {
        let metadata = close.metadata.into_builder();
        close.metadata = metadata
            .set_statistics(T::statistics(chunk, nulls))
            .build()?;
    }
    close.column_index = column_index;
    Ok((bytes, close))
}

/// Writes a DOUBLE column chunk without statistics as BYTE_STREAM_SPLIT pages, as
/// [`encode_delta_column`] writes its pages: each page's values split into their eight
/// bytes' streams ([`encoding::put_byte_stream_split`]), which lets zstd find what the
/// values' high bytes share.
fn encode_split_column(
    descr: &ColumnDescPtr,
    props: &WriterPropertiesPtr,
    values: &[f64],
    levels: Option<&[i16]>,
) -> parquet::errors::Result<(bytes::Bytes, ColumnCloseResult)> {
    let (bytes, close, _) = encode_own_pages(
        descr,
        props,
        values.len(),
        levels,
        Encoding::BYTE_STREAM_SPLIT,
        |range, _, buf| encoding::put_byte_stream_split(&values[range], buf),
    )?;
    Ok((bytes, close))
}

/// The pages of a column chunk of `values` values with definition `levels`, each page's
/// values put by `put_values(range of the values, nulls in the page, buffer)` in
/// `encoding`: version 1 data pages of [`OWN_PAGE_ROWS`] rows, definition levels
/// RLE-encoded, zstd-compressed if the column is, and the offset index. Returns the
/// chunk's bytes, what closing it gives (metadata without statistics, no column index) and
/// its nulls.
fn encode_own_pages(
    descr: &ColumnDescPtr,
    props: &WriterPropertiesPtr,
    values: usize,
    levels: Option<&[i16]>,
    encoding: Encoding,
    mut put_values: impl FnMut(std::ops::Range<usize>, i64, &mut Vec<u8>),
) -> parquet::errors::Result<(bytes::Bytes, ColumnCloseResult, u64)> {
    let path = descr.path();
    let nullable = descr.max_def_level() == 1;
    let rows = checked_rows(nullable, values, levels)?;
    let mut codec = PageCodec::of(props.compression(path))?;
    let mut offset_index = (!props.offset_index_disabled()).then(OffsetIndexBuilder::new);
    let mut sink = TrackedWrite::new(Vec::new());
    let mut pages = SerializedPageWriter::new(&mut sink);
    let mut totals = ChunkTotals::default();
    let mut buf = Vec::new();
    let mut next_value = 0;
    for first_row in (0..rows).step_by(OWN_PAGE_ROWS) {
        let page_rows = OWN_PAGE_ROWS.min(rows - first_row);
        buf.clear();
        let page_levels = levels.map(|l| &l[first_row..first_row + page_rows]);
        let page_values = put_page_levels(page_levels, nullable, page_rows, &mut buf);
        let range = next_value..next_value + page_values;
        next_value += page_values;
        put_values(range, (page_rows - page_values) as i64, &mut buf);
        let uncompressed_size = buf.len();
        let data = codec.compress(&mut buf)?;
        let page = Page::DataPage {
            buf: data.into(),
            num_values: page_rows as u32,
            encoding,
            def_level_encoding: Encoding::RLE,
            rep_level_encoding: Encoding::RLE,
            statistics: None,
        };
        let spec = pages.write_page(CompressedPage::new(page, uncompressed_size))?;
        if let Some(oi) = offset_index.as_mut() {
            oi.append_offset_and_size(spec.offset as i64, spec.compressed_size as i32);
            oi.append_row_count(page_rows as i64);
        }
        totals.compressed += spec.compressed_size as u64;
        totals.uncompressed += spec.uncompressed_size as u64;
        totals.written += spec.bytes_written;
        totals.pages += 1;
    }
    pages.close()?;
    let close = ColumnCloseResult {
        bytes_written: totals.written,
        rows_written: rows as u64,
        metadata: own_chunk_metadata(descr, props, &totals, rows, encoding)?,
        bloom_filter: None,
        column_index: None,
        offset_index: offset_index.map(OffsetIndexBuilder::build),
    };
    Ok((sink.into_inner()?.into(), close, (rows - values) as u64))
}

/// How the pages ingest encodes itself are compressed ([`own_encoding`] admits no other).
enum PageCodec {
    None,
    Zstd(zstd::bulk::Compressor<'static>),
    /// LZ4's block format, which is Parquet's LZ4_RAW.
    Lz4,
}

impl PageCodec {
    fn of(compression: Compression) -> parquet::errors::Result<Self> {
        match compression {
            Compression::UNCOMPRESSED => Ok(PageCodec::None),
            Compression::ZSTD(level) => zstd::bulk::Compressor::new(level.compression_level())
                .map(PageCodec::Zstd)
                .map_err(|e| ParquetError::External(Box::new(e))),
            Compression::LZ4_RAW => Ok(PageCodec::Lz4),
            other => Err(ParquetError::NYI(format!(
                "{other} for a column ingest encodes itself"
            ))),
        }
    }

    /// The page's bytes compressed (taken from `buf` when not compressed).
    fn compress(&mut self, buf: &mut Vec<u8>) -> parquet::errors::Result<Vec<u8>> {
        match self {
            PageCodec::None => Ok(std::mem::take(buf)),
            PageCodec::Zstd(z) => z
                .compress(buf)
                .map_err(|e| ParquetError::External(Box::new(e))),
            PageCodec::Lz4 => Ok(lz4_flex::block::compress(buf)),
        }
    }
}

/// Puts a data page's definition levels into `buf` (`levels` the page's, or none: every
/// one of its `page_rows` rows defined; nothing for a required column); returns how many
/// values the page holds.
fn put_page_levels(
    levels: Option<&[i16]>,
    nullable: bool,
    page_rows: usize,
    buf: &mut Vec<u8>,
) -> usize {
    match levels {
        Some(l) => {
            encoding::put_levels(l, buf);
            ones(l)
        }
        None if nullable => {
            encoding::put_all_defined(page_rows, buf);
            page_rows
        }
        None => page_rows,
    }
}

/// The rows of a column of `values` values with definition `levels`, checked: in a
/// nullable column every level 0 or 1 and one value per level 1; no levels for a required
/// column.
fn checked_rows(
    nullable: bool,
    values: usize,
    levels: Option<&[i16]>,
) -> parquet::errors::Result<usize> {
    match levels {
        Some(l) if nullable => {
            // All levels 0 or 1 exactly when their bits ORed (negative ones all set) are.
            if l.iter().fold(0u16, |a, &l| a | l as u16) > 1
                && let Some(bad) = l.iter().find(|&&l| l != 0 && l != 1)
            {
                return Err(ParquetError::General(format!(
                    "definition level {bad} in a column whose maximum is 1"
                )));
            }
            let defined = ones(l);
            if defined != values {
                return Err(ParquetError::General(format!(
                    "{values} values for {defined} definition levels of 1"
                )));
            }
            Ok(l.len())
        }
        Some(_) => Err(ParquetError::General(
            "definition levels for a required column".to_owned(),
        )),
        None => Ok(values),
    }
}

/// What a column chunk's pages add up to.
#[derive(Default)]
struct ChunkTotals {
    compressed: u64,
    uncompressed: u64,
    written: u64,
    pages: i32,
}

/// The bounds of a column chunk's pages as they are written: the chunk's min and max, the
/// page index's entries (with page statistics) and the order the pages' bounds keep.
struct PageBounds<T> {
    enabled: bool,
    column_index: Option<ColumnIndexBuilder>,
    ascending: bool,
    descending: bool,
    last_page: Option<(T, T)>,
    chunk: Option<(T, T)>,
}

impl<T: DeltaColumn> PageBounds<T> {
    fn new(descr: &ColumnDescPtr, statistics: EnabledStatistics) -> Self {
        PageBounds {
            enabled: statistics != EnabledStatistics::None,
            column_index: (statistics == EnabledStatistics::Page)
                .then(|| ColumnIndexBuilder::new(descr.physical_type())),
            ascending: true,
            descending: true,
            last_page: None,
            chunk: None,
        }
    }

    /// A page of `values` (its defined values) and `nulls`.
    fn page(&mut self, values: &[T], nulls: i64) {
        let min_max = match values.split_first() {
            Some((&v, rest)) if self.enabled => Some(
                rest.iter()
                    .fold((v, v), |(lo, hi), &v| (lo.min(v), hi.max(v))),
            ),
            _ => None,
        };
        if let Some((lo, hi)) = min_max {
            self.chunk = Some(self.chunk.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
            if let Some((plo, phi)) = self.last_page {
                self.ascending &= plo <= lo && phi <= hi;
                self.descending &= plo >= lo && phi >= hi;
            }
            self.last_page = Some((lo, hi));
        }
        if let Some(ci) = self.column_index.as_mut() {
            match min_max {
                Some((lo, hi)) => ci.append(false, lo.plain(), hi.plain(), nulls, None),
                None => ci.append(true, Vec::new(), Vec::new(), nulls, None),
            }
        }
    }

    /// The chunk's min and max, and the column index with the pages' boundary order.
    #[allow(clippy::type_complexity, reason = "parquet-rs's own types, once")]
    fn finish(
        self,
    ) -> parquet::errors::Result<(
        Option<(T, T)>,
        Option<parquet::file::page_index::column_index::ColumnIndexMetaData>,
    )> {
        let column_index = match self.column_index {
            Some(mut ci) => {
                ci.set_boundary_order(if self.ascending {
                    BoundaryOrder::ASCENDING
                } else if self.descending {
                    BoundaryOrder::DESCENDING
                } else {
                    BoundaryOrder::UNORDERED
                });
                Some(ci.build()?)
            }
            None => None,
        };
        Ok((self.chunk, column_index))
    }
}

/// The metadata of a column chunk ingest encoded itself: its encodings, sizes and rows.
fn own_chunk_metadata(
    descr: &ColumnDescPtr,
    props: &WriterPropertiesPtr,
    totals: &ChunkTotals,
    rows: usize,
    encoding: Encoding,
) -> parquet::errors::Result<ColumnChunkMetaData> {
    ColumnChunkMetaData::builder(descr.clone())
        .set_compression(props.compression(descr.path()))
        .set_encodings_mask(EncodingMask::new_from_encodings(
            [Encoding::RLE, encoding].iter(),
        ))
        .set_page_encoding_stats(vec![PageEncodingStats {
            page_type: PageType::DATA_PAGE,
            encoding,
            count: totals.pages,
        }])
        .set_total_compressed_size(totals.compressed as i64)
        .set_total_uncompressed_size(totals.uncompressed as i64)
        .set_num_values(rows as i64)
        .set_data_page_offset(0)
        .build()
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

#[cfg(test)]
mod tests {
    use super::*;
    use arrow_array::{Array, Float64Array, Int64Array, UInt8Array, UInt16Array};
    use arrow_schema::{DataType, Field, Schema};
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

    fn schema() -> SchemaRef {
        Arc::new(Schema::new_with_metadata(
            vec![
                Field::new("s", DataType::UInt16, false),
                Field::new("t", DataType::Int64, false),
                Field::new("c", DataType::Int32, true),
                Field::new("x", DataType::Float64, true),
                Field::new("b", DataType::UInt8, false),
            ],
            arrow_schema::Metadata::new().with("k", "v"),
        ))
    }

    /// `columns` named as [`schema`]'s, in its order.
    fn named(columns: Vec<ColumnValues>) -> Vec<(&'static str, ColumnValues)> {
        ["s", "t", "c", "x", "b"].into_iter().zip(columns).collect()
    }

    /// A column table `t.parquet` of [`schema`] in `dir`.
    fn writer(dir: &Path, encodings: Encodings<'_>) -> ColumnTableWriter {
        ColumnTableWriter::create(dir, "t.parquet", schema(), encodings).expect("create")
    }

    /// Row groups written through the column writers read back through Arrow with the Arrow
    /// types, the nulls where the levels put them, and the schema metadata.
    #[test]
    fn column_writer_round_trips_through_arrow() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut w = writer(
            dir.path(),
            Encodings {
                delta: &["c"],
                uncompressed: &["c"],
                ..Encodings::default()
            },
        );
        let group = |t0: i64| {
            vec![
                ColumnValues::Int32(vec![7; 3], None),
                ColumnValues::Int64(vec![t0, t0 + 1, t0 + 2], None),
                ColumnValues::Int32(vec![-8_388_608, 8_388_607], Some(vec![1, 0, 1])),
                ColumnValues::Double(vec![0.5], Some(vec![0, 0, 1])),
                ColumnValues::Int32(vec![0, 0b0010_0000, 255], None),
            ]
        };
        w.write_row_group(3, &named(group(10))).expect("group 1");
        w.write_row_group(3, &named(group(20))).expect("group 2");
        assert!(
            !dir.path().join("t.parquet").exists(),
            "renamed only at the end"
        );
        assert_eq!(w.finish().expect("finish"), 6);

        let f = File::open(dir.path().join("t.parquet")).expect("open");
        let builder = ParquetRecordBatchReaderBuilder::try_new(f).expect("reader");
        assert_eq!(
            builder.schema().metadata().get("k").map(String::as_str),
            Some("v")
        );
        let reader = builder.build().expect("build");
        let batches: Vec<_> = reader.map(|b| b.expect("batch")).collect();
        let batch =
            arrow_select::concat::concat_batches(&batches[0].schema(), &batches).expect("concat");
        assert_eq!(batch.schema().fields(), schema().fields());
        let col = |i: usize| batch.column(i).clone();
        assert_eq!(
            col(0).as_any().downcast_ref::<UInt16Array>(),
            Some(&UInt16Array::from(vec![7; 6]))
        );
        assert_eq!(
            col(1).as_any().downcast_ref::<Int64Array>(),
            Some(&Int64Array::from(vec![10, 11, 12, 20, 21, 22]))
        );
        let c = [Some(-8_388_608), None, Some(8_388_607)];
        assert_eq!(
            col(2).as_any().downcast_ref::<Int32Array>(),
            Some(&Int32Array::from([c, c].concat()))
        );
        assert_eq!(col(3).null_count(), 4);
        assert_eq!(
            col(3).as_any().downcast_ref::<Float64Array>(),
            Some(&Float64Array::from(vec![
                None,
                None,
                Some(0.5),
                None,
                None,
                Some(0.5)
            ]))
        );
        assert_eq!(
            col(4).as_any().downcast_ref::<UInt8Array>(),
            Some(&UInt8Array::from(vec![0, 32, 255, 0, 32, 255]))
        );
    }

    /// A nullable column given without levels has a value in every row, through parquet-rs's
    /// column writer (f64) as through ingest's own (delta-encoded i32).
    #[test]
    fn nullable_columns_without_levels_have_no_nulls() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut w = writer(
            dir.path(),
            Encodings {
                delta: &["c"],
                ..Encodings::default()
            },
        );
        w.write_row_group(
            2,
            &named(vec![
                ColumnValues::Int32(vec![1, 2], None),
                ColumnValues::Int64(vec![3, 4], None),
                ColumnValues::Int32(vec![5, 6], None),
                ColumnValues::Double(vec![7.5, 8.5], None),
                ColumnValues::Int32(vec![9, 10], None),
            ]),
        )
        .expect("row group");
        w.finish().expect("finish");
        let f = File::open(dir.path().join("t.parquet")).expect("open");
        let batch = ParquetRecordBatchReaderBuilder::try_new(f)
            .expect("reader")
            .build()
            .expect("build")
            .next()
            .expect("a batch")
            .expect("batch");
        assert_eq!(
            batch.column(2).as_any().downcast_ref::<Int32Array>(),
            Some(&Int32Array::from(vec![5, 6]))
        );
        assert_eq!(
            batch.column(3).as_any().downcast_ref::<Float64Array>(),
            Some(&Float64Array::from(vec![7.5, 8.5]))
        );
    }

    /// Levels the own delta path cannot write are errors naming the column, not panics.
    #[test]
    fn delta_columns_reject_inconsistent_levels() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut w = writer(
            dir.path(),
            Encodings {
                delta: &["t", "c"],
                ..Encodings::default()
            },
        );
        let group = |t: Option<Vec<i16>>, c: Vec<i32>, cl: Option<Vec<i16>>| {
            vec![
                ColumnValues::Int32(vec![1, 2], None),
                ColumnValues::Int64(vec![3, 4], t),
                ColumnValues::Int32(c, cl),
                ColumnValues::Double(vec![7.5, 8.5], None),
                ColumnValues::Int32(vec![9, 10], None),
            ]
        };
        for (columns, message) in [
            (
                group(None, vec![5, 6], Some(vec![1, 2])),
                "column 2: Parquet error: definition level 2 in a column whose maximum is 1",
            ),
            (
                group(None, vec![5, 6], Some(vec![1, 0])),
                "column 2: Parquet error: 2 values for 1 definition levels of 1",
            ),
            (
                group(Some(vec![1, 1]), vec![5, 6], None),
                "column 1: Parquet error: definition levels for a required column",
            ),
        ] {
            let e = w.write_row_group(2, &named(columns)).expect_err(message);
            assert!(e.to_string().contains(message), "{e}");
        }
        // Columns of other lengths than the row group's.
        let e = w
            .write_row_group(3, &named(group(None, vec![5, 6], None)))
            .expect_err("3 rows");
        assert!(
            e.to_string()
                .contains("t.parquet: Parquet error: column 0 has 2 rows, the row group 3"),
            "{e}"
        );
        // None of it touched the file.
        w.write_row_group(2, &named(group(None, vec![5, 6], None)))
            .expect("a good row group after the bad ones");
        assert_eq!(w.finish().expect("finish"), 2);
    }

    /// The Arrow writer takes columns by name too: a slipped order is refused naming the
    /// column and the table, and the table stays good for the next batch.
    #[test]
    fn table_writer_refuses_columns_under_other_names() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut w = TableWriter::create(dir.path(), "t.parquet", schema(), Encodings::default())
            .expect("create");
        let columns = |c: &'static str, x: &'static str| -> Vec<(&'static str, ArrayRef)> {
            vec![
                ("s", Arc::new(UInt16Array::from(vec![1]))),
                ("t", Arc::new(Int64Array::from(vec![2]))),
                (c, Arc::new(Int32Array::from(vec![3]))),
                (x, Arc::new(Float64Array::from(vec![4.5]))),
                ("b", Arc::new(UInt8Array::from(vec![5]))),
            ]
        };
        let e = w.write(columns("x", "c")).expect_err("names slipped");
        assert!(
            e.to_string()
                .contains("t.parquet: column 2 is given as x, the schema's is c"),
            "{e}"
        );
        w.write(columns("c", "x")).expect("the right names");
        assert_eq!(w.finish().expect("finish"), 1);
    }

    /// Values of the wrong type, or more columns than the schema has, are errors naming the
    /// table; nothing is left behind.
    #[test]
    fn column_writer_rejects_mismatched_columns() {
        let dir = tempfile::tempdir().expect("tempdir");
        let create = || writer(dir.path(), Encodings::default());
        let mut w = create();
        let e = w
            .write_row_group(1, &[("s", ColumnValues::Int64(vec![1], None))])
            .expect_err("wrong type");
        assert!(
            e.to_string()
                .contains("t.parquet: Parquet error: 1 columns given, the schema has 5"),
            "{e}"
        );
        drop(w);
        let mut w = create();
        let six = vec![
            ColumnValues::Int32(vec![1], None),
            ColumnValues::Int64(vec![1], None),
            ColumnValues::Int32(vec![1], Some(vec![1])),
            ColumnValues::Double(vec![1.0], Some(vec![1])),
            ColumnValues::Int32(vec![1], None),
        ];
        let mut six = named(six);
        six.push(("y", ColumnValues::Int32(vec![1], None)));
        let e = w.write_row_group(1, &six).expect_err("six columns");
        assert!(e.to_string().contains("6 columns given"), "{e}");
        six.pop();
        // Columns in another order than the schema's, each under its own name: refused by
        // name before any value is looked at.
        six.swap(2, 3);
        let e = w.write_row_group(1, &six).expect_err("a slipped order");
        assert!(
            e.to_string()
                .contains("t.parquet: Parquet error: column 2 is given as x, the schema's is c"),
            "{e}"
        );
        six.swap(2, 3);
        let (first, rest) = six.split_at_mut(1);
        std::mem::swap(&mut first[0].1, &mut rest[0].1);
        let e = w.write_row_group(1, &six).expect_err("wrong types");
        assert!(
            e.to_string().contains(
                "Parquet error: column 0: Parquet error: the values are not of the column's type"
            ),
            "{e}"
        );
        drop(w);
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 0);
    }
}
