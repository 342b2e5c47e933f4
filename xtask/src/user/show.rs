//! `cargo xtask show <file.parquet> [--csv] [--head N]`: any table the pipeline wrote, read
//! without Python. The schema first (each column's type and whether it may be null, and the
//! file's key-value metadata), then the rows: aligned for reading, or CSV (RFC 4180 quoting)
//! for a spreadsheet. Values are printed as Arrow's display gives them; nulls as empty
//! fields. A table whose stage's ledger lies beside it (OUT/<stage>/<stage>.json) is held
//! to the SHA-256 that ledger recorded: a table changed since is said to be so on stderr
//! before its rows, and the command then fails, as the next stage would refuse it.

use anyhow::{Context, Result, bail};
use arrow_array::Array;
use arrow_array::RecordBatch;
use arrow_array::cast::AsArray;
use arrow_array::types::{
    Float32Type, Float64Type, Int8Type, Int16Type, Int32Type, Int64Type, UInt8Type, UInt16Type,
    UInt32Type, UInt64Type,
};
use arrow_schema::DataType;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::io::Write;
use std::path::Path;

/// How to print.
#[derive(Clone, Copy, Debug)]
pub struct ShowOptions {
    /// CSV instead of aligned columns (and no schema lines).
    pub csv: bool,
    /// At most this many rows (all of them when None).
    pub head: Option<usize>,
}

/// Prints `path` to `out`.
pub fn show(path: &Path, options: ShowOptions, out: &mut impl Write) -> Result<()> {
    if path.is_dir() {
        anyhow::bail!("{}: is a folder, not a Parquet file", path.display());
    }
    let file = std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
    let changed = match recorded(path) {
        Some((ledger, sha256)) => {
            let now = ingest::contract::custody::sha256_file(path)?;
            (now != sha256).then(|| {
                format!(
                    "{}: is not the table {ledger} recorded (sha256 {} recorded, {} now): its \
                     bytes changed after the stage wrote it, and the next stage would refuse it",
                    path.display(),
                    &sha256[..sha256.len().min(12)],
                    &now[..12]
                )
            })
        }
        None => None,
    };
    if let Some(why) = &changed {
        eprintln!("show: {why}");
    }
    let builder = ParquetRecordBatchReaderBuilder::try_new(file)
        .with_context(|| format!("{}: not a Parquet file", path.display()))?;
    let rows = builder.metadata().file_metadata().num_rows();
    let schema = builder.schema().clone();
    let reader = builder
        .build()
        .with_context(|| format!("reading {}", path.display()))?;
    let names: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
    if options.csv {
        writeln!(
            out,
            "{}",
            names.iter().map(|n| quote(n)).collect::<Vec<_>>().join(",")
        )?;
    } else {
        writeln!(out, "# {}: {rows} rows", path.display())?;
        for f in schema.fields() {
            let null = if f.is_nullable() { ", may be null" } else { "" };
            writeln!(out, "# {}: {}{null}", f.name(), f.data_type())?;
        }
        for (k, v) in schema.metadata() {
            writeln!(out, "# metadata {k}: {v}")?;
        }
    }
    let result = print_rows(reader, &names, rows, options, path, out);
    match changed {
        Some(_) => result.and(Err(anyhow::anyhow!(
            "{}: the rows shown are not the table its stage wrote (said above)",
            path.display()
        ))),
        None => result,
    }
}

