//! `bfqi-ga batch` end to end: failing jobs, budget stop and resume, malformed plans.

mod common;
use common::{TempDir, bin, empty_dir, json, read};

use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    empty_dir("batch", name)
}

const SEARCH: &str = r#"{"name": "s", "search": "cartpole", "presets": ["quick"], "episodes": 25, "datasets": 2, "iterations": 2, "population": 4, "generations": 2, "seed": 4}"#;
const COMPARE: &str = r#"{"name": "c", "compare": "cartpole", "tuned": "from:s", "learner": "mlp", "datasets": 2, "episodes": 30, "iterations": 2}"#;

fn plan(dir: &Path, jobs: &[&str]) -> PathBuf {
    let p = dir.join("plan.json");
    std::fs::write(&p, format!("{{\"jobs\": [{}]}}", jobs.join(","))).unwrap();
    p
}

fn batch(args: &[&str]) -> Output {
    bin().arg("batch").args(args).arg("--quiet").output().unwrap()
}

#[test]
fn a_failing_job_is_recorded_and_the_others_go_on() {
    let d = tmp("fail");
    // A job that passes every check and fails when it runs: its network's learning rate makes
    // every unit diverge. (A job that cannot start is refused with the plan, before anything runs.)
    let spec = Path::new(env!("CARGO_MANIFEST_DIR")).join("searches/cartpole.json");
    let mut v: serde_json::Value = json(spec);
    v["search"]["network"]["learning_rate"] = serde_json::json!(1e300);
    std::fs::write(d.join("diverges.json"), v.to_string()).unwrap();
    let bad = format!(
        r#"{{"name": "bad", "search": "{}", "presets": ["quick"], "population": 2, "generations": 1, "datasets": 1, "episodes": 20, "iterations": 2}}"#,
        d.join("diverges.json").display()
    );
    let p = plan(&d, &[&bad, SEARCH]);
    let out = d.join("b");
    let o = batch(&[p.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = read(out.join("summary.md"));
    let bad = summary.lines().find(|l| l.starts_with("| bad ")).unwrap();
    assert!(bad.contains("failed") && bad.contains("every setting diverged"), "{bad}");
    let good = summary.lines().find(|l| l.starts_with("| s ")).unwrap();
    assert!(good.contains("finished") && good.contains("best fitness"), "{good}");
    assert!(out.join("s").join("best.json").is_file());
}

#[test]
fn budget_stop_then_resume_equals_an_uninterrupted_batch() {
    let d = tmp("budget");
    let p = plan(&d, &[SEARCH, COMPARE]);
    let (whole, cut) = (d.join("whole"), d.join("cut"));
    let o = batch(&[p.to_str().unwrap(), "--out", whole.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // A budget of ~4 ms: the search stops before its first unit.
    let o = batch(&[p.to_str().unwrap(), "--out", cut.to_str().unwrap(), "--max-hours", "0.000001"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let states: serde_json::Value = json(cut.join("batch.json"));
    assert_eq!(states[0]["state"], "interrupted", "{states}");
    assert_eq!(states[1]["state"], "pending");
    let o = batch(&["--resume", cut.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["s/generations.jsonl", "s/best.json", "c/summary.csv", "c/report.md"] {
        assert_eq!(read(whole.join(f)), read(cut.join(f)), "{f}");
    }
    let summary = read(cut.join("summary.md"));
    assert!(summary.contains("[report](c/report.md)"), "{summary}");
}

#[test]
fn a_malformed_plan_is_refused_naming_the_job_and_field() {
    let d = tmp("malformed");
    let p = plan(&d, &[SEARCH, r#"{"name": "c2", "compare": "cartpole", "learnr": "et"}"#]);
    let o = batch(&[p.to_str().unwrap(), "--out", d.join("b").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("job 2 (c2)") && err.contains("learnr"), "{err}");
}

#[test]
fn the_shipped_overnight_plan_is_valid() {
    let text = read("searches/batches/overnight.json");
    let plan = bfqi_ga::batch::Plan::parse(&text, Path::new("overnight.json")).unwrap();
    assert_eq!(plan.jobs.len(), 6);
}
