//! Any gymnasium env in one line (issue 48): `gymnasium:<id>` on the command line, or a spec file
//! that gives `env` and leaves out `seed`, `experiments` or `search`, is completed from the
//! committed template `searches/gymnasium/defaults.json`.
//!
//! Every default stays in that file: the template is the base, the few fields that depend on the
//! env (its horizon and evaluation length, a Box's actions, the tuned network's width) are set
//! from its probe by the template's `derive` rules, and the user's spec is merged over both, so
//! any field the user gives wins. A spec that gives all three is read as written, so the
//! committed gymnasium specs and their runs keep their hashes.
//!
//! Every user-given gymnasium spec is probed here, once, before anything is created: a recorded
//! `env.probed` that the env's worker does not confirm (copied from another env's spec) is
//! refused, naming the field, before a run directory exists.

use super::{file_error, merge_patch, strip_comments};
use crate::env::EnvConfig;
use crate::env::gymnasium::{Probed, Space};
use crate::error::{Error, Result};
use crate::store;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// What names a gymnasium env on the command line in place of a spec file: `gymnasium:<id>`.
pub const PREFIX: &str = "gymnasium:";

/// Where the template lives, relative to the working directory (else the built-in copy is used).
pub const TEMPLATE: &str = "searches/gymnasium/defaults.json";

const BUILTIN_TEMPLATE: &str = include_str!("../../searches/gymnasium/defaults.json");

/// The template's `derive` section: the constants of the rules that set env-derived fields.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Derive {
    /// The most steps a horizon taken from the env's time limit may have.
    horizon_max: usize,
    /// The most values a Box action space may have for its corners to be its actions (2^n).
    box_corner_values: usize,
}

/// The spec value `gymnasium:<id>` stands for (completed), with the origin errors name.
pub(super) fn from_name(name: &str) -> Option<Result<(Value, PathBuf)>> {
    let id = name.strip_prefix(PREFIX)?;
    let origin = PathBuf::from(name);
    if id.trim().is_empty() {
        return Some(Err(Error::invalid(
            "ENV",
            name,
            "must name a gymnasium env after gymnasium:, e.g. gymnasium:Acrobot-v1 or gymnasium:my_module:MyEnv-v0",
        )));
    }
    Some(complete(json!({"env": {"name": "gymnasium", "id": id}}), &origin).map(|v| (v, origin)))
}

/// The spec value `minari:<id>` stands for: the gymnasium env the dataset recorded, learning from
/// the dataset (`data.minari`), completed as `gymnasium:<id>` is, its datasets sized to the data.
pub(super) fn from_minari(name: &str) -> Option<Result<(Value, PathBuf)>> {
    let id = crate::dataset::minari::named(name)?;
    let origin = PathBuf::from(name);
    let (env, logged_episodes) = match crate::dataset::logged::minari_env(id) {
        Ok((Some(env), episodes)) => (env, episodes),
        Ok((None, _)) => {
            return Some(Err(Error::invalid(
                "ENV",
                name,
                "the dataset records no env spec to evaluate in: write a spec with env and \"data\": {\"minari\": …}",
            )));
        }
        Err(e) => return Some(Err(e)),
    };
    let mut e = json!({"name": "gymnasium", "id": env.id});
    if !env.kwargs.is_empty() {
        e["kwargs"] = Value::Object(env.kwargs);
    }
    if let Some(m) = env.max_episode_steps {
        e["max_episode_steps"] = json!(m);
    }
    let completed = complete(json!({"env": e, "data": {"minari": id}}), &origin);
    Some(completed.map(|mut v| {
        fit_to_data(&mut v, logged_episodes, &origin);
        (v, origin)
    }))
}

/// The episodes a built-in env's partial spec's logged data holds (`data.file` or `data.minari`,
/// dealt disjoint), read once; `None` for a bootstrap split, which any data size fits.
fn logged_episodes(v: &Value) -> Option<usize> {
    let source: crate::dataset::logged::DataSource = serde_json::from_value(v.get("data")?.clone()).ok()?;
    if source.split != crate::dataset::logged::Split::Disjoint || source.slots.is_some() {
        return None;
    }
    source.held_episodes(&crate::dataset::minari::python(None)).ok()
}

