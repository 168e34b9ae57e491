//! The early-stopped MLP regressor (SPEC §3).
//!
//! Hidden layers with one activation, a linear output, Glorot-uniform weights and zero biases;
//! inputs and targets z-scored on each fit (the model keeps the scaling, so it takes and returns
//! raw values); MSE loss; RMSProp as in Keras 1.2.1; mini-batches over a fresh shuffle of the
//! training rows every epoch; the last `validation_fraction` of the rows, as given, for Keras-style
//! early stopping ([`EarlyStopping`]).
//!
//! Everything is f32, computed 16 rows at a time by hand-written kernels (`kernels`) that give the
//! same bits on every x86-64 CPU: the AVX-512, AVX2 and baseline builds differ only in speed.
//!
//! ```
//! use bfqi_ga::learn::{Learner, Regressor, Rows};
//! use bfqi_ga::learn::mlp::{Activation, MlpParams};
//!
//! let x: Vec<f64> = (0..500).map(|i| i as f64 / 100.0).collect();
//! let y: Vec<f64> = x.iter().map(|v| 2.0 * v - 1.0).collect();
//! let params = MlpParams { hidden: vec![8], activation: Activation::Tanh, max_epochs: 200, ..Default::default() };
//! let (model, info) = params.fit(Rows::new(&x, 1).unwrap(), &y, 7).unwrap();
//! assert!(info.epochs >= 1);
//! assert!(model.predict_row(&[2.5]).is_finite());
//! ```

mod kernels;
mod lanes;
#[cfg(target_arch = "aarch64")]
mod neon;
mod net;
mod optim;
mod peak;
mod shuffle;
#[cfg(any(test, all(target_arch = "x86_64", not(target_feature = "fma"))))]
mod softfma;
#[cfg(test)]
mod tests;

pub use net::Shape;
pub use optim::{EarlyStopping, RmsProp};

use super::{FitInfo, Learner, Regressor, Rows, StopReason, check_training_data, cpu};
use crate::error::{Error, Result, ensure};
use crate::rng::{stream, uniform};
use lanes::{Isa, LANES, V};
use net::{Chunks, RowNet, TrainSet, Work};
use serde::{Deserialize, Serialize};
use shuffle::shuffle;

/// Hidden-layer activation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Activation {
    /// Logistic `1 / (1 + e^−x)`.
    Sigmoid,
    /// Hyperbolic tangent.
    Tanh,
    /// `max(x, 0)`.
    Relu,
}

/// Hyperparameters of the MLP (SPEC §3); the defaults are the thesis's bicycle network.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MlpParams {
    /// Widths of the hidden layers, input side first.
    pub hidden: Vec<usize>,
    /// Activation of every hidden unit (the output is linear).
    pub activation: Activation,
    /// RMSProp learning rate.
    pub learning_rate: f64,
    /// RMSProp decay of the squared-gradient average.
    pub rho: f64,
    /// RMSProp denominator offset.
    pub epsilon: f64,
    /// Rows per mini-batch (the last batch of an epoch may be smaller).
    pub batch_size: usize,
    /// Epoch cap.
    pub max_epochs: usize,
    /// Fraction of the rows, taken from the end, held out for early stopping.
    pub validation_fraction: f64,
    /// Minimum decrease of the validation loss that counts as an improvement.
    pub delta_min: f64,
    /// Epochs without improvement tolerated; the next one stops training.
    pub patience: usize,
}

impl Default for MlpParams {
    fn default() -> Self {
        MlpParams {
            hidden: vec![10, 10],
            activation: Activation::Sigmoid,
            learning_rate: 1e-3,
            rho: 0.9,
            epsilon: 1e-8,
            batch_size: 2000,
            max_epochs: 5000,
            validation_fraction: 0.1,
            delta_min: 0.011,
            patience: 75,
        }
    }
}

