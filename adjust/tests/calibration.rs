//! The adjust stage on the simulated experiments: estimates against the generator's truth,
//! blunders, disconnected channels, misalignment, and the Monte-Carlo acceptance test that
//! the reported sigmas and the global test are honest (fast in CI, full when gated).

mod common;
use common::{EXACT, Thermometer, quadratic_form_of_inverse};
use fixtures::write::Truth;
use ingest::contract::calibration::{Calibration, CalibrationResult};
use std::path::Path;

fn pipeline(dataset: &Path) -> (tempfile::TempDir, Calibration) {
    let out = tempfile::tempdir().expect("tempdir");
    ingest::run(dataset, out.path()).expect("ingest");
    align::run(dataset, out.path()).expect("align");
    let c = adjust::run(dataset, out.path()).expect("adjust");
    (out, c)
}

fn param(r: &CalibrationResult, name: &str) -> (f64, f64) {
    let p = r
        .parameters
        .iter()
        .find(|p| p.name == name)
        .unwrap_or_else(|| panic!("{name} in {}", r.model));
    (p.value, p.sigma)
}

fn within_3_sigma(what: &str, (value, sigma): (f64, f64), truth: f64) {
    let z = (value - truth) / sigma;
    assert!(
        z.abs() < 3.0,
        "{what}: {value} vs truth {truth}: {z:.2} sigma"
    );
}

/// Many parameters checked at once: 3 sigma each would fail 1 - 0.9973^n of correct runs
/// (5 % for n = 18), so the bound on the largest |z| is Bonferroni's for a 1 % family-wise
/// rate, and their mean square must be plausible for n standard normals (below 2.2, a
/// chi-square(18)/18 exceeds it with probability 0.2 %).
fn all_within_family_bound(z: &[(String, f64)]) {
    let n = z.len() as f64;
    let bound = statrs::distribution::ContinuousCDF::inverse_cdf(
        &statrs::distribution::Normal::standard(),
        1.0 - 0.01 / (2.0 * n),
    );
    let (worst, zmax) = z
        .iter()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .expect("some parameters");
    assert!(
        zmax.abs() < bound,
        "{worst}: {zmax:.2} sigma from truth (bound {bound:.2})"
    );
    let ms = z.iter().map(|(_, x)| x * x).sum::<f64>() / n;
    assert!(ms < 2.2, "mean square z {ms:.2} over {n} parameters: {z:?}");
}

/// Good readings removed by chance, at alpha = 0.001 per reading tested: at most the
/// Poisson's 99.9 % quantile of their expected number.
fn chance_removals_within_alpha(chance_removals: usize, tested: usize) {
    let expected = 0.001 * tested as f64;
    let (mut k, mut term, mut cdf) = (0usize, (-expected).exp(), (-expected).exp());
    while cdf < 0.999 {
        k += 1;
        term *= expected / k as f64;
        cdf += term;
    }
    assert!(
        chance_removals <= k,
        "{chance_removals} good readings removed of {tested} tested (alpha predicts \
         {expected:.1}, 99.9 % bound {k})"
    );
}

fn z_of((value, sigma): (f64, f64), truth: f64) -> f64 {
    (value - truth) / sigma
}

/// docs/model.md on the replica of the paper: per-session linear fits and the thermal model over
/// both days recover the truth (18 parameters, [`all_within_family_bound`]) with sigma0 near
/// 1; snooping removes the generator's two blunders, and good readings no more often than
/// alpha = 0.001 allows; acc2 on day 2 is skipped as disconnected.
#[test]
fn replica_recovers_the_truth() {
    let dataset = fixtures::dataset_dir("esgt-2005");
    let truth: Truth = fixtures::read_truth(&dataset).expect("truth");
    let (_out, c) = pipeline(&dataset);
    assert_eq!(c.format, "gravcal-calibration/1");
    assert!((c.gravity_mgal - truth.gravity_mgal).abs() < 1e-9);
    let blunders: Vec<(String, String, i64)> = truth
        .reading
        .iter()
        .filter(|r| r.blunder_rad != 0.0)
        .map(|r| (r.session.clone(), r.station.clone(), r.time_gps_ns))
        .collect();
    assert_eq!(blunders.len(), 2);
    let linear: Vec<&CalibrationResult> =
        c.results.iter().filter(|r| r.model == "linear").collect();
    assert_eq!(linear.len(), 5);
    // The linear fits of acc1 and acc3, whose temperature moved within the day, carry the
    // thermal model's sensitivity and say so (docs/model.md 6.1); acc2 has no thermal model
    // to say it with, and the thermal fits carry the temperature.
    let moved = |r: &&CalibrationResult| {
        r.warnings
            .iter()
            .any(|w| w.contains("temperature moved") && w.contains("consider parameter"))
    };
    let warned: Vec<(&str, &str)> = c
        .results
        .iter()
        .filter(moved)
        .map(|r| (r.accelerometer.as_str(), r.session.as_str()))
        .collect();
    assert_eq!(
        warned,
        [
            ("acc1", "day1"),
            ("acc1", "day2"),
            ("acc3", "day1"),
            ("acc3", "day2")
        ],
        "{:?}",
        c.results.iter().map(|r| &r.warnings).collect::<Vec<_>>()
    );
    // A linear fit with no thermal fit to take the sensitivity from (acc2) gives the
    // sensitivity at which its temperature's movement is 0.3 sigma of b, and says it cannot
    // tell.
    for r in &linear {
        let [lo, hi] = r.temperature_range_c.expect("temperatures");
        let limit = 0.3 * param(r, "b").1 / (hi - lo);
        match r.thermal_sensitivity_limit_mgal_per_k {
            Some(given) => assert!((given - limit).abs() < 1e-9 * limit, "{given} {limit}"),
            None => assert!(moved(r), "{:?}", r.warnings),
        }
        let unknown = r.warnings.iter().any(|w| {
            w.contains(&format!(
                "no fit of {} with temperature terms",
                r.accelerometer
            ))
        });
        assert_eq!(unknown, r.accelerometer == "acc2", "{:?}", r.warnings);
    }
    assert!(
        c.results
            .iter()
            .filter(|r| r.temperature)
            .all(|r| r.thermal_sensitivity_limit_mgal_per_k.is_none())
    );
    let mut z: Vec<(String, f64)> = Vec::new();
    let (mut chance_removals, mut tested) = (0usize, 0usize);
    for r in &linear {
        let s = truth
            .session
            .iter()
            .find(|s| s.id == r.session)
            .expect("session");
        let cal = s
            .calibration
            .iter()
            .find(|c| c.accelerometer == r.accelerometer)
            .expect("calibration");
        let what = format!("{} {}", r.accelerometer, r.session);
        z.push((format!("{what} b"), z_of(param(r, "b"), cal.b_mgal)));
        z.push((format!("{what} k"), z_of(param(r, "k"), cal.k_mgal_per_bit)));
        assert!(
            (0.85..1.15).contains(&r.sigma0),
            "{what}: sigma0 {}",
            r.sigma0
        );
        assert!(r.global_test.passed, "{what}: {:?}", r.global_test);
        // Counts of 1.4e6..3.3e6, far from zero: b and k anti-correlated near -0.98.
        assert!(
            r.correlation[0][1] < -0.95,
            "{what}: b-k correlation {}",
            r.correlation[0][1]
        );
        let removed: Vec<(String, String, i64)> = r
            .removed
            .iter()
            .map(|x| (x.session.clone(), x.station.clone(), x.time_gps_ns))
            .collect();
        for b in blunders.iter().filter(|b| b.0 == r.session) {
            assert!(
                removed.contains(b),
                "{what}: blunder {b:?} kept; removed {removed:?}"
            );
        }
        chance_removals += removed.iter().filter(|x| !blunders.contains(x)).count();
        tested += r.n_observations + r.removed.len();
        assert!(!r.removed.is_empty());
        assert!(
            r.removed
                .iter()
                .all(|x| x.w.abs() > adjust::calibration::calibrate::W_CRITICAL)
        );
        assert_eq!(r.n_excluded, r.removed.len());
    }
    let skipped: Vec<(&str, &str, &str)> = c
        .skipped
        .iter()
        .map(|s| {
            (
                s.model.as_str(),
                s.accelerometer.as_str(),
                s.session.as_str(),
            )
        })
        .collect();
    assert_eq!(
        skipped,
        [("linear", "acc2", "day2"), ("thermal", "acc2", "all")]
    );
    assert_eq!(c.skipped[0].reason, "channel not connected");
    // Regression: acc2 has one day, so one temperature set; its thermal fit printed b_t with
    // a sigma six times its size instead of saying the design cannot determine it.
    assert!(
        c.skipped[1].reason.contains("b_t is not estimable")
            && c.skipped[1].reason.contains("one temperature set"),
        "{}",
        c.skipped[1].reason
    );

    // The thermal model over both days: b_t and k_t of acc1 and acc3 (acc2 has one day only).
    for r in c
        .results
        .iter()
        .filter(|r| r.model == "thermal" && r.accelerometer != "acc2")
    {
        let a = truth
            .accelerometer
            .iter()
            .find(|a| a.id == r.accelerometer)
            .expect("acc");
        let t_ref = r.t_ref_c.expect("thermal has t_ref");
        let dt = t_ref - truth.t_ref_c;
        let what = format!("{} thermal", r.accelerometer);
        for (name, t) in [
            ("b", a.b_mgal + a.b_t_mgal_per_c * dt),
            ("k", a.k_mgal_per_bit + a.k_t_mgal_per_bit_per_c * dt),
            ("b_t", a.b_t_mgal_per_c),
            ("k_t", a.k_t_mgal_per_bit_per_c),
        ] {
            z.push((format!("{what} {name}"), z_of(param(r, name), t)));
        }
        assert!((0.85..1.15).contains(&r.sigma0));
        let removed: Vec<(String, String, i64)> = r
            .removed
            .iter()
            .map(|x| (x.session.clone(), x.station.clone(), x.time_gps_ns))
            .collect();
        for b in &blunders {
            assert!(removed.contains(b), "{what}: blunder {b:?} kept");
        }
        chance_removals += removed.iter().filter(|x| !blunders.contains(x)).count();
        tested += r.n_observations + r.removed.len();
    }
    chance_removals_within_alpha(chance_removals, tested);
    assert_eq!(z.len(), 18);
    all_within_family_bound(&z);
}

fn with_models(name: &str, models: &str) -> tempfile::TempDir {
    let ds = tempfile::tempdir().expect("tempdir");
    fixtures::copy_dataset(name, ds.path(), |m| m + models).expect("copy");
    ds
}

/// With tilts on both sides of the vertical, the misalignment of each accelerometer is
/// recovered within 3 sigma.
#[test]
fn two_sided_design_recovers_beta() {
    let dataset = fixtures::dataset_dir("two-sided");
    let truth = fixtures::read_truth(&dataset).expect("truth");
    let (_out, c) = pipeline(&dataset);
    let fits: Vec<&CalibrationResult> = c
        .results
        .iter()
        .filter(|r| r.model == "linear-beta")
        .collect();
    assert_eq!(fits.len(), 3);
    for r in fits {
        let a = truth
            .accelerometer
            .iter()
            .find(|a| a.id == r.accelerometer)
            .expect("acc");
        let (beta, sigma) = param(r, "beta");
        // At roll 0, sin beta = theta_x.
        let truth_beta = a.theta_x_rad.asin();
        within_3_sigma(
            &format!("{} beta", r.accelerometer),
            (beta, sigma),
            truth_beta,
        );
        assert!(
            sigma < 0.25 * truth_beta.abs(),
            "{}: beta {beta} +/- {sigma} is determined",
            r.accelerometer
        );
        let s = &truth.session[0]
            .calibration
            .iter()
            .find(|x| x.accelerometer == r.accelerometer)
            .expect("cal");
        within_3_sigma("b", param(r, "b"), s.b_mgal);
        within_3_sigma("k", param(r, "k"), s.k_mgal_per_bit);
    }
}

