//! Evaluation protocols (SPEC §1, "Evaluation"): run a policy on the environment's evaluation
//! episodes and score it.
//!
//! Start states and noise come from `(eval_seed, "episode", e)` only, where the caller derives
//! `eval_seed` from (master seed, "eval", dataset index): FQI and B-FQI, every iteration and every
//! chromosome are scored on the same episodes (paired comparisons).

use crate::env::{Env, MAX_STATE, ScoreKind, draw_box};
use crate::rng::{self, Rng, stream};
use serde::{Deserialize, Serialize};

/// The result of evaluating a policy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// The protocol's score, averaged over the evaluation episodes.
    pub score: f64,
    /// Steps before failure (or the full episode), averaged over the evaluation episodes.
    pub steps: f64,
}

/// The seed of the evaluation episodes that go with dataset `index` under a master seed.
pub fn eval_seed(master: u64, index: usize) -> u64 {
    rng::derive(master, rng::purpose::EVAL, &[index as u64])
}

/// Runs `policy` (observation → index into [`Env::actions`]) on the evaluation episodes of `env`.
pub fn evaluate(env: &dyn Env, policy: &mut dyn FnMut(&[f64]) -> usize, eval_seed: u64) -> Score {
    let proto = env.eval();
    let (mut total_score, mut total_steps) = (0.0, 0.0);
    for e in 0..proto.episodes {
        let mut rng = stream(eval_seed, rng::purpose::EPISODE, &[e as u64]);
        let mut s = [0.0; MAX_STATE];
        draw_box(&proto.start, &mut rng, &mut s[..env.state_dim()]);
        let ep = episode(env, policy, &mut rng, &s[..env.state_dim()], proto.steps, |_| {});
        total_score += ep.score;
        total_steps += ep.steps as f64;
    }
    let n = proto.episodes as f64;
    Score { score: total_score / n, steps: total_steps / n }
}

/// One step of an episode, as [`episode`] shows it to its observer.
#[derive(Debug, Clone, Copy)]
pub struct StepView<'a> {
    /// 0-based step index.
    pub t: usize,
    /// The hidden state the action was taken in.
    pub state: &'a [f64],
    /// Index of the action taken (into [`Env::actions`]).
    pub action: usize,
    /// The transition's reward.
    pub reward: f64,
    /// The state reached.
    pub next: &'a [f64],
    /// Whether the state reached is a failure (the episode ends there).
    pub failed: bool,
}

/// What one episode produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Episode {
    /// The protocol's score of this episode (see [`ScoreKind`]).
    pub score: f64,
    /// Steps taken.
    pub steps: usize,
    /// Whether it ended in a failure.
    pub failed: bool,
}

/// Runs one episode of at most `max_steps` steps from `start`, drawing the environment's noise from
/// `rng`, scored under the environment's evaluation protocol; `observe` sees every step. The
/// evaluation protocol and the rollouts share this loop, so a rollout of an evaluation episode
/// reproduces its score exactly.
pub fn episode(
    env: &dyn Env,
    policy: &mut dyn FnMut(&[f64]) -> usize,
    rng: &mut Rng,
    start: &[f64],
    max_steps: usize,
    mut observe: impl FnMut(StepView<'_>),
) -> Episode {
    let kind = env.eval().score;
    let (sd, od) = (env.state_dim(), env.obs_dim());
    let actions = env.actions();
    let mut s = [0.0; MAX_STATE];
    let mut next = [0.0; MAX_STATE];
    let mut obs = [0.0; MAX_STATE];
    s[..sd].copy_from_slice(start);
    let (mut sum, mut discount, mut steps, mut failed) = (0.0, 1.0, 0usize, false);
    for t in 0..max_steps {
        env.observe(&s[..sd], &mut obs[..od]);
        let a = policy(&obs[..od]);
        let o = env.step(&s[..sd], actions[a], rng, &mut next[..sd]);
        sum += match kind {
            ScoreKind::DiscountedReturn => discount * o.reward,
            _ => o.reward,
        };
        observe(StepView { t, state: &s[..sd], action: a, reward: o.reward, next: &next[..sd], failed: o.failed });
        discount *= env.gamma();
        steps += 1;
        s = next;
        if o.failed {
            failed = true;
            break;
        }
    }
    let score = match kind {
        ScoreKind::MeanRewardPerStep => sum / steps.max(1) as f64,
        ScoreKind::Return | ScoreKind::DiscountedReturn => sum,
    };
    Episode { score, steps, failed }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::EnvConfig;

    #[test]
    fn bicycle_do_nothing_falls_because_of_the_noise() {
        let c = EnvConfig::by_name("bicycle").unwrap();
        // Action 4: no torque, no displacement. Without noise the bicycle would stay upright forever.
        let s = evaluate(c.env(), &mut |_| 4, eval_seed(1, 0));
        assert!(s.steps < 5000.0, "fell after {} steps", s.steps);
        assert!(s.score < 0.0);
        let quiet = crate::env::BicycleConfig { noise: 0.0, ..Default::default() };
        let s = evaluate(&quiet, &mut |_| 4, eval_seed(1, 0));
        assert_eq!(s.steps, 5000.0, "without noise nothing moves");
        assert_eq!(s.score, 0.0);
    }

    #[test]
    fn cartpole_pd_controller_scores_near_200_and_random_does_not() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        // Push toward the side the pole is falling to, with a little cart centring.
        let mut pd = |o: &[f64]| usize::from(o[2] + 0.5 * o[3] + 0.01 * o[0] + 0.05 * o[1] > 0.0);
        for i in 0..10 {
            let s = evaluate(c.env(), &mut pd, eval_seed(3, i));
            assert_eq!(s.steps, 200.0);
            assert!(s.score > 190.0, "PD controller scored {}", s.score);
        }
        let mut r = rng::stream(0, "test", &[]);
        let mut random = |_: &[f64]| rng::below(&mut r, 2) as usize;
        let s = evaluate(c.env(), &mut random, eval_seed(3, 0));
        assert!(s.score < 100.0, "random policy scored {}", s.score);
    }

    #[test]
    fn pendulum_scores_mean_reward_per_step() {
        let c = EnvConfig::by_name("pendulum").unwrap();
        let s = evaluate(c.env(), &mut |_| 0, eval_seed(1, 0));
        assert_eq!(s.steps, 200.0);
        // Per-step cost is at most π² + 0.1·64 + 0.004 ≈ 16.3.
        assert!(s.score < 0.0 && s.score > -16.3, "{}", s.score);
    }

    #[test]
    fn same_seed_same_episodes_for_any_policy_order() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        let a = evaluate(c.env(), &mut |o| usize::from(o[2] > 0.0), eval_seed(5, 2));
        let _ = evaluate(c.env(), &mut |_| 0, eval_seed(5, 3));
        let b = evaluate(c.env(), &mut |o| usize::from(o[2] > 0.0), eval_seed(5, 2));
        assert_eq!(a, b);
    }
}
