//! A fit's result as calibration.json holds it: parameters and their sigmas, the notes on
//! what the design barely determines, the misalignment vector, the noise in Kalibr's
//! names, and what was done about the Earth tide.

use super::calibrate;
use super::jobs::{Job, component_of, range_of, roll_directions};
use super::model::{Misalignment, Terms};
use ingest::contract::align_ledger::AlignReport;
use ingest::contract::calibration::{
    CalibrationResult, GlobalTest, KalibrNoise, MisalignmentVector, Parameter, Removed,
};
use ingest::contract::tables;

/// A parameter (beyond b and k) whose multiple correlation with the others is above this is
/// noted as barely estimable.
pub(crate) const NOTE_CORRELATION: f64 = 0.999;

/// Multiple correlation of each parameter with all the others, from the correlation matrix
/// `C`: `sqrt(1 - 1 / (C^-1)_jj)`. 1 where `C` is numerically singular.
pub(crate) fn multiple_correlation(c: &[Vec<f64>]) -> Vec<f64> {
    use faer::linalg::solvers::DenseSolveCore;
    let n = c.len();
    // faer's Cholesky C = L L^T; numerically singular where a pivot L_jj^2 is at most
    // 1e-15 (a correlation matrix's diagonal is 1).
    let m = faer::Mat::<f64>::from_fn(n, n, |i, j| c[i][j]);
    let Ok(llt) = m.llt(faer::Side::Lower) else {
        return vec![1.0; n];
    };
    if (0..n).any(|j| llt.L()[(j, j)].powi(2) <= 1e-15) {
        return vec![1.0; n];
    }
    let inv = llt.inverse();
    (0..n)
        .map(|j| (1.0 - 1.0 / inv[(j, j)]).max(0.0).sqrt())
        .collect()
}

/// A thermal model whose temperatures differ mostly between two sessions: its b_t and k_t
/// cannot tell a temperature effect from a change of b or k between the days (MODEL 6.9).
fn two_day_confounding(job: &Job<'_>) -> Option<String> {
    let mut sessions: Vec<(&str, Vec<f64>)> = Vec::new();
    for o in &job.obs {
        let t = o.temperature_c?;
        match sessions.iter_mut().find(|(s, _)| *s == o.session) {
            Some((_, v)) => v.push(t),
            None => sessions.push((&o.session, vec![t])),
        }
    }
    let [(a, ta), (b, tb)] = &sessions[..] else {
        return None;
    };
    let range = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
                (lo.min(t), hi.max(t))
            });
        hi - lo
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let between = (mean(ta) - mean(tb)).abs();
    let within = range(ta).max(range(tb));
    (within < between / 2.0).then(|| {
        format!(
            "b_t and k_t rest mostly on two sessions' temperatures ({a} and {b}, their means \
             {between:.2} degC apart, the temperature moving at most {within:.2} degC within \
             either): a change of b or k between the days that is not a temperature effect \
             would be read as one. A third session at another temperature, or one whose \
             temperature moves, tells them apart"
        )
    })
}

