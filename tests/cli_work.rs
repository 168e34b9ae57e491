//! `bfqi-ga work`: the committed cart-pole search's work recomputed here from its unit files and
//! its datasets (written by `bfqi-ga dataset`), independently of the library's counting.

mod common;
use common::{bin, copy_dir, empty_dir, fresh, json, read};

use serde_json::Value;
use std::path::{Path, PathBuf};

fn cartpole() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results/searches/cartpole")
}

fn work(dir: &Path) -> Value {
    let o = bin().args(["work", "--json"]).arg(dir).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Rows per action (0 and 1) of search dataset `d`, counted in the CSV `bfqi-ga dataset` writes.
fn rows_per_action(spec: &Value, d: usize, tmp: &Path) -> [usize; 2] {
    let out = tmp.join(format!("d{d}.csv"));
    let o = bin()
        .args(["dataset", "cartpole", "--role", "search"])
        .args(["--seed", &spec["seed"].to_string(), "--index", &d.to_string()])
        .args(["--episodes", &spec["search"]["episodes"].to_string(), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = read(&out);
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "action").unwrap();
    let mut rows = [0; 2];
    for l in lines {
        rows[l.split(',').nth(col).unwrap().parse::<usize>().unwrap()] += 1;
    }
    rows
}

/// One epoch's FLOPs of the 4 → 10 → 10 → 1 network on `n` rows, 10 % held out, written out here:
/// 2 per multiply-add forward on every row and backward (weights and the hidden deltas) on the
/// training rows, plus each hidden unit's activation (forward, backward) per row.
fn epoch_flops(n: usize, activation: &str) -> f64 {
    let t = (n as f64 * 0.9).floor();
    let v = n as f64 - t;
    let forward = (4 * 10 + 10 * 10 + 10) as f64;
    let deltas = (10 * 10 + 10) as f64;
    let (f, b) = match activation {
        "sigmoid" => (40.0, 3.0),
        "tanh" => (36.0, 3.0),
        _ => (1.0, 1.0),
    };
    2.0 * (forward * (t + v) + (forward + deltas) * t) + 20.0 * (f * (t + v) + b * t)
}

#[test]
fn the_committed_cartpole_search_work_is_its_units_epochs_times_their_rows() {
    let dir = cartpole();
    let spec = json(dir.join("spec.json"));
    assert_eq!(spec["search"]["network"]["hidden"], serde_json::json!([10, 10]));
    assert_eq!(spec["search"]["network"]["validation_fraction"], 0.1);
    assert_eq!(spec["search"]["actions"], "per_action");
    // The search units alone: a copy without validation/ (whose datasets `dataset` does not offer).
    let copy = fresh("work", "cartpole");
    std::fs::create_dir_all(&copy).unwrap();
    for f in ["spec.json", "run.json", "state.json"] {
        std::fs::copy(dir.join(f), copy.join(f)).unwrap();
    }
    copy_dir(&dir.join("units"), &copy.join("units"));
    let tmp = empty_dir("work", "datasets");
    let rows: Vec<[usize; 2]> =
        (0..spec["search"]["datasets"].as_u64().unwrap() as usize).map(|d| rows_per_action(&spec, d, &tmp)).collect();
    let (mut units, mut epochs, mut epoch_rows, mut flops) = (0usize, 0u64, 0u64, [0.0f64; 3]);
    for e in std::fs::read_dir(dir.join("units")).unwrap() {
        let u = json(e.unwrap().path());
        let d = u["dataset"].as_u64().unwrap() as usize;
        let act = u["setting"]["activation"].as_str().unwrap();
        let a = ["sigmoid", "tanh", "relu"].iter().position(|x| *x == act).unwrap();
        units += 1;
        for it in u["iterations"].as_array().unwrap() {
            let nets = it["networks"].as_array().unwrap();
            assert_eq!(nets.len(), 2, "one network per action");
            for (j, n) in nets.iter().enumerate() {
                let e = n["epochs"].as_u64().unwrap();
                epochs += e;
                epoch_rows += e * rows[d][j] as u64;
                flops[a] += e as f64 * epoch_flops(rows[d][j], act);
            }
        }
    }
    let w = work(&copy);
    assert_eq!(w["kind"], "search");
    assert_eq!(w["units"].as_u64().unwrap() as usize, units);
    assert_eq!(w["tree_units"], 0);
    assert_eq!(w["epochs"].as_u64().unwrap(), epochs);
    assert_eq!(w["epoch_rows"].as_u64().unwrap(), epoch_rows);
    let total: f64 = flops.iter().sum();
    let got = w["flops"].as_f64().unwrap();
    assert!((got - total).abs() <= 1e-9 * total, "flops {got} against {total}");
    // Priced at the committed reference machine's rates, each activation at its own, on its cores.
    let r = json(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("searches/reference-machine.json"));
    let pct = &r["percent_of_peak"]["cartpole"];
    let peak = r["peak_gflops_per_core"].as_f64().unwrap() * 1e9;
    let core_s: f64 =
        ["sigmoid", "tanh", "relu"].iter().zip(flops).map(|(a, f)| f / (peak * pct[a].as_f64().unwrap() / 100.0)).sum();
    let hours = core_s / r["cores"].as_f64().unwrap() / 3600.0;
    let got = w["reference_hours"].as_f64().unwrap();
    assert!((got - hours).abs() <= 1e-9 * hours, "reference hours {got} against {hours}");
    assert_eq!(w["reference"], r["name"]);
    // Its wall time is the generations' seconds state.json records.
    let st = json(dir.join("state.json"));
    let wall: f64 = st["generation_seconds"].as_array().unwrap().iter().map(|s| s.as_f64().unwrap()).sum();
    assert!((w["wall_seconds"].as_f64().unwrap() - wall).abs() < 1e-6);

    // The whole run adds its validation units.
    let all = work(&dir);
    let validation = std::fs::read_dir(dir.join("validation")).unwrap().count();
    assert_eq!(all["units"].as_u64().unwrap() as usize, units + validation);
    assert!(all["epoch_rows"].as_u64().unwrap() > epoch_rows);
    // The committed work.json, which `status` reads, is that count.
    assert_eq!(json(dir.join("work.json")), all, "results/searches/cartpole/work.json is stale");
}

#[test]
fn work_of_a_folder_that_is_no_run_is_refused_in_one_line() {
    let d = empty_dir("work", "nothing");
    let o = bin().arg("work").arg(d.path()).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains(d.str()) && err.contains("no compare.json or spec.json"), "{err}");
}

#[test]
fn a_batch_works_the_sum_of_its_jobs_and_its_summary_and_status_say_so() {
    let d = empty_dir("work", "batch");
    let search = r#"{"name": "s", "search": "cartpole", "presets": ["quick"], "episodes": 25, "datasets": 2, "iterations": 2, "population": 4, "generations": 2, "seed": 4}"#;
    let compare = r#"{"name": "c", "compare": "cartpole", "tuned": "from:s", "learner": "both", "datasets": 2, "episodes": 30, "iterations": 2}"#;
    let plan = d.join("plan.json");
    std::fs::write(&plan, format!("{{\"jobs\": [{search}, {compare}]}}")).unwrap();
    let out = d.join("b");
    let o = bin().arg("batch").arg(&plan).arg("--out").arg(&out).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (s, c, b) = (work(&out.join("s")), work(&out.join("c")), work(&out));
    assert_eq!(b["kind"], "batch");
    assert!(s["units"].as_u64().unwrap() > 0 && c["units"].as_u64().unwrap() > 0);
    // The comparison's Extra-Trees units run no epochs: counted apart.
    assert!(c["tree_units"].as_u64().unwrap() > 0, "{c}");
    for k in ["units", "tree_units", "epochs", "epoch_rows"] {
        assert_eq!(b[k].as_u64().unwrap(), s[k].as_u64().unwrap() + c[k].as_u64().unwrap(), "{k}");
    }
    let hours = s["reference_hours"].as_f64().unwrap() + c["reference_hours"].as_f64().unwrap();
    assert!((b["reference_hours"].as_f64().unwrap() - hours).abs() <= 1e-12 + 1e-9 * hours);
    let jobs = json(out.join("batch.json"));
    let wall: f64 = jobs.as_array().unwrap().iter().map(|j| j["seconds"].as_f64().unwrap()).sum();
    assert!((b["wall_seconds"].as_f64().unwrap() - wall).abs() < 1e-9);

    // Each report wrote the same figures to its run's work.json (report.md is left as it was).
    for (dir, w) in [(out.join("s"), &s), (out.join("c"), &c), (out.clone(), &b)] {
        let stored = json(dir.join("work.json"));
        for k in ["kind", "units", "tree_units", "epochs", "epoch_rows", "flops"] {
            assert_eq!(stored[k], w[k], "{}: {k}", dir.display());
        }
    }
    assert!(!read(out.join("s/report.md")).contains("epoch-rows"));

    let summary = read(out.join("summary.md"));
    let row = summary.lines().find(|l| l.starts_with("| s |")).unwrap_or_else(|| panic!("{summary}"));
    assert!(row.contains(&format!("{:.2} ref. h", s["reference_hours"].as_f64().unwrap())), "{row}");
    assert!(summary.contains(&format!("**{hours:.2} ref. h**")), "{summary}");
    let st = bin().arg("status").arg(&out).output().unwrap();
    let text = String::from_utf8_lossy(&st.stdout);
    assert_eq!(text.lines().filter(|l| l.contains(" · work ") && l.contains("epoch-rows")).count(), 2, "{text}");

    // `status` reads a run's work.json while nothing it counts from has changed since (counting
    // again rebuilds every dataset), and counts again once a unit is added or removed.
    let mut stored = json(out.join("s/work.json"));
    stored["epoch_rows"] = serde_json::json!(123_456_789_000u64);
    std::fs::write(out.join("s/work.json"), stored.to_string()).unwrap();
    let st = |dir: &Path| String::from_utf8_lossy(&bin().arg("status").arg(dir).output().unwrap().stdout).into_owned();
    let cached = st(&out.join("s"));
    assert!(cached.contains("123.46 G epoch-rows"), "status reads work.json: {cached}");
    let unit = std::fs::read_dir(out.join("s/units")).unwrap().next().unwrap().unwrap().path();
    let bytes = std::fs::read(&unit).unwrap();
    std::fs::remove_file(&unit).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::write(&unit, bytes).unwrap();
    let counted = st(&out.join("s"));
    assert!(!counted.contains("123.46 G epoch-rows"), "a unit folder newer than work.json is counted again: {counted}");
}
