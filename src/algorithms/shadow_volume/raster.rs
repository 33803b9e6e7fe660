//! The hard shadow-volume pass as the thesis rendered it, on a rasterizer (paper 001 III §3.2.1;
//! z-fail Paper II §5; `raster.wgsl`), and `accum_hard`'s accumulation by blending (III §5.1):
//!
//! 1. **depth pre-pass** (once per frame): a screen-covering triangle writes the eye's depth
//!    buffer (Depth32Float) from the frame's shaded points, projected by the same matrix as
//!    the volumes (an infinite, reversed-depth perspective: no far plane cuts the z-fail dark
//!    caps, and depth keeps its relative precision far away);
//! 2. **count pass** (per light point): the shadow quads (z-pass) or the capped volumes' faces
//!    (z-fail, [`zfail_faces`]) drawn as triangles with no depth write into a count target
//!    (R16Float, exact integers up to ±2048) cleared to the eye's count (z-pass,
//!    [`super::eye_count`]) or 0 (z-fail); each fragment passing the depth test adds its
//!    face's count change by additive blending: the stencil pass with increment and decrement
//!    as one float target, which a later pass can read as a texture ([`HardRaster::count`];
//!    pass 1 of `soft_shadow_volume`'s raster pipeline, `soft_shadow_volume::raster`); or, for
//!    `accum_hard` ([`DepthTarget::StencilCount`]), the stencil of a Depth32FloatStencil8 depth
//!    cleared to the eye's count, the faces of change +1 drawn incrementing and those of −1
//!    decrementing it (8 bits, wrapping), as the thesis' stencil shadow volumes;
//! 3. **accumulation** (`accum_hard`, per light point): a screen-covering triangle adds 1 where
//!    the count (or the stencil, by the stencil test) is 0 into an accumulation target (R16Float, exact up to 2048 ≥ the 1024
//!    samples allowed: the paper's 16-bit accumulation buffer) by additive blending; then
//!    **resolve** divides by the number of samples into the visibility buffer.
//!
//! **The depth test is made in the fragment shader** (`fs_quad`), along the pixel's own ray
//! to its shaded point, as the cpu executions make it ([`super::FaceFrom`]: where the ray
//! meets the face's plane, against the point's distance), not by the depth buffer at the
//! pixel's centre. The shaded point is moved off its surface (`GBuffer::shading_point`), so it
//! does not lie on the centre's ray, and the quad of a silhouette edge starts on the surface
//! beside that edge and runs along it within the offset: compared at the centre, a whole row of
//! pixels along the edge (a straight edge seen straight) changed its count for some light
//! samples. The eye's depth buffer is still written (the wedge pass of `soft_shadow_volume`
//! and the stencil share it).
//!
//! **Shared edges.** The quads are cut where their side lines reach [`dark_cap_distance`] from
//! the light ([`far_point`], as z-fail's volumes), so two quads through one silhouette vertex
//! share that side to the bit and the rasterizer's own tie rule covers a pixel along it once
//! (cut per quad at a distance beyond its edge, the two sides differed in rounding and pixels
//! along the line from the light through the vertex were counted twice or missed).
//!
//! **The silhouette edge.** A z-pass quad starts on the occluder's surface, so a pixel whose
//! centre lies just before the silhouette edge and whose shaded point just beyond it (or the
//! reverse) would change its count on every light sample: each quad is drawn a little past its
//! edge towards the light ([`SILHOUETTE_MARGIN`]) and the fragment shader decides the edge
//! itself for the pixel's ray under the one tie rule ([`crate::scene::coverage`]), as the cpu
//! does.
//!
//! How coverage still differs from the cpu executions' ray casting
//! ([`super::ShadowQuad::ray_hit`]): the rasterizer decides which faces cover a pixel at its
//! centre, by its own fixed-point top-left rule, where the cpu rays go through the shaded point
//! with the one tie rule of [`crate::scene::coverage`]; a pixel whose centre and shaded point
//! lie on two sides of a face's boundary (within the offset, a fraction of a pixel) can change
//! hands by one face. The near plane (at 1e-4 of the scene's diagonal) cuts what lies closer
//! to the eye; z-pass quads are cut on a sphere around the light, the cpu's run on (both count
//! the crossings in front of the scene bounds too, where a volume reaches out towards the
//! eye). The count change of a face is its vertices' `w` (the face's side of the eye,
//! computed on the host exactly as the cpu does) rather than the rasterizer's front/back
//! facing, which agrees with it for every face that covers a pixel.
//!
//! Fill and passed fragments come from an instrumented replay (the same draws with the depth
//! test off and WGSL atomics) in the cpu-model's terms: `fill` the fragments within the scene
//! bounds along the pixel's ray (z-fail: from the entry on) or passing the depth test,
//! `passed` those passing it (the same comparison of the same values the timed pipeline
//! makes).

