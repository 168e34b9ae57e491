//! The comparison's text: `scores.csv` (every record), `summary.csv` (every summary a table or plot
//! shows) and the Markdown tables of `report.md`.

use super::figures::{Line, Pair};
use crate::compare::{Analysis, CompareConfig, LearnerPlan, UnitRecord};
use crate::report::claims::{Claim, Verdict};
use crate::stats::Summary;
use std::fmt::Write as _;

/// The header of `summary.csv`.
pub const SUMMARY_HEADER: &str =
    "analysis,learner,algorithm,complexity,episodes,iteration,n,mean,std,ci95,steps_mean,steps_ci95,diverged\n";

/// What a plan's complexity axis varies.
pub fn axis_name(plan: &LearnerPlan) -> &'static str {
    if plan.name == "et" { "max depth" } else { "hidden units" }
}

/// `scores.csv`: one row per stored iteration record (a row of blanks for a run that diverged
/// before its first).
pub fn scores_csv(cfg: &CompareConfig, units: &[UnitRecord]) -> String {
    let mut csv = String::from(
        "algorithm,learner,complexity,episodes,dataset,iteration,score,steps,bellman_residual,epochs,fit_seconds,predict_seconds,eval_seconds,diverged_at\n",
    );
    for u in units {
        let plan = &cfg.learners[u.unit.learner];
        let c = u.unit.complexity.map_or("preset".to_string(), |c| c.to_string());
        let div = u.result.record.diverged.as_ref().map_or(String::new(), |d| d.iteration.to_string());
        let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:?}"));
        for r in &u.result.record.iterations {
            let _ = writeln!(
                csv,
                "{},{},{c},{},{},{},{},{},{:?},{},{:?},{:?},{:?},{div}",
                u.unit.algorithm.name(),
                plan.name,
                u.unit.episodes,
                u.unit.dataset,
                r.iteration,
                o(r.score),
                o(r.steps),
                r.bellman_residual,
                r.epochs.map_or(String::new(), |e| e.to_string()),
                r.fit_seconds,
                r.predict_seconds,
                r.eval_seconds
            );
        }
        if u.result.record.iterations.is_empty() {
            let _ = writeln!(
                csv,
                "{},{},{c},{},{},,,,,,,,,{div}",
                u.unit.algorithm.name(),
                plan.name,
                u.unit.episodes,
                u.unit.dataset
            );
        }
    }
    csv
}

/// The top of `report.md`: title, seed, the tuned config, how to read the numbers, each learner's
/// base settings.
pub fn header(cfg: &CompareConfig) -> String {
    let mut md = String::new();
    let t = &cfg.tuned;
    let _ = writeln!(md, "# B-FQI vs FQI — {}\n", cfg.env.env().name());
    let _ = write!(md, "Master seed {}.", cfg.seed);
    if cfg.learners.iter().any(|p| p.name == "mlp") {
        let _ = write!(
            md,
            " Networks use the tuned config from `{}` ({}): activation {}, δ_min {}, patience {}.",
            t.source,
            if t.source == "thesis" { "the thesis's GA optimum" } else { "a search's best.json" },
            serde_json::to_value(t.activation).unwrap_or_default().as_str().unwrap_or("?"),
            t.delta_min,
            t.patience
        );
    }
    md.push_str("\n\n");
    if let Some(d) = &cfg.data {
        let _ = writeln!(md, "{}\n", d.describe());
    }
    let _ = writeln!(
        md,
        "Scores are means over datasets with 95 % intervals (1.96·std/√n, population std); diverged runs are left out of the means and counted.\n"
    );
    for plan in &cfg.learners {
        let _ = writeln!(
            md,
            "- **{}** base settings: `{}`, actions `{}`, K = {}, {} datasets × {} episodes",
            plan.name,
            serde_json::to_string(&plan.learner).unwrap_or_default(),
            serde_json::to_value(plan.actions).unwrap_or_default().as_str().unwrap_or("?"),
            plan.iterations,
            plan.datasets,
            plan.episodes
        );
    }
    if cfg.analyses.iter().any(|a| *a != Analysis::Iterations) {
        md.push_str(
            "\nThe complexity analysis varies the maximum depth (Extra-Trees) or the width of a single hidden layer \
             (networks); the dataset-size analysis names its own complexities and dataset count in its section.\n",
        );
    }
    md.push('\n');
    md
}

/// A mean with its interval, to one decimal for scores of 100 or more, three otherwise.
fn pm(s: Option<Summary>) -> String {
    s.map_or("—".into(), |s| {
        if s.mean.abs() >= 100.0 {
            format!("{:.1} ± {:.1}", s.mean, s.ci95)
        } else {
            format!("{:.3} ± {:.3}", s.mean, s.ci95)
        }
    })
}

fn point(line: &Line, i: usize) -> Option<Summary> {
    line[i].1
}

