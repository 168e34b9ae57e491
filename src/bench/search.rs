//! `bench search`: the main job, `bfqi-ga search <env>` at its default spec, measured.
//!
//! For each environment:
//! - the machine's FP32 peak (an FMA loop on one core) and, for the search's network shape, the
//!   epoch time of each activation against it (how FLOPs are counted: [`EpochWork`]);
//! - units (one chromosome on search dataset 0) of three fixed settings, the thesis optimum, a
//!   fast one and a slow one, on one thread, each stopped after the FQI iteration that passes the
//!   time cap and projected from the iterations it ran;
//! - the thesis optimum's unit on every thread of the pool, against one (one unit across cores);
//! - the projected wall time of the default search: the first generation's chromosomes (drawn
//!   from the spec's seed, as the search draws them), each distinct setting's unit timed as above
//!   and assumed to cost as much on every dataset, scheduled longest first on the pool's threads;
//! - with a Python that has Keras 3 and JAX, the thesis optimum's first FQI iteration (all its
//!   networks, early-stopped) trained by Keras on the same rows and settings, and the ratio.

use super::PythonReference;
use super::levels::{SHAPE_EPOCHS, parse_levels, shapes, side_by_side};
use crate::error::{Error, Result};
use crate::fqi::Fqi;
use crate::ga::chromosome::{Decoded, decode};
use crate::ga::operators::initial_population;
use crate::ga::units::{Evaluator, activation_name, setting_id};
use crate::learn::mlp::{Activation, EpochWork, Shape, fma_peak_gflops, kernel_isa, split_rows};
use crate::progress::human;
use crate::spec::Spec;
use crate::tuned::TunedConfig;
use serde::Serialize;
use serde_json::{Value, json};
use std::path::PathBuf;
use std::time::Instant;

/// What `bench search` runs.
#[derive(Debug, Clone)]
pub struct SearchBench {
    /// An environment name or spec file; every shipped environment when `None`.
    pub env: Option<String>,
    /// A Python with Keras 3 and JAX, for the side-by-side ratio.
    pub python: Option<PathBuf>,
    /// Seconds after which a timed unit stops (after the FQI iteration under way).
    pub cap_seconds: f64,
    /// Print JSON instead of text.
    pub json: bool,
    /// `all` or level names (`avx2,avx512`): time the network shapes at each of those kernel
    /// levels side by side, each against its own peak and bound, instead of the units.
    pub isa: Option<String>,
}

/// The fast and slow settings timed besides the thesis optimum: their genes, under the default
/// gene ranges (activation, a_δ, b_δ, a_p, b_p).
const FAST: [i64; 5] = [2, 99, 2, 10, 0];
const SLOW: [i64; 5] = [0, 10, 8, 99, 2];

#[derive(Debug, Clone, Serialize)]
struct UnitFigures {
    role: String,
    setting: String,
    seconds: f64,
    iterations_run: usize,
    iterations: usize,
    capped: bool,
    /// `seconds` over the iterations run, times K (the whole unit's time when not capped).
    projected_seconds: f64,
    epochs: usize,
    /// Fit seconds over epochs (all the unit's networks).
    ms_per_epoch: f64,
    gflops: f64,
    percent_of_peak: f64,
    /// The score after iteration K, when it ran to the end.
    score: Option<f64>,
}

#[derive(Debug, Serialize)]
struct AcrossCores {
    setting: String,
    iterations: usize,
    threads: usize,
    seconds_one_thread: f64,
    seconds: f64,
    speedup: f64,
    identical: bool,
}

#[derive(Debug, Serialize)]
struct Projection {
    method: &'static str,
    threads: usize,
    population: usize,
    distinct_settings: usize,
    units_per_generation: usize,
    generation_s: f64,
    slowest_unit_s: f64,
    generations: usize,
    /// Every generation as costly as the first.
    search_s_all_like_first: f64,
    /// Later generations pay for their children only (elites' units are stored).
    search_s_elites_reused: f64,
    /// One task per unit: a generation takes its slowest unit.
    cluster_generation_s: f64,
    units: Vec<UnitFigures>,
}

/// One thread's rayon pool (units are timed on one core, as a search runs them).
fn pool(threads: usize) -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| Error::Data(e.to_string()))
}

