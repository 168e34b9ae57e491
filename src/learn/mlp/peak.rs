//! The FMA peak of the kernels' build, measured: the figure `bench search` sets every epoch
//! against. Apart from the lane types, as it is a benchmark, not arithmetic of the fits.

use super::lanes::{Isa, LANES, Lanes, V, multiversion};

/// Independent chains of [`fma_chains`]: enough to cover the FMA latency on both FMA ports.
const PEAK_CHAINS: usize = 24;

/// `rounds` × [`PEAK_CHAINS`] vector FMAs on independent chains (the peak of the kernels' build);
/// returns a sum of the results so the work cannot be dropped.
#[inline(always)]
fn fma_chains_body<L: Lanes>(rounds: usize) -> f32 {
    let mut acc = [L::splat(0.5); PEAK_CHAINS];
    let (m, c) = (L::splat(0.999_9), L::splat(1e-4));
    for _ in 0..rounds {
        for a in &mut acc {
            *a = a.fma(m, c);
        }
    }
    let mut total = L::splat(0.0);
    for a in acc {
        total = total.add(a);
    }
    let mut out = V::ZERO;
    total.store(&mut out);
    out.0[0]
}

multiversion! {
    /// See `fma_chains_body`.
    fn fma_chains(rounds: usize) -> f32 = fma_chains_body
}

/// Measures this core's FP32 peak on the kernels' build, in GFLOP/s (an FMA is 2 FLOPs per lane),
/// over about `seconds` (the best of several short runs, so a busy moment does not count).
pub(crate) fn fma_peak_gflops(isa: Isa, seconds: f64) -> f64 {
    let rounds = 200_000;
    let flops = (rounds * PEAK_CHAINS * LANES * 2) as f64;
    let start = std::time::Instant::now();
    let mut best = f64::INFINITY;
    while start.elapsed().as_secs_f64() < seconds || best.is_infinite() {
        let t = std::time::Instant::now();
        std::hint::black_box(fma_chains(isa, std::hint::black_box(rounds)));
        best = best.min(t.elapsed().as_secs_f64());
    }
    flops / best / 1e9
}
