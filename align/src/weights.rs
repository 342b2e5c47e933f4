//! Station variances that borrow strength from the whole session (docs/model.md section 6.1):
//! each station's sample variance of Dz is shrunk toward the session's prior variance, with
//! prior degrees of freedom estimated from how much the station variances spread beyond what
//! their own sampling explains. This is the moderated variance of empirical Bayes (Smyth
//! 2004, "Linear models and empirical Bayes methods for assessing differential expression",
//! Stat. Appl. Genet. Mol. Biol. 3(1), section 6; limma's `squeezeVar`). No I/O.
//!
//! With `s_i^2` on `d_i` degrees of freedom: `e_i = ln s_i^2 - digamma(d_i/2) + ln(d_i/2)`;
//! the prior degrees of freedom `d0` solve `trigamma(d0/2) = var(e) - mean(trigamma(d_i/2))`
//! (infinite when the right side is not positive: the stations are alike, and all take the
//! pooled value), the prior variance is `s0^2 = exp(mean(e) + digamma(d0/2) - ln(d0/2))`, and
//! the moderated variance is `(d0 s0^2 + d_i s_i^2) / (d0 + d_i)`. A station of one reading
//! (`d_i = 0`) takes `s0^2`.

/// The session's prior and each station's moderated variance.
#[derive(Clone, Debug, PartialEq)]
pub struct Moderated {
    /// Prior variance s0^2.
    pub prior_variance: f64,
    /// Prior degrees of freedom d0 (infinite: every station takes the prior).
    pub prior_dof: f64,
    /// Moderated variance per station, in the order given.
    pub variances: Vec<f64>,
}

/// Moderates `(variance, degrees of freedom)` per station. Variances must be positive where
/// the degrees of freedom are (the caller floors them); `None` when no station has a
/// variance of its own.
pub fn moderate(stations: &[(f64, f64)]) -> Option<Moderated> {
    let own: Vec<(f64, f64)> = stations
        .iter()
        .copied()
        .filter(|&(v, d)| d > 0.0 && v > 0.0)
        .collect();
    if own.is_empty() {
        return None;
    }
    let e: Vec<f64> = own
        .iter()
        .map(|&(v, d)| v.ln() - digamma(d / 2.0) + (d / 2.0).ln())
        .collect();
    let g = e.len() as f64;
    let mean_e = e.iter().sum::<f64>() / g;
    let excess = if own.len() > 1 {
        e.iter().map(|x| (x - mean_e).powi(2)).sum::<f64>() / (g - 1.0)
            - own.iter().map(|&(_, d)| trigamma(d / 2.0)).sum::<f64>() / g
    } else {
        0.0
    };
    let (prior_dof, prior_variance) = if excess > 0.0 {
        let d0 = 2.0 * trigamma_inverse(excess);
        (d0, (mean_e + digamma(d0 / 2.0) - (d0 / 2.0).ln()).exp())
    } else {
        (f64::INFINITY, mean_e.exp())
    };
    let variances = stations
        .iter()
        .map(|&(v, d)| {
            if prior_dof.is_infinite() || d <= 0.0 {
                prior_variance
            } else {
                (prior_dof * prior_variance + d * v) / (prior_dof + d)
            }
        })
        .collect();
    Some(Moderated {
        prior_variance,
        prior_dof,
        variances,
    })
}

/// The digamma function, by recurrence up to 10 and the asymptotic series.
pub fn digamma(mut x: f64) -> f64 {
    let mut acc = 0.0;
    while x < 10.0 {
        acc -= 1.0 / x;
        x += 1.0;
    }
    let (x2, x4) = (x * x, x.powi(4));
    acc + x.ln() - 0.5 / x - 1.0 / (12.0 * x2) + 1.0 / (120.0 * x4) - 1.0 / (252.0 * x4 * x2)
        + 1.0 / (240.0 * x4 * x4)
        - 1.0 / (132.0 * x4 * x4 * x2)
}

