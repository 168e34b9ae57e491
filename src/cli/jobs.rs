//! The long jobs and their run directories: `search`, `compare`, `batch`, `validate`, `status`,
//! `report`, `export`.

use super::{Outcome, outcome};
use crate::compare;
use crate::exec::{self, interrupt_flag};
use crate::ga::search::{self, SearchOverrides};
use crate::run_dir::{Budget, Ending};
use crate::runs::RunKind;
use crate::spec::Select;
use anyhow::{Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// `bfqi-ga search`.
#[derive(Debug, Args)]
pub struct SearchArgs {
    #[command(flatten)]
    pub exec: exec::Options,
    /// Environment name (uses searches/<ENV>.json) or a spec file. Not needed with --resume.
    #[arg(required_unless_present = "resume")]
    pub env: Option<String>,
    /// Resume the search in this run directory (after Ctrl-C, a crash, kill -9 or a time budget).
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = [
        "env", "preset", "quick", "prune", "population", "datasets", "iterations", "episodes", "seed", "out",
        "seed_config",
    ])]
    pub resume: Option<PathBuf>,
    /// Overlay a preset (a name under searches/presets/ or a file); repeatable, applied in order.
    #[arg(long)]
    pub preset: Vec<String>,
    /// A small, real search (the `quick` preset) for trying the tool: a few seconds on 2 cores.
    #[arg(long)]
    pub quick: bool,
    /// Turn on the spec's opt-in pruning (the `prune` preset; beyond the thesis, see README).
    #[arg(long)]
    pub prune: bool,
    /// Overrides of the spec (with --resume, only --generations and --stall-generations).
    #[command(flatten)]
    pub overrides: SearchOverrides,
    /// Wall-clock budget of this invocation, in hours (stops cleanly; resume later).
    #[arg(long)]
    pub max_hours: Option<f64>,
    /// Run directory (default: results/<env>/search-<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Check the spec, presets and flags and print the resolved spec as JSON, creating nothing.
    #[arg(long, conflicts_with = "resume")]
    pub dry_run: bool,
    /// Before the first generation, take every unit of this search run that verifies and was
    /// computed under the same results hash (e.g. a random baseline sharing its GA search's cache).
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = ["resume", "dry_run"])]
    pub units_from: Option<PathBuf>,
    /// No progress output (the run directory still records everything).
    #[arg(long)]
    pub quiet: bool,
}

/// `bfqi-ga compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    #[command(flatten)]
    pub exec: exec::Options,
    /// Environment name (uses searches/<ENV>.json) or a spec file. Not needed with --resume.
    #[arg(required_unless_present = "resume")]
    pub env: Option<String>,
    /// What to compare (not with --resume: the run directory's compare.json has it).
    #[command(flatten)]
    pub request: compare::Request,
    /// Run directory (default: results/<env>/compare-<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Resume the comparison in this run directory (as its compare.json says: no request flags).
    #[arg(
        long,
        value_name = "RUN_DIR",
        conflicts_with_all = [
            "env", "out", "tuned", "analysis", "learner", "datasets", "episodes", "iterations", "complexities", "sizes"
        ]
    )]
    pub resume: Option<PathBuf>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

/// `bfqi-ga batch`.
#[derive(Debug, Args)]
pub struct BatchArgs {
    #[command(flatten)]
    pub exec: exec::Options,
    /// The plan (e.g. searches/batches/overnight.json). Not needed with --resume.
    #[arg(required_unless_present = "resume")]
    pub plan: Option<PathBuf>,
    /// Resume the batch in this directory.
    #[arg(long, value_name = "BATCH_DIR", conflicts_with_all = ["plan", "out"])]
    pub resume: Option<PathBuf>,
    /// Wall-clock budget of this invocation, in hours; stops cleanly between units.
    #[arg(long, conflicts_with = "until")]
    pub max_hours: Option<f64>,
    /// Stop cleanly at this local time, HH:MM (the next time it comes round).
    #[arg(long)]
    pub until: Option<String>,
    /// Batch directory (default: results/batches/<plan>-<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Check the plan (every job's spec, presets, tuned config and overrides) and list its jobs,
    /// creating nothing.
    #[arg(long, conflicts_with = "resume")]
    pub dry_run: bool,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

/// `bfqi-ga validate`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// A search's run directory (at least one generation done).
    pub dir: PathBuf,
    /// Settings of the hall of fame to re-score (default: the spec's `search.validate.top`).
    #[arg(long)]
    pub top: Option<usize>,
    /// Validation datasets (default: the spec's `search.validate.datasets`); with a race, the most
    /// any setting gets.
    #[arg(long)]
    pub datasets: Option<usize>,
    /// Race the settings: validation datasets of the first round (default: the spec's
    /// `search.validate.race.first`).
    #[arg(long)]
    pub race_first: Option<usize>,
    /// Race the settings: datasets added to each survivor per round (default: the spec's
    /// `search.validate.race.step`).
    #[arg(long)]
    pub race_step: Option<usize>,
    /// No race: every setting on every validation dataset, even where the spec races.
    #[arg(long, conflicts_with_all = ["race_first", "race_step"])]
    pub no_race: bool,
    /// Write this validation into DIR (validation.json, best.json, report.md and the units the
    /// search lacks) and only read the search: its own validation and best.json stay as they are.
    #[arg(long, value_name = "DIR")]
    pub into: Option<PathBuf>,
    /// Which setting DIR's best.json holds: `fitness` (the best fitness) or `validated` (the
    /// validation's winner); default: the search's `search.select`.
    #[arg(long, requires = "into", value_parser = ["fitness", "validated"])]
    pub select: Option<String>,
    /// Suppress progress output.
    #[arg(long)]
    pub quiet: bool,
    #[command(flatten)]
    pub exec: exec::Options,
}

