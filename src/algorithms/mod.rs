//! The algorithms, one folder each: its math once in `mod.rs`, then one file per execution.
//!
//! Every algorithm takes the same [`Frame`] and returns a [`FrameOutput`] (visibility buffer,
//! counters, phases, times); the harness adds quality against the reference and writes results.

pub mod accum_hard;
pub mod dbuffer;
pub mod eye_raster;
pub mod hard_shadow_map;
pub mod pcss;
pub mod penumbra_map;
pub mod reference;
pub mod shadow_map;
pub mod shadow_map_wgpu;
pub mod shadow_volume;
pub mod soft_izb;
pub mod soft_shadow_map;
pub mod soft_shadow_volume;
pub mod work;

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::{unknown_name, Error, InputError, Result};
use crate::frame::{Frame, RunParams};
use crate::model::MachineConfig;
use crate::record::{Counters, Phase};
use crate::scene::LightKind;
use crate::util::deadline::Deadline;
use crate::visibility::{RgbBuffer, VisibilityBuffer};

/// Where an algorithm runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Backend {
    /// The algorithm's kernels on the host, uninstrumented: honest host wall-clock time.
    CpuNative,
    /// The same kernels on the modelled many-core SIMD machine, counting and timing its work.
    CpuModel,
    /// Real GPU passes through wgpu.
    Wgpu,
}

impl Backend {
    pub const ALL: [Backend; 3] = [Backend::CpuNative, Backend::CpuModel, Backend::Wgpu];

    pub fn name(self) -> &'static str {
        match self {
            Backend::CpuNative => "cpu-native",
            Backend::CpuModel => "cpu-model",
            Backend::Wgpu => "wgpu",
        }
    }

    pub fn parse(s: &str) -> std::result::Result<Backend, String> {
        Backend::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| unknown_name("backend", s, &Backend::ALL.map(|b| b.name())))
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Shadowing an algorithm's method does not compute: its paper's design, not a fault. Declared
/// per algorithm ([`AlgorithmInfo::limits`]), listed in every record
/// (`execution.method_limits`), and a warning in a run where the reference shows it matters
/// (`harness::limit_warnings`); `error.mae_shadow_receivers` restricts the error to receiver-only
/// surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodLimit {
    /// Occluders are not shadowed (by themselves or each other) when the scene has receiver-only
    /// objects: only those receive the soft shadow (002 §3).
    NoOccluderShadowing,
    /// The penumbra is computed only outside the hard shadow of the light centre; the umbra is
    /// that hard shadow, so the inner penumbra is dark (000 §3).
    OuterPenumbraOnly,
    /// No penumbra: the hard shadow of a point light at the light's centre.
    NoPenumbra,
    /// One light-space map: receivers outside it are lit (`light_view.receivers_outside`, with
    /// its own warning).
    OneMap,
}

impl MethodLimit {
    pub fn describe(self) -> &'static str {
        match self {
            MethodLimit::NoOccluderShadowing => {
                "no shadow on occluders when the scene has receiver-only objects"
            }
            MethodLimit::OuterPenumbraOnly => {
                "outer penumbra only: the hard shadow of the light centre is umbra"
            }
            MethodLimit::NoPenumbra => "no penumbra: the hard shadow of the light centre",
            MethodLimit::OneMap => "one light-space map: receivers outside it are lit",
        }
    }
}

/// A registered algorithm.
pub struct AlgorithmInfo {
    pub id: &'static str,
    /// Paper and section it implements.
    pub source: &'static str,
    pub summary: &'static str,
    /// Light kinds it handles; another kind is converted to the first of these (same size).
    pub lights: &'static [LightKind],
    pub backends: &'static [Backend],
    /// Bytes of the algorithm's own buffers for a run (maps, grids, bins), estimated before
    /// anything is allocated; the frame itself is counted by the harness.
    pub memory_estimate: fn(&RunParams) -> u64,
    /// Estimated fill of a run ([`work`]), made before anything runs: reported with a run
    /// stopped by its time budget, and summed over a sweep before it starts.
    pub work_estimate: fn(&work::SceneExtent, &RunParams, &ExecContext) -> f64,
    /// Checks `options.<id>` of a scenario before any work starts.
    pub check_options:
        fn(&BTreeMap<String, serde_json::Value>) -> std::result::Result<(), InputError>,
    /// The shadowing its method does not compute.
    pub limits: &'static [MethodLimit],
}

impl AlgorithmInfo {
    /// The light kind this algorithm runs with when the scene's light is `kind`.
    pub fn light_for(&self, kind: LightKind) -> LightKind {
        if self.lights.contains(&kind) {
            kind
        } else {
            self.lights[0]
        }
    }
}

