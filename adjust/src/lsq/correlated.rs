//! ADC noise the weights cannot carry (docs/model.md 6.2). Flicker and a random walk of the bias
//! move the window means of a session together: the weights hold their Allan variance at
//! the window's length, but not that the error of one station's mean is nearly that of the
//! next, or of the next hour. This propagates the correlated part into the parameters'
//! covariance (the sandwich M (C - D) M^T, with M the adjustment's gain from the counts to
//! the parameters, C the covariance of the window means' coloured errors under
//! `align::colour`'s model and D its diagonal already in the weights), in time linear in
//! the observations: the model's covariances are sums of exponentials and a minimum, both
//! separable in time order. Sessions are independent. No I/O.

use crate::lsq::gh::Solution;
use align::colour::{Flicker, WindowedFlicker};

/// The coloured ADC noise of one accelerometer, in counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColouredAdc {
    /// Bias instability B, counts.
    pub bias_instability: f64,
    /// Random walk K, counts / sqrt(s).
    pub random_walk: f64,
    /// The window's length, s.
    pub window_s: f64,
    /// The dof of B^2 as align's Allan curve determined it (None: known).
    pub bias_instability_dof: Option<f64>,
    /// The dof of K^2, alike.
    pub random_walk_dof: Option<f64>,
}

impl ColouredAdc {
    /// The variance align added to a window mean's: the coloured terms of the Allan variance
    /// at the window's length.
    pub fn window_variance(&self) -> f64 {
        align::allan::NoiseTerms {
            white_density: 0.0,
            bias_instability: self.bias_instability,
            random_walk: self.random_walk,
        }
        .allan_variance(self.window_s)
    }
}

/// When each observation was read: its window's centre, s, and its session's index
/// (0..sessions). The coloured noise correlates observations within a session only.
#[derive(Clone, Copy, Debug)]
pub struct Timeline<'a> {
    /// Window centre per observation, s.
    pub time_s: &'a [f64],
    /// Session index per observation.
    pub session: &'a [usize],
}

impl Timeline<'_> {
    /// The first observation time of each session, by session index.
    fn session_starts(&self) -> Vec<f64> {
        let mut first = vec![f64::INFINITY; self.sessions()];
        for (&t, &s) in self.time_s.iter().zip(self.session) {
            first[s] = first[s].min(t);
        }
        first
    }

    /// How many sessions the indices run over.
    fn sessions(&self) -> usize {
        self.session.iter().max().map_or(0, |v| v + 1)
    }
}

/// Observations by station: `station[i]` in 0..stations, each station's indices in order.
fn station_members(station: &[usize]) -> Vec<Vec<usize>> {
    let stations = station.iter().max().map_or(0, |v| v + 1);
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); stations];
    for (i, &j) in station.iter().enumerate() {
        members[j].push(i);
    }
    members
}

/// L^T R, m x m row-major, for n x m matrices `l` and `r` (a row per observation).
fn cross(l: &[Vec<f64>], r: &[Vec<f64>], m: usize) -> Vec<f64> {
    let mut acc = vec![0.0; m * m];
    for (li, ri) in l.iter().zip(r) {
        for a in 0..m {
            for b in 0..m {
                acc[a * m + b] += li[a] * ri[b];
            }
        }
    }
    acc
}

/// The covariance the coloured noise adds to the parameters of solution `s` (its internal
/// parameters, m x m row-major): observation i at `time_s[i]` in session `session[i]`, the
/// counts its second observed quantity.
pub fn extra_covariance(s: &Solution<3>, at: Timeline<'_>, noise: &ColouredAdc) -> Vec<f64> {
    let m = s.p.len();
    let n = s.q_ww.len();
    // Gain of observation i's counts: dp/dNg_i = -Q_pp a_i B_i2 / q_i.
    let gain: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            let f = -s.b[i][1] / s.q_ww[i];
            q_pp_a(s, i).into_iter().map(|v| v * f).collect()
        })
        .collect();
    // sum_ij g_i g_j^T (C - D)_ij = G^T ((C - D) G).
    let cg = apply_excess(&gain, at, noise);
    let mut acc = cross(&gain, &cg, m);
    // Symmetric up to rounding; make it exactly so.
    for r in 0..m {
        for q in 0..r {
            let v = 0.5 * (acc[r * m + q] + acc[q * m + r]);
            acc[r * m + q] = v;
            acc[q * m + r] = v;
        }
    }
    acc
}

