//! The raced validation and `search.select` end to end (both beyond the thesis, opt-in): a race
//! ends the same on any thread count and after a kill and a resume, `select: validated` puts the
//! validated winner in best.json for every consumer, and an explicit `select: fitness` changes
//! nothing.

mod common;
use common::{TempDir, bin, empty_dir, json, read, spawn_quiet, tiny_with, wait_for_entries};

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    empty_dir("race", name)
}

/// A preset file in `dir` holding `search` as its `search` object.
fn preset(dir: &Path, name: &str, search: Value) -> PathBuf {
    let p = dir.join(format!("{name}.json"));
    std::fs::write(&p, serde_json::json!({ "search": search }).to_string()).unwrap();
    p
}

/// The top 3 raced on up to 6 validation datasets, 2 at a time.
fn race() -> Value {
    serde_json::json!({"top": 3, "datasets": 6, "race": {"first": 2, "step": 2, "confidence": 0.95}})
}

/// The tiny search into `dir/run`, with presets and flags.
fn search(dir: &Path, presets: &[&Path], extra: &[&str]) -> Output {
    let mut c = bin();
    c.args(["search", "cartpole", "--out"]).arg(dir.join("run")).args(tiny_with(extra));
    for p in presets {
        c.arg("--preset").arg(p);
    }
    c.output().unwrap()
}

fn ok(o: &Output) {
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
}

const RESULTS: [&str; 6] =
    ["generations.jsonl", "hall_of_fame.json", "validation.json", "best.json", "report.md", "fitness.csv"];

fn same_results(a: &Path, b: &Path, what: &str) {
    // report.md's standing line gives the wall time and the machine and threads of each
    // invocation, which differ from run to run by design; every other line must not.
    let results = |f: &str, dir: &Path| {
        let text = read(dir.join(f));
        if f == "report.md" {
            text.lines().filter(|l| !l.contains("Wall time")).collect::<Vec<_>>().join("\n")
        } else {
            text
        }
    };
    for f in RESULTS {
        assert_eq!(results(f, a), results(f, b), "{f} differs: {what}");
    }
}

#[test]
fn a_race_is_recorded_and_ends_the_same_on_any_thread_count_and_after_kill_and_resume() {
    let d = tmp("deterministic");
    let p = preset(d.path(), "race", serde_json::json!({ "validate": race() }));
    let (one, two) = (d.path().join("one"), d.path().join("two"));
    std::fs::create_dir_all(&one).unwrap();
    std::fs::create_dir_all(&two).unwrap();
    ok(&search(&one, &[&p], &["--jobs", "1"]));
    ok(&search(&two, &[&p], &["--jobs", "2"]));
    let (one, two) = (one.join("run"), two.join("run"));
    same_results(&one, &two, "1 and 2 threads");

    let v: Value = json(one.join("validation.json"));
    let rounds = v["rounds"].as_array().expect("validation.json records the rounds");
    assert!(!rounds.is_empty(), "{v}");
    let mut prev = 0;
    for (i, r) in rounds.iter().enumerate() {
        let n = r["datasets"].as_u64().unwrap();
        assert_eq!(n, [2, 4, 6][i], "round {} has {n} datasets", i + 1);
        assert!(n > prev);
        prev = n;
        let leader = r["leader"].as_str().unwrap();
        let lead = r["standings"].as_array().unwrap().iter().find(|s| s["setting"] == leader).unwrap();
        assert_eq!(lead["verdict"], "leader", "{r}");
    }
    // Every dropped setting stops getting datasets; survivors have the last round's count.
    let last = rounds.last().unwrap();
    let end = v["race_end"].as_str().unwrap();
    assert!(end == "separated" || end == "budget", "{end}");
    let survivors = last["standings"].as_array().unwrap().iter().filter(|s| s["verdict"] != "dropped").count();
    assert_eq!(end == "separated", survivors == 1, "{v}");
    let stored = std::fs::read_dir(one.join("validation")).unwrap().count();
    assert!(stored <= 4 * 6, "{stored} validation units");
    for e in v["entries"].as_array().unwrap() {
        let n = e["validation_scores"].as_array().unwrap().len();
        assert!(n % 2 == 0 && (2..=6).contains(&n), "{e}");
    }
    assert!(read(one.join("report.md")).contains("### Race"));
    let st = bin().arg("status").arg(&one).output().unwrap();
    assert!(String::from_utf8_lossy(&st.stdout).contains("race"), "{}", String::from_utf8_lossy(&st.stdout));

    // Units lost to a kill (some of the race's, the record): resuming replays the stored rounds and
    // computes only what is missing, to the same result.
    let lost = d.path().join("lost");
    common::copy_dir(&one, &lost);
    let mut units: Vec<PathBuf> =
        std::fs::read_dir(lost.join("validation")).unwrap().map(|e| e.unwrap().path()).collect();
    units.sort();
    for u in units.iter().step_by(3) {
        std::fs::remove_file(u).unwrap();
    }
    std::fs::remove_file(lost.join("validation.json")).unwrap();
    ok(&bin().args(["search", "--resume"]).arg(&lost).arg("--quiet").output().unwrap());
    same_results(&one, &lost, "units deleted and resumed");

    // A real SIGKILL during the validation, then a resume.
    let killed = d.path().join("killed");
    let mut child = spawn_quiet(
        bin()
            .args(["search", "cartpole", "--out"])
            .arg(&killed)
            .args(tiny_with(&["--jobs", "1"]))
            .arg("--preset")
            .arg(&p),
    );
    wait_for_entries(&killed.join("validation"), 2, &mut child);
    child.kill().ok(); // SIGKILL (a no-op if it already ended)
    let status = child.wait().unwrap();
    assert!(status.code().is_none(), "the search ended ({status}) before it could be killed mid-validation");
    assert!(!killed.join("validation.json").exists(), "killed before the race's record was written");
    ok(&bin().args(["search", "--resume"]).arg(&killed).arg("--quiet").output().unwrap());
    same_results(&one, &killed, "killed during the validation and resumed");
}

