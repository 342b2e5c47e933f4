//! gravcal's `report` stage: what a geodesist reads.
//!
//! Turns the outputs of ingest, align and adjust into OUT/report/index.html (one
//! self-contained file: inline CSS and SVG, no network), OUT/report/report.md, and the plots
//! as SVG files (OUT/report/plots/). The tables are built once and rendered to both formats.

mod plots;

use ingest::contract::align_ledger::{self, AlignReport};
use ingest::contract::calibration::{self, Calibration, CalibrationResult, Parameter};
use ingest::contract::custody::Root;
use ingest::contract::ledger::{self as ingest_ledger, IngestReport};
use ingest::contract::manifest::Dataset;
use statrs::distribution::{ContinuousCDF, StudentsT};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What can go wrong in this stage.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading the manifest or ingest's ledger.
    #[error(transparent)]
    Ingest(#[from] ingest::Error),
    /// Reading align's ledger.
    #[error(transparent)]
    Align(#[from] align::Error),
    /// Reading adjust's outputs.
    #[error(transparent)]
    Adjust(#[from] adjust::Error),
    /// Writing a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Drawing a plot failed.
    #[error("plot {name}: {message}")]
    Plot {
        /// The plot.
        name: String,
        /// What failed.
        message: String,
    },
}

/// A table, rendered to Markdown and HTML from the same cells.
#[derive(Clone, Debug, Default)]
pub struct Table {
    /// Column headings.
    pub header: Vec<String>,
    /// Rows of cells.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    fn new(header: &[&str]) -> Self {
        Table {
            header: header.iter().map(|s| (*s).to_owned()).collect(),
            rows: Vec::new(),
        }
    }

    /// GitHub-flavoured Markdown.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "| {} |\n|{}|\n",
            self.header.join(" | "),
            vec!["---"; self.header.len()].join("|")
        );
        for r in &self.rows {
            let _ = writeln!(s, "| {} |", r.join(" | "));
        }
        s
    }

    /// An HTML table.
    pub fn html(&self) -> String {
        let mut s = String::from("<table><thead><tr>");
        for h in &self.header {
            let _ = write!(s, "<th>{}</th>", esc(h));
        }
        s.push_str("</tr></thead><tbody>");
        for r in &self.rows {
            s.push_str("<tr>");
            for c in r {
                let _ = write!(s, "<td>{}</td>", esc(c));
            }
            s.push_str("</tr>");
        }
        s.push_str("</tbody></table>");
        s
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// One section of the report: a heading, paragraphs, tables and plots.
#[derive(Clone, Debug, Default)]
pub struct Section {
    /// Heading.
    pub title: String,
    /// Paragraphs (plain text).
    pub text: Vec<String>,
    /// Tables, each with a caption.
    pub tables: Vec<(String, Table)>,
    /// Plots: file name (without folder) and SVG.
    pub plots: Vec<(String, String)>,
    /// Tables shown on demand (HTML: a collapsible block; Markdown: in full), each with a
    /// caption, under the table of [`Section::tables`] whose index it gives.
    pub details: Vec<(usize, String, Table)>,
}

fn section(title: &str) -> Section {
    Section {
        title: title.to_owned(),
        ..Section::default()
    }
}

fn param<'a>(r: &'a CalibrationResult, name: &str) -> Option<&'a Parameter> {
    r.parameters.iter().find(|p| p.name == name)
}

fn t_critical(dof: usize) -> f64 {
    StudentsT::new(0.0, 1.0, dof.max(1) as f64).map_or(1.96, |t| t.inverse_cdf(0.975))
}

/// Points of a plot.
type Points = Vec<(f64, f64)>;
/// A residual plot's x axis: file key, label, and the value of an observation.
type Axis<'a> = (
    &'a str,
    &'a str,
    Box<dyn Fn(&adjust::io::ResidualRecord) -> f64 + 'a>,
);

fn gps(ns: i64) -> String {
    let week = ns.div_euclid(ingest::time::NS_PER_WEEK);
    let tow = ns.rem_euclid(ingest::time::NS_PER_WEEK) as f64 * 1e-9;
    format!("{week} / {tow:.3}")
}

/// Every file the stages read and wrote, with its hash.
fn custody_table(
    ingest_report: &IngestReport,
    align_report: &AlignReport,
    cal: &Calibration,
) -> Table {
    let mut t = Table::new(&["stage", "read or wrote", "file", "SHA-256"]);
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
    cal: Calibration,
    ingest_report: IngestReport,
    align_report: AlignReport,
    residuals: Vec<adjust::io::ResidualRecord>,
    observations: Vec<adjust::io::ObservationRow>,
}

/// Builds the report's sections from the stage outputs under `out`, one function a section.
pub fn build(ds: &Dataset, out: &Path) -> Result<Vec<Section>, Error> {
    let st = Stages {
        ds,
        cal: Calibration::load_verified(ds, out)?,
        ingest_report: IngestReport::load(&out.join(ingest_ledger::STAGE_DIR))?,
        align_report: AlignReport::load(&out.join(align_ledger::STAGE_DIR))?,
        residuals: adjust::io::read_residuals(&out.join(calibration::STAGE_DIR))?,
        observations: adjust::io::read_observations(&out.join(align_ledger::STAGE_DIR))?,
    };
    // The answer first; then what each kind of model holds, only where the dataset has one;
    // the ledgers and the chain of custody last.
    let axis = !st.cal.results.is_empty();
    let per_session_linear = st
        .cal
        .results
        .iter()
        .any(|r| r.session != "all" && r.order == 1 && !r.temperature && !r.misalignment);
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
    let mut sections = vec![summary_section(&st), dataset_section(&st)];
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
    sections.push(ledger_section(&st));
    if axis {
        sections.push(plots_section(&st)?);
        sections.push(noise_section(&st)?);
    }
    sections.push(custody_section(&st));
    Ok(sections)
}

/// A fit's one-line verdict from its global test.
fn verdict(test: &calibration::GlobalTest) -> &'static str {
    if test.rejects_the_model() {
        "REJECTED by the global test: see below"
    } else if test.passed {
        "consistent with its sigmas"
    } else {
        "sigmas pessimistic (global test low)"
    }
}

/// A fitted parameter as `value +/- sigma unit`.
fn with_sigma(p: &Parameter) -> String {
    format!(
        "{} = {:.6e} +/- {:.2e} {}",
        p.name, p.value, p.sigma, p.unit
    )
}

