//! The zero-phase low-pass filters of the gravity stage ([`Lowpass`], `[survey] filter`),
//! each with its amplitude response 0.5 at the cut-off f_c = 1 / `filter_s`:
//!
//! - Butterworth of order [`ORDER`] run forward and backward (scipy.signal's `sosfiltfilt`:
//!   odd extension at both ends, each pass started from its steady state). Run twice, its
//!   response is |H(f)|^2 = 1 / (1 + (f / f_c)^(2n)), and no phase at all. Designed as
//!   scipy's `butter` designs it (the analog prototype's poles, the cut-off pre-warped, the
//!   bilinear transform), in second-order sections.
//! - Windowed-sinc FIRs (Blackman, Hamming: scipy's `firwin`) of 2 P + 1 taps, P the cut-off
//!   period in samples, their sinc's cut-off set so that the response is 0.5 at f_c; and a
//!   Gaussian kernel of sd sqrt(ln 2 / 2) / (pi f_c), truncated at four sds (NAVO's and
//!   LDEO's filter). Each is symmetric and applied once, centred: zero phase, its response
//!   the kernel's real transform.
//!
//! No I/O.

use super::GravityError;
use ingest::contract::survey::FilterKind;

/// A zero-phase low-pass filter, designed for a cut-off period and a sampling rate.
#[derive(Clone, Debug, PartialEq)]
pub enum Lowpass {
    /// Butterworth sections, run forward and backward.
    Butterworth(Vec<Section>),
    /// A symmetric kernel of odd length, applied once, centred.
    Kernel(Vec<f64>),
}

/// A low-pass as a stretch's series take it ([`Lowpass::apply`]): the stretch's ends
/// extended by `pad` samples reflected through the Hann-weighted mean of `pivot` samples.
#[derive(Clone, Debug)]
pub struct StretchFilter {
    /// The low-pass.
    pub lowpass: Lowpass,
    /// Samples added at each end.
    pub pad: usize,
    /// Samples whose mean the reflection pivots on.
    pub pivot: usize,
}

impl StretchFilter {
    /// `x` filtered.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        self.lowpass.apply(x, self.pad, self.pivot)
    }
}

impl Lowpass {
    /// `kind` with its response 0.5 at `cutoff_hz`, for samples at `rate_hz`.
    pub fn design(kind: FilterKind, cutoff_hz: f64, rate_hz: f64) -> Result<Self, GravityError> {
        if !(cutoff_hz > 0.0 && cutoff_hz < rate_hz / 2.0) {
            return Err(GravityError::Filter(format!(
                "a cut-off of {cutoff_hz} Hz at {rate_hz} Hz: it must lie in (0, {}) Hz (the \
                 filter period longer than two sample intervals)",
                rate_hz / 2.0
            )));
        }
        let period = rate_hz / cutoff_hz;
        Ok(match kind {
            FilterKind::Butterworth => {
                Lowpass::Butterworth(butterworth(ORDER, cutoff_hz, rate_hz)?)
            }
            FilterKind::Gaussian => Lowpass::Kernel(gaussian(period)),
            FilterKind::Blackman | FilterKind::Hamming => {
                Lowpass::Kernel(windowed_sinc(kind, period))
            }
        })
    }

