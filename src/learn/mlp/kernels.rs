//! The arithmetic of the MLP: vectors of 16 rows, activation functions, and the small matrix
//! kernels of one chunk.
//!
//! Rows are processed 16 at a time, one row per lane. Kernels are generic over [`Lanes`], whose
//! implementations — AVX-512, AVX2, and plain `f32` loops — perform exactly the same IEEE
//! operation on each lane (fused multiply-add everywhere, same selects, no reassociation), and
//! every sum runs in a fixed order per lane. So a fit is bit-identical on every x86-64 CPU; only
//! the speed differs. Scalar code ([`Arith`] for `f32`) computes the same values for one row.
//!
//! Layout of a chunk buffer: feature-major, `buf[k * CHUNK + v]` holds feature (or unit) `k` of
//! the rows `16·v .. 16·v + 15` of the chunk.

use super::lanes::{Arith, Lanes, Multi, V};

/// Vectors per chunk (128 rows): a chunk's activations and deltas stay in L1. Results do not
/// depend on it (sums run per lane over the rows in batch order).
pub const CHUNK: usize = 8;

/// `e^−x`, after Cephes `expf`: `x = m·ln 2 + r` (Cody–Waite, ln 2 = 0.693359375 − 2.12194440·10⁻⁴),
/// `e^−r` by the degree-7 Taylor-like polynomial of `expf`, times `2⁻ᵐ` built in the exponent
/// bits. Relative error below 2·10⁻⁷; `x` is clamped to ±87 so the result stays a normal float.
/// Written for `e^−x` (the sigmoid's) so no negation is needed.
#[inline(always)]
pub fn exp_neg<A: Arith>(x: A) -> A {
    // Adding 1.5·2²³ rounds to an integer held in the low mantissa bits.
    const ROUND: f32 = 12_582_912.0;
    let x = x.max(A::splat(-87.0)).min(A::splat(87.0));
    let t = x.fma(A::splat(std::f32::consts::LOG2_E), A::splat(ROUND));
    let m = t.sub(A::splat(ROUND));
    // s = −r = m·ln 2 − x, exactly in the first part.
    let s = m.fms(A::splat(0.693_359_4), x);
    let s = m.fma(A::splat(-2.121_944_4e-4), s);
    let mut p = A::splat(1.987_569_2e-4);
    p = p.fma(s, A::splat(1.398_199_9e-3));
    p = p.fma(s, A::splat(8.333_452e-3));
    p = p.fma(s, A::splat(4.166_579_6e-2));
    p = p.fma(s, A::splat(1.666_666_5e-1));
    p = p.fma(s, A::splat(0.5));
    // e^s − 1 ≈ p·s² + s, and e^−x = (e^s − 1)·2⁻ᵐ + 2⁻ᵐ.
    let q = p.fma(s.mul(s), s);
    let scale = t.pow2_neg_from_rounded();
    q.fma(scale, scale)
}

/// `1/d` for positive normal `d`: three Newton steps `y ← y + y·(1 − d·y)` from
/// [`Arith::recip_guess`] square the relative error each time (0.12 → 4·10⁻⁸, plus rounding).
/// Seven operations, several times the throughput of a vector division.
#[inline(always)]
pub fn recip<A: Arith>(d: A) -> A {
    let one = A::splat(1.0);
    let mut y = d.recip_guess();
    for _ in 0..3 {
        y = y.fma(d.fnma(y, one), y);
    }
    y
}

/// The logistic function `1 / (1 + e^−x)`.
#[inline(always)]
pub fn sigmoid<A: Arith>(x: A) -> A {
    recip(exp_neg(x).add(A::splat(1.0)))
}

/// `tanh x` by Eigen's rational approximation (odd degree 13 over even degree 6, clamped where it
/// reaches ±1), accurate to a few ulp and relatively accurate near 0.
#[inline(always)]
pub fn tanh<A: Arith>(x: A) -> A {
    const CLAMP: f32 = 7.905_311;
    let x = x.max(A::splat(-CLAMP)).min(A::splat(CLAMP));
    let x2 = x.mul(x);
    let mut p = A::splat(-2.760_768_5e-16);
    p = p.fma(x2, A::splat(2.000_188e-13));
    p = p.fma(x2, A::splat(-8.604_672e-11));
    p = p.fma(x2, A::splat(5.122_297e-8));
    p = p.fma(x2, A::splat(1.485_722_4e-5));
    p = p.fma(x2, A::splat(6.372_619e-4));
    p = p.fma(x2, A::splat(4.893_524_6e-3));
    let mut q = A::splat(1.198_258_4e-6);
    q = q.fma(x2, A::splat(1.185_347_1e-4));
    q = q.fma(x2, A::splat(2.268_434_6e-3));
    q = q.fma(x2, A::splat(4.893_525e-3));
    x.mul(p).mul(recip(q))
}

