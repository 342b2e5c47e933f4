//! What a fit can say about its own weights when the theodolite's were estimated from the
//! very readings they weigh (docs/model.md section 6.1). No I/O.
//!
//! The scatter of a station's readings about their mean has already been spent on that
//! station's sigma_Dz; what is left to judge the weights is the scatter *between* stations:
//! each station's weighted mean misclosure against the fitted function. Under the model, a
//! station mean over its predictive sd is a Student t on the dof of its variance, so the
//! between-station part of v^T P v is a sum of t^2 terms, not a chi-square; its reference is
//! the scaled chi-square with the same mean and variance (Satterthwaite). With known sigmas
//! and one observation a station this is the classical chi-square(r) test of v^T P v.
//!
//! Variance components, one per group, each estimated where its redundancy lies:
//! - theodolite: from the station means (Foerstner's iterated estimate, each station's
//!   between-station share split by the groups' shares of its variance);
//! - ADC: from the scatter of a station's window means about their mean, against the sd of
//!   a window mean that the window's own samples (or the Allan deviation) gave. The station
//!   means cannot tell it: the ADC is a few per cent of their variance.

use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Below this many degrees of freedom a variance component is not estimated (held at 1).
pub const MIN_COMPONENT_DOF: f64 = 3.0;
/// The dof of an estimated variance is taken as at least this (a t on 4 or fewer dof has
/// no variance of its square).
const MIN_VARIANCE_DOF: f64 = 5.0;
/// The two groups, in the order of an observation pair.
pub const GROUPS: [&str; 2] = ["theodolite", "ADC"];

/// Factor from an estimated variance on `dof` degrees of freedom to the predictive variance
/// of a new reading, E[sigma^2 | data] = s^2 d / (d - 2); 1 for a known variance.
pub fn predictive_factor(dof: Option<f64>) -> f64 {
    match dof {
        Some(d) if d.is_finite() => {
            let d = d.max(MIN_VARIANCE_DOF);
            d / (d - 2.0)
        }
        _ => 1.0,
    }
}

/// Above this many dof a t's quantile is taken from its expansion about the normal's.
const T_EXPANSION_DOF: f64 = 1000.0;

/// The `p` quantile of Student's t on `dof` degrees of freedom. statrs's inverse
/// (bisection on its cdf) drifts at large dof and does not return at all near 1e9 (1.83
/// for the 0.975 quantile at 1e7 dof, where the normal's is 1.96); beyond
/// [`T_EXPANSION_DOF`] the Cornish-Fisher expansion in 1/dof (Abramowitz and Stegun
/// 26.7.5, four terms) is used, exact there to about 1e-15.
pub fn t_quantile(p: f64, dof: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
    let z = Normal::standard().inverse_cdf(p);
    if dof.is_nan() || dof <= 0.0 {
        return f64::NAN;
    }
    if dof > T_EXPANSION_DOF {
        let (z2, n) = (z * z, dof);
        let g1 = (z2 + 1.0) * z / 4.0;
        let g2 = ((5.0 * z2 + 16.0) * z2 + 3.0) * z / 96.0;
        let g3 = (((3.0 * z2 + 19.0) * z2 + 17.0) * z2 - 15.0) * z / 384.0;
        let g4 = ((((79.0 * z2 + 776.0) * z2 + 1482.0) * z2 - 1920.0) * z2 - 945.0) * z / 92160.0;
        return z + g1 / n + g2 / (n * n) + g3 / n.powi(3) + g4 / n.powi(4);
    }
    StudentsT::new(0.0, 1.0, dof).map_or(f64::NAN, |t| t.inverse_cdf(p))
}

/// The half-width of a parameter's 95 % interval, in its sigmas, when its sigma is the sd
/// of its t on `dof` ([`predictive_factor`], the dof floored alike): t(0.975, d) sqrt((d -
/// 2) / d), 1.97 at 37 dof, 1.99 at 12; 1.96 for a known variance.
pub fn interval_95_sigmas(dof: Option<f64>) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    match dof {
        Some(d) if d.is_finite() => {
            let d = d.max(MIN_VARIANCE_DOF);
            t_quantile(0.975, d) * ((d - 2.0) / d).sqrt()
        }
        _ => Normal::standard().inverse_cdf(0.975),
    }
}

/// Variance of t_d^2 (d - 2)/d, the square of a station mean over its predictive sd: 2 for
/// a known variance.
fn t2_variance(dof: Option<f64>) -> f64 {
    match dof {
        Some(d) if d.is_finite() => {
            let d = d.max(MIN_VARIANCE_DOF);
            2.0 * (d - 1.0) / (d - 4.0)
        }
        _ => 2.0,
    }
}

/// Relative variance of sigma^2 / s^2 for a variance s^2 estimated on `dof` degrees of
/// freedom, 2 / (d - 4); 0 for a known variance.
fn relative_variance(dof: Option<f64>) -> f64 {
    match dof {
        Some(d) if d.is_finite() => 2.0 / (d.max(MIN_VARIANCE_DOF) - 4.0),
        _ => 0.0,
    }
}

