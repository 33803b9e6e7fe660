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

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::algorithms::{self, Backend, ExecContext};
use crate::error::{Error, InputError, Result};
use crate::frame::{Frame, RunParams};
use crate::model::MachineConfig;
use crate::scenario;
use crate::scene::generators::GeneratorParams;

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
}

/// Scenes of the fixed sweep: a sphere (few silhouette edges), a torus (many, with holes) and a
/// lumpy blob of 10K triangles (paper 000's stand-in for the bunny).
pub const SCENES: [&str; 3] = ["sphere-on-plane", "torus-on-plane", "blob-on-plane"];
/// Image sizes of the fixed sweep.
pub const IMAGES: [[u32; 2]; 2] = [[320, 240], [640, 480]];

impl Default for Sweep {
    /// The fixed sweep: every algorithm with a CPU execution (not the reference) on
    /// [`SCENES`] at [`IMAGES`], 256² maps, 32-pixel tiles, `accum_hard` with 16 light samples
    /// (as `scenarios/ci.json`), 3 timed runs: about 5 minutes on a 2-core machine.
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
    /// Median over the timed `cpu-native` runs.
    pub measured_ms: f64,
    pub measured_min_ms: f64,
    pub measured_max_ms: f64,
    /// Median of the wall time spent inside the machine's steps (`execution.steps_wall_ms` of
    /// cpu-native): the work the model times, without the host-side work between steps
    /// (culling, clipping and copies the model does not count).
    pub steps_ms: f64,
    /// `modelled / measured`.
    pub ratio: f64,
    /// The run's whole wall time (median), with the host-side work between phases; runs only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub run_wall_ms: Option<f64>,
    /// The run's on-CPU time over the logical CPUs (median of the timed runs): the time every
    /// thread of this process spent running (`/proc/self/task/*/schedstat`), divided by the
    /// worker threads of cpu-native (`rayon::current_num_threads`, the logical CPUs). Time
    /// other processes held the CPUs does not count, so it is the run's time on an otherwise
    /// idle machine if its work were spread evenly (it also counts idle workers' spinning).
    /// Runs only, Linux only.
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

    /// Against the on-CPU time per logical CPU ([`Row::cpu_ms`]); rows without it are left out.
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
    /// Over whole runs.
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
    /// Over whole runs against their on-CPU time per logical CPU ([`Row::cpu_ms`]; absent where
    /// the OS does not state it).
    pub runs_agreement_cpu: Agreement,
    /// Over whole runs, per algorithm (in sweep order).
    pub per_algorithm: Vec<(String, Agreement)>,
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
    /// Where the machine's issue costs were fitted ([`super::fit`]), when they were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cost_fit: Option<super::fit::CostFit>,
}

/// The 1-minute load average (`/proc/loadavg`), where the OS states it.
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// Nanoseconds every thread of this process has spent on a CPU so far: the sum of the first
/// field of `/proc/self/task/*/schedstat` (Linux; `None` elsewhere or when unreadable).
fn cpu_ns() -> Option<u64> {
    let mut total = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let path = task.ok()?.path().join("schedstat");
        // A thread that ended between the listing and the read ran nothing since.
        let Ok(text) = std::fs::read_to_string(path) else {
            continue;
        };
        total += text.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total)
}

/// Runs `sweep` with `machine` as the cpu-model's machine; `progress` gets a line per case.
pub fn run(
    sweep: &Sweep,
    machine: &MachineConfig,
    mut progress: impl FnMut(&str),
) -> Result<Validation> {
    let start = Instant::now();
    let load_start = load_average();
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
    let all = |rows: &[Row]| Agreement::of(&rows.iter().collect::<Vec<_>>());
    let fastest = |rows: &[Row]| Agreement::of_fastest(&rows.iter().collect::<Vec<_>>());
    let steps = |rows: &[Row]| Agreement::of_steps(&rows.iter().collect::<Vec<_>>());
    let per_algorithm = sweep
        .algorithms
        .iter()
        .map(|a| {
            let rows: Vec<&Row> = runs.iter().filter(|r| &r.algorithm == a).collect();
            (a.clone(), Agreement::of(&rows))
        })
        .collect();
    Ok(Validation {
        machine: machine.clone(),
        sweep: sweep.clone(),
        runs_agreement: all(&runs),
        phases_agreement: all(&phases),
        runs_agreement_fastest: fastest(&runs),
        phases_agreement_fastest: fastest(&phases),
        runs_agreement_steps: steps(&runs),
        phases_agreement_steps: steps(&phases),
        runs_agreement_cpu: Agreement::of_cpu(&runs.iter().collect::<Vec<_>>()),
        per_algorithm,
        runs,
        phases,
        failures,
        seconds: start.elapsed().as_secs_f64(),
        load_average: load_start.zip(load_average()).map(|(a, b)| [a, b]),
        cost_fit: None,
    })
}

