//! Pictures of one episode of a greedy policy ([`crate::rollout::Trajectory`]): an animated GIF of
//! the task as a schematic ([`animate`]) and its state variables and actions over time ([`plot`]).
//!
//! The schematics are drawn to scale with plotters primitives, angles true (nothing exaggerated),
//! with the failure limits marked faintly so a viewer can see how close the policy came to them.

mod frames;
mod scene;

use crate::env::EnvConfig;
use crate::error::{Error, Result, ensure};
use crate::report::plot::{SIZE, Series, bounds, color, ensure_font, render_sized};
use crate::rollout::{Trajectory, dt, state_names};
use plotters::prelude::*;
use scene::{Area, frame};
use std::path::{Path, PathBuf};

/// Size limits of an animation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GifLimits {
    /// Most frames to write (at least 2: the first and the last state are always shown).
    pub max_frames: usize,
    /// Width in pixels (240 to 2000: narrower cuts the caption).
    pub width: u32,
    /// Height in pixels (180 to 2000).
    pub height: u32,
}

impl Default for GifLimits {
    /// 200 frames of 320 × 240. Every frame is stored whole (about 5 kB, two fifths of it the
    /// antialiased caption), so a full 200-frame animation is about 1.1 MB: small enough to keep
    /// beside a result and to show in a markdown report.
    fn default() -> Self {
        GifLimits { max_frames: 200, width: 320, height: 240 }
    }
}

impl GifLimits {
    fn validate(&self) -> Result<()> {
        ensure(self.max_frames >= 2, "max_frames", self.max_frames, "must be ≥ 2 (the first and last states)")?;
        ensure((240..=2000).contains(&self.width), "width", self.width, "must be in 240..=2000 pixels")?;
        ensure((180..=2000).contains(&self.height), "height", self.height, "must be in 180..=2000 pixels")
    }
}

/// What [`animate`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GifInfo {
    /// Frames in the file (`shown.len()`).
    pub frames: usize,
    /// Every `stride`-th state is shown (plus always the last one).
    pub stride: usize,
    /// Display time of every frame, in milliseconds (a multiple of 10: GIF counts centiseconds).
    pub delay_ms: u32,
    /// Size of the file.
    pub bytes: u64,
    /// The state index each frame shows (state `k` is the one before step `k`; `steps.len()` is
    /// the final state `last`).
    pub shown: Vec<usize>,
}

/// The shortest and longest frame delay (ms): faster is a blur, slower a slide show.
const DELAY_MS: (u32, u32) = (40, 200);

/// Writes an animated GIF of the episode to `path` (atomically: temp file then rename).
///
/// Frame `i` shows the state before step `shown[i]`: every `stride`-th state, with `stride` the
/// smallest that keeps the frames within `limits.max_frames`, and always the final state. Frames
/// last the simulated time they cover, clamped to 40–200 ms. An empty trajectory gives one frame
/// of its start state.
/// A gymnasium env's rollout shows the frames its `render()` gave instead (its trajectory's
/// `frames`).
pub fn animate(path: &Path, env: &EnvConfig, traj: &Trajectory, limits: GifLimits) -> Result<GifInfo> {
    limits.validate()?;
    ensure_font();
    if let (EnvConfig::Gymnasium(g), false) = (env, traj.frames.is_empty()) {
        let tmp = temp_path(path);
        let written = frames::write(&tmp, g, traj, limits.max_frames, dt(env));
        let finished = written.and_then(|info| {
            std::fs::File::open(&tmp).and_then(|f| f.sync_all()).map_err(|e| Error::io(&tmp, e))?;
            std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))?;
            Ok(info)
        });
        return match finished {
            Ok(info) => {
                let bytes = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.len();
                Ok(GifInfo { bytes, ..info })
            }
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                Err(e)
            }
        };
    }
    let states = traj.steps.len() + 1;
    let (stride, shown) = sample(states, limits.max_frames);
    let ms = (dt(env) * stride as f64 * 100.0).round() * 10.0;
    let delay_ms = if ms.is_finite() { ms.clamp(DELAY_MS.0 as f64, DELAY_MS.1 as f64) as u32 } else { 100 };
    // Running return: the rewards collected before each state.
    let mut returns = Vec::with_capacity(states);
    returns.push(0.0);
    for s in &traj.steps {
        returns.push(returns.last().copied().unwrap_or(0.0) + s.reward);
    }

    let tmp = temp_path(path);
    let fail = |e: &dyn std::fmt::Display| Error::File { path: path.to_path_buf(), message: format!("animation: {e}") };
    let written = (|| -> Result<()> {
        let backend = BitMapBackend::gif(&tmp, (limits.width, limits.height), delay_ms).map_err(|e| fail(&e))?;
        let root = backend.into_drawing_area();
        for &k in &shown {
            root.fill(&WHITE).map_err(|e| fail(&e))?;
            frame(&root, env, traj, k, returns[k]).map_err(|e| fail(&e))?;
            // Each present() appends one frame; nothing is drawn after the last one, so dropping
            // the backend (which writes the GIF trailer) adds no extra frame.
            root.present().map_err(|e| fail(&e))?;
        }
        Ok(())
    })();
    let finished = written.and_then(|()| {
        std::fs::File::open(&tmp).and_then(|f| f.sync_all()).map_err(|e| Error::io(&tmp, e))?;
        std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
    });
    if let Err(e) = finished {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    let bytes = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.len();
    Ok(GifInfo { frames: shown.len(), stride, delay_ms, bytes, shown })
}

