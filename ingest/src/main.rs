//! Command-line entry of the `ingest` stage, for running it alone while debugging.

use clap::Parser;
use std::process::ExitCode;

/// gravcal ingest: raw logs (binary .gcb or CSV, theodolite log) to Parquet tables with a
/// ledger of every byte, under OUT/ingest/.
#[derive(Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    stage: ingest::base::cli::StageArgs,
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
    let opts = ingest::Options {
        skip_bad_lines: args.skip_bad_lines,
        progress: true,
    };
    let result = ingest::run_with(&args.stage.dataset, &args.stage.out_dir(), &opts);
    ingest::base::cli::finish("ingest", result, args.report_peak_rss, |r| {
        ingest::print_summary(r, &mut std::io::stderr());
    })
}
