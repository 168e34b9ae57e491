//! Tests of spec files: loading, presets, errors naming file and field, claims.

use super::*;
use crate::env::NAMES;

#[test]
fn shipped_specs_load_and_match_the_spec_table() {
    for name in NAMES {
        let (s, _) = Spec::resolve(name).unwrap();
        assert_eq!(s.env.env().name(), name);
    }
    let (b, _) = Spec::resolve("bicycle").unwrap();
    assert_eq!(b.experiments.et.iterations, 20);
    assert_eq!(b.experiments.et.learner.complexity(), Some(17));
    assert_eq!(b.experiments.mlp.iterations, 80);
    let (c, _) = Spec::resolve("cartpole").unwrap();
    assert_eq!(c.experiments.et.actions, ActionEncoding::PerAction);
    assert_eq!(c.experiments.et.iterations, 10);
}

#[test]
fn presets_overlay_the_spec() {
    let (mut v, origin) = Spec::resolve_value("cartpole").unwrap();
    let (patch, _) = load_preset("thesis-text-ranges").unwrap();
    merge_patch(&mut v, &patch);
    let s = Spec::from_value(v, &origin).unwrap();
    assert_eq!(s.search.genes.b_delta, [3, 15]);
    assert_eq!(s.search.genes.a_delta, [10, 99], "untouched fields keep their values");
    let (mut v, _) = Spec::resolve_value("cartpole").unwrap();
    merge_patch(&mut v, &load_preset("quick").unwrap().0);
    let s = Spec::from_value(v, &origin).unwrap();
    assert_eq!((s.search.ga.population, s.search.stop.generations, s.search.stop.stall_generations), (8, 2, None));
    assert!(load_preset("nonesuch").unwrap_err().to_string().contains("quick"));
}

#[test]
fn an_epoch_cap_inside_the_patience_range_is_named_and_quick_keeps_below_its_cap() {
    for name in NAMES {
        let (s, _) = Spec::resolve(name).unwrap();
        assert_eq!(s.search.genes.max_patience(), 991, "{name}: the thesis range");
        assert_eq!(s.cap_inside_patience(), None, "{name}: the thesis cap of 5000 lies above it");
        let (mut v, origin) = Spec::resolve_value(name).unwrap();
        merge_patch(&mut v, &load_preset("quick").unwrap().0);
        let q = Spec::from_value(v, &origin).unwrap();
        assert_eq!(q.cap_inside_patience(), None, "{name} --quick");
        assert!(q.search.genes.max_patience() < q.search.network.max_epochs, "{name}");
        assert_eq!(q.search.genes.a_delta, s.search.genes.a_delta, "only the patience range follows the cap");
    }
    let (mut v, origin) = Spec::resolve_value("cartpole").unwrap();
    v["search"]["network"]["max_epochs"] = 500.into();
    let w = Spec::from_value(v, &origin).unwrap().cap_inside_patience().unwrap();
    for needle in ["search.network.max_epochs = 500", "search.genes.a_patience [10, 99]", "b_patience [0, 2]", "991"] {
        assert!(w.contains(needle), "{w} (expected {needle})");
    }
}

#[test]
fn errors_name_file_and_field() {
    let origin = Path::new("my.json");
    let base = BUILTIN[2].1;
    let mut v = Spec::parse_value(base, origin).unwrap();
    v["experiments"]["et"]["learner"]["n_trees"] = serde_json::json!("many");
    let e = Spec::from_value(v.clone(), origin).unwrap_err().to_string();
    assert!(e.starts_with("my.json: field experiments.et.learner"), "{e}");
    v["experiments"]["et"]["learner"]["n_trees"] = serde_json::json!(0);
    let e = Spec::from_value(v.clone(), origin).unwrap_err().to_string();
    assert!(e.contains("experiments.et.learner.n_trees = 0"), "{e}");
    v["experiments"]["et"]["learner"]["n_trees"] = serde_json::json!(5);
    v["experiments"]["et"]["iteratons"] = serde_json::json!(5);
    let e = Spec::from_value(v, origin).unwrap_err().to_string();
    assert!(e.contains("iteratons"), "{e}");
    let e = Spec::parse("{ not json", origin).unwrap_err().to_string();
    assert!(e.starts_with("my.json: "), "{e}");
}

