//! Seed derivation (SPEC §7).
//!
//! Every random draw in bfqi-ga comes from a [`ChaCha8Rng`] stream whose seed is a pure function of
//! (master seed, purpose, indices). Streams never depend on scheduling, so results are identical for
//! any thread count, evaluation order or interruption.
//!
//! The derivation is our own, fixed and portable: the purpose string and indices are absorbed
//! into a 64-bit state with the SplitMix64 finaliser (a well-mixed bijection). Changing it changes
//! every result, so it is pinned by a test.

use rand::RngCore;
pub use rand::SeedableRng;
pub use rand_chacha::ChaCha8Rng as Rng;

/// SplitMix64 finaliser: a bijective mixer with full avalanche.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Derives the seed of the stream named by `purpose` and `indices` under `master`.
///
/// `derive(seed, "dataset/search", &[i])` and `derive(seed, "dataset/compare", &[i])` never
/// coincide in practice, which keeps search and comparison datasets disjoint.
pub fn derive(master: u64, purpose: &str, indices: &[u64]) -> u64 {
    let mut h = mix(master);
    // Length-prefix the purpose so ("ab", [..]) and ("a", ..) cannot collide by concatenation.
    h = mix(h ^ purpose.len() as u64);
    for chunk in purpose.as_bytes().chunks(8) {
        let mut word = [0u8; 8];
        word[..chunk.len()].copy_from_slice(chunk);
        h = mix(h ^ u64::from_le_bytes(word));
    }
    h = mix(h ^ indices.len() as u64);
    for &i in indices {
        h = mix(h ^ i);
    }
    h
}

/// A generator for the stream named by `purpose` and `indices` under `master`.
pub fn stream(master: u64, purpose: &str, indices: &[u64]) -> Rng {
    Rng::seed_from_u64(derive(master, purpose, indices))
}

