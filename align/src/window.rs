//! The arithmetic of one ADC window, free of I/O: running sums of the counts relative to the
//! window's first value (so the squares keep their precision) and of time, from which the
//! mean, the sd of the mean, and the t statistic of a linear trend follow.

/// Variance of the rounding of a reading to whole counts, count^2: the floor of a sample's
/// variance when readings are counts. Readings in another unit (a lab stream's volts or
/// m/s^2) carry no known rounding, and their floor is 0: the samples' own scatter.
pub const QUANTISATION_VARIANCE: f64 = 1.0 / 12.0;

/// Running sums for one (reading, channel) window.
#[derive(Clone, Debug, Default)]
pub struct WindowSums {
    /// Rows (samples present) in the window, whatever their status.
    pub rows: u32,
    /// Samples flagged not connected.
    pub not_connected: u32,
    /// Samples flagged over range.
    pub saturated: u32,
    /// Valid samples.
    pub n: u32,
    x0: Option<f64>,
    sx: f64,
    sxx: f64,
    st: f64,
    stt: f64,
    stx: f64,
}

/// What a window gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowStats {
    /// Mean count.
    pub mean: f64,
    /// Sd of the mean (sample sd / sqrt(n)), never below the quantisation of the readings
    /// (for counts an sd of 1/sqrt(12) count per sample): samples all equal do not make a
    /// mean exact.
    pub sigma_mean: f64,
    /// t statistic of the slope of a straight line through the samples (0 when n < 4).
    pub drift_t: f64,
    /// Whether the sample variance was below the floor (the sd is then the floor's, known).
    pub floored: bool,
}

impl WindowStats {
    /// Degrees of freedom of the window mean's variance `sigma_mean^2 + coloured` taken from
    /// `n` samples: n - 1 for the sample variance, Satterthwaite's (n - 1) (total / estimated
    /// part)^2 when a known `coloured` variance is added; None when the floor set it (known).
    pub fn sigma_mean_dof(&self, n: u32, coloured: f64) -> Option<f64> {
        let own = self.sigma_mean.powi(2);
        (!self.floored && n >= 2 && own > 0.0)
            .then(|| f64::from(n - 1) * ((own + coloured.max(0.0)) / own).powi(2))
    }
}

impl WindowSums {
    /// Adds a valid sample `x` taken `t_s` seconds from the window's centre.
    pub fn add(&mut self, t_s: f64, x: f64) {
        let x0 = *self.x0.get_or_insert(x);
        let d = x - x0;
        self.n += 1;
        self.sx += d;
        self.sxx += d * d;
        self.st += t_s;
        self.stt += t_s * t_s;
        self.stx += t_s * d;
    }

    /// Mean, sd of the mean and trend statistic, a sample's variance taken as at least
    /// `floor_variance` (see [`QUANTISATION_VARIANCE`]); `None` with fewer than 2 samples.
    pub fn stats(&self, floor_variance: f64) -> Option<WindowStats> {
        let x0 = self.x0?;
        if self.n < 2 {
            return None;
        }
        let n = f64::from(self.n);
        let mean_d = self.sx / n;
        let sxx = (self.sxx - self.sx * mean_d).max(0.0);
        let var = sxx / (n - 1.0);
        let stt = self.stt - self.st * self.st / n;
        let stx = self.stx - self.st * mean_d;
        let drift_t = if self.n >= 4 && stt > 0.0 {
            let slope = stx / stt;
            let resid = (sxx - slope * stx).max(0.0) / (n - 2.0);
            if resid > 0.0 {
                slope / (resid / stt).sqrt()
            } else if slope == 0.0 {
                0.0
            } else {
                f64::INFINITY.copysign(slope)
            }
        } else {
            0.0
        };
        Some(WindowStats {
            mean: x0 + mean_d,
            sigma_mean: (var.max(floor_variance) / n).sqrt(),
            drift_t,
            floored: var < floor_variance,
        })
    }
}

