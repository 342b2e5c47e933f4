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
//! height) matters; with attitude the stage has already turned each sample into the
//! navigation frame and moved the positions by the lever arm (north and east are
//! [`super::horizontal`]'s).

use super::GravityError;
use super::coupling::Correction;
use super::errors::{self, AttitudeErrors};
use super::filter;
use super::navigation::{eotvos_down, longitude_step_deg, radii};
use super::normal::{MAX_DISTURBANCE_MGAL, NormalGravity};
use ingest::contract::survey::{ErrorModel, FilterKind, Heights};

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
    /// The antenna's, as the trajectory gives it, m (written out, not used here).
    pub height_antenna_m: Vec<f64>,
    /// The low-pass filter the stretch is reduced with (`[survey] filter`).
    pub filter: FilterKind,
    /// The positions' white sd up, m (0 where unknown): the larger of the file's and the
    /// heights' own white noise when the file's sds are declared white, the own noise alone
    /// otherwise.
    pub sd_up_m: Vec<f64>,
    /// The file's sd up where it is declared correlated or systematic (`position_errors`),
    /// m; empty when white.
    pub sd_up_declared_m: Vec<f64>,
    /// The model of `sd_up_declared_m`'s errors.
    pub position_errors: Option<ErrorModel>,
    /// Specific force down at each epoch, mGal (about -g at rest).
    pub f_down_mgal: Vec<f64>,
    /// Its sigma from the calibration's covariance, mGal.
    pub sigma_f_mgal: Vec<f64>,
    /// The ellipsoid of normal gravity, and of the radii the velocities are formed with.
    pub normal: NormalGravity,
    /// The body tide's effect on gravity at each epoch, mGal (empty: none removed).
    pub tide_mgal: Vec<f64>,
    /// A platform meter's cross-coupling: its monitors at each epoch and the correction.
    pub coupling: Option<StretchCoupling>,
    /// The effect on it of a one-sd error of the heading, the pitch and the roll, signed
    /// ([`errors::attitude_effects`]; 0 without attitude), mGal.
    pub attitude_effects_mgal: Vec<[f64; 3]>,
    /// How the attitude's errors behave over time.
    pub attitude_errors: AttitudeErrors,
    /// Where a tie will fix the level: how the calibration's error at each epoch less its
    /// error at the first tie (what the tie does not take away) depends on the parameters;
    /// None: taken as the difference of the sigmas (exact when one parameter dominates).
    pub calibration_tied: Option<CalibrationGradient>,
    /// The sd of the epoch's value from the samples' own noise (their scatter in the epoch
    /// over the square root of their number), mGal; 0 where unknown.
    pub noise_f_mgal: Vec<f64>,
    /// Where down is formed from the force's magnitude ([`super::magnitude`]): the white sd
    /// per epoch the horizontal force's error from the positions gives it, mGal (a part of
    /// the positions' sigma); empty otherwise.
    pub sd_force_mgal: Vec<f64>,
    /// There too: the low-pass's lag taken out of down where the horizontal force changes
    /// sharply, mGal (0 elsewhere; empty otherwise).
    pub lag_mgal: Vec<f64>,
}

/// A platform meter's cross-coupling along a stretch ([`super::coupling`]).
#[derive(Clone, Debug)]
pub struct StretchCoupling {
    /// VE, VCC, AL, AX at each epoch.
    pub monitors: Vec<[f64; 4]>,
    /// The coefficients and their covariance.
    pub correction: Correction,
}

/// `v` cut to `range`.
pub(super) fn cut<T>(v: &mut Vec<T>, range: std::ops::Range<usize>) {
    v.truncate(range.end);
    v.drain(..range.start);
}

impl Stretch {
    /// The epochs `range` alone (the calibration's gradients dropped).
    pub(super) fn keep(&mut self, range: std::ops::Range<usize>) {
        for v in [
            &mut self.latitude_deg,
            &mut self.longitude_deg,
            &mut self.height_m,
            &mut self.height_antenna_m,
            &mut self.sd_up_m,
            &mut self.f_down_mgal,
            &mut self.sigma_f_mgal,
            &mut self.noise_f_mgal,
        ] {
            cut(v, range.clone());
        }
        for v in [
            &mut self.sd_up_declared_m,
            &mut self.tide_mgal,
            &mut self.sd_force_mgal,
            &mut self.lag_mgal,
        ] {
            if !v.is_empty() {
                cut(v, range.clone());
            }
        }
        cut(&mut self.attitude_effects_mgal, range.clone());
        if let Some(c) = &mut self.coupling {
            cut(&mut c.monitors, range.clone());
        }
        cut(&mut self.time_gps_ns, range);
        self.calibration_tied = None;
    }
}

