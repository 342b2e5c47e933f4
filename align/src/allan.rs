//! The overlapping Allan deviation of a static accelerometer series (docs/model.md section 6.2),
//! its confidence intervals, and the three noise terms fitted to it: white-noise density,
//! bias instability and random walk. No I/O.
//!
//! The deviation follows NIST SP 1065 (eq. 14), computed from the integrated series (the
//! "phase" `x_k = tau0 * sum_{j<k} y_j`, `x_0 = 0`), as allantools' `oadev` does with
//! frequency data, so the two agree to rounding (`tests/allan.rs` runs them side by side).
//! Confidence intervals come from chi-square with the equivalent degrees of freedom of
//! white frequency noise (NIST SP 1065, Table 5; allantools' `edf_simple` with alpha = 0).

use statrs::distribution::{ChiSquared, ContinuousCDF};

/// One point of an Allan deviation curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AllanPoint {
    /// Averaging time, s.
    pub tau_s: f64,
    /// Averaging factor: tau = m tau0.
    pub m: usize,
    /// Overlapping Allan deviation, in the series' unit.
    pub adev: f64,
    /// Equivalent degrees of freedom (white frequency noise).
    pub edf: f64,
    /// Lower and upper ends of the 68.3 % confidence interval.
    pub interval: (f64, f64),
}

/// Averaging factors 1, 2, 4, ... up to a tenth of the series' length (at least one).
pub fn octave_factors(n: usize) -> Vec<usize> {
    let mut out = vec![1];
    while out[out.len() - 1] * 2 <= (n / 10).max(1) {
        out.push(out[out.len() - 1] * 2);
    }
    out
}

/// Overlapping Allan deviation of `y` sampled every `tau0_s`, at the averaging factors `ms`
/// (factors with fewer than two differences are left out).
pub fn overlapping(y: &[f64], tau0_s: f64, ms: &[usize]) -> Vec<AllanPoint> {
    pooled(&[y], tau0_s, ms)
}

/// The integrated series ("phase") of `y`, relative to its mean to keep its precision.
fn phase(y: &[f64], tau0_s: f64) -> Vec<f64> {
    let mean = y.iter().sum::<f64>() / y.len().max(1) as f64;
    let mut x = Vec::with_capacity(y.len() + 1);
    x.push(0.0);
    let mut acc = 0.0;
    for v in y {
        acc += (v - mean) * tau0_s;
        x.push(acc);
    }
    x
}

/// The overlapping Allan deviation pooled over several series of one sensor at one rate
/// (e.g. the still intervals of a calibration): the second differences of every series
/// long enough for a factor are summed, and so are their degrees of freedom. With one
/// series it is [`overlapping`].
pub fn pooled(series: &[&[f64]], tau0_s: f64, ms: &[usize]) -> Vec<AllanPoint> {
    let phases: Vec<Vec<f64>> = series.iter().map(|y| phase(y, tau0_s)).collect();
    ms.iter()
        .filter(|&&m| m > 0)
        .filter_map(|&m| {
            let tau = m as f64 * tau0_s;
            let (mut sum, mut terms, mut edf) = (0.0, 0usize, 0.0);
            for x in phases.iter().filter(|x| x.len() > 2 * m + 1) {
                let n = x.len() - 2 * m;
                sum += (0..n)
                    .map(|i| (x[i + 2 * m] - 2.0 * x[i + m] + x[i]).powi(2))
                    .sum::<f64>();
                terms += n;
                edf += edf_white_frequency(x.len(), m);
            }
            (terms > 0).then(|| {
                let adev = (sum / (2.0 * tau * tau * terms as f64)).sqrt();
                AllanPoint {
                    tau_s: tau,
                    m,
                    adev,
                    edf,
                    interval: interval(adev, edf),
                }
            })
        })
        .collect()
}

