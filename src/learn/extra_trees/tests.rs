//! The Extra-Trees' tests: pinned forests, the growing rules, kernels and walks that must agree bit
//! for bit, and the checks of settings and data.

use super::builder::{Data, Workspace, build_tree_with};
use super::kernels::Build;
use super::predict::LANES;
use super::routes::{NO_FORK, Record, Routes};
use super::splitter::{query_threshold, round_down_f32};
use super::*;
use crate::learn::{NO_ROW, NextStates, Regressor};

/// `n` rows of `d` uniform inputs in [-1, 1) from a fixed stream.
fn random_x(n: usize, d: usize, seed: u64) -> Vec<f64> {
    let mut r = rng::stream(seed, "test-x", &[]);
    (0..n * d).map(|_| rng::uniform(&mut r, -1.0, 1.0)).collect()
}

fn target(x: &[f64]) -> f64 {
    (3.0 * x[0]).sin() + x[1] * x[1]
}

fn synthetic(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let x = random_x(n, 2, seed);
    let y = x.chunks(2).map(target).collect();
    (x, y)
}

fn params(n_trees: usize, max_depth: Option<usize>, split: usize, leaf: usize) -> ExtraTreesParams {
    ExtraTreesParams { n_trees, max_depth, min_samples_split: split, min_samples_leaf: leaf }
}

fn fit(p: &ExtraTreesParams, x: &[f64], y: &[f64], seed: u64) -> ExtraTrees {
    let cols = x.len() / y.len();
    p.fit(Rows::new(x, cols).unwrap(), y, seed).unwrap().0
}

fn predict(m: &ExtraTrees, x: &[f64]) -> Vec<f64> {
    let rows = Rows::new(x, m.n_inputs()).unwrap();
    let mut out = vec![0.0; rows.n_rows()];
    m.predict_into(rows, &mut out);
    out
}

fn mse(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum::<f64>() / a.len() as f64
}

/// FNV-1a over the bits of `vals`.
fn fingerprint(vals: impl IntoIterator<Item = f64>) -> u64 {
    vals.into_iter().fold(0xcbf2_9ce4_8422_2325, |h, v| (h ^ v.to_bits()).wrapping_mul(0x100_0000_01b3))
}

/// Pins the trees of fixed seeds bit for bit (through their in-sample predictions, their Q of
/// every action on fresh states, and their sizes): speed work on the builder or the walks must
/// not change a tree, or the committed reference runs would no longer reproduce from their seeds.
#[test]
fn forests_are_pinned_bit_for_bit() {
    let n = 2500;
    let xs = random_x(n, 2, 70);
    let mut r = rng::stream(71, "test-pinned", &[]);
    let acts: Vec<f64> = (0..n).map(|_| rng::below(&mut r, 5) as f64).collect();
    let x: Vec<f64> = (0..n).flat_map(|i| [xs[2 * i], xs[2 * i + 1], acts[i]]).collect();
    let y: Vec<f64> = (0..n).map(|i| target(&xs[2 * i..]) + 0.3 * (acts[i] - 2.0).abs()).collect();
    let states = random_x(700, 2, 72);
    let actions = [0.0, 1.0, 2.0, 3.0, 4.0];
    let mut prints = Vec::new();
    for (p, seed) in [(params(12, Some(9), 8, 4), 1), (params(6, None, 2, 1), 2), (params(9, Some(4), 4, 2), 3)] {
        let mut in_sample = vec![0.0; n];
        let (m, _) = p.fit_predict(Rows::new(&x, 3).unwrap(), &y, seed, &mut in_sample).unwrap();
        let mut q = vec![0.0; 700 * actions.len()];
        m.predict_actions_into(Rows::new(&states, 2).unwrap(), &actions, &mut q);
        let sizes = (0..m.n_trees()).map(|t| (m.n_nodes(t) * 64 + m.tree_depth(t)) as f64);
        prints.push(fingerprint(in_sample.into_iter().chain(q).chain(sizes)));
    }
    assert_eq!(prints, [0xbdcf_bb03_52ff_ea44, 0x8a98_1ce4_84af_8f0f, 0x1dc4_9790_a165_8727], "{prints:#x?}");
}

