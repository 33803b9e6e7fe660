//! The host's issue costs fitted to a training sweep (`shadowbench calibrate`, `validate-model`).
//!
//! The calibration kernels (`model::calibrate`) measure what one idiom costs: latencies,
//! bandwidth and memory parallelism are properties of the memory system and come out right,
//! but a counted 16-lane instruction, line access or gather stands for different host code in
//! each kernel (one lane at a time, structure-of-arrays loops, `f64` edge arithmetic), and no
//! single kernel prices them all (`docs/model.md`, "Validation"). This module prices them from
//! the algorithms' own code instead: it runs a training sweep (every algorithm on
//! [`TRAINING_SCENES`], which `validate-model`'s scenes do not include) on `cpu-native` and
//! `cpu-model`, and finds by non-negative least squares the one cost table — per counted vector
//! instruction, active lane, scalar instruction, line loaded or stored, gathered line, gather,
//! atomic, and per phase — that best predicts every measured phase. The memory figures stay
//! as the kernels measured them; their stall time is taken off each phase before the fit.
//!
//! Per phase with `n` cores, in cycles at the machine's clock (`docs/model.md`, "Timing"):
//!
//! ```text
//! measured ≈ Σ_k c_k · work_k / n + stall / n + steps · barrier + c_phase
//! ```
//!
//! where `work_k` are the phase's counts summed over cores (even load assumed), `stall` the
//! model's stall cycles of its cache counts, `steps` its distinct steps. Each phase is weighted
//! by `1 / measured` (relative error: a 0.2 ms phase counts as much as a 200 ms one). One
//! table for the machine: nothing is per algorithm or per phase name.

use ndarray::{Array1, Array2};

use super::validate::{self, Agreement, Row, Sweep};
use crate::error::{Error, Result};
use crate::model::cache::CacheStats;
use crate::model::config::{OpCosts, Training};
use crate::model::timing::CoreWork;
use crate::model::MachineConfig;

/// Scenes of the training sweep: built-in scenes none of `validate-model`'s
/// ([`validate::SCENES`]): a box (flat faces, few silhouette edges), an upright cylinder on the
/// ground (contact) and a 3×3×3 grid of spheres (paper 001's many overlapping shadows).
pub const TRAINING_SCENES: [&str; 3] = ["box-on-plane", "cylinder-on-plane", "sphere-grid"];

/// Image sizes of the training sweep: none of `validate-model`'s ([`validate::IMAGES`]), and
/// modest, so that the training sweep is short.
pub const TRAINING_IMAGES: [[u32; 2]; 2] = [[240, 180], [480, 360]];

/// The fitted costs, in the order they are set (`fit`): machine field and the
/// [`validate::WORK_COUNTERS`] it multiplies (summed); `costs.phase` multiplies 1 per phase.
const FITTED: [(&str, &[&str]); 8] = [
    ("costs.vector", &["vector_ops"]),
    ("costs.lane", &["active_lanes"]),
    ("costs.scalar", &["scalar_ops"]),
    // The model charges `vector_memory` per line its loads and stores touch; the records count
    // the accesses, each of at most one line (the kernels' accesses are line-aligned blocks).
    ("costs.vector_memory", &["loads", "stores"]),
    ("costs.gather_line", &["gather_lines", "scatter_lines"]),
    ("costs.gather", &["gathers", "scatters"]),
    ("costs.atomic", &["atomics"]),
    ("costs.phase", &[]),
];

/// The training sweep: `sweep` (algorithms, maps, options, repeats, clock) on [`TRAINING_SCENES`]
/// at [`TRAINING_IMAGES`].
pub fn training_sweep(sweep: &Sweep) -> Sweep {
    Sweep {
        scenes: TRAINING_SCENES.map(String::from).to_vec(),
        images: TRAINING_IMAGES.to_vec(),
        ..sweep.clone()
    }
}

