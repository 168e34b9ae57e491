//! Run storage: atomic writes (temporary file, then rename), so an interrupted run never leaves a
//! corrupt file.

use crate::error::{Error, Result};
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes `path` atomically: `fill` writes into a temporary file beside it, which is flushed, synced
/// and renamed over `path`. On any error the temporary file is removed and `path` is untouched.
pub fn write_atomic(path: &Path, fill: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>) -> Result<()> {
    write_atomic_via(path, &temp_path(path), fill)
}

/// [`write_atomic`] through the temporary file `tmp` (which must be beside `path`): for writers
/// whose temporary files have names of their own (plots' `.<name>.tmp.png`). On any error `tmp`
/// is removed and the error names `path`, keeping the OS's error (a full disk is exit 1).
pub fn write_atomic_via(
    path: &Path,
    tmp: &Path,
    fill: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let result = (|| {
        let mut w = BufWriter::new(File::create(tmp)?);
        fill(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        fs::rename(tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// Writes a value as pretty JSON, atomically.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<()> {
    write_atomic(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value)?;
        w.write_all(b"\n")
    })
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp{}", std::process::id()))
}

mod read;
pub use read::{RECORD_BYTES, Refused, Roots, confined, confinement, read_checked, read_text, read_text_within};

/// Reads and parses a JSON record ([`read_text`]); errors name the file.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_text(path)?;
    // The plain parser is the faster; what it refuses is parsed again with the field path tracked,
    // for a message naming the field.
    serde_json::from_str(&text).or_else(|_| crate::error::from_json_text(&text, path, ""))
}

/// Whether anything is at `path`: a file, a directory, a FIFO, or a link (even a dangling one).
pub fn something_at(path: &Path) -> bool {
    fs::symlink_metadata(path).is_ok()
}

/// Reads an input file (spec, preset, plan, tuned config) as text. A directory, a FIFO or device
/// (reading one would block) or a dangling link is refused in one line naming it.
pub fn read_input(path: &Path) -> Result<String> {
    let refuse = |message: &str| Error::File { path: path.to_path_buf(), message: message.into() };
    match fs::metadata(path) {
        Err(_) if something_at(path) => return Err(refuse("is a link to nothing (dangling)")),
        Err(e) => return Err(Error::io(path, e)),
        Ok(m) if m.is_dir() => return Err(refuse("is a directory, not a file")),
        Ok(m) if !m.is_file() => return Err(refuse("is not a regular file (a FIFO or a device)")),
        Ok(_) => {}
    }
    read_text(path)
}

/// Parses JSON text, refusing a key that appears twice in one object (serde_json keeps the last
/// silently, so an edited file could say one thing and mean another); errors name the file.
pub fn parse_json(text: &str, origin: &Path) -> Result<serde_json::Value> {
    serde_json::from_str::<Strict>(text)
        .map(|s| s.0)
        .map_err(|e| Error::File { path: origin.to_path_buf(), message: e.to_string() })
}

/// A JSON value deserialised with a check for duplicate keys.
struct Strict(serde_json::Value);

impl<'de> serde::Deserialize<'de> for Strict {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_any(StrictVisitor)
    }
}

struct StrictVisitor;