/// Pins, as above, forests where most rows have one target, so that pure nodes of thousands of
/// rows (leaves, which draw nothing) sit beside nodes that go on splitting: a builder that
/// drew for a node before knowing it is pure, without putting the stream back, would fail.
#[test]
fn big_pure_nodes_are_pinned_bit_for_bit() {
    let n = 12_000;
    let x = random_x(n, 3, 80);
    let y: Vec<f64> = x.chunks(3).map(|r| if r[0] > 0.6 && r[1] > 0.2 { target(r) + r[2] } else { 0.25 }).collect();
    let fresh = random_x(900, 3, 81);
    let mut prints = Vec::new();
    for (p, seed) in [(params(8, None, 2, 1), 4), (params(5, Some(12), 6, 3), 5)] {
        let mut in_sample = vec![0.0; n];
        let (m, _) = p.fit_predict(Rows::new(&x, 3).unwrap(), &y, seed, &mut in_sample).unwrap();
        let sizes = (0..m.n_trees()).map(|t| (m.n_nodes(t) * 64 + m.tree_depth(t)) as f64);
        let feats = (0..m.n_trees()).flat_map(|t| m.split_features(t)).map(|f| f as f64);
        prints.push(fingerprint(in_sample.into_iter().chain(predict(&m, &fresh)).chain(sizes).chain(feats)));
    }
    assert_eq!(prints, [0x137b_ed4c_a527_1ebb, 0xd144_3b0f_4a64_6e0f], "{prints:#x?}");
}

/// A worker thread keeps its workspace from one fit to the next: fits of other widths and row
/// counts on the same thread in between must not reach a forest.
#[test]
fn kept_workspaces_change_no_forest() {
    let (x2, y2) = synthetic(3000, 90);
    let x5 = random_x(5000, 5, 91);
    let y5: Vec<f64> = x5.chunks(5).map(|r| target(r) + r[4]).collect();
    let (x_small, y_small) = synthetic(700, 92);
    let p = params(4, Some(12), 2, 1);
    let one_thread = || rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let forest = |x: &[f64], y: &[f64]| bits(&predict(&fit(&p, x, y, 7), x));
    // Each new pool has a new thread, so its first fit makes a new workspace.
    let alone = |x: &[f64], y: &[f64]| one_thread().install(|| forest(x, y));
    let in_turn =
        one_thread().install(|| [forest(&x2, &y2), forest(&x5, &y5), forest(&x_small, &y_small), forest(&x2, &y2)]);
    assert_eq!(in_turn[0], alone(&x2, &y2));
    assert_eq!(in_turn[1], alone(&x5, &y5));
    assert_eq!(in_turn[2], alone(&x_small, &y_small));
    assert_eq!(in_turn[3], in_turn[0]);
}

#[test]
fn depth_limit_bounds_depth_and_leaves() {
    let (x, y) = synthetic(1500, 1);
    for depth in 1..=7 {
        let m = fit(&params(5, Some(depth), 2, 1), &x, &y, 3);
        for t in 0..m.n_trees() {
            assert!(m.tree_depth(t) <= depth);
            assert!(m.n_leaves(t) <= 1 << depth, "depth {depth}: {} leaves", m.n_leaves(t));
            assert_eq!(m.n_nodes(t), 2 * m.n_leaves(t) - 1);
            // 1500 rows leave room for every allowed level.
            assert_eq!(m.tree_depth(t), depth);
        }
    }
    let stump = fit(&params(10, Some(1), 2, 1), &x, &y, 4);
    for t in 0..10 {
        assert_eq!(stump.n_leaves(t), 2);
        assert_eq!(stump.split_features(t).len(), 1);
        assert_eq!(stump.leaf_sizes(t).iter().sum::<usize>(), 1500);
    }
}

