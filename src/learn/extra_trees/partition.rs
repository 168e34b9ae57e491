//! Moving a split node's rows to its children (sklearn's `DensePartitioner`): a stable partition
//! of every column into the other buffer, which also takes each child's feature ranges.

#[cfg(target_arch = "x86_64")]
use super::kernels::avx512;
use super::kernels::portable;
use super::splitter::Split;

/// A range with +0.0 for −0.0, so that it does not depend on the order the extrema were taken in
/// (min/max of ±0 return either).
#[inline(always)]
pub(super) fn canonical((lo, hi): (f32, f32)) -> (f32, f32) {
    (lo + 0.0, hi + 0.0)
}

/// The partition's scratch memory and the children's ranges it takes (part of a workspace).
pub(super) struct Partitioner {
    /// Where the portable partition sends each row of the node, relative to its start.
    pos: Vec<u32>,
    /// Which rows go left, 16 per mask (AVX-512 partition).
    masks: Vec<u16>,
    /// The children's ranges of the node being split (of the last partition that moved every
    /// column).
    pub(super) left_ranges: Vec<(f32, f32)>,
    pub(super) right_ranges: Vec<(f32, f32)>,
}

impl Partitioner {
    /// For nodes of up to `n` rows on `d` features.
    pub(super) fn new(d: usize, n: usize) -> Self {
        Partitioner {
            pos: vec![0; n],
            masks: vec![0; n.div_ceil(16)],
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
    /// row indices `rows`, when tracked. `WIDE` selects the AVX-512 kernels; see
    /// [`super::builder::build_tree_impl`].
    #[inline(always)]
    pub(super) fn partition<'a, const WIDE: bool>(
        &mut self,
        key: &[f32],
        split: &Split,
        columns: impl Iterator<Item = (&'a [f32], &'a mut [f32])>,
        ys: (&[f64], &mut [f64]),
        rows: Option<(&[u32], &mut [u32])>,
    ) {
        let n = key.len();
        #[cfg(target_arch = "x86_64")]
        if WIDE {
            let masks = &mut self.masks[..n.div_ceil(16)];
            // SAFETY: WIDE is only set in build_tree_avx512, called after detecting the features.
            unsafe {
                avx512::left_masks(key, split.thr, masks);
                for (f, (src, dst)) in columns.enumerate() {
                    let (l, r) = avx512::partition_min_max(src, dst, masks, split.n_left);
                    (self.left_ranges[f], self.right_ranges[f]) = (canonical(l), canonical(r));
                }
                avx512::partition(ys.0, ys.1, masks, split.n_left);
                if let Some((src, dst)) = rows {
                    avx512::partition(src, dst, masks, split.n_left);
                }
            }
            return;
        }
        let pos = &mut self.pos[..n];
        portable::positions(key, split.thr, split.n_left, pos);
        for (f, (src, dst)) in columns.enumerate() {
            portable::scatter(src, dst, pos);
            let (l, r) = dst.split_at(split.n_left);
            (self.left_ranges[f], self.right_ranges[f]) =
                (canonical(portable::min_max(l)), canonical(portable::min_max(r)));
        }
        portable::scatter(ys.0, ys.1, pos);
        if let Some((src, dst)) = rows {
            portable::scatter(src, dst, pos);
        }
    }
}
