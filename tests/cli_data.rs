//! A spec's `data.file`: logged transitions in, through the real binary (`dataset`, `search`,
//! `--resume`, `reproduce`).

mod common;
use common::{TempDir, bin, empty_dir, json, read, spawn_quiet, tiny_with, wait_for_entries};

use bfqi_ga::dataset::{Dataset, table};
use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    empty_dir("data", name)
}

fn ok(o: &Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A cart-pole log of 180 random-policy episodes written by `dataset --out`, and a cart-pole spec
/// learning from it with `data` = `{"file": <log>}` merged with `data`.
fn logged_spec(dir: &Path, log: &str, data: serde_json::Value) -> (PathBuf, PathBuf) {
    let log = dir.join(log);
    ok(&bin().args(["dataset", "cartpole", "--episodes", "180", "--seed", "2", "--out"]).arg(&log).output().unwrap());
    let mut v: serde_json::Value = json("searches/cartpole.json");
    let mut d = serde_json::json!({"file": log});
    d.as_object_mut().unwrap().extend(data.as_object().unwrap().clone());
    v["data"] = d;
    let spec = dir.join(format!("spec-of-{}.json", log.file_name().unwrap().to_string_lossy()));
    std::fs::write(&spec, v.to_string()).unwrap();
    (spec, log)
}

/// Each episode's transitions as bits, sorted: a dataset's episodes compared as a set.
fn episodes(d: &Dataset) -> Vec<Vec<u64>> {
    let od = d.obs_dim;
    let mut out: Vec<Vec<u64>> = vec![Vec::new(); d.episodes()];
    for r in 0..d.len() {
        let e = &mut out[d.episode[r] as usize];
        e.extend(d.state[r * od..(r + 1) * od].iter().map(|x| x.to_bits()));
        e.extend([d.action[r].to_bits(), d.reward[r].to_bits(), u64::from(d.absorbing[r]), u64::from(d.step[r])]);
        e.extend(d.next_state[r * od..(r + 1) * od].iter().map(|x| x.to_bits()));
    }
    out.sort();
    out
}

#[test]
fn dataset_out_then_data_file_then_dataset_out_gives_the_same_transitions() {
    let dir = tmp("round-trip");
    // One comparison slot takes every logged episode: the file comes back whole, reshuffled.
    let (spec, log) =
        logged_spec(&dir, "log.csv", serde_json::json!({"slots": {"search": 0, "validation": 0, "compare": 1}}));
    let back = dir.join("back.parquet");
    ok(&bin().args(["dataset", spec.to_str().unwrap(), "--episodes", "180", "--out"]).arg(&back).output().unwrap());
    let (a, b) = (table::read(&log).unwrap(), table::read(&back).unwrap());
    assert_eq!(a.len(), b.len());
    assert_eq!(episodes(&a), episodes(&b), "the same episodes, bit for bit");
    assert_ne!(a, b, "dealt in the split's order, not the file's");
    // A disjoint split of the spec's own counts: datasets of different roles share no episode.
    let (spec, _) =
        logged_spec(&dir, "log.parquet", serde_json::json!({"slots": {"search": 2, "validation": 3, "compare": 2}}));
    let one = |role: &str, index: &str, name: &str| {
        let p = dir.join(name);
        let args = ["dataset", spec.to_str().unwrap(), "--episodes", "25", "--role", role, "--index", index];
        ok(&bin().args(args).arg("--out").arg(&p).output().unwrap());
        episodes(&table::read(&p).unwrap())
    };
    let (s1, c0, all) = (one("search", "1", "s1.csv"), one("compare", "0", "c0.csv"), episodes(&a));
    assert_eq!(s1.len(), 25);
    assert!(s1.iter().chain(&c0).all(|e| all.contains(e)), "every episode is a logged one");
    assert!(s1.iter().all(|e| !c0.contains(e)), "a search dataset and a comparison dataset share no episode");
    // 180 episodes over 7 slots leave 25 each: 26 are refused, naming the file and the way out.
    let o = bin()
        .args(["dataset", spec.to_str().unwrap(), "--episodes", "26", "--out"])
        .arg(dir.join("x.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("data.file") && err.contains("holds 180 episodes") && err.contains("bootstrap"), "{err}");
    // A comparison learns from its own slots, and says where its data came from.
    let compare = |datasets: &str, out: &str| {
        bin()
            .args(["compare", spec.to_str().unwrap(), "--learner", "mlp", "--analysis", "iterations"])
            .args(["--datasets", datasets, "--episodes", "25", "--iterations", "2", "--quiet", "--out"])
            .arg(dir.join(out))
            .output()
            .unwrap()
    };
    ok(&compare("2", "cmp"));
    let report = read(dir.join("cmp/report.md"));
    assert!(report.contains("logged data") && report.contains("2 comparison datasets"), "{report}");
    let o = compare("3", "cmp3");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("data.slots.compare") && err.contains("3 comparison datasets"), "{err}");
    assert!(!dir.join("cmp3").exists(), "refused before a run directory exists");
}

fn search(spec: &Path, dir: &Path, extra: &[&str]) -> Output {
    bin()
        .args(["search", spec.to_str().unwrap(), "--out", dir.to_str().unwrap()])
        .args(tiny_with(extra))
        .output()
        .unwrap()
}

#[test]
fn a_search_on_a_logged_file_is_the_same_on_1_and_2_threads_after_a_kill_and_when_reproduced() {
    let dir = tmp("search");
    let (spec, _) = logged_spec(&dir, "log.parquet", serde_json::json!({"split": "bootstrap"}));
    let (a, b, killed) = (dir.join("j1"), dir.join("j2"), dir.join("killed"));
    ok(&search(&spec, &a, &["--jobs", "1"]));
    ok(&search(&spec, &b, &["--jobs", "2"]));
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json", "fitness.csv"] {
        assert_eq!(read(a.join(f)), read(b.join(f)), "{f} differs between 1 and 2 threads");
    }
    // spec.json records the data it learnt from: the file's hash and episodes, and the split.
    let s = json(a.join("spec.json"));
    assert_eq!(s["data"]["split"], "bootstrap");
    assert_eq!(s["data"]["episodes"], 180);
    assert_eq!(s["data"]["hash"].as_str().unwrap().len(), 16);
    let report = read(a.join("report.md"));
    assert!(
        report.contains("logged data") && report.contains("180 episodes") && report.contains("bootstrap"),
        "{report}"
    );
    // The deal follows the spec file, not the flags: --datasets 2 leaves 10 search slots.
    let (disjoint, _) = logged_spec(&dir, "log2.parquet", serde_json::json!({}));
    let o = bin()
        .args(["search", disjoint.to_str().unwrap(), "--dry-run"])
        .args(tiny_with(&["--episodes", "3"]))
        .output()
        .unwrap();
    ok(&o);
    let resolved: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(resolved["search"]["datasets"], 2);
    assert_eq!(resolved["data"]["slots"], serde_json::json!({"search": 10, "validation": 10, "compare": 40}));
    // Not the random-policy search of the same flags: the data decides the units.
    let collected = dir.join("collected");
    ok(&bin()
        .args(["search", "cartpole", "--out", collected.to_str().unwrap()])
        .args(tiny_with(&[]))
        .output()
        .unwrap());
    assert_ne!(read(a.join("generations.jsonl")), read(collected.join("generations.jsonl")));

    let mut child = spawn_quiet(
        bin().args(["search", spec.to_str().unwrap(), "--out", killed.to_str().unwrap()]).args(tiny_with(&[])),
    );
    wait_for_entries(&killed.join("units"), 2, &mut child);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    ok(&bin().args(["search", "--resume", killed.to_str().unwrap(), "--quiet"]).output().unwrap());
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
        assert_eq!(read(a.join(f)), read(killed.join(f)), "{f} differs after kill -9 and resume");
    }
    let o = bin().args(["reproduce", a.join("best.json").to_str().unwrap()]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && !out.contains("NOT"), "{out}{}", String::from_utf8_lossy(&o.stderr));

    // A changed file is not the data the run learnt from: the resume is refused, naming data.hash.
    let log = PathBuf::from(s["data"]["file"].as_str().unwrap());
    let mut d = table::read(&log).unwrap();
    d.reward[0] += 1.0;
    table::write(&d, &log).unwrap();
    let o = bin().args(["search", "--resume", a.to_str().unwrap(), "--generations", "3", "--quiet"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("data.hash") && err.contains("not the data"), "{err}");
}

#[test]
fn a_one_row_log_is_refused_naming_the_file_and_an_unflagged_end_is_warned_of() {
    let dir = tmp("one-row");
    let log = dir.join("one.csv");
    // One transition whose episode ends with neither flag: the log stopped.
    std::fs::write(
        &log,
        "episode,step,state_0,state_1,state_2,state_3,action,reward,next_state_0,next_state_1,next_state_2,next_state_3,terminated,truncated\n\
         0,0,0.1,0,0,0,1,1,0.1,0.1,0,0,False,False\n",
    )
    .unwrap();
    let mut v: serde_json::Value = json("searches/cartpole.json");
    v["data"] = serde_json::json!({"file": log, "split": "bootstrap"});
    let spec = dir.join("spec.json");
    std::fs::write(&spec, v.to_string()).unwrap();
    let o = bin().args(["search", spec.to_str().unwrap(), "--quick", "--out"]).arg(dir.join("run")).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("one.csv") && err.contains("holds 1 episode(s)"), "names the file and what it holds: {err}");
    assert!(err.contains("end with neither terminated nor truncated: read as truncated"), "warned: {err}");
    assert!(!err.contains("invalid episodes"), "{err}");
}