/// A station's window means, for the ADC component: their weights' sums, count, and the
/// sums of their sds' predictive factors and relative variances.
#[derive(Clone, Debug, Default)]
struct WindowGroup {
    sum_w: f64,
    sum_wx: f64,
    m: usize,
    sum_f: f64,
    sum_c: f64,
}

/// A quadratic form tested against the scaled chi-square of its mean and variance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScaledChi2 {
    /// The form's value.
    pub statistic: f64,
    /// Its expectation under the model.
    pub mean: f64,
    /// Effective degrees of freedom of the reference, 2 mean^2 / variance.
    pub dof: f64,
    /// 2.5 % quantile of the reference.
    pub lower: f64,
    /// 97.5 % quantile.
    pub upper: f64,
}

impl ScaledChi2 {
    /// The reference moved by `excess`, an expected contribution of noise the weights do
    /// not carry (coloured ADC noise): its mean grows by it, its sd in proportion.
    fn with_excess(statistic: f64, mean: f64, variance: f64, excess: f64) -> Self {
        let grown = mean + excess.max(0.0);
        let variance = if mean > 0.0 {
            variance * (grown / mean).powi(2)
        } else {
            variance
        };
        Self::new(statistic, grown, variance)
    }

    fn new(statistic: f64, mean: f64, variance: f64) -> Self {
        let (scale, dof) = (variance / (2.0 * mean), 2.0 * mean * mean / variance);
        let (lower, upper) = match ChiSquared::new(dof) {
            Ok(d) if mean > 0.0 => (scale * d.inverse_cdf(0.025), scale * d.inverse_cdf(0.975)),
            _ => (0.0, 0.0),
        };
        Self {
            statistic,
            mean,
            dof,
            lower,
            upper,
        }
    }
    /// Within the bounds.
    pub fn passed(&self) -> bool {
        self.statistic >= self.lower && self.statistic <= self.upper
    }
}

/// Per station of a fit: its between-station quadratic form, redundancy, theodolite share
/// and the t^2 variance of its dof.
#[derive(Clone, Debug, Default)]
struct Station {
    sum_we: f64,
    sum_w: f64,
    redundancy: f64,
    share: f64,
    n: f64,
    t2_variance: f64,
}

/// Station-level sums of a solution, by station index (a station without observations is
/// all zeros): `station[i]` groups observation i, `dof[i]` is the dof of its sigma_Dz
/// (None: known).
fn stations(
    s: &crate::lsq::gh::Solution<3>,
    station: &[usize],
    dof: &[Option<f64>],
) -> Vec<Station> {
    let count = station.iter().max().map_or(0, |m| m + 1);
    let mut out = vec![Station::default(); count];
    for (i, &j) in station.iter().enumerate() {
        out[j].add(s, i, dof[i]);
    }
    for st in out.iter_mut().filter(|st| st.n > 0.0) {
        st.close();
    }
    out
}

/// Each station's sums, in the order of their indices: formed one at a time when the
/// observations come station by station (as readings do), so that a million stations of
/// one observation each hold no vector of them; otherwise [`stations`]' vector, whose
/// stations without observations are all zeros.
fn each_station(
    s: &crate::lsq::gh::Solution<3>,
    station: &[usize],
    dof: &[Option<f64>],
    visit: impl FnMut(&Station),
) {
    if !station.windows(2).all(|w| w[0] <= w[1]) {
        return stations(s, station, dof).iter().for_each(visit);
    }
    each_station_of(s, station, dof, 0..station.len(), visit);
}

/// [`each_station`] over the observations `rows`, which come station by station and begin
/// at a station's first observation: its stations in order, without the empty ones before
/// the first.
fn each_station_of(
    s: &crate::lsq::gh::Solution<3>,
    station: &[usize],
    dof: &[Option<f64>],
    rows: std::ops::Range<usize>,
    mut visit: impl FnMut(&Station),
) {
    let mut current: Option<(usize, Station)> = None;
    for (i, &j) in station.iter().enumerate().take(rows.end).skip(rows.start) {
        match &mut current {
            Some((k, st)) if *k == j => st.add(s, i, dof[i]),
            _ => {
                if let Some((k, mut st)) = current.take() {
                    st.close();
                    visit(&st);
                    // A station index skipped over has no observations.
                    (k + 1..j).for_each(|_| visit(&Station::default()));
                }
                let mut st = Station::default();
                st.add(s, i, dof[i]);
                current = Some((j, st));
            }
        }
    }
    if let Some((_, mut st)) = current {
        st.close();
        visit(&st);
    }
}

impl Station {
    /// Adds observation `i` of `s`, its sigma_Dz on `dof`.
    #[inline]
    fn add(&mut self, s: &crate::lsq::gh::Solution<3>, i: usize, dof: Option<f64>) {
        let w = 1.0 / s.q_ww[i];
        self.sum_we += w * s.misclosure[i];
        self.sum_w += w;
        self.redundancy += s.redundancy[i] - 1.0;
        self.share += s.q_parts[i][0] / s.q_ww[i];
        self.n += 1.0;
        self.t2_variance = self.t2_variance.max(t2_variance(dof));
    }

