//! Command-line definitions (clap derive) and their dispatch to the library. Nothing here computes:
//! flags become validated configs, then the library runs them.

use crate::dataset::{self, dataset_seed};
use crate::env::{EnvConfig, NAMES};
use crate::experiment::{self, RunConfig};
use crate::fqi::Algorithm;
use crate::learn::LearnerConfig;
use crate::learn::actions::ActionEncoding;
use crate::learn::mlp::Activation;
use crate::spec::{LearnerKind, Spec};
use crate::store;
use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

/// Boosted Fitted Q-Iteration, tuned by a genetic algorithm.
#[derive(Debug, Parser)]
#[command(name = "bfqi-ga", version, about, long_about = None)]
pub struct Cli {
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, short = 'j', global = true, visible_alias = "threads", value_name = "N")]
    pub jobs: Option<usize>,
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Genetic search of the MLP's early-stopping settings and activation (the main job).
    Search(Box<SearchArgs>),
    /// B-FQI vs FQI comparison runs with tuned settings.
    Compare(Box<CompareArgs>),
    /// One FQI or B-FQI run over one or more datasets.
    Run(Box<RunArgs>),
    /// Re-derive a tuned config's fitness from scratch and check it matches.
    Reproduce(ReproduceArgs),
    /// Re-score a search's top settings and the thesis optimum on fresh validation datasets.
    Validate(ValidateArgs),
    /// Score a given config (thesis optimum or a best.json) under a search's fitness.
    Fitness(FitnessArgs),
    /// Run a greedy policy and draw it: trajectory CSV, plots, animated GIF.
    Rollout(Box<RolloutArgs>),
    /// Score a saved model on more or other start states (mean and 95 % interval).
    Evaluate(EvaluateArgs),
    /// Run a plan of searches and comparisons (overnight batches).
    Batch(BatchArgs),
    /// One line per run under results/: state, generation, best fitness.
    Status(StatusArgs),
    /// Regenerate tables, plots and report.md from stored results.
    Report(ReportArgs),
    /// Write a random-policy dataset as CSV.
    Dataset(DatasetArgs),
    /// List the environments and their settings.
    Envs(EnvsArgs),
    /// Benchmarks: learners, FQI, search throughput.
    Bench(BenchArgs),
    /// Compute one unit of a run directory (what Slurm array tasks run).
    #[command(hide = true)]
    Worker(WorkerArgs),
}

/// `bfqi-ga dataset`.
#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// Environment: pendulum, cartpole or bicycle.
    pub env: String,
    /// Number of random-policy episodes.
    #[arg(long)]
    pub episodes: usize,
    /// Master seed: the file is dataset INDEX of ROLE under this seed, exactly as runs use it.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Which datasets: those of comparison runs or of the GA's fitness. Their seeds are disjoint.
    #[arg(long, value_enum, default_value_t = dataset::Role::Compare)]
    pub role: dataset::Role,
    /// Index of the dataset within its role.
    #[arg(long, default_value_t = 0)]
    pub index: usize,
    /// Output CSV (written atomically).
    #[arg(long)]
    pub out: PathBuf,
}

/// `bfqi-ga run`: presets come from the spec file's `experiments.<learner>`; flags override them.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Environment name (uses searches/<ENV>.json) or a spec file.
    pub env: String,
    /// Algorithm.
    #[arg(long, value_enum, default_value_t = Algorithm::Bfqi)]
    pub algo: Algorithm,
    /// Learner (selects the preset).
    #[arg(long, value_enum, default_value_t = LearnerKind::Et)]
    pub learner: LearnerKind,
    /// Action encoding.
    #[arg(long, value_enum)]
    pub actions: Option<ActionEncoding>,
    /// Extra-Trees: number of trees.
    #[arg(long, help_heading = "Extra-Trees")]
    pub trees: Option<usize>,
    /// Extra-Trees: maximum depth (edges from the root).
    #[arg(long, help_heading = "Extra-Trees")]
    pub depth: Option<usize>,
    /// Extra-Trees: minimum samples to split a node.
    #[arg(long, help_heading = "Extra-Trees")]
    pub min_split: Option<usize>,
    /// Extra-Trees: minimum samples per leaf.
    #[arg(long, help_heading = "Extra-Trees")]
    pub min_leaf: Option<usize>,
    /// MLP: hidden layer widths, e.g. 10,10.
    #[arg(long, value_delimiter = ',', help_heading = "MLP")]
    pub hidden: Option<Vec<usize>>,
    /// MLP: activation.
    #[arg(long, value_enum, help_heading = "MLP")]
    pub activation: Option<Activation>,
    /// MLP: early-stopping δ_min.
    #[arg(long, allow_negative_numbers = true, help_heading = "MLP")]
    pub delta_min: Option<f64>,
    /// MLP: early-stopping patience.
    #[arg(long, help_heading = "MLP")]
    pub patience: Option<usize>,
    /// MLP: RMSProp learning rate.
    #[arg(long, allow_negative_numbers = true, help_heading = "MLP")]
    pub learning_rate: Option<f64>,
    /// K, the number of iterations.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Episodes per dataset.
    #[arg(long)]
    pub episodes: Option<usize>,
    /// Number of datasets.
    #[arg(long)]
    pub datasets: Option<usize>,
    /// Master seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Evaluate the greedy policy every E iterations (and at the last).
    #[arg(long)]
    pub eval_every: Option<usize>,
    /// Print one JSON document (every record and the summary) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Also write run.json and run.csv into this directory (atomically).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Save each dataset's last Q-function into this directory (`dataset-<i>.model`), for
    /// `rollout` and `evaluate`.
    #[arg(long, value_name = "DIR")]
    pub save_model: Option<PathBuf>,
}

