//! The general fitting command (docs/formats.md section 7): a polynomial of any degree up to 10
//! through (x, y), with errors in y alone or in both variables (Gauss-Helmert).

use crate::calibration::model::{Polynomial, apply, monomial_map, propagate};
use crate::lsq::gh::{self, GhError, Options};
use faer::prelude::*;
use serde::{Deserialize, Serialize};

/// Highest degree `fit` accepts.
pub const MAX_DEGREE: usize = 10;

/// One estimated coefficient: `pj` multiplies x^j.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FitParameter {
    /// `p0`, `p1`, ...
    pub name: String,
    /// Estimate.
    pub value: f64,
    /// A-posteriori sd (scaled by sigma0).
    pub sigma: f64,
    /// A-priori sd (from the given weights alone).
    pub sigma_apriori: f64,
}

/// What `fit` prints.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FitOutput {
    /// Coefficients.
    pub parameters: Vec<FitParameter>,
    /// sqrt(v^T P v / dof).
    pub sigma0: f64,
    /// Residual sd of y: sqrt(sum of the y misclosures squared / dof).
    pub residual_sd: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Iterations.
    pub iterations: usize,
}

/// Why a fit failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// Degree above [`MAX_DEGREE`].
    #[error("degree {0} is above {MAX_DEGREE}")]
    Degree(usize),
    /// A value is not finite or a sd is negative.
    #[error("row {row}: {message}")]
    BadValue {
        /// 1-based data row.
        row: usize,
        /// What is wrong.
        message: String,
    },
    /// A coefficient the x values cannot determine.
    #[error("p{index} is not estimable from these x values")]
    NotEstimable {
        /// Its power of x.
        index: usize,
    },
    /// The adjustment failed otherwise.
    #[error(transparent)]
    Adjustment(GhError),
    /// The arithmetic cannot hold the fit (a power of x, or a result, beyond a double).
    #[error("{0}")]
    Overflow(String),
}

/// Fits `y = sum p_j x^j` of `degree`. Without `sigma_x` the x are exact; without `sigma_y`
/// every y has unit weight.
pub fn fit(
    x: &[f64],
    y: &[f64],
    sigma_x: Option<&[f64]>,
    sigma_y: Option<&[f64]>,
    degree: usize,
) -> Result<FitOutput, FitError> {
    if degree > MAX_DEGREE {
        return Err(FitError::Degree(degree));
    }
    assert_eq!(x.len(), y.len(), "x and y of equal length");
    let (l, sigma) = observations(x, y, sigma_x, sigma_y)?;
    let (centre, scale) = centre_and_scale(x, degree)?;
    let model = Polynomial {
        degree,
        centre,
        scale,
    };
    let p0 = vec![0.0; degree + 1];
    let s = gh::solve(&model, &gh::Held::new(&l, &sigma), &p0, &Options::default()).map_err(
        |e| match e {
            GhError::NotEstimable { index } => FitError::NotEstimable { index },
            other => FitError::Adjustment(other),
        },
    )?;
    let m = monomial_map(degree, centre, scale);
    let mut p = apply(&m, &s.p);
    if sigma_x.is_none_or(|sx| sx.iter().all(|&v| v == 0.0)) {
        refine(&mut p, x, y, &sigma, &model, &m);
    }
    let q = propagate(&m, &s.q_pp, degree + 1);
    let sigma0 = s.sigma0();
    let dof = s.dof;
    let residual_sd = if dof == 0 {
        0.0
    } else {
        (s.misclosure.iter().map(|e| e * e).sum::<f64>() / dof as f64).sqrt()
    };
    let parameters = (0..=degree)
        .map(|j| {
            let apriori = q[j * (degree + 1) + j].max(0.0).sqrt();
            FitParameter {
                name: format!("p{j}"),
                value: p[j],
                sigma: sigma0 * apriori,
                sigma_apriori: apriori,
            }
        })
        .collect();
    let parameters: Vec<FitParameter> = parameters;
    check_finite(&parameters, sigma0, residual_sd)?;
    Ok(FitOutput {
        parameters,
        sigma0,
        residual_sd,
        dof,
        iterations: s.iterations,
    })
}

/// Per observation, a pair: (x, y), or their sds.
type Pairs = Vec<[f64; 2]>;

/// The observations `(x, y)` and their sds (sigma_x 0 and sigma_y 1 when not given), each
/// checked: finite, sigma_y > 0, sigma_x >= 0; a bad one named by its row.
fn observations(
    x: &[f64],
    y: &[f64],
    sigma_x: Option<&[f64]>,
    sigma_y: Option<&[f64]>,
) -> Result<(Pairs, Pairs), FitError> {
    let n = x.len();
    let mut l = Vec::with_capacity(n);
    let mut sigma = Vec::with_capacity(n);
    for i in 0..n {
        let sx = sigma_x.map_or(0.0, |s| s[i]);
        let sy = sigma_y.map_or(1.0, |s| s[i]);
        if !(x[i].is_finite() && y[i].is_finite() && sx.is_finite() && sy.is_finite())
            || sx < 0.0
            || sy <= 0.0
        {
            return Err(FitError::BadValue {
                row: i + 1,
                message: format!(
                    "x {} y {} sigma_x {sx} sigma_y {sy}: values must be finite, sigma_y > 0, sigma_x >= 0",
                    x[i], y[i]
                ),
            });
        }
        l.push([x[i], y[i]]);
        sigma.push([sx, sy]);
    }
    Ok((l, sigma))
}

