//! Command-line entry of the `align` stage, for running it alone while debugging.

use clap::Parser;
use std::process::ExitCode;

/// gravcal align: ingest tables (OUT/ingest) to observations (OUT/align): one row per
/// theodolite reading and accelerometer.
#[derive(Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    stage: ingest::base::cli::StageArgs,
    /// Print `peak_rss_kb N` (the process's peak resident memory) and `cpu_s S` (its CPU
    /// time) at the end, for benchmarks.
    #[arg(long, hide = true)]
    report_peak_rss: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = align::run(&args.stage.dataset, &args.stage.out_dir());
    ingest::base::cli::finish("align", result, args.report_peak_rss, |r| {
        align::print_summary(r, &mut std::io::stderr());
    })
}
