//! Host geometry both executions of `dbuffer` share (paper 003, §2.1): the area silhouettes of
//! the occluders (`silhouettes`: eq. 1 per face, step `faces`; the umbra- and penumbra-volume
//! silhouette edges, step `edges`) and the umbra and penumbra volumes built from them
//! (`volumes`: extrusion points, step `extrude`; quads trimmed at convex corners, step `quads`;
//! closing triangles and silhouette faces, step `close`), as tasks of the machine on every core
//! or with `volume_build: single_core` on one ([`build_volumes`], [`super::VolumeBuild`]). The
//! wgpu execution runs them on the machine as the CPU executions do and uploads the meshes.

use std::collections::BTreeMap;

use glam::{Vec2, Vec3};

use super::Phase;
use super::{
    centre_behind, classify, extrude, extrusion_points, rim_arc, DbufferOptions, Disc, Facing,
    VolumeBuild,
};
use crate::algorithms::exec::{scan_edges, EDGE_CHUNK};
use crate::algorithms::shadow_map::LightView;
use crate::counters::names;
use crate::frame::Frame;
use crate::model::TaskKernel;
use crate::model::{lane_groups, task_items, task_weights, Buffer, Lanes, Machine, Probe};
use crate::record::PhaseId;
use crate::scene::adjacency::EdgeAdjacency;

/// Faces per task of the facing test.
const FACE_CHUNK: usize = 1024;
/// Silhouette edges per task of the extrusion.
const PRIM_CHUNK: usize = 64;

/// Vector instructions of eq. 1 for 16 faces: two edge vectors (6 subtracts), the normal
/// (3 multiplies, 3 multiply-adds), its length and normalization (3 multiply-adds, a reciprocal
/// square root, 3 multiplies), `(n × n_c) × n_c` (2 × 6), its normalization (5), the two disc
/// points (6 multiply-adds), the two plane tests (2 × 4) and the class selects (3).
const FACING_OPS: u32 = 12 + 7 + 12 + 5 + 6 + 8 + 3;
/// Vector instructions of the edge test for 16 edges: both faces' classes compared (4), the
/// boundary twin (2), the two silhouette masks (4).
const EDGE_OPS: u32 = 10;
/// Scalar work per silhouette edge found: its record (two vertices, two opposite vertices)
/// and the append.
const SILHOUETTE_EDGE_SCALAR: u32 = 12;
/// Scalar work per silhouette edge of the extrusion: the intersection `a` with the light plane
/// (2 dots, a divide, 3 multiply-adds), the tangent points (a dot, a cross, a divide, a square
/// root, 6 multiply-adds), the umbra/penumbra choice (2 crosses, 6 dots, compares) and the
/// extruded far points (2 normalizations, 6 multiply-adds per quad).
const EXTRUDE_SCALAR: u32 = 12 + 14 + 30 + 2 * 20;
/// Scalar work per neighbour of an umbra edge at one of its vertices: its plane (a cross
/// product, a normalization, the orientation dot) and the two convexity tests (2 dots).
const TRIM_TEST_SCALAR: u32 = 24;
/// Scalar work per polygon vertex of one clip: a dot, a compare, and for cut edges a lerp.
const CLIP_SCALAR: u32 = 10;
/// Scalar work per volume vertex: view-space depth and its reciprocal, the edge depth.
const VERTEX_SCALAR: u32 = 8;
/// Scalar work per penumbra edge end in the closing step: the vertex's list append and the
/// angle of its extrusion point around the disc centre.
const CLOSE_END_SCALAR: u32 = 12;
/// Scalar work per rim point of a closing fan: a rotation (a quaternion–vector product) and an
/// extrusion.
const RIM_POINT_SCALAR: u32 = 30;

/// A silhouette edge of either volume: its welded vertices and positions, the third vertices of
/// its two faces (the same twice for a boundary edge), and which volumes it bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeEdge {
    pub w: [u32; 2],
    pub v: [Vec3; 2],
    pub q: [Vec3; 2],
    pub umbra: bool,
    pub penumbra: bool,
}

/// The result of phase `silhouettes`.
pub struct Silhouettes {
    pub edges: Vec<VolumeEdge>,
    /// Silhouette faces with the light centre behind them (drawn with the umbra volume, §3.3).
    pub umbra_faces: Vec<[Vec3; 3]>,
}

