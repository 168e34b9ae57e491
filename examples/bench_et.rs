//! Times Extra-Trees on the thesis settings, to compare with `/work/shared/bench/sklearn_et.py`.
//!
//! Rows are [state, action] of a random-policy dataset; targets are the rewards (the first FQI
//! iteration, as the sklearn anchor) and, as a harder case, a smooth stand-in for a later iteration's
//! target (reward + a function of the next state).
//!
//! `actions` times `predict_actions_into` (Q of every action at every next state, as FQI asks it) on
//! forests fitted to the rewards and to a second FQI iteration's targets: the trait's default (one
//! row per action) against the forest's own (one forked walk per tree), in a batch and per state.
//!
//!   cargo run --release --example bench_et [bicycle|pendulum|cartpole|all] [repeats] [fit|actions|all]

use bfqi_ga::dataset::collect;
use bfqi_ga::env::EnvConfig;
use bfqi_ga::learn::extra_trees::{ExtraTrees, ExtraTreesParams};
use bfqi_ga::learn::{Learner, Regressor, Rows};
use std::time::Instant;

/// CPU seconds used by all threads of this process so far (Linux), to see through a busy machine.
fn cpu_seconds() -> f64 {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return f64::NAN;
    };
    tasks
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .sum::<f64>()
        * 1e-9
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The forest with the trait's default `predict_actions_into`: builds each [state, action] row.
struct DefaultPath<'a>(&'a ExtraTrees);

impl Regressor for DefaultPath<'_> {
    fn n_inputs(&self) -> usize {
        self.0.n_inputs()
    }
    fn predict_row(&self, row: &[f64]) -> f64 {
        self.0.predict_row(row)
    }
}

/// Median wall and CPU seconds of `repeats` runs of `f` on a pool of `threads`.
fn time_in_pool(threads: usize, repeats: usize, mut f: impl FnMut() + Send) -> (f64, f64) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let (wall, cpu): (Vec<f64>, Vec<f64>) = (0..repeats)
        .map(|_| {
            let (t, c) = (Instant::now(), cpu_seconds());
            pool.install(&mut f);
            (t.elapsed().as_secs_f64(), cpu_seconds() - c)
        })
        .unzip();
    (median(wall), median(cpu))
}

