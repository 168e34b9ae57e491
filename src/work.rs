//! The work a run did, counted from its records so that it does not depend on the machine.
//!
//! A unit's seconds depend on the CPU it ran on (the same units took 6–10× longer on an AVX2-only
//! VM than on an AVX-512 one); its epochs do not. So the work of a search, a comparison or a batch
//! is counted from its stored units:
//! - **epoch-rows**: every network fit's epochs times the rows it was fitted on (training and
//!   validation rows: one per transition of the FQI dataset, or of its action with `per_action`),
//!   summed over the networks of each FQI iteration, the iterations and the units;
//! - **FLOPs**: the same epochs times [`EpochWork::flops`] of the network's shape on those rows, the
//!   count `bench search` measures its GFLOP/s with;
//! - **reference hours**: those FLOPs at the rates `bench search` measured on a named reference
//!   machine (`searches/reference-machine.json`, built in), each activation at its own rate.
//!
//! Rows per network are in the unit records (`rows`, `network_rows`). Reading a run counts from its
//! units and `work.json` alone: it never collects a dataset, so it never starts a gymnasium worker
//! or Python for Minari and never needs the run's data file. Units written before the rows were
//! recorded are counted by [`Counting::Collect`] (`bfqi-ga work DIR --write`), which collects their
//! datasets again (a pure function of the spec) and records the count in `work.json`; reading
//! trusts that record while its `sources` fingerprint matches the run's files.
//! Extra-Trees units run no epochs: they are counted apart (`tree_units`), with no FLOPs.

use crate::compare::Comparison;
use crate::error::{Error, Result};
use crate::experiment::encoded_dataset;
use crate::fqi::IterationRecord;
use crate::ga::units::{Evaluator, Role, activation_name, unit_id};
use crate::learn::LearnerConfig;
use crate::learn::actions::ActionEncoding;
use crate::learn::mlp::{Activation, EpochWork, Shape, split_rows};
use crate::store::read_json;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

/// The reference machine's figures, as committed in `searches/reference-machine.json`.
const REFERENCE_JSON: &str = include_str!("../searches/reference-machine.json");

/// A machine on which `bench search` measured how fast the search networks train.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Reference {
    /// Its name in reports: `AVX-512 Xeon VM, 2 cores`.
    pub name: String,
    /// The CPU and kernel level.
    pub cpu: String,
    /// Cores a run uses side by side (one unit per core).
    pub cores: usize,
    /// One core's FP32 FMA peak, GFLOP/s.
    pub peak_gflops_per_core: f64,
    /// Per environment (`other` for the rest), per activation: the epoch's FLOPs per second as a
    /// percentage of the peak.
    pub percent_of_peak: BTreeMap<String, BTreeMap<String, f64>>,
    /// Where the figures come from.
    pub source: String,
}

impl Reference {
    /// The committed reference machine.
    pub fn committed() -> Result<Reference> {
        serde_json::from_str(REFERENCE_JSON)
            .map_err(|e| Error::Data(format!("searches/reference-machine.json (built in): {e}")))
    }

    /// FLOPs per second one core of it trains `env`'s networks with activation `a` at.
    pub fn flops_per_second(&self, env: &str, a: Activation) -> Result<f64> {
        let table = self.percent_of_peak.get(env).or_else(|| self.percent_of_peak.get("other"));
        let pct = table.and_then(|t| t.get(activation_name(a))).copied().ok_or_else(|| {
            Error::Data(format!(
                "searches/reference-machine.json (built in): percent_of_peak has no {} figure for {env} or other",
                activation_name(a)
            ))
        })?;
        Ok(self.peak_gflops_per_core * 1e9 * pct / 100.0)
    }
}

