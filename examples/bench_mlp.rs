//! Times the MLP on the bicycle data (1000 random episodes, rows [state, action], targets reward),
//! the setting of `/work/shared/bench/keras_mlp.py`.
//!
//!     cargo run --release --example bench_mlp -- [hidden=10,10] [activation=sigmoid] [epochs=30]
//!
//! `only=E` times E epochs alone and `predict=R` R prediction passes alone (for profiling).
//!
//! Times are this thread's CPU time (wall time off Linux). Epoch time is the difference between a fit of 1 + E epochs and one of 1 epoch (early stopping
//! off), divided by E, best of 3; GFLOP/s counts 2·in·out per layer and row forward, three times
//! that for a training row (forward + backward), once for a validation row.

use bfqi_ga::learn::mlp::{Activation, MlpParams, kernel_isa};
use bfqi_ga::learn::{Learner, Regressor, Rows};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |key: &str, default: &'static str| -> String {
        let prefix = format!("{key}=");
        args.iter().find_map(|a| a.strip_prefix(&prefix)).unwrap_or(default).to_string()
    };
    let hidden: Vec<usize> = arg("hidden", "10,10").split(',').map(|w| w.parse().unwrap()).collect();
    let activation = match arg("activation", "sigmoid").as_str() {
        "tanh" => Activation::Tanh,
        "relu" => Activation::Relu,
        _ => Activation::Sigmoid,
    };
    let epochs: usize = arg("epochs", "30").parse().unwrap();
    // `only=E` fits E epochs once and exits: for `perf stat`.
    let only: usize = arg("only", "0").parse().unwrap();

    let cfg = bfqi_ga::env::EnvConfig::by_name("bicycle").unwrap();
    let data = bfqi_ga::dataset::collect(cfg.env(), 1000, 1).unwrap();
    let d = data.obs_dim;
    let mut x = Vec::with_capacity(data.len() * (d + 1));
    for i in 0..data.len() {
        x.extend_from_slice(&data.state[i * d..(i + 1) * d]);
        x.push(data.action[i]);
    }
    let rows = Rows::new(&x, d + 1).unwrap();
    let y = &data.reward;
    let base = MlpParams { hidden: hidden.clone(), activation, ..Default::default() };

    let n = rows.n_rows();
    let split = (n as f64 * (1.0 - base.validation_fraction)).floor() as usize;
    let mut widths = vec![d + 1];
    widths.extend(&hidden);
    widths.push(1);
    let macs: usize = widths.windows(2).map(|w| w[0] * w[1]).sum();
    let flop = (2 * macs) as f64 * (3 * split + (n - split)) as f64;

    let time_fit = |max_epochs: usize| {
        let p = MlpParams { max_epochs, delta_min: 0.0, patience: usize::MAX, ..base.clone() };
        let t = Clock::start();
        let (_, info) = p.fit(rows, y, 3).unwrap();
        assert_eq!(info.epochs, max_epochs);
        t.secs()
    };
    if !arg("predict", "").is_empty() {
        let (model, _) = MlpParams { max_epochs: 20, ..base.clone() }.fit(rows, y, 3).unwrap();
        let mut out = vec![0.0; n];
        let passes: usize = arg("predict", "").parse().unwrap();
        let t = Clock::start();
        for _ in 0..passes {
            model.predict_into(rows, &mut out);
        }
        let batch_ns = t.secs() * 1e9 / (n * passes) as f64;
        let t = Clock::start();
        let mut s = 0.0;
        for _ in 0..passes {
            for i in 0..n {
                s += model.predict_row(rows.row(i));
            }
        }
        let row_ns = t.secs() * 1e9 / (n * passes) as f64;
        assert!(s.is_finite());
        println!("predict_into: {batch_ns:.1} ns/row, predict_row: {row_ns:.1} ns/row");
        return;
    }
    if only > 0 {
        println!("{:.3} ms per epoch", time_fit(only) * 1e3 / only as f64);
        return;
    }
    let mut per_epoch = f64::INFINITY;
    for _ in 0..3 {
        per_epoch = per_epoch.min((time_fit(1 + epochs) - time_fit(1)) / epochs as f64);
    }

    let t = Clock::start();
    let (model, info) = base.fit(rows, y, 3).unwrap();
    let fit_s = t.secs();
    let passes = 5;

    // Prediction: best of 5 passes over all rows, in batch and one row at a time.
    let mut out = vec![0.0; n];
    let (mut batch_ns, mut row_ns) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..passes {
        let t = Clock::start();
        model.predict_into(rows, &mut out);
        batch_ns = batch_ns.min(t.secs() * 1e9 / n as f64);
        let t = Clock::start();
        let mut s = 0.0;
        for i in 0..n {
            s += model.predict_row(rows.row(i));
        }
        row_ns = row_ns.min(t.secs() * 1e9 / n as f64);
        assert!(s.is_finite());
    }

    println!("rows {n} (train {split}), inputs {}, hidden {hidden:?} {activation:?}, kernels {}", d + 1, kernel_isa());
    println!("epoch: {:.3} ms, {:.1} MFLOP, {:.1} GFLOP/s", per_epoch * 1e3, flop / 1e6, flop / per_epoch / 1e9);
    println!(
        "early-stopped fit (delta_min {}, patience {}): {:.3} s, {} epochs, {:?}",
        base.delta_min, base.patience, fit_s, info.epochs, info.stop
    );
    println!("predict_into: {batch_ns:.1} ns/row, predict_row: {row_ns:.1} ns/row");
}

/// On-CPU time of this thread (Linux `CLOCK_THREAD_CPUTIME_ID`), so other work on a shared
/// machine does not count; wall time elsewhere.
struct Clock {
    wall: Instant,
    cpu: Option<f64>,
}

#[cfg(target_os = "linux")]
fn thread_cpu_secs() -> Option<f64> {
    #[repr(C)]
    struct Timespec {
        sec: i64,
        nsec: i64,
    }
    unsafe extern "C" {
        fn clock_gettime(clock: i32, ts: *mut Timespec) -> i32;
    }
    const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
    let mut ts = Timespec { sec: 0, nsec: 0 };
    // SAFETY: a valid out-pointer to a C `struct timespec` (two 64-bit fields on 64-bit Linux).
    let ok = unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0;
    ok.then_some(ts.sec as f64 + ts.nsec as f64 * 1e-9)
}

#[cfg(not(target_os = "linux"))]
fn thread_cpu_secs() -> Option<f64> {
    None
}

impl Clock {
    fn start() -> Clock {
        Clock { wall: Instant::now(), cpu: thread_cpu_secs() }
    }

    fn secs(&self) -> f64 {
        match (self.cpu, thread_cpu_secs()) {
            (Some(a), Some(b)) => b - a,
            _ => self.wall.elapsed().as_secs_f64(),
        }
    }
}
