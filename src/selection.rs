//! How well a criterion that can be computed without the simulator (an offline estimate, FQI's own
//! value, a TD error) ranks settings against their true (online) values: the agreement figures
//! offline policy selection is judged by (issue 61; Paine et al. 2020, DOPE's definitions).
//!
//! - [`spearman`]: Spearman's ρ, the Pearson correlation of the ranks (ties get their mean rank);
//! - [`kendall`]: Kendall's τ-b, which corrects for ties in either list;
//! - [`regret_at`]: normalised regret@k, `(V_best − max over the criterion's top k of V) /
//!   (V_best − V_worst)`: 0 when the best setting is among the criterion's top k, 1 when its
//!   choice is the worst;
//! - [`bootstrap`]: a percentile interval of any of them, resampling the settings with
//!   replacement from a seeded stream (SPEC §7), so the interval does not depend on threads.

use crate::rng;

/// Ranks 1..=n of `x` (ties share the mean of their ranks).
fn ranks(x: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..x.len()).collect();
    order.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
    let mut r = vec![0.0; x.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && x[order[j + 1]] == x[order[i]] {
            j += 1;
        }
        // Ranks i+1 ..= j+1 shared.
        let mean = (i + j) as f64 / 2.0 + 1.0;
        for &k in &order[i..=j] {
            r[k] = mean;
        }
        i = j + 1;
    }
    r
}

/// Pearson's correlation of `a` and `b`; `None` when either is constant or they have fewer than
/// two values.
fn pearson(a: &[f64], b: &[f64]) -> Option<f64> {
    let n = a.len();
    if n < 2 || b.len() != n {
        return None;
    }
    let (ma, mb) = (a.iter().sum::<f64>() / n as f64, b.iter().sum::<f64>() / n as f64);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

/// Spearman's ρ of `estimate` against `truth` (one value per setting); `None` when either is
/// constant or there are fewer than two settings.
pub fn spearman(estimate: &[f64], truth: &[f64]) -> Option<f64> {
    pearson(&ranks(estimate), &ranks(truth))
}

/// Kendall's τ-b of `estimate` against `truth`; `None` when either is constant or there are fewer
/// than two settings. O(n²): the settings of a search are hundreds at most.
pub fn kendall(estimate: &[f64], truth: &[f64]) -> Option<f64> {
    let n = estimate.len();
    if n < 2 || truth.len() != n {
        return None;
    }
    let (mut concordant, mut discordant, mut tied_e, mut tied_t) = (0i64, 0i64, 0i64, 0i64);
    for i in 0..n {
        for j in i + 1..n {
            let (de, dt) = (estimate[i] - estimate[j], truth[i] - truth[j]);
            match (de == 0.0, dt == 0.0) {
                (true, true) => {}
                (true, false) => tied_e += 1,
                (false, true) => tied_t += 1,
                (false, false) if (de > 0.0) == (dt > 0.0) => concordant += 1,
                (false, false) => discordant += 1,
            }
        }
    }
    let left = (concordant + discordant + tied_e) as f64;
    let right = (concordant + discordant + tied_t) as f64;
    (left > 0.0 && right > 0.0).then(|| (concordant - discordant) as f64 / (left * right).sqrt())
}

/// Normalised regret@k: how far below the best true value the best of the criterion's top `k`
/// settings is, as a share of the true values' range. Ties in the estimate at the k-th place are
/// broken against the criterion (the worse true value counts), so a criterion that cannot tell
/// settings apart gains nothing from the order they were listed in. `None` without settings or
/// when every true value is the same.
pub fn regret_at(k: usize, estimate: &[f64], truth: &[f64]) -> Option<f64> {
    let n = estimate.len();
    if n == 0 || truth.len() != n || k == 0 {
        return None;
    }
    let best = truth.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let worst = truth.iter().copied().fold(f64::INFINITY, f64::min);
    if best <= worst {
        return None;
    }
    let mut order: Vec<usize> = (0..n).collect();
    // By estimate, highest first; among equal estimates the lower true value first.
    order.sort_by(|&a, &b| estimate[b].total_cmp(&estimate[a]).then(truth[a].total_cmp(&truth[b])));
    let kth = estimate[order[k.min(n) - 1]];
    // Every setting estimated above the k-th place is in the top k; of those tied with it, only
    // as many as fill k, the worst first.
    let mut top: Vec<usize> = order.iter().copied().filter(|&i| estimate[i] > kth).collect();
    let tied: Vec<usize> = order.iter().copied().filter(|&i| estimate[i] == kth).collect();
    let room = k.min(n) - top.len();
    top.extend(tied.into_iter().take(room));
    let chosen = top.iter().map(|&i| truth[i]).fold(f64::NEG_INFINITY, f64::max);
    Some((best - chosen) / (best - worst))
}

/// A statistic with its bootstrap interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WithInterval {
    /// On the settings as given.
    pub value: f64,
    /// The interval's bounds (percentiles of the resampled statistic).
    pub low: f64,
    /// See `low`.
    pub high: f64,
}

