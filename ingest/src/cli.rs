//! What every stage's binary shares: the dataset and output folder it takes, and how it
//! ends (its summary, and for benchmarks the process's usage; or its error and exit 1).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The dataset and the output folder a stage's binary takes.
#[derive(clap::Args, Clone, Debug)]
pub struct StageArgs {
    /// Dataset folder (holding dataset.toml).
    pub dataset: PathBuf,
    /// Output folder OUT, holding the earlier stages' folders (default: out/<dataset folder
    /// name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

impl StageArgs {
    /// OUT: `--out`, or out/<dataset folder name> in the working directory.
    pub fn out_dir(&self) -> PathBuf {
        out_dir(Path::new(""), &self.dataset, self.out.as_deref())
    }
}

/// A stage's OUT: `out` when given, else `root`/out/<dataset folder name>.
pub fn out_dir(root: &Path, dataset: &Path, out: Option<&Path>) -> PathBuf {
    out.map_or_else(
        || {
            root.join("out")
                .join(dataset.file_name().unwrap_or_default())
        },
        Path::to_path_buf,
    )
}

/// A stage binary's end: on success `summary` of its report and, with `usage`, the
/// process's peak memory and CPU time ([`crate::print_usage`]), exit 0; on failure
/// `gravcal-<stage>: error: ...`, exit 1.
pub fn finish<R, E: std::fmt::Display>(
    stage: &str,
    result: Result<R, E>,
    usage: bool,
    summary: impl FnOnce(&R),
) -> ExitCode {
    match result {
        Ok(report) => {
            summary(&report);
            if usage {
                crate::print_usage();
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("gravcal-{stage}: error: {e}");
            ExitCode::FAILURE
        }
    }
}
