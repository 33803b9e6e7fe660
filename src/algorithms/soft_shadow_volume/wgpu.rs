//! `soft_shadow_volume` on wgpu: the two passes of III §3.2 as compute passes over the eye
//! pixels (`wgpu.wgsl`), per silhouette loop and sub-light as on the cpu executions.
//!
//! - `hard` (III §3.2.1): the hard shadow quads, built on the host from the silhouette seen from
//!   the light centre and binned to 8×8 screen tiles on the host (sort-middle, as
//!   [`crate::algorithms::eye_raster::raster_pass`] bins them), then one invocation per pixel
//!   walks its tile's quads in submission order and counts z-pass from the eye's count
//!   ([`crate::algorithms::shadow_volume`]) into an i32 V-buffer; with `counting: "z_fail"`
//!   (Paper II §5) it walks the faces of the capped volumes instead (sides, light and dark caps,
//!   built on the host by [`zfail_faces`]) and counts those at or behind the visible surface.
//! - `wedges` (III §3.1, IV §4.1): on the host, with the cpu executions' code
//!   (`cpu::build_wedge`, `cpu::wedge_primitives`: wedge halves when culling),
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
//! stencil traffic it would cost is counted as the cpu-model counts it. A timed submission
//! (timestamps and pipeline statistics per GPU pass) is followed by an instrumented replay with
//! WGSL atomics counting fragments. Not built on the GPU: silhouette detection and wedge
//! construction (host, as on the cpu executions), the z-fail caps (host; z-fail is counted on
//! the GPU).
//!
//! Textured lights (III §3.3): the RGB coverage texture is uploaded (three bytes a texel) and
//! the soft pass accumulates one f32 per channel (III §4.1), writing the light received per
//! channel and its luminance fraction as the visibility.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::cpu::{build_wedge, coverage_texture, wedge_primitives, wedge_reach};
use super::{
    silhouette_loops, split_light, CoverageMethod, CoverageTexture, EmitterShape,
    SoftShadowVolumeOptions, VBufferPrecision, Wedge, ID,
};
use crate::algorithms::eye_raster::{ConvexVolume, EyeRays, ScreenRect, DEPTH_BYTES};
use crate::algorithms::shadow_volume::{
    eye_count, face_footprints, quad_footprints, zfail_faces, Counting, ShadowQuad, VolumeFace,
};
use crate::algorithms::ExecContext;
use crate::algorithms::FrameOutput;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::layout;
use crate::gpu::readback::{words, Staging};
use crate::gpu::stats::{read_or_warn, PassStats, COMPUTE_INVOCATIONS};
use crate::gpu::timing::{self, read_ms_or_warn, PassTimer};
use crate::gpu::{resolve_queries, Gpu};
use crate::record::{Counters, Phase};
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};
use crate::scene::{Light, LightTexture, Mesh};
use crate::visibility::{RgbBuffer, VisibilityBuffer};

const WGSL: &str = include_str!("wgpu.wgsl");

/// Side of the screen tiles primitives are binned to (`TILE` and the workgroup in the WGSL).
const TILE: u32 = 8;
/// Storage buffers bound (bindings 1-12).
const STORAGE_BUFFERS: u32 = 12;
/// Record sizes: an eye ray, a shadow quad, a wedge primitive, a plane, a word.
const RAY_BYTES: u64 = 48;
const QUAD_BYTES: u64 = 80;
/// A z-fail volume face: six vec4 (corners, normal, footprint) in the `planes` binding.
const FACE_BYTES: u64 = 96;
const PRIM_BYTES: u64 = 32;
const PLANE_BYTES: u64 = 16;
const WORD: u64 = 4;
/// What an empty upload is padded to: a record of any kind the passes read.
const RECORD_BYTES: usize = 128;
/// Bytes per pixel of the V-buffer (f32, or one rgba8 buffer of the split pair) and of the
/// stencil the wedge-half culling of IV §4.4 uses on a rasterizer.
const VBUFFER_BYTES: u64 = 4;
const STENCIL_BYTES: u64 = 1;

/// The statistics slots of the instrumented pipelines (`STAT_*` in the WGSL), in slot order.
#[derive(Clone, Copy)]
enum Stat {
    HardFill,
    HardPassed,
    SoftFill,
    SoftFront,
    SoftInside,
    SoftCovered,
    SoftContributing,
    HardTests,
    SoftTests,
}

const STATS: u64 = 9;

/// The `Params` uniform of the WGSL.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    center: [f32; 4],
    half_u: [f32; 4],
    half_v: [f32; 4],
    eye: [f32; 4],
    width: u32,
    height: u32,
    tiles_x: u32,
    eye_count: i32,
    vbuffer: u32,
    coverage: u32,
    texture_n: u32,
    first_loop: u32,
    last_loop: u32,
    first_light: u32,
    last_light: u32,
    sub_lights: u32,
    /// 0: z-pass, 1: z-fail over the capped volumes.
    counting: u32,
    channels: u32,
    pad: [u32; 2],
    /// Mean colour of a textured light (`channels` = 3).
    mean: [f32; 4],
}

