//! Run directories by kind: a search (`spec.json`) or a comparison (`compare.json`), told apart
//! here, above both, so that the layers below them (`run_dir`, `exec`) never name either. The Slurm
//! worker's unit goes through here to the run that owns it.

use crate::compare::Comparison;
use crate::error::{Error, Result};
use crate::exec::Executor;
use crate::ga::search::{Evaluator, load_spec};
use crate::ga::units::Role;
use crate::ga::validate::{self, ValidateRule};
use crate::run_dir::{Budget, Units};
use std::path::{Path, PathBuf};

/// What a run directory holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunKind {
    /// A GA search (`spec.json`).
    Search,
    /// A comparison (`compare.json`).
    Compare,
}

/// The kind of the run in `dir`, from the file that defines it; an error names the directory.
pub fn kind(dir: &Path) -> Result<RunKind> {
    if dir.join("compare.json").is_file() {
        Ok(RunKind::Compare)
    } else if dir.join("spec.json").is_file() {
        Ok(RunKind::Search)
    } else {
        Err(Error::File {
            path: dir.to_path_buf(),
            message: "not a comparison or search run directory (no compare.json or spec.json)".into(),
        })
    }
}

/// The run directories under `root` (searches with a `spec.json` and `run.json`, started or not,
/// comparisons with a `compare.json`), sorted; a run's own folders are not searched further, nor hidden ones (a run
/// under construction is `.<name>.tmp<pid>-<host>` until it is whole).
pub fn find(root: &Path) -> Vec<PathBuf> {
    let mut dirs = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(d) = stack.pop() {
        // A spec.json alone is an input spec kept beside runs (results/minari/spec.json), not a
        // search: a search writes its run.json first.
        let search = d.join("spec.json").is_file() && d.join("run.json").is_file();
        if d.join("state.json").is_file() || search || d.join("compare.json").is_file() {
            dirs.push(d);
            continue;
        }
        if let Ok(entries) = std::fs::read_dir(&d) {
            stack.extend(
                entries
                    .flatten()
                    .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
                    .map(|e| e.path())
                    .filter(|p| p.is_dir()),
            );
        }
    }
    dirs.sort();
    dirs
}

/// One line on the run in `dir` for `bfqi-ga status`, by its kind, ending with what of it does not
/// verify.
pub fn status_line(dir: &Path) -> Result<String> {
    let line = match kind(dir)? {
        RunKind::Compare => crate::compare::status_line(dir)?,
        RunKind::Search => crate::ga::status::line(dir)?,
    };
    // Its work, once it has some, before what does not verify; left out when it cannot be counted
    // (a gymnasium run's datasets need its Python).
    Ok(match crate::work::cached(dir) {
        Ok(w) if w.units + w.tree_units > 0 => with_work(&line, &w.short()),
        _ => line,
    })
}

/// `line` with `work` added as one more field, before the problems (`  ! …`) it ends with.
fn with_work(line: &str, work: &str) -> String {
    match line.find("  ! ") {
        Some(i) => format!("{}  · {work}{}", &line[..i], &line[i..]),
        None => format!("{line}  · {work}"),
    }
}

/// Stamps the run in `dir` (`bfqi-ga stamp`): its units without a checksum that verify get one,
/// and its `run.json` says from then on that every unit has one ([`crate::ga::search::stamp`],
/// [`crate::compare::stamp`]). Under the run's lock, so never beside a run writing units.
pub fn stamp(dir: &Path) -> Result<crate::run_dir::Stamped> {
    let _lock = crate::store::RunLock::acquire(dir)?;
    match kind(dir)? {
        RunKind::Search => crate::ga::search::stamp(dir),
        RunKind::Compare => crate::compare::stamp(dir),
    }
}

/// The units of the run in `dir` stored in its folder `folder`: `units` (a search's or a
/// comparison's), or `validation` (a search's validation units).
pub fn units(dir: &Path, folder: &str) -> Result<Box<dyn Units>> {
    let role = match folder {
        "units" => Role::Search,
        "validation" => Role::Validation,
        other => return Err(Error::invalid("--units", other, "must be units or validation")),
    };
    Ok(match kind(dir)? {
        RunKind::Search => Box::new(Evaluator::with_role(load_spec(dir)?, dir, role)),
        RunKind::Compare if role == Role::Search => Box::new(Comparison::open(dir)?),
        RunKind::Compare => {
            return Err(Error::invalid("--units", folder, "a comparison stores its units in units"));
        }
    })
}

/// The worker side of the Slurm executor: computes unit `id` (stored in the run's folder `folder`)
/// of the run in `dir` and stores it atomically. A unit already stored whole is left alone (a
/// damaged one is computed again).
pub fn worker(dir: &Path, folder: &str, id: &str) -> Result<()> {
    if !dir.is_dir() {
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        return Err(Error::File {
            path: dir.to_path_buf(),
            message: format!(
                "run directory not visible from this node ({}): it must be on a file system shared by the nodes",
                host.trim()
            ),
        });
    }
    let units = units(dir, folder)?;
    // One line per task in its log, so a unit computed by two tasks would be seen there.
    if units.stored(id) {
        println!("{folder}/{id}: already stored, nothing to do");
        return Ok(());
    }
    units.compute(id)?;
    println!("{folder}/{id}: computed and stored");
    Ok(())
}

/// Rebuilds `dir/report.md` when `dir` holds a validation kept apart from its search (`validate
/// --into`: a `validation.json` naming its `source`); `Ok(false)` when it holds none. The source's
/// path is as `validate` was given it, so it is resolved from the directory `report` runs in.
pub fn report_validation_apart(dir: &Path) -> Result<bool> {
    let Some(v) = validate::load(dir) else { return Ok(false) };
    let Some(source) = v.source.as_deref() else { return Ok(false) };
    crate::report::validation::write(Path::new(source), dir, &v)?;
    Ok(true)
}

/// Validates the winner of the search in `dir` ([`validate::run`]) when no search is running: the
/// run's lock is taken first, so it never races a search (or another validation) writing the same
/// directory; then the search's report is rebuilt with the validation in it.
///
/// With `target.out` apart from the search (`validate --into`), `out` is created if missing and
/// locked instead, the search is only read, and `out/report.md` gets the validation alone.
pub fn validate(
    target: &validate::Target<'_>,
    rule: &ValidateRule,
    exec: &dyn Executor,
    budget: &Budget<'_>,
    quiet: bool,
) -> Result<validate::Outcome> {
    let apart = target.out != target.source;
    if apart {
        crate::store::create_dir(target.out)?;
    }
    let _lock = crate::store::RunLock::acquire(target.out)?;
    if !apart {
        // A search tidied before it was validated again holds its taken units once more.
        crate::ga::search::retake_units(target.source, quiet)?;
    }
    let outcome = validate::run_into(target, rule, exec, budget, quiet)?;
    if let validate::Outcome::Validated(v) = &outcome {
        if apart {
            crate::report::validation::write(target.source, target.out, v)?;
        } else {
            crate::report::search::write(target.source)?;
        }
    }
    Ok(outcome)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_work_field_comes_before_the_problems() {
        assert_eq!(super::with_work("cartpole finished  dir", "work 1 k"), "cartpole finished  dir  · work 1 k");
        assert_eq!(super::with_work("a  dir  ! damaged  ! edited", "w"), "a  dir  · w  ! damaged  ! edited");
    }
}
