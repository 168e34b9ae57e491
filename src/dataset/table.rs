//! A dataset as a table: what `bfqi-ga dataset --out X.parquet|X.csv` writes, and how logged
//! transitions are read back from such a file.
//!
//! One row per transition, in episode order: `episode`, `step` (integers), `state_0 … state_{d-1}`,
//! `action` (an integer column when every action is an index, floats otherwise), `reward`,
//! `next_state_0 … next_state_{d-1}`, `terminated` and `truncated` (0 or 1). As in Gymnasium, a
//! transition that ends its episode is `terminated` when the next state is a failure (absorbing: FQI
//! does not bootstrap from it) and `truncated` when the episode was cut (the horizon, or the end of
//! the log): FQI bootstraps through a truncation as through any other transition.

use super::Dataset;
use crate::error::{Error, Result};
use crate::table::{self, Column, Table};
use std::path::Path;

/// The dataset as a table, in the columns above.
pub fn to_table(d: &Dataset) -> Table {
    let n = d.len();
    let od = d.obs_dim;
    let mut t = Table::new();
    let ints = |v: &[u32]| Column::Int(v.iter().map(|&x| Some(i64::from(x))).collect());
    let obs = |v: &[f64], i: usize| Column::Float((0..n).map(|r| v[r * od + i]).collect());
    let ends = |r: usize| r + 1 == n || d.episode[r + 1] != d.episode[r];
    // Pushed columns have distinct names and n rows each: `push` cannot refuse them.
    let mut push = |name: &str, c: Column| t.push(name, c).expect("distinct names, equal lengths");
    push("episode", ints(&d.episode));
    push("step", ints(&d.step));
    for i in 0..od {
        push(&format!("state_{i}"), obs(&d.state, i));
    }
    let indices = d.action.iter().all(|a| a.fract() == 0.0 && a.abs() < 2f64.powi(53));
    push(
        "action",
        if indices {
            Column::Int(d.action.iter().map(|&a| Some(a as i64)).collect())
        } else {
            Column::Float(d.action.clone())
        },
    );
    push("reward", Column::Float(d.reward.clone()));
    for i in 0..od {
        push(&format!("next_state_{i}"), obs(&d.next_state, i));
    }
    push("terminated", Column::Int(d.absorbing.iter().map(|&a| Some(i64::from(a))).collect()));
    push("truncated", Column::Int((0..n).map(|r| Some(i64::from(ends(r) && !d.absorbing[r]))).collect()));
    t
}

/// Writes the dataset to `path` atomically, as Parquet or CSV by its extension.
pub fn write(d: &Dataset, path: &Path) -> Result<()> {
    let format = table::Format::of_path(path).ok_or_else(|| Error::File {
        path: path.to_path_buf(),
        message: "unknown dataset format: the name must end in .parquet, .pq or .csv".into(),
    })?;
    table::write(&to_table(d), path, format)
}

/// Reads logged transitions from a Parquet or CSV file in the columns [`to_table`] writes.
pub fn read(path: &Path) -> Result<Dataset> {
    from_table(&table::read(path)?, path)
}

