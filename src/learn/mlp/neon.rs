//! Sixteen lanes in four NEON registers: the aarch64 level (Apple Silicon, Graviton, Ampere).
//!
//! Each operation is the IEEE operation [`Arith`] names, as on x86: `vfmaq_f32`/`vfmsq_f32` are
//! fused, and `max`/`min` are a compare and a select rather than NEON's `fmax`/`fmin`, which
//! return NaN for a NaN operand and order −0 below +0 where x86's `maxps` returns its second
//! operand. So the kernels give the same bits here as on every other level.
//!
//! NEON is part of the aarch64 baseline (every aarch64 CPU and Rust target has it), so this
//! level needs no detection and no `target_feature` function.

use super::lanes::{Arith, LANES, Lanes, POW2_NEG_BIAS, RECIP_MAGIC, V, Words};
use std::arch::aarch64::*;

/// Sixteen lanes as four `float32x4_t`, lanes 0–3 in the first.
#[derive(Clone, Copy)]
pub struct Neon([float32x4_t; 4]);

/// An operation on the four registers one by one: `op(x, b…) => e` computes `e` from register
/// `i` of `self` (named `x`) and of each operand.
macro_rules! neon_op {
    ($name:ident($x:ident $(, $v:ident)*) => $e:expr) => {
        #[inline(always)]
        fn $name(self $(, $v: Self)*) -> Self {
            Neon(std::array::from_fn(|i| {
                let $x = self.0[i];
                $(let $v = $v.0[i];)*
                // SAFETY: NEON is in the aarch64 baseline; these intrinsics only compute.
                unsafe { $e }
            }))
        }
    };
}

impl Arith for Neon {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        // SAFETY: see `neon_op`.
        Neon([unsafe { vdupq_n_f32(x) }; 4])
    }
    neon_op!(add(x, b) => vaddq_f32(x, b));
    neon_op!(sub(x, b) => vsubq_f32(x, b));
    neon_op!(mul(x, b) => vmulq_f32(x, b));
    // vfmaq_f32(c, a, b) = c + a·b, rounded once.
    neon_op!(fma(x, b, c) => vfmaq_f32(c, x, b));
    // a·b − c = a·b + (−c): negation is exact, so this is x86's fmsub.
    neon_op!(fms(x, b, c) => vfmaq_f32(vnegq_f32(c), x, b));
    // vfmsq_f32(c, a, b) = c − a·b, rounded once.
    neon_op!(fnma(x, b, c) => vfmsq_f32(c, x, b));
    neon_op!(max(x, b) => vbslq_f32(vcgtq_f32(x, b), x, b));
    neon_op!(min(x, b) => vbslq_f32(vcltq_f32(x, b), x, b));
    neon_op!(if_pos(x, v) => vreinterpretq_f32_u32(vandq_u32(vcgtq_f32(x, vdupq_n_f32(0.0)), vreinterpretq_u32_f32(v))));
    neon_op!(pow2_neg_from_rounded(x) => {
        let e = vsubq_s32(vdupq_n_s32(POW2_NEG_BIAS), vreinterpretq_s32_f32(x));
        vreinterpretq_f32_s32(vshlq_n_s32::<23>(e))
    });
    neon_op!(recip_guess(x) => vreinterpretq_f32_s32(vsubq_s32(vdupq_n_s32(RECIP_MAGIC), vreinterpretq_s32_f32(x))));
}

impl Words for [uint32x4_t; 4] {
    #[inline(always)]
    fn load(w: &[u32; LANES]) -> Self {
        // SAFETY: each load reads 4 of the 16 words.
        std::array::from_fn(|i| unsafe { vld1q_u32(w.as_ptr().add(4 * i)) })
    }
    #[inline(always)]
    fn store(self, w: &mut [u32; LANES]) {
        for (i, r) in self.into_iter().enumerate() {
            // SAFETY: each store writes 4 of the 16 words.
            unsafe { vst1q_u32(w.as_mut_ptr().add(4 * i), r) }
        }
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        // SAFETY: see `neon_op`.
        std::array::from_fn(|i| unsafe { vaddq_u32(self[i], b[i]) })
    }
    #[inline(always)]
    fn xor_rotl<const R: u32>(self, b: Self) -> Self {
        // A negative count shifts right; both counts are in 1..32 as ChaCha's rotations are.
        // SAFETY: see `neon_op`.
        std::array::from_fn(|i| unsafe {
            let x = veorq_u32(self[i], b[i]);
            vorrq_u32(vshlq_u32(x, vdupq_n_s32(R as i32)), vshlq_u32(x, vdupq_n_s32(R as i32 - 32)))
        })
    }
}

impl Lanes for Neon {
    type Words = [uint32x4_t; 4];
    // 32 registers of 4 lanes: a vector takes 4, so the 5 × 4 tile (80 registers) would spill.
    // 5 × 1 keeps 20 accumulators with the inputs and a broadcast weight in registers.
    const TILE_VECS: usize = 1;
    const TILE_INPUTS: usize = 1;
    const ACT_GROUP: usize = 1;
    const PEAK_CHAINS: usize = 6;
    #[inline(always)]
    fn load(v: &V) -> Self {
        // SAFETY: each load reads 4 of the 16 values.
        Neon(std::array::from_fn(|i| unsafe { vld1q_f32(v.0.as_ptr().add(4 * i)) }))
    }
    #[inline(always)]
    fn store(self, v: &mut V) {
        for (i, r) in self.0.into_iter().enumerate() {
            // SAFETY: each store writes 4 of the 16 values.
            unsafe { vst1q_f32(v.0.as_mut_ptr().add(4 * i), r) }
        }
    }
}
