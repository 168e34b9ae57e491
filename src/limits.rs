//! The sizes bfqi-ga accepts. Each cap is far above anything the thesis or a researcher's run needs
//! and below what would exhaust a machine's memory or run for centuries: a value past it is refused
//! at validation, naming the field and the allowed range, instead of aborting on an allocation
//! failure hours later (or on every `--resume`).

use crate::error::{Result, ensure};

/// Datasets of a run, a search or a comparison point.
pub const DATASETS: usize = 10_000;
/// Individuals per generation.
pub const POPULATION: usize = 10_000;
/// Generations of a search.
pub const GENERATIONS: usize = 1_000_000;
/// FQI iterations K.
pub const ITERATIONS: usize = 100_000;
/// Transitions of one dataset at most (episodes × the environment's horizon): about 2 GB of
/// transitions, 50 times the thesis's largest (pendulum, 2000 × 200).
pub const TRANSITIONS: usize = 20_000_000;
/// Trees of a forest.
pub const TREES: usize = 10_000;
/// Units of one hidden layer (also the largest network complexity).
pub const WIDTH: usize = 4096;
/// Hidden layers.
pub const LAYERS: usize = 16;
/// Training epochs of one fit.
pub const EPOCHS: usize = 10_000_000;
/// Points of a complexity or dataset-size sweep.
pub const SWEEP_POINTS: usize = 1000;
/// Evaluation episodes, and steps per evaluation episode.
pub const EVAL_EPISODES: usize = 1_000_000;
/// See [`EVAL_EPISODES`].
pub const EVAL_STEPS: usize = 10_000_000;
/// Worker threads (`--jobs`).
pub const JOBS: usize = 1024;
/// Settings a search's validation re-scores (`search.validate.top`, `validate --top`).
pub const VALIDATE_TOP: usize = 100;
/// Validation datasets of a search's validation (`search.validate.datasets`, `validate --datasets`;
/// with a race, the most any setting gets).
pub const VALIDATE_DATASETS: usize = 1000;
/// Bytes of a model file (4 GiB), checked before it is read whole: 25 times the largest model the
/// thesis's settings give (the bicycle's B-FQI on Extra-Trees, 20 members × 50 trees, 165 MB).
pub const MODEL_BYTES: u64 = 4 << 30;

/// Rows of a table file read (`data.file`, a table `export` wrote): as many as the transitions of
/// the largest dataset.
pub const TABLE_ROWS: usize = TRANSITIONS;
/// Columns of a table file read.
pub const TABLE_COLUMNS: usize = 100_000;
/// Values (rows × columns) of a table file read: 4 GB as doubles.
pub const TABLE_CELLS: usize = 500_000_000;
/// Bytes of a table file, checked before it is opened.
pub const TABLE_BYTES: u64 = 16 << 30;

/// `lo ≤ v ≤ hi`, or an error naming `field` and the range.
pub fn within(field: &str, v: usize, lo: usize, hi: usize) -> Result<()> {
    ensure((lo..=hi).contains(&v), field, v, &format!("must be in {lo}..={hi}"))
}

/// A dataset of `episodes` episodes of at most `horizon` steps stays under [`TRANSITIONS`].
pub fn episodes(field: &str, episodes: usize, horizon: usize) -> Result<()> {
    let max = (TRANSITIONS / horizon.max(1)).max(1);
    ensure(
        (1..=max).contains(&episodes),
        field,
        episodes,
        &format!("must be in 1..={max} (episodes × the horizon of {horizon} steps ≤ {TRANSITIONS} transitions)"),
    )
}