/// Where units of work run.
#[derive(Debug, Clone, Args)]
pub struct ExecArgs {
    /// Where units of work run.
    #[arg(long, value_enum, default_value_t, help_heading = "Executor")]
    pub executor: crate::exec::Kind,
    /// Slurm partition.
    #[arg(long, help_heading = "Executor")]
    pub slurm_partition: Option<String>,
    /// Slurm time limit per task, e.g. 02:00:00.
    #[arg(long, help_heading = "Executor")]
    pub slurm_time: Option<String>,
    /// CPUs per Slurm task.
    #[arg(long, help_heading = "Executor")]
    pub slurm_cpus_per_task: Option<usize>,
    /// Array tasks running at once (`%T`).
    #[arg(long, help_heading = "Executor")]
    pub slurm_max_parallel: Option<usize>,
    /// Further sbatch argument, passed through (repeatable).
    #[arg(long, allow_hyphen_values = true, help_heading = "Executor")]
    pub slurm_arg: Vec<String>,
    /// Resubmissions of missing units before giving up.
    #[arg(long, default_value_t = 2, help_heading = "Executor")]
    pub slurm_retries: usize,
}

impl ExecArgs {
    /// The executor for a run directory.
    pub fn executor(&self, dir: &Path) -> crate::Result<Box<dyn crate::exec::Executor>> {
        if self.executor == crate::exec::Kind::Local {
            return Ok(Box::new(crate::exec::local::Local));
        }
        let mut s = crate::exec::slurm::Slurm::new(dir)?;
        s.partition = self.slurm_partition.clone();
        s.time = self.slurm_time.clone();
        s.cpus_per_task = self.slurm_cpus_per_task;
        s.max_parallel = self.slurm_max_parallel;
        s.extra = self.slurm_arg.clone();
        s.retries = self.slurm_retries;
        Ok(Box::new(s))
    }
}

/// `bfqi-ga search`.
#[derive(Debug, Args)]
pub struct SearchArgs {
    #[command(flatten)]
    pub exec: ExecArgs,
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
    pub overrides: crate::ga::search::SearchOverrides,
    /// Wall-clock budget of this invocation, in hours (stops cleanly; resume later).
    #[arg(long)]
    pub max_hours: Option<f64>,
    /// Run directory (default: results/<env>/search-<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Check the spec, presets and flags and print the resolved spec as JSON, creating nothing.
    #[arg(long, conflicts_with = "resume")]
    pub dry_run: bool,
    /// No progress output (the run directory still records everything).
    #[arg(long)]
    pub quiet: bool,
}

/// `bfqi-ga compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    #[command(flatten)]
    pub exec: ExecArgs,
    /// Environment name (uses searches/<ENV>.json) or a spec file. Not needed with --resume.
    #[arg(required_unless_present = "resume")]
    pub env: Option<String>,
    /// What to compare (ignored with --resume: the run directory has it).
    #[command(flatten)]
    pub request: crate::compare::Request,
    /// Run directory (default: results/<env>/compare-<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Resume the comparison in this run directory.
    #[arg(long, value_name = "RUN_DIR", conflicts_with_all = ["env", "out"])]
    pub resume: Option<PathBuf>,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
}

/// `bfqi-ga batch`.
#[derive(Debug, Args)]
pub struct BatchArgs {
    #[command(flatten)]
    pub exec: ExecArgs,
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

/// `bfqi-ga worker`.
#[derive(Debug, Args)]
pub struct WorkerArgs {
    /// The run directory (on a shared file system).
    pub dir: PathBuf,
    /// The unit id (its result file stem).
    pub unit: String,
}

/// `bfqi-ga report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// A comparison or search run directory.
    pub dir: PathBuf,
}

/// `bfqi-ga reproduce`.
#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// A search's best.json.
    pub best: PathBuf,
}

