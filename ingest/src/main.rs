//! Command-line entry of the `ingest` stage, for running it alone while debugging.

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal ingest: raw logs (binary .gcb or CSV, theodolite log) to Parquet tables with a ledger of every byte.
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
    match ingest::run(&args.dataset, &out) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e @ ingest::Error::NotBuilt) => {
            eprintln!("gravcal-ingest: {e}");
            ExitCode::from(3)
        }
        Err(e) => {
            eprintln!("gravcal-ingest: error: {e}");
            ExitCode::FAILURE
        }
    }
}
