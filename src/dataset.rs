//! Datasets of random-policy episodes (SPEC §2), stored column-wise.
//!
//! A dataset is a pure function of (environment config, episodes, seed): episode `e` draws from the
//! stream `(seed, "episode", e)`, so episodes can be collected in parallel, the result does not depend
//! on the thread count, and a dataset of N episodes is a prefix of one of M > N episodes with the same
//! seed (the sample analysis compares nested datasets).

use crate::env::gymnasium::{self, RawEpisode};
use crate::env::{Env, GymConfig, MAX_STATE};
use crate::error::{Error, Result};
use crate::rng::{self, stream};
use rayon::prelude::*;

pub mod logged;
pub mod minari;
pub mod table;

pub use logged::DataSource;

/// Dataset `index` of a role: from the logged data when a spec names some (`data`), else
/// `episodes` random-policy episodes collected from the dataset's seed under `master`.
pub fn make(
    env: &dyn Env,
    data: Option<&DataSource>,
    episodes: usize,
    master: u64,
    role: Role,
    index: usize,
) -> Result<Dataset> {
    match data {
        Some(d) => d.dataset(master, role, index, episodes),
        None => collect(env, episodes, dataset_seed(master, role, index)),
    }
}

/// Transitions of N episodes, one array per field. Observations are what learners see
/// (`obs_dim` values per row, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Observation dimension.
    pub obs_dim: usize,
    /// Episode index of each transition.
    pub episode: Vec<u32>,
    /// Step within its episode.
    pub step: Vec<u32>,
    /// Observations before the transition, `len × obs_dim`, row-major.
    pub state: Vec<f64>,
    /// Action as a feature value (torque for the pendulum, index otherwise).
    pub action: Vec<f64>,
    /// Rewards.
    pub reward: Vec<f64>,
    /// Observations after the transition, `len × obs_dim`, row-major.
    pub next_state: Vec<f64>,
    /// True where the next state is a failure (absorbing). Horizon cuts are never absorbing.
    pub absorbing: Vec<bool>,
}

impl Dataset {
    /// Number of transitions.
    pub fn len(&self) -> usize {
        self.reward.len()
    }

    /// True when there are no transitions.
    pub fn is_empty(&self) -> bool {
        self.reward.is_empty()
    }

    /// Number of episodes.
    pub fn episodes(&self) -> usize {
        self.episode.last().map_or(0, |&e| e as usize + 1)
    }

    /// An empty dataset of `obs_dim`-value observations, with room for `n` transitions.
    pub(crate) fn with_capacity(obs_dim: usize, n: usize) -> Self {
        Dataset {
            obs_dim,
            episode: Vec::with_capacity(n),
            step: Vec::with_capacity(n),
            state: Vec::with_capacity(n * obs_dim),
            action: Vec::with_capacity(n),
            reward: Vec::with_capacity(n),
            next_state: Vec::with_capacity(n * obs_dim),
            absorbing: Vec::with_capacity(n),
        }
    }

    fn append(&mut self, other: Dataset) {
        self.episode.extend(other.episode);
        self.step.extend(other.step);
        self.state.extend(other.state);
        self.action.extend(other.action);
        self.reward.extend(other.reward);
        self.next_state.extend(other.next_state);
        self.absorbing.extend(other.absorbing);
    }
}

/// Collects `episodes` random-policy episodes of `env` from `seed`.
///
/// Each episode starts from the dataset start distribution and runs until a failure (absorbing) or
/// the horizon (not absorbing). Episodes run in parallel; the result is independent of the thread count.
pub fn collect(env: &dyn Env, episodes: usize, seed: u64) -> Result<Dataset> {
    if episodes == 0 {
        return Err(Error::invalid("episodes", 0, "must be ≥ 1"));
    }
    if let Some(g) = env.gymnasium() {
        return collect_gymnasium(g, episodes, seed);
    }
    let parts: Vec<Dataset> = (0..episodes).into_par_iter().map(|e| episode(env, e, seed)).collect();
    let total = parts.iter().map(Dataset::len).sum();
    let mut out = Dataset::with_capacity(env.obs_dim(), total);
    for p in parts {
        out.append(p);
    }
    Ok(out)
}

/// Episode `e` of the dataset of `seed` alone: what [`collect`] gives for it, so a check can
/// collect a dataset an episode at a time and stop once it has seen enough.
pub fn episode(env: &dyn Env, e: usize, seed: u64) -> Dataset {
    let mut rng = stream(seed, rng::purpose::EPISODE, &[e as u64]);
    let (sd, od) = (env.state_dim(), env.obs_dim());
    let mut s = [0.0; MAX_STATE];
    let mut next = [0.0; MAX_STATE];
    let mut obs = [0.0; MAX_STATE];
    env.dataset_start(&mut rng, &mut s[..sd]);
    let mut out = Dataset::with_capacity(od, 16);
    for t in 0..env.horizon() {
        let a = env.dataset_action(&mut rng);
        let o = env.step(&s[..sd], a, &mut rng, &mut next[..sd]);
        out.episode.push(e as u32);
        out.step.push(t as u32);
        env.observe(&s[..sd], &mut obs[..od]);
        out.state.extend_from_slice(&obs[..od]);
        out.action.push(a);
        out.reward.push(o.reward);
        env.observe(&next[..sd], &mut obs[..od]);
        out.next_state.extend_from_slice(&obs[..od]);
        out.absorbing.push(o.failed);
        s = next;
        if o.failed {
            break;
        }
    }
    out
}

/// Steps per message to a gymnasium worker, about: a batch of episodes is one round trip.
const GYM_BATCH_STEPS: usize = 20_000;

