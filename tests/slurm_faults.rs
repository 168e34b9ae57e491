//! Faults on a real single-node Slurm cluster (CI starts one with scripts/local-slurm.sh and sets
//! `BFQI_REAL_SLURM=1`, `SLURM_CONF` and `BFQI_SLURM_DIR`): while a small search and a small
//! comparison run with `--executor slurm`, a thread cancels running array tasks, SIGKILLs workers,
//! stops and restarts slurmd, drains and resumes the node, and keeps slurmctld away for a while.
//! Each run must end identical to the local run (timings aside), or stop with a one-line message
//! and resume to it; the task logs show that no unit was computed by two tasks.
//!
//! Its own test binary, so nothing else submits to the cluster while it injects faults.

mod common;
use common::{bin, empty_dir, read};

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::sleep;
use std::time::{Duration, Instant};

/// The job name our arrays carry, so faults only ever hit this test's tasks.
const JOB: &str = "bfqi-faults";

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Fault {
    /// `scancel` of one running array task.
    Scancel,
    /// A running worker killed with SIGKILL.
    Sigkill,
    /// slurmd stopped for a few seconds mid-array, then started again.
    SlurmdRestart,
    /// The node drained (running tasks finish, nothing new starts), then resumed.
    Drain,
    /// slurmctld stopped for 15 s while tasks run, then started again.
    ControllerAway,
}

struct Cluster {
    conf: String,
    dir: PathBuf,
    node: String,
}

fn cluster() -> Option<Cluster> {
    if std::env::var("BFQI_REAL_SLURM").as_deref() != Ok("1") {
        eprintln!("BFQI_REAL_SLURM is not 1: the Slurm fault test runs in CI (scripts/local-slurm.sh)");
        return None;
    }
    let conf = std::env::var("SLURM_CONF").expect("SLURM_CONF with BFQI_REAL_SLURM=1");
    let dir = PathBuf::from(std::env::var("BFQI_SLURM_DIR").unwrap_or_else(|_| "/tmp/bfqi-slurm".into()));
    let out = cmd("sinfo", &["-h", "-o", "%N"]);
    let node = String::from_utf8_lossy(&out.stdout).trim().to_string();
    assert!(!node.is_empty(), "sinfo names no node: {}", String::from_utf8_lossy(&out.stderr));
    Some(Cluster { conf, dir, node })
}

fn cmd(program: &str, args: &[&str]) -> Output {
    Command::new(program).args(args).output().unwrap_or_else(|e| panic!("{program}: {e}"))
}

fn alive(pid: &str) -> bool {
    Path::new("/proc").join(pid).exists()
}

impl Cluster {
    /// Running tasks of our arrays, as `JOB_TASK`.
    fn running(&self) -> Vec<String> {
        let out = cmd("squeue", &["-h", "-t", "R", "-n", JOB, "-o", "%i"]);
        String::from_utf8_lossy(&out.stdout).lines().map(|l| l.trim().to_string()).filter(|l| !l.is_empty()).collect()
    }

    fn pid(&self, daemon: &str) -> String {
        read(self.dir.join(format!("{daemon}.pid"))).trim().to_string()
    }

    /// Stops a daemon by its PID file, waits `away`, starts it again and waits until it answers.
    fn bounce(&self, daemon: &str, away: Duration) {
        let pid = self.pid(daemon);
        assert!(cmd("kill", &["-TERM", &pid]).status.success(), "kill {daemon} {pid}");
        let t = Instant::now();
        while alive(&pid) && t.elapsed() < Duration::from_secs(30) {
            sleep(Duration::from_millis(100));
        }
        assert!(!alive(&pid), "{daemon} {pid} did not stop");
        sleep(away);
        let o = cmd(daemon, &["-f", &self.conf]);
        assert!(o.status.success(), "{daemon} did not start: {}", String::from_utf8_lossy(&o.stderr));
        let t = Instant::now();
        while t.elapsed() < Duration::from_secs(60) {
            let o = cmd("sinfo", &["-h", "-n", &self.node, "-o", "%t"]);
            let state = String::from_utf8_lossy(&o.stdout).trim().to_string();
            if o.status.success() && !state.is_empty() && !state.ends_with('*') {
                return;
            }
            sleep(Duration::from_millis(200));
        }
        panic!("the cluster did not answer after {daemon} restarted");
    }

