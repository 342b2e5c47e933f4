//! `cargo xtask verdicts [--replicas N]`: every verdict a fit prints, at its measured error
//! rate, in one table (docs/model.md 6.8). The Monte-Carlos are tests (so that CI runs
//! them on a small number of replicas and holds each rate to its rule); this runs them on
//! `N` replicas, gathers the rate lines they print ([`fixtures::verdicts::Rate`]) and
//! prints the nominal rate, the measured one, its standard error and whether it holds.

use anyhow::{Context, Result, bail};
use fixtures::verdicts::Rate;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

/// The tests that measure the rates: package, test binary, test.
const MONTE_CARLOS: [(&str, &str, &str); 5] = [
    ("adjust", "calibration", "every_verdict_holds_its_rate"),
    ("adjust", "calibration", "repeatability_holds_its_level"),
    (
        "adjust",
        "replicas",
        "the_pipelines_verdicts_hold_on_replicas_of_esgt_2005",
    ),
    (
        "align",
        "noise_selection",
        "noise_terms_are_kept_at_their_stated_rate",
    ),
    (
        "align",
        "noise_selection",
        "flicker_is_not_read_as_a_random_walk",
    ),
];

/// Runs the Monte-Carlos on `replicas` and prints the table; an error when a rate does not
/// hold or a Monte-Carlo did not run.
pub fn run(root: &std::path::Path, replicas: usize) -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let mut rates = Vec::new();
    let mut failed = Vec::new();
    for (package, binary, test) in MONTE_CARLOS {
        let args = [
            "test",
            "--release",
            "-p",
            package,
            "--test",
            binary,
            test,
            "--",
            "--exact",
            "--nocapture",
        ];
        eprintln!(
            "$ GRAVCAL_VERDICT_REPLICAS={replicas} cargo {}",
            args.join(" ")
        );
        let mut child = Command::new(&cargo)
            .args(args)
            .env("GRAVCAL_VERDICT_REPLICAS", replicas.to_string())
            .env_remove("GRAVCAL_MONTE_CARLO")
            .current_dir(root)
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| format!("running cargo {}", args.join(" ")))?;
        let stderr = child.stderr.take().context("the test's standard error")?;
        let before = rates.len();
        for line in BufReader::new(stderr).lines() {
            let line = line.context("reading the test's output")?;
            match Rate::parse(&line) {
                Some(rate) => rates.push(rate),
                None => eprintln!("{line}"),
            }
        }
        let status = child.wait()?;
        if rates.len() == before {
            failed.push(format!("{package}'s {test} printed no rate ({status})"));
        } else if !status.success() {
            failed.push(format!("{package}'s {test} failed ({status})"));
        }
    }
    println!("{}", table(&rates));
    let broken: Vec<String> = rates
        .iter()
        .filter(|r| !r.holds())
        .map(ToString::to_string)
        .chain(failed)
        .collect();
    if !broken.is_empty() {
        bail!(
            "{} verdict(s) not held:\n{}",
            broken.len(),
            broken.join("\n")
        );
    }
    Ok(())
}

/// The rates as a Markdown table.
pub fn table(rates: &[Rate]) -> String {
    let mut out = String::from(
        "| verdict | replicas | rate | nominal | measured | se | trials | held to | holds |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rates {
        let d = r.decimals();
        out.push_str(&format!(
            "| {} | {} | {} | {} | {:.d$} | {:.d$} | {} | {} | {} |\n",
            r.verdict,
            r.replicas,
            r.kind.as_str(),
            r.nominal,
            r.measured(),
            r.standard_error(),
            r.trials,
            r.bound(),
            if r.holds() { "yes" } else { "NO" }
        ));
    }
    out
}
