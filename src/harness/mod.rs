//! The sweep runner: scenario → cases → frames → runs → results, written as they complete.

pub mod animation;
pub mod cache;
pub mod fit;
pub mod images;
pub mod limits;
pub mod measure;
pub mod outdir;
pub mod output;
pub mod shard;
pub mod validate;

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use crate::algorithms::{self, Backend, Configured, ExecContext, FrameOutput};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::metrics;
use crate::record::{case_id, RunRecord};
use crate::scenario::Loaded;
use crate::scene::{Light, LightKind, Scene};
use crate::util::deadline::Deadline;
use crate::visibility::{RgbBuffer, VisibilityBuffer};

pub use cache::ReferenceCache;
pub use shard::Shard;

/// Converts `light` to `kind` keeping its centre and size: a sphere of radius r ↔ a disc of
/// radius r facing `toward` ↔ a square of half-width r facing `toward`. The one rule for every
/// conversion; [`light_for_run`] adds the check that the result still fits in the scene.
pub fn light_as(light: Light, kind: LightKind, toward: glam::Vec3) -> Light {
    if light.kind() == kind {
        return light;
    }
    let (c, r) = (light.center(), light.size());
    let normal = (toward - c).normalize_or(glam::Vec3::NEG_Y);
    match kind {
        LightKind::Sphere => Light::Sphere {
            center: c,
            radius: r,
        },
        LightKind::Disc => Light::Disc {
            center: c,
            normal,
            radius: r,
        },
        LightKind::Rect => {
            let (u, v) = normal.any_orthonormal_pair();
            Light::Rect {
                center: c,
                half_u: of_length(u, r),
                half_v: of_length(v, r),
            }
        }
    }
}

/// `u` (a unit vector) scaled to length exactly `r` in `f32` where that is reachable, so that a
/// converted rectangle's size ([`Light::size`], `|half_u|`) is the size it was given (`u · r`
/// alone rounds: a light of size 1 became 0.99999994 and the run fell beside its sweep point).
/// The largest component is stepped by units in the last place until the length is `r`.
fn of_length(u: glam::Vec3, r: f32) -> glam::Vec3 {
    let mut w = u * r;
    let axis = (0..3)
        .max_by(|&a, &b| w[a].abs().total_cmp(&w[b].abs()))
        .unwrap_or(0);
    for _ in 0..64 {
        let len = w.length();
        if len == r || !len.is_finite() || w[axis] == 0.0 {
            break;
        }
        // One unit in the last place away from zero lengthens, towards zero shortens.
        let bits = w[axis].to_bits();
        w[axis] = f32::from_bits(if len < r { bits + 1 } else { bits - 1 });
    }
    w
}

