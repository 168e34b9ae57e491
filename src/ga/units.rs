//! The search's units of work: one FQI run of a decoded setting on one search dataset.
//!
//! Fitness is a function of the decoded settings (activation, δ_min, patience), not of the genes
//! (SPEC §5): with b_p = 0 the 90 values of a_p decode to 9 patiences. So a unit is named by its
//! setting and dataset (`sigmoid_5.8e-1_601.d3`), its seeds derive from them, and chromosomes that
//! decode alike share one result, computed once per run.

use super::chromosome::Decoded;
use crate::dataset::{self, Dataset, dataset_seed};
use crate::error::{Error, Result};
use crate::fqi::{Divergence, Fqi, FqiSettings, IterationRecord};
use crate::learn::LearnerConfig;
use crate::learn::actions::Encoded;
use crate::learn::mlp::{Activation, MlpParams};
use crate::model::{Model, ModelInfo, QFunction};
use crate::rng;
use crate::run_dir::{UnitStore, Units};
use crate::spec::Spec;
use crate::store::{read_json, write_json};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// One FQI run of a setting on a search dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UnitResult {
    /// The decoded settings.
    pub setting: Decoded,
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
    /// Each FQI iteration run: its networks' epochs, why each stopped (early stopping or the epoch
    /// cap) and their last losses, the Bellman residual, and its seconds.
    #[serde(default)]
    pub iterations: Vec<IterationRecord>,
    /// The rows each network of an iteration was fitted on (one per action with `per_action`):
    /// what its epochs are counted against ([`crate::work`]), so that reading a run never
    /// collects its datasets again. (Absent in units written before it was recorded.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rows: Option<Vec<usize>>,
    /// With an offline fitness (`search.fitness`): what FQE measured on the held-out episodes,
    /// whose estimate is `score`. Absent with the online fitness.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offline: Option<crate::offline::OfflineScore>,
    /// With an offline fitness where the env can be simulated: the greedy policy's online score,
    /// recorded (never used by the search) so that the two fitnesses can be compared.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub online: Option<f64>,
    /// [`Spec::results_hash`] of the run that computed it: a unit from another spec is not reused.
    /// (Absent in units written before it was recorded.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec_hash: Option<String>,
    /// FNV-1a of the unit's JSON without this field: a damaged or edited file is recomputed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checksum: Option<String>,
}

impl UnitResult {
    /// The checksum of the unit's content (its JSON with `checksum` absent).
    pub fn content_checksum(&self) -> String {
        crate::store::json_hash(&UnitResult { checksum: None, ..self.clone() })
    }
}

/// What a unit without a checksum is in a run whose units all carry one.
pub(crate) const MISSING_CHECKSUM: &str =
    "it has no checksum, which every unit of this run carries (damaged or edited; run.json says checksummed)";

/// Whether the run in `dir` says every unit carries a checksum (`run.json`'s `checksummed`): runs
/// created since checksums exist, and runs stamped by `bfqi-ga stamp`. A unit of such a run without
/// one is damaged; a unit of an older, unmarked run without one is read as before.
pub fn checksummed(dir: &Path) -> bool {
    crate::store::read_json::<serde_json::Value>(&dir.join("run.json"))
        .ok()
        .and_then(|v| v["checksummed"].as_bool())
        .unwrap_or(false)
}

/// The activation's name in unit ids and files.
pub fn activation_name(a: Activation) -> &'static str {
    match a {
        Activation::Sigmoid => "sigmoid",
        Activation::Tanh => "tanh",
        Activation::Relu => "relu",
    }
}

fn activation_by_name(s: &str) -> Option<Activation> {
    [Activation::Sigmoid, Activation::Tanh, Activation::Relu].into_iter().find(|&a| activation_name(a) == s)
}

