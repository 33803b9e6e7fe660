//! `soft_shadow_volume` on wgpu, in one of two pipelines (option `gpu_pipeline`, recorded as
//! `execution.gpu_pipeline`): `"raster"` (default), the thesis' render pipeline
//! ([`super::raster`]), or `"gather"`, this module's compute passes. Both share the loops and
//! sub-lights set up here, the wedges ([`WedgeRecords`]), and in `wgpu.wgsl` the soft pass's
//! parameters ([`SoftParams`]), bindings ([`SoftGroup`]) and counters ([`SoftStat`]), the per-pixel
//! coverage (`wedge_sample`) and the combination of loops and sub-lights (`combine`).
//!
//! The gather: the two passes of III §3.2 as compute passes over the eye pixels (the family's
//! hard pass, then `gather.wgsl`), per silhouette loop and sub-light as on the cpu executions.
//!
//! - `hard` (III §3.2.1): the family's hard pass ([`crate::algorithms::shadow_volume::wgpu`]:
//!   shadow quads from the silhouette seen from the light centre, or the capped volumes' faces
//!   for z-fail, binned on the host and counted per pixel).
//! - `wedges` (III §3.1, IV §4.1): on the host, with the cpu executions' code
//!   (`wedges::build_wedge`, `wedges::wedge_primitives`: wedge halves when culling),
//!   binned and uploaded; host wall time only. Binning drops a (primitive, tile) pair when one
//!   of the primitive's planes has the eye outside and a cone around the tile's eye rays
//!   leaving it (`tile_misses`, a rasterizer's coarse test): no pixel of the tile could pass
//!   the per-pixel test, so images and fragment counts are unchanged.
//! - `soft` (III §3.2.2, IV §4.2-4.4): one invocation per pixel walks its tile's wedge
//!   primitives in submission order, intersects its eye ray with each, and for the points inside
//!   projects the edge onto the light and adds or subtracts the coverage by exact clipping or
//!   the 4D texture, in the f32 or the split 12-bit V-buffer; then the loop's V-buffer, the
//!   overlap approximation across loops (IV §5.1) and the sub-light average (IV §5.2).
//!
//! Accumulation: we chose a per-pixel gather over binned primitives rather than fixed-point
//! atomics or additive blending: each pixel's sum is formed by one invocation in the cpu
//! executions' order, so it is deterministic, needs no atomics, keeps the f32 V-buffer in f32
//! (the split 12-bit format is emulated per channel with saturating 8-bit adds), and mirrors
//! the cpu math operation by operation. The price is that a pixel tests every primitive binned
//! to its tile against its footprint.
//!
//! A pixel "rasterizes" a primitive when its eye ray meets it, exactly as on the cpu
//! executions; the wedge-half culling of IV §4.4 is done by the extra plane of the half, and the
//! stencil traffic it would cost is counted as the cpu-model counts it. Not built on the GPU:
//! silhouette detection and wedge construction (host, as on the cpu executions), the z-fail
//! caps (host; z-fail is counted on the GPU).
//!
//! Textured lights (III §3.3): the RGB coverage texture is uploaded (three bytes a texel) and
//! the soft pass accumulates one f32 per channel (III §4.1), writing the light received per
//! channel and its luminance fraction as the visibility.

use std::time::Instant;

use glam::Vec3;
use serde_json::json;

use super::wedges::{build_wedge, coverage_texture, wedge_primitives, wedge_reach, WedgePrimitive};
use super::Phase;
use super::{
    split_light, CoverageMethod, CoverageTexture, EmitterShape, GpuPipeline,
    SoftShadowVolumeOptions, SubLightLoops, VBufferPrecision, Wedge, ID,
};
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::algorithms::eye_raster::{EyeRays, ScreenRect, DEPTH_BYTES};
use crate::algorithms::shadow_volume::wgpu::{
    bins, check_limits, hard_fill, rect, tile_cones, tile_misses, upload_rays, HardPass, HardStat,
    HardUpload, FACE_BYTES, QUAD_BYTES, RAY_BYTES, RECORDS_WGSL, TILE, WORD,
};
use crate::algorithms::shadow_volume::{Counting, ShadowQuad};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, replay, Bind, Compute, Layout, Pass, Program, Slots, Statistics, Step, Timed,
};
use crate::gpu::{record_execution, Run};
use crate::record::Counters;
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};
use crate::scene::{Light, LightTexture};