/// The answer: every accelerometer's calibration of every model, with its sigmas, sigma0,
/// the global test, the observations used and removed, and a one-line verdict; then what
/// was not fitted and why.
fn summary_section(st: &Stages<'_>) -> Section {
    let cal = &st.cal;
    let mut s = section("Summary: the calibrations");
    let models: std::collections::BTreeSet<&str> = cal
        .results
        .iter()
        .map(|r| r.model.as_str())
        .chain(cal.triad.iter().map(|t| t.model.as_str()))
        .collect();
    let surveys = &st.align_report.surveys;
    s.text.push(match models.len() {
        0 if cal.skipped.is_empty() && !surveys.is_empty() => format!(
            "A survey dataset: nothing here to calibrate (no tilt-table or multi-position \
             session). Its survey sessions ({}) are calibrated by `cargo xtask apply <dataset> \
             --calibration C.json` with the calibration of a calibration dataset.",
            surveys.join(", ")
        ),
        0 if cal.skipped.is_empty() => "No session of this dataset is calibrated.".to_owned(),
        0 => "No calibration was fitted: the fits not made say why.".to_owned(),
        1 => format!(
            "One model, `{}`: `cargo xtask apply` uses it by default.",
            models.first().copied().unwrap_or_default()
        ),
        n => format!(
            "{n} models ({}): `cargo xtask apply --model M` chooses the one to apply; sigmas are at the estimated variance components.",
            models.iter().copied().collect::<Vec<_>>().join(", ")
        ),
    });
    let mut t = Table::new(&[
        "model",
        "accelerometer",
        "session",
        "calibration (value +/- sigma)",
        "sigma0",
        "global test",
        "used / removed",
        "verdict",
    ]);
    // One row: what was fitted, its parameters with sigmas, and its statistics.
    let row = |who: [&str; 3],
               parameters: &[Parameter],
               t_ref: Option<f64>,
               gt: &calibration::GlobalTest,
               sigma0: f64,
               used: String| {
        let calibration = parameters
            .iter()
            .map(with_sigma)
            .collect::<Vec<_>>()
            .join("; ")
            + &t_ref.map_or(String::new(), |t| format!(" (at t_ref {t:.2} degC)"));
        let passed = if gt.passed { "passed" } else { "FAILED" };
        let mut cells: Vec<String> = who.iter().map(|w| (*w).to_owned()).collect();
        cells.extend([
            calibration,
            format!("{sigma0:.3}"),
            passed.to_owned(),
            used,
            verdict(gt).to_owned(),
        ]);
        cells
    };
    for r in &cal.results {
        t.rows.push(row(
            [&r.model, &r.accelerometer, &r.session],
            &r.parameters,
            r.t_ref_c,
            &r.global_test,
            r.sigma0,
            format!("{} / {}", r.n_observations, r.n_excluded),
        ));
    }
    for r in &cal.triad {
        let removed = r.positions.iter().filter(|p| p.removed).count();
        t.rows.push(row(
            [&r.model, "triad (x, y, z)", &r.session],
            &r.parameters,
            None,
            &r.global_test,
            r.sigma0,
            format!("{} positions / {removed}", r.positions_used),
        ));
    }
    if !t.rows.is_empty() {
        s.tables.push(("Calibrations".to_owned(), t));
    }
    for r in &cal.results {
        if let Some(a) = r.global_test.advice(
            &format!("{} {} {}", r.model, r.accelerometer, r.session),
            false,
        ) {
            s.text.push(a);
        }
    }
    for r in &cal.triad {
        if let Some(a) = r
            .global_test
            .advice(&format!("triad {} {}", r.model, r.session), true)
        {
            s.text.push(a);
        }
    }
    if !cal.skipped.is_empty() {
        let mut k = Table::new(&["model", "accelerometer", "session", "why not"]);
        for f in &cal.skipped {
            k.rows.push(vec![
                f.model.clone(),
                f.accelerometer.clone(),
                f.session.clone(),
                f.reason.clone(),
            ]);
        }
        s.tables.push(("Fits not made".to_owned(), k));
    }
    s
}

/// Appendix: the inputs' hashes and the chain of custody.
fn custody_section(st: &Stages<'_>) -> Section {
    let mut s = section("Appendix: inputs and chain of custody");
    let mut inputs = Table::new(&["file", "SHA-256", "bytes"]);
    for f in &st.ingest_report.files {
        inputs
            .rows
            .push(vec![f.path.clone(), f.sha256.clone(), f.bytes.to_string()]);
    }
    s.tables.push(("Inputs".to_owned(), inputs));
    s.tables.push((
        "Chain of custody: every file each stage read and wrote, checked unchanged before this report was built".to_owned(),
        custody_table(&st.ingest_report, &st.align_report, &st.cal),
    ));
    s
}

/// The dataset and the gravity used (its files are in the appendix).
fn dataset_section(st: &Stages<'_>) -> Section {
    let Stages { ds, cal, .. } = st;
    let m = &ds.manifest;
    // Dataset and gravity.
    let mut s = section("Dataset");
    s.text.push(format!(
        "Dataset `{}`{}. Calibrated with {}; {} sessions, {} accelerometers.",
        m.name,
        m.description
            .as_deref()
            .map(|d| format!(": {d}"))
            .unwrap_or_default(),
        cal.software,
        ds.sessions.len(),
        m.instrument.accelerometer.len()
    ));
    s.text.push(format!(
        "Gravity used in the model, at the proof masses: g = g_abs + gradient x height = {:.1} mGal + ({} mGal/m x {} m) = {:.3} mGal.",
        m.site.g_abs_mgal, m.site.gradient_mgal_per_m, m.site.sensor_height_m, cal.gravity_mgal
    ));
    s.text.push(format!("Earth tide: {}.", cal.earth_tide));
    let surveys: Vec<&str> = ds
        .sessions
        .iter()
        .filter(|x| x.is_survey())
        .map(|x| x.session.id.as_str())
        .collect();
    if !surveys.is_empty() {
        s.text.push(format!(
            "Survey sessions, ingested but not calibrated (no theodolite; `cargo xtask apply` \
             calibrates them): {}.",
            surveys.join(", ")
        ));
    }
    s
}

/// The calibration function, stated with its direction.
fn function_section() -> Section {
    // The function, stated with its direction.
    let mut s = section("The calibration function");
    s.text.push(
        "Direction: from counts to acceleration. For each accelerometer, a mean ADC count Ng (bits of the 24-bit converter) \
         gives the acceleration along the sensitive axis a [mGal] = b + k·Ng (+ k2·Ng² + k3·Ng³ for higher orders), \
         with b in mGal and k in mGal/bit. With temperature terms, b and k hold at the reference temperature t_ref and \
         become b + b_t·(T − t_ref) and k + k_t·(T − t_ref). To go from an acceleration to counts, invert it: Ng = (a − b)/k. \
         The reference acceleration in the adjustment is F = −g·cos(Dz + beta) for the platform's zenith distance Dz."
            .to_owned(),
    );
    s
}