/// The light a run of algorithm `info` in `scene` uses: the scene's own when the algorithm takes
/// its kind, else [`light_as`] toward the scene's centre. Refused (naming `$.light`) when that
/// emitter meets triangles of the scene: every method and the reference take the light to lie
/// outside all geometry, and one passing through it (a light sized past its surroundings, a
/// 130 × 105 rectangle 0.1 below a ceiling made a sphere of radius 65) shadows nothing right.
pub fn light_for_run(
    scene: &Scene,
    info: &algorithms::AlgorithmInfo,
) -> std::result::Result<Light, crate::error::InputError> {
    let kind = info.light_for(scene.light.kind());
    let light = light_as(scene.light, kind, scene.bounds().center());
    let meeting = scene
        .objects
        .iter()
        .flat_map(|o| (0..o.mesh.triangles.len()).map(|t| o.mesh.triangle(t)))
        .filter(|&t| light.meets_triangle(t))
        .count();
    if meeting == 0 {
        return Ok(light);
    }
    let c = light.center();
    let what = format!(
        "{kind} light of size {} at ({}, {}, {}) passes through {meeting} triangle{} of the scene",
        light.size(),
        c.x,
        c.y,
        c.z,
        if meeting == 1 { "" } else { "s" }
    );
    let why = if kind == scene.light.kind() {
        format!("the {what}; the light must lie outside all geometry (move it or make it smaller)")
    } else {
        format!(
            "algorithm '{}' takes a {kind} light, but the scene's {} light converted to a {what}; \
             give the scene a light of a kind it takes ({}) or a smaller one",
            info.id,
            scene.light.kind(),
            info.lights
                .iter()
                .map(|k| k.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    Err(crate::error::InputError::new("$.light", why))
}

/// The note a run gets when its algorithm needs another light kind than the scene's.
pub fn light_converted(from: LightKind, to: LightKind) -> String {
    format!("light converted from {from} to {to} (same centre and size) for this algorithm")
}

/// The failure of a run stopped by its budget in `phase` after `elapsed`, with its estimate.
fn timed_out(
    c: crate::util::deadline::Cancelled,
    elapsed: Duration,
    phase: &str,
    estimate: Option<f64>,
) -> Error {
    let estimate = estimate.map_or_else(|| "unknown".into(), |w| format!("{w:.3e}"));
    Error::Resource(format!(
        "run timeout: stopped after {:.2} s in {phase}, over its budget of {} s (estimated work \
         {estimate} fill; raise --run-timeout or the scenario's run_timeout_s)",
        elapsed.as_secs_f64(),
        c.limit.as_secs_f64()
    ))
}

/// Runs `f`, turning an unwind at a deadline into `Err` (any other panic goes on unwinding).
fn within<T>(f: impl FnOnce() -> T) -> std::result::Result<T, crate::util::deadline::Cancelled> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|panic| {
        crate::util::deadline::cancelled(panic.as_ref())
            .unwrap_or_else(|| std::panic::resume_unwind(panic))
    })
}

/// Runs one algorithm on one frame by the measurement protocol `ctx.measure`
/// ([`measure`]) and turns its output into a record, with quality against `reference` when
/// given. The record's counters, modelled times and image are the first iteration's, checked
/// identical in every later one; its `wall_ms`, `gpu_ms` and phase times are the medians of the
/// timed iterations, with every sample in `measured` and the cold iteration apart
/// (`cold_wall_ms`, `cold_gpu_ms`). Failures of the first iteration (errors, panics, invalid
/// visibility, a run stopped at `ctx.deadline` with its work estimate and elapsed time) become
/// a record with `failure` set, so a sweep keeps going; a later iteration that fails ends the
/// measurement with the samples before it, and says so.
pub fn run_one(
    frame: &Frame,
    algorithm: &Configured,
    backend: Backend,
    ctx: &ExecContext,
    reference: Option<&VisibilityBuffer>,
) -> (RunRecord, Option<FrameOutput>) {
    let load_before = measure::load_average();
    let (result, first_ms) = iteration(frame, algorithm, backend, ctx);
    let info = algorithm.info;
    let mut record = RunRecord::new(info.id, backend, &frame.scene, frame.params.clone());
    record.variant = algorithm.variant();
    record.wall_ms = first_ms;
    // The light the run (and its reference) used, in full: after a conversion it is not the
    // scenario's.
    if let Ok(light) = serde_json::to_value(frame.scene.light) {
        record.execution.insert("light".into(), light);
    }
    if !info.limits.is_empty() {
        record.execution.insert(
            "method_limits".into(),
            serde_json::json!(info.limits.iter().map(|l| l.describe()).collect::<Vec<_>>()),
        );
    }
    match result {
        Ok(out) => {
            record.counters = out.counters.clone();
            record.phases = out.phases.clone();
            record.model_ms = out.model_ms;
            record.gpu_ms = out.gpu_ms;
            // GPU setup is paid once per process, not by the frame: apart from its time.
            record.gpu_setup_ms = out.gpu_setup_ms;
            record.execution.extend(out.execution.clone());
            record.warnings = out.warnings.clone();
            let mut measured = repeat(frame, algorithm, backend, ctx, &out, first_ms);
            apply_medians(
                &mut record,
                &measured,
                &out,
                first_ms,
                ctx.measure.warmup > 0,
            );
            let load_after = measure::load_average();
            measured.warnings = measure::warnings(&measured, [load_before, load_after]);
            record.execution.insert(
                "conditions".into(),
                measure::conditions(load_before, load_after),
            );
            record.measured = Some(measured);
            check_gpu_time(&mut record);
            if let Some(r) = reference.filter(|_| info.id != crate::algorithms::reference::ID) {
                let e = metrics::compare_with_receivers(
                    &out.visibility,
                    r,
                    &frame.gbuffer.mask(),
                    &frame.receiver_only_mask(),
                    &frame.grazing_mask(),
                );
                let mut e = e;
                let mask = frame.gbuffer.mask();
                e.flip = metrics::perceptual::mean_over(
                    &flip_map(&out.visibility, r, frame, ctx.flip_pixels_per_degree),
                    &mask,
                );
                e.ssim = metrics::perceptual::ssim(&out.visibility, r, &mask);
                record.warnings.extend(e.warnings());
                record.notes.extend(metrics::grazing_note(&e, info.id));
                record.error = Some(e);
                record.notes.extend(limit_notes(frame, info, r));
            }
            (record, Some(out))
        }
        Err(e) => {
            record.failure = Some(e.to_string());
            (record, None)
        }
    }
}

/// The ꟻLIP error map of the shaded view of `v` against the reference's shaded view `r` in
/// `frame` ([`images::shaded_rgb`], [`metrics::perceptual::flip_map`]).
pub fn flip_map(
    v: &VisibilityBuffer,
    r: &VisibilityBuffer,
    frame: &Frame,
    pixels_per_degree: f32,
) -> Vec<f32> {
    metrics::perceptual::flip_map(
        &images::shaded_rgb(r, frame),
        &images::shaded_rgb(v, frame),
        pixels_per_degree,
    )
}

/// One iteration of a run: its output, and its host milliseconds without GPU setup.
fn iteration(
    frame: &Frame,
    algorithm: &Configured,
    backend: Backend,
    ctx: &ExecContext,
) -> (Result<FrameOutput>, f64) {
    let start = Instant::now();
    let result = catch_unwind(AssertUnwindSafe(|| algorithm.run(backend, frame, ctx)))
        .unwrap_or_else(|panic| {
            if let Some(c) = crate::util::deadline::cancelled(panic.as_ref()) {
                let extent = algorithms::work::SceneExtent::of(&frame.scene);
                let own = algorithm.work_estimate(&extent, &frame.params, ctx);
                let estimate = Some(algorithms::work::frame(&extent, &frame.params) + own);
                // The budget covers the run's earlier phases (its frame, its reference) too.
                let elapsed = ctx.deadline.elapsed().max(start.elapsed());
                return Err(timed_out(c, elapsed, "the run", estimate));
            }
            Err(Error::Other(format!(
                "internal error (panic): {}",
                crate::error::panic_message(panic.as_ref())
            )))
        })
        .and_then(|out| {
            out.visibility
                .check_range()
                .map_err(|m| Error::Other(format!("invalid result: {m}")))?;
            Ok(out)
        });
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let setup = result.as_ref().ok().and_then(|o| o.gpu_setup_ms);
    (result, ms - setup.unwrap_or(0.0))
}

/// The times of one iteration: host and GPU milliseconds of the run and of each phase.
struct Sample {
    wall: f64,
    gpu: Option<f64>,
    phases: Vec<(f64, Option<f64>)>,
}

impl Sample {
    fn of(out: &FrameOutput, wall: f64) -> Sample {
        Sample {
            wall,
            gpu: out.gpu_ms,
            phases: out.phases.iter().map(|p| (p.wall_ms, p.gpu_ms)).collect(),
        }
    }
}

/// Whether two iterations gave the same counters, modelled times and image (bit for bit).
fn same_output(a: &FrameOutput, b: &FrameOutput) -> bool {
    let phases = |o: &FrameOutput| {
        o.phases
            .iter()
            .map(|p| (p.name.clone(), p.model_ms, p.counters.clone()))
            .collect::<Vec<_>>()
    };
    a.counters == b.counters
        && a.model_ms == b.model_ms
        && phases(a) == phases(b)
        && a.visibility.data.len() == b.visibility.data.len()
        && a.visibility
            .data
            .iter()
            .zip(&b.visibility.data)
            .all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The iterations after the first (`first`, which took `first_ms`): untimed warm-ups, then the
/// timed ones within the budget; their samples and whether they gave the first's output.
fn repeat(
    frame: &Frame,
    algorithm: &Configured,
    backend: Backend,
    ctx: &ExecContext,
    first: &FrameOutput,
    first_ms: f64,
) -> measure::Measured {
    let m = ctx.measure;
    let mut samples = Vec::new();
    if m.warmup == 0 {
        samples.push(Sample::of(first, first_ms));
    }
    let mut identical = true;
    let mut stopped = None;
    let mut warmup_runs = 0;
    for _ in 1..m.warmup {
        match iteration(frame, algorithm, backend, ctx) {
            (Ok(o), _) => identical &= same_output(first, &o),
            (Err(e), _) => {
                stopped = Some(e.to_string());
                break;
            }
        }
        warmup_runs += 1;
    }
    let mut spent_s: f64 = samples.iter().map(|s| s.wall / 1e3).sum();
    while stopped.is_none() && m.another(samples.len() as u32, spent_s) {
        match iteration(frame, algorithm, backend, ctx) {
            (Ok(o), ms) => {
                identical &= same_output(first, &o);
                spent_s += ms / 1e3;
                samples.push(Sample::of(&o, ms));
            }
            (Err(e), _) => stopped = Some(e.to_string()),
        }
    }
    if samples.is_empty() {
        // Every timed iteration failed: the cold one is the only sample.
        samples.push(Sample::of(first, first_ms));
    }
    let all_gpu: Option<Vec<f64>> = samples.iter().map(|s| s.gpu).collect();
    let same_phases = samples.iter().all(|s| s.phases.len() == first.phases.len());
    let phases = if same_phases {
        first
            .phases
            .iter()
            .enumerate()
            .filter_map(|(i, p)| {
                let gpu: Option<Vec<f64>> = samples.iter().map(|s| s.phases[i].1).collect();
                Some(measure::PhaseSpread {
                    name: p.name.clone(),
                    wall_ms: measure::Spread::of(samples.iter().map(|s| s.phases[i].0).collect())?,
                    gpu_ms: gpu.and_then(measure::Spread::of),
                })
            })
            .collect()
    } else {
        vec![]
    };
    let wall = measure::Spread::of(samples.iter().map(|s| s.wall).collect())
        .unwrap_or_else(|| measure::Spread::of(vec![0.0]).expect("one finite sample"));
    let mut warnings = Vec::new();
    if let Some(e) = stopped {
        warnings.push(format!(
            "measurement stopped after {} timed iterations: an iteration failed: {e}",
            samples.len()
        ));
    }
    measure::Measured {
        protocol: m,
        iterations: samples.len() as u32,
        warmup_runs,
        wall_ms: wall,
        gpu_ms: all_gpu.and_then(measure::Spread::of),
        phases,
        identical,
        warnings,
    }
}

/// The record's times from the measurement: medians of the timed samples, and the cold
/// iteration apart when the protocol warmed up (`cold`).
fn apply_medians(
    record: &mut RunRecord,
    m: &measure::Measured,
    first: &FrameOutput,
    first_ms: f64,
    cold: bool,
) {
    record.wall_ms = m.wall_ms.median;
    // A GPU median only where every timed iteration has a reading.
    record.gpu_ms = m.gpu_ms.as_ref().map(|s| s.median);
    for (p, s) in record.phases.iter_mut().zip(&m.phases) {
        p.wall_ms = s.wall_ms.median;
        p.gpu_ms = s.gpu_ms.as_ref().map(|g| g.median);
    }
    if cold {
        record.cold_wall_ms = Some(first_ms);
        record.cold_gpu_ms = first.gpu_ms;
    }
}

/// Notes for the declared limits of `info`'s method ([`algorithms::MethodLimit`]) that
/// matter in this frame, judged on the `reference`: pixels on occluders in shadow when the
/// method shadows receiver-only objects only; penumbra pixels (partly lit) inside the hard
/// shadow of the light centre for an outer-penumbra method; any penumbra for a hard-shadow
/// method; for a method whose shadow map holds every surface, pixels facing the light centre
/// whose ray to it only objects that are not occluders block; for a method without a facing
/// test, shadowed pixels of such objects' surfaces facing away from the light centre. `OneMap`
/// warns from the run itself (`light_view.receivers_outside`).
pub fn limit_notes(
    frame: &Frame,
    info: &algorithms::AlgorithmInfo,
    reference: &VisibilityBuffer,
) -> Vec<String> {
    use crate::algorithms::MethodLimit;
    let g = &frame.gbuffer;
    let hits = || (0..g.len()).filter(|&i| g.is_hit(i));
    let in_shadow = |i: usize| reference.data[i] < metrics::SHADOW_THRESHOLD;
    let penumbra = |i: usize| in_shadow(i) && reference.data[i] > 0.0;
    let has_receivers_only = frame.flat.roles.iter().any(|r| r.receiver && !r.occluder);
    let has_non_occluders = frame.flat.roles.iter().any(|r| !r.occluder);
    let centre = frame.scene.light.center();
    let lifted = |i: usize| g.position[i] + g.normal[i] * frame.epsilon;
    let facing = |i: usize| g.normal[i].dot(centre - lifted(i)) > 0.0;
    let mut warnings = Vec::new();
    for &limit in info.limits {
        let n = match limit {
            MethodLimit::NoOccluderShadowing if has_receivers_only => hits()
                .filter(|&i| frame.flat.role_of(g.triangle[i] as usize).occluder && in_shadow(i))
                .count(),
            MethodLimit::OuterPenumbraOnly => hits()
                .filter(|&i| penumbra(i) && frame.bvh.occluded(lifted(i), centre))
                .count(),
            MethodLimit::NoPenumbra => hits().filter(|&i| penumbra(i)).count(),
            MethodLimit::AvertedNonOccludersLit if has_non_occluders => hits()
                .filter(|&i| {
                    let role = frame.flat.role_of(g.triangle[i] as usize);
                    !role.occluder && in_shadow(i) && !facing(i)
                })
                .count(),
            MethodLimit::NonOccludersCast if has_non_occluders => hits()
                .filter(|&i| {
                    let p = lifted(i);
                    facing(i)
                        && !frame.bvh.occluded(p, centre)
                        && frame.bvh.blocked_by_any(p, centre)
                })
                .count(),
            _ => 0,
        };
        if n > 0 && limit == MethodLimit::NonOccludersCast {
            warnings.push(format!(
                "method limit ({}): {n} pixels that no occluder hides from the light centre are \
                 shadowed by objects that are not occluders in '{}'",
                limit.describe(),
                info.id
            ));
        } else if n > 0 {
            warnings.push(format!(
                "method limit ({}): {n} pixels the reference shadows this way are not computed \
                 by '{}'; error.mae_shadow_receivers gives the error on receiver-only surfaces",
                limit.describe(),
                info.id
            ));
        }
    }
    warnings
}

/// A run's GPU time cannot exceed its wall time: such a reading is moved to
/// `execution.gpu_ms_invalid` with a warning, so it is never charted, claimed or compared (the
/// wgpu executions already check each submission, `gpu::timing`; this is the last guard).
fn check_gpu_time(record: &mut RunRecord) {
    let Some(gpu_ms) = record.gpu_ms.filter(|g| g.is_nan() || *g > record.wall_ms) else {
        return;
    };
    let reason = format!(
        "GPU time {gpu_ms:.3} ms exceeds the run's wall time {:.3} ms",
        record.wall_ms
    );
    record.execution.insert(
        "gpu_ms_invalid".into(),
        serde_json::json!({ "reading_ms": gpu_ms, "run_wall_ms": record.wall_ms, "reason": reason }),
    );
    record.warnings.push(format!(
        "gpu_ms invalid, left out of charts, claims and comparisons: {reason}"
    ));
    record.gpu_ms = None;
    for p in &mut record.phases {
        p.gpu_ms = None;
    }
}

/// Options of `shadowbench run`.
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub out: PathBuf,
    /// Restrict to these algorithms.
    pub only: Option<Vec<String>>,
    /// Restrict to these backends.
    pub backends: Option<Vec<Backend>>,
    /// Where reference images are cached (default: `OUT/reference-cache`).
    pub cache_dir: Option<PathBuf>,
    /// Largest estimated working set of one run, in bytes.
    pub memory_limit: u64,
    /// Overrides the scenario's machine.
    pub machine: Option<crate::model::MachineConfig>,
    /// Run only this shard of the plan.
    pub shard: Option<Shard>,
    /// Most sweep points a scenario may have ([`crate::scenario::MAX_CASES`] by default).
    pub max_cases: u64,
    /// Wall-clock budget of one run (overrides the scenario's `run_timeout_s`); a run past it
    /// is cancelled and recorded as failed.
    pub run_timeout: Option<std::time::Duration>,
    /// What is printed while the sweep runs.
    pub verbosity: Verbosity,
    /// Whether wgpu runs make their instrumented replay (`--gpu-counters`).
    pub gpu_counters: crate::gpu::GpuCounters,
    /// The measurement protocol's fields given on the command line (over the scenario's
    /// `measure`).
    pub measure: measure::Overrides,
    /// Start afresh: results already in `out` (of any scenario or build) are replaced.
    pub fresh: bool,
    /// Run again the runs that failed in the results already in `out`.
    pub retry_failed: bool,
}

/// What `run` prints while it works.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Verbosity {
    /// Nothing but warnings and errors: no progress bar, no line per run.
    Quiet,
    /// A progress bar on a terminal; one line per finished run on standard output when that is
    /// not a terminal (a pipe, a CI log).
    #[default]
    Normal,
    /// One line per finished run always, beside the progress bar.
    Verbose,
}