/// The soft pass: its bindings and counters, `wedge_sample` and `combine`, shared with the
/// raster pipeline; joined after the family's records.
pub(super) const WGSL: &str = include_str!("wgpu.wgsl");
/// The gather's `soft` entry and its bindings (group 1), joined after [`WGSL`].
const GATHER_WGSL: &str = include_str!("gather.wgsl");

/// Storage buffers the gather's soft pass binds in one stage (the most of any pass of this
/// algorithm): those of [`SoftGroup`] and the wedge bins and hard counts of its group 1.
const STORAGE_BUFFERS: u32 = SOFT_STORAGE_BUFFERS + 2;
/// Storage buffers of [`SoftGroup`] (bindings 1-9).
const SOFT_STORAGE_BUFFERS: u32 = 9;
/// Record sizes: a wedge primitive, a plane.
const PRIM_BYTES: u64 = 32;
const PLANE_BYTES: u64 = 16;
/// Bytes per pixel of the V-buffer (f32, or one rgba8 buffer of the split pair) and of the
/// stencil the wedge-half culling of IV §4.4 uses on a rasterizer.
pub(super) const VBUFFER_BYTES: u64 = 4;
pub(super) const STENCIL_BYTES: u64 = 1;

/// The soft pass's statistics slots (`STAT_SOFT_*` in the WGSL), in slot order.
#[derive(Clone, Copy)]
pub(super) enum SoftStat {
    Fill,
    Front,
    Inside,
    Covered,
    Contributing,
    Tests,
}

const STATS: u64 = 6;

gpu_struct! {
    /// The parameters of one loop's soft pass (binding 0 of [`SoftGroup`]).
    pub(super) struct SoftParams as "SoftParams" {
        /// Light centre; w: emitter shape (0 square, 1 disc).
        center: [f32; 4] => "vec4f",
        /// Half-axes for rect and disc lights (constant); w: light kind (0 rect, 1 sphere,
        /// 2 disc).
        half_u: [f32; 4] => "vec4f",
        /// w: sphere radius.
        half_v: [f32; 4] => "vec4f",
        /// The eye position.
        eye: [f32; 4] => "vec4f",
        width: u32 => "u32",
        height: u32 => "u32",
        tiles_x: u32 => "u32",
        /// 0: f32 V-buffer, 1: split 12-bit rgba8 pair (IV §4.3).
        vbuffer: u32 => "u32",
        /// 0: exact clipping, 1: 4D texture.
        coverage: u32 => "u32",
        texture_n: u32 => "u32",
        /// 1 when this is the first silhouette loop of its sub-light.
        first_loop: u32 => "u32",
        /// 1 when this is the last loop of its sub-light; then the sub-light's visibility is
        /// added.
        last_loop: u32 => "u32",
        /// 1 for the first sub-light, 1 for the last (then the final clamp runs).
        first_light: u32 => "u32",
        last_light: u32 => "u32",
        sub_lights: u32 => "u32",
        /// 3 for a textured light (RGB coverage texture, one f32 per channel), else 1.
        channels: u32 => "u32",
        /// The textured light's mean colour (`LightTexture::mean`).
        mean: [f32; 4] => "vec4f",
    }
}

/// The soft pass's group 0 (`wgpu.wgsl`), bound by the gather's soft pass and the raster
/// pipeline's wedge and resolve passes, and the per-pixel buffers it holds: the eye rays, the
/// coverage texture, the loops' covered fraction, the visibility, the statistics ([`SoftStat`]) and
/// the light received per channel.
pub(super) struct SoftGroup<'g> {
    gpu: &'g Run,
    pub layout: Layout,
    pub rays: wgpu::Buffer,
    texels: wgpu::Buffer,
    covered: wgpu::Buffer,
    pub visibility: wgpu::Buffer,
    pub stats: wgpu::Buffer,
    /// Light received per channel (3 words a pixel) under a textured light, else one word.
    pub rgb: wgpu::Buffer,
    /// 3 for a textured light, else 1.
    pub channels: u32,
}

