//! Static intervals of a multi-position session (docs/formats.md 8.4), free of I/O: found in the
//! stream by a moving-variance detector, or taken from the manifest's `static_s`; each
//! interval's three mean readings with their sigmas.
//!
//! The detector judges each window (centred on a sample) by the three axes' sample
//! variances over the positions' own noise, summed: for a still block with white noise that
//! sum is chi2(3(w - 1))/(w - 1). The noise is the stream's, not the quiet start's
//! ([`still_class_variance`]: the windows split into still and moving by Otsu's threshold on
//! their log variance, the still class's median; raised until the stretches found with it
//! hold it); the quiet start is checked against it. A position is a run of windows under
//! [`HOLD_FACTOR`] times the noise holding one under [`SEED_FACTOR`] times it (or the law's
//! 99.9 % quantile, if larger): a hand's tremor scatters a position's windows far beyond the
//! white-noise law, while the turns stand thousands of times above it (docs/triad.md,
//! "Finding the positions"). Runs at least a window long are the intervals (the window's
//! half-width keeps them clear of the motion on either side). Each
//! window's variance is summed afresh (time n w, about a second for an hour at 200 Hz):
//! running sums over the stream cancel catastrophically.

use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The first this many seconds of a multi-position stream are taken for still (unless the
/// session declares its `quiet_start_s`): their noise is checked against the still
/// stretches' own, which the detector judges by (imu_tk asks for a quiet start of tens of
/// seconds and takes its threshold from it; none is needed here).
pub const QUIET_S: f64 = 10.0;
/// The moving-variance window, s, up to [`MAX_WINDOW_SAMPLES`].
pub const WINDOW_S: f64 = 1.0;
/// The most samples of the moving-variance window (imu_tk's 100): at high rates a window
/// of a second would swallow a hand-held position of 1-2 s.
pub const MAX_WINDOW_SAMPLES: usize = 100;
/// The fewest samples of a position (imu_tk's default too). Not a duration tuned to one
/// recording but what its sigma needs: a position's sigma is its samples' scatter about a
/// line over sqrt(n), itself uncertain by 1/sqrt(2(n - 2)), 7 % at 100 samples; fewer
/// would weight the position by a sigma of unknown worth.
pub const MIN_POSITION_SAMPLES: usize = 100;
/// The detector's false-alarm rate per window.
pub const ALPHA: f64 = 0.001;

/// A session's samples in time order.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// GPS time, ns.
    pub time_ns: Vec<i64>,
    /// Readings of channels 1..3 (None: not connected, saturated or `nan`).
    pub values: Vec<[Option<f64>; 3]>,
}

/// A quiet start whose variance is further than this factor from the variance inside the
/// still stretches (either way, on any axis) is warned of: motion in the quiet start, or a
/// start quieter than the positions.
pub const QUIET_START_AGREEMENT: f64 = 4.0;

/// The detector's reference is raised until the still stretches found with it have a
/// variance within this factor of it on every axis.
pub const STILLER_START: f64 = 1.05;

/// What the detector found.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    /// Each axis's sd over the quiet start.
    pub quiet_sd: [f64; 3],
    /// Each axis's noise sd inside the still stretches (the reference when the quiet start
    /// is at odds with it), when the stream has enough windows to say.
    pub still_sd: Option<[f64; 3]>,
    /// The quiet start was set aside for the still stretches' noise, and why.
    pub warning: Option<String>,
    /// The window, samples.
    pub window: usize,
    /// The white-noise law's 99.9 % quantile of the window statistic (a run's seed window
    /// is within the larger of it and 3 [`SEED_FACTOR`], every window within 3
    /// [`HOLD_FACTOR`]).
    pub threshold: f64,
    /// Runs of still samples: half-open index ranges, in time order.
    pub intervals: Vec<(usize, usize)>,
}

/// Why the detector could not run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DetectError {
    /// Fewer samples than the quiet start needs.
    #[error("the stream is shorter than the quiet start the detector needs")]
    TooShort,
    /// An axis has no spread over the quiet start (a constant, or no values).
    #[error("channel {0} does not vary over the quiet start: no noise to set a threshold from")]
    NoNoise(usize),
}

