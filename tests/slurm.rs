//! The Slurm executor: driver logic against a stand-in `sbatch` (always), and against a real
//! single-node Slurm cluster when `BFQI_REAL_SLURM=1` (CI starts one with scripts/local-slurm.sh).

mod common;
use common::{TempDir, bin, empty_dir, read, tiny_with};

use std::path::Path;
use std::process::Output;

fn tmp(name: &str) -> TempDir {
    empty_dir("slurm", name)
}

fn fake() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/support/fake-sbatch.sh").display().to_string()
}

/// The tiny search, seed 3.
fn search(out: &Path, extra: &[&str], env: &[(&str, String)]) -> Output {
    let mut c = bin();
    c.args(["search", "cartpole"]).args(tiny_with(&["--seed", "3"])).arg("--out").arg(out).args(extra);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().unwrap()
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
