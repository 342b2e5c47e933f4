//! The overlapping Allan deviation of a static accelerometer series (docs/model.md section 6.2),
//! its confidence intervals, and the three noise terms fitted to it: white-noise density,
//! bias instability and random walk. No I/O.
//!
//! The deviation follows NIST SP 1065 (eq. 14), computed from the integrated series (the
//! "phase" `x_k = tau0 * sum_{j<k} y_j`, `x_0 = 0`), as allantools' `oadev` does with
//! frequency data, so the two agree to rounding (`tests/allan.rs` runs them side by side).
//! Confidence intervals come from chi-square with the equivalent degrees of freedom of
//! white frequency noise (NIST SP 1065, Table 5; allantools' `edf_simple` with alpha = 0).

use faer::linalg::solvers::DenseSolveCore;
use faer::prelude::*;
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
    octave_factors_up_to(n / 10)
}

/// The factors a tilt-table's still intervals are analysed at (align's ADC noise): up to a
/// quarter of the longest. The intervals are raw counts, so the longest averaging times
/// keep a random walk's rise (a multi-position session's intervals, less their straight
/// lines, stop at a tenth: the line takes most of a walk's power beyond it); the quarter
/// tells a flicker floor from a walk over twice the taus a tenth reached (docs/model.md
/// 6.2).
pub fn still_interval_factors(n: usize) -> Vec<usize> {
    octave_factors_up_to(n / 4)
}

