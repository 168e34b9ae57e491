//! Opt-in pruning of hopeless individuals (`search.prune`), beyond the thesis: Appendix C scores
//! every individual on every search dataset. With pruning on, an individual's datasets run in
//! order, and its evaluation stops once the mean of its scores so far falls below the cutoff: the
//! previous generation's parent-pool line (the fitness of its worst parent) minus a margin.
//!
//! The previous generation's line, rather than one taken from the units finished so far in this
//! generation, because it is known before any unit of the generation runs: the decisions are then
//! the same for any thread count, completion order or executor, and a resumed search makes them
//! again identically. Generation 0 has no previous generation and is never pruned.
//!
//! A pruned individual keeps its partial scores, has no fitness, and is never an elite or a parent.

use crate::error::{Result, ensure};
use serde::{Deserialize, Serialize};

/// The pruning rule of a search spec.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PruneRule {
    /// Off by default: it departs from thesis Appendix C.
    pub enabled: bool,
    /// How far (in score units) the mean so far may fall below the parent-pool line.
    pub margin: f64,
    /// Datasets every individual runs before it can be pruned.
    pub min_datasets: usize,
}

impl Default for PruneRule {
    fn default() -> Self {
        PruneRule { enabled: false, margin: 0.0, min_datasets: 3 }
    }
}

impl PruneRule {
    /// Validates the rule; errors name the field.
    pub fn validate(&self) -> Result<()> {
        ensure(self.margin.is_finite() && self.margin >= 0.0, "prune.margin", self.margin, "must be finite and ≥ 0")?;
        ensure(self.min_datasets >= 1, "prune.min_datasets", self.min_datasets, "must be ≥ 1")
    }
}

/// Where an individual's evaluation stands after some of its datasets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Run the next dataset.
    Open,
    /// Every dataset ran, or one diverged (fitness −∞ whatever the rest): nothing more to run.
    Closed,
    /// The mean so far is below the cutoff: stop, and record it as pruned.
    Pruned,
}

/// The verdict on `scores` (datasets `0..scores.len()`, `None` = diverged) out of `total`, against
/// `cutoff` (already lowered by the margin).
pub fn decide(scores: &[Option<f64>], total: usize, rule: &PruneRule, cutoff: f64) -> Verdict {
    if scores.len() >= total || scores.contains(&None) {
        return Verdict::Closed;
    }
    if scores.len() < rule.min_datasets {
        return Verdict::Open;
    }
    let mean = scores.iter().flatten().sum::<f64>() / scores.len() as f64;
    if mean < cutoff { Verdict::Pruned } else { Verdict::Open }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prunes_only_below_the_cutoff_after_the_minimum() {
        let rule = PruneRule { enabled: true, margin: 5.0, min_datasets: 2 };
        assert_eq!(decide(&[Some(10.0)], 10, &rule, 100.0), Verdict::Open, "one dataset is not enough");
        assert_eq!(decide(&[Some(10.0), Some(20.0)], 10, &rule, 100.0), Verdict::Pruned);
        assert_eq!(decide(&[Some(150.0), Some(60.0)], 10, &rule, 100.0), Verdict::Open, "mean 105 ≥ 100");
        assert_eq!(decide(&[Some(1.0), None], 10, &rule, 100.0), Verdict::Closed, "diverged");
        assert_eq!(decide(&[Some(1.0); 10], 10, &rule, 100.0), Verdict::Closed, "complete");
        assert!(PruneRule { margin: -1.0, ..rule.clone() }.validate().is_err());
        assert!(PruneRule { min_datasets: 0, ..rule }.validate().is_err());
    }
}
