//! What goes wrong with a gymnasium env is said in one line naming the env, with exit 2 for a
//! setup the user must fix (no Python, no gymnasium, an unknown id, a continuous action space)
//! and exit 1 for a run that failed (a worker that crashes, hangs or returns non-finite
//! observations); nothing computed is lost, and a resume recomputes the unit that failed
//! (issue 39). The misbehaving envs are in `python/bfqi_gym_testenvs.py`.

mod common;
use common::gym::{gym_bin, python, write_spec};
use common::{TempDir, empty_dir, read, tiny_with, wait_for_entries};

use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

fn spec(dir: &TempDir, name: &str, env: Value) -> PathBuf {
    write_spec(&dir.join(format!("{name}.json")), "cartpole", env)
}

/// `bfqi-ga dataset SPEC` and its exit code and one-line message.
fn dataset(py: &str, spec: &Path, out: &Path) -> (Option<i32>, String) {
    let o = gym_bin(py).arg("dataset").arg(spec).args(["--episodes", "20", "--out"]).arg(out).output().unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stderr).trim().to_string())
}

fn one_line(err: &str) {
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn setup_problems_are_refused_before_anything_runs() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymfail", "setup");
    let out = d.join("d.csv");
    let cases = [
        (
            json!({"id": "CartPole-v1", "python": "/nonexistent/python3"}),
            vec!["env.python", "cannot be started", "CartPole-v1"],
        ),
        (json!({"id": "NoSuchEnv-v0"}), vec!["env.id", "NoSuchEnv", "gymnasium.make"]),
        (
            json!({"id": "Pendulum-v1"}),
            vec!["env.actions", "continuous action space", "supported are Discrete, and Box with env.actions"],
        ),
        (json!({"id": "Pendulum-v1", "actions": [-2.0, 5.0]}), vec!["env.actions[1]", "bounds [-2, 2]"]),
        (json!({"id": "CartPole-v1", "horizon": 800}), vec!["env.horizon = 800", "max_episode_steps", "500"]),
        (json!({"id": "CartPole-v1", "actions": [0, 3]}), vec!["env.actions[1] = 3:", "0..2"]),
        // A program that starts but is no Python running the worker.
        (json!({"id": "CartPole-v1", "python": "/bin/false"}), vec!["env.python", "/bin/false", "CartPole-v1"]),
        // Reset options the env refuses are refused with the spec, naming their field.
        (json!({"id": "CartPole-v1", "reset_options": {"low": "a"}}), vec!["env.reset_options", "reset"]),
        (
            json!({"id": "CartPole-v1", "eval": {"reset_options": {"low": "a"}}}),
            vec!["env.eval.reset_options", "reset"],
        ),
    ];
    for (i, (env, words)) in cases.into_iter().enumerate() {
        let s = spec(&d, &format!("case{i}"), env);
        let (code, err) = dataset(&py, &s, &out);
        assert_eq!(code, Some(2), "bad input: {err}");
        one_line(&err);
        assert!(!err.contains("Scalar(") && !err.contains("Some("), "Rust's debug forms: {err}");
        for w in words {
            assert!(err.contains(w), "{w:?} not in: {err}");
        }
        let o = gym_bin(&py).arg("search").arg(&s).args(["--quick", "--dry-run"]).output().unwrap();
        assert_eq!(o.status.code(), Some(2), "search --dry-run refuses it too");
    }
    assert!(!out.exists(), "nothing written");
}

#[test]
fn a_python_without_gymnasium_or_numpy_is_named_with_the_install_command() {
    let Some(py) = python() else { return };
    for module in ["gymnasium", "numpy"] {
        let d = empty_dir("gymfail", &format!("no-{module}"));
        without(&py, &d, module);
    }
}

