//! The genetic search (`bfqi-ga search`, SPEC §5): generations of chromosomes, each scored by FQI on
//! the search datasets, stored unit by unit in a run directory so that an interrupted search resumes
//! where it stopped and ends bit-identical to one never interrupted.
//!
//! Run directory layout:
//! - `run.json` — what was asked (spec source, presets, overrides) and `spec.json`, the resolved spec;
//! - `units/<genes>.d<i>.json` — one FQI run of a chromosome on a search dataset (written atomically);
//! - `generations.jsonl`, `hall_of_fame.json`, `best.json` (the tuned config), `fitness.csv`,
//!   `fitness.png`, `fitness.svg`, and `state.json` (running / finished / interrupted).
//!
//! A search is replayed from generation 0 on every start: chromosomes whose unit files exist are
//! read, not retrained, so resuming is just running again.

use super::chromosome::{Chromosome, Decoded, GeneRanges, decode};
use super::operators::{Birth, initial_population, next_generation, rank};
use super::prune;
pub use super::units::{Evaluator, UnitResult, parse_unit_id, unit_id};
use super::units::{activation_name, expected_cost, setting_id};
use crate::error::{Error, Result};
use crate::exec::Executor;
use crate::progress::{Progress, human};
use crate::report::stats::summarize;
use crate::spec::Spec;
use crate::store::{self, RunLock, read_json, write_atomic, write_json};
use crate::tuned::TunedConfig;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What was asked for, saved as `run.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// `search`.
    pub kind: String,
    /// Environment name.
    pub env: String,
    /// Where the spec came from.
    pub spec_source: String,
    /// Presets applied on top of it, in order.
    pub presets: Vec<String>,
    /// Command-line overrides, by spec field.
    pub overrides: BTreeMap<String, serde_json::Value>,
    /// When the run was created (UTC).
    pub created: String,
    /// bfqi-ga version that created it.
    pub version: String,
    /// The source commit it was built from (`+dirty` with uncommitted changes; `unknown` when
    /// built outside a git checkout).
    #[serde(default)]
    pub commit: String,
    /// Each later invocation that continued the run (`--resume`, or a batch resumed): when, and
    /// the commit of the binary, which may differ from `commit`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resumed: Vec<Resumed>,
    /// [`Spec::results_hash`] of `spec.json` when the run began (recorded at the first resume for
    /// runs created before it was): a resume refuses a spec.json changed since.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec_hash: Option<String>,
}

/// One invocation that continued a search, in `run.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Resumed {
    /// When it started (UTC).
    pub at: String,
    /// The source commit of its binary.
    pub commit: String,
}

/// Fitness from per-dataset scores: their mean, or −∞ if any run diverged.
pub fn fitness(scores: &[Option<f64>]) -> f64 {
    let mut sum = 0.0;
    for s in scores {
        match s {
            Some(v) => sum += v,
            None => return f64::NEG_INFINITY,
        }
    }
    sum / scores.len() as f64
}

fn finite(f: f64) -> Option<f64> {
    f.is_finite().then_some(f)
}

/// One individual of a generation, as logged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IndividualRecord {
    /// Position in the generation.
    pub index: usize,
    /// The genes.
    pub genes: Chromosome,
    /// What they decode to.
    #[serde(flatten)]
    pub decoded: Decoded,
    /// The result's name ([`setting_id`]): individuals with the same setting share one evaluation.
    pub setting: String,
    /// Other individuals of this generation that decode alike, and so share this result.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shares_with: Vec<usize>,
    /// Score per search dataset run (`null` = diverged); a pruned individual has fewer.
    pub scores: Vec<Option<f64>>,
    /// Mean score; `null` when any dataset diverged (fitness −∞) or when pruned.
    pub fitness: Option<f64>,
    /// Pruned (`search.prune`): its datasets stopped once their mean fell below the cutoff.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub pruned: bool,
    /// How it came about: `initial` (random), `seeded` (`--seed-config`), `elite` or `child`.
    pub origin: String,
    /// A child's parents (their positions in the previous generation), its genes after the
    /// interval crossover and before mutation, and whether it was mutated (thesis Appendix C).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub birth: Option<Birth>,
}

impl IndividualRecord {
    /// The fitness used for ranking: −∞ when diverged or pruned.
    pub fn rank_fitness(&self) -> f64 {
        self.fitness.unwrap_or(f64::NEG_INFINITY)
    }

    /// The mean of the scores run so far (a pruned individual's partial score).
    pub fn partial_mean(&self) -> Option<f64> {
        finite(fitness(&self.scores)).filter(|_| !self.scores.is_empty())
    }
}

/// Statistics of a generation's finite fitnesses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenerationStats {
    /// Lowest finite fitness.
    pub min: Option<f64>,
    /// Mean of the finite fitnesses.
    pub mean: Option<f64>,
    /// Highest fitness.
    pub max: Option<f64>,
    /// Population standard deviation of the finite fitnesses.
    pub std: Option<f64>,
    /// Individuals with fitness −∞ (a diverged run).
    pub diverged: usize,
    /// Individuals pruned (`search.prune`).
    #[serde(default)]
    pub pruned: usize,
}

/// One line of `generations.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenerationRecord {
    /// 0-based generation.
    pub generation: usize,
    /// Every individual.
    pub individuals: Vec<IndividualRecord>,
    /// Fitness statistics.
    pub stats: GenerationStats,
    /// Units (setting × dataset) this generation needed that no earlier generation had: the
    /// FQI runs it cost. Shared settings, elites and settings seen before cost nothing.
    #[serde(default)]
    pub new_units: usize,
    /// Pruning's cutoff for this generation (`search.prune`): the previous generation's
    /// parent-pool line minus the margin; absent when pruning is off or in generation 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prune_below: Option<f64>,
    /// Best individual so far (over all generations).
    pub best_so_far: IndividualRecord,
    /// Generation in which the best so far was found.
    pub best_generation: usize,
}