/// Q_pp a_i: the parameters' cofactor matrix times condition `i`'s design row, the part of
/// its gain the weights and the counts' partial then scale.
pub(crate) fn q_pp_a(s: &Solution<3>, i: usize) -> Vec<f64> {
    let m = s.p.len();
    (0..m)
        .map(|r| {
            (0..m)
                .map(|c| s.q_pp[r * m + c] * s.a[i * m + c])
                .sum::<f64>()
        })
        .collect()
}

/// `C x` for an n x k matrix `x` (row per observation): the coloured noise's covariance of
/// the window means less what the weights hold (C - D), within each session, by forward and
/// backward passes in time order. Windows are taken not to overlap (a pair that does is
/// counted as if its windows touched): a session's readings are seconds apart.
pub fn apply_excess(x: &[Vec<f64>], at: Timeline<'_>, noise: &ColouredAdc) -> Vec<Vec<f64>> {
    let n = x.len();
    let k = x.first().map_or(0, Vec::len);
    let flicker = Flicker::new(noise.bias_instability);
    let factors = flicker.window_factors(noise.window_s);
    let k2 = noise.random_walk.powi(2);
    // The diagonal: less what the weights hold, and what a window's mean takes off the
    // points' variance (the flicker's g - f per process, the random walk's K^2 w / 6).
    let d = noise.window_variance()
        + k2 * noise.window_s / 6.0
        + factors
            .iter()
            .map(|(f, g)| flicker.variance * (f - g))
            .sum::<f64>();
    let mut y: Vec<Vec<f64>> = x
        .iter()
        .map(|r| r.iter().map(|v| -d * v).collect())
        .collect();
    let Timeline { time_s, session } = at;
    for sess in 0..at.sessions() {
        let mut order: Vec<usize> = (0..n).filter(|&i| session[i] == sess).collect();
        order.sort_by(|&a, &b| time_s[a].total_cmp(&time_s[b]));
        let Some(&first) = order.first() else {
            continue;
        };
        for (&t, &(f, _)) in flicker.time_constants_s.iter().zip(&factors) {
            let variance = flicker.variance * f;
            // Forward: sum over j <= i; backward: over j > i.
            let mut run = vec![0.0; k];
            let mut last = time_s[first];
            for &i in &order {
                let decay = (-(time_s[i] - last) / t).exp();
                last = time_s[i];
                for (r, v) in run.iter_mut().zip(&x[i]) {
                    *r = *r * decay + v;
                }
                for (out, r) in y[i].iter_mut().zip(&run) {
                    *out += variance * r;
                }
            }
            let mut run = vec![0.0; k];
            let mut next: Option<usize> = None;
            for &i in order.iter().rev() {
                if let Some(j) = next {
                    let decay = (-(time_s[j] - time_s[i]) / t).exp();
                    for (r, v) in run.iter_mut().zip(&x[j]) {
                        *r = (*r + v) * decay;
                    }
                }
                next = Some(i);
                for (out, r) in y[i].iter_mut().zip(&run) {
                    *out += variance * r;
                }
            }
        }
        add_random_walk(&mut y, x, &order, |i| time_s[i] - time_s[first], k2);
    }
    y
}

