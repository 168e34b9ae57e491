//! The source layout's own rules (issue 19): no import cycle between the modules of `src/` (a file
//! is a module; a folder's `mod.rs` is the folder's module, which its children may use), and no
//! file much over 600 lines. Paths are read from `crate::…` and `super::…` uses outside tests.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The module path of a file: `ga::search` for src/ga/search.rs, `ga` for src/ga/mod.rs.
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|l| l == "mod") {
        parts.pop();
    }
    parts.join("::")
}

/// The code of a file without its test module and its comments.
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines().filter(|l| !l.trim_start().starts_with("//")).collect::<Vec<_>>().join("\n")
}

/// The paths a `use` tree names, expanded: `a::{b, c::{d, e}}` gives `a::b`, `a::c::d`, `a::c::e`.
fn expand(prefix: &str, s: &str, out: &mut Vec<String>) -> usize {
    let mut path = prefix.to_string();
    let mut i = 0;
    let b = s.as_bytes();
    while i < b.len() {
        let c = b[i] as char;
        if c.is_alphanumeric() || c == '_' || c == ':' {
            path.push(c);
            i += 1;
        } else if c == '{' {
            // A group: each comma-separated item continues the path so far.
            i += 1;
            loop {
                while i < b.len() && (b[i] as char).is_whitespace() {
                    i += 1;
                }
                i += expand(&path, &s[i..], out);
                // Past what follows an item (`as Name`) to the comma or the group's end.
                while i < b.len() && b[i] != b',' && b[i] != b'}' {
                    i += 1;
                }
                if i < b.len() && b[i] == b',' {
                    i += 1;
                    continue;
                }
                if i < b.len() && b[i] == b'}' {
                    i += 1;
                }
                return i;
            }
        } else {
            break;
        }
    }
    if !path.is_empty() {
        out.push(path);
    }
    i
}

/// The modules each module uses (itself, its ancestors and its descendants left out).
fn graph(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut list = Vec::new();
    files(src, &mut list);
    let modules: BTreeMap<String, PathBuf> = list
        .iter()
        .map(|f| (module_of(src, f), f.clone()))
        .filter(|(m, _)| !["lib", "main", "testkit"].contains(&m.as_str()))
        .collect();
    let resolve = |path: &str| -> Option<String> {
        let parts: Vec<&str> = path.split("::").filter(|p| !p.is_empty()).collect();
        (1..=parts.len()).rev().map(|i| parts[..i].join("::")).find(|c| modules.contains_key(c))
    };
    let mut deps: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, f) in &modules {
        let text = code(&std::fs::read_to_string(f).unwrap());
        // `super::` is the module above: `ga` for ga/search.rs, the crate root for ga/mod.rs.
        let mut parent: Vec<&str> = m.split("::").collect();
        parent.pop();
        let mut paths = Vec::new();
        for (key, base) in [("crate::", String::new()), ("super::", parent.join("::"))] {
            for (at, _) in text.match_indices(key) {
                if text[..at].ends_with('$') || text[..at].ends_with("::") {
                    continue; // `$crate::` in macros, or a longer path's tail
                }
                let start = if base.is_empty() { String::new() } else { format!("{base}::") };
                expand(&start, &text[at + key.len()..], &mut paths);
            }
        }
        let entry = deps.entry(m.clone()).or_default();
        for p in paths {
            if let Some(r) = resolve(&p) {
                let related = r == *m || m.starts_with(&format!("{r}::")) || r.starts_with(&format!("{m}::"));
                if !related {
                    entry.insert(r);
                }
            }
        }
    }
    deps
}

/// A cycle through `start`, if there is one.
fn cycle_through(deps: &BTreeMap<String, BTreeSet<String>>, start: &str) -> Option<Vec<String>> {
    let mut stack = vec![(start.to_string(), vec![start.to_string()])];
    let mut seen = BTreeSet::new();
    while let Some((m, path)) = stack.pop() {
        for d in deps.get(&m).into_iter().flatten() {
            if d == start {
                let mut p = path.clone();
                p.push(d.clone());
                return Some(p);
            }
            if seen.insert(d.clone()) {
                let mut p = path.clone();
                p.push(d.clone());
                stack.push((d.clone(), p));
            }
        }
    }
    None
}

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn no_module_imports_itself_through_others() {
    let deps = graph(&src());
    assert!(deps.len() > 50, "the scan found too few modules: {:?}", deps.keys());
    // The scan sees the layering it checks: the executors use only the run directory's layer.
    assert!(deps["exec"].contains("run_dir") && deps["exec::local"].contains("run_dir"), "{:?}", deps["exec"]);
    let cycles: Vec<String> = deps.keys().filter_map(|m| cycle_through(&deps, m)).map(|c| c.join(" → ")).collect();
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}

#[test]
fn the_scan_finds_a_cycle_when_there_is_one() {
    let mut out = Vec::new();
    expand("", "a::{b as x, c::{d, e}}, f", &mut out);
    assert_eq!(out, ["a::b", "a::c::d", "a::c::e"]);
    let mut deps = graph(&src());
    assert!(cycle_through(&deps, "exec").is_none());
    // exec using the GA's search (what the Slurm worker did) would close a loop.
    deps.get_mut("exec").unwrap().insert("ga::search".into());
    let c = cycle_through(&deps, "exec").expect("a cycle");
    assert_eq!(c.first(), c.last());
}

#[test]
fn executors_and_the_run_directory_layer_use_nothing_above_them() {
    let deps = graph(&src());
    let below = ["error", "store", "limits", "run_dir", "exec"];
    let top = |m: &str| m.split("::").next().unwrap_or("").to_string();
    let wrong: Vec<String> = deps
        .iter()
        .filter(|(m, _)| ["exec", "run_dir"].contains(&top(m).as_str()))
        .flat_map(|(m, ds)| ds.iter().filter(|d| !below.contains(&top(d).as_str())).map(move |d| format!("{m} → {d}")))
        .collect();
    assert!(wrong.is_empty(), "the executors' layer uses modules above it: {wrong:?}");
}

#[test]
fn no_source_file_is_much_over_600_lines() {
    let mut list = Vec::new();
    files(&src(), &mut list);
    let long: Vec<String> = list
        .iter()
        .map(|f| (f, std::fs::read_to_string(f).unwrap().lines().count()))
        .filter(|(_, n)| *n > 650)
        .map(|(f, n)| format!("{} ({n} lines)", f.display()))
        .collect();
    assert!(long.is_empty(), "files over 650 lines: {long:?}");
}