    /// After the last of its observations.
    fn close(&mut self) {
        // n_j - 1 of the station's redundancy lies within it.
        self.redundancy = (self.redundancy + 1.0).max(0.0);
        self.share /= self.n;
    }

    fn between(&self) -> f64 {
        if self.sum_w > 0.0 {
            self.sum_we * self.sum_we / self.sum_w
        } else {
            0.0
        }
    }
}

/// The theodolite's share of each station's variance, by station index.
pub fn shares(s: &crate::lsq::gh::Solution<3>, station: &[usize]) -> Vec<f64> {
    stations(s, station, &vec![None; station.len()])
        .iter()
        .map(|x| x.share)
        .collect()
}

/// The global test of a solution: the between-station part of v^T P v against its scaled
/// chi-square; `excess` is its expected part from noise the weights do not carry.
pub fn lack_of_fit(
    s: &crate::lsq::gh::Solution<3>,
    station: &[usize],
    dof: &[Option<f64>],
    excess: f64,
) -> ScaledChi2 {
    use rayon::prelude::{ParallelIterator, ParallelSlice};
    if !station.par_windows(2).all(|w| w[0] <= w[1]) {
        let mut sums = BetweenSums::default();
        each_station(s, station, dof, |x| sums.add(x, 1.0));
        return sums.test(excess);
    }
    // Tasks of about TASK_ROWS observations, each begun at a station's first observation
    // (bounds that depend on the stations alone), summed on the pool and added in their
    // order: the same bits on any number of cores. A station skipped over adds nothing.
    let task = crate::lsq::gh::TASK_ROWS;
    let mut bounds: Vec<usize> = (0..station.len().div_ceil(task))
        .map(|t| {
            let mut i = t * task;
            while i > 0 && i < station.len() && station[i] == station[i - 1] {
                i += 1;
            }
            i
        })
        .collect();
    bounds.push(station.len());
    bounds.dedup();
    let tasks: Vec<BetweenSums> = bounds
        .par_windows(2)
        .map(|w| {
            let mut sums = BetweenSums::default();
            each_station_of(s, station, dof, w[0]..w[1], |x| sums.add(x, 1.0));
            sums
        })
        .collect();
    let mut sums = BetweenSums::default();
    for t in &tasks {
        sums.form += t.form;
        sums.redundancy += t.redundancy;
        sums.t2 += t.t2;
    }
    sums.test(excess)
}

/// The between-station form, its redundancy and its t-inflated variance's part, summed
/// station by station.
#[derive(Default)]
struct BetweenSums {
    form: f64,
    redundancy: f64,
    t2: f64,
}

impl BetweenSums {
    fn add(&mut self, x: &Station, weight: f64) {
        self.form += x.between() * weight;
        self.redundancy += x.redundancy * weight;
        self.t2 += x.redundancy * weight.powi(2) * x.t2_variance;
    }

    fn test(self, excess: f64) -> ScaledChi2 {
        ScaledChi2::with_excess(self.form, self.redundancy, self.t2, excess)
    }
}

/// The between-station form with each station's part weighted by `weight`, against its
/// scaled chi-square.
fn between_form(st: &[Station], weight: impl Fn(&Station) -> f64, excess: f64) -> ScaledChi2 {
    let mut sums = BetweenSums::default();
    st.iter().for_each(|x| sums.add(x, weight(x)));
    sums.test(excess)
}

/// A variance component: the factor on a group's a-priori variances.
#[derive(Clone, Debug, PartialEq)]
pub struct Component {
    /// `theodolite` or `ADC`.
    pub group: &'static str,
    /// The estimate (1 when not estimable).
    pub estimate: f64,
    /// Its sd.
    pub sigma: f64,
    /// The test of whether it is 1: the group's quadratic form at the a-priori weights.
    pub test: ScaledChi2,
    /// Why it was not estimated, when it was not.
    pub not_estimable: Option<String>,
}

impl Component {
    /// The dof of the estimate, from its sd (`sigma = estimate sqrt(2 / dof)`); None when held
    /// at 1, which is then known.
    pub fn dof(&self) -> Option<f64> {
        (self.not_estimable.is_none() && self.sigma > 0.0)
            .then(|| 2.0 * (self.estimate / self.sigma).powi(2))
    }

    fn held(group: &'static str, test: ScaledChi2, why: String) -> Self {
        Self {
            group,
            estimate: 1.0,
            sigma: 0.0,
            test,
            not_estimable: Some(why),
        }
    }
}

