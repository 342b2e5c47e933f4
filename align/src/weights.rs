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

/// How far from its station's median a reading must lie, in robust sds, to be left out of
/// the other readings' left-out sigmas (see [`gross_readings`]).
pub const GROSS_READING_SDS: f64 = 10.0;

/// The readings of one station (`dz`, rad) so far from the others that they would mask
/// another blunder: each reading's w-test is referred to its station's sigma formed without
/// it, but a second blunder at the same station stays in that sigma and hides the first
/// (two readings 25 arcsec off among 15 each tested at w of about 3.1, under 3.29, and both
/// were kept, in a probe of adjust's per-session study not kept in the code). A reading more than [`GROSS_READING_SDS`] robust sds from the station's
/// median is left out of the other readings' sigmas as well (not out of its own, nor of
/// the station's). The robust sd is 1.4826 times the median absolute deviation, never below
/// `scale_floor` (the session's prior sd, or the resolution), so that a station whose
/// readings agree by chance does not flag its own good ones: without the floor, the median
/// absolute deviation of 14 readings is small by chance often enough to flag a good one in
/// 4.6e-4 of stations (`tests/gross_rule.rs`). Fewer than three readings: none.
pub fn gross_readings(dz: &[f64], scale_floor: f64) -> Vec<bool> {
    if dz.len() < 3 {
        return vec![false; dz.len()];
    }
    let median = |mut v: Vec<f64>| {
        v.sort_unstable_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let centre = median(dz.to_vec());
    let mad = median(dz.iter().map(|x| (x - centre).abs()).collect());
    let scale = (1.4826 * mad).max(scale_floor);
    dz.iter()
        .map(|x| (x - centre).abs() > GROSS_READING_SDS * scale)
        .collect()
}

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

    /// Two readings 25 arcsec off among fifteen within an arcsec are both gross (and each is
    /// then left out of the other's sigma); a station of good readings has none, however
    /// closely they agree (the floor), nor does one of two readings.
    #[test]
    fn gross_readings_are_the_ones_that_would_mask_a_blunder() {
        let arcsec = (1.0f64 / 3600.0).to_radians();
        let mut dz: Vec<f64> = (0..15)
            .map(|i| 2.0 + arcsec * (f64::from(i % 5) - 2.0) * 0.7)
            .collect();
        assert!(gross_readings(&dz, arcsec).iter().all(|g| !g));
        dz[3] += 25.0 * arcsec;
        dz[9] -= 25.0 * arcsec;
        let gross = gross_readings(&dz, arcsec);
        let flagged: Vec<usize> = (0..dz.len()).filter(|&i| gross[i]).collect();
        assert_eq!(flagged, vec![3, 9]);
        // Among readings that agree to 1e-9 of an arcsec, one 2 arcsec off is not gross:
        // the floor holds the scale at an arcsec.
        let tight: Vec<f64> = (0..15)
            .map(|i| 2.0 + 1e-9 * arcsec * f64::from(i))
            .collect();
        let mut one_off = tight.clone();
        one_off[0] += 2.0 * arcsec;
        assert!(gross_readings(&one_off, arcsec).iter().all(|g| !g));
        assert_eq!(gross_readings(&dz[..2], arcsec), vec![false, false]);
    }

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
