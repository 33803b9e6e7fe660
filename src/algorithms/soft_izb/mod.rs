//! Soft irregular shadow mapping (paper 004, Johnson et al. 2009), its math in one place.
//!
//! Eye-view receiver points are stored in a light-space perspective grid (§2, Figure 3). Umbrae
//! come from hard irregular shadow mapping from the light centre, counting the depth complexity
//! between each receiver point and the light (§2.4). Penumbrae come from one light-view
//! "penumbra quad" per silhouette edge (§2.2), tested coarsely against the stored points, then
//! exactly by the area of the light footprint clipped by the edge (§2.3, eq. 3). Eq. 4 combines
//! the two. Both overdraw optimisations of §2.5 are here: per-bin quad width and the
//! wedge/grid-column intersection.
//!
//! Light-view quantities live in the uv plane of [`LightView`] and in inverse linear depth
//! `1/z`, which interpolates linearly in the image plane: depth along an edge, across a triangle
//! and the perspective grid's slices are all linear in `1/z`.

pub mod cpu;
pub mod wgpu;

use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};
use serde::{Deserialize, Serialize};

use super::shadow_map::LightView;
use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, MethodLimit, WgpuEntry, WgpuParity,
    WorkEstimate,
};
use crate::algorithms::work;
use crate::error::InputError;
use crate::frame::Frame;
use crate::frame::RunParams;
use crate::record::phases;
use crate::scene::adjacency::{EdgeAdjacency, EdgeKind};
use crate::scene::coverage;
use crate::scene::LightKind;

phases! {
    /// The phases of a `soft_izb` run (004 §2): the light-space geometry (host), the irregular
    /// grid built of the eye samples, the hard (umbra) pass over it, and the soft pass of the
    /// penumbra quads with the resolve.
    pub enum Phase {
        Geometry => "geometry",
        Construct => "construct",
        Hard => "hard",
        Soft => "soft",
    }
}

pub const ID: &str = "soft_izb";

/// Options of `soft_izb` (scenario `options.soft_izb`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SoftIzbOptions {
    /// §2.5, first optimisation: recompute each penumbra quad's width per bin from that bin's
    /// maximum receiver depth, dropping the quad from bins it no longer overlaps.
    pub per_bin_width: bool,
    /// §2.5, second optimisation: per quad fragment, evaluate eq. 3 only for samples at and
    /// behind the depth where the edge's wedge enters the grid column.
    pub wedge_column_cull: bool,
    /// Depth slices of the perspective grid (Figure 3), uniform in `1/z`.
    pub depth_slices: u32,
    /// Where penumbra edges come from (§2.1).
    pub silhouettes: SilhouetteSource,
}

/// §2.1: silhouettes from adjacency, or every edge of every occluding triangle when adjacency
/// is not used (interior edges then cancel pairwise in eq. 4, at the cost of more quads).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SilhouetteSource {
    #[default]
    Adjacency,
    AllEdges,
}

impl Default for SoftIzbOptions {
    fn default() -> Self {
        SoftIzbOptions {
            per_bin_width: true,
            wedge_column_cull: true,
            depth_slices: 8,
            silhouettes: SilhouetteSource::default(),
        }
    }
}

impl AlgorithmOptions for SoftIzbOptions {
    fn validate(&self) -> Result<(), InputError> {
        let field = format!("$.options.{ID}.depth_slices");
        InputError::check_range(field, self.depth_slices, 1..=64)
    }
}

/// Smallest light-view depth, as a fraction of the far plane, that geometry is clipped to:
/// points at or behind the light's view plane have no image-plane position.
const NEAR_CLIP: f32 = 1e-4;

/// Fixed-point scale of the penumbral occlusion the wgpu execution accumulates per sample with
/// integer atomics (2^20). Each eq. 3 term (|Ṽ''| ≤ 1/2) is rounded to the nearest multiple of
/// 2^-20, so a sample's sum is off by at most 2^-21 per contributing edge: ~8000 edges before
/// the error reaches one step of an 8-bit image (2^-8). The integer sum is exact and
/// independent of the order the atomics are served in; i32 addition wraps, so partial sums
/// beyond ±2048 still give the right total as long as the total lies within that range.
pub const OCCLUSION_SCALE: f32 = 1_048_576.0;