#[test]
fn a_partial_spec_of_a_built_in_env_is_completed_from_its_spec() {
    let dir = tmp("partial");
    let log = dir.join("log.parquet");
    ok(&bin().args(["dataset", "cartpole", "--episodes", "180", "--seed", "2", "--out"]).arg(&log).output().unwrap());
    let spec = dir.join("mine.json");
    std::fs::write(&spec, serde_json::json!({"env": {"name": "cartpole"}, "data": {"file": log}}).to_string()).unwrap();
    let o = bin().args(["search", spec.to_str().unwrap(), "--dry-run"]).output().unwrap();
    ok(&o);
    let out = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value = serde_json::from_str(&out[out.find('{').unwrap()..]).unwrap();
    let thesis: serde_json::Value = json("searches/cartpole.json");
    assert_eq!(v["seed"], thesis["seed"]);
    for k in ["hidden", "max_epochs", "batch_size", "learning_rate"] {
        assert_eq!(v["search"]["network"][k], thesis["search"]["network"][k], "the cart-pole spec's search: {k}");
    }
    assert_eq!(v["data"]["episodes"], 180);
    // However many datasets the spec asks, each gets 4 episodes or more: fewer are asked if need be.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("holds 180 episodes: dealt to"), "{err}");
    assert!(v["search"]["episodes"].as_u64().unwrap() >= 4, "{}", v["search"]);
    // A simulator's dataset still needs its size.
    let o = bin().args(["dataset", "cartpole", "--out"]).arg(dir.join("x.csv")).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--episodes is needed"));
}
