//! Hard shadow volumes (Crow 1977, as used by paper 001 pass 1 and by its "1024-sample"
//! reference): one semi-infinite quad per silhouette edge, extruded away from a point on the
//! light, counted per pixel in a stencil or V-buffer.
//!
//! Two countings ([`Counting`], option `counting` of `soft_shadow_volume` and `accum_hard`):
//!
//! - **z-pass** (default): a quad fragment in front of the visible surface adds +1 when the quad
//!   faces the eye (the eye is on its outer side) and −1 otherwise, so a pixel's count is the
//!   number of shadow volumes its point lies in. A camera inside a shadow volume makes z-pass
//!   miss the volumes around the eye; the count is therefore started at the eye's own count (the
//!   light-facing occluder triangles the segment light→eye crosses, i.e. the front caps,
//!   [`eye_count`]), computed on the host.
//! - **z-fail** (paper 001, Paper II §5 "Eye Inside Shadow Regions", after Everitt and Kilgard):
//!   the volume is closed ([`zfail_faces`]): the hard shadow quads cut at a far distance, the
//!   *top* (light cap: the occluder triangles facing the light point) and a *bottom* (dark cap:
//!   the same triangles projected away from the light to that distance). Fragments at or behind
//!   the visible surface count, back faces +1, front faces −1 ("increment ... when the polygon is
//!   equal to or farther than the stored z-depth"), so the count is the number of volumes the
//!   point lies in whatever the eye's position, with no eye count. Our ray-cast rasterization
//!   has no far plane for z-fail (as with Everitt and Kilgard's infinite far plane): a fragment
//!   counts from the ray's entry into the scene bounds on, the dark cap lies beyond the bounds.
//!   Open occluder surfaces are capped by their light-facing triangles only, as [`eye_count`]
//!   counts them; an open surface facing away from the light gets no cap, so its volume leaks:
//!   runs on occluders with boundary or non-manifold edges count with z-pass instead, with a
//!   warning (`algorithms::run`).
//!
//! Coverage of quads and faces (and of the eye count's triangles) follows the one tie rule of
//! [`coverage`]: a ray through an edge or corner shared by two faces crosses exactly one.

pub mod raster;
pub mod wgpu;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::eye_raster::{raster_pass, Block, EyeBuffer, EyeRays, ScreenRect, TilePass};
use crate::counters::names;
use crate::model::{Machine, Mask, Probe, LANES};
use crate::scene::adjacency::SilhouetteEdge;
use crate::scene::{coverage, Bounds, Mesh};

/// How a hard shadow-volume pass counts (option `counting`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Counting {
    /// Fragments in front of the visible surface, from the eye's count.
    #[default]
    ZPass,
    /// Fragments at or behind the visible surface of the capped volume (Paper II §5).
    ZFail,
}

impl Counting {
    /// The count a pass at light point `light` starts from at the eye: [`eye_count`] for
    /// z-pass, 0 for z-fail (which needs none).
    pub fn eye_start(self, occluders: &Mesh, light: Vec3, eye: Vec3) -> i32 {
        match self {
            Counting::ZPass => eye_count(occluders, light, eye),
            Counting::ZFail => 0,
        }
    }
}

/// How the `wgpu` execution of a shadow-volume algorithm renders (option `gpu_pipeline` of
/// `soft_shadow_volume` and `accum_hard`; recorded as `execution.gpu_pipeline`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GpuPipeline {
    /// As the thesis renders it: the hard shadow quads (or capped volumes) rasterized with the
    /// depth test into a count target by additive blending ([`raster`], III §3.2.1); then
    /// `soft_shadow_volume` rasterizes each wedge's front faces with a fragment shader adding
    /// or subtracting the coverage into the V-buffer by additive blending (III §3.2.2, §4; IV
    /// §4), and `accum_hard` blends each sample's lit pixels into an accumulation target
    /// (III §5.1).
    #[default]
    Raster,
    /// Compute passes over the eye pixels: each pixel walks the quads (and wedge primitives)
    /// binned to its 8×8 tile on the host and casts its eye ray against them, as the cpu
    /// executions do ([`wgpu`]).
    Gather,
}

/// The hard shadow quad of silhouette edge `a→b` from light point `light` (paper 001 III §3.2.1):
/// the part of the plane through `a`, `b`, `light` beyond the edge and between the rays from the
/// light through `a` and `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowQuad {
    pub a: Vec3,
    pub b: Vec3,
    pub light: Vec3,
    /// `(a − l) × (b − l)`: points on its positive side are outside the volume (the paper's
    /// positive half-space of Q), points on its negative side are towards the umbra.
    pub normal: Vec3,
}

