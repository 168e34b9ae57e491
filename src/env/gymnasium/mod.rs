//! Any discrete-action gymnasium environment, stepped by a Python worker (issue 39).
//!
//! A spec names the env (`"env": {"name": "gymnasium", "id": "Acrobot-v1", …}`); the dataset
//! policy, the horizon, γ and the evaluation come from the spec as for the built-in tasks. The
//! worker (`python/bfqi_gym_worker.py`, built into the binary) is started with the spec's Python
//! and speaks the protocol documented in that file; FQI, the learners and the GA stay in Rust.
//!
//! A gymnasium env has no state the tool can set, so it is not stepped through [`Env::step`]:
//! datasets ([`collect`]) and evaluations ([`LockStep`]) run whole episodes in the worker, each
//! `reset(seed=…)` with a seed drawn from the tool's streams and driven by actions the tool draws
//! or chooses. The first time a spec is read, the worker is asked for the env's spaces, which are
//! written into the spec as `env.probed`: a stored run reads them back without Python, and every
//! worker started later must report the same.

mod episodes;
mod wire;
mod worker;

pub use episodes::{BridgeStats, Image, LockStep, RawEpisode, Stepped, collect, stats};
pub use worker::Versions;

use super::{Env, EvalConfig, Outcome, ScoreKind};
use crate::error::{Error, Result, ensure};
use crate::rng::{Rng, below, uniform};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::sync::OnceLock;

/// The most observation values an env may have: FQI here learns from low-dimensional states.
pub const MAX_OBSERVATION: usize = 1024;
/// The most actions a greedy policy maximises over.
pub const MAX_ACTIONS: usize = 1024;

/// Settings of a gymnasium environment (`"name": "gymnasium"`). Values derived from them (the
/// action table, the protocol the [`Env`] trait shows) are computed once: make a changed config
/// through JSON, as specs are, not by assigning to a field of one already used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GymConfig {
    /// The registered id (`CartPole-v1`, `module:MyEnv-v0` imports `module` first).
    pub id: String,
    /// Keyword arguments of `gymnasium.make`.
    #[serde(default, skip_serializing_if = "Map::is_empty")]
    pub kwargs: Map<String, Value>,
    /// The Python that runs the worker; default `$BFQI_PYTHON`, else `python3`. Not part of any
    /// results hash: a run can move to a machine whose Python lives elsewhere.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub python: Option<String>,
    /// `gymnasium.make`'s `max_episode_steps` (default: the registered time limit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_episode_steps: Option<usize>,
    /// Step cap of a dataset episode (a cut, never absorbing).
    #[serde(default = "default_steps")]
    pub horizon: usize,
    /// Discount factor.
    #[serde(default = "default_gamma")]
    pub gamma: f64,
    /// The actions the greedy policy maximises over: gymnasium action ids of a `Discrete` space
    /// (default: all of them), or the actions to send to a `Box` space (required there): numbers
    /// for a one-value Box (they are also the learner's action feature), vectors otherwise (the
    /// learner then sees their index).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actions: Option<Vec<ActionValue>>,
    /// How dataset episodes choose actions.
    #[serde(default, skip_serializing_if = "DatasetPolicy::is_uniform")]
    pub dataset_policy: DatasetPolicy,
    /// `options` of the dataset episodes' `reset` (e.g. CartPole's `{"low": -0.2, "high": 0.2}`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reset_options: Option<Map<String, Value>>,
    /// The evaluation protocol.
    #[serde(default)]
    pub eval: GymEval,
    /// Seconds the worker may take to answer one message (start, a batch of episodes, a step)
    /// before it is stopped and the run fails naming the env. Not part of any results hash.
    #[serde(default = "default_timeout")]
    pub timeout_s: f64,
    /// What the worker reported of the env when the spec was first read (filled in, not written
    /// by hand); every worker started later must report the same.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probed: Option<Probed>,
    #[serde(skip)]
    derived: Derived,
}

