//! The down component of the navigation equation along a track, free of I/O: given the
//! trajectory's epochs (evenly spaced, no gap) and the down specific force brought onto
//! them, the gravity disturbance down at each epoch, filtered, tied to known gravity, with
//! its sigmas from the calibration and from the positions kept apart (docs/model.md 7).
//!
//! g_D = a_D - f_D + (2 omega_ie + omega_en) x v |_D, and delta g_D = g_D - gamma. The
//! kinematic acceleration a_D = -d^2h/dt^2 and the velocities are central differences on
//! the epochs (their response, 2 (1 - cos(w T)) / T^2 against w^2, is within 1e-3 of exact
//! below a tenth of the epochs' Nyquist frequency, far above any filter's cut-off); f_D is
//! the specific force's down component (-g at rest). Without attitude the platform is
//! taken as levelled, so only the lever arm's down component (a constant offset of the
//! height) matters.

use super::GravityError;
use super::filter;
use super::navigation::{eotvos_down, radii};
use super::normal::GRS80;

/// One stretch of track: evenly spaced epochs and what was measured at them.
#[derive(Clone, Debug, Default)]
pub struct Stretch {
    /// GPS time, ns.
    pub time_gps_ns: Vec<i64>,
    /// Geodetic latitude, deg.
    pub latitude_deg: Vec<f64>,
    /// Longitude, deg.
    pub longitude_deg: Vec<f64>,
    /// Ellipsoidal height of the accelerometers, m.
    pub height_m: Vec<f64>,
    /// The positions' sd up, m (0 where unknown).
    pub sd_up_m: Vec<f64>,
    /// Specific force down at each epoch, mGal (about -g at rest).
    pub f_down_mgal: Vec<f64>,
    /// Its sigma from the calibration's covariance, mGal.
    pub sigma_f_mgal: Vec<f64>,
}

/// A static tie: the still window's centre and length, and gravity there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tie {
    /// Centre of the still window, GPS ns.
    pub time_gps_ns: i64,
    /// Length of the window, s.
    pub duration_s: f64,
    /// Absolute gravity at the accelerometers, mGal.
    pub g_mgal: f64,
}

/// What the reduction gives per epoch, and the drift removed.
#[derive(Clone, Debug, Default)]
pub struct Reduced {
    /// Gravity disturbance down, before the filter, mGal (ties applied).
    pub disturbance_mgal: Vec<f64>,
    /// After the filter, mGal (ties applied).
    pub filtered_mgal: Vec<f64>,
    /// Sigma of the filtered value from the calibration, mGal.
    pub sigma_calibration_mgal: Vec<f64>,
    /// Sigma of the filtered value from the positions, mGal.
    pub sigma_positions_mgal: Vec<f64>,
    /// Speed over ground, m/s.
    pub speed_m_s: Vec<f64>,
    /// The Eotvos term, mGal.
    pub eotvos_mgal: Vec<f64>,
    /// Normal gravity, mGal.
    pub normal_mgal: Vec<f64>,
    /// The drift removed: (offset mGal at the first tie, rate mGal/h), their sigmas.
    pub drift: Option<Drift>,
}

/// The accelerometer bias's drift fitted to the ties and removed.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Drift {
    /// Offset at the reference time, mGal.
    pub offset_mgal: f64,
    /// Its sigma, mGal.
    pub sigma_offset_mgal: f64,
    /// Rate, mGal per hour (0 with one tie).
    pub rate_mgal_per_h: f64,
    /// Its sigma (None with one tie).
    pub sigma_rate_mgal_per_h: Option<f64>,
    /// The reference time (the first tie's centre), GPS ns.
    pub reference_gps_ns: i64,
}

/// The epochs' interval, s, checked even (within 1 % of the median).
fn interval_s(t: &[i64]) -> Result<f64, GravityError> {
    let mut d: Vec<i64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_unstable();
    let m = *d
        .get(d.len() / 2)
        .ok_or_else(|| GravityError::Filter("a stretch of fewer than two epochs".to_owned()))?;
    if m <= 0 || d.iter().any(|&x| (x - m).abs() * 100 > m) {
        return Err(GravityError::Filter(
            "the epochs of a stretch must be evenly spaced (cut the track at gaps first)"
                .to_owned(),
        ));
    }
    Ok(m as f64 * 1e-9)
}

/// The white-noise gain of `x -> filter(second difference of x)`: the sd of the filtered
/// acceleration per unit sd of independent heights, at epoch `at` of `n`.
fn position_noise_gain(sections: &[filter::Section], n: usize, at: usize, dt: f64) -> f64 {
    // The operator's row at `at`: the response at `at` to a unit height at each epoch j.
    // By symmetry of the zero-phase filter, it is the response to an impulse at `at`.
    let mut x = vec![0.0; n];
    x[at] = 1.0;
    let mut second = vec![0.0; n];
    for j in 1..n - 1 {
        second[j] = (x[j + 1] - 2.0 * x[j] + x[j - 1]) / (dt * dt);
    }
    filter::filtfilt(sections, &second)
        .map(|y| y.iter().map(|v| v * v).sum::<f64>().sqrt())
        .unwrap_or(f64::NAN)
}

