//! Any gymnasium env in one line (issue 48): `gymnasium:<id>` as ENV, and a spec holding only
//! `env`, are completed from `searches/gymnasium/defaults.json` with the fields that depend on
//! the env taken from its probe; the completed spec states no thesis claims; a stale `env.probed`
//! is refused before a run directory exists.

mod common;
use common::gym::{gym_bin, python};
use common::{bin, empty_dir, read, tiny_with};

use serde_json::{Value, json};
use std::path::Path;
use std::process::Output;

fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    format!("{}{err}", String::from_utf8_lossy(&o.stdout))
}

/// A refusal: exit 2, one line, no panic, every word of `want`.
fn refused(o: &Output, want: &[&str]) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked") && err.trim_end().lines().count() == 1, "{err}");
    for w in want {
        assert!(err.contains(w), "{err:?} does not contain {w:?}");
    }
    err
}

/// The resolved spec `search <target> --dry-run` prints, run in `dir`.
fn dry_run(py: &str, dir: &Path, target: &str) -> Value {
    let o = gym_bin(py).current_dir(dir).args(["search", target, "--dry-run"]).output().unwrap();
    ok(&o);
    let out = String::from_utf8_lossy(&o.stdout);
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("--dry-run prints the spec: {e}: {out}"))
}

#[test]
fn a_gymnasium_id_alone_resolves_to_the_template_with_the_envs_own_horizon_and_no_claims() {
    let Some(py) = python() else { return };
    let d = empty_dir("oneline", "id");
    let s = dry_run(&py, &d, "gymnasium:Acrobot-v1");
    let template: Value =
        serde_json::from_str(&read(Path::new(env!("CARGO_MANIFEST_DIR")).join("searches/gymnasium/defaults.json")))
            .unwrap();
    // Acrobot-v1's time limit is 500 steps: the dataset horizon and the evaluation length.
    assert_eq!(s["env"]["id"], "Acrobot-v1");
    assert_eq!((s["env"]["horizon"].clone(), s["env"]["eval"]["steps"].clone()), (json!(500), json!(500)));
    assert_eq!(s["env"]["gamma"], template["env"]["gamma"]);
    assert_eq!(s["env"]["probed"]["action"], json!({"kind": "discrete", "n": 3, "start": 0}));
    // The thesis's search and GA, from the template, and no thesis claims.
    assert_eq!(s["search"]["ga"]["population"], template["search"]["ga"]["population"]);
    assert_eq!(s["search"]["network"]["hidden"], json!([10, 10]));
    for l in ["et", "mlp"] {
        assert!(s["experiments"][l].get("claims").is_none(), "{s}");
    }
    // Nothing was created by a dry run.
    assert!(std::fs::read_dir(&*d).unwrap().next().is_none());
}

#[test]
fn a_spec_holding_only_env_is_completed_and_every_field_it_gives_wins() {
    let Some(py) = python() else { return };
    let d = empty_dir("oneline", "partial");
    let spec = json!({
        "env": {"name": "gymnasium", "id": "CartPole-v1", "horizon": 100},
        "search": {"ga": {"population": 4}}
    });
    std::fs::write(d.join("mine.json"), spec.to_string()).unwrap();
    let s = dry_run(&py, &d, "mine.json");
    assert_eq!(s["env"]["horizon"], 100, "the user's horizon");
    assert_eq!(s["env"]["eval"]["steps"], 500, "CartPole-v1's time limit");
    assert_eq!(s["search"]["ga"]["population"], 4);
    assert_eq!(s["search"]["datasets"], 10, "the template's");
    // A continuous action space gets its bounds as the actions (the thesis's two pendulum torques).
    let s = dry_run(&py, &d, "gymnasium:Pendulum-v1");
    assert_eq!(s["env"]["actions"], json!([-2.0, 2.0]));
    assert_eq!(s["env"]["horizon"], 200);
    // The saved dry run is a complete spec that reads back the same.
    std::fs::write(d.join("saved.json"), s.to_string()).unwrap();
    assert_eq!(dry_run(&py, &d, "saved.json"), s);
}

