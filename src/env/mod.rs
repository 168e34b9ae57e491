//! The three control tasks of the thesis (SPEC §1), behind one [`Env`] trait.
//!
//! An environment is its configuration: every constant, the horizon, γ, the discrete action set,
//! the start distributions and the evaluation protocol live in a serde struct whose `Default` is the
//! SPEC value. Stepping is a pure function of (state, action, rng).

mod bicycle;
mod cartpole;
mod check;
pub mod gymnasium;
mod pendulum;

pub use bicycle::BicycleConfig;
pub use cartpole::CartPoleConfig;
pub use check::LEARNER_MAX;
pub use gymnasium::GymConfig;
pub use pendulum::PendulumConfig;

use crate::error::{Error, Result, ensure};
use crate::rng::{Rng, uniform};
use serde::{Deserialize, Serialize};

/// The largest hidden-state dimension of any environment (the bicycle's 5); lets hot loops keep
/// states on the stack.
pub const MAX_STATE: usize = 5;

/// What one step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    /// The reward of the transition.
    pub reward: f64,
    /// True when the new state is a failure: the transition is absorbing and the episode ends.
    pub failed: bool,
}

/// How an evaluation episode's rewards become a score.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScoreKind {
    /// Sum of rewards divided by the steps taken (pendulum).
    MeanRewardPerStep,
    /// Undiscounted sum of rewards (cart-pole).
    Return,
    /// Σ γ^t r_t (bicycle).
    DiscountedReturn,
}

impl ScoreKind {
    /// Whether reports show steps survived beside the score: a discounted return hides how long
    /// an episode lasted (a return counts the steps; a per-step mean runs every step).
    pub fn hides_steps(self) -> bool {
        self == ScoreKind::DiscountedReturn
    }
}

/// The evaluation protocol of an environment (SPEC §1, "Evaluation").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalConfig {
    /// Episodes per evaluation; the score is their mean.
    pub episodes: usize,
    /// Steps per episode unless it fails first.
    pub steps: usize,
    /// How rewards become the score.
    pub score: ScoreKind,
    /// Uniform box of start states, one `[lo, hi]` per hidden-state variable (`lo == hi` fixes it).
    pub start: Vec<[f64; 2]>,
}

impl EvalConfig {
    fn validate(&self, state_dim: usize) -> Result<()> {
        crate::limits::within("eval.episodes", self.episodes, 1, crate::limits::EVAL_EPISODES)?;
        crate::limits::within("eval.steps", self.steps, 1, crate::limits::EVAL_STEPS)?;
        validate_box(&self.start, state_dim, "eval.start")
    }
}

/// Checks a start box: one finite `[lo, hi]` with lo ≤ hi per state variable.
pub(crate) fn validate_box(b: &[[f64; 2]], dim: usize, field: &str) -> Result<()> {
    ensure(b.len() == dim, field, format!("{} ranges", b.len()), &format!("must have {dim} [lo, hi] ranges"))?;
    for (i, r) in b.iter().enumerate() {
        ensure(
            r[0].is_finite() && r[1].is_finite() && r[0] <= r[1],
            &format!("{field}[{i}]"),
            format!("[{}, {}]", r[0], r[1]),
            "must be finite with lo ≤ hi",
        )?;
    }
    Ok(())
}

/// Draws a state uniformly from a box.
pub(crate) fn draw_box(b: &[[f64; 2]], rng: &mut Rng, state: &mut [f64]) {
    for (s, r) in state.iter_mut().zip(b) {
        *s = uniform(rng, r[0], r[1]);
    }
}