impl Reduced {
    /// The epochs `range` alone.
    pub(super) fn keep(&mut self, range: std::ops::Range<usize>) {
        for v in [
            &mut self.disturbance_mgal,
            &mut self.filtered_mgal,
            &mut self.sigma_calibration_mgal,
            &mut self.sigma_positions_mgal,
            &mut self.sigma_noise_mgal,
            &mut self.sigma_tie_mgal,
            &mut self.sigma_attitude_mgal,
            &mut self.sigma_mgal,
            &mut self.speed_m_s,
            &mut self.eotvos_mgal,
            &mut self.normal_mgal,
            &mut self.tide_mgal,
            &mut self.coupling_mgal,
            &mut self.sigma_coupling_mgal,
        ] {
            cut(v, range.clone());
        }
    }
}

/// The calibration's error at each epoch as a linear function of the parameters' errors: for
/// the down component once tied, the error at the epoch less the error at the tie; for
/// north and east (never tied), the error at the epoch.
#[derive(Clone, Debug, Default)]
pub struct CalibrationGradient {
    /// Per parameter, per epoch: d(error) / d(parameter), mGal.
    pub gradient: Vec<Vec<f64>>,
    /// The parameters' covariance, row-major n x n.
    pub covariance: Vec<f64>,
}

impl CalibrationGradient {
    /// The sd at each epoch of the filtered error: the gradients filtered (the filter is
    /// linear and the parameters common to all epochs), then g C g^T.
    pub(super) fn filtered_sigma(&self, filter: &filter::StretchFilter) -> Vec<f64> {
        let g: Vec<Vec<f64>> = self.gradient.iter().map(|x| filter.apply(x)).collect();
        let n = g.len();
        let epochs = g.first().map_or(0, Vec::len);
        (0..epochs)
            .map(|k| {
                let mut var = 0.0;
                for a in 0..n {
                    for b in 0..n {
                        var += g[a][k] * self.covariance[a * n + b] * g[b][k];
                    }
                }
                var.max(0.0).sqrt()
            })
            .collect()
    }
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
    /// Sigma of the filtered value from the accelerometers' own noise, mGal.
    pub sigma_noise_mgal: Vec<f64>,
    /// Sigma of the tie's offset and drift at the epoch, mGal (0 untied).
    pub sigma_tie_mgal: Vec<f64>,
    /// Sigma of the filtered value from the attitude (taken as correlated over the
    /// filter's length, so not reduced by it), mGal (0 without attitude).
    pub sigma_attitude_mgal: Vec<f64>,
    /// The filtered value's sigma: the five above and the cross-coupling's in quadrature,
    /// mGal.
    pub sigma_mgal: Vec<f64>,
    /// Speed over ground, m/s.
    pub speed_m_s: Vec<f64>,
    /// The Eotvos term, mGal.
    pub eotvos_mgal: Vec<f64>,
    /// Normal gravity, mGal.
    pub normal_mgal: Vec<f64>,
    /// The body tide's effect on gravity, removed, mGal (0 without a tide).
    pub tide_mgal: Vec<f64>,
    /// The cross-coupling correction, added, mGal (0 without one).
    pub coupling_mgal: Vec<f64>,
    /// The filtered value's sigma from the correction's coefficients, mGal.
    pub sigma_coupling_mgal: Vec<f64>,
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
    /// Covariance of offset and rate, mGal^2/h (0 with one tie).
    pub covariance_mgal2_per_h: f64,
    /// The ties used (inside the stretch, with a window of at least two epochs).
    pub ties_used: usize,
}

impl Drift {
    /// The correction at `t_gps_ns`, mGal, and its sigma.
    pub fn at(&self, t_gps_ns: i64) -> (f64, f64) {
        let h = (t_gps_ns - self.reference_gps_ns) as f64 / 3.6e12;
        let sr = self.sigma_rate_mgal_per_h.unwrap_or(0.0);
        let var = self.sigma_offset_mgal.powi(2)
            + 2.0 * h * self.covariance_mgal2_per_h
            + (h * sr).powi(2);
        (
            self.offset_mgal + self.rate_mgal_per_h * h,
            var.max(0.0).sqrt(),
        )
    }
}

