//! A search's pages, read from `generations.jsonl`, `state.json`, `hall_of_fame.json` and
//! `validation.json` (never its units), and a setting's page, read from that setting's units only.

use super::discover::Run;
use super::html::encode;
use super::table::{Cell, Table, num};
use crate::ga::records::{GenerationRecord, Phase, RunState};
use crate::ga::units::{UnitResult, activation_name, describe, parse_setting_id, unit_id};
use crate::ga::validate::Validation;
use crate::progress::human;
use serde_json::{Value, json};
use std::collections::BTreeMap;

/// The generations recorded so far. A line without its newline is one being appended: skipped
/// while the search runs. Any other line that does not parse (invalid UTF-8, a damaged record) is
/// skipped and noted on the page, so a history with gaps never looks whole.
pub fn generations(run: &Run) -> Vec<GenerationRecord> {
    let Some(bytes) = run.read("generations.jsonl") else { return Vec::new() };
    let mut lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
    let partial = lines.pop().filter(|l| !l.is_empty());
    if partial.is_some() && !run.is_held() {
        run.note(format!("generations.jsonl: line {} skipped: cut short (no newline)", lines.len() + 1));
    }
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let why = match std::str::from_utf8(line) {
            Err(e) => format!("not UTF-8 (byte {})", e.valid_up_to()),
            Ok(l) if l.trim().is_empty() => continue,
            Ok(l) => match serde_json::from_str::<GenerationRecord>(l) {
                Ok(r) => {
                    out.push(r);
                    continue;
                }
                Err(e) => e.to_string(),
            },
        };
        run.note(format!("generations.jsonl: line {} skipped: {why}", i + 1));
    }
    out
}

/// The state, with a run nobody holds the lock of shown as interrupted.
pub fn state(run: &Run) -> Option<(RunState, Phase)> {
    let st: RunState = run.json("state.json")?;
    let phase = match st.state {
        Phase::Running if !run.is_held() => Phase::Interrupted,
        s => s,
    };
    Some((st, phase))
}

/// One evaluated setting: its last record over the generations.
struct Point {
    id: String,
    activation: &'static str,
    delta_min: f64,
    patience: usize,
    fitness: Option<f64>,
    partial: Option<f64>,
    pruned: bool,
    /// Raced out (`search.race`) in its last record: after how many datasets, and the p-value.
    raced: Option<crate::ga::racing::RaceRecord>,
    diverged: bool,
    first: usize,
}

fn points(gens: &[GenerationRecord]) -> Vec<Point> {
    let mut by: BTreeMap<String, Point> = BTreeMap::new();
    for g in gens {
        for ind in &g.individuals {
            let p = by.entry(ind.setting.clone()).or_insert(Point {
                id: ind.setting.clone(),
                activation: activation_name(ind.decoded.activation),
                delta_min: ind.decoded.delta_min,
                patience: ind.decoded.patience,
                fitness: None,
                partial: None,
                pruned: false,
                raced: None,
                diverged: false,
                first: g.generation,
            });
            p.fitness = ind.fitness;
            p.partial = ind.partial_mean();
            p.pruned = ind.pruned;
            p.raced = ind.race.filter(|r| r.stopped);
            p.diverged = !ind.stopped_early() && ind.fitness.is_none();
        }
    }
    by.into_values().collect()
}

/// How much of the fitness variance one gene explains.
#[derive(Debug, PartialEq)]
pub struct Importance {
    /// The gene's name.
    pub gene: &'static str,
    /// The correlation ratio η² of fitness on the gene's bins: between-bin variance over total
    /// variance, 0 (the bins' means are equal) to 1 (the gene decides fitness).
    pub eta2: f64,
    /// Bins: the gene's values when it has at most [`BINS`] of them, else [`BINS`] bins of equal count.
    pub bins: usize,
    /// Scored settings it is computed over.
    pub n: usize,
}

/// Bins per gene for [`importance`].
pub const BINS: usize = 5;

