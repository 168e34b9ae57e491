//! The numbers a comparison's report shows, taken once from its stored units: per analysis, the
//! mean score (and steps) with its 95 % interval at each iteration, complexity or dataset size.
//! Tables, plots and claims are all drawn from these.

use crate::compare::{LearnerPlan, UnitRecord};
use crate::experiment::DatasetResult;
use crate::fqi::Algorithm;
use crate::stats::{Summary, summarize};

/// Summaries along an axis (iteration, complexity or dataset size); `None` where no dataset has a
/// number (all diverged, or nothing stored).
pub type Line = Vec<(usize, Option<Summary>)>;

/// FQI's and B-FQI's figures of one setting, side by side.
#[derive(Debug, Clone, Default)]
pub struct Pair {
    /// FQI's scores.
    pub fqi: Line,
    /// B-FQI's scores.
    pub bfqi: Line,
    /// FQI's steps survived.
    pub fqi_steps: Line,
    /// B-FQI's steps survived.
    pub bfqi_steps: Line,
    /// Diverged datasets: FQI, B-FQI.
    pub diverged: (usize, usize),
}

/// Score and steps against iteration, at the plan's own complexity.
pub fn iterations(units: &[UnitRecord], li: usize, plan: &LearnerPlan) -> Pair {
    against_iteration(units, li, (None, None), plan.episodes, plan.iterations)
}

/// For each complexity of the sweep, score and steps against iteration.
pub fn complexity(units: &[UnitRecord], li: usize, plan: &LearnerPlan) -> Vec<(usize, Pair)> {
    plan.complexities
        .iter()
        .map(|&c| (c, against_iteration(units, li, (Some(c), Some(c)), plan.episodes, plan.iterations)))
        .collect()
}

/// For each dataset size of the sample sweep, score and steps at the last iteration (one point
/// per line), each algorithm at its own complexity.
pub fn samples(units: &[UnitRecord], li: usize, plan: &LearnerPlan) -> Vec<(usize, Pair)> {
    let s = plan.samples.as_ref().expect("validated");
    let k = plan.iterations;
    s.sizes
        .iter()
        .map(|&n| {
            let f = results(units, li, Algorithm::Fqi, Some(s.fqi), n);
            let b = results(units, li, Algorithm::Bfqi, Some(s.bfqi), n);
            let pair = Pair {
                fqi: vec![(k, at(&f, k, false))],
                bfqi: vec![(k, at(&b, k, false))],
                fqi_steps: vec![(k, at(&f, k, true))],
                bfqi_steps: vec![(k, at(&b, k, true))],
                diverged: (diverged(&f), diverged(&b)),
            };
            (n, pair)
        })
        .collect()
}

fn against_iteration(
    units: &[UnitRecord],
    li: usize,
    (cf, cb): (Option<usize>, Option<usize>),
    episodes: usize,
    k: usize,
) -> Pair {
    let f = results(units, li, Algorithm::Fqi, cf, episodes);
    let b = results(units, li, Algorithm::Bfqi, cb, episodes);
    let line = |rs: &[&DatasetResult], steps: bool| (1..=k).map(|it| (it, at(rs, it, steps))).collect();
    Pair {
        fqi: line(&f, false),
        bfqi: line(&b, false),
        fqi_steps: line(&f, true),
        bfqi_steps: line(&b, true),
        diverged: (diverged(&f), diverged(&b)),
    }
}

fn results(
    units: &[UnitRecord],
    learner: usize,
    algorithm: Algorithm,
    complexity: Option<usize>,
    episodes: usize,
) -> Vec<&DatasetResult> {
    let mut v: Vec<&UnitRecord> = units
        .iter()
        .filter(|u| {
            u.unit.learner == learner
                && u.unit.algorithm == algorithm
                && u.unit.complexity == complexity
                && u.unit.episodes == episodes
        })
        .collect();
    v.sort_by_key(|u| u.unit.dataset);
    v.into_iter().map(|u| &u.result).collect()
}

/// Score (or steps) at iteration k over datasets; diverged datasets are left out.
fn at(rs: &[&DatasetResult], k: usize, steps: bool) -> Option<Summary> {
    let v: Vec<f64> = rs
        .iter()
        .filter(|r| r.record.diverged.is_none())
        .filter_map(|r| r.record.iterations.iter().find(|i| i.iteration == k))
        .filter_map(|i| if steps { i.steps } else { i.score })
        .collect();
    summarize(&v)
}

fn diverged(rs: &[&DatasetResult]) -> usize {
    rs.iter().filter(|r| r.record.diverged.is_some()).count()
}

/// The last point of a line, when it has a number.
pub fn last(line: &Line) -> Option<Summary> {
    line.last().and_then(|p| p.1)
}
