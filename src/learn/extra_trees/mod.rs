//! Extra-Trees regression (SPEC §3), with scikit-learn's `ExtraTreesRegressor` semantics.
//!
//! Each tree sees every row (no bootstrap). At a node, every feature is tried in a random order:
//! constant features are skipped, the others get one threshold drawn uniformly in the node's
//! `[min, max)` of that feature, and the candidate with the largest variance reduction wins
//! (candidates leaving fewer than `min_samples_leaf` rows on a side are rejected). A row goes left iff
//! `x[f] <= threshold`. Leaves hold the mean target; the forest predicts the mean over trees.
//!
//! Like scikit-learn, the inputs are compared in `f32`: thresholds are chosen among the rows' `f32`
//! values, and a query goes left iff `(x as f32) <= t`. The stored `f64` threshold is rewritten so
//! that the plain `x <= threshold` on the `f64` query gives exactly that answer (see
//! `splitter::query_threshold`), which keeps prediction free of conversions.
//!
//! Speed: each tree works on its own copy of the data, stored column by column and physically
//! partitioned at every split (two buffers, alternating with depth), so every pass over a node's
//! rows reads contiguous memory; on CPUs with AVX-512 the passes are vectorised by hand (see
//! `kernels::avx512`), with sums kept in the same lanes as the portable code so the trees are
//! identical. Tree `t` draws from the stream `(seed, "tree", t)` only, so the forest is identical
//! for any thread count. Prediction walks 8 trees (or 8 rows) at once, branch-free, so cache misses
//! overlap. [`Regressor::predict_actions_into`](super::Regressor::predict_actions_into) (Q of every
//! action, the action being the last input) walks each tree once per state and forks only at the
//! splits on the action (see `predict::forked_walks`), adding the trees in the same order as
//! `predict_row`, so its answers are bit-identical.
//! [`Learner::fit_predict_next`] (FQI's Q(x′, ·) with the fit) goes further: a next state that is
//! also a training state takes that row's leaf, recorded during the build, and walks only from the
//! splits on the action above it.
//!
//! The code follows the seams of scikit-learn's `sklearn/tree`: `tree` (nodes and their storage),
//! `builder` (the depth-first builder), `splitter` (the random split rule), `criterion` (variance
//! arithmetic), `partition` (moving a node's rows to its children), `kernels` (portable and
//! AVX-512), `predict` (the walks), and `routes` (what only FQI needs).

mod builder;
mod criterion;
mod kernels;
mod partition;
mod predict;
mod routes;
mod splitter;
#[cfg(test)]
mod tests;
mod tree;

pub use tree::{ForestParts, TreeParts};

use super::{FitInfo, Learner, NextStates, Rows, check_training_data};
use crate::error::{Result, ensure};
use crate::rng;
use builder::{Data, build_tree, with_workspace};
use rayon::prelude::*;
use routes::{Record, Routes};
use serde::{Deserialize, Serialize};
use std::time::Instant;
use tree::Tree;

/// Hyperparameters of an Extra-Trees forest (scikit-learn names and defaults, except the 50 trees).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExtraTreesParams {
    /// Number of trees (≥ 1).
    pub n_trees: usize,
    /// Maximum depth, in edges from the root (1 = a stump); `None` grows until the other rules stop.
    pub max_depth: Option<usize>,
    /// A node with fewer rows than this is a leaf (≥ 2).
    pub min_samples_split: usize,
    /// Every leaf keeps at least this many rows (≥ 1).
    pub min_samples_leaf: usize,
}

impl Default for ExtraTreesParams {
    fn default() -> Self {
        ExtraTreesParams { n_trees: 50, max_depth: None, min_samples_split: 2, min_samples_leaf: 1 }
    }
}

impl Learner for ExtraTreesParams {
    type Model = ExtraTrees;

    fn check(&self) -> Result<()> {
        crate::limits::within("n_trees", self.n_trees, 1, crate::limits::TREES)?;
        if let Some(d) = self.max_depth {
            ensure(d >= 1, "max_depth", d, "must be ≥ 1 (or null for unlimited)")?;
        }
        ensure(self.min_samples_split >= 2, "min_samples_split", self.min_samples_split, "must be ≥ 2")?;
        ensure(self.min_samples_leaf >= 1, "min_samples_leaf", self.min_samples_leaf, "must be ≥ 1")
    }

    fn fit(&self, x: Rows<'_>, y: &[f64], seed: u64) -> Result<(ExtraTrees, FitInfo)> {
        Ok((self.fit_impl(x, y, seed, Record::Nothing)?.0, TREE_FIT))
    }

