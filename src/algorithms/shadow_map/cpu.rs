//! The shadow-map family's passes on the CPU executions (`cpu-native`, `cpu-model`): the light
//! pass on the sort-middle rasterizer, and the eye pass in 16-lane blocks. The eye pass is
//! generic over a [`Lookup`] (`hard_shadow_map`'s hard test, `pcss`, `penumbra_map`,
//! `dbuffer`), which reuse the light pass and the receiver setup unchanged.

use glam::{Vec2, Vec3};

use super::texel;
use super::Phase;
use super::{
    assemble_casters, Bias, CasterBuffers, CastersPart, FaceView, LightView, LightViews, ViewFit,
    FAN_TRIANGLES_MAX, FAN_VERTICES_MAX,
};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{eye_lookup_step, eye_tiles, machine, output, EyeBlock, EyeKernel};
use crate::counters::names;
use crate::frame::Frame;
use crate::model::raster::{self, DepthOnly, Geometry, Pipeline, Surface, Target, BLOCK};
use crate::model::{
    task_items, task_weights, Buffer, Lanes, Machine, Mask, Probe, TaskKernel, LANES,
};
use crate::record::PhaseId;
use crate::scene::Mesh;
use crate::visibility::VisibilityBuffer;

/// A rasterized shadow map and the view it was rasterized from.
pub struct ShadowMap {
    pub view: LightView,
    /// Which receivers the map shades (a single frustum, or one cube face).
    pub face: FaceView,
    pub map: Surface,
}

/// Phase `light_raster` (`light_raster[+x]` per cube face): NDC depth of every triangle of
/// `occluders` (the scene's occluder objects) that meets `face`'s frustum, nearest kept.
pub fn light_raster(
    m: &mut Machine,
    frame: &Frame,
    face: &FaceView,
    occluders: &Mesh,
) -> ShadowMap {
    m.phase(&face.phase(Phase::LightRaster.name()));
    let mesh = casters(m, &face.view, occluders);
    raster_shadow_map(m, frame, face, mesh)
}

/// Triangles per task of the `casters` step.
const CASTER_CHUNK: usize = 1024;

/// The `casters` step: [`LightView::casters_part`] over chunks of the scene's triangles.
struct Casters<'a> {
    view: &'a LightView,
    mesh: &'a Mesh,
    buffers: CasterBuffers,
}

impl TaskKernel for Casters<'_> {
    type Out = CastersPart;

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> CastersPart {
        let range = task_items(task, CASTER_CHUNK, self.mesh.triangles.len());
        self.view
            .casters_part(p, self.mesh, Some(&self.buffers), range)
    }
}

/// Step `casters` of the current phase: the light pass's draw list for `mesh` in `view`
/// ([`LightView::casters`]: triangles outside the frustum culled, those reaching nearer the
/// light than the near plane clipped to it), [`CASTER_CHUNK`] triangles a task; counts
/// `casters.triangles` (the draw list's triangles).
pub fn casters(m: &mut Machine, view: &LightView, mesh: &Mesh) -> Mesh {
    let n = mesh.triangles.len();
    let tri_bytes = size_of::<[u32; 3]>() as u64;
    let vertex_bytes = size_of::<Vec3>() as u64;
    let buffers = CasterBuffers {
        positions: m
            .memory
            .reserve("scene.vertices", mesh.positions.len() as u64 * vertex_bytes),
        indices: m.memory.reserve("scene.indices", n as u64 * tri_bytes),
        out_indices: m
            .memory
            .reserve("casters.indices", n as u64 * FAN_TRIANGLES_MAX * tri_bytes),
        out_positions: m.memory.reserve(
            "casters.vertices",
            n as u64 * FAN_VERTICES_MAX * vertex_bytes,
        ),
    };
    let step = Casters {
        view,
        mesh,
        buffers,
    };
    let parts = m.run_step("casters", &step, &task_weights(n, CASTER_CHUNK));
    let out = assemble_casters(mesh, parts);
    m.count(names::CASTERS_TRIANGLES, out.triangles.len() as f64);
    out
}

