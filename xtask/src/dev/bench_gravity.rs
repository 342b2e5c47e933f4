//! `cargo xtask bench gravity`: the gravity stage (apply, then the reduction) on a boat
//! survey logged at 250 Hz with a 10 Hz trajectory (fixtures' `survey_lines::bench_plan`),
//! at `hours` and a quarter of it, so that peak memory shows whether it grows with the log;
//! levelled (the down component) and rolling with a 10 Hz attitude file (north, east and
//! down, each sample turned into the navigation frame). No peer does this (docs/model.md 7).
//!
//! Then a platform meter's cruise of `hours` at 1 Hz (`fixtures::meter`, a DGS laptop file)
//! reduced to its free-air anomaly through a 240 s Blackman filter: gravcal's ingest and
//! gravity stages (the meter's stated calibration, every sigma) beside shipgrav's reduction
//! of the same file in the peers' venv (its reader, Eotvos, WGS84 normal gravity, Longman's
//! tide, scipy's `firwin` of the same taps applied centred, a CSV written). Measured, never
//! asserted.

use super::bench::Build;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// triad-multipos calibrated in `dir` (once); its calibration.json.
fn calibration(dir: &Path) -> Result<PathBuf> {
    let out = dir.join("out-gravity-calibration");
    let cal = out.join("adjust/calibration.json");
    if !cal.exists() {
        let dataset = fixtures::dataset_dir(fixtures::triad::MULTIPOS);
        ingest::run(&dataset, &out)?;
        align::run(&dataset, &out)?;
        let c = adjust::run(&dataset, &out)?;
        if c.triad.len() != 1 {
            bail!("triad-multipos gave {} triad fits, not 1", c.triad.len());
        }
    }
    Ok(cal)
}

/// What a survey benchmark is run on and how.
#[derive(Clone, Copy)]
pub struct SurveyBench<'a> {
    /// The workspace.
    pub root: &'a Path,
    /// The survey's length, h.
    pub hours: f64,
    /// Runs of each program, the fastest kept.
    pub runs: usize,
    /// The peers' Python, where shipgrav runs beside.
    pub peers: Option<&'a Path>,
    /// The stage binaries' profile.
    pub build: Build,
}

/// The gravity benchmark on `hours` and `hours / 4`, then the marine cruise of `hours`
/// beside shipgrav when `peers` names the peers' Python.
pub fn gravity(bench: &SurveyBench<'_>) -> Result<()> {
    let SurveyBench {
        root,
        hours,
        runs,
        peers: _,
        build,
    } = *bench;
    let bin = build.stage_binaries(root)?.join("gravcal-gravity");
    let data = root.join("target/bench-data");
    std::fs::create_dir_all(&data)?;
    let cal = calibration(&data)?;
    let mut rows = Vec::new();
    let cases = [hours / 4.0, hours]
        .into_iter()
        .flat_map(|h| [(h, false), (h, true)]);
    for (h, with_attitude) in cases {
        let mut plan = fixtures::survey_lines::bench_plan(h);
        let mut name = format!("survey-lines-250hz-{h}h");
        if with_attitude {
            plan.attitude = fixtures::survey_lines::attitude_plan().attitude;
            name.push_str("-attitude");
        }
        let dataset = data.join(name);
        if !dataset.join("dataset.toml").exists() {
            eprintln!("bench: generating {}", dataset.display());
            let _ = std::fs::remove_dir_all(&dataset);
            fixtures::survey_lines::write_survey_lines(&plan, &dataset)?;
        }
        let out = data.join(format!("out-gravity-{h}h-{with_attitude}"));
        let _ = std::fs::remove_dir_all(&out);
        ingest::run(&dataset, &out).context("ingesting the benchmark survey")?;
        let extra = [
            "--calibration".as_ref(),
            cal.as_os_str(),
            "--session".as_ref(),
            "lab".as_ref(),
        ];
        let (r, median) = super::bench::best_of(runs, || {
            super::bench::stage_once_with(&bin, &dataset, &out, &extra)
        })?;
        let report: ingest::contract::gravity_ledger::GravityReport = ingest::read_json(
            &out.join(ingest::contract::gravity_ledger::STAGE_DIR)
                .join(ingest::contract::gravity_ledger::LEDGER_FILE),
        )?;
        let samples = ingest::contract::ingest_ledger::IngestReport::load(&out.join("ingest"))?
            .tables
            .get(ingest::contract::tables::lab::FILE)
            .copied()
            .unwrap_or(0);
        rows.push((h, with_attitude, samples, report.rows_written, r, median));
        let _ = std::fs::remove_dir_all(&out);
    }
    println!(
        "| survey | samples (250 Hz) | epochs (10 Hz) | seconds (fastest) | seconds (median) | Msamples/s | CPU s | peak RSS MB |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (h, with_attitude, samples, epochs, r, median) in rows {
        let cpu = r.cpu_seconds.map_or("-".to_owned(), |c| format!("{c:.2}"));
        let kind = if with_attitude {
            "with attitude"
        } else {
            "levelled"
        };
        println!(
            "| {h} h, {kind} | {samples} | {epochs} | {:.2} | {median:.2} | {:.1} | {cpu} | {:.0} |",
            r.seconds,
            samples as f64 / 1e6 / r.seconds,
            r.peak_rss_mb
        );
    }
    marine(bench)
}