/// Most grid cells one run may allocate (4 bytes each).
pub const MAX_CELLS: u64 = 1 << 28;

/// Refuses a grid of `res²` columns × `slices` over [`MAX_CELLS`] before anything is allocated.
pub fn check_grid_size(res: u32, slices: u32) -> crate::error::Result<()> {
    let res = u64::from(res);
    if res * res * u64::from(slices) > MAX_CELLS {
        return Err(crate::error::Error::Resource(format!(
            "soft_izb grid of {res}² columns × {slices} depth slices exceeds {MAX_CELLS} cells; \
             lower map_resolution or options.soft_izb.depth_slices"
        )));
    }
    Ok(())
}

/// A point in the light-view image plane with its inverse linear depth.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LightPoint {
    pub uv: Vec2,
    pub inv_z: f32,
}

/// Light-space clip coordinates of a world point (linear in world space, so clipping against
/// the near plane can interpolate them).
pub fn clip_coords(view: &LightView, p: Vec3) -> Vec4 {
    view.view_proj * p.extend(1.0)
}

/// Perspective division of clip coordinates (w is the linear depth).
pub fn light_point(c: Vec4) -> LightPoint {
    let ndc = c.xy() / c.w;
    LightPoint {
        uv: Vec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5),
        inv_z: 1.0 / c.w,
    }
}

/// Whether a clip-space point is far enough in front of the light to be projected.
pub fn in_front(view: &LightView, c: Vec4) -> bool {
    c.w > NEAR_CLIP * view.far
}

/// Where the clip-space segment `a b` (one end in front of `w_min`, one not) crosses
/// `w = w_min`, interpolated from the end in front whichever way the segment runs, so that the
/// triangles and edges sharing a clipped edge get the same point (and stay watertight).
fn near_crossing(w_min: f32, a: Vec4, b: Vec4) -> Vec4 {
    let (inside, outside) = if a.w > w_min { (a, b) } else { (b, a) };
    inside + (outside - inside) * ((w_min - inside.w) / (outside.w - inside.w))
}

/// Clips a polygon in clip space to the part in front of the light (Sutherland–Hodgman against
/// one plane) and projects it.
pub fn clip_and_project(view: &LightView, poly: &[Vec4]) -> Vec<LightPoint> {
    let w_min = NEAR_CLIP * view.far;
    let mut out = Vec::with_capacity(poly.len() + 1);
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        if a.w > w_min {
            out.push(light_point(a));
        }
        if (a.w > w_min) != (b.w > w_min) {
            out.push(light_point(near_crossing(w_min, a, b)));
        }
    }
    out
}

/// Clips a segment in clip space to the part in front of the light and projects it; `None`
/// when it lies wholly behind.
pub fn clip_segment(view: &LightView, a: Vec4, b: Vec4) -> Option<(LightPoint, LightPoint)> {
    let w_min = NEAR_CLIP * view.far;
    let cut = |p: Vec4, q: Vec4| near_crossing(w_min, p, q);
    match (a.w > w_min, b.w > w_min) {
        (true, true) => Some((light_point(a), light_point(b))),
        (true, false) => Some((light_point(a), light_point(cut(a, b)))),
        (false, true) => Some((light_point(cut(a, b)), light_point(b))),
        (false, false) => None,
    }
}

/// Radius in uv of the light at unit depth: image-plane lengths scale as `light radius / z`.
pub fn light_radius_uv(view: &LightView, light_radius: f32) -> f32 {
    light_radius / (2.0 * view.tan_half_fov)
}

/// §2.3, Figure 4: radius R of the light's footprint, seen from the receiver point `p` through
/// the occluder depth of `q` and projected into the image plane. By similar triangles the light
/// disc (radius `r`) seen from depth `z_p` and cut at depth `z_q` has radius
/// `r·(z_p − z_q)/z_p`; projected from the light centre that is `r·(1/z_q − 1/z_p)`. Negative
/// when the silhouette lies behind the receiver: no occlusion is possible.
pub fn footprint_radius(r_uv: f32, inv_z_q: f32, inv_z_p: f32) -> f32 {
    r_uv * (inv_z_q - inv_z_p)
}

