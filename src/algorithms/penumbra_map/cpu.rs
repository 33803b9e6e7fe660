//! Penumbra maps on the CPU executions (`cpu-native`, `cpu-model`), in the paper's passes:
//!
//! 1. `shadow_map`: the hard shadow map's light pass, unchanged;
//! 2. `silhouettes`: brute-force silhouette extraction from the light centre over every edge of
//!    the occluders (§4: "our application detects silhouettes using a brute force algorithm"),
//!    then the silhouette vertices and how many silhouette edges meet at each;
//! 3. `penumbra_map`: cones and sheets built per vertex and edge, drawn with the binned
//!    rasterizer into a map cleared to white with min-blending, shaded by the fragment program
//!    of §3 ([`PenumbraFragments`]);
//! 4. `eye_lookup`: the umbra test in the shadow map, else the penumbra map's intensity.

use glam::{Vec2, Vec3};

use super::Phase;
use super::{
    cone_size, intensity, shadow_geometry, sheet_size, PenumbraGeometry, PenumbraMapOptions,
    Silhouettes,
};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{machine, output, scan_edges, EDGE_CHUNK};
use crate::algorithms::shadow_map::cpu::{
    casters, eye_lookup, raster_shadow_map, texel_indices, umbra_test, Lookup, Receivers,
    ShadowMap, COMPARE_OPS,
};
use crate::algorithms::shadow_map::lit;
use crate::algorithms::shadow_map::{LightView, LightViews, ViewFit};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::raster::{self, Blend, FragmentKernel, Fragments, Geometry, Pipeline, Shade};
use crate::model::raster::{Surface, Target, TileRect};
use crate::model::{task_items, task_weights, Buffer, Lanes, Machine, Mask, Probe};
use crate::model::{TaskKernel, LANES};
use crate::record::PhaseId;
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};

/// Cones and sheets per task of the geometry step.
const PRIM_CHUNK: usize = 64;

/// Vector instructions of the facing test of 16 edges: per adjacent face, two edge vectors
/// (6 subtracts), their cross product (3 multiplies, 3 multiply-adds), the vector to the light
/// (3 subtracts) and a 3-term dot (3); then the compare of both faces and the mask xor (4).
const FACING_OPS: u32 = 2 * 18 + 4;
/// Scalar work per silhouette edge found: orientation from the front face's winding and the
/// append to the edge list.
const SILHOUETTE_EDGE_SCALAR: u32 = 8;
/// Scalar work per silhouette edge in the vertex step: two counter updates with their
/// first-seen tests, and the sheet's planarity test (two cones' far points, a cross product,
/// a normalization, a dot, a divide).
const VERTEX_STEP_EDGE_SCALAR: u32 = 6 + 40;
/// Scalar work per cone or sheet: view-space projection of its points, cone radius, outward
/// direction, loop control.
const PRIM_SETUP_SCALAR: u32 = 24;
/// Vector instructions per 16 cone base points or sheet points: angle or edge parameter,
/// position (2 multiply-adds and a lerp of 3), radius, rim offset (2 multiply-adds), depth and
/// its reciprocal.
const POINT_OPS: u32 = 12;
/// The fragment program of §3 per 16 fragments: perspective-correct `Z_v` (3 multiplies,
/// 2 adds, a reciprocal, 3 multiply-adds), the discard compare, two NDC-to-linear depth
/// conversions (a multiply-add, a reciprocal, a multiply each), eq. 1 (2 subtracts, a divide,
/// a clamp) and `3t² − 2t³` (3). The paper's ARB program has 24 instructions.
const FRAGMENT_OPS: u32 = 9 + 1 + 6 + 4 + 3 + 1;

struct SilhouetteTest<'a> {
    adj: &'a EdgeAdjacency,
    light: Vec3,
    edges: Buffer<[u32; 4]>,
    triangles: Buffer<[u32; 3]>,
    vertices: Buffer<Vec3>,
    out: (crate::model::BufferId, u64),
}