/// A uniform draw in `[0, 1)` with 53 random bits.
///
/// Written out rather than taken from `rand`'s distributions so that the mapping from stream to
/// numbers is fixed by this crate and cannot change with a dependency upgrade.
#[inline]
pub fn unit(rng: &mut Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The stream's next 64 bits as they are: a gymnasium episode's `reset(seed=…)`.
#[inline]
pub fn word(rng: &mut Rng) -> u64 {
    rng.next_u64()
}

/// A uniform draw in `[lo, hi)`.
#[inline]
pub fn uniform(rng: &mut Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * unit(rng)
}

/// A uniform integer in `0..n` (n > 0), by Lemire's multiply-shift with rejection (unbiased).
#[inline]
pub fn below(rng: &mut Rng, n: u64) -> u64 {
    bounded(|| rng.next_u64(), n)
}

/// [`below`] on any source of the generator's words. The rejection threshold `2⁶⁴ mod n` is below
/// `n`, so its 64-bit division is only needed when the low product word is below `n` (almost
/// never): the same values and the same words consumed as testing every draw against it.
#[inline]
pub(crate) fn bounded(mut next: impl FnMut() -> u64, n: u64) -> u64 {
    debug_assert!(n > 0);
    loop {
        let m = (next() as u128) * (n as u128);
        let low = m as u64;
        if low >= n || low >= n.wrapping_neg() % n {
            return (m >> 64) as u64;
        }
    }
}

/// A uniform integer in `lo..=hi`.
#[inline]
pub fn int_in(rng: &mut Rng, lo: i64, hi: i64) -> i64 {
    debug_assert!(lo <= hi);
    lo + below(rng, (hi - lo) as u64 + 1) as i64
}

/// The purpose of every random stream, named once: what each draws and from which indices. The
/// README's "Determinism" section lists the same. Changing a name changes every result it seeds.
pub mod purpose {
    /// Dataset `d` of a role (`dataset/search`, `dataset/compare`, `dataset/validation`): `[d]`.
    pub fn dataset(role: &str) -> String {
        format!("dataset/{role}")
    }
    /// Episode `e` of a dataset, or of an evaluation (its start state and noise): `[e]`.
    pub const EPISODE: &str = "episode";
    /// A run's or comparison's learner seed for dataset `i`: `[i]`.
    pub const FIT: &str = "fit";
    /// A run's or comparison's evaluation episodes for dataset `i`: `[i]`.
    pub const EVAL: &str = "eval";
    /// A search unit's learner seed: `[activation code, δ_min bits, patience, d]`.
    pub const INIT: &str = "init";
    /// The same for a validation unit.
    pub const INIT_VALIDATION: &str = "init/validation";
    /// A search or validation unit's evaluation episodes (`eval/search`, `eval/validation`): `[d]`.
    pub fn eval_role(role: &str) -> String {
        format!("eval/{role}")
    }
    /// FQI member `k` (iteration k), from the learner seed: `[k]`.
    pub const MEMBER: &str = "member";
    /// The model of action `j` of a `per_action` member, from the member's seed: `[j]`.
    pub const ACTION: &str = "action";
    /// Extra-Trees tree `t`, from the model's seed: `[t]`.
    pub const TREE: &str = "tree";
    /// A network's initial weights, from the model's seed: `[]`.
    pub const MLP_INIT: &str = "mlp/init";
    /// A network's mini-batch shuffles, from the model's seed: `[]`.
    pub const MLP_SHUFFLE: &str = "mlp/shuffle";
    /// Fit `k` of Fitted Q Evaluation, from its seed: `[k]`.
    pub const FQE: &str = "fqe";
    /// Resample `b` of a selection statistic's bootstrap interval: `[b]`.
    pub const SELECTION_BOOTSTRAP: &str = "selection/bootstrap";
    /// The GA's own seed for an environment (`ga/cartpole`, …): `[]`.
    pub fn ga(env: &str) -> String {
        format!("ga/{env}")
    }
    /// Individual `i` of the initial population, from the GA seed: `[i]`.
    pub const GA_INIT: &str = "ga/init";
    /// Child `c` of generation `g` (parents, crossover, mutation), from the GA seed: `[g, c]`.
    pub const GA_BREED: &str = "ga/breed";
    /// Individual `i` of generation `g` ≥ 1 of a random search, from the GA seed: `[g, i]`.
    pub const GA_RANDOM: &str = "ga/random";
    /// Validation of an environment's settings (a few random steps), from seed 0: `[e]`.
    pub const ENV_CHECK: &str = "env/check";
    /// Whether an environment's dataset actions are discrete, from seed 0: `[]`.
    pub const ENV_CHECK_ACTIONS: &str = "env/check-actions";
    /// The permutation of a logged file's episodes a `disjoint` split deals, from the master
    /// seed: `[]`.
    pub const DATA_SPLIT: &str = "data/split";
    /// The episodes a `bootstrap` split draws for a dataset, from the dataset's seed: `[]`.
    pub const DATA_BOOTSTRAP: &str = "data/bootstrap";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivation_is_pinned() {
        // If this changes, every stored result of every user changes: do not.
        assert_eq!(derive(0, "", &[]), derive(0, "", &[]));
        assert_ne!(derive(1, "dataset/search", &[0]), derive(1, "dataset/compare", &[0]));
        assert_ne!(derive(1, "dataset", &[0, 1]), derive(1, "dataset", &[1, 0]));
        assert_ne!(derive(1, "ab", &[]), derive(1, "a", &[u64::from_le_bytes(*b"b\0\0\0\0\0\0\0")]));
        assert_eq!(derive(42, "eval", &[3]), 10090956817012991045);
    }

    /// Lemire's method as published: the threshold computed and tested on every draw.
    fn below_textbook(rng: &mut Rng, n: u64) -> u64 {
        let threshold = n.wrapping_neg() % n;
        loop {
            let m = (rng.next_u64() as u128) * (n as u128);
            if (m as u64) >= threshold {
                return (m >> 64) as u64;
            }
        }
    }

    #[test]
    fn below_matches_the_textbook_rejection() {
        // Large n reject often (2⁶⁴ mod n is near n for n just above 2⁶³), so both branches run.
        for n in [1, 2, 3, 9, 1000, (1 << 63) + 1, u64::MAX / 3 * 2, u64::MAX] {
            let (mut a, mut b) = (stream(3, "below", &[n]), stream(3, "below", &[n]));
            for _ in 0..2000 {
                assert_eq!(below(&mut a, n), below_textbook(&mut b, n), "n = {n}");
            }
            assert_eq!(a.next_u64(), b.next_u64(), "same words consumed, n = {n}");
        }
    }

    #[test]
    fn unit_in_range_and_uniformish() {
        let mut r = stream(7, "test", &[]);
        let n = 100_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = unit(&mut r);
            assert!((0.0..1.0).contains(&u));
            sum += u;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.01);
    }

    #[test]
    fn int_in_covers_range_inclusive() {
        let mut r = stream(7, "test", &[1]);
        let mut seen = [0usize; 3];
        for _ in 0..3000 {
            let v = int_in(&mut r, 10, 12);
            seen[(v - 10) as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c > 800), "{seen:?}");
    }
}
