//! Tuned configs and the policies they give: `reproduce`, `fitness`, `rollout`, `evaluate`.

use super::Outcome;
use crate::ga::fitness::TunedUnit;
use crate::limits::{EVAL_EPISODES, EVAL_STEPS};
use crate::rollout::Start;
use crate::spec::Spec;
use crate::tuned::TunedConfig;
use anyhow::{Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// `bfqi-ga reproduce`.
#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// A search's best.json.
    pub best: PathBuf,
    /// Leave its `validation` block unchecked (by default its validation scores are computed
    /// again too, which costs as many units as the validation had).
    #[arg(long)]
    pub skip_validation: bool,
}

/// `bfqi-ga fitness`.
#[derive(Debug, Args)]
pub struct FitnessArgs {
    /// Environment name (uses searches/<ENV>.json) or a spec file (e.g. a run directory's spec.json).
    pub env: String,
    /// The config to score: `thesis` (the thesis's GA optimum) or a best.json.
    #[arg(long, value_name = "thesis|FILE")]
    pub tuned: String,
    /// Print one JSON document instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// `bfqi-ga rollout`.
#[derive(Debug, Args)]
pub struct RolloutArgs {
    /// A model file (`run --save-model`), or with --tuned the environment name or spec file whose
    /// search fitness trains it (optional when the tuned config is a search's best.json).
    pub target: Option<String>,
    /// Train this config first (`thesis` or a best.json), as the search's unit on --dataset did.
    #[arg(long, value_name = "thesis|FILE")]
    pub tuned: Option<String>,
    /// With --tuned: the search dataset to train on.
    #[arg(long, default_value_t = 0, requires = "tuned")]
    pub dataset: usize,
    /// Episodes (default: the environment's evaluation episodes).
    #[arg(long)]
    pub episodes: Option<usize>,
    /// Where episodes start: the evaluation box, all zero, or the dataset box.
    #[arg(long, value_enum, default_value = "eval")]
    pub start: Start,
    /// Steps per episode (default: the evaluation protocol's).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Draw plots and a GIF for at most this many episodes (the CSV has them all).
    #[arg(long, default_value_t = 3)]
    pub draw: usize,
    /// Frames per GIF at most (long episodes show every n-th step).
    #[arg(long, default_value_t = 200)]
    pub frames: usize,
    /// Output directory (default: results/<env>/rollout-<timestamp>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// With --tuned: also save the trained Q-function to this file.
    #[arg(long, value_name = "FILE", requires = "tuned")]
    pub save_model: Option<PathBuf>,
}

/// `bfqi-ga evaluate`.
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// A model file (`run --save-model` or `rollout --save-model`).
    pub model: PathBuf,
    /// Episodes.
    #[arg(long, default_value_t = 100)]
    pub episodes: usize,
    /// Where episodes start: the evaluation box, all zero, or the dataset box (random bicycle
    /// headings, wide cart-pole starts).
    #[arg(long, value_enum, default_value = "random")]
    pub start: Start,
    /// Steps per episode (default: the evaluation protocol's).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Seed of the episodes' starts (and a gymnasium env's resets): fresh episodes, not the ones
    /// the model was scored on (default: the model's evaluation seed, those episodes).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Print one JSON document instead of the text.
    #[arg(long)]
    pub json: bool,
}

/// A fitness for people: `−∞ (diverged)` for a run that diverged.
fn show(v: Option<f64>) -> String {
    v.map_or("−∞ (diverged)".to_string(), |x| format!("{x:?}"))
}

