//! `bfqi-ga export`: the committed cart-pole search and comparison as Parquet and CSV tables, read
//! back by the tool's own reader and, where a Python with pandas and pyarrow is available, by
//! pandas. Every export goes to a temporary directory: committed run directories stay untouched.

mod common;

use bfqi_ga::table::{self, Column, Table};
use common::{bin, empty_dir};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn committed(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("results/searches").join(name)
}

fn files(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .map(|d| d.flatten().filter(|e| e.path().extension().is_some_and(|x| x == "json")).count())
        .unwrap_or(0)
}

/// Runs `export` with `args`, asserting it succeeds.
fn export(args: &[&str]) -> String {
    let out = bin().arg("export").args(args).output().unwrap();
    assert!(out.status.success(), "export {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

fn strs<'a>(t: &'a Table, name: &str) -> &'a [Option<String>] {
    match t.column(name) {
        Some(Column::Str(v)) => v,
        other => panic!("column {name}: {other:?}"),
    }
}

fn ints<'a>(t: &'a Table, name: &str) -> &'a [Option<i64>] {
    match t.column(name) {
        Some(Column::Int(v)) => v,
        other => panic!("column {name}: {other:?}"),
    }
}

fn floats<'a>(t: &'a Table, name: &str) -> &'a [f64] {
    match t.column(name) {
        Some(Column::Float(v)) => v,
        other => panic!("column {name}: {other:?}"),
    }
}

/// The row of unit `setting` on search dataset `d`.
fn row(t: &Table, setting: &str, d: i64) -> usize {
    let (s, ds, role) = (strs(t, "setting"), ints(t, "dataset"), strs(t, "role"));
    (0..t.rows())
        .find(|&i| s[i].as_deref() == Some(setting) && ds[i] == Some(d) && role[i].as_deref() == Some("search"))
        .unwrap_or_else(|| panic!("no row for {setting} on dataset {d}"))
}

#[test]
fn the_committed_search_exports_one_row_per_unit_in_both_formats() {
    let run = committed("cartpole");
    let tmp = empty_dir("export", "search");
    let (pq, csv) = (tmp.join("u.parquet"), tmp.join("u.csv"));
    export(&[run.to_str().unwrap(), "--out", pq.to_str().unwrap()]);
    export(&[run.to_str().unwrap(), "--format", "csv", "--out", csv.to_str().unwrap()]);
    assert!(!run.join("units.parquet").exists() && !run.join("units.csv").exists(), "nothing written into the run");

    let units = files(&run.join("units")) + files(&run.join("validation"));
    let (p, c) = (table::read(&pq).unwrap(), table::read(&csv).unwrap());
    assert_eq!((p.rows(), c.rows()), (units, units));
    assert_eq!(p.names(), c.names());
    assert_eq!(
        strs(&p, "role").iter().filter(|r| r.as_deref() == Some("validation")).count(),
        files(&run.join("validation"))
    );

    // A known unit: its score as stored, its first asker as generations.jsonl says.
    let unit: Value = serde_json::from_str(&common::read(run.join("units/relu_1.2e-3_63.d0.json"))).unwrap();
    for t in [&p, &c] {
        let i = row(t, "relu_1.2e-3_63", 0);
        assert_eq!(floats(t, "score")[i], unit["score"].as_f64().unwrap());
        assert_eq!(ints(t, "epochs")[i], unit["epochs"].as_i64());
        assert_eq!(strs(t, "activation")[i].as_deref(), Some("relu"));
        assert_eq!(floats(t, "delta_min")[i], 0.0012);
        assert_eq!(ints(t, "patience")[i], Some(63));
        let seed = strs(t, "seed")[i].as_deref().unwrap();
        assert!(seed.starts_with("0x") && seed.len() == 18, "{seed}");
    }
    let i = row(&p, "tanh_6e-3_74", 3);
    assert_eq!((ints(&p, "generation")[i], ints(&p, "individual")[i]), (Some(0), Some(1)));
    assert_eq!(ints(&p, "gene_a_delta")[i], Some(60));
    assert_eq!(floats(&p, "score")[i], 184.99140766243124);
    // A search unit was asked for by a generation unless no individual had its setting (the
    // thesis optimum, scored beside the search); validation units by none.
    let generations = common::read(run.join("generations.jsonl"));
    let (role, generation, setting) = (strs(&p, "role"), ints(&p, "generation"), strs(&p, "setting"));
    for i in 0..p.rows() {
        let asked = generations.contains(&format!("\"setting\":\"{}\"", setting[i].as_deref().unwrap()));
        assert_eq!(generation[i].is_some(), asked && role[i].as_deref() == Some("search"), "row {i}");
    }
    // Both formats hold the same values.
    for name in ["score", "delta_min", "seconds"] {
        let same = floats(&p, name).iter().zip(floats(&c, name)).all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "column {name} differs between Parquet and CSV");
    }
    assert_eq!(strs(&p, "seed"), strs(&c, "seed"));
    assert_eq!(ints(&p, "generation"), ints(&c, "generation"));

    pandas_reads(&pq, &csv, &p);

    // A search without units yet: no rows, the same columns and types.
    let fresh = tmp.join("fresh");
    std::fs::create_dir_all(&fresh).unwrap();
    for f in ["spec.json", "run.json"] {
        std::fs::copy(run.join(f), fresh.join(f)).unwrap();
    }
    export(&[fresh.to_str().unwrap()]);
    let e = table::read(&fresh.join("units.parquet")).unwrap();
    assert_eq!((e.rows(), e.names()), (0, p.names()));
    let types = |t: &Table| t.columns().map(|(_, c)| c.type_name()).collect::<Vec<_>>();
    assert_eq!(types(&e), types(&p));
}