/// Sessions at rolls 0 and 90 deg determine the misalignment vector: theta_x, theta_y within
/// 3 sigma of the truth, theta and psi given with sigmas, and psi near the truth's direction.
#[test]
fn two_rolls_recover_the_misalignment_vector() {
    let dataset = fixtures::dataset_dir("roll-sessions");
    let truth = fixtures::read_truth(&dataset).expect("truth");
    let (_out, c) = pipeline(&dataset);
    let fits: Vec<&CalibrationResult> = c.results.iter().filter(|r| r.model == "vector").collect();
    assert_eq!(fits.len(), 3);
    for (r, (theta, psi)) in fits.iter().zip(fixtures::catalog::ROLL_SESSIONS_THETA) {
        let a = truth
            .accelerometer
            .iter()
            .find(|a| a.id == r.accelerometer)
            .expect("acc");
        let what = &r.accelerometer;
        within_3_sigma(
            &format!("{what} theta_x"),
            param(r, "theta_x"),
            a.theta_x_rad,
        );
        within_3_sigma(
            &format!("{what} theta_y"),
            param(r, "theta_y"),
            a.theta_y_rad,
        );
        let v = r.misalignment_vector.as_ref().expect("theta and psi");
        within_3_sigma(
            &format!("{what} theta"),
            (v.theta_rad, v.sigma_theta_rad),
            theta,
        );
        let (p, sp) = (v.psi_deg.expect("psi"), v.sigma_psi_deg.expect("sigma psi"));
        within_3_sigma(&format!("{what} psi"), (p, sp), psi);
        // Nothing said of estimability; the one note is the moving temperature's, which no
        // model of this run includes (the fixture's temperature moves by about 20 mK).
        assert!(
            r.warnings
                .iter()
                .all(|w| w.contains("with temperature terms, this run cannot say")),
            "{:?}",
            r.warnings
        );
    }
}

/// One roll sees one component: a vector model on the two-sided design (roll 0 only) names
/// theta_y as not estimable, says which roll would fix it, and still gives beta.
#[test]
fn one_roll_names_the_component_it_cannot_see() {
    let ds = with_models(
        "two-sided",
        "\n[[adjust.model]]\nname = \"vector\"\norder = 1\nper = \"all\"\nmisalignment = \"vector\"\n",
    );
    let (_out, c) = pipeline(ds.path());
    let fits: Vec<&CalibrationResult> = c.results.iter().filter(|r| r.model == "vector").collect();
    assert_eq!(fits.len(), 3);
    for r in fits {
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("(theta_y) is not estimable")
                    && w.contains("a session at roll 90.0 deg would determine it")),
            "{:?}",
            r.warnings
        );
        assert!(param(r, "beta").1 > 0.0);
        assert!(r.parameters.iter().all(|p| p.name != "theta_y"));
        assert!(r.misalignment_vector.is_none());
    }
}

/// A vector model fitted per session is a manifest error naming the key.
#[test]
fn a_vector_model_per_session_is_refused() {
    let ds = with_models(
        "two-sided",
        "\n[[adjust.model]]\nname = \"vector\"\nper = \"session\"\nmisalignment = \"vector\"\n",
    );
    let e = ingest::contract::manifest::Dataset::load(ds.path()).expect_err("refused");
    let text = e.to_string();
    assert!(
        text.contains("adjust.model[2].misalignment") && text.contains("per = \"all\""),
        "{text}"
    );
}

/// On the paper's one-sided design, beta with a second-order term is not (or barely)
/// estimable: the result says so by name, with its correlation to k2.
#[test]
fn one_sided_design_cannot_separate_beta_from_k2() {
    let ds = with_models(
        "esgt-2005",
        "\n[[adjust.model]]\nname = \"quadratic-beta\"\norder = 2\nper = \"session\"\nmisalignment = true\n",
    );
    let (_out, c) = pipeline(ds.path());
    let mut seen = 0;
    for r in c.results.iter().filter(|r| r.model == "quadratic-beta") {
        seen += 1;
        assert!(
            r.warnings
                .iter()
                .any(|w| w.starts_with("beta is barely estimable") && w.contains(", k2 ")),
            "{}: {:?}",
            r.accelerometer,
            r.warnings
        );
    }
    for s in c
        .skipped
        .iter()
        .filter(|s| s.model == "quadratic-beta" && s.reason != "channel not connected")
    {
        seen += 1;
        assert!(s.reason.contains("beta"), "{}", s.reason);
    }
    assert_eq!(seen, 5);
}

/// Parameters of the acceptance design, in calibrate's order for order 1 with temperature
/// and misalignment.
const MC_PARAMETERS: [&str; 5] = ["b", "k", "b_t", "k_t", "beta"];
/// The Monte-Carlos' model: order 1 with temperature terms and misalignment.
const MC_TERMS: adjust::calibration::model::Terms = adjust::calibration::model::Terms {
    order: 1,
    temperature: true,
    misalignment: adjust::calibration::model::Misalignment::Plane,
};
/// True misalignment of the Monte-Carlo, rad.
const MC_BETA_RAD: f64 = 4.5e-4;
/// Where the Monte-Carlo checks the applied function's sigma: (fraction of the design's
/// counts range, temperature degC): inside both ranges; at the hot end beyond the 31 degC
/// the calibration saw; beyond the counts (as the survey's 150 deg attitude).
const MC_APPLY_POINTS: [(f64, f64); 3] = [(0.5, 28.0), (0.5, 32.5), (1.3, 31.0)];

/// What a Monte-Carlo measured.
struct MonteCarlo {
    /// Empirical sd over the mean reported sigma, per parameter of [`MC_PARAMETERS`].
    sd_over_sigma: [f64; 5],
    /// Mean estimate minus truth over its standard error, for b_t, k_t and beta (b and k
    /// are at the fit's own reference temperature).
    bias_z: [f64; 3],
    /// Share of replicas whose global test rejected.
    rejection_rate: f64,
    /// Mean of (p^ - p)^T C^-1 (p^ - p) over the five parameters, over 5: 1 when the
    /// reported covariance (correlations too) is the estimates' own.
    mahalanobis_ratio: f64,
    /// The calibration function's error over its reported sigma (J C J^T, what `apply`
    /// reports), sd over mean sigma, at each of [`MC_APPLY_POINTS`].
    applied_sd_over_sigma: [f64; 3],
    /// Mean theodolite variance component.
    mean_theodolite_component: f64,
    /// Mean ADC variance component.
    mean_adc_component: f64,
    /// Share of replicas whose two-sided 5 % test rejected, theodolite and ADC component.
    component_rejection: [f64; 2],
    /// Mean observations removed by snooping.
    mean_removed: f64,
    /// Replicas whose fit failed, with the error.
    failed: Vec<String>,
    /// The counts behind the verdicts' rates.
    counts: VerdictCounts,
}

/// What a Monte-Carlo's verdicts did, counted.
#[derive(Clone, Copy, Debug, Default)]
struct VerdictCounts {
    /// Replicas fitted.
    fits: usize,
    /// Of them, rejected by the global test.
    global_rejected: usize,
    /// Replicas whose theodolite and ADC components were tested (estimable).
    component_tested: [usize; 2],
    /// Of them, rejected by the component's two-sided 5 % test.
    component_rejected: [usize; 2],
    /// Observations tested by data snooping.
    observations: usize,
    /// Of them, removed (all good: these replicas carry no blunder).
    removed: usize,
    /// The sum over replicas of the square of each one's removals.
    removed_squared: usize,
    /// The parameters' 95 % intervals (on each one's dof) that missed the truth, over the
    /// replicas' [`MC_PARAMETERS`], and the sum of each replica's count squared.
    intervals_missed: usize,
    intervals_missed_squared: usize,
}

impl VerdictCounts {
    /// A count's design effect: the variance of a replica's count (`hits` in all, the sum
    /// of each replica's square `squared`, of `trials` in all) over the binomial variance
    /// of its trials' (a fit's observations are removed or kept together, and its
    /// correlated parameters' intervals miss together, not as independent trials).
    fn design_effect(&self, trials: usize, hits: usize, squared: usize) -> f64 {
        let r = self.fits as f64;
        let mean = hits as f64 / r;
        let variance = (squared as f64 - r * mean * mean) / (r - 1.0);
        let per_fit = trials as f64 / r;
        if mean == 0.0 || r < 2.0 {
            // Nothing counted: no dispersion to measure; the binomial's.
            return 1.0;
        }
        variance / (mean * (1.0 - mean / per_fit))
    }

    /// The false-alarm rates of the global test, the two components' tests, the w-test and
    /// the parameters' 95 % intervals, on `replicas`.
    fn rates(&self, replicas: &str) -> Vec<fixtures::verdicts::Rate> {
        let rate =
            |verdict: &str, nominal: f64, trials: usize, hits: usize| fixtures::verdicts::Rate {
                verdict: verdict.to_owned(),
                replicas: replicas.to_owned(),
                kind: fixtures::verdicts::Kind::FalseAlarm,
                nominal,
                trials: trials as u64,
                hits: hits as u64,
                design_effect: 1.0,
            };
        vec![
            rate("global test", 0.05, self.fits, self.global_rejected),
            rate(
                "theodolite variance component",
                0.05,
                self.component_tested[0],
                self.component_rejected[0],
            ),
            rate(
                "ADC variance component",
                0.05,
                self.component_tested[1],
                self.component_rejected[1],
            ),
            fixtures::verdicts::Rate {
                design_effect: self.design_effect(
                    self.observations,
                    self.removed,
                    self.removed_squared,
                ),
                ..rate(
                    "w-test (a good reading removed)",
                    0.001,
                    self.observations,
                    self.removed,
                )
            },
            fixtures::verdicts::Rate {
                design_effect: self.design_effect(
                    self.fits * MC_PARAMETERS.len(),
                    self.intervals_missed,
                    self.intervals_missed_squared,
                ),
                ..rate(
                    "95 % interval of b, k, b_t, k_t, beta (missing the truth)",
                    0.05,
                    self.fits * MC_PARAMETERS.len(),
                    self.intervals_missed,
                )
            },
        ]
    }
}

/// How the Monte-Carlo weighs the theodolite readings.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Weights {
    /// The generating sigma of each station, taken as known.
    Generating,
    /// Each station's own sample sd on n - 1 dof (eq. 4).
    StationSd,
    /// Each station's variance moderated toward its session's (align's default).
    Moderated,
}

/// One reading of the acceptance design.
#[derive(Clone)]
struct McReading {
    station: usize,
    session: usize,
    dz_true_rad: f64,
    sigma_dz_rad: f64,
    ng_true: f64,
    sigma_sample_bits: f64,
    temperature_c: f64,
    tide_mgal: f64,
    time_s: f64,
}

