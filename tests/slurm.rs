//! The Slurm executor: driver logic against a stand-in `sbatch` (always), and against a real
//! single-node Slurm cluster when `BFQI_REAL_SLURM=1` (CI starts one with scripts/local-slurm.sh).

mod common;
use common::{TempDir, bin, empty_dir, read, tiny_with};

use std::path::Path;
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    empty_dir("slurm", name)
}

fn support(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/support").join(name).display().to_string()
}

fn fake() -> String {
    support("fake-sbatch.sh")
}

/// The tiny search, seed 3.
fn search(out: &Path, extra: &[&str], env: &[(&str, String)]) -> Output {
    let mut c = bin();
    c.args(["search", "cartpole"]).args(tiny_with(&["--seed", "3"])).arg("--out").arg(out).args(extra);
    for (k, v) in env {
        c.env(k, v);
    }
    if env.iter().any(|(k, _)| *k == "BFQI_SBATCH") {
        c.env("BFQI_SQUEUE", support("fake-squeue.sh"));
    }
    c.output().unwrap()
}

/// Every task log of a Slurm run directory, concatenated.
fn task_logs(run: &Path) -> String {
    std::fs::read_dir(run.join("slurm/logs")).unwrap().flatten().map(|e| read(e.path())).collect()
}

/// How many units of `run` its tasks' logs say were computed, and the most times any one was.
fn computed(run: &Path) -> (usize, usize) {
    let mut seen = std::collections::HashMap::<String, usize>::new();
    for line in task_logs(run).lines() {
        if let Some(id) = line.strip_suffix(": computed and stored") {
            *seen.entry(id.to_string()).or_default() += 1;
        }
    }
    (seen.len(), seen.values().copied().max().unwrap_or(0))
}

#[test]
fn an_unreachable_controller_is_waited_for_at_submission() {
    let d = tmp("unreachable");
    let (local, slurm) = (d.join("local"), d.join("slurm"));
    assert!(search(&local, &[], &[]).status.success());
    let state = d.join("state").display().to_string();
    let env = [("BFQI_SBATCH", fake()), ("FAKE_SBATCH_UNREACHABLE", "2".into()), ("FAKE_SBATCH_STATE", state)];
    let o = search(&slurm, &["--executor", "slurm"], &env);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.matches("slurm: submission failed (sbatch: error: Batch job submission failed").count(), 2, "{err}");
    assert!(!err.contains("resubmitting"), "a failed submission is not a lost task: {err}");
    for f in ["generations.jsonl", "best.json", "validation.json"] {
        assert_eq!(read(local.join(f)), read(slurm.join(f)), "{f}: slurm vs local");
    }
    // A controller that stays away: one line, exit 1 (a failed run, resumable), no state lost.
    let state = d.join("state2").display().to_string();
    let env = [("BFQI_SBATCH", fake()), ("FAKE_SBATCH_UNREACHABLE", "100".into()), ("FAKE_SBATCH_STATE", state)];
    let o = search(&d.join("away"), &["--executor", "slurm", "--slurm-controller-wait", "1"], &env);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let last = err.lines().last().unwrap_or_default();
    assert!(
        last.contains("sbatch could not submit for") && last.contains("Unable to contact slurm controller"),
        "{err}"
    );
    assert!(last.contains("resume when the cluster accepts jobs again"), "{err}");
}

#[test]
fn a_task_still_running_when_sbatch_returns_is_waited_for_not_resubmitted() {
    let d = tmp("detached");
    let (local, slurm) = (d.join("local"), d.join("slurm"));
    assert!(search(&local, &[], &[]).status.success());
    let state = d.join("state").display().to_string();
    let env = [("BFQI_SBATCH", fake()), ("FAKE_SBATCH_DETACH_ONCE", "0".into()), ("FAKE_SBATCH_STATE", state)];
    let o = search(&slurm, &["--executor", "slurm"], &env);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("resubmitting"), "{err}");
    let retried = std::fs::read_dir(slurm.join("slurm"))
        .unwrap()
        .flatten()
        .any(|e| e.file_name().to_string_lossy().contains("-try1"));
    assert!(!retried, "a unit whose task still ran was resubmitted");
    for f in ["generations.jsonl", "best.json", "validation.json"] {
        assert_eq!(read(local.join(f)), read(slurm.join(f)), "{f}: slurm vs local");
    }
    let stored = std::fs::read_dir(slurm.join("units")).unwrap().count()
        + std::fs::read_dir(slurm.join("validation")).unwrap().count();
    assert_eq!(computed(&slurm), (stored, 1), "each unit computed by exactly one task");
}

#[test]
fn slurm_driver_matches_local_and_resubmits_a_lost_task() {
    let d = tmp("driver");
    let (local, slurm) = (d.join("local"), d.join("slurm"));
    assert!(search(&local, &[], &[]).status.success());
    let env = [
        ("BFQI_SBATCH", fake()),
        ("FAKE_SBATCH_DROP_ONCE", "0".to_string()),
        ("FAKE_SBATCH_STATE", d.join("state").display().to_string()),
    ];
    let o = search(&slurm, &["--executor", "slurm", "--slurm-max-parallel", "2"], &env);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["generations.jsonl", "best.json", "validation.json"] {
        assert_eq!(read(local.join(f)), read(slurm.join(f)), "{f}: slurm vs local");
    }
    // The validation's units went to the cluster too, as units of the `validation` folder.
    let scripts: Vec<String> = std::fs::read_dir(slurm.join("slurm"))
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with("array-"))
        .map(|e| read(e.path()))
        .collect();
    assert!(scripts.iter().any(|s| s.contains("--units 'validation'")), "no validation array");
    assert!(slurm.join("validation").read_dir().unwrap().count() > 0);
    // The lost task was resubmitted: more than one array for the first generation.
    let lists = std::fs::read_dir(slurm.join("slurm"))
        .unwrap()
        .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().starts_with("units-"))
        .count();
    assert!(lists >= 3, "expected a resubmission, saw {lists} arrays");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("slurm: 1 unit(s) missing after submission 1 (") && err.contains("resubmitting"), "{err}");
}

