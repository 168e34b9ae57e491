//! The offline fitness (beyond the thesis, issue 61): a setting's FQI policies scored on held-out
//! logged episodes by Fitted Q Evaluation ([`crate::fqe`]) instead of in the simulator.
//!
//! `search.fitness` is `{"kind": "online"}` (the thesis's, the default, left out of spec.json) or
//! `{"kind": "fqe", …}`. With `fqe`, one held-out set of `episodes` episodes (the `heldout`
//! dataset role: its own collection stream, or its own slot of a disjoint logged split) is shared
//! by every unit of a run, so all settings are scored on the same episodes; no search, validation
//! or comparison dataset holds any of them. A unit's score is the FQE estimate of its greedy
//! policy from the held-out episodes' first observations, in the units of the env's score:
//!
//! - `gamma` and `average` say which estimand: left out, they are the env's evaluation's own
//!   (`return`: γ = 1; `discounted_return`: the env's γ; `mean_reward_per_step`: γ = 1 and the
//!   estimate divided by `iterations`), so with `iterations` equal to the evaluation's steps the
//!   estimand is the finite-horizon value the online score measures, from the logged start states.
//! - The FQE learner and its `iterations` are fixed by the spec, never by the search.
//!
//! Beside the estimate each unit records two criteria that need no extra fit, as baselines of
//! the agreement report: FQI's own value (`max_a Q(s₀, a)` at the same starts) and the TD error
//! of its Q-function on the held-out transitions.

use crate::dataset::Dataset;
use crate::env::{Env, ScoreKind};
use crate::error::{Result, ensure};
use crate::fqe::{self, FqeSettings};
use crate::learn::actions::{ActionEncoding, QModel, argmax};
use crate::learn::extra_trees::ExtraTreesParams;
use crate::learn::{Learner, Regressor};
use serde::{Deserialize, Serialize};

/// `search.fitness`: how a setting's FQI policies are scored.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Fitness {
    /// In the simulator, under the env's evaluation protocol (SPEC §5).
    #[default]
    Online,
    /// By FQE on held-out logged episodes.
    Fqe(FqeFitness),
}

impl Fitness {
    /// Whether this is the thesis's online fitness (left out of spec.json).
    pub fn is_online(&self) -> bool {
        *self == Fitness::Online
    }

    /// The FQE settings of an offline fitness.
    pub fn fqe(&self) -> Option<&FqeFitness> {
        match self {
            Fitness::Online => None,
            Fitness::Fqe(f) => Some(f),
        }
    }

    /// Fills the estimand an offline fitness leaves out from `env`'s evaluation.
    pub fn resolve(&mut self, env: &dyn Env) {
        if let Fitness::Fqe(f) = self {
            let kind = env.eval().score;
            f.gamma.get_or_insert(if kind == ScoreKind::DiscountedReturn { env.gamma() } else { 1.0 });
            f.average.get_or_insert(kind == ScoreKind::MeanRewardPerStep);
        }
    }

    /// Validates the settings; errors name the field (under `fitness`).
    pub fn validate(&self, horizon: usize) -> Result<()> {
        let Fitness::Fqe(f) = self else { return Ok(()) };
        crate::limits::episodes("fitness.episodes", f.episodes, horizon)?;
        crate::limits::within("fitness.iterations", f.iterations, 1, crate::limits::ITERATIONS)?;
        if let Some(g) = f.gamma {
            ensure(g.is_finite() && (0.0..=1.0).contains(&g), "fitness.gamma", g, "must be in [0, 1]")?;
        }
        f.learner.check().map_err(|e| e.within("fitness.learner"))
    }
}

/// `search.fitness` with `"kind": "fqe"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FqeFitness {
    /// Episodes of the held-out set.
    pub episodes: usize,
    /// FQE's regressor (fixed: the search never tunes it).
    pub learner: ExtraTreesParams,
    /// FQE's fits K: the horizon of the estimated return.
    pub iterations: usize,
    /// The estimand's discount (the env's evaluation's when left out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    /// Whether the estimate is divided by `iterations` (a mean reward per step; the env's
    /// evaluation's when left out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub average: Option<bool>,
}

impl FqeFitness {
    /// FQE's settings.
    pub fn settings(&self) -> FqeSettings {
        FqeSettings { iterations: self.iterations, gamma: self.gamma.unwrap_or(1.0) }
    }

    /// What a return over `steps` steps is divided by to be in the score's units.
    fn scale(&self, steps: usize) -> f64 {
        if self.average.unwrap_or(false) { steps.max(1) as f64 } else { 1.0 }
    }

    /// One line for reports: which estimand, from what.
    pub fn describe(&self) -> String {
        let g = self.gamma.unwrap_or(1.0);
        let what = if self.average.unwrap_or(false) {
            format!("mean reward per step over {} steps", self.iterations)
        } else if g == 1.0 {
            format!("return over {} steps", self.iterations)
        } else {
            format!("γ = {g} discounted return, cut at {} steps", self.iterations)
        };
        format!(
            "offline fitness: FQE ({} Extra-Trees, K = {}) on {} held-out episodes, the {what} from their first states",
            self.learner.n_trees, self.iterations, self.episodes
        )
    }
}