/// One planned run.
struct Planned {
    case: usize,
    /// The algorithm with the scenario's options, read once for the sweep.
    algorithm: Configured,
    backend: Backend,
}

/// The error when `--only` / `--backend` leave no run of the scenario: what was asked and what
/// the scenario has.
fn nothing_selected(
    loaded: &Loaded,
    opts: &RunOptions,
    usable: &[Backend],
) -> crate::error::InputError {
    let s = &loaded.scenario;
    let asked = |v: Option<Vec<String>>| v.map_or("all".to_string(), |v| v.join(","));
    let mut message = format!(
        "no run selected: --only {} with --backend {} matches no algorithm × execution of \
         scenario '{}' (algorithms: {}; backends: {})",
        asked(opts.only.clone()),
        asked(
            opts.backends
                .as_ref()
                .map(|b| b.iter().map(|b| b.name().to_string()).collect())
        ),
        loaded.name(),
        s.algorithms.join(", "),
        s.backends.join(", "),
    );
    if s.backends.iter().any(|b| b == Backend::Wgpu.name())
        && !usable.contains(&Backend::Wgpu)
        && opts
            .backends
            .as_ref()
            .is_none_or(|b| b.contains(&Backend::Wgpu))
    {
        message.push_str("; the wgpu execution has no adapter here");
    }
    crate::error::InputError {
        file: Some(loaded.path.clone()),
        field: Some("--only/--backend".into()),
        message,
    }
}

