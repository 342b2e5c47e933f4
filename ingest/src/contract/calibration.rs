//! `OUT/adjust/calibration.json` (docs/formats.md section 6): the fitted calibration functions,
//! the fits skipped with their reasons, and exactly the files the numbers came from.

use crate::contract::custody::{Custody, Folders, check_dataset};
use crate::contract::manifest::{Dataset, Instrument, ReadingUnit};
use crate::contract::{align_ledger, ingest_ledger};
use crate::error::Result;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// File name of the result.
pub const CALIBRATION_FILE: &str = "calibration.json";
/// Format tag of calibration.json.
pub const CALIBRATION_FORMAT: &str = "gravcal-calibration/1";

/// An input file and its hash.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Input {
    /// Path relative to the dataset.
    pub path: String,
    /// SHA-256, hex.
    pub sha256: String,
}

/// The global test, two-sided at 5 %, at the a-priori weights: the between-station part of
/// v^T P v (the scatter of the station means about the fitted function; the whole v^T P v
/// when every station has one observation) against the scaled chi-square with its mean and
/// variance, which with weights estimated from the readings is wider than chi-square(dof)
/// (docs/model.md 6.1; docs/choices.md).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GlobalTest {
    /// The between-station part of v^T P v.
    pub statistic: f64,
    /// Its expectation: the station means' share of the redundancy.
    #[serde(default)]
    pub expectation: f64,
    /// Effective degrees of freedom of the reference, 2 mean^2 / variance.
    #[serde(default)]
    pub dof: f64,
    /// 2.5 % quantile.
    pub lower: f64,
    /// 97.5 % quantile.
    pub upper: f64,
    /// Within the bounds.
    pub passed: bool,
}

impl GlobalTest {
    /// "passed" or "failed", for a sentence.
    pub fn verdict(&self) -> &'static str {
        if self.passed { "passed" } else { "failed" }
    }

    /// "passed" or "FAILED", for a table's cell, where a failure must stand out.
    pub fn verdict_in_a_table(&self) -> &'static str {
        if self.passed { "passed" } else { "FAILED" }
    }

    /// The data reject the model: v^T P v above its 97.5 % bound (the model or the weights do
    /// not explain the scatter). A statistic below the 2.5 % bound fails the test too, but
    /// says the sigmas are pessimistic, not that the model is wrong.
    pub fn rejects_the_model(&self) -> bool {
        !self.passed && self.statistic > self.upper
    }

    /// What a failed test means and what to try, for the console and the report; None when
    /// it passed. `subject` names what was fitted ("triad triad lab", "thermal acc1 all").
    pub fn advice(&self, subject: &str, positions: bool) -> Option<String> {
        if self.passed {
            return None;
        }
        let causes = if positions {
            "a noise reference at odds with the noise inside the positions (align.json: the \
             quiet start's quiet_sd against the positions' sigma_white), motion or drift inside \
             the positions, or a model too small (a higher order, temperature terms)"
        } else {
            "a blunder the w-test did not reach, weights off (see the variance components), \
             or a model too small (a higher order, temperature terms, a misalignment)"
        };
        Some(if self.rejects_the_model() {
            format!(
                "GLOBAL TEST FAILED for {subject}: v^T P v {:.4e} is above its 97.5 % bound \
                 {:.4e}: the model or the weights do not explain the data, and its sigmas are \
                 not to be trusted. Likely causes: {causes}",
                self.statistic, self.upper
            )
        } else {
            format!(
                "global test failed low for {subject}: v^T P v {:.4e} is below its 2.5 % bound \
                 {:.4e}: the a-priori sigmas are larger than the scatter (pessimistic); the \
                 estimates stand, their sigmas are on the safe side (1 fit in 40 does this by \
                 chance)",
                self.statistic, self.lower
            )
        })
    }
}

/// One parameter.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Parameter {
    /// b, k, k2, k3, beta, b_t, k_t.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Estimate.
    pub value: f64,
    /// Sd from the estimated variance components: the one to quote. Where a component was
    /// estimated, the sd of the parameter's t on `dof` (docs/model.md 6.1).
    pub sigma: f64,
    /// Sd at the a-priori weights (every component 1).
    pub sigma_apriori: f64,
    /// Degrees of freedom of `sigma` (Welch-Satterthwaite over the estimated variance
    /// components); absent where no estimated component weighs the parameter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dof: Option<f64>,
}

