//! `bfqi-ga export`: a run's FQI units as one table for pandas (Parquet or CSV), one row per stored
//! unit. A search's rows say which generation and individual first asked for each unit, its genes
//! and decoded setting, dataset, the dataset's seed and the result; a comparison's say the
//! analysis, learner, algorithm, complexity and dataset size of each unit and its result; a batch's
//! concatenate its jobs' tables under a `job` column. README "Tables for pandas" documents every
//! column.

use crate::compare::Comparison;
use crate::error::{Error, Result};
use crate::ga::records::GenerationRecord;
use crate::ga::units::{Evaluator, Role, UnitResult, activation_name, setting_id};
use crate::runs::RunKind;
use crate::table::{Column, Format, Table};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Where and how `export` writes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Destination {
    /// A file (written atomically) in a format.
    File(PathBuf, Format),
    /// CSV on standard output (`--out -`).
    Stdout,
}

impl Destination {
    /// The destination of `export <dir> [--format F] [--out OUT]`: `OUT` (`-` is standard output,
    /// CSV only), by default `<dir>/units.<ext>`; the format is `F`, else the one `OUT`'s
    /// extension names, else Parquet.
    pub fn resolve(dir: &Path, format: Option<Format>, out: Option<&Path>) -> Result<Destination> {
        match out {
            Some(p) if p == Path::new("-") => match format {
                Some(Format::Csv) => Ok(Destination::Stdout),
                _ => Err(Error::Usage(
                    "--out - writes to standard output, which takes CSV only: add --format csv".into(),
                )),
            },
            Some(p) => {
                let f = format.or_else(|| Format::of_path(p)).unwrap_or(Format::Parquet);
                Ok(Destination::File(p.to_path_buf(), f))
            }
            None => {
                let f = format.unwrap_or(Format::Parquet);
                Ok(Destination::File(dir.join(format!("units.{}", f.extension())), f))
            }
        }
    }
}

/// The table of the run (search or comparison) or batch in `dir`.
pub fn table(dir: &Path) -> Result<Table> {
    if dir.join("plan.json").is_file() && dir.join("batch.json").is_file() {
        return batch(dir);
    }
    match crate::runs::kind(dir).map_err(|_| Error::File {
        path: dir.to_path_buf(),
        message: "not a search, comparison or batch directory (no spec.json, compare.json or plan.json)".into(),
    })? {
        RunKind::Search => search(dir),
        RunKind::Compare => comparison(dir),
    }
}

/// Writes the table of `dir` to `to`; returns its rows.
pub fn export(dir: &Path, to: &Destination) -> Result<usize> {
    let t = table(dir)?;
    match to {
        Destination::File(path, format) => crate::table::write(&t, path, *format)?,
        Destination::Stdout => {
            let mut out = std::io::stdout().lock();
            match crate::table::csv::write_to(&t, &mut out) {
                // The reader stopped reading (`| head`): it has what it wanted, as with any filter.
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
                other => other.map_err(|e| Error::io("standard output", e))?,
            }
        }
    }
    Ok(t.rows())
}