pub(crate) fn result_of(
    job: &Job<'_>,
    f: &calibrate::CalibrationSolution,
    terms: Terms,
    note: Option<String>,
) -> CalibrationResult {
    let names = terms.names();
    let correlation = f.correlation();
    let mut warnings: Vec<String> = note.into_iter().collect();
    warnings.extend(barely_estimable(&terms, &correlation));
    if terms.temperature {
        warnings.extend(two_day_confounding(job));
    }
    CalibrationResult {
        accelerometer: job.accelerometer.clone(),
        session: job.scope.id().to_owned(),
        model: job.model.name.clone(),
        order: job.model.order,
        temperature: job.model.temperature,
        misalignment: terms.misalignment.any(),
        t_ref_c: job.model.temperature.then_some(f.t_ref_c),
        mean_temperature_c: job
            .obs
            .iter()
            .all(|o| o.temperature_c.is_some())
            .then_some(f.mean_temperature_c),
        counts_range: range_of(f.residuals.iter().map(|r| job.obs[r.index].ng)),
        temperature_range_c: range_of(f.residuals.iter().map(|r| job.obs[r.index].temperature_c)),
        // Set over the whole run, where a fit with temperature terms may know more.
        thermal_sensitivity_limit_mgal_per_k: None,
        n_observations: f.residuals.len(),
        n_excluded: f.removed.len(),
        dof: f.dof,
        iterations: f.iterations,
        sigma0: f.sigma0,
        global_test: GlobalTest {
            statistic: f.global_test.statistic,
            expectation: f.global_test.mean,
            dof: f.global_test.dof,
            lower: f.global_test.lower,
            upper: f.global_test.upper,
            passed: f.global_test_passed(),
        },
        variance_components: f.components.iter().map(component_of).collect(),
        parameters: names
            .iter()
            .enumerate()
            .map(|(j, n)| Parameter {
                name: n.name.to_owned(),
                unit: n.unit.to_owned(),
                value: f.values[j],
                sigma: f.sigma(j),
                sigma_apriori: f.sigma_apriori(j),
                dof: f.parameter_dof[j],
            })
            .collect(),
        correlation,
        removed: f
            .removed
            .iter()
            .map(|r| {
                let o = job.obs[r.index];
                Removed {
                    session: o.session.clone(),
                    station: o.station.clone(),
                    line: o.line,
                    time_gps_ns: o.time_gps_ns,
                    w: r.w,
                }
            })
            .collect(),
        warnings,
        misalignment_vector: (terms.misalignment == Misalignment::Vector)
            .then(|| misalignment_vector(f, terms)),
    }
}

/// Each accelerometer's Allan noise terms (counts) in SI units, by the |k| of its first fit.
pub(crate) fn kalibr_noise(
    align_report: &AlignReport,
    results: &[CalibrationResult],
) -> Vec<KalibrNoise> {
    const M_S2_PER_MGAL: f64 = 1e-5;
    align_report
        .noise
        .iter()
        .filter_map(|n| {
            let r = results
                .iter()
                .find(|r| r.accelerometer == n.accelerometer)?;
            let k = r.parameters.iter().find(|p| p.name == "k")?.value.abs();
            let si = k * M_S2_PER_MGAL;
            Some(KalibrNoise {
                accelerometer: n.accelerometer.clone(),
                scale_from: format!("{} {}", r.model, r.session),
                accelerometer_noise_density: n.white_density_counts_per_sqrt_hz * si,
                accelerometer_random_walk: (n.random_walk_counts_sqrt_hz > 0.0)
                    .then_some(n.random_walk_counts_sqrt_hz * si),
                bias_instability: (n.bias_instability_counts > 0.0)
                    .then_some(n.bias_instability_counts * si),
            })
        })
        .collect()
}

/// What calibration.json says of the body tide: applied, with its range over the
/// observations used, or not, with its size (docs/formats.md 8.1).
pub(crate) fn earth_tide_note(used: &[&tables::observations::Observation]) -> String {
    let tides: Vec<f64> = used.iter().filter_map(|o| o.tide_mgal).collect();
    if tides.is_empty() {
        return "no body tide applied: the site has no latitude_deg and longitude_deg (or earth_tide = false); \
                the tide changes g by up to about 0.25 mGal peak to peak"
            .to_owned();
    }
    let (lo, hi) = tides
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| {
            (a.min(t), b.max(t))
        });
    format!(
        "body tide applied to g per observation (Longman 1959, gravimetric factor {:.4}): \
         {lo:.4} to {hi:.4} mGal over the observations used",
        align::tide::GRAVIMETRIC_FACTOR
    )
}

/// Notes on the parameters beyond b and k whose multiple correlation with all the others
/// exceeds [`NOTE_CORRELATION`], with their correlation to each (b and k are always strongly
/// correlated, the counts being far from zero: the report says so).
pub fn barely_estimable(terms: &Terms, correlation: &[Vec<f64>]) -> Vec<String> {
    let names = terms.names();
    let multiple = multiple_correlation(correlation);
    (2..names.len())
        .filter(|&i| multiple[i] > NOTE_CORRELATION)
        .map(|i| {
            let pairs: Vec<String> = (0..names.len())
                .filter(|&j| j != i)
                .map(|j| format!("{} {:.6}", names[j].name, correlation[i][j]))
                .collect();
            format!(
                "{} is barely estimable: multiple correlation {:.6} with the other parameters; correlation with {}",
                names[i].name,
                multiple[i],
                pairs.join(", ")
            )
        })
        .collect()
}

