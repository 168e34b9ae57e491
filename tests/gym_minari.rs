//! Minari datasets in and out (issue 48): `dataset --minari` writes one that minari loads with its
//! env spec; `data.minari` and `minari:<id>` read one to exactly Minari's own episodes; a search on
//! one is deterministic, resumes after kill -9 and reproduces; what cannot be learnt is refused in
//! one line. Each test has its own `MINARI_DATASETS_PATH`.

mod common;
use common::gym::{gym_bin, python};
use common::{empty_dir, read, spawn_quiet, tiny_with, wait_for_entries};

use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A Python with gymnasium and minari, or a skip (a failure under `BFQI_GYM_REQUIRED=1`).
fn minari_python() -> Option<String> {
    let py = python()?;
    let ok = Command::new(&py).args(["-c", "import minari, PIL"]).output().is_ok_and(|o| o.status.success());
    if ok {
        return Some(py);
    }
    let why = format!("skipped: {py} cannot import minari and pillow (pip install minari pillow)");
    assert!(std::env::var("BFQI_GYM_REQUIRED").as_deref() != Ok("1"), "{why}, and BFQI_GYM_REQUIRED=1");
    eprintln!("{why}");
    None
}

fn ok(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    format!("{}{err}", String::from_utf8_lossy(&o.stdout))
}

fn refused(o: &Output, want: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked") && err.trim_end().lines().count() == 1, "one line: {err}");
    for w in want {
        assert!(err.contains(w), "{err:?} does not contain {w:?}");
    }
}

/// The binary with `py` as its Python and `store` as minari's datasets folder.
fn tool(py: &str, store: &Path) -> Command {
    let mut c = gym_bin(py);
    c.env("MINARI_DATASETS_PATH", store);
    c
}

