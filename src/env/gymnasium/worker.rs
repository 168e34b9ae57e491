//! Worker processes: started with the env's Python, kept in a pool per env once they have
//! answered, and stopped (never reused) after any failure.
//!
//! Each process has a writer and a reader thread, so a request and its reply can both be timed
//! out: a worker that does not answer within `env.timeout_s` is killed and the request fails
//! naming the env. Its stderr is read by a third thread, which keeps the last lines for the
//! messages of a crash. A process left in the pool when the tool exits sees the end of its input
//! and exits too (also after `kill -9` of the tool).

use super::wire::{Frame, PROTOCOL};
use super::{GymConfig, Probed, Space};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::{HashMap, VecDeque};
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// The worker's source, run as `python -c`.
const SOURCE: &str = include_str!("../../../python/bfqi_gym_worker.py");

/// Lines of a worker's stderr kept for error messages.
const TAIL: usize = 20;

/// A running worker with an env open.
pub(super) struct Proc {
    child: Child,
    to: Sender<Vec<u8>>,
    from: Receiver<std::io::Result<Option<Frame>>>,
    tail: Arc<Mutex<VecDeque<String>>>,
    python: String,
    /// What the worker reported of the env.
    pub(super) probed: Probed,
    /// The versions its hello named.
    versions: Versions,
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Idle workers by what they opened (Python, id, make arguments, rendering).
fn pool() -> &'static Mutex<HashMap<String, Vec<Proc>>> {
    static POOL: OnceLock<Mutex<HashMap<String, Vec<Proc>>>> = OnceLock::new();
    POOL.get_or_init(|| Mutex::new(HashMap::new()))
}

/// Seconds spent in the workers (their own `busy` figures), seconds waited for replies, and
/// round trips, over the process's life: what `bench` reports as the bridge's cost.
static BUSY_NS: AtomicU64 = AtomicU64::new(0);
static WAIT_NS: AtomicU64 = AtomicU64::new(0);
static TRIPS: AtomicU64 = AtomicU64::new(0);
static STARTS: AtomicU64 = AtomicU64::new(0);

/// The bridge's running totals: (seconds the workers were busy, seconds waited for replies,
/// round trips, workers started).
pub(super) fn totals() -> (f64, f64, u64, u64) {
    let s = |a: &AtomicU64| a.load(Ordering::Relaxed) as f64 * 1e-9;
    (s(&BUSY_NS), s(&WAIT_NS), TRIPS.load(Ordering::Relaxed), STARTS.load(Ordering::Relaxed))
}

/// A worker checked out of the pool for one job (a batch of episodes, an evaluation); it goes
/// back when the job is done, unless it failed.
pub(super) struct Session<'a> {
    cfg: &'a GymConfig,
    key: String,
    proc: Option<Proc>,
}

impl Drop for Session<'_> {
    fn drop(&mut self) {
        if let Some(p) = self.proc.take() {
            pool().lock().expect("worker pool").entry(self.key.clone()).or_default().push(p);
        }
    }
}

fn key(cfg: &GymConfig, render: bool) -> String {
    let v = serde_json::json!([cfg.python(), cfg.id, cfg.kwargs, cfg.max_episode_steps, render]);
    v.to_string()
}

