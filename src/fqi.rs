//! Fitted Q-Iteration and Boosted FQI (SPEC §4; thesis Algorithm 7 and Appendix A).
//!
//! Both algorithms share one loop. Iteration k fits a fresh model on targets built from
//! `T̂Q_{k−1}(x_i, a_i) = r_i + γ(1 − absorbing_i)·max_a Q_{k−1}(x'_i, a)`:
//! - FQI fits the targets themselves and replaces Q;
//! - B-FQI fits the Bellman residual `T̂Q_{k−1} − Q_{k−1}` and adds the new member to Q.
//!
//! Q on the training rows and on every (next state, action) pair is kept as running values, so each
//! iteration costs one fit and one prediction of the new member, for B-FQI as for FQI. The greedy
//! policy on unseen states sums the members.

use crate::dataset::Dataset;
use crate::env::Env;
use crate::error::Result;
use crate::eval::{Score, evaluate};
use crate::learn::actions::{Encoded, QModel, argmax};
use crate::learn::{FitInfo, Learner, StopReason};
use crate::rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Which algorithm (`--algo`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Algorithm {
    /// Fitted Q-Iteration: Q_k = S(T̂Q_{k−1}).
    Fqi,
    /// Boosted FQI: Q_k = Q_{k−1} + S(T̂Q_{k−1} − Q_{k−1}).
    Bfqi,
}

impl Algorithm {
    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Algorithm::Fqi => "fqi",
            Algorithm::Bfqi => "bfqi",
        }
    }
}

/// What happened at one iteration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// 1-based iteration index.
    pub iteration: usize,
    /// Score of the greedy policy (SPEC §1), at the iterations evaluated.
    pub score: Option<f64>,
    /// Steps survived by the greedy policy, at the iterations evaluated.
    pub steps: Option<f64>,
    /// Empirical Bellman residual of Q_k on the training rows: `sqrt(mean_i (T̂Q_k − Q_k)(x_i, a_i)²)`.
    pub bellman_residual: f64,
    /// Epochs run by the member's networks (summed over per-action models); absent for trees.
    pub epochs: Option<usize>,
    /// Each network of the member (one per action with `per_action`): epochs, why training
    /// stopped (early stopping or the epoch cap) and the last epoch's losses; empty for trees.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub networks: Vec<FitInfo>,
    /// Seconds fitting the member.
    pub fit_seconds: f64,
    /// Seconds predicting the member on the training rows and next states.
    pub predict_seconds: f64,
    /// Seconds evaluating the greedy policy.
    pub eval_seconds: f64,
}

/// Why and when a run diverged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Divergence {
    /// The iteration at which a non-finite value appeared.
    pub iteration: usize,
    /// What was non-finite.
    pub reason: String,
}

/// The record of one run on one dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// One record per completed iteration.
    pub iterations: Vec<IterationRecord>,
    /// Set when the run stopped on a non-finite target, loss or Q value.
    pub diverged: Option<Divergence>,
}

impl RunRecord {
    /// The last evaluated score, or `None` if the run diverged or nothing was evaluated.
    pub fn final_score(&self) -> Option<f64> {
        if self.diverged.is_some() {
            return None;
        }
        self.iterations.iter().rev().find_map(|r| r.score)
    }
}

/// Iteration settings of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FqiSettings {
    /// FQI or B-FQI.
    pub algorithm: Algorithm,
    /// K, the number of iterations.
    pub iterations: usize,
    /// Evaluate the greedy policy every this many iterations (and always at the last).
    pub eval_every: usize,
}

/// An FQI / B-FQI run in progress on one dataset; [`Fqi::iterate`] performs one iteration.
pub struct Fqi<'a, L: Learner> {
    env: &'a dyn Env,
    data: &'a Dataset,
    enc: &'a Encoded,
    learner: &'a L,
    settings: FqiSettings,
    fit_seed: u64,
    eval_seed: u64,
    /// Q_k's members (one for FQI, k for B-FQI).
    members: Vec<QModel<L::Model>>,
    /// Q_k(x_i, a_i) on the training rows.
    q_train: Vec<f64>,
    /// Q_k(x'_i, a_j), i-major.
    q_next: Vec<f64>,
    /// T̂Q_k on the training rows: the next iteration's targets.
    targets: Vec<f64>,
    /// Scratch buffers reused across iterations.
    p_train: Vec<f64>,
    p_next: Vec<f64>,
    fit_target: Vec<f64>,
    k: usize,
    /// Models fitted so far (for B-FQI, one member per iteration).
    pub fits: usize,
}

