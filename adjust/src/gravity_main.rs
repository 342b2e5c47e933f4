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
    gravity: adjust::survey::gravity::stage::GravityArgs,
    /// Print `peak_rss_kb N` and `cpu_s S` at the end, for benchmarks.
    #[arg(long, hide = true)]
    report_peak_rss: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let out = args.gravity.apply.out_dir(std::path::Path::new("."));
    let result = args.gravity.run(&out);
    ingest::base::cli::finish("gravity", result, args.report_peak_rss, |r| {
        adjust::survey::gravity::stage::print_summary(r, &mut std::io::stderr());
    })
}
