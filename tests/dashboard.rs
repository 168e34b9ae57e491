//! `bfqi-ga dashboard` over HTTP: its routes on the committed runs and on a tiny search, path
//! traversal refused, strings from run files escaped, tables as CSV, and a run directory written
//! while requests arrive.

mod common;
use common::{Http, TempDir, bin, copy_dir, empty_dir, http_get, http_request, read, settings, tiny_with};

use bfqi_ga::dashboard::{Dashboard, Options};
use serde_json::Value;
use std::collections::BTreeSet;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::sync::atomic::{AtomicBool, Ordering};

/// A dashboard served from this process on a free port; stopped when dropped.
struct Served {
    url: String,
    // Behind a mutex so that request threads can share the handle.
    stop: std::sync::Mutex<Option<Box<dyn FnOnce() + Send>>>,
}

impl Drop for Served {
    fn drop(&mut self) {
        if let Some(stop) = self.stop.lock().unwrap().take() {
            stop();
        }
    }
}

fn serve(roots: &[PathBuf]) -> Served {
    let d = Dashboard::bind(&Options { roots: roots.to_vec(), host: "127.0.0.1".into(), port: 0 }).unwrap();
    let url = d.url().to_string();
    let stopper = d.stopper();
    let h = std::thread::spawn(move || d.run());
    Served {
        url,
        stop: std::sync::Mutex::new(Some(Box::new(move || {
            stopper();
            h.join().unwrap();
        }))),
    }
}

impl Served {
    fn get(&self, path: &str) -> Http {
        http_get(&self.url, path)
    }

    /// A page that must be served: its body.
    fn ok(&self, path: &str) -> String {
        let r = self.get(path);
        assert_eq!(r.status, 200, "{path}: {}", short(&r.body));
        r.body
    }

    fn json(&self, path: &str) -> Value {
        let body = self.ok(path);
        serde_json::from_str(&body).unwrap_or_else(|e| panic!("{path}: {e}: {}", short(&body)))
    }
}

/// The start of a long text, for failure messages.
fn short(s: &str) -> &str {
    &s[..s.floor_char_boundary(600)]
}

fn committed() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results/searches")
}

/// A tiny cart-pole search (4 individuals, 2 generations, 2 datasets) in `dir`.
fn tiny_search(dir: &Path) {
    let o = bin().args(["search", "cartpole", "--out"]).arg(dir).args(tiny_with(&[])).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn rows(table: &Value) -> usize {
    table["rows"].as_array().unwrap().len()
}

fn table<'a>(page: &'a Value, name: &str) -> &'a Value {
    page["tables"].as_array().unwrap().iter().find(|t| t["name"] == name).unwrap_or_else(|| panic!("no table {name}"))
}

