//! `shadowbench validate-model`: the cpu-model's modelled times against the cpu-native's measured
//! times of the same runs on this machine, modelled with one machine description (the calibrated
//! host) and no per-algorithm factor.
//!
//! For each case of a fixed sweep (every CPU algorithm × scenes × image sizes) the frame is built
//! once; `cpu-native` runs once to warm up and then `repeats` times (median of each phase's wall
//! time, and of their sum for the run); `cpu-model` runs once (its times are deterministic).
//! Measured run time is the sum of the phases' wall times: what the model models. The run's
//! whole wall time (with the host-side setup between phases) is reported beside it.
//!
//! Agreement is summarised as simulators report it against hardware (e.g. Accel-Sim): the
//! geometric mean of modelled / measured, the mean absolute percentage error
//! `100 · mean(|modelled − measured| / measured)`, and Spearman's rank correlation.
//!
//! Measured times are on the sweep's [`Clock`]: by default CPU time (each phase's
//! `execution.phase_cpu_ms`: the calling thread's CPU time plus the worker threads' over their
//! count), so that other processes' load is not measured as the machine's cost; the wall-clock
//! figures are kept beside it. The validation holds out by construction: a machine whose issue
//! costs were fitted (`MachineConfig::training`) is validated only on scenes and image sizes
//! its training sweep did not contain ([`check_held_out`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::algorithms::{self, Backend, ExecContext};
use crate::error::{Error, InputError, Result};
use crate::frame::{Frame, RunParams};
use crate::model::config::Training;
use crate::model::MachineConfig;
use crate::scenario;
use crate::scene::generators::GeneratorParams;
use crate::util::cpu_time::{self, Clock, Load};

/// The sweep `validate-model` runs.
#[derive(Clone, Debug, Serialize)]
pub struct Sweep {
    pub algorithms: Vec<String>,
    pub scenes: Vec<String>,
    pub images: Vec<[u32; 2]>,
    pub map_resolution: u32,
    pub tile_size: u32,
    /// Per-algorithm options (`options.<algorithm>` of a scenario).
    pub options: BTreeMap<String, serde_json::Value>,
    /// Timed `cpu-native` runs per case (after one warm-up run).
    pub repeats: usize,
    /// The clock `cpu-native` is measured on.
    pub clock: Clock,
}

/// Scenes of the fixed sweep: a sphere (few silhouette edges), a torus (many, with holes) and a
/// lumpy blob of 10K triangles (paper 000's stand-in for the bunny).
pub const SCENES: [&str; 3] = ["sphere-on-plane", "torus-on-plane", "blob-on-plane"];
/// Image sizes of the fixed sweep: none of the training sweep's (`harness::fit::TRAINING_IMAGES`),
/// one between them and one above.
pub const IMAGES: [[u32; 2]; 2] = [[400, 300], [640, 480]];

impl Default for Sweep {
    /// The fixed sweep: every algorithm with a CPU execution (not the reference) on
    /// [`SCENES`] at [`IMAGES`], 256² maps, 32-pixel tiles, `accum_hard` with 16 light samples
    /// (as `scenarios/ci.json`), 3 timed runs on the CPU clock.
    fn default() -> Self {
        Sweep {
            algorithms: algorithms::ALGORITHMS
                .iter()
                .filter(|a| a.id != "reference")
                .filter(|a| {
                    a.backends.contains(&Backend::CpuNative)
                        && a.backends.contains(&Backend::CpuModel)
                })
                .map(|a| a.id.to_string())
                .collect(),
            scenes: SCENES.map(String::from).to_vec(),
            images: IMAGES.to_vec(),
            map_resolution: 256,
            tile_size: 32,
            options: [(
                "accum_hard".to_string(),
                serde_json::json!({ "samples": 16 }),
            )]
            .into_iter()
            .collect(),
            repeats: 3,
            clock: Clock::Cpu,
        }
    }
}

/// Modelled against measured time of one run, or of one phase of it.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub algorithm: String,
    pub scene: String,
    pub image: [u32; 2],
    /// `None` for the whole run.
    pub phase: Option<String>,
    pub modelled_ms: f64,
    /// Median over the timed `cpu-native` runs on the sweep's clock ([`Sweep::clock`]); the
    /// fastest and slowest of them.
    pub measured_ms: f64,
    pub measured_min_ms: f64,
    pub measured_max_ms: f64,
    /// Median wall time of the timed runs.
    pub wall_ms: f64,
    /// Median of the wall time spent inside the machine's steps (`execution.steps_wall_ms` of
    /// cpu-native): the work the model times, without the host-side work between steps
    /// (culling, clipping and copies the model does not count).
    pub steps_ms: f64,
    /// `modelled / measured`.
    pub ratio: f64,
    /// The run's whole wall time (median), with the host-side work between phases; runs only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub run_wall_ms: Option<f64>,
    /// The same on the CPU clock (`util::cpu_time::Times::cpu_ms` of the whole run); runs only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub run_cpu_ms: Option<f64>,
    /// Median CPU-clock time of the timed runs (`util::cpu_time::Times::cpu_ms`: the calling
    /// thread's CPU time plus the worker threads' over their count; time other processes held
    /// the CPUs does not count, idle workers' spinning does). Absent without CPU clocks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu_ms: Option<f64>,
    /// What the cpu-model counted for the run or phase ([`WORK_COUNTERS`]; absent ones are
    /// left out): the work the modelled time is made of.
    pub work: BTreeMap<String, f64>,
}

