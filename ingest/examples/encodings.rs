//! Times Parquet encodings (plain, delta where the type allows, byte stream split) and
//! compression (zstd, LZ4_RAW, none) column by column on a table ingest wrote, through
//! parquet-rs's own writer: the measurement behind the encodings chosen in `streams.rs` and
//! `labstream.rs`:
//!
//! ```text
//! cargo xtask bench ingest --hours 24 --no-peers        # generates target/bench-data
//! cargo run --release -p ingest -- target/bench-data/bench-250hz-24h --out /tmp/b
//! cargo run --release -p ingest --example encodings -- /tmp/b/ingest/acceleration.parquet
//! ```
//!
//! Prints, per column, encoding and compression, the best of three writes to memory and the
//! bytes written.

use arrow_array::RecordBatch;
use parquet::arrow::ArrowWriter;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::file::properties::WriterProperties;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: encodings TABLE.parquet")?;
    let reader = ParquetRecordBatchReaderBuilder::try_new(std::fs::File::open(&path)?)?
        .with_batch_size(1 << 16)
        .build()?;
    let batches = reader.collect::<Result<Vec<RecordBatch>, _>>()?;
    let first = batches.first().ok_or("empty table")?;
    let rows: usize = batches.iter().map(RecordBatch::num_rows).sum();
    println!("{path}: {rows} rows");
    println!("| column | encoding | compression | seconds | MB |");
    println!("|---|---|---|---|---|");
    for (index, field) in first.schema().fields().iter().enumerate() {
        let column = batches
            .iter()
            .map(|b| b.project(&[index]))
            .collect::<Result<Vec<_>, _>>()?;
        let schema = column[0].schema();
        for encoding in [
            Encoding::PLAIN,
            Encoding::DELTA_BINARY_PACKED,
            Encoding::BYTE_STREAM_SPLIT,
        ] {
            // parquet-rs panics on a delta-encoded float column rather than refusing it.
            if encoding == Encoding::DELTA_BINARY_PACKED && field.data_type().is_floating() {
                continue;
            }
            for (label, compression) in [
                ("zstd(1)", Compression::ZSTD(ZstdLevel::try_new(1)?)),
                ("lz4_raw", Compression::LZ4_RAW),
                ("none", Compression::UNCOMPRESSED),
            ] {
                let props = WriterProperties::builder()
                    .set_compression(compression)
                    .set_dictionary_enabled(false)
                    .set_encoding(encoding)
                    .set_max_row_group_row_count(Some(ingest::parquet_io::table::ROWS_PER_GROUP))
                    .build();
                let mut best = f64::INFINITY;
                let mut bytes = 0;
                for _ in 0..3 {
                    let t0 = Instant::now();
                    let Ok(mut w) =
                        ArrowWriter::try_new(Vec::new(), schema.clone(), Some(props.clone()))
                    else {
                        break;
                    };
                    if column.iter().try_for_each(|b| w.write(b)).is_err() {
                        // This encoding does not apply to this column's type.
                        break;
                    }
                    bytes = w.into_inner()?.len();
                    best = best.min(t0.elapsed().as_secs_f64());
                }
                if best.is_finite() {
                    println!(
                        "| {} | {encoding:?} | {label} | {best:.3} | {:.1} |",
                        field.name(),
                        bytes as f64 / 1e6
                    );
                }
            }
        }
    }
    Ok(())
}
