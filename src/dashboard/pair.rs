//! Two runs side by side (`/compare-runs?a=R/PATH&b=R/PATH`): a GA search against a random one,
//! or a full search against a cheaper one. Searches show their best fitness so far per
//! generation in one chart and what they cost and found in one table; runs of other kinds show
//! what every run has (kind, env, state).

use super::discover::{Kind, Roots, Run};
use super::search::{generations, state};
use super::table::{Cell, Table};
use crate::ga::units::describe;
use crate::ga::validate::Validation;
use serde_json::{Value, json};

/// The page's table and chart data for runs `a` and `b` (which may be the same run).
pub fn page(roots: &Roots, a: &Run, b: &Run) -> (Vec<Table>, Value) {
    let runs = [a, b];
    let labels: Vec<String> = runs.iter().map(|r| r.label(roots)).collect();
    let mut t = Table::new("pair", "Side by side", &["", &labels[0], &labels[1]]);
    // Each run's row of the runs table: its kind, env and state (cells 1–3), read as that
    // table reads them, whatever the run's kind.
    let rows: Vec<Vec<Cell>> = runs.iter().map(|r| super::runs::row(r, roots)).collect();
    t.push(vec![Cell::text("run"), Cell::link(&labels[0], a.url()), Cell::link(&labels[1], b.url())]);
    for (name, i) in [("kind", 1), ("env", 2), ("state", 3)] {
        t.push(vec![Cell::text(name), rows[0][i].clone(), rows[1][i].clone()]);
    }
    let searches: Vec<Option<Facts>> = runs.iter().map(|r| (r.kind == Kind::Search).then(|| facts(r))).collect();
    if let [Some(x), Some(y)] = &searches[..] {
        let names = ["units evaluated", "generations", "best fitness", "best setting", VALIDATION];
        for ((name, x), y) in names.into_iter().zip(x.cells()).zip(y.cells()) {
            t.push(vec![Cell::text(name), x, y]);
        }
    }
    let chart: Vec<Value> = runs
        .iter()
        .zip(&searches)
        .enumerate()
        .map(|(i, (r, f))| {
            json!({
                "index": i, "label": labels[i], "kind": r.kind.name(),
                "generations": f.as_ref().map_or(&[][..], |f| &f.curve[..]),
            })
        })
        .collect();
    (vec![t], json!({ "runs": chart }))
}

/// The validation row's name.
const VALIDATION: &str = "validation (tuned setting, mean ± 95 %)";

/// What the table shows of a search.
struct Facts {
    units: usize,
    generations: String,
    best_fitness: Option<f64>,
    best: String,
    validation: String,
    /// Best fitness so far per generation, as the chart draws it.
    curve: Vec<Value>,
}

impl Facts {
    /// Its cells, in the order of the rows' names in [`page`].
    fn cells(&self) -> [Cell; 5] {
        [
            Cell::text(self.units.to_string()),
            Cell::text(&self.generations),
            Cell::num(self.best_fitness),
            Cell::text(&self.best),
            Cell::text(&self.validation),
        ]
    }
}

fn facts(run: &Run) -> Facts {
    let gens = generations(run);
    let st = state(run).map(|(s, _)| s);
    let validation = run
        .json::<Validation>("validation.json")
        .and_then(|v| {
            let e = v.entries.iter().find(|e| e.setting == v.tuned)?;
            Some(match &e.validation {
                Some(s) => format!("{:.4} ± {:.4} ({})", s.mean, s.ci95, e.setting),
                None => format!("diverged ({})", e.setting),
            })
        })
        .unwrap_or_else(|| "—".into());
    Facts {
        // The unit files on disk: every FQI run the search paid for, resumed or not.
        units: std::fs::read_dir(run.dir.join("units")).map_or(0, |d| {
            d.flatten()
                .filter(|e| {
                    let n = e.file_name();
                    let n = n.to_string_lossy();
                    n.ends_with(".json") && !n.starts_with('.')
                })
                .count()
        }),
        generations: st.as_ref().map_or("—".into(), |s| format!("{}/{}", s.generation, s.generations)),
        best_fitness: st.as_ref().and_then(|s| s.best_fitness),
        best: st.as_ref().and_then(|s| s.best.as_ref()).map_or("—".into(), describe),
        validation,
        curve: gens.iter().map(|g| json!({ "g": g.generation, "best_so_far": g.best_so_far.fitness })).collect(),
    }
}