fn default_steps() -> usize {
    200
}
fn default_gamma() -> f64 {
    0.99
}
fn default_timeout() -> f64 {
    120.0
}

/// One entry of `env.actions`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum ActionValue {
    /// A Discrete action id, or the value of a one-value Box.
    Scalar(f64),
    /// The vector sent to a Box of several values.
    Vector(Vec<f64>),
}

impl<'de> Deserialize<'de> for ActionValue {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        // By hand, so that a wrong entry is told what is expected, not "untagged enum ActionValue".
        match serde_json::Value::deserialize(d)? {
            serde_json::Value::Number(n) => n.as_f64().map(ActionValue::Scalar),
            serde_json::Value::Array(v) => {
                v.iter().map(serde_json::Value::as_f64).collect::<Option<_>>().map(ActionValue::Vector)
            }
            _ => None,
        }
        .ok_or_else(|| {
            serde::de::Error::custom(
                "an action is a number (a Discrete id, a one-value Box) or an array of numbers (a Box)",
            )
        })
    }
}

impl std::fmt::Display for ActionValue {
    /// As written in the spec: `2`, `[0.5, -1]`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ActionValue::Scalar(x) => write!(f, "{x}"),
            ActionValue::Vector(v) => {
                let items: Vec<String> = v.iter().map(|x| x.to_string()).collect();
                write!(f, "[{}]", items.join(", "))
            }
        }
    }
}

/// A time limit for people: its steps, or `none`.
fn limit(steps: Option<usize>) -> String {
    steps.map_or("none".into(), |n| n.to_string())
}

/// `env.dataset_policy`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DatasetPolicy {
    /// Uniform over `env.actions` (the thesis's random policy).
    #[default]
    Uniform,
    /// Uniform over a one-value Box's `[low, high]`, as the built-in pendulum's torques (the
    /// actions are then continuous: use the `input` encoding).
    UniformBox,
}

impl DatasetPolicy {
    fn is_uniform(&self) -> bool {
        *self == DatasetPolicy::Uniform
    }
}

/// `env.eval`: the evaluation protocol of a gymnasium env.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GymEval {
    /// Episodes per evaluation; the score is their mean.
    #[serde(default = "default_episodes")]
    pub episodes: usize,
    /// Steps per episode unless it terminates or is truncated first.
    #[serde(default = "default_steps")]
    pub steps: usize,
    /// How rewards become the score.
    #[serde(default = "default_score")]
    pub score: ScoreKind,
    /// `options` of the evaluation episodes' `reset`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reset_options: Option<Map<String, Value>>,
}

fn default_episodes() -> usize {
    10
}
fn default_score() -> ScoreKind {
    ScoreKind::Return
}

impl Default for GymEval {
    fn default() -> Self {
        GymEval { episodes: default_episodes(), steps: default_steps(), score: default_score(), reset_options: None }
    }
}

/// What the worker reports of an env (`env.probed`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Probed {
    /// The observation space: `box` (flattened) or `discrete` (one value).
    pub observation: Space,
    /// The action space.
    pub action: Space,
    /// The time limit of `make` (registered, or `env.max_episode_steps`).
    pub max_episode_steps: Option<usize>,
    /// Simulated seconds per step (the env's `dt` or `tau`), when it has one.
    pub dt: Option<f64>,
    /// Whether `render_mode="rgb_array"` is offered (rollout frames).
    pub rgb_array: bool,
}

/// A gymnasium space, as the worker describes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Space {
    /// `Discrete(n, start)`.
    Discrete {
        /// Number of values.
        n: u64,
        /// The first value.
        start: i64,
    },
    /// `Box(low, high, shape, dtype)`; unbounded ends are `null`.
    Box {
        /// Its shape.
        shape: Vec<usize>,
        /// Lower bounds, flattened.
        low: Vec<Option<f64>>,
        /// Upper bounds, flattened.
        high: Vec<Option<f64>>,
        /// numpy dtype name.
        dtype: String,
    },
    /// Anything else (not supported).
    Other {
        /// Python's repr of the space.
        repr: String,
    },
}

