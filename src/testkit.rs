//! What unit tests of several modules share: a tiny environment whose optimal Q is known by value
//! iteration, and an exact learner, so FQI's arithmetic can be checked without a learner's error.

use crate::dataset::Dataset;
use crate::env::{Env, EvalConfig, Outcome, ScoreKind};
use crate::error::Result;
use crate::learn::{FitInfo, Learner, Regressor, Rows};
use crate::rng::Rng;
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A 6-state chain: action 1 moves right, 0 moves left; reaching state 5 pays 1 and absorbs.
/// Every other step pays −0.1 (so Q* is not trivial).
pub struct Chain {
    eval: EvalConfig,
    actions: Vec<f64>,
}

impl Chain {
    pub fn new() -> Self {
        Chain {
            eval: EvalConfig { episodes: 1, steps: 20, score: ScoreKind::Return, start: vec![[0.0, 0.0]] },
            actions: vec![0.0, 1.0],
        }
    }
    pub fn next(s: f64, a: f64) -> f64 {
        if a > 0.5 { (s + 1.0).min(5.0) } else { (s - 1.0).max(0.0) }
    }
}

impl Env for Chain {
    fn name(&self) -> &'static str {
        "chain"
    }
    fn state_dim(&self) -> usize {
        1
    }
    fn obs_dim(&self) -> usize {
        1
    }
    fn observe(&self, s: &[f64], o: &mut [f64]) {
        o[0] = s[0];
    }
    fn actions(&self) -> &[f64] {
        &self.actions
    }
    fn gamma(&self) -> f64 {
        0.9
    }
    fn horizon(&self) -> usize {
        20
    }
    fn dataset_start(&self, _: &mut Rng, s: &mut [f64]) {
        s[0] = 0.0;
    }
    fn dataset_action(&self, _: &mut Rng) -> f64 {
        1.0
    }
    fn step(&self, s: &[f64], a: f64, _: &mut Rng, next: &mut [f64]) -> Outcome {
        next[0] = Chain::next(s[0], a);
        let done = next[0] == 5.0;
        Outcome { reward: if done { 1.0 } else { -0.1 }, failed: done }
    }
    fn eval(&self) -> &EvalConfig {
        &self.eval
    }
}

/// Every (state, action) pair of the chain once.
pub fn chain_data() -> Dataset {
    let mut d = Dataset::with_capacity(1, 0);
    for s in 0..5 {
        for a in [0.0, 1.0] {
            let n = Chain::next(s as f64, a);
            d.episode.push(d.episode.len() as u32);
            d.step.push(0);
            d.state.push(s as f64);
            d.action.push(a);
            d.reward.push(if n == 5.0 { 1.0 } else { -0.1 });
            d.next_state.push(n);
            d.absorbing.push(n == 5.0);
        }
    }
    d
}

/// An exact learner: a lookup table of the mean target per distinct input row. Counts its fits.
pub struct Table<'c>(pub &'c AtomicUsize);
#[derive(Debug, Clone)]
pub struct TableModel(HashMap<Vec<u64>, f64>, usize);

impl Regressor for TableModel {
    fn n_inputs(&self) -> usize {
        self.1
    }
    fn predict_row(&self, row: &[f64]) -> f64 {
        *self.0.get(&row.iter().map(|v| v.to_bits()).collect::<Vec<_>>()).unwrap_or(&0.0)
    }
}

impl Learner for Table<'_> {
    type Model = TableModel;
    fn check(&self) -> Result<()> {
        Ok(())
    }
    fn fit(&self, x: Rows<'_>, y: &[f64], _seed: u64) -> Result<(TableModel, FitInfo)> {
        self.0.fetch_add(1, Ordering::SeqCst);
        let mut sums: HashMap<Vec<u64>, (f64, f64)> = HashMap::new();
        for (i, &t) in y.iter().enumerate() {
            let e = sums.entry(x.row(i).iter().map(|v| v.to_bits()).collect()).or_default();
            e.0 += t;
            e.1 += 1.0;
        }
        let m = sums.into_iter().map(|(k, (s, n))| (k, s / n)).collect();
        Ok((TableModel(m, x.n_cols()), FitInfo::NOT_ITERATIVE))
    }
}

/// Value iteration on the chain from Q_0 = 0, K sweeps: Q[s][a].
pub fn value_iteration(k: usize) -> Vec<[f64; 2]> {
    let mut q = vec![[0.0f64; 2]; 6];
    for _ in 0..k {
        let old = q.clone();
        for (s, qs) in q.iter_mut().enumerate().take(5) {
            for (a, qa) in qs.iter_mut().enumerate() {
                let n = Chain::next(s as f64, a as f64) as usize;
                *qa = if n == 5 { 1.0 } else { -0.1 + 0.9 * old[n][0].max(old[n][1]) };
            }
        }
    }
    q
}
