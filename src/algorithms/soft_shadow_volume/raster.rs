//! `soft_shadow_volume` on wgpu as the thesis renders it (option `gpu_pipeline: "raster"`, the
//! default; `raster.wgsl`), per silhouette loop and sub-light as on the cpu executions:
//!
//! - `hard` (III §3.2.1): the eye's depth once, then the shadow quads of the silhouette seen
//!   from the light centre (z-pass, cleared to the eye's count) or the capped volumes' faces
//!   (z-fail) drawn into the count target by additive blending, the depth test made in the
//!   fragment shader along each pixel's ray to its shaded point
//!   ([`crate::algorithms::shadow_volume::raster::HardRaster`], which states how its coverage
//!   differs from the cpu's ray casting).
//! - `wedges` (III §3.1, IV §4.1): on the host with the cpu executions' code, as the gather
//!   ([`super::wgpu::WedgeRecords`]); each wedge primitive (the wedge, or with culling each
//!   half) is cut to the enlarged scene bounds and its front faces seen from the eye are
//!   triangulated and projected on the host ([`faces`]: the primitive's planes pushed out by
//!   [`WEDGE_MARGIN`], so that every pixel whose ray passes the primitive has a fragment, and
//!   the corners welded, so that neighbouring faces share their edges to the bit).
//! - `soft` (III §3.2.2, §4; IV §4.2-4.3): the front faces drawn, a fragment shader making the
//!   depth tests along the pixel's ray to its shaded point (the visible point behind the
//!   primitive's entry and in front of its exit) and computing the coverage of its pixel
//!   exactly as the gather does (`wedge_sample` of `wgpu.wgsl`: the point inside the
//!   primitive, the edge projected onto the light, exact clipping or the 4D
//!   texture) and adding or subtracting it into the V-buffer by additive blending: R32Float
//!   (Rgba32Float, one f32 per channel, under a textured light, III §4.1), or the split 12-bit
//!   format (IV §4.3) as two rgba8 buffers, the inner side's digits drawn into the additive
//!   one and the outer side's into the subtractive one, the 8-bit blend saturating as
//!   [`super::split12::blend`]; then a compute `resolve` forms `1 − count ± coverage` and the
//!   loops' and sub-lights' combination (`combine`, shared with the gather).
//! - Wedge-half culling (IV §4.4, `wedge_culling`, where the adapter has Depth32FloatStencil8):
//!   each half separately, its front faces marking the stencil with the half's reference where
//!   the point is behind them and in front of the half's back faces (no colour; the marking
//!   shader `fs_mark` makes these depth tests along the pixel's ray, `wedge_reach`), then its
//!   back faces, with the coverage shader, where the stencil holds the reference — the point
//!   inside the half, the coverage shader run for no other; every back-face fragment clears the
//!   stencil ([`LoopRaster::pass`]). The depth tests are not the depth buffer's: the shaded
//!   point is moved off its surface, off the pixel centre's ray, and a half's face that runs
//!   along the occluder beside its silhouette edge passes between the two.
//!   The split format draws the inner halves into the additive buffer and the outer halves
//!   into the subtractive one. The shader still tests the point against the half's planes, as
//!   the cpu executions do, so the image does not depend on the culling. Without the format the
//!   shader's test alone culls (recorded in `execution.wedge_culling`).
//!
//! Not built on the GPU: silhouettes, quads, caps and wedges (host, as on the cpu executions).
//! A wedge primitive that contains the eye has no front face and draws nothing (the gather and
//! the cpu executions still shade its pixels).
//!
//! How the image differs from the cpu's: the hard pass as [`HardRaster`] states; the wedges'
//! pixels are decided by the rasterizer's coverage of their faces at the pixel's centre
//! (top-left rule), so a pixel whose centre and shaded point lie on two sides of a primitive's
//! outline (within the point's offset, a fraction of a pixel) can change hands; the V-buffer
//! sums in rasterization order (f32 rounding); the coverage of a pixel the wedge covers is the
//! gather's, operation for operation.
//!
//! Counters: the hard pass's fill and overdraw from [`HardRaster::replay`] (rasterized
//! fragments, in the cpu-model's terms). The wedge pass's from an instrumented replay of its own
//! front faces (the counting pipeline: depth test off, `INSTRUMENT` on; one draw of the
//! primitives even where the split format draws them twice), each fragment counted in the
//! cpu-model's terms (`SoftPass::block`): fill, its ray meets the primitive within the scene
//! bounds (doubled with culling: the front and the back faces of the half are rasterized);
//! shader invocations, its point is behind the entry, or with culling the fragments that pass
//! the culled passes' stencil tests, counted by those passes themselves (each adds 1
//! into an R32Float target; `execution.shader_invocations` says which); fragments inside
//! wedges, the coverage was computed; overdraw, fill less the fragments adding a non-zero
//! coverage; `wedge_tests`, every rasterized fragment. A pixel whose ray grazes a primitive can
//! be rasterized where the cpu's interval misses it or the reverse, so these differ from the
//! cpu-model's by a small fraction of the fill ([`super::SoftShadowVolume`]'s `WGPU_PARITY`).

