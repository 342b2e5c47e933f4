//! The inputs' declared error models carried through the reduction (docs/model.md 7, "Error
//! models"), free of I/O. An input's sd says how large its error is at one sample; the
//! manifest says how that error behaves over time (`[survey] attitude_errors`,
//! `position_errors`): white (independent per sample), correlated (a first-order
//! Gauss-Markov process with a correlation time tau) or systematic (one error over a
//! stretch). The filtered value's sigma follows from the model through the same linear
//! operators as the value itself:
//!
//! - white: the sum over the filter's row of its squares times each epoch's variance, times
//!   the input's interval over the epochs' (a white error at an interval T_a has the
//!   low-frequency spectrum s^2 T_a, whatever the interpolation and the epochs' triangle do
//!   above the cut-off);
//! - correlated: the row's quadratic form with the autocovariance rho^|i - j|, rho =
//!   exp(-T / tau), at each epoch's own sensitivities (O(row) per epoch by the process's
//!   recursion);
//! - systematic: the sensitivities themselves filtered (signed: a swell's changing sign
//!   cancels as it does in the value), squared.
//!
//! The attitude's three angles' errors are independent of one another; each acts on the
//! specific force through delta f = eps x f, so that its effect at an epoch is a signed
//! sensitivity ([`attitude_effects`]).

use super::filter;
use ingest::contract::survey::ErrorModel;

/// The attitude's error model and the interval of its samples, s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttitudeErrors {
    /// The declared model.
    pub model: ErrorModel,
    /// The attitude file's median interval, s.
    pub interval_s: f64,
}

impl Default for AttitudeErrors {
    fn default() -> Self {
        AttitudeErrors {
            model: ErrorModel::White,
            interval_s: 0.0,
        }
    }
}

/// The effect on the specific force north, east and down (mGal) of a one-sd error of the
/// heading, the pitch and the roll, each signed, `[component][angle]`, at heading `heading`
/// (rad) with sds `sd` (heading, pitch, roll; rad) for the specific force `f` (N, E, D,
/// mGal): eps_N = cos(h) d_roll - sin(h) d_pitch, eps_E = sin(h) d_roll + cos(h) d_pitch,
/// eps_D = d_heading, delta f = eps x f. Down is first order only in the horizontal
/// specific force (a turn's centripetal acceleration: 0.17 m/s^2 times 0.1 mrad is 1.7
/// mGal); its second-order part, g eps^2 / 2, is 0.005 mGal at 0.1 mrad and left out.
pub fn attitude_effects(heading: f64, sd: [f64; 3], f: [f64; 3]) -> [[f64; 3]; 3] {
    let (sh, ch) = heading.sin_cos();
    let [s_head, s_pitch, s_roll] = sd;
    [
        // north = eps_E f_D - eps_D f_E
        [-f[1] * s_head, ch * f[2] * s_pitch, sh * f[2] * s_roll],
        // east = eps_D f_N - eps_N f_D
        [f[0] * s_head, sh * f[2] * s_pitch, -ch * f[2] * s_roll],
        // down = eps_N f_E - eps_E f_N
        [
            0.0,
            (-sh * f[1] - ch * f[0]) * s_pitch,
            (ch * f[1] - sh * f[0]) * s_roll,
        ],
    ]
}

/// [`attitude_effects`] for an attitude whose error is given as the covariance `c` (rad^2)
/// of a small rotation eps of the navigation frame (north, east, down; an antenna array's):
/// its Cholesky factor's columns are three independent one-sd errors e_k, each moving the
/// specific force by e_k x f, `[component][k]`. For independent angle errors this is the
/// same sum of squares as [`attitude_effects`]' (the covariance then has the angles' axes
/// as its eigenvectors); correlated ones are carried whole. A covariance that is not
/// positive definite (a degenerate array's) gives NaN effects.
pub fn attitude_effects_of_covariance(c: &[[f64; 3]; 3], f: [f64; 3]) -> [[f64; 3]; 3] {
    let m = faer::Mat::<f64>::from_fn(3, 3, |i, j| c[i][j]);
    let Ok(llt) = m.llt(faer::Side::Lower) else {
        return [[f64::NAN; 3]; 3];
    };
    let l = llt.L();
    let sources: [[f64; 3]; 3] = std::array::from_fn(|k| std::array::from_fn(|i| l[(i, k)]));
    let mut out = [[0.0; 3]; 3];
    for (k, e) in sources.iter().enumerate() {
        // delta f = e x f.
        out[0][k] = e[1] * f[2] - e[2] * f[1];
        out[1][k] = e[2] * f[0] - e[0] * f[2];
        out[2][k] = e[0] * f[1] - e[1] * f[0];
    }
    out
}

