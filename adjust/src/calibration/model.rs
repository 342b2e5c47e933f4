//! The condition equations: the calibration function of docs/model.md section 2 and the general
//! polynomial of the `fit` command, both in a centred and scaled variable
//! `x = (Ng - centre) / scale` so that powers stay near 1, and the exact linear map back to
//! the parameters in counts (b, k, k2, k3, b_t, k_t) with their covariance.

use crate::lsq::gh::Conditions;
pub use ingest::contract::manifest::Misalignment;

/// Which terms a calibration model has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Terms {
    /// Polynomial order, 1..=3.
    pub order: usize,
    /// Bias and scale depend linearly on temperature.
    pub temperature: bool,
    /// The misalignment: none, beta (the tilt plane), or theta_x, theta_y (the vector).
    pub misalignment: Misalignment,
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
        match self.misalignment {
            Misalignment::None => {}
            Misalignment::Plane => v.push(ParamName {
                name: "beta",
                unit: "rad",
            }),
            Misalignment::Vector => {
                v.push(ParamName {
                    name: "theta_x",
                    unit: "rad",
                });
                v.push(ParamName {
                    name: "theta_y",
                    unit: "rad",
                });
            }
        }
        v
    }

    /// Parameters of the misalignment.
    fn n_misalignment(&self) -> usize {
        match self.misalignment {
            Misalignment::None => 0,
            Misalignment::Plane => 1,
            Misalignment::Vector => 2,
        }
    }

    /// Number of parameters.
    pub fn len(&self) -> usize {
        self.order + 1 + 2 * usize::from(self.temperature) + self.n_misalignment()
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
/// Observations are `(Dz, Ng, T)`: the temperature is an observation with the sd the
/// thermometer's noise gives it (0: exact); without temperature terms it enters nothing.
/// With the misalignment as a vector (docs/model.md 6.4) the
/// reference is `g_i (s_z cos Dz - s_perp sin Dz)`: `s_perp = theta_x cos(roll) +
/// theta_y sin(roll)` is the sensitive axis's component in the tilt plane at the session's
/// roll, `s_z = sqrt(1 - theta_x^2 - theta_y^2)`; at roll 0, theta_x is beta (sin beta).
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
    /// Body tide at each observation, mGal; empty when none is applied (all 0).
    pub tide_mgal: &'a [f64],
    /// Roll of the block at each observation, rad; read by the vector misalignment only,
    /// and empty without it.
    pub roll_rad: &'a [f64],
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
        for j in at..n {
            m[j * n + j] = 1.0;
        }
        m
    }
}