#[test]
fn routes_serve_the_committed_runs() {
    let s = serve(&[committed()]);
    let home = s.json("/?json=1");
    let runs = table(&home, "runs");
    let kinds: Vec<(String, String)> = runs["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| (r[0]["text"].as_str().unwrap().to_string(), r[1]["text"].as_str().unwrap().to_string()))
        .collect();
    let bicycle = committed().join("bicycle");
    assert!(kinds.iter().any(|(n, k)| n.ends_with("/bicycle") && k == "search"), "{kinds:?}");
    assert!(
        kinds.iter().any(|(n, k)| n.ends_with("/bicycle-compare-mlp-iterations") && k == "comparison"),
        "{kinds:?}"
    );
    let html = s.ok("/");
    assert!(html.contains("href=\"/run/0/bicycle\"") && html.contains("/assets/app.js"), "{}", short(&html));

    // The search page: its charts' data name every evaluated setting once, and the thesis optimum.
    let page = s.json("/run/0/bicycle?json=1");
    let points = page["charts"]["points"].as_array().unwrap();
    let ids: BTreeSet<String> = points.iter().map(|p| p["id"].as_str().unwrap().to_string()).collect();
    assert_eq!(ids, settings(&bicycle));
    assert_eq!(points.len(), ids.len());
    assert_eq!(page["charts"]["generations"].as_array().unwrap().len(), 20);
    assert!(page["charts"]["reference"]["value"].as_f64().is_some(), "the thesis optimum's line");
    assert_eq!(rows(table(&page, "population")), ids.len());
    assert!(rows(table(&page, "hall_of_fame")) > 0 && rows(table(&page, "validation")) > 0);
    let html = s.ok("/run/0/bicycle");
    for id in ["fitness", "explorer", "gene-delta", "gene-patience", "gene-activation"] {
        assert!(html.contains(&format!("id=\"{id}\"")), "{id}");
    }

    // A setting's page: one row per dataset from its units, its FQI iterations and networks, births.
    // The search's best setting (state.json names it by its genes).
    let st: Value = common::json(bicycle.join("state.json"));
    let best: bfqi_ga::ga::chromosome::Decoded = serde_json::from_value(st["best"].clone()).unwrap();
    let id = bfqi_ga::ga::units::setting_id(&best);
    assert!(ids.contains(&id), "{id}");
    let setting = s.json(&format!("/run/0/bicycle?setting={id}&json=1"));
    let units = std::fs::read_dir(bicycle.join("units"))
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(&format!("{id}.d")))
        .count();
    assert_eq!(rows(table(&setting, "datasets")), units, "{id}");
    assert!(rows(table(&setting, "iterations")) >= units && rows(table(&setting, "networks")) > 0);
    assert!(rows(table(&setting, "births")) > 0, "{id} was born somewhere");
    assert_eq!(s.get("/run/0/bicycle?setting=not_a_setting").status, 404);

    // A comparison: its summary drawn as curves, the claims beside the thesis's, its plots.
    let cmp = s.json("/run/0/bicycle-compare-mlp-iterations?json=1");
    assert!(!cmp["charts"]["series"].as_array().unwrap().is_empty());
    assert!(rows(table(&cmp, "claims")) > 0, "the report's thesis claims");
    let html = s.ok("/run/0/bicycle-compare-mlp-iterations");
    assert!(html.contains("src=\"/file/0/bicycle-compare-mlp-iterations/mlp-iterations.png\""), "{}", short(&html));
    let png = s.get("/file/0/bicycle-compare-mlp-iterations/mlp-iterations.png");
    assert_eq!((png.status, png.header("content-type")), (200, Some("image/png")));
    assert_eq!(
        png.bytes,
        std::fs::read(committed().join("bicycle-compare-mlp-iterations/mlp-iterations.png")).unwrap()
    );

    // The embedded assets; anything else is absent; nothing but reading is allowed.
    let js = s.get("/assets/app.js");
    assert_eq!((js.status, js.header("content-type")), (200, Some("text/javascript; charset=utf-8")));
    assert!(js.body.contains("textContent"));
    assert!(s.get("/run/0/bicycle").header("content-security-policy").unwrap().contains("default-src 'none'"));
    assert_eq!(s.get("/assets/other.js").status, 404);
    assert_eq!(s.get("/run/0/no-such-run").status, 404);
    assert_eq!(s.get("/run/7/bicycle").status, 404);
    assert_eq!(http_request(&s.url, "POST", "/").status, 405);
    assert_eq!(http_request(&s.url, "DELETE", "/run/0/bicycle").status, 405);
}

#[test]
fn paths_outside_the_served_directories_are_refused() {
    let top = empty_dir("dashboard", "traversal");
    let root = top.join("served");
    tiny_search(&root.join("run"));
    std::fs::write(top.join("secret.png"), "SECRET").unwrap();
    std::fs::write(root.join("run/notes.txt"), "SECRET").unwrap();
    // A link inside the root that leads out of it, to a file and to a run.
    let outside = top.join("outside");
    tiny_search(&outside);
    std::fs::write(outside.join("x.png"), "SECRET").unwrap();
    std::os::unix::fs::symlink(&outside, root.join("escape")).unwrap();

    let s = serve(&[root.to_path_buf()]);
    assert_eq!(s.get("/file/0/run/fitness.png").status, 200, "a plot inside is served");
    for path in [
        "/file/0/../secret.png",
        "/file/0/run/../../secret.png",
        "/file/0/%2e%2e/secret.png",
        "/file/0/..%2Fsecret.png",
        "/file/0/run%2F..%2F..%2Fsecret.png",
        "/file/0//etc/passwd",
        &format!("/file/0/{}", top.join("secret.png").display()),
        "/file/0/run/notes.txt",
        "/file/0/escape/x.png",
        "/file/1/secret.png",
        "/run/0/..",
        "/run/0/../served/run",
        "/run/0/%2e%2e",
        "/run/0/escape",
        "/../secret.png",
    ] {
        let r = s.get(path);
        assert!(r.status == 403 || r.status == 404, "{path}: {} {}", r.status, r.body);
        assert!(!r.body.contains("SECRET"), "{path}");
    }
    // The link is not followed when listing runs either.
    let home = s.json("/?json=1");
    let names: Vec<&str> =
        table(&home, "runs")["rows"].as_array().unwrap().iter().map(|r| r[0]["text"].as_str().unwrap()).collect();
    assert!(names.iter().all(|n| !n.contains("escape")), "{names:?}");
}