/// Training and validation loss (MSE on standardized targets) after one epoch.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpochLoss {
    /// Mean over the epoch's batches of each batch's loss, weighted by batch size (as Keras logs it).
    pub train: f64,
    /// Loss on the validation rows with the weights at the end of the epoch.
    pub val: f64,
}

impl MlpParams {
    /// [`Learner::fit`], also returning the losses of every epoch run.
    pub fn fit_with_losses(&self, x: Rows<'_>, y: &[f64], seed: u64) -> Result<(Mlp, FitInfo, Vec<EpochLoss>)> {
        self.fit_on(cpu::mlp(), x, y, seed)
    }

    /// The fit, with the kernels compiled for `isa` (tests compare them; `bench search --isa`
    /// times them side by side).
    pub(crate) fn fit_on(&self, isa: Isa, x: Rows<'_>, y: &[f64], seed: u64) -> Result<(Mlp, FitInfo, Vec<EpochLoss>)> {
        self.check()?;
        check_training_data(x, y)?;
        let n = x.n_rows();
        let split = split_point(n, self.validation_fraction);
        if split == 0 || split >= n {
            return Err(Error::Data(format!(
                "{n} rows with validation_fraction {} leave {split} training and {} validation rows; both need ≥ 1",
                crate::error::short_number(self.validation_fraction.to_string()),
                n - split.min(n)
            )));
        }
        let n_in = x.n_cols();
        if n > u32::MAX as usize || !TrainSet::fits(split, n_in) {
            return Err(Error::Data(format!(
                "{n} rows of {n_in} inputs are more than the MLP's 32-bit row indexing supports"
            )));
        }
        let x_scale: Vec<Standardizer> = (0..n_in).map(|k| Standardizer::fit((0..n).map(|i| x.row(i)[k]))).collect();
        let y_scale = Standardizer::fit(y.iter().copied());
        let shape = Shape::new(n_in, &self.hidden, self.activation);
        let mut params = glorot_init(&shape, seed);

        let train =
            TrainSet::new(
                split,
                n_in,
                |r, k| {
                    if k < n_in { x_scale[k].apply(x.row(r)[k]) } else { y_scale.apply(y[r]) }
                },
            );
        let val =
            Chunks::new(n - split, n_in, |r, k| x_scale[k].apply(x.row(split + r)[k]), |r| y_scale.apply(y[split + r]));

        let mut work = Work::new(&shape);
        let mut opt = RmsProp::new(shape.n_params(), self.learning_rate, self.rho, self.epsilon);
        let mut rule = EarlyStopping::new(self.delta_min, self.patience);
        let mut rng = stream(seed, crate::rng::purpose::MLP_SHUFFLE, &[]);
        let mut perm = vec![0u32; split];
        let mut losses = Vec::with_capacity(self.max_epochs.min(10_000));
        let mut info = FitInfo { epochs: 0, stop: StopReason::MaxEpochs, train_loss: None, val_loss: None };
        for epoch in 1..=self.max_epochs {
            shuffle(&mut perm, &mut rng);
            let train_sse = net::epoch(isa, &shape, &mut params, &mut opt, &train, &perm, self.batch_size, &mut work);
            let val_sse = net::sse(isa, &shape, &params, &val, &mut work);
            let loss = EpochLoss { train: train_sse / split as f64, val: val_sse / (n - split) as f64 };
            losses.push(loss);
            info.epochs = epoch;
            (info.train_loss, info.val_loss) = (Some(loss.train), Some(loss.val));
            if !loss.train.is_finite() || !loss.val.is_finite() || params.iter().any(|p| !p.is_finite()) {
                info.stop = StopReason::NonFinite;
                break;
            }
            if rule.update(loss.val) {
                info.stop = StopReason::EarlyStopping;
                break;
            }
        }
        let row = RowNet::new(&shape, &params);
        Ok((Mlp { shape, params, x_scale, y_scale, row }, info, losses))
    }
}