/// Results in the form of the paper's Table 1.
fn table1_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    // Table 1.
    let mut s = section("Results in the form of the paper's Table 1");
    s.text.push(
        "Per session and accelerometer, order 1 without temperature terms. Sigmas from the estimated variance components \
         (next section) and a priori (every component 1). sigma0 is sqrt(v^T P v / r) at the a-priori weights; the global \
         test is of the station means' scatter about the fitted function (the between-station part of v^T P v) against its \
         scaled chi-square, since the weights were estimated from the readings within the stations. b and k are strongly anti-correlated because the counts are far from zero: \
         use them together, with their correlation."
            .to_owned(),
    );
    let mut t1 = Table::new(&[
        "session",
        "accelerometer",
        "values",
        "T (degC)",
        "b (mGal)",
        "k (mGal/kbit)",
        "sigma b (mGal)",
        "sigma k (mGal/Mbit)",
        "a priori sigma b",
        "a priori sigma k",
        "corr(b,k)",
        "sigma0",
        "removed",
        "global test",
    ]);
    for r in cal
        .results
        .iter()
        .filter(|r| r.session != "all" && r.order == 1 && !r.temperature && !r.misalignment)
    {
        let (Some(b), Some(k)) = (param(r, "b"), param(r, "k")) else {
            continue;
        };
        t1.rows.push(vec![
            r.session.clone(),
            format!("{} ({})", r.accelerometer, r.model),
            r.n_observations.to_string(),
            format!("{:.2}", r.mean_temperature_c),
            format!("{:.2}", b.value),
            format!("{:.5}", k.value * 1e3),
            format!("{:.3}", b.sigma),
            format!("{:.3}", k.sigma * 1e6),
            format!("{:.3}", b.sigma_apriori),
            format!("{:.3}", k.sigma_apriori * 1e6),
            format!("{:.5}", r.correlation[0][1]),
            format!("{:.3}", r.sigma0),
            r.n_excluded.to_string(),
            format!(
                "{} ({:.1} in [{:.1}, {:.1}])",
                if r.global_test.passed {
                    "passed"
                } else {
                    "FAILED"
                },
                r.global_test.statistic,
                r.global_test.lower,
                r.global_test.upper
            ),
        ]);
    }
    s.tables.push(("Table 1".to_owned(), t1));
    s
}

/// Variance components per fit: which observation group was mis-weighted, and by how much.
fn components_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    let mut s = section("Variance components");
    s.text.push(
        "The factor the data put on each observation group's a-priori variances, with its sd, its degrees of freedom and a \
         two-sided 5 % test of whether it is 1. The theodolite's comes from the scatter of the station means about the \
         fitted function (the scatter within a station set its sigma_Dz), the ADC's from the scatter of a station's window \
         means about their mean against the sd each window's samples gave. A group whose test fails was mis-weighted by \
         the factor shown; the parameters' sigmas above use the estimated factors. One the data give fewer than 3 dof \
         is not estimated."
            .to_owned(),
    );
    let mut t = Table::new(&[
        "model",
        "accelerometer",
        "session",
        "group",
        "factor",
        "sigma",
        "dof",
        "test: statistic in [2.5 %, 97.5 %]",
        "verdict",
    ]);
    for r in &cal.results {
        for c in &r.variance_components {
            let verdict = match (&c.not_estimable, c.passed) {
                (Some(why), _) => format!("not estimable: {why}"),
                (None, true) => "consistent with 1".to_owned(),
                (None, false) => format!("mis-weighted: variances x {:.2}", c.estimate),
            };
            t.rows.push(vec![
                r.model.clone(),
                r.accelerometer.clone(),
                r.session.clone(),
                c.group.clone(),
                format!("{:.3}", c.estimate),
                c.sigma.map_or("-".to_owned(), |x| format!("{x:.3}")),
                format!("{:.1}", c.dof),
                format!("{:.1} in [{:.1}, {:.1}]", c.statistic, c.lower, c.upper),
                verdict,
            ]);
        }
    }
    s.tables.push(("Variance components".to_owned(), t));
    s.text.extend(component_advice(cal));
    s
}

/// What a failed component test means and what to try, once for the report: how many
/// failed of how many tested, against the one in twenty a 5 % test fails by chance.
fn component_advice(cal: &Calibration) -> Option<String> {
    let tested: Vec<(&CalibrationResult, &calibration::VarianceComponent)> = cal
        .results
        .iter()
        .flat_map(|r| r.variance_components.iter().map(move |c| (r, c)))
        .filter(|(_, c)| c.not_estimable.is_none())
        .collect();
    let failed: Vec<String> = tested
        .iter()
        .filter(|(_, c)| !c.passed)
        .map(|(r, c)| {
            format!(
                "{} {} {} {} x {:.2}",
                r.model, r.accelerometer, r.session, c.group, c.estimate
            )
        })
        .collect();
    if failed.is_empty() {
        return None;
    }
    Some(format!(
        "{} of {} component tests failed ({}); a 5 % test fails in about {:.1} of {} by chance. \
         A factor below 1 means that group's a-priori variances were too large, above 1 too \
         small; the sigmas above already use the estimated factor, so the calibration stands. \
         What to try when failures recur across sessions and accelerometers: for the \
         theodolite, its sd per reading (align's sigma_dz, or [align] sigma_dz = \"station\"); \
         for the ADC, the window length ([align] window_s) and the noise terms align kept \
         (the Allan section).",
        failed.len(),
        tested.len(),
        failed.join("; "),
        0.05 * tested.len() as f64,
        tested.len()
    ))
}

/// Radius of the 95 % error ellipse of a 2-D normal, in sds: sqrt of chi-square(2)'s 95 %.
const ELLIPSE_95: f64 = 2.447_746_830_680_816;

/// For each vector misalignment: theta and psi with their sigmas, and a polar plot of
/// (theta_x, theta_y) with its 95 % error ellipse. Empty when no model has one.
fn misalignment_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("Misalignment vector");
    let mut t = Table::new(&[
        "model",
        "accelerometer",
        "theta (mrad)",
        "sigma theta (mrad)",
        "psi (deg)",
        "sigma psi (deg)",
    ]);
    for r in &st.cal.results {
        let Some(v) = &r.misalignment_vector else {
            continue;
        };
        t.rows.push(vec![
            r.model.clone(),
            r.accelerometer.clone(),
            format!("{:.4}", v.theta_rad * 1e3),
            format!("{:.4}", v.sigma_theta_rad * 1e3),
            v.psi_deg.map_or_else(
                || v.psi_not_determined.clone().unwrap_or_default(),
                |p| format!("{p:.2}"),
            ),
            v.sigma_psi_deg
                .map_or("-".to_owned(), |x| format!("{x:.2}")),
        ]);
        let at = |name: &str| r.parameters.iter().position(|p| p.name == name);
        let (Some(ix), Some(iy)) = (at("theta_x"), at("theta_y")) else {
            continue;
        };
        let (px, py) = (&r.parameters[ix], &r.parameters[iy]);
        let rho = r.correlation[ix][iy];
        // An ellipse too small to see beside theta is magnified by a power of ten, and says so.
        let theta_mrad = v.theta_rad * 1e3;
        let extent = ELLIPSE_95 * (px.sigma.max(py.sigma)) * 1e3;
        let magnify = if extent > 0.0 && extent < 0.05 * theta_mrad {
            10f64.powf((0.1 * theta_mrad / extent).log10().round())
        } else {
            1.0
        };
        let (sx, sy) = (px.sigma * 1e3 * magnify, py.sigma * 1e3 * magnify);
        // The ellipse: x = sx c cos u, y = sy c (rho cos u + sqrt(1 - rho^2) sin u).
        let ellipse: Vec<(f64, f64)> = (0..=72)
            .map(|i| {
                let u = f64::from(i) * std::f64::consts::TAU / 72.0;
                (
                    px.value * 1e3 + ELLIPSE_95 * sx * u.cos(),
                    py.value * 1e3
                        + ELLIPSE_95
                            * sy
                            * (rho * u.cos() + (1.0 - rho * rho).max(0.0).sqrt() * u.sin()),
                )
            })
            .collect();
        let title = format!("{} {}: misalignment", r.model, r.accelerometer);
        let name = format!("misalignment-{}-{}", r.model, r.accelerometer);
        let label = if magnify > 1.0 {
            format!("95 % error ellipse, magnified {magnify:.0} x")
        } else {
            "95 % error ellipse".to_owned()
        };
        let svg = plots::polar(&plots::Polar {
            title: &title,
            point: (px.value * 1e3, py.value * 1e3),
            ellipse: &ellipse,
            ellipse_label: &label,
        })
        .map_err(|message| Error::Plot {
            name: name.clone(),
            message,
        })?;
        s.plots.push((format!("{name}.svg"), svg));
    }
    if t.rows.is_empty() {
        s.text.push(
            "No model estimated the misalignment as a vector (misalignment = \"vector\", sessions at two rolls)."
                .to_owned(),
        );
    } else {
        s.text.push(
            "The sensitive axis's misalignment in the block's frame (x: the tilt axis at roll 0, y: at roll 90 deg): \
             theta = sqrt(theta_x^2 + theta_y^2) and its direction psi = atan2(theta_y, theta_x), with propagated sigmas; \
             psi is given only when theta is more than 3 sigma from 0. The plots show (theta_x, theta_y) with the 95 % \
             error ellipse of the two."
                .to_owned(),
        );
        s.tables.push(("Misalignment vector".to_owned(), t));
    }
    Ok(s)
}

