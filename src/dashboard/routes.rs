//! Requests to responses. Read-only: any method but GET/HEAD is refused; every path is resolved
//! through [`Roots`], which refuses what leaves the served directories.
//!
//! - `/` the runs; `/run/R/PATH` a run's page (`?setting=ID` a search's setting);
//!   `/compare-runs?a=R/PATH&b=R/PATH` two runs side by side;
//! - any page with `?csv=TABLE` gives that table as CSV, with `?json=1` its tables and chart data
//!   (what the script polls for live updates);
//! - `/file/R/PATH` a PNG or GIF inside a run; `/assets/…` the embedded script and style sheet.

use super::discover::{Kind, Refused, Roots, Run};
use super::html::{self, decode, escape};
use super::table::Table;
use serde_json::{Value, json};

/// A response: status, content type, body.
pub struct Reply {
    /// HTTP status.
    pub status: u16,
    /// Content type.
    pub content_type: &'static str,
    /// Body.
    pub body: Vec<u8>,
}

impl Reply {
    fn text(status: u16, content_type: &'static str, body: String) -> Reply {
        Reply { status, content_type, body: body.into_bytes() }
    }

    fn error(status: u16, why: &str) -> Reply {
        Reply::text(status, "text/plain; charset=utf-8", format!("{status} {why}\n"))
    }
}

/// What a page is made of before it is rendered as HTML, CSV or JSON.
struct Page {
    title: String,
    crumbs: Vec<(String, String)>,
    body: String,
    tables: Vec<Table>,
    charts: Value,
    /// What could not be read (files refused, lines skipped): shown, so that a gap is seen.
    notes: Vec<String>,
}

/// Answers one request (its method, and its target as sent).
pub fn handle(roots: &Roots, method: &str, url: &str) -> Reply {
    if method != "GET" && method != "HEAD" {
        return Reply::error(405, "read-only: only GET");
    }
    let (path, query) = url.split_once('?').unwrap_or((url, ""));
    let params: Vec<(String, String)> = query
        .split('&')
        .filter_map(|kv| {
            let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
            Some((decode(k, true)?, decode(v, true)?))
        })
        .collect();
    let param = |k: &str| params.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
    let Some(path) = decode(path, false) else { return Reply::error(400, "bad encoding") };
    match path.as_str() {
        "/assets/app.js" => return Reply::text(200, "text/javascript; charset=utf-8", html::APP_JS.into()),
        "/assets/style.css" => return Reply::text(200, "text/css; charset=utf-8", html::STYLE_CSS.into()),
        _ => {}
    }
    let page = if path == "/" {
        let (runs, notes) = super::runs::table(roots);
        Page {
            title: "Runs".into(),
            crumbs: vec![],
            // The script enables it once two runs are ticked.
            body: "<button id=\"compare-runs\" disabled>Tick two runs to see them side by side</button>".into(),
            tables: vec![runs],
            charts: Value::Null,
            notes,
        }
    } else if path == "/compare-runs" {
        match pair_page(roots, param("a"), param("b")) {
            Ok(p) => p,
            Err(r) => return r,
        }
    } else if let Some(rest) = path.strip_prefix("/file/") {
        return file(roots, rest);
    } else if let Some(rest) = path.strip_prefix("/run/") {
        match run_page(roots, rest, param("setting")) {
            Ok(p) => p,
            Err(r) => return r,
        }
    } else {
        return Reply::error(404, "no such page");
    };
    if let Some(name) = param("csv") {
        return match page.tables.iter().find(|t| t.name == name) {
            Some(t) => Reply::text(200, "text/csv; charset=utf-8", t.csv()),
            None => Reply::error(404, "no such table"),
        };
    }
    if param("json").is_some() {
        let body = json!({ "tables": page.tables, "charts": page.charts, "notes": page.notes });
        return Reply::text(200, "application/json", body.to_string());
    }
    let mut tables = notes_html(&page.notes);
    tables.extend(page.tables.iter().map(|t| t.html(url)));
    Reply::text(200, "text/html; charset=utf-8", html::page(&page.title, &page.crumbs, &page.body, &tables, url))
}

/// `R/PATH` → (root, path).
fn split_root(rest: &str) -> Option<(usize, &str)> {
    let (r, rel) = rest.split_once('/').unwrap_or((rest, ""));
    Some((r.parse().ok()?, rel.trim_end_matches('/')))
}

/// The run `R/PATH` names (as `/run/` and `/compare-runs` take it): `..` and `.` refused, and
/// anything that is not a run directory inside a served folder.
fn find_run(roots: &Roots, rest: &str) -> Result<Run, Reply> {
    let (root, rel) = split_root(rest).ok_or_else(|| Reply::error(404, "no such run"))?;
    if rel.split('/').any(|p| p == ".." || p == ".") {
        return Err(Reply::error(403, "outside the served directories"));
    }
    roots.run(root, rel).ok_or_else(|| Reply::error(404, "no such run"))
}

