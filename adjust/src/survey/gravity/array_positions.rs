//! Antennas' positions on the vehicle estimated from the data (`position_m = "estimate"`,
//! docs/formats.md 10.2.1, docs/model.md 7, "An antenna array"). The declared antennas (three
//! or more, not in a line) fix the vehicle frame and the accelerometers' origin at each epoch
//! ([`super::antennas::solve`] on them alone); an antenna to estimate is then seen at
//! b_k = C_k^T (d_k - p_k), whose error e_k - dp_k + [(C b) x] eps_k (its own position's, the
//! origin's and the rotation's, through the declared fit's covariance) is turned into the
//! vehicle frame. The estimate is the weighted mean of the epochs' b_k, each weighed by its
//! own covariance's inverse; an epoch further than `limit` (the square root of its
//! chi-square on 3 degrees of freedom) from the mean is screened out and the mean made again,
//! until none is. Each epoch's weight is formed at the mean so far, not at its own measured
//! lever arm. Its sds are the mean's, scaled by the scatter's sigma0 where that exceeds 1
//! (positions noisier than their sds say). No I/O.

use super::antennas::{Fix, Solution};
use faer::Mat;
use faer::linalg::solvers::DenseSolveCore;
use ingest::contract::gravity_ledger::EstimatedPosition as Estimated;

/// One epoch's sighting of an antenna: where it is measured from the declared antennas'
/// origin (north, east, down, m), their fit's rotation and covariance, and its own
/// position's sds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sighting {
    from_origin_m: [f64; 3],
    rotation: [[f64; 3]; 3],
    fit: [[f64; 6]; 6],
    own_sd_m: [f64; 3],
}

/// Where the declared antennas' fit `s` sees an antenna whose measured position is `fix`
/// (north, east, down in the fit's frame).
pub fn sighting(s: &Solution, fix: Fix) -> Sighting {
    Sighting {
        from_origin_m: std::array::from_fn(|k| fix.ned_m[k] - s.origin_ned_m[k]),
        rotation: s.rotation,
        fit: s.covariance,
        own_sd_m: fix.sd_m,
    }
}

impl Sighting {
    /// The antenna's position in the vehicle frame, C^T (d - p), and that position's
    /// covariance, with the lever arm from the origin taken as `at` (the estimate so far)
    /// turned by the fit's rotation, or the measured one for none. (Weights formed from each
    /// epoch's own measured lever arm err with the position they weigh: over 100 000
    /// simulated epochs of a rolling boat their mean was off by four to eight of its sds;
    /// [`tests::long_stretches_leave_no_bias_beyond_the_sd`].)
    fn seen(&self, at: Option<[f64; 3]>) -> ([f64; 3], Mat<f64>) {
        let c = &self.rotation;
        let u = at.map_or(self.from_origin_m, |b| {
            std::array::from_fn(|i| (0..3).map(|k| c[i][k] * b[k]).sum())
        });
        let position =
            std::array::from_fn(|i| (0..3).map(|k| c[k][i] * self.from_origin_m[k]).sum());
        // The error in the navigation frame: e - dp + [u x] eps, J = [-I | [u x]] on (dp, eps).
        let skew = [[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]];
        let j = Mat::<f64>::from_fn(3, 6, |r, col| match col {
            0..3 => -f64::from(u8::from(r == col)),
            _ => skew[r][col - 3],
        });
        let fit = Mat::<f64>::from_fn(6, 6, |r, col| self.fit[r][col]);
        let own = Mat::<f64>::from_fn(3, 3, |r, col| {
            if r == col {
                self.own_sd_m[r].powi(2)
            } else {
                0.0
            }
        });
        let nav = own + &j * fit * j.transpose();
        let turn = Mat::<f64>::from_fn(3, 3, |r, col| c[r][col]);
        (position, turn.transpose() * nav * &turn)
    }
}

/// The weighted mean of the sightings `kept` picks (by index into `all`), each seen with
/// the lever arm `at` ([`Sighting::seen`]).
struct Mean {
    position: [f64; 3],
    covariance: Mat<f64>,
    /// The chi-square of the kept about it.
    chi2: f64,
    /// The kept within the limit of it.
    within: Vec<usize>,
}

