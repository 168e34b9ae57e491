//! Evaluation protocols (SPEC §1, "Evaluation"): run a policy on the environment's evaluation
//! episodes and score it.
//!
//! Start states and noise come from `(eval_seed, "episode", e)` only, where the caller derives
//! `eval_seed` from (master seed, "eval", dataset index): FQI and B-FQI, every iteration and every
//! chromosome are scored on the same episodes (paired comparisons).

use crate::env::gymnasium::{Image, LockStep};
use crate::env::{Env, GymConfig, MAX_STATE, ScoreKind, draw_box};
use crate::error::Result;
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
/// Fails only for a gymnasium env whose worker fails.
pub fn evaluate(env: &dyn Env, policy: &mut dyn FnMut(&[f64]) -> usize, eval_seed: u64) -> Result<Score> {
    let proto = env.eval();
    if let Some(g) = env.gymnasium() {
        let seeds: Vec<u64> = (0..proto.episodes).map(|e| reset_seed(eval_seed, e)).collect();
        let opts = g.eval.reset_options.as_ref();
        let eps = gym_episodes(g, policy, &seeds, opts, proto.steps, None, "evaluation", &mut |_, _| {})?;
        let n = eps.len() as f64;
        let (score, steps) = eps.iter().fold((0.0, 0.0), |(s, t), e| (s + e.score, t + e.steps as f64));
        return Ok(Score { score: score / n, steps: steps / n });
    }
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
    Ok(Score { score: total_score / n, steps: total_steps / n })
}

/// The `reset(seed=…)` of a gymnasium episode `e` under `seed`: the first word of the stream
/// `(seed, "episode", e)`, which for a built-in env draws the start state.
pub fn reset_seed(seed: u64, e: usize) -> u64 {
    rng::word(&mut stream(seed, rng::purpose::EPISODE, &[e as u64]))
}

/// Which frames [`gym_episodes`] renders: of the first `episodes` slots, every `every`-th state
/// and the last, at most `max_width` pixels wide; they land in `got[slot]` as (state index, frame).
#[derive(Debug, Default)]
pub struct Frames {
    /// Slots drawn, from the first.
    pub episodes: usize,
    /// Every this many states.
    pub every: usize,
    /// Widest frame, pixels.
    pub max_width: usize,
    /// The frames of each drawn slot.
    pub got: Vec<Vec<(usize, Image)>>,
}