/// `bfqi-ga status`.
#[derive(Debug, Args)]
pub struct StatusArgs {
    /// Folder to scan (default: results).
    #[arg(default_value = "results")]
    pub dir: PathBuf,
}

/// `bfqi-ga work`.
#[derive(Debug, Args)]
pub struct WorkArgs {
    /// A search, comparison or batch directory.
    pub dir: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Count units that predate recorded rows by collecting their datasets again (which may start
    /// the run's gymnasium worker or Minari's Python, or read its data file), and record the count
    /// in the run's work.json, which reading the run then uses.
    #[arg(long)]
    pub write: bool,
}

/// `bfqi-ga stamp`.
#[derive(Debug, Args)]
pub struct StampArgs {
    /// A search or comparison run directory.
    pub dir: PathBuf,
}

/// `bfqi-ga tidy`.
#[derive(Debug, Args)]
pub struct TidyArgs {
    /// A search run directory: finished, or (if it took units with --units-from) stopped, to keep
    /// or commit it between sessions; its resume takes the removed copies again.
    pub dir: PathBuf,
    /// Only count what would be removed.
    #[arg(long)]
    pub dry_run: bool,
}

/// `bfqi-ga export`.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// A search, comparison or batch run directory.
    pub dir: PathBuf,
    /// Table format (default: the one --out's extension names, else parquet).
    #[arg(long, value_enum)]
    pub format: Option<crate::table::Format>,
    /// Output file (default: <RUN_DIR>/units.parquet, or units.csv); `-` writes CSV to standard output.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `bfqi-ga report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// A comparison, search or batch run directory.
    pub dir: PathBuf,
}

pub(super) fn search(a: SearchArgs) -> Result<Outcome> {
    // Flags are checked before a run directory exists, so a refused command leaves nothing.
    let budget = a.max_hours.map(crate::clock::check_hours).transpose()?;
    let o = &a.overrides;
    let dir = if let Some(dir) = &a.resume {
        search::extend(dir, o.generations, o.stall_generations)?;
        dir.clone()
    } else {
        let mut presets: Vec<String> = if a.quick { vec!["quick".into()] } else { vec![] };
        if a.prune {
            presets.push("prune".into());
        }
        presets.extend(a.preset.iter().cloned());
        let name = a.env.as_deref().context("give an environment or spec file, or --resume DIR")?;
        if a.dry_run {
            let (spec, _) = search::resolve(name, &presets, o)?;
            println!("{}", serde_json::to_string_pretty(&spec)?);
            return Ok(Outcome::Success);
        }
        if let Some(from) = &a.units_from {
            // Refused before a run directory exists.
            search::check_units_from(&search::resolve(name, &presets, o)?.0, from)?;
        }
        let dir = search::prepare(name, &presets, o, a.out.as_deref(), Path::new("results"))?;
        if let Some(from) = &a.units_from {
            let n = search::share_units(&dir, from)?;
            if !a.quiet {
                eprintln!("{n} units taken from {}", from.display());
            }
        }
        dir
    };
    let max_hours = match budget {
        Some(h) => Some(h),
        None => search::load_spec(&dir)?.search.stop.max_hours,
    };
    let budget = Budget::new(interrupt_flag(), max_hours);
    let exec = a.exec.executor(&dir)?;
    let ending = search::run(&dir, exec.as_ref(), &budget, a.quiet)?;
    if let Ending::Finished(reason) = &ending {
        eprintln!("finished ({reason}): {}", dir.display());
        eprintln!("tuned config: {}", dir.join("best.json").display());
    }
    Ok(outcome(&ending, &format!("bfqi-ga search --resume {}", dir.display())))
}