impl<'a, L: Learner> Fqi<'a, L> {
    /// Prepares a run. `fit_seed` seeds member k through `derive(fit_seed, "member", [k])`;
    /// `eval_seed` fixes the evaluation episodes (see [`crate::eval::eval_seed`]).
    pub fn new(
        env: &'a dyn Env,
        data: &'a Dataset,
        enc: &'a Encoded,
        learner: &'a L,
        settings: FqiSettings,
        fit_seed: u64,
        eval_seed: u64,
    ) -> Self {
        let (n, na) = (data.len(), enc.actions.len());
        Fqi {
            env,
            data,
            enc,
            learner,
            settings,
            fit_seed,
            eval_seed,
            members: Vec::new(),
            q_train: vec![0.0; n],
            q_next: vec![0.0; n * na],
            // Q_0 = 0, so T̂Q_0 = r: iteration 1 fits the rewards.
            targets: data.reward.clone(),
            p_train: vec![0.0; n],
            p_next: vec![0.0; n * na],
            fit_target: vec![0.0; n],
            k: 0,
            fits: 0,
        }
    }

    /// Q_k on the training rows (the running sum for B-FQI).
    pub fn q_train(&self) -> &[f64] {
        &self.q_train
    }

    /// Q_k on every (next state, action) pair, i-major.
    pub fn q_next(&self) -> &[f64] {
        &self.q_next
    }

    /// The members of Q_k.
    pub fn members(&self) -> &[QModel<L::Model>] {
        &self.members
    }

    /// Q_k(obs, a_j) for every action, summing the members; `scratch` holds at least |A| values.
    pub fn q_values(&self, obs: &[f64], scratch: &mut [f64], out: &mut [f64]) {
        out.fill(0.0);
        for m in &self.members {
            m.add_q_values(obs, &self.enc.actions, scratch, out);
        }
    }

    /// The greedy policy's score under the environment's evaluation protocol.
    ///
    /// An episode is sequential, but a B-FQI step sums many members: with several, their Q values
    /// are computed in parallel into one buffer each and then added in member order, so the
    /// policy is bit-identical to [`Fqi::q_values`] whatever the thread count. Fails only when a
    /// gymnasium env's worker does.
    pub fn evaluate(&self) -> Result<Score> {
        let na = self.enc.actions.len();
        let k = self.members.len();
        let mut q = vec![0.0; na];
        let parallel = k >= PARALLEL_MEMBERS && rayon::current_num_threads() > 1;
        let (mut per, mut scratch) = (vec![0.0; k.max(1) * na], vec![0.0; k.max(1) * na]);
        let mut policy = |obs: &[f64]| {
            if parallel {
                per.par_chunks_mut(na).zip(scratch.par_chunks_mut(na)).zip(self.members.par_iter()).for_each(
                    |((p, s), m)| {
                        p.fill(0.0);
                        m.add_q_values(obs, &self.enc.actions, s, p);
                    },
                );
                q.fill(0.0);
                for p in per.chunks_exact(na) {
                    add(&mut q, p);
                }
            } else {
                self.q_values(obs, &mut scratch, &mut q);
            }
            argmax(&q)
        };
        evaluate(self.env, &mut policy, self.eval_seed)
    }

