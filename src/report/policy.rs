//! What a greedy policy did, written to a directory (`bfqi-ga rollout`): every step of every
//! episode as CSV, the state variables and actions over time as PNG + SVG, an animated GIF of
//! the system, and `rollout.json` with the model's provenance and the scores.

use super::rollout::{GifInfo, GifLimits, animate, plot};
use crate::error::Result;
use crate::eval::Episode;
use crate::model::{Model, ModelInfo};
use crate::rollout::{self, Robustness, Start, Trajectory};
use crate::store;
use serde::Serialize;
use std::path::Path;

/// What to roll out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    /// Episodes.
    pub episodes: usize,
    /// Where they start.
    pub start: Start,
    /// Steps per episode at most.
    pub steps: usize,
    /// Episodes drawn (plots and GIF), from the first.
    pub draw: usize,
    /// GIF frames at most.
    pub frames: usize,
}

/// One episode's line in `rollout.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodeLine {
    /// Episode index.
    pub episode: usize,
    /// Its score under the evaluation protocol.
    pub score: f64,
    /// Steps taken.
    pub steps: usize,
    /// Whether it ended in a failure.
    pub failed: bool,
    /// The GIF drawn of it, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gif: Option<GifLine>,
}

/// A drawn GIF, in `rollout.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GifLine {
    /// File name.
    pub file: String,
    /// Frames.
    pub frames: usize,
    /// Steps per frame.
    pub stride: usize,
    /// Delay between frames (ms).
    pub delay_ms: u32,
    /// Size in bytes.
    pub bytes: u64,
}

/// `rollout.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// The model file (or how it was trained).
    pub model: String,
    /// Its provenance.
    pub info: ModelInfo,
    /// Start rule.
    pub start: Start,
    /// Steps per episode at most.
    pub max_steps: usize,
    /// Every episode.
    pub episodes: Vec<EpisodeLine>,
    /// Mean and 95 % interval over the episodes.
    pub result: Robustness,
}

/// Runs the request on `model` and writes everything into `dir` (created if needed).
pub fn write(dir: &Path, model: &Model, model_label: &str, req: &Request) -> Result<Summary> {
    store::create_dir(dir)?;
    let env = &model.info.env;
    let draw = Some(rollout::Draw { episodes: req.draw, frames: req.frames.max(2) });
    let q = |o: &[f64], q: &mut [f64]| model.q(o, q);
    let runs = rollout::run(env, &q, model.info.eval_seed, req.episodes, req.start, req.steps, true, draw)?;
    let trajectories: Vec<Trajectory> = runs.iter().filter_map(|(_, t)| t.clone()).collect();
    let csv = rollout::csv(env, &trajectories);
    store::write_atomic(&dir.join("trajectory.csv"), |w| std::io::Write::write_all(w, csv.as_bytes()))?;
    let mut lines = Vec::new();
    for (e, t) in runs.iter().map(|(e, _)| e).zip(&trajectories) {
        let gif = if t.episode < req.draw {
            let stem = format!("episode-{}", t.episode);
            plot(&dir.join(&stem), env, t)?;
            // A gymnasium env without rgb_array rendering has no pictures to animate.
            if matches!(env, crate::env::EnvConfig::Gymnasium(_)) && t.frames.is_empty() {
                lines.push(EpisodeLine {
                    episode: t.episode,
                    score: e.score,
                    steps: e.steps,
                    failed: e.failed,
                    gif: None,
                });
                continue;
            }
            let limits = GifLimits { max_frames: req.frames.max(2), ..GifLimits::default() };
            let file = format!("{stem}.gif");
            let info: GifInfo = animate(&dir.join(&file), env, t, limits)?;
            Some(GifLine { file, frames: info.frames, stride: info.stride, delay_ms: info.delay_ms, bytes: info.bytes })
        } else {
            None
        };
        lines.push(EpisodeLine { episode: t.episode, score: e.score, steps: e.steps, failed: e.failed, gif });
    }
    let eps: Vec<Episode> = runs.iter().map(|(e, _)| *e).collect();
    let result = rollout::robustness(req.start, &eps)
        .ok_or_else(|| crate::error::Error::invalid("episodes", 0, "must be ≥ 1"))?;
    let summary = Summary {
        model: model_label.to_string(),
        info: model.info.clone(),
        start: req.start,
        max_steps: req.steps,
        episodes: lines,
        result,
    };
    store::write_json(&dir.join("rollout.json"), &summary)?;
    Ok(summary)
}
