//! The triad model (docs/model.md 6.5): three accelerometers on one block, calibrated together
//! from static positions. For position p the three mean readings X_p give the calibrated
//! vector a_p = T u_p in imu_tk's body frame:
//!
//! ```text
//!     [ 1  -a_yz   a_zy ]     u_j = (s_j + st_j tau_j) d_j + s2_j d_j^2 + s3_j d_j^3
//! T = [ 0    1    -a_zx ]     d_j = x_j - b_j - bt_j tau_j,   tau_j = T_j - t_ref
//!     [ 0    0      1   ]
//! ```
//!
//! At order 1 without temperature this is imu_tk's a = T K (X - B) with K = diag(s). The
//! higher orders are in the reading less its bias (mGal per reading unit squared and cubed),
//! the temperature terms move each axis's bias (reading units per K) and scale (mGal per
//! reading unit per K) with its own temperature. The condition is `|a_p| - g_p = 0` (the
//! length of the calibrated vector is gravity; written in mGal, not as |a|^2 - g^2, so that
//! its residual is the report's |a| - g per position). Each condition has six observations
//! of its own: the three means with their sigmas, and the three axes' temperatures with the
//! sds align gives them from the thermometer's noise (exact, sd 0, when it gives none or the
//! model has no temperature terms): a Gauss-Helmert model on [`crate::lsq::gh`] with K = 6, data
//! snooping on the
//! positions (w-test, alpha 0.001), the global test, and the parameters the positions
//! cannot determine named (too few positions; orientations in one plane; one temperature
//! for temperature terms). No I/O.

use crate::calibration::calibrate::W_CRITICAL;
use crate::lsq::gh::{self, Conditions, GhError};
pub use ingest::contract::manifest::PositionFloor;

/// The linear model's parameter names, in order: the three non-orthogonality angles (rad),
/// the scales, the biases. [`TriadModel::names`] appends the others.
pub const NAMES: [&str; 9] = [
    "a_yz", "a_zy", "a_zx", "s_x", "s_y", "s_z", "b_x", "b_y", "b_z",
];

/// Names of the terms after the linear nine, by kind.
const S2: [&str; 3] = ["s2_x", "s2_y", "s2_z"];
const S3: [&str; 3] = ["s3_x", "s3_y", "s3_z"];
const BT: [&str; 3] = ["bt_x", "bt_y", "bt_z"];
const ST: [&str; 3] = ["st_x", "st_y", "st_z"];

/// Parameters of the largest model (order 3 with temperature terms).
pub const MAX_PARAMS: usize = 21;

/// Fewest positions for the 9 parameters of the linear model (docs/model.md 6.5); a model with
/// more parameters needs three more positions than parameters.
pub const MIN_POSITIONS: usize = 12;

/// Which terms a triad model has (docs/formats.md 8.4: `order`, `temperature`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriadModel {
    /// Polynomial order per axis, 1..=3.
    pub order: u8,
    /// Bias and scale move linearly with each axis's temperature.
    pub temperature: bool,
}

