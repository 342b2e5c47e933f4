//! The triad calibration (docs/model.md 6.5) on simulated static positions: the truth recovered
//! within its sigmas and the knocked position removed; a Monte-Carlo of the sigmas and the
//! global test; too few positions and positions in one plane named; and a second opinion,
//! scipy.optimize.least_squares on the same static means, written in Python beside it.

use adjust::calibration::triad::{self, NAMES, Position, TriadError, TriadModel};
use fixtures::rng::Rng;
use fixtures::triad::{StaticPosition, Triad, positions};

mod common;
use common::{EXACT, Thermometer, quadratic_form_of_inverse};

#[path = "../../align/tests/peers/mod.rs"]
mod peers;

const G: f64 = 980_855.7;
/// Per-sample noise, counts: the paper's 1-count sd of a 2.56 s window mean at 31.25 Hz.
const SAMPLE_SD: f64 = 9.0;

fn as_positions(s: &[StaticPosition]) -> Vec<Position> {
    s.iter()
        .map(|q| Position {
            mean: q.mean,
            sigma: q.sigma,
            g_mgal: q.g_mgal,
            temperature_c: None,
            temperature_sd_c: None,
        })
        .collect()
}

#[test]
fn thirty_positions_recover_the_triad_and_remove_the_knocked_one() {
    let truth = Triad::esgt();
    let mut rng = Rng::new(15, "triad/recover");
    let sim = positions(&truth, 30, G, 31.25, SAMPLE_SD, Some((7, 25.0)), &mut rng);
    let s = triad::calibrate(TriadModel::LINEAR, &as_positions(&sim)).expect("calibrates");
    assert_eq!(s.removed.len(), 1, "{:?}", s.removed);
    assert_eq!(s.removed[0].0, 7);
    let p = truth.parameters();
    let mut worst: f64 = 0.0;
    for j in 0..9 {
        let z = (s.values[j] - p[j]) / s.sigma(j);
        eprintln!(
            "{}: {:.6e} +/- {:.2e} (truth {:.6e}, z {z:.2})",
            NAMES[j],
            s.values[j],
            s.sigma(j),
            p[j]
        );
        worst = worst.max(z.abs());
    }
    // Nine z-values: 3.3 is Bonferroni's 1 % family-wise bound.
    assert!(worst < 3.3, "largest |z| {worst}");
    assert!(
        s.global_test.2,
        "global test {} {:?}",
        s.vtpv, s.global_test
    );
    // The angles are determined to a small fraction of their few mrad.
    for j in 0..3 {
        assert!(s.sigma(j) < 2e-5, "{}: {}", NAMES[j], s.sigma(j));
    }
}

/// What a Monte-Carlo of a triad model found: sd over mean sigma per parameter, the mean
/// Mahalanobis distance of the estimates from truth over the parameters, and the global
/// test's rejection rate.
struct MonteCarlo {
    ratios: Vec<f64>,
    mahalanobis: f64,
    rate: f64,
}

impl MonteCarlo {
    /// Every sd ratio within `ratio` of 1, the Mahalanobis mean within `mahalanobis` of 1,
    /// the global test rejecting 1.5-8.5 % (3 se of 5 % at 400 replicas).
    fn assert_honest(&self, names: &[&str], ratio: f64, mahalanobis: f64) {
        for (name, r) in names.iter().zip(&self.ratios) {
            assert!((r - 1.0).abs() < ratio, "sd({name})/sigma = {r}");
        }
        assert!(
            (self.mahalanobis - 1.0).abs() < mahalanobis,
            "{}",
            self.mahalanobis
        );
        assert!(
            (0.015..=0.085).contains(&self.rate),
            "rejects {}",
            self.rate
        );
    }
}

/// `replicas` replicas of one design of `n` positions (directions, durations; with
/// temperature terms each position at one of a chamber's plateaus 20, 27, 34 degC, read by
/// `thermometer`), new noise each replica.
fn monte_carlo(
    model: TriadModel,
    truth: &Triad,
    (n, replicas): (usize, usize),
    thermometer: Thermometer,
    seed: u64,
) -> MonteCarlo {
    let mut rng = Rng::new(seed, "triad/monte-carlo");
    let design = positions(truth, n, G, 31.25, SAMPLE_SD, None, &mut rng);
    let temperature = |i: usize| {
        let chamber = [20.0, 27.0, 34.0][i % 3];
        model
            .temperature
            .then_some([chamber + 0.4, chamber - 0.3, chamber + 0.1])
    };
    let names = model.names();
    let m = names.len();
    let (mut est, mut sig) = (Vec::new(), Vec::new());
    let (mut mahalanobis, mut rejected) = (0.0, 0);
    for _ in 0..replicas {
        let q: Vec<Position> = design
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let t = temperature(i);
                let a = d.direction.map(|x| x * G);
                let clean = truth.readings_at(a, t.unwrap_or([truth.t_ref_c; 3]));
                let mean = std::array::from_fn(|k| clean[k] + d.sigma[k] * rng.normal());
                Position {
                    mean,
                    sigma: d.sigma,
                    g_mgal: G,
                    temperature_c: t.map(|t| t.map(|t| t + thermometer.sd_c * rng.normal())),
                    temperature_sd_c: thermometer.given.then_some([thermometer.sd_c; 3]),
                }
            })
            .collect();
        let s = triad::calibrate(model, &q).expect("calibrates");
        // The truth referred to the fit's t_ref: b + bt shift, s + st shift.
        let mut p = truth.parameters_for(model.order, model.temperature);
        if let Some(t_ref) = s.t_ref_c {
            let shift = t_ref - truth.t_ref_c;
            for j in 0..3 {
                p[3 + j] += p[m - 3 + j] * shift;
                p[6 + j] += p[m - 6 + j] * shift;
            }
        }
        rejected += usize::from(!s.global_test.2);
        let delta: Vec<f64> = (0..m).map(|j| s.values[j] - p[j]).collect();
        mahalanobis +=
            quadratic_form_of_inverse(&|i, j| s.covariance[i * m + j], &delta) / m as f64;
        est.push(delta);
        sig.push((0..m).map(|j| s.sigma(j)).collect::<Vec<_>>());
    }
    let r = replicas as f64;
    let ratios: Vec<f64> = (0..m)
        .map(|j| {
            let mean = est.iter().map(|e| e[j]).sum::<f64>() / r;
            let sd = (est.iter().map(|e| (e[j] - mean).powi(2)).sum::<f64>() / (r - 1.0)).sqrt();
            sd / (sig.iter().map(|s| s[j]).sum::<f64>() / r)
        })
        .collect();
    let mc = MonteCarlo {
        ratios,
        mahalanobis: mahalanobis / r,
        rate: rejected as f64 / r,
    };
    eprintln!(
        "triad monte carlo, order {} {} temperature terms, {replicas} replicas of {n} positions, temperatures' sd {} mK{}: sd/sigma {}; Mahalanobis / dof {:.3}; global test rejects {:.1} %",
        model.order,
        if model.temperature { "with" } else { "without" },
        1e3 * thermometer.sd_c,
        if thermometer.given { " (given)" } else { "" },
        names
            .iter()
            .zip(&mc.ratios)
            .map(|(n, r)| format!("{n} {r:.3}"))
            .collect::<Vec<_>>()
            .join(", "),
        mc.mahalanobis,
        100.0 * mc.rate
    );
    mc
}

