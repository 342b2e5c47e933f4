//! `cargo xtask bench apply`: the calibration applied to the 250 Hz benchmark log, gravcal
//! beside polars doing the same arithmetic, in one run; measured, never asserted.
//!
//! The calibration is esgt-2005's thermal model with accelerometer 2 left connected on day
//! 2 (so all three have a fit), made in-process. The log is ingested once, untimed; then
//! each program reads the ingested Parquet tables, interpolates each channel's temperature
//! linearly in time (10 s gap limit), evaluates a = b + k Ng + (b_t + k_t Ng)(T - t_ref),
//! its sigma from the 4 x 4 covariance, the range flags, and writes zstd Parquet. Two log
//! lengths (`hours` and a quarter of it) show whether peak memory grows with the log.

use super::bench::Build;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::process::Command;

/// polars: the same arithmetic. Temperature rows where all three channels have a value (the
/// benchmark log has no disconnection); interpolation by a backward and a forward as-of
/// join per session; `lazy` streams (scan, sink), `eager` collects and writes.
const POLARS: &str = r##"
import json, resource, sys, time
import polars as pl
acc_path, temp_path, cal_path, out, method = sys.argv[1:6]
cal = json.load(open(cal_path))
channel = {a["id"]: a["channel"] for a in cal["accelerometers"]}
fits = {r["accelerometer"]: r for r in cal["results"] if r["model"] == "thermal"}
gap = 10_000_000_000
t0 = time.perf_counter()
temp = (pl.scan_parquet(temp_path)
        .drop_nulls(["temperature_ch1_c", "temperature_ch2_c", "temperature_ch3_c"])
        .select("session_index", "time_gps_ns", "temperature_ch1_c", "temperature_ch2_c",
                "temperature_ch3_c"))
before = temp.rename({c: c + "_0" for c in temp.collect_schema().names() if c != "session_index"})
after = temp.rename({c: c + "_1" for c in temp.collect_schema().names() if c != "session_index"})
lf = (pl.scan_parquet(acc_path)
      .join_asof(before, left_on="time_gps_ns", right_on="time_gps_ns_0", by="session_index",
                 strategy="backward")
      .join_asof(after, left_on="time_gps_ns", right_on="time_gps_ns_1", by="session_index",
                 strategy="forward"))
t = pl.col("time_gps_ns")
t0c, t1c = pl.col("time_gps_ns_0"), pl.col("time_gps_ns_1")
cols = [pl.col("session_index"), t]
for acc, r in fits.items():
    ch = channel[acc]
    v0, v1 = pl.col(f"temperature_ch{ch}_c_0"), pl.col(f"temperature_ch{ch}_c_1")
    w = (t - t0c).cast(pl.Float64) / (t1c - t0c).cast(pl.Float64)
    near = pl.min_horizontal(t - t0c, t1c - t)
    T = (pl.when(t0c.is_not_null() & t1c.is_not_null() & (t1c > t0c))
         .then(pl.when(near <= gap).then(v0 + w * (v1 - v0)))
         .when(t0c.is_not_null() & t1c.is_not_null())
         .then(pl.when(t - t0c <= gap).then(v0))
         .when(t0c.is_not_null()).then(pl.when(t - t0c <= gap).then(v0))
         .otherwise(pl.when(t1c - t <= gap).then(v1)))
    names = [p["name"] for p in r["parameters"]]
    idx = [names.index(n) for n in ("b", "k", "b_t", "k_t")]
    p = [r["parameters"][i]["value"] for i in idx]
    s = [r["parameters"][i]["sigma"] for i in idx]
    C = [[s[a] * s[b] * r["correlation"][idx[a]][idx[b]] for b in range(4)] for a in range(4)]
    ng = pl.col(f"counts_ch{ch}").cast(pl.Float64)
    tau = T - r["t_ref_c"]
    J = [pl.lit(1.0), ng, tau, tau * ng]
    a = p[0] + p[1] * ng + (p[2] + p[3] * ng) * tau
    var = sum(J[i] * J[j] * C[i][j] for i in range(4) for j in range(4))
    lo, hi = r["counts_range"]
    tlo, thi = r["temperature_range_c"]
    flags = (((ng < lo) | (ng > hi)).cast(pl.UInt8).fill_null(0)
             + ((T < tlo) | (T > thi)).cast(pl.UInt8).fill_null(0) * 2
             + T.is_null().cast(pl.UInt8) * 4)
    cols += [a.alias(f"{acc}_acceleration_mgal"), var.sqrt().alias(f"{acc}_sigma_mgal"),
             T.alias(f"{acc}_temperature_c"), flags.alias(f"{acc}_flags")]
lf = lf.select(cols)
if method == "lazy":
    lf.sink_parquet(out, compression="zstd")
else:
    lf.collect().write_parquet(out, compression="zstd")
dt = time.perf_counter() - t0
r = resource.getrusage(resource.RUSAGE_SELF)
print(f"{dt} {r.ru_maxrss} {r.ru_utime + r.ru_stime}")
"##;

