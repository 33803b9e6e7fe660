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
    let costs = fit_rows(kernels, &training.phases)?;
    let mut m = kernels.clone();
    let mut sources = Vec::new();
    for (((field, _), slot), c) in FITTED.iter().zip(slots(&mut m.costs)).zip(costs) {
        let kernel = kernels
            .sources
            .get(*field)
            .map(|s| format!("; the kernel measured {:.3} ({s})", *slot))
            .unwrap_or_default();
        *slot = c;
        sources.push((field.to_string(), format!("{method}{kernel}")));
    }
    m.sources.extend(sources);
    let rows = &training.phases;
    let phases_mape = mape(
        rows.iter()
            .map(|r| (predicted_ms(kernels, &costs, r), r.measured_ms)),
    );
    let runs_mape = mape(
        predicted_runs(kernels, &costs, &training.runs, rows)
            .into_iter()
            .map(|r| (r.modelled_ms, r.measured_ms)),
    );
    let fit = Training {
        scenes: sweep.scenes.clone(),
        images: sweep.images.clone(),
        map_resolution: sweep.map_resolution,
        clock: sweep.clock.name().into(),
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
fn predicted_runs(
    m: &MachineConfig,
    costs: &[f64; FITTED.len()],
    runs: &[Row],
    phases: &[Row],
) -> Vec<Row> {
    runs.iter()
        .map(|run| {
            let t: f64 = phases
                .iter()
                .filter(|p| {
                    p.algorithm == run.algorithm && p.scene == run.scene && p.image == run.image
                })
                .map(|p| predicted_ms(m, costs, p))
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

/// k-fold cross-validation over the scenes of `measured` (a sweep run with [`validate::run`]
/// at `training_images` and `held_out_images`, both on every scene): fold `i` fits the costs
/// on the other folds' scenes at `training_images` and predicts its own scenes' runs at
/// `held_out_images` with the fit's formula (the work spread evenly over the cores; not the
/// cpu-model's per-core schedule). Errors: `k` outside 2..=scenes; a fold with too few phases
/// to fit.
pub fn cross_validate(
    m: &MachineConfig,
    measured: &validate::Validation,
    training_images: &[[u32; 2]],
    held_out_images: &[[u32; 2]],
    k: usize,
) -> Result<CrossValidation> {
    let scenes = &measured.sweep.scenes;
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
        let train_phases = pick(&measured.phases, &training, training_images);
        let costs = fit_rows(m, &train_phases)?;
        let train_runs = predicted_runs(
            m,
            &costs,
            &pick(&measured.runs, &training, training_images),
            &train_phases,
        );
        let test_runs = predicted_runs(
            m,
            &costs,
            &pick(&measured.runs, &held_out, held_out_images),
            &pick(&measured.phases, &held_out, held_out_images),
        );
        folds.push(Fold {
            held_out,
            training,
            costs: FITTED
                .iter()
                .zip(costs)
                .map(|((f, _), c)| (f.to_string(), c))
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
    s += &format!(
        "all held-out runs  {}\n",
        agreement(&cv.held_out_runs)
    );
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

/// The [`FITTED`] costs (cycles, in its order) that best predict the measured time of `rows`
/// (phases) on `m`'s cores, clock, latencies and barrier. Rows whose measured time is not a
/// positive number carry nothing to fit and are left out. Errors: fewer usable rows than costs.
pub fn fit_rows(m: &MachineConfig, rows: &[Row]) -> Result<[f64; FITTED.len()]> {
    let rows: Vec<&Row> = rows
        .iter()
        .filter(|r| r.measured_ms.is_finite() && r.measured_ms > 0.0)
        .collect();
    if rows.len() < FITTED.len() {
        return Err(Error::Other(format!(
            "the training sweep measured {} phases with a positive time; fitting {} costs needs \
             at least as many",
            rows.len(),
            FITTED.len()
        )));
    }
    let cycles_per_ms = m.cycles_per_ms();
    let cores = f64::from(m.cores);
    let mut a = Array2::<f64>::zeros((rows.len(), FITTED.len()));
    let mut b = Array1::<f64>::zeros(rows.len());
    for (i, r) in rows.iter().enumerate() {
        let weight = 1.0 / (r.measured_ms * cycles_per_ms);
        for (j, x) in features(r, cores).into_iter().enumerate() {
            a[[i, j]] = x * weight;
        }
        b[i] = (r.measured_ms * cycles_per_ms - fixed_cycles(m, r)) * weight;
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
    Ok(std::array::from_fn(|j| x[j] / norms[j]))
}

/// The fit's prediction of a phase's time with `costs` ([`FITTED`] order), ms.
fn predicted_ms(m: &MachineConfig, costs: &[f64; FITTED.len()], r: &Row) -> f64 {
    let x = features(r, f64::from(m.cores));
    let issue: f64 = x.iter().zip(costs).map(|(x, c)| x * c).sum();
    (issue + fixed_cycles(m, r)) / m.cycles_per_ms()
}

/// The phase's work per core for each [`FITTED`] cost.
fn features(r: &Row, cores: f64) -> [f64; FITTED.len()] {
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

/// Cycles of the phase the fit does not price: the stalls of its cache counts over the cores
/// (as [`CoreWork::stall_cycles`]) and a barrier per distinct step.
fn fixed_cycles(m: &MachineConfig, r: &Row) -> f64 {
    let count = |k: &str| work(r, k) as u64;
    let cache = CacheStats {
        l2_hits: count("cache.l2_hits"),
        l2_misses: count("cache.l2_misses"),
        l3_hits: count("cache.l3_hits"),
        l3_misses: count("cache.l3_misses"),
        ..Default::default()
    };
    let stall = CoreWork {
        cache,
        ..Default::default()
    }
    .stall_cycles(m);
    stall / f64::from(m.cores) + work(r, "steps") * m.barrier_cycles
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
            modelled_ms: 1.0,
            measured_ms,
            measured_min_ms: measured_ms,
            measured_max_ms: measured_ms,
            wall_ms: measured_ms,
            steps_ms: measured_ms,
            ratio: 1.0,
            run_wall_ms: None,
            cpu_ms: None,
            work,
        }
    }

    /// Phases of varied work (a fixed pseudo-random sequence), timed by a known cost table
    /// through the fit's formula: the fit gives the table back.
    #[test]
    fn the_fit_recovers_the_cost_table_that_timed_the_phases() {
        let m = MachineConfig::larrabee(2);
        let truth = [3.0, 0.0, 2.0, 40.0, 15.0, 0.0, 20.0, 50_000.0];
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
        for (i, (f, t)) in fitted.iter().zip(truth).enumerate() {
            assert!(
                (f - t).abs() <= 1e-6 * t.max(1.0),
                "{}: fitted {f}, truth {t}",
                FITTED[i].0
            );
        }
    }

    #[test]
    fn too_few_phases_with_a_time_is_an_error() {
        let m = MachineConfig::larrabee(2);
        let work: BTreeMap<String, f64> = [("vector_ops".to_string(), 1e3)].into();
        let mut rows: Vec<Row> = (0..FITTED.len()).map(|_| row(work.clone(), 1.0)).collect();
        assert!(fit_rows(&m, &rows).is_ok());
        // A phase without a usable time is left out: one row short.
        rows[3].measured_ms = f64::NAN;
        let e = fit_rows(&m, &rows).unwrap_err().to_string();
        assert!(e.contains("7 phases with a positive time"), "{e}");
        rows[3].measured_ms = 0.0;
        assert!(fit_rows(&m, &rows).is_err());
    }
}
