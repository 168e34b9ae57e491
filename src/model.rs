//! Model files: a fitted Q-function (FQI's model or B-FQI's members, forests or networks) saved
//! after a run and loaded back with bit-identical predictions.
//!
//! Layout: the 8-byte magic `BFQIGA-Q`, the format version (u16, little-endian), a postcard body,
//! and an FNV-1a checksum of the body (u64, little-endian). The body holds the provenance as JSON
//! (environment settings, learner, encoding, actions, spec hash, seeds, tool version) and the
//! members in postcard's compact binary form. Postcard because its wire format is specified and
//! stable across its 1.x releases (a model written today loads with a later build), it writes
//! floats as their exact IEEE bits, and it is small, no-std-grade and actively maintained; JSON
//! would make forests of 10⁵ nodes per tree ten times larger and slow to read.

use crate::dataset::Dataset;
use crate::env::{Env, EnvConfig};
use crate::error::{Error, Result};
use crate::fqi::{Algorithm, Fqi, FqiSettings, IterationRecord, RunRecord};
use crate::learn::LearnerConfig;
use crate::learn::actions::{ActionEncoding, Encoded, QModel};
use crate::learn::extra_trees::{ExtraTrees, ForestParts};
use crate::learn::mlp::{Mlp, NetParts};
use crate::store;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The first bytes of every model file.
pub const MAGIC: &[u8; 8] = b"BFQIGA-Q";
/// The format version this build writes and reads.
pub const FORMAT_VERSION: u16 = 1;

/// Where a model came from: enough to rebuild its environment and policy, and to trace it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelInfo {
    /// bfqi-ga version that wrote the file.
    pub tool_version: String,
    /// Source commit of that build.
    pub commit: String,
    /// What produced it, e.g. `run` or `search unit tanh_6.1e-4_711.d0`.
    pub source: String,
    /// Hash of the resolved spec or run configuration that produced it.
    pub spec_hash: String,
    /// The environment with every setting.
    pub env: EnvConfig,
    /// FQI or B-FQI.
    pub algorithm: Algorithm,
    /// The learner and its settings.
    pub learner: LearnerConfig,
    /// How actions reach the learner.
    pub encoding: ActionEncoding,
    /// The discrete actions the policy maximises over.
    pub actions: Vec<f64>,
    /// Iterations fitted (K).
    pub iterations: usize,
    /// Dataset index within its role.
    pub dataset: usize,
    /// Seed of the evaluation episodes the run was scored on (rollouts of them reproduce `score`).
    pub eval_seed: u64,
    /// The score the run recorded for this Q-function.
    pub score: Option<f64>,
}

/// A fitted Q-function: its members, summed in order (one for FQI).
#[derive(Debug, Clone)]
pub enum QFunction {
    /// Extra-Trees members.
    Trees(Vec<QModel<ExtraTrees>>),
    /// Network members.
    Nets(Vec<QModel<Mlp>>),
}

impl QFunction {
    /// `Q(obs, a_j)` for every action into `out`, summing the members in order as FQI's greedy
    /// policy does; `scratch` holds at least `actions.len()` values.
    pub fn q_values(&self, obs: &[f64], actions: &[f64], scratch: &mut [f64], out: &mut [f64]) {
        out.fill(0.0);
        match self {
            QFunction::Trees(ms) => ms.iter().for_each(|m| m.add_q_values(obs, actions, scratch, out)),
            QFunction::Nets(ms) => ms.iter().for_each(|m| m.add_q_values(obs, actions, scratch, out)),
        }
    }

    /// Number of members.
    pub fn members(&self) -> usize {
        match self {
            QFunction::Trees(ms) => ms.len(),
            QFunction::Nets(ms) => ms.len(),
        }
    }
}

/// A Q-function with its provenance.
#[derive(Debug, Clone)]
pub struct Model {
    /// Where it came from.
    pub info: ModelInfo,
    /// The Q-function.
    pub q: QFunction,
}

impl Model {
    /// Q of every action at observation `obs` (allocates; for rollouts, not hot loops).
    pub fn q(&self, obs: &[f64], out: &mut [f64]) {
        let mut scratch = vec![0.0; self.info.actions.len()];
        self.q.q_values(obs, &self.info.actions, &mut scratch, out);
    }
}