    /// Performs one iteration. `Ok(Err(divergence))` when a non-finite value appeared: the run
    /// stops there and the divergence is a result, not an error.
    pub fn iterate(&mut self) -> Result<std::result::Result<IterationRecord, Divergence>> {
        self.k += 1;
        let k = self.k;
        let bfqi = self.settings.algorithm == Algorithm::Bfqi;
        let diverged = |reason: &str| Ok(Err(Divergence { iteration: k, reason: reason.to_string() }));

        // B-FQI fits the residual T̂Q_{k−1} − Q_{k−1}; FQI the targets.
        if bfqi {
            for ((f, t), q) in self.fit_target.iter_mut().zip(&self.targets).zip(&self.q_train) {
                *f = t - q;
            }
        } else {
            self.fit_target.copy_from_slice(&self.targets);
        }

        let t0 = Instant::now();
        let seed = rng::derive(self.fit_seed, rng::purpose::MEMBER, &[k as u64]);
        // The member's predictions on the training rows come with the fit (trees know each row's
        // leaf), so they count as fit time.
        // Q(x′, ·) of the member comes with it too (a tree gives a next state that is also a
        // training state that row's leaf), timed apart as prediction.
        let (member, fits, next_seconds) =
            self.enc.fit_predict_next(self.learner, &self.fit_target, seed, &mut self.p_train, &mut self.p_next)?;
        let info = FitInfo::combined(&fits);
        self.fits += 1;
        let fit_seconds = t0.elapsed().as_secs_f64() - next_seconds;
        if info.stop == StopReason::NonFinite {
            return diverged("non-finite training loss");
        }

        let t1 = Instant::now();
        if bfqi {
            add(&mut self.q_train, &self.p_train);
            add(&mut self.q_next, &self.p_next);
            self.members.push(member);
        } else {
            std::mem::swap(&mut self.q_train, &mut self.p_train);
            std::mem::swap(&mut self.q_next, &mut self.p_next);
            self.members.clear();
            self.members.push(member);
        }
        let predict_seconds = next_seconds + t1.elapsed().as_secs_f64();
        if !self.q_train.iter().chain(&self.q_next).all(|v| v.is_finite()) {
            return diverged("non-finite Q value");
        }

        // T̂Q_k: next iteration's targets, and Q_k's Bellman residual.
        let na = self.enc.actions.len();
        let gamma = self.env.gamma();
        let mut sq = 0.0;
        for i in 0..self.data.len() {
            let best = self.q_next[i * na..(i + 1) * na].iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let cont = if self.data.absorbing[i] { 0.0 } else { gamma * best };
            self.targets[i] = self.data.reward[i] + cont;
            sq += (self.targets[i] - self.q_train[i]).powi(2);
        }
        let bellman_residual = (sq / self.data.len() as f64).sqrt();
        if !bellman_residual.is_finite() {
            return diverged("non-finite target");
        }

        let t2 = Instant::now();
        let s = self.settings;
        let (score, steps) = if k.is_multiple_of(s.eval_every.max(1)) || k == s.iterations {
            let sc = self.evaluate()?;
            (Some(sc.score), Some(sc.steps))
        } else {
            (None, None)
        };
        let iterative = info.stop != StopReason::NotIterative;
        let epochs = iterative.then_some(info.epochs);
        let networks = if iterative { fits } else { Vec::new() };
        Ok(Ok(IterationRecord {
            iteration: k,
            score,
            steps,
            bellman_residual,
            epochs,
            networks,
            fit_seconds,
            predict_seconds,
            eval_seconds: t2.elapsed().as_secs_f64(),
        }))
    }

    /// Runs every remaining iteration, calling `progress` after each.
    pub fn run(self, progress: impl FnMut(&IterationRecord)) -> Result<RunRecord> {
        self.run_keeping(progress).map(|(rec, _)| rec)
    }

    /// [`Fqi::run`], also returning the members of the last Q-function.
    pub fn run_keeping(
        mut self,
        mut progress: impl FnMut(&IterationRecord),
    ) -> Result<(RunRecord, Vec<QModel<L::Model>>)> {
        let mut rec = RunRecord { iterations: Vec::new(), diverged: None };
        while self.k < self.settings.iterations {
            match self.iterate()? {
                Ok(r) => {
                    progress(&r);
                    rec.iterations.push(r);
                }
                Err(d) => {
                    rec.diverged = Some(d);
                    break;
                }
            }
        }
        Ok((rec, self.members))
    }
}

/// Members from which the greedy policy's steps sum them in parallel (below, the split costs more
/// than it saves).
const PARALLEL_MEMBERS: usize = 4;