/// The acceptance design: both days of esgt-2005 for acc1 (two temperature sets, the
/// paper's stations and readings, the simulator's station sigmas, 0.9-5.5 urad, and the
/// Earth tide at ESGT), with every other station of day 2 turned to the other side of the
/// vertical so that beta is estimable; counts from the truth's b, k, b_t, k_t and beta =
/// [`MC_BETA_RAD`].
fn acceptance_design(truth: &Truth) -> Vec<McReading> {
    let acc = &truth.accelerometer[0];
    let mut keys: Vec<(&str, &str)> = Vec::new();
    truth
        .reading
        .iter()
        .map(|r| {
            let key = (r.session.as_str(), r.station.as_str());
            if !keys.contains(&key) {
                keys.push(key);
            }
            let station = keys.iter().position(|k| *k == key).expect("key");
            let number: usize = r.station[1..].parse().expect("station number");
            let turned = r.session == "day2" && number.is_multiple_of(2);
            let dz = if turned {
                std::f64::consts::TAU - r.dz_true_rad
            } else {
                r.dz_true_rad
            };
            let t = r.temperature_c[0] - truth.t_ref_c;
            let g = truth.gravity_mgal + r.tide_mgal;
            let a = -g * (dz + MC_BETA_RAD).cos();
            McReading {
                station,
                session: usize::from(r.session == "day2"),
                dz_true_rad: dz,
                sigma_dz_rad: r.sigma_dz_rad,
                ng_true: (a - acc.b_mgal - acc.b_t_mgal_per_c * t)
                    / (acc.k_mgal_per_bit + acc.k_t_mgal_per_bit_per_c * t),
                sigma_sample_bits: r.sigma_sample_bits[0],
                temperature_c: r.temperature_c[0],
                tide_mgal: r.tide_mgal,
                time_s: r.time_gps_ns as f64 * 1e-9,
            }
        })
        .collect()
}

/// Samples a window holds (2.56 s at 31.25 Hz).
const WINDOW_SAMPLES: usize = 80;
/// Sampling interval, s.
const SAMPLE_S: f64 = 0.032;

/// One replica's ADC window means and their sds as align forms them: white samples of each
/// station's sd plus the coloured noise of `coloured` (flicker and random walk, one process
/// a session running through the readings in time order), the sd of a mean
/// sqrt(s^2/n + the coloured Allan variance at the window).
/// A window's mean, its sd and the sd's dof (None: known).
#[derive(Clone, Copy, Debug, Default)]
struct WindowMean {
    ng: f64,
    sigma: f64,
    dof: Option<f64>,
}

fn window_means(
    design: &[McReading],
    coloured: Option<fixtures::colour::ColouredNoise>,
    rng: &mut fixtures::rng::Rng,
) -> Vec<WindowMean> {
    let coloured = coloured.unwrap_or(fixtures::colour::ColouredNoise {
        bias_instability_bits: 0.0,
        random_walk_bits_per_sqrt_s: 0.0,
    });
    let mut out = vec![WindowMean::default(); design.len()];
    let half = WINDOW_SAMPLES as f64 * SAMPLE_S / 2.0;
    let sessions = design.iter().map(|r| r.session).max().map_or(0, |m| m + 1);
    for session in 0..sessions {
        let mut order: Vec<usize> = (0..design.len())
            .filter(|&i| design[i].session == session)
            .collect();
        if order.is_empty() {
            continue;
        }
        order.sort_by(|&a, &b| design[a].time_s.total_cmp(&design[b].time_s));
        let mut process = fixtures::colour::Coloured::new(coloured, rng);
        let mut now = design[order[0]].time_s - half;
        for i in order {
            let r = &design[i];
            let start = r.time_s - half;
            let mut drift = process.step((start - now).max(0.0), rng);
            let mut samples = [0.0; WINDOW_SAMPLES];
            for (k, x) in samples.iter_mut().enumerate() {
                if k > 0 {
                    drift = process.step(SAMPLE_S, rng);
                }
                *x = r.ng_true + r.sigma_sample_bits * rng.normal() + drift;
            }
            now = start + (WINDOW_SAMPLES - 1) as f64 * SAMPLE_S;
            let n = WINDOW_SAMPLES as f64;
            let m = samples.iter().sum::<f64>() / n;
            let var = samples.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
            let window_s = n * SAMPLE_S;
            // The window's own variance on n - 1 dof, the coloured part known: Satterthwaite's
            // dof, as align gives it.
            let (own, known) = (var / n, coloured.allan_variance(window_s));
            out[i] = WindowMean {
                ng: m,
                sigma: (own + known).sqrt(),
                dof: Some((n - 1.0) * ((own + known) / own).powi(2)),
            };
        }
    }
    out
}

/// The sd of a window mean at the generating noise: the white samples' over sqrt(n), and
/// the coloured noise's Allan variance at the window's length.
fn window_sigma(r: &McReading, coloured: Option<fixtures::colour::ColouredNoise>) -> f64 {
    let white = r.sigma_sample_bits.powi(2) / WINDOW_SAMPLES as f64;
    let known = coloured.map_or(0.0, |c| c.allan_variance(WINDOW_SAMPLES as f64 * SAMPLE_S));
    (white + known).sqrt()
}

/// The fit's options, told of `coloured` noise at its generating levels (as adjust is by
/// align's Allan deviation).
fn told_of(
    coloured: Option<fixtures::colour::ColouredNoise>,
) -> adjust::calibration::calibrate::FitOptions {
    adjust::calibration::calibrate::FitOptions {
        coloured: coloured.map(|c| adjust::lsq::correlated::ColouredAdc {
            bias_instability: c.bias_instability_bits,
            random_walk: c.random_walk_bits_per_sqrt_s,
            window_s: WINDOW_SAMPLES as f64 * SAMPLE_S,
            bias_instability_dof: None,
            random_walk_dof: None,
        }),
        ..adjust::calibration::calibrate::FitOptions::default()
    }
}

/// sigma_Dz and its dof per station as `weights` says (as align forms them), from the
/// replica's readings `dz`.
fn station_weights(design: &[McReading], dz: &[f64], weights: Weights) -> Vec<(f64, Option<f64>)> {
    let stations = design.iter().map(|r| r.station).max().unwrap_or(0) + 1;
    let mut by: Vec<Vec<f64>> = vec![Vec::new(); stations];
    for (r, d) in design.iter().zip(dz) {
        by[r.station].push(*d);
    }
    let own: Vec<(f64, f64)> = by
        .iter()
        .map(|v| {
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
            (var, n - 1.0)
        })
        .collect();
    let session_of: Vec<usize> = (0..stations)
        .map(|j| {
            design
                .iter()
                .find(|r| r.station == j)
                .expect("station")
                .session
        })
        .collect();
    let mut out = vec![(0.0, None); stations];
    for session in 0..=session_of.iter().copied().max().unwrap_or(0) {
        let idx: Vec<usize> = (0..stations)
            .filter(|&j| session_of[j] == session)
            .collect();
        if idx.is_empty() {
            continue;
        }
        let sub: Vec<(f64, f64)> = idx.iter().map(|&j| own[j]).collect();
        let m = align::weights::moderate(&sub).expect("stations with readings");
        let pooled: f64 = sub.iter().map(|x| x.1).sum();
        for (k, &j) in idx.iter().enumerate() {
            let generating = design.iter().find(|r| r.station == j).expect("station");
            out[j] = match weights {
                Weights::Generating => (generating.sigma_dz_rad, None),
                Weights::StationSd => (sub[k].0.sqrt(), Some(sub[k].1)),
                Weights::Moderated => {
                    let dof = if m.prior_dof.is_finite() {
                        m.prior_dof + sub[k].1
                    } else {
                        pooled
                    };
                    (m.variances[k].sqrt(), Some(dof))
                }
            };
        }
    }
    out
}

/// Each reading's sigma_Dz formed without it, as align forms it (its station's other
/// readings, less any gross enough to mask a blunder, under the session's prior, which is
/// not formed again); None with the generating sigmas.
fn left_out_weights(
    design: &[McReading],
    dz: &[f64],
    weights: Weights,
) -> Vec<Option<adjust::calibration::calibrate::LeftOut>> {
    if weights == Weights::Generating {
        return vec![None; design.len()];
    }
    let stations = design.iter().map(|r| r.station).max().unwrap_or(0) + 1;
    let mut by: Vec<Vec<usize>> = vec![Vec::new(); stations];
    for (i, r) in design.iter().enumerate() {
        by[r.station].push(i);
    }
    let own = |ks: &[usize]| -> (f64, f64) {
        let n = ks.len() as f64;
        if ks.len() < 2 {
            return (0.0, 0.0);
        }
        let mean = ks.iter().map(|&k| dz[k]).sum::<f64>() / n;
        let var = ks.iter().map(|&k| (dz[k] - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (var, n - 1.0)
    };
    let mut out = vec![None; design.len()];
    for session in 0..=design.iter().map(|r| r.session).max().unwrap_or(0) {
        let idx: Vec<usize> = (0..stations)
            .filter(|&j| by[j].first().is_some_and(|&k| design[k].session == session))
            .collect();
        if idx.is_empty() {
            continue;
        }
        let sub: Vec<(f64, f64)> = idx.iter().map(|&j| own(&by[j])).collect();
        let m = align::weights::moderate(&sub).expect("stations with readings");
        let pooled: f64 = sub.iter().map(|x| x.1).sum();
        let scale_floor = if weights == Weights::StationSd {
            0.0
        } else {
            m.prior_variance.sqrt()
        };
        for &j in &idx {
            let station_dz: Vec<f64> = by[j].iter().map(|&k| dz[k]).collect();
            let gross = align::weights::gross_readings(&station_dz, scale_floor);
            for &k in &by[j] {
                let others: Vec<usize> = by[j]
                    .iter()
                    .zip(&gross)
                    .filter(|&(&x, &g)| x != k && !g)
                    .map(|(&x, _)| x)
                    .collect();
                let (v, d) = own(&others);
                out[k] = Some(match weights {
                    Weights::StationSd => adjust::calibration::calibrate::LeftOut {
                        sigma_rad: v.sqrt(),
                        dof: Some(d),
                    },
                    _ if m.prior_dof.is_finite() => adjust::calibration::calibrate::LeftOut {
                        sigma_rad: ((m.prior_dof * m.prior_variance + d * v) / (m.prior_dof + d))
                            .sqrt(),
                        dof: Some(m.prior_dof + d),
                    },
                    _ => adjust::calibration::calibrate::LeftOut {
                        sigma_rad: m.prior_variance.sqrt(),
                        dof: Some(pooled),
                    },
                });
            }
        }
    }
    out
}

/// What a Monte-Carlo simulates beyond the acceptance design, and how it fits.
#[derive(Clone, Copy, Debug)]
struct McSetup {
    /// Coloured ADC noise added to the window means.
    coloured: Option<fixtures::colour::ColouredNoise>,
    /// What the fit is told of it (as adjust is by align's Allan deviation).
    told: Told,
    /// How the temperatures are read.
    thermometer: Thermometer,
    /// The variance components estimated (adjust's default).
    components: bool,
}

/// What a Monte-Carlo's fit is told of the coloured ADC noise.
#[derive(Clone, Copy, Debug)]
enum Told {
    /// Nothing: the noise is taken as white.
    Nothing,
    /// The levels that generated it.
    Generating,
    /// Other levels (as align may estimate them).
    #[cfg_attr(
        not(gravcal_monte_carlo),
        allow(dead_code, reason = "told only by a gated Monte-Carlo")
    )]
    These(fixtures::colour::ColouredNoise),
}