pub(super) fn compare(a: CompareArgs) -> Result<Outcome> {
    let dir = if let Some(d) = &a.resume {
        compare::load(d)?;
        d.clone()
    } else {
        let name = a.env.as_deref().expect("clap requires ENV without --resume");
        compare::prepare(name, &a.request, a.out.as_deref(), Path::new("results"))?
    };
    let exec = a.exec.executor(&dir)?;
    let ending = compare::run(&dir, exec.as_ref(), &Budget::new(interrupt_flag(), None), a.quiet)?;
    if !matches!(ending, Ending::Finished(_)) {
        return Ok(outcome(&ending, &format!("bfqi-ga compare --resume {}", dir.display())));
    }
    let out = crate::report::comparison::regenerate(&dir)?;
    if compare::load(&dir)?.learners.iter().all(|p| p.claims.is_empty()) {
        eprintln!("no thesis claims: this spec states none, so the report compares B-FQI with FQI without verdicts");
    }
    for c in &out.claims {
        let mark = if c.verdict == crate::report::claims::Verdict::Supported { "supported" } else { "NOT supported" };
        eprintln!("claim {mark}: {} ({})", c.statement, c.evidence);
    }
    eprintln!("report: {}", dir.join("report.md").display());
    Ok(Outcome::Success)
}

pub(super) fn batch(a: BatchArgs) -> Result<Outcome> {
    use crate::batch::{self, Job, Plan};
    // The budget is checked before the batch directory exists.
    let max_hours = crate::clock::budget(a.max_hours, a.until.as_deref())?;
    if let (true, Some(plan)) = (a.dry_run, &a.plan) {
        let p = Plan::parse(&crate::store::read_input(plan)?, plan)?;
        batch::check(&p, plan)?;
        for (i, j) in p.jobs.iter().enumerate() {
            let kind = if matches!(j, Job::Search(_)) { "search" } else { "compare" };
            println!("job {}: {} ({kind}) ok", i + 1, j.name());
        }
        return Ok(Outcome::Success);
    }
    let dir = match (&a.resume, &a.plan) {
        (Some(d), _) => d.clone(),
        (None, Some(plan)) => batch::create(plan, Path::new("results"), a.out.as_deref())?,
        (None, None) => anyhow::bail!("give a plan file, or --resume DIR"),
    };
    if !a.quiet {
        eprintln!("batch → {}", dir.display());
    }
    let budget = Budget::new(interrupt_flag(), max_hours);
    let ending = batch::run(&dir, &|d: &Path| a.exec.executor(d), &budget, a.quiet)?;
    eprintln!("summary: {}", dir.join("summary.md").display());
    Ok(outcome(&ending, &format!("bfqi-ga batch --resume {}", dir.display())))
}

pub(super) fn validate(a: ValidateArgs) -> Result<Outcome> {
    use crate::ga::validate;
    let flags = validate::RuleFlags {
        top: a.top,
        datasets: a.datasets,
        race_first: a.race_first,
        race_step: a.race_step,
        no_race: a.no_race,
    };
    let rule = validate::rule_for_search(&a.dir, &flags)?;
    if a.into.is_some() && a.exec.executor != crate::exec::Kind::Local {
        // A Slurm task finds a unit's spec in its run directory, which DIR has not.
        return Err(
            crate::error::Error::Usage("--into: runs on the local executor only (drop --executor)".into()).into()
        );
    }
    let exec = a.exec.executor(&a.dir)?;
    let budget = Budget::new(interrupt_flag(), None);
    let select = a.select.as_deref().map(|s| if s == "validated" { Select::Validated } else { Select::Fitness });
    let target = validate::Target { source: &a.dir, out: a.into.as_deref().unwrap_or(&a.dir), select };
    let v = match crate::runs::validate(&target, &rule, exec.as_ref(), &budget, a.quiet)? {
        validate::Outcome::Validated(v) => v,
        validate::Outcome::Stopped(stop) => {
            return Ok(outcome(&Ending::Stopped(stop), &format!("bfqi-ga validate {}", a.dir.display())));
        }
    };
    let ci = |s: &Option<crate::stats::Summary>| crate::stats::interval(*s, 4);
    println!("{:<22} {:<24} {:>20} {:>20}", "", "setting", "search datasets", "validation");
    for e in &v.entries {
        let tag = if e.setting == v.tuned { format!("{} (tuned)", e.source) } else { e.source.clone() };
        println!("{:<22} {:<24} {:>20} {:>20}", tag, e.setting, ci(&e.search), ci(&e.validation));
    }
    for r in &v.rounds {
        let dropped: Vec<&str> = r
            .standings
            .iter()
            .filter(|s| s.verdict == crate::ga::race::Verdict::Dropped)
            .map(|s| s.setting.as_str())
            .collect();
        println!(
            "race round {} ({} datasets): leader {}, dropped {}",
            r.round,
            r.datasets,
            r.leader,
            if dropped.is_empty() { "none".into() } else { dropped.join(", ") }
        );
    }
    println!("{}", v.note);
    Ok(Outcome::Success)
}

