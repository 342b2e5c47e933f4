//! One calibration fit: the Gauss-Helmert adjustment of docs/model.md section 2 for one
//! accelerometer over a set of observations, with data snooping (Baarda's w-test at
//! alpha = 0.001, critical value 3.29), the global test, and the parameters mapped back to
//! counts. No I/O.

use crate::calibration::model::{CalibrationConditions, Misalignment, Terms, apply, propagate};
use crate::lsq::components::{self, Component, ScaledChi2};
use crate::lsq::correlated::{self, ColouredAdc, Timeline};
use crate::lsq::gh::{self, GhError, Options};
use rayon::prelude::{
    IndexedParallelIterator, IntoParallelRefIterator, IntoParallelRefMutIterator, ParallelIterator,
    ParallelSlice, ParallelSliceMut,
};

/// Critical value of the w-test (two-sided, alpha = 0.001).
pub const W_CRITICAL: f64 = 3.29;

/// A reading's sigma_Dz formed without it (align's leave-one-out estimate): a blunder
/// inflates its own station's variance, so its w-test is referred to the others'.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeftOut {
    /// sd of one reading, rad.
    pub sigma_rad: f64,
    /// Its degrees of freedom (None: known).
    pub dof: Option<f64>,
}

/// One observation as the fit sees it.
#[derive(Clone, Debug)]
pub struct Obs {
    /// Zenith distance, rad.
    pub dz_rad: f64,
    /// Sd of one Dz reading, rad.
    pub sigma_dz_rad: f64,
    /// Degrees of freedom of that sd when it was estimated from readings (None: known). The
    /// fit weighs Dz by the predictive variance, sigma^2 d / (d - 2).
    pub sigma_dz_dof: Option<f64>,
    /// The station's sigma_Dz formed without this reading, the reference of its w-test
    /// (None: sigma_dz_rad and its dof, as for a sigma taken as known).
    pub sigma_dz_left_out: Option<LeftOut>,
    /// The station (a platform position) the reading belongs to: observations of one
    /// station share its index, unique within a fit.
    pub station: usize,
    /// The session, an index unique within a fit (coloured ADC noise is correlated within
    /// a session only).
    pub session: usize,
    /// Time of the reading, s (any origin).
    pub time_s: f64,
    /// Roll of the block in the reading's session, rad (docs/formats.md 8.2).
    pub roll_rad: f64,
    /// Mean counts.
    pub ng: f64,
    /// Sd of Ng.
    pub sigma_ng: f64,
    /// Degrees of freedom of that sd when it was estimated from the window's samples (None:
    /// known). The ADC component's reference takes it into account.
    pub sigma_ng_dof: Option<f64>,
    /// Temperature, degC.
    pub temperature_c: f64,
    /// Its sd from the thermometer's noise, degC (0: taken as exact). A model with
    /// temperature terms takes the temperature as an observation with this sd.
    pub sigma_temperature_c: f64,
    /// Body tide at the reading, mGal, added to the fit's gravity (0 when none).
    pub tide_mgal: f64,
}

/// Why a fit has no result.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CalError {
    /// The design cannot determine this parameter.
    #[error("parameter {parameter} is not estimable: {why}")]
    NotEstimable {
        /// Its name.
        parameter: &'static str,
        /// What in the design leaves it undetermined, and what would fix it.
        why: String,
    },
    /// An observation's condition has no variance (both its sds, or their derivatives,
    /// vanish); `index` is into the fit's observations, for the caller to name it.
    #[error("observation {index} has zero variance")]
    ZeroVariance {
        /// Index into the fit's observations.
        index: usize,
    },
    /// Too few observations.
    #[error("{n} observations for {m} parameters")]
    TooFew {
        /// Observations.
        n: usize,
        /// Parameters.
        m: usize,
    },
    /// The adjustment failed otherwise.
    #[error(transparent)]
    Adjustment(GhError),
}

/// An observation removed by data snooping.
#[derive(Clone, Debug, PartialEq)]
pub struct Removal {
    /// Index into the fit's observations.
    pub index: usize,
    /// Its w-test value when it was removed.
    pub w: f64,
    /// The adjustment round (1-based) that flagged it; 0 for a gross error screened out
    /// before the adjustment ([`GROSS_ERROR_SDS`]).
    pub round: usize,
}

/// Per observation of the final adjustment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residual {
    /// Index into the fit's observations.
    pub index: usize,
    /// Residual of Dz, rad.
    pub v_dz_rad: f64,
    /// Residual of Ng, counts.
    pub v_ng: f64,
    /// Condition residual, mGal.
    pub misclosure_mgal: f64,
    /// Redundancy number.
    pub redundancy: f64,
    /// Normalised residual.
    pub w: f64,
}

/// The observations of the final adjustment with their residuals, a column per quantity:
/// the adjustment's own vectors, taken over rather than copied into rows (at a million
/// observations, 48 MB of fresh pages and a pass).
#[derive(Clone, Debug, Default)]
pub struct Residuals {
    index: Vec<usize>,
    v: Vec<[f64; 3]>,
    misclosure: Vec<f64>,
    redundancy: Vec<f64>,
    w: Vec<f64>,
}

impl Residuals {
    /// The residuals of `s`'s conditions, whose observations are `index` into the fit's.
    fn of(index: Vec<usize>, s: gh::Solution<3>) -> Self {
        Residuals {
            index,
            v: s.v,
            misclosure: s.misclosure,
            redundancy: s.redundancy,
            w: s.w_test,
        }
    }

    /// How many observations the adjustment used.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether it used none.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// The `k`th observation used.
    pub fn get(&self, k: usize) -> Residual {
        Residual {
            index: self.index[k],
            v_dz_rad: self.v[k][0],
            v_ng: self.v[k][1],
            misclosure_mgal: self.misclosure[k],
            redundancy: self.redundancy[k],
            w: self.w[k],
        }
    }

    /// Each observation used, in the adjustment's order.
    pub fn iter(&self) -> ResidualIter<'_> {
        ResidualIter { of: self, next: 0 }
    }
}

/// The rows of [`Residuals`], by value.
pub struct ResidualIter<'a> {
    of: &'a Residuals,
    next: usize,
}

impl Iterator for ResidualIter<'_> {
    type Item = Residual;

    fn next(&mut self) -> Option<Residual> {
        let k = self.next;
        (k < self.of.len()).then(|| {
            self.next += 1;
            self.of.get(k)
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.of.len() - self.next;
        (left, Some(left))
    }
}

impl ExactSizeIterator for ResidualIter<'_> {}

impl<'a> IntoIterator for &'a Residuals {
    type Item = Residual;
    type IntoIter = ResidualIter<'a>;

    fn into_iter(self) -> ResidualIter<'a> {
        self.iter()
    }
}

/// A fitted calibration.
#[derive(Clone, Debug)]
pub struct CalibrationSolution {
    /// Parameters in counts: b, k, [k2], [k3], [b_t, k_t], [beta | theta_x, theta_y].
    pub values: Vec<f64>,
    /// Their covariance from the estimated variance components, row-major, each variance
    /// that of the parameter's t on `parameter_dof` (nu / (nu - 2) times the adjustment's).
    pub covariance: Vec<f64>,
    /// The dof of each parameter's variance (Welch-Satterthwaite over the estimated
    /// components); None where none weighs it, so that it is known.
    pub parameter_dof: Vec<Option<f64>>,
    /// Their covariance at the a-priori weights (every component 1), row-major.
    pub covariance_apriori: Vec<f64>,
    /// sqrt(v^T P v / dof) at the a-priori weights.
    pub sigma0: f64,
    /// v^T P v at the a-priori weights.
    pub vtpv: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Iterations of the final adjustment.
    pub iterations: usize,
    /// Reference temperature (temperature models), degC.
    pub t_ref_c: f64,
    /// Mean temperature of the observations used, degC.
    pub mean_temperature_c: f64,
    /// Global test at the a-priori weights: the between-station part of v^T P v against its
    /// scaled chi-square ([`components::lack_of_fit`]).
    pub global_test: ScaledChi2,
    /// The variance components of the theodolite and the ADC.
    pub components: Vec<Component>,
    /// Removed by snooping, in order.
    pub removed: Vec<Removal>,
    /// The observations used, with their residuals.
    pub residuals: Residuals,
    /// A model without temperature terms: what a thermal sensitivity it does not include
    /// moves each parameter by, per unit of b_t (mGal/degC) and of k_t (mGal/bit/degC),
    /// the effect being `(b_t + k_t Ng) (T - mean_temperature_c)` at each observation
    /// ([`CalibrationSolution::thermal_covariance`]). Empty with temperature terms.
    pub thermal_gain: Vec<[f64; 2]>,
}

