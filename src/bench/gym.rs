//! `bfqi-ga bench gym`: what the gymnasium bridge costs against a built-in env on the same job.
//! gymnasium's CartPole-v1 has the built-in cart-pole's dynamics (tests/gym_dynamics.rs), so the
//! pair isolates the bridge: the cart-pole search spec with its env replaced by CartPole-v1 at the
//! same horizon, γ and evaluation protocol. Figures: the worker's start, dataset collection and
//! greedy evaluation in steps per second, and a search unit's wall time with the share of it spent
//! in Python (the workers' own busy time) and in the bridge (waiting for replies).

use crate::dataset::{self, Role, dataset_seed};
use crate::env::gymnasium::{BridgeStats, stats};
use crate::env::{CartPoleConfig, EnvConfig, GymConfig};
use crate::error::{Error, Result};
use crate::eval::{eval_seed, evaluate};
use crate::ga::chromosome::Decoded;
use crate::ga::units::{Evaluator, setting_id};
use crate::spec::Spec;
use crate::tuned::TunedConfig;
use serde::Serialize;
use serde_json::Value;
use std::time::Instant;

/// One job timed on both envs.
#[derive(Debug, Clone, Serialize)]
struct Pair {
    job: String,
    steps: usize,
    builtin_s: f64,
    gymnasium_s: f64,
    builtin_steps_per_s: f64,
    gymnasium_steps_per_s: f64,
    /// Seconds inside the workers (stepping), and waiting for replies (that plus the pipes).
    python_s: f64,
    bridge_s: f64,
    round_trips: u64,
}

fn delta(a: BridgeStats, b: BridgeStats) -> (f64, f64, u64) {
    (b.python_s - a.python_s, b.wait_s - a.wait_s, b.round_trips - a.round_trips)
}

fn pool(threads: usize) -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| Error::Data(e.to_string()))
}

/// The cart-pole spec and the same with CartPole-v1 through the bridge.
fn specs() -> Result<(Spec, Spec)> {
    let (builtin, _) = Spec::resolve("cartpole")?;
    let (mut value, origin) = Spec::resolve_value("cartpole")?;
    let c = CartPoleConfig::default();
    value["env"] = serde_json::json!({
        "name": "gymnasium", "id": "CartPole-v1", "horizon": c.horizon, "gamma": c.gamma,
        "eval": {"episodes": c.eval.episodes, "steps": c.eval.steps, "score": "return"}
    });
    Ok((builtin, Spec::from_value(value, &origin)?))
}

/// A PD controller of the pole (a fixed policy that balances for the whole episode).
fn pd(o: &[f64]) -> usize {
    usize::from(o[2] + 0.5 * o[3] + 0.01 * o[0] + 0.05 * o[1] > 0.0)
}