/// The light pass in the current phase: `mesh` (the scene's triangles that meet the view, or a
/// stand-in for them) rasterized from the light centre into `face`'s view, nearest NDC depth
/// kept (the first pass of the penumbra map too).
pub fn raster_shadow_map(m: &mut Machine, frame: &Frame, face: &FaceView, mesh: Mesh) -> ShadowMap {
    let res = frame.params.map_resolution;
    let view = face.view;
    let positions = m.memory.buffer("vertices", mesh.positions);
    let triangles = m.memory.buffer("indices", mesh.triangles);
    let target = Target::square(res, frame.params.tile_size);
    let geometry = Geometry {
        positions: &positions,
        triangles: &triangles,
        view_proj: view.view_proj,
    };
    let out = raster::draw(
        m,
        "shadow_map",
        target,
        Pipeline::DEPTH_ONLY,
        &geometry,
        &DepthOnly,
    );
    let map = out.depth.expect("a depth-only pipeline has depth");
    // Overdraw: fragments that did not end up in the map (failed the depth test or were
    // overwritten by a nearer one).
    let kept = map.buf.data.iter().filter(|&&d| d < 1.0).count() as f64;
    let overdraw = m.counter(names::FILL) - kept;
    m.count(names::OVERDRAW, overdraw);
    ShadowMap {
        view,
        face: *face,
        map,
    }
}

/// Eye samples of one 16-lane block in light space.
pub struct Receivers {
    /// Lanes with a surface in front of the light that faces it; the others are lit, or
    /// averted.
    pub mask: Mask,
    /// Lanes whose surface faces away from the light centre (n·l ≤ 0): the surface itself hides
    /// the light from a point light, so they are in shadow whatever the map holds (a bias large
    /// enough for grazing angles would otherwise light them). With
    /// [`Lookup::AVERTED_IN_SHADOW`] false they are in `mask` too.
    pub averted: Mask,
    /// World position and unit normal of the surface.
    pub position: Lanes<Vec3>,
    pub normal: Lanes<Vec3>,
    pub uv: Lanes<Vec2>,
    /// Linear depth from the light.
    pub z: Lanes<f32>,
    pub bias: Lanes<f32>,
}

/// Vector instructions of the receiver setup per block: the light-view transform (3 rows × 4
/// multiply-adds, a reciprocal, 2 multiply-adds to uv), the direction to the light (3
/// subtracts, a 3-term dot, a reciprocal square root, a 3-term dot with the normal), and the
/// slope-scaled bias (clamp, multiply, subtract, square root, divide, min, 2 multiply-adds).
const RECEIVER_OPS: u32 = 15 + 9 + 8;
/// Per shadow-map tap: uv offset (2 multiply-adds), texel coordinates (2 multiplies, 2 floors,
/// 4 range compares, 2 mask ands), block-linear index (2 shifts, 2 ands, 3 multiply-adds).
pub const TAP_OPS: u32 = 2 + 10 + 7;
/// The depth comparison: linear depth of the tap (subtract, multiply, divide), compare, select.
pub const COMPARE_OPS: u32 = 5;

/// What the eye pass computes from a block's receivers and the map.
pub trait Lookup: Sync {
    /// Whether surfaces facing away from the light centre are in shadow without a lookup (the
    /// point-light rule); an area-light lookup that judges them itself sets this to false.
    const AVERTED_IN_SHADOW: bool = true;
    /// Visibility of the active lanes of `r` (the others are ignored).
    fn visibility<P: Probe>(&self, p: &mut P, map: &ShadowMap, r: &Receivers) -> Lanes<f32>;
}

/// Element indices of the map texels holding `uv` on `mask`'s lanes, and the lanes inside the
/// map (the address part of a tap; any map of the same size and layout shares them).
pub fn texel_indices<P: Probe>(
    p: &mut P,
    map: &ShadowMap,
    uv: &Lanes<Vec2>,
    mask: Mask,
) -> (Lanes<u32>, Mask) {
    p.vector(TAP_OPS, mask);
    let mut idx = [0u32; LANES];
    let inside = mask.and(Mask::from_fn(|l| match texel(&map.view, uv[l]) {
        Some((x, y)) => {
            idx[l] = map.map.index(x, y) as u32;
            true
        }
        None => false,
    }));
    (idx, inside)
}

