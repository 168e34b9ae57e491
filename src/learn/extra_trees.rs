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
//! [`query_threshold`]), which keeps prediction free of conversions.
//!
//! Speed: each tree works on its own copy of the data, stored column by column and physically
//! partitioned at every split (two buffers, alternating with depth), so every pass over a node's
//! rows reads contiguous memory; on CPUs with AVX-512 the passes are vectorised by hand (see
//! [`avx512`]), with sums kept in the same lanes as the portable code so the trees are identical.
//! Tree `t` draws from the stream `(seed, "tree", t)` only, so the forest is identical for any
//! thread count. Prediction walks 8 trees (or 8 rows) at once, branch-free, so cache misses overlap.
//! [`Regressor::predict_actions_into`] (Q of every action, the action being the last input) walks
//! each tree once per state and forks only at the splits on the action (see [`forked_walks`]),
//! adding the trees in the same order as `predict_row`, so its answers are bit-identical.
//! [`Learner::fit_predict_next`] (FQI's Q(x′, ·) with the fit) goes further: a next state that is
//! also a training state takes that row's leaf, recorded during the build, and walks only from the
//! splits on the action above it.

use super::{FitInfo, Learner, NO_ROW, NextStates, Regressor, Rows, check_training_data, cpu};
use crate::error::{Error, Result, ensure};
use crate::rng::{self, Rng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

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

/// Where the training rows end up in one tree (see [`Record::Routes`]).
struct Routes {
    /// Per row, its leaf, as an index into `value` and `fork`.
    leaf_of: Vec<u32>,
    /// The leaves the rows reach, in the order they were made: small arrays (a few rows per leaf
    /// at least), where the rows' lookups at random stay in cache, unlike the tree's nodes.
    value: Vec<f64>,
    /// The first node on the leaf's path that splits on [`Data::fork_col`], or [`NO_FORK`]: where
    /// a walk with the leaf's rows' state and any action leaves their path.
    fork: Vec<u32>,
}

/// No split on the fork column above a leaf (never a node index: a tree has < 2^32 − 1 nodes).
const NO_FORK: u32 = u32::MAX;

/// What a tree fit reports (trees are not iterative).
const TREE_FIT: FitInfo = FitInfo::NOT_ITERATIVE;

/// What the trees record for each training row while they are built.
#[derive(Debug, Clone, Copy)]
enum Record {
    Nothing,
    /// Its leaf, and each leaf's fork: its first ancestor that splits on this column (none for
    /// `usize::MAX`).
    Routes(usize),
}

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

/// A forest's storage as model files keep it (see [`crate::model`]): per tree, its nodes as
/// parallel arrays. Loading it back gives a forest whose predictions are bit-identical.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ForestParts {
    /// Input features.
    pub n_inputs: u32,
    /// The trees, in order (the prediction sums them in this order).
    pub trees: Vec<TreeParts>,
}

/// One tree of [`ForestParts`]: node `i` is `(val[i], feat[i], left[i])`, root at 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TreeParts {
    /// Edges from the root to the deepest leaf.
    pub depth: u32,
    /// Threshold (internal node) or prediction (leaf).
    pub val: Vec<f64>,
    /// Feature tested, or the leaf mark `1 << 31`.
    pub feat: Vec<u32>,
    /// Left child (the right one follows it), or the leaf itself.
    pub left: Vec<u32>,
    /// Training rows that reached each node.
    pub counts: Vec<u32>,
}

impl ExtraTrees {
    /// The forest's storage.
    pub fn to_parts(&self) -> ForestParts {
        let trees = self
            .trees
            .iter()
            .map(|t| TreeParts {
                depth: t.depth as u32,
                val: t.nodes.iter().map(|n| n.val).collect(),
                feat: t.nodes.iter().map(|n| n.feat).collect(),
                left: t.nodes.iter().map(|n| n.left).collect(),
                counts: t.counts.clone(),
            })
            .collect();
        ForestParts { n_inputs: self.n_inputs as u32, trees }
    }

    /// Rebuilds a forest from its storage, checking that every walk stays inside its tree and ends
    /// at a leaf within the recorded depth (a damaged file is refused, not walked).
    pub fn from_parts(p: ForestParts) -> Result<ExtraTrees> {
        let bad = |t: usize, what: String| Error::Data(format!("tree {t}: {what}"));
        if p.n_inputs == 0 || p.trees.is_empty() {
            return Err(Error::Data("a forest needs inputs and at least one tree".into()));
        }
        let mut trees = Vec::with_capacity(p.trees.len());
        for (t, tp) in p.trees.into_iter().enumerate() {
            let n = tp.val.len();
            if n == 0 || tp.feat.len() != n || tp.left.len() != n || tp.counts.len() != n || n > u32::MAX as usize / 2 {
                return Err(bad(t, "node arrays of different or zero lengths".into()));
            }
            // Children come after their parent, so depths follow in one pass over the nodes.
            let mut depth = vec![0u32; n];
            for i in 0..n {
                let (f, l) = (tp.feat[i], tp.left[i] as usize);
                if f == LEAF {
                    if l != i {
                        return Err(bad(t, format!("leaf {i} does not point at itself")));
                    }
                } else if f >= p.n_inputs || l <= i || l + 1 >= n {
                    return Err(bad(t, format!("node {i} tests feature {f} or has children at {l} out of range")));
                } else {
                    depth[l] = depth[i] + 1;
                    depth[l + 1] = depth[i] + 1;
                }
            }
            if depth.iter().max() != Some(&tp.depth) {
                return Err(bad(t, format!("recorded depth {} is not the tree's", tp.depth)));
            }
            let nodes = (0..n).map(|i| Node { val: tp.val[i], feat: tp.feat[i], left: tp.left[i] }).collect();
            trees.push(Tree { nodes, counts: tp.counts, depth: tp.depth as usize });
        }
        Ok(ExtraTrees { n_inputs: p.n_inputs as usize, trees })
    }
}

/// Walks interleaved in prediction: trees for one row, rows for one tree.
const WALKS: usize = 8;
/// Rows per block in [`ExtraTrees::predict_into`]: a tree is walked for the whole block before the
/// next tree, so its nodes stay in cache. Blocks are also the unit of parallel work; a row's sum
/// over trees is in tree order whatever the split, so the result never depends on it.
const PREDICT_BLOCK: usize = 4096;

impl Regressor for ExtraTrees {
    fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    #[inline]
    fn predict_row(&self, row: &[f64]) -> f64 {
        assert_eq!(row.len(), self.n_inputs, "row length must equal the number of inputs");
        let mut sum = 0.0;
        for group in self.trees.chunks(WALKS) {
            let steps = group.iter().map(|t| t.depth).max().unwrap_or(0);
            let mut at = [0u32; WALKS];
            for _ in 0..steps {
                for (i, tree) in at.iter_mut().zip(group) {
                    *i = tree.step(*i, row);
                }
            }
            for (&i, tree) in at.iter().zip(group) {
                sum += tree.nodes[i as usize].val;
            }
        }
        sum / self.trees.len() as f64
    }

    fn predict_into(&self, x: Rows<'_>, out: &mut [f64]) {
        assert_eq!(x.n_cols(), self.n_inputs, "rows must have as many columns as inputs");
        assert_eq!(out.len(), x.n_rows(), "one output per row");
        let work = |(b, block): (usize, &mut [f64])| {
            let start = b * PREDICT_BLOCK;
            self.predict_block(x.slice(start, start + block.len()), block);
        };
        // Same tree order per row as predict_row, so both give bit-identical answers.
        if out.len() * self.trees.len() < 200_000 {
            out.chunks_mut(PREDICT_BLOCK).enumerate().for_each(work);
        } else {
            out.par_chunks_mut(PREDICT_BLOCK).enumerate().for_each(work);
        }
    }

    /// Each tree is walked once per state, forking only at the nodes that split on the action (the
    /// last input): a walk carries the set of actions still on it, as a bit mask. Every output is
    /// the sum over trees in tree order divided by the tree count, as in `predict_row`, so the
    /// results are bit-identical to the default's.
    fn predict_actions_into(&self, states: Rows<'_>, actions: &[f64], out: &mut [f64]) {
        let k = actions.len();
        assert_eq!(states.n_cols() + 1, self.n_inputs, "states must have one column fewer than the inputs");
        assert_eq!(out.len(), states.n_rows() * k, "one output per state and action");
        if k == 0 {
            return;
        }
        if states.n_rows() < LANES {
            // The greedy policy's case (one state): the walks in flight are over trees.
            for (i, o) in out.chunks_exact_mut(k).enumerate() {
                self.predict_actions_state(states.row(i), actions, o);
            }
            return;
        }
        let d = states.n_cols();
        let rows_per_block = (ACTION_BLOCK / k).max(LANES);
        self.state_blocks(states, k, rows_per_block, out, |padded, _, block| {
            self.predict_actions_block(padded, d, actions, block)
        });
    }
}

impl ExtraTrees {
    fn predict_block(&self, rows: Rows<'_>, out: &mut [f64]) {
        out.fill(0.0);
        for tree in &self.trees {
            for (g, group) in out.chunks_mut(WALKS).enumerate() {
                let mut at = [0u32; WALKS];
                for _ in 0..tree.depth {
                    for (k, i) in at[..group.len()].iter_mut().enumerate() {
                        *i = tree.step(*i, rows.row(g * WALKS + k));
                    }
                }
                for (o, &i) in group.iter_mut().zip(&at) {
                    *o += tree.nodes[i as usize].val;
                }
            }
        }
        let m = self.trees.len() as f64;
        for o in out.iter_mut() {
            *o /= m;
        }
    }
}

/// Most actions one forked walk carries (a bit each); more are taken in groups of this many.
const MASK_ACTIONS: usize = 64;
/// Outputs (states × actions) per block in [`ExtraTrees::predict_actions_into`]: a tree is walked
/// for every state of the block before the next tree, and blocks are the unit of parallel work.
const ACTION_BLOCK: usize = 32768;
/// Leaf values buffered per call of [`ExtraTrees::predict_actions_state`] (trees × actions).
const STATE_VALUES: usize = 512;

impl ExtraTrees {
    /// [`Regressor::predict_actions_into`] for a block of at least [`LANES`] states, trees
    /// outermost (so each tree's nodes stay in cache), the walks in flight over states. `out`
    /// accumulates the sums in tree order (each output gets one leaf per tree), then is divided.
    fn predict_actions_block(&self, states: &[f64], d: usize, actions: &[f64], out: &mut [f64]) {
        let k = actions.len();
        let n = out.len() / k;
        out.fill(0.0);
        for tree in &self.trees {
            add_walks(tree, n, states, d, actions, |r| (r, 0), out);
        }
        let m = self.trees.len() as f64;
        for o in out.iter_mut() {
            *o /= m;
        }
    }

    /// [`Regressor::predict_actions_into`] for one state, the walks in flight over trees: the leaf
    /// values of a group of trees are buffered, then added in tree order.
    fn predict_actions_state(&self, state: &[f64], actions: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        let padded: Vec<f64> = state.iter().copied().chain([0.0]).collect();
        let mut vals = [0.0; STATE_VALUES];
        for (c, acts) in actions.chunks(MASK_ACTIONS).enumerate() {
            let kc = acts.len();
            let out = &mut out[c * MASK_ACTIONS..c * MASK_ACTIONS + kc];
            for group in self.trees.chunks(STATE_VALUES / kc) {
                forked_walks::<false, true>(
                    group.len(),
                    acts,
                    &padded,
                    state.len(),
                    |t| &group[t].nodes,
                    |_| (0, 0),
                    |t, mut mask, v| {
                        let row = &mut vals[t * kc..];
                        while mask != 0 {
                            row[mask.trailing_zeros() as usize] = v;
                            mask &= mask - 1;
                        }
                    },
                );
                for row in vals[..group.len() * kc].chunks_exact(kc) {
                    for (o, &v) in out.iter_mut().zip(row) {
                        *o += v;
                    }
                }
            }
        }
        let m = self.trees.len() as f64;
        for o in out.iter_mut() {
            *o /= m;
        }
    }
}