impl TaskKernel for SilhouetteTest<'_> {
    type Out = Vec<SilhouetteEdge>;

    fn run<P: Probe>(&self, p: &mut P, chunk: usize) -> Self::Out {
        let mut found = Vec::new();
        scan_edges(p, &self.edges, chunk, |p, group, k, mask, recs| {
            for f in 2..4 {
                let faces: Lanes<u32> = std::array::from_fn(|l| recs.get(l).map_or(0, |r| r[f]));
                let has = mask.and(Mask::from_fn(|l| faces[l] != u32::MAX));
                let tris = self.triangles.gather(p, &faces, has);
                for c in [0, 1, 2] {
                    let idx: Lanes<u32> = std::array::from_fn(|l| tris[l][c]);
                    self.vertices.gather(p, &idx, has);
                }
            }
            p.vector(FACING_OPS, mask);
            for e in group..group + k {
                if let Some(s) = self.adj.silhouette_edge(e, self.light) {
                    let at = (chunk * EDGE_CHUNK + found.len()) as u64 * 32;
                    p.scalar(SILHOUETTE_EDGE_SCALAR);
                    p.write(self.out.0, self.out.1 + at, 32);
                    found.push(s);
                }
            }
        });
        found
    }
}

/// The vertex step: silhouette vertices with their edge counts, and each edge's sheet.
struct VertexStep<'a> {
    edges: &'a [SilhouetteEdge],
    view: &'a LightView,
    light_radius: f32,
    max_strips: u32,
    vertex_count: usize,
    counts: (crate::model::BufferId, u64),
}

impl TaskKernel for VertexStep<'_> {
    type Out = Silhouettes;

    fn run<P: Probe>(&self, p: &mut P, _: usize) -> Silhouettes {
        let mut slot = vec![u32::MAX; self.vertex_count];
        let mut s = Silhouettes {
            edges: Vec::with_capacity(self.edges.len()),
            sheets: Vec::with_capacity(self.edges.len()),
            ..Default::default()
        };
        for e in self.edges {
            for &w in &e.v {
                let addr = self.counts.1 + u64::from(w) * 4;
                p.read(self.counts.0, addr, 4);
                p.write(self.counts.0, addr, 4);
            }
            p.scalar(VERTEX_STEP_EDGE_SCALAR);
            s.add(&mut slot, e, self.view, self.light_radius, self.max_strips);
        }
        s
    }
}

/// Phase `silhouettes`: the brute-force test of every occluder edge against the light centre,
/// then the vertex step.
fn silhouettes(
    m: &mut Machine,
    adj: &EdgeAdjacency,
    view: &LightView,
    light: Vec3,
    light_radius: f32,
    o: &PenumbraMapOptions,
) -> Silhouettes {
    m.phase(Phase::Silhouettes.name());
    let n = adj.edges.len();
    let test = SilhouetteTest {
        adj,
        light,
        edges: m.memory.buffer("adjacency.edges", adj.edge_records()),
        triangles: m
            .memory
            .buffer("adjacency.triangles", adj.triangles.clone()),
        vertices: m.memory.buffer("adjacency.vertices", adj.vertices.clone()),
        out: m.memory.reserve("silhouette.edges", n as u64 * 32),
    };
    let weights = task_weights(n, EDGE_CHUNK);
    let edges: Vec<SilhouetteEdge> = m
        .run_step("edges", &test, &weights)
        .into_iter()
        .flatten()
        .collect();
    let step = VertexStep {
        edges: &edges,
        view,
        light_radius,
        max_strips: o.max_sheet_strips,
        vertex_count: adj.vertices.len(),
        counts: m
            .memory
            .reserve("silhouette.vertex_edges", adj.vertices.len() as u64 * 4),
    };
    let s = m
        .run_step("vertices", &step, &[edges.len() as u64 + 1])
        .pop()
        .expect("one task");
    for (name, v) in s.counts() {
        m.count(name, v);
    }
    s
}

/// Where each cone and sheet puts its vertices and triangles (exclusive prefix sums, so that
/// the geometry step's tasks write disjoint ranges).
struct Layout {
    /// (first vertex, first triangle) of primitive `i`: cones first, then sheets.
    offsets: Vec<(u32, u32)>,
    vertices: u32,
    triangles: u32,
}