pub(super) fn status(a: StatusArgs) -> Result<Outcome> {
    let dirs = crate::runs::find(&a.dir);
    if dirs.is_empty() {
        println!("no runs under {}", a.dir.display());
    }
    for d in dirs {
        match crate::runs::status_line(&d) {
            Ok(line) => println!("{line}"),
            // One damaged run must not hide the others.
            Err(e) => eprintln!("warning: skipped {e}"),
        }
    }
    Ok(Outcome::Success)
}

pub(super) fn work(a: WorkArgs) -> Result<Outcome> {
    let w = if a.write {
        crate::work::record(&a.dir, crate::work::Counting::Collect)?
    } else {
        crate::work::cached(&a.dir)?
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&w)?);
    } else {
        println!("{} {} — counted from its units, priced on the reference machine", w.kind, a.dir.display());
        for l in w.lines() {
            println!("  {l}");
        }
    }
    Ok(Outcome::Success)
}

pub(super) fn stamp(a: StampArgs) -> Result<Outcome> {
    let s = crate::runs::stamp(&a.dir)?;
    println!(
        "{}: {} unit(s) stamped, {} had a checksum; run.json says checksummed",
        a.dir.display(),
        s.stamped,
        s.already
    );
    if let Some((path, problem)) = s.unverified.first() {
        // Not vouched for: left to be computed again on resume, as before.
        println!(
            "{} unit(s) do not verify and were left unstamped (first {}: {problem}); resuming computes them again",
            s.unverified.len(),
            path.display()
        );
    }
    Ok(Outcome::Success)
}

pub(super) fn tidy(a: TidyArgs) -> Result<Outcome> {
    let t = crate::ga::tidy::tidy(&a.dir, a.dry_run)?;
    println!(
        "{}: {} unit file(s) of settings it never drew nor validated {} ({:.1} MB), {} kept",
        a.dir.display(),
        t.removed,
        if a.dry_run { "would be removed" } else { "removed" },
        t.bytes as f64 / 1e6,
        t.kept
    );
    if t.partial && t.removed > 0 {
        println!("it has not reached its end: they were taken copies, and its resume takes them again");
    }
    Ok(Outcome::Success)
}

pub(super) fn report(a: ReportArgs) -> Result<Outcome> {
    if a.dir.join("batch.json").is_file() {
        let n = crate::batch::report(&a.dir)?;
        eprintln!("wrote {n} job reports and summary.md into {}", a.dir.display());
        return Ok(Outcome::Success);
    }
    if !a.dir.join("spec.json").is_file() && crate::runs::report_validation_apart(&a.dir)? {
        eprintln!("wrote report.md of the validation kept apart into {}", a.dir.display());
        return Ok(Outcome::Success);
    }
    match crate::runs::kind(&a.dir)? {
        RunKind::Compare => {
            let out = crate::report::comparison::regenerate(&a.dir)?;
            eprintln!("wrote {} files into {}", out.files.len(), a.dir.display());
        }
        RunKind::Search => {
            let n = crate::report::search::write(&a.dir)?;
            eprintln!(
                "wrote fitness.csv, fitness.png, fitness.svg and report.md for {n} generations into {}",
                a.dir.display()
            );
        }
    }
    Ok(Outcome::Success)
}

pub(super) fn export(a: ExportArgs) -> Result<Outcome> {
    let to = crate::export::Destination::resolve(&a.dir, a.format, a.out.as_deref())?;
    let rows = crate::export::export(&a.dir, &to)?;
    if let crate::export::Destination::File(path, _) = &to {
        eprintln!("wrote {rows} rows to {}", path.display());
    }
    Ok(Outcome::Success)
}