    /// `x` filtered, its ends extended by `pad` samples (at least the kernel's half length)
    /// reflected through the Hann-weighted mean of `pivot` samples ([`filtfilt_pivoted`]).
    pub fn apply(&self, x: &[f64], pad: usize, pivot: usize) -> Vec<f64> {
        match self {
            Lowpass::Butterworth(sections) => filtfilt_pivoted(sections, x, pad, pivot),
            Lowpass::Kernel(h) => {
                let half = h.len() / 2;
                let (ext, _) = extended(x, pad.max(half), pivot);
                let pad = pad.max(half).min(x.len().saturating_sub(1));
                let whole: f64 = h.iter().sum();
                // The kernel whole within the extension (every sample of a series longer
                // than it) from the window starting at `from`: a dot product.
                let whole_at = |i: usize| {
                    (i + pad)
                        .checked_sub(half)
                        .filter(|from| from + h.len() <= ext.len())
                };
                let mut out = Vec::with_capacity(x.len());
                // The run of samples whose kernel is whole, through the FFT where it is
                // long ([`correlate_fft`]).
                let run = (0..x.len()).find(|&i| whole_at(i).is_some()).map(|first| {
                    let last = (first..x.len()).rfind(|&i| whole_at(i).is_some());
                    first..last.map_or(first, |l| l + 1)
                });
                let by_fft = run.filter(|r| h.len() >= FFT_FROM_TAPS && r.len() >= 4 * h.len());
                while out.len() < x.len() {
                    let i = out.len();
                    if let Some(r) = by_fft.as_ref().filter(|r| r.start == i) {
                        let from = whole_at(i).expect("whole");
                        out.extend(correlate_fft(h, &ext, from, r.len()).map(|v| v / whole));
                        continue;
                    }
                    match (whole_at(i), whole_at(i + 3)) {
                        (Some(from), Some(_)) if i + 3 < x.len() => {
                            out.extend(dot4(h, &ext, from).map(|v| v / whole));
                        }
                        (Some(from), _) => out.push(dot(h, &ext[from..from + h.len()]) / whole),
                        _ => out.push(cut_kernel(h, &ext, i + pad)),
                    }
                }
                out
            }
        }
    }

    /// The zero-phase amplitude response at `f_hz` for samples at `rate_hz`: Butterworth's
    /// |H|^2 (two passes), a kernel's real transform.
    pub fn response(&self, f_hz: f64, rate_hz: f64) -> f64 {
        match self {
            Lowpass::Butterworth(sections) => response(sections, f_hz, rate_hz),
            Lowpass::Kernel(h) => kernel_response(h, f_hz / rate_hz),
        }
    }
}

/// The kernel `h` at sample `centre` of `ext`, where the extension is shorter than the
/// kernel (a series shorter than it): the kernel is cut there and its rest weighs to 1.
fn cut_kernel(h: &[f64], ext: &[f64], centre: usize) -> f64 {
    let half = h.len() / 2;
    let (sum, weight) = h
        .iter()
        .enumerate()
        .filter_map(|(k, c)| {
            ext.get((centre + k).checked_sub(half)?)
                .map(|v| (c * v, *c))
        })
        .fold((0.0, 0.0), |(s, w), (a, b)| (s + a, w + b));
    sum / weight
}

/// Kernels of this many taps or more are applied through the FFT where the series is
/// long: a 240 s kernel at 1 Hz (481 taps) took a tenth of a day's reduction as dot
/// products.
const FFT_FROM_TAPS: usize = 64;

/// y_j = sum_k h_k x_(j + k) for j in `from..from + count` (every window within `x`), by
/// overlap-save through the FFT: blocks of a power of two about eight kernels long, two
/// at a time as one complex series (the kernel is real: the real part of their transform's
/// product gives the first block's sums, the imaginary the second's). The series' mean
/// is taken out first and its sum added back, so the transform's rounding is relative to
/// the series' variation, not to its level (a specific force of 980 000 mGal): within
/// 1e-14 of that level of the dot products' sums in the test, their own rounding there.
fn correlate_fft(h: &[f64], x: &[f64], from: usize, count: usize) -> impl Iterator<Item = f64> {
    let l = h.len();
    let m = (8 * l).next_power_of_two();
    let step = m - l + 1;
    let plan = super::spectrum::Fft::new(m);
    let span = &x[from..from + count + l - 1];
    let level = span.iter().sum::<f64>() / span.len() as f64;
    let weight: f64 = h.iter().sum();
    // The kernel reversed: the circular convolution with it is the correlation with h.
    let (mut k_re, mut k_im) = (vec![0.0; m], vec![0.0; m]);
    for (k, v) in h.iter().rev().enumerate() {
        k_re[k] = *v;
    }
    plan.run(&mut k_re, &mut k_im);
    let mut y = Vec::with_capacity(count + 2 * step);
    let (mut re, mut im) = (vec![0.0; m], vec![0.0; m]);
    let block = |buf: &mut [f64], start: usize| {
        for (k, b) in buf.iter_mut().enumerate() {
            *b = span.get(start + k).map_or(0.0, |v| v - level);
        }
    };
    let mut start = 0;
    while start < count {
        block(&mut re, start);
        block(&mut im, start + step);
        plan.run(&mut re, &mut im);
        // The product, conjugated: transformed again and conjugated, the inverse.
        for k in 0..m {
            let (a, b) = (re[k], im[k]);
            re[k] = a * k_re[k] - b * k_im[k];
            im[k] = -(a * k_im[k] + b * k_re[k]);
        }
        plan.run(&mut re, &mut im);
        let scale = 1.0 / m as f64;
        y.extend(re[l - 1..].iter().map(|v| v * scale + level * weight));
        y.extend(im[l - 1..].iter().map(|v| -v * scale + level * weight));
        start += 2 * step;
    }
    y.truncate(count);
    y.into_iter()
}

