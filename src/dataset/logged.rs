//! Logged transitions as the datasets runs learn from: a spec's `data`, beyond the thesis (which
//! collects random-policy episodes, SPEC §2).
//!
//! `"data": {"file": "logs.parquet"}` reads the episodes of a Parquet or CSV file in the columns
//! `bfqi-ga dataset --out` writes ([`super::table`]); relative paths are read from the working
//! directory. How the E logged episodes become every dataset the spec asks for (`data.split`):
//!
//! - `disjoint` (the default): one permutation of the episodes, drawn from `(seed, "data/split")`,
//!   is dealt round-robin to T = S + V + C slots (`data.slots`: S search, V validation and C
//!   comparison datasets, filled from the spec's counts). Slot k holds the permuted episodes
//!   k, k + T, k + 2T, …, and a dataset of n episodes is its slot's first n: no two datasets share an
//!   episode, and a smaller dataset of a slot is a prefix of a larger one (the sample analysis's
//!   nested datasets). Every slot holds at least ⌊E / T⌋ episodes; a spec asking more is refused.
//! - `bootstrap`: a dataset draws its n episodes uniformly with replacement from all E, from its own
//!   stream `(dataset seed, "data/bootstrap")`: datasets overlap, and are nested as above.
//!
//! The file's content hash (`data.hash`), its episode count and the slots are written into the
//! resolved spec (spec.json), so they are part of the units hash and a run whose file has changed
//! is refused on resume. The file is read once per process.

use super::{Dataset, Role, dataset_seed};
use crate::env::EnvConfig;
use crate::error::{Error, Result};
use crate::learn::actions::ActionEncoding;
use crate::rng::{self, stream};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};

/// A spec's `data`: where the transitions come from instead of random-policy collection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataSource {
    /// A Parquet (`.parquet`, `.pq`) or CSV (`.csv`) file of logged transitions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// Or a Minari dataset id, read with `minari.load_dataset` ([`super::minari`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub minari: Option<String>,
    /// How the logged episodes are shared out between datasets.
    #[serde(default)]
    pub split: Split,
    /// The file's content hash (FNV-1a, 64 bits), filled when the spec is resolved.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hash: Option<String>,
    /// The file's episode count, filled when the spec is resolved.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episodes: Option<usize>,
    /// Datasets per role a `disjoint` split deals to: the spec's counts unless set (set more for,
    /// say, comparisons with `--datasets` beyond the spec's). None for `bootstrap`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slots: Option<Slots>,
}

/// `data.split`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Split {
    /// Each dataset its own episodes (see the module documentation).
    #[default]
    Disjoint,
    /// Each dataset drawn with replacement from all episodes.
    Bootstrap,
}

/// `data.slots`: how many datasets of each role a `disjoint` split deals episodes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Slots {
    /// Search datasets (the GA's fitness).
    pub search: usize,
    /// Validation datasets.
    pub validation: usize,
    /// Comparison (and `run`) datasets.
    pub compare: usize,
    /// Held-out sets of an offline fitness (`search.fitness`): 1 when it is offline, else 0 (and
    /// absent, so specs written before it deal as they did).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub heldout: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl Slots {
    fn of(&self, role: Role) -> usize {
        match role {
            Role::Search => self.search,
            Role::Validation => self.validation,
            Role::Compare => self.compare,
            Role::Heldout => self.heldout,
        }
    }
    fn offset(&self, role: Role) -> usize {
        match role {
            Role::Search => 0,
            Role::Validation => self.search,
            Role::Compare => self.search + self.validation,
            Role::Heldout => self.search + self.validation + self.compare,
        }
    }
    fn noun(role: Role) -> &'static str {
        match role {
            Role::Compare => "comparison",
            Role::Heldout => "held-out",
            other => other.name(),
        }
    }
    fn total(&self) -> usize {
        self.search + self.validation + self.compare + self.heldout
    }
}

