//! Vectors of 16 rows, with one fixed meaning per operation.
//!
//! [`Arith`] is implemented for `f32` (one row), for [`Portable`] (16 plain `f32` lanes), and on
//! x86-64 for [`Avx512`] and [`Avx2`], on aarch64 for `Neon`. Every implementation performs exactly the same IEEE
//! operation on each lane — fused multiply-adds as fused, the same selects, the same integer bit
//! tricks — so the kernels built on them give the same bits on every CPU; only the speed differs.
//! Data movement ([`Lanes::gather`], [`Lanes::gather8`]) may use any instructions: it is exact.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// Rows per vector.
pub const LANES: usize = 16;

/// Storage of one value for each of 16 rows, aligned for vector loads.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct V(pub [f32; LANES]);

impl V {
    /// All lanes zero.
    pub const ZERO: V = V([0.0; LANES]);
}

/// Lane-wise arithmetic.
pub trait Arith: Copy {
    /// Every lane `x`.
    fn splat(x: f32) -> Self;
    /// `a + b`.
    fn add(self, b: Self) -> Self;
    /// `a − b`.
    fn sub(self, b: Self) -> Self;
    /// `a · b`.
    fn mul(self, b: Self) -> Self;
    /// `a · b + c`, rounded once.
    fn fma(self, b: Self, c: Self) -> Self;
    /// `a · b − c`, rounded once.
    fn fms(self, b: Self, c: Self) -> Self;
    /// `c − a · b`, rounded once.
    fn fnma(self, b: Self, c: Self) -> Self;
    /// `if a > b { a } else { b }` (x86 `maxps`: NaN in `a` gives `b`).
    fn max(self, b: Self) -> Self;
    /// `if a < b { a } else { b }` (x86 `minps`).
    fn min(self, b: Self) -> Self;
    /// `if a > 0 { x } else { 0 }`.
    fn if_pos(self, x: Self) -> Self;
    /// `2⁻ⁿ` for `a = n + 1.5·2²³` with integer `n` in [−126, 127], by building the exponent bits.
    fn pow2_neg_from_rounded(self) -> Self;
    /// A first guess of `1/a` for positive normal `a`, within 12 %: `from_bits(0x7EF311C3 − bits(a))`.
    fn recip_guess(self) -> Self;
}

/// Sixteen `u32` lanes with wrapping integer operations (for the ChaCha generator in `shuffle`).
pub trait Words: Copy {
    /// Reads 16 words.
    fn load(w: &[u32; LANES]) -> Self;
    /// Writes 16 words.
    fn store(self, w: &mut [u32; LANES]);
    /// Wrapping `a + b`.
    fn add(self, b: Self) -> Self;
    /// `(a ^ b)` rotated left by `R` bits.
    fn xor_rotl<const R: u32>(self, b: Self) -> Self;
}

impl Words for [u32; LANES] {
    #[inline(always)]
    fn load(w: &[u32; LANES]) -> Self {
        *w
    }
    #[inline(always)]
    fn store(self, w: &mut [u32; LANES]) {
        *w = self;
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        let mut o = self;
        for l in 0..LANES {
            o[l] = self[l].wrapping_add(b[l]);
        }
        o
    }
    #[inline(always)]
    fn xor_rotl<const R: u32>(self, b: Self) -> Self {
        let mut o = self;
        for l in 0..LANES {
            o[l] = (self[l] ^ b[l]).rotate_left(R);
        }
        o
    }
}

/// [`Arith`] over the 16 lanes of a [`V`], with loads and stores.
pub trait Lanes: Arith {
    /// The integer vectors of the same build.
    type Words: Words;

    /// Output units per register tile of `kernels::dense` and `kernels::outer` (at most 5).
    /// Tiles only group independent sums, each still summed in its fixed order, so these sizes
    /// change the speed, never the bits; each build picks what fits its registers.
    const TILE_OUT: usize = 5;
    /// Vectors per tile of `kernels::dense` (4 or 1).
    const TILE_VECS: usize = 4;
    /// Inputs per tile of `kernels::outer` (at most 4).
    const TILE_INPUTS: usize = 4;
    /// Vectors activated together in `kernels::activate` (4, 2 or 1).
    const ACT_GROUP: usize = 4;
    /// Independent FMA chains that measure the build's peak (`peak`): enough to cover the FMA
    /// latency on two ports, few enough to stay in registers.
    const PEAK_CHAINS: usize = 24;

