//! Starting a search: its spec resolved from the spec file, presets and [`SearchOverrides`], and
//! its run directory created; and changing the stop rules of one before resuming it.

use super::chromosome::{Chromosome, Decoded, GeneRanges};
use super::records::RunInfo;
use super::units::describe;
use crate::error::{Error, Result};
use crate::spec::Spec;
use crate::store::{self, write_json};
use crate::tuned::TunedConfig;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Creates the run directory contents of a new search: `run.json` before `spec.json`, which marks
/// a search, so a search is never seen without its record.
pub fn create(dir: &Path, spec: &Spec, info: &RunInfo) -> Result<()> {
    crate::run_dir::UnitStore::units(dir).prepare()?;
    write_json(&dir.join("run.json"), info)?;
    write_json(&dir.join("spec.json"), spec)
}

/// Copies into the new search in `dir` every unit of the run `from` that this search would
/// compute identically: whole (its checksum verifies against its own run's spec) and computed
/// under the same units hash ([`Spec::units_hash`]), which leaves out how settings are found
/// (strategy, gene ranges, GA parameters, pruning) and the stop rules. A random baseline started
/// with `--units-from` the GA search of its spec thus shares the GA's cache (its generation 0 is
/// the GA's), and a smaller or pruned search the full one's. Its validation units are copied
/// too, so settings both runs validate are not trained again; a search that differs only in its
/// stop rules replays the other's generations and validation for free. Records the copy in
/// `run.json`; returns the number of search units copied.
pub fn share_units(dir: &Path, from: &Path) -> Result<usize> {
    let spec = load_spec(dir)?;
    check_units_from(&spec, from)?;
    let source = load_spec(from)?;
    let copied = copy_units(&spec, &source, dir, from, super::units::Role::Search)?;
    let validation = copy_units(&spec, &source, dir, from, super::units::Role::Validation)?;
    let path = dir.join("run.json");
    let mut info: RunInfo = store::read_json(&path)?;
    info.units_from.push(super::records::SharedUnits {
        dir: from.display().to_string(),
        units: copied,
        validation,
        tidied: false,
    });
    write_json(&path, &info)?;
    Ok(copied)
}

/// Takes again the units `bfqi-ga tidy` removed from the search in `dir` (the runs `run.json`
/// marks `tidied`), skipping those it holds, and clears the mark: called as a search resumes, so
/// a search tidied before its end (to be kept or committed at the size of what it has used) goes
/// on exactly as if it had never been. A run gone since is said, and what it held is computed
/// (the same numbers, at their cost). Returns the unit files taken. Call it with the lock held.
pub fn retake_units(dir: &Path, quiet: bool) -> Result<usize> {
    let path = dir.join("run.json");
    let mut info: RunInfo = store::read_json(&path)?;
    if !info.units_from.iter().any(|u| u.tidied) {
        return Ok(0);
    }
    let spec = load_spec(dir)?;
    let mut taken = 0;
    for shared in info.units_from.iter_mut().filter(|u| u.tidied) {
        let from = Path::new(&shared.dir);
        match load_spec(from) {
            Ok(source) => {
                for role in [super::units::Role::Search, super::units::Role::Validation] {
                    taken += copy_units(&spec, &source, dir, from, role)?;
                }
            }
            Err(e) if !quiet => {
                eprintln!("warning: {e}: the units tidy removed are computed again instead of taken from it");
            }
            Err(_) => {}
        }
        shared.tidied = false;
    }
    write_json(&path, &info)?;
    if !quiet && taken > 0 {
        eprintln!("{taken} units taken again (tidy had removed them)");
    }
    Ok(taken)
}

