//! What the GA adds over random sampling: the report section of a random-search baseline
//! (`search.strategy: random`) beside the GA search whose units it took (`--units-from`), at the
//! same number of FQI runs, with the paired differences of the two winners.

use crate::ga::records::{GenerationRecord, RunInfo};
use crate::ga::setup::load_spec;
use crate::ga::validate;
use crate::spec::{Spec, Strategy};
use crate::stats::{Paired, paired};
use crate::store::read_json;
use std::path::{Path, PathBuf};

/// The GA run a random baseline in `dir` took its units from: the path run.json records, as given
/// (relative to where the baseline was started) or beside the baseline's directory.
fn ga_run(dir: &Path, info: &RunInfo) -> Option<PathBuf> {
    info.units_from.iter().find_map(|u| {
        let given = PathBuf::from(&u.dir);
        let beside = dir.parent().zip(given.file_name()).map(|(p, f)| p.join(f));
        [Some(given), beside].into_iter().flatten().find(|p| p.join("generations.jsonl").is_file())
    })
}

/// The best fitness so far after the last generation whose cumulative FQI runs are ≤ `units`,
/// with those runs.
fn best_within(records: &[GenerationRecord], units: usize) -> Option<(usize, Option<f64>)> {
    let mut spent = 0;
    let mut best = None;
    for r in records {
        if spent + r.new_units > units {
            break;
        }
        spent += r.new_units;
        best = Some((spent, r.best_so_far.fitness));
    }
    best
}

fn cell(p: Option<Paired>) -> (String, &'static str) {
    match p {
        None => ("—".into(), "no interval (a diverged dataset, or under 2)"),
        Some(p) => (
            format!("{} (n = {})", p.show(3), p.n),
            match p.sign() {
                1 => "GA ahead",
                -1 => "GA behind",
                _ => "indistinguishable",
            },
        ),
    }
}

fn fmt(v: Option<f64>) -> String {
    v.map_or("−∞".into(), |x| format!("{x:.3}"))
}

/// The GA run the random baseline in `dir` took its units from, if it names one that exists.
pub fn ga_dir(dir: &Path) -> Option<PathBuf> {
    ga_run(dir, &read_json::<RunInfo>(&dir.join("run.json")).ok()?)
}

