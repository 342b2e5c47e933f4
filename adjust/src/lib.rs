//! gravcal's `adjust` stage: the calibration functions by a rigorous errors-in-both-variables
//! (Gauss-Helmert) adjustment. Not complete yet: the engine ([`gh`]), the models ([`model`])
//! and the general `fit` command ([`fit`]) are built; the stage itself is issue #5.

pub mod fit;
pub mod gh;
pub mod model;

use std::path::Path;

/// What can go wrong in this stage.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The stage has not been implemented yet.
    #[error("the adjust stage is not built yet (issue #5)")]
    NotBuilt,
}

/// Runs the stage on `dataset`, writing under `out`.
pub fn run(dataset: &Path, out: &Path) -> Result<(), Error> {
    let _ = (dataset, out);
    Err(Error::NotBuilt)
}
