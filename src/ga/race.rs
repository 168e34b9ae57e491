//! Racing the validation (beyond the thesis): rather than scoring every top setting on every
//! validation dataset, settings are scored in rounds on the same datasets; after each round, those
//! whose paired difference to the leader lies below 0 at the rule's confidence are dropped, and the
//! survivors get more datasets, until one setting is left or the budget is spent (as F-Race and
//! irace do). Each decision depends only on stored scores, so a race ends the same on any thread
//! count or executor, and after a kill and a resume.

use crate::error::Result;
use crate::spec::RaceRule;
use crate::stats::{Paired, paired};
use serde::{Deserialize, Serialize};

/// What a round decided for a setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// The best validation mean of the round.
    Leader,
    /// Not separated from the leader: races on.
    Kept,
    /// Below the leader at the rule's confidence (or diverged where the leader did not).
    Dropped,
}

/// One setting after a round.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Standing {
    /// The setting's name, as in unit ids.
    pub setting: String,
    /// Validation mean over the round's datasets (`None`: a dataset diverged).
    pub mean: Option<f64>,
    /// The setting minus the leader, paired by dataset (`None` for the leader, or with no interval).
    pub vs_leader: Option<Paired>,
    /// What the round decided.
    pub verdict: Verdict,
}

/// One round of the race: every setting still in it, scored on validation datasets `0..datasets`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Round {
    /// 1-based.
    pub round: usize,
    /// Validation datasets each setting of the round has.
    pub datasets: usize,
    /// The round's leader.
    pub leader: String,
    /// Every setting of the round, in the order they entered the race.
    pub standings: Vec<Standing>,
}

/// Why a race ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum End {
    /// One setting is left: the leader is separated from every other at the rule's confidence.
    Separated,
    /// The validation budget (datasets per setting) is spent with several settings left.
    Budget,
}

/// A finished race.
#[derive(Debug, Clone, PartialEq)]
pub struct Race {
    /// The rounds, first to last.
    pub rounds: Vec<Round>,
    /// Why it ended.
    pub end: End,
}

impl Race {
    /// The last round's leader: the validated winner.
    pub fn winner(&self) -> &str {
        &self.rounds.last().expect("a race has a round").leader
    }

    /// The settings still in the race at its end besides the winner: not separated from it.
    pub fn indistinguishable(&self) -> Vec<String> {
        let last = self.rounds.last().expect("a race has a round");
        last.standings.iter().filter(|s| s.verdict == Verdict::Kept).map(|s| s.setting.clone()).collect()
    }
}

/// Decides round `round` among `settings`, each with its scores on the same `datasets` validation
/// datasets, in race order. The leader has the best mean (a diverged dataset counts as −∞; ties go
/// to the earlier setting, the better fitness); it is never dropped.
pub fn decide(round: usize, datasets: usize, settings: &[(&str, &[Option<f64>])], confidence: f64) -> Round {
    let means: Vec<Option<f64>> = settings
        .iter()
        .map(|(_, s)| s.iter().copied().collect::<Option<Vec<f64>>>().map(|v| v.iter().sum::<f64>() / v.len() as f64))
        .collect();
    let key = |m: Option<f64>| m.unwrap_or(f64::NEG_INFINITY);
    let lead = (0..settings.len()).fold(0, |best, i| if key(means[i]) > key(means[best]) { i } else { best });
    let standings = settings
        .iter()
        .zip(&means)
        .enumerate()
        .map(|(i, ((name, scores), mean))| {
            if i == lead {
                return Standing { setting: name.to_string(), mean: *mean, vs_leader: None, verdict: Verdict::Leader };
            }
            let vs_leader = paired(scores, settings[lead].1, confidence);
            let verdict = match (mean, means[lead], vs_leader) {
                (None, Some(_), _) => Verdict::Dropped,
                (_, _, Some(p)) if p.high() < 0.0 => Verdict::Dropped,
                _ => Verdict::Kept,
            };
            Standing { setting: name.to_string(), mean: *mean, vs_leader, verdict }
        })
        .collect();
    Round { round, datasets, leader: settings[lead].0.to_string(), standings }
}