impl ShadowQuad {
    pub fn new(edge: &SilhouetteEdge, light: Vec3) -> ShadowQuad {
        ShadowQuad {
            a: edge.a,
            b: edge.b,
            light,
            normal: (edge.a - light).cross(edge.b - light),
        }
    }

    /// +1 on the outer (positive) side of the quad's plane, −1 on the inner side.
    pub fn side(&self, p: Vec3) -> f32 {
        if self.normal.dot(p - self.light) >= 0.0 {
            1.0
        } else {
            -1.0
        }
    }

    /// Distance along `o + t·d` to the quad, if the ray meets it. Coverage follows the one
    /// tie rule ([`coverage::line_crosses`]) over the quad's boundary lines `l → a`, `b → l` and
    /// `b → a` (the quad `a`, far `a`, far `b`, `b` wound around `normal`), so a ray through the
    /// line from the light through a vertex shared by two quads crosses exactly one of them.
    pub fn ray_hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
        self.from(o).hit(d)
    }

    /// The quad's ray test for rays from `o` with everything that does not depend on the ray's
    /// direction computed once.
    pub fn from(&self, o: Vec3) -> FaceFrom {
        let (l, a, b) = (self.light, self.a, self.b);
        FaceFrom::new(o, self.normal, l, &[(l, a), (b, l), (b, a)])
    }

    /// Corners of the quad cut at distance `reach` (the scene size) beyond its edge.
    pub fn hull(&self, reach: f32) -> [Vec3; 4] {
        let ab = self.b - self.a;
        let s = ((self.light - self.a).dot(ab) / ab.length_squared().max(1e-20)).clamp(0.0, 1.0);
        let nearest = (self.a + ab * s - self.light).length().max(1e-6);
        let k = reach / nearest;
        [
            self.a,
            self.b,
            self.b + (self.b - self.light) * k,
            self.a + (self.a - self.light) * k,
        ]
    }
}

/// What the stencil (or V-buffer) pass of a set of shadow quads did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HardPass {
    /// Per pixel: the number of shadow volumes its point is in (eye count included).
    pub count: Vec<i32>,
    /// Volume fragments rasterized (z-pass: within the scene bounds or in front of the visible
    /// surface; z-fail: from the entry into the scene bounds on).
    pub fill: u64,
    /// Fragments that passed the depth test (z-pass: in front, z-fail: at or behind the visible
    /// surface) and changed the count.
    pub passed: u64,
    /// The value the buffer is cleared to: the eye's own count (z-pass), 0 (z-fail).
    pub eye_count: i32,
    /// Cap faces rendered (light and dark caps, z-fail only).
    pub caps: u64,
}

/// z-fail counting closes each shadow volume with caps and is only right for closed
/// 2-manifold occluders: on an open or non-manifold mesh the volumes leak and streaks cross the
/// image. Such runs of algorithm `id` (`soft_shadow_volume`, `accum_hard`) fall back to z-pass
/// (from the eye's count, right wherever the eye is outside the shadow): sets `counting` to
/// [`Counting::ZPass`] and returns the run's warning naming the algorithm, the option and the
/// open edges; `None` (unchanged) for closed occluders or z-pass.
pub fn zfail_fallback(
    id: &str,
    frame: &crate::frame::Frame,
    counting: &mut Counting,
) -> Option<String> {
    let edges = frame.occluder_edges;
    if *counting != Counting::ZFail || edges.open() == 0 {
        return None;
    }
    *counting = Counting::ZPass;
    Some(format!(
        "{id}: options.{id}.counting \"z_fail\" needs closed occluders, but they have {} open \
         edges ({} boundary, {} non-manifold): counted with \"z_pass\" instead",
        edges.open(),
        edges.boundary,
        edges.non_manifold
    ))
}

/// The eye's shadow-volume count for light point `light`: the light-facing triangles of
/// `occluders` crossed by the segment from the light to `eye` (each the front cap of its
/// volume).
pub fn eye_count(occluders: &Mesh, light: Vec3, eye: Vec3) -> i32 {
    let d = eye - light;
    (0..occluders.triangles.len())
        .filter(|&t| {
            let [a, b, c] = occluders.triangle(t);
            let n = (b - a).cross(c - a);
            n.dot(light - a) > 0.0 && segment_hits_triangle(light, d, a, b, c)
        })
        .count() as i32
}