/// `state.json`: where a run stands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    /// `running`, `finished` or `interrupted`.
    pub state: String,
    /// Generations completed.
    pub generation: usize,
    /// Generations planned.
    pub generations: usize,
    /// Best fitness so far.
    pub best_fitness: Option<f64>,
    /// Best settings so far.
    pub best: Option<Decoded>,
    /// Why it stopped (empty while running).
    pub reason: String,
    /// Last update (UTC).
    pub updated: String,
    /// Wall-clock seconds of each completed generation (summed over invocations).
    #[serde(default)]
    pub generation_seconds: Vec<f64>,
    /// Seconds spent so far in the generation under way.
    #[serde(default)]
    pub current_seconds: f64,
    /// Units of the generation under way: computed, and to compute (an upper bound with pruning).
    #[serde(default)]
    pub units_done: usize,
    /// See `units_done`.
    #[serde(default)]
    pub units_total: usize,
    /// Projected seconds to the end of the search if it runs every planned generation (the stall
    /// rule may end it sooner), refined as units finish.
    #[serde(default)]
    pub eta_seconds: Option<f64>,
}

impl RunState {
    /// Wall-clock seconds the search has run, over all invocations.
    pub fn elapsed(&self) -> f64 {
        self.generation_seconds.iter().sum::<f64>() + self.current_seconds
    }
}

/// How a search ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// All done (generations reached, or stalled).
    Finished(String),
    /// Stopped early (Ctrl-C, time budget); resumable.
    Interrupted(String),
}

/// Stop controls of one invocation.
pub struct Controls<'a> {
    /// Raised by Ctrl-C.
    pub interrupt: &'a AtomicBool,
    /// Wall-clock budget of this invocation, in hours.
    pub max_hours: Option<f64>,
    /// Suppress progress output.
    pub quiet: bool,
}

/// Creates the run directory contents of a new search.
pub fn create(dir: &Path, spec: &Spec, info: &RunInfo) -> Result<()> {
    store::create_dir(&dir.join("units"))?;
    write_json(&dir.join("spec.json"), spec)?;
    write_json(&dir.join("run.json"), info)
}

/// Command-line (or batch-plan) overrides of a search spec.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchOverrides {
    /// `search.stop.generations`.
    pub generations: Option<usize>,
    /// `search.ga.population`.
    pub population: Option<usize>,
    /// `search.datasets`.
    pub datasets: Option<usize>,
    /// `search.iterations`.
    pub iterations: Option<usize>,
    /// `search.episodes`.
    pub episodes: Option<usize>,
    /// `seed`.
    pub seed: Option<u64>,
    /// `search.stop.stall_generations`.
    pub stall_generations: Option<usize>,
    /// Tuned configs (`thesis` or a best.json) whose settings become `search.seeded`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub seed_config: Vec<String>,
}

/// Resolves a spec (name or file), applies presets and overrides, validates it and creates the run
/// directory (`out`, or `<results>/<env>/search-<timestamp>`). Returns the directory.
pub fn prepare(
    spec_name: &str,
    presets: &[String],
    o: &SearchOverrides,
    out: Option<&Path>,
    results: &Path,
) -> Result<PathBuf> {
    let (spec, info) = resolve(spec_name, presets, o)?;
    let dir = store::claim_run_dir(out, "spec.json", "a run", &results.join(&info.env), "search-")?;
    create(&dir, &spec, &info)?;
    Ok(dir)
}

/// The spec and run record a search would start with, every layer validated, creating nothing
/// (what `prepare` and a batch plan's check before it runs use).
pub fn resolve(spec_name: &str, presets: &[String], o: &SearchOverrides) -> Result<(Spec, RunInfo)> {
    // Each layer is validated as written, so an error names the file that holds it: the spec
    // file alone, then after each preset (naming the preset), then after the flags.
    let (mut value, origin) = Spec::resolve_value(spec_name)?;
    Spec::from_value(value.clone(), &origin)?;
    let mut applied = Vec::new();
    for p in presets {
        let (patch, from) = crate::spec::load_preset(p)?;
        if !patch.is_object() {
            return Err(Error::File { path: from, message: "a preset must be a JSON object of spec fields".into() });
        }
        crate::spec::merge_patch(&mut value, &patch);
        Spec::from_value(value.clone(), &from).map_err(|e| match e {
            Error::File { path, message } => {
                Error::File { path, message: format!("{message} (applied to {})", origin.display()) }
            }
            other => other,
        })?;
        applied.push(from.display().to_string());
    }
    let mut overrides = BTreeMap::new();
    let mut set = |field: &str, path: &[&str], v: Option<serde_json::Value>| {
        if let Some(v) = v {
            // Objects on the path are created where a field was left to its default; the result is
            // validated below like everything else.
            let mut slot = &mut value;
            for key in path {
                if !slot.is_object() {
                    *slot = serde_json::Value::Object(Default::default());
                }
                let serde_json::Value::Object(m) = slot else { unreachable!("made an object above") };
                slot = m.entry(key.to_string()).or_insert(serde_json::Value::Null);
            }
            *slot = v.clone();
            overrides.insert(field.to_string(), v);
        }
    };
    use serde_json::json;
    set("generations", &["search", "stop", "generations"], o.generations.map(|v| json!(v)));
    set("population", &["search", "ga", "population"], o.population.map(|v| json!(v)));
    set("datasets", &["search", "datasets"], o.datasets.map(|v| json!(v)));
    set("iterations", &["search", "iterations"], o.iterations.map(|v| json!(v)));
    set("episodes", &["search", "episodes"], o.episodes.map(|v| json!(v)));
    set("seed", &["seed"], o.seed.map(|v| json!(v)));
    set("stall_generations", &["search", "stop", "stall_generations"], o.stall_generations.map(|v| json!(v)));
    let after = |e| match e {
        Error::File { path, message } => {
            Error::File { path, message: format!("{message} (after presets and overrides)") }
        }
        other => other,
    };
    let mut spec = Spec::from_value(value.clone(), &origin).map_err(after)?;
    let env = spec.env.env().name().to_string();
    if !o.seed_config.is_empty() {
        // Encoded on the gene grid of the spec as resolved, then validated with it.
        let seeded = seed_chromosomes(&o.seed_config, &env, &spec.search.genes)?;
        value["search"]["seeded"] = serde_json::json!(seeded);
        overrides.insert("seed_config".into(), serde_json::json!(o.seed_config));
        spec = Spec::from_value(value, &origin).map_err(after)?;
    }
    let info = RunInfo {
        kind: "search".into(),
        env,
        spec_source: origin.display().to_string(),
        presets: applied,
        overrides,
        created: store::now_utc().1,
        version: env!("CARGO_PKG_VERSION").into(),
        commit: env!("BFQI_GA_COMMIT").into(),
        resumed: Vec::new(),
        spec_hash: Some(spec.results_hash()),
    };
    Ok((spec, info))
}

