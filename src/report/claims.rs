//! The thesis's claims (SPEC §6) evaluated on a comparison's numbers. Each rule is written out so a
//! reader can check the verdict by hand from the tables next to it. Which claims a comparison
//! checks, and their thresholds, come from the spec file (`experiments.<learner>.claims`).

use crate::error::{Result, ensure};
use crate::stats::Summary;
use serde::{Deserialize, Serialize};

/// A claim a spec asks a comparison to check, with the rule that decides it and its thresholds:
/// `{"rule": "simpler_model", "score": 198, "statement": "…"}`. The rule names the analysis whose
/// numbers decide it: `simpler_model` and `similar_complexity` the complexity sweep,
/// `one_balances` and `both_balance` the iterations analysis (steps survived), `mostly_better` the
/// dataset-size sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "rule", rename_all = "snake_case")]
pub enum ClaimSpec {
    /// B-FQI reaches `score` at a strictly smaller complexity than FQI.
    SimplerModel(ScoreClaim),
    /// The complexities at which each reaches `score` differ by at most `tolerance`.
    SimilarComplexity(SimilarClaim),
    /// B-FQI's mean steps at the last iteration reach `steps`, and FQI's interval lies below B-FQI's.
    OneBalances(StepsClaim),
    /// Both algorithms' mean steps at the last iteration reach `steps`.
    BothBalance(StepsClaim),
    /// B-FQI's mean is at least FQI's at a `share` of the dataset sizes or more.
    MostlyBetter(ShareClaim),
}

/// A claim with a score threshold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScoreClaim {
    /// What the thesis says.
    pub statement: String,
    /// The mean last-iteration score that counts as reaching the top.
    pub score: f64,
}

/// A claim that two complexities are close.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimilarClaim {
    /// What the thesis says.
    pub statement: String,
    /// The mean last-iteration score that counts as reaching the top.
    pub score: f64,
    /// How many complexity steps apart the two may reach it.
    pub tolerance: usize,
}

/// A claim about steps survived.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepsClaim {
    /// What the thesis says.
    pub statement: String,
    /// Mean steps at the last iteration that count as balancing.
    pub steps: f64,
}

/// A claim about how often one algorithm wins.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShareClaim {
    /// What the thesis says.
    pub statement: String,
    /// The share of sizes (0–1] B-FQI must win or tie.
    pub share: f64,
}

impl<'de> Deserialize<'de> for ClaimSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        use crate::error::tagged;
        let (rule, rest) = crate::error::take_tag(d, "rule")?;
        match rule.as_str() {
            "simpler_model" => tagged(rest).map(ClaimSpec::SimplerModel),
            "similar_complexity" => tagged(rest).map(ClaimSpec::SimilarComplexity),
            "one_balances" => tagged(rest).map(ClaimSpec::OneBalances),
            "both_balance" => tagged(rest).map(ClaimSpec::BothBalance),
            "mostly_better" => tagged(rest).map(ClaimSpec::MostlyBetter),
            other => Err(crate::error::unknown_tag(
                "rule",
                other,
                &["simpler_model", "similar_complexity", "one_balances", "both_balance", "mostly_better"],
            )),
        }
    }
}

impl ClaimSpec {
    /// Checks the thresholds; errors name the field.
    pub fn validate(&self) -> Result<()> {
        match self {
            ClaimSpec::SimplerModel(c) => ensure(c.score.is_finite(), "score", c.score, "must be a finite score"),
            ClaimSpec::SimilarComplexity(c) => {
                ensure(c.score.is_finite(), "score", c.score, "must be a finite score")?;
                crate::limits::within("tolerance", c.tolerance, 0, crate::limits::WIDTH)
            }
            ClaimSpec::OneBalances(c) | ClaimSpec::BothBalance(c) => {
                ensure(c.steps.is_finite() && c.steps >= 0.0, "steps", c.steps, "must be a finite count ≥ 0")
            }
            ClaimSpec::MostlyBetter(c) => {
                ensure(c.share > 0.0 && c.share <= 1.0, "share", c.share, "must be in (0, 1]")
            }
        }
    }
}

/// Whether a run supports a claim.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The numbers agree with the claim.
    Supported,
    /// The numbers contradict it.
    NotSupported,
}

