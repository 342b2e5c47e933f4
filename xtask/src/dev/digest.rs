//! `cargo xtask digest`: the refactoring net. Every fixture of `fixtures::catalog::ALL` goes
//! through the six stages that apply to it (ingest, align, adjust; apply and gravity on the
//! survey fixtures of [`SURVEYS`]; then report) into a scratch folder, and each output is
//! summarised in lines `fixture/stage/file key value [scale]`:
//!
//! - a Parquet table: its rows, and per column its nulls and, for a number column, the sum
//!   and the sum of magnitudes of its values (NaN counted apart);
//! - a JSON ledger: each leaf by its path, the SHA-256 of files left out (a hash follows its
//!   table's bytes, which the table's own lines already cover at a tolerance);
//! - any other file (the report's HTML and Markdown): its SHA-256.
//!
//! `--check FILE` compares a run with the committed summary (`fixtures/digests.txt`, written
//! by `--write FILE`): every key there and nothing else, texts and integers equal, floats
//! within [`TOLERANCE`] of the larger of their value and their scale (a column's sum is
//! scaled by its sum of magnitudes), so that a platform whose libm rounds a last bit
//! otherwise passes, and a change of a value anywhere fails, naming the key.

use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::Path;

/// Runs the named stages on a dataset into an output folder (xtask's `run_stages`).
pub type Stages<'a> = &'a dyn Fn(&Path, &Path, &[&str]) -> Result<()>;

/// The relative tolerance of a float in the summary.
pub const TOLERANCE: f64 = 1e-9;

/// A survey fixture reduced past the pipeline.
pub struct Survey {
    /// The fixture.
    pub fixture: &'static str,
    /// The fixture whose calibration is applied (earlier in `ALL`).
    pub calibration_of: &'static str,
    /// Its model and the session it was fitted on, where it holds several.
    pub model: Option<&'static str>,
    pub session: Option<&'static str>,
    /// Whether gravity reduces it (it has a trajectory), else apply alone.
    pub gravity: bool,
}

/// survey applied with esgt-2005's thermal calibration and survey-lines reduced with
/// triad-multipos's triad, as their tests do (`adjust/tests/survey.rs`, `gravity_stage.rs`).
pub const SURVEYS: [Survey; 2] = [
    Survey {
        fixture: "survey",
        calibration_of: "esgt-2005",
        model: Some("thermal"),
        session: None,
        gravity: false,
    },
    Survey {
        fixture: fixtures::survey_lines::SURVEY_LINES,
        calibration_of: fixtures::triad::MULTIPOS,
        model: None,
        session: Some("lab"),
        gravity: true,
    },
];

/// The stages' folders, in the order they run.
const FOLDERS: [&str; 6] = ["ingest", "align", "adjust", "apply", "gravity", "report"];

/// Runs every fixture into `scratch` and returns its summary lines, in a fixed order.
pub fn summarise(scratch: &Path, run: Stages<'_>) -> Result<Vec<String>> {
    let mut lines = Vec::new();
    for name in fixtures::catalog::ALL {
        let out = scratch.join(name);
        let dataset = fixtures::dataset_dir(name);
        run(&dataset, &out, &["ingest", "align", "adjust"])?;
        if let Some(s) = SURVEYS.iter().find(|s| s.fixture == name) {
            survey(&dataset, &out, s, &scratch.join(s.calibration_of))?;
        }
        run(&dataset, &out, &["report"])?;
        for stage in FOLDERS {
            let dir = out.join(stage);
            if !dir.is_dir() {
                continue;
            }
            let mut files = Vec::new();
            files_under(&dir, &mut files)?;
            files.sort();
            for p in files {
                let rel = p.strip_prefix(scratch).unwrap_or(&p).display().to_string();
                for (key, value) in summary(&p).with_context(|| format!("summarising {rel}"))? {
                    lines.push(format!("{rel} {key} {}", placed(&value, scratch)));
                }
            }
        }
    }
    Ok(lines)
}

/// Every file under `dir`, its subfolders' (the report's plots) included.
fn files_under(dir: &Path, out: &mut Vec<std::path::PathBuf>) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let p = e?.path();
        match p.is_dir() {
            true => files_under(&p, out)?,
            false => out.push(p),
        }
    }
    Ok(())
}

/// `value` with the scratch folder and the workspace written as `$OUT` and `$ROOT`, which
/// move from run to run and machine to machine.
fn placed(value: &str, scratch: &Path) -> String {
    let root = fixtures::dataset_dir(fixtures::catalog::ALL[0]);
    let root = root.parent().and_then(Path::parent).unwrap_or(&root);
    value
        .replace(&scratch.display().to_string(), "$OUT")
        .replace(&root.display().to_string(), "$ROOT")
}

