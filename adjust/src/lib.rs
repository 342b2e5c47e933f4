//! gravcal's `adjust` stage: the calibration functions by a rigorous errors-in-both-variables
//! (Gauss-Helmert) adjustment (docs/model.md).
//!
//! Reads OUT/align (observations.parquet, align.json) and OUT/ingest/ingest.json, fits every
//! model the manifest declares (or the defaults of docs/formats.md section 2) per accelerometer
//! and session or over all sessions, in parallel (rayon), and writes
//! OUT/adjust/calibration.json (docs/formats.md section 6) and OUT/adjust/residuals.parquet.
//!
//! The mathematics does no I/O: [`lsq::gh`] is the general engine, [`calibration::model`]
//! the condition equations, [`calibration::calibrate`] one calibration fit with data
//! snooping, [`fit`] the general polynomial fitting command (docs/formats.md section 7).
//! [`survey`] holds the apply and gravity stages, which read calibration.json.

pub mod calibration;
pub mod fit;
pub mod lsq;
pub mod survey;

mod fit_cli;

pub use calibration::jobs::models;
use calibration::jobs::{
    Job, fit_job, plan_jobs, residual_rows_of, session_mean_temperatures, skip_reason,
};
pub use calibration::outputs::print_summary;
use calibration::outputs::write_outputs;
pub use calibration::results::{barely_estimable, misalignment_vector, vector_note};
use calibration::results::{earth_tide_note, kalibr_noise, thermal_effects};
pub use fit_cli::{FitArgs, fit_csv};
use ingest::contract::tables;

use calibration::calibrate::{self, CalError};
use calibration::{repeatability, triad_fits};
use ingest::contract::align_ledger::{self, AlignReport};
use ingest::contract::calibration::{
    CALIBRATION_FORMAT, Calibration, CalibrationResult, Input, Skipped,
};
use ingest::contract::custody::Custody;
use ingest::contract::ingest_ledger::IngestReport;
use ingest::contract::manifest::{Dataset, Per};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// What can go wrong in adjust.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading the manifest or an upstream ledger, writing a table, or reading or writing a
    /// file.
    #[error(transparent)]
    Ingest(#[from] ingest::Error),
    /// Reading align's outputs.
    #[error(transparent)]
    Align(#[from] align::Error),
    /// An input table is not what align writes.
    #[error("{}: {message}", path.display())]
    Table {
        /// The table.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A calibration cannot be applied as asked (the instrument, the model or the session
    /// does not match): `path` is the calibration file.
    #[error("{}: {message}", path.display())]
    Apply {
        /// The calibration file.
        path: PathBuf,
        /// What does not match, and what to change.
        message: String,
    },
    /// Two outputs would be written to one file (their names, joined from the manifest's,
    /// are the same, or differ only in case).
    #[error("{}: {message}", path.display())]
    OutputName {
        /// The file.
        path: PathBuf,
        /// Which outputs, and what to rename.
        message: String,
    },
    /// The fit command's input is unusable: `path`, at `line` where one is to blame.
    #[error("{}{}: {message}", path.display(), line.map_or(String::new(), |l| format!(":{l}")))]
    Fit {
        /// The CSV table.
        path: PathBuf,
        /// Its line, 1-based.
        line: Option<usize>,
        /// What is wrong, and where in the line.
        message: String,
    },
}

/// The jobs' outcomes sorted: the results kept with their fits and residual rows, and the
/// jobs skipped (planned so, implausible, without observations, or failed) with why.
struct Fitted<'a> {
    results: Vec<CalibrationResult>,
    fits: Vec<&'a calibrate::CalibrationSolution>,
    residual_rows: Vec<tables::residuals::Fitted<'a>>,
    skipped: Vec<Skipped>,
}

/// Sorts each job's outcome into [`Fitted`], after the jobs `skipped` when planned.
fn sort_outcomes<'a>(
    ds: &Dataset,
    jobs: &'a [Job<'a>],
    outcomes: &'a [Result<(CalibrationResult, calibrate::CalibrationSolution), CalError>],
    skipped: Vec<Skipped>,
) -> Fitted<'a> {
    let mut out = Fitted {
        results: Vec::new(),
        fits: Vec::new(),
        residual_rows: Vec::new(),
        skipped,
    };
    let skip = |job: &Job<'_>, reason: String| Skipped {
        accelerometer: job.accelerometer.clone(),
        session: job.scope.id().to_owned(),
        model: job.model.name.clone(),
        reason,
    };
    for (job, outcome) in jobs.iter().zip(outcomes) {
        match outcome {
            Ok((r, f)) => match r.implausible(&ds.manifest.instrument) {
                Some(reason) => out.skipped.push(skip(job, reason)),
                None => {
                    out.results.push(r.clone());
                    out.fits.push(f);
                    out.residual_rows.extend(residual_rows_of(job, f));
                }
            },
            Err(_) if job.obs.is_empty() => {
                out.skipped
                    .push(skip(job, "no usable observations".to_owned()));
            }
            Err(e) => out.skipped.push(skip(job, skip_reason(ds, job, e))),
        }
    }
    out
}