use glam::Vec3;
use wgpu::CompareFunction::{Always, Equal};
use wgpu::StencilOperation::{Keep, Replace, Zero};

use super::wgpu::{
    run_loops, LoopRun, Pipeline, Replayed, SoftGroup, SoftParams, SoftStat, WedgeRecords,
    STENCIL_BYTES, VBUFFER_BYTES, WGSL as SOFT_WGSL,
};
use super::{clip_half_plane, SoftShadowVolumeOptions, VBufferPrecision};
use crate::algorithms::algorithm::FrameOutput;
use crate::algorithms::eye_raster::{ConvexVolume, EyeRays, DEPTH_BYTES};
use crate::algorithms::shadow_volume::raster::{
    eye_projection, hard_triangles, DepthTarget, HardRaster,
};
use crate::algorithms::shadow_volume::wgpu::{hard_fill, quad_records, RECORDS_WGSL, TILE};
use crate::algorithms::shadow_volume::ShadowQuad;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    replay_slots, tiles, view, Bind, Compute, Instrumented, Layout, Onto, Pass, Program, Raster,
    Render, Statistics, Stencil, Step,
};
use crate::gpu::readback::read_texels;
use crate::gpu::{additive, record_execution, stencil_test, unwritten, GpuCounters, Run};
use crate::record::Counters;
use crate::scene::{Bounds, Mesh};

/// The wedge pass's WGSL.
const WGSL: &str = include_str!("raster.wgsl");
/// The wedge passes' and the resolve's shader as their pipelines join it.
const SOURCES: [&str; 5] = [
    SoftParams::WGSL,
    RECORDS_WGSL,
    SOFT_WGSL,
    WGSL,
    crate::scene::coverage::WGSL,
];
/// Bytes of a wedge vertex: clip position and the primitive's index.
const VERTEX_BYTES: u64 = 20;

/// How far, as a fraction of the scene bounds' diagonal, the faces a wedge primitive is drawn
/// with lie outside its planes ([`faces`]): 8 times the shaded points' offset off their
/// surfaces (`frame::offset_point`, 1e-4 of the diagonal). The fragment shader tests the
/// primitive's own planes along the pixel's ray to its shaded point, as the cpu does; drawn
/// with that margin, every pixel whose ray passes the primitive has a fragment, also where the
/// pixel's centre lies just outside its outline and its shaded point just inside (beside the
/// silhouette edge, where the wedge is thin).
pub const WEDGE_MARGIN: f32 = 8e-4;