/// `sign` as numpy defines it: 0 at 0. (`f64::signum(0.0)` is 1, which would be wrong here.)
#[inline]
pub(crate) fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// A control task: a deterministic function of (state, action, rng).
///
/// States are the hidden simulator states (`state_dim` values); learners see observations
/// (`obs_dim` values, produced by [`Env::observe`]). Actions are passed as their *feature value*:
/// a torque for the pendulum, an index for cart-pole and bicycle. [`Env::actions`] is the discrete
/// set the learner maximises over.
pub trait Env: Send + Sync {
    /// The name used on the command line (a gymnasium env's id).
    fn name(&self) -> &str;
    /// Hidden-state dimension.
    fn state_dim(&self) -> usize;
    /// Observation dimension (what a learner sees).
    fn obs_dim(&self) -> usize;
    /// Writes the observation of `state` into `obs`.
    fn observe(&self, state: &[f64], obs: &mut [f64]);
    /// The discrete actions the learner maximises over, as feature values. Ties go to the first.
    fn actions(&self) -> &[f64];
    /// Discount factor γ.
    fn gamma(&self) -> f64;
    /// Step cap of a dataset episode (a time-limit cut, never absorbing).
    fn horizon(&self) -> usize;
    /// Draws the start state of a dataset episode.
    fn dataset_start(&self, rng: &mut Rng, state: &mut [f64]);
    /// Draws the random policy's action (as a feature value).
    fn dataset_action(&self, rng: &mut Rng) -> f64;
    /// Advances `state` under `action` into `next`; may draw noise from `rng`.
    fn step(&self, state: &[f64], action: f64, rng: &mut Rng, next: &mut [f64]) -> Outcome;
    /// The evaluation protocol.
    fn eval(&self) -> &EvalConfig;
    /// A gymnasium env, stepped by its worker: datasets, evaluations and rollouts go through
    /// [`gymnasium`] instead of [`Env::step`]. `None` for the built-in simulators.
    fn gymnasium(&self) -> Option<&GymConfig> {
        None
    }
}

/// The names of the environments, in the order `bfqi-ga envs` lists them.
pub const NAMES: [&str; 3] = ["pendulum", "cartpole", "bicycle"];

/// The values `env.name` takes in a spec: the built-in environments and `gymnasium`.
const TAGS: [&str; 4] = ["pendulum", "cartpole", "bicycle", "gymnasium"];

/// An environment with its settings; the serialised form is `{"name": "...", ...settings}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "name", rename_all = "lowercase")]
pub enum EnvConfig {
    /// Swing-up pendulum (gym Pendulum-v0).
    Pendulum(PendulumConfig),
    /// Cart-pole (gym CartPole-v0 dynamics, thesis reward).
    Cartpole(CartPoleConfig),
    /// Bicycle balancing (Ernst et al. 2005).
    Bicycle(BicycleConfig),
    /// Any discrete-action gymnasium environment, stepped by a Python worker.
    Gymnasium(Box<GymConfig>),
}

impl<'de> Deserialize<'de> for EnvConfig {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let (name, rest) = crate::error::take_tag(d, "name")?;
        match name.as_str() {
            "pendulum" => crate::error::tagged(rest).map(EnvConfig::Pendulum),
            "cartpole" => crate::error::tagged(rest).map(EnvConfig::Cartpole),
            "bicycle" => crate::error::tagged(rest).map(EnvConfig::Bicycle),
            "gymnasium" => crate::error::tagged(rest).map(|g| EnvConfig::Gymnasium(Box::new(g))),
            other => Err(crate::error::unknown_tag("name", other, &TAGS)),
        }
    }
}

impl EnvConfig {
    /// The SPEC defaults of the environment called `name`.
    pub fn by_name(name: &str) -> Result<Self> {
        match name {
            "pendulum" => Ok(EnvConfig::Pendulum(PendulumConfig::default())),
            "cartpole" => Ok(EnvConfig::Cartpole(CartPoleConfig::default())),
            "bicycle" => Ok(EnvConfig::Bicycle(BicycleConfig::default())),
            "gymnasium" => Err(Error::Usage(
                "name a gymnasium env as gymnasium:<id> (e.g. gymnasium:CartPole-v1), or in a spec file: \"env\": \
                 {\"name\": \"gymnasium\", \"id\": \"CartPole-v1\", …} (see the README's Gymnasium section)"
                    .into(),
            )),
            _ => Err(Error::UnknownEnv { name: crate::error::shortened(name.to_string()), valid: NAMES.join(", ") }),
        }
    }

    /// The environment as a trait object.
    pub fn env(&self) -> &dyn Env {
        match self {
            EnvConfig::Pendulum(c) => c,
            EnvConfig::Cartpole(c) => c,
            EnvConfig::Bicycle(c) => c,
            EnvConfig::Gymnasium(c) => c.as_ref(),
        }
    }

    /// Completes the settings that need the environment itself: a gymnasium env's spaces, asked
    /// of a worker the first time a spec names it (`env.probed`). Nothing for the built-in ones.
    pub fn resolve(&mut self) -> Result<()> {
        match self {
            EnvConfig::Gymnasium(c) => c.resolve(),
            _ => Ok(()),
        }
    }

