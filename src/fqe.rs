//! Fitted Q Evaluation (Le, Voloshin & Yue 2019): the value of a fixed policy estimated from logged
//! transitions alone, the offline fitness's estimator (issue 61).
//!
//! FQE is FQI with the max replaced by the policy's own action: `Q_1` is fitted on the rewards, and
//! `Q_{k+1}` on `r + γ·Q_k(s', π(s'))` (just `r` where the next state is absorbing; a horizon cut
//! bootstraps, as in FQI). After `iterations` fits the estimate is the mean over the data's episode
//! starts (step 0) of `Q_K(s_0, π(s_0))`: the policy's γ-discounted value from the logged start
//! distribution. The regressor is any [`Learner`]; its seeds derive from (`seed`, `fqe`, `[k]`).

use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::learn::Learner;
use crate::learn::actions::{ActionEncoding, Encoded};
use crate::rng;

/// What FQE iterates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FqeSettings {
    /// Fits K (at least 1): a return of K steps' horizon is seen whole.
    pub iterations: usize,
    /// Discount γ in [0, 1].
    pub gamma: f64,
}

/// An FQE estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// The mean of `starts`.
    pub value: f64,
    /// `Q_K(s_0, π(s_0))` at each episode's first state, in episode order: what an interval over
    /// the held-out episodes is computed from.
    pub starts: Vec<f64>,
}

/// The value of `policy` (an action index of `actions` for an observation) from the transitions of
/// `data`, by FQE with `learner` under `encoding`. Refused when the data has no episode start or
/// the settings are out of range.
pub fn evaluate<L: Learner>(
    data: &Dataset,
    actions: &[f64],
    encoding: ActionEncoding,
    learner: &L,
    settings: FqeSettings,
    policy: &dyn Fn(&[f64]) -> usize,
    seed: u64,
) -> Result<Estimate> {
    let od = data.obs_dim;
    let next: Vec<usize> = (0..data.len()).map(|i| policy(&data.next_state[i * od..(i + 1) * od])).collect();
    let first: Vec<usize> = starts(data).iter().map(|&i| policy(&data.state[i * od..(i + 1) * od])).collect();
    evaluate_chosen(data, actions, encoding, learner, settings, Chosen { next: &next, first: &first }, seed)
}

/// The rows of `data` that start an episode (step 0), in order.
pub fn starts(data: &Dataset) -> Vec<usize> {
    (0..data.len()).filter(|&i| data.step[i] == 0).collect()
}

/// The policy's actions (indices of `actions`) where FQE needs them.
#[derive(Debug, Clone, Copy)]
pub struct Chosen<'a> {
    /// At each row's next state.
    pub next: &'a [usize],
    /// At each episode start ([`starts`]'s rows, in order).
    pub first: &'a [usize],
}

