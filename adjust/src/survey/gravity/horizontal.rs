//! North and east along a stretch of track (docs/model.md 7), free of I/O: with attitude and
//! a triad model the specific force is known in the navigation frame, and
//! `delta g_N = a_N - f_N + ((2 omega_ie + omega_en) x v)_N`, likewise east, normal gravity
//! having no horizontal component along the ellipsoidal normal. The
//! kinematic acceleration is the second difference of the track's northing and easting,
//! each step the change of latitude (longitude) times the radius of curvature (times the
//! cosine of the latitude) at the step's middle, so that the second difference is the
//! change of the local velocity, dv^n/dt, as the navigation equation wants it (a fixed
//! plane would add the meridians' convergence); the velocities for the Coriolis and
//! transport-rate term are central differences of the same. Filtered as the down component
//! is ([`super::reduce`]): the positions through the filter before they are differentiated,
//! the rest extended about its smooth level at each end.
//!
//! Sigmas, kept apart: the positions' sd north or east through the differentiator and the
//! filter; the accelerometers' noise (the down component's per-axis sd: the noise is taken
//! as the same on each axis) through the filter; the calibration's (untied: no tie gives the
//! horizontal components, so its whole error stays, the parameters' gradients filtered and
//! carried through their covariance where the triad has no temperature terms, the filtered
//! sigma otherwise); and the attitude's: a tilt error eps turns the specific force, delta f =
//! eps x f, so that its north part is f_D eps_E - f_E eps_heading, first order in the tilt (1
//! mrad is about 980 mGal), carried through the filter as the manifest declares the
//! attitude's errors to behave: white, correlated or systematic ([`super::errors`]).

use super::GravityError;
use super::errors;
use super::filter;
use super::navigation::{coriolis_transport, longitude_step_deg, radii};
use super::normal::GRS80;
use super::reduce::{self, CalibrationGradient, Stretch};
use ingest::contract::survey::FilterKind;

/// What a stretch's horizontal reduction needs beyond the down component's inputs, per
/// epoch, indexed [north, east].
#[derive(Clone, Debug, Default)]
pub struct Horizontal {
    /// The specific force north and east, mGal.
    pub f_mgal: [Vec<f64>; 2],
    /// The calibration's sigma of each (used where `calibration` is None), mGal.
    pub sigma_calibration_mgal: [Vec<f64>; 2],
    /// The calibration's error as gradients by the parameters, where they can be formed.
    pub calibration: [Option<CalibrationGradient>; 2],
    /// The effect on each of a one-sd error of the heading, the pitch and the roll, signed
    /// ([`errors::attitude_effects`]), mGal.
    pub attitude_effects_mgal: [Vec<[f64; 3]>; 2],
    /// The positions' white sds north and east, m (0 where unknown; as the down
    /// component's `sd_up_m`).
    pub sd_m: [Vec<f64>; 2],
    /// The file's sds north and east where declared correlated or systematic, m (empty when
    /// white).
    pub sd_declared_m: [Vec<f64>; 2],
}

/// North and east reduced, indexed [north, east].
#[derive(Clone, Debug, Default)]
pub struct ReducedHorizontal {
    /// Unfiltered disturbance, mGal.
    pub disturbance_mgal: [Vec<f64>; 2],
    /// Filtered.
    pub filtered_mgal: [Vec<f64>; 2],
    /// The filtered value's sigma, its four parts in quadrature.
    pub sigma_mgal: [Vec<f64>; 2],
    /// The calibration's part.
    pub sigma_calibration_mgal: [Vec<f64>; 2],
    /// The positions'.
    pub sigma_positions_mgal: [Vec<f64>; 2],
    /// The accelerometers' noise.
    pub sigma_noise_mgal: [Vec<f64>; 2],
    /// The attitude's.
    pub sigma_attitude_mgal: [Vec<f64>; 2],
}

impl ReducedHorizontal {
    /// The epochs `range` alone.
    pub(super) fn keep(&mut self, range: std::ops::Range<usize>) {
        for pair in [
            &mut self.disturbance_mgal,
            &mut self.filtered_mgal,
            &mut self.sigma_mgal,
            &mut self.sigma_calibration_mgal,
            &mut self.sigma_positions_mgal,
            &mut self.sigma_noise_mgal,
            &mut self.sigma_attitude_mgal,
        ] {
            for v in pair {
                reduce::cut(v, range.clone());
            }
        }
    }
}