/// The chromosomes of tuned configs (`thesis` or files) for `search.seeded`: each must be for
/// `env` and its setting must lie on the gene grid.
fn seed_chromosomes(names: &[String], env: &str, genes: &GeneRanges) -> Result<Vec<Chromosome>> {
    names
        .iter()
        .map(|name| {
            let (t, from) = TunedConfig::resolve(name, env)?;
            t.check_env(env, &from)?;
            let refuse = |message: String| Error::File { path: from.clone(), message };
            let setting = Decoded { activation: t.activation, delta_min: t.delta_min, patience: t.patience };
            super::chromosome::encode(&setting, genes).ok_or_else(|| {
                refuse(format!(
                    "its setting ({}) is not on this search's gene grid (search.genes), so it cannot join generation 0",
                    describe(&setting)
                ))
            })
        })
        .collect()
}

/// Changes the stop rules of an existing search before resuming it (they do not alter what was
/// computed, only how far it goes).
pub fn extend(dir: &Path, generations: Option<usize>, stall_generations: Option<usize>) -> Result<()> {
    let mut spec = load_spec(dir)?;
    if generations.is_none() && stall_generations.is_none() {
        return Ok(());
    }
    if let Some(g) = generations {
        spec.search.stop.generations = g;
    }
    if let Some(s) = stall_generations {
        spec.search.stop.stall_generations = Some(s);
    }
    spec.validate()?;
    write_json(&dir.join("spec.json"), &spec)
}

/// Loads the resolved spec of an existing search directory.
pub fn load_spec(dir: &Path) -> Result<Spec> {
    let path = dir.join("spec.json");
    if !path.is_file() {
        return Err(Error::File {
            path: dir.to_path_buf(),
            message: "not a search run directory (no spec.json)".into(),
        });
    }
    Spec::load(&path)
}

/// The stored scores of setting `s` on datasets `0..n`, as far as they run without a gap.
fn stored_scores(ev: &Evaluator, s: &Decoded, n: usize) -> Vec<Option<f64>> {
    (0..n).map_while(|d| ev.load_unit(&unit_id(s, d)).map(|u| u.score)).collect()
}

/// The record of individual `index`, from the stored scores of its setting.
fn record_for(
    index: usize,
    c: &Chromosome,
    ev: &Evaluator,
    origin: &str,
    birth: Option<Birth>,
    pruned: bool,
) -> Result<IndividualRecord> {
    let s = &ev.spec().search;
    let decoded = decode(c, &s.genes);
    let scores = stored_scores(ev, &decoded, s.datasets);
    let complete = scores.len() == s.datasets;
    if !complete && !pruned && !scores.contains(&None) {
        let id = unit_id(&decoded, scores.len());
        return Err(Error::File { path: ev.unit_path(&id), message: "missing unit result after evaluation".into() });
    }
    let f = if complete && !pruned { fitness(&scores) } else { f64::NEG_INFINITY };
    Ok(IndividualRecord {
        index,
        genes: *c,
        decoded,
        setting: setting_id(&decoded),
        shares_with: Vec::new(),
        scores,
        fitness: finite(f),
        pruned,
        origin: origin.to_string(),
        birth,
    })
}

fn stats(records: &[IndividualRecord]) -> GenerationStats {
    let f: Vec<f64> = records.iter().filter_map(|r| r.fitness).collect();
    let s = summarize(&f);
    let pruned = records.iter().filter(|r| r.pruned).count();
    GenerationStats {
        min: f.iter().copied().reduce(f64::min),
        mean: s.map(|s| s.mean),
        max: f.iter().copied().reduce(f64::max),
        std: s.map(|s| s.std),
        diverged: records.len() - f.len() - pruned,
        pruned,
    }
}

/// A setting for humans: `tanh δ_min 0.00059 patience 311`.
pub fn describe(d: &Decoded) -> String {
    format!("{} δ_min {} patience {}", activation_name(d.activation), d.delta_min, d.patience)
}