/// §2.2: half-width of a penumbra quad: the largest footprint radius any receiver up to depth
/// `1/inv_z_receiver` can have, with the edge at its minimum depth `1/inv_z_edge_near`
/// [Parker et al. 1998].
pub fn quad_half_width(r_uv: f32, inv_z_edge_near: f32, inv_z_receiver_max_depth: f32) -> f32 {
    footprint_radius(r_uv, inv_z_edge_near, inv_z_receiver_max_depth)
}

/// §2.3, eq. 3: normalised area of the minor circular segment of the unit disc cut off by a
/// chord piece at distance `d` (0 ≤ d ≤ 1) from the centre, running along the chord from `s0`
/// to `s1` (signed, measured from the foot of the perpendicular, already clipped to the disc).
/// With `w0 = −s0` and `w1 = s1` this is the paper's
/// `θ = acos((d² − w0·w1)/√((d² + w0²)(d² + w1²)))`, `Ṽ'' = (θ − d(w0 + w1))/2π`.
pub fn circular_segment_area(d: f32, s0: f32, s1: f32) -> f32 {
    let (w0, w1) = (-s0, s1);
    let denom = ((d * d + w0 * w0) * (d * d + w1 * w1)).sqrt();
    if denom <= 0.0 || s1 <= s0 {
        return 0.0;
    }
    let theta = ((d * d - w0 * w1) / denom).clamp(-1.0, 1.0).acos();
    ((theta - d * (w0 + w1)) / (2.0 * std::f32::consts::PI)).max(0.0)
}

/// A silhouette edge projected into the light-view image plane, oriented so that the occluding
/// surface adjacent to it lies on its inside (see [`ProjectedEdge::outside`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectedEdge {
    pub a: LightPoint,
    pub b: LightPoint,
}

impl ProjectedEdge {
    /// Inverse depth of the edge's nearest point to the light.
    pub fn inv_z_near(&self) -> f32 {
        self.a.inv_z.max(self.b.inv_z)
    }

    /// The edge equation at `p`: positive on the side away from the occluding surface. An edge
    /// of a face that faces the light runs in the face's counter-clockwise winding; the
    /// right-handed light view keeps that counter-clockwise in NDC and the uv flip of v turns it
    /// clockwise, so the surface lies where the 2D cross product is negative.
    pub fn outside(&self, p: Vec2) -> f32 {
        (self.b.uv - self.a.uv).perp_dot(p - self.a.uv)
    }

