//! What a comparison is asked for (`compare`'s flags, a batch plan's compare job): the analyses,
//! the learners, the tuned config and overrides of the spec's presets, each checked against the
//! analyses it applies to.

use super::Analysis;
use crate::error::{Error, Result};
use crate::spec::LearnerKind;
use serde::{Deserialize, Serialize};

/// Which analyses a comparison runs (`--analysis`, a plan's `analysis`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum AnalysisChoice {
    /// Score and steps against iterations.
    #[default]
    Iterations,
    /// Score against complexity × iteration.
    Complexity,
    /// Last-iteration score against dataset size.
    Samples,
    /// All three.
    All,
}

impl AnalysisChoice {
    /// The analyses chosen, in report order.
    pub fn analyses(self) -> Vec<Analysis> {
        match self {
            AnalysisChoice::Iterations => vec![Analysis::Iterations],
            AnalysisChoice::Complexity => vec![Analysis::Complexity],
            AnalysisChoice::Samples => vec![Analysis::Samples],
            AnalysisChoice::All => vec![Analysis::Iterations, Analysis::Complexity, Analysis::Samples],
        }
    }

    /// Its name, as `--analysis` and a plan spell it.
    pub fn name(self) -> &'static str {
        match self {
            AnalysisChoice::Iterations => "iterations",
            AnalysisChoice::Complexity => "complexity",
            AnalysisChoice::Samples => "samples",
            AnalysisChoice::All => "all",
        }
    }
}

/// Which learners a comparison runs (`--learner`, a plan's `learner`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum LearnerChoice {
    /// Extra-Trees only.
    Et,
    /// The MLP only.
    Mlp,
    /// Extra-Trees, then the MLP.
    #[default]
    Both,
}

impl LearnerChoice {
    /// The learners chosen, in report order.
    pub fn learners(self) -> Vec<LearnerKind> {
        match self {
            LearnerChoice::Et => vec![LearnerKind::Et],
            LearnerChoice::Mlp => vec![LearnerKind::Mlp],
            LearnerChoice::Both => vec![LearnerKind::Et, LearnerKind::Mlp],
        }
    }
}

/// What a comparison is asked for besides its spec: the tuned config, the analyses, the learners and
/// overrides of the spec's presets. Declared once for `compare`'s flags and a batch plan's compare
/// jobs, whose fields are the flags' names (`"analysis": "all"`, `"complexities": [1, 2, 5]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct Request {
    /// Tuned config: `thesis` (the thesis's GA optimum) or a search's best.json.
    #[arg(long, default_value = "thesis")]
    #[serde(default = "thesis")]
    pub tuned: String,
    /// Which analyses.
    #[arg(long, value_enum, default_value_t)]
    #[serde(default)]
    pub analysis: AnalysisChoice,
    /// Which learners.
    #[arg(long, value_enum, default_value_t)]
    #[serde(default)]
    pub learner: LearnerChoice,
    /// Datasets per point (overrides the spec).
    #[arg(long)]
    pub datasets: Option<usize>,
    /// Episodes per dataset (iterations and complexity analyses).
    #[arg(long)]
    pub episodes: Option<usize>,
    /// FQI iterations K.
    #[arg(long)]
    pub iterations: Option<usize>,
    /// Complexities, as `1..15` or `1,2,5`.
    // The full path keeps clap from reading `Vec` as a repeated flag: one value, parsed whole.
    #[arg(long, value_parser = parse_complexities)]
    pub complexities: Option<::std::vec::Vec<usize>>,
    /// Dataset sizes of the sample analysis, in episodes: `10,25,50`.
    #[arg(long, value_delimiter = ',')]
    pub sizes: Option<Vec<usize>>,
}

fn thesis() -> String {
    "thesis".into()
}

/// Parses `--complexities`: `1..15` (inclusive) or `1,2,5`, each ≥ 1.
pub fn parse_complexities(text: &str) -> Result<Vec<usize>> {
    let bad = || Error::Usage("must be like 1..15 or 1,2,5 (each ≥ 1)".into());
    let v: Vec<usize> = if let Some((a, b)) = text.split_once("..") {
        let (a, b): (usize, usize) = (a.trim().parse().map_err(|_| bad())?, b.trim().parse().map_err(|_| bad())?);
        // Checked before the range is collected: 1..10^12 must be refused, not allocated.
        let points = crate::limits::SWEEP_POINTS;
        if a > b || b - a >= points {
            return Err(Error::Usage(format!("a range must be lo..hi with at most {points} values")));
        }
        (a..=b).collect()
    } else {
        text.split(',').map(|x| x.trim().parse().map_err(|_| bad())).collect::<Result<_>>()?
    };
    if v.is_empty() || v.contains(&0) {
        return Err(bad());
    }
    Ok(v)
}

impl Request {
    /// Refuses an override that the chosen analyses do not read (it would be silently ignored, and
    /// its values never checked) and values outside their range; errors name the field as a plan
    /// and the flags spell it (`complexities`, `sizes`, `episodes`).
    pub fn check(&self) -> Result<()> {
        use crate::limits::{SWEEP_POINTS, WIDTH};
        let analyses = self.analysis.analyses();
        let kind = self.analysis.name();
        let applies = |field: &str, value: String, used_by: &[Analysis], which: &str| -> Result<()> {
            if used_by.iter().any(|a| analyses.contains(a)) {
                return Ok(());
            }
            Err(Error::invalid(field, value, format!("does not apply to analysis `{kind}`: {which}; remove it")))
        };
        if let Some(c) = &self.complexities {
            applies(
                "complexities",
                format!("{c:?}"),
                &[Analysis::Complexity],
                "only the complexity analysis reads it",
            )?;
            crate::error::ensure(
                (1..=SWEEP_POINTS).contains(&c.len()) && c.iter().all(|&x| (1..=WIDTH).contains(&x)),
                "complexities",
                format!("{c:?}"),
                &format!("must list 1 to {SWEEP_POINTS} complexities, each in 1..={WIDTH} (max depths, or units)"),
            )?;
        }
        if let Some(s) = &self.sizes {
            applies("sizes", format!("{s:?}"), &[Analysis::Samples], "only the sample analysis reads it")?;
            crate::error::ensure(
                (1..=SWEEP_POINTS).contains(&s.len()) && s.iter().all(|&x| x >= 1),
                "sizes",
                format!("{s:?}"),
                &format!("must list 1 to {SWEEP_POINTS} dataset sizes, each ≥ 1 episode"),
            )?;
        }
        if let Some(e) = self.episodes {
            applies(
                "episodes",
                e.to_string(),
                &[Analysis::Iterations, Analysis::Complexity],
                "only the iterations and complexity analyses read it (the sample analysis takes `sizes`)",
            )?;
        }
        Ok(())
    }
}