/// A thermal sensitivity dc/dT = b_t + k_t Ng (mGal/degC), as a fit with temperature terms
/// estimated it: the size of what a model without them leaves in its parameters
/// (docs/model.md 6.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensitivity {
    /// b_t, mGal/degC.
    pub b_t: f64,
    /// k_t, mGal/bit/degC.
    pub k_t: f64,
}

impl Sensitivity {
    /// From a fit with temperature terms `terms` (None without them).
    pub fn of(f: &CalibrationSolution, terms: Terms) -> Option<Self> {
        let names = terms.names();
        let at = |name: &str| names.iter().position(|n| n.name == name);
        Some(Self {
            b_t: f.values[at("b_t")?],
            k_t: f.values[at("k_t")?],
        })
    }
}

impl CalibrationSolution {
    /// Sd of parameter j from the estimated variance components.
    pub fn sigma(&self, j: usize) -> f64 {
        let n = self.values.len();
        self.covariance[j * n + j].max(0.0).sqrt()
    }
    /// A-priori sd of parameter j.
    pub fn sigma_apriori(&self, j: usize) -> f64 {
        let n = self.values.len();
        self.covariance_apriori[j * n + j].max(0.0).sqrt()
    }
    /// Correlation matrix.
    pub fn correlation(&self) -> Vec<Vec<f64>> {
        let n = self.values.len();
        (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let d = self.sigma_apriori(i) * self.sigma_apriori(j);
                        if d > 0.0 {
                            self.covariance_apriori[i * n + j] / d
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect()
    }
    /// Whether the global test passed (two-sided, 5 %).
    pub fn global_test_passed(&self) -> bool {
        self.global_test.passed()
    }
    /// The covariance (row-major, counts) that a thermal sensitivity `s` this model does not
    /// include adds to its parameters, taken as a consider parameter whose second moment is
    /// the estimate's own (`s s^T`; its expectation is the truth's plus the estimate's
    /// covariance): `G s s^T G^T` with G the [`thermal_gain`](Self::thermal_gain). Zero
    /// with temperature terms.
    pub fn thermal_covariance(&self, s: Sensitivity) -> Vec<f64> {
        let m = self.values.len();
        let shift: Vec<f64> = if self.thermal_gain.len() == m {
            self.thermal_gain
                .iter()
                .map(|g| g[0] * s.b_t + g[1] * s.k_t)
                .collect()
        } else {
            vec![0.0; m]
        };
        let mut out = vec![0.0; m * m];
        for i in 0..m {
            for j in 0..m {
                out[i * m + j] = shift[i] * shift[j];
            }
        }
        out
    }
}

/// How many observations data snooping may remove.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Snooping {
    /// One at a time while a w-test exceeds [`W_CRITICAL`], at most a tenth of them.
    TenthAtMost,
    /// None: one adjustment (for benchmarks of the adjustment itself).
    Off,
}

/// Tilt positions closer than this many sds of Dz are one position in [`design_check`].
const LEVEL_SEPARATION_SIGMAS: f64 = 10.0;
/// Counts whose whole spread is below this many sds of a window mean do not vary with tilt.
const COUNT_SPREAD_SIGMAS: f64 = 10.0;
/// Temperature terms need observations at least this far apart, degC (the same step that
/// makes the default models add the thermal one).
pub const MIN_TEMPERATURE_SPREAD_C: f64 = 1.0;

/// Whether the design can determine every parameter of `terms`, by what varies in it: the
/// polynomial of order n needs n + 1 distinct tilt positions (Dz values further apart than
/// [`LEVEL_SEPARATION_SIGMAS`] of their sd, counted along the spread of Dz, so a continuous
/// design is many positions) and counts that vary by more than noise
/// ([`COUNT_SPREAD_SIGMAS`] sds of a window mean); temperature terms need temperatures
/// spread over [`MIN_TEMPERATURE_SPREAD_C`]. These are the columns of the design scaled by
/// their noise: a column that varies by no more than its noise is numerically of full rank
/// and statistically empty, and would give a number with an absurd sigma. The QR of the
/// adjustment still catches exact rank loss (e.g. beta with tilts on one side only).
pub fn design_check(obs: &[Obs], terms: Terms) -> Result<(), CalError> {
    check_design(obs, terms).map(drop)
}

/// [`design_check`], returning what it read of the observations.
fn check_design(obs: &[Obs], terms: Terms) -> Result<Spread, CalError> {
    let names = terms.names();
    let mut spread = Spread::of(obs);
    // The element a sort would put in the middle, without the sort (total_cmp is a total
    // order: equal values are the same bits, so this cannot differ from a stable sort's).
    let median = |values: &mut Vec<f64>| {
        let mid = values.len() / 2;
        if values.is_empty() {
            0.0
        } else {
            *values.select_nth_unstable_by(mid, f64::total_cmp).1
        }
    };
    let (dz_median, noise) = rayon::join(
        || median(&mut spread.sigma_dz),
        || median(&mut spread.sigma_ng),
    );
    let separation = LEVEL_SEPARATION_SIGMAS * dz_median;
    let levels = tilt_levels(
        &spread.dz,
        spread.lowest_dz,
        separation.max(1e-9),
        terms.order + 1,
    );
    if levels < terms.order + 1 && !obs.is_empty() {
        return Err(CalError::NotEstimable {
            parameter: names[levels].name,
            why: format!(
                "the observations come from {levels} tilt position(s) (Dz {:.4} to {:.4} deg); \
                 a polynomial of order {} needs {} positions at different Dz",
                spread.lowest_dz.to_degrees(),
                spread.highest_dz.to_degrees(),
                terms.order,
                terms.order + 1
            ),
        });
    }
    let (lo, hi) = (spread.lowest_ng, spread.highest_ng);
    if hi - lo <= COUNT_SPREAD_SIGMAS * noise {
        return Err(CalError::NotEstimable {
            parameter: names[1].name,
            why: format!(
                "the counts do not vary with the tilt: they span {:.3} counts, against a noise \
                 of {noise:.3} counts per window mean",
                hi - lo
            ),
        });
    }
    if terms.temperature {
        let (lo, hi) = spread
            .t
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
                (a.min(*t), b.max(*t))
            });
        if hi - lo < MIN_TEMPERATURE_SPREAD_C {
            return Err(CalError::NotEstimable {
                parameter: "b_t",
                why: format!(
                    "one temperature set: the observations span {lo:.2} to {hi:.2} degC; b_t \
                     and k_t need temperatures at least {MIN_TEMPERATURE_SPREAD_C} degC apart \
                     (a second session at another temperature)"
                ),
            });
        }
    }
    Ok(spread)
}

/// What the design check reads of the observations, in one pass on the pool: the Dz (for
/// the tilt positions), the sds of Dz and of Ng (for their medians), the lowest and highest
/// Dz, the lowest and highest Ng; and for the fit's centres ([`Columns`]), the counts, the
/// temperatures and whether any reading has a tide.
struct Spread {
    dz: Vec<f64>,
    ng: Vec<f64>,
    t: Vec<f64>,
    tides: bool,
    sigma_dz: Vec<f64>,
    sigma_ng: Vec<f64>,
    lowest_dz: f64,
    highest_dz: f64,
    lowest_ng: f64,
    highest_ng: f64,
}