/// The expectation, under the coloured noise, of a solution's between-station quadratic
/// form sum_j share_j (u_j^T e)^2 / W_j (u_j: the weights of station j's observations, W_j
/// their sum, e the misclosure residuals), beyond what the weights predict: what the
/// variance components and the global test must not mistake for the theodolite.
pub fn between_station_excess(
    s: &Solution<3>,
    station: &[usize],
    share: &[f64],
    at: Timeline<'_>,
    noise: &ColouredAdc,
) -> f64 {
    let n = s.q_ww.len();
    let m = s.p.len();
    let w: Vec<f64> = s.q_ww.iter().map(|q| 1.0 / q).collect();
    let bng: Vec<f64> = s.b.iter().map(|b| b[1]).collect();
    // e = R eps with R = I - A Q_pp A^T W and eps_i = B_i2 dNg_i: cov(eps) = Bn C Bn.
    // X = Bn W A (n x m); CX = Bn (C - D) Bn W A.
    let x: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..m).map(|c| bng[i] * w[i] * s.a[i * m + c]).collect())
        .collect();
    let c_x = apply_excess(&x, at, noise);
    // A^T W Bn (C - D) Bn W A = X^T (C - D) X.
    let xcx = cross(&x, &c_x, m);
    let cx: Vec<Vec<f64>> = c_x
        .into_iter()
        .enumerate()
        .map(|(i, r)| r.into_iter().map(|v| v * bng[i]).collect())
        .collect();
    let Timeline { time_s, session } = at;
    let firsts = at.session_starts();
    let members = station_members(station);
    let flicker = Flicker::new(noise.bias_instability);
    let windows = flicker.windowed(noise.window_s);
    let mut total = 0.0;
    for (j, obs) in members.iter().enumerate() {
        if obs.is_empty() {
            continue;
        }
        let sum_w: f64 = obs.iter().map(|&i| w[i]).sum();
        // h = Q_pp A^T u_j.
        let atu: Vec<f64> = (0..m)
            .map(|c| obs.iter().map(|&i| s.a[i * m + c] * w[i]).sum())
            .collect();
        let h: Vec<f64> = (0..m)
            .map(|r| (0..m).map(|c| s.q_pp[r * m + c] * atu[c]).sum())
            .collect();
        // u^T Bn (C - D) Bn u within the station (one session, so the pairwise model).
        let first = firsts[session[obs[0]]];
        let mut local = 0.0;
        for &a in obs {
            for &b in obs {
                let c = pair_covariance(&windows, noise, (time_s[a], time_s[b], first), a == b);
                local += w[a] * bng[a] * c * bng[b] * w[b];
            }
        }
        // u^T (Bn (C - D) Bn W A) h.
        let cross: f64 = obs
            .iter()
            .map(|&i| w[i] * (0..m).map(|c| cx[i][c] * h[c]).sum::<f64>())
            .sum();
        let quad: f64 = (0..m)
            .map(|r| (0..m).map(|c| h[r] * xcx[r * m + c] * h[c]).sum::<f64>())
            .sum();
        total += share[j] * (local - 2.0 * cross + quad) / sum_w;
    }
    total
}

/// Adds the random walk's part of (C - D) x to `y` for one session's observations in time
/// `order`: K^2 (sum_{j<=i} tau_j x_j + tau_i sum_{j>i} x_j), `tau` the time since the
/// session's first observation.
fn add_random_walk(
    y: &mut [Vec<f64>],
    x: &[Vec<f64>],
    order: &[usize],
    tau: impl Fn(usize) -> f64,
    k2: f64,
) {
    let k = x.first().map_or(0, Vec::len);
    let mut below = vec![0.0; k];
    for &i in order {
        for (b, v) in below.iter_mut().zip(&x[i]) {
            *b += tau(i) * v;
        }
        for (out, b) in y[i].iter_mut().zip(&below) {
            *out += k2 * b;
        }
    }
    let mut above = vec![0.0; k];
    for &i in order.iter().rev() {
        for (out, a) in y[i].iter_mut().zip(&above) {
            *out += k2 * tau(i) * a;
        }
        for (a, v) in above.iter_mut().zip(&x[i]) {
            *a += v;
        }
    }
}

/// What the coloured noise adds to the variance of each condition's fitted misclosure
/// beyond the q_i r_i its weights give it: the diagonal of R S R^T, with R = I - A Q_pp A^T W
/// the map from the conditions' errors to the fitted misclosures and S = Bn (C - D) Bn the
/// errors' coloured covariance less what the weights hold, in time linear in the
/// observations. The w-test adds it to its reference (docs/model.md 6.2): a random walk
/// that no constant in the model absorbs makes the misclosures scatter more than their
/// weights say, and good readings were removed at 1.13 alpha.
pub fn misclosure_excess(s: &Solution<3>, at: Timeline<'_>, noise: &ColouredAdc) -> Vec<f64> {
    let n = s.q_ww.len();
    let m = s.p.len();
    let bng: Vec<f64> = s.b.iter().map(|b| b[1]).collect();
    // g_i = Q_pp a_i w_i, so that H = A G and (R S R^T)_ii = S_ii - 2 (H S)_ii + (H S H^T)_ii.
    let g: Vec<Vec<f64>> = (0..n)
        .map(|i| q_pp_a(s, i).into_iter().map(|v| v / s.q_ww[i]).collect())
        .collect();
    // Y = (C - D) Bn G^T; then S G^T = Bn Y.
    let x: Vec<Vec<f64>> = g
        .iter()
        .zip(&bng)
        .map(|(gi, b)| gi.iter().map(|v| v * b).collect())
        .collect();
    let y = apply_excess(&x, at, noise);
    // G S G^T = sum_i (g_i b_i) y_i^T = X^T Y.
    let gsg = cross(&x, &y, m);
    let Timeline { time_s, session } = at;
    let firsts = at.session_starts();
    let flicker = Flicker::new(noise.bias_instability);
    let windows = flicker.windowed(noise.window_s);
    (0..n)
        .map(|i| {
            let a = &s.a[i * m..(i + 1) * m];
            let t = time_s[i];
            let own = pair_covariance(&windows, noise, (t, t, firsts[session[i]]), true);
            let hs: f64 = a.iter().zip(&y[i]).map(|(a, y)| a * y).sum::<f64>() * bng[i];
            let hsh: f64 = (0..m)
                .map(|r| (0..m).map(|c| a[r] * gsg[r * m + c] * a[c]).sum::<f64>())
                .sum();
            bng[i] * bng[i] * own - 2.0 * hs + hsh
        })
        .collect()
}

