//! Command-line entry of the `adjust` stage, for running it alone while debugging.

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal adjust: observations to calibration functions by a Gauss-Helmert adjustment.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// Dataset folder (holding dataset.toml).
    dataset: PathBuf,
    /// Output folder (default: out/<dataset name>).
    #[arg(long)]
    out: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let out = args.out.unwrap_or_else(|| PathBuf::from("out"));
    match adjust::run(&args.dataset, &out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e @ adjust::Error::NotBuilt) => {
            eprintln!("gravcal-adjust: {e}");
            ExitCode::from(3)
        }
        Err(e) => {
            eprintln!("gravcal-adjust: error: {e}");
            ExitCode::FAILURE
        }
    }
}
