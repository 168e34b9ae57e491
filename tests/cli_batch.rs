//! `bfqi-ga batch` end to end: failing jobs, budget stop and resume, malformed plans.

mod common;
use bfqi_ga::progress::human;
use common::{TempDir, bin, empty_dir, json, read, tiny_with};

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
fn a_batch_killed_outright_keeps_the_running_jobs_time_to_its_last_heartbeat() {
    let d = tmp("heartbeat");
    // A search far longer than the 10 s heartbeat on any machine (200 generations of 20).
    let long = r#"{"name": "long", "search": "cartpole", "presets": ["quick"], "population": 20, "generations": 200, "stall_generations": 200, "datasets": 2, "episodes": 25, "iterations": 2}"#;
    let p = plan(&d, &[long]);
    let out = d.join("b");
    let mut child = common::spawn_quiet(bin().arg("batch").arg(&p).arg("--out").arg(&out));
    let seconds = |out: &Path| {
        std::fs::read_to_string(out.join("batch.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .map_or(0.0, |v| v[0]["seconds"].as_f64().unwrap_or(0.0))
    };
    let t = std::time::Instant::now();
    while seconds(&out) == 0.0 && t.elapsed().as_secs() < 120 && child.try_wait().unwrap().is_none() {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    assert!(child.try_wait().unwrap().is_none(), "the job ended before its first heartbeat");
    child.kill().unwrap();
    child.wait().unwrap();
    let kept = seconds(&out);
    assert!(kept >= 10.0, "batch.json kept {kept} s of a job killed after its first heartbeat");
    // A resume stopped before the job goes on keeps that time, and the summary shows it.
    let o = batch(&["--resume", out.to_str().unwrap(), "--max-hours", "1e-300"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(seconds(&out), kept);
    let summary = read(out.join("summary.md"));
    let row = summary.lines().find(|l| l.starts_with("| long ")).unwrap();
    assert!(row.contains(&format!("| {} |", human(kept))), "{row}");
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
    // Both invocations ran here with the same threads: one set-up, named once under the times.
    let here = json(cut.join("c/run.json"))["machine"]["cpu"].as_str().unwrap().to_string();
    let line =
        summary.lines().find(|l| l.starts_with("Every invocation ran on ")).unwrap_or_else(|| panic!("{summary}"));
    assert!(line.contains(&here), "{line}");
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

#[test]
fn a_search_job_is_checked_against_its_reference_and_report_rebuilds_the_summary() {
    let d = tmp("reference");
    // The reference: the same spec (env, seed, episodes, iterations, network) with a larger
    // population, validated as every search is.
    let full = d.join("full");
    let o = bin()
        .args(["search", "cartpole"])
        .args(tiny_with(&["--seed", "4", "--population", "6"]))
        .arg("--out")
        .arg(&full)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let job = SEARCH.replace("\"seed\": 4}", &format!("\"seed\": 4, \"reference\": \"{}\"}}", full.display()));
    let p = plan(&d, &[&job]);
    let out = d.join("b");
    let o = batch(&[p.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = read(out.join("summary.md"));
    assert!(summary.contains("## Against the full-size searches"), "{summary}");
    assert!(summary.contains("| **total** |"), "{summary}");
    let row = summary.lines().find(|l| l.starts_with("| s | `")).unwrap_or_else(|| panic!("{summary}"));

    // The row, recomputed from the two validation.json files.
    let winner = |v: &serde_json::Value| -> serde_json::Value {
        let name = v["best_validated"].as_str().unwrap_or_else(|| v["tuned"].as_str().unwrap()).to_string();
        v["entries"].as_array().unwrap().iter().find(|e| e["setting"] == name.as_str()).unwrap().clone()
    };
    let (mine, theirs) = (winner(&json(out.join("s/validation.json"))), winner(&json(full.join("validation.json"))));
    let n = theirs["validation_scores"].as_array().unwrap().len();
    let scores: Vec<f64> =
        mine["validation_scores"].as_array().unwrap()[..n].iter().map(|x| x.as_f64().unwrap()).collect();
    let mean = scores.iter().sum::<f64>() / n as f64;
    let (rm, rc) = (theirs["validation"]["mean"].as_f64().unwrap(), theirs["validation"]["ci95"].as_f64().unwrap());
    let verdict = if mean > rm + rc {
        "above"
    } else if mean >= rm - rc {
        "within"
    } else {
        "below"
    };
    assert!(row.contains(&format!("{mean:.3} ({n} datasets)")), "{row}");
    assert!(row.contains(&format!("{rm:.3} ± {rc:.3}")) && row.contains(&format!("| {verdict} |")), "{row}");
    assert!(
        row.contains(mine["setting"].as_str().unwrap()) && row.contains(theirs["setting"].as_str().unwrap()),
        "{row}"
    );
    // The work cell: the two searches' reference hours as `bfqi-ga work` counts them, and their ratio.
    let (jh, rh) = (reference_hours(&out.join("s")), reference_hours(&full));
    assert!(row.ends_with(&format!("| {jh:.2} / {rh:.2} h ({:.1} %) |", 100.0 * jh / rh)), "{row}");

    // `report` rebuilds the summary and the job's report from the records alone.
    for f in ["summary.md", "s/report.md", "s/fitness.png"] {
        std::fs::remove_file(out.join(f)).unwrap();
    }
    let o = bin().arg("report").arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read(out.join("summary.md")), summary);
    assert!(out.join("s/report.md").is_file() && out.join("s/fitness.png").is_file());

    // A reference of other validation datasets (another master seed) is refused with the plan.
    let other = job.replace("\"seed\": 4", "\"seed\": 5");
    let p = plan(&d, &[&other]);
    let o = batch(&[p.to_str().unwrap(), "--out", d.join("b2").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("job 1 (s)") && err.contains("field reference") && err.contains("its seed differs"), "{err}");
    assert!(!d.join("b2").exists(), "a refused plan created its batch directory");
}

/// `bfqi-ga work --json`'s reference hours of a run.
fn reference_hours(dir: &Path) -> f64 {
    let o = bin().arg("work").arg(dir).arg("--json").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()["reference_hours"].as_f64().unwrap()
}

#[test]
fn a_compare_job_sets_its_work_against_its_reference_and_a_different_comparison_is_refused() {
    let d = tmp("compare-reference");
    // The reference: the job's comparison under another tuned config (the thesis optimum, where
    // the job takes its search's winner).
    let full = d.join("full");
    let o = bin()
        .args(["compare", "cartpole", "--tuned", "thesis", "--learner", "mlp", "--datasets", "2"])
        .args(["--episodes", "30", "--iterations", "2", "--quiet", "--out"])
        .arg(&full)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let job =
        COMPARE.replace("\"iterations\": 2}", &format!("\"iterations\": 2, \"reference\": \"{}\"}}", full.display()));
    let p = plan(&d, &[SEARCH, &job]);
    let out = d.join("b");
    let o = batch(&[p.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary = read(out.join("summary.md"));
    assert!(summary.contains("## Work against the references"), "{summary}");
    // The row and the total, from the two runs' work as `bfqi-ga work` counts it; the search job
    // has no reference, so the total is not the whole plan's.
    let (jh, rh) = (reference_hours(&out.join("c")), reference_hours(&full));
    let pct = format!("{:.1} %", 100.0 * jh / rh);
    let row = summary.lines().find(|l| l.starts_with("| c | `")).unwrap_or_else(|| panic!("{summary}"));
    assert_eq!(row, format!("| c | `{}` | {jh:.2} ref. h | {rh:.2} ref. h | {pct} |", full.display()));
    let total = summary.lines().find(|l| l.starts_with("| **finished jobs** |")).unwrap();
    assert!(total.starts_with("| **finished jobs** | 1 of 2 |") && total.ends_with(&format!("**{pct}** |")), "{total}");
    assert!(summary.contains("counts the 1 finished job(s) with a reference, of the plan's 2"), "{summary}");

    // A reference that compares something else (other episodes) is refused with the plan.
    let other = job.replace("\"episodes\": 30", "\"episodes\": 31");
    let p = plan(&d, &[SEARCH, &other]);
    let o = batch(&[p.to_str().unwrap(), "--out", d.join("b2").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("job 2 (c)") && err.contains("field reference") && err.contains("its `learners` differs"),
        "{err}"
    );
    assert!(!d.join("b2").exists(), "a refused plan created its batch directory");
    // A search directory is not a comparison reference.
    let search = job.replace(&full.display().to_string(), &out.join("s").display().to_string());
    let p = plan(&d, &[SEARCH, &search]);
    let o = batch(&[p.to_str().unwrap(), "--out", d.join("b3").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("field reference: not a comparison run directory"), "{err}");
}

#[test]
fn the_shipped_one_night_plan_checks_against_the_committed_full_searches() {
    // Every search job names its full-size reference, and `check` holds each to the same env,
    // seed, episodes, iterations and network: the lean preset changes only the GA's budget.
    let path = Path::new("searches/batches/one-night.json");
    let plan = bfqi_ga::batch::Plan::parse(&read(path), path).unwrap();
    assert_eq!(plan.jobs.len(), 6);
    bfqi_ga::batch::check(&plan, path).unwrap();
    let text = read(path);
    for env in ["cartpole", "bicycle", "pendulum"] {
        assert!(text.contains(&format!("\"reference\": \"results/searches/{env}\"")), "{env} has no reference");
    }
    // Every comparison names the committed full plan's comparison of its env (`check` holds it to
    // the same analysis, learner, datasets, episodes and iterations), so the summary's total is
    // the plan's work against the full plan's.
    for job in &plan.jobs {
        if let bfqi_ga::batch::Job::Compare(c) = job {
            let r = c.reference.as_deref().unwrap_or_else(|| panic!("{} has no reference", c.name));
            assert!(r.starts_with(&format!("results/searches/{}-compare-mlp-", c.compare)), "{}: {r}", c.name);
        }
    }
    // Built on the lean search, taking the committed lean runs' units (the check above refuses a
    // units_from whose units hash differs, so they are the same units).
    for job in &plan.jobs {
        if let bfqi_ga::batch::Job::Search(s) = job {
            assert_eq!(s.presets, ["lean"], "{}", s.name);
            let env = s.name.trim_start_matches("search-");
            assert_eq!(s.units_from, Some(format!("results/searches/lean/lean-{env}")), "{}", s.name);
        }
    }
}

#[test]
fn the_shipped_night_levers_plan_replays_the_committed_full_searches() {
    // Each job takes the units of the full search it is checked against: the plan passes its
    // check only while both have the same units hash, i.e. differ only in the stop rules here.
    let path = Path::new("searches/batches/night-levers.json");
    let plan = bfqi_ga::batch::Plan::parse(&read(path), path).unwrap();
    assert_eq!(plan.jobs.len(), 3);
    bfqi_ga::batch::check(&plan, path).unwrap();
    for job in &plan.jobs {
        let bfqi_ga::batch::Job::Search(s) = job else { panic!("{} is not a search", job.name()) };
        assert_eq!(s.units_from, s.reference, "{}", s.name);
        assert_eq!((s.overrides.generations, s.overrides.stall_generations), (Some(10), Some(4)), "{}", s.name);
    }
}

#[test]
fn a_search_job_takes_the_units_of_another_run_once_and_a_foreign_spec_is_refused_with_the_plan() {
    let d = tmp("units-from");
    // The run to take from: the plan's search at three generations, made beforehand.
    let three = d.join("three");
    let o = bin()
        .args(["search", "cartpole", "--out"])
        .arg(&three)
        .args(tiny_with(&["--episodes", "25", "--seed", "4", "--generations", "3"]))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let job = format!(
        r#"{{"name": "s", "search": "cartpole", "presets": ["quick"], "episodes": 25, "datasets": 2, "iterations": 2, "population": 4, "generations": 2, "seed": 4, "units_from": "{}"}}"#,
        three.display()
    );
    let p = plan(&d, &[&job]);
    let out = d.join("b");
    // Stopped before its first unit, then resumed: the units are taken by the first invocation only.
    let o = batch(&[p.to_str().unwrap(), "--out", out.to_str().unwrap(), "--max-hours", "0.000001"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = batch(&["--resume", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info = json(out.join("s/run.json"));
    let taken = info["units_from"].as_array().unwrap();
    assert_eq!(taken.len(), 1, "{info}");
    let units = std::fs::read_dir(three.join("units")).unwrap().count();
    assert_eq!(taken[0]["units"], units, "{info}");
    // Its two generations are the longer run's first two, computed by nobody new: every unit
    // file is the other run's, byte for byte.
    let lines = |run: &Path| read(run.join("generations.jsonl")).lines().map(json_line).collect::<Vec<_>>();
    assert_eq!(lines(&out.join("s"))[..], lines(&three)[..2]);
    for e in std::fs::read_dir(out.join("s/units")).unwrap() {
        let f = e.unwrap().file_name();
        assert_eq!(read(out.join("s/units").join(&f)), read(three.join("units").join(&f)), "{f:?}");
    }
    // The summary says where the taken units were computed and that run's wall time: a replay's
    // seconds are not the search's time.
    let summary = read(out.join("summary.md"));
    let st = json(three.join("state.json"));
    let theirs: f64 = st["generation_seconds"].as_array().unwrap().iter().map(|s| s.as_f64().unwrap()).sum::<f64>()
        + st["current_seconds"].as_f64().unwrap();
    let row = format!(
        "| s | {units} (+{} validation) | `{}` | {} on ",
        taken[0]["validation"],
        three.display(),
        human(theirs)
    );
    assert!(summary.contains("## Units computed elsewhere") && summary.contains(&row), "{row}\n{summary}");

    // Units of another spec (another seed): the plan is refused before anything runs.
    let foreign = job.replace(r#""seed": 4"#, r#""seed": 5"#);
    let p = plan(&d, &[&foreign]);
    let o = batch(&[p.to_str().unwrap(), "--out", d.join("refused").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("job 1 (s)"), "{err}");
    assert!(err.contains("--units-from") && err.contains("another spec"), "{err}");
    assert!(!d.join("refused").exists());
}

/// A generations.jsonl line's individuals (the rest holds wall times).
fn json_line(l: &str) -> serde_json::Value {
    serde_json::from_str::<serde_json::Value>(l).unwrap()["individuals"].clone()
}