/// Mean, sample variance and count of each axis over samples [i, j): one pass of sums
/// relative to the range's first value (a prefix sum over the whole stream would subtract
/// numbers of 1e7 to find variances of 1e-10: readings in m/s^2 lost every digit).
fn stats_of(series: &Series, i: usize, j: usize) -> [(f64, f64, u32); 3] {
    std::array::from_fn(|k| {
        let values = series.values[i..j].iter().filter_map(|v| v[k]);
        let Some(reference) = series.values[i..j].iter().find_map(|v| v[k]) else {
            return (f64::NAN, f64::NAN, 0);
        };
        let (mut s1, mut s2, mut n) = (0.0, 0.0, 0u32);
        for x in values {
            let d = x - reference;
            s1 += d;
            s2 += d * d;
            n += 1;
        }
        if n < 2 {
            return (f64::NAN, f64::NAN, n);
        }
        let nf = f64::from(n);
        let mean = s1 / nf;
        (
            (reference + mean),
            ((s2 - s1 * mean) / (nf - 1.0)).max(0.0),
            n,
        )
    })
}

/// A gap in stillness up to this many windows long, between two runs whose means agree, is
/// a false alarm (the test is at 0.1 % a window, and an unlucky stretch of noise raises the
/// windows across it), not a turn of the block.
const MERGE_GAP_WINDOWS: usize = 3;

/// Joins neighbouring runs separated by fewer than `max_gap` samples when every axis's
/// means on the two sides agree within 5 sds of their difference (a real turn moves them
/// by thousands).
fn merge_false_alarms(
    series: &Series,
    runs: Vec<(usize, usize)>,
    max_gap: usize,
) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for (i, j) in runs {
        if let Some(last) = out.last_mut()
            && i - last.1 < max_gap
        {
            let a = stats_of(series, last.0, last.1);
            let b = stats_of(series, i, j);
            let agree = (0..3).all(|k| {
                let se =
                    (a[k].1 / f64::from(a[k].2.max(1)) + b[k].1 / f64::from(b[k].2.max(1))).sqrt();
                (a[k].0 - b[k].0).abs() <= 5.0 * se
            });
            if agree {
                last.1 = j;
                continue;
            }
        }
        out.push((i, j));
    }
    out
}

/// Finds the static intervals of `series` sampled at `rate_hz`, its first `quiet_s` seconds
/// taken for still.
pub fn detect(series: &Series, rate_hz: f64, quiet_s: f64) -> Result<Detection, DetectError> {
    let len = series.time_ns.len();
    let quiet = (quiet_s * rate_hz).round() as usize;
    if len < quiet.max(3) {
        return Err(DetectError::TooShort);
    }
    let q = stats_of(series, 0, quiet);
    let mut quiet_sd = [0.0; 3];
    for k in 0..3 {
        if q[k].1.is_nan() || q[k].1 <= 0.0 {
            return Err(DetectError::NoNoise(k + 1));
        }
        quiet_sd[k] = q[k].1.sqrt();
    }
    let window = ((WINDOW_S * rate_hz).round() as usize).clamp(5, MAX_WINDOW_SAMPLES);
    let dof = 3.0 * (window as f64 - 1.0);
    let threshold = ChiSquared::new(dof)
        .expect("positive dof")
        .inverse_cdf(1.0 - ALPHA)
        / (window as f64 - 1.0);
    let quiet_var = q.map(|x| x.1);
    // The noise the positions themselves have, as the windows' population says (a hand
    // trembles where the table the quiet start lay on did not), raised until the stretches
    // found with it hold it; the quiet start is checked against it, not taken for it.
    let population = still_class_variance(series, window).unwrap_or(quiet_var);
    let (intervals, still_var) = raised(series, window, threshold, population);
    let reference = still_var.unwrap_or(population);
    let sd = |v: [f64; 3]| v.map(|x| format!("{:.4e}", x.sqrt())).join(", ");
    let warning = (0..3)
        .any(|k| {
            let r = quiet_var[k] / reference[k];
            !(1.0 / QUIET_START_AGREEMENT..=QUIET_START_AGREEMENT).contains(&r)
        })
        .then(|| {
            format!(
                "the quiet start's noise (first {quiet_s} s, sd per axis {}) is at odds with the \
                 noise inside the still stretches (sd {}; more than {QUIET_START_AGREEMENT} \
                 times apart in variance): motion in the quiet start, or none at all; the still \
                 stretches' noise is the detector's reference",
                sd(quiet_var),
                sd(reference)
            )
        });
    Ok(Detection {
        quiet_sd,
        still_sd: still_var.map(|v| v.map(f64::sqrt)),
        warning,
        window,
        threshold,
        intervals,
    })
}

