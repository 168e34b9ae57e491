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
use super::race::{self, End, Round};
use super::records::fitness;
use super::setup::load_spec;
use super::units::{Evaluator, Role, expected_cost, setting_id, unit_id};
use crate::error::{Error, Result};
use crate::exec::Executor;
use crate::run_dir::{Budget, Stop, Units};
use crate::spec::Select;
pub use crate::spec::{RaceRule, ValidateRule};
use crate::stats::{Paired, Summary, interval, paired, summarize};
use crate::store::{read_json, write_json};
use crate::tuned::TunedConfig;
pub use crate::tuned::{Selection, ValidationSummary};
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
    /// The setting `best.json` holds: the best fitness, or with `select: validated` the
    /// validation's winner.
    pub tuned: String,
    /// The setting of the top `rule.top` with the best validation mean (a race's winner).
    pub best_validated: Option<String>,
    /// One line saying what the validation found.
    pub note: String,
    /// The spec's `search.select` (left out when `fitness`).
    #[serde(default, skip_serializing_if = "Select::is_fitness")]
    pub select: Select,
    /// The best fitness's setting, when `tuned` is another (`select: validated`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub by_fitness: Option<String>,
    /// The race's rounds, when the rule races.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rounds: Vec<Round>,
    /// Why the race ended, when the rule races.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub race_end: Option<End>,
    /// The search validated, when this validation lives apart from it (`validate --into`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
}

/// The rule `validate` applies to the search in `dir`: its spec's `search.validate`, with what the
/// flags give in its place; `top` and `datasets` are both needed when the spec has none.
pub fn rule_for_search(dir: &Path, flags: &RuleFlags) -> Result<ValidateRule> {
    let spec = load_spec(dir)?;
    let (top, datasets) = (flags.top, flags.datasets);
    let mut rule = match (&spec.search.validate, top, datasets) {
        (spec_rule, Some(top), Some(datasets)) => {
            ValidateRule { top, datasets, race: spec_rule.as_ref().and_then(|r| r.race) }
        }
        (Some(r), top, datasets) => {
            ValidateRule { top: top.unwrap_or(r.top), datasets: datasets.unwrap_or(r.datasets), race: r.race }
        }
        (None, _, _) => {
            return Err(crate::error::Error::Usage(format!(
                "{}: its spec has no search.validate; give both --top and --datasets (e.g. --top 5 --datasets 10)",
                dir.join("spec.json").display()
            )));
        }
    };
    if flags.no_race {
        rule.race = None;
    } else if flags.race_first.is_some() || flags.race_step.is_some() {
        let base = rule.race;
        let (first, step) = match (flags.race_first.or(base.map(|r| r.first)), flags.race_step.or(base.map(|r| r.step)))
        {
            (Some(f), Some(s)) => (f, s),
            _ => {
                return Err(Error::Usage(
                    "--race-first and --race-step: give both (the spec has no search.validate.race)".into(),
                ));
            }
        };
        rule.race = Some(RaceRule { first, step, confidence: base.map_or(0.95, |r| r.confidence) });
    }
    rule.validate().map_err(|e| Error::Usage(format!("{e} (from the flags of bfqi-ga validate)")))?;
    Ok(rule)
}

/// What `bfqi-ga validate` was given in place of the spec's rule.
#[derive(Debug, Clone, Default)]
pub struct RuleFlags {
    /// `--top`.
    pub top: Option<usize>,
    /// `--datasets`.
    pub datasets: Option<usize>,
    /// `--race-first`.
    pub race_first: Option<usize>,
    /// `--race-step`.
    pub race_step: Option<usize>,
    /// `--no-race`: score every setting on every dataset.
    pub no_race: bool,
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
    Validated(Box<Validation>),
    /// Stopped between units (Ctrl-C, the time budget); running it again goes on where it stopped.
    Stopped(Stop),
}

/// Re-scores the top settings of the search in `dir` (which must have finished at least one
/// generation) through `exec`, until `budget` says stop, and writes `validation.json` and
/// `best.json`'s `validation`. Units already stored are read, not recomputed.
pub fn run(dir: &Path, rule: &ValidateRule, exec: &dyn Executor, budget: &Budget<'_>, quiet: bool) -> Result<Outcome> {
    run_into(&Target { source: dir, out: dir, select: None }, rule, exec, budget, quiet)
}

/// Where a validation reads its search and writes its results.
#[derive(Debug, Clone, Copy)]
pub struct Target<'a> {
    /// The search's run directory.
    pub source: &'a Path,
    /// Where `validation.json`, `best.json` and new units go: `source` itself, or (`validate
    /// --into`) a directory of its own, so that a search's committed validation stays as it is
    /// while another rule is tried beside it.
    pub out: &'a Path,
    /// The winner rule in place of the spec's `search.select` (`validate --select`).
    pub select: Option<Select>,
}

