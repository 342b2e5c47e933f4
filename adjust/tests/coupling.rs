//! Cross-coupling on simulated cruises with known coefficients (issue 48, docs/model.md 7
//! "Cross-coupling"): `fixtures::meter` writes a DGS laptop file whose gravity holds the
//! monitors' coupling; the gravity stage fits it (`cross_coupling = "fit"`) and corrects
//! the anomaly. Over replicas, the coefficients' errors against their sigmas say which
//! covariance is honest; the corrected, filtered anomaly is held to the truth within its
//! sigma.

use adjust::gravity::stage::GravityArgs;
use ingest::contract::gravity_ledger::GravityReport;
use ingest::contract::tables::gravity;
use std::path::Path;

/// A cruise of `seconds` from `seed` reduced: the report, and per epoch the filtered value
/// and its sigma against the truth's disturbance (the truth filtered as the stage filters,
/// as the stage's own convention: the edges without a value are left out).
fn cruise(
    dir: &Path,
    (seconds, seed): (usize, u64),
    cross_coupling: &str,
) -> (GravityReport, Vec<(f64, f64, f64)>) {
    let dataset = dir.join("cruise");
    let truth =
        fixtures::meter::write_cruise(&dataset, seconds, seed, cross_coupling).expect("cruise");
    let out = dir.join("out");
    let report = GravityArgs {
        apply: adjust::apply::stream::ApplyArgs {
            dataset,
            calibration: adjust::apply::stream::VENDOR.into(),
            model: None,
            session: None,
            out: None,
        },
        accelerometer: None,
        skip_bad_lines: false,
        block_epochs: None,
    }
    .run(&out)
    .expect("reduced");
    let (sections, pad, pivot) = (
        adjust::gravity::filter::butterworth(
            adjust::gravity::filter::ORDER,
            1.0 / report.filter.filter_s,
            1.0,
        )
        .expect("filter"),
        720,
        240,
    );
    let truth_filtered =
        adjust::gravity::filter::filtfilt_pivoted(&sections, &truth.disturbance_mgal, pad, pivot);
    let mut rows = Vec::new();
    let names = ["down_filtered_mgal", "sigma_down_mgal"];
    let path = out.join("gravity").join(gravity::FILE);
    let mut k = 0;
    align::read::float_batches(&path, &names, gravity::FLAGS, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            let (v, s) = (b.values[0].value(i), b.values[1].value(i));
            if v.is_finite() {
                rows.push((v, s, truth_filtered[k]));
            }
            k += 1;
        }
        Ok(())
    })
    .expect("gravity.parquet");
    (report, rows)
}

/// The rms of the corrected, filtered anomaly's error against the truth once the untied
/// level (the meter's stated offset; the simulated meter has no other) is taken out, and
/// the rms of that error over its sigma.
fn scores(rows: &[(f64, f64, f64)]) -> (f64, f64) {
    let n = rows.len() as f64;
    let mean = rows.iter().map(|(v, _, t)| v - t).sum::<f64>() / n;
    let rms = (rows
        .iter()
        .map(|(v, _, t)| (v - t - mean).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let z = (rows
        .iter()
        .map(|(v, s, t)| ((v - t - mean) / s).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    (rms, z)
}

/// One cruise of two hours: each coefficient within 3 of its sigma of the truth, and the
/// corrected anomaly's error a fraction of the uncorrected one's (the coupling is about 4
/// mGal rms).
#[test]
fn a_cruise_with_known_cross_coupling_is_corrected() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (report, rows) = cruise(dir.path(), (7200, 1), "fit");
    let c = report.sessions[0].cross_coupling.as_ref().expect("fitted");
    for i in 0..4 {
        let z = (c.coefficients[i] - fixtures::meter::COUPLING[i]) / c.sigma[i];
        eprintln!(
            "{}: {:.4e} +/- {:.2e} (OLS {:.2e}), truth {:.4e}: z {z:.2}",
            adjust::gravity::coupling::MONITORS[i],
            c.coefficients[i],
            c.sigma[i],
            c.ols_sigma.expect("a fit's")[i],
            fixtures::meter::COUPLING[i]
        );
        assert!(z.abs() < 3.0, "{i}: z {z}");
    }
    let (rms, z) = scores(&rows);
    let dir = tempfile::tempdir().expect("tempdir");
    let (_, rows) = cruise(dir.path(), (7200, 1), "none");
    let (uncorrected, _) = scores(&rows);
    eprintln!(
        "corrected: rms error {rms:.3} mGal (rms z {z:.2}); uncorrected {uncorrected:.3} mGal"
    );
    assert!(rms < uncorrected / 3.0, "{rms} against {uncorrected} mGal");
}

/// Replicas of the cruise (`GRAVCAL_MONTE_CARLO=1`: 200, else 24): the rms over replicas and
/// coefficients of (error / sigma) for the Newey-West sigmas the stage carries and for the
/// ordinary ones, and the corrected anomaly's rms z. Neither covariance is honest yet
/// (docs/model.md 7 gives the figures): asserted is only that the carried one is far nearer
/// than the ordinary one, which assumes the filtered residuals independent.
#[test]
fn monte_carlo_of_the_cross_coupling_sigmas() {
    let replicas = if std::env::var_os("GRAVCAL_MONTE_CARLO").is_some() {
        200
    } else {
        24
    };
    let (mut nw, mut ols, mut anomaly) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 0..replicas {
        let dir = tempfile::tempdir().expect("tempdir");
        let (report, rows) = cruise(dir.path(), (7200, 1000 + seed), "fit");
        let c = report.sessions[0].cross_coupling.clone().expect("fitted");
        for i in 0..4 {
            let e = c.coefficients[i] - fixtures::meter::COUPLING[i];
            nw.push(e / c.sigma[i]);
            ols.push(e / c.ols_sigma.expect("a fit's")[i]);
        }
        anomaly.push(scores(&rows).1);
    }
    let rms = |z: &[f64]| (z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64).sqrt();
    eprintln!(
        "{replicas} cruises: coefficients' rms z {:.2} with the Newey-West sigmas, {:.2} with \
         the ordinary ones; the corrected anomaly's rms z {:.2}",
        rms(&nw),
        rms(&ols),
        rms(&anomaly)
    );
    assert!(
        rms(&nw) < rms(&ols) / 3.0,
        "{} against {}",
        rms(&nw),
        rms(&ols)
    );
}
