//! `cargo xtask`: runs the pipeline or one stage on a dataset, writes and checks the fixtures,
//! runs what CI runs, and the benchmarks.

mod dev;
mod user;

use dev::{bench, bench_apply, bench_gravity, digest, verdicts};
use user::{check, init, show};

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

#[derive(Parser)]
#[command(name = "cargo xtask", version, about)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(clap::Args, Clone)]
struct DatasetArgs {
    /// Dataset folder (holding dataset.toml).
    dataset: PathBuf,
    /// Output folder (default: out/<dataset folder name> in the workspace).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// `cargo xtask fixtures`'s arguments.
#[derive(clap::Args)]
struct FixturesArgs {
    /// Regenerate into a scratch folder and compare with what is committed; change nothing.
    #[arg(long)]
    check: bool,
    /// Write a large benchmark log instead (never committed) into --out.
    #[arg(long)]
    bench: bool,
    /// Benchmark sampling rate, Hz: 31.25 or 250.
    #[arg(long, default_value_t = 31.25)]
    rate: f64,
    /// Benchmark logging time, hours.
    #[arg(long, default_value_t = 8.0)]
    hours: f64,
    /// Where to write (default: the fixtures/ folder; for --bench, target/bench-data).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Only this committed dataset (default: all of them).
    #[arg(long)]
    only: Option<String>,
}

/// `cargo xtask bench`'s arguments.
#[derive(clap::Args)]
struct BenchArgs {
    /// Which stage: ingest, align, adjust, apply or gravity (marine: its platform meter's
    /// cruise beside shipgrav alone); or smoke (each once, small, as CI).
    what: String,
    /// Logging hours of the 250 Hz log (the 31.25 Hz log is twice as long).
    #[arg(long, default_value_t = 24.0)]
    hours: f64,
    /// Skip the Python peers (polars and pyarrow; shipgrav for gravity).
    #[arg(long)]
    no_peers: bool,
    /// Ingest benchmark: runs of each program; the table gives the fastest and the median.
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Align benchmark: stations per daily session (four sessions).
    #[arg(long, default_value_t = 250)]
    stations: usize,
    /// Align benchmark: readings per station.
    #[arg(long, default_value_t = 100)]
    readings: usize,
    /// Adjust benchmark: observations.
    #[arg(long, default_value_t = 1_000_000)]
    observations: usize,
}

#[derive(Subcommand)]
enum Cmd {
    /// Runs ingest, align, adjust and report in order.
    Pipeline(DatasetArgs),
    /// Raw logs to Parquet (OUT/ingest/).
    Ingest(DatasetArgs),
    /// Ingest tables to observations (OUT/align/).
    Align(DatasetArgs),
    /// Observations to calibration.json (OUT/adjust/).
    Adjust(DatasetArgs),
    /// Stage outputs to the report (OUT/report/).
    Report(DatasetArgs),
    /// A calibration applied to a dataset's (survey's) samples (OUT/apply/; docs/formats.md 8.5).
    Apply(adjust::survey::apply::stream::ApplyArgs),
    /// A survey reduced to gravity along the track (OUT/gravity/; docs/formats.md 10).
    Gravity(adjust::survey::gravity::stage::GravityArgs),
    /// Writes the committed fixture datasets, checks them, or writes a large benchmark log.
    Fixtures(FixturesArgs),
    /// Fits a polynomial to two columns of a CSV table (docs/formats.md section 7); prints JSON.
    Fit(adjust::FitArgs),
    /// Predicts what a planned experiment will determine, before any data (docs/model.md 6.6).
    Plan {
        /// The plan (TOML; docs/planning.md).
        plan: PathBuf,
        /// Print JSON instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Writes a commented draft dataset.toml from the logs in <dataset>/raw/ (never over one).
    Init {
        /// Dataset folder (holding raw/).
        dataset: PathBuf,
    },
    /// Validates a dataset's manifest and reads the head and tail of every log, printing
    /// per file what a run will read, or the error naming file, line and field.
    Check {
        /// Dataset folder (holding dataset.toml).
        dataset: PathBuf,
    },
    /// Runs the pipeline on a dataset and saves the first screen of its report (1400 x 900,
    /// headless Chromium) as a PNG: the README's picture.
    Screenshot {
        /// Dataset folder (holding dataset.toml).
        dataset: PathBuf,
        /// The PNG to write.
        #[arg(long, default_value = "docs/report-first-screen.png")]
        png: PathBuf,
    },
    /// Runs the six stages on every fixture and prints a summary of each output (each
    /// table's columns' sums, each ledger's values, each other file's SHA-256); `--check`
    /// compares it with a committed one at a tolerance, `--write` writes it
    /// (the README's "Other commands").
    Digest {
        /// Compare with this summary (fixtures/digests.txt); differences fail, by key.
        #[arg(long)]
        check: Option<PathBuf>,
        /// Write the summary to this file.
        #[arg(long)]
        write: Option<PathBuf>,
    },
    /// Prints a Parquet table the pipeline wrote: its schema and rows, or CSV.
    Show {
        /// The table (e.g. out/esgt-2005/align/observations.parquet).
        file: PathBuf,
        /// CSV (header and every row, or --head of them) instead of aligned columns.
        #[arg(long)]
        csv: bool,
        /// At most this many rows (default: 20 aligned, all as CSV).
        #[arg(long)]
        head: Option<usize>,
    },
    /// Every verdict a fit prints at its measured error rate: the Monte-Carlos run on
    /// --replicas, their rates in one table (docs/model.md 6.8); fails when one does not hold.
    Verdicts {
        /// Replicas of each Monte-Carlo (CI's tests run 300, and 200 of the noise selection).
        #[arg(long, default_value_t = 2000)]
        replicas: usize,
    },
    /// Runs what CI runs: fmt, clippy, the tests, the fixture check, the pipeline on every
    /// fixture, apply, and every benchmark once on a small size.
    Ci,
    /// Benchmarks (speed and memory), measured, not asserted.
    Bench(BenchArgs),
}

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask sits in the workspace")
        .to_path_buf()
}

/// OUT: `--out`, or out/<dataset folder name> in the workspace (the stage binaries' rule,
/// [`ingest::base::cli::out_dir`], from the workspace's root).
fn out_dir(args: &DatasetArgs) -> Result<PathBuf> {
    Ok(ingest::base::cli::out_dir(
        &workspace_root(),
        &args.dataset,
        args.out.as_deref(),
    ))
}

type Stage = fn(&Path, &Path) -> Result<()>;

const STAGES: [(&str, Stage); 4] = [
    ("ingest", |d, o| {
        let opts = ingest::Options {
            skip_bad_lines: false,
            progress: true,
        };
        let report = ingest::run_with(d, o, &opts)?;
        ingest::print_summary(&report, &mut std::io::stderr());
        Ok(())
    }),
    ("align", |d, o| {
        let report = align::run(d, o)?;
        align::print_summary(&report, &mut std::io::stderr());
        Ok(())
    }),
    ("adjust", |d, o| {
        let c = adjust::run(d, o)?;
        adjust::print_summary(&c, &mut std::io::stderr());
        Ok(())
    }),
    ("report", |d, o| {
        let w = report::run(d, o)?;
        eprintln!(
            "report: wrote {} and {} ({} plots)",
            w.html.display(),
            w.markdown.display(),
            w.plots
        );
        Ok(())
    }),
];

fn run_stages(args: &DatasetArgs, which: &[&str]) -> Result<()> {
    let out = out_dir(args)?;
    // Held across the stages, so no other run slips in between them.
    let _lock = ingest::base::lock::OutputLock::acquire(&out)?;
    for (name, stage) in STAGES.iter().filter(|(n, _)| which.contains(n)) {
        let t0 = std::time::Instant::now();
        stage(&args.dataset, &out)
            .with_context(|| format!("{name} on {}", args.dataset.display()))?;
        eprintln!("{name}: {:.2} s", t0.elapsed().as_secs_f64());
    }
    Ok(())
}

/// The pipeline on `dataset` into a scratch folder, then its report's first screen.
fn screenshot(dataset: &Path, png: &Path) -> Result<()> {
    let scratch = std::env::temp_dir().join(format!("gravcal-shot-{}", std::process::id()));
    let args = DatasetArgs {
        dataset: dataset.to_path_buf(),
        out: Some(scratch.join("out")),
    };
    let result = run_stages(&args, &["ingest", "align", "adjust", "report"]).and_then(|()| {
        let browser = std::env::var("GRAVCAL_CHROMIUM").unwrap_or_else(|_| "chromium".to_owned());
        let png = std::path::absolute(png)?;
        let index = std::path::absolute(scratch.join("out/report/index.html"))?;
        let status = Command::new(&browser)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                "--no-first-run",
                "--window-size=1400,900",
            ])
            .arg(format!(
                "--user-data-dir={}",
                scratch.join("profile").display()
            ))
            .arg(format!("--screenshot={}", png.display()))
            .arg(format!("file://{}", index.display()))
            .stderr(std::process::Stdio::null())
            .status()
            .with_context(|| format!("running {browser} (set GRAVCAL_CHROMIUM)"))?;
        anyhow::ensure!(
            status.success() && png.exists(),
            "{browser} failed ({status})"
        );
        eprintln!("screenshot: wrote {}", png.display());
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&scratch);
    result
}

