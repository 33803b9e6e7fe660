//! Umbra and penumbra volumes with the D-buffer on the CPU executions (`cpu-native`,
//! `cpu-model`), in the paper's steps:
//!
//! 1. `silhouettes`: every occluder face classified against the disc (eq. 1; step `faces`),
//!    then every edge marked as umbra- and/or penumbra-volume silhouette edge (step `edges`);
//! 2. `volumes`: extrusion points per silhouette edge (step `extrude`), the quads, umbra quads
//!    trimmed at convex corners (step `quads`), the closing triangles of the penumbra volume and the silhouette faces of the umbra volume (step
//!    `close`);
//! 3. `dbuffer`: three draws from the light centre on the binned rasterizer: the occluders' depth,
//!    the umbra volume and the penumbra volume, each volume fragment writing the depth of its
//!    silhouette edge below the light plane (the rule of [`super::DEPTH_RULE`]);
//! 4. `eye_lookup`: eq. 2, eq. 3 and eq. 4 per eye sample.
//!
//! Steps 1 and 2 run on every core, or with `volume_build: single_core` on one
//! ([`super::volumes::build_volumes`], [`super::VolumeBuild`]).
//!
//! `fill` counts the fragments of the two volume draws (the scene's depth draw is
//! `dbuffer.scene_fill`); `overdraw` the volume fragments that did not end up in the D-buffer
//! (behind a nearer volume surface, or in front of the scene for the umbra volume).

use glam::{Vec2, Vec3};

use super::volumes::{build_volumes, VolumeMesh, Volumes};
use super::Phase;
use super::{edge_distance, front_fraction, t_penumbra, t_umbra, visibility, DbufferOptions, Disc};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{machine, output};
use crate::algorithms::shadow_map::cpu::{
    casters, eye_lookup, raster_shadow_map, texel_indices, Lookup, Receivers, ShadowMap,
    COMPARE_OPS,
};
use crate::algorithms::shadow_map::lit;
use crate::algorithms::shadow_map::{FaceView, LightView, LightViews, ViewFit};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::raster::{self, Blend, FragmentKernel, Fragments, Geometry, Pipeline, Shade};
use crate::model::raster::{Surface, Target, TileRect};
use crate::model::LANES;
use crate::model::{Buffer, Lanes, Machine, Mask, Probe};
use crate::record::PhaseId;
use crate::scene::adjacency::EdgeAdjacency;
use crate::scene::Mesh;

/// The fragment program of the volume draws per 16 fragments: perspective-correct edge depth
/// (3 multiplies, 2 adds, a reciprocal, 3 multiply-adds) and, for the umbra volume, the two
/// linear depths and the compare with the scene (2 × 3 + 2).
const VOLUME_FRAGMENT_OPS: u32 = 9;
const UMBRA_DISCARD_OPS: u32 = 8;
/// The receiver's front fraction per block: the centre's distance to its plane (a 3-term dot),
/// the normal's spread over the disc (a dot, 3 multiply-adds, a length), the offset (a divide,
/// a clamp), the segment area (an arc cosine as a polynomial of 6, a square root, 3 multiplies,
/// a clamp).
const FRONT_FRACTION_OPS: u32 = 3 + 6 + 2 + 11;
/// The eye sample's ray per block: view-space direction from uv (4 multiply-adds), its length
/// (a 3-term dot, a square root), `dir·n_c` (a 3-term dot, a divide).
const RAY_OPS: u32 = 4 + 4 + 4;
/// Eq. 2, eq. 3 and eq. 4 per block and branch: linear depth of the volume (subtract, multiply,
/// divide), the distance ratio (a multiply), `|cx_s|` (a divide), eq. 3 (3 subtracts,
/// 3 multiplies, a divide, a clamp, compares and selects: 10), the falloff (3).
const LOOKUP_OPS: u32 = 3 + 1 + 1 + 10 + 3;

/// The fragment program of the volume draws: the perspective-correct edge depth; the umbra
/// volume discards fragments in front of the scene surface seen from `c`. Tile state: unused.
struct VolumeFragments<'a> {
    view: &'a LightView,
    triangles: &'a Buffer<[u32; 3]>,
    attributes: &'a Buffer<Vec2>,
    /// The scene's depth, for the umbra volume's rule ([`super::DEPTH_RULE`]).
    scene: Option<&'a ShadowMap>,
}