/// Apply (and gravity, where `s` says) on `dataset` into `out`, with the calibration the
/// fixture whose output folder is `from` fitted.
fn survey(dataset: &Path, out: &Path, s: &Survey, from: &Path) -> Result<()> {
    let apply = adjust::survey::apply::stream::ApplyArgs {
        dataset: dataset.to_path_buf(),
        calibration: from.join("adjust").join("calibration.json"),
        model: s.model.map(str::to_owned),
        session: s.session.map(str::to_owned),
        out: Some(out.to_path_buf()),
    };
    if !s.gravity {
        apply.run(out)?;
        return Ok(());
    }
    // Gravity runs apply itself.
    let gravity = adjust::survey::gravity::stage::GravityArgs {
        apply,
        accelerometer: None,
        skip_bad_lines: false,
        block_epochs: None,
    };
    gravity.run(out)?;
    Ok(())
}

/// One output's summary: (key, value) pairs.
fn summary(path: &Path) -> Result<Vec<(String, String)>> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("parquet") => parquet_summary(path),
        Some("json") => {
            let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path)?)?;
            let mut out = Vec::new();
            json_leaves("json", &v, &mut out);
            Ok(out)
        }
        _ => Ok(vec![(
            "sha256".to_owned(),
            ingest::contract::custody::sha256_file(path)?,
        )]),
    }
}

/// Each leaf of `v` under `at` (objects by key, arrays by index), `sha256` keys left out.
fn json_leaves(at: &str, v: &serde_json::Value, out: &mut Vec<(String, String)>) {
    use serde_json::Value;
    match v {
        Value::Object(m) => {
            for (k, v) in m {
                if k != "sha256" {
                    json_leaves(&format!("{at}.{k}"), v, out);
                }
            }
        }
        Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                json_leaves(&format!("{at}[{i}]"), v, out);
            }
        }
        Value::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => out.push((at.to_owned(), i.to_string())),
            (None, Some(f)) => out.push((at.to_owned(), float(f))),
            _ => out.push((at.to_owned(), n.to_string())),
        },
        Value::String(s) => out.push((at.to_owned(), format!("{s:?}"))),
        other => out.push((at.to_owned(), other.to_string())),
    }
}

/// A float as the summary writes it (marked `f`, so the comparison knows it for one).
fn float(f: f64) -> String {
    format!("f{f:.15e}")
}

/// A table's rows, and per column its nulls and, for numbers, the sum, the sum of
/// magnitudes and the NaNs (each column's values as doubles).
fn parquet_summary(path: &Path) -> Result<Vec<(String, String)>> {
    use arrow_array::Array;
    let file = std::fs::File::open(path)?;
    let reader =
        parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)?.build()?;
    let mut rows = 0usize;
    let mut columns: BTreeMap<usize, (String, usize, Option<[f64; 3]>)> = BTreeMap::new();
    for batch in reader {
        let batch = batch?;
        rows += batch.num_rows();
        for (i, field) in batch.schema().fields().iter().enumerate() {
            let c = batch.column(i);
            let entry = columns
                .entry(i)
                .or_insert_with(|| (field.name().clone(), 0, Some([0.0; 3])));
            entry.1 += c.null_count();
            let doubles = column_doubles(c.as_ref());
            match (doubles, &mut entry.2) {
                (Some(v), Some(acc)) => {
                    for x in v.into_iter().flatten() {
                        match x.is_nan() {
                            true => acc[2] += 1.0,
                            false => {
                                acc[0] += x;
                                acc[1] += x.abs();
                            }
                        }
                    }
                }
                _ => entry.2 = None,
            }
        }
    }
    let mut out = vec![("rows".to_owned(), rows.to_string())];
    for (name, nulls, sums) in columns.into_values() {
        out.push((format!("{name}.nulls"), nulls.to_string()));
        if let Some([sum, abs, nans]) = sums {
            out.push((
                format!("{name}.sum"),
                format!("{} {}", float(sum), float(abs)),
            ));
            out.push((format!("{name}.abs"), float(abs)));
            out.push((format!("{name}.nans"), (nans as u64).to_string()));
        }
    }
    Ok(out)
}

/// A numeric column's values as doubles (None where null); None for a column of another
/// type (strings, dictionaries).
fn column_doubles(c: &dyn arrow_array::Array) -> Option<Vec<Option<f64>>> {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{
        Float32Type, Float64Type, Int8Type, Int16Type, Int32Type, Int64Type, UInt8Type, UInt16Type,
        UInt32Type, UInt64Type,
    };
    use arrow_schema::DataType as T;
    macro_rules! doubles {
        // 64-bit integers beyond 2^53 lose their last digits: a sum's scale, not its key.
        (wide $t:ty) => {
            c.as_primitive::<$t>()
                .iter()
                .map(|v| v.map(|x| x as f64))
                .collect()
        };
        ($t:ty) => {
            c.as_primitive::<$t>()
                .iter()
                .map(|v| v.map(f64::from))
                .collect()
        };
    }
    Some(match c.data_type() {
        T::Float64 => doubles!(Float64Type),
        T::Float32 => doubles!(Float32Type),
        T::Int8 => doubles!(Int8Type),
        T::Int16 => doubles!(Int16Type),
        T::Int32 => doubles!(Int32Type),
        T::Int64 => doubles!(wide Int64Type),
        T::UInt8 => doubles!(UInt8Type),
        T::UInt16 => doubles!(UInt16Type),
        T::UInt32 => doubles!(UInt32Type),
        T::UInt64 => doubles!(wide UInt64Type),
        T::Boolean => c
            .as_boolean()
            .iter()
            .map(|v| v.map(|b| f64::from(u8::from(b))))
            .collect(),
        _ => return None,
    })
}