/// The track's northing and easting, m, from its first epoch (see the module's text).
fn northing_easting(s: &Stretch) -> [Vec<f64>; 2] {
    let n = s.time_gps_ns.len();
    let mut out = [vec![0.0; n], vec![0.0; n]];
    for k in 1..n {
        let lat = 0.5 * (s.latitude_deg[k] + s.latitude_deg[k - 1]);
        let h = 0.5 * (s.height_m[k] + s.height_m[k - 1]);
        let (r_m, r_n) = radii(&GRS80, lat);
        let d_lat = (s.latitude_deg[k] - s.latitude_deg[k - 1]).to_radians();
        let d_lon = longitude_step_deg(s.longitude_deg[k - 1], s.longitude_deg[k]).to_radians();
        out[0][k] = out[0][k - 1] + d_lat * (r_m + h);
        out[1][k] = out[1][k - 1] + d_lon * (r_n + h) * lat.to_radians().cos();
    }
    out
}

/// The Coriolis and transport-rate term north and east at each epoch, mGal.
fn coriolis(s: &Stretch, xy: &[Vec<f64>; 2], dt: f64) -> [Vec<f64>; 2] {
    let n = s.time_gps_ns.len();
    let mut out = [Vec::with_capacity(n), Vec::with_capacity(n)];
    for k in 0..n {
        let (lo, hi) = (k.saturating_sub(1), (k + 1).min(n - 1));
        let span = (hi - lo) as f64 * dt;
        let v = [
            (xy[0][hi] - xy[0][lo]) / span,
            (xy[1][hi] - xy[1][lo]) / span,
            -(s.height_m[hi] - s.height_m[lo]) / span,
        ];
        let c = coriolis_transport(&GRS80, s.latitude_deg[k], s.height_m[k], v);
        out[0].push(c[0] * 1e5);
        out[1].push(c[1] * 1e5);
    }
    out
}

/// The second difference of `x` at each epoch, mGal (at the ends, the neighbour's).
fn second_difference(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|k| {
            let c = k.clamp(1, n - 2);
            (x[c + 1] - 2.0 * x[c] + x[c - 1]) / (dt * dt) * 1e5
        })
        .collect()
}

/// The horizontal specific force the track alone gives, no attitude entering it: what the
/// down component of an antenna array's session is formed with (docs/model.md 7, "An
/// antenna array").
pub struct TrackForce {
    /// North and east at each epoch, mGal: the second difference of the accelerometers'
    /// northing and easting low-passed at the cut-off, plus the Coriolis and transport-rate
    /// term (f = dv/dt + (2 omega_ie + omega_en) x v - g, normal gravity having no
    /// horizontal component).
    pub f_mgal: [Vec<f64>; 2],
    /// The variance a white position error of 1 m^2 gives each, mGal^2: the sum of the
    /// squares of the low-passed second difference's weights, R(0) of their
    /// autocorrelation R.
    pub gain_mgal2_per_m2: f64,
    /// sqrt(sum_m R(m)^2), mGal^2 / m^2: the square of that error, |dh|^2, has a variance
    /// density at low frequencies (what a long filter passes) of 2 s^4 sum_m R(m)^2 per
    /// axis for a white position error of sd s.
    pub square_gain_mgal2_per_m2: f64,
}

/// The horizontal force along `s`, its epochs `dt` s apart, the positions low-passed at
/// `cutoff_hz` (a Butterworth's half-power point) before they are differentiated.
pub fn track_force(s: &Stretch, dt: f64, cutoff_hz: f64) -> Result<TrackForce, GravityError> {
    let n = s.time_gps_ns.len();
    let sections = filter::Lowpass::design(FilterKind::Butterworth, cutoff_hz, 1.0 / dt)?;
    let pad = reduce::padding(1.0 / cutoff_hz, dt);
    let xy = northing_easting(s);
    let cor = coriolis(s, &xy, dt);
    let f_mgal = std::array::from_fn(|c| {
        let x = sections.apply(&xy[c], pad, 1);
        let a = second_difference(&x, dt);
        (0..n).map(|k| a[k] + cor[c][k]).collect()
    });
    let row: Vec<f64> = reduce::row(&sections, reduce::reach(1.0 / cutoff_hz, dt), Some(dt))
        .iter()
        .map(|w| w * 1e5)
        .collect();
    let r = |m: usize| -> f64 { row.iter().zip(&row[m..]).map(|(a, b)| a * b).sum() };
    let squares = r(0).powi(2) + 2.0 * (1..row.len()).map(|m| r(m).powi(2)).sum::<f64>();
    Ok(TrackForce {
        f_mgal,
        gain_mgal2_per_m2: r(0),
        square_gain_mgal2_per_m2: squares.sqrt(),
    })
}

