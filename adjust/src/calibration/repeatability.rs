//! Whether b and k repeat between sessions (docs/model.md 6.9): for each model fitted per
//! session and each accelerometer with two or more sessions, the homogeneity test of the
//! sessions' (b, k). With x_i each session's estimate and C_i its covariance (the fit's
//! sigmas and correlation), the weighted mean is x = (sum C_i^-1)^-1 sum C_i^-1 x_i and
//! the statistic sum (x_i - x)' C_i^-1 (x_i - x), chi-square on 2 (n - 1) degrees of
//! freedom when b and k are the same in every session and the sigmas are honest. Its false
//! alarm rate is measured in `tests/calibration.rs` (`repeatability_holds_its_level`).

use ingest::contract::calibration::{CalibrationResult, Repeatability};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The test's level: a change is reported where the statistic's upper tail is below it.
pub const LEVEL: f64 = 0.05;

/// One session's (b, k) and their covariance.
#[derive(Clone, Copy, Debug)]
pub struct Estimate {
    /// b, mGal, and k, mGal per reading unit.
    pub values: [f64; 2],
    /// Their covariance.
    pub covariance: [[f64; 2]; 2],
}

impl Estimate {
    /// From sigmas and the correlation of b and k.
    pub fn new(values: [f64; 2], sigmas: [f64; 2], correlation: f64) -> Self {
        let c = correlation * sigmas[0] * sigmas[1];
        Estimate {
            values,
            covariance: [[sigmas[0].powi(2), c], [c, sigmas[1].powi(2)]],
        }
    }

    fn weight(&self) -> Option<[[f64; 2]; 2]> {
        let [[a, b], [_, d]] = self.covariance;
        let det = a * d - b * b;
        (det.is_finite() && det > 0.0).then(|| [[d / det, -b / det], [-b / det, a / det]])
    }
}

/// The homogeneity test's outcome.
#[derive(Clone, Copy, Debug)]
pub struct Homogeneity {
    /// The weighted mean of (b, k).
    pub mean: [f64; 2],
    /// The statistic.
    pub statistic: f64,
    /// Its degrees of freedom, 2 (n - 1).
    pub dof: u32,
    /// The chi-square upper tail at the statistic.
    pub p_value: f64,
}

impl Homogeneity {
    /// Whether b and k repeat at [`LEVEL`].
    pub fn passed(&self) -> bool {
        self.p_value >= LEVEL
    }
}

/// The test over `estimates`; None for fewer than two, or a covariance not positive definite.
pub fn homogeneity(estimates: &[Estimate]) -> Option<Homogeneity> {
    if estimates.len() < 2 {
        return None;
    }
    let weights: Vec<[[f64; 2]; 2]> = estimates
        .iter()
        .map(Estimate::weight)
        .collect::<Option<_>>()?;
    let mut w = [[0.0; 2]; 2];
    let mut wx = [0.0; 2];
    for (e, p) in estimates.iter().zip(&weights) {
        for i in 0..2 {
            for j in 0..2 {
                w[i][j] += p[i][j];
                wx[i] += p[i][j] * e.values[j];
            }
        }
    }
    let mean_weight = Estimate {
        values: [0.0; 2],
        covariance: w,
    }
    .weight()?;
    let mean = [0, 1].map(|i| mean_weight[i][0] * wx[0] + mean_weight[i][1] * wx[1]);
    let statistic = estimates
        .iter()
        .zip(&weights)
        .map(|(e, p)| {
            let d = [e.values[0] - mean[0], e.values[1] - mean[1]];
            d[0] * (p[0][0] * d[0] + p[0][1] * d[1]) + d[1] * (p[1][0] * d[0] + p[1][1] * d[1])
        })
        .sum::<f64>();
    let dof = 2 * u32::try_from(estimates.len() - 1).ok()?;
    let p_value = ChiSquared::new(f64::from(dof)).ok()?.sf(statistic);
    Some(Homogeneity {
        mean,
        statistic,
        dof,
        p_value,
    })
}

/// The test for every model `per_session` names and every accelerometer with two or more of
/// its sessions among `results` (in their order; models with temperature terms left out).
pub fn of_results(
    results: &[CalibrationResult],
    per_session: &dyn Fn(&str) -> bool,
) -> Vec<Repeatability> {
    let mut groups: Vec<(&str, &str, Vec<&CalibrationResult>)> = Vec::new();
    for r in results
        .iter()
        .filter(|r| per_session(&r.model) && !r.temperature)
    {
        match groups
            .iter_mut()
            .find(|(m, a, _)| *m == r.model && *a == r.accelerometer)
        {
            Some((_, _, v)) => v.push(r),
            None => groups.push((&r.model, &r.accelerometer, vec![r])),
        }
    }
    groups
        .into_iter()
        .filter_map(|(model, accelerometer, fits)| {
            let estimates: Vec<Estimate> =
                fits.iter().map(|r| estimate_of(r)).collect::<Option<_>>()?;
            let h = homogeneity(&estimates)?;
            Some(Repeatability {
                model: model.to_owned(),
                accelerometer: accelerometer.to_owned(),
                sessions: fits.iter().map(|r| r.session.clone()).collect(),
                mean_temperatures_c: fits.iter().map(|r| r.mean_temperature_c).collect(),
                b_mgal: estimates.iter().map(|e| e.values[0]).collect(),
                sigma_b_mgal: estimates
                    .iter()
                    .map(|e| e.covariance[0][0].sqrt())
                    .collect(),
                statistic: h.statistic,
                dof: h.dof,
                p_value: h.p_value,
                passed: h.passed(),
            })
        })
        .collect()
}

/// A fit's (b, k) and their covariance; None without both.
fn estimate_of(r: &CalibrationResult) -> Option<Estimate> {
    let index = |name: &str| r.parameters.iter().position(|p| p.name == name);
    let (b, k) = (index("b")?, index("k")?);
    let (pb, pk) = (&r.parameters[b], &r.parameters[k]);
    Some(Estimate::new(
        [pb.value, pk.value],
        [pb.sigma, pk.sigma],
        r.correlation.get(b)?.get(k).copied()?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two sessions: the statistic is the difference's Mahalanobis norm under the summed
    /// covariance (computed apart here), and the mean the weighted mean.
    #[test]
    fn two_sessions_reduce_to_their_difference() {
        let a = Estimate::new([1.0, 2.0], [0.3, 0.1], 0.4);
        let b = Estimate::new([1.6, 1.9], [0.2, 0.2], -0.3);
        let h = homogeneity(&[a, b]).expect("test");
        let s = [0, 1].map(|i| [0, 1].map(|j| a.covariance[i][j] + b.covariance[i][j]));
        let d = [0.6, -0.1];
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        let q = (s[1][1] * d[0] * d[0] - 2.0 * s[0][1] * d[0] * d[1] + s[0][0] * d[1] * d[1]) / det;
        assert!((h.statistic - q).abs() < 1e-12, "{} {q}", h.statistic);
        assert_eq!(h.dof, 2);
        assert!((h.p_value - (-q / 2.0).exp()).abs() < 1e-12);
        assert!(homogeneity(&[a]).is_none());
        let same = homogeneity(&[a, a]).expect("test");
        assert!(same.statistic.abs() < 1e-24 && same.passed());
        assert!((same.mean[0] - 1.0).abs() < 1e-12 && (same.mean[1] - 2.0).abs() < 1e-12);
    }
}
