//! Comparison runs (`bfqi-ga compare`, thesis §4.5–4.7): FQI and B-FQI on the same comparison
//! datasets, with tuned settings, over iterations, complexities and dataset sizes.
//!
//! A unit is one (learner, algorithm, complexity, size, dataset) run, stored atomically in the run
//! directory's units ([`crate::run_dir`]); results are always read back from those files, so an
//! interrupted comparison resumes without redoing finished units, and `report` rebuilds every table
//! and plot without recomputing.

use crate::env::EnvConfig;
use crate::error::{Error, Result};
use crate::exec::Executor;
use crate::experiment::{DatasetResult, RunConfig, run_dataset};
use crate::fqi::Algorithm;
use crate::learn::LearnerConfig;
use crate::learn::actions::ActionEncoding;
use crate::learn::mlp::MlpParams;
use crate::progress::Progress;
use crate::report::claims::ClaimSpec;
use crate::run_dir::{Budget, Ending, Stop, UnitStore, Units};
use crate::spec::{LearnerKind, SampleSweep, Spec};
use crate::store::{self, RunLock, read_json, write_json};
use crate::tuned::TunedConfig;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

mod request;
mod status;
pub use request::{AnalysisChoice, LearnerChoice, Request, parse_complexities};
pub use status::status_line;

/// Which analyses to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Analysis {
    /// Score (and steps) against iterations at the preset complexity (thesis Figures 4.10–4.11).
    Iterations,
    /// Score against complexity × iteration (Figures 4.4–4.7).
    Complexity,
    /// Last-iteration score against dataset size (Figures 4.8–4.9).
    Samples,
}

impl Analysis {
    /// Its name, as `compare.json` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Analysis::Iterations => "iterations",
            Analysis::Complexity => "complexity",
            Analysis::Samples => "samples",
        }
    }
}

/// One learner's part of a comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LearnerPlan {
    /// `et` or `mlp`.
    pub name: String,
    /// The learner at its preset complexity (for networks, the tuned network).
    pub learner: LearnerConfig,
    /// Action encoding.
    pub actions: ActionEncoding,
    /// K.
    pub iterations: usize,
    /// Datasets of the iterations and complexity analyses.
    pub datasets: usize,
    /// Episodes per dataset (iterations and complexity analyses).
    pub episodes: usize,
    /// Complexities of the complexity analysis.
    pub complexities: Vec<usize>,
    /// The sample analysis.
    pub samples: Option<SampleSweep>,
    /// The thesis claims its report checks (from the spec's preset).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub claims: Vec<ClaimSpec>,
}

/// Everything that determines a comparison (saved as `compare.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompareConfig {
    /// The environment.
    pub env: EnvConfig,
    /// Master seed.
    pub seed: u64,
    /// Analyses to run.
    pub analyses: Vec<Analysis>,
    /// Per learner.
    pub learners: Vec<LearnerPlan>,
    /// The tuned config the networks use.
    pub tuned: TunedConfig,
    /// The spec's logged data, when it learns from some instead of collecting datasets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<crate::dataset::DataSource>,
}

/// The network of a preset with a tuned config's activation and early stopping.
fn tuned_network(base: &MlpParams, t: &TunedConfig, keep_hidden: bool) -> MlpParams {
    MlpParams {
        hidden: if keep_hidden { base.hidden.clone() } else { t.network.hidden.clone() },
        activation: t.activation,
        delta_min: t.delta_min,
        patience: t.patience,
        ..t.network.clone()
    }
}

