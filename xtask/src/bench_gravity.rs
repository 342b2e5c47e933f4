//! `cargo xtask bench gravity`: the gravity stage (apply, then the reduction) on a boat
//! survey logged at 250 Hz with a 10 Hz trajectory (fixtures' `survey_lines::bench_plan`),
//! at `hours` and a quarter of it, so that peak memory shows whether it grows with the log;
//! levelled (the down component) and rolling with a 10 Hz attitude file (north, east and
//! down, each sample turned into the navigation frame). Measured, never asserted. No peer
//! does this (docs/model.md 7).

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

/// The gravity benchmark on `hours` and `hours / 4`.
pub fn gravity(root: &Path, hours: f64, runs: usize, build: Build) -> Result<()> {
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
    Ok(())
}