impl ExtraTrees {
    /// Calls `work(states, first, out)` for blocks of `rows_per_block` states and their outputs
    /// (`k` per state), in parallel when there is enough work: `states` holds the block's states
    /// from state `first` on, and one value more, which [`forked_walks`] may read (the states are
    /// copied once, with a value after the last).
    fn state_blocks(
        &self,
        states: Rows<'_>,
        k: usize,
        rows_per_block: usize,
        out: &mut [f64],
        work: impl Fn(&[f64], usize, &mut [f64]) + Sync,
    ) {
        let d = states.n_cols();
        let mut padded = Vec::with_capacity(states.data().len() + 1);
        padded.extend_from_slice(states.data());
        padded.push(0.0);
        let work = |(b, block): (usize, &mut [f64])| {
            let (start, end) = (b * rows_per_block, b * rows_per_block + block.len() / k);
            work(&padded[start * d..end * d + 1], start, block);
        };
        if out.len() * self.trees.len() < 200_000 {
            out.chunks_mut(rows_per_block * k).enumerate().for_each(work);
        } else {
            out.par_chunks_mut(rows_per_block * k).enumerate().for_each(work);
        }
    }

    /// The training rows' predictions from their recorded leaves; bit-identical to `predict_into`.
    fn predict_training(&self, routes: &[Routes], out: &mut [f64]) {
        let m = self.trees.len() as f64;
        out.par_chunks_mut(PREDICT_BLOCK).enumerate().for_each(|(b, block)| {
            let start = b * PREDICT_BLOCK;
            block.fill(0.0);
            for route in routes {
                for (o, &leaf) in block.iter_mut().zip(&route.leaf_of[start..]) {
                    *o += route.value[leaf as usize];
                }
            }
            for o in block.iter_mut() {
                *o /= m;
            }
        });
    }

    /// [`NextStates::predict`], each state with a training twin taking the twin's leaf, or starting
    /// its walks at the leaf's fork (see [`Routes`]), in each tree; the others are predicted as
    /// usual. Each state's outputs are its own sums over the trees, so splitting the states in two
    /// changes nothing.
    fn predict_next_routed(&self, next: &NextStates<'_>, routes: &[Routes], out: &mut [f64]) {
        let (states, d) = (next.states, next.states.n_cols());
        let k = next.actions.map_or(1, <[f64]>::len);
        if k == 0 {
            return;
        }
        let alone: Vec<usize> = (0..states.n_rows()).filter(|&i| next.same[i] == NO_ROW).collect();
        if !alone.is_empty() {
            let xs: Vec<f64> = alone.iter().flat_map(|&i| states.row(i)).copied().collect();
            let mut q = vec![0.0; alone.len() * k];
            let rows = Rows { data: &xs, cols: d };
            NextStates { states: rows, actions: next.actions, same: &[] }.predict(self, &mut q);
            for (&i, q) in alone.iter().zip(q.chunks_exact(k)) {
                out[i * k..(i + 1) * k].copy_from_slice(q);
            }
        }
        let m = self.trees.len() as f64;
        let Some(acts) = next.actions else {
            // The state alone as input: no forks, every twin's leaf is the state's.
            out.par_chunks_mut(PREDICT_BLOCK).zip(next.same.par_chunks(PREDICT_BLOCK)).for_each(|(block, same)| {
                let mut sums = vec![0.0; block.len()];
                for route in routes {
                    for (s, &r) in sums.iter_mut().zip(same).filter(|(_, r)| **r != NO_ROW) {
                        *s += route.value[route.leaf_of[r as usize] as usize];
                    }
                }
                for ((o, s), &r) in block.iter_mut().zip(sums).zip(same) {
                    if r != NO_ROW {
                        *o = s / m;
                    }
                }
            });
            return;
        };
        // Most states only read their twins' leaves, so blocks are kept small enough to share
        // out (a tree's leaves stay in cache anyway).
        let rows_per_block = (ACTION_BLOCK / k).clamp(LANES, PREDICT_BLOCK);
        self.state_blocks(states, k, rows_per_block, out, |states, first, block| {
            let same = &next.same[first..first + block.len() / k];
            self.predict_twins_block(states, d, acts, same, routes, block);
        });
    }

    /// [`ExtraTrees::predict_actions_block`] for the states with training twins (`same`, the
    /// others are left alone): a walk starts at the fork of the twin's leaf, and there is none to
    /// take when the leaf has no fork.
    fn predict_twins_block(
        &self,
        states: &[f64],
        d: usize,
        acts: &[f64],
        same: &[u32],
        routes: &[Routes],
        out: &mut [f64],
    ) {
        let k = acts.len();
        // Until a state's first walk, every tree gives all its actions one leaf, so their sums are
        // equal and one is kept (`shared`); the walk spreads it to the actions' cells (`spread`),
        // which then add their own leaves. Each cell's sum is thus the same sequence of additions
        // as in `predict_actions_block`.
        let mut shared = vec![0.0; same.len()];
        let mut spread = vec![false; same.len()];
        // (state, fork) of the walks to take in the tree at hand.
        let mut walks: Vec<(u32, u32)> = Vec::with_capacity(same.len());
        for (tree, route) in self.trees.iter().zip(routes) {
            walks.clear();
            for (i, &r) in same.iter().enumerate().filter(|(_, r)| **r != NO_ROW) {
                let leaf = route.leaf_of[r as usize] as usize;
                let fork = route.fork[leaf];
                if fork == NO_FORK && !spread[i] {
                    shared[i] += route.value[leaf];
                } else if fork == NO_FORK {
                    for o in &mut out[i * k..(i + 1) * k] {
                        *o += route.value[leaf];
                    }
                } else {
                    if !spread[i] {
                        out[i * k..(i + 1) * k].fill(shared[i]);
                        spread[i] = true;
                    }
                    walks.push((i as u32, fork));
                }
            }
            add_walks(tree, walks.len(), states, d, acts, |w| (walks[w].0 as usize, walks[w].1), out);
        }
        let m = self.trees.len() as f64;
        let twins = out.chunks_exact_mut(k).zip(&shared).zip(&spread).zip(same);
        for (((cells, &sum), &spread), _) in twins.filter(|(_, r)| **r != NO_ROW) {
            if !spread {
                cells.fill(sum);
            }
            for o in cells {
                *o /= m;
            }
        }
    }
}

/// Adds tree `tree`'s leaves to `out` (`actions.len()` cells per state, in action order) for
/// walks `0..n`: walk `w` is state `s` of `states` (`d` values each, and one more after the last)
/// from node `start`, with `(s, start) = origin(w)`, for every action.
fn add_walks(
    tree: &Tree,
    n: usize,
    states: &[f64],
    d: usize,
    actions: &[f64],
    origin: impl Fn(usize) -> (usize, u32),
    out: &mut [f64],
) {
    let k = actions.len();
    for (c, acts) in actions.chunks(MASK_ACTIONS).enumerate() {
        let base = c * MASK_ACTIONS;
        forked_walks::<true, false>(
            n,
            acts,
            states,
            d,
            |_| &tree.nodes,
            |w| {
                let (s, start) = origin(w);
                (s * d, start)
            },
            |w, mut mask, v| {
                let acc = &mut out[origin(w).0 * k + base..];
                while mask != 0 {
                    acc[mask.trailing_zeros() as usize] += v;
                    mask &= mask - 1;
                }
            },
        );
    }
}

/// Walks in flight at once in [`forked_walks`], stepped in turn so that their cache misses overlap.
const LANES: usize = 8;
/// Steps the walks of [`forked_walks`] take between two looks at where they stopped.
const ROUNDS: usize = 4;

/// A fork of [`forked_walks`] waiting to be walked: `node` of the tree of `slot`, with the actions
/// in `mask`.
#[derive(Debug, Clone, Copy, Default)]
struct Fork {
    node: u32,
    slot: u32,
    mask: u64,
}

/// For each slot `s < n_slots`, with `(offset, start) = origin(s)`, walks the tree `tree(s)` from
/// node `start` (the root, or a node every action reaches) with the inputs `[x, a]`, where `x` is
/// the state `data[offset..offset + d]`, for every action `a` of `acts` (1 to 64 of them) at once, and calls `leaf(s, mask, value)` for each leaf reached, `mask` holding the actions (bit j
/// for `acts[j]`) that reach it: every (slot, action) gets exactly one call. A walk forks only at
/// the nodes that split on the action (feature `d`), and compares as [`Tree::step`] does. `data`
/// must hold a value after the last slot's state: a walk at an action split reads `x[d]` (unused)
/// rather than pay for clamping the index in every step.
///
/// [`LANES`] walks advance together, branch-free, [`ROUNDS`] steps at a time, each stopping at a
/// leaf or an action split; between rounds, a walk at an action split goes on with the actions
/// that go left (or right if none do) and a fork with the others is stacked, and a walk at a leaf
/// is reported and its lane given the next walk at once, from the stack first (waiting for every
/// lane to reach a leaf left most steps idle: leaves lie at very different depths). So a slot
/// starts only when the stack is empty, at most [`LANES`] slots have walks left, and the walks of a
/// slot carry disjoint non-empty sets of actions: the stack never holds more than
/// `LANES × acts.len()`. A slot that starts at an action split (a fork) takes it as its lane is
/// given it, with the same rule, rather than a round later. Each (slot, action) gets one leaf,
/// which the callers put in a cell of its own, so the order the leaves are reported in does not
/// reach the results.
#[inline(always)]
fn forked_walks<'a, const SAME_TREE: bool, const SAME_STATE: bool>(
    n_slots: usize,
    acts: &[f64],
    data: &[f64],
    d: usize,
    tree: impl Fn(usize) -> &'a [Node],
    origin: impl Fn(usize) -> (usize, u32),
    mut leaf: impl FnMut(usize, u64, f64),
) {
    if n_slots == 0 {
        return;
    }
    // The unchecked reads below rely on this (offsets grow with the slot) and on the tree
    // invariant that every child index of a node is in its tree.
    assert!(d >= 1 && origin(n_slots - 1).0 + d < data.len(), "every slot's state, and one value more, is in `data`");
    let full = u64::MAX >> (64 - acts.len());
    let mut small = [Fork::default(); LANES * 16];
    let mut big = Vec::new();
    let stack: &mut [Fork] = if acts.len() <= 16 {
        &mut small
    } else {
        big.resize(LANES * acts.len(), Fork::default());
        &mut big
    };
    let mut top = 0;
    let feat_d = d as u32;
    // Lane l: at node `at[l]` of `nodes[l]`, state at `off[l]`, actions `masks[l]`, for `slots[l]`;
    // `live` has a bit per lane with a walk (an idle lane stays where it is, unreported).
    let mut at = [0u32; LANES];
    let mut off = [0usize; LANES];
    let mut masks = [0u64; LANES];
    let mut slots = [0u32; LANES];
    let mut nodes: [&[Node]; LANES] = [tree(0); LANES];
    let mut next = 0;
    let mut live = 0u32;
    // Lane l at `node`, a split on the action: goes on with the actions that go left (or right if
    // none do) and stacks a fork with the others.
    macro_rules! fork {
        ($l:expr, $node:expr) => {{
            let (l, node): (usize, Node) = ($l, $node);
            let mut le = 0u64;
            for (j, &a) in acts.iter().enumerate() {
                le |= ((a <= node.val) as u64) << j;
            }
            let (left, right) = (masks[l] & le, masks[l] & !le);
            if left == 0 {
                at[l] = node.left + 1;
            } else {
                if right != 0 {
                    stack[top] = Fork { node: node.left + 1, slot: slots[l], mask: right };
                    top += 1;
                }
                (at[l], masks[l]) = (node.left, left);
            }
        }};
    }
    // Gives lane l the next walk, from the stack first; false when there is none.
    macro_rules! take {
        ($l:expr) => {{
            let l = $l;
            if top > 0 {
                top -= 1;
                let f = stack[top];
                let s = f.slot as usize;
                (nodes[l], off[l], at[l], masks[l], slots[l]) = (tree(s), origin(s).0, f.node, f.mask, f.slot);
                true
            } else if next < n_slots {
                (nodes[l], off[l], at[l], masks[l], slots[l]) = {
                    let (offset, start) = origin(next);
                    // The unchecked reads below rely on every walk starting inside its tree.
                    assert!((start as usize) < tree(next).len(), "a walk starts at a node of its tree");
                    (tree(next), offset, start, full, next as u32)
                };
                next += 1;
                // A walk from a fork starts at a split on the action: taking it now spares the
                // lane a round of standing still there.
                let node = nodes[l][at[l] as usize];
                if node.feat == feat_d {
                    fork!(l, node);
                }
                true
            } else {
                false
            }
        }};
    }
    for l in 0..LANES {
        if take!(l) {
            live |= 1 << l;
        }
    }
    while live != 0 {
        let mut stopped = 0u32;
        for round in 0..ROUNDS {
            for l in 0..LANES {
                let tree = if SAME_TREE { nodes[0] } else { nodes[l] };
                debug_assert!((at[l] as usize) < tree.len());
                // SAFETY: walks start at a node of their tree (asserted in `take`) or at a child
                // of a node, and step only to children, which every tree holds; the state index is within `data` (asserted
                // above). Bounds checks here would double the instructions of the hottest loop.
                let node = unsafe { *tree.get_unchecked(at[l] as usize) };
                let go = node.feat < feat_d;
                // A leaf reads the state's first value and an action split the value after the
                // state: both are in `data` (asserted), and neither moves the walk.
                let i = if SAME_STATE { 0 } else { off[l] } + (node.feat & !LEAF) as usize;
                let x = unsafe { *data.get_unchecked(i) };
                let step = node.left + ((x <= node.val) as u32 ^ 1);
                at[l] = if go { step } else { at[l] };
                // A walk that stops (leaf or action split) stays stopped, so the last step tells.
                if round == ROUNDS - 1 {
                    stopped |= (!go as u32) << l;
                }
            }
        }
        stopped &= live;
        while stopped != 0 {
            let l = stopped.trailing_zeros() as usize;
            stopped &= stopped - 1;
            let node = nodes[l][at[l] as usize];
            if node.feat == feat_d {
                fork!(l, node);
            } else {
                leaf(slots[l] as usize, masks[l], node.val);
                if !take!(l) {
                    live &= !(1 << l);
                }
            }
        }
    }
}

