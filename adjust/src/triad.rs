//! The triad model (MODEL.md 6.5): three accelerometers on one block, calibrated together
//! from static positions. For position p the three mean readings X_p give the calibrated
//! vector a_p = T K (X_p - B) in imu_tk's body frame:
//!
//! ```text
//!     [ 1  -a_yz   a_zy ]        K = diag(s_x, s_y, s_z)     (mGal per reading unit)
//! T = [ 0    1    -a_zx ]        B = (b_x, b_y, b_z)         (reading units)
//!     [ 0    0      1   ]
//! ```
//!
//! and the condition `|a_p| - g_p = 0` (the length of the calibrated vector is gravity; the
//! condition is written in mGal, not as |a|^2 - g^2, so that its residual is the report's
//! |a| - g per position). Each condition has three observations of its own (the means, with
//! their sigmas): a Gauss-Helmert model on [`crate::gh`] with K = 3, data snooping on the
//! positions (w-test, alpha 0.001), the global test, and the parameters the positions
//! cannot determine named (fewer than 12 positions; orientations in one plane). No I/O.

use crate::calibrate::W_CRITICAL;
use crate::gh::{self, Conditions, GhError};

/// Parameter names, in order: the three non-orthogonality angles (rad), the scales, the
/// biases.
pub const NAMES: [&str; 9] = [
    "a_yz", "a_zy", "a_zx", "s_x", "s_y", "s_z", "b_x", "b_y", "b_z",
];

/// Fewest positions for the 9 parameters (MODEL.md 6.5).
pub const MIN_POSITIONS: usize = 12;

/// One static position: the three mean readings and their sds, and gravity there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Position {
    /// Mean reading of each axis.
    pub mean: [f64; 3],
    /// Sd of each mean.
    pub sigma: [f64; 3],
    /// Gravity at the block during the position, mGal (with the tide where known).
    pub g_mgal: f64,
}

/// T, K and B from the parameter vector.
fn parts(p: &[f64]) -> ([[f64; 3]; 3], [f64; 3], [f64; 3]) {
    let t = [[1.0, -p[0], p[1]], [0.0, 1.0, -p[2]], [0.0, 0.0, 1.0]];
    ([t[0], t[1], t[2]], [p[3], p[4], p[5]], [p[6], p[7], p[8]])
}

/// The calibrated vector a = T K (x - B).
pub fn calibrated(p: &[f64], x: [f64; 3]) -> [f64; 3] {
    let (t, k, b) = parts(p);
    let u: [f64; 3] = std::array::from_fn(|i| k[i] * (x[i] - b[i]));
    std::array::from_fn(|r| (0..3).map(|c| t[r][c] * u[c]).sum())
}

struct TriadConditions<'a> {
    positions: &'a [Position],
}

impl Conditions<3> for TriadConditions<'_> {
    fn n_params(&self) -> usize {
        9
    }

    fn eval(&self, i: usize, p: &[f64], l: [f64; 3], a: &mut [f64]) -> (f64, [f64; 3]) {
        let (t, k, b) = parts(p);
        let x: [f64; 3] = std::array::from_fn(|j| l[j] - b[j]);
        let u: [f64; 3] = std::array::from_fn(|j| k[j] * x[j]);
        let v = calibrated(p, l);
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let e: [f64; 3] = std::array::from_fn(|j| v[j] / n);
        // d|a|/da = e; da/d(angles); da/ds_j = T[:, j] x_j; da/db_j = -T[:, j] s_j.
        a[0] = -e[0] * u[1];
        a[1] = e[0] * u[2];
        a[2] = -e[1] * u[2];
        let column = |j: usize| -> f64 { (0..3).map(|r| e[r] * t[r][j]).sum() };
        let mut bl = [0.0; 3];
        for j in 0..3 {
            let c = column(j);
            a[3 + j] = c * x[j];
            a[6 + j] = -c * k[j];
            bl[j] = c * k[j];
        }
        (n - self.positions[i].g_mgal, bl)
    }
}

/// What a triad calibration found.
#[derive(Clone, Debug)]
pub struct TriadSolution {
    /// The 9 parameters of [`NAMES`].
    pub values: Vec<f64>,
    /// Their covariance at the a-priori sigmas of the means, row-major 9 x 9.
    pub covariance: Vec<f64>,
    /// sqrt(v^T P v / dof).
    pub sigma0: f64,
    /// v^T P v.
    pub vtpv: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Two-sided 5 % chi-square bounds of v^T P v, and whether it lies inside.
    pub global_test: (f64, f64, bool),
    /// Per position used: index into the input, |a| - g at the adjusted means (mGal, the
    /// condition's misclosure taken up), its w-test.
    pub residuals: Vec<(usize, f64, f64)>,
    /// Positions removed by data snooping, in order: index and w-test.
    pub removed: Vec<(usize, f64)>,
    /// Iterations of the final adjustment.
    pub iterations: usize,
}

