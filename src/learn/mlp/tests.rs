use super::kernels::{exp_neg, recip, sigmoid, tanh};
use super::lanes::{LANES, V};
use super::*;
use crate::rng::below;
use rand::RngCore;
use shuffle::{Draws, U64s, below_fast};

/// `n` rows of `n_in` inputs uniform in [−2, 2] and targets `f(row)`.
fn data(n: usize, n_in: usize, seed: u64, f: impl Fn(&[f64]) -> f64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = stream(seed, "test/data", &[]);
    let x: Vec<f64> = (0..n * n_in).map(|_| uniform(&mut rng, -2.0, 2.0)).collect();
    let y = x.chunks(n_in).map(f).collect();
    (x, y)
}

fn smooth(r: &[f64]) -> f64 {
    r.iter().enumerate().map(|(i, v)| (v * (i as f64 + 1.0)).sin()).sum::<f64>() + 3.0
}

fn quick(hidden: Vec<usize>, activation: Activation) -> MlpParams {
    MlpParams {
        hidden,
        activation,
        batch_size: 50,
        max_epochs: 8,
        delta_min: 0.0,
        patience: 1000,
        ..Default::default()
    }
}

/// The MSE of the network in f64 with libm's functions: an independent reference.
fn reference_loss(shape: &Shape, p: &[f64], x: &[f32], y: &[f32]) -> f64 {
    let w = shape.widths();
    let n_in = w[0];
    let mut total = 0.0;
    for (r, &t) in y.iter().enumerate() {
        let mut a: Vec<f64> = x[r * n_in..(r + 1) * n_in].iter().map(|&v| v as f64).collect();
        for l in 0..shape.n_layers() {
            let (wr, br, din) = (shape.weights_range(l), shape.bias_range(l), w[l]);
            let z: Vec<f64> = (0..w[l + 1])
                .map(|j| p[br.start + j] + (0..din).map(|i| p[wr.start + j * din + i] * a[i]).sum::<f64>())
                .collect();
            a = if l + 1 == shape.n_layers() {
                z
            } else {
                z.iter()
                    .map(|&z| match shape.activation() {
                        Activation::Sigmoid => 1.0 / (1.0 + (-z).exp()),
                        Activation::Tanh => z.tanh(),
                        Activation::Relu => z.max(0.0),
                    })
                    .collect()
            };
        }
        total += (a[0] - t as f64).powi(2);
    }
    total / y.len() as f64
}

#[test]
fn analytic_gradient_matches_central_differences() {
    let cases = [(6, vec![10, 10], 37), (3, vec![5], 300), (2, vec![4, 3, 2], 130), (17, vec![6], 20)];
    for act in [Activation::Sigmoid, Activation::Tanh, Activation::Relu] {
        for (n_in, hidden, n) in cases.clone() {
            let shape = Shape::new(n_in, &hidden, act);
            let mut rng = stream(5, "test/grad", &[n as u64]);
            // Nonzero biases and a scale that keeps sigmoids off their flat tails.
            let params: Vec<f32> =
                glorot_init(&shape, 11).iter().map(|&p| p + uniform(&mut rng, -0.2, 0.2) as f32).collect();
            let x: Vec<f32> = (0..n * n_in).map(|_| uniform(&mut rng, -2.0, 2.0) as f32).collect();
            let y: Vec<f32> = (0..n).map(|_| uniform(&mut rng, -1.0, 1.0) as f32).collect();
            let mut g = vec![0.0; params.len()];
            let loss = loss_and_gradient(&shape, &params, &x, &y, &mut g);
            let p64: Vec<f64> = params.iter().map(|&v| v as f64).collect();
            let exact = reference_loss(&shape, &p64, &x, &y);
            assert!((loss - exact).abs() < 1e-5 * (1.0 + exact), "{act:?} {hidden:?}: loss {loss} vs {exact}");
            let scale = g.iter().fold(0f32, |m, v| m.max(v.abs())) as f64;
            assert!(scale > 1e-3);
            let h = 1e-6;
            let mut p = p64.clone();
            for i in 0..params.len() {
                p[i] = p64[i] + h;
                let up = reference_loss(&shape, &p, &x, &y);
                p[i] = p64[i] - h;
                let down = reference_loss(&shape, &p, &x, &y);
                p[i] = p64[i];
                let fd = (up - down) / (2.0 * h);
                assert!(
                    (fd - g[i] as f64).abs() <= 1e-4 * scale + 1e-6,
                    "{act:?} {hidden:?} n={n}: parameter {i}: analytic {} vs numeric {fd}",
                    g[i]
                );
            }
        }
    }
}