/// The tuned config of the best individual.
fn tuned(spec: &Spec, best: &IndividualRecord, generation: usize, ev: &Evaluator) -> TunedConfig {
    let s = &spec.search;
    TunedConfig {
        env: spec.env.env().name().to_string(),
        source: "search".into(),
        activation: best.decoded.activation,
        delta_min: best.decoded.delta_min,
        patience: best.decoded.patience,
        network: ev.network(&best.decoded),
        actions: s.actions,
        algorithm: s.algorithm,
        iterations: s.iterations,
        episodes: s.episodes,
        datasets: s.datasets,
        fitness: best.fitness,
        scores: best.scores.clone(),
        spec_hash: Some(spec.hash()),
        seed: spec.seed,
        generation: Some(generation),
        chromosome: Some(best.genes),
        spec: Some(spec.clone()),
        validation: None,
    }
}

/// Timing of the search across invocations, for `state.json`, the progress line and the ETA.
struct Clock {
    /// Completed generations' wall seconds (from earlier invocations too).
    generation_seconds: Vec<f64>,
    /// Seconds the current generation ran in earlier invocations.
    prior: f64,
    /// Start of the current generation in this invocation.
    since: Instant,
    /// Expected seconds of each unit of the current generation still to run, and of those done.
    expected: HashMap<String, f64>,
    done_expected: f64,
    total_expected: f64,
    done: usize,
    total: usize,
    last_write: Option<Instant>,
}

impl Clock {
    fn resume(dir: &Path) -> Clock {
        let st: Option<RunState> = read_json(&dir.join("state.json")).ok();
        let (generation_seconds, prior) = match st {
            Some(st) if st.generation_seconds.len() == st.generation => (st.generation_seconds, st.current_seconds),
            _ => (Vec::new(), 0.0),
        };
        Clock {
            generation_seconds,
            prior,
            since: Instant::now(),
            expected: HashMap::new(),
            done_expected: 0.0,
            total_expected: 0.0,
            done: 0,
            total: 0,
            last_write: None,
        }
    }

    /// Seconds of the current generation so far.
    fn current(&self) -> f64 {
        self.prior + self.since.elapsed().as_secs_f64()
    }

    /// Adds units to run in the current generation, with their expected seconds.
    fn plan(&mut self, units: &[(String, f64)]) {
        for (id, e) in units {
            self.expected.insert(id.clone(), *e);
            self.total_expected += e;
        }
        self.total += units.len();
    }

    fn unit_done(&mut self, id: &str) {
        self.done += 1;
        self.done_expected += self.expected.get(id).copied().unwrap_or(0.0);
    }

    /// Projected wall seconds of the current generation: what ran, plus what is left at the rate
    /// (expected seconds per second) measured in this invocation.
    fn projected_generation(&self) -> Option<f64> {
        let ran = self.since.elapsed().as_secs_f64();
        if self.done_expected <= 0.0 || ran <= 0.0 {
            return (self.total == 0).then(|| self.current());
        }
        let rate = self.done_expected / ran;
        Some(self.current() + (self.total_expected - self.done_expected).max(0.0) / rate)
    }

    /// Projected seconds to the end of generation `generations − 1`, from generation `g`.
    fn eta(&self, g: usize, generations: usize) -> Option<f64> {
        let this = self.projected_generation()?;
        let per = if self.generation_seconds.is_empty() {
            this
        } else {
            self.generation_seconds.iter().sum::<f64>() / self.generation_seconds.len() as f64
        };
        Some((this - self.current()).max(0.0) + per * generations.saturating_sub(g + 1) as f64)
    }

    /// Ends generation `g` and returns its wall seconds. A generation replayed from stored units
    /// keeps the time recorded when it ran, and the generation under way keeps its earlier time.
    fn finish_generation(&mut self, g: usize) -> f64 {
        if let Some(&recorded) = self.generation_seconds.get(g) {
            return recorded;
        }
        let secs = self.current();
        self.generation_seconds.push(secs);
        self.prior = 0.0;
        self.since = Instant::now();
        self.expected.clear();
        (self.done_expected, self.total_expected, self.done, self.total) = (0.0, 0.0, 0, 0);
        secs
    }
}

/// What `state.json` says besides the timing.
struct StateInfo<'a> {
    state: &'a str,
    generation: usize,
    best: Option<&'a IndividualRecord>,
    reason: &'a str,
}

fn write_state(dir: &Path, spec: &Spec, info: &StateInfo<'_>, clock: &Clock) -> Result<()> {
    let running = info.state == "running";
    write_json(
        &dir.join("state.json"),
        &RunState {
            state: info.state.into(),
            generation: info.generation,
            generations: spec.search.stop.generations,
            best_fitness: info.best.and_then(|b| b.fitness),
            best: info.best.map(|b| b.decoded),
            reason: info.reason.into(),
            updated: store::now_utc().1,
            generation_seconds: clock.generation_seconds.clone(),
            current_seconds: if info.generation < spec.search.stop.generations { clock.current() } else { 0.0 },
            units_done: clock.done,
            units_total: clock.total,
            eta_seconds: if running { clock.eta(info.generation, spec.search.stop.generations) } else { None },
        },
    )
}

