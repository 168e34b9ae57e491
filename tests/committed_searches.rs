//! The runs committed under `results/`: every search's and comparison's tables, plots and report
//! rebuild identically from their records and units, the README's tables are the search reports'
//! own rows, and the cheapest search's tuned config reproduces bit for bit from a fresh clone.

mod common;
use common::{bin, copy_dir, fresh, json, read};

use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results/searches")
}

/// Committed search run directories with a report (a spec.json and a report.md; a search
/// committed before its first generation ended has neither records nor report yet), by name.
fn searches() -> Vec<(String, PathBuf)> {
    let mut out: Vec<(String, PathBuf)> = std::fs::read_dir(root())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("spec.json").is_file() && p.join("report.md").is_file())
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), p))
        .collect();
    out.sort();
    out
}

#[test]
fn reports_rebuild_identically_from_the_stored_records() {
    let found = searches();
    assert!(!found.is_empty(), "no committed search under {}", root().display());
    for (name, dir) in found {
        let copy = fresh("committed", &name);
        copy_dir(&dir, &copy);
        let derived = ["fitness.csv", "fitness.png", "fitness.svg", "report.md"];
        for f in derived {
            std::fs::remove_file(copy.join(f)).unwrap_or_else(|e| panic!("{name}/{f}: {e}"));
        }
        let o = bin().arg("report").arg(&copy).output().unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        for f in derived {
            let (a, b) = (std::fs::read(dir.join(f)).unwrap(), std::fs::read(copy.join(f)).unwrap());
            assert!(a == b, "{name}/{f}: `bfqi-ga report` does not rebuild the committed file");
        }
    }
}

/// Every committed comparison (a directory with a compare.json): the thesis references and the
/// comparisons run with a search's tuned config.
fn comparisons() -> Vec<PathBuf> {
    let results = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results");
    let mut out: Vec<PathBuf> = ["thesis", "searches"]
        .iter()
        .flat_map(|d| std::fs::read_dir(results.join(d)).unwrap().flatten().map(|e| e.path()))
        .filter(|p| p.join("compare.json").is_file())
        .collect();
    out.sort();
    out
}

#[test]
fn comparison_reports_rebuild_identically_from_their_units() {
    let found = comparisons();
    assert!(found.len() >= 10, "the thesis references are committed: {found:?}");
    for dir in found {
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let copy = fresh("committed-compare", &name);
        copy_dir(&dir, &copy);
        let derived: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|f| [".png", ".svg", ".csv", ".md"].iter().any(|x| f.ends_with(x)))
            .collect();
        assert!(derived.iter().any(|f| f == "report.md"), "{name}: no report.md");
        for f in &derived {
            std::fs::remove_file(copy.join(f)).unwrap();
        }
        let o = bin().arg("report").arg(&copy).output().unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        for f in &derived {
            let (a, b) = (std::fs::read(dir.join(f)).unwrap(), std::fs::read(copy.join(f)).unwrap());
            assert!(a == b, "{name}/{f}: `bfqi-ga report` does not rebuild the committed file");
        }
    }
}

/// Every committed run is stamped (`bfqi-ga stamp`): its run.json says `checksummed` and every unit
/// carries a checksum, which `status` verifies, so an edited unit or a deleted checksum line is seen.
#[test]
fn every_committed_unit_carries_its_checksum() {
    let results = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results");
    let mut units = std::collections::BTreeMap::new();
    for group in ["thesis", "searches"] {
        for dir in std::fs::read_dir(results.join(group)).unwrap().flatten().map(|e| e.path()) {
            if !dir.join("compare.json").is_file() && !dir.join("spec.json").is_file() {
                continue;
            }
            assert_eq!(json(dir.join("run.json"))["checksummed"], true, "{}: not stamped", dir.display());
            for folder in ["units", "validation"] {
                for f in std::fs::read_dir(dir.join(folder)).into_iter().flatten().flatten().map(|e| e.path()) {
                    assert!(json(&f)["checksum"].is_string(), "{}: no checksum", f.display());
                    *units.entry(group).or_insert(0) += 1;
                }
            }
        }
    }
    assert!(units["thesis"] >= 2980, "{units:?}");
    let o = bin().arg("status").arg(&results).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && !out.is_empty(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!out.contains(" ! "), "a committed run does not verify:\n{out}");
}

