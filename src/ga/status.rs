//! Where each search stands (`bfqi-ga status`): its run directories found under a folder, one line
//! each.

use super::records::{Phase, RunInfo};
use super::search::RunState;
use super::setup::load_spec;
use super::units::{Evaluator, Role};
use crate::error::Result;
use crate::progress::human;
use crate::store::{self, RunLock};
use std::path::Path;

/// One line on the run in `dir`: environment, state, generation, best fitness (and its validation),
/// best setting, the directory, and its time or progress.
pub fn line(dir: &Path) -> Result<String> {
    let env = store::read_json::<serde_json::Value>(&dir.join("run.json"))
        .ok()
        .and_then(|v| v["env"].as_str().map(String::from))
        .unwrap_or_else(|| "?".into());
    if !store::something_at(&dir.join("state.json")) {
        return not_started(dir, &env);
    }
    let st: RunState = store::read_json(&dir.join("state.json"))?;
    // A run whose lock nobody holds is not running, whatever it last wrote.
    let state = match st.state {
        Phase::Running if !RunLock::is_held(dir) => Phase::Interrupted,
        s => s,
    };
    // The best setting of a search in which every setting diverged is none.
    let best = st.best.filter(|_| st.best_fitness.is_some()).map_or("—".into(), |b| {
        format!(
            "{} δ_min {} patience {}",
            serde_json::to_value(b.activation).unwrap_or_default().as_str().unwrap_or("?"),
            b.delta_min,
            b.patience
        )
    });
    let timing = if st.state == Phase::Running || st.units_total > 0 {
        format!(
            "  units {}/{} · ran {} · ETA {}",
            st.units_done,
            st.units_total,
            human(st.elapsed()),
            if state == Phase::Running { st.eta_seconds.map_or("?".into(), human) } else { "— (resume it)".into() }
        )
    } else {
        format!("  ran {}", human(st.elapsed()))
    };
    // A validated winner shows its validation mean beside its fitness, the race's rounds, and the
    // validation's winner when it is another setting.
    let validated = super::validate::load(dir).map_or(String::new(), |v| {
        let own = v.entries.iter().find(|e| e.setting == v.tuned).map_or(String::new(), |e| {
            e.validation.map_or(" (validation: diverged".into(), |s| {
                format!(" (validation {:.4} ± {:.4} on {} datasets", s.mean, s.ci95, s.n)
            })
        });
        let race = match (v.rounds.len(), v.race_end) {
            (0, _) => String::new(),
            (n, Some(super::race::End::Separated)) => format!("; race: {n} rounds, separated"),
            (n, _) => format!("; race: {n} rounds, {} indistinguishable", v.indistinguishable().len() + 1),
        };
        let other = match (&v.best_validated, &v.by_fitness) {
            // `select: validated` put the validation's winner in best.json.
            (_, Some(f)) => format!("; best.json holds the validated winner {}, not the best fitness {f}", v.tuned),
            (Some(b), None) if *b != v.tuned => format!("; validated winner {b}"),
            _ => String::new(),
        };
        if own.is_empty() { String::new() } else { format!("{own}{race}{other})") }
    });
    let raced = racing(dir);
    // A failed run says why (every setting diverged, a full disk) and that it resumes.
    let failed = if state == Phase::Failed { format!("  failed: {}", st.reason) } else { String::new() };
    Ok(format!(
        "{:<9} {:<12} gen {:>3}/{:<3} best {:>12}{}  {}  {}{}{}{}{}",
        env,
        state.name(),
        st.generation,
        st.generations,
        st.best_fitness.map_or("—".into(), |f| format!("{f:.4}")),
        validated,
        best,
        dir.display(),
        timing,
        raced,
        failed,
        problems(dir).iter().map(|p| format!("  ! {p}")).collect::<String>()
    ))
}

/// A racing search's decisions so far (`search.race`): the individuals raced out of those raced,
/// and the latest one stopped; empty when the search does not race.
fn racing(dir: &Path) -> String {
    let Some(rule) = load_spec(dir).ok().and_then(|s| s.search.race) else { return String::new() };
    let path = dir.join("generations.jsonl");
    let text = crate::store::read_text_within(&path, super::records::GENERATIONS_BYTES).unwrap_or_default();
    let (mut raced, mut out, mut last) = (0, 0, String::new());
    // A line being appended by a running search is skipped.
    for r in text.lines().filter_map(|l| serde_json::from_str::<super::records::GenerationRecord>(l).ok()) {
        for i in &r.individuals {
            if let Some(d) = i.race {
                raced += 1;
                if d.stopped {
                    out += 1;
                    last = format!("; last: gen {} #{} {}", r.generation, i.index, d.describe());
                }
            }
        }
    }
    format!("  racing ({} {} %): {out} of {raced} raced out{last}", rule.test.name(), rule.confidence * 100.0)
}

/// The line of a search created but stopped before its first state was written (a kill in its
/// first milliseconds): `--resume` starts it.
fn not_started(dir: &Path, env: &str) -> Result<String> {
    let spec = load_spec(dir)?;
    Ok(format!(
        "{:<9} {:<12} gen {:>3}/{:<3} best {:>12}  {}  {}  not started: search --resume {} starts it{}",
        env,
        "not started",
        0,
        spec.search.stop.generations,
        "—",
        "—",
        dir.display(),
        dir.display(),
        problems(dir).iter().map(|p| format!("  ! {p}")).collect::<String>()
    ))
}

/// What of the search in `dir` does not verify: a `spec.json` changed since the run began, and
/// stored units (search and validation) that are damaged, edited or of another spec. A result that
/// does not verify is computed again on resume, but until then a report built from it is refused,
/// so `status` says so rather than showing the run as sound.
fn problems(dir: &Path) -> Vec<String> {
    let spec = match load_spec(dir) {
        Ok(s) => s,
        Err(e) => return vec![e.to_string()],
    };
    let recorded = store::read_json::<RunInfo>(&dir.join("run.json")).ok().and_then(|i| i.spec_hash);
    // The hash `--resume` checks (a random search's carries its strategy).
    if let Some(h) = recorded.filter(|h| *h != spec.run_hash()) {
        // Its units are checked against the spec the run began with, not the edited one: until
        // spec.json is restored, nothing resumes, so nothing is computed again either.
        return vec![format!(
            "{}: changed since the run began (results hash {}, run.json records {h}): resuming and reporting are \
             refused until it is restored",
            dir.join("spec.json").display(),
            spec.run_hash()
        )];
    }
    let mut out = Vec::new();
    for role in [Role::Search, Role::Validation] {
        let bad = Evaluator::with_role(spec.clone(), dir, role).unverified();
        if let Some((path, problem)) = bad.first() {
            let n = bad.len();
            out.push(format!(
                "{n} stored unit{} do{} not verify (first {}: {problem}); resuming computes {} again",
                if n == 1 { "" } else { "s" },
                if n == 1 { "es" } else { "" },
                path.display(),
                if n == 1 { "it" } else { "them" }
            ));
        }
    }
    out
}
