//! The animation's frames: a caption and a to-scale schematic of each task, drawn with plotters
//! primitives in pixel coordinates.

use crate::env::{BicycleConfig, CartPoleConfig, EnvConfig, PendulumConfig};
use crate::report::plot::color;
use crate::rollout::{Trajectory, dt};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::f64::consts::PI;

pub(super) type Area<DB> = DrawingArea<DB, Shift>;
type Drawn<DB> = std::result::Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

const INK: RGBColor = RGBColor(50, 50, 50);
const FAINT: RGBColor = RGBColor(210, 210, 210);
/// Failure limits.
const LIMIT: RGBColor = RGBColor(240, 160, 160);

/// State variable `i`, 0 if missing or not finite (a malformed trajectory still draws).
fn val(s: &[f64], i: usize) -> f64 {
    s.get(i).copied().filter(|v| v.is_finite()).unwrap_or(0.0)
}

/// An angle in degrees in (−180, 180].
pub(super) fn degrees(rad: f64) -> f64 {
    let d = rad.to_degrees().rem_euclid(360.0);
    if d > 180.0 { d - 360.0 } else { d }
}

/// A pixel; far-off points are clamped so that no primitive becomes huge.
fn ip((x, y): (f64, f64)) -> (i32, i32) {
    let c = |v: f64| if v.is_finite() { v.clamp(-1e4, 1e4).round() as i32 } else { 0 };
    (c(x), c(y))
}

/// The region a schematic may use, in pixels, and the text size.
#[derive(Debug, Clone, Copy)]
struct Scene {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
    font: f64,
}

impl Scene {
    fn w(&self) -> f64 {
        self.x1 - self.x0
    }
    fn h(&self) -> f64 {
        self.y1 - self.y0
    }
    fn cx(&self) -> f64 {
        (self.x0 + self.x1) / 2.0
    }
    /// `px` pixels at the default size, scaled with the text for larger animations.
    fn px(&self, px: f64) -> f64 {
        px * self.font / 13.0
    }
    /// A line width of `px` pixels at the default size.
    fn lw(&self, px: f64) -> u32 {
        self.px(px).round().max(1.0) as u32
    }
}

/// Metres → pixels: origin `(ox, oy)` in pixels, `s` pixels per metre, y up.
#[derive(Debug, Clone, Copy)]
struct View {
    ox: f64,
    oy: f64,
    s: f64,
}

impl View {
    fn p(&self, x: f64, y: f64) -> (f64, f64) {
        (self.ox + x * self.s, self.oy - y * self.s)
    }
}

fn line<DB: DrawingBackend>(a: &Area<DB>, from: (f64, f64), to: (f64, f64), c: RGBColor, w: u32) -> Drawn<DB> {
    a.draw(&PathElement::new(vec![ip(from), ip(to)], c.stroke_width(w)))
}

fn disc<DB: DrawingBackend>(a: &Area<DB>, at: (f64, f64), r: f64, c: RGBColor) -> Drawn<DB> {
    a.draw(&Circle::new(ip(at), r.max(1.0).round() as i32, c.filled()))
}

/// A polyline with an arrowhead at its end, pointing from the last point a head's length back.
fn arrow<DB: DrawingBackend>(a: &Area<DB>, path: &[(f64, f64)], c: RGBColor, w: u32) -> Drawn<DB> {
    let Some(&to) = path.last() else { return Ok(()) };
    let head = 4.0 + 2.5 * w as f64;
    let dist = |p: &(f64, f64)| (p.0 - to.0).hypot(p.1 - to.1);
    // The last segment of an arc is shorter than the head: aiming along it would tilt the head,
    // and a shaft ending behind its own previous point makes wide bitmap lines spike.
    let Some(from) = path.iter().rev().find(|p| dist(p) >= head).or(path.first()) else { return Ok(()) };
    let len = dist(from);
    if len < 1e-9 {
        return Ok(());
    }
    let (ux, uy) = ((to.0 - from.0) / len, (to.1 - from.1) / len);
    // Stop the shaft inside the head so its square end does not poke out of the tip.
    let mut shaft: Vec<(i32, i32)> = path.iter().filter(|p| dist(p) > head).map(|&p| ip(p)).collect();
    shaft.push(ip((to.0 - ux * head * 0.6, to.1 - uy * head * 0.6)));
    a.draw(&PathElement::new(shaft, c.stroke_width(w)))?;
    let base = (to.0 - ux * head, to.1 - uy * head);
    let wing = (-uy * head * 0.55, ux * head * 0.55);
    let tri = vec![ip(to), ip((base.0 + wing.0, base.1 + wing.1)), ip((base.0 - wing.0, base.1 - wing.1))];
    a.draw(&Polygon::new(tri, c.filled()))
}

