//! The noise-term selection's error rates (docs/model.md 6.2): how often a bias instability
//! or random walk is kept where the counts are white (false inclusion), and how often they
//! are found where they are there, on series shaped as align pools them (a tilt-table's
//! still intervals).

use align::allan::{fit_noise, octave_factors, pooled};
use fixtures::rng::Rng;

const TAU0_S: f64 = 0.032;

/// `intervals` still intervals of `len` samples: white noise of sd 10 counts plus a random
/// walk of `k` counts sqrt(Hz) running through them.
fn intervals(intervals: usize, len: usize, k: f64, rng: &mut Rng) -> Vec<Vec<f64>> {
    let mut walk = 0.0;
    (0..intervals)
        .map(|_| {
            (0..len)
                .map(|_| {
                    walk += k * TAU0_S.sqrt() * rng.normal();
                    walk + 10.0 * rng.normal()
                })
                .collect()
        })
        .collect()
}

/// Share of `replicas` whose fit kept a bias instability or a random walk.
fn kept(replicas: usize, n: usize, len: usize, k: f64, rng: &mut Rng) -> f64 {
    let mut count = 0;
    for _ in 0..replicas {
        let s = intervals(n, len, k, rng);
        let series: Vec<&[f64]> = s.iter().map(Vec::as_slice).collect();
        let points = pooled(&series, TAU0_S, &octave_factors(len));
        let fit = fit_noise(&points, &vec![len; n]);
        count += usize::from(fit.bias_instability > 0.0 || fit.random_walk > 0.0);
    }
    count as f64 / replicas as f64
}

/// White counts keep a coloured term in about 3 % of replicas (each term kept at 2
/// standard errors by a GLS that knows the Allan points' correlation), within 3
/// Monte-Carlo standard errors;
/// on the replica's design a random walk of 0.5 counts sqrt(Hz) under 10 counts of white
/// noise is found in at least 80 % of replicas. Printed for the record over shorter
/// designs, where the same walk is mostly out of reach.
#[test]
fn noise_terms_are_kept_at_their_stated_rate() {
    let replicas: usize = std::env::var("GRAVCAL_MONTE_CARLO").map_or(200, |_| 1000);
    let mut rng = Rng::new(20_261_124, "noise-selection");
    // A 3 % rate's Monte-Carlo standard error, printed beside each rate.
    let se = (0.03 * 0.97 / replicas as f64).sqrt();
    let mut rates = Vec::new();
    for (label, n, len) in [
        ("43 stations of 80 s (esgt-2005)", 43, 2500),
        ("10 stations of 30 s", 10, 940),
        ("100 stations of 10 s", 100, 312),
    ] {
        let white = kept(replicas, n, len, 0.0, &mut rng);
        let walk = kept(replicas, n, len, 0.5, &mut rng);
        eprintln!(
            "noise selection, {label}, {replicas} replicas: white counts keep a coloured term \
             in {white:.3} (se {se:.3}); a random walk of 0.5 counts sqrt(Hz) \
             found in {walk:.3}"
        );
        rates.push((label, white, walk));
    }
    // Two one-sided 2-se tests on correlated estimates: about 3 % together (measured with
    // 1000 replicas: 0.027, 0.025, 0.028; with the Allan points taken as independent it
    // was 0.073, 0.057, 0.052, rising with the design's length).
    let stated = 0.03;
    let bound = stated + 3.0 * (stated * (1.0 - stated) / replicas as f64).sqrt();
    for (label, white, _) in &rates {
        assert!(
            *white <= bound,
            "{label}: false inclusion {white} (bound {bound:.3})"
        );
    }
    // Power depends on the longest averaging time the stations allow (a tenth of one):
    // asserted on the replica's design only, printed for the short ones.
    assert!(rates[0].2 >= 0.8, "a random walk found in {}", rates[0].2);
}