impl<'a> Session<'a> {
    /// An idle worker of this env, or a new one; its report must match `env.probed`.
    pub(super) fn checkout(cfg: &'a GymConfig, render: bool) -> Result<Session<'a>> {
        let key = key(cfg, render);
        let idle = pool().lock().expect("worker pool").get_mut(&key).and_then(Vec::pop);
        let proc = match idle {
            Some(p) => p,
            None => start(cfg, render)?,
        };
        cfg.check_same(&proc.probed)?;
        Ok(Session { cfg, key, proc: Some(proc) })
    }

    /// The Python, gymnasium, numpy and minari versions the worker runs.
    pub(super) fn versions(&self) -> &Versions {
        &self.proc.as_ref().expect("a checked-out worker").versions
    }

    /// What the worker reported of the env.
    pub(super) fn probed(&self) -> &Probed {
        &self.proc.as_ref().expect("a checked-out worker").probed
    }

    /// Sends a request and waits for its reply; `what` names the job in messages. On any failure
    /// the worker is stopped and not reused.
    pub(super) fn ask(&mut self, what: &str, request: &Frame) -> Result<Frame> {
        let mut p = self.proc.take().expect("a checked-out worker");
        let r = exchange(&mut p, self.cfg, what, request);
        if r.is_ok() {
            self.proc = Some(p);
        }
        r
    }
}

/// Starts a worker, waits for its hello and opens the env.
fn start(cfg: &GymConfig, render: bool) -> Result<Proc> {
    let python = cfg.python();
    let id = &cfg.id;
    let mut child = Command::new(&python)
        .args(["-c", SOURCE])
        .env("PYTHONHASHSEED", "0")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| {
            Error::invalid(
                "env.python",
                &python,
                format!(
                    "cannot be started for gymnasium env {id} ({e}); install Python 3 with gymnasium, or set env.python or BFQI_PYTHON"
                ),
            )
        })?;
    STARTS.fetch_add(1, Ordering::Relaxed);
    let (mut stdin, stdout, stderr) =
        (child.stdin.take().expect("piped"), child.stdout.take().expect("piped"), child.stderr.take().expect("piped"));
    let tail = Arc::new(Mutex::new(VecDeque::new()));
    let t = Arc::clone(&tail);
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { break };
            let mut q = t.lock().expect("stderr tail");
            if q.len() == TAIL {
                q.pop_front();
            }
            q.push_back(line.chars().take(400).collect());
        }
    });
    let (to, inbox) = mpsc::channel::<Vec<u8>>();
    std::thread::spawn(move || {
        for bytes in inbox {
            if std::io::Write::write_all(&mut stdin, &bytes).and_then(|_| std::io::Write::flush(&mut stdin)).is_err() {
                break;
            }
        }
    });
    let (outbox, from) = mpsc::channel();
    std::thread::spawn(move || {
        let mut r = BufReader::with_capacity(1 << 16, stdout);
        loop {
            let f = Frame::read(&mut r);
            let end = !matches!(f, Ok(Some(_)));
            if outbox.send(f).is_err() || end {
                break;
            }
        }
    });
    let placeholder = Probed {
        observation: Space::Other { repr: String::new() },
        action: Space::Other { repr: String::new() },
        max_episode_steps: None,
        dt: None,
        rgb_array: false,
    };
    let versions = Versions::default();
    let mut p = Proc { child, to, from, tail, python: python.clone(), probed: placeholder, versions };
    // A program that starts but is no Python running the worker (`/bin/false`) is env.python's
    // fault, as one that cannot be started is.
    let hello = receive(&mut p, cfg, "its start").map_err(|e| {
        Error::invalid(
            "env.python",
            &python,
            format!(
                "did not run the gymnasium worker for env {id} ({}); it must be Python 3 with gymnasium: set env.python or BFQI_PYTHON",
                e.to_string().strip_prefix(&format!("gymnasium env {id}: ")).unwrap_or(&e.to_string())
            ),
        )
    })?;
    if hello.header.get("ok") != Some(&Value::Bool(true)) {
        let err = text(&hello, "error");
        return Err(if text(&hello, "kind") == "import" {
            Error::invalid(
                "env.python",
                &python,
                format!(
                    "cannot import gymnasium for env {id} ({err}); install it: {python} -m pip install gymnasium numpy"
                ),
            )
        } else {
            failed(&p, cfg, &format!("its start failed: {err}"))
        });
    }
    let named = |k: &str| hello.header.get(k).and_then(Value::as_str).map(String::from);
    p.versions = Versions {
        python: named("python").unwrap_or_default(),
        gymnasium: named("gymnasium").unwrap_or_default(),
        numpy: named("numpy").unwrap_or_default(),
        minari: named("minari"),
    };
    let protocol = hello.header.get("protocol").and_then(Value::as_u64);
    if protocol != Some(PROTOCOL) {
        let theirs = protocol.map_or("none".to_string(), |v| v.to_string());
        return Err(failed(&p, cfg, &format!("it speaks protocol {theirs}, this build {PROTOCOL}")));
    }
    let open = Frame::request(
        "open",
        serde_json::json!({"id": id, "kwargs": cfg.kwargs, "max_episode_steps": cfg.max_episode_steps, "render": render}),
    );
    let reply = round_trip(&mut p, cfg, "open", &open)?;
    if reply.header.get("ok") != Some(&Value::Bool(true)) {
        let err = text(&reply, "error");
        return Err(if text(&reply, "kind") == "make" {
            Error::invalid("env.id", id, err)
        } else {
            failed(&p, cfg, &format!("open failed: {err}"))
        });
    }
    p.probed = probed_of(&reply).ok_or_else(|| failed(&p, cfg, "it described the env's spaces in an unknown form"))?;
    Ok(p)
}

