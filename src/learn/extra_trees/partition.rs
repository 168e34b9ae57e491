//! Moving a split node's rows to its children (sklearn's `DensePartitioner`): a stable partition
//! of every column into the other buffer, which also takes each child's feature ranges.

use super::kernels::{Kernels, Marks};
use super::splitter::Split;

/// A range with +0.0 for −0.0, so that it does not depend on the order the extrema were taken in
/// (min/max of ±0 return either).
#[inline(always)]
pub(super) fn canonical((lo, hi): (f32, f32)) -> (f32, f32) {
    (lo + 0.0, hi + 0.0)
}

/// The partition's scratch memory and the children's ranges it takes (part of a workspace).
pub(super) struct Partitioner {
    marks: Marks,
    /// The children's ranges of the node being split (of the last partition that moved every
    /// column).
    pub(super) left_ranges: Vec<(f32, f32)>,
    pub(super) right_ranges: Vec<(f32, f32)>,
}

impl Partitioner {
    /// For nodes of up to `n` rows on `d` features.
    pub(super) fn new(d: usize, n: usize) -> Self {
        Partitioner {
            marks: Marks { pos: vec![0; n], masks: vec![0; n.div_ceil(16)] },
            left_ranges: vec![(0.0, 0.0); d],
            right_ranges: vec![(0.0, 0.0); d],
        }
    }

    /// The features it takes ranges of.
    pub(super) fn n_features(&self) -> usize {
        self.left_ranges.len()
    }

    /// Stable partition of a node's rows by `key <= split.thr` (`split.n_left` rows go left): each
    /// of `columns` (source, destination) with its children's ranges, then the targets `ys` and the
    /// row indices `rows`, when tracked.
    #[inline(always)]
    pub(super) fn partition<'a, K: Kernels>(
        &mut self,
        k: K,
        key: &[f32],
        split: &Split,
        columns: impl Iterator<Item = (&'a [f32], &'a mut [f32])>,
        ys: (&[f64], &mut [f64]),
        rows: Option<(&[u32], &mut [u32])>,
    ) {
        k.mark(key, split.thr, split.n_left, &mut self.marks);
        for (f, (src, dst)) in columns.enumerate() {
            let (l, r) = k.move_column(src, dst, &self.marks, split.n_left);
            (self.left_ranges[f], self.right_ranges[f]) = (canonical(l), canonical(r));
        }
        k.move_targets(ys.0, ys.1, &self.marks, split.n_left);
        if let Some((src, dst)) = rows {
            k.move_rows(src, dst, &self.marks, split.n_left);
        }
    }
}