/// The ledger beside `path` (a JSON file in its folder) whose custody lists it among the
/// tables its stage wrote (or gravity.json, for gravity.parquet), and the SHA-256 recorded;
/// None when no ledger there lists it (a table copied elsewhere, or one the pipeline did
/// not write).
fn recorded(path: &Path) -> Option<(String, String)> {
    let dir = path.parent()?;
    let want = format!(
        "{}/{}",
        dir.file_name()?.to_str()?,
        path.file_name()?.to_str()?
    );
    let mut ledgers: Vec<_> = std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    ledgers.sort();
    ledgers.into_iter().find_map(|ledger| {
        let text = std::fs::read_to_string(&ledger).ok()?;
        let mut v: serde_json::Value = serde_json::from_str(&text).ok()?;
        let name = ledger.file_name()?.to_string_lossy().into_owned();
        // gravity.json records its one table's hash as `sha256`, beside no custody.
        if name == ingest::contract::gravity_ledger::LEDGER_FILE
            && want
                == format!(
                    "{}/{}",
                    ingest::contract::gravity_ledger::STAGE_DIR,
                    ingest::contract::tables::gravity::FILE
                )
        {
            return Some((name, v.get("sha256")?.as_str()?.to_owned()));
        }
        let custody: ingest::contract::custody::Custody =
            serde_json::from_value(v.get_mut("custody")?.take()).ok()?;
        let entry = custody.outputs.into_iter().find(|f| f.path == want)?;
        Some((name, entry.sha256))
    })
}

/// The rows of `reader` (a table of `rows` rows whose columns are `names`), as `options`
/// says.
fn print_rows(
    reader: parquet::arrow::arrow_reader::ParquetRecordBatchReader,
    names: &[String],
    rows: i64,
    options: ShowOptions,
    path: &Path,
    out: &mut impl Write,
) -> Result<()> {
    let limit = options.head.unwrap_or(usize::MAX);
    let mut lines: Vec<Vec<String>> = Vec::new();
    let mut printed = 0usize;
    for batch in reader {
        let batch = batch.with_context(|| format!("reading {}", path.display()))?;
        let take = (limit - printed).min(batch.num_rows());
        let cells = format_batch(&batch, take)?;
        printed += take;
        if options.csv {
            for row in cells {
                writeln!(
                    out,
                    "{}",
                    row.iter().map(|c| quote(c)).collect::<Vec<_>>().join(",")
                )?;
            }
        } else {
            lines.extend(cells);
        }
        if printed >= limit {
            break;
        }
    }
    if !options.csv {
        write_aligned(out, names, &lines)?;
        if (printed as i64) < rows {
            writeln!(
                out,
                "# ... {} more rows (--head N, or --csv for all)",
                rows - printed as i64
            )?;
        }
    }
    Ok(())
}

