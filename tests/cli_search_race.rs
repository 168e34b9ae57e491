//! Racing inside the search (`search.race`, beyond the thesis) end to end: decisions recorded per
//! individual, elites never stopped, the same search on any thread count and after `kill -9` and
//! resumes, and the decisions in the report, `status` and the dashboard's JSON.

mod common;
use common::{TempDir, bin, fresh, http_get, json, read, spawn_quiet, tiny_with, wait_for_entries};

use bfqi_ga::dashboard::{Dashboard, Options};

use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    fresh("search-race", name)
}

/// Cart-pole's spec with a race a tiny search can decide: a signed-rank test at 80 % (2⁻³ = 0.125
/// is its first p-value below 0.2) from the 3rd of 4 datasets.
fn spec_file(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut v: serde_json::Value = json("searches/cartpole.json");
    v["search"]["race"] = serde_json::json!({"test": "wilcoxon", "confidence": 0.8, "first": 3});
    let p = dir.join("race.json");
    std::fs::write(&p, v.to_string()).unwrap();
    p
}

const ARGS: [&str; 10] =
    ["--datasets", "4", "--generations", "4", "--population", "8", "--seed", "3", "--episodes", "40"];

fn search(spec: &Path, dir: &Path, extra: &[&str]) -> Output {
    bin()
        .args(["search", spec.to_str().unwrap(), "--out", dir.to_str().unwrap()])
        .args(tiny_with(&[&ARGS[..], extra].concat()))
        .output()
        .unwrap()
}

