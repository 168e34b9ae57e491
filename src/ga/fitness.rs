//! A given config's fitness under a search spec (`bfqi-ga fitness`): "how does the thesis's
//! optimum, or another search's winner, score under my search's fitness?"
//!
//! Fitness is a function of the decoded setting (activation, δ_min, patience) and the spec: the
//! same units a search would run ([`Evaluator::evaluate`]) on the spec's search datasets, so a
//! search's own best.json scores exactly its recorded fitness.

use super::chromosome::{Decoded, encode};
use super::search::fitness;
use super::units::{Evaluator, UnitResult};
use crate::error::{Error, Result};
use crate::spec::Spec;
use crate::tuned::TunedConfig;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// A setting scored on a spec's search datasets.
#[derive(Debug, Clone, PartialEq)]
pub struct Scored {
    /// The setting.
    pub setting: Decoded,
    /// Each dataset's unit, in index order.
    pub units: Vec<UnitResult>,
    /// The mean score, or `None` (−∞) when a dataset diverged.
    pub fitness: Option<f64>,
    /// Where the tuned config differs from what the search would run (its network beyond the three
    /// genes, its algorithm, K, episodes or dataset count): the fitness is the search's, not a
    /// re-run of the tuned config's own settings.
    pub notes: Vec<String>,
}

/// The setting a tuned config stands for.
pub fn setting_of(t: &TunedConfig) -> Decoded {
    Decoded { activation: t.activation, delta_min: t.delta_min, patience: t.patience }
}

/// Scores tuned config `t` (read from `origin`) under `spec`'s fitness.
pub fn score(spec: &Spec, t: &TunedConfig, origin: &Path) -> Result<Scored> {
    t.check_env(spec.env.env().name(), origin)?;
    let setting = setting_of(t);
    let ev = Evaluator::new(spec.clone(), Path::new("."));
    let s = &spec.search;
    let units: Vec<UnitResult> =
        (0..s.datasets).into_par_iter().map(|d| ev.evaluate(&setting, d)).collect::<Result<_>>()?;
    let scores: Vec<Option<f64>> = units.iter().map(|u| u.score).collect();
    let f = fitness(&scores);
    Ok(Scored { setting, units, fitness: f.is_finite().then_some(f), notes: differences(spec, t, &setting) })
}

fn differences(spec: &Spec, t: &TunedConfig, setting: &Decoded) -> Vec<String> {
    let s = &spec.search;
    let mut notes = Vec::new();
    let searched = crate::learn::mlp::MlpParams {
        activation: t.network.activation,
        delta_min: t.network.delta_min,
        patience: t.network.patience,
        ..s.network.clone()
    };
    if searched != t.network {
        let (a, b) = (serde_json::to_value(&t.network).ok(), serde_json::to_value(&searched).ok());
        let fields: Vec<String> = match (a, b) {
            (Some(serde_json::Value::Object(a)), Some(serde_json::Value::Object(b))) => {
                a.iter().filter(|(k, v)| b.get(*k) != Some(*v)).map(|(k, v)| format!("{k} {v} → {}", b[k])).collect()
            }
            _ => vec![],
        };
        notes.push(format!("the search's network differs from the tuned config's: {}", fields.join(", ")));
    }
    let run = [
        ("algorithm", t.algorithm.name().to_string(), s.algorithm.name().to_string()),
        ("iterations", t.iterations.to_string(), s.iterations.to_string()),
        ("episodes", t.episodes.to_string(), s.episodes.to_string()),
        ("datasets", t.datasets.to_string(), s.datasets.to_string()),
    ];
    for (field, theirs, ours) in run {
        if theirs != ours {
            notes.push(format!("{field}: the tuned config's {theirs}, the search's {ours}"));
        }
    }
    if encode(setting, &s.genes).is_none() {
        notes.push("the setting is not on the spec's gene grid: a search could not reach it".into());
    }
    notes
}

/// Trains tuned config `t` on search dataset `d` exactly as a search under `spec` would (its
/// unit), keeping the Q-function: what `rollout --tuned` looks at.
pub fn train(spec: &Spec, t: &TunedConfig, origin: &Path, d: usize) -> Result<(UnitResult, crate::model::Model)> {
    t.check_env(spec.env.env().name(), origin)?;
    if d >= spec.search.datasets {
        return Err(Error::invalid("dataset", d, format!("must be below search.datasets = {}", spec.search.datasets)));
    }
    let ev = Evaluator::new(spec.clone(), Path::new("."));
    let (unit, model) = ev.evaluate_keeping(&setting_of(t), d, true)?;
    match model {
        Some(m) => Ok((unit, m)),
        None => Err(Error::Data(format!(
            "{} diverged on search dataset {d}: there is no policy to look at",
            super::units::describe(&unit.setting)
        ))),
    }
}

/// A tuned config to train as its search unit on a search dataset did (`rollout --tuned`).
#[derive(Debug, Clone)]
pub struct TunedUnit {
    /// The spec whose search fitness trains it.
    pub spec: Spec,
    /// The tuned config.
    pub tuned: TunedConfig,
    /// Where the tuned config came from.
    pub from: PathBuf,
}

impl TunedUnit {
    /// Resolves `tuned` (`thesis` or a best.json) and its spec: `target` (an environment name or a
    /// spec file), else the spec a best.json records.
    pub fn resolve(target: Option<&str>, tuned: &str) -> Result<TunedUnit> {
        let recorded = if tuned == "thesis" { None } else { TunedConfig::load(Path::new(tuned))?.spec };
        let spec = match (target, recorded) {
            (Some(t), _) => Spec::resolve(t)?.0,
            (None, Some(spec)) => spec,
            (None, None) => {
                return Err(Error::Usage(format!(
                    "give the environment or spec: bfqi-ga rollout <ENV|SPEC> --tuned {tuned}"
                )));
            }
        };
        let (tuned, from) = TunedConfig::resolve(tuned, spec.env.env().name())?;
        Ok(TunedUnit { spec, tuned, from })
    }

    /// What training on search dataset `d` does, for the line printed before it.
    pub fn describe(&self, d: usize) -> String {
        format!(
            "training {} on search dataset {d} as its search unit did ({} K={})…",
            super::units::describe(&setting_of(&self.tuned)),
            self.spec.search.algorithm.name(),
            self.spec.search.iterations
        )
    }

    /// Trains it on search dataset `d` ([`train`]), saving the Q-function to `save` when given.
    pub fn train(&self, d: usize, save: Option<&Path>) -> Result<crate::model::Model> {
        let (_, m) = train(&self.spec, &self.tuned, &self.from, d)?;
        if let Some(p) = save {
            if let Some(parent) = p.parent().filter(|dir| !dir.as_os_str().is_empty()) {
                crate::store::create_dir(parent)?;
            }
            crate::model::save(p, &m)?;
        }
        Ok(m)
    }
}
