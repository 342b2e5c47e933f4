//! The attitude from several GNSS antennas on the vehicle (docs/formats.md 10.2.1, docs/model.md
//! 7, "An antenna array"): per epoch, the rotation C_v^n and the accelerometers' position p
//! that best map the antennas' declared positions b_i (vehicle frame, from the
//! accelerometers to each antenna's phase centre) onto their measured ones d_i (a local
//! north-east-down frame), d_i = p + C b_i + e_i, each e_i with its position's sds.
//!
//! The fit is a weighted least-squares adjustment of six parameters, p and a small rotation
//! eps with C = (I + [eps x]) C0, iterated from C0 (TRIAD's closed form on the two
//! baselines that span the most area) until the rotation's step is below a nanoradian. Its
//! covariance is the normal matrix's inverse: of p, and of eps, the rotation's error in the
//! navigation frame (north, east, down), which is what tilts the specific force. Weighted
//! by each position's own sds, the fit is Wahba's problem with its weights, generalised to
//! sds that differ between up and the horizontal (a scalar weight per antenna cannot say
//! that an RTK height is twice as noisy as its horizontal position).
//!
//! A baseline whose measured length departs from its declared one by more than `limit`
//! times its sd sets an antenna aside for the epoch: the one whose leaving out lets the
//! others fit best (the least chi-square); the fit is made again from them
//! (`baseline_length`). Three
//! antennas not in a line are needed; two give heading and pitch only ([`heading_pitch`]),
//! the baseline along the vehicle's x axis. No I/O.

use faer::prelude::*;

/// An antenna's measured position at an epoch: north, east, down of a local origin, m,
/// and their sds, m.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fix {
    /// North, east, down, m.
    pub ned_m: [f64; 3],
    /// Their sds, m.
    pub sd_m: [f64; 3],
}

/// One epoch's fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution {
    /// The accelerometers' position, north, east, down of the fixes' origin, m.
    pub origin_ned_m: [f64; 3],
    /// C_v^n, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Heading, pitch, roll of [`Solution::rotation`] = Rz Ry Rx, rad.
    pub hpr_rad: [f64; 3],
    /// The covariance of (p north, east, down, m; eps north, east, down, rad).
    pub covariance: [[f64; 6]; 6],
    /// Bit k set: antenna k used.
    pub used: u32,
    /// Bit k set: antenna k set aside, its baselines' lengths off.
    pub set_aside: u32,
    /// The fit's weighted sum of squared residuals (chi-square on 3n - 6 degrees of
    /// freedom when the sds hold).
    pub chi2: f64,
}

impl Solution {
    /// The covariance of heading, pitch and roll, rad^2: eps = M (dh, dp, dr), with M's
    /// columns the down axis, Rz(h)'s y axis and Rz(h) Ry(p)'s x axis, so cov(hpr) =
    /// M^-1 cov(eps) M^-T.
    pub fn hpr_covariance(&self) -> [[f64; 3]; 3] {
        let [h, p, _] = self.hpr_rad;
        let (sh, ch) = h.sin_cos();
        let (sp, cp) = p.sin_cos();
        let m = Mat::<f64>::from_fn(3, 3, |i, j| {
            [[0.0, -sh, ch * cp], [0.0, ch, sh * cp], [1.0, 0.0, -sp]][i][j]
        });
        let eps = Mat::<f64>::from_fn(3, 3, |i, j| self.covariance[3 + i][3 + j]);
        let inv = m.qr().solve_lstsq(Mat::<f64>::identity(3, 3));
        let c = &inv * &eps * inv.transpose();
        std::array::from_fn(|i| std::array::from_fn(|j| c[(i, j)]))
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    a.map(|v| v / n)
}

fn apply(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// An orthonormal triad of two vectors: the first, the normal, the third; as columns.
fn triad(a: [f64; 3], b: [f64; 3]) -> [[f64; 3]; 3] {
    let t1 = unit(a);
    let t2 = unit(cross(a, b));
    let t3 = cross(t1, t2);
    std::array::from_fn(|i| [t1[i], t2[i], t3[i]])
}

/// TRIAD's rotation mapping the body baselines `v1`, `v2` onto the measured `w1`, `w2`.
fn triad_rotation(v: [[f64; 3]; 2], w: [[f64; 3]; 2]) -> [[f64; 3]; 3] {
    let (tv, tw) = (triad(v[0], v[1]), triad(w[0], w[1]));
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| tw[i][k] * tv[j][k]).sum()))
}