impl FragmentKernel for VolumeFragments<'_> {
    type TileState = ();

    fn begin_tile(&self, _: TileRect) {}

    fn shade<P: Probe>(&self, p: &mut P, _: &mut (), f: &Fragments<'_>) -> Shade {
        let tri = self.triangles.load(p, f.prim as usize);
        let attr = tri.map(|v| self.attributes.load(p, v as usize));
        p.vector(VOLUME_FRAGMENT_OPS, f.mask);
        let mut keep = f.mask;
        if let Some(scene) = self.scene {
            let map = &scene.map;
            let block = map.block_index(f.x / raster::BLOCK, f.y / raster::BLOCK);
            map.buf.record_load(p, block, LANES);
            p.vector(UMBRA_DISCARD_OPS, f.mask);
            keep = f.mask.and(Mask::from_fn(|l| {
                let (z_f, z_o) = (f.z[l], map.buf.data[block + l]);
                let slack = self.view.texel_world(self.view.linear_depth(z_o));
                self.view.linear_depth(z_f) >= self.view.linear_depth(z_o) - slack
            }));
        }
        let value = std::array::from_fn(|l| f.perspective_value(l, &attr));
        Shade { value, mask: keep }
    }
}

/// The D-buffer: the scene's depth from `c` and, per volume, the nearest kept surface's depth
/// and its edge depth `z_e`.
pub struct DBuffer {
    pub scene: ShadowMap,
    pub umbra_depth: Surface,
    pub umbra_edge: Surface,
    pub penumbra_depth: Surface,
    pub penumbra_edge: Surface,
}

/// Draws one volume into a depth and an edge-depth surface.
fn draw_volume(
    m: &mut Machine,
    frame: &Frame,
    name: &str,
    mesh: &VolumeMesh,
    view: &LightView,
    scene: Option<&ShadowMap>,
) -> (Surface, Surface) {
    let positions = m
        .memory
        .buffer(&format!("{name}.vertices"), mesh.positions.clone());
    let attributes = m
        .memory
        .buffer(&format!("{name}.attributes"), mesh.attributes.clone());
    let triangles = m
        .memory
        .buffer(&format!("{name}.triangles"), mesh.triangles.clone());
    let res = frame.params.map_resolution;
    let target = Target::square(res, frame.params.tile_size);
    let pipeline = Pipeline {
        color: Some((0.0, Blend::Replace)),
        ..Pipeline::DEPTH_ONLY
    };
    let geometry = Geometry {
        positions: &positions,
        triangles: &triangles,
        view_proj: view.view_proj,
    };
    let kernel = VolumeFragments {
        view,
        triangles: &triangles,
        attributes: &attributes,
        scene,
    };
    let out = raster::draw(m, name, target, pipeline, &geometry, &kernel);
    (
        out.depth.expect("the pipeline has depth"),
        out.color.expect("the pipeline has colour"),
    )
}

/// Phase `dbuffer`; `occluders` (the scene's occluder objects, a receiver-only object casts no
/// shadow) give `|cx_o|`.
pub fn dbuffer(
    m: &mut Machine,
    frame: &Frame,
    face: &FaceView,
    occluders: &Mesh,
    v: &Volumes,
) -> DBuffer {
    m.phase(Phase::Dbuffer.name());
    let mesh = casters(m, &face.view, occluders);
    let scene = raster_shadow_map(m, frame, face, mesh);
    // The scene's draw is the |cx_o| channel; fill and overdraw count the volumes.
    let (scene_fill, scene_over) = (m.counter(names::FILL), m.counter(names::OVERDRAW));
    m.count(names::FILL, -scene_fill);
    m.count(names::OVERDRAW, -scene_over);
    m.count(names::DBUFFER_SCENE_FILL, scene_fill);
    let view = scene.view;
    let (umbra_depth, umbra_edge) =
        draw_volume(m, frame, "dbuffer_uv", &v.umbra, &view, Some(&scene));
    let (penumbra_depth, penumbra_edge) =
        draw_volume(m, frame, "dbuffer_pv", &v.penumbra, &view, None);
    let kept = |s: &Surface| s.buf.data.iter().filter(|&&d| d < 1.0).count() as f64;
    let overdraw = m.counter(names::FILL) - kept(&umbra_depth) - kept(&penumbra_depth);
    m.count(names::OVERDRAW, overdraw);
    m.count(
        names::DBUFFER_BYTES,
        super::dbuffer_bytes(&frame.params) as f64,
    );
    DBuffer {
        scene,
        umbra_depth,
        umbra_edge,
        penumbra_depth,
        penumbra_edge,
    }
}