/// [`dot`] of `h` with the four windows of `x` starting at `from` to `from + 3`, each
/// summed as [`dot`] sums it (the same products in the same order: bit for bit its
/// value), the four windows' sums interleaved so that none waits on its own last addition.
fn dot4(h: &[f64], x: &[f64], from: usize) -> [f64; 4] {
    let n = h.len();
    let body = n - n % 4;
    let [w0, w1, w2, w3]: [&[f64]; 4] = std::array::from_fn(|j| &x[from + j..from + j + n]);
    let mut s = [[0.0; 4]; 4];
    let chunks = h[..body]
        .chunks_exact(4)
        .zip(w0[..body].chunks_exact(4))
        .zip(w1[..body].chunks_exact(4))
        .zip(w2[..body].chunks_exact(4))
        .zip(w3[..body].chunks_exact(4));
    for ((((c, a), b), d), e) in chunks {
        for k in 0..4 {
            s[0][k] += c[k] * a[k];
            s[1][k] += c[k] * b[k];
            s[2][k] += c[k] * d[k];
            s[3][k] += c[k] * e[k];
        }
    }
    let windows = [w0, w1, w2, w3];
    std::array::from_fn(|j| {
        let tail: f64 = h[body..]
            .iter()
            .zip(&windows[j][body..])
            .map(|(x, y)| x * y)
            .sum();
        (s[j][0] + s[j][1]) + (s[j][2] + s[j][3]) + tail
    })
}

/// The dot product of `a` and `b` (of one length) in four interleaved sums, which the
/// compiler keeps in vector registers: a 240 s kernel at 1 Hz over a day's epochs took a
/// quarter of the stage's time summed one product at a time.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            s[k] += x[k] * y[k];
        }
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// A symmetric kernel's transform at `cycles` per sample, about its centre.
fn kernel_response(h: &[f64], cycles: f64) -> f64 {
    let half = (h.len() / 2) as f64;
    h.iter()
        .enumerate()
        .map(|(k, c)| c * (std::f64::consts::TAU * cycles * (k as f64 - half)).cos())
        .sum()
}

/// The Gaussian kernel's sd, samples, whose transform is 0.5 at one cycle per `period`
/// samples: exp(-2 pi^2 sd^2 f^2) = 0.5.
pub fn gaussian_sd(period: f64) -> f64 {
    (std::f64::consts::LN_2 / 2.0).sqrt() * period / std::f64::consts::PI
}

/// The Gaussian kernel of sd [`gaussian_sd`], truncated at four sds, its sum 1.
fn gaussian(period: f64) -> Vec<f64> {
    let sd = gaussian_sd(period);
    let half = (4.0 * sd).ceil() as i64;
    let h: Vec<f64> = (-half..=half)
        .map(|k| (-0.5 * (k as f64 / sd).powi(2)).exp())
        .collect();
    let sum: f64 = h.iter().sum();
    h.into_iter().map(|v| v / sum).collect()
}

/// scipy's `firwin(taps, cutoff, window)` with its cut-off in cycles per sample: the sinc
/// times the symmetric window, its sum 1.
pub fn firwin(taps: usize, cutoff: f64, kind: FilterKind) -> Vec<f64> {
    let alpha = 0.5 * (taps as f64 - 1.0);
    let m = (taps - 1).max(1) as f64;
    let tau = std::f64::consts::TAU;
    let h: Vec<f64> = (0..taps)
        .map(|n| {
            let x = n as f64 - alpha;
            let arg = 2.0 * cutoff * x;
            let sinc = if arg == 0.0 {
                1.0
            } else {
                (std::f64::consts::PI * arg).sin() / (std::f64::consts::PI * arg)
            };
            let phase = tau * n as f64 / m;
            let w = match kind {
                FilterKind::Hamming => 0.54 - 0.46 * phase.cos(),
                _ => 0.42 - 0.5 * phase.cos() + 0.08 * (2.0 * phase).cos(),
            };
            2.0 * cutoff * sinc * w
        })
        .collect();
    let sum: f64 = h.iter().sum();
    h.into_iter().map(|v| v / sum).collect()
}