/// The triad calibrations (docs/formats.md 8.4): parameters, departures from orthogonality, the
/// fit's statistics, |a| - g per position and the positions' directions in the body frame.
fn triad_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("Triad");
    if st.cal.triad.is_empty() {
        s.text.push(
            "No triad model (kind = \"triad\" over multi-position sessions) was fitted.".to_owned(),
        );
        return Ok(s);
    }
    s.text.push(
        "The three accelerometers calibrated together from the block's static positions: a = T K (X - B) in imu_tk's body \
         frame (T upper-triangular with unit diagonal: the non-orthogonality angles a_yz, a_zy, a_zx; K the scales; B the \
         biases), under |a| = g at every position, by a Gauss-Helmert adjustment with data snooping on the positions. \
         Sigmas are a-priori (the means' sigmas from each interval's scatter); sigma0 and the global test say whether \
         those fit."
            .to_owned(),
    );
    for r in &st.cal.triad {
        let mut t = Table::new(&["parameter", "value", "sigma", "unit"]);
        for p in r.parameters.iter().chain(&r.non_orthogonality_mrad) {
            t.rows.push(vec![
                p.name.clone(),
                format!("{:.9e}", p.value),
                format!("{:.2e}", p.sigma),
                p.unit.clone(),
            ]);
        }
        let removed = r.positions.iter().filter(|p| p.removed).count();
        s.text.push(format!(
            "Model {} ({}): {} positions used, {removed} removed{}; sigma0 {:.3} on {} dof, global test {} ([{:.1}, {:.1}] for {:.1}); \
             {}. The last three rows are 90 deg minus the angle between each pair of sensitive axes.",
            r.model,
            r.session,
            r.positions_used,
            match r.positions_without_temperature {
                0 => String::new(),
                n => format!(", {n} left out for want of a temperature"),
            },
            r.sigma0,
            r.dof,
            if r.global_test.passed { "passed" } else { "failed" },
            r.global_test.lower,
            r.global_test.upper,
            r.global_test.statistic,
            match (r.order, r.t_ref_c) {
                (1, None) => String::new(),
                (o, t) => format!(
                    "order {o}{}; ",
                    t.map_or(String::new(), |t| format!(
                        ", temperature terms about t_ref = {t:.2} degC"
                    ))
                ),
            } + &r.calib_file.as_ref().map_or_else(
                || "no imu_tk file: its layout has no place for higher orders or temperature terms".to_owned(),
                |f| format!("imu_tk file adjust/{f}")
            )
        ));
        if let Some(advice) = r
            .global_test
            .advice(&format!("triad {} {}", r.model, r.session), true)
        {
            s.text.push(advice);
        }
        s.tables
            .push((format!("Triad {} ({})", r.model, r.session), t));
        let points =
            |removed: bool, f: &dyn Fn(usize, &calibration::TriadPosition) -> (f64, f64)| {
                r.positions
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| p.removed == removed)
                    .map(|(i, p)| f(i, p))
                    .collect::<Vec<_>>()
            };
        let residual = |i: usize, p: &calibration::TriadPosition| (i as f64, p.residual_mgal);
        let sky = |_: usize, p: &calibration::TriadPosition| {
            let [x, y, z] = p.direction;
            (
                y.atan2(x).to_degrees(),
                z.clamp(-1.0, 1.0).asin().to_degrees(),
            )
        };
        for (name, title, x_label, y_label, f, zero) in [
            (
                "residuals",
                "|a| - g per position",
                "position",
                "|a| - g (mGal)",
                &residual as &dyn Fn(usize, &calibration::TriadPosition) -> (f64, f64),
                true,
            ),
            (
                "sky",
                "gravity directions in the body frame",
                "azimuth atan2(y, x) (deg)",
                "elevation asin(z) (deg)",
                &sky,
                false,
            ),
        ] {
            let plot = format!("triad-{}-{}-{name}", r.model, r.session);
            let title = format!("{} ({}): {title}", r.model, r.session);
            let svg = plots::scatter(&plots::Scatter {
                title: &title,
                x_label,
                y_label,
                used: &points(false, f),
                removed: &points(true, f),
                line: &[],
                zero_line: zero,
                labels: ("positions", ""),
                y_range: None,
            })
            .map_err(|message| Error::Plot {
                name: plot.clone(),
                message,
            })?;
            s.plots.push((format!("{plot}.svg"), svg));
        }
    }
    Ok(s)
}

/// Every axis fit's parameters in a table of its own (what the model holds, the values,
/// sigmas at the estimated components and a priori), its correlations on demand.
fn parameters_section(st: &Stages<'_>) -> Section {
    let mut s = section("Parameters of every fit");
    s.text.push(
        "sigma is at the estimated variance components (the one to quote), sigma a priori at \
         the weights align gave; the correlations open under each table."
            .to_owned(),
    );
    for r in &st.cal.results {
        let mut t = Table::new(&["parameter", "value", "sigma", "sigma a priori", "unit"]);
        for p in &r.parameters {
            t.rows.push(vec![
                p.name.clone(),
                format!("{:.9e}", p.value),
                format!("{:.3e}", p.sigma),
                format!("{:.3e}", p.sigma_apriori),
                p.unit.clone(),
            ]);
        }
        let what = format!(
            "{} {} {}: order {}{}{}{}",
            r.model,
            r.accelerometer,
            r.session,
            r.order,
            if r.temperature {
                ", temperature terms"
            } else {
                ""
            },
            if r.misalignment_vector.is_some() {
                ", misalignment vector"
            } else if r.misalignment {
                ", misalignment (beta)"
            } else {
                ""
            },
            r.t_ref_c
                .map_or(String::new(), |t| format!(", at t_ref {t:.2} degC")),
        );
        let names: Vec<&str> = r.parameters.iter().map(|p| p.name.as_str()).collect();
        let mut header = vec![""];
        header.extend(&names);
        let mut c = Table::new(&header);
        for (name, row) in names.iter().zip(&r.correlation) {
            let mut cells = vec![(*name).to_owned()];
            cells.extend(row.iter().map(|x| format!("{x:+.4}")));
            c.rows.push(cells);
        }
        s.details
            .push((s.tables.len(), format!("{what}: correlations"), c));
        s.tables.push((what, t));
    }
    s
}