/// The work of a run, from its records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Work {
    /// What was counted: `search` (search and validation units), `comparison` or `batch` (the sum
    /// of its jobs).
    pub kind: String,
    /// Network units counted (FQI runs of a network learner).
    pub units: usize,
    /// Extra-Trees units: no epochs, so no epoch-rows or FLOPs; counted apart.
    pub tree_units: usize,
    /// Network epochs, summed over fits, iterations and units.
    pub epochs: u64,
    /// Epochs × the rows of each fit.
    pub epoch_rows: u64,
    /// FLOPs of those epochs, counted as `bench search` counts them.
    pub flops: f64,
    /// The reference machine's name.
    pub reference: String,
    /// Hours the FLOPs take on the reference machine, on all its cores.
    pub reference_hours: f64,
    /// Wall-clock seconds the run's records give (a search's generations, a batch's jobs); `None`
    /// when it records none (comparisons).
    pub wall_seconds: Option<f64>,
    /// The units' own recorded seconds, summed (machine-dependent, and not wall time when units
    /// ran side by side).
    pub unit_seconds: f64,
    /// The machines its invocations ran on, as run.json records them.
    pub machines: Vec<String>,
    /// [`fingerprint`] of the files it was counted from: while they are unchanged, `work.json`
    /// is the run's work. (Absent in records written before it was recorded.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sources: Option<String>,
}

/// How units that do not record the rows their networks were fitted on are counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Counting {
    /// Not at all: reading a run never collects a dataset (a gymnasium worker, Python for Minari,
    /// a data file, or seconds of simulation); such a run's work is "not counted", naming why.
    Recorded,
    /// By collecting their datasets again: `bfqi-ga work --write`, and a run's own report.
    Collect,
}

impl Work {
    /// A short line for `status`: `work 1.23e9 epoch-rows, 4.5 PFLOP ≈ 2.1 h on <reference>`.
    pub fn short(&self) -> String {
        let trees = if self.tree_units > 0 { format!(" + {} tree units", self.tree_units) } else { String::new() };
        format!(
            "work {} epoch-rows, {} ≈ {:.2} h on {}{trees}",
            si(self.epoch_rows as f64, ""),
            si(self.flops, "FLOP"),
            self.reference_hours,
            self.reference
        )
    }

    /// The figures, one per line, for `bfqi-ga work`.
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![
            format!("{} units with networks, {} Extra-Trees units (no epochs)", self.units, self.tree_units),
            format!("epochs       {}", self.epochs),
            format!("epoch-rows   {} ({})", self.epoch_rows, si(self.epoch_rows as f64, "")),
            format!("FLOPs        {:.4e} ({})", self.flops, si(self.flops, "FLOP")),
            format!("reference    {:.2} h on {}", self.reference_hours, self.reference),
        ];
        let on = crate::machine::wall_suffix(&self.machines);
        out.push(match self.wall_seconds {
            Some(w) => format!("wall time    {} ({:.2} h){on}", crate::progress::human(w), w / 3600.0),
            None => format!("wall time    not recorded{on}"),
        });
        out.push(format!(
            "unit time    {} (the units' own seconds, summed)",
            crate::progress::human(self.unit_seconds)
        ));
        out
    }

    fn add(&mut self, other: &Work) {
        self.units += other.units;
        self.tree_units += other.tree_units;
        self.epochs += other.epochs;
        self.epoch_rows += other.epoch_rows;
        self.flops += other.flops;
        self.reference_hours += other.reference_hours;
        self.unit_seconds += other.unit_seconds;
        self.wall_seconds = match (self.wall_seconds, other.wall_seconds) {
            (Some(a), Some(b)) => Some(a + b),
            (a, b) => a.or(b),
        };
        self.machines = crate::machine::distinct(self.machines.iter().chain(&other.machines).cloned());
    }
}