/// Whether the segment `o + t·d`, `t ∈ (0, 1)`, crosses triangle `a b c` under the one tie rule
/// ([`coverage::line_crosses`]), so that a segment through an edge shared by two front caps
/// counts one volume.
fn segment_hits_triangle(o: Vec3, d: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let n = (b - a).cross(c - a);
    let nd = n.dot(d);
    if nd == 0.0 || !coverage::line_crosses(o, d, n, &[(a, b), (b, c), (c, a)]) {
        return false;
    }
    let t = n.dot(a - o) / nd;
    t > 0.0 && t < 1.0
}

/// A face's ray test ([`ShadowQuad::ray_hit`], [`VolumeFace::ray_hit`]) for the rays from one
/// origin `o` (the eye): what does not depend on the ray's direction `d` is computed once per
/// face, as a rasterizer sets up a triangle's edge equations once. Every ray from `o` lies in
/// the plane through `o`, `p`, `q` on the side [`coverage::edge_function`] gives by
/// `d · ((p − o) × (q − o))`, so per edge only that cross product is kept (taken from the
/// lexicographically smaller endpoint, as `edge_function` takes it, so the values are the same
/// to the bit), and per ray remain a dot product per edge and the plane's.
#[derive(Clone, Copy, Debug)]
pub struct FaceFrom {
    normal: Vec3,
    /// `1e-12 · |normal|`: rays nearer parallel to the face than this miss it.
    parallel: f32,
    /// `normal · (corner − o)`: a ray meets the plane at this over `normal · d`.
    plane: f32,
    edges: [FromEdge; 4],
    sides: usize,
}

/// One directed boundary edge `p → q` of a [`FaceFrom`].
#[derive(Clone, Copy, Debug, Default)]
struct FromEdge {
    /// `(p − o) × (q − o)`, or `(q − o) × (p − o)` where `q` precedes `p` (then `negate`).
    cross: Vec3,
    negate: bool,
    p: Vec3,
    q: Vec3,
}

impl FaceFrom {
    /// The face of `normal` through `corner` bounded by the directed `edges` (at most 4), seen
    /// from `o`.
    fn new(o: Vec3, normal: Vec3, corner: Vec3, edges: &[(Vec3, Vec3)]) -> FaceFrom {
        let mut e = [FromEdge::default(); 4];
        for (out, &(p, q)) in e.iter_mut().zip(edges) {
            let (cross, negate) = coverage::edge_plane(o, p, q);
            *out = FromEdge {
                cross,
                negate,
                p,
                q,
            };
        }
        FaceFrom {
            normal,
            parallel: 1e-12 * normal.length(),
            plane: normal.dot(corner - o),
            edges: e,
            sides: edges.len(),
        }
    }

    /// Distance along `o + t·d` to the face, if the ray meets it, under the one tie rule
    /// ([`coverage::line_crosses`]).
    #[inline]
    pub fn hit(&self, d: Vec3) -> Option<f32> {
        let nd = self.normal.dot(d);
        if nd.abs() < self.parallel {
            return None;
        }
        let t = self.plane / nd;
        (t > 0.0 && self.crosses(d, nd)).then_some(t)
    }

    /// [`coverage::line_crosses`] for the ray along `d` with `s = d · normal`: with `s > 0`
    /// every edge function positive, with `s < 0` every one of the reversed edges (the
    /// negated value, its tie decided for `q → p`).
    #[inline]
    fn crosses(&self, d: Vec3, s: f32) -> bool {
        let edges = &self.edges[..self.sides];
        let value = |e: &FromEdge| {
            let v = d.dot(e.cross);
            if e.negate {
                -v
            } else {
                v
            }
        };
        if s > 0.0 {
            edges.iter().all(|e| {
                let v = value(e);
                v > 0.0 || (v == 0.0 && coverage::tie_owner(d, e.p, e.q))
            })
        } else if s < 0.0 {
            edges.iter().all(|e| {
                let v = value(e);
                v < 0.0 || (v == 0.0 && coverage::tie_owner(d, e.q, e.p))
            })
        } else {
            false
        }
    }
}

/// Vector instructions per block of a shadow quad seen from the eye ([`FaceFrom`], set up once
/// per quad on the host with its footprint): the ray–plane intersection (a 3-term dot, the
/// edge-on test as an absolute value and a compare, a divide, the sign test), the three edge
/// tests (a 3-term dot with the edge's precomputed plane, the orientation's sign select and a
/// compare each), and the scene-bounds slab test (per axis a reciprocal, two multiply-adds, a
/// min, a max; then the interval compares).
pub const QUAD_HIT_OPS: u32 = 5 + 2 + 1 + 1 + 3 * (5 + 1 + 1) + 3 * 5 + 4;
/// The depth test: compare with the visible surface's depth, mask and.
pub const DEPTH_TEST_OPS: u32 = 2;
/// The count update: select the quad's ±1, add.
pub const COUNT_OPS: u32 = 2;

