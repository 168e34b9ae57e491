//! The local executor: units in parallel on this machine's rayon pool.
//!
//! Every thread of the pool takes the next unit from one queue, in the order given (longest
//! expected first), so the last units of a generation are short ones. Units are not rayon tasks:
//! a thread waiting inside a unit (for the per-action fits it split off, say) can only steal such
//! inner work, never a whole other unit, and when the queue runs dry the idle threads take the
//! per-action fits of the units still running.

use super::Executor;
use crate::error::Result;
use crate::run_dir::{Budget, Stop, Units};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Runs units on the rayon pool (`--jobs` threads).
#[derive(Debug, Default, Clone, Copy)]
pub struct Local;

impl Executor for Local {
    fn run(
        &self,
        units: &dyn Units,
        ids: &[String],
        budget: &Budget<'_>,
        done: &(dyn Fn(&str) + Sync),
    ) -> Result<Option<Stop>> {
        let next = AtomicUsize::new(0);
        let first_error = Mutex::new(None);
        let stopped = Mutex::new(None);
        let workers = rayon::current_num_threads().min(ids.len());
        rayon::scope(|s| {
            for _ in 0..workers {
                s.spawn(|_| {
                    loop {
                        if first_error.lock().expect("error slot").is_some() {
                            return;
                        }
                        // Checked before every unit, so a budget ends the run between units.
                        if let Some(stop) = budget.check() {
                            stopped.lock().expect("stop slot").get_or_insert(stop);
                            return;
                        }
                        let Some(id) = ids.get(next.fetch_add(1, Ordering::SeqCst)) else { return };
                        match units.compute(id) {
                            Ok(()) => done(id),
                            Err(e) => {
                                first_error.lock().expect("error slot").get_or_insert(e);
                                return;
                            }
                        }
                    }
                });
            }
        });
        match first_error.into_inner().expect("error slot") {
            Some(e) => Err(e),
            None => Ok(stopped.into_inner().expect("stop slot")),
        }
    }
}
