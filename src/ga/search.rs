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

use super::chromosome::{Chromosome, Decoded, decode};
use super::operators::{initial_population, next_generation, rank};
use crate::dataset::{self, Dataset, dataset_seed};
use crate::error::{Error, Result};
use crate::exec::Executor;
use crate::fqi::{Divergence, Fqi, FqiSettings};
use crate::learn::actions::Encoded;
use crate::learn::mlp::MlpParams;
use crate::progress::{Progress, human};
use crate::report::plot::FitnessRow;
use crate::report::stats::summarize;
use crate::rng;
use crate::spec::Spec;
use crate::store::{self, RunLock, read_json, write_atomic, write_json};
use crate::tuned::TunedConfig;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
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
}

/// One FQI run of a chromosome on a search dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitResult {
    /// The genes.
    pub chromosome: Chromosome,
    /// Search dataset index.
    pub dataset: usize,
    /// Score of the greedy policy after the last iteration; `None` if the run diverged.
    pub score: Option<f64>,
    /// Steps survived in that evaluation.
    pub steps: Option<f64>,
    /// Set when the run diverged.
    pub diverged: Option<Divergence>,
    /// Epochs run over all iterations and networks.
    pub epochs: usize,
    /// Wall-clock seconds (not part of any comparison).
    pub seconds: f64,
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

/// The unit id (result file stem) of a chromosome on a dataset, e.g. `0_58_2_60_2.d3`.
pub fn unit_id(c: &Chromosome, dataset: usize) -> String {
    let genes: Vec<String> = c.iter().map(i64::to_string).collect();
    format!("{}.d{dataset}", genes.join("_"))
}

/// Parses a unit id back into (chromosome, dataset).
pub fn parse_unit_id(id: &str) -> Option<(Chromosome, usize)> {
    let (genes, d) = id.rsplit_once(".d")?;
    let v: Vec<i64> = genes.split('_').map(str::parse).collect::<std::result::Result<_, _>>().ok()?;
    Some((v.try_into().ok()?, d.parse().ok()?))
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
    /// Score per search dataset (`null` = diverged).
    pub scores: Vec<Option<f64>>,
    /// Mean score, `null` when any dataset diverged (fitness −∞).
    pub fitness: Option<f64>,
    /// How it came about: `initial`, `elite` or `child`.
    pub origin: String,
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
}

/// How a search ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// All done (generations reached, or stalled).
    Finished(String),
    /// Stopped early (Ctrl-C, time budget); resumable.
    Interrupted(String),
}

/// Evaluates units of one search: datasets are collected lazily and shared.
pub struct Evaluator {
    spec: Spec,
    dir: PathBuf,
    data: Mutex<HashMap<usize, Arc<(Dataset, Encoded)>>>,
}

impl Evaluator {
    /// An evaluator for the search in `dir` with resolved `spec`.
    pub fn new(spec: Spec, dir: &Path) -> Self {
        Evaluator { spec, dir: dir.to_path_buf(), data: Mutex::new(HashMap::new()) }
    }

    fn dataset(&self, d: usize) -> Result<Arc<(Dataset, Encoded)>> {
        if let Some(x) = self.data.lock().expect("dataset cache").get(&d) {
            return Ok(x.clone());
        }
        let env = self.spec.env.env();
        let s = &self.spec.search;
        let data = dataset::collect(env, s.episodes, dataset_seed(self.spec.seed, "search", d))?;
        let enc = Encoded::new(&data, env.actions(), s.actions)?;
        let x = Arc::new((data, enc));
        self.data.lock().expect("dataset cache").insert(d, x.clone());
        Ok(x)
    }

    /// The network a chromosome stands for.
    pub fn network(&self, c: &Chromosome) -> MlpParams {
        let d = decode(c, &self.spec.search.genes);
        MlpParams {
            activation: d.activation,
            delta_min: d.delta_min,
            patience: d.patience,
            ..self.spec.search.network.clone()
        }
    }