use glam::{Mat4, Vec3};
use wgpu::CompareFunction::{Always, Equal};
use wgpu::StencilOperation::{DecrementWrap, IncrementWrap, Keep};

use super::wgpu::ray_records;
use super::{dark_cap_distance, far_point, zfail_faces, Counting, ShadowQuad};
use crate::algorithms::eye_raster::EyeRays;
use crate::error::Result;
use crate::gpu::pass::{
    gpu_struct, per_vertex, replay_slots, tiles, view, Bind, Compute, Draw, Instrumented, Layout,
    Onto, Pass, Program, Raster, Render, Stencil,
};
use crate::gpu::{additive_red, stencil_test, unwritten, Run};
use crate::scene::Mesh;

/// The WGSL of the passes.
const WGSL: &str = include_str!("raster.wgsl");
/// The count and accumulation targets' format.
const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;

gpu_struct! {
    /// The parameters of the raster hard pass (group 0, binding 0).
    pub(crate) struct RasterParams as "RasterParams" {
        /// The world-to-clip matrix's columns ([`eye_projection`]).
        vp0: [f32; 4] => "vec4f",
        vp1: [f32; 4] => "vec4f",
        vp2: [f32; 4] => "vec4f",
        vp3: [f32; 4] => "vec4f",
        /// The eye position.
        eye: [f32; 4] => "vec4f",
        width: u32 => "u32",
        height: u32 => "u32",
        /// The number of light samples averaged by `resolve`.
        samples: u32 => "u32",
        /// 0: z-pass, 1: z-fail.
        counting: u32 => "u32",
    }
}

/// The eye's world-to-clip matrix for `rays`: the camera's view with an infinite perspective of
/// reversed depth (near/z: 1 at the near plane, 0 at infinity), the near plane at 1e-4 of the
/// scene's diagonal. Pixel centres map to the directions of `Camera::ray_direction`.
pub fn eye_projection(rays: &EyeRays, camera: &crate::scene::camera::Camera) -> Mat4 {
    let view = crate::scene::camera::look_at(camera.eye, camera.target, camera.up);
    let aspect = rays.width as f32 / rays.height as f32;
    let near = 1e-4 * rays.bounds.diagonal().max(1e-3);
    glam::camera::rh::proj::directx::perspective_infinite_reverse(
        camera.fov_y_deg.to_radians(),
        aspect,
        near,
    ) * view
}

