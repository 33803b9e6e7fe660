//! The shadow-volume family's GPU passes, shared by `soft_shadow_volume` and `accum_hard` on
//! wgpu (`wgpu.wgsl`; `soft_shadow_volume` joins its `soft` pass after it):
//!
//! - the frame's eye rays and per-pixel buffers ([`FrameResources`]);
//! - the hard pass (III §3.2.1): shadow quads built on the host from a silhouette and binned to
//!   8×8 screen tiles on the host (sort-middle, as [`crate::algorithms::eye_raster::raster_pass`]
//!   bins them), then one invocation per pixel walks its tile's quads in submission order and
//!   counts z-pass from the eye's count ([`super::eye_count`]) into an i32 V-buffer; with
//!   `counting: "z_fail"` (Paper II §5) it walks the faces of the capped volumes instead
//!   (sides, light and dark caps, built on the host by [`zfail_faces`]) and counts those at or
//!   behind the visible surface;
//! - `accum_hard`'s accumulation of one light sample's lit pixels (`accumulate`).
//!
//! The counters of the instrumented replay are 64-bit slots of one buffer ([`Stat`]).

use glam::{Vec3, Vec4};

use super::{face_footprints, quad_footprints, zfail_faces, Counting, ShadowQuad, VolumeFace};
use crate::algorithms::eye_raster::{ConvexVolume, EyeRays, ScreenRect};
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, replay_slots, tiles, Bind, Compute, Instrumented, Layout, Pass, Program,
};
use crate::gpu::{Needs, Run, EMPTY_BYTES};
use crate::record::Counters;
use crate::scene::Mesh;

/// The family's WGSL: parameters, bindings, the hard pass, the accumulation.
pub(crate) const WGSL: &str = include_str!("wgpu.wgsl");

/// Side of the screen tiles primitives are binned to (`TILE` and the workgroup in the WGSL).
pub(crate) const TILE: u32 = 8;
/// Storage buffers bound (bindings 1-12).
pub(crate) const STORAGE_BUFFERS: u32 = 12;
/// Record sizes: an eye ray, a shadow quad, a wedge primitive, a plane, a word.
pub(crate) const RAY_BYTES: u64 = 48;
pub(crate) const QUAD_BYTES: u64 = 80;
/// A z-fail volume face: six vec4 (corners, normal, footprint) in the `planes` binding.
pub(crate) const FACE_BYTES: u64 = 96;
pub(crate) const PRIM_BYTES: u64 = 32;
pub(crate) const PLANE_BYTES: u64 = 16;
pub(crate) const WORD: u64 = 4;
/// Bytes per pixel of the V-buffer (f32, or one rgba8 buffer of the split pair) and of the
/// stencil the wedge-half culling of IV §4.4 uses on a rasterizer.
pub(crate) const VBUFFER_BYTES: u64 = 4;
pub(crate) const STENCIL_BYTES: u64 = 1;