/// `x` with an SI prefix: `4.52 P` + unit.
fn si(x: f64, unit: &str) -> String {
    let prefixes = [(1e18, "E"), (1e15, "P"), (1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k")];
    match prefixes.iter().find(|(p, _)| x >= *p) {
        Some((p, name)) => format!("{:.2} {name}{unit}", x / p),
        None if unit.is_empty() => format!("{x:.0}"),
        None => format!("{x:.0} {unit}"),
    }
}

/// Work being counted: FLOPs kept per activation, to be priced at their own rates.
#[derive(Debug, Default)]
struct Tally {
    units: usize,
    tree_units: usize,
    epochs: u64,
    epoch_rows: u64,
    flops: [f64; 3],
    unit_seconds: f64,
}

fn activation_index(a: Activation) -> usize {
    match a {
        Activation::Sigmoid => 0,
        Activation::Tanh => 1,
        Activation::Relu => 2,
    }
}

impl Tally {
    /// One network fit of `epochs` epochs on `rows` rows (its last `validation_fraction` held out).
    fn fit(&mut self, shape: &Shape, rows: usize, validation_fraction: f64, epochs: usize) {
        let (t, v) = split_rows(rows, validation_fraction);
        self.epochs += epochs as u64;
        self.epoch_rows += (epochs * rows) as u64;
        self.flops[activation_index(shape.activation())] += epochs as f64 * EpochWork::new(shape, t, v).flops();
    }

    /// The iterations of one unit whose networks (`n_inputs` inputs, `hidden`, `a`) were fitted on
    /// `rows` (one entry per network of an iteration).
    fn iterations(&mut self, its: &[IterationRecord], net: (usize, &[usize], Activation, f64), rows: &[usize]) {
        let (n_inputs, hidden, a, vf) = net;
        let shape = Shape::new(n_inputs, hidden, a);
        for it in its {
            if it.networks.len() == rows.len() {
                for (fi, &r) in it.networks.iter().zip(rows) {
                    self.fit(&shape, r, vf, fi.epochs);
                }
            } else if let Some(e) = it.epochs {
                // Units written before each network's epochs were recorded: the mean network's rows.
                let mean = rows.iter().sum::<usize>() / rows.len().max(1);
                self.fit(&shape, mean, vf, e);
            }
        }
    }

    fn finish(self, kind: &str, env: &str, wall_seconds: Option<f64>, machines: Vec<String>) -> Result<Work> {
        let r = Reference::committed()?;
        let mut core_seconds = 0.0;
        for a in [Activation::Sigmoid, Activation::Tanh, Activation::Relu] {
            let f = self.flops[activation_index(a)];
            if f > 0.0 {
                core_seconds += f / r.flops_per_second(env, a)?;
            }
        }
        Ok(Work {
            kind: kind.into(),
            units: self.units,
            tree_units: self.tree_units,
            epochs: self.epochs,
            epoch_rows: self.epoch_rows,
            flops: self.flops.iter().sum(),
            reference: r.name.clone(),
            reference_hours: core_seconds / r.cores.max(1) as f64 / 3600.0,
            wall_seconds,
            unit_seconds: self.unit_seconds,
            machines,
            sources: None,
        })
    }
}

/// The work of the run in `dir`: a search (its search and validation units), a comparison (its
/// units) or a batch (the sum of its jobs that have a run directory), with the [`fingerprint`] of
/// what it was counted from.
pub fn of_run(dir: &Path, counting: Counting) -> Result<Work> {
    let sources = fingerprint(dir)?;
    // Told apart by their defining files here rather than by `runs`, which shows this in `status`.
    let w = if dir.join("plan.json").is_file() && dir.join("batch.json").is_file() {
        of_batch(dir, counting)
    } else if dir.join("compare.json").is_file() {
        of_comparison(dir, counting)
    } else if dir.join("spec.json").is_file() {
        of_search(dir, counting)
    } else {
        Err(not_a_run(dir))
    }?;
    Ok(Work { sources: Some(sources), ..w })
}

fn not_a_run(dir: &Path) -> Error {
    Error::File {
        path: dir.to_path_buf(),
        message: "not a comparison, search or batch directory (no compare.json or spec.json, nor plan.json)".into(),
    }
}

/// The record files a run's work is counted from, beside its unit folders.
const RECORDS: [&str; 8] = [
    "spec.json",
    "state.json",
    "run.json",
    "validation.json",
    "compare.json",
    "batch.json",
    "plan.json",
    "generations.jsonl",
];

/// A fingerprint of what the run in `dir`'s work is counted from: its record files' bytes and its
/// units' names and sizes (a batch: its jobs' fingerprints too). Content, not modification times,
/// which a clone or a copy does not keep. Reads only small files (each at most
/// [`crate::store::RECORD_BYTES`]) and lists the unit folders.
pub fn fingerprint(dir: &Path) -> Result<String> {
    let mut h = Vec::new();
    for f in RECORDS {
        let p = dir.join(f);
        match crate::store::read_checked(&p, crate::store::RECORD_BYTES) {
            Ok(bytes) => {
                h.extend_from_slice(f.as_bytes());
                h.extend_from_slice(&crate::store::fnv1a(&bytes).to_le_bytes());
            }
            Err(crate::store::Refused::Missing) => {}
            Err(r) => return Err(r.at(&p)),
        }
    }
    for folder in ["units", "validation"] {
        let Ok(entries) = std::fs::read_dir(dir.join(folder)) else { continue };
        let mut files: Vec<(String, u64)> = entries
            .filter_map(|e| e.ok())
            .map(|e| (e.file_name().to_string_lossy().into_owned(), e.metadata().map_or(0, |m| m.len())))
            .collect();
        files.sort_unstable();
        for (name, len) in files {
            h.extend_from_slice(format!("{folder}/{name}:{len}\n").as_bytes());
        }
    }
    if dir.join("plan.json").is_file() && dir.join("batch.json").is_file() {
        let jobs: Vec<serde_json::Value> = read_json(&dir.join("batch.json"))?;
        for job in batch_jobs(dir, &jobs) {
            h.extend_from_slice(fingerprint(&job)?.as_bytes());
        }
    }
    Ok(format!("{:016x}", crate::store::fnv1a(&h)))
}

/// The work of the run in `dir` as its `work.json` records it while the files it was counted from
/// are unchanged ([`fingerprint`]), else counted from the units ([`Counting::Recorded`]: no
/// dataset is collected). What `status`, `work`, the dashboard and a batch's summary read.
pub fn cached(dir: &Path) -> Result<Work> {
    match recorded(dir) {
        Some(w) => Ok(w),
        None => of_run(dir, Counting::Recorded),
    }
}

/// The run's `work.json`, if it was counted from the files the run holds now.
fn recorded(dir: &Path) -> Option<Work> {
    let w = read_json::<Work>(&dir.join("work.json")).ok()?;
    (w.sources.is_some() && w.sources == fingerprint(dir).ok()).then_some(w)
}

/// Writes the work of the run in `dir` to its `work.json`, beside its report (whose report.md it
/// leaves as it was: committed reports rebuild byte for byte), counted from the units
/// ([`Counting::Recorded`]). A run whose work cannot be counted is said on stderr and keeps its
/// report: the work is a record about the run, not a result of it.
pub fn write(dir: &Path) -> Result<()> {
    match record(dir, Counting::Recorded) {
        Ok(_) => Ok(()),
        Err(e) => {
            eprintln!("warning: {}: its work is not counted: {e}", dir.display());
            Ok(())
        }
    }
}

/// The work of the run in `dir`, recorded in its `work.json`: the record itself while current, else
/// counted and written (`bfqi-ga work --write` counts with [`Counting::Collect`]).
pub fn record(dir: &Path, counting: Counting) -> Result<Work> {
    if let Some(w) = recorded(dir) {
        return Ok(w);
    }
    let w = of_run(dir, counting)?;
    crate::store::write_json(&dir.join("work.json"), &w)?;
    Ok(w)
}

/// The unit ids a search used in one folder, and where the runs it took units from keep theirs.
type Used = (HashSet<String>, Vec<std::path::PathBuf>);

/// The units a search took with `--units-from` count only where it used them: the units its
/// generations scored and its validation read, per folder (`units`, `validation`). `None` when it
/// took none, so that every stored unit counts.
fn taken_but_used(dir: &Path) -> Result<Option<[Used; 2]>> {
    let info: crate::ga::records::RunInfo = read_json(&dir.join("run.json"))?;
    if info.units_from.is_empty() {
        return Ok(None);
    }
    let (mut search, mut validation) = (HashSet::new(), HashSet::new());
    if dir.join("generations.jsonl").is_file() {
        for g in crate::ga::records::read_generations(dir)? {
            for i in g.individuals {
                search.extend((0..i.scores.len()).map(|k| unit_id(&i.decoded, k)));
            }
        }
    }
    if let Some(v) = crate::ga::validate::load(dir) {
        for e in v.entries {
            search.extend((0..e.search_scores.len()).map(|k| unit_id(&e.decoded, k)));
            validation.extend((0..e.validation_scores.len()).map(|k| unit_id(&e.decoded, k)));
        }
    }
    let sources = |folder: &str| info.units_from.iter().map(|s| Path::new(&s.dir).join(folder)).collect();
    Ok(Some([(search, sources("units")), (validation, sources("validation"))]))
}

/// A search's work: every stored unit that verifies, of the search datasets and of validation;
/// of the units taken from another run (`--units-from`), those the search used.
pub fn of_search(dir: &Path, counting: Counting) -> Result<Work> {
    let spec = crate::ga::setup::load_spec(dir)?;
    let net = &spec.search.network;
    let n_inputs = spec.env.env().obs_dim() + usize::from(spec.search.actions == ActionEncoding::Input);
    let mut t = Tally::default();
    let taken = taken_but_used(dir)?;
    for (r, role) in [Role::Search, Role::Validation].into_iter().enumerate() {
        let ev = Evaluator::with_role(spec.clone(), dir, role);
        // A unit the search used counts; so does one it computed itself (stored, and not in a run
        // it took units from), though no record names it yet (a generation in progress).
        let counts = |id: &String| {
            taken.as_ref().is_none_or(|t| {
                let (used, sources) = &t[r];
                used.contains(id) || !sources.iter().any(|s| s.join(format!("{id}.json")).is_file())
            })
        };
        // A unit that does not verify is computed again on resume: not this run's work yet.
        let confinement = crate::store::confinement();
        let units: Vec<_> = crate::run_dir::Units::store(&ev)
            .ids()
            .par_iter()
            .filter(|id| counts(id))
            .filter_map(|id| crate::store::confined(confinement.clone(), || ev.verified(id).ok().flatten()))
            .collect();
        let mut datasets: Vec<usize> = units.iter().filter(|u| u.rows.is_none()).map(|u| u.dataset).collect();
        datasets.sort_unstable();
        datasets.dedup();
        if counting == Counting::Recorded && !datasets.is_empty() {
            return Err(uncounted(dir, datasets.len(), role.name()));
        }
        let rows: HashMap<usize, Vec<usize>> =
            datasets.par_iter().map(|&d| Ok((d, ev.network_rows(d)?.0))).collect::<Result<_>>()?;
        for u in &units {
            let r = u.rows.as_ref().unwrap_or_else(|| &rows[&u.dataset]);
            t.units += 1;
            t.unit_seconds += u.seconds;
            t.iterations(&u.iterations, (n_inputs, &net.hidden, u.setting.activation, net.validation_fraction), r);
        }
    }
    let wall = read_json::<crate::ga::records::RunState>(&dir.join("state.json")).ok().map(|s| s.elapsed());
    t.finish("search", spec.env.env().name(), wall, crate::machine::of_run(dir))
}

/// Work that reading a run does not count: units that predate recorded rows.
fn uncounted(dir: &Path, datasets: usize, what: &str) -> Error {
    Error::File {
        path: dir.to_path_buf(),
        message: format!(
            "work not counted: units of {datasets} {what} dataset(s) predate recorded rows, and reading a run \
             never collects its datasets (no simulator, worker or data file is touched); \
             `bfqi-ga work {} --write` counts them once, collecting those datasets, and records it in work.json",
            dir.display()
        ),
    }
}

/// A comparison's work: every stored unit that verifies.
pub fn of_comparison(dir: &Path, counting: Counting) -> Result<Work> {
    let c = Comparison::open(dir)?;
    let cfg = c.config();
    let mut t = Tally::default();
    let mut rows: HashMap<String, (Vec<usize>, usize)> = HashMap::new();
    let units = c.verified_units();
    if counting == Counting::Recorded {
        // With `input` one network learns every transition; `per_action` splits them by action,
        // which only the rows the unit records (or its dataset) tell.
        let unknown = units
            .iter()
            .filter(|rec| {
                let rc = cfg.run_config(&rec.unit);
                matches!(rc.learner, LearnerConfig::Mlp(_))
                    && rec.result.network_rows.is_none()
                    && rc.actions != ActionEncoding::Input
            })
            .map(|rec| (rec.unit.episodes, rec.unit.dataset))
            .collect::<HashSet<_>>();
        if !unknown.is_empty() {
            return Err(uncounted(dir, unknown.len(), "comparison"));
        }
    }
    let inputs = cfg.env.env().obs_dim();
    for rec in units {
        let rc = cfg.run_config(&rec.unit);
        let its = &rec.result.record.iterations;
        t.unit_seconds += its.iter().map(|i| i.fit_seconds + i.predict_seconds + i.eval_seconds).sum::<f64>();
        let LearnerConfig::Mlp(p) = &rc.learner else {
            t.tree_units += 1;
            continue;
        };
        // Datasets depend on size, index and encoding only: complexities share them.
        let key = format!("{}.{}.{:?}", rc.episodes, rec.unit.dataset, rc.actions);
        if let Some(r) = &rec.result.network_rows {
            rows.insert(key.clone(), (r.clone(), inputs + usize::from(rc.actions == ActionEncoding::Input)));
        } else if rc.actions == ActionEncoding::Input && !rows.contains_key(&key) {
            rows.insert(key.clone(), (vec![rec.result.transitions], inputs + 1));
        } else if !rows.contains_key(&key) {
            let (_, enc) = encoded_dataset(&rc, rec.unit.dataset)?;
            let r = (0..enc.n_models()).map(|j| enc.model_rows(j).1.len()).collect();
            rows.insert(key.clone(), (r, enc.n_inputs()));
        }
        let (r, n_inputs) = &rows[&key];
        t.units += 1;
        t.iterations(its, (*n_inputs, &p.hidden, p.activation, p.validation_fraction), r);
    }
    t.finish("comparison", cfg.env.env().name(), None, crate::machine::of_run(dir))
}

/// A batch's work: the sum of its jobs' (those with a run directory), and as wall time the jobs'
/// seconds batch.json records.
pub fn of_batch(dir: &Path, counting: Counting) -> Result<Work> {
    // batch.json's jobs, read for their directory and seconds only (the batch module shows this).
    let jobs: Vec<serde_json::Value> = read_json(&dir.join("batch.json"))?;
    let mut total = Tally::default().finish("batch", "other", None, Vec::new())?;
    for job in batch_jobs(dir, &jobs) {
        // A job's own work.json stands for it while current.
        let w = match (counting, recorded(&job)) {
            (_, Some(w)) => w,
            (Counting::Recorded, None) => of_run(&job, counting)?,
            (Counting::Collect, None) => {
                let w = of_run(&job, counting)?;
                // Counted at a cost: recorded beside the job as its report would.
                crate::store::write_json(&job.join("work.json"), &w)?;
                w
            }
        };
        total.add(&Work { wall_seconds: None, ..w });
    }
    total.wall_seconds = Some(jobs.iter().filter_map(|j| j["seconds"].as_f64()).sum());
    Ok(total)
}

/// The run directories of a batch's `jobs` (batch.json's, those that have one), in order.
fn batch_jobs(dir: &Path, jobs: &[serde_json::Value]) -> Vec<std::path::PathBuf> {
    jobs.iter()
        .map(|j| dir.join(j["dir"].as_str().unwrap_or_default()))
        .filter(|job| *job != dir && (job.join("compare.json").is_file() || job.join("spec.json").is_file()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::{FitInfo, StopReason};

    #[test]
    fn an_epoch_of_a_tiny_network_counts_its_flops_by_hand() {
        // 2 inputs → 3 ReLU units → 1 output, 4 training rows and 1 validation row (20 % held out).
        let shape = Shape::new(2, &[3], Activation::Relu);
        // Forward: 2·3 + 3·1 = 9 multiply-adds on all 5 rows; backward on the 4 training rows:
        // weight gradients 9, deltas of the hidden layer 3·1 = 3. Two FLOPs each: 2·(45 + 48) = 186.
        // ReLU: 3 units × (1 forward on 5 rows + 1 backward on 4 rows) = 27.
        let mut t = Tally::default();
        t.fit(&shape, 5, 0.2, 2);
        assert_eq!((t.epochs, t.epoch_rows), (2, 10));
        assert_eq!(t.flops, [0.0, 0.0, 2.0 * (186.0 + 27.0)]);
        // Sigmoid: 40 FLOPs forward and 3 backward per unit and row: 3 × (40·5 + 3·4) = 636.
        let mut s = Tally::default();
        s.fit(&Shape::new(2, &[3], Activation::Sigmoid), 5, 0.2, 1);
        assert_eq!(s.flops, [186.0 + 636.0, 0.0, 0.0]);
    }

    fn iteration(epochs: &[usize]) -> IterationRecord {
        IterationRecord {
            iteration: 1,
            score: None,
            steps: None,
            bellman_residual: 0.0,
            epochs: Some(epochs.iter().sum()),
            networks: epochs
                .iter()
                .map(|&e| FitInfo { epochs: e, stop: StopReason::EarlyStopping, train_loss: None, val_loss: None })
                .collect(),
            fit_seconds: 0.0,
            predict_seconds: 0.0,
            eval_seconds: 0.0,
        }
    }

    #[test]
    fn each_network_counts_its_own_rows_and_old_records_the_mean() {
        let mut t = Tally::default();
        t.iterations(&[iteration(&[3, 5]), iteration(&[1, 1])], (2, &[3], Activation::Tanh, 0.1), &[10, 30]);
        assert_eq!((t.epochs, t.epoch_rows), (10, 3 * 10 + 5 * 30 + 10 + 30));
        let mut old = iteration(&[3, 5]);
        old.networks.clear();
        let mut o = Tally::default();
        o.iterations(&[old], (2, &[3], Activation::Tanh, 0.1), &[10, 30]);
        assert_eq!((o.epochs, o.epoch_rows), (8, 8 * 20));
    }

    #[test]
    fn the_reference_machine_prices_each_activation_at_its_own_rate() {
        let r = Reference::committed().unwrap();
        assert_eq!(r.cores, 2);
        let relu = r.flops_per_second("cartpole", Activation::Relu).unwrap();
        assert!((relu - 218.6e9 * 0.28).abs() < 1.0, "{relu}");
        // An env without figures of its own takes `other`'s.
        let other = r.flops_per_second("Acrobot-v1", Activation::Tanh).unwrap();
        assert!((other - 218.6e9 * 0.42).abs() < 1.0, "{other}");
        let t = Tally { flops: [0.0, 0.0, relu * 3600.0 * 2.0], ..Default::default() };
        let w = t.finish("search", "cartpole", Some(60.0), Vec::new()).unwrap();
        assert!((w.reference_hours - 1.0).abs() < 1e-9, "{}", w.reference_hours);
        assert!(w.short().contains("1.00 h on AVX-512 Xeon VM, 2 cores"), "{}", w.short());
    }

    #[test]
    fn large_counts_read_with_si_prefixes() {
        assert_eq!(si(4.52e15, "FLOP"), "4.52 PFLOP");
        assert_eq!(si(1234.0, ""), "1.23 k");
        assert_eq!(si(12.0, ""), "12");
    }
}
