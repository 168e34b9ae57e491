//! `bfqi-ga search`, `reproduce` and `status` end to end.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_bfqi-ga"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bfqi-search-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// A tiny but real search: cart-pole, small datasets, 4 individuals, 2 generations.
const TINY: [&str; 14] = [
    "--quick",
    "--episodes",
    "25",
    "--datasets",
    "2",
    "--iterations",
    "2",
    "--population",
    "4",
    "--generations",
    "2",
    "--seed",
    "5",
    "--quiet",
];

/// TINY with the flags in `extra` replacing its own (`--flag value` pairs, or lone switches).
fn args_with(extra: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = TINY.iter().map(|s| s.to_string()).collect();
    let mut i = 0;
    while i < extra.len() {
        let takes_value = i + 1 < extra.len() && !extra[i + 1].starts_with("--");
        if let Some(p) = args.iter().position(|a| a == extra[i]) {
            if takes_value {
                args[p + 1] = extra[i + 1].to_string();
            }
        } else {
            args.push(extra[i].to_string());
            if takes_value {
                args.push(extra[i + 1].to_string());
            }
        }
        i += if takes_value { 2 } else { 1 };
    }
    args
}

fn search(dir: &Path, extra: &[&str]) -> Output {
    bin().args(["search", "cartpole", "--out", dir.to_str().unwrap()]).args(args_with(extra)).output().unwrap()
}

fn read(p: PathBuf) -> String {
    std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn one_and_two_threads_give_identical_results_and_reproduce_confirms() {
    let (a, b) = (tmp("j1"), tmp("j2"));
    let oa = search(&a, &["--jobs", "1"]);
    assert!(oa.status.success(), "{}", String::from_utf8_lossy(&oa.stderr));
    let ob = search(&b, &["--jobs", "2"]);
    assert!(ob.status.success(), "{}", String::from_utf8_lossy(&ob.stderr));
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json", "fitness.csv"] {
        assert_eq!(read(a.join(f)), read(b.join(f)), "{f} differs between 1 and 2 threads");
    }
    let gens: Vec<serde_json::Value> =
        read(a.join("generations.jsonl")).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(gens.len(), 2);
    assert_eq!(gens[0]["individuals"].as_array().unwrap().len(), 4);
    assert_eq!(gens[0]["individuals"][0]["scores"].as_array().unwrap().len(), 2);
    let best: serde_json::Value = serde_json::from_str(&read(a.join("best.json"))).unwrap();
    assert_eq!(best["source"], "search");
    assert_eq!(best["network"]["hidden"], serde_json::json!([10, 10]));
    for f in ["fitness.png", "fitness.svg", "spec.json", "run.json", "state.json"] {
        assert!(a.join(f).is_file(), "{f} missing");
    }
    let run: serde_json::Value = serde_json::from_str(&read(a.join("run.json"))).unwrap();
    assert_eq!(run["overrides"]["population"], 4, "overrides are recorded");

    let r = bin().arg("reproduce").arg(a.join("best.json")).output().unwrap();
    assert_eq!(r.status.code(), Some(0), "{}", String::from_utf8_lossy(&r.stdout));
    assert!(String::from_utf8_lossy(&r.stdout).contains("bit for bit"));
    // A tampered score is reported with its dataset, exit 1.
    let mut tampered = best.clone();
    tampered["scores"][1] = serde_json::json!(123.0);
    let tp = a.join("tampered.json");
    std::fs::write(&tp, serde_json::to_string(&tampered).unwrap()).unwrap();
    let r = bin().arg("reproduce").arg(&tp).output().unwrap();
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stdout).contains("dataset 1"));

    let s = bin().args(["status"]).arg(&a).output().unwrap();
    let line = String::from_utf8_lossy(&s.stdout);
    assert!(line.contains("cartpole") && line.contains("finished") && line.contains("gen   2/2"), "{line}");
}

#[test]
fn killed_mid_generation_and_resumed_ends_identical() {
    let (whole, killed) = (tmp("whole"), tmp("killed"));
    let slower = ["--episodes", "400", "--iterations", "4", "--datasets", "3", "--population", "6", "--jobs", "2"];
    let o = search(&whole, &slower);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let mut child = bin()
        .args(["search", "cartpole", "--out", killed.to_str().unwrap()])
        .args(args_with(&slower))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let units = killed.join("units");
    let t = Instant::now();
    loop {
        let n = std::fs::read_dir(&units).map(|d| d.count()).unwrap_or(0);
        if n >= 3 || t.elapsed() > Duration::from_secs(120) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let stored = std::fs::read_dir(&units).unwrap().count();
    assert!(stored < 6 * 3, "killed before the first generation finished ({stored} units stored)");

    let st = bin().arg("status").arg(&killed).output().unwrap();
    assert!(String::from_utf8_lossy(&st.stdout).contains("interrupted"));
    let r = bin().args(["search", "--resume", killed.to_str().unwrap(), "--quiet"]).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
        assert_eq!(read(whole.join(f)), read(killed.join(f)), "{f} differs after kill -9 and resume");
    }
}

#[test]
fn a_second_process_on_the_same_run_is_refused() {
    let dir = tmp("locked");
    assert!(search(&dir, &[]).status.success());
    // Pretend a live process (this test) holds the run.
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap();
    std::fs::write(dir.join("lock"), format!("{} {}", std::process::id(), host.trim())).unwrap();
    let o = bin().args(["search", "--resume", dir.to_str().unwrap(), "--quiet"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("in use by process"));
}

#[test]
fn malformed_specs_give_exit_2_and_a_one_line_message() {
    let dir = tmp("specs");
    std::fs::create_dir_all(&dir).unwrap();
    let base: serde_json::Value = serde_json::from_str(&read(PathBuf::from("searches/cartpole.json"))).unwrap();
    let cases: Vec<(&str, serde_json::Value, &str)> = vec![
        ("truncated", serde_json::Value::Null, "EOF"),
        (
            "type",
            {
                let mut v = base.clone();
                v["search"]["ga"]["population"] = "many".into();
                v
            },
            "search.ga.population",
        ),
        (
            "range",
            {
                let mut v = base.clone();
                v["search"]["ga"]["mutation"] = 1.5.into();
                v
            },
            "search.ga.mutation",
        ),
        (
            "unknown",
            {
                let mut v = base.clone();
                v["search"]["popsize"] = 3.into();
                v
            },
            "popsize",
        ),
        (
            "genes",
            {
                let mut v = base.clone();
                v["search"]["genes"]["b_delta"] = serde_json::json!([8, 2]);
                v
            },
            "search.genes.b_delta",
        ),
    ];
    for (name, v, needle) in cases {
        let p = dir.join(format!("{name}.json"));
        let text = if v.is_null() { "{\"env\": {\"name\": \"cartpole\"},".to_string() } else { v.to_string() };
        std::fs::write(&p, text).unwrap();
        let o = bin().args(["search", p.to_str().unwrap(), "--quiet"]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(p.to_str().unwrap()) && err.contains(needle), "{name}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{name}: {err}");
    }
}