/// The fewest episodes per dataset [`fit_to_data`] deals before it asks fewer datasets.
pub const MIN_EPISODES_PER_DATASET: usize = 4;

/// Sizes a completed spec's datasets to a disjoint split of `episodes` logged episodes: every
/// dataset's episodes (search, presets, the sample analysis's sizes) at most ⌊episodes / slots⌋,
/// the slots being the spec's search, validation and comparison datasets. When that is fewer
/// than [`MIN_EPISODES_PER_DATASET`], fewer datasets are asked (each count scaled down, at least
/// one), so that small data still makes datasets of a few episodes. What it chose is said on
/// stderr, with a warning when it is little.
fn fit_to_data(v: &mut Value, episodes: usize, origin: &Path) {
    let n = |v: &Value, p: &str| v.pointer(p).and_then(Value::as_u64).unwrap_or(0) as usize;
    let counts = [
        "/search/datasets",
        "/search/validate/datasets",
        "/experiments/et/datasets",
        "/experiments/mlp/datasets",
        "/experiments/et/samples/datasets",
        "/experiments/mlp/samples/datasets",
    ];
    let slots = |v: &Value| {
        let compare = counts[2..].iter().map(|p| n(v, p)).max().unwrap_or(0);
        n(v, counts[0]) + n(v, counts[1]) + compare
    };
    let asked = slots(v);
    if asked == 0 || episodes == 0 {
        return;
    }
    if episodes / asked < MIN_EPISODES_PER_DATASET {
        let room = (episodes / MIN_EPISODES_PER_DATASET).max(1);
        for p in counts {
            if let Some(x) = v.pointer_mut(p)
                && let Some(c) = x.as_u64()
            {
                *x = json!(((c as usize * room) / asked).max(1));
            }
        }
        // The validation's top cannot exceed what it validates on; its top settings stay.
    }
    let slots = slots(v);
    let each = episodes / slots.max(1);
    let said = format!(
        "{}: the data holds {episodes} episodes: dealt to {} search, {} validation and {} comparison datasets of {} \
         episode(s) each{}",
        origin.display(),
        n(v, counts[0]),
        n(v, counts[1]),
        slots - n(v, counts[0]) - n(v, counts[1]),
        each.min(n(v, "/search/episodes").max(1)),
        if asked != slots {
            format!(" (the spec asks {asked} datasets: fewer, so each has a few episodes)")
        } else {
            String::new()
        }
    );
    crate::warn_once(&if each < 2 * MIN_EPISODES_PER_DATASET {
        format!("warning: {said}; that is little data: results will vary much from dataset to dataset")
    } else {
        format!("note: {said}")
    });
    if each == 0 {
        return;
    }
    for p in ["/search/episodes", "/experiments/et/episodes", "/experiments/mlp/episodes"] {
        if let Some(x) = v.pointer_mut(p)
            && x.as_u64().is_some_and(|e| e as usize > each)
        {
            *x = json!(each);
        }
    }
    for p in ["/experiments/et/samples/sizes", "/experiments/mlp/samples/sizes"] {
        if let Some(Value::Array(sizes)) = v.pointer_mut(p) {
            sizes.retain(|x| x.as_u64().is_some_and(|e| e as usize <= each));
            if sizes.is_empty() {
                sizes.push(json!(each));
            }
        }
    }
}

/// Completes a user's spec value whose env is a gymnasium env (anything else is returned as it
/// is): probes the env, refuses a stale `env.probed`, records the probe, and when `seed`,
/// `experiments` or `search` is left out, merges the spec over the template.
pub(super) fn complete(mut value: Value, origin: &Path) -> Result<Value> {
    let name = value.pointer("/env/name").and_then(Value::as_str).map(String::from);
    if let Some(builtin) = name.as_deref().filter(|n| crate::env::NAMES.contains(n)) {
        // A built-in env's partial spec (`{"env": {"name": "cartpole"}, "data": …}`) is completed
        // from that env's own spec, the user's fields merged over it.
        if ["seed", "experiments", "search"].iter().all(|k| value.get(k).is_some()) {
            return Ok(value);
        }
        let (mut base, _) = super::Spec::resolve_value(builtin)?;
        merge_patch(&mut base, &value);
        if let Some(episodes) = logged_episodes(&base) {
            fit_to_data(&mut base, episodes, origin);
        }
        return Ok(base);
    }
    if name.as_deref() != Some("gymnasium") {
        return Ok(value);
    }
    let probed = probe(&value, origin)?;
    value["env"]["probed"] = serde_json::to_value(&probed).expect("a probe serialises");
    if ["seed", "experiments", "search"].iter().all(|k| value.get(k).is_some()) {
        return Ok(value);
    }
    let (mut base, from) = template()?;
    let derive = base.as_object_mut().and_then(|m| m.remove("derive")).unwrap_or(Value::Null);
    let derive: Derive = crate::error::from_json(derive, &from, "derive: ")?;
    derived(&mut base, &probed, &derive, &from)?;
    merge_patch(&mut base, &value);
    Ok(base)
}