#[test]
fn monte_carlo_of_the_triad_sigmas() {
    let mc = monte_carlo(TriadModel::LINEAR, &Triad::esgt(), (24, 400), EXACT, 16);
    // se of an sd ratio 1/sqrt(2n) = 0.035, of the Mahalanobis mean sqrt(2/9/n) = 0.024, of
    // the rate 0.011: bounds at about 3 se.
    mc.assert_honest(&NAMES, 0.11, 0.08);
}

/// The sigmas of order 2 with temperature terms (18 parameters, 42 positions over three
/// plateaus), temperatures known: sd over sigma per parameter within 3.5 se (0.035 for 400
/// replicas; 18 ratios), the Mahalanobis mean within 4 se (0.015), the rate within 3 se.
#[test]
fn monte_carlo_of_the_thermal_triad_sigmas() {
    let model = TriadModel {
        order: 2,
        temperature: true,
    };
    let mc = monte_carlo(model, &Triad::esgt_thermal(), (42, 400), EXACT, 17);
    mc.assert_honest(&model.names(), 0.125, 0.06);
}

/// The same with a noisy thermometer (each position's temperatures off by 5 mK sd, as a
/// position averaging a few readings of a 10 mK sensor): given that sd, the fit takes the
/// temperatures as observations and its sigmas and global test hold as above; taking them
/// as exact, the global test rejects far beyond its 5 %.
#[test]
fn monte_carlo_of_the_thermal_triad_with_a_noisy_thermometer() {
    let model = TriadModel {
        order: 2,
        temperature: true,
    };
    let noisy = Thermometer {
        sd_c: 0.005,
        given: true,
    };
    let mc = monte_carlo(model, &Triad::esgt_thermal(), (42, 400), noisy, 19);
    mc.assert_honest(&model.names(), 0.125, 0.06);
    let exact = Thermometer {
        given: false,
        ..noisy
    };
    let mc = monte_carlo(model, &Triad::esgt_thermal(), (42, 200), exact, 19);
    assert!(mc.rate > 0.3, "rejects {}", mc.rate);
}

#[test]
fn too_few_positions_and_one_plane_are_named() {
    let truth = Triad::esgt();
    let mut rng = Rng::new(17, "triad/names");
    let few = positions(&truth, 11, G, 31.25, SAMPLE_SD, None, &mut rng);
    let e = triad::calibrate(TriadModel::LINEAR, &as_positions(&few)).expect_err("11 positions");
    assert_eq!(
        e,
        TriadError::TooFewPositions {
            n: 11,
            params: 9,
            needed: 12
        }
    );
    assert!(e.to_string().contains("at least 12"), "{e}");
    // Twenty positions turned about the body's z axis only: every direction in the x-y plane.
    let flat: Vec<Position> = (0..20)
        .map(|i| {
            let phi = f64::from(i) * 0.31;
            let d = [phi.cos(), phi.sin(), 0.0];
            Position {
                mean: truth.readings(d.map(|x| x * G)),
                sigma: [0.5; 3],
                g_mgal: G,
                temperature_c: None,
                temperature_sd_c: None,
            }
        })
        .collect();
    let e = triad::calibrate(TriadModel::LINEAR, &flat).expect_err("one plane");
    assert!(matches!(e, TriadError::OnePlane { .. }), "{e}");
    assert!(e.to_string().contains("one plane"), "{e}");
}

/// The same model solved independently: scipy.optimize.least_squares on the static means,
/// residual (|T K (X - B)| - g) / sd with the sd propagated from the means' sds at each
/// evaluation (the weighted least squares imu_tk's problem becomes with weights), started
/// from T = I and the extremes. The two differ only where Gauss-Helmert's linearisation at
/// the adjusted observations differs from least squares on the observed ones, far below
/// the parameters' sigmas (measured: 1e-7 of a sigma): each parameter must agree within
/// 1e-4 of its sigma, and the sigmas (scipy's from J^T J) within 1e-4.
#[test]
fn scipy_least_squares_agrees() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let truth = Triad::esgt();
    let mut rng = Rng::new(18, "triad/scipy");
    let sim = positions(&truth, 30, G, 31.25, SAMPLE_SD, None, &mut rng);
    let s = triad::calibrate(TriadModel::LINEAR, &as_positions(&sim)).expect("calibrates");
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("means.csv");
    let mut text = String::from("x,y,z,sx,sy,sz,g\n");
    for q in &sim {
        text.push_str(&format!(
            "{:.17e},{:.17e},{:.17e},{:.17e},{:.17e},{:.17e},{:.17e}\n",
            q.mean[0], q.mean[1], q.mean[2], q.sigma[0], q.sigma[1], q.sigma[2], q.g_mgal
        ));
    }
    std::fs::write(&csv, text).expect("write");
    let script = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/triad_scipy.py");
    let o = std::process::Command::new(&py)
        .arg(&script)
        .arg(&csv)
        .output()
        .expect("python");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    for j in 0..9 {
        let v = got["values"][j].as_f64().expect("value");
        let sd = got["sigmas"][j].as_f64().expect("sigma");
        let dv = (v - s.values[j]) / s.sigma(j);
        let ds = sd / s.sigma(j) - 1.0;
        eprintln!(
            "{}: gravcal {:.9e} scipy {:.9e}: {dv:.2e} sigma apart, sigmas {ds:+.2e}",
            NAMES[j], s.values[j], v
        );
        assert!(dv.abs() < 1e-4, "{}: {dv} sigma apart", NAMES[j]);
        assert!(ds.abs() < 1e-4, "{}: sigmas differ by {ds}", NAMES[j]);
    }
}