fn normal(adj: &EdgeAdjacency, f: usize) -> (Vec3, Vec3) {
    let [a, b, c] = adj.triangles[f].map(|i| adj.vertices[i as usize]);
    ((b - a).cross(c - a).normalize_or_zero(), a)
}

struct FaceTest<'a> {
    adj: &'a EdgeAdjacency,
    disc: Disc,
    triangles: Buffer<[u32; 3]>,
    vertices: Buffer<Vec3>,
    classes: (crate::model::BufferId, u64),
}

impl TaskKernel for FaceTest<'_> {
    /// (class of each face of the chunk, centre-behind silhouette faces).
    type Out = (Vec<Facing>, Vec<[Vec3; 3]>);

    fn run<P: Probe>(&self, p: &mut P, chunk: usize) -> Self::Out {
        let n = self.adj.triangles.len();
        let items = task_items(chunk, FACE_CHUNK, n);
        let mut classes = Vec::with_capacity(items.len());
        let mut faces = Vec::new();
        for (group, k, mask) in lane_groups(items) {
            let tris = self.triangles.load_run(p, group, k);
            for c in [0, 1, 2] {
                let idx: Lanes<u32> = std::array::from_fn(|l| tris.get(l).map_or(0, |t| t[c]));
                self.vertices.gather(p, &idx, mask);
            }
            p.vector(FACING_OPS, mask);
            for f in group..group + k {
                let (nrm, q) = normal(self.adj, f);
                let class = classify(nrm, q, &self.disc);
                if class == Facing::Silhouette && centre_behind(nrm, q, &self.disc) {
                    p.scalar(4);
                    faces.push(self.adj.triangles[f].map(|i| self.adj.vertices[i as usize]));
                }
                classes.push(class);
            }
            p.write(self.classes.0, self.classes.1 + group as u64, k as u32);
        }
        (classes, faces)
    }
}

/// The faces' classes seen across an edge: a boundary edge's missing face is the other side
/// of its only face (a one-sided surface seen from behind).
fn twin(f: Facing) -> Facing {
    match f {
        Facing::All => Facing::None,
        Facing::None => Facing::All,
        Facing::Silhouette => Facing::Silhouette,
    }
}

struct EdgeTest<'a> {
    adj: &'a EdgeAdjacency,
    classes: &'a [Facing],
    edges: Buffer<[u32; 4]>,
    class_buf: (crate::model::BufferId, u64),
    out: (crate::model::BufferId, u64),
}

impl TaskKernel for EdgeTest<'_> {
    type Out = Vec<VolumeEdge>;

    fn run<P: Probe>(&self, p: &mut P, chunk: usize) -> Self::Out {
        let mut found = Vec::new();
        scan_edges(p, &self.edges, chunk, |p, group, k, mask, recs| {
            for f in 2..4 {
                let faces: Lanes<u64> =
                    std::array::from_fn(|l| recs.get(l).map_or(0, |r| u64::from(r[f].min(r[2]))));
                if P::ENABLED {
                    let addrs = faces.map(|i| self.class_buf.1 + i);
                    p.gather(self.class_buf.0, &addrs, 1, mask);
                }
            }
            p.vector(EDGE_OPS, mask);
            for e in group..group + k {
                let edge = &self.adj.edges[e];
                let Some(&f0) = edge.faces.first() else {
                    continue;
                };
                let c0 = self.classes[f0 as usize];
                let (f1, c1) = match edge.faces.get(1) {
                    Some(&f1) => (f1, self.classes[f1 as usize]),
                    None => (f0, twin(c0)),
                };
                let umbra = (c0 == Facing::None) != (c1 == Facing::None);
                let penumbra = (c0 == Facing::All) != (c1 == Facing::All);
                if !(umbra || penumbra) {
                    continue;
                }
                let third = |f: u32| {
                    let t = self.adj.triangles[f as usize];
                    let i = t.iter().find(|&&i| i != edge.v[0] && i != edge.v[1]);
                    self.adj.vertices[*i.unwrap_or(&t[0]) as usize]
                };
                p.scalar(SILHOUETTE_EDGE_SCALAR);
                p.write(self.out.0, self.out.1 + (e as u64) * 48, 48);
                found.push(VolumeEdge {
                    w: edge.v,
                    v: edge.v.map(|i| self.adj.vertices[i as usize]),
                    q: [third(f0), third(f1)],
                    umbra,
                    penumbra,
                });
            }
        });
        found
    }
}