    /// Reads a vector.
    fn load(v: &V) -> Self;
    /// Writes a vector.
    fn store(self, v: &mut V);

    /// Lane `l` is `base[at[l]]`.
    ///
    /// # Safety
    /// Every `at[l]` is a valid index of `base`.
    #[inline(always)]
    unsafe fn gather(base: &[f32], at: &[i32; LANES]) -> Self {
        let mut o = V::ZERO;
        for (x, &i) in o.0.iter_mut().zip(at) {
            // SAFETY: the caller's contract.
            *x = unsafe { *base.get_unchecked(i as usize) };
        }
        Self::load(&o)
    }

    /// Vector `k` holds value `k` of the 8-value rows starting at `base[at[l]]`: a transpose.
    ///
    /// # Safety
    /// Every `at[l]` is a multiple of 8 and `at[l] + 8 ≤ base.len()`.
    #[inline(always)]
    unsafe fn gather8(base: &[f32], at: &[i32; LANES]) -> [Self; 8] {
        let mut at = *at;
        let mut out = [Self::splat(0.0); 8];
        for o in &mut out {
            // SAFETY: the caller's contract covers the 8 values of each row.
            *o = unsafe { Self::gather(base, &at) };
            for a in &mut at {
                *a += 1;
            }
        }
        out
    }
}

/// Bits from which those of `a` are subtracted for a guess of `1/a`.
pub(super) const RECIP_MAGIC: i32 = 0x7EF3_11C3;

/// Bits from which a rounded value `n + 1.5·2²³` is subtracted for the biased exponent of `2⁻ⁿ`.
pub(super) const POW2_NEG_BIAS: i32 = 127 + 0x4B40_0000;

impl Arith for f32 {
    #[inline(always)]
    fn splat(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn add(self, b: f32) -> f32 {
        self + b
    }
    #[inline(always)]
    fn sub(self, b: f32) -> f32 {
        self - b
    }
    #[inline(always)]
    fn mul(self, b: f32) -> f32 {
        self * b
    }
    #[inline(always)]
    fn fma(self, b: f32, c: f32) -> f32 {
        fused(self, b, c)
    }
    #[inline(always)]
    fn fms(self, b: f32, c: f32) -> f32 {
        fused(self, b, -c)
    }
    #[inline(always)]
    fn fnma(self, b: f32, c: f32) -> f32 {
        fused(-self, b, c)
    }
    #[inline(always)]
    fn max(self, b: f32) -> f32 {
        if self > b { self } else { b }
    }
    #[inline(always)]
    fn min(self, b: f32) -> f32 {
        if self < b { self } else { b }
    }
    #[inline(always)]
    fn if_pos(self, x: f32) -> f32 {
        if self > 0.0 { x } else { 0.0 }
    }
    #[inline(always)]
    fn pow2_neg_from_rounded(self) -> f32 {
        f32::from_bits(POW2_NEG_BIAS.wrapping_sub(self.to_bits() as i32).wrapping_shl(23) as u32)
    }
    #[inline(always)]
    fn recip_guess(self) -> f32 {
        f32::from_bits(RECIP_MAGIC.wrapping_sub(self.to_bits() as i32) as u32)
    }
}

/// `a·b + c` rounded once: the instruction where the build targets one (aarch64, or x86-64 built
/// with FMA), else exact software that vectorises (`f32::mul_add` would call the C library's
/// `fmaf` once per lane).
#[inline(always)]
fn fused(a: f32, b: f32, c: f32) -> f32 {
    #[cfg(all(target_arch = "x86_64", not(target_feature = "fma")))]
    return super::softfma::fma(a, b, c);
    #[cfg(not(all(target_arch = "x86_64", not(target_feature = "fma"))))]
    return a.mul_add(b, c);
}

/// Sixteen lanes as plain `f32` operations: the reference the other implementations match, and
/// the build for CPUs without AVX2 and FMA.
#[derive(Clone, Copy)]
pub struct Portable([f32; LANES]);

/// `G` values stepped through the same operations together (each keeps its own arithmetic).
/// For vectors this interleaves independent dependency chains, which lets the CPU overlap their
/// latencies; [`Portable`] is `Multi<f32, 16>`.
#[derive(Clone, Copy)]
pub struct Multi<A, const G: usize>(pub [A; G]);

macro_rules! multi_op {
    ($name:ident($($b:ident),*)) => {
        #[inline(always)]
        fn $name(self $(, $b: Self)*) -> Self {
            let mut o = self.0;
            for g in 0..G {
                o[g] = self.0[g].$name($($b.0[g]),*);
            }
            Multi(o)
        }
    };
}

impl<A: Arith, const G: usize> Arith for Multi<A, G> {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Multi([A::splat(x); G])
    }
    multi_op!(add(b));
    multi_op!(sub(b));
    multi_op!(mul(b));
    multi_op!(fma(b, c));
    multi_op!(fms(b, c));
    multi_op!(fnma(b, c));
    multi_op!(max(b));
    multi_op!(min(b));
    multi_op!(if_pos(x));
    multi_op!(pow2_neg_from_rounded());
    multi_op!(recip_guess());
}