/// Runs FQI or B-FQI with the learner a [`LearnerConfig`] names, on one dataset laid out for its
/// action encoding (the unit of work of `run` and `compare`), and returns the last iteration's
/// Q-function too (`None` when the run diverged: there is no Q-function worth keeping).
#[allow(clippy::too_many_arguments)]
pub fn run_keeping(
    env: &dyn Env,
    data: &Dataset,
    enc: &Encoded,
    learner: &LearnerConfig,
    settings: FqiSettings,
    fit_seed: u64,
    eval_seed: u64,
    progress: impl FnMut(&IterationRecord),
) -> Result<(RunRecord, Option<QFunction>)> {
    let (rec, q) = match learner {
        LearnerConfig::ExtraTrees(p) => {
            let (rec, ms) = Fqi::new(env, data, enc, p, settings, fit_seed, eval_seed).run_keeping(progress)?;
            (rec, QFunction::Trees(ms))
        }
        LearnerConfig::Mlp(p) => {
            let (rec, ms) = Fqi::new(env, data, enc, p, settings, fit_seed, eval_seed).run_keeping(progress)?;
            (rec, QFunction::Nets(ms))
        }
    };
    let keep = rec.diverged.is_none();
    Ok((rec, keep.then_some(q)))
}

#[derive(Serialize, Deserialize)]
enum Member<T> {
    Input(T),
    PerAction(Vec<T>),
}

#[derive(Serialize, Deserialize)]
enum Members {
    Trees(Vec<Member<ForestParts>>),
    Nets(Vec<Member<NetParts>>),
}

#[derive(Serialize, Deserialize)]
struct Body {
    /// [`ModelInfo`] as JSON: its environment and learner are tagged enums, which a
    /// non-self-describing format cannot read back.
    info: String,
    members: Members,
}

fn to_member<M, T>(m: &QModel<M>, f: impl Fn(&M) -> T) -> Member<T> {
    match m {
        QModel::Input(x) => Member::Input(f(x)),
        QModel::PerAction(xs) => Member::PerAction(xs.iter().map(f).collect()),
    }
}

fn from_member<M, T>(m: Member<T>, f: impl Fn(T) -> Result<M>) -> Result<QModel<M>> {
    Ok(match m {
        Member::Input(x) => QModel::Input(f(x)?),
        Member::PerAction(xs) => QModel::PerAction(xs.into_iter().map(f).collect::<Result<_>>()?),
    })
}

/// The file's bytes.
pub fn encode(model: &Model) -> Result<Vec<u8>> {
    let members = match &model.q {
        QFunction::Trees(ms) => Members::Trees(ms.iter().map(|m| to_member(m, ExtraTrees::to_parts)).collect()),
        QFunction::Nets(ms) => Members::Nets(ms.iter().map(|m| to_member(m, Mlp::to_parts)).collect()),
    };
    let info = serde_json::to_string(&model.info).map_err(|e| Error::Data(format!("model info: {e}")))?;
    let body = postcard::to_stdvec(&Body { info, members }).map_err(|e| Error::Data(format!("model: {e}")))?;
    let mut out = Vec::with_capacity(body.len() + 18);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&body);
    out.extend_from_slice(&store::fnv1a(&body).to_le_bytes());
    Ok(out)
}

/// Reads a model from its bytes; `path` names the file in errors (one line each).
pub fn decode(bytes: &[u8], path: &Path) -> Result<Model> {
    let refuse = |message: String| Error::File { path: path.to_path_buf(), message };
    if bytes.len() < 10 || &bytes[..8] != MAGIC {
        return Err(refuse("not a bfqi-ga model file (no BFQIGA-Q header)".into()));
    }
    let version = u16::from_le_bytes([bytes[8], bytes[9]]);
    if version != FORMAT_VERSION {
        return Err(refuse(format!(
            "model format version {version}; this bfqi-ga ({}) reads version {FORMAT_VERSION}",
            env!("CARGO_PKG_VERSION")
        )));
    }
    if bytes.len() < 18 {
        return Err(refuse("truncated model file".into()));
    }
    let (body, sum) = bytes[10..].split_at(bytes.len() - 18);
    if store::fnv1a(body).to_le_bytes() != sum {
        return Err(refuse("truncated or corrupt model file (checksum mismatch)".into()));
    }
    let body: Body = postcard::from_bytes(body).map_err(|e| refuse(format!("corrupt model file: {e}")))?;
    let info: ModelInfo = crate::error::from_json_text(&body.info, path, "model info: ")?;
    info.env.validate().map_err(|e| refuse(format!("model info: {e}")))?;
    let fix = |e: Error| refuse(format!("corrupt model: {e}"));
    let q = match body.members {
        Members::Trees(ms) => QFunction::Trees(
            ms.into_iter().map(|m| from_member(m, ExtraTrees::from_parts)).collect::<Result<_>>().map_err(fix)?,
        ),
        Members::Nets(ms) => QFunction::Nets(
            ms.into_iter().map(|m| from_member(m, Mlp::from_parts)).collect::<Result<_>>().map_err(fix)?,
        ),
    };
    let model = Model { info, q };
    check_fits(&model).map_err(|m| refuse(format!("inconsistent model: {m}")))?;
    Ok(model)
}