/// Ingest, align and adjust on a multi-position dataset; its calibration.json.
fn pipeline(
    dataset: &std::path::Path,
    out: &std::path::Path,
) -> ingest::contract::calibration::Calibration {
    ingest::run(dataset, out).expect("ingest");
    align::run(dataset, out).expect("align");
    adjust::run(dataset, out).expect("adjust")
}

/// Each parameter within Bonferroni's 1 % family-wise bound of truth (3.3 sigma for nine,
/// 3.5 for 21).
fn within_sigmas(r: &ingest::contract::calibration::TriadResult, truth: &[f64]) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    assert_eq!(r.parameters.len(), truth.len());
    let bound = Normal::standard().inverse_cdf(1.0 - 0.005 / truth.len() as f64);
    let mut worst: f64 = 0.0;
    for (p, t) in r.parameters.iter().zip(truth) {
        let z = (p.value - t) / p.sigma;
        eprintln!(
            "{}: {:.9e} +/- {:.2e} {} (truth {t:.9e}, z {z:.2})",
            p.name, p.value, p.sigma, p.unit
        );
        worst = worst.max(z.abs());
    }
    assert!(worst < bound, "largest |z| {worst} (bound {bound:.2})");
    worst
}

#[test]
fn the_committed_lab_session_calibrates_the_triad() {
    let dataset = fixtures::dataset_dir(fixtures::triad::MULTIPOS);
    let text = std::fs::read_to_string(dataset.join("truth.toml")).expect("truth");
    let truth: fixtures::triad::MultiPosTruth = toml::from_str(&text).expect("parse");
    let out = tempfile::tempdir().expect("tempdir");
    let c = pipeline(&dataset, out.path());
    assert_eq!(c.triad.len(), 1, "{:?}", c.skipped);
    let r = &c.triad[0];
    within_sigmas(r, &truth.parameters);
    // The knocked position (truth's position 12: the quiet start is 0) and no other removed.
    let removed: Vec<usize> = r
        .positions
        .iter()
        .enumerate()
        .filter(|(_, p)| p.removed)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(removed, vec![12]);
    assert!(truth.position[12].knock_counts > 0.0);
    assert_eq!(r.positions.len(), truth.position.len());
    // The .calib file reads back to the parameters.
    let calib = std::fs::read_to_string(
        out.path()
            .join("adjust")
            .join(r.calib_file.as_ref().expect("a linear model's .calib")),
    )
    .expect("calib");
    let numbers: Vec<f64> = calib
        .split_whitespace()
        .map(|x| x.parse().expect("number"))
        .collect();
    assert_eq!(numbers.len(), 21);
    // Written with 17 significant digits: read back exactly.
    for (got, want) in [
        (numbers[1], -r.parameters[0].value),
        (numbers[9], r.parameters[3].value),
        (numbers[18], r.parameters[6].value),
    ] {
        assert_eq!(got.to_bits(), want.to_bits(), "{got} vs {want}");
    }
    // A scale damaged to 1e300 would make every applied vector inf (and the gravity
    // stage's every value NaN): refused where the function is meant to be used, as an
    // axis function's is.
    use adjust::survey::apply::triad_stream::TriadFunction;
    TriadFunction::new(r).expect("the real result applies");
    let mut bad = r.clone();
    bad.parameters[3].value = 1e300;
    let e = TriadFunction::new(&bad).err().expect("overflowing scale");
    assert!(
        e.contains("triad") && e.contains("overflow the arithmetic"),
        "{e}"
    );
}

/// imu_tk's ASCII layout at 200 Hz in m/s^2 with 10 ms stamps, no header, 36 positions
/// after a 30 s quiet start: through the pipeline with a manifest alone.
#[test]
fn an_imu_tk_ascii_file_calibrates_with_a_manifest_alone() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("imu-tk");
    let plan = fixtures::triad::imu_tk_style(36);
    let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
    let head = std::fs::read_to_string(dataset.join("raw/lab.txt")).expect("read");
    assert!(head.starts_with("0.00 "), "{}", &head[..40]);
    let out = dir.path().join("out");
    let c = pipeline(&dataset, &out);
    let report =
        ingest::contract::ingest_ledger::IngestReport::load(&out.join("ingest")).expect("ledger");
    let lab = report.files[0].lab_stream.as_ref().expect("lab");
    eprintln!(
        "{lab:?}; rate {:?}",
        report.sessions[0].measured_sample_rate_hz
    );
    assert!(lab.samples_sharing_a_stamp > truth.samples / 3, "{lab:?}");
    assert_eq!(report.files[0].accepted, truth.samples);
    assert_eq!(c.triad.len(), 1, "{:?}", c.skipped);
    let r = &c.triad[0];
    assert_eq!(r.reading_unit, "m/s^2");
    within_sigmas(r, &truth.parameters);
    assert_eq!(r.positions.len(), truth.position.len());
    assert!(r.unit_warnings().is_empty(), "{:?}", r.unit_warnings());
    // The same readings declared in mGal: the scales, 1e5 times too large, are named.
    let manifest = dataset.join("dataset.toml");
    let m = std::fs::read_to_string(&manifest).expect("manifest");
    let wrong = m.replacen("reading_unit = \"m/s^2\"", "reading_unit = \"mGal\"", 1);
    assert_ne!(wrong, m);
    std::fs::write(&manifest, wrong).expect("write");
    let c = pipeline(&dataset, &dir.path().join("out-mgal"));
    let warnings = c.triad[0].unit_warnings();
    assert_eq!(warnings.len(), 3, "{warnings:?}");
    assert!(
        warnings.iter().all(|w| w.contains("look like \"m/s^2\"")),
        "{warnings:?}"
    );
}