    /// Runs FQI for chromosome `c` on search dataset `d`: a pure function of (spec, c, d).
    pub fn evaluate(&self, c: &Chromosome, d: usize) -> Result<UnitResult> {
        let t = Instant::now();
        let x = self.dataset(d)?;
        let (data, enc) = (&x.0, &x.1);
        let s = &self.spec.search;
        let params = self.network(c);
        // Only the last iteration's score counts for fitness.
        let settings = FqiSettings { algorithm: s.algorithm, iterations: s.iterations, eval_every: s.iterations };
        let mut idx: Vec<u64> = c.iter().map(|&g| g as u64).collect();
        idx.push(d as u64);
        let fit_seed = rng::derive(self.spec.seed, "init", &idx);
        let eval_seed = rng::derive(self.spec.seed, "eval/search", &[d as u64]);
        let rec = Fqi::new(self.spec.env.env(), data, enc, &params, settings, fit_seed, eval_seed).run(|_| {})?;
        let last = rec.iterations.last();
        Ok(UnitResult {
            chromosome: *c,
            dataset: d,
            score: rec.final_score(),
            steps: if rec.diverged.is_some() { None } else { last.and_then(|r| r.steps) },
            diverged: rec.diverged.clone(),
            epochs: rec.iterations.iter().filter_map(|r| r.epochs).sum(),
            seconds: t.elapsed().as_secs_f64(),
        })
    }

    /// Where a unit's result is stored.
    pub fn unit_path(&self, id: &str) -> PathBuf {
        self.dir.join("units").join(format!("{id}.json"))
    }

    /// Computes a unit and stores it atomically.
    pub fn run_unit(&self, id: &str) -> Result<()> {
        let (c, d) = parse_unit_id(id).ok_or_else(|| Error::invalid("unit", id, "must look like 0_58_2_60_2.d3"))?;
        let r = self.evaluate(&c, d)?;
        if let Some(div) = &r.diverged {
            eprintln!("note: unit {id} diverged at iteration {} ({}): fitness −∞", div.iteration, div.reason);
        }
        write_json(&self.unit_path(id), &r)
    }