/// A stable code of the activation for seed derivation (independent of the spec's gene order).
fn activation_code(a: Activation) -> u64 {
    match a {
        Activation::Sigmoid => 0,
        Activation::Tanh => 1,
        Activation::Relu => 2,
    }
}

/// A setting for humans: `tanh δ_min 0.00059 patience 311`.
pub fn describe(d: &Decoded) -> String {
    format!("{} δ_min {} patience {}", activation_name(d.activation), d.delta_min, d.patience)
}

/// The name of a setting, e.g. `sigmoid_5.8e-1_601`: activation, δ_min (shortest round-trip
/// form, so it parses back to the same double) and patience.
pub fn setting_id(s: &Decoded) -> String {
    format!("{}_{:e}_{}", activation_name(s.activation), s.delta_min, s.patience)
}

/// Parses [`setting_id`] back.
pub fn parse_setting_id(id: &str) -> Option<Decoded> {
    let mut parts = id.split('_');
    let activation = activation_by_name(parts.next()?)?;
    let delta_min: f64 = parts.next()?.parse().ok()?;
    let patience: usize = parts.next()?.parse().ok()?;
    (parts.next().is_none() && delta_min.is_finite()).then_some(Decoded { activation, delta_min, patience })
}

/// The rows each network of an encoded dataset is fitted on (training and validation rows).
pub fn network_rows(enc: &Encoded) -> Vec<usize> {
    (0..enc.n_models()).map(|j| enc.model_rows(j).1.len()).collect()
}

/// The unit id (result file stem) of a setting on a dataset, e.g. `sigmoid_5.8e-1_601.d3`.
pub fn unit_id(s: &Decoded, dataset: usize) -> String {
    format!("{}.d{dataset}", setting_id(s))
}

/// Parses a unit id back into (setting, dataset).
pub fn parse_unit_id(id: &str) -> Option<(Decoded, usize)> {
    let (setting, d) = id.rsplit_once(".d")?;
    Some((parse_setting_id(setting)?, d.parse().ok()?))
}

/// A guess of a unit's cost before it runs, in arbitrary units, for ordering work longest first
/// and for weighting the first generation's time projection: epochs per fit grow with patience
/// and with smaller δ_min (more epochs count as improvements before the patience runs out), up
/// to the epoch cap; ReLU epochs are cheaper than sigmoid and tanh ones.
pub fn expected_cost(s: &Decoded, max_epochs: usize) -> f64 {
    let delta_factor = 1.0 + (0.1 / s.delta_min.max(1e-12)).log10().max(0.0);
    let epochs = ((s.patience as f64 + 1.0) * delta_factor).min(max_epochs as f64);
    let per_epoch = if s.activation == Activation::Relu { 0.7 } else { 1.0 };
    epochs * per_epoch
}

/// Which datasets a unit runs on: the search's (fitness), or the validation datasets that
/// re-score a search's top settings, from a third stream disjoint from search and comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Search datasets: `dataset/search`, networks from `init`, evaluation from `eval/search`;
    /// results in `units/`.
    Search,
    /// Validation datasets: `dataset/validation`, networks from `init/validation`, evaluation
    /// from `eval/validation`; results in `validation/`.
    Validation,
}

impl Role {
    /// The dataset stream's role name.
    pub fn name(self) -> &'static str {
        match self {
            Role::Search => "search",
            Role::Validation => "validation",
        }
    }
    /// The role of its datasets' stream.
    fn datasets(self) -> dataset::Role {
        match self {
            Role::Search => dataset::Role::Search,
            Role::Validation => dataset::Role::Validation,
        }
    }
    fn init_purpose(self) -> &'static str {
        match self {
            Role::Search => crate::rng::purpose::INIT,
            Role::Validation => crate::rng::purpose::INIT_VALIDATION,
        }
    }
    pub(crate) fn folder(self) -> &'static str {
        match self {
            Role::Search => "units",
            Role::Validation => "validation",
        }
    }
}