#[test]
fn claims_are_checked_with_their_path_and_do_not_change_the_results_hash() {
    let origin = Path::new("my.json");
    let base = Spec::parse_value(BUILTIN[0].1, origin).unwrap();
    let (spec, _) = Spec::resolve("pendulum").unwrap();
    assert_eq!(spec.experiments.mlp.claims.len(), 2, "complexity and sample claims");
    let claims = |v: &mut serde_json::Value| v["experiments"]["mlp"]["claims"].as_array_mut().unwrap().clone();
    let mut v = base.clone();
    let mut c = claims(&mut v);
    c[1]["share"] = serde_json::json!(1.5);
    v["experiments"]["mlp"]["claims"] = serde_json::json!(c);
    let e = Spec::from_value(v.clone(), origin).unwrap_err().to_string();
    assert!(e.contains("experiments.mlp.claims[1].share = 1.5") && e.contains("(0, 1]"), "{e}");
    c[1] = serde_json::json!({"rule": "mostly_worse", "share": 0.5, "statement": "x"});
    v["experiments"]["mlp"]["claims"] = serde_json::json!(c);
    let e = Spec::from_value(v.clone(), origin).unwrap_err().to_string();
    assert!(e.contains("mostly_worse") && e.contains("mostly_better"), "{e}");
    c[1] = serde_json::json!({"rule": "simpler_model", "steps": 5, "statement": "x"});
    v["experiments"]["mlp"]["claims"] = serde_json::json!(c);
    let e = Spec::from_value(v.clone(), origin).unwrap_err().to_string();
    assert!(e.contains("experiments.mlp.claims") && e.contains("steps"), "{e}");
    // Rewording or dropping a claim changes no number a search computes.
    let mut v = base.clone();
    v["experiments"]["et"]["claims"] = serde_json::json!([]);
    let other = Spec::from_value(v, origin).unwrap();
    assert_eq!(other.results_hash(), spec.results_hash());
    assert_ne!(other.hash(), spec.hash());
}

#[test]
fn the_units_hash_leaves_out_what_decides_which_units_run_and_keeps_what_they_compute() {
    let origin = Path::new("my.json");
    let base = Spec::parse_value(BUILTIN[0].1, origin).unwrap();
    let spec = Spec::from_value(base.clone(), origin).unwrap();
    let with = |path: &[&str], value: serde_json::Value| {
        let mut v = base.clone();
        let mut at = &mut v;
        for k in &path[..path.len() - 1] {
            at = &mut at[*k];
        }
        at[path[path.len() - 1]] = value;
        Spec::from_value(v, origin).unwrap()
    };
    // How settings are found and how many are validated: another run, the same units.
    for other in [
        with(&["search", "ga", "population"], 10.into()),
        with(&["search", "ga", "mutation"], 0.5.into()),
        with(&["search", "prune", "enabled"], true.into()),
        with(&["search", "race"], serde_json::json!({"test": "wilcoxon", "confidence": 0.95, "first": 5})),
        with(&["search", "validate"], serde_json::json!({"top": 3, "datasets": 20})),
        with(&["search", "validate"], serde_json::Value::Null),
        with(&["search", "genes", "a_delta"], serde_json::json!([20, 99])),
    ] {
        assert_eq!(other.units_hash(), spec.units_hash());
        assert_ne!(other.results_hash(), spec.results_hash(), "the run's identity still differs");
    }
    // What a unit computes: other numbers.
    for other in [
        with(&["seed"], 2.into()),
        with(&["search", "episodes"], 300.into()),
        with(&["search", "iterations"], 5.into()),
        with(&["search", "datasets"], 4.into()),
        with(&["search", "network", "hidden"], serde_json::json!([8, 8])),
        with(&["search", "network", "max_epochs"], 100.into()),
    ] {
        assert_ne!(other.units_hash(), spec.units_hash());
    }
}

#[test]
fn racing_is_checked_and_absent_from_the_thesis_specs() {
    let origin = Path::new("my.json");
    for (name, text) in BUILTIN {
        let v = Spec::parse_value(text, origin).unwrap();
        assert!(v["search"].get("race").is_none(), "{name}");
        // Absent, it is not written back: a thesis spec's resolved JSON and hashes are unchanged.
        let spec = Spec::from_value(v, origin).unwrap();
        assert!(serde_json::to_value(&spec).unwrap()["search"].get("race").is_none());
    }
    let base = Spec::parse_value(BUILTIN[1].1, origin).unwrap();
    let with = |race: serde_json::Value, prune: bool| {
        let mut v = base.clone();
        v["search"]["race"] = race;
        v["search"]["prune"]["enabled"] = prune.into();
        Spec::from_value(v, origin).map(|_| ()).map_err(|e| e.to_string())
    };
    assert!(with(serde_json::json!({"test": "t", "confidence": 0.9, "first": 2}), false).is_ok());
    for (race, prune, field) in [
        (serde_json::json!({"test": "wilcoxon", "confidence": 0.95, "first": 11}), false, "search.race.first"),
        (serde_json::json!({"test": "wilcoxon", "confidence": 1.5, "first": 5}), false, "search.race.confidence"),
        (serde_json::json!({"test": "wilcoxon", "confidence": 0.95, "first": 5}), true, "search.race"),
        (serde_json::json!({"test": "sign", "confidence": 0.95, "first": 5}), false, "search.race.test"),
    ] {
        let e = with(race, prune).unwrap_err();
        assert!(e.contains(field) && !e.contains('\n'), "{e}");
    }
}
