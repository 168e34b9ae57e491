//! The genetic algorithm of thesis Appendix C (SPEC §5).

pub mod chromosome;
pub mod fitness;
pub mod operators;
pub mod prune;
pub mod race;
pub mod racing;
pub mod records;
mod reproduce;
mod runner;
pub mod search;
pub mod setup;
pub mod status;
pub mod tidy;
pub mod units;
pub mod validate;
pub mod winner;