impl TriadSolution {
    /// Sd of parameter `j`.
    pub fn sigma(&self, j: usize) -> f64 {
        self.covariance[j * 9 + j].max(0.0).sqrt()
    }
}

/// Why a triad calibration has no answer; every variant names what is missing.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TriadError {
    /// Too few positions.
    #[error(
        "{n} static positions for the 9 parameters of the triad: at least {MIN_POSITIONS} well-spread positions are needed"
    )]
    TooFewPositions {
        /// Positions given.
        n: usize,
    },
    /// The positions' gravity directions do not span the three axes.
    #[error(
        "the positions' gravity directions lie in one plane (their spread across its normal, \
         about ({:.2}, {:.2}, {:.2}) in the body frame, is {spread:.1e} of the spread within it): \
         the biases and scales along that normal are not estimable; add positions with the \
         block turned out of that plane", normal[0], normal[1], normal[2]
    )]
    OnePlane {
        /// The plane's normal, approximately.
        normal: [f64; 3],
        /// Smallest over largest eigenvalue of the directions' scatter.
        spread: f64,
    },
    /// The adjustment could not determine a parameter.
    #[error("parameter {name} is not estimable from these positions")]
    NotEstimable {
        /// Its name.
        name: &'static str,
    },
    /// The adjustment failed otherwise.
    #[error("{0}")]
    Adjustment(GhError),
}

/// Start values: T = I, each axis's bias halfway between its extremes and its scale from
/// the spread (the axis points nearly up and down in some positions of a well-spread set).
fn start_values(positions: &[Position]) -> Vec<f64> {
    let g = positions.iter().map(|p| p.g_mgal).sum::<f64>() / positions.len() as f64;
    let mut p = vec![0.0; 9];
    for j in 0..3 {
        let (lo, hi) = positions
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), q| {
                (a.min(q.mean[j]), b.max(q.mean[j]))
            });
        p[6 + j] = 0.5 * (lo + hi);
        p[3 + j] = if hi > lo { 2.0 * g / (hi - lo) } else { 1.0 };
    }
    p
}

/// The symmetric eigen-decomposition of a 3 x 3 matrix by Jacobi rotations: (values,
/// vectors as columns), values ascending.
fn eigen3(mut m: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..50 {
        let (mut pi, mut qi, mut big) = (0, 1, 0.0);
        for i in 0..3 {
            for j in i + 1..3 {
                if m[i][j].abs() > big {
                    (pi, qi, big) = (i, j, m[i][j].abs());
                }
            }
        }
        if big < 1e-15 * (m[0][0].abs() + m[1][1].abs() + m[2][2].abs()) {
            break;
        }
        let theta = 0.5 * (2.0 * m[pi][qi]).atan2(m[qi][qi] - m[pi][pi]);
        let (s, c) = theta.sin_cos();
        for k in 0..3 {
            let (a, b) = (m[k][pi], m[k][qi]);
            m[k][pi] = c * a - s * b;
            m[k][qi] = s * a + c * b;
        }
        for k in 0..3 {
            let (a, b) = (m[pi][k], m[qi][k]);
            m[pi][k] = c * a - s * b;
            m[qi][k] = s * a + c * b;
        }
        for row in &mut v {
            let (a, b) = (row[pi], row[qi]);
            row[pi] = c * a - s * b;
            row[qi] = s * a + c * b;
        }
    }
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| m[a][a].total_cmp(&m[b][b]));
    let values = order.map(|i| m[i][i]);
    let vectors = std::array::from_fn(|r| order.map(|i| v[r][i]));
    (values, vectors)
}

/// The positions' spread of directions: fails when they lie in one plane (the smallest
/// eigenvalue of their scatter below 1 % of the largest).
fn check_spread(positions: &[Position], p0: &[f64]) -> Result<(), TriadError> {
    let mut s = [[0.0; 3]; 3];
    for q in positions {
        let a = calibrated(p0, q.mean);
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] += a[i] * a[j] / (n * n);
            }
        }
    }
    let (values, vectors) = eigen3(s);
    let spread = values[0] / values[2];
    if spread < 0.01 {
        return Err(TriadError::OnePlane {
            normal: std::array::from_fn(|r| vectors[r][0]),
            spread,
        });
    }
    Ok(())
}