/// The fits compared: per accelerometer with per-session linear fits and a temperature
/// model over all sessions, b and k of each session against its mean temperature, with the
/// temperature model's b(T) and k(T) and their 1-sigma bands (from its covariance).
fn comparison_section(st: &Stages<'_>) -> Result<Option<Section>, Error> {
    let mut s = section("The fits compared: b and k against temperature");
    let results = &st.cal.results;
    for thermal in results
        .iter()
        .filter(|r| r.session == "all" && r.temperature && r.order == 1 && !r.misalignment)
    {
        let sessions: Vec<&CalibrationResult> = results
            .iter()
            .filter(|r| {
                r.accelerometer == thermal.accelerometer
                    && r.session != "all"
                    && r.order == 1
                    && !r.temperature
                    && !r.misalignment
            })
            .collect();
        let Some(t_ref) = thermal.t_ref_c else {
            continue;
        };
        if sessions.is_empty() {
            continue;
        }
        for (name, slope, unit) in [("b", "b_t", "mGal"), ("k", "k_t", "mGal/bit")] {
            let at: Vec<(f64, f64, f64)> = sessions
                .iter()
                .filter_map(|r| {
                    let p = param(r, name)?;
                    Some((r.mean_temperature_c, p.value, p.sigma))
                })
                .collect();
            let line = temperature_line(thermal, name, slope, t_ref, &at);
            let Some(model_at) = temperature_model(thermal, name, slope, t_ref) else {
                continue;
            };
            // Differences from the model's line, which the plot draws at 0 with its band:
            // b changes by tens of mGal between sessions, their sigmas are below one.
            let points: Vec<(f64, f64, f64)> = at
                .iter()
                .map(|&(t, v, e)| (t, v - model_at(t), e))
                .collect();
            let line: Vec<(f64, f64, f64)> = line.iter().map(|&(t, _, e)| (t, 0.0, e)).collect();
            let title = format!(
                "{} {name}: per-session {} fits minus the {} model's {name}(T)",
                thermal.accelerometer, sessions[0].model, thermal.model
            );
            let y_label = format!("{name} - {name}(T) ({unit})");
            let labels = (
                format!("{} per session", sessions[0].model),
                format!("{} model {name}(T) (0)", thermal.model),
            );
            let svg = plots::trend(&plots::Trend {
                title: &title,
                y_label: &y_label,
                points: &points,
                line: &line,
                labels: (&labels.0, &labels.1),
            })
            .map_err(|message| Error::Plot {
                name: title.clone(),
                message,
            })?;
            s.plots.push((
                format!(
                    "trend-{}-{}-{name}.svg",
                    thermal.model, thermal.accelerometer
                ),
                svg,
            ));
        }
    }
    if s.plots.is_empty() {
        return Ok(None);
    }
    s.text.push(
        "Each session's linear fit holds b and k at its mean temperature; drawn is its \
         difference from the temperature model's b + b_t (T - t_ref) (and k + k_t (T - t_ref)) \
         at that temperature, against the model's 1-sigma band (from its parameters' \
         covariance) about 0. Points off the band by more than their bars say the \
         temperature model does not carry what changed between the sessions."
            .to_owned(),
    );
    Ok(Some(s))
}

/// The model's `name` + `slope` (T - t_ref) as a function of T.
fn temperature_model(
    r: &CalibrationResult,
    name: &str,
    slope: &str,
    t_ref: f64,
) -> Option<impl Fn(f64) -> f64> {
    let (a, b) = (param(r, name)?.value, param(r, slope)?.value);
    Some(move |t: f64| a + b * (t - t_ref))
}

/// (T, value, sigma) of `name` + `slope` (T - t_ref) over the points' temperatures (and a
/// degree beyond), from the fit's parameters and correlations.
fn temperature_line(
    r: &CalibrationResult,
    name: &str,
    slope: &str,
    t_ref: f64,
    points: &[(f64, f64, f64)],
) -> Vec<(f64, f64, f64)> {
    let index = |n: &str| r.parameters.iter().position(|p| p.name == n);
    let (Some(i), Some(j)) = (index(name), index(slope)) else {
        return Vec::new();
    };
    let (a, b) = (&r.parameters[i], &r.parameters[j]);
    let rho = r
        .correlation
        .get(i)
        .and_then(|row| row.get(j))
        .copied()
        .unwrap_or(0.0);
    let (lo, hi) = points
        .iter()
        .fold((t_ref, t_ref), |(l, h), p| (l.min(p.0), h.max(p.0)));
    (0..=40)
        .map(|k| {
            let t = lo - 1.0 + (hi - lo + 2.0) * f64::from(k) / 40.0;
            let d = t - t_ref;
            let var = a.sigma.powi(2) + (d * b.sigma).powi(2) + 2.0 * d * rho * a.sigma * b.sigma;
            (t, a.value + b.value * d, var.max(0.0).sqrt())
        })
        .collect()
}

/// Temperature, higher orders and misalignment: the significance of the extra terms.
fn extra_terms_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    // Temperature, higher orders, misalignment: significance of the extra terms.
    let mut s = section("Temperature, higher orders and misalignment");
    s.text.push(
        "Each term beyond b and k with its t = value/sigma against Student's t at 5 % (two-sided): a term is significant when |t| exceeds the critical value."
            .to_owned(),
    );
    let mut extra = Table::new(&[
        "model",
        "accelerometer",
        "session",
        "t_ref (degC)",
        "parameter",
        "value",
        "sigma",
        "unit",
        "t",
        "critical",
        "significant",
    ]);
    for r in &cal.results {
        for p in r
            .parameters
            .iter()
            .filter(|p| p.name != "b" && p.name != "k")
        {
            let t = if p.sigma > 0.0 {
                p.value / p.sigma
            } else {
                0.0
            };
            let crit = t_critical(r.dof);
            extra.rows.push(vec![
                r.model.clone(),
                r.accelerometer.clone(),
                r.session.clone(),
                r.t_ref_c
                    .map(|t| format!("{t:.2}"))
                    .unwrap_or_else(|| "-".into()),
                p.name.clone(),
                format!("{:.6e}", p.value),
                format!("{:.3e}", p.sigma),
                p.unit.clone(),
                format!("{t:.2}"),
                format!("{crit:.3}"),
                if t.abs() > crit { "yes" } else { "no" }.to_owned(),
            ]);
        }
    }
    if extra.rows.is_empty() {
        s.text
            .push("No model with terms beyond b and k was fitted.".to_owned());
    } else {
        s.tables.push(("Extra terms".to_owned(), extra));
    }
    for r in cal.results.iter().filter(|r| !r.warnings.is_empty()) {
        for w in &r.warnings {
            s.text.push(format!(
                "{} {} {}: {w}",
                r.model, r.accelerometer, r.session
            ));
        }
    }
    s
}