/// Gene importance over the scored settings: for activation, δ_min and patience, the correlation
/// ratio η² of fitness on the gene's bins. One number a gene, cheap and explained in a line; it
/// sees each gene alone (no interactions, unlike fANOVA), which the parallel-coordinate plot shows.
fn importance(pts: &[Point]) -> Vec<Importance> {
    let scored: Vec<&Point> = pts.iter().filter(|p| p.fitness.is_some_and(f64::is_finite)).collect();
    let y: Vec<f64> = scored.iter().filter_map(|p| p.fitness).collect();
    let genes: [(&'static str, Vec<f64>); 3] = [
        (
            "activation",
            scored
                .iter()
                .map(|p| ["sigmoid", "tanh", "relu"].iter().position(|a| *a == p.activation).unwrap_or(3) as f64)
                .collect(),
        ),
        ("δ_min", scored.iter().map(|p| p.delta_min).collect()),
        ("patience", scored.iter().map(|p| p.patience as f64).collect()),
    ];
    genes
        .into_iter()
        .map(|(gene, x)| {
            let (bin, bins) = bin_of(&x);
            Importance { gene, eta2: eta2(&y, &bin, bins), bins, n: y.len() }
        })
        .collect()
}

/// Each value's bin: its distinct value when there are at most [`BINS`], else its quantile bin.
fn bin_of(x: &[f64]) -> (Vec<usize>, usize) {
    let mut distinct: Vec<f64> = x.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() <= BINS {
        return (x.iter().map(|v| distinct.iter().position(|d| d == v).unwrap_or(0)).collect(), distinct.len());
    }
    let mut order: Vec<usize> = (0..x.len()).collect();
    order.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
    let mut bin = vec![0; x.len()];
    for (rank, &i) in order.iter().enumerate() {
        bin[i] = rank * BINS / x.len();
    }
    // Equal values share a bin (the lowest rank's), so a bin never splits one value.
    for w in 1..order.len() {
        if x[order[w]] == x[order[w - 1]] {
            bin[order[w]] = bin[order[w - 1]];
        }
    }
    (bin, BINS)
}

fn eta2(y: &[f64], bin: &[usize], bins: usize) -> f64 {
    let n = y.len() as f64;
    if y.len() < 2 {
        return 0.0;
    }
    let mean = y.iter().sum::<f64>() / n;
    let total: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
    if total == 0.0 {
        return 0.0;
    }
    let mut sum = vec![0.0; bins];
    let mut count = vec![0.0; bins];
    for (v, &b) in y.iter().zip(bin) {
        sum[b] += v;
        count[b] += 1.0;
    }
    let between: f64 = sum.iter().zip(&count).filter(|(_, c)| **c > 0.0).map(|(s, c)| c * (s / c - mean).powi(2)).sum();
    between / total
}

/// The link to a setting's page.
pub fn setting_url(run: &Run, id: &str) -> String {
    format!("{}?setting={}", run.url(), encode(id))
}

/// The search page: its tables, and the chart data the script draws.
pub fn page(run: &Run) -> (Vec<Table>, Value) {
    let gens = generations(run);
    let env = run.json::<Value>("run.json").and_then(|v| v["env"].as_str().map(String::from));
    let validation: Option<Validation> = run.json("validation.json");
    let reference = env.as_deref().and_then(|e| validation.as_ref()?.thesis_fitness(e));
    let pts = points(&gens);

    let mut g = Table::new(
        "generations",
        "Generations",
        &["generation", "best", "mean", "min", "std", "diverged", "pruned", "new units", "best so far"],
    );
    for r in &gens {
        let s = &r.stats;
        g.push(vec![
            Cell::text(r.generation.to_string()),
            Cell::num(s.max),
            Cell::num(s.mean),
            Cell::num(s.min),
            Cell::num(s.std),
            Cell::text(s.diverged.to_string()),
            Cell::text(s.pruned.to_string()),
            Cell::text(r.new_units.to_string()),
            Cell::num(r.best_so_far.fitness),
        ]);
    }
    let mut pop = Table::new(
        "population",
        "Population: every evaluated setting",
        &["setting", "activation", "δ_min", "patience", "fitness", "state", "first generation"],
    );
    for p in &pts {
        let state = if p.pruned {
            format!("pruned (partial {})", num(p.partial))
        } else if let Some(r) = p.raced {
            format!("raced out: {} (partial {})", r.describe(), num(p.partial))
        } else if p.diverged {
            "diverged".into()
        } else {
            "scored".into()
        };
        pop.push(vec![
            Cell::link(&p.id, setting_url(run, &p.id)),
            Cell::text(p.activation),
            Cell::text(format!("{:e}", p.delta_min)),
            Cell::text(p.patience.to_string()),
            Cell::num(p.fitness),
            Cell::text(state),
            Cell::text(p.first.to_string()),
        ]);
    }
    let mut tables = vec![summary(run, &gens), g];
    tables.push(hall_of_fame(run));
    if let Some(v) = &validation {
        tables.extend(validation_tables(run, v));
    }
    tables.push(pop);
    if let Some(t) = racing_table(run, &gens) {
        tables.push(t);
    }
    let imp = importance(&pts);
    let mut it = Table::new(
        "importance",
        "Gene importance: share of the fitness variance between the gene's bins (correlation ratio η²)",
        &["gene", "η²", "bins", "settings"],
    );
    for g in &imp {
        it.push(vec![
            Cell::text(g.gene),
            Cell::num(Some(g.eta2)),
            Cell::text(g.bins.to_string()),
            Cell::text(g.n.to_string()),
        ]);
    }
    tables.push(it);
    let chart = json!({
        "importance": imp.iter().map(|g| json!({"gene": g.gene, "eta2": g.eta2})).collect::<Vec<_>>(),
        "generations": gens.iter().map(|r| json!({
            "g": r.generation, "best": r.stats.max, "mean": r.stats.mean, "min": r.stats.min,
            "max": r.stats.max, "best_so_far": r.best_so_far.fitness,
        })).collect::<Vec<_>>(),
        "points": pts.iter().map(|p| json!({
            "id": p.id, "activation": p.activation, "delta_min": p.delta_min, "patience": p.patience,
            "fitness": p.fitness, "partial": p.partial, "pruned": p.pruned || p.raced.is_some(),
            "raced": p.raced.map(|r| r.describe()), "diverged": p.diverged,
            "first": p.first, "url": setting_url(run, &p.id),
        })).collect::<Vec<_>>(),
        "reference": reference.map(|f| json!({"label": "thesis optimum", "value": f})),
    });
    (tables, chart)
}

/// Racing's decisions (`search.race`), one row per raced individual, titled with the count raced
/// out; none when the search did not race.
fn racing_table(run: &Run, gens: &[GenerationRecord]) -> Option<Table> {
    let raced: Vec<(usize, &crate::ga::records::IndividualRecord)> = gens
        .iter()
        .flat_map(|g| g.individuals.iter().filter(|i| i.race.is_some()).map(move |i| (g.generation, i)))
        .collect();
    if raced.is_empty() {
        return None;
    }
    let out = raced.iter().filter(|(_, i)| i.raced_out()).count();
    let mut t = Table::new(
        "racing",
        &format!("Racing (beyond the thesis): {out} of {} raced individuals raced out", raced.len()),
        &["generation", "individual", "setting", "decision", "datasets", "p"],
    );
    for (g, i) in raced {
        let r = i.race.expect("filtered");
        t.push(vec![
            Cell::text(g.to_string()),
            Cell::text(i.index.to_string()),
            Cell::link(&i.setting, setting_url(run, &i.setting)),
            Cell::text(r.describe()),
            Cell::text(r.datasets.to_string()),
            Cell::num(r.p),
        ]);
    }
    Some(t)
}

fn summary(run: &Run, gens: &[GenerationRecord]) -> Table {
    let mut t = Table::new("summary", "State", &["state", "generation", "best fitness", "best setting", "ran", "ETA"]);
    if let Some((st, phase)) = state(run) {
        t.push(vec![
            Cell::text(phase.name()),
            Cell::text(format!("{}/{}", st.generation, st.generations)),
            Cell::num(st.best_fitness),
            Cell::text(st.best.as_ref().map_or("—".into(), describe)),
            Cell::text(human(st.elapsed())),
            Cell::text(match phase {
                Phase::Running => st.eta_seconds.map_or("?".into(), human),
                _ => "—".into(),
            }),
        ]);
    } else {
        t.push(vec![Cell::text("unreadable state.json"), Cell::text(gens.len().to_string())]);
    }
    t
}

fn hall_of_fame(run: &Run) -> Table {
    let mut t = Table::new("hall_of_fame", "Hall of fame", &["rank", "setting", "fitness", "generation"]);
    let hof: Vec<Value> = run.json("hall_of_fame.json").unwrap_or_default();
    for (i, e) in hof.iter().enumerate() {
        let id = serde_json::from_value(e["decoded"].clone()).ok().map(|d| crate::ga::units::setting_id(&d));
        let id = id.unwrap_or_else(|| "?".into());
        t.push(vec![
            Cell::text((i + 1).to_string()),
            Cell::link(&id, setting_url(run, &id)),
            Cell::num(e["fitness"].as_f64()),
            Cell::text(e["generation"].as_u64().map_or("?".into(), |g| g.to_string())),
        ]);
    }
    t
}

fn validation_tables(run: &Run, v: &Validation) -> Vec<Table> {
    let ci =
        |s: &Option<crate::stats::Summary>| s.map_or("diverged".into(), |s| format!("{:.4} ± {:.4}", s.mean, s.ci95));
    let mut t = Table::new(
        "validation",
        &format!("Validation on {} fresh datasets", v.rule.datasets),
        &["source", "setting", "fitness (search)", "search mean ± 95 %", "validation mean ± 95 %", "tuned"],
    );
    for e in &v.entries {
        t.push(vec![
            Cell::text(&e.source),
            Cell::link(&e.setting, setting_url(run, &e.setting)),
            Cell::num(e.fitness),
            Cell::text(ci(&e.search)),
            Cell::text(ci(&e.validation)),
            Cell::text(if e.setting == v.tuned { "yes" } else { "" }),
        ]);
    }
    let mut out = vec![t];
    // The race rounds, once validation.json records them: each round's fields as columns.
    let raw: Value = run.json("validation.json").unwrap_or_default();
    if let Some(rounds) = raw["rounds"].as_array().filter(|r| !r.is_empty()) {
        let cols: Vec<String> = rounds[0].as_object().map(|o| o.keys().cloned().collect()).unwrap_or_default();
        let mut r = Table::new("race_rounds", "Validation race rounds", &[]);
        r.columns = cols.clone();
        for round in rounds {
            r.push(cols.iter().map(|c| Cell::text(plain(&round[c]))).collect());
        }
        out.push(r);
    }
    out
}

/// A JSON value as table text: strings bare, the rest as JSON.
pub fn plain(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Null => "—".into(),
        other => other.to_string(),
    }
}

