//! A series' white noise measured where vehicle motion is not (docs/model.md 7, "The
//! accelerometers' noise"): the level of its spectrum's floor above the motion band.
//!
//! The samples are cut into runs of [`SEGMENT`] consecutive values (a gap starts a new
//! run); each is detrended, Hann-windowed and transformed, so that its periodogram
//! |X_k|^2 / sum w^2 has the expectation sigma^2 at every frequency for white noise of sd
//! sigma. The upper band, from an eighth of the sampling rate to 0.4 of it (clear of the
//! motion below, and of an anti-alias filter's roll-off at the Nyquist frequency), is split
//! into [`BANDS`] bands, each segment's mean periodogram kept per band. A band's level is
//! the mean over the segments of those within four times its median (a knock or a jerk does
//! not pass for noise); the floor is the mean of the bands within three standard errors of
//! the lowest, so that a band a swell's harmonic or an engine's vibration raises is left
//! out and white noise is measured in all of them. A swell at 10 s sampled at 1 Hz lies at
//! 0.1 Hz, under the band's 0.125 Hz; the third differences this replaces kept a quarter
//! of its amplitude (docs/model.md 7).
//!
//! Its limit: noise that is not white, rising toward low frequencies, is measured at its
//! level above fs/8, not in the filter's pass band; and a record shorter than one segment
//! falls back on the third differences. A floor needs two bands that agree: where no two
//! do (the spectrum of a meter's own filtered output falls by orders of magnitude toward
//! the Nyquist frequency: shipgrav's DGS test record from 695 to 0.04 mGal between 0.15 and
//! 0.37 Hz), the record cannot say its noise, and [`Floor::NotFlat`] says so.

/// Samples per segment.
pub const SEGMENT: usize = 256;
/// Bands the upper band is split into.
pub const BANDS: usize = 5;

/// What a record's spectrum says of its white noise.
#[derive(Clone, Debug, PartialEq)]
pub enum Floor {
    /// The sd per sample, from two or more bands that agree.
    Measured(f64),
    /// The sd per sample from the third differences: a record shorter than a segment.
    ThirdDifferences(f64),
    /// No two bands agree: the spectrum falls (or rises) across the upper band, as a record
    /// an instrument has filtered before writing it does, and its level at 0.4 fs says
    /// nothing of the noise the survey's filter passes. Each band's level as an sd per
    /// sample, from fs/8 up, and the segments averaged.
    NotFlat {
        /// The bands' levels, sd per sample.
        band_sd: Vec<f64>,
        /// Segments of [`SEGMENT`] samples averaged.
        segments: usize,
    },
}

/// The floor of a series' spectrum, built as the series streams past.
#[derive(Clone, Debug, Default)]
pub struct SpectralFloor {
    interval_ns: i64,
    run: Vec<f64>,
    last_t: Option<i64>,
    /// Per segment, its mean periodogram in each band.
    segments: Vec<[f64; BANDS]>,
    /// Third differences, for a record shorter than a segment.
    fallback: super::epochs::ThirdDifferences,
}

impl SpectralFloor {
    /// For values `interval_ns` apart (a longer step starts a new run).
    pub fn new(interval_ns: i64) -> Self {
        SpectralFloor {
            interval_ns,
            run: Vec::with_capacity(SEGMENT),
            fallback: super::epochs::ThirdDifferences::new(interval_ns),
            ..SpectralFloor::default()
        }
    }

    /// The next value, at `t` ns.
    pub fn push(&mut self, t: i64, v: f64) {
        if self
            .last_t
            .is_some_and(|p| (t - p - self.interval_ns).abs() * 2 > self.interval_ns)
        {
            self.run.clear();
        }
        self.last_t = Some(t);
        self.fallback.push(t, v);
        self.run.push(v);
        if self.run.len() == SEGMENT {
            self.segments.push(band_means(&self.run));
            self.run.clear();
        }
    }

    /// The white noise's sd (0 before any value), or why the record cannot give it.
    pub fn floor(&self) -> Floor {
        if self.segments.is_empty() {
            return Floor::ThirdDifferences(self.fallback.sd());
        }
        let levels: Vec<(f64, f64)> = (0..BANDS).map(|b| self.band_level(b)).collect();
        let (low, low_se) = levels
            .iter()
            .copied()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((0.0, 0.0));
        let kept: Vec<f64> = levels
            .iter()
            .filter(|(v, se)| v - low <= 3.0 * se.hypot(low_se))
            .map(|(v, _)| *v)
            .collect();
        if kept.len() < 2 {
            return Floor::NotFlat {
                band_sd: levels.iter().map(|(v, _)| v.sqrt()).collect(),
                segments: self.segments.len(),
            };
        }
        Floor::Measured((kept.iter().sum::<f64>() / kept.len() as f64).sqrt())
    }