/// The wall time inside the steps of each phase of a cpu-native run (`execution.steps_wall_ms`).
fn steps_of(out: &algorithms::FrameOutput) -> Vec<(String, f64)> {
    out.execution
        .get("steps_wall_ms")
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
    let ctx = ExecContext {
        machine: machine.clone(),
        options: sweep.options.clone(),
        ..Default::default()
    };
    let model = algorithms::run(alg, Backend::CpuModel, frame, &ctx)?;
    // Warm-up: first touches of the frame, the thread pool, the allocator.
    algorithms::run(alg, Backend::CpuNative, frame, &ctx)?;
    let mut timed = Vec::new();
    let mut cpu = Vec::new();
    for _ in 0..repeats.max(1) {
        let cpu_start = cpu_ns();
        let start = Instant::now();
        let out = algorithms::run(alg, Backend::CpuNative, frame, &ctx)?;
        let wall = start.elapsed().as_secs_f64() * 1e3;
        // The worker threads cpu-native runs on (one per logical CPU unless limited).
        let logical = rayon::current_num_threads() as f64;
        if let Some((a, b)) = cpu_start.zip(cpu_ns()) {
            cpu.push(b.saturating_sub(a) as f64 * 1e-6 / logical);
        }
        let steps = steps_of(&out);
        timed.push((wall, out.phases, steps));
    }
    let row = |phase: Option<String>,
               modelled: f64,
               work: BTreeMap<String, f64>,
               mut measured: Vec<f64>,
               mut steps: Vec<f64>| {
        let (lo, hi) = measured
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
        let t = median(&mut measured);
        Row {
            algorithm: alg.to_string(),
            scene: frame.scene.name.clone(),
            image: frame.params.image,
            phase,
            modelled_ms: modelled,
            measured_ms: t,
            measured_min_ms: lo,
            measured_max_ms: hi,
            steps_ms: median(&mut steps),
            ratio: modelled / t,
            run_wall_ms: None,
            cpu_ms: None,
            work,
        }
    };
    let mut phase_rows = Vec::new();
    for p in &model.phases {
        let measured: Vec<f64> = timed
            .iter()
            .filter_map(|(_, ps, _)| ps.iter().find(|q| q.name == p.name).map(|q| q.wall_ms))
            .collect();
        let steps: Vec<f64> = timed
            .iter()
            .filter_map(|(_, _, st)| st.iter().find(|(n, _)| *n == p.name).map(|(_, v)| *v))
            .collect();
        let complete = measured.len() == timed.len() && steps.len() == timed.len();
        match (p.model_ms, complete) {
            (Some(m), true) => phase_rows.push(row(
                Some(p.name.clone()),
                m,
                work_of(&p.counters),
                measured,
                steps,
            )),
            _ => {
                return Err(Error::Other(format!(
                    "phase '{}' has no modelled time or is missing from a cpu-native run",
                    p.name
                )))
            }
        }
    }
    let sums: Vec<f64> = timed
        .iter()
        .map(|(_, ps, _)| ps.iter().map(|p| p.wall_ms).sum())
        .collect();
    let step_sums: Vec<f64> = timed
        .iter()
        .map(|(_, _, st)| st.iter().map(|(_, v)| v).sum())
        .collect();
    let mut walls: Vec<f64> = timed.iter().map(|(w, _, _)| *w).collect();
    let modelled = model
        .model_ms
        .ok_or_else(|| Error::Other("the cpu-model run has no model_ms".into()))?;
    let mut run = row(None, modelled, work_of(&model.counters), sums, step_sums);
    run.run_wall_ms = Some(median(&mut walls));
    run.cpu_ms = (cpu.len() == timed.len()).then(|| median(&mut cpu));
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
/// measured_max_ms,steps_ms,ratio,run_wall_ms` (phase and run_wall_ms empty where they do not
/// apply).
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "algorithm,scene,image,phase,modelled_ms,measured_ms,measured_min_ms,measured_max_ms,\
         steps_ms,ratio,run_wall_ms\n",
    );
    for r in rows {
        s += &format!(
            "{},{},{}x{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{}\n",
            field(&r.algorithm),
            field(&r.scene),
            r.image[0],
            r.image[1],
            field(r.phase.as_deref().unwrap_or("")),
            r.modelled_ms,
            r.measured_ms,
            r.measured_min_ms,
            r.measured_max_ms,
            r.steps_ms,
            r.ratio,
            r.run_wall_ms.map_or(String::new(), |w| format!("{w:.6}"))
        );
    }
    s
}