/// When `terms` ask for the misalignment vector but the `rolls` (rad, per observation) lie
/// in one direction (mod 180 deg), the note naming the component they cannot see and the
/// roll that would: the fit then takes the plane (beta at that roll).
pub fn vector_note(terms: &Terms, rolls: &[f64]) -> Option<String> {
    let directions = roll_directions(rolls);
    if terms.misalignment != Misalignment::Vector || directions.len() >= 2 {
        return None;
    }
    let at = directions.first().copied().unwrap_or(0.0);
    // The unseen component lies along the block's direction at + 90 deg.
    let unseen = match at {
        a if a.abs() < 1e-9 => "theta_y".to_owned(),
        a if (a - 90.0).abs() < 1e-9 => "theta_x".to_owned(),
        a => format!("the component at psi = {:.1} deg", a + 90.0),
    };
    Some(format!(
        "the misalignment's component along the tilt axis at roll {at:.1} deg ({unseen}) is not estimable: \
         every session is at roll {at:.1} deg (mod 180); a session at roll {:.1} deg would determine it. \
         beta is the component in the tilt plane at roll {at:.1} deg",
        at + 90.0
    ))
}

/// theta and psi from theta_x, theta_y and their covariance: propagated; psi only when theta
/// is more than 3 sigma from 0 (closer, its distribution spreads toward uniform and a
/// linearised sd would be a fiction).
pub fn misalignment_vector(f: &calibrate::CalibrationSolution, terms: Terms) -> MisalignmentVector {
    let m = terms.len();
    let (ix, iy) = (m - 2, m - 1);
    let (tx, ty) = (f.values[ix], f.values[iy]);
    let c = |i: usize, j: usize| f.covariance[i * m + j];
    let theta = tx.hypot(ty);
    // Larger principal variance of (theta_x, theta_y).
    let (a, b, d) = (c(ix, ix), c(ix, iy), c(iy, iy));
    let lambda_max = 0.5 * (a + d) + (0.25 * (a - d).powi(2) + b * b).sqrt();
    let sigma_theta = if theta > 0.0 {
        let (jx, jy) = (tx / theta, ty / theta);
        (jx * jx * a + 2.0 * jx * jy * b + jy * jy * d)
            .max(0.0)
            .sqrt()
    } else {
        lambda_max.sqrt()
    };
    let determined = theta > PSI_SIGMAS * lambda_max.sqrt();
    let sigma_psi = {
        let (jx, jy) = (-ty / (theta * theta), tx / (theta * theta));
        (jx * jx * a + 2.0 * jx * jy * b + jy * jy * d)
            .max(0.0)
            .sqrt()
            .to_degrees()
    };
    MisalignmentVector {
        theta_rad: theta,
        sigma_theta_rad: if determined {
            sigma_theta
        } else {
            lambda_max.sqrt()
        },
        psi_deg: determined.then(|| ty.atan2(tx).to_degrees()),
        sigma_psi_deg: determined.then_some(sigma_psi),
        psi_not_determined: (!determined).then(|| {
            format!(
                "theta = {theta:.3e} rad is within {PSI_SIGMAS} sigma ({:.3e} rad) of 0: its direction is not determined",
                lambda_max.sqrt()
            )
        }),
    }
}

/// theta must exceed this many sds for its direction psi to be given.
pub(crate) const PSI_SIGMAS: f64 = 3.0;

/// A fit without temperature terms, and no sensitivity measured, names the sensitivity at
/// which its temperature's movement is this many sigma of b (docs/model.md 6.1).
pub(crate) const THERMAL_NOTE_SIGMAS: f64 = 0.3;

/// An accelerometer's thermal sensitivity from a fit with temperature terms.
struct Measured {
    accelerometer: String,
    model: String,
    sensitivity: calibrate::Sensitivity,
}

