//! `bfqi-ga reproduce`: a tuned config's fitness derived again from scratch, field by field.

use super::chromosome::decode;
use super::records::{finite, fitness};
use super::units::{Evaluator, Role};
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
    /// Validation datasets re-derived (best.json's `validation` block), when it has one and it
    /// was checked.
    pub validation_datasets: Option<usize>,
    /// Per validation dataset: (index, recorded, derived) where they differ.
    pub validation_differences: Vec<(usize, Option<f64>, Option<f64>)>,
}

impl Reproduction {
    /// True when every score matches bit for bit.
    pub fn matches(&self) -> bool {
        self.differences.is_empty()
            && self.validation_differences.is_empty()
            && self.mismatches.is_empty()
            && self.recorded.map(f64::to_bits) == self.derived.map(f64::to_bits)
    }
}

/// A value as its file spells it (`tanh`, `per_action`), not as Rust's debug form (`Tanh`).
fn named<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_value(v).map(|v| v.as_str().map_or_else(|| v.to_string(), String::from)).unwrap_or_default()
}

/// Re-derives a tuned config's fitness from scratch (no stored unit is read), and with
/// `validation` its `validation` block too: the scores on the validation datasets (computed
/// again, as the validation computed them), their count and their summary. The block's `note`,
/// which compares the setting with the other validated ones, is not re-derived.
pub fn reproduce(t: &TunedConfig, path: &Path, validation: bool) -> Result<Reproduction> {
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
    differs("activation", named(&t.activation), named(&setting.activation));
    differs("delta_min", format!("{:?}", t.delta_min), format!("{:?}", setting.delta_min));
    differs("patience", t.patience.to_string(), setting.patience.to_string());
    let network = |n: &crate::learn::mlp::MlpParams| serde_json::to_string(n).unwrap_or_default();
    differs("network", network(&t.network), network(&ev.network(&setting)));
    differs("algorithm", t.algorithm.name().into(), s.algorithm.name().into());
    differs("actions", named(&t.actions), named(&s.actions));
    differs("iterations", t.iterations.to_string(), s.iterations.to_string());
    differs("episodes", t.episodes.to_string(), s.episodes.to_string());
    differs("datasets", t.datasets.to_string(), s.datasets.to_string());
    differs("scores", format!("{} values", t.scores.len()), format!("{} values", s.datasets));
    differs("seed", t.seed.to_string(), spec.seed.to_string());
    let checked = t.validation.as_ref().filter(|_| validation);
    if let Some(v) = checked {
        // A raced setting has a prefix of the validation datasets: at least one, at most all.
        if v.scores.is_empty() || v.scores.len() > v.datasets {
            mismatches.push(format!(
                "validation.scores: stored {} values, validation.datasets says {} (1 to that many)",
                v.scores.len(),
                v.datasets
            ));
        }
        let recorded: Option<Vec<f64>> = v.scores.iter().copied().collect();
        let summary = recorded.and_then(|s| crate::stats::summarize(&s));
        if v.summary != summary {
            let json = |s: &Option<crate::stats::Summary>| serde_json::to_string(s).unwrap_or_default();
            mismatches.push(format!(
                "validation.summary: stored {}, its scores give {}",
                json(&v.summary),
                json(&summary)
            ));
        }
    }
    // The search's datasets and the validation's, all units at once.
    let n_validation = checked.map_or(0, |v| v.scores.len().min(crate::limits::DATASETS));
    let validation_ev = Evaluator::with_role(spec.clone(), Path::new("."), Role::Validation);
    let units: Vec<(Role, usize)> = (0..spec.search.datasets)
        .map(|d| (Role::Search, d))
        .chain((0..n_validation).map(|d| (Role::Validation, d)))
        .collect();
    let all: Vec<Option<f64>> = units
        .into_par_iter()
        .map(|(role, d)| {
            let ev = if role == Role::Search { &ev } else { &validation_ev };
            ev.evaluate(&setting, d).map(|u| u.score)
        })
        .collect::<Result<_>>()?;
    let (scores, validation_scores) = all.split_at(spec.search.datasets);
    let differing = |stored: &[Option<f64>], derived: &[Option<f64>]| -> Vec<(usize, Option<f64>, Option<f64>)> {
        derived
            .iter()
            .enumerate()
            .filter(|(d, s)| stored.get(*d).copied().flatten().map(f64::to_bits) != s.map(f64::to_bits))
            .map(|(d, s)| (d, stored.get(d).copied().flatten(), *s))
            .collect()
    };
    let differences = differing(&t.scores, scores);
    let validation_differences = checked.map_or(Vec::new(), |v| differing(&v.scores, validation_scores));
    if !(differences.is_empty() && validation_differences.is_empty()) {
        mismatches.extend(stack_differences(spec, path)?);
    }
    Ok(Reproduction {
        recorded: t.fitness,
        derived: finite(fitness(scores)),
        differences,
        mismatches,
        validation_datasets: checked.map(|_| n_validation),
        validation_differences,
    })
}