/// The global test, data snooping and the fits skipped.
fn snooping_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    // Blunders and skipped fits.
    let mut s = section("Global test and data snooping");
    s.text.push(format!(
        "Data snooping removed, one at a time, the observation with the largest normalised residual |w| > {} (alpha = 0.001) and re-adjusted. Every removal:",
        adjust::calibrate::W_CRITICAL
    ));
    let mut removed = Table::new(&[
        "model",
        "accelerometer",
        "fit",
        "session",
        "station",
        "line",
        "GPS week / tow (s)",
        "w",
    ]);
    for r in &cal.results {
        for x in &r.removed {
            removed.rows.push(vec![
                r.model.clone(),
                r.accelerometer.clone(),
                r.session.clone(),
                x.session.clone(),
                x.station.clone(),
                x.line.to_string(),
                gps(x.time_gps_ns),
                format!("{:.2}", x.w),
            ]);
        }
    }
    s.tables.push(("Removed observations".to_owned(), removed));
    s
}

/// What was read, used and excluded, from the ledgers.
fn ledger_section(st: &Stages<'_>) -> Section {
    let Stages {
        ingest_report,
        align_report,
        ..
    } = st;
    // Ledgers.
    let mut s = section("What was read, used and excluded");
    let mut files = Table::new(&[
        "file",
        "role",
        "read",
        "accepted",
        "rejected",
        "bytes skipped",
        "null values",
    ]);
    for f in &ingest_report.files {
        let rejected: Vec<String> = f.rejected.iter().map(|(r, n)| format!("{n} {r}")).collect();
        let nulls: Vec<String> = f
            .null_values
            .iter()
            .map(|(r, n)| format!("{n} {r}"))
            .collect();
        files.rows.push(vec![
            f.path.clone(),
            f.role.clone(),
            format!("{} {}", f.read, f.unit),
            f.accepted.to_string(),
            if rejected.is_empty() {
                "-".into()
            } else {
                rejected.join(", ")
            },
            f.byte_ledger
                .as_ref()
                .map_or("-".into(), |b| b.skipped_resynchronising.to_string()),
            if nulls.is_empty() {
                "-".into()
            } else {
                nulls.join(", ")
            },
        ]);
    }
    s.tables.push(("Ingest".to_owned(), files));
    let mut al = Table::new(&["session", "accelerometer", "readings", "used", "excluded"]);
    for c in &align_report.counts {
        let ex: Vec<String> = c.excluded.iter().map(|(r, n)| format!("{n} {r}")).collect();
        al.rows.push(vec![
            c.session.clone(),
            c.accelerometer.clone(),
            c.readings.to_string(),
            c.used.to_string(),
            if ex.is_empty() {
                "-".into()
            } else {
                ex.join(", ")
            },
        ]);
    }
    for d in &align_report.disconnected {
        al.rows.push(vec![
            d.session.clone(),
            d.accelerometer.clone(),
            "-".into(),
            "0".into(),
            format!("channel {}: {}", d.channel, d.reason),
        ]);
    }
    if al.rows.is_empty() {
        return s;
    }
    s.tables.push((
        format!(
            "Align (window of {} s, fill >= {})",
            align_report.config.window_s, align_report.config.min_window_fill
        ),
        al,
    ));
    s.text.push(format!(
        "Align settings: ADC window {} s centred on each reading, at least {} of its samples, temperature within {} s, {} arcsec for a station with a single reading.",
        align_report.config.window_s,
        align_report.config.min_window_fill,
        align_report.config.max_temperature_gap_s,
        align_report.config.theodolite_sigma_arcsec
    ));
    s
}

/// Residual plots, calibration curves, the sigma of one reading and the tide.
fn plots_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("Residuals, observation sigmas and calibration curves");
    s.text.push("Condition residuals B·v in mGal of every per-session fit; crosses mark observations removed by data snooping, drawn at their misclosure under the final parameters.".to_owned());
    // One residual axis per model, so that its fits' small multiples compare at a glance.
    let y_range = |model: &str| {
        let used = st
            .residuals
            .iter()
            .filter(|x| x.model == model && !x.removed)
            .filter_map(|x| x.residual_mgal);
        let (lo, hi) = plots::range(used);
        Some((lo.min(0.0), hi.max(0.0)))
    };
    for r in st.cal.results.iter().filter(|r| r.session != "all") {
        s.plots.extend(fit_plots(st, r, y_range(&r.model))?);
    }
    for session in st.ds.sessions.iter().filter(|x| x.is_tilt_table()) {
        s.plots.extend(sigma_plot(st, &session.session.id)?);
        s.plots.extend(tide_plot(st, &session.session.id)?);
    }
    Ok(s)
}

/// A plot: its file name and SVG.
type Plot = (String, String);

/// One per-session fit's residuals against Dz, time and temperature, and its calibration
/// curve.
fn fit_plots(
    st: &Stages<'_>,
    r: &CalibrationResult,
    y_range: Option<(f64, f64)>,
) -> Result<Vec<Plot>, Error> {
    let g = st.cal.gravity_mgal;
    let residuals = &st.residuals;
    let mut plots = Vec::new();
    let mine: Vec<&adjust::io::ResidualRecord> = residuals
        .iter()
        .filter(|x| {
            x.model == r.model && x.accelerometer == r.accelerometer && x.fit_session == r.session
        })
        .collect();
    if mine.is_empty() {
        return Ok(Vec::new());
    }
    let misclosure = |x: &adjust::io::ResidualRecord| -> f64 {
        x.residual_mgal
            .unwrap_or_else(|| -predict_misclosure(r, g, x))
    };
    let t0 = mine.iter().map(|x| x.time_gps_ns).min().unwrap_or(0);
    let split = |f: &dyn Fn(&adjust::io::ResidualRecord) -> f64| -> (Points, Points) {
        let used = mine
            .iter()
            .filter(|x| !x.removed)
            .map(|x| (f(x), misclosure(x)))
            .collect();
        let removed = mine
            .iter()
            .filter(|x| x.removed)
            .map(|x| (f(x), misclosure(x)))
            .collect();
        (used, removed)
    };
    let name = format!("{}-{}-{}", r.model, r.accelerometer, r.session);
    let axes: [Axis<'_>; 3] = [
        ("dz", "Dz (deg)", Box::new(|x| x.dz_rad.to_degrees())),
        (
            "time",
            "time since first reading (min)",
            Box::new(move |x| (x.time_gps_ns - t0) as f64 / 60e9),
        ),
        (
            "temperature",
            "temperature (degC)",
            Box::new(|x| x.temperature_c),
        ),
    ];
    for (key, xl, f) in axes {
        let (used, removed) = split(&*f);
        let title = format!(
            "{} {} ({}): residual vs {key}",
            r.accelerometer, r.session, r.model
        );
        let svg = plots::scatter(&plots::Scatter {
            title: &title,
            x_label: xl,
            y_label: "residual (mGal)",
            used: &used,
            removed: &removed,
            line: &[],
            zero_line: true,
            labels: plots::ADJUSTMENT_LABELS,
            y_range,
        })
        .map_err(|message| Error::Plot {
            name: name.clone(),
            message,
        })?;
        plots.push((format!("{name}-residual-{key}.svg"), svg));
    }
    if let Some(curve) = calibration_curve(r, g, &mine, &name)? {
        plots.push(curve);
    }
    Ok(plots)
}