impl Parameter {
    /// `name = value +/- sigma unit`, to the sigma's precision (GUM 7.2.6,
    /// [`crate::contract::precision`]): what the console and the report print.
    pub fn with_sigma(&self) -> String {
        let line = format!(
            "{} = {} {}",
            self.name,
            crate::contract::precision::value_with_sigma(self.value, self.sigma),
            self.unit
        );
        line.trim_end().to_owned()
    }
}

/// A variance component: the factor the data put on one observation group's a-priori
/// variances, and the test of whether it is 1.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VarianceComponent {
    /// `theodolite` or `ADC`.
    pub group: String,
    /// The factor (1 when not estimable).
    pub estimate: f64,
    /// Its sd (null when not estimable).
    pub sigma: Option<f64>,
    /// Degrees of freedom it was estimated on.
    pub dof: f64,
    /// The group's quadratic form at the a-priori weights.
    pub statistic: f64,
    /// Its expectation when the component is 1.
    pub expectation: f64,
    /// 2.5 % quantile of the statistic's reference.
    pub lower: f64,
    /// 97.5 % quantile.
    pub upper: f64,
    /// The component is consistent with 1 (two-sided, 5 %).
    pub passed: bool,
    /// Why it was not estimated (held at 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_estimable: Option<String>,
}

/// An observation removed by data snooping.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Removed {
    /// Session of the observation.
    pub session: String,
    /// Station.
    pub station: String,
    /// Line in the theodolite log.
    pub line: u32,
    /// GPS time, ns.
    pub time_gps_ns: i64,
    /// w-test value when removed (the normal quantile of its tail, its Dz referred to the
    /// station's sigma_Dz without it).
    pub w: f64,
}

/// Checks what an application of a fit reads of it (a calibration file is not trusted as it
/// is: it may come from anywhere): every value and sigma finite, sigmas positive, the
/// correlation matrix n x n, symmetric, with a unit diagonal, entries in [-1, 1], and
/// positive semi-definite. The message names the parameter or the entry.
pub fn check_parameters(
    parameters: &[Parameter],
    correlation: &[Vec<f64>],
) -> std::result::Result<(), String> {
    for p in parameters {
        if !p.value.is_finite() {
            return Err(format!("parameter {} is {} (not finite)", p.name, p.value));
        }
        if !(p.sigma.is_finite() && p.sigma > 0.0) {
            return Err(format!(
                "parameter {}: sigma {} is not a positive finite number",
                p.name, p.sigma
            ));
        }
    }
    let n = parameters.len();
    if correlation.len() != n || correlation.iter().any(|row| row.len() != n) {
        return Err(format!("the correlation matrix is not {n} x {n}"));
    }
    const TOLERANCE: f64 = 1e-9;
    let name = |i: usize| parameters[i].name.as_str();
    for i in 0..n {
        if (correlation[i][i] - 1.0).abs() > TOLERANCE {
            return Err(format!(
                "correlation of {} with itself is {}, not 1",
                name(i),
                correlation[i][i]
            ));
        }
        for j in 0..n {
            let r = correlation[i][j];
            if !(r.is_finite() && r.abs() <= 1.0 + TOLERANCE) {
                return Err(format!(
                    "correlation of {} with {} is {r}: not in [-1, 1]",
                    name(i),
                    name(j)
                ));
            }
            if (r - correlation[j][i]).abs() > TOLERANCE {
                return Err(format!(
                    "the correlation matrix is not symmetric ({} with {}: {r} and {})",
                    name(i),
                    name(j),
                    correlation[j][i]
                ));
            }
        }
    }
    // Positive semi-definite: Cholesky (LDL^T) with pivots allowed to be 0 to rounding.
    let mut l = vec![vec![0.0; n]; n];
    let mut d = vec![0.0; n];
    for j in 0..n {
        d[j] = correlation[j][j] - (0..j).map(|k| l[j][k] * l[j][k] * d[k]).sum::<f64>();
        if d[j] < -TOLERANCE {
            return Err(format!(
                "the correlation matrix is not positive semi-definite (pivot {:.3e} at {}): \
                 no covariance has these correlations",
                d[j],
                name(j)
            ));
        }
        for i in j + 1..n {
            let s = correlation[i][j] - (0..j).map(|k| l[i][k] * l[j][k] * d[k]).sum::<f64>();
            l[i][j] = if d[j] > TOLERANCE { s / d[j] } else { 0.0 };
        }
    }
    Ok(())
}

