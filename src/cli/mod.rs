//! The command line: clap declarations of every subcommand's arguments, each turned into the
//! library's own types (choices are its enums, override sets its structs), and one call into the
//! library per command. What a command computes lives in the library; here are only the arguments,
//! the calls and what is printed.

mod dashboard;
mod jobs;
mod models;
mod runs;

pub use dashboard::DashboardArgs;
pub use jobs::{
    BatchArgs, CompareArgs, ExportArgs, ReportArgs, SearchArgs, StampArgs, StatusArgs, TidyArgs, ValidateArgs, WorkArgs,
};
pub use models::{EvaluateArgs, FitnessArgs, ReproduceArgs, RolloutArgs};
pub use runs::{BenchArgs, DatasetArgs, EnvsArgs, RunArgs, WorkerArgs};

use crate::run_dir::{Ending, Stop};
use anyhow::Result;
use clap::{Parser, Subcommand};

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
    Batch(Box<BatchArgs>),
    /// One line per run under results/: state, generation, best fitness.
    Status(StatusArgs),
    /// A read-only local web view of the runs under results/ (or given folders).
    Dashboard(DashboardArgs),
    /// Regenerate tables, plots and report.md from stored results.
    Report(ReportArgs),
    /// One row per FQI unit of a search, comparison or batch, as Parquet or CSV (for pandas).
    Export(ExportArgs),
    /// The work a search, comparison or batch did, from its units: epochs × rows, FLOPs, and
    /// hours on the reference machine, beside its wall time.
    Work(WorkArgs),
    /// Give the units of a run made before units carried checksums their checksums, so that an
    /// edit or a deleted checksum is seen from then on.
    Stamp(StampArgs),
    /// Remove from a finished search the units it took with --units-from and never used.
    Tidy(TidyArgs),
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

/// How a command ended without an error; `main` turns it into the exit code, as it does errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// It did what was asked.
    Success,
    /// It ran, and something failed or disagreed (a batch job failed, a fitness did not reproduce).
    Failed,
    /// Ctrl-C stopped it cleanly; it resumes.
    Interrupted,
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<Outcome> {
    crate::exec::set_threads(cli.jobs, matches!(cli.command, Command::Worker(_)))?;
    match cli.command {
        Command::Dataset(a) => runs::dataset(a),
        Command::Envs(a) => runs::envs(a),
        Command::Run(a) => runs::run(*a),
        Command::Bench(a) => runs::bench(a),
        Command::Worker(a) => runs::worker(a),
        Command::Search(a) => jobs::search(*a),
        Command::Compare(a) => jobs::compare(*a),
        Command::Batch(a) => jobs::batch(*a),
        Command::Validate(a) => jobs::validate(a),
        Command::Status(a) => jobs::status(a),
        Command::Report(a) => jobs::report(a),
        Command::Stamp(a) => jobs::stamp(a),
        Command::Tidy(a) => jobs::tidy(a),
        Command::Export(a) => jobs::export(a),
        Command::Work(a) => jobs::work(a),
        Command::Dashboard(a) => dashboard::dashboard(a),
        Command::Reproduce(a) => models::reproduce(a),
        Command::Fitness(a) => models::fitness(a),
        Command::Rollout(a) => models::rollout(*a),
        Command::Evaluate(a) => models::evaluate(a),
    }
}

/// The outcome of a run's ending, saying on stderr how a stopped run resumes (`resume`): a stop by
/// Ctrl-C is `Interrupted`, one by the time budget a success, units missing a failure.
fn outcome(ending: &Ending, resume: &str) -> Outcome {
    match ending {
        Ending::Finished(_) => Outcome::Success,
        Ending::Failed(why) => {
            eprintln!("{why}");
            Outcome::Failed
        }
        Ending::Stopped(stop) => {
            eprintln!("stopped ({stop}): resume with  {resume}");
            match stop {
                Stop::Interrupted => Outcome::Interrupted,
                Stop::Budget(_) => Outcome::Success,
                Stop::Missing(_) => Outcome::Failed,
            }
        }
    }
}
