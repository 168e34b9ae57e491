//! The spec's claims held against a comparison's figures: each claim is decided by the analysis
//! its rule names, and only when that analysis ran and has numbers.

use super::figures::{Line, Pair, last};
use super::tables::axis_name;
use crate::compare::LearnerPlan;
use crate::report::claims::{self, Claim, ClaimSpec};
use crate::stats::Summary;

/// Steps claims, from the last iteration's steps survived.
pub fn iterations(c: &ClaimSpec, p: &Pair) -> Option<Claim> {
    let (f, b) = (last(&p.fqi_steps)?, last(&p.bfqi_steps)?);
    match c {
        ClaimSpec::OneBalances(c) => Some(claims::one_balances(&c.statement, f, b, c.steps)),
        ClaimSpec::BothBalance(c) => Some(claims::both_balance(&c.statement, f, b, c.steps)),
        _ => None,
    }
}

/// Complexity claims, from the last-iteration score at each complexity.
pub fn complexity(c: &ClaimSpec, plan: &LearnerPlan, rows: &[(usize, Pair)]) -> Option<Claim> {
    let k = plan.iterations;
    let table = |f: fn(&Pair) -> &Line| -> Vec<(usize, Summary)> {
        rows.iter().filter_map(|(c, p)| f(p)[k - 1].1.map(|s| (*c, s))).collect()
    };
    let (tf, tb) = (table(|p| &p.fqi), table(|p| &p.bfqi));
    let what = axis_name(plan);
    match c {
        ClaimSpec::SimplerModel(c) => Some(claims::simpler_model(&c.statement, what, &tf, &tb, c.score)),
        ClaimSpec::SimilarComplexity(c) => {
            Some(claims::similar_complexity(&c.statement, what, &tf, &tb, c.score, c.tolerance))
        }
        _ => None,
    }
}

/// Dataset-size claims, from the sizes where both algorithms have a score.
pub fn samples(c: &ClaimSpec, rows: &[(usize, Pair)]) -> Option<Claim> {
    let ClaimSpec::MostlyBetter(c) = c else { return None };
    let pairs: Vec<(usize, Summary, Summary)> =
        rows.iter().filter_map(|(n, p)| Some((*n, p.fqi[0].1?, p.bfqi[0].1?))).collect();
    Some(claims::mostly_better(&c.statement, &pairs, c.share))
}