/// The triangles of a hard pass for light point `light`, as vertices ([`HardVertex`]): z-pass
/// the shadow quads cut where their side lines reach [`dark_cap_distance`] from the light
/// ([`far_point`], so two quads through one silhouette vertex share their side to the bit and
/// the rasterizer covers each pixel along it once), z-fail the faces of the capped volumes
/// ([`zfail_faces`]); and the number of cap faces.
pub fn hard_triangles(
    rays: &EyeRays,
    quads: &[ShadowQuad],
    counting: Counting,
    occluders: &Mesh,
    light: Vec3,
) -> (Vec<HardVertex>, u64) {
    let mut out = Vec::new();
    let eye = rays.eye;
    // A face's corners (a fan), its count change, its plane as `FaceFrom` sets it up and the
    // edge the fragment shader decides (`None`: the rasterizer decides every edge).
    let mut polygon = |corners: &[Vec3], step: f32, normal: Vec3, on: Vec3, edge: Option<_>| {
        let plane = normal.extend(normal.dot(on - eye)).to_array();
        let (p, q): (Vec3, Vec3) = edge.unwrap_or_default();
        let tested = f32::from(u8::from(edge.is_some()));
        for k in 1..corners.len() - 1 {
            for c in [corners[0], corners[k], corners[k + 1]] {
                out.push(HardVertex {
                    position: c.extend(step).to_array(),
                    plane,
                    edge_p: p.extend(tested).to_array(),
                    edge_q: q.extend(0.0).to_array(),
                });
            }
        }
    };
    match counting {
        Counting::ZPass => {
            let reach = dark_cap_distance(&rays.bounds, light);
            // How far towards the light a quad reaches past its silhouette edge.
            let past = SILHOUETTE_MARGIN * rays.bounds.diagonal();
            for q in quads {
                let far = |v| far_point(q.light, v, reach);
                let near = |v: Vec3| {
                    let to_light = q.light - v;
                    let s = (past / to_light.length().max(1e-20)).clamp(1e-3, 0.5);
                    v + to_light * s
                };
                let corners = [near(q.a), near(q.b), far(q.b), far(q.a)];
                // The quad's boundary edge `b → a` (`ShadowQuad::from`).
                let edge = Some((q.b, q.a));
                polygon(&corners, q.side(eye), q.normal, q.light, edge);
            }
            (out, 0)
        }
        Counting::ZFail => {
            let faces = zfail_faces(quads, occluders, light, &rays.bounds);
            for f in &faces {
                let corners = &f.corners[..f.sides as usize];
                polygon(corners, -f.side(eye), f.normal, f.corners[0], None);
            }
            let caps = (faces.len() - quads.len()) as u64;
            (out, caps)
        }
    }
}

/// A vertex of a hard pass's triangles: the corner (xyz) with the face's count change (w); the
/// face's plane as the cpu's ray test sets it up from the eye `o` ([`super::FaceFrom`]): the
/// normal (xyz) and `normal · (corner − o)` (w), so that the fragment shader finds where the
/// pixel's own ray meets the face as the cpu does; and the boundary edge `p → q` the shader
/// tests under the one tie rule (`edge_p.w` 1; 0 where the rasterizer decides every edge).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct HardVertex {
    pub position: [f32; 4],
    pub plane: [f32; 4],
    pub edge_p: [f32; 4],
    pub edge_q: [f32; 4],
}

/// How far, as a fraction of the scene's diagonal, a z-pass quad is drawn past its silhouette
/// edge towards the light (at least 1e-3 and at most half of the way to the light): 8 times
/// the shaded points' offset off their surfaces (`frame::offset_point`, 1e-4 of the diagonal),
/// so that every pixel whose ray through its shaded point crosses the quad beside the edge has
/// a fragment, and the shader decides the edge.
const SILHOUETTE_MARGIN: f32 = 8e-4;

/// The eye's depth target of a [`HardRaster`], and where its count pass counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DepthTarget {
    /// Depth32Float; the count in the count target.
    Depth,
    /// Depth32FloatStencil8, its stencil left to a later pass (`soft_shadow_volume`'s
    /// wedge-half culling); the count in the count target.
    DepthStencil,
    /// Depth32FloatStencil8; the count pass in the stencil as the thesis' stencil shadow
    /// volumes (increment and decrement with wrap-around, 8 bits: a count that is a non-zero
    /// multiple of 256 reads as 0), cleared to the eye's count; the accumulation adds the
    /// pixels whose stencil is 0 (`accum_hard`, III §5.1).
    StencilCount,
}