impl CompareConfig {
    /// Builds a comparison from a spec, a tuned config and flags.
    pub fn new(
        spec: &Spec,
        tuned: TunedConfig,
        analyses: Vec<Analysis>,
        learners: &[LearnerKind],
        o: &Request,
    ) -> Result<Self> {
        if tuned.env != spec.env.env().name() {
            return Err(Error::invalid(
                "tuned.env",
                &tuned.env,
                format!("must be {} (the environment compared)", spec.env.env().name()),
            ));
        }
        let mut plans = Vec::new();
        for &kind in learners {
            let (p, name) = (spec.preset(kind), kind.name());
            let learner = match &p.learner {
                // The iterations analysis uses the tuned network ([10, 10] in the thesis's bicycle runs).
                LearnerConfig::Mlp(base) => LearnerConfig::Mlp(tuned_network(base, &tuned, false)),
                other => other.clone(),
            };
            let mut plan = LearnerPlan {
                name: name.to_string(),
                learner,
                actions: p.actions,
                iterations: o.iterations.unwrap_or(p.iterations),
                datasets: o.datasets.unwrap_or(p.datasets),
                episodes: o.episodes.unwrap_or(p.episodes),
                complexities: o.complexities.clone().unwrap_or_else(|| p.complexities.clone()),
                samples: p.samples.clone(),
                claims: p.claims.clone(),
            };
            if let Some(s) = &mut plan.samples {
                if let Some(sizes) = &o.sizes {
                    s.sizes = sizes.clone();
                }
                if let Some(d) = o.datasets {
                    s.datasets = d;
                }
            }
            if analyses.contains(&Analysis::Complexity) && plan.complexities.is_empty() {
                return Err(Error::invalid(
                    format!("experiments.{name}.complexities"),
                    "[]",
                    "the complexity analysis needs complexities (the spec or --complexities)",
                ));
            }
            if analyses.contains(&Analysis::Samples) && plan.samples.is_none() {
                return Err(Error::invalid(
                    format!("experiments.{name}.samples"),
                    "null",
                    "the sample analysis needs a samples section in the spec",
                ));
            }
            plans.push(plan);
        }
        let data = spec.data.clone();
        let c = CompareConfig { env: spec.env.clone(), seed: spec.seed, analyses, learners: plans, tuned, data };
        c.validate()?;
        Ok(c)
    }

    /// The hash of everything in `compare.json` that determines a unit's result (all but the
    /// claims, which decide how the report reads them), recorded in `run.json`.
    pub fn results_hash(&self) -> String {
        let mut c = self.clone();
        for p in &mut c.learners {
            p.claims.clear();
        }
        store::json_hash(&c)
    }

    fn validate(&self) -> Result<()> {
        for u in self.units() {
            self.run_config(&u).validate()?;
        }
        Ok(())
    }

    /// The learner of a plan at a complexity (`None` = the plan's own).
    fn learner_at(&self, plan: &LearnerPlan, complexity: Option<usize>) -> LearnerConfig {
        match complexity {
            None => plan.learner.clone(),
            Some(c) => plan.learner.with_complexity(c),
        }
    }

    /// Every unit, deduplicated, in a fixed order.
    pub fn units(&self) -> Vec<Unit> {
        let set: BTreeSet<Unit> = self.analyses.iter().flat_map(|&a| self.units_of(a)).collect();
        set.into_iter().collect()
    }

    /// The units analysis `a` reads (a unit can serve several analyses: the complexity sweep's
    /// point at the sample analysis's complexity and size is one of the sample analysis's).
    pub fn units_of(&self, a: Analysis) -> Vec<Unit> {
        let mut units = Vec::new();
        for (li, plan) in self.learners.iter().enumerate() {
            for algorithm in [Algorithm::Fqi, Algorithm::Bfqi] {
                let unit =
                    |complexity, episodes, dataset| Unit { learner: li, algorithm, complexity, episodes, dataset };
                match a {
                    Analysis::Iterations => {
                        units.extend((0..plan.datasets).map(|d| unit(None, plan.episodes, d)));
                    }
                    Analysis::Complexity => {
                        for &c in &plan.complexities {
                            units.extend((0..plan.datasets).map(|d| unit(Some(c), plan.episodes, d)));
                        }
                    }
                    Analysis::Samples => {
                        let s = plan.samples.as_ref().expect("validated");
                        let c = if algorithm == Algorithm::Fqi { s.fqi } else { s.bfqi };
                        for &n in &s.sizes {
                            units.extend((0..s.datasets).map(|d| unit(Some(c), n, d)));
                        }
                    }
                }
            }
        }
        units
    }