    /// Distance in uv from `p` to the edge segment.
    pub fn distance(&self, p: Vec2) -> f32 {
        let e = self.b.uv - self.a.uv;
        let t = (e.dot(p - self.a.uv) / e.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
        (self.a.uv + e * t - p).length()
    }

    /// §2.3, Figure 4 and eq. 3 with the sign rule: the signed occlusion of the light footprint
    /// around receiver point `p` by this edge. Positive (added) when `p` is outside the edge,
    /// negative (subtracted) when inside; zero when the edge is behind `p` or farther than R.
    pub fn penumbral_occlusion(&self, r_uv: f32, p: LightPoint) -> f32 {
        let e = self.b.uv - self.a.uv;
        let len = e.length();
        if len <= 0.0 {
            return 0.0;
        }
        let dir = e / len;
        // q: the point of the edge nearest p, with its depth (1/z is linear along the edge).
        let t = dir.dot(p.uv - self.a.uv).clamp(0.0, len);
        let inv_z_q = self.a.inv_z + (self.b.inv_z - self.a.inv_z) * (t / len);
        let r = footprint_radius(r_uv, inv_z_q, p.inv_z);
        if r <= 0.0 {
            return 0.0;
        }
        let side = self.outside(p.uv) / len;
        let d = side.abs() / r;
        if d >= 1.0 {
            return 0.0;
        }
        // Chord coordinates of the endpoints from the foot of the perpendicular, in units of R,
        // clipped to the footprint.
        let foot = dir.dot(p.uv - self.a.uv);
        let half_chord = (1.0 - d * d).sqrt();
        let s0 = (-foot / r).clamp(-half_chord, half_chord);
        let s1 = ((len - foot) / r).clamp(-half_chord, half_chord);
        let area = circular_segment_area(d, s0, s1);
        // The sign rule decides "inside" as the umbra test does (the surface lies on the side
        // of b → a that a positive face covers), ties included, so that a sample on an interior
        // edge gets opposite signs from its two faces.
        if coverage::edge_covers_2d(p.uv, self.b.uv, self.a.uv) {
            -area
        } else {
            area
        }
    }
}

/// §2.4, eq. 4: visibility from the umbral depth complexity and the summed signed penumbral
/// occlusion, assuming occluders do not overlap (§5.2, C = 0), clamped to [0, 1].
pub fn combined_visibility(depth_complexity: u32, penumbral: f32) -> f32 {
    let occlusion = depth_complexity as f32 + penumbral;
    if occlusion.is_finite() {
        1.0 - occlusion.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// §2.2: a penumbra quad: the rectangle coplanar with the image plane around the projected edge,
/// extended by `half_width` on every side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PenumbraQuad {
    pub edge: ProjectedEdge,
    pub half_width: f32,
}

impl PenumbraQuad {
    /// Centre, unit axis along the edge, and half extents (along, across).
    fn frame(&self) -> (Vec2, Vec2, Vec2) {
        let (a, b) = (self.edge.a.uv, self.edge.b.uv);
        let e = b - a;
        let len = e.length();
        let dir = if len > 0.0 { e / len } else { Vec2::X };
        (
            (a + b) * 0.5,
            dir,
            Vec2::new(len * 0.5 + self.half_width, self.half_width),
        )
    }

    /// Axis-aligned bounds in uv.
    pub fn bounds(&self) -> (Vec2, Vec2) {
        let (c, dir, h) = self.frame();
        let ext = Vec2::new(
            dir.x.abs() * h.x + dir.y.abs() * h.y,
            dir.y.abs() * h.x + dir.x.abs() * h.y,
        );
        (c - ext, c + ext)
    }

    /// Whether the quad overlaps the axis-aligned rectangle `[lo, hi]` (separating axes).
    pub fn overlaps(&self, lo: Vec2, hi: Vec2) -> bool {
        let (qlo, qhi) = self.bounds();
        if qlo.x > hi.x || qlo.y > hi.y || qhi.x < lo.x || qhi.y < lo.y {
            return false;
        }
        let (c, dir, h) = self.frame();
        let rc = (lo + hi) * 0.5 - c;
        let rh = (hi - lo) * 0.5;
        for (axis, extent) in [(dir, h.x), (dir.perp(), h.y)] {
            let r = rh.x * axis.x.abs() + rh.y * axis.y.abs();
            if rc.dot(axis).abs() > extent + r {
                return false;
            }
        }
        true
    }
}

/// §2.5, second optimisation: the nearest depth (as `1/z`, the largest) at which the wedge of
/// an edge reaches a grid column whose cells are at least `distance` (uv) from the edge. A
/// receiver at `1/z_p` can only be reached when `r·(1/z_q − 1/z_p) ≥ distance`, and `1/z_q` is
/// at most the edge's `1/z` nearest the light. `None` when no depth is deep enough.
pub fn wedge_entry_inv_z(r_uv: f32, inv_z_edge_near: f32, distance: f32) -> Option<f32> {
    let inv_z = inv_z_edge_near - distance / r_uv;
    (inv_z > 0.0).then_some(inv_z)
}

/// The occluding geometry seen from the light centre (the geometry stage of §2.1, shared by
/// every execution): triangles for the umbra (with their flat
/// index, to skip a receiver's own triangle) and penumbra edges.
#[derive(Default)]
pub struct Occluders {
    pub triangles: Vec<(u32, LightTriangle)>,
    pub edges: Vec<ProjectedEdge>,
}

/// The occluders of object `o`: its triangles facing the light centre (all of them in an open
/// mesh) and its penumbra edges.
pub fn object_occluders(
    frame: &Frame,
    view: &LightView,
    opts: &SoftIzbOptions,
    o: usize,
) -> Occluders {
    match object_adjacency(frame, o) {
        Some(adj) => occluders_of(frame, view, opts, o, &adj),
        None => Occluders::default(),
    }
}

/// The edge adjacency of object `o`'s mesh ([`EdgeAdjacency::build`]), `None` for an object
/// that does not occlude: a property of the mesh, built once before the frame's phases.
pub fn object_adjacency(frame: &Frame, o: usize) -> Option<EdgeAdjacency> {
    let object = &frame.scene.objects[o];
    object
        .role
        .occluder
        .then(|| EdgeAdjacency::build(&object.mesh))
}

/// [`object_occluders`] of occluding object `o` from its adjacency `adj`
/// ([`object_adjacency`]).
pub fn occluders_of(
    frame: &Frame,
    view: &LightView,
    opts: &SoftIzbOptions,
    o: usize,
    adj: &EdgeAdjacency,
) -> Occluders {
    let centre = frame.scene.light.center();
    let base = frame
        .flat
        .object_of_triangle
        .partition_point(|&x| (x as usize) < o) as u32;
    let closed = adj.count(EdgeKind::Boundary) == 0 && adj.count(EdgeKind::NonManifold) == 0;
    let mut tris = Vec::new();
    let mut edges = Vec::new();
    let clip = |i: u32| clip_coords(view, adj.vertices[i as usize]);
    for (f, tri) in adj.triangles.iter().enumerate() {
        let Some(front) = adj.faces_point(f as u32, centre) else {
            continue;
        };
        if !front && closed {
            continue;
        }
        let poly: Vec<Vec4> = tri.iter().map(|&i| clip(i)).collect();
        let pts = clip_and_project(view, &poly);
        for k in 1..pts.len().saturating_sub(1) {
            if let Some(lt) = LightTriangle::new([pts[0], pts[k], pts[k + 1]]) {
                tris.push((base + f as u32, lt));
            }
        }
        if opts.silhouettes == SilhouetteSource::AllEdges {
            let v = if front {
                *tri
            } else {
                [tri[0], tri[2], tri[1]]
            };
            for k in 0..3 {
                edges.push((v[k], v[(k + 1) % 3]));
            }
        }
    }
    if opts.silhouettes == SilhouetteSource::Adjacency {
        edges = adj
            .silhouette_from(centre)
            .edges
            .iter()
            .map(|e| (e.v[0], e.v[1]))
            .collect();
    }
    let projected = edges
        .into_iter()
        .filter_map(|(a, b)| clip_segment(view, clip(a), clip(b)))
        .map(|(a, b)| ProjectedEdge { a, b })
        .collect();
    Occluders {
        triangles: tris,
        edges: projected,
    }
}

/// A scene triangle projected into the light-view image plane for the umbra pass (§2.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightTriangle {
    pub v: [LightPoint; 3],
    /// Twice the signed uv area.
    area2: f32,
}

impl LightTriangle {
    /// `None` for a triangle with no area in the image plane (seen edge-on).
    pub fn new(v: [LightPoint; 3]) -> Option<LightTriangle> {
        let area2 = (v[1].uv - v[0].uv).perp_dot(v[2].uv - v[0].uv);
        (area2.abs() > 1e-14).then_some(LightTriangle { v, area2 })
    }

