//! Executors: how the units of work of a search or a comparison get evaluated.
//!
//! A unit is named by an id (its result file's stem) and evaluated by a closure that computes it and
//! stores its result atomically in the run directory. Results are always read back from the files,
//! so an executor only has to get every missing file written.

pub mod local;
pub mod slurm;

use crate::error::Result;
use std::sync::atomic::AtomicBool;

/// Evaluates units of work.
pub trait Executor: Sync {
    /// Evaluates every unit of `ids` through `work` (which stores the result), unless `stop` is raised:
    /// units not yet started are then skipped. Units start in the order given (callers put the
    /// longest first). `done` is called with each unit's id after it.
    fn run(
        &self,
        ids: &[String],
        work: &(dyn Fn(&str) -> Result<()> + Sync),
        done: &(dyn Fn(&str) + Sync),
        stop: &AtomicBool,
    ) -> Result<()>;
}

use crate::error::Error;
use std::path::Path;

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

/// Builds the executor of a run directory (the Slurm executor needs to know it).
pub type ExecutorFactory<'a> = dyn Fn(&Path) -> Result<Box<dyn Executor>> + 'a;

/// The worker side of the Slurm executor: computes one unit of the search or comparison in `dir`
/// and stores its result atomically. A unit already stored is left alone.
pub fn worker(dir: &Path, unit: &str) -> Result<()> {
    if !dir.is_dir() {
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        return Err(Error::File {
            path: dir.to_path_buf(),
            message: format!(
                "run directory not visible from this node ({}): it must be on a file system shared by the nodes",
                host.trim()
            ),
        });
    }
    if dir.join("spec.json").is_file() {
        let spec = crate::ga::search::load_spec(dir)?;
        let ev = crate::ga::search::Evaluator::new(spec, dir);
        // A stored unit is reused only if it verifies (a damaged one is computed again).
        if ev.load_unit(unit).is_some() {
            return Ok(());
        }
        ev.run_unit(unit)
    } else if dir.join("units").join(format!("{unit}.json")).is_file() {
        Ok(())
    } else if dir.join("compare.json").is_file() {
        let cfg = crate::compare::load(dir)?;
        crate::compare::run_unit(dir, &cfg, unit)
    } else {
        Err(Error::File { path: dir.to_path_buf(), message: "not a search or comparison run directory".into() })
    }
}