/// `soft_shadow_volume` on wgpu.
pub fn render(
    gpu: &Gpu,
    frame: &Frame,
    _: &ExecContext,
    opts: &SoftShadowVolumeOptions,
) -> Result<FrameOutput> {
    let light = frame.scene.light;
    let sub_lights = split_light(&light, opts.light_split).ok_or_else(|| {
        Error::Unsupported(format!(
            "{ID}: light splitting (light_split = {}) needs a rectangular light, got {}",
            opts.light_split,
            light.kind()
        ))
    })?;
    check_limits(gpu, frame)?;
    let start = Instant::now();
    let rays = EyeRays::new(frame);
    let light_texture = frame.scene.light_texture.as_deref();
    let texture = (opts.coverage == CoverageMethod::Texture)
        .then(|| coverage_texture(EmitterShape::of(&light), opts.texture_n, light_texture));
    let mean = light_texture.map(LightTexture::mean);
    let frame_res = FrameResources::new(gpu, &rays, texture.as_deref(), mean.is_some());
    let adjacency = EdgeAdjacency::build(&frame.scene.occluders());
    let occluders = frame.scene.occluders();
    let setup_ms = start.elapsed().as_secs_f64() * 1e3;
    let passes = Passes::new(gpu, &rays, opts, frame_res, occluders.clone());

    let mut runs = Vec::new();
    let mut warnings = Vec::new();
    for (s, sub) in sub_lights.iter().enumerate() {
        let centre = sub.center();
        let silhouette = adjacency.silhouette_from(centre);
        let mut loops = if opts.overlap_approximation {
            silhouette_loops(&silhouette.edges)
        } else {
            vec![silhouette.edges.clone()]
        };
        // No loop at all (overlap approximation, empty silhouette): the sub-light is unshadowed,
        // as on the cpu executions; one empty loop counted from 0 writes exactly that.
        let no_loop = loops.is_empty();
        if no_loop {
            loops.push(Vec::new());
        }
        let eye = match opts.counting {
            Counting::ZPass => eye_count(&occluders, centre, rays.eye),
            Counting::ZFail => 0,
        };
        if loops.len() > 1 && eye != 0 {
            warnings.push(format!(
                "the eye is inside {eye} shadow volume(s); per-loop V-buffers of the overlap \
                 approximation start at 0"
            ));
        }
        for (k, edges) in loops.iter().enumerate() {
            let (center, half_u, half_v) = frame_light(sub, EmitterShape::of(sub));
            let params = Params {
                center,
                half_u,
                half_v,
                eye: rays.eye.extend(0.0).to_array(),
                width: rays.width,
                height: rays.height,
                tiles_x: rays.width.div_ceil(TILE),
                eye_count: if loops.len() > 1 || no_loop { 0 } else { eye },
                vbuffer: u32::from(opts.vbuffer == VBufferPrecision::Split12),
                coverage: u32::from(texture.is_some()),
                texture_n: opts.texture_n,
                first_loop: u32::from(k == 0),
                last_loop: u32::from(k + 1 == loops.len()),
                first_light: u32::from(s == 0),
                last_light: u32::from(s + 1 == sub_lights.len()),
                sub_lights: sub_lights.len() as u32,
                counting: u32::from(opts.counting == Counting::ZFail),
                channels: if mean.is_some() { 3 } else { 1 },
                pad: [0; 2],
                mean: mean.map_or([1.0; 4], |m| [m[0], m[1], m[2], 1.0]),
            };
            runs.push(LoopRun {
                light: *sub,
                edges: edges.clone(),
                silhouette_edges: (k == 0).then_some(silhouette.edges.len()),
                params,
            });
        }
    }
    let mut out = passes.run(&rays, &runs, setup_ms)?;
    if let (Some(rgb), Some(mean)) = (&mut out.rgb, mean) {
        // Pixels without a surface receive the whole light, as their visibility is 1.
        for (i, c) in rgb.data.iter_mut().enumerate() {
            if !rays.is_hit(i) {
                *c = mean;
            }
        }
    }
    out.warnings.extend(warnings);
    out.execution
        .insert("options".to_string(), serde_json::json!(opts));
    out.execution.insert(
        "accumulation".into(),
        serde_json::json!("per-pixel gather over 8x8-tile bins in submission order, no atomics"),
    );
    if let Some(t) = &texture {
        out.execution.insert(
            "coverage_texture_bytes".into(),
            serde_json::json!(t.bytes()),
        );
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

pub(crate) fn check_limits(gpu: &Gpu, frame: &Frame) -> Result<()> {
    let l = &gpu.limits;
    if l.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS {
        return Err(Error::Resource(format!(
            "{ID} binds {STORAGE_BUFFERS} storage buffers; the adapter allows {}",
            l.max_storage_buffers_per_shader_stage
        )));
    }
    let bytes = RAY_BYTES * frame.gbuffer.len() as u64;
    if bytes > l.max_storage_buffer_binding_size {
        return Err(Error::Resource(format!(
            "{ID} buffer eye_rays needs {bytes} bytes, more than the adapter's storage binding \
             limit ({})",
            l.max_storage_buffer_binding_size
        )));
    }
    Ok(())
}

/// One silhouette loop of one sub-light.
struct LoopRun {
    light: Light,
    edges: Vec<SilhouetteEdge>,
    /// The sub-light's silhouette size, on its first loop.
    silhouette_edges: Option<usize>,
    params: Params,
}

/// Eye-sized buffers shared by every loop.
struct FrameResources {
    rays: wgpu::Buffer,
    texels: wgpu::Buffer,
    counts: wgpu::Buffer,
    covered: wgpu::Buffer,
    visibility: wgpu::Buffer,
    stats: wgpu::Buffer,
    /// Light received per channel (3 words a pixel) under a textured light, else one word.
    rgb: wgpu::Buffer,
    /// 3 for a textured light, else 1.
    channels: u32,
}

/// Infinite and NaN parameters become the largest finite ones (WGSL has no infinities).
fn finite(t: f32) -> f32 {
    if t.is_nan() {
        f32::MAX
    } else {
        t.clamp(-f32::MAX, f32::MAX)
    }
}

impl FrameResources {
    fn new(
        gpu: &Gpu,
        rays: &EyeRays,
        texture: Option<&CoverageTexture>,
        textured: bool,
    ) -> FrameResources {
        let storage = wgpu::BufferUsages::STORAGE;
        let records: Vec<[f32; 12]> = (0..rays.len())
            .map(|i| {
                let (d, p) = (rays.dir[i], rays.point[i]);
                let (t0, t1) = rays.bounds_interval(i);
                [
                    d.x,
                    d.y,
                    d.z,
                    finite(rays.depth[i]),
                    p.x,
                    p.y,
                    p.z,
                    finite(t0),
                    finite(t1),
                    if rays.is_hit(i) { 1.0 } else { 0.0 },
                    0.0,
                    0.0,
                ]
            })
            .collect();
        let texels: Vec<u8> = texture.map(|t| t.texels.clone()).unwrap_or_default();
        let mut packed = vec![0u32; texels.len().div_ceil(4)];
        for (k, &b) in texels.iter().enumerate() {
            packed[k / 4] |= u32::from(b) << (8 * (k % 4));
        }
        let pixels = rays.len() as u64;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        FrameResources {
            rays: gpu.buffer_init(
                "eye rays",
                bytemuck::cast_slice(&records),
                RECORD_BYTES,
                storage,
            ),
            texels: gpu.buffer_init(
                "coverage texture",
                bytemuck::cast_slice(&packed),
                RECORD_BYTES,
                storage,
            ),
            counts: gpu.storage_buffer("hard counts", WORD * pixels, copy),
            covered: gpu.storage_buffer("covered", WORD * pixels, copy),
            visibility: gpu.storage_buffer("visibility", WORD * pixels, copy),
            stats: gpu.storage_buffer("statistics", 2 * WORD * STATS, copy),
            rgb: gpu.storage_buffer("rgb", if textured { 3 * WORD * pixels } else { WORD }, copy),
            channels: if textured { 3 } else { 1 },
        }
    }
}

/// Per tile a `[start, end)` pair into the same array, then the primitive indices in
/// submission order (those `keep(primitive, tile)` lets through); and the number of entries.
fn bins(
    rays: &EyeRays,
    footprints: &[Option<ScreenRect>],
    keep: impl Fn(usize, usize) -> bool,
) -> (Vec<u32>, u64) {
    let (tx, ty) = (rays.width.div_ceil(TILE), rays.height.div_ceil(TILE));
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); (tx * ty) as usize];
    for (k, f) in footprints.iter().enumerate() {
        let Some(f) = f else { continue };
        for by in f.y0 / TILE..f.y1.div_ceil(TILE) {
            for bx in f.x0 / TILE..f.x1.div_ceil(TILE) {
                let t = (by * tx + bx) as usize;
                if keep(k, t) {
                    lists[t].push(k as u32);
                }
            }
        }
    }
    let mut out = vec![0u32; 2 * lists.len()];
    let mut entries = 0;
    for (t, l) in lists.iter().enumerate() {
        out[2 * t] = out.len() as u32;
        out.extend(l);
        out[2 * t + 1] = out.len() as u32;
        entries += l.len() as u64;
    }
    (out, entries)
}