    /// The run configuration of a unit (its dataset index selects the dataset and seeds).
    pub fn run_config(&self, u: &Unit) -> RunConfig {
        let plan = &self.learners[u.learner];
        RunConfig {
            env: self.env.clone(),
            algorithm: u.algorithm,
            learner: self.learner_at(plan, u.complexity),
            actions: plan.actions,
            iterations: plan.iterations,
            eval_every: 1,
            episodes: u.episodes,
            datasets: u.dataset + 1,
            seed: self.seed,
            data: self.data.clone(),
        }
    }

    /// A unit's id (its result file stem).
    pub fn unit_id(&self, u: &Unit) -> String {
        let c = u.complexity.map_or("base".to_string(), |c| format!("c{c}"));
        format!("{}.{}.{c}.n{}.d{}", self.learners[u.learner].name, u.algorithm.name(), u.episodes, u.dataset)
    }
}

/// One (learner, algorithm, complexity, size, dataset) run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Unit {
    /// Index into [`CompareConfig::learners`].
    pub learner: usize,
    /// FQI or B-FQI.
    pub algorithm: Algorithm,
    /// `None` = the plan's own learner (tuned network, preset depth).
    pub complexity: Option<usize>,
    /// Dataset size in episodes.
    pub episodes: usize,
    /// Dataset index.
    pub dataset: usize,
}

/// A stored unit with its key.
#[derive(Debug, Clone)]
pub struct UnitRecord {
    /// The unit.
    pub unit: Unit,
    /// Its result.
    pub result: DatasetResult,
}

/// Resolves spec and tuned config, builds the comparison and creates its run directory (`out`, or
/// `<results>/<env>/compare-<timestamp>`). Returns the directory.
pub fn prepare(spec_name: &str, r: &Request, out: Option<&Path>, results: &Path) -> Result<PathBuf> {
    let (cfg, info) = resolve(spec_name, r)?;
    let env = cfg.env.env().name();
    store::create_run_dir(out, "compare.json", "a comparison", &results.join(env), "compare-", |d| {
        create(d, &cfg, &info)
    })
}

/// The configuration and run record a comparison would start with, validated, creating nothing.
pub fn resolve(spec_name: &str, r: &Request) -> Result<(CompareConfig, serde_json::Value)> {
    r.check()?;
    if let Some(d) = r.datasets {
        crate::limits::within("datasets", d, 1, crate::limits::DATASETS)?;
    }
    let (spec, origin) = Spec::resolve(spec_name)?;
    let env = spec.env.env().name().to_string();
    let (tuned_cfg, tuned_from) = TunedConfig::resolve(&r.tuned, &env)?;
    let cfg = CompareConfig::new(&spec, tuned_cfg, r.analysis.analyses(), &r.learner.learners(), r)?;
    let mut info = serde_json::json!({
        "kind": "compare", "env": env, "spec_source": origin.display().to_string(),
        "tuned_source": tuned_from.display().to_string(), "analysis": r.analysis, "learner": r.learner,
        "created": store::now_utc().1, "version": env!("CARGO_PKG_VERSION"), "commit": env!("BFQI_GA_COMMIT"),
        "config_hash": cfg.results_hash(), "checksummed": true, "machine": crate::machine::Machine::this(),
    });
    // A gymnasium env's results hold only under the same Python stack: record it.
    if let Some(g) = spec.env.env().gymnasium() {
        info["gymnasium"] = serde_json::to_value(g.versions()?).expect("versions serialise");
    }
    Ok((cfg, info))
}