/// The front faces (the eye strictly outside their plane), or with `front` false the back
/// faces (strictly inside), of `volume` with its planes pushed out by [`WEDGE_MARGIN`], cut to
/// `bounds` and to the half-space in front of plane
/// `near` (`n·x ≤ d` kept, the eye outside: a primitive that contains the eye is entered
/// through it), as triangles (three points each): each face is a square on its plane reaching
/// past the bounds, clipped by every other plane (Sutherland–Hodgman), fanned from its first
/// corner.
///
/// Every face's corners are welded to one point per corner of the volume (corners within
/// 1e-5 of the bounds' diagonal of one another, what the clipping of two faces through one
/// corner rounds apart), whichever face computed it first, so that neighbouring faces — front
/// and back, whose union the culling's two passes must cover alike — share their edges to the
/// bit and the rasterizer covers a pixel along a shared edge once.
pub fn faces(
    volume: &ConvexVolume,
    bounds: &Bounds,
    near: (Vec3, f32),
    eye: Vec3,
    front: bool,
) -> Vec<Vec3> {
    let (lo, hi) = (bounds.min, bounds.max);
    let (centre, reach) = (bounds.center(), bounds.diagonal());
    // The primitive's own planes pushed out by the margin (the near plane and the bounds stay).
    let margin = WEDGE_MARGIN * reach;
    let mut planes: Vec<(Vec3, f32)> = (volume.planes.iter())
        .map(|&(n, d)| (n, d + margin * n.length()))
        .collect();
    planes.push(near);
    for (k, axis) in [Vec3::X, Vec3::Y, Vec3::Z].into_iter().enumerate() {
        planes.extend([(axis, hi[k]), (-axis, -lo[k])]);
    }
    let weld = 1e-5 * reach;
    let mut corners: Vec<Vec3> = Vec::new();
    let mut out = Vec::new();
    for (i, &(n, d)) in planes.iter().enumerate() {
        let len = n.length();
        if len == 0.0 {
            continue;
        }
        let facing = n.dot(eye) - d;
        let (n, d) = (n / len, d / len);
        let (u, v) = n.any_orthonormal_pair();
        let c = centre - n * (n.dot(centre) - d);
        let mut poly: Vec<Vec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(a, b)| c + (u * a + v * b) * reach)
            .to_vec();
        for (j, &(m, e)) in planes.iter().enumerate() {
            if j != i && poly.len() >= 3 {
                poly = clip_half_plane(&poly, |x| e - m.dot(x));
            }
        }
        // Every face is welded (the faces of the other facing too), so both calls weld alike.
        for x in &mut poly {
            match corners.iter().find(|c| c.distance(*x) <= weld) {
                Some(&c) => *x = c,
                None => corners.push(*x),
            }
        }
        if (front && facing <= 0.0) || (!front && facing >= 0.0) {
            continue;
        }
        for k in 1..poly.len().saturating_sub(1) {
            out.extend([poly[0], poly[k], poly[k + 1]]);
        }
    }
    out
}

/// What a loop's hard phase drew: the vertex buffer of its triangles ([`hard_triangles`]),
/// their vertex count, the eye's count the pass starts from and the z-fail caps.
struct HardVertices {
    buffer: wgpu::Buffer,
    count: u32,
    eye_count: i32,
    caps: u64,
}

/// What one loop's wedges phase uploaded, kept for the instrumented replay.
struct LoopRaster {
    /// The wedge primitives' front faces: the first `wedge_vertices` of `wedge`.
    wedge_vertices: u32,
    /// The wedge pass's bind group and vertex buffer.
    group: wgpu::BindGroup,
    wedge: wgpu::Buffer,
    /// The wedge halves' faces, with the stencil.
    halves: Vec<Half>,
}

impl LoopRaster {
    /// A wedge pass into `color`, cleared to 0, with the eye's depth `depth`: with one of
    /// `pipelines` over the front faces; with two, the culling of IV §4.4 over the halves
    /// `keep` lets through: per half, its front faces mark the stencil of `depth` with the
    /// half's reference where the point is inside the half (`pipelines[0]`), then its back
    /// faces shade where the stencil holds the reference (`pipelines[1]`), clearing it. References run 1..=255 and the back faces clear what the
    /// front faces marked, so no half sees another's marks.
    fn pass<'a>(
        &'a self,
        pipelines: &'a [Render],
        color: &'a wgpu::TextureView,
        depth: &'a wgpu::TextureView,
        keep: impl Fn(&Half) -> bool,
    ) -> Pass<'a> {
        let culled = pipelines.len() == 2;
        let draws = match culled {
            false => vec![(0, 0..self.wedge_vertices, 0)],
            true => (self.halves.iter().filter(|h| keep(h)).enumerate())
                .flat_map(|(i, h)| {
                    let reference = (i % 255) as u32 + 1;
                    [
                        (0, h.front.clone(), reference),
                        (1, h.back.clone(), reference),
                    ]
                })
                .collect(),
        };
        let stencil = if culled {
            Stencil::Clear(0)
        } else {
            Stencil::Off
        };
        let onto = Onto {
            depth: Some(depth),
            stencil,
            vertices: Some(&self.wedge),
            ..Onto::new(pipelines, draws, color, Some(0.0))
        };
        Pass::onto("soft", &[Some(&self.group)], onto)
    }
}

