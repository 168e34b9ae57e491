//! `bfqi-ga tidy`: a search started with `--units-from` holds a copy of every unit of the run it
//! took them from (it cannot know beforehand which it will need). Once it has finished, tidying
//! removes the unit files of settings it never drew nor validated, so the run can be kept, or
//! committed, at the size of what it used; its records, report and validation read only those.

use super::records::read_generations;
use crate::error::{Error, Result};
use crate::store::{RunLock, read_json};
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
}

/// The setting a unit file holds (`<setting>.d<k>.json`, as [`unit_id`] names it), or none for any
/// other file.
///
/// [`unit_id`]: super::units::unit_id
fn setting_of(file: &str) -> Option<String> {
    super::units::parse_unit_id(file.strip_suffix(".json")?).map(|(s, _)| super::units::setting_id(&s))
}

/// Removes from the finished search in `dir` the unit files (`units/`, `validation/`) of settings
/// that none of its generations drew and its validation did not score; with `dry_run`, only
/// counts them. A search still running, stopped before its end or not yet validated is refused:
/// a resume may need any unit it holds.
pub fn tidy(dir: &Path, dry_run: bool) -> Result<Tidy> {
    let _lock = RunLock::acquire(dir)?;
    let refuse = |message: String| Error::File { path: dir.to_path_buf(), message };
    let state: serde_json::Value = read_json(&dir.join("state.json"))?;
    if state["state"] != "finished" {
        return Err(refuse(format!(
            "state.json says {}: only a finished search is tidied (a resume may need any unit it holds)",
            state["state"]
        )));
    }
    let spec = super::setup::load_spec(dir)?;
    let validation = super::validate::load(dir);
    if spec.search.validate.is_some() && validation.is_none() {
        return Err(refuse("its validation has not run yet (no validation.json): resume it first".into()));
    }
    let drawn: BTreeSet<String> =
        read_generations(dir)?.into_iter().flat_map(|g| g.individuals.into_iter().map(|i| i.setting)).collect();
    let validated: BTreeSet<String> =
        validation.map(|v| v.entries.into_iter().map(|e| e.setting).collect()).unwrap_or_default();
    let mut t = Tidy::default();
    for (folder, keep) in
        [("units", drawn.union(&validated).cloned().collect::<BTreeSet<_>>()), ("validation", validated)]
    {
        let Ok(entries) = std::fs::read_dir(dir.join(folder)) else { continue };
        for e in entries {
            let e = e.map_err(|err| Error::io(dir.join(folder), err))?;
            let name = e.file_name().to_string_lossy().into_owned();
            match setting_of(&name) {
                Some(s) if !keep.contains(&s) => {
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