/// The runs of the scenario's `cases` that `opts` selects (`--only`, `--backend`, `--shard`),
/// in order: case by case, algorithm by algorithm, execution by execution. Executions an
/// algorithm lacks, and the wgpu execution without an adapter, are skipped with a note.
fn plan_runs(
    loaded: &Loaded,
    opts: &RunOptions,
    cases: &[crate::scenario::Case],
) -> Result<(Vec<Planned>, usize)> {
    let s = &loaded.scenario;
    // Validated with the scenario; an error still names the scenario's file.
    let in_file = |mut e: crate::error::InputError| {
        e.file = Some(loaded.path.clone());
        e
    };
    let mut algorithms = Vec::new();
    for a in &s.algorithms {
        if opts.only.as_ref().is_none_or(|o| o.contains(a)) {
            let info = algorithms::find(a)
                .map_err(|e| in_file(crate::error::InputError::new("$.algorithms", e)))?;
            algorithms.push(info.configure(&s.options).map_err(in_file)?);
        }
    }
    let mut backends: Vec<Backend> = s
        .backends
        .iter()
        .map(|b| Backend::parse(b).expect("validated"))
        .filter(|b| opts.backends.as_ref().is_none_or(|o| o.contains(b)))
        .collect();
    if backends.contains(&Backend::Wgpu) {
        if let Err(e) = crate::gpu::gpu() {
            // The reason as `list` gives it, without the error's `wgpu: ` prefix.
            let why = match &e {
                crate::error::Error::Gpu(reason) => reason.clone(),
                other => other.to_string(),
            };
            crate::errln!("note: skipping the wgpu execution: {why}");
            backends.retain(|&b| b != Backend::Wgpu);
        }
    }
    let mut plan = Vec::new();
    let mut skipped = Vec::new();
    for ci in 0..cases.len() {
        for configured in &algorithms {
            let info = configured.info;
            for &b in &backends {
                if info.backends.contains(&b) {
                    plan.push(Planned {
                        case: ci,
                        algorithm: configured.clone(),
                        backend: b,
                    });
                } else if ci == 0 && opts.backends.as_ref().is_some_and(|o| o.contains(&b)) {
                    // Only where --backend asked for it: a scenario's list of executions
                    // covers every algorithm, and which each has is in `list`.
                    skipped.push(format!("{} on {b}", info.id));
                }
            }
        }
    }
    if plan.is_empty() {
        return Err(nothing_selected(loaded, opts, &backends).into());
    }
    let (mut plan, repeats) = without_repeats(loaded, cases, plan);
    if let Some(shard) = opts.shard {
        plan = plan
            .into_iter()
            .enumerate()
            .filter(|(i, _)| shard.includes(*i))
            .map(|(_, p)| p)
            .collect();
    }
    for s in &skipped {
        crate::errln!("note: skipping {s} (no such execution)");
    }
    Ok((plan, repeats))
}

/// `plan` without the runs that repeat an earlier one: two sweep points that resolve to the
/// same run (a swept value equal to the base point's, a light size left to the scene that
/// equals a swept one) have one [`case_id`], computed here as the run will compute it, so the
/// planned count is what runs; with how many were left out. Builds each scene point's scene
/// once.
fn without_repeats(
    loaded: &Loaded,
    cases: &[crate::scenario::Case],
    plan: Vec<Planned>,
) -> (Vec<Planned>, usize) {
    let before = plan.len();
    let mut scenes: Vec<(crate::scenario::ScenePoint, String, u32, Light, glam::Vec3)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    let plan = plan
        .into_iter()
        .filter(|p| {
            let case = &cases[p.case];
            let at = match scenes.iter().position(|s| s.0 == case.scene) {
                Some(i) => i,
                None => {
                    let sc = loaded.build_scene(case.scene, None);
                    let center = sc.bounds().center();
                    let tris = sc.triangle_count() as u32;
                    scenes.push((case.scene, sc.name, tris, sc.light, center));
                    scenes.len() - 1
                }
            };
            let (_, name, tris, light, center) = &scenes[at];
            let light = case.light_size.map_or(*light, |s| light.with_size(s));
            let info = p.algorithm.info;
            let used = light_as(light, info.light_for(light.kind()), *center);
            let params = case.params_with(*tris, used.size());
            let variant = p.algorithm.variant();
            seen.insert(case_id(
                name,
                (info.id, variant.as_deref()),
                p.backend,
                &params,
            ))
        })
        .collect::<Vec<_>>();
    let repeats = before - plan.len();
    (plan, repeats)
}