/// For a gymnasium env whose scores disagree: how the Python stack recorded in the `run.json`
/// beside the best.json differs from the one that ran now (a different gymnasium or numpy is the
/// likely cause), or that none was recorded.
fn stack_differences(spec: &crate::spec::Spec, best: &Path) -> Result<Vec<String>> {
    let Some(g) = spec.env.env().gymnasium() else { return Ok(Vec::new()) };
    let run = best.parent().unwrap_or(Path::new(".")).join("run.json");
    let recorded = crate::store::read_text(&run)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| serde_json::from_value::<crate::env::gymnasium::Versions>(v.get("gymnasium")?.clone()).ok());
    let Some(recorded) = recorded else {
        return Ok(vec![format!(
            "versions: {} records no Python stack, so whether gymnasium or numpy differ is unknown",
            run.display()
        )]);
    };
    let now = g.versions()?;
    let d = recorded.differences(&now);
    Ok(if d.is_empty() {
        vec![format!("versions: the same as {} records (Python, gymnasium, numpy, minari)", run.display())]
    } else {
        d.into_iter().map(|x| format!("versions: {x} ({})", run.display())).collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fqi::Fqi;
    use crate::ga::units::{UnitResult, unit_id};
    use crate::learn::cpu::{Isa, with_mlp_level};

    /// The committed winners, unit by unit, at every MLP level this CPU runs (in CI also NEON,
    /// under qemu-aarch64): the first FQI iteration of each winner's unit on search dataset 0
    /// gives its committed record bit for bit — the Bellman residual, and every network's epochs,
    /// stop reason and last losses. A whole `reproduce` is 30 units of 5–10 s natively, which
    /// under qemu (some 350× slower) would take days; the first iteration is 2,500–3,500 epochs
    /// on cart-pole and the bicycle and 33 epochs on the pendulum's 400,000 rows.
    #[test]
    fn committed_winners_first_iteration_is_the_same_on_every_level() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/searches");
        // On aarch64 NEON alone: CI runs this under qemu, where each level takes some ten
        // minutes, and the learners' tests compare NEON with portable there.
        let levels: Vec<Isa> = if cfg!(target_arch = "aarch64") {
            vec![Isa::Neon]
        } else {
            Isa::ALL.into_iter().filter(|i| i.runs_mlp()).collect()
        };
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        for env in ["cartpole", "bicycle", "pendulum"] {
            let best = root.join(env).join("best.json");
            let t = TunedConfig::load(&best).unwrap();
            let (spec, c) = (t.spec.clone().unwrap(), t.chromosome.unwrap());
            let s = decode(&c, &spec.search.genes);
            let unit = root.join(env).join("units").join(format!("{}.json", unit_id(&s, 0)));
            let stored: UnitResult = serde_json::from_slice(&std::fs::read(&unit).unwrap()).unwrap();
            let want = &stored.iterations[0];
            let ev = Evaluator::new(spec.clone(), Path::new("."));
            let x = ev.dataset(0).unwrap();
            let (fit_seed, eval_seed) = ev.seeds(&s, 0);
            for &isa in &levels {
                let got = one.install(|| {
                    with_mlp_level(isa, || {
                        let params = ev.network(&s);
                        let mut fqi =
                            Fqi::new(spec.env.env(), &x.0, &x.1, &params, ev.fqi_settings(), fit_seed, eval_seed);
                        fqi.iterate().unwrap().unwrap()
                    })
                });
                let at = format!("{env} {} at {}", unit.display(), isa.name());
                assert_eq!(got.bellman_residual.to_bits(), want.bellman_residual.to_bits(), "{at}: residual");
                assert_eq!(got.epochs, want.epochs, "{at}: epochs");
                assert_eq!(got.networks, want.networks, "{at}: networks");
            }
        }
    }
}
