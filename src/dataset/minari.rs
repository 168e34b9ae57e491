//! Minari datasets (Farama's offline-RL standard) in and out, through the Python bridge
//! `python/bfqi_minari.py` (built into the binary): `data.minari` and `minari:<id>` read one into
//! the tool's table, `bfqi-ga dataset --minari <id>` writes one.
//!
//! The bridge runs under `$BFQI_PYTHON` (else `python3`), or the spec's gymnasium `env.python`;
//! local datasets are found where minari finds them (`MINARI_DATASETS_PATH`).

use super::Dataset;
use crate::env::EnvConfig;
use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};

const SOURCE: &str = include_str!("../../python/bfqi_minari.py");

/// What the bridge says of a dataset it read.
#[derive(Debug, Clone, Deserialize)]
pub struct Info {
    /// Episodes.
    pub episodes: usize,
    /// The gymnasium env the data was collected in, as minari recorded it, if it did.
    pub env: Option<EnvSpec>,
    /// The minari version that read it.
    pub minari: String,
}

/// A recorded gymnasium env spec: what `minari:<id>` evaluates in.
#[derive(Debug, Clone, Deserialize)]
pub struct EnvSpec {
    /// The gymnasium id.
    pub id: String,
    /// Its keyword arguments.
    #[serde(default)]
    pub kwargs: serde_json::Map<String, serde_json::Value>,
    /// Its time limit.
    pub max_episode_steps: Option<usize>,
}

/// The Python that runs the bridge: the env's own for a gymnasium env, else `$BFQI_PYTHON`, else
/// `python3`.
pub fn python(env: Option<&EnvConfig>) -> String {
    match env.and_then(|e| e.env().gymnasium()) {
        Some(g) => g.python(),
        None => crate::env::gymnasium::default_python(),
    }
}

/// A fresh path in the temporary directory for the bridge's CSV.
fn scratch(what: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("bfqi-minari-{}-{n}-{what}", std::process::id()))
}

/// How long the bridge may take to read or write a dataset before it is stopped: a FIFO or a
/// device among a dataset's files, or a hung import, fails in bounded time.
pub const BRIDGE_SECONDS: u64 = 600;

/// What of the bridge's stdout and stderr is kept: it prints one JSON line, or one error line.
const BRIDGE_OUTPUT: u64 = 1 << 20;

/// Runs the bridge; a refusal comes back as `field: message` on its stderr. It is stopped after
/// [`BRIDGE_SECONDS`], and what it prints is kept up to [`BRIDGE_OUTPUT`] bytes.
fn run(python: &str, id: &str, args: &[&std::ffi::OsStr]) -> Result<String> {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = Command::new(python)
        .arg("-c")
        .arg(SOURCE)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            Error::invalid(
                "data.minari",
                id,
                format!("cannot start {python} ({e}): set BFQI_PYTHON to a Python with minari (pip install minari)"),
            )
        })?;
    let capped = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut out = Vec::new();
            if let Some(r) = r {
                let mut r = r.take(BRIDGE_OUTPUT);
                let _ = r.read_to_end(&mut out);
                // The rest is read and dropped, so the bridge never blocks on a full pipe.
                let _ = std::io::copy(&mut r.into_inner(), &mut std::io::sink());
            }
            out
        })
    };
    let stdout = capped(child.stdout.take().map(|s| Box::new(s) as Box<dyn Read + Send>));
    let stderr = capped(child.stderr.take().map(|s| Box::new(s) as Box<dyn Read + Send>));
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(BRIDGE_SECONDS);
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if std::time::Instant::now() < deadline => {
                std::thread::sleep(std::time::Duration::from_millis(20))
            }
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(Error::invalid(
                    "data.minari",
                    id,
                    format!("the Minari bridge ({python}) did not finish within {BRIDGE_SECONDS} s and was stopped"),
                ));
            }
        }
    };
    let out = std::process::Output {
        status,
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    };
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let line = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("no message");
        let (field, message) = line.split_once(": ").unwrap_or(("data.minari", line));
        let field = if field.starts_with("data.") { field } else { "data.minari" };
        return Err(Error::invalid(field, id, format!("{message} (python: {python})")));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Minari dataset `id` as the bridge wrote it (the FNV-1a of its CSV: the content hash), read
/// into a dataset, with what the bridge said of it.
pub fn read(id: &str, python: &str) -> Result<(u64, Dataset, Info)> {
    let csv = scratch("read.csv");
    let result = (|| {
        let stdout = run(python, id, &["read".as_ref(), id.as_ref(), csv.as_os_str()])?;
        let line = stdout.lines().rev().find(|l| l.starts_with('{')).unwrap_or("");
        let info: Info = serde_json::from_str(line)
            .map_err(|e| Error::invalid("data.minari", id, format!("the bridge answered {line:?} ({e})")))?;
        let data = super::table::read(&csv).map_err(|e| Error::invalid("data.minari", id, e.to_string()))?;
        Ok((crate::store::fnv1a_file(&csv)?, data, info))
    })();
    let _ = std::fs::remove_file(&csv);
    result
}

/// Writes `d`, collected in `env`, as the new Minari dataset `id` (minari's `namespace/name-v0`
/// form); a gymnasium env's spec is recorded with it.
pub fn write(d: &Dataset, env: &EnvConfig, id: &str) -> Result<()> {
    let e = env.env();
    let action = {
        let a = e.actions();
        if env.discrete_dataset_actions() && a.iter().enumerate().all(|(i, &x)| x == i as f64) {
            serde_json::json!({"kind": "discrete", "n": a.len()})
        } else {
            let (lo, hi) = a.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| (l.min(x), h.max(x)));
            serde_json::json!({"kind": "box", "low": [lo], "high": [hi]})
        }
    };
    let gym = e
        .gymnasium()
        .map(|g| serde_json::json!({"id": g.id, "kwargs": g.kwargs, "max_episode_steps": g.max_episode_steps}));
    let meta = serde_json::json!({"obs_dim": d.obs_dim, "action": action, "env": gym});
    let (csv, meta_path) = (scratch("write.csv"), scratch("meta.json"));
    let result = (|| {
        super::table::write(d, &csv)?;
        std::fs::write(&meta_path, meta.to_string()).map_err(|err| Error::Io { path: meta_path.clone(), err })?;
        run(&python(Some(env)), id, &["write".as_ref(), id.as_ref(), csv.as_os_str(), meta_path.as_os_str()])
    })();
    for p in [&csv, &meta_path] {
        let _ = std::fs::remove_file(p);
    }
    result.map(|_| ())
}

/// Whether `path` names a Minari dataset on the command line (`minari:<id>`), and which.
pub fn named(name: &str) -> Option<&str> {
    name.strip_prefix("minari:")
}