fn add(acc: &mut [f64], x: &[f64]) {
    for (a, b) in acc.iter_mut().zip(x) {
        *a += b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::actions::ActionEncoding;
    use crate::testkit::{Chain, Table, chain_data, value_iteration};
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn settings(algorithm: Algorithm, iterations: usize) -> FqiSettings {
        FqiSettings { algorithm, iterations, eval_every: 1 }
    }

    #[test]
    fn fqi_with_an_exact_learner_is_value_iteration() {
        let (env, d) = (Chain::new(), chain_data());
        for enc in [ActionEncoding::Input, ActionEncoding::PerAction] {
            let e = Encoded::new(&d, env.actions(), enc).unwrap();
            let count = AtomicUsize::new(0);
            let learner = Table(&count);
            for k in 1..=8 {
                let mut f = Fqi::new(&env, &d, &e, &learner, settings(Algorithm::Fqi, k), 1, 2);
                for _ in 0..k {
                    f.iterate().unwrap().unwrap();
                }
                let vi = value_iteration(k);
                for i in 0..d.len() {
                    let (s, a) = (d.state[i] as usize, d.action[i] as usize);
                    assert!((f.q_train()[i] - vi[s][a]).abs() < 1e-12, "{enc:?} k={k} s={s} a={a}");
                }
            }
        }
    }

    #[test]
    fn bfqi_sum_of_members_equals_fqi_with_an_exact_learner() {
        let (env, d) = (Chain::new(), chain_data());
        let e = Encoded::new(&d, env.actions(), ActionEncoding::Input).unwrap();
        let count = AtomicUsize::new(0);
        let learner = Table(&count);
        let mut fqi = Fqi::new(&env, &d, &e, &learner, settings(Algorithm::Fqi, 10), 1, 2);
        let mut bfqi = Fqi::new(&env, &d, &e, &learner, settings(Algorithm::Bfqi, 10), 1, 2);
        let (mut row, mut qa, mut qb) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        for _ in 0..10 {
            let ra = fqi.iterate().unwrap().unwrap();
            let rb = bfqi.iterate().unwrap().unwrap();
            for s in 0..5 {
                fqi.q_values(&[s as f64], &mut row, &mut qa);
                bfqi.q_values(&[s as f64], &mut row, &mut qb);
                for j in 0..2 {
                    assert!((qa[j] - qb[j]).abs() < 1e-12);
                }
            }
            assert_eq!(ra.score, rb.score);
            assert!((ra.bellman_residual - rb.bellman_residual).abs() < 1e-12);
        }
        // The greedy policy walks right: 4 steps of −0.1, then +1.
        assert!((fqi.evaluate().unwrap().score - 0.6).abs() < 1e-12);
        assert_eq!(bfqi.members().len(), 10);
        // Ten members: two threads sum them in parallel, one thread in turn; same policy, same score.
        let pool = |n| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
        let (one, two) = (pool(1).install(|| bfqi.evaluate()).unwrap(), pool(2).install(|| bfqi.evaluate()).unwrap());
        assert_eq!((one.score.to_bits(), one.steps), (two.score.to_bits(), two.steps));
        assert!((two.score - 0.6).abs() < 1e-12);
        assert_eq!(fqi.members().len(), 1);
    }

    #[test]
    fn bfqi_fits_one_model_per_iteration_and_running_sums_match_members() {
        let (env, d) = (Chain::new(), chain_data());
        for enc in [ActionEncoding::Input, ActionEncoding::PerAction] {
            let e = Encoded::new(&d, env.actions(), enc).unwrap();
            let count = AtomicUsize::new(0);
            let learner = Table(&count);
            let mut f = Fqi::new(&env, &d, &e, &learner, settings(Algorithm::Bfqi, 7), 1, 2);
            for k in 1..=7 {
                f.iterate().unwrap().unwrap();
                assert_eq!(f.fits, k, "one member per iteration");
                let per_member = if enc == ActionEncoding::PerAction { 2 } else { 1 };
                assert_eq!(count.load(Ordering::SeqCst), k * per_member);
                // From-scratch sum of member predictions.
                let mut sum_train = vec![0.0; d.len()];
                let mut sum_next = vec![0.0; d.len() * 2];
                let (mut pt, mut pn) = (vec![0.0; d.len()], vec![0.0; d.len() * 2]);
                for m in f.members() {
                    e.predict_train(m, &mut pt);
                    e.predict_next(m, &mut pn);
                    add(&mut sum_train, &pt);
                    add(&mut sum_next, &pn);
                }
                assert_eq!(sum_train, f.q_train());
                assert_eq!(sum_next, f.q_next());
            }
        }
    }

    #[test]
    fn non_finite_rewards_are_a_divergence_not_a_crash() {
        let (env, mut d) = (Chain::new(), chain_data());
        d.reward[3] = f64::INFINITY;
        let e = Encoded::new(&d, env.actions(), ActionEncoding::Input).unwrap();
        let count = AtomicUsize::new(0);
        let learner = Table(&count);
        let rec = Fqi::new(&env, &d, &e, &learner, settings(Algorithm::Fqi, 5), 1, 2).run(|_| {}).unwrap();
        assert_eq!(rec.diverged.as_ref().unwrap().iteration, 1);
        assert_eq!(rec.final_score(), None);
    }

    #[test]
    fn per_action_refuses_continuous_actions() {
        let (env, mut d) = (Chain::new(), chain_data());
        d.action[0] = 0.3;
        let err = Encoded::new(&d, env.actions(), ActionEncoding::PerAction).unwrap_err().to_string();
        assert!(err.contains("per_action"), "{err}");
    }
}