impl Spread {
    fn of(obs: &[Obs]) -> Self {
        const ROWS: usize = gh::TASK_ROWS;
        let column = || vec![0.0; obs.len()];
        let (mut dz, mut ng, mut t) = (column(), column(), column());
        let (mut sigma_dz, mut sigma_ng) = (column(), column());
        let none = (
            [
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ],
            false,
        );
        // Lowest and highest are the same in any order: the tasks reduce as they finish.
        let ([lowest_dz, highest_dz, lowest_ng, highest_ng], tides) = dz
            .par_chunks_mut(ROWS)
            .zip(ng.par_chunks_mut(ROWS))
            .zip(t.par_chunks_mut(ROWS))
            .zip(sigma_dz.par_chunks_mut(ROWS))
            .zip(sigma_ng.par_chunks_mut(ROWS))
            .zip(obs.par_chunks(ROWS))
            .map(|(((((dz, ng), t), sigma_dz), sigma_ng), rows)| {
                let (mut ends, mut tides) = none;
                for (k, o) in rows.iter().enumerate() {
                    (dz[k], ng[k], t[k]) = (o.dz_rad, o.ng, o.temperature_c);
                    (sigma_dz[k], sigma_ng[k]) = (o.sigma_dz_rad, o.sigma_ng);
                    tides |= o.tide_mgal != 0.0;
                    ends = [
                        ends[0].min(o.dz_rad),
                        ends[1].max(o.dz_rad),
                        ends[2].min(o.ng),
                        ends[3].max(o.ng),
                    ];
                }
                (ends, tides)
            })
            .reduce(
                || none,
                |(a, ta), (b, tb)| {
                    (
                        [
                            a[0].min(b[0]),
                            a[1].max(b[1]),
                            a[2].min(b[2]),
                            a[3].max(b[3]),
                        ],
                        ta || tb,
                    )
                },
            );
        Spread {
            dz,
            ng,
            t,
            tides,
            sigma_dz,
            sigma_ng,
            lowest_dz,
            highest_dz,
            lowest_ng,
            highest_ng,
        }
    }
}

/// The tilt positions among the observations' Dz `dz` (whose lowest is `lowest`), counted
/// up to `most`: bins of width `separation` from the lowest Dz, a new one beginning at the
/// lowest Dz past the current one's start by more than the separation (the bins a pass
/// over the sorted Dz would open, found by one pass per bin instead of a sort of every
/// observation).
/// Chaining neighbours instead made a continuous spread of Dz (a motorised table read at
/// many angles) one "position".
fn tilt_levels(dz: &[f64], lowest: f64, separation: f64, most: usize) -> usize {
    if dz.is_empty() || most == 0 {
        return 0;
    }
    let mut levels = 1usize;
    let mut start = lowest;
    while levels < most {
        let next = dz
            .par_iter()
            .copied()
            .filter(|d| d - start > separation)
            .min_by(f64::total_cmp);
        let Some(d) = next else { break };
        levels += 1;
        start = d;
    }
    levels
}

/// A misclosure further than this many robust sds from a robust straight line of
/// `-g cos Dz` on the counts is a gross error, removed before the adjustment: one reading of Dz = 0 among
/// readings at 120 deg misses by 10^5 sds, pulls the first linearisation so far that the
/// other readings' Dz residuals reach radians, and the iteration never settles. Fixed
/// high so that every blunder within reach of the w-test is left to it.
pub const GROSS_ERROR_SDS: f64 = 1000.0;

/// Removes gross errors one at a time (the largest first, at most `max_removals`): an
/// observation whose residual from a robust straight line of `-g cos Dz` on Ng exceeds
/// [`GROSS_ERROR_SDS`] robust sds (1.4826 x the median absolute residual). Returns them as
/// removals of round 0, with the residual in robust sds as their w.
fn screen_gross_errors(
    obs: &[Obs],
    active: &mut Vec<usize>,
    g_mgal: f64,
    max_removals: usize,
) -> Vec<Removal> {
    let mut removed = Vec::new();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    while removed.len() < max_removals && active.len() > 3 {
        // A robust line: the median slope between points half the sample apart in Ng, and
        // the median intercept; a gross error moves neither.
        let mut pts: Vec<(f64, f64)> = active
            .iter()
            .map(|&i| (obs[i].ng, -g_mgal * obs[i].dz_rad.cos()))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let h = pts.len() / 2;
        let slopes: Vec<f64> = (0..pts.len() - h)
            .filter(|&j| pts[j + h].0 > pts[j].0)
            .map(|j| (pts[j + h].1 - pts[j].1) / (pts[j + h].0 - pts[j].0))
            .collect();
        if slopes.is_empty() {
            break;
        }
        let slope = median(slopes);
        let intercept = median(
            active
                .iter()
                .map(|&i| -g_mgal * obs[i].dz_rad.cos() - slope * obs[i].ng)
                .collect(),
        );
        let r: Vec<f64> = active
            .iter()
            .map(|&i| -g_mgal * obs[i].dz_rad.cos() - intercept - slope * obs[i].ng)
            .collect();
        let mut abs: Vec<f64> = r.iter().map(|v| v.abs()).collect();
        abs.sort_by(f64::total_cmp);
        let sd = 1.4826 * abs[abs.len() / 2];
        let Some((k, worst)) = r
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        else {
            break;
        };
        if sd.is_nan() || sd <= 0.0 || worst.abs() <= GROSS_ERROR_SDS * sd {
            break;
        }
        removed.push(Removal {
            index: active[k],
            w: worst / sd,
            round: 0,
        });
        active.remove(k);
    }
    removed
}

/// Start values of the scaled parameters: b and k from an ordinary least-squares line of
/// `-g cos Dz` (mean `mean_y`) on `x` (so that the first linearisation sees the slope, and
/// a reading at Dz = 0 has a variance), the rest 0. The sums in row order, two passes over
/// the readings' counts and `-g cos Dz` ([`Centres::line`]).
fn start_values(line: &Line, model: &CalibrationConditions<'_>, mean_y: f64) -> Vec<f64> {
    let mut p = vec![0.0; model.terms.len()];
    let n = line.ng.len() as f64;
    let x = |ng: f64| (ng - model.centre) / model.scale;
    let mx = line.ng.iter().map(|ng| x(*ng)).sum::<f64>() / n;
    let (mut sxx, mut sxy) = (-0.0, -0.0);
    for (ng, y) in line.ng.iter().zip(&line.y) {
        let dx = x(*ng) - mx;
        sxx += dx.powi(2);
        sxy += dx * (y - mean_y);
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    // The condition is g cos Dz + c = 0: c(x) is the line of -g cos Dz on x.
    p[0] = mean_y - slope * mx;
    p[1] = slope;
    p
}

/// Fits `terms` to `obs` with gravity `g_mgal` (plus each observation's tide), removing blunders one at a time while a
/// w-test exceeds [`W_CRITICAL`] (at most a tenth of the observations).
pub fn calibrate(obs: &[Obs], terms: Terms, g_mgal: f64) -> Result<CalibrationSolution, CalError> {
    calibrate_with(obs, terms, g_mgal, &FitOptions::default())
}

/// What a fit does beyond the adjustment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Data snooping.
    pub snooping: Snooping,
    /// The accelerometer's coloured ADC noise, propagated into the parameters' covariance
    /// ([`crate::lsq::correlated`]); None: white.
    pub coloured: Option<ColouredAdc>,
    /// Estimate the variance components (and adjust again at them); off, one adjustment and
    /// no components (for benchmarks of the adjustment itself).
    pub components: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            snooping: Snooping::TenthAtMost,
            coloured: None,
            components: true,
        }
    }
}