/// What a spec asks of its data: datasets per role, and the action encodings it learns with (each
/// with the field naming it).
#[derive(Debug, Clone, Default)]
pub struct Needs {
    /// Search datasets.
    pub search: usize,
    /// Validation datasets.
    pub validation: usize,
    /// Comparison datasets (the most any preset or sample analysis takes).
    pub compare: usize,
    /// Held-out sets (1 with an offline fitness).
    pub heldout: usize,
    /// `(field, encoding)` of every learner the spec configures.
    pub encodings: Vec<(String, ActionEncoding)>,
}

/// A file's transitions, with where each episode starts.
#[derive(Debug)]
struct Logged {
    data: Dataset,
    /// Row of each episode's first transition, and the row count last.
    starts: Vec<usize>,
    hash: String,
    /// What the Minari bridge said of a Minari dataset.
    minari: Option<super::minari::Info>,
}

impl Logged {
    fn episodes(&self) -> usize {
        self.starts.len() - 1
    }
}

/// The logged data read and hashed, once per process (a file again if its size or time changed).
fn load(source: &DataSource, python: &str) -> Result<Arc<Logged>> {
    type Key = (PathBuf, u64, Option<std::time::SystemTime>);
    static CACHE: OnceLock<Mutex<HashMap<Key, Arc<Logged>>>> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    let key = match (&source.file, &source.minari) {
        (Some(path), None) => {
            let meta = std::fs::metadata(path).map_err(|err| Error::Io { path: path.to_path_buf(), err })?;
            if !meta.is_file() {
                return Err(Error::File {
                    path: path.to_path_buf(),
                    message: "data.file must be a regular file".into(),
                });
            }
            (path.to_path_buf(), meta.len(), meta.modified().ok())
        }
        (None, Some(id)) => (PathBuf::from(format!("minari:{id}")), 0, None),
        _ => {
            return Err(Error::invalid(
                "data",
                "{…}",
                "must give one of file (Parquet or CSV) and minari (a dataset id)",
            ));
        }
    };
    if let Some(l) = cache.lock().expect("data cache").get(&key) {
        return Ok(l.clone());
    }
    let (hash, data, minari) = match (&source.file, &source.minari) {
        (Some(path), _) => {
            // Read first, so a file the caps refuse is refused before it is hashed.
            let data = super::table::read(path)?;
            (crate::store::fnv1a_file(path)?, data, None)
        }
        (_, Some(id)) => {
            let (hash, data, info) = super::minari::read(id, python)?;
            (hash, data, Some(info))
        }
        _ => unreachable!("checked above"),
    };
    let hash = format!("{hash:016x}");
    if data.is_empty() {
        return Err(Error::invalid(source.field(), source.origin(), "holds no transitions"));
    }
    let mut starts: Vec<usize> =
        (0..data.len()).filter(|&r| r == 0 || data.episode[r] != data.episode[r - 1]).collect();
    starts.push(data.len());
    let l = Arc::new(Logged { data, starts, hash, minari });
    cache.lock().expect("data cache").insert(key, l.clone());
    Ok(l)
}

/// The env spec a Minari dataset recorded, and its episode count, for `minari:<id>` on the
/// command line.
pub fn minari_env(id: &str) -> Result<(Option<super::minari::EnvSpec>, usize)> {
    let source = DataSource::minari(id);
    let l = load(&source, &super::minari::python(None))?;
    Ok((l.minari.as_ref().and_then(|i| i.env.clone()), l.episodes()))
}

impl DataSource {
    /// `{"minari": id}`, unresolved.
    pub fn minari(id: &str) -> Self {
        DataSource {
            file: None,
            minari: Some(id.into()),
            split: Split::default(),
            hash: None,
            episodes: None,
            slots: None,
        }
    }

