//! Experiments: FQI / B-FQI over several datasets (`bfqi-ga run`), the unit of every comparison.
//!
//! Dataset `i` of a run is comparison dataset `i` of the master seed; member fits draw from
//! `(seed, "fit", i)` and evaluation episodes from `(seed, "eval", i)`. Datasets run in parallel and
//! the results do not depend on the thread count.

use crate::dataset::{self, Dataset, dataset_seed};
use crate::env::EnvConfig;
use crate::error::{Error, Result, ensure};
use crate::eval::eval_seed;
use crate::fqi::{Algorithm, FqiSettings, IterationRecord, RunRecord};
use crate::learn::LearnerConfig;
use crate::learn::actions::{ActionEncoding, Encoded};
use crate::model::{self, Model, ModelInfo};
use crate::rng;
use crate::spec::{LearnerKind, Preset, Spec};
use crate::stats::{Summary, summarize};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Everything that determines a run's results.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunConfig {
    /// The environment.
    pub env: EnvConfig,
    /// FQI or B-FQI.
    pub algorithm: Algorithm,
    /// The learner.
    pub learner: LearnerConfig,
    /// How actions reach the learner.
    pub actions: ActionEncoding,
    /// K.
    pub iterations: usize,
    /// Evaluate every this many iterations (and at the last).
    pub eval_every: usize,
    /// Episodes per dataset.
    pub episodes: usize,
    /// Number of datasets.
    pub datasets: usize,
    /// Master seed.
    pub seed: u64,
    /// The spec's logged data, when it learns from some instead of collecting datasets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<dataset::DataSource>,
}

impl RunConfig {
    /// A run of `algorithm` with a preset's settings.
    pub fn from_preset(env: EnvConfig, seed: u64, algorithm: Algorithm, p: &Preset) -> Self {
        RunConfig {
            env,
            algorithm,
            learner: p.learner.clone(),
            actions: p.actions,
            iterations: p.iterations,
            eval_every: p.eval_every,
            episodes: p.episodes,
            datasets: p.datasets,
            seed,
            data: None,
        }
    }

    /// Validates every setting; errors name the field.
    pub fn validate(&self) -> Result<()> {
        self.env.validate()?;
        self.learner.check()?;
        use crate::limits::{self, DATASETS, ITERATIONS};
        self.actions.check_for(&self.env, "actions")?;
        limits::within("iterations", self.iterations, 1, ITERATIONS)?;
        ensure(self.eval_every >= 1, "eval_every", self.eval_every, "must be ≥ 1")?;
        limits::episodes("episodes", self.episodes, self.env.env().horizon())?;
        limits::within("datasets", self.datasets, 1, DATASETS)?;
        if let Some(d) = &self.data {
            d.check(dataset::Role::Compare, self.datasets, self.episodes)?;
        }
        match &self.learner {
            LearnerConfig::Mlp(net) => crate::spec::holdout(net, self.episodes, self.env.env().horizon(), "episodes")
                .map_err(|e| e.within("learner")),
            LearnerConfig::ExtraTrees(_) => Ok(()),
        }
    }

    /// A short hash of the configuration's canonical JSON (recorded in model files).
    pub fn hash(&self) -> String {
        crate::store::json_hash(self)
    }

    /// The seed dataset `index` is collected from (the comparison datasets' stream).
    pub fn dataset_seed(&self, index: usize) -> u64 {
        dataset_seed(self.seed, dataset::Role::Compare, index)
    }

    fn settings(&self) -> FqiSettings {
        FqiSettings { algorithm: self.algorithm, iterations: self.iterations, eval_every: self.eval_every }
    }
}

/// `bfqi-ga run`'s settings over a spec's preset: the algorithm, the learner (which selects the
/// preset) and any setting of the run or of that learner. A flag of the other learner is refused,
/// not ignored.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct RunOverrides {
    /// Algorithm.
    #[arg(long = "algo", value_name = "ALGO", value_enum, default_value_t = Algorithm::Bfqi)]
    pub algorithm: Algorithm,
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
    pub activation: Option<crate::learn::mlp::Activation>,
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
}