impl<'g> SoftGroup<'g> {
    /// The buffers of `rays`, with a coverage texture's `texels` (none: empty) and, when
    /// `textured`, an RGB buffer of three words a pixel.
    pub fn new(gpu: &'g Run, rays: &EyeRays, texels: &[u8], textured: bool) -> SoftGroup<'g> {
        // Binding 0 the parameters, 1-5 what the passes read, 6-9 what they write.
        let binds: Vec<Bind> = (0..=SOFT_STORAGE_BUFFERS)
            .map(|b| match b {
                0 => Bind::Uniform,
                1..=5 => Bind::ReadOnly,
                _ => Bind::ReadWrite,
            })
            .collect();
        let stages = wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT;
        // The texels four to a little-endian word, as the WGSL reads them.
        let mut packed = texels.to_vec();
        packed.resize(texels.len().div_ceil(4) * 4, 0);
        let pixels = rays.len() as u64;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let storage = wgpu::BufferUsages::STORAGE;
        SoftGroup {
            gpu,
            layout: Layout::new(gpu, "soft pass", stages, &binds),
            rays: upload_rays(gpu, rays),
            texels: gpu.upload("coverage texture", &packed, storage),
            covered: gpu.storage_buffer("covered", WORD * pixels, copy),
            visibility: gpu.storage_buffer("visibility", WORD * pixels, copy),
            stats: gpu.storage_buffer("soft statistics", 2 * WORD * STATS, copy),
            rgb: gpu.storage_buffer("rgb", if textured { 3 * WORD * pixels } else { WORD }, copy),
            channels: if textured { 3 } else { 1 },
        }
    }

    /// The group of one loop's soft pass: its `params`, the loop's shadow `quads` (uploaded) and
    /// its wedge primitives and planes `w` (uploaded here).
    pub fn group(
        &self,
        params: &SoftParams,
        quads: &wgpu::Buffer,
        w: &WedgeRecords,
    ) -> wgpu::BindGroup {
        let (gpu, storage) = (self.gpu, wgpu::BufferUsages::STORAGE);
        let params = gpu.uniform("soft params", params);
        let prims = gpu.upload("wedge primitives", &w.records, storage);
        let planes = gpu.upload("wedge planes", &w.planes, storage);
        let buffers = [
            &params,
            &self.rays,
            quads,
            &prims,
            &planes,
            &self.texels,
            &self.covered,
            &self.visibility,
            &self.stats,
            &self.rgb,
        ];
        let resources: Vec<_> = buffers.iter().map(|b| b.as_entire_binding()).collect();
        self.layout.group(gpu, "soft", &resources)
    }
}

/// `soft_shadow_volume` on wgpu.
pub fn render(
    gpu: &Run,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &SoftShadowVolumeOptions,
) -> Result<FrameOutput> {
    let sub_lights = split_light(&frame.scene.light, opts.light_split)?;
    check_limits(gpu, frame, ID, STORAGE_BUFFERS)?;
    let start = Instant::now();
    let rays = EyeRays::new(frame);
    let light_texture = frame.scene.light_texture.as_deref();
    let shape = EmitterShape::of(&frame.scene.light);
    let texture = (opts.coverage == CoverageMethod::Texture)
        .then(|| coverage_texture(shape, opts.texture_n, light_texture, ctx.deadline));
    let mean = light_texture.map(LightTexture::mean);
    let texels = texture.as_ref().map_or(&[][..], |t| &t.texels[..]);
    let soft = SoftGroup::new(gpu, &rays, texels, mean.is_some());
    let occluders = frame.scene.occluders();
    let adjacency = EdgeAdjacency::build(&occluders);
    // Without the pipelines' creation: the run's GPU setup, reported apart.
    let setup_ms = start.elapsed().as_secs_f64() * 1e3 - gpu.cache.run_objects_ms();

    let mut runs = Vec::new();
    let mut warnings = Vec::new();
    for (s, sub) in sub_lights.iter().enumerate() {
        let sl = SubLightLoops::new(&adjacency, &occluders, sub.center(), rays.eye, opts);
        warnings.extend(sl.warning);
        // No loop at all (overlap approximation, empty silhouette): the sub-light is unshadowed,
        // as on the cpu executions; one empty loop counted from 0 writes exactly that.
        let (no_loop, mut loops) = (sl.loops.is_empty(), sl.loops);
        if no_loop {
            loops.push(Vec::new());
        }
        let (center, half_u, half_v) = frame_light(sub, EmitterShape::of(sub));
        let n = loops.len();
        for (k, edges) in loops.into_iter().enumerate() {
            let params = SoftParams {
                center,
                half_u,
                half_v,
                eye: rays.eye.extend(0.0).to_array(),
                width: rays.width,
                height: rays.height,
                tiles_x: rays.width.div_ceil(TILE),
                vbuffer: u32::from(opts.vbuffer == VBufferPrecision::Split12),
                coverage: u32::from(texture.is_some()),
                texture_n: opts.texture_n,
                first_loop: u32::from(k == 0),
                last_loop: u32::from(k + 1 == n),
                first_light: u32::from(s == 0),
                last_light: u32::from(s + 1 == sub_lights.len()),
                sub_lights: sub_lights.len() as u32,
                channels: if mean.is_some() { 3 } else { 1 },
                mean: mean.map_or([1.0; 4], |m| [m[0], m[1], m[2], 1.0]),
            };
            let silhouette_edges = (k == 0).then_some(sl.silhouette_edges);
            runs.push(LoopRun {
                light: *sub,
                edges,
                silhouette_edges,
                eye_count: if n > 1 || no_loop { 0 } else { sl.eye },
                params,
            });
        }
    }
    let (mut out, accumulation) = match opts.gpu_pipeline {
        GpuPipeline::Raster => (
            super::raster::run(gpu, frame, &rays, opts, soft, &runs, setup_ms)?,
            "additive blending of the wedges' fragments in rasterization order",
        ),
        GpuPipeline::Gather => (
            {
                let gather = Gather::new(gpu, &rays, opts.counting, soft, occluders);
                run_loops(&gather, gpu, (&rays, &gather.soft, opts), &runs, setup_ms)?
            },
            "per-pixel gather over 8x8-tile bins in submission order, no atomics",
        ),
    };
    if let (Some(rgb), Some(mean)) = (&mut out.rgb, mean) {
        // Pixels without a surface receive the whole light, as their visibility is 1.
        for (i, c) in rgb.data.iter_mut().enumerate() {
            if !rays.is_hit(i) {
                *c = mean;
            }
        }
    }
    out.warnings.extend(warnings);
    let e = &mut out.execution;
    let pipeline = opts.gpu_pipeline;
    record_execution(
        e,
        json!({ "options": opts, "accumulation": accumulation, "gpu_pipeline": pipeline }),
    );
    if let Some(t) = &texture {
        record_execution(e, json!({ "coverage_texture_bytes": t.bytes() }));
    }
    Ok(out)
}

/// The light's centre (w: emitter shape, 0 square, 1 disc) and constant half-axes (w: light
/// kind 0 rect, 1 sphere, 2 disc; sphere radius in the second's w); a sphere's frame depends on
/// the point and is built in the WGSL.
fn frame_light(light: &Light, shape: EmitterShape) -> ([f32; 4], [f32; 4], [f32; 4]) {
    let (c, u, v) = light.emitter_frame(light.center() + Vec3::Y);
    let shape = match shape {
        EmitterShape::Square => 0.0,
        EmitterShape::Disc => 1.0,
    };
    let (kind, radius) = match *light {
        Light::Rect { .. } => (0.0, 0.0),
        Light::Sphere { radius, .. } => (1.0, radius),
        Light::Disc { .. } => (2.0, 0.0),
    };
    (
        c.extend(shape).to_array(),
        u.extend(kind).to_array(),
        v.extend(radius).to_array(),
    )
}

/// One silhouette loop of one sub-light.
pub(super) struct LoopRun {
    pub light: Light,
    pub edges: Vec<SilhouetteEdge>,
    /// The sub-light's silhouette size, on its first loop.
    pub silhouette_edges: Option<usize>,
    /// The count the loop's z-pass hard count starts from ([`super::SubLightLoops`]).
    pub eye_count: i32,
    pub params: SoftParams,
}

/// The wedges of a loop (III §3.1, IV §4.1, with the cpu executions' code) and their
/// primitives (wedge halves when culling, IV §4.4) as the WGSL reads them (`Prim`: footprint;
/// edge, first plane, plane count, half) with their planes.
pub(super) struct WedgeRecords {
    pub prims: Vec<WedgePrimitive>,
    pub footprints: Vec<Option<ScreenRect>>,
    pub records: Vec<[u32; 8]>,
    pub planes: Vec<[f32; 4]>,
    /// The wedges built, and the edges whose wedge is degenerate.
    pub wedges: u64,
    pub degenerate: u64,
}

impl WedgeRecords {
    pub fn new(
        rays: &EyeRays,
        run: &LoopRun,
        quads: &[ShadowQuad],
        opts: &SoftShadowVolumeOptions,
    ) -> WedgeRecords {
        let reach = wedge_reach(rays);
        let wedges: Vec<Option<Wedge>> = run
            .edges
            .iter()
            .map(|e| build_wedge(e, &run.light, opts.tighter_wedges, reach))
            .collect();
        let (prims, footprints) = wedge_primitives(rays, quads, &wedges, opts.wedge_culling);
        let mut planes: Vec<[f32; 4]> = Vec::new();
        let records = prims
            .iter()
            .zip(&footprints)
            .map(|(p, f)| {
                let first = planes.len() as u32;
                planes.extend(p.volume.planes.iter().map(|(n, d)| n.extend(*d).to_array()));
                let [x0, y0, x1, y1] = rect(f);
                let (edge, n) = (p.edge as u32, p.volume.planes.len() as u32);
                let half = p.half.unwrap_or(0.0).to_bits();
                [x0, y0, x1, y1, edge, first, n, half]
            })
            .collect();
        let degenerate = wedges.iter().filter(|w| w.is_none()).count() as u64;
        WedgeRecords {
            wedges: wedges.len() as u64 - degenerate,
            degenerate,
            prims,
            footprints,
            records,
            planes,
        }
    }
}

/// One of the two pipelines as [`run_loops`] runs it, loop by loop: the hard phase's host part
/// and passes, the upload of the wedges and the soft phase's passes, and a loop's replay.
pub(super) trait Pipeline {
    /// What a loop's hard and soft phases made, kept for the replay.
    type Hard;
    type Soft;
    /// The pipeline statistics its phases take.
    const STATISTICS: Statistics;
    /// How its counters were obtained (`execution.gpu_counters`).
    const NOTE: &'static str;
    /// The hard phase's host part for the loop `lr` of `quads`.
    fn hard(&self, rays: &EyeRays, lr: &LoopRun, quads: &[ShadowQuad]) -> Self::Hard;
    /// The hard phase's passes; `first` on the frame's first loop.
    fn hard_passes<'a>(&'a self, hard: &'a Self::Hard, first: bool) -> Vec<Pass<'a>>;
    /// The wedges phase's upload of the wedges `w` of loop `lr` of `quads`.
    fn soft(
        &self,
        rays: &EyeRays,
        lr: &LoopRun,
        quads: &[ShadowQuad],
        w: &WedgeRecords,
        hard: &Self::Hard,
    ) -> Self::Soft;
    fn soft_passes<'a>(&'a self, soft: &'a Self::Soft) -> Vec<Pass<'a>>;
    /// The loop's instrumented replay: `hard`'s counters (fill, overdraw, z-fail caps
    /// ([`hard_fill`]) and this pipeline's own) added to `k`.
    fn replay<'a>(
        &'a self,
        hard: &'a Self::Hard,
        soft: &'a Self::Soft,
        k: &mut Counters,
    ) -> Result<Replayed<'a>>;
}