impl Space {
    /// Values in a flattened element of the space.
    pub fn dim(&self) -> usize {
        match self {
            Space::Discrete { .. } => 1,
            Space::Box { shape, .. } => shape.iter().product(),
            Space::Other { .. } => 0,
        }
    }

    fn describe(&self) -> String {
        match self {
            Space::Discrete { n, start } if *start == 0 => format!("Discrete({n})"),
            Space::Discrete { n, start } => format!("Discrete({n}, start={start})"),
            Space::Box { shape, dtype, .. } => format!("Box(shape {shape:?}, {dtype})"),
            Space::Other { repr } => repr.clone(),
        }
    }
}

/// Values computed once from the settings and `probed` (never serialised; equal for equal
/// settings).
#[derive(Debug, Clone, Default)]
struct Derived(OnceLock<Tables>);

impl PartialEq for Derived {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

#[derive(Debug, Clone)]
struct Tables {
    /// The learner's feature value of each action.
    features: Vec<f64>,
    /// The vector sent for each action (Box with vector actions), else empty.
    vectors: Vec<Vec<f64>>,
    /// The protocol as the [`Env`] trait shows it (no start box: the env's reset draws starts).
    eval: EvalConfig,
}

/// The Python a spec that names none runs: `$BFQI_PYTHON`, else `python3` (the gymnasium worker's
/// and the Minari bridge's).
pub fn default_python() -> String {
    std::env::var("BFQI_PYTHON").ok().filter(|p| !p.is_empty()).unwrap_or_else(|| "python3".to_string())
}

impl GymConfig {
    /// The Python that runs the worker: `env.python`, else `$BFQI_PYTHON`, else `python3`.
    pub fn python(&self) -> String {
        self.python.clone().unwrap_or_else(default_python)
    }

    fn tables(&self) -> &Tables {
        self.derived.0.get_or_init(|| {
            let (features, vectors) = match (&self.probed, &self.actions) {
                (_, Some(list)) if list.iter().any(|a| matches!(a, ActionValue::Vector(_))) => (
                    (0..list.len()).map(|i| i as f64).collect(),
                    list.iter()
                        .map(|a| match a {
                            ActionValue::Vector(v) => v.clone(),
                            ActionValue::Scalar(x) => vec![*x],
                        })
                        .collect(),
                ),
                (_, Some(list)) => {
                    (list.iter().map(|a| if let ActionValue::Scalar(x) = a { *x } else { 0.0 }).collect(), vec![])
                }
                (Some(Probed { action: Space::Discrete { n, start }, .. }), None) => {
                    ((0..(*n).min(MAX_ACTIONS as u64)).map(|i| (*start + i as i64) as f64).collect(), vec![])
                }
                _ => (vec![], vec![]),
            };
            let eval = EvalConfig {
                episodes: self.eval.episodes,
                steps: self.eval.steps,
                score: self.eval.score,
                start: vec![],
            };
            Tables { features, vectors, eval }
        })
    }

    /// The action sent to the env for a feature value (a Discrete id, a Box value, or the index
    /// of a Box vector), into `out`.
    pub fn gym_action(&self, feature: f64, out: &mut Vec<f64>) {
        let t = self.tables();
        if t.vectors.is_empty() {
            out.push(feature);
        } else {
            out.extend_from_slice(&t.vectors[feature as usize]);
        }
    }

    /// Values per action sent to the env.
    pub fn action_dim(&self) -> usize {
        self.tables().vectors.first().map_or(1, Vec::len)
    }

    /// Values per observation.
    pub fn obs_len(&self) -> usize {
        self.probed.as_ref().map_or(0, |p| p.observation.dim())
    }

