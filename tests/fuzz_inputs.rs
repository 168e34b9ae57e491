//! A seeded fuzz test of every input a user edits or a run leaves on disk: the shipped spec files,
//! the presets, the overnight plan, a search's best.json, a comparison run directory's
//! compare.json and units, and model files (`run --save-model`), mutated (fields deleted, wrong
//! types, out-of-range and huge numbers, truncation, duplicate keys, non-objects; for model
//! files also flipped, overwritten and appended bytes, and info edits with the checksum made
//! right) and run through the command that reads them. Whatever the input: exit 0, 1 or 2, never
//! a panic, an abort or a signal, a refusal in one line that names the file.

mod common;
use common::{bin, copy_dir, empty_dir, read, split_info, varint, with_body};

use serde_json::Value;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

/// SplitMix64: the test's own seeded stream.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Paths to every leaf and object field of `v`.
fn paths(v: &Value, at: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                at.push(k.clone());
                out.push(at.clone());
                paths(x, at, out);
                at.pop();
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                at.push(i.to_string());
                out.push(at.clone());
                paths(x, at, out);
                at.pop();
            }
        }
        _ => {}
    }
}

fn slot<'a>(v: &'a mut Value, path: &[String]) -> &'a mut Value {
    path.iter().fold(v, |v, k| match v {
        Value::Object(m) => m.get_mut(k).unwrap(),
        Value::Array(a) => &mut a[k.parse::<usize>().unwrap()],
        _ => unreachable!(),
    })
}

/// One mutation of the JSON document `text`.
fn mutate(text: &str, rng: &mut Rng) -> String {
    let mut v: Value = serde_json::from_str(text).unwrap();
    let mut all = Vec::new();
    paths(&v, &mut Vec::new(), &mut all);
    let pick = all[rng.below(all.len())].clone();
    match rng.below(7) {
        0 => {
            // Delete the field.
            let (last, parent) = pick.split_last().unwrap();
            match slot(&mut v, parent) {
                Value::Object(m) => {
                    m.remove(last);
                }
                Value::Array(a) => {
                    a.remove(last.parse().unwrap());
                }
                _ => {}
            }
            v.to_string()
        }
        1 => {
            let wrong =
                [Value::from("x"), Value::from(true), serde_json::json!([]), serde_json::json!({}), Value::Null];
            *slot(&mut v, &pick) = wrong[rng.below(wrong.len())].clone();
            v.to_string()
        }
        2 | 3 => {
            let numbers = [-1.0, 0.0, 0.5, 1e308, -1e308, 1e12, 1e19, 3.0, 1e-300];
            *slot(&mut v, &pick) = serde_json::json!(numbers[rng.below(numbers.len())]);
            v.to_string()
        }
        4 => {
            let s = v.to_string();
            // Cut on a character boundary: the documents hold non-ASCII text (the claims' dashes).
            let mut cut = rng.below(s.len());
            while !s.is_char_boundary(cut) {
                cut -= 1;
            }
            s[..cut].to_string()
        }
        5 => {
            // Duplicate the first key of the top-level object.
            let s = v.to_string();
            let key = v.as_object().and_then(|m| m.keys().next().cloned()).unwrap_or_default();
            s.replacen('{', &format!("{{\"{key}\": 1, "), 1)
        }
        _ => ["[]", "5", "\"x\"", "null", ""][rng.below(5)].to_string(),
    }
}

