//! The chromosome of thesis Appendix C and its decoding (SPEC §5).
//!
//! Five integer genes `(activation, a_δ, b_δ, a_p, b_p)`:
//! `δ_min = a_δ · 10^(−b_δ)` and `patience = floor(a_p · 10^(b_p − 1)) + 1`, in integer arithmetic.

use crate::error::{Result, ensure};
use crate::learn::mlp::Activation;
use serde::{Deserialize, Serialize};

/// Number of genes.
pub const GENES: usize = 5;

/// The genes, in order: activation index, a_δ, b_δ, a_p, b_p.
pub type Chromosome = [i64; GENES];

/// Inclusive range of each gene, and what the activation gene's values mean.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeneRanges {
    /// Activation gene value i means `activations[i]`.
    pub activations: Vec<Activation>,
    /// `[min, max]` of a_δ.
    pub a_delta: [i64; 2],
    /// `[min, max]` of b_δ (δ_min = a_δ · 10^(−b_δ)).
    pub b_delta: [i64; 2],
    /// `[min, max]` of a_p.
    pub a_patience: [i64; 2],
    /// `[min, max]` of b_p (patience = floor(a_p · 10^(b_p − 1)) + 1).
    pub b_patience: [i64; 2],
}

impl Default for GeneRanges {
    /// The SPEC ranges, which contain every optimum the thesis reports.
    fn default() -> Self {
        GeneRanges {
            activations: vec![Activation::Sigmoid, Activation::Tanh, Activation::Relu],
            a_delta: [10, 99],
            b_delta: [2, 8],
            a_patience: [10, 99],
            b_patience: [0, 2],
        }
    }
}

impl GeneRanges {
    /// `[min, max]` of every gene, in chromosome order.
    pub fn bounds(&self) -> [[i64; 2]; GENES] {
        [[0, self.activations.len() as i64 - 1], self.a_delta, self.b_delta, self.a_patience, self.b_patience]
    }

    /// Checks the ranges: non-empty, and small enough that the decoded values are exact.
    pub fn validate(&self) -> Result<()> {
        ensure(!self.activations.is_empty(), "activations", "[]", "must list at least one activation")?;
        let checks = [
            ("a_delta", self.a_delta, [1, 1_000_000]),
            ("b_delta", self.b_delta, [-15, 22]),
            ("a_patience", self.a_patience, [0, 1_000_000]),
            ("b_patience", self.b_patience, [-6, 7]),
        ];
        for (field, [lo, hi], [min, max]) in checks {
            ensure(
                lo <= hi && lo >= min && hi <= max,
                field,
                format!("[{lo}, {hi}]"),
                &format!("must be [lo, hi] with {min} ≤ lo ≤ hi ≤ {max}"),
            )?;
        }
        Ok(())
    }

    /// The largest patience the ranges decode to (patience grows with a_p and with b_p).
    pub fn max_patience(&self) -> usize {
        let c = [0, self.a_delta[0], self.b_delta[0], self.a_patience[1], self.b_patience[1]];
        decode(&c, self).patience
    }

    /// True when every gene lies in its range.
    pub fn contains(&self, c: &Chromosome) -> bool {
        self.bounds().iter().zip(c).all(|([lo, hi], g)| lo <= g && g <= hi)
    }
}

/// The MLP settings a chromosome stands for.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Decoded {
    /// Hidden activation.
    pub activation: Activation,
    /// Early-stopping δ_min.
    pub delta_min: f64,
    /// Early-stopping patience.
    pub patience: usize,
}

/// `10^e` for e ≥ 0, exactly.
fn pow10(e: i64) -> i64 {
    10i64.pow(e as u32)
}

/// Decodes a chromosome (assumed inside `ranges`).
pub fn decode(c: &Chromosome, ranges: &GeneRanges) -> Decoded {
    let [act, a_d, b_d, a_p, b_p] = *c;
    // Division by an exact power of ten rounds once, so 58·10^−2 is exactly the double nearest 0.58.
    let delta_min = if b_d >= 0 { a_d as f64 / pow10(b_d) as f64 } else { (a_d * pow10(-b_d)) as f64 };
    let e = b_p - 1;
    let patience = if e >= 0 { a_p * pow10(e) } else { a_p / pow10(-e) } + 1;
    Decoded { activation: ranges.activations[act as usize], delta_min, patience: patience as usize }
}