/// What the offline fitness measured of one Q-function.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OfflineScore {
    /// The FQE estimate of the greedy policy's value (the unit's score).
    pub estimate: f64,
    /// FQI's own value at the held-out starts: the mean of `max_a Q(s₀, a)` (scaled as the
    /// estimate, by FQI's K when it is a mean per step).
    pub own_value: f64,
    /// The mean squared TD error of the Q-function on the held-out transitions, under the env's γ.
    pub td_error: f64,
    /// Held-out transitions each FQE fit was fitted on.
    pub rows: usize,
    /// FQE fits (its K).
    pub fits: usize,
}

/// Scores the greedy policy of `members` (a Q-function of FQI's, summed over its members) on the
/// held-out set `held`. `fqi_gamma` and `fqi_iterations` are FQI's, for the two baselines.
#[allow(clippy::too_many_arguments)]
pub fn score<M: Regressor>(
    held: &Dataset,
    actions: &[f64],
    encoding: ActionEncoding,
    fitness: &FqeFitness,
    members: &[QModel<M>],
    fqi_gamma: f64,
    fqi_iterations: usize,
    seed: u64,
) -> Result<OfflineScore> {
    let (na, od, n) = (actions.len(), held.obs_dim, held.len());
    // Q(·, a) of FQI's Q-function at every next state and episode start, computed once: the
    // policy's actions, its own value and the TD targets all read them.
    let (mut scratch, mut row) = (vec![0.0; na], vec![0.0; na]);
    let mut q_of = |states: &[f64], rows: &mut dyn Iterator<Item = usize>| -> Vec<f64> {
        let mut out = Vec::new();
        for i in rows {
            row.fill(0.0);
            for m in members {
                m.add_q_values(&states[i * od..(i + 1) * od], actions, &mut scratch, &mut row);
            }
            out.extend_from_slice(&row);
        }
        out
    };
    let starts = fqe::starts(held);
    let q_next = q_of(&held.next_state, &mut (0..n));
    let q_first = q_of(&held.state, &mut starts.iter().copied());
    let greedy = |q: &[f64]| q.chunks_exact(na).map(argmax).collect::<Vec<usize>>();
    let (next, first) = (greedy(&q_next), greedy(&q_first));
    let chosen = fqe::Chosen { next: &next, first: &first };
    let e = fqe::evaluate_chosen(held, actions, encoding, &fitness.learner, fitness.settings(), chosen, seed)?;
    let own = first.iter().enumerate().map(|(j, &a)| q_first[j * na + a]).sum::<f64>() / starts.len().max(1) as f64;
    let mut sq = 0.0;
    for i in 0..n {
        let s = &held.state[i * od..(i + 1) * od];
        let here: f64 = members.iter().map(|m| m.q_at(s, held.action[i], actions).unwrap_or(f64::NAN)).sum();
        let best = q_next[i * na + next[i]];
        let target = held.reward[i] + if held.absorbing[i] { 0.0 } else { fqi_gamma * best };
        sq += (target - here).powi(2);
    }
    Ok(OfflineScore {
        estimate: e.value / fitness.scale(fitness.iterations),
        own_value: own / fitness.scale(fqi_iterations),
        td_error: sq / n.max(1) as f64,
        rows: n,
        fits: fitness.iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::EnvConfig;

    fn fqe(json: &str) -> Fitness {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn the_estimand_is_the_envs_score_unless_the_spec_says() {
        let spec = r#"{"kind": "fqe", "episodes": 50, "learner": {"n_trees": 5}, "iterations": 200}"#;
        for (env, gamma, average) in [("cartpole", 1.0, false), ("pendulum", 1.0, true), ("bicycle", 0.98, false)] {
            let mut f = fqe(spec);
            f.resolve(EnvConfig::by_name(env).unwrap().env());
            let f = f.fqe().unwrap().clone();
            assert_eq!((f.gamma, f.average), (Some(gamma), Some(average)), "{env}");
        }
        let mut f = fqe(r#"{"kind": "fqe", "episodes": 5, "learner": {}, "iterations": 9, "gamma": 0.9}"#);
        f.resolve(EnvConfig::by_name("pendulum").unwrap().env());
        assert_eq!(f.fqe().unwrap().gamma, Some(0.9));
        assert!(Fitness::default().is_online() && Fitness::default().fqe().is_none());
        assert_eq!(serde_json::to_string(&Fitness::Online).unwrap(), r#"{"kind":"online"}"#);
    }

    #[test]
    fn out_of_range_settings_name_their_field() {
        for (json, field) in [
            (r#"{"kind": "fqe", "episodes": 0, "learner": {}, "iterations": 9}"#, "fitness.episodes"),
            (r#"{"kind": "fqe", "episodes": 5, "learner": {}, "iterations": 0}"#, "fitness.iterations"),
            (r#"{"kind": "fqe", "episodes": 5, "learner": {}, "iterations": 9, "gamma": 1.5}"#, "fitness.gamma"),
            (r#"{"kind": "fqe", "episodes": 5, "learner": {"n_trees": 0}, "iterations": 9}"#, "fitness.learner"),
        ] {
            let e = fqe(json).validate(200).unwrap_err().to_string();
            assert!(e.contains(field), "{json}: {e}");
        }
        assert!(serde_json::from_str::<Fitness>(r#"{"kind": "fqe", "episodes": 5}"#).is_err());
        assert!(serde_json::from_str::<Fitness>(r#"{"kind": "psychic"}"#).is_err());
    }
}
