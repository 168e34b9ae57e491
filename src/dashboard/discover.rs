//! The served directories and the runs found under them. A run is named by its root's index and
//! its path below that root; every path a request names is resolved here, canonicalised, and
//! refused unless it stays inside a root.

use crate::error::{Error, Result};
use std::path::{Component, Path, PathBuf};

/// What a run directory holds, from the file that defines it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A GA search (`spec.json` and `state.json`).
    Search,
    /// A comparison (`compare.json`).
    Compare,
    /// A batch (`batch.json`).
    Batch,
    /// A rollout (`rollout.json`).
    Rollout,
}

impl Kind {
    /// Its name on the pages.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Search => "search",
            Kind::Compare => "comparison",
            Kind::Batch => "batch",
            Kind::Rollout => "rollout",
        }
    }

    /// The kind of the run in `dir`, if it is one.
    pub fn of(dir: &Path) -> Option<Kind> {
        if dir.join("compare.json").is_file() {
            Some(Kind::Compare)
        } else if dir.join("spec.json").is_file() && dir.join("state.json").is_file() {
            Some(Kind::Search)
        } else if dir.join("batch.json").is_file() {
            Some(Kind::Batch)
        } else if dir.join("rollout.json").is_file() {
            Some(Kind::Rollout)
        } else {
            None
        }
    }
}

/// A run found under a root.
#[derive(Debug, Clone)]
pub struct Run {
    /// Index of its root.
    pub root: usize,
    /// Its path below the root, `/`-separated (empty when the root is the run).
    pub rel: String,
    /// Its directory.
    pub dir: PathBuf,
    /// What it is.
    pub kind: Kind,
}

impl Run {
    /// Its page.
    pub fn url(&self) -> String {
        format!("/run/{}/{}", self.root, super::html::encode_path(&self.rel))
    }

    /// Its name on the pages: the root's last component and the path below it.
    pub fn label(&self, roots: &Roots) -> String {
        let base = roots.shown[self.root].clone();
        if self.rel.is_empty() { base } else { format!("{base}/{}", self.rel) }
    }
}

/// The directories served, canonicalised.
#[derive(Debug, Clone)]
pub struct Roots {
    dirs: Vec<PathBuf>,
    shown: Vec<String>,
}

/// Folders inside a run that hold its units, not further runs: never walked.
const SKIP: [&str; 3] = ["units", "validation", "models"];

impl Roots {
    /// The roots; a missing one is refused, naming it.
    pub fn new(dirs: &[PathBuf]) -> Result<Roots> {
        let mut out = Vec::new();
        for d in dirs {
            let c = d.canonicalize().map_err(|e| Error::io(d, e))?;
            if !c.is_dir() {
                return Err(Error::File { path: d.clone(), message: "is not a directory".into() });
            }
            out.push(c);
        }
        let shown = dirs.iter().map(|d| d.display().to_string()).collect();
        Ok(Roots { dirs: out, shown })
    }

    /// Every run under every root, in order. A run's own folders are not walked.
    pub fn runs(&self) -> Vec<Run> {
        let mut runs = Vec::new();
        for (i, root) in self.dirs.iter().enumerate() {
            let mut stack = vec![root.clone()];
            let mut found = Vec::new();
            while let Some(d) = stack.pop() {
                if let Some(kind) = Kind::of(&d) {
                    found.push(self.run_at(i, &d, kind));
                    if kind != Kind::Batch {
                        continue;
                    }
                }
                if let Ok(entries) = std::fs::read_dir(&d) {
                    stack.extend(
                        entries
                            .flatten()
                            .filter(|e| e.file_type().is_ok_and(|t| t.is_dir()))
                            .filter(|e| !SKIP.iter().any(|s| e.file_name() == *s))
                            .map(|e| e.path()),
                    );
                }
            }
            found.sort_by(|a, b| a.rel.cmp(&b.rel));
            runs.extend(found);
        }
        runs
    }

    fn run_at(&self, root: usize, dir: &Path, kind: Kind) -> Run {
        let rel = dir.strip_prefix(&self.dirs[root]).unwrap_or(Path::new(""));
        let rel = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect::<Vec<_>>().join("/");
        Run { root, rel, dir: dir.to_path_buf(), kind }
    }

    /// The path `rel` (decoded, `/`-separated) below root `root`, if it exists and stays inside
    /// the root once links are resolved; `..` and absolute parts are refused outright.
    pub fn resolve(&self, root: usize, rel: &str) -> Option<PathBuf> {
        let base = self.dirs.get(root)?;
        let rel = Path::new(rel);
        if rel.components().any(|c| !matches!(c, Component::Normal(_))) && !rel.as_os_str().is_empty() {
            return None;
        }
        let p = base.join(rel).canonicalize().ok()?;
        p.starts_with(base).then_some(p)
    }

    /// The run at `rel` below root `root`, if that is a run directory inside the root.
    pub fn run(&self, root: usize, rel: &str) -> Option<Run> {
        let dir = self.resolve(root, rel)?;
        let kind = Kind::of(&dir)?;
        Some(self.run_at(root, &dir, kind))
    }

    /// Whether `path` (canonical) lies inside some root.
    pub fn contains(&self, path: &Path) -> Option<(usize, String)> {
        let p = path.canonicalize().ok()?;
        self.dirs.iter().enumerate().find(|(_, d)| p.starts_with(d)).map(|(i, d)| {
            let rel = p.strip_prefix(d).unwrap_or(Path::new(""));
            (i, rel.iter().map(|c| c.to_string_lossy().into_owned()).collect::<Vec<_>>().join("/"))
        })
    }
}