/// The session id of a fit over every session of a dataset (a model with `per = "all"`):
/// a scope, not a session, so the manifest reserves it as a session id.
pub const ALL_SESSIONS: &str = "all";

/// What a fit covers: one session, or every session of the dataset pooled. calibration.json
/// writes it as the session's id, or [`ALL_SESSIONS`] (which the manifest reserves).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FitScope {
    /// One session, by id.
    Session(String),
    /// Every session, pooled.
    All,
}

impl FitScope {
    /// As calibration.json writes it.
    pub fn id(&self) -> &str {
        match self {
            FitScope::Session(id) => id,
            FitScope::All => ALL_SESSIONS,
        }
    }

    /// Whether an observation of `session` belongs to the fit.
    pub fn covers(&self, session: &str) -> bool {
        match self {
            FitScope::Session(id) => id == session,
            FitScope::All => true,
        }
    }
}
/// The accelerometer id of a triad fit's rows where a row names an accelerometer (a fit not
/// made): the manifest reserves it as an accelerometer id.
pub const TRIAD: &str = "triad";

/// One fitted calibration function (docs/formats.md section 6).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationResult {
    /// Accelerometer id.
    pub accelerometer: String,
    /// Session id or [`ALL_SESSIONS`].
    pub session: String,
    /// Model name.
    pub model: String,
    /// Polynomial order.
    pub order: u8,
    /// Temperature terms.
    pub temperature: bool,
    /// Misalignment.
    pub misalignment: bool,
    /// Reference temperature of b and k (temperature models), degC.
    pub t_ref_c: Option<f64>,
    /// Mean temperature of the observations used, degC (absent when they carry none: a
    /// session without a thermometer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_temperature_c: Option<f64>,
    /// Least and greatest window mean of counts the fit used: the range it calibrates (an
    /// application outside it is flagged, docs/model.md 6.7).
    #[serde(default)]
    pub counts_range: Option<[f64; 2]>,
    /// Least and greatest temperature the fit used, degC.
    #[serde(default)]
    pub temperature_range_c: Option<[f64; 2]>,
    /// For a fit without temperature terms whose temperature moved, when no fit of the
    /// run with temperature terms measured the accelerometer's sensitivity (which its
    /// sigmas would then carry): the thermal sensitivity |dc/dT| = |b_t + k_t Ng| (mGal/K)
    /// at which that movement (the range of its observations' temperatures) is an effect
    /// of 0.3 sigma of b (docs/model.md 6.1). Its data cannot say whether the
    /// accelerometer's sensitivity is above it; a fit with temperature terms can.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal_sensitivity_limit_mgal_per_k: Option<f64>,
    /// Observations in the final adjustment.
    pub n_observations: usize,
    /// Observations removed by data snooping.
    pub n_excluded: usize,
    /// Degrees of freedom.
    pub dof: usize,
    /// Iterations of the final adjustment.
    pub iterations: usize,
    /// sqrt(v^T P v / dof) at the a-priori weights.
    pub sigma0: f64,
    /// The global test.
    pub global_test: GlobalTest,
    /// The variance components of the theodolite and the ADC.
    #[serde(default)]
    pub variance_components: Vec<VarianceComponent>,
    /// Parameters.
    pub parameters: Vec<Parameter>,
    /// Correlation matrix of the parameters.
    pub correlation: Vec<Vec<f64>>,
    /// Each removed observation with its w-test value.
    pub removed: Vec<Removed>,
    /// Notes on estimability (a parameter correlated above 0.999 with another; a vector
    /// misalignment that one roll could not determine), and on what the model does not
    /// carry (a temperature that moved, for a model without temperature terms).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The misalignment vector as a magnitude and a direction (models with
    /// `misalignment = "vector"` whose rolls determine it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub misalignment_vector: Option<MisalignmentVector>,
}

impl CalibrationResult {
    /// Whether the fit pooled every session ([`ALL_SESSIONS`]).
    pub fn over_all_sessions(&self) -> bool {
        self.session == ALL_SESSIONS
    }
}