impl ShadowMap {
    /// Gathers the map at `uv` on `mask`'s lanes: the depth per lane and the lanes inside the
    /// map.
    pub fn tap<P: Probe>(&self, p: &mut P, uv: &Lanes<Vec2>, mask: Mask) -> (Lanes<f32>, Mask) {
        let (idx, inside) = texel_indices(p, self, uv, mask);
        (self.map.buf.gather(p, &idx, inside), inside)
    }
}

struct EyePass<'a, L> {
    frame: &'a Frame,
    map: &'a ShadowMap,
    light: Vec3,
    bias: Bias,
    lookup: &'a L,
    position: Buffer<Vec3, &'a [Vec3]>,
    normal: Buffer<Vec3, &'a [Vec3]>,
    visibility: Buffer<f32>,
}

impl<L: Lookup> EyePass<'_, L> {
    /// The receivers of the 4×4 block at pixel (x0, y0).
    fn receivers<P: Probe>(&self, p: &mut P, x0: u32, y0: u32) -> Receivers {
        let g = &self.frame.gbuffer;
        let (w, h) = (g.width, g.height);
        // The block's inputs as structure of arrays; lanes outside the image stay invalid.
        let mut q = [[0.0f32; LANES]; 3];
        let mut nq = [[0.0f32; LANES]; 3];
        let mut valid = [false; LANES];
        for row in 0..BLOCK {
            let y = y0 + row;
            if y >= h {
                break;
            }
            let n = (w - x0).min(BLOCK) as usize;
            let i = (y * w + x0) as usize;
            let pos = self.position.load_run(p, i, n);
            let nrm = self.normal.load_run(p, i, n);
            for c in 0..n {
                let lane = (row * BLOCK) as usize + c;
                [q[0][lane], q[1][lane], q[2][lane]] = pos[c].to_array();
                [nq[0][lane], nq[1][lane], nq[2][lane]] = nrm[c].to_array();
                valid[lane] = g.is_hit(i + c) && self.map.face.owns(pos[c]);
            }
        }
        // Every lane computed (no branch per lane), one stage per loop over the 16 lanes so
        // that each compiles to packed instructions; the same operations in the same order as
        // `LightView::project_lane`, `Vec3::normalize_or_zero` and `Bias::at`, so the values
        // are theirs to the bit.
        let m = &self.map.view.view_proj;
        let (mx, my, mz, mw) = (m.x_axis, m.y_axis, m.z_axis, m.w_axis);
        // NDC x and y, and the clip w: the linear depth from the light.
        let mut ndc = [[0.0f32; LANES]; 2];
        let mut depth = [0.0f32; LANES];
        for l in 0..LANES {
            let (x, y, z) = (q[0][l], q[1][l], q[2][l]);
            // The matrix–vector product of the columns, w = 1.
            let cx = ((mx.x * x + my.x * y) + mz.x * z) + mw.x;
            let cy = ((mx.y * x + my.y * y) + mz.y * z) + mw.y;
            let cw = ((mx.w * x + my.w * y) + mz.w * z) + mw.w;
            ndc[0][l] = cx / cw;
            ndc[1][l] = cy / cw;
            depth[l] = cw;
        }
        let light = self.light;
        let mut n_dot_l = [0.0f32; LANES];
        for l in 0..LANES {
            let d = [light.x - q[0][l], light.y - q[1][l], light.z - q[2][l]];
            let rcp = 1.0 / ((d[0] * d[0]) + (d[1] * d[1]) + (d[2] * d[2])).sqrt();
            let ok = rcp.is_finite() && rcp > 0.0;
            let u = d.map(|v| if ok { v * rcp } else { 0.0 });
            n_dot_l[l] = (nq[0][l] * u[0]) + (nq[1][l] * u[1]) + (nq[2][l] * u[2]);
        }
        let view = &self.map.view;
        let bias: Lanes<f32> = std::array::from_fn(|l| self.bias.at(view, depth[l], n_dot_l[l]));
        let mut r = Receivers {
            mask: Mask::NONE,
            averted: Mask::NONE,
            position: [Vec3::ZERO; LANES],
            normal: [Vec3::ZERO; LANES],
            uv: [Vec2::ZERO; LANES],
            z: [0.0; LANES],
            bias: [0.0; LANES],
        };
        for lane in 0..LANES {
            let seen = valid[lane] && depth[lane] > 0.0;
            // A surface facing away from the centre behind the light (the top of a pillar
            // taller than it) is as averted as one in front.
            let averted = (seen || (valid[lane] && L::AVERTED_IN_SHADOW)) && n_dot_l[lane] <= 0.0;
            let active = seen && (!averted || !L::AVERTED_IN_SHADOW);
            r.averted.0 |= u16::from(averted) << lane;
            r.mask.0 |= u16::from(active) << lane;
            if active {
                r.position[lane] = Vec3::new(q[0][lane], q[1][lane], q[2][lane]);
                r.normal[lane] = Vec3::new(nq[0][lane], nq[1][lane], nq[2][lane]);
                r.uv[lane] = Vec2::new(ndc[0][lane] * 0.5 + 0.5, 0.5 - ndc[1][lane] * 0.5);
                r.z[lane] = depth[lane];
                r.bias[lane] = bias[lane];
            }
        }
        p.vector(RECEIVER_OPS, r.mask);
        r
    }
}

