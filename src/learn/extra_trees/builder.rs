//! The depth-first tree builder (sklearn's `DepthFirstTreeBuilder`), the data it reads and the
//! scratch memory it reuses.

use super::ExtraTreesParams;
#[cfg(target_arch = "x86_64")]
use super::kernels::{Avx2, avx512::Avx512};
use super::kernels::{Build, Kernels, Portable, portable};
use super::partition::{Partitioner, canonical};
use super::routes::{NO_FORK, Record, Routes, record_leaf};
use super::splitter::{NodeRows, Splitter, query_threshold};
use super::tree::{LEAF, Node, Tree};
use crate::error::{Error, Result};
use crate::learn::Rows;
use crate::rng::Rng;

/// The training set as the trees read it: inputs in `f32`, column-major (`x[f * n + i]`).
pub(super) struct Data {
    pub(super) n: usize,
    pub(super) d: usize,
    pub(super) x: Vec<f32>,
    pub(super) y: Vec<f64>,
    /// `0..n` when the trees record each row's leaf (the row indices are partitioned with the
    /// columns), else empty.
    pub(super) idx: Vec<u32>,
    /// A leaf's fork is its first ancestor that splits on this column (`usize::MAX`: none).
    pub(super) fork_col: usize,
    /// Each column's (min, max): the root's ranges, the same for every tree, so taken once.
    pub(super) ranges: Vec<(f32, f32)>,
}