/// The reference cache of a sweep: in `--cache-dir`, or `reference-cache` under `--out`; in
/// memory only when that folder cannot be used (the cache only saves time).
fn reference_cache(s: &crate::scenario::Scenario, opts: &RunOptions, seed: u64) -> ReferenceCache {
    let cache_dir = opts
        .cache_dir
        .clone()
        .unwrap_or_else(|| opts.out.join("reference-cache"));
    let mut refs = ReferenceCache::new(Some(cache_dir.clone()), s.reference.samples, seed);
    if s.reference.enabled {
        if let Err(e) = cache::describe(&cache_dir) {
            crate::errln!("warning: reference cache: {e}; going on without the cache folder");
            refs.memory_only();
        }
    }
    refs
}

/// Runs every case of the scenario; writes `results.json`, `results.csv` and images under
/// `opts.out` after each run, and returns what `results.json` holds.
pub fn run_scenario(loaded: &Loaded, opts: &RunOptions) -> Result<output::ResultsFile> {
    let s = &loaded.scenario;
    let cases = loaded.cases(opts.max_cases)?;
    let (plan, repeats) = plan_runs(loaded, opts, &cases)?;
    std::fs::create_dir_all(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    let mut refs = reference_cache(s, opts, s.seed);
    // The reference of another seed, for the floor of an animation's flicker; and that floor
    // per case and light kind, computed once.
    let mut floor_refs = s
        .animation
        .as_ref()
        .map(|_| reference_cache(s, opts, s.seed.wrapping_add(1)));
    let mut floors: BTreeMap<(usize, LightKind), Option<f64>> = BTreeMap::new();
    let mut ctx = ExecContext {
        reference_samples: s.reference.samples,
        seed: s.seed,
        options: s.options.clone(),
        machine: opts
            .machine
            .clone()
            .unwrap_or_else(|| loaded.machine.clone()),
        deadline: Deadline::default(),
        gpu_counters: opts.gpu_counters,
        measure: opts.measure.apply(s.measure.unwrap_or_default())?,
        flip_pixels_per_degree: s.reference.flip_pixels_per_degree(),
        time_tasks: false,
    };
    let timeout = opts
        .run_timeout
        .or(s.run_timeout_s.map(std::time::Duration::from_secs_f64));
    crate::errln!(
        "planned {} runs over {} cases{}; estimated work {:.3e} fill{}",
        plan.len(),
        cases.len(),
        match repeats {
            0 => String::new(),
            n => format!(" ({n} more would repeat an earlier run and are left out)"),
        },
        sweep_work(loaded, &cases, &plan, &ctx),
        timeout.map_or(String::new(), |t| format!(
            "; each run stops after {} s",
            t.as_secs_f64()
        ))
    );

    let origin = output::Origin {
        scenario_digest: scenario_digest(loaded, &ctx),
        build: crate::build::id(),
    };
    let kept = output::resumable(&opts.out, &origin, opts.fresh, opts.retry_failed)?;
    if !kept.is_empty() {
        crate::errln!(
            "resuming: {} finished runs kept from {}; only the missing ones run",
            kept.len(),
            opts.out.join("results.json").display()
        );
    }
    let mut progress = Progress::new(plan.len(), opts.verbosity);
    let bar = progress.bar.clone();
    let mut writer = output::ResultsWriter::new(&opts.out, loaded, Some(origin), kept);
    let mut current: Option<(usize, Scene)> = None;
    let mut frames: BTreeMap<LightKind, Frame> = BTreeMap::new();
    for p in &plan {
        let case = &cases[p.case];
        bar.set_message(format!(
            "{} on {} at case {}/{}: {}",
            p.algorithm.id(),
            p.backend,
            p.case + 1,
            cases.len(),
            case_label(case)
        ));
        // The run's budget covers each of its phases: the frame, the reference, the execution.
        let deadline = timeout.map_or(Deadline::default(), Deadline::after);
        if current.as_ref().map(|c| c.0) != Some(p.case) {
            current = Some((p.case, loaded.build_scene(case.scene, case.light_size)));
            frames.clear();
        }
        let scene = &current.as_ref().expect("set above").1;
        let info = p.algorithm.info;
        let kind = info.light_for(scene.light.kind());
        let mut sc = scene.clone();
        let converted = light_for_run(scene, info);
        if let Ok(l) = converted {
            sc.light = l;
        }
        let params = case.run_params(&sc);
        let refused = converted.err().map(|e| e.to_string()).or_else(|| {
            limits::check(info, p.backend, &ctx.machine, &params, opts.memory_limit)
                .err()
                .map(|e| e.to_string())
        });
        let variant = p.algorithm.variant();
        if let Some(e) = refused {
            let mut record = RunRecord::new(info.id, p.backend, &sc, params);
            record.variant = variant;
            if writer.take_kept(&record.case_id()) {
                progress.skipped();
                continue;
            }
            loaded.notes.annotate(&mut record);
            record.failure = Some(e);
            progress.finished(&record);
            writer.push(record, None, None, None, None)?;
            continue;
        }
        // The run finished in the sweep this one resumes.
        let id = case_id(&sc.name, (info.id, variant.as_deref()), p.backend, &params);
        if writer.take_kept(&id) {
            progress.skipped();
            continue;
        }
        // A run stopped before its execution: failed, with its elapsed time and estimate.
        let stopped =
            |c, phase: &str, sc: &Scene, params: crate::frame::RunParams, with_reference: bool| {
                let extent = algorithms::work::SceneExtent::of(sc);
                let reference = match with_reference {
                    true => algorithms::reference::work_estimate(&extent, &params, &ctx, &()),
                    false => 0.0,
                };
                let estimate = Some(
                    algorithms::work::frame(&extent, &params)
                        + p.algorithm.work_estimate(&extent, &params, &ctx)
                        + reference,
                );
                let mut record = RunRecord::new(info.id, p.backend, sc, params);
                record.variant = variant.clone();
                loaded.notes.annotate(&mut record);
                record.wall_ms = deadline.elapsed().as_secs_f64() * 1e3;
                record.failure =
                    Some(timed_out(c, deadline.elapsed(), phase, estimate).to_string());
                record
            };
        let frame = match frames.entry(kind) {
            std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::btree_map::Entry::Vacant(e) => {
                match within(|| Frame::new_until(sc.clone(), params.clone(), deadline)) {
                    Ok(f) => e.insert(f),
                    Err(c) => {
                        let record = stopped(c, "its frame (BVH, eye pass)", &sc, params, false);
                        progress.finished(&record);
                        writer.push(record, None, None, None, None)?;
                        continue;
                    }
                }
            }
        };
        let frame = &*frame;
        let (reference, cache_warnings) = if s.reference.enabled {
            match within(|| refs.get_or_compute_until(frame, deadline)) {
                Ok(r) => {
                    let (r, w) = r?;
                    for w in &w {
                        bar.suspend(|| crate::errln!("warning: {w}"));
                    }
                    (Some(r), w)
                }
                Err(c) => {
                    let record =
                        stopped(c, "its reference", &frame.scene, frame.params.clone(), true);
                    progress.finished(&record);
                    writer.push(record, None, None, None, None)?;
                    continue;
                }
            }
        } else {
            (None, vec![])
        };
        ctx.deadline = deadline;
        let (mut record, out) = run_one(frame, &p.algorithm, p.backend, &ctx, reference.as_ref());
        let sequence = match (&s.animation, &out, &mut floor_refs) {
            (Some(anim), Some(_), Some(floor_refs))
                if info.id != crate::algorithms::reference::ID && reference.is_some() =>
            {
                // The occluder's height of each frame, from the path's start or the case's.
                let objects = |t: u32| {
                    let h = anim.occluder_height.as_ref()?;
                    let start = h.from.or(case.scene.occluder_height)?;
                    let point = crate::scenario::ScenePoint {
                        occluder_height: Some(h.at(start, anim.frames, t)),
                        ..case.scene
                    };
                    Some(loaded.build_scene(point, case.light_size).objects)
                };
                animate(
                    anim,
                    &animation::Scenes {
                        scene: &frame.scene,
                        objects: &objects,
                        params: &frame.params,
                    },
                    (&p.algorithm, p.backend),
                    &ctx,
                    (&mut refs, floor_refs),
                    floors.entry((p.case, kind)).or_default(),
                    &mut record,
                )
            }
            _ => None,
        };
        loaded.notes.annotate(&mut record);
        record.warnings.extend(cache_warnings);
        if kind != scene.light.kind() {
            record.notes.push(light_converted(scene.light.kind(), kind));
        }
        progress.finished(&record);
        let images = opts.out.join("images").join(record.case_id());
        writer.push(
            record,
            out.as_ref().map(|o| &o.visibility),
            out.as_ref().and_then(|o| o.rgb.as_ref()),
            reference.as_ref(),
            Some(frame),
        )?;
        if let Some(seq) = sequence {
            animation::write(&images, &seq)?;
        }
    }
    bar.finish_and_clear();
    writer.finish()
}

/// The animated sequence of a run ([`animation`]) in `scenes`: its temporal figures into
/// `record.animation` (with the flicker floor `floor`, computed here once per case and light
/// kind from `refs.1`, the reference of another seed), the sequence returned for its images.
/// A sequence that fails leaves a warning and no figures.
fn animate(
    anim: &animation::Animation,
    scenes: &animation::Scenes,
    (algorithm, backend): (&Configured, Backend),
    ctx: &ExecContext,
    refs: (&mut ReferenceCache, &mut ReferenceCache),
    floor: &mut Option<f64>,
    record: &mut RunRecord,
) -> Option<animation::Rendered> {
    let seq = match animation::render(anim, scenes, algorithm, backend, ctx, refs.0) {
        Ok(seq) => seq,
        Err(e) => {
            record.warnings.push(format!("animation not rendered: {e}"));
            return None;
        }
    };
    if floor.is_none() {
        match animation::reference_sequence(anim, scenes, refs.1) {
            Ok(other) => *floor = animation::flicker(&other, &seq.reference, &seq.masks).0,
            Err(e) => record.warnings.push(format!(
                "animation: no flicker floor (reference of another seed: {e})"
            )),
        }
    }
    record.animation = Some(animation::record(&seq, *floor));
    Some(seq)
}

/// A digest of what a sweep's results depend on besides the build: the scenario as run, the
/// resolved machine of cpu-model runs and the wgpu counter mode (CRC-32, hex). Mesh files a
/// scenario names are not read into it.
fn scenario_digest(loaded: &Loaded, ctx: &ExecContext) -> String {
    let what = serde_json::json!({
        "scenario": loaded.scenario,
        "machine": ctx.machine,
        "gpu_counters": format!("{:?}", ctx.gpu_counters),
    });
    format!(
        "{:08x}",
        crc32fast::hash(&serde_json::to_vec(&what).expect("scenarios serialize"))
    )
}

/// The estimated fill of the planned runs ([`algorithms::work`]): each run's frame and
/// algorithm, and the reference of each case when the scenario has one. Builds
/// only the first case's scene (geometry dominates its cost); each case differs from it in its
/// light size and parameters, which is what the estimates depend on most.
fn sweep_work(
    loaded: &Loaded,
    cases: &[crate::scenario::Case],
    plan: &[Planned],
    ctx: &ExecContext,
) -> f64 {
    let Some(first) = plan.first() else {
        return 0.0;
    };
    let base = loaded.build_scene(cases[first.case].scene, None);
    let center = base.bounds().center();
    let mut cases_seen = std::collections::HashSet::new();
    plan.iter()
        .map(|p| {
            let case = &cases[p.case];
            let info = p.algorithm.info;
            let light = case
                .light_size
                .map_or(base.light, |size| base.light.with_size(size));
            let extent = algorithms::work::SceneExtent {
                light: light_as(light, info.light_for(light.kind()), center),
                center,
                light_texels: algorithms::work::texture_texels(&base),
            };
            let params = crate::frame::RunParams {
                light_size: extent.light.size(),
                ..case.run_params(&base)
            };
            // The reference of a case is computed once, by its first run.
            let first_of_case = cases_seen.insert(p.case);
            let quality = if loaded.scenario.reference.enabled && first_of_case {
                algorithms::reference::work_estimate(&extent, &params, ctx, &())
            } else {
                0.0
            };
            algorithms::work::frame(&extent, &params)
                + p.algorithm.work_estimate(&extent, &params, ctx)
                + quality
        })
        .sum()
}

/// The progress of a sweep: a bar on a terminal (standard error) and, where asked, one line per
/// finished run on standard output.
struct Progress {
    bar: ProgressBar,
    lines: bool,
    started: Instant,
    total: usize,
    done: usize,
}

impl Progress {
    fn new(total: usize, verbosity: Verbosity) -> Progress {
        let bar = if verbosity == Verbosity::Quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(total as u64)
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{bar:30} {pos}/{len} runs, {elapsed_precise} elapsed, ETA {eta_precise}  {msg}",
            )
            .expect("valid template"),
        );
        let lines = match verbosity {
            Verbosity::Quiet => false,
            Verbosity::Normal => !std::io::stdout().is_terminal(),
            Verbosity::Verbose => true,
        };
        Progress {
            bar,
            lines,
            started: Instant::now(),
            total,
            done: 0,
        }
    }

    /// A run finished (or failed).
    fn finished(&mut self, record: &RunRecord) {
        self.done += 1;
        if self.lines {
            let line = progress_line(self.done, self.total, self.started.elapsed(), record);
            self.bar.suspend(|| crate::outln!("{line}"));
        }
        self.bar.inc(1);
    }

    /// A run kept from the sweep this one resumes.
    fn skipped(&mut self) {
        self.done += 1;
        self.bar.inc(1);
    }
}