/// Two runs side by side.
fn pair_page(roots: &Roots, a: Option<&str>, b: Option<&str>) -> Result<Page, Reply> {
    let (Some(a), Some(b)) = (a, b) else {
        return Err(Reply::error(400, "two runs needed: /compare-runs?a=R/PATH&b=R/PATH"));
    };
    let (a, b) = (find_run(roots, a)?, find_run(roots, b)?);
    let crumbs = vec![(a.label(roots), a.url()), (b.label(roots), b.url())];
    let title = format!("{} and {} side by side", a.label(roots), b.label(roots));
    let (tables, charts) = super::pair::page(roots, &a, &b);
    let notes =
        [&a, &b].iter().flat_map(|r| r.notes().into_iter().map(|n| format!("{}: {n}", r.label(roots)))).collect();
    let body = "<section class=\"charts\"><div class=\"chart wide\" id=\"pair\"></div></section>".into();
    Ok(Page { title, crumbs, body, tables, charts, notes })
}

fn run_page(roots: &Roots, rest: &str, setting: Option<&str>) -> Result<Page, Reply> {
    let run = find_run(roots, rest)?;
    let label = run.label(roots);
    let crumbs = vec![(label.clone(), run.url())];
    let mut body = String::new();
    let (mut tables, charts) = match (run.kind, setting) {
        (Kind::Search, Some(id)) => {
            let (tables, charts) =
                super::search::setting_page(&run, id).ok_or_else(|| Reply::error(404, "no such setting"))?;
            body.push_str("<section class=\"charts\"><div class=\"chart wide\" id=\"losses\"></div></section>");
            let notes = run.notes();
            return Ok(Page { title: format!("Setting {id}"), crumbs, body, tables, charts, notes });
        }
        (_, Some(_)) => return Err(Reply::error(404, "only a search has settings")),
        (Kind::Search, None) => {
            body.push_str(
                "<section class=\"charts\"><div class=\"chart\" id=\"fitness\"></div>\
                 <div class=\"chart\" id=\"explorer\"></div></section>\
                 <section class=\"charts\"><div class=\"chart small\" id=\"gene-delta\"></div>\
                 <div class=\"chart small\" id=\"gene-patience\"></div><div class=\"chart small\" id=\"gene-activation\"></div></section>\
                 <section class=\"charts\"><div class=\"chart wide\" id=\"parallel\"></div>\
                 <div class=\"chart small\" id=\"importance\"></div></section>",
            );
            super::search::page(&run)
        }
        (Kind::Compare, None) => {
            body.push_str("<section class=\"charts\" id=\"curves\"></section>");
            let (t, c) = super::runs::comparison(&run);
            body.push_str(&gallery("Heatmaps and plots", &super::runs::images(&run, ".png")));
            body.push_str(&gallery("Rollouts", &super::runs::images(&run, ".gif")));
            (t, c)
        }
        (Kind::Batch, None) => (super::runs::batch(&run, roots), Value::Null),
        (Kind::Rollout, None) => {
            body.push_str(&gallery("States and actions", &super::runs::images(&run, ".png")));
            body.push_str(&gallery("Rollouts", &super::runs::images(&run, ".gif")));
            (super::runs::rollout(&run), Value::Null)
        }
    };
    if matches!(run.kind, Kind::Search | Kind::Compare | Kind::Batch) {
        tables.extend(super::runs::work(&run));
    }
    Ok(Page { title: format!("{} {label}", run.kind.name()), crumbs, body, tables, charts, notes: run.notes() })
}

/// The notes as a list above the tables (always there, so the script can fill it live).
fn notes_html(notes: &[String]) -> String {
    let items: String = notes.iter().map(|n| format!("<li>{}</li>", escape(n))).collect();
    format!(
        "<section id=\"notes\" class=\"notes\"{}><h2>Not shown</h2><ul>{items}</ul></section>",
        if notes.is_empty() { " hidden" } else { "" }
    )
}

fn gallery(title: &str, images: &[(String, String)]) -> String {
    if images.is_empty() {
        return String::new();
    }
    let mut h = format!("<section><h2>{}</h2><div class=\"gallery\">", escape(title));
    for (name, url) in images {
        h.push_str(&format!(
            "<figure><img loading=\"lazy\" src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
            escape(url),
            escape(name),
            escape(name)
        ));
    }
    h.push_str("</div></section>");
    h
}

/// A PNG or GIF inside a run directory (nothing else is served from the roots).
fn file(roots: &Roots, rest: &str) -> Reply {
    let Some((root, rel)) = split_root(rest) else { return Reply::error(404, "no such file") };
    if rel.split('/').any(|p| p == ".." || p == ".") {
        return Reply::error(403, "outside the served directories");
    }
    let content_type = if rel.ends_with(".png") {
        "image/png"
    } else if rel.ends_with(".gif") {
        "image/gif"
    } else {
        return Reply::error(403, "only PNG and GIF files are served");
    };
    match roots.read(root, rel) {
        Ok(body) => Reply { status: 200, content_type, body },
        Err(Refused::Missing) => Reply::error(404, "no such file"),
        Err(e) => Reply::error(403, &e.to_string()),
    }
}
