//! A search on a gymnasium env (CartPole-v1 through the bridge) is a search like any other
//! (issue 39): identical under 1 and 2 threads, after `kill -9` and a resume, and through the Slurm
//! executor (a stand-in sbatch always, the real single-node cluster when `BFQI_REAL_SLURM=1`); its
//! tuned config reproduces bit for bit and drives `fitness`, `compare`, `rollout` and `evaluate`.

mod common;
use common::gym::{gym_bin, python, write_spec};
use common::{TempDir, empty_dir, read, spawn_quiet, tiny_with, wait_for_entries};

use std::path::{Path, PathBuf};
use std::process::Output;

fn spec(dir: &TempDir) -> PathBuf {
    let env =
        serde_json::json!({"id": "CartPole-v1", "horizon": 200, "gamma": 1.0, "eval": {"episodes": 2, "steps": 200}});
    write_spec(&dir.join("cartpole-v1.json"), "cartpole", env)
}

fn search(py: &str, spec: &Path, out: &Path, extra: &[&str]) -> Output {
    gym_bin(py).arg("search").arg(spec).args(tiny_with(extra)).arg("--out").arg(out).output().unwrap()
}

fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    format!("{}{err}", String::from_utf8_lossy(&o.stdout))
}

fn same(a: &Path, b: &Path, why: &str) {
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
        assert_eq!(read(a.join(f)), read(b.join(f)), "{f}: {why}");
    }
}

#[test]
fn a_gymnasium_search_is_the_same_on_any_thread_count_and_reproduces() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymsearch", "threads");
    let s = spec(&d);
    ok(&search(&py, &s, &d.join("one"), &["--jobs", "1"]));
    ok(&search(&py, &s, &d.join("two"), &["--jobs", "2"]));
    same(&d.join("one"), &d.join("two"), "1 vs 2 threads");
    let spec_json = read(d.join("one/spec.json"));
    assert!(spec_json.contains("\"probed\"") && spec_json.contains("CartPole-v1"), "{spec_json}");
    let best = d.join("one/best.json");
    let r = ok(&gym_bin(&py).arg("reproduce").arg(&best).output().unwrap());
    assert!(r.contains("matches bit for bit"), "{r}");
    // The stored run needs no Python to be read: report and status work without one.
    let o = common::bin().env("BFQI_PYTHON", "/nonexistent/python").arg("report").arg(d.join("one")).output().unwrap();
    ok(&o);

    // Its tuned config drives the other commands on the same env.
    let f =
        ok(&gym_bin(&py).args(["fitness"]).arg(d.join("one/spec.json")).arg("--tuned").arg(&best).output().unwrap());
    assert!(f.contains("(identical)"), "{f}");
    let cmp = d.join("cmp");
    let args = ["--learner", "both", "--datasets", "2", "--episodes", "30", "--iterations", "2", "--quiet"];
    ok(&gym_bin(&py)
        .arg("compare")
        .arg(&s)
        .arg("--tuned")
        .arg(&best)
        .args(args)
        .arg("--out")
        .arg(&cmp)
        .output()
        .unwrap());
    assert!(read(cmp.join("report.md")).contains("CartPole-v1"));
    let ro = d.join("rollout");
    let m = d.join("q.model");
    let r = gym_bin(&py)
        .arg("rollout")
        .arg("--tuned")
        .arg(&best)
        .args(["--episodes", "3", "--draw", "1", "--frames", "20", "--save-model"])
        .arg(&m)
        .arg("--out")
        .arg(&ro)
        .output()
        .unwrap();
    let text = ok(&r);
    assert!(text.contains("(identical)"), "the rollout replays the unit's evaluation episodes: {text}");
    let csv = read(ro.join("trajectory.csv"));
    assert!(csv.starts_with("episode,step,time,obs_0,obs_1,obs_2,obs_3,action,action_value,reward,q_0,q_1"), "{csv}");
    assert!(ro.join("episode-0.png").is_file());
    let rgb = std::process::Command::new(&py).args(["-c", "import pygame"]).output().unwrap().status.success();
    assert_eq!(ro.join("episode-0.gif").is_file(), rgb, "frames from render() where pygame renders rgb_array");
    let e = ok(&gym_bin(&py).arg("evaluate").arg(&m).args(["--episodes", "5", "--start", "eval"]).output().unwrap());
    assert!(e.contains("5 episodes from eval starts"), "{e}");
    let z = gym_bin(&py).arg("evaluate").arg(&m).args(["--start", "zero"]).output().unwrap();
    assert_eq!(z.status.code(), Some(2), "{}", String::from_utf8_lossy(&z.stderr));
    assert!(String::from_utf8_lossy(&z.stderr).contains("--start eval"));
}

