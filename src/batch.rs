//! Overnight batches (`bfqi-ga batch PLAN.json`): searches and comparisons run in order, each in its
//! own run directory under one batch directory. A failing job is recorded and the others go on; a
//! wall-clock budget stops cleanly between units; `--resume` continues where it stopped.
//!
//! A plan is `{"jobs": [...]}`; a job is either
//! `{"name": "s", "search": "bicycle", "presets": [...], "generations": 5, ...}` (any
//! [`SearchOverrides`] field: the flags of `search`) or
//! `{"name": "c", "compare": "bicycle", "tuned": "from:s" | "thesis" | "path/best.json",
//!   "analysis": "iterations", "learner": "et", ...}` (any [`compare::Request`] field: the flags of
//! `compare`). `from:<job>` uses the best config that search job found.

use crate::compare;
use crate::error::{Error, Result};
use crate::exec::ExecutorFactory;
use crate::ga::search::{self, SearchOverrides};
use crate::run_dir::{Budget, Ending};
use crate::store::{self, RunLock, read_json, write_atomic, write_json};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A search job of a plan: `{"name", "search", "presets", ...}` and any [`SearchOverrides`] field.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SearchJob {
    /// Job name (also its directory name).
    pub name: String,
    /// Environment name or spec file.
    pub search: String,
    /// Presets to overlay, in order.
    pub presets: Vec<String>,
    /// A finished, validated search of the same spec at full size (e.g. `results/searches/bicycle`)
    /// whose validated winner this job's is checked against in the summary.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<String>,
    /// A search run whose stored units this job takes before it starts (`search --units-from`):
    /// checked with the plan, taken once.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub units_from: Option<String>,
    /// Overrides of the spec, as `search`'s flags.
    #[serde(flatten)]
    pub overrides: SearchOverrides,
}

/// A comparison job of a plan: `{"name", "compare", ...}` and any [`compare::Request`] field
/// (`tuned` may also be `from:<search job>`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompareJob {
    /// Job name (also its directory name).
    pub name: String,
    /// Environment name or spec file.
    pub compare: String,
    /// A finished comparison of the same thing under another tuned config (e.g. the one the full
    /// search's winner drove, `results/searches/cartpole-compare-mlp-complexity`), whose work this
    /// job's is set against in the summary.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference: Option<String>,
    /// What to compare, as `compare`'s flags.
    #[serde(flatten)]
    pub request: compare::Request,
}

impl<'de> Deserialize<'de> for SearchJob {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        struct Own {
            name: String,
            search: String,
            #[serde(default)]
            presets: Vec<String>,
            #[serde(default)]
            reference: Option<String>,
            #[serde(default)]
            units_from: Option<String>,
        }
        let (own, overrides): (Own, _) = split(d, &["name", "search", "presets", "reference", "units_from"])?;
        Ok(SearchJob {
            name: own.name,
            search: own.search,
            presets: own.presets,
            reference: own.reference,
            units_from: own.units_from,
            overrides,
        })
    }
}

impl<'de> Deserialize<'de> for CompareJob {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        struct Own {
            name: String,
            compare: String,
            #[serde(default)]
            reference: Option<String>,
        }
        let (own, request): (Own, _) = split(d, &["name", "compare", "reference"])?;
        Ok(CompareJob { name: own.name, compare: own.compare, reference: own.reference, request })
    }
}

/// Deserialises a job's own fields (`own`) and the rest (its overrides) from one object, each
/// keeping the path of a bad field: serde's `flatten` would lose it, and could not refuse an
/// unknown field.
fn split<'de, D, O, R>(d: D, own: &[&str]) -> std::result::Result<(O, R), D::Error>
where
    D: serde::Deserializer<'de>,
    O: serde::de::DeserializeOwned,
    R: serde::de::DeserializeOwned,
{
    let mut rest = serde_json::Map::<String, serde_json::Value>::deserialize(d)?;
    let mine = own.iter().filter_map(|k| rest.remove_entry(*k)).collect();
    Ok((crate::error::tagged(mine)?, crate::error::tagged(rest)?))
}