/// Per 8×8 tile a cone around the eye-ray directions of its pixels: unit axis and the sine of
/// the half-angle (2 when the half-angle reaches 90°: nothing is culled against it).
fn tile_cones(rays: &EyeRays) -> Vec<(Vec3, f32)> {
    let (tx, ty) = (rays.width.div_ceil(TILE), rays.height.div_ceil(TILE));
    (0..tx * ty)
        .map(|t| {
            let (x0, y0) = (t % tx * TILE, t / tx * TILE);
            let pixels: Vec<Vec3> = (y0..(y0 + TILE).min(rays.height))
                .flat_map(|y| (x0..(x0 + TILE).min(rays.width)).map(move |x| (x, y)))
                .map(|(x, y)| rays.dir[(y * rays.width + x) as usize])
                .collect();
            let axis = pixels.iter().sum::<Vec3>().normalize_or_zero();
            let cos = pixels.iter().map(|d| d.dot(axis)).fold(1.0f32, f32::min);
            let sin = if cos > 0.0 {
                (1.0 - cos * cos).max(0.0).sqrt()
            } else {
                2.0
            };
            (axis, sin)
        })
        .collect()
}

/// Whether a tile's eye rays all miss `volume`: one of its planes has the eye outside and
/// every direction of the tile's cone leaving it (a coarse test a rasterizer makes per tile;
/// the per-pixel test would reject every pixel, so the images and fragment counts do not
/// change). Margins of 1e-4 keep it conservative under rounding.
fn tile_misses(volume: &ConvexVolume, eye: Vec3, cone: (Vec3, f32)) -> bool {
    let (axis, sin) = cone;
    volume.planes.iter().any(|&(n, d)| {
        let len = n.length();
        n.dot(eye) - d > 1e-4 * (1.0 + d.abs()) && n.dot(axis) >= (sin + 1e-4) * len
    })
}

fn rect(f: &Option<ScreenRect>) -> [u32; 4] {
    f.map_or([0; 4], |r| [r.x0, r.y0, r.x1, r.y1])
}