/// The sd of each epoch's filtered attitude error, mGal, from the signed one-sd effects `b`
/// of the three angles at each epoch (epochs `dt` s apart, the first the `first_epoch`-th of
/// its grid, [`epoch_number`]), under `errors`. The filter (period `filter_s`) is applied
/// with the stretch's ends treated as the value's are.
pub fn attitude_sigma(
    b: &[[f64; 3]],
    errors: AttitudeErrors,
    filter: &filter::StretchFilter,
    first_epoch: i64,
    dt: f64,
    filter_s: f64,
) -> Vec<f64> {
    let sections = &filter.lowpass;
    let n = b.len();
    let angles: Vec<Vec<f64>> = (0..3)
        .map(|a| b.iter().map(|v| v[a]).collect::<Vec<f64>>())
        .filter(|x| x.iter().any(|v| *v != 0.0))
        .collect();
    // Each angle's effect filtered: what a systematic error leaves, exactly at every epoch
    // (white errors need none of it).
    let systematic: Vec<Vec<f64>> = match errors.model {
        ErrorModel::White => Vec::new(),
        _ => angles.iter().map(|x| filter.apply(x)).collect(),
    };
    let squares = |k: usize| systematic.iter().map(|y| y[k] * y[k]).sum::<f64>();
    let grid = Grid {
        n,
        first_epoch,
        step: step(filter_s, dt),
    };
    let var: Vec<f64> = match errors.model {
        ErrorModel::Systematic => (0..n).map(squares).collect(),
        ErrorModel::White => {
            let row = trimmed_row(sections, dt, filter_s);
            let v: Vec<f64> = b.iter().map(|e| e.iter().map(|x| x * x).sum()).collect();
            let ratio = errors.interval_s / dt;
            grid.interpolated(|k| ratio * white_form(&row, &v, k))
        }
        ErrorModel::Correlated { correlation_s } => {
            // The form less the systematic part is interpolated, the systematic part added
            // at every epoch: where a slowly correlated error's filtered effect changes sign
            // its variance has a parabola's minimum that an interpolation of the whole
            // would fill in.
            let row = trimmed_row(sections, dt, filter_s);
            let rho = (-dt / correlation_s).exp();
            let rest = grid.interpolated(|k| {
                angles
                    .iter()
                    .map(|x| markov_form(&row, x, rho, k) - markov_form(&row, x, 1.0, k))
                    .sum()
            });
            (0..n).map(|k| squares(k) + rest[k]).collect()
        }
    };
    var.into_iter().map(|v| v.max(0.0).sqrt()).collect()
}

/// The number of the first of `time_gps_ns`'s epochs, `dt` s apart, counted from GPS zero.
pub fn epoch_number(time_gps_ns: &[i64], dt: f64) -> i64 {
    time_gps_ns
        .first()
        .map_or(0, |t| (*t as f64 / (dt * 1e9)).round() as i64)
}

/// The epochs at which a slowly changing variance is computed exactly: every `step`-th of
/// the survey's epoch count from GPS zero (so that a stretch reduced in blocks meets the
/// same epochs as whole), and each end.
struct Grid {
    n: usize,
    first_epoch: i64,
    step: usize,
}

impl Grid {
    /// `f` at the grid's epochs, linearly interpolated between.
    fn interpolated(&self, f: impl Fn(usize) -> f64) -> Vec<f64> {
        let (n, step) = (self.n, self.step as i64);
        let mut out = vec![0.0; n];
        if n == 0 {
            return out;
        }
        let mut at: Vec<usize> = vec![0];
        let first = (step - self.first_epoch.rem_euclid(step)) % step;
        at.extend((first as usize..n).step_by(self.step).filter(|&k| k > 0));
        if at.last() != Some(&(n - 1)) {
            at.push(n - 1);
        }
        let vals: Vec<f64> = at.iter().map(|&k| f(k)).collect();
        for w in 0..at.len() {
            let (k0, v0) = (at[w], vals[w]);
            let (k1, v1) = if w + 1 < at.len() {
                (at[w + 1], vals[w + 1])
            } else {
                (k0 + 1, v0)
            };
            for k in k0..k1.min(n) {
                let f = (k - k0) as f64 / (k1 - k0) as f64;
                out[k] = v0 + f * (v1 - v0);
            }
        }
        out
    }
}