#[test]
fn a_gymnasium_search_killed_mid_generation_resumes_to_the_same_result() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymsearch", "kill");
    let s = spec(&d);
    let slower = ["--episodes", "300", "--iterations", "3", "--datasets", "3", "--population", "6", "--jobs", "2"];
    let (whole, killed) = (d.join("whole"), d.join("killed"));
    ok(&search(&py, &s, &whole, &slower));
    let mut child = spawn_quiet(gym_bin(&py).arg("search").arg(&s).args(tiny_with(&slower)).arg("--out").arg(&killed));
    wait_for_entries(&killed.join("units"), 3, &mut child);
    child.kill().unwrap(); // SIGKILL: its workers see their input end and exit
    child.wait().unwrap();
    let stored = std::fs::read_dir(killed.join("units")).unwrap().count();
    assert!(stored < 6 * 3, "killed before the first generation finished ({stored} units stored)");
    ok(&gym_bin(&py).args(["search", "--resume"]).arg(&killed).arg("--quiet").output().unwrap());
    same(&whole, &killed, "after kill -9 and resume");
}

#[test]
fn a_gymnasium_search_through_slurm_matches_local() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymsearch", "slurm");
    let s = spec(&d);
    let (local, fake, real) = (d.join("local"), d.join("fake"), d.join("real"));
    ok(&search(&py, &s, &local, &[]));
    let support = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/support");
    let o = gym_bin(&py)
        .env("BFQI_SBATCH", support.join("fake-sbatch.sh"))
        // The stand-in's squeue: the executor asks squeue whether the array is gone.
        .env("BFQI_SQUEUE", support.join("fake-squeue.sh"))
        .arg("search")
        .arg(&s)
        .args(tiny_with(&["--executor", "slurm"]))
        .arg("--out")
        .arg(&fake)
        .output()
        .unwrap();
    ok(&o);
    same(&local, &fake, "stand-in sbatch vs local");
    if std::env::var("BFQI_REAL_SLURM").as_deref() != Ok("1") {
        eprintln!("BFQI_REAL_SLURM is not 1: the real-cluster check runs in CI (scripts/local-slurm.sh)");
        return;
    }
    ok(&search(&py, &s, &real, &["--executor", "slurm", "--slurm-time", "00:10:00"]));
    same(&local, &real, "real slurm vs local");
}

#[test]
fn a_batch_searches_a_gymnasium_env_then_compares_with_its_winner() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymsearch", "batch");
    let s = spec(&d);
    let plan = serde_json::json!({"jobs": [
        {"name": "search", "search": s, "presets": ["quick"], "episodes": 25, "datasets": 2, "iterations": 2,
         "population": 4, "generations": 1},
        {"name": "compare", "compare": s, "tuned": "from:search", "analysis": "iterations", "learner": "et",
         "datasets": 2, "episodes": 25, "iterations": 2}
    ]});
    let p = d.join("plan.json");
    std::fs::write(&p, plan.to_string()).unwrap();
    ok(&gym_bin(&py).arg("batch").arg(&p).arg("--dry-run").output().unwrap());
    let out = d.join("batch");
    ok(&gym_bin(&py).arg("batch").arg(&p).arg("--out").arg(&out).output().unwrap());
    let summary = read(out.join("summary.md"));
    assert_eq!(summary.matches("| finished |").count(), 2, "{summary}");
}