/// The members must take the inputs the environment and encoding give them.
fn check_fits(m: &Model) -> std::result::Result<(), String> {
    let (env, na) = (m.info.env.env(), m.info.actions.len());
    if m.info.actions != env.actions() {
        return Err(format!("actions {:?} are not the environment's {:?}", m.info.actions, env.actions()));
    }
    let (want, models) = match m.info.encoding {
        ActionEncoding::Input => (env.obs_dim() + 1, 1),
        ActionEncoding::PerAction => (env.obs_dim(), na),
    };
    let inputs: Vec<usize> = match &m.q {
        QFunction::Trees(ms) => ms.iter().flat_map(member_inputs).collect(),
        QFunction::Nets(ms) => ms.iter().flat_map(member_inputs).collect(),
    };
    if m.q.members() == 0 || inputs.len() != m.q.members() * models || inputs.iter().any(|&n| n != want) {
        return Err(format!(
            "{} members do not each hold {models} model(s) of {want} inputs ({} encoding)",
            m.q.members(),
            serde_json::to_value(m.info.encoding).map_err(|e| e.to_string())?
        ));
    }
    Ok(())
}

fn member_inputs<M: crate::learn::Regressor>(m: &QModel<M>) -> Vec<usize> {
    match m {
        QModel::Input(x) => vec![x.n_inputs()],
        QModel::PerAction(xs) => xs.iter().map(|x| x.n_inputs()).collect(),
    }
}

/// Writes a model file atomically.
pub fn save(path: &Path, model: &Model) -> Result<()> {
    let bytes = encode(model)?;
    store::write_atomic(path, |w| std::io::Write::write_all(w, &bytes))
}

/// Reads a model file; a file of another format version, truncated or damaged, is refused.
pub fn load(path: &Path) -> Result<Model> {
    let refuse = |message: String| Error::File { path: path.to_path_buf(), message };
    let size = match std::fs::metadata(path) {
        Ok(m) if m.is_file() => m.len(),
        _ => return Err(refuse("not a model file (missing or not a file)".into())),
    };
    // Read whole, so a file past the cap would claim its size in memory before any check.
    let cap = crate::limits::MODEL_BYTES;
    if size > cap {
        return Err(refuse(format!(
            "is {size} bytes ({:.1} GiB); model files are capped at {cap} bytes ({} GiB)",
            size as f64 / f64::from(1u32 << 30),
            cap >> 30
        )));
    }
    let bytes = crate::store::read_checked(path, cap).map_err(|r| r.at(path))?;
    decode(&bytes, path)
}

