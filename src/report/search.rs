//! A search's report, rebuilt from what the run directory stores: `fitness.csv`, `fitness.png`,
//! `fitness.svg` and `report.md` come from `generations.jsonl`, `state.json`, `validation.json`
//! and the unit files, which are read to check the scores `generations.jsonl` records (a record
//! that disagrees with its unit is refused, naming both) and to count each generation's epochs.

use super::plot::FitnessRow;
use crate::error::{Error, Result};
use crate::ga::records::{GenerationRecord, Phase, RunState};
use crate::ga::setup::load_spec;
use crate::ga::units::{Evaluator, describe, unit_id};
use crate::ga::validate::{self, Validation};
use crate::progress::human;
use crate::spec::{Spec, Strategy};
use crate::stats::{Paired, Summary, interval};
use crate::store::{read_json, write_atomic};
use std::collections::HashSet;
use std::path::Path;

pub use crate::ga::records::read_generations;

/// `fitness.csv`, `fitness.png` and `fitness.svg`, with the thesis optimum's fitness as a reference
/// line once the validation has scored it.
pub fn write_fitness(dir: &Path, spec: &Spec, records: &[GenerationRecord]) -> Result<()> {
    let rows: Vec<FitnessRow> = records
        .iter()
        .map(|r| FitnessRow {
            generation: r.generation,
            best: r.stats.max,
            mean: r.stats.mean,
            best_so_far: r.best_so_far.fitness,
            min: r.stats.min,
        })
        .collect();
    let mut csv = String::from("generation,best,mean,best_so_far\n");
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:?}"));
    for r in &rows {
        csv.push_str(&format!("{},{},{},{}\n", r.generation, o(r.best), o(r.mean), o(r.best_so_far)));
    }
    write_atomic(&dir.join("fitness.csv"), |w| std::io::Write::write_all(w, csv.as_bytes()))?;
    let env = spec.env.env().name();
    let reference = validate::load(dir).and_then(|v| v.thesis_fitness(env));
    let title = match spec.search.strategy {
        Strategy::Ga => format!("GA fitness — {env}"),
        Strategy::Random => format!("Random-search fitness — {env}"),
    };
    super::plot::fitness(dir, &title, &rows, reference.map(|f| ("thesis optimum", f)))
}

/// What each generation cost: units no earlier generation had, and their epochs. Also checks every
/// recorded score against its unit file.
struct Cost {
    new_units: usize,
    epochs: usize,
}

fn costs(dir: &Path, spec: &Spec, records: &[GenerationRecord]) -> Result<Vec<Cost>> {
    let ev = Evaluator::new(spec.clone(), dir);
    let mut seen: HashSet<String> = HashSet::new();
    let mut out = Vec::with_capacity(records.len());
    for r in records {
        let mut cost = Cost { new_units: 0, epochs: 0 };
        for ind in &r.individuals {
            for (d, recorded) in ind.scores.iter().enumerate() {
                let id = unit_id(&ind.decoded, d);
                let refuse = |what: String| Error::File {
                    path: ev.unit_path(&id),
                    message: format!(
                        "{what}, but generations.jsonl scores generation {} individual {} with it: resume the \
                         search to compute it again",
                        r.generation, ind.index
                    ),
                };
                let unit = match ev.verified(&id) {
                    Ok(Some(u)) => u,
                    Ok(None) => return Err(refuse("missing".into())),
                    Err(problem) => return Err(refuse(problem)),
                };
                if unit.score.map(f64::to_bits) != recorded.map(f64::to_bits) {
                    // Scores as written in the files: the shortest round-trip form, or null (diverged).
                    let score = |v: Option<f64>| v.map_or("null (diverged)".to_string(), |x| format!("{x:?}"));
                    return Err(Error::File {
                        path: dir.join("generations.jsonl"),
                        message: format!(
                            "generation {} individual {} dataset {d} records score {}, but {} holds {}",
                            r.generation,
                            ind.index,
                            score(*recorded),
                            ev.unit_path(&id).display(),
                            score(unit.score)
                        ),
                    });
                }
                if seen.insert(id) {
                    cost.new_units += 1;
                    cost.epochs += unit.epochs;
                }
            }
        }
        out.push(cost);
    }
    Ok(out)
}

fn fmt(v: Option<f64>) -> String {
    v.map_or("−∞".into(), |x| format!("{x:.4}"))
}

/// How the search stands, in one sentence; `on` follows the wall time (the machines it ran on).
fn standing(st: Option<&RunState>, records: &[GenerationRecord], on: &str) -> String {
    let done = records.len();
    let gens = if done == 0 { "no generation".to_string() } else { format!("{done} generations (0–{})", done - 1) };
    match st {
        Some(st) => {
            let wall = format!("{}{on}", human(st.elapsed()));
            match st.state {
                Phase::Finished if st.reason == format!("{} generations", st.generations) => {
                    format!("Finished after {gens}, the spec's limit. Wall time {wall}.")
                }
                Phase::Finished => format!("Finished after {gens}: {}. Wall time {wall}.", st.reason),
                Phase::Interrupted if st.reason.ends_with("during the validation") => format!(
                    "Generations done after {gens}; stopped in the validation ({}); `bfqi-ga search --resume` finishes it. Wall time so far {wall}.",
                    st.reason.trim_end_matches(", during the validation")
                ),
                Phase::Interrupted => format!(
                    "Stopped after {gens} and {} of generation {done}'s units ({}); `bfqi-ga search --resume` continues it. Wall time so far {wall}.",
                    st.units_done, st.reason
                ),
                Phase::Running => format!("Running, after {gens}. Wall time so far {wall}."),
                Phase::Failed => format!("Failed after {gens}: {}. Wall time {wall}.", st.reason),
            }
        }
        None => format!("{gens}; no state.json."),
    }
}