/// esgt-2005 with accelerometer 2 connected on both days, calibrated in `dir`; returns its
/// calibration.json.
fn calibration(dir: &Path) -> Result<PathBuf> {
    let mut s = fixtures::catalog::esgt_2005(fixtures::scenario::LogFormat::Binary);
    s.name = "bench-apply-calibration".to_owned();
    for session in &mut s.sessions {
        session.disconnected = [false; 3];
    }
    let dataset = dir.join(&s.name);
    let out = dir.join("out-apply-calibration");
    let cal = out.join("adjust/calibration.json");
    if !cal.exists() {
        eprintln!("bench: calibrating {}", dataset.display());
        fixtures::write::write_dataset(&s, &dataset)?;
        ingest::run(&dataset, &out)?;
        align::run(&dataset, &out)?;
        let c = adjust::run(&dataset, &out)?;
        let thermal = c.results.iter().filter(|r| r.model == "thermal").count();
        if thermal != 3 {
            bail!("the benchmark's calibration has {thermal} thermal fits, not 3");
        }
    }
    Ok(cal)
}

/// Runs gravcal-apply once on an ingested OUT.
fn gravcal_once(bin: &Path, dataset: &Path, cal: &Path, out: &Path) -> Result<super::bench::Run> {
    super::bench::stage_once_with(
        bin,
        dataset,
        out,
        &[
            "--calibration".as_ref(),
            cal.as_os_str(),
            "--model".as_ref(),
            "thermal".as_ref(),
        ],
    )
}

fn polars_once(
    py: &Path,
    script: &Path,
    ingested: &Path,
    cal: &Path,
    method: &str,
) -> Result<super::bench::Run> {
    let out = ingested.join("polars-applied.parquet");
    let o = Command::new(py)
        .arg(script)
        .arg(ingested.join(ingest::contract::tables::acceleration::FILE))
        .arg(ingested.join(ingest::contract::tables::temperature::FILE))
        .arg(cal)
        .arg(&out)
        .arg(method)
        .output()?;
    if !o.status.success() {
        bail!(
            "polars {method} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    super::bench::parse_peer_run(&String::from_utf8_lossy(&o.stdout))
}

/// The apply benchmark on `hours` and `hours / 4` of the 250 Hz log.
pub fn apply(root: &Path, hours: f64, peers: bool, runs: usize, build: Build) -> Result<()> {
    let bin = build.stage_binaries(root)?.join("gravcal-apply");
    let data = root.join("target/bench-data");
    std::fs::create_dir_all(&data)?;
    let cal = calibration(&data)?;
    let py = if peers {
        Some(super::bench::venv_python(root)?)
    } else {
        None
    };
    let script = data.join("polars_apply.py");
    std::fs::write(&script, POLARS)?;
    let mut rows = Vec::new();
    for h in [hours / 4.0, hours] {
        let scenario = fixtures::catalog::bench(4, h);
        let dataset = data.join(&scenario.name);
        if !dataset.join("dataset.toml").exists() {
            eprintln!("bench: generating {}", dataset.display());
            fixtures::write::write_dataset(&scenario, &dataset)?;
        }
        let out = data.join(format!("out-apply-{h}h"));
        let _ = std::fs::remove_dir_all(&out);
        ingest::run(&dataset, &out).context("ingesting the benchmark log")?;
        let ingested = out.join("ingest");
        let samples = ingest::contract::ingest_ledger::IngestReport::load(&ingested)?
            .tables
            .get(ingest::contract::tables::acceleration::FILE)
            .copied()
            .unwrap_or(0);
        let (r, median) = super::bench::best_of(runs, || gravcal_once(&bin, &dataset, &cal, &out))?;
        let written = std::fs::metadata(
            out.join("apply")
                .join(ingest::contract::tables::applied::FILE),
        )?
        .len();
        rows.push((h, "gravcal apply".to_owned(), samples, written, r, median));
        if let Some(py) = &py {
            for method in ["lazy", "eager"] {
                let (r, median) = super::bench::best_of(runs, || {
                    polars_once(py, &script, &ingested, &cal, method)
                })?;
                let written = std::fs::metadata(ingested.join("polars-applied.parquet"))?.len();
                rows.push((h, format!("polars {method}"), samples, written, r, median));
            }
            let _ = std::fs::remove_file(ingested.join("polars-applied.parquet"));
        }
        let _ = std::fs::remove_dir_all(&out);
    }
    println!(
        "| log | what | samples | output MB | seconds (fastest) | seconds (median) | Msamples/s | CPU s | peak RSS MB |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (h, what, samples, written, r, median) in rows {
        let cpu = r.cpu_seconds.map_or("-".to_owned(), |c| format!("{c:.2}"));
        println!(
            "| 250 Hz, {h} h | {what} | {samples} | {:.0} | {:.2} | {median:.2} | {:.1} | {cpu} | {:.0} |",
            written as f64 / 1e6,
            r.seconds,
            samples as f64 / 1e6 / r.seconds,
            r.peak_rss_mb
        );
    }
    Ok(())
}
