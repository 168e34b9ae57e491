//! Swing-up pendulum, exactly gym's `Pendulum-v0` (SPEC §1.1).

use super::{Env, EvalConfig, Outcome, ScoreKind, draw_box, positive, validate_box, validate_common};
use crate::error::Result;
use crate::rng::{Rng, uniform};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Settings of the swing-up pendulum. Hidden state `(θ, θ̇)`; observation `(cos θ, sin θ, θ̇)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PendulumConfig {
    /// |θ̇| is clipped to this after each step.
    pub max_speed: f64,
    /// Torques are clipped to ±this.
    pub max_torque: f64,
    /// Integration step (s).
    pub dt: f64,
    /// Gravity.
    pub g: f64,
    /// Mass.
    pub m: f64,
    /// Length.
    pub l: f64,
    /// Dataset episode length (never absorbing).
    pub horizon: usize,
    /// Discount factor.
    pub gamma: f64,
    /// The discrete torques the learner maximises over (ties go to the first).
    pub actions: Vec<f64>,
    /// Uniform box of dataset start states `[θ, θ̇]`.
    pub dataset_start: Vec<[f64; 2]>,
    /// Range of the random policy's continuous torque.
    pub dataset_torque: [f64; 2],
    /// Evaluation protocol.
    pub eval: EvalConfig,
}

impl Default for PendulumConfig {
    fn default() -> Self {
        let reset = vec![[-PI, PI], [-1.0, 1.0]];
        PendulumConfig {
            max_speed: 8.0,
            max_torque: 2.0,
            dt: 0.05,
            g: 10.0,
            m: 1.0,
            l: 1.0,
            horizon: 200,
            gamma: 1.0,
            actions: vec![2.0, -2.0],
            dataset_start: reset.clone(),
            dataset_torque: [-2.0, 2.0],
            eval: EvalConfig { episodes: 5, steps: 200, score: ScoreKind::MeanRewardPerStep, start: reset },
        }
    }
}

/// `((x + π) mod 2π) − π` with a floored modulo, as numpy computes it.
fn angle_normalize(x: f64) -> f64 {
    (x + PI).rem_euclid(2.0 * PI) - PI
}

impl PendulumConfig {
    pub(super) fn validate(&self) -> Result<()> {
        for (f, v) in [("max_speed", self.max_speed), ("max_torque", self.max_torque), ("dt", self.dt)] {
            positive(f, v)?;
        }
        for (f, v) in [("g", self.g), ("m", self.m), ("l", self.l)] {
            positive(f, v)?;
        }
        validate_common(self.gamma, self.horizon, &self.actions)?;
        validate_box(&self.dataset_start, 2, "dataset_start")?;
        validate_box(&[self.dataset_torque], 1, "dataset_torque")
    }
}

impl Env for PendulumConfig {
    fn name(&self) -> &'static str {
        "pendulum"
    }
    fn state_dim(&self) -> usize {
        2
    }
    fn obs_dim(&self) -> usize {
        3
    }
    fn observe(&self, s: &[f64], obs: &mut [f64]) {
        obs[0] = s[0].cos();
        obs[1] = s[0].sin();
        obs[2] = s[1];
    }
    fn actions(&self) -> &[f64] {
        &self.actions
    }
    fn gamma(&self) -> f64 {
        self.gamma
    }
    fn horizon(&self) -> usize {
        self.horizon
    }
    fn dataset_start(&self, rng: &mut Rng, state: &mut [f64]) {
        draw_box(&self.dataset_start, rng, state);
    }
    fn dataset_action(&self, rng: &mut Rng) -> f64 {
        uniform(rng, self.dataset_torque[0], self.dataset_torque[1])
    }
    fn step(&self, s: &[f64], torque: f64, _rng: &mut Rng, next: &mut [f64]) -> Outcome {
        let (th, thdot) = (s[0], s[1]);
        let u = torque.clamp(-self.max_torque, self.max_torque);
        let cost = angle_normalize(th).powi(2) + 0.1 * thdot * thdot + 0.001 * u * u;
        let (g, m, l, dt) = (self.g, self.m, self.l, self.dt);
        let new_thdot = thdot + (-3.0 * g / (2.0 * l) * (th + PI).sin() + 3.0 / (m * l * l) * u) * dt;
        // gym integrates θ with the unclipped velocity, then clips the velocity.
        next[0] = th + new_thdot * dt;
        next[1] = new_thdot.clamp(-self.max_speed, self.max_speed);
        Outcome { reward: -cost, failed: false }
    }
    fn eval(&self) -> &EvalConfig {
        &self.eval
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;

    fn step(s: [f64; 2], u: f64) -> ([f64; 2], Outcome) {
        let mut next = [0.0; 2];
        let o = PendulumConfig::default().step(&s, u, &mut stream(0, "test", &[]), &mut next);
        (next, o)
    }

    fn close(a: f64, b: f64) {
        assert!((a - b).abs() <= 1e-12, "{a} vs {b}");
    }

    // Expected values worked by hand from the SPEC equations:
    // θ̇' = θ̇ + (−15·sin(θ+π) + 3u)·0.05, θ' = θ + θ̇'·0.05, cost = norm(θ)² + 0.1θ̇² + 0.001u².
    #[test]
    fn hand_worked_transition_upright_push() {
        // θ=0.5, θ̇=−0.3, u=1.2: sin(0.5+π) = −0.479425538604203
        // θ̇' = −0.3 + (7.191383079063045 + 3.6)·0.05 = 0.23956915395315226
        let (n, o) = step([0.5, -0.3], 1.2);
        close(n[1], 0.23956915395315226);
        close(n[0], 0.5 + 0.23956915395315226 * 0.05);
        close(o.reward, -(0.25 + 0.1 * 0.09 + 0.001 * 1.44));
        assert!(!o.failed);
    }

    #[test]
    fn hand_worked_transition_clips_torque_and_wraps_angle() {
        // θ=4.0 normalises to 4 − 2π = −2.283185307179586; u=5 clips to 2 (cost uses 2).
        // sin(4+π) = 0.7568024953079282 → θ̇' = 1.0 + (−11.352037429618923 + 6)·0.05 = 0.732_398_128_519_053_8
        let (n, o) = step([4.0, 1.0], 5.0);
        close(n[1], 0.732_398_128_519_053_8);
        close(n[0], 4.0 + 0.732_398_128_519_053_8 * 0.05);
        let norm: f64 = 4.0 - 2.0 * PI;
        close(o.reward, -(norm * norm + 0.1 + 0.001 * 4.0));
    }

    #[test]
    fn hand_worked_transition_clips_speed_after_integrating() {
        // θ=−2, θ̇=7.9, u=2: sin(−2+π) = 0.9092974268256817
        // θ̇' = 7.9 + (−13.639461402385225 + 6)·0.05 = 7.518026929880739 (inside the clip)
        let (n, _) = step([-2.0, 7.9], 2.0);
        close(n[1], 7.518026929880739);
        // θ=π/2 (sin(3π/2) = −1), θ̇=7.9, u=2: θ̇' = 7.9 + 21·0.05 = 8.95 → θ uses 8.95, θ̇ clips to 8.
        let (n, o) = step([PI / 2.0, 7.9], 2.0);
        close(n[0], PI / 2.0 + 8.95 * 0.05);
        close(n[1], 8.0);
        close(o.reward, -((PI / 2.0).powi(2) + 0.1 * 7.9 * 7.9 + 0.004));
    }

    #[test]
    fn observation_is_cos_sin_velocity() {
        let mut obs = [0.0; 3];
        PendulumConfig::default().observe(&[0.3, -1.5], &mut obs);
        assert_eq!(obs, [0.3f64.cos(), 0.3f64.sin(), -1.5]);
    }
}