/// A setting's page: its per-dataset scores, FQI iterations and networks, and its births. Reads
/// only that setting's unit files. `None` when the id is not a setting.
pub fn setting_page(run: &Run, id: &str) -> Option<(Vec<Table>, Value)> {
    let decoded = parse_setting_id(id)?;
    let mut scores = Table::new(
        "datasets",
        "Per dataset",
        &["dataset", "score", "steps", "diverged", "epochs", "seconds", "FQI iterations"],
    );
    let mut iters = Table::new(
        "iterations",
        "FQI iterations",
        &["dataset", "iteration", "score", "Bellman residual", "epochs", "stop reasons"],
    );
    let mut nets = Table::new(
        "networks",
        "Networks per iteration",
        &["dataset", "iteration", "network", "epochs", "stop", "train loss", "val loss"],
    );
    // Each network's last training and validation loss per FQI iteration (the units record
    // the losses a network stopped at, not every epoch's).
    let mut losses: Vec<Value> = Vec::new();
    for d in 0.. {
        let name = format!("units/{}.json", unit_id(&decoded, d));
        if !crate::store::something_at(&run.dir.join(&name)) {
            break;
        }
        let Some(u) = run.json::<UnitResult>(&name) else { continue };
        scores.push(vec![
            Cell::text(d.to_string()),
            Cell::num(u.score),
            Cell::num(u.steps),
            Cell::text(
                u.diverged.as_ref().map_or(String::new(), |x| format!("iteration {}: {}", x.iteration, x.reason)),
            ),
            Cell::text(u.epochs.to_string()),
            Cell { value: Some(u.seconds.to_string()), ..Cell::text(format!("{:.1}", u.seconds)) },
            Cell::text(u.iterations.len().to_string()),
        ]);
        for it in &u.iterations {
            let mut stops: BTreeMap<String, usize> = BTreeMap::new();
            for (k, n) in it.networks.iter().enumerate() {
                losses.push(json!({
                    "dataset": d, "iteration": it.iteration, "network": k,
                    "train": n.train_loss, "val": n.val_loss,
                }));
                let stop = plain(&serde_json::to_value(n.stop).unwrap_or_default());
                *stops.entry(stop.clone()).or_default() += 1;
                nets.push(vec![
                    Cell::text(d.to_string()),
                    Cell::text(it.iteration.to_string()),
                    Cell::text(k.to_string()),
                    Cell::text(n.epochs.to_string()),
                    Cell::text(stop),
                    loss(n.train_loss),
                    loss(n.val_loss),
                ]);
            }
            iters.push(vec![
                Cell::text(d.to_string()),
                Cell::text(it.iteration.to_string()),
                Cell::num(it.score),
                Cell {
                    value: Some(it.bellman_residual.to_string()),
                    ..Cell::text(format!("{:.4}", it.bellman_residual))
                },
                Cell::text(it.epochs.map_or("—".into(), |e| e.to_string())),
                Cell::text(stops.iter().map(|(s, n)| format!("{s}×{n}")).collect::<Vec<_>>().join(" ")),
            ]);
        }
    }
    let gens = generations(run);
    let mut births = Table::new(
        "births",
        "Births",
        &["generation", "index", "origin", "parents", "crossed genes", "mutated", "genes", "fitness"],
    );
    for g in &gens {
        for ind in g.individuals.iter().filter(|i| i.setting == id) {
            // Parents are indices into the generation before, found by its number: a skipped
            // line must not make the next generation's parents read from the wrong one.
            let prev = g.generation.checked_sub(1).and_then(|p| gens.iter().find(|r| r.generation == p));
            let parents = ind
                .birth
                .iter()
                .flat_map(|b| b.parents)
                .map(|p| match prev.and_then(|r| r.individuals.get(p)) {
                    Some(i) => i.setting.clone(),
                    None => format!("#{p} of generation {} (not read)", g.generation.saturating_sub(1)),
                })
                .collect::<Vec<_>>()
                .join(" × ");
            births.push(vec![
                Cell::text(g.generation.to_string()),
                Cell::text(ind.index.to_string()),
                Cell::text(plain(&serde_json::to_value(ind.origin).unwrap_or_default())),
                Cell::text(parents),
                Cell::text(ind.birth.as_ref().map_or(String::new(), |b| format!("{:?}", b.crossed))),
                Cell::text(ind.birth.as_ref().map_or(String::new(), |b| if b.mutated { "yes" } else { "no" }.into())),
                Cell::text(format!("{:?}", ind.genes)),
                Cell::num(ind.fitness),
            ]);
        }
    }
    Some((vec![scores, iters, births, nets], json!({ "losses": losses })))
}