/// North and east along `s` (its down component's inputs: positions, noise) with `h`,
/// filtered with cut-off period `filter_s`.
pub fn reduce_horizontal(
    s: &Stretch,
    h: &Horizontal,
    filter_s: f64,
) -> Result<ReducedHorizontal, GravityError> {
    let n = s.time_gps_ns.len();
    let dt = reduce::interval_s(&s.time_gps_ns)?;
    let filter = reduce::filter_of(s.filter, filter_s, dt, n)?;
    let sections = &filter.lowpass;
    let xy = northing_easting(s);
    let cor = coriolis(s, &xy, dt);
    let reach = reduce::reach(filter_s, dt);
    let (positions_row, noise_row) = (
        reduce::row(sections, reach, Some(dt)),
        reduce::row(sections, reach, None),
    );
    let mut out = ReducedHorizontal::default();
    for c in 0..2 {
        let a = second_difference(&xy[c], dt);
        out.disturbance_mgal[c] = (0..n).map(|k| a[k] - h.f_mgal[c][k] + cor[c][k]).collect();
        let rest: Vec<f64> = (0..n).map(|k| -h.f_mgal[c][k] + cor[c][k]).collect();
        let mut f = filter.apply(&rest);
        let x = sections.apply(&xy[c], filter.pad, 1);
        for (v, a) in f.iter_mut().zip(second_difference(&x, dt)) {
            *v += a;
        }
        out.filtered_mgal[c] = f;
        let sd: Vec<f64> = h.sd_m[c].iter().map(|sd| sd * 1e5).collect();
        out.sigma_positions_mgal[c] = reduce::propagated_sd(&positions_row, &sd);
        if let Some(model) = s.position_errors {
            let declared: Vec<f64> = h.sd_declared_m[c].iter().map(|sd| sd * 1e5).collect();
            let part = errors::position_sigma(&positions_row, &declared, model, dt, 0.0);
            for (v, p) in out.sigma_positions_mgal[c].iter_mut().zip(part) {
                *v = v.hypot(p);
            }
        }
        out.sigma_noise_mgal[c] = reduce::scaled(&noise_row, &s.noise_f_mgal);
        out.sigma_calibration_mgal[c] = match &h.calibration[c] {
            Some(g) => g.filtered_sigma(&filter),
            None => filter.apply(&h.sigma_calibration_mgal[c]),
        };
        out.sigma_attitude_mgal[c] = errors::attitude_sigma(
            &h.attitude_effects_mgal[c],
            s.attitude_errors,
            &filter,
            errors::epoch_number(&s.time_gps_ns, dt),
            dt,
            filter_s,
        );
        out.sigma_mgal[c] = (0..n)
            .map(|k| {
                [
                    out.sigma_calibration_mgal[c][k],
                    out.sigma_positions_mgal[c][k],
                    out.sigma_noise_mgal[c][k],
                    out.sigma_attitude_mgal[c][k],
                ]
                .iter()
                .map(|v| v * v)
                .sum::<f64>()
                .sqrt()
            })
            .collect();
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Northing and easting along a parallel going east at 10 m/s: the easting grows by
    /// 10 m an epoch, the northing stays, and the second difference is zero.
    #[test]
    fn a_steady_course_has_no_acceleration() {
        let mut s = Stretch::default();
        let (_, r_n) = radii(&GRS80, 45.0);
        for k in 0..100 {
            s.time_gps_ns.push(k * 1_000_000_000);
            s.latitude_deg.push(45.0);
            s.longitude_deg
                .push(5.0 + (10.0 * k as f64 / (r_n * 45f64.to_radians().cos())).to_degrees());
            s.height_m.push(0.0);
        }
        let xy = northing_easting(&s);
        assert!((xy[1][99] - 990.0).abs() < 1e-6, "{}", xy[1][99]);
        assert!(xy[0].iter().all(|v| v.abs() < 1e-9));
        let a = second_difference(&xy[1], 1.0);
        assert!(a.iter().all(|v| v.abs() < 1e-3), "{a:?}");
    }
}