/// The epochs' interval, s, checked even (within 1 % of the median).
pub(super) fn interval_s(t: &[i64]) -> Result<f64, GravityError> {
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

/// How far either side a filter's row reaches, in epochs: six filter periods, beyond which
/// its response (and the second difference's) holds under 1e-9 of its norm
/// (`the_row_reaches_far_enough`).
pub(super) fn reach(filter_s: f64, dt: f64) -> usize {
    (6.0 * filter_s / dt).ceil() as usize
}

/// The row of `x -> filter(x)` (or, with `dt`, of `x -> filter(second difference of x)`,
/// per unit of x, in x's unit per s^2) at any epoch of a stretch's interior: its response
/// to an impulse at the middle of `2 reach + 1` epochs (the zero-phase filter's operator is
/// symmetric, so its row is its column).
pub(super) fn row(sections: &filter::Lowpass, reach: usize, dt: Option<f64>) -> Vec<f64> {
    let n = 2 * reach + 1;
    let mut x = vec![0.0; n];
    x[reach] = 1.0;
    if let Some(dt) = dt {
        let mut second = vec![0.0; n];
        for j in 1..n - 1 {
            second[j] = (x[j + 1] - 2.0 * x[j] + x[j - 1]) / (dt * dt);
        }
        x = second;
    }
    sections.apply(&x, 0, 1)
}

/// The sd at each epoch of an operator's output whose `row` ([`row`]) applies to
/// independent inputs of sds `sd`: sqrt(sum_j row[j - k + reach]^2 sd_j^2), an input
/// beyond the stretch's ends taken with the end's sd. Where the sds vary by under 1 %
/// within the row's reach, the row's norm times the epoch's sd (the same to that 1 %, and
/// nearly free); elsewhere (a float or single solution among fixed ones) the sum itself,
/// so that an epoch's sd spreads as its error does: O(reach) an epoch there.
pub(super) fn propagated_sd(row: &[f64], sd: &[f64]) -> Vec<f64> {
    let n = sd.len();
    let reach = row.len() / 2;
    let gain = row.iter().map(|v| v * v).sum::<f64>().sqrt();
    let (lo, hi) = sliding_min_max(sd, reach);
    (0..n)
        .map(|k| {
            if hi[k] - lo[k] <= 0.01 * hi[k] {
                return gain * sd[k];
            }
            let var: f64 = row
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    let j = (k + i).saturating_sub(reach).min(n - 1);
                    (r * sd[j]).powi(2)
                })
                .sum();
            var.sqrt()
        })
        .collect()
}

/// The row's norm times each epoch's sd: [`propagated_sd`] for sds that hold over the
/// row's reach, or that change from one epoch to the next (the samples in an epoch, 3 or 4
/// at 31.25 Hz on 10 Hz epochs) and so average over it.
pub(super) fn scaled(row: &[f64], sd: &[f64]) -> Vec<f64> {
    let gain = row.iter().map(|v| v * v).sum::<f64>().sqrt();
    sd.iter().map(|v| v * gain).collect()
}

/// The least and greatest of `x` within `reach` of each index (monotone queues).
fn sliding_min_max(x: &[f64], reach: usize) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut out = (vec![0.0; n], vec![0.0; n]);
    let (mut qmin, mut qmax) = (
        std::collections::VecDeque::new(),
        std::collections::VecDeque::new(),
    );
    let mut next = 0;
    for k in 0..n {
        while next < n && next <= k + reach {
            while qmin.back().is_some_and(|&b: &usize| x[b] >= x[next]) {
                qmin.pop_back();
            }
            qmin.push_back(next);
            while qmax.back().is_some_and(|&b: &usize| x[b] <= x[next]) {
                qmax.pop_back();
            }
            qmax.push_back(next);
            next += 1;
        }
        while qmin.front().is_some_and(|&f| f + reach < k) {
            qmin.pop_front();
        }
        while qmax.front().is_some_and(|&f| f + reach < k) {
            qmax.pop_front();
        }
        out.0[k] = qmin.front().map_or(0.0, |&i| x[i]);
        out.1[k] = qmax.front().map_or(0.0, |&i| x[i]);
    }
    out
}

/// The unfiltered disturbance at each epoch (before ties), with the speed, the Eotvos term
/// and normal gravity pushed into `out`.
fn unfiltered(s: &Stretch, dt: f64, out: &mut Reduced) -> Vec<f64> {
    let n = s.time_gps_ns.len();
    let ellipsoid = s.normal.ellipsoid();
    let field = ellipsoid.field();
    let mut raw = vec![0.0; n];
    for k in 0..n {
        let (lo, hi) = (k.saturating_sub(1), (k + 1).min(n - 1));
        let span = (hi - lo) as f64 * dt;
        let (r_m, r_n) = radii(ellipsoid, s.latitude_deg[k]);
        let h = s.height_m[k];
        let v_n = (s.latitude_deg[hi] - s.latitude_deg[lo]).to_radians() * (r_m + h) / span;
        let v_e = longitude_step_deg(s.longitude_deg[lo], s.longitude_deg[hi]).to_radians()
            * (r_n + h)
            * s.latitude_deg[k].to_radians().cos()
            / span;
        // a_D = -d2h/dt2; at the ends, the neighbour's.
        let c = k.clamp(1, n - 2);
        let a_d = -(s.height_m[c + 1] - 2.0 * s.height_m[c] + s.height_m[c - 1]) / (dt * dt);
        let e = eotvos_down(ellipsoid, s.latitude_deg[k], h, v_n, v_e) * 1e5;
        let gamma = field.normal_gravity_mgal(s.latitude_deg[k], h);
        let tide = s.tide_mgal.get(k).copied().unwrap_or(0.0);
        let coupling = s
            .coupling
            .as_ref()
            .map_or(0.0, |c| c.correction.value(&c.monitors[k]));
        raw[k] = a_d * 1e5 - s.f_down_mgal[k] + e - gamma - tide + coupling;
        out.coupling_mgal.push(coupling);
        out.speed_m_s.push(v_n.hypot(v_e));
        out.eotvos_mgal.push(e);
        out.normal_mgal.push(gamma);
        out.tide_mgal.push(tide);
    }
    raw
}