    /// The Python, gymnasium, numpy and minari versions its worker runs (starting one if none is
    /// open), for run records.
    pub fn versions(&self) -> Result<Versions> {
        worker::versions(self)
    }

    /// Asks a worker for the env's spaces when the settings do not hold them yet (the first time
    /// a spec is read). Errors name their field in full (`env.python`).
    pub fn resolve(&mut self) -> Result<()> {
        if self.probed.is_none() {
            self.check_fields().map_err(|e| e.within("env"))?;
            self.probed = Some(worker::probe(self)?);
            self.derived = Derived::default();
        }
        Ok(())
    }

    fn check_fields(&self) -> Result<()> {
        ensure(!self.id.trim().is_empty(), "id", "\"\"", "must name a registered gymnasium env, e.g. CartPole-v1")?;
        ensure(self.gamma > 0.0 && self.gamma <= 1.0, "gamma", self.gamma, "must be in (0, 1]")?;
        crate::limits::within("horizon", self.horizon, 1, crate::limits::EVAL_STEPS)?;
        crate::limits::within("eval.episodes", self.eval.episodes, 1, crate::limits::EVAL_EPISODES)?;
        crate::limits::within("eval.steps", self.eval.steps, 1, crate::limits::EVAL_STEPS)?;
        if let Some(m) = self.max_episode_steps {
            ensure(m >= 1, "max_episode_steps", m, "must be ≥ 1")?;
        }
        ensure(
            self.timeout_s.is_finite() && (0.1..=86_400.0).contains(&self.timeout_s),
            "timeout_s",
            self.timeout_s,
            "must be in [0.1, 86400] seconds",
        )?;
        if let Some(p) = &self.python {
            ensure(!p.trim().is_empty(), "python", "\"\"", "must name a Python executable, e.g. python3")?;
        }
        if let Some(list) = &self.actions {
            let n = list.len();
            ensure(
                (1..=MAX_ACTIONS).contains(&n),
                "actions",
                format!("{n} actions"),
                &format!("must list 1 to {MAX_ACTIONS} actions"),
            )?;
            for (i, a) in list.iter().enumerate() {
                let ok = match a {
                    ActionValue::Scalar(x) => x.is_finite(),
                    ActionValue::Vector(v) => !v.is_empty() && v.iter().all(|x| x.is_finite()),
                };
                ensure(ok, &format!("actions[{i}]"), a.to_string(), "must be finite (a vector must not be empty)")?;
            }
        }
        Ok(())
    }

    /// Checks every setting (no Python: the spaces come from `probed`); errors name the field
    /// (without the `env.` prefix, which the caller adds).
    pub fn validate(&self) -> Result<()> {
        self.check_fields()?;
        let Some(p) = &self.probed else {
            return Err(Error::invalid("probed", "missing", "is filled in when the spec is read; do not remove it"));
        };
        self.check_probed(p)
    }

