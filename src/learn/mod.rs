//! Learners: the regressor S of the thesis (SPEC §3).
//!
//! The interface follows linfa's `Fit`/`PredictInplace`: hyperparameters are serde structs checked
//! before fitting ([`Learner::check`]), and a fitted [`Regressor`] predicts into a caller's buffer, for a
//! batch of rows or for one row (the greedy policy asks one state at a time).

pub mod actions;
pub(crate) mod cpu;
pub mod extra_trees;
pub mod mlp;

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// A borrowed row-major matrix: `data.len() == rows × cols`.
#[derive(Debug, Clone, Copy)]
pub struct Rows<'a> {
    data: &'a [f64],
    cols: usize,
}

impl<'a> Rows<'a> {
    /// Views `data` as rows of `cols` values. Fails if `cols` is 0 or does not divide the length.
    pub fn new(data: &'a [f64], cols: usize) -> Result<Self> {
        if cols == 0 || !data.len().is_multiple_of(cols) {
            return Err(Error::Data(format!("{} values do not form rows of {cols} columns", data.len())));
        }
        Ok(Rows { data, cols })
    }
    /// Number of rows.
    pub fn n_rows(&self) -> usize {
        self.data.len() / self.cols
    }
    /// Number of columns (features).
    pub fn n_cols(&self) -> usize {
        self.cols
    }
    /// Row `i`.
    #[inline]
    pub fn row(&self, i: usize) -> &'a [f64] {
        &self.data[i * self.cols..(i + 1) * self.cols]
    }
    /// The underlying row-major data.
    pub fn data(&self) -> &'a [f64] {
        self.data
    }
    /// Rows `start..end` as a view.
    pub fn slice(&self, start: usize, end: usize) -> Rows<'a> {
        Rows { data: &self.data[start * self.cols..end * self.cols], cols: self.cols }
    }
}

/// Checks a training set: at least one row, as many targets as rows, every value finite.
pub fn check_training_data(x: Rows<'_>, y: &[f64]) -> Result<()> {
    if x.n_rows() == 0 {
        return Err(Error::Data("the training set is empty".into()));
    }
    if y.len() != x.n_rows() {
        return Err(Error::Data(format!("{} rows but {} targets", x.n_rows(), y.len())));
    }
    if let Some(i) = x.data().iter().position(|v| !v.is_finite()) {
        return Err(Error::Data(format!(
            "non-finite input {} at row {}, column {}",
            x.data()[i],
            i / x.n_cols(),
            i % x.n_cols()
        )));
    }
    if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        return Err(Error::Data(format!("non-finite target {} at row {i}", y[i])));
    }
    Ok(())
}

/// Why an iterative fit ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// Not an iterative learner (trees).
    NotIterative,
    /// Early stopping: patience + 1 consecutive epochs without improvement.
    EarlyStopping,
    /// The epoch cap was reached.
    MaxEpochs,
    /// The training or validation loss became non-finite (a diverged fit: FQI records it).
    NonFinite,
}

/// What a fit did, beyond the model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitInfo {
    /// Epochs run (0 for trees).
    pub epochs: usize,
    /// Why it stopped.
    pub stop: StopReason,
    /// Training loss of the last epoch run (networks; `None` for trees).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub train_loss: Option<f64>,
    /// Validation loss of the last epoch run (networks; `None` for trees).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub val_loss: Option<f64>,
}

impl FitInfo {
    /// A fit that is not iterative (trees).
    pub const NOT_ITERATIVE: FitInfo =
        FitInfo { epochs: 0, stop: StopReason::NotIterative, train_loss: None, val_loss: None };

    /// What several models fitted as one member did: epochs summed; non-finite if any fit was,
    /// else the last model's reason; no single loss.
    pub fn combined(infos: &[FitInfo]) -> FitInfo {
        let mut info = FitInfo::NOT_ITERATIVE;
        for fi in infos {
            info.epochs += fi.epochs;
            if info.stop != StopReason::NonFinite {
                info.stop = fi.stop;
            }
        }
        if let [one] = infos {
            (info.train_loss, info.val_loss) = (one.train_loss, one.val_loss);
        }
        info
    }
}

