//! Tuned configs: what a search finds (`best.json`) and what `compare` consumes. The thesis's own
//! GA optima ship in the same format under `searches/tuned/`.

use crate::error::{Error, Result, ensure};
use crate::fqi::Algorithm;
use crate::ga::chromosome::Chromosome;
use crate::learn::Learner;
use crate::learn::actions::ActionEncoding;
use crate::learn::mlp::{Activation, MlpParams};
use crate::spec::{Select, Spec};
use crate::stats::Summary;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The settings a search tuned, with the evidence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TunedConfig {
    /// Environment name.
    pub env: String,
    /// `search` (found by a run) or `thesis` (the thesis's reported optimum).
    pub source: String,
    /// Hidden activation.
    pub activation: Activation,
    /// Early-stopping δ_min.
    pub delta_min: f64,
    /// Early-stopping patience.
    pub patience: usize,
    /// The complete network settings (activation, δ_min and patience included).
    pub network: MlpParams,
    /// Action encoding the network was tuned with.
    pub actions: ActionEncoding,
    /// The algorithm it was tuned for.
    pub algorithm: Algorithm,
    /// FQI iterations.
    pub iterations: usize,
    /// Episodes per dataset.
    pub episodes: usize,
    /// Datasets the fitness averages over.
    pub datasets: usize,
    /// Fitness (mean last-iteration score over the search datasets); `null` if any diverged or unknown.
    pub fitness: Option<f64>,
    /// Score per search dataset (`null` = diverged).
    pub scores: Vec<Option<f64>>,
    /// Hash of the resolved spec the search ran.
    pub spec_hash: Option<String>,
    /// Master seed.
    pub seed: u64,
    /// Generation in which this chromosome was first evaluated.
    pub generation: Option<usize>,
    /// The genes.
    pub chromosome: Option<Chromosome>,
    /// The resolved spec of the search (what `reproduce` re-runs).
    pub spec: Option<Spec>,
    /// How the setting scored on the validation datasets (`search.validate`), when validated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation: Option<ValidationSummary>,
    /// The search's two winners, best fitness and validated, and which of them this config is
    /// (`search.select`), when validated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selection: Option<Selection>,
}

/// The choice `search.select` made, as `best.json` records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Selection {
    /// The rule: `fitness` (the thesis's) or `validated`.
    pub select: Select,
    /// The setting with the best fitness on the search datasets.
    pub fitness: String,
    /// The validation's winner (a race's leader, or the best validation mean).
    pub validated: Option<String>,
    /// Top settings the validation cannot tell from its winner at 95 %.
    pub indistinguishable: Vec<String>,
}

/// Built-in copies of the thesis's tuned configs.
const THESIS: [(&str, &str); 3] = [
    ("pendulum", include_str!("../searches/tuned/pendulum.json")),
    ("cartpole", include_str!("../searches/tuned/cartpole.json")),
    ("bicycle", include_str!("../searches/tuned/bicycle.json")),
];

impl TunedConfig {
    /// Checks consistency and ranges; errors name the field.
    pub fn validate(&self) -> Result<()> {
        // A gymnasium env's tuned config names its id, as its embedded spec does.
        let gymnasium = self.spec.as_ref().is_some_and(|s| s.env.env().gymnasium().is_some_and(|g| g.id == self.env));
        ensure(
            crate::env::NAMES.contains(&self.env.as_str()) || gymnasium,
            "env",
            &self.env,
            "must be pendulum, cartpole or bicycle, or the gymnasium env id of its spec",
        )?;
        ensure(
            self.delta_min.is_finite() && self.delta_min >= 0.0,
            "delta_min",
            self.delta_min,
            "must be finite and ≥ 0",
        )?;
        self.network.check().map_err(|e| e.within("network"))?;
        let n = &self.network;
        ensure(
            n.activation == self.activation && n.delta_min == self.delta_min && n.patience == self.patience,
            "network",
            "mismatch",
            "network.activation, network.delta_min and network.patience must equal the top-level values",
        )?;
        // A search writes no best.json when every setting diverged; one that says so anyway (an
        // earlier binary's) holds no setting that scored.
        ensure(
            self.source != "search" || self.fitness.is_some() || self.validation.is_some(),
            "fitness",
            "null",
            "a search's tuned config needs a fitness: every setting of this search diverged, so it found none",
        )?;
        ensure(self.iterations >= 1, "iterations", self.iterations, "must be ≥ 1")?;
        ensure(self.episodes >= 1, "episodes", self.episodes, "must be ≥ 1")?;
        ensure(self.datasets >= 1, "datasets", self.datasets, "must be ≥ 1")?;
        // The embedded spec is what `reproduce` and `rollout` run: checked like a spec file, and the
        // chromosome must lie on its gene grid (else decoding would index past the activations).
        if let Some(spec) = &self.spec {
            spec.validate().map_err(|e| e.within("spec"))?;
            if let Some(c) = &self.chromosome {
                let b = spec.search.genes.bounds();
                ensure(
                    spec.search.genes.contains(c),
                    "chromosome",
                    format!("{c:?}"),
                    &format!("must lie in spec.search.genes {b:?}"),
                )?;
            }
        }
        // A network that could not hold out a validation row of its own search's datasets was
        // never trained; a comparison would fail at its first fit.
        let horizon = match &self.spec {
            Some(s) => s.env.env().horizon(),
            None => crate::env::EnvConfig::by_name(&self.env)?.env().horizon(),
        };
        crate::spec::holdout(&self.network, self.episodes, horizon, "episodes").map_err(|e| e.within("network"))?;
        Ok(())
    }

