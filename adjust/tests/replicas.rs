//! The whole pipeline's verdicts on replicas of `fixtures/esgt-2005` (docs/model.md 6.8):
//! the same design (stations, readings, temperatures, the QA3000's coloured ADC noise,
//! stations' ADC noise spread as the paper's), the noise drawn anew from another seed, each
//! replica written as raw logs and run through ingest, align and adjust as a user's would
//! be. The acceptance Monte-Carlo of `tests/calibration.rs` tells the fit the noise that
//! generated it; here align finds it from the still intervals, as it must on real data,
//! so the rates hold the noise-term selection and the variance components' tests together.
//!
//! Held: the global test and the theodolite component's test over the thermal fits, whose
//! model is the simulator's, at 5 %; the ADC component's over every fit (the within-station
//! scatter it reads is the same whatever the model), at most 5 %, since its reference takes
//! align's estimate of the coloured levels as independent of the scatter (the fits of a
//! replica share its noise: each se carries the design effect measured from the replicas);
//! and flicker read as a random walk (a walk kept at ten times the simulator's) at most 1 %
//! of the accelerometers. Printed, not held: the global and theodolite tests of the per-session
//! linear fits, over a temperature moving by 10-20 mK that the linear model does not carry
//! (adjust warns of it; a test that fails there more often than 5 % is detecting a real
//! effect). The global test and the theodolite's are nearly one statistic (the station
//! means' scatter about the fitted function; the global test's reference also holds the
//! ADC's share), so they fail together.
//!
//! Replicas: a tenth of GRAVCAL_VERDICT_REPLICAS (each writes a dataset's logs and reads
//! them: 200 in the default `cargo xtask verdicts`, about a minute), else 100 with
//! GRAVCAL_MONTE_CARLO, else 12.

use fixtures::verdicts::{Kind, Rate};

/// Seeds start here, away from the committed fixture's.
const FIRST_SEED: u64 = 1;

/// Per verdict: (fits, failed) summed, and per replica the failures, for the design effect.
#[derive(Default)]
struct Count {
    trials: u64,
    hits: u64,
    per_replica: Vec<(u64, u64)>,
}

impl Count {
    fn add(&mut self, replica_trials: u64, replica_hits: u64) {
        self.trials += replica_trials;
        self.hits += replica_hits;
        self.per_replica.push((replica_trials, replica_hits));
    }

    /// The hits' variance over replicas against the binomial's (1 when nothing was hit).
    fn design_effect(&self) -> f64 {
        let r = self.per_replica.len() as f64;
        if self.hits == 0 || r < 2.0 {
            return 1.0;
        }
        let mean = self.hits as f64 / r;
        let variance = self
            .per_replica
            .iter()
            .map(|&(_, h)| (h as f64 - mean).powi(2))
            .sum::<f64>()
            / (r - 1.0);
        let p = self.hits as f64 / self.trials as f64;
        let per_replica = self.trials as f64 / r;
        (variance / (per_replica * p * (1.0 - p))).max(1.0)
    }

    fn rate(&self, verdict: &str, kind: Kind, nominal: f64) -> Rate {
        Rate {
            verdict: verdict.to_owned(),
            replicas: "esgt-2005's design through the pipeline".to_owned(),
            kind,
            nominal,
            trials: self.trials,
            hits: self.hits,
            design_effect: self.design_effect(),
        }
    }
}

/// The counts over the replicas: the global test and the theodolite's, apart for the fits
/// whose model carries the temperature (thermal) and those that do not (linear, per
/// session); the ADC's over every fit; the accelerometers whose flicker was read as a walk.
#[derive(Default)]
struct Tally {
    global: [Count; 2],
    theodolite: [Count; 2],
    adc: Count,
    walk: Count,
}

impl Tally {
    /// One replica's fits: each test a trial, a failed one a hit.
    fn add(&mut self, cal: &ingest::contract::calibration::Calibration) {
        let (mut g, mut t, mut a) = ([(0, 0); 2], [(0, 0); 2], (0, 0));
        for r in &cal.results {
            let k = usize::from(r.model != "thermal");
            g[k].0 += 1;
            g[k].1 += u64::from(!r.global_test.passed);
            for c in r
                .variance_components
                .iter()
                .filter(|c| c.not_estimable.is_none())
            {
                let count = if c.group == "ADC" { &mut a } else { &mut t[k] };
                count.0 += 1;
                count.1 += u64::from(!c.passed);
            }
        }
        for k in 0..2 {
            self.global[k].add(g[k].0, g[k].1);
            self.theodolite[k].add(t[k].0, t[k].1);
        }
        self.adc.add(a.0, a.1);
    }
}

#[test]
fn the_pipelines_verdicts_hold_on_replicas_of_esgt_2005() {
    let replicas: u64 = std::env::var("GRAVCAL_VERDICT_REPLICAS")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .map(|n| (n / 10).max(1))
        .unwrap_or_else(|| std::env::var("GRAVCAL_MONTE_CARLO").map_or(12, |_| 100));
    let mut tally = Tally::default();
    for seed in FIRST_SEED..FIRST_SEED + replicas {
        let dir = tempfile::tempdir().expect("tempdir");
        let (dataset, out) = (dir.path().join("dataset"), dir.path().join("out"));
        let mut scenario = fixtures::catalog::esgt_2005(fixtures::scenario::LogFormat::Binary);
        scenario.seed = seed;
        let truth = fixtures::write::write_dataset(&scenario, &dataset).expect("replica written");
        let opts = ingest::Options {
            skip_bad_lines: false,
            progress: false,
        };
        ingest::run_with(&dataset, &out, &opts).expect("ingest");
        let aligned = align::run(&dataset, &out).expect("align");
        tally.add(&adjust::run(&dataset, &out).expect("adjust"));
        let true_walk = truth
            .adc_noise
            .as_ref()
            .map_or(0.0, |n| n.random_walk_bits_per_sqrt_s);
        let read_as_walk = aligned
            .noise
            .iter()
            .filter(|n| n.random_walk_counts_sqrt_hz > 10.0 * true_walk)
            .count();
        tally
            .walk
            .add(aligned.noise.len() as u64, read_as_walk as u64);
    }
    let held = [
        tally.global[0].rate("global test, thermal fits", Kind::FalseAlarm, 0.05),
        tally.theodolite[0].rate(
            "theodolite variance component, thermal fits",
            Kind::FalseAlarm,
            0.05,
        ),
        // At most its level: its reference widens by the uncertainty of align's levels as
        // though that were independent of the scatter it is compared with, where both come
        // from the same stations' samples (docs/model.md 6.8).
        tally
            .adc
            .rate("ADC variance component", Kind::FalseAlarmAtMost, 0.05),
        tally.walk.rate(
            "noise terms, flicker read as a random walk (10x the truth)",
            Kind::FalseAlarmAtMost,
            0.01,
        ),
    ];
    let failed: Vec<String> = held
        .iter()
        .filter(|r| !r.report())
        .map(ToString::to_string)
        .collect();
    for (verdict, c) in [
        ("global test", &tally.global[1]),
        ("theodolite variance component", &tally.theodolite[1]),
    ] {
        eprintln!(
            "  {verdict}, per-session linear fits (not held: the temperature moves by 10-20 mK \
             over a session, which they do not model): {} of {} failed ({:.4})",
            c.hits,
            c.trials,
            c.hits as f64 / c.trials.max(1) as f64
        );
    }
    assert!(failed.is_empty(), "{failed:#?}");
}
