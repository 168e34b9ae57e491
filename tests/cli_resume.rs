//! `--resume` verifies what it reads, and `reproduce` re-derives every stored field.

mod common;
use common::{bin, copy_dir, empty_dir, json, read, tiny_with};

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The tiny search, 20 episodes per dataset, seed 8.
fn search(dir: &Path) -> Output {
    bin()
        .args(["search", "cartpole"])
        .args(tiny_with(&["--episodes", "20", "--seed", "8"]))
        .args(["--out", dir.to_str().unwrap()])
        .output()
        .unwrap()
}

fn resume(dir: &Path) -> Output {
    bin().args(["search", "--resume", dir.to_str().unwrap(), "--quiet"]).output().unwrap()
}

/// Each generation's individuals with their scores (times and run records aside).
fn scores(dir: &Path) -> Vec<Value> {
    read(dir.join("generations.jsonl"))
        .lines()
        .map(|l| {
            let g: Value = serde_json::from_str(l).unwrap();
            g["individuals"].as_array().unwrap().iter().map(|i| (i["setting"].clone(), i["scores"].clone())).collect()
        })
        .map(|v: Vec<(Value, Value)>| serde_json::json!(v))
        .collect()
}

#[test]
fn damaged_directories_resume_to_the_uninterrupted_result() {
    let d = empty_dir("resume", "damaged");
    let whole = d.join("whole");
    let o = search(&whole);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let best = read(whole.join("best.json"));

    // A truncated unit, a temporary file a kill left behind and an empty lock (full disk).
    let cut = d.join("cut");
    copy_dir(&whole, &cut);
    let unit = std::fs::read_dir(cut.join("units")).unwrap().next().unwrap().unwrap().path();
    let text = read(&unit);
    std::fs::write(&unit, &text[..text.len() / 2]).unwrap();
    std::fs::write(cut.join("units/.x.json.tmp999"), "{").unwrap();
    std::fs::write(cut.join("lock"), "").unwrap();
    let o = resume(&cut);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("will be computed again") && err.contains("treated as stale"), "{err}");
    assert_eq!(scores(&cut), scores(&whole));
    assert_eq!(read(cut.join("best.json")), best);
    assert!(!cut.join("units/.x.json.tmp999").exists(), "temporary file left");
    let again: Value = json(&unit);
    assert!(again["checksum"].is_string() && again["spec_hash"].is_string());

    // An edited unit (its score changed, checksum kept) is recomputed too.
    let edited = d.join("edited");
    copy_dir(&whole, &edited);
    let mut u: Value = json(unit_in(&edited, &unit));
    u["score"] = serde_json::json!(1234.5);
    std::fs::write(unit_in(&edited, &unit), u.to_string()).unwrap();
    let o = resume(&edited);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stderr).contains("checksum"));
    assert_eq!(read(edited.join("best.json")), best);

    // A deleted units/ is made again and every unit recomputed.
    let bare = d.join("bare");
    copy_dir(&whole, &bare);
    std::fs::remove_dir_all(bare.join("units")).unwrap();
    let o = resume(&bare);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(scores(&bare), scores(&whole));

    // An edited spec.json is refused: resuming would mix results of two specs.
    let respec = d.join("respec");
    copy_dir(&whole, &respec);
    let mut spec: Value = json(respec.join("spec.json"));
    spec["search"]["episodes"] = serde_json::json!(21);
    std::fs::write(respec.join("spec.json"), spec.to_string()).unwrap();
    let o = resume(&respec);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("spec.json: changed since the run began"), "{err}");
}

