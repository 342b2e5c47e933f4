//! The adjust stage on the simulated experiments: estimates against the generator's truth,
//! blunders, disconnected channels, misalignment, and (gated) a Monte-Carlo check that the
//! reported sigmas are honest.

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

/// MODEL.md on the replica of the paper: per-session linear fits and the thermal model over
/// both days recover the truth within 3 sigma with sigma0 near 1; snooping removes exactly
/// the generator's two blunders; acc2 on day 2 is skipped as disconnected.
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
        within_3_sigma(&format!("{what} b"), param(r, "b"), cal.b_mgal);
        within_3_sigma(&format!("{what} k"), param(r, "k"), cal.k_mgal_per_bit);
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
        let expected: Vec<(String, String, i64)> = blunders
            .iter()
            .filter(|b| b.0 == r.session)
            .cloned()
            .collect();
        assert_eq!(removed, expected, "{what}");
        assert!(
            r.removed
                .iter()
                .all(|x| x.w.abs() > adjust::calibrate::W_CRITICAL)
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
        within_3_sigma("b", param(r, "b"), a.b_mgal + a.b_t_mgal_per_c * dt);
        within_3_sigma(
            "k",
            param(r, "k"),
            a.k_mgal_per_bit + a.k_t_mgal_per_bit_per_c * dt,
        );
        within_3_sigma("b_t", param(r, "b_t"), a.b_t_mgal_per_c);
        within_3_sigma("k_t", param(r, "k_t"), a.k_t_mgal_per_bit_per_c);
        assert!((0.85..1.15).contains(&r.sigma0));
        assert_eq!(r.removed.len(), 2, "both blunders");
    }
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
        within_3_sigma(
            &format!("{} beta", r.accelerometer),
            (beta, sigma),
            a.beta_rad,
        );
        assert!(
            sigma < 0.25 * a.beta_rad.abs(),
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

struct MonteCarlo {
    sd_over_sigma_b: f64,
    sd_over_sigma_k: f64,
    rejection_rate: f64,
}

/// How the Monte-Carlo weighs the theodolite readings.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Weights {
    /// The generating sigma of each station.
    Generating,
    /// Each station's own sample sd (eq. 4).
    StationSd,
    /// Each station's variance moderated toward the session's (align's default).
    Moderated,
}

/// `replicas` replicas of the day-1 design for acc1 with fresh noise: 80 ADC samples per
/// window averaged as align does; sigma_Dz as `weights` says (as align forms it).
fn monte_carlo(replicas: usize, weights: Weights) -> MonteCarlo {
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let day1: Vec<_> = truth
        .reading
        .iter()
        .filter(|r| r.session == "day1")
        .collect();
    let a = 0; // acc1
    let mut rng = fixtures::rng::Rng::new(20_261_122, "monte-carlo");
    let (mut bs, mut ks, mut sb, mut sk) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut rejected = 0;
    for _ in 0..replicas {
        let dz: Vec<f64> = day1
            .iter()
            .map(|r| r.dz_true_rad + r.sigma_dz_rad * rng.normal())
            .collect();
        let mut stations: Vec<&str> = day1.iter().map(|r| r.station.as_str()).collect();
        stations.dedup();
        let own: Vec<(f64, f64)> = stations
            .iter()
            .map(|st| {
                let v: Vec<f64> = day1
                    .iter()
                    .zip(&dz)
                    .filter(|(x, _)| x.station == *st)
                    .map(|(_, d)| *d)
                    .collect();
                let n = v.len() as f64;
                let mean = v.iter().sum::<f64>() / n;
                (
                    v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0),
                    n - 1.0,
                )
            })
            .collect();
        let moderated = align::weights::moderate(&own).expect("stations with readings");
        let mut obs = Vec::new();
        for (i, r) in day1.iter().enumerate() {
            let k = stations
                .iter()
                .position(|st| *st == r.station)
                .expect("station");
            let sigma_dz_rad = match weights {
                Weights::Generating => r.sigma_dz_rad,
                Weights::StationSd => own[k].0.sqrt(),
                Weights::Moderated => moderated.variances[k].sqrt(),
            };
            let samples: Vec<f64> = (0..80)
                .map(|_| r.ng_true[a] + r.sigma_sample_bits[a] * rng.normal())
                .collect();
            let m = samples.iter().sum::<f64>() / 80.0;
            let s = (samples.iter().map(|x| (x - m).powi(2)).sum::<f64>() / 79.0).sqrt();
            obs.push(adjust::calibrate::Obs {
                dz_rad: dz[i],
                sigma_dz_rad,
                ng: m,
                sigma_ng: s / 80f64.sqrt(),
                temperature_c: r.temperature_c[a],
                tide_mgal: r.tide_mgal,
            });
        }
        let terms = adjust::model::Terms {
            order: 1,
            temperature: false,
            misalignment: false,
        };
        let f = adjust::calibrate::calibrate(&obs, terms, truth.gravity_mgal).expect("fit");
        bs.push(f.values[0]);
        ks.push(f.values[1]);
        sb.push(f.sigma(0));
        sk.push(f.sigma(1));
        rejected += usize::from(!f.global_test_passed());
    }
    let sd = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    MonteCarlo {
        sd_over_sigma_b: sd(&bs) / mean(&sb),
        sd_over_sigma_k: sd(&ks) / mean(&sk),
        rejection_rate: rejected as f64 / replicas as f64,
    }
}

/// Gated (GRAVCAL_MONTE_CARLO=1): 500 replicas of the day-1 design with fresh noise and the
/// generating sigmas: the empirical sd of b and k matches the mean reported sigma within
/// 10 %, and the global test rejects about 5 % of the replicas. The same with sigma_Dz from
/// eq. 4 is printed for the record: weights estimated from the very readings they weigh pin
/// v^T P v near its expectation, so that test loses its power and the sigmas come out low.
#[test]
fn monte_carlo_sigmas_are_honest() {
    if std::env::var("GRAVCAL_MONTE_CARLO").is_err() {
        eprintln!("skipped: set GRAVCAL_MONTE_CARLO=1 to run the Monte-Carlo check");
        return;
    }
    let mc = monte_carlo(500, Weights::Generating);
    let eq4 = monte_carlo(500, Weights::StationSd);
    let moderated = monte_carlo(500, Weights::Moderated);
    for (label, m) in [
        ("generating sigmas", &mc),
        ("eq. 4 station sd", &eq4),
        ("moderated station variances", &moderated),
    ] {
        eprintln!(
            "monte carlo, {label}: sd(b)/sigma_b {:.3}, sd(k)/sigma_k {:.3}, global test rejects {:.1} %",
            m.sd_over_sigma_b,
            m.sd_over_sigma_k,
            100.0 * m.rejection_rate
        );
    }
    assert!(
        (0.9..1.1).contains(&mc.sd_over_sigma_b),
        "sd(b)/sigma_b = {}",
        mc.sd_over_sigma_b
    );
    assert!(
        (0.9..1.1).contains(&mc.sd_over_sigma_k),
        "sd(k)/sigma_k = {}",
        mc.sd_over_sigma_k
    );
    assert!(
        (0.02..0.09).contains(&mc.rejection_rate),
        "rejection rate {}",
        mc.rejection_rate
    );
}