/// A claim with its verdict and the numbers behind it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Claim {
    /// What the thesis says.
    pub statement: String,
    /// The rule applied.
    pub rule: String,
    /// The verdict.
    pub verdict: Verdict,
    /// The numbers.
    pub evidence: String,
}

/// The smallest complexity whose mean last-iteration score reaches `threshold`.
pub fn first_reaching(table: &[(usize, Summary)], threshold: f64) -> Option<usize> {
    table.iter().filter(|(_, s)| s.mean >= threshold).map(|(c, _)| *c).min()
}

fn show(c: Option<usize>) -> String {
    c.map_or("not within the sweep".to_string(), |c| c.to_string())
}

/// "B-FQI reaches the threshold with a simpler model than FQI": supported iff B-FQI reaches it at a
/// strictly smaller complexity than FQI (FQI never reaching it counts as larger).
pub fn simpler_model(
    statement: &str,
    what: &str,
    fqi: &[(usize, Summary)],
    bfqi: &[(usize, Summary)],
    threshold: f64,
) -> Claim {
    let (cf, cb) = (first_reaching(fqi, threshold), first_reaching(bfqi, threshold));
    let ok = match (cb, cf) {
        (Some(b), Some(f)) => b < f,
        (Some(_), None) => true,
        _ => false,
    };
    Claim {
        statement: statement.to_string(),
        rule: format!(
            "smallest {what} whose mean last-iteration score ≥ {threshold}: B-FQI's must be smaller than FQI's"
        ),
        verdict: if ok { Verdict::Supported } else { Verdict::NotSupported },
        evidence: format!("B-FQI reaches it at {what} {}, FQI at {}", show(cb), show(cf)),
    }
}

/// "Both algorithms perform similarly across complexity": supported iff the complexities at which
/// each first reaches the threshold differ by at most `tolerance`.
pub fn similar_complexity(
    statement: &str,
    what: &str,
    fqi: &[(usize, Summary)],
    bfqi: &[(usize, Summary)],
    threshold: f64,
    tolerance: usize,
) -> Claim {
    let (cf, cb) = (first_reaching(fqi, threshold), first_reaching(bfqi, threshold));
    let ok = matches!((cf, cb), (Some(f), Some(b)) if f.abs_diff(b) <= tolerance);
    Claim {
        statement: statement.to_string(),
        rule: format!("smallest {what} reaching {threshold}: within {tolerance} of each other"),
        verdict: if ok { Verdict::Supported } else { Verdict::NotSupported },
        evidence: format!("B-FQI at {what} {}, FQI at {}", show(cb), show(cf)),
    }
}

/// "B-FQI balances the bicycle while FQI does poorly": supported iff B-FQI's mean steps at the last
/// iteration are ≥ `good` and FQI's 95 % interval lies entirely below B-FQI's.
pub fn one_balances(statement: &str, fqi: Summary, bfqi: Summary, good: f64) -> Claim {
    let ok = bfqi.mean >= good && fqi.mean + fqi.ci95 < bfqi.mean - bfqi.ci95;
    Claim {
        statement: statement.to_string(),
        rule: format!("B-FQI mean steps ≥ {good} at the last iteration, and FQI's 95 % interval below B-FQI's"),
        verdict: if ok { Verdict::Supported } else { Verdict::NotSupported },
        evidence: format!(
            "steps at the last iteration: B-FQI {:.0} ± {:.0}, FQI {:.0} ± {:.0}",
            bfqi.mean, bfqi.ci95, fqi.mean, fqi.ci95
        ),
    }
}

/// "Both do well": supported iff both mean steps at the last iteration are ≥ `good`.
pub fn both_balance(statement: &str, fqi: Summary, bfqi: Summary, good: f64) -> Claim {
    let ok = bfqi.mean >= good && fqi.mean >= good;
    Claim {
        statement: statement.to_string(),
        rule: format!("both mean steps ≥ {good} at the last iteration"),
        verdict: if ok { Verdict::Supported } else { Verdict::NotSupported },
        evidence: format!("B-FQI {:.0} ± {:.0}, FQI {:.0} ± {:.0}", bfqi.mean, bfqi.ci95, fqi.mean, fqi.ci95),
    }
}