/// The header `names` and the rows `lines`, each column right-aligned to its widest cell.
fn write_aligned(out: &mut impl Write, names: &[String], lines: &[Vec<String>]) -> Result<()> {
    let widths: Vec<usize> = (0..names.len())
        .map(|c| {
            lines
                .iter()
                .map(|r| r[c].len())
                .chain([names[c].len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cells: &[String]| {
        cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:>w$}"))
            .collect::<Vec<_>>()
            .join("  ")
    };
    writeln!(out, "{}", line(names))?;
    for r in lines {
        writeln!(out, "{}", line(r))?;
    }
    Ok(())
}

/// The first `take` rows of `batch` as text, a row at a time.
fn format_batch(batch: &RecordBatch, take: usize) -> Result<Vec<Vec<String>>> {
    let columns = batch
        .columns()
        .iter()
        .zip(batch.schema().fields())
        .map(|(c, field)| {
            column_text(c.as_ref(), take)
                .with_context(|| format!("formatting column {}", field.name()))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((0..take)
        .map(|i| columns.iter().map(|c| c[i].clone()).collect())
        .collect())
}

/// The first `take` cells of `column` as text: a null empty, a float in Rust's shortest
/// form that reads back to the same bits (`-2.0`, `1e-7`), a dictionary's cell as its
/// value. A type gravcal's tables do not use is refused by name.
fn column_text(column: &dyn Array, take: usize) -> Result<Vec<String>> {
    macro_rules! cells {
        ($array:expr, $fmt:literal) => {{
            let a = $array;
            (0..take)
                .map(|i| {
                    if a.is_null(i) {
                        String::new()
                    } else {
                        format!($fmt, a.value(i))
                    }
                })
                .collect()
        }};
    }
    Ok(match column.data_type() {
        DataType::Float64 => cells!(column.as_primitive::<Float64Type>(), "{:?}"),
        DataType::Float32 => cells!(column.as_primitive::<Float32Type>(), "{:?}"),
        DataType::Int8 => cells!(column.as_primitive::<Int8Type>(), "{}"),
        DataType::Int16 => cells!(column.as_primitive::<Int16Type>(), "{}"),
        DataType::Int32 => cells!(column.as_primitive::<Int32Type>(), "{}"),
        DataType::Int64 => cells!(column.as_primitive::<Int64Type>(), "{}"),
        DataType::UInt8 => cells!(column.as_primitive::<UInt8Type>(), "{}"),
        DataType::UInt16 => cells!(column.as_primitive::<UInt16Type>(), "{}"),
        DataType::UInt32 => cells!(column.as_primitive::<UInt32Type>(), "{}"),
        DataType::UInt64 => cells!(column.as_primitive::<UInt64Type>(), "{}"),
        DataType::Boolean => cells!(column.as_boolean(), "{}"),
        DataType::Utf8 => cells!(column.as_string::<i32>(), "{}"),
        DataType::LargeUtf8 => cells!(column.as_string::<i64>(), "{}"),
        DataType::Dictionary(_, _) => {
            let dictionary = column.as_any_dictionary();
            let values = column_text(dictionary.values().as_ref(), dictionary.values().len())?;
            let keys = dictionary.normalized_keys();
            (0..take)
                .map(|i| {
                    if column.is_null(i) {
                        String::new()
                    } else {
                        values[keys[i]].clone()
                    }
                })
                .collect()
        }
        other => bail!("no text form for a column of {other}"),
    })
}

/// A CSV field, quoted when it holds a comma, a quote or a line break.
fn quote(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use arrow_array::{Float64Array, StringArray};
    use std::sync::Arc;

    /// `batch` written to `path` by parquet-rs.
    fn write_table(path: &Path, batch: &RecordBatch) {
        let mut w = parquet::arrow::ArrowWriter::try_new(
            std::fs::File::create(path).expect("create"),
            batch.schema(),
            None,
        )
        .expect("writer");
        w.write(batch).expect("write");
        w.close().expect("close");
    }

    /// A table written by parquet-rs, printed back: CSV with a null as an empty field and a
    /// comma quoted; aligned with its schema and a count of the rows left out.
    #[test]
    fn a_table_prints_as_csv_and_aligned() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("t.parquet");
        let batch = RecordBatch::try_from_iter([
            (
                "x",
                Arc::new(Float64Array::from(vec![Some(1.5), None, Some(-2.0)])) as _,
            ),
            (
                "why",
                Arc::new(StringArray::from(vec![Some("a, b"), Some("c"), None])) as _,
            ),
        ])
        .expect("batch");
        write_table(&path, &batch);
        let mut out = Vec::new();
        let csv = ShowOptions {
            csv: true,
            head: None,
        };
        show(&path, csv, &mut out).expect("show");
        assert_eq!(
            String::from_utf8(out).expect("utf-8"),
            "x,why\n1.5,\"a, b\"\n,c\n-2.0,\n"
        );
        let mut out = Vec::new();
        let aligned = ShowOptions {
            csv: false,
            head: Some(2),
        };
        show(&path, aligned, &mut out).expect("show");
        let text = String::from_utf8(out).expect("utf-8");
        assert!(
            text.contains("3 rows") && text.contains("# why: Utf8, may be null"),
            "{text}"
        );
        assert!(text.contains("1 more rows"), "{text}");
    }

    /// Every type gravcal's tables hold prints as its value: integers, a boolean, a float
    /// in its shortest round-trip form, a dictionary's name by its key, a null empty; a
    /// type they do not hold is refused by name.
    #[test]
    fn cells_of_every_type_gravcal_writes() {
        use arrow_array::types::Int32Type;
        use arrow_array::{BooleanArray, DictionaryArray, Int64Array, UInt16Array};
        let names: DictionaryArray<Int32Type> =
            vec![Some("b"), None, Some("a")].into_iter().collect();
        let columns: Vec<(arrow_array::ArrayRef, [&str; 3])> = vec![
            (
                Arc::new(Int64Array::from(vec![Some(-3), None, Some(7)])),
                ["-3", "", "7"],
            ),
            (
                Arc::new(UInt16Array::from(vec![1, 2, 65535])),
                ["1", "2", "65535"],
            ),
            (
                Arc::new(BooleanArray::from(vec![Some(true), Some(false), None])),
                ["true", "false", ""],
            ),
            (
                Arc::new(Float64Array::from(vec![1e-7, 0.1, 3.0])),
                ["1e-7", "0.1", "3.0"],
            ),
            (Arc::new(names), ["b", "", "a"]),
        ];
        for (column, want) in columns {
            assert_eq!(
                column_text(column.as_ref(), 3).expect("text"),
                want,
                "{column:?}"
            );
        }
        let dates = arrow_array::Date32Array::from(vec![1]);
        let e = column_text(&dates, 1)
            .expect_err("no text form")
            .to_string();
        assert!(e.contains("Date32"), "{e}");
    }

    /// A table listed by the ledger beside it is held to the SHA-256 recorded there: shown
    /// when it matches, shown and refused when its bytes changed; a table no ledger lists is
    /// shown as it is.
    #[test]
    fn a_table_changed_since_its_stage_wrote_it_is_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let stage = dir.path().join("ingest");
        std::fs::create_dir(&stage).expect("stage");
        let path = stage.join("t.parquet");
        let batch =
            RecordBatch::try_from_iter([("x", Arc::new(Float64Array::from(vec![1.5, 2.5])) as _)])
                .expect("batch");
        write_table(&path, &batch);
        let ledger = |sha: &str| {
            let text = serde_json::json!({
                "custody": {
                    "inputs": [],
                    "outputs": [{"root": "out", "path": "ingest/t.parquet", "sha256": sha}],
                },
            });
            std::fs::write(stage.join("ingest.json"), text.to_string()).expect("ledger");
        };
        let csv = ShowOptions {
            csv: true,
            head: None,
        };
        let sha = ingest::contract::custody::sha256_file(&path).expect("sha");
        ledger(&sha);
        let mut out = Vec::new();
        show(&path, csv, &mut out).expect("the recorded table");
        assert_eq!(String::from_utf8(out).expect("utf-8"), "x\n1.5\n2.5\n");
        ledger(&"0".repeat(64));
        let mut out = Vec::new();
        let err = show(&path, csv, &mut out).expect_err("a changed table");
        assert!(
            err.to_string().contains("not the table its stage wrote"),
            "{err}"
        );
        assert_eq!(String::from_utf8(out).expect("utf-8"), "x\n1.5\n2.5\n");
        std::fs::remove_file(stage.join("ingest.json")).expect("remove");
        show(&path, csv, &mut Vec::new()).expect("no ledger: shown as it is");
        // gravity.json's form: the one table's hash at the top.
        let gravity = dir.path().join("gravity");
        std::fs::create_dir(&gravity).expect("gravity");
        let table = gravity.join("gravity.parquet");
        std::fs::copy(&path, &table).expect("copy");
        let ledger = |sha: &str| {
            let text = serde_json::json!({"rows_written": 2, "sha256": sha});
            std::fs::write(gravity.join("gravity.json"), text.to_string()).expect("ledger");
        };
        ledger(&sha);
        show(&table, csv, &mut Vec::new()).expect("the recorded gravity table");
        ledger(&"0".repeat(64));
        show(&table, csv, &mut Vec::new()).expect_err("a changed gravity table");
    }
}