/// Runs the stage: reads OUT/ingest and OUT/align, writes OUT/adjust.
pub fn run(dataset: &Path, out: &Path) -> Result<Calibration, Error> {
    let ds = Dataset::load(dataset)?;
    let _lock = ingest::base::lock::OutputLock::acquire(out)?;
    let ingest_report = IngestReport::load_verified(&ds, out)?;
    let align_report = AlignReport::load_verified(&ds, out)?;
    let rows = tables::observations::read(&out.join(align_ledger::STAGE_DIR))?;
    let g = ds.manifest.site.gravity_mgal();
    let used: Vec<&tables::observations::Observation> = rows
        .iter()
        .filter(|o| {
            // A reading without a temperature is used only where its session declares no
            // thermometer (align excludes it otherwise), and then only by models without
            // temperature terms (plan_jobs).
            o.excluded.is_none() && o.ng.is_some() && o.sigma_ng.is_some()
        })
        .collect();
    let models = models(
        &ds.manifest.adjust.model,
        &session_mean_temperatures(&ds, &used),
    );
    let (jobs, skipped) = plan_jobs(&ds, &models, &used, &align_report);
    let outcomes: Vec<_> = jobs.par_iter().map(|job| fit_job(job, g)).collect();
    let Fitted {
        mut results,
        fits,
        residual_rows,
        mut skipped,
    } = sort_outcomes(&ds, &jobs, &outcomes, skipped);
    thermal_effects(&mut results, &fits);
    let unit = ds.manifest.instrument.reading_unit.name();
    for r in &mut results {
        let k = r.parameters.iter().find(|p| p.name == "k").map(|p| p.value);
        r.warnings.extend(
            k.and_then(|k| ingest::contract::calibration::scale_unit_warning(unit, "k", k)),
        );
    }
    let adc_noise = kalibr_noise(&align_report, &results);
    let (triad, triad_skipped) = triad_fits::fit_all(&ds, &models, &align_report);
    skipped.extend(triad_skipped);
    let repeatability = repeatability::of_results(&results, &|name| {
        models
            .iter()
            .any(|m| m.name == name && m.per == Per::Session)
    });
    let calibration = Calibration {
        format: CALIBRATION_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        inputs: ingest_report
            .files
            .iter()
            .map(|f| Input {
                path: f.path.clone(),
                sha256: f.sha256.clone(),
            })
            .collect(),
        gravity_mgal: g,
        reading_unit: ds.manifest.instrument.reading_unit.name().to_owned(),
        accelerometers: ds.manifest.instrument.accelerometer.clone(),
        results,
        skipped,
        triad,
        custody: Custody::default(),
        adc_noise,
        earth_tide: earth_tide_note(&used),
        repeatability,
    };
    write_outputs(&ds, out, calibration, &residual_rows)
}