/// Regenerates `fitness.csv`, `fitness.png`, `fitness.svg` and `report.md` of a search from its
/// stored records, after checking them against the unit files. Returns the number of generations.
pub fn write(dir: &Path) -> Result<usize> {
    let spec = load_spec(dir)?;
    let records = read_generations(dir)?;
    let costs = costs(dir, &spec, &records)?;
    let state: Option<RunState> = read_json(&dir.join("state.json")).ok();
    write_fitness(dir, &spec, &records)?;

    let s = &spec.search;
    let mut md = match s.strategy {
        Strategy::Ga => format!("# GA search — {}\n\n", spec.env.env().name()),
        Strategy::Random => format!(
            "# Random search — {}\n\n**Beyond the thesis: a random-search baseline** (`search.strategy: random`): every \
             generation is drawn uniformly from the gene ranges, generation 0 exactly as the GA's; no elites, \
             crossover or mutation.\n\n",
            spec.env.env().name()
        ),
    };
    md.push_str(&format!(
        "Population {}, {} search datasets × {} episodes, K = {}, network {:?}, master seed {}{}.\n\n",
        s.ga.population,
        s.datasets,
        s.episodes,
        s.iterations,
        s.network.hidden,
        spec.seed,
        if s.prune.enabled {
            format!("; **pruning on** (margin {}, after {} datasets)", s.prune.margin, s.prune.min_datasets)
        } else {
            String::new()
        }
    ));
    if let Some(d) = &spec.data {
        md.push_str(&format!("{}\n\n", d.describe()));
    }
    let on = crate::machine::wall_suffix(&crate::machine::of_run(dir));
    md.push_str(&standing(state.as_ref(), &records, &on));
    md.push('\n');
    if let Some(last) = records.last() {
        md.push_str(&format!(
            "Best: {}, fitness {} (generation {}).\n",
            describe(&last.best_so_far.decoded),
            fmt(last.best_so_far.fitness),
            last.best_generation
        ));
    }
    let pruning = s.prune.enabled;
    let (extra, extra_rule) = if pruning {
        (" | pruned", "---|")
    } else if s.race.is_some() {
        (" | raced out", "---|")
    } else {
        ("", "")
    };
    md.push_str(&format!(
        "\n| generation | new units | epochs | wall | best | mean | min | diverged{extra} | best so far | settings |\n|---|---|---|---|---|---|---|---|{extra_rule}---|---|\n"
    ));
    // A generation computed entirely by the run whose units this one took (`--units-from`) has no
    // wall time of its own: say so instead of "0 s".
    let info: Option<crate::ga::records::RunInfo> = read_json(&dir.join("run.json")).ok();
    let taken = info.as_ref().and_then(|i| i.units_from.first()).map(|u| u.dir.clone());
    let wall = |g: usize| match state.as_ref().and_then(|st| st.generation_seconds.get(g)) {
        Some(s) if *s < 0.5 && taken.is_some() && costs.get(g).is_some_and(|c| c.new_units > 0) => {
            format!("0 s (units taken from `{}`)", taken.as_deref().unwrap_or_default())
        }
        Some(s) => human(*s),
        None => "—".to_string(),
    };
    for (r, c) in records.iter().zip(&costs) {
        md.push_str(&format!(
            "| {} | {} | {:.2} M | {} | {} | {} | {} | {}{} | {} | {} |\n",
            r.generation,
            c.new_units,
            c.epochs as f64 / 1e6,
            wall(r.generation),
            fmt(r.stats.max),
            fmt(r.stats.mean),
            fmt(r.stats.min),
            r.stats.diverged,
            if pruning {
                format!(" | {}", r.stats.pruned)
            } else if s.race.is_some() {
                format!(" | {}", r.stats.raced)
            } else {
                String::new()
            },
            fmt(r.best_so_far.fitness),
            describe(&r.best_so_far.decoded)
        ));
    }
    md.push_str(
        "\n`new units`: FQI runs (setting × dataset) no earlier generation had; `epochs`: their \
         networks' epochs; `wall`: the generation's wall time, summed over invocations.\n",
    );
    md.push_str("\n![fitness per generation](fitness.png)\n");
    if let Some(rule) = &s.race {
        md.push_str(&racing(rule, &records));
    }
    if let Some(v) = validate::load(dir) {
        md.push_str(&v.markdown(spec.env.env().name()));
        md.push_str(&side_by_side(&v, spec.env.env().name()));
        md.push_str(&paired_differences(&v));
    }
    if s.strategy == Strategy::Random {
        let ga = super::baseline::ga_dir(dir).and_then(|g| read_generations(&g).ok().map(|r| (g, r)));
        md.push_str(&super::baseline::markdown(dir, &spec, &records, ga));
    }
    write_atomic(&dir.join("report.md"), |w| std::io::Write::write_all(w, md.as_bytes()))?;
    crate::work::write(dir)?;
    Ok(records.len())
}