/// The sensitive axis's misalignment as a magnitude and a direction in the block's frame.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MisalignmentVector {
    /// theta = sqrt(theta_x^2 + theta_y^2), rad.
    pub theta_rad: f64,
    /// Its sd, rad (propagated; near 0, where theta is not normal, the larger principal sd).
    pub sigma_theta_rad: f64,
    /// Direction psi = atan2(theta_y, theta_x), deg in (-180, 180]; null when theta is within
    /// 3 sigma of 0.
    pub psi_deg: Option<f64>,
    /// Its sd, deg (propagated); null with psi.
    pub sigma_psi_deg: Option<f64>,
    /// Why psi is not given, when it is not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub psi_not_determined: Option<String>,
}

/// A fit that has no result, with the reason.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Skipped {
    /// Accelerometer id.
    pub accelerometer: String,
    /// Session id or `all`.
    pub session: String,
    /// Model name.
    pub model: String,
    /// Why.
    pub reason: String,
}

/// A triad calibration in imu_tk's body frame: a = T K (X - B), T upper-triangular with unit
/// diagonal (angles a_yz, a_zy, a_zx), K = diag(s_x, s_y, s_z), B = (b_x, b_y, b_z).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriadResult {
    /// Model name.
    pub model: String,
    /// Session id or `all`.
    pub session: String,
    /// Unit of the readings X and the biases B.
    pub reading_unit: String,
    /// Polynomial order per axis (1: imu_tk's T K (X - B)).
    #[serde(default = "order_one")]
    pub order: u8,
    /// Bias and scale move with each axis's temperature.
    #[serde(default)]
    pub temperature: bool,
    /// The temperature tau = T - t_ref is counted from, degC (with temperature terms).
    #[serde(default)]
    pub t_ref_c: Option<f64>,
    /// Least and greatest temperature over the positions used, degC (with temperature
    /// terms): an application outside it is flagged.
    #[serde(default)]
    pub temperature_range_c: Option<[f64; 2]>,
    /// With temperature terms, the median over the positions used of each axis's
    /// temperature sd from the thermometer's noise, degC: the fit took the temperatures as
    /// observations with their sds (docs/model.md 6.5). None: taken as exact.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature_sd_c: Option<[f64; 3]>,
    /// a_yz, a_zy, a_zx (rad), s_x, s_y, s_z (mGal per reading unit), b_x, b_y, b_z; then
    /// by order s2_x.. (mGal per unit^2), s3_x.. (per unit^3); with temperature bt_x..
    /// (reading units per K) and st_x.. (mGal per unit per K).
    pub parameters: Vec<Parameter>,
    /// Correlation matrix of the parameters.
    pub correlation: Vec<Vec<f64>>,
    /// The sensitive axes' departures from orthogonality, from T: for the pairs xy, xz, yz,
    /// 90 deg minus the angle between the axes, mrad, with propagated sds.
    pub non_orthogonality_mrad: Vec<Parameter>,
    /// sqrt(v^T P v / dof) at the means' sigmas.
    pub sigma0: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Chi-square test of v^T P v, two-sided 5 %.
    pub global_test: GlobalTest,
    /// Positions in the final adjustment.
    pub positions_used: usize,
    /// Static positions left out of a model with temperature terms because the temperature
    /// log does not cover them (not in `positions`).
    #[serde(default)]
    pub positions_without_temperature: usize,
    /// Each position: |a| - g at the adjusted means, its w-test, its gravity direction in
    /// the body frame; removed positions flagged.
    pub positions: Vec<TriadPosition>,
    /// The imu_tk text file written beside calibration.json (T, K, B); none for a model
    /// with terms that layout has no place for (higher orders, temperature).
    pub calib_file: Option<String>,
    /// Least and greatest mean reading of each axis over the positions used: the range it
    /// calibrates (an application outside it is flagged).
    #[serde(default)]
    pub readings_range: Option<[[f64; 2]; 3]>,
    /// The position floor (the manifest's `position_floor`): the sd added to each
    /// position's gravity beyond its samples' scatter; none without one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_floor: Option<PositionFloorUsed>,
}

