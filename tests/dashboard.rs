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
    // Its work, as `bfqi-ga work` counts it from the units.
    let o = bin().args(["work", "--json"]).arg(&bicycle).output().unwrap();
    let cli: Value = serde_json::from_slice(&o.stdout).unwrap();
    let work = &table(&page, "work")["rows"][0];
    assert_eq!(work[0]["text"].as_str().unwrap(), cli["units"].to_string());
    assert_eq!(work[2]["text"].as_str().unwrap(), cli["epochs"].to_string());
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
    assert_eq!(rows(table(&cmp, "work")), 1, "a comparison's work");
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
    assert_eq!(lines[0], "run,kind,env,state,generation,best fitness,settings,progress,ETA,started,updated");
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

/// `bfqi-ga dashboard ROOT ARGS` started, with the first line it printed (its URL).
fn started(root: &Path, args: &[&str]) -> (std::process::Child, String) {
    let mut child =
        bin().arg("dashboard").arg(root).args(args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    (child, line)
}

#[test]
fn the_command_prints_its_url_and_warns_before_leaving_loopback() {
    let root: TempDir = empty_dir("dashboard", "cli");
    copy_dir(&committed().join("bicycle-compare-mlp-iterations"), &root.join("cmp"));
    let (mut child, line) = started(&root, &["--port", "0"]);
    let url = line.trim().strip_prefix("bfqi-ga dashboard: ").unwrap_or_else(|| panic!("{line}")).to_string();
    assert!(url.starts_with("http://127.0.0.1:"), "{url}");
    let r = http_get(&url, "/run/0/cmp");
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(r.status, 200);
    assert!(r.body.contains("Thesis claims"));

    // Any other address gets a warning once it is bound; one that cannot be bound here is refused
    // without a word of serving on it.
    let o = bin().args(["dashboard"]).arg(&*root).args(["--host", "192.0.2.1", "--port", "0"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("serving on") && err.contains("cannot listen on 192.0.2.1"), "{err}");
    assert!(!o.status.success());
    let (mut child, line) = started(&root, &["--host", "0.0.0.0", "--port", "0"]);
    child.kill().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    child.wait().unwrap();
    assert!(line.contains("bfqi-ga dashboard: http://0.0.0.0:"), "{line}");
    assert!(err.contains("warning: serving on 0.0.0.0"), "{err}");
    let o = bin().args(["dashboard"]).arg(root.join("missing")).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("missing"));
}

// ---- Security and robustness: every bound a request meets, with real sockets on 127.0.0.1. ----

/// `bfqi-ga dashboard` as a child process on a free port; killed when dropped.
struct Child {
    child: std::process::Child,
    url: String,
    addr: String,
}

impl Child {
    fn start(roots: &[&Path], extra: &[&str]) -> Child {
        let mut child = bin()
            .arg("dashboard")
            .args(roots)
            .args(["--port", "0"])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let url = line.trim().strip_prefix("bfqi-ga dashboard: ").unwrap_or_else(|| panic!("{line}")).to_string();
        let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
        Child { child, url, addr }
    }

    /// A line of the server's `/proc/PID/status`, in KiB (`VmHWM`: its peak resident memory).
    fn memory_kib(&self, field: &str) -> u64 {
        let s = read(format!("/proc/{}/status", self.child.id()));
        let line = s.lines().find(|l| l.starts_with(field)).unwrap_or_else(|| panic!("no {field}"));
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    }

    fn alive(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }
}

impl Drop for Child {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Sends `bytes` as they are and returns what comes back (empty when the connection is reset
/// before an answer), waiting at most `secs`.
fn raw(addr: &str, bytes: &[u8], secs: u64) -> String {
    use std::io::Read;
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(secs))).unwrap();
    let _ = s.write_all(bytes);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    String::from_utf8_lossy(&out).into_owned()
}

fn status_of(response: &str) -> Option<u16> {
    response.split(' ').nth(1)?.parse().ok()
}

#[test]
fn no_request_makes_the_server_allocate_more_than_a_small_bound() {
    let root = empty_dir("dashboard", "memory");
    copy_dir(&committed().join("bicycle-compare-mlp-iterations"), &root.join("cmp"));
    let mut srv = Child::start(&[&root], &[]);
    let host = format!("Host: {}\r\n", srv.addr);
    for _ in 0..3 {
        assert_eq!(http_get(&srv.url, "/run/0/cmp").status, 200);
    }
    let before = srv.memory_kib("VmHWM");

    // The declared body of a GET: refused, not allocated (tiny_http 0.12 allocated it and aborted).
    let r = raw(&srv.addr, format!("GET / HTTP/1.1\r\n{host}Content-Length: 99999999999\r\n\r\n").as_bytes(), 10);
    assert_eq!(status_of(&r), Some(400), "{r}");
    assert!(r.contains("no body"), "{r}");
    let r =
        raw(&srv.addr, format!("GET / HTTP/1.1\r\n{host}Transfer-Encoding: chunked\r\n\r\n5\r\nhello").as_bytes(), 10);
    assert_eq!(status_of(&r), Some(400), "{r}");
    let r = raw(&srv.addr, format!("POST / HTTP/1.1\r\n{host}Content-Length: 99999999999\r\n\r\n").as_bytes(), 10);
    assert_eq!(status_of(&r), Some(405), "{r}");
    // A 64 MB request line: answered 414 after 8 KiB (or reset while the client still sends).
    let mut line = b"GET /".to_vec();
    line.resize(64 << 20, b'a');
    let r = raw(&srv.addr, &line, 20);
    assert!(r.is_empty() || status_of(&r) == Some(414), "{}", &r[..r.len().min(300)]);
    // 64 MB of headers, and many small ones.
    let mut headers = format!("GET / HTTP/1.1\r\n{host}X-Big: ").into_bytes();
    headers.resize(64 << 20, b'b');
    let r = raw(&srv.addr, &headers, 20);
    assert!(r.is_empty() || status_of(&r) == Some(431), "{}", &r[..r.len().min(300)]);
    let many = format!("GET / HTTP/1.1\r\n{host}{}\r\n", "X-A: 1\r\n".repeat(200));
    assert_eq!(status_of(&raw(&srv.addr, many.as_bytes(), 10)), Some(431));
    // HEAD: the headers only.
    let r = raw(&srv.addr, format!("HEAD /run/0/cmp HTTP/1.1\r\n{host}\r\n").as_bytes(), 10);
    assert_eq!(status_of(&r), Some(200));
    assert!(r.ends_with("\r\n\r\n"), "no body after HEAD's headers");

    assert!(srv.alive(), "the server survived");
    assert_eq!(http_get(&srv.url, "/run/0/cmp").status, 200);
    let after = srv.memory_kib("VmHWM");
    println!("dashboard peak memory (VmHWM): {before} KiB after 3 pages, {after} KiB after the attack requests");
    assert!(after < before + 8 * 1024, "{before} → {after} KiB");
}

#[test]
fn slow_and_idle_clients_cannot_tie_up_the_server() {
    use std::io::Read;
    use std::time::{Duration, Instant};
    let root = empty_dir("dashboard", "slow");
    copy_dir(&committed().join("bicycle-compare-mlp-iterations"), &root.join("cmp"));
    let srv = Child::start(&[&root], &[]);
    // More slow clients than the old server had workers (4), each sending a byte every 300 ms.
    let mut slow: Vec<std::net::TcpStream> = (0..8).map(|_| std::net::TcpStream::connect(&srv.addr).unwrap()).collect();
    let started = Instant::now();
    let mut first: Option<Duration> = None;
    // They keep sending for 9 s (the server's whole-head deadline is 10 s).
    for step in 0..30 {
        for s in &mut slow {
            let _ = s.write_all(if step == 0 { b"G" } else { b"x" });
        }
        if first.is_none() {
            let t = Instant::now();
            assert_eq!(http_get(&srv.url, "/run/0/cmp").status, 200, "answered beside the slow clients");
            first = Some(t.elapsed());
        }
        std::thread::sleep(Duration::from_millis(300));
    }
    // Not a speed bound (the machines are shared and noisy): a server tied up by the slow clients
    // could answer only once their head deadline (10 s) freed it, after they stopped sending.
    let first = first.unwrap();
    assert!(first < Duration::from_secs(8), "the page waited {first:?}: behind the slow clients' 10 s deadline");
    // Each slow client had 10 s for its whole request head, however steadily it sent: it was
    // answered 408 and closed.
    for s in &mut slow {
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let mut out = Vec::new();
        let _ = s.read_to_end(&mut out);
        let r = String::from_utf8_lossy(&out);
        assert_eq!(status_of(&r), Some(408), "{r}");
    }
    assert!(started.elapsed() < Duration::from_secs(13), "{:?}", started.elapsed());
    // Idle connections past the cap (it is 32) do not starve a request: each newcomer takes the
    // slot of the oldest one still waiting for its head, so a normal request is answered while
    // they stay open (it waited the head deadline, 10 s, before).
    let mut idle: Vec<std::net::TcpStream> =
        (0..40).map(|_| std::net::TcpStream::connect(&srv.addr).unwrap()).collect();
    std::thread::sleep(Duration::from_millis(300));
    for round in 0..3 {
        let t = Instant::now();
        let r = raw(&srv.addr, format!("GET / HTTP/1.1\r\nHost: {}\r\n\r\n", srv.addr).as_bytes(), 5);
        assert_eq!(status_of(&r), Some(200), "round {round}: {r}");
        println!("answered beside 40 idle connections in {:?}", t.elapsed());
        assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
        // The attack renewed: as many idle connections again (a slot waits 200 ms for its head
        // before a newcomer may take it, so a burst of real requests is not closed under itself).
        idle.extend((0..32).map(|_| std::net::TcpStream::connect(&srv.addr).unwrap()));
        std::thread::sleep(Duration::from_millis(300));
    }
    // The oldest idle ones were closed to make room: they read an end, not an answer.
    idle[0].set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    assert_eq!(idle[0].read(&mut [0u8; 16]).unwrap_or(0), 0);
    drop(idle);
    let t = Instant::now();
    loop {
        let r = http_get(&srv.url, "/");
        if r.status == 200 {
            break;
        }
        assert!(t.elapsed() < Duration::from_secs(5), "still {}", r.status);
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_host_header_must_name_the_server() {
    let root = empty_dir("dashboard", "host");
    copy_dir(&committed().join("bicycle-compare-mlp-iterations"), &root.join("cmp"));
    let srv = Child::start(&[&root], &[]);
    let port = srv.addr.rsplit_once(':').unwrap().1;
    let get = |host: Option<&str>| {
        let h = host.map_or(String::new(), |h| format!("Host: {h}\r\n"));
        status_of(&raw(&srv.addr, format!("GET /run/0/cmp?json=1 HTTP/1.1\r\n{h}\r\n").as_bytes(), 10))
    };
    for ok in [format!("127.0.0.1:{port}"), format!("localhost:{port}"), format!("[::1]:{port}")] {
        assert_eq!(get(Some(&ok)), Some(200), "{ok}");
    }
    // What a DNS-rebinding page sends: its own name, at our port.
    for bad in [format!("attacker.example:{port}"), format!("127.0.0.1.nip.io:{port}"), "127.0.0.1:1".into()] {
        let r = raw(&srv.addr, format!("GET /run/0/cmp?json=1 HTTP/1.1\r\nHost: {bad}\r\n\r\n").as_bytes(), 10);
        assert_eq!(status_of(&r), Some(403), "{bad}: {r}");
        assert!(!r.contains("Thesis"), "{bad}");
    }
    assert_eq!(get(None), Some(400), "HTTP/1.1 requires a Host");
}

#[test]
fn the_host_flag_takes_loopback_in_every_spelling() {
    let root = empty_dir("dashboard", "hosts");
    for (host, url_start) in [
        ("[::1]", "http://[::1]:"),
        ("::1", "http://[::1]:"),
        ("127.1", "http://127.0.0.1:"),
        ("::ffff:127.0.0.1", "http://[::ffff:127.0.0.1]:"),
        ("localhost", "http://"),
    ] {
        let mut srv = Child::start(&[&root], &["--host", host]);
        assert!(srv.url.starts_with(url_start), "{host}: {}", srv.url);
        srv.child.kill().unwrap();
        let mut err = String::new();
        std::io::Read::read_to_string(srv.child.stderr.as_mut().unwrap(), &mut err).unwrap();
        assert!(!err.contains("warning"), "{host}: {err}");
    }
    // Only the 127.1 one is spoken to (127.0.0.1 only): it answers its own page.
    let srv = Child::start(&[&root], &["--host", "127.1"]);
    assert_eq!(http_get(&srv.url, "/").status, 200);
    let o = bin().args(["dashboard"]).arg(&*root).args(["--host", "no such host.invalid"]).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("no such host.invalid"));
}

#[test]
fn files_linked_out_fifos_and_devices_are_refused_and_said_so() {
    use std::time::{Duration, Instant};
    let root = empty_dir("dashboard", "links");
    let cmp = root.join("cmp");
    copy_dir(&committed().join("bicycle-compare-mlp-iterations"), &cmp);
    let summary = cmp.join("summary.csv");
    let csv_page = "/run/0/cmp?csv=summary";
    let srv = Child::start(&[&root], &[]);
    let page = |path: &str| serde_json::from_str::<Value>(&http_get(&srv.url, path).body).unwrap();

    // A link out of the served folders: not read, and the page says why.
    std::fs::remove_file(&summary).unwrap();
    std::os::unix::fs::symlink("/etc/passwd", &summary).unwrap();
    let r = http_get(&srv.url, csv_page);
    assert!(!r.body.contains("root:"), "{}", r.body);
    let notes = page("/run/0/cmp?json=1")["notes"].to_string();
    assert!(notes.contains("summary.csv: not read: links out of the served folders"), "{notes}");
    assert!(http_get(&srv.url, "/run/0/cmp").body.contains("links out of the served folders"));

    // A FIFO: never opened for a blocking read; more requests than the old server had workers.
    std::fs::remove_file(&summary).unwrap();
    let c = std::ffi::CString::new(summary.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let t = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..8 {
            s.spawn(|| assert_eq!(http_get(&srv.url, csv_page).status, 200));
        }
    });
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    assert!(page("/run/0/cmp?json=1")["notes"].to_string().contains("summary.csv: not read: not a regular file"));
    assert_eq!(http_get(&srv.url, "/").status, 200, "still answering");

    // A device (inside the folders, by a link to one inside): not a regular file either.
    std::fs::remove_file(&summary).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &summary).unwrap();
    assert!(page("/run/0/cmp?json=1")["notes"].to_string().contains("summary.csv"));
    let png = cmp.join("zero.png");
    std::os::unix::fs::symlink("/dev/zero", &png).unwrap();
    assert_eq!(http_get(&srv.url, "/file/0/cmp/zero.png").status, 403);

    // A regular file over the cap (sparse: no disk used) is not read whole.
    std::fs::remove_file(&summary).unwrap();
    std::fs::File::create(&summary).unwrap().set_len(40 << 20).unwrap();
    let notes = page("/run/0/cmp?json=1")["notes"].to_string();
    assert!(notes.contains("summary.csv: not read: larger than 32 MiB"), "{notes}");
    // The lock file is read the same way (it decides "running").
    std::os::unix::fs::symlink("/dev/zero", cmp.join("lock")).unwrap();
    let home = page("/?json=1");
    assert!(home["notes"].to_string().contains("cmp: lock: not read: links out of the served folders"), "{home}");

    // The Work table's files too: its run.json a FIFO, then a unit linked out of the folders and its
    // work.json stale, read through the same reader: pages answer, the page says what it skipped.
    let run_json = cmp.join("run.json");
    std::fs::remove_file(&run_json).unwrap();
    let c = std::ffi::CString::new(run_json.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let t = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..24 {
            s.spawn(|| assert_eq!(http_get(&srv.url, "/run/0/cmp").status, 200));
        }
    });
    assert!(t.elapsed() < Duration::from_secs(20), "{:?}", t.elapsed());
    assert!(
        page("/run/0/cmp?json=1")["notes"].to_string().contains("work: "),
        "the Work table says why it is not shown"
    );
    std::fs::remove_file(&run_json).unwrap();
    let unit = std::fs::read_dir(cmp.join("units")).unwrap().next().unwrap().unwrap().path();
    std::fs::remove_file(&unit).unwrap();
    std::os::unix::fs::symlink("/etc/passwd", &unit).unwrap();
    assert_eq!(http_get(&srv.url, "/run/0/cmp").status, 200);
    assert_eq!(http_get(&srv.url, "/").status, 200, "still answering");
}