/// Equivalent degrees of freedom of the overlapping Allan variance for white frequency
/// noise, `n` phase samples, factor `m` (NIST SP 1065, Table 5).
fn edf_white_frequency(n: usize, m: usize) -> f64 {
    let (n, m) = (n as f64, m as f64);
    ((3.0 * (n - 1.0) / (2.0 * m)) - (2.0 * (n - 2.0) / n)) * (4.0 * m * m / (4.0 * m * m + 5.0))
}

/// The 68.3 % interval of a deviation with `edf` degrees of freedom.
fn interval(adev: f64, edf: f64) -> (f64, f64) {
    let Ok(chi) = ChiSquared::new(edf.max(1e-3)) else {
        return (f64::NAN, f64::NAN);
    };
    let p = (1.0 - 0.683) / 2.0;
    let var = adev * adev * edf;
    (
        (var / chi.inverse_cdf(1.0 - p)).sqrt(),
        (var / chi.inverse_cdf(p)).sqrt(),
    )
}

/// The three noise terms of an Allan curve, in the series' unit: `sigma^2(tau) = N^2 / tau
/// + (2 ln 2 / pi) B^2 + K^2 tau / 3`. `N` is the white-noise density (unit / sqrt(Hz);
/// Kalibr's `accelerometer_noise_density`), `B` the bias instability (unit; the flicker
/// floor), `K` the random walk (unit * sqrt(Hz); Kalibr's `accelerometer_random_walk`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseTerms {
    /// White-noise density N.
    pub white_density: f64,
    /// Bias instability B.
    pub bias_instability: f64,
    /// Random walk K.
    pub random_walk: f64,
}

impl NoiseTerms {
    /// The Allan variance of the three terms at averaging time `tau_s`.
    pub fn allan_variance(&self, tau_s: f64) -> f64 {
        self.white_density.powi(2) / tau_s
            + crate::colour::FLICKER_AVAR * self.bias_instability.powi(2)
            + self.random_walk.powi(2) * tau_s / 3.0
    }
}

/// Standard errors a fitted bias instability or random walk must exceed to be kept.
const SIGNIFICANCE: f64 = 2.0;

/// Fits [`NoiseTerms`] to an Allan curve by weighted least squares on the variance (each
/// point weighted by its degrees of freedom over its variance squared), keeping every term
/// non-negative: a term that comes out negative is dropped and the rest refitted; so is a
/// bias instability or random walk below [`SIGNIFICANCE`] standard errors (the white term
/// always stays).
pub fn fit_noise(points: &[AllanPoint]) -> NoiseTerms {
    let basis = |p: &AllanPoint| [1.0 / p.tau_s, crate::colour::FLICKER_AVAR, p.tau_s / 3.0];
    let mut active = [true; 3];
    loop {
        let idx: Vec<usize> = (0..3).filter(|&j| active[j]).collect();
        let k = idx.len();
        let mut ata = vec![0.0; k * k];
        let mut atb = vec![0.0; k];
        for p in points {
            let var = p.adev * p.adev;
            if var.is_nan() || var <= 0.0 {
                continue;
            }
            let w = p.edf / (var * var);
            let f = basis(p);
            for (a, &ja) in idx.iter().enumerate() {
                atb[a] += w * f[ja] * var;
                for (b, &jb) in idx.iter().enumerate() {
                    ata[a * k + b] += w * f[ja] * f[jb];
                }
            }
        }
        let normal = ata.clone();
        let c = solve_small(&mut ata, &mut atb, k);
        let mut coef = [0.0; 3];
        for (a, &j) in idx.iter().enumerate() {
            coef[j] = c[a];
        }
        if let Some(j) = (0..3).find(|&j| active[j] && (coef[j].is_nan() || coef[j] < 0.0)) {
            active[j] = false;
            if active.iter().any(|&a| a) {
                continue;
            }
        }
        // A term not significantly positive (below SIGNIFICANCE standard errors: the variance
        // of an Allan variance is 2 sigma^4 / edf) is dropped: a random walk fitted to curves
        // of a few seconds is the flicker's curvature, not a random walk.
        let se: Vec<f64> = (0..k)
            .map(|a| {
                let mut e = vec![0.0; k];
                e[a] = 1.0;
                let mut n = normal.clone();
                (2.0 * solve_small(&mut n, &mut e, k)[a]).max(0.0).sqrt()
            })
            .collect();
        if let Some((_, &j)) = idx
            .iter()
            .enumerate()
            .filter(|&(a, &j)| j > 0 && coef[j] < SIGNIFICANCE * se[a])
            .min_by(|x, y| (coef[*x.1] / se[x.0]).total_cmp(&(coef[*y.1] / se[y.0])))
        {
            active[j] = false;
            continue;
        }
        return NoiseTerms {
            white_density: coef[0].max(0.0).sqrt(),
            bias_instability: coef[1].max(0.0).sqrt(),
            random_walk: coef[2].max(0.0).sqrt(),
        };
    }
}

