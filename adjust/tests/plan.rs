//! The planner against the adjustment: its predicted sigmas are the a-priori sigmas of the
//! same adjustment on simulated data of the same plan, and the scatter of that adjustment's
//! estimates over many replicas.

use adjust::calibration::calibrate::{FitOptions, Obs, Snooping};
use adjust::calibration::plan::{Plan, observations, predict};

fn plan(name: &str) -> Plan {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fixtures/plans")
        .join(name);
    toml::from_str(&std::fs::read_to_string(&path).expect("plan")).expect("parses")
}

/// The plan's observations with fresh noise of its sds.
fn replica(obs: &[(String, Obs)], rng: &mut fixtures::rng::Rng) -> Vec<Obs> {
    obs.iter()
        .map(|(_, o)| Obs {
            dz_rad: o.dz_rad + o.sigma_dz_rad * rng.normal(),
            ng: o.ng + o.sigma_ng * rng.normal(),
            ..o.clone()
        })
        .collect()
}

fn fit(plan: &Plan, obs: &[Obs]) -> adjust::calibration::calibrate::CalibrationSolution {
    let m = &plan.model[0];
    let terms = adjust::calibration::model::Terms {
        order: usize::from(m.order),
        temperature: m.temperature,
        misalignment: m.misalignment,
    };
    let options = FitOptions {
        snooping: Snooping::Off,
        coloured: None,
        components: false,
    };
    adjust::calibration::calibrate::calibrate_with(obs, terms, plan.site.g_mgal, &options)
        .expect("fits")
}

/// On one replica of the two-roll plan the adjustment's a-priori sigmas are the planner's
/// (they differ only by where the model is linearised: the noisy data against the
/// noise-free plan) and `cargo xtask plan`'s JSON names every parameter.
#[test]
fn predicted_sigmas_are_the_adjustments_a_priori_sigmas() {
    let p = plan("two-rolls.toml");
    let predicted = predict(&p).expect("predicts");
    assert_eq!(predicted.len(), 1);
    assert!(
        predicted[0].not_estimable.is_empty(),
        "{:?}",
        predicted[0].not_estimable
    );
    let mut rng = fixtures::rng::Rng::new(7, "plan");
    let obs = replica(&observations(&p).expect("observations"), &mut rng);
    let f = fit(&p, &obs);
    for (j, q) in predicted[0].parameters.iter().enumerate() {
        let a = f.sigma_apriori(j);
        assert!(
            (a / q.sigma - 1.0).abs() < 1e-3,
            "{}: {a} vs {}",
            q.name,
            q.sigma
        );
    }
    let names: Vec<&str> = predicted[0]
        .parameters
        .iter()
        .map(|q| q.name.as_str())
        .collect();
    assert_eq!(names, ["b", "k", "b_t", "k_t", "theta_x", "theta_y"]);
}