/// shipgrav's reduction of a DGS laptop file, timed by itself: argv the file, the CSV to
/// write, the FIR's taps and cut-off (cycles per sample), the meter's offset (mGal); its last
/// line wall seconds, peak RSS in kB, CPU seconds.
const SHIPGRAV: &str = r#"
import resource, sys, time
t0 = time.time()
import numpy as np
import pandas as pd
import shipgrav.grav as sgg
import shipgrav.io as sgi
from scipy.signal import firwin

path, out, taps, cutoff, offset = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5])
data = sgi.read_dgs_laptop([path], "Atlantis", progressbar=False)
grav = data["rgrav"].values + offset
lat, lon = data["lat"], data["lon"]
normal = (sgg.wgs_grav(lat) + sgg.free_air_second_order(lat, np.zeros(len(lat)))).values
e = sgg.eotvos_full(lon.values, lat.values, np.zeros(len(lat)), 1)
tide = np.asarray(sgg.longman_tide_prediction(lon, lat, data["date_time"]))
faa = grav - normal + e + tide
h = firwin(taps, cutoff, window="blackman", fs=1.0)
filtered = np.convolve(faa, h, mode="same")
pd.DataFrame({"time": data["date_time"], "lat": lat, "lon": lon, "faa": faa,
              "faa_filtered": filtered}).to_csv(out, index=False)
ru = resource.getrusage(resource.RUSAGE_SELF)
print(time.time() - t0, ru.ru_maxrss, ru.ru_utime + ru.ru_stime)
"#;

