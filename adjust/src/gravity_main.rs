//! Command-line entry of the gravity stage: a survey reduced to gravity along the track
//! (docs/formats.md 10), apply run first. `cargo xtask gravity` also runs the survey's own
//! pipeline and its report around it; this binary is the stage alone, for benchmarks.

use clap::Parser;
use std::process::ExitCode;

/// gravcal gravity: OUT/apply/ and OUT/gravity/gravity.parquet and gravity.json.
#[derive(Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    gravity: adjust::gravity::stage::GravityArgs,
    /// Print `peak_rss_kb N` and `cpu_s S` at the end, for benchmarks.
    #[arg(long, hide = true)]
    report_peak_rss: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let out = args.gravity.out.clone().unwrap_or_else(|| {
        std::path::Path::new("out").join(args.gravity.dataset.file_name().unwrap_or_default())
    });
    match args.gravity.run(&out) {
        Ok(report) => {
            adjust::gravity::stage::print_summary(&report, &mut std::io::stderr());
            if args.report_peak_rss {
                ingest::print_usage();
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("gravcal-gravity: error: {e}");
            ExitCode::FAILURE
        }
    }
}