/// `module` shadowed by a package that fails to import, as a Python without it does; the worker
/// still reports it (the frame saying so needs no numpy) and the tool prints the install line.
fn without(py: &str, d: &TempDir, module: &str) {
    let shadow = d.join(format!("shadow/{module}"));
    std::fs::create_dir_all(&shadow).unwrap();
    std::fs::write(shadow.join("__init__.py"), format!("raise ModuleNotFoundError(\"No module named '{module}'\")\n"))
        .unwrap();
    let s = spec(d, "cp", json!({"id": "CartPole-v1"}));
    let o = common::bin()
        .env("BFQI_PYTHON", py)
        .env("PYTHONPATH", d.join("shadow"))
        .arg("dataset")
        .arg(&s)
        .args(["--episodes", "5", "--out"])
        .arg(d.join("d.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).trim().to_string();
    assert_eq!(o.status.code(), Some(2), "{err}");
    one_line(&err);
    assert!(err.contains("cannot import gymnasium") && err.contains("-m pip install gymnasium numpy"), "{err}");
    assert!(err.contains(&format!("No module named '{module}'")), "{err}");
}

#[test]
fn workers_that_crash_hang_raise_or_return_nan_fail_the_run_naming_the_env() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymfail", "runtime");
    let out = d.join("d.csv");
    let cases = [
        ("BfqiCrash-v0", json!({}), vec!["the worker", "exited (exit status: 7)", "during dataset episodes"]),
        ("BfqiHang-v0", json!({"timeout_s": 1.5}), vec!["did not answer", "within 1.5 s (env.timeout_s)"]),
        ("BfqiNan-v0", json!({}), vec!["non-finite observation (NaN)", "at step 3 of dataset episode 0"]),
        ("BfqiRaise-v0", json!({}), vec!["RuntimeError: the simulator lost its state"]),
    ];
    for (id, extra, words) in cases {
        let mut env = json!({"id": format!("bfqi_gym_testenvs:{id}"), "kwargs": {"at": 3}});
        for (k, v) in extra.as_object().unwrap() {
            env[k] = v.clone();
        }
        let s = spec(&d, id, env);
        let t = Instant::now();
        let (code, err) = dataset(&py, &s, &out);
        assert_eq!(code, Some(1), "a failed run, not bad input: {err}");
        one_line(&err);
        assert!(err.contains(id), "names the env: {err}");
        for w in words {
            assert!(err.contains(w), "{w:?} not in: {err}");
        }
        assert!(t.elapsed() < Duration::from_secs(30), "{id} took {:?}", t.elapsed());
        assert!(!out.exists(), "no dataset from a failed run");
    }
}

#[test]
fn a_search_whose_worker_crashes_keeps_its_units_and_resumes_to_the_uninterrupted_result() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymfail", "resume");
    // Cart-pole that kills its worker on every step while the flag file exists.
    let flag = d.join("crash-now");
    let env = json!({"id": "bfqi_gym_testenvs:BfqiCrash-v0", "kwargs": {"at": 1, "flag": flag.to_str().unwrap()},
                     "horizon": 200, "gamma": 1.0, "eval": {"episodes": 2}});
    let s = spec(&d, "crashy", env);
    let slower = ["--episodes", "200", "--iterations", "3", "--datasets", "3", "--population", "6", "--jobs", "2"];
    let run = |out: &Path| -> Output {
        gym_bin(&py).arg("search").arg(&s).args(tiny_with(&slower)).arg("--out").arg(out).output().unwrap()
    };
    let whole = d.join("whole");
    let o = run(&whole);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let crashed = d.join("crashed");
    let mut child = gym_bin(&py)
        .arg("search")
        .arg(&s)
        .args(tiny_with(&slower))
        .arg("--out")
        .arg(&crashed)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let units = crashed.join("units");
    wait_for_entries(&units, 2, &mut child);
    std::fs::write(&flag, "").unwrap();
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("BfqiCrash-v0") && err.contains("exited"), "{err}");
    let kept = std::fs::read_dir(&units).unwrap().count();
    assert!(kept >= 2, "the units stored before the crash are kept ({kept})");

    std::fs::remove_file(&flag).unwrap();
    let r = gym_bin(&py).args(["search", "--resume"]).arg(&crashed).arg("--quiet").output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
        assert_eq!(read(whole.join(f)), read(crashed.join(f)), "{f}: crashed and resumed vs whole");
    }

    // A worker that dies while the first dataset is collected, before any unit or state.json:
    // state.json records the failure, `status` shows it, and a resume starts the search.
    std::fs::write(&flag, "").unwrap();
    let first = d.join("first");
    let o = run(&first);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    let state: Value = serde_json::from_str(&read(first.join("state.json"))).unwrap();
    assert_eq!(state["state"], "failed", "{state}");
    assert!(state["reason"].as_str().is_some_and(|r| r.contains("exited") && r.contains("dataset")), "{state}");
    let st = gym_bin(&py).arg("status").arg(&first).output().unwrap();
    let shown = String::from_utf8_lossy(&st.stdout);
    assert!(shown.contains("failed") && shown.contains("exited") && !shown.contains("not started"), "{shown}");
    std::fs::remove_file(&flag).unwrap();
    let r = gym_bin(&py).args(["search", "--resume"]).arg(&first).arg("--quiet").output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(read(whole.join("best.json")), read(first.join("best.json")), "failed first, resumed vs whole");
}

#[test]
fn a_rollout_whose_render_fails_keeps_its_trajectory_and_plots() {
    let Some(py) = python() else { return };
    let d = empty_dir("gymfail", "render");
    // Cart-pole that offers rgb_array rendering, but whose render() raises.
    let env = "gymnasium:bfqi_gym_testenvs:BfqiNoRender-v0";
    let models = d.join("models");
    let run = ["run", env, "--algo", "fqi", "--learner", "et", "--iterations", "2", "--datasets", "1"];
    let o = gym_bin(&py).args(run).args(["--episodes", "10", "--save-model"]).arg(&models).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = d.join("rollout");
    let o = gym_bin(&py)
        .arg("rollout")
        .arg(models.join("dataset-0.model"))
        .args(["--episodes", "2", "--draw", "1", "--frames", "5", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("no display for render()") && err.contains("without frames"), "{err}");
    assert!(read(out.join("trajectory.csv")).lines().count() > 2);
    assert!(out.join("episode-0.png").is_file() && !out.join("episode-0.gif").exists());
}
