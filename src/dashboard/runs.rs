//! The runs page's rows, and the pages of comparisons, batches and rollouts: read from their
//! small files (`state.json`, `run.json`, `summary.csv`, `report.md`, `batch.json`), never
//! from every unit.

use super::discover::{Kind, Roots, Run};
use super::search::{plain, state};
use super::table::{Cell, Table, num};
use crate::ga::records::Phase;
use crate::ga::units::describe;
use crate::progress::human;
use serde_json::{Value, json};

/// The runs table: every search, comparison, batch and rollout under the roots; and what could
/// not be read of them.
pub fn table(roots: &Roots) -> (Table, Vec<String>) {
    let mut t = Table::new(
        "runs",
        "Runs",
        &[
            "run",
            "kind",
            "env",
            "state",
            "generation",
            "best fitness",
            "settings",
            "progress",
            "ETA",
            "started",
            "updated",
        ],
    );
    t.full = true;
    let mut notes = Vec::new();
    for run in roots.runs() {
        let mut r = row(&run, roots);
        r.push(Cell::text(run.json::<Value>("run.json").map_or("—".into(), |i| plain(&i["created"]))));
        r.push(Cell::text(updated(&run).map_or("—".into(), |s| crate::store::utc(s).1)));
        t.push(r);
        notes.extend(run.notes().into_iter().map(|n| format!("{}: {n}", run.label(roots))));
    }
    (t, notes)
}

/// A run's row of the runs table, without its times: run, kind, env, state, generation, best
/// fitness, settings, progress, ETA.
pub(super) fn row(run: &Run, roots: &Roots) -> Vec<Cell> {
    let info: Value = run.json("run.json").unwrap_or_default();
    let env = info["env"].as_str().map(String::from);
    let cells = |state: String, generation: String, best: String, settings: String, progress: String, eta: String| {
        vec![
            Cell::link(run.label(roots), run.url()),
            Cell::text(run.kind.name()),
            Cell::text(env.clone().unwrap_or_else(|| "—".into())),
            Cell::text(state),
            Cell::text(generation),
            Cell::text(best),
            Cell::text(settings),
            Cell::text(progress),
            Cell::text(eta),
        ]
    };
    let dash = || "—".to_string();
    match run.kind {
        Kind::Search => match state(run) {
            Some((st, phase)) => cells(
                phase.name().into(),
                format!("{}/{}", st.generation, st.generations),
                num(st.best_fitness),
                st.best.as_ref().map_or_else(dash, describe),
                if st.units_total > 0 { format!("units {}/{}", st.units_done, st.units_total) } else { dash() },
                match phase {
                    Phase::Running => st.eta_seconds.map_or("?".into(), human),
                    _ => dash(),
                },
            ),
            None => cells("unreadable".into(), dash(), dash(), dash(), dash(), dash()),
        },
        Kind::Compare => {
            let done = std::fs::read_dir(run.dir.join("units")).map_or(0, |d| d.count());
            let state = if run.is_held() {
                "running"
            } else if crate::store::something_at(&run.dir.join("report.md")) {
                "finished"
            } else {
                "interrupted"
            };
            let settings = format!("{} · {}", plain(&info["learner"]), plain(&info["analysis"]));
            cells(state.into(), dash(), dash(), settings, format!("{done} units"), dash())
        }
        Kind::Batch => {
            let jobs: Vec<Value> = run.json("batch.json").unwrap_or_default();
            let done = jobs.iter().filter(|j| j["state"] == "finished").count();
            let state = if run.is_held() {
                "running"
            } else if !jobs.is_empty() && done == jobs.len() {
                "finished"
            } else {
                "stopped"
            };
            cells(
                state.into(),
                dash(),
                dash(),
                format!("{} jobs", jobs.len()),
                format!("{done}/{} jobs finished", jobs.len()),
                dash(),
            )
        }
        Kind::Rollout => {
            let r: Value = run.json("rollout.json").unwrap_or_default();
            let env = r["info"]["env"]["name"].as_str().unwrap_or("—").to_string();
            let mut c = cells("finished".into(), dash(), dash(), plain(&r["info"]["source"]), dash(), dash());
            c[2] = Cell::text(env);
            c
        }
    }
}

