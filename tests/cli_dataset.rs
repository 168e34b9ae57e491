//! `bfqi-ga dataset` and `bfqi-ga envs` through the real binary.

mod common;
use common::{TempDir, bin, empty_dir, read};

use std::path::Path;
use std::process::Output;

/// A directory for one test's CSV files, removed when the test ends.
fn tmp(test: &str) -> TempDir {
    empty_dir("dataset", test)
}

fn dataset(args: &[&str], out: &Path) -> Output {
    bin().arg("dataset").args(args).arg("--out").arg(out).output().unwrap()
}

#[test]
fn same_seed_gives_byte_identical_csv_for_any_thread_count() {
    let d = tmp("threads");
    let (a, b, c) = (d.join("a.csv"), d.join("b.csv"), d.join("c.csv"));
    assert!(dataset(&["bicycle", "--episodes", "50", "--seed", "3", "--jobs", "1"], &a).status.success());
    assert!(dataset(&["bicycle", "--episodes", "50", "--seed", "3", "--jobs", "2"], &b).status.success());
    assert!(dataset(&["bicycle", "--episodes", "50", "--seed", "4"], &c).status.success());
    let (a, b, c) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap(), std::fs::read(c).unwrap());
    assert_eq!(a, b);
    assert_ne!(a, c);
}

#[test]
fn csv_has_the_documented_schema_and_round_trips_floats() {
    let d = tmp("schema");
    let p = d.join("pendulum.csv");
    let o = dataset(&["pendulum", "--episodes", "2", "--seed", "1"], &p);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = read(&p);
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "episode,step,state_0,state_1,state_2,action,reward,next_state_0,next_state_1,next_state_2,terminated,truncated"
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 400);
    // The CSV must hold exactly the in-memory dataset.
    let env = bfqi_ga::env::EnvConfig::by_name("pendulum").unwrap();
    let d =
        bfqi_ga::dataset::collect(env.env(), 2, bfqi_ga::dataset::dataset_seed(1, bfqi_ga::dataset::Role::Compare, 0))
            .unwrap();
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r[2].parse::<f64>().unwrap(), d.state[i * 3]);
        assert_eq!(r[5].parse::<f64>().unwrap(), d.action[i]);
        assert_eq!(r[6].parse::<f64>().unwrap(), d.reward[i]);
        assert_eq!(r[9].parse::<f64>().unwrap(), d.next_state[i * 3 + 2]);
        assert_eq!(r[10], "0");
        // The pendulum never fails: each episode's last transition is its horizon's cut.
        assert_eq!(r[11], if (i + 1) % 200 == 0 { "1" } else { "0" }, "row {i}");
    }
    // Torques are continuous in [-2, 2).
    assert!(rows.iter().all(|r| r[5].parse::<f64>().unwrap().abs() <= 2.0));
}

#[test]
fn cartpole_actions_are_indices_and_failures_terminate() {
    let d = tmp("cartpole");
    let p = d.join("cartpole.csv");
    assert!(dataset(&["cartpole", "--episodes", "20"], &p).status.success());
    let text = read(&p);
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().all(|r| r[6] == "0" || r[6] == "1"));
    assert!(rows.iter().any(|r| r[12] == "1"));
}

fn assert_bad_input(args: &[&str], needle: &str) {
    let o = bin().args(args).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{args:?}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(needle), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "one-line error: {err}");
}

#[test]
fn bad_input_is_a_one_line_error_with_exit_code_2() {
    let d = tmp("bad");
    let out = d.join("x.csv");
    let out = out.to_str().unwrap();
    assert_bad_input(&["dataset", "acrobot", "--episodes", "5", "--out", out], "pendulum, cartpole, bicycle");
    assert_bad_input(&["dataset", "cartpole", "--episodes", "0", "--out", out], "--episodes");
    assert_bad_input(
        &["dataset", "cartpole", "--episodes", "5", "--out", "/nonexistent-dir/x.csv"],
        "/nonexistent-dir/x.csv",
    );
    assert_bad_input(&["dataset", "cartpole", "--episodes", "5", "--out", "x.txt"], "invalid --out = x.txt");
    assert!(!Path::new("x.txt").exists());
}

#[test]
fn help_lists_every_subcommand_and_envs_lists_every_environment() {
    let o = bin().arg("--help").output().unwrap();
    let help = String::from_utf8_lossy(&o.stdout);
    for c in ["search", "compare", "run", "reproduce", "batch", "status", "report", "export", "dataset", "bench"] {
        assert!(help.contains(&format!("  {c} ")), "--help lacks {c}");
    }
    let o = bin().arg("envs").output().unwrap();
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    for name in ["pendulum", "cartpole", "bicycle", "reward_factor=15.0", "gamma 0.98"] {
        assert!(s.contains(name), "envs lacks {name}: {s}");
    }
}

#[test]
fn parquet_and_csv_files_read_back_to_the_dataset_runs_learn_from() {
    let d = tmp("formats");
    let env = bfqi_ga::env::EnvConfig::by_name("cartpole").unwrap();
    let seed = bfqi_ga::dataset::dataset_seed(5, bfqi_ga::dataset::Role::Search, 2);
    let want = bfqi_ga::dataset::collect(env.env(), 30, seed).unwrap();
    for name in ["c.parquet", "c.csv"] {
        let p = d.join(name);
        let o = dataset(&["cartpole", "--episodes", "30", "--seed", "5", "--role", "search", "--index", "2"], &p);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(bfqi_ga::dataset::table::read(&p).unwrap(), want, "{name}");
    }
}
