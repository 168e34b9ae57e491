//! Single runs and tools: `run`, `dataset`, `envs`, `bench`, and `worker` (a Slurm task).

use super::Outcome;
use crate::dataset::{self, Role};
use crate::env::{EnvConfig, NAMES};
use crate::experiment::{self, RunOverrides};
use crate::spec::Spec;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;

/// `bfqi-ga dataset`.
#[derive(Debug, Args)]
pub struct DatasetArgs {
    /// Environment: pendulum, cartpole or bicycle, or a spec file (e.g. of a gymnasium env).
    pub env: String,
    /// Number of episodes: random-policy ones, or taken from a spec's logged data (`data`). With
    /// logged data (`minari:<id>`, a spec with `data`) and no --episodes, the whole data is written,
    /// in its own order.
    #[arg(long)]
    pub episodes: Option<usize>,
    /// Master seed: the file is dataset INDEX of ROLE under this seed, exactly as runs use it.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Which datasets: those of comparison runs or of the GA's fitness. Their seeds are disjoint.
    #[arg(long, value_enum, default_value_t = Role::Compare)]
    pub role: Role,
    /// Index of the dataset within its role.
    #[arg(long, default_value_t = 0)]
    pub index: usize,
    /// Output file, Parquet (`.parquet`) or CSV (`.csv`), written atomically: one row per
    /// transition (episode, step, state_i, action, reward, next_state_i, terminated, truncated),
    /// the columns a spec's `data.file` reads.
    #[arg(long, required_unless_present = "minari")]
    pub out: Option<PathBuf>,
    /// Also (or instead) write the dataset as a new Minari dataset of this id
    /// (`namespace/name-v0`, under `MINARI_DATASETS_PATH`), with a gymnasium env's spec.
    #[arg(long, value_name = "ID")]
    pub minari: Option<String>,
}

/// `bfqi-ga run`: presets come from the spec file's `experiments.<learner>`; flags override them.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Environment name (uses searches/<ENV>.json) or a spec file.
    pub env: String,
    #[command(flatten)]
    pub overrides: RunOverrides,
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
    /// `fqi`: scikit-learn; `search`: keras and jax; `data`: pandas and pyarrow). The scripts are
    /// built into the binary.
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// `search`: one environment name or spec file (default: all three, at their default specs).
    #[arg(long)]
    pub env: Option<String>,
    /// `search`: seconds after which a timed unit stops (after its FQI iteration under way); the
    /// unit's time is then projected from the iterations it ran.
    #[arg(long, default_value_t = 20.0)]
    pub cap_seconds: f64,
    /// `search`: `all`, or kernel levels (`avx512,avx2,neon,portable`) this CPU runs: time the
    /// network shapes at each side by side, each against its own peak and bound (no units).
    #[arg(long)]
    pub isa: Option<String>,
}

/// `bfqi-ga envs`.
#[derive(Debug, Args)]
pub struct EnvsArgs {
    /// Print the full settings as JSON.
    #[arg(long)]
    pub json: bool,
}

/// `bfqi-ga worker`.
#[derive(Debug, Args)]
pub struct WorkerArgs {
    /// The run directory (on a shared file system).
    pub dir: PathBuf,
    /// The unit id (its result file stem).
    pub unit: String,
    /// The run directory's folder the unit is stored in: `units`, or `validation` for a search's
    /// validation units.
    #[arg(long, default_value = "units")]
    pub units: String,
}