/// Evaluates units of one search: datasets are collected lazily and shared.
pub struct Evaluator {
    spec: Spec,
    results_hash: String,
    store: UnitStore,
    /// Where units missing from `store` are read (never written): the search a `validate --into`
    /// directory validates.
    also: Option<UnitStore>,
    role: Role,
    /// The run's `run.json` says every unit carries a checksum ([`checksummed`]).
    checksummed: bool,
    data: Mutex<HashMap<usize, Arc<(Dataset, Encoded)>>>,
    /// The offline fitness's held-out set, collected on first use.
    heldout: Mutex<Option<Arc<Dataset>>>,
    warned: Mutex<std::collections::HashSet<String>>,
}

impl Evaluator {
    /// An evaluator for the search in `dir` with resolved `spec`.
    pub fn new(spec: Spec, dir: &Path) -> Self {
        Self::with_role(spec, dir, Role::Search)
    }

    /// An evaluator of `role`'s datasets for the search in `dir`.
    pub fn with_role(spec: Spec, dir: &Path, role: Role) -> Self {
        Evaluator {
            results_hash: spec.results_hash(),
            spec,
            store: UnitStore::named(dir, role.folder()),
            also: None,
            role,
            checksummed: checksummed(dir),
            data: Mutex::new(HashMap::new()),
            heldout: Mutex::new(None),
            warned: Mutex::new(Default::default()),
        }
    }

    /// An evaluator of `role`'s datasets that stores units under `out` and reads those it lacks from
    /// the search in `source` (its spec's units, its checksum rule): what `validate --into` runs.
    pub fn reading_from(spec: Spec, source: &Path, out: &Path, role: Role) -> Self {
        let mut ev = Self::with_role(spec, out, role);
        ev.also = Some(UnitStore::named(source, role.folder()));
        ev.checksummed = checksummed(source);
        ev
    }

    /// The resolved spec.
    pub fn spec(&self) -> &Spec {
        &self.spec
    }

    /// The seed dataset `d` of this role is collected from.
    pub fn dataset_seed(&self, d: usize) -> u64 {
        dataset_seed(self.spec.seed, self.role.datasets(), d)
    }

    /// Search dataset `d`, laid out for the search's action encoding (collected on first use).
    pub fn dataset(&self, d: usize) -> Result<Arc<(Dataset, Encoded)>> {
        if let Some(x) = self.data.lock().expect("dataset cache").get(&d) {
            return Ok(x.clone());
        }
        let x = Arc::new(self.collect(d)?);
        self.data.lock().expect("dataset cache").insert(d, x.clone());
        Ok(x)
    }

    /// The offline fitness's held-out set ([`crate::offline`]): dataset 0 of the `heldout` role,
    /// of `search.fitness.episodes` episodes, shared by every unit (collected on first use).
    pub fn heldout(&self) -> Result<Arc<Dataset>> {
        let Some(f) = self.spec.search.fitness.fqe() else {
            return Err(Error::Usage("the spec's fitness is online: it has no held-out set".into()));
        };
        let mut held = self.heldout.lock().expect("held-out set");
        if let Some(h) = &*held {
            return Ok(h.clone());
        }
        let (env, role) = (self.spec.env.env(), dataset::Role::Heldout);
        let h = Arc::new(dataset::make(env, self.spec.data.as_ref(), f.episodes, self.spec.seed, role, 0)?);
        *held = Some(h.clone());
        Ok(h)
    }

    /// The rows each network of dataset `d` is fitted on (one per action with `per_action`), and
    /// the networks' inputs: what a unit's epochs are counted against ([`crate::work`]). Collected
    /// afresh, not kept: a run's work is counted once, and its datasets can be large.
    pub fn network_rows(&self, d: usize) -> Result<(Vec<usize>, usize)> {
        let rows = |enc: &Encoded| (network_rows(enc), enc.n_inputs());
        if let Some(x) = self.data.lock().expect("dataset cache").get(&d) {
            return Ok(rows(&x.1));
        }
        Ok(rows(&self.collect(d)?.1))
    }