/// The statistics slots of the instrumented pipelines (`STAT_*` in the WGSL), in slot order.
#[derive(Clone, Copy)]
pub(crate) enum Stat {
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

pub(crate) const STATS: u64 = 9;

gpu_struct! {
    /// The parameters of one pass (binding 0).
    pub(crate) struct Params as "Params" {
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
        eye_count: i32 => "i32",
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
        /// 0: z-pass from `eye_count`, 1: z-fail over the capped volumes' faces in `planes`.
        counting: u32 => "u32",
        /// 3 for a textured light (RGB coverage texture, one f32 per channel), else 1.
        channels: u32 => "u32",
        pad1: u32 => "u32",
        pad2: u32 => "u32",
        /// The textured light's mean colour (`LightTexture::mean`).
        mean: [f32; 4] => "vec4f",
    }
}

impl Params {
    /// What every pass over `rays` for light `s` of `n` (sub-light or light sample) counting as
    /// `counting` shares; the rest zero but one channel of white light.
    pub fn of_light(rays: &EyeRays, s: usize, n: usize, counting: Counting) -> Params {
        Params {
            eye: rays.eye.extend(0.0).to_array(),
            width: rays.width,
            height: rays.height,
            tiles_x: rays.width.div_ceil(TILE),
            first_light: u32::from(s == 0),
            last_light: u32::from(s + 1 == n),
            sub_lights: n as u32,
            counting: u32::from(counting == Counting::ZFail),
            channels: 1,
            mean: [1.0; 4],
            ..Params::default()
        }
    }
}

/// Checks the frame against the adapter's limits for the passes of algorithm `id`: the storage
/// buffers bound and the eye rays' bytes.
pub(crate) fn check_limits(gpu: &Run, frame: &Frame, id: &str) -> Result<()> {
    let needs = Needs {
        storage_buffers: STORAGE_BUFFERS,
        buffers: &[("eye_rays", RAY_BYTES * frame.gbuffer.len() as u64)],
        ..Needs::default()
    };
    gpu.check_limits(id, needs)
}

/// Eye-sized buffers shared by every loop.
pub(crate) struct FrameResources {
    pub rays: wgpu::Buffer,
    pub texels: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    pub covered: wgpu::Buffer,
    pub visibility: wgpu::Buffer,
    pub stats: wgpu::Buffer,
    /// Light received per channel (3 words a pixel) under a textured light, else one word.
    pub rgb: wgpu::Buffer,
    /// 3 for a textured light, else 1.
    pub channels: u32,
}

/// Infinite and NaN parameters become the largest finite ones (WGSL has no infinities).
fn finite(t: f32) -> f32 {
    if t.is_nan() {
        f32::MAX
    } else {
        t.clamp(-f32::MAX, f32::MAX)
    }
}

/// The eye rays as the WGSL reads them (`Ray`, 48 bytes a pixel): direction and depth; shaded
/// point and the bounds entry t0; the bounds exit t1 and 1 where the pixel has a surface.
pub(crate) fn ray_records(rays: &EyeRays) -> Vec<[f32; 12]> {
    (0..rays.len())
        .map(|i| {
            let (t0, t1) = rays.bounds_interval(i);
            let hit = if rays.is_hit(i) { 1.0 } else { 0.0 };
            let record = [
                rays.dir[i].extend(finite(rays.depth[i])),
                rays.point[i].extend(finite(t0)),
                Vec4::new(finite(t1), hit, 0.0, 0.0),
            ];
            bytemuck::cast(record.map(|v| v.to_array()))
        })
        .collect()
}

impl FrameResources {
    /// The buffers of `rays`, with a coverage texture's `texels` (none: empty) and, when
    /// `textured`, an RGB buffer of three words a pixel.
    pub fn new(gpu: &Run, rays: &EyeRays, texels: &[u8], textured: bool) -> FrameResources {
        let storage = wgpu::BufferUsages::STORAGE;
        let records = ray_records(rays);
        // The texels four to a little-endian word, as the WGSL reads them.
        let mut packed = texels.to_vec();
        packed.resize(texels.len().div_ceil(4) * 4, 0);
        let pixels = rays.len() as u64;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        FrameResources {
            rays: gpu.upload("eye rays", &records, storage),
            texels: gpu.upload("coverage texture", &packed, storage),
            counts: gpu.storage_buffer("hard counts", WORD * pixels, copy),
            covered: gpu.storage_buffer("covered", WORD * pixels, copy),
            visibility: gpu.storage_buffer("visibility", WORD * pixels, copy),
            stats: gpu.storage_buffer("statistics", 2 * WORD * STATS, copy),
            rgb: gpu.storage_buffer("rgb", if textured { 3 * WORD * pixels } else { WORD }, copy),
            channels: if textured { 3 } else { 1 },
        }
    }
}

/// A hard pass's `fill` and `overdraw` (the fragments that fail the depth test) in the
/// cpu-model's terms, from its `fill` and `passed` fragments, and counting z-fail the volumes'
/// `volume_caps`.
pub(crate) fn hard_fill(k: &mut Counters, counting: Counting, fill: f64, passed: f64, caps: u64) {
    k.add_fill(fill, fill - passed);
    if counting == Counting::ZFail {
        k.add("volume_caps", caps as f64);
    }
}

/// Per tile a `[start, end)` pair into the same array, then the primitive indices in
/// submission order (those `keep(primitive, tile)` lets through); and the number of entries.
pub(crate) fn bins(
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
pub(crate) fn tile_cones(rays: &EyeRays) -> Vec<(Vec3, f32)> {
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
pub(crate) fn tile_misses(volume: &ConvexVolume, eye: Vec3, cone: (Vec3, f32)) -> bool {
    let (axis, sin) = cone;
    volume.planes.iter().any(|&(n, d)| {
        let len = n.length();
        n.dot(eye) - d > 1e-4 * (1.0 + d.abs()) && n.dot(axis) >= (sin + 1e-4) * len
    })
}

/// A footprint as the WGSL reads it: x0 y0 x1 y1 (zeros without one).
pub(crate) fn rect(f: &Option<ScreenRect>) -> [u32; 4] {
    f.map_or([0; 4], |r| [r.x0, r.y0, r.x1, r.y1])
}

/// A primitive record as the WGSL reads it: the bits of `vectors` (a vec4 each), then the
/// footprint ([`rect`]) in the last four words; `N` words in all.
pub(crate) fn record<const N: usize>(
    vectors: impl IntoIterator<Item = Vec4>,
    footprint: &Option<ScreenRect>,
) -> [u32; N] {
    let mut w = [0u32; N];
    for (k, v) in vectors.into_iter().enumerate() {
        w[4 * k..4 * k + 4].copy_from_slice(&v.to_array().map(f32::to_bits));
    }
    w[N - 4..].copy_from_slice(&rect(footprint));
    w
}

/// The z-fail faces as the WGSL reads them from the `planes` binding: six vec4 per face, the
/// four corners (w of the first: the count change of a passing fragment, minus the eye's side;
/// w of the second: the number of corners), the outward normal and the footprint's bits.
fn face_records(rays: &EyeRays, faces: &[VolumeFace]) -> Vec<[u32; 24]> {
    faces
        .iter()
        .zip(face_footprints(rays, faces))
        .map(|(f, fp)| {
            let ws = [-f.side(rays.eye), f.sides as f32, 0.0, 0.0, 0.0];
            let vectors = f.corners.iter().chain([&f.normal]).zip(ws);
            record(vectors.map(|(c, w)| c.extend(w)), &fp)
        })
        .collect()
}

/// The shadow quads as the WGSL reads them (`Quad`, 80 bytes): a with the eye's side, b, the
/// light point, the normal, and the footprint `footprints` gives.
pub(crate) fn quad_records(
    rays: &EyeRays,
    quads: &[ShadowQuad],
    footprints: &[Option<ScreenRect>],
) -> Vec<[u32; 20]> {
    quads
        .iter()
        .zip(footprints)
        .map(|(q, f)| {
            let a = q.a.extend(q.side(rays.eye));
            let rest = [q.b, q.light, q.normal].map(|v| v.extend(0.0));
            record(std::iter::once(a).chain(rest), f)
        })
        .collect()
}

/// What the hard phase uploaded for one loop: the hard pass's bind group, the params, quads and
/// bins buffers the soft pass binds too, and the counts its counters need.
pub(crate) struct HardUpload {
    pub group: wgpu::BindGroup,
    pub buffers: [wgpu::Buffer; 3],
    pub bin_entries: u64,
    pub caps: u64,
}

/// The family's passes over one frame: the bind-group layout of every pass, the program
/// (the family's WGSL, an algorithm's, the coverage rule) and the hard and accumulate
/// pipelines.
pub(crate) struct VolumePasses<'g> {
    pub gpu: &'g Run,
    pub counting: Counting,
    pub res: FrameResources,
    /// Group 0 of every pass, visible to compute and fragment shaders (the raster wedge pass
    /// of `soft_shadow_volume` binds it too).
    pub layout: Layout,
    pub program: Program,
    /// The hard pass (`INSTRUMENT` counting in the replay).
    hard: Compute,
    /// Timed only.
    accumulate: Compute,
    pub groups: (u32, u32),
    pub pixels: u64,
    /// The occluders, whose light-facing triangles cap the z-fail volumes.
    occluders: Mesh,
}

impl<'g> VolumePasses<'g> {
    /// The passes over `rays` with `res`, counting as `counting`; `wgsl` is joined after the
    /// family's WGSL (an algorithm's own entries).
    pub fn new(
        gpu: &'g Run,
        rays: &EyeRays,
        counting: Counting,
        res: FrameResources,
        occluders: Mesh,
        wgsl: &str,
    ) -> VolumePasses<'g> {
        // Binding 0 the parameters, 1-7 what the passes read, 8-12 what they write.
        let binds: Vec<Bind> = (0..=STORAGE_BUFFERS)
            .map(|b| match b {
                0 => Bind::Uniform,
                1..=7 => Bind::ReadOnly,
                _ => Bind::ReadWrite,
            })
            .collect();
        let stages = wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT;
        let layout = Layout::new(gpu, "shadow volumes", stages, &binds);
        let sources = [Params::WGSL, WGSL, wgsl, crate::scene::coverage::WGSL];
        let program = Program::new(gpu, "shadow_volume/wgpu.wgsl", &sources, &[Some(&layout)]);
        VolumePasses {
            hard: program.instrumented(gpu, "hard"),
            accumulate: Instrumented::timed(program.compute(gpu, "accumulate", Some(false))),
            gpu,
            counting,
            res,
            layout,
            program,
            groups: tiles((rays.width, rays.height), TILE),
            pixels: rays.len() as u64,
            occluders,
        }
    }

    /// The bind group of one pass: `params`, then the primitives (quads, wedge primitives,
    /// planes or z-fail faces, quad bins, wedge bins).
    pub fn group(
        &self,
        params: &wgpu::Buffer,
        prims: [&wgpu::Buffer; 5],
        label: &str,
    ) -> wgpu::BindGroup {
        let r = &self.res;
        let buffers = [params, &r.rays].into_iter().chain(prims).chain([
            &r.texels,
            &r.counts,
            &r.covered,
            &r.visibility,
            &r.stats,
            &r.rgb,
        ]);
        let resources: Vec<_> = buffers.map(|b| b.as_entire_binding()).collect();
        self.layout.group(self.gpu, label, &resources)
    }

    /// The hard phase's host part: quads (and for z-fail the capped volumes' faces from light
    /// point `light`), footprints, bins, upload.
    pub fn upload_quads(
        &self,
        rays: &EyeRays,
        params: &Params,
        light: Vec3,
        quads: &[ShadowQuad],
    ) -> HardUpload {
        let gpu = self.gpu;
        let storage = wgpu::BufferUsages::STORAGE;
        let footprints = quad_footprints(rays, quads);
        let records = quad_records(rays, quads, &footprints);
        let faces = (self.counting == Counting::ZFail)
            .then(|| zfail_faces(quads, &self.occluders, light, &rays.bounds));
        let face_prints = faces.as_ref().map(|f| face_footprints(rays, f));
        let prints = face_prints.as_ref().unwrap_or(&footprints);
        let (quad_bins, entries) = bins(rays, prints, |_, _| true);
        let params = gpu.uniform("ssv params", params);
        let quads_buf = gpu.upload("shadow quads", &records, storage);
        let bins_buf = gpu.upload("quad bins", &quad_bins, storage);
        let empty = wgpu::BufferUsages::empty();
        let none = gpu.storage_buffer("no primitives", EMPTY_BYTES as u64, empty);
        let faces_buf =
            (faces.as_ref()).map(|f| gpu.upload("volume faces", &face_records(rays, f), storage));
        let planes = faces_buf.as_ref().unwrap_or(&none);
        let group = self.group(
            &params,
            [&quads_buf, &none, planes, &bins_buf, &none],
            "hard",
        );
        HardUpload {
            group,
            buffers: [params, quads_buf, bins_buf],
            bin_entries: entries,
            caps: faces.map_or(0, |f| (f.len() - quads.len()) as u64),
        }
    }

    /// A pass of `pipeline` over the image's tiles with `group`.
    pub fn pass<'a>(
        &'a self,
        label: &'a str,
        pipeline: &'a Compute,
        group: &'a wgpu::BindGroup,
    ) -> Pass<'a> {
        Pass::compute(label, &[Some(group)], pipeline, self.groups)
    }

    /// The hard pass of an upload.
    pub fn hard<'a>(&'a self, up: &'a HardUpload) -> Pass<'a> {
        self.pass("hard", &self.hard, &up.group)
    }

    /// `accum_hard`'s accumulation of a sample's lit pixels.
    pub fn accumulate<'a>(&'a self, up: &'a HardUpload) -> Pass<'a> {
        self.pass("accumulate", &self.accumulate, &up.group)
    }

    /// Runs `passes` as an instrumented replay (statistics cleared before, read after) and
    /// returns the statistics' reader.
    pub fn replay(&self, passes: Vec<Pass>) -> Result<impl Fn(Stat) -> f64> {
        let slot = replay_slots(self.gpu, &self.res.stats, passes)?;
        Ok(move |s: Stat| slot.get(s as usize))
    }
}

// `Params` against the family's WGSL as the pipelines join it: alone (`accum_hard`) and with
// `soft_shadow_volume`'s soft pass.
#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(
    [Params::WGSL, WGSL, "", crate::scene::coverage::WGSL],
    [
        Params::WGSL,
        WGSL,
        include_str!("../soft_shadow_volume/wgpu.wgsl"),
        crate::scene::coverage::WGSL
    ] => Params
);