/// The sd of a stretch's filtered value from positions whose `sd` (in the output's unit,
/// e.g. m times 1e5 for mGal) follows a model that is not white, through the operator whose
/// interior row is `row` (the second difference and the filter, [`super::reduce::row`]):
/// correlated, the row's quadratic form with the autocovariance (one gain, the sd taken at
/// each epoch); systematic, nothing through the second difference (a constant position
/// has no acceleration), and `free_air` times the sd for the height's part in normal
/// gravity (0.3086 mGal/m times 1e-5 per mGal of height error, down; 0 north and east).
pub fn position_sigma(
    row: &[f64],
    sd: &[f64],
    model: ErrorModel,
    dt: f64,
    free_air: f64,
) -> Vec<f64> {
    match model {
        ErrorModel::White => vec![0.0; sd.len()],
        ErrorModel::Systematic => sd.iter().map(|s| s * free_air).collect(),
        ErrorModel::Correlated { correlation_s } => {
            let rho = (-dt / correlation_s).exp();
            let gain = markov_form(row, &vec![1.0; row.len()], rho, row.len() / 2)
                .max(0.0)
                .sqrt();
            sd.iter().map(|s| s * gain).collect()
        }
    }
}

/// The row of the filter alone at a stretch's interior ([`super::reduce::row`]), trimmed to
/// where its tails hold under 1e-10 of its squares' sum (about four filter periods either
/// side).
fn trimmed_row(sections: &filter::Lowpass, dt: f64, filter_s: f64) -> Vec<f64> {
    let full = super::reduce::row(sections, super::reduce::reach(filter_s, dt), None);
    let total: f64 = full.iter().map(|v| v * v).sum();
    let mid = full.len() / 2;
    let mut tail = 0.0;
    let mut keep = mid;
    while keep > 0 {
        let next = full[mid - keep].powi(2) + full[mid + keep].powi(2);
        if tail + next > 1e-10 * total {
            break;
        }
        tail += next;
        keep -= 1;
    }
    full[mid - keep..=mid + keep].to_vec()
}

/// How many epochs apart a variance is computed exactly (and linearly interpolated
/// between): a twentieth of the filter period, over which it changes by little (the row
/// spans eighty of them).
fn step(filter_s: f64, dt: f64) -> usize {
    ((filter_s / dt / 20.0).floor() as usize).max(1)
}

/// The input's index at row position `i` for output epoch `k`: beyond the stretch's ends,
/// the end's (its sensitivity and sd continue there as the value's extension does).
fn at(k: usize, i: usize, half: usize, n: usize) -> usize {
    (k + i).saturating_sub(half).min(n - 1)
}

/// sum_i row_i^2 v_{k+i-half}: the filtered variance of white errors of variances `v`.
fn white_form(row: &[f64], v: &[f64], k: usize) -> f64 {
    let (half, n) = (row.len() / 2, v.len());
    row.iter()
        .enumerate()
        .map(|(i, r)| r * r * v[at(k, i, half, n)])
        .sum()
}