/// A MEMS recording taken by hand as imu_tk's users take them (45 positions held 1-4 s,
/// tremor and drift, 200 Hz, about 3 mm/s^2 of noise a sample, a 30 s quiet start): the
/// detector used 7 of them before (intervals under 3 s dropped, the triad skipped with "at
/// least 12 well-spread positions are needed"); now every position long enough for its
/// sigma (100 samples) is one, and the triad calibrates within its sigmas.
#[test]
fn a_hand_held_recording_calibrates() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("hand-held");
    let plan = fixtures::triad::hand_held(45, 30.0, 20_261_126);
    let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
    let out = dir.path().join("out");
    let c = pipeline(&dataset, &out);
    let a = ingest::contract::align_ledger::AlignReport::load(&out.join("align")).expect("align");
    let mut summary = Vec::new();
    align::print_summary(&a, &mut summary);
    eprintln!("{}", String::from_utf8(summary).expect("utf-8"));
    assert!(
        a.multi_position[0].warnings.is_empty(),
        "{:?}",
        a.multi_position[0].warnings
    );
    assert_eq!(c.triad.len(), 1, "{:?}", c.skipped);
    let r = &c.triad[0];
    eprintln!(
        "{} positions used, sigma0 {:.3}, {:?}",
        r.positions_used, r.sigma0, r.global_test
    );
    assert!(r.positions_used >= 40, "{} positions", r.positions_used);
    within_sigmas(r, &truth.parameters);
    assert!(r.global_test.passed, "{:?}", r.global_test);
}

/// A hand-held recording as a consumer IMU's logger writes it: 10 ms stamps at 200 Hz (two
/// samples a stamp) and each axis holding its last value a quarter of the time (the real
/// recording issue 47 describes repeats 20-27 %): every position long enough is found and
/// the triad calibrates within its sigmas.
#[test]
fn held_samples_and_shared_stamps_calibrate() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("held");
    let plan = fixtures::triad::MultiPosPlan {
        held_fraction: 0.25,
        tremor_rad: 0.0,
        ..fixtures::triad::hand_held(45, 30.0, 20_261_128)
    };
    let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
    let text = std::fs::read_to_string(dataset.join("raw/lab.txt")).expect("stream");
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(' ').collect()).collect();
    let repeats = rows.windows(2).filter(|w| w[0][1] == w[1][1]).count();
    let share = repeats as f64 / (rows.len() - 1) as f64;
    assert!((0.2..0.3).contains(&share), "x repeats {share}");
    let c = pipeline(&dataset, &dir.path().join("out"));
    let a = ingest::contract::align_ledger::AlignReport::load(&dir.path().join("out/align"))
        .expect("align");
    for n in &a.multi_position[0].noise {
        eprintln!(
            "held 25 %: channel {}: lag-one correlation {:?}, bias instability {:.2} times the \
             white density",
            n.channel,
            n.lag_one_correlation,
            n.bias_instability / n.white_density_per_sqrt_hz
        );
        // Held a quarter of the time, neighbours correlate about 0.25.
        let rho = n.lag_one_correlation.expect("the holds are seen");
        assert!((0.15..0.35).contains(&rho), "channel {}: {rho}", n.channel);
    }
    let r = &c.triad[0];
    eprintln!(
        "held 25 %: x repeats {:.1} %, {} positions used, sigma0 {:.3}, {:?}",
        100.0 * share,
        r.positions_used,
        r.sigma0,
        r.global_test
    );
    assert!(r.positions_used >= 40, "{} positions", r.positions_used);
    within_sigmas(r, &truth.parameters);
    // `GRAVCAL_MONTE_CARLO=1`: 200 such recordings, held to what the same recordings
    // without held samples are (`monte_carlo_of_hand_held_recordings`). Before align
    // widened the white part by the samples' lag-one correlation and started the Allan
    // curve beyond it, the rms z was 0.74-0.85 (the sigmas a third too large).
    if std::env::var("GRAVCAL_MONTE_CARLO").is_err() {
        return;
    }
    let replicas = 200;
    let (rms, rate, fewest) = hand_held_monte_carlo(replicas, "a quarter held", |k| {
        fixtures::triad::MultiPosPlan {
            held_fraction: 0.25,
            tremor_rad: 0.0,
            ..fixtures::triad::hand_held(45, 30.0, 11_000 + k)
        }
    });
    held_to_one(&rms, rate, replicas);
    assert!(fewest >= 40, "a replica used {fewest} positions");
}

/// The recording issue 47 describes, as the simulator makes it: 45 positions of 1-4 s
/// after a quiet start of 6.6 s (the detector's first 10 s take in the first turn), a
/// quarter of each axis's samples held, 10 ms stamps, and a hand that trembles by 2 mrad at
/// 8.7 and 10.3 Hz (about 20 mm/s^2, above the 3 mm/s^2 of noise a sample). The windows
/// inside a position then scatter far beyond the white-noise law, and the detector, which
/// took the quiet start's table-still noise for the positions' and cut a run at the first
/// window past its 99.9 % quantile, found 1 position here (no triad). It now takes the
/// positions' own noise and keeps a run through windows up to `statics::HOLD_FACTOR` times
/// it: 46 found (the quiet start and the 45), every one used, the triad within its sigmas.
/// Their sigmas are far too large (sigma0 0.11: a 10 Hz tremor averages out over a hold
/// faster than white noise), left open in docs/triad.md, "Finding the positions".
#[test]
fn a_trembling_hand_keeps_its_positions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("trembling");
    let plan = fixtures::triad::MultiPosPlan {
        held_fraction: 0.25,
        tremor_rad: 2e-3,
        ..fixtures::triad::hand_held(45, 6.6, 20_261_201)
    };
    let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
    let c = pipeline(&dataset, &dir.path().join("out"));
    let a = ingest::contract::align_ledger::AlignReport::load(&dir.path().join("out/align"))
        .expect("align");
    let mp = &a.multi_position[0];
    let r = &c.triad[0];
    eprintln!(
        "trembling hand: {} found, {} used by align, {} by the triad, sigma0 {:.3}, warnings \
         {:?}",
        mp.found, mp.used, r.positions_used, r.sigma0, mp.warnings
    );
    // The positions and the quiet start.
    assert!(
        r.positions_used >= 41,
        "{} positions used",
        r.positions_used
    );
    within_sigmas(r, &truth.parameters);
}

