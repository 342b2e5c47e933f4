//! The zero-phase low-pass filter of the gravity stage: a Butterworth filter of order
//! [`ORDER`] run forward and backward (scipy.signal's `sosfiltfilt`: odd extension at both
//! ends, each pass started from its steady state). Run twice, its amplitude response is
//! |H(f)|^2 = 1 / (1 + (f / f_c)^(2n)): 0.5 at the cut-off f_c = 1 / `filter_s` whatever the
//! sampling, and no phase at all. Designed as scipy's `butter` designs it (the analog
//! prototype's poles, the cut-off pre-warped, the bilinear transform), in second-order
//! sections. No I/O.

use super::GravityError;

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
    let n = x.len();
    let pad = pad.min(n.saturating_sub(1));
    let pivot = pivot.clamp(1, n);
    let (p0, p1) = (hann_mean(&x[..pivot]), hann_mean(&x[n - pivot..]));
    let mut ext = Vec::with_capacity(n + 2 * pad);
    ext.extend((1..=pad).rev().map(|i| 2.0 * p0 - x[i]));
    ext.extend_from_slice(x);
    ext.extend((1..=pad).map(|i| 2.0 * p1 - x[n - 1 - i]));
    let zi = steady_state(sections);
    let start = |v: f64| zi.iter().map(|z| [z[0] * v, z[1] * v]).collect::<Vec<_>>();
    let mut z = start(p0);
    run(sections, &mut z, &mut ext);
    ext.reverse();
    let mut z = start(ext[0]);
    run(sections, &mut z, &mut ext);
    ext.reverse();
    ext[pad..pad + n].to_vec()
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

    #[test]
    fn a_cutoff_beyond_nyquist_is_refused() {
        assert!(butterworth(ORDER, 6.0, 10.0).is_err());
        let s = butterworth(ORDER, 0.1, 1.0).expect("filter");
        assert!(filtfilt(&s, &[0.0; 10]).is_err());
    }
}
