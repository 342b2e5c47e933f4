//! What several of adjust's tests share.

/// x^T C^-1 x for a symmetric positive definite C of the size of `x`, given by its
/// elements `c(i, j)` (Cholesky, then one triangular solve): the squared Mahalanobis length
/// of `x`.
pub fn quadratic_form_of_inverse(c: &dyn Fn(usize, usize) -> f64, x: &[f64]) -> f64 {
    let n = x.len();
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let s = c(i, j) - (0..j).map(|k| l[i * n + k] * l[j * n + k]).sum::<f64>();
            l[i * n + j] = if i == j { s.sqrt() } else { s / l[j * n + j] };
        }
    }
    // Solve L y = x; x^T C^-1 x = |y|^2.
    let mut y = vec![0.0; n];
    for i in 0..n {
        y[i] = (x[i] - (0..i).map(|k| l[i * n + k] * y[k]).sum::<f64>()) / l[i * n + i];
    }
    y.iter().map(|v| v * v).sum()
}

/// How a Monte-Carlo's temperatures are read: each one off by `sd_c` (degC), the fit told
/// of that sd when `given` (as align tells adjust) or taking the temperatures as exact.
#[derive(Clone, Copy, Debug)]
#[allow(dead_code, reason = "not every test binary reads temperatures")]
pub struct Thermometer {
    /// The sd of a temperature, degC.
    pub sd_c: f64,
    /// Whether the fit is given that sd.
    pub given: bool,
}

/// The temperatures known exactly.
#[allow(dead_code, reason = "not every test binary reads temperatures")]
pub const EXACT: Thermometer = Thermometer {
    sd_c: 0.0,
    given: false,
};