/// `statistic` of (`estimate`, `truth`) with a percentile bootstrap interval at `confidence`: the
/// settings resampled with replacement `resamples` times from the stream (`seed`,
/// `selection/bootstrap`, `[b]`); resamples where the statistic is undefined (all one value) are
/// left out. `None` when the statistic is undefined on the settings as given.
pub fn bootstrap(
    statistic: impl Fn(&[f64], &[f64]) -> Option<f64>,
    estimate: &[f64],
    truth: &[f64],
    resamples: usize,
    confidence: f64,
    seed: u64,
) -> Option<WithInterval> {
    let value = statistic(estimate, truth)?;
    let n = estimate.len() as u64;
    let mut drawn: Vec<f64> = (0..resamples as u64)
        .filter_map(|b| {
            let mut r = rng::stream(seed, rng::purpose::SELECTION_BOOTSTRAP, &[b]);
            let picked: Vec<usize> = (0..n).map(|_| rng::below(&mut r, n) as usize).collect();
            let e: Vec<f64> = picked.iter().map(|&i| estimate[i]).collect();
            let t: Vec<f64> = picked.iter().map(|&i| truth[i]).collect();
            statistic(&e, &t)
        })
        .collect();
    if drawn.is_empty() {
        return Some(WithInterval { value, low: value, high: value });
    }
    drawn.sort_by(f64::total_cmp);
    let at = |q: f64| drawn[((q * (drawn.len() - 1) as f64).round() as usize).min(drawn.len() - 1)];
    let tail = (1.0 - confidence) / 2.0;
    Some(WithInterval { value, low: at(tail), high: at(1.0 - tail) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_correlations_match_hand_computed_values() {
        // Ranks of the estimate 1 3 2 5 4 against 1 2 3 4 5: Σd² = 4, ρ = 1 − 6·4/(5·24) = 0.8.
        let (e, t) = ([10.0, 30.0, 20.0, 50.0, 40.0], [1.0, 2.0, 3.0, 4.0, 5.0]);
        assert!((spearman(&e, &t).unwrap() - 0.8).abs() < 1e-12);
        // Of the 10 pairs, 8 concordant and 2 discordant (2–3 and 4–5 swapped): τ = 6/10 = 0.6.
        assert!((kendall(&e, &t).unwrap() - 0.6).abs() < 1e-12);
        // Reversed: −1 both.
        let rev = [5.0, 4.0, 3.0, 2.0, 1.0];
        assert!((spearman(&rev, &t).unwrap() + 1.0).abs() < 1e-12);
        assert!((kendall(&rev, &t).unwrap() + 1.0).abs() < 1e-12);
        // Ties: estimate 1 1 2 against 1 2 3. Ranks 1.5 1.5 3 against 1 2 3: ρ = √3/2.
        assert!((spearman(&[1.0, 1.0, 2.0], &[1.0, 2.0, 3.0]).unwrap() - 3f64.sqrt() / 2.0).abs() < 1e-12);
        // τ-b: 2 concordant, 0 discordant, 1 tie in the estimate: 2/√(3·2).
        assert!((kendall(&[1.0, 1.0, 2.0], &[1.0, 2.0, 3.0]).unwrap() - 2.0 / 6f64.sqrt()).abs() < 1e-12);
        assert_eq!(spearman(&[1.0, 1.0], &[1.0, 2.0]), None, "a constant criterion ranks nothing");
        assert_eq!(kendall(&[1.0], &[1.0]), None);
    }

    #[test]
    fn regret_is_the_best_of_the_top_k_against_the_best_over_the_range() {
        let truth = [0.0, 10.0, 4.0, 8.0, 2.0];
        // The criterion ranks settings 2, 4, 1, 3, 0: its choice has true value 4 (regret
        // (10 − 4)/10 = 0.6); its top 3 hold setting 1, the best (regret 0).
        let estimate = [1.0, 3.0, 5.0, 2.0, 4.0];
        assert!((regret_at(1, &estimate, &truth).unwrap() - 0.6).abs() < 1e-12);
        assert!((regret_at(2, &estimate, &truth).unwrap() - 0.6).abs() < 1e-12);
        assert_eq!(regret_at(3, &estimate, &truth), Some(0.0));
        assert_eq!(regret_at(9, &estimate, &truth), Some(0.0), "k past the settings takes them all");
        // A criterion that ties everything gets the worst of the tied for its top 1.
        assert_eq!(regret_at(1, &[7.0; 5], &truth), Some(1.0));
        assert_eq!(regret_at(1, &estimate, &[3.0; 5]), None, "no range to scale by");
    }

    #[test]
    fn the_bootstrap_interval_holds_the_value_and_repeats_under_its_seed() {
        let truth: Vec<f64> = (0..60).map(|i| i as f64).collect();
        // A noisy but informative criterion: the truth plus a deterministic wobble.
        let estimate: Vec<f64> = truth.iter().map(|t| t + 15.0 * ((t * 1.7).sin())).collect();
        let a = bootstrap(spearman, &estimate, &truth, 500, 0.95, 3).unwrap();
        let b = bootstrap(spearman, &estimate, &truth, 500, 0.95, 3).unwrap();
        assert_eq!(a, b, "the same seed, the same interval");
        assert!(a.low <= a.value && a.value <= a.high && a.low < a.high, "{a:?}");
        assert!(a.value > 0.7 && a.high <= 1.0, "{a:?}");
        let c = bootstrap(spearman, &estimate, &truth, 500, 0.95, 4).unwrap();
        assert_ne!((a.low, a.high), (c.low, c.high), "another seed, another resampling");
        // A perfect criterion: every resample gives 1.
        let p = bootstrap(kendall, &truth, &truth, 200, 0.95, 1).unwrap();
        assert_eq!((p.value, p.low, p.high), (1.0, 1.0, 1.0));
    }
}
