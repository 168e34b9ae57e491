//! Checks of a spec that need more than its fields' ranges: whether its datasets give every network
//! the rows it needs, and whether each network's `validation_fraction` holds out a row at all.
//! Run at validation, so a spec (or a preset, or a flag) that would fail at the first unit is
//! refused before a run directory exists, naming the field.

use super::{Preset, Spec};
use crate::dataset::{self, Role};
use crate::env::Env;
use crate::error::{Error, Result, ensure};
use crate::learn::LearnerConfig;
use crate::learn::actions::ActionEncoding;
use crate::learn::mlp::{MlpParams, split_rows};

/// Every check of this module on a spec whose fields are each in range.
pub(super) fn check(spec: &Spec) -> Result<()> {
    let env = spec.env.env();
    let horizon = env.horizon();
    for (name, p) in [("et", &spec.experiments.et), ("mlp", &spec.experiments.mlp)] {
        preset_holdout(p, horizon).map_err(|e| e.within(&format!("experiments.{name}")))?;
    }
    let s = &spec.search;
    holdout(&s.network, s.episodes, horizon, "episodes").map_err(|e| e.within("search.network"))?;
    let mut roles = vec![(Role::Search, s.datasets)];
    if let Some(v) = &s.validate {
        roles.push((Role::Validation, v.datasets));
    }
    // A gymnasium env's episodes come from its Python worker, which validation does not start
    // (and the built-in stepping this check uses has no such env), so it is not checked here.
    if matches!(spec.env, crate::env::EnvConfig::Gymnasium(_)) {
        return Ok(());
    }
    for (role, datasets) in roles {
        search_episodes(env, spec.seed, s.actions, &s.network, s.episodes, role, datasets)?;
    }
    Ok(())
}

/// A network fitted on datasets of up to `episodes` × `horizon` transitions must hold out a
/// validation row of the largest: a fraction too small for that (5e-324) would fail at the first
/// fit, after the run directory exists, as "bad data" naming no field. `of` names what sets the
/// size, for the message.
pub(crate) fn holdout(net: &MlpParams, episodes: usize, horizon: usize, of: &str) -> Result<()> {
    let most = episodes.saturating_mul(horizon);
    let f = net.validation_fraction;
    ensure(
        split_rows(most, f).1 >= 1,
        "validation_fraction",
        f,
        &format!("too small: it holds out no row of {most} transitions ({of} × horizon, the most a dataset has)"),
    )
}

/// [`holdout`] for a preset's network, at each dataset size it fits on: the iterations and
/// complexity analyses' `episodes`, and each size of its sample analysis.
fn preset_holdout(p: &Preset, horizon: usize) -> Result<()> {
    let LearnerConfig::Mlp(net) = &p.learner else { return Ok(()) };
    let within = |e: Error| e.within("learner");
    holdout(net, p.episodes, horizon, "episodes").map_err(within)?;
    for (i, &n) in p.samples.iter().flat_map(|s| s.sizes.iter()).enumerate() {
        holdout(net, n, horizon, &format!("samples.sizes[{i}]")).map_err(within)?;
    }
    Ok(())
}

/// Episodes collected at most to find how many a failing spec needs (far beyond any dataset whose
/// random policy takes each action now and then).
const SEARCH_CAP: usize = 100_000;

/// Each of `role`'s first `datasets` datasets of `episodes` episodes must give every network
/// (one per action with `per_action`) rows to train on and to validate on. Datasets of fewer
/// episodes are prefixes of larger ones, so each dataset is collected an episode at a time only
/// until it qualifies; for a count that is too small, the fewest that work are found the same way
/// and named as the allowed range.
fn search_episodes(
    env: &dyn Env,
    seed: u64,
    encoding: ActionEncoding,
    net: &MlpParams,
    episodes: usize,
    role: Role,
    datasets: usize,
) -> Result<()> {
    let models = match encoding {
        ActionEncoding::Input => 1,
        ActionEncoding::PerAction => env.actions().len(),
    };
    let enough = |rows: &[usize]| {
        rows.iter().all(|&r| matches!(split_rows(r, net.validation_fraction), (t, v) if t >= 1 && v >= 1))
    };
    // The dataset that needs the most episodes, and how many (None: more than the cap).
    let mut worst: Option<(usize, Option<usize>, Vec<usize>)> = None;
    for d in 0..datasets {
        let dseed = dataset::dataset_seed(seed, role, d);
        let mut rows = vec![0; models];
        let (mut e, mut at_episodes) = (0, None);
        let need = loop {
            if e > 0 && enough(&rows) {
                break Some(e);
            }
            if e == episodes {
                at_episodes = Some(rows.clone());
            }
            if e >= SEARCH_CAP.max(episodes) {
                break None;
            }
            let ep = dataset::episode(env, e, dseed);
            match encoding {
                ActionEncoding::Input => rows[0] += ep.len(),
                ActionEncoding::PerAction => {
                    for a in &ep.action {
                        // `check_for` has refused continuous actions with `per_action`.
                        if let Some(j) = env.actions().iter().position(|b| b == a) {
                            rows[j] += 1;
                        }
                    }
                }
            }
            e += 1;
        };
        if need.is_some_and(|n| n <= episodes) {
            continue;
        }
        // More than the cap counts as the most; no dataset can need more.
        let key = |n: Option<usize>| n.unwrap_or(usize::MAX);
        if worst.as_ref().is_none_or(|(_, w, _)| key(need) > key(*w)) {
            worst = Some((d, need, at_episodes.unwrap_or(rows)));
        }
        if need.is_none() {
            break;
        }
    }
    let Some((d, need, rows)) = worst else { return Ok(()) };
    let j = rows.iter().position(|&r| !enough(&[r])).unwrap_or(0);
    let (of, whose) = match encoding {
        ActionEncoding::Input => (String::new(), "the network"),
        ActionEncoding::PerAction => (format!(" of action {}", env.actions()[j]), "its network"),
    };
    let range =
        need.map_or(format!("must be larger (more than {SEARCH_CAP} are needed)"), |n| format!("must be ≥ {n}"));
    Err(Error::invalid(
        "search.episodes",
        episodes,
        format!(
            "{range}: with {episodes}, {} dataset {d} has {} transition(s){of}, too few for {whose} to train on \
             and hold out a validation row (validation_fraction {})",
            role.name(),
            rows[j],
            crate::error::short_number(net.validation_fraction.to_string())
        ),
    ))
}

impl Spec {
    /// When the epoch cap lies inside the patience genes' range: settings of a patience at or
    /// above the cap can never stop early, so what the search tunes of them means nothing.
    pub fn cap_inside_patience(&self) -> Option<String> {
        let (cap, g) = (self.search.network.max_epochs, &self.search.genes);
        let most = g.max_patience();
        (most >= cap).then(|| {
            format!(
                "search.network.max_epochs = {cap} lies inside the patience range of search.genes.a_patience {:?} and \
                 b_patience {:?} (up to {most}): a setting of patience ≥ {cap} never stops early, so its patience \
                 is not tuned; raise max_epochs above {most} or narrow the patience genes",
                g.a_patience, g.b_patience
            )
        })
    }
}
