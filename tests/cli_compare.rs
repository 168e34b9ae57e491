//! `bfqi-ga compare` and `bfqi-ga report` end to end.

mod common;
use common::{TempDir, bin, fresh, json, read};

use std::path::Path;
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

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
    let mut child = bin()
        .args(["compare", "cartpole", "--out", cut.to_str().unwrap()])
        .args(SMALL)
        .args(bigger)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while std::fs::read_dir(cut.join("units")).map(|d| d.count()).unwrap_or(0) < 4
        && t.elapsed() < Duration::from_secs(120)
    {
        std::thread::sleep(Duration::from_millis(10));
    }
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