/// Phase `eye_lookup`'s visibility (§4): behind the scene surface seen from `c` the umbra
/// branch of eq. 3, else the penumbra branch.
struct DLookup<'a> {
    d: &'a DBuffer,
    disc: Disc,
    /// `n_c` in light-view space.
    n_view: Vec3,
    o: DbufferOptions,
}

impl Lookup for DLookup<'_> {
    /// A surface facing away from the centre may face part of the disc: its visibility is the
    /// part in front of its plane ([`front_fraction`]); the others are looked up.
    const AVERTED_IN_SHADOW: bool = false;

    fn visibility<P: Probe>(&self, p: &mut P, map: &ShadowMap, r: &Receivers) -> Lanes<f32> {
        let view = &map.view;
        p.vector(FRONT_FRACTION_OPS, r.mask);
        let plane: Lanes<f32> = std::array::from_fn(|l| {
            if r.mask.get(l) {
                front_fraction(r.normal[l], r.position[l], &self.disc)
            } else {
                0.0
            }
        });
        let facing = r.mask.and_not(r.averted);
        let (idx, inside) = texel_indices(p, map, &r.uv, facing);
        let o = map.map.buf.gather(p, &idx, inside);
        p.vector(COMPARE_OPS, inside);
        let front = inside.and(Mask::from_fn(|l| lit(view, o[l], r.z[l], r.bias[l])));
        let behind = inside.and_not(front);
        p.vector(RAY_OPS, inside);
        let (ud, ue) = (
            self.d.umbra_depth.buf.gather(p, &idx, behind),
            self.d.umbra_edge.buf.gather(p, &idx, behind),
        );
        let (pd, pe) = (
            self.d.penumbra_depth.buf.gather(p, &idx, front),
            self.d.penumbra_edge.buf.gather(p, &idx, front),
        );
        p.vector(LOOKUP_OPS, behind);
        p.vector(LOOKUP_OPS, front);
        std::array::from_fn(|l| {
            if !facing.get(l) || !inside.get(l) {
                return plane[l];
            }
            let t = ray_t(
                view,
                self.n_view,
                r.uv[l],
                r.z[l] - if behind.get(l) { r.bias[l] } else { 0.0 },
                behind.get(l),
                if behind.get(l) {
                    (ud[l], ue[l])
                } else {
                    (pd[l], pe[l])
                },
            );
            visibility(t, self.o.falloff) * plane[l]
        })
    }
}

/// `t` of an eye sample at map coordinates `uv` and light-view depth `z`, behind the scene
/// surface or not, from the volume's NDC depth and edge depth at its texel: eq. 2 for `|cx_s|`
/// along the sample's ray, then eq. 3 in distances from `c`.
pub fn ray_t(
    view: &LightView,
    n_view: Vec3,
    uv: Vec2,
    z: f32,
    behind: bool,
    (ndc, z_e): (f32, f32),
) -> f32 {
    if ndc >= 1.0 {
        // No volume surface on the ray: all of it is umbra behind an occluder, lit beside.
        return if behind { 0.0 } else { 1.0 };
    }
    let ray = Vec3::new(
        (2.0 * uv.x - 1.0) * view.tan_half_fov,
        (1.0 - 2.0 * uv.y) * view.tan_half_fov,
        -1.0,
    );
    // Distance from c per unit of light-view depth along this ray.
    let per_depth = ray.length();
    let dir = ray / per_depth;
    let d = z * per_depth;
    let volume = view.linear_depth(ndc) * per_depth;
    let s = edge_distance(z_e, dir, n_view);
    if behind {
        t_umbra(d, volume, s)
    } else {
        t_penumbra(d, volume, s)
    }
}

/// `dbuffer` on a CPU execution.
pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    o: &DbufferOptions,
) -> Result<FrameOutput> {
    let disc = Disc::of(&frame.scene.light, frame.scene.bounds().center());
    let occluders = frame.scene.occluders();
    let adj = EdgeAdjacency::build(&occluders);
    let mut m = machine(backend, frame, ctx);
    let views = LightViews::fit(frame, ViewFit::Single);
    let v = build_volumes(&mut m, frame, &adj, disc, views.single(), o);
    let d = dbuffer(&mut m, frame, &views.views[0], &occluders, &v);
    let lookup = DLookup {
        d: &d,
        disc,
        n_view: d.scene.view.view.transform_vector3(disc.n),
        o: *o,
    };
    let vis = eye_lookup(&mut m, frame, &d.scene, o.bias, &lookup);
    let mut out = output(m, vis);
    out.execution.insert(
        "volume_build".into(),
        serde_json::json!(o.volume_build.describe()),
    );
    views.record(&mut out);
    Ok(out)
}
