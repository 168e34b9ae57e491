//! Bad input gets one line naming the file and the full field path, exit 2, and leaves nothing
//! behind: never a panic, never an abort on a huge allocation.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_bfqi-ga"))
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bfqi-bad-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

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
    let d = tmp("layers");
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
    let d = tmp("paths");
    let full = |patch: &str| patched("cartpole", patch);
    let s = write(&d, "env.json", &full(r#"{"env": {"g": "9.8"}}"#));
    refused(&d, &["search", &s], &["env.json: field env.g: invalid type: string \"9.8\", expected f64"]);
    let s = write(&d, "eval.json", &full(r#"{"env": {"eval": {"steps": -1}}}"#));
    refused(&d, &["search", &s], &["eval.json: field env.eval.steps: invalid value"]);
    let s = write(&d, "learner.json", &full(r#"{"experiments": {"mlp": {"learner": {"hidden": "wide"}}}}"#));
    refused(&d, &["search", &s], &["learner.json: field experiments.mlp.learner.hidden: invalid type"]);
    let s = write(&d, "kind.json", &full(r#"{"experiments": {"et": {"learner": {"kind": "forest"}}}}"#));
    refused(&d, &["search", &s], &["kind.json: field experiments.et.learner: unknown variant `forest`"]);
}

#[test]
fn huge_sizes_are_refused_with_their_range_before_anything_is_allocated() {
    let d = tmp("huge");
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
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    merge(&mut v, &serde_json::from_str(patch).unwrap());
    v.to_string()
}

#[test]
fn extreme_but_typed_values_are_caught_at_validation_with_their_field() {
    let d = tmp("extreme");
    let s = write(&d, "tau.json", &patched("cartpole", r#"{"env": {"tau": 1e308}}"#));
    let err = refused(&d, &["run", &s], &["tau.json: invalid env = cartpole settings", "non-finite"]);
    assert!(!err.contains("00000000000000000000"), "a 300-digit number: {err}");
    let s = write(&d, "vf.json", &patched("cartpole", r#"{"search": {"network": {"validation_fraction": 0.999}}}"#));
    refused(
        &d,
        &["search", &s, "--quick"],
        &["vf.json: invalid search.network.validation_fraction = 0.999: must be in (0, 0.5]"],
    );
    let s = write(&d, "pa.json", &patched("pendulum", r#"{"search": {"actions": "per_action"}}"#));
    refused(&d, &["search", &s], &["pa.json: invalid search.actions = per_action", "continuous"]);
    refused(&d, &["run", "pendulum", "--actions", "per-action"], &["invalid actions = per_action", "continuous"]);
    nothing_created(&d, &["tau.json", "vf.json", "pa.json"]);
}

#[test]
fn a_best_json_off_its_gene_grid_is_refused_not_decoded() {
    let d = tmp("grid");
    let best = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/searches/cartpole/best.json");
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(best).unwrap()).unwrap();
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
