//! Validating a search's winner. The best fitness is the maximum of hundreds of noisy
//! evaluations, so it is biased upward: the hall of fame's top settings, and the thesis's optimum
//! beside them, are re-scored on fresh validation datasets (a third stream, disjoint from the
//! search's and the comparisons'), with fresh network and evaluation seeds. The tuned config stays
//! the best fitness, as in the thesis; the validation says how much of it holds, and whether
//! another of the top settings validates better.
//!
//! Writes `validation.json` and the `validation` summary of `best.json`; results of its units live
//! in `validation/` (search-dataset units of the thesis optimum, when it was never drawn, in
//! `units/`), so running it again only reads them.

use super::chromosome::Decoded;
use super::records::fitness;
use super::setup::load_spec;
use super::units::{Evaluator, Role, expected_cost, setting_id, unit_id};
use crate::error::{Error, Result};
use crate::exec::Executor;
use crate::run_dir::{Budget, Stop, Units};
pub use crate::spec::ValidateRule;
use crate::stats::{Summary, interval, summarize};
use crate::store::{read_json, write_json};
use crate::tuned::TunedConfig;
pub use crate::tuned::ValidationSummary;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One setting's figures on the search and the validation datasets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// `hall of fame 1` … or `thesis optimum`.
    pub source: String,
    /// The setting's name, as in unit ids.
    pub setting: String,
    /// What it decodes to.
    #[serde(flatten)]
    pub decoded: Decoded,
    /// Fitness under the search (mean of `search_scores`; `None` when a dataset diverged).
    pub fitness: Option<f64>,
    /// Scores on the search datasets (`None` = diverged).
    pub search_scores: Vec<Option<f64>>,
    /// Mean and 95 % interval of the search scores (`None` when a dataset diverged).
    pub search: Option<Summary>,
    /// Scores on the validation datasets (`None` = diverged).
    pub validation_scores: Vec<Option<f64>>,
    /// Mean and 95 % interval of the validation scores (`None` when a dataset diverged).
    pub validation: Option<Summary>,
}

/// `validation.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Validation {
    /// The rule it ran with.
    pub rule: ValidateRule,
    /// The top settings in fitness order, then the thesis optimum when it is not among them.
    pub entries: Vec<Entry>,
    /// The tuned config's setting (the best fitness).
    pub tuned: String,
    /// The setting of the top `rule.top` with the best validation mean.
    pub best_validated: Option<String>,
    /// One line saying what the validation found.
    pub note: String,
}

/// The rule `validate` applies to the search in `dir`: its spec's `search.validate`, with
/// `top` and `datasets` given in its place; both are needed when the spec has none.
pub fn rule_for_search(dir: &Path, top: Option<usize>, datasets: Option<usize>) -> Result<ValidateRule> {
    let spec = load_spec(dir)?;
    match (&spec.search.validate, top, datasets) {
        (_, Some(top), Some(datasets)) => Ok(ValidateRule { top, datasets }),
        (Some(r), top, datasets) => {
            Ok(ValidateRule { top: top.unwrap_or(r.top), datasets: datasets.unwrap_or(r.datasets) })
        }
        (None, _, _) => Err(crate::error::Error::Usage(format!(
            "{}: its spec has no search.validate; give both --top and --datasets (e.g. --top 5 --datasets 10)",
            dir.join("spec.json").display()
        ))),
    }
}

fn summary(scores: &[Option<f64>]) -> Option<Summary> {
    let v: Option<Vec<f64>> = scores.iter().copied().collect();
    v.and_then(|v| summarize(&v))
}

#[derive(Deserialize)]
struct HallEntry {
    decoded: Decoded,
}

/// What [`run`] came to.
#[derive(Debug)]
pub enum Outcome {
    /// Every unit scored: the validation, also written to `validation.json` and `best.json`.
    Validated(Validation),
    /// Stopped between units (Ctrl-C, the time budget); running it again goes on where it stopped.
    Stopped(Stop),
}