/// Per parameter the rms z within 3 standard errors (1/sqrt(2n)) of 1 and the global
/// test's rejections within 3 se of 5 %, over `replicas`.
fn held_to_one(rms: &[f64], rate: f64, replicas: u64) {
    let n = replicas as f64;
    let se = 1.0 / (2.0 * n).sqrt();
    for (name, r) in NAMES.iter().zip(rms) {
        assert!(
            (r - 1.0).abs() < 3.0 * se,
            "rms z of {name} {r} (3 se {:.3})",
            3.0 * se
        );
    }
    let rate_se = (0.05 * 0.95 / n).sqrt();
    assert!((rate - 0.05).abs() < 3.0 * rate_se, "rejects {rate}");
}

/// Monte-Carlo of hand-held recordings through the whole pipeline (write the stream, ingest,
/// detect, adjust): each replica a new recording (new directions, holds and noise) of 45
/// positions held 1-4 s with a hand's drift. Per parameter the rms of (estimate - truth) /
/// sigma must be 1 within 3 standard errors (1/sqrt(2n) each), the global test must reject
/// 5 % within 3 se, and every replica use at least 40 positions. 100 replicas here (about
/// half a minute); `GRAVCAL_MONTE_CARLO=1` runs 400 (where 3 se is 0.9-1.1), and prints the
/// same with the hand's tremor.
#[test]
fn monte_carlo_of_hand_held_recordings() {
    let full = std::env::var("GRAVCAL_MONTE_CARLO").is_ok();
    let replicas: u64 = if full { 400 } else { 100 };
    let (rms, rate, fewest) = hand_held_monte_carlo(replicas, "no tremor", with_tremor(0.0));
    held_to_one(&rms, rate, replicas);
    assert!(fewest >= 40, "a replica used {fewest} positions");
    // With a hand's tremor (0.2 mrad at 8.7 and 10.3 Hz) the positions' sigmas come out on
    // the safe side: a periodic wobble averages out of a mean faster than the white noise
    // the scatter about a line takes it for. Printed for the record, not asserted.
    if full {
        hand_held_monte_carlo(replicas, "tremor 2e-4 rad", with_tremor(2e-4));
    }
}

/// A t on `dof` degrees of freedom (none: a normal z) as the normal deviate of the same
/// probability: a sigma estimated on few dof is honest when its t follows Student's law.
fn as_normal(t: f64, dof: Option<f64>) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
    match dof {
        Some(d) => {
            let p = StudentsT::new(0.0, 1.0, d).expect("dof").cdf(t);
            Normal::standard().inverse_cdf(p.clamp(1e-300, 1.0 - 1e-16))
        }
        None => t,
    }
}

/// Hand-held recordings whose every placement offsets the readings (150 counts per axis,
/// about 2.5 times a position mean's own sigma: what a block set down by hand does not
/// return to), without tremor (one error at a time), fitted twice in one run: without a
/// position floor the sigmas are too small (rms z near 3, the global test failing), with
/// `position_floor = "estimate"` the rms of (estimate - truth) / sigma, each t on the
/// fit's dof taken as the normal deviate of its probability, is 1 within 3 standard errors
/// per parameter (60 replicas here; `GRAVCAL_MONTE_CARLO=1` runs 400).
#[test]
fn monte_carlo_of_an_estimated_position_floor() {
    let replicas: u64 = if std::env::var("GRAVCAL_MONTE_CARLO").is_ok() {
        400
    } else {
        60
    };
    let (mut with, mut without) = ([0.0; 9], [0.0; 9]);
    let (mut floors, mut rejected) = (Vec::new(), 0u64);
    for k in 0..replicas {
        let dir = tempfile::tempdir().expect("tempdir");
        let dataset = dir.path().join("placed");
        let plan = fixtures::triad::MultiPosPlan {
            placement_sd: 150.0,
            tremor_rad: 0.0,
            ..fixtures::triad::hand_held(45, 30.0, 9_000 + k)
        };
        let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
        let manifest = dataset.join("dataset.toml");
        let text = std::fs::read_to_string(&manifest).expect("manifest");
        std::fs::write(
            &manifest,
            format!(
                "{text}\n[[adjust.model]]\nname = \"floor\"\nkind = \"triad\"\n\
                 position_floor = \"estimate\"\n"
            ),
        )
        .expect("manifest");
        let c = pipeline(&dataset, &dir.path().join("out"));
        let fit = |name: &str| {
            c.triad
                .iter()
                .find(|t| t.model == name)
                .unwrap_or_else(|| panic!("replica {k}: {name}: {:?}", c.skipped))
                .clone()
        };
        let (plain, floored) = (fit("triad"), fit("floor"));
        rejected += u64::from(!plain.global_test.passed);
        floors.push(floored.position_floor.as_ref().expect("estimated").mgal);
        for (sums, r) in [(&mut without, &plain), (&mut with, &floored)] {
            for (j, p) in r.parameters.iter().enumerate() {
                sums[j] += as_normal((p.value - truth.parameters[j]) / p.sigma, p.dof).powi(2);
            }
        }
    }
    let n = replicas as f64;
    let rms = |s: &[f64; 9]| s.map(|v| (v / n).sqrt());
    let (with, without) = (rms(&with), rms(&without));
    floors.sort_by(f64::total_cmp);
    eprintln!(
        "placement 150 counts, {replicas} replicas: rms z without a floor {without:.2?} \
         (global test rejecting {:.0} %), with the floor estimated {with:.3?}; median floor \
         {:.1} mGal",
        100.0 * rejected as f64 / n,
        floors[floors.len() / 2]
    );
    let se = 1.0 / (2.0 * n).sqrt();
    for (name, z) in NAMES.iter().zip(with) {
        assert!(
            (z - 1.0).abs() < 3.0 * se,
            "{name}: rms z {z} with the floor"
        );
    }
    let worst = without.iter().copied().fold(0.0, f64::max);
    assert!(
        worst > 1.5,
        "without a floor the sigmas should fail: {without:?}"
    );
}

