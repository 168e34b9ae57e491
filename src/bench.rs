//! Benchmarks (`bfqi-ga bench`): figures and ratios, never assertions.
//!
//! `bench learners` times the Extra-Trees and the MLP on simulator data in the thesis's settings and,
//! given a Python with scikit-learn / Keras, runs the reference scripts of `shared/bench/` on the
//! same data in the same run for side-by-side ratios. `bench fqi` times whole FQI / B-FQI runs.

use crate::dataset::{self, Dataset, dataset_seed};
use crate::env::{Env, EnvConfig};
use crate::error::{Error, Result};
use crate::eval::eval_seed;
use crate::fqi::{Algorithm, Fqi, FqiSettings, IterationRecord, RunRecord};
use crate::learn::actions::{ActionEncoding, Encoded};
use crate::learn::extra_trees::ExtraTreesParams;
use crate::learn::mlp::{Activation, MlpParams};
use crate::learn::{Learner, Regressor, Rows};
use crate::rng;
use serde::Serialize;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Where to find the Python reference, if any.
#[derive(Debug, Clone, Default)]
pub struct PythonReference {
    /// The Python interpreter with scikit-learn (and Keras + JAX for the MLP).
    pub python: Option<PathBuf>,
    /// The folder holding `sklearn_et.py` and `keras_mlp.py`.
    pub scripts: PathBuf,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn rows_input(d: &Dataset) -> Vec<f64> {
    let od = d.obs_dim;
    let mut x = Vec::with_capacity(d.len() * (od + 1));
    for i in 0..d.len() {
        x.extend_from_slice(&d.state[i * od..(i + 1) * od]);
        x.push(d.action[i]);
    }
    x
}

fn data(env: &str, episodes: usize) -> Result<(EnvConfig, Dataset)> {
    let c = EnvConfig::by_name(env)?;
    let d = dataset::collect(c.env(), episodes, dataset_seed(1, "compare", 0))?;
    Ok((c, d))
}

fn run_python(reference: &PythonReference, script: &str, args: &[String]) -> Option<Value> {
    run_python_at(reference.python.as_ref()?, &reference.scripts.join(script), args)
}

/// Runs `python script args…` and parses the last line it prints as JSON; a failure is reported on
/// stderr and gives `None` (the figures without a reference are still worth printing).
fn run_python_at(python: &Path, script: &Path, args: &[String]) -> Option<Value> {
    let name = script.file_name().map_or_else(|| script.display().to_string(), |n| n.to_string_lossy().into());
    let out = Command::new(python).arg(script).args(args).output().ok()?;
    if !out.status.success() {
        eprintln!("  (reference {name} failed: {})", String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or(""));
        return None;
    }
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().last()?).ok()
}

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
    reference: &PythonReference,
    tmp: &Path,
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

    let reference = if reference.python.is_some() {
        let csv = tmp.join(format!("{env}.csv"));
        d.write_csv(&csv)?;
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
        run_python(reference, "sklearn_et.py", &args)
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
pub fn learners(reference: &PythonReference, json: bool) -> Result<Value> {
    let tmp = std::env::temp_dir().join(format!("bfqi-bench-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
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
        let f = bench_et(name, env, episodes, p, reference, &tmp)?;
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
    let keras = if reference.python.is_some() {
        let csv = tmp.join("bicycle.csv");
        if !csv.exists() {
            d.write_csv(&csv)?;
        }
        let args =
            [csv.display().to_string(), "--hidden".into(), "10,10".into(), "--activation".into(), "sigmoid".into()];
        run_python(reference, "keras_mlp.py", &args)
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
        if reference.python.is_none() {
            println!("  (no --python given: pass one with scikit-learn, keras and jax for side-by-side ratios)");
        }
    }
    let _ = std::fs::remove_dir_all(&tmp);
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

/// The scikit-learn FQI / B-FQI script `bench fqi --python` runs side by side (ours, so it is built
/// into the binary and needs no checkout).
const SKLEARN_FQI: &str = include_str!("../scripts/sklearn_fqi.py");

/// The fit + predict seconds of a `sklearn_fqi.py` JSON line.
fn reference_fit_predict_s(v: &Value) -> Option<f64> {
    Some(v["fit_s"].as_f64()? + v["predict_s"].as_f64()?)
}

/// A full-run figure of `bench fqi`.
#[derive(Debug, Serialize)]
struct FqiFigures {
    run: String,
    seconds: f64,
    /// Fit + predict seconds summed over the iterations (the whole run less datasets and evaluation).
    fit_predict_s: f64,
    iterations: usize,
    final_score: Option<f64>,
    /// Steps the final evaluation ran, over all its episodes (what the reference is asked to predict).
    eval_steps: usize,
    /// B-FQI only: fit + predict seconds of iteration K over iteration 2 (the running sums keep it
    /// near 1); FQI refits from scratch each iteration, so there it would measure nothing.
    last_over_second_iteration: Option<f64>,
    /// The same from the medians of three iterations (K − 2..=K over 2..=4; K ≥ 6): one iteration
    /// takes tenths of a second, and on a shared machine one of them can read 40 % off.
    last_over_second_iteration_median3: Option<f64>,
    /// Fit + predict seconds of iteration K: B-FQI's against FQI's on the same data shows what the
    /// member count costs (the running sums make it nothing), apart from the targets' effect.
    last_iteration_fit_predict_s: f64,
    python_reference_s: f64,
    speedup: f64,
    /// scikit-learn on the same dataset, in the same window (`--python`): its JSON line.
    measured_reference: Option<Value>,
    /// With `--python`: our run again, right after scikit-learn's (whole run, fit + predict), so
    /// that its window is bracketed by ours.
    seconds_after_reference: Option<f64>,
    fit_predict_s_after_reference: Option<f64>,
    /// The second of our runs over the first (whole run): how much the machine drifted around the
    /// reference's run; outside [`STEADY`], the measured ratios are flagged as uncertain.
    drift: Option<f64>,
    /// Its whole run (evaluation of `eval_steps` steps included) over ours (the mean of our two).
    measured_speedup: Option<f64>,
    /// Its fit + predict seconds over ours (no evaluation on either side; the mean of our two).
    measured_fit_predict_speedup: Option<f64>,
}

/// The [`FqiFigures::drift`] within which a window counts as steady: our two identical runs around
/// scikit-learn's were less than 1.25× apart.
const STEADY: std::ops::RangeInclusive<f64> = 0.8..=1.25;

/// An iteration's fit + predict seconds.
fn fit_predict_s(r: &IterationRecord) -> f64 {
    r.fit_seconds + r.predict_seconds
}

/// One of our `bench fqi` runs: its record, whole-run seconds, and fit + predict seconds.
fn timed_run(
    env: &dyn Env,
    d: &Dataset,
    enc: &Encoded,
    p: &ExtraTreesParams,
    settings: FqiSettings,
) -> Result<(RunRecord, f64, f64)> {
    let t = Instant::now();
    let rec = Fqi::new(env, d, enc, p, settings, rng::derive(1, "fit", &[0]), eval_seed(1, 0)).run(|_| {})?;
    let seconds = t.elapsed().as_secs_f64();
    let total = rec.iterations.iter().map(fit_predict_s).sum();
    Ok((rec, seconds, total))
}

/// Benchmarks whole FQI / B-FQI runs with Extra-Trees; prints a table, or JSON with `json`. With a
/// Python that has scikit-learn, each run is followed by the same run in scikit-learn
/// (`scripts/sklearn_fqi.py`) on the same dataset, so the ratio is taken in one window of a shared,
/// noisy machine instead of against a figure from another day.
pub fn fqi(python: Option<&Path>, json: bool) -> Result<Value> {
    // (env, algorithm, depth, trees, split, leaf, K, episodes, encoding, scikit-learn reference seconds
    // measured on this machine class with n_jobs = 2, as given in the learners/FQI issues).
    let runs = [
        ("bicycle", Algorithm::Fqi, 17, 50, 8, 4, 20, 1000, ActionEncoding::Input, 88.0),
        ("bicycle", Algorithm::Bfqi, 17, 50, 8, 4, 20, 1000, ActionEncoding::Input, 91.0),
        ("cartpole", Algorithm::Bfqi, 6, 30, 4, 2, 10, 2000, ActionEncoding::PerAction, 2.4),
        ("pendulum", Algorithm::Fqi, 13, 30, 4, 2, 20, 2000, ActionEncoding::Input, 133.0),
    ];
    let tmp = std::env::temp_dir().join(format!("bfqi-bench-fqi-{}", std::process::id()));
    let script = tmp.join("sklearn_fqi.py");
    if python.is_some() {
        std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
        std::fs::write(&script, SKLEARN_FQI).map_err(|e| Error::io(&script, e))?;
    }
    let mut figures = Vec::new();
    if !json {
        println!(
            "bench fqi · {} thread(s) · one dataset per run, greedy policy evaluated at iteration K (as in the reference)",
            rayon::current_num_threads()
        );
    }
    for (env, algorithm, depth, trees, split, leaf, k, episodes, encoding, reference) in runs {
        let t = Instant::now();
        let (c, d) = data(env, episodes)?;
        let data_s = t.elapsed().as_secs_f64();
        let e = c.env();
        let enc = Encoded::new(&d, e.actions(), encoding)?;
        let p = ExtraTreesParams {
            n_trees: trees,
            max_depth: Some(depth),
            min_samples_split: split,
            min_samples_leaf: leaf,
        };
        // The reference's time includes one greedy evaluation (its ~40 s on bicycle are one 5000-step
        // episode through per-step predicts), so the policy is evaluated once, after iteration K.
        let settings = FqiSettings { algorithm, iterations: k, eval_every: k };
        let (rec, run_s, run_fp) = timed_run(e, &d, &enc, &p, settings)?;
        // Like the reference's, our whole run includes making the dataset.
        let seconds = data_s + run_s;
        let it = |i: usize| fit_predict_s(&rec.iterations[i]);
        let n_it = rec.iterations.len();
        let ratio = (algorithm == Algorithm::Bfqi && n_it >= 2).then(|| it(n_it - 1) / it(1));
        let median3 = |from: usize| median((from..from + 3).map(it).collect());
        let ratio3 = (algorithm == Algorithm::Bfqi && n_it >= 6).then(|| median3(n_it - 3) / median3(1));
        let eval_steps =
            rec.iterations.last().and_then(|r| r.steps).map_or(0, |s| (s * e.eval().episodes as f64).round() as usize);
        let measured_reference = match python {
            Some(py) => {
                let csv = tmp.join(format!("{env}.csv"));
                d.write_csv(&csv)?;
                let actions: Vec<String> = e.actions().iter().map(|a| a.to_string()).collect();
                let args = [
                    csv.display().to_string(),
                    format!("--algo={}", algorithm.name()),
                    format!("--actions={}", actions.join(",")),
                    format!("--encoding={}", json!(encoding).as_str().unwrap_or_default()),
                    format!("--gamma={}", e.gamma()),
                    format!("--trees={trees}"),
                    format!("--depth={depth}"),
                    format!("--min-split={split}"),
                    format!("--min-leaf={leaf}"),
                    format!("--iterations={k}"),
                    format!("--eval-steps={eval_steps}"),
                    format!("--jobs={}", rayon::current_num_threads()),
                ];
                run_python_at(py, &script, &args)
            }
            None => None,
        };
        // Our run again after scikit-learn's (the same record but for the timings), so that a drift
        // of the machine during its run shows.
        let after = measured_reference
            .is_some()
            .then(|| timed_run(e, &d, &enc, &p, settings))
            .transpose()?
            .map(|(_, run_s, fp)| (data_s + run_s, fp));
        let (ours, ours_fp) = after.map_or((seconds, run_fp), |(s, fp)| ((seconds + s) / 2.0, (run_fp + fp) / 2.0));
        let measured = |v: &Value| v["seconds"].as_f64().map(|s| s / ours);
        let measured_fp = |v: &Value| reference_fit_predict_s(v).map(|s| s / ours_fp);
        let f = FqiFigures {
            run: format!("{env} {} depth {depth} K={k} ({episodes} episodes)", algorithm.name()),
            seconds,
            fit_predict_s: run_fp,
            iterations: rec.iterations.len(),
            final_score: rec.final_score(),
            eval_steps,
            last_over_second_iteration: ratio,
            last_over_second_iteration_median3: ratio3,
            last_iteration_fit_predict_s: rec.iterations.len().checked_sub(1).map_or(f64::NAN, it),
            python_reference_s: reference,
            speedup: reference / seconds,
            seconds_after_reference: after.map(|a| a.0),
            fit_predict_s_after_reference: after.map(|a| a.1),
            drift: after.map(|a| a.0 / seconds),
            measured_speedup: measured_reference.as_ref().and_then(measured),
            measured_fit_predict_speedup: measured_reference.as_ref().and_then(measured_fp),
            measured_reference,
        };
        if !json {
            println!(
                "  {:<42} {:>8.2} s  (scikit-learn reference {:>5.1} s: {:>5.1}×)  fit+predict iteration K: {:.3} s{}  final score {}",
                f.run,
                f.seconds,
                f.python_reference_s,
                f.speedup,
                f.last_iteration_fit_predict_s,
                match (f.last_over_second_iteration, f.last_over_second_iteration_median3) {
                    (Some(r), Some(r3)) => format!(", / iteration 2: {r:.2} (medians of 3: {r3:.2})"),
                    (Some(r), None) => format!(", / iteration 2: {r:.2}"),
                    _ => String::new(),
                },
                f.final_score.map_or("—".into(), |s| format!("{s:.3}"))
            );
            if let (Some(r), Some(whole), Some(fp), Some(drift)) =
                (&f.measured_reference, f.measured_speedup, f.measured_fit_predict_speedup, f.drift)
            {
                println!(
                    "  {:<42} {:>8.2} s  scikit-learn in this window: {whole:.1}× whole run (evaluation of {} steps: {:.1} s vs ours {:.2} s); fit+predict {fp:.1}× ({:.1} s vs {:.2} s)",
                    "",
                    r["seconds"].as_f64().unwrap_or(f64::NAN),
                    f.eval_steps,
                    r["eval_s"].as_f64().unwrap_or(f64::NAN),
                    rec.iterations.iter().map(|r| r.eval_seconds).sum::<f64>(),
                    reference_fit_predict_s(r).unwrap_or(f64::NAN),
                    ours_fp,
                );
                println!(
                    "  {:<42}   ours {:.2} s before and {:.2} s after it (×{drift:.2}; the ratios use the mean){}",
                    "",
                    f.seconds,
                    f.seconds_after_reference.unwrap_or(f64::NAN),
                    if STEADY.contains(&drift) { "" } else { ": the machine drifted, so these ratios are uncertain" }
                );
            }
        }
        figures.push(f);
    }
    if !json && python.is_none() {
        println!("  (no --python given: pass one with scikit-learn to run the same runs in scikit-learn side by side)");
    }
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(json!({ "threads": rayon::current_num_threads(), "runs": figures }))
}

/// Search throughput: the units of one generation (a small cart-pole search) evaluated on a 1-thread
/// and a 2-thread pool; prints units per second and the speed-up.
pub fn search(json: bool) -> Result<Value> {
    use crate::ga::operators::initial_population;
    use crate::ga::search::Evaluator;
    use crate::spec::Spec;
    use rayon::prelude::*;
    let (mut spec, _) = Spec::resolve("cartpole")?;
    spec.search.episodes = 300;
    spec.search.iterations = 5;
    spec.search.datasets = 2;
    spec.search.network.max_epochs = 400;
    let population: Vec<_> = initial_population(spec.seed, &spec.search.genes, 8)
        .iter()
        .map(|c| crate::ga::chromosome::decode(c, &spec.search.genes))
        .collect();
    let units: Vec<(usize, usize)> =
        (0..population.len()).flat_map(|c| (0..spec.search.datasets).map(move |d| (c, d))).collect();
    let mut rows = Vec::new();
    let mut first = None;
    for threads in [1, 2] {
        let pool =
            rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| Error::Data(e.to_string()))?;
        let ev = Evaluator::new(spec.clone(), Path::new("."));
        // Datasets are collected once per search; keep that out of the figure.
        for d in 0..spec.search.datasets {
            ev.evaluate(&population[0], d)?;
        }
        let t = Instant::now();
        let scores: Vec<Option<f64>> = pool.install(|| {
            units
                .par_iter()
                .with_max_len(1)
                .map(|&(c, d)| ev.evaluate(&population[c], d).map(|u| u.score))
                .collect::<Result<_>>()
        })?;
        let secs = t.elapsed().as_secs_f64();
        match &first {
            None => first = Some((secs, scores)),
            Some((_, s)) if *s != scores => return Err(Error::Data("scores differ between 1 and 2 threads".into())),
            _ => {}
        }
        rows.push((threads, secs, units.len() as f64 / secs));
    }
    let speedup = rows[0].1 / rows[1].1;
    if !json {
        println!("bench search · cart-pole, {} units (8 chromosomes × 2 datasets, K = 5, 300 episodes)", units.len());
        for (t, s, ups) in &rows {
            println!("  {t} thread(s): {s:.2} s, {ups:.2} units/s");
        }
        println!("  speed-up 1 → 2 threads: {speedup:.2}× (identical scores)");
    }
    Ok(
        json!({"units": units.len(), "runs": rows.iter().map(|(t, s, u)| json!({"threads": t, "seconds": s, "units_per_second": u})).collect::<Vec<_>>(), "speedup": speedup}),
    )
}