fn generations(dir: &Path) -> Vec<serde_json::Value> {
    read(dir.join("generations.jsonl")).lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

const OUTPUTS: [&str; 4] = ["generations.jsonl", "best.json", "hall_of_fame.json", "fitness.csv"];

#[test]
fn racing_records_its_decisions_never_stops_an_elite_and_is_deterministic() {
    let base = tmp("det");
    let spec = spec_file(&base);
    let a = base.join("jobs1");
    let o = search(&spec, &a, &["--jobs", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let gens = generations(&a);
    assert_eq!(gens.len(), 4);
    assert!(gens[0].get("race_against").is_none(), "generation 0 has no elites and is not raced");
    let (mut out, mut survived) = (0, 0);
    for (g, next) in gens.iter().zip(gens.iter().skip(1).map(Some).chain([None])) {
        let ind = g["individuals"].as_array().unwrap();
        let against: Vec<&str> =
            g["race_against"].as_array().map_or(vec![], |a| a.iter().map(|s| s.as_str().unwrap()).collect());
        let stopped: Vec<&serde_json::Value> = ind.iter().filter(|i| i["race"]["stopped"] == true).collect();
        assert_eq!(g["stats"]["raced"].as_u64().unwrap_or(0) as usize, stopped.len());
        for i in ind {
            if i["origin"] == "elite" || against.contains(&i["setting"].as_str().unwrap()) {
                assert!(i.get("race").is_none(), "an elite's setting was raced: {i}");
            }
        }
        for i in ind.iter().filter(|i| i.get("race").is_some()) {
            let r = &i["race"];
            let n = r["datasets"].as_u64().unwrap() as usize;
            assert!(!against.is_empty());
            if r["stopped"] == true {
                out += 1;
                // Stopped no sooner than the signed-rank test can decide (3 datasets at 80 %).
                assert_eq!(i["scores"].as_array().unwrap().len(), n);
                assert!((3..=4).contains(&n) && r["p"].as_f64().unwrap() < 0.2, "{i}");
                assert!(i["fitness"].is_null());
                if let Some(next) = next {
                    let elites = next["individuals"].as_array().unwrap().iter().filter(|e| e["origin"] == "elite");
                    assert!(elites.into_iter().all(|e| e["setting"] != i["setting"]), "raced out, then an elite: {i}");
                }
            } else {
                survived += 1;
                assert!(r["p"].as_f64().unwrap() >= 0.2 && n == 4, "{i}");
            }
        }
    }
    assert!(
        out > 0 && survived > 0,
        "the test needs a seed that races some out and keeps some: {out} out, {survived} kept"
    );

    // One thread or three: the same decisions and the same search.
    let b = base.join("jobs3");
    let o = search(&spec, &b, &["--jobs", "3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in OUTPUTS {
        assert_eq!(read(a.join(f)), read(b.join(f)), "{f} differs between 1 and 3 threads");
    }

    // The decisions are in the report, status and the dashboard's search page.
    let report = read(a.join("report.md"));
    assert!(
        report.contains("## Racing (beyond the thesis)")
            && report.contains(&format!("{out} individuals were raced out"))
    );
    assert!(report.contains("stopped after 3 datasets: p=0.125"), "{report}");
    let st = bin().arg("status").arg(&a).output().unwrap();
    let line = String::from_utf8_lossy(&st.stdout);
    assert!(line.contains(&format!("racing (wilcoxon 80 %): {out} of {} raced out", out + survived)), "{line}");

    // The dashboard's search page: a Racing table titled with the count, a row per raced individual.
    let d = Dashboard::bind(&Options { roots: vec![base.to_path_buf()], host: "127.0.0.1".into(), port: 0 }).unwrap();
    let (url, stopper) = (d.url().to_string(), d.stopper());
    let server = std::thread::spawn(move || d.run());
    let page: serde_json::Value = serde_json::from_str(&http_get(&url, "/run/0/jobs1?json=1").body).unwrap();
    stopper();
    server.join().unwrap();
    let t = page["tables"].as_array().unwrap().iter().find(|t| t["name"] == "racing").expect("a racing table");
    assert!(t["title"].as_str().unwrap().contains(&format!("{out} of {} raced individuals raced out", out + survived)));
    assert_eq!(t["rows"].as_array().unwrap().len(), out + survived);
    assert!(t.to_string().contains("stopped after "), "{t}");

    // Killed mid-search (SIGKILL) and resumed, then stopped again and again by a tiny time
    // budget: the same decisions and the same search.
    let k = base.join("killed");
    let mut child = spawn_quiet(
        bin().args(["search", spec.to_str().unwrap(), "--out", k.to_str().unwrap()]).args(tiny_with(&ARGS)),
    );
    wait_for_entries(&k.join("units"), 40, &mut child);
    child.kill().unwrap();
    child.wait().unwrap();
    // A budget that has run out before the first unit stops a resume whatever the machine's speed
    // (how many units the tiny budget below lets through does: a fast machine may finish at once).
    let o =
        bin().args(["search", "--resume", k.to_str().unwrap(), "--quiet", "--max-hours", "1e-300"]).output().unwrap();
    assert!(o.status.success() && String::from_utf8_lossy(&o.stderr).contains("time budget"), "{o:?}");
    assert_eq!(json(k.join("state.json"))["state"], "interrupted");
    let mut stops = 1;
    while !read(k.join("state.json")).contains("\"finished\"") {
        stops += 1;
        assert!(stops < 500, "never finished");
        let o = bin()
            .args(["search", "--resume", k.to_str().unwrap(), "--quiet", "--max-hours", "0.00008"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    for f in OUTPUTS {
        assert_eq!(read(a.join(f)), read(k.join(f)), "{f} differs after a kill and {stops} resumes");
    }
}

#[test]
fn a_race_the_datasets_cannot_hold_is_refused_naming_the_field() {
    let base = tmp("bad");
    let spec = spec_file(&base);
    // The quick preset's 3 datasets hold a first test at dataset 3, not at 5.
    let mut v: serde_json::Value = json(&spec);
    v["search"]["race"]["first"] = 5.into();
    std::fs::write(&spec, v.to_string()).unwrap();
    let o = bin().args(["search", spec.to_str().unwrap(), "--quick", "--dry-run"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("search.race.first") && err.contains("2..=3") && err.lines().count() == 1, "{err}");
    // Racing and pruning both on: refused.
    let o = bin().args(["search", "cartpole", "--preset", "race-search", "--prune", "--dry-run"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("search.race") && err.contains("prune.enabled"), "{err}");
    // The preset on the full spec resolves, with the rule as shipped.
    let o = bin().args(["search", "cartpole", "--preset", "race-search", "--dry-run"]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("\"race\"") && out.contains("wilcoxon"), "{out}");
}