/// Creates a comparison run directory's configuration files: `run.json` before `compare.json`,
/// which marks a comparison, so a comparison is never seen without its record.
pub fn create(dir: &Path, cfg: &CompareConfig, info: &serde_json::Value) -> Result<()> {
    UnitStore::units(dir).prepare()?;
    write_json(&dir.join("run.json"), info)?;
    write_json(&dir.join("compare.json"), cfg)
}

/// Loads the configuration of a comparison directory.
pub fn load(dir: &Path) -> Result<CompareConfig> {
    let p = dir.join("compare.json");
    if !p.is_file() {
        return Err(Error::File {
            path: dir.to_path_buf(),
            message: "not a comparison run directory (no compare.json)".into(),
        });
    }
    read_json(&p)
}

/// The units of the comparison in a run directory, as executors and the Slurm worker see them.
pub struct Comparison {
    cfg: CompareConfig,
    units: Vec<Unit>,
    store: UnitStore,
    /// `run.json` says every unit carries a checksum ([`crate::ga::units::checksummed`]).
    checksummed: bool,
}

impl Comparison {
    /// The comparison in `dir` (its `compare.json`).
    pub fn open(dir: &Path) -> Result<Self> {
        let cfg = load(dir)?;
        Ok(Comparison {
            units: cfg.units(),
            cfg,
            store: UnitStore::units(dir),
            checksummed: crate::ga::units::checksummed(dir),
        })
    }

    /// Its configuration.
    pub fn config(&self) -> &CompareConfig {
        &self.cfg
    }

    /// Every unit's id, in the configuration's order.
    pub fn ids(&self) -> Vec<String> {
        self.units.iter().map(|u| self.cfg.unit_id(u)).collect()
    }

    fn unit(&self, id: &str) -> Option<&Unit> {
        self.units.iter().find(|u| self.cfg.unit_id(u) == id)
    }

    /// The stored units that verify ([`Self::verified`]), in the configuration's order: what a
    /// partial comparison has done so far.
    pub fn verified_units(&self) -> Vec<UnitRecord> {
        self.units.iter().filter_map(|&u| Some(UnitRecord { unit: u, result: self.verified(&u).ok()?? })).collect()
    }

    /// A unit's stored result: `Ok(None)` if there is no file, `Err` with what is wrong if it does
    /// not parse, holds another dataset, its checksum or configuration hash disagrees, or it has
    /// no checksum in a run whose `run.json` says every unit has one (units of older runs carry
    /// neither and are read as before).
    pub fn verified(&self, u: &Unit) -> std::result::Result<Option<DatasetResult>, String> {
        let path = self.store.path(&self.cfg.unit_id(u));
        if !path.is_file() {
            return Ok(None);
        }
        let r: DatasetResult = read_json(&path).map_err(|e| format!("unreadable ({e})"))?;
        if r.dataset != u.dataset {
            return Err(format!("holds dataset {}, not {}", r.dataset, u.dataset));
        }
        match &r.checksum {
            Some(c) if *c != r.content_checksum() => {
                return Err("its checksum does not match its content (damaged or edited)".into());
            }
            None if self.checksummed => return Err(crate::ga::units::MISSING_CHECKSUM.into()),
            _ => {}
        }
        match &r.spec_hash {
            Some(h) if *h != self.cfg.run_config(u).hash() => Err(format!(
                "computed with another configuration (hash {h}; compare.json gives {})",
                self.cfg.run_config(u).hash()
            )),
            _ => Ok(Some(r)),
        }
    }

    /// Refuses a `compare.json` changed since the run began (its results hash disagrees with the
    /// one `run.json` records; runs created before it was recorded are not checked). `doing` says
    /// what the change would spoil.
    fn check_config(&self, dir: &Path, doing: &str) -> Result<()> {
        let hash = self.cfg.results_hash();
        match recorded_hash(dir)? {
            Some(h) if h != hash => Err(Error::File {
                path: dir.join("compare.json"),
                message: format!(
                    "changed since the run began (results hash {hash}, run.json records {h}): {doing}; restore it \
                     or start a new run"
                ),
            }),
            _ => Ok(()),
        }
    }
}