/// Expected seconds of each unit: the mean of its setting's stored units where there are some,
/// else [`expected_cost`] scaled by the run's seconds per unit of cost so far.
fn expected_seconds(ev: &Evaluator, ids: &[(Decoded, usize)]) -> Vec<(String, f64)> {
    let s = &ev.spec().search;
    let mut known: HashMap<String, (f64, usize)> = HashMap::new();
    let mut ratios = Vec::new();
    let dir = ev.unit_path("x");
    if let Ok(entries) = std::fs::read_dir(dir.parent().expect("units folder")) {
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            let Some(id) = name.strip_suffix(".json") else { continue };
            let (Some((set, _)), Some(u)) = (parse_unit_id(id), ev.load_unit(id)) else { continue };
            let k = known.entry(setting_id(&set)).or_insert((0.0, 0));
            (k.0, k.1) = (k.0 + u.seconds, k.1 + 1);
            ratios.push(u.seconds / expected_cost(&set, s.network.max_epochs).max(1e-9));
        }
    }
    ratios.sort_by(f64::total_cmp);
    let per_cost = ratios.get(ratios.len() / 2).copied().unwrap_or(1.0);
    ids.iter()
        .map(|(set, d)| {
            let e = known
                .get(&setting_id(set))
                .map_or(expected_cost(set, s.network.max_epochs) * per_cost, |(t, n)| t / *n as f64);
            (unit_id(set, *d), e)
        })
        .collect()
}

/// Runs the units `want` that are not stored yet, longest expected first. Returns false when the
/// run must stop (interrupt, budget, or units missing afterwards), with the reason.
struct Runner<'a> {
    dir: &'a Path,
    spec: &'a Spec,
    ev: &'a Evaluator,
    exec: &'a dyn Executor,
    controls: &'a Controls<'a>,
    progress: &'a Progress,
    started: Instant,
    budget_hit: AtomicBool,
    stop: AtomicBool,
    clock: Mutex<Clock>,
}

impl Runner<'_> {
    fn over_budget(&self) -> bool {
        self.controls.max_hours.is_some_and(|h| self.started.elapsed().as_secs_f64() > h * 3600.0)
    }

    /// Evaluates the missing units among `want`; `Err(reason)` when the run has to stop.
    fn run(
        &self,
        g: usize,
        want: &[(Decoded, usize)],
        best: Option<&IndividualRecord>,
    ) -> Result<std::result::Result<(), String>> {
        let missing: Vec<(Decoded, usize)> =
            want.iter().copied().filter(|(s, d)| self.ev.load_unit(&unit_id(s, *d)).is_none()).collect();
        let mut planned = expected_seconds(self.ev, &missing);
        // Longest first (stable: ties keep setting and dataset order), so that the last units of a
        // generation are short and no core waits long for the others.
        planned.sort_by(|a, b| b.1.total_cmp(&a.1));
        self.clock.lock().expect("clock").plan(&planned);
        self.progress.add_to_stage(planned.len() as u64);
        let ids: Vec<String> = planned.into_iter().map(|(id, _)| id).collect();
        // Checked here too, for executors that do not call `work` (Slurm runs units elsewhere).
        if self.over_budget() {
            self.budget_hit.store(true, Ordering::SeqCst);
            self.stop.store(true, Ordering::SeqCst);
        }
        let work = |id: &str| -> Result<()> {
            if self.over_budget() {
                self.budget_hit.store(true, Ordering::SeqCst);
                self.stop.store(true, Ordering::SeqCst);
                return Ok(());
            }
            if self.controls.interrupt.load(Ordering::SeqCst) {
                self.stop.store(true, Ordering::SeqCst);
                return Ok(());
            }
            self.ev.run_unit(id)
        };
        let done = |id: &str| {
            let mut c = self.clock.lock().expect("clock");
            c.unit_done(id);
            let eta = c.eta(g, self.spec.search.stop.generations);
            let gen_left = c.projected_generation().map(|p| (p - c.current()).max(0.0));
            self.progress.unit_done(&format!(
                "gen ≈ {} left · search ≈ {} left",
                gen_left.map_or("?".into(), human),
                eta.map_or("?".into(), human)
            ));
            if c.last_write.is_none_or(|t| t.elapsed().as_secs_f64() > 5.0) {
                c.last_write = Some(Instant::now());
                let info = StateInfo { state: "running", generation: g, best, reason: "" };
                let _ = write_state(self.dir, self.spec, &info, &c);
            }
        };
        self.exec.run(&ids, &work, &done, &self.stop)?;
        let missing = ids.iter().any(|id| self.ev.load_unit(id).is_none());
        if self.stop.load(Ordering::SeqCst) || self.controls.interrupt.load(Ordering::SeqCst) || missing {
            let reason = if self.budget_hit.load(Ordering::SeqCst) {
                format!("time budget of {} h reached", self.controls.max_hours.unwrap_or(0.0))
            } else if self.controls.interrupt.load(Ordering::SeqCst) {
                "interrupted".to_string()
            } else {
                "units missing after evaluation".to_string()
            };
            return Ok(Err(reason));
        }
        Ok(Ok(()))
    }
}

/// The seed of the GA's own streams (initial population, breeding): from the master seed and the
/// environment, so searches of different environments with one master seed draw different
/// populations.
pub fn ga_seed(spec: &Spec) -> u64 {
    crate::rng::derive(spec.seed, &crate::rng::purpose::ga(spec.env.env().name()), &[])
}