impl<'de> serde::de::Visitor<'de> for StrictVisitor {
    type Value = Strict;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> std::result::Result<Strict, E> {
        Ok(Strict(v.into()))
    }
    fn visit_i64<E>(self, v: i64) -> std::result::Result<Strict, E> {
        Ok(Strict(v.into()))
    }
    fn visit_u64<E>(self, v: u64) -> std::result::Result<Strict, E> {
        Ok(Strict(v.into()))
    }
    fn visit_f64<E>(self, v: f64) -> std::result::Result<Strict, E> {
        Ok(Strict(v.into()))
    }
    fn visit_str<E>(self, v: &str) -> std::result::Result<Strict, E> {
        Ok(Strict(v.into()))
    }
    fn visit_string<E>(self, v: String) -> std::result::Result<Strict, E> {
        Ok(Strict(v.into()))
    }
    fn visit_unit<E>(self) -> std::result::Result<Strict, E> {
        Ok(Strict(serde_json::Value::Null))
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<Strict, A::Error> {
        let mut v = Vec::new();
        while let Some(Strict(x)) = seq.next_element()? {
            v.push(x);
        }
        Ok(Strict(serde_json::Value::Array(v)))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> std::result::Result<Strict, A::Error> {
        let mut m = serde_json::Map::new();
        while let Some(k) = map.next_key::<String>()? {
            if m.contains_key(&k) {
                return Err(serde::de::Error::custom(format!("duplicate key `{k}`")));
            }
            let Strict(v) = map.next_value()?;
            m.insert(k, v);
        }
        Ok(Strict(serde_json::Value::Object(m)))
    }
}

/// Creates a new run directory whole: `fill` writes its files into a temporary sibling
/// (`.<name>.tmp<pid>-<host>`), which is then renamed into place, so a kill at any moment leaves either
/// a run with every file `fill` writes (its `run.json` included) or no run at all. The directory is
/// `out` (refused if it already holds a run, i.e. has `marker`, naming the `--resume` to use
/// instead), or a fresh `<parent>/<prefix><timestamp>`. An `out` that already holds other files
/// is filled in place, as it always was; `fill` writes the `marker` last, so there too a run is
/// never seen without its record. Temporary siblings that killed processes left are removed.
pub fn create_run_dir(
    out: Option<&Path>,
    marker: &str,
    what: &str,
    parent: &Path,
    prefix: &str,
    fill: impl FnOnce(&Path) -> Result<()>,
) -> Result<PathBuf> {
    match out {
        Some(d) => {
            if d.join(marker).exists() {
                return Err(Error::File {
                    path: d.to_path_buf(),
                    message: format!("already holds {what}: use --resume {}", d.display()),
                });
            }
            let occupied = fs::read_dir(d).map(|mut e| e.next().is_some()).unwrap_or(false);
            if occupied {
                fill(d)?;
                return Ok(d.to_path_buf());
            }
            let name = d.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            let up = d.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            create_dir(up)?;
            let tmp = build_dir(up, &name, fill)?;
            // Replaces `d` only if it is missing or empty (rename(2) refuses a non-empty one).
            fs::rename(&tmp, d).map_err(|e| {
                let _ = fs::remove_dir_all(&tmp);
                Error::io(d, e)
            })?;
            Ok(d.to_path_buf())
        }
        None => {
            create_dir(parent)?;
            let (stamp, _) = now_utc();
            let tmp = build_dir(parent, &format!("{prefix}{stamp}"), fill)?;
            for n in 1.. {
                let name = if n == 1 { format!("{prefix}{stamp}") } else { format!("{prefix}{stamp}-{n}") };
                let dir = parent.join(name);
                if something_at(&dir) {
                    continue;
                }
                match fs::rename(&tmp, &dir) {
                    Ok(()) => return Ok(dir),
                    // Taken meanwhile by another run (a whole one: it was renamed in too).
                    Err(e) if matches!(e.raw_os_error(), Some(libc::ENOTEMPTY) | Some(libc::EEXIST)) => continue,
                    Err(e) => {
                        let _ = fs::remove_dir_all(&tmp);
                        return Err(Error::io(&dir, e));
                    }
                }
            }
            unreachable!("some suffix is free")
        }
    }
}

/// A run directory `name` built in the temporary sibling `parent/.<name>.tmp<pid>` by `fill`;
/// returns the sibling. Siblings of `name` left by processes that no longer exist are removed
/// first, and this one is removed if `fill` fails.
fn build_dir(parent: &Path, name: &str, fill: impl FnOnce(&Path) -> Result<()>) -> Result<PathBuf> {
    remove_stale_builds(parent);
    // The host too: on a shared file system a process of another host is not ours to judge.
    let tmp = parent.join(format!(".{name}.tmp{}-{}", std::process::id(), host()));
    let _ = fs::remove_dir_all(&tmp);
    fs::create_dir(&tmp).map_err(|e| Error::io(&tmp, e))?;
    if let Err(e) = fill(&tmp) {
        let _ = fs::remove_dir_all(&tmp);
        return Err(e);
    }
    Ok(tmp)
}

/// The process and host of a run directory under construction, from its name
/// (`.<name>.tmp<pid>-<host>`; the host may hold dots, and is empty if left out).
fn build_owner(name: &str) -> Option<(u32, &str)> {
    let rest = name.strip_prefix('.')?;
    rest.match_indices(".tmp").find_map(|(i, _)| {
        let tail = &rest[i + 4..];
        let (pid, host) = tail.split_once('-').unwrap_or((tail, ""));
        pid.parse().ok().map(|p| (p, host))
    })
}

/// Removes the run directories under construction in `parent` whose process no longer exists on
/// this host: what a kill during [`create_run_dir`] leaves. Another host's are left alone. Best
/// effort.
fn remove_stale_builds(parent: &Path) {
    let Ok(entries) = fs::read_dir(parent) else { return };
    let here = host();
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some((pid, owner)) = build_owner(&name) else { continue };
        let dead = (owner.is_empty() || owner == here) && !running(pid);
        if dead && e.path().is_dir() {
            let _ = fs::remove_dir_all(e.path());
        }
    }
}

/// Removes the temporary files that interrupted atomic writes left in `dir` (`.<name>.tmp<pid>`).
pub fn remove_temporaries(dir: &Path) -> Result<()> {
    let Ok(entries) = fs::read_dir(dir) else { return Ok(()) };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.contains(".tmp") && e.path().is_file() {
            fs::remove_file(e.path()).map_err(|err| Error::io(e.path(), err))?;
        }
    }
    Ok(())
}