/// What the coloured noise adds to the window means' scatter about their station's
/// weighted mean, sum_i (Ng_i - mean_j)^2 / sigma_i^2, beyond what the sigmas predict: its
/// expectation and its variance. The flicker moves the windows of a station apart, which
/// the ADC's variance component must not mistake for mis-weighting; and the windows move
/// together, so the scatter varies more than as many independent terms would.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Excess {
    /// Added expectation.
    pub mean: f64,
    /// Added variance.
    pub variance: f64,
}

/// The [`Excess`] of the within-station scatter of window means: per station the form is
/// y^T M y with M = W - w w^T / sum(w), y of covariance S = W^-1 + C (C the coloured
/// noise's, less the diagonal the weights hold), so its mean is tr(M S) and its variance
/// 2 tr((M S)^2); the excess is what they exceed m - 1 and 2 (m - 1) by.
///
/// Where a coloured level was estimated (align's Allan curve, on the dof given), the
/// variance also carries that estimate's own: the form's expectation takes the level's
/// part E_l = tr(M C_l) (its diagonal, which the weights hold, included) in proportion to
/// the level's square, so a level's square known to a relative variance 2 / nu adds
/// E_l^2 2 / nu. The ADC component's test then asks whether the scatter is what the
/// weights predict as far as the still intervals could tell them, not as though they knew.
pub fn within_station_excess(
    station: &[usize],
    sigma_ng: &[f64],
    at: Timeline<'_>,
    noise: &ColouredAdc,
) -> Excess {
    let mut excess = scatter_excess(station, sigma_ng, at, noise);
    let levels = [
        (
            ColouredAdc {
                random_walk: 0.0,
                ..*noise
            },
            noise.bias_instability_dof,
        ),
        (
            ColouredAdc {
                bias_instability: 0.0,
                ..*noise
            },
            noise.random_walk_dof,
        ),
    ];
    // sum over stations of tr(M) per unit of a diagonal added to every window.
    let members = station_members(station);
    let diagonal_trace: f64 = members
        .iter()
        .filter(|o| o.len() > 1)
        .map(|obs| {
            let w: Vec<f64> = obs.iter().map(|&i| sigma_ng[i].powi(-2)).collect();
            let sum_w: f64 = w.iter().sum();
            sum_w - w.iter().map(|x| x * x).sum::<f64>() / sum_w
        })
        .sum();
    for (level, dof) in levels {
        let (Some(nu), true) = (dof, level.bias_instability > 0.0 || level.random_walk > 0.0)
        else {
            continue;
        };
        let part = scatter_excess(station, sigma_ng, at, &level).mean
            + level.window_variance() * diagonal_trace;
        excess.variance += part * part * 2.0 / nu.max(1.0);
    }
    excess
}