fn probed_of(reply: &Frame) -> Option<Probed> {
    let h = &reply.header;
    let space = |k: &str| serde_json::from_value::<Space>(h.get(k)?.clone()).ok();
    let modes = h.get("render_modes").and_then(Value::as_array);
    Some(Probed {
        observation: space("observation")?,
        action: space("action")?,
        max_episode_steps: h.get("max_episode_steps").and_then(Value::as_u64).map(|m| m as usize),
        dt: h.get("dt").and_then(Value::as_f64),
        rgb_array: modes.is_some_and(|m| m.iter().any(|x| x.as_str() == Some("rgb_array"))),
    })
}

/// The Python stack a gymnasium run ran on, recorded in its `run.json`: a run is bit-identical
/// only under the same gymnasium and numpy (an env's dynamics and numpy's `sin` are theirs).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Versions {
    /// Python's `major.minor.micro`.
    pub python: String,
    /// `gymnasium.__version__`.
    pub gymnasium: String,
    /// `numpy.__version__`.
    pub numpy: String,
    /// Minari's version, when installed.
    #[serde(default)]
    pub minari: Option<String>,
}

impl Versions {
    /// What differs from `now`, one phrase per package: `gymnasium 1.2.0 when recorded, 1.4.0 now`.
    pub fn differences(&self, now: &Versions) -> Vec<String> {
        let show = |v: &Option<String>| v.clone().unwrap_or_else(|| "not installed".into());
        [
            ("Python", self.python.clone(), now.python.clone()),
            ("gymnasium", self.gymnasium.clone(), now.gymnasium.clone()),
            ("numpy", self.numpy.clone(), now.numpy.clone()),
            ("minari", show(&self.minari), show(&now.minari)),
        ]
        .into_iter()
        .filter(|(_, a, b)| a != b)
        .map(|(name, a, b)| format!("{name} {a} when recorded, {b} now"))
        .collect()
    }
}

/// The versions of the Python stack a worker for `cfg` runs (a pooled worker's, else a new one's).
pub(super) fn versions(cfg: &GymConfig) -> Result<Versions> {
    Ok(Session::checkout(cfg, false)?.versions().clone())
}

/// Asks a worker what the env is (the first time a spec naming it is read).
/// Its reset options are tried once each, so options the env refuses are refused with the spec,
/// naming their field, rather than when the run first resets.
pub(super) fn probe(cfg: &GymConfig) -> Result<Probed> {
    let mut s = Session::checkout(cfg, false)?;
    let probed = s.probed().clone();
    for (field, options) in [("reset_options", &cfg.reset_options), ("eval.reset_options", &cfg.eval.reset_options)] {
        let Some(o) = options else { continue };
        let req = Frame::request("reset", serde_json::json!({"options": o, "field": format!("env.{field}")})).with(
            "seeds",
            &[1],
            super::wire::Data::U8(vec![0]),
        );
        s.ask("a trial reset", &req).map_err(|e| {
            let text = e.to_string();
            let why = text.strip_prefix(&format!("gymnasium env {}: ", cfg.id)).unwrap_or(&text);
            let why = why.strip_suffix(&format!(": check env.{field} in the spec")).unwrap_or(why);
            Error::invalid(
                format!("env.{field}"),
                Value::Object(o.clone()),
                format!("gymnasium env {}'s reset refuses it: {why}", cfg.id),
            )
        })?;
    }
    Ok(probed)
}

fn text(f: &Frame, k: &str) -> String {
    f.header.get(k).and_then(Value::as_str).unwrap_or("").to_string()
}

