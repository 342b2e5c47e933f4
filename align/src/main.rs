//! Command-line entry of the `align` stage, for running it alone while debugging.

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal align: ingest tables to observations: one row per theodolite reading and accelerometer.
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
    match align::run(&args.dataset, &out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e @ align::Error::NotBuilt) => {
            eprintln!("gravcal-align: {e}");
            ExitCode::from(3)
        }
        Err(e) => {
            eprintln!("gravcal-align: error: {e}");
            ExitCode::FAILURE
        }
    }
}