/// The search network's epoch FLOPs for the mean model of dataset 0 (per-action models differ a
/// little in rows).
fn mean_work(ev: &Evaluator, act: Activation) -> Result<EpochWork> {
    let x = ev.dataset(0)?;
    let enc = &x.1;
    let net = &ev.spec().search.network;
    let shape = Shape::new(enc.n_inputs(), &net.hidden, act);
    let rows = enc.n / enc.n_models();
    let (t, v) = split_rows(rows, net.validation_fraction);
    Ok(EpochWork::new(&shape, t, v))
}

/// Times a unit of `s` on dataset 0 on the current pool, stopping after the iteration that passes
/// `cap` seconds (or after `iterations` when given).
fn time_unit(
    ev: &Evaluator,
    role: &str,
    s: &Decoded,
    cap: f64,
    iterations: Option<usize>,
    peak: f64,
) -> Result<(UnitFigures, Vec<u64>)> {
    let x = ev.dataset(0)?;
    let (data, enc) = (&x.0, &x.1);
    let params = ev.network(s);
    let settings = ev.fqi_settings();
    let (fit_seed, eval_seed) = ev.seeds(s, 0);
    let mut fqi = Fqi::new(ev.spec().env.env(), data, enc, &params, settings, fit_seed, eval_seed);
    let t = Instant::now();
    let (mut epochs, mut fit_s, mut score, mut run) = (0, 0.0, None, 0);
    let mut trace = Vec::new();
    let stop_after = iterations.unwrap_or(settings.iterations);
    while run < stop_after {
        match fqi.iterate()? {
            Ok(r) => {
                epochs += r.epochs.unwrap_or(0);
                fit_s += r.fit_seconds;
                score = r.score;
                trace.push(r.bellman_residual.to_bits());
            }
            Err(_) => {
                run += 1;
                break;
            }
        }
        run += 1;
        if iterations.is_none() && t.elapsed().as_secs_f64() > cap {
            break;
        }
    }
    let seconds = t.elapsed().as_secs_f64();
    let capped = run < settings.iterations;
    let work = mean_work(ev, s.activation)?;
    let ms = fit_s * 1e3 / epochs.max(1) as f64;
    let gflops = work.flops() / (ms / 1e3) / 1e9;
    Ok((
        UnitFigures {
            role: role.to_string(),
            setting: setting_id(s),
            seconds,
            iterations_run: run,
            iterations: settings.iterations,
            capped,
            projected_seconds: seconds / run.max(1) as f64 * settings.iterations as f64,
            epochs,
            ms_per_epoch: ms,
            gflops,
            percent_of_peak: 100.0 * gflops / peak,
            score: if capped { None } else { score },
        },
        trace,
    ))
}

/// Makespan of `jobs` scheduled longest first on `threads` identical workers.
fn longest_first(mut jobs: Vec<f64>, threads: usize) -> f64 {
    jobs.sort_by(|a, b| b.total_cmp(a));
    let mut load = vec![0.0f64; threads.max(1)];
    for j in jobs {
        let i = (0..load.len()).min_by(|&a, &b| load[a].total_cmp(&load[b])).expect("one worker");
        load[i] += j;
    }
    load.into_iter().fold(0.0, f64::max)
}

/// The Keras 3 reference on the thesis optimum's first FQI iteration.
fn keras(py: &PythonReference, ev: &Evaluator, s: &Decoded) -> Result<Option<Value>> {
    let x = ev.dataset(0)?;
    let (data, enc) = (&x.0, &x.1);
    let csv = py.file(&format!("{}-iteration1.csv", ev.spec().env.env().name()));
    let mut text = String::from("group");
    for k in 0..enc.n_inputs() {
        text.push_str(&format!(",x{k}"));
    }
    text.push_str(",y\n");
    for j in 0..enc.n_models() {
        let (rows, idx) = enc.model_rows(j);
        for (r, &i) in rows.chunks_exact(enc.n_inputs()).zip(&idx) {
            text.push_str(&j.to_string());
            for v in r {
                text.push_str(&format!(",{v:?}"));
            }
            text.push_str(&format!(",{:?}\n", data.reward[i]));
        }
    }
    std::fs::write(&csv, text).map_err(|e| Error::io(&csv, e))?;
    let net = ev.network(s);
    let hidden: Vec<String> = net.hidden.iter().map(usize::to_string).collect();
    let args = [
        csv.display().to_string(),
        format!("--hidden={}", hidden.join(",")),
        format!("--activation={}", activation_name(s.activation)),
        format!("--delta-min={}", s.delta_min),
        format!("--patience={}", s.patience),
        format!("--batch={}", net.batch_size),
        format!("--max-epochs={}", net.max_epochs),
        format!("--validation={}", net.validation_fraction),
        format!("--lr={}", net.learning_rate),
        format!("--rho={}", net.rho),
        format!("--epsilon={}", net.epsilon),
    ];
    Ok(py.run("keras_fqi_iteration.py", &args))
}