impl DepthTarget {
    /// The accumulation's target on `gpu`: the stencil where the adapter has the combined
    /// format, else the count target.
    pub fn for_accumulation(gpu: &Run) -> DepthTarget {
        match gpu.depth32_stencil8 {
            true => DepthTarget::StencilCount,
            false => DepthTarget::Depth,
        }
    }

    pub fn format(self) -> wgpu::TextureFormat {
        match self {
            DepthTarget::Depth => wgpu::TextureFormat::Depth32Float,
            _ => wgpu::TextureFormat::Depth32FloatStencil8,
        }
    }

    /// What the count pass counts into, for the record (`execution.hard_count`).
    pub fn describe(self) -> &'static str {
        match self {
            DepthTarget::StencilCount => {
                "8-bit stencil, increment and decrement with wrap-around (III §3.2.1)"
            }
            _ => "R16Float count target by additive blending",
        }
    }
}

/// The textures, bind groups and pipelines of the raster hard pass over one frame, created once
/// and reused for every light point.
pub(crate) struct HardRaster<'g> {
    gpu: &'g Run,
    size: (u32, u32),
    /// 64-bit fill and passed counters of the instrumented replay.
    /// The replay's fill and passed fragments (two 64-bit slots).
    pub stats: wgpu::Buffer,
    /// The average over the samples, per pixel (f32), after `resolve`.
    pub visibility: wgpu::Buffer,
    /// The eye's depth (reversed), written by the depth pre-pass.
    pub depth: wgpu::TextureView,
    /// The count target: per pixel the number of shadow volumes its point lies in.
    pub count: wgpu::TextureView,
    accumulation: wgpu::TextureView,
    group: wgpu::BindGroup,
    /// Group 1 reading the count (accumulation pass), or the accumulation (other passes).
    read_count: wgpu::BindGroup,
    read_accumulation: wgpu::BindGroup,
    /// The depth pre-pass, in the timed run and the replay.
    depth_pipeline: Render,
    /// The count pass into the count target, counting in the replay (`INSTRUMENT` on); with
    /// the stencil it is the replay's only (the timed run counts in the stencil).
    quad: [Render; 1],
    accumulate: [Render; 1],
    /// Counting in the stencil ([`DepthTarget::StencilCount`]): the pipelines incrementing for
    /// the faces of count change +1 and decrementing for −1, and the accumulation of the
    /// pixels whose stencil is 0 (timed only).
    stencil: Option<([Render; 2], [Render; 1])>,
    resolve: Compute,
}