/// The stretches found against `start`, the reference raised step by step (each axis to the
/// stretches' pooled noise when that is larger) until it holds within [`STILLER_START`]:
/// stretches found with a reference too small are their stillest parts. Returns the
/// stretches and their noise.
fn raised(
    series: &Series,
    window: usize,
    threshold: f64,
    start: [f64; 3],
) -> (Vec<(usize, usize)>, Option<[f64; 3]>) {
    let mut reference = start;
    let mut intervals = Vec::new();
    let mut still = None;
    for _ in 0..4 {
        intervals = intervals_with(series, window, threshold, reference);
        let Some(next) = pooled_variance(series, &intervals, window) else {
            break;
        };
        still = Some(next);
        if (0..3).all(|k| next[k] <= reference[k] * STILLER_START) {
            break;
        }
        reference = std::array::from_fn(|k| next[k].max(reference[k]));
    }
    (intervals, still)
}

/// Each axis's noise variance in the still windows of the stream, the positions' and the
/// quiet start's together: the windows (non-overlapping) split in two by Otsu's threshold on
/// the logarithm of their variance (each axis over its [`robust_variance`], averaged), the
/// still class the lower; its median variance per axis over the median of chi2(w - 1)/(w - 1).
/// The turns stand 10^3 and more above the still windows, and a hand's tremor a few times to
/// tens of times: the threshold falls between the still and the moving, and the median is the
/// positions' own noise, tremor included. None for fewer than 10 windows.
fn still_class_variance(series: &Series, window: usize) -> Option<[f64; 3]> {
    let scale = robust_variance(series, window)?;
    let n = series.time_ns.len() / window;
    let windows: Vec<[f64; 3]> = (0..n)
        .map(|w| stats_of(series, w * window, (w + 1) * window).map(|s| s.1))
        .filter(|v| v.iter().all(|x| x.is_finite() && *x > 0.0))
        .collect();
    let level: Vec<f64> = windows
        .iter()
        .map(|v| ((0..3).map(|k| v[k] / scale[k]).sum::<f64>() / 3.0).ln())
        .collect();
    let cut = otsu(&level)?;
    let dof = window as f64 - 1.0;
    let median_of_law = ChiSquared::new(dof).ok()?.inverse_cdf(0.5) / dof;
    let mut out = [0.0; 3];
    for k in 0..3 {
        let mut v: Vec<f64> = windows
            .iter()
            .zip(&level)
            .filter(|(_, l)| **l < cut)
            .map(|(v, _)| v[k])
            .collect();
        if v.is_empty() {
            return None;
        }
        let at = v.len() / 2;
        out[k] = *v.select_nth_unstable_by(at, f64::total_cmp).1 / median_of_law;
    }
    Some(out)
}

/// Otsu's threshold of `x`: the cut between two classes that maximises the variance between
/// them, over 128 bins of its range; None for a range of zero.
fn otsu(x: &[f64]) -> Option<f64> {
    const BINS: usize = 128;
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        return None;
    }
    let width = (hi - lo) / BINS as f64;
    let mut counts = [0usize; BINS];
    for &v in x {
        counts[(((v - lo) / width) as usize).min(BINS - 1)] += 1;
    }
    let centre = |i: usize| lo + (i as f64 + 0.5) * width;
    let total = x.len() as f64;
    let sum: f64 = (0..BINS).map(|i| counts[i] as f64 * centre(i)).sum();
    let (mut below, mut below_sum, mut best) = (0.0, 0.0, (f64::NEG_INFINITY, lo));
    for i in 0..BINS - 1 {
        below += counts[i] as f64;
        below_sum += counts[i] as f64 * centre(i);
        let above = total - below;
        if below == 0.0 || above == 0.0 {
            continue;
        }
        let between = below * above * (below_sum / below - (sum - below_sum) / above).powi(2);
        if between > best.0 {
            best = (between, lo + (i + 1) as f64 * width);
        }
    }
    best.0.is_finite().then_some(best.1)
}

/// How far a window of a position may rise above the noise it is judged by: up to this
/// many times the reference variance (the mean over the three axes), as long as the run it
/// belongs to holds a window within [`SEED_FACTOR`] of it. A hand-held position's
/// windows scatter well beyond the white-noise law (a tremor that comes and goes, held
/// samples that leave fewer independent values in a window), while the turns between
/// positions stand 10^3-10^4 times above the noise: cutting a run at the 99.9 % quantile,
/// the detector found 17 positions on ouabout/imu_tk's recording cut to a 6.6 s quiet start,
/// where imu_tk finds 21 (docs/triad.md, "Finding the positions"). 10 is imu_tk's largest
/// multiple.
pub const HOLD_FACTOR: f64 = 10.0;