/// [`collect`] for a gymnasium env: episode `e` draws its `reset` seed (the first word of its
/// stream) and then its random actions from `(seed, "episode", e)`, as a built-in env draws its
/// start and actions; the worker runs batches of episodes, in parallel on the threads, and the
/// dataset does not depend on how they were batched.
fn collect_gymnasium(g: &GymConfig, episodes: usize, seed: u64) -> Result<Dataset> {
    let per = (GYM_BATCH_STEPS / g.horizon.max(1)).clamp(1, episodes);
    let batches: Vec<Vec<RawEpisode>> = (0..episodes.div_ceil(per))
        .into_par_iter()
        .map(|b| {
            let lo = b * per;
            let batch: Vec<(u64, Vec<f64>)> = (lo..(lo + per).min(episodes))
                .map(|e| {
                    let mut rng = stream(seed, rng::purpose::EPISODE, &[e as u64]);
                    let reset = rng::word(&mut rng);
                    (reset, (0..g.horizon).map(|_| g.dataset_action(&mut rng)).collect())
                })
                .collect();
            gymnasium::collect(g, lo, &batch)
        })
        .collect::<Result<_>>()?;
    let d = g.obs_len();
    let total = batches.iter().flatten().map(|e| e.rewards.len()).sum();
    let mut out = Dataset::with_capacity(d, total);
    for (e, ep) in batches.into_iter().flatten().enumerate() {
        let t_end = ep.rewards.len();
        for t in 0..t_end {
            out.episode.push(e as u32);
            out.step.push(t as u32);
            out.state.extend_from_slice(&ep.obs[t * d..(t + 1) * d]);
            out.action.push(ep.actions[t]);
            out.reward.push(ep.rewards[t]);
            out.next_state.extend_from_slice(&ep.obs[(t + 1) * d..(t + 2) * d]);
            out.absorbing.push(ep.terminated && t + 1 == t_end);
        }
    }
    Ok(out)
}

/// Which datasets: each role has its own stream (`dataset/<role>`), so a search never tunes on the
/// datasets a comparison reports, nor validation on either.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Role {
    /// Comparison runs and `run`.
    Compare,
    /// The GA's fitness.
    Search,
    /// Re-scoring a search's top settings (`validate`); not offered by `dataset --role`.
    #[value(skip)]
    Validation,
    /// Held-out episodes an offline fitness scores policies on (`search.fitness`, beyond the
    /// thesis); never trained on.
    #[value(skip)]
    Heldout,
}

impl Role {
    /// The name in the stream's purpose (and on the command line).
    pub fn name(self) -> &'static str {
        match self {
            Role::Compare => "compare",
            Role::Search => "search",
            Role::Validation => "validation",
            Role::Heldout => "heldout",
        }
    }
}

/// The seed of dataset `index` of a role under a master seed.
pub fn dataset_seed(master: u64, role: Role, index: usize) -> u64 {
    rng::derive(master, &rng::purpose::dataset(role.name()), &[index as u64])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::EnvConfig;

    #[test]
    fn sizes_match_the_spec() {
        let p = EnvConfig::by_name("pendulum").unwrap();
        let d = collect(p.env(), 2000, 1).unwrap();
        assert_eq!(d.len(), 2000 * 200);
        assert!(d.absorbing.iter().all(|&a| !a), "pendulum never absorbs");
        assert_eq!(d.episodes(), 2000);

        let c = EnvConfig::by_name("cartpole").unwrap();
        let d = collect(c.env(), 2000, 1).unwrap();
        assert!((17_000..=23_000).contains(&d.len()), "cart-pole 2000 episodes: {}", d.len());

        let b = EnvConfig::by_name("bicycle").unwrap();
        let d = collect(b.env(), 1000, 1).unwrap();
        assert!((76_500..=103_500).contains(&d.len()), "bicycle 1000 episodes: {}", d.len());
    }

    #[test]
    fn every_episode_ends_in_failure_or_at_the_horizon() {
        for name in ["cartpole", "bicycle"] {
            let c = EnvConfig::by_name(name).unwrap();
            let d = collect(c.env(), 300, 5).unwrap();
            for i in 0..d.len() {
                let last = i + 1 == d.len() || d.episode[i + 1] != d.episode[i];
                if d.absorbing[i] {
                    assert!(last, "{name}: an absorbing transition ends its episode");
                } else if last {
                    assert_eq!(d.step[i] as usize + 1, c.env().horizon(), "{name}: cut only at the horizon");
                }
            }
        }
    }

    #[test]
    fn horizon_cut_is_not_absorbing() {
        let c = crate::env::CartPoleConfig { horizon: 3, dataset_start: vec![[0.0, 0.0]; 4], ..Default::default() };
        let d = collect(&c, 4, 2).unwrap();
        assert_eq!(d.len(), 12, "no episode can fail within 3 steps from rest");
        assert!(d.absorbing.iter().all(|&a| !a));
    }

    #[test]
    fn nested_datasets_share_their_prefix() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        let small = collect(c.env(), 10, 9).unwrap();
        let big = collect(c.env(), 20, 9).unwrap();
        assert_eq!(&big.reward[..small.len()], &small.reward[..]);
    }

    #[test]
    fn zero_episodes_is_an_error() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        assert!(collect(c.env(), 0, 1).unwrap_err().to_string().contains("episodes"));
    }

    #[test]
    fn roles_get_disjoint_seeds() {
        let search: Vec<u64> = (0..100).map(|i| dataset_seed(1, Role::Search, i)).collect();
        assert!((0..100).all(|i| !search.contains(&dataset_seed(1, Role::Compare, i))));
    }
}