/// The windowed sinc whose response is 0.5 at one cycle per `period` samples: 2 P + 1 taps
/// (P = `period`, rounded) and the sinc's cut-off (cycles per sample) found by bisection
/// (within 2 % of 1 / period for either window); [`firwin`] of these is the kernel.
pub fn windowed_sinc_design(kind: FilterKind, period: f64) -> (usize, f64) {
    let taps = 2 * (period.round() as usize).max(1) + 1;
    let f_c = 1.0 / period;
    let (mut lo, mut hi) = (0.5 * f_c, (2.0 * f_c).min(0.5));
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if kernel_response(&firwin(taps, mid, kind), f_c) < 0.5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (taps, 0.5 * (lo + hi))
}

fn windowed_sinc(kind: FilterKind, period: f64) -> Vec<f64> {
    let (taps, cutoff) = windowed_sinc_design(kind, period);
    firwin(taps, cutoff, kind)
}

/// `x` extended by `pad` samples at each end (at most its length less one), reflected
/// through the Hann-weighted mean of its first and last `pivot` samples; and the first.
fn extended(x: &[f64], pad: usize, pivot: usize) -> (Vec<f64>, f64) {
    let n = x.len();
    let pad = pad.min(n.saturating_sub(1));
    let pivot = pivot.clamp(1, n);
    let (p0, p1) = (hann_mean(&x[..pivot]), hann_mean(&x[n - pivot..]));
    let mut ext = Vec::with_capacity(n + 2 * pad);
    ext.extend((1..=pad).rev().map(|i| 2.0 * p0 - x[i]));
    ext.extend_from_slice(x);
    ext.extend((1..=pad).map(|i| 2.0 * p1 - x[n - 1 - i]));
    (ext, p0)
}

/// The Butterworth order of one pass.
pub const ORDER: usize = 4;

/// One second-order section: numerator b0, b1, b2 and denominator 1, a1, a2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Section {
    /// Numerator.
    pub b: [f64; 3],
    /// Denominator a1, a2 (a0 = 1).
    pub a: [f64; 2],
}

/// A low-pass Butterworth filter of `order` with its -3 dB point (|H|^2 = 0.5 in one pass)
/// at `cutoff_hz`, for samples at `rate_hz`, as second-order sections.
pub fn butterworth(
    order: usize,
    cutoff_hz: f64,
    rate_hz: f64,
) -> Result<Vec<Section>, GravityError> {
    if order == 0 || !(cutoff_hz > 0.0 && cutoff_hz < rate_hz / 2.0) {
        return Err(GravityError::Filter(format!(
            "a cut-off of {cutoff_hz} Hz at {rate_hz} Hz: it must lie in (0, {}) Hz (the filter \
             period longer than two sample intervals)",
            rate_hz / 2.0
        )));
    }
    let k = 2.0 * rate_hz;
    // The cut-off pre-warped, so that the digital filter's is exactly cutoff_hz.
    let wo = k * (std::f64::consts::PI * cutoff_hz / rate_hz).tan();
    let mut sections = Vec::new();
    for m in 0..order / 2 {
        // A conjugate pair of the prototype's poles, scaled to wo: p = wo exp(i theta).
        let theta = std::f64::consts::PI * (2 * m + order + 1) as f64 / (2 * order) as f64;
        let re = wo * theta.cos();
        let mag2 = wo * wo;
        let a0 = k * k - 2.0 * re * k + mag2;
        let g = mag2 / a0;
        sections.push(Section {
            b: [g, 2.0 * g, g],
            a: [
                (2.0 * mag2 - 2.0 * k * k) / a0,
                (k * k + 2.0 * re * k + mag2) / a0,
            ],
        });
    }
    if order % 2 == 1 {
        let a0 = k + wo;
        sections.push(Section {
            b: [wo / a0, wo / a0, 0.0],
            a: [(wo - k) / a0, 0.0],
        });
    }
    Ok(sections)
}

