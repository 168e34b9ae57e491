//! The one reader of the files commands read whole (records, specs, units, models): non-blocking,
//! regular files only, capped, and confined to a served folder where the dashboard asks.

use crate::error::{Error, Result};
use std::fs;
use std::path::{Path, PathBuf};

/// The largest record a command reads as a whole: a spec, a unit, a run's state or its
/// generations (kilobytes to a few megabytes). What a damaged or hostile file can make it hold.
pub const RECORD_BYTES: u64 = 32 << 20;

/// Why a file was not read by [`read_checked`].
#[derive(Debug, thiserror::Error)]
pub enum Refused {
    /// Nothing there.
    #[error("missing")]
    Missing,
    /// A link (or a path) that leads out of the folders a computation may read ([`confined`]).
    #[error("links out of the served folders")]
    Outside,
    /// A FIFO, device, socket or directory.
    #[error("not a regular file (a FIFO, a device or a directory)")]
    NotRegular,
    /// Over the cap.
    #[error("larger than {} MiB", .0 >> 20)]
    TooLarge(u64),
    /// Unreadable.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

impl Refused {
    /// As the library's error, naming the file.
    pub fn at(self, path: &Path) -> Error {
        match self {
            Refused::Io(e) => Error::io(path, e),
            Refused::Missing => Error::io(path, std::io::Error::from_raw_os_error(libc::ENOENT)),
            other => Error::File { path: path.to_path_buf(), message: format!("is {other}") },
        }
    }
}

thread_local! {
    /// The folders this thread may read from, while [`confined`] (the dashboard: a request's root).
    static CONFINED: std::cell::RefCell<Option<Roots>> = const { std::cell::RefCell::new(None) };
}

/// Canonical folders a computation may read files from ([`confined`]).
pub type Roots = std::sync::Arc<Vec<PathBuf>>;

/// Runs `f` with every [`read_checked`] of this thread confined to files that resolve (links
/// followed) inside `roots` (canonical paths; `None`: unconfined), so that a served folder's links
/// cannot make the dashboard read elsewhere. Work handed to other threads carries
/// [`confinement`] along.
pub fn confined<R>(roots: Option<Roots>, f: impl FnOnce() -> R) -> R {
    let before = CONFINED.with(|c| c.replace(roots));
    let out = f();
    CONFINED.with(|c| *c.borrow_mut() = before);
    out
}

/// This thread's confinement, to carry into work done on other threads ([`confined`]).
pub fn confinement() -> Option<Roots> {
    CONFINED.with(|c| c.borrow().clone())
}

/// The one reader of files a command reads whole: `path` must be a regular file of at most `cap`
/// bytes (inside the [`confined`] roots, if any). It is opened without blocking (a FIFO would block
/// an open for reading until a writer came) and checked on the open file, so what is read is what
/// was checked; the read stops at the cap even if the file grows.
pub fn read_checked(path: &Path, cap: u64) -> std::result::Result<Vec<u8>, Refused> {
    use std::io::Read;
    use std::os::unix::fs::OpenOptionsExt;
    let not_found = |e: std::io::Error| match e.kind() {
        std::io::ErrorKind::NotFound => Refused::Missing,
        _ => Refused::Io(e),
    };
    let mut open = fs::OpenOptions::new();
    open.read(true).custom_flags(libc::O_NONBLOCK | libc::O_CLOEXEC);
    let f = match confinement() {
        Some(roots) => {
            let real = path.canonicalize().map_err(not_found)?;
            if !roots.iter().any(|r| real.starts_with(r)) {
                return Err(Refused::Outside);
            }
            // The last component is not followed again: what was checked is what opens.
            open.custom_flags(libc::O_NONBLOCK | libc::O_CLOEXEC | libc::O_NOFOLLOW).open(&real)
        }
        None => open.open(path),
    }
    .map_err(not_found)?;
    let meta = f.metadata()?;
    if !meta.is_file() {
        return Err(Refused::NotRegular);
    }
    if meta.len() > cap {
        return Err(Refused::TooLarge(cap));
    }
    let mut out = Vec::with_capacity(meta.len() as usize);
    f.take(cap + 1).read_to_end(&mut out)?;
    if out.len() as u64 > cap {
        return Err(Refused::TooLarge(cap));
    }
    Ok(out)
}

/// A record file ([`read_checked`] within [`RECORD_BYTES`]) as UTF-8 text; errors name the file.
pub fn read_text(path: &Path) -> Result<String> {
    read_text_within(path, RECORD_BYTES)
}

/// [`read_text`] within `cap` bytes: a long search's `generations.jsonl`.
pub fn read_text_within(path: &Path, cap: u64) -> Result<String> {
    let bytes = read_checked(path, cap).map_err(|r| r.at(path))?;
    String::from_utf8(bytes).map_err(|_| Error::File { path: path.to_path_buf(), message: "is not UTF-8 text".into() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::read_json;

    #[test]
    fn the_checked_reader_refuses_a_fifo_without_blocking_and_caps_what_it_reads() {
        let dir = std::env::temp_dir().join(format!("bfqi-store-read-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let fifo = dir.join("run.json");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        // No writer ever comes: a blocking open would never return.
        assert!(matches!(read_checked(&fifo, RECORD_BYTES), Err(Refused::NotRegular)));
        let e = read_json::<serde_json::Value>(&fifo).unwrap_err().to_string();
        assert!(e.contains("run.json") && e.contains("not a regular file"), "{e}");
        assert!(matches!(read_checked(Path::new("/dev/zero"), RECORD_BYTES), Err(Refused::NotRegular)));
        let big = dir.join("unit.json");
        fs::File::create(&big).unwrap().set_len(RECORD_BYTES + 1).unwrap();
        assert!(matches!(read_checked(&big, RECORD_BYTES), Err(Refused::TooLarge(_))));
        // Confined, a link out of the roots is refused; unconfined, it is read.
        let outside = std::env::temp_dir().join(format!("bfqi-store-outside-{}.json", std::process::id()));
        fs::write(&outside, b"{}").unwrap();
        let link = dir.join("spec.json");
        std::os::unix::fs::symlink(&outside, &link).unwrap();
        let roots = Some(std::sync::Arc::new(vec![dir.canonicalize().unwrap()]));
        assert!(matches!(confined(roots, || read_checked(&link, RECORD_BYTES)), Err(Refused::Outside)));
        assert_eq!(read_checked(&link, RECORD_BYTES).unwrap(), b"{}");
        fs::remove_file(&outside).unwrap();
        fs::remove_dir_all(&dir).unwrap();
    }
}
