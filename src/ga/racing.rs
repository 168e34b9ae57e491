//! Racing inside the search (`search.race`, opt-in, beyond the thesis: Appendix C scores every
//! individual on every search dataset). As irace races configurations over instances and Optuna's
//! WilcoxonPruner stops a trial that loses to the best over the instances seen, a new setting is
//! scored dataset by dataset, in index order, against the generation's elites on the same
//! datasets, and stopped once a one-sided paired test (Wilcoxon signed-rank or t) says it scores
//! lower than every one of them at the rule's confidence.
//!
//! The elites are the previous generation's best `max(1, n_elites)` individuals with a finite
//! fitness (under the GA, exactly those carried over): scored in full, known before any unit of
//! the generation runs. So a verdict depends only on stored scores, in a fixed dataset order, and
//! is the same for any thread count, completion order or executor, and again after a kill and a
//! resume. An elite's setting is never raced, so an elite is never stopped. Generation 0 has no
//! elites and is never raced.
//!
//! A stopped individual keeps the scores it has, has no fitness, and is never an elite or a
//! parent, as a pruned one ([`super::prune`]).

use crate::error::{Result, ensure};
use crate::stats::PairedTest;
use serde::{Deserialize, Serialize};

/// The racing rule of a search spec (`search.race`); absent, the search does not race.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RaceRule {
    /// The one-sided paired test.
    pub test: PairedTest,
    /// A setting is stopped when its p-value against every elite is below 1 − confidence.
    pub confidence: f64,
    /// Datasets a setting runs before its first test (irace's `firstTest`).
    pub first: usize,
}

impl RaceRule {
    /// Validates the rule against the search's `datasets`; errors name the field.
    pub fn validate(&self, datasets: usize) -> Result<()> {
        ensure(
            self.confidence.is_finite() && (0.5..=0.999).contains(&self.confidence),
            "race.confidence",
            self.confidence,
            "must be in [0.5, 0.999]",
        )?;
        ensure(datasets >= 2, "race.first", self.first, "racing needs search.datasets ≥ 2")?;
        ensure(
            (2..=datasets).contains(&self.first),
            "race.first",
            self.first,
            &format!("must be in 2..={datasets} (search.datasets)"),
        )
    }

    /// The level a p-value must be below to stop a setting.
    pub fn alpha(&self) -> f64 {
        1.0 - self.confidence
    }

    /// The fewest datasets after which this rule can stop a setting: `first`, or more when the
    /// test cannot reach the level on fewer (a signed-rank test needs 2⁻ⁿ < α).
    pub fn fewest(&self) -> usize {
        self.first.max(self.test.fewest(self.alpha()))
    }
}

/// What racing decided for one individual, in `generations.jsonl`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RaceRecord {
    /// Datasets scored when it was decided: where it stopped, or all of them.
    pub datasets: usize,
    /// The p-value of the last test (the largest of those against each elite); `None` when no
    /// test was made.
    pub p: Option<f64>,
    /// Stopped: worse than every elite at the rule's confidence.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub stopped: bool,
}

impl RaceRecord {
    /// "stopped after 5 datasets: p=0.031" or "survived 10 datasets: p=0.41".
    pub fn describe(&self) -> String {
        let p = self.p.map_or("no test".into(), |p| format!("p={}", p_text(p)));
        if self.stopped {
            format!("stopped after {} datasets: {p}", self.datasets)
        } else {
            format!("survived {} datasets: {p}", self.datasets)
        }
    }
}

/// A p-value in 3 significant digits.
pub fn p_text(p: f64) -> String {
    if p == 0.0 || p >= 0.001 { format!("{p:.3}") } else { format!("{p:.2e}") }
}

/// Where a raced setting stands on its stored scores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Run this dataset next.
    Open(usize),
    /// Nothing more to run: its record keeps its first `keep` scores, and `race` says what racing
    /// decided (`None` when it diverged before any test decided).
    Done {
        /// Scores kept in its record.
        keep: usize,
        /// The race's decision.
        race: Option<RaceRecord>,
    },
}