/// Runs `sections` over `x` in place, from the states `z` (direct form II transposed).
fn run(sections: &[Section], z: &mut [[f64; 2]], x: &mut [f64]) {
    for v in x.iter_mut() {
        let mut s = *v;
        for (sec, z) in sections.iter().zip(z.iter_mut()) {
            let y = sec.b[0] * s + z[0];
            z[0] = sec.b[1] * s - sec.a[0] * y + z[1];
            z[1] = sec.b[2] * s - sec.a[1] * y;
            s = y;
        }
        *v = s;
    }
}

/// The sections' states in the steady state of a unit step (scipy's `sosfilt_zi`).
fn steady_state(sections: &[Section]) -> Vec<[f64; 2]> {
    let mut scale = 1.0;
    sections
        .iter()
        .map(|s| {
            let [b0, b1, b2] = s.b;
            let [a1, a2] = s.a;
            let (r0, r1) = (b1 - a1 * b0, b2 - a2 * b0);
            let z0 = (r0 + r1) / (1.0 + a1 + a2);
            let z = [scale * z0, scale * (r1 - a2 * z0)];
            scale *= (b0 + b1 + b2) / (1.0 + a1 + a2);
            z
        })
        .collect()
}

/// Samples each end is extended by (scipy's default `padlen` for `sections`).
pub fn pad_length(sections: &[Section]) -> usize {
    let zero_b2 = sections.iter().filter(|s| s.b[2] == 0.0).count();
    let zero_a2 = sections.iter().filter(|s| s.a[1] == 0.0).count();
    3 * (2 * sections.len() + 1 - zero_b2.min(zero_a2))
}

/// `x` filtered forward and backward through `sections`: zero phase, the response squared.
/// The series must be longer than [`pad_length`].
pub fn filtfilt(sections: &[Section], x: &[f64]) -> Result<Vec<f64>, GravityError> {
    let pad = pad_length(sections);
    if x.len() <= pad {
        return Err(GravityError::Filter(format!(
            "{} samples: the filter needs more than {pad} (a stretch longer than about three \
             filter periods)",
            x.len()
        )));
    }
    let n = x.len();
    // Odd extension: the series reflected through its end values.
    let mut ext = Vec::with_capacity(n + 2 * pad);
    ext.extend((1..=pad).rev().map(|i| 2.0 * x[0] - x[i]));
    ext.extend_from_slice(x);
    ext.extend((1..=pad).map(|i| 2.0 * x[n - 1] - x[n - 1 - i]));
    let zi = steady_state(sections);
    let start = |v: f64| zi.iter().map(|z| [z[0] * v, z[1] * v]).collect::<Vec<_>>();
    let mut z = start(ext[0]);
    run(sections, &mut z, &mut ext);
    ext.reverse();
    let mut z = start(ext[0]);
    run(sections, &mut z, &mut ext);
    ext.reverse();
    Ok(ext[pad..pad + n].to_vec())
}

/// A Hann-weighted mean of `x` (the window zero at both ends of `x`): a level whose noise,
/// for second differences of white positions, does not telescope into the end values as a
/// plain mean's does.
fn hann_mean(x: &[f64]) -> f64 {
    let n = x.len();
    if n < 3 {
        return x.iter().sum::<f64>() / n.max(1) as f64;
    }
    let w = |k: usize| 1.0 - (2.0 * std::f64::consts::PI * k as f64 / (n - 1) as f64).cos();
    let total: f64 = (0..n).map(w).sum();
    (0..n).map(|k| w(k) * x[k]).sum::<f64>() / total
}

/// `x` filtered forward and backward through `sections`, for series dominated by noise at
/// their ends (a gravity stretch's unfiltered values: second differences of positions with
/// cm noise, hundreds of Gal an epoch). scipy's odd extension reflects the series through
/// its end VALUE and starts the filter in the steady state of one noisy sample, leaving a
/// transient of hundreds of mGal for several filter periods. Here each end's pivot is the
/// Hann-weighted mean of its first `pivot` samples, `pad` samples are reflected through it
/// (an odd extension about a smooth level, so that a disturbance changing at the end
/// continues), and each pass starts in the steady state of that level: the forward pass at
/// the head's pivot, the backward at the forward pass's last output. `pad` is at most
/// `x.len() - 1`.
pub fn filtfilt_pivoted(sections: &[Section], x: &[f64], pad: usize, pivot: usize) -> Vec<f64> {
    let pad = pad.min(x.len().saturating_sub(1));
    let (mut ext, p0) = extended(x, pad, pivot);
    let zi = steady_state(sections);
    let start = |v: f64| zi.iter().map(|z| [z[0] * v, z[1] * v]).collect::<Vec<_>>();
    let mut z = start(p0);
    run(sections, &mut z, &mut ext);
    ext.reverse();
    let mut z = start(ext[0]);
    run(sections, &mut z, &mut ext);
    ext.reverse();
    ext[pad..pad + x.len()].to_vec()
}

