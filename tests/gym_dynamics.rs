//! gymnasium's CartPole-v1 and Pendulum-v1, through the bridge, against the built-in cart-pole and
//! pendulum, transition by transition (issue 39). The datasets come from `bfqi-ga dataset` on the
//! test env `BfqiStateObs-v0`, whose observation is the inner env's exact internal state (float64)
//! followed by its own observation; each transition is stepped again by the built-in simulator
//! from that state. The documented differences (README, "Gymnasium"):
//! - cart-pole: the dynamics coincide (to rounding: gymnasium writes θ̇²·sinθ as (m_p·l·θ̇²)·sinθ and
//!   cos²θ as m_p·cos²θ); gymnasium's reward is 1 per step where the built-in one is the thesis's
//!   cos(15·θ'); gymnasium's observation is the state rounded to float32.
//! - pendulum: Pendulum-v1 clips θ̇ before it integrates θ, the built-in Pendulum-v0 after (they
//!   differ only on steps that reach max_speed 8); v1 writes +3g/(2l)·sinθ for v0's −3g/(2l)·sin(θ+π);
//!   v1 computes the torque's terms 3u/(ml²) and 0.001·u² in float32 (u is the Box's float32
//!   action, and numpy keeps float32 against a Python float), differences below 2e-8; its
//!   observation (cos θ, sin θ, θ̇) is float32.

mod common;
use common::empty_dir;
use common::gym::{csv, gym_bin, python, write_spec};

use bfqi_ga::env::{CartPoleConfig, Env, PendulumConfig};
use std::f64::consts::PI;

fn dataset(py: &str, dir: &Path, base: &str, env: serde_json::Value, episodes: usize) -> Vec<Vec<f64>> {
    let spec = write_spec(&dir.join("spec.json"), base, env);
    let out = dir.join("d.csv");
    let o = gym_bin(py)
        .args(["dataset", spec.to_str().unwrap(), "--episodes", &episodes.to_string(), "--seed", "7", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    csv(&out).1
}

use std::path::Path;

/// |a − b| ≤ tol·max(1, |a|, |b|).
fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * 1f64.max(a.abs()).max(b.abs())
}

#[test]
fn cartpole_v1_steps_as_the_builtin_cartpole() {
    let Some(py) = python() else { return };
    let dir = empty_dir("gymdyn", "cartpole");
    let env = serde_json::json!({
        "id": "bfqi_gym_testenvs:BfqiStateObs-v0", "kwargs": {"inner": "CartPole-v1", "state_dim": 4},
        "horizon": 200, "gamma": 1.0, "reset_options": {"low": -0.2, "high": 0.2}
    });
    // Columns: episode, step, state (4 exact + 4 float32), action, reward, next (4 + 4), absorbing.
    let rows = dataset(&py, &dir, "cartpole", env, 300);
    assert!(rows.len() > 2000, "{} transitions", rows.len());
    let c = CartPoleConfig::default();
    let mut rng = bfqi_ga::rng::stream(0, "test", &[]);
    let mut worst = 0.0f64;
    for r in &rows {
        let (s, a, reward, next, absorbing) = (&r[2..6], r[10], r[11], &r[12..16], r[20] == 1.0);
        let mut ours = [0.0; 4];
        let o = c.step(s, a, &mut rng, &mut ours);
        for i in 0..4 {
            assert!(close(ours[i], next[i], 1e-12), "{r:?}: built-in {ours:?}");
            worst = worst.max((ours[i] - next[i]).abs());
        }
        assert_eq!(o.failed, absorbing, "{r:?}: termination");
        assert_eq!(reward, 1.0, "CartPole-v1 pays 1 per step (the built-in pays cos(15θ'))");
        for i in 0..4 {
            assert_eq!(r[6 + i], s[i] as f32 as f64, "the observation is the state in float32");
        }
    }
    eprintln!("cart-pole: {} transitions, largest difference {worst:e}", rows.len());
}

#[test]
fn pendulum_v1_steps_as_the_builtin_pendulum_but_clips_before_integrating() {
    let Some(py) = python() else { return };
    let dir = empty_dir("gymdyn", "pendulum");
    let env = serde_json::json!({
        "id": "bfqi_gym_testenvs:BfqiStateObs-v0", "kwargs": {"inner": "Pendulum-v1", "state_dim": 2},
        "actions": [-2.0, 0.0, 2.0], "dataset_policy": "uniform_box", "horizon": 200, "gamma": 1.0
    });
    // Columns: episode, step, state (θ, θ̇; cos, sin, θ̇ in float32), torque, reward, next (5), absorbing.
    let rows = dataset(&py, &dir, "pendulum", env, 40);
    assert_eq!(rows.len(), 40 * 200);
    let p = PendulumConfig::default();
    let mut rng = bfqi_ga::rng::stream(0, "test", &[]);
    let (mut clipped, mut obs) = (0, [0.0; 3]);
    for r in &rows {
        let (s, u, reward, next) = (&r[2..4], r[7], r[8], &r[9..11]);
        assert_eq!(u, u as f32 as f64, "torques are the float32 the env receives");
        let mut ours = [0.0; 2];
        let o = p.step(s, u, &mut rng, &mut ours);
        // Pendulum-v1 as written, differences and all: the torque term 3u/(ml²) and the cost
        // 0.001·u² in float32, +3g/(2l)·sinθ, θ̇ clipped before θ is integrated.
        let (th, thdot, dt) = (s[0], s[1], p.dt);
        let torque = (3.0f32 * u as f32) as f64;
        let v1_thdot = (thdot + (3.0 * p.g / (2.0 * p.l) * th.sin() + torque) * dt).clamp(-p.max_speed, p.max_speed);
        let v1_th = th + v1_thdot * dt;
        let norm = (th + PI).rem_euclid(2.0 * PI) - PI;
        let v1_reward = -(norm * norm + 0.1 * (thdot * thdot) + (0.001f32 * (u as f32 * u as f32)) as f64);
        assert!(close(v1_thdot, next[1], 1e-12) && close(v1_th, next[0], 1e-12), "{r:?}: v1 as written");
        // (numpy's float32 u**2 is not always u·u in float32: an ulp or two of the term, ≤ 5e-10.)
        assert!((v1_reward - reward).abs() <= 1e-9, "{r:?}: v1's reward as written");
        // The built-in pendulum: the same θ̇ up to the float32 torque term (half an ulp of 6 in
        // float32, 2⁻²², times dt: 1.2e-8).
        assert!((ours[1] - next[1]).abs() <= 2e-8, "{r:?}: θ̇ {ours:?}");
        let raw = (ours[0] - th) / dt;
        if raw.abs() > p.max_speed {
            // v0 integrates θ with the velocity before the clip, v1 with the clipped one.
            clipped += 1;
            assert!((th + ours[1] * dt - next[0]).abs() <= 2e-8, "{r:?}: v1 integrates the clipped θ̇");
        } else {
            assert!((ours[0] - next[0]).abs() <= 2e-8, "{r:?}: θ {ours:?}");
        }
        assert!((o.reward - reward).abs() <= 1e-9, "{r:?}: reward {} (v1's torque cost is float32)", o.reward);
        assert_eq!(r[14], 0.0, "never absorbing");
        p.observe(next, &mut obs);
        for i in 0..3 {
            assert!((r[11 + i] - obs[i] as f32 as f64).abs() <= 1e-7, "{r:?}: observation {obs:?} in float32");
        }
    }
    eprintln!("pendulum: {} transitions, {clipped} reach max_speed", rows.len());
}
