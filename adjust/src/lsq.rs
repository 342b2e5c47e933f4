//! The least-squares engine, with no calibration in it: the Gauss-Helmert adjustment
//! ([`gh`]), variance components and the global test ([`components`]), and coloured ADC
//! noise and correlated theodolite errors in the weights and w-tests ([`correlated`]).

pub mod components;
pub mod correlated;
pub mod gh;
