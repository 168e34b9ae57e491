//! Where each search stands (`bfqi-ga status`): its run directories found under a folder, one line
//! each.

use super::records::Phase;
use super::search::RunState;
use crate::error::Result;
use crate::progress::human;
use crate::store::{self, RunLock};
use std::path::{Path, PathBuf};

/// The run directories under `root` (those with a `state.json`), sorted; a run's own folders are
/// not searched further.
pub fn find_runs(root: &Path) -> Vec<PathBuf> {
    let mut dirs = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        if d.join("state.json").is_file() {
            dirs.push(d);
            continue;
        }
        if let Ok(entries) = std::fs::read_dir(&d) {
            stack.extend(entries.flatten().map(|e| e.path()).filter(|p| p.is_dir()));
        }
    }
    dirs.sort();
    dirs
}

/// One line on the run in `dir`: environment, state, generation, best fitness (and its validation),
/// best setting, the directory, and its time or progress.
pub fn line(dir: &Path) -> Result<String> {
    let st: RunState = store::read_json(&dir.join("state.json"))?;
    let env = store::read_json::<serde_json::Value>(&dir.join("run.json"))
        .ok()
        .and_then(|v| v["env"].as_str().map(String::from))
        .unwrap_or_else(|| "?".into());
    // A run whose lock nobody holds is not running, whatever it last wrote.
    let state = match st.state {
        Phase::Running if !RunLock::is_held(dir) => Phase::Interrupted,
        s => s,
    };
    let best = st.best.map_or("—".into(), |b| {
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
    Ok(format!(
        "{:<9} {:<12} gen {:>3}/{:<3} best {:>12}{}  {}  {}{}",
        env,
        state.name(),
        st.generation,
        st.generations,
        st.best_fitness.map_or("—".into(), |f| format!("{f:.4}")),
        validated,
        best,
        dir.display(),
        timing
    ))
}