impl Conditions<3> for CalibrationConditions<'_> {
    fn n_params(&self) -> usize {
        self.terms.len()
    }

    fn eval(&self, i: usize, p: &[f64], l: [f64; 3], a: &mut [f64]) -> (f64, [f64; 3]) {
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
        // dc/dT: the temperature terms' slope at this x.
        let mut by_t = 0.0;
        if self.terms.temperature {
            let tau = l[2] - self.t_ref_c;
            a[at] = tau;
            a[at + 1] = tau * x;
            value += (p[at] + p[at + 1] * x) * tau;
            slope += p[at + 1] * tau;
            by_t = p[at] + p[at + 1] * x;
            at += 2;
        }
        let tide = if self.tide_mgal.is_empty() {
            0.0
        } else {
            self.tide_mgal[i]
        };
        let g = self.g_mgal + tide;
        let (dz, sl) = (l[0], slope / self.scale);
        match self.terms.misalignment {
            Misalignment::Vector => {
                let (tx, ty) = (p[at], p[at + 1]);
                let (sin_r, cos_r) = self.roll_rad[i].sin_cos();
                let s_perp = tx * cos_r + ty * sin_r;
                let s_z = (1.0 - tx * tx - ty * ty).max(0.0).sqrt();
                let (sin_d, cos_d) = dz.sin_cos();
                a[at] = g * (-tx / s_z * cos_d - cos_r * sin_d);
                a[at + 1] = g * (-ty / s_z * cos_d - sin_r * sin_d);
                (
                    g * (s_z * cos_d - s_perp * sin_d) + value,
                    [-g * (s_z * sin_d + s_perp * cos_d), sl, by_t],
                )
            }
            Misalignment::Plane | Misalignment::None => {
                let beta = if self.terms.misalignment.any() {
                    p[at]
                } else {
                    0.0
                };
                let angle = dz + beta;
                let g_sin = g * angle.sin();
                if self.terms.misalignment.any() {
                    a[at] = -g_sin;
                }
                (g * angle.cos() + value, [-g_sin, sl, by_t])
            }
        }
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
            misalignment: Misalignment::Plane,
        };
        let names: Vec<&str> = t.names().iter().map(|n| n.name).collect();
        assert_eq!(names, ["b", "k", "k2", "b_t", "k_t", "beta"]);
        assert_eq!(t.len(), 6);
        let v = Terms {
            misalignment: Misalignment::Vector,
            ..t
        };
        let names: Vec<&str> = v.names().iter().map(|n| n.name).collect();
        assert_eq!(names, ["b", "k", "k2", "b_t", "k_t", "theta_x", "theta_y"]);
        assert_eq!(v.len(), 7);
    }

    /// The conditions of a tilt table at 980 000 mGal, the counts centred on 1.4e6 and
    /// scaled by 1e5, 25 degC the reference.
    fn conditions<'a>(
        terms: Terms,
        tides: &'a [f64],
        rolls: &'a [f64],
    ) -> CalibrationConditions<'a> {
        CalibrationConditions {
            terms,
            g_mgal: 980_000.0,
            centre: 1.4e6,
            scale: 1e5,
            t_ref_c: 25.0,
            tide_mgal: tides,
            roll_rad: rolls,
        }
    }

    /// With temperature terms, the condition's derivative by the temperature (the
    /// temperature an observation) is the numerical one: b_t + k_t Ng in the scaled terms.
    #[test]
    fn temperature_derivative_is_the_numerical_one() {
        let (tides, rolls) = ([0.0], [0.0]);
        let terms = Terms {
            order: 2,
            temperature: true,
            misalignment: Misalignment::None,
        };
        let c = conditions(terms, &tides, &rolls);
        let p = [-29_500.0, 24_300.0, 12.0, 35.0, -4.0];
        let l = [2.1, 1.45e6, 27.3];
        let mut a = [0.0; 5];
        let (_, b) = c.eval(0, &p, l, &mut a);
        let h = 1e-3;
        let up = c.eval(0, &p, [l[0], l[1], l[2] + h], &mut [0.0; 5]).0;
        let down = c.eval(0, &p, [l[0], l[1], l[2] - h], &mut [0.0; 5]).0;
        let numerical = (up - down) / (2.0 * h);
        assert!(
            (numerical - b[2]).abs() < 1e-9 * b[2].abs(),
            "{numerical} {}",
            b[2]
        );
        assert!((b[2] - (35.0 - 4.0 * 0.5)).abs() < 1e-9, "{}", b[2]);
    }

    /// The vector condition's derivatives are the numerical ones, and at roll 0 with
    /// theta_y = 0 it is the plane condition with beta = asin(theta_x).
    #[test]
    fn vector_condition_derivatives_and_the_plane() {
        let tides = [0.0];
        let rolls = [0.7];
        let terms = Terms {
            order: 1,
            temperature: false,
            misalignment: Misalignment::Vector,
        };
        let c = conditions(terms, &tides, &rolls);
        let p = [-29_500.0, 24_300.0, 3e-4, -2e-4];
        let l = [2.1, 1.45e6, 25.0];
        let mut a = [0.0; 4];
        let (f, b) = c.eval(0, &p, l, &mut a);
        let h = 1e-7;
        for j in 2..4 {
            let mut q = p;
            q[j] += h;
            let mut dummy = [0.0; 4];
            let (f2, _) = c.eval(0, &q, l, &mut dummy);
            assert!(((f2 - f) / h - a[j]).abs() < 1e-3 * a[j].abs(), "{j}");
        }
        let (f3, _) = c.eval(0, &p, [l[0] + 1e-7, l[1], l[2]], &mut [0.0; 4]);
        assert!(((f3 - f) / 1e-7 - b[0]).abs() < 1e-3 * b[0].abs());
        // Without temperature terms the temperature enters nothing.
        assert!(b[2].abs() < f64::MIN_POSITIVE, "{}", b[2]);
        let zero_roll = [0.0];
        let v = CalibrationConditions {
            roll_rad: &zero_roll,
            ..c
        };
        let plane = CalibrationConditions {
            terms: Terms {
                misalignment: Misalignment::Plane,
                ..terms
            },
            roll_rad: &zero_roll,
            ..c
        };
        let (fv, _) = v.eval(0, &[p[0], p[1], 3e-4, 0.0], l, &mut [0.0; 4]);
        let (fp, _) = plane.eval(0, &[p[0], p[1], 3e-4f64.asin()], l, &mut [0.0; 3]);
        assert!((fv - fp).abs() < 1e-6, "{fv} {fp}");
    }
}
