//! AVX-512 kernels: the same results as [`super::portable`], bit for bit. A node's last partial
//! block of 16 rows is read with masked loads, so no row is handled by scalar code (small nodes
//! are many, and a scalar loop's unpredictable branches cost more than the vector work).

use super::Kernels;
use super::Marks;
use crate::learn::cpu::Isa;
use crate::learn::extra_trees::criterion::{LeftSums, mean_var_of_sums};
use std::arch::x86_64::*;

/// The AVX-512 kernels. Holding one proves that this CPU has every feature they are compiled with
/// (avx512f, avx512vl, avx512bw, avx512dq, popcnt: the set [`crate::learn::cpu`] checks): the
/// private field keeps it from being made but by [`Avx512::detect`].
#[derive(Debug, Clone, Copy)]
pub struct Avx512 {
    _detected: (),
}

impl Avx512 {
    /// The kernels, if this CPU runs them.
    pub fn detect() -> Option<Avx512> {
        Isa::Avx512.runs_extra_trees().then_some(Avx512 { _detected: () })
    }
}

impl Kernels for Avx512 {
    const NODE_SUMS: bool = true;

    #[inline(always)]
    fn mean_var(self, ys: &[f64]) -> (f64, f64) {
        // SAFETY: `self` proves the CPU has the features the function is compiled with.
        unsafe { mean_var(ys) }
    }

    #[inline(always)]
    fn count_sum_blocks(self, xs: &[f32], ys: &[f64], t: f32, s: &mut LeftSums) {
        // SAFETY: as above.
        unsafe { count_sum_blocks(xs, ys, t, s) }
    }

    #[inline(always)]
    fn count_sum_node(self, xs: &[f32], ys: &[f64], t: f32) -> (usize, f64) {
        // SAFETY: as above.
        unsafe { count_sum_node(xs, ys, t) }
    }

    #[inline(always)]
    fn mark(self, key: &[f32], t: f32, _: usize, marks: &mut Marks) {
        // SAFETY: as above.
        unsafe { left_masks(key, t, &mut marks.masks[..key.len().div_ceil(16)]) }
    }

    #[inline(always)]
    fn move_column(self, src: &[f32], dst: &mut [f32], marks: &Marks, n_left: usize) -> ((f32, f32), (f32, f32)) {
        // SAFETY: as above.
        unsafe { partition_min_max(src, dst, &marks.masks[..src.len().div_ceil(16)], n_left) }
    }

    #[inline(always)]
    fn move_targets(self, src: &[f64], dst: &mut [f64], marks: &Marks, n_left: usize) {
        // SAFETY: as above.
        unsafe { partition(src, dst, &marks.masks[..src.len().div_ceil(16)], n_left) }
    }

    #[inline(always)]
    fn move_rows(self, src: &[u32], dst: &mut [u32], marks: &Marks, n_left: usize) {
        // SAFETY: as above.
        unsafe { partition(src, dst, &marks.masks[..src.len().div_ceil(16)], n_left) }
    }
}

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

/// [`super::portable::mean_var`].
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
    // `criterion::finish_mean_var`'s reduction, in registers.
    let (s, q) = (hsum(_mm512_add_pd(s0, s1)), hsum(_mm512_add_pd(q0, q1)));
    mean_var_of_sums(y0, s, q, n)
}

/// [`hsum8`](crate::learn::extra_trees::criterion::hsum8) of a vector's lanes, by halving in
/// registers (the same order).
#[inline]
#[target_feature(enable = "avx512f")]
fn hsum(v: __m512d) -> f64 {
    // (v0+v4, v1+v5, v2+v6, v3+v7), then ((v0+v4)+(v2+v6), (v1+v5)+(v3+v7)), then their sum.
    let w = _mm256_add_pd(_mm512_castpd512_pd256(v), _mm512_extractf64x4_pd::<1>(v));
    let u = _mm_add_pd(_mm256_castpd256_pd128(w), _mm256_extractf128_pd::<1>(w));
    _mm_cvtsd_f64(_mm_add_sd(u, _mm_unpackhi_pd(u, u)))
}

/// [`super::portable::count_sum_blocks`].
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
/// [`super::portable::count_sum_blocks`] from zero, reduced in registers in the order of
/// [`lanes_total`](crate::learn::extra_trees::criterion::lanes_total).
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
    ((_mm512_reduce_min_ps(lo_l), _mm512_reduce_max_ps(hi_l)), (_mm512_reduce_min_ps(lo_r), _mm512_reduce_max_ps(hi_r)))
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

/// [`super::portable::positions`] + [`super::portable::scatter`]: stable partition of `src` into
/// `dst` by the `masks` of [`left_masks`] (`n_left` rows go left).
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
