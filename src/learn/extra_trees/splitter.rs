//! The Extra-Trees split rule (sklearn's `RandomSplitter`): one uniform threshold per feature, the
//! best of them by variance reduction, and the `f32` thresholds it works with.

use super::criterion::{LeftSums, lanes_total};
use super::kernels::Kernels;
use crate::rng::{self, Rng};

/// sklearn's `FEATURE_THRESHOLD`: a feature whose range in the node is at most this is constant.
const FEATURE_THRESHOLD: f64 = 1e-7;

/// A candidate split: feature and threshold (rows with `x <= thr` go left).
#[derive(Clone, Copy)]
pub(super) struct Candidate {
    pub(super) feat: usize,
    pub(super) thr: f32,
}

/// A node's chosen split.
#[derive(Clone, Copy)]
pub(super) struct Split {
    pub(super) feat: usize,
    pub(super) thr: f32,
    pub(super) n_left: usize,
}

/// A node's rows as the split search reads them: feature `f` at `x[f * n_all + start..]` (the
/// columns of all the data's rows, one after the other), and the node's targets `ys`.
#[derive(Clone, Copy)]
pub(super) struct NodeRows<'a> {
    pub(super) x: &'a [f32],
    pub(super) n_all: usize,
    pub(super) start: usize,
    pub(super) ys: &'a [f64],
}

/// The splitter's scratch memory, reused across nodes and trees (it is part of a workspace).
pub(super) struct Splitter {
    /// The features in the order they are tried, shuffled in place at each node (so, as in
    /// sklearn, a node's order starts from the previous node's).
    order: Vec<usize>,
    /// The node's candidate splits and their left-side sums.
    cands: Vec<Candidate>,
    sums: Vec<LeftSums>,
}

impl Splitter {
    pub(super) fn new(d: usize) -> Self {
        Splitter { order: (0..d).collect(), cands: Vec::with_capacity(d), sums: vec![LeftSums::default(); d] }
    }

    /// Starts a tree: features in their natural order.
    pub(super) fn start_tree(&mut self, d: usize) {
        self.order.clear();
        self.order.extend(0..d);
    }

    /// The split of a node that the size, depth and purity rules let split: every feature in a
    /// random order, a threshold drawn uniformly in each non-constant one's range in the node
    /// (`ranges`, one per feature), and the first candidate with the largest variance reduction
    /// among those leaving `min_leaf` rows on each side; none if no candidate does. `mean` is the
    /// node's mean target.
    #[inline(always)]
    pub(super) fn node_split<K: Kernels>(
        &mut self,
        k: K,
        rng: &mut Rng,
        node: NodeRows<'_>,
        ranges: &[(f32, f32)],
        mean: f64,
        min_leaf: usize,
    ) -> Option<Split> {
        let n = node.ys.len();
        let d = self.order.len();
        for i in (1..d).rev() {
            let j = rng::below(rng, i as u64 + 1) as usize;
            self.order.swap(i, j);
        }
        // Draw every threshold first (the draws depend only on each feature's range), then
        // count all candidates in one sweep, so the node's targets are read once, not d times.
        self.cands.clear();
        for &f in &self.order {
            let (lo, hi) = ranges[f];
            let (lo, hi) = (lo as f64, hi as f64);
            if hi <= lo + FEATURE_THRESHOLD {
                continue;
            }
            let mut thr = rng::uniform(rng, lo, hi);
            if thr >= hi {
                thr = lo; // rounding reached the top: sklearn falls back to the minimum
            }
            // The rows are f32, so `x <= thr` ⟺ `x <= t` with t the largest f32 ≤ thr.
            self.cands.push(Candidate { feat: f, thr: round_down_f32(thr) });
        }
        let sums = &mut self.sums[..self.cands.len()];
        count_sum_left(k, node, &self.cands, sums);
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
        self.cands.get(best_i).map(|c| Split { feat: c.feat, thr: c.thr, n_left: sums[best_i].count })
    }
}

/// The largest `f32` not above `v` (finite `v` within the `f32` range).
pub(super) fn round_down_f32(v: f64) -> f32 {
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
pub(super) fn query_threshold(t: f32) -> f64 {
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

/// Rows per sweep step in [`count_sum_left`] (a multiple of 32): the step's targets (16 KiB) stay
/// in L1 while every candidate's column passes over them.
const SWEEP: usize = 2048;

/// For each candidate, the rows of the node with `x <= thr` and the sum of their targets, left in
/// `sums[i].count` and `sums[i].sum`.
#[inline(always)]
pub(super) fn count_sum_left<K: Kernels>(k: K, node: NodeRows<'_>, cands: &[Candidate], sums: &mut [LeftSums]) {
    let NodeRows { x: src_x, n_all, start, ys } = node;
    let n = ys.len();
    if K::NODE_SUMS && n <= SWEEP {
        // One sweep step: each candidate's lanes live in registers and are reduced there, in the
        // same order as below (most nodes are small, and for them the trip through memory and the
        // scalar reduction cost more than the counting).
        for (c, s) in cands.iter().zip(sums.iter_mut()) {
            let xs = &src_x[c.feat * n_all + start..c.feat * n_all + start + n];
            (s.count, s.sum) = k.count_sum_node(xs, ys, c.thr);
        }
        return;
    }
    sums.fill(LeftSums::default());
    let mut a = 0;
    while a < n {
        let b = (a + SWEEP).min(n);
        for (c, s) in cands.iter().zip(sums.iter_mut()) {
            let xs = &src_x[c.feat * n_all + start + a..c.feat * n_all + start + b];
            k.count_sum_blocks(xs, &ys[a..b], c.thr, s);
        }
        a = b;
    }
    for s in sums.iter_mut() {
        s.sum = lanes_total(&s.lanes);
    }
}