#[test]
fn the_committed_comparison_exports_one_row_per_unit() {
    let run = committed("cartpole-compare-mlp-complexity");
    let tmp = empty_dir("export", "compare");
    let out = export(&[run.to_str().unwrap(), "--format", "csv", "--out", "-"]);
    let csv = tmp.join("u.csv");
    std::fs::write(&csv, out).unwrap();
    let t = table::read(&csv).unwrap();
    assert_eq!(t.rows(), files(&run.join("units")));
    let unit: Value = serde_json::from_str(&common::read(run.join("units/mlp.bfqi.c1.n2000.d0.json"))).unwrap();
    let iterations = unit["iterations"].as_array().unwrap();
    let (alg, cx, d) = (strs(&t, "algorithm"), ints(&t, "complexity"), ints(&t, "dataset"));
    let i = (0..t.rows())
        .find(|&i| alg[i].as_deref() == Some("bfqi") && cx[i] == Some(1) && d[i] == Some(0))
        .expect("the unit's row");
    assert_eq!(floats(&t, "score")[i], iterations.last().unwrap()["score"].as_f64().unwrap());
    let epochs: i64 = iterations.iter().map(|it| it["epochs"].as_i64().unwrap()).sum();
    assert_eq!(ints(&t, "epochs")[i], Some(epochs));
    assert_eq!(strs(&t, "analysis")[i].as_deref(), Some("complexity"));
    assert_eq!(strs(&t, "learner")[i].as_deref(), Some("mlp"));
    assert_eq!(ints(&t, "episodes")[i], Some(2000));
}

