//! Command-line entry of the `report` stage, for running it alone while debugging.

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal report: stage outputs to a self-contained HTML report and a Markdown summary.
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
    match report::run(&args.dataset, &out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e @ report::Error::NotBuilt) => {
            eprintln!("gravcal-report: {e}");
            ExitCode::from(3)
        }
        Err(e) => {
            eprintln!("gravcal-report: error: {e}");
            ExitCode::FAILURE
        }
    }
}
