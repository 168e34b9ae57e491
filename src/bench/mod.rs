//! Benchmarks (`bfqi-ga bench`): figures and ratios, never assertions.
//!
//! - `bench learners` times the Extra-Trees and the MLP on simulator data in the thesis's settings;
//! - `bench fqi` times whole FQI / B-FQI runs with Extra-Trees;
//! - `bench search` measures the main job, `bfqi-ga search <env>` at its default spec: units of
//!   chosen chromosomes, the kernels against the machine's FMA peak, and the projected wall time
//!   of a whole search;
//! - `bench dashboard` times the requests of a search page's first paint on the committed bicycle
//!   search, and the memory serving them takes;
//! - `bench gym` times the gymnasium bridge against the built-in cart-pole on the same jobs;
//! - `bench data` times reading a million logged transitions from Parquet and CSV.
//!
//! Given a Python (`--python PY`) with scikit-learn, or Keras 3 and JAX, each also runs the
//! reference a researcher would otherwise use on the same data in the same run, for ratios that a
//! drifting shared machine cannot fake. The reference scripts are this repository's `scripts/`,
//! built into the binary and written to a temporary folder when needed.

mod dashboard;
mod fqi;
mod gym;
mod learners;
mod levels;
mod logged;
mod search;

pub use dashboard::dashboard;
pub use fqi::fqi;
pub use gym::gym;
pub use learners::learners;
pub use logged::logged;
pub use search::{SearchBench, search};

use crate::dataset::{self, Dataset, dataset_seed};
use crate::env::EnvConfig;
use crate::error::{Error, Result};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// What `bench` times.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// The Extra-Trees and the MLP on simulator data.
    Learners,
    /// Whole FQI / B-FQI runs with Extra-Trees.
    Fqi,
    /// Search units at the default specs, and a whole search's projected time.
    Search,
    /// The dashboard's first paint of the committed bicycle search, and its memory.
    Dashboard,
    /// The gymnasium bridge (CartPole-v1) against the built-in cart-pole: collection, evaluation,
    /// a search unit and its share in Python.
    Gym,
    /// Reading one million logged transitions from Parquet and CSV, against copying them.
    Data,
}

/// The reference scripts, by file name (the copies in `scripts/`).
const SCRIPTS: [(&str, &str); 4] = [
    ("sklearn_et.py", include_str!("../../scripts/sklearn_et.py")),
    ("keras_mlp.py", include_str!("../../scripts/keras_mlp.py")),
    ("sklearn_fqi.py", include_str!("../../scripts/sklearn_fqi.py")),
    ("keras_fqi_iteration.py", include_str!("../../scripts/keras_fqi_iteration.py")),
];

/// A Python to run the reference scripts with, and a temporary folder holding them and the data
/// handed over (removed on drop).
pub struct PythonReference {
    python: PathBuf,
    dir: PathBuf,
}

impl PythonReference {
    /// Writes the scripts into a fresh temporary folder; `None` without a Python.
    pub fn new(python: Option<&Path>) -> Result<Option<PythonReference>> {
        let Some(python) = python else { return Ok(None) };
        let dir = std::env::temp_dir().join(format!("bfqi-bench-{}-{}", std::process::id(), crate::store::now_utc().0));
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        for (name, text) in SCRIPTS {
            let p = dir.join(name);
            std::fs::write(&p, text).map_err(|e| Error::io(&p, e))?;
        }
        Ok(Some(PythonReference { python: python.to_path_buf(), dir }))
    }

    /// A path in the temporary folder, for data handed to a script.
    pub fn file(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Runs `python <script> args…` and parses the last line it prints as JSON; a failure is
    /// reported on stderr and gives `None` (the figures without a reference are still worth
    /// printing).
    pub fn run(&self, script: &str, args: &[String]) -> Option<Value> {
        let out = Command::new(&self.python).arg(self.dir.join(script)).args(args).output();
        let out = match out {
            Ok(o) => o,
            Err(e) => {
                eprintln!("  (reference {script} could not start {}: {e})", self.python.display());
                return None;
            }
        };
        if !out.status.success() {
            let err = String::from_utf8_lossy(&out.stderr);
            eprintln!("  (reference {script} failed: {})", err.lines().last().unwrap_or(""));
            return None;
        }
        let text = String::from_utf8_lossy(&out.stdout);
        serde_json::from_str(text.lines().last()?).ok()
    }
}

impl Drop for PythonReference {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn rows_input(d: &Dataset) -> Vec<f64> {
    let od = d.obs_dim;
    let mut x = Vec::with_capacity(d.len() * (od + 1));
    for i in 0..d.len() {
        x.extend_from_slice(&d.state[i * od..(i + 1) * od]);
        x.push(d.action[i]);
    }
    x
}

fn data(env: &str, episodes: usize) -> Result<(EnvConfig, Dataset)> {
    let c = EnvConfig::by_name(env)?;
    let d = dataset::collect(c.env(), episodes, dataset_seed(1, dataset::Role::Compare, 0))?;
    Ok((c, d))
}