    /// Search dataset `d` collected and encoded, checked for networks it cannot train.
    fn collect(&self, d: usize) -> Result<(Dataset, Encoded)> {
        let env = self.spec.env.env();
        let s = &self.spec.search;
        let data = dataset::make(env, self.spec.data.as_ref(), s.episodes, self.spec.seed, self.role.datasets(), d)?;
        let enc = Encoded::new(&data, env.actions(), s.actions).map_err(|e| match e {
            // An action missing from a tiny dataset is the episode count's doing.
            Error::Data(m) => match &self.spec.data {
                Some(logged) => logged.too_few(self.role.datasets(), d, s.episodes, &m),
                None => Error::invalid(
                    "search.episodes",
                    s.episodes,
                    format!("too few for {} dataset {d}: {m}", self.role.name()),
                ),
            },
            other => other,
        })?;
        // Each network holds out a validation tail: it needs two rows (validation_fraction ≤ 0.5).
        for j in 0..enc.n_models() {
            let rows = enc.model_rows(j).1.len();
            if rows < 2 {
                if let Some(logged) = &self.spec.data {
                    let why = format!("a network gets only {rows} transition(s)");
                    return Err(logged.too_few(self.role.datasets(), d, s.episodes, &why));
                }
                return Err(Error::invalid(
                    "search.episodes",
                    s.episodes,
                    format!(
                        "gives {} dataset {d} only {rows} transition(s) for a network, which needs 2 to hold out a \
                         validation row; use more episodes",
                        self.role.name()
                    ),
                ));
            }
        }
        Ok((data, enc))
    }

    /// The network a setting stands for.
    pub fn network(&self, s: &Decoded) -> MlpParams {
        MlpParams {
            activation: s.activation,
            delta_min: s.delta_min,
            patience: s.patience,
            ..self.spec.search.network.clone()
        }
    }

    /// The FQI settings of a unit: the search's K, evaluated after the last iteration only (only
    /// its score counts for fitness).
    pub fn fqi_settings(&self) -> FqiSettings {
        let search = &self.spec.search;
        FqiSettings { algorithm: search.algorithm, iterations: search.iterations, eval_every: search.iterations }
    }

    /// The seeds of setting `s` on dataset `d`: the networks' from
    /// `(seed, "init", [activation, δ_min bits, patience, d])`, the evaluation's from
    /// `(seed, "eval/search", [d])` (`init/validation` and `eval/validation` for validation).
    pub fn seeds(&self, s: &Decoded, d: usize) -> (u64, u64) {
        let idx = [activation_code(s.activation), s.delta_min.to_bits(), s.patience as u64, d as u64];
        let eval = crate::rng::purpose::eval_role(self.role.name());
        (rng::derive(self.spec.seed, self.role.init_purpose(), &idx), rng::derive(self.spec.seed, &eval, &[d as u64]))
    }

    /// Runs FQI for setting `s` on search dataset `d`: a pure function of (spec, s, d).
    pub fn evaluate(&self, s: &Decoded, d: usize) -> Result<UnitResult> {
        self.evaluate_keeping(s, d, false).map(|(u, _)| u)
    }