/// The rotation exp([e x]) (Rodrigues).
fn rotation_of(e: [f64; 3]) -> [[f64; 3]; 3] {
    let th = norm(e);
    if th == 0.0 {
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    }
    let k = e.map(|v| v / th);
    let (s, c) = th.sin_cos();
    let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let kk: f64 = (0..3).map(|m| kx[i][m] * kx[m][j]).sum();
            f64::from(u8::from(i == j)) + s * kx[i][j] + (1.0 - c) * kk
        })
    })
}

/// Heading, pitch, roll of C = Rz Ry Rx.
pub fn hpr_of(c: &[[f64; 3]; 3]) -> [f64; 3] {
    [
        c[1][0].atan2(c[0][0]),
        (-c[2][0]).clamp(-1.0, 1.0).asin(),
        c[2][1].atan2(c[2][2]),
    ]
}

/// The whitened design of the fit at `c`, `p`: rows per antenna and axis, columns p and
/// eps; and the whitened residuals.
fn linearised(
    positions: &[[f64; 3]],
    fixes: &[(usize, Fix)],
    (c, p): (&[[f64; 3]; 3], [f64; 3]),
) -> (Mat<f64>, Mat<f64>) {
    let rows = 3 * fixes.len();
    let mut a = Mat::<f64>::zeros(rows, 6);
    let mut y = Mat::<f64>::zeros(rows, 1);
    for (r, (k, f)) in fixes.iter().enumerate() {
        let cb = apply(c, positions[*k]);
        // d(C b) = eps x (C b) = -[(C b) x] eps.
        let skew = [
            [0.0, cb[2], -cb[1]],
            [-cb[2], 0.0, cb[0]],
            [cb[1], -cb[0], 0.0],
        ];
        for axis in 0..3 {
            let w = 1.0 / f.sd_m[axis];
            let row = 3 * r + axis;
            a[(row, axis)] = w;
            for j in 0..3 {
                a[(row, 3 + j)] = w * skew[axis][j];
            }
            y[(row, 0)] = w * (f.ned_m[axis] - p[axis] - cb[axis]);
        }
    }
    (a, y)
}

