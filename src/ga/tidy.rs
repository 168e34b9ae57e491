//! `bfqi-ga tidy`: a search started with `--units-from` holds a copy of every unit of the run it
//! took them from (it cannot know beforehand which it will need). Tidying removes the unit files
//! of settings it never drew nor validated, so the run can be kept, or committed, at the size of
//! what it used; its records, report and validation read only those. Before its end, only taken
//! copies go, and the resume takes them again.

use super::records::{RunInfo, read_generations};
use crate::error::{Error, Result};
use crate::store::{RunLock, read_json, write_json};
use std::collections::BTreeSet;
use std::path::Path;

/// What [`tidy`] removed (or, on a dry run, would remove).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Tidy {
    /// Unit files kept: those of settings the search drew or validated.
    pub kept: usize,
    /// Unit files removed.
    pub removed: usize,
    /// Their bytes.
    pub bytes: u64,
    /// The search had not reached its end: only taken copies went, and its resume takes them again.
    pub partial: bool,
}

/// The setting a unit file holds (`<setting>.d<k>.json`, as [`unit_id`] names it), or none for any
/// other file.
///
/// [`unit_id`]: super::units::unit_id
fn setting_of(file: &str) -> Option<String> {
    super::units::parse_unit_id(file.strip_suffix(".json")?).map(|(s, _)| super::units::setting_id(&s))
}

/// Removes from the search in `dir` the unit files (`units/`, `validation/`) of settings that none
/// of its generations drew and its validation did not score; with `dry_run`, only counts them.
///
/// A finished, validated search loses every such file. One not yet at its end (stopped, cut by
/// its budget, or not yet validated) may need any unit it computed when it resumes, so it loses
/// only the copies it took with `--units-from` (files its source run holds too), and `run.json`
/// marks them `tidied`: the resume takes them again before it goes on ([`retake_units`]), so a
/// long search can be kept or committed between sessions at the size of what it has used. A
/// search that took nothing is refused until it has finished.
///
/// [`retake_units`]: super::setup::retake_units
pub fn tidy(dir: &Path, dry_run: bool) -> Result<Tidy> {
    let _lock = RunLock::acquire(dir)?;
    let refuse = |message: String| Error::File { path: dir.to_path_buf(), message };
    let state: serde_json::Value = read_json(&dir.join("state.json"))?;
    let spec = super::setup::load_spec(dir)?;
    let validation = super::validate::load(dir);
    let complete = state["state"] == "finished" && (spec.search.validate.is_none() || validation.is_some());
    let info_path = dir.join("run.json");
    let mut info: RunInfo = read_json(&info_path)?;
    if !complete && info.units_from.is_empty() {
        let why = if state["state"] == "finished" {
            "its validation has not run yet (no validation.json)".to_string()
        } else {
            format!("state.json says {}", state["state"])
        };
        return Err(refuse(format!(
            "{why}, and it took no units with --units-from: only a finished search is tidied (a resume may need \
             any unit it computed); resume it first"
        )));
    }
    let drawn: BTreeSet<String> =
        read_generations(dir)?.into_iter().flat_map(|g| g.individuals.into_iter().map(|i| i.setting)).collect();
    let validated: BTreeSet<String> =
        validation.map(|v| v.entries.into_iter().map(|e| e.setting).collect()).unwrap_or_default();
    // A file the source runs hold too was taken (or would have been): a resume can take it again.
    let taken =
        |folder: &str, name: &str| info.units_from.iter().any(|u| Path::new(&u.dir).join(folder).join(name).is_file());
    let mut t = Tidy { partial: !complete, ..Tidy::default() };
    for (folder, keep) in
        [("units", drawn.union(&validated).cloned().collect::<BTreeSet<_>>()), ("validation", validated)]
    {
        let Ok(entries) = std::fs::read_dir(dir.join(folder)) else { continue };
        for e in entries {
            let e = e.map_err(|err| Error::io(dir.join(folder), err))?;
            let name = e.file_name().to_string_lossy().into_owned();
            match setting_of(&name) {
                Some(s) if !keep.contains(&s) && (complete || taken(folder, &name)) => {
                    let path = e.path();
                    t.bytes += e.metadata().map_err(|err| Error::io(&path, err))?.len();
                    t.removed += 1;
                    if !dry_run {
                        std::fs::remove_file(&path).map_err(|err| Error::io(&path, err))?;
                    }
                }
                Some(_) => t.kept += 1,
                None => {}
            }
        }
    }
    if !dry_run && t.removed > 0 && !info.units_from.is_empty() {
        for u in &mut info.units_from {
            u.tidied = true;
        }
        write_json(&info_path, &info)?;
    }
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_unit_file_names_its_setting() {
        assert_eq!(setting_of("tanh_6.1e-4_711.d3.json").as_deref(), Some("tanh_6.1e-4_711"));
        assert_eq!(setting_of("sigmoid_4.6e-5_4.d12.json").as_deref(), Some("sigmoid_4.6e-5_4"));
        assert_eq!(setting_of("tanh_6.1e-4_711.d3.json.tmp1").as_deref(), None);
        assert_eq!(setting_of("notes.json").as_deref(), None);
        assert_eq!(setting_of("x.dfoo.json").as_deref(), None);
    }
}