/// Copies the verified units of `role` from the run `from` (of spec `source`) into the search in
/// `dir` (of spec `spec`).
fn copy_units(spec: &Spec, source: &Spec, dir: &Path, from: &Path, role: super::units::Role) -> Result<usize> {
    let theirs = super::units::Evaluator::with_role(source.clone(), from, role);
    let ours = super::units::Evaluator::with_role(spec.clone(), dir, role);
    let ids = crate::run_dir::UnitStore::named(from, role.folder()).ids();
    if !ids.is_empty() {
        crate::run_dir::UnitStore::named(dir, role.folder()).prepare()?;
    }
    let ours_hash = spec.results_hash();
    let mut copied = 0;
    for id in ids {
        if ours.unit_path(&id).is_file() || super::units::parse_unit_id(&id).is_none() {
            continue;
        }
        // `load_unit` verifies the checksum and the results hash of the run that computed it
        // (warning once about the rest); units written before they carried either (the
        // thesis-sized searches') are taken on their run's spec.json, checked above.
        let Some(mut unit) = theirs.load_unit(&id) else { continue };
        match &unit.spec_hash {
            // A unit of an older run without a checksum: stamped too, as every unit of this run
            // carries one.
            _ if unit.checksum.is_none() => {
                unit.spec_hash = Some(ours_hash.clone());
                unit.checksum = Some(unit.content_checksum());
                write_json(&ours.unit_path(&id), &unit)?;
            }
            Some(h) if *h != ours_hash => {
                // Computed under a results hash that differs from ours only in what decides no
                // unit's numbers (the units hashes agree): stamped with ours, so this run verifies it.
                unit.spec_hash = Some(ours_hash.clone());
                unit.checksum = Some(unit.content_checksum());
                write_json(&ours.unit_path(&id), &unit)?;
            }
            _ => {
                // The file's bytes, so the copy is the unit as computed.
                let path = theirs.unit_path(&id);
                let bytes = store::read_checked(&path, store::RECORD_BYTES).map_err(|r| r.at(&path))?;
                store::write_atomic(&ours.unit_path(&id), |w| std::io::Write::write_all(w, &bytes))?;
            }
        }
        copied += 1;
    }
    Ok(copied)
}

/// Gives every unit of the search in `dir` (search and validation units) that verifies and has no
/// checksum its checksum, and its run's results hash where it has none, writing the unit's
/// content unchanged; then marks `run.json` `checksummed`, so that from then on a unit without a
/// checksum is damaged. For runs made before every unit carried one (the committed references).
/// Refused if `spec.json` changed since the run began. Call it with the run's lock held.
pub fn stamp(dir: &Path) -> Result<crate::run_dir::Stamped> {
    use super::units::{Evaluator, Role};
    let spec = load_spec(dir)?;
    let path = dir.join("run.json");
    let mut info: RunInfo = store::read_json(&path)?;
    let hash = spec.run_hash();
    if let Some(h) = info.spec_hash.as_ref().filter(|h| **h != hash) {
        return Err(Error::File {
            path: dir.join("spec.json"),
            message: format!(
                "changed since the run began (results hash {hash}, run.json records {h}): stamping would vouch for \
                 units of another spec; restore it"
            ),
        });
    }
    let mut done = crate::run_dir::Stamped::default();
    for role in [Role::Search, Role::Validation] {
        let ev = Evaluator::with_role(spec.clone(), dir, role);
        for id in crate::run_dir::UnitStore::named(dir, role.folder()).ids() {
            match ev.verified(&id) {
                Ok(Some(mut u)) if u.checksum.is_none() => {
                    u.spec_hash.get_or_insert_with(|| spec.results_hash());
                    u.checksum = Some(u.content_checksum());
                    write_json(&ev.unit_path(&id), &u)?;
                    done.stamped += 1;
                }
                Ok(_) => done.already += 1,
                Err(problem) => done.unverified.push((ev.unit_path(&id), problem)),
            }
        }
    }
    info.spec_hash.get_or_insert(hash);
    info.checksummed = true;
    write_json(&path, &info)?;
    Ok(done)
}

/// Refuses `--units-from` a directory that is not a search run, or whose units were computed
/// under another units hash than `spec`'s.
pub fn check_units_from(spec: &Spec, from: &Path) -> Result<()> {
    if !from.join("units").is_dir() || !from.join("spec.json").is_file() {
        return Err(Error::File {
            path: from.to_path_buf(),
            message: "--units-from: not a search run directory (no spec.json and units/)".into(),
        });
    }
    let (h, theirs) = (spec.units_hash(), load_spec(from)?.units_hash());
    if h != theirs {
        return Err(Error::File {
            path: from.join("spec.json"),
            message: format!(
                "--units-from: its units were computed under another spec (units hash {theirs}, this search's {h}); \
                 only how settings are found (strategy, gene ranges, GA parameters, seeded individuals, pruning), \
                 the validation, the selection and the stop rules may differ"
            ),
        });
    }
    Ok(())
}

