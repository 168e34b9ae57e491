//! Rollouts: the greedy policy of a Q-function, step by step (`bfqi-ga rollout` and `evaluate`).
//!
//! A rollout runs the same episode loop as the evaluation protocol ([`crate::eval::episode`]) and
//! records what the protocol only sums: every state, the action taken, its reward and the Q value
//! of every action. Start states come from a [`Start`] rule and noise from the stream
//! `(eval_seed, "episode", e)`, so with [`Start::Eval`] and a run's evaluation seed, episode `e` is
//! exactly the one the run scored.

use crate::env::gymnasium::Image;
use crate::env::{EnvConfig, GymConfig, MAX_STATE, draw_box};
use crate::error::{Error, Result};
use crate::eval::{Episode, Frames, episode, gym_episodes, reset_seed};
use crate::learn::actions::argmax;
use crate::rng::{purpose, stream};
use crate::stats::{Summary, summarize};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Where an episode starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Start {
    /// The evaluation protocol's start box (the episodes a run is scored on).
    Eval,
    /// Every state variable 0 (the pendulum hangs at the top, the bicycle heads along x).
    Zero,
    /// The dataset start box: wider than the evaluation's for cart-pole, random headings for the
    /// bicycle, the same as the evaluation's for the pendulum.
    Random,
}

impl Start {
    /// Draws a start state into `s`.
    pub fn draw(self, env: &EnvConfig, rng: &mut crate::rng::Rng, s: &mut [f64]) {
        match self {
            Start::Eval => draw_box(&env.env().eval().start, rng, s),
            Start::Zero => s.fill(0.0),
            Start::Random => env.env().dataset_start(rng, s),
        }
    }
}

/// One step of a rollout.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// The hidden state the action was taken in.
    pub state: Vec<f64>,
    /// Index of the action taken (into the environment's actions).
    pub action: usize,
    /// The reward of the transition.
    pub reward: f64,
    /// Q of every action in `state` (the greedy action is the first maximum).
    pub q: Vec<f64>,
}

/// One episode of the greedy policy.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Episode index (its noise stream).
    pub episode: usize,
    /// Every step, in order.
    pub steps: Vec<Step>,
    /// The state after the last step.
    pub last: Vec<f64>,
    /// The episode's score under the evaluation protocol.
    pub score: f64,
    /// Whether it ended in a failure.
    pub failed: bool,
    /// A gymnasium env's own pictures of some states (state index, frame), from `render()`.
    pub frames: Vec<(usize, Image)>,
}

/// What a rollout draws with a gymnasium env's `render()`: the first `episodes` episodes, at
/// most `frames` frames each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Draw {
    /// Episodes drawn, from the first.
    pub episodes: usize,
    /// Frames per episode at most.
    pub frames: usize,
}

/// Widest gymnasium frame kept (pixels): every n-th pixel of the env's picture.
const FRAME_WIDTH: usize = 320;

/// Episodes stepped together by one gymnasium worker in a rollout.
const GYM_SLOTS: usize = 64;