impl<L: Lookup> EyeKernel for EyePass<'_, L> {
    fn block<P: Probe>(&self, p: &mut P, b: &EyeBlock, out: &mut Vec<(u32, f32)>) {
        let r = self.receivers(p, b.x0, b.y0);
        let v = if r.mask.any() {
            self.lookup.visibility(p, self.map, &r)
        } else {
            [1.0; LANES]
        };
        b.store(p, &self.visibility, out, |lane| {
            if r.mask.get(lane) {
                Some(v[lane].clamp(0.0, 1.0))
            } else if r.averted.get(lane) {
                Some(0.0)
            } else {
                None
            }
        });
    }
}

/// A lookup's visibility after the map's depth test: 1 where the receiver lies outside the map
/// (`inside` false), 0 where the map shadows it (`lit` false), `lit_value(lane)` where it does
/// not (1 for the hard test, the penumbra map's intensity for paper 000 §3).
pub fn umbra_test(inside: Mask, lit: Mask, lit_value: impl Fn(usize) -> f32) -> Lanes<f32> {
    std::array::from_fn(|l| {
        if !inside.get(l) {
            1.0
        } else if lit.get(l) {
            lit_value(l)
        } else {
            0.0
        }
    })
}

/// Phase `eye_lookup` (`eye_lookup[+x]` per cube face): visibility of every eye pixel the map's
/// view shades ([`FaceView::owns`]), one eye tile per task. Pixels that see no surface, that
/// another face shades, or whose surface the light view does not contain, are lit.
pub fn eye_lookup<L: Lookup>(
    m: &mut Machine,
    frame: &Frame,
    map: &ShadowMap,
    bias: Bias,
    lookup: &L,
) -> VisibilityBuffer {
    m.phase(&map.face.phase(Phase::EyeLookup.name()));
    let g = &frame.gbuffer;
    let pass = EyePass {
        frame,
        map,
        light: frame.scene.light.center(),
        bias,
        lookup,
        position: m.memory.borrowed("gbuffer.position", &g.position),
        normal: m.memory.borrowed("gbuffer.normal", &g.normal),
        visibility: m.memory.unbacked("visibility", g.len()),
    };
    let weights = eye_tiles(frame).tile_weights(|i| g.is_hit(i) && map.face.owns(g.position[i]));
    eye_lookup_step(m, frame, &pass, &weights)
}

/// The shadow-map family's frame on a CPU execution with `lookup`: the light views of the frame
/// ([`ViewFit::CubeWhenWide`]), then per view its light pass and its eye pass, each pixel taken
/// from the view that shades it.
pub fn render_views<L: Lookup>(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    bias: Bias,
    lookup: &L,
) -> FrameOutput {
    let mut m = machine(backend, frame, ctx);
    let views = LightViews::fit(frame, ViewFit::CubeWhenWide);
    let mut vis = VisibilityBuffer::lit(frame.width(), frame.height());
    // Only occluders cast: a receiver-only object is left out of the map.
    let occluders = frame.scene.occluders();
    for face in &views.views {
        let map = light_raster(&mut m, frame, face, &occluders);
        let part = eye_lookup(&mut m, frame, &map, bias, lookup);
        face.take_owned(frame, &part, &mut vis);
    }
    let mut out = output(m, vis);
    views.record(&mut out);
    out
}
