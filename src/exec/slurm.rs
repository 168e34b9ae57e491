//! The Slurm executor: the missing units of a generation (or a comparison) become one job array,
//! submitted with `sbatch --wait`; each task runs `bfqi-ga worker <RUN_DIR> <UNIT>`, which computes
//! its unit and writes the result atomically into the run directory. The driver then reads the
//! results **from the files** (never from exit codes alone), resubmits missing units a bounded
//! number of times, and reports units that keep failing with their Slurm log paths.
//!
//! The run directory must be on a file system that every node sees (NFS, Lustre, BeeGFS…); the
//! worker refuses a unit whose run directory it cannot see.

use super::Executor;
use crate::error::{Error, Result};
use crate::run_dir::{Budget, Stop, UnitStore, Units};
use crate::store::{self, write_atomic};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// Settings of the Slurm executor.
#[derive(Debug, Clone, PartialEq)]
pub struct Slurm {
    /// The run directory (on a shared file system).
    pub run_dir: PathBuf,
    /// `--partition`.
    pub partition: Option<String>,
    /// `--time`, e.g. `02:00:00`.
    pub time: Option<String>,
    /// `--cpus-per-task`.
    pub cpus_per_task: Option<usize>,
    /// Array throttle `%T`: tasks running at once.
    pub max_parallel: Option<usize>,
    /// Further `sbatch` arguments, passed through.
    pub extra: Vec<String>,
    /// Resubmissions of missing units before giving up.
    pub retries: usize,
    /// The `bfqi-ga` binary the tasks run (must be visible from the nodes).
    pub binary: PathBuf,
    /// The `sbatch` command.
    pub sbatch: String,
    /// The `squeue` command, asked whether an array still has tasks before any is resubmitted.
    pub squeue: String,
    /// How long an unreachable controller is waited for (submission retries, and the check that an
    /// array has no task left) before the run stops with a message.
    pub controller_wait: Duration,
}

impl Slurm {
    /// An executor for `run_dir` with defaults: this binary, `sbatch` from PATH, 2 resubmissions.
    pub fn new(run_dir: &Path) -> Result<Self> {
        let binary = std::env::current_exe().map_err(|e| Error::io("bfqi-ga executable", e))?;
        let run_dir = std::fs::canonicalize(run_dir).map_err(|e| Error::io(run_dir, e))?;
        Ok(Slurm {
            run_dir,
            partition: None,
            time: None,
            cpus_per_task: None,
            max_parallel: None,
            extra: Vec::new(),
            retries: 2,
            binary,
            sbatch: std::env::var("BFQI_SBATCH").unwrap_or_else(|_| "sbatch".into()),
            squeue: std::env::var("BFQI_SQUEUE").unwrap_or_else(|_| "squeue".into()),
            controller_wait: Duration::from_secs(600),
        })
    }

    /// Submits one array over `ids` and waits for it. Returns, for each id, the log file of its task,
    /// and what `sbatch` said on stderr.
    fn submit(&self, units: &UnitStore, ids: &[String], attempt: usize) -> Result<(Vec<PathBuf>, String)> {
        let dir = self.run_dir.join("slurm");
        let logs = dir.join("logs");
        store::create_dir(&logs)?;
        // Arrays are numbered in submission order, so no two share a file (and resumes append).
        let seq = std::fs::read_dir(&dir)
            .map(|d| d.flatten().filter(|e| e.file_name().to_string_lossy().starts_with("units-")).count())
            .unwrap_or(0);
        let tag = format!("{seq:04}-try{attempt}");
        let list = dir.join(format!("units-{tag}.txt"));
        write_atomic(&list, |w| {
            for id in ids {
                writeln!(w, "{id}")?;
            }
            Ok(())
        })?;
        let script = dir.join(format!("array-{tag}.sh"));
        let body = format!(
            "#!/bin/bash\n# One bfqi-ga unit per array task; the worker writes the result atomically.\nset -eu\nid=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" {list})\nexec {bin} worker {run} \"$id\" --units {folder}\n",
            list = shell_quote(&list),
            bin = shell_quote(&self.binary),
            run = shell_quote(&self.run_dir),
            folder = shell_quote(Path::new(units.name())),
        );
        write_atomic(&script, |w| w.write_all(body.as_bytes()))?;
        let mut cmd = Command::new(&self.sbatch);
        let throttle = self.max_parallel.map_or(String::new(), |t| format!("%{t}"));
        cmd.arg("--wait")
            .arg(format!("--array=0-{}{throttle}", ids.len() - 1))
            .arg("--job-name=bfqi-ga")
            .arg(format!("--output={}/%A_%a.out", logs.display()))
            .arg(format!("--chdir={}", self.run_dir.display()));
        if let Some(p) = &self.partition {
            cmd.arg(format!("--partition={p}"));
        }
        if let Some(t) = &self.time {
            cmd.arg(format!("--time={t}"));
        }
        if let Some(c) = self.cpus_per_task {
            cmd.arg(format!("--cpus-per-task={c}"));
        }
        cmd.args(&self.extra).arg(&script);
        let (job, stderr) = self.submit_waiting(&mut cmd)?;
        // `sbatch --wait` can return while tasks still run (it lost the controller, or was killed):
        // resubmitting their units then would compute them twice, so wait until none is left.
        self.wait_gone(&job)?;
        let paths = (0..ids.len()).map(|k| logs.join(format!("{job}_{k}.out"))).collect();
        Ok((paths, stderr))
    }

    /// Runs `sbatch --wait`, retrying while the submission itself fails (no job id printed: the
    /// controller is unreachable or refuses jobs for now), for at most [`Slurm::controller_wait`].
    /// Returns the job id and what sbatch said on stderr.
    fn submit_waiting(&self, cmd: &mut Command) -> Result<(String, String)> {
        let start = Instant::now();
        let mut pause = Duration::from_secs(2);
        loop {
            // The array's exit status is not trusted either way: the result files decide.
            let out = cmd.output().map_err(|e| Error::io(&self.sbatch, e))?;
            let stdout = String::from_utf8_lossy(&out.stdout);
            let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
            if let Some(job) = job_id(&stdout) {
                return Ok((job, stderr));
            }
            if start.elapsed() >= self.controller_wait {
                return Err(Error::Failed(format!(
                    "{}: sbatch could not submit for {} s: {}; resume when the cluster accepts jobs again",
                    self.run_dir.display(),
                    start.elapsed().as_secs(),
                    first_line(&stderr)
                )));
            }
            eprintln!("slurm: submission failed ({}); retrying in {} s", first_line(&stderr), pause.as_secs());
            std::thread::sleep(pause);
            pause = (pause * 2).min(Duration::from_secs(30));
        }
    }

    /// Waits until `squeue` lists no task of `job`, for at most [`Slurm::controller_wait`] while
    /// the controller does not answer. No squeue on this machine: nothing to ask, nothing waited.
    fn wait_gone(&self, job: &str) -> Result<()> {
        let start = Instant::now();
        let mut said = String::new();
        while start.elapsed() < self.controller_wait {
            let out = match Command::new(&self.squeue).args(["-h", "-j", job, "-o", "%T"]).output() {
                Ok(out) => out,
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
                Err(e) => return Err(Error::io(&self.squeue, e)),
            };
            let stderr = String::from_utf8_lossy(&out.stderr);
            if out.status.success() {
                let listed = String::from_utf8_lossy(&out.stdout);
                // Finished tasks linger as COMPLETED/FAILED/CANCELLED for a while: only live ones count.
                if !listed.lines().any(|t| LIVE.contains(&t.trim())) {
                    return Ok(());
                }
            } else if stderr.contains("Invalid job id") {
                return Ok(()); // already purged from the controller's memory: long over
            } else {
                said = first_line(&stderr).to_string();
            }
            std::thread::sleep(Duration::from_secs(2));
        }
        Err(Error::Failed(format!(
            "{}: Slurm job {job} still has tasks (or the controller does not answer{}) after {} s; resume once it has ended",
            self.run_dir.display(),
            if said.is_empty() { String::new() } else { format!(": {said}") },
            start.elapsed().as_secs()
        )))
    }
}