impl Target<'_> {
    fn apart(&self) -> bool {
        self.source != self.out
    }

    fn evaluator(&self, spec: &crate::spec::Spec, role: Role) -> Evaluator {
        if self.apart() {
            Evaluator::reading_from(spec.clone(), self.source, self.out, role)
        } else {
            Evaluator::with_role(spec.clone(), self.source, role)
        }
    }
}

/// [`run`] for a [`Target`]: with `out` apart from `source`, the search is only read (units it
/// lacks are computed into `out`) and `validation.json` records the search it validated.
pub fn run_into(
    t: &Target<'_>,
    rule: &ValidateRule,
    exec: &dyn Executor,
    budget: &Budget<'_>,
    quiet: bool,
) -> Result<Outcome> {
    let dir = t.source;
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
            picks.push((THESIS.into(), d));
        }
    }

    let search = t.evaluator(&spec, Role::Search);
    let validation = t.evaluator(&spec, Role::Validation);
    validation.store().prepare()?;
    if t.apart() {
        search.store().prepare()?;
    }
    let s = &spec.search;
    // Search-dataset units (of the thesis optimum, when the search never drew it) first, then the
    // validation units; each list longest first, so the last units do not leave a core idle.
    let todo = |ev: &Evaluator, n: usize, picks: &[(String, Decoded)]| -> Vec<String> {
        let mut ids: Vec<(String, f64)> = picks
            .iter()
            .flat_map(|(_, d)| (0..n).map(move |k| (unit_id(d, k), expected_cost(d, s.network.max_epochs))))
            .filter(|(id, _)| !ev.stored(id))
            .collect();
        ids.sort_by(|a, b| b.1.total_cmp(&a.1));
        ids.into_iter().map(|(id, _)| id).collect()
    };
    let for_search = todo(&search, s.datasets, &picks);
    if let Some(stop) = exec.run(&search, &for_search, budget, &|_| {})? {
        return Ok(Outcome::Stopped(stop));
    }
    let scores = |ev: &Evaluator, d: &Decoded, n: usize| -> Result<Vec<Option<f64>>> {
        (0..n)
            .map(|k| {
                let id = unit_id(d, k);
                ev.load_unit(&id).map(|u| u.score).ok_or_else(|| Error::Data(format!("missing unit result {id}")))
            })
            .collect()
    };
    // The settings that race (the hall of fame's top) and the thesis optimum, which is a reference:
    // it gets the datasets the survivors get, and is never dropped nor selected.
    let racing: Vec<usize> = (0..picks.len()).filter(|&i| picks[i].0 != THESIS).collect();
    let reference: Option<usize> = picks.iter().position(|(src, _)| src == THESIS);
    // Validation datasets each pick gets: all of them without a race, its rounds' with one.
    let mut got = vec![rule.datasets; picks.len()];
    let (rounds, race_end) = match &rule.race {
        None => {
            let for_validation = todo(&validation, rule.datasets, &picks);
            if !quiet {
                eprintln!(
                    "validating {} settings on {} validation datasets: {} units to run",
                    picks.len(),
                    rule.datasets,
                    for_search.len() + for_validation.len()
                );
            }
            if let Some(stop) = exec.run(&validation, &for_validation, budget, &|_| {})? {
                return Ok(Outcome::Stopped(stop));
            }
            (Vec::new(), None)
        }
        Some(race_rule) => {
            let names: Vec<String> = racing.iter().map(|&i| setting_id(&picks[i].1)).collect();
            let mut stopped = None;
            let race = race::run(&names, race_rule, rule.datasets, |alive, n| {
                let these: Vec<(String, Decoded)> =
                    alive.iter().map(|&a| racing[a]).chain(reference).map(|i| picks[i].clone()).collect();
                for &a in alive {
                    got[racing[a]] = n;
                }
                if let Some(r) = reference {
                    got[r] = n;
                }
                let ids = todo(&validation, n, &these);
                if !quiet {
                    eprintln!(
                        "validation race: {} settings on {n} validation datasets: {} units to run",
                        alive.len(),
                        ids.len()
                    );
                }
                if let Some(stop) = exec.run(&validation, &ids, budget, &|_| {})? {
                    stopped = Some(stop);
                    return Ok(None);
                }
                alive.iter().map(|&a| scores(&validation, &picks[racing[a]].1, n)).collect::<Result<Vec<_>>>().map(Some)
            })?;
            match race {
                Some(r) => (r.rounds, Some(r.end)),
                None => return Ok(Outcome::Stopped(stopped.expect("a race stops only at a stop"))),
            }
        }
    };

    let mut entries = Vec::with_capacity(picks.len());
    for ((source, d), n) in picks.iter().zip(&got) {
        let search_scores = scores(&search, d, s.datasets)?;
        let validation_scores = scores(&validation, d, *n)?;
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

    let by_fitness =
        setting_id(&Decoded { activation: best.activation, delta_min: best.delta_min, patience: best.patience });
    let by_fitness = match best.selection.as_ref() {
        // A best.json already holding the validated winner: the fitness winner is recorded beside it.
        Some(sel) => sel.fitness.clone(),
        None => by_fitness,
    };
    let mean = |e: &Entry| e.validation.map_or(f64::NEG_INFINITY, |v| v.mean);
    let top: Vec<&Entry> = entries.iter().filter(|e| e.source != THESIS).collect();
    let best_validated = match rounds.last() {
        Some(last) => entries.iter().find(|e| e.setting == last.leader),
        None => top.iter().copied().max_by(|a, b| mean(a).total_cmp(&mean(b)).then(std::cmp::Ordering::Greater)),
    };
    let fitness_entry = entries.iter().find(|e| e.setting == by_fitness);
    let show = |e: &Entry| interval(e.validation, 3);
    let mut note = match (fitness_entry, best_validated) {
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
        (None, _) => format!("the tuned config {by_fitness} is not in the hall of fame's top {}", rule.top),
    };
    if let (Some(last), Some(end)) = (rounds.last(), race_end) {
        note = match end {
            End::Separated => format!(
                "{note}; the race separated {} from every other at {:.0} % after {} rounds ({} datasets)",
                last.leader,
                rule.race.map_or(95.0, |r| r.confidence * 100.0),
                last.round,
                last.datasets
            ),
            End::Budget => format!(
                "{note}; the race spent its {} datasets with {} settings left, indistinguishable from its leader {}",
                last.datasets,
                last.standings.iter().filter(|s| s.verdict != race::Verdict::Dropped).count(),
                last.leader
            ),
        };
    }
    let select = t.select.unwrap_or(spec.search.select);
    let tuned = match (select, best_validated) {
        (Select::Validated, Some(b)) => b.setting.clone(),
        _ => by_fitness.clone(),
    };
    let v = Validation {
        rule: rule.clone(),
        tuned: tuned.clone(),
        best_validated: best_validated.map(|b| b.setting.clone()),
        note,
        select,
        by_fitness: (tuned != by_fitness).then(|| by_fitness.clone()),
        rounds,
        race_end,
        entries,
        source: t.apart().then(|| dir.display().to_string()),
    };
    let v_path = t.out.join("validation.json");
    // Validating again with other caps discards the earlier result: say so rather than silently.
    if v_path.is_file() && read_json::<Validation>(&v_path).ok().is_none_or(|old| old.rule != v.rule) {
        eprintln!(
            "note: {}: replaced by this validation (the earlier one had other caps or did not parse)",
            v_path.display()
        );
    }
    write_json(&v_path, &v)?;
    if tuned != setting_id(&Decoded { activation: best.activation, delta_min: best.delta_min, patience: best.patience })
    {
        best = super::winner::tuned_for(dir, &spec, &tuned)?;
    }
    best.validation = v.summary_of(&tuned);
    best.selection = v.selection(&by_fitness);
    if t.apart() {
        // Kept apart, best.json records the rule that chose it, as a search run with that rule
        // would, so that it reads (and reproduces) the same as the in-search one.
        let mut chosen = spec.clone();
        chosen.search.validate = Some(rule.clone());
        chosen.search.select = select;
        best.spec_hash = Some(chosen.hash());
        best.spec = Some(chosen);
    }
    write_json(&t.out.join("best.json"), &best)?;
    Ok(Outcome::Validated(Box::new(v)))
}