/// [`calibrate`] with options.
pub fn calibrate_with(
    obs: &[Obs],
    terms: Terms,
    g_mgal: f64,
    options: &FitOptions,
) -> Result<CalibrationSolution, CalError> {
    let snooping = options.snooping;
    let m = terms.len();
    if obs.len() <= m {
        return Err(CalError::TooFew { n: obs.len(), m });
    }
    let spread = check_design(obs, terms)?;
    let t_ref_c = reference_temperature(&spread.t);
    let max_removals = match snooping {
        Snooping::TenthAtMost => obs.len() / 10,
        Snooping::Off => 0,
    };
    let mut active: Vec<usize> = (0..obs.len()).collect();
    let mut removed = match snooping {
        Snooping::TenthAtMost => screen_gross_errors(obs, &mut active, g_mgal, max_removals),
        Snooping::Off => Vec::new(),
    };
    // The observations with their stations' sigma_Dz as the removals leave them: a copy
    // only once one is removed.
    let mut obs_now = std::borrow::Cow::Borrowed(obs);
    for r in &removed {
        station_without(obs_now.to_mut(), r.index);
    }
    let names = terms.names();
    // What the design check read of every observation gives the first round's centres
    // when that round adjusts them all (no gross error screened out).
    let mut spread = removed.is_empty().then_some(spread);
    let mut round = 0;
    loop {
        round += 1;
        let used: Vec<&Obs> = active.par_iter().map(|&i| &obs_now[i]).collect();
        let centres = Centres::of(Columns::of_round(spread.take(), &used, g_mgal));
        let (tides, rolls) = tides_and_rolls(&used, terms, centres.tides);
        let model = CalibrationConditions {
            terms,
            g_mgal,
            centre: centres.centre,
            scale: centres.scale,
            t_ref_c,
            tide_mgal: &tides,
            roll_rad: &rolls,
        };
        let p0 = start_values(&centres.line, &model, centres.mean_y);
        drop(centres.line);
        let to_cal = |e| cal_error(e, &names, &active);
        let s = adjust_and_test(&model, &used, &p0, options).map_err(to_cal)?;
        if let Some((k, w)) = worst_w_test(&s)
            && w.abs() > W_CRITICAL
            && removed.len() < max_removals
            && s.dof > 1
        {
            removed.push(Removal {
                index: active[k],
                w,
                round,
            });
            station_without(obs_now.to_mut(), active[k]);
            active.remove(k);
            continue;
        }
        let fitted = Fitted {
            model: &model,
            used: &used,
            mean_temperature_c: centres.mean_temperature_c,
        };
        let (fit, s) = conclude(&fitted, s, options).map_err(to_cal)?;
        return Ok(CalibrationSolution {
            removed,
            residuals: Residuals::of(active, s),
            ..fit
        });
    }
}

/// One round's adjustment of `used` by `model` from `p0`, its w-tests referred to each
/// reading's left-out sigma_Dz (and the coloured noise's share, when declared).
fn adjust_and_test(
    model: &CalibrationConditions<'_>,
    used: &[&Obs],
    p0: &[f64],
    options: &FitOptions,
) -> Result<gh::Solution<3>, GhError> {
    let mut s = gh::solve(model, &Readings(used), p0, &Options::default())?;
    let coloured = options
        .coloured
        .as_ref()
        .map(|noise| misclosure_excess(&s, used, noise));
    let mut w_test = std::mem::take(&mut s.w_test);
    left_out_w_tests(&s, used, coloured.as_deref(), &mut w_test);
    s.w_test = w_test;
    Ok(s)
}

/// The reference temperature of b and k: the mean of all the observations' temperatures
/// `t` (to 0.01 degC), so that it does not move with what snooping removes.
fn reference_temperature(t: &[f64]) -> f64 {
    let all_t = t.iter().sum::<f64>() / t.len() as f64;
    (all_t * 100.0).round() / 100.0
}

/// The tides and rolls the conditions hold for `used` (`any_tide`: whether any reading has
/// one). Neither is held when it enters nothing (an empty slice): a million observations'
/// bench has no tide and no vector misalignment.
fn tides_and_rolls(used: &[&Obs], terms: Terms, any_tide: bool) -> (Vec<f64>, Vec<f64>) {
    let tides = if any_tide {
        used.iter().map(|o| o.tide_mgal).collect()
    } else {
        Vec::new()
    };
    let rolls = if terms.misalignment == Misalignment::Vector {
        used.iter().map(|o| o.roll_rad).collect()
    } else {
        Vec::new()
    };
    (tides, rolls)
}

/// The largest w-test of `s` in magnitude among the observations with redundancy (its
/// index and value).
fn worst_w_test<const K: usize>(s: &gh::Solution<K>) -> Option<(usize, f64)> {
    s.w_test
        .iter()
        .enumerate()
        .filter(|(i, _)| s.redundancy[*i] > 1e-6)
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map(|(k, w)| (k, *w))
}

/// The station of `obs[removed]` weighed without it: every reading of the station takes
/// the removed one's left-out sigma_Dz and dof (its station's sigma formed without it, and
/// without any reading gross enough to mask it; docs/model.md 6.1). A blunder inflates its
/// station's sigma, so that, once removed, it would still make the station's other
/// readings weigh little and its mean scatter less than its weight says: on esgt-2005's
/// day 1 with 0.6 % of the readings 25 arcsec off, the theodolite's component averaged
/// 0.83 over the replicas with a blunder, and the rms z of b and k was 1.16-1.18 (a probe
/// of the per-session study, not kept in the code). A sigma
/// taken as known (no left-out sigma) is kept.
fn station_without(obs: &mut [Obs], removed: usize) {
    let Some(left) = obs[removed].sigma_dz_left_out else {
        return;
    };
    let station = obs[removed].station;
    for o in obs.iter_mut().filter(|o| o.station == station) {
        o.sigma_dz_rad = left.sigma_rad;
        o.sigma_dz_dof = left.dof;
    }
}

/// The non-centrality a reading's bias must reach, in sds of its misclosure over sqrt(r),
/// to be found by the w-test with power 0.80: Baarda's 4.13 when the variances are known;
/// with the test on `dof` degrees of freedom (a Student t), the t's critical value c plus
/// 0.8416 sqrt(1 + c^2 / (2 dof)), the normal approximation to the non-central t's power
/// (Johnson and Welch 1940), which is larger: estimated weights detect less.
pub fn mdb_noncentrality(dof: Option<f64>) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    const ALPHA: f64 = 0.001;
    const POWER_Z: f64 = 0.841_621_233_572_914_3;
    match dof.filter(|d| d.is_finite() && *d > 0.0) {
        None => Normal::standard().inverse_cdf(1.0 - ALPHA / 2.0) + POWER_Z,
        Some(d) => {
            let c = components::t_quantile(1.0 - ALPHA / 2.0, d);
            c + POWER_Z * (1.0 + c * c / (2.0 * d)).sqrt()
        }
    }
}

/// What the model, the start values and the conclusion read of the readings: the counts'
/// mean and largest distance from it (at least 1), by which the model's internal
/// parameters are scaled, the mean of `-g cos Dz`, the mean temperature, whether any
/// reading has a tide, and the columns the start values' line is fitted to. The readings
/// are read once, on the pool, into contiguous columns; each sum is then taken over its
/// column in row order (its bits those of a sum of it alone), which is cheap where a
/// reading's record is not.
struct Centres {
    centre: f64,
    scale: f64,
    mean_y: f64,
    mean_temperature_c: f64,
    tides: bool,
    /// The counts and `-g cos Dz` of each reading, for [`start_values`].
    line: Line,
}

/// The counts and `-g cos Dz` of each reading.
struct Line {
    ng: Vec<f64>,
    y: Vec<f64>,
}