impl<'g> HardRaster<'g> {
    /// The passes over `rays` seen by `camera`, counting as `counting`, averaging `samples`
    /// light points, with the eye's depth in `target`.
    pub fn new(
        gpu: &'g Run,
        rays: &EyeRays,
        camera: &crate::scene::camera::Camera,
        counting: Counting,
        samples: u32,
        target: DepthTarget,
    ) -> HardRaster<'g> {
        let depth_format = target.format();
        let size = (rays.width, rays.height);
        let cols = eye_projection(rays, camera).to_cols_array_2d();
        let params = RasterParams {
            vp0: cols[0],
            vp1: cols[1],
            vp2: cols[2],
            vp3: cols[3],
            eye: rays.eye.extend(0.0).to_array(),
            width: size.0,
            height: size.1,
            samples,
            counting: u32::from(counting == Counting::ZFail),
        };
        let params = gpu.uniform("raster params", &params);
        let storage = wgpu::BufferUsages::STORAGE;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let rays_buf = gpu.upload("eye rays", &ray_records(rays), storage);
        let stats = gpu.storage_buffer("raster statistics", 16, copy);
        let visibility = gpu.storage_buffer("visibility", 4 * rays.len() as u64, copy);
        let stages = wgpu::ShaderStages::VERTEX_FRAGMENT | wgpu::ShaderStages::COMPUTE;
        let binds = [
            (Bind::Uniform, params.as_entire_binding()),
            (Bind::ReadOnly, rays_buf.as_entire_binding()),
            (Bind::ReadWrite, stats.as_entire_binding()),
            (Bind::ReadWrite, visibility.as_entire_binding()),
        ];
        let (layout0, group) = Layout::bound(gpu, "raster hard", stages, &binds);
        let layout1 = Layout::new(gpu, "raster target", stages, &[Bind::Float]);
        let program = Program::new(
            gpu,
            "shadow_volume/raster.wgsl",
            &[RasterParams::WGSL, crate::scene::coverage::WGSL, WGSL],
            &[Some(&layout0), Some(&layout1)],
        );
        let depth = gpu.target_view("eye depth", size, depth_format);
        let count = gpu.target_view("count", size, TARGET_FORMAT);
        let accumulation = gpu.target_view("accumulation", size, TARGET_FORMAT);
        let blend = Some(additive_red(TARGET_FORMAT));
        // A vertex: position and the count change, the face's plane.
        let attributes = wgpu::vertex_attr_array![
            0 => Float32x4, 1 => Float32x4, 2 => Float32x4, 3 => Float32x4
        ];
        // The count passes: every fragment of a face reaches the fragment shader, which makes
        // the depth test along the pixel's own ray (`fs_quad`); the eye's depth is left as is.
        let count_pipeline = |vs, stencil, color, instrument| {
            let r = Raster {
                vs,
                fs: "fs_quad",
                vertex: per_vertex(&attributes),
                depth: Some(Always),
                depth_format,
                stencil,
                depth_write: false,
                color,
                instrument: Some(instrument),
                ..Raster::default()
            };
            program.render(gpu, &r)
        };
        let quad =
            |instrument| count_pipeline("vs_quad", Default::default(), blend.clone(), instrument);
        // The screen-covering passes: the depth pre-pass, the accumulation of the lit pixels.
        let full = Raster {
            vs: "vs_full",
            fs: "fs_depth",
            depth: Some(Always),
            depth_format,
            ..Raster::default()
        };
        let stencil = (target == DepthTarget::StencilCount).then(|| {
            let unwritten = Some(unwritten(TARGET_FORMAT));
            let counted = |vs, op| {
                count_pipeline(vs, stencil_test(Always, op, Keep), unwritten.clone(), false)
            };
            let lit = Raster {
                fs: "fs_lit",
                stencil: stencil_test(Equal, Keep, Keep),
                depth_write: false,
                color: blend.clone(),
                ..full.clone()
            };
            (
                [
                    counted("vs_quad_up", IncrementWrap),
                    counted("vs_quad_down", DecrementWrap),
                ]
                .map(Instrumented::timed),
                [Instrumented::timed(program.render(gpu, &lit))],
            )
        });
        let accumulate = Raster {
            vs: "vs_full",
            fs: "fs_accumulate",
            depth: None,
            color: blend.clone(),
            ..Raster::default()
        };
        HardRaster {
            depth_pipeline: Instrumented::both(program.render(gpu, &full)),
            quad: [Instrumented {
                timed: stencil.is_none().then(|| quad(false)),
                counting: Some(quad(true)),
            }],
            stencil,
            accumulate: [Instrumented::timed(program.render(gpu, &accumulate))],
            resolve: Instrumented::timed(program.compute(gpu, "resolve", None)),
            read_count: layout1.group(gpu, "read count", &[view(&count)]),
            read_accumulation: layout1.group(gpu, "read accumulation", &[view(&accumulation)]),
            gpu,
            size,
            stats,
            visibility,
            depth,
            count,
            accumulation,
            group,
        }
    }

    /// The vertex buffer of `vertices` ([`hard_triangles`], every light point's in one).
    pub fn vertices(&self, vertices: &[HardVertex]) -> wgpu::Buffer {
        self.gpu.upload(
            "shadow volume vertices",
            vertices,
            wgpu::BufferUsages::VERTEX,
        )
    }

    /// The bind groups of a pass: group 0, and group 1 reading the count or the accumulation.
    fn groups(&self, read_count: bool) -> [Option<&wgpu::BindGroup>; 2] {
        let read = match read_count {
            true => &self.read_count,
            false => &self.read_accumulation,
        };
        [Some(&self.group), Some(read)]
    }

    /// The depth pre-pass.
    pub fn depth_pass(&self) -> Pass<'_> {
        let draw = Draw {
            depth: Some(&self.depth),
            ..Draw::of(&self.depth_pipeline, 3)
        };
        Pass::draw("eye depth", &self.groups(false), draw)
    }

    /// The count pass of the triangles `range` of `vertices`, from `eye_count` (z-pass; 0 for
    /// z-fail): into the count target (timed and counting), or with the stencil the timed run's
    /// count in the stencil and the replay's into the count target.
    pub fn count_passes<'a>(
        &'a self,
        vertices: &'a wgpu::Buffer,
        range: std::ops::Range<u32>,
        eye_count: i32,
    ) -> Vec<Pass<'a>> {
        let pass = |pipelines, draws, stencil, clear| {
            let onto = Onto {
                depth: Some(&self.depth),
                stencil,
                vertices: Some(vertices),
                ..Onto::new(pipelines, draws, &self.count, clear)
            };
            Pass::onto("hard", &self.groups(false), onto)
        };
        let mut passes = Vec::new();
        if let Some((quads, _)) = &self.stencil {
            let stencil = Stencil::Clear(eye_count.rem_euclid(256) as u32);
            let draws = vec![(0, range.clone(), 0), (1, range.clone(), 0)];
            passes.push(pass(&quads[..], draws, stencil, None));
        }
        let clear = Some(f64::from(eye_count));
        passes.push(pass(
            &self.quad[..],
            vec![(0, range, 0)],
            Stencil::Off,
            clear,
        ));
        passes
    }

    /// The accumulation of the lit pixels of the last count pass; `first` clears the
    /// accumulation first.
    pub fn accumulate_pass(&self, first: bool) -> Pass<'_> {
        let (pipelines, depth, stencil) = match &self.stencil {
            Some((_, lit)) => (&lit[..], Some(&self.depth), Stencil::Keep),
            None => (&self.accumulate[..], None, Stencil::Off),
        };
        let clear = first.then_some(0.0);
        let onto = Onto {
            depth,
            stencil,
            ..Onto::new(pipelines, vec![(0, 0..3, 0)], &self.accumulation, clear)
        };
        Pass::onto("accumulate", &self.groups(true), onto)
    }

    /// The average over the samples into [`HardRaster::visibility`].
    pub fn resolve_pass(&self) -> Pass<'_> {
        Pass::compute(
            "resolve",
            &self.groups(false),
            &self.resolve,
            tiles(self.size, 8),
        )
    }

    /// Runs the depth pre-pass and the instrumented count passes of `ranges` (with their eye
    /// counts) and returns the fill and passed fragments.
    pub fn replay(
        &self,
        vertices: &wgpu::Buffer,
        ranges: &[(std::ops::Range<u32>, i32)],
    ) -> Result<(f64, f64)> {
        let mut passes = vec![self.depth_pass()];
        for (r, eye) in ranges {
            passes.extend(self.count_passes(vertices, r.clone(), *eye));
        }
        let slots = replay_slots(self.gpu, &self.stats, passes)?;
        Ok((slots.get(0), slots.get(1)))
    }
}

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(
    [RasterParams::WGSL, crate::scene::coverage::WGSL, WGSL] => RasterParams
);