    /// [`Evaluator::evaluate`], also returning the unit's last Q-function when `keep` is set and
    /// the run did not diverge (what `rollout --tuned` looks at).
    pub fn evaluate_keeping(&self, s: &Decoded, d: usize, keep: bool) -> Result<(UnitResult, Option<Model>)> {
        let t = Instant::now();
        let x = self.dataset(d)?;
        let (data, enc) = (&x.0, &x.1);
        let params = self.network(s);
        let (fit_seed, eval_seed) = self.seeds(s, d);
        let fqi = Fqi::new(self.spec.env.env(), data, enc, &params, self.fqi_settings(), fit_seed, eval_seed);
        let (rec, members) = fqi.run_keeping(|_| {})?;
        let offline = match self.spec.search.fitness.fqe() {
            Some(f) if rec.diverged.is_none() => {
                let env = self.spec.env.env();
                let seed = rng::derive(self.spec.seed, rng::purpose::FQE, &[]);
                let search = &self.spec.search;
                let held = self.heldout()?;
                let o = crate::offline::score(
                    &held,
                    env.actions(),
                    search.actions,
                    f,
                    &members,
                    env.gamma(),
                    search.iterations,
                    seed,
                )?;
                Some(o)
            }
            _ => None,
        };
        let model = (keep && rec.diverged.is_none()).then(|| {
            let (tool_version, commit) = crate::model::build_stamp();
            let search = &self.spec.search;
            let info = ModelInfo {
                tool_version,
                commit,
                source: format!("{} unit {}", self.role.name(), unit_id(s, d)),
                spec_hash: self.spec.hash(),
                env: self.spec.env.clone(),
                algorithm: search.algorithm,
                learner: LearnerConfig::Mlp(params.clone()),
                encoding: search.actions,
                actions: self.spec.env.env().actions().to_vec(),
                iterations: search.iterations,
                dataset: d,
                eval_seed,
                score: rec.final_score(),
            };
            Model { info, q: QFunction::Nets(members) }
        });
        let last = rec.iterations.last();
        let online = rec.final_score();
        let mut unit = UnitResult {
            setting: *s,
            dataset: d,
            score: match &offline {
                Some(o) => o.estimate.is_finite().then_some(o.estimate),
                None => online,
            },
            steps: if rec.diverged.is_some() { None } else { last.and_then(|r| r.steps) },
            diverged: rec.diverged.clone(),
            epochs: rec.iterations.iter().filter_map(|r| r.epochs).sum(),
            seconds: t.elapsed().as_secs_f64(),
            iterations: rec.iterations,
            rows: Some(network_rows(enc)),
            online: offline.as_ref().and(online),
            offline,
            spec_hash: Some(self.results_hash.clone()),
            checksum: None,
        };
        unit.checksum = Some(unit.content_checksum());
        Ok((unit, model))
    }

    /// Where a unit's result is stored.
    pub fn unit_path(&self, id: &str) -> PathBuf {
        self.store.path(id)
    }

    /// Computes a unit and stores it atomically.
    pub fn run_unit(&self, id: &str) -> Result<()> {
        let (s, d) = parse_unit_id(id)
            .ok_or_else(|| Error::invalid("unit", id, "must look like sigmoid_5.8e-1_601.d3 (setting.dataset)"))?;
        let r = self.evaluate(&s, d)?;
        if let Some(div) = &r.diverged {
            eprintln!("note: unit {id} diverged at iteration {} ({}): fitness −∞", div.iteration, div.reason);
        }
        write_json(&self.unit_path(id), &r)
    }

    /// Reads a stored unit, if present, whole and this run's: a file that does not parse, whose
    /// checksum or spec hash disagrees, or that names another unit is treated as absent (so it
    /// is computed again), with a warning the first time.
    pub fn load_unit(&self, id: &str) -> Option<UnitResult> {
        match self.verified(id) {
            Ok(u) => u,
            Err(problem) => {
                if self.warned.lock().expect("warned").insert(id.to_string()) {
                    eprintln!("warning: {}: {problem}; it will be computed again", self.unit_path(id).display());
                }
                None
            }
        }
    }

    /// A stored unit without a warning: `Ok(None)` if there is no file, `Err` with what is wrong
    /// if it does not parse, names another unit, or its checksum or spec hash disagrees.
    pub fn verified(&self, id: &str) -> std::result::Result<Option<UnitResult>, String> {
        let mut path = self.unit_path(id);
        if !path.is_file() {
            match self.also.as_ref().map(|a| a.path(id)).filter(|p| p.is_file()) {
                Some(p) => path = p,
                None => return Ok(None),
            }
        }
        let u = read_json::<UnitResult>(&path).map_err(|e| format!("unreadable ({e})"))?;
        match self.check_unit(&u, id) {
            None => Ok(Some(u)),
            Some(p) => Err(p),
        }
    }

