//! `soft_shadow_volume` on wgpu, in one of two pipelines (option `gpu_pipeline`, recorded as
//! `execution.gpu_pipeline`): `"raster"` (default), the thesis' render pipeline
//! ([`super::raster`]), or `"gather"`, this module's compute passes. Both share the loops and
//! sub-lights set up here, the wedges ([`WedgeRecords`]), and in `wgpu.wgsl` the per-pixel
//! coverage (`wedge_sample`) and the combination of loops and sub-lights (`combine`).
//!
//! The gather: the two passes of III §3.2 as compute passes over the eye pixels
//! (`wgpu.wgsl`), per silhouette loop and sub-light as on the cpu executions.
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
use super::{
    split_light, CoverageMethod, CoverageTexture, EmitterShape, GpuPipeline,
    SoftShadowVolumeOptions, SubLightLoops, VBufferPrecision, Wedge, ID,
};
use crate::algorithms::eye_raster::{EyeRays, ScreenRect, DEPTH_BYTES};
use crate::algorithms::shadow_volume::wgpu::{
    bins, check_limits, hard_fill, rect, tile_cones, tile_misses, FrameResources, HardUpload,
    Params, Stat, VolumePasses, FACE_BYTES, PLANE_BYTES, PRIM_BYTES, QUAD_BYTES, RAY_BYTES,
    STENCIL_BYTES, VBUFFER_BYTES, WORD,
};
use crate::algorithms::shadow_volume::{Counting, ShadowQuad};
use crate::algorithms::{ExecContext, FrameOutput};
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{Compute, Pass, Statistics, Timed};
use crate::gpu::{record_execution, Run};
use crate::record::Counters;
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};
use crate::scene::{Light, LightTexture};

/// The soft pass: `wedge_sample` and `combine`, shared with the raster pipeline, and the
/// gather's `soft` entry.
pub(super) const WGSL: &str = include_str!("wgpu.wgsl");

