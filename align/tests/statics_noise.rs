//! A multi-position session's noise (docs/model.md 6.2 applied to static positions): white
//! noise leaves the positions' sigmas white; a random walk is found in the static intervals
//! and the sigma of an interval's mean then says how far apart the means of neighbouring
//! intervals fall, as the white sd over sqrt(n) does not.

use align::statics::{self, Series};
use fixtures::rng::Rng;

const TAU0_S: f64 = 0.032;
/// Samples of an interval: 20 s at 31.25 Hz.
const N: usize = 625;

/// `intervals` contiguous intervals of white noise of sd `white` plus a random walk of `k`
/// (units sqrt(Hz)), on every axis alike.
fn series(intervals: usize, white: f64, k: f64, rng: &mut Rng) -> Series {
    let mut s = Series::default();
    let mut walk = 0.0;
    for i in 0..intervals * N {
        walk += k * TAU0_S.sqrt() * rng.normal();
        s.time_ns.push((i as f64 * TAU0_S * 1e9).round() as i64);
        let v = walk + white * rng.normal();
        s.values.push([Some(v), Some(v), Some(v)]);
    }
    s
}

/// The predicted sd of each interval's mean (white part and coloured part, as align forms a
/// position's sigma), and the sd the neighbouring means show: sqrt(mean (m_k+1 - m_k)^2 / 2),
/// what the Allan variance at the interval's length is.
fn predicted_and_seen(s: &Series, intervals: usize) -> (f64, f64, statics::AxisNoise) {
    let spans: Vec<(usize, usize)> = (0..intervals).map(|i| (i * N, (i + 1) * N)).collect();
    let noise = statics::noise(s, &spans, TAU0_S)[0].clone().expect("noise");
    let means: Vec<([f64; 3], [f64; 3], u64)> = spans
        .iter()
        .map(|&span| statics::means(s, span).expect("means"))
        .collect();
    let duration = N as f64 * TAU0_S;
    let predicted = means
        .iter()
        .map(|m| m.1[0] * m.1[0] + noise.coloured_variance(duration))
        .sum::<f64>()
        / intervals as f64;
    let seen = means
        .windows(2)
        .map(|w| (w[1].0[0] - w[0].0[0]).powi(2) / 2.0)
        .sum::<f64>()
        / (intervals - 1) as f64;
    (predicted.sqrt(), seen.sqrt(), noise)
}

#[test]
fn white_noise_keeps_white_sigmas() {
    let mut rng = Rng::new(41, "statics/white");
    let s = series(300, 9.0, 0.0, &mut rng);
    let (predicted, seen, noise) = predicted_and_seen(&s, 300);
    eprintln!(
        "white: predicted {predicted:.4}, seen {seen:.4}, terms {:?}",
        noise.terms
    );
    // Dropped as not significant: exactly zero.
    assert!(noise.terms.random_walk == 0.0 && noise.terms.bias_instability == 0.0);
    // 299 differences: se of the sd ratio about 1/sqrt(2 * 299 / 1.5) = 0.05.
    assert!(
        (seen / predicted - 1.0).abs() < 0.15,
        "{}",
        seen / predicted
    );
}

#[test]
fn a_random_walk_widens_the_sigmas_to_what_the_means_show() {
    let mut rng = Rng::new(42, "statics/random-walk");
    let s = series(300, 9.0, 2.0, &mut rng);
    let (predicted, seen, noise) = predicted_and_seen(&s, 300);
    let white_only = statics::means(&s, (0, N)).expect("means").1[0];
    eprintln!(
        "random walk: predicted {predicted:.4}, seen {seen:.4}, white part {white_only:.4}, terms {:?}",
        noise.terms
    );
    assert!(noise.terms.random_walk > 0.0, "{:?}", noise.terms);
    // The white sd over sqrt(n) alone is far too small; the sigma with the coloured part
    // is what the means show.
    assert!(seen / white_only > 3.0, "{}", seen / white_only);
    assert!(
        (seen / predicted - 1.0).abs() < 0.25,
        "{}",
        seen / predicted
    );
}