/// The verdict on a setting's `scores` (datasets `0..scores.len()` in order, `None` = diverged)
/// out of `total`, against `elites`' scores on every dataset. The datasets are judged one by one
/// as a dataset-by-dataset evaluation would reach them, so a setting stored further (in an earlier
/// generation, or taken with `--units-from`) is decided where it would have been, and its record
/// is the same. A diverged dataset ends the setting (its fitness is −∞ whatever the rest).
pub fn judge(scores: &[Option<f64>], total: usize, elites: &[&[Option<f64>]], rule: &RaceRule) -> Verdict {
    let mut last: Option<f64> = None;
    let mut mine = Vec::with_capacity(scores.len());
    for (n, s) in scores.iter().take(total).enumerate().map(|(i, s)| (i + 1, s)) {
        let Some(v) = s else {
            let race = last.map(|p| RaceRecord { datasets: n - 1, p: Some(p), stopped: false });
            return Verdict::Done { keep: n, race };
        };
        mine.push(*v);
        if n < rule.first || elites.is_empty() {
            continue;
        }
        let p = elites.iter().map(|e| rule.test.p_less(&differences(&mine, e))).fold(0.0, f64::max);
        last = Some(p);
        if p < rule.alpha() {
            return Verdict::Done { keep: n, race: Some(RaceRecord { datasets: n, p: Some(p), stopped: true }) };
        }
    }
    if scores.len() >= total {
        Verdict::Done { keep: total, race: Some(RaceRecord { datasets: total, p: last, stopped: false }) }
    } else {
        Verdict::Open(scores.len())
    }
}