impl Mean {
    /// The mean of `all[kept]` seen at `at`, the kept within `limit` of it; None for none.
    fn of(all: &[Sighting], kept: &[usize], at: Option<[f64; 3]>, limit: f64) -> Option<Self> {
        let mut normal = Mat::<f64>::zeros(3, 3);
        let mut rhs = Mat::<f64>::zeros(3, 1);
        let mut seen = Vec::with_capacity(kept.len());
        for &k in kept {
            let (b, cov) = all[k].seen(at);
            let Ok(llt) = cov.llt(faer::Side::Lower) else {
                continue;
            };
            let w = llt.inverse();
            normal += &w;
            rhs += &w * Mat::<f64>::from_fn(3, 1, |r, _| b[r]);
            seen.push((k, b, w));
        }
        let covariance = normal.llt(faer::Side::Lower).ok()?.inverse();
        let x = &covariance * rhs;
        let position = [x[(0, 0)], x[(1, 0)], x[(2, 0)]];
        let mut chi2 = 0.0;
        let mut within = Vec::with_capacity(seen.len());
        for (k, b, w) in seen {
            let d = Mat::<f64>::from_fn(3, 1, |r, _| b[r] - position[r]);
            let d2 = (d.transpose() * w * &d)[(0, 0)];
            chi2 += d2;
            if d2.sqrt() <= limit {
                within.push(k);
            }
        }
        Some(Mean {
            position,
            covariance,
            chi2,
            within,
        })
    }
}

