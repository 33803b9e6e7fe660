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

use super::validate::{self, Row, Sweep};
use crate::error::{Error, Result};
use crate::model::cache::CacheStats;
use crate::model::config::OpCosts;
use crate::model::timing::CoreWork;
use crate::model::MachineConfig;

/// Scenes of the training sweep: built-in scenes none of `validate-model`'s
/// ([`validate::SCENES`]): a box (flat faces, few silhouette edges), an upright cylinder on the
/// ground (contact) and a 3×3×3 grid of spheres (paper 001's many overlapping shadows).
pub const TRAINING_SCENES: [&str; 3] = ["box-on-plane", "cylinder-on-plane", "sphere-grid"];

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

/// The training sweep of a fit and how well the fitted table predicts it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CostFit {
    /// The training sweep's scenes.
    pub scenes: Vec<String>,
    /// Runs and phases fitted.
    pub runs: usize,
    pub phases: usize,
    /// Mean absolute percentage error of the fitted table's prediction of the training runs and
    /// phases (the fit's own formula, not the cpu-model's), in percent.
    pub runs_mape: f64,
    pub phases_mape: f64,
}

impl CostFit {
    /// The scenes of `scenes` the fit was trained on (their runs are not held out).
    pub fn trained_on<'a>(&self, scenes: &'a [String]) -> Vec<&'a str> {
        scenes
            .iter()
            .filter(|x| self.scenes.contains(x))
            .map(String::as_str)
            .collect()
    }
}

/// The training sweep: `sweep` (algorithms, image sizes, maps, options, repeats) on
/// [`TRAINING_SCENES`].
pub fn training_sweep(sweep: &Sweep) -> Sweep {
    Sweep {
        scenes: TRAINING_SCENES.map(String::from).to_vec(),
        ..sweep.clone()
    }
}

/// Runs the training sweep with `kernels` (a machine from `model::calibrate`) and returns it
/// with the fitted issue costs (the memory figures unchanged) and each fitted figure's method
/// in `sources`. Errors: the sweep's errors; a sweep with fewer phases than costs to fit.
pub fn fit(
    kernels: &MachineConfig,
    sweep: &Sweep,
    progress: impl FnMut(&str),
) -> Result<(MachineConfig, CostFit)> {
    let training = validate::run(sweep, kernels, progress)?;
    let method = format!(
        "fitted by non-negative least squares (relative error) to the measured phases of the \
         training sweep ({} runs, {} phases: {} on {} at {}; none of validate-model's default scenes)",
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
    let ms = |r: &Row| predicted_ms(kernels, &costs, r);
    let rows = &training.phases;
    let phases_mape = mape(rows.iter().map(|r| (ms(r), r.measured_ms)));
    let runs_mape = mape(training.runs.iter().map(|run| {
        let of_run = rows.iter().filter(|p| {
            p.algorithm == run.algorithm && p.scene == run.scene && p.image == run.image
        });
        (of_run.map(ms).sum::<f64>(), run.measured_ms)
    }));
    let fit = CostFit {
        scenes: sweep.scenes.clone(),
        runs: training.runs.len(),
        phases: rows.len(),
        runs_mape,
        phases_mape,
    };
    Ok((m, fit))
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