    pub fn bounds(&self) -> (Vec2, Vec2) {
        let lo = self.v[0].uv.min(self.v[1].uv).min(self.v[2].uv);
        let hi = self.v[0].uv.max(self.v[1].uv).max(self.v[2].uv);
        (lo, hi)
    }

    pub fn inv_z_near(&self) -> f32 {
        self.v[0].inv_z.max(self.v[1].inv_z).max(self.v[2].inv_z)
    }

    /// Irregular rasterization: whether the triangle covers the sample position `p` exactly,
    /// and its `1/z` there. Samples on an edge or a vertex shared with other occluding triangles
    /// are covered by exactly one of them (the one tie rule, [`coverage::triangle_covers_2d`]).
    pub fn covers(&self, p: Vec2) -> Option<f32> {
        let [a, b, c] = self.v;
        let e = coverage::triangle_covers_2d(p, [a.uv, b.uv, c.uv])?;
        let w = e.map(|e| e / self.area2);
        Some(w[0] * a.inv_z + w[1] * b.inv_z + w[2] * c.inv_z)
    }
}

/// The light-view perspective grid of Figure 3: `res × res` columns over the uv square, each
/// split into `slices` cells uniform in `1/z` between the nearest and farthest receiver. Columns
/// are grouped into `bin × bin` bins of the sort-middle rasterizer; cells are stored bin by
/// bin, column by column, front to back, so that a bin's samples, a column's samples and the
/// samples behind a given depth are each one contiguous range of the sample array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub res: u32,
    pub slices: u32,
    pub bin: u32,
    /// `1/z` of the nearest and of the farthest receiver.
    pub inv_z_front: f32,
    pub inv_z_back: f32,
}