    /// Each tree records the leaf every training row lands in while it is built (the rows are
    /// physically partitioned anyway), so the in-sample prediction is a sum of leaf values, added
    /// in tree order exactly as `predict_into` adds them: no walk.
    fn fit_predict(&self, x: Rows<'_>, y: &[f64], seed: u64, out: &mut [f64]) -> Result<(ExtraTrees, FitInfo)> {
        assert_eq!(out.len(), x.n_rows(), "one output per row");
        let (model, routes) = self.fit_impl(x, y, seed, Record::Routes(usize::MAX))?;
        model.predict_training(&routes, out);
        Ok((model, TREE_FIT))
    }

    /// A next state equal to a training row's state (its twin) follows the twin's path to the
    /// twin's leaf, unless a node on that path splits on the action: then it follows it to the
    /// first such node, the leaf's fork. So each tree records every training row's leaf and each
    /// leaf's fork, and a next state takes its twin's leaf for every action, or starts its walk at
    /// the fork. In FQI's trajectories nearly every next state is the next transition's state and
    /// most leaves have no fork, so most of the walking is skipped. The sums are added in tree
    /// order as in `predict_actions_into` / `predict_into`, so the results are bit-identical.
    fn fit_predict_next(
        &self,
        x: Rows<'_>,
        y: &[f64],
        seed: u64,
        out: &mut [f64],
        next: &NextStates<'_>,
        out_next: &mut [f64],
    ) -> Result<(ExtraTrees, FitInfo, f64)> {
        assert_eq!(out.len(), x.n_rows(), "one output per row");
        let d = next.states.n_cols();
        let (k, fork_col) = match next.actions {
            Some(a) => (a.len(), d),
            None => (1, usize::MAX),
        };
        assert_eq!(x.n_cols(), d + next.actions.is_some() as usize, "the states are the inputs before the action");
        assert_eq!(next.same.len(), next.states.n_rows(), "one hint per state");
        assert_eq!(out_next.len(), next.states.n_rows() * k, "one output per state (and action)");
        let (model, routes) = self.fit_impl(x, y, seed, Record::Routes(fork_col))?;
        model.predict_training(&routes, out);
        let t = Instant::now();
        model.predict_next_routed(next, &routes, out_next);
        Ok((model, TREE_FIT, t.elapsed().as_secs_f64()))
    }
}

/// What a tree fit reports (trees are not iterative).
const TREE_FIT: FitInfo = FitInfo::NOT_ITERATIVE;

impl ExtraTreesParams {
    /// Fits the forest; with [`Record::Routes`], also returns where the training rows end up in
    /// each tree.
    fn fit_impl(&self, x: Rows<'_>, y: &[f64], seed: u64, record: Record) -> Result<(ExtraTrees, Vec<Routes>)> {
        self.check()?;
        check_training_data(x, y)?;
        let data = Data::new(x, y, record)?;
        let built: Vec<(Tree, Routes)> = (0..self.n_trees)
            .into_par_iter()
            .map(|t| {
                let m = if data.idx.is_empty() { 0 } else { data.n };
                let mut routes = Routes { leaf_of: vec![0; m], value: Vec::new(), fork: Vec::new() };
                let tree = with_workspace(data.d, data.n, |ws| {
                    build_tree(self, &data, ws, rng::stream(seed, rng::purpose::TREE, &[t as u64]), &mut routes)
                });
                (tree, routes)
            })
            .collect();
        let (trees, routes) = built.into_iter().unzip();
        Ok((ExtraTrees { n_inputs: data.d, trees }, routes))
    }
}

/// A fitted Extra-Trees forest.
#[derive(Debug, Clone)]
pub struct ExtraTrees {
    n_inputs: usize,
    trees: Vec<Tree>,
}

impl ExtraTrees {
    /// Number of trees.
    pub fn n_trees(&self) -> usize {
        self.trees.len()
    }

    /// Depth of tree `t` (edges from the root to its deepest leaf; 0 for a single leaf).
    pub fn tree_depth(&self, t: usize) -> usize {
        self.trees[t].depth
    }

    /// Number of nodes (internal and leaves) of tree `t`.
    pub fn n_nodes(&self, t: usize) -> usize {
        self.trees[t].nodes.len()
    }

    /// Number of leaves of tree `t`.
    pub fn n_leaves(&self, t: usize) -> usize {
        self.trees[t].nodes.iter().filter(|n| n.is_leaf()).count()
    }

    /// Training rows in each leaf of tree `t`, in node order.
    pub fn leaf_sizes(&self, t: usize) -> Vec<usize> {
        let tree = &self.trees[t];
        tree.nodes.iter().zip(&tree.counts).filter(|(n, _)| n.is_leaf()).map(|(_, &c)| c as usize).collect()
    }

    /// Features tested by the internal nodes of tree `t`, in node order.
    pub fn split_features(&self, t: usize) -> Vec<usize> {
        self.trees[t].nodes.iter().filter(|n| !n.is_leaf()).map(|n| n.feat as usize).collect()
    }
}
