//! The answer first (every fit's calibration with its verdict and advice), the dataset, the
//! calibration function, the ledgers, and the chain of custody as an appendix.

use super::{
    Calibration, IngestReport, Parameter, Section, Stages, Table, calibration, custody_table,
    section,
};

/// A fit's one-line verdict from its global test.
pub(crate) fn verdict(test: &calibration::GlobalTest) -> &'static str {
    if test.rejects_the_model() {
        "REJECTED by the global test: see below"
    } else if test.passed {
        "consistent with its sigmas"
    } else {
        "sigmas pessimistic (global test low)"
    }
}

/// The answer: every accelerometer's calibration of every model, with its sigmas, sigma0,
/// the global test, the observations used and removed, and a one-line verdict; then what
/// was not fitted and why.
pub(crate) fn summary_section(st: &Stages<'_>) -> Section {
    let cal = &st.cal;
    let mut s = section("Summary: the calibrations");
    s.text.push(models_sentence(cal, &st.align_report.surveys));
    let t = calibrations_table(cal);
    if !t.rows.is_empty() {
        s.tables.push(("Calibrations".to_owned(), t));
    }
    s.text.extend(global_test_advice(cal));
    if !cal.skipped.is_empty() {
        let mut k = Table::headed("model | accelerometer | session | why not");
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

/// What the dataset's models are, and how `apply` chooses among them; or why there is none.
fn models_sentence(cal: &Calibration, surveys: &[String]) -> String {
    let models: std::collections::BTreeSet<&str> = cal
        .results
        .iter()
        .map(|r| r.model.as_str())
        .chain(cal.triad.iter().map(|t| t.model.as_str()))
        .collect();
    match models.len() {
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
            "{n} models ({}): `cargo xtask apply --model M` chooses the one to apply; sigmas are at the estimated variance components, each the sd of its parameter's t, so that +/- 2 sigma is a 95 % interval.",
            models.iter().copied().collect::<Vec<_>>().join(", ")
        ),
    }
}

/// One row per fit, axis and triad: what was fitted, its parameters with sigmas, and its
/// statistics.
fn calibrations_table(cal: &Calibration) -> Table {
    let mut t = Table::headed(
        "model | accelerometer | session | calibration (value +/- sigma) | sigma0 | global test | used / removed | verdict",
    );
    for r in &cal.results {
        let fit = Fit {
            parameters: &r.parameters,
            t_ref: r.t_ref_c,
            gt: &r.global_test,
            sigma0: r.sigma0,
        };
        t.rows.push(summary_row(
            [&r.model, &r.accelerometer, &r.session],
            &fit,
            format!("{} / {}", r.n_observations, r.n_excluded),
        ));
    }
    for r in &cal.triad {
        let removed = r.positions.iter().filter(|p| p.removed).count();
        let fit = Fit {
            parameters: &r.parameters,
            t_ref: None,
            gt: &r.global_test,
            sigma0: r.sigma0,
        };
        let mut row = summary_row(
            [&r.model, "triad (x, y, z)", &r.session],
            &fit,
            format!("{} positions / {removed}", r.positions_used),
        );
        if let (Some(f), Some(cell)) = (r.estimated_floor(), row.last_mut()) {
            *cell = format!(
                "sigmas include a position floor of {:.3e} mGal: see below",
                f.mgal
            );
        }
        t.rows.push(row);
    }
    t
}

/// What the calibrations' table shows of a fit: its parameters, their reference temperature
/// (None without temperature terms), its global test and sigma0.
struct Fit<'a> {
    parameters: &'a [Parameter],
    t_ref: Option<f64>,
    gt: &'a calibration::GlobalTest,
    sigma0: f64,
}

/// A row of the calibrations' table: who was fitted, the `fit`, the observations `used`.
fn summary_row(who: [&str; 3], fit: &Fit<'_>, used: String) -> Vec<String> {
    let Fit {
        parameters,
        t_ref,
        gt,
        sigma0,
    } = *fit;
    let calibration = parameters
        .iter()
        .map(Parameter::with_sigma)
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
}

/// What each failed global test means and what to try, axis fits first.
fn global_test_advice(cal: &Calibration) -> Vec<String> {
    let axis = cal.results.iter().filter_map(|r| {
        r.global_test.advice(
            &format!("{} {} {}", r.model, r.accelerometer, r.session),
            false,
        )
    });
    let triad = cal.triad.iter().filter_map(|r| r.advice());
    axis.chain(triad).collect()
}

/// Appendix: the inputs' hashes and the chain of custody.
pub(crate) fn custody_section(st: &Stages<'_>) -> Section {
    let mut s = section("Appendix: inputs and chain of custody");
    let mut inputs = Table::headed("file | SHA-256 | bytes");
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
pub(crate) fn dataset_section(st: &Stages<'_>) -> Section {
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
pub(crate) fn function_section() -> Section {
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

/// What was read, used and excluded, from the ledgers.
pub(crate) fn ledger_section(st: &Stages<'_>) -> Section {
    let Stages {
        ingest_report,
        align_report,
        ..
    } = st;
    // Ledgers.
    let mut s = section("What was read, used and excluded");
    s.tables
        .push(("Ingest".to_owned(), ingest_table(ingest_report)));
    let mut al = Table::headed("session | accelerometer | readings | used | excluded");
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

/// Ingest's ledger per file: what was read, accepted and rejected (by reason), the bytes
/// skipped resynchronising and the values stored as null.
fn ingest_table(report: &IngestReport) -> Table {
    let mut files =
        Table::headed("file | role | read | accepted | rejected | bytes skipped | null values");
    for f in &report.files {
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
    files
}