/// The env's spaces as its worker reports them now; a recorded `env.probed` must be the same.
fn probe(value: &Value, origin: &Path) -> Result<Probed> {
    #[derive(Serialize, Deserialize)]
    struct EnvOnly {
        env: EnvConfig,
    }
    let only = json!({"env": value["env"].clone()});
    let EnvOnly { env } = crate::error::from_json(only, origin, "")?;
    let EnvConfig::Gymnasium(mut g) = env else { unreachable!("env.name is gymnasium") };
    let recorded = g.probed.take();
    g.resolve().map_err(|e| file_error(origin, e.to_string()))?;
    let got = g.probed.clone().expect("resolve records the probe");
    if let Some(r) = &recorded {
        g.check_recorded(r, &got).map_err(|e| file_error(origin, e.within("env").to_string()))?;
    }
    Ok(got)
}

/// The template (comments removed): `searches/gymnasium/defaults.json` from the working
/// directory, or the copy built into the binary.
fn template() -> Result<(Value, PathBuf)> {
    let local = PathBuf::from(TEMPLATE);
    let (text, origin) = if store::something_at(&local) {
        (store::read_input(&local)?, local)
    } else {
        (BUILTIN_TEMPLATE.to_string(), PathBuf::from(format!("<built-in {TEMPLATE}>")))
    };
    let v = strip_comments(store::parse_json(&text, &origin)?);
    crate::error::expect_object(&v, &origin, "a spec template")?;
    Ok((v, origin))
}

/// Sets the env-derived fields of the template `base` from the probe, by `derive`'s rules.
fn derived(base: &mut Value, p: &Probed, derive: &Derive, from: &Path) -> Result<()> {
    let refuse = |field: &str, allowed: &str| file_error(from, format!("{field}: {allowed}"));
    let horizon = match p.max_episode_steps {
        Some(limit) => limit.min(derive.horizon_max),
        None => base.pointer("/env/horizon").and_then(Value::as_u64).map(|h| h as usize).ok_or_else(|| {
            refuse("env.horizon", "must be a whole number of steps (the horizon of an env with no time limit)")
        })?,
    };
    base["env"]["horizon"] = json!(horizon);
    base["env"]["eval"]["steps"] = json!(horizon);
    if let Some(actions) = box_actions(&p.action, derive.box_corner_values) {
        base["env"]["actions"] = actions;
    }
    let width = p.observation.dim();
    let hidden = base
        .pointer_mut("/search/network/hidden")
        .and_then(Value::as_array_mut)
        .ok_or_else(|| refuse("search.network.hidden", "must list the tuned network's hidden layer widths"))?;
    for layer in hidden.iter_mut() {
        if layer.as_u64().is_some_and(|w| (w as usize) < width) {
            *layer = json!(width);
        }
    }
    Ok(())
}