/// Marks a leaf in [`Node::feat`].
const LEAF: u32 = 1 << 31;

/// A tree node (16 bytes). Internal: a row goes to `left` iff `x[feat] <= val`, else to `left + 1`
/// (siblings are adjacent). Leaf: `feat == LEAF`, `left` is the leaf itself and `val` the
/// prediction, so that walking on from a leaf stays there (see [`Tree::step`]).
#[derive(Debug, Clone, Copy)]
#[repr(C)]
struct Node {
    val: f64,
    feat: u32,
    left: u32,
}

/// One tree, as a flat array with the root at 0.
#[derive(Debug, Clone)]
struct Tree {
    nodes: Vec<Node>,
    /// Training rows that reached each node.
    counts: Vec<u32>,
    depth: usize,
}

impl Node {
    fn leaf(slot: usize, value: f64) -> Node {
        Node { val: value, feat: LEAF, left: slot as u32 }
    }

    fn is_leaf(&self) -> bool {
        self.feat & LEAF != 0
    }
}

impl Tree {
    /// One step down from node `i` (a leaf stays put). Branch-free, so several walks (trees or
    /// rows) interleave and their cache misses overlap, which a loop ending at the leaf prevents.
    #[inline(always)]
    fn step(&self, i: u32, row: &[f64]) -> u32 {
        let node = &self.nodes[i as usize];
        let x = row[(node.feat & !LEAF) as usize];
        let internal = (node.feat >> 31) ^ 1;
        // Right unless x <= threshold (so NaN goes right, as `NaN as f32 <= t` is false).
        let right = (x <= node.val) as u32 ^ 1;
        node.left + (right & internal)
    }
}

/// sklearn's `FEATURE_THRESHOLD`: a feature whose range in the node is at most this is constant.
const FEATURE_THRESHOLD: f64 = 1e-7;

/// The training set as the trees read it: inputs in `f32`, column-major (`x[f * n + i]`).
struct Data {
    n: usize,
    d: usize,
    x: Vec<f32>,
    y: Vec<f64>,
    /// `0..n` when the trees record each row's leaf (the row indices are partitioned with the
    /// columns), else empty.
    idx: Vec<u32>,
    /// A leaf's fork is its first ancestor that splits on this column (`usize::MAX`: none).
    fork_col: usize,
    /// Each column's (min, max): the root's ranges, the same for every tree, so taken once.
    ranges: Vec<(f32, f32)>,
}

impl Data {
    fn new(rows: Rows<'_>, y: &[f64], record: Record) -> Result<Self> {
        let (n, d) = (rows.n_rows(), rows.n_cols());
        // Node indices are u32 and a tree has at most 2n − 1 nodes; feature indices leave the
        // top bit to LEAF.
        if n > (u32::MAX / 2) as usize || d >= LEAF as usize {
            return Err(Error::Data(format!("{n} rows × {d} columns: Extra-Trees accepts < 2^31 of each")));
        }
        let mut x = vec![0.0f32; n * d];
        for (i, row) in rows.data().chunks_exact(d).enumerate() {
            for (f, &v) in row.iter().enumerate() {
                if v.abs() > f32::MAX as f64 {
                    return Err(Error::Data(format!(
                        "input {v} at row {i}, column {f} is too large for Extra-Trees (|x| ≤ {:e})",
                        f32::MAX
                    )));
                }
                x[f * n + i] = v as f32;
            }
        }
        let idx = if matches!(record, Record::Nothing) { Vec::new() } else { (0..n as u32).collect() };
        let fork_col = if let Record::Routes(c) = record { c } else { usize::MAX };
        // Exact extrema, so the portable kernel gives what the vector one would (up to the sign
        // of zero, which `canonical` settles).
        let ranges = x.chunks_exact(n).map(|col| canonical(portable::min_max(col))).collect();
        Ok(Data { n, d, x, y: y.to_vec(), idx, fork_col, ranges })
    }
}

/// A tree builder's scratch memory, reused across the trees one worker builds.
struct Workspace {
    /// Two copies of the columns: a node at odd depth reads `bx` and writes its children into `ax`,
    /// a node at even depth reads `ax` (the root reads [`Data`]) and writes into `bx`.
    ax: Vec<f32>,
    bx: Vec<f32>,
    ay: Vec<f64>,
    by: Vec<f64>,
    /// Row indices, partitioned like the columns (only when [`Data::idx`] is set).
    ai: Vec<u32>,
    bi: Vec<u32>,
    /// Where the portable partition sends each row of the node, relative to its start.
    pos: Vec<u32>,
    /// Which rows go left, 16 per mask (AVX-512 partition).
    masks: Vec<u16>,
    order: Vec<usize>,
    /// The node's candidate splits and their left-side sums.
    cands: Vec<Candidate>,
    sums: Vec<LeftSums>,
    stack: Vec<Pending>,
    /// Each pending node's per-feature (min, max), `d` entries per node in stack order: a split
    /// computes its children's while it partitions them, so no node reads its columns for them.
    ranges: Vec<(f32, f32)>,
    /// The children's ranges of the node being split.
    left_ranges: Vec<(f32, f32)>,
    right_ranges: Vec<(f32, f32)>,
}

thread_local! {
    /// The workspace of this thread's tree builds, kept from one fit to the next: FQI fits a forest
    /// on the same rows every iteration, and allocating a workspace (tens of MB, zeroed) for every
    /// rayon split of every fit cost a pendulum run ~3 % of its time in `memset`. It holds nothing
    /// a tree reads before writing, so reusing it changes no tree.
    static WORKSPACE: std::cell::RefCell<Option<Workspace>> = const { std::cell::RefCell::new(None) };
}

/// Calls `f` with this thread's workspace, (re)made when it is too small for `d` columns × `n` rows.
fn with_workspace<T>(d: usize, n: usize, f: impl FnOnce(&mut Workspace) -> T) -> T {
    WORKSPACE.with_borrow_mut(|slot| {
        if !slot.as_ref().is_some_and(|ws| ws.holds(d, n)) {
            // Drop the old one first, so the two are never held at once.
            *slot = None;
            *slot = Some(Workspace::new(d, n));
        }
        f(slot.as_mut().expect("just made"))
    })
}

impl Workspace {
    /// Whether it serves trees on `d` columns × `n` rows: the builder indexes columns by the data's
    /// own row count and slices the per-row buffers to the node, so more rows are fine; the
    /// per-feature buffers (children's ranges) are used whole, so the columns must match.
    fn holds(&self, d: usize, n: usize) -> bool {
        self.left_ranges.len() == d && self.ay.len() >= n && self.ax.len() >= d * n
    }

    fn new(d: usize, n: usize) -> Self {
        Workspace {
            ax: vec![0.0; d * n],
            bx: vec![0.0; d * n],
            ay: vec![0.0; n],
            by: vec![0.0; n],
            // Zeroed lazily by the allocator: untouched pages cost nothing when rows are not tracked.
            ai: vec![0; n],
            bi: vec![0; n],
            pos: vec![0; n],
            masks: vec![0; n.div_ceil(16)],
            order: (0..d).collect(),
            cands: Vec::with_capacity(d),
            sums: vec![LeftSums::default(); d],
            stack: Vec::new(),
            ranges: Vec::new(),
            left_ranges: vec![(0.0, 0.0); d],
            right_ranges: vec![(0.0, 0.0); d],
        }
    }
}

/// A node waiting to be grown: rows `start..end` of the buffer its depth reads.
#[derive(Clone, Copy)]
struct Pending {
    slot: usize,
    start: usize,
    end: usize,
    depth: usize,
    /// The first ancestor that splits on [`Data::fork_col`], or [`NO_FORK`].
    fork: u32,
}

/// A candidate split: feature and threshold (rows with `x <= thr` go left).
#[derive(Clone, Copy)]
struct Candidate {
    feat: usize,
    thr: f32,
}

/// Rows with `x <= t` so far, their target sums in 32 lanes (lane k: rows ≡ k mod 32), and the
/// total of the lanes once every row is in.
#[derive(Clone, Copy)]
struct LeftSums {
    lanes: [f64; 32],
    count: usize,
    sum: f64,
}

impl Default for LeftSums {
    fn default() -> Self {
        LeftSums { lanes: [0.0; 32], count: 0, sum: 0.0 }
    }
}

/// A node's chosen split.
#[derive(Clone, Copy)]
struct Split {
    feat: usize,
    thr: f32,
    n_left: usize,
}

/// Builds one tree, with AVX-512 kernels when the CPU has them (and `BFQI_ISA` does not cap them,
/// see [`cpu`]). Both paths build the same tree: the kernels add in the same order (explicit
/// lanes), and partitions and extrema are exact.
///
/// When `data.idx` is set, `routes` gets each training row's leaf and each leaf's value and fork.
fn build_tree(p: &ExtraTreesParams, data: &Data, ws: &mut Workspace, rng: Rng, routes: &mut Routes) -> Tree {
    #[cfg(target_arch = "x86_64")]
    match cpu::extra_trees() {
        // SAFETY: the guard checked every feature `build_tree_avx512` is compiled with.
        isa @ cpu::Isa::Avx512 if isa.runs_extra_trees() => {
            return unsafe { build_tree_avx512(p, data, ws, rng, routes) };
        }
        // SAFETY: as above.
        isa @ cpu::Isa::Avx2 if isa.runs_extra_trees() => return unsafe { build_tree_avx2(p, data, ws, rng, routes) },
        _ => {}
    }
    build_tree_impl::<false>(p, data, ws, rng, routes)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,popcnt")]
fn build_tree_avx512(p: &ExtraTreesParams, data: &Data, ws: &mut Workspace, rng: Rng, routes: &mut Routes) -> Tree {
    build_tree_impl::<true>(p, data, ws, rng, routes)
}

/// The portable kernels, compiled for AVX2 (the compiler vectorises the extrema).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn build_tree_avx2(p: &ExtraTreesParams, data: &Data, ws: &mut Workspace, rng: Rng, routes: &mut Routes) -> Tree {
    build_tree_impl::<false>(p, data, ws, rng, routes)
}