impl Learner for MlpParams {
    type Model = Mlp;

    fn check(&self) -> Result<()> {
        use crate::limits::{EPOCHS, LAYERS, WIDTH};
        ensure(
            (1..=LAYERS).contains(&self.hidden.len()) && self.hidden.iter().all(|&w| (1..=WIDTH).contains(&w)),
            "hidden",
            format!("{:?}", self.hidden),
            &format!("must list 1 to {LAYERS} layers, each of width 1..={WIDTH}"),
        )?;
        let lr = self.learning_rate;
        ensure(lr.is_finite() && lr > 0.0, "learning_rate", lr, "must be finite and > 0")?;
        ensure(self.rho.is_finite() && (0.0..1.0).contains(&self.rho), "rho", self.rho, "must be in [0, 1)")?;
        ensure(self.epsilon.is_finite() && self.epsilon > 0.0, "epsilon", self.epsilon, "must be finite and > 0")?;
        ensure(self.batch_size >= 1, "batch_size", self.batch_size, "must be ≥ 1")?;
        crate::limits::within("max_epochs", self.max_epochs, 1, EPOCHS)?;
        let f = self.validation_fraction;
        // ≤ 0.5 keeps a training and a validation row in any fit of two rows or more.
        ensure(f.is_finite() && f > 0.0 && f <= 0.5, "validation_fraction", f, "must be in (0, 0.5]")?;
        ensure(
            self.delta_min.is_finite() && self.delta_min >= 0.0,
            "delta_min",
            self.delta_min,
            "must be finite and ≥ 0",
        )
    }

    fn fit(&self, x: Rows<'_>, y: &[f64], seed: u64) -> Result<(Mlp, FitInfo)> {
        self.fit_with_losses(x, y, seed).map(|(m, info, _)| (m, info))
    }
}

/// A z-score: `(v − mean) · (1 / std)` with the population std, and std 1 for a constant column.
/// (Multiplying by the reciprocal, in f64, keeps prediction cheap; fit and predict share it.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Standardizer {
    /// Mean of the fitted values.
    pub mean: f64,
    /// Population standard deviation, or 1 if the values are all equal.
    pub std: f64,
    inv_std: f64,
}

impl Standardizer {
    /// The z-score with this mean and standard deviation (> 0).
    pub fn new(mean: f64, std: f64) -> Standardizer {
        Standardizer { mean, std, inv_std: 1.0 / std }
    }

