//! Command-line entry of the `report` stage, for running it alone while debugging.

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal report: the outputs of ingest, align and adjust (under OUT) to OUT/report:
/// index.html (self-contained), report.md and the plots as SVG.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// Dataset folder (holding dataset.toml).
    dataset: PathBuf,
    /// Output folder OUT (default: out/<dataset folder name>).
    #[arg(long)]
    out: Option<PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("out").join(args.dataset.file_name().unwrap_or_default()));
    match report::run(&args.dataset, &out) {
        Ok(w) => {
            eprintln!(
                "report: wrote {} and {} ({} plots)",
                w.html.display(),
                w.markdown.display(),
                w.plots
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("gravcal-report: error: {e}");
            ExitCode::FAILURE
        }
    }
}