pub const ALGORITHMS: &[AlgorithmInfo] = &[
    AlgorithmInfo {
        id: "reference",
        source: "ground truth",
        summary: "visible fraction of the light by stratified sampling and BVH ray casting",
        lights: &[LightKind::Sphere, LightKind::Disc, LightKind::Rect],
        backends: &[Backend::CpuNative],
        memory_estimate: |_| 0,
        work_estimate: work::reference,
        check_options: |o| no_options("reference", o),
        limits: &[],
    },
    AlgorithmInfo {
        id: hard_shadow_map::ID,
        source: "baseline (Williams 1978)",
        summary: "shadow map from the light centre with slope-scaled bias",
        lights: &[LightKind::Sphere, LightKind::Disc, LightKind::Rect],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: shadow_map::memory_estimate,
        work_estimate: work::hard_shadow_map,
        check_options: hard_shadow_map::check_options,
        limits: &[MethodLimit::NoPenumbra],
    },
    AlgorithmInfo {
        id: pcss::ID,
        source: "Fernando 2005, cited in 004 Table 2",
        summary: "blocker search + variable-width percentage-closer filter",
        lights: &[LightKind::Sphere, LightKind::Disc, LightKind::Rect],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: shadow_map::memory_estimate,
        work_estimate: work::pcss,
        check_options: pcss::check_options,
        limits: &[],
    },
    AlgorithmInfo {
        id: soft_izb::ID,
        source: "paper 004 (soft irregular shadow mapping), §2",
        summary: "eye samples in a light-space grid; umbra by irregular rasterization (depth \
              complexity), penumbra quads per silhouette edge with analytic circular-segment \
              occlusion (eq. 3), per-bin width and wedge/column culling (§2.5)",
        // §2.3 sizes the light's footprint in the light's image plane: the light it computes is
        // the disc there (normal along its view axis), so a sphere is converted to that disc and
        // the reference is computed for it.
        lights: &[LightKind::Disc],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: soft_izb::cpu::memory_estimate,
        work_estimate: work::soft_izb,
        check_options: |o| soft_izb::SoftIzbOptions::parse(o).map(|_| ()),
        limits: &[MethodLimit::OneMap],
    },
    AlgorithmInfo {
        id: accum_hard::ID,
        source: "001 §1.3, Paper III §5",
        summary: "average of N hard shadow-volume shadows from N light samples",
        lights: &[LightKind::Sphere, LightKind::Disc, LightKind::Rect],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: accum_hard::memory_estimate,
        work_estimate: work::accum_hard,
        check_options: accum_hard::check_options,
        limits: &[],
    },
    AlgorithmInfo {
        id: soft_shadow_volume::ID,
        source: "001 Papers III and IV",
        summary: "hard shadow quads plus penumbra wedges adding or subtracting light coverage",
        lights: &[LightKind::Rect, LightKind::Sphere],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: soft_shadow_volume::memory_estimate,
        work_estimate: work::soft_shadow_volume,
        check_options: soft_shadow_volume::check_options,
        limits: &[],
    },
    AlgorithmInfo {
        id: penumbra_map::ID,
        source: "000 §3-§4 (Wyman and Hansen 2003)",
        summary: "shadow map + penumbra map of cones and sheets on the light-centre silhouette",
        lights: &[LightKind::Sphere],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: penumbra_map::memory_estimate,
        work_estimate: work::penumbra_map,
        check_options: penumbra_map::check_options,
        limits: &[MethodLimit::OuterPenumbraOnly, MethodLimit::OneMap],
    },
    AlgorithmInfo {
        id: soft_shadow_map::ID,
        source: "002 §3-§4 (Atty et al. 2006)",
        summary: "occluder map as micro-patches; penumbra-extent quads add each patch's hidden \
              fraction of the light (interval product) into a soft shadow map; one or two \
              passes, FP32 or FP16 accumulation",
        lights: &[LightKind::Rect],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: soft_shadow_map::memory_estimate,
        work_estimate: work::soft_shadow_map,
        check_options: soft_shadow_map::check_options,
        limits: &[MethodLimit::NoOccluderShadowing, MethodLimit::OneMap],
    },
    AlgorithmInfo {
        id: dbuffer::ID,
        source: "003 §2-§4 (umbra and penumbra volumes, D-buffer)",
        summary: "umbra/penumbra volumes of the area silhouettes (p_near/p_far) drawn from the \
              light centre into a D-buffer of distances; t by eq. 3, V(t) = 3t^2 - 2t^3",
        lights: &[LightKind::Disc],
        backends: &[Backend::CpuNative, Backend::CpuModel, Backend::Wgpu],
        memory_estimate: dbuffer::memory_estimate,
        work_estimate: work::dbuffer,
        check_options: dbuffer::check_options,
        limits: &[MethodLimit::OneMap],
    },
];

