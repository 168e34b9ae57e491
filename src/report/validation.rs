//! The report of a validation kept apart from its search (`validate --into DIR`): `DIR/report.md`
//! says which search it read and with what rule, then gives the validation as a search's report
//! does (the table, the race, the winners, the tuned config beside the thesis optimum, the paired
//! differences), so another rule can be tried on a committed search without touching its files.

use crate::error::Result;
use crate::ga::setup::load_spec;
use crate::ga::validate::Validation;
use crate::store::write_atomic;
use std::path::Path;

/// Writes `out/report.md` for the validation `v` of the search in `source`.
pub fn write(source: &Path, out: &Path, v: &Validation) -> Result<()> {
    let spec = load_spec(source)?;
    let env = spec.env.env().name();
    let race = v.rule.race.map_or("no race".to_string(), |r| {
        format!("a race (first {}, step {}, {:.0} %)", r.first, r.step, r.confidence * 100.0)
    });
    let mut md = format!(
        "# Validation of `{}` ({env})\n\nThe search's top {} settings re-scored on up to {} validation datasets with {race}; \
         best.json here holds the setting `search.select: {}` gives. The search's own files (its validation.json, \
         best.json and report.md) are only read.\n",
        source.display(),
        v.rule.top,
        v.rule.datasets,
        v.select.name()
    );
    md.push_str(&v.markdown(env));
    md.push_str(&super::search::side_by_side(v, env));
    md.push_str(&super::search::paired_differences(v));
    write_atomic(&out.join("report.md"), |w| std::io::Write::write_all(w, md.as_bytes()))
}