/// Episodes of a gymnasium env in lock-step, one per seed, at most `max_steps` steps each, scored
/// as [`episode`] scores: every round trip steps each running episode once. `observe` sees every
/// step with the slot it belongs to (the observations are the states).
#[allow(clippy::too_many_arguments)]
pub fn gym_episodes(
    g: &GymConfig,
    policy: &mut dyn FnMut(&[f64]) -> usize,
    seeds: &[u64],
    options: Option<&serde_json::Map<String, serde_json::Value>>,
    max_steps: usize,
    mut frames: Option<&mut Frames>,
    what: &str,
    observe: &mut dyn FnMut(usize, StepView<'_>),
) -> Result<Vec<Episode>> {
    let n = seeds.len();
    let (kind, actions, gamma) = (g.eval.score, Env::actions(g), g.gamma);
    let mut ls = LockStep::reset(g, seeds, options, frames.is_some(), what)?;
    let mut tally = vec![(0.0f64, 1.0f64, 0usize, false); n];
    let drawn = frames.as_ref().map_or(0, |f| f.episodes.min(n));
    if let Some(f) = frames.as_deref_mut() {
        f.got = vec![Vec::new(); drawn];
        let slots: Vec<usize> = (0..drawn).collect();
        for (s, im) in slots.iter().zip(ls.render(&slots, f.max_width)?) {
            f.got[*s].push((0, im));
        }
    }
    let mut alive: Vec<usize> = (0..n).collect();
    let (mut prev, mut chosen) = (Vec::new(), Vec::new());
    for t in 0..max_steps {
        if alive.is_empty() {
            break;
        }
        prev.clear();
        chosen.clear();
        let mut moves = Vec::with_capacity(alive.len());
        for &slot in &alive {
            let o = ls.obs(slot);
            prev.extend_from_slice(o);
            let a = policy(o);
            chosen.push(a);
            moves.push((slot, actions[a]));
        }
        let out = ls.step(&moves)?;
        let d = g.obs_len();
        let mut ended = Vec::new();
        for (i, (&slot, st)) in alive.iter().zip(&out).enumerate() {
            let (sum, discount, steps, failed) = &mut tally[slot];
            *sum += match kind {
                ScoreKind::DiscountedReturn => *discount * st.reward,
                _ => st.reward,
            };
            *discount *= gamma;
            *steps += 1;
            *failed = st.terminated;
            let view = StepView {
                t,
                state: &prev[i * d..(i + 1) * d],
                action: chosen[i],
                reward: st.reward,
                next: ls.obs(slot),
                failed: st.terminated,
            };
            observe(slot, view);
            if st.terminated || st.truncated || t + 1 == max_steps {
                ended.push(slot);
            }
        }
        if let Some(f) = frames.as_deref_mut() {
            let every = f.every.max(1);
            let slots: Vec<usize> =
                alive.iter().copied().filter(|&s| s < drawn && ((t + 1) % every == 0 || ended.contains(&s))).collect();
            if !slots.is_empty() {
                for (s, im) in slots.iter().zip(ls.render(&slots, f.max_width)?) {
                    f.got[*s].push((t + 1, im));
                }
            }
        }
        alive.retain(|s| !ended.contains(s));
    }
    Ok(tally
        .into_iter()
        .map(|(sum, _, steps, failed)| {
            let score = match kind {
                ScoreKind::MeanRewardPerStep => sum / steps.max(1) as f64,
                ScoreKind::Return | ScoreKind::DiscountedReturn => sum,
            };
            Episode { score, steps, failed }
        })
        .collect())
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
        let s = evaluate(c.env(), &mut |_| 4, eval_seed(1, 0)).unwrap();
        assert!(s.steps < 5000.0, "fell after {} steps", s.steps);
        assert!(s.score < 0.0);
        let quiet = crate::env::BicycleConfig { noise: 0.0, ..Default::default() };
        let s = evaluate(&quiet, &mut |_| 4, eval_seed(1, 0)).unwrap();
        assert_eq!(s.steps, 5000.0, "without noise nothing moves");
        assert_eq!(s.score, 0.0);
    }

    #[test]
    fn cartpole_pd_controller_scores_near_200_and_random_does_not() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        // Push toward the side the pole is falling to, with a little cart centring.
        let mut pd = |o: &[f64]| usize::from(o[2] + 0.5 * o[3] + 0.01 * o[0] + 0.05 * o[1] > 0.0);
        for i in 0..10 {
            let s = evaluate(c.env(), &mut pd, eval_seed(3, i)).unwrap();
            assert_eq!(s.steps, 200.0);
            assert!(s.score > 190.0, "PD controller scored {}", s.score);
        }
        let mut r = rng::stream(0, "test", &[]);
        let mut random = |_: &[f64]| rng::below(&mut r, 2) as usize;
        let s = evaluate(c.env(), &mut random, eval_seed(3, 0)).unwrap();
        assert!(s.score < 100.0, "random policy scored {}", s.score);
    }

    #[test]
    fn pendulum_scores_mean_reward_per_step() {
        let c = EnvConfig::by_name("pendulum").unwrap();
        let s = evaluate(c.env(), &mut |_| 0, eval_seed(1, 0)).unwrap();
        assert_eq!(s.steps, 200.0);
        // Per-step cost is at most π² + 0.1·64 + 0.004 ≈ 16.3.
        assert!(s.score < 0.0 && s.score > -16.3, "{}", s.score);
    }

    #[test]
    fn same_seed_same_episodes_for_any_policy_order() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        let a = evaluate(c.env(), &mut |o| usize::from(o[2] > 0.0), eval_seed(5, 2)).unwrap();
        let _ = evaluate(c.env(), &mut |_| 0, eval_seed(5, 3)).unwrap();
        let b = evaluate(c.env(), &mut |o| usize::from(o[2] > 0.0), eval_seed(5, 2)).unwrap();
        assert_eq!(a, b);
    }
}