/// `bfqi-ga fitness`.
#[derive(Debug, Args)]
pub struct FitnessArgs {
    /// Environment name (uses searches/<ENV>.json) or a spec file (e.g. a run directory's spec.json).
    pub env: String,
    /// The config to score: `thesis` (the thesis's GA optimum) or a best.json.
    #[arg(long, value_name = "thesis|FILE")]
    pub tuned: String,
    /// Print one JSON document instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// `bfqi-ga rollout`.
#[derive(Debug, Args)]
pub struct RolloutArgs {
    /// A model file (`run --save-model`), or with --tuned the environment name or spec file whose
    /// search fitness trains it (optional when the tuned config is a search's best.json).
    pub target: Option<String>,
    /// Train this config first (`thesis` or a best.json), as the search's unit on --dataset did.
    #[arg(long, value_name = "thesis|FILE")]
    pub tuned: Option<String>,
    /// With --tuned: the search dataset to train on.
    #[arg(long, default_value_t = 0, requires = "tuned")]
    pub dataset: usize,
    /// Episodes (default: the environment's evaluation episodes).
    #[arg(long)]
    pub episodes: Option<usize>,
    /// Where episodes start: the evaluation box, all zero, or the dataset box.
    #[arg(long, value_enum, default_value = "eval")]
    pub start: crate::rollout::Start,
    /// Steps per episode (default: the evaluation protocol's).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Draw plots and a GIF for at most this many episodes (the CSV has them all).
    #[arg(long, default_value_t = 3)]
    pub draw: usize,
    /// Frames per GIF at most (long episodes show every n-th step).
    #[arg(long, default_value_t = 200)]
    pub frames: usize,
    /// Output directory (default: results/<env>/rollout-<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// With --tuned: also save the trained Q-function to this file.
    #[arg(long, value_name = "FILE", requires = "tuned")]
    pub save_model: Option<PathBuf>,
}

/// `bfqi-ga evaluate`.
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// A model file (`run --save-model` or `rollout --save-model`).
    pub model: PathBuf,
    /// Episodes.
    #[arg(long, default_value_t = 100)]
    pub episodes: usize,
    /// Where episodes start: the evaluation box, all zero, or the dataset box (random bicycle
    /// headings, wide cart-pole starts).
    #[arg(long, value_enum, default_value = "random")]
    pub start: crate::rollout::Start,
    /// Steps per episode (default: the evaluation protocol's).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Print one JSON document instead of the text.
    #[arg(long)]
    pub json: bool,
}

/// `bfqi-ga validate`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// A search's run directory (at least one generation done).
    pub dir: PathBuf,
    /// Settings of the hall of fame to re-score (default: the spec's `search.validate.top`).
    #[arg(long)]
    pub top: Option<usize>,
    /// Validation datasets (default: the spec's `search.validate.datasets`).
    #[arg(long)]
    pub datasets: Option<usize>,
    /// Suppress progress output.
    #[arg(long)]
    pub quiet: bool,
}

/// `bfqi-ga status`.
#[derive(Debug, Args)]
pub struct StatusArgs {
    /// Folder to scan (default: results).
    #[arg(default_value = "results")]
    pub dir: PathBuf,
}

/// `bfqi-ga bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to time.
    #[arg(value_enum)]
    pub what: crate::bench::Target,
    /// Print JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// A Python to run the reference side by side (`learners`: scikit-learn, keras and jax;
    /// `fqi`: scikit-learn; `search`: keras and jax). The scripts are built into the binary.
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// `search`: one environment name or spec file (default: all three, at their default specs).
    #[arg(long)]
    pub env: Option<String>,
    /// `search`: seconds after which a timed unit stops (after its FQI iteration under way); the
    /// unit's time is then projected from the iterations it ran.
    #[arg(long, default_value_t = 20.0)]
    pub cap_seconds: f64,
}

/// `bfqi-ga envs`.
#[derive(Debug, Args)]
pub struct EnvsArgs {
    /// Print the full settings as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<ExitCode> {
    // A Slurm task uses the cores it was given (`--slurm-cpus-per-task`) unless told otherwise.
    let slurm_cpus = || std::env::var("SLURM_CPUS_PER_TASK").ok().and_then(|v| v.parse::<usize>().ok());
    let jobs = match &cli.command {
        Command::Worker(_) => cli.jobs.or_else(slurm_cpus),
        _ => cli.jobs,
    };
    if let Some(n) = jobs {
        let max = crate::limits::JOBS;
        anyhow::ensure!((1..=max).contains(&n), "invalid --jobs = {n}: must be in 1..={max}");
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().context("setting up the thread pool")?;
    }
    match cli.command {
        Command::Dataset(a) => cmd_dataset(a),
        Command::Envs(a) => cmd_envs(a),
        Command::Run(a) => cmd_run(*a),
        Command::Bench(a) => cmd_bench(a),
        Command::Search(a) => cmd_search(*a),
        Command::Reproduce(a) => cmd_reproduce(a),
        Command::Validate(a) => cmd_validate(a),
        Command::Fitness(a) => cmd_fitness(a),
        Command::Rollout(a) => cmd_rollout(*a),
        Command::Evaluate(a) => cmd_evaluate(a),
        Command::Status(a) => cmd_status(a),
        Command::Compare(a) => cmd_compare(*a),
        Command::Report(a) => cmd_report(a),
        Command::Batch(a) => cmd_batch(a),
        Command::Worker(a) => {
            crate::exec::worker(&a.dir, &a.unit)?;
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn cmd_dataset(a: DatasetArgs) -> Result<ExitCode> {
    let env = EnvConfig::by_name(&a.env)?;
    anyhow::ensure!(a.episodes >= 1, "invalid --episodes = 0: must be ≥ 1");
    let seed = dataset_seed(a.seed, a.role, a.index);
    let d = dataset::collect(env.env(), a.episodes, seed)?;
    d.write_csv(&a.out)?;
    eprintln!("wrote {} transitions of {} episodes to {}", d.len(), a.episodes, a.out.display());
    Ok(ExitCode::SUCCESS)
}

fn cmd_envs(a: EnvsArgs) -> Result<ExitCode> {
    let all: Vec<EnvConfig> = NAMES.iter().map(|n| EnvConfig::by_name(n)).collect::<Result<_, _>>()?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&all)?);
        return Ok(ExitCode::SUCCESS);
    }
    for c in &all {
        let e = c.env();
        let p = e.eval();
        println!("{}", e.name());
        println!(
            "  observation {} values, actions {:?}, gamma {}, dataset horizon {}",
            e.obs_dim(),
            e.actions(),
            e.gamma(),
            e.horizon()
        );
        println!(
            "  evaluation: {} episode(s) × {} steps, score {}",
            p.episodes,
            p.steps,
            serde_json::to_value(p.score)?
        );
        let json = serde_json::to_value(c)?;
        let settings: Vec<String> = json
            .as_object()
            .into_iter()
            .flatten()
            .filter(|(k, _)| !matches!(k.as_str(), "name" | "eval" | "actions"))
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        println!("  settings: {}", settings.join(" "));
    }
    Ok(ExitCode::SUCCESS)
}

