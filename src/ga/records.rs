//! The files a search writes about itself: `run.json` ([`RunInfo`]), `generations.jsonl`
//! ([`GenerationRecord`] lines) and `state.json` ([`RunState`]).

use super::chromosome::{Chromosome, Decoded};
use super::operators::Birth;
use crate::machine::Machine;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What was asked for, saved as `run.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// `search`.
    pub kind: String,
    /// Environment name.
    pub env: String,
    /// Where the spec came from.
    pub spec_source: String,
    /// Presets applied on top of it, in order.
    pub presets: Vec<String>,
    /// Command-line overrides, by spec field.
    pub overrides: BTreeMap<String, serde_json::Value>,
    /// When the run was created (UTC).
    pub created: String,
    /// bfqi-ga version that created it.
    pub version: String,
    /// The source commit it was built from (`+dirty` with uncommitted changes; `unknown` when
    /// built outside a git checkout).
    #[serde(default)]
    pub commit: String,
    /// Each later invocation that continued the run (`--resume`, or a batch resumed): when, and
    /// the commit of the binary, which may differ from `commit`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resumed: Vec<Resumed>,
    /// [`Spec::results_hash`] of `spec.json` when the run began (recorded at the first resume for
    /// runs created before it was): a resume refuses a spec.json changed since.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spec_hash: Option<String>,
    /// Every unit of the run carries a checksum: one that lacks it is damaged or edited, and is
    /// computed again. Set by runs created since checksums exist and by `bfqi-ga stamp`; units of
    /// an unmarked (older) run without one are read as before.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub checksummed: bool,
    /// Runs whose units this one took at its start (`search --units-from`), and how many.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub units_from: Vec<SharedUnits>,
    /// The machine of the invocation that created the run (absent in runs made before it was
    /// recorded): its wall times are that machine's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine: Option<Machine>,
    /// A gymnasium env's Python stack (Python, gymnasium, numpy, minari) when the run was
    /// created: its results are bit-identical only under the same versions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gymnasium: Option<crate::env::gymnasium::Versions>,
}

/// Units a search took from another run's cache (`search --units-from`), in `run.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SharedUnits {
    /// The run directory they came from, as given.
    pub dir: String,
    /// Units copied: those that verify (checksum, where they carry one) and were computed under
    /// this run's results hash.
    pub units: usize,
    /// Validation units copied likewise (absent in runs made before they were).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub validation: usize,
    /// `bfqi-ga tidy` removed taken units the search had not used: the next resume takes them
    /// again from `dir` before it goes on, so they are not recomputed.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub tidied: bool,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// One invocation that continued a search, in `run.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Resumed {
    /// When it started (UTC).
    pub at: String,
    /// The source commit of its binary.
    pub commit: String,
    /// The machine it ran on (absent in invocations made before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine: Option<Machine>,
}

impl Resumed {
    /// This invocation: now, this binary's commit, this machine.
    pub fn now() -> Resumed {
        Resumed { at: crate::store::now_utc().1, commit: env!("BFQI_GA_COMMIT").into(), machine: Some(Machine::this()) }
    }
}

/// Fitness from per-dataset scores: their mean, or −∞ if any run diverged.
pub fn fitness(scores: &[Option<f64>]) -> f64 {
    let mut sum = 0.0;
    for s in scores {
        match s {
            Some(v) => sum += v,
            None => return f64::NEG_INFINITY,
        }
    }
    sum / scores.len() as f64
}

pub(super) fn finite(f: f64) -> Option<f64> {
    f.is_finite().then_some(f)
}

/// One individual of a generation, as logged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IndividualRecord {
    /// Position in the generation.
    pub index: usize,
    /// The genes.
    pub genes: Chromosome,
    /// What they decode to.
    #[serde(flatten)]
    pub decoded: Decoded,
    /// The result's name ([`setting_id`]): individuals with the same setting share one evaluation.
    pub setting: String,
    /// Other individuals of this generation that decode alike, and so share this result.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shares_with: Vec<usize>,
    /// Score per search dataset run (`null` = diverged); a pruned individual has fewer.
    pub scores: Vec<Option<f64>>,
    /// Mean score; `null` when any dataset diverged (fitness −∞) or when pruned.
    pub fitness: Option<f64>,
    /// Pruned (`search.prune`): its datasets stopped once their mean fell below the cutoff.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub pruned: bool,
    /// What racing decided (`search.race`): stopped after some datasets with its p-value, or
    /// survived them all; absent when it was not raced (racing off, generation 0, an elite's
    /// setting, or diverged before a test).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub race: Option<super::racing::RaceRecord>,
    /// How it came about.
    pub origin: Origin,
    /// A child's parents (their positions in the previous generation), its genes after the
    /// interval crossover and before mutation, and whether it was mutated (thesis Appendix C).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub birth: Option<Birth>,
}

/// How an individual came about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Origin {
    /// Drawn at random for the first generation.
    Initial,
    /// Given (`--seed-config`, `search.seeded`) in the first generation.
    Seeded,
    /// Carried over unchanged from the previous generation.
    Elite,
    /// Bred from two parents of the previous generation.
    Child,
    /// Drawn at random for a later generation of a random search (`search.strategy: random`).
    Random,
}