/// Runs `episodes` episodes of the greedy policy of `q` (observation → Q of every action) from
/// `start`, at most `steps` steps each, keeping every step when `record` is set. Episodes run in
/// parallel; each has its own streams, so the results do not depend on the thread count. With a
/// gymnasium env that renders `rgb_array`, `draw` says which episodes keep frames. Fails only
/// when a gymnasium env's worker does (or `start` is `zero` for one).
#[allow(clippy::too_many_arguments)]
pub fn run(
    env_cfg: &EnvConfig,
    q: &(dyn Fn(&[f64], &mut [f64]) + Sync),
    eval_seed: u64,
    episodes: usize,
    start: Start,
    steps: usize,
    record: bool,
    draw: Option<Draw>,
) -> Result<Vec<(Episode, Option<Trajectory>)>> {
    if let EnvConfig::Gymnasium(g) = env_cfg {
        let opts = match start {
            Start::Eval => g.eval.reset_options.as_ref(),
            Start::Random => g.reset_options.as_ref(),
            Start::Zero => {
                return Err(Error::Usage(format!(
                    "--start zero: gymnasium env {} starts where its reset() puts it; use --start eval \
                     (env.eval.reset_options) or random (env.reset_options)",
                    g.id
                )));
            }
        };
        let draw = draw.filter(|_| record && g.probed.as_ref().is_some_and(|p| p.rgb_array));
        let go = |draw: Option<Draw>| -> Result<Vec<_>> {
            let chunks: Vec<usize> = (0..episodes.div_ceil(GYM_SLOTS)).collect();
            let parts = chunks
                .into_par_iter()
                .map(|c| {
                    let lo = c * GYM_SLOTS;
                    gym_chunk(g, q, eval_seed, lo..(lo + GYM_SLOTS).min(episodes), opts, steps, record, draw)
                })
                .collect::<Result<Vec<_>>>()?;
            Ok(parts.into_iter().flatten().collect())
        };
        // Frames are an extra: an env whose render() fails (a missing pygame, a broken display)
        // still gets its trajectory and plots. Its episodes are the same without rendering (same
        // reset seeds, same greedy actions), so they are run again without frames; a failure that
        // was not the rendering's fails that run too, and is reported as it is.
        return match go(draw) {
            Err(e) if draw.is_some() => {
                eprintln!(
                    "warning: {}: the rollout failed while drawing frames ({e}); running it again without \
                     frames, to keep its trajectory and plots",
                    g.id
                );
                go(None)
            }
            r => r,
        };
    }
    Ok((0..episodes).into_par_iter().map(|e| one(env_cfg, q, eval_seed, e, start, steps, record)).collect())
}

/// Episodes `range` of a gymnasium rollout, in lock-step in one worker.
#[allow(clippy::too_many_arguments)]
fn gym_chunk(
    g: &GymConfig,
    q: &(dyn Fn(&[f64], &mut [f64]) + Sync),
    eval_seed: u64,
    range: std::ops::Range<usize>,
    options: Option<&serde_json::Map<String, serde_json::Value>>,
    steps: usize,
    record: bool,
    draw: Option<Draw>,
) -> Result<Vec<(Episode, Option<Trajectory>)>> {
    let na = crate::env::Env::actions(g).len();
    let seeds: Vec<u64> = range.clone().map(|e| reset_seed(eval_seed, e)).collect();
    let mut qv = vec![0.0; na];
    let mut policy = |obs: &[f64]| {
        q(obs, &mut qv);
        argmax(&qv)
    };
    let mut kept: Vec<Vec<Step>> = vec![Vec::new(); seeds.len()];
    let mut last: Vec<Vec<f64>> = vec![Vec::new(); seeds.len()];
    let mut observe = |slot: usize, v: crate::eval::StepView<'_>| {
        if record {
            let mut qs = vec![0.0; na];
            q(v.state, &mut qs);
            kept[slot].push(Step { state: v.state.to_vec(), action: v.action, reward: v.reward, q: qs });
            last[slot] = v.next.to_vec();
        }
    };
    let mut frames = draw.filter(|d| range.start < d.episodes).map(|d| Frames {
        episodes: d.episodes - range.start,
        every: steps.div_ceil(d.frames.max(2) - 1).max(1),
        max_width: FRAME_WIDTH,
        got: Vec::new(),
    });
    let what = "rollout";
    let eps = gym_episodes(g, &mut policy, &seeds, options, steps, frames.as_mut(), what, &mut observe)?;
    let mut got = frames.map(|f| f.got).unwrap_or_default();
    got.resize(seeds.len(), Vec::new());
    Ok(eps
        .into_iter()
        .zip(kept.into_iter().zip(last))
        .zip(got)
        .enumerate()
        .map(|(i, ((ep, (steps, last)), frames))| {
            let traj = record.then(|| Trajectory {
                episode: range.start + i,
                steps,
                last,
                score: ep.score,
                failed: ep.failed,
                frames,
            });
            (ep, traj)
        })
        .collect())
}