#[test]
fn select_validated_puts_the_validated_winner_in_best_json_for_every_consumer() {
    let d = tmp("validated");
    let p = preset(d.path(), "select", serde_json::json!({ "validate": race(), "select": "validated" }));
    // Seed 4: the tiny search whose race leader is not its best fitness, so both winners show.
    ok(&search(d.path(), &[&p], &["--jobs", "2", "--seed", "4"]));
    let run = d.path().join("run");
    let v: Value = json(run.join("validation.json"));
    let best: Value = json(run.join("best.json"));
    let winner = v["rounds"].as_array().unwrap().last().unwrap()["leader"].as_str().unwrap().to_string();
    let first = v["entries"].as_array().unwrap().iter().find(|e| e["source"] == "hall of fame 1").unwrap();
    let sel = &best["selection"];
    assert_eq!(sel["select"], "validated", "{best}");
    assert_eq!(sel["validated"], winner.as_str());
    assert_eq!(sel["fitness"], first["setting"], "best.json records the fitness winner too: {best}");
    assert_ne!(sel["validated"], sel["fitness"], "seed 4's winners differ: {best}");
    let others: Vec<&str> = sel["indistinguishable"].as_array().unwrap().iter().map(|s| s.as_str().unwrap()).collect();
    assert!(others.contains(&first["setting"].as_str().unwrap()), "the fitness winner is tied with the leader here");
    let entry = v["entries"].as_array().unwrap().iter().find(|e| e["setting"] == winner.as_str()).unwrap();
    for g in ["activation", "delta_min", "patience"] {
        assert_eq!(best[g], entry[g], "best.json's {g} is the validated winner's");
    }
    assert_eq!(best["validation"]["scores"], entry["validation_scores"]);
    let report = read(run.join("report.md"));
    assert!(report.contains("search.select: validated"), "the report says which rule chose");
    assert!(report.contains("**The two winners differ**"), "{report}");
    for o in &others {
        assert!(report.contains(&format!("`{o}`")), "the report lists {o} as indistinguishable");
    }

    let st = bin().arg("status").arg(&run).output().unwrap();
    let st = String::from_utf8_lossy(&st.stdout);
    assert!(st.contains(&format!("best.json holds the validated winner {winner}")), "{st}");

    // Every consumer takes it: reproduce, fitness, rollout and compare --tuned.
    let best_path = run.join("best.json");
    let r = bin().arg("reproduce").arg(&best_path).output().unwrap();
    assert_eq!(
        r.status.code(),
        Some(0),
        "{}{}",
        String::from_utf8_lossy(&r.stdout),
        String::from_utf8_lossy(&r.stderr)
    );
    let f =
        bin().arg("fitness").arg(run.join("spec.json")).arg("--tuned").arg(&best_path).arg("--json").output().unwrap();
    ok(&f);
    let fit: Value = serde_json::from_slice(&f.stdout).unwrap();
    assert_eq!(fit["fitness"], entry["fitness"], "fitness re-scores the validated winner: {fit}");
    let out = d.path().join("rollout");
    ok(&bin()
        .args(["rollout", "--tuned"])
        .arg(&best_path)
        .args(["--episodes", "1", "--out"])
        .arg(&out)
        .output()
        .unwrap());
    assert!(out.join("trajectory.csv").is_file() || std::fs::read_dir(&out).unwrap().count() > 0);
    let cmp = d.path().join("compare");
    ok(&bin()
        .args(["compare", "cartpole", "--tuned"])
        .arg(&best_path)
        .args(["--analysis", "iterations", "--learner", "mlp", "--datasets", "1", "--iterations", "2"])
        .args(["--episodes", "20", "--quiet", "--out"])
        .arg(&cmp)
        .output()
        .unwrap());
    let c = read(cmp.join("compare.json"));
    assert!(c.contains(&format!("{}", entry["delta_min"])), "compare ran the validated winner: {c}");
}