#[test]
fn stumps_prefer_the_informative_feature() {
    // y is a step in x0; x1 is noise. A random cut of x0 explains far more variance than one
    // of x1 almost always, so the variance criterion should pick x0 in most stumps.
    let x = random_x(1000, 2, 50);
    let y: Vec<f64> = x.chunks(2).map(|r| if r[0] > 0.2 { 1.0 } else { 0.0 }).collect();
    let m = fit(&params(200, Some(1), 2, 1), &x, &y, 3);
    let on_x0 = (0..200).filter(|&t| m.split_features(t) == [0]).count();
    assert!(on_x0 > 170, "{on_x0} of 200 stumps split on x0");
}

#[test]
fn leaves_respect_min_samples_leaf_and_split() {
    let (x, y) = synthetic(2000, 2);
    for (split, leaf) in [(2, 1), (8, 4), (4, 2), (30, 10), (3, 7)] {
        let m = fit(&params(4, None, split, leaf), &x, &y, 5);
        for t in 0..m.n_trees() {
            let sizes = m.leaf_sizes(t);
            assert_eq!(sizes.iter().sum::<usize>(), 2000);
            assert!(sizes.iter().all(|&s| s >= leaf), "split {split} leaf {leaf}: {sizes:?}");
        }
        // Fully grown with 1-row leaves on distinct inputs: every leaf is a single row.
        if leaf == 1 {
            assert!(m.leaf_sizes(0).iter().all(|&s| s == 1));
        }
    }
    // A node smaller than min_samples_split is never split.
    let m = fit(&params(3, None, 2001, 1), &x, &y, 5);
    assert_eq!(m.n_leaves(0), 1);
    assert_eq!(m.tree_depth(0), 0);
    let m = fit(&params(3, None, 2000, 1), &x, &y, 5);
    assert!(m.n_leaves(0) >= 2 && m.tree_depth(0) <= 1);
}

#[test]
fn fully_grown_tree_reproduces_training_targets() {
    // Exercises the f32 thresholds: every training row must land in its own leaf.
    let (x, y) = synthetic(800, 3);
    // Two trees: (v + v) / 2 == v exactly.
    let m = fit(&params(2, None, 2, 1), &x, &y, 9);
    for (row, &target) in x.chunks(2).zip(&y) {
        assert_eq!(m.predict_row(row), target);
    }
}

#[test]
fn forest_learns_and_improves_with_depth() {
    let (x, y) = synthetic(2000, 10);
    let (xt, yt) = synthetic(1000, 11);
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let base = mse(&vec![mean; yt.len()], &yt);
    let errs: Vec<f64> =
        [2, 6, 12].iter().map(|&d| mse(&predict(&fit(&params(30, Some(d), 2, 1), &x, &y, 7), &xt), &yt)).collect();
    assert!(errs[0] < base / 2.0 && errs[1] < errs[0] && errs[2] < errs[1], "{errs:?} vs {base}");
    assert!(errs[2] < base / 50.0, "{errs:?} vs {base}");
}

