//! Scalar kernels, and the reference for the summation order of the AVX-512 ones: a sum over rows
//! is kept in lanes, lane k taking the rows ≡ k modulo the lane count (16 or 32), so a vector
//! kernel adds in the same order (its padding lanes add +0.0, which changes nothing).

use crate::learn::extra_trees::criterion::{LeftSums, finish_mean_var};

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