    fn node_state(&self, state: &str) {
        let mut args = vec!["update".to_string(), format!("NodeName={}", self.node), format!("State={state}")];
        if state == "DRAIN" {
            args.push("Reason=bfqi-fault-test".into());
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = cmd("scontrol", &args);
        assert!(o.status.success(), "scontrol {args:?}: {}", String::from_utf8_lossy(&o.stderr));
    }

    /// Injects `fault` once some task of ours runs; false when the run ended first.
    fn inject(&self, fault: Fault, run: &Path, done: &AtomicBool) -> bool {
        loop {
            if done.load(Ordering::SeqCst) {
                return false;
            }
            let running = self.running();
            if let Some(task) = running.first() {
                match fault {
                    Fault::Scancel => {
                        if cmd("scancel", &[task]).status.success() {
                            return true;
                        }
                    }
                    Fault::Sigkill => {
                        let pattern = format!("bfqi-ga worker {}", run.display());
                        let out = cmd("pgrep", &["-f", &pattern]);
                        let pids = String::from_utf8_lossy(&out.stdout);
                        if let Some(pid) = pids.split_whitespace().next()
                            && cmd("kill", &["-KILL", pid]).status.success()
                        {
                            return true;
                        }
                    }
                    Fault::SlurmdRestart => {
                        self.bounce("slurmd", Duration::from_secs(3));
                        return true;
                    }
                    Fault::Drain => {
                        self.node_state("DRAIN");
                        sleep(Duration::from_secs(4));
                        self.node_state("RESUME");
                        return true;
                    }
                    Fault::ControllerAway => {
                        self.bounce("slurmctld", Duration::from_secs(15));
                        return true;
                    }
                }
            }
            sleep(Duration::from_millis(25));
        }
    }
}

/// Runs `args` (a search or a comparison writing to `run`) through Slurm while faults are injected
/// in `plan`'s order; resumes after a failure that stopped it with a one-line message. Returns how
/// many faults of each kind were injected and how many resumes it took.
fn survive(c: &Cluster, args: &[String], run: &Path, plan: &[Fault]) -> (BTreeMap<Fault, usize>, usize) {
    let injected = Arc::new(Mutex::new(BTreeMap::new()));
    let done = Arc::new(AtomicBool::new(false));
    let spawn = |resume: bool| -> Child {
        let mut cmd = bin();
        if resume {
            cmd.arg(&args[0]).arg("--resume").arg(run);
        } else {
            cmd.args(args).arg("--out").arg(run);
        }
        cmd.args(["--executor", "slurm", "--slurm-time", "00:10:00", "--slurm-arg", &format!("--job-name={JOB}")])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let injector = {
        let (plan, injected, done, run) = (plan.to_vec(), injected.clone(), done.clone(), run.to_path_buf());
        let c = Cluster { conf: c.conf.clone(), dir: c.dir.clone(), node: c.node.clone() };
        std::thread::spawn(move || {
            for fault in plan {
                if !c.inject(fault, &run, &done) {
                    return;
                }
                *injected.lock().unwrap().entry(fault).or_insert(0) += 1;
                // Let the next array task start before the next fault.
                sleep(Duration::from_secs(2));
            }
        })
    };
    let mut resumes = 0;
    let mut child = spawn(false);
    loop {
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        if out.status.success() {
            break;
        }
        // A stop must be a failed run (exit 1) with a one-line message, then resume.
        assert_eq!(out.status.code(), Some(1), "{err}");
        let last = err.lines().last().unwrap_or_default();
        assert!(last.starts_with("error: ") && !err.contains("panicked"), "{err}");
        resumes += 1;
        assert!(resumes <= 3, "still failing after 3 resumes: {err}");
        child = spawn(true);
    }
    done.store(true, Ordering::SeqCst);
    injector.join().unwrap();
    let injected = injected.lock().unwrap().clone();
    (injected, resumes)
}

/// A unit file with its timings (`*seconds`) and the checksum over them left out.
fn untimed(path: &Path) -> serde_json::Value {
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.retain(|k, _| !k.ends_with("seconds") && k != "checksum");
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut v: serde_json::Value = serde_json::from_str(&read(path)).unwrap();
    strip(&mut v);
    v
}

/// The results of `folder` (units/, validation/), by name, timings left out; temporary files a
/// killed worker left (`.NAME.tmpPID`, never read as results) are not results.
fn results(run: &Path, folder: &str) -> BTreeMap<String, serde_json::Value> {
    let Ok(dir) = std::fs::read_dir(run.join(folder)) else { return BTreeMap::new() };
    dir.flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| !n.starts_with('.'))
        .map(|n| (n.clone(), untimed(&run.join(folder).join(&n))))
        .collect()
}

/// How many times each unit was computed to the end, from the task logs.
fn computed(run: &Path) -> HashMap<String, usize> {
    let mut seen = HashMap::new();
    for e in std::fs::read_dir(run.join("slurm/logs")).unwrap().flatten() {
        for line in read(e.path()).lines() {
            if let Some(id) = line.strip_suffix(": computed and stored") {
                *seen.entry(id.to_string()).or_insert(0) += 1;
            }
        }
    }
    seen
}

/// A CSV file without its timing columns (`*_seconds`).
fn untimed_csv(path: &Path) -> Vec<Vec<String>> {
    let text = read(path);
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let keep: Vec<bool> = header.iter().map(|h| !h.ends_with("_seconds")).collect();
    std::iter::once(text.lines().next().unwrap_or_default())
        .chain(lines)
        .map(|l| l.split(',').zip(&keep).filter(|(_, k)| **k).map(|(c, _)| c.to_string()).collect())
        .collect()
}

/// Same results as the local run, every unit computed by exactly one task.
fn same_as_local(local: &Path, slurm: &Path, files: &[&str], folders: &[&str]) {
    for f in files {
        if f.ends_with(".csv") {
            assert_eq!(untimed_csv(&local.join(f)), untimed_csv(&slurm.join(f)), "{f}: slurm with faults vs local");
        } else {
            assert_eq!(read(local.join(f)), read(slurm.join(f)), "{f}: slurm with faults vs local");
        }
    }
    let mut units = 0;
    for folder in folders {
        let (l, s) = (results(local, folder), results(slurm, folder));
        assert!(!l.is_empty(), "{folder}: no local results");
        assert_eq!(l.keys().collect::<Vec<_>>(), s.keys().collect::<Vec<_>>(), "{folder}: unit names");
        for (name, v) in &l {
            assert_eq!(v, &s[name], "{folder}/{name}: slurm with faults vs local (timings aside)");
        }
        units += l.len();
    }
    let seen = computed(slurm);
    assert_eq!(seen.len(), units, "units computed per the task logs vs results stored");
    let twice: Vec<_> = seen.iter().filter(|(_, n)| **n > 1).collect();
    assert!(twice.is_empty(), "computed by more than one task: {twice:?}");
}

/// Printed past the test harness's capture, so CI's log shows the counts.
fn say(line: &str) {
    use std::io::Write as _;
    let _ = writeln!(std::io::stderr(), "{line}");
}

fn counts(injected: &BTreeMap<Fault, usize>) -> String {
    injected.iter().map(|(f, n)| format!("{f:?} {n}")).collect::<Vec<_>>().join(", ")
}

#[test]
fn a_search_and_a_comparison_survive_slurm_faults() {
    let Some(c) = cluster() else { return };
    let d = empty_dir("slurm-faults", "run");
    let all = [Fault::Scancel, Fault::Sigkill, Fault::SlurmdRestart, Fault::Drain, Fault::ControllerAway];

    // A search whose units take about a second, so faults land on running tasks.
    let search: Vec<String> = [
        "search",
        "cartpole",
        "--quick",
        "--episodes",
        "200",
        "--datasets",
        "2",
        "--iterations",
        "6",
        "--population",
        "6",
        "--generations",
        "3",
        "--seed",
        "3",
        "--quiet",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let local = d.join("search-local");
    let o = bin().args(&search).arg("--out").arg(&local).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let plan = [all.as_slice(), &[Fault::Scancel, Fault::Sigkill]].concat();
    let slurm = d.join("search-slurm");
    let (injected, resumes) = survive(&c, &search, &slurm, &plan);
    say(&format!("search: faults injected: {} ({resumes} resume(s))", counts(&injected)));
    for f in all {
        assert!(injected.get(&f).copied().unwrap_or(0) >= 1, "{f:?} never injected into the search: {injected:?}");
    }
    let files = ["generations.jsonl", "best.json", "hall_of_fame.json", "validation.json"];
    same_as_local(&local, &slurm, &files, &["units", "validation"]);

    // A comparison: B-FQI vs FQI with Extra-Trees on cart-pole.
    let compare: Vec<String> = [
        "compare",
        "cartpole",
        "--learner",
        "et",
        "--datasets",
        "6",
        "--episodes",
        "200",
        "--iterations",
        "8",
        "--quiet",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let local = d.join("compare-local");
    let o = bin().args(&compare).arg("--out").arg(&local).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let slurm = d.join("compare-slurm");
    let (injected, resumes) = survive(
        &c,
        &compare,
        &slurm,
        &[Fault::Scancel, Fault::ControllerAway, Fault::Sigkill, Fault::SlurmdRestart, Fault::Drain],
    );
    say(&format!("comparison: faults injected: {} ({resumes} resume(s))", counts(&injected)));
    // A comparison is one array (and its resubmissions): the first two faults always land; the
    // others land while it still runs, and are counted above.
    for f in [Fault::Scancel, Fault::Sigkill] {
        assert!(injected.get(&f).copied().unwrap_or(0) >= 1, "{f:?} never injected into the comparison: {injected:?}");
    }
    same_as_local(&local, &slurm, &["summary.csv", "scores.csv"], &["units"]);
}