/// Checks that every job of a plan would start: its spec, presets, tuned config and overrides
/// resolve and validate (a `from:` job is checked with the thesis optimum in place of the search's
/// winner, which does not exist yet). Errors name the plan and the job.
pub fn check(plan: &Plan, plan_path: &Path) -> Result<()> {
    for (i, job) in plan.jobs.iter().enumerate() {
        let checked = match job {
            Job::Search(s) => search::resolve(&s.search, &s.presets, &s.overrides).and_then(|spec| {
                if let Some(from) = &s.units_from {
                    search::check_units_from(&spec.0, Path::new(from))?;
                }
                match &s.reference {
                    Some(r) => crate::report::batch::check_reference(&spec.0, Path::new(r)),
                    None => Ok(()),
                }
            }),
            Job::Compare(c) => {
                let mut r = c.request.clone();
                let from = r.tuned.starts_with("from:");
                if from {
                    r.tuned = "thesis".into();
                }
                let cfg = match crate::spec::Spec::resolve(&c.compare) {
                    Ok((spec, _)) if from && spec.env.env().gymnasium().is_some() => stand_in(&spec, &r),
                    _ => compare::resolve(&c.compare, &r).map(|(cfg, _)| cfg),
                };
                cfg.and_then(|cfg| match &c.reference {
                    Some(p) => crate::report::batch::check_compare_reference(&cfg, Path::new(p)),
                    None => Ok(()),
                })
            }
        };
        checked.map_err(|e| Error::File {
            path: plan_path.to_path_buf(),
            message: format!("job {} ({}): {e}", i + 1, job.name()),
        })?;
    }
    Ok(())
}

/// Checks a `from:` comparison of a gymnasium env, which has no thesis optimum, with the
/// cart-pole one's settings in place of the winner its search will find.
fn stand_in(spec: &crate::spec::Spec, r: &compare::Request) -> Result<compare::CompareConfig> {
    let (mut t, _) = crate::tuned::TunedConfig::resolve("thesis", "cartpole")?;
    t.env = spec.env.env().name().to_string();
    t.spec = None;
    compare::CompareConfig::new(spec, t, r.analysis.analyses(), &r.learner.learners(), r)
}

/// A job.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Job {
    /// A search.
    Search(SearchJob),
    /// A comparison.
    Compare(CompareJob),
}

impl Job {
    /// The job's name.
    pub fn name(&self) -> &str {
        match self {
            Job::Search(j) => &j.name,
            Job::Compare(j) => &j.name,
        }
    }
}

/// A batch plan, read only through [`Plan::parse`] (which checks what serde cannot).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plan {
    /// Jobs, run in order.
    pub jobs: Vec<Job>,
}

impl Plan {
    /// Parses a plan; errors name the file, the job and the field.
    pub fn parse(text: &str, origin: &Path) -> Result<Plan> {
        let err = |message: String| Error::File { path: origin.to_path_buf(), message };
        let v = store::parse_json(text, origin)?;
        let obj = v.as_object().ok_or_else(|| err("a plan is an object {\"jobs\": [...]}".into()))?;
        if let Some(k) = obj.keys().find(|k| *k != "jobs" && !k.starts_with('_')) {
            return Err(err(format!("unknown field `{k}`: a plan has only `jobs`")));
        }
        let jobs = obj
            .get("jobs")
            .and_then(|j| j.as_array())
            .ok_or_else(|| err("field jobs: must be a list of jobs".into()))?;
        let mut out: Vec<Job> = Vec::new();
        for (i, j) in jobs.iter().enumerate() {
            // `_comment` keys are notes, inside a job as at the top level.
            let j = &crate::spec::strip_comments(j.clone());
            let name = j.get("name").and_then(|n| n.as_str()).map(String::from);
            let label = format!("job {} ({})", i + 1, name.as_deref().unwrap_or("unnamed"));
            let job = if j.get("search").is_some() {
                Job::Search(deser(j, &label, origin)?)
            } else if j.get("compare").is_some() {
                Job::Compare(deser(j, &label, origin)?)
            } else {
                return Err(err(format!("{label}: needs a `search` or a `compare` field")));
            };
            let n = job.name();
            if n.is_empty() || n.contains('/') || n.starts_with('.') {
                return Err(err(format!("{label}: field name: must be a non-empty name without '/'")));
            }
            if out.iter().any(|o| o.name() == n) {
                return Err(err(format!("{label}: field name: `{n}` is used by an earlier job")));
            }
            let source = match &job {
                Job::Compare(c) => c.request.tuned.strip_prefix("from:"),
                Job::Search(_) => None,
            };
            if let Some(src) = source.filter(|src| !out.iter().any(|o| matches!(o, Job::Search(s) if s.name == *src))) {
                return Err(err(format!("{label}: field tuned: `from:{src}` must name an earlier search job")));
            }
            out.push(job);
        }
        if out.is_empty() {
            return Err(err("field jobs: the plan has no jobs".into()));
        }
        Ok(Plan { jobs: out })
    }
}