/// The differences between the `committed` summary and this run's `now`, each naming its
/// key: a key missing or new, a text or integer changed, a float beyond [`TOLERANCE`].
pub fn compare(committed: &str, now: &[String]) -> Vec<String> {
    let split = |l: &str| -> Option<(String, String)> {
        let mut parts = l.splitn(3, ' ');
        let (file, key, value) = (parts.next()?, parts.next()?, parts.next()?);
        Some((format!("{file} {key}"), value.to_owned()))
    };
    let old: BTreeMap<String, String> = committed.lines().filter_map(split).collect();
    let new: BTreeMap<String, String> = now.iter().filter_map(|l| split(l)).collect();
    let mut out = Vec::new();
    for (k, v) in &old {
        match new.get(k) {
            None => out.push(format!("{k}: gone (was {v})")),
            Some(w) if !same(v, w) => out.push(format!("{k}: {v} now {w}")),
            Some(_) => {}
        }
    }
    for (k, w) in &new {
        if !old.contains_key(k) {
            out.push(format!("{k}: new ({w})"));
        }
    }
    out
}

/// Two values alike: equal, or floats (with their scales) within [`TOLERANCE`].
fn same(a: &str, b: &str) -> bool {
    if a == b {
        return true;
    }
    let parse = |s: &str| -> Option<Vec<f64>> {
        s.split(' ')
            .map(|t| t.strip_prefix('f').and_then(|x| x.parse().ok()))
            .collect()
    };
    match (parse(a), parse(b)) {
        (Some(x), Some(y)) if x.len() == y.len() && !x.is_empty() => {
            let scale = x[1..]
                .iter()
                .chain(&y[1..])
                .fold(0.0f64, |m, v| m.max(v.abs()));
            let bound = TOLERANCE * x[0].abs().max(y[0].abs()).max(scale);
            (x[0] - y[0]).abs() <= bound || (x[0].is_nan() && y[0].is_nan())
        }
        _ => false,
    }
}

/// `cargo xtask digest [--check FILE | --write FILE]`.
pub fn command(run: Stages<'_>, (check, write): (Option<&Path>, Option<&Path>)) -> Result<()> {
    let scratch = std::env::temp_dir().join(format!("gravcal-digest-{}", std::process::id()));
    let lines = summarise(&scratch, run);
    let _ = std::fs::remove_dir_all(&scratch);
    let lines = lines?;
    if let Some(path) = write {
        std::fs::write(path, lines.join("\n") + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
        eprintln!(
            "digest: {} lines written to {}",
            lines.len(),
            path.display()
        );
    }
    if let Some(path) = check {
        let committed =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let differences = compare(&committed, &lines);
        if !differences.is_empty() {
            for d in differences.iter().take(50) {
                eprintln!("digest: {d}");
            }
            bail!(
                "{} of {} summary lines differ from {} (at {TOLERANCE:e} for floats); if the \
                 change is meant, write it again: `cargo xtask digest --write {}`",
                differences.len(),
                lines.len(),
                path.display(),
                path.display()
            );
        }
        eprintln!("digest: {} lines as {}", lines.len(), path.display());
    }
    if check.is_none() && write.is_none() {
        for l in &lines {
            println!("{l}");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A float within the tolerance of its scale passes, beyond it fails; a text changed,
    /// a key gone and a key new each fail by name.
    #[test]
    fn the_comparison_holds_floats_to_their_tolerance_and_texts_exactly() {
        let committed = "a/t.parquet x.sum f1.000000000000000e0 f1.000000000000000e3\n\
                         a/t.parquet rows 10\na/l.json json.id \"x\"\na/l.json json.gone 1\n";
        let within = vec![
            "a/t.parquet x.sum f1.000000000100000e0 f1.000000000000000e3".to_owned(),
            "a/t.parquet rows 10".to_owned(),
            "a/l.json json.id \"x\"".to_owned(),
            "a/l.json json.gone 1".to_owned(),
        ];
        assert!(compare(committed, &within).is_empty());
        let beyond = vec![
            "a/t.parquet x.sum f1.000010000000000e0 f1.000000000000000e3".to_owned(),
            "a/t.parquet rows 11".to_owned(),
            "a/l.json json.id \"y\"".to_owned(),
            "a/l.json json.new 1".to_owned(),
        ];
        let d = compare(committed, &beyond);
        for key in ["x.sum", "rows", "json.id", "json.gone", "json.new"] {
            assert!(d.iter().any(|l| l.contains(key)), "{key}: {d:?}");
        }
        assert_eq!(d.len(), 5, "{d:?}");
    }
}