/// Task states in which a task may still write its unit.
const LIVE: [&str; 9] =
    ["PENDING", "RUNNING", "CONFIGURING", "COMPLETING", "SUSPENDED", "REQUEUED", "RESIZING", "SIGNALING", "STAGE_OUT"];

/// The job id in sbatch's "Submitted batch job N".
fn job_id(stdout: &str) -> Option<String> {
    let rest = stdout.lines().find_map(|l| l.trim().strip_prefix("Submitted batch job "))?;
    let id = rest.split_whitespace().next()?;
    id.chars().all(|c| c.is_ascii_digit()).then(|| id.to_string())
}

fn first_line(s: &str) -> &str {
    let line = s.lines().find(|l| !l.trim().is_empty()).unwrap_or("no message");
    line.trim()
}

use std::io::Write as _;

fn shell_quote(p: &Path) -> String {
    format!("'{}'", p.display().to_string().replace('\'', "'\\''"))
}

impl Executor for Slurm {
    fn run(
        &self,
        units: &dyn Units,
        ids: &[String],
        budget: &Budget<'_>,
        done: &(dyn Fn(&str) + Sync),
    ) -> Result<Option<Stop>> {
        // The units are computed by `bfqi-ga worker` on the nodes; here they are only looked up.
        let mut missing: Vec<String> = ids.iter().filter(|id| !units.stored(id)).cloned().collect();
        for id in ids.iter().filter(|id| !missing.contains(id)) {
            done(id);
        }
        let mut last: Vec<(String, PathBuf)> = Vec::new();
        let mut said = String::new();
        for attempt in 0..=self.retries {
            if missing.is_empty() {
                break;
            }
            if let Some(stop) = budget.check() {
                return Ok(Some(stop));
            }
            let (logs, stderr) = self.submit(units.store(), &missing, attempt)?;
            said = stderr;
            last = missing.iter().cloned().zip(logs).collect();
            missing.retain(|id| {
                let there = units.stored(id);
                if there {
                    done(id);
                }
                !there
            });
            if !missing.is_empty() && attempt < self.retries {
                // Said, so a lost task (a node that died, a cancelled or killed task) is noticed.
                let first: Vec<&str> = missing.iter().take(3).map(String::as_str).collect();
                eprintln!(
                    "slurm: {} unit(s) missing after submission {} ({}{}); resubmitting",
                    missing.len(),
                    attempt + 1,
                    first.join(", "),
                    if missing.len() > 3 { ", …" } else { "" }
                );
            }
        }
        if missing.is_empty() {
            return Ok(None);
        }
        if let Some(stop) = budget.check() {
            return Ok(Some(stop));
        }
        let shown: Vec<String> = last
            .iter()
            .filter(|(id, _)| missing.contains(id))
            .take(5)
            .map(|(id, log)| format!("{id} (log {})", log.display()))
            .collect();
        let said = if said.is_empty() { String::new() } else { format!("; sbatch said: {said}") };
        // The run failed (exit 1), it is not bad input: resumable once the cause is fixed.
        Err(Error::Failed(format!(
            "{}: {} unit(s) still missing after {} submission(s): {}{said}",
            self.run_dir.display(),
            missing.len(),
            self.retries + 1,
            shown.join(", ")
        )))
    }
}