/// A run must hold a window within this many times the reference variance (the mean over
/// the axes), or within the white-noise quantile if that is larger: twice the noise, imu_tk's
/// smallest multiple, is still by anyone's reading, and a slow turn is not.
pub const SEED_FACTOR: f64 = 2.0;

/// The still stretches of `series` against the noise variances `reference` per axis:
/// hysteresis on the window statistic (the sum over the axes of each window's variance over
/// the reference). A run is a stretch of windows below `3 HOLD_FACTOR` holding at least one
/// below `3 SEED_FACTOR` (or `threshold`, the white-noise quantile, if larger): the strict
/// test finds the positions, the loose one keeps a position whole through its tremor.
fn intervals_with(
    series: &Series,
    window: usize,
    threshold: f64,
    reference: [f64; 3],
) -> Vec<(usize, usize)> {
    let len = series.time_ns.len();
    let half = window / 2;
    let hold = (3.0 * HOLD_FACTOR).max(threshold);
    let seed = (3.0 * SEED_FACTOR).max(threshold);
    let stat: Vec<f64> = (0..len)
        .map(|i| {
            if i < half || i + window - half > len {
                return f64::INFINITY;
            }
            let s = stats_of(series, i - half, i - half + window);
            (0..3).map(|k| s[k].1 / reference[k]).sum()
        })
        .collect();
    let mut runs = Vec::new();
    let mut i = 0;
    while i < len {
        if stat[i] < hold {
            let j = (i..len)
                .find(|&j| stat[j].is_nan() || stat[j] >= hold)
                .unwrap_or(len);
            if stat[i..j].iter().any(|&x| x < seed) {
                runs.push((i, j));
            }
            i = j;
        } else {
            i += 1;
        }
    }
    // A run shorter than a window is a lull inside a false alarm or a turn, not an interval.
    runs.retain(|(i, j)| j - i >= window);
    merge_false_alarms(series, runs, MERGE_GAP_WINDOWS * window)
}

/// Each axis's noise variance inside `intervals`: the windows' sample variances pooled
/// (each window of an interval, its own mean taken out, so a slow drift does not count);
/// None without a whole window.
fn pooled_variance(
    series: &Series,
    intervals: &[(usize, usize)],
    window: usize,
) -> Option<[f64; 3]> {
    let mut sum = [0.0; 3];
    let mut dof = [0.0; 3];
    for &(i, j) in intervals {
        let mut a = i;
        while a + window <= j {
            let s = stats_of(series, a, a + window);
            for k in 0..3 {
                if s[k].2 >= 2 && s[k].1.is_finite() {
                    sum[k] += s[k].1 * f64::from(s[k].2 - 1);
                    dof[k] += f64::from(s[k].2 - 1);
                }
            }
            a += window;
        }
    }
    (dof.iter().all(|&d| d > 0.0) && sum.iter().all(|&s| s > 0.0))
        .then(|| std::array::from_fn(|k| sum[k] / dof[k]))
}

/// Each axis's noise variance from the stream alone: the 10 % quantile of the variances of
/// non-overlapping windows, over the 10 % quantile of chi2(w - 1)/(w - 1) (what it is for
/// a still block). Approximate (the still windows' share of the stream shifts the
/// quantile); the stretches found with it then give the reference. None for fewer than 10
/// windows.
fn robust_variance(series: &Series, window: usize) -> Option<[f64; 3]> {
    let len = series.time_ns.len();
    let n = len / window;
    if n < 10 {
        return None;
    }
    let scale =
        ChiSquared::new(window as f64 - 1.0).ok()?.inverse_cdf(0.10) / (window as f64 - 1.0);
    let mut out = [0.0; 3];
    for k in 0..3 {
        let mut v: Vec<f64> = (0..n)
            .map(|w| stats_of(series, w * window, (w + 1) * window)[k].1)
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        if v.len() < 10 {
            return None;
        }
        let at = v.len() / 10;
        out[k] = *v.select_nth_unstable_by(at, f64::total_cmp).1 / scale;
    }
    Some(out)
}