impl TriadResult {
    /// The floor, when it was estimated: then the global test judged the positions' own
    /// sigmas, and the floor took up what they did not explain.
    pub fn estimated_floor(&self) -> Option<&PositionFloorUsed> {
        self.position_floor
            .as_ref()
            .filter(|f| f.how == "estimated")
    }

    /// What the fit's global test means: with an estimated floor, the floor and its
    /// interval; else the test's own advice when it failed.
    pub fn advice(&self) -> Option<String> {
        let subject = format!("triad {} {}", self.model, self.session);
        let Some(f) = self.estimated_floor() else {
            return self.global_test.advice(&subject, true);
        };
        let interval = f.interval_mgal.map_or(String::new(), |[a, b]| {
            format!(" (95 %: {a:.3e} to {b:.3e})")
        });
        Some(format!(
            "{subject}: the positions scatter beyond their own sigmas (sigma0 {:.3} at those; \
             global test {}), so a position floor of {:.3e} mGal{interval} was estimated and \
             added to every position: the sigmas include it. A block placed by hand does this; \
             so does a model too small (a higher order, temperature terms), which a floor \
             would hide: look at the residuals beside the directions (the report plots both)",
            self.sigma0,
            self.global_test.verdict(),
            f.mgal
        ))
    }

    /// `, position floor <mGal> <how>`, or nothing without one: for a fit's line.
    pub fn floor_clause(&self) -> String {
        self.position_floor.as_ref().map_or(String::new(), |f| {
            format!(", position floor {:.3e} mGal {}", f.mgal, f.how)
        })
    }
}

/// The position floor a triad fit used (docs/model.md 6.5).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PositionFloorUsed {
    /// The sd added to each position's gravity, mGal.
    pub mgal: f64,
    /// `"declared"` or `"estimated"`.
    pub how: String,
    /// Estimated: its 95 % interval, mGal (the floors at which the fit's v^T P v reaches
    /// its chi-square's 97.5 % and 2.5 % points).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_mgal: Option<[f64; 2]>,
}

fn order_one() -> u8 {
    1
}

/// One static position of a triad fit.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriadPosition {
    /// Session id.
    pub session: String,
    /// First sample's GPS time, ns.
    pub start_gps_ns: i64,
    /// |a| - g, mGal: the misclosure the adjustment took up (at the last adjustment the
    /// position took part in).
    pub residual_mgal: f64,
    /// Its w-test.
    pub w: f64,
    /// Unit vector of the calibrated specific force in the body frame.
    pub direction: [f64; 3],
    /// Temperature of the three axes, degC, when logged.
    #[serde(default)]
    pub temperature_c: Option<[f64; 3]>,
    /// Removed by data snooping.
    pub removed: bool,
}

/// An accelerometer's noise terms in SI units, under the names of Kalibr's `imu.yaml`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KalibrNoise {
    /// Accelerometer id.
    pub accelerometer: String,
    /// The fit whose k converted counts to acceleration: `model session`.
    pub scale_from: String,
    /// White-noise density, m/s^2/sqrt(Hz) (velocity random walk).
    pub accelerometer_noise_density: f64,
    /// Random walk of the bias, m/s^3/sqrt(Hz); null when the Allan deviation does not
    /// determine it.
    pub accelerometer_random_walk: Option<f64>,
    /// Bias instability (the flicker floor), m/s^2; null when not determined.
    pub bias_instability: Option<f64>,
}

/// Whether b and k of one accelerometer repeat between the sessions a model was fitted to
/// one at a time (docs/model.md 6.9): the homogeneity test of their (b, k) at their sigmas.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Repeatability {
    /// The model, fitted per session.
    pub model: String,
    /// Accelerometer id.
    pub accelerometer: String,
    /// The sessions, as fitted.
    pub sessions: Vec<String>,
    /// Each session's mean temperature, degC (null without a thermometer).
    pub mean_temperatures_c: Vec<Option<f64>>,
    /// Each session's b, mGal.
    pub b_mgal: Vec<f64>,
    /// Its sigma.
    pub sigma_b_mgal: Vec<f64>,
    /// sum (x_i - x)' C_i^-1 (x_i - x) over the sessions' (b, k) about their weighted mean.
    pub statistic: f64,
    /// Its degrees of freedom, 2 (sessions - 1).
    pub dof: u32,
    /// The chi-square upper tail at the statistic.
    pub p_value: f64,
    /// b and k repeat at the 5 % level.
    pub passed: bool,
}

