//! Command-line entry of the `adjust` stage: runs the stage alone on OUT/align, or fits a
//! polynomial to a CSV table (`fit`, docs/formats.md section 7).

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal adjust: observations (OUT/align) to calibration functions (OUT/adjust) by a
/// Gauss-Helmert adjustment; or `fit` a polynomial to a CSV table.
#[derive(Parser)]
#[command(version, args_conflicts_with_subcommands = true)]
struct Args {
    #[command(subcommand)]
    cmd: Option<Cmd>,
    /// Dataset folder (holding dataset.toml).
    dataset: Option<PathBuf>,
    /// Output folder OUT, holding ingest/ and align/ (default: out/<dataset folder name>).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Subcommand)]
enum Cmd {
    /// Fits y = sum p_j x^j to two columns of a CSV table; prints JSON.
    Fit(adjust::FitArgs),
    /// For `cargo xtask bench adjust`: times the linear calibration of the observations in a
    /// CSV (dz_rad,sigma_dz_rad,ng,sigma_ng) and prints seconds and peak memory.
    #[command(hide = true)]
    BenchFit {
        /// The observations.
        #[arg(long)]
        input: PathBuf,
        /// Gravity, mGal.
        #[arg(long)]
        g_mgal: f64,
    },
}

fn bench_fit(input: &std::path::Path, g_mgal: f64) -> Result<String, String> {
    let text = std::fs::read_to_string(input).map_err(|e| format!("{}: {e}", input.display()))?;
    // As many as the lines less the header: a vector grown by doubling to a million
    // observations held 5 % more than it needed.
    let mut obs = Vec::with_capacity(text.lines().count().saturating_sub(1));
    for (n, line) in text.lines().enumerate().skip(1) {
        let v: Vec<f64> = line
            .split(',')
            .map(|x| x.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("line {}: {e}", n + 1))?;
        if v.len() != 4 {
            return Err(format!("line {}: 4 fields expected", n + 1));
        }
        obs.push(adjust::calibration::calibrate::Obs {
            dz_rad: v[0],
            sigma_dz_rad: v[1],
            sigma_dz_dof: None,
            sigma_dz_left_out: None,
            station: n,
            session: 0,
            time_s: n as f64,
            roll_rad: 0.0,
            ng: v[2],
            sigma_ng: v[3],
            sigma_ng_dof: None,
            temperature_c: 20.0,
            sigma_temperature_c: 0.0,
            tide_mgal: 0.0,
        });
    }
    // The file's text is not the adjustment's: gone before it starts.
    drop(text);
    let terms = adjust::calibration::model::Terms {
        order: 1,
        temperature: false,
        misalignment: adjust::calibration::model::Misalignment::None,
    };
    let cpu0 = ingest::cpu_seconds();
    let t0 = std::time::Instant::now();
    let f = adjust::calibration::calibrate::calibrate_with(
        &obs,
        terms,
        g_mgal,
        &adjust::calibration::calibrate::FitOptions {
            snooping: adjust::calibration::calibrate::Snooping::Off,
            coloured: None,
            components: false,
        },
    )
    .map_err(|e| e.to_string())?;
    let flagged = f
        .residuals
        .iter()
        .filter(|r| r.w.abs() > adjust::calibration::calibrate::W_CRITICAL)
        .count();
    let seconds = t0.elapsed().as_secs_f64();
    // CPU time of all threads over the fit (null where /proc is not there).
    let cpu = cpu0
        .zip(ingest::cpu_seconds())
        .map_or("null".to_owned(), |(a, b)| format!("{}", b - a));
    Ok(format!(
        "{{\"observations\": {}, \"seconds\": {seconds}, \"cpu_seconds\": {cpu}, \"iterations\": {}, \"flagged\": {flagged}, \"b\": {}, \"k\": {}, \"peak_rss_kb\": {}}}",
        obs.len(),
        f.iterations,
        f.values[0],
        f.values[1],
        ingest::peak_rss_kb().unwrap_or(0)
    ))
}

/// Prints to stdout; a reader that went away (a closed pipe) is not an error.
fn print_stdout(text: &str) -> ExitCode {
    use std::io::Write;
    match writeln!(std::io::stdout().lock(), "{text}") {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            eprintln!("gravcal-adjust: error: writing to stdout: {e}");
            ExitCode::FAILURE
        }
        _ => ExitCode::SUCCESS,
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    match (args.cmd, args.dataset) {
        (Some(Cmd::Fit(f)), _) => match adjust::fit_csv(&f) {
            Ok(out) => match serde_json::to_string_pretty(&out) {
                Ok(json) => print_stdout(&json),
                Err(e) => {
                    eprintln!("gravcal-adjust fit: error: {e}");
                    ExitCode::FAILURE
                }
            },
            Err(e) => {
                eprintln!("gravcal-adjust fit: error: {e}");
                ExitCode::FAILURE
            }
        },
        (Some(Cmd::BenchFit { input, g_mgal }), _) => match bench_fit(&input, g_mgal) {
            Ok(json) => print_stdout(&json),
            Err(e) => {
                eprintln!("gravcal-adjust bench-fit: error: {e}");
                ExitCode::FAILURE
            }
        },
        (None, Some(dataset)) => {
            let stage = ingest::base::cli::StageArgs {
                dataset,
                out: args.out,
            };
            let result = adjust::run(&stage.dataset, &stage.out_dir());
            ingest::base::cli::finish("adjust", result, false, |c| {
                adjust::print_summary(c, &mut std::io::stderr());
            })
        }
        (None, None) => {
            eprintln!("gravcal-adjust: give a dataset folder, or `fit --input ...` (see --help)");
            ExitCode::from(2)
        }
    }
}