fn text<DB: DrawingBackend>(a: &Area<DB>, s: &str, at: (f64, f64), size: f64, c: RGBColor) -> Drawn<DB> {
    a.draw(&Text::new(s.to_string(), ip(at), ("sans-serif", size).into_font().color(&c)))
}

/// Text whose right edge is at `right`.
fn text_right<DB: DrawingBackend>(a: &Area<DB>, s: &str, right: f64, y: f64, size: f64, c: RGBColor) -> Drawn<DB> {
    let (w, _) = a.estimate_text_size(s, &("sans-serif", size).into_font().color(&c))?;
    text(a, s, (right - w as f64, y), size, c)
}

/// One frame: the caption (environment, time, step, action, return) and the schematic of state
/// `k` (with the action taken in it, none for the final state).
pub(super) fn frame<DB: DrawingBackend>(
    a: &Area<DB>,
    env: &EnvConfig,
    traj: &Trajectory,
    k: usize,
    ret: f64,
) -> Drawn<DB> {
    let (w, h) = a.dim_in_pixel();
    let font = (h as f64 / 18.0).round().clamp(11.0, 28.0);
    let n = traj.steps.len();
    let (state, action) = match traj.steps.get(k) {
        Some(s) => (s.state.as_slice(), Some(s.action)),
        None => (traj.last.as_slice(), None),
    };
    let line1 = format!("{} · t {:.2} s · step {k}/{n}", env.env().name(), k as f64 * dt(env));
    let act = action.map_or("end".to_string(), |a| action_text(env, a));
    text(a, &line1, (6.0, 4.0), font, INK)?;
    text(a, &format!("{act} · return {ret:.2}"), (6.0, 6.0 + 1.25 * font), font, INK)?;
    if k == n && traj.failed {
        // On the second line, which the final frame keeps short ("end · return …").
        text_right(a, "failed", w as f64 - 6.0, 6.0 + 1.25 * font, font, color(1))?;
    }
    let sc = Scene { x0: 4.0, y0: 10.0 + 2.5 * font, x1: w as f64 - 4.0, y1: h as f64 - 4.0, font };
    match env {
        EnvConfig::Pendulum(c) => pendulum(a, &sc, c, state, action.and_then(|i| c.actions.get(i).copied())),
        EnvConfig::Cartpole(c) => cartpole(a, &sc, c, state, action),
        EnvConfig::Bicycle(c) => bicycle(a, &sc, c, state, action),
        // Drawn from its own frames (see `frames`); without them, the caption alone.
        EnvConfig::Gymnasium(_) => Ok(()),
    }
}

/// The action as a frame's caption names it.
fn action_text(env: &EnvConfig, a: usize) -> String {
    match env {
        EnvConfig::Pendulum(c) => c.actions.get(a).map_or(format!("action {a}"), |u| format!("torque {u:+.1}")),
        EnvConfig::Cartpole(_) => ["push left", "push right"].get(a).map_or(format!("action {a}"), |s| s.to_string()),
        EnvConfig::Bicycle(c) => match (c.torques.get(a / 3), c.displacements.get(a % 3)) {
            (Some(t), Some(d)) => format!("T {t:+.0}, d {:+.0} cm", d * 100.0),
            _ => format!("action {a}"),
        },
        EnvConfig::Gymnasium(_) => {
            format!("action {}", env.env().actions().get(a).copied().unwrap_or(a as f64))
        }
    }
}