impl Repeatability {
    /// The verdict in a sentence, for the console and the report: each session's b with
    /// its sigma (and its mean temperature), and what a change may be.
    pub fn sentence(&self) -> String {
        let b: Vec<String> = self
            .sessions
            .iter()
            .zip(self.b_mgal.iter().zip(&self.sigma_b_mgal))
            .zip(&self.mean_temperatures_c)
            .map(|((s, (b, sb)), t)| {
                let at = t.map_or(String::new(), |t| format!(" at {t:.2} degC"));
                format!(
                    "{} mGal in {s}{at}",
                    crate::contract::precision::value_with_sigma(*b, *sb)
                )
            })
            .collect();
        let test = format!(
            "chi-square {:.2} on {} dof, p {}",
            self.statistic,
            self.dof,
            self.p_text()
        );
        let temperatures: Vec<f64> = self.mean_temperatures_c.iter().flatten().copied().collect();
        let spread = temperatures
            .iter()
            .fold(f64::NEG_INFINITY, |a, &t| a.max(t))
            - temperatures.iter().fold(f64::INFINITY, |a, &t| a.min(t));
        if self.passed {
            format!(
                "{} {}: b and k repeat between sessions {} ({test}; b {})",
                self.model,
                self.accelerometer,
                self.sessions.join(", "),
                b.join(", ")
            )
        } else {
            format!(
                "{} {}: b and k differ between sessions {} beyond their sigmas ({test}; b {}): {}",
                self.model,
                self.accelerometer,
                self.sessions.join(", "),
                b.join(", "),
                if spread > 0.1 {
                    format!(
                        "the sessions' mean temperatures differ by {spread:.2} degC, so a \
                         temperature effect (a model with temperature terms) or a change of the \
                         instrument between them"
                    )
                } else {
                    "a change of the instrument between them (their temperatures hardly \
                     differ), or sigmas too small"
                        .to_owned()
                }
            )
        }
    }

    /// The p-value to three decimals, or two significant digits below 0.001.
    pub fn p_text(&self) -> String {
        let p = self.p_value;
        if p >= 0.001 {
            format!("{p:.3}")
        } else if p >= 1e-99 {
            format!("{p:.1e}")
        } else {
            "below 1e-99".to_owned()
        }
    }
}

/// mGal per reading unit of the physical units, as the manifest names them.
const PHYSICAL_UNITS: [(&str, f64); 3] = [("m/s^2", 1e5), ("mGal", 1.0), ("g", 980_665.0)];

/// A scale factor `name` = `scale` (mGal per reading unit) that does not fit the declared
/// physical `unit` (issue 49): a calibrated accelerometer's is within a factor 2 of the
/// unit's mGal (its scale error is a few per cent at most), so a scale beyond says the
/// readings are in another unit, named where one fits. None for counts and volts, whose
/// scale is the instrument's own.
pub fn scale_unit_warning(unit: &str, name: &str, scale: f64) -> Option<String> {
    let (_, factor) = PHYSICAL_UNITS.iter().find(|(u, _)| *u == unit)?;
    let fits = |f: f64| (0.5..=2.0).contains(&(scale.abs() / f));
    if fits(*factor) {
        return None;
    }
    let suggested = PHYSICAL_UNITS
        .iter()
        .find(|(_, f)| fits(*f))
        .map_or("no physical unit gravcal knows".to_owned(), |(u, _)| {
            format!("\"{u}\"")
        });
    Some(format!(
        "{name} = {scale:.4e} mGal per {unit}, where readings in {unit} give a scale near \
         {factor:.0} (a scale error of a few per cent): the readings look like {suggested}; \
         check instrument.reading_unit. The fit itself maps the readings to mGal, but a \
         calibration applied in the declared unit would be wrong by that factor"
    ))
}

impl TriadResult {
    /// Its scales s_x, s_y, s_z held to its reading unit ([`scale_unit_warning`]).
    pub fn unit_warnings(&self) -> Vec<String> {
        self.parameters
            .iter()
            .filter(|p| p.name.starts_with("s_"))
            .filter_map(|p| scale_unit_warning(&self.reading_unit, &p.name, p.value))
            .collect()
    }
}