/// Applies `run`'s flags to a preset. Flags of the other learner are refused, not ignored.
fn run_config(a: &RunArgs) -> Result<RunConfig> {
    let (spec, _) = Spec::resolve(&a.env)?;
    let mut cfg = RunConfig::from_preset(spec.env.clone(), spec.seed, a.algo, spec.preset(a.learner));
    match &mut cfg.learner {
        LearnerConfig::ExtraTrees(p) => {
            let mlp_flag = [a.hidden.is_some(), a.activation.is_some(), a.delta_min.is_some(), a.patience.is_some()];
            anyhow::ensure!(
                !mlp_flag.contains(&true) && a.learning_rate.is_none(),
                "--hidden/--activation/--delta-min/--patience/--learning-rate apply to --learner mlp"
            );
            set(&mut p.n_trees, a.trees);
            if let Some(d) = a.depth {
                p.max_depth = Some(d);
            }
            set(&mut p.min_samples_split, a.min_split);
            set(&mut p.min_samples_leaf, a.min_leaf);
        }
        LearnerConfig::Mlp(p) => {
            let et_flag = [a.trees, a.depth, a.min_split, a.min_leaf];
            anyhow::ensure!(
                et_flag.iter().all(Option::is_none),
                "--trees/--depth/--min-split/--min-leaf apply to --learner et"
            );
            if let Some(h) = &a.hidden {
                p.hidden = h.clone();
            }
            set(&mut p.activation, a.activation);
            set(&mut p.delta_min, a.delta_min);
            set(&mut p.patience, a.patience);
            set(&mut p.learning_rate, a.learning_rate);
        }
    }
    set(&mut cfg.actions, a.actions);
    set(&mut cfg.iterations, a.iterations);
    set(&mut cfg.episodes, a.episodes);
    set(&mut cfg.datasets, a.datasets);
    set(&mut cfg.seed, a.seed);
    set(&mut cfg.eval_every, a.eval_every);
    cfg.validate().map_err(|e| anyhow::anyhow!("{e} (from the flags or {})", a.env))?;
    Ok(cfg)
}

fn set<T>(slot: &mut T, v: Option<T>) {
    if let Some(v) = v {
        *slot = v;
    }
}

fn cmd_run(a: RunArgs) -> Result<ExitCode> {
    let cfg = run_config(&a)?;
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let bar = indicatif::ProgressBar::new((cfg.datasets * cfg.iterations) as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} iterations  ETA {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    if let Some(dir) = &a.save_model {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let report = experiment::run_saving(&cfg, a.save_model.as_deref(), &|_, _| bar.inc(1))?;
    bar.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let l = &cfg.learner;
        println!(
            "{} · {} · {} (complexity {}) · {:?} actions · K={} · {} datasets × {} episodes · seed {}",
            cfg.env.env().name(),
            cfg.algorithm.name(),
            l.short(),
            l.complexity().map_or("unbounded".into(), |c| c.to_string()),
            cfg.actions,
            cfg.iterations,
            cfg.datasets,
            cfg.episodes,
            cfg.seed
        );
        print!("{}", report.table());
    }
    if let Some(dir) = &a.out {
        store::write_json(&dir.join("run.json"), &report)?;
        let csv = report.csv();
        store::write_atomic(&dir.join("run.csv"), |w| std::io::Write::write_all(w, csv.as_bytes()))?;
        eprintln!("wrote {}", dir.display());
    }
    if let Some(dir) = &a.save_model {
        eprintln!("models: {}", experiment::model_path(dir, 0).with_file_name("dataset-<i>.model").display());
    }
    let diverged = report.datasets.iter().filter(|d| d.record.diverged.is_some()).count();
    if diverged > 0 {
        eprintln!("{diverged} of {} datasets diverged (recorded in the results)", cfg.datasets);
    }
    Ok(ExitCode::SUCCESS)
}

fn cmd_bench(a: BenchArgs) -> Result<ExitCode> {
    use crate::bench::Target;
    let figures = match a.what {
        Target::Learners => crate::bench::learners(a.python.as_deref(), a.json)?,
        Target::Fqi => crate::bench::fqi(a.python.as_deref(), a.json)?,
        Target::Search => {
            anyhow::ensure!(
                a.cap_seconds.is_finite() && a.cap_seconds > 0.0,
                "invalid --cap-seconds = {}: must be > 0",
                a.cap_seconds
            );
            let opts = crate::bench::SearchBench {
                env: a.env.clone(),
                python: a.python.clone(),
                cap_seconds: a.cap_seconds,
                json: a.json,
            };
            crate::bench::search(&opts)?
        }
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&figures)?);
    }
    Ok(ExitCode::SUCCESS)
}

