//! The tuned config (`best.json`) of a search's setting: the best individual's, or under
//! `search.select: validated` the validation's winner, rebuilt from the hall of fame.

use super::chromosome::{Chromosome, decode};
use super::records::IndividualRecord;
use super::units::{Evaluator, setting_id};
use crate::error::{Error, Result};
use crate::spec::Spec;
use crate::store::read_json;
use crate::tuned::TunedConfig;
use std::path::Path;

/// The tuned config of the best individual.
pub fn tuned(spec: &Spec, best: &IndividualRecord, generation: usize, ev: &Evaluator) -> TunedConfig {
    tuned_of(spec, &best.genes, best.fitness, &best.scores, generation, ev)
}

/// The tuned config of the setting `genes` decode to, first evaluated in `generation`.
pub fn tuned_of(
    spec: &Spec,
    genes: &Chromosome,
    fitness: Option<f64>,
    scores: &[Option<f64>],
    generation: usize,
    ev: &Evaluator,
) -> TunedConfig {
    let s = &spec.search;
    let decoded = decode(genes, &s.genes);
    TunedConfig {
        env: spec.env.env().name().to_string(),
        source: "search".into(),
        activation: decoded.activation,
        delta_min: decoded.delta_min,
        patience: decoded.patience,
        network: ev.network(&decoded),
        actions: s.actions,
        algorithm: s.algorithm,
        iterations: s.iterations,
        episodes: s.episodes,
        datasets: s.datasets,
        fitness,
        scores: scores.to_vec(),
        spec_hash: Some(spec.hash()),
        seed: spec.seed,
        generation: Some(generation),
        chromosome: Some(*genes),
        spec: Some(spec.clone()),
        validation: None,
        selection: None,
    }
}

/// The tuned config of `setting`, one of the hall of fame of the search in `dir` (how
/// `search.select: validated` makes the validation's winner the search's `best.json`).
pub fn tuned_for(dir: &Path, spec: &Spec, setting: &str) -> Result<TunedConfig> {
    #[derive(serde::Deserialize)]
    struct Hall {
        generation: usize,
        genes: Chromosome,
        fitness: Option<f64>,
        scores: Vec<Option<f64>>,
    }
    let path = dir.join("hall_of_fame.json");
    let hall: Vec<Hall> = read_json(&path)?;
    let h = hall
        .iter()
        .find(|h| setting_id(&decode(&h.genes, &spec.search.genes)) == setting)
        .ok_or_else(|| Error::File { path: path.clone(), message: format!("has no setting {setting}") })?;
    Ok(tuned_of(spec, &h.genes, h.fitness, &h.scores, h.generation, &Evaluator::new(spec.clone(), dir)))
}
