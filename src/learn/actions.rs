//! Action encodings (SPEC §3): how a regressor on states becomes a Q-function over actions.
//!
//! - `input`: one model on `[observation, action]`;
//! - `per_action`: one model per discrete action, on the observation alone, fitted on the transitions
//!   that took that action.
//!
//! [`Encoded`] lays a dataset out once for an encoding (the training rows and every (next state,
//! action) pair), so FQI's iterations only fit and predict.

use super::{FitInfo, Learner, NO_ROW, NextStates, Regressor, Rows};
use crate::dataset::Dataset;
use crate::env::EnvConfig;
use crate::error::{Error, Result};
use crate::rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::time::Instant;

/// How actions reach the learner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionEncoding {
    /// One model on `[state, action]`.
    Input,
    /// One model per discrete action, on the state.
    PerAction,
}

impl ActionEncoding {
    /// Refuses `per_action` for an environment whose dataset actions are continuous, naming `field`.
    pub fn check_for(self, env: &EnvConfig, field: &str) -> Result<()> {
        crate::error::ensure(
            self != ActionEncoding::PerAction || env.discrete_dataset_actions(),
            field,
            "per_action",
            &format!(
                "needs discrete dataset actions; {}'s random policy takes continuous ones (use input)",
                env.env().name()
            ),
        )
    }
}

/// A dataset laid out for one encoding and one discrete action set.
#[derive(Debug, Clone)]
pub struct Encoded {
    /// The encoding.
    pub encoding: ActionEncoding,
    /// The discrete actions (feature values) maximised over.
    pub actions: Vec<f64>,
    /// Observation dimension.
    pub obs_dim: usize,
    /// Transitions.
    pub n: usize,
    /// `input`: rows `[x_i, a_i]` (n rows). `per_action`: for each action, the rows `x_i` of its
    /// transitions, concatenated in action order.
    train: Vec<f64>,
    /// `per_action`: transition indices of each action's rows, concatenated in action order.
    train_index: Vec<usize>,
    /// `per_action`: start of each action's rows in `train_index` (len = actions + 1).
    train_offsets: Vec<usize>,
    /// Next states `x'_i` (n rows); the models are asked for every action at once.
    next: Vec<f64>,
    /// Each next state's training twin (see [`NextStates::same`]): `input`, n entries, a training
    /// row; `per_action`, n per action in action order, a row of that action's model (or
    /// [`NO_ROW`]). In a dataset of trajectories, `x'_i` is the state of transition i + 1.
    twins: Vec<u32>,
}

impl Encoded {
    /// Lays out `d` for `encoding` over the discrete `actions`. With `per_action`, every dataset
    /// action must be one of `actions` (a continuous-action dataset such as the pendulum's cannot be
    /// split per action) and every action must occur at least once.
    pub fn new(d: &Dataset, actions: &[f64], encoding: ActionEncoding) -> Result<Self> {
        let (n, od) = (d.len(), d.obs_dim);
        if n == 0 {
            return Err(Error::Data("the dataset is empty".into()));
        }
        let mut e = Encoded {
            encoding,
            actions: actions.to_vec(),
            obs_dim: od,
            n,
            train: Vec::new(),
            train_index: Vec::new(),
            train_offsets: Vec::new(),
            next: Vec::new(),
            twins: Vec::new(),
        };
        match encoding {
            ActionEncoding::Input => {
                e.train.reserve(n * (od + 1));
                for i in 0..n {
                    e.train.extend_from_slice(&d.state[i * od..(i + 1) * od]);
                    e.train.push(d.action[i]);
                }
                // Next states only: models predict them under every action at once.
                e.next = d.next_state.clone();
            }
            ActionEncoding::PerAction => {
                let mut groups: Vec<Vec<usize>> = vec![Vec::new(); actions.len()];
                for (i, a) in d.action.iter().enumerate() {
                    let j = actions.iter().position(|b| b == a).ok_or_else(|| {
                        Error::invalid(
                            "actions",
                            "per_action",
                            format!("needs dataset actions in {actions:?}; transition {i} has action {a} (use input)"),
                        )
                    })?;
                    groups[j].push(i);
                }
                if let Some(j) = groups.iter().position(Vec::is_empty) {
                    return Err(Error::Data(format!(
                        "action {} never occurs in the dataset: per_action cannot fit it",
                        actions[j]
                    )));
                }
                e.train_offsets.push(0);
                for g in &groups {
                    for &i in g {
                        e.train.extend_from_slice(&d.state[i * od..(i + 1) * od]);
                        e.train_index.push(i);
                    }
                    e.train_offsets.push(e.train_index.len());
                }
                e.next = d.next_state.clone();
            }
        }
        e.twins = twins(d, &e);
        Ok(e)
    }

