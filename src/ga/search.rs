//! The genetic search (`bfqi-ga search`, SPEC §5): generations of chromosomes, each scored by FQI on
//! the search datasets, stored unit by unit in a run directory so that an interrupted search resumes
//! where it stopped and ends bit-identical to one never interrupted.
//!
//! Run directory layout:
//! - `run.json` — what was asked (spec source, presets, overrides) and `spec.json`, the resolved spec;
//! - `units/<genes>.d<i>.json` — one FQI run of a chromosome on a search dataset (written atomically);
//! - `generations.jsonl`, `hall_of_fame.json`, `best.json` (the tuned config), `fitness.csv`,
//!   `fitness.png`, `fitness.svg`, and `state.json` (running / finished / interrupted / failed).
//!
//! A search is replayed from generation 0 on every start: chromosomes whose unit files exist are
//! read, not retrained, so resuming is just running again.

use super::chromosome::{Chromosome, Decoded, decode};
use super::operators::{Birth, initial_population, next_generation, random_generation, rank};
use super::prune;
use super::racing::{self, RaceRecord};
use super::records::finite;
pub use super::records::{
    GenerationRecord, GenerationStats, IndividualRecord, Origin, Phase, Resumed, RunInfo, RunState, fitness,
};
pub use super::reproduce::{Reproduction, reproduce};
use super::runner::{Clock, Runner, StateInfo, write_state};
pub use super::setup::{
    SearchOverrides, check_units_from, create, extend, load_spec, prepare, resolve, retake_units, share_units, stamp,
};
use super::units::setting_id;
pub use super::units::{Evaluator, UnitResult, describe, parse_unit_id, unit_id};
use crate::error::{Error, Result};
use crate::exec::Executor;
use crate::progress::{Progress, human};
use crate::run_dir::{Budget, Ending, Stop, UnitStore};
use crate::spec::{Spec, Strategy};
use crate::stats::summarize;
use crate::store::{self, RunLock, read_json, write_atomic, write_json};
use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Mutex;

/// The stored scores of setting `s` on datasets `0..n`, as far as they run without a gap.
fn stored_scores(ev: &Evaluator, s: &Decoded, n: usize) -> Vec<Option<f64>> {
    (0..n).map_while(|d| ev.load_unit(&unit_id(s, d)).map(|u| u.score)).collect()
}

/// The record of individual `index`, from the stored scores of its setting; `raced` is what racing
/// decided for the setting (the scores its record keeps, and the decision), if it was raced.
fn record_for(
    index: usize,
    c: &Chromosome,
    ev: &Evaluator,
    origin: Origin,
    birth: Option<Birth>,
    pruned: bool,
    raced: Option<&(usize, Option<RaceRecord>)>,
) -> Result<IndividualRecord> {
    let s = &ev.spec().search;
    let decoded = decode(c, &s.genes);
    let mut scores = stored_scores(ev, &decoded, s.datasets);
    let race = raced.and_then(|(keep, r)| {
        scores.truncate(*keep);
        *r
    });
    let stopped = pruned || race.is_some_and(|r| r.stopped);
    let complete = scores.len() == s.datasets;
    if !complete && !stopped && !scores.contains(&None) {
        let id = unit_id(&decoded, scores.len());
        return Err(Error::File { path: ev.unit_path(&id), message: "missing unit result after evaluation".into() });
    }
    let f = if complete && !stopped { fitness(&scores) } else { f64::NEG_INFINITY };
    Ok(IndividualRecord {
        index,
        genes: *c,
        decoded,
        setting: setting_id(&decoded),
        shares_with: Vec::new(),
        scores,
        fitness: finite(f),
        pruned,
        race,
        origin,
        birth,
    })
}

fn stats(records: &[IndividualRecord]) -> GenerationStats {
    let f: Vec<f64> = records.iter().filter_map(|r| r.fitness).collect();
    let s = summarize(&f);
    let pruned = records.iter().filter(|r| r.pruned).count();
    let raced = records.iter().filter(|r| r.raced_out()).count();
    GenerationStats {
        min: f.iter().copied().reduce(f64::min),
        mean: s.map(|s| s.mean),
        max: f.iter().copied().reduce(f64::max),
        std: s.map(|s| s.std),
        diverged: records.len() - f.len() - pruned - raced,
        pruned,
        raced,
    }
}

