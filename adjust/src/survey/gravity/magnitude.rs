//! The down component of an antenna array's session from the specific force's magnitude
//! (docs/model.md 7, "An antenna array"): f_D = -sqrt(|f|^2 - |h|^2), |f| each sample's
//! own (no attitude enters it) and h the horizontal force the track gives
//! ([`horizontal::track_force`]), so that the array's tilt error, a few mrad an epoch,
//! does not reach down. Turned by that attitude instead, down errs by g eps^2 / 2 (12 mGal
//! an epoch at 5 mrad) and by eps times the horizontal force.
//!
//! The track's force is low-passed where the positions' noise, differentiated twice,
//! stays under what the attitude's would give: the noise densities s_p^2 (2 pi f)^4 and
//! g^2 s_eps^2 meet at f = sqrt(g s_eps / s_p) / (2 pi), 0.35 Hz for 1 cm and 5 mrad. The
//! noise left adds |dh|^2 / 2 g: its mean is taken out, its fluctuation is a part of the
//! positions' sigma. Where the force changes sharply (a turn's onset and end, a ramp's)
//! the low-pass lags and its square misses some of |h|^2: a low-pass of half the cut-off
//! measures the miss ([`Lag`]), which is added, half of it in the sigma. What the vehicle's
//! horizontal force holds above the cut-off that is no sharp change (a sway, turbulence)
//! is not seen; its mean square over 2 g is what down would lose, and the sigma does not
//! say so: hence `[survey] array_down = "magnitude"` is declared, not the default.

use super::GravityError;
use super::filter::Lowpass;
use super::horizontal::{self, TrackForce};
use super::reduce::{self, Stretch};
use ingest::contract::gravity_ledger::AntennasUsed;
use ingest::contract::survey::FilterKind;

/// The lag correction's own uncertainty, as a fraction of it (its filtered value, signed,
/// in the positions' sigma): a clean step is corrected to 0.8 % (`the_lag_at_a_turn_is_taken_
/// out`), a turn of the simulated aircraft less well; half is taken, which the aircraft's
/// Monte-Carlo checks (docs/model.md 7).
pub const LAG_UNCERTAINTY: f64 = 0.5;

/// Gravity the cut-off is computed with, m/s^2.
const G_M_S2: f64 = 9.8;

/// The cut-off of the track's horizontal force for an array whose solved epochs have
/// these median sds, positions `white_m` (north, east, up) white per epoch, at epochs `dt`
/// s apart: where the positions' differentiated noise meets the tilt's, within [0.01 Hz, a
/// quarter of the epochs' rate]. None for an array without roll (two antennas).
pub fn cutoff_hz(used: &AntennasUsed, white_m: [f64; 3], dt: f64) -> Option<f64> {
    let [_, pitch, roll] = used.median_sd_hpr_deg;
    let tilt = (pitch?.to_radians().hypot(roll?.to_radians())) / 2f64.sqrt();
    let [n, e, _] = used.median_sd_position_m;
    let position = n.max(white_m[0]).hypot(e.max(white_m[1])) / 2f64.sqrt();
    let f = (G_M_S2 * tilt / position.max(1e-4)).sqrt() / std::f64::consts::TAU;
    Some(f.clamp(0.01, 0.25 / dt))
}