/// Per parameter, the degrees of freedom of its variance at estimated components
/// (Welch-Satterthwaite): each group's part of the variance varies with its component,
/// estimated on the component's dof, so `nu = q^2 / sum_g q_g^2 / nu_g`; None where no
/// estimated component weighs the parameter. `s` is the adjustment at the components, `map`
/// takes its parameters to the reported ones, `covariance` is the reported covariance
/// (with what no component scales, such as coloured noise's). The group's part is
/// `Q (sum_i a_i a_i^T u_ig / q_i^2) Q`, u_ig its share of condition i's variance q_i (the
/// parts sum to Q).
pub fn parameter_dof(
    s: &crate::lsq::gh::Solution<3>,
    components: &[Component],
    map: &[f64],
    covariance: &[f64],
) -> Vec<Option<f64>> {
    let m = s.p.len();
    // The estimated groups and their dof; each one's part of the cofactor, built in one
    // pass over the conditions (Q a_i once per condition).
    let estimated: Vec<(usize, f64)> = components
        .iter()
        .take(GROUPS.len())
        .enumerate()
        .filter_map(|(g, c)| c.dof().map(|dof| (g, dof)))
        .collect();
    if estimated.is_empty() {
        // No estimated component weighs any parameter: no pass over the conditions.
        return vec![None; m];
    }
    let mut parts = vec![vec![0.0; m * m]; estimated.len()];
    let mut y = vec![0.0; m];
    for (i, (a, shares)) in s.a.chunks_exact(m).zip(&s.q_parts).enumerate() {
        for (r, yr) in y.iter_mut().enumerate() {
            *yr = (0..m).map(|j| s.q_pp[r * m + j] * a[j]).sum();
        }
        for ((g, _), part) in estimated.iter().zip(&mut parts) {
            let w = shares[*g] / (s.q_ww[i] * s.q_ww[i]);
            for r in 0..m {
                for j in 0..m {
                    part[r * m + j] += w * y[r] * y[j];
                }
            }
        }
    }
    let mut denominator = vec![0.0; m];
    for ((_, dof), part) in estimated.iter().zip(&parts) {
        let reported = crate::calibration::model::propagate(map, part, m);
        for (j, d) in denominator.iter_mut().enumerate() {
            *d += reported[j * m + j].powi(2) / dof;
        }
    }
    denominator
        .iter()
        .enumerate()
        .map(|(j, &d)| {
            let q = covariance[j * m + j];
            (d > 0.0 && q > 0.0).then(|| q * q / d)
        })
        .collect()
}

/// The theodolite's share of the between-station quadratic form, against its expectation
/// at the current components (`excess`: the share-weighted part of noise the weights do not
/// carry); the test is meaningful at the a-priori weights.
pub fn theodolite_step(
    s: &crate::lsq::gh::Solution<3>,
    station: &[usize],
    dof: &[Option<f64>],
    excess: f64,
) -> ScaledChi2 {
    between_form(&stations(s, station, dof), |x| x.share, excess)
}

/// The degrees of freedom of the theodolite component estimated at the weights of `s` (the
/// converged components). The estimate is the theta at which the share-weighted form
/// sum_j s_j b_j meets its expectation sum_j s_j r_j; a station's b_j moves with theta by
/// its share s_j (the rest of its variance, the ADC's and the temperatures', does not), so
/// to first order theta's error is sum_j s_j (b_j - r_j) / sum_j s_j^2 r_j, of variance
/// sum_j s_j^2 r_j v_j / (sum_j s_j^2 r_j)^2 (v_j the t^2 variance per unit of redundancy,
/// 2 for known sigmas): the dof, 2 / that, are sum_j s_j^2 r_j where every share is 1 and
/// fewer as the other groups take more of the stations' variance (a 0.1 K thermometer
/// leaves the theodolite half of it, and a quarter of the dof the form's own would say).
pub fn theodolite_dof(
    s: &crate::lsq::gh::Solution<3>,
    station: &[usize],
    dof: &[Option<f64>],
) -> f64 {
    let st = stations(s, station, dof);
    share_weighted_dof(st.iter().map(|x| (x.share, x.redundancy, x.t2_variance)))
}

/// [`theodolite_dof`] from each station's (share, redundancy, t^2 variance per unit).
fn share_weighted_dof(stations: impl Iterator<Item = (f64, f64, f64)>) -> f64 {
    let (mut sensitivity, mut variance) = (0.0, 0.0);
    for (share, redundancy, t2) in stations {
        sensitivity += share * share * redundancy;
        variance += share * share * redundancy * t2;
    }
    if variance > 0.0 {
        2.0 * sensitivity * sensitivity / variance
    } else {
        0.0
    }
}

/// The theodolite component from its dof at the a-priori weights (`apriori_dof`, which
/// decide whether it is estimated) and at the converged components (`dof`, which give its
/// sd; both [`theodolite_dof`]) and its test at the a-priori weights (`at_one`).
pub fn theodolite_component(
    estimate: f64,
    (apriori_dof, dof): (f64, f64),
    at_one: ScaledChi2,
) -> Component {
    if apriori_dof < MIN_COMPONENT_DOF {
        return Component::held(
            GROUPS[0],
            at_one,
            format!(
                "the station means give it {apriori_dof:.1} degrees of freedom (fewer than {MIN_COMPONENT_DOF})"
            ),
        );
    }
    Component {
        group: GROUPS[0],
        estimate,
        sigma: estimate * (2.0 / dof).sqrt(),
        test: at_one,
        not_estimable: None,
    }
}

