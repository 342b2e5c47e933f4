//! gravcal's `align` stage: ingest tables to observations: one row per theodolite reading and accelerometer.
//!
//! Not built yet: issue #4 builds it. Until then [`run`] says so and fails, so that
//! nothing downstream mistakes an empty folder for a result.

use std::path::Path;

/// What can go wrong in this stage.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The stage has not been implemented yet.
    #[error("the align stage is not built yet (issue #4)")]
    NotBuilt,
}

/// Runs the stage on `dataset`, writing under `out`.
pub fn run(dataset: &Path, out: &Path) -> Result<(), Error> {
    let _ = (dataset, out);
    Err(Error::NotBuilt)
}
