//! Messages that must read as text: no control bytes from a damaged file, no `Some(…)`, the flag
//! at fault named rather than the spec, a model file's size checked before it is read, and the
//! caps `validate` enforces written where the README documents it.

mod common;
use common::{bin, empty_dir, read, split_info, varint, with_body};

use std::path::Path;
use std::process::Output;

/// Runs `args` in `dir`; asserts exit `code` and a one-line message containing every one of `want`.
fn fails(dir: &Path, args: &[&str], code: i32, want: &[&str]) -> String {
    let o: Output = bin().current_dir(dir).args(args).env("RUST_BACKTRACE", "0").output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: not one line: {err:?}");
    for w in want {
        assert!(err.contains(w), "{args:?}: {err:?} does not contain {w:?}");
    }
    err
}

/// A one-generation search of two individuals on one small dataset, in `dir/run`.
fn tiny_search(dir: &Path) {
    let o = bin()
        .current_dir(dir)
        .args(["search", "cartpole", "--quick", "--population", "2", "--generations", "1", "--datasets", "1"])
        .args(["--episodes", "20", "--iterations", "1", "--out", "run", "--quiet"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The model file `bytes` with its info JSON (the body's first field, a postcard string: a varint
/// length, then the text) edited by `edit`, its checksum made right again.
fn with_info(bytes: &[u8], edit: impl Fn(&mut serde_json::Value)) -> Vec<u8> {
    let (text, rest) = split_info(&bytes[10..bytes.len() - 8]);
    let mut info: serde_json::Value = serde_json::from_str(&text).unwrap();
    edit(&mut info);
    let text = info.to_string();
    let mut new = Vec::new();
    varint(text.len(), &mut new);
    new.extend_from_slice(text.as_bytes());
    new.extend_from_slice(rest);
    with_body(bytes, &new)
}

#[test]
fn control_bytes_in_a_model_file_are_escaped_in_its_message() {
    let d = empty_dir("msg", "model-controls");
    let o = bin()
        .current_dir(&d)
        .args(["run", "cartpole", "--learner", "et", "--trees", "2", "--datasets", "1", "--iterations", "1"])
        .args(["--episodes", "20", "--out", "out", "--save-model", "models"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let model = std::fs::read(d.join("models/dataset-0.model")).unwrap();
    // A name with a bell and a newline, a number that is a string with a bell.
    let named = with_info(&model, |v| v["env"]["name"] = serde_json::json!("cart\u{7}pole\n"));
    std::fs::write(d.join("name.model"), named).unwrap();
    let err = fails(&d, &["evaluate", "name.model"], 2, &["name.model: model info: field env.name: unknown variant"]);
    assert!(err.contains(r"`cart\u{7}pole\n`"), "{err:?}");
    assert!(!err.trim_end().chars().any(char::is_control), "a control character: {err:?}");
    let g = with_info(&model, |v| v["env"]["g"] = serde_json::json!("x\u{7}y"));
    std::fs::write(d.join("g.model"), g).unwrap();
    let err = fails(&d, &["evaluate", "g.model"], 2, &["g.model: model info: field env.g: invalid type: string"]);
    assert!(!err.trim_end().chars().any(char::is_control), "a control character: {err:?}");
}

#[test]
fn a_model_file_past_the_size_cap_is_refused_before_it_is_read() {
    let d = empty_dir("msg", "model-size");
    // Sparse: 5 GiB of nothing, so the test costs no disk, and reading it would cost 5 GiB of memory.
    let f = std::fs::File::create(d.join("big.model")).unwrap();
    f.set_len(5 << 30).unwrap();
    let started = std::time::Instant::now();
    fails(
        &d,
        &["evaluate", "big.model"],
        2,
        &["big.model: is 5368709120 bytes (5.0 GiB); model files are capped at 4294967296 bytes (4 GiB)"],
    );
    fails(&d, &["rollout", "big.model"], 2, &["big.model: is 5368709120 bytes"]);
    assert!(started.elapsed().as_secs() < 10, "the file was read: {:?}", started.elapsed());
}

#[test]
fn a_reports_score_mismatch_prints_the_scores_not_options() {
    let d = empty_dir("msg", "report-some");
    tiny_search(&d);
    let path = d.join("run/generations.jsonl");
    let mut g: serde_json::Value = serde_json::from_str(read(&path).lines().next().unwrap()).unwrap();
    g["individuals"][0]["scores"][0] = serde_json::json!(1.5);
    std::fs::write(&path, format!("{g}\n")).unwrap();
    let err = fails(
        &d,
        &["report", "run"],
        2,
        &["run/generations.jsonl: generation 0 individual 0 dataset 0 records score 1.5, but run/units/"],
    );
    assert!(!err.contains("Some("), "{err}");
    g["individuals"][0]["scores"][0] = serde_json::Value::Null;
    std::fs::write(&path, format!("{g}\n")).unwrap();
    let err = fails(&d, &["report", "run"], 2, &["records score null (diverged), but"]);
    assert!(!err.contains("None") && !err.contains("Some("), "{err}");
}

#[test]
fn too_many_seed_configs_are_blamed_on_the_flag_with_its_limit() {
    let d = empty_dir("msg", "seed-configs");
    let args = ["search", "cartpole", "--quick", "--population", "2", "--dry-run"];
    let three = ["--seed-config", "thesis", "--seed-config", "thesis", "--seed-config", "thesis"];
    let err = fails(
        &d,
        &[&args[..], &three].concat(),
        2,
        &["invalid --seed-config = given 3 times: at most search.ga.population = 2 times"],
    );
    assert!(!err.contains("cartpole.json") && !err.contains("search.seeded"), "{err}");
}

#[test]
fn validates_caps_are_documented_in_the_readme_and_enforced() {
    use bfqi_ga::limits::{VALIDATE_DATASETS, VALIDATE_TOP};
    let readme = read(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md"));
    let thousands = |n: usize| {
        let s = n.to_string();
        let mut out = String::new();
        for (i, c) in s.chars().enumerate() {
            if i > 0 && (s.len() - i).is_multiple_of(3) {
                out.push(',');
            }
            out.push(c);
        }
        out
    };
    for doc in [
        format!("`--top` 1–{VALIDATE_TOP} settings"),
        format!("`--datasets` 1–{} validation", thousands(VALIDATE_DATASETS)),
    ] {
        assert!(readme.contains(&doc), "README.md does not document {doc:?}");
    }
    let d = empty_dir("msg", "validate-caps");
    tiny_search(&d);
    let top = (VALIDATE_TOP + 1).to_string();
    fails(
        &d,
        &["validate", "run", "--top", &top, "--datasets", "2"],
        2,
        &[&format!("invalid validate.top = {top}: must be in 1..={VALIDATE_TOP}")],
    );
    let datasets = (VALIDATE_DATASETS + 1).to_string();
    fails(
        &d,
        &["validate", "run", "--top", "2", "--datasets", &datasets],
        2,
        &[&format!("invalid validate.datasets = {datasets}: must be in 1..={VALIDATE_DATASETS}")],
    );
}

#[test]
fn a_tiny_time_budget_is_printed_short() {
    let d = empty_dir("msg", "max-hours");
    let o = bin()
        .current_dir(&d)
        .args(["search", "cartpole", "--quick", "--population", "2", "--generations", "1", "--datasets", "1"])
        .args(["--episodes", "20", "--iterations", "1", "--out", "run", "--quiet", "--max-hours", "1e-300"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "a budget's stop exits 0: {err}");
    assert!(err.contains("time budget of 1e-300 h reached"), "{err}");
    assert!(!err.contains("0.0000"), "{err}");
}

#[test]
fn a_gymnasium_action_is_named_as_written_not_as_rust_debugs_it() {
    // A spec given by the user is probed when read (a stale `env.probed` is refused), so this needs
    // a Python with gymnasium.
    // (`fails` runs the binary with this process's environment, so with the same Python.)
    if common::gym::python().is_none() {
        return;
    }
    let d = empty_dir("msg", "gym-action");
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/searches/cartpole-v1/spec.json");
    let mut spec: serde_json::Value = serde_json::from_str(&read(&committed)).unwrap();
    spec["env"]["actions"] = serde_json::json!([0, 5]);
    std::fs::write(d.join("spec.json"), spec.to_string()).unwrap();
    let err = fails(&d, &["search", "spec.json", "--dry-run"], 2, &["spec.json", "env.actions[1] = 5:", "0..2"]);
    assert!(!err.contains("Scalar") && !err.contains("Some("), "{err}");
    spec["env"]["actions"] = serde_json::json!([0, [1, 2]]);
    std::fs::write(d.join("spec.json"), spec.to_string()).unwrap();
    let err = fails(&d, &["search", "spec.json", "--dry-run"], 2, &["env.actions[1] = [1, 2]:"]);
    assert!(!err.contains("Vector"), "{err}");
}

#[test]
fn a_huge_name_is_echoed_short_and_a_refused_host_does_not_say_it_serves() {
    let d = empty_dir("messages", "huge-id");
    let id = "x".repeat(100_000);
    let err = fails(&d, &["search", &id, "--dry-run"], 2, &["unknown environment", "(100000 characters)"]);
    assert!(err.len() < 2_000, "{} bytes", err.len());
    let minari = format!("minari:{id}");
    let o = bin()
        .current_dir(&d)
        .args(["search", &minari, "--dry-run"])
        .env("BFQI_PYTHON", "/nonexistent/python")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.len() < 2_000 && err.contains("characters)"),
        "{} bytes: {}",
        err.len(),
        &err[..err.len().min(300)]
    );
    // An address that cannot be bound: refused, without first saying it serves there.
    std::fs::create_dir_all(d.join("results")).unwrap();
    let o = bin().current_dir(&d).args(["dashboard", "--host", "192.0.2.1", "--port", "1"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("cannot listen on 192.0.2.1:1"), "{err}");
    assert!(!err.contains("serving on"), "{err}");
}
