//! The condition equations: the calibration function of MODEL.md section 2 and the general
//! polynomial of the `fit` command, both in a centred and scaled variable
//! `x = (Ng - centre) / scale` so that powers stay near 1, and the exact linear map back to
//! the parameters in counts (b, k, k2, k3, b_t, k_t) with their covariance.

use crate::gh::Conditions;

/// Which terms a calibration model has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Terms {
    /// Polynomial order, 1..=3.
    pub order: usize,
    /// Bias and scale depend linearly on temperature.
    pub temperature: bool,
    /// The sensitive-axis angle beta.
    pub misalignment: bool,
}

/// A parameter's name and unit in the output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamName {
    /// Name as in calibration.json.
    pub name: &'static str,
    /// Unit.
    pub unit: &'static str,
}

impl Terms {
    /// Parameters in order: b, k, [k2], [k3], [b_t, k_t], [beta].
    pub fn names(&self) -> Vec<ParamName> {
        let mut v = vec![
            ParamName {
                name: "b",
                unit: "mGal",
            },
            ParamName {
                name: "k",
                unit: "mGal/bit",
            },
        ];
        if self.order >= 2 {
            v.push(ParamName {
                name: "k2",
                unit: "mGal/bit^2",
            });
        }
        if self.order >= 3 {
            v.push(ParamName {
                name: "k3",
                unit: "mGal/bit^3",
            });
        }
        if self.temperature {
            v.push(ParamName {
                name: "b_t",
                unit: "mGal/degC",
            });
            v.push(ParamName {
                name: "k_t",
                unit: "mGal/bit/degC",
            });
        }
        if self.misalignment {
            v.push(ParamName {
                name: "beta",
                unit: "rad",
            });
        }
        v
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.order + 1 + 2 * usize::from(self.temperature) + usize::from(self.misalignment)
    }

    /// Whether there are no parameters (never: a model has at least b and k).
    pub fn is_empty(&self) -> bool {
        false
    }
}

/// Binomial coefficient.
fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// The map from polynomial coefficients in `x = (u - centre) / scale` to those in `u`:
/// row i holds the coefficients of `u^i` (row-major, (degree+1)^2).
pub fn monomial_map(degree: usize, centre: f64, scale: f64) -> Vec<f64> {
    let n = degree + 1;
    let shift = -centre / scale;
    let mut m = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..=j {
            m[i * n + j] = binomial(j, i) * shift.powi((j - i) as i32) / scale.powi(i as i32);
        }
    }
    m
}

/// `M Q M^T` for a row-major square `m` and `q`.
pub fn propagate(m: &[f64], q: &[f64], n: usize) -> Vec<f64> {
    let mut mq = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            mq[i * n + j] = (0..n).map(|k| m[i * n + k] * q[k * n + j]).sum();
        }
    }
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            out[i * n + j] = (0..n).map(|k| mq[i * n + k] * m[j * n + k]).sum();
        }
    }
    out
}

/// `M p`.
pub fn apply(m: &[f64], p: &[f64]) -> Vec<f64> {
    let n = p.len();
    (0..n)
        .map(|i| (0..n).map(|k| m[i * n + k] * p[k]).sum())
        .collect()
}

/// The calibration condition `g_i cos(Dz + beta) + c(Ng, T) = 0`, `g_i = g + tide_i`, with
/// `c = a0 + a1 x + a2 x^2 + a3 x^3 + (at0 + at1 x) (T - t_ref)`, `x = (Ng - centre) / scale`.
/// Observations are `(Dz, Ng)`.
pub struct CalibrationConditions<'a> {
    /// The terms.
    pub terms: Terms,
    /// Gravity at the proof masses, mGal.
    pub g_mgal: f64,
    /// Centre of the counts.
    pub centre: f64,
    /// Scale of the counts.
    pub scale: f64,
    /// Reference temperature, degC.
    pub t_ref_c: f64,
    /// Temperature of each observation, degC.
    pub temperature_c: &'a [f64],
    /// Body tide at each observation, mGal (all 0 when none is applied).
    pub tide_mgal: &'a [f64],
}