    /// Refuses a tuned config of another environment than `env`, naming the file it came from.
    pub fn check_env(&self, env: &str, origin: &Path) -> Result<()> {
        if self.env == env {
            return Ok(());
        }
        Err(Error::File {
            path: origin.to_path_buf(),
            message: format!("is a tuned config for {}, not {env}", self.env),
        })
    }

    /// Reads and validates a tuned config; errors name the file and the field.
    pub fn load(path: &Path) -> Result<TunedConfig> {
        let text = crate::store::read_input(path)?;
        Self::parse(&text, path)
    }

    fn parse(text: &str, origin: &Path) -> Result<TunedConfig> {
        let file_err = |message: String| Error::File { path: origin.to_path_buf(), message };
        let value = crate::store::parse_json(text, origin)?;
        crate::error::expect_object(&value, origin, "a tuned config")?;
        let t: TunedConfig = crate::error::from_json(value, origin, "")?;
        t.validate().map_err(|e| file_err(e.to_string()))?;
        Ok(t)
    }

    /// `thesis` (the shipped optimum for `env`) or a path to a `best.json`.
    pub fn resolve(name_or_path: &str, env: &str) -> Result<(TunedConfig, PathBuf)> {
        if name_or_path == "thesis" {
            let local = PathBuf::from(format!("searches/tuned/{env}.json"));
            // Anything there is the user's: a directory or FIFO is refused by `load`, as at a
            // spec's path, not silently replaced by the built-in copy.
            if crate::store::something_at(&local) {
                return Ok((Self::load(&local)?, local));
            }
            let (_, text) =
                THESIS.iter().find(|(n, _)| *n == env).ok_or_else(|| match crate::env::NAMES.contains(&env) {
                    false if !env.is_empty() => Error::Usage(format!(
                        "thesis: the thesis has no optimum for {env} (it tuned {} only); give a search's best.json",
                        crate::env::NAMES.join(", ")
                    )),
                    _ => Error::UnknownEnv {
                        name: crate::error::shortened(env.to_string()),
                        valid: crate::env::NAMES.join(", "),
                    },
                })?;
            let origin = PathBuf::from(format!("<built-in searches/tuned/{env}.json>"));
            return Ok((Self::parse(text, &origin)?, origin));
        }
        let p = PathBuf::from(name_or_path);
        Ok((Self::load(&p)?, p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_optima_ship_and_validate() {
        let (p, _) = TunedConfig::resolve("thesis", "pendulum").unwrap();
        assert_eq!((p.activation, p.delta_min, p.patience), (Activation::Sigmoid, 0.06, 5));
        let (c, _) = TunedConfig::resolve("thesis", "cartpole").unwrap();
        assert_eq!((c.delta_min, c.patience), (0.58, 601));
        let (b, _) = TunedConfig::resolve("thesis", "bicycle").unwrap();
        assert_eq!((b.delta_min, b.patience, b.network.hidden.clone()), (0.011, 75, vec![10, 10]));
    }

    #[test]
    fn missing_or_invalid_fields_are_named() {
        let text = THESIS[1].1;
        let mut v: serde_json::Value = serde_json::from_str(text).unwrap();
        v.as_object_mut().unwrap().remove("patience");
        let e = TunedConfig::parse(&v.to_string(), Path::new("t.json")).unwrap_err().to_string();
        assert!(e.contains("t.json") && e.contains("patience"), "{e}");
        let mut v: serde_json::Value = serde_json::from_str(text).unwrap();
        v["delta_min"] = serde_json::json!(-1.0);
        let e = TunedConfig::parse(&v.to_string(), Path::new("t.json")).unwrap_err().to_string();
        assert!(e.contains("delta_min"), "{e}");
        let mut v: serde_json::Value = serde_json::from_str(text).unwrap();
        v["network"]["hidden"] = serde_json::json!([]);
        let e = TunedConfig::parse(&v.to_string(), Path::new("t.json")).unwrap_err().to_string();
        assert!(e.contains("network.hidden"), "{e}");
    }
}

/// The validation summary kept in `best.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValidationSummary {
    /// Validation datasets.
    pub datasets: usize,
    /// The tuned setting's scores on them (`None` = diverged).
    pub scores: Vec<Option<f64>>,
    /// Their mean and 95 % interval.
    pub summary: Option<Summary>,
    /// What the validation found (see `validation.json`).
    pub note: String,
}
