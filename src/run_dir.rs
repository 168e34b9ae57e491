//! A run directory of units: what a search and a comparison have in common, and all an executor
//! needs to know about either.
//!
//! A run (a search's generations, a comparison's analyses) is split into units of work, each named
//! by an id and stored as one JSON file, written atomically, in a folder of the run directory
//! (`units/<id>.json`; a search's validation units in `validation/<id>.json`). Results are always
//! read back from those files, so a run stopped for any reason resumes by computing the units that
//! are missing. A run stops between units when its [`Budget`] says so (Ctrl-C or the time budget)
//! and ends in one of the ways of [`Ending`].
//!
//! Executors ([`crate::exec`]) see a run only through [`Units`]; the run kinds themselves, and the
//! dispatch from a directory to its kind, live above (`ga`, `compare`, [`crate::runs`]).

use crate::error::Result;
use crate::store;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The folder of a run directory where units are stored, one `<id>.json` each.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnitStore {
    folder: PathBuf,
}

impl UnitStore {
    /// The units of the run in `run_dir`: its `units/` folder.
    pub fn units(run_dir: &Path) -> Self {
        Self::named(run_dir, "units")
    }

    /// Units in the folder `name` of `run_dir` (a search's validation units: `validation`).
    pub fn named(run_dir: &Path, name: &str) -> Self {
        UnitStore { folder: run_dir.join(name) }
    }

    /// Where unit `id` is stored.
    pub fn path(&self, id: &str) -> PathBuf {
        self.folder.join(format!("{id}.json"))
    }

    /// The folder.
    pub fn folder(&self) -> &Path {
        &self.folder
    }

    /// The folder's name in the run directory (`units`, `validation`).
    pub fn name(&self) -> &str {
        self.folder.file_name().and_then(|n| n.to_str()).unwrap_or("units")
    }

    /// Makes the folder ready for a run: created if missing (a deleted `units/` is made again), and
    /// cleared of the temporary files of atomic writes a kill interrupted. Call it with the run's
    /// lock held, so that no writer is alive.
    pub fn prepare(&self) -> Result<()> {
        store::create_dir(&self.folder)?;
        store::remove_temporaries(&self.folder)
    }

    /// The ids of the files in the folder, sorted (whether or not they are whole).
    pub fn ids(&self) -> Vec<String> {
        let mut ids: Vec<String> = std::fs::read_dir(&self.folder)
            .map(|d| {
                d.flatten()
                    .filter_map(|e| e.file_name().to_str().and_then(|n| n.strip_suffix(".json")).map(String::from))
                    .collect()
            })
            .unwrap_or_default();
        ids.sort();
        ids
    }
}

/// The units of one run, as an executor sees them: where they live, whether one is stored, and how
/// one is computed.
pub trait Units: Sync {
    /// Where the units are stored.
    fn store(&self) -> &UnitStore;
    /// Whether unit `id` is stored whole and belongs to this run (a damaged file, or one from another
    /// spec, is not: it is computed again).
    fn stored(&self, id: &str) -> bool;
    /// Computes unit `id` and stores its result atomically.
    fn compute(&self, id: &str) -> Result<()>;
}

/// What `bfqi-ga stamp` did to a run made before every unit carried a checksum.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stamped {
    /// Units that verified and had no checksum: given one (and their run's hash where they lacked
    /// it), their content unchanged.
    pub stamped: usize,
    /// Units that carried a checksum already.
    pub already: usize,
    /// Units that do not verify, each with its path and what is wrong: left as they are, computed
    /// again on resume.
    pub unverified: Vec<(PathBuf, String)>,
}

/// Why a run stopped before its end; it resumes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stop {
    /// Ctrl-C.
    Interrupted,
    /// The time budget of this invocation, in hours, ran out.
    Budget(f64),
    /// Units still missing after the executor ran (a Slurm executor told to stop before its retries).
    Missing(usize),
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stop::Interrupted => write!(f, "interrupted"),
            // `1e-300`, not the 300 digits of f64's Display; `1.53`, not an `--until`'s 1.5316666666666667.
            Stop::Budget(h) if *h >= 0.01 => {
                let two = format!("{h:.2}");
                write!(f, "time budget of {} h reached", two.trim_end_matches('0').trim_end_matches('.'))
            }
            Stop::Budget(h) => write!(f, "time budget of {} h reached", crate::error::short_number(h.to_string())),
            Stop::Missing(n) => write!(f, "{n} unit(s) missing after evaluation"),
        }
    }
}

/// How a run (a search, a comparison, a batch of them) ended without an error.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// It ran to its end; why it ended (generations reached, no improvement, every unit done).
    Finished(String),
    /// It stopped early and resumes.
    Stopped(Stop),
    /// It ran to its end, and parts of it failed (a batch's jobs): what failed.
    Failed(String),
}

/// When a run must stop: Ctrl-C, or this invocation's wall-clock budget. Checked before each unit
/// starts; units under way finish.
#[derive(Debug, Clone, Copy)]
pub struct Budget<'a> {
    interrupt: &'a AtomicBool,
    max_hours: Option<f64>,
    started: Instant,
}

impl<'a> Budget<'a> {
    /// A budget of `max_hours` from now (none: no limit), stopped early by `interrupt`.
    pub fn new(interrupt: &'a AtomicBool, max_hours: Option<f64>) -> Self {
        Budget { interrupt, max_hours, started: Instant::now() }
    }

    /// Why the run must stop now, if it must: Ctrl-C first, then the budget.
    pub fn check(&self) -> Option<Stop> {
        if self.interrupt.load(Ordering::SeqCst) {
            return Some(Stop::Interrupted);
        }
        let h = self.max_hours?;
        (self.started.elapsed().as_secs_f64() > h * 3600.0).then_some(Stop::Budget(h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_stops_on_interrupt_first_then_on_time() {
        let flag = AtomicBool::new(false);
        assert_eq!(Budget::new(&flag, None).check(), None);
        assert_eq!(Budget::new(&flag, Some(1.0)).check(), None);
        assert_eq!(
            Budget::new(&flag, Some(0.0)).check().map(|s| s.to_string()),
            Some("time budget of 0 h reached".into())
        );
        flag.store(true, Ordering::SeqCst);
        assert_eq!(Budget::new(&flag, Some(0.0)).check(), Some(Stop::Interrupted));
    }

    #[test]
    fn a_budget_reads_as_typed_or_to_two_decimals() {
        let said = |h: f64| Stop::Budget(h).to_string();
        assert_eq!(said(1.5316666666666667), "time budget of 1.53 h reached", "an --until's budget");
        assert_eq!(said(2.0), "time budget of 2 h reached");
        assert_eq!(said(0.5), "time budget of 0.5 h reached");
        assert_eq!(said(0.000000001), "time budget of 0.000000001 h reached", "a tiny budget as typed");
        assert_eq!(said(1e-300), "time budget of 1e-300 h reached");
    }

    #[test]
    fn a_store_lists_its_ids_and_clears_temporaries() {
        let dir = std::env::temp_dir().join(format!("bfqi-run-dir-{}", std::process::id()));
        let units = UnitStore::units(&dir);
        units.prepare().unwrap();
        store::write_json(&units.path("b.d1"), &1).unwrap();
        store::write_json(&units.path("a.d0"), &2).unwrap();
        std::fs::write(units.folder().join(".a.d2.json.tmp"), "{").unwrap();
        units.prepare().unwrap();
        assert_eq!(units.ids(), ["a.d0", "b.d1"]);
        assert_eq!(units.path("a.d0"), dir.join("units").join("a.d0.json"));
        std::fs::remove_dir_all(dir).unwrap();
    }
}