/// Ctrl-C: the first stops cleanly after the running units, the second exits at once.
fn interrupt_flag() -> &'static AtomicBool {
    static FLAG: AtomicBool = AtomicBool::new(false);
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(|| {
        let _ = ctrlc::set_handler(|| {
            if FLAG.swap(true, Ordering::SeqCst) {
                eprintln!("\naborted");
                std::process::exit(130);
            }
            eprintln!("\nstopping after the running units finish (Ctrl-C again to abort; resume later)");
        });
    });
    &FLAG
}

fn cmd_search(a: SearchArgs) -> Result<ExitCode> {
    use crate::ga::search;
    // Flags are checked before a run directory exists, so a refused command leaves nothing.
    if let Some(h) = a.max_hours {
        anyhow::ensure!(h.is_finite() && h > 0.0, "invalid --max-hours = {h}: must be > 0 and finite");
    }
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
            return Ok(ExitCode::SUCCESS);
        }
        search::prepare(name, &presets, o, a.out.as_deref(), Path::new("results"))?
    };
    let max_hours = match a.max_hours {
        Some(h) => Some(h),
        None => crate::ga::search::load_spec(&dir)?.search.stop.max_hours,
    };
    let controls = crate::ga::search::Controls { interrupt: interrupt_flag(), max_hours, quiet: a.quiet };
    let exec = a.exec.executor(&dir)?;
    let ending = crate::ga::search::run(&dir, exec.as_ref(), &controls)?;
    match ending {
        crate::ga::search::Ending::Finished(reason) => {
            eprintln!("finished ({reason}): {}", dir.display());
            eprintln!("tuned config: {}", dir.join("best.json").display());
            Ok(ExitCode::SUCCESS)
        }
        crate::ga::search::Ending::Interrupted(reason) => {
            eprintln!("stopped ({reason}): resume with  bfqi-ga search --resume {}", dir.display());
            Ok(if interrupt_flag().load(Ordering::SeqCst) { ExitCode::from(130) } else { ExitCode::SUCCESS })
        }
    }
}

fn cmd_reproduce(a: ReproduceArgs) -> Result<ExitCode> {
    let t = crate::tuned::TunedConfig::load(&a.best)?;
    let r = crate::ga::search::reproduce(&t, &a.best)?;
    let show = |v: Option<f64>| v.map_or("−∞ (diverged)".to_string(), |x| format!("{x:?}"));
    if r.matches() {
        println!("reproduced: fitness {} matches bit for bit ({} datasets)", show(r.derived), t.scores.len());
        Ok(ExitCode::SUCCESS)
    } else {
        println!("NOT reproduced: recorded fitness {}, derived {}", show(r.recorded), show(r.derived));
        for m in &r.mismatches {
            println!("  {m}");
        }
        for (d, rec, der) in &r.differences {
            println!("  dataset {d}: recorded {}, derived {}", show(*rec), show(*der));
        }
        Ok(ExitCode::from(1))
    }
}