impl Centres {
    /// The centres of the readings whose counts, `-g cos Dz` and temperatures are
    /// `columns`, each sum over its column in row order.
    fn of(columns: Columns) -> Self {
        let Columns { ng, y, t, tides } = columns;
        let n = ng.len() as f64;
        let (lo, hi) = ng
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (f64::min(lo, *x), f64::max(hi, *x))
            });
        let centre = ng.iter().sum::<f64>() / n;
        // The largest |Ng - centre| is at the lowest or the highest Ng (a rounded
        // difference is monotone in Ng).
        let scale = (hi - centre).max(centre - lo).max(1.0);
        Centres {
            centre,
            scale,
            mean_y: y.iter().sum::<f64>() / n,
            mean_temperature_c: t.iter().sum::<f64>() / n,
            tides,
            line: Line { ng, y },
        }
    }
}

/// The readings' counts, `-g cos Dz` and temperatures, a column each, and whether any
/// reading has a tide: what [`Centres`] is summed from.
struct Columns {
    ng: Vec<f64>,
    y: Vec<f64>,
    t: Vec<f64>,
    tides: bool,
}

impl Columns {
    /// A round's: the design check's reading, where it read the round's very readings
    /// (`spread`), else read from `used`.
    fn of_round(spread: Option<Spread>, used: &[&Obs], g_mgal: f64) -> Self {
        match spread {
            Some(spread) => Columns::of_spread(spread, g_mgal),
            None => Columns::of(used, g_mgal),
        }
    }

    /// Read from `used` on the pool.
    fn of(used: &[&Obs], g_mgal: f64) -> Self {
        let column = || vec![0.0; used.len()];
        let (mut ng, mut y, mut t) = (column(), column(), column());
        let tides = ng
            .par_chunks_mut(gh::TASK_ROWS)
            .zip(y.par_chunks_mut(gh::TASK_ROWS))
            .zip(t.par_chunks_mut(gh::TASK_ROWS))
            .zip(used.par_chunks(gh::TASK_ROWS))
            .map(|(((ng, y), t), rows)| {
                let mut tides = false;
                for (((ng, y), t), o) in ng.iter_mut().zip(y).zip(t).zip(rows) {
                    (*ng, *y, *t) = (o.ng, -g_mgal * o.dz_rad.cos(), o.temperature_c);
                    tides |= o.tide_mgal != 0.0;
                }
                tides
            })
            .reduce(|| false, |a, b| a || b);
        Columns { ng, y, t, tides }
    }

    /// Taken over from the design check's reading of every observation (a fit's first
    /// round, when no gross error was screened out): `-g cos Dz` formed on the pool in the
    /// buffer of the sds of Dz, which the check is done with.
    fn of_spread(spread: Spread, g_mgal: f64) -> Self {
        let Spread {
            dz,
            ng,
            t,
            tides,
            sigma_dz: mut y,
            ..
        } = spread;
        y.par_iter_mut()
            .zip(&dz)
            .with_min_len(gh::TASK_ROWS)
            .for_each(|(y, dz)| *y = -g_mgal * dz.cos());
        Columns { ng, y, t, tides }
    }
}

/// What the coloured ADC noise adds to the variance of each of `used`'s misclosures
/// ([`correlated::misclosure_excess`]).
fn misclosure_excess(s: &gh::Solution<3>, used: &[&Obs], noise: &ColouredAdc) -> Vec<f64> {
    correlated::misclosure_excess(s, Groups::of(used).timeline(), noise)
}

/// Baarda's w of each condition with its reading's Dz referred to the left-out sigma_Dz
/// ([`Obs::sigma_dz_left_out`]; docs/model.md 6.1): the misclosure over
/// sqrt(r (q_Dz,left-out + q_Ng + q_T)), a Student t whose degrees of freedom are the left-out
/// variance's and the window mean's sd's, each carried by its share of the condition's
/// variance (Welch-Satterthwaite; the temperature's variance is taken as known), returned
/// as the standard normal quantile of the same tail probability, so that one critical value
/// ([`W_CRITICAL`]) holds alpha whatever the dof. With both sds known the t is the normal
/// and w is Baarda's own. The shares that weigh the dofs are the fitted variances', not
/// the left-out one's: the left-out variance is the t's denominator, and its shares taken
/// from it made the dof largest (the tail lightest) exactly when it came out small by
/// chance: on esgt-2005's design at the stations' own sds, 1.067 alpha beyond 3.29 before,
/// 0.972 with the fitted shares (`the_w_statistic_holds_its_tail`, docs/model.md 6.8).
/// `coloured`: what the coloured ADC noise adds to each misclosure's variance
/// ([`correlated::misclosure_excess`]), known as the window means' variance is. Written into
/// `w_test`, one per condition.
fn left_out_w_tests(
    s: &gh::Solution<3>,
    used: &[&Obs],
    coloured: Option<&[f64]>,
    w_test: &mut [f64],
) {
    use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
    let normal = Normal::standard();
    let each = |(i, o): (usize, &&Obs)| {
        let r = s.redundancy[i];
        if r <= 1e-9 {
            return 0.0;
        }
        let fitted = o.sigma_dz_rad.powi(2) * components::predictive_factor(o.sigma_dz_dof);
        let (sigma, dof) = o
            .sigma_dz_left_out
            .map_or((o.sigma_dz_rad, o.sigma_dz_dof), |l| (l.sigma_rad, l.dof));
        let q_dz = s.q_parts[i][0] * sigma.powi(2) / fitted;
        // The misclosure's variance is q r; the coloured noise's share, over r, joins
        // the known part (kept positive: an excess is a small correction).
        let extra = coloured.map_or(0.0, |c| c[i] / r);
        let q_known = s.q_parts[i][1] + s.q_parts[i][2];
        let q = q_dz + (q_known + extra).max(0.5 * q_known);
        let w = s.misclosure[i] / (q * r).sqrt();
        // Welch-Satterthwaite over the estimated shares: the left-out sigma_Dz's and the
        // window mean's sd (estimated from its own samples; a t's tail at 3.29 is far
        // from the normal's even on 79 dof).
        let share = |part: f64, dof: Option<f64>| {
            dof.filter(|d| d.is_finite() && *d > 0.0)
                .map(|d| part * part / d)
        };
        let q_dz_fitted = s.q_parts[i][0] * o.sigma_dz_rad.powi(2) / fitted;
        let parts = [
            share(q_dz_fitted, dof),
            share(s.q_parts[i][1], o.sigma_ng_dof),
        ];
        if parts.iter().all(Option::is_none) {
            return w;
        }
        let q_fitted = q - q_dz + q_dz_fitted;
        let nu = q_fitted * q_fitted / parts.iter().flatten().sum::<f64>();
        let tail = StudentsT::new(0.0, 1.0, nu).map_or(f64::NAN, |t| t.cdf(-w.abs()));
        if tail.is_finite() && tail > 0.0 {
            -normal.inverse_cdf(tail) * w.signum()
        } else {
            w
        }
    };
    // Into the solution's own vector, which the left-out tests replace: a second one was
    // a million observations' peak.
    w_test
        .par_iter_mut()
        .zip(used.par_iter().enumerate())
        .with_min_len(4096)
        .for_each(|(w, x)| *w = each(x));
}

/// Observations and their sds as the adjustment takes them: Dz weighed by its predictive
/// variance, then Ng, then the temperature with its sd from the thermometer's noise; formed
/// from the readings on each call, not copied.
struct Readings<'a>(&'a [&'a Obs]);

impl gh::Observations<3> for Readings<'_> {
    fn count(&self) -> usize {
        self.0.len()
    }

    #[inline]
    fn get(&self, i: usize) -> ([f64; 3], [f64; 3]) {
        let o = self.0[i];
        let factor = components::predictive_factor(o.sigma_dz_dof);
        (
            [o.dz_rad, o.ng, o.temperature_c],
            [
                o.sigma_dz_rad * factor.sqrt(),
                o.sigma_ng,
                o.sigma_temperature_c,
            ],
        )
    }
}

/// [`Readings`] held, for the components' re-adjustments at scaled sds.
fn observations(used: &[&Obs]) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let readings = Readings(used);
    (0..used.len())
        .map(|i| gh::Observations::get(&readings, i))
        .unzip()
}

