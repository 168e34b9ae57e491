//! Spec files (`searches/<env>.json`): every default of SPEC §1–§6 lives in one of these, never deep
//! in the code. A spec is validated on load; an error names the file, the field and what is allowed.
//!
//! `bfqi-ga <cmd> bicycle` reads `searches/bicycle.json` from the working directory, or the copy
//! built into the binary (the same file) when there is none; `bfqi-ga <cmd> path/to/spec.json` reads
//! that file.

use crate::env::EnvConfig;
use crate::error::{Error, Result, ensure};
use crate::fqi::Algorithm;
use crate::ga::chromosome::GeneRanges;
use crate::ga::operators::GaParams;
use crate::learn::actions::ActionEncoding;
use crate::learn::mlp::MlpParams;
use crate::learn::{Learner, LearnerConfig};
use crate::report::claims::ClaimSpec;
use crate::store;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The settings of one original experiment (a row of the SPEC §6 table): what `bfqi-ga run` and
/// `bfqi-ga compare` use unless flags override them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    /// K, FQI iterations.
    pub iterations: usize,
    /// Number of datasets results are averaged over.
    pub datasets: usize,
    /// Episodes per dataset.
    pub episodes: usize,
    /// How actions reach the learner.
    pub actions: ActionEncoding,
    /// Evaluate the greedy policy every this many iterations (and at the last).
    #[serde(default = "one")]
    pub eval_every: usize,
    /// The learner and its settings.
    pub learner: LearnerConfig,
    /// Complexities of the complexity analysis: max depths, or units of one hidden layer.
    #[serde(default)]
    pub complexities: Vec<usize>,
    /// The sample analysis (thesis §4.6).
    #[serde(default)]
    pub samples: Option<SampleSweep>,
    /// The thesis's claims a comparison of this learner checks (SPEC §6), with their thresholds.
    /// Left out of the file when empty, so specs written before claims moved here hash alike.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub claims: Vec<ClaimSpec>,
}

/// The sample analysis: one complexity per algorithm, scored against dataset size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SampleSweep {
    /// Complexity of FQI's learner.
    pub fqi: usize,
    /// Complexity of B-FQI's learner.
    pub bfqi: usize,
    /// Datasets per size.
    pub datasets: usize,
    /// Dataset sizes, in episodes.
    pub sizes: Vec<usize>,
}

fn one() -> usize {
    1
}

impl Preset {
    fn validate(&self, horizon: usize) -> Result<()> {
        use crate::limits::{self, DATASETS, ITERATIONS, SWEEP_POINTS, WIDTH};
        limits::within("iterations", self.iterations, 1, ITERATIONS)?;
        limits::within("datasets", self.datasets, 1, DATASETS)?;
        limits::episodes("episodes", self.episodes, horizon)?;
        ensure(
            self.complexities.len() <= SWEEP_POINTS && self.complexities.iter().all(|&c| c <= WIDTH),
            "complexities",
            format!("{} values", self.complexities.len()),
            &format!("must be at most {SWEEP_POINTS} values, each ≤ {WIDTH}"),
        )?;
        ensure(self.eval_every >= 1, "eval_every", self.eval_every, "must be ≥ 1")?;
        ensure(
            self.complexities.iter().all(|&c| c >= 1),
            "complexities",
            format!("{:?}", self.complexities),
            "must all be ≥ 1",
        )?;
        if let Some(s) = &self.samples {
            ensure(
                s.fqi >= 1 && s.bfqi >= 1,
                "samples",
                format!("fqi {} bfqi {}", s.fqi, s.bfqi),
                "complexities must be ≥ 1",
            )?;
            limits::within("samples.datasets", s.datasets, 1, DATASETS)?;
            ensure(
                (1..=SWEEP_POINTS).contains(&s.sizes.len()),
                "samples.sizes",
                format!("{} sizes", s.sizes.len()),
                &format!("must list 1 to {SWEEP_POINTS} sizes"),
            )?;
            for (i, &n) in s.sizes.iter().enumerate() {
                limits::episodes(&format!("samples.sizes[{i}]"), n, horizon)?;
            }
        }
        for (i, c) in self.claims.iter().enumerate() {
            c.validate().map_err(|e| e.within(&format!("claims[{i}]")))?;
        }
        self.learner.check()
    }
}