#[test]
fn damaged_generation_lines_are_shown_and_births_name_the_right_parents() {
    let root = empty_dir("dashboard", "damaged");
    let dir = root.join("run");
    let o = bin()
        .args(["search", "cartpole", "--out"])
        .arg(&dir)
        .args(tiny_with(&["--generations", "3"]))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = read(dir.join("generations.jsonl"));
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 3);
    // An individual of generation 2 with parents, and what its parents were.
    let g2: Value = serde_json::from_str(lines[2]).unwrap();
    let g1: Value = serde_json::from_str(lines[1]).unwrap();
    let child = g2["individuals"].as_array().unwrap().iter().find(|i| i["birth"]["parents"].is_array()).unwrap();
    let id = child["setting"].as_str().unwrap().to_string();
    let parents: Vec<String> = child["birth"]["parents"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| g1["individuals"][p.as_u64().unwrap() as usize]["setting"].as_str().unwrap().to_string())
        .collect();

    let s = serve(&[root.to_path_buf()]);
    let index = child["index"].to_string();
    let births = |s: &Served| {
        let p = s.json(&format!("/run/0/run?setting={id}&json=1"));
        table(&p, "births")["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r[0]["text"] == "2" && r[1]["text"].as_str() == Some(index.as_str()))
            .map(|r| r[3]["text"].as_str().unwrap().to_string())
    };
    assert_eq!(births(&s).unwrap(), parents.join(" × "));

    // One invalid UTF-8 byte in generation 1's line: that line is skipped, and the page says so.
    let mut bytes = text.clone().into_bytes();
    let at = lines[0].len() + 1 + lines[1].find("\"setting\":\"").unwrap() + 11;
    bytes[at] = 0xff;
    std::fs::write(dir.join("generations.jsonl"), &bytes).unwrap();
    let page = s.json("/run/0/run?json=1");
    assert_eq!(page["charts"]["generations"].as_array().unwrap().len(), 2);
    let notes = page["notes"].to_string();
    assert!(notes.contains("generations.jsonl: line 2 skipped: not UTF-8"), "{notes}");
    assert!(s.ok("/run/0/run").contains("line 2 skipped"));
    // Generation 2's parents were in the skipped line: not named from another generation.
    let unread: Vec<String> = child["birth"]["parents"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| format!("#{p} of generation 1 (not read)"))
        .collect();
    assert_eq!(births(&s).unwrap(), unread.join(" × "));
    // A record damaged as JSON: skipped and said so too.
    std::fs::write(dir.join("generations.jsonl"), text.replacen("\"generation\"", "\"generation\":[", 1)).unwrap();
    assert!(s.json("/run/0/run?json=1")["notes"].to_string().contains("line 1 skipped"));
}