/// The results hash of `compare.json` that `run.json` records, if it does.
fn recorded_hash(dir: &Path) -> Result<Option<String>> {
    let p = dir.join("run.json");
    if !p.is_file() {
        return Ok(None);
    }
    let info: serde_json::Value = read_json(&p)?;
    Ok(info["config_hash"].as_str().map(String::from))
}

impl Units for Comparison {
    fn store(&self) -> &UnitStore {
        &self.store
    }

    /// Whether a unit is stored whole and this configuration's: a file that does not parse
    /// (truncated by a kill or a full disk, or damaged), whose checksum or configuration hash
    /// disagrees, or that holds another unit is computed again, with a warning.
    fn stored(&self, id: &str) -> bool {
        match self.unit(id).map(|u| self.verified(u)) {
            Some(Ok(Some(_))) => true,
            Some(Err(problem)) => {
                eprintln!("warning: {}: {problem}; it will be computed again", self.store.path(id).display());
                false
            }
            _ => false,
        }
    }

    fn compute(&self, id: &str) -> Result<()> {
        let u = self.unit(id).ok_or_else(|| Error::invalid("unit", id, "is not a unit of this comparison"))?;
        let run = self.cfg.run_config(u);
        let mut r = run_dataset(&run, u.dataset, |_| {})?;
        r.spec_hash = Some(run.hash());
        r.checksum = Some(r.content_checksum());
        write_json(&self.store.path(id), &r)
    }
}

/// Runs (or resumes) every missing unit of the comparison in `dir`, until `budget` says stop.
pub fn run(dir: &Path, exec: &dyn Executor, budget: &Budget<'_>, quiet: bool) -> Result<Ending> {
    let comparison = Comparison::open(dir)?;
    let _lock = RunLock::acquire(dir)?;
    comparison.check_config(dir, "resuming would mix results of two configurations")?;
    let info_path = dir.join("run.json");
    if info_path.is_file() && recorded_hash(dir)?.is_none() {
        // A run created before the hash was recorded: record it now, so later edits are refused.
        let mut info: serde_json::Value = read_json(&info_path)?;
        info["config_hash"] = comparison.cfg.results_hash().into();
        write_json(&info_path, &info)?;
    }
    // What a kill can leave: a deleted units/ is made again, temporary files are removed.
    store::remove_temporaries(dir)?;
    comparison.store.prepare()?;
    let all = comparison.ids();
    let ids: Vec<String> = all.iter().filter(|id| !comparison.stored(id)).cloned().collect();
    if !ids.is_empty() && ids.len() < all.len() && info_path.is_file() {
        // A comparison continued: say which binary and machine add wall time to it.
        let mut info: serde_json::Value = read_json(&info_path)?;
        let entry = serde_json::to_value(crate::ga::records::Resumed::now()).expect("a record serialises");
        match info.get_mut("resumed").and_then(|r| r.as_array_mut()) {
            Some(list) => list.push(entry),
            None => info["resumed"] = serde_json::json!([entry]),
        }
        write_json(&info_path, &info)?;
    }
    let progress = Progress::new("comparison", 1, quiet);
    progress.line(&format!(
        "compare {} → {} ({} units to run)",
        comparison.cfg.env.env().name(),
        dir.display(),
        ids.len()
    ));
    progress.start_stage("units", ids.len() as u64);
    let stop = exec.run(&comparison, &ids, budget, &|_| progress.unit_done(""))?;
    progress.stage_done();
    progress.finish();
    let missing = ids.iter().filter(|id| !comparison.store.path(id).is_file()).count();
    Ok(match stop {
        Some(stop) => Ending::Stopped(stop),
        None if missing > 0 => Ending::Stopped(Stop::Missing(missing)),
        None => Ending::Finished(format!("all {} units", all.len())),
    })
}