/// `replicas` hand-held recordings (replica k's plan from `plan(k)`) through the pipeline:
/// per parameter the rms of (estimate - truth) / sigma, the global test's rejection rate,
/// and the fewest positions a replica used; printed under `label`.
fn hand_held_monte_carlo(
    replicas: u64,
    label: &str,
    plan: impl Fn(u64) -> fixtures::triad::MultiPosPlan,
) -> (Vec<f64>, f64, usize) {
    let mut sum_z2 = [0.0; 9];
    let (mut rejected, mut fewest) = (0u64, usize::MAX);
    for k in 0..replicas {
        let dir = tempfile::tempdir().expect("tempdir");
        let dataset = dir.path().join("hand-held");
        let truth = fixtures::triad::write_multipos(&plan(k), &dataset).expect("write");
        let c = pipeline(&dataset, &dir.path().join("out"));
        let r = c
            .triad
            .first()
            .unwrap_or_else(|| panic!("replica {k}: {:?}", c.skipped));
        fewest = fewest.min(r.positions_used);
        rejected += u64::from(!r.global_test.passed);
        for (j, p) in r.parameters.iter().enumerate() {
            let z = (p.value - truth.parameters[j]) / p.sigma;
            sum_z2[j] += z * z;
        }
    }
    let n = replicas as f64;
    let rms: Vec<f64> = sum_z2.iter().map(|s| (s / n).sqrt()).collect();
    let rate = rejected as f64 / n;
    eprintln!(
        "hand-held monte carlo, {replicas} replicas, {label}: rms z {}; global test rejects \
         {:.1} %; fewest positions used {fewest}",
        NAMES
            .iter()
            .zip(&rms)
            .map(|(name, r)| format!("{name} {r:.3}"))
            .collect::<Vec<_>>()
            .join(", "),
        100.0 * rate
    );
    (rms, rate, fewest)
}

/// The hand-held plan of replica `k` with a hand's `tremor`, rad.
fn with_tremor(tremor: f64) -> impl Fn(u64) -> fixtures::triad::MultiPosPlan {
    move |k| fixtures::triad::MultiPosPlan {
        tremor_rad: tremor,
        ..fixtures::triad::hand_held(45, 30.0, 7_000 + k)
    }
}

/// A 5 s quiet start (the detector measures its reference over the first 10 s, so the
/// first turn falls inside it and the reference noise came out about 100 times the noise
/// inside the positions: every sigma inflated, the global test failed, a `.calib` written
/// without a word). Now align names both figures in a warning and takes the still
/// stretches' noise as its reference: the triad calibrates within its sigmas. And a model
/// the data reject says so in its `.calib`'s name and on the console.
#[test]
fn a_short_quiet_start_is_named_and_set_aside() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("short-quiet");
    let mut plan = fixtures::triad::imu_tk_style(36);
    plan.quiet_s = 5.0;
    let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
    let out = dir.path().join("out");
    let c = pipeline(&dataset, &out);
    let a = ingest::contract::align_ledger::AlignReport::load(&out.join("align")).expect("align");
    let mp = &a.multi_position[0];
    let mut summary = Vec::new();
    align::print_summary(&a, &mut summary);
    let summary = String::from_utf8(summary).expect("utf-8");
    eprintln!("{summary}");
    assert_eq!(mp.warnings.len(), 1, "{mp:?}");
    assert!(
        summary.contains("WARNING") && summary.contains("quiet start"),
        "{summary}"
    );
    let (quiet, still) = (mp.quiet_sd.expect("quiet"), mp.still_sd.expect("still"));
    assert!(quiet[0] > 4.0 * still[0], "{quiet:?} {still:?}");
    assert_eq!(c.triad.len(), 1, "{:?}", c.skipped);
    let r = &c.triad[0];
    within_sigmas(r, &truth.parameters);
    assert!(r.global_test.passed, "{:?}", r.global_test);
    assert_eq!(r.calib_file.as_deref(), Some("triad-lab.calib"));

    // Declared, the quiet start is taken as it is: no warning, the same calibration.
    let manifest = dataset.join("dataset.toml");
    let m = std::fs::read_to_string(&manifest).expect("manifest");
    std::fs::write(
        &manifest,
        m.replace(
            "kind = \"multi-position\"",
            "kind = \"multi-position\"\nquiet_start_s = 4.5",
        ),
    )
    .expect("manifest");
    let declared = dir.path().join("declared");
    let d = pipeline(&dataset, &declared);
    let a =
        ingest::contract::align_ledger::AlignReport::load(&declared.join("align")).expect("align");
    assert!(
        a.multi_position[0].warnings.is_empty(),
        "{:?}",
        a.multi_position[0].warnings
    );
    assert_eq!(a.multi_position[0].quiet_start_s, Some(4.5));
    within_sigmas(&d.triad[0], &truth.parameters);

    // The same result with its global test made to fail high: the .calib's name and the
    // console say the model was rejected.
    let mut rejected = c.clone();
    rejected.triad[0].global_test.statistic = 10.0 * r.global_test.upper;
    rejected.triad[0].global_test.passed = false;
    let mut console = Vec::new();
    adjust::print_summary(&rejected, &mut console);
    let console = String::from_utf8(console).expect("utf-8");
    assert!(
        console.contains("GLOBAL TEST FAILED for triad triad lab"),
        "{console}"
    );
}