/// The seed of the GA's own streams (initial population, breeding): from the master seed and the
/// environment, so searches of different environments with one master seed draw different
/// populations.
pub fn ga_seed(spec: &Spec) -> u64 {
    crate::rng::derive(spec.seed, &crate::rng::purpose::ga(spec.env.env().name()), &[])
}

/// Runs (or resumes) the search in `dir` until it ends or `budget` says stop. Unit results already
/// stored are reused. A finished search whose spec has `search.validate` then validates its winner
/// ([`super::validate`]).
pub fn run(dir: &Path, exec: &dyn Executor, budget: &Budget<'_>, quiet: bool) -> Result<Ending> {
    let spec = load_spec(dir)?;
    let lock = RunLock::acquire(dir)?;
    let path = dir.join("run.json");
    let mut info: RunInfo = read_json(&path)?;
    let hash = spec.run_hash();
    match &info.spec_hash {
        Some(h) if *h != hash => {
            return Err(Error::File {
                path: dir.join("spec.json"),
                message: format!(
                    "changed since the run began (results hash {hash}, run.json records {h}): resuming would mix \
                     results of two specs; restore it or start a new run"
                ),
            });
        }
        _ => {}
    }
    if dir.join("state.json").is_file() {
        // A run that began before: say which binary continues it.
        info.resumed.push(Resumed::now());
        info.spec_hash = Some(hash);
        write_json(&path, &info)?;
    }
    // What a kill can leave: a deleted units/ is made again, and temporary files of interrupted
    // atomic writes are removed (the lock is ours, so no writer is alive).
    store::remove_temporaries(dir)?;
    UnitStore::units(dir).prepare()?;
    retake_units(dir, quiet)?;
    // Whatever ends the run with an error, state.json says so (it would read `running`).
    let ending = run_to_end(dir, &spec, exec, budget, quiet).inspect_err(|e| {
        let text = e.to_string();
        let text = text.strip_prefix(&format!("{}: ", dir.display())).unwrap_or(&text).to_string();
        // Every setting having diverged is the search's result, which a resume would only replay.
        let reason =
            if matches!(e, Error::Failed(_)) { text } else { format!("{text} (resume it once that is fixed)") };
        mark_failed(dir, &reason, spec.search.stop.generations)
    })?;
    drop(lock);
    Ok(ending)
}

/// Records in `state.json` that the run failed and why; a failure to write it (the disk that
/// failed the run) leaves the error being reported as the one the user sees. A run that failed
/// before its first `state.json` (a gymnasium worker that died collecting the first dataset) gets
/// one, so `status` shows the failure rather than `not started`.
fn mark_failed(dir: &Path, reason: &str, generations: usize) {
    let path = dir.join("state.json");
    let state = match read_json::<RunState>(&path) {
        Ok(state) => Some(state),
        Err(_) if !path.exists() => Some(RunState {
            state: Phase::Failed,
            generation: 0,
            generations,
            best_fitness: None,
            best: None,
            reason: String::new(),
            updated: String::new(),
            generation_seconds: Vec::new(),
            current_seconds: 0.0,
            units_done: 0,
            units_total: 0,
            eta_seconds: None,
        }),
        Err(_) => None,
    };
    if let Some(mut state) = state {
        state.state = Phase::Failed;
        state.reason = reason.to_string();
        state.eta_seconds = None;
        state.updated = store::now_utc().1;
        let _ = write_json(&path, &state);
    }
}

/// The generations, then the validation a finished search's spec asks for.
fn run_to_end(dir: &Path, spec: &Spec, exec: &dyn Executor, budget: &Budget<'_>, quiet: bool) -> Result<Ending> {
    let ending = run_generations(dir, spec, exec, budget, quiet)?;
    if matches!(ending, Ending::Finished(_)) {
        let state: RunState = read_json(&dir.join("state.json"))?;
        if state.best_fitness.is_none() {
            // Every individual scored −∞: the records say so, no best.json was written, and the
            // command fails (exit 1).
            return Err(Error::Failed(format!(
                "{}: every setting diverged on some dataset (fitness −∞ throughout): no tuned config, so no \
                 best.json; see the units' `diverged` reasons",
                dir.display()
            )));
        }
    }
    if let (Ending::Finished(_), Some(rule)) = (&ending, &spec.search.validate) {
        match super::validate::run(dir, rule, exec, budget, quiet)? {
            // The generations are complete: resuming replays them and goes on with the validation.
            super::validate::Outcome::Stopped(stop) => {
                let path = dir.join("state.json");
                let mut state: RunState = read_json(&path)?;
                state.state = Phase::Interrupted;
                state.reason = format!("{stop}, during the validation");
                write_json(&path, &state)?;
                return Ok(Ending::Stopped(stop));
            }
            super::validate::Outcome::Validated(v) => {
                if !quiet {
                    eprintln!("validation: {}", v.note);
                }
            }
        }
        crate::report::search::write(dir)?;
    }
    Ok(ending)
}

