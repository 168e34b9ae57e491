//! Scaffolding shared by the end-to-end tests: the binary and per-process temporary directories.
#![allow(dead_code)] // each test file uses part of it

use std::path::PathBuf;
use std::process::Command;

/// The `bfqi-ga` binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_bfqi-ga"))
}

/// A path under the temporary directory, unique to this process, that does not exist yet.
pub fn fresh(prefix: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bfqi-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// [`fresh`], created empty.
pub fn empty_dir(prefix: &str, name: &str) -> PathBuf {
    let d = fresh(prefix, name);
    std::fs::create_dir_all(&d).unwrap();
    d
}