/// `.<name>.tmp.gif` beside `path`, so the rename stays on one file system.
fn temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map_or("animation".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.tmp.gif"))
}

/// Which of `states` states to show in at most `max_frames ≥ 2` frames: every `stride`-th, the
/// first and the last always. Returns `(stride, indices)`.
fn sample(states: usize, max_frames: usize) -> (usize, Vec<usize>) {
    let stride = states.div_ceil(max_frames.max(2)).max(1);
    let mut shown: Vec<usize> = (0..states).step_by(stride).collect();
    let last = states.saturating_sub(1);
    if shown.last() != Some(&last) {
        // The last state replaces the last sample when there is no room for one more frame.
        if shown.len() < max_frames {
            shown.push(last);
        } else if let Some(s) = shown.last_mut() {
            *s = last;
        }
    }
    (stride, shown)
}

/// One panel of [`plot`]: its series, y-axis label and failure limits (drawn as dashed lines).
struct Panel {
    label: String,
    series: Vec<Series>,
    limits: Vec<f64>,
}

/// More points than this in one series are thinned to the extremes of buckets: a 5,000-step
/// bicycle episode would otherwise make a multi-megabyte SVG without a visible difference.
const MAX_POINTS: usize = 4000;

fn thin(points: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    if points.len() <= MAX_POINTS {
        return points;
    }
    let chunk = points.len().div_ceil(MAX_POINTS / 2);
    let mut out = Vec::with_capacity(MAX_POINTS);
    for c in points.chunks(chunk) {
        let lo = c.iter().min_by(|a, b| a.1.total_cmp(&b.1));
        let hi = c.iter().max_by(|a, b| a.1.total_cmp(&b.1));
        if let (Some(&lo), Some(&hi)) = (lo, hi) {
            // In time order, so the line does not double back.
            out.extend(if lo.0 <= hi.0 { [lo, hi] } else { [hi, lo] });
        }
    }
    out.dedup();
    out
}

fn series(label: &str, points: Vec<(f64, f64)>, color: usize) -> Series {
    let points = thin(points.into_iter().filter(|p| p.1.is_finite()).collect());
    Series { label: label.to_string(), points, band: vec![], color, wide: false }
}