/// Phase `silhouettes`.
pub fn silhouettes(m: &mut Machine, adj: &EdgeAdjacency, disc: Disc) -> Silhouettes {
    m.phase(Phase::Silhouettes.name());
    let nf = adj.triangles.len();
    let faces = FaceTest {
        adj,
        disc,
        triangles: m
            .memory
            .buffer("adjacency.triangles", adj.triangles.clone()),
        vertices: m.memory.buffer("adjacency.vertices", adj.vertices.clone()),
        classes: m.memory.reserve("silhouette.face_classes", nf as u64),
    };
    let class_buf = faces.classes;
    let weights = task_weights(nf, FACE_CHUNK);
    let mut classes = Vec::with_capacity(nf);
    let mut umbra_faces = Vec::new();
    for (c, f) in m.run_step("faces", &faces, &weights) {
        classes.extend(c);
        umbra_faces.extend(f);
    }
    let ne = adj.edges.len();
    let test = EdgeTest {
        adj,
        classes: &classes,
        edges: m.memory.buffer("adjacency.edges", adj.edge_records()),
        class_buf,
        out: m.memory.reserve("silhouette.edges", ne as u64 * 48),
    };
    let weights = task_weights(ne, EDGE_CHUNK);
    let edges: Vec<VolumeEdge> = m
        .run_step("edges", &test, &weights)
        .into_iter()
        .flatten()
        .collect();
    let count = |f: Facing| classes.iter().filter(|&&c| c == f).count() as f64;
    m.count(names::SILHOUETTE_FACES_ALL_FRONT, count(Facing::All));
    m.count(names::SILHOUETTE_FACES_NONE_FRONT, count(Facing::None));
    let silhouette_faces = classes.iter().filter(|&&c| c == Facing::Silhouette).count();
    m.count(names::SILHOUETTE_SILHOUETTE_FACES, silhouette_faces as f64);
    m.count(
        names::SILHOUETTE_UMBRA_EDGES,
        edges.iter().filter(|e| e.umbra).count() as f64,
    );
    m.count(
        names::SILHOUETTE_PENUMBRA_EDGES,
        edges.iter().filter(|e| e.penumbra).count() as f64,
    );
    Silhouettes { edges, umbra_faces }
}

/// Triangles of one volume in world space; each vertex carries the depth of its silhouette edge
/// below the light plane and the reciprocal of its light-view depth (perspective-correct
/// interpolation).
#[derive(Clone, Debug, Default)]
pub struct VolumeMesh {
    pub positions: Vec<Vec3>,
    /// (edge depth `z_e`, 1 / light-view depth) per vertex.
    pub attributes: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
}

impl VolumeMesh {
    fn vertex(&mut self, view: &LightView, p: Vec3, z_e: f32) -> u32 {
        let w = -view.view.transform_point3(p).z;
        self.positions.push(p);
        self.attributes.push(Vec2::new(z_e, 1.0 / w));
        (self.positions.len() - 1) as u32
    }

    /// The quad of the edge `v1v2` extruded away from the disc point `p`.
    fn quad(&mut self, view: &LightView, disc: &Disc, v: [Vec3; 2], p: Vec3, length: f32) {
        let [z1, z2] = v.map(|x| disc.depth(x));
        let a = self.vertex(view, v[0], z1);
        let b = self.vertex(view, v[1], z2);
        let fa = self.vertex(view, far_point(view, v[0], p, length), z1);
        let fb = self.vertex(view, far_point(view, v[1], p, length), z2);
        self.triangles.push([a, b, fb]);
        self.triangles.push([a, fb, fa]);
    }

    /// A convex polygon (points with their edge depth) as a triangle fan.
    fn polygon(&mut self, view: &LightView, poly: &[(Vec3, f32)]) {
        if poly.len() < 3 {
            return;
        }
        let first = self.positions.len() as u32;
        for &(x, z) in poly {
            self.vertex(view, x, z);
        }
        for k in 1..poly.len() as u32 - 1 {
            self.triangles.push([first, first + k, first + k + 1]);
        }
    }

    fn append(&mut self, other: VolumeMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend(other.positions);
        self.attributes.extend(other.attributes);
        self.triangles
            .extend(other.triangles.into_iter().map(|t| t.map(|i| i + base)));
    }
}

/// The two volumes.
pub struct Volumes {
    pub umbra: VolumeMesh,
    pub penumbra: VolumeMesh,
}

/// Light-view depth at which the volumes end, just inside the light view's far plane (which
/// lies behind every point of the scene): both rasterizers then cover the same fragments (a GPU
/// clips at the far plane, the binned rasterizer only at the near plane).
const FAR_FRACTION: f32 = 0.999;

