//! A seeded fuzz test of every input a user edits: the shipped spec files, the presets, the
//! overnight plan and a search's best.json, mutated (fields deleted, wrong types, out-of-range and
//! huge numbers, truncation, duplicate keys, non-objects) and run through the command that reads
//! them. Whatever the input: exit 0, 1 or 2, never a panic or an abort, a refusal in one line
//! that names the file.

mod common;
use common::{bin, empty_dir, read};

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
    eprintln!(
        "{runs} mutated inputs: {refused} refused, {timed_out} still running after 3 s (valid), {:.1} s",
        started.elapsed().as_secs_f64()
    );
    assert!(refused > runs / 2, "most mutations must be refused: {refused} of {runs}");
}
