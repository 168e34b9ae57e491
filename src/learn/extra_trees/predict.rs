//! The prediction engines: a row over all trees, blocks of rows tree by tree, and the Q of every
//! action, whose walks fork only at the splits on the action ([`forked_walks`]).

use super::ExtraTrees;
use super::tree::{LEAF, Node, Tree};
use crate::learn::{Regressor, Rows};
use rayon::prelude::*;

/// Walks interleaved in prediction: trees for one row, rows for one tree.
const WALKS: usize = 8;
/// Rows per block in [`ExtraTrees::predict_into`]: a tree is walked for the whole block before the
/// next tree, so its nodes stay in cache. Blocks are also the unit of parallel work; a row's sum
/// over trees is in tree order whatever the split, so the result never depends on it.
pub(super) const PREDICT_BLOCK: usize = 4096;

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
pub(super) const ACTION_BLOCK: usize = 32768;
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
    pub(super) fn state_blocks(
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
}

/// Adds tree `tree`'s leaves to `out` (`actions.len()` cells per state, in action order) for
/// walks `0..n`: walk `w` is state `s` of `states` (`d` values each, and one more after the last)
/// from node `start`, with `(s, start) = origin(w)`, for every action.
pub(super) fn add_walks(
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
pub(super) const LANES: usize = 8;
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