/// The down gravity disturbance along `s`, filtered with cut-off period `filter_s`, tied
/// to `ties` (those inside the stretch).
pub fn reduce(s: &Stretch, filter_s: f64, ties: &[Tie]) -> Result<Reduced, GravityError> {
    let n = s.time_gps_ns.len();
    let dt = interval_s(&s.time_gps_ns)?;
    let sections = filter::butterworth(filter::ORDER, 1.0 / filter_s, 1.0 / dt)?;
    if n <= filter::pad_length(&sections) + 2 {
        return Err(GravityError::Filter(format!(
            "a stretch of {n} epochs ({:.0} s) is too short for a {filter_s} s filter",
            n as f64 * dt
        )));
    }
    let mut out = Reduced::default();
    let mut raw = vec![0.0; n];
    for k in 0..n {
        let (lo, hi) = (k.saturating_sub(1), (k + 1).min(n - 1));
        let span = (hi - lo) as f64 * dt;
        let (r_m, r_n) = radii(&GRS80, s.latitude_deg[k]);
        let h = s.height_m[k];
        let v_n = (s.latitude_deg[hi] - s.latitude_deg[lo]).to_radians() * (r_m + h) / span;
        let v_e = (s.longitude_deg[hi] - s.longitude_deg[lo]).to_radians()
            * (r_n + h)
            * s.latitude_deg[k].to_radians().cos()
            / span;
        // a_D = -d2h/dt2; at the ends, the neighbour's.
        let c = k.clamp(1, n - 2);
        let a_d = -(s.height_m[c + 1] - 2.0 * s.height_m[c] + s.height_m[c - 1]) / (dt * dt);
        let e = eotvos_down(&GRS80, s.latitude_deg[k], h, v_n, v_e) * 1e5;
        let gamma = GRS80.normal_gravity_mgal(s.latitude_deg[k], h);
        raw[k] = a_d * 1e5 - s.f_down_mgal[k] + e - gamma;
        out.speed_m_s.push(v_n.hypot(v_e));
        out.eotvos_mgal.push(e);
        out.normal_mgal.push(gamma);
    }
    let mut filtered = filter::filtfilt(&sections, &raw)?;
    let drift = tie(&s.time_gps_ns, &raw, &out.normal_mgal, ties);
    if let Some(d) = &drift {
        for (k, t) in s.time_gps_ns.iter().enumerate() {
            let hours = (t - d.reference_gps_ns) as f64 / 3.6e12;
            let c = d.offset_mgal + d.rate_mgal_per_h * hours;
            raw[k] -= c;
            filtered[k] -= c;
        }
    }
    // The calibration's error is common to neighbouring samples: the filter keeps it.
    out.sigma_calibration_mgal = filter::filtfilt(&sections, &s.sigma_f_mgal)?;
    let mid_gain = position_noise_gain(&sections, n, n / 2, dt) * 1e5;
    out.sigma_positions_mgal = s.sd_up_m.iter().map(|sd| sd * mid_gain).collect();
    out.disturbance_mgal = raw;
    out.filtered_mgal = filtered;
    out.drift = drift;
    Ok(out)
}

/// The drift fitted to the ties inside the stretch: at each, the unfiltered disturbance's
/// mean over its still window against the tie's g - gamma (the filter passes a constant
/// unchanged, and the unfiltered values' scatter gives the mean's sigma); a constant with
/// one tie, a line in time with more.
fn tie(t: &[i64], raw: &[f64], gamma: &[f64], ties: &[Tie]) -> Option<Drift> {
    let mut points = Vec::new();
    for tie in ties {
        let half = (tie.duration_s * 0.5e9) as i64;
        let idx: Vec<usize> = (0..t.len())
            .filter(|&k| (t[k] - tie.time_gps_ns).abs() <= half)
            .collect();
        if idx.len() < 2 {
            continue;
        }
        let n = idx.len() as f64;
        let misfit: Vec<f64> = idx
            .iter()
            .map(|&k| raw[k] - (tie.g_mgal - gamma[k]))
            .collect();
        let mean = misfit.iter().sum::<f64>() / n;
        let var = misfit.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (n - 1.0);
        points.push((tie.time_gps_ns, mean, (var / n).sqrt()));
    }
    let (t0, _, _) = *points.first()?;
    if points.len() == 1 {
        let (_, m, s) = points[0];
        return Some(Drift {
            offset_mgal: m,
            sigma_offset_mgal: s,
            rate_mgal_per_h: 0.0,
            sigma_rate_mgal_per_h: None,
            reference_gps_ns: t0,
        });
    }
    // Weighted straight line through (hours, misfit).
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(ti, m, s) in &points {
        let w = 1.0 / s.max(1e-6).powi(2);
        let x = (ti - t0) as f64 / 3.6e12;
        sw += w;
        sx += w * x;
        sy += w * m;
        sxx += w * x * x;
        sxy += w * x * m;
    }
    let det = sw * sxx - sx * sx;
    if det <= 0.0 {
        return None;
    }
    Some(Drift {
        offset_mgal: (sxx * sy - sx * sxy) / det,
        sigma_offset_mgal: (sxx / det).sqrt(),
        rate_mgal_per_h: (sw * sxy - sx * sy) / det,
        sigma_rate_mgal_per_h: Some((sw / det).sqrt()),
        reference_gps_ns: t0,
    })
}