impl McSetup {
    /// White ADC noise, exact temperatures, the components estimated.
    const WHITE: McSetup = McSetup {
        coloured: None,
        told: Told::Nothing,
        thermometer: EXACT,
        components: true,
    };
}

/// `replicas` replicas of [`acceptance_design`] with fresh noise: Dz readings with the
/// station sigmas, ADC windows with white noise or `coloured` added ([`window_means`]),
/// sigma_Dz as `weights` says, temperatures read as `setup` says; the model with
/// temperature terms and misalignment fitted as adjust does, told of the coloured noise
/// as `setup.told` says.
fn monte_carlo(replicas: usize, weights: Weights, setup: McSetup) -> MonteCarlo {
    let McSetup {
        coloured,
        told,
        thermometer,
        components,
    } = setup;
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let design = acceptance_design(&truth);
    let acc = &truth.accelerometer[0];
    let mut rng = fixtures::rng::Rng::new(20_261_123, "monte-carlo");
    let mut est: Vec<[f64; 5]> = Vec::new();
    let mut sig: Vec<[f64; 5]> = Vec::new();
    let mut mahalanobis = Vec::new();
    let mut applied: Vec<[(f64, f64); 3]> = Vec::new();
    let (ng_lo, ng_hi) = design
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| {
            (a.min(r.ng_true), b.max(r.ng_true))
        });
    let (mut theodolite, mut adc) = (0.0, 0.0);
    let mut failed = Vec::new();
    let mut counts = VerdictCounts::default();
    let terms = MC_TERMS;
    for _ in 0..replicas {
        let dz: Vec<f64> = design
            .iter()
            .map(|r| r.dz_true_rad + r.sigma_dz_rad * rng.normal())
            .collect();
        let means = window_means(&design, coloured, &mut rng);
        let mut obs = replica_obs(&design, &dz, &means, weights);
        for o in &mut obs {
            o.temperature_c += thermometer.sd_c * rng.normal();
            o.sigma_temperature_c = if thermometer.given {
                thermometer.sd_c
            } else {
                0.0
            };
        }
        let options = adjust::calibration::calibrate::FitOptions {
            components,
            ..told_of(match told {
                Told::Nothing => None,
                Told::Generating => coloured,
                Told::These(c) => Some(c),
            })
        };
        let f = match adjust::calibration::calibrate::calibrate_with(
            &obs,
            terms,
            truth.gravity_mgal,
            &options,
        ) {
            Ok(f) => f,
            Err(e) => {
                failed.push(e.to_string());
                continue;
            }
        };
        let names: Vec<&str> = terms.names().iter().map(|n| n.name).collect();
        let at = |p: &str| names.iter().position(|n| *n == p).expect("parameter");
        est.push(MC_PARAMETERS.map(|p| f.values[at(p)]));
        sig.push(MC_PARAMETERS.map(|p| f.sigma(at(p))));
        let idx = MC_PARAMETERS.map(at);
        let n = f.values.len();
        let cov = |a: usize, b: usize| f.covariance[idx[a] * n + idx[b]];
        // Truth at the fit's reference temperature.
        let dt = f.t_ref_c - truth.t_ref_c;
        let p_true = [
            acc.b_mgal + acc.b_t_mgal_per_c * dt,
            acc.k_mgal_per_bit + acc.k_t_mgal_per_bit_per_c * dt,
            acc.b_t_mgal_per_c,
            acc.k_t_mgal_per_bit_per_c,
            MC_BETA_RAD,
        ];
        let delta: Vec<f64> = (0..5).map(|j| f.values[idx[j]] - p_true[j]).collect();
        let missed = (0..5)
            .filter(|&j| {
                let half = adjust::lsq::components::interval_95_sigmas(f.parameter_dof[idx[j]]);
                delta[j].abs() > half * f.sigma(idx[j])
            })
            .count();
        counts.intervals_missed += missed;
        counts.intervals_missed_squared += missed * missed;
        mahalanobis.push(quadratic_form_of_inverse(&cov, &delta));
        applied.push(MC_APPLY_POINTS.map(|(x, t_c)| {
            let ng = ng_lo + x * (ng_hi - ng_lo);
            let tau = t_c - f.t_ref_c;
            let j = [1.0, ng, tau, tau * ng];
            let err: f64 = (0..4).map(|a| j[a] * delta[a]).sum();
            let var: f64 = (0..4)
                .map(|a| (0..4).map(|b| j[a] * cov(a, b) * j[b]).sum::<f64>())
                .sum();
            (err, var.sqrt())
        }));
        theodolite += f.components.first().map_or(1.0, |c| c.estimate);
        adc += f.components.get(1).map_or(1.0, |c| c.estimate);
        counts.fits += 1;
        counts.global_rejected += usize::from(!f.global_test_passed());
        counts.observations += obs.len();
        counts.removed += f.removed.len();
        counts.removed_squared += f.removed.len().pow(2);
        for (k, c) in f.components.iter().take(2).enumerate() {
            let tested = c.not_estimable.is_none();
            counts.component_tested[k] += usize::from(tested);
            counts.component_rejected[k] += usize::from(tested && !c.test.passed());
        }
    }
    let n = est.len() as f64;
    let mean = |j: usize, v: &[[f64; 5]]| v.iter().map(|x| x[j]).sum::<f64>() / n;
    let sd = |j: usize| {
        let m = mean(j, &est);
        (est.iter().map(|x| (x[j] - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    };
    let truths = [acc.b_t_mgal_per_c, acc.k_t_mgal_per_bit_per_c, MC_BETA_RAD];
    MonteCarlo {
        sd_over_sigma: [0, 1, 2, 3, 4].map(|j| sd(j) / mean(j, &sig)),
        bias_z: [2, 3, 4].map(|j| (mean(j, &est) - truths[j - 2]) / (sd(j) / n.sqrt())),
        rejection_rate: counts.global_rejected as f64 / n,
        mahalanobis_ratio: mahalanobis.iter().sum::<f64>() / n / 5.0,
        applied_sd_over_sigma: [0, 1, 2].map(|k| {
            let e: Vec<f64> = applied.iter().map(|a| a[k].0).collect();
            let m = e.iter().sum::<f64>() / n;
            let sd = (e.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            sd / (applied.iter().map(|a| a[k].1).sum::<f64>() / n)
        }),
        mean_theodolite_component: theodolite / n,
        mean_adc_component: adc / n,
        component_rejection: counts.component_rejected.map(|k| k as f64 / n),
        mean_removed: counts.removed as f64 / n,
        failed,
        counts,
    }
}

fn print_monte_carlo(label: &str, replicas: usize, m: &MonteCarlo) {
    let ratios: Vec<String> = MC_PARAMETERS
        .iter()
        .zip(m.sd_over_sigma)
        .map(|(p, r)| format!("{p} {r:.3}"))
        .collect();
    eprintln!(
        "monte carlo, {label}, {replicas} replicas: sd/sigma {}; Mahalanobis / dof {:.3}; \
         applied sd/sigma {:.3} {:.3} {:.3}; global test rejects {:.1} %; \
         components: theodolite {:.3} (its test rejects {:.1} %), ADC {:.3} ({:.1} %); bias/se of b_t, k_t, beta {:.1} {:.1} {:.1}; \
         {:.2} observations removed a replica; {} fits failed{}",
        ratios.join(", "),
        m.mahalanobis_ratio,
        m.applied_sd_over_sigma[0],
        m.applied_sd_over_sigma[1],
        m.applied_sd_over_sigma[2],
        100.0 * m.rejection_rate,
        m.mean_theodolite_component,
        100.0 * m.component_rejection[0],
        m.mean_adc_component,
        100.0 * m.component_rejection[1],
        m.bias_z[0],
        m.bias_z[1],
        m.bias_z[2],
        m.mean_removed,
        m.failed.len(),
        m.failed
            .first()
            .map(|e| format!(" (first: {e})"))
            .unwrap_or_default()
    );
}

/// The acceptance test of the default configuration (docs/model.md 6.1-6.3): moderated station
/// variances, variance components, the coloured ADC noise of esgt-2005 propagated, Earth tide.
/// With n replicas the standard error of an sd ratio is about 1/sqrt(2n) and that of a
/// rejection rate sqrt(0.05 0.95/n): `ratio` and `rate` give the bounds.
fn accept(replicas: usize, ratio: f64, rate: (f64, f64)) {
    let m = monte_carlo(
        replicas,
        Weights::Moderated,
        McSetup {
            coloured: Some(fixtures::catalog::QA3000_COLOURED),
            told: Told::Generating,
            ..McSetup::WHITE
        },
    );
    print_monte_carlo("default, coloured ADC noise", replicas, &m);
    assert!(m.failed.is_empty(), "{:?}", m.failed);
    for (p, r) in MC_PARAMETERS.iter().zip(m.sd_over_sigma) {
        assert!((r - 1.0).abs() <= ratio, "sd({p})/sigma_{p} = {r}");
    }
    // The whole covariance, correlations too (mean of chi2(5)/5 has se 0.63/sqrt(n)), and
    // the applied function's sigma where apply reports it.
    assert!(
        (m.mahalanobis_ratio - 1.0).abs() <= ratio,
        "Mahalanobis / dof = {}",
        m.mahalanobis_ratio
    );
    for (point, r) in MC_APPLY_POINTS.iter().zip(m.applied_sd_over_sigma) {
        assert!(
            (r - 1.0).abs() <= ratio,
            "applied at {point:?}: sd/sigma = {r}"
        );
    }
    for (p, z) in ["b_t", "k_t", "beta"].iter().zip(m.bias_z) {
        assert!(z.abs() < 4.0, "{p} biased by {z} standard errors");
    }
    assert!(
        (rate.0..=rate.1).contains(&m.rejection_rate),
        "global test rejects {}",
        m.rejection_rate
    );
    // The variance components average 1 when the weights are right (the ADC's averaged
    // 0.77 and failed its test in 73 % of replicas while the within-station excess took
    // the points' covariance for the window means'), and their tests hold their level as
    // the global test does (the ADC's rejected 7.8 % of 4000 replicas while its reference
    // took each window's sd, from 80 samples, as known).
    for ((group, c), r) in [
        ("theodolite", m.mean_theodolite_component),
        ("ADC", m.mean_adc_component),
    ]
    .into_iter()
    .zip(m.component_rejection)
    {
        assert!((c - 1.0).abs() <= 0.05, "mean {group} component {c}");
        assert!(
            (rate.0..=rate.1).contains(&r),
            "{group} component's test rejects {r}"
        );
    }
}

/// The fast acceptance test, in CI: 1000 replicas; sd/sigma within 1 +/- 0.07 and rejection
/// 2.9-7.1 % (3 standard errors each).
#[test]
fn monte_carlo_default_is_honest_fast() {
    accept(1000, 0.07, (0.029, 0.071));
}

/// The full acceptance test (GRAVCAL_MONTE_CARLO=1): 4000 replicas against the issue's
/// bounds (sd/sigma 1 +/- 0.05, rejection 3.5-6.5 %: 4.5 and 4.4 standard errors, so that a
/// method off by 2 % still passes and one off by 5 % fails). Prints, for the record, 2000
/// replicas each of: white ADC noise with the default, with eq. 4 and with the generating
/// sigmas, and the coloured noise not propagated. Compiled only with GRAVCAL_MONTE_CARLO
/// set (adjust/build.rs), so a run without it does not count it as passed.
#[cfg(gravcal_monte_carlo)]
#[test]
fn monte_carlo_default_is_honest_full() {
    for (label, w) in [
        ("white ADC noise, default", Weights::Moderated),
        ("white ADC noise, eq. 4 station sd", Weights::StationSd),
        ("white ADC noise, generating sigmas", Weights::Generating),
    ] {
        print_monte_carlo(label, 2000, &monte_carlo(2000, w, McSetup::WHITE));
    }
    print_monte_carlo(
        "coloured ADC noise not propagated",
        2000,
        &monte_carlo(
            2000,
            Weights::Moderated,
            McSetup {
                coloured: Some(fixtures::catalog::QA3000_COLOURED),
                ..McSetup::WHITE
            },
        ),
    );
    accept(4000, 0.05, (0.035, 0.065));
}

/// The ADC component when the fit is told less coloured noise than there is (docs/model.md
/// 6.8): esgt-2005's coloured noise generated (B = 0.75 counts, K = 0.01 counts sqrt(Hz)),
/// the fit told the generating levels, the levels align estimates on esgt-2005 for acc1 (B
/// 0.65, no random walk found), or nothing (GRAVCAL_MONTE_CARLO=1). Told the generating
/// levels, the ADC component averages 1 within 0.05; told less, its test sees it: above
/// 1.05 and rejecting more than its 5 % when told align's estimate, above 1.2 told nothing.
#[cfg(gravcal_monte_carlo)]
#[test]
fn adc_component_when_the_noise_is_under_told() {
    let estimated = fixtures::colour::ColouredNoise {
        bias_instability_bits: 0.65,
        random_walk_bits_per_sqrt_s: 0.0,
    };
    for (label, told) in [
        ("told the generating levels", Told::Generating),
        ("told align's estimate on esgt-2005", Told::These(estimated)),
        ("told nothing", Told::Nothing),
    ] {
        let setup = McSetup {
            coloured: Some(fixtures::catalog::QA3000_COLOURED),
            told,
            ..McSetup::WHITE
        };
        let m = monte_carlo(1000, Weights::Moderated, setup);
        print_monte_carlo(label, 1000, &m);
        let (adc, rejects) = (m.mean_adc_component, m.component_rejection[1]);
        match told {
            Told::Generating => assert!((adc - 1.0).abs() <= 0.05, "{label}: {adc}"),
            Told::These(_) => assert!(adc > 1.05 && rejects > 0.1, "{label}: {adc} {rejects}"),
            Told::Nothing => assert!(adc > 1.2, "{label}: {adc}"),
        }
    }
}

/// A thermometer of 0.1 K noise a reading (a cheap thermistor; acc1's b_t of 14 mGal/K
/// makes that 1.4 mGal, as large as the theodolite's share at many stations), its sd given:
/// the adjustment takes the temperatures as observations and its sigmas hold (sd/sigma and
/// the Mahalanobis mean within 1 +/- 0.07, 3 se at 1000 replicas; the global test
/// 2.9-7.1 %; with GRAVCAL_MONTE_CARLO, which docs/model.md quotes; CI runs 400 replicas
/// at 3 se, [`rms_z_bound`]). The adjustment alone, at the a-priori weights: with the variance components
/// estimated as well, the theodolite's on few dof (a quarter of the stations' redundancy:
/// the temperatures take half of each station's variance) leaves the sigmas of b and k 5-7 %
/// small (printed for the record, with the same temperatures taken as exact; docs/model.md
/// 6.1).
#[test]
fn monte_carlo_with_a_noisy_thermometer() {
    let noisy = Thermometer {
        sd_c: 0.1,
        given: true,
    };
    let setup = McSetup {
        thermometer: noisy,
        components: false,
        ..McSetup::WHITE
    };
    let replicas = replicas_of(400, 1000);
    let m = monte_carlo(replicas, Weights::Generating, setup);
    print_monte_carlo(
        "0.1 K thermometer noise, given, a-priori weights",
        replicas,
        &m,
    );
    assert!(m.failed.is_empty(), "{:?}", m.failed);
    let (bound, n) = (rms_z_bound(replicas), replicas as f64);
    for (p, r) in MC_PARAMETERS.iter().zip(m.sd_over_sigma) {
        assert!((r - 1.0).abs() <= bound, "sd({p})/sigma_{p} = {r}");
    }
    assert!(
        (m.mahalanobis_ratio - 1.0).abs() <= bound,
        "{}",
        m.mahalanobis_ratio
    );
    let rate_se = (0.05 * 0.95 / n).sqrt();
    assert!(
        (m.rejection_rate - 0.05).abs() <= 3.0 * rate_se,
        "{}",
        m.rejection_rate
    );
    for (label, setup) in [
        (
            "given, components estimated",
            McSetup {
                components: true,
                ..setup
            },
        ),
        (
            "taken as exact",
            McSetup {
                thermometer: Thermometer {
                    given: false,
                    ..noisy
                },
                ..setup
            },
        ),
    ] {
        let n = replicas_of(100, 200);
        let m = monte_carlo(n, Weights::Generating, setup);
        print_monte_carlo(&format!("0.1 K thermometer noise, {label}"), n, &m);
    }
}

/// What estimating the theodolite's component costs (docs/model.md 6.1), 1000 replicas
/// each of the acceptance design with white noise and exact temperatures, the components
/// estimated and held at 1, moderated and generating station sigmas; then a 0.03 K
/// thermometer, given, the components estimated. Printed for the record; asserted: held
/// at 1, the Mahalanobis mean is 1 within 3 se (0.06). Compiled only with
/// GRAVCAL_MONTE_CARLO set (adjust/build.rs).
#[cfg(gravcal_monte_carlo)]
#[test]
fn what_an_estimated_component_costs() {
    for weights in [Weights::Moderated, Weights::Generating] {
        for components in [true, false] {
            let setup = McSetup {
                components,
                ..McSetup::WHITE
            };
            let m = monte_carlo(1000, weights, setup);
            print_monte_carlo(
                &format!("{weights:?} station sigmas, components estimated: {components}"),
                1000,
                &m,
            );
            if !components {
                assert!(
                    (m.mahalanobis_ratio - 1.0).abs() < 0.06,
                    "{}",
                    m.mahalanobis_ratio
                );
            }
        }
    }
    let setup = McSetup {
        thermometer: Thermometer {
            sd_c: 0.03,
            given: true,
        },
        ..McSetup::WHITE
    };
    let m = monte_carlo(400, Weights::Generating, setup);
    print_monte_carlo(
        "0.03 K thermometer noise, given, components estimated",
        400,
        &m,
    );
}

/// Baarda's non-centrality for alpha 0.001 (two-sided) and power 0.80.
const DELTA0: f64 = 4.13;

/// What the data snooping did over a Monte-Carlo.
struct Snooping {
    /// Observations of good readings tested.
    good: usize,
    /// Good observations removed.
    good_removed: usize,
    /// Replicas with a blunder at the MDB.
    blundered: usize,
    /// Of them, where the blunder was removed.
    found: usize,
}

/// Which blunder a snooping replica carries.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Blunder {
    /// None: every removal is a false one.
    None,
    /// One reading moved by Baarda's MDB for a known sigma (DELTA0).
    KnownSigmaMdb,
    /// One reading moved by the MDB at the dof its test runs on
    /// ([`adjust::calibration::calibrate::mdb_noncentrality`]).
    MdbAtItsDof,
}

/// `replicas` replicas of [`acceptance_design`] (sigma_Dz as `weights` says, the model of
/// [`monte_carlo`], ADC noise white or with `coloured` added and propagated as adjust is
/// told of it); with a `blunder`, one reading a replica (a random one) moved by its
/// minimal detectable bias in Dz, sds of its misclosure over sqrt(r).
/// The station variances are formed from the readings as they are, the blunder included,
/// as align forms them.
fn snooping_monte_carlo(
    replicas: usize,
    weights: Weights,
    blunder: Blunder,
    coloured: Option<fixtures::colour::ColouredNoise>,
) -> Snooping {
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let design = acceptance_design(&truth);
    let acc = &truth.accelerometer[0];
    let mut rng = fixtures::rng::Rng::new(20_261_124, "snooping");
    let terms = MC_TERMS;
    let g = truth.gravity_mgal;
    let mut out = Snooping {
        good: 0,
        good_removed: 0,
        blundered: 0,
        found: 0,
    };
    let n = design.len();
    // Redundancy numbers from a noise-free fit at the generating sigmas (they hardly depend
    // on the noise).
    let redundancy: Vec<f64> = {
        let obs = replica_obs(
            &design,
            &design.iter().map(|r| r.dz_true_rad).collect::<Vec<_>>(),
            &design
                .iter()
                .map(|r| WindowMean {
                    ng: r.ng_true,
                    sigma: window_sigma(r, coloured),
                    dof: None,
                })
                .collect::<Vec<_>>(),
            Weights::Generating,
        );
        let f = adjust::calibration::calibrate::calibrate_with(
            &obs,
            terms,
            g,
            &adjust::calibration::calibrate::FitOptions::default(),
        )
        .expect("noise-free fit");
        let mut r = vec![1.0; n];
        for x in &f.residuals {
            r[x.index] = x.redundancy;
        }
        r
    };
    for _ in 0..replicas {
        let mut dz: Vec<f64> = design
            .iter()
            .map(|r| r.dz_true_rad + r.sigma_dz_rad * rng.normal())
            .collect();
        let target = if blunder != Blunder::None {
            let j = rng.below(n as u64) as usize;
            let r = &design[j];
            let slope = g * (r.dz_true_rad + MC_BETA_RAD).sin().abs();
            let sigma_ng = window_sigma(r, coloured);
            let q_dz = (slope * r.sigma_dz_rad).powi(2);
            let q_ng = (acc.k_mgal_per_bit * sigma_ng).powi(2);
            let q = q_dz + q_ng;
            // The reading's test runs on the dof of its left-out sigma (before the blunder)
            // and of its window's sd, carried by their shares of the condition's variance.
            let own = r.sigma_sample_bits.powi(2) / WINDOW_SAMPLES as f64;
            let ng_dof = (WINDOW_SAMPLES - 1) as f64 * (sigma_ng.powi(2) / own).powi(2);
            let dof = left_out_weights(&design, &dz, weights)[j]
                .and_then(|l| l.dof)
                .map(|d| q * q / (q_dz * q_dz / d + q_ng * q_ng / ng_dof));
            let delta = if blunder == Blunder::MdbAtItsDof {
                adjust::calibration::calibrate::mdb_noncentrality(dof)
            } else {
                DELTA0
            };
            let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
            dz[j] += sign * delta * (q / redundancy[j]).sqrt() / slope;
            Some(j)
        } else {
            None
        };
        let means = window_means(&design, coloured, &mut rng);
        let obs = replica_obs(&design, &dz, &means, weights);
        let f = adjust::calibration::calibrate::calibrate_with(&obs, terms, g, &told_of(coloured))
            .expect("fit");
        out.good += n - usize::from(target.is_some());
        for r in &f.removed {
            if Some(r.index) == target {
                out.found += 1;
            } else {
                out.good_removed += 1;
            }
        }
        out.blundered += usize::from(target.is_some());
    }
    out
}

/// The observations of one replica: readings `dz`, window means and sds `means`, sigma_Dz
/// as `weights` says.
fn replica_obs(
    design: &[McReading],
    dz: &[f64],
    means: &[WindowMean],
    weights: Weights,
) -> Vec<adjust::calibration::calibrate::Obs> {
    let w = station_weights(design, dz, weights);
    let left_out = left_out_weights(design, dz, weights);
    design
        .iter()
        .zip(dz)
        .zip(means)
        .zip(left_out)
        .map(
            |(((r, &dz_rad), mean), sigma_dz_left_out)| adjust::calibration::calibrate::Obs {
                dz_rad,
                sigma_dz_rad: w[r.station].0,
                sigma_dz_dof: w[r.station].1,
                sigma_dz_left_out,
                station: r.station,
                session: r.session,
                time_s: r.time_s - design[0].time_s,
                roll_rad: 0.0,
                ng: mean.ng,
                sigma_ng: mean.sigma,
                sigma_ng_dof: mean.dof,
                temperature_c: r.temperature_c,
                sigma_temperature_c: 0.0,
                tide_mgal: r.tide_mgal,
            },
        )
        .collect()
}

/// The w-test held to its level (docs/model.md 6.1): on replicas without blunders the share
/// of good observations removed is alpha = 0.001 within 3 standard errors; with one
/// reading a replica moved by its minimal detectable bias (at the dof its test runs on) it
/// is found in 0.8 +/- 0.1 of the replicas. With GRAVCAL_MONTE_CARLO (1000 replicas, not
/// 200), printed for the record as well: the generating sigmas (Baarda's own setting), and
/// the power at Baarda's known-sigma MDB, which a test on estimated variances cannot reach.
#[test]
fn snooping_holds_its_level() {
    let full = full_studies();
    let replicas = replicas_of(200, 1000);
    let mut checked = Vec::new();
    for (label, weights) in [
        ("generating sigmas", Weights::Generating),
        ("station sd (eq. 4)", Weights::StationSd),
        ("moderated station variances", Weights::Moderated),
    ] {
        let held = weights != Weights::Generating;
        if !held && !full {
            continue;
        }
        let clean = snooping_monte_carlo(replicas, weights, Blunder::None, None);
        let rate = clean.good_removed as f64 / clean.good as f64;
        let se = (0.001 * 0.999 / clean.good as f64).sqrt();
        let power = |blunder| {
            let dirty = snooping_monte_carlo(replicas, weights, blunder, None);
            dirty.found as f64 / dirty.blundered as f64
        };
        let at_its_dof = power(Blunder::MdbAtItsDof);
        let known_sigma = if full {
            format!("{:.3}", power(Blunder::KnownSigmaMdb))
        } else {
            "(not run; GRAVCAL_MONTE_CARLO=1)".to_owned()
        };
        let power_se = (0.8 * 0.2 / replicas as f64).sqrt();
        eprintln!(
            "snooping, {label}, {replicas} replicas: good observations removed {} of {} \
             ({rate:.5}; alpha 0.001, se {se:.5}); a blunder found in {at_its_dof:.3} of the \
             replicas at the MDB for its dof, {known_sigma} at Baarda's known-sigma MDB (se \
             {power_se:.3})",
            clean.good_removed, clean.good,
        );
        if held {
            checked.push((label, rate, se, at_its_dof));
        }
    }
    for (label, rate, se, power) in checked {
        assert!(
            (rate - 0.001).abs() <= 3.0 * se,
            "{label}: false removals {rate}"
        );
        assert!(
            (power - 0.8).abs() <= 0.1,
            "{label}: power at the MDB {power}"
        );
    }
}

/// Replicas of [`every_verdict_holds_its_rate`]: GRAVCAL_VERDICT_REPLICAS, or 300 (CI's
/// subset).
fn verdict_replicas() -> usize {
    std::env::var("GRAVCAL_VERDICT_REPLICAS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

/// Every verdict of a fit at its error rate (docs/model.md 6.8), on white replicas and on
/// replicas with esgt-2005's coloured ADC noise (propagated, as align tells adjust of it),
/// default weights and components: the global test, the theodolite's and the ADC's
/// variance-component tests and the w-test's false removals from the acceptance
/// Monte-Carlo, which carries no blunder; the w-test's power from replicas with one reading
/// moved by its MDB at the dof its test runs on; and, as a control, the w-test's false
/// removals on the same replicas weighed at their generating sigmas. Each rate is printed
/// as the line `cargo xtask verdicts` gathers (with the noise-term selection's from align)
/// and held to its rule ([`fixtures::verdicts::Rate::holds`]: a false alarm within 3
/// standard errors of its level, the power 0.8 +/- 0.1).
#[test]
fn every_verdict_holds_its_rate() {
    use fixtures::verdicts::{Kind, Rate};
    let replicas = verdict_replicas();
    let mut rates = Vec::new();
    for (label, coloured) in [
        ("white ADC noise", None),
        (
            "coloured ADC noise (esgt-2005's)",
            Some(fixtures::catalog::QA3000_COLOURED),
        ),
    ] {
        let setup = McSetup {
            coloured,
            told: Told::Generating,
            ..McSetup::WHITE
        };
        let m = monte_carlo(replicas, Weights::Moderated, setup);
        assert!(m.failed.is_empty(), "{label}: {:?}", m.failed);
        rates.extend(m.counts.rates(label));
        // The control: the same replicas (the same draws) weighed at their generating
        // sigmas, Baarda's own setting, so that a w-test rate off its level is told apart
        // into the test's and the estimated weights' part.
        let control = monte_carlo(replicas, Weights::Generating, setup);
        assert!(control.failed.is_empty(), "{label}: {:?}", control.failed);
        rates.extend(
            control
                .counts
                .rates(label)
                .into_iter()
                .filter(|r| r.verdict.starts_with("w-test"))
                .map(|r| Rate {
                    verdict: "w-test at the generating sigmas (control)".to_owned(),
                    ..r
                }),
        );
        let s = snooping_monte_carlo(replicas, Weights::Moderated, Blunder::MdbAtItsDof, coloured);
        rates.push(Rate {
            verdict: "w-test (a reading moved by its MDB found)".to_owned(),
            replicas: label.to_owned(),
            kind: Kind::Power,
            nominal: 0.8,
            trials: s.blundered as u64,
            hits: s.found as u64,
            design_effect: 1.0,
        });
    }
    let failed: Vec<String> = rates
        .iter()
        .filter(|r| !r.report())
        .map(ToString::to_string)
        .collect();
    assert!(failed.is_empty(), "{failed:#?}");
}

/// What the per-session study varies, one thing at a time.
#[derive(Clone, Copy, Debug)]
enum Varied {
    /// esgt-2005's day as simulated: its accelerometer's temperature moving by a few mK
    /// over the half hour, which a per-session linear model does not include.
    AsSimulated,
    /// The temperature held at the day's mean: nothing the model does not include.
    ConstantTemperature,
    /// The temperature held, and every other station's readings left out (half the
    /// stations, so the theodolite's component on about half the dof).
    HalfTheStations,
    /// The temperature held, the stations' theodolite sds spread evenly in log over a
    /// factor 4 about the day's median (redrawn each replica).
    StationSpread,
    /// The temperature held, each station's ADC noise drawn from 4.5 to 20 counts a sample.
    AdcPerStation,
    /// The temperature held, 0.6 % of the readings (at random) 25 arcsec off.
    Blunders,
    /// The last three together, the temperature held.
    Together,
    /// As simulated, with a wander added: a random walk reaching 5 mK sd in 50 minutes.
    Wander,
    /// Everything of the independent simulation: the wander, the station spread, the ADC
    /// noise per station and the blunders.
    All,
}

/// rms of (estimate - truth) / sigma for b and k, the global test's rejection rate and b's
/// mean dof over `replicas` per-session linear fits of esgt-2005's day 1 for accelerometer
/// `acc` (0-based), default weights and components, white ADC noise. The truth is b and k at the
/// day's mean temperature: a temperature moving within the day is, for this model, an error
/// it does not carry.
fn per_session_study(replicas: usize, acc: usize, varied: Varied) -> ([f64; 2], f64, f64) {
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let a = &truth.accelerometer[acc];
    let mut stations: Vec<&str> = Vec::new();
    let day: Vec<&fixtures::write::ReadingTruth> = truth
        .reading
        .iter()
        .filter(|r| r.session == "day1")
        .filter(|r| {
            if !stations.contains(&r.station.as_str()) {
                stations.push(&r.station);
            }
            let index = stations.iter().position(|k| *k == r.station).unwrap_or(0);
            !matches!(varied, Varied::HalfTheStations) || index % 2 == 0
        })
        .collect();
    let mean_t = day.iter().map(|r| r.temperature_c[acc]).sum::<f64>() / day.len() as f64;
    let mut rng = fixtures::rng::Rng::new(20_261_126, "per-session study");
    let want = b_and_k_at(a, mean_t - truth.t_ref_c);
    let (mut z2, mut rejected, mut n, mut dof) = ([0.0; 2], 0, 0, 0.0);
    for _ in 0..replicas {
        let design = day_design(&truth, &day, acc, varied, &mut rng);
        let Some(f) = study_fit(design, varied, &mut rng, LINEAR, truth.gravity_mgal) else {
            continue;
        };
        for j in 0..2 {
            z2[j] += ((f.values[j] - want[j]) / f.sigma(j)).powi(2);
        }
        rejected += usize::from(!f.global_test_passed());
        dof += f.parameter_dof[0].unwrap_or(f64::INFINITY);
        n += 1;
    }
    let n = f64::from(u32::try_from(n).unwrap_or(u32::MAX));
    (
        z2.map(|s| (s / n).sqrt()),
        f64::from(u32::try_from(rejected).unwrap_or(u32::MAX)) / n,
        dof / n,
    )
}

/// A linear model without temperature terms or misalignment.
const LINEAR: adjust::calibration::model::Terms = adjust::calibration::model::Terms {
    order: 1,
    temperature: false,
    misalignment: adjust::calibration::model::Misalignment::None,
};

/// One replica's design of the day's readings `day` for accelerometer `acc` (0-based):
/// each reading's true counts at its temperature as `varied` says (as simulated, plus the
/// wander where it asks for it, drawn from `rng`; or held at the day's mean).
fn day_design(
    truth: &Truth,
    day: &[&fixtures::write::ReadingTruth],
    acc: usize,
    varied: Varied,
    rng: &mut fixtures::rng::Rng,
) -> Vec<McReading> {
    let a = &truth.accelerometer[acc];
    let mean_t = day.iter().map(|r| r.temperature_c[acc]).sum::<f64>() / day.len() as f64;
    let t0 = day[0].time_gps_ns;
    let mut keys: Vec<&str> = Vec::new();
    // The wander: a random walk of variance (5 mK)^2 per 50 minutes, from 0.
    let mut wander = 0.0;
    let mut last_s = 0.0;
    day.iter()
        .map(|r| {
            let time_s = (r.time_gps_ns - t0) as f64 * 1e-9;
            if matches!(varied, Varied::Wander | Varied::All) {
                wander += WANDER_C_PER_SQRT_S * (time_s - last_s).sqrt() * rng.normal();
            }
            last_s = time_s;
            let t = match varied {
                Varied::AsSimulated | Varied::Wander | Varied::All => r.temperature_c[acc] + wander,
                _ => mean_t,
            } - truth.t_ref_c;
            if !keys.contains(&r.station.as_str()) {
                keys.push(&r.station);
            }
            let g = truth.gravity_mgal + r.tide_mgal;
            McReading {
                station: keys.iter().position(|k| *k == r.station).unwrap_or(0),
                session: 0,
                dz_true_rad: r.dz_true_rad,
                sigma_dz_rad: r.sigma_dz_rad,
                ng_true: (-g * r.dz_true_rad.cos() - a.b_mgal - a.b_t_mgal_per_c * t)
                    / (a.k_mgal_per_bit + a.k_t_mgal_per_bit_per_c * t),
                sigma_sample_bits: r.sigma_sample_bits[acc],
                temperature_c: r.temperature_c[acc],
                tide_mgal: r.tide_mgal,
                time_s,
            }
        })
        .collect()
}

/// The repeatability test's false alarms (docs/model.md 6.9): esgt-2005's day 1 for acc1,
/// its temperature held, fitted twice from independent draws (two sessions of one truth),
/// the homogeneity test of their (b, k) at the fits' sigmas; its rejections at the 5 %
/// level, printed as `cargo xtask verdicts` gathers them and held to 3 standard errors.
/// Replicas: [`verdict_replicas`] pairs.
#[test]
fn repeatability_holds_its_level() {
    use fixtures::verdicts::{Kind, Rate};
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let day: Vec<&fixtures::write::ReadingTruth> = truth
        .reading
        .iter()
        .filter(|r| r.session == "day1")
        .collect();
    let mut rng = fixtures::rng::Rng::new(20_261_129, "repeatability study");
    let design = day_design(&truth, &day, 0, Varied::ConstantTemperature, &mut rng);
    let replicas = verdict_replicas();
    let (mut trials, mut hits) = (0u64, 0u64);
    for _ in 0..replicas {
        let estimates: Option<Vec<adjust::calibration::repeatability::Estimate>> = (0..2)
            .map(|_| {
                let f = study_fit(
                    design.clone(),
                    Varied::ConstantTemperature,
                    &mut rng,
                    LINEAR,
                    truth.gravity_mgal,
                )?;
                let c = f.correlation();
                Some(adjust::calibration::repeatability::Estimate::new(
                    [f.values[0], f.values[1]],
                    [f.sigma(0), f.sigma(1)],
                    c[0][1],
                ))
            })
            .collect();
        let Some(h) = estimates.and_then(|e| adjust::calibration::repeatability::homogeneity(&e))
        else {
            continue;
        };
        trials += 1;
        hits += u64::from(!h.passed());
    }
    assert!(
        trials as usize >= replicas * 9 / 10,
        "{trials} of {replicas} fitted"
    );
    let rate = Rate {
        verdict: "repeatability of b and k between sessions".to_owned(),
        replicas: "two sessions of one truth (esgt-2005 day 1, acc1, temperature held)".to_owned(),
        kind: Kind::FalseAlarm,
        nominal: adjust::calibration::repeatability::LEVEL,
        trials,
        hits,
        design_effect: 1.0,
    };
    assert!(rate.report(), "{rate}");
}

/// The truth's b and k of accelerometer `a` at `tau` degC from its reference temperature.
fn b_and_k_at(a: &fixtures::scenario::Accelerometer, tau: f64) -> [f64; 2] {
    [
        a.b_mgal + a.b_t_mgal_per_c * tau,
        a.k_mgal_per_bit + a.k_t_mgal_per_bit_per_c * tau,
    ]
}

/// How many of esgt-2005's accelerometers a study runs: acc1 in CI, all three with
/// GRAVCAL_MONTE_CARLO (their z hardly differ).
fn studied_accelerometers() -> usize {
    if full_studies() { 3 } else { 1 }
}

/// Whether GRAVCAL_MONTE_CARLO asks for the studies' full counts (the runs docs/model.md
/// and docs/choices.md quote) rather than CI's subset.
fn full_studies() -> bool {
    std::env::var("GRAVCAL_MONTE_CARLO").is_ok()
}

/// Replicas of a study whose figures docs/model.md quotes: `full` with GRAVCAL_MONTE_CARLO
/// set (the run the figures come from), `ci` without (CI's subset, the same random streams'
/// first replicas).
fn replicas_of(ci: usize, full: usize) -> usize {
    if full_studies() { full } else { ci }
}

/// The bound on an rms z (or an sd ratio) over `replicas`: the issues' 0.07, or 3 standard
/// errors (1/sqrt(2n) each) where the replicas are too few for it (0.12 at 300).
fn rms_z_bound(replicas: usize) -> f64 {
    0.07_f64.max(3.0 / (2.0 * replicas as f64).sqrt())
}

/// The wander of the studies: a random walk of variance (5 mK)^2 per 50 minutes, degC per
/// sqrt(s).
const WANDER_C_PER_SQRT_S: f64 = 0.005 / 54.772_255_750_516_61;

/// A study's Dz readings: each at its station's sd, and with `varied`'s blunders (0.6 % of
/// the readings, at random, 25 arcsec off either way).
fn study_readings(design: &[McReading], varied: Varied, rng: &mut fixtures::rng::Rng) -> Vec<f64> {
    let blunders = matches!(varied, Varied::Blunders | Varied::Together | Varied::All);
    design
        .iter()
        .map(|r| {
            let blunder = if blunders && rng.uniform() < 0.006 {
                (25.0f64 / 3600.0).to_radians() * if rng.uniform() < 0.5 { -1.0 } else { 1.0 }
            } else {
                0.0
            };
            r.dz_true_rad + r.sigma_dz_rad * rng.normal() + blunder
        })
        .collect()
}

/// One study replica's fit: the stations varied, the readings and window means drawn
/// (white ADC noise), moderated weights; None where the fit fails.
fn study_fit(
    design: Vec<McReading>,
    varied: Varied,
    rng: &mut fixtures::rng::Rng,
    terms: adjust::calibration::model::Terms,
    g_mgal: f64,
) -> Option<adjust::calibration::calibrate::CalibrationSolution> {
    let obs = study_obs(design, varied, rng);
    adjust::calibration::calibrate::calibrate(&obs, terms, g_mgal).ok()
}

/// One study replica's observations: the stations varied, the readings and window means
/// drawn (white ADC noise), moderated weights.
fn study_obs(
    design: Vec<McReading>,
    varied: Varied,
    rng: &mut fixtures::rng::Rng,
) -> Vec<adjust::calibration::calibrate::Obs> {
    let design = vary_stations(design, varied, rng);
    let dz = study_readings(&design, varied, rng);
    let means = window_means(&design, None, rng);
    replica_obs(&design, &dz, &means, Weights::Moderated)
}

/// The per-session design's stations as `varied` says: the theodolite's sds spread over a
/// factor 4, or each station's ADC noise from 4.5 to 20 counts a sample (both for
/// `Together`); otherwise as they are.
fn vary_stations(
    mut design: Vec<McReading>,
    varied: Varied,
    rng: &mut fixtures::rng::Rng,
) -> Vec<McReading> {
    let stations = design.iter().map(|r| r.station).max().map_or(0, |m| m + 1);
    let together = matches!(varied, Varied::Together | Varied::All);
    if together || matches!(varied, Varied::StationSpread) {
        let mut sds: Vec<f64> = design.iter().map(|r| r.sigma_dz_rad).collect();
        sds.sort_unstable_by(f64::total_cmp);
        let median = sds[sds.len() / 2];
        let factor: Vec<f64> = (0..stations)
            .map(|_| 2f64.powf(rng.range(-1.0, 1.0)))
            .collect();
        for r in &mut design {
            r.sigma_dz_rad = median * factor[r.station];
        }
    }
    if together || matches!(varied, Varied::AdcPerStation) {
        let sd: Vec<f64> = (0..stations).map(|_| rng.range(4.5, 20.0)).collect();
        for r in &mut design {
            r.sigma_sample_bits = sd[r.station];
        }
    }
    design
}

/// The independent simulation's sigmas came out 16-28 % small for the per-session linear
/// fits. One thing at a time on esgt-2005's day 1, 300 replicas each, printed for the
/// record (docs/model.md 6.1): the temperature held at the day's mean, as simulated (it
/// moves by 6-14 mK over the half hour), with a 5 mK wander added, with everything of the
/// independent simulation together (printed, not held); and, the temperature
/// held, with half the stations, with the independent simulation's station spread, ADC
/// noise per station and blunders, each alone and the three together. Asserted: with the
/// temperature held, the rms z of b and k is within 0.07 of 1 (the bound; 1.09-1.12
/// while the sigmas were the adjustment's at the theodolite's component, estimated on
/// about 12 dof, which makes z a t, not a normal; now each parameter's variance is its
/// t's), and so with each of the independent simulation's features (the blunders' 1.11-1.13
/// came from two at one station masking each other, and from a removed blunder's station
/// still weighed by it); with half the stations (about 5 dof) within 0.15 (1.33-1.35
/// before, 1.06-1.10 now). For acc1; all three with GRAVCAL_MONTE_CARLO (docs/model.md
/// quotes that run).
#[test]
fn per_session_fits_one_thing_at_a_time() {
    let replicas = 300;
    for acc in 0..studied_accelerometers() {
        for varied in [
            Varied::ConstantTemperature,
            Varied::HalfTheStations,
            Varied::StationSpread,
            Varied::AdcPerStation,
            Varied::Blunders,
            Varied::Together,
            Varied::AsSimulated,
            Varied::Wander,
            Varied::All,
        ] {
            let ([zb, zk], rate, dof) = per_session_study(replicas, acc, varied);
            eprintln!(
                "per-session linear fit, acc{} day1, {varied:?}, {replicas} replicas: rms z b {zb:.3}, k {zk:.3}; global test rejects {:.1} %; b's dof {dof:.1} on average",
                acc + 1,
                100.0 * rate
            );
            let bound = match varied {
                Varied::HalfTheStations => 0.15,
                Varied::AsSimulated | Varied::Wander | Varied::All => continue,
                _ => 0.07,
            };
            assert!(
                (zb - 1.0).abs() < bound && (zk - 1.0).abs() < bound,
                "{varied:?}: {zb} {zk}"
            );
        }
    }
}

/// rms of (estimate - truth) / sigma for b, k, b_t and k_t, and the global test's rejection
/// rate, over `replicas` thermal fits (order 1 with temperature terms, both days of
/// esgt-2005) for accelerometer `acc` (0-based), default weights and components, white ADC
/// noise, the temperatures read exactly: the model that carries a temperature moving
/// within a session, where the per-session linear fit cannot ([`per_session_study`]).
/// The truth is b and k at the fit's reference temperature.
fn thermal_study(replicas: usize, acc: usize, varied: Varied) -> ([f64; 4], f64) {
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let a = &truth.accelerometer[acc];
    let mut keys: Vec<(&str, &str)> = Vec::new();
    let mut rng = fixtures::rng::Rng::new(20_261_127, "thermal study");
    let terms = adjust::calibration::model::Terms {
        order: 1,
        temperature: true,
        misalignment: adjust::calibration::model::Misalignment::None,
    };
    let (mut z2, mut rejected, mut n) = ([0.0; 4], 0, 0);
    for _ in 0..replicas {
        let design = both_days_design(&truth, acc, varied, &mut rng, &mut keys);
        let Some(f) = study_fit(design, varied, &mut rng, terms, truth.gravity_mgal) else {
            continue;
        };
        let [b, k] = b_and_k_at(a, f.t_ref_c - truth.t_ref_c);
        let want = [b, k, a.b_t_mgal_per_c, a.k_t_mgal_per_bit_per_c];
        for j in 0..4 {
            z2[j] += ((f.values[j] - want[j]) / f.sigma(j)).powi(2);
        }
        rejected += usize::from(!f.global_test_passed());
        n += 1;
    }
    let n = f64::from(u32::try_from(n).unwrap_or(u32::MAX));
    (
        z2.map(|s| (s / n).sqrt()),
        f64::from(u32::try_from(rejected).unwrap_or(u32::MAX)) / n,
    )
}

/// Both days of esgt-2005 for accelerometer `acc` as the studies draw them: the counts from
/// the truth at each reading's temperature, the wander (`varied`) added to the temperature
/// from 0 at each session's first reading and read by an exact thermometer; stations keyed
/// by (session, station) in `keys`, kept across replicas.
fn both_days_design<'t>(
    truth: &'t Truth,
    acc: usize,
    varied: Varied,
    rng: &mut fixtures::rng::Rng,
    keys: &mut Vec<(&'t str, &'t str)>,
) -> Vec<McReading> {
    let a = &truth.accelerometer[acc];
    let t0 = truth.reading[0].time_gps_ns;
    // The wander, from 0 at each session's first reading.
    let (mut wander, mut last): (f64, Option<(&str, f64)>) = (0.0, None);
    truth
        .reading
        .iter()
        .map(|r| {
            let time_s = (r.time_gps_ns - t0) as f64 * 1e-9;
            match last {
                Some((session, last_s)) if session == r.session => {
                    if matches!(varied, Varied::Wander | Varied::All) {
                        wander += WANDER_C_PER_SQRT_S * (time_s - last_s).sqrt() * rng.normal();
                    }
                }
                _ => wander = 0.0,
            }
            last = Some((r.session.as_str(), time_s));
            let temperature_c = r.temperature_c[acc] + wander;
            let t = temperature_c - truth.t_ref_c;
            let key = (r.session.as_str(), r.station.as_str());
            if !keys.contains(&key) {
                keys.push(key);
            }
            let g = truth.gravity_mgal + r.tide_mgal;
            McReading {
                station: keys.iter().position(|k| *k == key).unwrap_or(0),
                session: usize::from(r.session != truth.reading[0].session),
                dz_true_rad: r.dz_true_rad,
                sigma_dz_rad: r.sigma_dz_rad,
                ng_true: (-g * r.dz_true_rad.cos() - a.b_mgal - a.b_t_mgal_per_c * t)
                    / (a.k_mgal_per_bit + a.k_t_mgal_per_bit_per_c * t),
                sigma_sample_bits: r.sigma_sample_bits[acc],
                temperature_c,
                tide_mgal: r.tide_mgal,
                time_s,
            }
        })
        .collect()
}

/// rms of (estimate - truth) / sigma for b and k over `replicas` per-session linear fits of
/// esgt-2005's day 1 for accelerometer `acc` (0-based): with the sigmas as the fit gives
/// them, and widened by the thermal sensitivity that the same replica's fit with temperature
/// terms over both days estimates (the consider covariance adjust adds in a run that has
/// both, docs/model.md 6.1). The truth is b and k at the linear fit's mean temperature, the
/// temperature its b and k are given at.
fn per_session_with_thermal_study(replicas: usize, acc: usize, varied: Varied) -> [[f64; 2]; 2] {
    use adjust::calibration::calibrate::{Sensitivity, calibrate};
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let a = &truth.accelerometer[acc];
    let mut keys: Vec<(&str, &str)> = Vec::new();
    let mut rng = fixtures::rng::Rng::new(20_261_128, "per-session with thermal study");
    let terms = |temperature| adjust::calibration::model::Terms {
        order: 1,
        temperature,
        misalignment: adjust::calibration::model::Misalignment::None,
    };
    let g = truth.gravity_mgal;
    let (mut plain, mut widened, mut n) = ([0.0; 2], [0.0; 2], 0);
    for _ in 0..replicas {
        let design = both_days_design(&truth, acc, varied, &mut rng, &mut keys);
        let obs = study_obs(design, varied, &mut rng);
        let day1: Vec<adjust::calibration::calibrate::Obs> =
            obs.iter().filter(|o| o.session == 0).cloned().collect();
        let (Ok(thermal), Ok(f)) = (
            calibrate(&obs, terms(true), g),
            calibrate(&day1, terms(false), g),
        ) else {
            continue;
        };
        let sensitivity = Sensitivity::of(&thermal, terms(true)).expect("temperature terms");
        let extra = f.thermal_covariance(sensitivity);
        let want = b_and_k_at(a, f.mean_temperature_c - truth.t_ref_c);
        for j in 0..2 {
            let e2 = (f.values[j] - want[j]).powi(2);
            plain[j] += e2 / f.sigma(j).powi(2);
            widened[j] += e2 / (f.sigma(j).powi(2) + extra[j * 2 + j]);
        }
        n += 1;
    }
    let n = f64::from(u32::try_from(n).unwrap_or(u32::MAX));
    [plain, widened].map(|z2| z2.map(|s| (s / n).sqrt()))
}

/// A per-session linear fit over a moving temperature carries the thermal sensitivity that a
/// fit with temperature terms in the same run measures (docs/model.md 6.1): 300 replicas of
/// both days of esgt-2005 each, the linear fit on day 1 widened by the thermal fit's
/// sensitivity over both days. Asserted: the rms z of b and k within 0.07 of 1 (the issue's
/// bound) as simulated, with the 5 mK wander, and with everything of the independent
/// simulation together; printed beside the rms z without it. For acc1; all three with
/// GRAVCAL_MONTE_CARLO.
#[test]
fn per_session_fits_carry_the_measured_sensitivity() {
    let replicas = 300;
    for acc in 0..studied_accelerometers() {
        for varied in [Varied::AsSimulated, Varied::Wander, Varied::All] {
            let [plain, widened] = per_session_with_thermal_study(replicas, acc, varied);
            eprintln!(
                "per-session linear fit, acc{} day1, {varied:?}, {replicas} replicas: rms z b {:.3}, k {:.3} as fitted; {:.3}, {:.3} with the thermal fit's sensitivity",
                acc + 1,
                plain[0],
                plain[1],
                widened[0],
                widened[1]
            );
            assert!(
                widened.iter().all(|z| (z - 1.0).abs() < 0.07),
                "acc{} {varied:?}: {widened:?}",
                acc + 1
            );
        }
    }
}

/// The model with temperature terms carries what the per-session linear fits cannot
/// (docs/model.md 6.1): over both days of esgt-2005, 1000 replicas each with
/// GRAVCAL_MONTE_CARLO (300 in CI, [`rms_z_bound`]), the rms z of b, k, b_t and k_t is
/// within 0.07 of 1 (the bound) as simulated (the temperature
/// moving 6-14 mK within each day), with the independent simulation's 5 mK wander added,
/// and with everything of it together (the wander, the station spread, the ADC noise per
/// station, the blunders). For acc1; all three with GRAVCAL_MONTE_CARLO (the z of the
/// three hardly differ: the theodolite's noise dominates each, and z is free of scale).
#[test]
fn thermal_fits_carry_what_the_linear_ones_cannot() {
    let replicas = replicas_of(300, 1000);
    for acc in 0..studied_accelerometers() {
        for varied in [Varied::AsSimulated, Varied::Wander, Varied::All] {
            let (z, rate) = thermal_study(replicas, acc, varied);
            eprintln!(
                "thermal fit, acc{} both days, {varied:?}, {replicas} replicas: rms z b {:.3}, k {:.3}, b_t {:.3}, k_t {:.3}; global test rejects {:.1} %",
                acc + 1,
                z[0],
                z[1],
                z[2],
                z[3],
                100.0 * rate
            );
            assert!(
                z.iter().all(|z| (z - 1.0).abs() < rms_z_bound(replicas)),
                "acc{} {varied:?}: {z:?}",
                acc + 1
            );
        }
    }
}

/// The w-test's first round on the acceptance design, without snooping: the share of good
/// readings beyond the two-sided 5 %, 1 % and 0.1 % critical values, weighed at the
/// generating sigmas, at each station's own sd (eq. 4, the left-out variance an exact
/// chi-square) and at the moderated variances (docs/model.md 6.8). 4000 replicas (2.54
/// million readings); each rate at 0.1 % is held within 3 standard errors of alpha. Before
/// the dof's shares came from the fitted variances the same count gave 1.067 alpha at the
/// stations' own sds and 1.074 moderated. Compiled only with GRAVCAL_MONTE_CARLO set.
#[cfg(gravcal_monte_carlo)]
#[test]
fn the_w_statistic_holds_its_tail() {
    let replicas = 4000;
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let design = acceptance_design(&truth);
    let critical = [1.959_964, 2.575_829, 3.290_527];
    let nominal = [0.05, 0.01, 0.001];
    for (label, weights) in [
        ("generating sigmas", Weights::Generating),
        ("station sd (eq. 4)", Weights::StationSd),
        ("moderated station variances", Weights::Moderated),
    ] {
        let mut rng = fixtures::rng::Rng::new(20_261_123, "monte-carlo");
        let (mut beyond, mut n) = ([0usize; 3], 0usize);
        for _ in 0..replicas {
            let dz: Vec<f64> = design
                .iter()
                .map(|r| r.dz_true_rad + r.sigma_dz_rad * rng.normal())
                .collect();
            let means = window_means(&design, None, &mut rng);
            let obs = replica_obs(&design, &dz, &means, weights);
            let options = adjust::calibration::calibrate::FitOptions {
                snooping: adjust::calibration::calibrate::Snooping::Off,
                ..adjust::calibration::calibrate::FitOptions::default()
            };
            let f = adjust::calibration::calibrate::calibrate_with(
                &obs,
                MC_TERMS,
                truth.gravity_mgal,
                &options,
            )
            .expect("fit");
            for r in &f.residuals {
                n += 1;
                for (b, c) in beyond.iter_mut().zip(critical) {
                    *b += usize::from(r.w.abs() > c);
                }
            }
        }
        let rate = |k: usize| beyond[k] as f64 / n as f64 / nominal[k];
        let se = (0.001 * 0.999 / n as f64).sqrt() / 0.001;
        eprintln!(
            "w-test, first round, {label}, {n} readings: rate over alpha {:.3} at 0.05, {:.3} at 0.01, {:.3} at 0.001 (se {se:.3})",
            rate(0),
            rate(1),
            rate(2)
        );
        assert!((rate(2) - 1.0).abs() < 3.0 * se, "{label}: {}", rate(2));
    }
}