impl Grid {
    pub fn bins_x(&self) -> u32 {
        self.res.div_ceil(self.bin)
    }

    pub fn bins(&self) -> usize {
        (self.bins_x() * self.bins_x()) as usize
    }

    pub fn cells_per_bin(&self) -> usize {
        (self.bin * self.bin * self.slices) as usize
    }

    pub fn cells(&self) -> usize {
        self.bins() * self.cells_per_bin()
    }

    /// The column holding uv `p`; points outside the uv square go to the border columns
    /// (range queries clamp their bounds the same way, so they stay conservative).
    pub fn column(&self, p: Vec2) -> (u32, u32) {
        let f = |x: f32| ((x * self.res as f32).floor().max(0.0) as u32).min(self.res - 1);
        (f(p.x), f(p.y))
    }

    /// Inclusive column range covered by uv bounds.
    pub fn column_range(&self, lo: Vec2, hi: Vec2) -> ((u32, u32), (u32, u32)) {
        (self.column(lo), self.column(hi))
    }

    /// uv rectangle of column (x, y); border columns extend to infinity.
    pub fn column_rect(&self, x: u32, y: u32) -> (Vec2, Vec2) {
        let s = 1.0 / self.res as f32;
        let edge = |i: u32| {
            let lo = if i == 0 {
                f32::NEG_INFINITY
            } else {
                i as f32 * s
            };
            let hi = if i + 1 == self.res {
                f32::INFINITY
            } else {
                (i + 1) as f32 * s
            };
            (lo, hi)
        };
        let ((x0, x1), (y0, y1)) = (edge(x), edge(y));
        (Vec2::new(x0, y0), Vec2::new(x1, y1))
    }

    /// The slice holding inverse depth `inv_z` (0 = front).
    pub fn slice(&self, inv_z: f32) -> u32 {
        let span = self.inv_z_front - self.inv_z_back;
        if span <= 0.0 {
            return 0;
        }
        let f = (self.inv_z_front - inv_z) / span * self.slices as f32;
        (f.floor().max(0.0) as u32).min(self.slices - 1)
    }

    pub fn bin_of_column(&self, x: u32, y: u32) -> usize {
        ((y / self.bin) * self.bins_x() + x / self.bin) as usize
    }

    /// Index of cell (column x, y; slice k) in storage order.
    pub fn cell(&self, x: u32, y: u32, k: u32) -> usize {
        let local = ((y % self.bin) * self.bin + x % self.bin) * self.slices + k;
        self.bin_of_column(x, y) * self.cells_per_bin() + local as usize
    }

    /// Inclusive column range of bin `b`, clipped to the grid.
    pub fn bin_columns(&self, b: usize) -> ((u32, u32), (u32, u32)) {
        let (bx, by) = (b as u32 % self.bins_x(), b as u32 / self.bins_x());
        let lo = (bx * self.bin, by * self.bin);
        let hi = (
            ((bx + 1) * self.bin).min(self.res) - 1,
            ((by + 1) * self.bin).min(self.res) - 1,
        );
        (lo, hi)
    }

