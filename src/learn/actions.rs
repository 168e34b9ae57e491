//! Action encodings (SPEC §3): how a regressor on states becomes a Q-function over actions.
//!
//! - `input`: one model on `[observation, action]`;
//! - `per_action`: one model per discrete action, on the observation alone, fitted on the transitions
//!   that took that action.
//!
//! [`Encoded`] lays a dataset out once for an encoding (the training rows and every (next state,
//! action) pair), so FQI's iterations only fit and predict.

use super::{FitInfo, Learner, Regressor, Rows, StopReason};
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::rng;
use serde::{Deserialize, Serialize};

/// How actions reach the learner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionEncoding {
    /// One model on `[state, action]`.
    Input,
    /// One model per discrete action, on the state.
    PerAction,
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
        Ok(e)
    }

    /// `out[i] = vals[k]` for the k-th training row of action j (`per_action` layout).
    fn put_action_rows(&self, j: usize, vals: &[f64], out: &mut [f64]) {
        let (lo, hi) = (self.train_offsets[j], self.train_offsets[j + 1]);
        for (&i, &v) in self.train_index[lo..hi].iter().zip(vals) {
            out[i] = v;
        }
    }

    /// Number of input features of each model.
    pub fn n_inputs(&self) -> usize {
        match self.encoding {
            ActionEncoding::Input => self.obs_dim + 1,
            ActionEncoding::PerAction => self.obs_dim,
        }
    }

    /// Fits one Q-function member on targets `y` (one per transition) and leaves its predictions on
    /// the training rows in `out` (`out[i] = Q(x_i, a_i)`, as [`Encoded::predict_train`] would).
    /// With `per_action`, model j is fitted on action j's transitions with the seed
    /// `derive(seed, "action", [j])`.
    pub fn fit_predict<L: Learner>(
        &self,
        learner: &L,
        y: &[f64],
        seed: u64,
        out: &mut [f64],
    ) -> Result<(QModel<L::Model>, FitInfo)> {
        match self.encoding {
            ActionEncoding::Input => {
                let (m, info) = learner.fit_predict(Rows::new(&self.train, self.n_inputs())?, y, seed, out)?;
                Ok((QModel::Input(m), info))
            }
            ActionEncoding::PerAction => {
                let mut models = Vec::with_capacity(self.actions.len());
                let mut info = FitInfo { epochs: 0, stop: StopReason::NotIterative };
                let (mut ys, mut buf) = (Vec::new(), Vec::new());
                for j in 0..self.actions.len() {
                    let (lo, hi) = (self.train_offsets[j], self.train_offsets[j + 1]);
                    ys.clear();
                    ys.extend(self.train_index[lo..hi].iter().map(|&i| y[i]));
                    buf.resize(hi - lo, 0.0);
                    let x = &self.train[lo * self.obs_dim..hi * self.obs_dim];
                    let seed_j = rng::derive(seed, "action", &[j as u64]);
                    let (m, fi) = learner.fit_predict(Rows::new(x, self.obs_dim)?, &ys, seed_j, &mut buf)?;
                    self.put_action_rows(j, &buf, out);
                    info.epochs += fi.epochs;
                    // Any non-finite fit makes the member diverged; otherwise report the last reason.
                    if info.stop != StopReason::NonFinite {
                        info.stop = fi.stop;
                    }
                    models.push(m);
                }
                Ok((QModel::PerAction(models), info))
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
        let na = self.actions.len();
        match q {
            QModel::Input(m) => {
                m.predict_actions_into(Rows::new(&self.next, self.obs_dim).expect("laid out"), &self.actions, out)
            }
            QModel::PerAction(ms) => {
                let mut buf = vec![0.0; self.n];
                for (j, m) in ms.iter().enumerate() {
                    m.predict_into(Rows::new(&self.next, self.obs_dim).expect("laid out"), &mut buf);
                    for (i, v) in buf.iter().enumerate() {
                        out[i * na + j] = *v;
                    }
                }
            }
        }
    }
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

    #[test]
    fn argmax_ties_go_first() {
        assert_eq!(argmax(&[1.0, 1.0, 0.5]), 0);
        assert_eq!(argmax(&[0.0, 2.0, 2.0]), 1);
        assert_eq!(argmax(&[3.0]), 0);
    }
}
