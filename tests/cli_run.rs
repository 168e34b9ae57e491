//! `bfqi-ga run` end to end: JSON schema, determinism, divergence, bad flags.

mod common;
use common::{bin, fresh, json, read};

use serde_json::Value;
use std::process::Output;

fn bfqi(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

fn run_json(extra: &[&str]) -> Value {
    let mut args = vec!["run", "cartpole", "--episodes", "60", "--datasets", "3", "--iterations", "3", "--json"];
    args.extend_from_slice(extra);
    let o = bfqi(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Removes every wall-clock field, which legitimately differs between runs.
fn without_timings(mut v: Value) -> Value {
    fn strip(v: &mut Value) {
        match v {
            Value::Object(m) => {
                m.retain(|k, _| !k.ends_with("_seconds"));
                m.values_mut().for_each(strip);
            }
            Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    strip(&mut v);
    v
}

#[test]
fn json_has_every_record_and_the_summary() {
    let v = run_json(&["--algo", "bfqi", "--depth", "4", "--trees", "5"]);
    assert_eq!(v["config"]["algorithm"], "bfqi");
    assert_eq!(v["config"]["learner"]["kind"], "extra_trees");
    assert_eq!(v["config"]["learner"]["max_depth"], 4);
    assert_eq!(v["config"]["actions"], "per_action", "cart-pole's preset encodes actions per action");
    let datasets = v["datasets"].as_array().unwrap();
    assert_eq!(datasets.len(), 3);
    for d in datasets {
        let its = d["iterations"].as_array().unwrap();
        assert_eq!(its.len(), 3);
        for (k, r) in its.iter().enumerate() {
            assert_eq!(r["iteration"], k + 1);
            let score = r["score"].as_f64().unwrap();
            // cos(15θ) rewards lie in [−1, 1] over at most 200 steps.
            assert!((-200.0..=200.0).contains(&score), "cart-pole return {score}");
            assert!(r["steps"].as_f64().unwrap() >= 1.0);
            assert!(r["bellman_residual"].as_f64().unwrap() >= 0.0);
            for t in ["fit_seconds", "predict_seconds", "eval_seconds"] {
                assert!(r[t].as_f64().unwrap() >= 0.0);
            }
        }
        assert!(d["diverged"].is_null());
    }
    let summary = v["summary"].as_array().unwrap();
    assert_eq!(summary.len(), 3);
    assert_eq!(summary[2]["score"]["n"], 3);
    // The summary is the mean over the datasets' records.
    let mean: f64 = datasets.iter().map(|d| d["iterations"][2]["score"].as_f64().unwrap()).sum::<f64>() / 3.0;
    assert!((summary[2]["score"]["mean"].as_f64().unwrap() - mean).abs() < 1e-9);
}

#[test]
fn same_seed_same_results_for_any_thread_count() {
    let flags = ["--algo", "fqi", "--depth", "5", "--trees", "8"];
    let a = without_timings(run_json(&[&flags[..], &["--jobs", "1"]].concat()));
    let b = without_timings(run_json(&[&flags[..], &["--jobs", "2"]].concat()));
    let c = without_timings(run_json(&flags));
    assert_eq!(a, b);
    assert_eq!(a, c);
    let other = without_timings(run_json(&[&flags[..], &["--seed", "9"]].concat()));
    assert_ne!(a["datasets"], other["datasets"]);
}

#[test]
fn mlp_runs_and_a_forced_divergence_is_recorded() {
    let ok = run_json(&["--learner", "mlp", "--hidden", "3", "--patience", "2"]);
    assert!(ok["datasets"][0]["iterations"][0]["epochs"].as_u64().unwrap() >= 3);
    // A learning rate of 1e30 blows the weights up: the run must end as `diverged`, not crash.
    let v = run_json(&["--learner", "mlp", "--hidden", "3", "--learning-rate", "1e30"]);
    for d in v["datasets"].as_array().unwrap() {
        let div = &d["diverged"];
        assert_eq!(div["iteration"], 1, "{v}");
        assert!(div["reason"].as_str().unwrap().contains("non-finite"));
    }
    assert_eq!(v["summary"][0]["diverged"], 3);
}

#[test]
fn out_writes_json_and_csv() {
    let dir = fresh("run", "out");
    let o = bfqi(&[
        "run",
        "bicycle",
        "--episodes",
        "30",
        "--datasets",
        "2",
        "--iterations",
        "2",
        "--trees",
        "5",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.contains("score (mean ± 95%)"), "{table}");
    let csv = read(dir.join("run.csv"));
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "dataset,iteration,score,steps,bellman_residual,epochs,fit_seconds,predict_seconds,eval_seconds,diverged"
    );
    assert_eq!(lines.count(), 4);
    let json: Value = json(dir.join("run.json"));
    assert_eq!(json["config"]["learner"]["n_trees"], 5);
    assert_eq!(json["config"]["learner"]["min_samples_split"], 8, "bicycle preset");
}

fn assert_exit_2(args: &[&str], needle: &str) {
    let o = bfqi(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
    assert!(!err.contains("panicked"));
}

#[test]
fn bad_flags_exit_2_with_a_clear_message() {
    assert_exit_2(&["run", "cartpole", "--iterations", "0"], "iterations");
    assert_exit_2(&["run", "cartpole", "--trees", "0"], "learner.n_trees");
    assert_exit_2(&["run", "cartpole", "--learner", "mlp", "--trees", "5"], "--learner et");
    assert_exit_2(&["run", "cartpole", "--learner", "mlp", "--delta-min", "-1"], "delta_min");
    assert_exit_2(&["run", "acrobot"], "pendulum, cartpole, bicycle");
    assert_exit_2(
        &["run", "pendulum", "--actions", "per-action", "--episodes", "2", "--iterations", "1"],
        "per_action",
    );
    assert_exit_2(&["run", "cartpole", "--algo", "sarsa"], "sarsa");
}