fn cargo(args: &[&str]) -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    eprintln!("$ cargo {}", args.join(" "));
    let status = Command::new(&cargo)
        .args(args)
        // CI runs the fast Monte-Carlo acceptance test; the full one (about 5 minutes) runs
        // with GRAVCAL_MONTE_CARLO=1, from the README's command.
        .env_remove("GRAVCAL_MONTE_CARLO")
        .current_dir(workspace_root())
        .status()
        .with_context(|| format!("running cargo {}", args.join(" ")))?;
    if !status.success() {
        bail!("cargo {} failed ({status})", args.join(" "));
    }
    Ok(())
}

fn fixtures_check() -> Result<()> {
    let scratch =
        std::env::temp_dir().join(format!("gravcal-fixtures-check-{}", std::process::id()));
    let diffs = fixtures::check(&fixtures::fixtures_dir(), &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    let diffs = diffs?;
    if diffs.is_empty() {
        eprintln!(
            "fixtures: all {} committed datasets are exactly what the generator makes",
            fixtures::catalog::ALL.len()
        );
        Ok(())
    } else {
        for d in &diffs {
            eprintln!("fixtures: {d}");
        }
        bail!(
            "{} fixture files differ from the generator's output; run `cargo xtask fixtures`",
            diffs.len()
        )
    }
}

/// Makes the Python peers' environment the tests compare against (`.ci/peers-venv.sh`),
/// unless `GRAVCAL_SKIP_PEERS=1`.
fn peers_venv() -> Result<()> {
    if std::env::var("GRAVCAL_SKIP_PEERS").as_deref() == Ok("1") {
        eprintln!("GRAVCAL_SKIP_PEERS=1: the tests against the Python peers are left out");
        return Ok(());
    }
    eprintln!("$ bash .ci/peers-venv.sh");
    let ok = Command::new("bash")
        .arg(workspace_root().join(".ci/peers-venv.sh"))
        .status()
        .context("running .ci/peers-venv.sh")?
        .success();
    if !ok {
        bail!(".ci/peers-venv.sh failed (or set GRAVCAL_SKIP_PEERS=1 to leave those tests out)");
    }
    Ok(())
}

/// `cargo xtask ci`: what CI runs (.ci/run), each phase timed.
fn ci() -> Result<()> {
    let start = std::time::Instant::now();
    timed("fmt", || cargo(&["fmt", "--all", "--", "--check"]))?;
    timed("clippy", || {
        cargo(&[
            "clippy",
            "--workspace",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ])
    })?;
    timed("peers' venv", peers_venv)?;
    timed("tests", || cargo(&["test", "--workspace"]))?;
    timed("one feature set", one_feature_set)?;
    timed("fixtures check", fixtures_check)?;
    timed("pipeline, apply and gravity on the fixtures", ci_pipelines)?;
    timed("benchmarks on small sizes", bench_smoke)?;
    eprintln!(
        "ci: every phase passed in {:.0} s",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Fails when the dev build of the stage binaries the benchmarks run ([`bench::Build::Dev`])
/// and xtask, after `cargo test --workspace`, compiles a registry crate again: the normal
/// and the test build's feature sets have drifted apart (ingest/Cargo.toml says why they
/// must not), and a clean machine compiles arrow, parquet and faer twice. The crates
/// compiled anew are named.
fn one_feature_set() -> Result<()> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let mut args = vec!["build", "--message-format=json"];
    for p in bench::DEV_PACKAGES {
        args.extend(["-p", p]);
    }
    eprintln!("$ cargo {}", args.join(" "));
    let out = Command::new(&cargo)
        .args(&args)
        .current_dir(workspace_root())
        .output()
        .context("running cargo build")?;
    if !out.status.success() {
        bail!(
            "cargo build failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let rebuilt = recompiled_registry_crates(&String::from_utf8_lossy(&out.stdout))?;
    if !rebuilt.is_empty() {
        bail!(
            "a build after the tests compiled {} again: their features differ between a build and a test build; ask for the test build's features in ingest/Cargo.toml",
            rebuilt.join(", ")
        );
    }
    Ok(())
}

/// The registry crates a `cargo build --message-format=json` compiled rather than found
/// fresh.
fn recompiled_registry_crates(messages: &str) -> Result<Vec<String>> {
    let mut rebuilt = Vec::new();
    for line in messages.lines().filter(|l| l.starts_with('{')) {
        let m: serde_json::Value = serde_json::from_str(line).context("cargo's JSON message")?;
        let id = m["package_id"].as_str().unwrap_or_default();
        if m["reason"] == "compiler-artifact" && m["fresh"] == false && id.starts_with("registry+")
        {
            rebuilt.push(id.rsplit('#').next().unwrap_or(id).to_owned());
        }
    }
    Ok(rebuilt)
}

/// One phase of `cargo xtask ci`, its time printed when it ends, passed or failed.
fn timed(name: &str, phase: impl FnOnce() -> Result<()>) -> Result<()> {
    let start = std::time::Instant::now();
    let result = phase();
    eprintln!(
        "ci: {name}: {} in {:.0} s",
        if result.is_ok() { "passed" } else { "FAILED" },
        start.elapsed().as_secs_f64()
    );
    result
}

/// The pipeline on every fixture, and the README's apply and gravity commands.
fn ci_pipelines() -> Result<()> {
    let scratch = std::env::temp_dir().join(format!("gravcal-ci-{}", std::process::id()));
    for name in fixtures::catalog::ALL {
        let args = DatasetArgs {
            dataset: fixtures::dataset_dir(name),
            out: Some(scratch.join(name)),
        };
        let result = run_stages(&args, &["ingest", "align", "adjust", "report"]);
        if let Err(e) = result {
            let _ = std::fs::remove_dir_all(&scratch);
            return Err(e.context(format!("pipeline on fixture {name}")));
        }
        eprintln!("pipeline on {name}: ok");
    }
    // The README's second command: esgt-2005's calibration applied to the survey.
    let apply = adjust::survey::apply::stream::ApplyArgs {
        dataset: fixtures::dataset_dir("survey"),
        calibration: scratch.join("esgt-2005/adjust/calibration.json"),
        model: Some("thermal".to_owned()),
        session: None,
        out: Some(scratch.join("survey")),
    };
    let result = apply.run(&workspace_root());
    let report = result.context("apply of esgt-2005's calibration to fixture survey");
    // The third: triad-multipos's calibration reducing survey-lines to gravity.
    let lines = fixtures::survey_lines::SURVEY_LINES;
    let gravity = adjust::survey::gravity::stage::GravityArgs {
        apply: adjust::survey::apply::stream::ApplyArgs {
            dataset: fixtures::dataset_dir(lines),
            calibration: scratch.join("triad-multipos/adjust/calibration.json"),
            model: None,
            session: Some("lab".to_owned()),
            out: None,
        },
        accelerometer: None,
        block_epochs: None,
        skip_bad_lines: false,
    }
    .run(&scratch.join(lines))
    .context("gravity of survey-lines with triad-multipos's calibration")
    .and_then(|g| {
        let args = DatasetArgs {
            dataset: fixtures::dataset_dir(lines),
            out: Some(scratch.join(lines)),
        };
        run_stages(&args, &["report"]).context("survey-lines' report with its gravity")?;
        Ok(g)
    });
    let _ = std::fs::remove_dir_all(&scratch);
    let report = report?;
    adjust::survey::apply::stream::print_summary(&report, &mut std::io::stderr());
    eprintln!("apply on survey: ok");
    let gravity = gravity?;
    adjust::survey::gravity::stage::print_summary(&gravity, &mut std::io::stderr());
    eprintln!("gravity on {lines}: ok");
    Ok(())
}

/// Every benchmark once on a small size, without the peers, so that none can break unseen
/// (`bench adjust` stopped on a design check for months); the figures are not judged here:
/// `cargo xtask bench` measures.
fn bench_smoke() -> Result<()> {
    let root = workspace_root();
    let dev = bench::Build::Dev;
    bench::ingest(&root, 0.05, false, 1, dev).context("bench ingest on a small log")?;
    bench::align(&root, 5, 10, dev).context("bench align on a small dataset")?;
    bench::adjust(&root, 20_000, false, dev).context("bench adjust on 20 000 observations")?;
    bench_apply::apply(&root, 0.05, false, 1, dev).context("bench apply on a small log")?;
    let survey = bench_gravity::SurveyBench {
        root: &root,
        hours: 0.4,
        runs: 1,
        peers: None,
        build: dev,
    };
    bench_gravity::gravity(&survey).context("bench gravity on a short survey")?;
    eprintln!("benchmarks on small sizes: ok");
    Ok(())
}

fn run(cli: Cli) -> Result<()> {
    match cli.cmd {
        Cmd::Pipeline(a) => run_stages(&a, &["ingest", "align", "adjust", "report"]),
        Cmd::Init { dataset } => {
            let path = init::run(&dataset)?;
            eprintln!(
                "init: wrote {}: replace every \"FILL IN\", then `cargo xtask check {}`",
                path.display(),
                dataset.display()
            );
            Ok(())
        }
        Cmd::Digest { check, write } => {
            let run = |d: &Path, o: &Path, which: &[&str]| {
                run_stages(
                    &DatasetArgs {
                        dataset: d.to_path_buf(),
                        out: Some(o.to_path_buf()),
                    },
                    which,
                )
            };
            digest::command(&run, (check.as_deref(), write.as_deref()))
        }
        Cmd::Verdicts { replicas } => verdicts::run(&workspace_root(), replicas),
        Cmd::Check { dataset } => {
            let mut out = std::io::stdout().lock();
            if check::run(&dataset, &mut out)? {
                Ok(())
            } else {
                bail!("{} does not check", dataset.display())
            }
        }
        Cmd::Screenshot { dataset, png } => screenshot(&dataset, &png),
        Cmd::Show { file, csv, head } => {
            let options = show::ShowOptions {
                csv,
                head: head.or((!csv).then_some(20)),
            };
            let mut out = std::io::stdout().lock();
            show::show(&file, options, &mut out)
        }
        Cmd::Ingest(a) => run_stages(&a, &["ingest"]),
        Cmd::Align(a) => run_stages(&a, &["align"]),
        Cmd::Adjust(a) => run_stages(&a, &["adjust"]),
        Cmd::Report(a) => run_stages(&a, &["report"]),
        Cmd::Apply(a) => apply(a),
        Cmd::Gravity(a) => gravity(&a),
        Cmd::Fixtures(a) => fixtures_command(a),
        Cmd::Ci => ci(),
        Cmd::Fit(args) => {
            let out = adjust::fit_csv(&args)?;
            print_stdout(&serde_json::to_string_pretty(&out)?)
        }
        Cmd::Plan { plan, json } => plan_command(&plan, json),
        Cmd::Bench(a) => bench_command(&a),
    }
}

/// `cargo xtask apply`: the calibration applied to a dataset's survey samples.
fn apply(mut a: adjust::survey::apply::stream::ApplyArgs) -> Result<()> {
    a.out = Some(out_dir(&DatasetArgs {
        dataset: a.dataset.clone(),
        out: a.out.clone(),
    })?);
    let t0 = std::time::Instant::now();
    let report = a
        .run(&workspace_root())
        .with_context(|| format!("apply on {}", a.dataset.display()))?;
    adjust::survey::apply::stream::print_summary(&report, &mut std::io::stderr());
    eprintln!("apply: {:.2} s", t0.elapsed().as_secs_f64());
    Ok(())
}

/// `cargo xtask gravity`: the survey dataset's own pipeline first (its report gains the
/// gravity section), then apply and gravity, then the report again.
fn gravity(a: &adjust::survey::gravity::stage::GravityArgs) -> Result<()> {
    let args = DatasetArgs {
        dataset: a.apply.dataset.clone(),
        out: a.apply.out.clone(),
    };
    let out = out_dir(&args)?;
    run_stages(&args, &["ingest", "align", "adjust"])?;
    let t0 = std::time::Instant::now();
    let report = a
        .run(&out)
        .with_context(|| format!("gravity on {}", a.apply.dataset.display()))?;
    adjust::survey::gravity::stage::print_summary(&report, &mut std::io::stderr());
    eprintln!("gravity: {:.2} s", t0.elapsed().as_secs_f64());
    run_stages(&args, &["report"])
}

/// `cargo xtask fixtures`: the committed datasets written or checked, or a benchmark log.
fn fixtures_command(a: FixturesArgs) -> Result<()> {
    let FixturesArgs {
        check,
        bench,
        rate,
        hours,
        out,
        only,
    } = a;
    if check {
        return fixtures_check();
    }
    if bench {
        let interval_ms = match rate {
            r if (r - 31.25).abs() < 1e-9 => 32,
            r if (r - 250.0).abs() < 1e-9 => 4,
            r => bail!("--rate {r}: the benchmark logs are at 31.25 or 250 Hz"),
        };
        let scenario = fixtures::catalog::bench(interval_ms, hours);
        let root = out.unwrap_or_else(|| workspace_root().join("target/bench-data"));
        let dir = root.join(&scenario.name);
        fixtures::write::write_dataset(&scenario, &dir)?;
        eprintln!("fixtures: wrote {}", dir.display());
        return Ok(());
    }
    let root = out.unwrap_or_else(fixtures::fixtures_dir);
    if let Some(name) = only
        .as_deref()
        .filter(|n| !fixtures::catalog::ALL.contains(n))
    {
        bail!(
            "--only {name}: the datasets are {}",
            fixtures::catalog::ALL.join(", ")
        );
    }
    for name in fixtures::catalog::ALL
        .iter()
        .filter(|n| only.as_deref().is_none_or(|o| o == **n))
    {
        fixtures::generate(name, &root)?;
        eprintln!("fixtures: wrote {}", root.join(name).display());
    }
    Ok(())
}

/// `cargo xtask plan`: a plan's predictions, as a table or JSON.
fn plan_command(plan: &Path, json: bool) -> Result<()> {
    let text =
        std::fs::read_to_string(plan).with_context(|| format!("reading {}", plan.display()))?;
    // An antenna array's plan (docs/planning.md, "An antenna array"): its own table.
    if toml::from_str::<toml::Table>(&text).is_ok_and(|t| t.contains_key("array")) {
        use adjust::survey::gravity::array_plan;
        let parsed: array_plan::ArrayPlan =
            toml::from_str(&text).with_context(|| format!("{}", plan.display()))?;
        let rows = array_plan::predict(&parsed).with_context(|| format!("{}", plan.display()))?;
        return match json {
            true => print_stdout(&serde_json::to_string_pretty(&rows)?),
            false => print_stdout(&array_plan::render(&parsed, &rows)),
        };
    }
    let parsed: adjust::calibration::plan::Plan =
        toml::from_str(&text).with_context(|| format!("{}", plan.display()))?;
    let predictions = adjust::calibration::plan::predict(&parsed)
        .with_context(|| format!("{}", plan.display()))?;
    if json {
        print_stdout(&serde_json::to_string_pretty(&predictions)?)
    } else {
        print_stdout(&adjust::calibration::plan::render(&predictions))
    }
}

/// `cargo xtask bench`: one stage's benchmark.
fn bench_command(a: &BenchArgs) -> Result<()> {
    let root = workspace_root();
    let release = bench::Build::Release;
    match a.what.as_str() {
        "ingest" => bench::ingest(&root, a.hours, !a.no_peers, a.runs.max(1), release),
        "align" => bench::align(&root, a.stations, a.readings, release),
        "adjust" => bench::adjust(&root, a.observations, !a.no_peers, release),
        "apply" => bench_apply::apply(&root, a.hours, !a.no_peers, a.runs.max(1), release),
        "gravity" | "marine" => {
            let py = if a.no_peers {
                None
            } else {
                peers_venv()?;
                Some(root.join("target/peers-venv/bin/python")).filter(|p| p.exists())
            };
            let bench = bench_gravity::SurveyBench {
                root: &root,
                hours: a.hours,
                runs: a.runs.max(1),
                peers: py.as_deref(),
                build: release,
            };
            if a.what == "marine" {
                bench_gravity::marine(&bench)
            } else {
                bench_gravity::gravity(&bench)
            }
        }
        "smoke" => bench_smoke(),
        other => bail!(
            "no benchmark `{other}`: there are ingest, align, adjust, apply, gravity, marine \
             (and smoke: each once on a small size, as CI runs them)"
        ),
    }
}

/// Prints to stdout; a reader that went away (a closed pipe) is not an error.
fn print_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    match writeln!(std::io::stdout().lock(), "{text}") {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::recompiled_registry_crates;

    /// Only a registry crate compiled anew counts: one found fresh, a workspace crate
    /// compiled anew and cargo's other messages do not.
    #[test]
    fn a_registry_crate_compiled_again_is_named() {
        let messages = [
            r#"{"reason":"compiler-artifact","package_id":"registry+https://github.com/rust-lang/crates.io-index#arrow-array@60.1.0","fresh":false}"#,
            r#"{"reason":"compiler-artifact","package_id":"registry+https://github.com/rust-lang/crates.io-index#faer@0.24.0","fresh":true}"#,
            r#"{"reason":"compiler-artifact","package_id":"path+file:///w/ingest#0.1.0","fresh":false}"#,
            r#"{"reason":"build-finished","success":true}"#,
            "   Compiling arrow-array v60.1.0",
        ]
        .join("\n");
        assert_eq!(
            recompiled_registry_crates(&messages).expect("cargo's messages"),
            ["arrow-array@60.1.0"]
        );
    }
}