/// `h:mm:ss` or `m:ss`.
fn clock(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 3600 {
        format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
    } else {
        format!("{}:{:02}", s / 60, s % 60)
    }
}

/// A case's parameters, short: `2000 tris, light 0.6, map 256, tile 32, 160×120`.
fn case_label(c: &crate::scenario::Case) -> String {
    let mut s = Vec::new();
    if let Some(t) = c.scene.triangles {
        s.push(format!("{t} tris"));
    }
    if let Some(m) = c.scene.mesh {
        s.push(format!("mesh {}", m + 1));
    }
    if let Some(l) = c.light_size {
        s.push(format!("light {l}"));
    }
    s.push(format!("map {}", c.map_resolution));
    s.push(format!("tile {}", c.tile_size));
    s.push(format!("{}×{}", c.image[0], c.image[1]));
    if let Some(h) = c.scene.occluder_height {
        s.push(format!("height {h}"));
    }
    if let Some(d) = c.scene.occluder_offset {
        s.push(format!("offset {d}"));
    }
    if let Some(n) = c.cores {
        s.push(format!("{n} cores"));
    }
    s.join(", ")
}

/// The line of a finished run: count, elapsed time and ETA, algorithm, execution, the case's
/// parameters and the outcome.
pub fn progress_line(done: usize, total: usize, elapsed: Duration, r: &RunRecord) -> String {
    let eta = if done > 0 {
        elapsed.mul_f64((total - done.min(total)) as f64 / done as f64)
    } else {
        Duration::ZERO
    };
    let p = &r.params;
    let outcome = match (&r.failure, &r.error) {
        (Some(f), _) => format!("FAILED: {}", f.lines().next().unwrap_or_default()),
        (None, Some(e)) => match e.mae_shadow {
            Some(m) => format!("{} ms, mae_shadow {m:.4}", short(r.wall_ms)),
            None => format!("{} ms", short(r.wall_ms)),
        },
        (None, None) => format!("{} ms", short(r.wall_ms)),
    };
    let width = total.to_string().len();
    format!(
        "[{done:>width$}/{total} {} ETA {}] {:<18} {:<10} {} tris, light {}, map {}: {outcome}",
        clock(elapsed),
        clock(eta),
        r.algorithm,
        r.backend,
        p.triangles,
        crate::record::fmt_light_size(p.light_size),
        p.map_resolution,
    )
}