fn deser<T: serde::de::DeserializeOwned + serde::Serialize>(
    v: &serde_json::Value,
    label: &str,
    origin: &Path,
) -> Result<T> {
    crate::error::from_json(v.clone(), origin, &format!("{label}: "))
}

/// What a job is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobKind {
    /// A search.
    Search,
    /// A comparison.
    Compare,
}

impl JobKind {
    /// Its name, as `batch.json` spells it.
    pub fn name(self) -> &'static str {
        match self {
            JobKind::Search => "search",
            JobKind::Compare => "compare",
        }
    }
}

/// Where a job stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobPhase {
    /// Not started.
    Pending,
    /// Ran to its end.
    Finished,
    /// Failed (its message says why); the other jobs went on.
    Failed,
    /// Stopped by the budget or Ctrl-C; it resumes.
    Interrupted,
}

impl JobPhase {
    /// Its name, as `batch.json` spells it.
    pub fn name(self) -> &'static str {
        match self {
            JobPhase::Pending => "pending",
            JobPhase::Finished => "finished",
            JobPhase::Failed => "failed",
            JobPhase::Interrupted => "interrupted",
        }
    }
}

/// Where each job stands (`batch.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobState {
    /// Job name.
    pub name: String,
    /// Search or comparison.
    pub kind: JobKind,
    /// Pending, finished, failed or interrupted.
    pub state: JobPhase,
    /// Its run directory (relative to the batch directory).
    pub dir: String,
    /// Why it failed or stopped.
    pub message: String,
    /// Seconds spent (over all invocations).
    pub seconds: f64,
    /// One-line result: best fitness and settings, or claims.
    pub result: String,
}

/// Creates a batch directory for `plan` (read from `plan_path`).
pub fn create(plan_path: &Path, results: &Path, out: Option<&Path>) -> Result<PathBuf> {
    let text = store::read_input(plan_path)?;
    let plan = Plan::parse(&text, plan_path)?;
    check(&plan, plan_path)?;
    let stem = plan_path.file_stem().map_or("batch".into(), |s| s.to_string_lossy().into_owned());
    let states: Vec<JobState> = plan
        .jobs
        .iter()
        .map(|j| JobState {
            name: j.name().to_string(),
            kind: if matches!(j, Job::Search(_)) { JobKind::Search } else { JobKind::Compare },
            state: JobPhase::Pending,
            dir: j.name().to_string(),
            message: String::new(),
            seconds: 0.0,
            result: String::new(),
        })
        .collect();
    // batch.json first, plan.json (what marks a batch) last.
    let dir = store::create_run_dir(out, "plan.json", "a batch", &results.join("batches"), &format!("{stem}-"), |d| {
        write_json(&d.join("batch.json"), &states)?;
        write_json(&d.join("plan.json"), &plan)
    })?;
    Ok(dir)
}

fn describe_search(dir: &Path) -> String {
    match read_json::<crate::tuned::TunedConfig>(&dir.join("best.json")) {
        Ok(t) => format!(
            "best fitness {} — {} δ_min {} patience {}",
            t.fitness.map_or("−∞".into(), |f| format!("{f:.4}")),
            serde_json::to_value(t.activation).unwrap_or_default().as_str().unwrap_or("?"),
            t.delta_min,
            t.patience
        ),
        Err(_) => "no best.json".into(),
    }
}

/// A job's state after it ran: its ending, and its one-line result.
fn job_state(ending: &Ending) -> (JobPhase, String) {
    match ending {
        Ending::Finished(why) => (JobPhase::Finished, why.clone()),
        Ending::Stopped(stop) => (JobPhase::Interrupted, stop.to_string()),
        Ending::Failed(why) => (JobPhase::Failed, why.clone()),
    }
}