/// What a loop's instrumented replay gave for the soft phase: what finds the wedge primitives
/// ([`soft_counters`]: name, bytes) and the soft pass's statistics.
pub(super) struct Replayed<'a> {
    pub index: (&'static str, f64),
    pub stat: Box<dyn Fn(SoftStat) -> f64 + 'a>,
}

/// Runs pipeline `p` over `runs` (the loops of every sub-light) on the soft pass's buffers `res`:
/// per loop the hard phase (III §3.2.1), the wedges (III §3.1, IV §4.1, on the host) and the
/// soft phase (III §3.2.2) timed, then every loop's instrumented replay; `setup_ms` of host
/// work counts into phase `hard`.
pub(super) fn run_loops<P: Pipeline>(
    p: &P,
    gpu: &Run,
    (rays, res, opts): (&EyeRays, &SoftGroup, &SoftShadowVolumeOptions),
    runs: &[LoopRun],
    setup_ms: f64,
) -> Result<FrameOutput> {
    let readback = &[&res.visibility, &res.rgb][..1 + usize::from(res.channels == 3)];
    let mut run = Timed::new(gpu, Phase::ALL, P::STATISTICS, readback);
    run.add_wall(Phase::Hard, setup_ms);
    let mut loops = Vec::with_capacity(runs.len());
    for (k, lr) in runs.iter().enumerate() {
        let centre = lr.light.center();
        let (quads, hard) = run.host(Phase::Hard, || {
            let quads: Vec<_> = lr
                .edges
                .iter()
                .map(|e| ShadowQuad::new(e, centre))
                .collect();
            let hard = p.hard(rays, lr, &quads);
            (quads, hard)
        });
        run.submit_timed(Phase::Hard, &p.hard_passes(&hard, k == 0))?;
        let (w, soft) = run.host(Phase::Wedges, || {
            let w = WedgeRecords::new(rays, lr, &quads, opts);
            let soft = p.soft(rays, lr, &quads, &w, &hard);
            (w, soft)
        });
        run.submit_timed(Phase::Soft, &p.soft_passes(&soft))?;
        loops.push((quads.len(), w, hard, soft));
    }
    let timing = run.finish()?;
    let size = (rays.width, rays.height);
    let rgb = timing.rgb(1, size);
    let [mut hard_c, mut wedges_c, mut soft_c] = [(); 3].map(|_| Counters::default());
    for (lr, (quads, w, hard, soft)) in runs.iter().zip(&loops) {
        let r = p.replay(hard, soft, &mut hard_c)?;
        if let Some(n) = lr.silhouette_edges {
            hard_c.add(names::SILHOUETTE_EDGES, n as f64);
        }
        hard_c.add(names::SHADOW_QUADS, *quads as f64);
        wedges_c.add(names::WEDGES, w.wedges as f64);
        wedges_c.add(names::WEDGES_DEGENERATE, w.degenerate as f64);
        let pixels = rays.len() as u64;
        soft_counters(&mut soft_c, (opts, res.channels, pixels), w, &r);
    }
    let per_phase = vec![
        (Phase::Hard, hard_c),
        (Phase::Wedges, wedges_c),
        (Phase::Soft, soft_c),
    ];
    let mut out = timing.output(size, per_phase, P::NOTE);
    out.rgb = rgb;
    Ok(out)
}