/// Calibrates the triad from `positions`: the adjustment, then data snooping (the position
/// with the largest |w| above 3.29 removed and the adjustment repeated, at most a tenth of
/// the positions), then the global test.
pub fn calibrate(positions: &[Position]) -> Result<TriadSolution, TriadError> {
    if positions.len() < MIN_POSITIONS {
        return Err(TriadError::TooFewPositions { n: positions.len() });
    }
    let p0 = start_values(positions);
    check_spread(positions, &p0)?;
    let mut used: Vec<usize> = (0..positions.len()).collect();
    let mut removed = Vec::new();
    let mut start = p0;
    loop {
        let kept: Vec<Position> = used.iter().map(|&i| positions[i]).collect();
        let l: Vec<[f64; 3]> = kept.iter().map(|q| q.mean).collect();
        let sigma: Vec<[f64; 3]> = kept.iter().map(|q| q.sigma).collect();
        let s = gh::solve(
            &TriadConditions { positions: &kept },
            &l,
            &sigma,
            &start,
            &gh::Options::default(),
        )
        .map_err(|e| match e {
            GhError::NotEstimable { index } => TriadError::NotEstimable { name: NAMES[index] },
            other => TriadError::Adjustment(other),
        })?;
        let worst = s
            .w_test
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map(|(i, w)| (i, *w));
        if let Some((i, w)) = worst
            && w.abs() > W_CRITICAL
            && removed.len() < positions.len() / 10
            && used.len() > MIN_POSITIONS
        {
            removed.push((used[i], w));
            used.remove(i);
            start = s.p;
            continue;
        }
        let dof = s.dof;
        let chi2 =
            statrs::distribution::ChiSquared::new(dof.max(1) as f64).expect("dof is positive");
        let (lo, hi) = (
            statrs::distribution::ContinuousCDF::inverse_cdf(&chi2, 0.025),
            statrs::distribution::ContinuousCDF::inverse_cdf(&chi2, 0.975),
        );
        return Ok(TriadSolution {
            sigma0: s.sigma0(),
            vtpv: s.vtpv,
            dof,
            global_test: (lo, hi, (lo..=hi).contains(&s.vtpv)),
            residuals: used
                .iter()
                .enumerate()
                .map(|(k, &i)| (i, s.misclosure[k], s.w_test[k]))
                .collect(),
            removed,
            iterations: s.iterations,
            covariance: s.q_pp,
            values: s.p,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The condition's derivatives against numerical ones.
    #[test]
    fn derivatives_match_numerical_ones() {
        let q = [Position {
            mean: [2.1e6, -1.3e6, 3.0e6],
            sigma: [1.0; 3],
            g_mgal: 980_000.0,
        }];
        let c = TriadConditions { positions: &q };
        let p = [2e-3, -1e-3, 3e-3, 0.243, 0.242, 0.2435, 1.2e5, 1.4e5, 9.0e4];
        let mut a = [0.0; 9];
        let (_, b) = c.eval(0, &p, q[0].mean, &mut a);
        let mut scratch = [0.0; 9];
        for j in 0..9 {
            let h = 1e-6 * p[j].abs().max(1e-6);
            let mut up = p;
            up[j] += h;
            let mut down = p;
            down[j] -= h;
            let d = (c.eval(0, &up, q[0].mean, &mut scratch).0
                - c.eval(0, &down, q[0].mean, &mut scratch).0)
                / (2.0 * h);
            assert!(
                (d - a[j]).abs() <= 1e-6 * d.abs().max(1e-3),
                "{}: {d} vs {}",
                NAMES[j],
                a[j]
            );
        }
        for j in 0..3 {
            let h = 1.0;
            let mut up = q[0].mean;
            up[j] += h;
            let mut down = q[0].mean;
            down[j] -= h;
            let d = (c.eval(0, &p, up, &mut scratch).0 - c.eval(0, &p, down, &mut scratch).0)
                / (2.0 * h);
            assert!((d - b[j]).abs() <= 1e-6 * d.abs(), "x{j}: {d} vs {}", b[j]);
        }
    }

    #[test]
    fn eigen_decomposition_of_a_known_matrix() {
        let (values, vectors) = eigen3([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]]);
        assert!((values[0] - 1.0).abs() < 1e-12 && (values[2] - 5.0).abs() < 1e-12);
        let v0 = [vectors[0][0], vectors[1][0], vectors[2][0]];
        assert!(
            (v0[0] + v0[1]).abs() < 1e-12 && v0[2].abs() < 1e-12,
            "{v0:?}"
        );
    }
}