    /// Band `b`'s level over the segments (those within four times its median) and the
    /// standard error white noise at that level would give it.
    fn band_level(&self, b: usize) -> (f64, f64) {
        let mut v: Vec<f64> = self.segments.iter().map(|s| s[b]).collect();
        v.sort_by(f64::total_cmp);
        let median = v[v.len() / 2];
        let kept: Vec<f64> = v.into_iter().filter(|x| *x <= 4.0 * median).collect();
        let n = kept.len() as f64;
        let mean = kept.iter().sum::<f64>() / n;
        // The standard error white noise at this level would give: a band's mean over its
        // bins is about bins / 1.5 independent chi-square(2) / 2 values (the Hann window
        // correlates neighbouring bins). Not the segments' own scatter: over the three
        // segments of a 1000 s record a swell's band scatters so much that it passed for
        // agreeing with the floor.
        let bins = (band_range(0).len() as f64 / 1.5).max(1.0);
        let se = mean / (bins * n).sqrt();
        (mean, se)
    }
}

/// The bins of band `b` (of a [`SEGMENT`]-sample periodogram).
fn band_range(b: usize) -> std::ops::Range<usize> {
    let (lo, hi) = (SEGMENT / 8, SEGMENT * 2 / 5);
    let width = (hi - lo) / BANDS;
    lo + b * width..lo + (b + 1) * width
}

/// One segment's mean periodogram in each band (`x` of [`SEGMENT`] values).
fn band_means(x: &[f64]) -> [f64; BANDS] {
    let n = x.len();
    // Detrended (a least-squares line), Hann-windowed.
    let mid = (n as f64 - 1.0) / 2.0;
    let mean = x.iter().sum::<f64>() / n as f64;
    let sxx: f64 = (0..n).map(|i| (i as f64 - mid).powi(2)).sum();
    let slope = x
        .iter()
        .enumerate()
        .map(|(i, v)| (i as f64 - mid) * (v - mean))
        .sum::<f64>()
        / sxx;
    let mut re = vec![0.0; n];
    let mut im = vec![0.0; n];
    let mut sum_w2 = 0.0;
    for (i, v) in x.iter().enumerate() {
        let w = 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos();
        re[i] = w * (v - mean - slope * (i as f64 - mid));
        sum_w2 += w * w;
    }
    // One plan of a segment's transform for every segment of the run.
    static PLAN: std::sync::OnceLock<Fft> = std::sync::OnceLock::new();
    PLAN.get_or_init(|| Fft::new(SEGMENT)).run(&mut re, &mut im);
    std::array::from_fn(|b| {
        let r = band_range(b);
        let len = r.len() as f64;
        r.map(|k| (re[k] * re[k] + im[k] * im[k]) / sum_w2)
            .sum::<f64>()
            / len
    })
}

/// The discrete Fourier transform in place, X_k = sum_j x_j exp(-2 pi i j k / n), n a power
/// of two (iterative radix 2).
pub fn fft(re: &mut [f64], im: &mut [f64]) {
    Fft::new(re.len()).run(re, im);
}

/// An [`fft`] of one power-of-two length planned once: its bit reversal and its twiddles,
/// for a length transformed many times (the filter's blocks, [`super::filter`]).
#[derive(Clone, Debug)]
pub struct Fft {
    /// exp(-2 pi i k / n) for k below n / 2, as (sin, cos).
    twiddles: Vec<(f64, f64)>,
    /// The index pairs the bit reversal swaps.
    swaps: Vec<(u32, u32)>,
}

impl Fft {
    /// The plan for length `n`, a power of two.
    pub fn new(n: usize) -> Self {
        debug_assert!(n.is_power_of_two());
        let angle = -std::f64::consts::TAU / n as f64;
        let twiddles = (0..n / 2).map(|k| (angle * k as f64).sin_cos()).collect();
        let mut swaps = Vec::new();
        let mut j = 0;
        for i in 1..n {
            let mut bit = n >> 1;
            while j & bit != 0 {
                j ^= bit;
                bit >>= 1;
            }
            j |= bit;
            if i < j {
                swaps.push((i as u32, j as u32));
            }
        }
        Fft { twiddles, swaps }
    }