/// The summary table printed at the end and written as `summary.txt`.
pub fn summary_text(v: &Validation) -> String {
    let line = |name: &str, a: &Agreement| {
        // Spearman's ρ needs two runs at least (NaN, `null` in the JSON, otherwise).
        let rho = if a.spearman.is_finite() {
            format!("{:.3}", a.spearman)
        } else {
            "n/a".to_string()
        };
        format!(
            "{name:<22} {:>4}  {:>9.3}  {:>7.1}%  {rho:>8}\n",
            a.n, a.geomean_ratio, a.mape_pct
        )
    };
    let mut s = format!(
        "machine {} ({})\n{:<22} {:>4}  {:>9}  {:>8}  {:>8}\n",
        v.machine.name,
        v.machine.describe(),
        "",
        "n",
        "geomean",
        "MAPE",
        "Spearman"
    );
    s += &line("all runs", &v.runs_agreement);
    s += &line("all phases", &v.phases_agreement);
    for (a, agreement) in &v.per_algorithm {
        s += &line(a, agreement);
    }
    s += "against the wall time inside the machine's steps (no host-side work between them):\n";
    s += &line("all runs", &v.runs_agreement_steps);
    s += &line("all phases", &v.phases_agreement_steps);
    s += "against the on-CPU time per logical CPU (time other processes held the CPUs left out):\n";
    s += &line("all runs", &v.runs_agreement_cpu);
    s += "against the fastest timed run instead of the median:\n";
    s += &line("all runs", &v.runs_agreement_fastest);
    s += &line("all phases", &v.phases_agreement_fastest);
    if let Some(f) = &v.cost_fit {
        s += &format!(
            "issue costs fitted on {} ({} runs, {} phases; the fit predicts them at MAPE {:.1}% \
             for runs, {:.1}% for phases)\n",
            f.scenes.join(", "),
            f.runs,
            f.phases,
            f.runs_mape,
            f.phases_mape
        );
        let shared = f.trained_on(&v.sweep.scenes);
        if !shared.is_empty() {
            s += &format!(
                "warning: {} also in the training sweep: those runs are not held out\n",
                shared.join(", ")
            );
        }
    }
    if let Some([a, b]) = v.load_average {
        s += &format!(
            "host load average {a:.2} at the start, {b:.2} at the end ({} cores)\n",
            v.machine.cores * v.machine.threads_per_core
        );
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
            steps_ms: 1.75,
            ratio: 0.5,
            run_wall_ms: None,
            cpu_ms: None,
            work: BTreeMap::new(),
        };
        let text = csv(&[r]);
        let line = text.lines().nth(1).unwrap();
        assert!(
            line.starts_with("a,\"x,y\",4x3,p,1.000000,2.000000"),
            "{line}"
        );
        assert!(line.ends_with(",0.500000,"), "{line}");
    }
}
