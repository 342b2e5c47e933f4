//! Command-line entry of the `ingest` stage, for running it alone while debugging.

use clap::Parser;
use std::path::PathBuf;
use std::process::ExitCode;

/// gravcal ingest: raw logs (binary .gcb or CSV, theodolite log) to Parquet tables with a
/// ledger of every byte, under OUT/ingest/.
#[derive(Parser)]
#[command(version)]
struct Args {
    /// Dataset folder (holding dataset.toml).
    dataset: PathBuf,
    /// Output folder OUT (default: out/<dataset folder name>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Count and list malformed text lines instead of stopping at the first one.
    #[arg(long)]
    skip_bad_lines: bool,
    /// Print `peak_rss_kb N` (the process's peak resident memory) and `cpu_s S` (its CPU
    /// time) at the end, for benchmarks.
    #[arg(long, hide = true)]
    report_peak_rss: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let out = args
        .out
        .unwrap_or_else(|| PathBuf::from("out").join(args.dataset.file_name().unwrap_or_default()));
    let opts = ingest::Options {
        skip_bad_lines: args.skip_bad_lines,
        progress: true,
    };
    match ingest::run_with(&args.dataset, &out, &opts) {
        Ok(report) => {
            ingest::print_summary(&report, &mut std::io::stderr());
            if args.report_peak_rss {
                ingest::print_usage();
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("gravcal-ingest: error: {e}");
            ExitCode::FAILURE
        }
    }
}