/// Overrides of a search spec, each of one spec field (see [`resolve`]). Declared once for
/// `search`'s flags and a batch plan's search jobs, whose fields are the flags' names
/// (`"stall_generations": 5`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct SearchOverrides {
    /// Generations to run.
    #[arg(long)]
    pub generations: Option<usize>,
    /// Individuals per generation.
    #[arg(long)]
    pub population: Option<usize>,
    /// Search datasets per chromosome.
    #[arg(long)]
    pub datasets: Option<usize>,
    /// FQI iterations.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Episodes per search dataset.
    #[arg(long)]
    pub episodes: Option<usize>,
    /// Master seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Stop after this many generations without improvement.
    #[arg(long)]
    pub stall_generations: Option<usize>,
    /// Place a given config in generation 0 (`thesis` or a best.json; repeatable), in place of a
    /// random individual; recorded as `seeded` in generations.jsonl.
    #[arg(long, value_name = "thesis|FILE")]
    #[serde(default)]
    pub seed_config: Vec<String>,
}

/// Resolves a spec (name or file), applies presets and overrides, validates it and creates the run
/// directory (`out`, or `<results>/<env>/search-<timestamp>`). Returns the directory.
pub fn prepare(
    spec_name: &str,
    presets: &[String],
    o: &SearchOverrides,
    out: Option<&Path>,
    results: &Path,
) -> Result<PathBuf> {
    let (spec, info) = resolve(spec_name, presets, o)?;
    store::create_run_dir(out, "spec.json", "a run", &results.join(&info.env), "search-", |d| create(d, &spec, &info))
}

/// A preset's search episodes over a `minari:<id>` one-liner, capped at what each of the data's
/// disjoint datasets holds (the one-liner sized its own to the data; `--quick`'s 200 would not
/// fit a 300-episode dataset dealt to 24 datasets), saying so.
fn fit_preset_to_data(value: &mut serde_json::Value, preset: &Path) {
    let n = |p: &str| value.pointer(p).and_then(serde_json::Value::as_u64);
    let (Some(held), Some(asked)) = (n("/data/episodes"), n("/search/episodes")) else { return };
    let slots: u64 = ["search", "validation", "compare"].iter().filter_map(|r| n(&format!("/data/slots/{r}"))).sum();
    let each = held / slots.max(1);
    if slots > 0 && each >= 1 && asked > each {
        value["search"]["episodes"] = each.into();
        crate::warn_once(&format!(
            "note: {}: search.episodes {asked} capped at {each}, the episodes each of the data's {slots} disjoint datasets holds",
            preset.display()
        ));
    }
}