#[test]
fn strings_from_run_files_show_as_text() {
    let root = empty_dir("dashboard", "escape");
    let dir = root.join("<script>alert(1)");
    tiny_search(&dir);
    // Setting names in the records, as a hostile or damaged file might have them.
    let gens = read(dir.join("generations.jsonl"));
    let first = settings(&dir).into_iter().next().unwrap();
    std::fs::write(dir.join("generations.jsonl"), gens.replace(&first, "<script>alert(2)</script>")).unwrap();

    let s = serve(&[root.to_path_buf()]);
    let run = "/run/0/%3Cscript%3Ealert%281%29";
    for path in ["/", run, &format!("{run}?setting={}", "%3Cscript%3Ealert(3)")] {
        let r = s.get(path);
        assert!(!r.body.contains("<script>alert"), "{path}: {}", r.body);
    }
    let home = s.ok("/");
    assert!(home.contains("&lt;script&gt;alert(1)"), "{home}");
    assert!(home.contains("href=\"/run/0/%3Cscript%3Ealert%281%29\""), "{home}");
    let page = s.ok(run);
    assert!(page.contains("&lt;script&gt;alert(2)&lt;/script&gt;"), "{page}");
    // The chart data carry the name as data (the script sets it with textContent), as JSON.
    let r = s.get(&format!("{run}?json=1"));
    // Served as JSON that a browser may not sniff into HTML, under a policy that runs no inline script.
    assert_eq!(r.header("content-type"), Some("application/json"));
    assert_eq!(r.header("x-content-type-options"), Some("nosniff"));
    assert!(r.header("content-security-policy").unwrap().contains("script-src 'self'"));
    let j: Value = serde_json::from_str(&r.body).unwrap();
    assert!(j["charts"]["points"].as_array().unwrap().iter().any(|p| p["id"] == "<script>alert(2)</script>"));
    // CSV is not HTML: the name as it is, quoted by CSV's rules only.
    let csv = s.get(&format!("{run}?csv=population"));
    assert_eq!(csv.header("content-type"), Some("text/csv; charset=utf-8"));
    assert!(csv.body.contains("\n<script>alert(2)</script>,"), "{}", csv.body);
}

#[test]
fn every_table_downloads_as_csv() {
    let root = empty_dir("dashboard", "csv");
    tiny_search(&root.join("a,b"));
    let s = serve(&[root.to_path_buf()]);
    let home = s.json("/?json=1");
    let csv = s.ok("/?csv=runs");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "run,kind,env,state,generation,best fitness,settings,progress,ETA");
    assert_eq!(lines.len(), 1 + rows(table(&home, "runs")));
    assert!(lines[1].starts_with("\"") && lines[1].contains("a,b\",search,cartpole,finished,2/2,"), "{csv}");

    let run = "/run/0/a%2Cb";
    let page = s.json(&format!("{run}?json=1"));
    let html = s.ok(run);
    for t in page["tables"].as_array().unwrap() {
        let name = t["name"].as_str().unwrap();
        assert!(html.contains(&format!("href=\"{run}?csv={name}\"")), "{name}'s CSV link");
        let csv = s.ok(&format!("{run}?csv={name}"));
        let header: Vec<String> = t["columns"].as_array().unwrap().iter().map(|c| c.as_str().unwrap().into()).collect();
        assert_eq!(csv.lines().next().unwrap(), header.join(","), "{name}");
        assert_eq!(csv.lines().count(), 1 + rows(t), "{name}");
    }
    let pop = s.ok(&format!("{run}?csv=population"));
    assert_eq!(pop.lines().count(), 1 + settings(&root.join("a,b")).len());
    let id = settings(&root.join("a,b")).into_iter().next().unwrap();
    let nets = s.ok(&format!("{run}?setting={id}&csv=networks"));
    assert!(nets.starts_with("dataset,iteration,network,epochs,stop,train loss,val loss\n"), "{nets}");
    assert_eq!(nets.lines().count(), 1 + 2 * 2 * 2, "2 datasets × K = 2 × one network per action");
    assert_eq!(s.get(&format!("{run}?csv=nothing")).status, 404);
}