    /// Fits on `values` (at least one).
    pub fn fit(values: impl Iterator<Item = f64> + Clone) -> Standardizer {
        let (mut n, mut sum, mut lo, mut hi) = (0usize, 0.0, f64::INFINITY, f64::NEG_INFINITY);
        for v in values.clone() {
            n += 1;
            sum += v;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if lo == hi {
            // Exactly constant: every z-score is exactly 0 (the sum above may round the mean).
            return Standardizer::new(lo, 1.0);
        }
        let mean = sum / n as f64;
        let var = values.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
        let std = var.sqrt();
        Standardizer::new(mean, if std > 0.0 { std } else { 1.0 })
    }

    /// The z-score of `v`, as the network sees it.
    #[inline]
    pub fn apply(&self, v: f64) -> f32 {
        ((v - self.mean) * self.inv_std) as f32
    }

    /// The raw value of the standardized `z`.
    #[inline]
    pub fn invert(&self, z: f32) -> f64 {
        z as f64 * self.std + self.mean
    }
}

/// Rows before the validation tail, as Keras computes it: `int(n · (1 − validation_split))`.
fn split_point(n: usize, validation_fraction: f64) -> usize {
    (n as f64 * (1.0 - validation_fraction)).floor() as usize
}

/// Glorot-uniform weights (each in ±√(6 / (fan_in + fan_out)), drawn layer by layer in parameter
/// order from the stream `(seed, "mlp/init")`) and zero biases.
pub fn glorot_init(shape: &Shape, seed: u64) -> Vec<f32> {
    let mut rng = stream(seed, crate::rng::purpose::MLP_INIT, &[]);
    let mut p = vec![0.0; shape.n_params()];
    let w = shape.widths();
    for l in 0..shape.n_layers() {
        let limit = (6.0 / (w[l] + w[l + 1]) as f64).sqrt();
        for v in &mut p[shape.weights_range(l)] {
            *v = uniform(&mut rng, -limit, limit) as f32;
        }
    }
    p
}

/// The MSE of the network `params` on the rows `x` (row-major, `shape.n_inputs()` standardized
/// values per row) against `y`, and its gradient with respect to `params` written to `grad`:
/// exactly what one training batch of these rows computes (for checking against finite
/// differences).
pub fn loss_and_gradient(shape: &Shape, params: &[f32], x: &[f32], y: &[f32], grad: &mut [f32]) -> f64 {
    loss_and_gradient_on(cpu::mlp(), shape, params, x, y, grad)
}

fn loss_and_gradient_on(isa: Isa, shape: &Shape, params: &[f32], x: &[f32], y: &[f32], grad: &mut [f32]) -> f64 {
    let n_in = shape.n_inputs();
    assert!(x.len() == y.len() * n_in && params.len() == shape.n_params() && grad.len() == params.len());
    assert!(!y.is_empty() && y.len() <= u32::MAX as usize);
    let set = TrainSet::new(y.len(), n_in, |r, k| if k < n_in { x[r * n_in + k] } else { y[r] });
    let idx: Vec<u32> = (0..y.len() as u32).collect();
    let mut work = Work::new(shape);
    let sse = net::gradient(isa, shape, params, &set, &idx, &mut work);
    grad.copy_from_slice(work.grad());
    sse / y.len() as f64
}

/// Which kernel build fits and predictions use on this CPU: `avx512`, `avx2` or `portable` (the
/// best it has, capped by the environment variable `BFQI_ISA`; see `learn/cpu.rs`).
pub fn kernel_isa() -> &'static str {
    cpu::mlp().name()
}

/// The kernel levels this CPU runs the MLP at, best first (whatever `BFQI_ISA` caps).
pub(crate) fn kernel_levels() -> Vec<Isa> {
    Isa::ALL.into_iter().filter(|i| i.runs_mlp()).collect()
}

/// [`fma_peak_gflops`] on the build for `isa` (one this CPU runs).
pub(crate) fn fma_peak_gflops_on(isa: Isa, seconds: f64) -> f64 {
    peak::fma_peak_gflops(isa, seconds)
}

/// This core's FP32 peak in GFLOP/s on the kernels' build (independent FMA chains; an FMA is 2
/// FLOPs per lane), the best of short runs over about `seconds`.
pub fn fma_peak_gflops(seconds: f64) -> f64 {
    peak::fma_peak_gflops(cpu::mlp(), seconds)
}

/// The arithmetic of one training epoch of a network, as the kernels execute it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EpochWork {
    /// 2 per multiply-add of the forward pass (every row, training and validation) and of the
    /// backward pass (training rows: the weight gradients of every layer and the deltas of every
    /// layer but the input's).
    pub matmul_flops: f64,
    /// The activations, per hidden unit and row (forward on every row, derivative on training
    /// rows), counted as the operations our kernels run with an FMA as 2 FLOPs: sigmoid 40 + 3,
    /// tanh 36 + 3, ReLU 1 + 1.
    pub activation_flops: f64,
    /// The same activations as vector-lane operations (an FMA as 1): sigmoid 24 + 3, tanh 21 + 3,
    /// ReLU 1 + 1. With the multiply-adds, what bounds an epoch at two vector operations per cycle.
    pub activation_ops: f64,
}

