//! The local executor: units in parallel on this machine's rayon pool.
//!
//! Every thread of the pool takes the next unit from one queue, in the order given (longest
//! expected first), so the last units of a generation are short ones. Units are not rayon tasks:
//! a thread waiting inside a unit (for the per-action fits it split off, say) can only steal such
//! inner work, never a whole other unit, and when the queue runs dry the idle threads take the
//! per-action fits of the units still running.
//!
//! Chained units ([`Executor::run_chained`]) share one priority queue: a unit opened by one that
//! finished starts as soon as a thread is free, with no barrier between the links of the chains.
//! A thread that finds the queue empty leaves (to help with inner work, as above), and a unit that
//! opens others spawns threads for them again, up to the pool's size.

use super::{Executor, Queued};
use crate::error::{Error, Result};
use crate::run_dir::{Budget, Stop, Units};
use std::sync::Mutex;

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
        // The given order as priorities (first highest), and nothing opened: one queue, as chains.
        let first: Vec<Queued> = ids.iter().enumerate().map(|(i, id)| (id.clone(), -(i as f64))).collect();
        self.run_chained(units, first, budget, &|id: &str| {
            done(id);
            Vec::new()
        })
    }

    fn run_chained(
        &self,
        units: &dyn Units,
        first: Vec<Queued>,
        budget: &Budget<'_>,
        done: &(dyn Fn(&str) -> Vec<Queued> + Sync),
    ) -> Result<Option<Stop>> {
        let chains = Chains {
            units,
            budget,
            done,
            threads: rayon::current_num_threads(),
            queue: Mutex::new(Queue { waiting: Vec::new(), queued: 0, active: 0 }),
            first_error: Mutex::new(None),
            stopped: Mutex::new(None),
        };
        rayon::scope(|s| {
            let workers = chains.add(first, 0);
            for _ in 0..workers {
                s.spawn(|s| chains.work(s));
            }
        });
        match chains.first_error.into_inner().expect("error slot") {
            Some(e) => Err(e),
            None => Ok(chains.stopped.into_inner().expect("stop slot")),
        }
    }
}

/// The units waiting, and how many threads work on them.
struct Queue {
    /// Id, priority, and the order queued (for ties).
    waiting: Vec<(String, f64, usize)>,
    queued: usize,
    active: usize,
}

/// What the threads of one [`Local::run_chained`] call share.
struct Chains<'a> {
    units: &'a dyn Units,
    budget: &'a Budget<'a>,
    done: &'a (dyn Fn(&str) -> Vec<Queued> + Sync),
    threads: usize,
    queue: Mutex<Queue>,
    first_error: Mutex<Option<Error>>,
    stopped: Mutex<Option<Stop>>,
}

impl<'a> Chains<'a> {
    /// Queues `more` and returns how many new threads to start for them: enough that every waiting
    /// unit has one, beyond the `taking` units the calling thread takes itself, within the pool.
    fn add(&self, more: Vec<Queued>, taking: usize) -> usize {
        let mut q = self.queue.lock().expect("queue");
        for (id, p) in more {
            let n = q.queued;
            q.waiting.push((id, p, n));
            q.queued += 1;
        }
        let extra = q.waiting.len().saturating_sub(taking).min(self.threads.saturating_sub(q.active));
        q.active += extra;
        extra
    }

    /// The next unit (highest priority, then first queued), or `None` after leaving the pool of
    /// workers, all under one lock so that a unit queued meanwhile always gets a thread.
    fn take(&self) -> Option<String> {
        let mut q = self.queue.lock().expect("queue");
        let best = (0..q.waiting.len()).max_by(|&i, &j| {
            let (a, b) = (&q.waiting[i], &q.waiting[j]);
            a.1.total_cmp(&b.1).then(b.2.cmp(&a.2))
        });
        match best {
            Some(i) => Some(q.waiting.swap_remove(i).0),
            None => {
                q.active -= 1;
                None
            }
        }
    }

    fn leave(&self) {
        self.queue.lock().expect("queue").active -= 1;
    }