/// The gather: the family's hard pass, then this algorithm's soft pass over the wedge
/// primitives binned to each tile.
struct Gather<'g> {
    hard: HardPass<'g>,
    soft: SoftGroup<'g>,
    /// The soft pass's group 1: the wedge bins and the hard counts.
    gather_layout: Layout,
    /// The soft pass (`INSTRUMENT` counting in the replay).
    pipeline: Compute,
    cones: Vec<(Vec3, f32)>,
}

impl<'g> Gather<'g> {
    /// The gather over `rays` with the soft pass's buffers `soft`, counting as `counting` with
    /// the z-fail volumes capped by `occluders`.
    fn new(
        gpu: &'g Run,
        rays: &EyeRays,
        counting: Counting,
        soft: SoftGroup<'g>,
        occluders: crate::scene::Mesh,
    ) -> Gather<'g> {
        let hard = HardPass::new(gpu, rays, &soft.rays, counting, occluders);
        let read = [Bind::ReadOnly, Bind::ReadOnly];
        let gather_layout = Layout::new(gpu, "gather", wgpu::ShaderStages::COMPUTE, &read);
        let groups = [Some(&soft.layout), Some(&gather_layout)];
        let program = Program::new(
            gpu,
            "soft_shadow_volume/gather.wgsl",
            &GATHER_SOURCES,
            &groups,
        );
        Gather {
            pipeline: program.instrumented(gpu, "soft"),
            hard,
            soft,
            gather_layout,
            cones: tile_cones(rays),
        }
    }

    /// The bytes of bins of `entries` and their per-tile ranges.
    fn bin_bytes(&self, entries: u64) -> f64 {
        let tiles = u64::from(self.hard.groups.0) * u64::from(self.hard.groups.1);
        (WORD * (entries + 2 * tiles)) as f64
    }

    /// The soft pass of a loop.
    fn soft_pass<'a>(&'a self, soft: &'a <Self as Pipeline>::Soft) -> Pass<'a> {
        let groups = [Some(&soft.0), Some(&soft.1)];
        Pass::compute("soft", &groups, &self.pipeline, self.hard.groups)
    }
}

