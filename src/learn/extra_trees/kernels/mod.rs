//! The builder's kernels: portable code, and AVX-512 code that gives the same bits.
//!
//! The builder is generic over [`Kernels`], so each implementation gets its own copy of it. An
//! implementation that needs CPU features can only be had from the CPU detection ([`Build`]), so
//! holding one proves the features are there: the `unsafe` that runs vector code stands where that
//! proof is used, not in the builder.

#[cfg(target_arch = "x86_64")]
pub(super) mod avx512;
pub(super) mod portable;

use super::criterion::{LeftSums, lanes_total};
use crate::learn::cpu::{self, Isa};

/// Where a split sends each row of its node, as the kernels note it for the moves
/// ([`Kernels::mark`]).
pub(super) struct Marks {
    /// Each row's destination, relative to the node's start (portable kernels).
    pub(super) pos: Vec<u32>,
    /// Which rows go left, 16 per mask (AVX-512 kernels; unread on other targets).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(super) masks: Vec<u16>,
}

/// The operations the builder's passes over a node's rows are made of. Every implementation gives
/// the same bits (sums in the lanes of [`portable`], exact partitions and extrema); only the speed
/// differs.
pub(super) trait Kernels: Copy {
    /// Whether [`Kernels::count_sum_node`] pays off for a node of at most one sweep step.
    const NODE_SUMS: bool;

    /// [`portable::mean_var`].
    fn mean_var(self, ys: &[f64]) -> (f64, f64);

    /// [`portable::count_sum_blocks`].
    fn count_sum_blocks(self, xs: &[f32], ys: &[f64], t: f32, s: &mut LeftSums);

    /// The rows of a whole node with `x <= t` and the sum of their targets: the lanes of
    /// [`Kernels::count_sum_blocks`] from zero, reduced by [`lanes_total`].
    fn count_sum_node(self, xs: &[f32], ys: &[f64], t: f32) -> (usize, f64);

    /// Notes in `marks` where a stable partition of a node's rows by `key <= t` sends each row
    /// (`n_left` rows go left), for the moves below.
    fn mark(self, key: &[f32], t: f32, n_left: usize, marks: &mut Marks);

    /// Moves a column of the node to `dst` as `marks` says, and returns the (min, max) of the rows
    /// sent left and of those sent right (both sides non-empty).
    fn move_column(self, src: &[f32], dst: &mut [f32], marks: &Marks, n_left: usize) -> ((f32, f32), (f32, f32));

    /// Moves the node's targets to `dst` as `marks` says.
    fn move_targets(self, src: &[f64], dst: &mut [f64], marks: &Marks, n_left: usize);

    /// Moves the node's row indices to `dst` as `marks` says.
    fn move_rows(self, src: &[u32], dst: &mut [u32], marks: &Marks, n_left: usize);
}

/// The portable kernels: plain loops, on any CPU.
#[derive(Debug, Clone, Copy)]
pub(super) struct Portable;

impl Kernels for Portable {
    const NODE_SUMS: bool = false;

    #[inline(always)]
    fn mean_var(self, ys: &[f64]) -> (f64, f64) {
        portable::mean_var(ys)
    }

    #[inline(always)]
    fn count_sum_blocks(self, xs: &[f32], ys: &[f64], t: f32, s: &mut LeftSums) {
        portable::count_sum_blocks(xs, ys, t, s);
    }

    #[inline(always)]
    fn count_sum_node(self, xs: &[f32], ys: &[f64], t: f32) -> (usize, f64) {
        let mut s = LeftSums::default();
        portable::count_sum_blocks(xs, ys, t, &mut s);
        (s.count, lanes_total(&s.lanes))
    }

    #[inline(always)]
    fn mark(self, key: &[f32], t: f32, n_left: usize, marks: &mut Marks) {
        portable::positions(key, t, n_left, &mut marks.pos[..key.len()]);
    }

    #[inline(always)]
    fn move_column(self, src: &[f32], dst: &mut [f32], marks: &Marks, n_left: usize) -> ((f32, f32), (f32, f32)) {
        portable::scatter(src, dst, &marks.pos[..src.len()]);
        let (l, r) = dst.split_at(n_left);
        (portable::min_max(l), portable::min_max(r))
    }

    #[inline(always)]
    fn move_targets(self, src: &[f64], dst: &mut [f64], marks: &Marks, _: usize) {
        portable::scatter(src, dst, &marks.pos[..src.len()]);
    }

    #[inline(always)]
    fn move_rows(self, src: &[u32], dst: &mut [u32], marks: &Marks, _: usize) {
        portable::scatter(src, dst, &marks.pos[..src.len()]);
    }
}

/// Proof that this CPU has AVX2, for the portable kernels compiled with it (the compiler
/// vectorises the extrema). The private field keeps it from being made but by [`Avx2::detect`].
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy)]
pub(super) struct Avx2 {
    _detected: (),
}

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// The proof, if this CPU has AVX2.
    fn detect() -> Option<Avx2> {
        Isa::Avx2.runs_extra_trees().then_some(Avx2 { _detected: () })
    }
}

/// A build of the tree builder that this CPU runs: which kernels, compiled with which features.
#[derive(Debug, Clone, Copy)]
pub(super) enum Build {
    /// [`Portable`], for the baseline CPU.
    Portable,
    /// [`Portable`], compiled with AVX2.
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    /// [`avx512::Avx512`].
    #[cfg(target_arch = "x86_64")]
    Avx512(avx512::Avx512),
}

impl Build {
    /// The build the trees use: the best this CPU runs, capped by `BFQI_ISA` (see [`cpu`]).
    pub(super) fn chosen() -> Build {
        Build::at(cpu::extra_trees()).unwrap_or(Build::Portable)
    }

    /// Every build this CPU runs, best first, whatever the cap.
    #[cfg(test)]
    pub(super) fn available() -> Vec<Build> {
        Isa::ALL.into_iter().filter_map(Build::at).collect()
    }

    /// The build of level `isa`, if this CPU runs it.
    fn at(isa: Isa) -> Option<Build> {
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => avx512::Avx512::detect().map(Build::Avx512),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => Avx2::detect().map(Build::Avx2),
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx512 | Isa::Avx2 => None,
            Isa::Neon => None,
            Isa::Portable => Some(Build::Portable),
        }
    }
}