/// The final round of a fit: its model, the readings it used and their mean temperature.
struct Fitted<'a> {
    model: &'a CalibrationConditions<'a>,
    used: &'a [&'a Obs],
    mean_temperature_c: f64,
}

/// The fit from the final round's adjustment `s` of `fitted`: the variance components and
/// the adjustment at them, the coloured noise's covariance, the global test; no removals
/// and no residuals. With it, what of `s` the residuals are formed from (its designs and
/// its variances' parts gone: at a million observations they and the residuals were the
/// fit's peak).
fn conclude(
    fitted: &Fitted<'_>,
    mut s: gh::Solution<3>,
    options: &FitOptions,
) -> Result<(CalibrationSolution, gh::Solution<3>), GhError> {
    let Fitted {
        model,
        used,
        mean_temperature_c,
    } = *fitted;
    let m = model.terms.len();
    let map = model.to_counts();
    let groups = Groups::of(used);
    // Without components the fit's own weights stand: `s` itself, not a copy of its
    // per-observation vectors.
    let (estimated, components) = if options.components {
        let (l, sigma) = observations(used);
        let (w, c) =
            estimate_components(model, &l, &sigma, &s, &groups, options.coloured.as_ref())?;
        (Some(w), c)
    } else {
        (None, Vec::new())
    };
    let weighted = estimated.as_ref().unwrap_or(&s);
    let mut q = weighted.q_pp.clone();
    if let Some(noise) = &options.coloured {
        let extra = correlated::extra_covariance(weighted, groups.timeline(), noise);
        for (x, e) in q.iter_mut().zip(extra) {
            *x += e;
        }
    }
    let excess = groups.excess(&s, options.coloured.as_ref(), false);
    let (covariance, parameter_dof) = t_scaled(propagate(&map, &q, m), weighted, &components, &map);
    let thermal_gain = if model.terms.temperature {
        Vec::new()
    } else {
        thermal_gain(weighted, used, &map, mean_temperature_c)
    };
    let values = apply(&map, &weighted.p);
    // What is left needs neither design: gone before the global test's stations and the
    // residuals are formed (at a million observations a design and B are 40 MB).
    drop(estimated);
    s.a = Vec::new();
    s.b = Vec::new();
    let global_test = components::lack_of_fit(&s, groups.station(), groups.dof(), excess);
    drop(groups);
    let fit = CalibrationSolution {
        values,
        covariance,
        parameter_dof,
        covariance_apriori: propagate(&map, &s.q_pp, m),
        sigma0: s.sigma0(),
        vtpv: s.vtpv,
        dof: s.dof,
        iterations: s.iterations,
        t_ref_c: model.t_ref_c,
        mean_temperature_c,
        global_test,
        components,
        removed: Vec::new(),
        residuals: Residuals::default(),
        thermal_gain,
    };
    s.q_parts = Vec::new();
    s.q_ww = Vec::new();
    Ok((fit, s))
}

/// What a thermal effect `(b_t + k_t Ng_i) (T_i - mean_t)` the model does not include moves
/// the parameters (in counts) by, per unit of b_t and of k_t: the effect adds to each
/// observation's calibration value, so to its condition's misclosure, whose gain on the
/// parameters is `Q_pp a_i / q_i` at the weights of `s`. Summed a task of
/// [`gh::TASK_ROWS`] readings at a time on the pool, the tasks' sums then added in their
/// order: the same bits on any number of cores.
fn thermal_gain(s: &gh::Solution<3>, used: &[&Obs], map: &[f64], mean_t: f64) -> Vec<[f64; 2]> {
    let m = s.p.len();
    let tasks: Vec<Vec<[f64; 2]>> = used
        .par_chunks(gh::TASK_ROWS)
        .enumerate()
        .map(|(task, rows)| {
            let mut sum = vec![[0.0; 2]; m];
            for (k, o) in rows.iter().enumerate() {
                let i = task * gh::TASK_ROWS + k;
                let dt = o.temperature_c - mean_t;
                if dt == 0.0 || s.q_ww[i] <= 0.0 {
                    continue;
                }
                let effect = [dt, o.ng * dt];
                let a = &s.a[i * m..(i + 1) * m];
                for (r, g) in sum.iter_mut().enumerate() {
                    // (Q_pp a_i)_r, as [`correlated::q_pp_a`] forms it.
                    let qa: f64 = (0..m).map(|c| s.q_pp[r * m + c] * a[c]).sum();
                    for c in 0..2 {
                        g[c] += qa / s.q_ww[i] * effect[c];
                    }
                }
            }
            sum
        })
        .collect();
    let mut scaled = vec![[0.0; 2]; m];
    for task in tasks {
        for (g, t) in scaled.iter_mut().zip(task) {
            g[0] += t[0];
            g[1] += t[1];
        }
    }
    (0..m)
        .map(|r| [0, 1].map(|c| (0..m).map(|j| map[r * m + j] * scaled[j][c]).sum()))
        .collect()
}

/// The covariance at estimated components scaled to its parameters' t (docs/model.md 6.1):
/// each parameter's variance times nu / (nu - 2) on its own dof
/// ([`components::parameter_dof`]; GUM Supplement 1, 6.4.9.4, the variance of a t, as for a
/// reading's predictive variance, [`components::predictive_factor`]), the correlations
/// kept; with its dofs.
fn t_scaled(
    mut covariance: Vec<f64>,
    s: &gh::Solution<3>,
    components: &[Component],
    map: &[f64],
) -> (Vec<f64>, Vec<Option<f64>>) {
    let m = s.p.len();
    let dof = components::parameter_dof(s, components, map, &covariance);
    let f: Vec<f64> = dof
        .iter()
        .map(|&d| components::predictive_factor(d).sqrt())
        .collect();
    for (i, row) in covariance.chunks_exact_mut(m).enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x *= f[i] * f[j];
        }
    }
    (covariance, dof)
}

/// An adjustment's failure as a fit's, naming the parameter or observation.
fn cal_error(
    e: GhError,
    names: &[crate::calibration::model::ParamName],
    active: &[usize],
) -> CalError {
    match e {
        GhError::NotEstimable { index } => CalError::NotEstimable {
            parameter: names[index].name,
            why: "its column of the design depends on the others (e.g. beta with tilts on \
                  one side of the vertical only)"
                .to_owned(),
        },
        GhError::TooFewObservations { n, m } => CalError::TooFew { n, m },
        GhError::ZeroVariance { index } => CalError::ZeroVariance {
            index: active[index],
        },
        other => CalError::Adjustment(other),
    }
}

/// The observations of a fit by station, with what the components and the coloured noise
/// need of them, formed when first asked for: a fit without either (a million observations'
/// bench) holds only the stations and the sigma_Dz dofs, 24 bytes an observation, not 72.
struct Groups<'a> {
    used: &'a [&'a Obs],
    /// Station per observation, compacted to 0..stations, and the dof of each sigma_Dz:
    /// read in one pass.
    station_and_dof: std::cell::OnceCell<(Vec<usize>, Vec<Option<f64>>)>,
    windows: std::cell::OnceCell<Windows>,
    times: std::cell::OnceCell<(Vec<f64>, Vec<usize>)>,
}

/// The window means, their a-priori sds and the sds' dof, per observation.
struct Windows {
    ng: Vec<f64>,
    sigma_ng: Vec<f64>,
    sigma_ng_dof: Vec<Option<f64>>,
}

