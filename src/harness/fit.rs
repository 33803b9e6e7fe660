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
    let rows = &training.phases;
    if rows.len() < FITTED.len() {
        return Err(Error::Other(format!(
            "the training sweep measured {} phases; fitting {} costs needs at least as many",
            rows.len(),
            FITTED.len()
        )));
    }
    let cycles_per_ms = kernels.clock_ghz * 1e6;
    let cores = f64::from(kernels.cores);
    let mut a = Array2::<f64>::zeros((rows.len(), FITTED.len()));
    let mut b = Array1::<f64>::zeros(rows.len());
    for (i, r) in rows.iter().enumerate() {
        let weight = 1.0 / (r.measured_ms * cycles_per_ms);
        for (j, x) in features(r, cores).into_iter().enumerate() {
            a[[i, j]] = x * weight;
        }
        b[i] = (r.measured_ms * cycles_per_ms - fixed_cycles(kernels, r)) * weight;
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
    let costs: [f64; FITTED.len()] = std::array::from_fn(|j| x[j] / norms[j]);

    let mut m = kernels.clone();
    let method = format!(
        "fitted by non-negative least squares (relative error) to the measured phases of the \
         training sweep ({} runs, {} phases: {} on {} at {}; none of validate-model's scenes)",
        training.runs.len(),
        rows.len(),
        sweep.algorithms.join(", "),
        sweep.scenes.join(", "),
        sweep
            .images
            .iter()
            .map(|[w, h]| format!("{w}x{h}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let k = &mut m.costs;
    let kernel_costs = [
        k.vector,
        k.lane,
        k.scalar,
        k.vector_memory,
        k.gather_line,
        k.gather,
        k.atomic,
        k.phase,
    ];
    [
        k.vector,
        k.lane,
        k.scalar,
        k.vector_memory,
        k.gather_line,
        k.gather,
        k.atomic,
        k.phase,
    ] = costs;
    for ((field, _), was) in FITTED.iter().zip(kernel_costs) {
        let kernel = m
            .sources
            .get(*field)
            .map(|s| format!("; the kernel measured {was:.3} ({s})"))
            .unwrap_or_default();
        m.sources
            .insert(field.to_string(), format!("{method}{kernel}"));
    }
    let predicted = |r: &Row| {
        let x = features(r, cores);
        (x.iter().zip(&costs).map(|(x, c)| x * c).sum::<f64>() + fixed_cycles(kernels, r))
            / cycles_per_ms
    };
    let phases_mape = mape(rows.iter().map(|r| (predicted(r), r.measured_ms)));
    let runs_mape = mape(training.runs.iter().map(|run| {
        let of_run = rows.iter().filter(|p| {
            p.algorithm == run.algorithm && p.scene == run.scene && p.image == run.image
        });
        (of_run.map(predicted).sum::<f64>(), run.measured_ms)
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
