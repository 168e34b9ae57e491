//! `bfqi-ga search`, `reproduce` and `status` end to end.

mod common;
use common::{TempDir, bin, fresh, json, read, spawn_quiet, tiny_with, wait_for_entries};

use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    fresh("search", name)
}

fn search(dir: &Path, extra: &[&str]) -> Output {
    bin().args(["search", "cartpole", "--out", dir.to_str().unwrap()]).args(tiny_with(extra)).output().unwrap()
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
    let best: serde_json::Value = json(a.join("best.json"));
    assert_eq!(best["source"], "search");
    assert_eq!(best["network"]["hidden"], serde_json::json!([10, 10]));
    for f in ["fitness.png", "fitness.svg", "spec.json", "run.json", "state.json"] {
        assert!(a.join(f).is_file(), "{f} missing");
    }
    let run: serde_json::Value = json(a.join("run.json"));
    assert_eq!(run["overrides"]["population"], 4, "overrides are recorded");
    let commit = run["commit"].as_str().unwrap();
    assert!(commit == "unknown" || commit.len() >= 40, "run.json records the source commit: {commit}");
    // Each unit says, per FQI iteration and per action's network, how its training went.
    for e in std::fs::read_dir(a.join("units")).unwrap() {
        let u: serde_json::Value = json(e.unwrap().path());
        let its = u["iterations"].as_array().unwrap();
        assert_eq!(its.len(), 2, "K = 2: {u}");
        let mut epochs = 0;
        for it in its {
            let nets = it["networks"].as_array().unwrap();
            assert_eq!(nets.len(), 2, "cart-pole: one network per action");
            for n in nets {
                let stop = n["stop"].as_str().unwrap();
                assert!(stop == "early_stopping" || stop == "max_epochs", "{stop}");
                assert!(n["val_loss"].as_f64().unwrap().is_finite() && n["train_loss"].as_f64().unwrap().is_finite());
                epochs += n["epochs"].as_u64().unwrap();
            }
            assert!(it["fit_seconds"].as_f64().unwrap() >= 0.0);
        }
        assert_eq!(u["epochs"].as_u64().unwrap(), epochs, "the unit's epochs are its networks' sum");
    }

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
fn each_invocation_records_its_machine_and_the_report_names_them() {
    let dir = tmp("machine");
    let o = search(&dir, &["--jobs", "1", "--generations", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let run: serde_json::Value = json(dir.join("run.json"));
    let m = &run["machine"];
    assert_eq!(m["threads"], 1, "{run}");
    assert!(m["cpus"].as_u64().unwrap() >= 1 && !m["cpu"].as_str().unwrap().is_empty(), "{run}");
    let isa = m["mlp_isa"].as_str().unwrap();
    assert!(["avx512", "avx2", "portable"].contains(&isa), "{isa}");

    // A second invocation with two threads: recorded apart, and the wall time names both set-ups.
    let r = bin()
        .args(["search", "--resume"])
        .arg(&dir)
        .args(["--generations", "2", "--jobs", "2", "--quiet"])
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let run: serde_json::Value = json(dir.join("run.json"));
    assert_eq!(run["resumed"][0]["machine"]["threads"], 2, "{run}");
    assert_eq!(run["machine"]["threads"], 1, "the first invocation's record stays");
    assert!(bin().arg("report").arg(&dir).output().unwrap().status.success());
    let report = read(dir.join("report.md"));
    let cpu = m["cpu"].as_str().unwrap();
    let both = format!("on {cpu}, {isa}, 1 thread and {cpu}, {isa}, 2 threads (its invocations differ");
    assert!(report.lines().any(|l| l.contains("Wall time") && l.contains(&both)), "{report}");
}

#[test]
fn a_search_that_differs_in_its_stop_rules_replays_anothers_generations_and_validation_from_its_units() {
    let (long, short) = (tmp("stop-long"), tmp("stop-short"));
    assert!(search(&long, &["--generations", "3"]).status.success());
    let validate = |run: &Path| {
        bin().arg("validate").arg(run).args(["--top", "3", "--datasets", "3", "--quiet"]).output().unwrap()
    };
    assert!(validate(&long).status.success());
    let o = bin()
        .args(["search", "cartpole", "--out"])
        .arg(&short)
        .args(tiny_with(&["--generations", "2"]))
        .arg("--units-from")
        .arg(&long)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let gens = |run: &Path| -> Vec<serde_json::Value> {
        read(run.join("generations.jsonl"))
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["individuals"].clone())
            .collect()
    };
    assert_eq!(gens(&short)[..], gens(&long)[..2], "the same GA path, generation by generation");
    let files = |run: &Path, folder: &str| -> Vec<std::ffi::OsString> {
        std::fs::read_dir(run.join(folder)).unwrap().map(|e| e.unwrap().file_name()).collect()
    };
    let info: serde_json::Value = json(short.join("run.json"));
    assert_eq!(info["units_from"][0]["validation"], files(&long, "validation").len(), "{info}");
    assert!(validate(&short).status.success());
    // A unit both validations need was taken, not trained again: its file (with its seconds) is
    // the longer run's.
    let shared: Vec<_> =
        files(&short, "validation").into_iter().filter(|f| long.join("validation").join(f).is_file()).collect();
    assert!(!shared.is_empty(), "the two runs validate some setting in common");
    for f in shared {
        assert_eq!(read(short.join("validation").join(&f)), read(long.join("validation").join(&f)), "{f:?}");
    }
}

#[test]
fn a_smaller_pruned_search_takes_a_larger_ones_units_and_ends_as_if_it_had_computed_them() {
    let (big, own, taken) = (tmp("share-big"), tmp("share-own"), tmp("share-taken"));
    assert!(search(&big, &["--population", "6", "--generations", "3"]).status.success());
    let small = ["--population", "4", "--generations", "3", "--prune"];
    assert!(search(&own, &small).status.success());
    let o = bin()
        .args(["search", "cartpole", "--out"])
        .arg(&taken)
        .args(tiny_with(&small))
        .arg("--units-from")
        .arg(&big)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info: serde_json::Value = json(taken.join("run.json"));
    assert!(info["units_from"][0]["units"].as_u64().unwrap() > 0, "{info}");
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
        assert_eq!(read(own.join(f)), read(taken.join(f)), "{f}: taking the units changed the result");
    }
    // The taken units are stamped with this run's results hash, so they verify here.
    let st = bin().arg("status").arg(&taken).output().unwrap();
    let text = String::from_utf8_lossy(&st.stdout);
    assert!(!text.contains("not verify") && text.contains("finished"), "{text}");
}

#[test]
fn killed_mid_generation_and_resumed_ends_identical() {
    let (whole, killed) = (tmp("whole"), tmp("killed"));
    let slower = ["--episodes", "400", "--iterations", "4", "--datasets", "3", "--population", "6", "--jobs", "2"];
    let o = search(&whole, &slower);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let mut child =
        spawn_quiet(bin().args(["search", "cartpole", "--out", killed.to_str().unwrap()]).args(tiny_with(&slower)));
    wait_for_entries(&killed.join("units"), 3, &mut child);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let stored = std::fs::read_dir(killed.join("units")).unwrap().count();
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
    // Validating a run in use is refused the same way.
    let o = bin().args(["validate", dir.to_str().unwrap(), "--quiet"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("in use by process"));
}

#[test]
fn malformed_specs_give_exit_2_and_a_one_line_message() {
    let dir = tmp("specs");
    std::fs::create_dir_all(&dir).unwrap();
    let base: serde_json::Value = json("searches/cartpole.json");
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

/// The cart-pole spec with `edit` applied, written to `dir/name.json`.
fn spec_file(dir: &Path, name: &str, edit: impl FnOnce(&mut serde_json::Value)) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut v: serde_json::Value = json("searches/cartpole.json");
    edit(&mut v);
    let p = dir.join(format!("{name}.json"));
    std::fs::write(&p, v.to_string()).unwrap();
    p
}

fn search_spec(spec: &Path, dir: &Path, extra: &[&str]) -> Output {
    bin()
        .args(["search", spec.to_str().unwrap(), "--out", dir.to_str().unwrap()])
        .args(tiny_with(extra))
        .output()
        .unwrap()
}

fn generations(dir: &Path) -> Vec<serde_json::Value> {
    read(dir.join("generations.jsonl")).lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

#[test]
fn chromosomes_that_decode_alike_share_one_evaluation() {
    // b_p = 0 with a_p in 10..=19: every patience is 2; one activation and one δ_min. Four
    // different chromosomes, one setting.
    let base = tmp("alike");
    let spec = spec_file(&base, "alike", |_| {});
    // As a preset, applied after --quick's (which narrows a_patience to its epoch cap).
    let genes = base.join("alike-genes.json");
    let ranges = serde_json::json!({
        "activations": ["tanh"], "a_delta": [10, 10], "b_delta": [2, 2], "a_patience": [10, 19], "b_patience": [0, 0]
    });
    std::fs::write(&genes, serde_json::json!({"search": {"genes": ranges}}).to_string()).unwrap();
    let dir = base.join("run");
    let o = search_spec(&spec, &dir, &["--generations", "1", "--preset", genes.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let g = &generations(&dir)[0];
    let ind = g["individuals"].as_array().unwrap();
    let genes: std::collections::HashSet<String> = ind.iter().map(|i| i["genes"].to_string()).collect();
    assert!(genes.len() >= 2, "the test needs chromosomes that differ: {genes:?}");
    assert!(ind.iter().all(|i| i["setting"] == "tanh_1e-1_2" && i["fitness"] == ind[0]["fitness"]));
    for (k, i) in ind.iter().enumerate() {
        let others: Vec<u64> = (0..ind.len() as u64).filter(|&j| j != k as u64).collect();
        assert_eq!(i["shares_with"], serde_json::json!(others), "individual {k} records its sharers");
    }
    // One evaluation: a unit per dataset, counted as such.
    assert_eq!(g["new_units"], 2);
    // (The validation adds the thesis optimum's units; the GA's own are the setting's two.)
    let units: Vec<String> = std::fs::read_dir(dir.join("units"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with("sigmoid_5.8e-1_601."))
        .collect();
    assert_eq!(units.len(), 2, "{units:?}");
}

#[test]
fn pruning_that_prunes_nothing_changes_nothing_and_pruning_is_recorded() {
    let base = tmp("prune");
    // Pruning on with a margin no score can fall below: the rounds path must select, keep elites
    // and pick the best exactly as the unpruned search.
    let never = spec_file(&base, "never", |v| {
        v["search"]["prune"] = serde_json::json!({"enabled": true, "margin": 1e9, "min_datasets": 1});
    });
    let off = spec_file(&base, "off", |_| {});
    let extra = ["--datasets", "3", "--generations", "3", "--population", "6"];
    let (a, b) = (base.join("off-run"), base.join("never-run"));
    for (spec, dir) in [(&off, &a), (&never, &b)] {
        let o = search_spec(spec, dir, &extra);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (ga, gb) = (generations(&a), generations(&b));
    assert_eq!(ga.len(), gb.len());
    for (x, y) in ga.iter().zip(&gb) {
        assert_eq!(x["individuals"], y["individuals"], "generation {}", x["generation"]);
        assert_eq!(x["stats"], y["stats"]);
    }
    assert!(gb[1]["prune_below"].is_number() && ga[1].get("prune_below").is_none());
    let best = |d: &Path| {
        let mut v: serde_json::Value = json(d.join("best.json"));
        v.as_object_mut().unwrap().retain(|k, _| k != "spec" && k != "spec_hash");
        v
    };
    assert_eq!(best(&a), best(&b));

    // A margin of 0 with one dataset: individuals below the parent-pool line stop after one
    // dataset, are recorded as pruned with their partial scores, and are never elites or parents.
    let eager = spec_file(&base, "eager", |v| {
        v["search"]["prune"] = serde_json::json!({"enabled": true, "margin": 0.0, "min_datasets": 1});
    });
    let c = base.join("eager-run");
    let o = search_spec(&eager, &c, &["--datasets", "3", "--generations", "4", "--population", "8", "--seed", "3"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let gc = generations(&c);
    let mut pruned_seen = 0;
    for (g, next) in gc.iter().zip(gc.iter().skip(1)) {
        let ind = g["individuals"].as_array().unwrap();
        let pruned: Vec<&serde_json::Value> = ind.iter().filter(|i| i["pruned"] == true).collect();
        assert_eq!(g["stats"]["pruned"].as_u64().unwrap() as usize, pruned.len());
        for p in &pruned {
            pruned_seen += 1;
            assert!(p["fitness"].is_null());
            let n = p["scores"].as_array().unwrap().len();
            assert!((1..3).contains(&n), "partial scores: {p}");
            // Never an elite of the next generation.
            let elites: Vec<&serde_json::Value> =
                next["individuals"].as_array().unwrap().iter().filter(|i| i["origin"] == "elite").collect();
            assert!(elites.iter().all(|e| e["setting"] != p["setting"]), "pruned {} became an elite", p["setting"]);
        }
    }
    assert!(pruned_seen > 0, "the eager rule pruned nobody; the test needs a seed that prunes");
    let st = bin().arg("status").arg(&c).output().unwrap();
    assert!(String::from_utf8_lossy(&st.stdout).contains("finished"));

    // Stopped again and again by a tiny time budget, in the middle of rounds, and resumed: the
    // same pruning decisions and the same search.
    let d = base.join("eager-resumed");
    let eager_args =
        ["--datasets", "3", "--generations", "4", "--population", "8", "--seed", "3", "--max-hours", "0.00005"];
    // The first invocation's budget has run out before its first unit, so at least one stop does
    // not hang on the machine's speed; the resumes' tiny budget then stops them mid-round.
    let first = [&eager_args[..8], &["--max-hours", "1e-300"]].concat();
    let o = search_spec(&eager, &d, &first);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut stops = 0;
    while !read(d.join("state.json")).contains("\"finished\"") {
        stops += 1;
        assert!(stops < 500, "never finished");
        let o = bin()
            .args(["search", "--resume", d.to_str().unwrap(), "--quiet", "--max-hours", "0.00005"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // Each generation's wall time is recorded once, however many invocations it took.
    let st: serde_json::Value = json(d.join("state.json"));
    let secs = st["generation_seconds"].as_array().unwrap();
    assert_eq!(secs.len(), 4, "one wall time per generation after {stops} resumes: {secs:?}");
    assert!(secs.iter().all(|s| s.as_f64().unwrap() > 0.0), "{secs:?}");
    let run: serde_json::Value = json(d.join("run.json"));
    assert_eq!(run["resumed"].as_array().map(Vec::len), Some(stops), "run.json lists each resume");
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
        assert_eq!(read(c.join(f)), read(d.join(f)), "{f} differs after {stops} stops and resumes");
    }

    // Each individual's datasets run as a chain, with no barrier between datasets: one thread or
    // three, the same verdicts and the same search.
    for jobs in ["1", "3"] {
        let e = base.join(format!("eager-jobs{jobs}"));
        let o = search_spec(&eager, &e, &[&eager_args[..8], &["--jobs", jobs]].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
            assert_eq!(read(c.join(f)), read(e.join(f)), "{f} differs with --jobs {jobs}");
        }
    }
}

#[test]
fn children_record_their_birth_and_follow_the_ga_rules() {
    // Population 6 (1 elite, a parent pool of 3), 3 generations: every child's parents, crossed
    // genes and mutation flag are in generations.jsonl, and the rules of Appendix C can be checked
    // from the records alone.
    let dir = tmp("births");
    let o = search(&dir, &["--population", "6", "--generations", "3", "--jobs", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let gens = generations(&dir);
    assert_eq!(gens.len(), 3);
    assert!(gens.iter().enumerate().all(|(g, r)| r["generation"] == g as u64), "generations count from 0");
    let genes = |i: &serde_json::Value| -> Vec<i64> {
        i["genes"].as_array().unwrap().iter().map(|v| v.as_i64().unwrap()).collect()
    };
    for w in gens.windows(2) {
        let (prev, next) = (w[0]["individuals"].as_array().unwrap(), w[1]["individuals"].as_array().unwrap());
        // The ranking the GA used: fitness (−∞ for none) descending, ties by position.
        let fit = |i: &serde_json::Value| i["fitness"].as_f64().unwrap_or(f64::NEG_INFINITY);
        let mut order: Vec<usize> = (0..prev.len()).collect();
        order.sort_by(|&a, &b| fit(&prev[b]).total_cmp(&fit(&prev[a])).then(a.cmp(&b)));
        assert_eq!(next[0]["origin"], "elite");
        assert!(next[0]["birth"].is_null());
        assert_eq!(genes(&next[0]), genes(&prev[order[0]]), "the elite is the best, unchanged");
        let pool = &order[..3];
        let children: Vec<&serde_json::Value> = next.iter().filter(|i| i["origin"] == "child").collect();
        assert_eq!(children.len(), 5);
        for c in children {
            let b = &c["birth"];
            let parents: Vec<usize> =
                b["parents"].as_array().unwrap().iter().map(|p| p.as_u64().unwrap() as usize).collect();
            assert!(parents.iter().all(|p| pool.contains(p)), "parents {parents:?} outside the pool {pool:?}");
            let crossed: Vec<i64> = b["crossed"].as_array().unwrap().iter().map(|v| v.as_i64().unwrap()).collect();
            let (p1, p2) = (genes(&prev[parents[0]]), genes(&prev[parents[1]]));
            for g in 0..crossed.len() {
                assert!(
                    p1[g].min(p2[g]) <= crossed[g] && crossed[g] <= p1[g].max(p2[g]),
                    "gene {g} outside its parents"
                );
            }
            if b["mutated"] == false {
                assert_eq!(genes(c), crossed, "an unmutated child is its crossover");
            }
        }
    }
}

#[test]
fn the_winner_is_validated_on_fresh_datasets() {
    // The quick preset validates the top 3 on 3 validation datasets.
    let dir = tmp("validate");
    let o = search(&dir, &["--jobs", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = json(dir.join("validation.json"));
    let hall: serde_json::Value = json(dir.join("hall_of_fame.json"));
    let entries = v["entries"].as_array().unwrap();
    // The top 3 in fitness order, then the thesis optimum (never drawn by this tiny search).
    assert_eq!(entries.len(), 4, "{v}");
    assert_eq!(entries[3]["source"], "thesis optimum");
    assert_eq!(entries[3]["setting"], "sigmoid_5.8e-1_601");
    let mut differ = false;
    for (i, e) in entries.iter().enumerate() {
        assert_eq!(e["search_scores"].as_array().unwrap().len(), 2);
        assert_eq!(e["validation_scores"].as_array().unwrap().len(), 3);
        if i < 3 {
            assert_eq!(e["fitness"], hall[i]["fitness"], "entry {i} is hall of fame {}", i + 1);
        }
        differ |=
            e["search_scores"][0] != e["validation_scores"][0] || e["search_scores"][1] != e["validation_scores"][1];
    }
    assert!(differ, "validation datasets are not the search's: {v}");
    let best: serde_json::Value = json(dir.join("best.json"));
    let tuned = entries.iter().find(|e| e["setting"] == v["tuned"]).unwrap();
    assert_eq!(best["validation"]["scores"], tuned["validation_scores"]);
    assert_eq!(best["validation"]["summary"], tuned["validation"]);
    assert!(read(dir.join("report.md")).contains("## Validation"));
    // best.json with its validation still reproduces.
    let r = bin().arg("reproduce").arg(dir.join("best.json")).output().unwrap();
    assert_eq!(r.status.code(), Some(0), "{}", String::from_utf8_lossy(&r.stdout));
    // Validating again reads the stored units: same file, no new unit.
    let count = |d: &str| std::fs::read_dir(dir.join(d)).unwrap().count();
    let (units, val) = (count("units"), count("validation"));
    assert_eq!(val, 4 * 3);
    let before = read(dir.join("validation.json"));
    let o = bin().args(["validate"]).arg(&dir).arg("--quiet").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read(dir.join("validation.json")), before);
    assert_eq!((count("units"), count("validation")), (units, val));
    assert!(String::from_utf8_lossy(&o.stdout).contains("(tuned)"));
    let s = bin().args(["status"]).arg(&dir).output().unwrap();
    assert!(String::from_utf8_lossy(&s.stdout).contains("validation "), "{}", String::from_utf8_lossy(&s.stdout));
    // `report` rebuilds the tables and plots from the stored results, identically; the plot shows
    // the thesis optimum's fitness as its reference line.
    let files = ["report.md", "fitness.csv", "fitness.svg", "best.json"];
    let before: Vec<String> = files.iter().map(|f| read(dir.join(f))).collect();
    assert!(before[2].contains("thesis optimum"), "fitness.svg has the reference line");
    let o = bin().args(["report"]).arg(&dir).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (f, b) in files.iter().zip(&before) {
        assert_eq!(&read(dir.join(f)), b, "{f} rebuilt differently");
    }
}