/// Hidden-layer nonlinearity, as a value; [`with_act!`] turns it into its [`ActFn`] type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Act {
    /// [`Sigmoid`].
    Sigmoid,
    /// [`Tanh`].
    Tanh,
    /// [`Relu`].
    Relu,
}

/// Evaluates `$body` with `$f` bound to the [`ActFn`] value of `$act`, one copy per function.
macro_rules! with_act {
    ($act:expr, $f:ident => $body:expr) => {
        match $act {
            $crate::learn::mlp::kernels::Act::Sigmoid => {
                let $f = $crate::learn::mlp::kernels::Sigmoid;
                $body
            }
            $crate::learn::mlp::kernels::Act::Tanh => {
                let $f = $crate::learn::mlp::kernels::Tanh;
                $body
            }
            $crate::learn::mlp::kernels::Act::Relu => {
                let $f = $crate::learn::mlp::kernels::Relu;
                $body
            }
        }
    };
}
pub(crate) use with_act;

/// Applies `f` in place to the first `nv` vectors of each of `units` rows of a chunk buffer,
/// [`Lanes::ACT_GROUP`] vectors interleaved (see [`Multi`]).
#[inline(always)]
pub fn activate<L: Lanes, F: ActFn>(f: F, buf: &mut [V], units: usize, nv: usize) {
    match L::ACT_GROUP {
        1 => activate_in::<L, F, 1>(f, buf, units, nv),
        2 => activate_in::<L, F, 2>(f, buf, units, nv),
        _ => activate_in::<L, F, 4>(f, buf, units, nv),
    }
}

#[inline(always)]
fn activate_in<L: Lanes, F: ActFn, const G: usize>(f: F, buf: &mut [V], units: usize, nv: usize) {
    for u in 0..units {
        let row = &mut buf[u * CHUNK..u * CHUNK + nv];
        let mut groups = row.chunks_exact_mut(G);
        for grp in &mut groups {
            let mut z = Multi([L::splat(0.0); G]);
            for (zg, v) in z.0.iter_mut().zip(grp.iter()) {
                *zg = L::load(v);
            }
            for (a, v) in f.apply(z).0.iter().zip(grp.iter_mut()) {
                a.store(v);
            }
        }
        for v in groups.into_remainder() {
            f.apply(L::load(v)).store(v);
        }
    }
}

/// `if z > 0 { z } else { 0 }`.
#[inline(always)]
pub fn relu<A: Arith>(z: A) -> A {
    z.if_pos(z)
}

/// What [`dense`] does with each finished output vector `z` (unit `o`, vector `v`) before
/// storing it: fusing this into the kernel saves a pass over the chunk.
pub trait Finish: Copy {
    /// Panics unless `finish` may be called for every unit `o < n_out` and `v < CHUNK`.
    fn check(self, n_out: usize) {
        let _ = n_out;
    }
    /// The value to store.
    fn finish<L: Lanes>(self, z: L, o: usize, v: usize) -> L;
}

/// Stores the sums unchanged (the linear output, or the deltas of the inputs).
#[derive(Clone, Copy)]
pub struct Linear;

impl Finish for Linear {
    #[inline(always)]
    fn finish<L: Lanes>(self, z: L, _: usize, _: usize) -> L {
        z
    }
}

/// Multiplies by the derivative of `F` at the activations `a` (chunk layout): turns deltas of a
/// layer's outputs into deltas of its pre-activations.
#[derive(Clone, Copy)]
pub struct Backprop<'a, F> {
    /// Activations of the layer whose deltas are computed.
    pub a: &'a [V],
    /// The activation function.
    pub f: F,
}

impl<F: ActFn> Finish for Backprop<'_, F> {
    fn check(self, n_out: usize) {
        assert!(self.a.len() >= n_out * CHUNK);
    }
    #[inline(always)]
    fn finish<L: Lanes>(self, z: L, o: usize, v: usize) -> L {
        // SAFETY: `check` bounded every (o, v) that `dense` passes.
        self.f.backprop(z, L::load(unsafe { self.a.get_unchecked(o * CHUNK + v) }))
    }
}

/// An activation function as a type, so kernels are compiled for each one.
pub trait ActFn: Copy {
    /// The activation of a pre-activation `z`.
    fn apply<A: Arith>(self, z: A) -> A;
    /// `d` times the derivative at the unit whose activation is `a` (all three are functions of
    /// the output, as in TensorFlow's `SigmoidGrad`, `TanhGrad` and `ReluGrad`).
    fn backprop<A: Arith>(self, d: A, a: A) -> A;
}