/// The unfiltered disturbance at each epoch of `s` (before ties), alone: what the
/// cross-coupling regression is fitted to.
pub fn unfiltered_disturbance(s: &Stretch) -> Result<Vec<f64>, GravityError> {
    let dt = interval_s(&s.time_gps_ns)?;
    Ok(unfiltered(s, dt, &mut Reduced::default()))
}

/// The filtered disturbance, term by term, the ends extended consistently. The heights
/// are filtered before they are differentiated (in the interior the same as filtering the
/// differentiated heights, the operators commuting), extended oddly through their end
/// values (value and slope continue, the curvature turns over); the rest (specific force,
/// Eotvos, normal gravity) is extended oddly about its smooth level at each end (the
/// Hann-weighted mean over a filter period), so that its swell turns over with the
/// heights' and the two cancel in the padding as in the series. Filtering the unfiltered
/// disturbance itself would put a second difference of cm position noise (hundreds of Gal)
/// at each end as a step of velocity: a transient of hundreds of mGal for a filter period.
fn filtered(s: &Stretch, filter: &filter::StretchFilter, out: &Reduced, dt: f64) -> Vec<f64> {
    let n = s.time_gps_ns.len();
    let rest: Vec<f64> = (0..n)
        .map(|k| {
            -s.f_down_mgal[k] + out.eotvos_mgal[k] - out.normal_mgal[k] - out.tide_mgal[k]
                + out.coupling_mgal[k]
        })
        .collect();
    let mut f = filter.apply(&rest);
    let h = filter.lowpass.apply(&s.height_m, filter.pad, 1);
    for (k, v) in f.iter_mut().enumerate() {
        let c = k.clamp(1, n - 2);
        *v -= (h[c + 1] - 2.0 * h[c] + h[c - 1]) / (dt * dt) * 1e5;
    }
    f
}

/// Normal gravity's change with height, per mGal of height error (a height error in mGal is
/// 1e5 times the error in m): 0.3086 mGal/m times 1e-5 m/mGal.
const FREE_AIR_PER_MGAL: f64 = 0.3086e-5;

/// The padding at each end of a stretch: three filter periods, or the stretch.
pub(super) fn padding(filter_s: f64, dt: f64) -> usize {
    (3.0 * filter_s / dt).ceil() as usize
}

/// The filter of a stretch of `n` epochs `dt` apart: the low-pass, the padding at each end
/// and the pivot's length ([`filter::filtfilt_pivoted`]).
pub(super) fn filter_of(
    kind: FilterKind,
    filter_s: f64,
    dt: f64,
    n: usize,
) -> Result<filter::StretchFilter, GravityError> {
    Ok(filter::StretchFilter {
        lowpass: filter::Lowpass::design(kind, 1.0 / filter_s, 1.0 / dt)?,
        pad: padding(filter_s, dt),
        pivot: ((filter_s / dt).round() as usize).min(n),
    })
}

/// The down gravity disturbance along `s`, filtered with cut-off period `filter_s`, tied
/// to `ties` (those inside the stretch): [`untied`], the ties' [`level`], then
/// [`apply_level`].
///
/// Sigmas, each of the filtered value, kept apart: the positions' (their white noise
/// through the differentiator and the filter), the accelerometers' own noise (the epochs'
/// sds through the filter), the calibration's (common to neighbouring samples, so the
/// filter keeps it; once tied, only what differs from its value at the first tie, the
/// error being one of the calibration's parameters carried through the same function) and
/// the tie's (the drift line's sigma at the epoch).
pub fn reduce(s: &Stretch, filter_s: f64, ties: &[Tie]) -> Result<Reduced, GravityError> {
    let mut r = untied(s, filter_s)?;
    let mut points = Vec::new();
    for tie in ties {
        points.extend(tie_point(s, &r, tie, filter_s)?);
    }
    apply_level(s, &mut r, level(&points).as_ref(), filter_s)?;
    Ok(r)
}