impl TriadModel {
    /// imu_tk's model: T, K, B.
    pub const LINEAR: TriadModel = TriadModel {
        order: 1,
        temperature: false,
    };

    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        9 + 3 * usize::from(self.order.clamp(1, 3) - 1) + if self.temperature { 6 } else { 0 }
    }

    /// Parameter names in order: [`NAMES`], then s2, s3 (by order), then bt, st.
    pub fn names(&self) -> Vec<&'static str> {
        let mut n = NAMES.to_vec();
        if self.order >= 2 {
            n.extend(S2);
        }
        if self.order >= 3 {
            n.extend(S3);
        }
        if self.temperature {
            n.extend(BT);
            n.extend(ST);
        }
        n
    }

    /// Fewest positions: [`MIN_POSITIONS`] or three more than the parameters.
    pub fn min_positions(&self) -> usize {
        MIN_POSITIONS.max(self.n_params() + 3)
    }

    /// Index of the first of s2, s3, bt (each a run of three), when the model has them.
    fn offsets(&self) -> (Option<usize>, Option<usize>, Option<usize>) {
        let s2 = (self.order >= 2).then_some(9);
        let s3 = (self.order >= 3).then_some(12);
        let bt = self
            .temperature
            .then_some(9 + 3 * usize::from(self.order.clamp(1, 3) - 1));
        (s2, s3, bt)
    }

    /// Each axis's du_j/dtau_j at readings `x` and temperature offsets `tau` (0 without
    /// temperature terms): da_r/dtau_j = T[r][j] du_j/dtau_j.
    pub fn tau_slopes(&self, p: &[f64], x: [f64; 3], tau: [f64; 3]) -> [f64; 3] {
        let (o2, o3, ot) = self.offsets();
        let Some(ot) = ot else {
            return [0.0; 3];
        };
        let at = |o: Option<usize>, j: usize| o.map_or(0.0, |o| p[o + j]);
        std::array::from_fn(|j| {
            let (s2, s3, bt, st) = (at(o2, j), at(o3, j), p[ot + j], p[ot + 3 + j]);
            let d = x[j] - p[6 + j] - bt * tau[j];
            let du = p[3 + j] + st * tau[j] + d * (2.0 * s2 + 3.0 * s3 * d);
            st * d - du * bt
        })
    }

    /// The calibrated vector at readings `x` and temperature offsets `tau` (ignored without
    /// temperature terms), its derivatives by the readings (da_r/dx_j = T[r][j] u'_j), and,
    /// when `jac` is given, da/dp into it (3 rows of n_params).
    pub fn evaluate(
        &self,
        p: &[f64],
        x: [f64; 3],
        tau: [f64; 3],
        jac: Option<&mut [f64]>,
    ) -> ([f64; 3], [[f64; 3]; 3]) {
        let (o2, o3, ot) = self.offsets();
        let at = |o: Option<usize>, j: usize| o.map_or(0.0, |o| p[o + j]);
        let tau = if self.temperature { tau } else { [0.0; 3] };
        let t = [[1.0, -p[0], p[1]], [0.0, 1.0, -p[2]], [0.0, 0.0, 1.0]];
        let mut u = [0.0; 3];
        let mut du = [0.0; 3];
        // Per axis, du_j/dp for: s, b, s2, s3, bt, st.
        let mut parts = [[0.0; 6]; 3];
        for j in 0..3 {
            let (s2, s3) = (at(o2, j), at(o3, j));
            let (bt, st) = (at(ot, j), at(ot.map(|o| o + 3), j));
            let d = x[j] - p[6 + j] - bt * tau[j];
            let scale = p[3 + j] + st * tau[j];
            u[j] = d * (scale + d * (s2 + d * s3));
            du[j] = scale + d * (2.0 * s2 + 3.0 * s3 * d);
            parts[j] = [d, -du[j], d * d, d * d * d, -du[j] * tau[j], tau[j] * d];
        }
        let a: [f64; 3] = std::array::from_fn(|r| (0..3).map(|c| t[r][c] * u[c]).sum());
        if let Some(jac) = jac {
            let n = self.n_params();
            jac[..3 * n].fill(0.0);
            jac[0] = -u[1];
            jac[1] = u[2];
            jac[n + 2] = -u[2];
            for j in 0..3 {
                let columns = [
                    Some(3 + j),
                    Some(6 + j),
                    o2.map(|o| o + j),
                    o3.map(|o| o + j),
                    ot.map(|o| o + j),
                    ot.map(|o| o + 3 + j),
                ];
                for (column, part) in columns.iter().zip(parts[j]) {
                    if let Some(c) = column {
                        for r in 0..3 {
                            jac[r * n + c] = t[r][j] * part;
                        }
                    }
                }
            }
        }
        (
            a,
            std::array::from_fn(|r| std::array::from_fn(|j| t[r][j] * du[j])),
        )
    }
}

/// One static position: the three mean readings and their sds, gravity there, and the
/// axes' temperatures when logged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Position {
    /// Mean reading of each axis.
    pub mean: [f64; 3],
    /// Sd of each mean.
    pub sigma: [f64; 3],
    /// Gravity at the block during the position, mGal (with the tide where known).
    pub g_mgal: f64,
    /// Each axis's temperature over the position, degC.
    pub temperature_c: Option<[f64; 3]>,
    /// The sd of each of those temperatures; none (or 0) takes them as exact.
    pub temperature_sd_c: Option<[f64; 3]>,
}