/// `s`'s down force formed again from the epochs' magnitudes `norm_mgal` and the track's
/// horizontal force low-passed at `cutoff_hz`, less the variance its positions' white sds
/// north and east (`var_ne_m2`, their squares summed) put into |h|^2 (its mean, which
/// would otherwise bias down by var / 2 g); what that error's square does about its mean,
/// a white error per epoch of sd s^2 sqrt(sum_m R(m)^2) / |f| (two axes of sd s each:
/// [`horizontal::TrackForce`]), into `s.sd_force_mgal`; and near a sharp change of the
/// force the low-pass's lag added to |h|^2 ([`Lag`]), its part of down into `s.lag_mgal`.
pub fn form_down(
    s: &mut Stretch,
    norm_mgal: &[f64],
    var_ne_m2: &[f64],
    (dt, cutoff_hz): (f64, f64),
) -> Result<(), GravityError> {
    let h = horizontal::track_force(s, dt, cutoff_hz)?;
    let lag = Lag::new(dt, cutoff_hz)?;
    let corrections = lag.corrections(&h, var_ne_m2);
    let lagged = lag.in_down(s, (&h, &corrections), (dt, cutoff_hz))?;
    s.sd_force_mgal.clear();
    s.lag_mgal.clear();
    for (k, f) in s.f_down_mgal.iter_mut().enumerate() {
        let h2 = square(&h.f_mgal, k) - h.gain_mgal2_per_m2 * var_ne_m2[k];
        *f = -(norm_mgal[k].powi(2) - h2).max(0.0).sqrt() + lagged[k];
        s.lag_mgal.push(lagged[k]);
        // |dh|^2 / 2 |f| about its mean: two axes of sd^2 = var / 2 each.
        let sd = 0.5 * var_ne_m2[k] * h.square_gain_mgal2_per_m2 / norm_mgal[k].max(1.0);
        s.sd_force_mgal.push(sd);
    }
    Ok(())
}

/// |h|^2 at epoch `k` of a north and east pair.
fn square(f: &[Vec<f64>; 2], k: usize) -> f64 {
    f[0][k].powi(2) + f[1][k].powi(2)
}

/// The low-pass's lag where the horizontal force changes sharply (a turn's onset and end,
/// a speed's ramp): the low-passed force's square misses |h|^2 - |LP h|^2 there, which a
/// low-pass of half the cut-off applied to it measures, |LP h|^2 - |LP' LP h|^2 times
/// `factor` (for a step, the ratio of the two misses summed; nothing where the force is
/// smooth, the passband being flat). The miss M lies within an epoch or two of the step,
/// the correction C over the half cut-off's response, seconds: down takes M as
/// M / 2 |f_D| - M^2 / 8 |f_D|^3 at the step, with |f_D| there (an aircraft's turbulence
/// moves it by 4 % in 3.5 s), so C is taken in down at the step's |f_D| ([`Lag::in_down`]),
/// the square's part by `spike`, for a step the sum of M^2 over the sum of C^2.
struct Lag {
    /// The half cut-off's low-pass.
    sections: Lowpass,
    pad: usize,
    /// The ratio for a step.
    factor: f64,
    /// For a step, the sum of the miss squared over the sum of the correction squared.
    spike: f64,
    /// What a white position error of 1 m^2 puts into |LP h|^2 - |LP' LP h|^2, mGal^2.
    noise_gain: f64,
    /// The variance of LP h - LP' LP h for a white position error of 1 m^2, mGal^2.
    cross_gain: f64,
    /// Epochs either side a sharp change reaches (six periods of the half cut-off).
    reach: usize,
}

impl Lag {
    fn new(dt: f64, cutoff_hz: f64) -> Result<Self, GravityError> {
        let first = Lowpass::design(FilterKind::Butterworth, cutoff_hz, 1.0 / dt)?;
        let sections = Lowpass::design(FilterKind::Butterworth, cutoff_hz / 2.0, 1.0 / dt)?;
        let pad = reduce::padding(2.0 / cutoff_hz, dt);
        let reach = reduce::reach(2.0 / cutoff_hz, dt);
        // A step as the epochs see it: through the triangle of one epoch either side (the
        // second difference's of the positions, the bins' of |f|^2), at eight phases.
        let (mut missed_once, mut missed_twice) = (0.0, 0.0);
        let mut steps = Vec::new();
        for phase in 0..8 {
            let step: Vec<f64> = (0..=2 * reach)
                .map(|k| triangle_step(k as f64 - reach as f64 - f64::from(phase) / 8.0))
                .collect();
            let once = first.apply(&step, pad, 1);
            let twice = sections.apply(&once, pad, 1);
            for k in 0..step.len() {
                missed_once += step[k] - once[k].powi(2);
                missed_twice += once[k].powi(2) - twice[k].powi(2);
            }
            steps.push((step, once, twice));
        }
        let factor = missed_once / missed_twice;
        let (mut missed, mut corrected) = (0.0, 0.0);
        for (step, once, twice) in &steps {
            for k in 0..step.len() {
                missed += (step[k] - once[k].powi(2)).powi(2);
                corrected += (factor * (once[k].powi(2) - twice[k].powi(2))).powi(2);
            }
        }
        let row = reduce::row(&first, reach, Some(dt));
        let row_twice = sections.apply(&row, 0, 1);
        let energy = |r: &[f64]| r.iter().map(|w| (w * 1e5).powi(2)).sum::<f64>();
        Ok(Lag {
            factor,
            spike: missed / corrected,
            noise_gain: energy(&row) - energy(&row_twice),
            cross_gain: energy(
                &row.iter()
                    .zip(&row_twice)
                    .map(|(a, b)| a - b)
                    .collect::<Vec<_>>(),
            ),
            sections,
            pad,
            reach,
        })
    }