impl RunOverrides {
    /// The run: the preset of the learner in the spec `spec_name` (an environment name or a spec
    /// file), with these settings over it, validated.
    pub fn config(&self, spec_name: &str) -> Result<RunConfig> {
        let (spec, _) = Spec::resolve(spec_name)?;
        let mut cfg = RunConfig::from_preset(spec.env.clone(), spec.seed, self.algorithm, spec.preset(self.learner));
        cfg.data = spec.data.clone();
        match &mut cfg.learner {
            LearnerConfig::ExtraTrees(p) => {
                let mlp_flag = [self.hidden.is_some(), self.activation.is_some(), self.delta_min.is_some()];
                if mlp_flag.contains(&true) || self.patience.is_some() || self.learning_rate.is_some() {
                    return Err(Error::Usage(
                        "--hidden/--activation/--delta-min/--patience/--learning-rate apply to --learner mlp".into(),
                    ));
                }
                set(&mut p.n_trees, self.trees);
                if let Some(d) = self.depth {
                    p.max_depth = Some(d);
                }
                set(&mut p.min_samples_split, self.min_split);
                set(&mut p.min_samples_leaf, self.min_leaf);
            }
            LearnerConfig::Mlp(p) => {
                if [self.trees, self.depth, self.min_split, self.min_leaf].iter().any(Option::is_some) {
                    return Err(Error::Usage("--trees/--depth/--min-split/--min-leaf apply to --learner et".into()));
                }
                if let Some(h) = &self.hidden {
                    p.hidden = h.clone();
                }
                set(&mut p.activation, self.activation);
                set(&mut p.delta_min, self.delta_min);
                set(&mut p.patience, self.patience);
                set(&mut p.learning_rate, self.learning_rate);
            }
        }
        set(&mut cfg.actions, self.actions);
        set(&mut cfg.iterations, self.iterations);
        set(&mut cfg.episodes, self.episodes);
        set(&mut cfg.datasets, self.datasets);
        set(&mut cfg.seed, self.seed);
        set(&mut cfg.eval_every, self.eval_every);
        cfg.validate().map_err(|e| Error::Usage(format!("{e} (from the flags or {spec_name})")))?;
        Ok(cfg)
    }
}

fn set<T>(slot: &mut T, v: Option<T>) {
    if let Some(v) = v {
        *slot = v;
    }
}

/// `--actions` reads the spec files' spelling (`per_action`), and `per-action`, the command line's
/// spelling before. Written out beside the flag rather than derived in `learn`, since the alias
/// needs attributes on the enum.
impl clap::ValueEnum for ActionEncoding {
    fn value_variants<'a>() -> &'a [Self] {
        &[ActionEncoding::Input, ActionEncoding::PerAction]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        use clap::builder::PossibleValue;
        Some(match self {
            ActionEncoding::Input => PossibleValue::new("input").help("One model on [state, action]"),
            ActionEncoding::PerAction => {
                PossibleValue::new("per_action").alias("per-action").help("One model per discrete action")
            }
        })
    }
}

/// The record of one dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetResult {
    /// Dataset index.
    pub dataset: usize,
    /// Transitions in the dataset.
    pub transitions: usize,
    /// Per-iteration records.
    #[serde(flatten)]
    pub record: RunRecord,
    /// The rows each network was fitted on (one per action with `per_action`; none for
    /// Extra-Trees): what its epochs are counted against ([`crate::work`]). (Absent in units
    /// written before it was recorded.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub network_rows: Option<Vec<usize>>,
    /// [`RunConfig::hash`] of the configuration that computed it, in a comparison's units: a unit
    /// of another configuration is not reused. (Absent in `run` reports and in comparison units
    /// written before it was recorded.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec_hash: Option<String>,
    /// FNV-1a of the unit's JSON without this field, in a comparison's units: a damaged or edited
    /// file is computed again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checksum: Option<String>,
}

impl DatasetResult {
    /// The checksum of the result's content (its JSON with `checksum` absent).
    pub fn content_checksum(&self) -> String {
        crate::store::json_hash(&DatasetResult { checksum: None, ..self.clone() })
    }
}

/// Statistics over datasets at one iteration (diverged datasets excluded).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IterationSummary {
    /// 1-based iteration.
    pub iteration: usize,
    /// Score over the datasets evaluated at this iteration.
    pub score: Option<Summary>,
    /// Steps survived.
    pub steps: Option<Summary>,
    /// Bellman residual.
    pub bellman_residual: Option<Summary>,
    /// Datasets that diverged at or before this iteration.
    pub diverged: usize,
}

