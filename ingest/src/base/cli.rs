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

/// A stage's OUT: `out` when given, else `root`/out/<dataset folder name>, the one rule of
/// every stage's binary (`root` the working directory) and of `cargo xtask` (`root` the
/// workspace). The folder's name is its canonical path's (`.` is the folder it names), and
/// `dataset` for a path that has none.
pub fn out_dir(root: &Path, dataset: &Path, out: Option<&Path>) -> PathBuf {
    out.map_or_else(
        || {
            let named = dataset
                .canonicalize()
                .unwrap_or_else(|_| dataset.to_path_buf());
            let name = named
                .file_name()
                .unwrap_or_else(|| std::ffi::OsStr::new("dataset"));
            root.join("out").join(name)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The default OUT is named after the dataset's folder however the path is written: `.`
    /// and a trailing slash name the folder, a path not there yet its last part, the root
    /// `dataset`; `--out` wins.
    #[test]
    fn the_default_out_is_named_after_the_folder() {
        let dir = tempfile::tempdir().expect("tempdir");
        let ds = dir.path().join("cruise-7");
        std::fs::create_dir(&ds).expect("dir");
        let root = Path::new("/r");
        let want = root.join("out").join("cruise-7");
        assert_eq!(out_dir(root, &ds, None), want);
        assert_eq!(out_dir(root, &ds.join("."), None), want);
        assert_eq!(out_dir(root, &dir.path().join("cruise-7/"), None), want);
        std::fs::create_dir(ds.join("sub")).expect("sub");
        assert_eq!(out_dir(root, &ds.join("sub/.."), None), want);
        assert_eq!(
            out_dir(root, Path::new("not/there/lines"), None),
            root.join("out").join("lines")
        );
        assert_eq!(
            out_dir(root, Path::new("/"), None),
            root.join("out").join("dataset")
        );
        assert_eq!(out_dir(root, &ds, Some(Path::new("o"))), Path::new("o"));
    }
}