/// A bounded Box's corners (low and high of each value): numbers for a one-value Box, vectors
/// otherwise; `None` for a Discrete space (every action is used without listing them), an
/// unbounded Box or one of more than `most` values (validation then asks for `env.actions`).
fn box_actions(space: &Space, most: usize) -> Option<Value> {
    let Space::Box { low, high, .. } = space else { return None };
    let n = space.dim();
    if n == 0 || n > most || n != low.len() || n != high.len() {
        return None;
    }
    let bounds: Vec<(f64, f64)> = low.iter().zip(high).map(|(l, h)| Some(((*l)?, (*h)?))).collect::<Option<_>>()?;
    if n == 1 {
        let (l, h) = bounds[0];
        return Some(if l == h { json!([l]) } else { json!([l, h]) });
    }
    let mut corners: Vec<Vec<f64>> = Vec::new();
    for mask in 0..1usize << n {
        let c: Vec<f64> =
            bounds.iter().enumerate().map(|(j, (l, h))| if mask >> j & 1 == 1 { *h } else { *l }).collect();
        // A value with low == high gives each corner twice.
        if !corners.contains(&c) {
            corners.push(c);
        }
    }
    Some(json!(corners))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(low: &[Option<f64>], high: &[Option<f64>]) -> Space {
        Space::Box { shape: vec![low.len()], low: low.to_vec(), high: high.to_vec(), dtype: "float32".into() }
    }

    #[test]
    fn box_actions_are_its_corners_and_discrete_spaces_list_none() {
        assert_eq!(box_actions(&Space::Discrete { n: 3, start: 0 }, 10), None);
        assert_eq!(box_actions(&boxed(&[Some(-2.0)], &[Some(2.0)]), 10), Some(json!([-2.0, 2.0])));
        let two = box_actions(&boxed(&[Some(-1.0), Some(0.0)], &[Some(1.0), Some(0.5)]), 10).unwrap();
        assert_eq!(two, json!([[-1.0, 0.0], [1.0, 0.0], [-1.0, 0.5], [1.0, 0.5]]));
        // Equal bounds do not repeat a corner.
        let flat = box_actions(&boxed(&[Some(-1.0), Some(3.0)], &[Some(1.0), Some(3.0)]), 10).unwrap();
        assert_eq!(flat, json!([[-1.0, 3.0], [1.0, 3.0]]));
        // Unbounded, or too many values for 2^n corners: the user lists the actions.
        assert_eq!(box_actions(&boxed(&[None], &[Some(1.0)]), 10), None);
        assert_eq!(box_actions(&boxed(&[Some(0.0); 3], &[Some(1.0); 3]), 2), None);
    }

    fn probed(limit: Option<usize>, obs: usize) -> Probed {
        Probed {
            observation: boxed(&vec![None; obs], &vec![None; obs]),
            action: Space::Discrete { n: 3, start: 0 },
            max_episode_steps: limit,
            dt: None,
            rgb_array: false,
        }
    }

    #[test]
    fn horizon_and_eval_steps_follow_the_time_limit_and_networks_widen_to_the_observation() {
        let (template, from) = template().unwrap();
        let d = Derive { horizon_max: 1000, box_corner_values: 10 };
        let mut b = template.clone();
        derived(&mut b, &probed(Some(500), 6), &d, &from).unwrap();
        assert_eq!((b["env"]["horizon"].clone(), b["env"]["eval"]["steps"].clone()), (json!(500), json!(500)));
        assert_eq!(b["search"]["network"]["hidden"], json!([10, 10]));
        assert!(b["env"].get("actions").is_none());
        let mut b = template.clone();
        derived(&mut b, &probed(Some(100_000), 24), &d, &from).unwrap();
        assert_eq!(b["env"]["horizon"], json!(1000));
        assert_eq!(b["search"]["network"]["hidden"], json!([24, 24]));
        // No time limit: the template's own horizon.
        let mut b = template;
        let own = b["env"]["horizon"].clone();
        derived(&mut b, &probed(None, 4), &d, &from).unwrap();
        assert_eq!(b["env"]["horizon"], own);
    }

    #[test]
    fn the_template_states_no_thesis_claims_and_has_a_derive_section() {
        let (t, from) = template().unwrap();
        for l in ["et", "mlp"] {
            assert!(t["experiments"][l].get("claims").is_none(), "experiments.{l}.claims");
        }
        let _: Derive = crate::error::from_json(t["derive"].clone(), &from, "").unwrap();
    }

    #[test]
    fn an_empty_id_after_the_prefix_is_refused_naming_the_form() {
        let e = from_name("gymnasium: ").unwrap().unwrap_err().to_string();
        assert!(e.contains("gymnasium:Acrobot-v1"), "{e}");
        assert!(from_name("cartpole").is_none());
    }
}