/// The fit of the antennas `fixes` (index, fix), at least three not in a line; None where
/// they are (to a part in 10^6 of the baselines' area).
fn fit(positions: &[[f64; 3]], fixes: &[(usize, Fix)]) -> Option<Solution> {
    let (a0, f0) = fixes[0];
    let far = fixes
        .iter()
        .max_by(|x, y| {
            let d = |k: usize| norm(sub(positions[k], positions[a0]));
            d(x.0).total_cmp(&d(y.0))
        })
        .copied()?;
    let span = sub(positions[far.0], positions[a0]);
    let third = fixes
        .iter()
        .max_by(|x, y| {
            let area = |k: usize| norm(cross(span, sub(positions[k], positions[a0])));
            area(x.0).total_cmp(&area(y.0))
        })
        .copied()?;
    let other = sub(positions[third.0], positions[a0]);
    if norm(cross(span, other)) <= 1e-6 * norm(span).powi(2) {
        return None;
    }
    let measured = |f: Fix| sub(f.ned_m, f0.ned_m);
    let mut c = triad_rotation([span, other], [measured(far.1), measured(third.1)]);
    let mut p = sub(f0.ned_m, apply(&c, positions[a0]));
    let mut design = Mat::<f64>::zeros(0, 0);
    for _ in 0..8 {
        let (a, y) = linearised(positions, fixes, (&c, p));
        let step = a.qr().solve_lstsq(&y);
        for i in 0..3 {
            p[i] += step[(i, 0)];
        }
        let e = [step[(3, 0)], step[(4, 0)], step[(5, 0)]];
        let r = rotation_of(e);
        c = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..3).map(|k| r[i][k] * c[k][j]).sum())
        });
        design = a;
        if norm(e) < 1e-9 {
            break;
        }
    }
    let normal = design.transpose() * &design;
    let cov = normal.qr().solve_lstsq(Mat::<f64>::identity(6, 6));
    let chi2 = linearised(positions, fixes, (&c, p)).1.squared_norm_l2();
    Some(Solution {
        origin_ned_m: p,
        hpr_rad: hpr_of(&c),
        rotation: c,
        covariance: std::array::from_fn(|i| std::array::from_fn(|j| cov[(i, j)])),
        used: fixes.iter().fold(0, |m, (k, _)| m | 1 << k),
        set_aside: 0,
        chi2,
    })
}

/// A baseline's measured length less its declared one, over its sd (the two positions'
/// sds along it).
pub(super) fn baseline_z(
    positions: &[[f64; 3]],
    (i, fi): (usize, Fix),
    (j, fj): (usize, Fix),
) -> f64 {
    let d = sub(fi.ned_m, fj.ned_m);
    let length = norm(d);
    let u = d.map(|v| v / length);
    let var: f64 = (0..3)
        .map(|k| u[k] * u[k] * (fi.sd_m[k].powi(2) + fj.sd_m[k].powi(2)))
        .sum();
    (length - norm(sub(positions[i], positions[j]))) / var.sqrt()
}

/// Whether a baseline of `fixes` is off by more than `limit` sds.
fn any_off(positions: &[[f64; 3]], fixes: &[(usize, Fix)], limit: f64) -> bool {
    (0..fixes.len()).any(|a| {
        (a + 1..fixes.len()).any(|b| baseline_z(positions, fixes[a], fixes[b]).abs() > limit)
    })
}