/// The far end of the volume edge from `v` away from the disc point `p`: where it reaches the
/// depth of [`FAR_FRACTION`] of the far plane (the volumes are infinite; nothing lies beyond),
/// or `length` along it when it does not recede from the light.
pub fn far_point(view: &LightView, v: Vec3, p: Vec3, length: f32) -> Vec3 {
    let depth = |x: Vec3| -view.view.transform_point3(x).z;
    let (dv, step) = (depth(v), depth(2.0 * v - p) - depth(v));
    let s = (FAR_FRACTION * view.far - dv) / step;
    if step > 1e-6 * (v - p).length() && s > 0.0 {
        v + s * (v - p)
    } else {
        extrude(v, p, length)
    }
}

/// Length the volumes are extruded by where [`far_point`] cannot use the far plane: past every
/// point of the scene seen from the light.
pub fn extrusion_length(frame: &Frame, disc: &Disc) -> f32 {
    let b = frame.scene.bounds();
    2.0 * (b.diagonal() + (b.center() - disc.c).length())
}

/// The plane of an umbra quad (through the edge and `p_u`), unit normal towards the light
/// centre: the umbra volume lies on that side of each of its planes.
fn umbra_plane(v: [Vec3; 2], pu: Vec3, c: Vec3) -> (Vec3, Vec3) {
    let m = (v[1] - v[0]).cross(pu - v[0]).normalize_or_zero();
    (if m.dot(c - v[0]) < 0.0 { -m } else { m }, v[0])
}

/// Sutherland–Hodgman: the part of the convex polygon `poly` on the positive side of the plane
/// `(m, o)`, edge depths interpolated along the cut edges.
fn clip(poly: &[(Vec3, f32)], (m, o): (Vec3, Vec3)) -> Vec<(Vec3, f32)> {
    let mut out = Vec::with_capacity(poly.len() + 1);
    for k in 0..poly.len() {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        let (da, db) = (m.dot(a.0 - o), m.dot(b.0 - o));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out.push((a.0.lerp(b.0, t), a.1 + (b.1 - a.1) * t));
        }
    }
    out
}

/// Step `extrude`: the extrusion points of every silhouette edge.
struct Points<'a> {
    edges: &'a [VolumeEdge],
    disc: Disc,
}

impl TaskKernel for Points<'_> {
    type Out = Vec<Option<(Vec3, Vec3)>>;

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Self::Out {
        let items = task_items(task, PRIM_CHUNK, self.edges.len());
        self.edges[items]
            .iter()
            .map(|e| {
                p.scalar(EXTRUDE_SCALAR);
                extrusion_points(e.v[0], e.v[1], e.q, &self.disc)
            })
            .collect()
    }
}

/// Step `quads`: the umbra quads, trimmed by the planes of the umbra quads they meet at convex
/// corners (§2.1, Figure 2b), and the penumbra quads.
struct Quads<'a> {
    edges: &'a [VolumeEdge],
    points: &'a [Option<(Vec3, Vec3)>],
    /// Umbra edges (with extrusion points) at each welded vertex.
    at_vertex: &'a BTreeMap<u32, Vec<usize>>,
    disc: Disc,
    view: &'a LightView,
    length: f32,
    out: (crate::model::BufferId, u64),
}

impl Quads<'_> {
    /// The umbra quad of edge `i` as a polygon, trimmed where a neighbouring umbra quad's plane
    /// cuts it: at a vertex shared with umbra edge `j` whose far ends each lie on the other's
    /// volume side (a convex corner), the part of `i` outside `j`'s plane is outside the umbra
    /// volume. Concave corners are left untrimmed. Returns the polygon and the planes applied.
    fn umbra_polygon<P: Probe>(&self, p: &mut P, i: usize, pu: Vec3) -> (Vec<(Vec3, f32)>, u32) {
        let e = &self.edges[i];
        let [z0, z1] = e.v.map(|x| self.disc.depth(x));
        let far = |x: Vec3| far_point(self.view, x, pu, self.length);
        let mut poly = vec![
            (e.v[0], z0),
            (e.v[1], z1),
            (far(e.v[1]), z1),
            (far(e.v[0]), z0),
        ];
        let plane_i = umbra_plane(e.v, pu, self.disc.c);
        let tol = 1e-5 * (e.v[1] - e.v[0]).length().max(1e-6);
        let mut planes = 0;
        for k in 0..2 {
            for &j in self.at_vertex.get(&e.w[k]).map_or(&[][..], |v| &v[..]) {
                if j == i {
                    continue;
                }
                p.scalar(TRIM_TEST_SCALAR);
                let ej = &self.edges[j];
                let Some((pu_j, _)) = self.points[j] else {
                    continue;
                };
                let plane_j = umbra_plane(ej.v, pu_j, self.disc.c);
                let other_i = e.v[1 - k];
                let other_j = if ej.w[0] == e.w[k] { ej.v[1] } else { ej.v[0] };
                let side = |(m, o): (Vec3, Vec3), x: Vec3| m.dot(x - o);
                if side(plane_j, other_i) >= -tol && side(plane_i, other_j) >= -tol {
                    p.scalar(CLIP_SCALAR * poly.len() as u32);
                    poly = clip(&poly, plane_j);
                    planes += 1;
                }
            }
        }
        (poly, planes)
    }
}