/// The reduction of `s` before any tie: every series of [`Reduced`] but the tie's sigma
/// (zero) and the total sigma (filled in by [`apply_level`]), the calibration's sigma not
/// yet relative to a tie. A window of a longer stretch reduced alone gives the stretch's
/// own values wherever it extends twelve filter periods beyond: what its ends are extended
/// by dies away with the filter's slowest pole, to 3e-13 there (the stage's blocks,
/// docs/model.md 7).
pub fn untied(s: &Stretch, filter_s: f64) -> Result<Reduced, GravityError> {
    let n = s.time_gps_ns.len();
    let dt = interval_s(&s.time_gps_ns)?;
    let filter = filter_of(s.filter, filter_s, dt, n)?;
    if (n as f64) * dt < filter_s {
        return Err(GravityError::TooShort {
            epochs: n,
            seconds: n as f64 * dt,
            filter_s,
        });
    }
    let mut out = Reduced::default();
    out.disturbance_mgal = unfiltered(s, dt, &mut out);
    // The value and the calibration's sigma filtered on two cores (three passes of the
    // filter's kernel over the stretch, a tenth of a day at 1 Hz's stage).
    let (filtered_mgal, sigma_calibration_mgal) = rayon::join(
        || filtered(s, &filter, &out, dt),
        || filter.apply(&s.sigma_f_mgal),
    );
    out.filtered_mgal = filtered_mgal;
    let reach = reach(filter_s, dt);
    let heights: Vec<f64> = s.sd_up_m.iter().map(|sd| sd * 1e5).collect();
    let positions_row = row(&filter.lowpass, reach, Some(dt));
    out.sigma_positions_mgal = propagated_sd(&positions_row, &heights);
    if let Some(model) = s.position_errors {
        let declared: Vec<f64> = s.sd_up_declared_m.iter().map(|sd| sd * 1e5).collect();
        let part = errors::position_sigma(&positions_row, &declared, model, dt, FREE_AIR_PER_MGAL);
        for (v, p) in out.sigma_positions_mgal.iter_mut().zip(part) {
            *v = v.hypot(p);
        }
    }
    let noise_row = row(&filter.lowpass, reach, None);
    if !s.sd_force_mgal.is_empty() {
        let part = scaled(&noise_row, &s.sd_force_mgal);
        let lag = filter.apply(&s.lag_mgal);
        for ((v, p), l) in out.sigma_positions_mgal.iter_mut().zip(part).zip(lag) {
            *v = v.hypot(p).hypot(super::magnitude::LAG_UNCERTAINTY * l);
        }
    }
    out.sigma_noise_mgal = scaled(&noise_row, &s.noise_f_mgal);
    out.sigma_calibration_mgal = sigma_calibration_mgal;
    out.sigma_tie_mgal = vec![0.0; n];
    out.sigma_coupling_mgal = coupling_sigma(s, &filter);
    out.sigma_attitude_mgal = if s.attitude_effects_mgal.iter().flatten().any(|v| *v != 0.0) {
        errors::attitude_sigma(
            &s.attitude_effects_mgal,
            s.attitude_errors,
            &filter,
            errors::epoch_number(&s.time_gps_ns, dt),
            dt,
            filter_s,
        )
    } else {
        vec![0.0; n]
    };
    Ok(out)
}

/// The sd the cross-coupling coefficients' errors give each filtered value: the monitors
/// filtered as the value is, through the coefficients' covariance (0 without a correction).
fn coupling_sigma(s: &Stretch, filter: &filter::StretchFilter) -> Vec<f64> {
    let n = s.time_gps_ns.len();
    let Some(c) = &s.coupling else {
        return vec![0.0; n];
    };
    let filtered: Vec<Vec<f64>> = (0..4)
        .map(|i| {
            let series: Vec<f64> = c.monitors.iter().map(|m| m[i]).collect();
            filter.apply(&series)
        })
        .collect();
    (0..n)
        .map(|k| {
            c.correction.sigma(&[
                filtered[0][k],
                filtered[1][k],
                filtered[2][k],
                filtered[3][k],
            ])
        })
        .collect()
}

/// What one tie says of the level: at the centre of its window, the filtered disturbance's
/// mean over the window less the tie's g - gamma, the sd of that mean, and the
/// (untied) calibration sigma at the epoch nearest the centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TiePoint {
    /// The tie's centre, GPS ns.
    pub time_gps_ns: i64,
    /// The misfit, mGal.
    pub misfit_mgal: f64,
    /// Its sd, mGal.
    pub sd_mgal: f64,
    /// The untied calibration sigma at the epoch nearest the centre, mGal.
    pub calibration_mgal: f64,
}

/// The level the ties fix on a stretch: the drift, and the calibration's sigma at its
/// reference (which the tie takes away).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    /// The drift fitted to the ties.
    pub drift: Drift,
    /// The untied calibration sigma at the drift's reference, mGal.
    pub calibration_at_tie_mgal: f64,
}