    /// Reads a stored unit, if present and whole.
    pub fn load_unit(&self, id: &str) -> Option<UnitResult> {
        read_json(&self.unit_path(id)).ok()
    }
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
    let (mut value, origin) = Spec::resolve_value(spec_name)?;
    let mut applied = Vec::new();
    for p in presets {
        let (patch, from) = crate::spec::load_preset(p)?;
        crate::spec::merge_patch(&mut value, &patch);
        applied.push(from.display().to_string());
    }
    let mut overrides = BTreeMap::new();
    let mut set = |field: &str, path: &[&str], v: Option<serde_json::Value>| {
        if let Some(v) = v {
            let mut slot = &mut value;
            for key in path {
                slot = &mut slot[*key];
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
    let spec = Spec::from_value(value, &origin).map_err(|e| match e {
        Error::File { path, message } => {
            Error::File { path, message: format!("{message} (after presets and overrides)") }
        }
        other => other,
    })?;
    let env = spec.env.env().name().to_string();
    let dir = match out {
        Some(d) => {
            if d.join("spec.json").exists() {
                return Err(Error::File {
                    path: d.to_path_buf(),
                    message: format!("already holds a run: use --resume {}", d.display()),
                });
            }
            store::create_dir(d)?;
            d.to_path_buf()
        }
        None => store::new_run_dir(&results.join(&env), "search-")?,
    };
    let info = RunInfo {
        kind: "search".into(),
        env,
        spec_source: origin.display().to_string(),
        presets: applied,
        overrides,
        created: store::now_utc().1,
        version: env!("CARGO_PKG_VERSION").into(),
    };
    create(&dir, &spec, &info)?;
    Ok(dir)
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

fn record_for(index: usize, c: &Chromosome, ev: &Evaluator, origin: &str) -> Result<IndividualRecord> {
    let s = &ev.spec.search;
    let mut scores = Vec::with_capacity(s.datasets);
    for d in 0..s.datasets {
        let id = unit_id(c, d);
        let u = ev.load_unit(&id).ok_or_else(|| Error::File {
            path: ev.unit_path(&id),
            message: "missing unit result after evaluation".into(),
        })?;
        scores.push(u.score);
    }
    let f = fitness(&scores);
    Ok(IndividualRecord {
        index,
        genes: *c,
        decoded: decode(c, &s.genes),
        scores,
        fitness: finite(f),
        origin: origin.to_string(),
    })
}

fn stats(records: &[IndividualRecord]) -> GenerationStats {
    let f: Vec<f64> = records.iter().filter_map(|r| r.fitness).collect();
    let s = summarize(&f);
    GenerationStats {
        min: f.iter().copied().reduce(f64::min),
        mean: s.map(|s| s.mean),
        max: f.iter().copied().reduce(f64::max),
        std: s.map(|s| s.std),
        diverged: records.len() - f.len(),
    }
}

fn describe(d: &Decoded) -> String {
    format!(
        "{} δ_min {} patience {}",
        serde_json::to_value(d.activation).unwrap_or_default().as_str().unwrap_or("?"),
        d.delta_min,
        d.patience
    )
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
        network: ev.network(&best.genes),
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
    }
}

fn write_state(
    dir: &Path,
    state: &str,
    generation: usize,
    spec: &Spec,
    best: Option<&IndividualRecord>,
    reason: &str,
) -> Result<()> {
    write_json(
        &dir.join("state.json"),
        &RunState {
            state: state.into(),
            generation,
            generations: spec.search.stop.generations,
            best_fitness: best.and_then(|b| b.fitness),
            best: best.map(|b| b.decoded),
            reason: reason.into(),
            updated: store::now_utc().1,
        },
    )
}

/// Runs (or resumes) the search in `dir`. Unit results already stored are reused.
pub fn run(dir: &Path, exec: &dyn Executor, controls: &Controls<'_>) -> Result<Ending> {
    let spec = load_spec(dir)?;
    let _lock = RunLock::acquire(dir)?;
    let ev = Evaluator::new(spec.clone(), dir);
    // Fail early on a dataset that cannot be encoded (e.g. per_action on continuous actions).
    ev.dataset(0)?;
    let s = &spec.search;
    let progress = Progress::new("generations", s.stop.generations as u64, controls.quiet);
    progress.line(&format!("search {} → {}", spec.env.env().name(), dir.display()));
    let started = Instant::now();
    let budget_hit = AtomicBool::new(false);
    let stop = AtomicBool::new(false);

    let mut population = initial_population(spec.seed, &s.genes, s.ga.population);
    let mut origins = vec!["initial"; population.len()];
    let mut records: Vec<GenerationRecord> = Vec::new();
    let mut best: Option<(IndividualRecord, usize)> = None;
    let mut hall: Vec<(IndividualRecord, usize)> = Vec::new();
    let mut stall = 0usize;
    write_state(dir, "running", 0, &spec, None, "")?;

    for g in 0..s.stop.generations {
        // Each distinct chromosome once; stored units are not recomputed.
        let mut ids = Vec::new();
        for (i, c) in population.iter().enumerate() {
            if population[..i].contains(c) {
                continue;
            }
            for d in 0..s.datasets {
                let id = unit_id(c, d);
                if !ev.unit_path(&id).is_file() {
                    ids.push(id);
                }
            }
        }
        progress.start_stage(&format!("gen {}", g + 1), ids.len() as u64);
        // Checked here too, for executors that do not call `work` (Slurm runs units elsewhere).
        if controls.max_hours.is_some_and(|h| started.elapsed().as_secs_f64() > h * 3600.0) {
            budget_hit.store(true, Ordering::SeqCst);
            stop.store(true, Ordering::SeqCst);
        }
        let work = |id: &str| -> Result<()> {
            if controls.max_hours.is_some_and(|h| started.elapsed().as_secs_f64() > h * 3600.0) {
                budget_hit.store(true, Ordering::SeqCst);
                stop.store(true, Ordering::SeqCst);
                return Ok(());
            }
            if controls.interrupt.load(Ordering::SeqCst) {
                stop.store(true, Ordering::SeqCst);
                return Ok(());
            }
            ev.run_unit(id)
        };
        exec.run(&ids, &work, &|| progress.unit_done(), &stop)?;
        let missing = ids.iter().any(|id| !ev.unit_path(id).is_file());
        if stop.load(Ordering::SeqCst) || controls.interrupt.load(Ordering::SeqCst) || missing {
            let reason = if budget_hit.load(Ordering::SeqCst) {
                format!("time budget of {} h reached", controls.max_hours.unwrap_or(0.0))
            } else if controls.interrupt.load(Ordering::SeqCst) {
                "interrupted".to_string()
            } else {
                "units missing after evaluation".to_string()
            };
            progress.finish();
            write_state(dir, "interrupted", g, &spec, best.as_ref().map(|b| &b.0), &reason)?;
            return Ok(Ending::Interrupted(reason));
        }

        let individuals: Vec<IndividualRecord> =
            population.iter().enumerate().map(|(i, c)| record_for(i, c, &ev, origins[i])).collect::<Result<_>>()?;
        let fit: Vec<f64> = individuals.iter().map(|r| r.fitness.unwrap_or(f64::NEG_INFINITY)).collect();
        let top = &individuals[rank(&fit)[0]];
        let improved = match &best {
            None => true,
            Some((b, _)) => fit[top.index] > b.fitness.unwrap_or(f64::NEG_INFINITY),
        };
        if improved {
            best = Some((top.clone(), g));
            stall = 0;
        } else {
            stall += 1;
        }
        for r in &individuals {
            if !hall.iter().any(|(h, _)| h.genes == r.genes) {
                hall.push((r.clone(), g));
            }
        }
        // Best first; ties keep the earlier discovery first (stable sort).
        hall.sort_by(|a, b| {
            b.0.fitness.unwrap_or(f64::NEG_INFINITY).total_cmp(&a.0.fitness.unwrap_or(f64::NEG_INFINITY))
        });
        hall.truncate(10);
        let (b, bg) = best.clone().expect("set above");
        let st = stats(&individuals);
        records.push(GenerationRecord {
            generation: g,
            individuals,
            stats: st.clone(),
            best_so_far: b.clone(),
            best_generation: bg,
        });

        write_outputs(dir, &spec, &records, &hall, &b, bg, &ev)?;
        write_state(dir, "running", g + 1, &spec, Some(&b), "")?;
        progress.stage_done();
        progress.line(&format!(
            "gen {}/{}: best {} mean {} ({} diverged) | best so far {} → fitness {} (gen {}) | {}",
            g + 1,
            s.stop.generations,
            fmt(st.max),
            fmt(st.mean),
            st.diverged,
            describe(&b.decoded),
            fmt(b.fitness),
            bg + 1,
            human(progress.elapsed())
        ));

        if let Some(limit) = s.stop.stall_generations.filter(|&l| stall >= l) {
            progress.finish();
            let reason = format!("no improvement for {limit} generations");
            write_state(dir, "finished", g + 1, &spec, Some(&b), &reason)?;
            return Ok(Ending::Finished(reason));
        }
        if g + 1 < s.stop.generations {
            let (next, _) = next_generation(spec.seed, g, &population, &fit, &s.genes, &s.ga);
            let elites = s.ga.n_elites();
            origins = (0..next.len()).map(|i| if i < elites { "elite" } else { "child" }).collect();
            population = next;
        }
    }
    progress.finish();
    let reason = format!("{} generations", s.stop.generations);
    write_state(dir, "finished", s.stop.generations, &spec, best.as_ref().map(|b| &b.0), &reason)?;
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
    write_json(&dir.join("best.json"), &tuned(spec, best, best_generation, ev))?;
    let rows = fitness_rows(records);
    write_fitness_csv(dir, &rows)?;
    crate::report::plot::fitness(dir, spec.env.env().name(), &rows)
}

/// Regenerates `fitness.csv`, `fitness.png`, `fitness.svg` and `report.md` of a search from its
/// `generations.jsonl`, without recomputing. Returns the number of generations.
pub fn report(dir: &Path) -> Result<usize> {
    let spec = load_spec(dir)?;
    let path = dir.join("generations.jsonl");
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let records: Vec<GenerationRecord> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            serde_json::from_str(l)
                .map_err(|e| Error::File { path: path.clone(), message: format!("line {}: {e}", i + 1) })
        })
        .collect::<Result<_>>()?;
    let rows = fitness_rows(&records);
    write_fitness_csv(dir, &rows)?;
    crate::report::plot::fitness(dir, spec.env.env().name(), &rows)?;
    let mut md = format!("# GA search — {}\n\n", spec.env.env().name());
    md.push_str(&format!(
        "Population {}, {} search datasets × {} episodes, K = {}, master seed {}.\n\n",
        spec.search.ga.population, spec.search.datasets, spec.search.episodes, spec.search.iterations, spec.seed
    ));
    md.push_str("| generation | best | mean | diverged | best so far | settings |\n|---|---|---|---|---|---|\n");
    for r in &records {
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            r.generation + 1,
            fmt(r.stats.max),
            fmt(r.stats.mean),
            r.stats.diverged,
            fmt(r.best_so_far.fitness),
            describe(&r.best_so_far.decoded)
        ));
    }
    md.push_str("\n![fitness per generation](fitness.png)\n");
    write_atomic(&dir.join("report.md"), |w| std::io::Write::write_all(w, md.as_bytes()))?;
    Ok(records.len())
}