    /// `out[i] = vals[k]` for the k-th training row of action j (`per_action` layout).
    /// `out[i·|A| + j] = vals[i]`: action j's Q on every next state, into the i-major table.
    fn put_action_column(&self, j: usize, vals: &[f64], out: &mut [f64]) {
        for (i, &v) in vals.iter().enumerate() {
            out[i * self.actions.len() + j] = v;
        }
    }

    fn put_action_rows(&self, j: usize, vals: &[f64], out: &mut [f64]) {
        let (lo, hi) = (self.train_offsets[j], self.train_offsets[j + 1]);
        for (&i, &v) in self.train_index[lo..hi].iter().zip(vals) {
            out[i] = v;
        }
    }

    /// Models per Q-function member: one with `input`, one per action with `per_action`.
    pub fn n_models(&self) -> usize {
        match self.encoding {
            ActionEncoding::Input => 1,
            ActionEncoding::PerAction => self.actions.len(),
        }
    }

    /// Model `j`'s training rows (row-major, [`Encoded::n_inputs`] values each), in the order it
    /// is fitted on them, and the transition each row comes from.
    pub fn model_rows(&self, j: usize) -> (&[f64], Vec<usize>) {
        match self.encoding {
            ActionEncoding::Input => (&self.train, (0..self.n).collect()),
            ActionEncoding::PerAction => {
                let (lo, hi) = (self.train_offsets[j], self.train_offsets[j + 1]);
                (&self.train[lo * self.obs_dim..hi * self.obs_dim], self.train_index[lo..hi].to_vec())
            }
        }
    }

    /// Number of input features of each model.
    pub fn n_inputs(&self) -> usize {
        match self.encoding {
            ActionEncoding::Input => self.obs_dim + 1,
            ActionEncoding::PerAction => self.obs_dim,
        }
    }

    /// Fits one Q-function member on targets `y` (one per transition), leaving its predictions on
    /// the training rows in `out` (`out[i] = Q(x_i, a_i)`, as [`Encoded::predict_train`] would) and
    /// on every (next state, action) pair in `out_next` (as [`Encoded::predict_next`] would); also
    /// returns the seconds the latter took. With `per_action`, model j is fitted on action j's
    /// transitions with the seed `derive(seed, "action", [j])`.
    pub fn fit_predict_next<L: Learner>(
        &self,
        learner: &L,
        y: &[f64],
        seed: u64,
        out: &mut [f64],
        out_next: &mut [f64],
    ) -> Result<(QModel<L::Model>, Vec<FitInfo>, f64)> {
        let states = Rows::new(&self.next, self.obs_dim)?;
        match self.encoding {
            ActionEncoding::Input => {
                let next = NextStates { states, actions: Some(&self.actions), same: &self.twins };
                let x = Rows::new(&self.train, self.n_inputs())?;
                let (m, info, seconds) = learner.fit_predict_next(x, y, seed, out, &next, out_next)?;
                Ok((QModel::Input(m), vec![info], seconds))
            }
            ActionEncoding::PerAction => {
                let (na, n) = (self.actions.len(), self.n);
                // The actions' models are independent (each has its own rows and seed), so they are
                // fitted in parallel: idle threads take some, results do not depend on which.
                let wall = Instant::now();
                let fits: Vec<_> = (0..na)
                    .into_par_iter()
                    .map(|j| {
                        let busy = Instant::now();
                        let (lo, hi) = (self.train_offsets[j], self.train_offsets[j + 1]);
                        let ys: Vec<f64> = self.train_index[lo..hi].iter().map(|&i| y[i]).collect();
                        let (mut buf, mut next_buf) = (vec![0.0; hi - lo], vec![0.0; n]);
                        let x = &self.train[lo * self.obs_dim..hi * self.obs_dim];
                        let seed_j = rng::derive(seed, rng::purpose::ACTION, &[j as u64]);
                        let next = NextStates { states, actions: None, same: &self.twins[j * n..(j + 1) * n] };
                        let (m, fi, s) = learner.fit_predict_next(
                            Rows::new(x, self.obs_dim)?,
                            &ys,
                            seed_j,
                            &mut buf,
                            &next,
                            &mut next_buf,
                        )?;
                        Ok((m, fi, s, busy.elapsed().as_secs_f64(), buf, next_buf))
                    })
                    .collect::<Result<_>>()?;
                let wall = wall.elapsed().as_secs_f64();
                let mut models = Vec::with_capacity(na);
                let mut infos = Vec::with_capacity(na);
                let (mut next_busy, mut busy) = (0.0, 0.0);
                for (j, (m, fi, s, b, buf, next_buf)) in fits.into_iter().enumerate() {
                    self.put_action_rows(j, &buf, out);
                    self.put_action_column(j, &next_buf, out_next);
                    next_busy += s;
                    busy += b;
                    infos.push(fi);
                    models.push(m);
                }
                // The actions ran on several threads at once: summed, their prediction seconds can
                // exceed the wall time (and the caller's fit time, wall minus this, went negative).
                // Report the prediction's share of the threads' busy time, as wall seconds.
                let seconds = if busy > 0.0 { wall * (next_busy / busy).min(1.0) } else { 0.0 };
                Ok((QModel::PerAction(models), infos, seconds))
            }
        }
    }

