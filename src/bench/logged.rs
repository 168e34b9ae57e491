//! `bfqi-ga bench data`: reading logged transitions. One million pendulum transitions (5,000
//! random-policy episodes of 200 steps) written as Parquet and as CSV, then read back to a
//! [`Dataset`] as a spec's logged data is: wall time, transitions per second and bytes per second.
//!
//! The limit beside each figure: the decoded dataset's bytes copied once in memory (the least a
//! reader must move, measured in the same run), so `× copy` says how far reading is from moving
//! the bytes alone. With `--python`, pandas reads the same files (`read_parquet`, `read_csv`) for
//! the ratio a researcher would compare with.

use super::PythonReference;
use crate::dataset::{self, Dataset, dataset_seed};
use crate::env::EnvConfig;
use crate::error::{Error, Result};
use serde::Serialize;
use serde_json::Value;
use std::path::Path;
use std::time::Instant;

/// Episodes of the pendulum's 200-step horizon: one million transitions.
const EPISODES: usize = 5_000;

/// Timed reads per format; the figure is the fastest (the least disturbed by a shared machine).
const READS: usize = 3;

/// One format's figures.
#[derive(Debug, Clone, Serialize)]
struct Format {
    format: &'static str,
    file_bytes: u64,
    write_s: f64,
    read_s: f64,
    transitions_per_s: f64,
    file_mb_per_s: f64,
    /// The read's time over the in-memory copy of the decoded bytes.
    times_copy: f64,
    pandas_s: Option<f64>,
}

/// The decoded dataset's bytes (what a reader must produce).
fn decoded_bytes(d: &Dataset) -> usize {
    8 * (d.state.len() + d.next_state.len() + d.action.len() + d.reward.len())
        + 4 * (d.episode.len() + d.step.len())
        + d.absorbing.len()
}

/// The fastest of [`READS`] copies of the dataset's arrays: the bytes moved once.
fn copy_seconds(d: &Dataset) -> f64 {
    (0..READS)
        .map(|_| {
            let t = Instant::now();
            let c = std::hint::black_box(d.clone());
            let s = t.elapsed().as_secs_f64();
            drop(c);
            s
        })
        .fold(f64::INFINITY, f64::min)
}

/// pandas' read of `path`, timed inside Python (the import not counted).
fn pandas_seconds(python: &Path, path: &Path, parquet: bool) -> Option<f64> {
    let call = if parquet { "read_parquet" } else { "read_csv" };
    let code = format!(
        "import sys, time, pandas as pd\nbest = 1e300\nfor _ in range({READS}):\n    t = time.perf_counter(); \
         df = pd.{call}(sys.argv[1]); best = min(best, time.perf_counter() - t)\nassert len(df) > 0\nprint(best)"
    );
    let out = std::process::Command::new(python).arg("-c").arg(code).arg(path).output().ok()?;
    if !out.status.success() {
        eprintln!("  (pandas failed: {})", String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or(""));
        return None;
    }
    String::from_utf8_lossy(&out.stdout).trim().parse().ok()
}

/// Runs the benchmark; prints a table unless `json`, and returns the figures.
pub fn logged(python: Option<&Path>, json: bool) -> Result<Value> {
    let say = |s: String| {
        if !json {
            println!("{s}");
        }
    };
    let env = EnvConfig::by_name("pendulum")?;
    let d = dataset::collect(env.env(), EPISODES, dataset_seed(1, dataset::Role::Compare, 0))?;
    let bytes = decoded_bytes(&d);
    let copy_s = copy_seconds(&d);
    say(format!(
        "bench data · {} pendulum transitions ({} episodes, {} observation values) · decoded {:.1} MB, copied in \
         {:.3} s ({:.1} GB/s): the least a reader moves",
        d.len(),
        EPISODES,
        d.obs_dim,
        bytes as f64 / 1e6,
        copy_s,
        bytes as f64 / copy_s / 1e9
    ));
    let reference = PythonReference::new(python)?;
    let dir = match &reference {
        Some(r) => r.file(""),
        None => {
            let dir = std::env::temp_dir().join(format!("bfqi-bench-data-{}", std::process::id()));
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
            dir
        }
    };
    let mut rows = Vec::new();
    for (format, parquet) in [("parquet", true), ("csv", false)] {
        let path = dir.join(format!("pendulum.{format}"));
        let t = Instant::now();
        dataset::table::write(&d, &path)?;
        let write_s = t.elapsed().as_secs_f64();
        let file_bytes = std::fs::metadata(&path).map_err(|e| Error::io(&path, e))?.len();
        let mut read_s = f64::INFINITY;
        for _ in 0..READS {
            let t = Instant::now();
            let back = dataset::table::read(&path)?;
            read_s = read_s.min(t.elapsed().as_secs_f64());
            if back != d {
                return Err(Error::Data(format!("{}: read back differs from what was written", path.display())));
            }
        }
        let pandas_s = python.and_then(|py| pandas_seconds(py, &path, parquet));
        let f = Format {
            format,
            file_bytes,
            write_s,
            read_s,
            transitions_per_s: d.len() as f64 / read_s,
            file_mb_per_s: file_bytes as f64 / read_s / 1e6,
            times_copy: read_s / copy_s,
            pandas_s,
        };
        say(format!(
            "  {:<8} file {:>6.1} MB · write {:.2} s · read {:.3} s = {:.2} M transitions/s, {:.0} MB/s of file, {:.0}× \
             the copy{}",
            f.format,
            f.file_bytes as f64 / 1e6,
            f.write_s,
            f.read_s,
            f.transitions_per_s / 1e6,
            f.file_mb_per_s,
            f.times_copy,
            f.pandas_s.map_or(String::new(), |p| format!(" · pandas {p:.3} s ({:.2}× ours)", p / f.read_s))
        ));
        std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        rows.push(f);
    }
    if reference.is_none() {
        let _ = std::fs::remove_dir(&dir);
    }
    Ok(serde_json::json!({
        "transitions": d.len(),
        "decoded_bytes": bytes,
        "copy_s": copy_s,
        "formats": rows,
    }))
}
