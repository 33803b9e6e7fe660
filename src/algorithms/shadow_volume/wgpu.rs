//! The shadow-volume family's GPU base, shared by `soft_shadow_volume` and `accum_hard` on
//! wgpu: the records every pass reads (`records.wgsl`: eye rays, shadow quads, their tests) and
//! the hard pass with its bindings (`wgpu.wgsl`, [`HardPass`]):
//!
//! - the hard pass (III §3.2.1): shadow quads built on the host from a silhouette and binned to
//!   8×8 screen tiles on the host (sort-middle, as [`crate::algorithms::eye_raster::raster_pass`]
//!   bins them), then one invocation per pixel walks its tile's quads in submission order and
//!   counts z-pass from the eye's count ([`super::eye_count`]) into an i32 per pixel; with
//!   `counting: "z_fail"` (Paper II §5) it walks the faces of the capped volumes instead
//!   (sides, light and dark caps, built on the host by [`zfail_faces`]) and counts those at or
//!   behind the visible surface.
//!
//! The algorithms own the rest: `soft_shadow_volume` its soft pass, parameters, bindings and
//! counters; `accum_hard` its accumulation, which binds the hard pass's group 0 beside its own.
//! The hard pass's counters are 64-bit slots of the family's buffer ([`HardStat`]).

use glam::{Vec3, Vec4};

use super::{face_footprints, quad_footprints, zfail_faces, Counting, ShadowQuad, VolumeFace};
use crate::algorithms::eye_raster::{ConvexVolume, EyeRays, ScreenRect};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{gpu_struct, tiles, Bind, Compute, Layout, Pass, Program};
use crate::gpu::{Needs, Run, EMPTY_BYTES};
use crate::record::Counters;
use crate::scene::Mesh;

/// The records and geometry every pass of the family reads (no bindings).
pub(crate) const RECORDS_WGSL: &str = include_str!("records.wgsl");
/// The hard pass: its bindings (group 0), counters and entry; joined after [`RECORDS_WGSL`].
pub(crate) const WGSL: &str = include_str!("wgpu.wgsl");

/// Side of the screen tiles primitives are binned to (`TILE` and the workgroup in the WGSL).
pub(crate) const TILE: u32 = 8;
/// Storage buffers the hard pass binds (group 0, bindings 1-6).
pub(crate) const STORAGE_BUFFERS: u32 = 6;
/// Record sizes: an eye ray, a shadow quad, a word.
pub(crate) const RAY_BYTES: u64 = 48;
pub(crate) const QUAD_BYTES: u64 = 80;
/// A z-fail volume face: six vec4 (corners, normal, footprint) in the `faces` binding.
pub(crate) const FACE_BYTES: u64 = 96;
pub(crate) const WORD: u64 = 4;

/// The hard pass's statistics slots (`STAT_HARD_*` in the WGSL), in slot order.
#[derive(Clone, Copy)]
pub(crate) enum HardStat {
    Fill,
    Passed,
    Tests,
}

const STATS: u64 = 3;

gpu_struct! {
    /// The parameters of one hard pass (binding 0).
    pub(crate) struct HardParams as "HardParams" {
        /// The eye position.
        eye: [f32; 4] => "vec4f",
        width: u32 => "u32",
        height: u32 => "u32",
        tiles_x: u32 => "u32",
        /// The count a z-pass count starts from ([`super::eye_count`]).
        eye_count: i32 => "i32",
        /// 0: z-pass from `eye_count`, 1: z-fail over the capped volumes' faces in `faces`.
        counting: u32 => "u32",
        pad0: u32 => "u32",
        pad1: u32 => "u32",
        pad2: u32 => "u32",
    }
}