/// A wedge half's front and back faces (vertex ranges) and its side of the hard shadow quad
/// (−1 inner, +1 outer).
struct Half {
    front: std::ops::Range<u32>,
    back: std::ops::Range<u32>,
    side: f32,
}

/// The wedge pass (pass 2): its V-buffers, pipelines and the host's cut of the primitives.
struct WedgePass {
    split: bool,
    /// Wedge-half culling by the stencil test (IV §4.4).
    stencil: bool,
    vbuffers: Vec<wgpu::TextureView>,
    /// Per V-buffer: the timed pipeline, or with the stencil the marking and shading ones.
    timed: Vec<Vec<Render>>,
    /// The counting pipeline (depth test off, `INSTRUMENT` on), alone (replay only).
    counting: [Render; 1],
    /// With the stencil and the counters: an R32Float target and the culled pipelines that add
    /// 1 per fragment passing both tests (replay only).
    culled_count: Option<(wgpu::Texture, wgpu::TextureView, Vec<Render>)>,
    projection: glam::Mat4,
    /// The plane just in front of the eye and the scene bounds, slightly enlarged, that cut
    /// the primitives.
    near: (Vec3, f32),
    bounds: Bounds,
}

impl WedgePass {
    fn new(
        gpu: &Run,
        frame: &Frame,
        rays: &EyeRays,
        opts: &SoftShadowVolumeOptions,
        program: &Program,
        textured: bool,
    ) -> WedgePass {
        let split = opts.vbuffer == VBufferPrecision::Split12;
        let stencil = stencil_in(opts, gpu);
        let size = (rays.width, rays.height);
        let (format, entries) = match (split, textured) {
            (true, _) => (
                wgpu::TextureFormat::Rgba8Unorm,
                &["fs_wedge_add", "fs_wedge_sub"][..],
            ),
            (false, true) => (wgpu::TextureFormat::Rgba32Float, &["fs_wedge"][..]),
            (false, false) => (wgpu::TextureFormat::R32Float, &["fs_wedge"][..]),
        };
        let attributes = wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32];
        // Every pipeline lets each fragment of a face through to the fragment shader, which
        // makes the depth tests along the pixel's ray to its shaded point (`wedge_sample`,
        // `fs_mark`): the depth buffer at the pixel's centre is not where that point lies.
        let pipeline = |fs: &str, format, test: wgpu::StencilState, instrument: bool| {
            program.render(
                gpu,
                &Raster {
                    vs: "vs_wedge",
                    fs,
                    vertex: Some((VERTEX_BYTES, wgpu::VertexStepMode::Vertex, &attributes)),
                    depth: Some(Always),
                    depth_format: depth_target(stencil).format(),
                    stencil: test,
                    depth_write: false,
                    // `fs_mark` only marks the stencil.
                    color: Some(match fs {
                        "fs_mark" => unwritten(format),
                        _ => additive(format),
                    }),
                    instrument: Some(instrument),
                    ..Raster::default()
                },
            )
        };
        // Per half (IV §4.4): the front faces mark the stencil (`fs_mark`, no colour) where the
        // point is behind them and in front of the back faces (inside the half), the back faces
        // shade where the stencil holds the half's reference, clearing it.
        let culled = |fs: &str, format| {
            let mark = stencil_test(Always, Replace, Keep);
            let shade = stencil_test(Equal, Zero, Zero);
            vec![
                pipeline("fs_mark", format, mark, false),
                pipeline(fs, format, shade, false),
            ]
        };
        let timed = entries
            .iter()
            .map(|e| match stencil {
                false => vec![pipeline(e, format, Default::default(), false)],
                true => culled(e, format),
            })
            .map(|p| p.into_iter().map(Instrumented::timed).collect())
            .collect();
        let measure = stencil && gpu.float32_blendable && gpu.counters() == GpuCounters::On;
        let culled_count = measure.then(|| {
            let f = wgpu::TextureFormat::R32Float;
            let target = gpu.texture("culled fragments", size, f, wgpu::TextureUsages::COPY_SRC);
            let view = target.create_view(&Default::default());
            let pipelines = culled("fs_one", f).into_iter().map(Instrumented::counting);
            (target, view, pipelines.collect())
        });
        let camera = &frame.scene.camera;
        let forward = (camera.target - camera.eye).normalize_or(Vec3::NEG_Z);
        let reach = 1e-3 * rays.bounds.diagonal();
        let mut bounds = rays.bounds;
        (bounds.min, bounds.max) = (bounds.min - reach, bounds.max + reach);
        WedgePass {
            split,
            stencil,
            vbuffers: entries
                .iter()
                .map(|e| gpu.target_view(e, size, format))
                .collect(),
            timed,
            counting: [Instrumented::counting(pipeline(
                entries[0],
                format,
                Default::default(),
                true,
            ))],
            culled_count,
            projection: eye_projection(rays, camera),
            near: (-forward, -forward.dot(rays.eye) - reach),
            bounds,
        }
    }

    /// Every primitive's front faces in clip space (with its index), then with the stencil
    /// every one's back faces; the count of front-face vertices and the halves' ranges.
    fn geometry(&self, rays: &EyeRays, w: &WedgeRecords) -> (Vec<[f32; 5]>, u32, Vec<Half>) {
        let n = w.prims.len();
        let (mut vertices, mut ranges, mut fronts) = (Vec::new(), Vec::new(), 0);
        for front in [true, false]
            .into_iter()
            .take(1 + usize::from(self.stencil))
        {
            for (i, p) in w.prims.iter().enumerate() {
                let first = vertices.len() as u32;
                for x in faces(&p.volume, &self.bounds, self.near, rays.eye, front) {
                    let c = self.projection * x.extend(1.0);
                    vertices.push([c.x, c.y, c.z, c.w, i as f32]);
                }
                ranges.push(first..vertices.len() as u32);
            }
            if front {
                fronts = vertices.len() as u32;
            }
        }
        let halves = match self.stencil {
            false => Vec::new(),
            true => (0..n)
                .map(|i| Half {
                    front: ranges[i].clone(),
                    back: ranges[n + i].clone(),
                    side: w.prims[i].half.unwrap_or(0.0),
                })
                .collect(),
        };
        (vertices, fronts, halves)
    }

    /// The timed wedge passes of loop `lg`, one per V-buffer, with the eye's depth `depth`;
    /// with the stencil the split format's additive buffer takes the inner halves, the
    /// subtractive one the outer halves.
    fn passes<'a>(&'a self, lg: &'a LoopRaster, depth: &'a wgpu::TextureView) -> Vec<Pass<'a>> {
        let split = self.split;
        (self.timed.iter().zip(&self.vbuffers).enumerate())
            .map(|(j, (pipelines, color))| {
                lg.pass(pipelines, color, depth, |h| {
                    !split || (h.side < 0.0) == (j == 0)
                })
            })
            .collect()
    }

    /// The fragments of loop `lg` that pass the culled passes' stencil tests, counted
    /// by those passes; `None` without the stencil or the counters.
    fn shaded(&self, gpu: &Run, lg: &LoopRaster, depth: &wgpu::TextureView) -> Result<Option<f64>> {
        let Some((target, view, pipelines)) = &self.culled_count else {
            return Ok(None);
        };
        let pass = lg.pass(pipelines, view, depth, |_| true);
        crate::gpu::pass::replay(gpu, &[Step::Submit(vec![pass])])?;
        let texels = read_texels::<f32>(gpu, std::slice::from_ref(target))?;
        Ok(Some(texels[0].iter().map(|&n| f64::from(n)).sum()))
    }

    /// `execution.wedge_culling` and `execution.shader_invocations`: how the halves were culled
    /// and what the shader invocations count.
    fn record(&self, opts: &SoftShadowVolumeOptions) -> serde_json::Value {
        let culling = match (opts.wedge_culling, self.stencil) {
            (false, _) => "off",
            (true, true) => {
                "stencil test: front faces mark the points inside the half (the depth tests in \
                 the marking shader, along the pixel's ray), back faces shade (IV §4.4)"
            }
            (true, false) => {
                "the half's plane tested in the fragment shader (the adapter lacks \
                 DEPTH32FLOAT_STENCIL8)"
            }
        };
        let shaded = match self.culled_count {
            Some(_) => "fragments passing the culled passes' stencil tests",
            None => "fragments whose point the shader finds inside the primitive",
        };
        serde_json::json!({ "wedge_culling": culling, "shader_invocations": shaded })
    }
}