/// Runs the training sweep `sweep` with `kernels` (a machine from `model::calibrate`) and returns
/// it with the fitted issue costs (the memory figures unchanged), each fitted figure's method in
/// `sources` and the training sweep in `training` (which `validate-model` then holds out).
/// Errors: the sweep's errors; a sweep with fewer phases than costs to fit.
pub fn fit(
    kernels: &MachineConfig,
    sweep: &Sweep,
    progress: impl FnMut(&str),
) -> Result<(MachineConfig, Training)> {
    let training = validate::run(sweep, kernels, progress)?;
    let method = format!(
        "fitted by non-negative least squares (relative error) to the measured phases ({} clock) \
         of the training sweep ({} runs, {} phases: {} on {} at {})",
        sweep.clock.name(),
        training.runs.len(),
        training.phases.len(),
        sweep.algorithms.join(", "),
        sweep.scenes.join(", "),
        sweep
            .images
            .iter()
            .map(|[w, h]| format!("{w}x{h}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let fitted = fit_rows(kernels, &training.phases)?;
    let method = format!(
        "{method}, each phase's work weighted by the cpu-model's load imbalance, then scaled by \
         {:.3} for a geometric mean ratio of 1 over the training runs",
        fitted.scale
    );
    let mut m = kernels.clone();
    let mut sources = Vec::new();
    for (((field, _), slot), c) in FITTED.iter().zip(slots(&mut m.costs)).zip(fitted.costs) {
        let kernel = kernels
            .sources
            .get(*field)
            .map(|s| format!("; the kernel measured {:.3} ({s})", *slot))
            .unwrap_or_default();
        *slot = c;
        sources.push((field.to_string(), format!("{method}{kernel}")));
    }
    // The stall factor as the model's memory parallelism (it divides the stall cycles).
    let mlp = if fitted.stall > 0.0 {
        (1.0 / fitted.stall).clamp(1.0, 64.0)
    } else {
        64.0
    };
    sources.push((
        "memory_parallelism".into(),
        format!(
            "{method}: 1 / the fitted cycles per stall cycle ({:.4}), clamped to 1..=64 (it \
             includes what hardware prefetching hides); the kernels measured {:.2} ({})",
            fitted.stall,
            kernels.mlp(),
            kernels
                .sources
                .get("memory_parallelism")
                .map_or("no source", String::as_str)
        ),
    ));
    m.memory_parallelism = Some(mlp);
    m.sources.extend(sources);
    let rows = &training.phases;
    let phases_mape = mape(
        rows.iter()
            .map(|r| (predicted_ms(kernels, &fitted, r), r.measured_ms)),
    );
    let runs_mape = mape(
        predicted_runs(kernels, &fitted, &training.runs, rows)
            .into_iter()
            .map(|r| (r.modelled_ms, r.measured_ms)),
    );
    let fit = Training {
        scenes: sweep.scenes.clone(),
        images: sweep.images.clone(),
        map_resolution: sweep.map_resolution,
        clock: sweep.clock,
        runs: training.runs.len(),
        phases: rows.len(),
        runs_mape,
        phases_mape,
        load_average: training.load_average,
        waited_pct: training.waited_pct,
    };
    m.training = Some(fit.clone());
    Ok((m, fit))
}

/// `runs` with their modelled time replaced by the fit's prediction with `costs` (the sum over
/// the run's rows of `phases`).
fn predicted_runs(m: &MachineConfig, f: &Fitted, runs: &[Row], phases: &[Row]) -> Vec<Row> {
    runs.iter()
        .map(|run| {
            let t: f64 = phases
                .iter()
                .filter(|p| {
                    p.algorithm == run.algorithm && p.scene == run.scene && p.image == run.image
                })
                .map(|p| predicted_ms(m, f, p))
                .sum();
            Row {
                modelled_ms: t,
                ratio: t / run.measured_ms,
                ..run.clone()
            }
        })
        .collect()
}

/// One fold of a cross-validation over scenes: the scenes held out, and the fit's error on the
/// runs it trained on and on the held-out ones.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Fold {
    pub held_out: Vec<String>,
    pub training: Vec<String>,
    /// The fitted costs (cycles), by machine field.
    pub costs: Vec<(String, f64)>,
    pub training_runs: Agreement,
    pub held_out_runs: Agreement,
}

/// A k-fold cross-validation over scenes ([`cross_validate`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct CrossValidation {
    pub folds: Vec<Fold>,
    /// Every held-out run of every fold together (each run is held out in exactly one fold):
    /// the headline.
    pub held_out_runs: Agreement,
    /// The training images (fitted) and the held-out images (predicted).
    pub training_images: Vec<[u32; 2]>,
    pub held_out_images: Vec<[u32; 2]>,
    /// The held-out runs with the fold's prediction as `modelled_ms`.
    pub runs: Vec<Row>,
}

/// The scenes of fold `i` of `k`: every `k`-th scene from the `i`-th.
pub fn fold_scenes(scenes: &[String], k: usize, i: usize) -> Vec<String> {
    scenes
        .iter()
        .enumerate()
        .filter(|(j, _)| j % k == i)
        .map(|(_, s)| s.clone())
        .collect()
}

/// k-fold cross-validation over `scenes` of the measured `runs` and `phases` (rows of a sweep
/// run with [`validate::run`] at `training_images` and `held_out_images`, both on every scene,
/// on `m`'s cores and memory figures): fold `i` ([`fold_scenes`]) fits the costs on the other
/// folds' scenes at `training_images` and predicts its own scenes' runs at `held_out_images`
/// with the fit's formula (the work spread evenly over the cores; not the cpu-model's per-core
/// schedule). Errors: `k` outside 2..=scenes; a fold with too few phases to fit.
pub fn cross_validate(
    m: &MachineConfig,
    scenes: &[String],
    (runs, phases): (&[Row], &[Row]),
    training_images: &[[u32; 2]],
    held_out_images: &[[u32; 2]],
    k: usize,
) -> Result<CrossValidation> {
    if !(2..=scenes.len()).contains(&k) {
        return Err(Error::Other(format!(
            "{k} folds over {} scenes: the folds must number 2 to the scenes' count",
            scenes.len()
        )));
    }
    let mut folds = Vec::new();
    let mut all = Vec::new();
    for i in 0..k {
        let held_out = fold_scenes(scenes, k, i);
        let training: Vec<String> = scenes
            .iter()
            .filter(|s| !held_out.contains(s))
            .cloned()
            .collect();
        let pick = |rows: &[Row], sc: &[String], im: &[[u32; 2]]| -> Vec<Row> {
            rows.iter()
                .filter(|r| sc.contains(&r.scene) && im.contains(&r.image))
                .cloned()
                .collect()
        };
        let train_phases = pick(phases, &training, training_images);
        let fitted = fit_rows(m, &train_phases)?;
        let train_runs = predicted_runs(
            m,
            &fitted,
            &pick(runs, &training, training_images),
            &train_phases,
        );
        let test_runs = predicted_runs(
            m,
            &fitted,
            &pick(runs, &held_out, held_out_images),
            &pick(phases, &held_out, held_out_images),
        );
        folds.push(Fold {
            held_out,
            training,
            costs: FITTED
                .iter()
                .zip(fitted.costs)
                .map(|((f, _), c)| (f.to_string(), c))
                .chain([
                    ("stall".to_string(), fitted.stall),
                    ("scale".to_string(), fitted.scale),
                ])
                .collect(),
            training_runs: Agreement::of(&train_runs.iter().collect::<Vec<_>>()),
            held_out_runs: Agreement::of(&test_runs.iter().collect::<Vec<_>>()),
        });
        all.extend(test_runs);
    }
    Ok(CrossValidation {
        folds,
        held_out_runs: Agreement::of(&all.iter().collect::<Vec<_>>()),
        training_images: training_images.to_vec(),
        held_out_images: held_out_images.to_vec(),
        runs: all,
    })
}

/// The cross-validation's summary: per fold the training and held-out scenes, the training
/// and held-out error, then every held-out run together (the headline) and the sweep's clock and
/// load.
pub fn cross_validation_text(cv: &CrossValidation, v: &validate::Validation) -> String {
    let sizes = |v: &[[u32; 2]]| {
        v.iter()
            .map(|[w, h]| format!("{w}x{h}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let agreement = |a: &Agreement| {
        format!(
            "n {:>3}  geomean {:.3}  MAPE {:>5.1}%  Spearman {:.3}",
            a.n, a.geomean_ratio, a.mape_pct, a.spearman
        )
    };
    let mut s = format!(
        "{}-fold cross-validation over scenes (machine {}); fitted at {}, held out at {}; \
         predictions by the fit's formula; cpu-native on the {} clock\n",
        cv.folds.len(),
        v.machine.name,
        sizes(&cv.training_images),
        sizes(&cv.held_out_images),
        v.sweep.clock.name()
    );
    for (i, f) in cv.folds.iter().enumerate() {
        s += &format!(
            "fold {}: held out {}; trained on {}\n  training runs  {}\n  held-out runs  {}{}\n",
            i + 1,
            f.held_out.join(", "),
            f.training.join(", "),
            agreement(&f.training_runs),
            agreement(&f.held_out_runs),
            if f.held_out_runs.mape_pct > f.training_runs.mape_pct {
                "  (worse than training)"
            } else {
                ""
            }
        );
    }
    s += &format!("all held-out runs  {}\n", agreement(&cv.held_out_runs));
    if let Some([a, b]) = v.load_average {
        s += &format!("host load average {a:.2} at the start, {b:.2} at the end\n");
    }
    if let Some(w) = &v.load_warning {
        s += w;
        s += "\n";
    }
    s
}

/// The fields of `k` the fit sets, in [`FITTED`] order.
fn slots(k: &mut OpCosts) -> [&mut f64; FITTED.len()] {
    [
        &mut k.vector,
        &mut k.lane,
        &mut k.scalar,
        &mut k.vector_memory,
        &mut k.gather_line,
        &mut k.gather,
        &mut k.atomic,
        &mut k.phase,
    ]
}

/// The costs the fit sets, by machine field (`costs.vector`, ...), in cycles.
pub fn fitted_costs(k: &OpCosts) -> Vec<(&'static str, f64)> {
    let mut k = k.clone();
    FITTED
        .iter()
        .zip(slots(&mut k))
        .map(|((field, _), v)| (*field, *v))
        .collect()
}

/// A fitted cost table ([`fit_rows`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fitted {
    /// The [`FITTED`] costs, cycles, in its order.
    pub costs: [f64; FITTED.len()],
    /// Cycles charged per stall cycle of the phase's cache counts at memory parallelism 1 (the
    /// machine's latencies): `1 / memory_parallelism` of the timing model.
    pub stall: f64,
    /// The factor the least-squares issue costs and stall were multiplied by so that the
    /// training runs' geometric mean ratio is 1 (relative-error least squares predicts low).
    pub scale: f64,
}

/// Fits a cost table to `rows` (phases measured on the host and modelled on `m`: its cores,
/// clock, latencies and barrier). Per phase, in cycles,
///
/// ```text
/// measured ≈ g · (Σ_k c_k · work_k / n + c_stall · stall₁ / n) + c_phase + steps · barrier
/// ```
///
/// with `stall₁` the stall cycles of its cache counts at memory parallelism 1 and `g`
/// ([`imbalance`]) how much longer than an even spread over the `n` cores the cpu-model's own
/// schedule made the phase. The costs `c_k`, `c_stall`, `c_phase ≥ 0` minimise the squared
/// relative error (non-negative least squares, Lawson and Hanson 1974, each phase weighted by
/// 1 / measured); then the issue costs and `c_stall` are scaled by one factor so that the
/// geometric mean of predicted over measured training runs (the sums of their phases) is 1.
/// Rows whose measured time is not a positive number carry nothing to fit and are left out.
/// Errors: fewer usable rows than costs.
pub fn fit_rows(m: &MachineConfig, rows: &[Row]) -> Result<Fitted> {
    let rows: Vec<&Row> = rows
        .iter()
        .filter(|r| r.measured_ms.is_finite() && r.measured_ms > 0.0)
        .collect();
    let columns = FITTED.len() + 1;
    if rows.len() < columns {
        return Err(Error::Other(format!(
            "the training sweep measured {} phases with a positive time; fitting {columns} costs \
             needs at least as many",
            rows.len(),
        )));
    }
    let cycles_per_ms = m.cycles_per_ms();
    let mut a = Array2::<f64>::zeros((rows.len(), columns));
    let mut b = Array1::<f64>::zeros(rows.len());
    for (i, r) in rows.iter().enumerate() {
        let weight = 1.0 / (r.measured_ms * cycles_per_ms);
        for (j, x) in features(m, r).into_iter().enumerate() {
            a[[i, j]] = x * weight;
        }
        b[i] = (r.measured_ms * cycles_per_ms - barriers(m, r)) * weight;
    }
    // Columns to unit length (the counts span eight orders of magnitude), solved, scaled back.
    let norms: Vec<f64> = a
        .columns()
        .into_iter()
        .map(|c| c.dot(&c).sqrt().max(f64::MIN_POSITIVE))
        .collect();
    for (mut c, n) in a.columns_mut().into_iter().zip(&norms) {
        c /= *n;
    }
    let (x, _) = nnls::nnls(a.view(), b.view());
    let mut fitted = Fitted {
        costs: std::array::from_fn(|j| x[j] / norms[j]),
        stall: x[FITTED.len()] / norms[FITTED.len()],
        scale: 1.0,
    };
    // Per training run (the phases of one algorithm, scene and size): the scaled part, the
    // fixed part and the measured time, ms.
    type Run<'a> = (&'a str, &'a str, [u32; 2]);
    let mut groups: Vec<(Run, [f64; 3])> = Vec::new();
    for r in &rows {
        let k = (r.algorithm.as_str(), r.scene.as_str(), r.image);
        let (scaled, fixed) = parts_ms(m, &fitted, r);
        match groups.iter_mut().find(|(g, _)| *g == k) {
            Some((_, v)) => {
                v[0] += scaled;
                v[1] += fixed;
                v[2] += r.measured_ms;
            }
            None => groups.push((k, [scaled, fixed, r.measured_ms])),
        }
    }
    // Σ ln((s·A + B) / T) rises with s: bisection on ln s.
    let log_bias = |s: f64| -> f64 {
        groups
            .iter()
            .map(|(_, [a, b, t])| ((s * a + b) / t).ln())
            .sum()
    };
    if groups.iter().any(|(_, [a, _, _])| *a > 0.0) {
        let (mut lo, mut hi) = (-10.0f64, 10.0f64);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if log_bias(mid.exp()) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let s = (0.5 * (lo + hi)).exp();
        fitted.scale = s;
        fitted.stall *= s;
        for (c, (field, _)) in fitted.costs.iter_mut().zip(FITTED) {
            if field != "costs.phase" {
                *c *= s;
            }
        }
    }
    Ok(fitted)
}

/// How much longer than an even spread of its work over the cores the cpu-model's schedule
/// made phase `r` on `m` (the machine that modelled it): its modelled time less its barriers
/// and phase cost, over the even spread's issue and stall cycles with `m`'s costs; 1 where
/// that is not a number above 1, at most 4 (a phase whose steps run many times has more
/// barriers than the distinct steps the row counts).
pub fn imbalance(m: &MachineConfig, r: &Row) -> f64 {
    let x = work_per_core(m, r);
    let issue: f64 = FITTED
        .iter()
        .zip(&x)
        .zip(fitted_costs(&m.costs))
        .filter(|(((field, _), _), _)| *field != "costs.phase")
        .map(|((_, x), (_, c))| x * c)
        .sum();
    let even = issue + stall_cycles(m, r) / m.mlp() / f64::from(m.cores);
    let g = (r.modelled_ms * m.cycles_per_ms() - barriers(m, r) - m.costs.phase) / even;
    if g.is_finite() && even > 0.0 {
        g.clamp(1.0, 4.0)
    } else {
        1.0
    }
}

/// The fit's prediction of a phase's time with `f`, ms.
pub fn predicted_ms(m: &MachineConfig, f: &Fitted, r: &Row) -> f64 {
    let (scaled, fixed) = parts_ms(m, f, r);
    scaled + fixed
}

/// A phase's predicted time in the part the scale multiplies (issue and stall) and the rest
/// (phase cost and barriers), ms.
fn parts_ms(m: &MachineConfig, f: &Fitted, r: &Row) -> (f64, f64) {
    let x = features(m, r);
    let mut scaled = 0.0;
    let mut fixed = barriers(m, r);
    for (j, (field, _)) in FITTED.iter().enumerate() {
        if *field == "costs.phase" {
            fixed += x[j] * f.costs[j];
        } else {
            scaled += x[j] * f.costs[j];
        }
    }
    scaled += x[FITTED.len()] * f.stall;
    let c = m.cycles_per_ms();
    (scaled / c, fixed / c)
}

/// The phase's columns: for each [`FITTED`] cost its work per core times [`imbalance`] (1 for
/// `costs.phase`), then the stall cycles at memory parallelism 1 per core times the imbalance.
fn features(m: &MachineConfig, r: &Row) -> [f64; FITTED.len() + 1] {
    let g = imbalance(m, r);
    let x = work_per_core(m, r);
    std::array::from_fn(|j| match FITTED.get(j) {
        Some((_, [])) => 1.0,
        Some(_) => g * x[j],
        None => g * stall_cycles(m, r) / f64::from(m.cores),
    })
}

/// The phase's work per core for each [`FITTED`] cost (1 for `costs.phase`).
fn work_per_core(m: &MachineConfig, r: &Row) -> [f64; FITTED.len()] {
    let cores = f64::from(m.cores);
    FITTED.map(|(_, counters)| {
        if counters.is_empty() {
            1.0
        } else {
            counters.iter().map(|k| work(r, k)).sum::<f64>() / cores
        }
    })
}

fn work(r: &Row, k: &str) -> f64 {
    r.work.get(k).copied().unwrap_or(0.0)
}

/// The stall cycles of the phase's cache counts with `m`'s latencies at memory parallelism 1
/// (as [`CoreWork::stall_cycles`] times the machine's memory parallelism), summed over cores.
fn stall_cycles(m: &MachineConfig, r: &Row) -> f64 {
    let count = |k: &str| work(r, k) as u64;
    let cache = CacheStats {
        l2_hits: count("cache.l2_hits"),
        l2_misses: count("cache.l2_misses"),
        l3_hits: count("cache.l3_hits"),
        l3_misses: count("cache.l3_misses"),
        ..Default::default()
    };
    CoreWork {
        cache,
        ..Default::default()
    }
    .stall_cycles(m)
        * m.mlp()
}

/// A barrier per distinct step of the phase, cycles.
fn barriers(m: &MachineConfig, r: &Row) -> f64 {
    work(r, "steps") * m.barrier_cycles
}

/// Mean absolute percentage error of (predicted, measured) pairs, in percent.
fn mape(pairs: impl Iterator<Item = (f64, f64)>) -> f64 {
    let (p, y): (Vec<f64>, Vec<f64>) = pairs.unzip();
    validate::mape(&p, &y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// A phase row with `work` and a measured time.
    fn row(work: BTreeMap<String, f64>, measured_ms: f64) -> Row {
        Row {
            algorithm: "a".into(),
            scene: "s".into(),
            image: [8, 8],
            phase: Some("p".into()),
            // No modelled time: the imbalance is 1 (`imbalance`).
            modelled_ms: 0.0,
            measured_ms,
            measured_min_ms: measured_ms,
            measured_max_ms: measured_ms,
            wall_ms: measured_ms,
            steps_ms: measured_ms,
            ratio: 1.0,
            run_wall_ms: None,
            run_cpu_ms: None,
            cpu_ms: None,
            work,
        }
    }

    /// Phases of varied work (a fixed pseudo-random sequence), timed by a known cost table
    /// through the fit's formula: the fit gives the table back.
    #[test]
    fn the_fit_recovers_the_cost_table_that_timed_the_phases() {
        let m = MachineConfig::larrabee(2);
        let truth = Fitted {
            costs: [3.0, 0.0, 2.0, 40.0, 15.0, 0.0, 20.0, 50_000.0],
            stall: 0.25,
            scale: 1.0,
        };
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |scale: f64| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 * scale
        };
        let rows: Vec<Row> = (0..40)
            .map(|_| {
                let vector = next(1e7);
                let work: BTreeMap<String, f64> = [
                    ("vector_ops", vector),
                    ("active_lanes", vector * (4.0 + next(12.0))),
                    ("scalar_ops", next(1e6)),
                    ("loads", next(1e5)),
                    ("stores", next(1e5)),
                    ("gathers", next(1e4)),
                    ("gather_lines", next(1e5)),
                    ("atomics", next(1e4)),
                    ("cache.l2_hits", next(1e5)),
                    ("cache.l2_misses", next(1e4)),
                    ("steps", (1.0 + next(4.0)).floor()),
                ]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect();
                let r = row(work, 1.0);
                let t = predicted_ms(&m, &truth, &r);
                row(r.work, t)
            })
            .collect();
        let fitted = fit_rows(&m, &rows).unwrap();
        for (i, (f, t)) in fitted.costs.iter().zip(truth.costs).enumerate() {
            assert!(
                (f - t).abs() <= 1e-6 * t.max(1.0),
                "{}: fitted {f}, truth {t}",
                FITTED[i].0
            );
        }
        assert!((fitted.stall - truth.stall).abs() < 1e-9, "{fitted:?}");
        // Exact times are unbiased already.
        assert!((fitted.scale - 1.0).abs() < 1e-9, "{fitted:?}");
    }

    /// Times off the formula by a pseudo-random factor in 0.6..1.4 per phase: the least-squares
    /// table is rescaled so that the training runs' geometric mean ratio is 1 exactly.
    #[test]
    fn the_fitted_table_predicts_the_training_runs_without_bias() {
        let m = MachineConfig::larrabee(2);
        let truth = [3.0, 0.5, 2.0, 40.0, 15.0, 0.0, 20.0, 50_000.0];
        let (runs, mut phases) = synthetic_sweep(&truth, 1.0);
        let mut state = 7u64;
        for p in &mut phases {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            p.measured_ms *= 0.6 + 0.8 * ((state >> 11) as f64 / (1u64 << 53) as f64);
        }
        let fitted = fit_rows(&m, &phases).unwrap();
        assert!((fitted.scale - 1.0).abs() > 1e-3, "{fitted:?}");
        let runs: Vec<Row> = runs
            .into_iter()
            .map(|r| {
                let t = phases
                    .iter()
                    .filter(|p| {
                        (&p.algorithm, &p.scene, p.image) == (&r.algorithm, &r.scene, r.image)
                    })
                    .map(|p| p.measured_ms)
                    .sum();
                Row {
                    measured_ms: t,
                    ..r
                }
            })
            .collect();
        let predicted = predicted_runs(&m, &fitted, &runs, &phases);
        let ratios: Vec<f64> = predicted.iter().map(|r| r.ratio).collect();
        assert!((validate::geomean(&ratios) - 1.0).abs() < 1e-9);
    }

    /// A phase the cpu-model timed at 1.5× the even spread of its work (plus its barriers):
    /// imbalance 1.5; below the even spread 1; far above it 4.
    #[test]
    fn the_imbalance_is_the_modelled_time_over_the_even_spread() {
        let m = MachineConfig::larrabee(2);
        let work: BTreeMap<String, f64> = [("vector_ops", 4e6), ("stores", 1e5), ("steps", 2.0)]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect();
        // Larrabee: 1 cycle per vector instruction and per line, 2000 per barrier, 1 GHz.
        let even_cycles = (4e6 + 1e5) / 2.0;
        for (factor, g) in [(1.5, 1.5), (0.5, 1.0), (10.0, 4.0)] {
            let mut r = row(work.clone(), 1.0);
            r.modelled_ms = (factor * even_cycles + 2.0 * 2000.0) / 1e6;
            assert!((imbalance(&m, &r) - g).abs() < 1e-9, "{factor}");
        }
    }

    /// Runs of 3 algorithms × 4 scenes × 2 image sizes, 3 phases each of pseudo-random work,
    /// timed by `truth` through the fit's formula; the held-out size's measured times
    /// multiplied by `held_out_factor`.
    fn synthetic_sweep(costs: &[f64; FITTED.len()], held_out_factor: f64) -> (Vec<Row>, Vec<Row>) {
        let truth = &Fitted {
            costs: *costs,
            stall: 0.5,
            scale: 1.0,
        };
        let m = MachineConfig::larrabee(2);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = |scale: f64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * scale
        };
        let (mut runs, mut phases) = (Vec::new(), Vec::new());
        for scene in ["s0", "s1", "s2", "s3"] {
            for image in [[8, 8], [16, 16]] {
                for alg in ["a0", "a1", "a2"] {
                    let mut total = 0.0;
                    for p in ["p0", "p1", "p2"] {
                        let vector = next(1e7);
                        let work: BTreeMap<String, f64> = [
                            ("vector_ops", vector),
                            ("active_lanes", vector * (4.0 + next(12.0))),
                            ("scalar_ops", next(1e6)),
                            ("loads", next(1e5)),
                            ("stores", next(1e5)),
                            ("gathers", next(1e4)),
                            ("gather_lines", next(1e5)),
                            ("atomics", next(1e4)),
                            ("cache.l2_misses", next(1e4)),
                            ("steps", (1.0 + next(4.0)).floor()),
                        ]
                        .into_iter()
                        .map(|(k, v)| (k.to_string(), v))
                        .collect();
                        let mut r = row(work, 1.0);
                        let factor = if image == [16, 16] {
                            held_out_factor
                        } else {
                            1.0
                        };
                        r.measured_ms = predicted_ms(&m, truth, &r) * factor;
                        (r.algorithm, r.scene, r.image, r.phase) =
                            (alg.into(), scene.into(), image, Some(p.into()));
                        total += r.measured_ms;
                        phases.push(r);
                    }
                    let mut run = row(BTreeMap::new(), total);
                    (run.algorithm, run.scene, run.image, run.phase) =
                        (alg.into(), scene.into(), image, None);
                    runs.push(run);
                }
            }
        }
        (runs, phases)
    }

    #[test]
    fn folds_take_every_kth_scene_and_cover_each_once() {
        let scenes: Vec<String> = (0..5).map(|i| format!("s{i}")).collect();
        assert_eq!(fold_scenes(&scenes, 2, 0), ["s0", "s2", "s4"]);
        assert_eq!(fold_scenes(&scenes, 2, 1), ["s1", "s3"]);
        let mut all: Vec<String> = (0..3).flat_map(|i| fold_scenes(&scenes, 3, i)).collect();
        all.sort();
        assert_eq!(all, scenes);
    }

    /// Exact synthetic times: every fold recovers the table and predicts its held-out runs
    /// exactly. With the held-out size's times doubled: the training runs still fit exactly
    /// (the held-out rows take no part in the fit) and every held-out prediction is half the
    /// measured time (geometric mean 0.5, MAPE 50%).
    #[test]
    fn cross_validation_fits_on_the_training_folds_and_scores_the_held_out_ones() {
        let m = MachineConfig::larrabee(2);
        let truth = [3.0, 0.5, 2.0, 40.0, 15.0, 0.0, 20.0, 50_000.0];
        let scenes: Vec<String> = ["s0", "s1", "s2", "s3"].map(String::from).to_vec();
        for (factor, geomean, mape) in [(1.0, 1.0, 0.0), (2.0, 0.5, 50.0)] {
            let (runs, phases) = synthetic_sweep(&truth, factor);
            let cv =
                cross_validate(&m, &scenes, (&runs, &phases), &[[8, 8]], &[[16, 16]], 2).unwrap();
            assert_eq!(cv.folds.len(), 2);
            assert_eq!(cv.folds[0].held_out, ["s0", "s2"]);
            assert_eq!(cv.folds[0].training, ["s1", "s3"]);
            for f in &cv.folds {
                for ((field, c), t) in f.costs.iter().zip(truth.iter().chain(&[0.5, 1.0])) {
                    assert!((c - t).abs() <= 1e-6 * t.max(1.0), "{field}: {c} vs {t}");
                }
                // 2 scenes × 3 algorithms at the one training size, the same held out.
                assert_eq!((f.training_runs.n, f.held_out_runs.n), (6, 6));
                assert!(f.training_runs.mape_pct < 1e-6, "{:?}", f.training_runs);
            }
            // Each run held out once: 4 scenes × 3 algorithms at the held-out size.
            assert_eq!(cv.held_out_runs.n, 12);
            assert!(cv.runs.iter().all(|r| r.image == [16, 16]));
            let a = &cv.held_out_runs;
            assert!((a.geomean_ratio - geomean).abs() < 1e-6, "{a:?}");
            assert!((a.mape_pct - mape).abs() < 1e-4, "{a:?}");
        }
        let (runs, phases) = synthetic_sweep(&truth, 1.0);
        for k in [1, 5] {
            assert!(
                cross_validate(&m, &scenes, (&runs, &phases), &[[8, 8]], &[[16, 16]], k).is_err()
            );
        }
    }

    #[test]
    fn too_few_phases_with_a_time_is_an_error() {
        let m = MachineConfig::larrabee(2);
        let work: BTreeMap<String, f64> = [("vector_ops".to_string(), 1e3)].into();
        let mut rows: Vec<Row> = (0..=FITTED.len()).map(|_| row(work.clone(), 1.0)).collect();
        assert!(fit_rows(&m, &rows).is_ok());
        // A phase without a usable time is left out: one row short.
        rows[3].measured_ms = f64::NAN;
        let e = fit_rows(&m, &rows).unwrap_err().to_string();
        assert!(e.contains("8 phases with a positive time"), "{e}");
        rows[3].measured_ms = 0.0;
        assert!(fit_rows(&m, &rows).is_err());
    }
}