/// [`within_station_excess`] at known levels.
fn scatter_excess(
    station: &[usize],
    sigma_ng: &[f64],
    at: Timeline<'_>,
    noise: &ColouredAdc,
) -> Excess {
    let Timeline { time_s, session } = at;
    let firsts = at.session_starts();
    let members = station_members(station);
    let flicker = Flicker::new(noise.bias_instability);
    let windows = flicker.windowed(noise.window_s);
    let mut total = Excess::default();
    for obs in members.iter().filter(|o| o.len() > 1) {
        let first = firsts[session[obs[0]]];
        let m = obs.len();
        let w: Vec<f64> = obs.iter().map(|&i| sigma_ng[i].powi(-2)).collect();
        let sum_w: f64 = w.iter().sum();
        // S = W^-1 + C, then M S = W S - w (w^T S) / sum(w).
        let mut s = vec![0.0; m * m];
        for (a, &ia) in obs.iter().enumerate() {
            for (b, &ib) in obs.iter().enumerate() {
                let c = pair_covariance(&windows, noise, (time_s[ia], time_s[ib], first), a == b);
                s[a * m + b] = c + if a == b { 1.0 / w[a] } else { 0.0 };
            }
        }
        let wts: Vec<f64> = (0..m)
            .map(|b| (0..m).map(|a| w[a] * s[a * m + b]).sum())
            .collect();
        let ms: Vec<f64> = (0..m * m)
            .map(|k| {
                let (a, b) = (k / m, k % m);
                w[a] * s[k] - w[a] * wts[b] / sum_w
            })
            .collect();
        let trace: f64 = (0..m).map(|a| ms[a * m + a]).sum();
        let trace_sq: f64 = (0..m)
            .map(|a| (0..m).map(|b| ms[a * m + b] * ms[b * m + a]).sum::<f64>())
            .sum();
        total.mean += trace - (m - 1) as f64;
        total.variance += 2.0 * (trace_sq - (m - 1) as f64);
    }
    total
}