/// The marine cruise of `hours` at 1 Hz: gravcal (ingest, then gravity) and shipgrav.
pub fn marine(bench: &SurveyBench<'_>) -> Result<()> {
    let SurveyBench {
        root,
        hours,
        runs,
        peers,
        build,
    } = *bench;
    let bins = build.stage_binaries(root)?;
    let data = root.join("target/bench-data");
    let seconds = (hours * 3600.0).round() as usize;
    let dataset = data.join(format!("meter-cruise-{hours}h"));
    if !dataset.join("dataset.toml").exists() {
        eprintln!("bench: generating {}", dataset.display());
        let _ = std::fs::remove_dir_all(&dataset);
        fixtures::meter::write_cruise(&dataset, fixtures::meter::Cruise::new(seconds, 1), "none")?;
        let manifest = std::fs::read_to_string(dataset.join("dataset.toml"))?;
        std::fs::write(
            dataset.join("dataset.toml"),
            manifest.replace(
                "filter_s = 240.0\n",
                "filter_s = 240.0\nfilter = \"blackman\"\nnormal_gravity = \"WGS84\"\n",
            ),
        )?;
    }
    let out = data.join(format!("out-meter-{hours}h"));
    let vendor = [
        "--calibration".as_ref(),
        adjust::survey::apply::stream::VENDOR.as_ref(),
    ];
    let ours = || -> Result<super::bench::Run> {
        let _ = std::fs::remove_dir_all(&out);
        let i = super::bench::stage_once_with(&bins.join("gravcal-ingest"), &dataset, &out, &[])?;
        let g =
            super::bench::stage_once_with(&bins.join("gravcal-gravity"), &dataset, &out, &vendor)?;
        Ok(super::bench::Run {
            seconds: i.seconds + g.seconds,
            peak_rss_mb: i.peak_rss_mb.max(g.peak_rss_mb),
            cpu_seconds: i.cpu_seconds.zip(g.cpu_seconds).map(|(a, b)| a + b),
        })
    };
    let script = data.join("shipgrav_reduce.py");
    let csv = data.join("shipgrav-reduced.csv");
    let (taps, cutoff) = adjust::survey::gravity::filter::windowed_sinc_design(
        ingest::contract::survey::FilterKind::Blackman,
        240.0,
    );
    let theirs = |py: &Path| -> Result<super::bench::Run> {
        let o = std::process::Command::new(py)
            .arg(&script)
            .arg(dataset.join("raw/cruise.dat"))
            .arg(&csv)
            .arg(taps.to_string())
            .arg(cutoff.to_string())
            .arg(fixtures::meter::OFFSET_MGAL.to_string())
            .output()?;
        if !o.status.success() {
            bail!("shipgrav failed: {}", String::from_utf8_lossy(&o.stderr));
        }
        super::bench::parse_peer_run(&String::from_utf8_lossy(&o.stdout))
    };
    if peers.is_some() {
        std::fs::write(&script, SHIPGRAV)?;
    }
    // The two in turn, run after run, so that the machine's slower minutes fall on both.
    let (mut mine, mut peer) = (Vec::new(), Vec::new());
    for _ in 0..runs.max(1) {
        mine.push(ours()?);
        if let Some(py) = peers {
            peer.push(theirs(py)?);
        }
    }
    let _ = std::fs::remove_file(&csv);
    let _ = std::fs::remove_dir_all(&out);
    print_marine(hours, seconds, mine, peer)
}

/// The marine bench's table, `mine` and `peer` the runs in turn (`peer` empty without the
/// peers), and the pairs' ratios.
fn print_marine(
    hours: f64,
    seconds: usize,
    mine: Vec<super::bench::Run>,
    peer: Vec<super::bench::Run>,
) -> Result<()> {
    let ratios: Vec<f64> = mine
        .iter()
        .zip(&peer)
        .map(|(a, b)| b.seconds / a.seconds)
        .collect();
    let (ours, median) = super::bench::fastest_and_median(mine)?;
    let mut rows = vec![("gravcal ingest + gravity", ours, median)];
    if !peer.is_empty() {
        let (theirs, median) = super::bench::fastest_and_median(peer)?;
        rows.push(("shipgrav (its reader, FAA, scipy's FIR)", theirs, median));
    }
    println!();
    println!(
        "| DGS laptop file at 1 Hz | what | seconds (fastest) | seconds (median) | CPU s | peak RSS MB |"
    );
    println!("|---|---|---|---|---|---|");
    for (what, r, median) in rows {
        let cpu = r.cpu_seconds.map_or("-".to_owned(), |c| format!("{c:.2}"));
        println!(
            "| {hours} h, {seconds} lines | {what} | {:.2} | {median:.2} | {cpu} | {:.0} |",
            r.seconds, r.peak_rss_mb
        );
    }
    if !ratios.is_empty() {
        let (fast, slow) = ratios
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &r| (a.min(r), b.max(r)));
        let mut sorted = ratios.clone();
        sorted.sort_by(f64::total_cmp);
        println!(
            "\nshipgrav / gravcal, run by run (each pair one after the other): median {:.1}, \
             from {fast:.1} to {slow:.1}",
            sorted[sorted.len() / 2]
        );
    }
    Ok(())
}
