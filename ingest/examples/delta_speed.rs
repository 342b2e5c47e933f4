//! Times ingest's DELTA_BINARY_PACKED encoder (`ingest::parquet_io::encoding::put_delta`) alone on the
//! counts and times of an acceleration table ingest wrote:
//!
//! ```text
//! cargo run --release -p ingest -- target/bench-data/bench-250hz-24h --out /tmp/b
//! cargo run --release -p ingest --example delta_speed -- /tmp/b/ingest/acceleration.parquet
//! ```
//!
//! Prints, per column, the best of five passes in ns per value and the encoded bits per
//! value, encoding pages of `OWN_PAGE_ROWS` values as ingest does.

use arrow_array::{Array, Int32Array, Int64Array, RecordBatch};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::time::Instant;

fn time<T: ingest::parquet_io::encoding::DeltaValue>(name: &str, values: &[T]) {
    let mut best = f64::INFINITY;
    let mut bytes = 0;
    let mut out = Vec::new();
    for _ in 0..5 {
        let t0 = Instant::now();
        bytes = 0;
        for page in values.chunks(ingest::parquet_io::table::OWN_PAGE_ROWS) {
            out.clear();
            ingest::parquet_io::encoding::put_delta(page, &mut out);
            bytes += out.len();
        }
        best = best.min(t0.elapsed().as_secs_f64());
    }
    println!(
        "{name}: {} values, {:.2} ns/value, {:.2} bits/value",
        values.len(),
        best * 1e9 / values.len() as f64,
        bytes as f64 * 8.0 / values.len() as f64
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: delta_speed ACCELERATION.parquet")?;
    let reader = ParquetRecordBatchReaderBuilder::try_new(std::fs::File::open(&path)?)?
        .with_batch_size(1 << 16)
        .build()?;
    let batches = reader.collect::<Result<Vec<RecordBatch>, _>>()?;
    let column = |name: &str| -> Result<Vec<_>, Box<dyn std::error::Error>> {
        let mut out = Vec::new();
        for b in &batches {
            let c = b.column_by_name(name).ok_or(format!("no column {name}"))?;
            out.push(c.clone());
        }
        Ok(out)
    };
    let time_ns: Vec<i64> = column(ingest::contract::tables::TIME_GPS_NS)?
        .iter()
        .filter_map(|c| c.as_any().downcast_ref::<Int64Array>())
        .flat_map(|c| c.values().iter().copied())
        .collect();
    time(ingest::contract::tables::TIME_GPS_NS, &time_ns);
    for name in ingest::contract::tables::acceleration::COUNTS {
        let counts: Vec<i32> = column(name)?
            .iter()
            .filter_map(|c| c.as_any().downcast_ref::<Int32Array>())
            .flat_map(|c| c.iter().flatten())
            .collect();
        time(name, &counts);
    }
    Ok(())
}
