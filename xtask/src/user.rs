//! The commands a user runs besides the stages: `init` (a draft manifest from a folder of
//! logs, with `preflight`, check's readers run on it first), `check` (a dataset read and
//! refused or passed before a run) and `show` (a table or ledger printed).

pub mod check;
pub mod init;
pub mod preflight;
pub mod show;
