//! The builder's kernels: portable code, and AVX-512 code that gives the same bits.

#[cfg(target_arch = "x86_64")]
pub(super) mod avx512;
pub(super) mod portable;