/// A fitted regression model.
pub trait Regressor: Send + Sync {
    /// Number of input features it was fitted on.
    fn n_inputs(&self) -> usize;
    /// Predicts one row (`row.len() == n_inputs()`).
    fn predict_row(&self, row: &[f64]) -> f64;
    /// Predicts every row of `x` into `out` (`out.len() == x.n_rows()`), allocating nothing per row.
    fn predict_into(&self, x: Rows<'_>, out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = self.predict_row(x.row(i));
        }
    }

    /// Predicts each row of `states` extended by each action as its last feature:
    /// `out[i·|A| + j] = f([states_i, actions[j]])` (the `input` action encoding's Q over all actions).
    /// Models can do much better than the default, which builds every row: a tree can follow a
    /// state once and fork only where it splits on the action.
    fn predict_actions_into(&self, states: Rows<'_>, actions: &[f64], out: &mut [f64]) {
        let d = states.n_cols();
        // A stack row for the usual few features: no allocation per call in the greedy policy.
        let (mut stack, mut heap) = ([0.0f64; 16], Vec::new());
        let row: &mut [f64] = if d < 16 {
            &mut stack[..=d]
        } else {
            heap.resize(d + 1, 0.0);
            &mut heap
        };
        for i in 0..states.n_rows() {
            row[..d].copy_from_slice(states.row(i));
            for (j, &a) in actions.iter().enumerate() {
                row[d] = a;
                out[i * actions.len() + j] = self.predict_row(row);
            }
        }
    }
}

/// A learning algorithm with its hyperparameters.
pub trait Learner: Send + Sync {
    /// The fitted model.
    type Model: Regressor;
    /// Validates the hyperparameters; the error names the field and what is allowed.
    fn check(&self) -> Result<()>;
    /// Fits a model on `x` → `y`. Every random draw derives from `seed` (SPEC §7), so the model is
    /// a pure function of (hyperparameters, data, seed), whatever the thread count.
    fn fit(&self, x: Rows<'_>, y: &[f64], seed: u64) -> Result<(Self::Model, FitInfo)>;

    /// [`Learner::fit`], also leaving the model's predictions on the training rows in `out`,
    /// bit-identical to `predict_into(x, out)`. FQI needs them every iteration (the Bellman residual,
    /// B-FQI's running sums); a learner that knows where each training row ends up (a tree's leaves)
    /// overrides this to skip the walk.
    fn fit_predict(&self, x: Rows<'_>, y: &[f64], seed: u64, out: &mut [f64]) -> Result<(Self::Model, FitInfo)> {
        let (m, info) = self.fit(x, y, seed)?;
        m.predict_into(x, out);
        Ok((m, info))
    }

    /// [`Learner::fit_predict`], also predicting the states of `next` into `out_next` as
    /// [`NextStates::predict`] would; returns the seconds that prediction took, so that callers can
    /// report fit and prediction apart. FQI asks this every iteration for Q(x′, ·), and in a
    /// dataset of trajectories almost every next state is also a training state: a learner that
    /// knows the training rows' routes (trees) overrides this to start from them.
    fn fit_predict_next(
        &self,
        x: Rows<'_>,
        y: &[f64],
        seed: u64,
        out: &mut [f64],
        next: &NextStates<'_>,
        out_next: &mut [f64],
    ) -> Result<(Self::Model, FitInfo, f64)> {
        let (m, info) = self.fit_predict(x, y, seed, out)?;
        let t = Instant::now();
        next.predict(&m, out_next);
        Ok((m, info, t.elapsed().as_secs_f64()))
    }
}

/// Marks a state of [`NextStates`] that is no training row's.
pub const NO_ROW: u32 = u32::MAX;

/// States to predict along with a fit (see [`Learner::fit_predict_next`]).
#[derive(Debug, Clone, Copy)]
pub struct NextStates<'a> {
    /// One state per row.
    pub states: Rows<'a>,
    /// `Some(actions)`: the model's inputs are a state followed by an action (the `input` action
    /// encoding), and every action is predicted for every state, as `predict_actions_into` does;
    /// `None`: the inputs are the state alone, as in `predict_into`.
    pub actions: Option<&'a [f64]>,
    /// `same[i]`: a training row whose state (its inputs before the action, or all of them) equals
    /// state `i` value for value, or [`NO_ROW`]. A hint: the predictions do not depend on it.
    pub same: &'a [u32],
}