/// The logistic function.
#[derive(Clone, Copy)]
pub struct Sigmoid;

impl ActFn for Sigmoid {
    #[inline(always)]
    fn apply<A: Arith>(self, z: A) -> A {
        sigmoid(z)
    }
    #[inline(always)]
    fn backprop<A: Arith>(self, d: A, a: A) -> A {
        d.mul(a.mul(A::splat(1.0).sub(a)))
    }
}

/// The hyperbolic tangent.
#[derive(Clone, Copy)]
pub struct Tanh;

impl ActFn for Tanh {
    #[inline(always)]
    fn apply<A: Arith>(self, z: A) -> A {
        tanh(z)
    }
    #[inline(always)]
    fn backprop<A: Arith>(self, d: A, a: A) -> A {
        d.mul(A::splat(1.0).sub(a.mul(a)))
    }
}

/// The rectified linear unit.
#[derive(Clone, Copy)]
pub struct Relu;

impl ActFn for Relu {
    #[inline(always)]
    fn apply<A: Arith>(self, z: A) -> A {
        relu(z)
    }
    #[inline(always)]
    fn backprop<A: Arith>(self, d: A, a: A) -> A {
        a.if_pos(d)
    }
}

/// A weight matrix seen through strides: `at(o, k) = w[o·so + k·sk]`, so one kernel serves the
/// forward pass (`W`) and the backward pass (`Wᵀ`).
#[derive(Clone, Copy)]
pub struct Mat<'a> {
    /// The values.
    pub w: &'a [f32],
    /// Stride between outputs.
    pub so: usize,
    /// Stride between summed inputs.
    pub sk: usize,
}

