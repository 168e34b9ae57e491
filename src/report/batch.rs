//! A batch's check against full-size runs: each search job with a `reference` (a finished,
//! validated search of the same spec, e.g. `results/searches/bicycle`) has its validated winner
//! scored on the reference's validation datasets and set against the reference's validated
//! winner's 95 % interval, as the one-night plan promises; each job with a reference, search or
//! comparison, has its work set beside the reference's, and the plan's total beside theirs.

use crate::compare::CompareConfig;
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

/// Refuses a comparison reference that does not compare what `cfg` compares under another tuned
/// config: same env, seed, analyses, logged data and learners (episodes, iterations, datasets,
/// complexities, network), the networks' activation and early stopping (δ_min, patience) aside.
pub fn check_compare_reference(cfg: &CompareConfig, reference: &Path) -> Result<()> {
    let refuse =
        |message: String| Error::File { path: reference.to_path_buf(), message: format!("field reference: {message}") };
    let theirs = crate::compare::load(reference).map_err(|e| refuse(format!("not a comparison run directory: {e}")))?;
    let (mine, theirs) = (untuned(cfg), untuned(&theirs));
    let keys: std::collections::BTreeSet<&String> = mine.keys().chain(theirs.keys()).collect();
    match keys.into_iter().find(|k| mine.get(*k) != theirs.get(*k)) {
        Some(k) => Err(refuse(format!(
            "its `{k}` differs from this job's: a reference compares the same thing, only the tuned config \
             (activation, delta_min, patience) may differ"
        ))),
        None => Ok(()),
    }
}

/// A comparison's configuration without what the tuned config sets.
fn untuned(cfg: &CompareConfig) -> serde_json::Map<String, serde_json::Value> {
    let mut v = match value(cfg) {
        serde_json::Value::Object(m) => m,
        _ => serde_json::Map::new(),
    };
    v.remove("tuned");
    for plan in v.get_mut("learners").and_then(|l| l.as_array_mut()).into_iter().flatten() {
        if let Some(l) = plan.get_mut("learner").and_then(|l| l.as_object_mut()) {
            for k in ["activation", "delta_min", "patience"] {
                l.remove(k);
            }
        }
    }
    v
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
        (Ok(j), Ok(r)) if r.reference_hours > 0.0 => {
            format!(
                "{:.2} / {:.2} h ({})",
                j.reference_hours,
                r.reference_hours,
                percent(j.reference_hours, r.reference_hours)
            )
        }
        _ => "—".into(),
    }
}

/// A job with a `reference`, for [`work_section`].
#[derive(Debug, Clone)]
pub struct Referenced {
    /// The job's name.
    pub job: String,
    /// Its directory under the batch.
    pub dir: String,
    /// Its reference's directory.
    pub reference: String,
    /// Whether the job ran to its end.
    pub finished: bool,
}

/// summary.md's section setting each job's work beside its reference's, on the reference
/// machine, with their totals: the plan's work against the plan its references ran, once every
/// one of the plan's `jobs` names a reference and has finished.
pub fn work_section(batch: &Path, refs: &[Referenced], jobs: usize) -> String {
    let mut md = String::from(
        "\n## Work against the references\n\nEach job that names a `reference` (a search or a comparison of the same \
         thing at full size), its work and its reference's, counted from the units each used (`bfqi-ga work`) and \
         priced in hours on the reference machine.\n\n\
         | job | reference | work | reference's work | ratio |\n|---|---|---|---|---|\n",
    );
    let (mut mine, mut theirs, mut counted) = (0.0, 0.0, 0);
    for r in refs {
        let under_way = if r.finished { "" } else { " (not finished)" };
        match (crate::work::cached(&batch.join(&r.dir)), crate::work::cached(Path::new(&r.reference))) {
            (Ok(j), Ok(f)) => {
                md.push_str(&format!(
                    "| {}{under_way} | `{}` | {:.2} ref. h | {:.2} ref. h | {} |\n",
                    r.job,
                    r.reference,
                    j.reference_hours,
                    f.reference_hours,
                    percent(j.reference_hours, f.reference_hours)
                ));
                if r.finished {
                    mine += j.reference_hours;
                    theirs += f.reference_hours;
                    counted += 1;
                }
            }
            (j, f) => {
                let cell = |w: Result<crate::work::Work>| {
                    w.map_or("—".to_string(), |w| format!("{:.2} ref. h", w.reference_hours))
                };
                md.push_str(&format!("| {}{under_way} | `{}` | {} | {} | — |\n", r.job, r.reference, cell(j), cell(f)));
            }
        }
    }
    md.push_str(&format!(
        "| **finished jobs** | {counted} of {jobs} | **{mine:.2} ref. h** | **{theirs:.2} ref. h** | **{}** |\n\n",
        percent(mine, theirs)
    ));
    md.push_str(&if counted == jobs {
        "Every job names a reference and has finished: the total is the plan's work against the plan its references ran.\n"
            .to_string()
    } else {
        format!(
            "The total counts the {counted} finished job(s) with a reference, of the plan's {jobs}: it is the whole plan's only once every job has a reference and has finished.\n"
        )
    });
    md
}

/// summary.md's section for the `jobs` (name, directory under `batch`) that took units from
/// other runs (`units_from` in their run.json). Such a job's `time` is its replay's, seconds: this
/// names the runs that computed the units and the wall time their reports state (their
/// generations), on their machines; not added to the batch's time, as a source's wall covers all
/// of its units, of which a job may use few. Empty when no job took any.
pub fn taken_units_section(batch: &Path, jobs: &[(String, String)]) -> String {
    let mut rows = String::new();
    for (job, dir) in jobs {
        let Ok(info) = crate::store::read_json::<crate::ga::records::RunInfo>(&batch.join(dir).join("run.json")) else {
            continue;
        };
        for u in &info.units_from {
            let from = Path::new(&u.dir);
            // The source's work record holds its wall time (its state's) and its machines.
            let wall = match crate::work::cached(from) {
                Ok(crate::work::Work { wall_seconds: Some(w), machines, .. }) => {
                    format!("{}{}", crate::progress::human(w), crate::machine::wall_suffix(&machines))
                }
                _ => "— (not recorded)".into(),
            };
            let validation = if u.validation > 0 { format!(" (+{} validation)", u.validation) } else { String::new() };
            rows.push_str(&format!("| {job} | {}{validation} | `{}` | {wall} |\n", u.units, u.dir));
        }
    }
    if rows.is_empty() {
        return rows;
    }
    format!(
        "\n## Units computed elsewhere\n\nA job that took units from another run (`units_from`) did not compute \
         them: its `time` above is only what it computed and replayed itself. The wall time that computed them is \
         the source run's, as its report states it: its generations' walls summed over its invocations, on its \
         machines, for all of its units (the job copies those of its own spec and may use fewer; the source's \
         validation wall is not recorded).\n\n| job | units copied | from | the source's wall time |\n\
         |---|---|---|---|\n{rows}"
    )
}

fn percent(part: f64, whole: f64) -> String {
    if whole > 0.0 { format!("{:.1} %", 100.0 * part / whole) } else { "—".into() }
}
