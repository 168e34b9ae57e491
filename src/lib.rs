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
pub mod fqe;
pub mod fqi;
pub mod ga;
pub mod learn;
pub mod limits;
pub mod machine;
pub mod model;
pub mod offline;
pub mod progress;
pub mod report;
pub mod rng;
pub mod rollout;
pub mod run_dir;
pub mod runs;
pub mod selection;
pub mod spec;
pub mod stats;
pub mod store;
pub mod table;
#[cfg(test)]
pub(crate) mod testkit;
pub mod tuned;
pub mod work;

pub use error::{Error, Result};

/// Prints `message` on stderr the first time this process says it (a spec resolved several times
/// in one command warns once).
pub fn warn_once(message: &str) {
    static SAID: std::sync::Mutex<Option<std::collections::HashSet<String>>> = std::sync::Mutex::new(None);
    let mut said = SAID.lock().unwrap_or_else(|p| p.into_inner());
    if said.get_or_insert_with(Default::default).insert(message.to_string()) {
        eprintln!("{message}");
    }
}