/// Sends `request` and returns the worker's successful reply; a refusal (`ok: false`) is an error
/// naming the env.
fn exchange(p: &mut Proc, cfg: &GymConfig, what: &str, request: &Frame) -> Result<Frame> {
    let reply = round_trip(p, cfg, what, request)?;
    if reply.header.get("ok") == Some(&Value::Bool(true)) {
        if let Some(b) = reply.header.get("busy").and_then(Value::as_f64) {
            BUSY_NS.fetch_add((b.max(0.0) * 1e9) as u64, Ordering::Relaxed);
        }
        return Ok(reply);
    }
    let _ = p.child.kill();
    if text(&reply, "kind") == "reset" {
        // The env refused the spec's reset options: name the field that holds them.
        let field = request.header.get("field").and_then(Value::as_str).unwrap_or("env.reset_options");
        return Err(Error::Failed(format!(
            "gymnasium env {}: {} (during {what}): check {field} in the spec",
            cfg.id,
            text(&reply, "error")
        )));
    }
    Err(Error::Failed(format!("gymnasium env {}: {} (during {what})", cfg.id, text(&reply, "error"))))
}

/// Sends `request` and returns the worker's reply, whatever it says.
fn round_trip(p: &mut Proc, cfg: &GymConfig, what: &str, request: &Frame) -> Result<Frame> {
    if p.to.send(request.encode()).is_err() {
        return Err(ended(p, cfg, what));
    }
    receive(p, cfg, what)
}

fn receive(p: &mut Proc, cfg: &GymConfig, what: &str) -> Result<Frame> {
    let t0 = Instant::now();
    let got = p.from.recv_timeout(Duration::from_secs_f64(cfg.timeout_s));
    WAIT_NS.fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
    TRIPS.fetch_add(1, Ordering::Relaxed);
    match got {
        Ok(Ok(Some(f))) => Ok(f),
        Ok(Ok(None)) | Err(RecvTimeoutError::Disconnected) => Err(ended(p, cfg, what)),
        Ok(Err(e)) => {
            let _ = p.child.kill();
            Err(failed(p, cfg, &format!("it broke the protocol during {what} ({e})")))
        }
        Err(RecvTimeoutError::Timeout) => {
            let _ = p.child.kill();
            Err(failed(
                p,
                cfg,
                &format!("it did not answer {what} within {} s (env.timeout_s) and was stopped", cfg.timeout_s),
            ))
        }
    }
}

/// The worker's end of the pipes closed: it exited (or crashed).
fn ended(p: &mut Proc, cfg: &GymConfig, what: &str) -> Error {
    // The pipes close as the process exits; give it a moment to be reaped.
    let deadline = Instant::now() + Duration::from_secs(5);
    let status = loop {
        match p.child.try_wait() {
            Ok(Some(s)) => break s.to_string(),
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(10)),
            _ => {
                let _ = p.child.kill();
                break "closed its output".to_string();
            }
        }
    };
    failed(p, cfg, &format!("it exited ({status}) during {what}"))
}

fn failed(p: &Proc, cfg: &GymConfig, why: &str) -> Error {
    // Let the stderr reader catch up with what the process wrote last.
    std::thread::sleep(Duration::from_millis(50));
    let last = p.tail.lock().expect("stderr tail").iter().rev().find(|l| !l.trim().is_empty()).cloned();
    let last = last.map_or(String::new(), |l| format!("; its last stderr line: {}", l.trim()));
    Error::Failed(format!(
        "gymnasium env {}: the worker ({}, pid {}) failed: {why}{last}",
        cfg.id,
        p.python,
        p.child.id()
    ))
}

#[cfg(test)]
mod tests {
    use super::Versions;

    #[test]
    fn version_differences_name_each_package_that_changed() {
        let v = |numpy: &str, minari: Option<&str>| Versions {
            python: "3.11.2".into(),
            gymnasium: "1.2.0".into(),
            numpy: numpy.into(),
            minari: minari.map(String::from),
        };
        assert!(v("2.4.6", None).differences(&v("2.4.6", None)).is_empty());
        assert_eq!(
            v("2.4.6", None).differences(&v("2.3.0", Some("0.5.3"))),
            ["numpy 2.4.6 when recorded, 2.3.0 now", "minari not installed when recorded, 0.5.3 now"]
        );
    }
}
