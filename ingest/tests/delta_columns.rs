//! The columns ingest encodes itself (`ingest::parquet_io::encoding`, written by `ColumnTableWriter`):
//! delta-encoded integers and byte-stream-split doubles read back through parquet-rs and
//! Arrow as the values, nulls, statistics and page index that parquet-rs's own writer gives
//! for the same data.

use arrow_array::{ArrayRef, Float64Array, Int32Array, Int64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use ingest::parquet_io::table::{ColumnTableWriter, ColumnValues, Encodings, OWN_PAGE_ROWS};
use parquet::arrow::ArrowWriter;
use parquet::arrow::arrow_reader::{ArrowReaderOptions, ParquetRecordBatchReaderBuilder};
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::file::metadata::{PageIndexPolicy, ParquetMetaData};
use parquet::file::page_index::column_index::ColumnIndexMetaData;
use parquet::file::properties::{EnabledStatistics, WriterProperties};
use parquet::schema::types::ColumnPath;
use proptest::prelude::*;
use std::sync::Arc;

/// Columns: t, i64 required, zstd, statistics; c, i32 nullable, uncompressed, no statistics;
/// z, i32 nullable, zstd, statistics; w, i64 nullable, LZ4_RAW, statistics; d, f64
/// nullable, byte stream split, zstd, no statistics.
fn schema() -> SchemaRef {
    Arc::new(Schema::new(vec![
        Field::new("t", DataType::Int64, false),
        Field::new("c", DataType::Int32, true),
        Field::new("z", DataType::Int32, true),
        Field::new("w", DataType::Int64, true),
        Field::new("d", DataType::Float64, true),
    ]))
}

const DELTA: [&str; 4] = ["t", "c", "z", "w"];

/// The same columns as parquet-rs's own writer would encode them, in row groups of `group`.
fn reference_properties(group: usize) -> WriterProperties {
    let b = WriterProperties::builder()
        .set_max_row_group_row_count(Some(group))
        .set_compression(Compression::ZSTD(ZstdLevel::try_new(1).expect("level")))
        .set_dictionary_enabled(false)
        .set_encoding(Encoding::DELTA_BINARY_PACKED);
    b.set_column_compression(ColumnPath::from("c"), Compression::UNCOMPRESSED)
        .set_column_compression(ColumnPath::from("w"), Compression::LZ4_RAW)
        .set_column_statistics_enabled(ColumnPath::from("c"), EnabledStatistics::None)
        .set_column_statistics_enabled(ColumnPath::from("d"), EnabledStatistics::None)
        .set_column_encoding(ColumnPath::from("d"), Encoding::BYTE_STREAM_SPLIT)
        .build()
}

/// A column as (values of the non-null rows, definition levels), the levels left out if
/// `all_given` is false and every row has a value.
fn split<T: Copy>(all: &[Option<T>], all_given: bool) -> (Vec<T>, Option<Vec<i16>>) {
    let levels = (all_given || all.iter().any(Option::is_none))
        .then(|| all.iter().map(|v| i16::from(v.is_some())).collect());
    (all.iter().filter_map(|v| *v).collect(), levels)
}

struct Table {
    t: Vec<i64>,
    c: Vec<Option<i32>>,
    z: Vec<Option<i32>>,
    w: Vec<Option<i64>>,
    d: Vec<Option<f64>>,
}

impl Table {
    fn batch(&self) -> RecordBatch {
        let columns: Vec<ArrayRef> = vec![
            Arc::new(Int64Array::from(self.t.clone())),
            Arc::new(Int32Array::from(self.c.clone())),
            Arc::new(Int32Array::from(self.z.clone())),
            Arc::new(Int64Array::from(self.w.clone())),
            Arc::new(Float64Array::from(self.d.clone())),
        ];
        RecordBatch::try_new(schema(), columns).expect("batch")
    }

    /// Written by ingest's column writer, in row groups of `group` rows.
    fn write_own(&self, dir: &std::path::Path, group: usize) -> std::path::PathBuf {
        let mut w = ColumnTableWriter::create(
            dir,
            "own.parquet",
            schema(),
            Encodings {
                delta: &DELTA,
                uncompressed: &["c"],
                lz4: &["w"],
                no_statistics: &["c", "d"],
                byte_stream_split: &["d"],
                ..Encodings::default()
            },
        )
        .expect("create");
        let n = self.t.len();
        for start in (0..n).step_by(group.max(1)) {
            let end = (start + group).min(n);
            let (c, cl) = split(&self.c[start..end], false);
            let (z, zl) = split(&self.z[start..end], true);
            let (wv, wl) = split(&self.w[start..end], false);
            let (d, dl) = split(&self.d[start..end], false);
            w.write_row_group(
                end - start,
                &[
                    ("t", ColumnValues::Int64(self.t[start..end].to_vec(), None)),
                    ("c", ColumnValues::Int32(c, cl)),
                    ("z", ColumnValues::Int32(z, zl)),
                    ("w", ColumnValues::Int64(wv, wl)),
                    ("d", ColumnValues::Double(d, dl)),
                ],
            )
            .expect("row group");
        }
        w.finish().expect("finish");
        dir.join("own.parquet")
    }

    /// Written by parquet-rs's Arrow writer, in row groups of `group` rows.
    fn write_reference(&self, dir: &std::path::Path, group: usize) -> std::path::PathBuf {
        let path = dir.join("reference.parquet");
        let f = std::fs::File::create(&path).expect("create");
        let props = reference_properties(group);
        let mut w = ArrowWriter::try_new(f, schema(), Some(props)).expect("writer");
        w.write(&self.batch()).expect("write");
        w.close().expect("close");
        path
    }
}

/// The file's rows as one batch, and its metadata with the page index.
fn read(path: &std::path::Path) -> (RecordBatch, Arc<ParquetMetaData>) {
    let f = std::fs::File::open(path).expect("open");
    let builder = ParquetRecordBatchReaderBuilder::try_new_with_options(
        f,
        ArrowReaderOptions::new().with_page_index_policy(PageIndexPolicy::Optional),
    )
    .expect("reader");
    let metadata = builder.metadata().clone();
    let batches: Vec<RecordBatch> = builder
        .build()
        .expect("build")
        .map(|b| b.expect("batch"))
        .collect();
    let batch = arrow_select::concat::concat_batches(&schema(), &batches).expect("concat");
    (batch, metadata)
}

/// Checks the own file against the data and against parquet-rs's file of the same data.
fn check(table: &Table, group: usize) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().expect("tempdir");
    let (own, own_meta) = read(&table.write_own(dir.path(), group));
    let (reference, ref_meta) = read(&table.write_reference(dir.path(), group));
    prop_assert_eq!(&own, &table.batch());
    prop_assert_eq!(&reference, &table.batch());

    let rows = table.t.len();
    prop_assert_eq!(own_meta.num_row_groups(), rows.div_ceil(group));
    prop_assert_eq!(own_meta.num_row_groups(), ref_meta.num_row_groups());
    for (g, (ours, theirs)) in own_meta
        .row_groups()
        .iter()
        .zip(ref_meta.row_groups())
        .enumerate()
    {
        prop_assert_eq!(ours.num_rows(), theirs.num_rows());
        let group_rows = usize::try_from(ours.num_rows()).expect("rows");
        for (c, (a, b)) in ours.columns().iter().zip(theirs.columns()).enumerate() {
            // Chunk statistics as parquet-rs computes them (none where disabled).
            prop_assert_eq!(a.statistics(), b.statistics(), "group {} column {}", g, c);
            prop_assert_eq!(a.num_values(), b.num_values());
            prop_assert_eq!(a.compression(), b.compression());
            prop_assert_eq!(
                a.encodings().collect::<Vec<_>>(),
                b.encodings().collect::<Vec<_>>()
            );
            // Pages of OWN_PAGE_ROWS rows in the offset index.
            let pages = own_meta.page_index_for_row_group(g);
            let firsts: Vec<i64> = pages
                .page_locations(c)
                .expect("offset index")
                .iter()
                .map(|p| p.first_row_index)
                .collect();
            let expected: Vec<i64> = (0..group_rows)
                .step_by(OWN_PAGE_ROWS)
                .map(|r| r as i64)
                .collect();
            prop_assert_eq!(firsts, expected);
        }
        // Column index: each page's min and max where statistics are on, none on c.
        let index = own_meta.page_index_for_row_group(g);
        prop_assert!(index.column_index(1).is_none(), "no statistics on c");
        prop_assert!(index.column_index(4).is_none(), "no statistics on d");
        let Some(ColumnIndexMetaData::INT64(ti)) = index.column_index(0) else {
            return Err(TestCaseError::fail("t has an INT64 column index"));
        };
        let Some(ColumnIndexMetaData::INT32(zi)) = index.column_index(2) else {
            return Err(TestCaseError::fail("z has an INT32 column index"));
        };
        let (mut t_min, mut t_max, mut z_min, mut z_max) = (vec![], vec![], vec![], vec![]);
        let start = g * group;
        for page in (0..group_rows).step_by(OWN_PAGE_ROWS) {
            let rows = start + page..start + (page + OWN_PAGE_ROWS).min(group_rows);
            let t = &table.t[rows.clone()];
            t_min.push(t.iter().min());
            t_max.push(t.iter().max());
            let z: Vec<&i32> = table.z[rows].iter().flatten().collect();
            z_min.push(z.iter().min().copied());
            z_max.push(z.iter().max().copied());
        }
        prop_assert_eq!(ti.min_values_iter().collect::<Vec<_>>(), t_min);
        prop_assert_eq!(ti.max_values_iter().collect::<Vec<_>>(), t_max);
        prop_assert_eq!(zi.min_values_iter().collect::<Vec<_>>(), z_min);
        prop_assert_eq!(zi.max_values_iter().collect::<Vec<_>>(), z_max);
    }
    Ok(())
}