    /// Predicts a member on the training rows, `out[i] = Q(x_i, a_i)`.
    pub fn predict_train<M: Regressor>(&self, q: &QModel<M>, out: &mut [f64]) {
        match q {
            QModel::Input(m) => m.predict_into(Rows::new(&self.train, self.n_inputs()).expect("laid out"), out),
            QModel::PerAction(ms) => {
                let mut buf = Vec::new();
                for (j, m) in ms.iter().enumerate() {
                    let (lo, hi) = (self.train_offsets[j], self.train_offsets[j + 1]);
                    buf.resize(hi - lo, 0.0);
                    let x = &self.train[lo * self.obs_dim..hi * self.obs_dim];
                    m.predict_into(Rows::new(x, self.obs_dim).expect("laid out"), &mut buf);
                    self.put_action_rows(j, &buf, out);
                }
            }
        }
    }

    /// Predicts a member on every (next state, action) pair, `out[i·|A| + j] = Q(x'_i, a_j)`.
    pub fn predict_next<M: Regressor>(&self, q: &QModel<M>, out: &mut [f64]) {
        match q {
            QModel::Input(m) => {
                m.predict_actions_into(Rows::new(&self.next, self.obs_dim).expect("laid out"), &self.actions, out)
            }
            QModel::PerAction(ms) => {
                let mut buf = vec![0.0; self.n];
                for (j, m) in ms.iter().enumerate() {
                    m.predict_into(Rows::new(&self.next, self.obs_dim).expect("laid out"), &mut buf);
                    self.put_action_column(j, &buf, out);
                }
            }
        }
    }
}

/// Each next state's training twin for `e` (see [`Encoded`]'s `twins`): the first training row with
/// the same state, value for value (bit patterns, so the twin's inputs are exactly the state's).
fn twins(d: &Dataset, e: &Encoded) -> Vec<u32> {
    let (n, od) = (d.len(), d.obs_dim);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
    let (state, next) = (bits(&d.state), bits(&d.next_state));
    // (state, model) → the model's training row: the transition itself with `input`, its
    // position among its action's rows with `per_action`.
    let mut first: HashMap<(&[u64], usize), u32> = HashMap::with_capacity(n);
    match e.encoding {
        ActionEncoding::Input => {
            for i in 0..n {
                first.entry((&state[i * od..(i + 1) * od], 0)).or_insert(i as u32);
            }
        }
        ActionEncoding::PerAction => {
            for (j, w) in e.train_offsets.windows(2).enumerate() {
                for (r, &i) in e.train_index[w[0]..w[1]].iter().enumerate() {
                    first.entry((&state[i * od..(i + 1) * od], j)).or_insert(r as u32);
                }
            }
        }
    }
    let models = if e.encoding == ActionEncoding::Input { 1 } else { e.actions.len() };
    (0..models)
        .flat_map(|j| (0..n).map(move |i| (j, i)))
        .map(|(j, i)| first.get(&(&next[i * od..(i + 1) * od], j)).copied().unwrap_or(NO_ROW))
        .collect()
}
/// One fitted Q-function member under an encoding.
#[derive(Debug, Clone)]
pub enum QModel<M> {
    /// One model on `[state, action]`.
    Input(M),
    /// One model per action.
    PerAction(Vec<M>),
}

impl<M: Regressor> QModel<M> {
    /// Adds `Q(obs, a_j)` to `out[j]` for every action; `scratch` holds at least `actions.len()` values.
    pub fn add_q_values(&self, obs: &[f64], actions: &[f64], scratch: &mut [f64], out: &mut [f64]) {
        match self {
            QModel::Input(m) => {
                let q = &mut scratch[..actions.len()];
                m.predict_actions_into(Rows::new(obs, obs.len()).expect("one row"), actions, q);
                for (o, v) in out.iter_mut().zip(q.iter()) {
                    *o += v;
                }
            }
            QModel::PerAction(ms) => {
                for (o, m) in out.iter_mut().zip(ms) {
                    *o += m.predict_row(obs);
                }
            }
        }
    }