/// A loss for a table: three significant digits shown, the stored value exported.
fn loss(v: Option<f64>) -> Cell {
    Cell { value: v.map(|x| x.to_string()), ..Cell::text(v.map_or("—".into(), |x| format!("{x:.3e}"))) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(activation: &'static str, delta_min: f64, patience: usize, fitness: f64) -> Point {
        Point {
            id: String::new(),
            activation,
            delta_min,
            patience,
            fitness: Some(fitness),
            partial: None,
            pruned: false,
            raced: None,
            diverged: false,
            first: 0,
        }
    }

    #[test]
    fn importance_finds_the_gene_fitness_follows() {
        // Fitness is patience alone; activation and δ_min vary without effect.
        let acts = ["sigmoid", "tanh", "relu"];
        let pts: Vec<Point> =
            (0..60).map(|i| point(acts[i % 3], 10f64.powi(-(((i * 7) % 5) as i32)), i, i as f64)).collect();
        let imp = importance(&pts);
        let by = |g: &str| imp.iter().find(|i| i.gene == g).unwrap().eta2;
        assert!(by("patience") > 0.9, "{imp:?}");
        assert!(by("activation") < 0.05 && by("δ_min") < 0.05, "{imp:?}");
        assert_eq!(imp[2].bins, BINS);
        assert_eq!(imp[0].bins, 3);
        // Constant fitness: nothing explains anything.
        let flat: Vec<Point> = (0..10).map(|i| point("tanh", 1e-3, i, 1.0)).collect();
        assert!(importance(&flat).iter().all(|i| i.eta2 == 0.0));
    }
}
