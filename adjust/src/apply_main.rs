//! Command-line entry of the `apply` stage: a calibration applied to a dataset's
//! acceleration stream (docs/formats.md 8.5).

use clap::Parser;
use std::process::ExitCode;

/// gravcal apply: a survey's samples to accelerations in mGal with sigmas and flags
/// (OUT/apply/acceleration.parquet and apply.json), ingesting the survey first if needed.
#[derive(Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    apply: adjust::survey::apply::stream::ApplyArgs,
    /// Print `peak_rss_kb N` and `cpu_s S` at the end, for benchmarks.
    #[arg(long, hide = true)]
    report_peak_rss: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = args.apply.run(std::path::Path::new("."));
    ingest::base::cli::finish("apply", result, args.report_peak_rss, |r| {
        adjust::survey::apply::stream::print_summary(r, &mut std::io::stderr());
    })
}