/// The thesis optimum's source label in a validation.
const THESIS: &str = "thesis optimum";

impl Validation {
    /// The settings of the top that the validation cannot tell from its winner at 95 %: a race's
    /// survivors besides its leader, or, without a race, those whose paired validation difference
    /// to the winner holds 0.
    pub fn indistinguishable(&self) -> Vec<String> {
        if let Some(last) = self.rounds.last() {
            return last
                .standings
                .iter()
                .filter(|s| s.verdict == race::Verdict::Kept)
                .map(|s| s.setting.clone())
                .collect();
        }
        let Some(w) = self.best_validated.as_ref().and_then(|b| self.entries.iter().find(|e| &e.setting == b)) else {
            return Vec::new();
        };
        self.entries
            .iter()
            .filter(|e| e.source != THESIS && e.setting != w.setting)
            .filter(|e| self.vs(e, w, false).is_some_and(|p| p.sign() == 0))
            .map(|e| e.setting.clone())
            .collect()
    }

    /// `a` minus `b`, paired by dataset on the datasets both have, with a t interval at the race's
    /// confidence (0.95 without a race): on the validation datasets, or on the search's.
    pub fn vs(&self, a: &Entry, b: &Entry, search: bool) -> Option<Paired> {
        let (x, y) =
            if search { (&a.search_scores, &b.search_scores) } else { (&a.validation_scores, &b.validation_scores) };
        let n = x.len().min(y.len());
        paired(&x[..n], &y[..n], self.confidence())
    }