impl<'a> Groups<'a> {
    /// When each observation was read, for the coloured noise.
    fn timeline(&self) -> Timeline<'_> {
        let (time_s, session) = self.times.get_or_init(|| {
            let time_s = self.used.iter().map(|o| o.time_s).collect();
            let session = self.used.iter().map(|o| o.session).collect();
            (time_s, session)
        });
        Timeline { time_s, session }
    }

    /// The window means and their sds.
    fn windows(&self) -> &Windows {
        self.windows.get_or_init(|| Windows {
            ng: self.used.iter().map(|o| o.ng).collect(),
            sigma_ng: self.used.iter().map(|o| o.sigma_ng).collect(),
            sigma_ng_dof: self.used.iter().map(|o| o.sigma_ng_dof).collect(),
        })
    }

    fn of(used: &'a [&'a Obs]) -> Self {
        Self {
            used,
            station_and_dof: std::cell::OnceCell::new(),
            windows: std::cell::OnceCell::new(),
            times: std::cell::OnceCell::new(),
        }
    }

    /// Station per observation, compacted to 0..stations.
    fn station(&self) -> &[usize] {
        &self.station_and_dof().0
    }

    /// Dof of each sigma_Dz.
    fn dof(&self) -> &[Option<f64>] {
        &self.station_and_dof().1
    }

    /// Both, read in one pass over the readings.
    fn station_and_dof(&self) -> &(Vec<usize>, Vec<Option<f64>>) {
        self.station_and_dof.get_or_init(|| {
            let (mut station, mut dof) = (Vec::new(), Vec::new());
            self.used
                .par_iter()
                .map(|o| (o.station, o.sigma_dz_dof))
                .unzip_into_vecs(&mut station, &mut dof);
            compact(&mut station);
            (station, dof)
        })
    }

    /// The expected part of solution `s`'s between-station form due to coloured ADC noise
    /// (0 when white): weighted by the theodolite's shares for its component, or whole for
    /// the global test.
    fn excess(&self, s: &gh::Solution<3>, noise: Option<&ColouredAdc>, shared: bool) -> f64 {
        noise.map_or(0.0, |noise| {
            let share = if shared {
                components::shares(s, self.station())
            } else {
                vec![1.0; self.station().iter().max().map_or(0, |m| m + 1)]
            };
            correlated::between_station_excess(s, self.station(), &share, self.timeline(), noise)
        })
    }
}

/// Most re-adjustments of the theodolite component's iteration.
const MAX_COMPONENT_ITERATIONS: usize = 50;

/// Station ids renumbered 0..stations in order of their values: readings in station order
/// (as align writes them) in one pass, others through the sorted distinct ids.
fn compact(station: &mut [usize]) {
    if station.windows(2).all(|w| w[0] <= w[1]) {
        let mut previous = station.first().copied();
        let mut count = 0;
        for id in station.iter_mut() {
            if Some(*id) != previous {
                previous = Some(*id);
                count += 1;
            }
            *id = count;
        }
        return;
    }
    let mut ids = station.to_vec();
    ids.sort_unstable();
    ids.dedup();
    for id in station.iter_mut() {
        *id = ids.binary_search(id).unwrap_or(0);
    }
}

