//! `bench dashboard`: what the first useful paint of a search page costs on the committed bicycle
//! search (2,680 units): the runs page, the search page, its JSON (the charts' data) and the
//! script, each timed over a real local HTTP connection; and the process's memory, to show that
//! serving does not hold every unit's iterations.

use crate::dashboard::{Dashboard, Options};
use crate::error::{Error, Result};
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::path::Path;
use std::time::Instant;

/// Requests per page: the first is the first this process serves (the server keeps nothing
/// between requests, so each reads the run's files again), the median of the rest the steady figure.
const REPEATS: usize = 7;

/// Times the pages a browser fetches to draw `results/searches/bicycle`'s search page.
pub fn dashboard(json_out: bool) -> Result<Value> {
    let root = Path::new("results/searches");
    if !root.join("bicycle/generations.jsonl").is_file() {
        return Err(Error::Usage(
            "bench dashboard reads results/searches/bicycle: run it from the repository's top folder".into(),
        ));
    }
    let rss_before = memory_kib("VmRSS");
    let d = Dashboard::bind(&Options { roots: vec![root.to_path_buf()], host: "127.0.0.1".into(), port: 0 })?;
    let addr = d.url().trim_start_matches("http://").trim_end_matches('/').to_string();
    let stop = d.stopper();
    let units = std::fs::read_dir(root.join("bicycle/units")).map_or(0, |d| d.count());
    let pages = ["/", "/run/0/bicycle", "/run/0/bicycle?json=1", "/assets/app.js"];
    let mut rows = Vec::new();
    std::thread::scope(|s| -> Result<()> {
        s.spawn(|| d.run());
        let result = (|| {
            for path in pages {
                let mut times = Vec::new();
                let mut bytes = 0;
                for _ in 0..REPEATS {
                    let t = Instant::now();
                    bytes = get(&addr, path)?;
                    times.push(t.elapsed().as_secs_f64());
                }
                let cold = times[0];
                let mut warm = times[1..].to_vec();
                warm.sort_by(f64::total_cmp);
                rows.push((path, cold, warm[warm.len() / 2], bytes));
            }
            Ok(())
        })();
        stop();
        result
    })?;
    let committed = committed_runs()?;
    let peak = memory_kib("VmHWM");
    // The first paint needs the page, then its script and its JSON (fetched one after the other).
    let paint_cold: f64 = rows[1..].iter().map(|r| r.1).sum();
    let paint_warm: f64 = rows[1..].iter().map(|r| r.2).sum();
    if !json_out {
        println!("bench dashboard · results/searches/bicycle ({units} units) over 127.0.0.1, {REPEATS} requests each");
        println!("{:<24} {:>10} {:>12} {:>10}", "request", "first ms", "median ms", "bytes");
        for (path, cold, warm, bytes) in &rows {
            println!("{path:<24} {:>10.1} {:>12.1} {bytes:>10}", cold * 1e3, warm * 1e3);
        }
        println!(
            "search page's first useful paint (page + script + JSON): {:.0} ms first, {:.0} ms median (target ≤ 1000 ms)",
            paint_cold * 1e3,
            paint_warm * 1e3
        );
        match (rss_before, peak) {
            (Some(a), Some(p)) => println!(
                "memory: {:.1} MiB resident before serving, {:.1} MiB peak (the units' files: {:.1} MiB on disk)",
                a as f64 / 1024.0,
                p as f64 / 1024.0,
                dir_bytes(&root.join("bicycle/units")) as f64 / 1048576.0
            ),
            _ => println!("memory: not measured (no /proc/self/status)"),
        }
        let c = &committed;
        println!(
            "every committed run's page, first view (Work table from work.json): {} runs, median {:.0} ms, slowest {:.0} ms ({}) (target < 1000 ms)",
            c.views.len(),
            c.median * 1e3,
            c.slowest.1 * 1e3,
            c.slowest.0
        );
        println!(
            "{} overlapping first requests for {}: {:.0} ms for the last to be answered (they share one reading)",
            OVERLAPPING,
            c.slowest.0,
            c.overlapping * 1e3
        );
    }
    Ok(json!({
        "committed_runs": committed.views.iter().map(|(p, s)| json!({"path": p, "first_s": s})).collect::<Vec<_>>(),
        "committed_first_view_median_s": committed.median,
        "committed_first_view_slowest_s": committed.slowest.1,
        "overlapping_requests": OVERLAPPING,
        "overlapping_last_s": committed.overlapping,
        "units": units,
        "requests": rows.iter().map(|(p, c, w, b)| json!({"path": p, "first_s": c, "median_s": w, "bytes": b})).collect::<Vec<_>>(),
        "first_paint_first_s": paint_cold,
        "first_paint_median_s": paint_warm,
        "rss_before_kib": rss_before,
        "peak_rss_kib": peak,
    }))
}