/// The thermal chamber read by a thermometer ten times noisier (5 mK a reading): align
/// estimates that noise from the log, gives each position's temperatures their sd, and the
/// order-2 thermal triad takes them as observations: its global test passes and every
/// parameter is within its sigma's Bonferroni bound of truth (with the temperatures taken as
/// exact, sigma0 is 1.33 and the global test fails).
#[test]
fn a_noisy_thermometer_widens_the_sigmas_instead_of_failing_the_model() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("thermal-noisy");
    let mut plan = fixtures::triad::thermal_chamber(42, 2);
    let noise_c = 0.005;
    if let Some(th) = plan.thermal.as_mut() {
        th.noise_c = noise_c;
    }
    let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
    let out = dir.path().join("out");
    let c = pipeline(&dataset, &out);
    let a = ingest::contract::align_ledger::AlignReport::load(&out.join("align")).expect("align");
    let found = a.multi_position[0].thermometer_sd_c;
    eprintln!("thermometer sd estimated {found:?} degC");
    for sd in found {
        let sd = sd.expect("estimated");
        assert!((sd / noise_c - 1.0).abs() < 0.1, "{sd}");
    }
    let position = &a.multi_position[0].positions[0];
    let sd = position
        .temperature_sd_c
        .expect("a position's temperature sd");
    assert!(sd.iter().all(|&s| s > 0.0 && s < noise_c), "{sd:?}");
    let r = &c.triad[0];
    let taken = r
        .temperature_sd_c
        .expect("the temperatures taken as observations");
    eprintln!(
        "sigma0 {:.3}, global test {:?}, median temperature sds {taken:?}",
        r.sigma0, r.global_test
    );
    assert!(r.global_test.passed, "{:?}", r.global_test);
    let shift = r.t_ref_c.expect("t_ref") - plan.triad.t_ref_c;
    let mut want = truth.parameters.clone();
    for j in 0..3 {
        want[3 + j] += want[15 + j] * shift;
        want[6 + j] += want[12 + j] * shift;
    }
    within_sigmas(r, &want);

    // The thermometer's noise given in the manifest (a datasheet's): used instead of the
    // estimate, and the fit holds as well.
    let manifest = std::fs::read_to_string(dataset.join("dataset.toml")).expect("manifest");
    let given = manifest.replace("[instrument]\n", "[instrument]\nthermometer_sd_c = 0.005\n");
    assert_ne!(given, manifest, "an [instrument] table to give it in");
    std::fs::write(dataset.join("dataset.toml"), given).expect("write");
    let c = pipeline(&dataset, &out);
    let a = ingest::contract::align_ledger::AlignReport::load(&out.join("align")).expect("align");
    assert_eq!(a.multi_position[0].thermometer_sd_c, [Some(noise_c); 3]);
    let r = &c.triad[0];
    eprintln!(
        "given: sigma0 {:.3}, global test {:?}",
        r.sigma0, r.global_test
    );
    assert!(r.global_test.passed, "{:?}", r.global_test);
    within_sigmas(r, &want);
}

/// A thermal chamber (plateaus at 20, 27 and 34 degC, a temperature log in the "seconds"
/// layout beside the stream): a triad of order 2 with temperature terms recovers all 18
/// parameters, each within its sigma's Bonferroni bound; the same stream fitted without
/// temperature terms fails its global test. Applied to its own stream, the vector's length
/// at each plateau's positions is g within the sigmas.
#[test]
fn a_thermal_chamber_calibrates_higher_orders_and_temperature_terms() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("thermal");
    let plan = fixtures::triad::thermal_chamber(42, 2);
    let truth = fixtures::triad::write_multipos(&plan, &dataset).expect("write");
    let out = dir.path().join("out");
    let c = pipeline(&dataset, &out);
    assert_eq!(c.triad.len(), 1, "{:?}", c.skipped);
    let r = &c.triad[0];
    assert_eq!((r.order, r.temperature), (2, true));
    assert!(
        r.calib_file.is_none(),
        "imu_tk's layout has no s2 or temperature terms"
    );
    eprintln!(
        "t_ref {:?}, range {:?}, sigma0 {:.3}, {} positions, global test {:?}",
        r.t_ref_c, r.temperature_range_c, r.sigma0, r.positions_used, r.global_test
    );
    // The truth is referred to 27 degC, the fit to the positions' mean temperature: the
    // same model with b + bt (t_ref - 27) and s + st (t_ref - 27).
    let shift = r.t_ref_c.expect("t_ref") - plan.triad.t_ref_c;
    let mut want = truth.parameters.clone();
    for j in 0..3 {
        want[3 + j] += want[15 + j] * shift;
        want[6 + j] += want[12 + j] * shift;
    }
    within_sigmas(r, &want);
    assert!(r.global_test.passed, "{:?}", r.global_test);
    // Every position has its temperatures, near the truth's at its middle.
    let found: Vec<[f64; 3]> = r.positions.iter().filter_map(|p| p.temperature_c).collect();
    assert_eq!(found.len(), r.positions.len());
    let (lo, hi) = (
        r.temperature_range_c.expect("range")[0],
        r.temperature_range_c.expect("range")[1],
    );
    assert!(lo < 20.0 && hi > 34.0, "{lo} {hi}");

    // Applied to its own stream with the temperatures interpolated per sample: g along the
    // true direction at every position, the rests between plateaus (the temperature
    // moving) included.
    let (report, z) = applied_z(&dataset, &out, &truth);
    let worst = z.iter().flatten().fold(0.0f64, |w, z| w.max(z.abs()));
    eprintln!(
        "applied: {:?}; largest |z| {worst:.2} over {} spans",
        report.accelerometers[0].flagged,
        z.len()
    );
    assert!(worst < 4.0, "{z:?}");
    assert_eq!(report.accelerometers[0].with_value, truth.samples);

    // A gap of the temperature log over one position: that position is left out and
    // counted, the others still fit.
    let gap = &truth.position[5];
    let log = std::fs::read_to_string(dataset.join("raw/temperature.txt")).expect("log");
    let kept: Vec<&str> = log
        .lines()
        .filter(|l| {
            l.split(',')
                .next()
                .and_then(|t| t.parse::<f64>().ok())
                .is_none_or(|t| t < gap.start_s - 30.0 || t > gap.end_s + 30.0)
        })
        .collect();
    std::fs::write(dataset.join("raw/temperature.txt"), kept.join("\n") + "\n").expect("write");
    let gapped = pipeline(&dataset, &out);
    let g = &gapped.triad[0];
    eprintln!(
        "temperature gap: {} positions used, {} without temperature",
        g.positions_used, g.positions_without_temperature
    );
    assert!(
        g.positions_without_temperature >= 1,
        "{}",
        g.positions_without_temperature
    );
    assert_eq!(
        g.positions.len() + g.positions_without_temperature,
        r.positions.len()
    );

    // Without temperature terms the same positions do not fit: the global test fails.
    let manifest = std::fs::read_to_string(dataset.join("dataset.toml")).expect("manifest");
    std::fs::write(
        dataset.join("dataset.toml"),
        manifest.replace("temperature = true\n", ""),
    )
    .expect("write");
    let plain = pipeline(&dataset, &out);
    let p = &plain.triad[0];
    eprintln!("without temperature terms: sigma0 {:.1}", p.sigma0);
    assert!(
        !p.global_test.passed && p.sigma0 > 3.0,
        "{:?}",
        p.global_test
    );
}