/// A face of the closed shadow volume of z-fail counting (Paper II §5): a side (the hard shadow
/// quad of a silhouette edge cut at the far distance), a light cap or a dark cap triangle.
/// Corners run counter-clockwise around `normal`, which points out of the volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolumeFace {
    pub corners: [Vec3; 4],
    /// 3 (cap triangle) or 4 (side quad).
    pub sides: u32,
    pub normal: Vec3,
}

impl VolumeFace {
    /// Distance along `o + t·d` to the face, if the ray meets it, under the one tie rule
    /// ([`coverage::line_crosses`], as [`ShadowQuad::ray_hit`]): the faces of a closed volume
    /// share their corners exactly, so a ray through an edge or corner crosses the volume's
    /// boundary once per entry or exit.
    pub fn ray_hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
        self.from(o).hit(d)
    }

    /// The face's ray test for rays from `o` with everything that does not depend on the ray's
    /// direction computed once.
    pub fn from(&self, o: Vec3) -> FaceFrom {
        let c = &self.corners;
        let k = self.sides as usize;
        let edges: [(Vec3, Vec3); 4] = std::array::from_fn(|i| (c[i % k], c[(i + 1) % k]));
        FaceFrom::new(o, self.normal, c[0], &edges[..k])
    }

    /// +1 on the outer side of the face's plane, −1 on the inner side.
    pub fn side(&self, p: Vec3) -> f32 {
        if self.normal.dot(p - self.corners[0]) >= 0.0 {
            1.0
        } else {
            -1.0
        }
    }

    /// Vector instructions per block: [`QUAD_HIT_OPS`] with one edge test per side.
    pub fn hit_ops(&self) -> u32 {
        QUAD_HIT_OPS + (self.sides - 3) * (5 + 1 + 1)
    }
}

/// The distance from the light point at which z-fail closes its volumes: twice the farthest
/// corner of `bounds`, so that every point of the scene in a volume's cone is in front of the
/// dark cap. The dark cap's triangles and the sides' far edges are flat chords of that sphere:
/// they stay beyond the scene as long as no light-facing triangle or silhouette edge spans more
/// than 120° seen from the light (a chord's middle is at `cos(angle / 2)` of the distance).
pub fn dark_cap_distance(bounds: &Bounds, light: Vec3) -> f32 {
    2.0 * bounds
        .corners()
        .iter()
        .map(|c| (*c - light).length())
        .fold(0.0f32, f32::max)
        .max(1e-3)
}

/// Vertex `v` projected from `light` to distance `reach` ([`dark_cap_distance`]): computed
/// from `v` and `light` alone, so every face through `v` (the sides of two adjacent shadow
/// quads, a cap) gets the same point to the bit and the faces close up exactly.
pub fn far_point(light: Vec3, v: Vec3, reach: f32) -> Vec3 {
    light + (v - light) * (reach / (v - light).length().max(1e-20))
}

/// Whether triangle `t` of `occluders` faces `light` (the predicate of [`eye_count`]).
fn faces_light(occluders: &Mesh, t: usize, light: Vec3) -> bool {
    let [a, b, c] = occluders.triangle(t);
    (b - a).cross(c - a).dot(light - a) > 0.0
}

/// The closed shadow volumes of z-fail counting (Paper II §5) for light point `light`: per
/// silhouette quad a side cut at [`dark_cap_distance`] from the light, then the top (the
/// occluder triangles facing the light) and the bottom (those triangles projected from the
/// light to that distance, reversed so that they face out). A vertex is projected to the same
/// point by every face that uses it, so the faces close up exactly.
pub fn zfail_faces(
    quads: &[ShadowQuad],
    occluders: &Mesh,
    light: Vec3,
    bounds: &Bounds,
) -> Vec<VolumeFace> {
    let reach = dark_cap_distance(bounds, light);
    let far = |v: Vec3| far_point(light, v, reach);
    let mut faces: Vec<VolumeFace> = quads
        .iter()
        .map(|q| VolumeFace {
            corners: [q.a, far(q.a), far(q.b), q.b],
            sides: 4,
            normal: q.normal,
        })
        .collect();
    let top: Vec<[Vec3; 3]> = (0..occluders.triangles.len())
        .filter(|&t| faces_light(occluders, t, light))
        .map(|t| occluders.triangle(t))
        .collect();
    for &[a, b, c] in &top {
        faces.push(VolumeFace {
            corners: [a, b, c, c],
            sides: 3,
            normal: (b - a).cross(c - a),
        });
    }
    for &[a, b, c] in &top {
        let [a, c, b] = [far(a), far(c), far(b)];
        faces.push(VolumeFace {
            corners: [a, c, b, b],
            sides: 3,
            normal: (c - a).cross(b - a),
        });
    }
    faces
}

