//! Variance arithmetic (sklearn's `MSE` criterion): a node's mean and variance, and the left-side
//! sums of a candidate, kept in fixed lanes so every kernel adds in one order.

/// Rows with `x <= t` so far, their target sums in 32 lanes (lane k: rows ≡ k mod 32), and the
/// total of the lanes once every row is in.
#[derive(Clone, Copy)]
pub(super) struct LeftSums {
    pub(super) lanes: [f64; 32],
    pub(super) count: usize,
    pub(super) sum: f64,
}

impl Default for LeftSums {
    fn default() -> Self {
        LeftSums { lanes: [0.0; 32], count: 0, sum: 0.0 }
    }
}

/// The total of [`LeftSums::lanes`]: lane-wise `(l[j] + l[j+8]) + (l[j+16] + l[j+24])`, then
/// [`hsum8`] (the order the AVX-512 kernels reduce their registers in).
#[inline(always)]
pub(super) fn lanes_total(l: &[f64; 32]) -> f64 {
    hsum8(std::array::from_fn(|j| (l[j] + l[j + 8]) + (l[j + 16] + l[j + 24])))
}

/// Sum of 8 lanes in the order of an AVX-512 halving reduction (the same order in every path).
#[inline(always)]
pub(super) fn hsum8(v: [f64; 8]) -> f64 {
    ((v[0] + v[4]) + (v[2] + v[6])) + ((v[1] + v[5]) + (v[3] + v[7]))
}

/// From the 16 lanes of Σ(y − y0) and Σ(y − y0)² over n rows: the mean and the population variance.
#[inline(always)]
pub(super) fn finish_mean_var(y0: f64, s: [f64; 16], q: [f64; 16], n: usize) -> (f64, f64) {
    let s = hsum8(std::array::from_fn(|j| s[j] + s[j + 8]));
    let q = hsum8(std::array::from_fn(|j| q[j] + q[j + 8]));
    mean_var_of_sums(y0, s, q, n)
}

/// The mean and population variance from the reduced Σ(y − y0) and Σ(y − y0)² over n rows.
#[inline(always)]
pub(super) fn mean_var_of_sums(y0: f64, s: f64, q: f64, n: usize) -> (f64, f64) {
    let m = s / n as f64;
    (y0 + m, (q / n as f64 - m * m).max(0.0))
}