/// Requests for one page sent at once, in [`committed_runs`].
const OVERLAPPING: usize = 6;

/// First views of the committed runs' pages.
struct Committed {
    /// Each run's page and the seconds of its first view.
    views: Vec<(String, f64)>,
    median: f64,
    /// The slowest page and its seconds.
    slowest: (String, f64),
    /// The slowest page asked [`OVERLAPPING`] times at once by a fresh server: seconds until the
    /// last answer.
    overlapping: f64,
}

/// Serves `results/` and views each run's page once (each view the first of its run in this
/// server), then asks the slowest page of a fresh server [`OVERLAPPING`] times at once.
fn committed_runs() -> Result<Committed> {
    let serve = |f: &mut dyn FnMut(&str) -> Result<()>| -> Result<()> {
        let d = Dashboard::bind(&Options { roots: vec!["results".into()], host: "127.0.0.1".into(), port: 0 })?;
        let addr = d.url().trim_start_matches("http://").trim_end_matches('/').to_string();
        let stop = d.stopper();
        std::thread::scope(|s| {
            s.spawn(|| d.run());
            let r = f(&addr);
            stop();
            r
        })
    };
    let runs = crate::dashboard::discover::Roots::new(&["results".into()])?.runs();
    let mut views = Vec::new();
    serve(&mut |addr| {
        for r in &runs {
            let url = r.url();
            let t = Instant::now();
            get(addr, &url)?;
            views.push((url, t.elapsed().as_secs_f64()));
        }
        Ok(())
    })?;
    let mut sorted: Vec<f64> = views.iter().map(|v| v.1).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let slowest = views.iter().max_by(|a, b| a.1.total_cmp(&b.1)).cloned().unwrap_or_default();
    let mut overlapping = 0.0;
    crate::dashboard::runs::forget_works();
    serve(&mut |addr| {
        let t = Instant::now();
        std::thread::scope(|s| {
            let asks: Vec<_> = (0..OVERLAPPING).map(|_| s.spawn(|| get(addr, &slowest.0))).collect();
            asks.into_iter().try_for_each(|a| {
                a.join().unwrap_or_else(|_| Err(Error::Usage("a request panicked".into()))).map(|_| ())
            })
        })?;
        overlapping = t.elapsed().as_secs_f64();
        Ok(())
    })?;
    Ok(Committed { views, median, slowest, overlapping })
}

/// One GET over a fresh connection; the response's size. A status other than 200 is an error.
fn get(addr: &str, path: &str) -> Result<usize> {
    let fail = |e: std::io::Error| Error::Usage(format!("GET {path}: {e}"));
    let mut s = std::net::TcpStream::connect(addr).map_err(fail)?;
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").map_err(fail)?;
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).map_err(fail)?;
    let status = raw.split(|&b| b == b' ').nth(1).map(String::from_utf8_lossy).unwrap_or_default().into_owned();
    if status != "200" {
        return Err(Error::Usage(format!("GET {path}: status {status}")));
    }
    Ok(raw.len())
}

/// A line of `/proc/self/status` in KiB (`VmRSS` now, `VmHWM` the peak); `None` off Linux.
fn memory_kib(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn dir_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir).into_iter().flatten().flatten().filter_map(|e| e.metadata().ok()).map(|m| m.len()).sum()
}
