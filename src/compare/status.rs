//! A comparison's line in `bfqi-ga status`, with what of it does not verify.

use super::Comparison;
use crate::error::Result;
use std::path::Path;

/// One line on the comparison in `dir` for `bfqi-ga status`: environment, learners and analyses,
/// units stored of all, the directory, and what does not verify (a `compare.json` changed since
/// the run began, stored units that are damaged, edited or of another configuration).
pub fn status_line(dir: &Path) -> Result<String> {
    let c = Comparison::open(dir)?;
    let mut problems = Vec::new();
    let changed = c.check_config(dir, "resuming and reporting are refused").err();
    let (mut done, mut bad) = (0, Vec::new());
    match changed {
        // Units are checked against the configuration the run began with, not the edited one:
        // until compare.json is restored nothing resumes, so nothing is computed again either.
        Some(e) => {
            problems.push(e.to_string());
            done = c.units.iter().filter(|u| c.store.path(&c.cfg.unit_id(u)).is_file()).count();
        }
        None => {
            for u in &c.units {
                match c.verified(u) {
                    Ok(Some(_)) => done += 1,
                    Ok(None) => {}
                    Err(p) => bad.push(format!("{}: {p}", c.store.path(&c.cfg.unit_id(u)).display())),
                }
            }
        }
    }
    if let Some(first) = bad.first() {
        problems.push(format!(
            "{} stored unit{} do{} not verify (first {first}); compare --resume computes {} again",
            bad.len(),
            if bad.len() == 1 { "" } else { "s" },
            if bad.len() == 1 { "es" } else { "" },
            if bad.len() == 1 { "it" } else { "them" }
        ));
    }
    let names: Vec<&str> = c.cfg.learners.iter().map(|p| p.name.as_str()).collect();
    let analyses: Vec<String> = c
        .cfg
        .analyses
        .iter()
        .map(|a| serde_json::to_value(a).ok().and_then(|v| v.as_str().map(String::from)).unwrap_or_default())
        .collect();
    let state = if done == c.units.len() { "compared" } else { "partial" };
    Ok(format!(
        "{:<9} {:<12} {} {}  units {done}/{}  {}{}",
        c.cfg.env.env().name(),
        state,
        names.join("+"),
        analyses.join("+"),
        c.units.len(),
        dir.display(),
        problems.iter().map(|p| format!("  ! {p}")).collect::<String>()
    ))
}
