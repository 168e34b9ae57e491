//! Whether an environment's constants give dynamics a run can learn from: every constant can be
//! finite and positive and the dynamics still overflow (`tau` 1e308), or reach states no learner
//! takes (`l` 1e200 gives observations of 1e198; Extra-Trees holds inputs as f32). A few short
//! random-policy episodes, from the dataset's and the evaluation's start boxes, find it at
//! validation: a one-line refusal naming the constant, instead of a "non-finite target" or "bad
//! data" naming nothing hours into a search.

use super::{EnvConfig, MAX_STATE, draw_box};
use crate::error::{Error, Result, short_number};

/// The largest magnitude a learner takes as input or target: Extra-Trees stores its inputs as f32.
pub const LEARNER_MAX: f64 = f32::MAX as f64;

/// Steps of each check episode at most.
const STEPS: usize = 100;

/// What went wrong in a check episode.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    /// A state or reward became NaN or infinite.
    Overflow,
    /// An observation, reward or action grew past [`LEARNER_MAX`]; the largest seen.
    TooLarge(f64),
}

/// Runs the check episodes; the first fault found.
fn fault(cfg: &EnvConfig) -> Option<Fault> {
    let env = cfg.env();
    let (sd, od) = (env.state_dim(), env.obs_dim());
    // Episodes 0–2 from the dataset's start box (as before the evaluation's were added), 3–5 from
    // the evaluation's.
    for e in 0..6u64 {
        let mut rng = crate::rng::stream(0, crate::rng::purpose::ENV_CHECK, &[e]);
        let (mut s, mut next, mut obs) = ([0.0; MAX_STATE], [0.0; MAX_STATE], [0.0; MAX_STATE]);
        if e < 3 {
            env.dataset_start(&mut rng, &mut s[..sd]);
        } else {
            draw_box(&env.eval().start, &mut rng, &mut s[..sd]);
        }
        for _ in 0..env.horizon().min(STEPS) {
            let a = env.dataset_action(&mut rng);
            let o = env.step(&s[..sd], a, &mut rng, &mut next[..sd]);
            if !o.reward.is_finite() || next[..sd].iter().any(|v| !v.is_finite()) {
                return Some(Fault::Overflow);
            }
            env.observe(&next[..sd], &mut obs[..od]);
            let most = obs[..od].iter().chain([&o.reward, &a]).fold(0.0f64, |m, v| m.max(v.abs()));
            if !most.is_finite() {
                return Some(Fault::Overflow);
            }
            if most > LEARNER_MAX {
                return Some(Fault::TooLarge(most));
            }
            if o.failed {
                break;
            }
            s = next;
        }
    }
    None
}

/// The environment's name as the thesis writes it.
fn title(cfg: &EnvConfig) -> &'static str {
    match cfg {
        EnvConfig::Pendulum(_) => "pendulum",
        EnvConfig::Cartpole(_) => "cart-pole",
        EnvConfig::Bicycle(_) => "bicycle",
        // Never checked here: a gymnasium env's dynamics are its worker's (see `EnvConfig::validate`).
        EnvConfig::Gymnasium(_) => "gymnasium",
    }
}

/// Refuses settings whose dynamics overflow or outgrow the learners within [`STEPS`] random steps,
/// naming the constant: each field that differs from the environment's defaults is tried alone
/// against the defaults, and the first that faults by itself is the one named.
pub(super) fn dynamics(cfg: &EnvConfig) -> Result<()> {
    let Some(f) = fault(cfg) else { return Ok(()) };
    let within = format!("within {STEPS} random steps from the dataset or evaluation starts");
    let what = match f {
        Fault::Overflow => {
            format!("makes the {} dynamics overflow to non-finite states or rewards {within}", title(cfg))
        }
        Fault::TooLarge(v) => format!(
            "makes the {} dynamics reach {v:.2e} in an observation, reward or action {within}, beyond the \
             ±{LEARNER_MAX:.1e} the learners take",
            title(cfg)
        ),
    };
    let changed = changed_fields(cfg);
    let defaults = EnvConfig::by_name(cfg.env().name()).ok().and_then(|d| serde_json::to_value(d).ok());
    for (key, value) in &changed {
        let Some(mut trial) = defaults.clone() else { break };
        trial[key.as_str()] = value.clone();
        let Ok(alone) = serde_json::from_value::<EnvConfig>(trial) else { continue };
        if fault(&alone).is_some() {
            let default = defaults.as_ref().map_or(String::new(), |d| written(&d[key.as_str()]));
            return Err(Error::invalid(
                format!("env.{key}"),
                written(value),
                format!("{what} (the default is {default}); bring it back to a physical range"),
            ));
        }
    }
    let names: Vec<String> = changed.iter().map(|(k, _)| format!("env.{k}")).collect();
    let which = if names.is_empty() { "its constants".to_string() } else { names.join(", ") };
    Err(Error::invalid(
        "env",
        format!("{} settings", cfg.env().name()),
        format!("{which} together {what}; bring them back to a physical range"),
    ))
}

/// A field's value as a person writes it: `1e308` and `10`, not `1e+308` and `10.0`.
fn written(v: &serde_json::Value) -> String {
    match v.as_f64() {
        Some(x) if v.is_number() => short_number(x.to_string()),
        _ => v.to_string(),
    }
}

/// The fields of `cfg` that differ from its environment's defaults, in the file's order.
fn changed_fields(cfg: &EnvConfig) -> Vec<(String, serde_json::Value)> {
    let (Ok(serde_json::Value::Object(mine)), Ok(Some(serde_json::Value::Object(defaults)))) =
        (serde_json::to_value(cfg), EnvConfig::by_name(cfg.env().name()).map(|d| serde_json::to_value(d).ok()))
    else {
        return Vec::new();
    };
    mine.into_iter().filter(|(k, v)| k != "name" && defaults.get(k) != Some(v)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::CartPoleConfig;

    #[test]
    fn the_constant_at_fault_is_named_among_others_changed() {
        let c = CartPoleConfig { force: 1e308, g: 9.81, ..Default::default() };
        let e = EnvConfig::Cartpole(c).validate().unwrap_err().to_string();
        assert!(e.starts_with("invalid env.force = 1e308: makes the cart-pole dynamics reach"), "{e}");
        let c = CartPoleConfig { tau: 1e308, ..Default::default() };
        let e = EnvConfig::Cartpole(c).validate().unwrap_err().to_string();
        assert!(e.starts_with("invalid env.tau = 1e308: makes the cart-pole dynamics overflow"), "{e}");
        let c = CartPoleConfig { l: 1e200, ..Default::default() };
        let e = EnvConfig::Cartpole(c).validate().unwrap_err().to_string();
        assert!(e.contains("invalid env.l = 1e200") && e.contains("beyond the ±3.4e38"), "{e}");
        for name in crate::env::NAMES {
            assert_eq!(fault(&EnvConfig::by_name(name).unwrap()), None, "{name}'s defaults");
        }
    }
}