#[test]
fn rmsprop_step_matches_hand_computation() {
    let mut opt = RmsProp::new(2, 0.01, 0.9, 1e-8);
    let mut p = [1.0f32, -2.0];
    opt.step(&mut p, &[0.5, -0.25]);
    // Keras holds ρ as float32, so 1 − ρ = 1 − 0.9f32 = 0.100000024.
    let (rho, omr) = (0.9f32 as f64, 1.0 - 0.9f32 as f64);
    let a = [omr * 0.25, omr * 0.0625];
    // w −= lr·g/(√a + ε): the first step moves each weight by ≈ lr/√0.1 against its gradient.
    let w = [1.0 - 0.01 * 0.5 / (a[0].sqrt() + 1e-8), -2.0 + 0.01 * 0.25 / (a[1].sqrt() + 1e-8)];
    let close = |x: f32, y: f64| (x as f64 - y).abs() <= 1e-6 * y.abs().max(1e-3);
    assert!(close(opt.accumulators()[0], a[0]) && close(opt.accumulators()[1], a[1]));
    assert!(close(p[0], w[0]) && close(p[1], w[1]), "{p:?} vs {w:?}");
    assert!((p[0] as f64 - (1.0 - 0.01 / 0.1f64.sqrt())).abs() < 1e-6);
    // Second step: the accumulator decays, a zero gradient leaves its weight alone.
    opt.step(&mut p, &[0.5, 0.0]);
    let a = [rho * a[0] + omr * 0.25, rho * a[1]];
    let w = [w[0] - 0.01 * 0.5 / (a[0].sqrt() + 1e-8), w[1]];
    assert!(close(opt.accumulators()[0], a[0]) && close(opt.accumulators()[1], a[1]));
    assert!(close(p[0], w[0]) && close(p[1], w[1]), "{p:?} vs {w:?}");
}

/// The 1-based epoch at which the rule stops, and the epochs that improved.
fn run_rule(delta: f64, patience: usize, losses: &[f64]) -> (Option<usize>, Vec<usize>) {
    let mut rule = EarlyStopping::new(delta, patience);
    let mut improved = Vec::new();
    for (e, &l) in losses.iter().enumerate() {
        let best = rule.best();
        let stop = rule.update(l);
        if rule.best() != best {
            improved.push(e + 1);
        }
        if stop {
            return (Some(e + 1), improved);
        }
    }
    (None, improved)
}

#[test]
fn early_stopping_follows_keras_on_scripted_losses() {
    // Improvements at 1 and 4 (0.85 < 1.0 − 0.1); then three epochs without → stop at 7.
    let l = [1.0, 0.95, 0.92, 0.85, 0.80, 0.78, 0.76, 0.1];
    assert_eq!(run_rule(0.1, 2, &l), (Some(7), vec![1, 4]));
    // Patience 0: the first epoch without improvement stops (0.9 is not < 0.9 − 0).
    assert_eq!(run_rule(0.0, 0, &[1.0, 0.9, 0.9, 0.1]), (Some(3), vec![1, 2]));
    assert_eq!(run_rule(0.0, 0, &[1.0, 1.1]), (Some(2), vec![1]));
    // Compared with the best loss, not the previous one: 0.84 < 1.0 − 0.1 improves.
    assert_eq!(run_rule(0.1, 5, &[1.0, 0.92, 0.84]), (None, vec![1, 3]));
    // Patience 1, δ 0.05: 0.94 < 0.95 improves, 0.93 does not, 0.5 does, then two misses.
    let l = [1.0, 0.97, 0.94, 0.93, 0.5, 0.6, 0.7, 0.0];
    assert_eq!(run_rule(0.05, 1, &l), (Some(7), vec![1, 3, 5]));
    // Steady improvement never stops; a NaN counts as no improvement.
    assert_eq!(run_rule(0.0, 0, &[3.0, 2.0, 1.0]), (None, vec![1, 2, 3]));
    assert_eq!(run_rule(0.0, 1, &[1.0, f64::NAN, f64::NAN]), (Some(3), vec![1]));
}