    /// What to add to |LP h|^2 at each epoch of the track's force `h` (its positions' white
    /// variance north plus east `var_ne_m2`): `factor` times the difference |LP h|^2 -
    /// |LP' LP h|^2 (less its noise's mean) near a sharp change, 0 elsewhere.
    fn corrections(&self, h: &TrackForce, var_ne_m2: &[f64]) -> Vec<f64> {
        let n = var_ne_m2.len();
        let again: [Vec<f64>; 2] =
            std::array::from_fn(|c| self.sections.apply(&h.f_mgal[c], self.pad, 1));
        let difference: Vec<f64> = (0..n)
            .map(|k| square(&h.f_mgal, k) - square(&again, k) - self.noise_gain * var_ne_m2[k])
            .collect();
        // Its sd where nothing changes sharply: its noise's first-order part, 2 h . (dh -
        // dh'), and its square's.
        let sd: Vec<f64> = (0..n)
            .map(|k| {
                let axis = 0.5 * var_ne_m2[k];
                let first = 4.0 * square(&h.f_mgal, k) * axis * self.cross_gain;
                (first + 2.0 * (axis * h.square_gain_mgal2_per_m2).powi(2)).sqrt()
            })
            .collect();
        let sharp = self.sharp(&difference, &sd);
        (0..n)
            .map(|k| {
                if sharp[k] {
                    self.factor * difference[k]
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The corrections `c` (mGal^2 of |h|^2, [`Lag::corrections`]) of the track's force `h`
    /// as down takes them, mGal: c / 2 |f_D| - `spike` c^2 / 8 |f_D|^3 with |f_D| at the
    /// step, the epoch within a period of the half cut-off where |LP h|^2 changes fastest (a
    /// zero-phase low-pass's step crosses half-way at the step): normal gravity less the
    /// heights' vertical acceleration, low-passed at `cutoff_hz` (its noise, a tenth of a per
    /// cent of g, and the Eotvos term and the disturbance, a tenth, left in).
    fn in_down(
        &self,
        s: &Stretch,
        (h, c): (&TrackForce, &[f64]),
        (dt, cutoff_hz): (f64, f64),
    ) -> Result<Vec<f64>, GravityError> {
        let n = c.len();
        let mut out = vec![0.0; n];
        if n < 3 || c.iter().all(|v| *v == 0.0) {
            return Ok(out);
        }
        let sections = Lowpass::design(FilterKind::Butterworth, cutoff_hz, 1.0 / dt)?;
        let up = sections.apply(&s.height_m, reduce::padding(1.0 / cutoff_hz, dt), 1);
        let field = s.normal.ellipsoid().field();
        let change = |i: usize| (square(&h.f_mgal, i) - square(&h.f_mgal, i - 1)).abs();
        let near = (self.reach / 6).max(1);
        for j in (0..n).filter(|&j| c[j] != 0.0) {
            let (lo, hi) = (j.saturating_sub(near).max(1), (j + near + 1).min(n));
            let step = (lo..hi)
                .max_by(|a, b| change(*a).total_cmp(&change(*b)))
                .unwrap_or(j);
            let m = step.clamp(1, n - 2);
            let lift = (up[m + 1] - 2.0 * up[m] + up[m - 1]) / (dt * dt) * 1e5;
            let f = field.normal_gravity_mgal(s.latitude_deg[m], s.height_m[m]) + lift;
            out[j] = c[j] / (2.0 * f) - self.spike * c[j].powi(2) / (8.0 * f.powi(3));
        }
        Ok(out)
    }

    /// The epochs near a sharp change: where the difference's mean over a fifth of a
    /// period of the half cut-off, in units of the sd `sd` its noise has where nothing
    /// changes, stands out of those units' own scatter over the stretch (six of their
    /// median absolute deviations, which scale for the mean's averaging), and `reach`
    /// either side of them. A constant or smooth force (a ramp's steady acceleration, a
    /// swell) changes nothing there, however large: only its noise, which `sd` follows.
    fn sharp(&self, difference: &[f64], sd: &[f64]) -> Vec<bool> {
        let n = difference.len();
        let half = (self.reach / 60).max(1);
        let units: Vec<f64> = (0..n)
            .map(|k| {
                let (lo, hi) = (k.saturating_sub(half), (k + half + 1).min(n));
                let mean = difference[lo..hi].iter().sum::<f64>() / (hi - lo) as f64;
                // (a floor of 1 mGal^2, 5e-7 mGal of down, for positions without noise)
                mean / sd[k].max(1.0)
            })
            .collect();
        let mut scatter: Vec<f64> = units.iter().map(|v| v.abs()).collect();
        scatter.sort_by(f64::total_cmp);
        // (at least a fifth of a unit: the mean of a dozen epochs' noise is no less)
        let mad = (scatter.get(n / 2).copied().unwrap_or(0.0) * 1.4826).max(0.2);
        let mut out = vec![false; n];
        for (k, v) in units.iter().enumerate() {
            if v.abs() > 6.0 * mad {
                for o in &mut out[k.saturating_sub(self.reach)..(k + self.reach + 1).min(n)] {
                    *o = true;
                }
            }
        }
        out
    }
}

/// A unit step at 0 seen through a triangle of half-width 1, at `x`.
fn triangle_step(x: f64) -> f64 {
    match x {
        x if x <= -1.0 => 0.0,
        x if x <= 0.0 => 0.5 * (1.0 + x).powi(2),
        x if x < 1.0 => 1.0 - 0.5 * (1.0 - x).powi(2),
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A still triad whose positions err white, 1 cm north and east at 10 Hz: down formed
    /// from the magnitude keeps the true force's mean (the squared error's mean taken out,
    /// within a hundredth of a mGal), and through a 100 s filter its error's sd is the
    /// sigma part `sd_force_mgal` gives, within 10 % over 40 draws of a 2000 s stretch.
    #[test]
    fn the_squared_position_error_is_taken_out_and_its_sigma_honest() {
        let (dt, n, sd) = (0.1, 20_000, 0.01);
        let g = 980_000.0;
        let (sections, pad) = (
            Lowpass::design(FilterKind::Butterworth, 0.01, 1.0 / dt).expect("filter"),
            reduce::padding(100.0, dt),
        );
        let noise_row = reduce::row(&sections, reduce::reach(100.0, dt), None);
        let (mut mean, mut square, mut count) = (0.0, 0.0, 0.0);
        let mut predicted = 0.0;
        for draw in 0..40 {
            let mut rng = fixtures::rng::Rng::new(draw, "magnitude");
            let mut s = Stretch::default();
            for k in 0..n {
                s.time_gps_ns.push(k as i64 * 100_000_000);
                s.latitude_deg
                    .push(45.0 + (sd * rng.normal() / 6_367_000.0).to_degrees());
                s.longitude_deg
                    .push(5.0 + (sd * rng.normal() / 4_517_000.0).to_degrees());
                s.height_m.push(0.0);
                s.f_down_mgal.push(-g);
            }
            let var = vec![2.0 * sd * sd; n];
            form_down(&mut s, &vec![g; n], &var, (dt, 0.35)).expect("formed");
            let error: Vec<f64> = s.f_down_mgal.iter().map(|f| f + g).collect();
            let filtered = sections.apply(&error, pad, (100.0 / dt) as usize);
            for e in &filtered[n / 4..3 * n / 4] {
                mean += e;
                square += e * e;
                count += 1.0;
            }
            predicted = reduce::scaled(&noise_row, &s.sd_force_mgal)[n / 2];
        }
        let mean = mean / count;
        let sd_seen = (square / count - mean * mean).sqrt();
        eprintln!("mean {mean:.4} mGal, sd {sd_seen:.4} against {predicted:.4} mGal");
        assert!(mean.abs() < 0.01, "{mean}");
        assert!(
            (sd_seen / predicted - 1.0).abs() < 0.1,
            "{sd_seen} {predicted}"
        );
    }
}

#[cfg(test)]
mod lag_tests {
    use super::*;
    use crate::survey::gravity::navigation::radii;
    use crate::survey::gravity::normal::GRS80;

    /// An aircraft's half-circle turn at 60 m/s (1500 m radius) on the equator (no Coriolis
    /// force north or east there), no noise, the epochs' |f|^2 as their triangles see the
    /// centripetal step: through a 100 s filter, down's error from the low-pass's lag (tens
    /// of mGal) is taken out to under 1 % of it, and a minute and a half from the turn and from
    /// the stretch's ends nothing is corrected.
    #[test]
    fn the_lag_at_a_turn_is_taken_out() {
        let (dt, n, v, r) = (0.1, 30_000, 60.0, 1500.0);
        let g = 980_000.0;
        let (t_on, t_off) = (1000.0, 1000.0 + std::f64::consts::PI * r / v);
        let (rm, rn) = radii(&GRS80, 0.0);
        let mut s = Stretch::default();
        let mut norms = Vec::new();
        for k in 0..n {
            let t = k as f64 * dt;
            let (north, east) = if t < t_on {
                (0.0, v * t)
            } else if t < t_off {
                let a = v * (t - t_on) / r;
                (r - r * a.cos(), v * t_on + r * a.sin())
            } else {
                (2.0 * r, v * t_on - v * (t - t_off))
            };
            s.time_gps_ns.push(k as i64 * 100_000_000);
            s.latitude_deg.push((north / rm).to_degrees());
            s.longitude_deg.push(5.0 + (east / rn).to_degrees());
            s.height_m.push(0.0);
            s.f_down_mgal.push(-g);
            let on = triangle_step((t - t_on) / dt) - triangle_step((t - t_off) / dt);
            norms.push((g * g + on * (v * v / r * 1e5).powi(2)).sqrt());
        }
        let lowpass = Lowpass::design(FilterKind::Butterworth, 0.01, 1.0 / dt).expect("filter");
        let filtered = |f: &[f64]| {
            let error: Vec<f64> = f.iter().map(|f| f + g).collect();
            lowpass.apply(&error, reduce::padding(100.0, dt), 1000)
        };
        let h = horizontal::track_force(&s, dt, 0.34).expect("force");
        let uncorrected: Vec<f64> = (0..n)
            .map(|k| -(norms[k].powi(2) - square(&h.f_mgal, k)).sqrt())
            .collect();
        let mut corrected = s.clone();
        form_down(&mut corrected, &norms, &vec![0.0; n], (dt, 0.34)).expect("formed");
        let largest = |x: &[f64]| x[5000..25_000].iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let (before, after) = (
            largest(&filtered(&uncorrected)),
            largest(&filtered(&corrected.f_down_mgal)),
        );
        eprintln!("the lag's filtered error: {before:.2} mGal, corrected {after:.2} mGal");
        assert!(before > 10.0 && after < 0.01 * before, "{before} {after}");
        // (within the first and last 100 s the low-passes extend a moving track's ends)
        let far = |k: usize| {
            let t = k as f64 * dt;
            (t - t_on).abs() > 90.0 && (t - t_off).abs() > 90.0 && (1000..n - 1000).contains(&k)
        };
        let touched: Vec<usize> = (0..n)
            .filter(|&k| far(k) && corrected.lag_mgal[k] != 0.0)
            .collect();
        assert!(touched.is_empty(), "{:?}", &touched[..touched.len().min(5)]);
    }
}