impl EpochWork {
    /// The work of an epoch of `shape` over `train_rows` + `val_rows` rows.
    pub fn new(shape: &Shape, train_rows: usize, val_rows: usize) -> EpochWork {
        let w = shape.widths();
        let forward: usize = w.windows(2).map(|p| p[0] * p[1]).sum();
        let deltas: usize = w.windows(2).skip(1).map(|p| p[0] * p[1]).sum();
        let (t, v) = (train_rows as f64, val_rows as f64);
        let units = w[1..w.len() - 1].iter().sum::<usize>() as f64;
        let ((ff, bf), (fo, bo)) = match shape.activation() {
            Activation::Sigmoid => ((40.0, 3.0), (24.0, 3.0)),
            Activation::Tanh => ((36.0, 3.0), (21.0, 3.0)),
            Activation::Relu => ((1.0, 1.0), (1.0, 1.0)),
        };
        EpochWork {
            matmul_flops: 2.0 * (forward as f64 * (t + v) + (forward + deltas) as f64 * t),
            activation_flops: units * (ff * (t + v) + bf * t),
            activation_ops: units * (fo * (t + v) + bo * t),
        }
    }

    /// All FLOPs.
    pub fn flops(&self) -> f64 {
        self.matmul_flops + self.activation_flops
    }

    /// Seconds the epoch needs at least on a core whose FMA peak is `peak_gflops`: every
    /// multiply-add and activation operation takes one of the core's vector-lane slots, of which
    /// it has peak / 2 per second.
    pub fn bound_seconds(&self, peak_gflops: f64) -> f64 {
        (self.matmul_flops / 2.0 + self.activation_ops) / (peak_gflops * 1e9 / 2.0)
    }
}

/// Rows a fit of `n` rows trains on, and validates on (the last `validation_fraction`).
pub fn split_rows(n: usize, validation_fraction: f64) -> (usize, usize) {
    let s = split_point(n, validation_fraction);
    (s, n - s)
}

/// Blocks of 16 units that [`Mlp::predict_row`] evaluates on the stack (layers up to 64 wide).
const STACK_BLOCKS: usize = 4;

/// A fitted MLP: the network and the standardization it was trained with.
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    shape: Shape,
    params: Vec<f32>,
    x_scale: Vec<Standardizer>,
    y_scale: Standardizer,
    row: RowNet,
}

impl Mlp {
    /// The network's shape.
    pub fn shape(&self) -> &Shape {
        &self.shape
    }

    /// The flat parameter vector (layout in [`Shape`]).
    pub fn params(&self) -> &[f32] {
        &self.params
    }

    /// Layer `l`'s weights, `widths[l+1] × widths[l]` row-major.
    pub fn weights(&self, l: usize) -> &[f32] {
        &self.params[self.shape.weights_range(l)]
    }

    /// Layer `l`'s biases.
    pub fn biases(&self, l: usize) -> &[f32] {
        &self.params[self.shape.bias_range(l)]
    }

    /// The standardization of each input.
    pub fn input_scaling(&self) -> &[Standardizer] {
        &self.x_scale
    }

    /// The standardization of the target.
    pub fn target_scaling(&self) -> Standardizer {
        self.y_scale
    }

    fn eval_row(&self, isa: Isa, row: &[f64], a: &mut [V], b: &mut [V]) -> f64 {
        for (i, (&v, s)) in row.iter().zip(&self.x_scale).enumerate() {
            a[i / LANES].0[i % LANES] = s.apply(v);
        }
        self.y_scale.invert(net::predict_one(isa, &self.row, a, b))
    }

    fn predict_row_on(&self, isa: Isa, row: &[f64]) -> f64 {
        assert_eq!(row.len(), self.n_inputs(), "row length");
        if self.row.blocks() <= STACK_BLOCKS {
            let (mut a, mut b) = ([V::ZERO; STACK_BLOCKS], [V::ZERO; STACK_BLOCKS]);
            self.eval_row(isa, row, &mut a, &mut b)
        } else {
            let (mut a, mut b) = (vec![V::ZERO; self.row.blocks()], vec![V::ZERO; self.row.blocks()]);
            self.eval_row(isa, row, &mut a, &mut b)
        }
    }