/// The original experiments' settings per learner.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiments {
    /// Extra-Trees.
    pub et: Preset,
    /// MLP.
    pub mlp: Preset,
}

/// A learner family, as the spec's presets (`experiments.et`, `experiments.mlp`) and `--learner`
/// name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum LearnerKind {
    /// Extra-Trees.
    Et,
    /// The multilayer perceptron.
    Mlp,
}

impl LearnerKind {
    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            LearnerKind::Et => "et",
            LearnerKind::Mlp => "mlp",
        }
    }
}

/// When a search stops.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StopRules {
    /// Generations to evaluate.
    pub generations: usize,
    /// Wall-clock budget in hours (the search stops cleanly between units and can be resumed).
    pub max_hours: Option<f64>,
    /// Stop after this many generations without improvement of the best fitness.
    pub stall_generations: Option<usize>,
}

/// Everything a genetic search needs beyond the environment (SPEC §5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchSpec {
    /// Search datasets each chromosome is scored on (seeds disjoint from comparison datasets).
    pub datasets: usize,
    /// Episodes per search dataset.
    pub episodes: usize,
    /// FQI iterations K; fitness is the score after the last.
    pub iterations: usize,
    /// The algorithm whose network is tuned (the thesis tunes FQI, which is pessimistic for B-FQI).
    pub algorithm: Algorithm,
    /// How actions reach the network.
    pub actions: ActionEncoding,
    /// The tuned network; its activation, delta_min and patience are replaced by the genes'.
    pub network: MlpParams,
    /// Gene ranges.
    pub genes: GeneRanges,
    /// GA parameters.
    pub ga: GaParams,
    /// Stop rules.
    pub stop: StopRules,
    /// Opt-in pruning of individuals whose first datasets score far below the parent pool
    /// (beyond the thesis; off when absent).
    #[serde(default)]
    pub prune: crate::ga::prune::PruneRule,
    /// Opt-in racing of each new setting against the elites, dataset by dataset, with a paired
    /// test (beyond the thesis; off when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub race: Option<crate::ga::racing::RaceRule>,
    /// After the last generation, re-score the hall of fame's top settings (and the thesis
    /// optimum) on fresh validation datasets; none when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validate: Option<ValidateRule>,
    /// Which winner `best.json` holds: the best fitness (the thesis's rule, the default) or the
    /// validation's winner (beyond the thesis; needs `validate`).
    #[serde(default, skip_serializing_if = "Select::is_fitness")]
    pub select: Select,
    /// How each generation after the first is made: bred by the GA (thesis Appendix C, the
    /// default) or drawn uniformly from the gene ranges (`random`, a baseline beyond the thesis).
    #[serde(default, skip_serializing_if = "Strategy::is_ga")]
    pub strategy: Strategy,
    /// Chromosomes placed first in generation 0 in place of random ones (`search --seed-config`),
    /// as Optuna's `enqueue_trial` does; none when absent.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub seeded: Vec<crate::ga::chromosome::Chromosome>,
    /// How settings are scored: in the simulator (the thesis's, the default) or offline, by FQE
    /// on held-out logged episodes (beyond the thesis; [`crate::offline`]).
    #[serde(default, skip_serializing_if = "crate::offline::Fitness::is_online")]
    pub fitness: crate::offline::Fitness,
}

