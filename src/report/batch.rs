//! A batch's check against full-size searches: each search job with a `reference` (a finished,
//! validated search of the same spec, e.g. `results/searches/bicycle`) has its validated winner
//! scored on the reference's validation datasets and set against the reference's validated
//! winner's 95 % interval, as the one-night plan promises.

use crate::error::{Error, Result};
use crate::ga::setup::load_spec;
use crate::ga::validate::{self, Entry, Validation};
use crate::spec::Spec;
use crate::stats::{Summary, paired};
use std::path::Path;

/// Refuses a reference that is not a validated search of the same datasets and scores as `spec`:
/// same env, master seed, episodes, iterations, algorithm, action encoding and network, so its
/// validation datasets (and what a setting scores on them) are the job's.
pub fn check_reference(spec: &Spec, reference: &Path) -> Result<()> {
    let refuse =
        |message: String| Error::File { path: reference.to_path_buf(), message: format!("field reference: {message}") };
    if validate::load(reference).is_none() {
        return Err(refuse(
            "not a validated search run directory (no readable validation.json); `bfqi-ga validate` it first".into(),
        ));
    }
    let theirs = load_spec(reference).map_err(|e| refuse(e.to_string()))?;
    let (a, b) = (&spec.search, &theirs.search);
    let fields: [(&str, serde_json::Value, serde_json::Value); 7] = [
        ("env", value(&spec.env), value(&theirs.env)),
        ("seed", value(&spec.seed), value(&theirs.seed)),
        ("search.episodes", value(&a.episodes), value(&b.episodes)),
        ("search.iterations", value(&a.iterations), value(&b.iterations)),
        ("search.algorithm", value(&a.algorithm), value(&b.algorithm)),
        ("search.actions", value(&a.actions), value(&b.actions)),
        ("search.network", value(&a.network), value(&b.network)),
    ];
    for (field, mine, theirs) in fields {
        if mine != theirs {
            return Err(refuse(format!(
                "its {field} differs from this job's ({theirs} vs {mine}), so its validation datasets or scores are not this job's"
            )));
        }
    }
    Ok(())
}

fn value<T: serde::Serialize>(v: &T) -> serde_json::Value {
    serde_json::to_value(v).unwrap_or(serde_json::Value::Null)
}

/// Where a job's validated winner lands against its reference's.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceCheck {
    /// The job's validated winner.
    pub winner: String,
    /// Its validation mean over the reference's validation datasets.
    pub mean: Option<f64>,
    /// How many datasets that is.
    pub datasets: usize,
    /// The reference's validated winner.
    pub reference_winner: String,
    /// Its validation summary (mean and 95 % interval, 1.96·std/√n).
    pub reference: Summary,
    /// The winner minus the reference's winner, dataset by dataset (Student t, 95 %).
    pub difference: Option<crate::stats::Paired>,
}

impl ReferenceCheck {
    /// `below`, `within` or `above` the reference's interval (a diverged dataset is below).
    pub fn verdict(&self) -> &'static str {
        let (lo, hi) = (self.reference.mean - self.reference.ci95, self.reference.mean + self.reference.ci95);
        match self.mean {
            Some(m) if m > hi => "above",
            Some(m) if m >= lo => "within",
            _ => "below",
        }
    }
}

fn winner(v: &Validation) -> Option<&Entry> {
    let name = v.best_validated.as_ref().unwrap_or(&v.tuned);
    v.entries.iter().find(|e| &e.setting == name)
}

/// The check of the search in `job` against `reference`, or why there is none yet.
pub fn reference_check(job: &Path, reference: &Path) -> std::result::Result<ReferenceCheck, String> {
    let night = validate::load(job).ok_or("not validated yet")?;
    let full = validate::load(reference).ok_or_else(|| format!("{} has no validation.json", reference.display()))?;
    let (w, r) =
        (winner(&night).ok_or("no validated winner")?, winner(&full).ok_or("the reference has no validated winner")?);
    let n = r.validation_scores.len();
    if w.validation_scores.len() < n {
        return Err(format!(
            "the winner was validated on {} datasets, the reference on {n}",
            w.validation_scores.len()
        ));
    }
    let mine = &w.validation_scores[..n];
    let mean = mine.iter().copied().collect::<Option<Vec<f64>>>().map(|s| s.iter().sum::<f64>() / n as f64);
    let reference = r.validation.ok_or("the reference's winner diverged on a validation dataset")?;
    Ok(ReferenceCheck {
        winner: w.setting.clone(),
        mean,
        datasets: n,
        reference_winner: r.setting.clone(),
        reference,
        difference: paired(mine, &r.validation_scores, 0.95),
    })
}

/// summary.md's section for `checks` (job name, its directory under `batch`, its reference).
pub fn reference_section(batch: &Path, checks: &[(String, String, String)]) -> String {
    let mut md = String::from(
        "\n## Against the full-size searches\n\nEach search job's validated winner, scored on its reference's validation datasets (the same \
         datasets: same env, seed, episodes, iterations and network, checked when the batch started), against the \
         reference's validated winner: its mean ± 95 % interval (1.96·std/√n, as its report shows) and the paired \
         difference (Student t, n − 1 degrees of freedom). `within` or `above` the interval keeps the promise. \
         `work`: the job's and the reference's hours on the reference machine, counted from the units each used \
         (`bfqi-ga work`), and their ratio.\n\n\
         | job | validated winner | its validation mean | reference | reference's validated winner | its validation mean | verdict | winner − reference | work |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    for (job, dir, reference) in checks {
        match reference_check(&batch.join(dir), Path::new(reference)) {
            Ok(c) => md.push_str(&format!(
                "| {job} | `{}` | {} ({} datasets) | `{reference}` | `{}` | {:.3} ± {:.3} | {} | {} | {} |\n",
                c.winner,
                c.mean.map_or("−∞ (diverged)".into(), |m| format!("{m:.3}")),
                c.datasets,
                c.reference_winner,
                c.reference.mean,
                c.reference.ci95,
                c.verdict(),
                c.difference.map_or("—".into(), |d| d.show(3)),
                work_ratio(&batch.join(dir), Path::new(reference)),
            )),
            Err(why) => md.push_str(&format!("| {job} | — | {why} | `{reference}` | | | | | |\n")),
        }
    }
    md
}

/// `job / reference h (ratio %)`: the two searches' hours on the reference machine, or `—` when
/// either cannot be counted.
fn work_ratio(job: &Path, reference: &Path) -> String {
    match (crate::work::cached(job), crate::work::cached(reference)) {
        (Ok(j), Ok(r)) if r.reference_hours > 0.0 => format!(
            "{:.2} / {:.2} h ({:.1} %)",
            j.reference_hours,
            r.reference_hours,
            100.0 * j.reference_hours / r.reference_hours
        ),
        _ => "—".into(),
    }
}