/// A whole run: the configuration, every dataset's records and the summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunReport {
    /// What was run.
    pub config: RunConfig,
    /// One entry per dataset, in index order.
    pub datasets: Vec<DatasetResult>,
    /// One entry per iteration.
    pub summary: Vec<IterationSummary>,
}

/// Comparison dataset `index` of `cfg`, collected and laid out for its action encoding, refused
/// (naming `episodes`) when a network would have fewer than two rows: what [`run_dataset`] learns
/// from, and what a comparison's work is counted against ([`crate::work`]).
pub fn encoded_dataset(cfg: &RunConfig, index: usize) -> Result<(Dataset, Encoded)> {
    let env = cfg.env.env();
    let data = dataset::make(env, cfg.data.as_ref(), cfg.episodes, cfg.seed, dataset::Role::Compare, index)?;
    let enc = Encoded::new(&data, env.actions(), cfg.actions).map_err(|e| match e {
        crate::error::Error::Data(m) => match &cfg.data {
            Some(logged) => logged.too_few(dataset::Role::Compare, index, cfg.episodes, &m),
            None => crate::error::Error::invalid("episodes", cfg.episodes, format!("too few for dataset {index}: {m}")),
        },
        other => other,
    })?;
    if matches!(cfg.learner, LearnerConfig::Mlp(_)) {
        // Each network holds out a validation tail: it needs two rows (validation_fraction ≤ 0.5).
        if let Some(rows) = (0..enc.n_models()).map(|j| enc.model_rows(j).1.len()).find(|&r| r < 2) {
            if let Some(logged) = &cfg.data {
                let why = format!("a network gets only {rows} transition(s)");
                return Err(logged.too_few(dataset::Role::Compare, index, cfg.episodes, &why));
            }
            return Err(crate::error::Error::invalid(
                "episodes",
                cfg.episodes,
                format!(
                    "gives dataset {index} only {rows} transition(s) for a network, which needs 2; use more episodes"
                ),
            ));
        }
    }
    Ok((data, enc))
}

/// Runs the configured algorithm on dataset `index` (collecting it first).
pub fn run_dataset(cfg: &RunConfig, index: usize, progress: impl FnMut(&IterationRecord)) -> Result<DatasetResult> {
    run_dataset_saving(cfg, index, None, progress)
}

/// [`run_dataset`], also writing the last Q-function to `models/dataset-<index>.model` when
/// `models` is given (not for a diverged dataset).
pub fn run_dataset_saving(
    cfg: &RunConfig,
    index: usize,
    models: Option<&Path>,
    progress: impl FnMut(&IterationRecord),
) -> Result<DatasetResult> {
    let env = cfg.env.env();
    let (data, enc) = encoded_dataset(cfg, index)?;
    let fit_seed = rng::derive(cfg.seed, rng::purpose::FIT, &[index as u64]);
    let eval_seed = eval_seed(cfg.seed, index);
    let (record, q) =
        model::run_keeping(env, &data, &enc, &cfg.learner, cfg.settings(), fit_seed, eval_seed, progress)?;
    if let (Some(dir), Some(q)) = (models, q) {
        let (tool_version, commit) = model::build_stamp();
        let info = ModelInfo {
            tool_version,
            commit,
            source: "run".into(),
            spec_hash: cfg.hash(),
            env: cfg.env.clone(),
            algorithm: cfg.algorithm,
            learner: cfg.learner.clone(),
            encoding: cfg.actions,
            actions: env.actions().to_vec(),
            iterations: cfg.iterations,
            dataset: index,
            eval_seed,
            score: record.final_score(),
        };
        model::save(&model_path(dir, index), &Model { info, q })?;
    }
    let network_rows = matches!(cfg.learner, LearnerConfig::Mlp(_)).then(|| crate::ga::units::network_rows(&enc));
    Ok(DatasetResult { dataset: index, transitions: data.len(), record, network_rows, spec_hash: None, checksum: None })
}

/// Where `run --save-model DIR` writes dataset `index`'s Q-function.
pub fn model_path(dir: &Path, index: usize) -> PathBuf {
    dir.join(format!("dataset-{index}.model"))
}

