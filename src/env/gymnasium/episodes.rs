//! Episodes in the worker: whole random-policy episodes for datasets ([`collect`], one message
//! per batch) and lock-step episodes for a policy chosen in Rust ([`LockStep`], one message per
//! step of every running episode). Every observation and reward is checked finite here, so a bad
//! env fails naming the env, the episode and the step instead of poisoning a fit.

use super::GymConfig;
use super::wire::{Data, Frame};
use super::worker::{Session, totals};
use crate::error::{Error, Result};
use serde::Serialize;
use serde_json::{Map, Value};

/// One dataset episode as the env ran it.
#[derive(Debug, Clone, PartialEq)]
pub struct RawEpisode {
    /// Observations `o_0 … o_T`, `(T + 1) × d` values.
    pub obs: Vec<f64>,
    /// The T actions taken, as feature values.
    pub actions: Vec<f64>,
    /// The T rewards.
    pub rewards: Vec<f64>,
    /// Whether the last step terminated the episode (absorbing); else it was cut (horizon or
    /// gymnasium's truncation).
    pub terminated: bool,
}

/// What one lock-step move did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stepped {
    /// The reward.
    pub reward: f64,
    /// The env terminated the episode (absorbing).
    pub terminated: bool,
    /// The env cut the episode (its time limit).
    pub truncated: bool,
}

/// An RGB frame from the env's `render()`.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `height × width × 3` bytes, row-major.
    pub rgb: Vec<u8>,
}

/// The bridge's cost over this process's life so far.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BridgeStats {
    /// Seconds the workers spent on requests (stepping, resetting, rendering).
    pub python_s: f64,
    /// Seconds the tool waited for replies (the above plus pipes, framing and process wake-ups).
    pub wait_s: f64,
    /// Messages answered.
    pub round_trips: u64,
    /// Workers started.
    pub workers: u64,
}

/// See [`BridgeStats`].
pub fn stats() -> BridgeStats {
    let (python_s, wait_s, round_trips, workers) = totals();
    BridgeStats { python_s, wait_s, round_trips, workers }
}

fn options(o: Option<&Map<String, Value>>) -> Value {
    o.map_or(Value::Null, |m| Value::Object(m.clone()))
}

fn f8<'f>(f: &'f Frame, name: &str, len: usize, cfg: &GymConfig, what: &str) -> Result<&'f [f64]> {
    match f.array(name).map(|a| &a.data) {
        Some(Data::F8(v)) if v.len() == len => Ok(v),
        _ => Err(broken(cfg, what, name)),
    }
}

fn flags<'f>(f: &'f Frame, name: &str, len: usize, cfg: &GymConfig, what: &str) -> Result<&'f [u8]> {
    match f.array(name).map(|a| &a.data) {
        Some(Data::U1(v)) if v.len() == len => Ok(v),
        _ => Err(broken(cfg, what, name)),
    }
}

fn broken(cfg: &GymConfig, what: &str, name: &str) -> Error {
    Error::Failed(format!("gymnasium env {}: the worker's reply to {what} lacks a well-formed `{name}`", cfg.id))
}

/// Refuses a non-finite observation or reward, naming where it came from.
fn finite(cfg: &GymConfig, values: &[f64], what: &str, at: impl Fn(usize) -> String) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::Failed(format!(
            "gymnasium env {} returned a non-finite {what} ({}) {}: FQI needs finite observations and rewards",
            cfg.id,
            values[i],
            at(i)
        ))),
    }
}

/// Runs dataset episodes: episode `first + i` is reset with `episodes[i].0` and takes the
/// actions (feature values) `episodes[i].1`, one per step up to the horizon, until it
/// terminates, is truncated, or reaches the horizon. One message for the whole batch.
pub fn collect(cfg: &GymConfig, first: usize, episodes: &[(u64, Vec<f64>)]) -> Result<Vec<RawEpisode>> {
    let (h, a, d, e) = (cfg.horizon, cfg.action_dim(), cfg.obs_len(), episodes.len());
    let mut actions = Vec::with_capacity(e * h * a);
    for (_, feats) in episodes {
        for &f in feats.iter().take(h) {
            cfg.gym_action(f, &mut actions);
        }
    }
    let what = format!("dataset episodes {first}..{}", first + e);
    let req = Frame::request(
        "collect",
        serde_json::json!({"horizon": h, "options": options(cfg.reset_options.as_ref()), "field": "env.reset_options"}),
    )
    .with("seeds", &[e], Data::U8(episodes.iter().map(|(s, _)| *s).collect()))
    .with("actions", &[e, h, a], Data::F8(actions));
    let mut s = Session::checkout(cfg, false)?;
    let reply = s.ask(&what, &req)?;
    let steps: Vec<usize> = match reply.array("steps").map(|x| &x.data) {
        Some(Data::U8(v)) if v.len() == e && v.iter().all(|&t| t as usize <= h) => {
            v.iter().map(|&t| t as usize).collect()
        }
        _ => return Err(broken(cfg, &what, "steps")),
    };
    let n: usize = steps.iter().sum();
    let terminated = flags(&reply, "terminated", e, cfg, &what)?;
    let obs = f8(&reply, "obs", (n + e) * d, cfg, &what)?;
    let rewards = f8(&reply, "reward", n, cfg, &what)?;
    let (mut o, mut r) = (0, 0);
    let mut out = Vec::with_capacity(e);
    for (i, (&t, (seed, feats))) in steps.iter().zip(episodes).enumerate() {
        let ep = RawEpisode {
            obs: obs[o..o + (t + 1) * d].to_vec(),
            actions: feats[..t].to_vec(),
            rewards: rewards[r..r + t].to_vec(),
            terminated: terminated[i] != 0,
        };
        let at = |k: usize| format!("at step {k} of dataset episode {} (reset seed {seed})", first + i);
        finite(cfg, &ep.obs, "observation", |j| at(j / d))?;
        finite(cfg, &ep.rewards, "reward", |j| at(j + 1))?;
        o += (t + 1) * d;
        r += t;
        out.push(ep);
    }
    Ok(out)
}

