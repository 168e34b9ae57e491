//! Cart-pole: gym `CartPole-v0` dynamics with the thesis's reward `cos(k·θ')` (SPEC §1.2).

use super::{Env, EvalConfig, Outcome, ScoreKind, draw_box, positive, validate_box, validate_common};
use crate::error::{Result, ensure};
use crate::rng::{Rng, below};
use serde::{Deserialize, Serialize};

/// Settings of the cart-pole. State and observation `(x, ẋ, θ, θ̇)`; actions are indices
/// `0 → −force`, `1 → +force`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CartPoleConfig {
    /// Gravity.
    pub g: f64,
    /// Cart mass.
    pub m_cart: f64,
    /// Pole mass.
    pub m_pole: f64,
    /// Half the pole's length.
    pub l: f64,
    /// Magnitude of the push (N).
    pub force: f64,
    /// Integration step (s).
    pub tau: f64,
    /// Failure when |x| exceeds this.
    pub x_threshold: f64,
    /// Failure when |θ| exceeds this many degrees.
    pub theta_threshold_deg: f64,
    /// k in the reward `cos(k·θ')` (thesis text 15; the original code later used 3.75).
    pub reward_factor: f64,
    /// Dataset episode cap (a time limit, not absorbing).
    pub horizon: usize,
    /// Discount factor.
    pub gamma: f64,
    /// Action indices as feature values (`[0, 1]`).
    pub actions: Vec<f64>,
    /// Uniform box of dataset start states `[x, ẋ, θ, θ̇]`.
    pub dataset_start: Vec<[f64; 2]>,
    /// Evaluation protocol.
    pub eval: EvalConfig,
}

impl Default for CartPoleConfig {
    fn default() -> Self {
        CartPoleConfig {
            g: 9.8,
            m_cart: 1.0,
            m_pole: 0.1,
            l: 0.5,
            force: 10.0,
            tau: 0.02,
            x_threshold: 2.4,
            theta_threshold_deg: 12.0,
            reward_factor: 15.0,
            horizon: 200,
            gamma: 1.0,
            actions: vec![0.0, 1.0],
            dataset_start: vec![[-2.4, 2.4], [-3.5, 3.5], [-0.05, 0.05], [-3.0, 3.0]],
            eval: EvalConfig { episodes: 1, steps: 200, score: ScoreKind::Return, start: vec![[-0.05, 0.05]; 4] },
        }
    }
}

impl CartPoleConfig {
    pub(super) fn validate(&self) -> Result<()> {
        for (f, v) in [("g", self.g), ("m_cart", self.m_cart), ("m_pole", self.m_pole), ("l", self.l)] {
            positive(f, v)?;
        }
        for (f, v) in [("force", self.force), ("tau", self.tau), ("x_threshold", self.x_threshold)] {
            positive(f, v)?;
        }
        positive("theta_threshold_deg", self.theta_threshold_deg)?;
        ensure(self.reward_factor.is_finite(), "reward_factor", self.reward_factor, "must be finite")?;
        validate_common(self.gamma, self.horizon, &self.actions)?;
        ensure(self.actions == [0.0, 1.0], "actions", format!("{:?}", self.actions), "must be [0, 1]")?;
        validate_box(&self.dataset_start, 4, "dataset_start")
    }
}

impl Env for CartPoleConfig {
    fn name(&self) -> &'static str {
        "cartpole"
    }
    fn state_dim(&self) -> usize {
        4
    }
    fn obs_dim(&self) -> usize {
        4
    }
    fn observe(&self, s: &[f64], obs: &mut [f64]) {
        obs.copy_from_slice(&s[..4]);
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
        below(rng, 2) as f64
    }
    fn step(&self, s: &[f64], action: f64, _rng: &mut Rng, next: &mut [f64]) -> Outcome {
        let (x, x_dot, th, th_dot) = (s[0], s[1], s[2], s[3]);
        let f = if action >= 0.5 { self.force } else { -self.force };
        let total = self.m_cart + self.m_pole;
        let pml = self.m_pole * self.l;
        let (sin, cos) = th.sin_cos();
        let temp = (f + pml * th_dot * th_dot * sin) / total;
        let th_acc = (self.g * sin - cos * temp) / (self.l * (4.0 / 3.0 - self.m_pole * cos * cos / total));
        let x_acc = temp - pml * th_acc * cos / total;
        // Explicit Euler in gym's order: positions use the old velocities.
        next[0] = x + self.tau * x_dot;
        next[1] = x_dot + self.tau * x_acc;
        next[2] = th + self.tau * th_dot;
        next[3] = th_dot + self.tau * th_acc;
        let theta_limit = self.theta_threshold_deg * 2.0 * std::f64::consts::PI / 360.0;
        let failed = next[0].abs() > self.x_threshold || next[2].abs() > theta_limit;
        Outcome { reward: (self.reward_factor * next[2]).cos(), failed }
    }
    fn eval(&self) -> &EvalConfig {
        &self.eval
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;

    fn step(c: &CartPoleConfig, s: [f64; 4], a: f64) -> ([f64; 4], Outcome) {
        let mut next = [0.0; 4];
        let o = c.step(&s, a, &mut stream(0, "test", &[]), &mut next);
        (next, o)
    }

    fn close(a: &[f64], b: &[f64]) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-12, "{a:?} vs {b:?}");
        }
    }

    // Expected values computed independently (a separate Python transcription of the SPEC equations).
    #[test]
    fn hand_worked_transition_at_rest_push_right() {
        // θ=0: temp = 10/1.1 = 9.090909…, θ̈ = −temp/(0.5·(4/3 − 0.1/1.1)) = −14.634146341463413,
        // ẍ = temp − 0.05·θ̈/1.1 = 9.75609756097561; positions move with the old (zero) velocities.
        let (n, o) = step(&CartPoleConfig::default(), [0.0; 4], 1.0);
        close(&n, &[0.0, 0.1951219512195122, 0.0, -0.2926829268292683]);
        assert_eq!(o.reward, 1.0);
        assert!(!o.failed);
    }

    #[test]
    fn hand_worked_transition_tilted_push_left() {
        let (n, o) = step(&CartPoleConfig::default(), [0.1, -0.2, 0.05, 0.3], 0.0);
        close(&n, &[0.096, -0.3957976546439626, 0.056, 0.6080233136061515]);
        close(&[o.reward], &[(15.0f64 * 0.056).cos()]);
        assert!(!o.failed);
    }

    #[test]
    fn hand_worked_transition_with_other_reward_factor() {
        let c = CartPoleConfig { reward_factor: 3.75, ..Default::default() };
        let (n, o) = step(&c, [-1.0, 0.5, -0.1, -1.0], 1.0);
        close(&n, &[-0.99, 0.6963059968567418, -0.12, -1.322338951306437]);
        close(&[o.reward], &[(3.75f64 * -0.12).cos()]);
    }

    #[test]
    fn failure_on_angle_and_position_only() {
        let c = CartPoleConfig::default();
        // θ' = 0.2 + 0.02·1 = 0.22 > 12° = 0.2094 rad → failure.
        assert!(step(&c, [0.0, 0.0, 0.2, 1.0], 1.0).1.failed);
        // x' = 2.39 + 0.02·1 = 2.41 > 2.4 → failure.
        assert!(step(&c, [2.39, 1.0, 0.0, 0.0], 1.0).1.failed);
        assert!(!step(&c, [2.3, 1.0, 0.1, 0.0], 1.0).1.failed);
    }
}
