//! The gravity stage (docs/model.md 7, docs/formats.md 10): a survey's calibrated specific
//! force reduced to the gravity disturbance along the track. It reads apply's output, so it
//! lives beside apply in the adjust crate, as a module tree of its own with its own error
//! type. The pieces the navigation equation is made of, each checked against a peer
//! (`tests/gravity_peers.rs`) or the simulator's truth:
//!
//! - [`normal`] (the contract's, re-exported): GRS80 or WGS84 normal gravity at any point
//!   on or above the ellipsoid (closed form, no free-air series), against boule;
//! - [`navigation`]: the ellipsoid's radii of curvature and the Coriolis and transport-rate
//!   term of the navigation equation (its down component is the Eotvos correction),
//!   against shipgrav's Harlan (1968);
//! - [`filter`]: the zero-phase Butterworth low-pass whose response is 0.5 at the cut-off
//!   period `filter_s`, against scipy.signal's `sosfiltfilt`;
//! - [`trajectory`]: GNSS positions from RTKLIB's `.pos` or a CSV;
//! - [`attitude`]: heading, pitch and roll from a CSV, onto the trajectory's epochs;
//! - [`antennas`]: the attitude and the accelerometers' position per epoch from several
//!   GNSS antennas' positions (a weighted fit of the declared array, with its covariance);
//!   `array`: an array session's antennas read, matched by time and fitted, the fit given
//!   to its track and written as attitude.parquet; [`array_plan`]: an array sized before
//!   it is bought (`cargo xtask plan` on an `[array]` plan);
//! - `spill`: per-epoch records written aside and read back a block at a time;
//! - `track`: a session's track made ready (gated, attitude, lever arm, noise) with its
//!   kept positions written aside, only their times held;
//! - [`reduce`]: the down component along an evenly spaced stretch (or block) of track,
//!   free of I/O: kinematic acceleration and velocities by central differences, the Eotvos
//!   term, normal gravity, the filter with the stretch's ends extended consistently, ties
//!   and a drift, the sigmas apart (`tests/gravity_reduce.rs`);
//! - [`horizontal`]: north and east along a stretch with attitude, never tied, the
//!   attitude's part of their sigma apart; and the horizontal force the track gives;
//! - [`magnitude`]: an antenna array's down from the force's magnitude and the track's
//!   horizontal force, no tilt entering it;
//! - [`epochs`]: apply's calibrated samples brought onto the trajectory's epochs (with
//!   attitude, each turned into the navigation frame at its own time);
//! - [`coupling`]: a platform meter's cross-coupling, its coefficients fitted by LaCoste's
//!   method as shipgrav fits them (against shipgrav's own fit);
//! - [`meter`]: a platform meter's own record beside its readings, its monitors and status
//!   word a line, brought onto the epochs;
//! - [`crossover`]: where the track crosses itself, the two passes' difference and its
//!   sigma;
//! - [`stage`]: the run, `cargo xtask gravity` (`tests/gravity_stage.rs`: the fixture
//!   survey-lines recovered within its sigmas, its crossover within its sigma, each
//!   convention broken failing; a rolling boat with attitude, north and east within theirs).

pub mod antennas;
mod array;
pub mod array_plan;
pub mod array_positions;
pub mod attitude;
pub mod coupling;
pub mod crossover;
pub mod epochs;
pub mod errors;
pub mod filter;
pub mod horizontal;
pub mod magnitude;
pub mod meter;
pub mod navigation;
pub use ingest::contract::normal;
pub mod reduce;
pub mod spectrum;
mod spill;
pub mod stage;
mod track;
pub mod trajectory;

/// What the readers' tests share: a log written to a scratch folder, and the time form
/// their CSV logs are written in.
#[cfg(test)]
mod test_logs {
    use ingest::base::time::{TimeForm, TimeReader};
    use ingest::contract::manifest::TimeScale;

    /// `text` written as `name` in a new scratch folder (removed when the folder is
    /// dropped).
    pub(super) fn written(name: &str, text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let d = tempfile::tempdir().expect("tempdir");
        let p = d.path().join(name);
        std::fs::write(&p, text).expect("write");
        (d, p)
    }

    /// Times in Unix seconds, UTC.
    pub(super) fn unix_utc() -> TimeReader {
        TimeReader::new(TimeForm::UnixS, TimeScale::Utc, None)
    }
}

/// What can go wrong in the gravity stage.
#[derive(Debug, thiserror::Error)]
pub enum GravityError {
    /// A trajectory or attitude file that breaks its format.
    #[error("{path}:{line}: {field}: {message}")]
    Line {
        /// The file.
        path: std::path::PathBuf,
        /// Its line (1-based).
        line: u64,
        /// The field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A file as a whole that cannot serve.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        message: String,
    },
    /// A filter that cannot be built.
    #[error("filter: {0}")]
    Filter(String),
    /// A stretch of track too short for the filter.
    #[error("a stretch of {epochs} epochs ({seconds:.0} s) is too short for a {filter_s} s filter")]
    TooShort {
        /// Its epochs.
        epochs: usize,
        /// Its length, s.
        seconds: f64,
        /// The filter's cut-off period, s.
        filter_s: f64,
    },
    /// The stage cannot run as asked (what is missing or contradictory, and what would work).
    #[error("gravity: {message}")]
    Refused {
        /// Why.
        message: String,
    },
    /// A stage it runs first (ingest, apply) or a table it reads failed.
    #[error(transparent)]
    Stage(#[from] crate::Error),
    /// The manifest, a lock, a file written.
    #[error(transparent)]
    Ingest(#[from] ingest::Error),
}

/// A line of a trajectory or attitude file set aside under `--skip-bad-lines` (without it,
/// the same line is an error): where it is and why.
#[derive(Clone, Debug, PartialEq)]
pub struct BadLine {
    /// The line (1-based).
    pub line: u64,
    /// The field.
    pub field: String,
    /// What is wrong.
    pub message: String,
}

/// With `skip`, a line's error set aside into `bad`; any other error, or any error without
/// `skip`, returned.
fn set_aside(e: GravityError, skip: bool, bad: &mut Vec<BadLine>) -> Result<(), GravityError> {
    match e {
        GravityError::Line {
            line,
            field,
            message,
            ..
        } if skip => {
            bad.push(BadLine {
                line,
                field,
                message,
            });
            Ok(())
        }
        e => Err(e),
    }
}