/// The calibrated vector of the linear model a = T K (x - B) (the first 9 parameters).
fn calibrated(p: &[f64], x: [f64; 3]) -> [f64; 3] {
    TriadModel::LINEAR.evaluate(&p[..9], x, [0.0; 3], None).0
}

struct TriadConditions {
    model: TriadModel,
    t_ref_c: f64,
}

impl Conditions<7> for TriadConditions {
    fn n_params(&self) -> usize {
        self.model.n_params()
    }

    /// Observations `l`: the three means, then the three temperatures (taken as t_ref, and
    /// so ignored, without temperature terms), then the position's gravity (its sd the
    /// position floor: what the block's placement adds beyond the samples' scatter).
    fn eval(&self, _i: usize, p: &[f64], l: [f64; 7], a: &mut [f64]) -> (f64, [f64; 7]) {
        let n = self.model.n_params();
        let x = [l[0], l[1], l[2]];
        let tau = [l[3], l[4], l[5]].map(|t| t - self.t_ref_c);
        let mut jac = [0.0; 3 * MAX_PARAMS];
        let (v, dadx) = self.model.evaluate(p, x, tau, Some(&mut jac));
        let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let e: [f64; 3] = std::array::from_fn(|j| v[j] / norm);
        // d|a|/dp = e^T da/dp; d|a|/dx = e^T da/dx; d|a|/dT_j = e^T T[.][j] du_j/dtau_j.
        for (k, out) in a.iter_mut().enumerate().take(n) {
            *out = (0..3).map(|r| e[r] * jac[r * n + k]).sum();
        }
        // T's column j is da/dx_j over du_j/dx_j; the temperature moves u_j by its slope.
        let slopes = self.model.tau_slopes(p, x, tau);
        let t = [[1.0, -p[0], p[1]], [0.0, 1.0, -p[2]], [0.0, 0.0, 1.0]];
        let bl = std::array::from_fn(|j| match j {
            0..3 => (0..3).map(|r| e[r] * dadx[r][j]).sum::<f64>(),
            3..6 => (0..3).map(|r| e[r] * t[r][j - 3]).sum::<f64>() * slopes[j - 3],
            _ => -1.0,
        });
        (norm - l[6], bl)
    }
}

/// The seven observations of each position, and their sds: the means, then the
/// temperatures (t_ref, sd 0, without temperature terms or a temperature; sd 0 when it has
/// none), then gravity with the position floor's sd `floor_mgal`.
fn position_observations(
    positions: &[Position],
    t_ref_c: Option<f64>,
    floor_mgal: f64,
) -> (Vec<[f64; 7]>, Vec<[f64; 7]>) {
    positions
        .iter()
        .map(|q| {
            let (t, sd) = match (t_ref_c, q.temperature_c) {
                (Some(_), Some(t)) => (t, q.temperature_sd_c.unwrap_or([0.0; 3])),
                _ => ([t_ref_c.unwrap_or(0.0); 3], [0.0; 3]),
            };
            let l = [q.mean[0], q.mean[1], q.mean[2], t[0], t[1], t[2], q.g_mgal];
            let s = [
                q.sigma[0], q.sigma[1], q.sigma[2], sd[0], sd[1], sd[2], floor_mgal,
            ];
            (l, s)
        })
        .unzip()
}

/// What a triad calibration found.
#[derive(Clone, Debug)]
pub struct TriadSolution {
    /// The model fitted.
    pub model: TriadModel,
    /// The parameters of [`TriadModel::names`].
    pub values: Vec<f64>,
    /// Their covariance at the a-priori sigmas of the means (and the floor), row-major n x n.
    pub covariance: Vec<f64>,
    /// The temperature tau is counted from, degC (with temperature terms).
    pub t_ref_c: Option<f64>,
    /// sqrt(v^T P v / dof): the fit's, or with an estimated floor the positions' own sigmas'.
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
    /// The parameters' sds at the positions' own sigmas (no floor).
    pub sigma_apriori: Vec<f64>,
    /// The position floor used, if any.
    pub floor: Option<FloorUsed>,
}