/// A fitted bias beyond the instrument's full scale (docs/formats.md 6): the acceleration
/// its ADC's zero stands for cannot be beyond the range the accelerometer measures (a
/// QA3000's is a few mg, a consumer MEMS's tens of mg, the full scale g's). One beyond says
/// the readings are not this accelerometer's, or not in the declared unit, or the reference
/// they were fitted to is not theirs. An ADC's zero is reading 0 (two's complement), or for
/// counts mid-scale, 2^(adc_bits - 1) (offset binary: an unsigned 16-bit IMU's raw counts
/// stand near 32768 still, as imu_tk's own Xsens test data): `zeros` gives the acceleration
/// at reading 0 and, for counts, at mid-scale, mGal; the one nearer zero g is held to the
/// bound. The refusal names the parameter and its bound; None when within.
pub fn bias_beyond_full_scale(
    name: &str,
    zeros: (f64, Option<f64>),
    instrument: &Instrument,
) -> Option<String> {
    let full_scale_g = instrument.full_scale_g;
    let bound = full_scale_g * 980_665.0;
    let bias_mgal = match zeros {
        (at_zero, Some(at_mid)) if at_mid.abs() < at_zero.abs() => at_mid,
        (at_zero, _) => at_zero,
    };
    (bias_mgal.abs() > bound || bias_mgal.is_nan()).then(|| {
        let offset_binary = match zeros.1 {
            Some(at_mid) => format!(
                ", and {:.2} g at mid-scale, count 2^{} (an offset-binary ADC's zero: \
                 instrument.adc_bits = {} says where it is)",
                at_mid / 980_665.0,
                instrument.adc_bits - 1,
                instrument.adc_bits
            ),
            None => String::new(),
        };
        format!(
            "implausible: the fitted bias {name} = {:.0} mGal ({:.2} g{offset_binary}) is beyond \
             the instrument's full scale (+/-{full_scale_g} g, instrument.full_scale_g); likely a \
             channel that is not this accelerometer's (channel, adc_columns), readings in \
             another unit than instrument.reading_unit, or a reference of another instrument",
            zeros.0,
            zeros.0 / 980_665.0
        )
    })
}

/// Mid-scale of the instrument's ADC, counts, when its readings are counts: 2^(adc_bits - 1).
fn mid_scale(instrument: &Instrument) -> Option<f64> {
    (instrument.reading_unit == ReadingUnit::Count)
        .then(|| 2f64.powi(i32::try_from(instrument.adc_bits).unwrap_or(32) - 1))
}

impl CalibrationResult {
    /// Its bias `b` held to the instrument's full scale ([`bias_beyond_full_scale`]): `b` at
    /// reading 0, `b + k 2^(adc_bits - 1)` at mid-scale.
    pub fn implausible(&self, instrument: &Instrument) -> Option<String> {
        let value = |name: &str| {
            self.parameters
                .iter()
                .find(|p| p.name == name)
                .map(|p| p.value)
        };
        let b = value("b")?;
        let at_mid = mid_scale(instrument).and_then(|m| Some(b + value("k")? * m));
        bias_beyond_full_scale("b", (b, at_mid), instrument)
    }
}

impl TriadResult {
    /// Its biases held to the instrument's full scale, each in mGal as its scale makes it
    /// (`s_j b_j` at reading 0, `s_j (b_j - 2^(adc_bits - 1))` at mid-scale,
    /// [`bias_beyond_full_scale`]); the first beyond.
    pub fn implausible(&self, instrument: &Instrument) -> Option<String> {
        let value = |name: String| {
            self.parameters
                .iter()
                .find(|p| p.name == name)
                .map(|p| p.value)
        };
        ["x", "y", "z"].iter().find_map(|axis| {
            let (s, b) = (value(format!("s_{axis}"))?, value(format!("b_{axis}"))?);
            let at_mid = mid_scale(instrument).map(|m| s * (b - m));
            bias_beyond_full_scale(&format!("s_{axis} b_{axis}"), (s * b, at_mid), instrument)
        })
    }
}