impl TaskKernel for Quads<'_> {
    /// (umbra quads, penumbra quads, each penumbra edge's vertices with its `p_p`, edges with
    /// no extrusion points, trimming planes applied).
    type Out = (
        VolumeMesh,
        VolumeMesh,
        Vec<([u32; 2], [Vec3; 2], Vec3)>,
        u32,
        u32,
    );

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Self::Out {
        let items = task_items(task, PRIM_CHUNK, self.edges.len());
        let (mut umbra, mut penumbra) = (VolumeMesh::default(), VolumeMesh::default());
        let mut ends = Vec::new();
        let (mut degenerate, mut trims) = (0, 0);
        for i in items {
            let e = &self.edges[i];
            let Some((pu, pp)) = self.points[i] else {
                degenerate += 1;
                continue;
            };
            let mut verts = 0;
            if e.umbra {
                let (poly, planes) = self.umbra_polygon(p, i, pu);
                trims += planes;
                verts += poly.len() as u32;
                umbra.polygon(self.view, &poly);
            }
            if e.penumbra {
                penumbra.quad(self.view, &self.disc, e.v, pp, self.length);
                ends.push((e.w, e.v, pp));
                verts += 4;
            }
            p.scalar(VERTEX_SCALAR * verts);
            p.write(self.out.0, self.out.1 + (i as u64) * 256, verts * 24);
        }
        (umbra, penumbra, ends, degenerate, trims)
    }
}

struct Close<'a> {
    ends: &'a [([u32; 2], [Vec3; 2], Vec3)],
    faces: &'a [[Vec3; 3]],
    disc: Disc,
    view: &'a LightView,
    length: f32,
    segments: u32,
    out: (crate::model::BufferId, u64),
}

impl TaskKernel for Close<'_> {
    /// (closing fans of the penumbra volume, silhouette faces of the umbra volume).
    type Out = (VolumeMesh, VolumeMesh);

    fn run<P: Probe>(&self, p: &mut P, _: usize) -> Self::Out {
        // Extrusion points of the penumbra edges meeting at each vertex.
        let mut at: BTreeMap<u32, (Vec3, Vec<Vec3>)> = BTreeMap::new();
        for (w, v, pp) in self.ends {
            for k in 0..2 {
                p.scalar(CLOSE_END_SCALAR);
                at.entry(w[k])
                    .or_insert_with(|| (v[k], Vec::new()))
                    .1
                    .push(*pp);
            }
        }
        let (u, v) = self.disc.n.any_orthonormal_pair();
        let angle = |q: Vec3| {
            let d = q - self.disc.c;
            d.dot(v).atan2(d.dot(u))
        };
        let mut fans = VolumeMesh::default();
        let mut written = 0u64;
        for (vertex, mut points) in at.into_values() {
            if points.len() < 2 {
                continue;
            }
            points.sort_by(|a, b| angle(*a).total_cmp(&angle(*b)));
            let n = points.len();
            let pairs = if n == 2 { 1 } else { n };
            for k in 0..pairs {
                let (from, to) = (points[k], points[(k + 1) % n]);
                let arc = rim_arc(from, to, self.segments, &self.disc);
                p.scalar(RIM_POINT_SCALAR * arc.len() as u32);
                let z = self.disc.depth(vertex);
                let apex = fans.vertex(self.view, vertex, z);
                let first = fans.positions.len() as u32;
                for q in &arc {
                    fans.vertex(self.view, far_point(self.view, vertex, *q, self.length), z);
                }
                for s in 0..self.segments {
                    fans.triangles.push([apex, first + s, first + s + 1]);
                }
                written += (arc.len() as u64 + 1) * 24;
            }
        }
        let mut faces = VolumeMesh::default();
        for f in self.faces {
            p.scalar(3 * VERTEX_SCALAR);
            // The face's edge nearest the light (its penumbra-silhouette side) stands for `e`.
            let z = f
                .map(|x| self.disc.depth(x))
                .into_iter()
                .fold(f32::INFINITY, f32::min);
            let [a, b, c] = f.map(|x| faces.vertex(self.view, x, z));
            faces.triangles.push([a, b, c]);
            written += 3 * 24;
        }
        p.write(
            self.out.0,
            self.out.1,
            written.min(u64::from(u32::MAX)) as u32,
        );
        (fans, faces)
    }
}