/// `out[o][v] = fin(init[o] + Σ_k at(o, k) · inp[k][v])` for `o < n_out`, `k < n_k`, `v < nv`:
/// one dense layer on a chunk. Each sum is a fused multiply-add chain in increasing `k`, starting
/// from `init[o]` (the bias) or 0 when `init` is `None`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn dense<L: Lanes, F: Finish>(
    m: Mat<'_>,
    init: Option<&[f32]>,
    n_out: usize,
    n_k: usize,
    inp: &[V],
    out: &mut [V],
    nv: usize,
    fin: F,
) {
    assert!(n_out >= 1 && n_k >= 1 && nv <= CHUNK);
    assert!(inp.len() >= n_k * CHUNK && out.len() >= n_out * CHUNK);
    assert!((n_out - 1) * m.so + (n_k - 1) * m.sk < m.w.len());
    if let Some(b) = init {
        assert!(b.len() >= n_out);
    }
    fin.check(n_out);
    let mut o0 = 0;
    while o0 < n_out {
        let mo = (n_out - o0).min(L::TILE_OUT);
        // Whole tiles of TILE_VECS vectors, then single vectors (only a batch's last chunk has a
        // tail).
        let mut v0 = 0;
        while v0 < nv {
            let nt = if nv - v0 >= L::TILE_VECS { L::TILE_VECS } else { 1 };
            macro_rules! tile {
                ($($a:literal $b:literal)*) => {
                    match (mo, nt) {
                        $(($a, $b) => dense_tile::<L, F, $a, $b>(m, init, n_k, o0, v0, inp, out, fin),)*
                        _ => unreachable!(),
                    }
                };
            }
            tile!(1 1 1 4 2 1 2 4 3 1 3 4 4 1 4 4 5 1 5 4);
            v0 += nt;
        }
        o0 += mo;
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn dense_tile<L: Lanes, F: Finish, const M: usize, const N: usize>(
    m: Mat<'_>,
    init: Option<&[f32]>,
    n_k: usize,
    o0: usize,
    v0: usize,
    inp: &[V],
    out: &mut [V],
    fin: F,
) {
    let mut acc = [[L::splat(0.0); N]; M];
    if let Some(b) = init {
        for (i, row) in acc.iter_mut().enumerate() {
            *row = [L::splat(b[o0 + i]); N];
        }
    }
    for k in 0..n_k {
        let mut x = [L::splat(0.0); N];
        for (j, xj) in x.iter_mut().enumerate() {
            // SAFETY: `dense` checked that every (k, v) is inside `inp`.
            *xj = L::load(unsafe { inp.get_unchecked(k * CHUNK + v0 + j) });
        }
        for (i, row) in acc.iter_mut().enumerate() {
            // SAFETY: `dense` checked that every (o, k) is inside `w`.
            let s = L::splat(unsafe { *m.w.get_unchecked((o0 + i) * m.so + k * m.sk) });
            for j in 0..N {
                row[j] = s.fma(x[j], row[j]);
            }
        }
    }
    for (i, row) in acc.iter().enumerate() {
        for (j, &z) in row.iter().enumerate() {
            // SAFETY: `dense` checked that every (o, v) is inside `out`.
            fin.finish(z, o0 + i, v0 + j).store(unsafe { out.get_unchecked_mut((o0 + i) * CHUNK + v0 + j) });
        }
    }
}

/// Accumulates one layer's gradient over a chunk, per lane: `g[o·n_in + i] ← fma(d[o][v],
/// a[i][v], ·)` and `gb[o] ← gb[o] + d[o][v]`, for `v` in increasing order. So each lane sums its
/// own rows in batch order, whatever the chunking.
#[inline(always)]
pub fn outer<L: Lanes>(d: &[V], a: &[V], n_out: usize, n_in: usize, nv: usize, g: &mut [V], gb: &mut [V]) {
    assert!(d.len() >= n_out * CHUNK && a.len() >= n_in * CHUNK && nv <= CHUNK);
    assert!(g.len() >= n_out * n_in && gb.len() >= n_out);
    let mut o0 = 0;
    while o0 < n_out {
        let mo = (n_out - o0).min(L::TILE_OUT);
        let mut i0 = 0;
        while i0 < n_in {
            let mi = (n_in - i0).min(L::TILE_INPUTS);
            macro_rules! tile {
                ($($a:literal $b:literal)*) => {
                    match (mo, mi) {
                        $(($a, $b) => outer_tile::<L, $a, $b>(d, a, n_in, o0, i0, nv, g),)*
                        _ => unreachable!(),
                    }
                };
            }
            tile!(1 1 1 2 1 3 1 4 2 1 2 2 2 3 2 4 3 1 3 2 3 3 3 4 4 1 4 2 4 3 4 4 5 1 5 2 5 3 5 4);
            i0 += mi;
        }
        // The bias sums of these units, interleaved so their add chains overlap (a tile per
        // count, so the sums stay in registers).
        match mo {
            1 => bias_tile::<L, 1>(d, o0, nv, gb),
            2 => bias_tile::<L, 2>(d, o0, nv, gb),
            3 => bias_tile::<L, 3>(d, o0, nv, gb),
            4 => bias_tile::<L, 4>(d, o0, nv, gb),
            5 => bias_tile::<L, 5>(d, o0, nv, gb),
            _ => unreachable!(),
        }
        o0 += mo;
    }
}

/// `gb[o0 + m] ← gb[o0 + m] + d[o0 + m][v]` for `m < M`, `v < nv` in increasing order.
#[inline(always)]
fn bias_tile<L: Lanes, const M: usize>(d: &[V], o0: usize, nv: usize, gb: &mut [V]) {
    let mut acc = [L::splat(0.0); M];
    for (m, x) in acc.iter_mut().enumerate() {
        *x = L::load(&gb[o0 + m]);
    }
    for v in 0..nv {
        for (m, x) in acc.iter_mut().enumerate() {
            // SAFETY: `outer` checked the extent of `d` for every unit and v < nv ≤ CHUNK.
            *x = x.add(L::load(unsafe { d.get_unchecked((o0 + m) * CHUNK + v) }));
        }
    }
    for (m, x) in acc.iter().enumerate() {
        x.store(&mut gb[o0 + m]);
    }
}

#[inline(always)]
fn outer_tile<L: Lanes, const M: usize, const N: usize>(
    d: &[V],
    a: &[V],
    n_in: usize,
    o0: usize,
    i0: usize,
    nv: usize,
    g: &mut [V],
) {
    let mut acc = [[L::splat(0.0); N]; M];
    // SAFETY (all unchecked accesses): `outer` checked the extents of `d`, `a` and `g` for every
    // unit, input and v < nv.
    for (o, row) in acc.iter_mut().enumerate() {
        for (i, x) in row.iter_mut().enumerate() {
            *x = L::load(unsafe { g.get_unchecked((o0 + o) * n_in + i0 + i) });
        }
    }
    for v in 0..nv {
        let (mut dv, mut av) = ([L::splat(0.0); M], [L::splat(0.0); N]);
        for (o, x) in dv.iter_mut().enumerate() {
            *x = L::load(unsafe { d.get_unchecked((o0 + o) * CHUNK + v) });
        }
        for (i, x) in av.iter_mut().enumerate() {
            *x = L::load(unsafe { a.get_unchecked((i0 + i) * CHUNK + v) });
        }
        for o in 0..M {
            for i in 0..N {
                acc[o][i] = dv[o].fma(av[i], acc[o][i]);
            }
        }
    }
    for (o, row) in acc.iter().enumerate() {
        for (i, x) in row.iter().enumerate() {
            x.store(unsafe { g.get_unchecked_mut((o0 + o) * n_in + i0 + i) });
        }
    }
}