/// Three significant digits, at most 8 characters.
fn short(v: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    let a = v.abs();
    if a >= 1e5 || (a < 1e-3 && a > 0.0) {
        format!("{v:.2e}")
    } else if a >= 100.0 || a == 0.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// The end-of-sweep summary, per algorithm × execution, at most 100 columns wide: runs,
/// failures, and the range (min–max over the runs) of wall, modelled and GPU time and of
/// `mae_shadow`.
pub fn grouped_summary(records: &[RunRecord]) -> String {
    let mut groups: Vec<(&str, Backend)> = records
        .iter()
        .map(|r| (r.algorithm.as_str(), r.backend))
        .collect();
    // Registered order of algorithms (unknown names last), then of executions.
    groups.sort_by_key(|&(a, b)| {
        (
            algorithms::ALGORITHMS
                .iter()
                .position(|x| x.id == a)
                .unwrap_or(usize::MAX),
            b,
            a,
        )
    });
    groups.dedup();
    let range = |v: Vec<f64>| -> String {
        let min = v.iter().copied().fold(f64::INFINITY, f64::min);
        let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        match v.len() {
            0 => "-".into(),
            _ if min == max => short(min),
            _ => format!("{}-{}", short(min), short(max)),
        }
    };
    let mut s = format!(
        "{:<18} {:<10} {:>4} {:>4} {:>14} {:>14} {:>14} {:>15}\n",
        "algorithm", "execution", "runs", "fail", "wall ms", "model ms", "gpu ms", "mae_shadow"
    );
    for (a, b) in groups {
        let runs: Vec<&RunRecord> = records
            .iter()
            .filter(|r| r.algorithm == a && r.backend == b)
            .collect();
        let ok: Vec<&&RunRecord> = runs.iter().filter(|r| r.failure.is_none()).collect();
        let mae: Vec<f64> = ok
            .iter()
            .filter_map(|r| r.error.as_ref().and_then(|e| e.mae_shadow))
            .collect();
        let mae = match mae.len() {
            0 => "-".to_string(),
            _ => {
                let min = mae.iter().copied().fold(f64::INFINITY, f64::min);
                let max = mae.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                if min == max {
                    format!("{min:.4}")
                } else {
                    format!("{min:.4}-{max:.4}")
                }
            }
        };
        s.push_str(&format!(
            "{:<18} {:<10} {:>4} {:>4} {:>14} {:>14} {:>14} {:>15}\n",
            a,
            b,
            runs.len(),
            runs.len() - ok.len(),
            range(ok.iter().map(|r| r.wall_ms).collect()),
            range(ok.iter().filter_map(|r| r.model_ms).collect()),
            range(ok.iter().filter_map(|r| r.gpu_ms).collect()),
            mae,
        ));
    }
    s
}

/// A one-line summary table of records.
pub fn summary_table(records: &[RunRecord]) -> String {
    let mut s = format!(
        "{:<18} {:<10} {:<16} {:>7} {:>6} {:>5} {:>9} {:>10} {:>10} {:>9} {:>10}\n",
        "algorithm",
        "backend",
        "scene",
        "tris",
        "light",
        "map",
        "image",
        "wall_ms",
        "model_ms",
        "gpu_ms",
        "mae_shadow"
    );
    let opt = |v: Option<f64>| v.map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into());
    for r in records {
        let p = &r.params;
        s.push_str(&format!(
            "{:<18} {:<10} {:<16} {:>7} {:>6.3} {:>5} {:>9} {:>10.2} {:>10} {:>9} {:>10}\n",
            r.algorithm,
            r.backend,
            r.scene,
            p.triangles,
            p.light_size,
            p.map_resolution,
            format!("{}x{}", p.image[0], p.image[1]),
            r.wall_ms,
            opt(r.model_ms),
            opt(r.gpu_ms),
            match (&r.failure, &r.error) {
                (Some(_), _) => "FAILED".to_string(),
                (None, Some(e)) => e
                    .mae_shadow
                    .map_or_else(|| "-".into(), |v| format!("{v:.4}")),
                _ => "-".into(),
            }
        ));
    }
    s
}

