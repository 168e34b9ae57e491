//! Scaffolding shared by the end-to-end tests: the binary, temporary directories that remove
//! themselves, file helpers and the tiny search every CLI test builds on.
#![allow(dead_code)] // each test file uses part of it

use serde_json::Value;
use std::ffi::OsStr;
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The `bfqi-ga` binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_bfqi-ga"))
}

/// A directory under the system's temporary directory, unique to this process and name, removed
/// when dropped. A failing test keeps it (and prints where), so its files can be inspected.
pub struct TempDir(PathBuf);

impl TempDir {
    /// The path, without creating anything (for `--out` directories the tool must create).
    pub fn path(&self) -> &Path {
        &self.0
    }

    /// The path as a string, for command-line arguments built with `format!` or `&str` slices.
    pub fn str(&self) -> &str {
        self.0.to_str().expect("temporary paths are UTF-8")
    }
}

impl Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<OsStr> for TempDir {
    fn as_ref(&self) -> &OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept {} for inspection", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A [`TempDir`] that does not exist yet (anything left by an earlier run is removed).
pub fn fresh(prefix: &str, name: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("bfqi-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    TempDir(d)
}

/// [`fresh`], created empty.
pub fn empty_dir(prefix: &str, name: &str) -> TempDir {
    let d = fresh(prefix, name);
    std::fs::create_dir_all(&d.0).unwrap();
    d
}

/// The file's text; a missing file fails the test naming it.
pub fn read(p: impl AsRef<Path>) -> String {
    let p = p.as_ref();
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The file parsed as JSON.
pub fn json(p: impl AsRef<Path>) -> Value {
    let p = p.as_ref();
    serde_json::from_str(&read(p)).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Copies a directory tree (a run directory, to damage or resume the copy).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.path().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}

/// Starts `cmd` with its output discarded: a run the test will kill or interrupt.
pub fn spawn_quiet(cmd: &mut Command) -> Child {
    cmd.stdout(Stdio::null()).stderr(Stdio::null()).spawn().expect("the binary under test starts")
}

/// Waits until `dir` holds at least `n` entries (say, stored units), the child has ended, or two
/// minutes have passed, whichever comes first; returns how many entries `dir` holds then. Used to
/// kill a run part-way through: the caller asserts that the run was still short of its end.
pub fn wait_for_entries(dir: &Path, n: usize, child: &mut Child) -> usize {
    let count = || std::fs::read_dir(dir).map(|d| d.count()).unwrap_or(0);
    let t = Instant::now();
    while count() < n && t.elapsed() < Duration::from_secs(120) && child.try_wait().unwrap().is_none() {
        std::thread::sleep(Duration::from_millis(2));
    }
    count()
}

/// A tiny but real search's flags: cart-pole-sized datasets of 25 episodes, 2 datasets, 2 FQI
/// iterations, 4 individuals, 2 generations, quiet. Seconds per run.
pub const TINY: [&str; 14] = [
    "--quick",
    "--episodes",
    "25",
    "--datasets",
    "2",
    "--iterations",
    "2",
    "--population",
    "4",
    "--generations",
    "2",
    "--seed",
    "5",
    "--quiet",
];

/// [`TINY`] with the flags in `extra` replacing its own (`--flag value` pairs, or lone switches).
pub fn tiny_with(extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = TINY.iter().map(|s| s.to_string()).collect();
    let mut i = 0;
    while i < extra.len() {
        let takes_value = i + 1 < extra.len() && !extra[i + 1].starts_with("--");
        if let Some(p) = args.iter().position(|a| a == extra[i]) {
            if takes_value {
                args[p + 1] = extra[i + 1].to_string();
            }
        } else {
            args.push(extra[i].to_string());
            if takes_value {
                args.push(extra[i + 1].to_string());
            }
        }
        i += if takes_value { 2 } else { 1 };
    }
    args
}

/// A response read by [`http_get`]: status, the headers' lines, body (as sent, and as text with
/// anything not UTF-8 replaced, so an image's bytes can be checked and a page's text searched).
pub struct Http {
    pub status: u16,
    pub headers: String,
    pub bytes: Vec<u8>,
    pub body: String,
}

impl Http {
    /// The value of a header (case-insensitive name), if sent.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.trim().eq_ignore_ascii_case(name).then(|| v.trim())
        })
    }
}

