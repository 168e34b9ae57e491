//! The gymnasium bridge's tests: a Python with gymnasium, the binary set up to use it (and the
//! test envs of `python/bfqi_gym_testenvs.py`), and spec files naming gymnasium envs.

use super::bin;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A Python that imports gymnasium: `$BFQI_PYTHON`, else `python3`. `None`, with the reason
/// printed, where there is none; `.ci/run` installs one and sets `BFQI_GYM_REQUIRED=1`, which
/// turns a missing one into a failure.
pub fn python() -> Option<String> {
    let py = std::env::var("BFQI_PYTHON").ok().filter(|p| !p.is_empty()).unwrap_or_else(|| "python3".into());
    let ok = Command::new(&py).args(["-c", "import gymnasium"]).output().is_ok_and(|o| o.status.success());
    if ok {
        return Some(py);
    }
    let why = format!("skipped: {py} cannot import gymnasium (set BFQI_PYTHON to a Python that has it)");
    if std::env::var("BFQI_GYM_REQUIRED").as_deref() == Ok("1") {
        panic!("{why}, and BFQI_GYM_REQUIRED=1");
    }
    eprintln!("{why}");
    None
}

/// The repository's `python/` folder (the worker's tests and the test envs).
pub fn python_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("python")
}

/// The binary, with `py` as the workers' Python and the test envs importable.
pub fn gym_bin(py: &str) -> Command {
    let mut c = bin();
    c.env("BFQI_PYTHON", py).env("PYTHONPATH", python_dir());
    c
}

/// The shipped spec `searches/<base>.json` with its env replaced by `env` (a gymnasium env's
/// settings, without `name`), written to `path`.
pub fn write_spec(path: &Path, base: &str, env: Value) -> PathBuf {
    let text = super::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("searches/{base}.json")));
    let mut spec: Value = serde_json::from_str(&text).unwrap();
    let mut env = env;
    env["name"] = Value::from("gymnasium");
    spec["env"] = env;
    std::fs::write(path, serde_json::to_string_pretty(&spec).unwrap()).unwrap();
    path.to_path_buf()
}

/// A dataset CSV's rows as numbers, with its header.
pub fn csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = super::read(path);
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    (header, rows)
}