/// The z-fail faces as the WGSL reads them from the `planes` binding: six vec4 per face, the
/// four corners (w of the first: the count change of a passing fragment, minus the eye's side;
/// w of the second: the number of corners), the outward normal and the footprint's bits.
fn face_records(rays: &EyeRays, faces: &[VolumeFace]) -> Vec<[u32; 24]> {
    faces
        .iter()
        .zip(face_footprints(rays, faces))
        .map(|(f, fp)| {
            let mut w = [0u32; 24];
            let ws = [-f.side(rays.eye), f.sides as f32, 0.0, 0.0];
            for (k, c) in f.corners.iter().chain([&f.normal]).enumerate() {
                let v = c.extend(ws.get(k).copied().unwrap_or(0.0));
                for j in 0..4 {
                    w[4 * k + j] = v[j].to_bits();
                }
            }
            w[20..24].copy_from_slice(&rect(&fp));
            w
        })
        .collect()
}

/// What the hard phase uploaded for one loop: the hard pass's bind group, the params, quads and
/// bins buffers the soft pass binds too, and the counts its counters need.
struct HardUpload {
    group: wgpu::BindGroup,
    buffers: [wgpu::Buffer; 3],
    bin_entries: u64,
    caps: u64,
}

/// A loop's uploaded primitives and what its counters need from the host.
struct LoopGpu {
    hard_group: wgpu::BindGroup,
    soft_group: wgpu::BindGroup,
    quads: u64,
    /// Cap faces of the z-fail volumes (0 for z-pass).
    caps: u64,
    quad_bin_entries: u64,
    wedges: WedgeCounts,
}

/// What the wedges phase built for one loop.
struct WedgeCounts {
    wedges: u64,
    degenerate: u64,
    prims: u64,
    planes: u64,
    bin_entries: u64,
}

struct Passes<'g> {
    gpu: &'g Gpu,
    opts: SoftShadowVolumeOptions,
    res: FrameResources,
    layout: wgpu::BindGroupLayout,
    hard: [wgpu::ComputePipeline; 2],
    soft: [wgpu::ComputePipeline; 2],
    /// `accum_hard`'s accumulation of one sample's lit pixels.
    accumulate: wgpu::ComputePipeline,
    groups: (u32, u32),
    pixels: u64,
    cones: Vec<(Vec3, f32)>,
    /// The occluders, whose light-facing triangles cap the z-fail volumes.
    occluders: Mesh,
}