/// Runs a race over `settings` (in race order) under `rule` with at most `budget` datasets per
/// setting. `score(survivors, n)` makes the scores of the survivors (indices into `settings`) on
/// validation datasets `0..n` available and returns them in order, or `None` when the run must
/// stop (the time budget, Ctrl-C): then the race returns `None`, and running it again replays the
/// rounds from the stored scores.
pub fn run<F>(settings: &[String], rule: &RaceRule, budget: usize, mut score: F) -> Result<Option<Race>>
where
    F: FnMut(&[usize], usize) -> Result<Option<Vec<Vec<Option<f64>>>>>,
{
    let mut alive: Vec<usize> = (0..settings.len()).collect();
    let mut n = rule.first.min(budget);
    let mut rounds = Vec::new();
    loop {
        let Some(scores) = score(&alive, n)? else { return Ok(None) };
        let named: Vec<(&str, &[Option<f64>])> =
            alive.iter().zip(&scores).map(|(&i, s)| (settings[i].as_str(), &s[..n])).collect();
        let round = decide(rounds.len() + 1, n, &named, rule.confidence);
        alive = alive
            .into_iter()
            .zip(&round.standings)
            .filter(|(_, s)| s.verdict != Verdict::Dropped)
            .map(|(i, _)| i)
            .collect();
        rounds.push(round);
        if alive.len() == 1 {
            return Ok(Some(Race { rounds, end: End::Separated }));
        }
        if n >= budget {
            return Ok(Some(Race { rounds, end: End::Budget }));
        }
        n = (n + rule.step).min(budget);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{stream, unit};

    /// A standard normal draw of the stream named by `purpose` and `indices` (Box–Muller).
    fn normal(seed: u64, purpose: &str, indices: &[u64]) -> f64 {
        let mut r = stream(seed, purpose, indices);
        let (u, v) = (1.0 - unit(&mut r), unit(&mut r));
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    const RULE: RaceRule = RaceRule { first: 5, step: 5, confidence: 0.95 };

    /// Setting `i` on dataset `k`: its true value, a dataset effect every setting shares (paired
    /// comparisons remove it) and its own noise.
    fn landscape(truth: &[f64], noise: f64) -> impl Fn(usize, usize) -> Option<f64> + '_ {
        landscape_of(99, truth, noise)
    }

    /// [`landscape`] drawn from `seed`.
    fn landscape_of(seed: u64, truth: &[f64], noise: f64) -> impl Fn(usize, usize) -> Option<f64> + '_ {
        move |i, k| {
            let shared = normal(seed, "race-test-dataset", &[k as u64]);
            Some(truth[i] + 3.0 * shared + noise * normal(seed, "race-test-noise", &[i as u64, k as u64]))
        }
    }

    fn names(n: usize) -> Vec<String> {
        (0..n).map(|i| format!("s{i}")).collect()
    }

    fn race_on(f: &dyn Fn(usize, usize) -> Option<f64>, n: usize, budget: usize) -> (Race, usize) {
        let mut units = 0;
        let race = run(&names(n), &RULE, budget, |alive, d| {
            units += alive.len() * d;
            Ok(Some(alive.iter().map(|&i| (0..d).map(|k| f(i, k)).collect()).collect()))
        })
        .unwrap()
        .unwrap();
        (race, units)
    }

    #[test]
    fn finds_the_one_clearly_better_setting_and_stops_early() {
        // Setting 3 is better by 1.0 with noise 0.5 on top of a dataset effect of 3.
        let truth = [0.0, 0.1, -0.2, 1.0, 0.05];
        let (race, _) = race_on(&landscape(&truth, 0.5), truth.len(), 40);
        assert_eq!(race.winner(), "s3");
        assert_eq!(race.end, End::Separated);
        assert!(race.rounds.last().unwrap().datasets < 40, "separated before the budget: {:?}", race.rounds);
        assert!(race.indistinguishable().is_empty());
    }

    #[test]
    fn a_flat_landscape_mostly_spends_the_budget_and_keeps_its_ties() {
        // Four equal settings, 200 landscapes: a race may drop a tie by chance (each comparison
        // errs at 2.5 % one-sided, more for a leader picked as the best of four), but rarely all.
        let truth = [0.0; 4];
        let (mut separated, mut kept) = (0, 0);
        for seed in 0..200 {
            let mut units = 0;
            let f = landscape_of(seed, &truth, 0.5);
            let race = run(&names(4), &RULE, 15, |alive, d| {
                units += alive.len() * d;
                Ok(Some(alive.iter().map(|&i| (0..d).map(|k| f(i, k)).collect()).collect()))
            })
            .unwrap()
            .unwrap();
            assert!(units <= 4 * (5 + 10 + 15));
            if race.end == End::Separated {
                separated += 1;
            } else {
                assert_eq!(race.rounds.iter().map(|r| r.datasets).collect::<Vec<_>>(), vec![5, 10, 15]);
            }
            kept += race.indistinguishable().len();
        }
        eprintln!("separated {separated}/200, kept {kept}/600");
        assert!(separated <= 20, "a flat landscape was separated {separated} times in 200");
        assert!(kept >= 450, "ties kept: {kept} of 600");
    }

    #[test]
    fn never_drops_the_leader_and_the_survivors_shrink() {
        for seed_shift in 0..20 {
            let truth: Vec<f64> = (0..6).map(|i| ((i * 7 + seed_shift) % 5) as f64 * 0.3).collect();
            let (race, _) = race_on(&landscape(&truth, 1.0), truth.len(), 30);
            let mut alive = truth.len();
            for r in &race.rounds {
                assert_eq!(r.standings.len(), alive);
                let leader = r.standings.iter().find(|s| s.setting == r.leader).unwrap();
                assert_eq!(leader.verdict, Verdict::Leader);
                // The leader has the best mean of its round.
                assert!(r.standings.iter().all(|s| s.mean.unwrap() <= leader.mean.unwrap()));
                alive = r.standings.iter().filter(|s| s.verdict != Verdict::Dropped).count();
            }
        }
    }

    #[test]
    fn a_diverged_setting_is_dropped_and_ties_go_to_the_earlier() {
        let a = [Some(1.0), Some(2.0)];
        let b = [Some(1.0), None];
        let r = decide(1, 2, &[("a", &a), ("b", &b), ("c", &a)], 0.95);
        assert_eq!(r.leader, "a");
        assert_eq!(
            r.standings.iter().map(|s| s.verdict).collect::<Vec<_>>(),
            [Verdict::Leader, Verdict::Dropped, Verdict::Kept]
        );
    }

    #[test]
    fn stopping_mid_race_returns_none_and_the_replay_is_identical() {
        let truth = [0.0, 0.4, 1.2];
        let f = landscape(&truth, 0.5);
        let (whole, _) = race_on(&f, 3, 30);
        let mut calls = 0;
        let stopped = run(&names(3), &RULE, 30, |alive, d| {
            calls += 1;
            Ok((calls < 2).then(|| alive.iter().map(|&i| (0..d).map(|k| f(i, k)).collect()).collect()))
        })
        .unwrap();
        assert!(stopped.is_none());
        let (again, _) = race_on(&f, 3, 30);
        assert_eq!(whole, again);
    }
}