    /// The field that names the data: `data.file` or `data.minari`.
    pub fn field(&self) -> &'static str {
        if self.minari.is_some() { "data.minari" } else { "data.file" }
    }

    /// The file's path or the Minari dataset's id, for messages.
    pub fn origin(&self) -> String {
        match (&self.file, &self.minari) {
            (Some(p), _) => p.display().to_string(),
            (_, Some(id)) => id.clone(),
            _ => "nothing".into(),
        }
    }

    /// Reads the data and fills `hash`, `episodes` and (for `disjoint`) `slots`; refuses, naming
    /// the field, data that changed since they were recorded, observations that are not the
    /// env's, and logged actions a `per_action` encoding cannot learn. Whether the episodes
    /// suffice is [`Self::check`]ed by what uses a role's datasets (a search its search and
    /// validation datasets, a comparison its own), once its flags apply.
    pub fn resolve(&mut self, env: &EnvConfig, needs: &Needs) -> Result<()> {
        if self.file.is_some() == self.minari.is_some() {
            return Err(Error::invalid(
                "data",
                if self.file.is_some() { "file and minari" } else { "neither file nor minari" },
                "must give one of file (Parquet or CSV) and minari (a dataset id)",
            ));
        }
        let l = load(self, &super::minari::python(Some(env)))?;
        let file = self.origin();
        if let Some(h) = &self.hash
            && *h != l.hash
        {
            return Err(Error::invalid(
                "data.hash",
                h,
                format!("{file} now hashes {}: it is not the data this spec was made from", l.hash),
            ));
        }
        if let Some(e) = self.episodes
            && e != l.episodes()
        {
            return Err(Error::invalid("data.episodes", e, format!("{file} holds {} episodes", l.episodes())));
        }
        let e = env.env();
        if l.data.obs_dim != e.obs_dim() {
            return Err(Error::invalid(
                self.field(),
                &file,
                format!("has {} observation values; {} observes {} values", l.data.obs_dim, e.name(), e.obs_dim()),
            ));
        }
        let actions = e.actions();
        if let Some(r) = l.data.action.iter().position(|a| !actions.contains(a))
            && let Some((field, _)) = needs.encodings.iter().find(|(_, enc)| *enc == ActionEncoding::PerAction)
        {
            return Err(Error::invalid(
                field,
                "per_action",
                format!(
                    "needs every logged action among {}'s actions {actions:?}; {file} has action {} at row {r}: \
                     learn logged actions with \"input\" (the greedy policy still picks among the env's actions)",
                    e.name(),
                    l.data.action[r]
                ),
            ));
        }
        self.hash = Some(l.hash.clone());
        self.episodes = Some(l.episodes());
        match self.split {
            Split::Bootstrap => {
                if self.slots.is_some() {
                    return Err(Error::invalid("data.slots", "set", "applies to split \"disjoint\" only"));
                }
                if needs.heldout > 0 {
                    return Err(Error::invalid(
                        "data.split",
                        "bootstrap",
                        "draws every dataset from all episodes, so none is held out: an offline fitness \
                         (search.fitness) needs \"disjoint\"",
                    ));
                }
            }
            Split::Disjoint => {
                // Slots the spec file sets are kept (fewer comparison slots than a sample
                // analysis it never runs, say); a role asking more is refused where it is used.
                let asked = Slots {
                    search: needs.search,
                    validation: needs.validation,
                    compare: needs.compare,
                    heldout: needs.heldout,
                };
                self.slots.get_or_insert(asked);
            }
        }
        Ok(())
    }

    /// One sentence for reports: where the datasets come from and how they were dealt.
    pub fn describe(&self) -> String {
        let how = match (self.split, self.slots) {
            (Split::Disjoint, Some(s)) => format!(
                "dealt without overlap to {} search, {} validation and {} comparison datasets",
                s.search, s.validation, s.compare
            ),
            _ => "each dataset drawn with replacement (bootstrap)".into(),
        };
        let from = match &self.minari {
            Some(id) => format!("the Minari dataset `{id}`"),
            None => format!("`{}`", self.origin()),
        };
        format!(
            "**Beyond the thesis: logged data.** Datasets come from {from} ({} episodes, content hash {}), {how}; \
             not from random-policy collection (`data`).",
            self.episodes.unwrap_or(0),
            self.hash.as_deref().unwrap_or("?")
        )
    }

    /// Refuses `datasets` datasets of `episodes` episodes of a role that the split cannot give,
    /// naming the data's fields and what would fit.
    pub fn check(&self, role: Role, datasets: usize, episodes: usize) -> Result<()> {
        let file = self.origin();
        let logged = self.episodes.unwrap_or(0);
        match (self.split, self.slots) {
            (Split::Disjoint, Some(s)) => {
                if datasets > s.of(role) {
                    return Err(Error::invalid(
                        format!("data.slots.{}", role.name()),
                        s.of(role),
                        format!(
                            "{datasets} {} datasets are asked: raise it (a new split of the episodes) or ask fewer",
                            Slots::noun(role)
                        ),
                    ));
                }
                let each = logged / s.total().max(1);
                if episodes > each {
                    return Err(Error::invalid(
                        self.field(),
                        file,
                        format!(
                            "holds {logged} episodes, dealt to {} disjoint datasets ({} search, {} validation, {} \
                             comparison) of at least {each} episodes; {} datasets of {episodes} episodes are asked: \
                             ask fewer episodes, or use \"split\": \"bootstrap\"",
                            s.total(),
                            s.search,
                            s.validation,
                            s.compare,
                            Slots::noun(role)
                        ),
                    ));
                }
                Ok(())
            }
            (Split::Disjoint, None) => Err(Error::invalid("data.slots", "absent", "the spec was not resolved")),
            (Split::Bootstrap, _) => Ok(()),
        }
    }

    /// The episodes the data holds, read (and cached) as [`Self::resolve`] reads it.
    pub fn held_episodes(&self, python: &str) -> Result<usize> {
        Ok(load(self, python)?.episodes())
    }

    /// Every logged transition, in the data's own order: `bfqi-ga dataset` of logged data
    /// without `--episodes`.
    pub fn whole(&self, python: &str) -> Result<Dataset> {
        Ok(load(self, python)?.data.clone())
    }

    /// The refusal of a logged dataset too small to learn from (`why`: an action it lacks, a network
    /// without two rows), naming the data and how many episodes it holds against those asked:
    /// with logged data, more episodes per dataset cannot help beyond what the data holds.
    pub fn too_few(&self, role: Role, index: usize, episodes: usize, why: &str) -> Error {
        let logged = self.episodes.unwrap_or(0);
        Error::invalid(
            self.field(),
            self.origin(),
            format!(
                "holds {logged} episode(s): {} dataset {index} of {episodes} episode(s) taken from them is too small ({why}); \
                 log more episodes (every action's transitions, at least 2 for each network)",
                Slots::noun(role)
            ),
        )
    }

    /// Dataset `index` of a role, of `episodes` episodes, under master seed `master` (see the module
    /// documentation). Episodes are renumbered 0, 1, … in the order taken.
    pub fn dataset(&self, master: u64, role: Role, index: usize, episodes: usize) -> Result<Dataset> {
        let l = load(self, &super::minari::python(None))?;
        if self.hash.as_deref() != Some(l.hash.as_str()) {
            return Err(Error::invalid(
                "data.hash",
                self.hash.as_deref().unwrap_or("absent"),
                format!("{} now hashes {}: it is not the data this spec was made from", self.origin(), l.hash),
            ));
        }
        self.check(role, index + 1, episodes)?;
        let e = l.episodes();
        let picked: Vec<usize> = match (self.split, self.slots) {
            (Split::Disjoint, Some(s)) => {
                let perm = permutation(e, master);
                let (k, t) = (s.offset(role) + index, s.total());
                (0..episodes).map(|j| perm[k + j * t]).collect()
            }
            _ => {
                let mut rng = stream(dataset_seed(master, role, index), rng::purpose::DATA_BOOTSTRAP, &[]);
                (0..episodes).map(|_| rng::below(&mut rng, e as u64) as usize).collect()
            }
        };
        Ok(gather(&l, &picked))
    }
}

