//! What only FQI needs: where the training rows end up in each tree, recorded while it is built,
//! and the predictions that reuse it (in-sample, and next states with a training twin).

use super::ExtraTrees;
use super::predict::{ACTION_BLOCK, LANES, PREDICT_BLOCK, add_walks};
use crate::learn::{NO_ROW, NextStates, Rows};
use rayon::prelude::*;

/// Where the training rows end up in one tree (see [`Record::Routes`]).
pub(super) struct Routes {
    /// Per row, its leaf, as an index into `value` and `fork`.
    pub(super) leaf_of: Vec<u32>,
    /// The leaves the rows reach, in the order they were made: small arrays (a few rows per leaf
    /// at least), where the rows' lookups at random stay in cache, unlike the tree's nodes.
    pub(super) value: Vec<f64>,
    /// The first node on the leaf's path that splits on
    /// [`Data::fork_col`](super::builder::Data::fork_col), or [`NO_FORK`]: where a walk with the
    /// leaf's rows' state and any action leaves their path.
    pub(super) fork: Vec<u32>,
}

/// No split on the fork column above a leaf (never a node index: a tree has < 2^32 − 1 nodes).
pub(super) const NO_FORK: u32 = u32::MAX;

/// What the trees record for each training row while they are built.
#[derive(Debug, Clone, Copy)]
pub(super) enum Record {
    Nothing,
    /// Its leaf, and each leaf's fork: its first ancestor that splits on this column (none for
    /// `usize::MAX`).
    Routes(usize),
}

impl ExtraTrees {
    /// The training rows' predictions from their recorded leaves; bit-identical to `predict_into`.
    pub(super) fn predict_training(&self, routes: &[Routes], out: &mut [f64]) {
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
    pub(super) fn predict_next_routed(&self, next: &NextStates<'_>, routes: &[Routes], out: &mut [f64]) {
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

/// Records a new leaf of value `value` below `fork` (see [`Routes`]) as the leaf of `rows`.
#[inline(always)]
pub(super) fn record_leaf(value: f64, fork: u32, rows: &[u32], routes: &mut Routes) {
    let l = routes.value.len() as u32;
    routes.value.push(value);
    routes.fork.push(fork);
    for &i in rows {
        routes.leaf_of[i as usize] = l;
    }
}