/// The centre and half-range of `x` the polynomial is formed in; an error when x^degree
/// is beyond a double.
fn centre_and_scale(x: &[f64], degree: usize) -> Result<(f64, f64), FitError> {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let centre = 0.5 * lo + 0.5 * hi;
    let scale = if hi > lo { 0.5 * hi - 0.5 * lo } else { 1.0 };
    let largest = lo.abs().max(hi.abs());
    let representable = largest
        .powi(i32::try_from(degree).unwrap_or(i32::MAX))
        .is_finite()
        && scale.is_finite();
    if !(x.is_empty() || representable) {
        return Err(FitError::Overflow(format!(
            "x reaches {largest:e}: x^{degree} is beyond a double (about 1.8e308), so the \
             coefficients cannot be represented; rescale x (e.g. fit in x / {:e})",
            10f64.powi(largest.log10().floor() as i32)
        )));
    }
    Ok((centre, scale))
}

/// An error when a parameter, its a-priori sd, sigma0 or the residual sd is not a finite
/// number (with finite weights no a-priori sd is 0: one that is has underflowed).
fn check_finite(
    parameters: &[FitParameter],
    sigma0: f64,
    residual_sd: f64,
) -> Result<(), FitError> {
    if let Some(p) = parameters
        .iter()
        .find(|p| !(p.value.is_finite() && p.sigma_apriori.is_finite() && p.sigma_apriori > 0.0))
    {
        return Err(FitError::Overflow(format!(
            "{} came out as {:e} with an a-priori sd of {:e}: the arithmetic over- or \
             underflowed (x or y too large or too small for their powers); rescale them",
            p.name, p.value, p.sigma_apriori
        )));
    }
    if !(sigma0.is_finite() && residual_sd.is_finite()) {
        return Err(FitError::Overflow(format!(
            "sigma0 {sigma0:e}, residual sd {residual_sd:e}: the arithmetic overflowed; \
             rescale x and y"
        )));
    }
    Ok(())
}

/// `a + b` as a sum and its rounding error.
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `a * b` as a product and its rounding error (exact by fused multiply-add).
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

/// `y - sum p_j x^j`, evaluated as if in twice the working precision (compensated Horner),
/// returned as an unevaluated sum `hi + lo`.
fn residual(p: &[f64], x: f64, y: f64) -> (f64, f64) {
    let n = p.len();
    let mut s = p[n - 1];
    let mut c = 0.0_f64;
    for j in (0..n - 1).rev() {
        let (prod, e1) = two_prod(s, x);
        let (sum, e2) = two_sum(prod, p[j]);
        s = sum;
        c = c.mul_add(x, e1 + e2);
    }
    let (d, e) = two_sum(y, -s);
    two_sum(d, e - c)
}

/// Iterative refinement of a fit with exact x (corrected semi-normal equations): the
/// gradient `X^T W r` of the coefficients in powers of x is formed with powers, residuals and
/// dot products in twice the working precision, and the correction solved with the R factor
/// of the well-scaled design, until it no longer changes the coefficients. A plain QR solve
/// of the residual cannot do this when the residual is large; this carries the estimates of
/// problems like NIST's Wampler5 (coefficients of 1 with sds of 10^7) to full precision.
fn refine(
    p: &mut [f64],
    x: &[f64],
    y: &[f64],
    sigma: &[[f64; 2]],
    model: &Polynomial,
    to_monomial: &[f64],
) {
    let n = x.len();
    let k = p.len();
    let mut design = Mat::<f64>::zeros(n, k);
    for i in 0..n {
        let t = (x[i] - model.centre) / model.scale;
        let mut tp = 1.0 / sigma[i][1];
        for j in 0..k {
            design[(i, j)] = tp;
            tp *= t;
        }
    }
    let qr = design.qr();
    let r_mat = qr.thin_R();
    for _ in 0..4 {
        // g_j = sum_i x_i^j r_i / sigma_i^2, each term and the sum compensated.
        let mut g = vec![(0.0f64, 0.0f64); k];
        for i in 0..n {
            let w = 1.0 / (sigma[i][1] * sigma[i][1]);
            let (r_hi, r_lo) = residual(p, x[i], y[i]);
            let (rw, rw_err) = two_prod(r_hi, w);
            let rw_err = rw_err + r_lo * w;
            let mut pow = (1.0f64, 0.0f64);
            for gj in g.iter_mut() {
                // term = pow * (rw + rw_err), accumulated into gj.
                let (t, t_err) = two_prod(pow.0, rw);
                let t_err = t_err + pow.0 * rw_err + pow.1 * rw;
                let (s, s_err) = two_sum(gj.0, t);
                *gj = (s, gj.1 + s_err + t_err);
                let (q, q_err) = two_prod(pow.0, x[i]);
                pow = (q, q_err + pow.1 * x[i]);
            }
        }
        // h = M^T g, then R^T R da = h.
        let h: Vec<f64> = (0..k)
            .map(|j| {
                (0..k)
                    .map(|i| to_monomial[i * k + j] * (g[i].0 + g[i].1))
                    .sum()
            })
            .collect();
        let mut z = vec![0.0; k];
        for j in 0..k {
            let s: f64 = (0..j).map(|t| r_mat[(t, j)] * z[t]).sum();
            z[j] = (h[j] - s) / r_mat[(j, j)];
        }
        let mut da = vec![0.0; k];
        for j in (0..k).rev() {
            let s: f64 = (j + 1..k).map(|t| r_mat[(j, t)] * da[t]).sum();
            da[j] = (z[j] - s) / r_mat[(j, j)];
        }
        let dp = apply(to_monomial, &da);
        let mut changed = false;
        for j in 0..k {
            let before = p[j];
            p[j] += dp[j];
            changed |= p[j].to_bits() != before.to_bits();
        }
        if !changed {
            break;
        }
    }
}