/// `check_options` of an algorithm that takes no options.
pub fn no_options(
    id: &str,
    options: &BTreeMap<String, serde_json::Value>,
) -> std::result::Result<(), InputError> {
    match options.get(id) {
        None => Ok(()),
        Some(_) => Err(InputError::new(
            format!("$.options.{id}"),
            format!("algorithm '{id}' takes no options"),
        )),
    }
}

/// Whether algorithm `id` with `options` honours a textured light (`$.light.texture`): the
/// reference weights each light sample by the texture, `soft_shadow_volume` with the 4D coverage
/// texture weights its texels (Paper III §3.3). Every other algorithm would treat the light as
/// uniform white, so it is refused rather than silently wrong.
pub fn check_light_texture(
    id: &str,
    options: &BTreeMap<String, serde_json::Value>,
) -> std::result::Result<(), InputError> {
    match id {
        "reference" => Ok(()),
        soft_shadow_volume::ID => soft_shadow_volume::check_light_texture(options),
        _ => Err(InputError::new(
            "$.light.texture",
            format!(
                "algorithm '{id}' cannot honour a textured light (only reference and {} with \
                 coverage \"texture\" do); drop '{id}' from the algorithms or the texture",
                soft_shadow_volume::ID
            ),
        )),
    }
}

/// The registered algorithm `id`, or an error suggesting the closest name.
pub fn find(id: &str) -> std::result::Result<&'static AlgorithmInfo, String> {
    if let Some(a) = ALGORITHMS.iter().find(|a| a.id == id) {
        return Ok(a);
    }
    let ids: Vec<&str> = ALGORITHMS.iter().map(|a| a.id).collect();
    Err(unknown_name("algorithm", id, &ids))
}

/// Settings that apply to a whole execution (all runs of a `render` or `run`).
#[derive(Clone, Debug)]
pub struct ExecContext {
    /// Light samples per pixel of the reference (a perfect square).
    pub reference_samples: u32,
    pub seed: u64,
    /// Per-algorithm options from the scenario (`options.<algorithm>`), validated by each
    /// algorithm.
    pub options: BTreeMap<String, serde_json::Value>,
    /// The modelled machine of `cpu-model` runs (a run's `cores` overrides its core count).
    pub machine: MachineConfig,
    /// When the run must stop (`--run-timeout`); checked cooperatively by every execution.
    pub deadline: Deadline,
}

impl Default for ExecContext {
    fn default() -> Self {
        ExecContext {
            reference_samples: reference::DEFAULT_SAMPLES,
            seed: 1,
            options: BTreeMap::new(),
            machine: MachineConfig::default(),
            deadline: Deadline::default(),
        }
    }
}

/// What one algorithm produced for one frame.
#[derive(Clone, Debug)]
pub struct FrameOutput {
    pub visibility: VisibilityBuffer,
    pub counters: Counters,
    pub phases: Vec<Phase>,
    pub model_ms: Option<f64>,
    pub gpu_ms: Option<f64>,
    pub execution: BTreeMap<String, serde_json::Value>,
    pub warnings: Vec<String>,
    /// Light received per channel, from algorithms that honour a textured light
    /// ([`check_light_texture`]) when the scene has one.
    pub rgb: Option<RgbBuffer>,
}

/// Runs algorithm `id` on `backend` for `frame`. The derived figures of the counters
/// (`overdraw_ratio`, `simd_utilization`: [`crate::counters::derive`]) are computed here, for
/// the run and each phase, the same way for every algorithm and execution.
pub fn run(id: &str, backend: Backend, frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    let mut out = execute(id, backend, frame, ctx)?;
    crate::counters::derive(&mut out.counters);
    for p in &mut out.phases {
        crate::counters::derive(&mut p.counters);
    }
    Ok(out)
}