/// Runs (or resumes) the search in `dir`. Unit results already stored are reused. A finished
/// search whose spec has `search.validate` then validates its winner ([`super::validate`]).
pub fn run(dir: &Path, exec: &dyn Executor, controls: &Controls<'_>) -> Result<Ending> {
    let spec = load_spec(dir)?;
    let lock = RunLock::acquire(dir)?;
    let path = dir.join("run.json");
    let mut info: RunInfo = read_json(&path)?;
    let hash = spec.results_hash();
    match &info.spec_hash {
        Some(h) if *h != hash => {
            return Err(Error::File {
                path: dir.join("spec.json"),
                message: format!(
                    "changed since the run began (results hash {hash}, run.json records {h}): resuming would mix \
                     results of two specs; restore it or start a new run"
                ),
            });
        }
        _ => {}
    }
    if dir.join("state.json").is_file() {
        // A run that began before: say which binary continues it.
        info.resumed.push(Resumed { at: store::now_utc().1, commit: env!("BFQI_GA_COMMIT").into() });
        info.spec_hash = Some(hash);
        write_json(&path, &info)?;
    }
    // What a kill can leave: a deleted units/ is made again, and temporary files of interrupted
    // atomic writes are removed (the lock is ours, so no writer is alive).
    store::create_dir(&dir.join("units"))?;
    store::remove_temporaries(dir)?;
    store::remove_temporaries(&dir.join("units"))?;
    let ending = run_generations(dir, &spec, exec, controls)?;
    if matches!(ending, Ending::Finished(_)) {
        let state: RunState = read_json(&dir.join("state.json"))?;
        if state.best_fitness.is_none() {
            // Every individual scored −∞: the records say so, and the command fails (exit 1).
            return Err(Error::Failed(format!(
                "{}: every setting diverged on some dataset (fitness −∞ throughout): no tuned config; \
                 see the units' `diverged` reasons",
                dir.display()
            )));
        }
    }
    if let (Ending::Finished(_), Some(rule)) = (&ending, &spec.search.validate) {
        let v = super::validate::run(dir, rule, controls.quiet)?;
        if !controls.quiet {
            eprintln!("validation: {}", v.note);
        }
        crate::report::search::write(dir)?;
    }
    drop(lock);
    Ok(ending)
}

