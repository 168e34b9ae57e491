//! The two training controls: the RMSProp update and the early-stopping rule.

/// RMSProp as in Keras 1.2.1 (the thesis's version), in f32: per parameter,
/// `a ← ρ·a + (1−ρ)·g²;  w ← w − lr·g / (√a + ε)`, accumulators starting at 0.
#[derive(Debug, Clone, PartialEq)]
pub struct RmsProp {
    lr: f32,
    rho: f32,
    one_minus_rho: f32,
    eps: f32,
    acc: Vec<f32>,
}

impl RmsProp {
    /// An optimiser for `n_params` parameters, accumulators zero.
    pub fn new(n_params: usize, learning_rate: f64, rho: f64, epsilon: f64) -> RmsProp {
        let rho = rho as f32;
        // Keras computes `1. - rho` with rho held as a float32 variable.
        RmsProp {
            lr: learning_rate as f32,
            rho,
            one_minus_rho: 1.0 - rho,
            eps: epsilon as f32,
            acc: vec![0.0; n_params],
        }
    }

    /// One update of `params` with the gradient `grad`.
    #[inline(always)]
    pub fn step(&mut self, params: &mut [f32], grad: &[f32]) {
        assert!(params.len() == self.acc.len() && grad.len() == self.acc.len());
        // Separate multiplies and adds (never contracted by Rust), so every CPU rounds alike.
        for ((p, a), &g) in params.iter_mut().zip(&mut self.acc).zip(grad) {
            *a = self.rho * *a + self.one_minus_rho * (g * g);
            *p -= self.lr * g / (a.sqrt() + self.eps);
        }
    }

    /// The running averages of squared gradients.
    pub fn accumulators(&self) -> &[f32] {
        &self.acc
    }
}

/// Keras 1.2.1's `EarlyStopping(monitor="val_loss")`: an epoch improves iff
/// `val_loss < best − delta_min` (best starts at +∞, and becomes the improving loss); training
/// stops at the end of the (patience+1)-th consecutive epoch without improvement. Weights are not
/// rolled back, so this holds no model.
#[derive(Debug, Clone, PartialEq)]
pub struct EarlyStopping {
    delta_min: f64,
    patience: usize,
    best: f64,
    wait: usize,
}

impl EarlyStopping {
    /// A rule with no epoch seen yet.
    pub fn new(delta_min: f64, patience: usize) -> EarlyStopping {
        EarlyStopping { delta_min, patience, best: f64::INFINITY, wait: 0 }
    }

    /// Records one epoch's validation loss; returns true when training stops after this epoch.
    pub fn update(&mut self, val_loss: f64) -> bool {
        if val_loss < self.best - self.delta_min {
            self.best = val_loss;
            self.wait = 0;
            false
        } else {
            self.wait += 1;
            self.wait > self.patience
        }
    }

    /// The best validation loss so far (+∞ before the first epoch).
    pub fn best(&self) -> f64 {
        self.best
    }

    /// Consecutive epochs without improvement so far.
    pub fn wait(&self) -> usize {
        self.wait
    }
}
