//! What the integration tests share: reading a table ingest wrote.

use arrow_array::RecordBatch;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::path::Path;

/// The batches of `out/ingest/file`.
pub fn read_table(out: &Path, file: &str) -> Vec<RecordBatch> {
    let f = std::fs::File::open(out.join("ingest").join(file)).expect("table exists");
    ParquetRecordBatchReaderBuilder::try_new(f)
        .expect("parquet")
        .build()
        .expect("reader")
        .map(|b| b.expect("batch"))
        .collect()
}
