//! The local executor: units in parallel on this machine's rayon pool.

use super::Executor;
use crate::error::Result;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Runs units on the rayon pool (`--jobs` threads).
#[derive(Debug, Default, Clone, Copy)]
pub struct Local;

impl Executor for Local {
    fn run(
        &self,
        ids: &[String],
        work: &(dyn Fn(&str) -> Result<()> + Sync),
        done: &(dyn Fn() + Sync),
        stop: &AtomicBool,
    ) -> Result<()> {
        // One unit per task: units are long (whole FQI runs), so scheduling overhead is irrelevant and
        // fine-grained stealing keeps both cores busy until the end of a generation.
        ids.par_iter().with_max_len(1).try_for_each(|id| {
            if stop.load(Ordering::SeqCst) {
                return Ok(());
            }
            work(id)?;
            done();
            Ok(())
        })
    }
}
