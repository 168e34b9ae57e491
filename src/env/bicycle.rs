//! Bicycle balancing: Randløv & Alstrøm dynamics as printed by Ernst et al. 2005 (SPEC §1.3).

use super::{Env, EvalConfig, Outcome, ScoreKind, draw_box, positive, sign, validate_box, validate_common};
use crate::error::{Result, ensure};
use crate::rng::{Rng, below, uniform};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Settings of the bicycle. State and observation `(ω, ω̇, θ, θ̇, ψ)`: frame tilt and its rate,
/// handlebar angle and its rate, heading. Action `a ∈ 0..9` applies torque `torques[a div 3]` and
/// displacement `displacements[a mod 3]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BicycleConfig {
    /// Integration step (s).
    pub dt: f64,
    /// Speed (m/s).
    pub v: f64,
    /// Gravity.
    pub g: f64,
    /// Vertical distance between the centre of mass of bicycle and cyclist.
    pub d_cm: f64,
    /// Horizontal distance between the front tyre's contact point and the centre of mass.
    pub c: f64,
    /// Height of the centre of mass over the ground.
    pub h: f64,
    /// Mass of the bicycle.
    pub m_c: f64,
    /// Mass of a tyre.
    pub m_d: f64,
    /// Mass of the cyclist.
    pub m_p: f64,
    /// Tyre radius.
    pub r: f64,
    /// Distance between the tyres' contact points.
    pub l: f64,
    /// Half-width of the uniform displacement noise w.
    pub noise: f64,
    /// Failure when |ω| exceeds this many degrees.
    pub omega_max_deg: f64,
    /// The handlebar angle is held within ±this many degrees.
    pub theta_max_deg: f64,
    /// Torques on the handlebar, indexed by `a div 3`.
    pub torques: [f64; 3],
    /// Rider displacements, indexed by `a mod 3`.
    pub displacements: [f64; 3],
    /// Step cap of a dataset episode.
    pub horizon: usize,
    /// Discount factor.
    pub gamma: f64,
    /// Action indices as feature values (`0..9`).
    pub actions: Vec<f64>,
    /// Uniform box of dataset start states.
    pub dataset_start: Vec<[f64; 2]>,
    /// Evaluation protocol.
    pub eval: EvalConfig,
}

impl Default for BicycleConfig {
    fn default() -> Self {
        BicycleConfig {
            dt: 0.01,
            v: 10.0 / 3.6,
            g: 9.82,
            d_cm: 0.3,
            c: 0.66,
            h: 0.94,
            m_c: 15.0,
            m_d: 1.7,
            m_p: 60.0,
            r: 0.34,
            l: 1.11,
            noise: 0.02,
            omega_max_deg: 12.0,
            theta_max_deg: 80.0,
            torques: [-2.0, 0.0, 2.0],
            displacements: [-0.02, 0.0, 0.02],
            horizon: 5000,
            gamma: 0.98,
            actions: (0..9).map(f64::from).collect(),
            dataset_start: vec![[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [-PI, PI]],
            eval: EvalConfig {
                episodes: 1,
                steps: 5000,
                score: ScoreKind::DiscountedReturn,
                start: vec![[0.0, 0.0]; 5],
            },
        }
    }
}

impl BicycleConfig {
    pub(super) fn validate(&self) -> Result<()> {
        for (f, v) in [("dt", self.dt), ("v", self.v), ("g", self.g), ("d_cm", self.d_cm), ("c", self.c)] {
            positive(f, v)?;
        }
        for (f, v) in [("h", self.h), ("m_c", self.m_c), ("m_d", self.m_d), ("m_p", self.m_p), ("r", self.r)] {
            positive(f, v)?;
        }
        positive("l", self.l)?;
        positive("omega_max_deg", self.omega_max_deg)?;
        positive("theta_max_deg", self.theta_max_deg)?;
        ensure(self.noise.is_finite() && self.noise >= 0.0, "noise", self.noise, "must be finite and ≥ 0")?;
        validate_common(self.gamma, self.horizon, &self.actions)?;
        let indices: Vec<f64> = (0..9).map(f64::from).collect();
        ensure(self.actions == indices, "actions", format!("{:?}", self.actions), "must be [0, 1, …, 8]")?;
        validate_box(&self.dataset_start, 5, "dataset_start")
    }