/// The gather's soft pass as its pipeline joins it.
const GATHER_SOURCES: [&str; 5] = [
    SoftParams::WGSL,
    RECORDS_WGSL,
    WGSL,
    GATHER_WGSL,
    crate::scene::coverage::WGSL,
];

impl Pipeline for Gather<'_> {
    type Hard = HardUpload;
    /// The soft pass's groups 0 and 1 and the entries of the wedge bins.
    type Soft = (wgpu::BindGroup, wgpu::BindGroup, u64);
    const STATISTICS: Statistics = Statistics::Compute;
    const NOTE: &'static str = "fill, overdraw, shader invocations and culls from an \
        instrumented replay (WGSL atomics), in the cpu-model's terms; mem_est.* estimated from \
        counts and record sizes";

    fn hard(&self, rays: &EyeRays, lr: &LoopRun, quads: &[ShadowQuad]) -> HardUpload {
        (self.hard).upload_quads(rays, lr.eye_count, lr.light.center(), quads)
    }

    fn hard_passes<'a>(&'a self, hard: &'a HardUpload, _first: bool) -> Vec<Pass<'a>> {
        vec![self.hard.pass(hard)]
    }

    /// Primitives, bins, upload, the soft pass's group.
    fn soft(
        &self,
        rays: &EyeRays,
        lr: &LoopRun,
        _: &[ShadowQuad],
        w: &WedgeRecords,
        h: &HardUpload,
    ) -> Self::Soft {
        let gpu = self.hard.gpu;
        let (wedge_bins, bin_entries) = bins(rays, &w.footprints, |k, t| {
            !tile_misses(&w.prims[k].volume, rays.eye, self.cones[t])
        });
        let bins_buf = gpu.upload("wedge bins", &wedge_bins, wgpu::BufferUsages::STORAGE);
        let read = [&bins_buf, &self.hard.counts].map(|b| b.as_entire_binding());
        let group1 = self.gather_layout.group(gpu, "gather", &read);
        (
            self.soft.group(&lr.params, &h.quads, w),
            group1,
            bin_entries,
        )
    }

    fn soft_passes<'a>(&'a self, soft: &'a Self::Soft) -> Vec<Pass<'a>> {
        vec![self.soft_pass(soft)]
    }

    /// `hard`'s own counters: the quad tests and the estimated traffic: rays of every pixel,
    /// quad records per test, the bins, a depth read per fragment, the count written.
    fn replay<'a>(
        &'a self,
        h: &'a HardUpload,
        soft: &'a Self::Soft,
        k: &mut Counters,
    ) -> Result<Replayed<'a>> {
        let (hard, soft_stats) = (&self.hard.stats, &self.soft.stats);
        let steps = [
            Step::Clear(hard),
            Step::Clear(soft_stats),
            Step::Submit(vec![self.hard.pass(h), self.soft_pass(soft)]),
            Step::Read(hard),
            Step::Read(soft_stats),
        ];
        let [hard, soft_slots] = <[Vec<u8>; 2]>::try_from(replay(self.hard.gpu, &steps)?)
            .expect("two reads")
            .map(|b| Slots::of(&b));
        let hard = |s: HardStat| hard.get(s as usize);
        let [fill, passed, tests] = [HardStat::Fill, HardStat::Passed, HardStat::Tests].map(hard);
        k.add(names::QUAD_TESTS, tests);
        let record = match self.hard.counting {
            Counting::ZFail => FACE_BYTES,
            Counting::ZPass => QUAD_BYTES,
        };
        let pixels = self.hard.pixels;
        let reads = [
            ("eye_rays", (RAY_BYTES * pixels) as f64),
            ("shadow_quads", record as f64 * tests),
            ("quad_bins", self.bin_bytes(h.bin_entries)),
            ("depth", fill * DEPTH_BYTES as f64),
        ];
        let vbuffer = (VBUFFER_BYTES * pixels) as f64;
        k.add_traffic("mem_est", &reads, &[("vbuffer", vbuffer)]);
        hard_fill(k, self.hard.counting, fill, passed, h.caps);
        let index = ("wedge_bins", self.bin_bytes(soft.2));
        let stat = Box::new(move |s: SoftStat| soft_slots.get(s as usize));
        Ok(Replayed { index, stat })
    }
}