/// The environments to bench: one name or spec file, or the three shipped ones.
fn targets(env: &Option<String>) -> Vec<String> {
    match env {
        Some(e) => vec![e.clone()],
        None => crate::env::NAMES.iter().map(|s| s.to_string()).collect(),
    }
}

/// `bench search --isa`: per environment, the network shapes at each level side by side.
fn every_level(opts: &SearchBench, levels: &[crate::learn::cpu::Isa]) -> Result<Value> {
    let say = |s: String| {
        if !opts.json {
            println!("{s}");
        }
    };
    say(format!(
        "bench search --isa · the kernel levels this CPU runs the MLP at, each timed and measured against its own FMA peak (this process would use {})",
        kernel_isa()
    ));
    let one = pool(1)?;
    let mut envs = Vec::new();
    for name in targets(&opts.env) {
        let (spec, origin) = Spec::resolve(&name)?;
        let env_name = spec.env.env().name();
        let tmp = std::env::temp_dir().join(format!("bfqi-bench-levels-{}-{env_name}", std::process::id()));
        let ev = Evaluator::new(spec.clone(), &tmp);
        let widths =
            Shape::new(ev.dataset(0)?.1.n_inputs(), &spec.search.network.hidden, Activation::Sigmoid).widths().to_vec();
        let arrow: Vec<String> = widths.iter().map(usize::to_string).collect();
        say(format!("\n{env_name} ({}) — network {}", origin.display(), arrow.join(" → ")));
        let figures = side_by_side(&ev, levels, &one, &say)?;
        envs.push(json!({"env": env_name, "spec": origin.display().to_string(), "widths": widths, "levels": figures}));
    }
    say("\n  (the bound counts every vector operation as one slot; on the portable level an FMA is ~15 SSE2 instructions when the build has no FMA, so that level can pass its bound)".into());
    Ok(json!({"kernels": kernel_isa(), "levels": levels.iter().map(|l| l.name()).collect::<Vec<_>>(), "envs": envs}))
}