/// The index ranges of the listed intervals, `[t0, t1]` seconds since the first sample.
pub fn listed(series: &Series, static_s: &[[f64; 2]]) -> Vec<(usize, usize)> {
    let Some(&t0) = series.time_ns.first() else {
        return Vec::new();
    };
    static_s
        .iter()
        .map(|[a, b]| {
            let from = t0 + (a * 1e9).round() as i64;
            let to = t0 + (b * 1e9).round() as i64;
            (
                series.time_ns.partition_point(|&t| t < from),
                series.time_ns.partition_point(|&t| t <= to),
            )
        })
        .collect()
}

/// One interval's means: (mean, sd of the mean, samples) per axis; None when an axis has
/// fewer than three values. The sd is the samples' scatter about a straight line in time
/// over sqrt(n): a block that drifts while still (its temperature moving) keeps the mean
/// of a line, its value at the samples' mean time, and the sd of its noise, not of the
/// drift.
pub fn means(series: &Series, (i, j): (usize, usize)) -> Option<([f64; 3], [f64; 3], u64)> {
    let s = stats_of(series, i, j);
    if s.iter().any(|x| x.2 < 3) {
        return None;
    }
    let t0 = series.time_ns[i];
    let sd: [f64; 3] = std::array::from_fn(|k| {
        let points = || {
            series.time_ns[i..j]
                .iter()
                .zip(&series.values[i..j])
                .filter_map(move |(&t, v)| v[k].map(|x| ((t - t0) as f64 * 1e-9, x)))
        };
        let n = f64::from(s[k].2);
        let t_mean = points().map(|(t, _)| t).sum::<f64>() / n;
        let (mut stt, mut stx, mut sxx) = (0.0, 0.0, 0.0);
        for (t, x) in points() {
            let (dt, dx) = (t - t_mean, x - s[k].0);
            stt += dt * dt;
            stx += dt * dx;
            sxx += dx * dx;
        }
        let residual = if stt > 0.0 {
            sxx - stx * stx / stt
        } else {
            sxx
        };
        (residual.max(0.0) / (n - 2.0) / n).sqrt()
    });
    Some((
        s.map(|x| x.0),
        sd,
        u64::from(s.iter().map(|x| x.2).min().unwrap_or(0)),
    ))
}

/// Fewest samples of an interval for the noise analysis.
pub const MIN_NOISE_SAMPLES: usize = 64;

/// One axis's noise over a session's static intervals: the Allan curve pooled over them and
/// the terms fitted to it ([`crate::allan::fit_noise`]: a bias instability or random walk
/// only when significant), with the intervals and samples it used.
#[derive(Clone, Debug)]
pub struct AxisNoise {
    /// The Allan curve.
    pub points: Vec<crate::allan::AllanPoint>,
    /// Its fitted terms.
    pub terms: crate::allan::NoiseTerms,
    /// Intervals used (every sample of the axis valid, at least [`MIN_NOISE_SAMPLES`]).
    pub intervals: usize,
    /// Samples in them.
    pub samples: usize,
    /// The samples' lag-one autocorrelation, when significantly above 0 ([`lag_one`]): a
    /// logger that holds its last value (issue 47). The curve then starts beyond its reach.
    pub lag_one: Option<f64>,
}

impl AxisNoise {
    /// The variance the coloured terms add to the mean of an interval of `duration_s`:
    /// their Allan variance there (docs/model.md 6.2), 0 for white noise.
    pub fn coloured_variance(&self, duration_s: f64) -> f64 {
        crate::allan::NoiseTerms {
            white_density: 0.0,
            ..self.terms
        }
        .allan_variance(duration_s)
    }
}