    fn check_probed(&self, p: &Probed) -> Result<()> {
        let id = &self.id;
        let supported = "supported are Discrete, and Box with env.actions listing the actions to send";
        match &p.observation {
            Space::Discrete { .. } => {}
            Space::Box { .. } => {
                let d = p.observation.dim();
                ensure(
                    (1..=MAX_OBSERVATION).contains(&d),
                    "id",
                    id,
                    &format!("has observations of {d} values; FQI here needs 1 to {MAX_OBSERVATION}"),
                )?;
            }
            other => {
                return Err(Error::invalid(
                    "id",
                    id,
                    format!(
                        "has the observation space {}, which is not supported (supported are Box, flattened, and Discrete)",
                        other.describe()
                    ),
                ));
            }
        }
        let policy_box = self.dataset_policy == DatasetPolicy::UniformBox;
        match (&p.action, &self.actions) {
            (Space::Discrete { n, start }, list) => {
                ensure(
                    *n as usize <= MAX_ACTIONS,
                    "id",
                    id,
                    &format!(
                        "has {n} discrete actions; at most {MAX_ACTIONS} are supported (list some in env.actions)"
                    ),
                )?;
                ensure(
                    !policy_box,
                    "dataset_policy",
                    "uniform_box",
                    &format!("needs a Box action space; {id} has {}", p.action.describe()),
                )?;
                for (i, a) in list.iter().flatten().enumerate() {
                    let ok = matches!(a, ActionValue::Scalar(x) if x.fract() == 0.0 && *x >= *start as f64 && *x < (*start + *n as i64) as f64);
                    ensure(
                        ok,
                        &format!("actions[{i}]"),
                        a.to_string(),
                        &format!(
                            "must be an action id of {id}'s {}: an integer in {start}..{}",
                            p.action.describe(),
                            *start + *n as i64
                        ),
                    )?;
                }
            }
            (Space::Box { .. }, None) => {
                return Err(Error::invalid(
                    "actions",
                    "missing",
                    format!(
                        "{id} has the continuous action space {}; {supported} (e.g. \"actions\": [-2.0, 0.0, 2.0] for a one-value Box)",
                        p.action.describe()
                    ),
                ));
            }
            (Space::Box { low, high, .. }, Some(list)) => {
                let dim = p.action.dim();
                for (i, a) in list.iter().enumerate() {
                    let v: Vec<f64> = match a {
                        ActionValue::Scalar(x) => vec![*x],
                        ActionValue::Vector(v) => v.clone(),
                    };
                    ensure(
                        v.len() == dim,
                        &format!("actions[{i}]"),
                        a.to_string(),
                        &format!(
                            "must have {dim} value(s), as {id}'s {} (a number for a one-value Box)",
                            p.action.describe()
                        ),
                    )?;
                    for (j, x) in v.iter().enumerate() {
                        let (lo, hi) = (low[j].unwrap_or(f64::NEG_INFINITY), high[j].unwrap_or(f64::INFINITY));
                        ensure(
                            (lo..=hi).contains(x),
                            &format!("actions[{i}]"),
                            a.to_string(),
                            &format!("must lie in {id}'s action bounds [{lo}, {hi}] (value {j})"),
                        )?;
                    }
                }
                if policy_box {
                    let finite = low.first().copied().flatten().is_some() && high.first().copied().flatten().is_some();
                    ensure(
                        dim == 1 && finite && list.iter().all(|a| matches!(a, ActionValue::Scalar(_))),
                        "dataset_policy",
                        "uniform_box",
                        "needs a bounded one-value Box with numbers in env.actions",
                    )?;
                }
            }
            (other, _) => {
                return Err(Error::invalid(
                    "id",
                    id,
                    format!("has the action space {}, which is not supported; {supported}", other.describe()),
                ));
            }
        }
        let features = &self.tables().features;
        let mut sorted = features.clone();
        sorted.sort_by(f64::total_cmp);
        sorted.dedup();
        ensure(sorted.len() == features.len(), "actions", format!("{features:?}"), "must not repeat an action")?;
        if let Some(limit) = p.max_episode_steps {
            for (field, v) in [("horizon", self.horizon), ("eval.steps", self.eval.steps)] {
                ensure(
                    v <= limit,
                    field,
                    v,
                    &format!(
                        "must be ≤ {limit}, {id}'s max_episode_steps (gymnasium truncates its episodes there); raise env.max_episode_steps to go further"
                    ),
                )?;
            }
        }
        Ok(())
    }

    /// The worker's description of the env must be the one recorded.
    pub(crate) fn check_same(&self, got: &Probed) -> Result<()> {
        match &self.probed {
            Some(p) if p != got => Err(Error::Failed(format!(
                "gymnasium env {}: the worker reports observation {} and action {} (time limit {}), but env.probed \
                 recorded observation {} and action {} (time limit {}): was gymnasium or the env changed since?",
                self.id,
                got.observation.describe(),
                got.action.describe(),
                limit(got.max_episode_steps),
                p.observation.describe(),
                p.action.describe(),
                limit(p.max_episode_steps)
            ))),
            _ => Ok(()),
        }
    }