/// Whether a run of `opts` on `gpu` culls the wedge halves by the stencil (IV §4.4).
fn stencil_in(opts: &SoftShadowVolumeOptions, gpu: &Run) -> bool {
    opts.wedge_culling && gpu.depth32_stencil8
}

/// The eye depth: with the stencil of the culling, or without.
fn depth_target(stencil: bool) -> DepthTarget {
    match stencil {
        true => DepthTarget::DepthStencil,
        false => DepthTarget::Depth,
    }
}

/// The raster pipeline: the family's raster hard pass, the soft pass's group and buffers, the
/// wedge pass, and the resolve reading the count and V-buffers.
struct Rasterized<'g> {
    gpu: &'g Run,
    opts: SoftShadowVolumeOptions,
    occluders: Mesh,
    hard: HardRaster<'g>,
    soft: SoftGroup<'g>,
    wp: WedgePass,
    read_targets: wgpu::BindGroup,
    resolve: Compute,
    /// The resolve's workgroups: the image's 8×8 tiles.
    tiles: (u32, u32),
}

/// The raster pipeline over `runs` (the loops of every sub-light, [`super::wgpu::render`]).
pub(super) fn run(
    gpu: &Run,
    frame: &Frame,
    rays: &EyeRays,
    opts: &SoftShadowVolumeOptions,
    soft: SoftGroup,
    runs: &[LoopRun],
    setup_ms: f64,
) -> Result<FrameOutput> {
    let instead = "vbuffer \"split12\" or gpu_pipeline \"gather\"";
    gpu.check_float32_blend(opts.vbuffer == VBufferPrecision::F32, instead)?;
    let start = std::time::Instant::now();
    let objects_ms = gpu.cache.run_objects_ms();
    let occluders = frame.scene.occluders();
    let depth = depth_target(stencil_in(opts, gpu));
    let hard = HardRaster::new(gpu, rays, &frame.scene.camera, opts.counting, 1, depth);
    let textured = soft.channels == 3;
    let program = Program::new(gpu, "ssv raster", &SOURCES, &[Some(&soft.layout)]);
    let wp = WedgePass::new(gpu, frame, rays, opts, &program, textured);
    let vb = &wp.vbuffers;
    let (targets, read_targets) = Layout::bound(
        gpu,
        "ssv targets",
        wgpu::ShaderStages::COMPUTE,
        &[&hard.count, &vb[0], vb.last().unwrap_or(&vb[0])].map(|t| (Bind::Float, view(t))),
    );
    let groups = [Some(&soft.layout), Some(&targets)];
    let resolve = Program::new(gpu, "ssv resolve", &SOURCES, &groups);
    let resolve = Instrumented::timed(resolve.compute(gpu, "resolve_soft", Some(false)));
    let p = Rasterized {
        gpu,
        opts: *opts,
        occluders,
        hard,
        soft,
        wp,
        read_targets,
        resolve,
        tiles: tiles((rays.width, rays.height), TILE),
    };
    // Without the pipelines' creation: the run's GPU setup, reported apart.
    let objects_ms = gpu.cache.run_objects_ms() - objects_ms;
    let setup_ms = setup_ms + start.elapsed().as_secs_f64() * 1e3 - objects_ms;
    let mut out = run_loops(&p, gpu, (rays, &p.soft, opts), runs, setup_ms)?;
    record_execution(&mut out.execution, p.wp.record(opts));
    Ok(out)
}