    fn predict_into_on(&self, isa: Isa, x: Rows<'_>, out: &mut [f64]) {
        assert_eq!(x.n_cols(), self.n_inputs(), "columns");
        assert_eq!(out.len(), x.n_rows(), "output length");
        let mut work = Work::new(&self.shape);
        let mut z = vec![0f32; out.len()];
        net::predict(isa, &self.shape, &self.params, x.data(), &self.x_scale, &mut work, &mut z);
        for (o, &v) in out.iter_mut().zip(&z) {
            *o = self.y_scale.invert(v);
        }
    }
}

/// A network's storage as model files keep it (see [`crate::model`]): the shape, the flat
/// parameters and the standardizations. Loading it back gives bit-identical predictions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NetParts {
    /// Hidden layer widths.
    pub hidden: Vec<u32>,
    /// Number of inputs.
    pub n_inputs: u32,
    /// Hidden activation.
    pub activation: Activation,
    /// The flat parameter vector (layout in [`Shape`]).
    pub params: Vec<f32>,
    /// Mean and standard deviation of each input.
    pub x_scale: Vec<(f64, f64)>,
    /// Mean and standard deviation of the target.
    pub y_scale: (f64, f64),
}

impl Mlp {
    /// The network's storage.
    pub fn to_parts(&self) -> NetParts {
        let w = self.shape.widths();
        NetParts {
            hidden: w[1..w.len() - 1].iter().map(|&h| h as u32).collect(),
            n_inputs: w[0] as u32,
            activation: self.shape.activation(),
            params: self.params.clone(),
            x_scale: self.x_scale.iter().map(|s| (s.mean, s.std)).collect(),
            y_scale: (self.y_scale.mean, self.y_scale.std),
        }
    }

    /// Rebuilds a network from its storage; sizes must agree and scales be finite and positive.
    pub fn from_parts(p: NetParts) -> Result<Mlp> {
        let ok_scale = |(m, s): (f64, f64)| m.is_finite() && s.is_finite() && s > 0.0;
        let widths_ok =
            p.n_inputs >= 1 && p.hidden.iter().all(|&h| (1..=1 << 16).contains(&h)) && p.n_inputs <= 1 << 16;
        if !widths_ok || p.x_scale.len() != p.n_inputs as usize {
            return Err(Error::Data(format!(
                "network of {} inputs and hidden {:?} is malformed",
                p.n_inputs, p.hidden
            )));
        }
        let hidden: Vec<usize> = p.hidden.iter().map(|&h| h as usize).collect();
        let shape = Shape::new(p.n_inputs as usize, &hidden, p.activation);
        if p.params.len() != shape.n_params() {
            return Err(Error::Data(format!("{} parameters where the shape has {}", p.params.len(), shape.n_params())));
        }
        if !p.x_scale.iter().all(|&s| ok_scale(s)) || !ok_scale(p.y_scale) {
            return Err(Error::Data("a standardization is not finite and positive".into()));
        }
        let x_scale = p.x_scale.iter().map(|&(m, s)| Standardizer::new(m, s)).collect();
        let y_scale = Standardizer::new(p.y_scale.0, p.y_scale.1);
        let row = RowNet::new(&shape, &p.params);
        Ok(Mlp { shape, params: p.params, x_scale, y_scale, row })
    }
}

impl Regressor for Mlp {
    fn n_inputs(&self) -> usize {
        self.shape.n_inputs()
    }

    fn predict_row(&self, row: &[f64]) -> f64 {
        self.predict_row_on(cpu::mlp(), row)
    }

    fn predict_into(&self, x: Rows<'_>, out: &mut [f64]) {
        self.predict_into_on(cpu::mlp(), x, out)
    }
}