    /// The transform of (`re`, `im`) in place, both of the planned length.
    pub fn run(&self, re: &mut [f64], im: &mut [f64]) {
        let n = 2 * self.twiddles.len();
        debug_assert!(re.len() == n.max(1) && im.len() == re.len());
        for &(i, j) in &self.swaps {
            re.swap(i as usize, j as usize);
            im.swap(i as usize, j as usize);
        }
        let mut len = 2;
        while len <= n {
            let (half, stride) = (len / 2, n / len);
            for start in (0..n).step_by(len) {
                let (lo_re, hi_re) = re[start..start + len].split_at_mut(half);
                let (lo_im, hi_im) = im[start..start + len].split_at_mut(half);
                for k in 0..half {
                    let (s, c) = self.twiddles[k * stride];
                    let tr = hi_re[k] * c - hi_im[k] * s;
                    let ti = hi_re[k] * s + hi_im[k] * c;
                    hi_re[k] = lo_re[k] - tr;
                    hi_im[k] = lo_im[k] - ti;
                    lo_re[k] += tr;
                    lo_im[k] += ti;
                }
            }
            len <<= 1;
        }
    }
}

/// The discrete Fourier transform of a series of any length n, X_k = sum_j x_j exp(-2 pi i
/// j k / n), as (re, im): Bluestein's chirp, its convolution through [`fft`] at the next
/// power of two of 2n - 1 (a power of two itself goes to [`fft`] straight).
pub fn dft(x_re: &[f64], x_im: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = x_re.len();
    debug_assert_eq!(x_im.len(), n);
    if n.is_power_of_two() || n == 0 {
        let (mut re, mut im) = (x_re.to_vec(), x_im.to_vec());
        fft(&mut re, &mut im);
        return (re, im);
    }
    // w_k = exp(-i pi k^2 / n), k^2 taken modulo 2n so the angle stays exact.
    let chirp: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            let k2 = (k as u128 * k as u128 % (2 * n as u128)) as f64;
            let (s, c) = (-std::f64::consts::PI * k2 / n as f64).sin_cos();
            (c, s)
        })
        .collect();
    let m = (2 * n - 1).next_power_of_two();
    let (mut a_re, mut a_im) = (vec![0.0; m], vec![0.0; m]);
    let (mut b_re, mut b_im) = (vec![0.0; m], vec![0.0; m]);
    for (k, &(c, s)) in chirp.iter().enumerate() {
        a_re[k] = x_re[k] * c - x_im[k] * s;
        a_im[k] = x_re[k] * s + x_im[k] * c;
        b_re[k] = c;
        b_im[k] = -s;
        if k > 0 {
            b_re[m - k] = c;
            b_im[m - k] = -s;
        }
    }
    fft(&mut a_re, &mut a_im);
    fft(&mut b_re, &mut b_im);
    // The product, conjugated, transformed and conjugated again: the inverse transform.
    for k in 0..m {
        let (re, im) = (
            a_re[k] * b_re[k] - a_im[k] * b_im[k],
            a_re[k] * b_im[k] + a_im[k] * b_re[k],
        );
        a_re[k] = re;
        a_im[k] = -im;
    }
    fft(&mut a_re, &mut a_im);
    chirp
        .iter()
        .enumerate()
        .map(|(k, &(c, s))| {
            let (re, im) = (a_re[k] / m as f64, -a_im[k] / m as f64);
            (re * c - im * s, re * s + im * c)
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transform_of_any_length_is_the_sum() {
        for n in [1_usize, 3, 13, 100, 1001] {
            let x: Vec<f64> = (0..n).map(|i| ((i * 7) % 5) as f64 - 1.3).collect();
            let y: Vec<f64> = (0..n).map(|i| ((i * 3) % 4) as f64 * 0.5).collect();
            let (re, im) = dft(&x, &y);
            for k in (0..n).step_by(1 + n / 17) {
                let (mut r, mut i) = (0.0, 0.0);
                for j in 0..n {
                    let a = -std::f64::consts::TAU * ((j * k) % n) as f64 / n as f64;
                    r += x[j] * a.cos() - y[j] * a.sin();
                    i += x[j] * a.sin() + y[j] * a.cos();
                }
                let scale = 1.0 + r.abs() + i.abs();
                assert!(
                    (re[k] - r).abs() < 1e-9 * scale && (im[k] - i).abs() < 1e-9 * scale,
                    "{n} {k}: {} {} against {r} {i}",
                    re[k],
                    im[k]
                );
            }
        }
    }

    struct Normal(u64);
    impl Normal {
        fn next(&mut self) -> f64 {
            let mut u = || {
                self.0 = self
                    .0
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (u1, u2) = (u(), u());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    #[test]
    fn the_transform_is_the_sum() {
        let x: Vec<f64> = (0..16).map(|i| f64::from((i * 7) % 5) - 1.3).collect();
        let (mut re, mut im) = (x.clone(), vec![0.0; 16]);
        fft(&mut re, &mut im);
        for k in 0..16 {
            let (mut r, mut i) = (0.0, 0.0);
            for (j, v) in x.iter().enumerate() {
                let a = -std::f64::consts::TAU * (j * k) as f64 / 16.0;
                r += v * a.cos();
                i += v * a.sin();
            }
            assert!(
                (re[k] - r).abs() < 1e-12 && (im[k] - i).abs() < 1e-12,
                "{k}"
            );
        }
    }

    /// White noise alone, and the same under a swell of 600 times its sd at 10 s sampled at
    /// 1 Hz (the marine meter's record): both measure the noise within a few percent, where
    /// the third differences read the swell.
    #[test]
    fn a_swell_does_not_pass_for_noise() {
        for (seconds, tol) in [(1001usize, 0.15), (20_000, 0.03)] {
            let mut rng = Normal(5);
            let (mut quiet, mut swell) = (
                SpectralFloor::new(1_000_000_000),
                SpectralFloor::new(1_000_000_000),
            );
            let mut third = super::super::epochs::ThirdDifferences::new(1_000_000_000);
            for k in 0..seconds {
                let t = k as i64 * 1_000_000_000;
                let e = 2.0 * rng.next();
                let s = 1200.0 * (std::f64::consts::TAU * k as f64 / 10.0 + 0.3).sin()
                    + 400.0 * (std::f64::consts::TAU * k as f64 / 13.0).sin();
                quiet.push(t, e);
                swell.push(t, e + s);
                third.push(t, e + s);
            }
            for (name, f) in [("quiet", &quiet), ("swell", &swell)] {
                let floor = f.floor();
                assert!(
                    matches!(floor, Floor::Measured(v) if (v / 2.0 - 1.0).abs() < tol),
                    "{seconds} s {name}: {floor:?}"
                );
            }
            assert!(third.sd() > 20.0, "third differences {}", third.sd());
        }
    }

    /// A knock (one segment a thousand times louder) and a vibration in one band do not
    /// raise the floor.
    #[test]
    fn a_knock_and_a_vibration_are_left_out() {
        let mut rng = Normal(9);
        let mut f = SpectralFloor::new(10);
        for k in 0..100_000usize {
            let knock = if (50_000..50_200).contains(&k) {
                1000.0
            } else {
                0.0
            };
            // At 0.35 of the sampling rate, in the last band.
            let vibration = 30.0 * (std::f64::consts::TAU * 0.35 * k as f64).sin();
            f.push(k as i64 * 10, rng.next() * (1.0 + knock) + vibration);
        }
        let floor = f.floor();
        assert!(
            matches!(floor, Floor::Measured(v) if (v - 1.0).abs() < 0.03),
            "{floor:?}"
        );
    }

    /// A real record (shipgrav's DGS AT1M test file, fixtures/real/shipgrav-dgs): the
    /// meter's own filter makes its 1 Hz spectrum fall by orders of magnitude across the
    /// upper band, so no floor is measured, where the third differences read its swell (the
    /// 6.65 mGal of noise the 100 s filter was said to pass) and the lowest band alone
    /// would claim almost none. The same swell-free fall filtered white noise shows, and
    /// white noise added back under it gives its floor again.
    #[test]
    fn a_record_its_meter_filtered_has_no_floor() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../fixtures/real/shipgrav-dgs/DGStest_laptop.dat"
        );
        let text = std::fs::read_to_string(path).expect(path);
        let rgrav: Vec<f64> = text
            .lines()
            .map(|l| {
                l.split(',')
                    .nth(1)
                    .expect("column 2")
                    .trim()
                    .parse()
                    .expect("mGal")
            })
            .collect();
        assert_eq!(rgrav.len(), 1001);
        let (mut real, mut with_noise) = (
            SpectralFloor::new(1_000_000_000),
            SpectralFloor::new(1_000_000_000),
        );
        let mut third = super::super::epochs::ThirdDifferences::new(1_000_000_000);
        let mut rng = Normal(3);
        for (k, v) in rgrav.iter().enumerate() {
            let t = k as i64 * 1_000_000_000;
            real.push(t, *v);
            third.push(t, *v);
            with_noise.push(t, v + 10.0 * rng.next());
        }
        let floor = real.floor();
        let Floor::NotFlat { band_sd, segments } = &floor else {
            panic!("the DGS record's floor: {floor:?}")
        };
        eprintln!(
            "DGS record: bands' sd {band_sd:.3?} mGal over {segments} segments; third \
             differences {:.1} mGal",
            third.sd()
        );
        assert!(band_sd[0] > 100.0 * band_sd[BANDS - 1], "{band_sd:?}");
        assert!(third.sd() > 20.0, "{}", third.sd());
        let floor = with_noise.floor();
        assert!(
            matches!(floor, Floor::Measured(v) if (v / 10.0 - 1.0).abs() < 0.3),
            "10 mGal of white noise under the record: {floor:?}"
        );
    }
}