impl CalibrationConditions<'_> {
    /// The map from the scaled parameters to b, k, [k2], [k3], [b_t, k_t], [beta]
    /// (row-major, len x len).
    pub fn to_counts(&self) -> Vec<f64> {
        let n = self.terms.len();
        let o = self.terms.order;
        let poly = monomial_map(o, self.centre, self.scale);
        let mut m = vec![0.0; n * n];
        for i in 0..=o {
            for j in 0..=o {
                m[i * n + j] = poly[i * (o + 1) + j];
            }
        }
        let mut at = o + 1;
        if self.terms.temperature {
            // (at0 + at1 x) tau = (at0 - at1 centre/scale) tau + (at1 / scale) Ng tau.
            m[at * n + at] = 1.0;
            m[at * n + at + 1] = -self.centre / self.scale;
            m[(at + 1) * n + at + 1] = 1.0 / self.scale;
            at += 2;
        }
        if self.terms.misalignment {
            m[at * n + at] = 1.0;
        }
        m
    }
}

impl Conditions for CalibrationConditions<'_> {
    fn n_params(&self) -> usize {
        self.terms.len()
    }

    fn eval(&self, i: usize, p: &[f64], l: [f64; 2], a: &mut [f64]) -> (f64, [f64; 2]) {
        let o = self.terms.order;
        let x = (l[1] - self.centre) / self.scale;
        let mut value = 0.0;
        let mut slope = 0.0;
        let mut xp = 1.0;
        for j in 0..=o {
            a[j] = xp;
            value += p[j] * xp;
            if j < o {
                slope += (j + 1) as f64 * p[j + 1] * xp;
            }
            xp *= x;
        }
        let mut at = o + 1;
        if self.terms.temperature {
            let tau = self.temperature_c[i] - self.t_ref_c;
            a[at] = tau;
            a[at + 1] = tau * x;
            value += (p[at] + p[at + 1] * x) * tau;
            slope += p[at + 1] * tau;
            at += 2;
        }
        let beta = if self.terms.misalignment { p[at] } else { 0.0 };
        let angle = l[0] + beta;
        let g = self.g_mgal + self.tide_mgal[i];
        let g_sin = g * angle.sin();
        if self.terms.misalignment {
            a[at] = -g_sin;
        }
        (g * angle.cos() + value, [-g_sin, slope / self.scale])
    }
}

/// The general polynomial `y - sum p_j x^j = 0`, `x` centred and scaled; observations `(x, y)`.
pub struct Polynomial {
    /// Degree.
    pub degree: usize,
    /// Centre of x.
    pub centre: f64,
    /// Scale of x.
    pub scale: f64,
}

impl Conditions for Polynomial {
    fn n_params(&self) -> usize {
        self.degree + 1
    }

    fn eval(&self, _i: usize, p: &[f64], l: [f64; 2], a: &mut [f64]) -> (f64, [f64; 2]) {
        let t = (l[0] - self.centre) / self.scale;
        let mut value = 0.0;
        let mut slope = 0.0;
        let mut tp = 1.0;
        for j in 0..=self.degree {
            a[j] = -tp;
            value += p[j] * tp;
            if j < self.degree {
                slope += (j + 1) as f64 * p[j + 1] * tp;
            }
            tp *= t;
        }
        (l[1] - value, [-slope / self.scale, 1.0])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The map to counts reproduces the polynomial at any point.
    #[test]
    fn monomial_map_is_exact() {
        let (centre, scale) = (2.3e6, 9.0e5);
        let a = [-5.0e5, 2.2e5, 13.0, -4.0];
        let m = monomial_map(3, centre, scale);
        let b = apply(&m, &a);
        for u in [1.4e6, 2.3e6, 3.3e6] {
            let x: f64 = (u - centre) / scale;
            let scaled: f64 = a
                .iter()
                .enumerate()
                .map(|(j, c)| c * x.powi(j as i32))
                .sum();
            let raw: f64 = b
                .iter()
                .enumerate()
                .map(|(j, c)| c * u.powi(j as i32))
                .sum();
            assert!(
                (scaled - raw).abs() < 1e-6 * scaled.abs(),
                "{scaled} vs {raw}"
            );
        }
    }

    #[test]
    fn names_follow_the_terms() {
        let t = Terms {
            order: 2,
            temperature: true,
            misalignment: true,
        };
        let names: Vec<&str> = t.names().iter().map(|n| n.name).collect();
        assert_eq!(names, ["b", "k", "k2", "b_t", "k_t", "beta"]);
        assert_eq!(t.len(), 6);
    }
}