fn status(dir: &Path) -> String {
    let o = bin().arg("status").arg(dir).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn status_and_report_say_which_stored_unit_does_not_verify() {
    let d = empty_dir("resume", "verify");
    let dir = d.join("run");
    let o = search(&dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!status(&dir).contains('!'), "{}", status(&dir));

    let unit = std::fs::read_dir(dir.join("units")).unwrap().next().unwrap().unwrap().path();
    let name = format!("units/{}", unit.file_name().unwrap().to_string_lossy());
    let mut u: Value = json(&unit);
    u["score"] = serde_json::json!(1234.5);
    std::fs::write(&unit, u.to_string()).unwrap();
    let line = status(&dir);
    assert!(line.contains("1 stored unit does not verify") && line.contains(&name), "{line}");
    assert!(line.contains("checksum does not match its content"), "{line}");

    let o = bin().arg("report").arg(&dir).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(&name) && err.contains("checksum does not match") && err.contains("resume"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");

    let mut spec: Value = json(dir.join("spec.json"));
    spec["search"]["episodes"] = serde_json::json!(21);
    std::fs::write(dir.join("spec.json"), spec.to_string()).unwrap();
    let line = status(&dir);
    assert!(line.contains("spec.json: changed since the run began"), "{line}");
}

fn unit_in(dir: &Path, like: &Path) -> PathBuf {
    dir.join("units").join(like.file_name().unwrap())
}

#[test]
fn reproduce_rederives_every_stored_field() {
    let d = empty_dir("resume", "reproduce");
    let run = d.join("run");
    assert!(search(&run).status.success());
    let best: Value = json(run.join("best.json"));
    let check = |name: &str, edit: &dyn Fn(&mut Value), want: &str| {
        let mut b = best.clone();
        edit(&mut b);
        let p = d.join(name);
        std::fs::write(&p, b.to_string()).unwrap();
        let o = bin().args(["reproduce", p.to_str().unwrap()]).output().unwrap();
        let out = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(1), "{name}: {out} {}", String::from_utf8_lossy(&o.stderr));
        assert!(out.contains("NOT reproduced") && out.contains(want), "{name}: {out}");
    };
    check(
        "delta.json",
        &|b| {
            let x = b["delta_min"].as_f64().unwrap() * 2.0;
            b["delta_min"] = serde_json::json!(x);
            b["network"]["delta_min"] = serde_json::json!(x);
        },
        "delta_min: stored",
    );
    check(
        "patience.json",
        &|b| {
            let p = b["patience"].as_u64().unwrap() + 1;
            b["patience"] = serde_json::json!(p);
            b["network"]["patience"] = serde_json::json!(p);
        },
        "patience: stored",
    );
    check("lr.json", &|b| b["network"]["learning_rate"] = serde_json::json!(0.5), "network: stored");
    check(
        "extra.json",
        &|b| b["scores"].as_array_mut().unwrap().push(serde_json::json!(1.0)),
        "scores: stored 3 values",
    );
    // Its validation block (the quick preset validates the top 3 on 3 datasets) is re-derived too.
    assert!(best["validation"].is_object(), "{best}");
    check(
        "validation-score.json",
        &|b| {
            let x = b["validation"]["scores"][1].as_f64().unwrap() + 0.5;
            b["validation"]["scores"][1] = serde_json::json!(x);
        },
        "validation dataset 1: recorded",
    );
    check(
        "validation-mean.json",
        &|b| {
            let x = b["validation"]["summary"]["mean"].as_f64().unwrap() + 0.5;
            b["validation"]["summary"]["mean"] = serde_json::json!(x);
        },
        "validation.summary: stored",
    );
    check(
        "validation-count.json",
        &|b| b["validation"]["datasets"] = serde_json::json!(1),
        "validation.scores: stored 3 values, validation.datasets says 1",
    );
    let o = bin().args(["reproduce", run.join("best.json").to_str().unwrap()]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "the untouched best.json reproduces: {out}");
    assert!(out.contains("validation: 3 datasets re-derived"), "{out}");
    // Skipped on request, and then said to be unchecked.
    let o = bin().args(["reproduce", "--skip-validation", d.join("validation-score.json").to_str().unwrap()]).output();
    let out = String::from_utf8_lossy(&o.as_ref().unwrap().stdout).into_owned();
    assert!(o.unwrap().status.success() && out.contains("validation: not checked"), "{out}");
}

#[test]
fn a_full_disk_fails_the_run_and_a_later_resume_works() {
    let d = empty_dir("resume", "enospc");
    let mnt = d.join("small");
    std::fs::create_dir_all(&mnt).unwrap();
    let mounted = Command::new("mount").args(["-t", "tmpfs", "-o", "size=2m", "tmpfs"]).arg(&mnt).status();
    if !mounted.is_ok_and(|s| s.success()) {
        eprintln!("skipped: cannot mount a small tmpfs here (needs root) to fill a disk");
        return;
    }
    let result = std::panic::catch_unwind(|| {
        // The reference: three generations in one go.
        let whole = d.join("whole");
        let args = ["--quick", "--population", "4", "--datasets", "2", "--episodes", "20", "--iterations", "2"];
        let run = |dir: &Path, gens: &str| {
            bin()
                .args(["search", "cartpole"])
                .args(args)
                .args(["--seed", "8", "--quiet", "--generations", gens, "--out"])
                .arg(dir)
                .output()
                .unwrap()
        };
        assert!(run(&whole, "3").status.success());
        // Two generations on the small disk, then the disk fills up.
        let small = mnt.join("run");
        assert!(run(&small, "2").status.success());
        let filler = mnt.join("filler");
        let mut f = std::fs::File::create(&filler).unwrap();
        let block = vec![0u8; 4096];
        while std::io::Write::write_all(&mut f, &block).is_ok() {}
        drop(f);
        // Resuming on the full disk: the lock file is created but its owner cannot be written.
        let o = bin().args(["search", "--resume"]).arg(&small).args(["--quiet"]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "a full disk fails the run: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains("No space left"), "{err}");
        // Room again: a resume takes over what the full disk left (an empty lock) and
        // ends where the uninterrupted run did.
        std::fs::remove_file(&filler).unwrap();
        let o =
            bin().args(["search", "--resume"]).arg(&small).args(["--generations", "3", "--quiet"]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(err.contains("empty or unreadable lock, treated as stale"), "{err}");
        assert_eq!(scores(&small), scores(&whole));
        assert_eq!(read(small.join("best.json")), read(whole.join("best.json")));
    });
    let _ = Command::new("umount").arg(&mnt).status();
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
}

#[test]
fn a_budget_stops_the_validation_and_a_resume_finishes_it() {
    let d = empty_dir("resume", "validation-budget");
    let dir = d.path().join("run");
    assert!(search(&dir).status.success());
    let whole: Value = json(dir.join("validation.json"));
    // Drop the validation, then resume with a budget already spent: the generations replay from
    // their units, and the validation stops before its first unit.
    std::fs::remove_dir_all(dir.join("validation")).unwrap();
    std::fs::remove_file(dir.join("validation.json")).unwrap();
    let out = bin().args(["search", "--resume", dir.to_str().unwrap(), "--max-hours", "1e-9"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("stopped (time budget of 0.000000001 h reached)"), "{err}");
    assert!(!dir.join("validation.json").exists(), "validated past the budget");
    let state: Value = json(dir.join("state.json"));
    assert_eq!(state["state"], "interrupted", "{state}");
    assert!(std::fs::read_dir(dir.join("validation")).unwrap().next().is_none(), "a validation unit ran");
    // Resumed without a budget, it validates, to the same numbers.
    let out = resume(&dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let again: Value = json(dir.join("validation.json"));
    assert_eq!(json(dir.join("state.json"))["state"], "finished");
    assert_eq!(again["entries"], whole["entries"]);
    assert_eq!(again["note"], whole["note"]);
}

#[test]
fn validate_names_an_unfinished_search_and_notes_a_replaced_validation() {
    let d = empty_dir("resume", "revalidate");
    let dir = d.join("run");
    let o = search(&dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let validate = |extra: &[&str]| {
        let o = bin().arg("validate").arg(&dir).args(["--quiet", "--top", "2"]).args(extra).output().unwrap();
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (code, err) = validate(&["--datasets", "2"]);
    assert_eq!(code, Some(0), "{err}");
    // Other caps replace validation.json: a note says so; the same caps again rewrite it silently.
    let (code, err) = validate(&["--datasets", "3"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("validation.json: replaced by this validation"), "{err}");
    let (_, err) = validate(&["--datasets", "3"]);
    assert!(!err.contains("replaced"), "{err}");
    // A search stopped before its first generation ended has no hall of fame yet.
    std::fs::remove_file(dir.join("hall_of_fame.json")).unwrap();
    let (code, err) = validate(&[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("has no hall_of_fame.json: the search has not finished a generation yet"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
}

/// A run killed in its first milliseconds: whatever the moment, the run directory is either
/// absent (its construction was a hidden `.<name>.tmp<pid>` sibling, removed by the next run) or
/// whole, with its run.json, listed by `status` and continued by `--resume`.
#[test]
fn a_run_killed_at_its_start_is_absent_or_whole() {
    let d = empty_dir("resume", "first-write");
    let cmds: [(&str, Vec<String>); 2] = [
        ("search", [vec!["search".into(), "cartpole".into()], tiny_with(&[])].concat()),
        (
            "compare",
            ["compare", "cartpole", "--tuned", "thesis", "--analysis", "iterations", "--learner", "et"]
                .iter()
                .chain(&["--datasets", "1", "--episodes", "20", "--iterations", "2", "--quiet"])
                .map(|s| s.to_string())
                .collect(),
        ),
    ];
    for (kind, args) in &cmds {
        for (i, ms) in [0u64, 1, 2, 4, 8, 15, 30].into_iter().enumerate() {
            let out = d.join(format!("{kind}-{i}"));
            let mut child = common::spawn_quiet(bin().args(args).arg("--out").arg(&out).env("RUST_BACKTRACE", "0"));
            std::thread::sleep(std::time::Duration::from_millis(ms));
            child.kill().unwrap();
            child.wait().unwrap();
            if out.exists() {
                assert!(out.join("run.json").is_file(), "{kind} killed at {ms} ms: {} has no run.json", out.display());
                let _: Value = json(out.join("run.json"));
            }
        }
    }
    // What a kill leaves: runs whole or absent, and the hidden directories under construction.
    let line = status(&d);
    for e in std::fs::read_dir(&d).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !name.starts_with('.') {
            assert!(line.contains(&format!("{name} ")) || line.contains(&format!("{name}\n")), "{name}: {line}");
        }
    }
    assert!(!line.contains(".tmp"), "a run under construction is listed: {line}");

    // A search whose directory is whole but which never wrote its state (killed before its first
    // unit): listed as not started, and `--resume` runs it to the uninterrupted result.
    let whole = d.join("whole");
    assert!(search(&whole).status.success());
    let early = d.join("early");
    std::fs::create_dir_all(early.join("units")).unwrap();
    for f in ["spec.json", "run.json"] {
        std::fs::copy(whole.join(f), early.join(f)).unwrap();
    }
    let line = status(&early);
    assert!(line.contains("not started") && line.contains("search --resume"), "{line}");
    let o = resume(&early);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(scores(&early), scores(&whole));

    // A directory under construction left by a dead process is removed by the next run made
    // beside it, and `status` never lists it.
    let stale = d.join(".next.tmp4294967295");
    std::fs::create_dir_all(stale.join("units")).unwrap();
    std::fs::write(stale.join("compare.json"), "{}").unwrap();
    assert!(!status(&d).contains(".next.tmp"), "{}", status(&d));
    assert!(search(&d.join("next")).status.success());
    assert!(!stale.exists(), "the dead process's directory under construction was left");
}

/// A tiny comparison (Extra-Trees, one dataset, K = 2) in `dir`.
fn compare(dir: &Path) -> Output {
    bin()
        .args(["compare", "cartpole", "--tuned", "thesis", "--analysis", "iterations", "--learner", "et"])
        .args(["--datasets", "1", "--episodes", "20", "--iterations", "2", "--quiet", "--out"])
        .arg(dir)
        .output()
        .unwrap()
}

/// Removes `key` from a JSON file, written back as the tool writes it.
fn strip(path: &Path, key: &str) {
    let mut v: Value = json(path);
    v.as_object_mut().unwrap().remove(key);
    std::fs::write(path, serde_json::to_string_pretty(&v).unwrap() + "\n").unwrap();
}

fn unit_files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = ["units", "validation"]
        .iter()
        .flat_map(|f| std::fs::read_dir(dir.join(f)).into_iter().flatten().flatten().map(|e| e.path()))
        .collect();
    v.sort();
    v
}

/// In a run created with checksums, a unit without one is damaged; a run made before them (no
/// `checksummed` in run.json) reads its units as before until `bfqi-ga stamp` gives them their
/// checksums, exactly as a run would have written them.
#[test]
fn a_unit_without_its_checksum_is_damaged_in_a_checksummed_run() {
    let d = empty_dir("resume", "checksums");
    for (kind, make) in [("search", search as fn(&Path) -> Output), ("compare", compare)] {
        let whole = d.join(kind);
        let o = make(&whole);
        assert!(o.status.success(), "{kind}: {}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(json(whole.join("run.json"))["checksummed"], true, "{kind}");
        assert!(!status(&whole).contains('!'), "{}", status(&whole));

        // The checksum line deleted from one unit: status and resume see it.
        let cut = d.join(format!("{kind}-cut"));
        copy_dir(&whole, &cut);
        let unit = unit_files(&cut)[0].clone();
        strip(&unit, "checksum");
        let line = status(&cut);
        assert!(line.contains("1 stored unit does not verify") && line.contains("has no checksum"), "{line}");
        let o = if kind == "search" {
            resume(&cut)
        } else {
            bin().args(["compare", "--resume", cut.to_str().unwrap(), "--quiet"]).output().unwrap()
        };
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success() && err.contains("has no checksum") && err.contains("computed again"), "{err}");
        assert!(json(&unit)["checksum"].is_string(), "{}: computed again, with its checksum", unit.display());

        // The same run as an older binary wrote it: no checksums, no mark. Trusted as before, then
        // stamped back to the very bytes a run writes.
        let old = d.join(format!("{kind}-old"));
        copy_dir(&whole, &old);
        for u in unit_files(&old) {
            strip(&u, "checksum");
            strip(&u, "spec_hash");
        }
        strip(&old.join("run.json"), "checksummed");
        assert!(!status(&old).contains('!'), "an unmarked run's units are read as before: {}", status(&old));
        let o = bin().arg("stamp").arg(&old).output().unwrap();
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{out}{}", String::from_utf8_lossy(&o.stderr));
        let n = unit_files(&whole).len();
        assert!(out.contains(&format!("{n} unit(s) stamped")), "{out}");
        for u in unit_files(&whole) {
            assert_eq!(read(&u), read(old.join(u.strip_prefix(&whole).unwrap())), "{}", u.display());
        }
        assert_eq!(json(old.join("run.json"))["checksummed"], true);
        // From then on a deleted checksum is seen.
        strip(&unit_files(&old)[0], "checksum");
        assert!(status(&old).contains("has no checksum"), "{}", status(&old));
    }
}

/// `status` of a run whose spec.json or compare.json was edited says that resuming is refused,
/// and does not also promise that resuming computes its units again.
#[test]
fn status_of_an_edited_configuration_does_not_promise_a_resume() {
    let d = empty_dir("resume", "edited-config");
    let c = d.join("compare");
    assert!(compare(&c).status.success());
    let mut cfg: Value = json(c.join("compare.json"));
    cfg["seed"] = serde_json::json!(cfg["seed"].as_u64().unwrap() + 1);
    std::fs::write(c.join("compare.json"), cfg.to_string()).unwrap();
    let line = status(&c);
    assert!(line.contains("compare.json: changed since the run began") && line.contains("refused"), "{line}");
    assert!(!line.contains("--resume computes"), "{line}");
    let o = bin().args(["compare", "--resume", c.to_str().unwrap(), "--quiet"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));

    let s = d.join("search");
    assert!(search(&s).status.success());
    let mut spec: Value = json(s.join("spec.json"));
    spec["seed"] = serde_json::json!(spec["seed"].as_u64().unwrap() + 1);
    std::fs::write(s.join("spec.json"), spec.to_string()).unwrap();
    let line = status(&s);
    assert!(line.contains("spec.json: changed since the run began") && line.contains("refused"), "{line}");
    assert!(!line.contains("resuming computes"), "{line}");
}
