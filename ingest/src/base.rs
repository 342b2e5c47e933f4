//! What every stage of the workspace shares that is not the data contract: the command
//! line's common options and output folder ([`cli`]), the output folder's lock ([`lock`]),
//! time scales and forms ([`time`]), the time gate every reader passes ([`timegate`]),
//! and the run's CPU time and peak memory (`probes`).

pub mod cli;
pub mod lock;
pub(crate) mod probes;
pub mod time;
pub mod timegate;