fn layout(s: &Silhouettes, segments: u32) -> Layout {
    let sizes = s.vertices.iter().map(|_| cone_size(segments)).chain(
        s.sheets
            .iter()
            .map(|sh| sh.map_or((0, 0), |(_, n)| sheet_size(n))),
    );
    let (mut v, mut t) = (0u32, 0u32);
    let offsets = sizes
        .map(|(nv, nt)| {
            let o = (v, t);
            v += nv;
            t += nt;
            o
        })
        .collect();
    Layout {
        offsets,
        vertices: v,
        triangles: t,
    }
}

struct GeometryStep<'a> {
    s: &'a Silhouettes,
    view: &'a LightView,
    light_radius: f32,
    segments: u32,
    layout: &'a Layout,
    positions: &'a Buffer<Vec3>,
    attributes: &'a Buffer<Vec2>,
    triangles: &'a Buffer<[u32; 3]>,
}

impl TaskKernel for GeometryStep<'_> {
    type Out = PenumbraGeometry;

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> PenumbraGeometry {
        let cones = self.s.vertices.len();
        let total = self.layout.offsets.len();
        let items = task_items(task, PRIM_CHUNK, total);
        let mut g = PenumbraGeometry::default();
        let base = self.layout.offsets[items.start];
        for i in items {
            let (v0, t0) = (g.positions.len(), g.triangles.len());
            if i < cones {
                g.cone(
                    self.view,
                    self.light_radius,
                    self.s.vertices[i].1,
                    self.segments,
                );
            } else if let Some((sheet, strips)) = &self.s.sheets[i - cones] {
                g.sheet(self.view, self.light_radius, sheet, *strips);
            }
            debug_assert_eq!(self.layout.offsets[i].0 - base.0, v0 as u32);
            let (nv, nt) = (g.positions.len() - v0, g.triangles.len() - t0);
            p.scalar(PRIM_SETUP_SCALAR);
            for k in (0..nv).step_by(LANES) {
                p.vector(POINT_OPS, Mask::first(nv - k));
            }
            let at = (base.0 as usize + v0, base.1 as usize + t0);
            self.positions.record_store(p, at.0, nv);
            self.attributes.record_store(p, at.0, nv);
            self.triangles.record_store(p, at.1, nt);
        }
        // Task-local vertex indices become global.
        for t in &mut g.triangles {
            *t = t.map(|i| i + base.0);
        }
        g
    }
}

/// The fragment program of §3 over the penumbra map's fragments, with the shadow map of the
/// same view. Tile state: the fragments discarded (behind the shadow-map surface).
struct PenumbraFragments<'a> {
    shadow: &'a ShadowMap,
    triangles: &'a Buffer<[u32; 3]>,
    attributes: &'a Buffer<Vec2>,
}

impl FragmentKernel for PenumbraFragments<'_> {
    type TileState = u64;

    fn begin_tile(&self, _: TileRect) -> u64 {
        0
    }

    fn shade<P: Probe>(&self, p: &mut P, discarded: &mut u64, f: &Fragments<'_>) -> Shade {
        let view = &self.shadow.view;
        let tri = self.triangles.load(p, f.prim as usize);
        let attr = tri.map(|v| self.attributes.load(p, v as usize));
        // Same view and resolution: the fragment's window coordinates address the shadow map.
        let map = &self.shadow.map;
        let block = map.block_index(f.x / raster::BLOCK, f.y / raster::BLOCK);
        map.buf.record_load(p, block, LANES);
        p.vector(FRAGMENT_OPS, f.mask);
        let shade = Shade::select(f.mask, 1.0, |l| {
            let (z_f, z_p) = (f.z[l], map.buf.data[block + l]);
            (z_f <= z_p).then(|| {
                let z_v = f.perspective_value(l, &attr);
                intensity(view.linear_depth(z_f), view.linear_depth(z_p), z_v)
            })
        });
        *discarded += u64::from(f.mask.and_not(shade.mask).count());
        shade
    }
}

