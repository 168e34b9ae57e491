//! Running a generation's units and keeping the search's time across invocations: the executor
//! call, `state.json`, and the ETA.

use super::chromosome::Decoded;
use super::records::{IndividualRecord, Phase, RunState};
use super::units::{Evaluator, expected_cost, parse_unit_id, setting_id, unit_id};
use crate::error::Result;
use crate::exec::{Executor, Queued};
use crate::progress::{Progress, human};
use crate::run_dir::{Budget, Stop, Units};
use crate::spec::Spec;
use crate::store::{self, read_json, write_json};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

/// Timing of the search across invocations, for `state.json`, the progress line and the ETA.
pub(super) struct Clock {
    /// Completed generations' wall seconds (from earlier invocations too).
    pub(super) generation_seconds: Vec<f64>,
    /// Seconds the current generation ran in earlier invocations.
    pub(super) prior: f64,
    /// Start of the current generation in this invocation.
    pub(super) since: Instant,
    /// Expected seconds of each unit of the current generation still to run, and of those done.
    pub(super) expected: HashMap<String, f64>,
    pub(super) done_expected: f64,
    pub(super) total_expected: f64,
    pub(super) done: usize,
    pub(super) total: usize,
    /// Expected seconds of each chain's datasets not queued yet, by setting: they run unless the
    /// setting is pruned, so the generation's estimate counts them until its chain ends.
    pub(super) unqueued: HashMap<String, f64>,
    pub(super) last_write: Option<Instant>,
}

impl Clock {
    pub(super) fn resume(dir: &Path) -> Clock {
        let st: Option<RunState> = read_json(&dir.join("state.json")).ok();
        let (generation_seconds, prior) = match st {
            Some(st) if st.generation_seconds.len() == st.generation => (st.generation_seconds, st.current_seconds),
            _ => (Vec::new(), 0.0),
        };
        Clock {
            generation_seconds,
            prior,
            since: Instant::now(),
            expected: HashMap::new(),
            done_expected: 0.0,
            total_expected: 0.0,
            done: 0,
            total: 0,
            unqueued: HashMap::new(),
            last_write: None,
        }
    }

    /// Seconds of the current generation so far.
    pub(super) fn current(&self) -> f64 {
        self.prior + self.since.elapsed().as_secs_f64()
    }

    /// Adds units to run in the current generation, with their expected seconds.
    pub(super) fn plan(&mut self, units: &[(String, f64)]) {
        for (id, e) in units {
            self.expected.insert(id.clone(), *e);
            self.total_expected += e;
        }
        self.total += units.len();
    }

    pub(super) fn unit_done(&mut self, id: &str) {
        self.done += 1;
        self.done_expected += self.expected.get(id).copied().unwrap_or(0.0);
    }

    /// Sets the expected seconds of `setting`'s datasets that its chain has not queued yet (0 once
    /// the chain has ended).
    pub(super) fn set_unqueued(&mut self, setting: String, seconds: f64) {
        self.unqueued.insert(setting, seconds);
    }

    /// Projected wall seconds of the current generation: what ran, plus what is left at the rate
    /// (expected seconds per second) measured in this invocation. Left counts the queued units and
    /// the rest of every open chain, so pruning can only make the generation shorter.
    pub(super) fn projected_generation(&self) -> Option<f64> {
        let ran = self.since.elapsed().as_secs_f64();
        if self.done_expected <= 0.0 || ran <= 0.0 {
            return (self.total == 0).then(|| self.current());
        }
        let rate = self.done_expected / ran;
        let left = (self.total_expected - self.done_expected).max(0.0) + self.unqueued.values().sum::<f64>();
        Some(self.current() + left / rate)
    }

    /// Projected seconds to the end of generation `generations − 1`, from generation `g`. Later
    /// generations are expected to take the mean of generations 1 onwards once one has run:
    /// generation 0 computes every unit of every individual, later ones reuse the elites' stored
    /// units (and may prune), so including it over-reads.
    pub(super) fn eta(&self, g: usize, generations: usize) -> Option<f64> {
        let this = self.projected_generation()?;
        let past = match self.generation_seconds.as_slice() {
            [] => std::slice::from_ref(&this),
            [first] => std::slice::from_ref(first),
            [_, later @ ..] => later,
        };
        let per = past.iter().sum::<f64>() / past.len() as f64;
        Some((this - self.current()).max(0.0) + per * generations.saturating_sub(g + 1) as f64)
    }

    /// Ends generation `g` and returns its wall seconds. A generation replayed from stored units
    /// keeps the time recorded when it ran, and the generation under way keeps its earlier time.
    pub(super) fn finish_generation(&mut self, g: usize) -> f64 {
        if let Some(&recorded) = self.generation_seconds.get(g) {
            return recorded;
        }
        let secs = self.current();
        self.generation_seconds.push(secs);
        self.prior = 0.0;
        self.since = Instant::now();
        self.expected.clear();
        self.unqueued.clear();
        (self.done_expected, self.total_expected, self.done, self.total) = (0.0, 0.0, 0, 0);
        secs
    }
}

