//! The comparison's plots (PNG and SVG), each with the line of `report.md` that shows it.

use super::figures::{Line, Pair};
use super::tables::axis_name;
use crate::compare::LearnerPlan;
use crate::error::Result;
use crate::report::plot::{self, Grid, Series};
use std::fmt::Write as _;
use std::path::Path;

/// Where plots go and what records them.
pub struct Sink<'a> {
    /// The run directory.
    pub dir: &'a Path,
    /// The environment's name, for titles.
    pub env: &'a str,
    /// `report.md` so far.
    pub md: &'a mut String,
    /// Files written, relative to `dir`.
    pub files: &'a mut Vec<String>,
}

impl Sink<'_> {
    /// Records a drawn plot `name` (.png and .svg) under `alt` in the report.
    fn shown(&mut self, name: &str, alt: &str) {
        let _ = writeln!(self.md, "![{alt}]({name}.png)\n");
        self.files.extend([format!("{name}.png"), format!("{name}.svg")]);
    }
}

/// A line of means with its 95 % band; points without data are skipped.
fn series(label: &str, color: usize, points: &Line) -> Series {
    Series {
        label: label.into(),
        points: points.iter().filter_map(|(x, s)| s.map(|s| (*x as f64, s.mean))).collect(),
        band: points.iter().filter_map(|(x, s)| s.map(|s| (*x as f64, s.mean - s.ci95, s.mean + s.ci95))).collect(),
        color,
        wide: false,
    }
}

/// Score against iteration, and steps against iteration when `steps`.
pub fn iterations(out: &mut Sink, plan: &LearnerPlan, p: &Pair, steps: bool) -> Result<()> {
    let name = format!("{}-iterations", plan.name);
    plot::lines(
        &out.dir.join(&name),
        &format!("{}, {}: score of the greedy policy", out.env, plan.name),
        "iteration",
        "score",
        &[series("FQI", 0, &p.fqi), series("B-FQI", 1, &p.bfqi)],
    )?;
    out.shown(&name, "score vs iteration");
    if steps {
        let name = format!("{}-steps", plan.name);
        plot::lines(
            &out.dir.join(&name),
            &format!("{}, {}: steps survived", out.env, plan.name),
            "iteration",
            "steps",
            &[series("FQI", 0, &p.fqi_steps), series("B-FQI", 1, &p.bfqi_steps)],
        )?;
        out.shown(&name, "steps vs iteration");
    }
    Ok(())
}

/// Heatmaps of complexity × iteration (FQI, B-FQI, their difference) and the last-iteration score
/// against complexity.
pub fn complexity(out: &mut Sink, plan: &LearnerPlan, rows: &[(usize, Pair)]) -> Result<()> {
    let (what, k) = (axis_name(plan), plan.iterations);
    let grid = |values: Vec<Vec<Option<f64>>>| Grid {
        cols: (1..=k).collect(),
        rows: rows.iter().map(|(c, _)| *c).collect(),
        values,
    };
    let means = |line: &Line| line.iter().map(|(_, s)| s.map(|s| s.mean)).collect::<Vec<_>>();
    let diff = |p: &Pair| {
        p.fqi.iter().zip(&p.bfqi).map(|((_, a), (_, b))| Some(b.as_ref()?.mean - a.as_ref()?.mean)).collect()
    };
    let grids = [
        grid(rows.iter().map(|(_, p)| means(&p.fqi)).collect()),
        grid(rows.iter().map(|(_, p)| means(&p.bfqi)).collect()),
        grid(rows.iter().map(|(_, p)| diff(p)).collect()),
    ];
    for (grid, tag, title, div) in [
        (&grids[0], "fqi", "FQI", false),
        (&grids[1], "bfqi", "B-FQI", false),
        (&grids[2], "diff", "B-FQI − FQI", true),
    ] {
        let name = format!("{}-heatmap-{tag}", plan.name);
        plot::heatmap(
            &out.dir.join(&name),
            &format!("{}, {}: {title} score", out.env, plan.name),
            "iteration",
            what,
            grid,
            div,
        )?;
        out.shown(&name, &format!("{title} heatmap"));
    }
    let last = |f: fn(&Pair) -> &Line| rows.iter().map(|(c, p)| (*c, f(p)[k - 1].1)).collect::<Line>();
    let name = format!("{}-complexity", plan.name);
    plot::lines(
        &out.dir.join(&name),
        &format!("{}, {}: score at iteration {k}", out.env, plan.name),
        what,
        "score",
        &[series("FQI", 0, &last(|p| &p.fqi)), series("B-FQI", 1, &last(|p| &p.bfqi))],
    )?;
    out.shown(&name, "score vs complexity");
    Ok(())
}

/// Last-iteration score against dataset size, on a log axis.
pub fn samples(out: &mut Sink, plan: &LearnerPlan, rows: &[(usize, Pair)]) -> Result<()> {
    let s = plan.samples.as_ref().expect("validated");
    let (what, k) = (axis_name(plan), plan.iterations);
    let at_size = |f: fn(&Pair) -> &Line| rows.iter().map(|(n, p)| (*n, f(p)[0].1)).collect::<Line>();
    let name = format!("{}-samples", plan.name);
    plot::lines_scaled(
        &out.dir.join(&name),
        &format!("{}, {}: score at iteration {k} vs dataset size", out.env, plan.name),
        "episodes (log scale)",
        "score",
        &[
            series(&format!("FQI ({what} {})", s.fqi), 0, &at_size(|p| &p.fqi)),
            series(&format!("B-FQI ({what} {})", s.bfqi), 1, &at_size(|p| &p.bfqi)),
        ],
        true,
    )?;
    out.shown(&name, "score vs dataset size");
    Ok(())
}