/// The section for a random baseline in `dir` (empty for a GA search), beside the GA run
/// `ga` (its directory and records, from [`ga_dir`]); without one, the section says so.
pub fn markdown(
    dir: &Path,
    spec: &Spec,
    records: &[GenerationRecord],
    ga: Option<(PathBuf, Vec<GenerationRecord>)>,
) -> String {
    if spec.search.strategy != Strategy::Random {
        return String::new();
    }
    let mut md = String::from("\n## The GA against this random search\n\n");
    let Some((ga_dir, ga)) = ga else {
        md.push_str("No GA run to compare with: run.json names none that exists (`search --units-from`).\n");
        return md;
    };
    let ga_spec = match load_spec(&ga_dir) {
        Ok(s) if s.results_hash() == spec.results_hash() && s.search.strategy == Strategy::Ga => s,
        _ => {
            md.push_str(&format!("`{}` is not a GA search of this spec: no comparison.\n", ga_dir.display()));
            return md;
        }
    };
    let (Some(ga_last), Some(rnd_last)) = (ga.last(), records.last()) else { return String::new() };
    let units = |r: &[GenerationRecord]| r.iter().map(|g| g.new_units).sum::<usize>();
    let (ga_units, rnd_units) = (units(&ga), units(records));
    let common = ga_units.min(rnd_units);
    md.push_str(&format!(
        "The GA search `{}` (population {}, the thesis's breeding) and this random search draw from the same gene \
         ranges, score settings on the same {} search datasets and share generation 0. FQI runs are the units \
         each search needed (the `new units` column).\n\n",
        ga_dir.display(),
        ga_spec.search.ga.population,
        spec.search.datasets
    ));
    md.push_str("| | GA | random |\n|---|---|---|\n");
    md.push_str(&format!("| generations | {} | {} |\n", ga.len(), records.len()));
    md.push_str(&format!("| FQI runs | {ga_units} | {rnd_units} |\n"));
    let (gw, rw) = (best_within(&ga, common), best_within(records, common));
    md.push_str(&format!(
        "| best fitness within {common} FQI runs | {} ({} runs) | {} ({} runs) |\n",
        gw.map_or("—".into(), |(_, f)| fmt(f)),
        gw.map_or(0, |(u, _)| u),
        rw.map_or("—".into(), |(_, f)| fmt(f)),
        rw.map_or(0, |(u, _)| u)
    ));
    md.push_str(&format!(
        "| best fitness at the end | {} `{}` | {} `{}` |\n",
        fmt(ga_last.best_so_far.fitness),
        ga_last.best_so_far.setting,
        fmt(rnd_last.best_so_far.fitness),
        rnd_last.best_so_far.setting
    ));

    md.push_str(
        "\nThe GA's winner minus the random search's, dataset by dataset (mean ± 95 % interval, Student t with \
         n − 1 degrees of freedom); each winner is the maximum of its own search, so the search-dataset row \
         favours neither but is biased upward for both, and the validation row is the one to trust.\n\n\
         | GA winner minus random winner | difference | verdict |\n|---|---|---|\n",
    );
    let (d, verdict) = cell(paired(&ga_last.best_so_far.scores, &rnd_last.best_so_far.scores, 0.95));
    md.push_str(&format!("| search datasets | {d} | {verdict} |\n"));
    match (validate::load(&ga_dir), validate::load(dir)) {
        (Some(gv), Some(rv)) => {
            let winner = |v: &validate::Validation| v.entries.iter().find(|e| e.setting == v.tuned).cloned();
            if let (Some(g), Some(r)) = (winner(&gv), winner(&rv)) {
                let n = g.validation_scores.len().min(r.validation_scores.len());
                let (d, verdict) = cell(paired(&g.validation_scores[..n], &r.validation_scores[..n], 0.95));
                md.push_str(&format!(
                    "| validation datasets (`{}` vs `{}`) | {d} | {verdict} |\n",
                    g.setting, r.setting
                ));
            }
        }
        _ => md.push_str(
            "\nThe validation row appears once both searches are validated on the same validation datasets \
             (`bfqi-ga validate`).\n",
        ),
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ga::records::{GenerationStats, IndividualRecord};

    fn record(new_units: usize, best: f64) -> GenerationRecord {
        let mut b: IndividualRecord = serde_json::from_value(serde_json::json!({"index": 0,
            "genes": [0, 10, 2, 10, 0], "activation": "sigmoid", "delta_min": 0.01, "patience": 10,
            "setting": "sigmoid_1e-2_10", "scores": [best], "fitness": best, "origin": "initial"}))
        .unwrap();
        b.fitness = Some(best);
        GenerationRecord {
            generation: 0,
            individuals: vec![],
            stats: serde_json::from_value::<GenerationStats>(
                serde_json::json!({"min": null, "mean": null, "max": null, "std": null, "diverged": 0}),
            )
            .unwrap(),
            new_units,
            prune_below: None,
            race_against: Vec::new(),
            best_so_far: b,
            best_generation: 0,
        }
    }

    #[test]
    fn best_within_a_budget_stops_before_the_generation_that_exceeds_it() {
        let r = [record(200, 1.0), record(150, 2.0), record(150, 3.0)];
        assert_eq!(best_within(&r, 349), Some((200, Some(1.0))));
        assert_eq!(best_within(&r, 350), Some((350, Some(2.0))));
        assert_eq!(best_within(&r, 10_000), Some((500, Some(3.0))));
        assert_eq!(best_within(&r, 10), None);
    }
}
