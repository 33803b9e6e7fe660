//! Hard shadow volumes (Crow 1977, as used by paper 001 pass 1 and by its "1024-sample"
//! reference): one semi-infinite quad per silhouette edge, extruded away from a point on the
//! light, counted per pixel in a stencil or V-buffer.
//!
//! Counting is z-pass: a quad fragment in front of the visible surface adds +1 when the quad
//! faces the eye (the eye is on its outer side) and −1 otherwise, so a pixel's count is the
//! number of shadow volumes its point lies in. A camera inside a shadow volume makes z-pass miss
//! the volumes around the eye; the count is therefore started at the eye's own count (the
//! light-facing occluder triangles the segment light→eye crosses, i.e. the front caps), which
//! gives every pixel the same count depth-fail (z-fail) counting would give.

use glam::Vec3;

use super::eye_raster::{raster_pass, Block, EyeBuffer, EyeRays, ScreenRect, TilePass};
use crate::model::{Machine, Mask, Probe, LANES};
use crate::scene::adjacency::SilhouetteEdge;
use crate::scene::Mesh;

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

    /// Distance along `o + t·d` to the quad, if the ray meets it.
    pub fn ray_hit(&self, o: Vec3, d: Vec3) -> Option<f32> {
        let n = self.normal;
        let nd = n.dot(d);
        if nd.abs() < 1e-12 * n.length() {
            return None;
        }
        let t = n.dot(self.light - o) / nd;
        let y = o + d * t;
        let l = self.light;
        let inside = (self.a - l).cross(y - l).dot(n) >= 0.0
            && (y - l).cross(self.b - l).dot(n) >= 0.0
            && (self.b - self.a).cross(y - self.a).dot(n) <= 0.0;
        (t > 0.0 && inside).then_some(t)
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
    /// Quad fragments rasterized (within the scene bounds).
    pub fill: u64,
    /// Fragments that passed the depth test and changed the count.
    pub passed: u64,
    /// The eye's own count, the value the buffer is cleared to.
    pub eye_count: i32,
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

/// Möller–Trumbore for the segment `o + t·d`, `t ∈ (0, 1)`.
fn segment_hits_triangle(o: Vec3, d: Vec3, a: Vec3, b: Vec3, c: Vec3) -> bool {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return false;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    let t = e2.dot(q) * inv;
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t < 1.0
}

/// Vector instructions per block of a shadow quad: the ray–plane intersection (two 3-term dots,
/// a divide, a multiply-add per coordinate), the three edge tests (a cross product and a dot
/// each, with a compare), and the scene-bounds slab test (per axis a reciprocal, two
/// multiply-adds, a min, a max; then the interval compares).
pub const QUAD_HIT_OPS: u32 = 2 * 5 + 1 + 3 + 3 * (9 + 5 + 1) + 3 * 5 + 4;
/// The depth test: compare with the visible surface's depth, mask and.
pub const DEPTH_TEST_OPS: u32 = 2;
/// The count update: select the quad's ±1, add.
pub const COUNT_OPS: u32 = 2;

/// Where a hard shadow-volume pass counts: the count buffer (a V-buffer or a stencil) and the
/// eye depth it tests against, and whether it clears the count buffer first (counted as writes).
pub struct CountTarget {
    pub depth: EyeBuffer,
    pub count: EyeBuffer,
    pub clear: bool,
}

struct QuadPass<'a> {
    rays: &'a EyeRays,
    quads: &'a [ShadowQuad],
    eye_sides: Vec<i32>,
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
        p.vector(QUAD_HIT_OPS, b.mask);
        let mut hit = [f32::INFINITY; LANES];
        // Lanes outside the mask may lie past the image edge: never index with them.
        let fill = Mask::from_fn(|l| {
            if !b.mask.get(l) {
                return false;
            }
            let i = b.pixel[l] as usize;
            let (t0, t1) = rays.bounds_interval(i);
            match self.quads[k].ray_hit(rays.eye, rays.dir[i]) {
                Some(t) if t >= t0 && t <= t1 => {
                    hit[l] = t;
                    true
                }
                _ => false,
            }
        });
        if !fill.any() {
            return;
        }
        self.target.depth.read(p, b, fill);
        p.vector(DEPTH_TEST_OPS, fill);
        let passed = Mask::from_fn(|l| fill.get(l) && hit[l] < rays.depth[b.pixel[l] as usize]);
        s.fill += u64::from(fill.count());
        s.passed += u64::from(passed.count());
        if !passed.any() {
            return;
        }
        self.target.count.read(p, b, passed);
        p.vector(COUNT_OPS, passed);
        let w = s.rect.x1 - s.rect.x0;
        for l in passed.lanes() {
            let (x, y) = (b.pixel[l] % rays.width, b.pixel[l] / rays.width);
            s.count[((y - s.rect.y0) * w + x - s.rect.x0) as usize] += self.eye_sides[k];
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

/// Renders `quads` z-pass into a count buffer cleared to `eye_count` (tiles of `tile` pixels), as
/// step `step` of the machine's current phase.
pub fn render_quads(
    m: &mut Machine,
    step: &str,
    rays: &EyeRays,
    quads: &[ShadowQuad],
    eye_count: i32,
    tile: u32,
    target: &CountTarget,
) -> HardPass {
    let footprints = quad_footprints(rays, quads);
    let pass = QuadPass {
        rays,
        quads,
        eye_sides: quads.iter().map(|q| q.side(rays.eye) as i32).collect(),
        eye_count,
        target,
    };
    let tiles = raster_pass(m, step, rays, &footprints, tile, &pass);
    let mut out = HardPass {
        count: vec![eye_count; rays.len()],
        eye_count,
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
        m.count(&format!("mem.{buffer}.read_bytes"), bytes as f64);
        m.count("mem_read_bytes", bytes as f64);
    }
}

/// Counts `bytes` written to named buffer `buffer` (`mem.<buffer>.write_bytes` and the total) on
/// `cpu-native`, as [`mem_read`].
pub fn mem_write(m: &mut Machine, buffer: &str, bytes: u64) {
    if !m.is_model() {
        m.count(&format!("mem.{buffer}.write_bytes"), bytes as f64);
        m.count("mem_write_bytes", bytes as f64);
    }
}