/// Runs every dataset of `cfg` in parallel. `progress(dataset, record)` is called after each
/// iteration of each dataset (from worker threads).
pub fn run(cfg: &RunConfig, progress: &(dyn Fn(usize, &IterationRecord) + Sync)) -> Result<RunReport> {
    run_saving(cfg, None, progress)
}

/// [`run`], also saving each dataset's last Q-function into `models` (see [`run_dataset_saving`]).
pub fn run_saving(
    cfg: &RunConfig,
    models: Option<&Path>,
    progress: &(dyn Fn(usize, &IterationRecord) + Sync),
) -> Result<RunReport> {
    cfg.validate()?;
    let datasets: Vec<DatasetResult> = (0..cfg.datasets)
        .into_par_iter()
        .map(|i| run_dataset_saving(cfg, i, models, |r| progress(i, r)))
        .collect::<Result<_>>()?;
    let summary = summarize_iterations(&datasets, cfg.iterations);
    Ok(RunReport { config: cfg.clone(), datasets, summary })
}

/// Per-iteration statistics over datasets.
pub fn summarize_iterations(datasets: &[DatasetResult], iterations: usize) -> Vec<IterationSummary> {
    (1..=iterations)
        .map(|k| {
            let at: Vec<&IterationRecord> =
                datasets.iter().filter_map(|d| d.record.iterations.iter().find(|r| r.iteration == k)).collect();
            let pick = |f: fn(&IterationRecord) -> Option<f64>| -> Option<Summary> {
                summarize(&at.iter().filter_map(|r| f(r)).collect::<Vec<_>>())
            };
            IterationSummary {
                iteration: k,
                score: pick(|r| r.score),
                steps: pick(|r| r.steps),
                bellman_residual: pick(|r| Some(r.bellman_residual)),
                diverged: datasets
                    .iter()
                    .filter(|d| d.record.diverged.as_ref().is_some_and(|v| v.iteration <= k))
                    .count(),
            }
        })
        .collect()
}

impl RunReport {
    /// The per-dataset, per-iteration records as CSV rows (with a header). A dataset that
    /// diverged has a last row at the iteration it diverged, with only `diverged` set (its reason),
    /// so every dataset appears even when it diverged at the first iteration.
    pub fn csv(&self) -> String {
        let mut s = String::from(
            "dataset,iteration,score,steps,bellman_residual,epochs,fit_seconds,predict_seconds,eval_seconds,diverged\n",
        );
        let opt = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:?}"));
        for d in &self.datasets {
            for r in &d.record.iterations {
                s.push_str(&format!(
                    "{},{},{},{},{:?},{},{:?},{:?},{:?},\n",
                    d.dataset,
                    r.iteration,
                    opt(r.score),
                    opt(r.steps),
                    r.bellman_residual,
                    r.epochs.map_or(String::new(), |e| e.to_string()),
                    r.fit_seconds,
                    r.predict_seconds,
                    r.eval_seconds
                ));
            }
            if let Some(div) = &d.record.diverged {
                s.push_str(&format!("{},{},,,,,,,,{}\n", d.dataset, div.iteration, div.reason));
            }
        }
        s
    }

    /// A readable per-iteration table: mean ± 95 % interval over datasets.
    pub fn table(&self) -> String {
        let mut s = format!(
            "{:>5}  {:>22}  {:>20}  {:>12}  {:>8}\n",
            "iter", "score (mean ± 95%)", "steps (mean ± 95%)", "residual", "diverged"
        );
        let pm = |v: &Option<Summary>, prec: usize| {
            v.map_or("—".to_string(), |x| format!("{:.prec$} ± {:.prec$}", x.mean, x.ci95, prec = prec))
        };
        for it in &self.summary {
            if it.score.is_none() && it.iteration != self.config.iterations {
                continue;
            }
            s.push_str(&format!(
                "{:>5}  {:>22}  {:>20}  {:>12}  {:>8}\n",
                it.iteration,
                pm(&it.score, 4),
                pm(&it.steps, 1),
                it.bellman_residual.map_or("—".into(), |r| format!("{:.5}", r.mean)),
                it.diverged
            ));
        }
        s
    }
}