/// Runs (or resumes) the batch in `dir`, one job after another, until `budget` says stop (each job
/// stops between its units). Ends `Failed` when some job failed.
pub fn run(dir: &Path, make_exec: &ExecutorFactory<'_>, budget: &Budget<'_>, quiet: bool) -> Result<Ending> {
    let plan_path = dir.join("plan.json");
    let plan = Plan::parse(&store::read_input(&plan_path)?, &plan_path)?;
    let mut states: Vec<JobState> = read_json(&dir.join("batch.json"))?;
    let _lock = RunLock::acquire(dir)?;
    let n = plan.jobs.len();
    let mut stopped = None;
    for (i, job) in plan.jobs.iter().enumerate() {
        if states[i].state == JobPhase::Finished {
            continue;
        }
        if let Some(stop) = budget.check() {
            stopped = Some(stop);
            break;
        }
        if !quiet {
            eprintln!("{} job {} of {n}: {} ({})", store::now_utc().1, i + 1, job.name(), states[i].kind.name());
        }
        let t = Instant::now();
        let outcome = with_heartbeat(&dir.join("batch.json"), &states, i, t, || {
            run_job(dir, &plan, &states, i, make_exec, budget, quiet)
        });
        states[i].seconds += t.elapsed().as_secs_f64();
        match outcome {
            Ok((ending, result)) => {
                let (phase, message) = job_state(&ending);
                states[i].state = phase;
                states[i].message = message;
                states[i].result = result;
                if let Ending::Stopped(stop) = ending {
                    stopped = Some(stop);
                }
            }
            Err(e) => {
                states[i].state = JobPhase::Failed;
                states[i].message = e.to_string();
                if !quiet {
                    eprintln!("{} job {} failed: {e}", store::now_utc().1, job.name());
                }
            }
        }
        write_json(&dir.join("batch.json"), &states)?;
        write_summary(dir, &plan, &states)?;
        if stopped.is_some() {
            break;
        }
    }
    write_summary(dir, &plan, &states)?;
    let failed = states.iter().filter(|s| s.state == JobPhase::Failed).count();
    Ok(match stopped {
        Some(stop) => Ending::Stopped(stop),
        None if failed > 0 => Ending::Failed(format!("{failed} job(s) failed (see the summary)")),
        None => Ending::Finished(format!("all {n} jobs")),
    })
}

/// Runs `work` while a thread rewrites batch.json every 10 s with job `i`'s time so far (its
/// recorded seconds plus this invocation's since `started`): an invocation killed outright
/// (SIGKILL, a session's end) loses at most 10 s of its wall time, not all of it.
fn with_heartbeat<T>(path: &Path, states: &[JobState], i: usize, started: Instant, work: impl FnOnce() -> T) -> T {
    let (done, wait) = std::sync::mpsc::channel::<()>();
    let mut beat = states.to_vec();
    let base = beat[i].seconds;
    std::thread::scope(|scope| {
        scope.spawn(move || {
            while let Err(std::sync::mpsc::RecvTimeoutError::Timeout) =
                wait.recv_timeout(std::time::Duration::from_secs(10))
            {
                beat[i].seconds = base + started.elapsed().as_secs_f64();
                // Best effort: the job's end writes batch.json again, and reports a failure then.
                write_json(path, &beat).ok();
            }
        });
        let out = work();
        drop(done);
        out
    })
}

/// Runs (or resumes) job `i` of `plan`: its ending and its one-line result.
fn run_job(
    dir: &Path,
    plan: &Plan,
    states: &[JobState],
    i: usize,
    make_exec: &ExecutorFactory<'_>,
    budget: &Budget<'_>,
    quiet: bool,
) -> Result<(Ending, String)> {
    let job = &plan.jobs[i];
    let job_dir = dir.join(job.name());
    match job {
        Job::Search(s) => {
            if !job_dir.join("spec.json").is_file() {
                search::prepare(&s.search, &s.presets, &s.overrides, Some(&job_dir), Path::new("results"))?;
            }
            if let Some(from) = &s.units_from {
                // Taken once: run.json records the copy when it is done (a copy cut short
                // is taken again, skipping the units already there).
                let info: crate::ga::records::RunInfo = read_json(&job_dir.join("run.json"))?;
                if !info.units_from.iter().any(|u| u.dir == *from) {
                    let n = search::share_units(&job_dir, Path::new(from))?;
                    if !quiet {
                        eprintln!("{n} units taken from {from}");
                    }
                }
            }
            let exec = make_exec(&job_dir)?;
            let ending = search::run(&job_dir, exec.as_ref(), budget, quiet)?;
            Ok((ending, describe_search(&job_dir)))
        }
        Job::Compare(cj) => {
            if !job_dir.join("compare.json").is_file() {
                let mut r = cj.request.clone();
                if let Some(src) = r.tuned.strip_prefix("from:") {
                    let k = plan.jobs.iter().position(|j| j.name() == src).expect("validated");
                    if states[k].state != JobPhase::Finished {
                        return Err(Error::File {
                            path: dir.join(src),
                            message: format!(
                                "search job `{src}` has not finished ({}), so it has no tuned config",
                                states[k].state.name()
                            ),
                        });
                    }
                    r.tuned = dir.join(src).join("best.json").display().to_string();
                }
                compare::prepare(&cj.compare, &r, Some(&job_dir), Path::new("results"))?;
            }
            let exec = make_exec(&job_dir)?;
            let ending = compare::run(&job_dir, exec.as_ref(), budget, quiet)?;
            if !matches!(ending, Ending::Finished(_)) {
                return Ok((ending, String::new()));
            }
            let out = crate::report::comparison::regenerate(&job_dir)?;
            let supported =
                out.claims.iter().filter(|c| c.verdict == crate::report::claims::Verdict::Supported).count();
            Ok((ending, format!("{supported} of {} thesis claims supported; report.md", out.claims.len())))
        }
    }
}