/// The images of a run directory to show (PNG plots and GIF animations), as `/file/` links.
pub fn images(run: &Run, ext: &str) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = std::fs::read_dir(&run.dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(ext) && !n.starts_with('.'))
        .map(|n| {
            let rel = if run.rel.is_empty() { n.clone() } else { format!("{}/{n}", run.rel) };
            (n, format!("/file/{}/{}", run.root, super::html::encode_path(&rel)))
        })
        .collect();
    out.sort();
    out
}

/// A comparison's page: its summary (curves with 95 % bands drawn from it) and the claims its
/// report states, with the thesis's statement beside each verdict.
pub fn comparison(run: &Run) -> (Vec<Table>, Value) {
    let text = run.text("summary.csv").unwrap_or_default();
    let mut lines = text.lines();
    let cols: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let mut t = Table::new("summary", "Summary (mean, std and 95 % interval per point)", &cols);
    let mut series: Vec<Value> = Vec::new();
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != cols.len() {
            continue; // a line being written
        }
        let get = |k: &str| cols.iter().position(|c| *c == k).map(|i| f[i]).unwrap_or("");
        series.push(json!({
            "analysis": get("analysis"), "learner": get("learner"), "algorithm": get("algorithm"),
            "complexity": get("complexity"), "episodes": get("episodes"),
            "iteration": get("iteration").parse::<f64>().ok(), "mean": get("mean").parse::<f64>().ok(),
            "ci95": get("ci95").parse::<f64>().ok(),
        }));
        t.push(f.iter().map(|s| Cell::text(*s)).collect());
    }
    let mut claims = Table::new("claims", "Thesis claims", &["the thesis says", "verdict here", "rule", "this run"]);
    let report = run.text("report.md").unwrap_or_default();
    let mut lines = report.lines().skip_while(|l| !l.starts_with("## Thesis claims")).peekable();
    while let Some(l) = lines.next() {
        if let Some(rest) = l.strip_prefix("- **") {
            let (verdict, statement) = rest.split_once("** — ").unwrap_or((rest, ""));
            let mut next = |p: &str| lines.next().and_then(|x| x.trim().strip_prefix(p).map(String::from));
            let rule = next("- rule: ").unwrap_or_default();
            let evidence = next("- this run: ").unwrap_or_default();
            claims.push(vec![Cell::text(statement), Cell::text(verdict), Cell::text(rule), Cell::text(evidence)]);
        }
    }
    (vec![claims, t], json!({ "series": series }))
}

/// A run directory's work as last read, with the fingerprint it was read at; one lock per run, so
/// that overlapping requests for a run share one reading rather than each doing it.
type WorkSlot = std::sync::Arc<std::sync::Mutex<Option<(String, crate::work::Work)>>>;
static WORKS: std::sync::Mutex<Option<std::collections::HashMap<std::path::PathBuf, WorkSlot>>> =
    std::sync::Mutex::new(None);

/// Forgets every work read so far: `bench dashboard` times first views.
pub fn forget_works() {
    if let Ok(mut w) = WORKS.lock() {
        *w = None;
    }
}

/// A search's, comparison's or batch's work as a table: its `work.json` while current, else
/// counted from its units ([`crate::work::cached`]: no dataset is collected, no process started),
/// every file read inside the run's root; none when it cannot be counted. The page polls every
/// 2 s, so a run's work is read again only when its [`crate::work::fingerprint`] changed.
pub fn work(run: &Run) -> Option<Table> {
    let slot = WORKS.lock().ok()?.get_or_insert_with(Default::default).entry(run.dir.clone()).or_default().clone();
    let w = {
        let mut held = slot.lock().ok()?;
        let roots = Some(std::sync::Arc::new(vec![run.base.clone()]));
        crate::store::confined(roots, || {
            let now = crate::work::fingerprint(&run.dir).map_err(|e| run.note(format!("work: {e}"))).ok()?;
            match held.as_ref() {
                Some((f, w)) if *f == now => Some(w.clone()),
                _ => match crate::work::cached(&run.dir) {
                    Ok(w) => {
                        *held = Some((now, w.clone()));
                        Some(w)
                    }
                    Err(e) => {
                        run.note(format!("work: {e}"));
                        None
                    }
                },
            }
        })?
    };
    let mut t = Table::new(
        "work",
        &format!("Work, counted from the units (machine-independent), and hours on the {}", w.reference),
        &["network units", "tree units", "epochs", "epoch-rows", "FLOPs", "reference hours", "wall time", "ran on"],
    );
    t.push(vec![
        Cell::text(w.units.to_string()),
        Cell::text(w.tree_units.to_string()),
        Cell::text(w.epochs.to_string()),
        Cell::text(format!("{:.4e}", w.epoch_rows as f64)),
        Cell::text(format!("{:.4e}", w.flops)),
        Cell::num(Some(w.reference_hours)),
        Cell::text(w.wall_seconds.map_or("not recorded".into(), human)),
        Cell::text(if w.machines.is_empty() { "not recorded".into() } else { w.machines.join("; ") }),
    ]);
    Some(t)
}