/// The tool version and commit that model files record.
pub fn build_stamp() -> (String, String) {
    (env!("CARGO_PKG_VERSION").to_string(), env!("BFQI_GA_COMMIT").to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::collect;
    use crate::eval::evaluate;
    use crate::learn::actions::argmax;
    use crate::learn::extra_trees::ExtraTreesParams;
    use crate::learn::mlp::MlpParams;

    fn learners() -> [LearnerConfig; 2] {
        [
            LearnerConfig::ExtraTrees(ExtraTreesParams { n_trees: 4, ..Default::default() }),
            LearnerConfig::Mlp(MlpParams { hidden: vec![6], max_epochs: 15, batch_size: 64, ..Default::default() }),
        ]
    }

    /// Every learner, algorithm and encoding: a tiny cart-pole run, saved and loaded.
    fn cases() -> Vec<(Model, Model)> {
        let env = EnvConfig::by_name("cartpole").unwrap();
        let data = collect(env.env(), 8, 11).unwrap();
        let mut out = Vec::new();
        for learner in learners() {
            for algorithm in [Algorithm::Fqi, Algorithm::Bfqi] {
                for encoding in [ActionEncoding::Input, ActionEncoding::PerAction] {
                    let enc = Encoded::new(&data, env.env().actions(), encoding).unwrap();
                    let settings = FqiSettings { algorithm, iterations: 3, eval_every: 3 };
                    let (rec, q) = run_keeping(env.env(), &data, &enc, &learner, settings, 5, 6, |_| {}).unwrap();
                    let info = ModelInfo {
                        tool_version: "test".into(),
                        commit: "test".into(),
                        source: "test".into(),
                        spec_hash: "0".into(),
                        env: env.clone(),
                        algorithm,
                        learner: learner.clone(),
                        encoding,
                        actions: env.env().actions().to_vec(),
                        iterations: 3,
                        dataset: 0,
                        eval_seed: 6,
                        score: rec.final_score(),
                    };
                    let model = Model { info, q: q.expect("a finite run keeps its Q-function") };
                    let back = decode(&encode(&model).unwrap(), Path::new("m.model")).unwrap();
                    out.push((model, back));
                }
            }
        }
        out
    }

    #[test]
    fn saved_models_predict_bit_for_bit_and_replay_the_recorded_score() {
        let mut rng = crate::rng::stream(3, "test", &[]);
        for (model, back) in cases() {
            assert_eq!(back.info, model.info);
            assert_eq!(back.q.members(), model.q.members());
            let what = format!("{} {:?} {:?}", model.info.learner.short(), model.info.algorithm, model.info.encoding);
            if model.info.algorithm == Algorithm::Bfqi {
                assert_eq!(model.q.members(), 3, "{what}: one member per iteration");
            }
            let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
            for _ in 0..200 {
                let obs: Vec<f64> = (0..4).map(|_| crate::rng::uniform(&mut rng, -2.0, 2.0)).collect();
                model.q(&obs, &mut a);
                back.q(&obs, &mut b);
                assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{what}");
            }
            // The loaded greedy policy scores what the run recorded, on the run's episodes.
            let env = back.info.env.env();
            let mut policy = |o: &[f64]| {
                let mut q = [0.0; 2];
                back.q(o, &mut q);
                argmax(&q)
            };
            let s = evaluate(env, &mut policy, back.info.eval_seed).unwrap();
            assert_eq!(Some(s.score.to_bits()), back.info.score.map(f64::to_bits), "{what}");
        }
    }

    #[test]
    fn damaged_and_foreign_files_are_refused_in_one_line() {
        let (model, _) = cases().swap_remove(0);
        let bytes = encode(&model).unwrap();
        let p = Path::new("x.model");
        let one_line = |e: Error| {
            let m = e.to_string();
            assert!(!m.contains('\n') && m.contains("x.model"), "{m}");
            m
        };
        let m = one_line(decode(&bytes[..bytes.len() / 2], p).unwrap_err());
        assert!(m.contains("truncated or corrupt"), "{m}");
        let mut flipped = bytes.clone();
        flipped[bytes.len() / 3] ^= 1;
        assert!(one_line(decode(&flipped, p).unwrap_err()).contains("checksum"));
        let mut v2 = bytes.clone();
        v2[8..10].copy_from_slice(&2u16.to_le_bytes());
        let m = one_line(decode(&v2, p).unwrap_err());
        assert!(m.contains("format version 2") && m.contains("reads version 1"), "{m}");
        assert!(one_line(decode(b"{\"json\": true}", p).unwrap_err()).contains("not a bfqi-ga model"));
        // A model whose members do not fit its environment (a cart-pole forest labelled bicycle).
        let mut foreign = model.clone();
        foreign.info.env = EnvConfig::by_name("bicycle").unwrap();
        foreign.info.actions = foreign.info.env.env().actions().to_vec();
        let m = one_line(decode(&encode(&foreign).unwrap(), p).unwrap_err());
        assert!(m.contains("inconsistent model"), "{m}");
    }
}