/// Writes `<base>.png` and `<base>.svg`: one panel per state variable (failure limits dashed)
/// and one for the action, stacked over a shared time axis in seconds.
pub fn plot(base: &Path, env: &EnvConfig, traj: &Trajectory) -> Result<()> {
    let (step, n) = (dt(env), traj.steps.len());
    let states = || traj.steps.iter().map(|s| s.state.as_slice()).chain(std::iter::once(traj.last.as_slice()));
    let names = state_names(env);
    let units: Vec<&str> = match env {
        EnvConfig::Pendulum(_) => vec!["rad", "rad/s"],
        EnvConfig::Cartpole(_) => vec!["m", "m/s", "rad", "rad/s"],
        EnvConfig::Bicycle(_) => vec!["rad", "rad/s", "rad", "rad/s", "rad"],
        EnvConfig::Gymnasium(_) => vec![""; names.len()],
    };
    let limits = |i: usize| -> Vec<f64> {
        let l = match (env, i) {
            (EnvConfig::Cartpole(c), 0) => c.x_threshold,
            (EnvConfig::Cartpole(c), 2) => c.theta_threshold_deg.to_radians(),
            (EnvConfig::Bicycle(c), 0) => c.omega_max_deg.to_radians(),
            _ => return vec![],
        };
        vec![-l, l]
    };
    let mut panels: Vec<Panel> = names
        .iter()
        .zip(units)
        .enumerate()
        .map(|(i, (name, unit))| {
            let pts = states().enumerate().map(|(k, s)| (k as f64 * step, s.get(i).copied().unwrap_or(f64::NAN)));
            let label = if unit.is_empty() { name.clone() } else { format!("{name} ({unit})") };
            Panel { label, series: vec![series(name, pts.collect(), 0)], limits: limits(i) }
        })
        .collect();
    // Actions hold for a whole step: drawn as steps, one corner per change (a repeated point
    // would make a zero-length segment, which thick bitmap lines draw as a spike).
    let held = |f: &dyn Fn(usize) -> Option<f64>| -> Vec<(f64, f64)> {
        let at = |k: usize| k as f64 * step;
        let mut pts: Vec<(f64, f64)> = Vec::new();
        for (k, s) in traj.steps.iter().enumerate() {
            let v = f(s.action).unwrap_or(f64::NAN);
            if let Some(&(_, prev)) = pts.last() {
                if prev.to_bits() == v.to_bits() {
                    continue;
                }
                pts.push((at(k), prev));
            }
            pts.push((at(k), v));
        }
        if let Some(&(_, v)) = pts.last() {
            pts.push((at(n), v));
        }
        pts
    };
    let action = match env {
        EnvConfig::Pendulum(c) => Panel {
            label: "torque (N·m)".into(),
            series: vec![series("torque", held(&|a| c.actions.get(a).copied()), 1)],
            limits: vec![],
        },
        EnvConfig::Cartpole(c) => Panel {
            label: "push (N)".into(),
            series: vec![series("push", held(&|a| (a < 2).then(|| if a == 1 { c.force } else { -c.force })), 1)],
            limits: vec![],
        },
        EnvConfig::Bicycle(c) => Panel {
            label: "action".into(),
            series: vec![
                series("handlebar torque T (N·m)", held(&|a| c.torques.get(a / 3).copied()), 1),
                series("displacement d (cm)", held(&|a| c.displacements.get(a % 3).map(|d| d * 100.0)), 2),
            ],
            limits: vec![],
        },
        EnvConfig::Gymnasium(_) => Panel {
            label: "action".into(),
            series: vec![series("action", held(&|a| env.env().actions().get(a).copied()), 1)],
            limits: vec![],
        },
    };
    panels.push(action);
    let t_end = n as f64 * step;
    let t_end = if t_end > 0.0 && t_end.is_finite() { t_end } else { step.max(1e-3) };
    let failed = if traj.failed { ", failed" } else { "" };
    let title = format!("{} — episode {}: {n} steps, score {:.3}{failed}", env.env().name(), traj.episode, traj.score);
    let size = (SIZE.0, 50 + 44 + PANEL * panels.len() as u32);
    render_sized(base, size, &|a| draw_panels(a, &title, t_end, &panels), &|a| draw_panels(a, &title, t_end, &panels))
}

/// Height of one panel of [`plot`] (pixels).
const PANEL: u32 = 160;