/// Runs Python code with `store` as minari's datasets folder; its stdout.
fn py_run(py: &str, store: &Path, code: &str) -> String {
    let o = Command::new(py).env("MINARI_DATASETS_PATH", store).args(["-c", code]).output().unwrap();
    ok(&o);
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Episodes as sorted lists of transitions [s…, a, r, s'…, terminated, truncated] in bits.
type Episodes = Vec<Vec<Vec<u64>>>;

/// The transitions of a table the tool wrote, per episode, sorted.
fn table_episodes(path: &Path) -> Episodes {
    let d = bfqi_ga::dataset::table::read(path).unwrap();
    let od = d.obs_dim;
    let mut eps: Episodes = vec![Vec::new(); d.episodes()];
    for r in 0..d.len() {
        let last = r + 1 == d.len() || d.episode[r + 1] != d.episode[r];
        let mut t: Vec<u64> = d.state[r * od..(r + 1) * od].iter().map(|x| x.to_bits()).collect();
        t.extend([d.action[r].to_bits(), d.reward[r].to_bits()]);
        t.extend(d.next_state[r * od..(r + 1) * od].iter().map(|x| x.to_bits()));
        t.extend([u64::from(d.absorbing[r]), u64::from(last && !d.absorbing[r])]);
        eps[d.episode[r] as usize].push(t);
    }
    eps.sort();
    eps
}

/// Minari's own episodes of `id`, read in Python with minari (N + 1 observations per episode
/// of N steps), as the same transitions.
fn minari_episodes(py: &str, store: &Path, id: &str) -> Episodes {
    let code = format!(
        "import json, minari\nds = minari.load_dataset({id:?})\nout = []\nfor ep in ds.iterate_episodes():\n    n = len(ep.rewards)\n    out.append({{'obs': ep.observations.astype(float).tolist(), 'act': ep.actions.astype(float).reshape(n).tolist(), 'rew': ep.rewards.astype(float).tolist(), 'term': ep.terminations.tolist(), 'trunc': ep.truncations.tolist()}})\nprint(json.dumps(out))"
    );
    let raw: Vec<Value> = serde_json::from_str(&py_run(py, store, &code)).unwrap();
    let f = |v: &Value| v.as_f64().unwrap().to_bits();
    let mut eps: Episodes = raw
        .iter()
        .map(|e| {
            let (obs, n) = (e["obs"].as_array().unwrap(), e["rew"].as_array().unwrap().len());
            assert_eq!(obs.len(), n + 1, "Minari keeps N + 1 observations");
            (0..n)
                .map(|t| {
                    let mut row: Vec<u64> = obs[t].as_array().unwrap().iter().map(f).collect();
                    row.extend([f(&e["act"][t]), f(&e["rew"][t])]);
                    row.extend(obs[t + 1].as_array().unwrap().iter().map(f));
                    let last = t + 1 == n;
                    let term = e["term"][t].as_bool().unwrap();
                    // An episode cut by neither flag (the log stopped) is read as truncated.
                    row.extend([u64::from(term), u64::from(last && !term)]);
                    row
                })
                .collect()
        })
        .collect();
    eps.sort();
    eps
}

/// The resolved spec of `minari:<id>` with `data` replaced by `data`, written to `dir`.
fn minari_spec(py: &str, store: &Path, dir: &Path, id: &str, data: Value) -> PathBuf {
    let o = tool(py, store).args(["search", &format!("minari:{id}"), "--dry-run"]).output().unwrap();
    ok(&o);
    let mut spec: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(spec["env"]["id"], "CartPole-v1", "the env minari recorded is the one evaluated in");
    assert_eq!(spec["data"]["minari"], id);
    // Every dataset sized to a disjoint split of the logged episodes.
    let slots = &spec["data"]["slots"];
    let total: u64 = ["search", "validation", "compare"].iter().map(|k| slots[k].as_u64().unwrap()).sum();
    let each = spec["data"]["episodes"].as_u64().unwrap() / total;
    assert!(each >= 1 && spec["search"]["episodes"].as_u64().unwrap() <= each, "{spec}");
    assert!(spec["experiments"]["mlp"]["episodes"].as_u64().unwrap() <= each, "{spec}");
    let mut d = json!({"minari": id});
    d.as_object_mut().unwrap().extend(data.as_object().unwrap().clone());
    spec["data"] = d;
    // Two short evaluation episodes keep the tests quick.
    spec["env"]["eval"] = json!({"episodes": 2, "steps": 200, "score": "return"});
    let p = dir.join(format!("{}.json", id.replace('/', "-")));
    std::fs::write(&p, spec.to_string()).unwrap();
    p
}

#[test]
fn a_minari_dataset_the_tool_writes_loads_in_minari_and_reads_back_to_minaris_own_episodes() {
    let Some(py) = minari_python() else { return };
    let dir = empty_dir("minari", "round-trip");
    let store = dir.join("datasets");
    let (id, table) = ("bfqi/cartpole-random-v0", dir.join("logged.parquet"));
    let args = ["dataset", "gymnasium:CartPole-v1", "--episodes", "130", "--seed", "3", "--minari", id, "--out"];
    ok(&tool(&py, &store).args(args).arg(&table).output().unwrap());
    // minari loads it, with the env spec recorded.
    let spec_id = py_run(&py, &store, &format!("import minari\nprint(minari.load_dataset({id:?}).env_spec.id)"));
    assert_eq!(spec_id.trim(), "CartPole-v1");
    let theirs = minari_episodes(&py, &store, id);
    assert_eq!(theirs.len(), 130);
    assert_eq!(theirs, table_episodes(&table), "minari holds the transitions the tool wrote");
    // data.minari with one comparison slot takes every episode: Minari's own, bit for bit.
    let whole = minari_spec(&py, &store, &dir, id, json!({"slots": {"search": 0, "validation": 0, "compare": 1}}));
    let back = dir.join("back.csv");
    ok(&tool(&py, &store).arg("dataset").arg(&whole).args(["--episodes", "130", "--out"]).arg(&back).output().unwrap());
    assert_eq!(table_episodes(&back), theirs, "what data.minari reads is Minari's episodes");
}

#[test]
fn a_search_on_a_minari_dataset_is_deterministic_resumes_and_reproduces() {
    let Some(py) = minari_python() else { return };
    let dir = empty_dir("minari", "search");
    let store = dir.join("datasets");
    let id = "bfqi/cartpole-search-v0";
    let make = ["dataset", "gymnasium:CartPole-v1", "--episodes", "60", "--seed", "4", "--minari", id];
    ok(&tool(&py, &store).args(make).output().unwrap());
    let spec = minari_spec(&py, &store, &dir, id, json!({"split": "bootstrap"}));
    let search = |out: &str, extra: &[&str]| {
        let flags = tiny_with(&[&["--episodes", "10"], extra].concat());
        tool(&py, &store).arg("search").arg(&spec).args(flags).arg("--out").arg(dir.join(out)).output().unwrap()
    };
    ok(&search("one", &["--jobs", "1"]));
    ok(&search("two", &["--jobs", "2"]));
    let same = |a: &str, b: &str, why: &str| {
        for f in ["generations.jsonl", "best.json", "hall_of_fame.json"] {
            assert_eq!(read(dir.join(a).join(f)), read(dir.join(b).join(f)), "{f}: {why}");
        }
    };
    same("one", "two", "1 vs 2 threads");
    let recorded: Value = serde_json::from_str(&read(dir.join("one/spec.json"))).unwrap();
    assert_eq!(recorded["data"]["minari"], id);
    assert_eq!(recorded["data"]["episodes"], 60);
    assert!(read(dir.join("one/report.md")).contains("the Minari dataset"));

    let killed = dir.join("killed");
    let flags = tiny_with(&["--episodes", "10"]);
    let mut child = spawn_quiet(tool(&py, &store).arg("search").arg(&spec).args(flags).arg("--out").arg(&killed));
    wait_for_entries(&killed.join("units"), 2, &mut child);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    ok(&tool(&py, &store).args(["search", "--resume"]).arg(&killed).arg("--quiet").output().unwrap());
    same("one", "killed", "after kill -9 and resume");
    let r = ok(&tool(&py, &store).arg("reproduce").arg(dir.join("one/best.json")).output().unwrap());
    assert!(r.contains("matches bit for bit"), "{r}");
}

#[test]
fn minari_data_that_cannot_be_learnt_is_refused_in_one_line() {
    let Some(py) = minari_python() else { return };
    let dir = empty_dir("minari", "refusals");
    let store = dir.join("datasets");
    // Datasets made in Python: image observations, no env spec, a NaN reward, dict observations.
    let code = r#"
import numpy as np, gymnasium as gym, minari, warnings
from minari.data_collector.episode_buffer import EpisodeBuffer
warnings.simplefilter("ignore")
def make(id, obs, space, rew):
    b = EpisodeBuffer(observations=obs, actions=np.array([0, 1]), rewards=np.array(rew),
                      terminations=np.array([False, True]), truncations=np.array([False, False]))
    minari.create_dataset_from_buffers(id, buffer=[b], observation_space=space,
                                       action_space=gym.spaces.Discrete(2), data_format="arrow")
make("bfqi/image-v0", np.zeros((3, 2, 2), np.float32), gym.spaces.Box(0, 1, (2, 2), np.float32), [1.0, 1.0])
box = gym.spaces.Box(-np.inf, np.inf, (4,), np.float64)
make("bfqi/nospec-v0", np.zeros((3, 4)), box, [1.0, 1.0])
make("bfqi/nan-v0", np.zeros((3, 4)), box, [1.0, float("nan")])
make("bfqi/dict-v0", {"a": np.zeros((3, 4))}, gym.spaces.Dict({"a": box}), [1.0, 1.0])
"#;
    py_run(&py, &store, code);
    let dry = |target: &str| tool(&py, &store).args(["search", target, "--dry-run"]).output().unwrap();
    refused(&dry("minari:bfqi/nospec-v0"), &["records no env spec"]);
    refused(&dry("minari:bfqi/absent-v0"), &["data.minari", "bfqi/absent-v0"]);
    // A spec that names its env, with data that cannot be learnt from.
    let with = |id: &str| {
        let mut spec: Value = serde_json::from_str(&read("searches/cartpole.json")).unwrap();
        spec["data"] = json!({"minari": id});
        let p = dir.join(format!("{}.json", id.replace('/', "-")));
        std::fs::write(&p, spec.to_string()).unwrap();
        tool(&py, &store).arg("search").arg(&p).arg("--dry-run").output().unwrap()
    };
    refused(&with("bfqi/image-v0"), &["data.minari", "image observations"]);
    refused(&with("bfqi/dict-v0"), &["data.minari", "non-vector observations"]);
    refused(&with("bfqi/nan-v0"), &["data.minari", "non-finite", "episode 0"]);
    // Its observations fit cart-pole's, but 1 episode cannot make the spec's datasets.
    refused(&with("bfqi/nospec-v0"), &["data.minari", "holds 1 episodes"]);
}

#[test]
fn a_dataset_with_a_fifo_or_a_device_among_its_files_is_refused_naming_it() {
    let Some(py) = minari_python() else { return };
    let dir = empty_dir("minari", "special-files");
    let store = dir.join("datasets");
    let id = "bfqi/cartpole-small-v0";
    let args = ["dataset", "cartpole", "--episodes", "12", "--seed", "5", "--minari", id];
    ok(&tool(&py, &store).args(args).output().unwrap());
    let data = store.join(id).join("data");
    let read = || {
        tool(&py, &store).args(["dataset", &format!("minari:{id}"), "--out"]).arg(dir.join("x.csv")).output().unwrap()
    };
    ok(&read());
    // The dataset's metadata a FIFO (minari's open of it would wait for a writer for ever), then an
    // episode's file a link to /dev/zero (it was skipped: 11 of 12 episodes read, exit 0).
    let meta = data.join("metadata.json");
    let saved = std::fs::read(&meta).unwrap();
    std::fs::remove_file(&meta).unwrap();
    let c = std::ffi::CString::new(meta.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    refused(&read(), &["data.minari", "metadata.json", "not a regular file"]);
    std::fs::remove_file(&meta).unwrap();
    std::fs::write(&meta, saved).unwrap();
    let episode = std::fs::read_dir(data.join("3"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|x| x == "arrow"))
        .unwrap();
    std::fs::remove_file(&episode).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &episode).unwrap();
    refused(&read(), &["data.minari", &episode.file_name().unwrap().to_string_lossy(), "not a regular file"]);
    // An episode minari cannot read (its folder gone) is named, not dropped.
    std::fs::remove_dir_all(data.join("3")).unwrap();
    let o = read();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("data.minari") && !err.contains("panicked"), "{err}");
}

#[test]
fn small_minari_data_in_one_line_is_dealt_to_fewer_datasets_and_written_whole() {
    let Some(py) = minari_python() else { return };
    let dir = empty_dir("minari", "small");
    let store = dir.join("datasets");
    for (id, episodes) in [("bfqi/cartpole-40-v0", "40"), ("bfqi/cartpole-300-v0", "300")] {
        let args = ["dataset", "gymnasium:CartPole-v1", "--episodes", episodes, "--seed", "4", "--minari", id];
        ok(&tool(&py, &store).args(args).output().unwrap());
    }
    // `dataset minari:<id>` writes the whole dataset.
    let whole = dir.join("whole.csv");
    ok(&tool(&py, &store).args(["dataset", "minari:bfqi/cartpole-40-v0", "--out"]).arg(&whole).output().unwrap());
    assert_eq!(table_episodes(&whole).len(), 40);
    // 40 episodes cannot fill the template's 60 datasets: fewer are asked, and it says so.
    let said = ok(&tool(&py, &store).args(["search", "minari:bfqi/cartpole-40-v0", "--dry-run"]).output().unwrap());
    assert!(said.contains("holds 40 episodes: dealt to") && said.contains("little data"), "{said}");
    let spec: Value = serde_json::from_str(&said[said.find('{').unwrap()..said.rfind('}').unwrap() + 1]).unwrap();
    let slots = &spec["data"]["slots"];
    let total: u64 = ["search", "validation", "compare"].iter().map(|r| slots[r].as_u64().unwrap()).sum();
    assert!(total * 4 <= 40 && spec["search"]["episodes"].as_u64().unwrap() >= 4, "{slots} {}", spec["search"]);
    // `--quick` on 300 episodes: the preset's 200 episodes are capped at what a dataset holds.
    let said = ok(&tool(&py, &store)
        .args(["search", "minari:bfqi/cartpole-300-v0", "--quick", "--dry-run"])
        .output()
        .unwrap());
    assert!(said.contains("search.episodes 200 capped at 5"), "{said}");
}

#[test]
fn the_committed_minari_example_reproduces_from_its_committed_dataset() {
    let Some(py) = minari_python() else { return };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/minari");
    let store = root.join("datasets");
    // The tuned config re-trained from the committed dataset (its hash checked on the way).
    let r = ok(&tool(&py, &store).arg("reproduce").arg(root.join("search/best.json")).output().unwrap());
    assert!(r.contains("matches bit for bit"), "{r}");
    // The committed reports say where their data came from.
    for run in ["search", "compare"] {
        let report = read(root.join(run).join("report.md"));
        assert!(report.contains("the Minari dataset `bfqi/cartpole-random-v0` (500 episodes"), "{run}: {report}");
    }
}