/// The dataset a table holds, checked: refused, naming `path` and the column (and row), when a
/// column is missing or of the wrong type, a value is missing or not finite, a flag is not 0 or 1,
/// an episode's rows are not together with steps 0, 1, 2, …, or an episode goes on after it
/// terminated or was truncated. Episodes are numbered 0, 1, … in the order they first appear.
pub fn from_table(t: &Table, path: &Path) -> Result<Dataset> {
    let refuse = |message: String| Error::File { path: path.to_path_buf(), message };
    // Looked up by name in a map: `Table::column` per state column is quadratic in the width.
    let index: std::collections::HashMap<&str, &Column> = t.columns().collect();
    let column = |name: &str| index.get(name).copied();
    let od = (0..).take_while(|i| column(&format!("state_{i}")).is_some()).count();
    if od == 0 {
        // One line, however wide the table: its first names and the count.
        const SHOWN: usize = 20;
        let names = t.names();
        let mut has = names[..names.len().min(SHOWN)]
            .iter()
            .map(|n| crate::error::shortened(n.clone()))
            .collect::<Vec<_>>()
            .join(", ");
        if names.len() > SHOWN {
            has.push_str(&format!(", … ({} columns)", names.len()));
        }
        return Err(refuse(format!(
            "no column state_0: a dataset has the columns episode, step, state_0…, action, reward, next_state_0…, \
             terminated, truncated (it has {has})"
        )));
    }
    let numbers = |name: &str| -> Result<Vec<f64>> {
        let c = column(name).ok_or_else(|| refuse(format!("no column {name} (it has {} state columns)", od)))?;
        let v: Vec<f64> = match c {
            Column::Float(v) => v.clone(),
            Column::Int(v) => v.iter().map(|x| x.map_or(f64::NAN, |x| x as f64)).collect(),
            Column::Str(_) => return Err(refuse(format!("column {name} holds strings, not numbers"))),
        };
        match v.iter().position(|x| !x.is_finite()) {
            Some(r) => Err(refuse(format!(
                "column {name}, row {}: {} (every value must be a finite number)",
                r + 1,
                if v[r].is_nan() { "missing or NaN".to_string() } else { v[r].to_string() }
            ))),
            // The learners work in f32: a larger value would become infinite in them, and fail
            // (or mislead) far from this file.
            None => match v.iter().position(|x| x.abs() > f64::from(f32::MAX)) {
                Some(r) => Err(refuse(format!(
                    "column {name}, row {}: {:e} is beyond ±{:e}, the largest value the learners (in f32) hold",
                    r + 1,
                    v[r],
                    f32::MAX
                ))),
                None => Ok(v),
            },
        }
    };
    let counter = |name: &str| -> Result<Vec<u32>> {
        numbers(name)?
            .into_iter()
            .enumerate()
            .map(|(r, x)| {
                if x >= 0.0 && x.fract() == 0.0 && x <= f64::from(u32::MAX) {
                    Ok(x as u32)
                } else {
                    Err(refuse(format!("column {name}, row {}: {x} is not an integer in 0..={}", r + 1, u32::MAX)))
                }
            })
            .collect()
    };
    let flag = |name: &str| -> Result<Vec<bool>> {
        // Booleans as pandas (True / False), polars (true / false) and Python's csv module write
        // them: a CSV reads them as a string column.
        if let Some(Column::Str(v)) = column(name) {
            return v
                .iter()
                .enumerate()
                .map(|(r, x)| match x.as_deref().map(str::trim) {
                    Some("1" | "True" | "true" | "TRUE") => Ok(true),
                    Some("0" | "False" | "false" | "FALSE") => Ok(false),
                    other => Err(refuse(format!(
                        "column {name}, row {}: {} is not 0 or 1 (nor True or False)",
                        r + 1,
                        other.map_or("a missing value".to_string(), |s| format!("'{s}'"))
                    ))),
                })
                .collect();
        }
        numbers(name)?
            .into_iter()
            .enumerate()
            .map(|(r, x)| match x {
                0.0 => Ok(false),
                1.0 => Ok(true),
                _ => Err(refuse(format!("column {name}, row {}: {x} is not 0 or 1", r + 1))),
            })
            .collect()
    };
    if column(&format!("next_state_{od}")).is_some() {
        return Err(refuse(format!("column next_state_{od} has no state_{od}: states and next states differ in size")));
    }
    let (ids, steps) = (counter("episode")?, counter("step")?);
    let (terminated, truncated) = (flag("terminated")?, flag("truncated")?);
    let n = t.rows();
    if n == 0 {
        return Err(refuse("no transitions".into()));
    }
    let mut d = Dataset::with_capacity(od, n);
    let (states, nexts): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (
        (0..od).map(|i| numbers(&format!("state_{i}"))).collect::<Result<_>>()?,
        (0..od).map(|i| numbers(&format!("next_state_{i}"))).collect::<Result<_>>()?,
    );
    let (action, reward) = (numbers("action")?, numbers("reward")?);
    let mut seen = std::collections::HashSet::new();
    let mut episode = 0u32;
    // Episodes whose last transition is neither terminated nor truncated (the log stopped).
    let mut unflagged = 0usize;
    for r in 0..n {
        let first = r == 0 || ids[r] != ids[r - 1];
        if r + 1 == n || ids[r + 1] != ids[r] {
            unflagged += usize::from(!terminated[r] && !truncated[r]);
        }
        if first {
            if !seen.insert(ids[r]) {
                return Err(refuse(format!(
                    "column episode, row {}: episode {} appears again after other episodes (an episode's rows must \
                     be together)",
                    r + 1,
                    ids[r]
                )));
            }
            if r > 0 {
                episode += 1;
            }
        } else if terminated[r - 1] || truncated[r - 1] {
            return Err(refuse(format!(
                "row {}: episode {} goes on after it {} at row {r}",
                r + 1,
                ids[r],
                if terminated[r - 1] { "terminated" } else { "was truncated" }
            )));
        }
        let want = if first { 0 } else { steps[r - 1] + 1 };
        if steps[r] != want {
            return Err(refuse(format!(
                "column step, row {}: {} where episode {} needs step {want} (steps count 0, 1, 2, … within an episode)",
                r + 1,
                steps[r],
                ids[r]
            )));
        }
        d.episode.push(episode);
        d.step.push(steps[r]);
        d.state.extend(states.iter().map(|c| c[r]));
        d.action.push(action[r]);
        d.reward.push(reward[r]);
        d.next_state.extend(nexts.iter().map(|c| c[r]));
        d.absorbing.push(terminated[r]);
    }
    if unflagged > 0 {
        eprintln!(
            "warning: {}: {unflagged} of {} episodes end with neither terminated nor truncated: read as truncated \
             (the log stopped; FQI bootstraps from their last next state)",
            path.display(),
            episode + 1
        );
    }
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::env::EnvConfig;

    fn tmp(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("bfqi-dataset-table-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_dataset_round_trips_through_both_formats_bit_for_bit() {
        let dir = tmp("round");
        for env in ["cartpole", "pendulum", "bicycle"] {
            let c = EnvConfig::by_name(env).unwrap();
            let d = super::super::collect(c.env(), 6, 9).unwrap();
            for ext in ["parquet", "csv"] {
                let p = dir.join(format!("{env}.{ext}"));
                write(&d, &p).unwrap();
                assert_eq!(read(&p).unwrap(), d, "{env} through {ext}");
            }
        }
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn terminations_and_truncations_are_told_apart() {
        // Cart-pole's random episodes fail (terminated); the pendulum's are all cut by the horizon.
        for (env, failing) in [("cartpole", true), ("pendulum", false)] {
            let c = EnvConfig::by_name(env).unwrap();
            let d = super::super::collect(c.env(), 5, 3).unwrap();
            let t = to_table(&d);
            let Some(Column::Int(term)) = t.column("terminated") else { panic!() };
            let Some(Column::Int(trunc)) = t.column("truncated") else { panic!() };
            let ends: usize = term.iter().chain(trunc).map(|x| x.unwrap() as usize).sum();
            assert_eq!(ends, 5, "{env}: one end per episode");
            assert_eq!(term.contains(&Some(1)), failing, "{env}");
            assert_eq!(trunc.contains(&Some(1)), !failing, "{env}");
            // Discrete actions are written as integers, the pendulum's torques as floats.
            assert_eq!(matches!(t.column("action"), Some(Column::Int(_))), env == "cartpole", "{env}");
        }
    }

    fn refused(t: &Table, needle: &str) {
        let e = from_table(t, Path::new("logged.csv")).unwrap_err().to_string();
        assert!(e.contains("logged.csv") && e.contains(needle), "{e} (expected {needle})");
    }

    fn with(t: &Table, name: &str, c: Column) -> Table {
        let mut out = Table::new();
        for (n, col) in t.columns() {
            out.push(n, if n == name { c.clone() } else { col.clone() }).unwrap();
        }
        out
    }

    #[test]
    fn what_cannot_be_learned_from_is_refused_naming_the_column_and_row() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        let d = super::super::collect(c.env(), 3, 1).unwrap();
        let t = to_table(&d);
        let n = t.rows();
        let Some(Column::Float(s)) = t.column("state_1") else { panic!() };
        let mut bad = s.clone();
        bad[4] = f64::INFINITY;
        refused(&with(&t, "state_1", Column::Float(bad)), "column state_1, row 5: inf");
        let mut flags = vec![Some(0); n];
        flags[0] = Some(2);
        refused(&with(&t, "terminated", Column::Int(flags)), "column terminated, row 1: 2 is not 0 or 1");
        refused(&with(&t, "reward", Column::Str(vec![None; n])), "column reward holds strings");
        let mut steps: Vec<Option<i64>> = d.step.iter().map(|&s| Some(i64::from(s))).collect();
        steps[2] = Some(7);
        refused(&with(&t, "step", Column::Int(steps)), "column step, row 3: 7 where episode 0 needs step 2");
        // The first episode's end moved back a row: it goes on after it terminated.
        let end = d.episode.iter().position(|&e| e == 1).unwrap() - 1;
        let mut term: Vec<Option<i64>> = vec![Some(0); n];
        term[end - 1] = Some(1);
        refused(
            &with(&t, "terminated", Column::Int(term)),
            &format!("row {}: episode 0 goes on after it terminated", end + 1),
        );
        let mut ids: Vec<Option<i64>> = d.episode.iter().map(|&e| Some(i64::from(e))).collect();
        let last = ids.len() - 1;
        ids[last] = Some(0);
        let mut steps: Vec<Option<i64>> = d.step.iter().map(|&s| Some(i64::from(s))).collect();
        steps[last] = Some(0);
        refused(&with(&with(&t, "episode", Column::Int(ids)), "step", Column::Int(steps)), "episode 0 appears again");
        let mut only = Table::new();
        only.push("episode", Column::Int(vec![Some(0)])).unwrap();
        refused(&only, "no column state_0");
        // Finite in f64 but infinite in the learners' f32.
        let mut big = s.clone();
        big[2] = 1e39;
        refused(&with(&t, "state_1", Column::Float(big)), "column state_1, row 3: 1e39 is beyond");
        let mut word = vec![Some("False".to_string()); n];
        word[1] = Some("yes".into());
        refused(&with(&t, "truncated", Column::Str(word)), "column truncated, row 2: 'yes' is not 0 or 1");
    }

    #[test]
    fn booleans_as_pandas_polars_and_python_write_them_are_flags() {
        let c = EnvConfig::by_name("cartpole").unwrap();
        let d = super::super::collect(c.env(), 3, 2).unwrap();
        let t = to_table(&d);
        let words = |name: &str, yes: &str, no: &str| {
            let Some(Column::Int(v)) = t.column(name) else { panic!() };
            Column::Str(v.iter().map(|x| Some(if *x == Some(1) { yes } else { no }.to_string())).collect())
        };
        for (yes, no) in [("True", "False"), ("true", "false"), ("1", "0")] {
            let w =
                with(&with(&t, "terminated", words("terminated", yes, no)), "truncated", words("truncated", yes, no));
            assert_eq!(from_table(&w, Path::new("logged.csv")).unwrap(), d, "{yes}/{no}");
        }
    }
}