/// The antenna of `fixes` (more than three) to set aside once a baseline is off: the one
/// whose leaving out lets the others fit best (the least chi-square). A baseline's length
/// alone does not say which of its two ends moved; the fit of the rest does.
fn worst(positions: &[[f64; 3]], fixes: &[(usize, Fix)]) -> Option<usize> {
    (0..fixes.len())
        .filter_map(|k| {
            let mut rest = fixes.to_vec();
            rest.remove(k);
            fit(positions, &rest).map(|s| (k, s.chi2))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
}

/// Why an epoch has no fit: the antennas set aside (bit k: antenna k), and whether that
/// left too few (else the usable ones lie in a line).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Unsolved {
    /// Bit k set: antenna k set aside, its baselines' lengths off.
    pub set_aside: u32,
    /// Fewer than three antennas usable, or three whose baselines disagree.
    pub too_few: bool,
}

/// The epoch's attitude and the accelerometers' position from the antennas at `positions`
/// (vehicle frame, m) whose `fixes` are given (None: no position at the epoch), setting
/// aside one antenna at a time while a baseline is off by more than `limit` sds; with
/// fewer than three usable antennas not in a line, why not.
pub fn solve(
    positions: &[[f64; 3]],
    fixes: &[Option<Fix>],
    limit: f64,
) -> Result<Solution, Unsolved> {
    let mut given: Vec<(usize, Fix)> = fixes
        .iter()
        .enumerate()
        .filter_map(|(k, f)| f.map(|f| (k, f)))
        .collect();
    let mut set_aside = 0u32;
    while given.len() >= 3 {
        match (any_off(positions, &given, limit), given.len() > 3) {
            (true, true) => {
                let k = worst(positions, &given).unwrap_or(0);
                set_aside |= 1 << given[k].0;
                given.remove(k);
            }
            (true, false) => {
                // Three antennas, a baseline off: which is wrong cannot be told apart.
                break;
            }
            (false, _) => {
                let unsolved = Unsolved {
                    set_aside,
                    too_few: false,
                };
                let mut s = fit(positions, &given).ok_or(unsolved)?;
                s.set_aside = set_aside;
                return Ok(s);
            }
        }
    }
    Err(Unsolved {
        set_aside,
        too_few: true,
    })
}

/// Heading and pitch from two antennas whose declared baseline lies along the vehicle's x
/// axis, and their sds (rad): the measured baseline's azimuth and elevation, linearised
/// for the sds. Roll turns the vehicle about that baseline and is not given.
pub fn heading_pitch(a: Fix, b: Fix, fore: bool) -> ([f64; 2], [f64; 2]) {
    let w = if fore {
        sub(b.ned_m, a.ned_m)
    } else {
        sub(a.ned_m, b.ned_m)
    };
    let var: [f64; 3] = std::array::from_fn(|k| a.sd_m[k].powi(2) + b.sd_m[k].powi(2));
    let [n, e, d] = w;
    let hh = n * n + e * e;
    let h = hh.sqrt();
    let heading = e.atan2(n);
    let pitch = (-d).atan2(h);
    // dh = (n de - e dn) / h^2; dp = (-h dd + d dH) / (h^2 + d^2), dH = (n dn + e de) / h.
    let sd_h = ((e * e * var[0] + n * n * var[1]) / (hh * hh)).sqrt();
    let l2 = hh + d * d;
    let dp = [d * n / h / l2, d * e / h / l2, -h / l2];
    let sd_p = (0..3).map(|k| dp[k] * dp[k] * var[k]).sum::<f64>().sqrt();
    ([heading, pitch], [sd_h, sd_p])
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Four antennas of a 3 m array, 5 mm horizontal and 10 mm vertical.
    const ARRAY: [[f64; 3]; 4] = [
        [1.6, 0.0, -2.1],
        [-1.4, 0.0, -2.0],
        [0.0, 1.3, -1.9],
        [0.1, -1.2, -2.2],
    ];
    const SD: [f64; 3] = [0.005, 0.005, 0.010];

    fn rot(h: f64, p: f64, r: f64) -> [[f64; 3]; 3] {
        super::super::attitude::rotation(h, p, r)
    }

    fn fixes(c: &[[f64; 3]; 3], p: [f64; 3], noise: &mut impl FnMut() -> f64) -> Vec<Option<Fix>> {
        ARRAY
            .iter()
            .map(|b| {
                let cb = apply(c, *b);
                Some(Fix {
                    ned_m: std::array::from_fn(|k| p[k] + cb[k] + SD[k] * noise()),
                    sd_m: SD,
                })
            })
            .collect()
    }

    /// A small generator of normals for the tests (Box-Muller on a 64-bit LCG; also
    /// `array_positions`'s).
    pub(in crate::survey::gravity) fn normals(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            let mut u = || {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        }
    }

    /// Without noise the fit gives the attitude and position back to 1e-12 at any heading,
    /// through pitch and roll of tens of degrees.
    #[test]
    fn the_attitude_comes_back_exactly() {
        for (h, p, r) in [(0.3, 0.05, -0.1), (3.0, -0.3, 0.4), (-2.0, 0.0, 0.0)] {
            let c = rot(h, p, r);
            let s = solve(&ARRAY, &fixes(&c, [10.0, -4.0, 2.0], &mut || 0.0), 5.0).expect("fit");
            for (got, want) in s.hpr_rad.iter().zip([h, p, r]) {
                assert!(
                    (got - want).abs() < 1e-12,
                    "{:?} against {h} {p} {r}",
                    s.hpr_rad
                );
            }
            assert!(
                (s.origin_ned_m[0] - 10.0).abs() < 1e-12,
                "{:?}",
                s.origin_ned_m
            );
            assert_eq!((s.used, s.set_aside), (0b1111, 0));
        }
    }

    /// Over 4000 noisy epochs at random attitudes, each angle's error over its sd (from the
    /// fit's covariance) has an rms within 0.05 of 1, and so has the position's.
    #[test]
    fn the_covariance_is_honest() {
        let mut noise = normals(20_261_201);
        let mut draw = normals(7);
        let (mut z2, mut zp2, n) = ([0.0; 3], [0.0; 3], 4000);
        for _ in 0..n {
            let truth = [3.0 * draw(), 0.1 * draw(), 0.1 * draw()];
            let c = rot(truth[0], truth[1], truth[2]);
            let s = solve(&ARRAY, &fixes(&c, [0.0; 3], &mut noise), 5.0).expect("fit");
            let cov = s.hpr_covariance();
            for k in 0..3 {
                let mut d = s.hpr_rad[k] - truth[k];
                d = (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                z2[k] += d * d / cov[k][k];
                zp2[k] += s.origin_ned_m[k].powi(2) / s.covariance[k][k];
            }
        }
        let rms = |v: [f64; 3]| v.map(|x| (x / f64::from(n)).sqrt());
        eprintln!(
            "rms z heading, pitch, roll {:?}; position {:?}",
            rms(z2),
            rms(zp2)
        );
        for z in rms(z2).into_iter().chain(rms(zp2)) {
            assert!((z - 1.0).abs() < 0.05, "{z}");
        }
    }

    /// An antenna 5 cm off along its baseline at one epoch is set aside, and the epoch
    /// fitted from the other three; with three antennas left so, which one is off cannot
    /// be told, and the epoch has no fit.
    #[test]
    fn an_antenna_whose_baselines_are_off_is_set_aside() {
        let c = rot(1.0, 0.02, -0.03);
        let mut f = fixes(&c, [0.0; 3], &mut normals(3));
        if let Some(x) = &mut f[2] {
            x.ned_m[0] += 0.05;
        }
        let s = solve(&ARRAY, &f, 5.0).expect("three left");
        assert_eq!((s.used, s.set_aside), (0b1011, 0b0100));
        assert!((s.hpr_rad[0] - 1.0).abs() < 0.01);
        f[3] = None;
        let e = solve(&ARRAY, &f, 5.0).expect_err("too few");
        assert!(e.too_few && e.set_aside == 0, "{e:?}");
    }

    /// Two antennas fore and aft: heading and pitch of the baseline, their sds honest over
    /// 4000 epochs (rms z within 0.05 of 1).
    #[test]
    fn two_antennas_give_heading_and_pitch() {
        let mut noise = normals(11);
        let (mut z2, n) = ([0.0; 2], 4000);
        for k in 0..n {
            let (h, p) = (0.001 * f64::from(k), 0.05);
            let c = rot(h, p, 0.2);
            let at = |b: [f64; 3], noise: &mut dyn FnMut() -> f64| {
                let cb = apply(&c, b);
                Fix {
                    ned_m: std::array::from_fn(|k| cb[k] + SD[k] * noise()),
                    sd_m: SD,
                }
            };
            let fore = at([1.5, 0.0, -2.0], &mut noise);
            let aft = at([-1.5, 0.0, -2.0], &mut noise);
            let (hp, sd) = heading_pitch(aft, fore, true);
            let dh = (hp[0] - h + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            z2[0] += (dh / sd[0]).powi(2);
            z2[1] += ((hp[1] - p) / sd[1]).powi(2);
        }
        let rms = z2.map(|x| (x / f64::from(n)).sqrt());
        eprintln!("rms z heading, pitch {rms:?}");
        for z in rms {
            assert!((z - 1.0).abs() < 0.05, "{z}");
        }
    }
}