/// Phase `volumes`.
pub fn volumes(
    m: &mut Machine,
    frame: &Frame,
    s: &Silhouettes,
    disc: Disc,
    view: &LightView,
    o: &DbufferOptions,
) -> Volumes {
    m.phase(Phase::Volumes.name());
    let length = extrusion_length(frame, &disc);
    let n = s.edges.len();
    let weights = task_weights(n, PRIM_CHUNK);
    let points: Vec<Option<(Vec3, Vec3)>> = m
        .run_step(
            "extrude",
            &Points {
                edges: &s.edges,
                disc,
            },
            &weights,
        )
        .into_iter()
        .flatten()
        .collect();
    let mut at_vertex: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (i, e) in s.edges.iter().enumerate() {
        if e.umbra && points[i].is_some() {
            for w in e.w {
                at_vertex.entry(w).or_default().push(i);
            }
        }
    }
    let step = Quads {
        edges: &s.edges,
        points: &points,
        at_vertex: &at_vertex,
        disc,
        view,
        length,
        out: m.memory.reserve("volumes.quads", n as u64 * 256),
    };
    let (mut umbra, mut penumbra) = (VolumeMesh::default(), VolumeMesh::default());
    let mut ends = Vec::new();
    let (mut degenerate, mut trims) = (0, 0);
    for (u, pv, e, d, t) in m.run_step("quads", &step, &weights) {
        umbra.append(u);
        penumbra.append(pv);
        ends.extend(e);
        degenerate += d;
        trims += t;
    }
    let close = Close {
        ends: &ends,
        faces: &s.umbra_faces,
        disc,
        view,
        length,
        segments: o.closing_segments,
        out: m.memory.reserve(
            "volumes.closing",
            (ends.len() * 2 * (o.closing_segments as usize + 2) + s.umbra_faces.len() * 3) as u64
                * 24,
        ),
    };
    let (fans, faces) = m
        .run_step(
            "close",
            &close,
            &[ends.len() as u64 + s.umbra_faces.len() as u64 + 1],
        )
        .pop()
        .expect("one task");
    m.count(
        names::VOLUMES_UMBRA_QUADS,
        s.edges
            .iter()
            .zip(&points)
            .filter(|(e, p)| e.umbra && p.is_some())
            .count() as f64,
    );
    m.count(names::VOLUMES_UMBRA_TRIANGLES, umbra.triangles.len() as f64);
    m.count(names::VOLUMES_UMBRA_TRIM_PLANES, f64::from(trims));
    m.count(
        names::VOLUMES_PENUMBRA_QUADS,
        (penumbra.triangles.len() / 2) as f64,
    );
    m.count(
        names::VOLUMES_CLOSING_TRIANGLES,
        fans.triangles.len() as f64,
    );
    m.count(
        names::VOLUMES_SILHOUETTE_FACES,
        faces.triangles.len() as f64,
    );
    m.count(names::VOLUMES_DEGENERATE_EDGES, f64::from(degenerate));
    umbra.append(faces);
    penumbra.append(fans);
    Volumes { umbra, penumbra }
}

/// Phases `silhouettes` and `volumes`, on every core or on one ([`VolumeBuild`]).
pub fn build_volumes(
    m: &mut Machine,
    frame: &Frame,
    adj: &EdgeAdjacency,
    disc: Disc,
    view: &LightView,
    o: &DbufferOptions,
) -> Volumes {
    m.set_single_core(o.volume_build == VolumeBuild::SingleCore);
    let s = silhouettes(m, adj, disc);
    let v = volumes(m, frame, &s, disc, view, o);
    m.set_single_core(false);
    v
}
