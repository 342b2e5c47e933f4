//! Command-line entry of the `adjust` stage: runs the stage alone on OUT/align, or fits a
//! polynomial to a CSV table (`fit`, FORMATS.md section 7).

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
    Fit(FitArgs),
}

/// Arguments of `fit`.
#[derive(clap::Args)]
pub struct FitArgs {
    /// CSV table with a header line.
    #[arg(long)]
    input: PathBuf,
    /// Column of x.
    #[arg(long)]
    x: String,
    /// Column of y.
    #[arg(long)]
    y: String,
    /// Column of the sd of x (errors in both variables).
    #[arg(long)]
    sigma_x: Option<String>,
    /// Column of the sd of y (default: unit weights).
    #[arg(long)]
    sigma_y: Option<String>,
    /// Polynomial degree, 0..=10.
    #[arg(long, default_value_t = 1)]
    degree: usize,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match (args.cmd, args.dataset) {
        (Some(Cmd::Fit(f)), _) => {
            match adjust::fit_csv(
                &f.input,
                &f.x,
                &f.y,
                f.sigma_x.as_deref(),
                f.sigma_y.as_deref(),
                f.degree,
            ) {
                Ok(out) => {
                    println!(
                        "{}",
                        serde_json::to_string_pretty(&out).expect("serialises")
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("gravcal-adjust fit: error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        (None, Some(dataset)) => {
            let out = args.out.unwrap_or_else(|| {
                PathBuf::from("out").join(dataset.file_name().unwrap_or_default())
            });
            match adjust::run(&dataset, &out) {
                Ok(c) => {
                    adjust::print_summary(&c, &mut std::io::stderr());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("gravcal-adjust: error: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        (None, None) => {
            eprintln!("gravcal-adjust: give a dataset folder, or `fit --input ...` (see --help)");
            ExitCode::from(2)
        }
    }
}