impl SearchSpec {
    fn validate(&self, horizon: usize) -> Result<()> {
        use crate::limits::{self, DATASETS, GENERATIONS, ITERATIONS, POPULATION};
        limits::within("datasets", self.datasets, 1, DATASETS)?;
        limits::episodes("episodes", self.episodes, horizon)?;
        limits::within("iterations", self.iterations, 1, ITERATIONS)?;
        limits::within("ga.population", self.ga.population, 2, POPULATION)?;
        limits::within("stop.generations", self.stop.generations, 1, GENERATIONS)?;
        self.network.check().map_err(|e| e.within("network"))?;
        self.genes.validate().map_err(|e| e.within("genes"))?;
        let ga = &self.ga;
        for (f, v) in [("ga.elitism", ga.elitism), ("ga.parent_pool", ga.parent_pool)] {
            ensure((0.0..=1.0).contains(&v), f, v, "must be in [0, 1]")?;
        }
        ensure(ga.n_elites() < ga.population, "ga.elitism", ga.elitism, "must leave room for at least one child")?;
        for (f, v) in [("ga.mutation", ga.mutation), ("ga.gene_resampling", ga.gene_resampling)] {
            ensure((0.0..=1.0).contains(&v), f, v, "must be in [0, 1]")?;
        }
        if let Some(h) = self.stop.max_hours {
            ensure(h.is_finite() && h > 0.0, "stop.max_hours", h, "must be > 0")?;
        }
        if let Some(s) = self.stop.stall_generations {
            ensure(s >= 1, "stop.stall_generations", s, "must be ≥ 1")?;
        }
        self.prune.validate()?;
        self.fitness.validate(horizon)?;
        if let Some(r) = &self.race {
            r.validate(self.datasets)?;
            ensure(
                !self.prune.enabled,
                "race",
                r.test.name(),
                "cannot be combined with prune.enabled (each stops settings its own way); turn one off",
            )?;
        }
        ensure(self.seeded.len() <= ga.population, "seeded", self.seeded.len(), "must not exceed ga.population")?;
        for (i, c) in self.seeded.iter().enumerate() {
            let b = self.genes.bounds();
            ensure(
                self.genes.contains(c),
                &format!("seeded[{i}]"),
                format!("{c:?}"),
                &format!("must lie in the gene ranges {b:?}"),
            )?;
        }
        ensure(
            self.select == Select::Fitness || self.validate.is_some(),
            "select",
            "validated",
            "needs search.validate (the validation decides the winner)",
        )?;
        self.validate.as_ref().map_or(Ok(()), |v| v.validate())
    }
}

/// `search.select`: which setting the search's tuned config (`best.json`) is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Select {
    /// The best fitness on the search datasets (thesis Appendix C).
    #[default]
    Fitness,
    /// The winner of the validation (the race's leader, or the best validation mean).
    Validated,
}

impl Select {
    /// Whether this is the thesis's rule (left out of spec files and hashes when it is).
    pub fn is_fitness(&self) -> bool {
        *self == Select::Fitness
    }
    /// `fitness` or `validated`, as spec files spell it.
    pub fn name(&self) -> &'static str {
        match self {
            Select::Fitness => "fitness",
            Select::Validated => "validated",
        }
    }
}

/// `search.strategy`: where the individuals of generations 1, 2, … come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Strategy {
    /// Elites, crossover and mutation (thesis Appendix C).
    #[default]
    Ga,
    /// Every individual drawn uniformly over the gene ranges, as generation 0 is: random search at
    /// the GA's population size, the baseline that says what the GA's breeding adds.
    Random,
}

impl Strategy {
    /// Whether this is the thesis's GA (left out of spec files and hashes when it is).
    pub fn is_ga(&self) -> bool {
        *self == Strategy::Ga
    }
}

/// A spec file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// The environment; fields left out take their SPEC defaults.
    pub env: EnvConfig,
    /// Logged transitions to learn from instead of random-policy episodes (beyond the thesis;
    /// collected as SPEC §2 says when absent). See [`crate::dataset::logged`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<crate::dataset::DataSource>,
    /// Master seed of every stream (SPEC §7).
    pub seed: u64,
    /// Settings of the original experiments.
    pub experiments: Experiments,
    /// The genetic search.
    pub search: SearchSpec,
}

/// Built-in copies of the shipped presets (overlays).
const BUILTIN_PRESETS: [(&str, &str); 3] = [
    ("quick", include_str!("../../searches/presets/quick.json")),
    ("prune", include_str!("../../searches/presets/prune.json")),
    ("thesis-text-ranges", include_str!("../../searches/presets/thesis-text-ranges.json")),
];

/// Applies a JSON merge patch (RFC 7386): objects merge key by key, anything else replaces, `null`
/// removes. Keys starting with `_` (comments) are skipped.
pub fn merge_patch(base: &mut serde_json::Value, patch: &serde_json::Value) {
    use serde_json::Value;
    match (base, patch) {
        (Value::Object(b), Value::Object(p)) => {
            for (k, v) in p {
                if k.starts_with('_') {
                    continue;
                }
                if v.is_null() {
                    b.remove(k);
                } else {
                    merge_patch(b.entry(k.clone()).or_insert(Value::Null), v);
                }
            }
        }
        (b, p) => *b = strip_comments(p.clone()),
    }
}