/// `tie`'s point on `s` reduced untied into `r` (None where its window holds fewer than two
/// of the stretch's epochs): its window must be still, and its gravity that of a place on
/// the Earth (each refused otherwise, naming the tie).
pub fn tie_point(
    s: &Stretch,
    r: &Reduced,
    tie: &Tie,
    filter_s: f64,
) -> Result<Option<TiePoint>, GravityError> {
    let t = &s.time_gps_ns;
    let dt = interval_s(t)?;
    still(tie, s, dt)?;
    let half = (tie.duration_s * 0.5e9) as i64;
    let idx: Vec<usize> = (0..t.len())
        .filter(|&k| (t[k] - tie.time_gps_ns).abs() <= half)
        .collect();
    if idx.len() < 2 {
        return Ok(None);
    }
    let n = idx.len() as f64;
    let gamma = &r.normal_mgal;
    let disturbance = idx.iter().map(|&k| tie.g_mgal - gamma[k]).sum::<f64>() / n;
    if disturbance.abs() > MAX_DISTURBANCE_MGAL {
        let k = idx[idx.len() / 2];
        return Err(GravityError::Refused {
            message: format!(
                "the tie at {}: its {} mGal is {disturbance:.0} mGal from normal gravity \
                 where the track is then ({:.5}, {:.5} deg, {:.1} m), beyond any \
                 disturbance on the Earth ({MAX_DISTURBANCE_MGAL} mGal): is it this \
                 place's gravity, and the trajectory's position?",
                ingest::base::time::utc_iso(tie.time_gps_ns),
                tie.g_mgal,
                s.latitude_deg[k],
                s.longitude_deg[k],
                s.height_m[k]
            ),
        });
    }
    let mean = idx.iter().map(|&k| r.filtered_mgal[k]).sum::<f64>() / n - disturbance;
    let filter = filter_of(s.filter, filter_s, dt, t.len())?;
    let sd = window_mean_sd(s, &idx, &filter.lowpass, dt, filter.pad);
    let calibration = nearest(t, tie.time_gps_ns).map_or(0.0, |k| r.sigma_calibration_mgal[k]);
    Ok(Some(TiePoint {
        time_gps_ns: tie.time_gps_ns,
        misfit_mgal: mean,
        sd_mgal: sd,
        calibration_mgal: calibration,
    }))
}

/// The level of a stretch's tie points (in the ties' order; the first is the drift's
/// reference): a constant with one, a weighted line in time with more; None without.
pub fn level(points: &[TiePoint]) -> Option<Level> {
    let line_points: Vec<(i64, f64, f64)> = points
        .iter()
        .map(|p| (p.time_gps_ns, p.misfit_mgal, p.sd_mgal))
        .collect();
    Some(Level {
        drift: line(&line_points)?,
        calibration_at_tie_mgal: points.first()?.calibration_mgal,
    })
}

/// `r` (of `s`, reduced [`untied`]) tied to `level`: the drift removed from the
/// disturbance before and after the filter, the tie's sigma at each epoch, the
/// calibration's sigma relative to the tie (through `s.calibration_tied` where given; the
/// difference of the sigmas otherwise); then the total sigma, the six parts in quadrature.
pub fn apply_level(
    s: &Stretch,
    r: &mut Reduced,
    level: Option<&Level>,
    filter_s: f64,
) -> Result<(), GravityError> {
    let n = s.time_gps_ns.len();
    if let Some(level) = level {
        let d = &level.drift;
        let tied = match &s.calibration_tied {
            Some(c) => {
                let filter = filter_of(s.filter, filter_s, interval_s(&s.time_gps_ns)?, n)?;
                Some(c.filtered_sigma(&filter))
            }
            None => None,
        };
        for k in 0..n {
            let (c, sigma) = d.at(s.time_gps_ns[k]);
            r.disturbance_mgal[k] -= c;
            r.filtered_mgal[k] -= c;
            r.sigma_tie_mgal[k] = sigma;
            r.sigma_calibration_mgal[k] = match &tied {
                Some(v) => v[k],
                None => (r.sigma_calibration_mgal[k] - level.calibration_at_tie_mgal).abs(),
            };
        }
        r.drift = Some(*d);
    }
    r.sigma_mgal = (0..n)
        .map(|k| {
            let parts = [
                r.sigma_positions_mgal[k],
                r.sigma_noise_mgal[k],
                r.sigma_calibration_mgal[k],
                r.sigma_tie_mgal[k],
                r.sigma_attitude_mgal[k],
                r.sigma_coupling_mgal[k],
            ];
            parts.iter().map(|v| v * v).sum::<f64>().sqrt()
        })
        .collect();
    Ok(())
}

/// The steps between consecutive times, counted by value: their median (the sorted steps'
/// element at half their count) without holding them, for times that come one at a time.
#[derive(Clone, Debug, Default)]
pub(super) struct Steps {
    last: Option<i64>,
    counts: std::collections::BTreeMap<i64, u64>,
}

impl Steps {
    /// The next time.
    pub(super) fn push(&mut self, t: i64) {
        if let Some(p) = self.last.replace(t) {
            *self.counts.entry(t - p).or_insert(0) += 1;
        }
    }

    /// The median step, ns (the upper one of an even count; None for fewer than two).
    pub(super) fn median(&self) -> Option<i64> {
        let n: u64 = self.counts.values().sum();
        let mut seen = 0;
        self.counts.iter().find_map(|(&d, &c)| {
            seen += c;
            (seen > n / 2).then_some(d)
        })
    }
}

/// The track's displacement north and east from epoch `a` to `b`, m, at epoch `at`'s
/// latitude ([`super::navigation::step_ne_m`]).
pub(super) fn displacement_ne_m(s: &Stretch, (a, b): (usize, usize), at: usize) -> [f64; 2] {
    let point = |k: usize| [s.latitude_deg[k], s.longitude_deg[k]];
    super::navigation::step_ne_m(point(a), point(b), s.latitude_deg[at])
}