fn run_generations(dir: &Path, spec: &Spec, exec: &dyn Executor, controls: &Controls<'_>) -> Result<Ending> {
    let spec = spec.clone();
    let ev = Evaluator::new(spec.clone(), dir);
    // Fail early on a dataset that cannot be encoded (e.g. per_action on continuous actions).
    ev.dataset(0)?;
    let s = &spec.search;
    let progress = Progress::new("generations", s.stop.generations as u64, controls.quiet);
    progress.line(&format!("search {} → {}", spec.env.env().name(), dir.display()));
    let runner = Runner {
        dir,
        spec: &spec,
        ev: &ev,
        exec,
        controls,
        progress: &progress,
        started: Instant::now(),
        budget_hit: AtomicBool::new(false),
        stop: AtomicBool::new(false),
        clock: Mutex::new(Clock::resume(dir)),
    };

    let seed = ga_seed(&spec);
    let mut population = initial_population(seed, &s.genes, s.ga.population);
    let mut origins = vec!["initial"; population.len()];
    // Given configs take the first places; the other individuals keep their own random streams.
    for (i, c) in s.seeded.iter().enumerate() {
        population[i] = *c;
        origins[i] = "seeded";
    }
    let mut births: Vec<Option<Birth>> = vec![None; population.len()];
    let mut records: Vec<GenerationRecord> = Vec::new();
    let mut best: Option<(IndividualRecord, usize)> = None;
    let mut hall: Vec<(IndividualRecord, usize)> = Vec::new();
    let mut stall = 0usize;
    // Units needed by earlier generations, so each generation can say what it cost.
    let mut seen: HashSet<String> = HashSet::new();
    // Pruning's cutoff: the previous generation's parent-pool line, known before any unit of this
    // generation runs, so the decisions do not depend on thread count, order or executor.
    let mut prune_below: Option<f64> = None;
    {
        let c = runner.clock.lock().expect("clock");
        let info = StateInfo {
            state: "running",
            generation: c.generation_seconds.len().min(s.stop.generations),
            best: None,
            reason: "",
        };
        write_state(dir, &spec, &info, &c)?;
    }

    for g in 0..s.stop.generations {
        let settings: Vec<Decoded> = population.iter().map(|c| decode(c, &s.genes)).collect();
        // Each distinct setting once, in order of first appearance.
        let mut distinct: Vec<Decoded> = Vec::new();
        for d in &settings {
            if !distinct.iter().any(|x| setting_id(x) == setting_id(d)) {
                distinct.push(*d);
            }
        }
        progress.start_stage(&format!("gen {g}"), 0);
        let mut pruned: HashSet<String> = HashSet::new();
        let stopped = match prune_below.filter(|_| s.prune.enabled) {
            None => {
                let want: Vec<(Decoded, usize)> =
                    distinct.iter().flat_map(|x| (0..s.datasets).map(move |d| (*x, d))).collect();
                runner.run(g, &want, best.as_ref().map(|b| &b.0))?.err()
            }
            Some(cutoff) => {
                // Datasets in rounds: each round runs the next dataset of every setting still
                // open, then closes the settings whose mean so far is below the cutoff (pruned)
                // or that diverged (fitness −∞ whatever the rest).
                let mut open: Vec<Decoded> = distinct.clone();
                let mut stopped = None;
                for r in 0..s.datasets {
                    let want: Vec<(Decoded, usize)> = open.iter().map(|x| (*x, r)).collect();
                    if let Err(reason) = runner.run(g, &want, best.as_ref().map(|b| &b.0))? {
                        stopped = Some(reason);
                        break;
                    }
                    open.retain(|x| {
                        // Every score stored so far: a setting scored in full before is judged by
                        // its fitness, never pruned; one scored further in an earlier generation
                        // (or before an interruption) is judged on all it has, which gives the
                        // verdict the rounds would reach (they stop at the first mean below).
                        let sc = stored_scores(&ev, x, s.datasets);
                        match prune::decide(&sc, s.datasets, &s.prune, cutoff) {
                            prune::Verdict::Open => true,
                            prune::Verdict::Pruned => {
                                pruned.insert(setting_id(x));
                                false
                            }
                            prune::Verdict::Closed => false,
                        }
                    });
                }
                stopped
            }
        };
        if let Some(reason) = stopped {
            progress.finish();
            let c = runner.clock.lock().expect("clock");
            let info =
                StateInfo { state: "interrupted", generation: g, best: best.as_ref().map(|b| &b.0), reason: &reason };
            write_state(dir, &spec, &info, &c)?;
            return Ok(Ending::Interrupted(reason));
        }

        let mut individuals: Vec<IndividualRecord> = population
            .iter()
            .enumerate()
            .map(|(i, c)| record_for(i, c, &ev, origins[i], births[i], pruned.contains(&setting_id(&settings[i]))))
            .collect::<Result<_>>()?;
        for i in 0..individuals.len() {
            let key = individuals[i].setting.clone();
            individuals[i].shares_with =
                (0..individuals.len()).filter(|&j| j != i && individuals[j].setting == key).collect();
        }
        let mut new_units = 0;
        for x in &distinct {
            for d in 0..s.datasets {
                let id = unit_id(x, d);
                if ev.load_unit(&id).is_some() && seen.insert(id) {
                    new_units += 1;
                }
            }
        }
        let fit: Vec<f64> = individuals.iter().map(IndividualRecord::rank_fitness).collect();
        let eligible: Vec<bool> = individuals.iter().map(|r| !r.pruned).collect();
        let mut order: Vec<usize> = rank(&fit).into_iter().filter(|&i| eligible[i]).collect();
        if order.is_empty() {
            // Everyone pruned (possible only without elites): rank them all, as −∞.
            order = rank(&fit);
        }
        let top = &individuals[order[0]];
        let improved = match &best {
            None => true,
            Some((b, _)) => fit[top.index] > b.rank_fitness(),
        };
        if improved {
            best = Some((top.clone(), g));
            stall = 0;
        } else {
            stall += 1;
        }
        for r in individuals.iter().filter(|r| !r.pruned) {
            if !hall.iter().any(|(h, _)| h.setting == r.setting) {
                hall.push((r.clone(), g));
            }
        }
        // Best first; ties keep the earlier discovery first (stable sort).
        hall.sort_by(|a, b| b.0.rank_fitness().total_cmp(&a.0.rank_fitness()));
        hall.truncate(10);
        let (b, bg) = best.clone().expect("set above");
        let st = stats(&individuals);
        let this_cutoff = prune_below.filter(|_| s.prune.enabled);
        // The next generation's cutoff: this generation's parent-pool line (its worst parent).
        prune_below = order
            .get(s.ga.n_parents().min(order.len()) - 1)
            .map(|&i| fit[i] - s.prune.margin)
            .filter(|v| v.is_finite());
        records.push(GenerationRecord {
            generation: g,
            individuals,
            stats: st.clone(),
            new_units,
            prune_below: this_cutoff,
            best_so_far: b.clone(),
            best_generation: bg,
        });

        write_outputs(dir, &spec, &records, &hall, &b, bg, &ev)?;
        let (secs, ran, replayed) = {
            let mut c = runner.clock.lock().expect("clock");
            let (ran, replayed) = (c.done, g < c.generation_seconds.len());
            (c.finish_generation(g), ran, replayed)
        };
        let cost = if replayed {
            format!("replayed from stored units (ran in {})", human(secs))
        } else if secs > 0.0 && ran > 0 {
            format!("{ran} units in {} ({:.2} units/s)", human(secs), ran as f64 / secs)
        } else {
            format!("0 units in {} (nothing to run)", human(secs))
        };
        {
            let c = runner.clock.lock().expect("clock");
            write_state(
                dir,
                &spec,
                &StateInfo { state: "running", generation: g + 1, best: Some(&b), reason: "" },
                &c,
            )?;
        }
        progress.stage_done();
        progress.line(&format!(
            "gen {} ({} of {}): best {} mean {} ({} diverged{}) | {} | best so far {} → fitness {} (gen {}) | {}",
            g,
            g + 1,
            s.stop.generations,
            fmt(st.max),
            fmt(st.mean),
            st.diverged,
            if s.prune.enabled { format!(", {} pruned", st.pruned) } else { String::new() },
            cost,
            describe(&b.decoded),
            fmt(b.fitness),
            bg,
            human(progress.elapsed())
        ));

        if let Some(limit) = s.stop.stall_generations.filter(|&l| stall >= l) {
            progress.finish();
            let reason = format!("no improvement for {limit} generations");
            let c = runner.clock.lock().expect("clock");
            write_state(
                dir,
                &spec,
                &StateInfo { state: "finished", generation: g + 1, best: Some(&b), reason: &reason },
                &c,
            )?;
            return Ok(Ending::Finished(reason));
        }
        if g + 1 < s.stop.generations {
            let (next, born) = next_generation(seed, g, &population, &fit, &eligible, &s.genes, &s.ga);
            let elites = next.len() - born.len();
            origins = (0..next.len()).map(|i| if i < elites { "elite" } else { "child" }).collect();
            births = std::iter::repeat_n(None, elites).chain(born.into_iter().map(Some)).collect();
            population = next;
        }
    }
    progress.finish();
    let reason = format!("{} generations", s.stop.generations);
    let c = runner.clock.lock().expect("clock");
    let info = StateInfo {
        state: "finished",
        generation: s.stop.generations,
        best: best.as_ref().map(|b| &b.0),
        reason: &reason,
    };
    write_state(dir, &spec, &info, &c)?;
    Ok(Ending::Finished(reason))
}

fn fmt(v: Option<f64>) -> String {
    v.map_or("−∞".into(), |x| format!("{x:.4}"))
}