/// One HTTP/1.1 request to `base` (`http://host:port/`) for `path`, sent as written (so `..` and
/// odd encodings reach the server unchanged), the connection closed after it.
pub fn http_request(base: &str, method: &str, path: &str) -> Http {
    use std::io::{Read, Write};
    let addr = base.trim_start_matches("http://").trim_end_matches('/');
    let mut s = std::net::TcpStream::connect(addr).unwrap_or_else(|e| panic!("{addr}: {e}"));
    write!(s, "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    // A server at its connection cap answers 503 and closes: if the request arrived after it
    // looked, the close resets the connection, after the answer (kept in `raw`).
    if let Err(e) = s.read_to_end(&mut raw) {
        assert!(e.kind() == std::io::ErrorKind::ConnectionReset && raw.starts_with(b"HTTP/1.1 503"), "{path}: {e}");
    }
    let end = raw.windows(4).position(|w| w == b"\r\n\r\n").expect("the end of the headers");
    let head = String::from_utf8_lossy(&raw[..end]).into_owned();
    let (status_line, headers) = head.split_once("\r\n").unwrap_or((&head, ""));
    let status = status_line.split_whitespace().nth(1).and_then(|c| c.parse().ok()).expect("a status code");
    let mut r = Http { status, headers: headers.to_string(), bytes: Vec::new(), body: String::new() };
    let body = &raw[end + 4..];
    let chunked = r.header("transfer-encoding").is_some_and(|t| t.eq_ignore_ascii_case("chunked"));
    // Chunks are cut at byte counts, possibly inside a character: joined before decoding.
    r.bytes = if chunked { dechunk(body) } else { body.to_vec() };
    r.body = String::from_utf8_lossy(&r.bytes).into_owned();
    r
}

/// A chunked body's content: hex sizes, each chunk followed by CRLF, up to the empty chunk.
fn dechunk(mut s: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let eol = s.windows(2).position(|w| w == b"\r\n").expect("a chunk size line");
        let size = std::str::from_utf8(&s[..eol]).unwrap();
        let n = usize::from_str_radix(size.split(';').next().unwrap().trim(), 16).expect("a hex chunk size");
        if n == 0 {
            return out;
        }
        out.extend_from_slice(&s[eol + 2..eol + 2 + n]);
        s = &s[eol + 2 + n + 2..];
    }
}

/// [`http_request`] with GET.
pub fn http_get(base: &str, path: &str) -> Http {
    http_request(base, "GET", path)
}

/// The distinct settings a search's records name.
pub fn settings(dir: &Path) -> std::collections::BTreeSet<String> {
    read(dir.join("generations.jsonl"))
        .lines()
        .flat_map(|l| {
            let g: Value = serde_json::from_str(l).unwrap();
            g["individuals"]
                .as_array()
                .unwrap()
                .iter()
                .map(|i| i["setting"].as_str().unwrap().to_string())
                .collect::<Vec<_>>()
        })
        .collect()
}

/// FNV-1a, 64 bits: the model file's checksum of its body.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// A model file (8-byte magic, u16 version, postcard body, FNV-1a of the body) with its body
/// replaced and the checksum made right, so a mutation reaches the checks past the checksum.
pub fn with_body(bytes: &[u8], body: &[u8]) -> Vec<u8> {
    let mut out = bytes[..10].to_vec();
    out.extend_from_slice(body);
    out.extend_from_slice(&fnv1a(body).to_le_bytes());
    out
}

/// The body's first field, the info JSON (a postcard string: varint length, then the text): its
/// text and the rest of the body.
pub fn split_info(body: &[u8]) -> (String, &[u8]) {
    let (mut len, mut at) = (0usize, 0);
    loop {
        len |= usize::from(body[at] & 0x7f) << (7 * at);
        at += 1;
        if body[at - 1] < 0x80 {
            break;
        }
    }
    (String::from_utf8(body[at..at + len].to_vec()).unwrap(), &body[at + len..])
}

pub fn varint(mut n: usize, out: &mut Vec<u8>) {
    loop {
        let b = (n & 0x7f) as u8;
        n >>= 7;
        out.push(if n > 0 { b | 0x80 } else { b });
        if n == 0 {
            return;
        }
    }
}

pub mod gym;