impl NextStates<'_> {
    /// The model's predictions for these states, without the hint.
    pub fn predict<M: Regressor + ?Sized>(&self, m: &M, out: &mut [f64]) {
        match self.actions {
            Some(actions) => m.predict_actions_into(self.states, actions, out),
            None => m.predict_into(self.states, out),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_view_and_checks() {
        let d = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let r = Rows::new(&d, 2).unwrap();
        assert_eq!(r.n_rows(), 3);
        assert_eq!(r.row(1), &[3.0, 4.0]);
        assert_eq!(r.slice(1, 3).row(0), &[3.0, 4.0]);
        assert!(Rows::new(&d, 4).is_err());
        assert!(check_training_data(r, &[1.0, 2.0, 3.0]).is_ok());
        assert!(check_training_data(r, &[1.0, 2.0]).is_err());
        let e = check_training_data(r, &[1.0, f64::NAN, 3.0]).unwrap_err().to_string();
        assert!(e.contains("non-finite target NaN at row 1"), "{e}");
        let bad = [1.0, f64::INFINITY];
        let e = check_training_data(Rows::new(&bad, 2).unwrap(), &[0.0]).unwrap_err().to_string();
        assert!(e.contains("row 0, column 1"), "{e}");
    }
}

/// A learner with its settings, as spec files and run records name it:
/// `{"kind": "extra_trees", "n_trees": 50, ...}` or `{"kind": "mlp", "hidden": [10, 10], ...}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LearnerConfig {
    /// Extra-Trees (Geurts et al. 2006).
    ExtraTrees(extra_trees::ExtraTreesParams),
    /// The early-stopped MLP.
    Mlp(mlp::MlpParams),
}

impl<'de> Deserialize<'de> for LearnerConfig {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let (kind, rest) = crate::error::take_tag(d, "kind")?;
        match kind.as_str() {
            "extra_trees" => crate::error::tagged(rest).map(LearnerConfig::ExtraTrees),
            "mlp" => crate::error::tagged(rest).map(LearnerConfig::Mlp),
            other => Err(crate::error::unknown_tag("kind", other, &["extra_trees", "mlp"])),
        }
    }
}

impl LearnerConfig {
    /// Validates the settings; the error names the field (prefixed `learner.`).
    pub fn check(&self) -> Result<()> {
        match self {
            LearnerConfig::ExtraTrees(p) => p.check(),
            LearnerConfig::Mlp(p) => p.check(),
        }
        .map_err(|e| e.within("learner"))
    }

    /// The complexity knob the thesis sweeps: max depth for trees, units of the (single) hidden
    /// layer for networks.
    pub fn complexity(&self) -> Option<usize> {
        match self {
            LearnerConfig::ExtraTrees(p) => p.max_depth,
            LearnerConfig::Mlp(p) => p.hidden.first().copied(),
        }
    }

    /// The same learner at another complexity (see [`LearnerConfig::complexity`]); a network becomes
    /// one hidden layer of `c` units, as in the thesis's complexity analysis.
    pub fn with_complexity(&self, c: usize) -> Self {
        match self {
            LearnerConfig::ExtraTrees(p) => {
                LearnerConfig::ExtraTrees(extra_trees::ExtraTreesParams { max_depth: Some(c), ..p.clone() })
            }
            LearnerConfig::Mlp(p) => LearnerConfig::Mlp(mlp::MlpParams { hidden: vec![c], ..p.clone() }),
        }
    }

    /// A short label: `et` or `mlp`.
    pub fn short(&self) -> &'static str {
        match self {
            LearnerConfig::ExtraTrees(_) => "et",
            LearnerConfig::Mlp(_) => "mlp",
        }
    }
}