#[test]
fn same_seed_same_forest_for_any_thread_count() {
    let (x, y) = synthetic(3000, 20);
    let (xt, _) = synthetic(500, 21);
    let p = params(12, Some(10), 4, 2);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| predict(&fit(&p, &x, &y, 42), &xt))
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
    let other = predict(&fit(&p, &x, &y, 43), &xt);
    assert_ne!(one, other);
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Every kernel build this CPU runs (whatever `BFQI_ISA` says) grows the same trees as the portable
/// one, node for node, leaf for leaf, so the forests predict the same bits.
#[test]
fn every_kernel_build_grows_the_same_trees() {
    let builds = Build::available();
    assert!(matches!(builds.last(), Some(Build::Portable)), "{builds:?}");
    let fresh = random_x(500, 3, 98);
    // Sizes around the block lengths (16, 32) and the sweep step, a large target offset
    // (rounding differences would show) and duplicated inputs (ties at thresholds).
    for (n, offset) in [(1, 0.0), (15, 0.0), (17, 1e6), (33, -3.0), (700, 1e6), (5000, 0.5)] {
        let mut x = random_x(n, 3, n as u64);
        x.iter_mut().skip(2).step_by(3).for_each(|v| *v = (*v * 4.0).round());
        let y: Vec<f64> = x.chunks(3).map(|r| offset + target(r) + r[2]).collect();
        // Forks at splits on the last column.
        let data = Data::new(Rows::new(&x, 3).unwrap(), &y, Record::Routes(2)).unwrap();
        for p in [params(3, None, 2, 1), params(3, Some(5), 4, 2)] {
            let grow = |build: Build| {
                let mut ws = Workspace::new(3, n);
                let mut routes = Vec::new();
                let trees = (0..p.n_trees as u64)
                    .map(|t| {
                        let mut r = Routes { leaf_of: vec![0; n], value: Vec::new(), fork: Vec::new() };
                        let tree = build_tree_with(build, &p, &data, &mut ws, rng::stream(9, "tree", &[t]), &mut r);
                        routes.push(r);
                        tree
                    })
                    .collect();
                (ExtraTrees { n_inputs: 3, trees }, routes)
            };
            let (want, want_routes) = grow(Build::Portable);
            for &build in &builds {
                let (got, got_routes) = grow(build);
                for ((a, b), (la, lb)) in want.trees.iter().zip(&got.trees).zip(want_routes.iter().zip(&got_routes)) {
                    assert_eq!(a.counts, b.counts, "{build:?}, n {n}");
                    assert_eq!((&la.leaf_of, &la.fork), (&lb.leaf_of, &lb.fork), "{build:?}, n {n}");
                    assert_eq!(bits(&la.value), bits(&lb.value), "{build:?}, n {n}");
                    for (u, v) in a.nodes.iter().zip(&b.nodes) {
                        let node = |u: &tree::Node| (u.val.to_bits(), u.feat, u.left);
                        assert_eq!(node(u), node(v), "{build:?}, n {n}");
                    }
                }
                assert_eq!(bits(&predict(&got, &fresh)), bits(&predict(&want, &fresh)), "{build:?}, n {n}");
            }
        }
    }
}

#[test]
fn fit_predict_matches_predict_into() {
    // Ties at thresholds (rounded inputs), a depth limit (leaves above the deepest level), a
    // large target offset, one and several trees, and rows in the parallel path.
    for (n, trees, depth, leaf) in [(1, 1, None, 1), (37, 3, Some(3), 2), (9000, 20, Some(9), 1)] {
        let mut x = random_x(n, 3, n as u64 + 5);
        x.iter_mut().skip(1).step_by(3).for_each(|v| *v = (*v * 8.0).round() / 8.0);
        let y: Vec<f64> = x.chunks(3).map(|r| 1e5 + target(r) + r[1]).collect();
        let p = params(trees, depth, 2, leaf);
        let rows = Rows::new(&x, 3).unwrap();
        let mut inside = vec![f64::NAN; n];
        let (m, _) = p.fit_predict(rows, &y, 4, &mut inside).unwrap();
        let mut walked = vec![0.0; n];
        m.predict_into(rows, &mut walked);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&inside), bits(&walked), "n {n}");
        // Same model as a plain fit.
        assert_eq!(bits(&predict(&fit(&p, &x, &y, 4), &x)), bits(&walked), "n {n}");
    }
}

#[test]
fn predict_into_matches_predict_row() {
    let (x, y) = synthetic(2000, 30);
    // Enough rows to go through the parallel path and a ragged last chunk.
    let xt = random_x(5000 + 17, 2, 31);
    let m = fit(&params(50, Some(8), 2, 1), &x, &y, 1);
    let batch = predict(&m, &xt);
    for (row, &b) in xt.chunks(2).zip(&batch) {
        assert_eq!(m.predict_row(row), b);
    }
}

