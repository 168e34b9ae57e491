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
    // Its units predate recorded rows: reading the copy does not collect datasets to count them,
    // and says what does.
    let o = bin().arg("work").arg(&copy).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("work not counted") && err.contains("--write"), "{err}");
    let o = bin().args(["work", "--json", "--write"]).arg(&copy).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let w: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(work(&copy), w, "what --write recorded, read back");
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

    // The whole run adds its validation units; counted afresh in a copy without its work.json, it
    // is the committed work.json, which reading the run (status, work, the dashboard) returns.
    let whole = fresh("work", "cartpole-whole");
    copy_dir(&dir, &whole);
    std::fs::remove_file(whole.join("work.json")).unwrap();
    let o = bin().args(["work", "--json", "--write"]).arg(&whole).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let all: Value = serde_json::from_slice(&o.stdout).unwrap();
    let validation = std::fs::read_dir(dir.join("validation")).unwrap().count();
    assert_eq!(all["units"].as_u64().unwrap() as usize, units + validation);
    assert!(all["epoch_rows"].as_u64().unwrap() > epoch_rows);
    assert_eq!(json(dir.join("work.json")), all, "results/searches/cartpole/work.json is stale");
    assert_eq!(work(&dir), all);
}

/// A `python3` on the PATH that leaves a mark when anything starts it.
fn marking_python(dir: &Path) -> (PathBuf, PathBuf) {
    use std::os::unix::fs::PermissionsExt;
    let bin_dir = dir.join("bin");
    std::fs::create_dir_all(&bin_dir).unwrap();
    let mark = dir.join("python-ran");
    for name in ["python3", "python"] {
        let p = bin_dir.join(name);
        std::fs::write(&p, format!("#!/bin/sh\necho \"$@\" >> '{}'\nexit 1\n", mark.display())).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    (bin_dir, mark)
}

#[test]
fn reading_a_minari_run_starts_no_process_and_needs_no_dataset() {
    // The committed Minari search, copied where its dataset is not, with a `python3` that marks.
    let d = empty_dir("work", "minari-read");
    let run = d.join("search");
    copy_dir(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results/minari/search"), &run);
    let (bin_dir, mark) = marking_python(&d);
    let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default());
    let committed = json(run.join("work.json"));
    let ask = |args: &[&str]| {
        let o = bin().args(args).env("PATH", &path).env("MINARI_DATASETS_PATH", d.join("nowhere")).output().unwrap();
        assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let w: Value = serde_json::from_str(&ask(&["work", "--json", run.to_str().unwrap()])).unwrap();
    assert_eq!(w, committed, "its work.json, read");
    let status = ask(&["status", run.to_str().unwrap()]);
    assert!(status.contains("epoch-rows"), "{status}");
    ask(&["export", run.to_str().unwrap(), "--out", d.join("export").to_str().unwrap()]);
    ask(&["report", run.to_str().unwrap()]);
    // An edited record makes work.json stale: counted again from the units, still without Python.
    let spec = run.join("spec.json");
    let mut v = json(&spec);
    v["env"]["python"] = serde_json::json!(bin_dir.join("python3"));
    std::fs::write(&spec, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let o = bin().args(["work", run.to_str().unwrap()]).env("PATH", &path).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("work not counted"), "old units without rows are not counted by reading: {err}");
    ask(&["status", run.to_str().unwrap()]);
    assert!(!mark.exists(), "a reading command started Python: {}", read(&mark));
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

    // `status` reads a run's work.json while what it counts from is as it was, and counts again
    // from the units once one is added or removed.
    let mut stored = json(out.join("s/work.json"));
    stored["epoch_rows"] = serde_json::json!(123_456_789_000u64);
    std::fs::write(out.join("s/work.json"), stored.to_string()).unwrap();
    let st = |dir: &Path| String::from_utf8_lossy(&bin().arg("status").arg(dir).output().unwrap().stdout).into_owned();
    let cached = st(&out.join("s"));
    assert!(cached.contains("123.46 G epoch-rows"), "status reads work.json: {cached}");
    // Touched records of the same bytes leave it current: a clone or a copy keeps no times.
    let state = out.join("s/state.json");
    std::fs::write(&state, std::fs::read(&state).unwrap()).unwrap();
    assert!(st(&out.join("s")).contains("123.46 G epoch-rows"));
    let unit = std::fs::read_dir(out.join("s/units")).unwrap().next().unwrap().unwrap().path();
    std::fs::remove_file(&unit).unwrap();
    let counted = st(&out.join("s"));
    assert!(!counted.contains("123.46 G epoch-rows"), "a run whose units changed is counted again: {counted}");
    assert!(counted.contains("epoch-rows"), "from the rows its new units record: {counted}");
}

#[test]
fn status_of_the_committed_minari_folder_lists_its_runs_not_its_input_spec() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results/minari");
    let o = bin().arg("status").arg(&root).env("MINARI_DATASETS_PATH", "/nonexistent").output().unwrap();
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success() && !err.contains("warning"), "{err}");
    for run in ["search", "compare"] {
        let line = out.lines().find(|l| l.contains(&format!("minari/{run}"))).unwrap_or_else(|| panic!("{out}"));
        assert!(line.contains("epoch-rows"), "its work, from work.json: {line}");
    }
    assert!(!out.contains("minari/spec.json"), "{out}");
}

/// Runs the binary with `args`, killed if it has not finished within 60 s (a hang fails the test
/// rather than the suite).
fn within_a_minute(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let mut child =
        bin().args(args).stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let t = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t.elapsed() > std::time::Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("{args:?} hung");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn a_fifo_among_a_runs_records_hangs_neither_status_nor_work() {
    let d = empty_dir("work", "fifo");
    let run = d.join("cmp");
    copy_dir(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results/searches/bicycle-compare-mlp-iterations"), &run);
    for f in ["run.json", "lock"] {
        let p = run.join(f);
        let _ = std::fs::remove_file(&p);
        let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    }
    let o = within_a_minute(&["status".as_ref(), run.as_os_str()]);
    let out = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("cmp"), "{out}");
    let o = within_a_minute(&["work".as_ref(), run.as_os_str()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() || err.contains("not a regular file"), "{err}");
}