    /// The stored units (files of the units folder) that do not verify ([`Self::verified`]), each
    /// with its path and what is wrong, sorted by path: what `status` reports.
    pub fn unverified(&self) -> Vec<(PathBuf, String)> {
        self.store
            .ids()
            .into_iter()
            .filter_map(|id| self.verified(&id).err().map(|p| (self.unit_path(&id), p)))
            .collect()
    }

    fn check_unit(&self, u: &UnitResult, id: &str) -> Option<String> {
        if unit_id(&u.setting, u.dataset) != id {
            return Some(format!("holds unit {}", unit_id(&u.setting, u.dataset)));
        }
        match &u.checksum {
            Some(c) if *c != u.content_checksum() => {
                return Some("its checksum does not match its content (damaged or edited)".into());
            }
            None if self.checksummed => return Some(MISSING_CHECKSUM.into()),
            _ => {}
        }
        match &u.spec_hash {
            Some(h) if *h != self.results_hash => Some(format!("computed under another spec (hash {h})")),
            _ => None,
        }
    }
}

impl Units for Evaluator {
    fn store(&self) -> &UnitStore {
        &self.store
    }

    fn stored(&self, id: &str) -> bool {
        self.load_unit(id).is_some()
    }

    fn compute(&self, id: &str) -> Result<()> {
        self.run_unit(id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ga::chromosome::{GeneRanges, decode};

    #[test]
    fn unit_ids_round_trip_exactly() {
        let r = GeneRanges::default();
        for (c, d) in [([0, 58, 2, 60, 2], 3), ([2, 10, 8, 99, 0], 11), ([1, 99, 8, 10, 1], 0)] {
            let s = decode(&c, &r);
            let (back, bd) = parse_unit_id(&unit_id(&s, d)).unwrap();
            assert_eq!(
                (back.activation, back.delta_min.to_bits(), back.patience, bd),
                (s.activation, s.delta_min.to_bits(), s.patience, d)
            );
        }
        assert_eq!(unit_id(&decode(&[0, 58, 2, 60, 2], &r), 3), "sigmoid_5.8e-1_601.d3");
        for bad in ["junk", "sigmoid_0.5.d1", "swish_0.5_3.d1", "relu_0.5_3_4.d1", "relu_NaN_3.d1", "relu_0.5_3.dx"] {
            assert_eq!(parse_unit_id(bad), None, "{bad}");
        }
    }

    #[test]
    fn settings_that_decode_alike_share_an_id() {
        let r = GeneRanges::default();
        // b_p = 0: a_p 40..49 all give patience 5.
        let ids: Vec<String> = (40..50).map(|a_p| unit_id(&decode(&[0, 60, 3, a_p, 0], &r), 0)).collect();
        assert!(ids.iter().all(|i| *i == ids[0]), "{ids:?}");
        assert_ne!(ids[0], unit_id(&decode(&[0, 60, 3, 50, 0], &r), 0));
    }

    #[test]
    fn expected_cost_orders_slow_settings_first() {
        let slow = Decoded { activation: Activation::Sigmoid, delta_min: 1e-8, patience: 991 };
        let thesis = Decoded { activation: Activation::Sigmoid, delta_min: 0.011, patience: 75 };
        let fast = Decoded { activation: Activation::Relu, delta_min: 0.9, patience: 2 };
        let c = |s: &Decoded| expected_cost(s, 5000);
        assert!(c(&slow) > c(&thesis) && c(&thesis) > c(&fast));
        assert_eq!(c(&slow), 5000.0, "capped at the epoch cap");
    }
}