    /// Refuses a recorded `env.probed` that is not what the env's worker reports now (`got`): one
    /// copied from another env's spec, or recorded before gymnasium changed. Errors name the field
    /// without the `env.` prefix, which the caller adds.
    pub fn check_recorded(&self, recorded: &Probed, got: &Probed) -> Result<()> {
        let show = |p: &Probed| {
            format!(
                "observation {}, action {}, time limit {}",
                p.observation.describe(),
                p.action.describe(),
                limit(p.max_episode_steps)
            )
        };
        ensure(
            recorded == got,
            "probed",
            show(recorded),
            &format!(
                "is not what {}'s worker reports ({}): copied from another env's spec, or recorded before gymnasium or the env changed; remove env.probed, it is filled in when the spec is read",
                self.id,
                show(got)
            ),
        )
    }

    /// Clears the settings that decide no result (the Python, the timeout), for results hashes.
    pub fn for_hash(&mut self) {
        self.python = None;
        self.timeout_s = default_timeout();
    }
}

impl Env for GymConfig {
    fn name(&self) -> &str {
        &self.id
    }
    fn state_dim(&self) -> usize {
        self.obs_len()
    }
    fn obs_dim(&self) -> usize {
        self.obs_len()
    }
    fn observe(&self, state: &[f64], obs: &mut [f64]) {
        obs.copy_from_slice(state);
    }
    fn actions(&self) -> &[f64] {
        &self.tables().features
    }
    fn gamma(&self) -> f64 {
        self.gamma
    }
    fn horizon(&self) -> usize {
        self.horizon
    }
    fn dataset_start(&self, _: &mut Rng, _: &mut [f64]) {
        unreachable!("a gymnasium env draws its starts in reset(); datasets go through gymnasium::collect")
    }
    fn dataset_action(&self, rng: &mut Rng) -> f64 {
        let f = &self.tables().features;
        match (self.dataset_policy, &self.probed) {
            (DatasetPolicy::UniformBox, Some(Probed { action: Space::Box { low, high, dtype, .. }, .. })) => {
                let (lo, hi) = (low[0].unwrap_or(0.0), high[0].unwrap_or(0.0));
                let v = uniform(rng, lo, hi);
                // The worker casts to the Box's dtype: record the value the env receives.
                if dtype == "float32" { v as f32 as f64 } else { v }
            }
            _ => f[below(rng, f.len().max(1) as u64) as usize],
        }
    }
    fn step(&self, _: &[f64], _: f64, _: &mut Rng, _: &mut [f64]) -> Outcome {
        unreachable!("a gymnasium env is stepped by its worker (gymnasium::LockStep)")
    }
    fn eval(&self) -> &EvalConfig {
        let e = &self.tables().eval;
        assert!(
            (e.episodes, e.steps, e.score) == (self.eval.episodes, self.eval.steps, self.eval.score),
            "a gymnasium config was changed in place after use (make it through JSON)"
        );
        e
    }
    fn gymnasium(&self) -> Option<&GymConfig> {
        Some(self)
    }
}

#[cfg(test)]
mod tests {
    use super::ActionValue;

    #[test]
    fn an_action_that_is_no_number_is_told_what_an_action_is() {
        assert_eq!(serde_json::from_str::<ActionValue>("2").unwrap(), ActionValue::Scalar(2.0));
        assert_eq!(serde_json::from_str::<ActionValue>("[1, -1]").unwrap(), ActionValue::Vector(vec![1.0, -1.0]));
        for bad in ["\"a\"", "[1, \"b\"]", "{}", "null"] {
            let e = serde_json::from_str::<ActionValue>(bad).unwrap_err().to_string();
            assert!(e.contains("an action is a number") && !e.contains("untagged"), "{bad}: {e}");
        }
    }
}