#[test]
fn a_pruned_search_through_slurm_matches_local() {
    // Pruned generations run each individual's datasets as chains: locally with no barrier, on
    // Slurm as one array per round of links. Same verdicts, same search.
    let d = tmp("pruned");
    let (local, slurm) = (d.join("local"), d.join("slurm"));
    let o = search(&local, &["--prune"], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let env = [("BFQI_SBATCH", fake()), ("FAKE_SBATCH_STATE", d.join("state").display().to_string())];
    let o = search(&slurm, &["--prune", "--executor", "slurm"], &env);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["generations.jsonl", "best.json"] {
        assert_eq!(read(local.join(f)), read(slurm.join(f)), "{f}: slurm vs local");
    }
    assert!(read(slurm.join("generations.jsonl")).contains("prune_below"), "no pruned generation ran");
}

#[test]
fn a_raced_search_through_slurm_matches_local() {
    // Raced generations run each new setting's datasets as chains too (`search.race`): the same
    // decisions through Slurm's job arrays as locally.
    let d = tmp("raced");
    let overlay = d.join("race.json");
    std::fs::write(&overlay, r#"{"search": {"race": {"test": "wilcoxon", "confidence": 0.8, "first": 3}}}"#).unwrap();
    let run = |out: &Path, extra: &[&str], env: &[(&str, String)]| {
        let mut c = bin();
        c.args(["search", "cartpole", "--preset", overlay.to_str().unwrap()])
            .args(tiny_with(&[
                "--seed",
                "3",
                "--datasets",
                "4",
                "--population",
                "8",
                "--generations",
                "4",
                "--episodes",
                "40",
            ]))
            .arg("--out")
            .arg(out)
            .args(extra);
        for (k, v) in env {
            c.env(k, v);
        }
        c.env("BFQI_SQUEUE", support("fake-squeue.sh"));
        c.output().unwrap()
    };
    let (local, slurm) = (d.join("local"), d.join("slurm"));
    let o = run(&local, &[], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let env = [("BFQI_SBATCH", fake()), ("FAKE_SBATCH_STATE", d.join("state").display().to_string())];
    let o = run(&slurm, &["--executor", "slurm"], &env);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["generations.jsonl", "best.json"] {
        assert_eq!(read(local.join(f)), read(slurm.join(f)), "{f}: slurm vs local");
    }
    assert!(read(slurm.join("generations.jsonl")).contains("\"stopped\":true"), "nobody was raced out");
}

#[test]
fn a_unit_that_always_fails_is_reported_with_its_log() {
    let d = tmp("always");
    let env = [("BFQI_SBATCH", fake()), ("FAKE_SBATCH_DROP_ALWAYS", "0".to_string())];
    let o = search(&d.join("run"), &["--executor", "slurm", "--slurm-retries", "1"], &env);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "a run that failed, not bad input: {err}");
    assert!(err.contains("still missing after 2 submission(s)") && err.contains("log "), "{err}");
}

#[test]
fn the_worker_refuses_a_run_directory_it_cannot_see() {
    let o = bin().args(["worker", "/nonexistent/run", "0_10_2_10_0.d0"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2));
    assert!(err.contains("shared by the nodes"), "{err}");
}

/// Needs a running cluster: `scripts/local-slurm.sh start` then `BFQI_REAL_SLURM=1 cargo test`.
#[test]
fn real_slurm_matches_local_for_a_search_and_a_comparison() {
    if std::env::var("BFQI_REAL_SLURM").as_deref() != Ok("1") {
        eprintln!("BFQI_REAL_SLURM is not 1: the real-cluster check runs in CI (scripts/local-slurm.sh)");
        return;
    }
    let d = tmp("real");
    let (local, slurm) = (d.join("local"), d.join("slurm"));
    assert!(search(&local, &[], &[]).status.success());
    let o = search(&slurm, &["--executor", "slurm", "--slurm-time", "00:10:00"], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["generations.jsonl", "best.json"] {
        assert_eq!(read(local.join(f)), read(slurm.join(f)), "{f}: real slurm vs local");
    }
    let cmp = |out: &Path, extra: &[&str]| {
        bin()
            .args([
                "compare",
                "cartpole",
                "--learner",
                "et",
                "--datasets",
                "2",
                "--episodes",
                "30",
                "--iterations",
                "2",
                "--quiet",
                "--out",
            ])
            .arg(out)
            .args(extra)
            .output()
            .unwrap()
    };
    assert!(cmp(&d.join("cl"), &[]).status.success());
    let o = cmp(&d.join("cs"), &["--executor", "slurm"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read(d.join("cl/summary.csv")), read(d.join("cs/summary.csv")));
}