/// Episodes stepped together in one worker, one env per slot: every message steps each running
/// episode once, so an evaluation of any number of episodes costs one round trip per step.
pub struct LockStep<'a> {
    cfg: &'a GymConfig,
    session: Session<'a>,
    obs: Vec<f64>,
    seeds: Vec<u64>,
    steps: Vec<usize>,
    what: String,
}

impl<'a> LockStep<'a> {
    /// Resets slot `i` with `seeds[i]` (and `options`); `render` opens the env for `rgb_array`
    /// frames; `what` names the episodes in messages (`evaluation`, `rollout`).
    pub fn reset(
        cfg: &'a GymConfig,
        seeds: &[u64],
        options_: Option<&Map<String, Value>>,
        render: bool,
        what: &str,
    ) -> Result<LockStep<'a>> {
        let mut session = Session::checkout(cfg, render)?;
        // The spec field the options come from, for a message if the env refuses them.
        let field = if options_.is_some() && options_ == cfg.eval.reset_options.as_ref() {
            "env.eval.reset_options"
        } else {
            "env.reset_options"
        };
        let req = Frame::request("reset", serde_json::json!({"options": options(options_), "field": field})).with(
            "seeds",
            &[seeds.len()],
            Data::U8(seeds.to_vec()),
        );
        let reply = session.ask(&format!("the reset of the {what}"), &req)?;
        let d = cfg.obs_len();
        let obs = f8(&reply, "obs", seeds.len() * d, cfg, what)?.to_vec();
        let ls = LockStep { cfg, session, obs, seeds: seeds.to_vec(), steps: vec![0; seeds.len()], what: what.into() };
        for (i, o) in ls.obs.chunks(d.max(1)).enumerate() {
            finite(cfg, o, "observation", |_| ls.at(i))?;
        }
        Ok(ls)
    }

    fn at(&self, slot: usize) -> String {
        format!("at step {} of {} episode {slot} (reset seed {})", self.steps[slot], self.what, self.seeds[slot])
    }

    /// The current observation of a slot.
    pub fn obs(&self, slot: usize) -> &[f64] {
        let d = self.cfg.obs_len();
        &self.obs[slot * d..(slot + 1) * d]
    }

    /// Steps each `(slot, action feature)` once; their observations are updated.
    pub fn step(&mut self, moves: &[(usize, f64)]) -> Result<Vec<Stepped>> {
        let (k, a, d) = (moves.len(), self.cfg.action_dim(), self.cfg.obs_len());
        let mut actions = Vec::with_capacity(k * a);
        for &(_, f) in moves {
            self.cfg.gym_action(f, &mut actions);
        }
        let req = Frame::request("step", Value::Object(Map::new()))
            .with("slots", &[k], Data::U8(moves.iter().map(|&(s, _)| s as u64).collect()))
            .with("actions", &[k, a], Data::F8(actions));
        let what = format!("a step of the {}", self.what);
        let reply = self.session.ask(&what, &req)?;
        let obs = f8(&reply, "obs", k * d, self.cfg, &what)?;
        let reward = f8(&reply, "reward", k, self.cfg, &what)?;
        let term = flags(&reply, "terminated", k, self.cfg, &what)?;
        let trunc = flags(&reply, "truncated", k, self.cfg, &what)?;
        let mut out = Vec::with_capacity(k);
        for (i, &(slot, _)) in moves.iter().enumerate() {
            self.steps[slot] += 1;
            let o = &obs[i * d..(i + 1) * d];
            finite(self.cfg, o, "observation", |_| self.at(slot))?;
            finite(self.cfg, &reward[i..i + 1], "reward", |_| self.at(slot))?;
            self.obs[slot * d..(slot + 1) * d].copy_from_slice(o);
            out.push(Stepped { reward: reward[i], terminated: term[i] != 0, truncated: trunc[i] != 0 });
        }
        Ok(out)
    }

    /// Each slot's `render()` frame, every n-th pixel so that it is at most `max_width` wide.
    pub fn render(&mut self, slots: &[usize], max_width: usize) -> Result<Vec<Image>> {
        let req = Frame::request("render", serde_json::json!({"max_width": max_width})).with(
            "slots",
            &[slots.len()],
            Data::U8(slots.iter().map(|&s| s as u64).collect()),
        );
        let what = format!("the frames of the {}", self.what);
        let reply = self.session.ask(&what, &req)?;
        let frames = reply.array("frames").ok_or_else(|| broken(self.cfg, &what, "frames"))?;
        match (&frames.data, frames.shape.as_slice()) {
            (Data::U1(v), [n, h, w, 3]) if *n == slots.len() => Ok(v
                .chunks_exact((h * w * 3).max(1))
                .map(|c| Image { width: *w as u32, height: *h as u32, rgb: c.to_vec() })
                .collect()),
            _ => Err(broken(self.cfg, &what, "frames")),
        }
    }
}