/// `soft_shadow_volume` on wgpu.
pub fn render(
    gpu: &Run,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &SoftShadowVolumeOptions,
) -> Result<FrameOutput> {
    let sub_lights = split_light(&frame.scene.light, opts.light_split)?;
    check_limits(gpu, frame, ID)?;
    let start = Instant::now();
    let rays = EyeRays::new(frame);
    let light_texture = frame.scene.light_texture.as_deref();
    let shape = EmitterShape::of(&frame.scene.light);
    let texture = (opts.coverage == CoverageMethod::Texture)
        .then(|| coverage_texture(shape, opts.texture_n, light_texture, ctx.deadline));
    let mean = light_texture.map(LightTexture::mean);
    let texels = texture.as_ref().map_or(&[][..], |t| &t.texels[..]);
    let frame_res = FrameResources::new(gpu, &rays, texels, mean.is_some());
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
            let params = Params {
                center,
                half_u,
                half_v,
                eye_count: if n > 1 || no_loop { 0 } else { sl.eye },
                vbuffer: u32::from(opts.vbuffer == VBufferPrecision::Split12),
                coverage: u32::from(texture.is_some()),
                texture_n: opts.texture_n,
                first_loop: u32::from(k == 0),
                last_loop: u32::from(k + 1 == n),
                channels: if mean.is_some() { 3 } else { 1 },
                mean: mean.map_or([1.0; 4], |m| [m[0], m[1], m[2], 1.0]),
                ..Params::of_light(&rays, s, sub_lights.len(), opts.counting)
            };
            let silhouette_edges = (k == 0).then_some(sl.silhouette_edges);
            runs.push(LoopRun {
                light: *sub,
                edges,
                silhouette_edges,
                params,
            });
        }
    }
    let (mut out, accumulation) = match opts.gpu_pipeline {
        GpuPipeline::Raster => (
            super::raster::run(gpu, frame, &rays, opts, frame_res, &runs, setup_ms)?,
            "additive blending of the wedges' fragments in rasterization order",
        ),
        GpuPipeline::Gather => (
            {
                let v = VolumePasses::new(gpu, &rays, opts.counting, frame_res, occluders, WGSL);
                let soft = v.program.instrumented(gpu, "soft");
                let gather = Gather {
                    soft,
                    v,
                    cones: tile_cones(&rays),
                };
                run_loops(&gather, gpu, (&rays, &gather.v.res, opts), &runs, setup_ms)?
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
    pub params: Params,
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
    pub stat: Box<dyn Fn(Stat) -> f64 + 'a>,
}

/// Runs pipeline `p` over `runs` (the loops of every sub-light) on the frame resources `res`:
/// per loop the hard phase (III §3.2.1), the wedges (III §3.1, IV §4.1, on the host) and the
/// soft phase (III §3.2.2) timed, then every loop's instrumented replay; `setup_ms` of host
/// work counts into phase `hard`.
pub(super) fn run_loops<P: Pipeline>(
    p: &P,
    gpu: &Run,
    (rays, res, opts): (&EyeRays, &FrameResources, &SoftShadowVolumeOptions),
    runs: &[LoopRun],
    setup_ms: f64,
) -> Result<FrameOutput> {
    let readback = &[&res.visibility, &res.rgb][..1 + usize::from(res.channels == 3)];
    let names = ["hard", "wedges", "soft"];
    let mut run = Timed::new(gpu, &names, P::STATISTICS, readback);
    run.add_wall(0, setup_ms);
    let mut loops = Vec::with_capacity(runs.len());
    for (k, lr) in runs.iter().enumerate() {
        let centre = lr.light.center();
        let (quads, hard) = run.host(0, || {
            let quads: Vec<_> = lr
                .edges
                .iter()
                .map(|e| ShadowQuad::new(e, centre))
                .collect();
            let hard = p.hard(rays, lr, &quads);
            (quads, hard)
        });
        run.submit_timed(0, &p.hard_passes(&hard, k == 0))?;
        let (w, soft) = run.host(1, || {
            let w = WedgeRecords::new(rays, lr, &quads, opts);
            let soft = p.soft(rays, lr, &quads, &w, &hard);
            (w, soft)
        });
        run.submit_timed(2, &p.soft_passes(&soft))?;
        loops.push((quads.len(), w, hard, soft));
    }
    let timing = run.finish()?;
    let size = (rays.width, rays.height);
    let rgb = timing.rgb(1, size);
    let mut per_phase = vec![Counters::default(); 3];
    for (lr, (quads, w, hard, soft)) in runs.iter().zip(&loops) {
        let r = p.replay(hard, soft, &mut per_phase[0])?;
        let k = &mut per_phase[0];
        if let Some(n) = lr.silhouette_edges {
            k.add("silhouette_edges", n as f64);
        }
        k.add("shadow_quads", *quads as f64);
        per_phase[1].add("wedges", w.wedges as f64);
        per_phase[1].add("wedges_degenerate", w.degenerate as f64);
        let pixels = rays.len() as u64;
        soft_counters(&mut per_phase[2], (opts, res.channels, pixels), w, &r);
    }
    let mut out = timing.output(size, per_phase, P::NOTE);
    out.rgb = rgb;
    Ok(out)
}

/// The gather: the family's passes with the soft pass of this algorithm.
struct Gather<'g> {
    v: VolumePasses<'g>,
    /// The soft pass (`INSTRUMENT` counting in the replay).
    soft: Compute,
    cones: Vec<(Vec3, f32)>,
}

impl<'g> Gather<'g> {
    /// The bytes of bins of `entries` and their per-tile ranges.
    fn bin_bytes(&self, entries: u64) -> f64 {
        let tiles = u64::from(self.v.groups.0) * u64::from(self.v.groups.1);
        (WORD * (entries + 2 * tiles)) as f64
    }
}

impl Pipeline for Gather<'_> {
    type Hard = HardUpload;
    /// The soft pass's group and the entries of the wedge bins.
    type Soft = (wgpu::BindGroup, u64);
    const STATISTICS: Statistics = Statistics::Compute;
    const NOTE: &'static str = "fill, overdraw, shader invocations and culls from an \
        instrumented replay (WGSL atomics), in the cpu-model's terms; mem_est.* estimated from \
        counts and record sizes";

    fn hard(&self, rays: &EyeRays, lr: &LoopRun, quads: &[ShadowQuad]) -> HardUpload {
        self.v
            .upload_quads(rays, &lr.params, lr.light.center(), quads)
    }

    fn hard_passes<'a>(&'a self, hard: &'a HardUpload, _first: bool) -> Vec<Pass<'a>> {
        vec![self.v.hard(hard)]
    }

    /// Primitives, bins, upload, the soft pass's group.
    fn soft(
        &self,
        rays: &EyeRays,
        _: &LoopRun,
        _: &[ShadowQuad],
        w: &WedgeRecords,
        h: &HardUpload,
    ) -> Self::Soft {
        let gpu = self.v.gpu;
        let storage = wgpu::BufferUsages::STORAGE;
        let (wedge_bins, bin_entries) = bins(rays, &w.footprints, |k, t| {
            !tile_misses(&w.prims[k].volume, rays.eye, self.cones[t])
        });
        let prims_buf = gpu.upload("wedge primitives", &w.records, storage);
        let planes_buf = gpu.upload("wedge planes", &w.planes, storage);
        let bins_buf = gpu.upload("wedge bins", &wedge_bins, storage);
        let [params, quads_buf, quad_bins] = &h.buffers;
        let prims = [quads_buf, &prims_buf, &planes_buf, quad_bins, &bins_buf];
        (self.v.group(params, prims, "soft"), bin_entries)
    }

    fn soft_passes<'a>(&'a self, soft: &'a Self::Soft) -> Vec<Pass<'a>> {
        vec![self.v.pass("soft", &self.soft, &soft.0)]
    }

    /// `hard`'s own counters: the quad tests and the estimated traffic: rays of every pixel,
    /// quad records per test, the bins, a depth read per fragment, the count written.
    fn replay<'a>(
        &'a self,
        h: &'a HardUpload,
        soft: &'a Self::Soft,
        k: &mut Counters,
    ) -> Result<Replayed<'a>> {
        let soft_pass = self.v.pass("soft", &self.soft, &soft.0);
        let stat = self.v.replay(vec![self.v.hard(h), soft_pass])?;
        let [fill, passed, tests] = [Stat::HardFill, Stat::HardPassed, Stat::HardTests].map(&stat);
        k.add("quad_tests", tests);
        let record = match self.v.counting {
            Counting::ZFail => FACE_BYTES,
            Counting::ZPass => QUAD_BYTES,
        };
        let pixels = self.v.pixels;
        let reads = [
            ("eye_rays", (RAY_BYTES * pixels) as f64),
            ("shadow_quads", record as f64 * tests),
            ("quad_bins", self.bin_bytes(h.bin_entries)),
            ("depth", fill * DEPTH_BYTES as f64),
        ];
        let vbuffer = (VBUFFER_BYTES * pixels) as f64;
        k.add_traffic("mem_est", &reads, &[("vbuffer", vbuffer)]);
        hard_fill(k, self.v.counting, fill, passed, h.caps);
        let (index, stat) = (("wedge_bins", self.bin_bytes(soft.1)), Box::new(stat));
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
    use Stat::*;
    let [fill, front, inside, covered, contributing, tests] = [
        SoftFill,
        SoftFront,
        SoftInside,
        SoftCovered,
        SoftContributing,
        SoftTests,
    ]
    .map(&r.stat);
    let (raster_fill, shaded, culled, stencil_read, stencil_write) = if opts.wedge_culling {
        (2.0 * fill, inside, fill - inside, fill, 2.0 * front)
    } else {
        (fill, front, 0.0, 0.0, 0.0)
    };
    k.add_fill(raster_fill, raster_fill - contributing);
    k.add("shader_invocations", shaded);
    k.add("culled_fragments", culled);
    k.add("fragments_inside_wedges", covered);
    k.add("wedge_tests", tests);
    k.add("wedge_primitives", w.prims.len() as f64);
    let texture_reads = if opts.coverage == CoverageMethod::Texture {
        CoverageTexture::READS as f64 * covered
    } else {
        0.0
    };
    k.add("coverage_texture_reads", texture_reads);
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