/// The builder (sklearn's depth-first builder with its random splitter). `WIDE` selects the AVX-512
/// kernels; it is only true inside [`build_tree_avx512`].
#[inline(always)]
fn build_tree_impl<const WIDE: bool>(
    p: &ExtraTreesParams,
    data: &Data,
    ws: &mut Workspace,
    mut rng: Rng,
    routes: &mut Routes,
) -> Tree {
    let (n_all, d) = (data.n, data.d);
    let track = !data.idx.is_empty();
    let max_depth = p.max_depth.unwrap_or(usize::MAX);
    let (min_split, min_leaf) = (p.min_samples_split, p.min_samples_leaf);
    let mut nodes = vec![Node::leaf(0, 0.0)];
    let mut counts = vec![0u32];
    let mut tree_depth = 0;
    ws.order.clear();
    ws.order.extend(0..d);
    ws.stack.clear();
    ws.stack.push(Pending { slot: 0, start: 0, end: n_all, depth: 0, fork: NO_FORK });
    ws.ranges.clear();
    ws.ranges.extend_from_slice(&data.ranges);

    while let Some(Pending { slot, start, end, depth, fork }) = ws.stack.pop() {
        let n = end - start;
        // This node's ranges are the top `d` entries, read by the draws and then dropped.
        let r0 = ws.ranges.len() - d;
        counts[slot] = n as u32;
        let (src_x, src_y, src_i, dst_x, dst_y, dst_i) = if depth == 0 {
            (&data.x[..], &data.y[..], &data.idx[..], &mut ws.bx[..], &mut ws.by[..], &mut ws.bi[..])
        } else if depth % 2 == 1 {
            (&ws.bx[..], &ws.by[..], &ws.bi[..], &mut ws.ax[..], &mut ws.ay[..], &mut ws.ai[..])
        } else {
            (&ws.ax[..], &ws.ay[..], &ws.ai[..], &mut ws.bx[..], &mut ws.by[..], &mut ws.bi[..])
        };
        let ys = &src_y[start..end];
        let (mean, var) = mean_var::<WIDE>(ys);

        let mut best: Option<Split> = None;
        // sklearn's leaf rules; `var <= EPSILON` is its "impurity ≈ 0".
        if n >= min_split && n >= 2 * min_leaf && depth < max_depth && var > f64::EPSILON {
            for i in (1..d).rev() {
                let j = rng::below(&mut rng, i as u64 + 1) as usize;
                ws.order.swap(i, j);
            }
            // Draw every threshold first (the draws depend only on each feature's range), then
            // count all candidates in one sweep, so the node's targets are read once, not d times.
            ws.cands.clear();
            for &f in &ws.order {
                let (lo, hi) = ws.ranges[r0 + f];
                let (lo, hi) = (lo as f64, hi as f64);
                if hi <= lo + FEATURE_THRESHOLD {
                    continue;
                }
                let mut thr = rng::uniform(&mut rng, lo, hi);
                if thr >= hi {
                    thr = lo; // rounding reached the top: sklearn falls back to the minimum
                }
                // The rows are f32, so `x <= thr` ⟺ `x <= t` with t the largest f32 ≤ thr.
                ws.cands.push(Candidate { feat: f, thr: round_down_f32(thr) });
            }
            let sums = &mut ws.sums[..ws.cands.len()];
            count_sum_left::<WIDE>(src_x, n_all, start, ys, &ws.cands, sums);
            // The first candidate with the largest proxy among those leaving `min_leaf` rows on
            // each side, chosen with selects: which candidate wins is a coin toss, and
            // mispredicted branches cost a small node more than the arithmetic.
            let (mut best_i, mut best_proxy) = (usize::MAX, f64::NEG_INFINITY);
            for (i, s) in sums.iter().enumerate() {
                let (n_left, sum_left) = (s.count, s.sum);
                let n_right = n - n_left;
                // Variance reduction × n = n_l n_r / n · (mean_l − mean_r)², written with the
                // left sum's deviation from its share of the total so a large target offset
                // cancels before squaring. With both sides non-empty it is never NaN, so the
                // first valid candidate beats −∞; an invalid one's value is never looked at.
                let dev = sum_left - n_left as f64 * mean;
                let proxy = dev * dev * (1.0 / n_left as f64 + 1.0 / n_right as f64);
                let take = (n_left >= min_leaf) & (n_right >= min_leaf) & (proxy > best_proxy);
                best_i = if take { i } else { best_i };
                best_proxy = if take { proxy } else { best_proxy };
            }
            if let Some(c) = ws.cands.get(best_i) {
                best = Some(Split { feat: c.feat, thr: c.thr, n_left: sums[best_i].count });
            }
        }

        ws.ranges.truncate(r0);
        let Some(split) = best else {
            nodes[slot] = Node::leaf(slot, mean);
            if track {
                record_leaf(mean, fork, &src_i[start..end], routes);
            }
            tree_depth = tree_depth.max(depth);
            continue;
        };

        // A child that the size or depth rules make a leaf is finished here rather than pushed; if
        // both children are, their input columns are not needed and are not moved.
        let (n_left, n_right) = (split.n_left, n - split.n_left);
        let forced_leaf = |m: usize| m < min_split || m < 2 * min_leaf || depth + 1 >= max_depth;
        let (leaf_left, leaf_right) = (forced_leaf(n_left), forced_leaf(n_right));
        let fork = if fork == NO_FORK && split.feat == data.fork_col { slot as u32 } else { fork };
        let move_x = !(leaf_left && leaf_right);

        // Stable partition of every column (and y) into the other buffer.
        let key = &src_x[split.feat * n_all + start..split.feat * n_all + end];
        let columns = (0..if move_x { d } else { 0 }).map(|f| f * n_all + start..f * n_all + end);
        #[cfg(target_arch = "x86_64")]
        if WIDE {
            let masks = &mut ws.masks[..n.div_ceil(16)];
            // SAFETY: WIDE is only set in build_tree_avx512, called after detecting the features.
            unsafe {
                avx512::left_masks(key, split.thr, masks);
                for (f, range) in columns.clone().enumerate() {
                    let (l, r) =
                        avx512::partition_min_max(&src_x[range.clone()], &mut dst_x[range], masks, split.n_left);
                    (ws.left_ranges[f], ws.right_ranges[f]) = (canonical(l), canonical(r));
                }
                avx512::partition(ys, &mut dst_y[start..end], masks, split.n_left);
                if track {
                    avx512::partition(&src_i[start..end], &mut dst_i[start..end], masks, split.n_left);
                }
            }
        }
        if !WIDE || cfg!(not(target_arch = "x86_64")) {
            let pos = &mut ws.pos[..n];
            portable::positions(key, split.thr, split.n_left, pos);
            for (f, range) in columns.enumerate() {
                portable::scatter(&src_x[range.clone()], &mut dst_x[range.clone()], pos);
                let (l, r) = dst_x[range].split_at(split.n_left);
                (ws.left_ranges[f], ws.right_ranges[f]) =
                    (canonical(portable::min_max(l)), canonical(portable::min_max(r)));
            }
            portable::scatter(ys, &mut dst_y[start..end], pos);
            if track {
                portable::scatter(&src_i[start..end], &mut dst_i[start..end], pos);
            }
        }

        let left = nodes.len();
        nodes[slot] = Node { val: query_threshold(split.thr), feat: split.feat as u32, left: left as u32 };
        nodes.extend([Node::leaf(left, 0.0), Node::leaf(left + 1, 0.0)]);
        counts.extend([n_left as u32, n_right as u32]);
        let mid = start + n_left;
        // Right pushed first so the left subtree is grown first (depth-first, as sklearn). Leaves
        // draw nothing from `rng`, so finishing them out of turn changes no later draw.
        for (child, leaf, rows, ranges) in
            [(left + 1, leaf_right, mid..end, &ws.right_ranges), (left, leaf_left, start..mid, &ws.left_ranges)]
        {
            if leaf {
                let mean = mean_var::<WIDE>(&dst_y[rows.clone()]).0;
                nodes[child] = Node::leaf(child, mean);
                if track {
                    record_leaf(mean, fork, &dst_i[rows], routes);
                }
                tree_depth = tree_depth.max(depth + 1);
            } else {
                ws.stack.push(Pending { slot: child, start: rows.start, end: rows.end, depth: depth + 1, fork });
                ws.ranges.extend_from_slice(ranges);
            }
        }
    }
    Tree { nodes, counts, depth: tree_depth }
}

/// Records a new leaf of value `value` below `fork` (see [`Routes`]) as the leaf of `rows`.
#[inline(always)]
fn record_leaf(value: f64, fork: u32, rows: &[u32], routes: &mut Routes) {
    let l = routes.value.len() as u32;
    routes.value.push(value);
    routes.fork.push(fork);
    for &i in rows {
        routes.leaf_of[i as usize] = l;
    }
}

/// A range with +0.0 for −0.0, so that it does not depend on the order the extrema were taken in
/// (min/max of ±0 return either).
#[inline(always)]
fn canonical((lo, hi): (f32, f32)) -> (f32, f32) {
    (lo + 0.0, hi + 0.0)
}

#[inline(always)]
fn mean_var<const WIDE: bool>(ys: &[f64]) -> (f64, f64) {
    #[cfg(target_arch = "x86_64")]
    if WIDE {
        // SAFETY: see build_tree_impl.
        return unsafe { avx512::mean_var(ys) };
    }
    portable::mean_var(ys)
}

/// Rows per sweep step in [`count_sum_left`] (a multiple of 32): the step's targets (16 KiB) stay
/// in L1 while every candidate's column passes over them.
const SWEEP: usize = 2048;

/// For each candidate, the rows of the node (`ys.len()` rows from `start`) with `x <= thr` and the
/// sum of their targets, left in `sums[i].count` and `sums[i].sum`.
#[inline(always)]
fn count_sum_left<const WIDE: bool>(
    src_x: &[f32],
    n_all: usize,
    start: usize,
    ys: &[f64],
    cands: &[Candidate],
    sums: &mut [LeftSums],
) {
    let n = ys.len();
    #[cfg(target_arch = "x86_64")]
    if WIDE && n <= SWEEP {
        // One sweep step: each candidate's lanes live in registers and are reduced there, in the
        // same order as below (most nodes are small, and for them the trip through memory and the
        // scalar reduction cost more than the counting).
        for (c, s) in cands.iter().zip(sums.iter_mut()) {
            let xs = &src_x[c.feat * n_all + start..c.feat * n_all + start + n];
            // SAFETY: see build_tree_impl.
            (s.count, s.sum) = unsafe { avx512::count_sum_node(xs, ys, c.thr) };
        }
        return;
    }
    sums.fill(LeftSums::default());
    let mut a = 0;
    while a < n {
        let b = (a + SWEEP).min(n);
        for (c, s) in cands.iter().zip(sums.iter_mut()) {
            let xs = &src_x[c.feat * n_all + start + a..c.feat * n_all + start + b];
            #[cfg(target_arch = "x86_64")]
            if WIDE {
                // SAFETY: see build_tree_impl.
                unsafe { avx512::count_sum_blocks(xs, &ys[a..b], c.thr, s) };
                continue;
            }
            portable::count_sum_blocks(xs, &ys[a..b], c.thr, s);
        }
        a = b;
    }
    for s in sums.iter_mut() {
        let l = &s.lanes;
        s.sum = hsum8(std::array::from_fn(|j| (l[j] + l[j + 8]) + (l[j + 16] + l[j + 24])));
    }
}

/// Sum of 8 lanes in the order of an AVX-512 halving reduction (the same order in every path).
#[inline(always)]
fn hsum8(v: [f64; 8]) -> f64 {
    ((v[0] + v[4]) + (v[2] + v[6])) + ((v[1] + v[5]) + (v[3] + v[7]))
}

/// From the 16 lanes of Σ(y − y0) and Σ(y − y0)² over n rows: the mean and the population variance.
#[inline(always)]
fn finish_mean_var(y0: f64, s: [f64; 16], q: [f64; 16], n: usize) -> (f64, f64) {
    let s = hsum8(std::array::from_fn(|j| s[j] + s[j + 8]));
    let q = hsum8(std::array::from_fn(|j| q[j] + q[j + 8]));
    mean_var_of_sums(y0, s, q, n)
}

/// The mean and population variance from the reduced Σ(y − y0) and Σ(y − y0)² over n rows.
#[inline(always)]
fn mean_var_of_sums(y0: f64, s: f64, q: f64, n: usize) -> (f64, f64) {
    let m = s / n as f64;
    (y0 + m, (q / n as f64 - m * m).max(0.0))
}

