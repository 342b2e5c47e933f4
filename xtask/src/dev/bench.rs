//! `cargo xtask bench`: speed and memory, measured on this machine, never asserted.
//!
//! `bench ingest` generates large logs (never committed) with the simulator, ingests them
//! with the release build, and converts the same CSV with polars and pyarrow (installed in a
//! throwaway virtualenv under target/) for comparison. Files are read from the page cache
//! (each is read once before timing); the fastest and the median of `--runs` runs (3) are
//! reported, with the CPU time (user + system) of the fastest.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const PEERS: &str = r##"
import resource, sys, time
path, out, method = sys.argv[1], sys.argv[2], sys.argv[3]
t0 = time.perf_counter()
if method == "polars-read-write":
    import polars as pl
    pl.read_csv(path, comment_prefix="#").write_parquet(out, compression="zstd")
elif method == "polars-sink":
    import polars as pl
    pl.scan_csv(path, comment_prefix="#").sink_parquet(out, compression="zstd")
elif method == "pyarrow":
    import pyarrow.csv as pc, pyarrow.parquet as pq
    t = pc.read_csv(path, read_options=pc.ReadOptions(skip_rows=1))
    pq.write_table(t, out, compression="zstd")
dt = time.perf_counter() - t0
r = resource.getrusage(resource.RUSAGE_SELF)
print(f"{dt} {r.ru_maxrss} {r.ru_utime + r.ru_stime}")
"##;

/// Reads an acceleration table with pyarrow, decoding every page: rows and, per column, the
/// sum of its values (nulls left out; pyarrow's int64 sum wraps), as JSON.
const PYARROW_READS: &str = r##"
import json, sys
import pyarrow.compute as pc, pyarrow.parquet as pq
t = pq.read_table(sys.argv[1])
print(json.dumps({"rows": t.num_rows,
                  "sums": {n: int(pc.sum(t[n]).as_py() or 0) for n in t.column_names}}))
"##;

/// The non-null values of an integer column (the acceleration table's types), widened to
/// i64 as pyarrow's sum widens them.
fn integers(column: &dyn arrow_array::Array) -> Result<Box<dyn Iterator<Item = i64> + '_>> {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Int32Type, Int64Type, UInt8Type, UInt16Type};
    use arrow_schema::DataType;
    macro_rules! widened {
        ($t:ty) => {
            Box::new(column.as_primitive::<$t>().iter().flatten().map(i64::from))
        };
    }
    Ok(match column.data_type() {
        DataType::Int64 => widened!(Int64Type),
        DataType::Int32 => widened!(Int32Type),
        DataType::UInt16 => widened!(UInt16Type),
        DataType::UInt8 => widened!(UInt8Type),
        other => bail!("a column of {other} in the acceleration table"),
    })
}