fn cmd_fitness(a: FitnessArgs) -> Result<ExitCode> {
    let (spec, spec_from) = Spec::resolve(&a.env)?;
    let (t, from) = crate::tuned::TunedConfig::resolve(&a.tuned, spec.env.env().name())?;
    let r = crate::ga::fitness::score(&spec, &t, &from)?;
    let scores: Vec<Option<f64>> = r.units.iter().map(|u| u.score).collect();
    if a.json {
        let doc = serde_json::json!({
            "spec": spec_from.display().to_string(),
            "spec_hash": spec.hash(),
            "tuned": from.display().to_string(),
            "setting": r.setting,
            "scores": scores,
            "fitness": r.fitness,
            "notes": r.notes,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(ExitCode::SUCCESS);
    }
    let s = &spec.search;
    println!(
        "{} ({}) under the fitness of {}: {} on {} search datasets, K={}, {} episodes each",
        from.display(),
        crate::ga::search::describe(&r.setting),
        spec_from.display(),
        s.algorithm.name(),
        s.datasets,
        s.iterations,
        s.episodes
    );
    for u in &r.units {
        let score = u.score.map_or("−∞ (diverged)".to_string(), |v| format!("{v:.4}"));
        println!("  dataset {:>2}: {score:>12}   {:>7} epochs", u.dataset, u.epochs);
    }
    let finite: Vec<f64> = scores.iter().flatten().copied().collect();
    let summary = crate::report::stats::summarize(&finite).filter(|_| r.fitness.is_some());
    println!(
        "fitness {}  (95 % interval over datasets; exact {})",
        crate::report::stats::interval(summary, 4),
        r.fitness.map_or("−∞".into(), |f| format!("{f:?}"))
    );
    if let Some(f) = t.fitness.filter(|_| t.spec.as_ref().is_some_and(|ts| ts.hash() == spec.hash())) {
        let same = r.fitness.map(f64::to_bits) == Some(f.to_bits());
        println!("recorded in {}: {f:?} ({})", from.display(), if same { "identical" } else { "DIFFERENT" });
    }
    for n in &r.notes {
        println!("note: {n}");
    }
    Ok(ExitCode::SUCCESS)
}

fn cmd_rollout(a: RolloutArgs) -> Result<ExitCode> {
    anyhow::ensure!(a.frames >= 2, "invalid --frames = {}: must be ≥ 2", a.frames);
    let (model, label) = match &a.tuned {
        None => {
            let path = a.target.as_deref().context("give a model file, or --tuned thesis|FILE with an environment")?;
            (crate::model::load(Path::new(path))?, path.to_string())
        }
        Some(tuned) => {
            let tuned_file =
                (tuned != "thesis").then(|| crate::tuned::TunedConfig::load(Path::new(tuned))).transpose()?;
            let spec = match (&a.target, tuned_file.as_ref().and_then(|t| t.spec.clone())) {
                (Some(t), _) => Spec::resolve(t)?.0,
                (None, Some(spec)) => spec,
                (None, None) => {
                    anyhow::bail!("give the environment or spec: bfqi-ga rollout <ENV|SPEC> --tuned {tuned}")
                }
            };
            let (t, from) = crate::tuned::TunedConfig::resolve(tuned, spec.env.env().name())?;
            eprintln!(
                "training {} on search dataset {} as its search unit did ({} K={})…",
                crate::ga::search::describe(&crate::ga::fitness::setting_of(&t)),
                a.dataset,
                spec.search.algorithm.name(),
                spec.search.iterations
            );
            let (_, m) = crate::ga::fitness::train(&spec, &t, &from, a.dataset)?;
            if let Some(p) = &a.save_model {
                if let Some(parent) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
                    store::create_dir(parent)?;
                }
                crate::model::save(p, &m)?;
                eprintln!("saved the Q-function to {}", p.display());
            }
            (m, format!("{} trained on search dataset {}", from.display(), a.dataset))
        }
    };
    let protocol = model.info.env.env().eval();
    let req = crate::report::policy::Request {
        episodes: a.episodes.unwrap_or(protocol.episodes),
        start: a.start,
        steps: a.steps.unwrap_or(protocol.steps),
        draw: a.draw,
        frames: a.frames,
    };
    let (me, ms) = (crate::limits::EVAL_EPISODES, crate::limits::EVAL_STEPS);
    anyhow::ensure!((1..=me).contains(&req.episodes), "invalid --episodes = {}: must be in 1..={me}", req.episodes);
    // Every step of every episode is kept in memory for the CSV.
    anyhow::ensure!(
        req.steps >= 1 && req.steps.saturating_mul(req.episodes) <= ms,
        "invalid --steps = {}: must be ≥ 1, with steps × episodes ≤ {ms}",
        req.steps
    );
    let env = model.info.env.env().name();
    let dir = match &a.out {
        Some(d) => d.clone(),
        None => store::new_run_dir(&Path::new("results").join(env), "rollout-")?,
    };
    let s = crate::report::policy::write(&dir, &model, &label, &req)?;
    println!("{}", crate::rollout::describe_model(&model.info, Path::new(&label)));
    for e in &s.episodes {
        let gif = e
            .gif
            .as_ref()
            .map_or(String::new(), |g| format!("  {} ({} frames, {} KiB)", g.file, g.frames, g.bytes / 1024));
        println!(
            "  episode {:>3}: score {:>10.4}  {:>5} steps{}{gif}",
            e.episode,
            e.score,
            e.steps,
            if e.failed { "  failed" } else { "" }
        );
    }
    if a.start == crate::rollout::Start::Eval && req.steps == protocol.steps && req.episodes >= protocol.episodes {
        // The first protocol.episodes episodes are the ones the run was scored on.
        let mean = s.episodes[..protocol.episodes].iter().map(|e| e.score).sum::<f64>() / protocol.episodes as f64;
        if let Some(rec) = model.info.score {
            let same = mean.to_bits() == rec.to_bits();
            println!(
                "evaluation episodes: {mean:?}, recorded {rec:?} ({})",
                if same { "identical" } else { "DIFFERENT" }
            );
        }
    }
    println!("wrote {}", dir.display());
    Ok(ExitCode::SUCCESS)
}

fn cmd_evaluate(a: EvaluateArgs) -> Result<ExitCode> {
    let (me, ms) = (crate::limits::EVAL_EPISODES, crate::limits::EVAL_STEPS);
    anyhow::ensure!((1..=me).contains(&a.episodes), "invalid --episodes = {}: must be in 1..={me}", a.episodes);
    let m = crate::model::load(&a.model)?;
    let steps = a.steps.unwrap_or(m.info.env.env().eval().steps);
    anyhow::ensure!((1..=ms).contains(&steps), "invalid --steps = {steps}: must be in 1..={ms}");
    let eps = crate::rollout::run(&m.info.env, &|o, q| m.q(o, q), m.info.eval_seed, a.episodes, a.start, steps, false);
    let eps: Vec<crate::eval::Episode> = eps.into_iter().map(|(e, _)| e).collect();
    let r = crate::rollout::robustness(a.start, &eps).expect("at least one episode");
    if a.json {
        let doc =
            serde_json::json!({ "model": a.model.display().to_string(), "info": m.info, "steps": steps, "result": r });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("{}", crate::rollout::describe_model(&m.info, &a.model));
    println!(
        "{} episodes from {} starts, ≤ {steps} steps: score {}, steps {}, failures {}/{}",
        r.episodes,
        serde_json::to_value(a.start)?.as_str().unwrap_or("?"),
        crate::report::stats::interval(Some(r.score), 4),
        crate::report::stats::interval(Some(r.steps), 1),
        r.failures,
        r.episodes
    );
    Ok(ExitCode::SUCCESS)
}

fn cmd_validate(a: ValidateArgs) -> Result<ExitCode> {
    use crate::ga::validate::{self, ValidateRule};
    let spec = crate::ga::search::load_spec(&a.dir)?;
    let rule = match (&spec.search.validate, a.top, a.datasets) {
        (_, Some(top), Some(datasets)) => ValidateRule { top, datasets },
        (Some(r), top, datasets) => {
            ValidateRule { top: top.unwrap_or(r.top), datasets: datasets.unwrap_or(r.datasets) }
        }
        (None, _, _) => anyhow::bail!(
            "{}: its spec has no search.validate; give both --top and --datasets (e.g. --top 5 --datasets 10)",
            a.dir.join("spec.json").display()
        ),
    };
    let v = validate::run_alone(&a.dir, &rule, a.quiet)?;
    let ci = |s: &Option<crate::report::stats::Summary>| crate::report::stats::interval(*s, 4);
    println!("{:<22} {:<24} {:>20} {:>20}", "", "setting", "search datasets", "validation");
    for e in &v.entries {
        let tag = if e.setting == v.tuned { format!("{} (tuned)", e.source) } else { e.source.clone() };
        println!("{:<22} {:<24} {:>20} {:>20}", tag, e.setting, ci(&e.search), ci(&e.validation));
    }
    println!("{}", v.note);
    Ok(ExitCode::SUCCESS)
}

fn cmd_status(a: StatusArgs) -> Result<ExitCode> {
    let mut dirs = Vec::new();
    let mut stack = vec![a.dir.clone()];
    while let Some(d) = stack.pop() {
        if d.join("state.json").is_file() {
            dirs.push(d);
            continue;
        }
        if let Ok(entries) = std::fs::read_dir(&d) {
            stack.extend(entries.flatten().map(|e| e.path()).filter(|p| p.is_dir()));
        }
    }
    dirs.sort();
    if dirs.is_empty() {
        println!("no runs under {}", a.dir.display());
    }
    for d in dirs {
        let st: crate::ga::search::RunState = match store::read_json(&d.join("state.json")) {
            Ok(st) => st,
            Err(e) => {
                // One damaged run must not hide the others.
                eprintln!("warning: skipped {e}");
                continue;
            }
        };
        let env = store::read_json::<serde_json::Value>(&d.join("run.json"))
            .ok()
            .and_then(|v| v["env"].as_str().map(String::from))
            .unwrap_or_else(|| "?".into());
        let state = match st.state.as_str() {
            "running" if !store::RunLock::is_held(&d) => "interrupted".to_string(),
            s => s.to_string(),
        };
        let best = st.best.map_or("—".into(), |b| {
            format!(
                "{} δ_min {} patience {}",
                serde_json::to_value(b.activation).unwrap_or_default().as_str().unwrap_or("?"),
                b.delta_min,
                b.patience
            )
        });
        let timing = if st.state == "running" || st.units_total > 0 {
            let human = crate::progress::human;
            format!(
                "  units {}/{} · ran {} · ETA {}",
                st.units_done,
                st.units_total,
                human(st.elapsed()),
                if state == "running" { st.eta_seconds.map_or("?".into(), human) } else { "— (resume it)".into() }
            )
        } else {
            format!("  ran {}", crate::progress::human(st.elapsed()))
        };
        // A validated winner shows its validation mean beside its fitness.
        let validated = crate::ga::validate::load(&d)
            .and_then(|v| v.entries.into_iter().find(|e| e.setting == v.tuned))
            .map_or(String::new(), |e| {
                e.validation.map_or(" (validation: diverged)".into(), |s| {
                    format!(" (validation {:.4} ± {:.4} on {} datasets)", s.mean, s.ci95, s.n)
                })
            });
        println!(
            "{:<9} {:<12} gen {:>3}/{:<3} best {:>12}{}  {}  {}{}",
            env,
            state,
            st.generation,
            st.generations,
            st.best_fitness.map_or("—".into(), |f| format!("{f:.4}")),
            validated,
            best,
            d.display(),
            timing
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn cmd_compare(a: CompareArgs) -> Result<ExitCode> {
    use crate::compare;
    let dir = if let Some(d) = &a.resume {
        compare::load(d)?;
        d.clone()
    } else {
        let name = a.env.as_deref().expect("clap requires ENV without --resume");
        compare::prepare(name, &a.request, a.out.as_deref(), Path::new("results"))?
    };
    let exec = a.exec.executor(&dir)?;
    let complete = compare::run(&dir, exec.as_ref(), interrupt_flag(), None, a.quiet)?;
    if !complete {
        eprintln!("stopped: resume with  bfqi-ga compare --resume {}", dir.display());
        return Ok(ExitCode::from(130));
    }
    let out = crate::report::comparison::regenerate(&dir)?;
    for c in &out.claims {
        let mark = if c.verdict == crate::report::claims::Verdict::Supported { "supported" } else { "NOT supported" };
        eprintln!("claim {mark}: {} ({})", c.statement, c.evidence);
    }
    eprintln!("report: {}", dir.join("report.md").display());
    Ok(ExitCode::SUCCESS)
}

fn cmd_report(a: ReportArgs) -> Result<ExitCode> {
    if a.dir.join("compare.json").is_file() {
        let out = crate::report::comparison::regenerate(&a.dir)?;
        eprintln!("wrote {} files into {}", out.files.len(), a.dir.display());
    } else if a.dir.join("spec.json").is_file() {
        let n = crate::report::search::write(&a.dir)?;
        eprintln!(
            "wrote fitness.csv, fitness.png, fitness.svg and report.md for {n} generations into {}",
            a.dir.display()
        );
    } else {
        anyhow::bail!("{}: not a comparison or search run directory (no compare.json or spec.json)", a.dir.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// Hours from now until the next local `HH:MM` (the offset from UTC is asked of `date +%z`; UTC if
/// that is unavailable).
fn hours_until(hhmm: &str) -> Result<f64> {
    let bad = || anyhow::anyhow!("invalid --until = {hhmm}: must be HH:MM (24-hour clock)");
    let (h, m) = hhmm.split_once(':').ok_or_else(bad)?;
    let (h, m): (u64, u64) = (h.parse().map_err(|_| bad())?, m.parse().map_err(|_| bad())?);
    anyhow::ensure!(h < 24 && m < 60, bad());
    let offset_s: i64 = std::process::Command::new("date")
        .arg("+%z")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|z| {
            let z = z.trim();
            let sign = if z.starts_with('-') { -1 } else { 1 };
            let digits = z.trim_start_matches(['+', '-']);
            let (hh, mm) = (digits.get(..2)?.parse::<i64>().ok()?, digits.get(2..4)?.parse::<i64>().ok()?);
            Some(sign * (hh * 3600 + mm * 60))
        })
        .unwrap_or(0);
    let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH)?.as_secs() as i64 + offset_s;
    let today = now.rem_euclid(86_400);
    let target = (h * 3600 + m * 60) as i64;
    let wait = (target - today).rem_euclid(86_400);
    Ok(wait as f64 / 3600.0)
}

fn cmd_batch(a: BatchArgs) -> Result<ExitCode> {
    // The budget is checked before the batch directory exists.
    let max_hours = match (&a.max_hours, &a.until) {
        (Some(h), _) => {
            anyhow::ensure!(h.is_finite() && *h > 0.0, "invalid --max-hours = {h}: must be > 0 and finite");
            Some(*h)
        }
        (None, Some(t)) => Some(hours_until(t)?),
        _ => None,
    };
    if let (true, Some(plan)) = (a.dry_run, &a.plan) {
        let p = crate::batch::Plan::parse(&store::read_input(plan)?, plan)?;
        crate::batch::check(&p, plan)?;
        for (i, j) in p.jobs.iter().enumerate() {
            let kind = if matches!(j, crate::batch::Job::Search(_)) { "search" } else { "compare" };
            println!("job {}: {} ({kind}) ok", i + 1, j.name());
        }
        return Ok(ExitCode::SUCCESS);
    }
    let dir = match (&a.resume, &a.plan) {
        (Some(d), _) => d.clone(),
        (None, Some(plan)) => crate::batch::create(plan, Path::new("results"), a.out.as_deref())?,
        (None, None) => anyhow::bail!("give a plan file, or --resume DIR"),
    };
    if !a.quiet {
        eprintln!("batch → {}", dir.display());
    }
    let controls = crate::batch::BatchControls { interrupt: interrupt_flag(), max_hours, quiet: a.quiet };
    let ending = crate::batch::run(&dir, &|d: &Path| a.exec.executor(d), &controls)?;
    eprintln!("summary: {}", dir.join("summary.md").display());
    match ending {
        crate::batch::BatchEnding::Done { failed: 0 } => Ok(ExitCode::SUCCESS),
        crate::batch::BatchEnding::Done { failed } => {
            eprintln!("{failed} job(s) failed (see the summary)");
            Ok(ExitCode::from(1))
        }
        crate::batch::BatchEnding::Stopped(reason) => {
            eprintln!("stopped ({reason}): resume with  bfqi-ga batch --resume {}", dir.display());
            Ok(if interrupt_flag().load(Ordering::SeqCst) { ExitCode::from(130) } else { ExitCode::SUCCESS })
        }
    }
}