macro_rules! portable_op {
    ($name:ident($($b:ident),*)) => {
        #[inline(always)]
        fn $name(self $(, $b: Self)*) -> Self {
            Portable(Multi(self.0).$name($(Multi($b.0)),*).0)
        }
    };
}

impl Arith for Portable {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Portable([x; LANES])
    }
    portable_op!(add(b));
    portable_op!(sub(b));
    portable_op!(mul(b));
    portable_op!(fma(b, c));
    portable_op!(fms(b, c));
    portable_op!(fnma(b, c));
    portable_op!(max(b));
    portable_op!(min(b));
    portable_op!(if_pos(x));
    portable_op!(pow2_neg_from_rounded());
    portable_op!(recip_guess());
}

impl Lanes for Portable {
    type Words = [u32; LANES];
    #[inline(always)]
    fn load(v: &V) -> Self {
        Portable(v.0)
    }
    #[inline(always)]
    fn store(self, v: &mut V) {
        v.0 = self.0;
    }
}

/// Sixteen lanes in one AVX-512 register.
///
/// SAFETY (for this type and [`Avx2`]): values only exist inside kernels instantiated in
/// functions compiled with, and called after checking, the matching CPU features (see
/// [`Isa`]), so the intrinsics below always run on a CPU that has them.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct Avx512(__m512);

#[cfg(target_arch = "x86_64")]
macro_rules! avx512_op {
    ($name:ident, $f:ident($($b:ident),*)) => {
        #[inline(always)]
        fn $name(self $(, $b: Self)*) -> Self {
            // SAFETY: see the type.
            Avx512(unsafe { $f(self.0 $(, $b.0)*) })
        }
    };
}