#[test]
fn an_explicit_select_fitness_changes_nothing() {
    let d = tmp("explicit");
    let p = preset(d.path(), "fitness", serde_json::json!({ "select": "fitness" }));
    let (a, b) = (d.path().join("absent"), d.path().join("explicit"));
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    ok(&search(&a, &[], &[]));
    ok(&search(&b, &[&p], &[]));
    let (a, b) = (a.join("run"), b.join("run"));
    same_results(&a, &b, "select absent and select: fitness");
    assert_eq!(read(a.join("spec.json")), read(b.join("spec.json")));
    assert!(!read(a.join("best.json")).contains("selection"), "the thesis's rule adds no field to best.json");
}

/// Every regular file under `dir`, by path relative to it, with its bytes.
fn snapshot(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else {
                out.insert(p.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

#[test]
fn validate_into_races_a_finished_search_apart_and_leaves_its_files_as_they_are() {
    let d = tmp("into");
    // The search validates by its spec's rule (no race); the same search raced in-run is the
    // reference the validation kept apart must equal.
    ok(&search(d.path(), &[], &["--jobs", "2", "--seed", "4"]));
    let run = d.path().join("run");
    let raced_dir = d.path().join("raced");
    std::fs::create_dir_all(&raced_dir).unwrap();
    let p = preset(d.path(), "select", serde_json::json!({ "validate": race(), "select": "validated" }));
    ok(&search(&raced_dir, &[&p], &["--jobs", "2", "--seed", "4"]));
    let before = snapshot(&run);

    let apart = d.path().join("apart");
    let validate = |jobs: &str| {
        bin()
            .arg("validate")
            .arg(&run)
            .args(["--top", "3", "--datasets", "6", "--race-first", "2", "--race-step", "2", "--select", "validated"])
            .args(["--jobs", jobs, "--quiet", "--into"])
            .arg(&apart)
            .output()
            .unwrap()
    };
    ok(&validate("2"));
    assert!(before == snapshot(&run), "validate --into wrote into the search it validated");

    let v: Value = json(apart.join("validation.json"));
    let mut reference: Value = json(raced_dir.join("run").join("validation.json"));
    assert_eq!(v["source"], run.display().to_string(), "validation.json names the search it read");
    reference["source"] = v["source"].clone();
    assert_eq!(v, reference, "the race run apart equals the same race run inside the search");
    let best: Value = json(apart.join("best.json"));
    let winner = v["rounds"].as_array().unwrap().last().unwrap()["leader"].as_str().unwrap();
    assert_eq!(best["selection"]["select"], "validated", "{best}");
    assert_eq!(best["selection"]["validated"], winner);
    assert_eq!(best, json(raced_dir.join("run").join("best.json")), "best.json as select: validated gives");
    let r = bin().arg("reproduce").arg(apart.join("best.json")).output().unwrap();
    assert_eq!(r.status.code(), Some(0), "{}", String::from_utf8_lossy(&r.stdout));
    let report = read(apart.join("report.md"));
    assert!(report.contains(&format!("# Validation of `{}`", run.display())), "{report}");
    assert!(report.contains("### Race") && report.contains("search.select: validated"), "{report}");
    // `report` rebuilds the report of a validation kept apart from its records.
    std::fs::remove_file(apart.join("report.md")).unwrap();
    ok(&bin().arg("report").arg(&apart).output().unwrap());
    assert_eq!(report, read(apart.join("report.md")));
    // Units the search already had are read, not recomputed: only the race's missing ones are here.
    let stored = |dir: &Path| std::fs::read_dir(dir.join("validation")).map_or(0, |r| r.count());
    assert!(stored(&apart) + stored(&run) >= stored(&raced_dir.join("run")));

    // Again, on one thread: nothing new is computed and the result is the same.
    let units = snapshot(&apart.join("validation"));
    ok(&validate("1"));
    assert_eq!(units, snapshot(&apart.join("validation")));
    assert_eq!(v, json(apart.join("validation.json")));
    assert!(before == snapshot(&run));

    // Refused before anything is computed: a winner rule with nowhere to keep it apart, and a
    // validation apart on Slurm (whose tasks find a unit's spec in the run directory).
    let o = bin().arg("validate").arg(&run).args(["--select", "validated"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let o = bin()
        .arg("validate")
        .arg(&run)
        .args(["--executor", "slurm", "--into"])
        .arg(d.path().join("slurm"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--into"));
    assert!(!d.path().join("slurm").exists());
    assert!(before == snapshot(&run));
}

#[test]
fn a_raced_search_that_took_units_counts_only_those_its_individuals_used() {
    // The full search's store holds every dataset of each setting; a raced-out individual of the
    // search that takes them uses only its first datasets, and `new_units` (generations.jsonl,
    // status, the baseline report) counts what was used, as report.md's `new units` does.
    let d = tmp("taken-new-units");
    let wide = ["--datasets", "8", "--generations", "4", "--population", "8", "--seed", "3"];
    let full = d.path().join("full");
    ok(&bin().args(["search", "cartpole", "--out"]).arg(&full).args(tiny_with(&wide)).output().unwrap());
    let raced = d.path().join("raced");
    // The race-search preset's rule, on the 8 datasets (the quick preset has 3, too few for it).
    let race = serde_json::json!({"datasets": 8, "race": {"test": "wilcoxon", "confidence": 0.95, "first": 5}});
    let p = preset(d.path(), "race8", race);
    let mut c = bin();
    c.args(["search", "cartpole", "--out"]).arg(&raced).args(tiny_with(&wide));
    ok(&c.arg("--preset").arg(&p).arg("--units-from").arg(&full).output().unwrap());
    let generations: Vec<Value> =
        read(raced.join("generations.jsonl")).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let mut seen = std::collections::HashSet::new();
    let mut short = 0;
    for g in &generations {
        let mut new = 0;
        for i in g["individuals"].as_array().unwrap() {
            let n = i["scores"].as_array().unwrap().len();
            short += usize::from(n < 8);
            for k in 0..n {
                new += usize::from(seen.insert(format!("{}.d{k}", i["setting"].as_str().unwrap())));
            }
        }
        assert_eq!(g["new_units"].as_u64().unwrap() as usize, new, "generation {}", g["generation"]);
    }
    assert!(short > 0, "no individual was raced out: the check would not see the difference");
    let report = read(raced.join("report.md"));
    for g in &generations {
        let row = format!("| {} | {} |", g["generation"], g["new_units"]);
        assert!(report.contains(&row), "{row} not in the report");
    }
}