#[test]
fn a_batch_concatenates_its_jobs_under_job_and_kind() {
    let tmp = empty_dir("export", "batch");
    let batch = tmp.join("batch");
    std::fs::create_dir_all(batch.join("jobs")).unwrap();
    // The committed runs as the batch's jobs (read only), and a job not started yet.
    std::os::unix::fs::symlink(committed("cartpole"), batch.join("jobs/s")).unwrap();
    std::os::unix::fs::symlink(committed("cartpole-compare-mlp-complexity"), batch.join("jobs/c")).unwrap();
    std::fs::write(batch.join("plan.json"), "{}").unwrap();
    let job = |name: &str, kind: &str, state: &str| {
        serde_json::json!({"name": name, "kind": kind, "state": state, "dir": format!("jobs/{name}"),
            "message": "", "seconds": 0.0, "result": ""})
    };
    let states = serde_json::json!([
        job("s", "search", "finished"),
        job("c", "compare", "finished"),
        job("p", "search", "pending")
    ]);
    std::fs::write(batch.join("batch.json"), states.to_string()).unwrap();
    let out = tmp.join("b.parquet");
    export(&[batch.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let t = table::read(&out).unwrap();
    let (search, compare) = (committed("cartpole"), committed("cartpole-compare-mlp-complexity"));
    let n_search = files(&search.join("units")) + files(&search.join("validation"));
    assert_eq!(t.rows(), n_search + files(&compare.join("units")));
    assert_eq!(&t.names()[..3], ["job", "kind", "run"]);
    let (jobs, kinds) = (strs(&t, "job"), strs(&t, "kind"));
    assert!(jobs[..n_search].iter().all(|j| j.as_deref() == Some("s")) && kinds[0].as_deref() == Some("search"));
    assert!(
        jobs[n_search..].iter().all(|j| j.as_deref() == Some("c")) && kinds[n_search].as_deref() == Some("compare")
    );
    // Columns of one kind only are missing in the other's rows.
    assert!(strs(&t, "analysis")[..n_search].iter().all(Option::is_none));
    assert!(strs(&t, "setting")[n_search..].iter().all(Option::is_none));
    assert!(!batch.join("units.parquet").exists());
}

#[test]
fn bad_destinations_and_directories_are_refused() {
    let run = committed("cartpole");
    let out = bin().args(["export", run.to_str().unwrap(), "--out", "-"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("add --format csv"));
    let tmp = empty_dir("export", "bad");
    let out = bin().args(["export", tmp.str()]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(tmp.str()) && err.contains("not a search, comparison or batch directory"), "{err}");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "nothing written");
}

/// A Python with pandas and pyarrow: `$BFQI_PYTHON`, else `python3`. `None`, with the reason
/// printed, where there is none; `BFQI_PANDAS_REQUIRED=1` (set by `.ci/run`) makes that a failure.
fn pandas_python() -> Option<String> {
    let py = std::env::var("BFQI_PYTHON").ok().filter(|p| !p.is_empty()).unwrap_or_else(|| "python3".into());
    let ok = Command::new(&py).args(["-c", "import pandas, pyarrow"]).output().is_ok_and(|o| o.status.success());
    if ok {
        return Some(py);
    }
    let why = format!("pandas check skipped: {py} cannot import pandas and pyarrow (set BFQI_PYTHON to one that can)");
    if std::env::var("BFQI_PANDAS_REQUIRED").as_deref() == Ok("1") {
        panic!("{why}, and BFQI_PANDAS_REQUIRED=1");
    }
    eprintln!("{why}");
    None
}

/// pandas reads both files to the tool's own values: shape, names, and every row's setting,
/// dataset, generation, seed and score (floats bit for bit).
fn pandas_reads(pq: &Path, csv: &Path, ours: &Table) {
    let Some(py) = pandas_python() else { return };
    let script = r#"
import json, math, sys
import pandas as pd
def plain(v):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    return v.item() if hasattr(v, "item") else v
out = {}
for name, df in (("parquet", pd.read_parquet(sys.argv[1])), ("csv", pd.read_csv(sys.argv[2]))):
    out[name] = {"columns": list(df.columns), "rows": len(df)}
    for c in ("setting", "dataset", "generation", "seed", "score"):
        out[name][c] = [plain(v) for v in df[c].tolist()]
print(json.dumps(out))
"#;
    let out = Command::new(&py).args(["-c", script]).arg(pq).arg(csv).output().unwrap();
    assert!(out.status.success(), "pandas: {}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    for format in ["parquet", "csv"] {
        let got = &v[format];
        assert_eq!(got["rows"].as_u64(), Some(ours.rows() as u64), "{format}");
        let names: Vec<&str> = got["columns"].as_array().unwrap().iter().map(|c| c.as_str().unwrap()).collect();
        assert_eq!(names, ours.names(), "{format}");
        for i in 0..ours.rows() {
            assert_eq!(got["setting"][i].as_str(), strs(ours, "setting")[i].as_deref(), "{format} row {i}");
            assert_eq!(got["seed"][i].as_str(), strs(ours, "seed")[i].as_deref(), "{format} row {i}");
            assert_eq!(got["dataset"][i].as_f64(), ints(ours, "dataset")[i].map(|x| x as f64), "{format} row {i}");
            assert_eq!(
                got["generation"][i].as_f64(),
                ints(ours, "generation")[i].map(|x| x as f64),
                "{format} row {i}"
            );
            let score = floats(ours, "score")[i];
            assert_eq!(got["score"][i].as_f64(), (!score.is_nan()).then_some(score), "{format} row {i}");
        }
    }
}

#[test]
fn a_reader_that_stops_early_ends_the_export_quietly() {
    // `bfqi-ga export RUN --format csv --out - | head -1`: the closed pipe is not an error.
    use std::io::{BufRead, BufReader};
    let run = committed("cartpole-compare-mlp-complexity");
    let mut child = bin()
        .args(["export", run.to_str().unwrap(), "--format", "csv", "--out", "-"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut header = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut header).unwrap();
    assert!(header.starts_with("run,"), "{header}");
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{:?}: {}", o.status, String::from_utf8_lossy(&o.stderr));
    assert!(o.stderr.is_empty(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A Parquet file pyarrow writes with page checksums: read; a flipped bit in a page is caught by
/// its checksum (the same flip without checksums reads back as another number).
#[test]
fn parquet_page_checksums_are_checked_on_read() {
    let Some(py) = pandas_python() else { return };
    let tmp = common::empty_dir("export", "crc");
    let write = |name: &str, crc: bool| {
        let p = tmp.join(name);
        let code = format!(
            "import pyarrow as pa, pyarrow.parquet as pq\n\
             pq.write_table(pa.table({{'x': [float(i) + 0.125 for i in range(1000)]}}), {:?}, compression='NONE', write_page_checksum={})",
            p.to_str().unwrap(),
            if crc { "True" } else { "False" }
        );
        let o = Command::new(&py).args(["-c", &code]).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        p
    };
    let flip = |p: &std::path::Path| {
        let mut bytes = std::fs::read(p).unwrap();
        let needle = 500.125f64.to_le_bytes();
        let at = bytes.windows(8).position(|w| w == needle).expect("the value's bytes in the page");
        bytes[at + 7] ^= 0x01;
        std::fs::write(p, bytes).unwrap();
    };
    let (with, without) = (write("crc.parquet", true), write("plain.parquet", false));
    assert_eq!(bfqi_ga::table::read(&with).unwrap().rows(), 1000);
    flip(&with);
    flip(&without);
    let e = bfqi_ga::table::read(&with).unwrap_err().to_string();
    assert!(e.contains("crc.parquet") && e.to_lowercase().contains("crc"), "{e}");
    let t = bfqi_ga::table::read(&without).unwrap();
    let Some(bfqi_ga::table::Column::Float(x)) = t.column("x") else { panic!() };
    assert_ne!(x[500], 500.125, "unchecked, the flip goes unseen");
}