/// Sample standard deviation; `None` for fewer than 2 values.
pub fn sample_sd(values: &[f64]) -> Option<f64> {
    if values.len() < 2 {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    Some((values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt())
}

/// [`interpolate`] for times that mostly increase (a stream in time order): it remembers
/// where the last time fell and steps from there, searching anew only when time goes back.
/// The same values as [`interpolate`], bit for bit.
#[derive(Clone, Debug)]
pub struct Interpolator<'a> {
    times: &'a [i64],
    values: &'a [f64],
    /// `times[..next]` are <= the last time asked.
    next: usize,
    last: i64,
}

impl<'a> Interpolator<'a> {
    /// Over a time series sorted by time.
    pub fn new(times: &'a [i64], values: &'a [f64]) -> Self {
        Interpolator {
            times,
            values,
            next: 0,
            last: i64::MIN,
        }
    }

    /// The value at `t` as [`interpolate`] gives it.
    #[inline]
    pub fn at(&mut self, t: i64, max_gap_ns: i64) -> Option<(f64, i64)> {
        let times = self.times;
        if t < self.last {
            self.next = times.partition_point(|&x| x <= t);
        } else {
            while self.next < times.len() && times[self.next] <= t {
                self.next += 1;
            }
        }
        self.last = t;
        interpolate_at(times, self.values, self.next, t, max_gap_ns)
    }
}

/// Linear interpolation in a time series sorted by time; `None` when the nearest sample is
/// further than `max_gap_ns` (or there is none). Returns (value, distance to nearest, ns).
pub fn interpolate(times: &[i64], values: &[f64], t: i64, max_gap_ns: i64) -> Option<(f64, i64)> {
    interpolate_at(
        times,
        values,
        times.partition_point(|&x| x <= t),
        t,
        max_gap_ns,
    )
}

/// [`interpolate`] where `i` is the first index with a time after `t`.
#[inline]
fn interpolate_at(
    times: &[i64],
    values: &[f64],
    i: usize,
    t: i64,
    max_gap_ns: i64,
) -> Option<(f64, i64)> {
    let left = i.checked_sub(1).map(|j| (times[j], values[j]));
    let right = times.get(i).map(|&x| (x, values[i]));
    let (value, nearest) = match (left, right) {
        (Some((tl, vl)), Some((tr, vr))) => {
            let w = (t - tl) as f64 / (tr - tl) as f64;
            (vl + w * (vr - vl), (t - tl).min(tr - t))
        }
        (Some((tl, vl)), None) => (vl, t - tl),
        (None, Some((tr, vr))) => (vr, tr - t),
        (None, None) => return None,
    };
    (nearest <= max_gap_ns).then_some((value, nearest))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interpolator_gives_interpolate_s_values() {
        let times: Vec<i64> = vec![10, 20, 20, 35, 60, 61];
        let values = [1.0, 2.0, 4.0, -3.0, 0.5, 7.0];
        let mut it = Interpolator::new(&times, &values);
        // Forward, repeated, then back in time, then forward past the end.
        for t in [
            0, 5, 10, 15, 20, 20, 21, 34, 35, 50, 12, 13, 61, 62, 100, 9, 200,
        ] {
            for gap in [0, 5, 30] {
                let mut fresh = Interpolator::new(&times, &values);
                let want = interpolate(&times, &values, t, gap);
                assert_eq!(fresh.at(t, gap), want, "t {t} gap {gap} fresh");
            }
            assert_eq!(it.at(t, 30), interpolate(&times, &values, t, 30), "t {t}");
        }
    }

    #[test]
    fn mean_sd_and_precision_far_from_zero() {
        let mut w = WindowSums::default();
        let xs = [3_000_001.0, 2_999_999.0, 3_000_003.0, 2_999_997.0];
        for (i, x) in xs.iter().enumerate() {
            w.add(i as f64, *x);
        }
        let s = w.stats(QUANTISATION_VARIANCE).expect("stats");
        assert!((s.mean - 3_000_000.0).abs() < 1e-9);
        let sd = sample_sd(&xs).expect("sd");
        assert!(
            (s.sigma_mean - sd / 2.0).abs() < 1e-9,
            "{} vs {}",
            s.sigma_mean,
            sd / 2.0
        );
    }

    #[test]
    fn trend_is_found_and_noise_is_not() {
        let mut flat = WindowSums::default();
        let mut tilt = WindowSums::default();
        for i in 0..80 {
            let t = (f64::from(i) - 40.0) * 0.032;
            let noise = if i % 2 == 0 { 9.0 } else { -9.0 };
            flat.add(t, 1.0e6 + noise);
            tilt.add(t, 1.0e6 + noise + 30.0 * t);
        }
        assert!(flat.stats(QUANTISATION_VARIANCE).expect("s").drift_t.abs() < 1.0);
        assert!(tilt.stats(QUANTISATION_VARIANCE).expect("s").drift_t > 10.0);
    }

    #[test]
    fn interpolation_and_gaps() {
        let t = [0, 4_096, 8_192];
        let v = [20.0, 21.0, 23.0];
        assert_eq!(interpolate(&t, &v, 2_048, 10_000), Some((20.5, 2_048)));
        assert_eq!(interpolate(&t, &v, 8_192, 10), Some((23.0, 0)));
        assert_eq!(interpolate(&t, &v, 9_000, 1_000), Some((23.0, 808)));
        assert_eq!(interpolate(&t, &v, 9_000, 100), None);
        assert_eq!(interpolate(&[], &[], 9_000, 100), None);
    }
}