/// Each fit without temperature terms whose observations' temperature moved, `fits[i]` the
/// solution of `results[i]`. When a fit of the same accelerometer with temperature terms
/// gives its sensitivity dc/dT = b_t + k_t Ng, the fit's covariance takes that sensitivity
/// as a consider parameter ([`calibrate::CalibrationSolution::thermal_covariance`]) and a
/// note says by how much its sigmas grew: on esgt-2005's day 1, 300 replicas, rms z of b
/// and k 1.13-1.47 without it and 0.95-1.01 with it (docs/model.md 6.1). When no fit gives
/// it, the fit gets the sensitivity at which that movement is an effect of
/// [`THERMAL_NOTE_SIGMAS`] sigma of b (its limit) and a note that the limit is what the run
/// cannot check.
pub(crate) fn thermal_effects(
    results: &mut [CalibrationResult],
    fits: &[&calibrate::CalibrationSolution],
) {
    let measured: Vec<Measured> = results
        .iter()
        .filter(|r| r.temperature)
        .filter_map(|r| {
            let value = |name: &str| r.parameters.iter().find(|p| p.name == name);
            Some(Measured {
                accelerometer: r.accelerometer.clone(),
                model: r.model.clone(),
                sensitivity: calibrate::Sensitivity {
                    b_t: value("b_t")?.value,
                    k_t: value("k_t")?.value,
                },
            })
        })
        .collect();
    for (r, f) in results.iter_mut().zip(fits).filter(|(r, _)| !r.temperature) {
        let Some([t_lo, t_hi]) = r.temperature_range_c.filter(|[lo, hi]| hi > lo) else {
            continue;
        };
        match measured.iter().find(|m| m.accelerometer == r.accelerometer) {
            Some(m) => carry_sensitivity(r, f, m, 1e3 * (t_hi - t_lo)),
            None => name_the_limit(r, t_hi - t_lo),
        }
    }
}

/// A fit without temperature terms whose temperature moved by `moved_k`, and no fit of the
/// run that measured its accelerometer's sensitivity: the limit and the note that the run
/// cannot check it.
fn name_the_limit(r: &mut CalibrationResult, moved_k: f64) {
    let Some(sigma_b) = r.parameters.iter().find(|p| p.name == "b").map(|p| p.sigma) else {
        return;
    };
    let limit = THERMAL_NOTE_SIGMAS * sigma_b / moved_k;
    r.thermal_sensitivity_limit_mgal_per_k = Some(limit);
    r.warnings.push(format!(
        "the temperature moved by {:.1} mK over the observations (their range, a \
         thermometer's noise included) and this model has no temperature terms: a \
         thermal sensitivity |dc/dT| = |b_t + k_t Ng| above {limit:.1} mGal/K would \
         make that {THERMAL_NOTE_SIGMAS} sigma of b or more, which its sigmas do not \
         carry. With no fit of {} with temperature terms, this run cannot say whether \
         the sensitivity is above it: a model with `temperature = true` over sessions \
         at different temperatures can",
        1e3 * moved_k,
        r.accelerometer
    ));
}

/// A fit without temperature terms (solution `f`) whose temperature moved by `moved_mk`:
/// its covariance widened by the sensitivity `m` measured, and a note of each sigma before
/// and after.
fn carry_sensitivity(
    r: &mut CalibrationResult,
    f: &calibrate::CalibrationSolution,
    m: &Measured,
    moved_mk: f64,
) {
    let s = m.sensitivity;
    let [n_lo, n_hi] = r.counts_range.unwrap_or([0.0; 2]);
    let (lo, hi) = (s.b_t + s.k_t * n_lo, s.b_t + s.k_t * n_hi);
    let before: Vec<f64> = r.parameters.iter().map(|p| p.sigma).collect();
    widen(
        &mut r.parameters,
        &mut r.correlation,
        &f.thermal_covariance(s),
    );
    let grew: Vec<String> = r
        .parameters
        .iter()
        .zip(&before)
        .map(|(p, was)| {
            let (was, now) = (three(*was), three(p.sigma));
            format!("{}'s sigma {was} to {now} {}", p.name, p.unit)
        })
        .collect();
    r.warnings.push(format!(
        "the temperature moved by {moved_mk:.1} mK over the observations (their range, a \
         thermometer's noise included); model {} gives this accelerometer dc/dT = b_t + \
         k_t Ng of {} to {} mGal/K over these counts, an effect this model, without \
         temperature terms, does not include: its sigmas carry that sensitivity as a \
         consider parameter ({}). b and k are at the observations' mean temperature, \
         {:.3} degC; {} gives them at any temperature, and a session at a steadier \
         temperature narrows them",
        m.model,
        three(lo.min(hi)),
        three(lo.max(hi)),
        grew.join(", "),
        f.mean_temperature_c,
        m.model
    ));
}