/// 500 replicas of the two-roll plan: the empirical sd of every parameter within 10 % of
/// the prediction (the standard error of an sd ratio is 1/sqrt(1000) = 3.2 %).
#[test]
fn predicted_sigmas_match_the_scatter_of_replicas() {
    let p = plan("two-rolls.toml");
    let predicted = predict(&p).expect("predicts");
    let base = observations(&p).expect("observations");
    let mut rng = fixtures::rng::Rng::new(11, "plan-monte-carlo");
    let n: usize = 500;
    let values: Vec<Vec<f64>> = (0..n)
        .map(|_| fit(&p, &replica(&base, &mut rng)).values)
        .collect();
    for (j, q) in predicted[0].parameters.iter().enumerate() {
        let mean = values.iter().map(|v| v[j]).sum::<f64>() / n as f64;
        let sd =
            (values.iter().map(|v| (v[j] - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        eprintln!(
            "plan monte carlo: {} sd/predicted {:.3}",
            q.name,
            sd / q.sigma
        );
        assert!(
            (sd / q.sigma - 1.0).abs() < 0.1,
            "{}: sd {sd} vs {}",
            q.name,
            q.sigma
        );
    }
}

/// The paper's design names what it cannot determine, and what would fix it.
#[test]
fn the_papers_design_names_what_it_cannot_determine() {
    let predicted = predict(&plan("paper.toml")).expect("predicts");
    let vector = predicted
        .iter()
        .find(|x| x.model == "vector")
        .expect("vector model");
    let notes = vector.not_estimable.join("\n");
    assert!(notes.contains("(theta_y) is not estimable"), "{notes}");
    assert!(
        notes.contains("a session at roll 90.0 deg would determine it"),
        "{notes}"
    );
    assert!(notes.contains("beta is barely estimable"), "{notes}");
    assert!(
        notes.contains("tilts on both sides of the vertical"),
        "{notes}"
    );
    let linear = predicted
        .iter()
        .find(|x| x.model == "linear")
        .expect("linear");
    assert!(linear.not_estimable.is_empty());
    // The MDB as the w-test on the station's other readings finds it (a t on n - 2 = 13
    // dof for 15 readings a station), and Baarda's with sigma_Dz known: larger by the ratio
    // of their non-centralities.
    let mdb = linear.mdb.as_ref().expect("an MDB");
    let ratio = adjust::calibration::calibrate::mdb_noncentrality(Some(13.0))
        / adjust::calibration::plan::DELTA_0;
    for (t, known) in [
        (mdb.dz_arcsec[0], mdb.dz_arcsec_known[0]),
        (mdb.ng_counts[0], mdb.ng_counts_known[0]),
    ] {
        assert!(
            ratio > 1.2 && (t / known / ratio - 1.0).abs() < 0.02,
            "{t} {known} {ratio}"
        );
    }
}

/// The two-roll plan's observations with the sensitive axis misaligned by `theta` at `psi`.
fn misaligned(p: &Plan, theta: f64, psi_deg: f64) -> Vec<(String, Obs)> {
    let (tx, ty) = (
        theta * psi_deg.to_radians().cos(),
        theta * psi_deg.to_radians().sin(),
    );
    observations(p)
        .expect("observations")
        .into_iter()
        .map(|(s, o)| {
            let s_perp = tx * o.roll_rad.cos() + ty * o.roll_rad.sin();
            let s_z = (1.0 - tx * tx - ty * ty).sqrt();
            let a = -p.site.g_mgal * (s_z * o.dz_rad.cos() - s_perp * o.dz_rad.sin());
            let ng = (a - p.instrument.b_mgal) / p.instrument.k_mgal_per_bit;
            (s, Obs { ng, ..o })
        })
        .collect()
}

/// The direction's sigma is honest where psi is given, and psi is withheld near theta = 0:
/// 500 replicas of the two-roll plan with theta = 1.0 urad (about 5 sigma) at 30 deg give
/// sd(psi) within 10 % of the mean reported sigma of psi; with theta = 0, psi is withheld in
/// at least 95 % of them (theta-hat is then Rayleigh, above 3 sigma with probability 1 %).
#[test]
fn the_direction_is_honest_or_withheld() {
    let p = plan("two-rolls.toml");
    let terms = adjust::calibration::model::Terms {
        order: 1,
        temperature: true,
        misalignment: adjust::calibration::model::Misalignment::Vector,
    };
    let mut rng = fixtures::rng::Rng::new(13, "plan-psi");
    let n = 500;
    let small = misaligned(&p, 1.0e-6, 30.0);
    let mut psi = Vec::new();
    let mut sigma = Vec::new();
    for _ in 0..n {
        let v = adjust::misalignment_vector(&fit(&p, &replica(&small, &mut rng)), terms);
        if let (Some(x), Some(s)) = (v.psi_deg, v.sigma_psi_deg) {
            psi.push(x);
            sigma.push(s);
        }
    }
    assert!(psi.len() > n * 9 / 10, "psi given in {} of {n}", psi.len());
    let m = psi.iter().sum::<f64>() / psi.len() as f64;
    let sd = (psi.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (psi.len() - 1) as f64).sqrt();
    let mean_sigma = sigma.iter().sum::<f64>() / sigma.len() as f64;
    eprintln!(
        "psi at theta 1 urad: sd {sd:.2} deg, mean sigma {mean_sigma:.2} deg, given in {} of {n}",
        psi.len()
    );
    assert!(
        (sd / mean_sigma - 1.0).abs() < 0.1,
        "sd {sd} vs sigma {mean_sigma}"
    );
    assert!(
        (m - 30.0).abs() < 3.0 * sd / (psi.len() as f64).sqrt() + 0.5,
        "mean psi {m}"
    );

    let zero = misaligned(&p, 0.0, 0.0);
    let withheld = (0..n)
        .filter(|_| {
            adjust::misalignment_vector(&fit(&p, &replica(&zero, &mut rng)), terms)
                .psi_deg
                .is_none()
        })
        .count();
    eprintln!("psi at theta 0: withheld in {withheld} of {n}");
    assert!(withheld >= n * 95 / 100, "withheld in {withheld} of {n}");
}