/// A model that keeps the trait's default `predict_actions_into` (one row per action).
struct DefaultPath<'a>(&'a ExtraTrees);

impl Regressor for DefaultPath<'_> {
    fn n_inputs(&self) -> usize {
        self.0.n_inputs()
    }
    fn predict_row(&self, row: &[f64]) -> f64 {
        self.0.predict_row(row)
    }
}

fn predict_actions(m: &dyn Regressor, states: &[f64], actions: &[f64]) -> Vec<u64> {
    let rows = Rows::new(states, m.n_inputs() - 1).unwrap();
    let mut out = vec![f64::NAN; rows.n_rows() * actions.len()];
    m.predict_actions_into(rows, actions, &mut out);
    out.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn predict_actions_into_is_bit_identical_to_the_default() {
    let d = 3;
    let n = 3000;
    let mut r = rng::stream(5, "test-actions", &[]);
    // Training actions: 9 discrete values, plus a column never split on (constant).
    let xs = random_x(n, d, 60);
    let acts: Vec<f64> = (0..n).map(|_| rng::below(&mut r, 9) as f64).collect();
    let join = |a: &dyn Fn(usize) -> f64| -> Vec<f64> {
        (0..n).flat_map(|i| xs[i * d..(i + 1) * d].iter().copied().chain([a(i)])).collect()
    };
    let x_discrete = join(&|i| acts[i]);
    let x_constant = join(&|_| 1.0);
    let x_continuous = join(&|i| xs[i * d] * 0.5 + (i as f64 * 0.37).sin());
    let noise = |i: usize| (i as f64 * 1.7).cos() * 0.1;
    // A weak action effect, and one where the action dominates (split at the top of every tree).
    let y_weak: Vec<f64> = (0..n).map(|i| target(&xs[i * d..]) + 0.2 * acts[i] + noise(i)).collect();
    let y_strong: Vec<f64> = (0..n).map(|i| 10.0 * (acts[i] - 4.0).abs() + xs[i * d + 2] + noise(i)).collect();
    let y_cont: Vec<f64> = (0..n).map(|i| x_continuous[i * (d + 1) + d].sin() * 3.0 + xs[i * d + 1]).collect();
    let forests = [
        fit(&params(10, Some(12), 4, 2), &x_discrete, &y_weak, 1),
        fit(&params(7, None, 2, 1), &x_discrete, &y_strong, 2),
        fit(&params(9, Some(6), 8, 4), &x_constant, &y_weak, 3),
        fit(&params(12, None, 2, 1), &x_continuous, &y_cont, 4),
        fit(&params(3, Some(1), 2, 1), &x_discrete, &y_strong, 5),
        fit(&params(4, None, 2, 1), &x_discrete, &[2.5; 3000], 6),
    ];
    assert!(forests[1].split_features(0)[0] == d, "the action should split the root");
    assert!((0..9).all(|t| forests[2].split_features(t).iter().all(|&f| f != d)));
    let many: Vec<f64> = (0..70).map(|j| j as f64 * 0.15 - 1.0).collect();
    let action_sets: Vec<Vec<f64>> = vec![
        (0..9).map(f64::from).collect(),
        vec![2.0, -2.0],
        vec![4.0],
        vec![8.0, 0.0, 3.5, 3.0, 3.0, -0.0, 0.0, 100.0, -7.0],
        vec![0.5, f64::NAN, -0.25, 1e-9, f32::MAX as f64 * 2.0],
        many[..64].to_vec(),
        many.clone(),
    ];
    // Queries: fresh states, the training states (ties with thresholds) and odd values.
    let mut states = random_x(4100, d, 61);
    states.extend_from_slice(&xs[..300 * d]);
    states.extend_from_slice(&[0.0, -0.0, f64::NAN, 1e30, -1e30, 0.5]);
    let n_states = states.len() / d;
    for (f, m) in forests.iter().enumerate() {
        // Actions on, just below and just above the forest's own action thresholds.
        let on_thresholds: Vec<f64> = (m.trees.iter().flat_map(|t| &t.nodes))
            .filter(|node| node.feat == d as u32)
            .flat_map(|node| [node.val, node.val.next_down(), node.val.next_up()])
            .take(63)
            .collect();
        assert_eq!(on_thresholds.is_empty(), f == 2 || f == 5, "forest {f}");
        // States on the forest's own state thresholds.
        let mut states = states.clone();
        for (i, node) in
            (m.trees.iter().flat_map(|t| &t.nodes)).filter(|node| node.feat < d as u32).take(200).enumerate()
        {
            states[i * d + node.feat as usize] = if i % 2 == 0 { node.val } else { node.val.next_up() };
        }
        for acts in action_sets.iter().chain([&on_thresholds].into_iter().filter(|a| !a.is_empty())) {
            let want = predict_actions(&DefaultPath(m), &states, acts);
            // Many rows (parallel when large enough), a few, and single states.
            assert!(predict_actions(m, &states, acts) == want, "forest {f}, {} actions", acts.len());
            for (a, b) in [(0, 5), (10, 19), (100, 100 + LANES + 1)] {
                let few = predict_actions(m, &states[a * d..b * d], acts);
                assert!(few == want[a * acts.len()..b * acts.len()], "forest {f}, states {a}..{b}");
            }
            let single = (0..n_states).step_by(37).chain(n_states - 6..n_states);
            for i in single {
                let one = predict_actions(m, &states[i * d..(i + 1) * d], acts);
                assert!(one == want[i * acts.len()..(i + 1) * acts.len()], "forest {f}, state {i}");
            }
        }
    }
    // Any thread count gives the same answer.
    let acts = &action_sets[0];
    let want = predict_actions(&forests[0], &states, acts);
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        assert!(pool.install(|| predict_actions(&forests[0], &states, acts)) == want);
    }
    // No states, no actions.
    assert!(predict_actions(&forests[0], &[], acts).is_empty());
    assert!(predict_actions(&forests[0], &states, &[]).is_empty());
}