impl Pipeline for Rasterized<'_> {
    type Hard = HardVertices;
    type Soft = LoopRaster;
    const STATISTICS: Statistics = Statistics::All;
    const NOTE: &'static str = "fill, overdraw, shader invocations and culls from an \
        instrumented replay of the count and wedge passes' draws (depth test off, WGSL atomics; \
        with the stencil, shader invocations from the culled passes), in the cpu-model's terms; \
        mem_est.* estimated from counts and record sizes";

    fn hard(&self, rays: &EyeRays, lr: &LoopRun, quads: &[ShadowQuad]) -> HardVertices {
        let (counting, centre) = (self.opts.counting, lr.light.center());
        let (tris, caps) = hard_triangles(rays, quads, counting, &self.occluders, centre);
        HardVertices {
            buffer: self.hard.vertices(&tris),
            count: tris.len() as u32,
            eye_count: lr.eye_count,
            caps,
        }
    }

    fn hard_passes<'a>(&'a self, h: &'a HardVertices, first: bool) -> Vec<Pass<'a>> {
        let count = (self.hard).count_passes(&h.buffer, 0..h.count, h.eye_count);
        match first {
            true => [vec![self.hard.depth_pass()], count].concat(),
            false => count,
        }
    }

    /// The wedges' faces, the upload.
    fn soft(
        &self,
        rays: &EyeRays,
        lr: &LoopRun,
        q: &[ShadowQuad],
        w: &WedgeRecords,
        _: &HardVertices,
    ) -> LoopRaster {
        let (gpu, storage) = (self.gpu, wgpu::BufferUsages::STORAGE);
        let (vertices, wedge_vertices, halves) = self.wp.geometry(rays, w);
        let no_footprints = vec![None; q.len()];
        let quad_buf = gpu.upload("quads", &quad_records(rays, q, &no_footprints), storage);
        LoopRaster {
            wedge_vertices,
            group: self.soft.group(&lr.params, &quad_buf, w),
            wedge: gpu.upload("wedge vertices", &vertices, wgpu::BufferUsages::VERTEX),
            halves,
        }
    }

    /// The wedge passes, then the loop's V-buffer and combination.
    fn soft_passes<'a>(&'a self, l: &'a LoopRaster) -> Vec<Pass<'a>> {
        let mut passes = self.wp.passes(l, &self.hard.depth);
        let groups = [Some(&l.group), Some(&self.read_targets)];
        // The family's 8×8 tiles are the resolve's workgroups.
        passes.push(Pass::compute("resolve", &groups, &self.resolve, self.tiles));
        passes
    }

    /// The count pass's replay and `hard`'s estimated traffic as the cpu-model counts it: a
    /// depth read per fragment, the V-buffer (the stencil for the split format) read and
    /// written per passing fragment; the wedge pass's front faces with the counting pipeline
    /// (depth test off), and with the stencil the shaded fragments those the culled passes let
    /// through.
    fn replay<'a>(
        &'a self,
        h: &'a HardVertices,
        l: &'a LoopRaster,
        k: &mut Counters,
    ) -> Result<Replayed<'a>> {
        let (fill, passed) = self.hard.replay(&h.buffer, &[(0..h.count, h.eye_count)])?;
        let (target, count_bytes) = match self.wp.split {
            true => ("stencil", STENCIL_BYTES as f64),
            false => ("vbuffer", VBUFFER_BYTES as f64),
        };
        let reads = [
            ("depth", fill * DEPTH_BYTES as f64),
            (target, passed * count_bytes),
        ];
        k.add_traffic("mem_est", &reads, &[(target, passed * count_bytes)]);
        let (wp, depth) = (&self.wp, &self.hard.depth);
        let pass = l.pass(&wp.counting, &wp.vbuffers[0], depth, |_| true);
        let slots = replay_slots(self.gpu, &self.soft.stats, vec![pass])?;
        let shaded = wp.shaded(self.gpu, l, depth)?;
        let stat = Box::new(move |s: SoftStat| match (s, shaded) {
            (SoftStat::Inside, Some(n)) => n,
            _ => slots.get(s as usize),
        });
        hard_fill(k, self.opts.counting, fill, passed, h.caps);
        let index = (
            "wedge_vertices",
            VERTEX_BYTES as f64 * f64::from(l.wedge_vertices),
        );
        Ok(Replayed { index, stat })
    }
}
