//! Command-line entry of the `align` stage, for running it alone while debugging.

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal align: ingest tables (OUT/ingest) to observations (OUT/align): one row per
/// theodolite reading and accelerometer.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// Dataset folder (holding dataset.toml).
    dataset: PathBuf,
    /// Output folder OUT, holding ingest/ (default: out/<dataset folder name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print `peak_rss_kb N` (the process's peak resident memory) at the end, for benchmarks.
    #[arg(long, hide = true)]
    report_peak_rss: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("out").join(args.dataset.file_name().unwrap_or_default()));
    match align::run(&args.dataset, &out) {
        Ok(report) => {
            align::print_summary(&report, &mut std::io::stderr());
            if args.report_peak_rss {
                match ingest::peak_rss_kb() {
                    Some(kb) => eprintln!("peak_rss_kb {kb}"),
                    None => eprintln!("peak_rss_kb unavailable"),
                }
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("gravcal-align: error: {e}");
            ExitCode::FAILURE
        }
    }
}