#[test]
fn learns_sine() {
    let mut rng = stream(3, "test/sine", &[]);
    let x: Vec<f64> = (0..2000).map(|_| uniform(&mut rng, -std::f64::consts::PI, std::f64::consts::PI)).collect();
    let y: Vec<f64> = x.iter().map(|v| v.sin()).collect();
    let rows = Rows::new(&x, 1).unwrap();
    for (hidden, activation) in [(vec![20], Activation::Tanh), (vec![10, 10], Activation::Sigmoid)] {
        let p = MlpParams {
            hidden: hidden.clone(),
            activation,
            batch_size: 32,
            max_epochs: 400,
            delta_min: 0.0,
            patience: 20,
            learning_rate: 3e-3,
            ..Default::default()
        };
        let (model, info) = p.fit(rows, &y, 1).unwrap();
        let mut pred = vec![0.0; 2000];
        model.predict_into(rows, &mut pred);
        let mse = pred.iter().zip(&y).map(|(p, t)| (p - t) * (p - t)).sum::<f64>() / 2000.0;
        assert!(mse < 0.01, "{hidden:?} {activation:?}: MSE {mse} after {info:?}");
    }
}

#[test]
fn same_seed_same_model_other_seed_other_model() {
    let (x, y) = data(700, 4, 1, smooth);
    let rows = Rows::new(&x, 4).unwrap();
    let p = quick(vec![10, 10], Activation::Sigmoid);
    let (a, ia, la) = p.fit_with_losses(rows, &y, 9).unwrap();
    let (b, ib, lb) = p.fit_with_losses(rows, &y, 9).unwrap();
    assert_eq!(a, b);
    assert_eq!((ia, la), (ib, lb));
    let (c, _) = p.fit(rows, &y, 10).unwrap();
    assert_ne!(a.params(), c.params());
    // Both streams differ: the initial weights and the shuffles.
    let shape = a.shape();
    assert_ne!(glorot_init(shape, 9), glorot_init(shape, 10));
    // Inside a rayon pool of any size the fit is the same (it runs on the calling thread).
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let (d, _) = pool.install(|| p.fit(rows, &y, 9)).unwrap();
        assert_eq!(a, d);
    }
}

#[test]
fn every_kernel_build_gives_the_same_bits() {
    let isas: Vec<Isa> = Isa::ALL.into_iter().filter(|i| i.runs_mlp()).collect();
    assert!(isas.contains(&Isa::Portable));
    let cases = [
        (6, vec![10, 10], Activation::Sigmoid, 450, 77),
        (2, vec![5], Activation::Tanh, 301, 2000),
        (16, vec![17, 3], Activation::Relu, 260, 33),
        (1, vec![3, 2], Activation::Sigmoid, 150, 16),
    ];
    for (n_in, hidden, act, n, batch) in cases {
        let (x, y) = data(n, n_in, 2, smooth);
        let rows = Rows::new(&x, n_in).unwrap();
        let p = MlpParams { batch_size: batch, max_epochs: 5, ..quick(hidden.clone(), act) };
        let reference = p.fit_on(Isa::Portable, rows, &y, 4).unwrap();
        let mut pred_ref = vec![0.0; n];
        reference.0.predict_into_on(Isa::Portable, rows, &mut pred_ref);
        for &isa in &isas {
            let fit = p.fit_on(isa, rows, &y, 4).unwrap();
            assert_eq!(fit, reference, "{isa:?} {hidden:?}");
            let mut pred = vec![0.0; n];
            fit.0.predict_into_on(isa, rows, &mut pred);
            assert_eq!(pred, pred_ref, "{isa:?}");
            for (i, &p) in pred.iter().enumerate() {
                assert_eq!(fit.0.predict_row_on(isa, rows.row(i)).to_bits(), p.to_bits(), "{isa:?} row {i}");
            }
        }
    }
    // Activations and their derivatives on awkward values, lane by lane.
    let mut vals = vec![0.0f32, -0.0, 1e-30, -1e-30, 1e-8, 0.5, -0.5, 15.9, -15.9, 86.9, -86.9, 87.5, -87.5];
    vals.extend([100.0, -100.0, 1e30, -1e30, f32::MAX, f32::MIN, f32::INFINITY, f32::NEG_INFINITY]);
    let mut rng = stream(1, "test/values", &[]);
    vals.extend((0..3000).map(|_| uniform(&mut rng, -20.0, 20.0) as f32));
    vals.resize(vals.len().next_multiple_of(LANES), 1.0);
    let buf: Vec<V> = vals.chunks(LANES).map(|c| V(c.try_into().unwrap())).collect();
    let deltas: Vec<V> = buf.iter().map(|v| V(v.0.map(|x| x * 0.25 + 1.0))).collect();
    for act in [Activation::Sigmoid, Activation::Tanh, Activation::Relu] {
        let (mut a0, mut d0) = (buf.clone(), deltas.clone());
        net::activate_all(Isa::Portable, act, &mut a0, &mut d0);
        for &isa in &isas {
            let (mut a, mut d) = (buf.clone(), deltas.clone());
            net::activate_all(isa, act, &mut a, &mut d);
            let bits = |v: &[V]| v.iter().flat_map(|x| x.0.map(f32::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&a), bits(&a0), "{isa:?} {act:?}");
            assert_eq!(bits(&d), bits(&d0), "{isa:?} {act:?}");
        }
        // And the scalar build agrees with the lanes.
        for (x, a) in vals.iter().zip(a0.iter().flat_map(|v| v.0)) {
            let s = match act {
                Activation::Sigmoid => sigmoid(*x),
                Activation::Tanh => tanh(*x),
                Activation::Relu => x.max(0.0),
            };
            assert_eq!(s.to_bits(), a.to_bits(), "{act:?} at {x}");
        }
    }
}