/// What `state.json` says besides the timing.
pub(super) struct StateInfo<'a> {
    pub(super) phase: Phase,
    pub(super) generation: usize,
    pub(super) best: Option<&'a IndividualRecord>,
    pub(super) reason: &'a str,
}

pub(super) fn write_state(dir: &Path, spec: &Spec, info: &StateInfo<'_>, clock: &Clock) -> Result<()> {
    let running = info.phase == Phase::Running;
    write_json(
        &dir.join("state.json"),
        &RunState {
            state: info.phase,
            generation: info.generation,
            generations: spec.search.stop.generations,
            best_fitness: info.best.and_then(|b| b.fitness),
            best: info.best.map(|b| b.decoded),
            reason: info.reason.into(),
            updated: store::now_utc().1,
            generation_seconds: clock.generation_seconds.clone(),
            current_seconds: if info.generation < spec.search.stop.generations { clock.current() } else { 0.0 },
            units_done: clock.done,
            units_total: clock.total,
            eta_seconds: if running { clock.eta(info.generation, spec.search.stop.generations) } else { None },
        },
    )
}

/// Expected seconds of each unit: the mean of its setting's stored units where there are some,
/// else [`expected_cost`] scaled by the run's seconds per unit of cost so far.
fn expected_seconds(ev: &Evaluator, ids: &[(Decoded, usize)]) -> Vec<(String, f64)> {
    let s = &ev.spec().search;
    let mut known: HashMap<String, (f64, usize)> = HashMap::new();
    let mut ratios = Vec::new();
    for id in ev.store().ids() {
        let (Some((set, _)), Some(u)) = (parse_unit_id(&id), ev.load_unit(&id)) else { continue };
        let k = known.entry(setting_id(&set)).or_insert((0.0, 0));
        (k.0, k.1) = (k.0 + u.seconds, k.1 + 1);
        ratios.push(u.seconds / expected_cost(&set, s.network.max_epochs).max(1e-9));
    }
    ratios.sort_by(f64::total_cmp);
    let per_cost = ratios.get(ratios.len() / 2).copied().unwrap_or(1.0);
    ids.iter()
        .map(|(set, d)| {
            let e = known
                .get(&setting_id(set))
                .map_or(expected_cost(set, s.network.max_epochs) * per_cost, |(t, n)| t / *n as f64);
            (unit_id(set, *d), e)
        })
        .collect()
}

/// Runs a generation's units through the executor, keeping the clock and `state.json` up to date.
pub(super) struct Runner<'a> {
    pub(super) dir: &'a Path,
    pub(super) spec: &'a Spec,
    pub(super) ev: &'a Evaluator,
    pub(super) exec: &'a dyn Executor,
    pub(super) budget: &'a Budget<'a>,
    pub(super) progress: &'a Progress,
    pub(super) clock: Mutex<Clock>,
}