#[test]
fn a_record_that_disagrees_with_its_unit_is_refused() {
    let (name, dir) = searches().into_iter().next().expect("a committed search");
    let copy = fresh("committed", &format!("edited-{name}"));
    copy_dir(&dir, &copy);
    // A unit generation 0 scores its first individual with.
    let gens = read(copy.join("generations.jsonl"));
    let g0: serde_json::Value = serde_json::from_str(gens.lines().next().unwrap()).unwrap();
    let first = copy.join("units").join(format!("{}.d0.json", g0["individuals"][0]["setting"].as_str().unwrap()));
    let mut unit: serde_json::Value = json(&first);
    let score = unit["score"].as_f64().expect("a finite score in the first unit");
    unit["score"] = serde_json::json!(score + 1.0);
    std::fs::write(&first, serde_json::to_string(&unit).unwrap()).unwrap();
    let o = bin().arg("report").arg(&copy).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("generations.jsonl") && err.contains(first.file_name().unwrap().to_str().unwrap()), "{err}");
}

/// Student's t quantile at 0.975 with 9 degrees of freedom, from the tables (10 paired datasets).
const T_975_9: f64 = 2.262_157;

/// The scores of `setting` on datasets 0..10 of `dir/units` (search) or `dir/validation`.
fn unit_scores(dir: &std::path::Path, setting: &str) -> Vec<f64> {
    (0..10).map(|k| json(dir.join(format!("{setting}.d{k}.json")))["score"].as_f64().unwrap()).collect()
}

/// `mean ± t·s/√n` of `a − b`, paired, as the report prints it.
fn reference_paired(a: &[f64], b: &[f64]) -> String {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    format!("{mean:+.3} ± {:.3}", T_975_9 * sd / n.sqrt())
}

#[test]
fn the_reports_paired_intervals_are_recomputed_from_the_stored_units() {
    let dir = root().join("bicycle");
    // Hall of fame 1, the tuned config under the thesis's `select: fitness`.
    let entry = &json(dir.join("validation.json"))["entries"][0];
    assert_eq!(entry["source"], "hall of fame 1");
    let tuned = entry["setting"].as_str().unwrap().to_string();
    let thesis = "sigmoid_1.1e-2_75";
    let search = reference_paired(&unit_scores(&dir.join("units"), &tuned), &unit_scores(&dir.join("units"), thesis));
    let validation =
        reference_paired(&unit_scores(&dir.join("validation"), &tuned), &unit_scores(&dir.join("validation"), thesis));
    let row = format!("| thesis optimum | `{thesis}` | {search} | 10 | {validation} | 10 | tuned config ahead |");
    let report = read(dir.join("report.md"));
    assert!(report.lines().any(|l| l == row), "not in bicycle/report.md:\n{row}");
}

/// The README's rows of the tables it copies from the search reports (the generations table and
/// the dataset-by-dataset table), with the section they are in: `## <env> …`, where `<env>` is the
/// run directory's name, hyphens allowed (`cart-pole`).
fn readme_rows() -> Vec<(String, String)> {
    let text = read(root().join("README.md"));
    let (mut section, mut header) = (String::new(), String::new());
    let mut rows = Vec::new();
    for line in text.lines() {
        if let Some(h) = line.strip_prefix("## ") {
            section = h.split_whitespace().next().unwrap_or("").to_string();
            continue;
        }
        if !line.starts_with('|') {
            header.clear();
            continue;
        }
        if header.is_empty() {
            header = line.to_string();
            continue;
        }
        let copied = [
            "| generation | new units |",
            "| | datasets |",
            "| | setting |",
            "| tuned config minus |",
            "| | GA | random |",
            "| GA winner minus random winner |",
            "| job | validated winner |",
        ]
        .iter()
        .any(|h| header.starts_with(h));
        if copied && !line.starts_with("|---") {
            rows.push((section.clone(), line.to_string()));
        }
    }
    rows
}