/// Runs algorithm `id`'s `backend` execution.
fn execute(id: &str, backend: Backend, frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    let info = find(id).map_err(Error::Unsupported)?;
    if !info.backends.contains(&backend) {
        return Err(Error::Unsupported(format!(
            "algorithm '{id}' has no {backend} execution (it has: {})",
            info.backends
                .iter()
                .map(|b| b.name())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    if frame.scene.light_texture.is_some() {
        check_light_texture(id, &ctx.options)?;
    }
    let fallback = zfail_fallback(id, frame, ctx);
    let ctx = fallback.as_ref().map_or(ctx, |(c, _)| c);
    let mut out = dispatch(id, backend, frame, ctx)?;
    let edges = frame.occluder_edges;
    out.counters
        .set("occluders.boundary_edges", edges.boundary as f64);
    out.counters
        .set("occluders.non_manifold_edges", edges.non_manifold as f64);
    out.warnings.extend(edges.warning());
    out.warnings.extend(frame.precision_warning.clone());
    out.warnings.extend(fallback.map(|(_, w)| w));
    Ok(out)
}

/// z-fail counting (`counting: "z_fail"` of `soft_shadow_volume` and `accum_hard`) closes each
/// shadow volume with caps and is only right for closed 2-manifold occluders: on an open or
/// non-manifold mesh the volumes leak and streaks cross the image. Such runs fall back to z-pass
/// (from the eye's count, right wherever the eye is outside the shadow); returns the options
/// they run with and the run's warning naming the algorithm, the option and the open edges.
fn zfail_fallback(id: &str, frame: &Frame, ctx: &ExecContext) -> Option<(ExecContext, String)> {
    let edges = frame.occluder_edges;
    if ![soft_shadow_volume::ID, accum_hard::ID].contains(&id) || edges.open() == 0 {
        return None;
    }
    // Options the algorithm itself refuses are left for it to report.
    let counting = match id {
        soft_shadow_volume::ID => {
            let o: soft_shadow_volume::SoftShadowVolumeOptions =
                shadow_map::parse_options(id, &ctx.options).ok()?;
            o.validate().ok()?;
            o.counting
        }
        _ => {
            let o: accum_hard::AccumHardOptions =
                shadow_map::parse_options(id, &ctx.options).ok()?;
            o.strata_side().ok()?;
            o.counting
        }
    };
    if counting != shadow_volume::Counting::ZFail {
        return None;
    }
    let mut ctx = ctx.clone();
    if let Some(serde_json::Value::Object(o)) = ctx.options.get_mut(id) {
        o.insert("counting".into(), serde_json::json!("z_pass"));
    }
    let warning = format!(
        "{id}: options.{id}.counting \"z_fail\" needs closed occluders, but they have {} open \
         edges ({} boundary, {} non-manifold): counted with \"z_pass\" instead",
        edges.open(),
        edges.boundary,
        edges.non_manifold
    );
    Some((ctx, warning))
}

/// Runs algorithm `id` (registered, with a `backend` execution) on `backend` for `frame`.
fn dispatch(id: &str, backend: Backend, frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    if backend == Backend::Wgpu {
        return crate::gpu::guarded_run(ctx.deadline, |gpu| match id {
            hard_shadow_map::ID => hard_shadow_map::wgpu::render(gpu, frame, ctx),
            pcss::ID => pcss::wgpu::render(gpu, frame, ctx),
            penumbra_map::ID => penumbra_map::wgpu::render(gpu, frame, ctx),
            dbuffer::ID => dbuffer::wgpu::render(gpu, frame, ctx, dbuffer::options(&ctx.options)?),
            soft_shadow_map::ID => soft_shadow_map::wgpu::render(
                gpu,
                frame,
                &soft_shadow_map::SoftShadowMapOptions::parse(&ctx.options)?,
            ),
            soft_shadow_volume::ID => soft_shadow_volume::wgpu::render(gpu, frame, ctx),
            accum_hard::ID => accum_hard::wgpu::render(gpu, frame, ctx),
            soft_izb::ID => {
                soft_izb::wgpu::render(gpu, frame, &soft_izb::SoftIzbOptions::parse(&ctx.options)?)
            }
            _ => unreachable!("registered wgpu execution without a dispatch arm: {id}"),
        });
    }
    match id {
        "reference" => Ok(reference::render_until(
            frame,
            ctx.reference_samples,
            ctx.seed,
            ctx.deadline,
        )),
        hard_shadow_map::ID => {
            let o: shadow_map::HardShadowOptions = shadow_map::parse_options(id, &ctx.options)?;
            Ok(hard_shadow_map::cpu::render(backend, frame, ctx, o.bias))
        }
        pcss::ID => Ok(pcss::cpu::render(
            backend,
            frame,
            ctx,
            pcss::options(&ctx.options)?,
        )),
        soft_izb::ID => {
            let opts = soft_izb::SoftIzbOptions::parse(&ctx.options)?;
            soft_izb::cpu::render(backend, frame, ctx, &opts)
        }
        accum_hard::ID => accum_hard::cpu::render(backend, frame, ctx),
        soft_shadow_volume::ID => soft_shadow_volume::cpu::render(backend, frame, ctx),
        penumbra_map::ID => Ok(penumbra_map::cpu::render(
            backend,
            frame,
            ctx,
            penumbra_map::options(&ctx.options)?,
        )),
        soft_shadow_map::ID => {
            let o = soft_shadow_map::SoftShadowMapOptions::parse(&ctx.options)?;
            Ok(soft_shadow_map::cpu::render(backend, frame, ctx, &o))
        }
        dbuffer::ID => Ok(dbuffer::cpu::render(
            backend,
            frame,
            ctx,
            dbuffer::options(&ctx.options)?,
        )),
        _ => unreachable!("registered algorithm without a dispatch arm: {id}"),
    }
}
