//! The developers' tasks: `bench` (with `bench_apply` and `bench_gravity`, each beside its
//! peer in one run), `digest` (the refactoring net over every fixture) and `verdicts` (the
//! Monte-Carlos' error rates in one table).

pub mod bench;
pub mod bench_apply;
pub mod bench_gravity;
pub mod digest;
pub mod verdicts;