/// The cpu-model counters of a run or phase that the timing model turns into time
/// (`docs/model.md`, "Timing"), kept in each [`Row`] to relate a phase's ratio to its work.
pub const WORK_COUNTERS: [&str; 16] = [
    "vector_ops",
    "active_lanes",
    "scalar_ops",
    "loads",
    "stores",
    "gathers",
    "gather_lines",
    "scatters",
    "scatter_lines",
    "atomics",
    "cache.l1_misses",
    "cache.l2_hits",
    "cache.l2_misses",
    "cache.l3_hits",
    "cache.l3_misses",
    "dram_read_bytes",
];

/// The [`WORK_COUNTERS`] among `c`, and `steps`: how many distinct steps it ran (its
/// `step.<name>.model_ms` counters).
fn work_of(c: &crate::record::Counters) -> BTreeMap<String, f64> {
    let steps =
        c.0.keys()
            .filter(|k| k.starts_with("step.") && k.ends_with(".model_ms"))
            .count();
    WORK_COUNTERS
        .iter()
        .filter_map(|k| c.get(k).map(|v| (k.to_string(), v)))
        .chain(std::iter::once(("steps".to_string(), steps as f64)))
        .collect()
}

/// Agreement of modelled with measured times over a set of rows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Agreement {
    pub n: usize,
    /// Geometric mean of modelled / measured (1: no bias).
    pub geomean_ratio: f64,
    /// Mean absolute percentage error, `100 · mean(|m − t| / t)`.
    pub mape_pct: f64,
    /// Spearman's rank correlation of modelled and measured.
    pub spearman: f64,
}

/// The median of `v` (the mean of the middle two for an even count); NaN when empty.
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Geometric mean of `v` (all > 0); NaN when empty.
pub fn geomean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().map(|x| x.ln()).sum::<f64>() / v.len() as f64).exp()
}

/// Mean absolute percentage error of `modelled` against `measured` (same length, measured > 0),
/// in percent; NaN when empty.
pub fn mape(modelled: &[f64], measured: &[f64]) -> f64 {
    if measured.is_empty() {
        return f64::NAN;
    }
    100.0
        * modelled
            .iter()
            .zip(measured)
            .map(|(m, t)| ((m - t) / t).abs())
            .sum::<f64>()
        / measured.len() as f64
}

/// Ranks of `v` from 1, ties sharing the mean of their ranks.
pub fn ranks(v: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..v.len()).collect();
    order.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && v[order[j + 1]] == v[order[i]] {
            j += 1;
        }
        let mean = (i + j) as f64 / 2.0 + 1.0;
        for &k in &order[i..=j] {
            r[k] = mean;
        }
        i = j + 1;
    }
    r
}

