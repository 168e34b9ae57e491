//! The served directories and the runs found under them. A run is named by its root's index and
//! its path below that root; every path a request names is resolved here, canonicalised, and
//! refused unless it stays inside a root. Every file the dashboard reads is read by [`read_inside`]:
//! inside a root once links are resolved, a regular file, at most [`MAX_FILE`] bytes.

use crate::error::{Error, Result};
use std::cell::RefCell;
use std::path::{Component, Path, PathBuf};

/// The largest file the dashboard reads (a search's records are kilobytes, a rollout's GIF a
/// megabyte): what one request can make it hold of a file.
pub const MAX_FILE: u64 = 32 << 20;

pub use crate::store::Refused;

/// Reads `path`, which must resolve (links followed) inside `base` (a canonical root) and be a
/// regular file of at most `cap` bytes, through the one checked reader ([`crate::store::read_checked`]:
/// not blocking on a FIFO, checked on the open file, stopped at the cap).
pub fn read_inside(base: &Path, path: &Path, cap: u64) -> std::result::Result<Vec<u8>, Refused> {
    let real = path.canonicalize().map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => Refused::Missing,
        _ => Refused::Io(e),
    })?;
    if !real.starts_with(base) {
        return Err(Refused::Outside);
    }
    crate::store::read_checked(&real, cap)
}

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
#[derive(Debug)]
pub struct Run {
    /// Index of its root.
    pub root: usize,
    /// Its path below the root, `/`-separated (empty when the root is the run).
    pub rel: String,
    /// Its directory.
    pub dir: PathBuf,
    /// What it is.
    pub kind: Kind,
    /// Its root, canonical: every file it reads must resolve inside.
    pub(crate) base: PathBuf,
    /// What could not be read while building its page (files refused, lines skipped), shown on
    /// the page.
    notes: RefCell<Vec<String>>,
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

    /// The bytes of its file `name` (a path below the run), read by [`read_inside`]. A missing
    /// file is `None` silently (many appear only later in a run); any other refusal is noted.
    pub fn read(&self, name: &str) -> Option<Vec<u8>> {
        match read_inside(&self.base, &self.dir.join(name), MAX_FILE) {
            Ok(b) => Some(b),
            Err(Refused::Missing) => None,
            Err(e) => {
                self.note(format!("{name}: not read: {e}"));
                None
            }
        }
    }

    /// Its file `name` as text; invalid UTF-8 is noted and the file not used.
    pub fn text(&self, name: &str) -> Option<String> {
        String::from_utf8(self.read(name)?)
            .map_err(|e| self.note(format!("{name}: not read: not UTF-8 (byte {})", e.utf8_error().valid_up_to())))
            .ok()
    }

    /// Its JSON file `name` as a `T`; one that does not parse is noted, naming the field.
    pub fn json<T: serde::de::DeserializeOwned>(&self, name: &str) -> Option<T> {
        let text = self.text(name)?;
        let parsed = serde_json::from_str(&text).or_else(|_| crate::error::from_json_text(&text, Path::new(name), ""));
        parsed.map_err(|e| self.note(format!("not read: {e}"))).ok()
    }

    /// Whether a live process holds its lock (read as every other file is).
    pub fn is_held(&self) -> bool {
        self.text("lock").is_some_and(|t| crate::store::RunLock::held_by(&t))
    }

    /// Notes something the page could not show.
    pub fn note(&self, what: String) {
        let mut n = self.notes.borrow_mut();
        if !n.contains(&what) {
            n.push(what);
        }
    }

    /// What was noted so far.
    pub fn notes(&self) -> Vec<String> {
        self.notes.borrow().clone()
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
                            // Hidden folders: a run still being built (`.<name>.tmp…`, renamed
                            // into place when whole) is not a run yet.
                            .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
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
        Run { root, rel, dir: dir.to_path_buf(), kind, base: self.dirs[root].clone(), notes: RefCell::default() }
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

    /// The file `rel` below root `root`, read by [`read_inside`].
    pub fn read(&self, root: usize, rel: &str) -> std::result::Result<Vec<u8>, Refused> {
        let base = self.dirs.get(root).ok_or(Refused::Missing)?;
        if Path::new(rel).components().any(|c| !matches!(c, Component::Normal(_))) {
            return Err(Refused::Outside);
        }
        read_inside(base, &base.join(rel), MAX_FILE)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_still_being_built_in_a_hidden_folder_is_not_listed() {
        let root = std::env::temp_dir().join(format!("bfqi-discover-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for name in ["done", ".done.tmp123-host"] {
            std::fs::create_dir_all(root.join(name)).unwrap();
            std::fs::write(root.join(name).join("compare.json"), "{}").unwrap();
        }
        let roots = Roots { dirs: vec![root.clone()], shown: vec![root.display().to_string()] };
        let rels: Vec<String> = roots.runs().into_iter().map(|r| r.rel).collect();
        std::fs::remove_dir_all(&root).unwrap();
        assert_eq!(rels, ["done"]);
    }
}