#[test]
fn transcendental_approximations_are_accurate() {
    let mut worst = [0f64; 4];
    let mut x = -87.0f64;
    while x <= 87.0 {
        let xf = x as f32;
        let xd = xf as f64;
        let rel = |a: f32, b: f64| ((a as f64 - b) / b).abs();
        worst[0] = worst[0].max(rel(exp_neg(xf), (-xd).exp()));
        worst[1] = worst[1].max(rel(sigmoid(xf), 1.0 / (1.0 + (-xd).exp())));
        if xf != 0.0 {
            worst[2] = worst[2].max(rel(tanh(xf), xd.tanh()));
        }
        x += 0.00731;
    }
    let mut d = 1e-3f64;
    while d < 1e37 {
        let df = d as f32;
        worst[3] = worst[3].max(((recip(df) as f64) * df as f64 - 1.0).abs());
        d *= 1.0137;
    }
    assert!(worst[0] < 3e-7 && worst[1] < 4e-7 && worst[2] < 5e-7 && worst[3] < 3e-7, "{worst:?}");
    assert_eq!(sigmoid(0.0), 0.5);
    assert_eq!(tanh(0.0), 0.0);
    assert!(sigmoid(-200.0) > 0.0 && sigmoid(200.0) == 1.0);
    // tanh saturates within 3·10⁻⁷ of ±1, never beyond.
    assert!((0.9999997..=1.0).contains(&tanh(50.0)) && tanh(-50.0) == -tanh(50.0));
}

#[test]
fn invalid_settings_name_their_field() {
    let bad = |p: MlpParams, field: &str| {
        let e = p.check().unwrap_err().to_string();
        assert!(e.contains(&format!("invalid {field} =")), "{e}");
        let e = p.fit(Rows::new(&[0.0; 40], 2).unwrap(), &[0.0; 20], 1).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    };
    let d = MlpParams::default;
    bad(MlpParams { hidden: vec![], ..d() }, "hidden");
    bad(MlpParams { hidden: vec![10, 0], ..d() }, "hidden");
    bad(MlpParams { delta_min: -0.1, ..d() }, "delta_min");
    bad(MlpParams { delta_min: f64::NAN, ..d() }, "delta_min");
    bad(MlpParams { delta_min: f64::INFINITY, ..d() }, "delta_min");
    bad(MlpParams { learning_rate: 0.0, ..d() }, "learning_rate");
    bad(MlpParams { rho: 1.0, ..d() }, "rho");
    bad(MlpParams { rho: -0.1, ..d() }, "rho");
    bad(MlpParams { epsilon: 0.0, ..d() }, "epsilon");
    bad(MlpParams { batch_size: 0, ..d() }, "batch_size");
    bad(MlpParams { max_epochs: 0, ..d() }, "max_epochs");
    bad(MlpParams { validation_fraction: 0.0, ..d() }, "validation_fraction");
    bad(MlpParams { validation_fraction: 1.0, ..d() }, "validation_fraction");
    bad(MlpParams { validation_fraction: 0.999, ..d() }, "validation_fraction");
    assert!(d().check().is_ok());
    let e = MlpParams { delta_min: -1.0, ..d() }.check().unwrap_err().within("mlp").to_string();
    assert_eq!(e, "invalid mlp.delta_min = -1: must be finite and ≥ 0");

    // Data: NaN, too few rows for both parts.
    let p = quick(vec![3], Activation::Tanh);
    let e = p.fit(Rows::new(&[1.0, f64::NAN, 2.0, 3.0], 1).unwrap(), &[1.0; 4], 1).unwrap_err().to_string();
    assert!(e.contains("non-finite input NaN"), "{e}");
    let e = p.fit(Rows::new(&[1.0, 2.0], 1).unwrap(), &[1.0, f64::NAN], 1).unwrap_err().to_string();
    assert!(e.contains("non-finite target"), "{e}");
    let e = p.fit(Rows::new(&[1.0], 1).unwrap(), &[1.0], 1).unwrap_err().to_string();
    assert!(e.contains("both need ≥ 1"), "{e}");
    assert!(p.fit(Rows::new(&[1.0, 2.0], 1).unwrap(), &[1.0, 2.0], 1).is_ok());
}