/// Scalar kernels, and the reference for the summation order of the AVX-512 ones: a sum over rows
/// is kept in lanes, lane k taking the rows ≡ k modulo the lane count (16 or 32), so a vector
/// kernel adds in the same order (its padding lanes add +0.0, which changes nothing).
mod portable {
    use super::{LeftSums, finish_mean_var};

    /// Mean and population variance of `ys` (non-empty), from sums shifted by `ys[0]` so that a
    /// constant target gives exactly 0 and a large offset loses no precision.
    #[inline(always)]
    pub fn mean_var(ys: &[f64]) -> (f64, f64) {
        let y0 = ys[0];
        let (mut s, mut q) = ([0.0f64; 16], [0.0f64; 16]);
        let blocks = ys.chunks_exact(16);
        let rest = blocks.remainder();
        for c in blocks {
            for k in 0..16 {
                let v = c[k] - y0;
                s[k] += v;
                q[k] += v * v;
            }
        }
        for (k, &y) in rest.iter().enumerate() {
            let v = y - y0;
            s[k] += v;
            q[k] += v * v;
        }
        finish_mean_var(y0, s, q, ys.len())
    }

    /// Minimum and maximum of `xs` (non-empty, no NaN); exact, so any order will do.
    #[inline(always)]
    pub fn min_max(xs: &[f32]) -> (f32, f32) {
        let (mut lo, mut hi) = ([f32::INFINITY; 16], [f32::NEG_INFINITY; 16]);
        let blocks = xs.chunks_exact(16);
        let rest = blocks.remainder();
        for c in blocks {
            for k in 0..16 {
                lo[k] = if c[k] < lo[k] { c[k] } else { lo[k] };
                hi[k] = if c[k] > hi[k] { c[k] } else { hi[k] };
            }
        }
        for (k, &v) in rest.iter().enumerate() {
            lo[k] = if v < lo[k] { v } else { lo[k] };
            hi[k] = if v > hi[k] { v } else { hi[k] };
        }
        let (mut a, mut b) = (lo[0], hi[0]);
        for k in 1..16 {
            a = if lo[k] < a { lo[k] } else { a };
            b = if hi[k] > b { hi[k] } else { b };
        }
        (a, b)
    }

    /// Adds rows to `s` (starting at a multiple of 32 rows into the node): lane k gets the target
    /// of each row ≡ k (mod 32) with `x <= t`, else +0.0.
    #[inline(always)]
    pub fn count_sum_blocks(xs: &[f32], ys: &[f64], t: f32, s: &mut LeftSums) {
        let full = xs.len() / 32 * 32;
        let mut counts = [0u32; 32];
        for (xb, yb) in xs[..full].chunks_exact(32).zip(ys[..full].chunks_exact(32)) {
            for k in 0..32 {
                let left = xb[k] <= t;
                counts[k] += left as u32;
                s.lanes[k] += if left { yb[k] } else { 0.0 };
            }
        }
        for (k, (&x, &y)) in xs[full..].iter().zip(&ys[full..]).enumerate() {
            let left = x <= t;
            counts[k] += left as u32;
            s.lanes[k] += if left { y } else { 0.0 };
        }
        s.count += counts.iter().map(|&c| c as usize).sum::<usize>();
    }

    /// Destination of each row in a stable partition by `key <= t` (`n_left` rows go left).
    #[inline(always)]
    pub fn positions(key: &[f32], t: f32, n_left: usize, pos: &mut [u32]) {
        let (mut l, mut r) = (0u32, n_left as u32);
        for (p, &v) in pos.iter_mut().zip(key) {
            let left = v <= t;
            *p = if left { l } else { r };
            l += left as u32;
            r += !left as u32;
        }
    }

    /// `dst[pos[i]] = src[i]`.
    #[inline(always)]
    pub fn scatter<T: Copy>(src: &[T], dst: &mut [T], pos: &[u32]) {
        for (&v, &p) in src.iter().zip(pos) {
            dst[p as usize] = v;
        }
    }
}

/// AVX-512 kernels: the same results as [`portable`], bit for bit. A node's last partial block
/// of 16 rows is read with masked loads, so no row is handled by scalar code (small nodes are
/// many, and a scalar loop's unpredictable branches cost more than the vector work).
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{LeftSums, mean_var_of_sums};
    use std::arch::x86_64::*;

    /// The lanes of a block of 16 rows that exist, when `len` rows remain.
    #[inline(always)]
    fn valid(len: usize) -> u16 {
        if len >= 16 { u16::MAX } else { (1u16 << len) - 1 }
    }

    #[inline]
    #[target_feature(enable = "avx512f")]
    fn store(v: __m512d, out: &mut [f64]) {
        assert!(out.len() >= 8);
        // SAFETY: `out` holds at least 8 f64.
        unsafe { _mm512_storeu_pd(out.as_mut_ptr(), v) };
    }

    /// [`portable::mean_var`].
    #[inline]
    #[target_feature(enable = "avx512f")]
    pub fn mean_var(ys: &[f64]) -> (f64, f64) {
        let n = ys.len();
        let y0 = ys[0];
        let shift = _mm512_set1_pd(y0);
        let zero = _mm512_setzero_pd();
        let (mut s0, mut s1, mut q0, mut q1) = (zero, zero, zero, zero);
        for i in (0..n).step_by(16) {
            let m = valid(n - i);
            // SAFETY: the masks cover only rows i..n; masked-out lanes are not read.
            let (v0, v1) = unsafe {
                let p = ys.as_ptr().add(i);
                let (m0, m1) = (m as u8, (m >> 8) as u8);
                (
                    _mm512_maskz_sub_pd(m0, _mm512_maskz_loadu_pd(m0, p), shift),
                    _mm512_maskz_sub_pd(m1, _mm512_maskz_loadu_pd(m1, p.wrapping_add(8)), shift),
                )
            };
            s0 = _mm512_add_pd(s0, v0);
            s1 = _mm512_add_pd(s1, v1);
            q0 = _mm512_add_pd(q0, _mm512_mul_pd(v0, v0));
            q1 = _mm512_add_pd(q1, _mm512_mul_pd(v1, v1));
        }
        // [`super::finish_mean_var`]'s reduction, in registers.
        let (s, q) = (hsum(_mm512_add_pd(s0, s1)), hsum(_mm512_add_pd(q0, q1)));
        mean_var_of_sums(y0, s, q, n)
    }

    /// [`super::hsum8`] of a vector's lanes, by halving in registers (the same order).
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn hsum(v: __m512d) -> f64 {
        // (v0+v4, v1+v5, v2+v6, v3+v7), then ((v0+v4)+(v2+v6), (v1+v5)+(v3+v7)), then their sum.
        let w = _mm256_add_pd(_mm512_castpd512_pd256(v), _mm512_extractf64x4_pd::<1>(v));
        let u = _mm_add_pd(_mm256_castpd256_pd128(w), _mm256_extractf128_pd::<1>(w));
        _mm_cvtsd_f64(_mm_add_sd(u, _mm_unpackhi_pd(u, u)))
    }

    /// [`portable::count_sum_blocks`].
    #[inline]
    #[target_feature(enable = "avx512f,avx512dq,popcnt")]
    pub fn count_sum_blocks(xs: &[f32], ys: &[f64], t: f32, s: &mut LeftSums) {
        // SAFETY: `lanes` holds 32 f64.
        let acc: [__m512d; 4] = std::array::from_fn(|i| unsafe { _mm512_loadu_pd(s.lanes.as_ptr().add(8 * i)) });
        let (acc, count) = accumulate(xs, ys, t, acc);
        for (i, a) in acc.iter().enumerate() {
            store(*a, &mut s.lanes[8 * i..]);
        }
        s.count += count;
    }

    /// The rows with `x <= t` and the sum of their targets, for a whole node: the lanes of
    /// [`portable::count_sum_blocks`] from zero, reduced as [`super::count_sum_left`] reduces them
    /// (lane-wise `(l[j] + l[j+8]) + (l[j+16] + l[j+24])`, then [`super::hsum8`]'s halving order).
    #[inline]
    #[target_feature(enable = "avx512f,avx512dq,popcnt")]
    pub fn count_sum_node(xs: &[f32], ys: &[f64], t: f32) -> (usize, f64) {
        let (a, count) = accumulate(xs, ys, t, [_mm512_setzero_pd(); 4]);
        (count, hsum(_mm512_add_pd(_mm512_add_pd(a[0], a[1]), _mm512_add_pd(a[2], a[3]))))
    }

    /// Adds the targets of the rows with `x <= t` to the 32 lanes `acc` (lane k: rows ≡ k mod 32,
    /// `xs` starting at a multiple of 32 rows into the node) and counts those rows. Pairs of
    /// 16-row blocks are unrolled so the four accumulators stay in registers (indexing them by a
    /// block's parity would put them in memory, and every block would wait for a store to forward).
    #[inline]
    #[target_feature(enable = "avx512f,popcnt")]
    fn accumulate(xs: &[f32], ys: &[f64], t: f32, acc: [__m512d; 4]) -> ([__m512d; 4], usize) {
        let n = xs.len();
        assert_eq!(ys.len(), n);
        let tv = _mm512_set1_ps(t);
        let [mut a0, mut a1, mut a2, mut a3] = acc;
        let mut count = 0usize;
        // The targets of the rows with x <= t in a block at row i (zeros elsewhere: +0.0, exactly
        // as the portable `else { 0.0 }`), and their count.
        let block = |i: usize, m: u16| {
            // SAFETY: the mask covers only rows that exist; masked-out lanes are not read.
            unsafe {
                let (px, py) = (xs.as_ptr().add(i), ys.as_ptr().add(i));
                let k = _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(m, _mm512_maskz_loadu_ps(m, px), tv);
                let y0 = _mm512_maskz_loadu_pd(k as u8, py);
                (k.count_ones() as usize, y0, _mm512_maskz_loadu_pd((k >> 8) as u8, py.wrapping_add(8)))
            }
        };
        let pairs = n / 32 * 32;
        for i in (0..pairs).step_by(32) {
            let (c0, y0, y1) = block(i, u16::MAX);
            let (c1, y2, y3) = block(i + 16, u16::MAX);
            count += c0 + c1;
            a0 = _mm512_add_pd(a0, y0);
            a1 = _mm512_add_pd(a1, y1);
            a2 = _mm512_add_pd(a2, y2);
            a3 = _mm512_add_pd(a3, y3);
        }
        if pairs < n {
            let (c0, y0, y1) = block(pairs, valid(n - pairs));
            count += c0;
            a0 = _mm512_add_pd(a0, y0);
            a1 = _mm512_add_pd(a1, y1);
            if pairs + 16 < n {
                let (c1, y2, y3) = block(pairs + 16, valid(n - pairs - 16));
                count += c1;
                a2 = _mm512_add_pd(a2, y2);
                a3 = _mm512_add_pd(a3, y3);
            }
        }
        ([a0, a1, a2, a3], count)
    }

    /// [`partition`] of an input column, also returning the (min, max) of the rows sent left and
    /// of those sent right (both sides non-empty), taken from the vectors already loaded.
    #[inline]
    #[target_feature(enable = "avx512f,popcnt")]
    pub fn partition_min_max(src: &[f32], dst: &mut [f32], masks: &[u16], n_left: usize) -> ((f32, f32), (f32, f32)) {
        let n = src.len();
        assert!(dst.len() == n && masks.len() == n.div_ceil(16) && 0 < n_left && n_left < n);
        let (inf, ninf) = (_mm512_set1_ps(f32::INFINITY), _mm512_set1_ps(f32::NEG_INFINITY));
        let (mut lo_l, mut hi_l, mut lo_r, mut hi_r) = (inf, ninf, inf, ninf);
        let (mut l, mut r) = (0, n_left);
        for (b, &k) in masks.iter().enumerate() {
            let m = valid(n - 16 * b);
            let kr = m & !k;
            let (nk, nr) = (k.count_ones() as usize, kr.count_ones() as usize);
            assert!(k & !m == 0 && l + nk <= n_left && r + nr <= n);
            // SAFETY: the `m` lanes of block b exist; each store writes nk (nr) values, which fit
            // (asserted).
            unsafe {
                let v = _mm512_maskz_loadu_ps(m, src.as_ptr().add(16 * b));
                _mm512_mask_storeu_ps(dst.as_mut_ptr().add(l), first(nk as u32), _mm512_maskz_compress_ps(k, v));
                _mm512_mask_storeu_ps(dst.as_mut_ptr().add(r), first(nr as u32), _mm512_maskz_compress_ps(kr, v));
                lo_l = _mm512_mask_min_ps(lo_l, k, lo_l, v);
                hi_l = _mm512_mask_max_ps(hi_l, k, hi_l, v);
                lo_r = _mm512_mask_min_ps(lo_r, kr, lo_r, v);
                hi_r = _mm512_mask_max_ps(hi_r, kr, hi_r, v);
            }
            l += nk;
            r += nr;
        }
        assert!(l == n_left && r == n, "the partition counts disagree with the split");
        (
            (_mm512_reduce_min_ps(lo_l), _mm512_reduce_max_ps(hi_l)),
            (_mm512_reduce_min_ps(lo_r), _mm512_reduce_max_ps(hi_r)),
        )
    }

    /// `masks[b]` bit i set iff row 16 b + i exists and `key[16 b + i] <= t`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    pub fn left_masks(key: &[f32], t: f32, masks: &mut [u16]) {
        let n = key.len();
        assert_eq!(masks.len(), n.div_ceil(16));
        let tv = _mm512_set1_ps(t);
        for (b, mask) in masks.iter_mut().enumerate() {
            let m = valid(n - 16 * b);
            // SAFETY: the mask covers only existing rows; masked-out lanes are not read.
            let x = unsafe { _mm512_maskz_loadu_ps(m, key.as_ptr().add(16 * b)) };
            *mask = _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(m, x, tv);
        }
    }

    /// A value type [`partition`] moves: u32 row indices, 16 per vector, or f64 targets, 8 (the
    /// f32 inputs go through [`partition_min_max`], which also takes each side's range).
    pub trait Lane: Copy {
        /// Stores the lanes of a block of 16 values at `src` selected by `k` contiguously at `dst`,
        /// writing exactly `k.count_ones()` values (compress in a register, then a masked store:
        /// a compressing store to memory is much slower on Intel cores). Only the lanes in `valid`
        /// (a superset of `k`) are read.
        ///
        /// # Safety
        /// AVX-512F is available, the `valid` lanes of `src` exist and `dst` has room for
        /// `k.count_ones()` values.
        unsafe fn compress16(src: *const Self, valid: u16, k: u16, dst: *mut Self);
    }

    /// The first `c` lanes (c ≤ 16).
    #[inline(always)]
    fn first(c: u32) -> u16 {
        ((1u32 << c) - 1) as u16
    }

    impl Lane for u32 {
        #[inline]
        #[target_feature(enable = "avx512f,popcnt")]
        unsafe fn compress16(src: *const u32, valid: u16, k: u16, dst: *mut u32) {
            // SAFETY: per the trait contract.
            unsafe {
                let v = _mm512_maskz_compress_epi32(k, _mm512_maskz_loadu_epi32(valid, src.cast()));
                _mm512_mask_storeu_epi32(dst.cast(), first(k.count_ones()), v);
            }
        }
    }

    impl Lane for f64 {
        #[inline]
        #[target_feature(enable = "avx512f,popcnt")]
        unsafe fn compress16(src: *const f64, valid: u16, k: u16, dst: *mut f64) {
            // SAFETY: per the trait contract; the first half writes (k as u8).count_ones() values.
            unsafe {
                let (k0, k1) = (k as u8, (k >> 8) as u8);
                let v0 = _mm512_maskz_compress_pd(k0, _mm512_maskz_loadu_pd(valid as u8, src));
                let v1 = _mm512_maskz_compress_pd(k1, _mm512_maskz_loadu_pd((valid >> 8) as u8, src.wrapping_add(8)));
                let c0 = k0.count_ones();
                _mm512_mask_storeu_pd(dst, first(c0) as u8, v0);
                _mm512_mask_storeu_pd(dst.add(c0 as usize), first(k1.count_ones()) as u8, v1);
            }
        }
    }

    /// [`portable::positions`] + [`portable::scatter`]: stable partition of `src` into `dst` by
    /// the `masks` of [`left_masks`] (`n_left` rows go left).
    #[inline]
    #[target_feature(enable = "avx512f,popcnt")]
    pub fn partition<T: Lane>(src: &[T], dst: &mut [T], masks: &[u16], n_left: usize) {
        let n = src.len();
        assert!(dst.len() == n && masks.len() == n.div_ceil(16) && n_left <= n);
        let (mut l, mut r) = (0, n_left);
        for (b, &k) in masks.iter().enumerate() {
            let m = valid(n - 16 * b);
            let (nk, nr) = (k.count_ones() as usize, (m & !k).count_ones() as usize);
            // Needed for the stores below to stay inside `dst`; holds when n_left counts the
            // same comparison as the masks.
            assert!(k & !m == 0 && l + nk <= n_left && r + nr <= n);
            // SAFETY: the `m` lanes of block b exist; the stores write nk (nr) values, which fit
            // (asserted).
            unsafe {
                let s = src.as_ptr().add(16 * b);
                T::compress16(s, m, k, dst.as_mut_ptr().add(l));
                T::compress16(s, m, m & !k, dst.as_mut_ptr().add(r));
            }
            l += nk;
            r += nr;
        }
        assert!(l == n_left && r == n, "the partition counts disagree with the split");
    }
}