/// A batch's page: its jobs, linked to their run directories when those are served.
pub fn batch(run: &Run, roots: &Roots) -> Vec<Table> {
    let jobs: Vec<Value> = run.json("batch.json").unwrap_or_default();
    let mut t = Table::new("jobs", "Jobs", &["name", "kind", "state", "directory", "seconds", "result", "message"]);
    for j in &jobs {
        let dir = plain(&j["dir"]);
        let link = [run.dir.join(&dir), std::path::PathBuf::from(&dir)]
            .iter()
            .find_map(|p| roots.contains(p))
            .and_then(|(r, rel)| roots.run(r, &rel))
            .map(|r| r.url());
        t.push(vec![
            Cell::text(plain(&j["name"])),
            Cell::text(plain(&j["kind"])),
            Cell::text(plain(&j["state"])),
            match link {
                Some(l) => Cell::link(&dir, l),
                None => Cell::text(&dir),
            },
            Cell::text(j["seconds"].as_f64().map_or("—".into(), |s| format!("{s:.0}"))),
            Cell::text(plain(&j["result"])),
            Cell::text(plain(&j["message"])),
        ]);
    }
    vec![t]
}

/// A rollout's page: what was rolled out, and each episode (its state and action plots and its
/// GIF are the page's images).
pub fn rollout(run: &Run) -> Vec<Table> {
    let r: Value = run.json("rollout.json").unwrap_or_default();
    let mut t = Table::new("rollout", "Rollout", &["field", "value"]);
    let i = &r["info"];
    let fields = [
        ("env", &i["env"]["name"]),
        ("algorithm", &i["algorithm"]),
        ("learner", &i["learner"]),
        ("source", &i["source"]),
        ("model", &r["model"]),
        ("start", &r["start"]),
        ("max steps", &r["max_steps"]),
        ("mean score", &r["result"]["score"]),
        ("failures", &r["result"]["failures"]),
        ("commit", &i["commit"]),
    ];
    for (k, v) in fields {
        if !v.is_null() {
            t.push(vec![Cell::text(k), Cell::text(plain(v))]);
        }
    }
    let mut e = Table::new("episodes", "Episodes", &["episode", "score", "steps", "failed", "GIF"]);
    for ep in r["episodes"].as_array().into_iter().flatten() {
        let gif = plain(&ep["gif"]["file"]);
        let url = format!("/file/{}/{}", run.root, super::html::encode_path(&join(&run.rel, &gif)));
        e.push(vec![
            Cell::text(plain(&ep["episode"])),
            Cell::num(ep["score"].as_f64()),
            Cell::text(plain(&ep["steps"])),
            Cell::text(plain(&ep["failed"])),
            if ep["gif"].is_object() { Cell::link(gif, url) } else { Cell::text("—") },
        ]);
    }
    vec![t, e]
}

fn join(rel: &str, name: &str) -> String {
    if rel.is_empty() { name.to_string() } else { format!("{rel}/{name}") }
}

/// When the run last changed: the newest of its own files (links not followed), in seconds.
fn updated(run: &Run) -> Option<u64> {
    std::fs::read_dir(&run.dir)
        .ok()?
        .flatten()
        .filter_map(|e| e.path().symlink_metadata().ok()?.modified().ok())
        .max()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()
        .map(|d| d.as_secs())
}