/// Averaging factors 1, 2, 4, ... up to `largest` (at least one).
fn octave_factors_up_to(largest: usize) -> Vec<usize> {
    let mut out = vec![1];
    while out[out.len() - 1] * 2 <= largest.max(1) {
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
/// long enough for a factor are summed. With one series it is [`overlapping`].
///
/// Its degrees of freedom are those of the pooled variance when the series' white levels
/// differ (a tilt-table's stations read at different ADC noise): each series' variance at
/// the factor is its own white level (from its first factor) over tau plus the pooled
/// coloured part, and the pooled variance, a mean weighted by the series' terms, has
/// `(sum n_i a_i)^2 / sum (n_i^2 a_i^2 / edf_i)` dof. With equal white levels and lengths
/// that is the sum of the series' dof; with unequal ones less, as the noisiest series
/// dominate the scatter of the pooled variance.
pub fn pooled(series: &[&[f64]], tau0_s: f64, ms: &[usize]) -> Vec<AllanPoint> {
    let phases: Vec<Vec<f64>> = series.iter().map(|y| phase(y, tau0_s)).collect();
    // Each series' white level N_i^2 (unit^2 s): its Allan variance at the first factor
    // times tau0, where the coloured terms are nothing beside the white.
    let white: Vec<f64> = phases
        .iter()
        .map(|x| {
            let n = x.len().saturating_sub(2);
            let sum = (0..n)
                .map(|i| (x[i + 2] - 2.0 * x[i + 1] + x[i]).powi(2))
                .sum::<f64>();
            sum / (2.0 * tau0_s * n.max(1) as f64)
        })
        .collect();
    ms.iter()
        .filter(|&&m| m > 0)
        .filter_map(|&m| {
            let tau = m as f64 * tau0_s;
            let (mut sum, mut terms) = (0.0, 0usize);
            // (terms, white level, dof) of each series long enough for m.
            let mut used = Vec::new();
            for (x, &w) in phases
                .iter()
                .zip(&white)
                .filter(|(x, _)| x.len() > 2 * m + 1)
            {
                let n = x.len() - 2 * m;
                sum += (0..n)
                    .map(|i| (x[i + 2 * m] - 2.0 * x[i + m] + x[i]).powi(2))
                    .sum::<f64>();
                terms += n;
                used.push((n as f64, w, edf_white_frequency(x.len(), m)));
            }
            (terms > 0).then(|| {
                let avar = sum / (2.0 * tau * tau * terms as f64);
                let adev = avar.sqrt();
                let edf = pooled_edf(&used, avar, tau);
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

/// The dof of a pooled Allan variance `avar` at `tau` from its series' (terms, white level,
/// dof): see [`pooled`].
fn pooled_edf(used: &[(f64, f64, f64)], avar: f64, tau: f64) -> f64 {
    let total: f64 = used.iter().map(|&(n, _, _)| n).sum();
    let white_mean = used.iter().map(|&(n, w, _)| n * w).sum::<f64>() / total / tau;
    let coloured = (avar - white_mean).max(0.0);
    let (mut num, mut den) = (0.0, 0.0);
    for &(n, w, e) in used {
        let a = w / tau + coloured;
        num += n * a;
        den += n * n * a * a / e;
    }
    if den > 0.0 && num > 0.0 {
        num * num / den
    } else {
        used.iter().map(|&(_, _, e)| e).sum()
    }
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
    /// The Allan variance the fit ([`fit_noise`]) takes the terms to give at `tau_s`: the
    /// flicker of gravcal's model ([`crate::colour::Flicker`]), which bends below the floor
    /// under about 2 s; [`NoiseTerms::allan_variance`] elsewhere.
    pub fn fitted_allan_variance(&self, tau_s: f64) -> f64 {
        self.white_density.powi(2) / tau_s
            + crate::colour::Flicker::new(self.bias_instability).allan_variance(tau_s)
            + self.random_walk.powi(2) * tau_s / 3.0
    }

    /// The Allan variance of the three terms at averaging time `tau_s`, the flicker at its
    /// floor.
    pub fn allan_variance(&self, tau_s: f64) -> f64 {
        self.white_density.powi(2) / tau_s
            + crate::colour::FLICKER_AVAR * self.bias_instability.powi(2)
            + self.random_walk.powi(2) * tau_s / 3.0
    }
}

/// Standard errors a fitted bias instability or random walk must exceed to be kept.
const SIGNIFICANCE: [f64; 3] = [0.0, 2.0, WALK_SIGNIFICANCE];
/// Standard errors a random walk must exceed: more than the flicker, because adjust carries
/// a random walk from the tens of seconds the curve reaches to the hours of a session, where
/// one kept falsely (flicker read as a walk) weighs the stations a hundredfold wrong.
const WALK_SIGNIFICANCE: f64 = 3.0;

/// Overlap of the integer intervals [a, b) and [c, d).
fn overlap(a: i64, b: i64, c: i64, d: i64) -> i64 {
    (b.min(d) - a.max(c)).max(0)
}

/// `sum_u h_m(u) h_n(u + lag)` for the Allan kernels h_m (-1 on [0, m), +1 on [m, 2m)):
/// the covariance, per unit variance of white samples, of two second differences of the
/// phase at factors m and n, `lag` samples apart.
fn kernel_product(m: i64, n: i64, lag: i64) -> i64 {
    let halves = |k: i64| [(0, k, -1), (k, 2 * k, 1)];
    let mut total = 0;
    for (a, b, s) in halves(m) {
        for (c, d, t) in halves(n) {
            total += s * t * overlap(a, b, c - lag, d - lag);
        }
    }
    total
}

/// The covariance matrix of the pooled overlapping Allan variances at `points` when the
/// series are white with unit sample variance, the series being `lengths` samples long
/// (docs/model.md 6.2): Cov(d_i^2, e_k^2) = 2 Cov(d_i, e_k)^2 for Gaussian second
/// differences, summed over every pair of terms of each series. Row-major p x p.
pub fn white_covariance(points: &[AllanPoint], lengths: &[usize]) -> Vec<f64> {
    let p = points.len();
    let mut out = vec![0.0; p * p];
    for a in 0..p {
        for b in a..p {
            let (ma, mb) = (points[a].m as i64, points[b].m as i64);
            let tau0 = points[a].tau_s / points[a].m as f64;
            // Terms of each series at each factor (a series of n samples has n + 1 - 2m).
            let terms = |m: i64, n: usize| (n as i64 + 1 - 2 * m).max(0);
            // Each factor's total over the series long enough for it, as `pooled` sums them.
            let total = |m: i64| -> i64 {
                lengths
                    .iter()
                    .filter(|&&n| n as i64 > 2 * m)
                    .map(|&n| terms(m, n))
                    .sum()
            };
            let (ta, tb) = (total(ma), total(mb));
            if ta == 0 || tb == 0 {
                continue;
            }
            // d_i (factor ma) and e_k (factor mb) at lag = i - k: the kernels' products,
            // the same for every series, then each distinct length once, times its count.
            let kernel: Vec<(i64, f64)> = ((-2 * ma + 1)..(2 * mb))
                .map(|lag| (lag, kernel_product(ma, mb, lag) as f64))
                .filter(|&(_, g)| g != 0.0)
                .collect();
            let mut sum = 0.0;
            for (n, count) in distinct_lengths(lengths) {
                let (na, nb) = (terms(ma, n), terms(mb, n));
                if na == 0 || nb == 0 || n as i64 <= 2 * ma || n as i64 <= 2 * mb {
                    continue;
                }
                let series: f64 = kernel
                    .iter()
                    .map(|&(lag, g)| 2.0 * g * g * overlap(0, na, lag, lag + nb) as f64)
                    .sum();
                sum += series * count as f64;
            }
            let (tau_a, tau_b) = (points[a].tau_s, points[b].tau_s);
            let c =
                sum * tau0.powi(4) / (4.0 * tau_a * tau_a * tau_b * tau_b * ta as f64 * tb as f64);
            out[a * p + b] = c;
            out[b * p + a] = c;
        }
    }
    out
}

/// Each distinct length among `lengths`, with how many series have it.
fn distinct_lengths(lengths: &[usize]) -> Vec<(usize, usize)> {
    let mut sorted = lengths.to_vec();
    sorted.sort_unstable();
    let mut out: Vec<(usize, usize)> = Vec::new();
    for n in sorted {
        match out.last_mut() {
            Some((m, count)) if *m == n => *count += 1,
            _ => out.push((n, 1)),
        }
    }
    out
}

/// Fits [`NoiseTerms`] to an Allan curve pooled over series of `lengths` samples by
/// generalised least squares on the variance: the points' covariance is that of white
/// counts at the fitted white level ([`white_covariance`]), so the test of whether the
/// counts are white knows that neighbouring octaves share their samples. Every term is kept
/// non-negative: a term that comes out negative is dropped and the rest refitted; so is a
/// bias instability or random walk below [`SIGNIFICANCE`] standard errors (the white term
/// always stays). When neither is significant beside the other, the random walk goes first:
/// over the seconds a still interval's Allan curve reaches, flicker and a random walk look
/// alike, and a random walk is what adjust carries over the whole session (its covariance
/// grows with the time between windows), so it is kept only where it shows beside the
/// flicker. [`fit_noise_levels`] also gives the dof of the coloured levels.
pub fn fit_noise(points: &[AllanPoint], lengths: &[usize]) -> NoiseTerms {
    fit_noise_levels(points, lengths).terms
}

/// [`NoiseTerms`] fitted, with the degrees of freedom of the coloured terms' squares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FittedNoise {
    /// The terms.
    pub terms: NoiseTerms,
    /// The dof of B^2, 2 (B^2 / se)^2 with se the generalised fit's (None: not kept).
    pub bias_instability_dof: Option<f64>,
    /// The dof of K^2, alike.
    pub random_walk_dof: Option<f64>,
}

/// [`fit_noise`] with the dof of the coloured terms kept.
pub fn fit_noise_levels(points: &[AllanPoint], lengths: &[usize]) -> FittedNoise {
    let points: Vec<AllanPoint> = points
        .iter()
        .filter(|p| p.adev.is_finite() && p.adev > 0.0)
        .cloned()
        .collect();
    if points.is_empty() {
        return FittedNoise {
            terms: NoiseTerms {
                white_density: 0.0,
                bias_instability: 0.0,
                random_walk: 0.0,
            },
            bias_instability_dof: None,
            random_walk_dof: None,
        };
    }
    let v: Vec<f64> = points.iter().map(|q| q.adev * q.adev).collect();
    let correlation = white_correlation(&points, lengths);
    let mut inverse = correlated_inverse(&points, &correlation, &v);
    let mut reweighted = 0;
    let mut active = [true; 3];
    loop {
        let idx: Vec<usize> = (0..3).filter(|&j| active[j]).collect();
        let (coef, se) = generalised_fit(&points, &v, &inverse, &idx);
        let fitted: Vec<f64> = points
            .iter()
            .map(|q| noise_basis(q).iter().zip(coef).map(|(f, c)| f * c).sum())
            .collect();
        // Iteratively reweighted: the points' sds from the fit, three times a term set.
        if reweighted < 3 && fitted.iter().all(|&x| x > 0.0) {
            reweighted += 1;
            inverse = correlated_inverse(&points, &correlation, &fitted);
            continue;
        }
        if let Some(j) = (0..3).find(|&j| active[j] && (coef[j].is_nan() || coef[j] < 0.0)) {
            active[j] = false;
            reweighted = 0;
            if active.iter().any(|&a| a) {
                continue;
            }
        }
        // A term not significantly positive (below SIGNIFICANCE standard errors) is
        // dropped: a random walk fitted to curves of a few seconds is the flicker's
        // curvature, not a random walk.
        if let Some((_, &j)) = idx
            .iter()
            .enumerate()
            .filter(|&(a, &j)| j > 0 && coef[j] < SIGNIFICANCE[j] * se[a])
            .max_by_key(|&(_, &j)| j)
        {
            active[j] = false;
            reweighted = 0;
            continue;
        }
        let terms = weighted_fit(&points, active);
        let dof = |j: usize, level: f64| {
            let a = idx.iter().position(|&i| i == j)?;
            (level > 0.0 && se[a] > 0.0).then(|| 2.0 * (coef[j] / se[a]).powi(2))
        };
        return FittedNoise {
            terms,
            bias_instability_dof: dof(1, terms.bias_instability),
            random_walk_dof: dof(2, terms.random_walk),
        };
    }
}

/// The three terms' shapes in the Allan variance at a point: N^2 / tau, the flicker of
/// gravcal's model ([`crate::colour::Flicker`], the floor from about 2 s up and bending
/// down below it), K^2 tau / 3.
fn noise_basis(q: &AllanPoint) -> [f64; 3] {
    let flicker = crate::colour::Flicker::new(1.0).allan_variance(q.tau_s);
    [1.0 / q.tau_s, flicker, q.tau_s / 3.0]
}

/// The points' correlation matrix as white counts give it ([`white_covariance`]).
fn white_correlation(points: &[AllanPoint], lengths: &[usize]) -> Vec<f64> {
    let p = points.len();
    let white = white_covariance(points, lengths);
    (0..p * p)
        .map(|i| {
            let (a, b) = (i / p, i % p);
            let d = (white[a * p + a] * white[b * p + b]).sqrt();
            if d > 0.0 {
                white[i] / d
            } else {
                f64::from(u8::from(a == b))
            }
        })
        .collect()
}

/// The inverse of the points' covariance: `correlation` with sds sqrt(2 / edf) times the
/// variance `model` gives each point.
fn correlated_inverse(points: &[AllanPoint], correlation: &[f64], model: &[f64]) -> Vec<f64> {
    let p = points.len();
    let sd: Vec<f64> = points
        .iter()
        .zip(model)
        .map(|(q, m)| m.abs().max(1e-300) * (2.0 / q.edf.max(1e-9)).sqrt())
        .collect();
    let cov: Vec<f64> = (0..p * p)
        .map(|i| correlation[i] * sd[i / p] * sd[i % p])
        .collect();
    inverse_small(&cov, p)
}

/// The generalised least-squares fit of the terms `idx` to the variances `v` with the
/// points' inverse covariance: the three coefficients (0 where not fitted) and the fitted
/// ones' standard errors, in `idx`'s order.
fn generalised_fit(
    points: &[AllanPoint],
    v: &[f64],
    inverse: &[f64],
    idx: &[usize],
) -> ([f64; 3], Vec<f64>) {
    let (p, k) = (points.len(), idx.len());
    let design: Vec<Vec<f64>> = points
        .iter()
        .map(|q| idx.iter().map(|&j| noise_basis(q)[j]).collect())
        .collect();
    let mut ata = vec![0.0; k * k];
    let mut atb = vec![0.0; k];
    for r in 0..p {
        for c in 0..p {
            let w = inverse[r * p + c];
            for a in 0..k {
                atb[a] += design[r][a] * w * v[c];
                for b in 0..k {
                    ata[a * k + b] += design[r][a] * w * design[c][b];
                }
            }
        }
    }
    let c = solve_small(&ata, &atb, k);
    let mut coef = [0.0; 3];
    for (a, &j) in idx.iter().enumerate() {
        coef[j] = c[a];
    }
    let normal_inverse = inverse_small(&ata, k);
    let se = (0..k)
        .map(|a| normal_inverse[a * k + a].max(0.0).sqrt())
        .collect();
    (coef, se)
}

/// The kept terms' values by weighted least squares on the variance (each point weighted by
/// its degrees of freedom over its variance squared), a term that comes out negative
/// dropped: the estimates stay on the points when the three-term model misses a feature of
/// the curve (a tremor's bump), where a fit with the points' strong correlations can lie
/// beside them (Peelle's puzzle). The generalised fit decides which terms are there.
fn weighted_fit(points: &[AllanPoint], mut active: [bool; 3]) -> NoiseTerms {
    let basis = noise_basis;
    loop {
        let idx: Vec<usize> = (0..3).filter(|&j| active[j]).collect();
        let k = idx.len();
        let mut ata = vec![0.0; k * k];
        let mut atb = vec![0.0; k];
        for q in points {
            let var = q.adev * q.adev;
            let w = q.edf / (var * var);
            let f = basis(q);
            for (a, &ja) in idx.iter().enumerate() {
                atb[a] += w * f[ja] * var;
                for (b, &jb) in idx.iter().enumerate() {
                    ata[a * k + b] += w * f[ja] * f[jb];
                }
            }
        }
        let c = solve_small(&ata, &atb, k);
        let mut coef = [0.0; 3];
        for (a, &j) in idx.iter().enumerate() {
            coef[j] = c[a];
        }
        match (1..3).find(|&j| active[j] && (coef[j].is_nan() || coef[j] < 0.0)) {
            Some(j) => active[j] = false,
            None => {
                return NoiseTerms {
                    white_density: coef[0].max(0.0).sqrt(),
                    bias_instability: coef[1].max(0.0).sqrt(),
                    random_walk: coef[2].max(0.0).sqrt(),
                };
            }
        }
    }
}

/// Solves the k x k system `a c = b` (row-major `a`) by faer's LU with partial pivoting; a
/// singular system (a solution not finite) gives zeros.
fn solve_small(a: &[f64], b: &[f64], k: usize) -> Vec<f64> {
    let m = Mat::<f64>::from_fn(k, k, |i, j| a[i * k + j]);
    let rhs = Mat::<f64>::from_fn(k, 1, |i, _| b[i]);
    let x = m.partial_piv_lu().solve(&rhs);
    let x: Vec<f64> = (0..k).map(|i| x[(i, 0)]).collect();
    if x.iter().all(|v| v.is_finite()) {
        x
    } else {
        vec![0.0; k]
    }
}

/// The inverse of the p x p matrix `a` (row-major) by faer's LU with partial pivoting, row
/// major; a singular matrix (an inverse not finite) gives zeros.
fn inverse_small(a: &[f64], p: usize) -> Vec<f64> {
    let inv = Mat::<f64>::from_fn(p, p, |i, j| a[i * p + j])
        .partial_piv_lu()
        .inverse();
    let out: Vec<f64> = (0..p * p).map(|i| inv[(i / p, i % p)]).collect();
    if out.iter().all(|v| v.is_finite()) {
        out
    } else {
        vec![0.0; p * p]
    }
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
    /// The white covariance's diagonal is NIST's variance of the overlapping Allan variance
    /// for white frequency noise (2 / edf), and neighbouring octaves are correlated.
    #[test]
    fn white_covariance_matches_the_edf() {
        let n = 20_000;
        let tau0 = 0.032;
        let pts: Vec<AllanPoint> = [1usize, 4, 16, 64]
            .iter()
            .map(|&m| AllanPoint {
                tau_s: m as f64 * tau0,
                m,
                adev: (1.0 / m as f64).sqrt(),
                edf: edf_white_frequency(n + 1, m),
                interval: (0.0, 0.0),
            })
            .collect();
        let c = white_covariance(&pts, &[n]);
        for (a, q) in pts.iter().enumerate() {
            let relative = c[a * pts.len() + a] * (q.m * q.m) as f64;
            assert!(
                (relative * q.edf / 2.0 - 1.0).abs() < 0.05,
                "m {}: {relative} vs {}",
                q.m,
                2.0 / q.edf
            );
        }
    }

    /// A series too short for a factor counts in the other factor's total (as `pooled`
    /// sums it) and in no pair with it.
    #[test]
    fn short_series_count_where_pooled_counts_them() {
        let pts: Vec<AllanPoint> = [1usize, 16]
            .iter()
            .map(|&m| AllanPoint {
                tau_s: m as f64,
                m,
                adev: 1.0,
                edf: 1.0,
                interval: (0.0, 0.0),
            })
            .collect();
        let long = white_covariance(&pts, &[2000]);
        let both = white_covariance(&pts, &[2000, 20]);
        assert!((both[3] / long[3] - 1.0).abs() < 1e-12);
        let (t_long, t_all) = (2000.0 + 1.0 - 2.0, 2000.0 + 1.0 - 2.0 + 20.0 + 1.0 - 2.0);
        assert!(
            (both[1] / long[1] - t_long / t_all).abs() < 1e-12,
            "{} {}",
            both[1],
            long[1]
        );
    }

    /// The white covariance's correlation of neighbouring octaves against the one white
    /// series show: pooled Allan variances at m = 1 and 2 over four series of 500 samples,
    /// 3000 replicas.
    #[test]
    fn white_covariance_correlates_octaves_as_white_series_do() {
        let (n, series, replicas): (usize, usize, usize) = (500, 4, 3000);
        let ms = [1usize, 2];
        let mut at: Vec<[f64; 2]> = Vec::new();
        for r in 0..replicas {
            let y = normals(
                n * series,
                (r as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15),
            );
            let s: Vec<&[f64]> = y.chunks(n).collect();
            let p = pooled(&s, 1.0, &ms);
            at.push([p[0].adev.powi(2), p[1].adev.powi(2)]);
        }
        let mean = |k: usize| at.iter().map(|x| x[k]).sum::<f64>() / replicas as f64;
        let (m0, m1) = (mean(0), mean(1));
        let cov = |a: usize, b: usize, ma: f64, mb: f64| {
            at.iter().map(|x| (x[a] - ma) * (x[b] - mb)).sum::<f64>() / (replicas as f64 - 1.0)
        };
        let seen = cov(0, 1, m0, m1) / (cov(0, 0, m0, m0) * cov(1, 1, m1, m1)).sqrt();
        let pts = pooled(
            &normals(n * series, 1).chunks(n).collect::<Vec<_>>(),
            1.0,
            &ms,
        );
        let c = white_covariance(&pts, &[n; 4]);
        let predicted = c[1] / (c[0] * c[3]).sqrt();
        eprintln!(
            "correlation of the Allan variances at m = 1 and 2: seen {seen:.3}, predicted {predicted:.3}"
        );
        assert!(
            (seen - predicted).abs() < 0.06,
            "correlation seen {seen}, predicted {predicted}"
        );
        assert!(predicted > 0.3, "{predicted}");
    }

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
        let fit = fit_noise(&pts, &[y.len()]);
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
        let fit = fit_noise(&overlapping(&y, tau0, &octave_factors(y.len())), &[y.len()]);
        assert!((fit.random_walk / k - 1.0).abs() < 0.3, "{fit:?}");
        assert!(
            (fit.white_density / tau0.sqrt() - 1.0).abs() < 0.1,
            "{fit:?}"
        );
    }
}