/// `mine[i] − elite[i]` over the datasets `mine` has; an elite's diverged dataset (not reachable:
/// elites have a finite fitness) counts as no evidence (difference 0).
fn differences(mine: &[f64], elite: &[Option<f64>]) -> Vec<f64> {
    mine.iter().zip(elite).map(|(m, e)| e.map_or(0.0, |e| m - e)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const WILCOXON: RaceRule = RaceRule { test: PairedTest::Wilcoxon, confidence: 0.95, first: 3 };
    const T: RaceRule = RaceRule { test: PairedTest::T, confidence: 0.95, first: 2 };

    fn some(v: &[f64]) -> Vec<Option<f64>> {
        v.iter().map(|x| Some(*x)).collect()
    }

    #[test]
    fn a_clearly_worse_setting_stops_after_the_fewest_datasets_the_test_allows() {
        let elite = some(&[100.0, 120.0, 90.0, 110.0, 105.0, 95.0, 100.0, 130.0, 80.0, 100.0]);
        let worse = some(&[10.0, 30.0, 5.0, 20.0, 15.0, 10.0, 12.0, 40.0, 1.0, 9.0]);
        // Signed-rank at 95 %: 2⁻⁴ = 0.0625 is not below 0.05, 2⁻⁵ = 0.031 is.
        assert_eq!(WILCOXON.fewest(), 5);
        for n in 0..5 {
            assert_eq!(judge(&worse[..n], 10, &[&elite], &WILCOXON), Verdict::Open(n));
        }
        let stop =
            Verdict::Done { keep: 5, race: Some(RaceRecord { datasets: 5, p: Some(1.0 / 32.0), stopped: true }) };
        assert_eq!(judge(&worse[..5], 10, &[&elite], &WILCOXON), stop);
        // Stored further (an earlier generation, --units-from): decided where it would have been.
        assert_eq!(judge(&worse, 10, &[&elite], &WILCOXON), stop);
        // The t test can decide from its second dataset on.
        assert_eq!(T.fewest(), 2);
        match judge(&worse[..2], 10, &[&elite], &T) {
            Verdict::Done { keep: 2, race: Some(r) } => assert!(r.stopped && r.p.unwrap() < 0.05, "{r:?}"),
            v => panic!("{v:?}"),
        }
    }

    #[test]
    fn a_setting_must_lose_to_every_elite() {
        let strong = some(&[100.0; 6]);
        let weak = some(&[10.0; 6]);
        let mid = some(&[50.0, 52.0, 48.0, 51.0, 49.0, 50.0]);
        // Worse than the strong elite, better than the weak one: runs on.
        assert_eq!(judge(&mid[..5], 6, &[&strong, &weak], &WILCOXON), Verdict::Open(5));
        match judge(&mid, 6, &[&strong, &weak], &WILCOXON) {
            Verdict::Done { keep: 6, race: Some(r) } => assert!(!r.stopped && r.p == Some(1.0), "{r:?}"),
            v => panic!("{v:?}"),
        }
        assert!(matches!(judge(&mid[..5], 6, &[&strong], &WILCOXON), Verdict::Done { keep: 5, .. }));
    }

    #[test]
    fn a_better_setting_survives_and_divergence_ends_a_setting() {
        let elite = some(&[100.0; 4]);
        let better = some(&[110.0, 101.0, 130.0, 100.5]);
        let v = judge(&better, 4, &[&elite], &T);
        match v {
            Verdict::Done { keep: 4, race: Some(r) } => assert!(!r.stopped && r.datasets == 4 && r.p.unwrap() > 0.8),
            v => panic!("{v:?}"),
        }
        let diverged = [Some(1.0), Some(2.0), None, Some(3.0)];
        let r = judge(&diverged, 4, &[&elite], &RaceRule { first: 2, ..WILCOXON });
        assert_eq!(r, Verdict::Done { keep: 3, race: Some(RaceRecord { datasets: 2, p: Some(0.25), stopped: false }) });
        assert_eq!(judge(&diverged, 4, &[&elite], &WILCOXON), Verdict::Done { keep: 3, race: None });
        // No elites: nothing to race against, every dataset runs.
        assert_eq!(judge(&some(&[1.0; 3]), 4, &[], &WILCOXON), Verdict::Open(3));
    }

    /// A standard normal draw of the stream named by `purpose` and `indices` (Box–Muller).
    fn normal(seed: u64, purpose: &str, indices: &[u64]) -> f64 {
        let mut r = crate::rng::stream(seed, purpose, indices);
        let (u, v) = (1.0 - crate::rng::unit(&mut r), crate::rng::unit(&mut r));
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// Setting `i`'s scores on 10 datasets: its true value, a dataset effect every setting shares
    /// (paired tests remove it) and its own noise.
    fn scores(seed: u64, truth: f64, i: u64) -> Vec<Option<f64>> {
        (0..10u64)
            .map(|k| {
                Some(
                    truth
                        + 20.0 * normal(seed, "racing-test-dataset", &[k])
                        + normal(seed, "racing-test-noise", &[i, k]),
                )
            })
            .collect()
    }

    /// Races `candidate` dataset by dataset, as the search does: the verdict after each stored unit.
    fn race(candidate: &[Option<f64>], elites: &[&[Option<f64>]], rule: &RaceRule) -> (usize, Option<RaceRecord>) {
        let mut n = 0;
        loop {
            match judge(&candidate[..n], 10, elites, rule) {
                Verdict::Open(d) => n = d + 1,
                Verdict::Done { keep, race } => return (keep, race),
            }
        }
    }

    #[test]
    fn on_a_synthetic_landscape_it_keeps_the_better_setting_and_stops_the_worse_at_the_fewest_datasets() {
        for seed in 0..50 {
            let elites: Vec<Vec<Option<f64>>> = (0..4).map(|i| scores(seed, 100.0 + i as f64 * 0.5, i)).collect();
            let refs: Vec<&[Option<f64>]> = elites.iter().map(Vec::as_slice).collect();
            for rule in [WILCOXON, RaceRule { first: 5, ..WILCOXON }, T] {
                // Clearly better than every elite: never stopped, scored on all 10 datasets.
                let (keep, r) = race(&scores(seed, 110.0, 9), &refs, &rule);
                assert_eq!(keep, 10);
                assert!(!r.unwrap().stopped, "seed {seed}: {r:?}");
                // Clearly worse: stopped at the first dataset the test can decide on.
                let (keep, r) = race(&scores(seed, 50.0, 8), &refs, &rule);
                let r = r.unwrap();
                assert!(r.stopped && keep == rule.fewest() && r.datasets == keep, "seed {seed} {rule:?}: {r:?}");
            }
            // An elite's twin (as good as the best elite) is not stopped at 95 %, seed after seed.
            let (_, r) = race(&scores(seed, 101.5, 3), &refs, &WILCOXON);
            assert!(!r.unwrap().stopped, "seed {seed}");
        }
        assert_eq!((WILCOXON.fewest(), RaceRule { first: 5, ..WILCOXON }.fewest(), T.fewest()), (5, 5, 2));
    }

    #[test]
    fn the_rule_is_checked() {
        assert!(WILCOXON.validate(10).is_ok());
        assert!(RaceRule { first: 1, ..WILCOXON }.validate(10).is_err());
        assert!(RaceRule { first: 11, ..WILCOXON }.validate(10).is_err());
        assert!(RaceRule { first: 2, ..WILCOXON }.validate(1).is_err());
        assert!(RaceRule { confidence: 1.0, ..WILCOXON }.validate(10).is_err());
        assert!(RaceRule { confidence: f64::NAN, ..WILCOXON }.validate(10).is_err());
        let e = RaceRule { first: 12, ..WILCOXON }.validate(10).unwrap_err().to_string();
        assert!(e.contains("race.first") && e.contains("2..=10"), "{e}");
    }

    #[test]
    fn decisions_read_as_the_report_shows_them() {
        let r = RaceRecord { datasets: 5, p: Some(1.0 / 32.0), stopped: true };
        assert_eq!(r.describe(), "stopped after 5 datasets: p=0.031");
        let s = RaceRecord { datasets: 10, p: Some(0.0004), stopped: false };
        assert_eq!(s.describe(), "survived 10 datasets: p=4.00e-4");
    }
}