/// Re-scores the top settings of the search in `dir` (which must have finished at least one
/// generation) through `exec`, until `budget` says stop, and writes `validation.json` and
/// `best.json`'s `validation`. Units already stored are read, not recomputed.
pub fn run(dir: &Path, rule: &ValidateRule, exec: &dyn Executor, budget: &Budget<'_>, quiet: bool) -> Result<Outcome> {
    rule.validate().map_err(|e| Error::File { path: dir.to_path_buf(), message: e.to_string() })?;
    let spec = load_spec(dir)?;
    let hall_path = dir.join("hall_of_fame.json");
    if !hall_path.is_file() {
        // Only "No such file" would leave the user to guess that the search is not far enough.
        return Err(Error::File {
            path: dir.to_path_buf(),
            message: "has no hall_of_fame.json: the search has not finished a generation yet; resume it \
                      (search --resume) and validate once it has"
                .into(),
        });
    }
    let hall: Vec<HallEntry> = read_json(&hall_path)?;
    let best_path = dir.join("best.json");
    let mut best = TunedConfig::load(&best_path)?;
    let env = spec.env.env().name();

    let mut picks: Vec<(String, Decoded)> =
        hall.iter().take(rule.top).enumerate().map(|(i, h)| (format!("hall of fame {}", i + 1), h.decoded)).collect();
    if let Ok((t, _)) = TunedConfig::resolve("thesis", env) {
        let d = Decoded { activation: t.activation, delta_min: t.delta_min, patience: t.patience };
        if !picks.iter().any(|(_, p)| setting_id(p) == setting_id(&d)) {
            picks.push(("thesis optimum".into(), d));
        }
    }

    let search = Evaluator::new(spec.clone(), dir);
    let validation = Evaluator::with_role(spec.clone(), dir, Role::Validation);
    validation.store().prepare()?;
    let s = &spec.search;
    // Search-dataset units (of the thesis optimum, when the search never drew it) first, then the
    // validation units; each list longest first, so the last units do not leave a core idle.
    let todo = |ev: &Evaluator, n: usize| -> Vec<String> {
        let mut ids: Vec<(String, f64)> = picks
            .iter()
            .flat_map(|(_, d)| (0..n).map(move |k| (unit_id(d, k), expected_cost(d, s.network.max_epochs))))
            .filter(|(id, _)| !ev.stored(id))
            .collect();
        ids.sort_by(|a, b| b.1.total_cmp(&a.1));
        ids.into_iter().map(|(id, _)| id).collect()
    };
    let (for_search, for_validation) = (todo(&search, s.datasets), todo(&validation, rule.datasets));
    if !quiet {
        eprintln!(
            "validating {} settings on {} validation datasets: {} units to run",
            picks.len(),
            rule.datasets,
            for_search.len() + for_validation.len()
        );
    }
    for (ev, ids) in [(&search, &for_search), (&validation, &for_validation)] {
        if let Some(stop) = exec.run(ev, ids, budget, &|_| {})? {
            return Ok(Outcome::Stopped(stop));
        }
    }

    let scores = |ev: &Evaluator, d: &Decoded, n: usize| -> Result<Vec<Option<f64>>> {
        (0..n)
            .map(|k| {
                let id = unit_id(d, k);
                ev.load_unit(&id).map(|u| u.score).ok_or_else(|| Error::Data(format!("missing unit result {id}")))
            })
            .collect()
    };
    let mut entries = Vec::with_capacity(picks.len());
    for (source, d) in &picks {
        let search_scores = scores(&search, d, s.datasets)?;
        let validation_scores = scores(&validation, d, rule.datasets)?;
        let f = fitness(&search_scores);
        entries.push(Entry {
            source: source.clone(),
            setting: setting_id(d),
            decoded: *d,
            fitness: f.is_finite().then_some(f),
            search: summary(&search_scores),
            search_scores,
            validation: summary(&validation_scores),
            validation_scores,
        });
    }

    let tuned =
        setting_id(&Decoded { activation: best.activation, delta_min: best.delta_min, patience: best.patience });
    let mean = |e: &Entry| e.validation.map_or(f64::NEG_INFINITY, |v| v.mean);
    let top: Vec<&Entry> = entries.iter().filter(|e| e.source != "thesis optimum").collect();
    let best_validated =
        top.iter().copied().max_by(|a, b| mean(a).total_cmp(&mean(b)).then(std::cmp::Ordering::Greater));
    let tuned_entry = entries.iter().find(|e| e.setting == tuned);
    let show = |e: &Entry| interval(e.validation, 3);
    let note = match (tuned_entry, best_validated) {
        (Some(t), Some(b)) if b.setting != t.setting && mean(b) > mean(t) => format!(
            "the tuned config ({}, fitness {}) validates at {}; {} ({}, fitness {}) validates better at {}",
            t.setting,
            fmt(t.fitness),
            show(t),
            b.source,
            b.setting,
            fmt(b.fitness),
            show(b)
        ),
        (Some(t), _) => format!(
            "the tuned config ({}, fitness {}) validates at {}, the best of the top {}",
            t.setting,
            fmt(t.fitness),
            show(t),
            top.len()
        ),
        (None, _) => format!("the tuned config {tuned} is not in the hall of fame's top {}", rule.top),
    };
    let v = Validation {
        rule: rule.clone(),
        tuned: tuned.clone(),
        best_validated: best_validated.map(|b| b.setting.clone()),
        note,
        entries,
    };
    let v_path = dir.join("validation.json");
    // Validating again with other caps discards the earlier result: say so rather than silently.
    if v_path.is_file() && read_json::<Validation>(&v_path).ok().is_none_or(|old| old.rule != v.rule) {
        eprintln!(
            "note: {}: replaced by this validation (the earlier one had other caps or did not parse)",
            v_path.display()
        );
    }
    write_json(&v_path, &v)?;
    best.validation = v.summary_of(&tuned);
    write_json(&best_path, &best)?;
    Ok(Outcome::Validated(v))
}