#[cfg(target_arch = "x86_64")]
impl Arith for Avx512 {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        // SAFETY: see the type.
        Avx512(unsafe { _mm512_set1_ps(x) })
    }
    avx512_op!(add, _mm512_add_ps(b));
    avx512_op!(sub, _mm512_sub_ps(b));
    avx512_op!(mul, _mm512_mul_ps(b));
    avx512_op!(fma, _mm512_fmadd_ps(b, c));
    avx512_op!(fms, _mm512_fmsub_ps(b, c));
    avx512_op!(fnma, _mm512_fnmadd_ps(b, c));
    avx512_op!(max, _mm512_max_ps(b));
    avx512_op!(min, _mm512_min_ps(b));
    #[inline(always)]
    fn if_pos(self, x: Self) -> Self {
        // SAFETY: see the type.
        unsafe {
            let m = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, _mm512_setzero_ps());
            Avx512(_mm512_maskz_mov_ps(m, x.0))
        }
    }
    #[inline(always)]
    fn pow2_neg_from_rounded(self) -> Self {
        // SAFETY: see the type.
        unsafe {
            let e = _mm512_sub_epi32(_mm512_set1_epi32(POW2_NEG_BIAS), _mm512_castps_si512(self.0));
            Avx512(_mm512_castsi512_ps(_mm512_slli_epi32::<23>(e)))
        }
    }
    #[inline(always)]
    fn recip_guess(self) -> Self {
        // SAFETY: see the type.
        unsafe {
            let g = _mm512_sub_epi32(_mm512_set1_epi32(RECIP_MAGIC), _mm512_castps_si512(self.0));
            Avx512(_mm512_castsi512_ps(g))
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl Words for __m512i {
    #[inline(always)]
    fn load(w: &[u32; LANES]) -> Self {
        // SAFETY: see `Avx512` (only used by its kernels).
        unsafe { _mm512_loadu_si512(w.as_ptr().cast()) }
    }
    #[inline(always)]
    fn store(self, w: &mut [u32; LANES]) {
        // SAFETY: as in `load`.
        unsafe { _mm512_storeu_si512(w.as_mut_ptr().cast(), self) }
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        // SAFETY: as in `load`.
        unsafe { _mm512_add_epi32(self, b) }
    }
    #[inline(always)]
    fn xor_rotl<const R: u32>(self, b: Self) -> Self {
        // SAFETY: as in `load`.
        unsafe { _mm512_rolv_epi32(_mm512_xor_si512(self, b), _mm512_set1_epi32(R as i32)) }
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes for Avx512 {
    type Words = __m512i;
    #[inline(always)]
    fn load(v: &V) -> Self {
        // SAFETY: see the type; `V` is 64-byte aligned.
        Avx512(unsafe { _mm512_load_ps(v.0.as_ptr()) })
    }
    #[inline(always)]
    fn store(self, v: &mut V) {
        // SAFETY: as in `load`.
        unsafe { _mm512_store_ps(v.0.as_mut_ptr(), self.0) }
    }
    #[inline(always)]
    unsafe fn gather(base: &[f32], at: &[i32; LANES]) -> Self {
        // SAFETY: see the type; the caller's contract bounds every index.
        unsafe {
            let idx = _mm512_loadu_si512(at.as_ptr().cast());
            Avx512(_mm512_i32gather_ps::<4>(idx, base.as_ptr()))
        }
    }
    /// A register transpose: rows `l` and `l + 8` share a register, an 8×8 transpose runs on
    /// both halves at once, and two-source permutes put the four quarters in row order. About
    /// 32 shuffles per 16 rows, several times faster than eight hardware gathers.
    #[inline(always)]
    unsafe fn gather8(base: &[f32], at: &[i32; LANES]) -> [Self; 8] {
        // SAFETY: see the type; the caller's contract bounds every row.
        unsafe {
            let mut a = [_mm512_setzero_ps(); 8];
            for (i, ai) in a.iter_mut().enumerate() {
                let lo = _mm256_castps_pd(_mm256_loadu_ps(base.as_ptr().add(at[i] as usize)));
                let hi = _mm256_castps_pd(_mm256_loadu_ps(base.as_ptr().add(at[i + 8] as usize)));
                *ai = _mm512_castpd_ps(_mm512_insertf64x4::<1>(_mm512_castpd256_pd512(lo), hi));
            }
            let mut u = [_mm512_setzero_ps(); 8];
            for h in 0..2 {
                let r = &a[4 * h..4 * h + 4];
                let t0 = _mm512_unpacklo_ps(r[0], r[1]);
                let t1 = _mm512_unpackhi_ps(r[0], r[1]);
                let t2 = _mm512_unpacklo_ps(r[2], r[3]);
                let t3 = _mm512_unpackhi_ps(r[2], r[3]);
                u[4 * h] = _mm512_shuffle_ps::<0x44>(t0, t2);
                u[4 * h + 1] = _mm512_shuffle_ps::<0xEE>(t0, t2);
                u[4 * h + 2] = _mm512_shuffle_ps::<0x44>(t1, t3);
                u[4 * h + 3] = _mm512_shuffle_ps::<0xEE>(t1, t3);
            }
            // u[k] (k < 4) holds value k of rows 0–3 | value k+4 of rows 0–3 | value k of rows
            // 8–11 | value k+4 of rows 8–11; u[k + 4] the same for rows 4–7 and 12–15.
            let lo = _mm512_setr_epi32(0, 1, 2, 3, 16, 17, 18, 19, 8, 9, 10, 11, 24, 25, 26, 27);
            let hi = _mm512_setr_epi32(4, 5, 6, 7, 20, 21, 22, 23, 12, 13, 14, 15, 28, 29, 30, 31);
            let mut out = [Avx512(_mm512_setzero_ps()); 8];
            for k in 0..4 {
                out[k] = Avx512(_mm512_permutex2var_ps(u[k], lo, u[k + 4]));
                out[k + 4] = Avx512(_mm512_permutex2var_ps(u[k], hi, u[k + 4]));
            }
            out
        }
    }
}

/// Sixteen lanes in two AVX2 registers (safety as for [`Avx512`]).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct Avx2([__m256; 2]);

#[cfg(target_arch = "x86_64")]
macro_rules! avx2_op {
    ($name:ident, $f:ident($($b:ident),*)) => {
        #[inline(always)]
        fn $name(self $(, $b: Self)*) -> Self {
            // SAFETY: see `Avx512`.
            unsafe { Avx2([$f(self.0[0] $(, $b.0[0])*), $f(self.0[1] $(, $b.0[1])*)]) }
        }
    };
}

#[cfg(target_arch = "x86_64")]
impl Arith for Avx2 {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        // SAFETY: see `Avx512`.
        let r = unsafe { _mm256_set1_ps(x) };
        Avx2([r, r])
    }
    avx2_op!(add, _mm256_add_ps(b));
    avx2_op!(sub, _mm256_sub_ps(b));
    avx2_op!(mul, _mm256_mul_ps(b));
    avx2_op!(fma, _mm256_fmadd_ps(b, c));
    avx2_op!(fms, _mm256_fmsub_ps(b, c));
    avx2_op!(fnma, _mm256_fnmadd_ps(b, c));
    avx2_op!(max, _mm256_max_ps(b));
    avx2_op!(min, _mm256_min_ps(b));
    #[inline(always)]
    fn if_pos(self, x: Self) -> Self {
        // SAFETY: see `Avx512`.
        unsafe {
            let z = _mm256_setzero_ps();
            Avx2([
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(self.0[0], z), x.0[0]),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(self.0[1], z), x.0[1]),
            ])
        }
    }
    #[inline(always)]
    fn pow2_neg_from_rounded(self) -> Self {
        // SAFETY: see `Avx512`.
        unsafe {
            let b = _mm256_set1_epi32(POW2_NEG_BIAS);
            let e0 = _mm256_sub_epi32(b, _mm256_castps_si256(self.0[0]));
            let e1 = _mm256_sub_epi32(b, _mm256_castps_si256(self.0[1]));
            Avx2([_mm256_castsi256_ps(_mm256_slli_epi32::<23>(e0)), _mm256_castsi256_ps(_mm256_slli_epi32::<23>(e1))])
        }
    }
    #[inline(always)]
    fn recip_guess(self) -> Self {
        // SAFETY: see `Avx512`.
        unsafe {
            let m = _mm256_set1_epi32(RECIP_MAGIC);
            Avx2([
                _mm256_castsi256_ps(_mm256_sub_epi32(m, _mm256_castps_si256(self.0[0]))),
                _mm256_castsi256_ps(_mm256_sub_epi32(m, _mm256_castps_si256(self.0[1]))),
            ])
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl Words for [__m256i; 2] {
    #[inline(always)]
    fn load(w: &[u32; LANES]) -> Self {
        // SAFETY: see `Avx512` (only used by `Avx2` kernels).
        unsafe { [_mm256_loadu_si256(w.as_ptr().cast()), _mm256_loadu_si256(w.as_ptr().add(8).cast())] }
    }
    #[inline(always)]
    fn store(self, w: &mut [u32; LANES]) {
        // SAFETY: as in `load`.
        unsafe {
            _mm256_storeu_si256(w.as_mut_ptr().cast(), self[0]);
            _mm256_storeu_si256(w.as_mut_ptr().add(8).cast(), self[1]);
        }
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        // SAFETY: as in `load`.
        unsafe { [_mm256_add_epi32(self[0], b[0]), _mm256_add_epi32(self[1], b[1])] }
    }
    #[inline(always)]
    fn xor_rotl<const R: u32>(self, b: Self) -> Self {
        // SAFETY: as in `load`.
        unsafe {
            let (x0, x1) = (_mm256_xor_si256(self[0], b[0]), _mm256_xor_si256(self[1], b[1]));
            let (l, r) = (_mm_cvtsi32_si128(R as i32), _mm_cvtsi32_si128(32 - R as i32));
            [
                _mm256_or_si256(_mm256_sll_epi32(x0, l), _mm256_srl_epi32(x0, r)),
                _mm256_or_si256(_mm256_sll_epi32(x1, l), _mm256_srl_epi32(x1, r)),
            ]
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes for Avx2 {
    type Words = [__m256i; 2];
    // A vector is two of the 16 ymm registers (AVX-512 has 32 zmm, one per vector): the shared
    // 5 × 4 tile would hold 40 accumulators and spill. 5 × 1 keeps 10 accumulators, the inputs
    // and a broadcast weight in registers; `outer` 5 × 1 likewise, and activations two vectors
    // at a time (each polynomial step then has four independent ymm operations).
    const TILE_VECS: usize = 1;
    const TILE_INPUTS: usize = 1;
    const ACT_GROUP: usize = 2;
    const PEAK_CHAINS: usize = 6;
    #[inline(always)]
    fn load(v: &V) -> Self {
        // SAFETY: see `Avx512`; `V` is 64-byte aligned.
        unsafe { Avx2([_mm256_load_ps(v.0.as_ptr()), _mm256_load_ps(v.0.as_ptr().add(8))]) }
    }
    #[inline(always)]
    fn store(self, v: &mut V) {
        // SAFETY: as in `load`.
        unsafe {
            _mm256_store_ps(v.0.as_mut_ptr(), self.0[0]);
            _mm256_store_ps(v.0.as_mut_ptr().add(8), self.0[1]);
        }
    }
    #[inline(always)]
    unsafe fn gather(base: &[f32], at: &[i32; LANES]) -> Self {
        // SAFETY: see `Avx512`; the caller's contract bounds every index.
        unsafe {
            let i0 = _mm256_loadu_si256(at.as_ptr().cast());
            let i1 = _mm256_loadu_si256(at.as_ptr().add(8).cast());
            Avx2([_mm256_i32gather_ps::<4>(base.as_ptr(), i0), _mm256_i32gather_ps::<4>(base.as_ptr(), i1)])
        }
    }
}

/// The instruction-set level a pass is compiled for (see [`crate::learn::cpu`]). Only the speed
/// differs.
pub(crate) use crate::learn::cpu::Isa;

/// Defines `$name(isa, args…)` running `$body::<Lanes>(args…)` compiled for the level `isa`:
/// one copy per level, with the matching `target_feature`s, so the generic kernels inline into
/// it as AVX-512, AVX2 or baseline code.
macro_rules! multiversion {
    ($(#[$m:meta])* fn $name:ident($($p:ident: $t:ty),*) -> $r:ty = $body:ident) => {
        $(#[$m])*
        pub(crate) fn $name(isa: $crate::learn::mlp::lanes::Isa, $($p: $t),*) -> $r {
            use $crate::learn::mlp::lanes as lanes;
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
                fn avx512($($p: $t),*) -> $r {
                    $body::<lanes::Avx512>($($p),*)
                }
                #[target_feature(enable = "avx2,fma")]
                fn avx2($($p: $t),*) -> $r {
                    $body::<lanes::Avx2>($($p),*)
                }
                // The guards re-check the CPU (a cached load) so no `Isa` value can be unsound.
                match isa {
                    // SAFETY: the guard checked every feature `avx512` is compiled with.
                    lanes::Isa::Avx512 if isa.runs_mlp() => return unsafe { avx512($($p),*) },
                    // SAFETY: as above.
                    lanes::Isa::Avx2 if isa.runs_mlp() => return unsafe { avx2($($p),*) },
                    _ => {}
                }
            }
            // NEON is in every aarch64 CPU: no check, no `target_feature` function.
            #[cfg(target_arch = "aarch64")]
            if isa == lanes::Isa::Neon && isa.runs_mlp() {
                return $body::<$crate::learn::mlp::neon::Neon>($($p),*);
            }
            let _ = isa;
            $body::<lanes::Portable>($($p),*)
        }
    };
}
pub(crate) use multiversion;

/// Sum of the lanes in a fixed pairwise order.
#[inline(always)]
pub fn hsum(v: &V) -> f32 {
    let mut a = v.0;
    let mut w = LANES / 2;
    while w > 0 {
        for l in 0..w {
            a[l] += a[l + w];
        }
        w /= 2;
    }
    a[0]
}