/// [`evaluate`] with the policy's actions already chosen: for a caller that computes the policy's
/// Q values on those states anyway (the offline fitness's baselines), so that it does once.
pub fn evaluate_chosen<L: Learner>(
    data: &Dataset,
    actions: &[f64],
    encoding: ActionEncoding,
    learner: &L,
    settings: FqeSettings,
    chosen: Chosen<'_>,
    seed: u64,
) -> Result<Estimate> {
    crate::error::ensure(settings.iterations >= 1, "fqe.iterations", settings.iterations, "must be ≥ 1")?;
    let g = settings.gamma;
    crate::error::ensure((0.0..=1.0).contains(&g), "fqe.gamma", g, "must be in [0, 1]")?;
    let (n, od, na) = (data.len(), data.obs_dim, actions.len());
    let starts = starts(data);
    if starts.is_empty() {
        return Err(Error::Data("FQE needs episode starts (step 0) to estimate a value from".into()));
    }
    if chosen.next.len() != n || chosen.first.len() != starts.len() {
        return Err(Error::Data("FQE needs the policy's action at every next state and episode start".into()));
    }
    if let Some(&a) = chosen.next.iter().chain(chosen.first).find(|&&a| a >= na) {
        return Err(Error::Data(format!("the policy chose action {a} of {na}")));
    }
    let enc = Encoded::new(data, actions, encoding)?;
    let mut y = data.reward.clone();
    let (mut out, mut out_next) = (vec![0.0; n], vec![0.0; n * na]);
    let mut last = None;
    for k in 1..=settings.iterations {
        let s = rng::derive(seed, rng::purpose::FQE, &[k as u64]);
        let (q, _, _) = enc.fit_predict_next(learner, &y, s, &mut out, &mut out_next)?;
        for i in 0..n {
            let future = if data.absorbing[i] { 0.0 } else { out_next[i * na + chosen.next[i]] };
            y[i] = data.reward[i] + g * future;
        }
        last = Some(q);
    }
    let q = last.expect("at least one iteration");
    let (mut scratch, mut values) = (vec![0.0; na], vec![0.0; na]);
    let starts: Vec<f64> = starts
        .iter()
        .zip(chosen.first)
        .map(|(&i, &a)| {
            values.fill(0.0);
            q.add_q_values(&data.state[i * od..(i + 1) * od], actions, &mut scratch, &mut values);
            values[a]
        })
        .collect();
    Ok(Estimate { value: starts.iter().sum::<f64>() / starts.len() as f64, starts })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::extra_trees::ExtraTreesParams;

    /// A chain 0 … 4: action 1 moves right, action 0 left (not below 0); moving right from 4 ends
    /// the episode with reward 1 (absorbing), every other step gives 0. Episodes of random actions
    /// from 0, of at most 30 steps (a horizon cut, not absorbing).
    fn chain(episodes: u32) -> Dataset {
        let mut d = Dataset::with_capacity(1, 0);
        for e in 0..episodes {
            let mut r = rng::stream(7, "test/chain", &[u64::from(e)]);
            let mut x = 0.0f64;
            for t in 0..30 {
                let a = rng::below(&mut r, 2) as f64;
                let (next, reward, end) = match (a, x) {
                    (1.0, 4.0) => (4.0, 1.0, true),
                    (1.0, _) => (x + 1.0, 0.0, false),
                    _ => ((x - 1.0).max(0.0), 0.0, false),
                };
                d.episode.push(e);
                d.step.push(t);
                d.state.push(x);
                d.action.push(a);
                d.reward.push(reward);
                d.next_state.push(next);
                d.absorbing.push(end);
                if end {
                    break;
                }
                x = next;
            }
        }
        d
    }

    #[test]
    fn fqe_recovers_the_exact_value_of_a_fixed_policy_on_a_chain() {
        let d = chain(40);
        let trees = ExtraTreesParams { n_trees: 5, ..Default::default() };
        let right = |_: &[f64]| 1usize;
        let left = |_: &[f64]| 0usize;
        let out = |_: &[f64]| 5usize;
        let fqe = |encoding, iterations, policy: &dyn Fn(&[f64]) -> usize| {
            evaluate(&d, &[0.0, 1.0], encoding, &trees, FqeSettings { iterations, gamma: 0.9 }, policy, 1)
        };
        for encoding in [ActionEncoding::PerAction, ActionEncoding::Input] {
            // Always right from 0: four steps of 0, then 1 on the fifth, so V(0) = γ⁴.
            let e = fqe(encoding, 8, &right).unwrap();
            assert_eq!(e.starts.len(), 40);
            assert!((e.value - 0.9f64.powi(4)).abs() < 1e-9, "{encoding:?}: {}", e.value);
            // Fewer fits than steps to the reward see none of it.
            assert!(fqe(encoding, 4, &right).unwrap().value.abs() < 1e-9);
            // Always left never reaches the reward.
            let e = fqe(encoding, 8, &left).unwrap();
            assert!(e.value.abs() < 1e-9, "{encoding:?}: {}", e.value);
        }
        let bad = fqe(ActionEncoding::PerAction, 0, &right);
        assert!(bad.unwrap_err().to_string().contains("fqe.iterations"));
        let e = fqe(ActionEncoding::PerAction, 1, &out);
        assert!(e.unwrap_err().to_string().contains("action 5 of 2"));
    }
}