#[test]
fn one_line_envs_work_in_dataset_run_search_and_compare_without_thesis_verdicts() {
    let Some(py) = python() else { return };
    let d = empty_dir("oneline", "commands");
    let env = "gymnasium:CartPole-v1";
    let csv = d.join("d.csv");
    ok(&gym_bin(&py).args(["dataset", env, "--episodes", "3", "--out"]).arg(&csv).output().unwrap());
    assert!(read(&csv).lines().count() > 3);
    let run = ["run", env, "--algo", "bfqi", "--learner", "et", "--iterations", "2", "--datasets", "1"];
    let models = d.join("models");
    ok(&gym_bin(&py).args(run).args(["--episodes", "10", "--save-model"]).arg(&models).output().unwrap());
    // `evaluate --seed` scores the policy on fresh episodes; without it, on its evaluation's.
    let evaluate = |extra: &[&str]| -> Value {
        let m = models.join("dataset-0.model");
        let o = gym_bin(&py).arg("evaluate").arg(&m).args(["--episodes", "5", "--json"]).args(extra).output().unwrap();
        ok(&o);
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let own = evaluate(&[]);
    let eval_seed = own["info"]["eval_seed"].to_string();
    assert_eq!(evaluate(&["--seed", &eval_seed])["result"], own["result"]);
    let fresh = evaluate(&["--seed", "7"]);
    assert_eq!(fresh["seed"], 7);
    assert_ne!(fresh["result"], own["result"], "other starts, another score");
    let out = d.join("search");
    ok(&gym_bin(&py).arg("search").arg(env).args(tiny_with(&[])).arg("--out").arg(&out).output().unwrap());
    let mut run_json: Value = serde_json::from_str(&read(out.join("run.json"))).unwrap();
    assert_eq!(run_json["spec_source"], env);
    // run.json records the Python stack, and `reproduce` names a difference in it when the scores
    // disagree (here a score edited, and numpy's version as if recorded elsewhere).
    let stack = run_json["gymnasium"].clone();
    for k in ["python", "gymnasium", "numpy"] {
        assert!(stack[k].as_str().is_some_and(|v| !v.is_empty()), "{k}: {run_json}");
    }
    run_json["gymnasium"]["numpy"] = json!("0.0.1");
    let mut best: Value = serde_json::from_str(&read(out.join("best.json"))).unwrap();
    let first = best["scores"][0].as_f64().unwrap();
    best["scores"][0] = json!(first + 1.0);
    let edited = d.join("edited");
    std::fs::create_dir_all(&edited).unwrap();
    std::fs::write(edited.join("best.json"), best.to_string()).unwrap();
    std::fs::write(edited.join("run.json"), run_json.to_string()).unwrap();
    let o = gym_bin(&py).arg("reproduce").arg(edited.join("best.json")).output().unwrap();
    let said = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert_eq!(o.status.code(), Some(1), "{said}");
    let now = stack["numpy"].as_str().unwrap();
    assert!(said.contains(&format!("numpy 0.0.1 when recorded, {now} now")), "{said}");
    let cmp = d.join("cmp");
    let o = gym_bin(&py)
        .args(["compare", env, "--learner", "et", "--analysis", "iterations"])
        .args(["--datasets", "2", "--episodes", "10", "--iterations", "2", "--quiet", "--tuned"])
        .arg(out.join("best.json"))
        .arg("--out")
        .arg(&cmp)
        .output()
        .unwrap();
    let said = ok(&o);
    assert!(said.contains("no thesis claims") && !said.contains("supported"), "{said}");
    let report = read(cmp.join("report.md"));
    assert!(report.contains("this spec states no thesis claims") && !report.contains("Cart-pole"), "{report}");
}

#[test]
fn a_probe_copied_from_another_env_is_refused_before_a_run_directory_exists() {
    let Some(py) = python() else { return };
    let d = empty_dir("oneline", "stale");
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/searches/cartpole-v1/spec.json");
    let mut spec: Value = serde_json::from_str(&read(committed)).unwrap();
    spec["env"]["id"] = json!("Acrobot-v1");
    std::fs::write(d.join("copied.json"), spec.to_string()).unwrap();
    let out = d.join("run");
    let o = gym_bin(&py).arg("search").arg(d.join("copied.json")).arg("--out").arg(&out).output().unwrap();
    refused(&o, &["copied.json", "env.probed", "Discrete(2)", "Acrobot-v1's worker reports", "Discrete(3)"]);
    assert!(!out.exists());
    let o = gym_bin(&py)
        .arg("dataset")
        .arg(d.join("copied.json"))
        .args(["--episodes", "2", "--out"])
        .arg(d.join("d.csv"))
        .output();
    refused(&o.unwrap(), &["env.probed"]);
    assert!(!d.join("d.csv").exists());
}

#[test]
fn malformed_one_line_envs_are_refused_naming_what_is_allowed() {
    let d = empty_dir("oneline", "refusals");
    // No Python is needed to refuse these.
    let o = bin().current_dir(&d).args(["search", "gymnasium:", "--dry-run"]).output().unwrap();
    refused(&o, &["ENV", "gymnasium:Acrobot-v1"]);
    let o = bin().current_dir(&d).args(["search", "acrobot", "--dry-run"]).output().unwrap();
    refused(&o, &["unknown environment 'acrobot'", "pendulum, cartpole, bicycle", "gymnasium:<id>"]);
    std::fs::write(d.join("noid.json"), r#"{"env": {"name": "gymnasium"}}"#).unwrap();
    let o = bin().current_dir(&d).args(["search", "noid.json", "--dry-run"]).output().unwrap();
    refused(&o, &["noid.json", "env", "id"]);
    let Some(py) = python() else { return };
    let o = gym_bin(&py).current_dir(&d).args(["search", "gymnasium:NoSuchEnv-v0", "--dry-run"]).output().unwrap();
    refused(&o, &["gymnasium:NoSuchEnv-v0", "env.id", "gymnasium.make"]);
    // A template edited wrong is refused naming the template's file and field.
    std::fs::create_dir_all(d.join("searches/gymnasium")).unwrap();
    std::fs::write(d.join("searches/gymnasium/defaults.json"), r#"{"derive": {"horizon_max": 10}}"#).unwrap();
    let o = gym_bin(&py).current_dir(&d).args(["search", "gymnasium:CartPole-v1", "--dry-run"]).output().unwrap();
    refused(&o, &["searches/gymnasium/defaults.json", "derive", "box_corner_values"]);
}