pub(super) fn reproduce(a: ReproduceArgs) -> Result<Outcome> {
    let t = TunedConfig::load(&a.best)?;
    let r = crate::ga::search::reproduce(&t, &a.best, !a.skip_validation)?;
    let validation = match (r.validation_datasets, &t.validation) {
        (Some(n), _) => format!("; validation: {n} datasets re-derived"),
        (None, Some(_)) => "; validation: not checked (--skip-validation)".into(),
        (None, None) => String::new(),
    };
    if r.matches() {
        println!(
            "reproduced: fitness {} matches bit for bit ({} datasets){validation}",
            show(r.derived),
            t.scores.len()
        );
        return Ok(Outcome::Success);
    }
    println!("NOT reproduced: recorded fitness {}, derived {}", show(r.recorded), show(r.derived));
    for m in &r.mismatches {
        println!("  {m}");
    }
    for (d, rec, der) in &r.differences {
        println!("  dataset {d}: recorded {}, derived {}", show(*rec), show(*der));
    }
    for (d, rec, der) in &r.validation_differences {
        println!("  validation dataset {d}: recorded {}, derived {}", show(*rec), show(*der));
    }
    Ok(Outcome::Failed)
}

pub(super) fn fitness(a: FitnessArgs) -> Result<Outcome> {
    let (spec, spec_from) = Spec::resolve(&a.env)?;
    let (t, from) = TunedConfig::resolve(&a.tuned, spec.env.env().name())?;
    let r = crate::ga::fitness::score(&spec, &t, &from)?;
    let scores: Vec<Option<f64>> = r.units.iter().map(|u| u.score).collect();
    if a.json {
        let doc = serde_json::json!({
            "spec": spec_from.display().to_string(),
            "spec_hash": spec.hash(),
            "tuned": from.display().to_string(),
            "setting": r.setting,
            "scores": scores,
            "fitness": r.fitness,
            "notes": r.notes,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(Outcome::Success);
    }
    let s = &spec.search;
    println!(
        "{} ({}) under the fitness of {}: {} on {} search datasets, K={}, {} episodes each",
        from.display(),
        crate::ga::search::describe(&r.setting),
        spec_from.display(),
        s.algorithm.name(),
        s.datasets,
        s.iterations,
        s.episodes
    );
    for u in &r.units {
        let score = u.score.map_or("−∞ (diverged)".to_string(), |v| format!("{v:.4}"));
        println!("  dataset {:>2}: {score:>12}   {:>7} epochs", u.dataset, u.epochs);
    }
    let finite: Vec<f64> = scores.iter().flatten().copied().collect();
    let summary = crate::stats::summarize(&finite).filter(|_| r.fitness.is_some());
    println!(
        "fitness {}  (95 % interval over datasets; exact {})",
        crate::stats::interval(summary, 4),
        r.fitness.map_or("−∞".into(), |f| format!("{f:?}"))
    );
    if let Some(f) = t.fitness.filter(|_| t.spec.as_ref().is_some_and(|ts| ts.hash() == spec.hash())) {
        let same = r.fitness.map(f64::to_bits) == Some(f.to_bits());
        println!("recorded in {}: {f:?} ({})", from.display(), if same { "identical" } else { "DIFFERENT" });
    }
    for n in &r.notes {
        println!("note: {n}");
    }
    Ok(Outcome::Success)
}

pub(super) fn rollout(a: RolloutArgs) -> Result<Outcome> {
    anyhow::ensure!(a.frames >= 2, "invalid --frames = {}: must be ≥ 2", a.frames);
    let (model, label) = match &a.tuned {
        None => {
            let path = a.target.as_deref().context("give a model file, or --tuned thesis|FILE with an environment")?;
            (crate::model::load(Path::new(path))?, path.to_string())
        }
        Some(tuned) => {
            let unit = TunedUnit::resolve(a.target.as_deref(), tuned)?;
            eprintln!("{}", unit.describe(a.dataset));
            let m = unit.train(a.dataset, a.save_model.as_deref())?;
            if let Some(p) = &a.save_model {
                eprintln!("saved the Q-function to {}", p.display());
            }
            (m, format!("{} trained on search dataset {}", unit.from.display(), a.dataset))
        }
    };
    let protocol = model.info.env.env().eval();
    let req = crate::report::policy::Request {
        episodes: a.episodes.unwrap_or(protocol.episodes),
        start: a.start,
        steps: a.steps.unwrap_or(protocol.steps),
        draw: a.draw,
        frames: a.frames,
    };
    let (me, ms) = (EVAL_EPISODES, EVAL_STEPS);
    anyhow::ensure!((1..=me).contains(&req.episodes), "invalid --episodes = {}: must be in 1..={me}", req.episodes);
    // Every step of every episode is kept in memory for the CSV.
    anyhow::ensure!(
        req.steps >= 1 && req.steps.saturating_mul(req.episodes) <= ms,
        "invalid --steps = {}: must be ≥ 1, with steps × episodes ≤ {ms}",
        req.steps
    );
    let dir = match &a.out {
        Some(d) => d.clone(),
        None => crate::store::new_run_dir(&Path::new("results").join(model.info.env.env().name()), "rollout-")?,
    };
    let s = crate::report::policy::write(&dir, &model, &label, &req)?;
    println!("{}", crate::rollout::describe_model(&model.info, Path::new(&label)));
    for e in &s.episodes {
        let gif = e
            .gif
            .as_ref()
            .map_or(String::new(), |g| format!("  {} ({} frames, {} KiB)", g.file, g.frames, g.bytes / 1024));
        println!(
            "  episode {:>3}: score {:>10.4}  {:>5} steps{}{gif}",
            e.episode,
            e.score,
            e.steps,
            if e.failed { "  failed" } else { "" }
        );
    }
    if a.start == Start::Eval && req.steps == protocol.steps && req.episodes >= protocol.episodes {
        // The first protocol.episodes episodes are the ones the run was scored on.
        let mean = s.episodes[..protocol.episodes].iter().map(|e| e.score).sum::<f64>() / protocol.episodes as f64;
        if let Some(rec) = model.info.score {
            let same = mean.to_bits() == rec.to_bits();
            println!(
                "evaluation episodes: {mean:?}, recorded {rec:?} ({})",
                if same { "identical" } else { "DIFFERENT" }
            );
        }
    }
    println!("wrote {}", dir.display());
    Ok(Outcome::Success)
}

pub(super) fn evaluate(a: EvaluateArgs) -> Result<Outcome> {
    let (me, ms) = (EVAL_EPISODES, EVAL_STEPS);
    anyhow::ensure!((1..=me).contains(&a.episodes), "invalid --episodes = {}: must be in 1..={me}", a.episodes);
    let m = crate::model::load(&a.model)?;
    let steps = a.steps.unwrap_or(m.info.env.env().eval().steps);
    anyhow::ensure!((1..=ms).contains(&steps), "invalid --steps = {steps}: must be in 1..={ms}");
    let q = |o: &[f64], q: &mut [f64]| m.q(o, q);
    // The episodes' streams are seeded by this seed as an evaluation's are by its seed E.
    let seed = a.seed.unwrap_or(m.info.eval_seed);
    let eps = crate::rollout::run(&m.info.env, &q, seed, a.episodes, a.start, steps, false, None)?;
    let eps: Vec<crate::eval::Episode> = eps.into_iter().map(|(e, _)| e).collect();
    let r = crate::rollout::robustness(a.start, &eps).expect("at least one episode");
    if a.json {
        let doc = serde_json::json!({ "model": a.model.display().to_string(), "info": m.info, "seed": seed, "steps": steps, "result": r });
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(Outcome::Success);
    }
    println!("{}", crate::rollout::describe_model(&m.info, &a.model));
    let episodes =
        if seed == m.info.eval_seed { "its evaluation's episodes".to_string() } else { format!("seed {seed}") };
    println!(
        "{} episodes from {} starts ({episodes}), ≤ {steps} steps: score {}, steps {}, failures {}/{}",
        r.episodes,
        serde_json::to_value(a.start)?.as_str().unwrap_or("?"),
        crate::stats::interval(Some(r.score), 4),
        crate::stats::interval(Some(r.steps), 1),
        r.failures,
        r.episodes
    );
    Ok(Outcome::Success)
}