fn run_generations(dir: &Path, spec: &Spec, exec: &dyn Executor, budget: &Budget<'_>, quiet: bool) -> Result<Ending> {
    let spec = spec.clone();
    let ev = Evaluator::new(spec.clone(), dir);
    // Fail early on a dataset that cannot be encoded (e.g. per_action on continuous actions).
    ev.dataset(0)?;
    let s = &spec.search;
    let progress = Progress::new("generations", s.stop.generations as u64, quiet);
    progress.line(&format!("search {} → {}", spec.env.env().name(), dir.display()));
    let runner =
        Runner { dir, spec: &spec, ev: &ev, exec, budget, progress: &progress, clock: Mutex::new(Clock::resume(dir)) };

    let seed = ga_seed(&spec);
    let mut population = initial_population(seed, &s.genes, s.ga.population);
    let mut origins = vec![Origin::Initial; population.len()];
    // Given configs take the first places; the other individuals keep their own random streams.
    for (i, c) in s.seeded.iter().enumerate() {
        population[i] = *c;
        origins[i] = Origin::Seeded;
    }
    let mut births: Vec<Option<Birth>> = vec![None; population.len()];
    let mut records: Vec<GenerationRecord> = Vec::new();
    let mut best: Option<(IndividualRecord, usize)> = None;
    let mut hall: Vec<(IndividualRecord, usize)> = Vec::new();
    let mut stall = 0usize;
    // Units needed by earlier generations, so each generation can say what it cost.
    let mut seen: HashSet<String> = HashSet::new();
    // Pruning's cutoff: the previous generation's parent-pool line, known before any unit of this
    // generation runs, so the decisions do not depend on thread count, order or executor.
    let mut prune_below: Option<f64> = None;
    // Racing's elites: the previous generation's best with a finite fitness (their settings and
    // full scores), likewise known before any unit of this generation runs.
    let mut elites: Vec<(String, Vec<Option<f64>>)> = Vec::new();
    {
        let c = runner.clock.lock().expect("clock");
        let info = StateInfo {
            phase: Phase::Running,
            generation: c.generation_seconds.len().min(s.stop.generations),
            best: None,
            reason: "",
        };
        write_state(dir, &spec, &info, &c)?;
    }

    for g in 0..s.stop.generations {
        let settings: Vec<Decoded> = population.iter().map(|c| decode(c, &s.genes)).collect();
        // Each distinct setting once, in order of first appearance.
        let mut distinct: Vec<Decoded> = Vec::new();
        for d in &settings {
            if !distinct.iter().any(|x| setting_id(x) == setting_id(d)) {
                distinct.push(*d);
            }
        }
        progress.start_stage(&format!("gen {g}"), 0);
        let mut pruned: HashSet<String> = HashSet::new();
        let mut raced: Raced = HashMap::new();
        let race = s.race.filter(|_| !elites.is_empty());
        let stopped = match prune_below.filter(|_| s.prune.enabled) {
            None if race.is_some() => {
                // Never raced: the elites compared against, and every individual carried over as an
                // elite (one with fitness −∞ is not compared against, but is not stopped either).
                let exempt: HashSet<String> = elites
                    .iter()
                    .map(|(e, _)| e.clone())
                    .chain(
                        settings.iter().zip(&origins).filter(|(_, o)| **o == Origin::Elite).map(|(x, _)| setting_id(x)),
                    )
                    .collect();
                let (stop, decided) =
                    race_generation(&runner, g, &distinct, &elites, &exempt, best.as_ref().map(|b| &b.0))?;
                raced = decided;
                stop
            }
            None => {
                let want: Vec<(Decoded, usize)> =
                    distinct.iter().flat_map(|x| (0..s.datasets).map(move |d| (*x, d))).collect();
                runner.run(g, &want, best.as_ref().map(|b| &b.0))?
            }
            Some(cutoff) => {
                // Each setting's datasets in order, as a chain: once one is stored, the setting is
                // judged on every score it has, and runs its next dataset unless its mean so far
                // is below the cutoff (pruned) or it diverged or is complete (closed). A verdict
                // depends only on the setting's own scores and the previous generation's cutoff,
                // so no barrier between datasets is needed, and the verdicts do not depend on
                // thread count, completion order or executor. A setting scored in full before is
                // judged by its fitness, never pruned; one scored further in an earlier generation
                // (or before an interruption) is judged on all it has, which gives the verdict a
                // dataset-by-dataset evaluation would reach (it stops at the first mean below).
                let pruned_now: Mutex<HashSet<String>> = Mutex::new(HashSet::new());
                let next = |x: &Decoded| -> Option<usize> {
                    let sc = stored_scores(&ev, x, s.datasets);
                    match prune::decide(&sc, s.datasets, &s.prune, cutoff) {
                        prune::Verdict::Open => Some(sc.len()),
                        prune::Verdict::Pruned => {
                            pruned_now.lock().expect("pruned").insert(setting_id(x));
                            None
                        }
                        prune::Verdict::Closed => None,
                    }
                };
                let first: Vec<(Decoded, usize)> = distinct.iter().filter_map(|x| next(x).map(|d| (*x, d))).collect();
                let stopped = runner.run_chained(g, &first, &next, best.as_ref().map(|b| &b.0))?;
                pruned = pruned_now.into_inner().expect("pruned");
                stopped
            }
        };
        if let Some(stop) = stopped {
            progress.finish();
            let c = runner.clock.lock().expect("clock");
            let reason = stop.to_string();
            let info = StateInfo {
                phase: Phase::Interrupted,
                generation: g,
                best: best.as_ref().map(|b| &b.0),
                reason: &reason,
            };
            write_state(dir, &spec, &info, &c)?;
            return Ok(Ending::Stopped(stop));
        }

        let mut individuals: Vec<IndividualRecord> = population
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let id = setting_id(&settings[i]);
                record_for(i, c, &ev, origins[i], births[i], pruned.contains(&id), raced.get(&id))
            })
            .collect::<Result<_>>()?;
        for i in 0..individuals.len() {
            let key = individuals[i].setting.clone();
            individuals[i].shares_with =
                (0..individuals.len()).filter(|&j| j != i && individuals[j].setting == key).collect();
        }
        // The units the individuals' scores used, as the report counts them: not every stored one,
        // since a search with --units-from holds units a raced-out setting never ran.
        let mut new_units = 0;
        for ind in &individuals {
            for d in 0..ind.scores.len() {
                if seen.insert(unit_id(&ind.decoded, d)) {
                    new_units += 1;
                }
            }
        }
        let fit: Vec<f64> = individuals.iter().map(IndividualRecord::rank_fitness).collect();
        let eligible: Vec<bool> = individuals.iter().map(|r| !r.stopped_early()).collect();
        let mut order: Vec<usize> = rank(&fit).into_iter().filter(|&i| eligible[i]).collect();
        if order.is_empty() {
            // Everyone pruned (possible only without elites): rank them all, as −∞.
            order = rank(&fit);
        }
        let top = &individuals[order[0]];
        let improved = match &best {
            None => true,
            Some((b, _)) => fit[top.index] > b.rank_fitness(),
        };
        if improved {
            best = Some((top.clone(), g));
            stall = 0;
        } else {
            stall += 1;
        }
        for r in individuals.iter().filter(|r| !r.stopped_early()) {
            if !hall.iter().any(|(h, _)| h.setting == r.setting) {
                hall.push((r.clone(), g));
            }
        }
        // Best first; ties keep the earlier discovery first (stable sort).
        hall.sort_by(|a, b| b.0.rank_fitness().total_cmp(&a.0.rank_fitness()));
        hall.truncate(10);
        let (b, bg) = best.clone().expect("set above");
        let st = stats(&individuals);
        let this_cutoff = prune_below.filter(|_| s.prune.enabled);
        // The next generation's cutoff: this generation's parent-pool line (its worst parent).
        prune_below = order
            .get(s.ga.n_parents().min(order.len()) - 1)
            .map(|&i| fit[i] - s.prune.margin)
            .filter(|v| v.is_finite());
        let race_against = if race.is_some() { elites.iter().map(|(e, _)| e.clone()).collect() } else { Vec::new() };
        // The next generation's elites: as many as the GA keeps (at least the best), in rank order.
        elites = order
            .iter()
            .filter(|&&i| individuals[i].fitness.is_some())
            .take(s.ga.n_elites().max(1))
            .map(|&i| (individuals[i].setting.clone(), individuals[i].scores.clone()))
            .collect();
        records.push(GenerationRecord {
            generation: g,
            individuals,
            stats: st.clone(),
            new_units,
            prune_below: this_cutoff,
            race_against,
            best_so_far: b.clone(),
            best_generation: bg,
        });

        write_outputs(dir, &spec, &records, &hall, &b, bg, &ev)?;
        let (secs, ran, replayed) = {
            let mut c = runner.clock.lock().expect("clock");
            let (ran, replayed) = (c.done, g < c.generation_seconds.len());
            (c.finish_generation(g), ran, replayed)
        };
        let cost = if replayed {
            format!("replayed from stored units (ran in {})", human(secs))
        } else if secs > 0.0 && ran > 0 {
            format!("{ran} units in {} ({:.2} units/s)", human(secs), ran as f64 / secs)
        } else {
            format!("0 units in {} (nothing to run)", human(secs))
        };
        {
            let c = runner.clock.lock().expect("clock");
            write_state(
                dir,
                &spec,
                &StateInfo { phase: Phase::Running, generation: g + 1, best: Some(&b), reason: "" },
                &c,
            )?;
        }
        progress.stage_done();
        progress.line(&format!(
            "gen {} ({} of {}): best {} mean {} ({} diverged{}) | {} | best so far {} → fitness {} (gen {}) | {}",
            g,
            g + 1,
            s.stop.generations,
            fmt(st.max),
            fmt(st.mean),
            st.diverged,
            if s.prune.enabled {
                format!(", {} pruned", st.pruned)
            } else if s.race.is_some() {
                format!(", {} raced out", st.raced)
            } else {
                String::new()
            },
            cost,
            describe(&b.decoded),
            fmt(b.fitness),
            bg,
            human(progress.elapsed())
        ));

        if let Some(limit) = s.stop.stall_generations.filter(|&l| stall >= l) {
            progress.finish();
            let reason = format!("no improvement for {limit} generations");
            let c = runner.clock.lock().expect("clock");
            write_state(
                dir,
                &spec,
                &StateInfo { phase: Phase::Finished, generation: g + 1, best: Some(&b), reason: &reason },
                &c,
            )?;
            return Ok(Ending::Finished(reason));
        }
        if g + 1 < s.stop.generations && s.strategy == Strategy::Random {
            // The baseline: a fresh uniform draw, with no elites, parents or mutation.
            population = random_generation(seed, g + 1, &s.genes, s.ga.population);
            origins = vec![Origin::Random; population.len()];
            births = vec![None; population.len()];
        } else if g + 1 < s.stop.generations {
            let (next, born) = next_generation(seed, g, &population, &fit, &eligible, &s.genes, &s.ga);
            let elites = next.len() - born.len();
            origins = (0..next.len()).map(|i| if i < elites { Origin::Elite } else { Origin::Child }).collect();
            births = std::iter::repeat_n(None, elites).chain(born.into_iter().map(Some)).collect();
            population = next;
        }
    }
    progress.finish();
    let reason = format!("{} generations", s.stop.generations);
    let c = runner.clock.lock().expect("clock");
    let info = StateInfo {
        phase: Phase::Finished,
        generation: s.stop.generations,
        best: best.as_ref().map(|b| &b.0),
        reason: &reason,
    };
    write_state(dir, &spec, &info, &c)?;
    Ok(Ending::Finished(reason))
}

