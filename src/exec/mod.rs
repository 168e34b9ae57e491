//! Executors: how the units of work of a search or a comparison get computed.
//!
//! An executor sees a run only as its [`Units`] (named by ids, each stored as a file of the run
//! directory) and knows nothing of searches or comparisons. Results are always read back from the
//! files, so an executor only has to get every missing file written.

pub mod local;
pub mod slurm;

use crate::error::Result;
use crate::run_dir::{Budget, Stop, Units};
use std::sync::atomic::AtomicBool;

/// Computes units of work.
pub trait Executor: Sync {
    /// Gets every unit of `ids` computed and stored, starting them in the order given (callers put
    /// the longest first), until `budget` says stop: units not yet started are then left, and the
    /// stop is returned. `done` is called with each unit's id once it is stored.
    fn run(
        &self,
        units: &dyn Units,
        ids: &[String],
        budget: &Budget<'_>,
        done: &(dyn Fn(&str) + Sync),
    ) -> Result<Option<Stop>>;

    /// Gets chains of units computed, where a unit may open further ones: starts with `first`, and
    /// once each unit is stored, `done` returns the units it opens, which join the queue. Among the
    /// units waiting, the one with the highest priority starts first (ties: the one queued first).
    /// Returns once nothing waits and nothing runs, or at a stop, as [`Executor::run`].
    ///
    /// This default runs rounds (everything queued, then everything those opened), which suits an
    /// executor that submits batches; the local executor starts opened units at once instead.
    fn run_chained(
        &self,
        units: &dyn Units,
        first: Vec<Queued>,
        budget: &Budget<'_>,
        done: &(dyn Fn(&str) -> Vec<Queued> + Sync),
    ) -> Result<Option<Stop>> {
        let mut round = first;
        while !round.is_empty() {
            round.sort_by(|a, b| b.1.total_cmp(&a.1));
            let ids: Vec<String> = round.into_iter().map(|(id, _)| id).collect();
            let opened = std::sync::Mutex::new(Vec::new());
            let note = |id: &str| {
                let more = done(id);
                opened.lock().expect("opened").extend(more);
            };
            if let Some(stop) = self.run(units, &ids, budget, &note)? {
                return Ok(Some(stop));
            }
            round = opened.into_inner().expect("opened");
        }
        Ok(None)
    }
}

/// A unit to start, by id, with its priority in the queue of [`Executor::run_chained`].
pub type Queued = (String, f64);

use crate::error::Error;
use std::path::Path;
use std::sync::atomic::Ordering;

/// Which executor (`--executor`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// This machine's threads.
    #[default]
    Local,
    /// One job array per generation or comparison; the run directory must be on a file system
    /// shared by the nodes.
    Slurm,
}

/// Where units of work run: the executor and its Slurm settings, as `search`, `compare` and
/// `batch` take them.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Options {
    /// Where units of work run.
    #[arg(long, value_enum, default_value_t, help_heading = "Executor")]
    pub executor: Kind,
    /// Slurm partition.
    #[arg(long, help_heading = "Executor")]
    pub slurm_partition: Option<String>,
    /// Slurm time limit per task, e.g. 02:00:00.
    #[arg(long, help_heading = "Executor")]
    pub slurm_time: Option<String>,
    /// CPUs per Slurm task.
    #[arg(long, help_heading = "Executor")]
    pub slurm_cpus_per_task: Option<usize>,
    /// Array tasks running at once (`%T`).
    #[arg(long, help_heading = "Executor")]
    pub slurm_max_parallel: Option<usize>,
    /// Further sbatch argument, passed through (repeatable).
    #[arg(long, allow_hyphen_values = true, help_heading = "Executor")]
    pub slurm_arg: Vec<String>,
    /// Resubmissions of missing units before giving up.
    #[arg(long, default_value_t = 2, help_heading = "Executor")]
    pub slurm_retries: usize,
    /// Seconds to wait for an unreachable Slurm controller (submissions are retried, and no unit is
    /// resubmitted while its array may still run) before stopping with a message.
    #[arg(long, default_value_t = 600, value_parser = clap::value_parser!(u64).range(1..=604_800), help_heading = "Executor")]
    pub slurm_controller_wait: u64,
}

impl Options {
    /// The executor for the run directory `dir`.
    pub fn executor(&self, dir: &Path) -> Result<Box<dyn Executor>> {
        if self.executor == Kind::Local {
            return Ok(Box::new(local::Local));
        }
        let mut s = slurm::Slurm::new(dir)?;
        s.partition = self.slurm_partition.clone();
        s.time = self.slurm_time.clone();
        s.cpus_per_task = self.slurm_cpus_per_task;
        s.max_parallel = self.slurm_max_parallel;
        s.extra = self.slurm_arg.clone();
        s.retries = self.slurm_retries;
        s.controller_wait = std::time::Duration::from_secs(self.slurm_controller_wait);
        Ok(Box::new(s))
    }
}

/// Sizes the global thread pool: `jobs` threads, or for a Slurm task (`worker`) the CPUs Slurm
/// gave it; all cores otherwise. Results do not depend on it.
pub fn set_threads(jobs: Option<usize>, worker: bool) -> Result<()> {
    let slurm_cpus = || std::env::var("SLURM_CPUS_PER_TASK").ok().and_then(|v| v.parse::<usize>().ok());
    let Some(n) = jobs.or_else(|| if worker { slurm_cpus() } else { None }) else { return Ok(()) };
    let max = crate::limits::JOBS;
    if !(1..=max).contains(&n) {
        return Err(Error::Usage(format!("invalid --jobs = {n}: must be in 1..={max}")));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build_global()
        .map_err(|e| Error::Usage(format!("setting up the thread pool: {e}")))
}

/// The process's Ctrl-C flag, its handler installed on first use: the first Ctrl-C raises it (runs
/// stop cleanly after the units under way), the second exits at once.
pub fn interrupt_flag() -> &'static AtomicBool {
    static FLAG: AtomicBool = AtomicBool::new(false);
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(|| {
        let _ = ctrlc::set_handler(|| {
            if FLAG.swap(true, Ordering::SeqCst) {
                eprintln!("\naborted");
                std::process::exit(130);
            }
            eprintln!("\nstopping after the running units finish (Ctrl-C again to abort; resume later)");
        });
    });
    &FLAG
}

/// Builds the executor of a run directory (the Slurm executor needs to know it).
pub type ExecutorFactory<'a> = dyn Fn(&Path) -> Result<Box<dyn Executor>> + 'a;