/// The tuned config beside the thesis optimum, dataset by dataset, on the search and the
/// validation datasets.
/// The Racing section: the rule, then every raced individual's decision, generation by generation.
fn racing(rule: &crate::ga::racing::RaceRule, records: &[GenerationRecord]) -> String {
    let raced: usize = records.iter().map(|r| r.stats.raced).sum();
    let mut md = format!(
        "\n## Racing (beyond the thesis)\n\nEach new setting ran its datasets in index order against the \
         previous generation's elites and was stopped once a one-sided paired {} test put it below every \
         elite at {} % confidence, testing from dataset {} on (the test can stop a setting from dataset {}); \
         elites are never stopped. {raced} individuals were raced out.\n\n\
         | generation | individual | setting | decision |\n|---|---|---|---|\n",
        rule.test.name(),
        rule.confidence * 100.0,
        rule.first,
        rule.fewest()
    );
    for r in records {
        for i in r.individuals.iter() {
            if let Some(d) = &i.race {
                md.push_str(&format!(
                    "| {} | {} | {} | {} |\n",
                    r.generation,
                    i.index,
                    describe(&i.decoded),
                    d.describe()
                ));
            }
        }
    }
    md
}

pub(super) fn side_by_side(v: &Validation, env: &str) -> String {
    let Some(ours) = v.entries.iter().find(|e| e.setting == v.tuned) else { return String::new() };
    let Some(thesis) = v.thesis_entry(env) else { return String::new() };
    let n = ours.search_scores.len().max(ours.validation_scores.len());
    let mut md = String::from(
        "\n### GA optimum vs the thesis optimum, dataset by dataset\n\nScores per dataset; mean ± 95 % interval.\n\n",
    );
    md.push_str("| | datasets |");
    for d in 0..n {
        md.push_str(&format!(" {d} |"));
    }
    md.push_str(" mean ± 95 % |\n|---|---|");
    md.push_str(&"---|".repeat(n + 1));
    md.push('\n');
    let row = |who: &str, setting: &str, which: &str, scores: &[Option<f64>], summary: Option<Summary>| {
        let mut line = format!("| {who} `{setting}` | {which} |");
        for d in 0..n {
            let cell = match scores.get(d) {
                Some(Some(x)) => format!("{x:.3}"),
                Some(None) => "−∞".into(),
                None => String::new(),
            };
            line.push_str(&format!(" {cell} |"));
        }
        line.push_str(&format!(" {} |\n", interval(summary, 3)));
        line
    };
    for (which, pick) in [("search", true), ("validation", false)] {
        for (who, e) in [("GA optimum", ours), ("thesis optimum", thesis)] {
            let (scores, summary) =
                if pick { (&e.search_scores, e.search) } else { (&e.validation_scores, e.validation) };
            md.push_str(&row(who, &e.setting, which, scores, summary));
        }
    }
    md
}

/// The tuned config minus each other validated setting, paired by dataset, with t intervals, on
/// the search and on the validation datasets.
pub(super) fn paired_differences(v: &Validation) -> String {
    let Some(winner) = v.entries.iter().find(|e| e.setting == v.tuned) else { return String::new() };
    let mut md = format!(
        "\n### Paired differences\n\nThe tuned config `{}` minus each other setting, dataset by dataset, over the \
         datasets both scored: the mean difference ± the half-width of its {:.0} % interval, t·s/√n with s the \
         sample standard deviation of the differences and t Student's quantile with n − 1 degrees of freedom. \
         Positive: the tuned config scores higher; `indistinguishable`: the interval holds 0.\n\n",
        winner.setting,
        v.confidence() * 100.0
    );
    md.push_str(
        "| tuned config minus | setting | search datasets | n | validation datasets | n | on validation |\n|---|---|---|---|---|---|---|\n",
    );
    let cell = |p: Option<Paired>| p.map_or(("—".to_string(), "—".to_string()), |p| (p.show(3), p.n.to_string()));
    for e in v.entries.iter().filter(|e| e.setting != winner.setting) {
        let (s, sn) = cell(v.vs(winner, e, true));
        let on_validation = v.vs(winner, e, false);
        let (val, vn) = cell(on_validation);
        let verdict = match on_validation.map(|p| p.sign()) {
            Some(1) => "tuned config ahead",
            Some(-1) => "tuned config behind",
            Some(_) => "indistinguishable",
            None => "no interval (a diverged dataset)",
        };
        md.push_str(&format!("| {} | `{}` | {s} | {sn} | {val} | {vn} | {verdict} |\n", e.source, e.setting));
    }
    md
}