    /// The confidence of the paired intervals: the race's, else 0.95.
    pub fn confidence(&self) -> f64 {
        self.rule.race.map_or(0.95, |r| r.confidence)
    }

    /// The setting with the best fitness.
    pub fn fitness_winner(&self) -> &str {
        self.by_fitness.as_deref().unwrap_or(&self.tuned)
    }

    /// What `best.json` records of the choice between the two winners: nothing under the thesis's
    /// rule (`select: fitness`), so its results stay byte-identical to a search without the field.
    pub fn selection(&self, by_fitness: &str) -> Option<Selection> {
        (self.select == Select::Validated).then(|| Selection {
            select: self.select,
            fitness: by_fitness.to_string(),
            validated: self.best_validated.clone(),
            indistinguishable: self.indistinguishable(),
        })
    }

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

    /// The validation as a Markdown section of the search's report on `env`.
    pub fn markdown(&self, env: &str) -> String {
        let ci = |s: &Option<Summary>| interval(*s, 3);
        // A gymnasium env has no thesis optimum to score beside the top settings.
        let thesis = if TunedConfig::resolve("thesis", env).is_ok() { " and the thesis optimum" } else { "" };
        let mut md = format!(
            "\n## Validation\n\nThe hall of fame's top {}{thesis}, re-scored on {} validation datasets \
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
        md.push_str(&self.race_markdown());
        md.push_str(&self.winners_markdown());
        md
    }

    /// The race's rounds, when it raced.
    fn race_markdown(&self) -> String {
        let Some(r) = self.rule.race else { return String::new() };
        let mut md = format!(
            "\n### Race\n\nEvery setting of the top {} starts on {} validation datasets; after each round, a setting \
             whose paired difference to the round's leader lies below 0 at {:.0} % (Student t) is dropped, and the \
             survivors get {} more, up to {}. The thesis optimum is scored alongside as a reference and does not race.\n\n",
            self.rule.top,
            r.first,
            r.confidence * 100.0,
            r.step,
            self.rule.datasets
        );
        md.push_str("| round | datasets | setting | validation mean | minus the leader | verdict |\n|---|---|---|---|---|---|\n");
        for round in &self.rounds {
            for st in &round.standings {
                md.push_str(&format!(
                    "| {} | {} | `{}` | {} | {} | {} |\n",
                    round.round,
                    round.datasets,
                    st.setting,
                    st.mean.map_or("−∞".into(), |m| format!("{m:.3}")),
                    st.vs_leader.map_or("—".into(), |p| p.show(3)),
                    match st.verdict {
                        race::Verdict::Leader => "leader",
                        race::Verdict::Kept => "kept",
                        race::Verdict::Dropped => "dropped",
                    }
                ));
            }
        }
        let end = match self.race_end {
            Some(End::Separated) => "its leader was separated from every other setting",
            Some(End::Budget) => "the budget was spent with several settings left",
            None => "it did not end",
        };
        md.push_str(&format!("\nThe race ended after {} rounds: {end}.\n", self.rounds.len()));
        md
    }

    /// Which winner `best.json` holds, and what the validation cannot tell apart from the best.
    fn winners_markdown(&self) -> String {
        let Some(validated) = &self.best_validated else { return String::new() };
        let by_fitness = self.fitness_winner();
        let others = self.indistinguishable();
        let list = if others.is_empty() {
            "none".to_string()
        } else {
            others.iter().map(|s| format!("`{s}`")).collect::<Vec<_>>().join(", ")
        };
        let mut md = String::from("\n");
        if validated == by_fitness {
            md.push_str(&format!(
                "The best fitness, `{by_fitness}`, is also the validation's winner (`search.select: {}`).",
                self.select.name()
            ));
        } else {
            md.push_str(&format!(
                "**The two winners differ**: the best fitness is `{by_fitness}`, the validation's winner `{validated}`; \
                 best.json holds `{}` (`search.select: {}`).",
                self.tuned,
                self.select.name()
            ));
        }
        md.push_str(&format!(" Indistinguishable from the validation's winner at 95 %: {list}.\n"));
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