fn owned(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// Runs a command with a time limit (a valid input may start real work: that is not a failure).
fn run(args: &[String], dir: &Path) -> Option<(i32, String)> {
    let mut child = bin()
        .current_dir(dir)
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            let o = child.wait_with_output().unwrap();
            return Some((o.status.code().unwrap_or(-1), String::from_utf8_lossy(&o.stderr).into_owned()));
        }
        if start.elapsed() > Duration::from_secs(3) {
            child.kill().unwrap();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn mutated_inputs_never_panic_and_refusals_name_their_file() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let work = empty_dir("fuzz", "inputs");

    // A small search's best.json, the input `reproduce` reads.
    let o = bin()
        .current_dir(&work)
        .args(["search", "cartpole", "--quick", "--population", "2", "--generations", "1", "--datasets", "1"])
        .args(["--episodes", "10", "--iterations", "1", "--quiet", "--out", "tiny"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let best = read(work.join("tiny/best.json"));

    let read = |p: &str| read(root.join(p));
    // (input, what the command does with the mutated file at `m`)
    type Cmd = fn(&str) -> Vec<String>;
    let cases: Vec<(String, Cmd)> = vec![
        (read("searches/cartpole.json"), |m| owned(&["search", m, "--dry-run"])),
        (read("searches/bicycle.json"), |m| owned(&["search", m, "--dry-run"])),
        (read("searches/pendulum.json"), |m| owned(&["search", m, "--dry-run"])),
        (read("searches/presets/quick.json"), |m| owned(&["search", "cartpole", "--preset", m, "--dry-run"])),
        (read("searches/presets/prune.json"), |m| owned(&["search", "pendulum", "--preset", m, "--dry-run"])),
        (read("searches/batches/overnight.json"), |m| owned(&["batch", m, "--dry-run"])),
        (read("searches/tuned/cartpole.json"), |m| owned(&["fitness", "tiny/spec.json", "--tuned", m, "--json"])),
        (best, |m| owned(&["reproduce", m])),
    ];
    let mut rng = Rng(20261202);
    let (mut runs, mut refused, mut timed_out) = (0, 0, 0);
    let started = Instant::now();
    for (i, (text, cmd)) in cases.iter().enumerate() {
        for k in 0..100 {
            let name = format!("m{i}-{k}.json");
            let mutated = mutate(text, &mut rng);
            std::fs::write(work.join(&name), &mutated).unwrap();
            let args = cmd(&name);
            runs += 1;
            let Some((code, err)) = run(&args, &work) else {
                timed_out += 1;
                continue;
            };
            let what = format!("{args:?} on {mutated:.300}: exit {code}: {err}");
            assert!([0, 1, 2].contains(&code), "{what}");
            assert!(!err.contains("panicked") && !err.contains("memory allocation"), "{what}");
            if code == 2 {
                refused += 1;
                assert_eq!(err.trim_end().lines().count(), 1, "not one line: {what}");
                assert!(err.contains(&name), "the refusal does not name the file: {what}");
            }
        }
    }
    let (dir_runs, dir_refused) = run_directories(&work, &mut rng);
    let (model_runs, model_refused) = model_files(&work, &mut rng);
    eprintln!(
        "{} mutations: {runs} of input files ({refused} refused), {dir_runs} of comparison run directories \
         ({dir_refused} refused), {model_runs} of model files ({model_refused} refused); {timed_out} still running \
         after 3 s (valid); {:.1} s",
        runs + dir_runs + model_runs,
        started.elapsed().as_secs_f64()
    );
    assert!(refused > runs / 2, "most mutations must be refused: {refused} of {runs}");
    assert!(dir_refused > dir_runs / 2, "most run directory mutations must be refused: {dir_refused} of {dir_runs}");
    assert!(model_refused > model_runs / 2, "most model mutations must be refused: {model_refused} of {model_runs}");
}

/// Checks one command's ending: exit 0, 1 or 2 (never 101, a panic, nor a signal, which has no
/// code), nothing panicked or aborted, and a refusal is one line naming `name`. Whether it was
/// refused.
fn judge(args: &[String], dir: &Path, name: &str, what: &str) -> bool {
    let Some((code, err)) = run(args, dir) else { return false };
    let what = format!("{args:?} on {what}: exit {code}: {err}");
    assert!([0, 1, 2].contains(&code), "{what}");
    assert!(!err.contains("panicked") && !err.contains("memory allocation"), "{what}");
    if code == 2 {
        assert_eq!(err.trim_end().lines().count(), 1, "not one line: {what}");
        assert!(err.contains(name), "the refusal does not name {name}: {what}");
    }
    code == 2
}

/// A small comparison's run directory, copied and damaged once per case: compare.json read by
/// `compare --resume`, a unit file read by `report`. Returns (runs, refused).
fn run_directories(work: &Path, rng: &mut Rng) -> (usize, usize) {
    let o = bin()
        .current_dir(work)
        .args(["compare", "cartpole", "--analysis", "iterations", "--learner", "et", "--datasets", "1"])
        .args(["--iterations", "1", "--episodes", "10", "--out", "cmp", "--quiet"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let units: Vec<String> = std::fs::read_dir(work.join("cmp/units"))
        .unwrap()
        .map(|e| format!("units/{}", e.unwrap().file_name().to_string_lossy()))
        .collect();
    assert_eq!(units.len(), 2, "{units:?}");
    let (mut runs, mut refused) = (0, 0);
    for k in 0..120 {
        let name = format!("c{k}");
        let dir = work.join(&name);
        copy_dir(&work.join("cmp"), &dir);
        let (file, cmd) = if k % 2 == 0 {
            ("compare.json".to_string(), owned(&["compare", "--resume", &name, "--quiet"]))
        } else {
            (units[k / 2 % units.len()].clone(), owned(&["report", &name]))
        };
        let mutated = mutate(&read(dir.join(&file)), rng);
        std::fs::write(dir.join(&file), &mutated).unwrap();
        runs += 1;
        if judge(&cmd, work, &name, &format!("{file} = {mutated:.300}")) {
            refused += 1;
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
    (runs, refused)
}

/// One mutation of a model file's bytes.
fn mutate_model(bytes: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = bytes.to_vec();
    let body = &bytes[10..bytes.len() - 8];
    match rng.below(6) {
        0 => {
            // Flip a byte anywhere (the checksum catches it, or the header check).
            let i = rng.below(b.len());
            b[i] ^= 1 << rng.below(8);
            b
        }
        1 => {
            b.truncate(rng.below(b.len()));
            b
        }
        2 => {
            // Another version, or another magic.
            let i = rng.below(10);
            b[i] = rng.below(256) as u8;
            b
        }
        3 => {
            // The info JSON mutated, the file's checksum right: the info's own checks must refuse it.
            let (info, rest) = split_info(body);
            let info = mutate(&info, rng);
            let mut new = Vec::new();
            varint(info.len(), &mut new);
            new.extend_from_slice(info.as_bytes());
            new.extend_from_slice(rest);
            with_body(bytes, &new)
        }
        4 => {
            // The members' bytes damaged under a right checksum: the decoder must refuse them.
            let mut new = body.to_vec();
            for _ in 0..1 + rng.below(8) {
                let i = rng.below(new.len());
                new[i] = rng.below(256) as u8;
            }
            with_body(bytes, &new)
        }
        _ => {
            b.extend((0..1 + rng.below(64)).map(|_| rng.below(256) as u8));
            b
        }
    }
}

/// Model files of both learners (`run --save-model`), mutated and read by `evaluate` and
/// `rollout`. Returns (runs, refused).
fn model_files(work: &Path, rng: &mut Rng) -> (usize, usize) {
    let mut models = Vec::new();
    for (learner, extra) in [("et", ["--trees", "2"]), ("mlp", ["--hidden", "4"])] {
        let out = format!("models-{learner}");
        let o = bin()
            .current_dir(work)
            .args(["run", "cartpole", "--learner", learner, "--datasets", "1", "--iterations", "2"])
            .args(["--episodes", "10", "--out", &format!("run-{learner}"), "--save-model", &out])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        models.push(std::fs::read(work.join(out).join("dataset-0.model")).unwrap());
    }
    let (mut runs, mut refused) = (0, 0);
    for k in 0..240 {
        let name = format!("q{k}.model");
        let mutated = mutate_model(&models[k % models.len()], rng);
        std::fs::write(work.join(&name), &mutated).unwrap();
        let cmd = if k % 4 == 3 {
            owned(&["rollout", &name, "--steps", "20", "--frames", "2", "--out", &format!("r{k}")])
        } else {
            owned(&["evaluate", &name, "--episodes", "2", "--steps", "20"])
        };
        runs += 1;
        if judge(&cmd, work, &name, &format!("{} bytes of a mutated model", mutated.len())) {
            refused += 1;
        }
    }
    (runs, refused)
}
