//! gravcal's `report` stage: what a geodesist reads.
//!
//! Turns the outputs of ingest, align and adjust into OUT/report/index.html (one
//! self-contained file: inline CSS and SVG, no network), OUT/report/report.md, and the plots
//! as SVG files (OUT/report/plots/). The tables are built once and rendered to both formats.

mod figures;
mod fits;
mod gravity;
mod models;
mod plots;
mod render;
mod summary;

use figures::{Plot, noise_section, plots_section};
use fits::{
    components_section, extra_terms_section, parameters_section, repeatability_section,
    snooping_section, table1_section,
};
use models::{comparison_section, misalignment_section, triad_section};
use render::section;
pub use render::{Section, Table, html, markdown};
use summary::{
    custody_section, dataset_section, function_section, ledger_section, summary_section,
};

use ingest::contract::align_ledger::{self, AlignReport};
use ingest::contract::calibration::{self, Calibration, CalibrationResult, Parameter};
use ingest::contract::custody::Root;
use ingest::contract::ingest_ledger::{self, IngestReport};
use ingest::contract::manifest::Dataset;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What can go wrong in this stage.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An upstream stage's error, as adjust carries it: reading the manifest, a ledger or
    /// adjust's outputs, or reading or writing a file (ingest's and align's errors too).
    #[error(transparent)]
    Upstream(#[from] adjust::Error),
    /// Drawing a plot failed.
    #[error("plot {name}: {message}")]
    Plot {
        /// The plot.
        name: String,
        /// What failed.
        message: String,
    },
}

impl From<ingest::Error> for Error {
    fn from(e: ingest::Error) -> Self {
        Error::Upstream(e.into())
    }
}

impl From<align::Error> for Error {
    fn from(e: align::Error) -> Self {
        Error::Upstream(e.into())
    }
}

fn param<'a>(r: &'a CalibrationResult, name: &str) -> Option<&'a Parameter> {
    r.parameters.iter().find(|p| p.name == name)
}

fn t_critical(dof: usize) -> f64 {
    adjust::lsq::components::t_quantile(0.975, dof.max(1) as f64)
}

fn gps(ns: i64) -> String {
    let week = ns.div_euclid(ingest::base::time::NS_PER_WEEK);
    let tow = ns.rem_euclid(ingest::base::time::NS_PER_WEEK) as f64 * 1e-9;
    format!("{week} / {tow:.3}")
}

/// Every file the stages read and wrote, with its hash.
fn custody_table(
    ingest_report: &IngestReport,
    align_report: &AlignReport,
    cal: &Calibration,
) -> Table {
    let mut t = Table::headed("stage | read or wrote | file | SHA-256");
    for (stage, custody) in [
        ("ingest", &ingest_report.custody),
        ("align", &align_report.custody),
        ("adjust", &cal.custody),
    ] {
        for (what, list) in [("read", &custody.inputs), ("wrote", &custody.outputs)] {
            for f in list {
                let path = match f.root {
                    Root::Dataset => f.path.clone(),
                    Root::Out => format!("OUT/{}", f.path),
                };
                t.rows.push(vec![
                    stage.to_owned(),
                    what.to_owned(),
                    path,
                    f.sha256.clone(),
                ]);
            }
        }
    }
    t
}

/// What the report is built from: the stage outputs, their chain of custody checked.
struct Stages<'a> {
    ds: &'a Dataset,
    /// The stages' output folder (for the tables the report reads on demand).
    out: &'a Path,
    cal: Calibration,
    ingest_report: IngestReport,
    align_report: AlignReport,
    residuals: Vec<ingest::contract::tables::residuals::Residual>,
    observations: Vec<ingest::contract::tables::observations::Observation>,
}