/// The zero-phase response |H(f)|^2 of `sections` at `f_hz` for samples at `rate_hz`.
pub fn response(sections: &[Section], f_hz: f64, rate_hz: f64) -> f64 {
    let w = 2.0 * std::f64::consts::PI * f_hz / rate_hz;
    let (c1, s1, c2, s2) = (w.cos(), w.sin(), (2.0 * w).cos(), (2.0 * w).sin());
    sections
        .iter()
        .map(|s| {
            // H(e^{-iw}) = (b0 + b1 e^{-iw} + b2 e^{-2iw}) / (1 + a1 e^{-iw} + a2 e^{-2iw}).
            let num =
                (s.b[0] + s.b[1] * c1 + s.b[2] * c2).powi(2) + (s.b[1] * s1 + s.b[2] * s2).powi(2);
            let den =
                (1.0 + s.a[0] * c1 + s.a[1] * c2).powi(2) + (s.a[0] * s1 + s.a[1] * s2).powi(2);
            num / den
        })
        .product()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four windows at a time are each window's dot product bit for bit, for kernels of
    /// every length modulo 4; and a kernel applied gives, at every sample, the one-window
    /// dot product (or the cut kernel near a short series' ends).
    #[test]
    fn four_windows_at_a_time_are_one_at_a_time_bit_for_bit() {
        let mut rng = fixtures::rng::Rng::new(11, "dot4");
        let mut next = move || rng.uniform() - 0.5;
        let x: Vec<f64> = (0..2000).map(|_| next() * 1e3).collect();
        for n in [1, 2, 3, 4, 5, 7, 8, 13, 241, 481] {
            let h: Vec<f64> = (0..n).map(|_| next()).collect();
            for from in [0, 1, 17, 2000 - n - 3] {
                let four = dot4(&h, &x, from);
                for (j, v) in four.iter().enumerate() {
                    let one = dot(&h, &x[from + j..from + j + n]);
                    assert_eq!(v.to_bits(), one.to_bits(), "{n} taps from {from} + {j}");
                }
            }
        }
        for len in [5, 60, 700] {
            let kernel = Lowpass::Kernel((0..241u32).map(|k| 1.0 + f64::from(k % 7)).collect());
            let Lowpass::Kernel(h) = &kernel else {
                unreachable!()
            };
            let whole: f64 = h.iter().sum();
            let series = &x[..len];
            let (pad, pivot) = (100, 1);
            let got = kernel.apply(series, pad, pivot);
            let (ext, _) = extended(series, pad.max(120), pivot);
            let pad = pad.max(120).min(len - 1);
            for (i, v) in got.iter().enumerate() {
                let want = match (i + pad).checked_sub(120) {
                    Some(from) if from + 241 <= ext.len() => dot(h, &ext[from..from + 241]) / whole,
                    _ => cut_kernel(h, &ext, i + pad),
                };
                assert_eq!(v.to_bits(), want.to_bits(), "{len} samples, at {i}");
            }
        }
    }

    /// A long kernel over a long series goes through the FFT: each sample within 1e-14 of
    /// the series' level (a specific force's 980 000 mGal) of its dot product, whose own
    /// rounding at that level is of the same order (0.7 to 2.1e-9 mGal here); the ends' cut
    /// kernels as before.
    #[test]
    fn the_fft_gives_the_dot_products() {
        let mut rng = fixtures::rng::Rng::new(12, "fft");
        let x: Vec<f64> = (0..20_011)
            .map(|_| 980_000.0 + 1e3 * (rng.uniform() - 0.5))
            .collect();
        for taps in [64, 481, 1201] {
            let kernel = Lowpass::Kernel(windowed_sinc(FilterKind::Blackman, f64::from(taps / 2)));
            let Lowpass::Kernel(h) = &kernel else {
                unreachable!()
            };
            let half = h.len() / 2;
            let whole: f64 = h.iter().sum();
            let got = kernel.apply(&x, 0, 1);
            let (ext, _) = extended(&x, half, 1);
            let mut worst = 0.0_f64;
            for (i, v) in got.iter().enumerate() {
                // The extension is the kernel's half: the window of sample i starts at i.
                let want = if i + h.len() <= ext.len() {
                    dot(h, &ext[i..i + h.len()]) / whole
                } else {
                    cut_kernel(h, &ext, i + half)
                };
                worst = worst.max((v - want).abs());
            }
            eprintln!("{taps} taps: worst {worst:.3e} mGal");
            assert!(worst < 1e-14 * 980_000.0, "{taps} taps: {worst}");
        }
    }

    /// Run forward and backward, the response is 0.5 at the cut-off (the definition of
    /// `filter_s`), 1 at zero frequency, and small a decade above.
    #[test]
    fn half_power_at_the_cutoff() {
        for (order, rate, period) in [(4, 10.0, 100.0), (3, 1.0, 30.0), (4, 20.0, 60.0)] {
            let s = butterworth(order, 1.0 / period, rate).expect("filter");
            let at = |f: f64| response(&s, f, rate);
            assert!(
                (at(1.0 / period) - 0.5).abs() < 1e-9,
                "{order} {rate} {period}"
            );
            assert!((at(0.0) - 1.0).abs() < 1e-9, "{order} {rate} {period}");
            assert!(at(10.0 / period) < 1e-6);
        }
    }

    /// A constant passes unchanged, ends included (the steady-state start).
    #[test]
    fn a_constant_passes() {
        let s = butterworth(ORDER, 0.01, 1.0).expect("filter");
        let y = filtfilt(&s, &[3.5; 200]).expect("filtered");
        assert!(y.iter().all(|v| (v - 3.5).abs() < 1e-9), "{:?}", &y[..3]);
    }

    /// Every kind's response is 1 at zero frequency, 0.5 at the cut-off (the definition of
    /// `filter_s`; the Gaussian's to its sampling, 1e-3) and small two octaves above; and a
    /// constant passes every kind unchanged, ends included.
    #[test]
    fn every_kind_has_half_its_response_at_the_cutoff() {
        for kind in [
            FilterKind::Butterworth,
            FilterKind::Gaussian,
            FilterKind::Blackman,
            FilterKind::Hamming,
        ] {
            for (rate, period) in [(1.0, 30.0), (10.0, 100.0), (1.0, 240.0)] {
                let f = Lowpass::design(kind, 1.0 / period, rate).expect("filter");
                if matches!(kind, FilterKind::Blackman | FilterKind::Hamming) {
                    // The sinc's own cut-off within 2 % of the response's (docs/model.md 7).
                    let (_, cutoff) = windowed_sinc_design(kind, period * rate);
                    assert!(
                        (cutoff * period * rate - 1.0).abs() < 0.02,
                        "{kind:?}: {cutoff}"
                    );
                }
                let at = |x: f64| f.response(x / period, rate);
                let tolerance = if kind == FilterKind::Gaussian {
                    1e-3
                } else {
                    1e-9
                };
                assert!(
                    (at(1.0) - 0.5).abs() < tolerance,
                    "{kind:?} {period}: {}",
                    at(1.0)
                );
                assert!((at(0.0) - 1.0).abs() < 1e-9, "{kind:?}");
                assert!(at(4.0).abs() < 0.01, "{kind:?} {period}: {}", at(4.0));
                let y = f.apply(&[3.5; 400], 300, 30);
                assert!(y.iter().all(|v| (v - 3.5).abs() < 1e-9), "{kind:?}");
            }
        }
    }

    #[test]
    fn a_cutoff_beyond_nyquist_is_refused() {
        assert!(Lowpass::design(FilterKind::Blackman, 0.6, 1.0).is_err());
        assert!(butterworth(ORDER, 6.0, 10.0).is_err());
        let s = butterworth(ORDER, 0.1, 1.0).expect("filter");
        assert!(filtfilt(&s, &[0.0; 10]).is_err());
    }
}