/// Phase `penumbra_map`: cones and sheets built (step `geometry`), then drawn into a map
/// cleared to white, darkest kept (steps `binning` and `raster`).
fn penumbra_map(
    m: &mut Machine,
    frame: &Frame,
    shadow: &ShadowMap,
    s: &Silhouettes,
    light_radius: f32,
    o: &PenumbraMapOptions,
) -> Surface {
    m.phase(Phase::PenumbraMap.name());
    let view = &shadow.view;
    let layout = layout(s, o.cone_segments);
    let mut positions = m.memory.buffer(
        "penumbra.vertices",
        vec![Vec3::ZERO; layout.vertices as usize],
    );
    let mut attributes = m.memory.buffer(
        "penumbra.attributes",
        vec![Vec2::ZERO; layout.vertices as usize],
    );
    let mut triangles = m.memory.buffer(
        "penumbra.triangles",
        vec![[0u32; 3]; layout.triangles as usize],
    );
    let step = GeometryStep {
        s,
        view,
        light_radius,
        segments: o.cone_segments,
        layout: &layout,
        positions: &positions,
        attributes: &attributes,
        triangles: &triangles,
    };
    let n = layout.offsets.len();
    let weights = task_weights(n, PRIM_CHUNK);
    let parts = m.run_step("geometry", &step, &weights);
    let (mut pv, mut pa, mut pt) = (Vec::new(), Vec::new(), Vec::new());
    for g in parts {
        pv.extend(g.positions);
        pa.extend(g.attributes);
        pt.extend(g.triangles);
    }
    positions.data = pv;
    attributes.data = pa;
    triangles.data = pt;
    let cone_tris = s.vertices.len() as u32 * o.cone_segments;
    m.count(names::PENUMBRA_CONE_TRIANGLES, f64::from(cone_tris));
    m.count(
        names::PENUMBRA_SHEET_TRIANGLES,
        f64::from(layout.triangles - cone_tris),
    );

    let res = frame.params.map_resolution;
    let target = Target::square(res, frame.params.tile_size);
    // §4: the darkest contribution wins (the paper's GL_LESS on intensity as depth).
    let pipeline = Pipeline::color_only(1.0, Blend::Min);
    let geometry = Geometry {
        positions: &positions,
        triangles: &triangles,
        view_proj: view.proj,
    };
    let kernel = PenumbraFragments {
        shadow,
        triangles: &triangles,
        attributes: &attributes,
    };
    let out = raster::draw(m, "penumbra_map", target, pipeline, &geometry, &kernel);
    m.count(names::OVERDRAW, out.tiles.iter().sum::<u64>() as f64);
    out.color.expect("the pipeline has a colour target")
}

/// The final pass (§3): umbra where the shadow map shadows the receiver, else the penumbra map.
struct PenumbraLookup<'a> {
    penumbra: &'a Surface,
}

impl Lookup for PenumbraLookup<'_> {
    fn visibility<P: Probe>(&self, p: &mut P, map: &ShadowMap, r: &Receivers) -> Lanes<f32> {
        let (idx, inside) = texel_indices(p, map, &r.uv, r.mask);
        let d = map.map.buf.gather(p, &idx, inside);
        p.vector(COMPARE_OPS, inside);
        let lit_lanes = inside.and(Mask::from_fn(|l| lit(&map.view, d[l], r.z[l], r.bias[l])));
        let penumbra = self.penumbra.buf.gather(p, &idx, lit_lanes);
        p.vector(1, inside);
        umbra_test(inside, lit_lanes, |l| penumbra[l])
    }
}

/// `penumbra_map` on a CPU execution.
pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    o: &PenumbraMapOptions,
) -> Result<FrameOutput> {
    let geometry = shadow_geometry(frame, o);
    let mut m = machine(backend, frame, ctx);
    let views = LightViews::fit(frame, ViewFit::Single);
    let face = &views.views[0];
    m.phase(Phase::ShadowMap.name());
    let mesh = casters(&mut m, &face.view, &geometry.shadow_map);
    let shadow = raster_shadow_map(&mut m, frame, face, mesh);
    let light = frame.scene.light.center();
    let light_radius = frame.scene.light.size();
    let adj = EdgeAdjacency::build(&geometry.occluders);
    let s = silhouettes(&mut m, &adj, &shadow.view, light, light_radius, o);
    let penumbra = penumbra_map(&mut m, frame, &shadow, &s, light_radius, o);
    let lookup = PenumbraLookup {
        penumbra: &penumbra,
    };
    let vis = eye_lookup(&mut m, frame, &shadow, o.bias, &lookup);
    let mut out = output(m, vis);
    views.record(&mut out);
    Ok(out)
}