    /// One step with an explicit noise value `w` (the trait's [`Env::step`] draws it).
    /// Every right-hand side uses the old state (explicit Euler).
    pub fn step_with_noise(&self, s: &[f64], action: usize, w: f64, next: &mut [f64]) -> Outcome {
        let (omega, omega_dot, theta, theta_dot, psi) = (s[0], s[1], s[2], s[3], s[4]);
        let torque = self.torques[action / 3];
        let d = self.displacements[action % 3];
        let m = self.m_c + self.m_p;
        let sigma_dot = self.v / self.r;
        let i_bc = 13.0 / 3.0 * self.m_c * self.h * self.h + self.m_p * (self.h + self.d_cm).powi(2);
        let i_dc = self.m_d * self.r * self.r;
        let i_dv = 1.5 * self.m_d * self.r * self.r;
        let i_dl = 0.5 * self.m_d * self.r * self.r;

        let phi = omega + (d + w).atan() / self.h;
        let invr_f = theta.sin().abs() / self.l;
        let invr_b = theta.tan().abs() / self.l;
        let invr_cm =
            if theta != 0.0 { 1.0 / ((self.l - self.c).powi(2) + 1.0 / (invr_b * invr_b)).sqrt() } else { 0.0 };

        next[0] = omega + self.dt * omega_dot;
        let lean = m * self.h * self.g * phi.sin();
        let steer = i_dc * sigma_dot * theta_dot
            + sign(theta) * self.v * self.v * (self.m_d * self.r * (invr_f + invr_b) + m * self.h * invr_cm);
        next[1] = omega_dot + self.dt * (lean - phi.cos() * steer) / i_bc;
        let theta_max = self.theta_max_deg * PI / 180.0;
        let new_theta = theta + self.dt * theta_dot;
        if new_theta.abs() > theta_max {
            next[2] = sign(new_theta) * theta_max;
            next[3] = 0.0;
        } else {
            next[2] = new_theta;
            next[3] = theta_dot + self.dt * (torque - i_dv * sigma_dot * omega_dot) / i_dl;
        }
        next[4] = psi + self.dt * sign(theta) * self.v * invr_b;

        let omega_max = self.omega_max_deg * PI / 180.0;
        if next[0].abs() > omega_max {
            Outcome { reward: -1.0, failed: true }
        } else {
            Outcome { reward: -next[0].abs() / omega_max, failed: false }
        }
    }
}

impl Env for BicycleConfig {
    fn name(&self) -> &'static str {
        "bicycle"
    }
    fn state_dim(&self) -> usize {
        5
    }
    fn obs_dim(&self) -> usize {
        5
    }
    fn observe(&self, s: &[f64], obs: &mut [f64]) {
        obs.copy_from_slice(&s[..5]);
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
        below(rng, 9) as f64
    }
    fn step(&self, s: &[f64], action: f64, rng: &mut Rng, next: &mut [f64]) -> Outcome {
        let w = uniform(rng, -self.noise, self.noise);
        self.step_with_noise(s, action as usize, w, next)
    }
    fn eval(&self) -> &EvalConfig {
        &self.eval
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(s: [f64; 5], a: usize, w: f64) -> ([f64; 5], Outcome) {
        let mut next = [0.0; 5];
        let o = BicycleConfig::default().step_with_noise(&s, a, w, &mut next);
        (next, o)
    }

    fn close(a: &[f64], b: &[f64]) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-12, "{a:?} vs {b:?}");
        }
    }

    // Expected values computed independently (a separate Python transcription of the SPEC equations).
    #[test]
    fn hand_worked_transition_upright_lean_only() {
        // θ = 0: the invr terms vanish and sign(θ) = 0, so only the lean φ = atan(d + w)/h acts.
        let (n, o) = step([0.0; 5], 5, 0.01);
        close(&n, &[0.0, 0.001475357591819984, 0.0, 0.0, 0.0]);
        assert_eq!(o.reward, 0.0);
        assert!(!o.failed);
    }

    #[test]
    fn hand_worked_transition_turning() {
        let (n, o) = step([0.05, -0.2, 0.3, 1.5, 0.7], 0, -0.015);
        close(&n, &[0.048, -0.2097800058763677, 0.315, 1.3454779835809756, 0.7077411473876282]);
        close(&[o.reward], &[-0.2291831180523293]);
        assert!(!o.failed);
    }

    #[test]
    fn hand_worked_transition_handlebar_hits_its_stop() {
        // θ + dt·θ̇ = −1.41 < −80°: θ' is held at −80° and θ̇' set to 0.
        let (n, o) = step([-0.1, 0.4, -1.39, -2.0, -2.5], 8, 0.0);
        close(&n, &[-0.096, 0.4716949607873385, -1.3962634015954636, 0.0, -2.636904120194024]);
        close(&[o.reward], &[-0.4583662361046586]);
    }

    #[test]
    fn falling_is_absorbing_with_reward_minus_one() {
        let (n, o) = step([0.2, 0.8, 0.1, 0.0, 0.0], 4, 0.0);
        close(&n[..1], &[0.208]);
        assert!(!o.failed, "0.208 rad is 11.9°, still up");
        let (n, o) = step([0.205, 0.5, 0.1, 0.0, 0.0], 4, 0.0);
        assert!(n[0] > 12.0 * PI / 180.0);
        assert_eq!(o, Outcome { reward: -1.0, failed: true });
    }
}
