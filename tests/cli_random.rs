//! The random-search baseline (`search.strategy: random`, beyond the thesis): generation 0 is the
//! GA's, later generations are uniform draws from the same gene ranges, and with `--units-from`
//! it takes the GA run's stored units instead of computing them again.

mod common;
use common::{bin, empty_dir, json, tiny_with};

use serde_json::Value;
use std::path::Path;

fn generations(run: &Path) -> Vec<Value> {
    common::read(run.join("generations.jsonl")).lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_random_search_draws_from_the_gene_ranges_and_shares_the_gas_units() {
    let d = empty_dir("random", "baseline");
    let (ga, rnd) = (d.path().join("ga"), d.path().join("random"));
    let wide = ["--generations", "4", "--population", "6"];
    ok(&bin().args(["search", "cartpole", "--out"]).arg(&ga).args(tiny_with(&wide)).output().unwrap());
    let preset = Path::new(env!("CARGO_MANIFEST_DIR")).join("searches/presets/random.json");
    let out = bin()
        .args(["search", "cartpole", "--out"])
        .arg(&rnd)
        .args(tiny_with(&wide))
        .arg("--preset")
        .arg(&preset)
        .arg("--units-from")
        .arg(&ga)
        .output()
        .unwrap();
    ok(&out);

    let spec: Value = json(rnd.join("spec.json"));
    assert_eq!(spec["search"]["strategy"], "random");
    let genes = &spec["search"]["genes"];
    let (g_ga, g_rnd) = (generations(&ga), generations(&rnd));
    assert_eq!(g_rnd.len(), 4);
    // Generation 0 is the GA's, individual by individual.
    assert_eq!(g_ga[0]["individuals"], g_rnd[0]["individuals"]);
    let mut drawn = std::collections::HashSet::new();
    for g in &g_rnd[1..] {
        for i in g["individuals"].as_array().unwrap() {
            assert_eq!(i["origin"], "random", "{i}");
            let c = i["genes"].as_array().unwrap();
            let acts = genes["activations"].as_array().unwrap().len() as i64;
            assert!((0..acts).contains(&c[0].as_i64().unwrap()), "{i}");
            for (k, name) in [(1, "a_delta"), (2, "b_delta"), (3, "a_patience"), (4, "b_patience")] {
                let (lo, hi) = (genes[name][0].as_i64().unwrap(), genes[name][1].as_i64().unwrap());
                assert!((lo..=hi).contains(&c[k].as_i64().unwrap()), "gene {name} of {i} outside [{lo}, {hi}]");
            }
            drawn.insert(i["setting"].as_str().unwrap().to_string());
        }
    }
    // Uniform draws, not copies of the previous generation: 18 draws give many distinct settings.
    assert!(drawn.len() >= 12, "{drawn:?}");

    // The GA's units were taken, not recomputed: every stored GA unit is in the random run, byte
    // for byte, and run.json records how many.
    let info: Value = json(rnd.join("run.json"));
    let taken = info["units_from"][0]["units"].as_u64().unwrap() as usize;
    let ga_units: Vec<_> = std::fs::read_dir(ga.join("units")).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(taken, ga_units.len());
    for f in &ga_units {
        assert_eq!(std::fs::read(ga.join("units").join(f)).unwrap(), std::fs::read(rnd.join("units").join(f)).unwrap());
    }
    // Neither run resumes as the other.
    assert_ne!(info["spec_hash"], json(ga.join("run.json"))["spec_hash"]);
    assert!(common::read(rnd.join("report.md")).starts_with("# Random search"));

    // What the GA adds: the random report sets both searches side by side at their FQI runs, and
    // once both are validated, the paired difference of their winners on the validation datasets.
    for run in [&ga, &rnd] {
        ok(&bin().arg("validate").arg(run).args(["--top", "3", "--datasets", "4", "--quiet"]).output().unwrap());
    }
    ok(&bin().arg("report").arg(&rnd).output().unwrap());
    let report = common::read(rnd.join("report.md"));
    assert!(report.contains("## The GA against this random search"), "{report}");
    let units = |g: &[Value]| g.iter().map(|r| r["new_units"].as_u64().unwrap()).sum::<u64>();
    assert!(report.contains(&format!("| FQI runs | {} | {} |", units(&g_ga), units(&g_rnd))), "{report}");
    let winner = |run: &Path| {
        let v: Value = json(run.join("validation.json"));
        let e = v["entries"].as_array().unwrap().iter().find(|e| e["setting"] == v["tuned"]).unwrap().clone();
        e["validation_scores"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect::<Vec<f64>>()
    };
    let (a, b) = (winner(&ga), winner(&rnd));
    let mean = a.iter().zip(&b).map(|(x, y)| x - y).sum::<f64>() / a.len() as f64;
    let row = report.lines().find(|l| l.starts_with("| validation datasets")).expect("a validation row");
    assert!(row.contains(&format!("{mean:+.3} ± ")), "{row} (expected mean difference {mean:+.3})");

    // `tidy` removes the taken units of settings the random search never drew nor validated, and
    // nothing its records, report or validation read.
    let tidy = |dry: bool| {
        let mut c = bin();
        c.arg("tidy").arg(&rnd);
        if dry {
            c.arg("--dry-run");
        }
        let o = c.output().unwrap();
        ok(&o);
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let count = |folder: &str| std::fs::read_dir(rnd.join(folder)).map_or(0, |r| r.count());
    let before = count("units");
    // The work counted is the units the search used, whether it took or computed them: the same
    // before and after tidy, and less than the files it took.
    let work = || -> Value {
        let o = bin().arg("work").arg(&rnd).arg("--json").output().unwrap();
        ok(&o);
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let work_before = work();
    assert!((work_before["units"].as_u64().unwrap() as usize) < before + count("validation"), "{work_before}");
    let dry = tidy(true);
    assert_eq!(count("units"), before, "a dry run removes nothing: {dry}");
    let done = tidy(false);
    assert_eq!(dry.replace("would be removed", "removed"), done);
    assert!(count("units") < before, "{done}");
    let mut used: std::collections::HashSet<String> = g_rnd
        .iter()
        .flat_map(|g| g["individuals"].as_array().unwrap().iter())
        .map(|i| i["setting"].as_str().unwrap().into())
        .collect();
    let v: Value = json(rnd.join("validation.json"));
    used.extend(v["entries"].as_array().unwrap().iter().map(|e| e["setting"].as_str().unwrap().to_string()));
    for f in std::fs::read_dir(rnd.join("units")).unwrap() {
        let name = f.unwrap().file_name().to_string_lossy().into_owned();
        let setting = name.rsplit_once(".d").unwrap().0;
        assert!(used.contains(setting), "{name} was kept but nothing uses it");
    }
    for s in &used {
        assert!(rnd.join("units").join(format!("{s}.d0.json")).is_file(), "{s}'s units were removed");
    }
    // The same work, from other files (its fingerprint names them).
    let counted = |mut w: Value| {
        w.as_object_mut().unwrap().remove("sources");
        w
    };
    assert_eq!(counted(work()), counted(work_before), "tidy removed a unit the search used");
    ok(&bin().arg("report").arg(&rnd).output().unwrap());
    assert_eq!(report, common::read(rnd.join("report.md")), "the report rebuilds the same after tidy");
    let st = bin().arg("status").arg(&rnd).output().unwrap();
    assert!(!String::from_utf8_lossy(&st.stdout).contains(" ! "), "{}", String::from_utf8_lossy(&st.stdout));
    assert!(tidy(false).contains(": 0 unit file(s)"), "a second tidy has nothing to remove");

    // A search that has not finished may need any unit on resume: refused, nothing removed.
    let mut state: Value = json(ga.join("state.json"));
    state["state"] = "stopped".into();
    std::fs::write(ga.join("state.json"), state.to_string()).unwrap();
    let units = std::fs::read_dir(ga.join("units")).unwrap().count();
    let o = bin().arg("tidy").arg(&ga).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("only a finished search"));
    assert_eq!(units, std::fs::read_dir(ga.join("units")).unwrap().count());
}

#[test]
fn units_from_another_spec_is_refused_before_a_run_directory_exists() {
    let d = empty_dir("random", "refused");
    let ga = d.path().join("ga");
    ok(&bin().args(["search", "cartpole", "--out"]).arg(&ga).args(tiny_with(&[])).output().unwrap());
    let rnd = d.path().join("other");
    let o = bin()
        .args(["search", "cartpole", "--out"])
        .arg(&rnd)
        .args(tiny_with(&["--episodes", "30"]))
        .arg("--units-from")
        .arg(&ga)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--units-from") && err.contains("another spec"), "{err}");
    assert!(!rnd.exists(), "a refused command leaves nothing");
}

#[test]
fn a_search_tidied_before_its_end_takes_the_units_again_and_ends_as_if_never_tidied() {
    let d = empty_dir("random", "tidy-partial");
    let (ga, whole, cut) = (d.path().join("ga"), d.path().join("whole"), d.path().join("cut"));
    let wide = ["--generations", "4", "--population", "6"];
    ok(&bin().args(["search", "cartpole", "--out"]).arg(&ga).args(tiny_with(&wide)).output().unwrap());
    let preset = Path::new(env!("CARGO_MANIFEST_DIR")).join("searches/presets/random.json");
    let random = |out: &Path, generations: &str| {
        let mut c = bin();
        c.args(["search", "cartpole", "--out"]).arg(out).args(tiny_with(&[
            "--generations",
            generations,
            "--population",
            "6",
        ]));
        ok(&c.arg("--preset").arg(&preset).arg("--units-from").arg(&ga).output().unwrap());
    };
    random(&whole, "4");
    let tidy = |out: &Path| {
        let o = bin().arg("tidy").arg(out).output().unwrap();
        ok(&o);
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let tidied = |out: &Path| json(out.join("run.json"))["units_from"][0]["tidied"] == true;
    let resume = |out: &Path, extra: &[&str]| {
        let o = bin().args(["search", "--resume"]).arg(out).args(extra).output().unwrap();
        ok(&o);
        String::from_utf8_lossy(&o.stderr).into_owned()
    };

    // Two generations, finished and tidied, then extended to four but stopped by its budget before
    // any of them: the resume took the removed units again first.
    random(&cut, "2");
    let first = tidy(&cut);
    assert!(tidied(&cut) && !first.contains("resume takes them again"), "{first}");
    let err = resume(&cut, &["--generations", "4", "--max-hours", "1e-300"]);
    assert!(err.contains("units taken again") && !tidied(&cut), "{err}");
    assert_eq!(json(cut.join("state.json"))["state"], "interrupted");
    assert_eq!(generations(&cut).len(), 2);

    // Stopped before its end: only copies the GA run holds too go, and what it computed stays.
    let before: Vec<_> = std::fs::read_dir(cut.join("units")).unwrap().map(|e| e.unwrap().file_name()).collect();
    let second = tidy(&cut);
    assert!(second.contains("resume takes them again") && tidied(&cut), "{second}");
    let after: std::collections::HashSet<_> =
        std::fs::read_dir(cut.join("units")).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(after.len() < before.len(), "{second}");
    for f in before.iter().filter(|f| !after.contains(*f)) {
        assert!(ga.join("units").join(f).is_file(), "{f:?} was computed by the search, yet removed");
    }

    // Resumed to its end: the same generations and unit files as the search never tidied, and
    // the GA's units taken, not computed again (a unit computed again records another wall time).
    let err = resume(&cut, &["--quiet"]);
    assert!(!tidied(&cut), "{err}");
    let strip = |g: Vec<Value>| {
        g.into_iter()
            .map(|r| (r["individuals"].clone(), r["stats"].clone(), r["new_units"].clone()))
            .collect::<Vec<_>>()
    };
    assert_eq!(strip(generations(&cut)), strip(generations(&whole)));
    let names = |run: &Path| {
        let mut v: Vec<_> = std::fs::read_dir(run.join("units")).unwrap().map(|e| e.unwrap().file_name()).collect();
        v.sort();
        v
    };
    assert_eq!(names(&cut), names(&whole));
    for f in names(&ga) {
        assert_eq!(
            std::fs::read(cut.join("units").join(&f)).unwrap(),
            std::fs::read(ga.join("units").join(&f)).unwrap(),
            "{f:?}"
        );
    }
}