/// Where a hard shadow-volume pass counts: the count buffer (a V-buffer or a stencil) and the
/// eye depth it tests against, and whether it clears the count buffer first (counted as writes).
pub struct CountTarget {
    pub depth: EyeBuffer,
    pub count: EyeBuffer,
    pub clear: bool,
}

struct QuadPass<'a> {
    rays: &'a EyeRays,
    /// Per face its ray test from the eye and its vector instructions per block.
    faces: Vec<(FaceFrom, u32)>,
    /// Per face the count change of a passing fragment: z-pass +1 for a face whose outer side
    /// the eye is on, z-fail the opposite.
    steps: Vec<i32>,
    counting: Counting,
    eye_count: i32,
    target: &'a CountTarget,
}

struct QuadTile {
    rect: ScreenRect,
    count: Vec<i32>,
    fill: u64,
    passed: u64,
}

impl TilePass for QuadPass<'_> {
    type State = QuadTile;

    fn begin<P: Probe>(&self, p: &mut P, rect: ScreenRect) -> QuadTile {
        if self.target.clear {
            for b in Block::cover(self.rays, rect) {
                self.target.count.write(p, &b, b.mask);
            }
        }
        QuadTile {
            rect,
            count: vec![self.eye_count; ((rect.x1 - rect.x0) * (rect.y1 - rect.y0)) as usize],
            fill: 0,
            passed: 0,
        }
    }

    fn block<P: Probe>(&self, p: &mut P, s: &mut QuadTile, k: usize, b: &Block) {
        let rays = self.rays;
        let (face, ops) = &self.faces[k];
        p.vector(*ops, b.mask);
        let mut passes = [false; LANES];
        // Fill: the fragments within the scene bounds (z-fail: from the entry on) or passing
        // the depth test. z-pass counts every crossing in front of the visible surface, also
        // one before the ray enters the bounds (a volume reaching out of them towards the eye:
        // the eye's count is the eye's, not the bounds'); z-fail the crossings at or behind it.
        // Lanes outside the mask may lie past the image edge: never index with them.
        let fill = Mask::from_fn(|l| {
            if !b.mask.get(l) {
                return false;
            }
            let i = b.pixel[l] as usize;
            let Some(t) = face.hit(rays.dir[i]) else {
                return false;
            };
            let (t0, t1) = rays.bounds_interval(i);
            let depth = rays.depth[i];
            let (inside, pass) = match self.counting {
                Counting::ZPass => (t >= t0 && t <= t1, t < depth),
                Counting::ZFail => (t >= t0, t >= t0 && t >= depth),
            };
            passes[l] = pass;
            inside || pass
        });
        if !fill.any() {
            return;
        }
        self.target.depth.read(p, b, fill);
        p.vector(DEPTH_TEST_OPS, fill);
        let passed = Mask::from_fn(|l| fill.get(l) && passes[l]);
        s.fill += u64::from(fill.count());
        s.passed += u64::from(passed.count());
        if !passed.any() {
            return;
        }
        self.target.count.read(p, b, passed);
        p.vector(COUNT_OPS, passed);
        let w = s.rect.x1 - s.rect.x0;
        for l in passed.lanes() {
            let (x, y) = b.lane_xy(l);
            s.count[((y - s.rect.y0) * w + x - s.rect.x0) as usize] += self.steps[k];
        }
        self.target.count.write(p, b, passed);
    }
}

/// The screen footprints of `quads`, cut at twice the scene's size beyond their edges.
pub fn quad_footprints(rays: &EyeRays, quads: &[ShadowQuad]) -> Vec<Option<ScreenRect>> {
    let reach = 2.0 * rays.bounds.diagonal();
    quads
        .iter()
        .map(|q| rays.footprint(&q.hull(reach)))
        .collect()
}

/// The screen footprints of z-fail volume faces (their corners).
pub fn face_footprints(rays: &EyeRays, faces: &[VolumeFace]) -> Vec<Option<ScreenRect>> {
    faces
        .iter()
        .map(|f| rays.footprint(&f.corners[..f.sides as usize]))
        .collect()
}

/// The closing of a hard pass's count.
#[derive(Clone, Copy)]
pub enum HardCounting<'a> {
    /// z-pass from the eye's count ([`eye_count`]).
    ZPass { eye_count: i32 },
    /// z-fail over the volumes from light point `light` closed with the light-facing triangles
    /// of `occluders` ([`zfail_faces`]).
    ZFail { occluders: &'a Mesh, light: Vec3 },
}

