//! The FMA peak of the kernels' build, measured: the figure `bench search` sets every epoch
//! against. Apart from the lane types, as it is a benchmark, not arithmetic of the fits.

use super::lanes::{Isa, LANES, Lanes, V, multiversion};

/// Most independent chains [`fma_chains`] runs (the AVX-512 build's: 24 of its 32 registers).
const MAX_CHAINS: usize = 24;

/// `rounds` × `L::PEAK_CHAINS` vector FMAs on independent chains (the peak of the kernels'
/// build); returns a sum of the results so the work cannot be dropped.
///
/// Every lane starts from its own value: from a splat, both halves of an AVX2 pair would stay
/// equal and the compiler computes one and copies it, which read as 1.45–1.7× the real peak.
#[inline(always)]
fn fma_chains_body<L: Lanes>(rounds: usize) -> f32 {
    let chains = L::PEAK_CHAINS.min(MAX_CHAINS);
    let mut acc = [L::splat(0.0); MAX_CHAINS];
    for (c, a) in acc.iter_mut().enumerate().take(chains) {
        let mut start = V::ZERO;
        for (l, x) in start.0.iter_mut().enumerate() {
            *x = 0.5 + (c * LANES + l) as f32 * 1e-3;
        }
        *a = L::load(&start);
    }
    let (m, k) = (L::splat(0.999_9), L::splat(1e-4));
    for _ in 0..rounds {
        for a in acc.iter_mut().take(chains) {
            *a = a.fma(m, k);
        }
    }
    let mut total = L::splat(0.0);
    for a in acc.iter().take(chains) {
        total = total.add(*a);
    }
    let mut out = V::ZERO;
    total.store(&mut out);
    out.0.iter().sum()
}

multiversion! {
    /// See `fma_chains_body`.
    fn fma_chains(rounds: usize) -> (f32, usize) = fma_chains_counted
}

/// `fma_chains_body` with the chain count it ran.
#[inline(always)]
fn fma_chains_counted<L: Lanes>(rounds: usize) -> (f32, usize) {
    (fma_chains_body::<L>(rounds), L::PEAK_CHAINS.min(MAX_CHAINS))
}

/// Measures this core's FP32 peak on the kernels' build, in GFLOP/s (an FMA is 2 FLOPs per lane),
/// over about `seconds` (the best of several short runs, so a busy moment does not count).
pub(crate) fn fma_peak_gflops(isa: Isa, seconds: f64) -> f64 {
    let rounds = 200_000;
    let start = std::time::Instant::now();
    let mut best = f64::INFINITY;
    let mut chains = 1;
    while start.elapsed().as_secs_f64() < seconds || best.is_infinite() {
        let t = std::time::Instant::now();
        let (sum, c) = fma_chains(isa, std::hint::black_box(rounds));
        std::hint::black_box(sum);
        best = best.min(t.elapsed().as_secs_f64());
        chains = c;
    }
    (rounds * chains * LANES * 2) as f64 / best / 1e9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_chain_and_lane_is_computed() {
        // The same FMAs lane by lane in f32: a level that skipped half a vector (or a chain)
        // would sum to something else, as every lane starts from its own value.
        for isa in Isa::ALL.into_iter().filter(|i| i.runs_mlp()) {
            let (sum, chains) = fma_chains(isa, 10);
            let mut lanes = [0.0f32; LANES];
            for c in 0..chains {
                for (l, t) in lanes.iter_mut().enumerate() {
                    let mut x = 0.5 + (c * LANES + l) as f32 * 1e-3;
                    for _ in 0..10 {
                        x = x.mul_add(0.999_9, 1e-4);
                    }
                    *t += x;
                }
            }
            assert_eq!(sum.to_bits(), lanes.iter().sum::<f32>().to_bits(), "{isa:?}");
        }
    }
}