impl Data {
    pub(super) fn new(rows: Rows<'_>, y: &[f64], record: Record) -> Result<Self> {
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
                        "input {v:.3e} at row {i}, column {f} is too large for Extra-Trees (|x| ≤ {:e})",
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
pub(super) struct Workspace {
    /// Two copies of the columns: a node at odd depth reads `bx` and writes its children into `ax`,
    /// a node at even depth reads `ax` (the root reads [`Data`]) and writes into `bx`.
    ax: Vec<f32>,
    bx: Vec<f32>,
    ay: Vec<f64>,
    by: Vec<f64>,
    /// Row indices, partitioned like the columns (only when [`Data::idx`] is set).
    ai: Vec<u32>,
    bi: Vec<u32>,
    splitter: Splitter,
    partitioner: Partitioner,
    stack: Vec<Pending>,
    /// Each pending node's per-feature (min, max), `d` entries per node in stack order: a split
    /// computes its children's while it partitions them, so no node reads its columns for them.
    ranges: Vec<(f32, f32)>,
}

thread_local! {
    /// The workspace of this thread's tree builds, kept from one fit to the next: FQI fits a forest
    /// on the same rows every iteration, and allocating a workspace (tens of MB, zeroed) for every
    /// rayon split of every fit cost a pendulum run ~3 % of its time in `memset`. It holds nothing
    /// a tree reads before writing, so reusing it changes no tree.
    static WORKSPACE: std::cell::RefCell<Option<Workspace>> = const { std::cell::RefCell::new(None) };
}

/// Calls `f` with this thread's workspace, (re)made when it is too small for `d` columns × `n` rows.
pub(super) fn with_workspace<T>(d: usize, n: usize, f: impl FnOnce(&mut Workspace) -> T) -> T {
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
        self.partitioner.n_features() == d && self.ay.len() >= n && self.ax.len() >= d * n
    }

    pub(super) fn new(d: usize, n: usize) -> Self {
        Workspace {
            ax: vec![0.0; d * n],
            bx: vec![0.0; d * n],
            ay: vec![0.0; n],
            by: vec![0.0; n],
            // Zeroed lazily by the allocator: untouched pages cost nothing when rows are not tracked.
            ai: vec![0; n],
            bi: vec![0; n],
            splitter: Splitter::new(d),
            partitioner: Partitioner::new(d, n),
            stack: Vec::new(),
            ranges: Vec::new(),
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

/// Builds one tree, with AVX-512 kernels when the CPU has them (and `BFQI_ISA` does not cap them,
/// see [`crate::learn::cpu`]). Every build makes the same tree: the kernels add in the same order
/// (explicit lanes), and partitions and extrema are exact.
///
/// When `data.idx` is set, `routes` gets each training row's leaf and each leaf's value and fork.
pub(super) fn build_tree(p: &ExtraTreesParams, data: &Data, ws: &mut Workspace, rng: Rng, routes: &mut Routes) -> Tree {
    build_tree_with(Build::chosen(), p, data, ws, rng, routes)
}

/// [`build_tree`] with the kernels of `build`.
pub(super) fn build_tree_with(
    build: Build,
    p: &ExtraTreesParams,
    data: &Data,
    ws: &mut Workspace,
    rng: Rng,
    routes: &mut Routes,
) -> Tree {
    match build {
        Build::Portable => build_tree_impl(Portable, p, data, ws, rng, routes),
        // SAFETY: `k` exists only if this CPU has every feature `build_tree_avx2` is compiled with.
        #[cfg(target_arch = "x86_64")]
        Build::Avx2(k) => unsafe { build_tree_avx2(k, p, data, ws, rng, routes) },
        // SAFETY: as above, for `build_tree_avx512`.
        #[cfg(target_arch = "x86_64")]
        Build::Avx512(k) => unsafe { build_tree_avx512(k, p, data, ws, rng, routes) },
    }
}

/// The builder compiled with the AVX-512 features (the set [`Avx512`] proves), so that the
/// kernels' intrinsics inline into it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,popcnt")]
fn build_tree_avx512(
    k: Avx512,
    p: &ExtraTreesParams,
    data: &Data,
    ws: &mut Workspace,
    rng: Rng,
    routes: &mut Routes,
) -> Tree {
    build_tree_impl(k, p, data, ws, rng, routes)
}

/// The portable kernels, compiled for AVX2 (the compiler vectorises the extrema).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn build_tree_avx2(
    _: Avx2,
    p: &ExtraTreesParams,
    data: &Data,
    ws: &mut Workspace,
    rng: Rng,
    routes: &mut Routes,
) -> Tree {
    build_tree_impl(Portable, p, data, ws, rng, routes)
}

/// The builder (sklearn's depth-first builder with its random splitter), on the kernels `k`.
#[inline(always)]
fn build_tree_impl<K: Kernels>(
    k: K,
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
    ws.splitter.start_tree(d);
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
        let (mean, var) = k.mean_var(ys);

        let mut best = None;
        // sklearn's leaf rules; `var <= EPSILON` is its "impurity ≈ 0".
        if n >= min_split && n >= 2 * min_leaf && depth < max_depth && var > f64::EPSILON {
            let node = NodeRows { x: src_x, n_all, start, ys };
            best = ws.splitter.node_split(k, &mut rng, node, &ws.ranges[r0..], mean, min_leaf);
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
        let columns = (src_x.chunks_exact(n_all).zip(dst_x.chunks_exact_mut(n_all)))
            .take(if move_x { d } else { 0 })
            .map(|(s, t)| (&s[start..end], &mut t[start..end]));
        let rows = if track { Some((&src_i[start..end], &mut dst_i[start..end])) } else { None };
        ws.partitioner.partition(k, key, &split, columns, (ys, &mut dst_y[start..end]), rows);

        let left = nodes.len();
        nodes[slot] = Node { val: query_threshold(split.thr), feat: split.feat as u32, left: left as u32 };
        nodes.extend([Node::leaf(left, 0.0), Node::leaf(left + 1, 0.0)]);
        counts.extend([n_left as u32, n_right as u32]);
        let mid = start + n_left;
        // Right pushed first so the left subtree is grown first (depth-first, as sklearn). Leaves
        // draw nothing from `rng`, so finishing them out of turn changes no later draw.
        let (left_ranges, right_ranges) = (&ws.partitioner.left_ranges, &ws.partitioner.right_ranges);
        for (child, leaf, rows, ranges) in
            [(left + 1, leaf_right, mid..end, right_ranges), (left, leaf_left, start..mid, left_ranges)]
        {
            if leaf {
                let mean = k.mean_var(&dst_y[rows.clone()]).0;
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
