//! Tables, plots and `report.md` of a comparison, built only from its stored units (so `bfqi-ga
//! report` regenerates them without recomputing).

mod figures;
mod plots;
mod tables;
mod verdicts;

use crate::compare::{Analysis, CompareConfig, UnitRecord};
use crate::error::Result;
use crate::report::claims::Claim;
use crate::store::write_atomic;
use plots::Sink;
use std::path::Path;

/// What a report wrote.
#[derive(Debug, Clone)]
pub struct Outputs {
    /// Files written (relative to the run directory).
    pub files: Vec<String>,
    /// The claims evaluated.
    pub claims: Vec<Claim>,
}

/// Writes `scores.csv`, `summary.csv`, every plot and `report.md` into `dir`: the numbers are
/// taken from the units once ([`figures`]), then written as tables, drawn, and held against the
/// claims the spec names for each learner.
pub fn write(dir: &Path, cfg: &CompareConfig, units: &[UnitRecord]) -> Result<Outputs> {
    let env = cfg.env.env();
    let steps = env.eval().score.hides_steps();
    let mut files = Vec::new();
    let csv = tables::scores_csv(cfg, units);
    write_atomic(&dir.join("scores.csv"), |w| std::io::Write::write_all(w, csv.as_bytes()))?;
    files.push("scores.csv".into());

    let mut md = tables::header(cfg);
    let mut summary = String::from(tables::SUMMARY_HEADER);
    let mut claims = Vec::new();
    for (li, plan) in cfg.learners.iter().enumerate() {
        for analysis in &cfg.analyses {
            match analysis {
                Analysis::Iterations => {
                    let p = figures::iterations(units, li, plan);
                    tables::iterations(&mut md, &mut summary, plan, &p, steps);
                    plots::iterations(
                        &mut Sink { dir, env: env.name(), md: &mut md, files: &mut files },
                        plan,
                        &p,
                        steps,
                    )?;
                    claims.extend(plan.claims.iter().filter_map(|c| verdicts::iterations(c, &p)));
                }
                Analysis::Complexity => {
                    let rows = figures::complexity(units, li, plan);
                    tables::complexity(&mut md, &mut summary, plan, &rows);
                    plots::complexity(&mut Sink { dir, env: env.name(), md: &mut md, files: &mut files }, plan, &rows)?;
                    claims.extend(plan.claims.iter().filter_map(|c| verdicts::complexity(c, plan, &rows)));
                }
                Analysis::Samples => {
                    let rows = figures::samples(units, li, plan);
                    tables::samples(&mut md, &mut summary, plan, &rows);
                    plots::samples(&mut Sink { dir, env: env.name(), md: &mut md, files: &mut files }, plan, &rows)?;
                    claims.extend(plan.claims.iter().filter_map(|c| verdicts::samples(c, &rows)));
                }
            }
        }
    }
    write_atomic(&dir.join("summary.csv"), |w| std::io::Write::write_all(w, summary.as_bytes()))?;
    files.push("summary.csv".into());
    tables::claims(&mut md, &claims, cfg.learners.iter().any(|p| !p.claims.is_empty()));
    write_atomic(&dir.join("report.md"), |w| std::io::Write::write_all(w, md.as_bytes()))?;
    files.push("report.md".into());
    crate::work::write(dir)?;
    Ok(Outputs { files, claims })
}

/// Rebuilds every table, plot and `report.md` of the comparison in `dir` from its stored units.
pub fn regenerate(dir: &Path) -> Result<Outputs> {
    let (cfg, units) = crate::compare::collect(dir)?;
    write(dir, &cfg, &units)
}
