//! The local executor: units in parallel on this machine's rayon pool.
//!
//! Every thread of the pool takes the next unit from one queue, in the order given (longest
//! expected first), so the last units of a generation are short ones. Units are not rayon tasks:
//! a thread waiting inside a unit (for the per-action fits it split off, say) can only steal such
//! inner work, never a whole other unit, and when the queue runs dry the idle threads take the
//! per-action fits of the units still running.

use super::Executor;
use crate::error::Result;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Runs units on the rayon pool (`--jobs` threads).
#[derive(Debug, Default, Clone, Copy)]
pub struct Local;

impl Executor for Local {
    fn run(
        &self,
        ids: &[String],
        work: &(dyn Fn(&str) -> Result<()> + Sync),
        done: &(dyn Fn(&str) + Sync),
        stop: &AtomicBool,
    ) -> Result<()> {
        let next = AtomicUsize::new(0);
        let first_error = Mutex::new(None);
        let workers = rayon::current_num_threads().min(ids.len());
        rayon::scope(|s| {
            for _ in 0..workers {
                s.spawn(|_| {
                    loop {
                        if stop.load(Ordering::SeqCst) || first_error.lock().expect("error slot").is_some() {
                            return;
                        }
                        let Some(id) = ids.get(next.fetch_add(1, Ordering::SeqCst)) else { return };
                        match work(id) {
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
            None => Ok(()),
        }
    }
}