/// What racing decided per setting: the scores its record keeps, and the decision.
type Raced = HashMap<String, (usize, Option<RaceRecord>)>;

/// Runs generation `g`'s settings under racing: each setting's datasets as a chain in index order,
/// judged after each stored unit against `elites` ([`racing::judge`]); an `exempt` setting (an
/// elite's) runs in full, never raced. Returns why the run must stop, if it must, and what racing
/// decided per setting (the scores its record keeps, and the decision).
fn race_generation(
    runner: &Runner<'_>,
    g: usize,
    distinct: &[Decoded],
    elites: &[(String, Vec<Option<f64>>)],
    exempt: &HashSet<String>,
    best: Option<&IndividualRecord>,
) -> Result<(Option<Stop>, Raced)> {
    let (ev, s) = (runner.ev, &runner.spec.search);
    let rule = s.race.expect("racing is on");
    let against: Vec<&[Option<f64>]> = elites.iter().map(|(_, sc)| sc.as_slice()).collect();
    let decided: Mutex<Raced> = Mutex::new(HashMap::new());
    let next = |x: &Decoded| -> Option<usize> {
        let id = setting_id(x);
        let sc = stored_scores(ev, x, s.datasets);
        if exempt.contains(&id) {
            return (sc.len() < s.datasets && !sc.contains(&None)).then_some(sc.len());
        }
        match racing::judge(&sc, s.datasets, &against, &rule) {
            racing::Verdict::Open(d) => Some(d),
            racing::Verdict::Done { keep, race } => {
                decided.lock().expect("decided").insert(id, (keep, race));
                None
            }
        }
    };
    let first: Vec<(Decoded, usize)> = distinct.iter().filter_map(|x| next(x).map(|d| (*x, d))).collect();
    let stop = runner.run_chained(g, &first, &next, best)?;
    Ok((stop, decided.into_inner().expect("decided")))
}