/// Whether process `pid` of this machine is running.
fn running(pid: u32) -> bool {
    Path::new(&format!("/proc/{pid}")).exists()
}

/// Removes the temporary files ([`write_atomic`]'s `.<name>.tmp<pid>`) that killed writers of
/// `path` left beside it: those of processes no longer running. Best effort: what cannot be
/// removed stays.
pub fn remove_stale_temporaries(path: &Path) {
    let (Some(parent), Some(name)) = (path.parent(), path.file_name()) else { return };
    let parent = if parent.as_os_str().is_empty() { Path::new(".") } else { parent };
    let prefix = format!(".{}.tmp", name.to_string_lossy());
    let Ok(entries) = fs::read_dir(parent) else { return };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = file.strip_prefix(&prefix).and_then(|p| p.parse::<u32>().ok()) else { continue };
        if !running(pid) && e.file_type().is_ok_and(|t| t.is_file()) {
            let _ = fs::remove_file(e.path());
        }
    }
}

/// Creates a directory and its parents; errors name it.
pub fn create_dir(path: &Path) -> Result<()> {
    fs::create_dir_all(path).map_err(|e| Error::io(path, e))
}

/// The current UTC time as `YYYYMMDD-HHMMSS` (for run ids) and RFC 3339 (for records).
pub fn now_utc() -> (String, String) {
    utc(std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs()))
}

/// Seconds since 1970 as `YYYYMMDD-HHMMSS` and as RFC 3339 UTC: the one date formatting every
/// record and page uses (the dashboard shows file times with it too).
pub fn utc(secs: u64) -> (String, String) {
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Civil-from-days (Howard Hinnant's algorithm), proleptic Gregorian.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    let (hh, mm, ss) = (rem / 3600, rem % 3600 / 60, rem % 60);
    (format!("{y:04}{m:02}{d:02}-{hh:02}{mm:02}{ss:02}"), format!("{y:04}-{m:02}-{d:02}T{hh:02}:{mm:02}:{ss:02}Z"))
}

/// A fresh run directory `root/<prefix><timestamp>` (suffixed `-2`, `-3`, … if taken).
pub fn new_run_dir(root: &Path, prefix: &str) -> Result<PathBuf> {
    create_dir(root)?;
    let (stamp, _) = now_utc();
    for n in 1.. {
        let name = if n == 1 { format!("{prefix}{stamp}") } else { format!("{prefix}{stamp}-{n}") };
        let dir = root.join(name);
        match fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(Error::io(&dir, e)),
        }
    }
    unreachable!("some suffix is free")
}

/// An exclusive claim on a run directory, released on drop. A lock left by a process that no longer
/// exists on this host is taken over.
#[derive(Debug)]
pub struct RunLock {
    path: PathBuf,
}