/// `soft`: fill, overdraw, shader invocations, culled fragments and fragments inside wedges
/// in the cpu-model's terms (with culling each half is rasterized twice, IV §4.4), and
/// estimated traffic: rays, primitive records and planes per test (`wedge_tests`: the
/// gather's pixel–primitive tests, the raster pass's rasterized fragments), what finds the
/// primitives (`index`: the gather's bins, the raster pass's vertices), depth and stencil as a
/// rasterizer touches them, the V-buffer per fragment inside, texture reads; for `opts`, light
/// `channels` and `pixels` eye pixels.
fn soft_counters(
    k: &mut Counters,
    (opts, channels, pixels): (&SoftShadowVolumeOptions, u32, u64),
    w: &WedgeRecords,
    r: &Replayed,
) {
    use SoftStat::*;
    let [fill, front, inside, covered, contributing, tests] =
        [Fill, Front, Inside, Covered, Contributing, Tests].map(&r.stat);
    let (raster_fill, shaded, culled, stencil_read, stencil_write) = if opts.wedge_culling {
        (2.0 * fill, inside, fill - inside, fill, 2.0 * front)
    } else {
        (fill, front, 0.0, 0.0, 0.0)
    };
    k.add_fill(raster_fill, raster_fill - contributing);
    k.add(names::SHADER_INVOCATIONS, shaded);
    k.add(names::CULLED_FRAGMENTS, culled);
    k.add(names::FRAGMENTS_INSIDE_WEDGES, covered);
    k.add(names::WEDGE_TESTS, tests);
    k.add(names::WEDGE_PRIMITIVES, w.prims.len() as f64);
    let texture_reads = if opts.coverage == CoverageMethod::Texture {
        CoverageTexture::READS as f64 * covered
    } else {
        0.0
    };
    k.add(names::COVERAGE_TEXTURE_READS, texture_reads);
    // Bytes: one per channel of each texel read.
    let texture_reads = texture_reads * f64::from(channels);
    // Planes per primitive (none without primitives).
    let per_plane = w.planes.len() as f64 / (w.prims.len() as f64).max(1.0);
    let rays = (RAY_BYTES * pixels) as f64;
    let prims = tests * (PRIM_BYTES as f64 + per_plane * PLANE_BYTES as f64);
    let quads = QUAD_BYTES as f64 * inside;
    let depth = raster_fill * DEPTH_BYTES as f64;
    let stencil_r = stencil_read * STENCIL_BYTES as f64;
    let stencil_w = stencil_write * STENCIL_BYTES as f64;
    // As the cpu-model: an f32 per channel, or the split format's rgba8 texel.
    let vbytes = match opts.vbuffer {
        VBufferPrecision::F32 => VBUFFER_BYTES * u64::from(channels),
        VBufferPrecision::Split12 => VBUFFER_BYTES,
    };
    let vbuffer = vbytes as f64 * covered;
    let counts = (WORD * pixels) as f64;
    let out = (2 * WORD * pixels) as f64;
    let reads = [
        ("eye_rays", rays),
        ("wedge_primitives", prims),
        r.index,
        ("shadow_quads", quads),
        ("depth", depth),
        ("stencil", stencil_r),
        ("vbuffer", vbuffer + counts),
        ("coverage_texture", texture_reads),
    ];
    let writes = [
        ("stencil", stencil_w),
        ("vbuffer", vbuffer),
        ("visibility", out),
    ];
    k.add_traffic("mem_est", &reads, &writes);
}

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(GATHER_SOURCES => SoftParams);