// ---- What users of optuna-dashboard expect, on the server's side. ----

#[test]
fn csv_exports_the_stored_numbers_and_pages_carry_the_new_tables() {
    let root = empty_dir("dashboard", "ux");
    let dir = root.join("run");
    tiny_search(&dir);
    // A finished batch, and a rollout with its plots.
    std::fs::create_dir_all(root.join("batch")).unwrap();
    std::fs::write(root.join("batch/batch.json"), r#"[{"name":"a","kind":"search","state":"finished","dir":"run"}]"#)
        .unwrap();
    copy_dir(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("results/rollouts/bicycle-bfqi-et"), &root.join("roll"));
    let s = serve(&[root.to_path_buf()]);

    // The runs list: whole (no scroll box), with start and update times; the batch finished.
    let html = s.ok("/");
    assert!(html.contains("<div class=\"whole\"><table data-table=\"runs\">"), "{}", short(&html));
    let home = s.json("/?json=1");
    let runs = table(&home, "runs")["rows"].as_array().unwrap().clone();
    let row = |name: &str| runs.iter().find(|r| r[0]["text"].as_str().unwrap().ends_with(name)).unwrap().clone();
    let created = common::json(dir.join("run.json"))["created"].as_str().unwrap().to_string();
    assert_eq!(row("/run")[9]["text"], created.as_str());
    assert!(row("/run")[10]["text"].as_str().unwrap().ends_with('Z'));
    assert_eq!(row("/batch")[3]["text"], "finished");

    // CSV: the stored numbers, not the page's four decimals.
    let first: Value = serde_json::from_str(read(dir.join("generations.jsonl")).lines().next().unwrap()).unwrap();
    let csv = s.ok("/run/0/run?csv=generations");
    let best: f64 = csv.lines().nth(1).unwrap().split(',').nth(1).unwrap().parse().unwrap();
    assert_eq!(best, first["stats"]["max"].as_f64().unwrap(), "{csv}");
    assert!(csv.lines().nth(1).unwrap().split(',').nth(1).unwrap().len() > 6, "{csv}");

    // Gene importance, named by its method, as a table and as chart data.
    let page = s.json("/run/0/run?json=1");
    let imp = table(&page, "importance");
    assert!(imp["title"].as_str().unwrap().contains("η²"));
    assert_eq!(rows(imp), 3);
    assert_eq!(page["charts"]["importance"].as_array().unwrap().len(), 3);
    let html = s.ok("/run/0/run");
    assert!(html.contains("id=\"parallel\"") && html.contains("id=\"importance\""));

    // A setting's losses, as chart data: one entry per dataset, iteration and network.
    let id = settings(&dir).into_iter().next().unwrap();
    let setting = s.json(&format!("/run/0/run?setting={id}&json=1"));
    assert_eq!(setting["charts"]["losses"].as_array().unwrap().len(), rows(table(&setting, "networks")));
    assert!(s.ok(&format!("/run/0/run?setting={id}")).contains("id=\"losses\""));

    // The rollout: its fields, its episodes, its state and action plot and its GIF; no cut JSON.
    let r = s.json("/run/0/roll?json=1");
    assert_eq!(rows(table(&r, "episodes")), 1);
    assert!(table(&r, "rollout").to_string().contains("bicycle"));
    assert!(!r.to_string().contains('…'));
    let html = s.ok("/run/0/roll");
    assert!(html.contains("src=\"/file/0/roll/episode-0.png\"") && html.contains("src=\"/file/0/roll/episode-0.gif\""));
}

#[test]
fn two_runs_show_side_by_side_and_their_paths_are_checked_like_run_pages() {
    let s = serve(&[committed()]);
    // Two searches: a GA search against a random one, each curve a generation per point.
    let page = s.json("/compare-runs?a=0/cartpole&b=0/cartpole-random&json=1");
    let runs = page["charts"]["runs"].as_array().unwrap();
    for (run, name) in runs.iter().zip(["cartpole", "cartpole-random"]) {
        let lines = common::read(committed().join(name).join("generations.jsonl")).lines().count();
        assert_eq!(run["generations"].as_array().unwrap().len(), lines, "{name}");
        assert!(run["label"].as_str().unwrap().ends_with(&format!("/{name}")), "{run}");
    }
    let t = table(&page, "pair");
    let row = |name: &str| {
        t["rows"].as_array().unwrap().iter().find(|r| r[0]["text"] == name).unwrap_or_else(|| panic!("{name}: {t}"))
    };
    assert_eq!(row("kind")[1]["text"], "search");
    assert_eq!(row("env")[2]["text"], "cartpole");
    // The units evaluated are the unit files on disk; the best fitness is state.json's.
    let units = std::fs::read_dir(committed().join("cartpole-random/units")).unwrap().count();
    assert_eq!(row("units evaluated")[2]["text"], units.to_string());
    let st = common::json(committed().join("cartpole-random/state.json"));
    assert_eq!(row("best fitness")[2]["value"], st["best_fitness"].as_f64().unwrap().to_string());
    assert!(row("validation (tuned setting, mean ± 95 %)")[1]["text"].as_str().unwrap().contains(" ± "));
    assert!(row("best setting")[1]["text"].as_str().unwrap().contains("patience"), "{t}");
    let html = s.ok("/compare-runs?a=0/cartpole&b=0/cartpole-random");
    assert!(html.contains("id=\"pair\"") && html.contains("href=\"/run/0/cartpole-random\""), "{}", short(&html));
    assert_eq!(s.get("/compare-runs?a=0/cartpole&b=0/cartpole-random&csv=pair").status, 200);

    // A search beside a comparison: what both have, no search rows, no curve for the comparison.
    let mixed = s.json("/compare-runs?a=0/bicycle&b=0/bicycle-compare-mlp-iterations&json=1");
    let names: Vec<&str> =
        table(&mixed, "pair")["rows"].as_array().unwrap().iter().map(|r| r[0]["text"].as_str().unwrap()).collect();
    assert_eq!(names, ["run", "kind", "env", "state"]);
    assert_eq!(mixed["charts"]["runs"][1]["generations"], serde_json::json!([]));
    assert_eq!(mixed["charts"]["runs"][0]["generations"].as_array().unwrap().len(), 20);

    // Paths as run pages check them; a missing run is named as missing, not an error page.
    assert_eq!(s.get("/compare-runs?a=0/cartpole").status, 400);
    assert_eq!(s.get("/compare-runs?a=0/cartpole&b=0/..").status, 403);
    assert_eq!(s.get("/compare-runs?a=0/%2e%2e/searches/cartpole&b=0/cartpole").status, 403);
    assert_eq!(s.get("/compare-runs?a=0/cartpole&b=0/cartpole/units").status, 404);
    assert_eq!(s.get("/compare-runs?a=0/cartpole&b=3/cartpole").status, 404);
    assert_eq!(s.get("/compare-runs?a=0/cartpole&b=x").status, 404);
    assert_eq!(s.get("/compare-runs?a=0/%2Fetc&b=0/cartpole").status, 404);
}