/// Removes `_`-prefixed keys (comments) at every level.
pub(crate) fn strip_comments(v: serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Object(m) => Value::Object(
            m.into_iter().filter(|(k, _)| !k.starts_with('_')).map(|(k, v)| (k, strip_comments(v))).collect(),
        ),
        Value::Array(a) => Value::Array(a.into_iter().map(strip_comments).collect()),
        other => other,
    }
}

/// Reads a preset overlay: a built-in name (`quick`, `thesis-text-ranges`), `searches/presets/<name>.json`,
/// or a path.
pub fn load_preset(name_or_path: &str) -> Result<(serde_json::Value, PathBuf)> {
    let local = PathBuf::from(format!("searches/presets/{name_or_path}.json"));
    let path = PathBuf::from(name_or_path);
    // Something at the path that is not a readable file is refused, never replaced by a built-in.
    let (text, origin) = if store::something_at(&local) {
        (store::read_input(&local)?, local)
    } else if store::something_at(&path) {
        (store::read_input(&path)?, path)
    } else if let Some((n, t)) = BUILTIN_PRESETS.iter().find(|(n, _)| *n == name_or_path) {
        (t.to_string(), PathBuf::from(format!("<built-in searches/presets/{n}.json>")))
    } else {
        let names: Vec<&str> = BUILTIN_PRESETS.iter().map(|(n, _)| *n).collect();
        return Err(Error::invalid("preset", name_or_path, format!("must be one of {} or a file", names.join(", "))));
    };
    let v = store::parse_json(&text, &origin)?;
    Ok((v, origin))
}

/// Built-in copies of the shipped spec files, so the binary works from any directory.
const BUILTIN: [(&str, &str); 3] = [
    ("pendulum", include_str!("../../searches/pendulum.json")),
    ("cartpole", include_str!("../../searches/cartpole.json")),
    ("bicycle", include_str!("../../searches/bicycle.json")),
];

/// `search.validate` of a spec: how many of the hall of fame's best settings to re-score, on how
/// many validation datasets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValidateRule {
    /// Settings re-scored, best fitness first.
    pub top: usize,
    /// Validation datasets each is scored on; with `race`, the most any setting gets (the budget).
    pub datasets: usize,
    /// Race the settings in rounds instead of scoring each on every dataset; none when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub race: Option<RaceRule>,
}

/// `search.validate.race`: every setting is scored on `first` validation datasets; after each
/// round, settings whose paired difference to the leader is below 0 at `confidence` are dropped,
/// and the survivors get `step` datasets more, until one is left or `datasets` are spent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RaceRule {
    /// Datasets of the first round (≥ 2: a paired interval needs two pairs).
    pub first: usize,
    /// Datasets added to each survivor per round.
    pub step: usize,
    /// Confidence of the paired t intervals that drop a setting (0.95).
    pub confidence: f64,
}

impl ValidateRule {
    /// Validates the rule; errors name the field.
    pub fn validate(&self) -> Result<()> {
        use crate::limits::{VALIDATE_DATASETS, VALIDATE_TOP, within};
        within("validate.top", self.top, 1, VALIDATE_TOP)?;
        within("validate.datasets", self.datasets, 1, VALIDATE_DATASETS)?;
        if let Some(r) = &self.race {
            let d = self.datasets;
            ensure(
                (2..=d).contains(&r.first),
                "validate.race.first",
                r.first,
                &format!("must be in 2..={d} (validate.datasets)"),
            )?;
            ensure(
                (1..=d).contains(&r.step),
                "validate.race.step",
                r.step,
                &format!("must be in 1..={d} (validate.datasets)"),
            )?;
            ensure(
                r.confidence.is_finite() && (0.5..=0.999).contains(&r.confidence),
                "validate.race.confidence",
                r.confidence,
                "must be in [0.5, 0.999]",
            )?;
        }
        Ok(())
    }
}