pub(super) fn dataset(a: DatasetArgs) -> Result<Outcome> {
    // A Minari dataset written whole needs no env to evaluate in (it may record none).
    if let (None, Some(id), Some(out), None) = (a.episodes, dataset::minari::named(&a.env), &a.out, &a.minari) {
        let d = dataset::logged::DataSource::minari(id).whole(&dataset::minari::python(None))?;
        dataset::table::write(&d, out)?;
        eprintln!("wrote {} transitions of {} episodes to {}", d.len(), d.episodes(), out.display());
        return Ok(Outcome::Success);
    }
    let (env, data) = if NAMES.contains(&a.env.as_str()) {
        (EnvConfig::by_name(&a.env)?, None)
    } else {
        let spec = Spec::resolve(&a.env)?.0;
        (spec.env, spec.data)
    };
    anyhow::ensure!(a.episodes != Some(0), "invalid --episodes = 0: must be ≥ 1");
    if let Some(out) = &a.out {
        anyhow::ensure!(
            crate::table::Format::of_path(out).is_some(),
            "invalid --out = {}: the name must end in .parquet, .pq or .csv",
            out.display()
        );
    }
    let d = match (a.episodes, &data) {
        (Some(episodes), _) => {
            crate::limits::episodes("--episodes", episodes, env.env().horizon())?;
            dataset::make(env.env(), data.as_ref(), episodes, a.seed, a.role, a.index)?
        }
        (None, Some(logged)) => logged.whole(&dataset::minari::python(Some(&env)))?,
        (None, None) => anyhow::bail!(
            "--episodes is needed: {} collects random-policy episodes (only logged data is written whole without it)",
            a.env
        ),
    };
    let episodes = d.episodes();
    if let Some(out) = &a.out {
        dataset::table::write(&d, out)?;
        eprintln!("wrote {} transitions of {episodes} episodes to {}", d.len(), out.display());
    }
    if let Some(id) = &a.minari {
        dataset::minari::write(&d, &env, id)?;
        eprintln!("wrote {} transitions of {episodes} episodes as the Minari dataset {id}", d.len());
    }
    Ok(Outcome::Success)
}

pub(super) fn envs(a: EnvsArgs) -> Result<Outcome> {
    let all: Vec<EnvConfig> = NAMES.iter().map(|n| EnvConfig::by_name(n)).collect::<Result<_, _>>()?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&all)?);
        return Ok(Outcome::Success);
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
    println!("gymnasium");
    println!("  any discrete-action gymnasium env (or a Box env with env.actions), stepped by a Python worker:");
    println!(
        "  named in a spec file, \"env\": {{\"name\": \"gymnasium\", \"id\": \"Acrobot-v1\", …}} (README, Gymnasium)"
    );
    Ok(Outcome::Success)
}

pub(super) fn run(a: RunArgs) -> Result<Outcome> {
    let cfg = a.overrides.config(&a.env)?;
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
            "{} · {} · {} (complexity {}) · {} actions · K={} · {} datasets × {} episodes · seed {}",
            cfg.env.env().name(),
            cfg.algorithm.name(),
            l.short(),
            l.complexity().map_or("unbounded".into(), |c| c.to_string()),
            serde_json::to_value(cfg.actions)?.as_str().unwrap_or("?"),
            cfg.iterations,
            cfg.datasets,
            cfg.episodes,
            cfg.seed
        );
        print!("{}", report.table());
    }
    if let Some(dir) = &a.out {
        crate::store::write_json(&dir.join("run.json"), &report)?;
        let csv = report.csv();
        crate::store::write_atomic(&dir.join("run.csv"), |w| std::io::Write::write_all(w, csv.as_bytes()))?;
        eprintln!("wrote {}", dir.display());
    }
    if let Some(dir) = &a.save_model {
        eprintln!("models: {}", experiment::model_path(dir, 0).with_file_name("dataset-<i>.model").display());
    }
    let diverged = report.datasets.iter().filter(|d| d.record.diverged.is_some()).count();
    if diverged > 0 {
        eprintln!("{diverged} of {} datasets diverged (recorded in the results)", cfg.datasets);
    }
    Ok(Outcome::Success)
}

pub(super) fn bench(a: BenchArgs) -> Result<Outcome> {
    use crate::bench::{self, Target};
    let figures = match a.what {
        Target::Learners => bench::learners(a.python.as_deref(), a.json)?,
        Target::Fqi => bench::fqi(a.python.as_deref(), a.json)?,
        Target::Dashboard => bench::dashboard(a.json)?,
        Target::Gym => bench::gym(a.json)?,
        Target::Data => bench::logged(a.python.as_deref(), a.json)?,
        Target::Search => {
            anyhow::ensure!(
                a.cap_seconds.is_finite() && a.cap_seconds > 0.0,
                "invalid --cap-seconds = {}: must be > 0",
                a.cap_seconds
            );
            let opts = bench::SearchBench {
                env: a.env,
                python: a.python,
                cap_seconds: a.cap_seconds,
                json: a.json,
                isa: a.isa,
            };
            bench::search(&opts)?
        }
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&figures)?);
    }
    Ok(Outcome::Success)
}

pub(super) fn worker(a: WorkerArgs) -> Result<Outcome> {
    crate::runs::worker(&a.dir, &a.units, &a.unit)?;
    Ok(Outcome::Success)
}