/// Solves the k x k system `a c = b` by Gaussian elimination with partial pivoting (k <= 3);
/// a singular system gives zeros.
fn solve_small(a: &mut [f64], b: &mut [f64], k: usize) -> Vec<f64> {
    for col in 0..k {
        let Some(piv) =
            (col..k).max_by(|&i, &j| a[i * k + col].abs().total_cmp(&a[j * k + col].abs()))
        else {
            return vec![0.0; k];
        };
        if a[piv * k + col].abs() < 1e-300 {
            return vec![0.0; k];
        }
        for c in 0..k {
            a.swap(col * k + c, piv * k + c);
        }
        b.swap(col, piv);
        for r in col + 1..k {
            let f = a[r * k + col] / a[col * k + col];
            for c in col..k {
                a[r * k + c] -= f * a[col * k + c];
            }
            b[r] -= f * b[col];
        }
    }
    let mut x = vec![0.0; k];
    for r in (0..k).rev() {
        let s: f64 = (r + 1..k).map(|c| a[r * k + c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r * k + r];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reproducible normal stream (xorshift and Box-Muller), for the tests only.
    fn normals(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        let mut uniform = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let (u, v) = (uniform(), uniform());
                (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
            })
            .collect()
    }

    /// White noise of sd s at rate 1/tau0: adev(tau) = s sqrt(tau0 / tau), N = s sqrt(tau0);
    /// the fit finds it within a few percent and no random walk to speak of.
    #[test]
    fn white_noise_has_the_textbook_curve() {
        let tau0: f64 = 0.032;
        let y: Vec<f64> = normals(400_000, 7).iter().map(|v| 2.0 * v).collect();
        let pts = overlapping(&y, tau0, &octave_factors(y.len()));
        for p in &pts {
            let expected = 2.0 * (tau0 / p.tau_s).sqrt();
            // Within three of its own relative sds, 1 / sqrt(2 edf).
            let tolerance = 3.0 / (2.0 * p.edf).sqrt();
            assert!(
                (p.adev / expected - 1.0).abs() < tolerance,
                "{p:?} vs {expected}"
            );
            assert!(p.interval.0 < p.adev && p.adev < p.interval.1);
        }
        let fit = fit_noise(&pts);
        let n = 2.0 * tau0.sqrt();
        assert!((fit.white_density / n - 1.0).abs() < 0.05, "{fit:?} vs {n}");
        assert!(fit.random_walk < 0.05 * n, "{fit:?}");
    }

    /// A random walk added to white noise shows as K, and the curve turns up at long tau.
    #[test]
    fn a_random_walk_is_found() {
        let tau0: f64 = 0.032;
        let k = 0.5;
        let white = normals(400_000, 11);
        let steps = normals(400_000, 13);
        let mut walk = 0.0;
        let y: Vec<f64> = white
            .iter()
            .zip(&steps)
            .map(|(w, s)| {
                walk += k * tau0.sqrt() * s;
                w + walk
            })
            .collect();
        let fit = fit_noise(&overlapping(&y, tau0, &octave_factors(y.len())));
        assert!((fit.random_walk / k - 1.0).abs() < 0.3, "{fit:?}");
        assert!(
            (fit.white_density / tau0.sqrt() - 1.0).abs() < 0.1,
            "{fit:?}"
        );
    }
}