/// Runs the search bench; prints text, or JSON with `json`.
pub fn search(opts: &SearchBench) -> Result<Value> {
    if let Some(levels) = &opts.isa {
        return every_level(opts, &parse_levels(levels)?);
    }
    let threads = rayon::current_num_threads();
    let one = pool(1)?;
    let peak = fma_peak_gflops(1.0);
    let reference = PythonReference::new(opts.python.as_deref())?;
    let say = |s: String| {
        if !opts.json {
            println!("{s}");
        }
    };
    say(format!(
        "bench search · {threads} thread(s) · one core's FP32 peak {peak:.1} GFLOP/s (an FMA loop on the {} build)",
        kernel_isa()
    ));
    say("  FLOPs: 2 per multiply-add, forward on every row and backward on training rows (weight gradients, and".into());
    say("  the deltas of every layer but the input's), plus activations as our kernels run them (per unit and row:"
        .into());
    say("  sigmoid 40 forward + 3 backward, tanh 36 + 3, ReLU 1 + 1); 'bound' is the epoch at one vector operation"
        .into());
    say("  per slot (multiply-adds and activation operations, two slots per cycle).".into());
    let mut envs = Vec::new();
    for name in targets(&opts.env) {
        let (spec, origin) = Spec::resolve(&name)?;
        let s = &spec.search;
        let env_name = spec.env.env().name();
        let tmp = std::env::temp_dir().join(format!("bfqi-bench-search-{}-{env_name}", std::process::id()));
        let ev = Evaluator::new(spec.clone(), &tmp);
        let t = Instant::now();
        let transitions = ev.dataset(0)?.0.len();
        let dataset_s = t.elapsed().as_secs_f64();
        let enc_models = ev.dataset(0)?.1.n_models();
        let widths = Shape::new(ev.dataset(0)?.1.n_inputs(), &s.network.hidden, Activation::Sigmoid).widths().to_vec();
        let arrow: Vec<String> = widths.iter().map(usize::to_string).collect();
        say(format!(
            "\n{env_name} ({}) — population {}, {} datasets × {} episodes, K = {}, {} network(s) of {} per iteration, ≤ {} generations",
            origin.display(),
            s.ga.population,
            s.datasets,
            s.episodes,
            s.iterations,
            enc_models,
            arrow.join(" → "),
            s.stop.generations
        ));
        say(format!("  dataset 0: {transitions} transitions in {dataset_s:.2} s"));

        let shape_figures = one.install(|| shapes(&ev, crate::learn::cpu::mlp(), peak))?;
        say(format!("  network shape, {SHAPE_EPOCHS} epochs on the first model's rows, 1 thread:"));
        for f in &shape_figures {
            say(format!(
                "    {:<8} {} + {} rows: {:.3} ms/epoch · {:.1} GFLOP/s · {:.0} % of peak (multiply-adds alone {:.0} %) · bound {:.3} ms ({:.0} % of it reached)",
                f.activation,
                f.train_rows,
                f.val_rows,
                f.ms_per_epoch,
                f.gflops,
                f.percent_of_peak,
                f.percent_of_peak_matmul,
                f.bound_ms_per_epoch,
                100.0 * f.bound_ms_per_epoch / f.ms_per_epoch
            ));
        }

        let thesis = TunedConfig::resolve("thesis", env_name).ok().map(|(t, _)| Decoded {
            activation: t.activation,
            delta_min: t.delta_min,
            patience: t.patience,
        });
        let mut roles: Vec<(String, Decoded)> = Vec::new();
        if let Some(t) = thesis {
            roles.push(("thesis optimum".into(), t));
        }
        for (role, genes) in [("fast", FAST), ("slow", SLOW)] {
            if s.genes.contains(&genes) {
                roles.push((role.into(), decode(&genes, &s.genes)));
            }
        }
        say(format!(
            "  units (dataset 0, 1 thread, stopped after the iteration that passes {:.0} s):",
            opts.cap_seconds
        ));
        let mut units = Vec::new();
        let mut traces = Vec::new();
        for (role, set) in &roles {
            let (u, trace) = one.install(|| time_unit(&ev, role, set, opts.cap_seconds, None, peak))?;
            say(format!(
                "    {:<15} {:<22} {:>8.2} s  {}/{} iterations{}  {} epochs  {:.3} ms/epoch  {:.1} GFLOP/s ({:.0} % of peak){}",
                u.role,
                u.setting,
                u.seconds,
                u.iterations_run,
                u.iterations,
                if u.capped {
                    format!(" (capped; whole unit ≈ {})", human(u.projected_seconds))
                } else {
                    String::new()
                },
                u.epochs,
                u.ms_per_epoch,
                u.gflops,
                u.percent_of_peak,
                u.score.map_or(String::new(), |v| format!("  score {v:.3}"))
            ));
            units.push(u);
            traces.push(trace);
        }

        let across = match units.first() {
            Some(u) if threads > 1 => {
                let set = roles[0].1;
                let (u2, trace2) = time_unit(&ev, &u.role, &set, opts.cap_seconds, Some(u.iterations_run), peak)?;
                let a = AcrossCores {
                    setting: u.setting.clone(),
                    iterations: u.iterations_run,
                    threads,
                    seconds_one_thread: u.seconds,
                    seconds: u2.seconds,
                    speedup: u.seconds / u2.seconds,
                    identical: trace2 == traces[0],
                };
                say(format!(
                    "  one unit across cores: {} ({} iterations) {:.2} s on 1 thread, {:.2} s on {threads}: {:.2}× ({})",
                    a.setting,
                    a.iterations,
                    a.seconds_one_thread,
                    a.seconds,
                    a.speedup,
                    if a.identical { "identical results" } else { "RESULTS DIFFER" }
                ));
                Some(a)
            }
            _ => None,
        };

        // The first generation, as the search draws it.
        let population = initial_population(crate::ga::search::ga_seed(&spec), &s.genes, s.ga.population);
        let mut distinct: Vec<Decoded> = Vec::new();
        for c in &population {
            let d = decode(c, &s.genes);
            if !distinct.iter().any(|x| setting_id(x) == setting_id(&d)) {
                distinct.push(d);
            }
        }
        if !opts.json {
            eprintln!("  timing the first generation's {} settings on dataset 0…", distinct.len());
        }
        let mut first = Vec::new();
        for (i, set) in distinct.iter().enumerate() {
            let known = units.iter().find(|u| u.setting == setting_id(set)).cloned();
            let u = match known {
                Some(u) => u,
                None => {
                    one.install(|| {
                        time_unit(&ev, &format!("generation 0, setting {i}"), set, opts.cap_seconds, None, peak)
                    })?
                    .0
                }
            };
            first.push(u);
        }
        let jobs: Vec<f64> = first.iter().flat_map(|u| std::iter::repeat_n(u.projected_seconds, s.datasets)).collect();
        let generation_s = longest_first(jobs.clone(), threads);
        let slowest = jobs.iter().copied().fold(0.0, f64::max);
        let children = s.ga.population - s.ga.n_elites();
        let g = s.stop.generations as f64;
        let projection = Projection {
            method: "the first generation's chromosomes (drawn as the search draws them); each distinct setting's unit on dataset 0 timed on one thread (stopped after the iteration passing the cap, then projected from its iterations) and assumed to cost as much on every dataset; units scheduled longest first on the pool's threads",
            threads,
            population: s.ga.population,
            distinct_settings: distinct.len(),
            units_per_generation: jobs.len(),
            generation_s,
            slowest_unit_s: slowest,
            generations: s.stop.generations,
            search_s_all_like_first: generation_s * g,
            search_s_elites_reused: generation_s * (1.0 + (g - 1.0) * children as f64 / s.ga.population as f64),
            cluster_generation_s: slowest,
            units: first,
        };
        say(format!(
            "  projected default search here ({threads} threads; first generation's {} settings × {} datasets = {} units, each setting timed on dataset 0, longest first):",
            projection.distinct_settings, s.datasets, projection.units_per_generation
        ));
        say(format!(
            "    per generation ≈ {} (slowest unit {}); {} generations ≈ {} if each costs the first's, ≈ {} with the elites' units reused",
            human(projection.generation_s),
            human(projection.slowest_unit_s),
            s.stop.generations,
            human(projection.search_s_all_like_first),
            human(projection.search_s_elites_reused)
        ));
        say(format!(
            "    on a cluster (a task per unit): per generation ≈ the slowest unit, {}{}",
            human(slowest),
            across.as_ref().map_or(String::new(), |a| format!(
                " (≈ {} with {} cores per task, at the speed-up above)",
                human(slowest / a.speedup),
                a.threads
            ))
        ));

        let keras_figures = match (&reference, roles.first()) {
            (Some(py), Some((_, set))) => {
                let (ours, _) = time_unit(&ev, "thesis optimum, iteration 1", set, f64::INFINITY, Some(1), peak)?;
                let k = keras(py, &ev, set)?;
                let ratio = k.as_ref().and_then(|k| k["seconds"].as_f64()).map(|ks| ks / ours.seconds);
                if let (Some(k), Some(r)) = (&k, ratio) {
                    let kn = k["networks"].as_array().cloned().unwrap_or_default();
                    let kepochs: f64 = kn.iter().filter_map(|n| n["epochs"].as_f64()).sum();
                    let kms = kn
                        .iter()
                        .filter_map(|n| Some(n["epoch_ms_median"].as_f64()? * n["epochs"].as_f64()?))
                        .sum::<f64>()
                        / kepochs.max(1.0);
                    say(format!(
                        "  vs Keras {} on {} (thesis optimum, first FQI iteration, {} network(s), early-stopped, {threads} threads each): Keras {:.2} s, ours {:.3} s: {:.0}× (epochs {kepochs:.0} vs {}; per epoch {kms:.2} ms vs {:.3} ms)",
                        k["keras"].as_str().unwrap_or("?"),
                        k["backend"].as_str().unwrap_or("?"),
                        kn.len(),
                        k["seconds"].as_f64().unwrap_or(f64::NAN),
                        ours.seconds,
                        r,
                        ours.epochs,
                        ours.ms_per_epoch
                    ));
                }
                Some(json!({"ours": ours, "keras": k, "ratio": ratio}))
            }
            _ => None,
        };
        envs.push(json!({
            "env": env_name,
            "spec": origin.display().to_string(),
            "population": s.ga.population,
            "datasets": s.datasets,
            "episodes": s.episodes,
            "iterations": s.iterations,
            "generations": s.stop.generations,
            "networks_per_iteration": enc_models,
            "widths": widths,
            "dataset_transitions": transitions,
            "dataset_s": dataset_s,
            "shapes": shape_figures,
            "units": units,
            "unit_across_cores": across,
            "projection": projection,
            "keras": keras_figures,
        }));
    }
    if reference.is_none() {
        say("\n(no --python given: pass one with keras and jax to train the thesis optimum's first iteration in Keras 3 side by side)".into());
    }
    Ok(json!({
        "threads": threads,
        "kernels": kernel_isa(),
        "peak_gflops_per_core": peak,
        "cap_seconds": opts.cap_seconds,
        "envs": envs,
    }))
}