    /// uv rectangle of bin `b` (border bins extend to infinity).
    pub fn bin_rect(&self, b: usize) -> (Vec2, Vec2) {
        let ((x0, y0), (x1, y1)) = self.bin_columns(b);
        (self.column_rect(x0, y0).0, self.column_rect(x1, y1).1)
    }
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct SoftIzb;

/// Soft irregular shadow mapping: the eye samples into the light-space grid, the umbra by
/// irregular rasterization, and the penumbra quads along the silhouette in the grid.
pub fn work_estimate(
    scene: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    _: &SoftIzbOptions,
) -> f64 {
    3.0 * work::pixels(p) + work::outline(scene, p.map_resolution)
}

impl Algorithm for SoftIzb {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "paper 004 (soft irregular shadow mapping), §2";
    const SUMMARY: &'static str =
        "eye samples in a light-space grid; umbra by irregular rasterization (depth \
              complexity), penumbra quads per silhouette edge with analytic circular-segment \
              occlusion (eq. 3), per-bin width and wedge/column culling (§2.5)";
    // §2.3 sizes the light's footprint in the light's image plane: the light it computes is
    // the disc there (normal along its view axis), so a sphere is converted to that disc and
    // the reference is computed for it.
    const LIGHTS: &'static [LightKind] = &[LightKind::Disc];
    const LIMITS: &'static [MethodLimit] =
        &[MethodLimit::OneMap, MethodLimit::AvertedNonOccludersLit];
    type Options = SoftIzbOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = cpu::memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] = &[
        r#"{"per_bin_width": false, "wedge_column_cull": false}"#,
        r#"{"silhouettes": "all_edges", "depth_slices": 2}"#,
    ];
    /// GPU atomics count the grid's insertion retries, the model one per insertion; overdraw
    /// (fill whose eq. 3 gave exactly 0) differs where a sample's footprint just touches an
    /// edge and one execution returns a tiny value, the other 0 (measured: 2 of 63,000).
    const WGPU_PARITY: WgpuParity = WgpuParity {
        differ: &[("atomics", None), ("overdraw", Some(0.005))],
        ..WgpuParity::SAME_FORMULAS
    };
    const CPU: CpuEntry<SoftIzbOptions> = cpu::render;
    const WGPU: Option<WgpuEntry<SoftIzbOptions>> = Some(wgpu::render);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Light;
    use std::f32::consts::PI;

    /// Fraction of the unit disc beyond a chord at distance d, from the textbook formula.
    fn segment_fraction(d: f32) -> f32 {
        (d.acos() - d * (1.0 - d * d).sqrt()) / PI
    }

    #[test]
    fn eq3_matches_the_circular_segment_for_a_full_chord() {
        for i in 0..10 {
            let d = i as f32 / 10.0;
            let h = (1.0 - d * d).sqrt();
            let got = circular_segment_area(d, -h, h);
            assert!((got - segment_fraction(d)).abs() < 1e-5, "d={d}: {got}");
        }
    }

    #[test]
    fn eq3_with_the_sign_rule_sums_a_square_inside_the_footprint_to_its_area() {
        // A small square occluder inside the footprint, centre outside it: the signed
        // contributions of its four edges must add up to its area over the disc's.
        let p = LightPoint {
            uv: Vec2::ZERO,
            inv_z: 0.5,
        };
        let inv_z_edge = 1.0;
        let r_uv = 2.0; // R = 2·(1 − 0.5) = 1
        let (x0, x1, y0, y1) = (0.2f32, 0.6f32, -0.1f32, 0.3f32);
        let pt = |x: f32, y: f32| LightPoint {
            uv: Vec2::new(x, y),
            inv_z: inv_z_edge,
        };
        // Clockwise in uv: the surface inside (negative cross product), as for a front face.
        let corners = [pt(x0, y0), pt(x0, y1), pt(x1, y1), pt(x1, y0)];
        // Eq. 3 summed over the square's edges for the point `q`.
        let square = |q: LightPoint| -> f32 {
            (0..4)
                .map(|i| {
                    let (a, b) = (corners[i], corners[(i + 1) % 4]);
                    ProjectedEdge { a, b }.penumbral_occlusion(r_uv, q)
                })
                .sum()
        };
        let sum = square(p);
        let expected = (x1 - x0) * (y1 - y0) / PI;
        assert!((sum - expected).abs() < 1e-4, "{sum} vs {expected}");
        // Centre inside the square: one unit of umbra minus the unoccluded rest.
        let inside = LightPoint {
            uv: Vec2::new(0.4, 0.1),
            inv_z: 0.5,
        };
        let v = combined_visibility(1, square(inside));
        assert!((v - (1.0 - expected)).abs() < 1e-4, "{v}");
    }