fn one(
    env_cfg: &EnvConfig,
    q: &(dyn Fn(&[f64], &mut [f64]) + Sync),
    eval_seed: u64,
    e: usize,
    start: Start,
    steps: usize,
    record: bool,
) -> (Episode, Option<Trajectory>) {
    let env = env_cfg.env();
    let (sd, na) = (env.state_dim(), env.actions().len());
    let mut rng = stream(eval_seed, purpose::EPISODE, &[e as u64]);
    let mut s = [0.0; MAX_STATE];
    start.draw(env_cfg, &mut rng, &mut s[..sd]);
    let mut qv = vec![0.0; na];
    // The policy leaves each step's Q values here; the observer pairs them with the step.
    let mut qs: Vec<f64> = Vec::new();
    let mut policy = |obs: &[f64]| {
        q(obs, &mut qv);
        if record {
            qs.extend_from_slice(&qv);
        }
        argmax(&qv)
    };
    let mut kept: Vec<Step> = Vec::new();
    let mut last = s[..sd].to_vec();
    let ep = episode(env, &mut policy, &mut rng, &s[..sd], steps, |v| {
        if record {
            kept.push(Step { state: v.state.to_vec(), action: v.action, reward: v.reward, q: Vec::new() });
            last.copy_from_slice(v.next);
        }
    });
    let traj = record.then(|| {
        for (st, qrow) in kept.iter_mut().zip(qs.chunks_exact(na)) {
            st.q = qrow.to_vec();
        }
        Trajectory { episode: e, steps: kept, last, score: ep.score, failed: ep.failed, frames: Vec::new() }
    });
    (ep, traj)
}

/// Scores of several episodes: mean and 95 % interval, steps, failures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Robustness {
    /// Where the episodes started.
    pub start: Start,
    /// Episodes run.
    pub episodes: usize,
    /// Score over the episodes.
    pub score: Summary,
    /// Steps survived over the episodes.
    pub steps: Summary,
    /// Episodes that ended in a failure.
    pub failures: usize,
}

/// Summarises episodes (at least one).
pub fn robustness(start: Start, eps: &[Episode]) -> Option<Robustness> {
    let scores: Vec<f64> = eps.iter().map(|e| e.score).collect();
    let steps: Vec<f64> = eps.iter().map(|e| e.steps as f64).collect();
    Some(Robustness {
        start,
        episodes: eps.len(),
        score: summarize(&scores)?,
        steps: summarize(&steps)?,
        failures: eps.iter().filter(|e| e.failed).count(),
    })
}

/// The steps of `trajectories` as CSV: episode, step, time, every state variable, the action
/// (index and value), the reward and the Q value of every action (`q_<index>`).
pub fn csv(env: &EnvConfig, trajectories: &[Trajectory]) -> String {
    let names = state_names(env);
    let actions = env.env().actions();
    let mut s = String::from("episode,step,time");
    for n in &names {
        s.push_str(&format!(",{n}"));
    }
    s.push_str(",action,action_value,reward");
    for j in 0..actions.len() {
        s.push_str(&format!(",q_{j}"));
    }
    s.push('\n');
    let dt = dt(env);
    for t in trajectories {
        for (k, st) in t.steps.iter().enumerate() {
            s.push_str(&format!("{},{k},{:?}", t.episode, k as f64 * dt));
            for v in &st.state {
                s.push_str(&format!(",{v:?}"));
            }
            s.push_str(&format!(",{},{:?},{:?}", st.action, actions[st.action], st.reward));
            for v in &st.q {
                s.push_str(&format!(",{v:?}"));
            }
            s.push('\n');
        }
    }
    s
}

/// One line naming a model and where it came from.
pub fn describe_model(info: &crate::model::ModelInfo, path: &std::path::Path) -> String {
    format!(
        "{} · {} · {} with {} ({} member(s)) · from {}, dataset {}, K={}, recorded score {} · bfqi-ga {}",
        path.display(),
        info.env.env().name(),
        info.algorithm.name(),
        info.learner.short(),
        if info.algorithm == crate::fqi::Algorithm::Bfqi { info.iterations } else { 1 },
        info.source,
        info.dataset,
        info.iterations,
        info.score.map_or("—".into(), |s| format!("{s:.4}")),
        info.tool_version
    )
}

