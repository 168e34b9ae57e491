//! bfqi-ga: Boosted Fitted Q-Iteration with a genetic algorithm for its neural network's settings.
//!
//! Data flows one way: spec → datasets → learner → FQI → evaluation → fitness → GA → tuned config →
//! comparison → report. Each module is one of those concepts.

pub mod batch;
pub mod bench;
pub mod cli;
pub mod clock;
pub mod compare;
pub mod dashboard;
pub mod dataset;
pub mod env;
pub mod error;
pub mod eval;
pub mod exec;
pub mod experiment;
pub mod export;
pub mod fqi;
pub mod ga;
pub mod learn;
pub mod limits;
pub mod machine;
pub mod model;
pub mod progress;
pub mod report;
pub mod rng;
pub mod rollout;
pub mod run_dir;
pub mod runs;
pub mod spec;
pub mod stats;
pub mod store;
pub mod table;
#[cfg(test)]
pub(crate) mod testkit;
pub mod tuned;
pub mod work;

pub use error::{Error, Result};