    #[test]
    fn footprint_vanishes_for_edges_behind_the_receiver() {
        let e = ProjectedEdge {
            a: LightPoint {
                uv: Vec2::new(-1.0, 0.0),
                inv_z: 0.2,
            },
            b: LightPoint {
                uv: Vec2::new(1.0, 0.0),
                inv_z: 0.2,
            },
        };
        let p = LightPoint {
            uv: Vec2::new(0.0, 0.01),
            inv_z: 0.5,
        };
        assert_eq!(e.penumbral_occlusion(1.0, p), 0.0);
        assert!(quad_half_width(1.0, 0.2, 0.5) < 0.0);
    }

    #[test]
    fn front_faces_lie_inside_their_projected_edges() {
        let light = Light::Sphere {
            center: Vec3::new(0.5, 10.0, -0.3),
            radius: 1.0,
        };
        let view = LightView::looking(light.center(), -light.center(), 0.5, 1.0, 20.0, 256);
        // Counter-clockwise seen from above (normal +y): faces the light.
        let tri = [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 1.0),
            Vec3::new(1.0, 1.0, 0.0),
        ];
        assert!((tri[1] - tri[0]).cross(tri[2] - tri[0]).y > 0.0);
        let pts = tri.map(|p| light_point(clip_coords(&view, p)));
        let centroid = (pts[0].uv + pts[1].uv + pts[2].uv) / 3.0;
        for i in 0..3 {
            let e = ProjectedEdge {
                a: pts[i],
                b: pts[(i + 1) % 3],
            };
            assert!(e.outside(centroid) < 0.0);
        }
    }

    #[test]
    fn wedge_entry_is_where_the_footprint_reaches_the_column() {
        let (r_uv, inv_z_edge, dist) = (0.5, 0.25, 0.05);
        let inv_z = wedge_entry_inv_z(r_uv, inv_z_edge, dist).unwrap();
        assert!((footprint_radius(r_uv, inv_z_edge, inv_z) - dist).abs() < 1e-6);
        assert!(wedge_entry_inv_z(r_uv, inv_z_edge, 1.0).is_none());
    }

    #[test]
    fn quads_overlap_only_rectangles_they_touch() {
        let q = PenumbraQuad {
            edge: ProjectedEdge {
                a: LightPoint {
                    uv: Vec2::new(0.0, 0.0),
                    inv_z: 1.0,
                },
                b: LightPoint {
                    uv: Vec2::new(1.0, 1.0),
                    inv_z: 1.0,
                },
            },
            half_width: 0.05,
        };
        assert!(q.overlaps(Vec2::new(0.45, 0.45), Vec2::new(0.55, 0.55)));
        // Inside the axis-aligned bounds but off the diagonal band.
        assert!(!q.overlaps(Vec2::new(0.8, 0.0), Vec2::new(0.9, 0.1)));
    }

    #[test]
    fn grid_cells_are_unique_and_columns_contiguous() {
        let g = Grid {
            res: 10,
            slices: 3,
            bin: 4,
            inv_z_front: 1.0,
            inv_z_back: 0.5,
        };
        let mut seen = vec![false; g.cells()];
        for y in 0..10 {
            for x in 0..10 {
                let c0 = g.cell(x, y, 0);
                for k in 0..3 {
                    assert_eq!(g.cell(x, y, k), c0 + k as usize);
                    assert!(!std::mem::replace(&mut seen[c0 + k as usize], true));
                }
            }
        }
        assert_eq!(g.slice(1.0), 0);
        assert_eq!(g.slice(0.5), 2);
        assert_eq!(g.column(Vec2::new(-3.0, 7.0)), (0, 9));
    }

    #[test]
    fn options_are_checked_with_their_path() {
        let mut o = std::collections::BTreeMap::new();
        o.insert(ID.to_string(), serde_json::json!({"depth_slices": 0}));
        let e = SoftIzb::options(&o).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("$.options.soft_izb.depth_slices"));
        o.insert(ID.to_string(), serde_json::json!({"per_bin_width": "no"}));
        let e = SoftIzb::options(&o).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("$.options.soft_izb.per_bin_width"));
    }
}
