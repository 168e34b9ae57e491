//! The search network's epoch, timed at a kernel level: the shape figures of `bench search`, and
//! with `--isa`, every level this CPU runs side by side, each against its own peak and bound.

use crate::error::{Error, Result};
use crate::ga::units::{Evaluator, activation_name};
use crate::learn::Rows;
use crate::learn::cpu::Isa;
use crate::learn::mlp::{Activation, EpochWork, MlpParams, Shape, fma_peak_gflops_on, kernel_levels, split_rows};
use serde::Serialize;
use std::time::Instant;

/// Epochs timed per activation for the shape figures (early stopping off).
pub(super) const SHAPE_EPOCHS: usize = 30;

/// One activation's epoch at one level.
#[derive(Debug, Serialize)]
pub(super) struct ShapeFigures {
    pub activation: &'static str,
    /// `[inputs, hidden…, 1]`.
    pub widths: Vec<usize>,
    pub train_rows: usize,
    pub val_rows: usize,
    pub ms_per_epoch: f64,
    pub work: EpochWork,
    pub gflops: f64,
    pub percent_of_peak: f64,
    /// The multiply-adds alone (the activations left out of the count, not of the time).
    pub percent_of_peak_matmul: f64,
    /// The epoch at one vector operation per slot (`EpochWork::bound_seconds`).
    pub bound_ms_per_epoch: f64,
}

/// Epoch time of the search's network shape with each activation, on dataset 0's first model,
/// with the kernels of `isa` (on the calling thread).
pub(super) fn shapes(ev: &Evaluator, isa: Isa, peak: f64) -> Result<Vec<ShapeFigures>> {
    let x = ev.dataset(0)?;
    let enc = &x.1;
    let (rows, idx) = enc.model_rows(0);
    let y: Vec<f64> = idx.iter().map(|&i| x.0.reward[i]).collect();
    let net = &ev.spec().search.network;
    let rows = Rows::new(rows, enc.n_inputs())?;
    let (t, v) = split_rows(rows.n_rows(), net.validation_fraction);
    let mut out = Vec::new();
    for act in [Activation::Sigmoid, Activation::Tanh, Activation::Relu] {
        let p = MlpParams {
            activation: act,
            max_epochs: SHAPE_EPOCHS,
            delta_min: 0.0,
            patience: usize::MAX / 2,
            ..net.clone()
        };
        // Best of three fits: the machine is shared.
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let start = Instant::now();
            let (_, info, _) = p.fit_on(isa, rows, &y, 1)?;
            best = best.min(start.elapsed().as_secs_f64() / info.epochs as f64);
        }
        let shape = Shape::new(enc.n_inputs(), &net.hidden, act);
        let work = EpochWork::new(&shape, t, v);
        let gflops = work.flops() / best / 1e9;
        out.push(ShapeFigures {
            activation: activation_name(act),
            widths: shape.widths().to_vec(),
            train_rows: t,
            val_rows: v,
            ms_per_epoch: best * 1e3,
            work,
            gflops,
            percent_of_peak: 100.0 * gflops / peak,
            percent_of_peak_matmul: 100.0 * work.matmul_flops / best / 1e9 / peak,
            bound_ms_per_epoch: work.bound_seconds(peak) * 1e3,
        });
    }
    Ok(out)
}

/// The levels `--isa` names: `all` (every level this CPU runs, best first) or a comma-separated
/// list of level names, each one this CPU runs.
pub(super) fn parse_levels(value: &str) -> Result<Vec<Isa>> {
    let runs = kernel_levels();
    let names: Vec<&str> = runs.iter().map(|i| i.name()).collect();
    if value == "all" {
        return Ok(runs);
    }
    let mut out = Vec::new();
    for name in value.split(',').map(str::trim) {
        let isa = runs.iter().copied().find(|i| i.name() == name).ok_or_else(|| Error::Invalid {
            field: "--isa".into(),
            value: name.into(),
            allowed: format!("this CPU runs the MLP at {}, or 'all'", names.join(", ")),
        })?;
        if !out.contains(&isa) {
            out.push(isa);
        }
    }
    Ok(out)
}

/// One level's figures for one environment.
#[derive(Debug, Serialize)]
pub(super) struct LevelFigures {
    pub level: &'static str,
    pub peak_gflops_per_core: f64,
    pub shapes: Vec<ShapeFigures>,
}

/// Times the shapes at each of `levels` on the one-thread pool `one`, printing a side-by-side table.
pub(super) fn side_by_side(
    ev: &Evaluator,
    levels: &[Isa],
    one: &rayon::ThreadPool,
    say: &dyn Fn(String),
) -> Result<Vec<LevelFigures>> {
    let mut out = Vec::new();
    for &isa in levels {
        let peak = fma_peak_gflops_on(isa, 1.0);
        let shapes = one.install(|| shapes(ev, isa, peak))?;
        out.push(LevelFigures { level: isa.name(), peak_gflops_per_core: peak, shapes });
    }
    if let Some(first) = out.first().and_then(|l| l.shapes.first()) {
        say(format!(
            "  every level, {SHAPE_EPOCHS} epochs of {} + {} rows on 1 thread; ms/epoch, then (% of that level's peak · % of its op-slot bound reached):",
            first.train_rows, first.val_rows
        ));
    }
    let head: Vec<String> =
        out.first().map_or(vec![], |l| l.shapes.iter().map(|s| format!("{:<26}", s.activation)).collect());
    say(format!("    {:<9} {:>9}   {}", "level", "peak", head.join("")));
    let best = out.first().map(|l| l.shapes.iter().map(|s| s.ms_per_epoch).collect::<Vec<_>>());
    for l in &out {
        let cells: Vec<String> = l
            .shapes
            .iter()
            .map(|s| {
                format!(
                    "{:<26}",
                    format!(
                        "{:.3} ({:.0} % · {:.0} %)",
                        s.ms_per_epoch,
                        s.percent_of_peak,
                        100.0 * s.bound_ms_per_epoch / s.ms_per_epoch
                    )
                )
            })
            .collect();
        say(format!("    {:<9} {:>9}   {}", l.level, format!("{:.1} GF/s", l.peak_gflops_per_core), cells.join("")));
    }
    if let (Some(best), Some(name)) = (best, out.first().map(|l| l.level)) {
        for l in out.iter().skip(1) {
            let r: Vec<String> = l
                .shapes
                .iter()
                .zip(&best)
                .map(|(s, b)| format!("{} {:.2}×", s.activation, s.ms_per_epoch / b))
                .collect();
            say(format!("    {} against {name}: {}", l.level, r.join(", ")));
        }
    }
    Ok(out)
}