/// The iterations section's table (score, and steps when `steps`) and its summary rows.
pub fn iterations(md: &mut String, csv: &mut String, plan: &LearnerPlan, p: &Pair, steps: bool) {
    let _ = writeln!(md, "## {} — score vs iteration\n", plan.name);
    let _ = writeln!(
        md,
        "| iteration | FQI score | B-FQI score |{}",
        if steps { " FQI steps | B-FQI steps |" } else { "" }
    );
    let _ = writeln!(md, "|---|---|---|{}", if steps { "---|---|" } else { "" });
    for (i, &(it, sf)) in p.fqi.iter().enumerate() {
        let (sb, tf, tb) = (point(&p.bfqi, i), point(&p.fqi_steps, i), point(&p.bfqi_steps, i));
        let _ = writeln!(
            md,
            "| {it} | {} | {} |{}",
            pm(sf),
            pm(sb),
            if steps { format!(" {} | {} |", pm(tf), pm(tb)) } else { String::new() }
        );
        summary_line(csv, "iterations", &plan.name, "fqi", "preset", plan.episodes, it, sf, tf, p.diverged.0);
        summary_line(csv, "iterations", &plan.name, "bfqi", "preset", plan.episodes, it, sb, tb, p.diverged.1);
    }
    let _ = writeln!(md, "\nDiverged runs: FQI {}, B-FQI {}.\n", p.diverged.0, p.diverged.1);
}

/// The complexity section's table (last-iteration scores by complexity) and its summary rows
/// (every complexity × iteration).
pub fn complexity(md: &mut String, csv: &mut String, plan: &LearnerPlan, rows: &[(usize, Pair)]) {
    let (what, k) = (axis_name(plan), plan.iterations);
    let _ = writeln!(md, "## {} — complexity ({what})\n", plan.name);
    let _ = writeln!(md, "| {what} | FQI score at K={k} | B-FQI score at K={k} | B-FQI − FQI |");
    let _ = writeln!(md, "|---|---|---|---|");
    for (c, p) in rows {
        let (sf, sb) = (point(&p.fqi, k - 1), point(&p.bfqi, k - 1));
        let diff = match (sf, sb) {
            (Some(a), Some(b)) => format!("{:+.3}", b.mean - a.mean),
            _ => "—".into(),
        };
        let _ = writeln!(md, "| {c} | {} | {} | {diff} |", pm(sf), pm(sb));
        let c = c.to_string();
        for (i, &(it, sf)) in p.fqi.iter().enumerate() {
            let (sb, tf, tb) = (point(&p.bfqi, i), point(&p.fqi_steps, i), point(&p.bfqi_steps, i));
            summary_line(csv, "complexity", &plan.name, "fqi", &c, plan.episodes, it, sf, tf, p.diverged.0);
            summary_line(csv, "complexity", &plan.name, "bfqi", &c, plan.episodes, it, sb, tb, p.diverged.1);
        }
    }
    md.push('\n');
}

/// The dataset-size section's table and its summary rows.
pub fn samples(md: &mut String, csv: &mut String, plan: &LearnerPlan, rows: &[(usize, Pair)]) {
    let s = plan.samples.as_ref().expect("validated");
    let (what, k) = (axis_name(plan), plan.iterations);
    let _ = writeln!(
        md,
        "## {} — dataset size (FQI {what} {}, B-FQI {what} {}, {} datasets)\n",
        plan.name, s.fqi, s.bfqi, s.datasets
    );
    let _ = writeln!(md, "| episodes | FQI score at K={k} | B-FQI score at K={k} |");
    let _ = writeln!(md, "|---|---|---|");
    let (cf, cb) = (s.fqi.to_string(), s.bfqi.to_string());
    for (n, p) in rows {
        let (sf, sb) = (point(&p.fqi, 0), point(&p.bfqi, 0));
        let _ = writeln!(md, "| {n} | {} | {} |", pm(sf), pm(sb));
        let (tf, tb) = (point(&p.fqi_steps, 0), point(&p.bfqi_steps, 0));
        summary_line(csv, "samples", &plan.name, "fqi", &cf, *n, k, sf, tf, p.diverged.0);
        summary_line(csv, "samples", &plan.name, "bfqi", &cb, *n, k, sb, tb, p.diverged.1);
    }
    md.push('\n');
}

/// The claims section: each claim with its verdict, rule and numbers. `stated` is whether the
/// spec states any claim at all: a spec beyond the thesis (a gymnasium env's) states none, and its
/// report says so rather than suggest the thesis was checked.
pub fn claims(md: &mut String, claims: &[Claim], stated: bool) {
    let _ = writeln!(md, "## Thesis claims\n");
    if !stated {
        let _ = writeln!(
            md,
            "None: this spec states no thesis claims (the thesis made them about its own tasks), so the \
             tables above are B-FQI vs FQI as measured, without verdicts.\n"
        );
        return;
    }
    if claims.is_empty() {
        let _ = writeln!(md, "No claim of SPEC §6 is touched by this analysis.\n");
    }
    for c in claims {
        let mark = if c.verdict == Verdict::Supported { "supported" } else { "NOT supported" };
        let _ = writeln!(md, "- **{mark}** — {}\n  - rule: {}\n  - this run: {}", c.statement, c.rule, c.evidence);
    }
}

#[allow(clippy::too_many_arguments)]
fn summary_line(
    csv: &mut String,
    analysis: &str,
    learner: &str,
    algorithm: &str,
    complexity: &str,
    episodes: usize,
    iteration: usize,
    s: Option<Summary>,
    steps: Option<Summary>,
    diverged: usize,
) {
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:?}"));
    let _ = writeln!(
        csv,
        "{analysis},{learner},{algorithm},{complexity},{episodes},{iteration},{},{},{},{},{},{},{diverged}",
        s.map_or(0, |s| s.n),
        o(s.map(|s| s.mean)),
        o(s.map(|s| s.std)),
        o(s.map(|s| s.ci95)),
        o(steps.map(|s| s.mean)),
        o(steps.map(|s| s.ci95))
    );
}