/// The position floor a triad fit used (docs/model.md 6.5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloorUsed {
    /// The sd added to each position's gravity, mGal.
    pub mgal: f64,
    /// Estimated: the floors at which v^T P v (at the positions' own sigmas plus the floor)
    /// reaches its chi-square's 97.5 % and 2.5 % points, a 95 % interval; none when declared.
    pub interval_mgal: Option<[f64; 2]>,
}

impl TriadSolution {
    /// Sd of parameter `j`.
    pub fn sigma(&self, j: usize) -> f64 {
        let n = self.values.len();
        self.covariance[j * n + j].max(0.0).sqrt()
    }

    /// The calibrated vector of position `q` (at its readings and temperatures).
    pub fn calibrated(&self, q: &Position) -> [f64; 3] {
        let tau = match (q.temperature_c, self.t_ref_c) {
            (Some(t), Some(r)) => t.map(|t| t - r),
            _ => [0.0; 3],
        };
        self.model.evaluate(&self.values, q.mean, tau, None).0
    }
}

/// Why a triad calibration has no answer; every variant names what is missing.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TriadError {
    /// Too few positions.
    #[error(
        "{n} static positions for the {params} parameters of the triad: at least {needed} well-spread positions are needed"
    )]
    TooFewPositions {
        /// Positions given.
        n: usize,
        /// Parameters of the model.
        params: usize,
        /// Positions needed.
        needed: usize,
    },
    /// A model with temperature terms, and a position without temperatures.
    #[error(
        "{missing} of {n} static positions have no temperature (the session logged none, or \
         the log has a gap there): a model with temperature terms cannot be fitted to them"
    )]
    NoTemperature {
        /// Positions without temperature.
        missing: usize,
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
    /// No position floor up to 1e9 mGal brings the fit's v^T P v to its dof.
    #[error(
        "no position floor up to 1e9 mGal makes the positions agree with the model: they are \
         not static positions of this triad"
    )]
    NoFloor,
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

/// The reference temperature of a model with temperature terms: the mean of every axis's
/// temperature over the positions, rounded to 0.01 degC (as the axis model's t_ref).
fn reference_temperature(positions: &[Position]) -> Result<f64, TriadError> {
    let missing = positions
        .iter()
        .filter(|q| q.temperature_c.is_none())
        .count();
    if missing > 0 {
        return Err(TriadError::NoTemperature {
            missing,
            n: positions.len(),
        });
    }
    let sum: f64 = positions
        .iter()
        .filter_map(|q| q.temperature_c)
        .map(|t| t.iter().sum::<f64>())
        .sum();
    Ok((sum / (3 * positions.len()) as f64 * 100.0).round() / 100.0)
}

/// One adjustment of the triad `model` to `positions` from `start`.
fn adjust_positions(
    model: TriadModel,
    positions: &[Position],
    t_ref_c: Option<f64>,
    floor_mgal: f64,
    start: &[f64],
) -> Result<gh::Solution<7>, TriadError> {
    let (l, sigma) = position_observations(positions, t_ref_c, floor_mgal);
    gh::solve(
        &TriadConditions {
            model,
            t_ref_c: t_ref_c.unwrap_or(0.0),
        },
        &gh::Held::new(&l, &sigma),
        start,
        &gh::Options::default(),
    )
    .map_err(|e| match e {
        GhError::NotEstimable { index } => TriadError::NotEstimable {
            name: model.names()[index],
        },
        other => TriadError::Adjustment(other),
    })
}

/// Calibrates the triad `model` from `positions` with no position floor: see
/// [`calibrate_with_floor`].
pub fn calibrate(model: TriadModel, positions: &[Position]) -> Result<TriadSolution, TriadError> {
    calibrate_with_floor(model, positions, PositionFloor::None)
}