impl<'g> Passes<'g> {
    fn new(
        gpu: &'g Gpu,
        rays: &EyeRays,
        opts: &SoftShadowVolumeOptions,
        res: FrameResources,
        occluders: Mesh,
    ) -> Passes<'g> {
        let device = &gpu.device;
        let mut entries = vec![layout::buffer(
            0,
            wgpu::ShaderStages::COMPUTE,
            wgpu::BufferBindingType::Uniform,
        )];
        for b in 1..=STORAGE_BUFFERS {
            entries.push(layout::buffer(
                b,
                wgpu::ShaderStages::COMPUTE,
                wgpu::BufferBindingType::Storage { read_only: b <= 7 },
            ));
        }
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(ID),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(ID),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("soft_shadow_volume/wgpu.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                format!("{WGSL}\n{}", crate::scene::coverage::WGSL).into(),
            ),
        });
        let pipeline = |entry: &str, instrument: bool| {
            gpu.instrumented_compute_pipeline(&pipeline_layout, &module, entry, instrument)
        };
        Passes {
            gpu,
            opts: *opts,
            res,
            layout,
            hard: [pipeline("hard", false), pipeline("hard", true)],
            soft: [pipeline("soft", false), pipeline("soft", true)],
            accumulate: pipeline("accumulate", false),
            groups: (rays.width.div_ceil(TILE), rays.height.div_ceil(TILE)),
            pixels: rays.len() as u64,
            cones: tile_cones(rays),
            occluders,
        }
    }

    fn group(
        &self,
        params: &wgpu::Buffer,
        prims: [&wgpu::Buffer; 5],
        label: &str,
    ) -> wgpu::BindGroup {
        let r = &self.res;
        let buffers = [
            params,
            &r.rays,
            prims[0],
            prims[1],
            prims[2],
            prims[3],
            prims[4],
            &r.texels,
            &r.counts,
            &r.covered,
            &r.visibility,
            &r.stats,
            &r.rgb,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.gpu
            .device
            .create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &self.layout,
                entries: &entries,
            })
    }

    /// The hard phase's host part: quads (and for z-fail the capped volumes' faces from light
    /// point `light`), footprints, bins, upload.
    fn upload_quads(
        &self,
        rays: &EyeRays,
        params: &Params,
        light: Vec3,
        quads: &[ShadowQuad],
    ) -> HardUpload {
        let gpu = self.gpu;
        let storage = wgpu::BufferUsages::STORAGE;
        let footprints = quad_footprints(rays, quads);
        let records: Vec<[u32; 20]> = quads
            .iter()
            .zip(&footprints)
            .map(|(q, f)| {
                let mut w = [0u32; 20];
                let eye_side = q.side(rays.eye);
                for (k, v) in [q.a.extend(eye_side), q.b.extend(0.0)]
                    .into_iter()
                    .chain([q.light.extend(0.0), q.normal.extend(0.0)])
                    .enumerate()
                {
                    for c in 0..4 {
                        w[4 * k + c] = v[c].to_bits();
                    }
                }
                w[16..20].copy_from_slice(&rect(f));
                w
            })
            .collect();
        let faces = (params.counting == 1)
            .then(|| zfail_faces(quads, &self.occluders, light, &rays.bounds));
        let (quad_bins, entries) = match &faces {
            None => bins(rays, &footprints, |_, _| true),
            Some(f) => bins(rays, &face_footprints(rays, f), |_, _| true),
        };
        let params = gpu.buffer_init(
            "ssv params",
            bytemuck::bytes_of(params),
            RECORD_BYTES,
            wgpu::BufferUsages::UNIFORM,
        );
        let quads_buf = gpu.buffer_init(
            "shadow quads",
            bytemuck::cast_slice(&records),
            RECORD_BYTES,
            storage,
        );
        let bins_buf = gpu.buffer_init(
            "quad bins",
            bytemuck::cast_slice(&quad_bins),
            RECORD_BYTES,
            storage,
        );
        let none = gpu.storage_buffer("no primitives", 128, wgpu::BufferUsages::empty());
        let faces_buf = faces.as_ref().map(|f| {
            let records = face_records(rays, f);
            gpu.buffer_init(
                "volume faces",
                bytemuck::cast_slice(&records),
                RECORD_BYTES,
                storage,
            )
        });
        let group = self.group(
            &params,
            [
                &quads_buf,
                &none,
                faces_buf.as_ref().unwrap_or(&none),
                &bins_buf,
                &none,
            ],
            "hard",
        );
        HardUpload {
            group,
            buffers: [params, quads_buf, bins_buf],
            bin_entries: entries,
            caps: faces.map_or(0, |f| (f.len() - quads.len()) as u64),
        }
    }

    /// The wedges phase's host part: wedges, primitives, bins, upload; the soft pass's group.
    fn upload_wedges(
        &self,
        rays: &EyeRays,
        run: &LoopRun,
        quads: &[ShadowQuad],
        quad_buffers: &[wgpu::Buffer; 3],
    ) -> (wgpu::BindGroup, WedgeCounts) {
        let gpu = self.gpu;
        let storage = wgpu::BufferUsages::STORAGE;
        let reach = wedge_reach(rays);
        let wedges: Vec<Option<Wedge>> = run
            .edges
            .iter()
            .map(|e| build_wedge(e, &run.light, self.opts.tighter_wedges, reach))
            .collect();
        let (prims, footprints) = wedge_primitives(rays, quads, &wedges, self.opts.wedge_culling);
        let mut planes: Vec<[f32; 4]> = Vec::new();
        let records: Vec<[u32; 8]> = prims
            .iter()
            .zip(&footprints)
            .map(|(p, f)| {
                let first = planes.len() as u32;
                planes.extend(p.volume.planes.iter().map(|(n, d)| n.extend(*d).to_array()));
                let r = rect(f);
                [
                    r[0],
                    r[1],
                    r[2],
                    r[3],
                    p.edge as u32,
                    first,
                    p.volume.planes.len() as u32,
                    p.half.unwrap_or(0.0).to_bits(),
                ]
            })
            .collect();
        let (wedge_bins, entries) = bins(rays, &footprints, |k, t| {
            !tile_misses(&prims[k].volume, rays.eye, self.cones[t])
        });
        let degenerate = wedges.iter().filter(|w| w.is_none()).count() as u64;
        let counts = WedgeCounts {
            wedges: wedges.len() as u64 - degenerate,
            degenerate,
            prims: prims.len() as u64,
            planes: planes.len() as u64,
            bin_entries: entries,
        };
        let prims_buf = gpu.buffer_init(
            "wedge primitives",
            bytemuck::cast_slice(&records),
            RECORD_BYTES,
            storage,
        );
        let planes_buf = gpu.buffer_init(
            "wedge planes",
            bytemuck::cast_slice(&planes),
            RECORD_BYTES,
            storage,
        );
        let bins_buf = gpu.buffer_init(
            "wedge bins",
            bytemuck::cast_slice(&wedge_bins),
            RECORD_BYTES,
            storage,
        );
        let [params, quads_buf, quad_bins] = quad_buffers;
        let group = self.group(
            params,
            [quads_buf, &prims_buf, &planes_buf, quad_bins, &bins_buf],
            "soft",
        );
        (group, counts)
    }

    /// Records one compute pass: `soft` picks the pass, `instrument` the counting pipelines.
    fn pass(
        &self,
        e: &mut wgpu::CommandEncoder,
        group: &wgpu::BindGroup,
        soft: bool,
        instrument: bool,
        queries: Option<(Option<&PassTimer>, Option<&PassStats>, u32)>,
    ) {
        let (timer, stats, index) = queries.unwrap_or((None, None, 0));
        let label = if soft { "soft" } else { "hard" };
        let mut pass = timing::compute_pass(e, label, timer.map(|t| (t, index)));
        if let Some(s) = stats {
            s.begin_compute(&mut pass, index);
        }
        let k = usize::from(instrument);
        pass.set_pipeline(if soft { &self.soft[k] } else { &self.hard[k] });
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
        if stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    fn run(&self, rays: &EyeRays, runs: &[LoopRun], setup_ms: f64) -> Result<FrameOutput> {
        let gpu = self.gpu;
        let mut warnings = Vec::new();
        // Every sub-light has at least one loop: `runs` is never empty.
        let n_passes = 2 * runs.len() as u32;
        let timer = PassTimer::new(gpu, n_passes);
        let stats = PassStats::new(gpu, n_passes);
        let mut wall = [setup_ms, 0.0, 0.0];
        let mut loops = Vec::with_capacity(runs.len());
        let vis_staging = Staging::new(gpu, "visibility readback", self.res.visibility.size());
        let rgb_staging = (self.res.channels == 3)
            .then(|| Staging::new(gpu, "rgb readback", self.res.rgb.size()));
        for (j, run) in runs.iter().enumerate() {
            let j = j as u32;
            // Pass 1: hard shadow quads (III §3.2.1).
            let start = Instant::now();
            let centre = run.light.center();
            let quads: Vec<ShadowQuad> = run
                .edges
                .iter()
                .map(|e| ShadowQuad::new(e, centre))
                .collect();
            let up = self.upload_quads(rays, &run.params, centre, &quads);
            let q = Some((timer.as_ref(), stats.as_ref(), 2 * j));
            self.gpu
                .submit(|e| self.pass(e, &up.group, false, false, q))?;
            wall[0] += start.elapsed().as_secs_f64() * 1e3;
            // Wedges (III §3.1, IV §4.1), on the host.
            let start = Instant::now();
            let (soft_group, w) = self.upload_wedges(rays, run, &quads, &up.buffers);
            let lg = LoopGpu {
                hard_group: up.group,
                soft_group,
                quads: quads.len() as u64,
                caps: up.caps,
                quad_bin_entries: up.bin_entries,
                wedges: w,
            };
            wall[1] += start.elapsed().as_secs_f64() * 1e3;
            // Pass 2: penumbra wedges (III §3.2.2).
            let last = j + 1 == runs.len() as u32;
            let q = Some((timer.as_ref(), stats.as_ref(), 2 * j + 1));
            wall[2] += self.gpu.submit(|e| {
                self.pass(e, &lg.soft_group, true, false, q);
                if last {
                    vis_staging.copy(e, &self.res.visibility);
                    if let Some(r) = &rgb_staging {
                        r.copy(e, &self.res.rgb);
                    }
                    resolve_queries(e, timer.as_ref(), stats.as_ref());
                }
            })?;
            loops.push(lg);
        }
        let readback_start = Instant::now();
        let data: Vec<f32> = words(&vis_staging.read(gpu)?);
        let rgb = match &rgb_staging {
            Some(r) => {
                let w: Vec<f32> = words(&r.read(gpu)?);
                Some(RgbBuffer {
                    width: rays.width,
                    height: rays.height,
                    data: w.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                })
            }
            None => None,
        };
        let readback_ms = readback_start.elapsed().as_secs_f64() * 1e3;
        let times = read_ms_or_warn(gpu, &timer, &mut warnings)?;
        let gpu_ms = times.ms.clone();
        let pipeline = read_or_warn(gpu, &stats, &mut warnings)?;

        // The instrumented replay: the same passes counting with atomics, per loop.
        let mut per_phase = [
            Counters::default(),
            Counters::default(),
            Counters::default(),
        ];
        for (run, lg) in runs.iter().zip(&loops) {
            let staging = Staging::new(gpu, "statistics readback", self.res.stats.size());
            self.gpu.submit(|e| {
                e.clear_buffer(&self.res.stats, 0, None);
                self.pass(e, &lg.hard_group, false, true, None);
                self.pass(e, &lg.soft_group, true, true, None);
                staging.copy(e, &self.res.stats);
            })?;
            let raw: Vec<u32> = words(&staging.read(gpu)?);
            let stat = |s: Stat| {
                let i = s as usize;
                (u64::from(raw[2 * i + 1]) << 32 | u64::from(raw[2 * i])) as f64
            };
            let [hard, wedges, soft] = &mut per_phase;
            if let Some(n) = run.silhouette_edges {
                hard.add("silhouette_edges", n as f64);
            }
            self.hard_counters(hard, lg, &stat);
            wedges.add("wedges", lg.wedges.wedges as f64);
            wedges.add("wedges_degenerate", lg.wedges.degenerate as f64);
            self.soft_counters(soft, lg, &stat);
        }
        if let Some(p) = &pipeline {
            for (j, s) in p.iter().enumerate() {
                if let Some(v) = s.get(COMPUTE_INVOCATIONS) {
                    let phase = if j % 2 == 0 { 0 } else { 2 };
                    per_phase[phase].add(COMPUTE_INVOCATIONS, v);
                }
            }
        }
        let names = ["hard", "wedges", "soft"];
        let gpu_phase_ms = |phase: usize| {
            gpu_ms.as_ref().map(|t| match phase {
                0 => t.iter().step_by(2).sum(),
                2 => t.iter().skip(1).step_by(2).sum(),
                _ => 0.0,
            })
        };
        let mut counters = Counters::default();
        let mut phases = Vec::with_capacity(3);
        for (i, c) in per_phase.into_iter().enumerate() {
            counters.merge(&c);
            phases.push(Phase {
                name: names[i].into(),
                wall_ms: wall[i],
                model_ms: None,
                gpu_ms: if i == 1 { None } else { gpu_phase_ms(i) },
                counters: c,
            });
        }
        let mut execution = gpu.execution();
        times.record(&mut execution);
        execution.insert("readback_ms".into(), serde_json::json!(readback_ms));
        execution.insert(
            "gpu_counters".into(),
            serde_json::json!(
                "fill, overdraw, shader invocations and culls from an instrumented replay (WGSL \
                 atomics), in the cpu-model's terms; mem_est.* estimated from counts and record \
                 sizes"
            ),
        );
        Ok(FrameOutput {
            visibility: VisibilityBuffer {
                width: rays.width,
                height: rays.height,
                data,
            },
            counters,
            phases,
            model_ms: None,
            gpu_ms: gpu_ms.map(|t| t.iter().sum()),
            execution,
            warnings,
            rgb,
        })
    }

    /// `hard`: fill and overdraw as on the cpu executions (quad fragments within the scene
    /// bounds, and those behind the visible surface), and estimated traffic: rays of every
    /// pixel, quad records per test, the bins, a depth read per fragment, the count written.
    fn hard_counters(&self, k: &mut Counters, lg: &LoopGpu, stat: &impl Fn(Stat) -> f64) {
        let (fill, passed, tests) = (
            stat(Stat::HardFill),
            stat(Stat::HardPassed),
            stat(Stat::HardTests),
        );
        k.add("fill", fill);
        k.add("overdraw", fill - passed);
        k.add("quad_tests", tests);
        k.add("shadow_quads", lg.quads as f64);
        let record = if self.opts.counting == Counting::ZFail {
            k.add("volume_caps", lg.caps as f64);
            FACE_BYTES
        } else {
            QUAD_BYTES
        };
        let rays = (RAY_BYTES * self.pixels) as f64;
        let quads = record as f64 * tests;
        let bins = (WORD * (lg.quad_bin_entries + 2 * self.tiles())) as f64;
        let depth = fill * DEPTH_BYTES as f64;
        let vbuffer = (VBUFFER_BYTES * self.pixels) as f64;
        k.add("mem_est.eye_rays.read_bytes", rays);
        k.add("mem_est.shadow_quads.read_bytes", quads);
        k.add("mem_est.quad_bins.read_bytes", bins);
        k.add("mem_est.depth.read_bytes", depth);
        k.add("mem_est.vbuffer.write_bytes", vbuffer);
        k.add("mem_est.read_bytes", rays + quads + bins + depth);
        k.add("mem_est.write_bytes", vbuffer);
    }

    /// `soft`: fill, overdraw, shader invocations, culled fragments and fragments inside wedges
    /// in the cpu-model's terms (with culling each half is rasterized twice, IV §4.4), and
    /// estimated traffic: rays, primitive records and planes per test, bins, depth and stencil
    /// as a rasterizer would touch them, the V-buffer per fragment inside, texture reads.
    fn soft_counters(&self, k: &mut Counters, lg: &LoopGpu, stat: &impl Fn(Stat) -> f64) {
        let (fill, front, inside, covered, contributing, tests) = (
            stat(Stat::SoftFill),
            stat(Stat::SoftFront),
            stat(Stat::SoftInside),
            stat(Stat::SoftCovered),
            stat(Stat::SoftContributing),
            stat(Stat::SoftTests),
        );
        let (raster_fill, shaded, culled, stencil_read, stencil_write) = if self.opts.wedge_culling
        {
            (2.0 * fill, inside, fill - inside, fill, 2.0 * front)
        } else {
            (fill, front, 0.0, 0.0, 0.0)
        };
        k.add("fill", raster_fill);
        k.add("overdraw", raster_fill - contributing);
        k.add("shader_invocations", shaded);
        k.add("culled_fragments", culled);
        k.add("fragments_inside_wedges", covered);
        k.add("wedge_tests", tests);
        k.add("wedge_primitives", lg.wedges.prims as f64);
        let texture_reads = if self.opts.coverage == CoverageMethod::Texture {
            CoverageTexture::READS as f64 * covered
        } else {
            0.0
        };
        k.add("coverage_texture_reads", texture_reads);
        // Bytes: one per channel of each texel read.
        let texture_reads = texture_reads * f64::from(self.res.channels);
        let per_plane = if lg.wedges.prims > 0 {
            lg.wedges.planes as f64 / lg.wedges.prims as f64
        } else {
            0.0
        };
        let rays = (RAY_BYTES * self.pixels) as f64;
        let prims = tests * (PRIM_BYTES as f64 + per_plane * PLANE_BYTES as f64);
        let bins = (WORD * (lg.wedges.bin_entries + 2 * self.tiles())) as f64;
        let quads = QUAD_BYTES as f64 * inside;
        let depth = raster_fill * DEPTH_BYTES as f64;
        let stencil_r = stencil_read * STENCIL_BYTES as f64;
        let stencil_w = stencil_write * STENCIL_BYTES as f64;
        let vbuffer = (VBUFFER_BYTES * u64::from(self.res.channels)) as f64 * covered;
        let counts = (WORD * self.pixels) as f64;
        let out = (2 * WORD * self.pixels) as f64;
        k.add("mem_est.eye_rays.read_bytes", rays);
        k.add("mem_est.wedge_primitives.read_bytes", prims);
        k.add("mem_est.wedge_bins.read_bytes", bins);
        k.add("mem_est.shadow_quads.read_bytes", quads);
        k.add("mem_est.depth.read_bytes", depth);
        k.add("mem_est.stencil.read_bytes", stencil_r);
        k.add("mem_est.stencil.write_bytes", stencil_w);
        k.add("mem_est.vbuffer.read_bytes", vbuffer + counts);
        k.add("mem_est.vbuffer.write_bytes", vbuffer);
        k.add("mem_est.coverage_texture.read_bytes", texture_reads);
        k.add("mem_est.visibility.write_bytes", out);
        k.add(
            "mem_est.read_bytes",
            rays + prims + bins + quads + depth + stencil_r + vbuffer + counts + texture_reads,
        );
        k.add("mem_est.write_bytes", stencil_w + vbuffer + out);
    }

    fn tiles(&self) -> u64 {
        u64::from(self.groups.0) * u64::from(self.groups.1)
    }
}

