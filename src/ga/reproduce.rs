//! `bfqi-ga reproduce`: a tuned config's fitness derived again from scratch, field by field.

use super::chromosome::decode;
use super::records::{finite, fitness};
use super::units::Evaluator;
use crate::error::{Error, Result};
use crate::tuned::TunedConfig;
use std::path::Path;

/// The outcome of `reproduce`.
#[derive(Debug, Clone, PartialEq)]
pub struct Reproduction {
    /// Recorded fitness.
    pub recorded: Option<f64>,
    /// Re-derived fitness.
    pub derived: Option<f64>,
    /// Per dataset: (index, recorded, derived) where they differ.
    pub differences: Vec<(usize, Option<f64>, Option<f64>)>,
    /// Stored fields that disagree with what the spec and chromosome give (an edited best.json).
    pub mismatches: Vec<String>,
}

impl Reproduction {
    /// True when every score matches bit for bit.
    pub fn matches(&self) -> bool {
        self.differences.is_empty()
            && self.mismatches.is_empty()
            && self.recorded.map(f64::to_bits) == self.derived.map(f64::to_bits)
    }
}

/// Re-derives a tuned config's fitness from scratch (no stored unit is read).
pub fn reproduce(t: &TunedConfig, path: &Path) -> Result<Reproduction> {
    use rayon::prelude::*;
    let (Some(spec), Some(c)) = (&t.spec, &t.chromosome) else {
        return Err(Error::File {
            path: path.to_path_buf(),
            message: "has no spec or chromosome: only a search's best.json can be reproduced".into(),
        });
    };
    if let Some(h) = t.spec_hash.as_ref().filter(|h| **h != spec.hash()) {
        return Err(Error::File {
            path: path.to_path_buf(),
            message: format!("spec_hash {h} does not match its spec ({})", spec.hash()),
        });
    }
    if !spec.search.genes.contains(c) {
        return Err(Error::File {
            path: path.to_path_buf(),
            message: format!("chromosome {c:?} lies outside its spec's gene ranges {:?}", spec.search.genes.bounds()),
        });
    }
    let setting = decode(c, &spec.search.genes);
    let ev = Evaluator::new(spec.clone(), Path::new("."));
    // Every stored field must be what the spec and the chromosome give.
    let s = &spec.search;
    let mut mismatches = Vec::new();
    let mut differs = |field: &str, stored: String, derived: String| {
        if stored != derived {
            mismatches.push(format!("{field}: stored {stored}, the spec and chromosome give {derived}"));
        }
    };
    differs("activation", format!("{:?}", t.activation), format!("{:?}", setting.activation));
    differs("delta_min", format!("{:?}", t.delta_min), format!("{:?}", setting.delta_min));
    differs("patience", t.patience.to_string(), setting.patience.to_string());
    let network = |n: &crate::learn::mlp::MlpParams| serde_json::to_string(n).unwrap_or_default();
    differs("network", network(&t.network), network(&ev.network(&setting)));
    differs("algorithm", t.algorithm.name().into(), s.algorithm.name().into());
    differs("actions", format!("{:?}", t.actions), format!("{:?}", s.actions));
    differs("iterations", t.iterations.to_string(), s.iterations.to_string());
    differs("episodes", t.episodes.to_string(), s.episodes.to_string());
    differs("datasets", t.datasets.to_string(), s.datasets.to_string());
    differs("scores", format!("{} values", t.scores.len()), format!("{} values", s.datasets));
    differs("seed", t.seed.to_string(), spec.seed.to_string());
    let scores: Vec<Option<f64>> = (0..spec.search.datasets)
        .into_par_iter()
        .map(|d| ev.evaluate(&setting, d).map(|u| u.score))
        .collect::<Result<_>>()?;
    let differences = scores
        .iter()
        .enumerate()
        .filter(|(d, s)| t.scores.get(*d).copied().flatten().map(f64::to_bits) != s.map(f64::to_bits))
        .map(|(d, s)| (d, t.scores.get(d).copied().flatten(), *s))
        .collect();
    Ok(Reproduction { recorded: t.fitness, derived: finite(fitness(&scores)), differences, mismatches })
}