impl IndividualRecord {
    /// The fitness used for ranking: −∞ when diverged or pruned.
    pub fn rank_fitness(&self) -> f64 {
        self.fitness.unwrap_or(f64::NEG_INFINITY)
    }

    /// Raced out (`search.race`): stopped as worse than every elite.
    pub fn raced_out(&self) -> bool {
        self.race.is_some_and(|r| r.stopped)
    }

    /// Stopped before its last dataset, by pruning or racing: never an elite or a parent.
    pub fn stopped_early(&self) -> bool {
        self.pruned || self.raced_out()
    }

    /// The mean of the scores run so far (a pruned individual's partial score).
    pub fn partial_mean(&self) -> Option<f64> {
        finite(fitness(&self.scores)).filter(|_| !self.scores.is_empty())
    }
}

/// Statistics of a generation's finite fitnesses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenerationStats {
    /// Lowest finite fitness.
    pub min: Option<f64>,
    /// Mean of the finite fitnesses.
    pub mean: Option<f64>,
    /// Highest fitness.
    pub max: Option<f64>,
    /// Population standard deviation of the finite fitnesses.
    pub std: Option<f64>,
    /// Individuals with fitness −∞ (a diverged run).
    pub diverged: usize,
    /// Individuals pruned (`search.prune`).
    #[serde(default)]
    pub pruned: usize,
    /// Individuals raced out (`search.race`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub raced: usize,
}

/// One line of `generations.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenerationRecord {
    /// 0-based generation.
    pub generation: usize,
    /// Every individual.
    pub individuals: Vec<IndividualRecord>,
    /// Fitness statistics.
    pub stats: GenerationStats,
    /// Units (setting × dataset) this generation needed that no earlier generation had: the
    /// FQI runs it cost. Shared settings, elites and settings seen before cost nothing.
    #[serde(default)]
    pub new_units: usize,
    /// Pruning's cutoff for this generation (`search.prune`): the previous generation's
    /// parent-pool line minus the margin; absent when pruning is off or in generation 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prune_below: Option<f64>,
    /// The elites' settings this generation's new settings were raced against (`search.race`);
    /// absent when racing is off or in generation 0.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub race_against: Vec<String>,
    /// Best individual so far (over all generations).
    pub best_so_far: IndividualRecord,
    /// Generation in which the best so far was found.
    pub best_generation: usize,
}

/// Where a search stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Running, or killed while running (then nobody holds its lock).
    Running,
    /// Ran to its end.
    Finished,
    /// Stopped early (Ctrl-C, the time budget); it resumes.
    Interrupted,
    /// Ended by an error (a write that failed, a full disk) or with no tuned config (every setting
    /// diverged); `reason` says which. `--resume` tries again from the stored units.
    Failed,
}

impl Phase {
    /// Its name, as `state.json` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Running => "running",
            Phase::Finished => "finished",
            Phase::Interrupted => "interrupted",
            Phase::Failed => "failed",
        }
    }
}

/// `state.json`: where a run stands.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunState {
    /// Running, finished, interrupted or failed.
    pub state: Phase,
    /// Generations completed.
    pub generation: usize,
    /// Generations planned.
    pub generations: usize,
    /// Best fitness so far.
    pub best_fitness: Option<f64>,
    /// Best settings so far.
    pub best: Option<Decoded>,
    /// Why it stopped (empty while running).
    pub reason: String,
    /// Last update (UTC).
    pub updated: String,
    /// Wall-clock seconds of each completed generation (summed over invocations).
    #[serde(default)]
    pub generation_seconds: Vec<f64>,
    /// Seconds spent so far in the generation under way.
    #[serde(default)]
    pub current_seconds: f64,
    /// Units of the generation under way: computed, and to compute (an upper bound with pruning).
    #[serde(default)]
    pub units_done: usize,
    /// See `units_done`.
    #[serde(default)]
    pub units_total: usize,
    /// Projected seconds to the end of the search if it runs every planned generation (the stall
    /// rule may end it sooner), refined as units finish.
    #[serde(default)]
    pub eta_seconds: Option<f64>,
}

impl RunState {
    /// Wall-clock seconds the search has run, over all invocations.
    pub fn elapsed(&self) -> f64 {
        self.generation_seconds.iter().sum::<f64>() + self.current_seconds
    }
}

/// The largest `generations.jsonl` read: a thesis search's is some 100 kB a generation at most.
pub const GENERATIONS_BYTES: u64 = 1 << 30;

/// Reads `generations.jsonl`.
pub fn read_generations(dir: &std::path::Path) -> crate::error::Result<Vec<GenerationRecord>> {
    let path = dir.join("generations.jsonl");
    let text = crate::store::read_text_within(&path, GENERATIONS_BYTES)?;
    text.lines()
        .enumerate()
        .map(|(i, l)| {
            serde_json::from_str(l)
                .map_err(|e| crate::error::Error::File { path: path.clone(), message: format!("line {}: {e}", i + 1) })
        })
        .collect()
}