/// Simulated seconds per step of an environment.
pub fn dt(env: &EnvConfig) -> f64 {
    match env {
        EnvConfig::Pendulum(c) => c.dt,
        EnvConfig::Cartpole(c) => c.tau,
        EnvConfig::Bicycle(c) => c.dt,
        // Steps when the env has no `dt` (or `tau`).
        EnvConfig::Gymnasium(c) => c.probed.as_ref().and_then(|p| p.dt).unwrap_or(1.0),
    }
}

/// Names of the hidden-state variables, as plots and CSV headers show them.
/// (A gymnasium env's are its observation's values, `obs_0`, `obs_1`, ….)
pub fn state_names(env: &EnvConfig) -> Vec<String> {
    let fixed: &[&str] = match env {
        EnvConfig::Pendulum(_) => &["theta", "theta_dot"],
        EnvConfig::Cartpole(_) => &["x", "x_dot", "theta", "theta_dot"],
        EnvConfig::Bicycle(_) => &["omega", "omega_dot", "theta", "theta_dot", "psi"],
        EnvConfig::Gymnasium(c) => return (0..c.obs_len()).map(|i| format!("obs_{i}")).collect(),
    };
    fixed.iter().map(|s| s.to_string()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::{eval_seed, evaluate};

    /// Push toward the side the pole is falling to (a decent cart-pole controller) as Q values.
    fn pd(o: &[f64], q: &mut [f64]) {
        let push = o[2] + 0.5 * o[3] + 0.01 * o[0] + 0.05 * o[1];
        q[0] = -push;
        q[1] = push;
    }

    #[test]
    fn eval_rollouts_reproduce_the_protocol_score() {
        for name in crate::env::NAMES {
            let c = EnvConfig::by_name(name).unwrap();
            let na = c.env().actions().len();
            // A fixed, state-dependent policy for every environment.
            let q = |o: &[f64], q: &mut [f64]| {
                for (j, v) in q.iter_mut().enumerate() {
                    *v = ((j as f64 + 1.0) * o[0]).sin();
                }
                if name == "cartpole" {
                    pd(o, q)
                }
            };
            let seed = eval_seed(7, 1);
            let protocol = c.env().eval();
            let eps = run(&c, &q, seed, protocol.episodes, Start::Eval, protocol.steps, true, None).unwrap();
            let mean = eps.iter().map(|(e, _)| e.score).sum::<f64>() / eps.len() as f64;
            let mut policy = |o: &[f64]| {
                let mut v = vec![0.0; na];
                q(o, &mut v);
                argmax(&v)
            };
            let s = evaluate(c.env(), &mut policy, seed).unwrap();
            assert_eq!(mean.to_bits(), s.score.to_bits(), "{name}");
            for (e, t) in &eps {
                let t = t.as_ref().unwrap();
                assert_eq!(t.steps.len(), e.steps);
                assert!(t.steps.iter().all(|s| s.q.len() == na && s.action == argmax(&s.q)));
            }
        }
    }

    #[test]
    fn start_rules_differ_where_the_boxes_do() {
        let c = EnvConfig::by_name("bicycle").unwrap();
        let mut s = [0.0; 5];
        let mut rng = stream(1, "test", &[]);
        Start::Random.draw(&c, &mut rng, &mut s);
        assert!(s[4] != 0.0 && s[..4].iter().all(|&v| v == 0.0), "random heading only: {s:?}");
        Start::Eval.draw(&c, &mut rng, &mut s);
        assert_eq!(s, [0.0; 5]);
        let c = EnvConfig::by_name("cartpole").unwrap();
        let mut wide = 0.0f64;
        for _ in 0..50 {
            let mut s = [0.0; 4];
            Start::Random.draw(&c, &mut rng, &mut s);
            wide = wide.max(s[0].abs());
        }
        assert!(wide > 0.5, "dataset starts span the track: {wide}");
    }
}