/// "B-FQI almost always beats FQI across dataset sizes": supported iff B-FQI's mean is at least
/// FQI's at a `share` of the sizes or more.
pub fn mostly_better(statement: &str, pairs: &[(usize, Summary, Summary)], share: f64) -> Claim {
    let wins = pairs.iter().filter(|(_, f, b)| b.mean >= f.mean).count();
    let ok = !pairs.is_empty() && wins as f64 >= share * pairs.len() as f64;
    Claim {
        statement: statement.to_string(),
        rule: format!("B-FQI's mean ≥ FQI's at ≥ {} % of the dataset sizes", share * 100.0),
        verdict: if ok { Verdict::Supported } else { Verdict::NotSupported },
        evidence: format!("B-FQI ≥ FQI at {wins} of {} sizes", pairs.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(mean: f64, ci95: f64) -> Summary {
        Summary { n: 10, mean, std: ci95, ci95 }
    }

    fn table(means: &[f64]) -> Vec<(usize, Summary)> {
        means.iter().enumerate().map(|(i, &m)| (i + 1, s(m, 1.0))).collect()
    }

    #[test]
    fn a_claim_that_holds_and_one_that_fails() {
        // Cart-pole-like: B-FQI reaches 198 at depth 5, FQI at depth 13.
        let mut fqi = vec![20.0; 15];
        fqi[12] = 198.5;
        fqi[13] = 199.0;
        fqi[14] = 199.0;
        let bfqi: Vec<f64> = (1..=15).map(|d| if d >= 5 { 199.0 } else { 50.0 }).collect();
        let c = simpler_model("B-FQI needs shallower trees", "depth", &table(&fqi), &table(&bfqi), 198.0);
        assert_eq!(c.verdict, Verdict::Supported);
        assert!(c.evidence.contains("depth 5, FQI at 13"), "{}", c.evidence);
        // Reversed roles: the claim fails.
        let c = simpler_model("B-FQI needs shallower trees", "depth", &table(&bfqi), &table(&fqi), 198.0);
        assert_eq!(c.verdict, Verdict::NotSupported);
        // Nobody reaches the threshold: not supported.
        let c = simpler_model("x", "depth", &table(&[1.0, 2.0]), &table(&[1.0, 2.0]), 198.0);
        assert_eq!(c.verdict, Verdict::NotSupported);
        assert!(c.evidence.contains("not within the sweep"));
    }

    #[test]
    fn bicycle_rules() {
        assert_eq!(one_balances("x", s(800.0, 300.0), s(4900.0, 100.0), 4500.0).verdict, Verdict::Supported);
        assert_eq!(one_balances("x", s(4000.0, 900.0), s(4900.0, 100.0), 4500.0).verdict, Verdict::NotSupported);
        assert_eq!(both_balance("x", s(4600.0, 1.0), s(5000.0, 0.0), 4500.0).verdict, Verdict::Supported);
        assert_eq!(both_balance("x", s(100.0, 1.0), s(5000.0, 0.0), 4500.0).verdict, Verdict::NotSupported);
    }

    #[test]
    fn sample_and_similarity_rules() {
        let pairs = vec![
            (10, s(-3.0, 0.1), s(-2.0, 0.1)),
            (100, s(-2.0, 0.1), s(-1.5, 0.1)),
            (1000, s(-1.0, 0.1), s(-1.1, 0.1)),
            (2000, s(-1.0, 0.1), s(-0.9, 0.1)),
        ];
        assert_eq!(mostly_better("x", &pairs, 0.75).verdict, Verdict::Supported);
        assert!(mostly_better("x", &pairs, 0.75).rule.contains("≥ 75 % of"));
        assert_eq!(mostly_better("x", &pairs, 1.0).verdict, Verdict::NotSupported);
        assert_eq!(mostly_better("x", &pairs[2..3], 0.75).verdict, Verdict::NotSupported);
        let a = table(&[100.0, 195.0, 199.0]);
        let b = table(&[100.0, 100.0, 195.0]);
        assert_eq!(similar_complexity("x", "units", &a, &b, 190.0, 1).verdict, Verdict::Supported);
        assert_eq!(similar_complexity("x", "units", &a, &b, 190.0, 0).verdict, Verdict::NotSupported);
    }
}