fn host() -> String {
    fs::read_to_string("/proc/sys/kernel/hostname").map(|h| h.trim().to_string()).unwrap_or_default()
}

impl RunLock {
    /// Claims `dir`, or explains who holds it.
    pub fn acquire(dir: &Path) -> Result<RunLock> {
        let path = dir.join("lock");
        let me = format!("{} {}", std::process::id(), host());
        for _ in 0..2 {
            match fs::OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(mut f) => {
                    f.write_all(me.as_bytes()).map_err(|e| Error::io(&path, e))?;
                    return Ok(RunLock { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let held = read_text(&path).unwrap_or_default();
                    let mut parts = held.split_whitespace();
                    let pid: Option<u32> = parts.next().and_then(|p| p.parse().ok());
                    let their_host = parts.next().unwrap_or("").to_string();
                    let alive = match pid {
                        Some(p) if their_host == host() => running(p),
                        // Empty or unreadable (a full disk while it was written): no process can
                        // be named as its holder, so it is stale.
                        None => {
                            eprintln!("warning: {}: empty or unreadable lock, treated as stale", path.display());
                            false
                        }
                        // Another host: assume alive, the user can remove the lock.
                        _ => true,
                    };
                    if alive {
                        return Err(Error::File {
                            path: dir.to_path_buf(),
                            message: format!(
                                "this run directory is in use by process {} on {} (if that process is gone, remove {})",
                                pid.map_or("?".into(), |p| p.to_string()),
                                if their_host.is_empty() { "an unknown host" } else { &their_host },
                                path.display()
                            ),
                        });
                    }
                    let _ = fs::remove_file(&path);
                }
                Err(e) => return Err(Error::io(&path, e)),
            }
        }
        Err(Error::File { path: dir.to_path_buf(), message: "could not take over a stale lock".into() })
    }

    /// True when `dir` holds a lock of a live process on this host.
    pub fn is_held(dir: &Path) -> bool {
        read_text(&dir.join("lock")).is_ok_and(|held| RunLock::held_by(&held))
    }

    /// Whether a lock file's text (`PID HOST`) names a live process on this host, or another host
    /// (which cannot be checked from here, so counts as held).
    pub fn held_by(held: &str) -> bool {
        let mut parts = held.split_whitespace();
        match (parts.next().and_then(|p| p.parse::<u32>().ok()), parts.next()) {
            (Some(p), Some(h)) if h == host() => running(p),
            _ => true,
        }
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let _ = fs::remove_file(&self.path);
    }
}

/// FNV-1a, 64 bits: the short content hash of spec hashes and file checksums (not cryptographic:
/// it catches damage, not tampering).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// [`fnv1a`] of a file's bytes, read in chunks: memory stays small however large the file.
pub fn fnv1a_file(path: &Path) -> Result<u64> {
    use std::io::Read;
    let mut f = File::open(path).map_err(|e| Error::io(path, e))?;
    let (mut h, mut buf) = (0xcbf2_9ce4_8422_2325u64, vec![0u8; 1 << 20]);
    loop {
        let n = match f.read(&mut buf) {
            Ok(0) => return Ok(h),
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(Error::io(path, e)),
        };
        for &b in &buf[..n] {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
}

/// [`fnv1a`] of a value's compact JSON, as 16 hex digits: spec hashes and unit checksums.
pub fn json_hash<T: serde::Serialize>(value: &T) -> String {
    let text = serde_json::to_string(value).expect("a stored value serialises");
    format!("{:016x}", fnv1a(text.as_bytes()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_matches_known_dates() {
        assert_eq!(utc(0).1, "1970-01-01T00:00:00Z");
        assert_eq!(utc(951_782_400).1, "2000-02-29T00:00:00Z");
        assert_eq!(utc(1_796_272_000 + 3_723), ("20261203-052843".into(), "2026-12-03T05:28:43Z".into()));
    }

    #[test]
    fn a_killed_writers_temporary_file_is_removed_and_a_live_ones_kept() {
        let dir = std::env::temp_dir().join(format!("bfqi-store-stale-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        // A process that has exited (and been waited for) holds no pid.
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let dead = child.id();
        child.wait().unwrap();
        let p = dir.join("log.csv");
        let (stale, live) = (dir.join(format!(".log.csv.tmp{dead}")), temp_path(&p));
        let other = dir.join(format!(".other.csv.tmp{dead}"));
        for f in [&stale, &live, &other] {
            fs::write(f, b"partial").unwrap();
        }
        remove_stale_temporaries(&p);
        assert!(!stale.exists(), "the dead writer's is removed");
        assert!(live.exists() && other.exists(), "this process's, and another file's, are kept");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn atomic_write_replaces_whole_file_or_nothing() {
        let dir = std::env::temp_dir().join(format!("bfqi-store-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.txt");
        write_atomic(&p, |w| w.write_all(b"first")).unwrap();
        let failed = write_atomic(&p, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("interrupted"))
        });
        assert!(failed.is_err());
        assert_eq!(fs::read_to_string(&p).unwrap(), "first");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "no temporary file left behind");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn lock_refuses_a_second_holder_and_is_released() {
        let dir = std::env::temp_dir().join(format!("bfqi-lock-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let lock = RunLock::acquire(&dir).unwrap();
        assert!(RunLock::is_held(&dir));
        let e = RunLock::acquire(&dir).unwrap_err().to_string();
        assert!(e.contains("in use by process"), "{e}");
        drop(lock);
        assert!(!RunLock::is_held(&dir));
        // A stale lock (a pid that cannot exist) is taken over.
        fs::write(dir.join("lock"), format!("4294967295 {}", host())).unwrap();
        drop(RunLock::acquire(&dir).unwrap());
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_run_directory_appears_whole_or_not_at_all() {
        let root = std::env::temp_dir().join(format!("bfqi-create-run-{}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        let whole = |d: &Path| write_json(&d.join("run.json"), &1).and_then(|_| write_json(&d.join("m.json"), &2));
        // A fill that fails half-way leaves nothing, not even its sibling under construction.
        let failed = create_run_dir(None, "m.json", "a run", &root, "r-", |d| {
            write_json(&d.join("run.json"), &1)?;
            Err(Error::Failed("killed".into()))
        });
        assert!(failed.is_err());
        assert_eq!(fs::read_dir(&root).unwrap().count(), 0);
        // What a killed process left is removed; another host's build is not ours to remove.
        fs::create_dir_all(root.join(".r-x.tmp4294967295")).unwrap();
        fs::create_dir_all(root.join(".r-y.tmp4294967295-another.host")).unwrap();
        let d = create_run_dir(None, "m.json", "a run", &root, "r-", whole).unwrap();
        assert!(d.join("run.json").is_file() && d.join("m.json").is_file());
        let mut names: Vec<String> =
            fs::read_dir(&root).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        assert_eq!(
            names,
            [".r-y.tmp4294967295-another.host".to_string(), d.file_name().unwrap().to_string_lossy().into()]
        );
        // A second run of the same second gets its own name; `--out` of a run is refused.
        let d2 = create_run_dir(None, "m.json", "a run", &root, "r-", whole).unwrap();
        assert_ne!(d, d2);
        let e = create_run_dir(Some(&d), "m.json", "a run", &root, "r-", whole).unwrap_err().to_string();
        assert!(e.contains("already holds a run: use --resume"), "{e}");
        // An empty --out folder is replaced by the whole run.
        let out = root.join("out");
        fs::create_dir(&out).unwrap();
        assert_eq!(create_run_dir(Some(&out), "m.json", "a run", &root, "r-", whole).unwrap(), out);
        assert!(out.join("run.json").is_file());
        assert_eq!(build_owner(".search-1.tmp12-node.a.b"), Some((12, "node.a.b")));
        assert_eq!(build_owner(".search-1.tmp12"), Some((12, "")));
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn timestamps_are_well_formed() {
        let (id, iso) = now_utc();
        assert_eq!(id.len(), 15);
        assert!(iso.ends_with('Z') && iso.len() == 20, "{iso}");
        assert!(id.starts_with("20"), "{id}");
    }

    #[test]
    fn unwritable_path_names_the_file() {
        let e = write_atomic(Path::new("/nonexistent-dir/x.csv"), |_| Ok(())).unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent-dir/x.csv"), "{e}");
    }
}