    /// `Q(obs, action)` at one action's feature value: any value with `Input` (a logged continuous
    /// action), one of `actions` with `PerAction` (`None` otherwise).
    pub fn q_at(&self, obs: &[f64], action: f64, actions: &[f64]) -> Option<f64> {
        match self {
            QModel::Input(m) => {
                let mut row = Vec::with_capacity(obs.len() + 1);
                row.extend_from_slice(obs);
                row.push(action);
                Some(m.predict_row(&row))
            }
            QModel::PerAction(ms) => actions.iter().position(|&a| a == action).map(|j| ms[j].predict_row(obs)),
        }
    }
}

/// The first index of the largest value (ties go to the first action, SPEC §1).
pub fn argmax(values: &[f64]) -> usize {
    let mut best = 0;
    for (j, &v) in values.iter().enumerate().skip(1) {
        if v > values[best] {
            best = j;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset;
    use crate::env::EnvConfig;
    use crate::learn::extra_trees::ExtraTreesParams;

    #[test]
    fn next_states_find_their_training_twins() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        let (e, od) = (c.env(), c.env().obs_dim());
        let d = dataset::collect(e, 30, 5).unwrap();
        let state = |i: usize| &d.state[i * od..(i + 1) * od];
        let next = |i: usize| &d.next_state[i * od..(i + 1) * od];
        let input = Encoded::new(&d, e.actions(), ActionEncoding::Input).unwrap();
        // Within an episode, the next state is the next transition's state.
        for i in 0..d.len() {
            let r = input.twins[i];
            if i + 1 < d.len() && d.episode[i + 1] == d.episode[i] {
                assert_ne!(r, NO_ROW, "transition {i}");
            }
            if r != NO_ROW {
                assert!(state(r as usize) == next(i) && r as usize <= i + 1, "transition {i}: first twin");
            }
        }
        let found = input.twins.iter().filter(|&&r| r != NO_ROW).count();
        assert!(found >= d.len() - d.episodes() && found < d.len(), "{found} twins");
        // Per action: a row of the model of the action the twin took.
        let per = Encoded::new(&d, e.actions(), ActionEncoding::PerAction).unwrap();
        for (i, &r) in input.twins.iter().enumerate() {
            for j in 0..per.actions.len() {
                let twin = per.twins[j * d.len() + i];
                let takes_j = r != NO_ROW && d.action[r as usize] == per.actions[j];
                assert_eq!(twin != NO_ROW, takes_j, "transition {i}, action {j}");
                if twin != NO_ROW {
                    let row = per.train_index[per.train_offsets[j] + twin as usize];
                    assert!(state(row) == next(i), "transition {i}, action {j}");
                }
            }
        }
        // The predictions with twins are those without, to the bit.
        let p = ExtraTreesParams { n_trees: 6, max_depth: Some(10), min_samples_split: 2, min_samples_leaf: 1 };
        for enc in [input, per] {
            let (n, na) = (d.len(), enc.actions.len());
            let (mut train, mut next_q) = (vec![0.0; n], vec![0.0; n * na]);
            let (m, _, seconds) = enc.fit_predict_next(&p, &d.reward, 9, &mut train, &mut next_q).unwrap();
            assert!(seconds >= 0.0);
            let (mut want_train, mut want_next) = (vec![0.0; n], vec![0.0; n * na]);
            enc.predict_train(&m, &mut want_train);
            enc.predict_next(&m, &mut want_next);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&train), bits(&want_train), "{:?}", enc.encoding);
            assert_eq!(bits(&next_q), bits(&want_next), "{:?}", enc.encoding);
        }
    }

    #[test]
    fn per_action_networks_fit_in_parallel_give_the_same_bits() {
        use crate::learn::mlp::MlpParams;
        let c = EnvConfig::by_name("cartpole").unwrap();
        let d = dataset::collect(c.env(), 40, 3).unwrap();
        let enc = Encoded::new(&d, c.env().actions(), ActionEncoding::PerAction).unwrap();
        let p = MlpParams { hidden: vec![6], max_epochs: 30, patience: 3, delta_min: 1e-4, ..Default::default() };
        let fit = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (mut train, mut next) = (vec![0.0; d.len()], vec![0.0; d.len() * enc.actions.len()]);
            let (_, infos, _) = pool.install(|| enc.fit_predict_next(&p, &d.reward, 5, &mut train, &mut next)).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let fits: Vec<_> = infos.iter().map(|i| (i.epochs, i.stop, i.val_loss.map(f64::to_bits))).collect();
            assert_eq!(fits.len(), enc.actions.len(), "one fit record per action's network");
            (bits(&train), bits(&next), fits)
        };
        assert_eq!(fit(1), fit(2));
        assert_eq!(fit(1), fit(3));
    }

    #[test]
    fn argmax_ties_go_first() {
        assert_eq!(argmax(&[1.0, 1.0, 0.5]), 0);
        assert_eq!(argmax(&[0.0, 2.0, 2.0]), 1);
        assert_eq!(argmax(&[3.0]), 0);
    }
}