#[test]
fn fit_predict_next_is_bit_identical_to_fitting_then_predicting() {
    let (n, d) = (2500, 3);
    let mut r = rng::stream(8, "test-next", &[]);
    let xs = random_x(n, d, 70);
    let acts: Vec<f64> = (0..n).map(|_| rng::below(&mut r, 9) as f64).collect();
    let join = |a: &dyn Fn(usize) -> f64| -> Vec<f64> {
        (0..n).flat_map(|i| xs[i * d..(i + 1) * d].iter().copied().chain([a(i)])).collect()
    };
    let (with_action, constant_action) = (join(&|i| acts[i]), join(&|_| 1.0));
    let noise = |i: usize| (i as f64 * 1.7).cos() * 0.1;
    // The action splits here and there (weak), at the top (strong), or nowhere (constant).
    let y_weak: Vec<f64> = (0..n).map(|i| target(&xs[i * d..]) + 0.01 * acts[i] + noise(i)).collect();
    let y_strong: Vec<f64> = (0..n).map(|i| 10.0 * (acts[i] - 4.0).abs() + xs[i * d + 2] + noise(i)).collect();
    // Next states: training states hinted with their row (in trajectory order, and one that
    // hints another row with the same state), training states and fresh ones without a hint.
    let fresh = random_x(300, d, 71);
    let mut states = Vec::new();
    let mut same = Vec::new();
    for i in 0..n + 300 {
        let (state, hint) = match i % 5 {
            _ if i >= n => (&fresh[(i - n) * d..(i - n + 1) * d], NO_ROW),
            4 => (&xs[i * d..(i + 1) * d], NO_ROW),
            _ => (&xs[(i + 1) % n * d..((i + 1) % n + 1) * d], ((i + 1) % n) as u32),
        };
        states.extend_from_slice(state);
        same.push(hint);
    }
    let states = Rows::new(&states, d).unwrap();
    let many: Vec<f64> = (0..70).map(|j| j as f64 * 0.15 - 1.0).collect();
    for (f, (p, x, y)) in [
        (params(8, Some(12), 4, 2), &with_action, &y_weak),
        (params(5, None, 2, 1), &with_action, &y_strong),
        (params(6, Some(8), 8, 4), &constant_action, &y_weak),
    ]
    .into_iter()
    .enumerate()
    {
        // Rows whose leaf has a fork and rows whose leaf has none, except where nothing splits
        // on the action.
        let x = Rows::new(x, d + 1).unwrap();
        let (_, routes) = p.fit_impl(x, y, 3, Record::Routes(d)).unwrap();
        let forked = |r: &Routes| r.leaf_of.iter().filter(|&&l| r.fork[l as usize] != NO_FORK).count();
        let at_split: usize = routes.iter().map(forked).sum();
        let at_leaf = n * p.n_trees - at_split;
        assert_eq!(at_split == 0, f == 2, "forest {f}: {at_split} rows below a fork");
        assert!(f == 1 || at_leaf > 0, "forest {f}: every row below a fork");
        for actions in [(0..9).map(f64::from).collect(), many.clone(), vec![4.0]] {
            let next = NextStates { states, actions: Some(&actions), same: &same };
            let (mut train, mut q) = (vec![0.0; n], vec![0.0; (n + 300) * actions.len()]);
            let (m, _) = p.fit_predict(x, y, 3, &mut train).unwrap();
            m.predict_actions_into(states, &actions, &mut q);
            let (mut train2, mut q2) = (vec![f64::NAN; n], vec![f64::NAN; q.len()]);
            p.fit_predict_next(x, y, 3, &mut train2, &next, &mut q2).unwrap();
            assert_eq!(bits(&train2), bits(&train), "forest {f}, in-sample");
            assert_eq!(bits(&q2), bits(&q), "forest {f}, {} actions", actions.len());
        }
        // The state alone as input (one model per action): no forks.
        let x = Rows::new(&xs, d).unwrap();
        let next = NextStates { states, actions: None, same: &same };
        let (mut train, mut q) = (vec![0.0; n], vec![0.0; n + 300]);
        let (m, _) = p.fit_predict(x, y, 4, &mut train).unwrap();
        m.predict_into(states, &mut q);
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (mut train2, mut q2) = (vec![f64::NAN; n], vec![f64::NAN; q.len()]);
            pool.install(|| p.fit_predict_next(x, y, 4, &mut train2, &next, &mut q2)).unwrap();
            assert_eq!(bits(&train2), bits(&train), "forest {f}, state inputs, in-sample");
            assert_eq!(bits(&q2), bits(&q), "forest {f}, state inputs, {threads} threads");
        }
    }
}

