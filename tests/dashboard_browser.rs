//! The dashboard in a real browser: headless Chromium, driven over the DevTools protocol on a pipe
//! (`--remote-debugging-pipe`), opens a tiny search's page, sees one point per evaluated setting,
//! sees a further generation appear while the page stays open (no reload), renders hostile names
//! as text, and saves screenshots. Skipped, saying why, only where Chromium cannot start.

mod common;
use common::{bin, copy_dir, empty_dir, settings, tiny_with};

use serde_json::{Value, json};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::{Duration, Instant};

/// A headless Chromium and one page in it, spoken to in DevTools protocol messages (JSON, each
/// ended by a NUL byte) over the pipe Chromium reads on fd 3 and writes on fd 4.
struct Browser {
    child: Child,
    to: ChildStdin,
    from: Receiver<Value>,
    next: u64,
    session: Option<String>,
}

impl Browser {
    fn start(profile: &Path) -> Result<Browser, String> {
        if Command::new("chromium").arg("--version").output().is_err() {
            return Err("no `chromium` on PATH (Debian: apt-get install chromium)".into());
        }
        // The shell hands the child's stdin and stdout to Chromium as fds 3 and 4.
        let script = format!(
            "exec chromium --headless --no-sandbox --disable-gpu --disable-dev-shm-usage --hide-scrollbars \
             --no-first-run --window-size=1400,1100 --user-data-dir='{}' --remote-debugging-pipe about:blank \
             3<&0 4>&1 0</dev/null 1>/dev/null 2>/dev/null",
            profile.display()
        );
        let mut child = Command::new("sh")
            .args(["-c", &script])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot start chromium: {e}"))?;
        let to = child.stdin.take().unwrap();
        let mut out = child.stdout.take().unwrap();
        let (tx, from) = channel();
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            let mut chunk = [0u8; 65536];
            while let Ok(n) = out.read(&mut chunk) {
                if n == 0 {
                    break;
                }
                buf.extend_from_slice(&chunk[..n]);
                while let Some(end) = buf.iter().position(|&b| b == 0) {
                    let msg: Vec<u8> = buf.drain(..=end).collect();
                    if let Ok(v) = serde_json::from_slice::<Value>(&msg[..msg.len() - 1])
                        && tx.send(v).is_err()
                    {
                        return;
                    }
                }
            }
        });
        let mut b = Browser { child, to, from, next: 0, session: None };
        b.call("Browser.getVersion", json!({})).map_err(|e| format!("chromium does not answer: {e}"))?;
        Ok(b)
    }

    /// Sends a command (to the page once one is attached) and waits for its result.
    fn call(&mut self, method: &str, params: Value) -> Result<Value, String> {
        self.next += 1;
        let mut msg = json!({ "id": self.next, "method": method, "params": params });
        if let Some(s) = &self.session
            && !method.starts_with("Target.")
            && !method.starts_with("Browser.")
        {
            msg["sessionId"] = json!(s);
        }
        let mut bytes = serde_json::to_vec(&msg).unwrap();
        bytes.push(0);
        self.to.write_all(&bytes).map_err(|e| e.to_string())?;
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.from.recv_timeout(left) {
                Ok(v) if v["id"] == self.next => {
                    return match v.get("error") {
                        Some(e) => Err(format!("{method}: {e}")),
                        None => Ok(v["result"].clone()),
                    };
                }
                Ok(_) => {} // an event
                Err(RecvTimeoutError::Timeout) => return Err(format!("{method}: no answer in 60 s")),
                Err(RecvTimeoutError::Disconnected) => return Err(format!("{method}: chromium exited")),
            }
        }
    }

    /// Opens `url` in a new page and attaches to it.
    fn open(&mut self, url: &str) {
        let t = self.call("Target.createTarget", json!({ "url": url })).unwrap();
        let s = self.call("Target.attachToTarget", json!({ "targetId": t["targetId"], "flatten": true })).unwrap();
        self.session = Some(s["sessionId"].as_str().unwrap().to_string());
    }

    /// The value of a JavaScript expression in the page.
    fn eval(&mut self, expr: &str) -> Value {
        let r = self
            .call("Runtime.evaluate", json!({ "expression": expr, "returnByValue": true, "awaitPromise": true }))
            .unwrap();
        assert!(r.get("exceptionDetails").is_none(), "{expr}: {r}");
        r["result"]["value"].clone()
    }

    /// Waits until `expr` evaluates to `want`; fails with the last value after `secs`.
    fn wait_for(&mut self, expr: &str, want: &Value, secs: u64) {
        let deadline = Instant::now() + Duration::from_secs(secs);
        loop {
            let v = self.eval(expr);
            if &v == want {
                return;
            }
            assert!(Instant::now() < deadline, "{expr}: {v} after {secs} s, want {want}");
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Saves the page as a PNG.
    fn screenshot(&mut self, path: &Path) {
        let r = self.call("Page.captureScreenshot", json!({ "format": "png" })).unwrap();
        let png = base64(r["data"].as_str().unwrap());
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        std::fs::write(path, png).unwrap();
        println!("screenshot: {}", path.display());
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.call("Browser.close", json!({}));
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Standard base64 (the screenshots' encoding).
fn base64(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let digits: Vec<u8> = s.bytes().filter(|&c| c != b'=' && !c.is_ascii_whitespace()).map(val).collect();
    let mut out = Vec::with_capacity(digits.len() * 3 / 4);
    for q in digits.chunks(4) {
        let n = q.iter().enumerate().fold(0u32, |n, (i, &d)| n | (u32::from(d) << (18 - 6 * i)));
        out.extend_from_slice(&n.to_be_bytes()[1..q.len()]);
    }
    out
}

/// `bfqi-ga dashboard` as a child process; killed when dropped.
struct Server {
    child: Child,
    url: String,
}

impl Server {
    /// Serves `roots`; relative ones are the repository's (and are shown as given, relative).
    fn start(roots: &[&Path]) -> Server {
        let mut child = bin()
            .current_dir(repo())
            .arg("dashboard")
            .args(roots)
            .args(["--port", "0"])
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let url = line.trim().strip_prefix("bfqi-ga dashboard: ").unwrap_or_else(|| panic!("{line}")).to_string();
        Server { child, url }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The repository's top folder.
fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn screenshots() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("dashboard-screenshots");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A browser with its profile under `top`, or `None` after saying why none could start (the test
/// is then skipped).
fn browser_or_skip(top: &Path) -> Option<Browser> {
    match Browser::start(&top.join("profile")) {
        Ok(b) => Some(b),
        Err(why) => {
            println!("skipped: {why}");
            None
        }
    }
}

#[test]
fn the_page_shows_every_setting_and_a_new_generation_without_a_reload() {
    let top = empty_dir("dashboard-browser", "live");
    let root = top.join("served");
    let run = root.join("run");
    let o = bin().args(["search", "cartpole", "--out"]).arg(&run).args(tiny_with(&[])).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The same run under a name a browser would run as markup if it were not escaped.
    copy_dir(&run, &root.join("<img src=x onerror=window.pwned=1>"));

    let Some(mut browser) = browser_or_skip(&top) else { return };
    let server = Server::start(&[&root]);
    let shots = screenshots();

    browser.open(&format!("{}run/0/run", server.url));
    let before = settings(&run).len();
    let points = "document.querySelectorAll('#explorer .pt').length";
    let generations = "document.querySelectorAll('table[data-table=generations] tbody tr').length";
    browser.wait_for(points, &json!(before), 30);
    browser.wait_for(generations, &json!(2), 5);
    // A mark on this page's window: a reload would lose it.
    browser.eval("window.stayed = 'yes'");
    let draws = browser.eval("window.dashboardDrawn.count").as_u64().unwrap();
    browser.screenshot(&shots.join("search-2-generations.png"));

    // A third generation, written by the search itself while the page is open.
    let o = bin().args(["search", "--resume"]).arg(&run).args(["--generations", "3", "--quiet"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let after = settings(&run).len();
    assert!(after > before, "the third generation brings new settings: {before} → {after}");
    browser.wait_for(points, &json!(after), 30);
    browser.wait_for(generations, &json!(3), 5);
    assert_eq!(browser.eval("window.stayed"), json!("yes"), "updated in place, not reloaded");
    assert!(browser.eval("window.dashboardDrawn.count").as_u64().unwrap() > draws);
    // The fitness chart follows too: a point per generation on its best-so-far line.
    let chart = browser.eval("document.querySelector('#fitness svg').textContent");
    assert!(chart.as_str().unwrap().contains("Fitness per generation"), "{chart}");
    browser.screenshot(&shots.join("search-3-generations.png"));

    // A setting's page from the explorer's links.
    let href = browser.eval("document.querySelector('#explorer a').getAttribute('href')");
    browser.open(&format!("{}{}", server.url.trim_end_matches('/'), href.as_str().unwrap()));
    browser.wait_for("document.querySelectorAll('table[data-table=datasets] tbody tr').length", &json!(2), 30);
    browser.screenshot(&shots.join("setting.png"));

    // The hostile name shows as text: no image element, no script ran.
    browser.open(&server.url);
    browser.wait_for("document.querySelectorAll('table[data-table=runs] tbody tr').length", &json!(2), 30);
    assert_eq!(browser.eval("document.querySelectorAll('img').length"), json!(0));
    assert_eq!(browser.eval("document.body.textContent.includes('<img src=x onerror=window.pwned=1>')"), json!(true));
    // Its copy was taken before the third generation: the first two generations' settings.
    browser.open(&format!("{}run/0/%3Cimg%20src%3Dx%20onerror%3Dwindow.pwned%3D1%3E", server.url));
    browser.wait_for(points, &json!(before), 30);
    assert_eq!(browser.eval("typeof window.pwned"), json!("undefined"));
    assert_eq!(browser.eval("document.scripts.length"), json!(1), "only the dashboard's own script");
}

#[test]
fn the_committed_bicycle_search_draws_every_setting() {
    let top = empty_dir("dashboard-browser", "bicycle");
    let Some(mut browser) = browser_or_skip(&top) else { return };
    // Served by its relative path, as a user would: the page (and the README's screenshot of it)
    // shows `results/searches/bicycle`, not where this checkout happens to be.
    let server = Server::start(&[Path::new("results/searches")]);
    let n = settings(&repo().join("results/searches/bicycle")).len();
    browser.open(&format!("{}run/0/bicycle", server.url));
    browser.wait_for("document.querySelectorAll('#explorer .pt').length", &json!(n), 30);
    assert_eq!(browser.eval("document.querySelector('h1').textContent"), json!("search results/searches/bicycle"));
    // From navigation start to the charts drawn from the first poll: the first useful paint.
    let ms = browser.eval("window.dashboardDrawn.firstMs").as_f64().unwrap();
    println!("bicycle search ({n} settings): charts drawn {ms:.0} ms after navigation start");
    // Printed, not asserted: speed is the bench's (`bfqi-ga bench dashboard`), not a test's.
    browser.screenshot(&screenshots().join("bicycle.png"));
}

#[test]
fn one_generation_is_drawn_tables_sort_and_filter_and_new_tables_arrive_live() {
    let top = empty_dir("dashboard-browser", "ux");
    let root = top.join("served");
    let run = root.join("run");
    let o = bin()
        .args(["search", "cartpole", "--out"])
        .arg(&run)
        .args(tiny_with(&["--generations", "1"]))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    copy_dir(&run, &root.join("second"));
    // Validation not yet there when the page opens.
    let held = top.join("validation.json");
    std::fs::rename(run.join("validation.json"), &held).unwrap();

    let Some(mut browser) = browser_or_skip(&top) else { return };
    let server = Server::start(&[&root]);
    browser.open(&format!("{}run/0/run", server.url));
    let n = settings(&run).len();
    browser.wait_for("document.querySelectorAll('#explorer .pt').length", &json!(n), 30);
    // One generation: its points are drawn, not empty axes.
    assert!(browser.eval("document.querySelectorAll('#fitness circle.gen').length").as_u64().unwrap() >= 3);
    // The legend sits right of the plot area, not over it; the explorer has a colour bar.
    let outside = "(() => { const s = document.querySelector('#fitness svg'), r = s.querySelector('rect'); \
        const right = +r.getAttribute('x') + +r.getAttribute('width'); const l = [...s.querySelectorAll('.legend')]; \
        return l.length > 0 && l.every((e) => +e.getAttribute('x') >= right); })()";
    assert_eq!(browser.eval(outside), json!(true));
    assert_eq!(browser.eval("document.querySelectorAll('#explorer .colourbar rect').length > 0"), json!(true));
    // Parallel coordinates: a line per scored setting; importance bars, one per gene.
    let page: Value = serde_json::from_str(&common::http_get(&server.url, "/run/0/run?json=1").body).unwrap();
    let scored = page["charts"]["points"].as_array().unwrap().iter().filter(|p| p["fitness"].is_number()).count();
    assert_eq!(browser.eval("document.querySelectorAll('#parallel .pc').length"), json!(scored));
    assert_eq!(browser.eval("document.querySelectorAll('#importance .bar').length"), json!(3));
    // A chart saves as SVG.
    let svg = browser.eval(
        "window.dashboardSvg('fitness').then((t) => t.startsWith('<svg') && t.includes('Fitness per generation'))",
    );
    assert_eq!(svg, json!(true));
    browser.screenshot(&screenshots().join("search-1-generation.png"));

    // Validation lands while the page is open: its table appears without a reload.
    browser.eval("window.stayed = 'yes'");
    std::fs::rename(&held, run.join("validation.json")).unwrap();
    browser.wait_for("document.querySelectorAll('table[data-table=validation] tbody tr').length > 0", &json!(true), 30);
    assert_eq!(browser.eval("window.stayed"), json!("yes"));

    // The runs table: whole, sortable by a click on a heading, filtered by the box above it.
    browser.open(&server.url);
    let rows = "[...document.querySelectorAll('table[data-table=runs] tbody tr')].filter((r) => !r.hidden).map((r) => r.cells[0].textContent)";
    browser.wait_for(&format!("{rows}.length"), &json!(2), 30);
    // The script has run (its handlers are on the headings) and drawn from its first poll.
    browser.wait_for("!!window.dashboardDrawn && window.dashboardDrawn.count > 0", &json!(true), 30);
    browser.eval("document.querySelector('table[data-table=runs] th').click()");
    let asc = browser.eval(rows);
    browser.eval("document.querySelector('table[data-table=runs] th').click()");
    let desc = browser.eval(rows);
    let mut rev = asc.as_array().unwrap().clone();
    rev.reverse();
    assert_eq!(desc, json!(rev));
    assert!(asc[0].as_str().unwrap().ends_with("/run"), "{asc}");
    browser.eval(
        "const f = document.querySelector('input.filter'); f.value = 'second'; f.dispatchEvent(new Event('input'))",
    );
    let shown = browser.eval(rows);
    assert_eq!(shown.as_array().unwrap().len(), 1);
    assert!(shown[0].as_str().unwrap().ends_with("/second"), "{shown}");
    assert_eq!(
        browser.eval("getComputedStyle(document.querySelector('table[data-table=runs]').parentNode).maxHeight"),
        json!("none")
    );
    browser.screenshot(&screenshots().join("runs.png"));
}

/// The texts of the elements `selector` matches.
fn texts(browser: &mut Browser, selector: &str) -> Vec<String> {
    let v = browser.eval(&format!("[...document.querySelectorAll({selector:?})].map((e) => e.textContent)"));
    serde_json::from_value(v).unwrap()
}

#[test]
fn committed_runs_draw_losses_plots_gifs_log_axes_and_clear_parallel_coordinates() {
    let top = empty_dir("dashboard-browser", "committed");
    let Some(mut browser) = browser_or_skip(&top) else { return };
    let roots = ["results/searches", "results/rollouts", "results/thesis"].map(Path::new);
    let server = Server::start(&roots);
    let shots = screenshots();

    // A setting's page: its losses drawn as paths and points, one point per network's training
    // loss (all > 0 in these units, so the axis is log), not empty axes.
    let st: Value = common::json(repo().join("results/searches/bicycle/state.json"));
    let best: bfqi_ga::ga::chromosome::Decoded = serde_json::from_value(st["best"].clone()).unwrap();
    let id = bfqi_ga::ga::units::setting_id(&best);
    let path = format!("/run/0/bicycle?setting={id}");
    let page: Value = serde_json::from_str(&common::http_get(&server.url, &format!("{path}&json=1")).body).unwrap();
    let losses = page["charts"]["losses"].as_array().unwrap();
    let train = losses.iter().filter(|l| l["train"].as_f64().is_some_and(|v| v > 0.0)).count();
    assert!(train > 0, "the best setting's units record losses");
    browser.open(&format!("{}{}", server.url.trim_end_matches('/'), path));
    browser.wait_for("document.querySelectorAll('#losses circle.loss').length", &json!(train), 30);
    assert!(browser.eval("document.querySelectorAll('#losses path').length").as_u64().unwrap() > 0);
    assert!(texts(&mut browser, "#losses .yticks text").iter().all(|t| t.starts_with("1e")));
    browser.screenshot(&shots.join("setting-losses.png"));

    // A rollout's page: its state/action plot and its GIF, both decoded by the browser.
    browser.open(&format!("{}run/1/cartpole-ga-optimum", server.url));
    let loaded =
        "[...document.images].filter((i) => i.complete && i.naturalWidth > 0).map((i) => i.getAttribute('src'))";
    browser.wait_for(&format!("{loaded}.length"), &json!(2), 30);
    let srcs = browser.eval(loaded);
    for want in ["/file/1/cartpole-ga-optimum/episode-0.png", "/file/1/cartpole-ga-optimum/episode-0.gif"] {
        assert!(srcs.as_array().unwrap().contains(&json!(want)), "{want} not shown: {srcs}");
    }
    browser.wait_for("document.querySelectorAll('table[data-table=episodes] tbody tr').length", &json!(1), 30);
    browser.screenshot(&shots.join("rollout.png"));

    // A sample-size comparison: episodes on a log axis (ticks at powers of ten), and its toggle
    // switches that axis to linear and back.
    browser.open(&format!("{}run/2/cartpole-et-samples", server.url));
    browser.wait_for("document.querySelectorAll('#curve-0 .xticks text').length > 1", &json!(true), 30);
    let log = texts(&mut browser, "#curve-0 .xticks text");
    assert!(log.iter().all(|t| t.starts_with("1e")), "{log:?}");
    let label = "[...document.querySelectorAll('#curve-0 svg > text')].some((t) => t.textContent === 'episodes (log)')";
    assert_eq!(browser.eval(label), json!(true));
    let button = "document.querySelector('#curve-0 button[data-axis=\"curve-0:x\"]')";
    assert_eq!(browser.eval(&format!("{button}.textContent")), json!("x: log"));
    browser.eval(&format!("{button}.click()"));
    let linear = texts(&mut browser, "#curve-0 .xticks text");
    assert!(linear.len() > 1 && linear.iter().all(|t| t.parse::<f64>().is_ok()), "{linear:?}");
    assert_eq!(browser.eval(&format!("{button}.textContent")), json!("x: linear"));
    browser.screenshot(&shots.join("samples-linear.png"));
    // The choice survives the page's live redraws (a poll with changed data redraws all charts).
    browser.eval("render(lastCharts)");
    assert_eq!(texts(&mut browser, "#curve-0 .xticks text"), linear);
    browser.eval(&format!("{button}.click()"));
    assert_eq!(texts(&mut browser, "#curve-0 .xticks text"), log);

    // Log is offered only where every value is > 0: cart-pole's fitness (> 0) has a toggle,
    // the bicycle's (< 0) none; patience (≥ 1) has one on both.
    for (run, fitness_toggles) in [("cartpole", 1), ("bicycle", 0)] {
        browser.open(&format!("{}run/0/{run}", server.url));
        browser.wait_for("document.querySelectorAll('#explorer .pt').length > 0", &json!(true), 30);
        assert_eq!(browser.eval("document.querySelectorAll('#fitness button.scale').length"), json!(fitness_toggles));
        let patience = "document.querySelector('#gene-patience button[data-axis=\"gene-patience:x\"]')";
        assert_eq!(browser.eval(&format!("{patience}.textContent")), json!("x: linear"), "{run}");
    }
    browser.eval("document.querySelector('#gene-patience button[data-axis=\"gene-patience:x\"]').click()");
    let ticks = texts(&mut browser, "#gene-patience .xticks text");
    assert!(ticks.len() > 1 && ticks.iter().all(|t| t.starts_with("1e")), "{ticks:?}");

    // Parallel coordinates: no 0–1 axis of the frame's own; every gene axis its own ticks; no
    // label reaching into the colour bar.
    assert_eq!(browser.eval("document.querySelectorAll('#parallel .yticks text').length"), json!(0));
    let per_axis =
        browser.eval("[...document.querySelectorAll('#parallel .pc-ticks')].map((g) => g.children.length / 2)");
    assert_eq!(per_axis.as_array().unwrap().len(), 4, "{per_axis}");
    assert!(per_axis.as_array().unwrap().iter().all(|n| n.as_f64().unwrap() >= 2.0), "{per_axis}");
    assert_eq!(texts(&mut browser, "#parallel .pc-ticks")[0], "sigmoidtanhrelu");
    let clear = "(() => { const s = document.querySelector('#parallel svg'); \
        const bar = Math.min(...[...s.querySelectorAll('.colourbar rect')].map((r) => r.getBBox().x)); \
        const over = [...s.querySelectorAll('text')].filter((t) => !t.closest('.colourbar')) \
          .filter((t) => { const b = t.getBBox(); return b.x + b.width > bar; }); \
        return over.map((t) => t.textContent); })()";
    assert_eq!(browser.eval(clear), json!([]));
    browser.screenshot(&shots.join("bicycle-parallel.png"));
}

#[test]
fn two_runs_ticked_in_the_runs_table_open_side_by_side() {
    let top = empty_dir("dashboard-browser", "pair");
    let Some(mut browser) = browser_or_skip(&top) else { return };
    let server = Server::start(&[Path::new("results/searches")]);
    browser.open(&server.url);
    browser.wait_for("document.querySelectorAll('table[data-table=runs] input.pick').length > 2", &json!(true), 30);
    assert_eq!(browser.eval("document.getElementById('compare-runs').disabled"), json!(true));
    for name in ["cartpole", "cartpole-random"] {
        let tick = format!(
            "[...document.querySelectorAll('table[data-table=runs] tbody tr')] \
             .find((r) => r.cells[0].textContent.endsWith('/{name}')).querySelector('input.pick').click()"
        );
        browser.eval(&tick);
    }
    assert_eq!(browser.eval("document.getElementById('compare-runs').disabled"), json!(false));
    browser.eval("document.getElementById('compare-runs').click()");
    browser.wait_for(
        "location.pathname + location.search",
        &json!("/compare-runs?a=0%2Fcartpole&b=0%2Fcartpole-random"),
        30,
    );

    // Both runs' best-so-far curves, a point per generation each, in two colours with a legend.
    browser.wait_for("document.querySelectorAll('#pair path.curve').length", &json!(2), 30);
    for (i, name) in ["cartpole", "cartpole-random"].iter().enumerate() {
        let n = common::read(repo().join("results/searches").join(name).join("generations.jsonl")).lines().count();
        assert_eq!(browser.eval(&format!("document.querySelectorAll('#pair circle.run-{i}').length")), json!(n));
    }
    // Best-so-far values differ in the first decimal: the ticks still read apart.
    let ticks = texts(&mut browser, "#pair .yticks text");
    let distinct: std::collections::BTreeSet<&String> = ticks.iter().collect();
    assert!(ticks.len() > 2 && distinct.len() == ticks.len(), "{ticks:?}");
    let colours =
        browser.eval("[...document.querySelectorAll('#pair path.curve')].map((p) => p.getAttribute('stroke'))");
    assert_ne!(colours[0], colours[1]);
    let legend = texts(&mut browser, "#pair svg > text");
    for want in ["results/searches/cartpole", "results/searches/cartpole-random"] {
        assert!(legend.iter().any(|t| t == want), "{want} not in the legend: {legend:?}");
    }
    // The table side by side, and the page keeps polling like every other.
    let rows = texts(&mut browser, "table[data-table=pair] tbody tr td:first-child");
    assert!(rows.iter().any(|r| r == "units evaluated") && rows.iter().any(|r| r == "best setting"), "{rows:?}");
    browser.wait_for("window.dashboardDrawn.count > 0", &json!(true), 30);
    browser.screenshot(&screenshots().join("pair.png"));
}