impl Spec {
    /// Validates every field; the error names the field path.
    pub fn validate(&self) -> Result<()> {
        self.env.validate()?;
        let horizon = self.env.env().horizon();
        self.experiments.et.actions.check_for(&self.env, "experiments.et.actions")?;
        self.experiments.mlp.actions.check_for(&self.env, "experiments.mlp.actions")?;
        self.search.actions.check_for(&self.env, "search.actions")?;
        self.experiments.et.validate(horizon).map_err(|e| e.within("experiments.et"))?;
        self.experiments.mlp.validate(horizon).map_err(|e| e.within("experiments.mlp"))?;
        self.search.validate(horizon).map_err(|e| e.within("search"))?;
        checks::check(self)
    }

    /// Parses and validates spec text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &Path) -> Result<Spec> {
        Self::from_value(Self::parse_value(text, origin)?, origin)
    }

    /// Parses spec text into JSON (comments removed), without validating it as a spec.
    pub fn parse_value(text: &str, origin: &Path) -> Result<serde_json::Value> {
        Ok(strip_comments(store::parse_json(text, origin)?))
    }

    /// The JSON text of `bicycle` (→ `searches/bicycle.json` or the built-in copy) or of a file,
    /// with its origin; for callers that patch it before validating.
    /// `gymnasium:<id>`, and a gymnasium spec file that leaves out `seed`, `experiments` or
    /// `search`, are completed from the template `searches/gymnasium/defaults.json`; a
    /// gymnasium env is probed (see [`template`]).
    pub fn resolve_value(name_or_path: &str) -> Result<(serde_json::Value, PathBuf)> {
        if let Some(named) = template::from_name(name_or_path) {
            return named;
        }
        if let Some(named) = template::from_minari(name_or_path) {
            return named;
        }
        if let Some((name, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
            let local = PathBuf::from(format!("searches/{name}.json"));
            if store::something_at(&local) {
                let t = store::read_input(&local)?;
                return Ok((Self::parse_value(&t, &local)?, local));
            }
            let origin = PathBuf::from(format!("<built-in searches/{name}.json>"));
            return Ok((Self::parse_value(text, &origin)?, origin));
        }
        let path = PathBuf::from(name_or_path);
        if store::something_at(&path) {
            let t = store::read_input(&path)?;
            return Ok((template::complete(Self::parse_value(&t, &path)?, &path)?, path));
        }
        Err(Error::UnknownEnv {
            name: crate::error::shortened(name_or_path.to_string()),
            valid: format!(
                "{}, gymnasium:<id> (any gymnasium env, e.g. gymnasium:Acrobot-v1), minari:<dataset id> or the path of a \
                 spec file",
                crate::env::NAMES.join(", ")
            ),
        })
    }

    /// The hash of everything that determines a unit's result: the spec without its stop rules
    /// (which `search --resume --generations` may change), recorded in units and `run.json`.
    pub fn results_hash(&self) -> String {
        self.for_results_hash().hash()
    }

    /// The hash of what decides a unit's numbers and nothing more: [`Self::results_hash`]'s
    /// spec without the gene ranges, the GA's parameters, the seeded individuals, pruning, racing
    /// and the validation's size, which decide which units a search runs but not what any unit computes
    /// (units are named and seeded by their decoded setting). Two searches of equal units hash
    /// can share units (`search --units-from`): say, a population of 10 taking a population of 20's.
    pub fn units_hash(&self) -> String {
        let mut v = serde_json::to_value(self.for_results_hash()).expect("a spec serialises");
        if let Some(search) = v.get_mut("search").and_then(|s| s.as_object_mut()) {
            for k in ["genes", "ga", "seeded", "prune", "race", "validate"] {
                search.remove(k);
            }
        }
        crate::store::json_hash(&v)
    }

    /// The spec as [`Self::results_hash`] hashes it.
    fn for_results_hash(&self) -> Spec {
        let mut s = self.clone();
        // A gymnasium env's Python and timeout decide no result.
        s.env = s.env.for_hash();
        s.search.stop = StopRules { generations: 1, max_hours: None, stall_generations: None };
        // Claims decide how a comparison is read, not any number a search computes.
        s.experiments.et.claims.clear();
        s.experiments.mlp.claims.clear();
        // Which winner best.json holds and how the validation races decide no unit's number
        // either; left at their defaults so older runs keep their hash.
        s.search.select = Select::Fitness;
        if let Some(v) = &mut s.search.validate {
            v.race = None;
        }
        // A unit's result does not depend on how its setting was found, so a random baseline
        // shares units with the GA search of the same spec (`search --units-from`).
        s.search.strategy = Strategy::Ga;
        s
    }

    /// The identity a run directory records in `run.json` and checks on resume: the results hash,
    /// and for a random search its strategy too, so neither run resumes as the other.
    pub fn run_hash(&self) -> String {
        let h = self.results_hash();
        match self.search.strategy {
            Strategy::Ga => h,
            Strategy::Random => format!("{h}-random"),
        }
    }

    /// A short, stable hash of the spec's canonical JSON (FNV-1a, 64 bits), recorded in tuned configs.
    pub fn hash(&self) -> String {
        crate::store::json_hash(self)
    }

    /// Deserialises and validates a JSON value; `origin` names it in errors.
    pub fn from_value(value: serde_json::Value, origin: &Path) -> Result<Spec> {
        crate::error::expect_object(&value, origin, "a spec")?;
        let mut spec: Spec = crate::error::from_json(value, origin, "")?;
        // A gymnasium env's spaces are asked of its worker the first time (`env.probed`).
        spec.env.resolve().map_err(|e| file_error(origin, e.to_string()))?;
        spec.search.fitness.resolve(spec.env.env());
        spec.validate().map_err(|e| file_error(origin, e.to_string()))?;
        let needs = spec.data_needs();
        if let Some(d) = &mut spec.data {
            d.resolve(&spec.env, &needs).map_err(|e| file_error(origin, e.to_string()))?;
        }
        if let Some(w) = spec.cap_inside_patience() {
            crate::warn_once(&format!("warning: {}: {w}", origin.display()));
        }
        Ok(spec)
    }

    /// Reads and validates a spec file.
    pub fn load(path: &Path) -> Result<Spec> {
        let text = store::read_input(path)?;
        Self::parse(&text, path)
    }

    /// Resolves `bicycle` (→ `searches/bicycle.json`, or the built-in copy) or a path to a file.
    /// Returns the spec and where it came from.
    pub fn resolve(name_or_path: &str) -> Result<(Spec, PathBuf)> {
        let (value, origin) = Self::resolve_value(name_or_path)?;
        Ok((Self::from_value(value, &origin)?, origin))
    }

    /// What the spec asks of logged data: datasets per role, and its encodings.
    fn data_needs(&self) -> crate::dataset::logged::Needs {
        let (et, mlp, s) = (&self.experiments.et, &self.experiments.mlp, &self.search);
        let samples = [et, mlp].into_iter().filter_map(|p| p.samples.as_ref()).map(|x| x.datasets);
        crate::dataset::logged::Needs {
            search: s.datasets,
            validation: s.validate.as_ref().map_or(0, |v| v.datasets),
            compare: samples.chain([et.datasets, mlp.datasets]).max().unwrap_or(0),
            heldout: usize::from(!s.fitness.is_online()),
            encodings: vec![
                ("search.actions".into(), s.actions),
                ("experiments.et.actions".into(), et.actions),
                ("experiments.mlp.actions".into(), mlp.actions),
            ],
        }
    }

    /// Refuses a search whose search or validation datasets its logged data cannot give (see
    /// [`crate::dataset::logged`]); nothing to check when it collects its datasets.
    pub fn check_search_data(&self) -> Result<()> {
        let Some(d) = &self.data else { return Ok(()) };
        use crate::dataset::Role;
        d.check(Role::Search, self.search.datasets, self.search.episodes)?;
        if let Some(f) = self.search.fitness.fqe() {
            d.check(Role::Heldout, 1, f.episodes)?;
        }
        match &self.search.validate {
            Some(v) => d.check(Role::Validation, v.datasets, self.search.episodes),
            None => Ok(()),
        }
    }

    /// The preset of a learner.
    pub fn preset(&self, learner: LearnerKind) -> &Preset {
        match learner {
            LearnerKind::Et => &self.experiments.et,
            LearnerKind::Mlp => &self.experiments.mlp,
        }
    }
}

fn file_error(path: &Path, message: String) -> Error {
    Error::File { path: path.to_path_buf(), message }
}

mod checks;
mod recorded;
pub(crate) use checks::holdout;
pub mod template;

#[cfg(test)]
mod tests;
