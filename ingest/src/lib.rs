//! gravcal's `ingest` stage: raw logs (binary .gcb or CSV, theodolite log) to Parquet tables with a ledger of every byte.
//!
//! Not built yet: issue #3 builds it. Until then [`run`] says so and fails, so that
//! nothing downstream mistakes an empty folder for a result.

use std::path::Path;

/// What can go wrong in this stage.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The stage has not been implemented yet.
    #[error("the ingest stage is not built yet (issue #3)")]
    NotBuilt,
}

/// Runs the stage on `dataset`, writing under `out`.
pub fn run(dataset: &Path, out: &Path) -> Result<(), Error> {
    let _ = (dataset, out);
    Err(Error::NotBuilt)
}