/// Builds the report's sections from the stage outputs under `out`, one function a section.
pub fn build(ds: &Dataset, out: &Path) -> Result<Vec<Section>, Error> {
    let st = Stages {
        ds,
        out,
        cal: Calibration::load_verified(ds, out)?,
        ingest_report: IngestReport::load(&out.join(ingest_ledger::STAGE_DIR))?,
        align_report: AlignReport::load(&out.join(align_ledger::STAGE_DIR))?,
        residuals: ingest::contract::tables::residuals::read(&out.join(calibration::STAGE_DIR))?,
        observations: ingest::contract::tables::observations::read(
            &out.join(align_ledger::STAGE_DIR),
        )?,
    };
    // The answer first; then what each kind of model holds, only where the dataset has one;
    // the ledgers and the chain of custody last.
    let axis = !st.cal.results.is_empty();
    let per_session_linear = st
        .cal
        .results
        .iter()
        .any(|r| !r.over_all_sessions() && r.order == 1 && !r.temperature && !r.misalignment);
    let extra = st
        .cal
        .results
        .iter()
        .any(|r| r.order > 1 || r.temperature || r.misalignment);
    let vector = st
        .cal
        .results
        .iter()
        .any(|r| r.misalignment_vector.is_some());
    let triad = !st.cal.triad.is_empty();
    // A dataset with nothing to calibrate and a survey reduced opens on the survey.
    let nothing_calibrated = st.cal.results.is_empty() && st.cal.triad.is_empty();
    let mut sections = vec![summary_section(&st), dataset_section(&st)];
    match gravity::gravity_section(ds, out)? {
        Some(g) if nothing_calibrated && st.cal.skipped.is_empty() => sections.insert(0, g),
        Some(g) => sections.push(g),
        None => {}
    }
    if axis {
        sections.push(function_section());
    }
    if per_session_linear {
        sections.push(table1_section(&st));
    }
    if axis {
        sections.push(components_section(&st));
    }
    if let Some(c) = comparison_section(&st)? {
        sections.push(c);
    }
    if axis {
        sections.push(parameters_section(&st));
    }
    if extra {
        sections.push(extra_terms_section(&st));
    }
    if vector {
        sections.push(misalignment_section(&st)?);
    }
    if triad {
        sections.push(triad_section(&st)?);
    }
    if axis {
        sections.push(snooping_section(&st));
    }
    if !st.cal.repeatability.is_empty() {
        sections.push(repeatability_section(&st));
    }
    sections.push(ledger_section(&st));
    if axis {
        sections.push(plots_section(&st)?);
        sections.push(noise_section(&st)?);
    }
    sections.push(custody_section(&st));
    Ok(sections)
}

fn write_atomically(path: &Path, text: &str) -> Result<(), Error> {
    ingest::write_atomically(path, text.as_bytes()).map_err(|e| ingest::Error::io(path, e).into())
}

/// Where the report went.
#[derive(Clone, Debug)]
pub struct Written {
    /// index.html.
    pub html: PathBuf,
    /// report.md.
    pub markdown: PathBuf,
    /// Plot files.
    pub plots: usize,
}

/// Builds the report from OUT/ingest, OUT/align and OUT/adjust; writes OUT/report.
pub fn run(dataset: &Path, out: &Path) -> Result<Written, Error> {
    let ds = Dataset::load(dataset)?;
    let _lock = ingest::base::lock::OutputLock::acquire(out)?;
    let sections = build(&ds, out)?;
    let dir = out.join("report");
    let plot_dir = dir.join("plots");
    std::fs::create_dir_all(&plot_dir).map_err(|e| ingest::Error::io(plot_dir.clone(), e))?;
    let mut plots = 0;
    // Plot names join a model's name, an accelerometer's id and a session's with `-`, which
    // names may hold: `a-b` with `c` and `a` with `b-c` would write one file, the report
    // then showing one plot twice.
    let mut names = ingest::contract::manifest::Names::default();
    for sec in &sections {
        for (file, svg) in &sec.plots {
            names.insert(file, "plot").map_err(|e| Error::Plot {
                name: file.clone(),
                message: format!(
                    "{e}: two fits would draw one plot file (their model names, ids and \
                     session ids joined by `-` are the same); rename one"
                ),
            })?;
            // Plot names come from ids and model names: whatever calibration.json says, a
            // plot is one plain file inside OUT/report/plots.
            if !ingest::contract::manifest::is_plain_file_name(file) {
                return Err(Error::Plot {
                    name: file.clone(),
                    message: "not a plain file name (its ids or model name are not ones a \
                              manifest allows)"
                        .to_owned(),
                });
            }
            write_atomically(&plot_dir.join(file), svg)?;
            plots += 1;
        }
    }
    let md = dir.join("report.md");
    write_atomically(&md, &markdown(&ds.manifest.name, &sections))?;
    let html_path = dir.join("index.html");
    write_atomically(&html_path, &html(&ds.manifest.name, &sections))?;
    Ok(Written {
        html: html_path,
        markdown: md,
        plots,
    })
}