/// sum_ij a_i a_j rho^|i-j| with a_i = row_i x_{k+i-half}: the filtered variance of a unit
/// Gauss-Markov error of correlation rho per epoch acting through the effects `x`, by the
/// recursion c_i = rho (c_{i-1} + a_{i-1}).
fn markov_form(row: &[f64], x: &[f64], rho: f64, k: usize) -> f64 {
    let (half, n) = (row.len() / 2, x.len());
    let (mut sum, mut c, mut prev) = (0.0, 0.0, 0.0);
    for (i, r) in row.iter().enumerate() {
        let a = r * x[at(k, i, half, n)];
        c = rho * (c + prev);
        sum += a * a + 2.0 * a * c;
        prev = a;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filter_of(filter_s: f64, dt: f64) -> filter::Lowpass {
        filter::Lowpass::Butterworth(
            filter::butterworth(filter::ORDER, 1.0 / filter_s, 1.0 / dt).expect("filter"),
        )
    }

    /// The effects agree with the sigmas of the old form: each component's three effects in
    /// quadrature are |delta f| for independent angles.
    #[test]
    fn the_effects_are_the_cross_product_of_the_tilt() {
        let g = 980_000.0;
        let e = attitude_effects(0.0, [1e-3, 1e-4, 0.0], [0.0, 0.0, -g]);
        assert!((e[0][1].abs() - 98.0).abs() < 1e-9, "{e:?}");
        assert!(e[1].iter().all(|v| v.abs() < 1e-9), "{e:?}");
        // A centripetal 16 700 mGal east, roll heading north: 1.67 mGal down.
        let e = attitude_effects(0.0, [0.0, 0.0, 1e-4], [0.0, 16_700.0, -g]);
        assert!((e[2][2] - 1.67).abs() < 1e-9, "{e:?}");
        // The sign: a roll to starboard (positive) heading north tilts the force west.
        let e = attitude_effects(0.0, [0.0, 0.0, 1e-4], [0.0, 0.0, -g]);
        assert!(e[1][2] > 0.0, "{e:?}");
    }

    /// The covariance form of independent angle errors gives each component the same sum of
    /// squares as the angles' form, at any heading, with a turn's horizontal force.
    #[test]
    fn the_covariance_form_agrees_with_independent_angles() {
        let f = [1200.0, -16_700.0, -980_000.0];
        for heading in [0.0, 0.7, 2.5, -1.9] {
            let sd: [f64; 3] = [1e-3, 2e-4, 1e-4];
            let e = attitude_effects(heading, sd, f);
            // eps = M (dh, dp, dr): columns down, (-sin h, cos h, 0), (cos h, sin h, 0).
            let (s, c) = f64::sin_cos(heading);
            let m = [[0.0, -s, c], [0.0, c, s], [1.0, 0.0, 0.0]];
            let cov: [[f64; 3]; 3] = std::array::from_fn(|i| {
                std::array::from_fn(|j| (0..3).map(|k| m[i][k] * sd[k] * sd[k] * m[j][k]).sum())
            });
            let g = attitude_effects_of_covariance(&cov, f);
            for comp in 0..3 {
                let a: f64 = e[comp].iter().map(|v| v * v).sum();
                let b: f64 = g[comp].iter().map(|v| v * v).sum();
                assert!(
                    (a - b).abs() <= 1e-9 * a.max(1e-12),
                    "{heading} {comp}: {a} {b}"
                );
            }
        }
    }

    /// The three models against a Monte-Carlo of the same filter: unit errors drawn white,
    /// Gauss-Markov (tau 300 s) and constant, through an oscillating sensitivity (a swell at
    /// 8 s times a steady part), filtered; the sample sd at the middle against the
    /// propagated one.
    #[test]
    fn each_model_matches_a_monte_carlo_of_the_filter() {
        let (dt, filter_s, n) = (0.5, 60.0, 2000usize);
        let sections = filter_of(filter_s, dt);
        let sens: Vec<f64> = (0..n)
            .map(|k| 3.0 + 10.0 * (std::f64::consts::TAU * k as f64 * dt / 8.0).sin())
            .collect();
        let b: Vec<[f64; 3]> = sens.iter().map(|s| [0.0, *s, 0.0]).collect();
        let mut state = 11u64;
        let mut normal = move || {
            // Box-Muller from an LCG: enough for a test of second moments.
            let mut u = || {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (u1, u2) = (u(), u());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        };
        for model in [
            ErrorModel::White,
            ErrorModel::Correlated {
                correlation_s: 300.0,
            },
            ErrorModel::Systematic,
        ] {
            let errors = AttitudeErrors {
                model,
                interval_s: dt,
            };
            let unpadded = filter::StretchFilter {
                lowpass: sections.clone(),
                pad: 0,
                pivot: 1,
            };
            let want = attitude_sigma(&b, errors, &unpadded, 0, dt, filter_s)[n / 2];
            let runs = 1500;
            let mut sum2 = 0.0;
            for _ in 0..runs {
                let rho = match model {
                    ErrorModel::White => 0.0,
                    ErrorModel::Correlated { correlation_s } => (-dt / correlation_s).exp(),
                    ErrorModel::Systematic => 1.0,
                };
                let mut e = normal();
                let x: Vec<f64> = (0..n)
                    .map(|k| {
                        if k > 0 {
                            e = rho * e + (1.0 - rho * rho).sqrt() * normal();
                        }
                        sens[k] * e
                    })
                    .collect();
                let y = sections.apply(&x, 0, 1);
                sum2 += y[n / 2].powi(2);
            }
            let got = (sum2 / f64::from(runs)).sqrt();
            assert!(
                (got / want - 1.0).abs() < 0.06,
                "{model:?}: Monte-Carlo {got}, propagated {want}"
            );
        }
    }

    /// White errors at a tenth of the epochs' interval average within each epoch: the sd
    /// falls by sqrt(10).
    #[test]
    fn a_faster_white_input_averages_within_the_epoch() {
        let (dt, filter_s) = (1.0, 50.0);
        let unpadded = filter::StretchFilter {
            lowpass: filter_of(filter_s, dt),
            pad: 0,
            pivot: 1,
        };
        let b = vec![[0.0, 1.0, 0.0]; 1000];
        let sd = |interval_s| {
            attitude_sigma(
                &b,
                AttitudeErrors {
                    model: ErrorModel::White,
                    interval_s,
                },
                &unpadded,
                0,
                dt,
                filter_s,
            )[500]
        };
        assert!((sd(1.0) / sd(0.1) - 10f64.sqrt()).abs() < 1e-9);
    }
}
