//! A fitted tree: its nodes in one flat array, the step of a walk, and the storage model files keep
//! (sklearn's `_tree`).

use super::ExtraTrees;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// Marks a leaf in [`Node::feat`].
pub(super) const LEAF: u32 = 1 << 31;

/// A tree node (16 bytes). Internal: a row goes to `left` iff `x[feat] <= val`, else to `left + 1`
/// (siblings are adjacent). Leaf: `feat == LEAF`, `left` is the leaf itself and `val` the
/// prediction, so that walking on from a leaf stays there (see [`Tree::step`]).
#[derive(Debug, Clone, Copy)]
#[repr(C)]
pub(super) struct Node {
    pub(super) val: f64,
    pub(super) feat: u32,
    pub(super) left: u32,
}

/// One tree, as a flat array with the root at 0.
#[derive(Debug, Clone)]
pub(super) struct Tree {
    pub(super) nodes: Vec<Node>,
    /// Training rows that reached each node.
    pub(super) counts: Vec<u32>,
    pub(super) depth: usize,
}

impl Node {
    pub(super) fn leaf(slot: usize, value: f64) -> Node {
        Node { val: value, feat: LEAF, left: slot as u32 }
    }

    pub(super) fn is_leaf(&self) -> bool {
        self.feat & LEAF != 0
    }
}

impl Tree {
    /// One step down from node `i` (a leaf stays put). Branch-free, so several walks (trees or
    /// rows) interleave and their cache misses overlap, which a loop ending at the leaf prevents.
    #[inline(always)]
    pub(super) fn step(&self, i: u32, row: &[f64]) -> u32 {
        let node = &self.nodes[i as usize];
        let x = row[(node.feat & !LEAF) as usize];
        let internal = (node.feat >> 31) ^ 1;
        // Right unless x <= threshold (so NaN goes right, as `NaN as f32 <= t` is false).
        let right = (x <= node.val) as u32 ^ 1;
        node.left + (right & internal)
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