fn fmt(v: Option<f64>) -> String {
    v.map_or("−∞".into(), |x| format!("{x:.4}"))
}

fn write_outputs(
    dir: &Path,
    spec: &Spec,
    records: &[GenerationRecord],
    hall: &[(IndividualRecord, usize)],
    best: &IndividualRecord,
    best_generation: usize,
    ev: &Evaluator,
) -> Result<()> {
    write_atomic(&dir.join("generations.jsonl"), |w| {
        for r in records {
            serde_json::to_writer(&mut *w, r)?;
            std::io::Write::write_all(w, b"\n")?;
        }
        Ok(())
    })?;
    let hof: Vec<serde_json::Value> = hall
        .iter()
        .map(|(r, g)| serde_json::json!({"generation": g, "genes": r.genes, "decoded": r.decoded, "fitness": r.fitness, "scores": r.scores}))
        .collect();
    write_json(&dir.join("hall_of_fame.json"), &hof)?;
    if best.fitness.is_none() {
        // Every setting so far diverged: no tuned config, and nothing a consumer could take for
        // one (a best.json of an earlier binary included).
        let path = dir.join("best.json");
        if store::something_at(&path) {
            std::fs::remove_file(&path).map_err(|e| Error::io(&path, e))?;
        }
        return crate::report::search::write_fitness(dir, spec, records);
    }
    // Keep a validation of this same fitness winner (a resumed or re-reported search), and the
    // setting it selected.
    let validation = super::validate::load(dir).filter(|v| v.fitness_winner() == best.setting);
    let mut t = match &validation {
        Some(v) if v.tuned != best.setting => super::winner::tuned_for(dir, spec, &v.tuned)?,
        _ => super::winner::tuned(spec, best, best_generation, ev),
    };
    if let Some(v) = &validation {
        t.validation = v.summary_of(&v.tuned);
        t.selection = v.selection(&best.setting);
    }
    write_json(&dir.join("best.json"), &t)?;
    crate::report::search::write_fitness(dir, spec, records)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fitness_is_the_mean_or_minus_infinity() {
        assert_eq!(fitness(&[Some(1.0), Some(3.0)]), 2.0);
        assert_eq!(fitness(&[Some(1.0), None]), f64::NEG_INFINITY);
    }

    #[test]
    fn each_environment_draws_its_own_initial_population() {
        let pops: Vec<Vec<Chromosome>> = ["cartpole", "bicycle", "pendulum"]
            .iter()
            .map(|e| {
                let spec = Spec::resolve(e).unwrap().0;
                initial_population(ga_seed(&spec), &spec.search.genes, spec.search.ga.population)
            })
            .collect();
        assert_ne!(pops[0], pops[1]);
        assert_ne!(pops[0], pops[2]);
        assert_ne!(pops[1], pops[2]);
    }
}