/// The split's permutation of `n` episodes (Fisher–Yates from `(master, "data/split")`).
fn permutation(n: usize, master: u64) -> Vec<usize> {
    let mut rng = stream(master, rng::purpose::DATA_SPLIT, &[]);
    let mut p: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        p.swap(i, rng::below(&mut rng, i as u64 + 1) as usize);
    }
    p
}

/// The logged episodes `picked`, in that order, numbered 0, 1, ….
fn gather(l: &Logged, picked: &[usize]) -> Dataset {
    let od = l.data.obs_dim;
    let rows: usize = picked.iter().map(|&e| l.starts[e + 1] - l.starts[e]).sum();
    let mut out = Dataset::with_capacity(od, rows);
    let d = &l.data;
    for (new, &e) in picked.iter().enumerate() {
        let (a, b) = (l.starts[e], l.starts[e + 1]);
        out.episode.extend(std::iter::repeat_n(new as u32, b - a));
        out.step.extend_from_slice(&d.step[a..b]);
        out.state.extend_from_slice(&d.state[a * od..b * od]);
        out.action.extend_from_slice(&d.action[a..b]);
        out.reward.extend_from_slice(&d.reward[a..b]);
        out.next_state.extend_from_slice(&d.next_state[a * od..b * od]);
        out.absorbing.extend_from_slice(&d.absorbing[a..b]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::collect;
    use std::path::Path;

    /// A cart-pole log of `episodes` episodes written to a fresh file, and its collected dataset.
    fn log(name: &str, episodes: usize) -> (PathBuf, Dataset) {
        let dir = std::env::temp_dir().join(format!("bfqi-logged-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("log.parquet");
        let c = EnvConfig::by_name("cartpole").unwrap();
        let d = collect(c.env(), episodes, 11).unwrap();
        super::super::table::write(&d, &path).unwrap();
        (path, d)
    }

    fn needs(search: usize, validation: usize, compare: usize) -> Needs {
        Needs {
            search,
            validation,
            compare,
            heldout: 0,
            encodings: vec![("search.actions".into(), ActionEncoding::PerAction)],
        }
    }

    fn source(path: &Path, split: Split) -> DataSource {
        DataSource { file: Some(path.to_path_buf()), minari: None, split, hash: None, episodes: None, slots: None }
    }

    /// The transitions of each episode of `d`, as rows of bits, to compare episodes exactly.
    fn episodes(d: &Dataset) -> Vec<Vec<u64>> {
        let od = d.obs_dim;
        let mut out: Vec<Vec<u64>> = vec![Vec::new(); d.episodes()];
        for r in 0..d.len() {
            let e = &mut out[d.episode[r] as usize];
            e.extend(d.state[r * od..(r + 1) * od].iter().map(|x| x.to_bits()));
            e.extend([d.action[r].to_bits(), d.reward[r].to_bits(), u64::from(d.absorbing[r])]);
            e.extend(d.next_state[r * od..(r + 1) * od].iter().map(|x| x.to_bits()));
        }
        out
    }

    #[test]
    fn a_disjoint_split_deals_whole_logged_episodes_nested_and_never_shared() {
        let (path, logged) = log("disjoint", 60);
        let c = EnvConfig::by_name("cartpole").unwrap();
        let mut s = source(&path, Split::Disjoint);
        s.resolve(&c, &needs(3, 2, 4)).unwrap();
        assert_eq!(s.episodes, Some(60));
        assert_eq!(s.slots, Some(Slots { search: 3, validation: 2, compare: 4, heldout: 0 }));
        let all = episodes(&logged);
        let mut seen = std::collections::HashSet::new();
        for (role, n) in [(Role::Search, 3), (Role::Validation, 2), (Role::Compare, 4)] {
            for i in 0..n {
                let big = s.dataset(7, role, i, 6).unwrap();
                assert_eq!(big.episodes(), 6);
                let eps = episodes(&big);
                for e in &eps {
                    assert!(all.contains(e), "every episode is a logged one, bit for bit");
                    assert!(seen.insert(e.clone()), "no episode is in two datasets");
                }
                let small = s.dataset(7, role, i, 2).unwrap();
                assert_eq!(episodes(&small), eps[..2], "a smaller dataset is a prefix of its slot's");
            }
        }
        // Seeded: the same master deals alike, another deals otherwise.
        assert_eq!(s.dataset(7, Role::Search, 0, 6).unwrap(), s.dataset(7, Role::Search, 0, 6).unwrap());
        assert_ne!(s.dataset(7, Role::Search, 0, 6).unwrap(), s.dataset(8, Role::Search, 0, 6).unwrap());
        // ⌊60 / 9⌋ = 6 episodes per dataset; 7 are refused, naming the file and the way out.
        let e = s.dataset(7, Role::Compare, 0, 7).unwrap_err().to_string();
        assert!(e.contains("data.file") && e.contains("holds 60 episodes") && e.contains("bootstrap"), "{e}");
        let e = s.dataset(7, Role::Compare, 4, 2).unwrap_err().to_string();
        assert!(e.contains("data.slots.compare"), "{e}");
    }

    #[test]
    fn a_bootstrap_split_draws_logged_episodes_with_replacement_nested() {
        let (path, logged) = log("bootstrap", 8);
        let c = EnvConfig::by_name("cartpole").unwrap();
        let mut s = source(&path, Split::Bootstrap);
        s.resolve(&c, &needs(2, 0, 2)).unwrap();
        assert_eq!(s.slots, None);
        let all = episodes(&logged);
        let big = s.dataset(3, Role::Search, 0, 40).unwrap();
        let eps = episodes(&big);
        assert!(eps.iter().all(|e| all.contains(e)));
        let distinct: std::collections::HashSet<_> = eps.iter().collect();
        assert!(distinct.len() < 40, "40 draws from 8 episodes repeat some");
        assert_eq!(episodes(&s.dataset(3, Role::Search, 0, 5).unwrap()), eps[..5]);
        assert_ne!(s.dataset(3, Role::Search, 1, 40).unwrap(), big, "each dataset draws its own");
    }

    #[test]
    fn data_that_does_not_fit_the_spec_is_refused_naming_the_field() {
        let (path, _) = log("refusals", 12);
        let cartpole = EnvConfig::by_name("cartpole").unwrap();
        // Observations of another env.
        let bicycle = EnvConfig::by_name("bicycle").unwrap();
        let e = source(&path, Split::Disjoint).resolve(&bicycle, &needs(1, 0, 1)).unwrap_err().to_string();
        assert!(e.contains("data.file") && e.contains("observation values"), "{e}");
        // Actions outside the env's set cannot be learnt per action.
        let mut d = super::super::table::read(&path).unwrap();
        d.action[3] = 0.5;
        let odd = path.with_file_name("odd.csv");
        super::super::table::write(&d, &odd).unwrap();
        let e = source(&odd, Split::Disjoint).resolve(&cartpole, &needs(1, 0, 1)).unwrap_err().to_string();
        assert!(e.contains("search.actions") && e.contains("row 3") && e.contains("input"), "{e}");
        let input = Needs { encodings: vec![("search.actions".into(), ActionEncoding::Input)], ..needs(1, 0, 1) };
        source(&odd, Split::Disjoint).resolve(&cartpole, &input).unwrap();
        // A recorded hash the file no longer has.
        let mut s = source(&path, Split::Disjoint);
        s.hash = Some("0123456789abcdef".into());
        let e = s.resolve(&cartpole, &needs(1, 0, 1)).unwrap_err().to_string();
        assert!(e.contains("data.hash") && e.contains("not the data"), "{e}");
        // Slots set in the spec are kept; a role asking more datasets is refused where it is used.
        let mut s = source(&path, Split::Disjoint);
        s.slots = Some(Slots { search: 1, validation: 0, compare: 1, heldout: 0 });
        s.resolve(&cartpole, &needs(2, 0, 1)).unwrap();
        let e = s.check(Role::Search, 2, 1).unwrap_err().to_string();
        assert!(e.contains("data.slots.search") && e.contains("2 search datasets"), "{e}");
    }
}