/// Old (default) against new `predict_actions_into`: all next states at once, then one at a time.
fn bench_actions(m: &ExtraTrees, next: Rows<'_>, actions: &[f64], repeats: usize) {
    let k = actions.len();
    let action_nodes: usize =
        (0..m.n_trees()).map(|t| m.split_features(t).iter().filter(|&&f| f == m.n_inputs() - 1).count()).sum();
    let internal: usize = (0..m.n_trees()).map(|t| m.n_leaves(t) - 1).sum();
    println!(
        "    {:.1}% of the splits are on the action; batch {} states × {k} actions",
        100.0 * action_nodes as f64 / internal as f64,
        next.n_rows()
    );
    let mut old = vec![0.0; next.n_rows() * k];
    let mut new = vec![0.0; next.n_rows() * k];
    let (ow, oc) = time_in_pool(1, repeats.min(3), || DefaultPath(m).predict_actions_into(next, actions, &mut old));
    println!("    batch old (default), 1 thread: {ow:.3} s wall, {oc:.3} s cpu");
    // For reference: the rows built beforehand and predicted by the blocked `predict_into`.
    let built: Vec<f64> = (0..next.n_rows())
        .flat_map(|i| actions.iter().flat_map(move |&a| next.row(i).iter().copied().chain([a])))
        .collect();
    let built = Rows::new(&built, next.n_cols() + 1).unwrap();
    let (w, c) = time_in_pool(1, repeats.min(3), || m.predict_into(built, &mut new));
    println!("    batch of built rows by predict_into, 1 thread: {w:.3} s wall, {c:.3} s cpu");
    for threads in [1, 2] {
        let (w, c) = time_in_pool(threads, repeats, || m.predict_actions_into(next, actions, &mut new));
        println!(
            "    batch new, {threads} thread(s): {w:.4} s wall, {c:.4} s cpu  (×{:.1} wall, ×{:.1} cpu)",
            ow / w,
            oc / c
        );
    }
    assert!(old.iter().zip(&new).all(|(a, b)| a.to_bits() == b.to_bits()), "the two paths disagree");
    // One state per call, as the greedy policy asks (sequential, on the calling thread).
    let calls = 50_000.min(next.n_rows());
    let stride = next.n_rows() / calls;
    let mut out = [0.0; 64];
    let mut single = |r: &dyn Regressor| {
        let (t, c) = (Instant::now(), cpu_seconds());
        for i in 0..calls {
            r.predict_actions_into(next.slice(i * stride, i * stride + 1), actions, &mut out[..k]);
            std::hint::black_box(&out);
        }
        (t.elapsed().as_secs_f64() / calls as f64 * 1e6, (cpu_seconds() - c) / calls as f64 * 1e6)
    };
    let (mut ow, mut oc, mut nw, mut nc) = (vec![], vec![], vec![], vec![]);
    for _ in 0..repeats {
        let (w, c) = single(&DefaultPath(m));
        ow.push(w);
        oc.push(c);
        let (w, c) = single(m);
        nw.push(w);
        nc.push(c);
    }
    let (ow, oc, nw, nc) = (median(ow), median(oc), median(nw), median(nc));
    println!(
        "    single state: old {ow:.2} µs wall ({oc:.2} cpu), new {nw:.2} µs wall ({nc:.2} cpu)  (×{:.1} wall, ×{:.1} cpu)",
        ow / nw,
        oc / nc
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let only = args.get(1).cloned().filter(|o| o != "all");
    let repeats: usize = args.get(2).map_or(3, |s| s.parse().unwrap());
    let what = args.get(3).cloned().unwrap_or_else(|| "all".into());
    let (do_fit, do_actions) = (what != "actions", what != "fit");
    let settings = [
        (
            "bicycle",
            1000,
            ExtraTreesParams { n_trees: 50, max_depth: Some(17), min_samples_split: 8, min_samples_leaf: 4 },
        ),
        (
            "pendulum",
            2000,
            ExtraTreesParams { n_trees: 30, max_depth: Some(13), min_samples_split: 4, min_samples_leaf: 2 },
        ),
        (
            "cartpole",
            2000,
            ExtraTreesParams { n_trees: 30, max_depth: Some(14), min_samples_split: 4, min_samples_leaf: 2 },
        ),
    ];
    for (name, episodes, p) in settings {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let cfg = EnvConfig::by_name(name).unwrap();
        let ds = collect(cfg.env(), episodes, 1).unwrap();
        let d = ds.obs_dim;
        let x: Vec<f64> =
            (0..ds.len()).flat_map(|i| ds.state[i * d..(i + 1) * d].iter().copied().chain([ds.action[i]])).collect();
        let rows = Rows::new(&x, d + 1).unwrap();
        let smooth: Vec<f64> = (0..ds.len())
            .map(|i| {
                let s = &ds.next_state[i * d..(i + 1) * d];
                ds.reward[i] + 0.9 * s.iter().enumerate().map(|(k, v)| ((k + 1) as f64 * v).sin()).sum::<f64>()
            })
            .collect();
        println!("{name}: {} rows × {} inputs, {p:?}", rows.n_rows(), d + 1);
        if do_actions {
            let env = cfg.env();
            let actions = env.actions();
            let next = Rows::new(&ds.next_state, d).unwrap();
            let m1 = p.fit(rows, &ds.reward, 0).unwrap().0;
            println!("  predict_actions_into [reward]");
            bench_actions(&m1, next, actions, repeats);
            // A second FQI iteration's targets: r + γ max_a Q1(s', a), 0 after an absorbing step.
            let mut q = vec![0.0; next.n_rows() * actions.len()];
            m1.predict_actions_into(next, actions, &mut q);
            let y2: Vec<f64> = (0..ds.len())
                .map(|i| {
                    let best = q[i * actions.len()..(i + 1) * actions.len()].iter().copied().fold(f64::MIN, f64::max);
                    ds.reward[i] + if ds.absorbing[i] { 0.0 } else { env.gamma() * best }
                })
                .collect();
            let m2 = p.fit(rows, &y2, 1).unwrap().0;
            println!("  predict_actions_into [fqi iteration 2]");
            bench_actions(&m2, next, actions, repeats);
        }
        if !do_fit {
            continue;
        }
        for (label, y) in [("reward", &ds.reward), ("smooth", &smooth)] {
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let (times, cpu): (Vec<f64>, Vec<f64>) = (0..repeats)
                    .map(|r| {
                        let (t, c) = (Instant::now(), cpu_seconds());
                        let m = pool.install(|| p.fit(rows, y, r as u64).unwrap().0);
                        let s = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
                        std::hint::black_box(m);
                        s
                    })
                    .unzip();
                println!(
                    "  fit [{label}] {threads} thread(s): median {:.3} s wall, {:.3} s cpu  (wall {times:.3?})",
                    median(times.clone()),
                    median(cpu)
                );
            }
            let m = p.fit(rows, y, 0).unwrap().0;
            let leaves: usize = (0..m.n_trees()).map(|t| m.n_leaves(t)).sum();
            let depth = (0..m.n_trees()).map(|t| m.tree_depth(t)).max().unwrap();
            println!("  [{label}] {} leaves/tree on average, max depth {depth}", leaves / m.n_trees());
            let mut out = vec![0.0; rows.n_rows()];
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let times: Vec<f64> = (0..repeats)
                    .map(|_| {
                        let t = Instant::now();
                        pool.install(|| m.predict_into(rows, &mut out));
                        t.elapsed().as_secs_f64()
                    })
                    .collect();
                println!("  predict_into {threads} thread(s): {:.2e} rows/s", rows.n_rows() as f64 / median(times));
            }
            let n_single = 20_000.min(rows.n_rows());
            let t = Instant::now();
            let mut acc = 0.0;
            for i in 0..n_single {
                acc += m.predict_row(rows.row(i * (rows.n_rows() / n_single)));
            }
            std::hint::black_box(acc);
            println!("  predict_row: {:.2} µs/row", t.elapsed().as_secs_f64() / n_single as f64 * 1e6);
        }
    }
}