#[test]
fn serde_names_and_defaults() {
    let p: MlpParams = serde_json::from_str(r#"{"hidden": [5], "activation": "relu", "patience": 3}"#).unwrap();
    assert_eq!(p, MlpParams { hidden: vec![5], activation: Activation::Relu, patience: 3, ..Default::default() });
    assert!(serde_json::from_str::<MlpParams>(r#"{"hiden": [5]}"#).is_err());
    let d = MlpParams::default();
    assert_eq!(
        (d.hidden.as_slice(), d.activation, d.batch_size, d.max_epochs),
        (&[10, 10][..], Activation::Sigmoid, 2000, 5000)
    );
    assert_eq!((d.learning_rate, d.rho, d.epsilon, d.validation_fraction), (1e-3, 0.9, 1e-8, 0.1));
    assert_eq!((d.delta_min, d.patience), (0.011, 75));
    assert_eq!(serde_json::to_string(&Activation::Tanh).unwrap(), r#""tanh""#);
}

#[test]
fn epochs_and_stop_reason_are_recorded() {
    let (x, y) = data(400, 3, 5, smooth);
    let rows = Rows::new(&x, 3).unwrap();
    let (_, info, losses) = quick(vec![8], Activation::Tanh).fit_with_losses(rows, &y, 1).unwrap();
    assert_eq!((info.epochs, info.stop), (8, StopReason::MaxEpochs));
    assert_eq!(losses.len(), 8);
    assert_eq!(
        (info.train_loss, info.val_loss),
        (Some(losses[7].train), Some(losses[7].val)),
        "the last epoch's losses"
    );
    assert!(losses[7].train < losses[0].train && losses[7].val < losses[0].val, "{losses:?}");
    // A huge δ: epoch 1 improves on +∞, the next `patience + 1` do not.
    let p = MlpParams { delta_min: 1e9, patience: 2, max_epochs: 100, ..quick(vec![8], Activation::Tanh) };
    let (_, info) = p.fit(rows, &y, 1).unwrap();
    assert_eq!((info.epochs, info.stop), (4, StopReason::EarlyStopping));
    // A learning rate that overflows the weights ends the fit as diverged, not in a panic.
    let p = MlpParams { learning_rate: 1e38, activation: Activation::Relu, ..quick(vec![8], Activation::Relu) };
    let (_, info) = p.fit(rows, &y, 1).unwrap();
    assert_eq!(info.stop, StopReason::NonFinite, "{info:?}");
}

#[test]
fn validation_is_the_last_rows_and_never_trains() {
    let n = 1000;
    let (x, y) = data(n, 2, 8, |r| (2.0 * r[0]).sin() + r[1] * r[1]);
    assert_eq!(split_point(n, 0.1), 900);
    assert_eq!((split_point(10, 0.1), split_point(25, 0.1), split_point(92058, 0.1)), (9, 22, 82852));
    // Reversing the tail's targets keeps every column's values (so the standardization), and the
    // training rows; only what validation sees changes.
    let mut y2 = y.clone();
    y2[900..].reverse();
    let rows = Rows::new(&x, 2).unwrap();
    let p = MlpParams { max_epochs: 12, ..quick(vec![16], Activation::Tanh) };
    let (a, _, la) = p.fit_with_losses(rows, &y, 3).unwrap();
    let (b, _, lb) = p.fit_with_losses(rows, &y2, 3).unwrap();
    assert_eq!(a.params(), b.params());
    assert!(la.iter().zip(&lb).all(|(a, b)| a.train == b.train && a.val != b.val));
    // Early stopping sees the difference: the scrambled tail stops improving at once.
    let p = MlpParams { max_epochs: 200, patience: 3, ..p };
    let (_, clean) = p.fit(rows, &y, 3).unwrap();
    let (_, scrambled) = p.fit(rows, &y2, 3).unwrap();
    assert_eq!(scrambled.stop, StopReason::EarlyStopping);
    assert!(scrambled.epochs < clean.epochs, "{scrambled:?} vs {clean:?}");
}

#[test]
fn predictions_are_raw_scale_and_row_equals_batch() {
    // Targets far from 0 with a large spread, a constant input column, and a wide layer that
    // takes `predict_row`'s heap path.
    let (x, y) = data(600, 3, 4, |r| 1000.0 + 50.0 * r[0] - 20.0 * r[1]);
    let x: Vec<f64> = x.chunks(3).flat_map(|r| [r[0], 7.5, r[1], r[2]]).collect();
    let rows = Rows::new(&x, 4).unwrap();
    for hidden in [vec![12], vec![70]] {
        let p = MlpParams { max_epochs: 150, batch_size: 32, ..quick(hidden, Activation::Tanh) };
        let (m, _) = p.fit(rows, &y, 2).unwrap();
        assert_eq!(m.input_scaling()[1], Standardizer::new(7.5, 1.0));
        let mut out = vec![0.0; 600];
        m.predict_into(rows, &mut out);
        let mse = out.iter().zip(&y).map(|(p, t)| (p - t) * (p - t)).sum::<f64>() / 600.0;
        assert!(mse < 25.0, "MSE {mse} on targets of std ~32");
        for (i, &o) in out.iter().enumerate() {
            assert_eq!(m.predict_row(rows.row(i)).to_bits(), o.to_bits());
        }
        assert_eq!(m.n_inputs(), 4);
    }
}

#[test]
fn shuffle_draws_are_the_crates() {
    for n in [1u64, 2, 3, 7, 1000, 82_852, (1 << 32) + 5, u64::MAX / 3 + 7, u64::MAX] {
        let (mut a, mut b) = (stream(1, "test/below", &[n]), stream(1, "test/below", &[n]));
        for _ in 0..20_000 {
            assert_eq!(below_fast(&mut a, n), below(&mut b, n));
        }
        assert_eq!(a.next_u64(), b.next_u64());
    }
}

#[test]
fn standardizer_is_population_z_score() {
    let s = Standardizer::fit([1.0, 2.0, 3.0, 4.0].into_iter());
    assert_eq!(s.mean, 2.5);
    assert!((s.std - 1.25f64.sqrt()).abs() < 1e-15);
    assert_eq!(s.apply(2.5), 0.0);
    let c = Standardizer::fit([0.1; 3].into_iter());
    assert_eq!((c, c.apply(0.1)), (Standardizer::new(0.1, 1.0), 0.0));
}

#[test]
fn shuffle_is_fisher_yates_with_the_crates_draws() {
    for n in [0usize, 1, 2, 33, 1000] {
        let mut perm = vec![7u32; n];
        let mut rng = stream(2, "test/shuffle", &[]);
        shuffle(&mut perm, &mut rng);
        let mut expect: Vec<u32> = (0..n as u32).collect();
        let mut rng2 = stream(2, "test/shuffle", &[]);
        for i in (1..n).rev() {
            expect.swap(i, below(&mut rng2, i as u64 + 1) as usize);
        }
        assert_eq!(perm, expect);
        let after = rng2.next_u64();
        assert_eq!(rng.next_u64(), after);
    }
}

#[test]
fn bulk_chacha_is_rand_chacha_word_for_word() {
    for (seed, skip) in [(1u64, 0usize), (2, 1), (3, 7), (4, 64), (5, 255), (6, 256), (7, 1001)] {
        let mut a = stream(seed, "test/chacha", &[]);
        let mut b = a.clone();
        for _ in 0..skip {
            a.next_u32();
            b.next_u32();
        }
        {
            let mut d = Draws::new(&mut a);
            for i in 0..5000 {
                assert_eq!(d.next(), b.next_u64(), "seed {seed}, skip {skip}, draw {i}");
            }
        }
        // Dropping the bulk generator leaves the crate's where the same draws would have.
        assert_eq!(a.get_word_pos(), b.get_word_pos());
        assert_eq!(a.next_u64(), b.next_u64());
    }
}