/// splitmix64: the test's data from a seed proptest chooses and shrinks.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// `n` values: 0 full-range noise, 1 a walk of small steps, 2 a constant, 3 the two
    /// extremes in turn (deltas that wrap).
    fn values(&mut self, n: usize, mode: u8) -> Vec<i64> {
        let mut x = self.next() as i64;
        (0..n)
            .map(|i| match mode {
                0 => self.next() as i64,
                1 => {
                    x = x.wrapping_add((self.next() % 2001) as i64 - 1000);
                    x
                }
                2 => x,
                _ if i % 2 == 0 => i64::MIN,
                _ => i64::MAX,
            })
            .collect()
    }

    /// `n` validity flags: 0 all valid, 1 all null, 2 long runs, 3 a coin per row.
    fn valid(&mut self, n: usize, mode: u8) -> Vec<bool> {
        let mut v = true;
        (0..n)
            .map(|_| match mode {
                0 => true,
                1 => false,
                2 => {
                    if self.next().is_multiple_of(500) {
                        v = !v;
                    }
                    v
                }
                _ => self.next().is_multiple_of(2),
            })
            .collect()
    }
}

fn table(rows: usize, seed: u64, modes: [u8; 4], valid: [u8; 3]) -> Table {
    let mut rng = Rng(seed);
    let narrow = |v: i64| match v {
        i64::MIN => i32::MIN,
        i64::MAX => i32::MAX,
        v => v as i32,
    };
    let t = rng.values(rows, modes[0]);
    let c = rng.values(rows, modes[1]);
    let z = rng.values(rows, modes[2]);
    let w = rng.values(rows, modes[3]);
    let d = rng.values(rows, modes[1]);
    let (vc, vz, vw, vd) = (
        rng.valid(rows, valid[0]),
        rng.valid(rows, valid[1]),
        rng.valid(rows, valid[2]),
        rng.valid(rows, valid[0]),
    );
    Table {
        t,
        c: c.iter()
            .zip(&vc)
            .map(|(&x, &v)| v.then(|| narrow(x)))
            .collect(),
        z: z.iter()
            .zip(&vz)
            .map(|(&x, &v)| v.then(|| narrow(x)))
            .collect(),
        w: w.iter().zip(&vw).map(|(&x, &v)| v.then_some(x)).collect(),
        // Doubles with every byte in play: counts, their thousandths and the extremes.
        d: d.iter()
            .zip(&vd)
            .map(|(&x, &v)| v.then_some(x as f64 * 1e-3))
            .collect(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn own_columns_read_back_as_parquet_rs_writes_them(
        rows in prop_oneof![1usize..300, 300usize..40_000],
        group in prop_oneof![Just(97usize), Just(OWN_PAGE_ROWS), Just(50_000)],
        seed in any::<u64>(),
        modes in proptest::array::uniform4(0u8..4),
        valid in proptest::array::uniform3(0u8..4),
    ) {
        check(&table(rows, seed, modes, valid), group)?;
    }
}

/// A walk like the logged counts, several pages and row groups, every validity pattern.
#[test]
fn counts_like_columns_over_several_pages() {
    for valid in 0..4 {
        let t = table(3 * OWN_PAGE_ROWS + 5, 7, [1, 1, 1, 1], [valid; 3]);
        check(&t, 2 * OWN_PAGE_ROWS + 1).expect("check");
    }
}
