//! Bad input gets one line naming the file and the full field path, exit 2, and leaves nothing
//! behind: never a panic, never an abort on a huge allocation.

mod common;
use common::{bin, empty_dir, json, read};

use std::path::Path;
use std::process::{Command, Output};

/// Runs `args` in `dir`; asserts exit 2 and a one-line message containing every one of `want`.
fn refused(dir: &Path, args: &[&str], want: &[&str]) -> String {
    let o: Output = bin().current_dir(dir).args(args).env("RUST_BACKTRACE", "0").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: not one line: {err}");
    for w in want {
        assert!(err.contains(w), "{args:?}: {err:?} does not contain {w:?}");
    }
    err
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    std::fs::write(dir.join(name), text).unwrap();
    name.to_string()
}

/// Nothing but the input files is left in `dir`.
fn nothing_created(dir: &Path, inputs: &[&str]) {
    let left: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !inputs.contains(&n.as_str()))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn malformed_spec_layers_name_their_file_and_field() {
    let d = empty_dir("bad", "layers");
    let s = write(&d, "s.json", r#"{"search": 5}"#);
    refused(&d, &["search", &s, "--generations", "1"], &["s.json: field search: invalid type: integer `5`"]);
    let s2 = write(&d, "s2.json", r#"{"search": {"stop": "x"}}"#);
    refused(&d, &["search", &s2, "--generations", "1"], &["s2.json: field search"]);
    let s3 = write(&d, "s3.json", "[1, 2]");
    refused(&d, &["search", &s3, "--seed", "3"], &["s3.json: a spec must be a JSON object, not an array"]);
    // A preset's error names the preset, not the spec it is applied to.
    let p = write(&d, "p.json", r#"{"search": {"ga": {"population": "many"}}}"#);
    refused(&d, &["search", "cartpole", "--preset", &p], &["p.json: field search.ga.population: invalid type"]);
    let p2 = write(&d, "p2.json", r#"{"search": {"ga": {"population": 1}}}"#);
    refused(&d, &["search", "cartpole", "--preset", &p2], &["p2.json: invalid search.ga.population = 1", "applied to"]);
    nothing_created(&d, &["s.json", "s2.json", "s3.json", "p.json", "p2.json"]);
}

#[test]
fn type_errors_inside_env_and_learners_keep_the_whole_path() {
    let d = empty_dir("bad", "paths");
    let full = |patch: &str| patched("cartpole", patch);
    let s = write(&d, "env.json", &full(r#"{"env": {"g": "9.8"}}"#));
    refused(&d, &["search", &s], &["env.json: field env.g: invalid type: string \"9.8\", expected f64"]);
    let s = write(&d, "eval.json", &full(r#"{"env": {"eval": {"steps": -1}}}"#));
    refused(&d, &["search", &s], &["eval.json: field env.eval.steps: invalid value"]);
    let s = write(&d, "learner.json", &full(r#"{"experiments": {"mlp": {"learner": {"hidden": "wide"}}}}"#));
    refused(&d, &["search", &s], &["learner.json: field experiments.mlp.learner.hidden: invalid type"]);
    let s = write(&d, "kind.json", &full(r#"{"experiments": {"et": {"learner": {"kind": "forest"}}}}"#));
    refused(&d, &["search", &s], &["kind.json: field experiments.et.learner.kind: unknown variant `forest`"]);
}

#[test]
fn a_tagged_objects_bad_tag_is_named_with_the_tag_in_its_path() {
    let d = empty_dir("bad", "tags");
    let s = write(&d, "name.json", &patched("cartpole", r#"{"env": {"name": "CARTPOLE"}}"#));
    refused(&d, &["search", &s], &["name.json: field env.name: unknown variant `CARTPOLE`", "`cartpole`"]);
    let mut v: serde_json::Value = serde_json::from_str(&patched("cartpole", "{}")).unwrap();
    v["experiments"]["mlp"]["claims"][0]["rule"] = serde_json::json!("bogus");
    let s = write(&d, "rule.json", &v.to_string());
    refused(&d, &["search", &s], &["rule.json: field experiments.mlp.claims[0].rule: unknown variant `bogus`"]);
    nothing_created(&d, &["name.json", "rule.json"]);
}

#[test]
fn an_empty_array_where_an_object_belongs_is_refused() {
    let d = empty_dir("bad", "array-object");
    let s = write(&d, "net.json", &patched("cartpole", r#"{"search": {"network": []}}"#));
    refused(
        &d,
        &["search", &s, "--out", "run"],
        &["net.json: field search.network: must be a JSON object, not an array"],
    );
    // A struct without defaults already refuses an empty array by its length.
    let s = write(&d, "eval.json", &patched("cartpole", r#"{"env": {"eval": []}}"#));
    refused(&d, &["search", &s, "--out", "run"], &["eval.json: field env.eval: invalid length 0"]);
    nothing_created(&d, &["net.json", "eval.json"]);
}

#[test]
fn huge_sizes_are_refused_with_their_range_before_anything_is_allocated() {
    let d = empty_dir("bad", "huge");
    let big = "1000000000000";
    refused(
        &d,
        &["search", "cartpole", "--population", big],
        &["invalid search.ga.population = 1000000000000", "2..=10000"],
    );
    refused(&d, &["search", "cartpole", "--episodes", big], &["invalid search.episodes", "transitions"]);
    refused(&d, &["run", "cartpole", "--episodes", big], &["invalid episodes", "transitions"]);
    refused(&d, &["run", "cartpole", "--trees", big], &["invalid learner.n_trees", "1..=10000"]);
    refused(&d, &["run", "cartpole", "--learner", "mlp", "--hidden", big], &["invalid learner.hidden", "1..=4096"]);
    refused(
        &d,
        &["compare", "cartpole", "--complexities", "1..1000000000000"],
        &["--complexities", "at most 1000 values"],
    );
    refused(&d, &["--jobs", "100000", "envs"], &["invalid --jobs = 100000: must be in 1..=1024"]);
    nothing_created(&d, &[]);
}

/// A copy of a shipped spec with `patch` merged in.
fn patched(env: &str, patch: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("searches/{env}.json"));
    let mut v: serde_json::Value = json(path);
    merge(&mut v, &serde_json::from_str(patch).unwrap());
    v.to_string()
}

#[test]
fn extreme_but_typed_values_are_caught_at_validation_with_their_field() {
    let d = empty_dir("bad", "extreme");
    let s = write(&d, "tau.json", &patched("cartpole", r#"{"env": {"tau": 1e308}}"#));
    let err = refused(
        &d,
        &["run", &s],
        &[
            "tau.json: invalid env.tau = 1e308: makes the cart-pole dynamics overflow to non-finite",
            "(the default is 0.02)",
        ],
    );
    assert!(!err.contains("00000000000000000000"), "a 300-digit number: {err}");
    // The constant at fault is found by trying each changed one alone: `g` is changed too, but harmless.
    for (patch, field) in [
        (r#"{"env": {"force": 1e308, "g": 9.81}}"#, "env.force = 1e308"),
        (r#"{"env": {"l": 1e-300}}"#, "env.l = 1e-300"),
    ] {
        let s = write(&d, "c.json", &patched("cartpole", patch));
        let err =
            refused(&d, &["search", &s, "--dry-run"], &[&format!("c.json: invalid {field}: makes the cart-pole")]);
        assert!(!err.contains("00000000000000000000"), "a 300-digit number: {err}");
    }
    // Finite but past what the learners take (Extra-Trees holds f32): caught at validation, not as
    // "bad data" naming nothing at the first fit.
    let s = write(&d, "l.json", &patched("cartpole", r#"{"env": {"l": 1e200}}"#));
    refused(
        &d,
        &["run", &s, "--learner", "et", "--datasets", "1", "--iterations", "1", "--episodes", "10", "--out", "out"],
        &["l.json: invalid env.l = 1e200: makes the cart-pole dynamics reach", "beyond the ±3.4e38 the learners take"],
    );
    let s = write(&d, "vf.json", &patched("cartpole", r#"{"search": {"network": {"validation_fraction": 0.999}}}"#));
    refused(
        &d,
        &["search", &s, "--quick"],
        &["vf.json: invalid search.network.validation_fraction = 0.999: must be in (0, 0.5]"],
    );
    let s = write(&d, "vf0.json", &patched("cartpole", r#"{"search": {"network": {"validation_fraction": 5e-324}}}"#));
    let err = refused(
        &d,
        &["search", &s, "--quick", "--out", "run"],
        &["vf0.json: invalid search.network.validation_fraction = 5e-324", "holds out no row"],
    );
    assert!(!err.contains("00000000000000000000"), "a 324-digit number: {err}");
    let s = write(&d, "pa.json", &patched("pendulum", r#"{"search": {"actions": "per_action"}}"#));
    refused(&d, &["search", &s], &["pa.json: invalid search.actions = per_action", "continuous"]);
    refused(&d, &["run", "pendulum", "--actions", "per-action"], &["invalid actions = per_action", "continuous"]);
    nothing_created(&d, &["tau.json", "c.json", "l.json", "vf.json", "vf0.json", "pa.json"]);
}

#[test]
fn a_best_json_off_its_gene_grid_is_refused_not_decoded() {
    let d = empty_dir("bad", "grid");
    let best = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/searches/cartpole/best.json");
    let mut v: serde_json::Value = json(best);
    v["chromosome"] = serde_json::json!([9, 9, 9, 9, 9]);
    let b = write(&d, "b.json", &v.to_string());
    refused(&d, &["reproduce", &b], &["b.json", "invalid chromosome = [9, 9, 9, 9, 9]: must lie in spec.search.genes"]);
    v["spec"]["search"]["genes"]["activations"] = serde_json::json!([]);
    let b = write(&d, "b2.json", &v.to_string());
    refused(&d, &["reproduce", &b], &["b2.json", "spec.search.genes.activations"]);
}

fn merge(base: &mut serde_json::Value, patch: &serde_json::Value) {
    match (base, patch) {
        (serde_json::Value::Object(b), serde_json::Value::Object(p)) => {
            for (k, v) in p {
                merge(b.entry(k.clone()).or_insert(serde_json::Value::Null), v);
            }
        }
        (b, p) => *b = p.clone(),
    }
}

#[test]
fn inputs_that_are_not_regular_files_or_repeat_a_key_are_refused() {
    let d = empty_dir("bad", "kinds");
    let dup = patched("cartpole", "{}").replacen("{", r#"{"seed": 1, "#, 1);
    let s = write(&d, "dup.json", &dup);
    refused(&d, &["search", &s], &["dup.json: duplicate key `seed`"]);
    std::fs::create_dir(d.join("dir.json")).unwrap();
    refused(&d, &["search", "dir.json"], &["dir.json: is a directory, not a file"]);
    refused(&d, &["search", "cartpole", "--preset", "dir.json"], &["dir.json: is a directory, not a file"]);
    std::os::unix::fs::symlink(d.join("nowhere.json"), d.join("dangling.json")).unwrap();
    refused(&d, &["compare", "cartpole", "--tuned", "dangling.json"], &["dangling.json: is a link to nothing"]);
    // A FIFO would block a reader forever: refused without opening it.
    let fifo = d.join("fifo.json");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let mut child =
        bin().current_dir(&d).args(["search", "fifo.json"]).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let started = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed().as_secs() > 20 {
            child.kill().unwrap();
            panic!("bfqi-ga blocked on a FIFO");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("fifo.json: is not a regular file"));
    // A `searches/<env>.json` that is not a file is refused, not replaced by the built-in copy.
    std::fs::create_dir_all(d.join("searches/cartpole.json")).unwrap();
    refused(&d, &["search", "cartpole"], &["searches/cartpole.json: is a directory, not a file"]);
    std::fs::create_dir_all(d.join("searches/tuned/bicycle.json")).unwrap();
    refused(
        &d,
        &["compare", "bicycle", "--tuned", "thesis", "--out", "cmp"],
        &["searches/tuned/bicycle.json: is a directory, not a file"],
    );
    assert!(!d.join("cmp").exists());
}

#[test]
fn flags_and_every_job_of_a_plan_are_checked_before_anything_is_created() {
    let d = empty_dir("bad", "before");
    for h in ["0", "NaN", "inf"] {
        refused(&d, &["search", "cartpole", "--quick", "--out", "run", "--max-hours", h], &["invalid --max-hours"]);
    }
    // clap's own refusals are one line too (the error and its tip, no usage block).
    refused(&d, &["search", "cartpole", "--max-hours", "-1"], &["unexpected argument '-1'", "tip:"]);
    let plan = write(
        &d,
        "plan.json",
        r#"{"jobs": [{"name": "s", "search": "cartpole", "presets": ["quick"]},
                     {"name": "c", "compare": "cartpole", "tuned": "from:s", "analysis": "bogus"}]}"#,
    );
    refused(&d, &["batch", &plan], &["plan.json: job 2 (c): field analysis: unknown variant `bogus`"]);
    let plan2 = write(&d, "plan2.json", r#"{"jobs": [{"name": "s", "search": "cartpole", "population": 1}]}"#);
    refused(&d, &["batch", &plan2], &["plan2.json: job 1 (s)", "search.ga.population = 1"]);
    let ok_plan = write(&d, "ok.json", r#"{"jobs": [{"name": "s", "search": "cartpole", "presets": ["quick"]}]}"#);
    refused(&d, &["batch", &ok_plan, "--until", "25:00"], &["invalid --until = 25:00"]);
    refused(&d, &["batch", &ok_plan, "--max-hours", "0"], &["invalid --max-hours"]);
    refused(&d, &["compare", "cartpole", "--datasets", "0", "--out", "cmp"], &["invalid datasets = 0"]);
    // A resumed comparison is what its compare.json says: a request flag is refused, not ignored.
    for flag in [["--datasets", "3"], ["--analysis", "all"], ["--tuned", "best.json"]] {
        let args = ["compare", "--resume", "cmp", flag[0], flag[1]];
        refused(&d, &args, &["'--resume <RUN_DIR>' cannot be used with", flag[0]]);
    }
    nothing_created(&d, &["plan.json", "plan2.json", "ok.json"]);
}

#[test]
fn a_search_in_which_every_unit_diverged_fails_with_exit_1() {
    let d = empty_dir("bad", "diverged");
    let s = write(&d, "lr.json", &patched("cartpole", r#"{"search": {"network": {"learning_rate": 1e300}}}"#));
    let o = bin()
        .current_dir(&d)
        .args(["search", &s, "--quick", "--population", "2", "--generations", "1", "--datasets", "1"])
        .args(["--episodes", "20", "--iterations", "2", "--out", "run", "--quiet"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("every setting diverged"), "{err}");
    assert!(err.contains("no tuned config, so no best.json"), "{err}");
    // The records are there to look at, but no best.json a consumer could take for a tuned config.
    let gen0 = read(d.join("run/generations.jsonl"));
    assert!(gen0.contains("\"fitness\":null"), "{gen0}");
    assert!(!d.join("run/best.json").exists(), "a best.json of no setting that scored");
    let state = json(d.join("run/state.json"));
    assert_eq!(state["state"], "failed", "{state}");
    assert!(state["reason"].as_str().unwrap().starts_with("every setting diverged"), "{state}");
    let o = bin().current_dir(&d).args(["status", "run"]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains(" failed ") && out.contains("failed: every setting diverged"), "{out}");
    // A best.json with fitness null (as earlier binaries wrote) is refused by every consumer.
    let best = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/searches/cartpole/best.json");
    let mut v: serde_json::Value = json(best);
    v["fitness"] = serde_json::Value::Null;
    v.as_object_mut().unwrap().remove("validation");
    let b = write(&d, "null.json", &v.to_string());
    let want = ["null.json: invalid fitness = null", "every setting of this search diverged"];
    refused(&d, &["reproduce", &b], &want);
    refused(&d, &["compare", "cartpole", "--tuned", &b, "--out", "cmp"], &want);
    refused(&d, &["fitness", "cartpole", "--tuned", &b], &want);
    refused(&d, &["search", "cartpole", "--seed-config", &b, "--dry-run"], &want);
    assert!(!d.join("cmp").exists());
}

#[test]
fn a_full_disk_while_plotting_fails_the_run_with_exit_1_and_it_resumes() {
    let d = empty_dir("bad", "disk-full");
    // The plot's temporary file leads to /dev/full: its write fails with ENOSPC, as on a full disk.
    std::fs::create_dir(d.join("run")).unwrap();
    std::os::unix::fs::symlink("/dev/full", d.join("run/.fitness.tmp.png")).unwrap();
    let args = ["search", "cartpole", "--quick", "--population", "2", "--generations", "1", "--datasets", "1"];
    let o = bin()
        .current_dir(&d)
        .args(args)
        .args(["--episodes", "20", "--iterations", "1", "--out", "run", "--quiet"])
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(err.contains("error: run/fitness.png: No space left on device"), "{err}");
    assert!(!err.contains("ImageError") && !err.contains("Os {"), "a debug dump: {err}");
    assert!(std::fs::symlink_metadata(d.join("run/.fitness.tmp.png")).is_err(), "the temporary file is left");
    let state = json(d.join("run/state.json"));
    assert_eq!(state["state"], "failed", "{state}");
    assert!(state["reason"].as_str().unwrap().contains("run/fitness.png: No space left on device"), "{state}");
    let o = bin().current_dir(&d).args(["status", "run"]).output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains(" failed ") && out.contains("No space left on device"), "{out}");
    // With room again, the search resumes from its stored units and finishes.
    let o = bin().current_dir(&d).args(["search", "--resume", "run", "--quiet"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(json(d.join("run/state.json"))["state"], "finished");
    assert!(d.join("run/fitness.png").is_file() && d.join("run/best.json").is_file());
}

#[test]
fn diverged_datasets_have_rows_in_run_csv() {
    let d = empty_dir("bad", "runcsv");
    let o = bin()
        .current_dir(&d)
        .args(["run", "cartpole", "--learner", "mlp", "--learning-rate", "1e300", "--datasets", "2"])
        .args(["--iterations", "2", "--episodes", "10", "--out", "out"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = read(d.join("out/run.csv"));
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    for ds in ["0", "1"] {
        let row =
            rows.iter().find(|r| r.starts_with(&format!("{ds},"))).unwrap_or_else(|| panic!("no row of {ds}: {csv}"));
        assert!(row.ends_with("non-finite training loss"), "{row}");
    }
}

#[test]
fn a_dataset_too_small_for_the_network_names_the_episode_count() {
    let d = empty_dir("bad", "tiny-data");
    refused(
        &d,
        &[
            "search",
            "cartpole",
            "--quick",
            "--episodes",
            "1",
            "--population",
            "2",
            "--generations",
            "1",
            "--out",
            "run",
            "--quiet",
        ],
        &["invalid search.episodes = 1: must be ≥ 2", "search dataset 2 has 0 transition(s) of action 0"],
    );
    assert!(!d.join("run").exists(), "refused at validation, before the run directory");
}

#[test]
fn too_few_episodes_from_a_preset_are_refused_at_validation_naming_the_preset() {
    let d = empty_dir("bad", "preset-episodes");
    let p = write(&d, "few.json", r#"{"search": {"episodes": 1}}"#);
    let args = ["search", "cartpole", "--quick", "--preset", &p, "--population", "2", "--generations", "1"];
    let err = refused(
        &d,
        &[&args[..], &["--out", "run", "--quiet"]].concat(),
        &[
            "few.json: invalid search.episodes = 1: must be ≥ 2: with 1, search dataset 2 has 0 transition(s) of action 0",
        ],
    );
    assert!(err.contains("(applied to <built-in searches/cartpole.json>)"), "{err}");
    // A batch job's preset is checked the same way, before the batch starts.
    let plan =
        write(&d, "plan.json", r#"{"jobs": [{"name": "s", "search": "cartpole", "presets": ["quick", "few.json"]}]}"#);
    refused(&d, &["batch", &plan], &["plan.json: job 1 (s): few.json: invalid search.episodes = 1: must be ≥ 2"]);
    nothing_created(&d, &["few.json", "plan.json"]);
}

#[test]
fn every_networks_validation_fraction_must_hold_out_a_row() {
    let d = empty_dir("bad", "holdout");
    let s = write(
        &d,
        "mlp.json",
        &patched("cartpole", r#"{"experiments": {"mlp": {"learner": {"validation_fraction": 5e-324}}}}"#),
    );
    refused(
        &d,
        &["compare", &s, "--out", "cmp"],
        &["mlp.json: invalid experiments.mlp.learner.validation_fraction = 5e-324", "holds out no row"],
    );
    // From a preset, the preset is named, with the full field path.
    let p = write(&d, "vf.json", r#"{"experiments": {"mlp": {"learner": {"validation_fraction": 5e-324}}}}"#);
    let err = refused(
        &d,
        &["search", "cartpole", "--preset", &p, "--out", "run"],
        &["vf.json: invalid experiments.mlp.learner.validation_fraction = 5e-324", "holds out no row"],
    );
    assert!(!err.contains("00000000000000000000"), "a 324-digit number: {err}");
    // A comparison's networks take the tuned config's fraction: its file is named.
    let mut t: serde_json::Value = json(Path::new(env!("CARGO_MANIFEST_DIR")).join("searches/tuned/cartpole.json"));
    t["network"]["validation_fraction"] = serde_json::json!(5e-324);
    let t = write(&d, "t.json", &t.to_string());
    refused(
        &d,
        &["compare", "cartpole", "--tuned", &t, "--learner", "mlp", "--out", "cmp"],
        &["t.json: invalid network.validation_fraction = 5e-324", "holds out no row"],
    );
    nothing_created(&d, &["mlp.json", "vf.json", "t.json"]);
}

#[test]
fn plan_fields_that_do_not_apply_to_a_job_or_are_out_of_range_are_refused() {
    let d = empty_dir("bad", "plan-fields");
    let job = |analysis: &str, field: &str| {
        format!(
            r#"{{"jobs": [{{"name": "c", "compare": "cartpole", "analysis": "{analysis}", "learner": "et", {field}}}]}}"#
        )
    };
    for c in ["[]", "[0]", "[3]"] {
        let plan = write(&d, "plan.json", &job("iterations", &format!(r#""complexities": {c}"#)));
        refused(
            &d,
            &["batch", &plan, "--dry-run"],
            &["plan.json: job 1 (c): invalid complexities", "does not apply to analysis `iterations`"],
        );
    }
    // On a complexity job, a 0 is the plan's field at fault, not the learner's max_depth.
    let plan = write(&d, "plan.json", &job("complexity", r#""complexities": [0]"#));
    let err = refused(
        &d,
        &["batch", &plan, "--dry-run"],
        &["plan.json: job 1 (c): invalid complexities = [0]: must list 1 to 1000 complexities, each in 1..=4096"],
    );
    assert!(!err.contains("max_depth"), "{err}");
    let plan = write(&d, "plan.json", &job("iterations", r#""sizes": [10]"#));
    refused(
        &d,
        &["batch", &plan],
        &["plan.json: job 1 (c): invalid sizes = [10]: does not apply to analysis `iterations`"],
    );
    let plan = write(&d, "plan.json", &job("samples", r#""episodes": 10"#));
    refused(
        &d,
        &["batch", &plan],
        &["plan.json: job 1 (c): invalid episodes = 10: does not apply to analysis `samples`"],
    );
    // The same request from the command line is refused alike.
    refused(
        &d,
        &["compare", "cartpole", "--analysis", "iterations", "--complexities", "1..3", "--out", "cmp"],
        &["invalid complexities = [1, 2, 3]: does not apply to analysis `iterations`"],
    );
    nothing_created(&d, &["plan.json"]);
}