/// The triad model `model` of `out`'s calibration applied to its own lab session: the
/// apply report, and per truth span the z of each axis's mean calibrated value against g
/// along the true direction (over the covariance and the samples' scatter).
fn applied_z(
    dataset: &std::path::Path,
    out: &std::path::Path,
    truth: &fixtures::triad::MultiPosTruth,
) -> (ingest::contract::apply_ledger::ApplyReport, Vec<[f64; 3]>) {
    use arrow_array::types::{Float64Type, Int64Type};
    use arrow_array::{Array, cast::AsArray};
    use ingest::contract::tables::applied::TRIAD_COLUMNS;
    let cal = out.join("adjust/calibration.json");
    let report = adjust::survey::apply::stream::run(
        dataset,
        out,
        &adjust::survey::apply::stream::Options {
            calibration: &cal,
            choice: adjust::survey::apply::select::Choice {
                model: Some("triad"),
                session: Some("lab"),
            },
        },
    )
    .expect("apply");
    assert_eq!(report.rows_written, truth.samples);
    let f = std::fs::File::open(out.join("apply/acceleration.parquet")).expect("table");
    let mut t = Vec::new();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 9];
    for b in parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(f)
        .expect("parquet")
        .build()
        .expect("reader")
    {
        let b = b.expect("batch");
        t.extend_from_slice(
            b.column_by_name("time_gps_ns")
                .expect("t")
                .as_primitive::<Int64Type>()
                .values(),
        );
        for (k, c) in cols.iter_mut().enumerate() {
            let a = b.column_by_name(TRIAD_COLUMNS[k]).expect("column");
            assert_eq!(a.null_count(), 0);
            c.extend_from_slice(a.as_primitive::<Float64Type>().values());
        }
    }
    let t0 = t[0];
    let z = truth
        .position
        .iter()
        .map(|p| {
            let idx: Vec<usize> = (0..t.len())
                .filter(|&j| {
                    let s = (t[j] - t0) as f64 * 1e-9;
                    s > p.start_s + 1.5 && s < p.end_s - 1.5
                })
                .collect();
            let n = idx.len() as f64;
            std::array::from_fn(|k| {
                let want = truth.gravity_mgal * p.direction[k];
                let e: Vec<f64> = idx.iter().map(|&j| cols[k][j] - want).collect();
                let mean = e.iter().sum::<f64>() / n;
                let var = e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
                let cov = idx.iter().map(|&j| cols[3 + [0, 3, 5][k]][j]).sum::<f64>() / n;
                mean / (cov + var / n).sqrt()
            })
        })
        .collect();
    (report, z)
}

/// The triad applied (docs/model.md 6.7) to its own lab session: at every good static position
/// the mean calibrated vector is g along the true direction, within its covariance and the
/// samples' noise; the knocked position is off by its knock.
#[test]
fn the_triad_applied_gives_the_gravity_vector() {
    let dataset = fixtures::dataset_dir(fixtures::triad::MULTIPOS);
    let text = std::fs::read_to_string(dataset.join("truth.toml")).expect("truth");
    let truth: fixtures::triad::MultiPosTruth = toml::from_str(&text).expect("parse");
    let out = tempfile::tempdir().expect("tempdir");
    pipeline(&dataset, out.path());
    let (_, z) = applied_z(&dataset, out.path(), &truth);
    let mut worst: f64 = 0.0;
    for (i, (p, z)) in truth.position.iter().zip(&z).enumerate() {
        if p.knock_counts > 0.0 {
            assert!(z[0].abs() > 20.0, "the knocked position's x: z {}", z[0]);
            continue;
        }
        for (k, z) in z.iter().enumerate() {
            worst = worst.max(z.abs());
            assert!(z.abs() < 4.0, "position {i} axis {k}: z {z}");
        }
    }
    eprintln!("largest |error| / sigma of a position's mean vector: {worst:.2}");
}

/// The sigmas of order 3 without temperature terms (15 parameters, 36 positions; the truth
/// with esgt_thermal's second-order terms and a third-order term of about 2 micro-g per
/// g^3), the same bounds as order 2.
#[test]
fn monte_carlo_of_the_cubic_triad_sigmas() {
    let model = TriadModel {
        order: 3,
        temperature: false,
    };
    let truth = Triad {
        s3: [3e-20, -2e-20, 2.5e-20],
        ..Triad::esgt_thermal()
    };
    let mc = monte_carlo(model, &truth, (36, 400), EXACT, 18);
    mc.assert_honest(&model.names(), 0.125, 0.06);
}

/// Temperature terms from positions all at one temperature are named not estimable;
/// positions without temperatures are refused, counted; an order 3 model with temperature
/// terms needs 24 positions.
#[test]
fn temperature_terms_need_temperatures_that_vary() {
    let model = TriadModel {
        order: 1,
        temperature: true,
    };
    let truth = Triad::esgt_thermal();
    let mut rng = Rng::new(19, "triad/one-temperature");
    let sim = positions(&truth, 30, G, 31.25, SAMPLE_SD, None, &mut rng);
    let mut q = as_positions(&sim);
    for p in &mut q {
        p.temperature_c = Some([27.0; 3]);
    }
    let e = triad::calibrate(model, &q).expect_err("one temperature");
    assert!(
        matches!(&e, TriadError::NotEstimable { name } if name.starts_with("bt_") || name.starts_with("st_")),
        "{e}"
    );
    q[3].temperature_c = None;
    let e = triad::calibrate(model, &q).expect_err("a position without temperature");
    assert_eq!(e, TriadError::NoTemperature { missing: 1, n: 30 });
    let cubic = TriadModel {
        order: 3,
        temperature: true,
    };
    let e = triad::calibrate(cubic, &q[..20]).expect_err("too few");
    assert!(e.to_string().contains("at least 24"), "{e}");
}
