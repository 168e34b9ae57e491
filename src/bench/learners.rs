//! `bench learners`: the Extra-Trees and the MLP alone, in the thesis's settings.

use super::{PythonReference, data, median, rows_input};
use crate::error::Result;
use crate::learn::extra_trees::ExtraTreesParams;
use crate::learn::mlp::{Activation, MlpParams};
use crate::learn::{Learner, Regressor, Rows};
use serde::Serialize;
use serde_json::{Value, json};
use std::time::Instant;

/// One Extra-Trees setting's figures.
#[derive(Debug, Serialize)]
struct EtFigures {
    setting: &'static str,
    rows: usize,
    features: usize,
    fit_s_median: f64,
    predict_rows_per_s: f64,
    single_row_predict_us: f64,
    reference: Option<Value>,
    fit_speedup: Option<f64>,
    single_row_speedup: Option<f64>,
}

fn bench_et(
    setting: &'static str,
    env: &str,
    episodes: usize,
    params: ExtraTreesParams,
    reference: Option<&PythonReference>,
) -> Result<EtFigures> {
    let (_, d) = data(env, episodes)?;
    let x = rows_input(&d);
    let cols = d.obs_dim + 1;
    let rows = Rows::new(&x, cols)?;
    let mut fits = Vec::new();
    let mut model = None;
    for r in 0..3 {
        let t = Instant::now();
        let (m, _) = params.fit(rows, &d.reward, r)?;
        fits.push(t.elapsed().as_secs_f64());
        model = Some(m);
    }
    let m = model.expect("three fits");
    let mut out = vec![0.0; d.len()];
    let t = Instant::now();
    m.predict_into(rows, &mut out);
    let predict = t.elapsed().as_secs_f64();
    let n_single = 2000.min(d.len());
    let t = Instant::now();
    let mut acc = 0.0;
    for i in 0..n_single {
        acc += m.predict_row(rows.row(i));
    }
    let single = t.elapsed().as_secs_f64() / n_single as f64;
    std::hint::black_box(acc);

    let reference = if let Some(reference) = reference {
        let csv = reference.file(&format!("{env}.csv"));
        crate::dataset::table::write(&d, &csv)?;
        let args = vec![
            csv.display().to_string(),
            "--trees".into(),
            params.n_trees.to_string(),
            "--depth".into(),
            params.max_depth.map_or("0".into(), |v| v.to_string()),
            "--min-split".into(),
            params.min_samples_split.to_string(),
            "--min-leaf".into(),
            params.min_samples_leaf.to_string(),
            "--jobs".into(),
            rayon::current_num_threads().to_string(),
        ];
        reference.run("sklearn_et.py", &args)
    } else {
        None
    };
    let fit_s_median = median(fits);
    let fit_speedup = reference.as_ref().and_then(|r| r["fit_s_median"].as_f64()).map(|s| s / fit_s_median);
    let single_row_speedup = reference.as_ref().and_then(|r| r["single_row_predict_s"].as_f64()).map(|s| s / single);
    Ok(EtFigures {
        setting,
        rows: d.len(),
        features: cols,
        fit_s_median,
        predict_rows_per_s: d.len() as f64 / predict,
        single_row_predict_us: single * 1e6,
        reference,
        fit_speedup,
        single_row_speedup,
    })
}