/// Spearman's rank correlation: Pearson's correlation of the ranks (ties averaged); NaN with
/// fewer than two values or when either side is constant.
pub fn spearman(x: &[f64], y: &[f64]) -> f64 {
    let (rx, ry) = (ranks(x), ranks(y));
    let n = rx.len() as f64;
    if rx.len() < 2 {
        return f64::NAN;
    }
    let (mx, my) = (rx.iter().sum::<f64>() / n, ry.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in rx.iter().zip(&ry) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    sxy / (sxx * syy).sqrt()
}

impl Agreement {
    /// Against the median measured times.
    pub fn of(rows: &[&Row]) -> Agreement {
        Agreement::against(rows, |r| r.measured_ms)
    }

    /// Against the fastest timed run of each case (other processes on the host only add time).
    pub fn of_fastest(rows: &[&Row]) -> Agreement {
        Agreement::against(rows, |r| r.measured_min_ms)
    }

    /// Against the median wall time ([`Row::wall_ms`]).
    pub fn of_wall(rows: &[&Row]) -> Agreement {
        Agreement::against(rows, |r| r.wall_ms)
    }

    /// Against the median CPU-clock time ([`Row::cpu_ms`]); rows without it are left out.
    pub fn of_cpu(rows: &[&Row]) -> Agreement {
        let with: Vec<&Row> = rows
            .iter()
            .copied()
            .filter(|r| r.cpu_ms.is_some())
            .collect();
        Agreement::against(&with, |r| r.cpu_ms.unwrap_or(f64::NAN))
    }

    /// Against the median wall time inside the machine's steps.
    pub fn of_steps(rows: &[&Row]) -> Agreement {
        Agreement::against(rows, |r| r.steps_ms)
    }

    fn against(rows: &[&Row], measured: impl Fn(&Row) -> f64) -> Agreement {
        let m: Vec<f64> = rows.iter().map(|r| r.modelled_ms).collect();
        let t: Vec<f64> = rows.iter().map(|r| measured(r)).collect();
        let ratios: Vec<f64> = m.iter().zip(&t).map(|(m, t)| m / t).collect();
        Agreement {
            n: rows.len(),
            geomean_ratio: geomean(&ratios),
            mape_pct: mape(&m, &t),
            spearman: spearman(&m, &t),
        }
    }
}

/// What `validate-model` found.
#[derive(Clone, Debug, Serialize)]
pub struct Validation {
    pub machine: MachineConfig,
    pub sweep: Sweep,
    /// The training sweep the machine's issue costs were fitted to (`machine.training`);
    /// `None` when none was (a preset, `--kernels-only`). Its scenes and image sizes are not
    /// in `sweep` ([`check_held_out`]).
    pub training: Option<Training>,
    /// Over whole runs, on the sweep's clock: the headline.
    pub runs_agreement: Agreement,
    /// Over every phase of every run.
    pub phases_agreement: Agreement,
    /// The same against the fastest timed run instead of the median (a reading of how much the
    /// host's other load moved the medians; the medians are the result).
    pub runs_agreement_fastest: Agreement,
    pub phases_agreement_fastest: Agreement,
    /// The same against the wall time inside the machine's steps ([`Row::steps_ms`]).
    pub runs_agreement_steps: Agreement,
    pub phases_agreement_steps: Agreement,
    /// The same against the median wall time ([`Row::wall_ms`]).
    pub runs_agreement_wall: Agreement,
    pub phases_agreement_wall: Agreement,
    /// Over whole runs against the CPU clock ([`Row::cpu_ms`]; absent where the OS has none).
    pub runs_agreement_cpu: Agreement,
    /// Over whole runs, per algorithm (in sweep order).
    pub per_algorithm: Vec<(String, Agreement)>,
    /// Over phases, per algorithm and phase name (sweep order, then the phases' order).
    pub per_phase: Vec<(String, String, Agreement)>,
    /// Over whole runs, per image size (sweep order): a ratio drifting with the size is a
    /// fixed cost the model misses or overcounts.
    pub per_image: Vec<([u32; 2], Agreement)>,
    /// Over whole runs, per scene (sweep order).
    pub per_scene: Vec<(String, Agreement)>,
    /// Per algorithm, the median over its runs of the time outside its phases (the run's whole
    /// time less its phases'), ms, and of its share of the run's time, on the wall clock and on
    /// the CPU clock (NaN without it): host work neither execution times (the light-view fit,
    /// gathering the occluders, the frame output), measured apart.
    pub outside_phases: Vec<OutsidePhases>,
    pub runs: Vec<Row>,
    pub phases: Vec<Row>,
    /// Cases that could not run, with the reason.
    pub failures: Vec<String>,
    /// Wall seconds the sweep took.
    pub seconds: f64,
    /// The 1-minute load average of the host when the sweep started and ended (`/proc/loadavg`;
    /// absent elsewhere): above the core count, other processes shared the cores and the
    /// measured times are longer than the machine's own.
    pub load_average: Option<[f64; 2]>,
    /// Time this process's threads waited for a CPU during the sweep, percent of their CPU
    /// time (`util::cpu_time::Load::waited_pct_since`).
    pub waited_pct: Option<f64>,
    /// Set when the host was loaded during the sweep (`util::cpu_time::loaded_warning`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub load_warning: Option<String>,
}

/// Time of an algorithm's runs outside their phases ([`Validation::outside_phases`]).
#[derive(Clone, Debug, Serialize)]
pub struct OutsidePhases {
    pub algorithm: String,
    pub wall_ms: f64,
    pub wall_share: f64,
    pub cpu_ms: f64,
    pub cpu_share: f64,
}

/// Refuses a sweep that shares a scene or an image size with a training sweep's (`scenes`,
/// `images`: those a machine's costs were fitted to), naming the flag (`scenes_flag`,
/// `images_flag`) and the value: its runs would not be held out. Errors: an [`InputError`] on
/// the first shared scene or size.
pub fn check_held_out(
    sweep: &Sweep,
    scenes: &[String],
    images: &[[u32; 2]],
    scenes_flag: &str,
    images_flag: &str,
) -> std::result::Result<(), InputError> {
    if let Some(s) = sweep.scenes.iter().find(|s| scenes.contains(s)) {
        return Err(InputError::new(
            scenes_flag,
            format!(
                "'{s}' is a scene the machine's issue costs are fitted on ({}): validation holds \
                 out the training scenes",
                scenes.join(", ")
            ),
        ));
    }
    if let Some([w, h]) = sweep.images.iter().find(|i| images.contains(i)) {
        return Err(InputError::new(
            images_flag,
            format!(
                "'{w}x{h}' is an image size the machine's issue costs are fitted at ({}): \
                 validation holds out the training image sizes",
                images
                    .iter()
                    .map(|[w, h]| format!("{w}x{h}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    Ok(())
}

/// Runs `sweep` with `machine` as the cpu-model's machine; `progress` gets a line per case.
pub fn run(
    sweep: &Sweep,
    machine: &MachineConfig,
    mut progress: impl FnMut(&str),
) -> Result<Validation> {
    let start = Instant::now();
    let load_start = Load::now();
    let mut runs = Vec::new();
    let mut phases = Vec::new();
    let mut failures = Vec::new();
    let total = sweep.scenes.len() * sweep.images.len() * sweep.algorithms.len();
    let mut done = 0;
    for scene_name in &sweep.scenes {
        let (scene, _) = scenario::scene_from_arg(
            scene_name,
            GeneratorParams {
                triangles: None,
                seed: 1,
                occluder_height: None,
                occluder_offset: None,
            },
        )?;
        for &image in &sweep.images {
            for alg in &sweep.algorithms {
                done += 1;
                let info = algorithms::find(alg).map_err(Error::Unsupported)?;
                let mut scene = scene.clone();
                scene.light = crate::harness::light_for_run(&scene, info)?;
                let params =
                    RunParams::of_scene(&scene, image, sweep.map_resolution, sweep.tile_size);
                let frame = Frame::new(scene, params);
                match case(&frame, alg, machine, sweep) {
                    Ok((run, ps)) => {
                        progress(&format!(
                            "[{done}/{total}] {alg:<19} {scene_name:<16} {}x{}  modelled \
                             {:>8.2} ms  measured {:>8.2} ms  ratio {:.2}",
                            image[0], image[1], run.modelled_ms, run.measured_ms, run.ratio
                        ));
                        runs.push(run);
                        phases.extend(ps);
                    }
                    Err(e) => {
                        let line = format!("{alg} on {scene_name} {}x{}: {e}", image[0], image[1]);
                        progress(&format!("[{done}/{total}] failed: {line}"));
                        failures.push(line);
                    }
                }
            }
        }
    }
    let load_end = Load::now();
    fn refs(rows: &[Row]) -> Vec<&Row> {
        rows.iter().collect()
    }
    let of = |pred: &dyn Fn(&Row) -> bool| -> Agreement {
        Agreement::of(&runs.iter().filter(|r| pred(r)).collect::<Vec<_>>())
    };
    let per_algorithm = sweep
        .algorithms
        .iter()
        .map(|a| (a.clone(), of(&|r| &r.algorithm == a)))
        .collect();
    let per_image = sweep
        .images
        .iter()
        .map(|i| (*i, of(&|r| &r.image == i)))
        .collect();
    let per_scene = sweep
        .scenes
        .iter()
        .map(|x| (x.clone(), of(&|r| &r.scene == x)))
        .collect();
    let mut per_phase = Vec::new();
    for a in &sweep.algorithms {
        let mut names: Vec<&str> = Vec::new();
        for p in phases.iter().filter(|p| &p.algorithm == a) {
            let name = p.phase.as_deref().unwrap_or("");
            if !names.contains(&name) {
                names.push(name);
            }
        }
        for name in names {
            let rows: Vec<&Row> = phases
                .iter()
                .filter(|p| &p.algorithm == a && p.phase.as_deref() == Some(name))
                .collect();
            per_phase.push((a.clone(), name.to_string(), Agreement::of(&rows)));
        }
    }
    let outside_phases = sweep
        .algorithms
        .iter()
        .map(|a| {
            let of = |whole: &dyn Fn(&Row) -> Option<f64>, phases: &dyn Fn(&Row) -> Option<f64>| {
                let (mut ms, mut share): (Vec<f64>, Vec<f64>) = runs
                    .iter()
                    .filter(|r| &r.algorithm == a)
                    .filter_map(|r| {
                        let (whole, inside) = (whole(r)?, phases(r)?);
                        let outside = (whole - inside).max(0.0);
                        Some((outside, outside / whole))
                    })
                    .unzip();
                (median(&mut ms), median(&mut share))
            };
            let (wall_ms, wall_share) = of(&|r| r.run_wall_ms, &|r| Some(r.wall_ms));
            let (cpu_ms, cpu_share) = of(&|r| r.run_cpu_ms, &|r| r.cpu_ms);
            OutsidePhases {
                algorithm: a.clone(),
                wall_ms,
                wall_share,
                cpu_ms,
                cpu_share,
            }
        })
        .collect();
    let cpus = machine.cores * machine.threads_per_core;
    Ok(Validation {
        machine: machine.clone(),
        sweep: sweep.clone(),
        training: machine.training.clone(),
        runs_agreement: Agreement::of(&refs(&runs)),
        phases_agreement: Agreement::of(&refs(&phases)),
        runs_agreement_fastest: Agreement::of_fastest(&refs(&runs)),
        phases_agreement_fastest: Agreement::of_fastest(&refs(&phases)),
        runs_agreement_steps: Agreement::of_steps(&refs(&runs)),
        phases_agreement_steps: Agreement::of_steps(&refs(&phases)),
        runs_agreement_wall: Agreement::of_wall(&refs(&runs)),
        phases_agreement_wall: Agreement::of_wall(&refs(&phases)),
        runs_agreement_cpu: Agreement::of_cpu(&refs(&runs)),
        per_algorithm,
        per_phase,
        per_image,
        per_scene,
        outside_phases,
        runs,
        phases,
        failures,
        seconds: start.elapsed().as_secs_f64(),
        load_average: load_start
            .load_average
            .zip(load_end.load_average)
            .map(|(a, b)| [a, b]),
        waited_pct: load_end.waited_pct_since(&load_start),
        load_warning: cpu_time::loaded_warning(&load_start, &load_end, cpus, sweep.clock),
    })
}

/// A per-phase figure a cpu-native run records under `execution` (`steps_wall_ms`: the wall
/// time inside each phase's steps; `phase_cpu_ms`: each phase on the CPU clock), by phase name;
/// `null` values are NaN.
fn named_ms(out: &algorithms::FrameOutput, key: &str) -> Vec<(String, f64)> {
    out.execution
        .get(key)
        .and_then(|v| v.as_object())
        .map(|o| {
            o.iter()
                .map(|(k, v)| (k.clone(), v.as_f64().unwrap_or(f64::NAN)))
                .collect()
        })
        .unwrap_or_default()
}

/// One case: the run's row and its phases' rows.
fn case(
    frame: &Frame,
    alg: &str,
    machine: &MachineConfig,
    sweep: &Sweep,
) -> Result<(Row, Vec<Row>)> {
    let repeats = sweep.repeats;
    // Each task of cpu-native's steps on its thread's CPU clock (the phases' CPU-clock times
    // schedule them as an idle machine would; cpu-model does not read it).
    let ctx = ExecContext {
        machine: machine.clone(),
        options: sweep.options.clone(),
        time_tasks: true,
        ..Default::default()
    };
    let model = algorithms::run(alg, Backend::CpuModel, frame, &ctx)?;
    // Warm-up: first touches of the frame, the thread pool, the allocator.
    algorithms::run(alg, Backend::CpuNative, frame, &ctx)?;
    // Per timed run: its whole wall and CPU-clock time and, per phase name, (wall, cpu, inside
    // steps) ms.
    type Timed = (f64, f64, Vec<(String, f64, f64, f64)>);
    let mut timed: Vec<Timed> = Vec::new();
    for _ in 0..repeats.max(1) {
        let start = cpu_time::Span::start();
        let out = algorithms::run(alg, Backend::CpuNative, frame, &ctx)?;
        let whole = start.elapsed(rayon::current_num_threads());
        let (wall, whole_cpu) = (whole.wall_ms, whole.cpu_ms.unwrap_or(f64::NAN));
        let steps = named_ms(&out, "steps_wall_ms");
        let cpu = named_ms(&out, "phase_cpu_ms");
        let find = |v: &[(String, f64)], n: &str| {
            v.iter().find(|(k, _)| k == n).map_or(f64::NAN, |(_, x)| *x)
        };
        let phases = out
            .phases
            .iter()
            .map(|p| {
                (
                    p.name.clone(),
                    p.wall_ms,
                    find(&cpu, &p.name),
                    find(&steps, &p.name),
                )
            })
            .collect();
        timed.push((wall, whole_cpu, phases));
    }
    let clock = sweep.clock;
    // One row from the timed runs' (wall, cpu, steps) of the run or phase.
    let row =
        |phase: Option<String>, modelled: f64, work: BTreeMap<String, f64>, t: &[[f64; 3]]| {
            let col = |i: usize| t.iter().map(|x| x[i]).collect::<Vec<f64>>();
            let (mut wall, mut cpu, mut steps) = (col(0), col(1), col(2));
            let cpu_ok = cpu.iter().all(|c| c.is_finite());
            let mut measured = match clock {
                Clock::Cpu if cpu_ok => cpu.clone(),
                _ => wall.clone(),
            };
            let (lo, hi) = measured
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
            let m = median(&mut measured);
            Row {
                algorithm: alg.to_string(),
                scene: frame.scene.name.clone(),
                image: frame.params.image,
                phase,
                modelled_ms: modelled,
                measured_ms: m,
                measured_min_ms: lo,
                measured_max_ms: hi,
                wall_ms: median(&mut wall),
                steps_ms: median(&mut steps),
                ratio: modelled / m,
                run_wall_ms: None,
                run_cpu_ms: None,
                cpu_ms: cpu_ok.then(|| median(&mut cpu)),
                work,
            }
        };
    let mut phase_rows = Vec::new();
    for p in &model.phases {
        let t: Vec<[f64; 3]> = timed
            .iter()
            .filter_map(|(_, _, ps)| ps.iter().find(|q| q.0 == p.name).map(|q| [q.1, q.2, q.3]))
            .collect();
        match (p.model_ms, t.len() == timed.len()) {
            (Some(m), true) => {
                phase_rows.push(row(Some(p.name.clone()), m, work_of(&p.counters), &t))
            }
            _ => {
                return Err(Error::Other(format!(
                    "phase '{}' has no modelled time or is missing from a cpu-native run",
                    p.name
                )))
            }
        }
    }
    // The run: the sums over its phases (what the model models).
    let sums: Vec<[f64; 3]> = timed
        .iter()
        .map(|(_, _, ps)| {
            ps.iter()
                .fold([0.0; 3], |a, q| [a[0] + q.1, a[1] + q.2, a[2] + q.3])
        })
        .collect();
    let mut walls: Vec<f64> = timed.iter().map(|(w, _, _)| *w).collect();
    let mut cpus: Vec<f64> = timed.iter().map(|(_, c, _)| *c).collect();
    let modelled = model
        .model_ms
        .ok_or_else(|| Error::Other("the cpu-model run has no model_ms".into()))?;
    let mut run = row(None, modelled, work_of(&model.counters), &sums);
    run.run_wall_ms = Some(median(&mut walls));
    run.run_cpu_ms = cpus
        .iter()
        .all(|c| c.is_finite())
        .then(|| median(&mut cpus));
    Ok((run, phase_rows))
}

/// A CSV field: quoted when it holds a comma, quote or newline.
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The rows as CSV: `algorithm,scene,image,phase,modelled_ms,measured_ms,measured_min_ms,
/// measured_max_ms,wall_ms,cpu_ms,steps_ms,ratio,run_wall_ms` (measured on the sweep's clock;
/// phase, cpu_ms and run_wall_ms empty where they do not apply).
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "algorithm,scene,image,phase,modelled_ms,measured_ms,measured_min_ms,measured_max_ms,\
         wall_ms,cpu_ms,steps_ms,ratio,run_wall_ms\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |w| format!("{w:.6}"));
    for r in rows {
        s += &format!(
            "{},{},{}x{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{},{:.6},{:.6},{}\n",
            field(&r.algorithm),
            field(&r.scene),
            r.image[0],
            r.image[1],
            field(r.phase.as_deref().unwrap_or("")),
            r.modelled_ms,
            r.measured_ms,
            r.measured_min_ms,
            r.measured_max_ms,
            r.wall_ms,
            opt(r.cpu_ms),
            r.steps_ms,
            r.ratio,
            opt(r.run_wall_ms)
        );
    }
    s
}

/// The summary table printed at the end and written as `summary.txt`: the training and the
/// held-out sets, the held-out error (the headline) beside the training error, per algorithm,
/// per image size, per scene and per phase, then the same runs on the other clocks.
pub fn summary_text(v: &Validation) -> String {
    let line = |name: &str, a: &Agreement| {
        // Spearman's ρ needs two runs at least (NaN, `null` in the JSON, otherwise).
        let rho = if a.spearman.is_finite() {
            format!("{:.3}", a.spearman)
        } else {
            "n/a".to_string()
        };
        format!(
            "{name:<34} {:>4}  {:>9.3}  {:>7.1}%  {rho:>8}\n",
            a.n, a.geomean_ratio, a.mape_pct
        )
    };
    let sizes = |v: &[[u32; 2]]| {
        v.iter()
            .map(|[w, h]| format!("{w}x{h}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let clock = match v.sweep.clock {
        Clock::Cpu => "CPU time (the calling thread's plus the workers' over their count)",
        Clock::Wall => "wall time",
    };
    let mut s = format!("machine {} ({})\n", v.machine.name, v.machine.describe());
    match &v.training {
        Some(t) => {
            s += &format!(
                "training set (the fit's): scenes {}; images {}; {}² maps; clock {}; load average \
                 {}\n",
                t.scenes.join(", "),
                sizes(&t.images),
                t.map_resolution,
                t.clock.name(),
                t.load_average
                    .map_or("unknown".into(), |[a, b]| format!("{a:.2}-{b:.2}")),
            );
        }
        None => s += "training set: none (no cost of this machine was fitted to a scene)\n",
    }
    s += &format!(
        "held-out set: scenes {}; images {}; {}² maps (the map resolution is {}); cpu-native \
         measured in {clock}\n",
        v.sweep.scenes.join(", "),
        sizes(&v.sweep.images),
        v.sweep.map_resolution,
        match &v.training {
            Some(t) if t.map_resolution == v.sweep.map_resolution => "the training's: not held out",
            Some(_) => "not the training's",
            None => "not fitted",
        }
    );
    s += &format!(
        "{:<34} {:>4}  {:>9}  {:>8}  {:>8}\n",
        "", "n", "geomean", "MAPE", "Spearman"
    );
    let held = if v.training.is_some() {
        "held-out runs"
    } else {
        "runs"
    };
    s += &line(held, &v.runs_agreement);
    if let Some(t) = &v.training {
        s += &format!(
            "{:<34} {:>4}  {:>9}  {:>7.1}%  {:>8}  (the fit's formula)\n",
            "training runs", t.runs, "", t.runs_mape, ""
        );
        if v.runs_agreement.mape_pct > t.runs_mape {
            s += &format!(
                "the held-out error is worse than the training error: {:.1}% against {:.1}%\n",
                v.runs_agreement.mape_pct, t.runs_mape
            );
        }
    }
    s += &line("held-out phases", &v.phases_agreement);
    s += "per algorithm (runs):\n";
    for (a, agreement) in &v.per_algorithm {
        s += &line(&format!("  {a}"), agreement);
    }
    s += "per image size (runs):\n";
    for ([w, h], agreement) in &v.per_image {
        s += &line(&format!("  {w}x{h}"), agreement);
    }
    s += "per scene (runs):\n";
    for (x, agreement) in &v.per_scene {
        s += &line(&format!("  {x}"), agreement);
    }
    s += "per phase:\n";
    for (a, p, agreement) in &v.per_phase {
        s += &line(&format!("  {a} {p}"), agreement);
    }
    s += "time outside the phases (in neither execution's times), median per run:\n";
    s += &format!(
        "  {:<32} {:>11} {:>6}  {:>11} {:>6}\n",
        "", "wall", "share", "CPU clock", "share"
    );
    for o in &v.outside_phases {
        s += &format!(
            "  {:<32} {:>8.3} ms {:>5.1}%  {:>8.3} ms {:>5.1}%\n",
            o.algorithm,
            o.wall_ms,
            100.0 * o.wall_share,
            o.cpu_ms,
            100.0 * o.cpu_share
        );
    }
    s += "the same runs against the median wall time:\n";
    s += &line("  runs", &v.runs_agreement_wall);
    s += &line("  phases", &v.phases_agreement_wall);
    s += "against the CPU clock:\n";
    s += &line("  runs", &v.runs_agreement_cpu);
    s += "against the wall time inside the machine's steps (no host-side work between them):\n";
    s += &line("  runs", &v.runs_agreement_steps);
    s += &line("  phases", &v.phases_agreement_steps);
    s += "against the fastest timed run instead of the median:\n";
    s += &line("  runs", &v.runs_agreement_fastest);
    s += &line("  phases", &v.phases_agreement_fastest);
    if let Some([a, b]) = v.load_average {
        s += &format!(
            "host load average {a:.2} at the start, {b:.2} at the end ({} cores){}\n",
            v.machine.cores * v.machine.threads_per_core,
            v.waited_pct.map_or(String::new(), |w| format!(
                "; this process's threads waited for a CPU {w:.1}% of their CPU time"
            ))
        );
    }
    if let Some(w) = &v.load_warning {
        s += w;
        s += "\n";
    }
    if !v.failures.is_empty() {
        s += &format!("{} cases failed:\n", v.failures.len());
        for f in &v.failures {
            s += &format!("  {f}\n");
        }
    }
    s
}

/// The files `validate-model` writes into its output folder: [`write`]'s and the chart
/// (`crate::report::validation::chart`).
pub const FILES: [&str; 6] = [
    "validation.json",
    "runs.csv",
    "phases.csv",
    "summary.txt",
    "modelled_vs_measured.png",
    "modelled_vs_measured.svg",
];

/// Writes `validation.json`, `runs.csv`, `phases.csv` and `summary.txt` into `out`; returns
/// their paths.
pub fn write(out: &Path, v: &Validation) -> Result<Vec<PathBuf>> {
    let write = |name: &str, bytes: &[u8]| -> Result<PathBuf> {
        let path = out.join(name);
        crate::visibility::write_atomic(&path, bytes)?;
        Ok(path)
    };
    Ok(vec![
        write(
            "validation.json",
            &serde_json::to_vec_pretty(v).expect("validation serializes"),
        )?,
        write("runs.csv", csv(&v.runs).as_bytes())?,
        write("phases.csv", csv(&v.phases).as_bytes())?,
        write("summary.txt", summary_text(v).as_bytes())?,
    ])
}

/// Parses `--images 320x240,640x480`.
pub fn parse_images(
    field: &str,
    list: &[String],
) -> std::result::Result<Vec<[u32; 2]>, InputError> {
    list.iter()
        .map(|s| {
            let bad = || InputError::new(field, format!("expected WxH (e.g. 320x240), got '{s}'"));
            let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
            let image = [
                w.trim().parse().map_err(|_| bad())?,
                h.trim().parse().map_err(|_| bad())?,
            ];
            crate::scenario::validate::image(field, image)?;
            Ok(image)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!(median(&mut []).is_nan());
    }

    #[test]
    fn agreement_figures_match_hand_computed_values() {
        // modelled 1, 4, 9 against measured 2, 2, 3: ratios 0.5, 2, 3.
        let m = [1.0, 4.0, 9.0];
        let t = [2.0, 2.0, 3.0];
        // |1−2|/2 = 0.5, |4−2|/2 = 1, |9−3|/3 = 2: mean 7/6.
        assert!((mape(&m, &t) - 100.0 * 7.0 / 6.0).abs() < 1e-12);
        // (0.5 · 2 · 3)^(1/3) = 3^(1/3).
        assert!((geomean(&[0.5, 2.0, 3.0]) - 3f64.cbrt()).abs() < 1e-12);
        // Ranks of t with the tie averaged: 1.5, 1.5, 3; of m: 1, 2, 3.
        assert_eq!(ranks(&t), vec![1.5, 1.5, 3.0]);
        // Pearson of (1, 2, 3) and (1.5, 1.5, 3): cov 0.75·…; by hand ρ = √3/2.
        assert!((spearman(&m, &t) - 3f64.sqrt() / 2.0).abs() < 1e-12);
        // A reversed order is −1, the same order +1, whatever the values.
        assert_eq!(
            spearman(&[1.0, 2.0, 3.0, 4.0], &[40.0, 30.0, 20.0, 10.0]),
            -1.0
        );
        assert_eq!(spearman(&[1.0, 2.0, 3.0], &[1.0, 100.0, 1000.0]), 1.0);
        assert!(spearman(&[1.0], &[2.0]).is_nan());
    }

    #[test]
    fn a_sweep_sharing_a_training_scene_or_size_is_refused_naming_the_flag() {
        let scenes = ["box-on-plane".to_string(), "sphere-grid".to_string()];
        let images = [[240, 180], [480, 360]];
        let mut sweep = Sweep {
            scenes: vec!["room".into(), "torus-on-plane".into()],
            images: vec![[400, 300]],
            ..Sweep::default()
        };
        assert!(check_held_out(&sweep, &scenes, &images, "--scenes", "--images").is_ok());
        sweep.scenes.push("sphere-grid".into());
        let e = check_held_out(&sweep, &scenes, &images, "--scenes", "--images").unwrap_err();
        assert!(
            e.to_string().contains("--scenes") && e.to_string().contains("'sphere-grid'"),
            "{e}"
        );
        sweep.scenes.pop();
        sweep.images.push([480, 360]);
        let e = check_held_out(&sweep, &scenes, &images, "--scenes", "--images").unwrap_err();
        assert!(
            e.to_string().contains("--images") && e.to_string().contains("'480x360'"),
            "{e}"
        );
        // The defaults hold out the training sweep's defaults.
        let train = crate::harness::fit::training_sweep(&Sweep::default());
        assert!(check_held_out(
            &Sweep::default(),
            &train.scenes,
            &train.images,
            "--scenes",
            "--images"
        )
        .is_ok());
    }

    #[test]
    fn csv_quotes_fields_and_leaves_run_fields_empty_for_phases() {
        let r = Row {
            algorithm: "a".into(),
            scene: "x,y".into(),
            image: [4, 3],
            phase: Some("p".into()),
            modelled_ms: 1.0,
            measured_ms: 2.0,
            measured_min_ms: 1.5,
            measured_max_ms: 2.5,
            wall_ms: 2.0,
            steps_ms: 1.75,
            ratio: 0.5,
            run_wall_ms: None,
            run_cpu_ms: None,
            cpu_ms: None,
            work: BTreeMap::new(),
        };
        let text = csv(&[r]);
        let line = text.lines().nth(1).unwrap();
        assert!(
            line.starts_with("a,\"x,y\",4x3,p,1.000000,2.000000"),
            "{line}"
        );
        assert!(line.ends_with(",2.000000,,1.750000,0.500000,"), "{line}");
    }
}