/// Checks the frame against the adapter's limits for the passes of algorithm `id`, which bind
/// `storage_buffers` storage buffers in one stage: those and the eye rays' bytes.
pub(crate) fn check_limits(gpu: &Run, frame: &Frame, id: &str, storage_buffers: u32) -> Result<()> {
    let needs = Needs {
        storage_buffers,
        buffers: &[("eye_rays", RAY_BYTES * frame.gbuffer.len() as u64)],
        ..Needs::default()
    };
    gpu.check_limits(id, needs)
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

/// The eye rays of `rays` uploaded as the WGSL reads them ([`ray_records`]).
pub(crate) fn upload_rays(gpu: &Run, rays: &EyeRays) -> wgpu::Buffer {
    gpu.upload("eye rays", &ray_records(rays), wgpu::BufferUsages::STORAGE)
}

/// A hard pass's `fill` and `overdraw` (the fragments that fail the depth test) in the
/// cpu-model's terms, from its `fill` and `passed` fragments, and counting z-fail the volumes'
/// `volume_caps`.
pub(crate) fn hard_fill(k: &mut Counters, counting: Counting, fill: f64, passed: f64, caps: u64) {
    k.add_fill(fill, fill - passed);
    if counting == Counting::ZFail {
        k.add(names::VOLUME_CAPS, caps as f64);
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

/// What the hard phase uploaded for one loop (or light sample): the hard pass's bind group
/// (group 0), the shadow quads (the soft pass binds them too) and the counts its counters need.
pub(crate) struct HardUpload {
    pub group: wgpu::BindGroup,
    pub quads: wgpu::Buffer,
    pub bin_entries: u64,
    pub caps: u64,
}

/// The family's hard pass over one frame: its bind-group layout (group 0, which an algorithm's
/// own pass may bind beside its own groups), its program and pipeline, and the per-pixel counts
/// and statistics it writes.
pub(crate) struct HardPass<'g> {
    pub gpu: &'g Run,
    pub counting: Counting,
    /// The eye rays ([`upload_rays`]), the hard counts (an i32 per pixel) and the hard pass's
    /// statistics slots ([`HardStat`]).
    pub rays: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    pub stats: wgpu::Buffer,
    pub layout: Layout,
    /// The hard pass (`INSTRUMENT` counting in the replay).
    hard: Compute,
    /// The workgroups of a pass over the image's 8×8 tiles.
    pub groups: (u32, u32),
    pub pixels: u64,
    /// The occluders, whose light-facing triangles cap the z-fail volumes.
    occluders: Mesh,
}

impl<'g> HardPass<'g> {
    /// The hard pass over `rays` (uploaded as `rays_buf`), counting as `counting`, the z-fail
    /// volumes capped by `occluders`.
    pub fn new(
        gpu: &'g Run,
        rays: &EyeRays,
        rays_buf: &wgpu::Buffer,
        counting: Counting,
        occluders: Mesh,
    ) -> HardPass<'g> {
        // Binding 0 the parameters, 1-4 what the pass reads, 5-6 what it writes.
        let binds: Vec<Bind> = (0..=STORAGE_BUFFERS)
            .map(|b| match b {
                0 => Bind::Uniform,
                1..=4 => Bind::ReadOnly,
                _ => Bind::ReadWrite,
            })
            .collect();
        let layout = Layout::new(gpu, "hard pass", wgpu::ShaderStages::COMPUTE, &binds);
        let program = Program::new(gpu, "shadow_volume/wgpu.wgsl", &SOURCES, &[Some(&layout)]);
        let pixels = rays.len() as u64;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        HardPass {
            hard: program.instrumented(gpu, "hard"),
            gpu,
            counting,
            rays: rays_buf.clone(),
            counts: gpu.storage_buffer("hard counts", WORD * pixels, copy),
            stats: gpu.storage_buffer("hard statistics", 2 * WORD * STATS, copy),
            layout,
            groups: tiles((rays.width, rays.height), TILE),
            pixels,
            occluders,
        }
    }

    /// The hard phase's host part for one light point `light` of `rays`, the z-pass count
    /// starting from `eye_count`: quads (and for z-fail the capped volumes' faces), footprints,
    /// bins, upload, the pass's group.
    pub fn upload_quads(
        &self,
        rays: &EyeRays,
        eye_count: i32,
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
        let params = HardParams {
            eye: rays.eye.extend(0.0).to_array(),
            width: rays.width,
            height: rays.height,
            tiles_x: rays.width.div_ceil(TILE),
            eye_count,
            counting: u32::from(self.counting == Counting::ZFail),
            ..HardParams::default()
        };
        let params = gpu.uniform("hard params", &params);
        let quads_buf = gpu.upload("shadow quads", &records, storage);
        let bins_buf = gpu.upload("quad bins", &quad_bins, storage);
        // Counting z-pass the pass reads no faces: the binding is empty.
        let faces_buf = match &faces {
            Some(f) => gpu.upload("volume faces", &face_records(rays, f), storage),
            None => gpu.storage_buffer("no faces", EMPTY_BYTES as u64, wgpu::BufferUsages::empty()),
        };
        let buffers = [
            &params,
            &self.rays,
            &quads_buf,
            &faces_buf,
            &bins_buf,
            &self.counts,
            &self.stats,
        ];
        let resources: Vec<_> = buffers.iter().map(|b| b.as_entire_binding()).collect();
        HardUpload {
            group: self.layout.group(gpu, "hard", &resources),
            quads: quads_buf,
            bin_entries: entries,
            caps: faces.map_or(0, |f| (f.len() - quads.len()) as u64),
        }
    }

    /// The hard pass of an upload.
    pub fn pass<'a>(&'a self, up: &'a HardUpload) -> Pass<'a> {
        Pass::compute("hard", &[Some(&up.group)], &self.hard, self.groups)
    }
}

/// The hard pass's shader as its pipeline joins it.
const SOURCES: [&str; 4] = [
    HardParams::WGSL,
    RECORDS_WGSL,
    WGSL,
    crate::scene::coverage::WGSL,
];

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(SOURCES => HardParams);