#[test]
fn constant_parts_are_not_split() {
    // Constant target: every tree is one leaf with that value.
    let x = random_x(300, 3, 40);
    let m = fit(&params(5, None, 2, 1), &x, &[2.5; 300], 1);
    assert!((0..5).all(|t| m.n_leaves(t) == 1));
    assert_eq!(m.predict_row(&[0.0, 0.0, 0.0]), 2.5);
    // A constant feature is never chosen.
    let mut x = random_x(500, 3, 41);
    x.iter_mut().skip(1).step_by(3).for_each(|v| *v = 7.0);
    let y: Vec<f64> = x.chunks(3).map(|r| r[0] + r[2]).collect();
    let m = fit(&params(5, None, 2, 1), &x, &y, 2);
    assert!((0..5).all(|t| m.split_features(t).iter().all(|&f| f != 1)));
}

#[test]
fn invalid_params_name_the_field() {
    let cases = [
        (params(0, None, 2, 1), "n_trees"),
        (params(5, Some(0), 2, 1), "max_depth"),
        (params(5, None, 1, 1), "min_samples_split"),
        (params(5, None, 2, 0), "min_samples_leaf"),
    ];
    let x = [0.0, 1.0];
    for (p, field) in cases {
        let e = p.check().unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
        let e = p.fit(Rows::new(&x, 1).unwrap(), &[0.0, 1.0], 0).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
    assert!(ExtraTreesParams::default().check().is_ok());
}

#[test]
fn bad_data_is_an_error() {
    let p = ExtraTreesParams::default();
    let x = [0.0, 1.0, f64::NAN, 3.0];
    assert!(p.fit(Rows::new(&x, 2).unwrap(), &[0.0, 1.0], 0).is_err());
    let x = [0.0, 1.0, 2.0, 3.0];
    assert!(p.fit(Rows::new(&x, 2).unwrap(), &[0.0, f64::NAN], 0).is_err());
    assert!(p.fit(Rows::new(&x, 2).unwrap(), &[0.0], 0).is_err());
    let x = [0.0, 1e300];
    let e = p.fit(Rows::new(&x, 1).unwrap(), &[0.0, 1.0], 0).unwrap_err().to_string();
    assert!(e.contains("too large"), "{e}");
}

#[test]
fn params_serde_defaults_and_unknown_fields() {
    let p: ExtraTreesParams = serde_json::from_str(r#"{"n_trees": 30, "max_depth": 13}"#).unwrap();
    assert_eq!(p, ExtraTreesParams { n_trees: 30, max_depth: Some(13), ..Default::default() });
    let p: ExtraTreesParams = serde_json::from_str("{}").unwrap();
    assert_eq!(p, ExtraTreesParams::default());
    assert!(serde_json::from_str::<ExtraTreesParams>(r#"{"n_tree": 3}"#).is_err());
    let back: ExtraTreesParams = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
    assert_eq!(back, p);
}

#[test]
fn query_threshold_agrees_with_f32_rounding() {
    let mut r = rng::stream(1, "test-thr", &[]);
    let mut ts: Vec<f32> = (0..2000).map(|_| rng::uniform(&mut r, -1e3, 1e3) as f32).collect();
    ts.extend([0.0, -0.0, 1.0, -1.0, f32::MAX, -f32::MAX, f32::MIN_POSITIVE, 1e-40, 16777216.0]);
    for &t in &ts {
        let big = query_threshold(t);
        let up = t.next_up() as f64;
        let mid = if t == f32::MAX { f32::MAX as f64 + 2f64.powi(103) } else { (t as f64 + up) / 2.0 };
        for q in [t as f64, mid.next_down(), mid, mid.next_up(), up, (t as f64).next_down()] {
            assert_eq!(q <= big, (q as f32) <= t, "t {t:e}, q {q:e}");
        }
    }
    for v in [0.3, -0.3, 1.0 / 3.0, 1e-3, 12345.678] {
        let t = round_down_f32(v);
        assert!(t as f64 <= v && (t.next_up() as f64) > v);
    }
}

#[test]
fn round_down_f32_is_the_largest_f32_not_above() {
    let mut r = rng::stream(1, "test-round-down", &[]);
    let mut vs: Vec<f64> = (0..20_000).map(|_| rng::uniform(&mut r, -2.0, 2.0)).collect();
    vs.extend((0..2000).map(|_| rng::uniform(&mut r, -1e-44, 1e-44)));
    vs.extend([0.0, -0.0, 1e-300, -1e-300, 1.0, -1.0, f32::MAX as f64, -(f32::MAX as f64)]);
    vs.extend([f32::MIN_POSITIVE as f64, -(f32::MIN_POSITIVE as f64), 1e-45, -1e-45]);
    for &v in &vs {
        let textbook = {
            let t = v as f32;
            if t as f64 > v { t.next_down() } else { t }
        };
        assert_eq!(round_down_f32(v).to_bits(), textbook.to_bits(), "v {v:e}");
    }
}
