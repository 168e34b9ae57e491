//! `bench fqi`: whole FQI / B-FQI runs with Extra-Trees, against scikit-learn in the same window.

use super::{PythonReference, data, median};
use crate::dataset::Dataset;
use crate::env::Env;
use crate::error::Result;
use crate::eval::eval_seed;
use crate::fqi::{Algorithm, Fqi, FqiSettings, IterationRecord, RunRecord};
use crate::learn::actions::{ActionEncoding, Encoded};
use crate::learn::extra_trees::ExtraTreesParams;
use crate::rng;
use serde::Serialize;
use serde_json::{Value, json};
use std::path::Path;
use std::time::Instant;

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
    let rec =
        Fqi::new(env, d, enc, p, settings, rng::derive(1, rng::purpose::FIT, &[0]), eval_seed(1, 0)).run(|_| {})?;
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
    let py_ref = PythonReference::new(python)?;
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
        let measured_reference = match &py_ref {
            Some(py) => {
                let csv = py.file(&format!("{env}.csv"));
                crate::dataset::table::write(&d, &csv)?;
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
                py.run("sklearn_fqi.py", &args)
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
    Ok(json!({ "threads": rayon::current_num_threads(), "runs": figures }))
}
