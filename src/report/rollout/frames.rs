//! A gymnasium env's own pictures as an animated GIF: the frames its `render()` gave during the
//! rollout, under a caption (env, time, step, action, return), as [`super::animate`] draws the
//! built-in tasks' schematics.

use super::{DELAY_MS, GifInfo, sample};
use crate::env::GymConfig;
use crate::error::{Error, Result};
use crate::rollout::Trajectory;
use plotters::prelude::*;
use std::path::Path;

/// Caption height above each frame (pixels).
const CAPTION: u32 = 40;

/// Writes the GIF of `traj`'s frames to `tmp` (the caller renames it into place): at most
/// `max_frames` of them, the first and the last always, each shown for the simulated time it
/// covers (`dt` per step, clamped to 40–200 ms).
pub(super) fn write(tmp: &Path, g: &GymConfig, traj: &Trajectory, max_frames: usize, dt: f64) -> Result<GifInfo> {
    let fail = |e: &dyn std::fmt::Display| Error::File { path: tmp.to_path_buf(), message: format!("animation: {e}") };
    let (_, picks) = sample(traj.frames.len(), max_frames);
    let frames: Vec<&(usize, crate::env::gymnasium::Image)> = picks.iter().map(|&i| &traj.frames[i]).collect();
    let stride = frames.windows(2).map(|w| w[1].0 - w[0].0).max().unwrap_or(1).max(1);
    let ms = (dt * stride as f64 * 100.0).round() * 10.0;
    let delay_ms = if ms.is_finite() { ms.clamp(DELAY_MS.0 as f64, DELAY_MS.1 as f64) as u32 } else { 100 };
    let (w, h) = frames.iter().fold((240, 140), |(w, h), (_, im)| (w.max(im.width), h.max(im.height)));
    let size = (w, (h + CAPTION).max(180));
    let mut returns = vec![0.0];
    for s in &traj.steps {
        returns.push(returns.last().copied().unwrap_or(0.0) + s.reward);
    }
    let n = traj.steps.len();
    let actions = crate::env::Env::actions(g);
    {
        let backend = BitMapBackend::gif(tmp, size, delay_ms).map_err(|e| fail(&e))?;
        let root = backend.into_drawing_area();
        for (k, im) in &frames {
            root.fill(&WHITE).map_err(|e| fail(&e))?;
            let act = traj.steps.get(*k).map_or("end".to_string(), |s| {
                actions.get(s.action).map_or(format!("action {}", s.action), |v| format!("action {v}"))
            });
            let ret = returns.get(*k).copied().unwrap_or(f64::NAN);
            let failed = if *k == n && traj.failed { " · terminated" } else { "" };
            let lines = [
                format!("{} · t {:.2} s · step {k}/{n}", g.id, *k as f64 * dt),
                format!("{act} · return {ret:.2}{failed}"),
            ];
            for (i, l) in lines.iter().enumerate() {
                let style = ("sans-serif", 14).into_font().color(&BLACK);
                root.draw(&Text::new(l.clone(), (6, 3 + 18 * i as i32), style)).map_err(|e| fail(&e))?;
            }
            let x = ((w - im.width) / 2) as i32;
            let pic = BitMapElement::with_ref((x, CAPTION as i32), (im.width, im.height), &im.rgb)
                .ok_or_else(|| fail(&"a frame's size does not match its pixels"))?;
            root.draw(&pic).map_err(|e| fail(&e))?;
            root.present().map_err(|e| fail(&e))?;
        }
    }
    Ok(GifInfo { frames: frames.len(), stride, delay_ms, bytes: 0, shown: frames.iter().map(|(k, _)| *k).collect() })
}