impl Runner<'_> {
    /// Computes the units among `want` that are not stored yet, longest expected first. Returns why
    /// the run must stop, if it must (Ctrl-C, the budget, or units missing afterwards).
    pub(super) fn run(
        &self,
        g: usize,
        want: &[(Decoded, usize)],
        best: Option<&IndividualRecord>,
    ) -> Result<Option<Stop>> {
        let missing: Vec<(Decoded, usize)> =
            want.iter().copied().filter(|(s, d)| self.ev.load_unit(&unit_id(s, *d)).is_none()).collect();
        let mut planned = expected_seconds(self.ev, &missing);
        // Longest first (stable: ties keep setting and dataset order), so that the last units of a
        // generation are short and no core waits long for the others.
        planned.sort_by(|a, b| b.1.total_cmp(&a.1));
        self.clock.lock().expect("clock").plan(&planned);
        self.progress.add_to_stage(planned.len() as u64, true);
        let ids: Vec<String> = planned.into_iter().map(|(id, _)| id).collect();
        let done = |id: &str| self.unit_done(g, id, best);
        if let Some(stop) = self.exec.run(self.ev, &ids, self.budget, &done)? {
            return Ok(Some(stop));
        }
        Ok(self.missing(&ids))
    }

    /// `Stop::Missing` if some of `ids` are not stored after the executor ran.
    fn missing<'i>(&self, ids: impl IntoIterator<Item = &'i String>) -> Option<Stop> {
        let missing = ids.into_iter().filter(|id| self.ev.load_unit(id).is_none()).count();
        (missing > 0).then_some(Stop::Missing(missing))
    }

    /// Runs each setting's datasets as a chain: `first` holds each setting's next dataset (not
    /// stored yet), and once one is stored `next` says which dataset of that setting runs next,
    /// if any. A setting whose chain has the most expected seconds left starts first. Returns why
    /// the run must stop, as [`Runner::run`].
    pub(super) fn run_chained(
        &self,
        g: usize,
        first: &[(Decoded, usize)],
        next: &(dyn Fn(&Decoded) -> Option<usize> + Sync),
        best: Option<&IndividualRecord>,
    ) -> Result<Option<Stop>> {
        let datasets = self.spec.search.datasets;
        // A setting's units are expected to cost alike (its stored mean, or the cost model), so its
        // chain's priority is that times the datasets it has left.
        let per_setting: HashMap<String, f64> =
            first.iter().zip(expected_seconds(self.ev, first)).map(|((x, _), (_, e))| (setting_id(x), e)).collect();
        let queued: Mutex<HashMap<String, Decoded>> = Mutex::new(HashMap::new());
        let queue = |units: &[(Decoded, usize)], say: bool| -> Vec<Queued> {
            let each: Vec<f64> =
                units.iter().map(|(x, _)| per_setting.get(&setting_id(x)).copied().unwrap_or(0.0)).collect();
            let planned: Vec<(String, f64)> = units.iter().zip(&each).map(|((x, d), e)| (unit_id(x, *d), *e)).collect();
            let mut c = self.clock.lock().expect("clock");
            c.plan(&planned);
            for ((x, d), e) in units.iter().zip(&each) {
                c.set_unqueued(setting_id(x), e * datasets.saturating_sub(d + 1) as f64);
            }
            drop(c);
            self.progress.add_to_stage(planned.len() as u64, say);
            let mut q = queued.lock().expect("queued");
            units
                .iter()
                .zip(planned)
                .map(|((x, d), (id, e))| {
                    q.insert(id.clone(), *x);
                    (id, e * datasets.saturating_sub(*d) as f64)
                })
                .collect()
        };
        let first_queued = queue(first, true);
        let done = |id: &str| {
            self.unit_done(g, id, best);
            let Some(x) = queued.lock().expect("queued").get(id).copied() else { return Vec::new() };
            match next(&x) {
                Some(d) => queue(&[(x, d)], false),
                None => {
                    self.clock.lock().expect("clock").set_unqueued(setting_id(&x), 0.0);
                    Vec::new()
                }
            }
        };
        if let Some(stop) = self.exec.run_chained(self.ev, first_queued, self.budget, &done)? {
            return Ok(Some(stop));
        }
        Ok(self.missing(queued.into_inner().expect("queued").keys()))
    }

    /// Counts unit `id` of generation `g` as done: the clock, the progress line, and `state.json`
    /// (at most every 5 s).
    fn unit_done(&self, g: usize, id: &str, best: Option<&IndividualRecord>) {
        let mut c = self.clock.lock().expect("clock");
        c.unit_done(id);
        let eta = c.eta(g, self.spec.search.stop.generations);
        let gen_left = c.projected_generation().map(|p| (p - c.current()).max(0.0));
        self.progress.unit_done(&format!(
            "gen ≈ {} left · search ≈ {} left",
            gen_left.map_or("?".into(), human),
            eta.map_or("?".into(), human)
        ));
        if c.last_write.is_none_or(|t| t.elapsed().as_secs_f64() > 5.0) {
            c.last_write = Some(Instant::now());
            let info = StateInfo { phase: Phase::Running, generation: g, best, reason: "" };
            let _ = write_state(self.dir, self.spec, &info, &c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn clock(generation_seconds: Vec<f64>, ran: f64) -> Clock {
        let mut c = Clock::resume(Path::new("/nonexistent"));
        c.generation_seconds = generation_seconds;
        c.since = Instant::now().checked_sub(Duration::from_secs_f64(ran)).expect("uptime");
        c
    }

    #[test]
    fn unqueued_chain_datasets_count_until_the_chain_ends() {
        let mut c = clock(vec![], 10.0);
        c.plan(&[("a".into(), 10.0), ("b".into(), 10.0)]);
        c.unit_done("a");
        // 10 expected seconds done in 10 s: the 10 queued seconds left take about 10 s more.
        assert!((c.projected_generation().unwrap() - 20.0).abs() < 0.5);
        c.set_unqueued("x".into(), 30.0);
        assert!((c.projected_generation().unwrap() - 50.0).abs() < 0.5);
        c.set_unqueued("x".into(), 0.0);
        assert!((c.projected_generation().unwrap() - 20.0).abs() < 0.5);
        c.set_unqueued("y".into(), 5.0);
        c.finish_generation(0);
        assert!(c.unqueued.is_empty());
    }

    #[test]
    fn later_generations_are_expected_to_take_the_mean_after_generation_0() {
        // No generation finished: the current one's projection stands for the rest.
        let mut c = clock(vec![], 10.0);
        c.plan(&[("a".into(), 10.0), ("b".into(), 10.0)]);
        c.unit_done("a");
        assert!((c.eta(0, 3).unwrap() - (10.0 + 2.0 * 20.0)).abs() < 1.0);
        // Only generation 0 finished: it is all there is to go by.
        let c = clock(vec![7200.0], 0.0);
        assert!((c.eta(1, 4).unwrap() - 2.0 * 7200.0).abs() < 1.0);
        // Generation 0 computed everything; later ones set the pace.
        let c = clock(vec![7200.0, 600.0, 1200.0], 0.0);
        assert!((c.eta(3, 5).unwrap() - 900.0).abs() < 1.0);
    }
}