/// The hard pass of this module once per light sample, for `accum_hard` on wgpu: per sample the
/// hard shadow quads (or z-fail faces) binned and counted per pixel by the `hard` entry, then
/// the `accumulate` entry adding the pixels with count 0 to a per-pixel sum (the `covered`
/// buffer) and, after the last sample, writing the average to `visibility`.
pub(crate) struct HardSamples<'g> {
    passes: Passes<'g>,
    samples: u32,
}

/// One light sample's uploaded hard pass.
pub(crate) struct SampleUpload {
    up: HardUpload,
    /// Quads and cap faces, for the counters.
    pub quads: u64,
    pub caps: u64,
}

/// Fragment counts of the instrumented replay, summed over samples.
pub(crate) struct HardTally {
    pub fill: f64,
    pub passed: f64,
    pub tests: f64,
}

impl<'g> HardSamples<'g> {
    pub(crate) fn new(
        gpu: &'g Gpu,
        rays: &EyeRays,
        counting: Counting,
        occluders: Mesh,
        samples: u32,
    ) -> HardSamples<'g> {
        let opts = SoftShadowVolumeOptions {
            counting,
            ..Default::default()
        };
        let res = FrameResources::new(gpu, rays, None, false);
        HardSamples {
            passes: Passes::new(gpu, rays, &opts, res, occluders),
            samples,
        }
    }

    /// Uploads sample `s`'s quads from light point `light` (host part of the hard phase).
    pub(crate) fn upload(
        &self,
        rays: &EyeRays,
        s: u32,
        light: Vec3,
        quads: &[ShadowQuad],
        eye_count: i32,
    ) -> SampleUpload {
        let params = Params {
            center: light.extend(0.0).to_array(),
            half_u: [0.0; 4],
            half_v: [0.0; 4],
            eye: rays.eye.extend(0.0).to_array(),
            width: rays.width,
            height: rays.height,
            tiles_x: rays.width.div_ceil(TILE),
            eye_count,
            vbuffer: 0,
            coverage: 0,
            texture_n: 0,
            first_loop: 1,
            last_loop: 1,
            first_light: u32::from(s == 0),
            last_light: u32::from(s + 1 == self.samples),
            sub_lights: self.samples,
            counting: u32::from(self.passes.opts.counting == Counting::ZFail),
            channels: 1,
            pad: [0; 2],
            mean: [1.0; 4],
        };
        let up = self.passes.upload_quads(rays, &params, light, quads);
        SampleUpload {
            quads: quads.len() as u64,
            caps: up.caps,
            up,
        }
    }

    /// Records the sample's hard pass (timed as pass `index` when queries are given).
    pub(crate) fn hard(
        &self,
        e: &mut wgpu::CommandEncoder,
        s: &SampleUpload,
        queries: Option<(Option<&PassTimer>, Option<&PassStats>, u32)>,
    ) {
        self.passes.pass(e, &s.up.group, false, false, queries);
    }

    /// Records the sample's accumulation (timed as pass `index` when queries are given).
    pub(crate) fn accumulate(
        &self,
        e: &mut wgpu::CommandEncoder,
        s: &SampleUpload,
        queries: Option<(Option<&PassTimer>, Option<&PassStats>, u32)>,
    ) {
        let (timer, stats, index) = queries.unwrap_or((None, None, 0));
        let mut pass = timing::compute_pass(e, "accumulate", timer.map(|t| (t, index)));
        if let Some(st) = stats {
            st.begin_compute(&mut pass, index);
        }
        pass.set_pipeline(&self.passes.accumulate);
        pass.set_bind_group(0, &s.up.group, &[]);
        pass.dispatch_workgroups(self.passes.groups.0, self.passes.groups.1, 1);
        if stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    /// The averaged visibility, written by the last sample's accumulation.
    pub(crate) fn visibility(&self) -> &wgpu::Buffer {
        &self.passes.res.visibility
    }

    /// The instrumented replay of every sample's hard pass (WGSL atomics), in one submission.
    pub(crate) fn replay(&self, samples: &[SampleUpload]) -> Result<HardTally> {
        let gpu = self.passes.gpu;
        let stats = &self.passes.res.stats;
        let staging = Staging::new(gpu, "statistics readback", stats.size());
        gpu.submit(|e| {
            e.clear_buffer(stats, 0, None);
            for s in samples {
                self.passes.pass(e, &s.up.group, false, true, None);
            }
            staging.copy(e, stats);
        })?;
        let raw: Vec<u32> = words(&staging.read(gpu)?);
        let stat = |s: Stat| {
            let i = s as usize;
            (u64::from(raw[2 * i + 1]) << 32 | u64::from(raw[2 * i])) as f64
        };
        Ok(HardTally {
            fill: stat(Stat::HardFill),
            passed: stat(Stat::HardPassed),
            tests: stat(Stat::HardTests),
        })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::*;
    use crate::gpu::wgsl_layout::assert_wgsl_layout;

    #[test]
    fn uniforms_match_wgsl() {
        let source = format!("{WGSL}\n{}", crate::scene::coverage::WGSL);
        assert_wgsl_layout!(
            source,
            "Params",
            Params {
                center,
                half_u,
                half_v,
                eye,
                width,
                height,
                tiles_x,
                eye_count,
                vbuffer,
                coverage,
                texture_n,
                first_loop,
                last_loop,
                first_light,
                last_light,
                sub_lights,
                counting,
                channels,
                pad,
                mean
            }
        );
    }
}