/// Renders the hard shadow volumes of `quads` into a count
/// buffer (tiles of `tile` pixels), as step `step` of the machine's current phase: z-pass into a
/// buffer cleared to the eye's count, or z-fail over the capped volumes into a buffer cleared
/// to 0.
pub fn render_hard(
    m: &mut Machine,
    step: &str,
    rays: &EyeRays,
    quads: &[ShadowQuad],
    counting: HardCounting,
    tile: u32,
    target: &CountTarget,
) -> HardPass {
    match counting {
        HardCounting::ZPass { eye_count } => {
            let footprints = quad_footprints(rays, quads);
            let pass = QuadPass {
                rays,
                faces: quads
                    .iter()
                    .map(|q| (q.from(rays.eye), QUAD_HIT_OPS))
                    .collect(),
                steps: quads.iter().map(|q| q.side(rays.eye) as i32).collect(),
                counting: Counting::ZPass,
                eye_count,
                target,
            };
            collect(m, step, rays, &footprints, tile, &pass, 0)
        }
        HardCounting::ZFail { occluders, light } => {
            let faces = zfail_faces(quads, occluders, light, &rays.bounds);
            let footprints = face_footprints(rays, &faces);
            let pass = QuadPass {
                rays,
                faces: faces
                    .iter()
                    .map(|f| (f.from(rays.eye), f.hit_ops()))
                    .collect(),
                steps: faces.iter().map(|f| -(f.side(rays.eye) as i32)).collect(),
                counting: Counting::ZFail,
                eye_count: 0,
                target,
            };
            let caps = (faces.len() - quads.len()) as u64;
            collect(m, step, rays, &footprints, tile, &pass, caps)
        }
    }
}

fn collect(
    m: &mut Machine,
    step: &str,
    rays: &EyeRays,
    footprints: &[Option<ScreenRect>],
    tile: u32,
    pass: &QuadPass<'_>,
    caps: u64,
) -> HardPass {
    let tiles = raster_pass(m, step, rays, footprints, tile, pass);
    let mut out = HardPass {
        count: vec![pass.eye_count; rays.len()],
        eye_count: pass.eye_count,
        caps,
        ..Default::default()
    };
    for t in tiles {
        let s = t.state;
        out.fill += s.fill;
        out.passed += s.passed;
        let w = s.rect.x1 - s.rect.x0;
        for y in s.rect.y0..s.rect.y1 {
            for x in s.rect.x0..s.rect.x1 {
                out.count[(y * rays.width + x) as usize] =
                    s.count[((y - s.rect.y0) * w + x - s.rect.x0) as usize];
            }
        }
    }
    out
}

/// Counts `bytes` read from named buffer `buffer` (`mem.<buffer>.read_bytes` and the total) on
/// `cpu-native`, where no probe counts them; on `cpu-model` the probe counts every access.
pub fn mem_read(m: &mut Machine, buffer: &str, bytes: u64) {
    if !m.is_model() {
        m.count(&format!("mem_est.{buffer}.read_bytes"), bytes as f64);
        m.count(names::MEM_EST_READ_BYTES, bytes as f64);
    }
}