#[test]
fn the_readme_tables_are_the_reports_rows() {
    let rows = readme_rows();
    // A section's rows come from its directory's report.md (a search, or a validation kept apart
    // from one) or, for a batch, its summary.md.
    let source = |name: &str| {
        let dir = root().join(name);
        ["report.md", "summary.md"].into_iter().map(|f| dir.join(f)).find(|p| p.is_file())
    };
    let mut checked = 0;
    for (name, row) in &rows {
        let file = source(name).unwrap_or_else(|| panic!("README rows under a section with no committed run: {name}"));
        let text = read(&file);
        assert!(text.lines().any(|l| l == row), "README row not in {}:\n{row}", file.display());
        checked += 1;
    }
    assert!(checked > 0, "no README row was checked");
    assert!(searches().iter().any(|(n, _)| rows.iter().any(|(s, _)| s == n)), "no search's rows were checked");
}

#[test]
fn the_cartpole_search_reproduces_bit_for_bit() {
    let best = root().join("cartpole/best.json");
    let o = bin().arg("reproduce").arg(&best).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{out}{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("matches bit for bit (10 datasets)"), "{out}");
}

/// The committed full searches' raced validations (`validate --into <env>-raced`, issue 50): each
/// reads its search, whose validation scores are a prefix of the race's, gives the best.json that
/// `select: validated` gives, and its report rebuilds from its records.
#[test]
fn the_raced_validations_of_the_full_searches_extend_theirs_and_rebuild() {
    let mut found = 0;
    for (name, dir) in searches() {
        let raced = root().join(format!("{name}-raced"));
        if !raced.is_dir() {
            continue;
        }
        found += 1;
        let v = json(raced.join("validation.json"));
        assert_eq!(v["source"], format!("results/searches/{name}"), "{name}-raced");
        assert!(v["rule"]["race"].is_object(), "{name}-raced is a race");
        let full = json(dir.join("validation.json"));
        for e in v["entries"].as_array().unwrap() {
            let Some(f) = full["entries"].as_array().unwrap().iter().find(|f| f["setting"] == e["setting"]) else {
                continue;
            };
            let (mine, theirs) =
                (e["validation_scores"].as_array().unwrap(), f["validation_scores"].as_array().unwrap());
            let n = mine.len().min(theirs.len());
            assert_eq!(mine[..n], theirs[..n], "{name}-raced {}: not a prefix of the full validation", e["setting"]);
        }
        let best = json(raced.join("best.json"));
        let leader = v["rounds"].as_array().unwrap().last().unwrap()["leader"].clone();
        assert_eq!(best["selection"]["select"], "validated");
        assert_eq!(best["selection"]["validated"], leader, "{name}-raced");
        for f in std::fs::read_dir(raced.join("validation")).into_iter().flatten().flatten().map(|e| e.path()) {
            assert!(json(&f)["checksum"].is_string(), "{}: no checksum", f.display());
        }
        let copy = fresh("committed-raced", &name);
        copy_dir(&raced, &copy);
        std::fs::remove_file(copy.join("report.md")).unwrap();
        let o = bin().arg("report").arg(&copy).output().unwrap();
        assert!(o.status.success(), "{name}-raced: {}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(read(raced.join("report.md")), read(copy.join("report.md")), "{name}-raced/report.md");
    }
    assert_eq!(found, 3, "cartpole, bicycle and pendulum each have a raced validation");
}