/// The calibration curve: F = -g cos(Dz) against Ng, with the fitted function.
fn calibration_curve(
    r: &CalibrationResult,
    g: f64,
    mine: &[&adjust::io::ResidualRecord],
    name: &str,
) -> Result<Option<Plot>, Error> {
    let (Some(b), Some(k)) = (param(r, "b"), param(r, "k")) else {
        return Ok(None);
    };
    let pts: Vec<(f64, f64)> = mine
        .iter()
        .filter(|x| !x.removed)
        .map(|x| (x.ng / 1e6, -g * x.dz_rad.cos()))
        .collect();
    let rem: Vec<(f64, f64)> = mine
        .iter()
        .filter(|x| x.removed)
        .map(|x| (x.ng / 1e6, -g * x.dz_rad.cos()))
        .collect();
    let (lo, hi) = pts
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), p| {
            (a.min(p.0), c.max(p.0))
        });
    let line: Vec<(f64, f64)> = (0..=20)
        .map(|i| lo + (hi - lo) * f64::from(i) / 20.0)
        .map(|u| (u, b.value + k.value * u * 1e6))
        .collect();
    let title = format!(
        "{} {} ({}): calibration a = b + k Ng",
        r.accelerometer, r.session, r.model
    );
    let svg = plots::scatter(&plots::Scatter {
        title: &title,
        x_label: "Ng (million counts)",
        y_label: "acceleration (mGal)",
        used: &pts,
        removed: &rem,
        line: &line,
        zero_line: false,
        labels: plots::ADJUSTMENT_LABELS,
        y_range: None,
    })
    .map_err(|message| Error::Plot {
        name: name.to_owned(),
        message,
    })?;
    Ok(Some((format!("{name}-calibration.svg"), svg)))
}

/// The ADC noise: the Allan deviation of each accelerometer's counts over the still
/// intervals, log-log, with the fitted terms; and those terms in SI units (Kalibr's names).
fn noise_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("ADC noise: Allan deviation");
    s.text.push(
        "Overlapping Allan deviation of each accelerometer's counts, pooled over the still intervals (the platform at rest at a \
         station), with the white-noise density N, bias instability B and random walk K fitted to sigma^2(tau) = N^2/tau + \
         (2 ln 2/pi) B^2 + K^2 tau/3. For white noise the curve falls as tau^-1/2; it flattens with flicker and rises with a \
         random walk. In SI units by the accelerometer's scale factor k, under Kalibr's imu.yaml names. A B or K below 2 \
         standard errors of its fit is not determined by these curves and shows as such. When B or K is found, the sd of each \
         window mean includes their Allan variance at the window's length, and the adjustment propagates the noise's \
         correlation between stations and over the session into the parameters' sigmas (flicker modelled up to 5000 s)."
            .to_owned(),
    );
    let determined = |x: f64| {
        if x > 0.0 {
            format!("{x:.4}")
        } else {
            "not determined".to_owned()
        }
    };
    let mut t = Table::new(&[
        "accelerometer",
        "still intervals",
        "samples",
        "N (counts/sqrt(Hz))",
        "B (counts)",
        "K (counts sqrt(Hz))",
        "accelerometer_noise_density (m/s^2/sqrt(Hz))",
        "accelerometer_random_walk (m/s^3/sqrt(Hz))",
        "scale from",
    ]);
    for n in &st.align_report.noise {
        let si = st
            .cal
            .adc_noise
            .iter()
            .find(|k| k.accelerometer == n.accelerometer);
        t.rows.push(vec![
            n.accelerometer.clone(),
            n.still_intervals.to_string(),
            n.samples.to_string(),
            format!("{:.4}", n.white_density_counts_per_sqrt_hz),
            determined(n.bias_instability_counts),
            determined(n.random_walk_counts_sqrt_hz),
            si.map_or("-".into(), |k| {
                format!("{:.3e}", k.accelerometer_noise_density)
            }),
            si.map_or("-".into(), |k| {
                k.accelerometer_random_walk
                    .map_or("not determined".into(), |x| format!("{x:.3e}"))
            }),
            si.map_or("-".into(), |k| k.scale_from.clone()),
        ]);
        let pts: Vec<(f64, f64)> = n
            .allan
            .iter()
            .map(|r| (r.tau_s.log10(), r.adev.log10()))
            .collect();
        let terms = align::allan::NoiseTerms {
            white_density: n.white_density_counts_per_sqrt_hz,
            bias_instability: n.bias_instability_counts,
            random_walk: n.random_walk_counts_sqrt_hz,
        };
        let model = |tau: f64| terms.allan_variance(tau).sqrt();
        let line: Vec<(f64, f64)> = n
            .allan
            .iter()
            .map(|r| (r.tau_s.log10(), model(r.tau_s).log10()))
            .collect();
        let title = format!("{}: Allan deviation of the counts (log10)", n.accelerometer);
        let svg = plots::scatter(&plots::Scatter {
            title: &title,
            x_label: "log10 tau (s)",
            y_label: "log10 Allan deviation (counts)",
            used: &pts,
            removed: &[],
            line: &line,
            zero_line: false,
            labels: ("Allan deviation", "fitted N, B, K"),
            y_range: None,
        })
        .map_err(|message| Error::Plot {
            name: format!("allan-{}", n.accelerometer),
            message,
        })?;
        s.plots
            .push((format!("allan-{}.svg", n.accelerometer), svg));
    }
    s.tables.push(("Noise terms".to_owned(), t));
    Ok(s)
}

/// The body tide applied at each reading of session `id` against time, when one was.
fn tide_plot(st: &Stages<'_>, id: &str) -> Result<Option<Plot>, Error> {
    let Some(first) = st.ds.manifest.instrument.accelerometer.first() else {
        return Ok(None);
    };
    let mine: Vec<&adjust::io::ObservationRow> = st
        .observations
        .iter()
        .filter(|o| o.session == id && o.accelerometer == first.id)
        .collect();
    let Some(t0) = mine.iter().map(|o| o.time_gps_ns).min() else {
        return Ok(None);
    };
    let pts: Vec<(f64, f64)> = mine
        .iter()
        .filter_map(|o| {
            o.tide_mgal
                .map(|t| ((o.time_gps_ns - t0) as f64 / 3.6e12, t * 1e3))
        })
        .collect();
    if pts.is_empty() {
        return Ok(None);
    }
    let title = format!("{id}: body tide added to g at each reading");
    let svg = plots::scatter(&plots::Scatter {
        title: &title,
        x_label: "time since first reading (h)",
        y_label: "tide (microGal)",
        used: &pts,
        removed: &[],
        line: &[],
        zero_line: true,
        labels: ("readings", ""),
        y_range: None,
    })
    .map_err(|message| Error::Plot {
        name: format!("tide-{id}"),
        message,
    })?;
    Ok(Some((format!("tide-{id}.svg"), svg)))
}

