//! Command-line entry of the `report` stage, for running it alone while debugging.

use clap::Parser;
use std::process::ExitCode;

/// gravcal report: the outputs of ingest, align and adjust (under OUT) to OUT/report:
/// index.html (self-contained), report.md and the plots as SVG.
#[derive(Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    stage: ingest::base::cli::StageArgs,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = report::run(&args.stage.dataset, &args.stage.out_dir());
    ingest::base::cli::finish("report", result, false, |w| {
        eprintln!(
            "report: wrote {} and {} ({} plots)",
            w.html.display(),
            w.markdown.display(),
            w.plots
        );
    })
}