/// The speed below which a tie's window counts as still, m/s (its epochs' median).
pub const STILL_M_S: f64 = 0.5;

/// A tie's window still: a tie at a time the vehicle moves (a time or a day mistyped)
/// would shift the whole stretch to the gravity of another place, so it is refused with
/// its time and the speed. The speed at an epoch is taken from the positions 5 s either
/// side (the epoch-to-epoch speed of a 20 Hz trajectory with 3 cm noise is 0.5 m/s of
/// noise alone).
fn still(tie: &Tie, s: &Stretch, dt: f64) -> Result<(), GravityError> {
    let t = &s.time_gps_ns;
    let n = t.len();
    let w = ((5.0 / dt).round() as usize).max(1);
    let speed = |k: usize| {
        let (a, b) = (k.saturating_sub(w), (k + w).min(n - 1));
        let [north, east] = displacement_ne_m(s, (a, b), k);
        north.hypot(east) / ((b - a).max(1) as f64 * dt)
    };
    let half = (tie.duration_s * 0.5e9) as i64;
    let mut v: Vec<f64> = (0..n)
        .filter(|&k| (t[k] - tie.time_gps_ns).abs() <= half)
        .map(speed)
        .collect();
    if v.is_empty() {
        return Ok(());
    }
    v.sort_unstable_by(f64::total_cmp);
    let median = v[v.len() / 2];
    if median > STILL_M_S {
        return Err(GravityError::Refused {
            message: format!(
                "the tie at {}: the vehicle moves at {median:.1} m/s (the median over its {} \
                 s window), where a tie's window must be still (below {STILL_M_S} m/s): is \
                 its time right?",
                ingest::base::time::utc_iso(tie.time_gps_ns),
                tie.duration_s
            ),
        });
    }
    Ok(())
}

/// The epoch nearest `t0`, if any.
fn nearest(t: &[i64], t0: i64) -> Option<usize> {
    (0..t.len()).min_by_key(|&k| (t[k] - t0).abs())
}

/// The sd of the filtered disturbance's mean over the epochs `window` (in order, without a
/// gap), mGal, from the positions' and the accelerometers' white noise, each through its
/// operator. The positions' part telescopes: the mean of a second difference is the
/// difference of the first differences at the window's ends over its length, so it falls as
/// 1 / length, not as the square root of the filter periods in the window (which overstated
/// a tie's sigma fourfold on the boat). The filter's operator is taken as symmetric (its
/// row is its response to an impulse) and as in the interior of a stretch: the weights are
/// filtered with `margin` epochs of zeros either side, so that a window at a stretch's end
/// does not start the filter on a step, and an epoch beyond the stretch takes the noise of
/// the nearest in it.
fn window_mean_sd(
    s: &Stretch,
    window: &[usize],
    sections: &filter::Lowpass,
    dt: f64,
    margin: usize,
) -> f64 {
    let n = s.time_gps_ns.len();
    let len = window.len() as f64;
    // The mean as weights on the filtered heights (the stage's second difference, its ends
    // the neighbour's) and on the filtered specific force, epoch j at j + margin.
    let mut on_heights = vec![0.0; n + 2 * margin];
    let mut on_force = on_heights.clone();
    for &k in window {
        let c = k.clamp(1, n - 2) + margin;
        let w = 1e5 / (len * dt * dt);
        on_heights[c + 1] -= w;
        on_heights[c] += 2.0 * w;
        on_heights[c - 1] -= w;
        on_force[k + margin] += 1.0 / len;
    }
    let heights = sections.apply(&on_heights, 0, 1);
    let force = sections.apply(&on_force, 0, 1);
    let var: f64 = (0..n + 2 * margin)
        .map(|i| {
            let j = i.saturating_sub(margin).min(n - 1);
            (s.sd_up_m[j] * heights[i]).powi(2) + (s.noise_f_mgal[j] * force[i]).powi(2)
        })
        .sum();
    var.sqrt()
}

/// A weighted straight line through (time, misfit, sigma): a constant for one point.
fn line(points: &[(i64, f64, f64)]) -> Option<Drift> {
    let (t0, _, _) = *points.first()?;
    if points.len() == 1 {
        let (_, m, s) = points[0];
        return Some(Drift {
            offset_mgal: m,
            sigma_offset_mgal: s,
            rate_mgal_per_h: 0.0,
            sigma_rate_mgal_per_h: None,
            reference_gps_ns: t0,
            covariance_mgal2_per_h: 0.0,
            ties_used: 1,
        });
    }
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(ti, m, s) in points {
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
        covariance_mgal2_per_h: -sx / det,
        ties_used: points.len(),
    })
}