/// The model's covariance (less the diagonal the weights hold) of the window means centred
/// at `ta` and `tb` of one session that began at `first`; `same`: one and the same window.
/// The means' covariance, not the points': a window of 2.56 s averages away most of the
/// variance of the flicker's fastest processes, which the points' covariance would count as
/// scatter between a station's windows.
fn pair_covariance(
    windows: &WindowedFlicker<'_>,
    noise: &ColouredAdc,
    (ta, tb, first): (f64, f64, f64),
    same: bool,
) -> f64 {
    let k2 = noise.random_walk.powi(2);
    let c = windows.covariance(ta - tb) + k2 * (ta.min(tb) - first);
    // A window's mean of the random walk has K^2 (t - first - w / 6) of variance (t its
    // centre); two windows apart covary by K^2 (the earlier centre - first).
    if same {
        c - k2 * noise.window_s / 6.0 - noise.window_variance()
    } else {
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A solution of `m` parameters with these cofactors and designs (A row-major, B per
    /// observation), the rest as a test of the sums needs none of it.
    fn solution(
        m: usize,
        q_pp: Vec<f64>,
        q_ww: Vec<f64>,
        (a, b): (Vec<f64>, Vec<[f64; 3]>),
    ) -> Solution<3> {
        let n = q_ww.len();
        Solution {
            p: vec![0.0; m],
            q_pp,
            v: vec![[0.0; 3]; n],
            misclosure: vec![0.0; n],
            q_ww,
            q_parts: vec![[0.5, 0.5, 0.0]; n],
            redundancy: vec![0.5; n],
            w_test: vec![0.0; n],
            vtpv: 0.0,
            dof: n - m,
            iterations: 1,
            a,
            b,
        }
    }

    /// The flicker and random walk the sums are tested with.
    fn noise() -> ColouredAdc {
        ColouredAdc {
            bias_instability: 0.8,
            random_walk: 0.02,
            window_s: 2.56,
            bias_instability_dof: None,
            random_walk_dof: None,
        }
    }

    /// The within-station excess is the mean and variance of the scatter form itself: window
    /// means drawn from N(0, W^-1 + C) (C the model's, a random walk and a flicker), the form
    /// sum_i w_i (y_i - y_w)^2 over 40 000 draws has mean m - 1 + excess and variance
    /// 2 (m - 1) + excess, within 4 standard errors.
    #[test]
    fn within_station_excess_is_the_forms_mean_and_variance() {
        let noise = ColouredAdc {
            bias_instability: 0.6,
            random_walk: 0.05,
            window_s: 2.56,
            bias_instability_dof: None,
            random_walk_dof: None,
        };
        let time: Vec<f64> = vec![30.0, 60.0, 90.0, 300.0, 330.0, 600.0];
        let sigma: Vec<f64> = vec![1.0, 1.5, 1.0, 2.0, 1.0, 1.2];
        let m = time.len();
        let session = vec![0; m];
        let at = Timeline {
            time_s: &time,
            session: &session,
        };
        let excess = within_station_excess(&vec![0; m], &sigma, at, &noise);
        assert!(excess.mean > 0.5 && excess.variance > 1.0, "{excess:?}");
        // S and its Cholesky factor.
        let flicker = Flicker::new(noise.bias_instability);
        let windows = flicker.windowed(noise.window_s);
        let mut s = vec![0.0; m * m];
        for a in 0..m {
            for b in 0..m {
                let c = pair_covariance(&windows, &noise, (time[a], time[b], time[0]), a == b);
                s[a * m + b] = c + if a == b { sigma[a].powi(2) } else { 0.0 };
            }
        }
        let mut l = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..=i {
                let dot: f64 = (0..j).map(|k| l[i * m + k] * l[j * m + k]).sum();
                l[i * m + j] = if i == j {
                    (s[i * m + i] - dot).sqrt()
                } else {
                    (s[i * m + j] - dot) / l[j * m + j]
                };
            }
        }
        let mut rng = fixtures::rng::Rng::new(7, "within-station");
        let draws = 40_000;
        let w: Vec<f64> = sigma.iter().map(|x| x.powi(-2)).collect();
        let sum_w: f64 = w.iter().sum();
        let forms: Vec<f64> = (0..draws)
            .map(|_| {
                let z: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
                let y: Vec<f64> = (0..m)
                    .map(|i| (0..=i).map(|k| l[i * m + k] * z[k]).sum())
                    .collect();
                let mean = (0..m).map(|i| w[i] * y[i]).sum::<f64>() / sum_w;
                (0..m).map(|i| w[i] * (y[i] - mean).powi(2)).sum()
            })
            .collect();
        let n = f64::from(draws);
        let mean = forms.iter().sum::<f64>() / n;
        let variance = forms.iter().map(|f| (f - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let (want_mean, want_var) = (
            (m - 1) as f64 + excess.mean,
            2.0 * (m - 1) as f64 + excess.variance,
        );
        eprintln!("excess {excess:?}; form mean {mean:.3}, variance {variance:.3}");
        // The form's sd over sqrt(n); its variance's se from the fourth moment.
        let fourth = forms.iter().map(|f| (f - mean).powi(4)).sum::<f64>() / n;
        let se_var = ((fourth - variance * variance) / n).sqrt();
        assert!(
            (mean - want_mean).abs() < 4.0 * (variance / n).sqrt(),
            "mean {mean} vs {want_mean}"
        );
        assert!(
            (variance - want_var).abs() < 4.0 * se_var,
            "variance {variance} vs {want_var} (se {se_var})"
        );
        // The excess's variance matters: the known-sd variance alone is far off.
        assert!((variance - 2.0 * (m - 1) as f64).abs() > 6.0 * se_var);
    }

    /// The between-station excess equals its dense form: sum_j share_j u_j^T R S R^T u_j / W_j
    /// with R = I - A Q A^T W and S = Bn (C - D) Bn; and each misclosure's excess the
    /// diagonal of R S R^T.
    #[test]
    fn excesses_equal_their_dense_forms() {
        let (n, m) = (8, 2);
        let time: Vec<f64> = vec![0.0, 5.0, 10.0, 130.0, 135.0, 140.0, 400.0, 410.0];
        let session = vec![0; n];
        let at = Timeline {
            time_s: &time,
            session: &session,
        };
        let station = vec![0, 0, 0, 1, 1, 1, 2, 2];
        let share = vec![0.9, 0.8, 0.95];
        let a: Vec<f64> = (0..n).flat_map(|i| [1.0, 0.3 * i as f64 - 1.0]).collect();
        let q_ww: Vec<f64> = (0..n).map(|i| 1.0 + 0.2 * (i % 3) as f64).collect();
        let mut nm = [0.0; 4];
        for i in 0..n {
            for r in 0..m {
                for c in 0..m {
                    nm[r * m + c] += a[i * m + r] * a[i * m + c] / q_ww[i];
                }
            }
        }
        let det = nm[0] * nm[3] - nm[1] * nm[2];
        let q_pp = vec![nm[3] / det, -nm[1] / det, -nm[2] / det, nm[0] / det];
        let b = (0..n).map(|i| [1.0, 0.25 + 0.01 * i as f64, 0.0]).collect();
        let s = solution(m, q_pp.clone(), q_ww.clone(), (a.clone(), b));
        let noise = noise();
        let fast = between_station_excess(&s, &station, &share, at, &noise);
        let flicker = Flicker::new(noise.bias_instability);
        let windows = flicker.windowed(noise.window_s);
        let cov = |i: usize, j: usize| {
            let c = pair_covariance(&windows, &noise, (time[i], time[j], 0.0), i == j);
            c * s.b[i][1] * s.b[j][1]
        };
        // R[i][k] = delta_ik - a_i^T Q a_k w_k.
        let r = |i: usize, k: usize| {
            let aqa: f64 = (0..m)
                .map(|p| {
                    (0..m)
                        .map(|c| a[i * m + p] * q_pp[p * m + c] * a[k * m + c])
                        .sum::<f64>()
                })
                .sum();
            f64::from(u8::from(i == k)) - aqa / q_ww[k]
        };
        let mut slow = 0.0;
        for j in 0..3 {
            let u: Vec<f64> = (0..n)
                .map(|i| if station[i] == j { 1.0 / q_ww[i] } else { 0.0 })
                .collect();
            // z = R^T u.
            let z: Vec<f64> = (0..n)
                .map(|k| (0..n).map(|i| r(i, k) * u[i]).sum())
                .collect();
            let quad: f64 = (0..n)
                .map(|i| (0..n).map(|k| z[i] * cov(i, k) * z[k]).sum::<f64>())
                .sum();
            slow += share[j] * quad / u.iter().sum::<f64>();
        }
        assert!((fast - slow).abs() < 1e-9 * slow.abs(), "{fast} vs {slow}");
        // Each misclosure's excess: (R S R^T)_ii.
        let fast = misclosure_excess(&s, at, &noise);
        for (i, f) in fast.iter().enumerate() {
            let slow: f64 = (0..n)
                .map(|k| (0..n).map(|l| r(i, k) * cov(k, l) * r(i, l)).sum::<f64>())
                .sum();
            assert!((f - slow).abs() < 1e-9 * slow.abs(), "{i}: {f} vs {slow}");
        }
    }

    /// The linear-time sums equal the direct double sum over the model's covariance (windows
    /// that do not overlap, as a session's readings' do not).
    #[test]
    fn recursions_equal_the_double_sum() {
        let m = 2;
        let n = 7;
        let time: Vec<f64> = vec![0.0, 3.0, 5.6, 40.0, 42.6, 900.0, 2000.0];
        let session = vec![0, 0, 0, 0, 1, 1, 1];
        let at = Timeline {
            time_s: &time,
            session: &session,
        };
        let a = (0..n * m)
            .map(|k| ((k * 7919) % 13) as f64 / 13.0 - 0.4)
            .collect();
        let b = (0..n).map(|i| [1.0, 0.2 + 0.05 * i as f64, 0.0]).collect();
        let q_ww = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
        let s = solution(m, vec![2.0, 0.3, 0.3, 1.0], q_ww, (a, b));
        let noise = noise();
        let fast = extra_covariance(&s, at, &noise);
        let flicker = Flicker::new(noise.bias_instability);
        let windows = flicker.windowed(noise.window_s);
        let gain = |i: usize| -> Vec<f64> {
            let f = -s.b[i][1] / s.q_ww[i];
            q_pp_a(&s, i).into_iter().map(|x| x * f).collect()
        };
        let mut slow = vec![0.0; m * m];
        for i in 0..n {
            for j in 0..n {
                if session[i] != session[j] {
                    continue;
                }
                let t0 = time
                    .iter()
                    .zip(&session)
                    .filter(|(_, s)| **s == session[i])
                    .map(|(t, _)| *t)
                    .fold(f64::INFINITY, f64::min);
                let c = pair_covariance(&windows, &noise, (time[i], time[j], t0), i == j);
                let (gi, gj) = (gain(i), gain(j));
                for r in 0..m {
                    for q in 0..m {
                        slow[r * m + q] += gi[r] * gj[q] * c;
                    }
                }
            }
        }
        for (a, b) in fast.iter().zip(&slow) {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1e-12), "{a} vs {b}");
        }
    }
}