/// `x` to three significant digits, in scientific notation when below 0.01 (no "-0").
fn three(x: f64) -> String {
    if x.abs() >= 0.01 || x == 0.0 {
        let decimals = 2 - x.abs().log10().floor().clamp(-2.0, 2.0) as i32;
        ingest::contract::precision::without_negative_zero(format!(
            "{x:.*}",
            decimals.max(0) as usize
        ))
    } else {
        format!("{x:.2e}")
    }
}

/// Adds `extra` (row-major, the parameters' order) to a fit's covariance as its sigmas and
/// correlations give it (the covariance apply rebuilds), and sets each sigma's
/// Welch-Satterthwaite dof with `extra` as known.
fn widen(parameters: &mut [Parameter], correlation: &mut [Vec<f64>], extra: &[f64]) {
    let m = parameters.len();
    if extra.len() != m * m || correlation.len() != m {
        return;
    }
    let sigma: Vec<f64> = parameters.iter().map(|p| p.sigma).collect();
    let cov: Vec<Vec<f64>> = (0..m)
        .map(|i| {
            (0..m)
                .map(|j| sigma[i] * sigma[j] * correlation[i][j] + extra[i * m + j])
                .collect()
        })
        .collect();
    let wide: Vec<f64> = (0..m).map(|j| cov[j][j].max(0.0).sqrt()).collect();
    for (i, row) in correlation.iter_mut().enumerate() {
        for (j, c) in row.iter_mut().enumerate() {
            let d = wide[i] * wide[j];
            if d > 0.0 {
                *c = cov[i][j] / d;
            }
        }
    }
    for (j, p) in parameters.iter_mut().enumerate() {
        if sigma[j] > 0.0 {
            p.dof = p.dof.map(|nu| nu * (wide[j] / sigma[j]).powi(4));
        }
        p.sigma = wide[j];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The widened covariance is the old one (sigmas times correlations) plus the extra, its
    /// dofs Welch-Satterthwaite's with the extra known.
    #[test]
    fn widening_adds_the_covariance_and_keeps_the_dof_honest() {
        let parameter = |name: &str, sigma: f64, dof: Option<f64>| Parameter {
            name: name.to_owned(),
            unit: "mGal".to_owned(),
            value: 1.0,
            sigma,
            sigma_apriori: sigma,
            dof,
        };
        let mut parameters = vec![parameter("b", 2.0, Some(10.0)), parameter("k", 3.0, None)];
        let mut correlation = vec![vec![1.0, 0.5], vec![0.5, 1.0]];
        widen(&mut parameters, &mut correlation, &[1.0, 0.5, 0.5, 4.0]);
        assert!((parameters[0].sigma - 5f64.sqrt()).abs() < 1e-12);
        assert!((parameters[1].sigma - 13f64.sqrt()).abs() < 1e-12);
        assert!((correlation[0][1] - 3.5 / 65f64.sqrt()).abs() < 1e-12);
        assert!((correlation[0][1] - correlation[1][0]).abs() < 1e-15);
        assert!((correlation[1][1] - 1.0).abs() < 1e-12);
        // (5)^2 / (4^2 / 10): the extra is known.
        assert!((parameters[0].dof.expect("dof") - 15.625).abs() < 1e-9);
        assert_eq!(parameters[1].dof, None);
    }
}
