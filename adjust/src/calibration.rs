//! The calibration half of adjust: the condition equations ([`model`]), one calibration
//! fit with data snooping ([`calibrate`]), the triad ([`triad`], [`triad_fits`]), the
//! planner ([`plan`]), the homogeneity of per-session fits ([`repeatability`]), align's
//! tables read ([`io`]), and the stage's fits to make (`jobs`), their results as
//! calibration.json holds them (`results`) and the files written (`outputs`), which the
//! crate root's `run` drives.

pub mod calibrate;
pub mod model;
pub mod plan;
pub mod repeatability;
pub mod triad;
pub mod triad_fits;

pub(crate) mod jobs;
pub(crate) mod outputs;
pub(crate) mod results;