/// The sigma of one reading against Dz, for session `id`.
fn sigma_plot(st: &Stages<'_>, id: &str) -> Result<Option<Plot>, Error> {
    let (cal, residuals) = (&st.cal, &st.residuals);
    let g = cal.gravity_mgal;
    let Some(first) = cal.results.iter().find(|r| r.session == id) else {
        return Ok(None);
    };
    let pts: Vec<(f64, f64)> = residuals
        .iter()
        .filter(|x| {
            x.model == first.model && x.accelerometer == first.accelerometer && x.fit_session == id
        })
        .map(|x| {
            (
                x.dz_rad.to_degrees(),
                g * x.dz_rad.sin().abs() * x.sigma_dz_rad,
            )
        })
        .collect();
    let title = format!("{id}: sigma of one reading, g |sin Dz| sigma_Dz");
    let svg = plots::scatter(&plots::Scatter {
        title: &title,
        x_label: "Dz (deg)",
        y_label: "sigma (mGal)",
        used: &pts,
        removed: &[],
        line: &[],
        zero_line: false,
        labels: ("observations", ""),
        y_range: None,
    })
    .map_err(|message| Error::Plot {
        name: id.to_owned(),
        message,
    })?;
    Ok(Some((format!("sigma-{id}.svg"), svg)))
}

/// The condition value g cos(Dz + beta) + c(Ng, T) of an observation under the fit's final
/// parameters (the misclosure before residuals), for observations removed by snooping.
fn predict_misclosure(r: &CalibrationResult, g: f64, x: &adjust::io::ResidualRecord) -> f64 {
    let v = |name: &str| param(r, name).map_or(0.0, |p| p.value);
    let tau = r.t_ref_c.map_or(0.0, |t| x.temperature_c - t);
    let ng = x.ng;
    let c = v("b")
        + v("b_t") * tau
        + (v("k") + v("k_t") * tau) * ng
        + v("k2") * ng * ng
        + v("k3") * ng * ng * ng;
    g * (x.dz_rad + v("beta")).cos() + c
}

/// The report as Markdown.
pub fn markdown(name: &str, sections: &[Section]) -> String {
    let mut s = format!("# Calibration report: {name}\n");
    for sec in sections {
        let _ = write!(s, "\n## {}\n\n", sec.title);
        for t in &sec.text {
            let _ = write!(s, "{t}\n\n");
        }
        for (i, (caption, t)) in sec.tables.iter().enumerate() {
            let _ = write!(s, "**{caption}**\n\n{}\n", t.markdown());
            for (_, caption, t) in sec.details.iter().filter(|d| d.0 == i) {
                let _ = write!(s, "**{caption}**\n\n{}\n", t.markdown());
            }
        }
        for (file, _) in &sec.plots {
            let _ = writeln!(s, "![{file}](plots/{file})");
        }
    }
    s
}

const CSS: &str = "body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:0.85em}th,td{border:1px solid #bbb;padding:3px 6px;text-align:right}\
th{background:#eef}td:first-child,th:first-child{text-align:left}h1{border-bottom:2px solid #446}\
.plots{display:flex;flex-wrap:wrap;gap:8px}.plots figure{margin:0}caption,.caption{font-weight:bold;text-align:left}\
code{background:#f3f3f6;padding:0 3px;border-radius:3px;font-size:0.95em}details{margin:0 0 1em}summary{cursor:pointer;color:#446}\
@page{size:A4;margin:14mm}\
@media print{body{max-width:none;margin:0;padding:0;font-size:9pt}table{font-size:8pt;page-break-inside:auto}\
tr,figure{page-break-inside:avoid}h2,h3,.caption{page-break-after:avoid}.plots svg{max-width:100%;height:auto}\
details{display:block}details>*{display:block}code{background:none}}";

/// Markdown's inline code (`...`) as HTML `<code>` in already escaped text; an unpaired
/// backtick stays as it is.
fn inline_code(escaped: &str) -> String {
    let parts: Vec<&str> = escaped.split('`').collect();
    if parts.len().is_multiple_of(2) {
        return escaped.to_owned();
    }
    let mut out = String::with_capacity(escaped.len() + 16);
    for (i, p) in parts.iter().enumerate() {
        if i % 2 == 1 {
            let _ = write!(out, "<code>{p}</code>");
        } else {
            out.push_str(p);
        }
    }
    out
}

/// A section's id in the page: its title's words in lower case joined by `-`
/// (`summary-the-calibrations`).
fn anchor(title: &str) -> String {
    title
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_ascii_lowercase)
        .collect::<Vec<_>>()
        .join("-")
}

/// The report as one self-contained HTML page.
pub fn html(name: &str, sections: &[Section]) -> String {
    let mut s = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>Calibration report: {}</title><style>{CSS}</style></head><body>\n<h1>Calibration report: {}</h1>\n",
        esc(name),
        esc(name)
    );
    for sec in sections {
        let _ = writeln!(
            s,
            "<section id=\"{}\"><h2>{}</h2>",
            anchor(&sec.title),
            esc(&sec.title)
        );
        for t in &sec.text {
            let _ = writeln!(s, "<p>{}</p>", inline_code(&esc(t)));
        }
        for (i, (caption, t)) in sec.tables.iter().enumerate() {
            let _ = writeln!(
                s,
                "<div class=\"caption\">{}</div>{}",
                esc(caption),
                t.html()
            );
            for (_, caption, t) in sec.details.iter().filter(|d| d.0 == i) {
                let _ = writeln!(
                    s,
                    "<details><summary>{}</summary>{}</details>",
                    esc(caption),
                    t.html()
                );
            }
        }
        if !sec.plots.is_empty() {
            s.push_str("<div class=\"plots\">");
            for (file, svg) in &sec.plots {
                let body = svg.find("<svg").map_or(svg.as_str(), |i| &svg[i..]);
                let _ = write!(s, "<figure id=\"{}\">{body}</figure>", esc(file));
            }
            s.push_str("</div>\n");
        }
        s.push_str("</section>\n");
    }
    s.push_str("</body></html>\n");
    s
}

fn write_atomically(path: &Path, text: &str) -> Result<(), Error> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.partial"));
    std::fs::write(&tmp, text).map_err(|e| Error::Io {
        path: tmp.clone(),
        source: e,
    })?;
    std::fs::rename(&tmp, path).map_err(|e| Error::Io {
        path: path.to_path_buf(),
        source: e,
    })
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
    let _lock = ingest::lock::OutputLock::acquire(out)?;
    let sections = build(&ds, out)?;
    let dir = out.join("report");
    let plot_dir = dir.join("plots");
    std::fs::create_dir_all(&plot_dir).map_err(|e| Error::Io {
        path: plot_dir.clone(),
        source: e,
    })?;
    let mut plots = 0;
    for sec in &sections {
        for (file, svg) in &sec.plots {
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