/// Counts `bytes` written to named buffer `buffer` (`mem.<buffer>.write_bytes` and the total) on
/// `cpu-native`, as [`mem_read`].
pub fn mem_write(m: &mut Machine, buffer: &str, bytes: u64) {
    if !m.is_model() {
        m.count(&format!("mem_est.{buffer}.write_bytes"), bytes as f64);
        m.count(names::MEM_EST_WRITE_BYTES, bytes as f64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::algorithm::{Backend, ExecContext};
    use crate::algorithms::exec::machine;
    use crate::frame::{Frame, RunParams};
    use crate::scene::adjacency::EdgeAdjacency;
    use crate::scene::generators::{self, GeneratorParams};

    /// A 64×48 frame of generated scene `name`, seen from `eye` towards `target` when given.
    fn frame(name: &str, view: Option<(Vec3, Vec3)>) -> Frame {
        let mut scene = generators::find(name)
            .unwrap()
            .build(&GeneratorParams::default());
        if let Some((eye, target)) = view {
            scene.camera.eye = eye;
            scene.camera.target = target;
        }
        let params = RunParams::of_scene(&scene, [64, 48], 256, 16);
        Frame::new(scene, params)
    }

    /// The hard pass of the light centre's silhouette, counted as `counting` says.
    fn hard_pass(frame: &Frame, counting: impl Fn(&Mesh, Vec3, Vec3) -> HardCounting) -> HardPass {
        let mut m = machine(Backend::CpuNative, frame, &ExecContext::default());
        m.phase("hard");
        let rays = EyeRays::new(frame);
        let occluders = frame.scene.occluders();
        let light = frame.scene.light.center();
        let quads: Vec<ShadowQuad> = EdgeAdjacency::build(&occluders)
            .silhouette_from(light)
            .edges
            .iter()
            .map(|e| ShadowQuad::new(e, light))
            .collect();
        let target = CountTarget {
            depth: EyeBuffer::new(&mut m, &rays, "depth", 4),
            count: EyeBuffer::new(&mut m, &rays, "stencil", 1),
            clear: true,
        };
        let counting = counting(&occluders, light, rays.eye);
        render_hard(&mut m, "stencil", &rays, &quads, counting, 16, &target)
    }

    /// Pixels (with a surface) whose count differs from the independent count: the light-facing
    /// occluder triangles the segment from the light to the pixel's point crosses.
    fn wrong_pixels(frame: &Frame, pass: &HardPass) -> (usize, usize) {
        let rays = EyeRays::new(frame);
        let occluders = frame.scene.occluders();
        let light = frame.scene.light.center();
        let hits: Vec<usize> = (0..rays.len()).filter(|&i| rays.is_hit(i)).collect();
        let wrong = hits
            .iter()
            .filter(|&&i| pass.count[i] != eye_count(&occluders, light, rays.point[i]))
            .count();
        (wrong, hits.len())
    }

    /// The raster pipeline's z-pass quads cut their side lines at one point per silhouette
    /// vertex: two quads through a vertex share that side to the bit (as z-fail's volumes do),
    /// so the rasterizer covers a pixel along it once. The distinct corners of the triangles
    /// are the silhouette's vertices and one far point each.
    #[test]
    fn neighbouring_raster_quads_share_their_sides_to_the_bit() {
        let f = frame("box-on-plane", None);
        let rays = EyeRays::new(&f);
        let occluders = f.scene.occluders();
        let light = f.scene.light.center() + Vec3::new(0.123, 0.0, -0.071);
        let quads: Vec<ShadowQuad> = EdgeAdjacency::build(&occluders)
            .silhouette_from(light)
            .edges
            .iter()
            .map(|e| ShadowQuad::new(e, light))
            .collect();
        let (vertices, _) =
            raster::hard_triangles(&rays, &quads, Counting::ZPass, &occluders, light);
        let bits = |p: Vec3| p.to_array().map(f32::to_bits);
        let mut silhouette: Vec<[u32; 3]> =
            quads.iter().flat_map(|q| [bits(q.a), bits(q.b)]).collect();
        silhouette.sort_unstable();
        silhouette.dedup();
        let mut corners: Vec<[u32; 3]> = vertices
            .iter()
            .map(|v| bits(Vec3::from_slice(&v.position[..3])))
            .collect();
        corners.sort_unstable();
        corners.dedup();
        assert!(quads.len() >= 4, "{} quads", quads.len());
        assert_eq!(corners.len(), 2 * silhouette.len());
    }

    /// The ray test set up once per face ([`FaceFrom`]) gives, for every direction, the
    /// distance and coverage of the plane intersection and the general line–face test of
    /// `scene::coverage` ([`coverage::line_crosses`] over the face's boundary) to the bit:
    /// directions scattered over the sphere, and directions through the faces' corners and
    /// edge midpoints, where the tie rule decides.
    #[test]
    fn a_face_set_up_from_the_eye_hits_what_the_general_line_test_hits() {
        // A fixed sequence in [-1, 1) (xorshift), so the test is the same every run.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 23) as f32 - 1.0
        };
        let mut v3 = || Vec3::new(next(), next(), next());
        let o = Vec3::new(0.25, 3.0, -0.5);
        let mut checked = (0, 0);
        for _ in 0..40 {
            let light = v3() * 4.0 + Vec3::Y * 6.0;
            let (a, b) = (v3(), v3());
            let quad = ShadowQuad {
                a,
                b,
                light,
                normal: (a - light).cross(b - light),
            };
            let corners = [v3(), v3(), v3(), v3()];
            let face = VolumeFace {
                corners: [corners[0], corners[1], corners[2], corners[2]],
                sides: 3,
                normal: (corners[1] - corners[0]).cross(corners[2] - corners[0]),
            };
            let faces = [
                (
                    quad.from(o),
                    quad.normal,
                    light,
                    vec![(light, a), (b, light), (b, a)],
                ),
                (
                    face.from(o),
                    face.normal,
                    corners[0],
                    vec![
                        (corners[0], corners[1]),
                        (corners[1], corners[2]),
                        (corners[2], corners[0]),
                    ],
                ),
            ];
            for (from, n, corner, edges) in &faces {
                let mut dirs: Vec<Vec3> = (0..200).map(|_| v3()).collect();
                for &(p, q) in edges {
                    dirs.extend([p - o, q - o, (p + q) * 0.5 - o, a + (a - light) - o]);
                }
                // Towards a point inside the face: a hit unless the face is seen edge-on.
                let mid = (a + b) * 0.5;
                dirs.push(if *corner == light {
                    mid + (mid - light) * 0.5 - o
                } else {
                    (corners[0] + corners[1] + corners[2]) / 3.0 - o
                });
                for d in dirs {
                    let nd = n.dot(d);
                    let expected = if nd.abs() < 1e-12 * n.length() {
                        None
                    } else {
                        let t = n.dot(*corner - o) / nd;
                        (t > 0.0 && coverage::line_crosses(o, d, *n, edges)).then_some(t)
                    };
                    let got = from.hit(d);
                    assert_eq!(got.map(f32::to_bits), expected.map(f32::to_bits), "d {d}");
                    checked.0 += 1;
                    checked.1 += usize::from(got.is_some());
                }
            }
        }
        // Both outcomes occur often enough to mean something (80 faces aimed at).
        assert!(
            checked.1 >= 80 && checked.0 - checked.1 >= 80,
            "{checked:?}"
        );
    }

    /// z-fail over the capped volumes (Paper II §5) counts, at every visible point, the volumes
    /// the point lies in, with the eye outside the shadow or inside the umbra of a closed plate
    /// and of a tessellated box; so does z-pass from the eye's count, while z-pass from 0 is
    /// wrong on many pixels when the eye is in shadow (what the eye count and z-fail fix). A
    /// few pixels whose rays graze a shared edge or a silhouette vertex may count a face twice
    /// or miss it (as a rasterizer without a tie rule would); we allow 0.5% of the pixels.
    #[test]
    fn zfail_counts_the_volumes_of_every_point_wherever_the_eye_is() {
        let cases = [
            ("plate-on-plane", None, false),
            (
                "plate-on-plane",
                Some((Vec3::new(0.3, 0.8, 0.2), Vec3::new(3.0, 0.0, 2.0))),
                true,
            ),
            ("box-on-plane", None, false),
            (
                "box-on-plane",
                Some((Vec3::new(0.1, 0.4, -0.2), Vec3::new(-2.0, 0.0, 3.0))),
                true,
            ),
        ];
        for (name, view, eye_in_shadow) in cases {
            let f = frame(name, view);
            let light = f.scene.light.center();
            let eye = eye_count(&f.scene.occluders(), light, f.scene.camera.eye);
            assert_eq!(eye > 0, eye_in_shadow, "{name}: eye count {eye}");
            let zfail = hard_pass(&f, |occluders, light, _| HardCounting::ZFail {
                occluders,
                light,
            });
            let zpass = hard_pass(&f, |occluders, light, eye| HardCounting::ZPass {
                eye_count: eye_count(occluders, light, eye),
            });
            let zpass_0 = hard_pass(&f, |_, _, _| HardCounting::ZPass { eye_count: 0 });
            let (wrong_fail, n) = wrong_pixels(&f, &zfail);
            let (wrong_pass, _) = wrong_pixels(&f, &zpass);
            let (wrong_pass_0, _) = wrong_pixels(&f, &zpass_0);
            crate::errln!(
                "{name} eye count {eye}: of {n} pixels z-fail {wrong_fail}, z-pass {wrong_pass}, \
                 z-pass from 0 {wrong_pass_0} wrong; fill z-fail {} z-pass {}, caps {}",
                zfail.fill,
                zpass.fill,
                zfail.caps
            );
            let shadowed = zfail.count.iter().filter(|&&c| c > 0).count();
            assert!(shadowed > n / 50, "{name}: too little shadow ({shadowed})");
            assert!(shadowed < n, "{name}: no lit pixel");
            assert!(
                wrong_fail * 200 <= n,
                "{name}: z-fail wrong on {wrong_fail}"
            );
            assert!(
                wrong_pass * 200 <= n,
                "{name}: z-pass wrong on {wrong_pass}"
            );
            assert!(zfail.caps > 0 && zpass.caps == 0);
            assert_eq!(zfail.eye_count, 0);
            if eye_in_shadow {
                assert!(wrong_pass_0 * 10 > n, "{name}: z-pass from 0 should fail");
            } else {
                assert_eq!(zpass_0.count, zpass.count);
            }
        }
    }
}