/// Gives every unit of the comparison in `dir` that verifies and has no checksum its checksum, and
/// its configuration hash where it has none, writing the unit's content unchanged; then records
/// `config_hash` (if missing) and `checksummed` in `run.json`, so that from then on a unit without
/// a checksum is damaged. For comparisons made before every unit carried one (the thesis
/// references). Refused if `compare.json` changed since the run began. Call it with the run's
/// lock held.
pub fn stamp(dir: &Path) -> Result<crate::run_dir::Stamped> {
    let c = Comparison::open(dir)?;
    c.check_config(dir, "stamping would vouch for units of another configuration")?;
    let mut done = crate::run_dir::Stamped::default();
    for u in &c.units {
        let path = c.store.path(&c.cfg.unit_id(u));
        match c.verified(u) {
            Ok(Some(mut r)) if r.checksum.is_none() => {
                r.spec_hash.get_or_insert_with(|| c.cfg.run_config(u).hash());
                r.checksum = Some(r.content_checksum());
                write_json(&path, &r)?;
                done.stamped += 1;
            }
            Ok(Some(_)) => done.already += 1,
            Ok(None) => {}
            Err(problem) => done.unverified.push((path, problem)),
        }
    }
    let info_path = dir.join("run.json");
    let mut info: serde_json::Value = if info_path.is_file() { read_json(&info_path)? } else { serde_json::json!({}) };
    if info["config_hash"].as_str().is_none() {
        info["config_hash"] = c.cfg.results_hash().into();
    }
    info["checksummed"] = true.into();
    write_json(&info_path, &info)?;
    Ok(done)
}

/// Reads every unit of a finished comparison, refusing a `compare.json` changed since the run
/// began and a unit that is missing or does not verify ([`Comparison::verified`]), naming it.
pub fn collect(dir: &Path) -> Result<(CompareConfig, Vec<UnitRecord>)> {
    let c = Comparison::open(dir)?;
    c.check_config(dir, "the report would describe settings the units were not computed with")?;
    let records = c
        .units
        .iter()
        .map(|&u| {
            let path = c.store.path(&c.cfg.unit_id(&u));
            let refuse = |message: String| Error::File { path: path.clone(), message };
            match c.verified(&u) {
                Ok(Some(result)) => Ok(UnitRecord { unit: u, result }),
                Ok(None) => Err(refuse("missing: resume the comparison (compare --resume) to compute it".into())),
                Err(problem) => Err(refuse(format!("{problem}: resume the comparison to compute it again"))),
            }
        })
        .collect::<Result<_>>()?;
    Ok((c.cfg, records))
}

#[cfg(test)]
mod resume_tests {
    use super::*;

    #[test]
    fn a_truncated_unit_is_not_stored() {
        let dir = std::env::temp_dir().join(format!("bfqi-compare-unit-{}", std::process::id()));
        let spec = Spec::resolve("cartpole").unwrap().0;
        let (tuned, _) = TunedConfig::resolve("thesis", "cartpole").unwrap();
        let r = Request {
            tuned: "thesis".into(),
            analysis: AnalysisChoice::Iterations,
            learner: LearnerChoice::Et,
            datasets: Some(1),
            episodes: None,
            iterations: None,
            complexities: None,
            sizes: None,
        };
        let cfg = CompareConfig::new(&spec, tuned, r.analysis.analyses(), &r.learner.learners(), &r).unwrap();
        create(&dir, &cfg, &serde_json::json!({})).unwrap();
        let c = Comparison::open(&dir).unwrap();
        let id = &c.ids()[0];
        assert!(!c.stored(id));
        std::fs::write(c.store().path(id), "{\"dataset\": 0, \"transi").unwrap();
        assert!(!c.stored(id));
        std::fs::remove_dir_all(dir).unwrap();
    }
}