/// Calibrates the triad `model` from `positions`: the adjustment, then data snooping (the
/// position with the largest |w| above 3.29 removed and the adjustment repeated, at most a
/// tenth of the positions), then the global test. With `floor` each position's gravity is
/// an observation with the floor's sd (declared, or estimated at each step so that
/// v^T P v equals its degrees of freedom when the positions scatter beyond their sigmas).
pub fn calibrate_with_floor(
    model: TriadModel,
    positions: &[Position],
    floor: PositionFloor,
) -> Result<TriadSolution, TriadError> {
    let needed = model.min_positions();
    if positions.len() < needed {
        return Err(TriadError::TooFewPositions {
            n: positions.len(),
            params: model.n_params(),
            needed,
        });
    }
    let t_ref_c = if model.temperature {
        Some(reference_temperature(positions)?)
    } else {
        None
    };
    let mut p0 = start_values(positions);
    check_spread(positions, &p0)?;
    p0.resize(model.n_params(), 0.0);
    let mut used: Vec<usize> = (0..positions.len()).collect();
    let mut removed = Vec::new();
    let mut start = p0;
    loop {
        let kept: Vec<Position> = used.iter().map(|&i| positions[i]).collect();
        let fit = |f: f64, start: &[f64]| adjust_positions(model, &kept, t_ref_c, f, start);
        let floor_mgal = match floor {
            PositionFloor::None => 0.0,
            PositionFloor::Mgal(v) => v,
            PositionFloor::Estimate => {
                // One condition a position: the dof are the positions less the parameters.
                let dof = (kept.len() - model.n_params()) as f64;
                floor_for(&|f| fit(f, &start).map(|s| s.vtpv), dof)?
            }
        };
        let s = fit(floor_mgal, &start)?;
        let worst = s
            .w_test
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map(|(i, w)| (i, *w));
        if let Some((i, w)) = worst
            && w.abs() > W_CRITICAL
            && removed.len() < positions.len() / 10
            && used.len() > needed
        {
            removed.push((used[i], w));
            used.remove(i);
            start = s.p;
            continue;
        }
        let weighting = Weighting {
            t_ref_c,
            floor,
            floor_mgal,
        };
        return conclude(model, weighting, &fit, s, &used, removed);
    }
}

/// How a triad's fit is weighted: the reference temperature of its temperature terms (None
/// without), the position floor asked for, and the floor it was fitted at (mGal).
#[derive(Clone, Copy, Debug)]
struct Weighting {
    t_ref_c: Option<f64>,
    floor: PositionFloor,
    floor_mgal: f64,
}

/// The positions refitted at a floor (mGal) from a start.
type FitAt<'a> = &'a dyn Fn(f64, &[f64]) -> Result<gh::Solution<7>, TriadError>;

/// The fit `s` of the positions `used` (the others `removed`), concluded: the test of its
/// weights (the fit's own, or with an estimated floor the positions' sigmas alone, refitted
/// by `fit` at a floor: the floor makes v^T P v its dof by construction) and the floor's
/// interval.
fn conclude(
    model: TriadModel,
    weighting: Weighting,
    fit: FitAt<'_>,
    s: gh::Solution<7>,
    used: &[usize],
    removed: Vec<(usize, f64)>,
) -> Result<TriadSolution, TriadError> {
    let Weighting {
        t_ref_c,
        floor,
        floor_mgal,
    } = weighting;
    let tested = match floor {
        PositionFloor::Estimate => fit(0.0, &s.p)?,
        _ => s.clone(),
    };
    let dof = tested.dof;
    let chi2 = statrs::distribution::ChiSquared::new(dof.max(1) as f64).expect("dof is positive");
    let quantile = |q: f64| statrs::distribution::ContinuousCDF::inverse_cdf(&chi2, q);
    let (lo, hi) = (quantile(0.025), quantile(0.975));
    let floor_used = match floor {
        PositionFloor::None => None,
        PositionFloor::Mgal(v) => Some(FloorUsed {
            mgal: v,
            interval_mgal: None,
        }),
        PositionFloor::Estimate => {
            let vtpv = |f| fit(f, &s.p).map(|s| s.vtpv);
            Some(FloorUsed {
                mgal: floor_mgal,
                interval_mgal: Some([floor_for(&vtpv, hi)?, floor_for(&vtpv, lo)?]),
            })
        }
    };
    let n = s.p.len();
    Ok(TriadSolution {
        model,
        t_ref_c,
        sigma0: tested.sigma0(),
        vtpv: tested.vtpv,
        dof,
        global_test: (lo, hi, (lo..=hi).contains(&tested.vtpv)),
        residuals: used
            .iter()
            .enumerate()
            .map(|(k, &i)| (i, s.misclosure[k], s.w_test[k]))
            .collect(),
        removed,
        iterations: s.iterations,
        sigma_apriori: (0..n)
            .map(|j| tested.q_pp[j * n + j].max(0.0).sqrt())
            .collect(),
        floor: floor_used,
        covariance: s.q_pp,
        values: s.p,
    })
}