/// The first chromosome inside `ranges` (genes in increasing order) that decodes to `setting`
/// exactly (same activation, same δ_min bits, same patience), or `None` if the grid has none.
pub fn encode(setting: &Decoded, ranges: &GeneRanges) -> Option<Chromosome> {
    let b = ranges.bounds();
    let act = ranges.activations.iter().position(|&a| a == setting.activation)? as i64;
    let mut delta = None;
    'delta: for b_d in b[2][0]..=b[2][1] {
        for a_d in b[1][0]..=b[1][1] {
            if decode(&[act, a_d, b_d, b[3][0], b[4][0]], ranges).delta_min.to_bits() == setting.delta_min.to_bits() {
                delta = Some((a_d, b_d));
                break 'delta;
            }
        }
    }
    let (a_d, b_d) = delta?;
    for b_p in b[4][0]..=b[4][1] {
        for a_p in b[3][0]..=b[3][1] {
            let c = [act, a_d, b_d, a_p, b_p];
            if decode(&c, ranges).patience == setting.patience {
                return Some(c);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_optima_decode_exactly() {
        let r = GeneRanges::default();
        // Cart-pole: sigmoid, δ 0.58, patience 601.
        let d = decode(&[0, 58, 2, 60, 2], &r);
        assert_eq!((d.activation, d.delta_min, d.patience), (Activation::Sigmoid, 0.58, 601));
        // Pendulum: sigmoid, δ 0.06, patience 5 (b_p = 0: a_p div 10 + 1).
        let d = decode(&[0, 60, 3, 45, 0], &r);
        assert_eq!((d.delta_min, d.patience), (0.06, 5));
        // Bicycle: δ 0.011, patience 75.
        let d = decode(&[0, 11, 3, 74, 1], &r);
        assert_eq!((d.delta_min, d.patience), (0.011, 75));
        assert_eq!(decode(&[2, 99, 8, 99, 2], &r).activation, Activation::Relu);
        assert_eq!(decode(&[1, 10, 8, 10, 0], &r).delta_min, 1e-7);
    }

    #[test]
    fn ranges_contain_their_optima_and_refuse_nonsense() {
        let r = GeneRanges::default();
        r.validate().unwrap();
        assert!(r.contains(&[0, 58, 2, 60, 2]));
        assert!(!r.contains(&[3, 58, 2, 60, 2]));
        let bad = GeneRanges { a_delta: [50, 10], ..GeneRanges::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("a_delta"));
    }

    #[test]
    fn thesis_text_range_with_negative_exponents() {
        // The thesis text's b_p ∈ {−1, 0, 1}: b_p = −1 gives a_p div 100 + 1.
        let r = GeneRanges { b_patience: [-1, 1], ..GeneRanges::default() };
        assert_eq!(decode(&[0, 10, 3, 99, -1], &r).patience, 1);
        assert_eq!(decode(&[0, 10, 15, 99, 1], &r).delta_min, 10.0 / 1e15);
    }

    #[test]
    fn encode_finds_a_chromosome_of_each_thesis_optimum_and_none_off_the_grid() {
        let r = GeneRanges::default();
        for c in [[0, 58, 2, 60, 2], [0, 60, 3, 45, 0], [0, 11, 3, 74, 1], [1, 61, 5, 71, 2], [2, 99, 8, 99, 2]] {
            let d = decode(&c, &r);
            let e = encode(&d, &r).unwrap();
            assert!(r.contains(&e));
            let back = decode(&e, &r);
            assert_eq!(
                (back.activation, back.delta_min.to_bits(), back.patience),
                (d.activation, d.delta_min.to_bits(), d.patience)
            );
        }
        let off = Decoded { activation: Activation::Tanh, delta_min: 0.123, patience: 5 };
        assert_eq!(encode(&off, &r), None, "0.123 is not a·10^−b with two-digit a");
        let off = Decoded { activation: Activation::Tanh, delta_min: 0.5, patience: 2000 };
        assert_eq!(encode(&off, &r), None, "patience above the grid");
    }
}