/// The noise of each axis over `intervals` of `series` sampled every `tau0_s`: each
/// interval's readings less their straight line in time (as the positions' sds: a drift
/// while still, the temperature moving, is not noise; the line also takes some of a random
/// walk's power at the longest taus), pooled into one Allan curve per axis. None for an
/// axis without an interval of [`MIN_NOISE_SAMPLES`].
pub fn noise(series: &Series, intervals: &[(usize, usize)], tau0_s: f64) -> [Option<AxisNoise>; 3] {
    std::array::from_fn(|k| {
        let residuals: Vec<Vec<f64>> = intervals
            .iter()
            .filter_map(|&(i, j)| {
                let y: Option<Vec<f64>> = series.values[i..j].iter().map(|v| v[k]).collect();
                y.filter(|y| y.len() >= MIN_NOISE_SAMPLES).map(detrended)
            })
            .collect();
        let longest = residuals.iter().map(Vec::len).max()?;
        let slices: Vec<&[f64]> = residuals.iter().map(Vec::as_slice).collect();
        let lag_one = lag_one(&slices);
        // Held samples correlate their neighbours as rho^lag: the curve starts where that
        // has fallen below 5 %, beyond which the samples' means scatter as white noise
        // of the inflated level (a bias instability read into the first octaves is none).
        let first = lag_one.map_or(1, |r| (0.05f64.ln() / r.ln()).ceil().max(1.0) as usize);
        let factors: Vec<usize> = crate::allan::octave_factors(longest)
            .into_iter()
            .filter(|&m| m >= first)
            .collect();
        let points = crate::allan::pooled(&slices, tau0_s, &factors);
        Some(AxisNoise {
            lag_one,
            terms: crate::allan::fit_noise(
                &points,
                &slices.iter().map(|s| s.len()).collect::<Vec<_>>(),
            ),
            points,
            intervals: slices.len(),
            samples: slices.iter().map(|s| s.len()).sum(),
        })
    })
}

/// The lag-one autocorrelation of the `residuals` pooled (sum r_t r_t+1 over sum r_t^2),
/// when it is above 3 / sqrt(samples), where white noise puts it with odds of about 1 in
/// 700, and below 0.9 (beyond, the samples are too few to say what the noise is).
pub fn lag_one(residuals: &[&[f64]]) -> Option<f64> {
    let (mut lagged, mut squares, mut n) = (0.0, 0.0, 0usize);
    for r in residuals {
        lagged += r.windows(2).map(|w| w[0] * w[1]).sum::<f64>();
        squares += r.iter().map(|x| x * x).sum::<f64>();
        n += r.len();
    }
    let rho = lagged / squares;
    (rho > 3.0 / (n as f64).sqrt() && rho < 0.9).then_some(rho)
}

/// The factor by which samples of lag-one autocorrelation `rho` (each neighbour's rho^lag,
/// as held samples give) multiply the variance of a long mean against white samples:
/// (1 + rho) / (1 - rho).
pub fn held_variance_factor(rho: Option<f64>) -> f64 {
    rho.map_or(1.0, |r| (1.0 + r) / (1.0 - r))
}

/// `y` less its least-squares line in the sample index.
fn detrended(y: Vec<f64>) -> Vec<f64> {
    let n = y.len() as f64;
    let i_mean = (n - 1.0) / 2.0;
    let y_mean = y.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in y.iter().enumerate() {
        let d = i as f64 - i_mean;
        sxy += d * (v - y_mean);
        sxx += d * d;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    y.iter()
        .enumerate()
        .map(|(i, v)| v - y_mean - slope * (i as f64 - i_mean))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Still, moving, still: two intervals, clear of the motion.
    #[test]
    fn still_moving_still() {
        let rate = 50.0;
        let mut s = Series::default();
        let mut state = 1u64;
        let mut noise = || {
            // A small LCG, uniform in [-0.5, 0.5): sd 0.29.
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for i in 0..3000 {
            let t = f64::from(i) / rate;
            let moving = (20.0..26.0).contains(&t);
            let level = if t < 23.0 { 100.0 } else { 300.0 };
            let amp = if moving { 50.0 } else { 1.0 };
            s.time_ns.push((t * 1e9) as i64);
            s.values.push([
                Some(level + amp * noise()),
                Some(-level + amp * noise()),
                Some(amp * noise()),
            ]);
        }
        let d = detect(&s, rate, QUIET_S).expect("detects");
        let long: Vec<(usize, usize)> = d
            .intervals
            .iter()
            .copied()
            .filter(|(a, b)| (b - a) as f64 > 3.0 * rate)
            .collect();
        assert_eq!(long.len(), 2, "{:?}", d.intervals);
        assert!(long[0].1 <= 1000 && long[0].1 >= 975, "{:?}", long[0]);
        assert!(long[1].0 >= 1300 && long[1].0 <= 1330, "{:?}", long[1]);
        let (m, sigma, n) = means(&s, long[1]).expect("means");
        assert!((m[0] - 300.0).abs() < 0.05 && n > 1000, "{m:?}");
        assert!(
            (sigma[0] - 0.29 / (n as f64).sqrt()).abs() < 0.002,
            "{sigma:?}"
        );
    }
}