/// Benchmarks the learners; prints a table, or JSON with `json`.
pub fn learners(python: Option<&std::path::Path>, json: bool) -> Result<Value> {
    let reference = PythonReference::new(python)?;
    let reference = reference.as_ref();
    let threads = rayon::current_num_threads();
    if !json {
        println!("bench learners · {threads} thread(s)");
    }
    let bicycle = ExtraTreesParams { n_trees: 50, max_depth: Some(17), min_samples_split: 8, min_samples_leaf: 4 };
    let pendulum = ExtraTreesParams { n_trees: 30, max_depth: Some(13), min_samples_split: 4, min_samples_leaf: 2 };
    let mut et = Vec::new();
    for (name, env, episodes, p) in [
        ("bicycle (50 trees, depth 17)", "bicycle", 1000, bicycle),
        ("pendulum (30 trees, depth 13)", "pendulum", 2000, pendulum),
    ] {
        let f = bench_et(name, env, episodes, p, reference)?;
        if !json {
            println!(
                "  extra-trees {:<30} {:>7} rows  fit {:>7.3} s  predict {:>6.2} M rows/s  single row {:>6.2} µs{}",
                f.setting,
                f.rows,
                f.fit_s_median,
                f.predict_rows_per_s / 1e6,
                f.single_row_predict_us,
                match (f.fit_speedup, f.single_row_speedup) {
                    (Some(a), Some(b)) => format!("  | vs scikit-learn: fit {a:.1}×, single row {b:.0}×"),
                    _ => String::new(),
                }
            );
        }
        et.push(f);
    }

    // MLP: [10, 10] sigmoid on the bicycle data, batch 2000.
    let (_, d) = data("bicycle", 1000)?;
    let x = rows_input(&d);
    let cols = d.obs_dim + 1;
    let rows = Rows::new(&x, cols)?;
    let base = MlpParams { hidden: vec![10, 10], activation: Activation::Sigmoid, ..MlpParams::default() };
    let epochs = 40;
    let fixed = MlpParams { max_epochs: epochs, patience: usize::MAX / 2, delta_min: 0.0, ..base.clone() };
    let t = Instant::now();
    let (_, info) = fixed.fit(rows, &d.reward, 1)?;
    let per_epoch = t.elapsed().as_secs_f64() / info.epochs as f64;
    let n_val = (d.len() as f64 * fixed.validation_fraction) as usize;
    let n_train = d.len() - n_val;
    let (h1, h2) = (10.0, 10.0);
    let macs = cols as f64 * h1 + h1 * h2 + h2;
    let flops_per_epoch = 2.0 * macs * (3.0 * n_train as f64 + n_val as f64);
    let gflops = flops_per_epoch / per_epoch / 1e9;
    let early = MlpParams { delta_min: 0.011, patience: 75, ..base };
    let t = Instant::now();
    let (_, info_es) = early.fit(rows, &d.reward, 2)?;
    let es_seconds = t.elapsed().as_secs_f64();
    let keras = if let Some(reference) = reference {
        let csv = reference.file("bicycle.csv");
        if !csv.exists() {
            crate::dataset::table::write(&d, &csv)?;
        }
        let args =
            [csv.display().to_string(), "--hidden".into(), "10,10".into(), "--activation".into(), "sigmoid".into()];
        reference.run("keras_mlp.py", &args)
    } else {
        None
    };
    let epoch_speedup = keras.as_ref().and_then(|k| k["epoch_ms_median"].as_f64()).map(|ms| ms / (per_epoch * 1e3));
    let fit_speedup = keras.as_ref().and_then(|k| k["early_stopped_fit_s"].as_f64()).map(|s| s / es_seconds);
    if !json {
        println!(
            "  mlp [10, 10] sigmoid on {} rows: {:.3} ms/epoch ({:.1} GFLOP/s); early-stopped fit (δ 0.011, patience 75): {:.2} s, {} epochs{}",
            d.len(),
            per_epoch * 1e3,
            gflops,
            es_seconds,
            info_es.epochs,
            match (epoch_speedup, fit_speedup) {
                (Some(a), Some(b)) => format!("  | vs Keras: epoch {a:.1}×, early-stopped fit {b:.1}×"),
                _ => String::new(),
            }
        );
        if reference.is_none() {
            println!("  (no --python given: pass one with scikit-learn, keras and jax for side-by-side ratios)");
        }
    }
    Ok(json!({
        "threads": threads,
        "extra_trees": et,
        "mlp": {
            "rows": d.len(), "inputs": cols, "hidden": [10, 10], "activation": "sigmoid",
            "ms_per_epoch": per_epoch * 1e3, "gflops": gflops, "flops_per_epoch": flops_per_epoch,
            "early_stopped_fit_s": es_seconds, "early_stopped_epochs": info_es.epochs,
            "reference": keras, "epoch_speedup": epoch_speedup, "fit_speedup": fit_speedup,
        }
    }))
}