impl Validation {
    /// The summary for `best.json` when `setting` is the validated tuned config.
    pub fn summary_of(&self, setting: &str) -> Option<ValidationSummary> {
        let t = self.entries.iter().find(|e| e.setting == setting && self.tuned == setting)?;
        Some(ValidationSummary {
            datasets: self.rule.datasets,
            scores: t.validation_scores.clone(),
            summary: t.validation,
            note: self.note.clone(),
        })
    }

    /// The thesis optimum's entry, when it was scored (as itself or among the top settings).
    pub fn thesis_entry(&self, env: &str) -> Option<&Entry> {
        let (t, _) = TunedConfig::resolve("thesis", env).ok()?;
        let id = setting_id(&Decoded { activation: t.activation, delta_min: t.delta_min, patience: t.patience });
        self.entries.iter().find(|e| e.setting == id)
    }

    /// The thesis optimum's fitness under this search's fitness, when it was scored.
    pub fn thesis_fitness(&self, env: &str) -> Option<f64> {
        self.thesis_entry(env)?.fitness
    }

    /// The validation as a Markdown section of the search's report.
    pub fn markdown(&self) -> String {
        let ci = |s: &Option<Summary>| interval(*s, 3);
        let mut md = format!(
            "\n## Validation\n\nThe hall of fame's top {} and the thesis optimum, re-scored on {} validation datasets \
             (fresh datasets, network and evaluation seeds). Means with 95 % intervals (1.96·std/√n).\n\n",
            self.rule.top, self.rule.datasets
        );
        md.push_str("| | setting | fitness (search datasets) | validation |\n|---|---|---|---|\n");
        for e in &self.entries {
            let tuned = if e.setting == self.tuned { " (tuned)" } else { "" };
            md.push_str(&format!(
                "| {}{} | `{}` | {} | {} |\n",
                e.source,
                tuned,
                e.setting,
                ci(&e.search),
                ci(&e.validation)
            ));
        }
        md.push_str(&format!("\n{}.\n", self.note));
        md
    }
}

fn fmt(v: Option<f64>) -> String {
    v.map_or("−∞".into(), |x| format!("{x:.3}"))
}

/// The stored validation of a search, if it ran.
pub fn load(dir: &Path) -> Option<Validation> {
    read_json(&dir.join("validation.json")).ok()
}