/// How a session's named quantities come from its filtered value, gravity less normal
/// gravity at the trajectory's heights (docs/formats.md 10.3): that value is the quantity
/// the heights give (the disturbance above the ellipsoid, the free-air anomaly above sea
/// level); the other is it moved by normal gravity's change over the geoid's height N,
/// when N is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Named {
    /// What the heights are measured from.
    pub heights: Heights,
    /// The geoid's height above the ellipsoid, m.
    pub geoid_height_m: Option<f64>,
    /// The ellipsoid of normal gravity.
    pub normal: NormalGravity,
}

impl Named {
    /// The disturbance and the free-air anomaly (None where not formed) of filtered value
    /// `value_mgal` at `latitude_deg` and height `height_m`, as the heights give it.
    pub fn at(&self, latitude_deg: f64, height_m: f64, value_mgal: f64) -> [Option<f64>; 2] {
        let gamma = |h: f64| self.normal.ellipsoid().normal_gravity_mgal(latitude_deg, h);
        match self.heights {
            // delta g = g - gamma(h); Delta g = g - gamma(h - N).
            Heights::Ellipsoidal => [
                Some(value_mgal),
                self.geoid_height_m
                    .map(|n| value_mgal + gamma(height_m) - gamma(height_m - n)),
            ],
            // Delta g = g - gamma(H); delta g = g - gamma(H + N).
            Heights::SeaLevel => [
                self.geoid_height_m
                    .map(|n| value_mgal + gamma(height_m) - gamma(height_m + n)),
                Some(value_mgal),
            ],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The named quantities: the one the heights give is the value itself; the other is it
    /// moved by normal gravity's change over the geoid's height, the free-air gradient's
    /// 0.3086 mGal/m to its second-order term, and not formed without N.
    #[test]
    fn the_disturbance_and_the_free_air_anomaly_differ_by_the_geoid_height() {
        let named = |heights, geoid_height_m| Named {
            heights,
            geoid_height_m,
            normal: NormalGravity::Grs80,
        };
        let (lat, h, v) = (48.07, 10.0, 12.5);
        assert_eq!(
            named(Heights::Ellipsoidal, None).at(lat, h, v),
            [Some(v), None]
        );
        assert_eq!(
            named(Heights::SeaLevel, None).at(lat, h, v),
            [None, Some(v)]
        );
        for n in [-40.0, 55.0] {
            let [d, f] = named(Heights::Ellipsoidal, Some(n)).at(lat, h, v);
            assert_eq!(d, Some(v));
            let f = f.expect("formed");
            assert!((v - f - 0.3086 * n).abs() < 0.002 * n.abs(), "{n}: {f}");
            let [d, f] = named(Heights::SeaLevel, Some(n)).at(lat, h, v);
            assert_eq!(f, Some(v));
            let d = d.expect("formed");
            assert!((d - v - 0.3086 * n).abs() < 0.002 * n.abs(), "{n}: {d}");
        }
    }

    fn sections() -> filter::Lowpass {
        filter::Lowpass::Butterworth(
            filter::butterworth(filter::ORDER, 1.0 / 100.0, 10.0).expect("filter"),
        )
    }

    /// The row's reach holds its energy: the gain over four filter periods either side is
    /// the gain over a stretch five times longer.
    #[test]
    fn the_row_reaches_far_enough() {
        let reach = reach(100.0, 0.1);
        for dt in [None, Some(0.1)] {
            let short = row(&sections(), reach, dt);
            let long = row(&sections(), 5 * reach, dt);
            let norm = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(
                (norm(&short) / norm(&long) - 1.0).abs() < 1e-9,
                "{dt:?} {}",
                norm(&short) / norm(&long) - 1.0
            );
        }
    }

    /// An epoch's sd spreads as its error does: with one epoch 100 times noisier, the sd
    /// at each epoch is the brute-force sum over the row, and a constant sd gives the
    /// gain times it.
    #[test]
    fn an_epochs_sd_spreads_over_the_rows_reach() {
        let r = row(&sections(), reach(100.0, 0.1), Some(0.1));
        let n = 20_000;
        let mut sd = vec![0.02; n];
        let flat = propagated_sd(&r, &sd);
        let gain = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(flat.iter().all(|v| (v / (0.02 * gain) - 1.0).abs() < 1e-12));
        sd[10_000] = 2.0;
        let got = propagated_sd(&r, &sd);
        let reach = r.len() / 2;
        for k in [10_000, 10_050, 10_300, 11_000, 13_000, 500] {
            let brute: f64 = (0..n)
                .filter(|&j| j + reach >= k && j <= k + reach)
                .map(|j| (r[j + reach - k] * sd[j]).powi(2))
                .sum::<f64>()
                .sqrt();
            let want = if k.abs_diff(10_000) > reach {
                0.02 * gain
            } else {
                brute
            };
            assert!((got[k] / want - 1.0).abs() < 1e-9, "{k}: {} {want}", got[k]);
        }
        // Near the spike the sigma is far above the quiet epochs'.
        assert!(got[10_050] > 2.0 * flat[10_050], "{}", got[10_050]);
    }
}