/// Writes the files of a single rendered frame: visibility.png (grey, transparent where the
/// pixel sees no surface), visibility.npy, mask.npy (1 where the pixel sees a surface),
/// shaded.png (visibility × a Lambertian term, [`images::write_shaded`]), run.json,
/// visibility_rgb.png (the light received per channel) under a textured light and, with a
/// reference, reference.png, reference_shaded.png, error.png and flip.png (the ꟻLIP error map
/// of the shaded views at `pixels_per_degree`, [`flip_map`]). Those of them an earlier
/// frame left in `dir` and this one does not write are removed, so the folder holds one
/// frame's files.
pub fn write_frame_files(
    dir: &Path,
    record: &RunRecord,
    visibility: Option<&VisibilityBuffer>,
    rgb: Option<&RgbBuffer>,
    reference: Option<&VisibilityBuffer>,
    frame: &Frame,
    pixels_per_degree: f32,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut written = Vec::new();
    if let Some(c) = rgb {
        c.write_png(&dir.join(FRAME_FILES[0]))?;
        written.push(FRAME_FILES[0]);
    }
    if let Some(v) = visibility {
        let mask = frame.gbuffer.mask();
        images::write_masked_png(v, &mask, &dir.join("visibility.png"))?;
        v.write_npy(&dir.join("visibility.npy"))?;
        images::write_mask_npy(&mask, v.width, v.height, &dir.join("mask.npy"))?;
        images::write_shaded(v, frame, &dir.join("shaded.png"))?;
        written.extend(&FRAME_FILES[1..5]);
        if let Some(r) = reference.filter(|_| record.algorithm != crate::algorithms::reference::ID)
        {
            images::write_masked_png(r, &mask, &dir.join("reference.png"))?;
            images::write_shaded(r, frame, &dir.join("reference_shaded.png"))?;
            metrics::write_error_heatmap(v, r, &mask, &dir.join("error.png"))?;
            metrics::perceptual::write_flip_map(
                &flip_map(v, r, frame, pixels_per_degree),
                &mask,
                v.width,
                v.height,
                &dir.join("flip.png"),
            )?;
            written.extend(&FRAME_FILES[5..]);
        }
    }
    for stale in FRAME_FILES.iter().filter(|f| !written.contains(f)) {
        let path = dir.join(stale);
        match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(Error::io(&path, e)),
            _ => {}
        }
    }
    let json = serde_json::to_vec_pretty(record).expect("records serialize");
    crate::visibility::write_atomic(&dir.join("run.json"), &json)
}

/// The image files [`write_frame_files`] writes besides run.json, in the order it writes them.
const FRAME_FILES: [&str; 9] = [
    "visibility_rgb.png",
    "visibility.png",
    "visibility.npy",
    "mask.npy",
    "shaded.png",
    "reference.png",
    "reference_shaded.png",
    "error.png",
    "flip.png",
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::testdata::record;

    #[test]
    fn the_end_summary_has_a_row_per_algorithm_and_execution_within_100_columns() {
        let mut runs = Vec::new();
        for t in [500, 2000, 8000] {
            for a in algorithms::ALGORITHMS {
                for b in Backend::ALL {
                    let mut r = record(a.id, b, t, 32);
                    // Wide figures: the columns must still fit.
                    r.wall_ms = 1000.0 * t as f64;
                    r.model_ms = Some(0.000123 * t as f64);
                    r.gpu_ms = Some(98765.4);
                    runs.push(r);
                }
            }
        }
        runs[1].failure = Some("out of memory".into());
        let text = grouped_summary(&runs);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines.len(),
            1 + algorithms::ALGORITHMS.len() * Backend::ALL.len()
        );
        for l in &lines {
            assert!(
                l.chars().count() <= 100,
                "{} columns: {l}",
                l.chars().count()
            );
        }
        // The failed run counts in its group, and only there.
        let r = &runs[1];
        let row = lines
            .iter()
            .find(|l| l.starts_with(&format!("{:<18} {:<10}", r.algorithm, r.backend)))
            .unwrap();
        let cols: Vec<&str> = row.split_whitespace().collect();
        assert_eq!((cols[2], cols[3]), ("3", "1"), "{row}");
        // A range from the smallest to the largest wall time of the group's successful runs.
        let first = lines[1];
        assert!(first.contains(" 5.00e5-8.00e6 "), "{first}");
    }

    #[test]
    fn the_planned_runs_of_quick_are_what_runs_the_base_point_merged_once() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick.json");
        let loaded = Loaded::from_file(&path).unwrap();
        let cases = loaded.cases(1000).unwrap();
        // The base point (2000 triangles, the scene's light) and five swept points.
        assert_eq!(cases.len(), 6);
        let scene = loaded.build_scene(cases[0].scene, None);
        // The light sweep holds the scene's own size: that point is the base point again.
        assert!(loaded
            .scenario
            .sweep
            .light_size
            .contains(&scene.light.size()));
        let cpu = [Backend::CpuNative, Backend::CpuModel];
        let opts = RunOptions {
            out: PathBuf::from("unused"),
            only: None,
            backends: Some(cpu.to_vec()),
            cache_dir: None,
            memory_limit: u64::MAX,
            machine: None,
            shard: None,
            max_cases: 1000,
            run_timeout: None,
            verbosity: Verbosity::Quiet,
            gpu_counters: Default::default(),
            measure: Default::default(),
            fresh: false,
            retry_failed: false,
        };
        let per_case: usize = loaded
            .scenario
            .algorithms
            .iter()
            .map(|a| {
                let info = algorithms::find(a).unwrap();
                cpu.iter().filter(|b| info.backends.contains(b)).count()
            })
            .sum();
        let (plan, _) = plan_runs(&loaded, &opts, &cases).unwrap();
        assert_eq!(plan.len(), 5 * per_case);
    }

    #[test]
    fn a_progress_line_names_the_run_its_case_and_the_time_left() {
        let mut r = record("pcss", Backend::CpuModel, 2000, 32);
        r.params.light_size = 0.6;
        let l = progress_line(10, 40, Duration::from_secs(75), &r);
        // 75 s for 10 runs: 30 runs left take 225 s.
        assert!(l.starts_with("[10/40 1:15 ETA 3:45] pcss"), "{l}");
        assert!(
            l.contains("cpu-model") && l.contains("2000 tris, light 0.6, map 512"),
            "{l}"
        );
        assert!(l.contains("mae_shadow 0.0500"), "{l}");
        r.failure = Some("no adapter\nmore".into());
        let l = progress_line(40, 40, Duration::from_secs(3700), &r);
        assert!(
            l.contains("1:01:40 ETA 0:00") && l.ends_with("FAILED: no adapter"),
            "{l}"
        );
    }

    #[test]
    fn a_gpu_time_above_the_wall_time_is_recorded_invalid_not_kept() {
        let scene = crate::scene::generators::find("sphere-on-plane")
            .unwrap()
            .build(&Default::default());
        let params = crate::frame::RunParams::of_scene(&scene, [8, 6], 64, 16);
        let mut r = RunRecord::new("pcss", Backend::Wgpu, &scene, params);
        r.wall_ms = 10.0;
        r.gpu_ms = Some(4.0);
        check_gpu_time(&mut r);
        assert_eq!(r.gpu_ms, Some(4.0));
        r.gpu_ms = Some(25.0);
        r.phases.push(crate::record::Phase {
            name: "eye_lookup".into(),
            gpu_ms: Some(25.0),
            ..Default::default()
        });
        check_gpu_time(&mut r);
        assert_eq!(r.gpu_ms, None);
        assert_eq!(r.phases[0].gpu_ms, None);
        assert_eq!(r.execution["gpu_ms_invalid"]["reading_ms"], 25.0);
        assert!(
            r.warnings[0].contains("exceeds the run's wall time"),
            "{:?}",
            r.warnings
        );
    }
}