/// Rebuilds a batch directory's reports from its records: every job's report (a search's
/// report.md and fitness plot, a comparison's report and figures), then summary.md, whose times
/// are the ones batch.json recorded. Returns how many job reports were written.
pub fn report(dir: &Path) -> Result<usize> {
    let plan_path = dir.join("plan.json");
    let plan = Plan::parse(&store::read_input(&plan_path)?, &plan_path)?;
    let states: Vec<JobState> = read_json(&dir.join("batch.json"))?;
    let mut written = 0;
    for s in &states {
        let job_dir = dir.join(&s.dir);
        if job_dir.join("compare.json").is_file() && s.state == JobPhase::Finished {
            crate::report::comparison::regenerate(&job_dir)?;
            written += 1;
        } else if job_dir.join("generations.jsonl").is_file() {
            crate::report::search::write(&job_dir)?;
            written += 1;
        }
    }
    write_summary(dir, &plan, &states)?;
    Ok(written)
}

fn write_summary(dir: &Path, plan: &Plan, states: &[JobState]) -> Result<()> {
    let mut md = String::from(
        "# Batch summary\n\n| job | kind | state | time | work | result | details |\n|---|---|---|---|---|---|---|\n",
    );
    // Each job's work from its units, as `bfqi-ga work` counts it (none before its run exists).
    let works: Vec<Option<crate::work::Work>> = states
        .iter()
        .map(|s| crate::runs::kind(&dir.join(&s.dir)).ok().and_then(|_| crate::work::cached(&dir.join(&s.dir)).ok()))
        .collect();
    let work_cell =
        |w: &crate::work::Work| format!("{:.2} ref. h ({:.3e} epoch-rows)", w.reference_hours, w.epoch_rows as f64);
    for (s, w) in states.iter().zip(&works) {
        let link = match s.kind {
            JobKind::Compare if s.state == JobPhase::Finished => format!("[report]({}/report.md)", s.dir),
            JobKind::Search if dir.join(&s.dir).join("best.json").is_file() => {
                format!("[best.json]({0}/best.json), [fitness]({0}/fitness.png)", s.dir)
            }
            _ => String::new(),
        };
        let details = if s.message.is_empty() { link } else { format!("{} {link}", s.message.replace('|', "/")) };
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            s.name,
            s.kind.name(),
            s.state.name(),
            crate::progress::human(s.seconds),
            w.as_ref().map_or(String::new(), work_cell),
            s.result.replace('|', "/"),
            details
        ));
    }
    let total: f64 = states.iter().map(|s| s.seconds).sum();
    let reference = crate::work::Reference::committed().map(|r| r.name).unwrap_or_default();
    let (ref_h, rows) =
        works.iter().flatten().fold((0.0, 0.0), |(h, r), w| (h + w.reference_hours, r + w.epoch_rows as f64));
    md.push_str(&format!(
        "| **total** | | | **{}** ({:.2} h) | **{ref_h:.2} ref. h** ({rows:.3e} epoch-rows) | | |\n\n`time`: each job's wall time over all invocations, as batch.json recorded it. \
         `work`: counted from each job's units, whatever machine ran them (`bfqi-ga work`): network epochs × the rows \
         each fit trained on, and the hours their FLOPs take on the reference machine ({reference}).\n",
        crate::progress::human(total),
        total / 3600.0
    ));
    // A wall time means little without the machine: the same batch runs several times longer on
    // an AVX2-only CPU than on an AVX-512 one.
    let machines = crate::machine::distinct(states.iter().flat_map(|s| crate::machine::of_run(&dir.join(&s.dir))));
    match machines.as_slice() {
        [] => {}
        [one] => md.push_str(&format!("Every invocation ran on {one}.\n")),
        many => md.push_str(&format!(
            "Invocations ran on {} set-ups (CPU, kernel level, threads), so the times add up different speeds: {}.\n",
            many.len(),
            many.join("; ")
        )),
    }
    let names: Vec<(String, String)> = states.iter().map(|s| (s.name.clone(), s.dir.clone())).collect();
    md.push_str(&crate::report::batch::taken_units_section(dir, &names));
    let checks: Vec<(String, String, String)> = plan
        .jobs
        .iter()
        .zip(states)
        .filter_map(|(j, s)| match j {
            Job::Search(SearchJob { reference: Some(r), .. }) => Some((s.name.clone(), s.dir.clone(), r.clone())),
            _ => None,
        })
        .collect();
    if !checks.is_empty() {
        md.push_str(&crate::report::batch::reference_section(dir, &checks));
    }
    let references: Vec<crate::report::batch::Referenced> =
        plan.jobs
            .iter()
            .zip(states)
            .filter_map(|(j, s)| match j {
                Job::Search(SearchJob { reference: Some(r), .. })
                | Job::Compare(CompareJob { reference: Some(r), .. }) => Some(crate::report::batch::Referenced {
                    job: s.name.clone(),
                    dir: s.dir.clone(),
                    reference: r.clone(),
                    finished: s.state == JobPhase::Finished,
                }),
                _ => None,
            })
            .collect();
    if !references.is_empty() {
        md.push_str(&crate::report::batch::work_section(dir, &references, plan.jobs.len()));
    }
    write_atomic(&dir.join("summary.md"), |w| std::io::Write::write_all(w, md.as_bytes()))?;
    crate::work::write(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> std::result::Result<Plan, String> {
        Plan::parse(text, Path::new("plan.json")).map_err(|e| e.to_string())
    }

    #[test]
    fn plans_parse_and_errors_name_job_and_field() {
        let p = parse(r#"{"jobs": [{"name": "s", "search": "bicycle", "seed": 3}, {"name": "c", "compare": "bicycle", "tuned": "from:s"}]}"#).unwrap();
        assert_eq!(p.jobs.len(), 2);
        let e = parse(r#"{"jobs": [{"name": "s", "search": "bicycle", "sed": 3}]}"#).unwrap_err();
        assert!(e.contains("plan.json") && e.contains("job 1 (s)") && e.contains("sed"), "{e}");
        let e = parse(r#"{"jobs": [{"name": "c", "compare": "bicycle", "datasets": "ten"}]}"#).unwrap_err();
        assert!(e.contains("job 1 (c)") && e.contains("datasets"), "{e}");
        let e = parse(r#"{"jobs": [{"name": "c", "compare": "bicycle", "tuned": "from:nowhere"}]}"#).unwrap_err();
        assert!(e.contains("field tuned"), "{e}");
        let e = parse(r#"{"jobs": [{"name": "x"}]}"#).unwrap_err();
        assert!(e.contains("job 1 (x)") && e.contains("search"), "{e}");
        let e = parse(r#"{"jobs": [{"name": "a", "search": "cartpole"}, {"name": "a", "search": "cartpole"}]}"#)
            .unwrap_err();
        assert!(e.contains("job 2 (a)") && e.contains("earlier job"), "{e}");
    }

    #[test]
    fn comments_inside_jobs_are_notes_and_duplicate_keys_are_refused() {
        let p =
            parse(r#"{"_comment": "a", "jobs": [{"_comment": "why", "name": "s", "search": "cartpole"}]}"#).unwrap();
        assert_eq!(p.jobs[0].name(), "s");
        let e = parse(r#"{"jobs": [{"name": "s", "search": "cartpole", "seed": 1, "seed": 2}]}"#).unwrap_err();
        assert!(e.contains("plan.json") && e.contains("duplicate key `seed`"), "{e}");
    }
}
