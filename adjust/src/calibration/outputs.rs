//! calibration.json and residuals.parquet written with their chain of custody, and the
//! console's summary.

use super::triad_fits;
use crate::Error;
use ingest::contract::align_ledger;
use ingest::contract::calibration::{
    CALIBRATION_FILE, Calibration, CalibrationResult, Parameter, STAGE_DIR,
};
use ingest::contract::custody::{Custody, Folders, Root};
use ingest::contract::ingest_ledger;
use ingest::contract::manifest::Dataset;
use ingest::contract::tables;
use std::path::Path;

/// Writes residuals.parquet and calibration.json, with the chain of custody: every file
/// adjust read and the table it wrote.
pub(crate) fn write_outputs(
    ds: &Dataset,
    out: &Path,
    mut calibration: Calibration,
    residual_rows: &[tables::residuals::Fitted<'_>],
) -> Result<Calibration, Error> {
    let dir = out.join(STAGE_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| ingest::Error::io(dir.clone(), e))?;
    let cal_path = dir.join(CALIBRATION_FILE);
    ingest::remove_stale(&cal_path)?;
    tables::residuals::write(&dir, residual_rows)?;
    let folders = Folders {
        dataset: &ds.dir,
        out,
    };
    let mut inputs = vec![folders.record(Root::Dataset, ingest_ledger::MANIFEST_FILE)?];
    for file in [
        format!(
            "{}/{}",
            ingest_ledger::STAGE_DIR,
            ingest_ledger::LEDGER_FILE
        ),
        format!("{}/{}", align_ledger::STAGE_DIR, align_ledger::LEDGER_FILE),
        format!("{}/{}", align_ledger::STAGE_DIR, tables::observations::FILE),
    ] {
        inputs.push(folders.record(Root::Out, &file)?);
    }
    let mut outputs = vec![folders.record(
        Root::Out,
        &format!("{STAGE_DIR}/{}", tables::residuals::FILE),
    )?];
    // A file name joins a model's name and a session's id with `-`, which they may hold.
    let mut names = ingest::contract::manifest::Names::default();
    for t in &calibration.triad {
        let Some(file) = &t.calib_file else {
            continue;
        };
        let path = dir.join(file);
        names.insert(file, "file").map_err(|e| Error::OutputName {
            path: path.clone(),
            message: format!(
                "{e}: two triad fits (model {}, session {} among them) would write one \
                     file; rename a model or a session",
                t.model, t.session
            ),
        })?;
        ingest::write_atomically(&path, triad_fits::calib_text(t).as_bytes())
            .map_err(|e| ingest::Error::io(path.clone(), e))?;
        outputs.push(folders.record(Root::Out, &format!("{STAGE_DIR}/{file}"))?);
    }
    calibration.custody = Custody { inputs, outputs };
    ingest::write_json_atomically(&cal_path, &calibration)?;
    Ok(calibration)
}

/// A few lines per fit: b, k and sigma0; and every skipped fit with its reason.
pub fn print_summary(c: &Calibration, w: &mut impl std::io::Write) {
    if c.results.is_empty() && c.skipped.is_empty() && c.triad.is_empty() {
        let _ = writeln!(
            w,
            "adjust: no observation to calibrate with (a dataset of survey sessions only: \
             `cargo xtask apply` calibrates them)"
        );
    }
    for t in &c.triad {
        print_triad(t, w);
    }
    for r in &c.results {
        print_fit(r, w);
    }
    if let Some(advice) = c.component_advice() {
        let _ = writeln!(w, "adjust: {advice}");
    }
    for r in &c.repeatability {
        let _ = writeln!(w, "adjust: {}", r.sentence());
    }
    for s in &c.skipped {
        let _ = writeln!(
            w,
            "adjust: {} {} {}: skipped: {}",
            s.model, s.accelerometer, s.session, s.reason
        );
    }
}

/// A triad fit's line: its parameters, sigma0, positions, the global test and its imu_tk
/// file; and what a failed global test means.
fn print_triad(t: &ingest::contract::calibration::TriadResult, w: &mut impl std::io::Write) {
    let removed = t.positions.iter().filter(|p| p.removed).count();
    let p: Vec<String> = t.parameters.iter().map(Parameter::with_sigma).collect();
    let _ = writeln!(
        w,
        "adjust: triad {} {}: {}; sigma0 {:.3}, {} positions, {removed} removed{}, global test {}{}; {}",
        t.model,
        t.session,
        p.join(", "),
        t.sigma0,
        t.positions_used,
        match t.positions_without_temperature {
            0 => String::new(),
            n => format!(", {n} without temperature left out"),
        },
        t.global_test.verdict(),
        t.floor_clause(),
        t.calib_file.as_ref().map_or_else(
            || "no imu_tk file (its layout has no higher orders or temperature terms)".to_owned(),
            |f| format!("wrote {f}")
        )
    );
    if let Some(advice) = t.advice() {
        let _ = writeln!(w, "adjust: {advice}");
    }
    for warning in t.unit_warnings() {
        let _ = writeln!(w, "adjust: triad {} {}: {warning}", t.model, t.session);
    }
}

/// An axis fit's line: its parameters, sigma0, observations, the global test; what a failed
/// global test means, and the fit's warnings.
fn print_fit(r: &CalibrationResult, w: &mut impl std::io::Write) {
    let p: Vec<String> = r.parameters.iter().map(Parameter::with_sigma).collect();
    let _ = writeln!(
        w,
        "adjust: {} {} {}: {}; sigma0 {:.3}, {} obs, {} removed, global test {}",
        r.model,
        r.accelerometer,
        r.session,
        p.join(", "),
        r.sigma0,
        r.n_observations,
        r.n_excluded,
        r.global_test.verdict_in_a_table()
    );
    if let Some(advice) = r.global_test.advice(
        &format!("{} {} {}", r.model, r.accelerometer, r.session),
        false,
    ) {
        let _ = writeln!(w, "adjust: {advice}");
    }
    for note in &r.warnings {
        let _ = writeln!(
            w,
            "adjust: {} {} {}: {note}",
            r.model, r.accelerometer, r.session
        );
    }
}
