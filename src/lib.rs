//! bfqi-ga: Boosted Fitted Q-Iteration with a genetic algorithm for its neural network's settings.
//!
//! Data flows one way: spec → datasets → learner → FQI → evaluation → fitness → GA → tuned config →
//! comparison → report. Each module is one of those concepts.

pub mod cli;
pub mod dataset;
pub mod env;
pub mod error;
pub mod eval;
pub mod fqi;
pub mod learn;
pub mod rng;
pub mod store;

pub use error::{Error, Result};