/// The ADC component from the scatter of each station's window means `ng` about their
/// weighted mean, in units of their a-priori sds `sigma_ng`, less `excess`, what coloured
/// noise adds to it (its expectation and its variance, which the reference carries too).
///
/// A window mean's sd s estimated from its own samples on `dof` degrees of freedom (None:
/// known) is independent of the mean (a normal sample's mean and variance are), so each
/// term is u (x - x_w)^2 / sigma^2 with u = sigma^2 / s^2 an inverse chi-square of mean
/// f = d/(d - 2) and relative variance c = 2/(d - 4). Given the u, a station's form of
/// m windows has mean tr(A) and variance 2 tr(A^2), A = U - u u^T / sum(u); to first order
/// in c its expectation is f (m - 1 - c) and its variance f^2 (2 (m - 1 + c (m - 4)) +
/// m c (1 - 1/m)^2), the weighted mean taking a little of the scatter the estimated sds
/// add. The reference is the scaled chi-square of their sums (a station's f and c the
/// means of its windows'). Taken as known, sds from 80 samples made the test reject 7.8 %
/// of the time at its 5 % (docs/model.md 6.2).
pub fn adc_component(
    ng: &[f64],
    sigma_ng: &[f64],
    dof: &[Option<f64>],
    station: &[usize],
    excess: crate::lsq::correlated::Excess,
) -> Component {
    let count = station.iter().max().map_or(0, |m| m + 1);
    // Two passes: the weighted mean of each station (with its windows' f and c), then the
    // squares about it (counts of millions would cancel to nothing in sum w x^2 - (sum w
    // x)^2 / sum w).
    let mut mean = vec![WindowGroup::default(); count];
    for (((&x, &s), &d), &j) in ng.iter().zip(sigma_ng).zip(dof).zip(station) {
        let w = 1.0 / (s * s);
        let g = &mut mean[j];
        g.sum_w += w;
        g.sum_wx += w * x;
        g.m += 1;
        g.sum_f += predictive_factor(d);
        g.sum_c += relative_variance(d);
    }
    let mut form = 0.0;
    for ((&x, &s), &j) in ng.iter().zip(sigma_ng).zip(station) {
        let g = &mean[j];
        if g.m > 1 && g.sum_w > 0.0 {
            form += ((x - g.sum_wx / g.sum_w) / s).powi(2);
        }
    }
    let (mut expected, mut variance) = (0.0, 0.0);
    for g in mean.iter().filter(|g| g.m > 1 && g.sum_w > 0.0) {
        let m = g.m as f64;
        let (f, c) = (g.sum_f / m, g.sum_c / m);
        expected += f * (m - 1.0 - c);
        variance += f * f * (2.0 * (m - 1.0 + c * (m - 4.0)) + m * c * (1.0 - 1.0 / m).powi(2));
    }
    let dof: f64 = mean
        .iter()
        .filter(|g| g.m > 1 && g.sum_w > 0.0)
        .map(|g| (g.m - 1) as f64)
        .sum();
    let test = ScaledChi2::new(
        form,
        expected + excess.mean.max(0.0),
        variance + excess.variance.max(0.0),
    );
    if dof < MIN_COMPONENT_DOF || !form.is_finite() {
        return Component::held(
            GROUPS[1],
            test,
            format!(
                "stations give {dof} degrees of freedom of repeated window means (fewer than {MIN_COMPONENT_DOF})"
            ),
        );
    }
    let estimate = ((form - excess.mean) / expected).max(1e-6);
    Component {
        group: GROUPS[1],
        estimate,
        sigma: estimate * (2.0 / test.dof).sqrt(),
        test,
        not_estimable: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lsq::correlated::Excess;

    /// A two-parameter solution of `n` conditions, condition i's misclosure, q_ww, theodolite
    /// part of it (the ADC's 0.5) and redundancy `of(i)`; the rest zero.
    fn with_conditions(
        n: usize,
        of: impl Fn(usize) -> (f64, f64, f64, f64),
    ) -> crate::lsq::gh::Solution<3> {
        let rows: Vec<_> = (0..n).map(of).collect();
        crate::lsq::gh::Solution::<3> {
            p: vec![0.0; 2],
            q_pp: vec![1.0, 0.0, 0.0, 1.0],
            v: vec![[0.0; 3]; n],
            misclosure: rows.iter().map(|r| r.0).collect(),
            q_ww: rows.iter().map(|r| r.1).collect(),
            q_parts: rows.iter().map(|r| [r.2, 0.5, 0.0]).collect(),
            redundancy: rows.iter().map(|r| r.3).collect(),
            w_test: vec![0.0; n],
            vtpv: 0.0,
            dof: n - 2,
            iterations: 1,
            a: vec![0.0; 2 * n],
            b: vec![[0.0; 3]; n],
        }
    }

    /// Observations that come station by station are summed one station at a time, and give
    /// the vector's stations, a station index with no observation (3) included as zeros.
    #[test]
    fn stations_streamed_are_the_vectors() {
        let s = with_conditions(7, |i| {
            let i = i as f64;
            (0.1 * i - 0.3, 1.0 + 0.2 * i, 0.5 + 0.05 * i, 0.6 + 0.03 * i)
        });
        let station = [0, 0, 1, 1, 1, 2, 4];
        let dof = [None, Some(9.0), None, Some(4.0), None, None, Some(30.0)];
        let vector = stations(&s, &station, &dof);
        let mut streamed = Vec::new();
        each_station(&s, &station, &dof, |x| streamed.push(x.clone()));
        assert_eq!(format!("{streamed:?}"), format!("{vector:?}"));
        assert_eq!(streamed.len(), 5);
        assert!(streamed[3].n == 0.0 && streamed[3].sum_w == 0.0);
        // Out of order, the vector itself.
        let mut shuffled = Vec::new();
        each_station(&s, &[1, 0, 0, 1, 1, 2, 4], &dof, |x| shuffled.push(x.n));
        assert_eq!(shuffled, [2.0, 3.0, 1.0, 0.0, 1.0]);
    }

    /// The global test's stations summed a task at a time on the pool: the sums of one pass
    /// over them to rounding, with stations of many observations across the tasks'
    /// boundaries and of one; and out of station order, the vector's.
    #[test]
    fn the_global_test_in_tasks_is_the_one_pass() {
        let n = 3 * crate::lsq::gh::TASK_ROWS + 1234;
        let s = with_conditions(n, |i| {
            (
                ((i * 37) % 101) as f64 * 0.02 - 1.0,
                1.0 + 0.001 * (i % 997) as f64,
                0.5 + 1e-4 * (i % 13) as f64,
                0.6 + 1e-5 * (i % 31) as f64,
            )
        });
        // Stations of 1 to 5000 observations, in order.
        let mut station = Vec::with_capacity(n);
        let (mut id, mut left) = (0, 1);
        for _ in 0..n {
            if left == 0 {
                id += 1;
                left = [1, 7, 5000, 2, 900][id % 5];
            }
            station.push(id);
            left -= 1;
        }
        let dof: Vec<Option<f64>> = (0..n).map(|i| (i % 3 == 0).then_some(20.0)).collect();
        let mut one_pass = BetweenSums::default();
        each_station(&s, &station, &dof, |x| one_pass.add(x, 1.0));
        let want = one_pass.test(0.0);
        let got = lack_of_fit(&s, &station, &dof, 0.0);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(1.0);
        assert!(
            close(got.statistic, want.statistic),
            "{} {}",
            got.statistic,
            want.statistic
        );
        assert!(close(got.mean, want.mean), "{} {}", got.mean, want.mean);
        assert!(close(got.dof, want.dof), "{} {}", got.dof, want.dof);
        // Out of order: the stations' vector, one pass.
        station.swap(0, n - 1);
        let mut vector = BetweenSums::default();
        stations(&s, &station, &dof)
            .iter()
            .for_each(|x| vector.add(x, 1.0));
        let shuffled = lack_of_fit(&s, &station, &dof, 0.0);
        assert_eq!(
            shuffled.statistic.to_bits(),
            vector.test(0.0).statistic.to_bits()
        );
    }

    /// A weighted mean of n conditions, each with a theodolite part u0 and an ADC part u1 of
    /// its variance: the parameter's dof is Welch-Satterthwaite's (u0 + u1)^2 / (u0^2 /
    /// nu0 + u1^2 / nu1); a held component counts as known, and with both held there is
    /// none.
    /// The theodolite component as calibrate iterates it (theta times the share-weighted
    /// form over its expectation, the shares and forms at the current theta), on stations
    /// whose theodolite part T_j and other part O_j (known) differ: the estimates' relative
    /// variance over 20 000 draws is 2 / [`share_weighted_dof`] within 5 %, where the form's
    /// own dof, (sum s_j r_j)^2 / sum s_j^2 r_j, would say two fifths of it.
    #[test]
    fn the_theodolite_components_dof_is_its_shares() {
        let mut rng = fixtures::rng::Rng::new(27, "theodolite-dof");
        // 30 stations of one unit of redundancy, shares from 0.2 to 0.9 at theta = 1.
        let parts: Vec<(f64, f64)> = (0..30)
            .map(|j| {
                let s = 0.2 + 0.7 * f64::from(j) / 29.0;
                (s, 1.0 - s)
            })
            .collect();
        let draws = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..draws {
            let x: Vec<f64> = parts.iter().map(|_| rng.normal().powi(2)).collect();
            let mut theta = 1.0_f64;
            for _ in 0..200 {
                let (mut form, mut mean) = (0.0, 0.0);
                for (&(t, o), &xj) in parts.iter().zip(&x) {
                    let v = theta * t + o;
                    let share = theta * t / v;
                    form += share * xj * (t + o) / v;
                    mean += share;
                }
                let next = (theta * form / mean).clamp(1e-6, 1e6);
                let settled = (next / theta - 1.0).abs() < 1e-10;
                theta = next;
                if settled {
                    break;
                }
            }
            sum += theta;
            sum2 += theta * theta;
        }
        let mean = sum / f64::from(draws);
        let relative = (sum2 / f64::from(draws) - mean * mean) / (mean * mean);
        let dof = share_weighted_dof(parts.iter().map(|&(s, _)| (s, 1.0, 2.0)));
        let form_dof = parts.iter().map(|p| p.0).sum::<f64>().powi(2)
            / parts.iter().map(|p| p.0 * p.0).sum::<f64>();
        eprintln!(
            "theodolite component: relative variance {relative:.4}, 2 / dof {:.4} (dof {dof:.1}; \
             the form's own {form_dof:.1})",
            2.0 / dof
        );
        assert!(
            (relative * dof / 2.0 - 1.0).abs() < 0.05,
            "{relative} against {}",
            2.0 / dof
        );
    }

    #[test]
    fn a_parameters_dof_is_welch_satterthwaites() {
        let (n, u0, u1, nu0, nu1) = (8, 3.0, 1.0, 12.0, 40.0);
        let q = u0 + u1;
        let s = crate::lsq::gh::Solution::<3> {
            p: vec![0.0],
            q_pp: vec![q / n as f64],
            v: vec![[0.0; 3]; n],
            misclosure: vec![0.0; n],
            q_ww: vec![q; n],
            q_parts: vec![[u0, u1, 0.0]; n],
            redundancy: vec![1.0; n],
            w_test: vec![0.0; n],
            vtpv: 0.0,
            dof: n - 1,
            iterations: 1,
            a: vec![1.0; n],
            b: vec![[1.0; 3]; n],
        };
        let test = ScaledChi2::new(1.0, 1.0, 2.0);
        let estimated = |group, dof: f64| Component {
            group,
            estimate: 1.3,
            sigma: 1.3 * (2.0 / dof).sqrt(),
            test,
            not_estimable: None,
        };
        let both = [estimated(GROUPS[0], nu0), estimated(GROUPS[1], nu1)];
        let covariance = [q / n as f64];
        let nu = parameter_dof(&s, &both, &[1.0], &covariance)[0].expect("dof");
        let want = q * q / (u0 * u0 / nu0 + u1 * u1 / nu1);
        assert!((nu / want - 1.0).abs() < 1e-12, "{nu} {want}");
        let held = Component::held(GROUPS[1], test, "held".to_owned());
        let one = [estimated(GROUPS[0], nu0), held.clone()];
        let nu = parameter_dof(&s, &one, &[1.0], &covariance)[0].expect("dof");
        assert!((nu / (q * q / (u0 * u0 / nu0)) - 1.0).abs() < 1e-12, "{nu}");
        let none = [Component::held(GROUPS[0], test, "held".to_owned()), held];
        assert_eq!(parameter_dof(&s, &none, &[1.0], &covariance), vec![None]);
    }

    /// The t's quantile where statrs's holds, and its expansion beyond (statrs's at 1e3
    /// dof, scipy's `t.ppf(0.975, d)` at 1e4, 1e7 and 1e9; statrs's own never returns at
    /// 1e9), and at the switch the two agree.
    #[test]
    fn the_ts_quantile_holds_at_any_dof() {
        for (d, want) in [
            (1e4, 1.960_201_239_890_626),
            (1e7, 1.959_964_221_767_205),
            (1e9, 1.959_963_986_912_325),
        ] {
            let got = t_quantile(0.975, d);
            assert!((got - want).abs() < 1e-9, "{d}: {got} {want}");
        }
        let below = statrs::distribution::StudentsT::new(0.0, 1.0, T_EXPANSION_DOF)
            .map(|t| t.inverse_cdf(0.975))
            .expect("t");
        let above = t_quantile(0.975, T_EXPANSION_DOF * (1.0 + 1e-12));
        assert!((below - above).abs() < 1e-9, "{below} {above}");
        assert!((interval_95_sigmas(Some(1e12)) - 1.959_963_984_540_054).abs() < 1e-9);
    }

    /// The 95 % interval's half-width against scipy's `t.ppf(0.975, d) * sqrt((d - 2) / d)`.
    #[test]
    fn the_interval_is_the_ts() {
        for (d, want) in [
            (37.0, 1.970_669_775_038_486_7),
            (12.0, 1.988_974_892_313_858_4),
            (6.0, 1.997_895_160_291_400_4),
        ] {
            let got = interval_95_sigmas(Some(d));
            assert!((got - want).abs() < 1e-9, "{d}: {got} {want}");
        }
        assert!((interval_95_sigmas(None) - 1.959_963_984_540_054).abs() < 1e-12);
    }

    #[test]
    fn known_sigmas_reduce_to_chi_square() {
        let t = ScaledChi2::new(10.0, 10.0, 20.0);
        let d = ChiSquared::new(10.0).expect("chi2");
        assert!((t.dof - 10.0).abs() < 1e-12);
        assert!((t.lower - d.inverse_cdf(0.025)).abs() < 1e-9);
        assert!((t.upper - d.inverse_cdf(0.975)).abs() < 1e-9);
        assert!(t.passed());
    }

    #[test]
    fn estimated_variances_widen_the_bounds() {
        let known = ScaledChi2::new(10.0, 10.0, 10.0 * t2_variance(None));
        let est = ScaledChi2::new(10.0, 10.0, 10.0 * t2_variance(Some(14.0)));
        assert!(est.upper > known.upper && est.lower < known.lower);
        assert!((predictive_factor(Some(14.0)) - 14.0 / 12.0).abs() < 1e-12);
        assert!((predictive_factor(None) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn window_means_scattering_beyond_their_sd_raise_the_adc_component() {
        // Two stations, window means 1 sd (2 counts) either side of their station's mean.
        let ng = [10.0, 14.0, 10.0, 14.0, 100.0, 104.0, 100.0, 104.0];
        let sigma = [2.0; 8];
        let station = [0, 0, 0, 0, 1, 1, 1, 1];
        let c = adc_component(&ng, &sigma, &[None; 8], &station, Excess::default());
        // Each station: 4 x (2/2)^2 = 4 on 3 dof; 8 / 6.
        assert!((c.estimate - 8.0 / 6.0).abs() < 1e-12, "{c:?}");
        // Sds estimated on 20 dof: a station expects f (m - 1 - c), f = 20/18, c = 2/16.
        let estimated = adc_component(&ng, &sigma, &[Some(20.0); 8], &station, Excess::default());
        let expected = 2.0 * 20.0 / 18.0 * (3.0 - 2.0 / 16.0);
        assert!((estimated.estimate - 8.0 / expected).abs() < 1e-12);
        assert!(estimated.test.upper > c.test.upper);
        let one = adc_component(
            &ng[..2],
            &sigma[..2],
            &[None; 2],
            &station[..2],
            Excess::default(),
        );
        assert!(one.not_estimable.is_some());
    }

    /// Window means whose sds come from their own 80 samples, 5 and 20 windows a station:
    /// the component averages 1 and its two-sided 5 % test rejects 5 % of the time (within
    /// 3 standard errors of 3000 replicas), where taking the sds as known rejects
    /// measurably more often (the more windows, the more).
    #[test]
    fn the_adc_test_holds_its_level_with_estimated_window_sds() {
        let mut rng = fixtures::rng::Rng::new(26, "adc-component");
        let (replicas, samples) = (3000, 80);
        let n = f64::from(replicas);
        let se = (0.05 * 0.95 / n).sqrt();
        for (stations, windows) in [(40, 5), (20, 20)] {
            let (mut estimate, mut rejected, mut low, mut rejected_known) = (0.0, 0, 0, 0);
            let station: Vec<usize> = (0..stations * windows).map(|i| i / windows).collect();
            let dof = vec![Some(f64::from(samples - 1)); station.len()];
            for _ in 0..replicas {
                let mut ng = Vec::with_capacity(station.len());
                let mut sigma = Vec::with_capacity(station.len());
                for &j in &station {
                    let x: Vec<f64> = (0..samples)
                        .map(|_| 1000.0 * j as f64 + rng.normal())
                        .collect();
                    let k = f64::from(samples);
                    let m = x.iter().sum::<f64>() / k;
                    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (k - 1.0);
                    ng.push(m);
                    sigma.push((var / k).sqrt());
                }
                let c = adc_component(&ng, &sigma, &dof, &station, Excess::default());
                estimate += c.estimate;
                rejected += usize::from(!c.test.passed());
                low += usize::from(c.test.statistic < c.test.lower);
                let known = adc_component(
                    &ng,
                    &sigma,
                    &vec![None; station.len()],
                    &station,
                    Excess::default(),
                );
                rejected_known += usize::from(!known.test.passed());
            }
            let (rate, known) = (rejected as f64 / n, rejected_known as f64 / n);
            eprintln!(
                "ADC component, {stations} stations x {windows} windows of {samples} samples, \
                 {replicas} replicas: mean {:.4}, test rejects {:.2} % ({:.2} % low), \
                 {:.2} % with the sds taken as known",
                estimate / n,
                100.0 * rate,
                100.0 * low as f64 / n,
                100.0 * known
            );
            assert!((estimate / n - 1.0).abs() < 0.01, "mean {}", estimate / n);
            assert!((rate - 0.05).abs() < 3.0 * se, "rejects {rate}");
            if windows == 20 {
                assert!(known > 0.05 + 3.0 * se, "known sds reject only {known}");
            }
        }
    }
}