fn draw_panels<DB: DrawingBackend>(area: &Area<DB>, title: &str, t_end: f64, panels: &[Panel]) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |err: &dyn std::fmt::Display| Error::Data(format!("plot '{title}': {err}"));
    let mut rest = area.titled(title, ("sans-serif", 22)).map_err(|x| e(&x))?;
    for (i, p) in panels.iter().enumerate() {
        // Only the bottom panel has the time axis' labels; it gets their height on top of its own.
        let bottom = i + 1 == panels.len();
        let here = if bottom {
            rest.clone()
        } else {
            let (here, below) = rest.split_vertically(PANEL);
            rest = below;
            here
        };
        let (_, _, mut y0, mut y1) = bounds(&p.series);
        for &l in &p.limits {
            let pad = 0.06 * (y1 - y0);
            (y0, y1) = (y0.min(l - pad), y1.max(l + pad));
        }
        let mut chart = ChartBuilder::on(&here)
            .margin_top(6)
            .margin_bottom(6)
            .margin_left(14)
            .margin_right(24)
            .x_label_area_size(if bottom { 44 } else { 0 })
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..t_end, y0..y1)
            .map_err(|x| e(&x))?;
        let mut mesh = chart.configure_mesh();
        mesh.y_desc(p.label.as_str())
            .y_labels(5)
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .light_line_style(RGBColor(235, 235, 235));
        if bottom {
            mesh.x_desc("time (s)");
        }
        mesh.draw().map_err(|x| e(&x))?;
        for &l in &p.limits {
            let dash = color(1).mix(0.6).stroke_width(1);
            chart.draw_series(DashedLineSeries::new([(0.0, l), (t_end, l)], 6, 4, dash)).map_err(|x| e(&x))?;
        }
        for s in &p.series {
            // Bitmap lines wider than a pixel spike where a line turns back sharply, which dense
            // series (more points than pixels) do all the time: those get 1-pixel lines.
            let style = color(s.color).stroke_width(if s.points.len() > 800 { 1 } else { 2 });
            chart
                .draw_series(LineSeries::new(s.points.iter().copied(), style))
                .map_err(|x| e(&x))?
                .label(s.label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], style));
        }
        if p.series.len() > 1 {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(|x| e(&x))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::scene::degrees;
    use super::*;
    use crate::rng::stream;
    use crate::rollout::Step;
    use std::f64::consts::PI;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A fresh directory under the system's temp dir, removed on drop.
    struct Scratch(PathBuf);

    impl Scratch {
        fn new(tag: &str) -> Self {
            static N: AtomicUsize = AtomicUsize::new(0);
            let n = N.fetch_add(1, Ordering::Relaxed);
            let p = std::env::temp_dir().join(format!("bfqi-draw-{tag}-{}-{n}", std::process::id()));
            std::fs::create_dir_all(&p).unwrap();
            Scratch(p)
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// Up to `steps` steps of `rule` (state → action index) from `start`, ending at a failure.
    fn simulate(env: &EnvConfig, start: &[f64], steps: usize, rule: impl Fn(&[f64]) -> usize) -> Trajectory {
        let e = env.env();
        let mut rng = stream(3, "test", &[]);
        let (mut s, mut kept, mut failed, mut score) = (start.to_vec(), Vec::new(), false, 0.0);
        for _ in 0..steps {
            let action = rule(&s);
            let mut next = vec![0.0; s.len()];
            let o = e.step(&s, e.actions()[action], &mut rng, &mut next);
            kept.push(Step { state: s, action, reward: o.reward, q: vec![0.0; e.actions().len()] });
            (s, score, failed) = (next, score + o.reward, o.failed);
            if failed {
                break;
            }
        }
        Trajectory { episode: 0, steps: kept, last: s, score, failed, frames: vec![] }
    }

    /// Pendulum: pump energy (torque along the motion), then balance near the top.
    fn swing_up(s: &[f64]) -> usize {
        let th = degrees(s[0]).to_radians();
        let u = if th.abs() < 0.8 { -(8.0 * th + 1.5 * s[1]) } else { s[1] };
        if u >= 0.0 { 0 } else { 1 } // actions: +2, −2
    }

    /// Cart-pole: push toward the side the pole leans to.
    fn balance_pole(s: &[f64]) -> usize {
        usize::from(s[2] + 0.3 * s[3] + 0.03 * s[0] + 0.1 * s[1] > 0.0)
    }

    /// Bicycle: steer into the lean (damped); `shift` moves the rider's weight against it.
    fn ride(s: &[f64], shift: bool) -> usize {
        let e = 5.0 * s[0] + s[1] - s[2] - 0.1 * s[3];
        let t = if e > 0.01 {
            2
        } else if e < -0.01 {
            0
        } else {
            1
        };
        let d = if !shift {
            1
        } else if s[0] > 0.0 {
            0
        } else {
            2
        };
        3 * t + d
    }

    fn example(name: &str, steps: usize) -> (EnvConfig, Trajectory) {
        let env = EnvConfig::by_name(name).unwrap();
        let t = match name {
            "pendulum" => simulate(&env, &[PI - 0.3, 0.0], steps, swing_up),
            "cartpole" => simulate(&env, &[-0.5, 0.3, 0.04, -0.1], steps, balance_pole),
            _ => simulate(&env, &[0.02, 0.0, 0.0, 0.0, 0.3], steps, |s| ride(s, true)),
        };
        (env, t)
    }

    /// The delay of every frame of a GIF file, in centiseconds.
    fn gif_delays(path: &Path) -> Vec<u16> {
        let bytes = std::fs::read(path).unwrap();
        assert_eq!(&bytes[..6], b"GIF89a", "{}", path.display());
        let mut d = gif::DecodeOptions::new().read_info(bytes.as_slice()).unwrap();
        let mut delays = vec![];
        while let Some(f) = d.read_next_frame().unwrap() {
            delays.push(f.delay);
        }
        delays
    }

    fn check(info: &GifInfo, path: &Path, steps: usize) {
        let delays = gif_delays(path);
        assert_eq!((delays.len(), info.frames), (info.shown.len(), info.shown.len()), "{}", path.display());
        assert!(delays.iter().all(|&d| u32::from(d) * 10 == info.delay_ms), "{delays:?} vs {}", info.delay_ms);
        assert_eq!((info.shown.first(), info.shown.last()), (Some(&0), Some(&steps)));
        assert!(info.shown.windows(2).all(|w| w[0] < w[1] && w[1] - w[0] < 2 * info.stride));
        assert_eq!(info.bytes, std::fs::metadata(path).unwrap().len());
        let dir = std::fs::read_dir(path.parent().unwrap()).unwrap();
        assert!(dir.flatten().all(|f| !f.file_name().to_string_lossy().contains(".tmp")), "temp file left");
    }

    #[test]
    fn sampling_keeps_the_first_and_last_states_within_the_limit() {
        for states in 1..60 {
            for max in 2..14 {
                let (stride, shown) = sample(states, max);
                assert!(shown.len() <= max && shown.len() >= states.min(2), "{states} {max}: {shown:?}");
                assert_eq!((shown[0], *shown.last().unwrap()), (0, states - 1));
                assert!(shown.windows(2).all(|w| w[0] < w[1] && w[1] - w[0] < 2 * stride), "{shown:?}");
            }
        }
        assert_eq!(sample(201, 200).0, 2);
        assert_eq!(sample(200, 200), (1, (0..200).collect()));
    }

    #[test]
    fn every_environment_animates_one_frame_per_shown_state() {
        let dir = Scratch::new("anim");
        for name in crate::env::NAMES {
            let (env, t) = example(name, 40);
            assert!(!t.steps.is_empty());
            let path = dir.0.join(format!("{name}.gif"));
            let info = animate(&path, &env, &t, GifLimits { max_frames: 15, ..Default::default() }).unwrap();
            check(&info, &path, t.steps.len());
            assert!(info.frames <= 15 && info.stride == (t.steps.len() + 1).div_ceil(15), "{info:?}");
        }
    }

    #[test]
    fn delays_follow_simulated_time_within_the_readable_range() {
        let dir = Scratch::new("delay");
        // Pendulum steps are 50 ms: 2 per frame is 100 ms; cart-pole's 20 ms × 1 is raised to 40.
        for (name, steps, max_frames, delay) in [("pendulum", 30, 16, 100), ("cartpole", 10, 20, 40)] {
            let (env, t) = example(name, steps);
            let path = dir.0.join("a.gif");
            let info = animate(&path, &env, &t, GifLimits { max_frames, ..Default::default() }).unwrap();
            assert_eq!(info.delay_ms, delay, "{name}: {info:?}");
            check(&info, &path, t.steps.len());
        }
    }

    #[test]
    fn a_long_episode_stays_within_the_frame_and_size_limits() {
        let dir = Scratch::new("long");
        let (env, t) = example("cartpole", 1000);
        assert_eq!(t.steps.len(), 1000, "the controller balances");
        let path = dir.0.join("long.gif");
        let info = animate(&path, &env, &t, GifLimits::default()).unwrap();
        check(&info, &path, 1000);
        assert_eq!((info.stride, info.frames), (6, 168));
        // About 4–5.5 kB a frame at the default size (measured); 200 frames stay under 1.5 MB.
        assert!(info.bytes < 7_000 * info.frames as u64, "{} bytes", info.bytes);
    }

    #[test]
    fn an_empty_trajectory_shows_its_start_state() {
        let dir = Scratch::new("empty");
        for name in crate::env::NAMES {
            let env = EnvConfig::by_name(name).unwrap();
            let last = vec![0.1; env.env().state_dim()];
            let t = Trajectory { episode: 0, steps: vec![], last, score: 0.0, failed: false, frames: vec![] };
            let path = dir.0.join(format!("{name}.gif"));
            let info = animate(&path, &env, &t, GifLimits::default()).unwrap();
            check(&info, &path, 0);
            assert_eq!(info.shown, [0]);
            plot(&dir.0.join(name), &env, &t).unwrap();
        }
    }

    #[test]
    fn malformed_trajectories_still_draw() {
        let dir = Scratch::new("odd");
        for name in crate::env::NAMES {
            let env = EnvConfig::by_name(name).unwrap();
            let odd = [vec![], vec![f64::NAN; 5], vec![1e300, -f64::INFINITY, 1e9, 7.0, -1e12]];
            let steps = odd.iter().map(|s| Step { state: s.clone(), action: 99, reward: f64::NAN, q: vec![] });
            let t = Trajectory {
                episode: 1,
                steps: steps.collect(),
                last: vec![],
                score: f64::NAN,
                failed: true,
                frames: vec![],
            };
            let info = animate(&dir.0.join("odd.gif"), &env, &t, GifLimits::default()).unwrap();
            check(&info, &dir.0.join("odd.gif"), 3);
            plot(&dir.0.join("odd"), &env, &t).unwrap();
        }
        let (env, t) = example("cartpole", 5);
        let bad = GifLimits { max_frames: 1, ..Default::default() };
        let e = animate(&dir.0.join("x.gif"), &env, &t, bad).unwrap_err().to_string();
        assert!(e.contains("max_frames"), "{e}");
        let e = animate(&dir.0.join("x.gif"), &env, &t, GifLimits { width: 70_000, ..Default::default() });
        assert!(e.unwrap_err().to_string().contains("width"));
        assert!(!dir.0.join("x.gif").exists());
    }

    #[test]
    fn plots_are_written_as_png_and_svg() {
        let dir = Scratch::new("plot");
        for name in crate::env::NAMES {
            let (env, t) = example(name, 60);
            let base = dir.0.join(name);
            plot(&base, &env, &t).unwrap();
            let png = std::fs::read(base.with_extension("png")).unwrap();
            assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
            let svg = std::fs::read_to_string(base.with_extension("svg")).unwrap();
            assert!(svg.contains("<svg") && svg.contains("time (s)"), "{name}");
        }
    }

    /// Writes examples to `<temp dir>/draw-check/` to look at by eye
    /// (`cargo test --lib report::rollout -- --ignored --nocapture`).
    #[test]
    #[ignore]
    fn examples_for_the_eye() {
        let dir = &std::env::temp_dir().join("draw-check");
        std::fs::create_dir_all(dir).unwrap();
        for (name, steps) in [("pendulum", 200), ("cartpole", 200), ("bicycle", 5000)] {
            let (env, t) = example(name, steps);
            let info = animate(&dir.join(format!("{name}.gif")), &env, &t, GifLimits::default()).unwrap();
            println!("{name}: {} steps, failed {}, {info:?}", t.steps.len(), t.failed);
            plot(&dir.join(name), &env, &t).unwrap();
        }
        let env = EnvConfig::by_name("bicycle").unwrap();
        // No steering, only the rider's weight against the lean: it falls.
        let t = simulate(&env, &[0.01, 0.0, 0.0, 0.0, 0.0], 5000, |s| if s[0] > 0.0 { 3 } else { 5 });
        let info = animate(&dir.join("bicycle-fall.gif"), &env, &t, GifLimits::default()).unwrap();
        println!("bicycle-fall: {} steps, failed {}, {info:?}", t.steps.len(), t.failed);
        let (small, big) = (
            GifLimits { width: 240, height: 180, max_frames: 20 },
            GifLimits { width: 640, height: 480, max_frames: 20 },
        );
        animate(&dir.join("bicycle-small.gif"), &env, &t, small).unwrap();
        animate(&dir.join("bicycle-big.gif"), &env, &t, big).unwrap();
        plot(&dir.join("bicycle-fall"), &env, &t).unwrap();
    }
}
