//! A fit's result as calibration.json holds it: parameters and their sigmas, the notes on
//! what the design barely determines, the misalignment vector, the noise in Kalibr's
//! names, and what was done about the Earth tide.

use super::*;

/// A parameter (beyond b and k) whose multiple correlation with the others is above this is
/// noted as barely estimable.
pub(crate) const NOTE_CORRELATION: f64 = 0.999;

/// Multiple correlation of each parameter with all the others, from the correlation matrix
/// `C`: `sqrt(1 - 1 / (C^-1)_jj)`. 1 where `C` is numerically singular.
pub(crate) fn multiple_correlation(c: &[Vec<f64>]) -> Vec<f64> {
    let n = c.len();
    // Cholesky C = L L^T; (C^-1)_jj = sum_k (L^-1)_kj^2.
    let mut l = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = c[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s <= 1e-15 {
                    return vec![1.0; n];
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut inv = vec![vec![0.0; n]; n];
    for col in 0..n {
        for i in col..n {
            let s: f64 = (col..i).map(|k| l[i][k] * inv[k][col]).sum();
            inv[i][col] = (if i == col { 1.0 } else { 0.0 } - s) / l[i][i];
        }
    }
    (0..n)
        .map(|j| {
            let d: f64 = (0..n).map(|k| inv[k][j] * inv[k][j]).sum();
            (1.0 - 1.0 / d).max(0.0).sqrt()
        })
        .collect()
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
    CalibrationResult {
        accelerometer: job.accelerometer.clone(),
        session: job.scope.id().to_owned(),
        model: job.model.name.clone(),
        order: job.model.order,
        temperature: job.model.temperature,
        misalignment: terms.misalignment.any(),
        t_ref_c: job.model.temperature.then_some(f.t_ref_c),
        mean_temperature_c: f.mean_temperature_c,
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
pub(crate) fn earth_tide_note(used: &[&io::ObservationRow]) -> String {
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

/// A temperature effect this large against sigma_b is named (docs/model.md 6.1).
pub(crate) const THERMAL_NOTE_SIGMAS: f64 = 0.3;

/// Each fit without temperature terms whose observations' temperature moved: the thermal
/// sensitivity at which that movement is an effect of [`THERMAL_NOTE_SIGMAS`] sigma of b
/// (its limit). When a fit of the same accelerometer with temperature terms gives its
/// sensitivity dc/dT = b_t + k_t Ng and the largest over the fit's counts is above the
/// limit, a warning of what the model takes for noise it does not weigh (on esgt-2005's
/// day 1, a few mK made the rms z of b 1.28-1.42 where 1.10 without it); when no fit gives
/// it, a note that the limit is what the run cannot check.
pub(crate) fn thermal_warnings(results: &mut [CalibrationResult]) {
    /// An accelerometer's thermal sensitivity from a fit with temperature terms.
    struct Sensitivity {
        accelerometer: String,
        model: String,
        b_t: f64,
        k_t: f64,
    }
    let sensitivities: Vec<Sensitivity> = results
        .iter()
        .filter(|r| r.temperature)
        .filter_map(|r| {
            let value = |name: &str| r.parameters.iter().find(|p| p.name == name);
            Some(Sensitivity {
                accelerometer: r.accelerometer.clone(),
                model: r.model.clone(),
                b_t: value("b_t")?.value,
                k_t: value("k_t")?.value,
            })
        })
        .collect();
    for r in results.iter_mut().filter(|r| !r.temperature) {
        let (Some([t_lo, t_hi]), Some([n_lo, n_hi])) = (r.temperature_range_c, r.counts_range)
        else {
            continue;
        };
        let Some(sigma_b) = r.parameters.iter().find(|p| p.name == "b").map(|p| p.sigma) else {
            continue;
        };
        if t_hi <= t_lo {
            continue;
        }
        let limit = THERMAL_NOTE_SIGMAS * sigma_b / (t_hi - t_lo);
        r.thermal_sensitivity_limit_mgal_per_k = Some(limit);
        let Some(Sensitivity {
            model, b_t, k_t, ..
        }) = sensitivities
            .iter()
            .find(|s| s.accelerometer == r.accelerometer)
        else {
            r.warnings.push(format!(
                "the temperature moved by {:.1} mK over the observations (their range, a \
                 thermometer's noise included) and this model has no temperature terms: a \
                 thermal sensitivity |dc/dT| = |b_t + k_t Ng| above {limit:.1} mGal/K would \
                 make that {THERMAL_NOTE_SIGMAS} sigma of b or more, which its sigmas do not \
                 carry. With no fit of {} with temperature terms, this run cannot say whether \
                 the sensitivity is above it: a model with `temperature = true` over sessions \
                 at different temperatures can",
                1e3 * (t_hi - t_lo),
                r.accelerometer
            ));
            continue;
        };
        let (lo, hi) = (b_t + k_t * n_lo, b_t + k_t * n_hi);
        let effect = lo.abs().max(hi.abs()) * (t_hi - t_lo);
        if effect > THERMAL_NOTE_SIGMAS * sigma_b {
            r.warnings.push(format!(
                "the temperature moved by {:.1} mK over the observations (their range, a \
                 thermometer's noise included); model {model} \
                 gives this accelerometer dc/dT = b_t + k_t Ng of {:.0} to {:.0} mGal/K over \
                 these counts, so up to {effect:.2} mGal ({:.1} sigma of b) that this model, \
                 without temperature terms, takes as noise its sigmas do not carry: prefer \
                 {model}, or a session at a steadier temperature",
                1e3 * (t_hi - t_lo),
                lo.min(hi),
                lo.max(hi),
                effect / sigma_b
            ));
        }
    }
}