/// The position the `sightings` give: their weighted mean with each weighed at the mean
/// before it (the first at its own measured lever arm), epochs further than `limit` from
/// it screened out, until the kept and the mean settle (a micrometre); None with fewer
/// than two epochs left.
pub fn estimate(sightings: &[Sighting], limit: f64) -> Option<Estimated> {
    let mut kept: Vec<usize> = (0..sightings.len()).collect();
    let mut at = None;
    for _ in 0..20 {
        if kept.len() < 2 {
            return None;
        }
        let m = Mean::of(sightings, &kept, at, limit)?;
        let moved =
            at.is_none_or(|a: [f64; 3]| (0..3).any(|k| (a[k] - m.position[k]).abs() > 1e-6));
        if !moved && m.within.len() == kept.len() {
            let n = kept.len() as u64;
            let sigma0 = (m.chi2 / (3.0 * kept.len() as f64 - 3.0)).sqrt();
            return Some(Estimated {
                position_m: m.position,
                sd_m: std::array::from_fn(|k| m.covariance[(k, k)].sqrt() * sigma0.max(1.0)),
                epochs: n,
                screened: sightings.len() as u64 - n,
                sigma0,
            });
        }
        at = Some(m.position);
        kept = m.within;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::super::antennas::{self, Fix};
    use super::*;

    /// RTK's 5 mm horizontal and 10 mm vertical noise.
    const SD: [f64; 3] = [0.005, 0.005, 0.010];

    /// The simulator's four antennas of a 3 m array; the fourth is the one to estimate.
    fn array() -> [[f64; 3]; 4] {
        let p = fixtures::survey_lines::four_antennas().positions_m;
        [p[0], p[1], p[2], p[3]]
    }

    /// A rolling boat's `epochs` (heading turning, roll 8 deg and pitch 3 deg on the swell),
    /// the fourth antenna's sightings from the other three; `jump` adds 5 cm north to the
    /// fourth's fix at epoch 7.
    fn sightings(seed: u64, epochs: usize, jump: bool) -> Vec<Sighting> {
        let mut noise = antennas::tests::normals(seed);
        let a = array();
        let declared = [a[0], a[1], a[2], [0.0; 3]];
        (0..epochs)
            .filter_map(|k| {
                let t = k as f64;
                let c = super::super::attitude::rotation(
                    0.001 * t,
                    0.05 * (t / 7.0).sin(),
                    0.14 * (t / 5.0).sin(),
                );
                let p = [3.0 * t, -t, 0.2 * (t / 4.0).sin()];
                let fixes: Vec<Fix> = a
                    .iter()
                    .map(|b| Fix {
                        ned_m: std::array::from_fn(|i| {
                            let cb: f64 = (0..3).map(|j| c[i][j] * b[j]).sum();
                            p[i] + cb + SD[i] * noise()
                        }),
                        sd_m: SD,
                    })
                    .collect();
                let mut fourth = fixes[3];
                if jump && k == 7 {
                    fourth.ned_m[0] += 0.05;
                }
                let seen = [Some(fixes[0]), Some(fixes[1]), Some(fixes[2]), None];
                let s = antennas::solve(&declared, &seen, 5.0).ok()?;
                Some(sighting(&s, fourth))
            })
            .collect()
    }

    /// Over 200 simulated stretches of 300 epochs the estimate is within its sds of the
    /// truth: rms z 0.85 to 1.15 per axis, sigma0 within 0.1 of 1.
    #[test]
    fn the_estimate_is_within_its_sds() {
        let mut z2 = [0.0; 3];
        let trials = 200;
        for seed in 0..trials {
            let e = estimate(&sightings(seed, 300, false), 5.0).expect("an estimate");
            for k in 0..3 {
                z2[k] += ((e.position_m[k] - array()[3][k]) / e.sd_m[k]).powi(2);
            }
            assert!((e.sigma0 - 1.0).abs() < 0.1, "sigma0 {}", e.sigma0);
        }
        let z = z2.map(|v| (v / trials as f64).sqrt());
        eprintln!("estimated antenna: rms z x, y, z {z:?}");
        for v in z {
            assert!((0.85..1.15).contains(&v), "rms z {z:?}");
        }
    }

    /// A 5 cm jump of the antenna at one epoch is screened out, and the estimate made from
    /// the others.
    #[test]
    fn a_jump_is_screened_out() {
        let clean = estimate(&sightings(7, 300, false), 5.0).expect("an estimate");
        let jumped = estimate(&sightings(7, 300, true), 5.0).expect("an estimate");
        assert_eq!(clean.screened, 0, "{clean:?}");
        assert_eq!(jumped.screened, 1, "{jumped:?}");
        assert_eq!(jumped.epochs, 299);
        for k in 0..3 {
            let d = (jumped.position_m[k] - array()[3][k]) / jumped.sd_m[k];
            assert!(d.abs() < 4.0, "{jumped:?}");
        }
    }

    /// Too few epochs give no estimate.
    #[test]
    fn one_epoch_is_too_few() {
        assert!(estimate(&sightings(1, 1, false), 5.0).is_none());
    }

    /// The weighted mean of `all` with each sighting's covariance at its own measured lever
    /// arm, none screened: what the estimator would give without weights formed at the mean.
    fn plain_mean(all: &[Sighting]) -> [f64; 3] {
        let every: Vec<usize> = (0..all.len()).collect();
        Mean::of(all, &every, None, f64::INFINITY)
            .expect("a mean")
            .position
    }

    /// Long stretches (`GRAVCAL_MONTE_CARLO=1`: four of 100 000 epochs, else one of 25 000),
    /// where a bias of the estimator shows against its small sds: the estimate within 3.5 of
    /// its sds of the truth on every axis, and their rms over the stretches and axes below
    /// 1.6. Printed beside it, in the same sds, the plain weighted mean (each epoch weighed at
    /// its own measured lever arm).
    #[test]
    fn long_stretches_leave_no_bias_beyond_the_sd() {
        let (stretches, epochs) = match std::env::var("GRAVCAL_MONTE_CARLO") {
            Ok(_) => (4, 100_000),
            Err(_) => (1, 25_000),
        };
        let mut z2 = 0.0;
        for seed in 0..stretches {
            let all = sightings(100 + seed, epochs, false);
            let e = estimate(&all, 5.0).expect("an estimate");
            let z = |p: [f64; 3]| -> [f64; 3] {
                std::array::from_fn(|k| (p[k] - array()[3][k]) / e.sd_m[k])
            };
            eprintln!(
                "{epochs} epochs: in the estimate's sds ({:.4?} mm), the plain mean {:.2?}, \
                 the estimate {:.2?}",
                e.sd_m.map(|v| v * 1e3),
                z(plain_mean(&all)),
                z(e.position_m),
            );
            for (k, z) in z(e.position_m).into_iter().enumerate() {
                assert!(z.abs() < 3.5, "axis {k}: {z} sds; {e:?}");
                z2 += z * z;
            }
        }
        let rms = (z2 / (3 * stretches) as f64).sqrt();
        eprintln!("rms z over {stretches} stretch(es) and 3 axes: {rms:.2}");
        assert!(rms < 1.6, "rms z {rms}");
    }
}