/// The smallest floor f >= 0 at which `vtpv(f)` (decreasing in f) is at most `target`: 0
/// when it already is, else by bisection to a part in 1e6.
fn floor_for(
    vtpv: &dyn Fn(f64) -> Result<f64, TriadError>,
    target: f64,
) -> Result<f64, TriadError> {
    if vtpv(0.0)? <= target {
        return Ok(0.0);
    }
    let mut hi = 1.0;
    while vtpv(hi)? > target {
        hi *= 4.0;
        if hi > 1e9 {
            return Err(TriadError::NoFloor);
        }
    }
    let mut lo = 0.0;
    while hi - lo > 1e-6 * hi {
        let mid = 0.5 * (lo + hi);
        if vtpv(mid)? > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The condition's derivatives against numerical ones, for every order with and
    /// without temperature terms.
    #[test]
    fn derivatives_match_numerical_ones() {
        let q = [Position {
            mean: [2.1e6, -1.3e6, 3.0e6],
            sigma: [1.0; 3],
            g_mgal: 980_000.0,
            temperature_c: Some([31.5, 29.0, 30.2]),
            temperature_sd_c: None,
        }];
        for order in 1..=3 {
            for temperature in [false, true] {
                let model = TriadModel { order, temperature };
                let c = TriadConditions {
                    model,
                    t_ref_c: 30.0,
                };
                let mut p = vec![2e-3, -1e-3, 3e-3, 0.243, 0.242, 0.2435, 1.2e5, 1.4e5, 9.0e4];
                let names = model.names();
                for name in &names[9..] {
                    p.push(match &name[..2] {
                        "s2" => 3e-9,
                        "s3" => -2e-15,
                        "bt" => 40.0,
                        _ => 2e-5,
                    });
                }
                let (l, _) = position_observations(&q, Some(30.0), 0.0);
                check_derivatives(&c, &p, &names, l[0]);
            }
        }
    }

    fn check_derivatives(c: &TriadConditions, p: &[f64], names: &[&str], x: [f64; 7]) {
        let n = p.len();
        let mut a = vec![0.0; n];
        let (_, b) = c.eval(0, p, x, &mut a);
        let mut scratch = vec![0.0; n];
        for j in 0..n {
            let h = 1e-4 * p[j].abs();
            let mut up = p.to_vec();
            up[j] += h;
            let mut down = p.to_vec();
            down[j] -= h;
            let d = (c.eval(0, &up, x, &mut scratch).0 - c.eval(0, &down, x, &mut scratch).0)
                / (2.0 * h);
            assert!(
                (d - a[j]).abs() <= 1e-6 * d.abs().max(1e-3),
                "{:?} {}: {d} vs {}",
                c.model,
                names[j],
                a[j]
            );
        }
        // The readings by one unit, the temperatures by 1 mK, gravity by 1 mGal.
        for j in 0..7 {
            let h = if j == 3 || j == 4 || j == 5 {
                1e-3
            } else {
                1.0
            };
            let mut up = x;
            up[j] += h;
            let mut down = x;
            down[j] -= h;
            let d =
                (c.eval(0, p, up, &mut scratch).0 - c.eval(0, p, down, &mut scratch).0) / (2.0 * h);
            assert!(
                (d - b[j]).abs() <= 1e-6 * d.abs().max(1e-6),
                "{:?} l{j}: {d} vs {}",
                c.model,
                b[j]
            );
        }
        if !c.model.temperature {
            assert_eq!(&b[3..6], &[0.0; 3]);
        } else {
            assert!(b[3..6].iter().all(|d| d.abs() > 1.0), "{b:?}");
        }
        assert!((b[6] + 1.0).abs() < 1e-12, "{b:?}");
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