/// `calibration.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// [`CALIBRATION_FORMAT`].
    pub format: String,
    /// Dataset name.
    pub dataset: String,
    /// Software and version.
    pub software: String,
    /// Raw inputs and their hashes.
    pub inputs: Vec<Input>,
    /// Gravity at the proof masses, mGal.
    pub gravity_mgal: f64,
    /// The accelerometers calibrated, as the manifest declares them (id, channel, serial):
    /// what `apply` checks a survey's instrument against.
    #[serde(default)]
    pub accelerometers: Vec<crate::contract::manifest::Accelerometer>,
    /// The unit of the readings every fit was made on (the manifest's `reading_unit`:
    /// "count" for ADC counts); k is in mGal per this unit. A calibration written before
    /// this field was recorded is in counts.
    #[serde(default = "count_unit")]
    pub reading_unit: String,
    /// Fitted calibrations.
    pub results: Vec<CalibrationResult>,
    /// Fits without a result.
    pub skipped: Vec<Skipped>,
    /// Triad calibrations (models of kind "triad", docs/formats.md 8.4); fits without a result
    /// are in `skipped` with the accelerometer `triad`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub triad: Vec<TriadResult>,
    /// Every file adjust read (the manifest, the upstream ledgers and observations) and
    /// wrote (residuals.parquet), with its SHA-256: with `inputs`, exactly what the numbers
    /// came from.
    pub custody: Custody,
    /// Each accelerometer's ADC noise in SI units under Kalibr's `imu.yaml` names, from
    /// align's Allan deviation in counts and the scale factor k of one of its fits.
    #[serde(default)]
    pub adc_noise: Vec<KalibrNoise>,
    /// Whether the body tide was applied to g per observation, and its range; or why not.
    #[serde(default)]
    pub earth_tide: String,
    /// Whether b and k repeat between sessions, per model fitted per session and
    /// accelerometer with two or more sessions.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub repeatability: Vec<Repeatability>,
}

/// The stage's folder in OUT.
pub const STAGE_DIR: &str = "adjust";

fn count_unit() -> String {
    ReadingUnit::Count.name().to_owned()
}

impl Calibration {
    /// What a failed component test means and what to try, once for the console and the report: how many
    /// failed of how many tested, against the one in twenty a 5 % test fails by chance.
    pub fn component_advice(&self) -> Option<String> {
        let tested: Vec<(&CalibrationResult, &VarianceComponent)> = self
            .results
            .iter()
            .flat_map(|r| r.variance_components.iter().map(move |c| (r, c)))
            .filter(|(_, c)| c.not_estimable.is_none())
            .collect();
        let failed: Vec<String> = tested
            .iter()
            .filter(|(_, c)| !c.passed)
            .map(|(r, c)| {
                format!(
                    "{} {} {} {} x {:.2}",
                    r.model, r.accelerometer, r.session, c.group, c.estimate
                )
            })
            .collect();
        if failed.is_empty() {
            return None;
        }
        Some(format!(
            "{} of {} component tests failed ({}); a 5 % test fails in about {:.1} of {} by chance. \
             A factor below 1 means that group's a-priori variances were too large, above 1 too \
             small; the sigmas above already use the estimated factor, so the calibration stands. \
             What to try when failures recur across sessions and accelerometers: for the \
             theodolite, its sd per reading (align's sigma_dz, or [align] sigma_dz = \"station\"); \
             for the ADC, the window length ([align] window_s) and the noise terms align kept \
             (the Allan section).",
            failed.len(),
            tested.len(),
            failed.join("; "),
            0.05 * tested.len() as f64,
            tested.len()
        ))
    }

    /// Reads `dir/calibration.json` (`dir` being OUT/adjust).
    pub fn load(dir: &Path) -> Result<Self> {
        crate::read_json(&dir.join(CALIBRATION_FILE))
    }

    /// Reads OUT/adjust/calibration.json and checks the whole chain behind it: ingest's and
    /// align's records and its own still match the files on disk, all for `ds`.
    pub fn load_verified(ds: &Dataset, out: &Path) -> Result<Self> {
        ingest_ledger::IngestReport::load_verified(ds, out)?;
        align_ledger::AlignReport::load_verified(ds, out)?;
        let dir = out.join(STAGE_DIR);
        let c = Calibration::load(&dir)?;
        check_dataset(&dir.join(CALIBRATION_FILE), &c.dataset, &ds.manifest.name)?;
        let folders = Folders {
            dataset: &ds.dir,
            out,
        };
        folders.verify(&c.custody, STAGE_DIR, STAGE_DIR)?;
        Ok(c)
    }
}