fn write_outputs(
    dir: &Path,
    spec: &Spec,
    records: &[GenerationRecord],
    hall: &[(IndividualRecord, usize)],
    best: &IndividualRecord,
    best_generation: usize,
    ev: &Evaluator,
) -> Result<()> {
    write_atomic(&dir.join("generations.jsonl"), |w| {
        for r in records {
            serde_json::to_writer(&mut *w, r)?;
            std::io::Write::write_all(w, b"\n")?;
        }
        Ok(())
    })?;
    let hof: Vec<serde_json::Value> = hall
        .iter()
        .map(|(r, g)| serde_json::json!({"generation": g, "genes": r.genes, "decoded": r.decoded, "fitness": r.fitness, "scores": r.scores}))
        .collect();
    write_json(&dir.join("hall_of_fame.json"), &hof)?;
    let mut t = tuned(spec, best, best_generation, ev);
    // Keep a validation of this same winner (a resumed or re-reported search).
    t.validation = super::validate::load(dir).and_then(|v| v.summary_of(&best.setting));
    write_json(&dir.join("best.json"), &t)?;
    crate::report::search::write_fitness(dir, spec, records)
}

/// The outcome of `reproduce`.
#[derive(Debug, Clone, PartialEq)]
pub struct Reproduction {
    /// Recorded fitness.
    pub recorded: Option<f64>,
    /// Re-derived fitness.
    pub derived: Option<f64>,
    /// Per dataset: (index, recorded, derived) where they differ.
    pub differences: Vec<(usize, Option<f64>, Option<f64>)>,
    /// Stored fields that disagree with what the spec and chromosome give (an edited best.json).
    pub mismatches: Vec<String>,
}

impl Reproduction {
    /// True when every score matches bit for bit.
    pub fn matches(&self) -> bool {
        self.differences.is_empty()
            && self.mismatches.is_empty()
            && self.recorded.map(f64::to_bits) == self.derived.map(f64::to_bits)
    }
}

/// Re-derives a tuned config's fitness from scratch (no stored unit is read).
pub fn reproduce(t: &TunedConfig, path: &Path) -> Result<Reproduction> {
    use rayon::prelude::*;
    let (Some(spec), Some(c)) = (&t.spec, &t.chromosome) else {
        return Err(Error::File {
            path: path.to_path_buf(),
            message: "has no spec or chromosome: only a search's best.json can be reproduced".into(),
        });
    };
    if let Some(h) = t.spec_hash.as_ref().filter(|h| **h != spec.hash()) {
        return Err(Error::File {
            path: path.to_path_buf(),
            message: format!("spec_hash {h} does not match its spec ({})", spec.hash()),
        });
    }
    if !spec.search.genes.contains(c) {
        return Err(Error::File {
            path: path.to_path_buf(),
            message: format!("chromosome {c:?} lies outside its spec's gene ranges {:?}", spec.search.genes.bounds()),
        });
    }
    let setting = decode(c, &spec.search.genes);
    let ev = Evaluator::new(spec.clone(), Path::new("."));
    // Every stored field must be what the spec and the chromosome give.
    let s = &spec.search;
    let mut mismatches = Vec::new();
    let mut differs = |field: &str, stored: String, derived: String| {
        if stored != derived {
            mismatches.push(format!("{field}: stored {stored}, the spec and chromosome give {derived}"));
        }
    };
    differs("activation", format!("{:?}", t.activation), format!("{:?}", setting.activation));
    differs("delta_min", format!("{:?}", t.delta_min), format!("{:?}", setting.delta_min));
    differs("patience", t.patience.to_string(), setting.patience.to_string());
    let network = |n: &crate::learn::mlp::MlpParams| serde_json::to_string(n).unwrap_or_default();
    differs("network", network(&t.network), network(&ev.network(&setting)));
    differs("algorithm", t.algorithm.name().into(), s.algorithm.name().into());
    differs("actions", format!("{:?}", t.actions), format!("{:?}", s.actions));
    differs("iterations", t.iterations.to_string(), s.iterations.to_string());
    differs("episodes", t.episodes.to_string(), s.episodes.to_string());
    differs("datasets", t.datasets.to_string(), s.datasets.to_string());
    differs("scores", format!("{} values", t.scores.len()), format!("{} values", s.datasets));
    differs("seed", t.seed.to_string(), spec.seed.to_string());
    let scores: Vec<Option<f64>> = (0..spec.search.datasets)
        .into_par_iter()
        .map(|d| ev.evaluate(&setting, d).map(|u| u.score))
        .collect::<Result<_>>()?;
    let differences = scores
        .iter()
        .enumerate()
        .filter(|(d, s)| t.scores.get(*d).copied().flatten().map(f64::to_bits) != s.map(f64::to_bits))
        .map(|(d, s)| (d, t.scores.get(d).copied().flatten(), *s))
        .collect();
    Ok(Reproduction { recorded: t.fitness, derived: finite(fitness(&scores)), differences, mismatches })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fitness_is_the_mean_or_minus_infinity() {
        assert_eq!(fitness(&[Some(1.0), Some(3.0)]), 2.0);
        assert_eq!(fitness(&[Some(1.0), None]), f64::NEG_INFINITY);
    }

    #[test]
    fn each_environment_draws_its_own_initial_population() {
        let pops: Vec<Vec<Chromosome>> = ["cartpole", "bicycle", "pendulum"]
            .iter()
            .map(|e| {
                let spec = Spec::resolve(e).unwrap().0;
                initial_population(ga_seed(&spec), &spec.search.genes, spec.search.ga.population)
            })
            .collect();
        assert_ne!(pops[0], pops[1]);
        assert_ne!(pops[0], pops[2]);
        assert_ne!(pops[1], pops[2]);
    }
}
