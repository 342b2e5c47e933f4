//! The thermometer's own noise (docs/model.md 6.5): estimated per session and channel from
//! the temperature log, and carried into the temperature a static position is given, so
//! that a model with temperature terms takes its temperatures as observations with a sd
//! rather than as exact.
//!
//! The estimate is that of white noise from the log's second differences,
//! `d_k = T_{k-1} - 2 T_k + T_{k+1}`, whose variance is `6 sigma^2` for white noise and which
//! a temperature changing smoothly (a plateau, a ramp) leaves near zero. The sd of the
//! differences is their root mean square over those within 5 robust sds (1.4826 times their
//! median absolute value) of zero, so the few knees where a ramp begins or ends do not count
//! as noise, and a log written in steps (a median of whole steps) is still measured finely.
//! A log resolved coarser than its noise gives the quantisation's share (rounding to steps
//! of q adds q^2/12 to each value); one whose differences are mostly 0 gives 0.

/// Fewest second differences for an estimate.
pub const MIN_DIFFERENCES: usize = 20;

/// The white noise sd of a temperature series sampled at a steady interval, degC; none when
/// it has fewer than [`MIN_DIFFERENCES`] + 2 values.
pub fn white_noise_sd(values: &[f64]) -> Option<f64> {
    if values.len() < MIN_DIFFERENCES + 2 {
        return None;
    }
    let mut d: Vec<f64> = values
        .windows(3)
        .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
        .collect();
    let mid = d.len() / 2;
    let (_, median, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    let bound = 5.0 * 1.4826 * *median;
    let (sum, n) = d
        .iter()
        .filter(|x| **x <= bound)
        .fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    Some((sum / n as f64 / 6.0).sqrt())
}

/// The mean over `times` (sorted) of the series `(t, v)` interpolated linearly, as align's
/// windows interpolate it, and the sum of the squared weights that mean gives each sample
/// (its variance is that sum times the thermometer's variance, for white noise); none when
/// a time is farther than `max_gap_ns` from a sample.
pub fn interval_mean(t: &[i64], v: &[f64], times: &[i64], max_gap_ns: i64) -> Option<(f64, f64)> {
    if times.is_empty() || t.is_empty() {
        return None;
    }
    // Weights of the samples from `first` on.
    let first = t.partition_point(|&x| x <= times[0]).saturating_sub(1);
    let mut weights: Vec<f64> = Vec::new();
    let mut add = |k: usize, w: f64| {
        let i = k - first;
        if weights.len() <= i {
            weights.resize(i + 1, 0.0);
        }
        weights[i] += w;
    };
    let mut next = first;
    for &time in times {
        while next < t.len() && t[next] <= time {
            next += 1;
        }
        match (next.checked_sub(1), (next < t.len()).then_some(next)) {
            (Some(l), Some(r)) => {
                if (time - t[l]).min(t[r] - time) > max_gap_ns {
                    return None;
                }
                let w = (time - t[l]) as f64 / (t[r] - t[l]) as f64;
                add(l, 1.0 - w);
                add(r, w);
            }
            (Some(l), None) if time - t[l] <= max_gap_ns => add(l, 1.0),
            (None, Some(r)) if t[r] - time <= max_gap_ns => add(r, 1.0),
            _ => return None,
        }
    }
    let n = times.len() as f64;
    let mean = weights
        .iter()
        .enumerate()
        .map(|(i, w)| w * v[first + i])
        .sum::<f64>()
        / n;
    let squares = weights.iter().map(|w| (w / n).powi(2)).sum();
    Some((mean, squares))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small generator: uniform in (0, 1), and normal by Box-Muller.
    struct Lcg(u64);
    impl Lcg {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    /// Plateaus joined by ramps, with white noise of 5 mK: the estimate is within 5 % of
    /// it (4000 samples: the robust sd's own se is about 2 %); the noise-free series gives 0.
    #[test]
    fn white_noise_under_plateaus_and_ramps() {
        let mut rng = Lcg(7);
        let truth = |k: usize| {
            let s = k as f64 * 2.0;
            match s {
                s if s < 2000.0 => 20.0,
                s if s < 2600.0 => 20.0 + 7.0 * (s - 2000.0) / 600.0,
                s if s < 5000.0 => 27.0,
                s if s < 5600.0 => 27.0 + 7.0 * (s - 5000.0) / 600.0,
                _ => 34.0,
            }
        };
        let clean: Vec<f64> = (0..4000).map(truth).collect();
        assert_eq!(white_noise_sd(&clean), Some(0.0));
        let noisy: Vec<f64> = clean.iter().map(|t| t + 0.005 * rng.normal()).collect();
        let sd = white_noise_sd(&noisy).expect("enough samples");
        assert!((sd / 0.005 - 1.0).abs() < 0.05, "{sd}");
        assert_eq!(white_noise_sd(&noisy[..21]), None);
        // Written in whole mK (as a logger of millidegrees): 2 mK of noise is measured as
        // the root of 2^2 + 1/12 mK^2, not in steps of the median's whole mK.
        let steps: Vec<f64> = clean
            .iter()
            .map(|t| ((t + 0.002 * rng.normal()) * 1e3).round() / 1e3)
            .collect();
        let sd = white_noise_sd(&steps).expect("enough samples");
        let want = (4.0f64 + 1.0 / 12.0).sqrt() * 1e-3;
        assert!((sd / want - 1.0).abs() < 0.05, "{sd} {want}");
    }

    /// The mean is the mean of the interpolated values, and the squared weights' sum is
    /// the variance of that mean over many draws of the samples' noise.
    #[test]
    fn interval_mean_and_its_variance() {
        let t: Vec<i64> = (0..10).map(|k| k * 2_000).collect();
        let v: Vec<f64> = (0..10).map(|k| 20.0 + 0.1 * f64::from(k)).collect();
        let times: Vec<i64> = (0..80).map(|k| 3_100 + k * 100).collect();
        let (mean, squares) = interval_mean(&t, &v, &times, 5_000).expect("covered");
        let direct: f64 = times
            .iter()
            .map(|&x| 20.0 + 0.1 * x as f64 / 2_000.0)
            .sum::<f64>()
            / 80.0;
        assert!((mean - direct).abs() < 1e-12, "{mean} {direct}");
        let mut rng = Lcg(3);
        let draws = 20_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..draws {
            let noisy: Vec<f64> = v.iter().map(|x| x + rng.normal()).collect();
            let m = interval_mean(&t, &noisy, &times, 5_000).expect("covered").0 - mean;
            s += m;
            s2 += m * m;
        }
        let var = s2 / f64::from(draws) - (s / f64::from(draws)).powi(2);
        assert!((var / squares - 1.0).abs() < 0.04, "{var} {squares}");
        // A time past the last sample by more than the gap allowed: none.
        assert!(interval_mean(&t, &v, &[30_000], 5_000).is_none());
        assert!(interval_mean(&t, &v, &[20_000], 5_000).is_some());
    }
}