/// Pendulum: pivot, rod and bob, θ measured counter-clockwise from straight up (gym's
/// rendering), and the torque as an arc around the pivot (counter-clockwise when positive, which
/// is the direction it drives θ).
fn pendulum<DB: DrawingBackend>(
    a: &Area<DB>,
    sc: &Scene,
    c: &PendulumConfig,
    s: &[f64],
    torque: Option<f64>,
) -> Drawn<DB> {
    let (th, thdot) = (val(s, 0), val(s, 1));
    let r = 0.36 * sc.w().min(sc.h());
    let o = (sc.cx(), (sc.y0 + sc.y1) / 2.0);
    a.draw(&Circle::new(ip(o), r.round() as i32, FAINT.stroke_width(1)))?;
    // The goal: straight up.
    line(a, o, (o.0, o.1 - r - 0.3 * sc.font), color(2), 1)?;
    if let Some(u) = torque.filter(|u| *u != 0.0 && u.is_finite()) {
        // Centred opposite the bob so the rod does not hide it; its span grows with |u|.
        let centre = PI / 2.0 + th + PI;
        let span = 2.4 * (u.abs() / c.max_torque).min(1.0);
        let rho = 0.3 * r;
        let pts: Vec<(f64, f64)> = (0..=16)
            .map(|i| {
                let f = centre + u.signum() * span * (i as f64 / 16.0 - 0.5);
                (o.0 + rho * f.cos(), o.1 - rho * f.sin())
            })
            .collect();
        arrow(a, &pts, color(4), sc.lw(3.0))?;
    }
    let bob = (o.0 - r * th.sin(), o.1 - r * th.cos());
    line(a, o, bob, INK, (r / 25.0).max(3.0) as u32)?;
    disc(a, bob, 0.1 * r, color(0))?;
    disc(a, o, sc.px(4.0), INK)?;
    let label = format!("θ {:+.0}° · θ' {thdot:+.1} rad/s", degrees(th));
    text(a, &label, (sc.x0 + 2.0, sc.y1 - sc.font - 2.0), sc.font * 0.9, INK)
}

/// Cart-pole: the track with its limits, the cart at x, the pole (2·l long, θ clockwise from
/// upright as in gym, so positive θ leans right) with its failure angles, and the push.
fn cartpole<DB: DrawingBackend>(
    a: &Area<DB>,
    sc: &Scene,
    c: &CartPoleConfig,
    s: &[f64],
    action: Option<usize>,
) -> Drawn<DB> {
    let reach = c.x_threshold + 0.55;
    let (x, th) = (val(s, 0).clamp(-reach - 1.0, reach + 1.0), val(s, 2));
    let (above, below) = (2.2 * c.l + 0.3, 1.6 * sc.font);
    let scale = (sc.w() / (2.0 * reach)).min((sc.h() - below) / above);
    // The track is much longer than the pole is tall: centre the drawing vertically.
    let oy = ((sc.y0 + sc.y1 + above * scale - below) / 2.0).min(sc.y1 - below);
    let v = View { ox: sc.cx(), oy, s: scale };
    line(a, v.p(-c.x_threshold - 0.35, 0.0), v.p(c.x_threshold + 0.35, 0.0), INK, sc.lw(2.0))?;
    for side in [-1.0, 1.0] {
        line(a, v.p(side * c.x_threshold, 0.0), v.p(side * c.x_threshold, 0.3), LIMIT, sc.lw(2.0))?;
    }
    let pivot = (x, 0.27);
    let limit = c.theta_threshold_deg.to_radians();
    for side in [-1.0, 1.0] {
        let tip = (x + 2.2 * c.l * (side * limit).sin(), pivot.1 + 2.2 * c.l * limit.cos());
        line(a, v.p(pivot.0, pivot.1), v.p(tip.0, tip.1), LIMIT, 1)?;
    }
    a.draw(&Rectangle::new([ip(v.p(x - 0.2, 0.3)), ip(v.p(x + 0.2, 0.07))], INK.filled()))?;
    for dx in [-0.12, 0.12] {
        disc(a, v.p(x + dx, 0.05), 0.05 * scale, INK)?;
    }
    if let Some(act) = action {
        let dir = if act >= 1 { 1.0 } else { -1.0 };
        arrow(a, &[v.p(x + dir * 0.22, 0.18), v.p(x + dir * 0.52, 0.18)], color(2), sc.lw(3.0))?;
    }
    let tip = (x + 2.0 * c.l * th.sin(), pivot.1 + 2.0 * c.l * th.cos());
    line(a, v.p(pivot.0, pivot.1), v.p(tip.0, tip.1), RGBColor(204, 153, 102), (0.07 * scale).max(3.0) as u32)?;
    disc(a, v.p(pivot.0, pivot.1), (0.04 * scale).max(2.0), RGBColor(129, 132, 203))?;
    let label = format!("x {:+.2} m · θ {:+.1}°", val(s, 0), th.to_degrees());
    text(a, &label, (sc.x0 + 2.0, v.oy + 0.3 * sc.font), sc.font * 0.9, INK)
}