/// Runs the bench; prints text, or returns JSON with `json`.
pub fn gym(json: bool) -> Result<Value> {
    let say = |s: String| {
        if !json {
            println!("{s}");
        }
    };
    let threads = rayon::current_num_threads();
    let t = Instant::now();
    let (builtin, gym) = specs()?;
    let start_s = t.elapsed().as_secs_f64();
    let EnvConfig::Gymnasium(g) = &gym.env else { unreachable!("the spec names a gymnasium env") };
    say(format!(
        "bench gym · cart-pole (built-in) vs CartPole-v1 through the bridge ({}) · {threads} thread(s)",
        g.python()
    ));
    say(format!("  a worker's start (Python, import gymnasium, make): {start_s:.2} s"));
    let mut pairs = Vec::new();

    // Dataset collection: the search's dataset 0, on 1 thread and on all.
    let episodes = builtin.search.episodes;
    let seed = dataset_seed(builtin.seed, Role::Search, 0);
    for n in [1, threads] {
        let p = pool(n)?;
        let t = Instant::now();
        let a = p.install(|| dataset::collect(builtin.env.env(), episodes, seed))?;
        let builtin_s = t.elapsed().as_secs_f64();
        // One batch to start the pool's workers, so that the figure is the steady state.
        p.install(|| dataset::collect(g.as_ref(), n * 100, seed))?;
        let before = stats();
        let t = Instant::now();
        let b = p.install(|| dataset::collect(g.as_ref(), episodes, seed))?;
        let gymnasium_s = t.elapsed().as_secs_f64();
        let (python_s, bridge_s, round_trips) = delta(before, stats());
        pairs.push(Pair {
            job: format!("dataset collection, {episodes} random-policy episodes, {n} thread(s)"),
            steps: b.len(),
            builtin_s,
            gymnasium_s,
            builtin_steps_per_s: a.len() as f64 / builtin_s,
            gymnasium_steps_per_s: b.len() as f64 / gymnasium_s,
            python_s,
            bridge_s,
            round_trips,
        });
    }

    // Greedy evaluation: E episodes of the PD controller, in lock-step through the bridge.
    for e in [1, 10, 100] {
        let mut c = CartPoleConfig::default();
        c.eval.episodes = e;
        // Through JSON, as any setting of a gymnasium env is made (its derived tables are fresh).
        let mut v = serde_json::to_value(g.as_ref()).map_err(|x| Error::Data(x.to_string()))?;
        v["eval"]["episodes"] = e.into();
        let gc: GymConfig = serde_json::from_value(v).map_err(|x| Error::Data(x.to_string()))?;
        let seed = eval_seed(builtin.seed, 0);
        let t = Instant::now();
        let a = evaluate(&c, &mut pd, seed)?;
        let builtin_s = t.elapsed().as_secs_f64();
        let before = stats();
        let t = Instant::now();
        let b = evaluate(&gc, &mut pd, seed)?;
        let gymnasium_s = t.elapsed().as_secs_f64();
        let (python_s, bridge_s, round_trips) = delta(before, stats());
        let (sa, sb) = (a.steps * e as f64, b.steps * e as f64);
        pairs.push(Pair {
            job: format!("greedy evaluation, {e} episode(s) of ≤ {} steps", c.eval.steps),
            steps: sb as usize,
            builtin_s,
            gymnasium_s,
            builtin_steps_per_s: sa / builtin_s,
            gymnasium_steps_per_s: sb / gymnasium_s,
            python_s,
            bridge_s,
            round_trips,
        });
    }
    for p in &pairs {
        say(format!(
            "  {}: built-in {:.0} steps/s ({:.3} s), CartPole-v1 {:.0} steps/s ({:.3} s, {:.1}× slower); \
             in Python {:.3} s, waiting for the worker {:.3} s over {} round trips",
            p.job,
            p.builtin_steps_per_s,
            p.builtin_s,
            p.gymnasium_steps_per_s,
            p.gymnasium_s,
            p.gymnasium_s / p.builtin_s,
            p.python_s,
            p.bridge_s,
            p.round_trips
        ));
    }
    let per_step_us = |p: &Pair| 1e6 * p.python_s / p.steps.max(1) as f64;
    let per_trip_us = |p: &Pair| 1e6 * (p.bridge_s - p.python_s) / p.round_trips.max(1) as f64;
    let (collect, lock) = (&pairs[0], &pairs[pairs.len() - 1]);
    say(format!(
        "  what bounds it: {:.1} µs of Python per step when collecting (gymnasium's step with its wrappers), \
         {:.1} µs per step and {:.0} µs per round trip beyond it (pipes, framing, wake-ups) when evaluating",
        per_step_us(collect),
        per_step_us(lock),
        per_trip_us(&pairs[2])
    ));

    // A search unit: the thesis optimum on search dataset 0, one thread, in a fresh evaluator
    // (so its dataset is collected inside the unit, as the first unit of a dataset is).
    let (t_cfg, _) = TunedConfig::resolve("thesis", "cartpole")?;
    let s = Decoded { activation: t_cfg.activation, delta_min: t_cfg.delta_min, patience: t_cfg.patience };
    let one = pool(1)?;
    let mut units = Vec::new();
    for spec in [&builtin, &gym] {
        let tmp = std::env::temp_dir().join(format!("bfqi-bench-gym-{}", std::process::id()));
        let ev = Evaluator::new(spec.clone(), &tmp);
        let before = stats();
        let t = Instant::now();
        let u = one.install(|| ev.evaluate(&s, 0))?;
        let seconds = t.elapsed().as_secs_f64();
        let (python_s, bridge_s, round_trips) = delta(before, stats());
        let _ = std::fs::remove_dir_all(&tmp);
        units.push(serde_json::json!({
            "env": spec.env.env().name(), "setting": setting_id(&s), "seconds": seconds, "score": u.score,
            "epochs": u.epochs, "python_s": python_s, "bridge_s": bridge_s, "round_trips": round_trips,
            "python_share": python_s / seconds, "bridge_share": bridge_s / seconds,
        }));
        say(format!(
            "  search unit {} on {} dataset 0 (collection included), 1 thread: {seconds:.2} s, {} epochs, score {}; \
             {python_s:.3} s in Python ({:.1} %), {bridge_s:.3} s waiting for the worker ({:.1} %, {round_trips} round trips)",
            setting_id(&s),
            spec.env.env().name(),
            u.epochs,
            u.score.map_or("diverged".into(), |v| format!("{v:.1}")),
            100.0 * python_s / seconds,
            100.0 * bridge_s / seconds
        ));
    }
    Ok(serde_json::json!({
        "threads": threads,
        "python": g.python(),
        "worker_start_s": start_s,
        "jobs": pairs,
        "units": units,
        "python_us_per_step_collecting": per_step_us(collect),
        "python_us_per_step_lock_step": per_step_us(lock),
        "bridge_us_per_round_trip": per_trip_us(&pairs[2]),
    }))
}
