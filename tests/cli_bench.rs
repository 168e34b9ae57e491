//! `bfqi-ga bench search --json` on a tiny spec: the fields the README documents are there and
//! consistent (the figures themselves are timings, never asserted).

mod common;
use common::{bin, empty_dir, json};

use serde_json::Value;

#[test]
fn bench_search_json_has_the_documented_fields() {
    let dir = empty_dir("bench", "tiny");
    let mut spec: Value = json("searches/cartpole.json");
    spec["search"]["episodes"] = 30.into();
    spec["search"]["iterations"] = 2.into();
    spec["search"]["datasets"] = 3.into();
    spec["search"]["ga"]["population"] = 4.into();
    spec["search"]["network"]["max_epochs"] = 40.into();
    let path = dir.join("tiny.json");
    std::fs::write(&path, serde_json::to_string(&spec).unwrap()).unwrap();
    let out = bin()
        .args(["--jobs", "2", "bench", "search", "--json", "--cap-seconds", "0.5", "--env"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["peak_gflops_per_core"].as_f64().unwrap() > 0.0);
    assert_eq!(v["threads"], 2);
    let e = &v["envs"][0];
    assert_eq!(e["env"], "cartpole");
    assert_eq!(
        (e["population"].as_u64(), e["datasets"].as_u64(), e["iterations"].as_u64()),
        (Some(4), Some(3), Some(2))
    );
    assert_eq!(e["networks_per_iteration"], 2, "per-action cart-pole");
    assert_eq!(e["widths"], serde_json::json!([4, 10, 10, 1]));
    let shapes = e["shapes"].as_array().unwrap();
    assert_eq!(shapes.len(), 3);
    for s in shapes {
        for f in ["ms_per_epoch", "gflops", "percent_of_peak", "percent_of_peak_matmul", "bound_ms_per_epoch"] {
            assert!(s[f].as_f64().unwrap() > 0.0, "shape field {f}: {s}");
        }
        let w = &s["work"];
        assert!(w["matmul_flops"].as_f64().unwrap() > 0.0 && w["activation_flops"].as_f64().unwrap() > 0.0);
    }
    let units = e["units"].as_array().unwrap();
    let roles: Vec<&str> = units.iter().map(|u| u["role"].as_str().unwrap()).collect();
    assert_eq!(roles, ["thesis optimum", "fast", "slow"]);
    assert_eq!(units[0]["setting"], "sigmoid_5.8e-1_601");
    for u in units {
        for f in ["seconds", "projected_seconds", "ms_per_epoch", "gflops", "percent_of_peak"] {
            assert!(u[f].as_f64().unwrap() > 0.0, "unit field {f}: {u}");
        }
        assert!(u["epochs"].as_u64().unwrap() > 0);
        let (run, k) = (u["iterations_run"].as_u64().unwrap(), u["iterations"].as_u64().unwrap());
        assert_eq!(u["capped"].as_bool().unwrap(), run < k);
        assert_eq!(u["score"].is_null(), run < k, "a score only for a whole unit");
    }
    let a = &e["unit_across_cores"];
    assert_eq!(a["threads"], 2);
    assert_eq!(a["identical"], true, "one unit on 1 and 2 threads: same results");
    let p = &e["projection"];
    assert_eq!(p["population"], 4);
    let n = p["distinct_settings"].as_u64().unwrap();
    assert_eq!(p["units_per_generation"].as_u64().unwrap(), n * 3);
    assert_eq!(p["units"].as_array().unwrap().len() as u64, n);
    let (generation, slowest) = (p["generation_s"].as_f64().unwrap(), p["slowest_unit_s"].as_f64().unwrap());
    assert!(generation >= slowest && slowest > 0.0);
    assert_eq!(p["cluster_generation_s"].as_f64().unwrap(), slowest);
    let all = p["search_s_all_like_first"].as_f64().unwrap();
    assert!((all - generation * e["generations"].as_f64().unwrap()).abs() < 1e-6 * all);
    assert!(p["search_s_elites_reused"].as_f64().unwrap() <= all);
    assert!(e["keras"].is_null(), "no --python, no reference");
}

#[test]
fn bench_search_isa_all_times_every_level_against_its_own_peak() {
    let dir = empty_dir("bench", "levels");
    let mut spec: Value = json("searches/cartpole.json");
    spec["search"]["episodes"] = 30.into();
    let path = dir.join("tiny.json");
    std::fs::write(&path, serde_json::to_string(&spec).unwrap()).unwrap();
    let out = bin().args(["bench", "search", "--json", "--isa", "all", "--env"]).arg(&path).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let levels: Vec<&str> = v["levels"].as_array().unwrap().iter().map(|l| l.as_str().unwrap()).collect();
    // Every CPU runs the portable level, last; the best level the CPU has comes first.
    assert_eq!(levels.last(), Some(&"portable"), "{levels:?}");
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        assert!(levels.contains(&"avx2"), "{levels:?}");
    }
    let per_level = v["envs"][0]["levels"].as_array().unwrap();
    assert_eq!(per_level.len(), levels.len());
    for (l, name) in per_level.iter().zip(&levels) {
        assert_eq!(l["level"], *name);
        assert!(l["peak_gflops_per_core"].as_f64().unwrap() > 0.0);
        let shapes = l["shapes"].as_array().unwrap();
        let acts: Vec<&str> = shapes.iter().map(|s| s["activation"].as_str().unwrap()).collect();
        assert_eq!(acts, ["sigmoid", "tanh", "relu"]);
        for s in shapes {
            // Each level's bound is computed from its own peak.
            let peak = l["peak_gflops_per_core"].as_f64().unwrap();
            let ms = s["ms_per_epoch"].as_f64().unwrap();
            let pct = s["percent_of_peak"].as_f64().unwrap();
            let flops = s["work"]["matmul_flops"].as_f64().unwrap() + s["work"]["activation_flops"].as_f64().unwrap();
            assert!((pct - 100.0 * flops / (ms / 1e3) / 1e9 / peak).abs() < 1e-6 * pct.max(1.0), "{s}");
        }
    }

    // A level this CPU does not run is refused, naming the flag and what it runs.
    let out = bin().args(["bench", "search", "--isa", "portable,sse9", "--env"]).arg(&path).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("invalid --isa = sse9") && err.contains("portable"), "{err}");
}