/// Checks that pyarrow (Arrow C++, an independent reader) decodes the acceleration table
/// ingest wrote into `out` to the rows ingest counted and the sums of the values it stored.
fn pyarrow_reads(py: &Path, script: &Path, out: &Path) -> Result<()> {
    let table = out
        .join("ingest")
        .join(ingest::contract::tables::acceleration::FILE);
    let o = Command::new(py).arg(script).arg(&table).output()?;
    if !o.status.success() {
        bail!(
            "pyarrow could not read {}: {}",
            table.display(),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let got: serde_json::Value = serde_json::from_slice(&o.stdout)?;
    let report = ingest::contract::ingest_ledger::IngestReport::load(&out.join("ingest"))?;
    let rows = report
        .tables
        .get(ingest::contract::tables::acceleration::FILE)
        .copied()
        .context("no acceleration table in ingest.json")?;
    if got["rows"].as_u64() != Some(rows) {
        bail!(
            "pyarrow read {} rows of {}, ingest wrote {rows}",
            got["rows"],
            table.display()
        );
    }
    // The same sums from the Parquet reader of the Rust side.
    let f = std::fs::File::open(&table)?;
    let reader =
        parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(f)?.build()?;
    // Wrapping, as pyarrow's sum does: the times' sum passes 2^63.
    let mut sums = std::collections::BTreeMap::<String, i64>::new();
    for batch in reader {
        let batch = batch?;
        for (field, column) in batch.schema().fields().iter().zip(batch.columns()) {
            let sum = sums.entry(field.name().clone()).or_default();
            *sum = integers(column.as_ref())
                .with_context(|| format!("column {}", field.name()))?
                .fold(*sum, i64::wrapping_add);
        }
    }
    for (name, sum) in &sums {
        let theirs = got["sums"][name].as_i64();
        if theirs != Some(*sum) {
            bail!("column {name}: pyarrow sums {theirs:?}, parquet-rs {sum}");
        }
    }
    eprintln!(
        "bench: pyarrow reads {} as parquet-rs does ({rows} rows, {} column sums)",
        table.display(),
        sums.len()
    );
    Ok(())
}

#[derive(Clone, Copy)]
pub(crate) struct Run {
    pub(crate) seconds: f64,
    pub(crate) peak_rss_mb: f64,
    /// CPU time, user plus system, if the program reported it.
    pub(crate) cpu_seconds: Option<f64>,
}

/// Runs `f` `n` times; the fastest run, and the median wall time.
pub(crate) fn best_of(n: usize, mut f: impl FnMut() -> Result<Run>) -> Result<(Run, f64)> {
    fastest_and_median((0..n).map(|_| f()).collect::<Result<Vec<_>>>()?)
}

/// The fastest of `runs` and the median's seconds.
pub(crate) fn fastest_and_median(mut runs: Vec<Run>) -> Result<(Run, f64)> {
    runs.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
    let median = runs.get(runs.len() / 2).context("no run")?.seconds;
    Ok((runs[0], median))
}

fn ingest_once(bin: &Path, dataset: &Path, out: &Path) -> Result<Run> {
    let _ = std::fs::remove_dir_all(out);
    stage_once(bin, dataset, out)
}

/// Runs a stage binary once; its peak RSS as it reports it.
fn stage_once(bin: &Path, dataset: &Path, out: &Path) -> Result<Run> {
    stage_once_with(bin, dataset, out, &[])
}

/// Runs a stage binary once with `extra` arguments; its peak RSS as it reports it.
pub(crate) fn stage_once_with(
    bin: &Path,
    dataset: &Path,
    out: &Path,
    extra: &[&std::ffi::OsStr],
) -> Result<Run> {
    let t0 = Instant::now();
    let o = Command::new(bin)
        .arg(dataset)
        .arg("--out")
        .arg(out)
        .args(extra)
        .arg("--report-peak-rss")
        .output()
        .with_context(|| format!("running {}", bin.display()))?;
    let seconds = t0.elapsed().as_secs_f64();
    if !o.status.success() {
        bail!(
            "{} failed: {}",
            bin.display(),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let stderr = String::from_utf8_lossy(&o.stderr);
    let kb: f64 = stderr
        .lines()
        .find_map(|l| l.strip_prefix("peak_rss_kb "))
        .and_then(|v| v.trim().parse().ok())
        .context("the stage binary did not report its peak RSS")?;
    let cpu_seconds = stderr
        .lines()
        .find_map(|l| l.strip_prefix("cpu_s "))
        .and_then(|v| v.trim().parse().ok());
    Ok(Run {
        seconds,
        peak_rss_mb: kb / 1024.0,
        cpu_seconds,
    })
}

pub(crate) fn venv_python(root: &Path) -> Result<PathBuf> {
    let venv = root.join("target/bench-venv");
    let py = venv.join("bin/python");
    if !py.exists() {
        eprintln!("bench: creating {} with polars and pyarrow", venv.display());
        let ok = Command::new("python3")
            .args(["-m", "venv"])
            .arg(&venv)
            .status()?
            .success();
        if !ok {
            bail!("python3 -m venv failed");
        }
    }
    let have = Command::new(&py)
        .args(["-c", "import polars, pyarrow"])
        .output()?
        .status
        .success();
    if !have {
        let ok = Command::new(&py)
            .args(["-m", "pip", "install", "-q", "polars", "pyarrow"])
            .status()?
            .success();
        if !ok {
            bail!("pip install polars pyarrow failed");
        }
    }
    Ok(py)
}

fn peer_once(py: &Path, script: &Path, csv: &Path, out: &Path, method: &str) -> Result<Run> {
    let o = Command::new(py)
        .arg(script)
        .arg(csv)
        .arg(out)
        .arg(method)
        .output()?;
    if !o.status.success() {
        bail!("{method} failed: {}", String::from_utf8_lossy(&o.stderr));
    }
    parse_peer_run(&String::from_utf8_lossy(&o.stdout))
}

/// A peer script's last line: seconds, peak RSS in kB, CPU seconds.
pub(crate) fn parse_peer_run(s: &str) -> Result<Run> {
    let mut it = s.split_whitespace();
    let seconds: f64 = it
        .next()
        .and_then(|x| x.parse().ok())
        .context("peer time")?;
    let kb: f64 = it.next().and_then(|x| x.parse().ok()).context("peer rss")?;
    Ok(Run {
        seconds,
        peak_rss_mb: kb / 1024.0,
        cpu_seconds: it.next().and_then(|x| x.parse().ok()),
    })
}

/// A CSV twin of a benchmark dataset: the same folder layout with hard links to its CSV
/// logs and a manifest naming them.
fn csv_twin(dataset: &Path) -> Result<PathBuf> {
    let twin = dataset.with_file_name(format!(
        "{}-csv",
        dataset.file_name().context("name")?.to_string_lossy()
    ));
    let _ = std::fs::remove_dir_all(&twin);
    std::fs::create_dir_all(twin.join("raw"))?;
    let manifest = std::fs::read_to_string(dataset.join("dataset.toml"))?;
    let mut out = String::new();
    for line in manifest.lines() {
        if let Some(rest) = line.strip_prefix("acquisition = \"raw/") {
            let id = rest.trim_end_matches(".gcb\"");
            out.push_str(&format!(
                "adc_csv = \"raw/{id}_adc.csv\"\ntemperature_csv = \"raw/{id}_temp.csv\"\n"
            ));
        } else if let Some(rest) = line.strip_prefix("name = \"") {
            out.push_str(&format!("name = \"{}-csv\"\n", rest.trim_end_matches('"')));
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    std::fs::write(twin.join("dataset.toml"), out)?;
    for entry in std::fs::read_dir(dataset.join("raw"))? {
        let p = entry?.path();
        let name = p.file_name().context("name")?;
        if !p.to_string_lossy().ends_with(".gcb") {
            std::fs::hard_link(&p, twin.join("raw").join(name))?;
        }
    }
    Ok(twin)
}

/// A lab-logger twin of a benchmark dataset's CSV twin: the ADC log rewritten in the
/// "seconds" layout (`t,x,y,z`, a header, seconds since 00:00 UTC of the session's date,
/// counts as readings) as a multi-position session, for the lab reader's figure beside
/// the CSV reader's on the same samples.
fn lab_twin(csv_twin: &Path) -> Result<PathBuf> {
    use std::io::{BufRead, Write};
    let name = csv_twin.file_name().context("name")?.to_string_lossy();
    let twin = csv_twin.with_file_name(format!("{}-lab", name.trim_end_matches("-csv")));
    let lab = twin.join("raw/long_lab.txt");
    let manifest = std::fs::read_to_string(csv_twin.join("dataset.toml"))?;
    let date = manifest
        .lines()
        .find_map(|l| l.strip_prefix("date = \""))
        .map(|d| d.trim_end_matches('"').to_owned())
        .context("no session date")?;
    if !lab.exists() {
        std::fs::create_dir_all(twin.join("raw"))?;
        let ymd: Vec<i32> = date
            .split('-')
            .map(|x| x.parse())
            .collect::<Result<_, _>>()?;
        let midnight = ingest::base::time::gps_ns(
            ingest::base::time::Calendar::midnight((ymd[0], ymd[1] as u8, ymd[2] as u8)),
            ingest::contract::manifest::TimeScale::Utc,
        )
        .context("date")?;
        let input =
            std::io::BufReader::new(std::fs::File::open(csv_twin.join("raw/long_adc.csv"))?);
        let tmp = lab.with_extension("partial");
        let mut out = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        writeln!(out, "t,x,y,z")?;
        for line in input.lines() {
            let line = line?;
            let mut f = line.split(',');
            let (Some(week), Some(tow)) = (f.next(), f.next()) else {
                continue;
            };
            let (Ok(week), Some((s, ms))) = (week.parse::<i64>(), tow.split_once('.')) else {
                continue;
            };
            let ns = (week * 604_800 + s.parse::<i64>()?) * 1_000_000_000
                + ms.parse::<i64>()? * 1_000_000
                - midnight;
            let rest: Vec<&str> = f.collect();
            writeln!(
                out,
                "{}.{:03},{}",
                ns / 1_000_000_000,
                (ns % 1_000_000_000) / 1_000_000,
                rest.join(",")
            )?;
        }
        out.flush()?;
        std::fs::rename(&tmp, &lab)?;
    }
    let adc = format!(
        "kind = \"multi-position\"\nadc_format = \"seconds\"\nadc_csv = \"raw/long_lab.txt\"\nstart = \"{date}T00:00:00\"\n"
    );
    let text = twin_manifest(&manifest, "lab", &adc, &["temperature_csv", "theodolite"]);
    std::fs::write(twin.join("dataset.toml"), text)?;
    Ok(twin)
}

/// A twin's manifest: the CSV twin's with its name's suffix `-csv` replaced by `-{suffix}`,
/// its `adc_csv` line by `adc`, and the lines starting with `drop` left out.
fn twin_manifest(manifest: &str, suffix: &str, adc: &str, drop: &[&str]) -> String {
    let mut text = String::new();
    for line in manifest.lines() {
        if line.starts_with("adc_csv") {
            text.push_str(adc);
        } else if drop.iter().any(|d| line.starts_with(d)) {
            continue;
        } else if let Some(rest) = line.strip_prefix("name = \"") {
            text.push_str(&format!(
                "name = \"{}-{suffix}\"\n",
                rest.trim_end_matches('"').trim_end_matches("-csv")
            ));
        } else {
            text.push_str(line);
            text.push('\n');
        }
    }
    text
}

/// An ISO-time twin of a benchmark dataset's CSV twin: the ADC CSV rewritten with ISO 8601
/// UTC times with `Z` (`adc_time = "iso"`, docs/formats.md 9.1), the temperature CSV and
/// theodolite log as they were, for the time form's figure beside the counts CSV's.
fn iso_twin(csv_twin: &Path) -> Result<PathBuf> {
    use std::io::{BufRead, Write};
    let name = csv_twin.file_name().context("name")?.to_string_lossy();
    let twin = csv_twin.with_file_name(format!("{}-iso", name.trim_end_matches("-csv")));
    let iso = twin.join("raw/long_iso.csv");
    if !iso.exists() {
        std::fs::create_dir_all(twin.join("raw"))?;
        let input =
            std::io::BufReader::new(std::fs::File::open(csv_twin.join("raw/long_adc.csv"))?);
        let tmp = iso.with_extension("partial");
        let mut out = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        writeln!(out, "time,c1,c2,c3")?;
        for line in input.lines() {
            let line = line?;
            let mut f = line.split(',');
            let (Some(week), Some(tow)) = (f.next(), f.next()) else {
                continue;
            };
            let (Ok(week), Some(tow_ns)) = (
                week.parse::<i64>(),
                ingest::base::time::parse_seconds_ns(tow.as_bytes()),
            ) else {
                continue;
            };
            let gps_ns = week * ingest::base::time::NS_PER_WEEK + tow_ns;
            let rest: Vec<&str> = f.collect();
            writeln!(
                out,
                "{},{}",
                ingest::base::time::utc_iso(gps_ns),
                rest.join(",")
            )?;
        }
        out.flush()?;
        std::fs::rename(&tmp, &iso)?;
    }
    for entry in std::fs::read_dir(csv_twin.join("raw"))? {
        let p = entry?.path();
        let file = p.file_name().context("name")?;
        let target = twin.join("raw").join(file);
        if !p.to_string_lossy().ends_with("_adc.csv") && !target.exists() {
            std::fs::hard_link(&p, target)?;
        }
    }
    let manifest = std::fs::read_to_string(csv_twin.join("dataset.toml"))?;
    let adc = "adc_csv = \"raw/long_iso.csv\"\nadc_time = \"iso\"\n";
    let text = twin_manifest(&manifest, "iso", adc, &[]);
    std::fs::write(twin.join("dataset.toml"), text)?;
    Ok(twin)
}

fn dir_bytes(dir: &Path, keep: impl Fn(&str) -> bool) -> Result<u64> {
    let mut total = 0;
    for entry in std::fs::read_dir(dir.join("raw"))? {
        let p = entry?.path();
        if keep(&p.to_string_lossy()) {
            total += std::fs::metadata(&p)?.len();
        }
    }
    Ok(total)
}

fn warm(dir: &Path) -> Result<()> {
    for entry in std::fs::read_dir(dir.join("raw"))? {
        let _ = std::fs::read(entry?.path())?;
    }
    Ok(())
}

/// The stage binaries the benchmarks time, built once for all of them: one `cargo build` of
/// the three packages, so that every benchmark shares one feature set (built one package at
/// a time, arrow and parquet were compiled twice on a clean machine, about 5 minutes of CI).
const STAGE_PACKAGES: [&str; 3] = ["ingest", "align", "adjust"];

/// The packages a dev build of the stage binaries names: the stages and xtask, whose
/// dependencies are the whole workspace, so that the build resolves the features the test
/// build did (a dev build of the three stages alone resolved some differently and compiled
/// arrow, parquet and faer again on a clean machine). `cargo xtask ci` checks it.
pub(crate) const DEV_PACKAGES: [&str; 4] = ["xtask", "ingest", "align", "adjust"];

/// Which build of the stage binaries a benchmark runs.
#[derive(Clone, Copy, Debug)]
pub enum Build {
    /// `cargo build --release`: what `cargo xtask bench` times and docs/benchmarks.md quotes.
    Release,
    /// The dev profile's binaries, which `cargo test --workspace` has already built with the
    /// same feature set (ingest/Cargo.toml): `cargo xtask ci`'s run on small sizes checks that
    /// every benchmark runs and agrees with its peer, not its speed, and a release build
    /// compiled arrow, parquet and faer a third time on a clean machine.
    Dev,
}

impl Build {
    /// Builds the stage binaries in this profile ([`STAGE_PACKAGES`], or [`DEV_PACKAGES`]);
    /// the folder holding them.
    pub(crate) fn stage_binaries(self, root: &Path) -> Result<PathBuf> {
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
        let (flag, folder, packages) = match self {
            Build::Release => (Some("--release"), "release", &STAGE_PACKAGES[..]),
            Build::Dev => (None, "debug", &DEV_PACKAGES[..]),
        };
        let mut args: Vec<&str> = std::iter::once("build").chain(flag).collect();
        for p in packages {
            args.extend(["-p", p]);
        }
        if !Command::new(&cargo)
            .args(&args)
            .current_dir(root)
            .status()?
            .success()
        {
            bail!("{folder} build of {} failed", packages.join(", "));
        }
        Ok(root.join("target").join(folder))
    }
}

/// Runs the align benchmark: `stations` x `readings` readings 3.2 s apart at 31.25 Hz.
pub fn align(root: &Path, stations: usize, readings: usize, build: Build) -> Result<()> {
    let bins = build.stage_binaries(root)?;
    let data = root.join("target/bench-data");
    let scenario = fixtures::catalog::bench_dense(stations, readings);
    let dataset = data.join(&scenario.name);
    if !dataset.join("dataset.toml").exists() {
        eprintln!("bench: generating {}", dataset.display());
        fixtures::write::write_dataset(&scenario, &dataset)?;
    }
    let out = data.join("out-align");
    let _ = std::fs::remove_dir_all(&out);
    ingest_once(&bins.join("gravcal-ingest"), &dataset, &out)?;
    let ledger = ingest::contract::ingest_ledger::IngestReport::load(&out.join("ingest"))?;
    let samples: u64 = ledger.sessions.iter().map(|s| s.acceleration_samples).sum();
    let readings_n: u64 = ledger.sessions.iter().map(|s| s.readings).sum();
    let (r, _) = best_of(3, || {
        stage_once(&bins.join("gravcal-align"), &dataset, &out)
    })?;
    let observations =
        ingest::contract::align_ledger::AlignReport::load(&out.join("align"))?.observations;
    println!("| samples | readings | observations | seconds | peak RSS MB |");
    println!("|---|---|---|---|---|");
    println!(
        "| {samples} | {readings_n} | {observations} | {:.2} | {:.0} |",
        r.seconds, r.peak_rss_mb
    );
    let _ = std::fs::remove_dir_all(&out);
    Ok(())
}

/// The adjust benchmark's `n` observations at gravity `g` mGal, as the CSV `bench-fit`
/// reads: tilts spread continuously from 109 to 140 deg, sds drawn as the simulator's.
fn adjust_observations(n: usize, g: f64) -> String {
    let (b, k) = (-29_497.03, 0.243_05);
    let mut rng = fixtures::rng::Rng::new(1, "bench-adjust");
    let mut text = String::with_capacity(n * 64);
    text.push_str("dz_rad,sigma_dz_rad,ng,sigma_ng\n");
    for _ in 0..n {
        let dz: f64 = rng.range(109.0, 140.0).to_radians();
        let sigma_dz = rng.lognormal_clipped(2.1, 0.45, 0.8, 4.5) / (g * dz.sin().abs());
        let sigma_ng = rng.lognormal_clipped(1.0, 0.5, 0.5, 2.5);
        let ng = (-g * dz.cos() - b) / k;
        text.push_str(&format!(
            "{:.12},{:.6e},{:.4},{:.4}\n",
            dz + sigma_dz * rng.normal(),
            sigma_dz,
            ng + sigma_ng * rng.normal(),
            sigma_ng
        ));
    }
    text
}

/// Runs the ingest benchmark; `hours` scales the logs (31.25 Hz for 2x hours, 250 Hz for
/// hours); each program runs `runs` times.
pub fn ingest(root: &Path, hours: f64, peers: bool, runs: usize, build: Build) -> Result<()> {
    let bin = build.stage_binaries(root)?.join("gravcal-ingest");
    let data = root.join("target/bench-data");
    let py = if peers {
        Some(venv_python(root)?)
    } else {
        None
    };
    let script = data.join("peers.py");
    std::fs::create_dir_all(&data)?;
    std::fs::write(&script, PEERS)?;
    std::fs::write(data.join("pyarrow_reads.py"), PYARROW_READS)?;
    let mut rows = Vec::new();
    for (interval_ms, h) in [(32u32, 2.0 * hours), (4u32, hours)] {
        let scenario = fixtures::catalog::bench(interval_ms, h);
        let dataset = data.join(&scenario.name);
        if !dataset.join("dataset.toml").exists() {
            eprintln!("bench: generating {}", dataset.display());
            fixtures::write::write_dataset(&scenario, &dataset)?;
        }
        let twin = csv_twin(&dataset)?;
        let lab = lab_twin(&twin)?;
        let iso = iso_twin(&twin)?;
        let rate = 1000.0 / f64::from(interval_ms);
        let out = data.join("out");
        for (label, ds, keep) in [
            (
                "gravcal ingest, binary .gcb",
                &dataset,
                (|p: &str| !p.ends_with(".csv")) as fn(&str) -> bool,
            ),
            ("gravcal ingest, CSV", &twin, |p: &str| !p.ends_with(".gcb")),
            (
                "gravcal ingest, CSV with ISO 8601 times (ADC)",
                &iso,
                |p: &str| !p.ends_with(".gcb"),
            ),
            (
                "gravcal ingest, lab seconds layout (ADC only)",
                &lab,
                |p: &str| p.ends_with("_lab.txt"),
            ),
        ] {
            warm(ds)?;
            let bytes = dir_bytes(ds, keep)?;
            let r = best_of(runs, || ingest_once(&bin, ds, &out))?;
            rows.push((format!("{rate} Hz, {h} h"), label.to_owned(), bytes, r));
            if let Some(py) = &py {
                pyarrow_reads(py, &data.join("pyarrow_reads.py"), &out)?;
            }
        }
        if let Some(py) = &py {
            let csv = twin.join("raw/long_adc.csv");
            let bytes = std::fs::metadata(&csv)?.len();
            for method in ["polars-read-write", "polars-sink", "pyarrow"] {
                let r = best_of(runs, || {
                    peer_once(py, &script, &csv, &data.join("peer.parquet"), method)
                })?;
                rows.push((
                    format!("{rate} Hz, {h} h"),
                    format!("{method} (ADC CSV only)"),
                    bytes,
                    r,
                ));
            }
        }
        let _ = std::fs::remove_dir_all(&out);
    }
    print_ingest_table(rows);
    Ok(())
}

/// The ingest benchmark's table: per row the log, what read it, the input's bytes and the
/// fastest run with the median's seconds.
fn print_ingest_table(rows: Vec<(String, String, u64, (Run, f64))>) {
    println!(
        "| log | what | input MB | seconds (fastest) | MB/s (fastest) | MB/s (median) | CPU s | peak RSS MB |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (log, what, bytes, (r, median)) in rows {
        let mb = bytes as f64 / 1e6;
        let cpu = r.cpu_seconds.map_or("-".to_owned(), |c| format!("{c:.2}"));
        println!(
            "| {log} | {what} | {mb:.0} | {:.2} | {:.0} | {:.0} | {cpu} | {:.0} |",
            r.seconds,
            mb / r.seconds,
            mb / median,
            r.peak_rss_mb
        );
    }
}

const ODR: &str = r##"
import json, resource, sys, time, warnings
import numpy as np
warnings.simplefilter("ignore")
path, g = sys.argv[1], float(sys.argv[2])
d = np.loadtxt(path, delimiter=",", skiprows=1)
dz, sdz, ng, sng = d[:, 0], d[:, 1], d[:, 2], d[:, 3]
# The same errors-in-both-variables line, explicit: Ng = a + c F, F = -g cos Dz with
# sd g |sin Dz| sd_Dz, Ng with sd_Ng.
F = -g * np.cos(dz)
sF = g * np.abs(np.sin(dz)) * sdz
try:
    from scipy import odr
    which = "scipy.odr"
except ImportError:
    import odrpack as odr
    which = "odrpack"
t0, c0 = time.perf_counter(), time.process_time()
# unilinear: y = beta[0] x + beta[1]; start near the answer.
fit = odr.ODR(odr.RealData(F, ng, sx=sF, sy=sng), odr.unilinear, beta0=[4.0, 1e5]).run()
dt, cpu = time.perf_counter() - t0, time.process_time() - c0
slope, intercept = fit.beta
print(json.dumps({"seconds": dt, "cpu_seconds": cpu, "which": which, "k": 1 / slope, "b": -intercept / slope,
                  "stop": "; ".join(fit.stopreason),
                  "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}))
"##;

/// Runs of each program in the adjust benchmark; the fastest is printed (a shared 2-core
/// machine's runs of either spread by a factor of 1.5).
const ADJUST_RUNS: usize = 3;

/// The fastest of `runs` runs of `run` (each printing the JSON of one fit) by its `seconds`.
fn fastest_json(
    runs: usize,
    mut run: impl FnMut() -> Result<serde_json::Value>,
) -> Result<serde_json::Value> {
    let mut best: Option<serde_json::Value> = None;
    for _ in 0..runs {
        let v = run()?;
        let secs = |x: &serde_json::Value| x["seconds"].as_f64().unwrap_or(f64::INFINITY);
        if best.as_ref().is_none_or(|b| secs(&v) < secs(b)) {
            best = Some(v);
        }
    }
    best.ok_or_else(|| anyhow::anyhow!("no run"))
}

/// A fit's CPU seconds as the table prints them.
fn cpu_cell(v: &serde_json::Value) -> String {
    v["cpu_seconds"]
        .as_f64()
        .map_or("-".to_owned(), |c| format!("{c:.2}"))
}

/// Runs the adjust benchmark: `n` observations of the linear model, gravcal against scipy's
/// ODR, each the fastest of [`ADJUST_RUNS`] runs.
pub fn adjust(root: &Path, n: usize, peers: bool, build: Build) -> Result<()> {
    let bins = build.stage_binaries(root)?;
    let data = root.join("target/bench-data");
    std::fs::create_dir_all(&data)?;
    let csv = data.join(format!("adjust-{n}.csv"));
    let g = 980_855.7;
    std::fs::write(&csv, adjust_observations(n, g))?;
    let ours = fastest_json(ADJUST_RUNS, || {
        let run = Command::new(bins.join("gravcal-adjust"))
            .args(["bench-fit", "--input"])
            .arg(&csv)
            .args(["--g-mgal", &g.to_string()])
            .output()?;
        if !run.status.success() {
            bail!("bench-fit failed: {}", String::from_utf8_lossy(&run.stderr));
        }
        Ok(serde_json::from_slice(&run.stdout)?)
    })?;
    println!(
        "| what | observations | seconds (fastest of {ADJUST_RUNS}) | CPU s | peak RSS MB | k (mGal/bit) |"
    );
    println!("|---|---|---|---|---|---|");
    let secs = ours["seconds"].as_f64().unwrap_or(f64::NAN);
    println!(
        "| gravcal Gauss-Helmert ({} iterations, one adjustment; {} w-tests above 3.29 not removed) | {n} | {secs:.3} | {} | {:.0} | {} |",
        ours["iterations"],
        ours["flagged"],
        cpu_cell(&ours),
        ours["peak_rss_kb"].as_f64().unwrap_or(0.0) / 1024.0,
        ours["k"]
    );
    if peers {
        let py = venv_python(root)?;
        let ok = Command::new(&py)
            .args(["-c", "import scipy"])
            .output()?
            .status
            .success();
        if !ok
            && !Command::new(&py)
                .args(["-m", "pip", "install", "-q", "scipy"])
                .status()?
                .success()
        {
            bail!("pip install scipy failed");
        }
        let script = data.join("odr.py");
        std::fs::write(&script, ODR)?;
        let odr = fastest_json(ADJUST_RUNS, || {
            let o = Command::new(&py)
                .arg(&script)
                .arg(&csv)
                .arg(g.to_string())
                .output()?;
            if !o.status.success() {
                bail!("ODR failed: {}", String::from_utf8_lossy(&o.stderr));
            }
            Ok(serde_json::from_slice(&o.stdout)?)
        })?;
        let osecs = odr["seconds"].as_f64().unwrap_or(f64::NAN);
        println!(
            "| {} (explicit line, same data; {}) | {n} | {osecs:.3} | {} | {:.0} | {} |",
            odr["which"].as_str().unwrap_or("odr"),
            odr["stop"].as_str().unwrap_or("?"),
            cpu_cell(&odr),
            odr["peak_rss_kb"].as_f64().unwrap_or(0.0) / 1024.0,
            odr["k"]
        );
        println!("\nODR / gravcal time ratio: {:.1}", osecs / secs);
        if let (Some(c), Some(oc)) = (ours["cpu_seconds"].as_f64(), odr["cpu_seconds"].as_f64()) {
            println!("ODR / gravcal CPU-time ratio: {:.1}", oc / c);
        }
    }
    Ok(())
}