/// The trigamma function, likewise.
pub fn trigamma(mut x: f64) -> f64 {
    let mut acc = 0.0;
    while x < 10.0 {
        acc += 1.0 / (x * x);
        x += 1.0;
    }
    acc + 1.0 / x + 1.0 / (2.0 * x * x) + 1.0 / (6.0 * x.powi(3)) - 1.0 / (30.0 * x.powi(5))
        + 1.0 / (42.0 * x.powi(7))
        - 1.0 / (30.0 * x.powi(9))
}

/// The tetragamma function (derivative of trigamma), likewise.
fn tetragamma(mut x: f64) -> f64 {
    let mut acc = 0.0;
    while x < 10.0 {
        acc -= 2.0 / x.powi(3);
        x += 1.0;
    }
    acc - 1.0 / (x * x) - 1.0 / x.powi(3) - 1.0 / (2.0 * x.powi(4)) + 1.0 / (6.0 * x.powi(6))
        - 1.0 / (6.0 * x.powi(8))
        + 3.0 / (10.0 * x.powi(10))
}

/// The y with trigamma(y) = x > 0, by Newton's method on 1/trigamma (as limma does).
fn trigamma_inverse(x: f64) -> f64 {
    if x > 1e7 {
        return 1.0 / x.sqrt();
    }
    if x < 1e-6 {
        return 1.0 / x;
    }
    let mut y = 0.5 + 1.0 / x;
    for _ in 0..50 {
        let tri = trigamma(y);
        let dif = tri * (1.0 - tri / x) / tetragamma(y);
        y += dif;
        if -dif / y < 1e-8 {
            break;
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn special_functions() {
        // digamma(1) = -Euler's gamma; trigamma(1) = pi^2/6; trigamma(1/2) = pi^2/2.
        assert!((digamma(1.0) + 0.577_215_664_901_532_9).abs() < 1e-12);
        assert!((trigamma(1.0) - std::f64::consts::PI.powi(2) / 6.0).abs() < 1e-12);
        assert!((trigamma(0.5) - std::f64::consts::PI.powi(2) / 2.0).abs() < 1e-11);
        for x in [0.3, 1.0, 4.0, 40.0] {
            assert!(
                (trigamma(trigamma_inverse(x)) / x - 1.0).abs() < 1e-7,
                "{x}"
            );
            let h = 1e-5;
            let numeric = (trigamma(x + h) - trigamma(x - h)) / (2.0 * h);
            assert!((tetragamma(x) / numeric - 1.0).abs() < 1e-6, "{x}");
        }
    }

    /// Stations that differ by far more than sampling explains keep most of their own
    /// variance; stations alike shrink to the pooled value.
    #[test]
    fn shrinks_by_how_much_stations_differ() {
        let spread: Vec<(f64, f64)> = (0..15_i32)
            .map(|i| ((1.0 + f64::from(i)).powi(2), 14.0))
            .collect();
        let m = moderate(&spread).expect("moderated");
        assert!(m.prior_dof.is_finite() && m.prior_dof < 14.0, "{m:?}");
        assert!(m.variances[0] < m.variances[14]);
        assert!(m.variances[14] < 225.0 && m.variances[0] > 1.0);

        // 15 stations of one true variance: sample variances scatter only as chi-square.
        let alike: Vec<(f64, f64)> = [
            0.8, 1.1, 0.9, 1.3, 0.7, 1.0, 1.2, 0.95, 1.05, 0.85, 1.15, 0.9, 1.1, 1.0, 0.75,
        ]
        .iter()
        .map(|&v| (v, 14.0))
        .collect();
        let m = moderate(&alike).expect("moderated");
        assert!(m.prior_dof > 50.0, "{m:?}");
        let (lo, hi) = m
            .variances
            .iter()
            .fold((f64::INFINITY, 0f64), |(a, b), &v| (a.min(v), b.max(v)));
        assert!(hi / lo < 1.2, "{lo} {hi}");

        // A station of one reading takes the prior.
        let mut with_one = spread.clone();
        with_one.push((0.0, 0.0));
        let m = moderate(&with_one).expect("moderated");
        assert!((m.variances[15] - m.prior_variance).abs() < 1e-12);
    }
}
