//! `bfqi-ga compare` and `bfqi-ga report` end to end.

mod common;
use common::{TempDir, bin, fresh, json, read, spawn_quiet, wait_for_entries};

use std::path::Path;
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    fresh("compare", name)
}

/// A small comparison touching every analysis and both learners.
const SMALL: [&str; 15] = [
    "--analysis",
    "all",
    "--learner",
    "both",
    "--datasets",
    "2",
    "--iterations",
    "3",
    "--complexities",
    "1..3",
    "--sizes",
    "20,40",
    "--quiet",
    "--tuned",
    "thesis",
];

fn compare(dir: &Path, extra: &[&str]) -> Output {
    bin().args(["compare", "cartpole", "--out", dir.to_str().unwrap()]).args(SMALL).args(extra).output().unwrap()
}

fn png_size(p: &Path) -> (u32, u32) {
    let b = std::fs::read(p).unwrap();
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n", "{} is not a PNG", p.display());
    let w = u32::from_be_bytes(b[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(b[20..24].try_into().unwrap());
    (w, h)
}

#[test]
fn small_compare_writes_every_file_and_threads_do_not_matter() {
    let (a, b) = (tmp("a"), tmp("b"));
    let o = compare(&a, &["--jobs", "1", "--episodes", "40"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = compare(&b, &["--jobs", "2", "--episodes", "40"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let csv = read(a.join("scores.csv"));
    let header = csv.lines().next().unwrap();
    assert_eq!(
        header,
        "algorithm,learner,complexity,episodes,dataset,iteration,score,steps,bellman_residual,epochs,fit_seconds,predict_seconds,eval_seconds,diverged_at"
    );
    let strip = |text: &str| -> Vec<String> {
        // Drop the three timing columns (10–12), which legitimately differ between runs.
        text.lines()
            .map(|l| {
                l.split(',')
                    .enumerate()
                    .filter(|(i, _)| !(10..=12).contains(i))
                    .map(|(_, f)| f)
                    .collect::<Vec<_>>()
                    .join(",")
            })
            .collect()
    };
    assert_eq!(strip(&csv), strip(&read(b.join("scores.csv"))), "1 vs 2 threads");
    // Timings are durations: with per-action models fitted on 2 threads at once, the prediction
    // seconds once summed past the wall time and left a negative fit time.
    for l in read(b.join("scores.csv")).lines().skip(1) {
        let cols: Vec<&str> = l.split(',').collect();
        for c in &cols[10..=12] {
            assert!(c.parse::<f64>().is_ok_and(|t| t >= 0.0), "negative or missing timing in {l}");
        }
    }
    assert_eq!(read(a.join("summary.csv")), read(b.join("summary.csv")));

    let report = read(a.join("report.md"));
    let mut pngs = 0;
    for entry in std::fs::read_dir(&a).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "png") {
            pngs += 1;
            assert_eq!(png_size(&p), (900, 560));
            let name = p.file_name().unwrap().to_str().unwrap();
            assert!(report.contains(&format!("({name})")), "report.md does not show {name}");
            assert!(p.with_extension("svg").is_file());
        }
    }
    // Per learner: iterations, 3 heatmaps, complexity, samples.
    assert_eq!(pngs, 12);
    assert!(report.contains("## Thesis claims"));
    assert!(report.contains("Cart-pole, Extra-Trees"));

    // `report` rebuilds the same tables from the stored units.
    let before = read(a.join("summary.csv"));
    std::fs::remove_file(a.join("summary.csv")).unwrap();
    std::fs::remove_file(a.join("et-complexity.png")).unwrap();
    let r = bin().arg("report").arg(&a).output().unwrap();
    assert!(r.status.success());
    assert_eq!(read(a.join("summary.csv")), before);
    assert!(a.join("et-complexity.png").is_file());
}

#[test]
fn interrupted_and_resumed_is_identical() {
    let (whole, cut) = (tmp("whole"), tmp("cut"));
    let bigger = ["--episodes", "150", "--jobs", "2"];
    assert!(compare(&whole, &bigger).status.success());
    let mut child =
        spawn_quiet(bin().args(["compare", "cartpole", "--out", cut.to_str().unwrap()]).args(SMALL).args(bigger));
    wait_for_entries(&cut.join("units"), 4, &mut child);
    child.kill().unwrap();
    child.wait().unwrap();
    let o = bin().args(["compare", "--resume", cut.to_str().unwrap(), "--quiet"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read(whole.join("summary.csv")), read(cut.join("summary.csv")));
}

#[test]
fn a_tuned_config_with_a_missing_or_invalid_field_is_refused() {
    let dir = tmp("tuned");
    std::fs::create_dir_all(&dir).unwrap();
    let mut v: serde_json::Value = json("searches/tuned/cartpole.json");
    v.as_object_mut().unwrap().remove("delta_min");
    let p = dir.join("missing.json");
    std::fs::write(&p, v.to_string()).unwrap();
    let o = bin()
        .args(["compare", "cartpole", "--tuned", p.to_str().unwrap(), "--out"])
        .arg(dir.join("x"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("missing.json") && err.contains("delta_min"), "{err}");

    v["delta_min"] = serde_json::json!(0.58);
    v["patience"] = serde_json::json!("lots");
    let p = dir.join("invalid.json");
    std::fs::write(&p, v.to_string()).unwrap();
    let o = bin()
        .args(["compare", "cartpole", "--tuned", p.to_str().unwrap(), "--out"])
        .arg(dir.join("y"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("invalid.json") && err.contains("patience"), "{err}");
}

/// A one-dataset Extra-Trees iterations comparison of `iterations` FQI iterations (milliseconds).
fn tiny_compare(dir: &Path, iterations: &str) {
    let o = bin()
        .args(["compare", "cartpole", "--out", dir.to_str().unwrap(), "--analysis", "iterations", "--learner", "et"])
        .args(["--datasets", "1", "--episodes", "20", "--quiet", "--iterations", iterations])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn report(dir: &Path) -> (Option<i32>, String) {
    let o = bin().arg("report").arg(dir).output().unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

fn resume(dir: &Path) -> (Option<i32>, String) {
    let o = bin().args(["compare", "--resume", dir.to_str().unwrap(), "--quiet"]).output().unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

const UNIT: &str = "units/et.fqi.base.n20.d0.json";

#[test]
fn an_edited_comparison_unit_is_refused_by_report_and_computed_again_by_resume() {
    let dir = tmp("edited-unit");
    tiny_compare(&dir, "2");
    let original = read(dir.join(UNIT));
    let mut v = json(dir.join(UNIT));
    v["iterations"][1]["score"] = serde_json::json!(999.0);
    std::fs::write(dir.join(UNIT), serde_json::to_string_pretty(&v).unwrap()).unwrap();

    let (code, err) = report(&dir);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(UNIT) && err.contains("checksum does not match its content"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");

    let (code, err) = resume(&dir);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains(UNIT) && err.contains("it will be computed again"), "{err}");
    // Times differ between runs, and with them the checksum.
    let strip = |t: &str| {
        t.lines().filter(|l| !l.contains("_seconds") && !l.contains("checksum")).collect::<Vec<_>>().join("\n")
    };
    assert_eq!(strip(&read(dir.join(UNIT))), strip(&original), "recomputed as first computed");
    assert!(!read(dir.join("scores.csv")).contains(",999"));
    assert!(!status(&dir).contains('!'), "{}", status(&dir));
}

fn status(dir: &Path) -> String {
    let o = bin().arg("status").arg(dir).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn status_lists_a_comparison_and_says_which_unit_does_not_verify() {
    let dir = tmp("status");
    tiny_compare(&dir, "2");
    let line = status(&dir);
    assert!(line.contains("cartpole") && line.contains("compared") && line.contains("units 2/2"), "{line}");
    assert!(!line.contains('!'), "{line}");

    let mut v = json(dir.join(UNIT));
    v["iterations"][0]["score"] = serde_json::json!(5.0);
    std::fs::write(dir.join(UNIT), v.to_string()).unwrap();
    let line = status(&dir);
    assert!(line.contains("units 1/2") && line.contains("1 stored unit does not verify"), "{line}");
    assert!(line.contains(UNIT) && line.contains("checksum does not match"), "{line}");

    let mut c = json(dir.join("compare.json"));
    c["seed"] = serde_json::json!(99);
    std::fs::write(dir.join("compare.json"), c.to_string()).unwrap();
    let line = status(&dir);
    assert!(line.contains("compare.json: changed since the run began"), "{line}");
}

#[test]
fn a_unit_of_another_configuration_is_refused_by_report_and_computed_again_by_resume() {
    let (dir, other) = (tmp("foreign-unit"), tmp("foreign-source"));
    tiny_compare(&dir, "2");
    tiny_compare(&other, "3");
    std::fs::copy(other.join(UNIT), dir.join(UNIT)).unwrap();

    let (code, err) = report(&dir);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(UNIT) && err.contains("computed with another configuration"), "{err}");

    let (code, err) = resume(&dir);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("computed with another configuration") && err.contains("computed again"), "{err}");
    assert_eq!(json(dir.join(UNIT))["iterations"].as_array().unwrap().len(), 2, "recomputed with K = 2");
    assert_eq!(report(&dir).0, Some(0));
}

#[test]
fn an_edited_compare_json_is_refused_by_resume_and_report() {
    for (name, pointer, value) in [("seed", "/seed", serde_json::json!(7)), ("g", "/env/g", serde_json::json!(10.0))] {
        let dir = tmp(&format!("edited-config-{name}"));
        tiny_compare(&dir, "2");
        let mut v = json(dir.join("compare.json"));
        *v.pointer_mut(pointer).unwrap_or_else(|| panic!("{pointer} in compare.json")) = value;
        std::fs::write(dir.join("compare.json"), serde_json::to_string_pretty(&v).unwrap()).unwrap();
        for (code, err) in [resume(&dir), report(&dir)] {
            assert_eq!(code, Some(2), "{err}");
            assert!(err.contains("compare.json: changed since the run began"), "{name}: {err}");
            assert_eq!(err.lines().count(), 1, "{err}");
        }
    }
}

#[test]
fn a_comparison_created_before_the_hash_records_it_at_its_first_resume() {
    let dir = tmp("old-run-json");
    tiny_compare(&dir, "2");
    let mut info = json(dir.join("run.json"));
    let hash = info.as_object_mut().unwrap().remove("config_hash").expect("run.json records config_hash");
    std::fs::write(dir.join("run.json"), info.to_string()).unwrap();
    assert_eq!(report(&dir).0, Some(0), "an old run.json is read as before");
    assert_eq!(resume(&dir).0, Some(0));
    assert_eq!(json(dir.join("run.json"))["config_hash"], hash);
}
