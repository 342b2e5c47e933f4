//! The survey half of adjust, after a calibration: applying it to a survey's samples
//! ([`apply`], the apply stage) and reducing the survey to gravity along the track
//! ([`gravity`], the gravity stage, which reads apply's output). Each has its own error
//! type.

pub mod apply;
pub mod gravity;