/// The largest `f32` not above `v` (finite `v` within the `f32` range).
fn round_down_f32(v: f64) -> f32 {
    let t = v as f32;
    // `t.next_down()` for a finite t, without branches: `t > v` for half the thresholds and t's
    // sign are coin tosses, and their mispredictions cost more than the rest of a small node's
    // draws (±0 go to the smallest negative subnormal, every other t one ulp toward −∞).
    let bits = t.to_bits();
    let below = if bits << 1 == 0 { (1 << 31) | 1 } else { bits.wrapping_add(((bits >> 31) << 1).wrapping_sub(1)) };
    f32::from_bits(if t as f64 > v { below } else { bits })
}

/// The `f64` threshold `T` with `x <= T` ⟺ `(x as f32) <= t` for every `f64` x.
///
/// `x as f32` rounds to nearest, ties to even, so it is ≤ t exactly when x is below the midpoint
/// between t and the next `f32` up, or on it when t's last significand bit is 0 (even).
fn query_threshold(t: f32) -> f64 {
    let up = t.next_up();
    let mid = if up.is_finite() {
        // Exact: both are f32, so their sum needs at most 25 significant bits.
        (t as f64 + up as f64) / 2.0
    } else {
        // t = f32::MAX, whose ulp is 2^104: values round to it up to MAX + 2^103.
        f32::MAX as f64 + 2f64.powi(103)
    };
    if t.to_bits() & 1 == 0 { mid } else { mid.next_down() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::learn::{NO_ROW, NextStates};

    /// `n` rows of `d` uniform inputs in [-1, 1) from a fixed stream.
    fn random_x(n: usize, d: usize, seed: u64) -> Vec<f64> {
        let mut r = rng::stream(seed, "test-x", &[]);
        (0..n * d).map(|_| rng::uniform(&mut r, -1.0, 1.0)).collect()
    }

    fn target(x: &[f64]) -> f64 {
        (3.0 * x[0]).sin() + x[1] * x[1]
    }

    fn synthetic(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let x = random_x(n, 2, seed);
        let y = x.chunks(2).map(target).collect();
        (x, y)
    }

    fn params(n_trees: usize, max_depth: Option<usize>, split: usize, leaf: usize) -> ExtraTreesParams {
        ExtraTreesParams { n_trees, max_depth, min_samples_split: split, min_samples_leaf: leaf }
    }

    fn fit(p: &ExtraTreesParams, x: &[f64], y: &[f64], seed: u64) -> ExtraTrees {
        let cols = x.len() / y.len();
        p.fit(Rows::new(x, cols).unwrap(), y, seed).unwrap().0
    }

    fn predict(m: &ExtraTrees, x: &[f64]) -> Vec<f64> {
        let rows = Rows::new(x, m.n_inputs()).unwrap();
        let mut out = vec![0.0; rows.n_rows()];
        m.predict_into(rows, &mut out);
        out
    }

    fn mse(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum::<f64>() / a.len() as f64
    }

    /// FNV-1a over the bits of `vals`.
    fn fingerprint(vals: impl IntoIterator<Item = f64>) -> u64 {
        vals.into_iter().fold(0xcbf2_9ce4_8422_2325, |h, v| (h ^ v.to_bits()).wrapping_mul(0x100_0000_01b3))
    }

    /// Pins the trees of fixed seeds bit for bit (through their in-sample predictions, their Q of
    /// every action on fresh states, and their sizes): speed work on the builder or the walks must
    /// not change a tree, or the committed reference runs would no longer reproduce from their seeds.
    #[test]
    fn forests_are_pinned_bit_for_bit() {
        let n = 2500;
        let xs = random_x(n, 2, 70);
        let mut r = rng::stream(71, "test-pinned", &[]);
        let acts: Vec<f64> = (0..n).map(|_| rng::below(&mut r, 5) as f64).collect();
        let x: Vec<f64> = (0..n).flat_map(|i| [xs[2 * i], xs[2 * i + 1], acts[i]]).collect();
        let y: Vec<f64> = (0..n).map(|i| target(&xs[2 * i..]) + 0.3 * (acts[i] - 2.0).abs()).collect();
        let states = random_x(700, 2, 72);
        let actions = [0.0, 1.0, 2.0, 3.0, 4.0];
        let mut prints = Vec::new();
        for (p, seed) in [(params(12, Some(9), 8, 4), 1), (params(6, None, 2, 1), 2), (params(9, Some(4), 4, 2), 3)] {
            let mut in_sample = vec![0.0; n];
            let (m, _) = p.fit_predict(Rows::new(&x, 3).unwrap(), &y, seed, &mut in_sample).unwrap();
            let mut q = vec![0.0; 700 * actions.len()];
            m.predict_actions_into(Rows::new(&states, 2).unwrap(), &actions, &mut q);
            let sizes = (0..m.n_trees()).map(|t| (m.n_nodes(t) * 64 + m.tree_depth(t)) as f64);
            prints.push(fingerprint(in_sample.into_iter().chain(q).chain(sizes)));
        }
        assert_eq!(prints, [0xbdcf_bb03_52ff_ea44, 0x8a98_1ce4_84af_8f0f, 0x1dc4_9790_a165_8727], "{prints:#x?}");
    }

    /// Pins, as above, forests where most rows have one target, so that pure nodes of thousands of
    /// rows (leaves, which draw nothing) sit beside nodes that go on splitting: a builder that
    /// drew for a node before knowing it is pure, without putting the stream back, would fail.
    #[test]
    fn big_pure_nodes_are_pinned_bit_for_bit() {
        let n = 12_000;
        let x = random_x(n, 3, 80);
        let y: Vec<f64> = x.chunks(3).map(|r| if r[0] > 0.6 && r[1] > 0.2 { target(r) + r[2] } else { 0.25 }).collect();
        let fresh = random_x(900, 3, 81);
        let mut prints = Vec::new();
        for (p, seed) in [(params(8, None, 2, 1), 4), (params(5, Some(12), 6, 3), 5)] {
            let mut in_sample = vec![0.0; n];
            let (m, _) = p.fit_predict(Rows::new(&x, 3).unwrap(), &y, seed, &mut in_sample).unwrap();
            let sizes = (0..m.n_trees()).map(|t| (m.n_nodes(t) * 64 + m.tree_depth(t)) as f64);
            let feats = (0..m.n_trees()).flat_map(|t| m.split_features(t)).map(|f| f as f64);
            prints.push(fingerprint(in_sample.into_iter().chain(predict(&m, &fresh)).chain(sizes).chain(feats)));
        }
        assert_eq!(prints, [0x137b_ed4c_a527_1ebb, 0xd144_3b0f_4a64_6e0f], "{prints:#x?}");
    }

    /// A worker thread keeps its workspace from one fit to the next: fits of other widths and row
    /// counts on the same thread in between must not reach a forest.
    #[test]
    fn kept_workspaces_change_no_forest() {
        let (x2, y2) = synthetic(3000, 90);
        let x5 = random_x(5000, 5, 91);
        let y5: Vec<f64> = x5.chunks(5).map(|r| target(r) + r[4]).collect();
        let (x_small, y_small) = synthetic(700, 92);
        let p = params(4, Some(12), 2, 1);
        let one_thread = || rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let forest = |x: &[f64], y: &[f64]| bits(&predict(&fit(&p, x, y, 7), x));
        // Each new pool has a new thread, so its first fit makes a new workspace.
        let alone = |x: &[f64], y: &[f64]| one_thread().install(|| forest(x, y));
        let in_turn =
            one_thread().install(|| [forest(&x2, &y2), forest(&x5, &y5), forest(&x_small, &y_small), forest(&x2, &y2)]);
        assert_eq!(in_turn[0], alone(&x2, &y2));
        assert_eq!(in_turn[1], alone(&x5, &y5));
        assert_eq!(in_turn[2], alone(&x_small, &y_small));
        assert_eq!(in_turn[3], in_turn[0]);
    }

    #[test]
    fn depth_limit_bounds_depth_and_leaves() {
        let (x, y) = synthetic(1500, 1);
        for depth in 1..=7 {
            let m = fit(&params(5, Some(depth), 2, 1), &x, &y, 3);
            for t in 0..m.n_trees() {
                assert!(m.tree_depth(t) <= depth);
                assert!(m.n_leaves(t) <= 1 << depth, "depth {depth}: {} leaves", m.n_leaves(t));
                assert_eq!(m.n_nodes(t), 2 * m.n_leaves(t) - 1);
                // 1500 rows leave room for every allowed level.
                assert_eq!(m.tree_depth(t), depth);
            }
        }
        let stump = fit(&params(10, Some(1), 2, 1), &x, &y, 4);
        for t in 0..10 {
            assert_eq!(stump.n_leaves(t), 2);
            assert_eq!(stump.split_features(t).len(), 1);
            assert_eq!(stump.leaf_sizes(t).iter().sum::<usize>(), 1500);
        }
    }

    #[test]
    fn stumps_prefer_the_informative_feature() {
        // y is a step in x0; x1 is noise. A random cut of x0 explains far more variance than one
        // of x1 almost always, so the variance criterion should pick x0 in most stumps.
        let x = random_x(1000, 2, 50);
        let y: Vec<f64> = x.chunks(2).map(|r| if r[0] > 0.2 { 1.0 } else { 0.0 }).collect();
        let m = fit(&params(200, Some(1), 2, 1), &x, &y, 3);
        let on_x0 = (0..200).filter(|&t| m.split_features(t) == [0]).count();
        assert!(on_x0 > 170, "{on_x0} of 200 stumps split on x0");
    }

    #[test]
    fn leaves_respect_min_samples_leaf_and_split() {
        let (x, y) = synthetic(2000, 2);
        for (split, leaf) in [(2, 1), (8, 4), (4, 2), (30, 10), (3, 7)] {
            let m = fit(&params(4, None, split, leaf), &x, &y, 5);
            for t in 0..m.n_trees() {
                let sizes = m.leaf_sizes(t);
                assert_eq!(sizes.iter().sum::<usize>(), 2000);
                assert!(sizes.iter().all(|&s| s >= leaf), "split {split} leaf {leaf}: {sizes:?}");
            }
            // Fully grown with 1-row leaves on distinct inputs: every leaf is a single row.
            if leaf == 1 {
                assert!(m.leaf_sizes(0).iter().all(|&s| s == 1));
            }
        }
        // A node smaller than min_samples_split is never split.
        let m = fit(&params(3, None, 2001, 1), &x, &y, 5);
        assert_eq!(m.n_leaves(0), 1);
        assert_eq!(m.tree_depth(0), 0);
        let m = fit(&params(3, None, 2000, 1), &x, &y, 5);
        assert!(m.n_leaves(0) >= 2 && m.tree_depth(0) <= 1);
    }

    #[test]
    fn fully_grown_tree_reproduces_training_targets() {
        // Exercises the f32 thresholds: every training row must land in its own leaf.
        let (x, y) = synthetic(800, 3);
        // Two trees: (v + v) / 2 == v exactly.
        let m = fit(&params(2, None, 2, 1), &x, &y, 9);
        for (row, &target) in x.chunks(2).zip(&y) {
            assert_eq!(m.predict_row(row), target);
        }
    }

    #[test]
    fn forest_learns_and_improves_with_depth() {
        let (x, y) = synthetic(2000, 10);
        let (xt, yt) = synthetic(1000, 11);
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        let base = mse(&vec![mean; yt.len()], &yt);
        let errs: Vec<f64> =
            [2, 6, 12].iter().map(|&d| mse(&predict(&fit(&params(30, Some(d), 2, 1), &x, &y, 7), &xt), &yt)).collect();
        assert!(errs[0] < base / 2.0 && errs[1] < errs[0] && errs[2] < errs[1], "{errs:?} vs {base}");
        assert!(errs[2] < base / 50.0, "{errs:?} vs {base}");
    }

    #[test]
    fn same_seed_same_forest_for_any_thread_count() {
        let (x, y) = synthetic(3000, 20);
        let (xt, _) = synthetic(500, 21);
        let p = params(12, Some(10), 4, 2);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| predict(&fit(&p, &x, &y, 42), &xt))
        };
        let one = run(1);
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
        let other = predict(&fit(&p, &x, &y, 43), &xt);
        assert_ne!(one, other);
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn vector_and_portable_kernels_build_the_same_trees() {
        #[cfg(target_arch = "x86_64")]
        if cpu::Isa::Avx512.runs_extra_trees() {
            // Sizes around the block lengths (16, 32) and the sweep step, a large target offset
            // (rounding differences would show) and duplicated inputs (ties at thresholds).
            for (n, offset) in [(1, 0.0), (15, 0.0), (17, 1e6), (33, -3.0), (700, 1e6), (5000, 0.5)] {
                let mut x = random_x(n, 3, n as u64);
                x.iter_mut().skip(2).step_by(3).for_each(|v| *v = (*v * 4.0).round());
                let y: Vec<f64> = x.chunks(3).map(|r| offset + target(r) + r[2]).collect();
                // Forks at splits on the last column.
                let data = Data::new(Rows::new(&x, 3).unwrap(), &y, Record::Routes(2)).unwrap();
                for p in [params(1, None, 2, 1), params(1, Some(5), 4, 2)] {
                    let mut ws = Workspace::new(3, n);
                    let routes = || Routes { leaf_of: vec![0; n], value: Vec::new(), fork: Vec::new() };
                    let (mut la, mut lb) = (routes(), routes());
                    let a = build_tree_impl::<false>(&p, &data, &mut ws, rng::stream(9, "tree", &[0]), &mut la);
                    // SAFETY: the features were just detected.
                    let b = unsafe { build_tree_avx512(&p, &data, &mut ws, rng::stream(9, "tree", &[0]), &mut lb) };
                    assert_eq!(a.counts, b.counts, "n {n}");
                    assert_eq!((&la.leaf_of, &la.fork), (&lb.leaf_of, &lb.fork), "n {n}");
                    assert_eq!(bits(&la.value), bits(&lb.value), "n {n}");
                    for (u, v) in a.nodes.iter().zip(&b.nodes) {
                        assert_eq!((u.val.to_bits(), u.feat, u.left), (v.val.to_bits(), v.feat, v.left), "n {n}");
                    }
                }
            }
        }
    }

    #[test]
    fn fit_predict_matches_predict_into() {
        // Ties at thresholds (rounded inputs), a depth limit (leaves above the deepest level), a
        // large target offset, one and several trees, and rows in the parallel path.
        for (n, trees, depth, leaf) in [(1, 1, None, 1), (37, 3, Some(3), 2), (9000, 20, Some(9), 1)] {
            let mut x = random_x(n, 3, n as u64 + 5);
            x.iter_mut().skip(1).step_by(3).for_each(|v| *v = (*v * 8.0).round() / 8.0);
            let y: Vec<f64> = x.chunks(3).map(|r| 1e5 + target(r) + r[1]).collect();
            let p = params(trees, depth, 2, leaf);
            let rows = Rows::new(&x, 3).unwrap();
            let mut inside = vec![f64::NAN; n];
            let (m, _) = p.fit_predict(rows, &y, 4, &mut inside).unwrap();
            let mut walked = vec![0.0; n];
            m.predict_into(rows, &mut walked);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&inside), bits(&walked), "n {n}");
            // Same model as a plain fit.
            assert_eq!(bits(&predict(&fit(&p, &x, &y, 4), &x)), bits(&walked), "n {n}");
        }
    }

    #[test]
    fn predict_into_matches_predict_row() {
        let (x, y) = synthetic(2000, 30);
        // Enough rows to go through the parallel path and a ragged last chunk.
        let xt = random_x(5000 + 17, 2, 31);
        let m = fit(&params(50, Some(8), 2, 1), &x, &y, 1);
        let batch = predict(&m, &xt);
        for (row, &b) in xt.chunks(2).zip(&batch) {
            assert_eq!(m.predict_row(row), b);
        }
    }

    /// A model that keeps the trait's default `predict_actions_into` (one row per action).
    struct DefaultPath<'a>(&'a ExtraTrees);

    impl Regressor for DefaultPath<'_> {
        fn n_inputs(&self) -> usize {
            self.0.n_inputs()
        }
        fn predict_row(&self, row: &[f64]) -> f64 {
            self.0.predict_row(row)
        }
    }

    fn predict_actions(m: &dyn Regressor, states: &[f64], actions: &[f64]) -> Vec<u64> {
        let rows = Rows::new(states, m.n_inputs() - 1).unwrap();
        let mut out = vec![f64::NAN; rows.n_rows() * actions.len()];
        m.predict_actions_into(rows, actions, &mut out);
        out.iter().map(|v| v.to_bits()).collect()
    }

    #[test]
    fn predict_actions_into_is_bit_identical_to_the_default() {
        let d = 3;
        let n = 3000;
        let mut r = rng::stream(5, "test-actions", &[]);
        // Training actions: 9 discrete values, plus a column never split on (constant).
        let xs = random_x(n, d, 60);
        let acts: Vec<f64> = (0..n).map(|_| rng::below(&mut r, 9) as f64).collect();
        let join = |a: &dyn Fn(usize) -> f64| -> Vec<f64> {
            (0..n).flat_map(|i| xs[i * d..(i + 1) * d].iter().copied().chain([a(i)])).collect()
        };
        let x_discrete = join(&|i| acts[i]);
        let x_constant = join(&|_| 1.0);
        let x_continuous = join(&|i| xs[i * d] * 0.5 + (i as f64 * 0.37).sin());
        let noise = |i: usize| (i as f64 * 1.7).cos() * 0.1;
        // A weak action effect, and one where the action dominates (split at the top of every tree).
        let y_weak: Vec<f64> = (0..n).map(|i| target(&xs[i * d..]) + 0.2 * acts[i] + noise(i)).collect();
        let y_strong: Vec<f64> = (0..n).map(|i| 10.0 * (acts[i] - 4.0).abs() + xs[i * d + 2] + noise(i)).collect();
        let y_cont: Vec<f64> = (0..n).map(|i| x_continuous[i * (d + 1) + d].sin() * 3.0 + xs[i * d + 1]).collect();
        let forests = [
            fit(&params(10, Some(12), 4, 2), &x_discrete, &y_weak, 1),
            fit(&params(7, None, 2, 1), &x_discrete, &y_strong, 2),
            fit(&params(9, Some(6), 8, 4), &x_constant, &y_weak, 3),
            fit(&params(12, None, 2, 1), &x_continuous, &y_cont, 4),
            fit(&params(3, Some(1), 2, 1), &x_discrete, &y_strong, 5),
            fit(&params(4, None, 2, 1), &x_discrete, &[2.5; 3000], 6),
        ];
        assert!(forests[1].split_features(0)[0] == d, "the action should split the root");
        assert!((0..9).all(|t| forests[2].split_features(t).iter().all(|&f| f != d)));
        let many: Vec<f64> = (0..70).map(|j| j as f64 * 0.15 - 1.0).collect();
        let action_sets: Vec<Vec<f64>> = vec![
            (0..9).map(f64::from).collect(),
            vec![2.0, -2.0],
            vec![4.0],
            vec![8.0, 0.0, 3.5, 3.0, 3.0, -0.0, 0.0, 100.0, -7.0],
            vec![0.5, f64::NAN, -0.25, 1e-9, f32::MAX as f64 * 2.0],
            many[..64].to_vec(),
            many.clone(),
        ];
        // Queries: fresh states, the training states (ties with thresholds) and odd values.
        let mut states = random_x(4100, d, 61);
        states.extend_from_slice(&xs[..300 * d]);
        states.extend_from_slice(&[0.0, -0.0, f64::NAN, 1e30, -1e30, 0.5]);
        let n_states = states.len() / d;
        for (f, m) in forests.iter().enumerate() {
            // Actions on, just below and just above the forest's own action thresholds.
            let on_thresholds: Vec<f64> = (m.trees.iter().flat_map(|t| &t.nodes))
                .filter(|node| node.feat == d as u32)
                .flat_map(|node| [node.val, node.val.next_down(), node.val.next_up()])
                .take(63)
                .collect();
            assert_eq!(on_thresholds.is_empty(), f == 2 || f == 5, "forest {f}");
            // States on the forest's own state thresholds.
            let mut states = states.clone();
            for (i, node) in
                (m.trees.iter().flat_map(|t| &t.nodes)).filter(|node| node.feat < d as u32).take(200).enumerate()
            {
                states[i * d + node.feat as usize] = if i % 2 == 0 { node.val } else { node.val.next_up() };
            }
            for acts in action_sets.iter().chain([&on_thresholds].into_iter().filter(|a| !a.is_empty())) {
                let want = predict_actions(&DefaultPath(m), &states, acts);
                // Many rows (parallel when large enough), a few, and single states.
                assert!(predict_actions(m, &states, acts) == want, "forest {f}, {} actions", acts.len());
                for (a, b) in [(0, 5), (10, 19), (100, 100 + LANES + 1)] {
                    let few = predict_actions(m, &states[a * d..b * d], acts);
                    assert!(few == want[a * acts.len()..b * acts.len()], "forest {f}, states {a}..{b}");
                }
                let single = (0..n_states).step_by(37).chain(n_states - 6..n_states);
                for i in single {
                    let one = predict_actions(m, &states[i * d..(i + 1) * d], acts);
                    assert!(one == want[i * acts.len()..(i + 1) * acts.len()], "forest {f}, state {i}");
                }
            }
        }
        // Any thread count gives the same answer.
        let acts = &action_sets[0];
        let want = predict_actions(&forests[0], &states, acts);
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            assert!(pool.install(|| predict_actions(&forests[0], &states, acts)) == want);
        }
        // No states, no actions.
        assert!(predict_actions(&forests[0], &[], acts).is_empty());
        assert!(predict_actions(&forests[0], &states, &[]).is_empty());
    }

    #[test]
    fn fit_predict_next_is_bit_identical_to_fitting_then_predicting() {
        let (n, d) = (2500, 3);
        let mut r = rng::stream(8, "test-next", &[]);
        let xs = random_x(n, d, 70);
        let acts: Vec<f64> = (0..n).map(|_| rng::below(&mut r, 9) as f64).collect();
        let join = |a: &dyn Fn(usize) -> f64| -> Vec<f64> {
            (0..n).flat_map(|i| xs[i * d..(i + 1) * d].iter().copied().chain([a(i)])).collect()
        };
        let (with_action, constant_action) = (join(&|i| acts[i]), join(&|_| 1.0));
        let noise = |i: usize| (i as f64 * 1.7).cos() * 0.1;
        // The action splits here and there (weak), at the top (strong), or nowhere (constant).
        let y_weak: Vec<f64> = (0..n).map(|i| target(&xs[i * d..]) + 0.01 * acts[i] + noise(i)).collect();
        let y_strong: Vec<f64> = (0..n).map(|i| 10.0 * (acts[i] - 4.0).abs() + xs[i * d + 2] + noise(i)).collect();
        // Next states: training states hinted with their row (in trajectory order, and one that
        // hints another row with the same state), training states and fresh ones without a hint.
        let fresh = random_x(300, d, 71);
        let mut states = Vec::new();
        let mut same = Vec::new();
        for i in 0..n + 300 {
            let (state, hint) = match i % 5 {
                _ if i >= n => (&fresh[(i - n) * d..(i - n + 1) * d], NO_ROW),
                4 => (&xs[i * d..(i + 1) * d], NO_ROW),
                _ => (&xs[(i + 1) % n * d..((i + 1) % n + 1) * d], ((i + 1) % n) as u32),
            };
            states.extend_from_slice(state);
            same.push(hint);
        }
        let states = Rows::new(&states, d).unwrap();
        let many: Vec<f64> = (0..70).map(|j| j as f64 * 0.15 - 1.0).collect();
        for (f, (p, x, y)) in [
            (params(8, Some(12), 4, 2), &with_action, &y_weak),
            (params(5, None, 2, 1), &with_action, &y_strong),
            (params(6, Some(8), 8, 4), &constant_action, &y_weak),
        ]
        .into_iter()
        .enumerate()
        {
            // Rows whose leaf has a fork and rows whose leaf has none, except where nothing splits
            // on the action.
            let x = Rows::new(x, d + 1).unwrap();
            let (_, routes) = p.fit_impl(x, y, 3, Record::Routes(d)).unwrap();
            let forked = |r: &Routes| r.leaf_of.iter().filter(|&&l| r.fork[l as usize] != NO_FORK).count();
            let at_split: usize = routes.iter().map(forked).sum();
            let at_leaf = n * p.n_trees - at_split;
            assert_eq!(at_split == 0, f == 2, "forest {f}: {at_split} rows below a fork");
            assert!(f == 1 || at_leaf > 0, "forest {f}: every row below a fork");
            for actions in [(0..9).map(f64::from).collect(), many.clone(), vec![4.0]] {
                let next = NextStates { states, actions: Some(&actions), same: &same };
                let (mut train, mut q) = (vec![0.0; n], vec![0.0; (n + 300) * actions.len()]);
                let (m, _) = p.fit_predict(x, y, 3, &mut train).unwrap();
                m.predict_actions_into(states, &actions, &mut q);
                let (mut train2, mut q2) = (vec![f64::NAN; n], vec![f64::NAN; q.len()]);
                p.fit_predict_next(x, y, 3, &mut train2, &next, &mut q2).unwrap();
                assert_eq!(bits(&train2), bits(&train), "forest {f}, in-sample");
                assert_eq!(bits(&q2), bits(&q), "forest {f}, {} actions", actions.len());
            }
            // The state alone as input (one model per action): no forks.
            let x = Rows::new(&xs, d).unwrap();
            let next = NextStates { states, actions: None, same: &same };
            let (mut train, mut q) = (vec![0.0; n], vec![0.0; n + 300]);
            let (m, _) = p.fit_predict(x, y, 4, &mut train).unwrap();
            m.predict_into(states, &mut q);
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let (mut train2, mut q2) = (vec![f64::NAN; n], vec![f64::NAN; q.len()]);
                pool.install(|| p.fit_predict_next(x, y, 4, &mut train2, &next, &mut q2)).unwrap();
                assert_eq!(bits(&train2), bits(&train), "forest {f}, state inputs, in-sample");
                assert_eq!(bits(&q2), bits(&q), "forest {f}, state inputs, {threads} threads");
            }
        }
    }

    #[test]
    fn constant_parts_are_not_split() {
        // Constant target: every tree is one leaf with that value.
        let x = random_x(300, 3, 40);
        let m = fit(&params(5, None, 2, 1), &x, &[2.5; 300], 1);
        assert!((0..5).all(|t| m.n_leaves(t) == 1));
        assert_eq!(m.predict_row(&[0.0, 0.0, 0.0]), 2.5);
        // A constant feature is never chosen.
        let mut x = random_x(500, 3, 41);
        x.iter_mut().skip(1).step_by(3).for_each(|v| *v = 7.0);
        let y: Vec<f64> = x.chunks(3).map(|r| r[0] + r[2]).collect();
        let m = fit(&params(5, None, 2, 1), &x, &y, 2);
        assert!((0..5).all(|t| m.split_features(t).iter().all(|&f| f != 1)));
    }

    #[test]
    fn invalid_params_name_the_field() {
        let cases = [
            (params(0, None, 2, 1), "n_trees"),
            (params(5, Some(0), 2, 1), "max_depth"),
            (params(5, None, 1, 1), "min_samples_split"),
            (params(5, None, 2, 0), "min_samples_leaf"),
        ];
        let x = [0.0, 1.0];
        for (p, field) in cases {
            let e = p.check().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
            let e = p.fit(Rows::new(&x, 1).unwrap(), &[0.0, 1.0], 0).unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
        assert!(ExtraTreesParams::default().check().is_ok());
    }

    #[test]
    fn bad_data_is_an_error() {
        let p = ExtraTreesParams::default();
        let x = [0.0, 1.0, f64::NAN, 3.0];
        assert!(p.fit(Rows::new(&x, 2).unwrap(), &[0.0, 1.0], 0).is_err());
        let x = [0.0, 1.0, 2.0, 3.0];
        assert!(p.fit(Rows::new(&x, 2).unwrap(), &[0.0, f64::NAN], 0).is_err());
        assert!(p.fit(Rows::new(&x, 2).unwrap(), &[0.0], 0).is_err());
        let x = [0.0, 1e300];
        let e = p.fit(Rows::new(&x, 1).unwrap(), &[0.0, 1.0], 0).unwrap_err().to_string();
        assert!(e.contains("too large"), "{e}");
    }

    #[test]
    fn params_serde_defaults_and_unknown_fields() {
        let p: ExtraTreesParams = serde_json::from_str(r#"{"n_trees": 30, "max_depth": 13}"#).unwrap();
        assert_eq!(p, ExtraTreesParams { n_trees: 30, max_depth: Some(13), ..Default::default() });
        let p: ExtraTreesParams = serde_json::from_str("{}").unwrap();
        assert_eq!(p, ExtraTreesParams::default());
        assert!(serde_json::from_str::<ExtraTreesParams>(r#"{"n_tree": 3}"#).is_err());
        let back: ExtraTreesParams = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
        assert_eq!(back, p);
    }

    #[test]
    fn query_threshold_agrees_with_f32_rounding() {
        let mut r = rng::stream(1, "test-thr", &[]);
        let mut ts: Vec<f32> = (0..2000).map(|_| rng::uniform(&mut r, -1e3, 1e3) as f32).collect();
        ts.extend([0.0, -0.0, 1.0, -1.0, f32::MAX, -f32::MAX, f32::MIN_POSITIVE, 1e-40, 16777216.0]);
        for &t in &ts {
            let big = query_threshold(t);
            let up = t.next_up() as f64;
            let mid = if t == f32::MAX { f32::MAX as f64 + 2f64.powi(103) } else { (t as f64 + up) / 2.0 };
            for q in [t as f64, mid.next_down(), mid, mid.next_up(), up, (t as f64).next_down()] {
                assert_eq!(q <= big, (q as f32) <= t, "t {t:e}, q {q:e}");
            }
        }
        for v in [0.3, -0.3, 1.0 / 3.0, 1e-3, 12345.678] {
            let t = round_down_f32(v);
            assert!(t as f64 <= v && (t.next_up() as f64) > v);
        }
    }

    #[test]
    fn round_down_f32_is_the_largest_f32_not_above() {
        let mut r = rng::stream(1, "test-round-down", &[]);
        let mut vs: Vec<f64> = (0..20_000).map(|_| rng::uniform(&mut r, -2.0, 2.0)).collect();
        vs.extend((0..2000).map(|_| rng::uniform(&mut r, -1e-44, 1e-44)));
        vs.extend([0.0, -0.0, 1e-300, -1e-300, 1.0, -1.0, f32::MAX as f64, -(f32::MAX as f64)]);
        vs.extend([f32::MIN_POSITIVE as f64, -(f32::MIN_POSITIVE as f64), 1e-45, -1e-45]);
        for &v in &vs {
            let textbook = {
                let t = v as f32;
                if t as f64 > v { t.next_down() } else { t }
            };
            assert_eq!(round_down_f32(v).to_bits(), textbook.to_bits(), "v {v:e}");
        }
    }
}