fn fitness_rows(records: &[GenerationRecord]) -> Vec<FitnessRow> {
    records
        .iter()
        .map(|r| FitnessRow {
            generation: r.generation + 1,
            best: r.stats.max,
            mean: r.stats.mean,
            best_so_far: r.best_so_far.fitness,
        })
        .collect()
}

fn write_fitness_csv(dir: &Path, rows: &[FitnessRow]) -> Result<()> {
    let mut csv = String::from("generation,best,mean,best_so_far\n");
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:?}"));
    for r in rows {
        csv.push_str(&format!("{},{},{},{}\n", r.generation, o(r.best), o(r.mean), o(r.best_so_far)));
    }
    write_atomic(&dir.join("fitness.csv"), |w| std::io::Write::write_all(w, csv.as_bytes()))
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
}

impl Reproduction {
    /// True when every score matches bit for bit.
    pub fn matches(&self) -> bool {
        self.differences.is_empty() && self.recorded.map(f64::to_bits) == self.derived.map(f64::to_bits)
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
    let ev = Evaluator::new(spec.clone(), Path::new("."));
    let scores: Vec<Option<f64>> =
        (0..spec.search.datasets).into_par_iter().map(|d| ev.evaluate(c, d).map(|u| u.score)).collect::<Result<_>>()?;
    let differences = scores
        .iter()
        .enumerate()
        .filter(|(d, s)| t.scores.get(*d).copied().flatten().map(f64::to_bits) != s.map(f64::to_bits))
        .map(|(d, s)| (d, t.scores.get(d).copied().flatten(), *s))
        .collect();
    Ok(Reproduction { recorded: t.fitness, derived: finite(fitness(&scores)), differences })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_ids_round_trip() {
        for (c, d) in [([0, 58, 2, 60, 2], 3), ([2, 10, 15, 99, -1], 11)] {
            assert_eq!(parse_unit_id(&unit_id(&c, d)), Some((c, d)));
        }
        assert_eq!(parse_unit_id("junk"), None);
    }

    #[test]
    fn fitness_is_the_mean_or_minus_infinity() {
        assert_eq!(fitness(&[Some(1.0), Some(3.0)]), 2.0);
        assert_eq!(fitness(&[Some(1.0), None]), f64::NEG_INFINITY);
    }
}