#[test]
fn a_run_written_during_requests_gives_no_error() {
    let root = empty_dir("dashboard", "live");
    let dir = root.join("run");
    tiny_search(&dir);
    let gens = read(dir.join("generations.jsonl"));
    let record: Value = serde_json::from_str(gens.lines().last().unwrap()).unwrap();
    let state: Value = common::json(dir.join("state.json"));
    let id = settings(&dir).into_iter().next().unwrap();
    let unit = dir.join(format!("units/{id}.d1.json"));
    let unit_text = read(&unit);
    // What the setting's page may show per dataset: a whole unit's score, never a half-read one.
    let scores: BTreeSet<String> = (0..2)
        .map(|d| common::json(dir.join(format!("units/{id}.d{d}.json")))["score"].as_f64())
        .map(|s| s.map_or("—".into(), |s| format!("{s:.4}")))
        .collect();
    // Held as a running search holds it, so the page says "running".
    let _lock = bfqi_ga::store::RunLock::acquire(&dir).unwrap();

    let s = serve(&[root.to_path_buf()]);
    let done = AtomicBool::new(false);
    let appended = 40;
    std::thread::scope(|sc| {
        sc.spawn(|| {
            for k in 0..appended {
                // state.json as the search writes it: whole files renamed into place.
                let mut st = state.clone();
                st["state"] = "running".into();
                st["generation"] = (3 + k).into();
                let tmp = dir.join(".state.json.tmp");
                std::fs::write(&tmp, serde_json::to_string_pretty(&st).unwrap()).unwrap();
                std::fs::rename(&tmp, dir.join("state.json")).unwrap();
                // A generation's line appended in two writes: readers meet the half line.
                let mut r = record.clone();
                r["generation"] = (2 + k).into();
                let line = format!("{}\n", serde_json::to_string(&r).unwrap());
                let mut f = std::fs::OpenOptions::new().append(true).open(dir.join("generations.jsonl")).unwrap();
                let (a, b) = line.split_at(line.len() / 2);
                f.write_all(a.as_bytes()).unwrap();
                f.flush().unwrap();
                std::thread::sleep(std::time::Duration::from_millis(3));
                f.write_all(b.as_bytes()).unwrap();
                // A unit missing for a moment, then half written (as if by a tool that does not rename).
                std::fs::remove_file(&unit).unwrap();
                std::thread::sleep(std::time::Duration::from_millis(2));
                std::fs::write(&unit, &unit_text[..unit_text.len() / 2]).unwrap();
                std::thread::sleep(std::time::Duration::from_millis(2));
                std::fs::write(&unit, &unit_text).unwrap();
            }
            done.store(true, Ordering::SeqCst);
        });
        for _ in 0..2 {
            sc.spawn(|| {
                let mut n = 0;
                while !done.load(Ordering::SeqCst) || n < 5 {
                    for path in ["/?json=1", "/run/0/run?json=1"] {
                        let page = s.json(path);
                        assert!(page["tables"].is_array(), "{path}");
                    }
                    let page = s.json(&format!("/run/0/run?setting={id}&json=1"));
                    let shown = table(&page, "datasets")["rows"].as_array().unwrap().clone();
                    assert!(!shown.is_empty() && shown.len() <= 2, "{shown:?}");
                    for row in &shown {
                        assert!(scores.contains(row[1]["text"].as_str().unwrap()), "{row:?} not in {scores:?}");
                    }
                    let gens = s.json("/run/0/run?json=1")["charts"]["generations"].as_array().unwrap().clone();
                    assert!(gens.iter().enumerate().all(|(i, g)| g["g"] == i), "whole records, in order: {gens:?}");
                    for path in ["/", "/run/0/run", "/run/0/run?csv=population", &format!("/run/0/run?setting={id}")] {
                        s.ok(path);
                    }
                    n += 1;
                }
            });
        }
    });
    // Once the writes are over, the page shows them all.
    let page = s.json("/run/0/run?json=1");
    assert_eq!(page["charts"]["generations"].as_array().unwrap().len(), 2 + appended);
    assert_eq!(table(&page, "summary")["rows"][0][0]["text"], "running");
    assert_eq!(table(&page, "summary")["rows"][0][1]["text"], format!("{}/2", 2 + appended));
    // A state.json cut short by a writer that does not rename: shown as unreadable, no error.
    std::fs::write(dir.join("state.json"), "{\"state\": \"runn").unwrap();
    let home = s.json("/?json=1");
    assert_eq!(table(&home, "runs")["rows"][0][3]["text"], "unreadable");
    s.ok("/run/0/run");
}

#[test]
fn the_command_prints_its_url_and_warns_before_leaving_loopback() {
    let root: TempDir = empty_dir("dashboard", "cli");
    copy_dir(&committed().join("bicycle-compare-mlp-iterations"), &root.join("cmp"));
    let mut child = bin()
        .args(["dashboard"])
        .arg(&*root)
        .args(["--port", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let url = line.trim().strip_prefix("bfqi-ga dashboard: ").unwrap_or_else(|| panic!("{line}")).to_string();
    assert!(url.starts_with("http://127.0.0.1:"), "{url}");
    let r = http_get(&url, "/run/0/cmp");
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(r.status, 200);
    assert!(r.body.contains("Thesis claims"));

    // Any other address needs the flag and gets a warning (this one cannot be bound here).
    let o = bin().args(["dashboard"]).arg(&*root).args(["--host", "192.0.2.1", "--port", "0"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("warning: serving on 192.0.2.1"), "{err}");
    assert!(!o.status.success());
    let o = bin().args(["dashboard"]).arg(root.join("missing")).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("missing"));
}