    fn work<'s>(&'s self, scope: &rayon::Scope<'s>)
    where
        'a: 's,
    {
        loop {
            if self.first_error.lock().expect("error slot").is_some() {
                return self.leave();
            }
            // Checked before every unit, so a budget ends the run between units.
            if let Some(stop) = self.budget.check() {
                self.stopped.lock().expect("stop slot").get_or_insert(stop);
                return self.leave();
            }
            let Some(id) = self.take() else { return };
            if let Err(e) = self.units.compute(&id) {
                // A run that failed (a gymnasium worker that crashed, say) says in which unit.
                let e = match e {
                    Error::Failed(m) => Error::Failed(format!("unit {id}: {m}")),
                    other => other,
                };
                self.first_error.lock().expect("error slot").get_or_insert(e);
                return self.leave();
            }
            let opened = (self.done)(&id);
            for _ in 0..self.add(opened, 1) {
                scope.spawn(|s| self.work(s));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run_dir::UnitStore;
    use std::collections::HashMap;
    use std::sync::atomic::AtomicBool;

    /// Units that only record the order they ran in; unit `c<k>-<d>` opens `c<k>-<d+1>` below `len`.
    struct Recorder {
        store: UnitStore,
        ran: Mutex<Vec<String>>,
        fail: Option<&'static str>,
    }

    impl Units for Recorder {
        fn store(&self) -> &UnitStore {
            &self.store
        }
        fn stored(&self, id: &str) -> bool {
            self.ran.lock().unwrap().iter().any(|r| r == id)
        }
        fn compute(&self, id: &str) -> Result<()> {
            if self.fail == Some(id) {
                return Err(Error::Failed(format!("{id} failed")));
            }
            self.ran.lock().unwrap().push(id.to_string());
            Ok(())
        }
    }

    fn recorder(fail: Option<&'static str>) -> Recorder {
        Recorder { store: UnitStore::units(std::path::Path::new("unused")), ran: Mutex::new(Vec::new()), fail }
    }

    /// Chain `k` has `lens[k]` links; each link's priority is the links left in its chain.
    fn run_chains(threads: usize, lens: &[usize], r: &Recorder, budget: &Budget<'_>) -> Result<Option<Stop>> {
        let lens: HashMap<String, usize> = lens.iter().enumerate().map(|(k, n)| (format!("c{k}"), *n)).collect();
        let first: Vec<Queued> = lens.iter().map(|(c, n)| (format!("{c}-0"), *n as f64)).collect();
        let done = |id: &str| {
            let (c, d) = id.split_once('-').unwrap();
            let d: usize = d.parse().unwrap();
            let n = lens[c];
            if d + 1 < n { vec![(format!("{c}-{}", d + 1), (n - d - 1) as f64)] } else { Vec::new() }
        };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| Local.run_chained(r, first, budget, &done))
    }

    #[test]
    fn chained_units_all_run_after_their_predecessors_longest_chain_first() {
        for threads in [1, 2, 4] {
            let r = recorder(None);
            let go = AtomicBool::new(false);
            let stop = run_chains(threads, &[3, 1, 5, 2], &r, &Budget::new(&go, None)).unwrap();
            assert_eq!(stop, None);
            let ran = r.ran.into_inner().unwrap();
            assert_eq!(ran.len(), 11, "{ran:?}");
            for id in &ran {
                let (c, d) = id.split_once('-').unwrap();
                let d: usize = d.parse().unwrap();
                let at = ran.iter().position(|x| x == id).unwrap();
                if d > 0 {
                    let before = ran.iter().position(|x| *x == format!("{c}-{}", d - 1)).unwrap();
                    assert!(before < at, "{id} ran before its predecessor: {ran:?}");
                }
            }
            if threads == 1 {
                // One thread always takes the unit with the most left in its chain, so the
                // longest chain runs first and no short one holds it up.
                assert_eq!(ran[..3], ["c2-0", "c2-1", "c0-0"], "{ran:?}");
            }
        }
    }

    #[test]
    fn chained_units_stop_at_the_budget_and_at_the_first_error() {
        let (stop_now, go) = (AtomicBool::new(true), AtomicBool::new(false));
        let r = recorder(None);
        let stop = run_chains(2, &[4, 4], &r, &Budget::new(&stop_now, None)).unwrap();
        assert_eq!(stop, Some(Stop::Interrupted));
        assert!(r.ran.into_inner().unwrap().is_empty());

        let r = recorder(Some("c0-2"));
        let e = run_chains(2, &[4, 4], &r, &Budget::new(&go, None)).unwrap_err();
        assert!(e.to_string().contains("c0-2 failed"), "{e}");
        assert!(!r.ran.into_inner().unwrap().iter().any(|x| x == "c0-3"));
    }
}