/// Bicycle seen from behind, riding away from the viewer: the tyre and frame leaning by ω, the
/// handlebar across the top, and the heading ψ in an inset compass. Positive angles turn and lean
/// left (ψ grows counter-clockwise seen from above, as in Randløv's position update), which seen
/// from behind is the viewer's left too.
fn bicycle<DB: DrawingBackend>(
    a: &Area<DB>,
    sc: &Scene,
    c: &BicycleConfig,
    s: &[f64],
    action: Option<usize>,
) -> Drawn<DB> {
    let (omega, theta, psi) = (val(s, 0), val(s, 2), val(s, 4));
    let (top, tall) = (1.0, 1.2);
    let v = View { ox: sc.cx(), oy: sc.y1 - 1.6 * sc.font, s: (sc.h() - 2.4 * sc.font) / 1.25 };
    line(a, (sc.x0 + 2.0, v.oy), (sc.x1 - 2.0, v.oy), INK, sc.lw(2.0))?;
    line(a, v.p(0.0, 0.0), v.p(0.0, tall), FAINT, 1)?;
    let limit = c.omega_max_deg.to_radians();
    for side in [-1.0, 1.0] {
        line(a, v.p(0.0, 0.0), v.p(-side * tall * limit.sin(), tall * limit.cos()), LIMIT, 1)?;
    }
    // Bicycle coordinates (u to the right, up the frame) → pixels, leaning left for ω > 0.
    let (sin, cos) = omega.sin_cos();
    let at = |u: f64, up: f64| v.p(u * cos - up * sin, u * sin + up * cos);
    let tyre = [at(-0.03, 0.0), at(0.03, 0.0), at(0.03, 2.0 * c.r), at(-0.03, 2.0 * c.r)];
    a.draw(&Polygon::new(tyre.iter().map(|&p| ip(p)).collect::<Vec<_>>(), INK.filled()))?;
    line(a, at(0.0, c.r), at(0.0, top), color(0), sc.lw(3.0))?;
    line(a, at(-0.09, 0.86), at(0.09, 0.86), INK, sc.lw(4.0))?;
    // The handlebar (0.6 m wide) turned by θ about the steering axis, seen from slightly above:
    // its apparent width shrinks with cos θ, and the grip that swings away from the viewer is
    // drawn higher and small, the near one lower and large. Turning left (θ > 0) brings the left
    // grip back towards the viewer.
    let (b, (st, ct)) = (0.3, theta.sin_cos());
    let (left, right) = (at(-b * ct, top - 0.4 * b * st), at(b * ct, top + 0.4 * b * st));
    line(a, left, right, color(0), sc.lw(3.0))?;
    let (near, far) = if theta >= 0.0 { (left, right) } else { (right, left) };
    disc(a, far, sc.px(3.0), INK)?;
    if theta == 0.0 {
        disc(a, near, sc.px(3.0), INK)?
    } else {
        disc(a, near, sc.px(5.0), color(4))?
    }
    if let Some((t, d)) = action.and_then(|i| Some((*c.torques.get(i / 3)?, *c.displacements.get(i % 3)?))) {
        // Arrows point the way each part of the action pushes: positive torque steers left,
        // a positive displacement moves the rider's weight to the left.
        let len = 0.22 * v.s;
        for (value, up, col) in [(t, top + 0.14, color(1)), (d, 0.72, color(2))] {
            if value != 0.0 {
                let p = at(0.0, up);
                arrow(a, &[p, (p.0 - value.signum() * len, p.1)], col, sc.lw(3.0))?;
            }
        }
    }
    // Heading inset: ψ = 0 points up the picture (straight ahead), positive to the left.
    let rad = 0.13 * sc.h();
    let o = (sc.x1 - rad - 4.0, sc.y0 + rad + 2.0);
    a.draw(&Circle::new(ip(o), rad.round() as i32, FAINT.stroke_width(1)))?;
    arrow(a, &[o, (o.0 - 0.85 * rad * psi.sin(), o.1 - 0.85 * rad * psi.cos())], INK, sc.lw(2.0))?;
    text_right(a, &format!("ψ {:+.0}°", degrees(psi)), sc.x1 - 2.0, o.1 + rad + 3.0, sc.font * 0.9, INK)?;
    let label = format!("ω {:+.1}° · θ {:+.1}°", omega.to_degrees(), theta.to_degrees());
    text(a, &label, (sc.x0 + 2.0, v.oy + 0.3 * sc.font), sc.font * 0.9, INK)
}