/// The spec and run record a search would start with, every layer validated, creating nothing
/// (what `prepare` and a batch plan's check before it runs use).
pub fn resolve(spec_name: &str, presets: &[String], o: &SearchOverrides) -> Result<(Spec, RunInfo)> {
    // Each layer is validated as written, so an error names the file that holds it: the spec
    // file alone, then after each preset (naming the preset), then after the flags.
    let (mut value, origin) = Spec::resolve_value(spec_name)?;
    let file = Spec::from_value(value.clone(), &origin)?;
    if let Some(d) = &file.data {
        // The split is dealt by the spec file's own counts, never the flags' or presets': a
        // search and a comparison of one spec file share one deal, so their datasets stay apart.
        value["data"] = serde_json::to_value(d).expect("a spec serialises");
    }
    let mut applied = Vec::new();
    for p in presets {
        let (patch, from) = crate::spec::load_preset(p)?;
        if !patch.is_object() {
            return Err(Error::File { path: from, message: "a preset must be a JSON object of spec fields".into() });
        }
        crate::spec::merge_patch(&mut value, &patch);
        if crate::dataset::minari::named(spec_name).is_some() {
            fit_preset_to_data(&mut value, &from);
        }
        Spec::from_value(value.clone(), &from).map_err(|e| match e {
            Error::File { path, message } => {
                Error::File { path, message: format!("{message} (applied to {})", origin.display()) }
            }
            other => other,
        })?;
        applied.push(from.display().to_string());
    }
    let mut overrides = BTreeMap::new();
    let mut set = |field: &str, path: &[&str], v: Option<serde_json::Value>| {
        if let Some(v) = v {
            // Objects on the path are created where a field was left to its default; the result is
            // validated below like everything else.
            let mut slot = &mut value;
            for key in path {
                if !slot.is_object() {
                    *slot = serde_json::Value::Object(Default::default());
                }
                let serde_json::Value::Object(m) = slot else { unreachable!("made an object above") };
                slot = m.entry(key.to_string()).or_insert(serde_json::Value::Null);
            }
            *slot = v.clone();
            overrides.insert(field.to_string(), v);
        }
    };
    use serde_json::json;
    set("generations", &["search", "stop", "generations"], o.generations.map(|v| json!(v)));
    set("population", &["search", "ga", "population"], o.population.map(|v| json!(v)));
    set("datasets", &["search", "datasets"], o.datasets.map(|v| json!(v)));
    set("iterations", &["search", "iterations"], o.iterations.map(|v| json!(v)));
    set("episodes", &["search", "episodes"], o.episodes.map(|v| json!(v)));
    set("seed", &["seed"], o.seed.map(|v| json!(v)));
    set("stall_generations", &["search", "stop", "stall_generations"], o.stall_generations.map(|v| json!(v)));
    let after = |e| match e {
        Error::File { path, message } => {
            Error::File { path, message: format!("{message} (after presets and overrides)") }
        }
        other => other,
    };
    let mut spec = Spec::from_value(value.clone(), &origin).map_err(after)?;
    spec.check_search_data()
        .map_err(|e| Error::File { path: origin.clone(), message: e.to_string() })
        .map_err(after)?;
    let env = spec.env.env().name().to_string();
    if !o.seed_config.is_empty() {
        // The flags' count is the flags' fault, not the spec file's.
        let population = spec.search.ga.population;
        if o.seed_config.len() > population {
            return Err(Error::invalid(
                "--seed-config",
                format!("given {} times", o.seed_config.len()),
                format!(
                    "at most search.ga.population = {population} times (each seeds one individual of generation 0)"
                ),
            ));
        }
        // Encoded on the gene grid of the spec as resolved, then validated with it.
        let seeded = seed_chromosomes(&o.seed_config, &env, &spec.search.genes)?;
        value["search"]["seeded"] = serde_json::json!(seeded);
        overrides.insert("seed_config".into(), serde_json::json!(o.seed_config));
        spec = Spec::from_value(value, &origin).map_err(after)?;
    }
    let info = RunInfo {
        kind: "search".into(),
        env,
        spec_source: origin.display().to_string(),
        presets: applied,
        overrides,
        created: store::now_utc().1,
        version: env!("CARGO_PKG_VERSION").into(),
        commit: env!("BFQI_GA_COMMIT").into(),
        resumed: Vec::new(),
        spec_hash: Some(spec.run_hash()),
        checksummed: true,
        units_from: Vec::new(),
        machine: Some(crate::machine::Machine::this()),
        gymnasium: spec.env.env().gymnasium().map(|g| g.versions()).transpose()?,
    };
    Ok((spec, info))
}

/// The chromosomes of tuned configs (`thesis` or files) for `search.seeded`: each must be for
/// `env` and its setting must lie on the gene grid.
fn seed_chromosomes(names: &[String], env: &str, genes: &GeneRanges) -> Result<Vec<Chromosome>> {
    names
        .iter()
        .map(|name| {
            let (t, from) = TunedConfig::resolve(name, env)?;
            t.check_env(env, &from)?;
            let refuse = |message: String| Error::File { path: from.clone(), message };
            let setting = Decoded { activation: t.activation, delta_min: t.delta_min, patience: t.patience };
            super::chromosome::encode(&setting, genes).ok_or_else(|| {
                refuse(format!(
                    "its setting ({}) is not on this search's gene grid (search.genes), so it cannot join generation 0",
                    describe(&setting)
                ))
            })
        })
        .collect()
}

/// Changes the stop rules of an existing search before resuming it (they do not alter what was
/// computed, only how far it goes).
pub fn extend(dir: &Path, generations: Option<usize>, stall_generations: Option<usize>) -> Result<()> {
    let mut spec = load_spec(dir)?;
    if generations.is_none() && stall_generations.is_none() {
        return Ok(());
    }
    if let Some(g) = generations {
        spec.search.stop.generations = g;
    }
    if let Some(s) = stall_generations {
        spec.search.stop.stall_generations = Some(s);
    }
    spec.validate()?;
    write_json(&dir.join("spec.json"), &spec)
}

/// Loads the resolved spec of an existing search directory.
pub fn load_spec(dir: &Path) -> Result<Spec> {
    let path = dir.join("spec.json");
    if !path.is_file() {
        return Err(Error::File {
            path: dir.to_path_buf(),
            message: "not a search run directory (no spec.json)".into(),
        });
    }
    Spec::load_recorded(&path)
}
