//! Command-line definitions (clap derive) and their dispatch to the library. Nothing here computes:
//! flags become validated configs, then the library runs them.

use crate::dataset::{self, dataset_seed};
use crate::env::{EnvConfig, NAMES};
use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

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
    Search(Unavailable),
    /// B-FQI vs FQI comparison runs with tuned settings.
    Compare(Unavailable),
    /// One FQI or B-FQI run over one or more datasets.
    Run(Unavailable),
    /// Re-derive a tuned config's fitness from scratch and check it matches.
    Reproduce(Unavailable),
    /// Run a plan of searches and comparisons (overnight batches).
    Batch(Unavailable),
    /// One line per run under results/: state, generation, best fitness.
    Status(Unavailable),
    /// Regenerate tables, plots and report.md from stored results.
    Report(Unavailable),
    /// Write a random-policy dataset as CSV.
    Dataset(DatasetArgs),
    /// List the environments and their settings.
    Envs(EnvsArgs),
    /// Benchmarks: learners, FQI, search throughput.
    Bench(Unavailable),
}

/// Arguments of a subcommand that this build does not have yet.
#[derive(Debug, Args)]
pub struct Unavailable {
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    rest: Vec<String>,
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
    /// Which datasets: `compare` (comparison runs) or `search` (GA fitness). Their seeds are disjoint.
    #[arg(long, default_value = "compare", value_parser = ["compare", "search"])]
    pub role: String,
    /// Index of the dataset within its role.
    #[arg(long, default_value_t = 0)]
    pub index: usize,
    /// Output CSV (written atomically).
    #[arg(long)]
    pub out: PathBuf,
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
    if let Some(n) = cli.jobs {
        anyhow::ensure!(n >= 1, "invalid --jobs = 0: must be ≥ 1");
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().context("setting up the thread pool")?;
    }
    match cli.command {
        Command::Dataset(a) => cmd_dataset(a),
        Command::Envs(a) => cmd_envs(a),
        other => {
            let name = format!("{other:?}");
            let name = name.split('(').next().unwrap_or("").to_lowercase();
            anyhow::bail!("`{name}` is not available in this build yet")
        }
    }
}

fn cmd_dataset(a: DatasetArgs) -> Result<ExitCode> {
    let env = EnvConfig::by_name(&a.env)?;
    anyhow::ensure!(a.episodes >= 1, "invalid --episodes = 0: must be ≥ 1");
    let seed = dataset_seed(a.seed, &a.role, a.index);
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