    /// The settings as results hashes see them: without those that decide no result (a
    /// gymnasium env's Python and timeout).
    pub fn for_hash(&self) -> EnvConfig {
        let mut c = self.clone();
        if let EnvConfig::Gymnasium(g) = &mut c {
            g.for_hash();
        }
        c
    }

    /// Checks every setting; the error names the field (prefixed `env.`).
    pub fn validate(&self) -> Result<()> {
        let r = match self {
            EnvConfig::Pendulum(c) => c.validate(),
            EnvConfig::Cartpole(c) => c.validate(),
            EnvConfig::Bicycle(c) => c.validate(),
            // Its dynamics are the worker's: checked (finite) on every step it returns.
            EnvConfig::Gymnasium(c) => return c.validate().map_err(|e| e.within("env")),
        };
        r.and_then(|_| self.env().eval().validate(self.env().state_dim())).map_err(|e| e.within("env"))?;
        self.check_dynamics()
    }

    /// The dynamics must stay finite and within what learners take for a few random episodes
    /// ([`check::dynamics`]), which names the constant at fault.
    fn check_dynamics(&self) -> Result<()> {
        check::dynamics(self)
    }

    /// Whether every action a dataset can take is one of the discrete actions (the `per_action`
    /// encoding needs it; the pendulum's random policy draws continuous torques).
    pub fn discrete_dataset_actions(&self) -> bool {
        let env = self.env();
        let mut rng = crate::rng::stream(0, crate::rng::purpose::ENV_CHECK_ACTIONS, &[]);
        (0..64).all(|_| env.actions().contains(&env.dataset_action(&mut rng)))
    }
}

/// Validates settings shared by every environment: positive finite constants, γ in (0, 1].
pub(crate) fn validate_common(gamma: f64, horizon: usize, actions: &[f64]) -> Result<()> {
    ensure(gamma > 0.0 && gamma <= 1.0, "gamma", gamma, "must be in (0, 1]")?;
    ensure(horizon >= 1, "horizon", horizon, "must be ≥ 1")?;
    ensure(!actions.is_empty(), "actions", "[]", "must list at least one action")?;
    for (i, a) in actions.iter().enumerate() {
        ensure(a.is_finite(), &format!("actions[{i}]"), a, "must be finite")?;
    }
    Ok(())
}

/// Validates that a physical constant is finite and strictly positive.
pub(crate) fn positive(field: &str, v: f64) -> Result<()> {
    ensure(v.is_finite() && v > 0.0, field, v, "must be finite and > 0")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_env_lists_valid_names() {
        let e = EnvConfig::by_name("acrobot").unwrap_err().to_string();
        assert!(e.contains("pendulum, cartpole, bicycle"), "{e}");
    }

    #[test]
    fn defaults_validate_and_round_trip_through_json() {
        for name in NAMES {
            let c = EnvConfig::by_name(name).unwrap();
            c.validate().unwrap();
            let json = serde_json::to_string(&c).unwrap();
            let back: EnvConfig = serde_json::from_str(&json).unwrap();
            assert_eq!(back, c);
            assert_eq!(back.env().name(), name);
        }
    }

    #[test]
    fn partial_json_takes_defaults_and_unknown_fields_are_refused() {
        let c: EnvConfig = serde_json::from_str(r#"{"name": "cartpole", "reward_factor": 3.75}"#).unwrap();
        match c {
            EnvConfig::Cartpole(c) => {
                assert_eq!(c.reward_factor, 3.75);
                assert_eq!(c.horizon, 200);
            }
            _ => panic!("wrong variant"),
        }
        let e = serde_json::from_str::<EnvConfig>(r#"{"name": "cartpole", "reward_facto": 3.75}"#);
        assert!(e.unwrap_err().to_string().contains("reward_facto"));
    }

    #[test]
    fn invalid_settings_name_the_field() {
        let c = CartPoleConfig { gamma: 1.5, ..Default::default() };
        let e = EnvConfig::Cartpole(c).validate().unwrap_err().to_string();
        assert!(e.contains("env.gamma"), "{e}");
    }

    #[test]
    fn sign_is_zero_at_zero() {
        assert_eq!(sign(0.0), 0.0);
        assert_eq!(sign(-0.0), 0.0);
        assert_eq!(sign(-3.0), -1.0);
        assert_eq!(sign(2.0), 1.0);
    }
}
