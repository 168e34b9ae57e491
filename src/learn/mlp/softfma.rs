//! `a·b + c` rounded once to `f32`, for x86-64 CPUs without the FMA instruction.
//!
//! Rust's `f32::mul_add` compiles there to a call of the C library's `fmaf`: exact, but one call
//! per lane (glibc's generic version also switches the rounding mode twice), which keeps the
//! portable kernels far below what the CPU can add and multiply. This version is exact by
//! construction and branch-free, so the compiler vectorises it with SSE2 over the 16 lanes:
//! - the product of two `f32` is exact in `f64` (24 + 24 significant bits ≤ 53; exponents far
//!   inside `f64`'s range);
//! - a two-sum gives `s + e = a·b + c` exactly, `s` the sum rounded to nearest;
//! - `s` is turned into the sum rounded to odd (truncate, then set the last bit if inexact), and
//!   rounding that to `f32` to nearest is the correctly rounded result, as `f64` carries more than
//!   the 24 + 2 bits this needs (Boldo and Melquiond, "When double rounding is odd", 2005).
//!
//! About 15 operations on two lanes at a time instead of one instruction on 8 or 16: what bounds
//! the portable level on such CPUs (see the README's Speed section).

/// `a·b + c` rounded once, bit for bit as a hardware FMA (NaNs as NaNs).
#[inline(always)]
pub(super) fn fma(a: f32, b: f32, c: f32) -> f32 {
    let p = f64::from(a) * f64::from(b);
    let c = f64::from(c);
    let s = p + c;
    // Knuth's two-sum: the rounding error of `s`, exactly (only finite `s` is used).
    let cb = s - p;
    let e = (p - (s - cb)) + (c - cb);
    let bits = s.to_bits();
    // False for a NaN `e` (an infinite or NaN `s`, which is already the answer).
    let inexact = (e > 0.0) | (e < 0.0);
    // Truncating toward zero moves one step down in magnitude when the error points to zero
    // (`s` is never 0 when inexact: a sum of doubles that rounds to 0 is 0).
    let toward_zero = inexact & (((e.to_bits() ^ bits) >> 63) == 1);
    let odd = (bits - u64::from(toward_zero)) | u64::from(inexact);
    f64::from_bits(odd) as f32
}

#[cfg(test)]
mod tests {
    use super::fma;
    use crate::rng::stream;
    use rand::RngCore;

    fn same(a: f32, b: f32, c: f32) {
        let want = a.mul_add(b, c);
        let got = fma(a, b, c);
        assert!(
            want.to_bits() == got.to_bits() || (want.is_nan() && got.is_nan()),
            "fma({a:e}, {b:e}, {c:e}) = {got:e} ({:#x}), want {want:e} ({:#x})",
            got.to_bits(),
            want.to_bits()
        );
    }

    #[test]
    fn matches_the_c_library_on_edge_cases() {
        let edges = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            f32::from_bits(0x8000_0001),
            f32::from_bits(0x007f_ffff),
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::EPSILON,
            1.0 + f32::EPSILON,
            1.0 - f32::EPSILON / 2.0,
            3.0,
            1e-20,
            1e20,
            0.1,
            -0.3,
        ];
        for &a in &edges {
            for &b in &edges {
                for &c in &edges {
                    same(a, b, c);
                }
            }
        }
    }

    #[test]
    fn matches_the_c_library_on_random_bits_and_near_cancellation() {
        let mut rng = stream(11, "test/softfma", &[]);
        for _ in 0..2_000_000 {
            let (a, b) = (f32::from_bits(rng.next_u32()), f32::from_bits(rng.next_u32()));
            // Any c, and a c that nearly cancels a·b: the cases where a double rounding errs.
            same(a, b, f32::from_bits(rng.next_u32()));
            let near = -(a * b);
            same(a, b, f32::from_bits(near.to_bits() ^ (rng.next_u32() & 0x3)));
            // Moderate exponents, where products and sums keep all their bits in play.
            let m = |x: u32| f32::from_bits((x & 0x807f_ffff) | (((x >> 23) & 0x1f) + 112) << 23);
            let (a, b) = (m(rng.next_u32()), m(rng.next_u32()));
            same(a, b, m(rng.next_u32()));
            same(a, b, -(a * b) * (1.0 + f32::EPSILON * (rng.next_u32() % 4) as f32));
            // Products of 13-bit integers often fall on a midpoint between two f32 (25 or 26
            // bits): a tiny c then decides the rounding, which rounding c into the sum first loses.
            let int = |x: u32| (4096 + x % 4096) as f32;
            let tiny = f32::from_bits(rng.next_u32() & 0x9fff_ffff);
            same(int(rng.next_u32()), int(rng.next_u32()), tiny);
        }
    }
}