/// The run's name in the `run` column: its directory's name.
fn run_name(dir: &Path) -> String {
    let abs = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());
    abs.file_name().map_or_else(|| dir.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// A dataset's seed as written: 16 hexadecimal digits after `0x`, exact in both formats (a u64
/// does not fit pandas' int64, and a CSV reader would read large ones as floats).
fn seed_text(seed: u64) -> String {
    format!("0x{seed:016x}")
}

/// Where in a search a unit was first asked for: (generation, individual) by (setting, dataset),
/// and the genes of the first individual of each setting.
struct Origins {
    first: HashMap<(String, usize), (usize, usize)>,
    genes: HashMap<String, [i64; 5]>,
}

impl Origins {
    /// From `generations.jsonl` (none when the search has not finished a generation): an individual
    /// asks for the datasets it has scores for, 0 up (a pruned or raced one has fewer).
    fn read(dir: &Path) -> Result<Origins> {
        let mut o = Origins { first: HashMap::new(), genes: HashMap::new() };
        if !dir.join("generations.jsonl").is_file() {
            return Ok(o);
        }
        let records: Vec<GenerationRecord> = crate::ga::records::read_generations(dir)?;
        for r in &records {
            for i in &r.individuals {
                o.genes.entry(i.setting.clone()).or_insert(i.genes);
                for d in 0..i.scores.len() {
                    o.first.entry((i.setting.clone(), d)).or_insert((r.generation, i.index));
                }
            }
        }
        Ok(o)
    }
}

/// Columns filled row by row.
#[derive(Default)]
struct Rows {
    columns: Vec<(&'static str, Column)>,
}

impl Rows {
    fn col(&mut self, name: &'static str, empty: Column) -> &mut Column {
        let i = match self.columns.iter().position(|(n, _)| *n == name) {
            Some(i) => i,
            None => {
                self.columns.push((name, empty));
                self.columns.len() - 1
            }
        };
        &mut self.columns[i].1
    }
    fn str(&mut self, name: &'static str, v: Option<String>) {
        if let Column::Str(c) = self.col(name, Column::Str(Vec::new())) {
            c.push(v);
        }
    }
    fn int(&mut self, name: &'static str, v: Option<i64>) {
        if let Column::Int(c) = self.col(name, Column::Int(Vec::new())) {
            c.push(v);
        }
    }
    fn float(&mut self, name: &'static str, v: Option<f64>) {
        if let Column::Float(c) = self.col(name, Column::Float(Vec::new())) {
            c.push(v.unwrap_or(f64::NAN));
        }
    }
    fn table(self) -> Result<Table> {
        let mut t = Table::new();
        for (name, c) in self.columns {
            t.push(name, c)?;
        }
        Ok(t)
    }
}

fn int(v: usize) -> Option<i64> {
    i64::try_from(v).ok()
}

/// A search's table: its units, then its validation units, each folder in file-name order.
fn search(dir: &Path) -> Result<Table> {
    let spec = crate::ga::search::load_spec(dir)?;
    let origins = Origins::read(dir)?;
    let run = run_name(dir);
    let mut rows = Rows::default();
    for role in [Role::Search, Role::Validation] {
        let units = Evaluator::with_role(spec.clone(), dir, role);
        let store = crate::run_dir::UnitStore::named(dir, role.folder());
        for id in store.ids() {
            let refuse = |message: String| Error::File { path: store.path(&id), message };
            let u = match units.verified(&id) {
                Ok(Some(u)) => u,
                // Gone since listed (a live search replaces files atomically, never deletes them).
                Ok(None) => continue,
                Err(problem) => return Err(refuse(format!("{problem}: resume the search to compute it again"))),
            };
            search_row(&mut rows, &run, role, &origins, &units, &u);
        }
    }
    if rows.columns.is_empty() {
        return Ok(empty_search());
    }
    rows.table()
}

fn search_row(rows: &mut Rows, run: &str, role: Role, origins: &Origins, units: &Evaluator, u: &UnitResult) {
    let setting = setting_id(&u.setting);
    let first = match role {
        Role::Search => origins.first.get(&(setting.clone(), u.dataset)).copied(),
        Role::Validation => None,
    };
    let genes = origins.genes.get(&setting);
    rows.str("run", Some(run.to_string()));
    rows.str("role", Some(role.name().to_string()));
    rows.int("generation", first.and_then(|f| int(f.0)));
    rows.int("individual", first.and_then(|f| int(f.1)));
    for (i, name) in GENE_COLUMNS.iter().enumerate() {
        rows.int(name, genes.map(|g| g[i]));
    }
    rows.str("setting", Some(setting));
    rows.str("activation", Some(activation_name(u.setting.activation).to_string()));
    rows.float("delta_min", Some(u.setting.delta_min));
    rows.int("patience", int(u.setting.patience));
    rows.int("dataset", int(u.dataset));
    rows.str("seed", Some(seed_text(units.dataset_seed(u.dataset))));
    rows.float("score", u.score);
    rows.float("steps", u.steps);
    rows.int("diverged", u.diverged.as_ref().and_then(|d| int(d.iteration)));
    rows.str("diverged_reason", u.diverged.as_ref().map(|d| d.reason.clone()));
    rows.int("epochs", int(u.epochs));
    rows.float("seconds", Some(u.seconds));
}

/// The genes' columns, in the chromosome's order.
const GENE_COLUMNS: [&str; 5] =
    ["gene_activation", "gene_a_delta", "gene_b_delta", "gene_a_patience", "gene_b_patience"];

/// A search table without rows, with its columns and their types.
fn empty_search() -> Table {
    let mut t = Table::new();
    let (s, i, f) = (Column::Str(vec![]), Column::Int(vec![]), Column::Float(vec![]));
    let mut names: Vec<(&str, &Column)> = vec![("run", &s), ("role", &s), ("generation", &i), ("individual", &i)];
    names.extend(GENE_COLUMNS.iter().map(|n| (*n, &i)));
    names.extend([
        ("setting", &s),
        ("activation", &s),
        ("delta_min", &f),
        ("patience", &i),
        ("dataset", &i),
        ("seed", &s),
        ("score", &f),
        ("steps", &f),
        ("diverged", &i),
        ("diverged_reason", &s),
        ("epochs", &i),
        ("seconds", &f),
    ]);
    for (n, c) in names {
        t.push(n, c.clone()).expect("distinct names, no rows");
    }
    t
}

/// A comparison's table: its stored units in the configuration's order.
fn comparison(dir: &Path) -> Result<Table> {
    let c = Comparison::open(dir)?;
    let cfg = c.config();
    let run = run_name(dir);
    let analyses: Vec<(crate::compare::Analysis, std::collections::HashSet<crate::compare::Unit>)> =
        cfg.analyses.iter().map(|&a| (a, cfg.units_of(a).into_iter().collect())).collect();
    let mut rows = Rows::default();
    for u in cfg.units() {
        let path = dir.join("units").join(format!("{}.json", cfg.unit_id(&u)));
        let r = match c.verified(&u) {
            Ok(Some(r)) => r,
            Ok(None) => continue,
            Err(problem) => {
                return Err(Error::File {
                    path,
                    message: format!("{problem}: resume the comparison to compute it again"),
                });
            }
        };
        let plan = &cfg.learners[u.learner];
        let of: Vec<&str> = analyses.iter().filter(|(_, s)| s.contains(&u)).map(|(a, _)| a.name()).collect();
        let last = r.record.iterations.last();
        let epochs: Option<usize> = r.record.iterations.iter().map(|i| i.epochs).sum();
        let seconds: f64 = r.record.iterations.iter().map(|i| i.fit_seconds + i.predict_seconds + i.eval_seconds).sum();
        rows.str("run", Some(run.clone()));
        rows.str("analysis", Some(of.join("+")));
        rows.str("learner", Some(plan.name.clone()));
        rows.str("algorithm", Some(u.algorithm.name().to_string()));
        rows.int("complexity", u.complexity.and_then(int));
        rows.int("episodes", int(u.episodes));
        rows.int("transitions", int(r.transitions));
        rows.int("dataset", int(u.dataset));
        rows.str("seed", Some(seed_text(cfg.run_config(&u).dataset_seed(u.dataset))));
        rows.int("iterations", int(r.record.iterations.len()));
        rows.float("score", last.and_then(|i| i.score));
        rows.float("steps", last.and_then(|i| i.steps));
        rows.int("diverged", r.record.diverged.as_ref().and_then(|d| int(d.iteration)));
        rows.str("diverged_reason", r.record.diverged.as_ref().map(|d| d.reason.clone()));
        rows.int("epochs", epochs.and_then(int));
        rows.float("seconds", Some(seconds));
    }
    if rows.columns.is_empty() {
        return Err(Error::File {
            path: dir.join("units"),
            message: "no unit stored yet: nothing to export (resume the comparison first)".into(),
        });
    }
    rows.table()
}

/// A batch's table: each job's (searches and comparisons) under `job` and `kind` columns, the
/// columns of one kind missing in the other's rows. Jobs not started yet are left out.
fn batch(dir: &Path) -> Result<Table> {
    let states: Vec<crate::batch::JobState> = crate::store::read_json(&dir.join("batch.json"))?;
    let mut all = Table::new();
    for s in &states {
        let job_dir = dir.join(&s.dir);
        let kind = match crate::runs::kind(&job_dir) {
            Ok(RunKind::Search) => "search",
            Ok(RunKind::Compare) => "compare",
            Err(_) => continue,
        };
        let t = match table(&job_dir) {
            Ok(t) => t,
            // A comparison that has stored nothing yet has no rows to add.
            Err(Error::File { path, .. }) if path == job_dir.join("units") => continue,
            Err(e) => return Err(e),
        };
        let mut with_job = Table::new();
        with_job.push("job", Column::Str(vec![Some(s.name.clone()); t.rows()]))?;
        with_job.push("kind", Column::Str(vec![Some(kind.to_string()); t.rows()]))?;
        for (name, c) in t.columns() {
            with_job
                .push(name, c.clone())
                .map_err(|e| Error::File { path: job_dir.clone(), message: e.to_string() })?;
        }
        all.append(&with_job).map_err(|e| Error::File { path: job_dir.clone(), message: e.to_string() })?;
    }
    if all.width() == 0 {
        return Err(Error::File {
            path: dir.to_path_buf(),
            message: "no job has stored units yet: nothing to export".into(),
        });
    }
    Ok(all)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_destination_defaults_to_parquet_in_the_run_and_follows_the_extension() {
        let d = Path::new("runs/s");
        let file = |p: &str, f| Destination::File(PathBuf::from(p), f);
        let to = |format, out: Option<&str>| Destination::resolve(d, format, out.map(Path::new)).unwrap();
        assert_eq!(to(None, None), file("runs/s/units.parquet", Format::Parquet));
        assert_eq!(to(Some(Format::Csv), None), file("runs/s/units.csv", Format::Csv));
        assert_eq!(to(None, Some("t.CSV")), file("t.CSV", Format::Csv));
        assert_eq!(to(None, Some("t.dat")), file("t.dat", Format::Parquet));
        assert_eq!(to(Some(Format::Parquet), Some("t.csv")), file("t.csv", Format::Parquet));
        assert_eq!(to(Some(Format::Csv), Some("-")), Destination::Stdout);
        let e = Destination::resolve(d, None, Some(Path::new("-"))).unwrap_err().to_string();
        assert!(e.contains("add --format csv"), "{e}");
    }

    #[test]
    fn seeds_are_written_whole_in_hexadecimal() {
        assert_eq!(seed_text(1), "0x0000000000000001");
        assert_eq!(seed_text(u64::MAX), "0xffffffffffffffff");
    }

    #[test]
    fn an_empty_search_table_has_every_column() {
        let t = empty_search();
        assert_eq!(t.rows(), 0);
        assert_eq!(t.width(), 21);
        assert!(matches!(t.column("generation"), Some(Column::Int(_))));
        assert!(matches!(t.column("seed"), Some(Column::Str(_))));
    }
}