/// The variance components ([`components`]) and the adjustment at them, from the a-priori
/// solution `s` of observations `l` with sds `sigma`: the ADC's from the repeated window
/// means, then the theodolite's iterated on the station means with the ADC's applied, less
/// what `coloured` ADC noise explains of them.
fn estimate_components(
    model: &CalibrationConditions<'_>,
    l: &[[f64; 3]],
    sigma: &[[f64; 3]],
    s: &gh::Solution<3>,
    groups: &Groups<'_>,
    coloured: Option<&ColouredAdc>,
) -> Result<(gh::Solution<3>, Vec<Component>), GhError> {
    let within = coloured.map_or(correlated::Excess::default(), |noise| {
        correlated::within_station_excess(
            groups.station(),
            &groups.windows().sigma_ng,
            groups.timeline(),
            noise,
        )
    });
    let adc = components::adc_component(
        &groups.windows().ng,
        &groups.windows().sigma_ng,
        &groups.windows().sigma_ng_dof,
        groups.station(),
        within,
    );
    let at_one = components::theodolite_step(
        s,
        groups.station(),
        groups.dof(),
        groups.excess(s, coloured, true),
    );
    let refit = |theta: f64, from: &gh::Solution<3>| {
        let scaled: Vec<[f64; 3]> = sigma
            .iter()
            .map(|x| [x[0] * theta.sqrt(), x[1] * adc.estimate.sqrt(), x[2]])
            .collect();
        gh::solve(
            model,
            &gh::Held::new(l, &scaled),
            &from.p,
            &Options::default(),
        )
    };
    let mut theta = 1.0;
    let mut sol = refit(theta, s)?;
    let mut step = components::theodolite_step(&sol, groups.station(), groups.dof(), 0.0);
    // Whether the component is estimated is decided here, at its a-priori weight: its
    // degrees of freedom grow with its estimate, and deciding at the converged one kept the
    // high estimates and held the low ones at 1 (a 0.1 K thermometer's share left about 3
    // dof, and the kept estimates averaged 1.7). The dof are the estimate's own
    // ([`components::theodolite_dof`]), not the form's.
    let apriori_dof = components::theodolite_dof(&sol, groups.station(), groups.dof());
    if apriori_dof >= components::MIN_COMPONENT_DOF {
        for _ in 0..MAX_COMPONENT_ITERATIONS {
            // The theodolite's part of the form is what the coloured noise does not explain.
            let excess = groups.excess(&sol, coloured, true);
            let next = (theta * (step.statistic - excess) / step.mean).clamp(1e-6, 1e6);
            let settled = (next / theta - 1.0).abs() < 1e-5;
            theta = next;
            sol = refit(theta, &sol)?;
            step = components::theodolite_step(&sol, groups.station(), groups.dof(), 0.0);
            if settled {
                break;
            }
        }
    }
    let dof = components::theodolite_dof(&sol, groups.station(), groups.dof());
    let theodolite = components::theodolite_component(theta, (apriori_dof, dof), at_one);
    Ok((sol, vec![theodolite, adc]))
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: f64 = 980_000.0;

    /// Observations at the given Dz (deg), with counts from a = b + k Ng, or `counts` when
    /// given, a small deterministic noise, and temperature `t`.
    fn design(dz_deg: &[f64], counts: Option<f64>, t: f64) -> Vec<Obs> {
        let (b, k) = (-29_500.0, 0.243);
        dz_deg
            .iter()
            .enumerate()
            .map(|(i, &dz)| {
                let dz_rad = dz.to_radians();
                let noise = ((i * 7919) % 13) as f64 / 13.0 - 0.5;
                Obs {
                    dz_rad,
                    sigma_dz_rad: 2e-6,
                    sigma_dz_dof: None,
                    sigma_dz_left_out: None,
                    station: i,
                    session: 0,
                    time_s: 10.0 * i as f64,
                    roll_rad: 0.0,
                    ng: counts.unwrap_or((-G * dz_rad.cos() - b) / k) + noise,
                    sigma_ng: 0.3,
                    sigma_ng_dof: None,
                    temperature_c: t + 0.001 * i as f64,
                    sigma_temperature_c: 0.0,
                    tide_mgal: 0.0,
                }
            })
            .collect()
    }

    /// The bins a pass per bin opens are those a pass over the sorted Dz opens, on spreads
    /// of Dz in any order: clustered positions, an even spread, and values on a bin's edge.
    #[test]
    fn tilt_levels_are_the_sorted_passes_bins() {
        let sorted_pass = |obs: &[Obs], separation: f64| {
            let mut dz: Vec<f64> = obs.iter().map(|o| o.dz_rad).collect();
            dz.sort_unstable_by(f64::total_cmp);
            let (mut levels, mut start) = (0usize, f64::NEG_INFINITY);
            for d in dz {
                if levels == 0 || d - start > separation {
                    levels += 1;
                    start = d;
                }
            }
            levels
        };
        let clustered: Vec<f64> = (0..60)
            .map(|i| [120.0, 0.0, 240.0][i % 3] + 1e-5 * i as f64)
            .collect();
        let spread: Vec<f64> = (0..97u32).map(|i| f64::from((i * 37) % 97) * 0.5).collect();
        let edges: Vec<f64> = (0..20u32).map(|i| f64::from((i * 7) % 20)).collect();
        for (dz, separation) in [
            (clustered, 1e-3),
            (spread, 1.2_f64.to_radians()),
            (edges, 1.0_f64.to_radians()),
        ] {
            let obs = design(&dz, None, 20.0);
            let all = sorted_pass(&obs, separation);
            assert!(all > 2, "{all}");
            for most in 1..=all + 2 {
                assert_eq!(
                    {
                        let spread = Spread::of(&obs);
                        tilt_levels(&spread.dz, spread.lowest_dz, separation, most)
                    },
                    all.min(most),
                    "{most} of {all}"
                );
            }
        }
    }

    fn terms(order: usize, temperature: bool) -> Terms {
        Terms {
            order,
            temperature,
            misalignment: Misalignment::None,
        }
    }

    fn tilts(n: usize) -> Vec<f64> {
        (0..n).map(|i| 110.0 + (i % 8) as f64 * 4.0).collect()
    }

    /// The thermal gain is what an effect the model does not include moves its parameters
    /// by: the same readings with and without a temperature effect about their mean
    /// temperature, fitted without temperature terms, differ by the gain times (b_t, k_t) to
    /// the adjustment's linearisation; with temperature terms there is no gain. At 40
    /// readings and at 40 000 (several of the adjustment's tasks, its QR in two halves).
    #[test]
    fn the_thermal_gain_is_what_an_unmodelled_effect_moves() {
        for n in [40, 40_000] {
            thermal_gain_of(n);
        }
    }

    fn thermal_gain_of(n: usize) {
        // Nine tilt positions, a period that no task's start repeats.
        let dz: Vec<f64> = (0..n).map(|i| 110.0 + (i % 9) as f64 * 3.5).collect();
        let plain = design(&dz, None, 25.0);
        let (b, k) = (-29_500.0, 0.243);
        let sensitivity = Sensitivity {
            b_t: 40.0,
            k_t: 2e-4,
        };
        // Warmer at the higher tilts, with a ripple: a pattern that moves the parameters
        // at any number of readings.
        let temperature = |i: usize| {
            let (position, i) = ((i % 9) as f64, i as f64);
            25.0 + 0.01 * position + 0.005 * (0.7 * i).sin()
        };
        let mean_t = (0..n).map(temperature).sum::<f64>() / n as f64;
        let warm: Vec<Obs> = plain
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let dt = temperature(i) - mean_t;
                let noise = o.ng - (-G * o.dz_rad.cos() - b) / k;
                Obs {
                    ng: (-G * o.dz_rad.cos() - b - sensitivity.b_t * dt)
                        / (k + sensitivity.k_t * dt)
                        + noise,
                    temperature_c: temperature(i),
                    ..o.clone()
                }
            })
            .collect();
        let options = FitOptions {
            snooping: Snooping::Off,
            coloured: None,
            components: false,
        };
        let linear = terms(1, false);
        let before = calibrate_with(&plain, linear, G, &options).expect("fits");
        let after = calibrate_with(&warm, linear, G, &options).expect("fits");
        assert!((after.mean_temperature_c - mean_t).abs() < 1e-12);
        let extra = after.thermal_covariance(sensitivity);
        for j in 0..2 {
            let moved = after.values[j] - before.values[j];
            let predicted = extra[j * 2 + j].sqrt() * moved.signum();
            let gain = after.thermal_gain[j][0] * sensitivity.b_t
                + after.thermal_gain[j][1] * sensitivity.k_t;
            assert!(
                moved.abs() > 3.0 * after.sigma(j),
                "parameter {j}: moved {moved}, sigma {}",
                after.sigma(j)
            );
            assert!(
                (moved - gain).abs() < 1e-3 * moved.abs(),
                "parameter {j}: moved {moved}, gain {gain}"
            );
            assert!((predicted - gain).abs() < 1e-9 * gain.abs());
        }
        let two_sets: Vec<Obs> = warm
            .iter()
            .enumerate()
            .map(|(i, o)| Obs {
                temperature_c: o.temperature_c + 2.0 * (i % 2) as f64,
                ..o.clone()
            })
            .collect();
        let thermal = calibrate_with(&two_sets, terms(1, true), G, &options).expect("fits");
        assert!(thermal.thermal_gain.is_empty());
        assert!(
            thermal
                .thermal_covariance(sensitivity)
                .iter()
                .all(|&c| c == 0.0)
        );
    }

    #[test]
    fn a_good_design_passes_the_check_and_fits() {
        let obs = design(&tilts(40), None, 25.0);
        design_check(&obs, terms(1, false)).expect("estimable");
        let s = calibrate(&obs, terms(1, false), G).expect("fits");
        assert!((s.values[1] - 0.243).abs() < 1e-4, "k {}", s.values[1]);
    }

    /// Regression: counts that do not change with the tilt (a dead channel) gave k near 0
    /// with a small sigma.
    #[test]
    fn counts_without_spread_name_k() {
        let obs = design(&tilts(40), Some(1_500_000.0), 25.0);
        match calibrate(&obs, terms(1, false), G) {
            Err(CalError::NotEstimable { parameter, why }) => {
                assert_eq!(parameter, "k");
                assert!(why.contains("do not vary with the tilt"), "{why}");
            }
            other => panic!("{other:?}"),
        }
    }

    /// A continuous spread of Dz (a motorised table read at every angle, as `cargo xtask
    /// bench adjust` builds it) is many positions, not one chained together; the same
    /// number of readings at one Dz is still one.
    #[test]
    fn a_continuous_design_is_many_positions() {
        let spread: Vec<f64> = (0..100_000)
            .map(|i| 109.0 + 31.0 * f64::from(i) / 99_999.0)
            .collect();
        let obs = design(&spread, None, 25.0);
        design_check(&obs, terms(3, false)).expect("a cubic from a continuous spread");
        let one: Vec<f64> = (0..2000).map(|i| 120.0 + 1e-7 * f64::from(i % 3)).collect();
        match design_check(&design(&one, None, 25.0), terms(1, false)) {
            Err(CalError::NotEstimable { parameter, why }) => {
                assert_eq!(parameter, "k");
                assert!(why.contains("1 tilt position(s)"), "{why}");
            }
            other => panic!("one position gave {other:?}"),
        }
    }

    /// Two tilt positions determine a line but not a parabola: k2 is named.
    #[test]
    fn an_order_beyond_the_positions_is_named() {
        let dz: Vec<f64> = (0..40)
            .map(|i| if i % 2 == 0 { 110.0 } else { 130.0 })
            .collect();
        let obs = design(&dz, None, 25.0);
        design_check(&obs, terms(1, false)).expect("a line from two positions");
        match design_check(&obs, terms(2, false)) {
            Err(CalError::NotEstimable { parameter, why }) => {
                assert_eq!(parameter, "k2");
                assert!(why.contains("2 tilt position(s)"), "{why}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn one_temperature_set_names_b_t() {
        let obs = design(&tilts(40), None, 25.0);
        match design_check(&obs, terms(1, true)) {
            Err(CalError::NotEstimable { parameter, why }) => {
                assert_eq!(parameter, "b_t");
                assert!(why.contains("one temperature set"), "{why}");
            }
            other => panic!("{other:?}"),
        }
        let mut two = design(&tilts(40), None, 25.0);
        two.extend(design(&tilts(40), None, 31.0));
        design_check(&two, terms(1, true)).expect("two temperature sets");
    }

    /// A gross error is screened out before the adjustment and listed as round 0; the
    /// fit recovers k.
    #[test]
    fn a_gross_error_is_screened_out() {
        let mut obs = design(&tilts(40), None, 25.0);
        obs[9].dz_rad = 0.0;
        let s = calibrate(&obs, terms(1, false), G).expect("fits");
        assert_eq!(s.removed.first().map(|r| (r.index, r.round)), Some((9, 0)));
        assert!((s.values[1] - 0.243).abs() < 1e-4, "k {}", s.values[1]);
    }
}
