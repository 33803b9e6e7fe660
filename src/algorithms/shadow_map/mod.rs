//! The light-view projection and the filtering math shared by the shadow-map family
//! (`hard_shadow_map`, `pcss`, and the penumbra map's first pass). One place for each formula;
//! the cpu and wgpu executions both call (or mirror in WGSL) exactly these.
//!
//! Maps hold NDC depth in [0, 1] from a perspective projection at the light centre, which is
//! what a GPU depth buffer holds and what a rasterizer interpolates linearly in screen space;
//! [`LightView::linear_depth`] turns it back into distance along the view axis for the PCSS math.
//!
//! The family's passes: [`cpu`] (the light raster on the modelled rasterizer and the eye pass
//! generic over a [`cpu::Lookup`]) and [`wgpu`] (the same two passes on the GPU, each algorithm
//! appending its `visibility_at` in WGSL).

pub mod cpu;
pub mod wgpu;

use glam::{Mat4, Vec2, Vec3, Vec4Swizzles};

use crate::counters::names;
use crate::model::{lane_groups, BufferId, Lanes, NoProbe, Probe};
use crate::record::phases;
use crate::scene::camera::{look_at, perspective};
use crate::scene::{Light, Mesh};

phases! {
    /// The phases of a shadow-map family run (`hard_shadow_map`, `pcss`): the light raster into
    /// the map, and the eye lookup against it; per cube face `light_raster[+x]`, ...
    /// ([`LightView::phase`]).
    pub enum Phase {
        LightRaster => "light_raster",
        EyeLookup => "eye_lookup",
    }
}

/// The texel of the map that holds `uv` (nearest), or `None` outside the map, where nothing
/// was rasterized and the receiver counts as lit.
pub fn texel(view: &LightView, uv: Vec2) -> Option<(u32, u32)> {
    let r = view.resolution as f32;
    let (x, y) = (uv.x * r, uv.y * r);
    // ⌊x⌋ lies in [0, r) exactly when x does (r is a whole number), and there ⌊x⌋ is the
    // truncation `as u32` does: the same texel as flooring first (as the WGSL mirror does),
    // without a call to `floor` (a library call on baseline x86-64) per tap.
    (x >= 0.0 && y >= 0.0 && x < r && y < r).then_some((x as u32, y as u32))
}

/// The shadow test: a receiver at linear depth `z` is lit when no occluder in the map lies
/// nearer the light than `z − bias` (`map_ndc` is the map's stored NDC depth).
pub fn lit(view: &LightView, map_ndc: f32, z: f32, bias: f32) -> bool {
    z - bias <= view.linear_depth(map_ndc)
}

/// Largest half-angle of one light frustum (one perspective map cannot see a hemisphere).
pub const MAX_HALF_FOV_DEG: f32 = 80.0;

/// Widest half-angle of one frustum fitted to the visible receivers before an algorithm that can
/// use a cube map switches to one ([`ViewFit::CubeWhenWide`]): beyond it a texel at the centre
/// of the map subtends more than √3 times the angle of a cube face's centre texel.
pub const SINGLE_VIEW_MAX_HALF_DEG: f32 = 60.0;

/// Largest guard band around a view's receivers: the angular radius of the light seen from the
/// nearest receiver, up to this, so that occluders of an area light's penumbra just outside the
/// receivers' cone (and filter taps across a cube face's edge) stay in the map.
pub const MAX_GUARD_DEG: f32 = 10.0;

/// Smallest near plane as a fraction of the far plane (f32 NDC depth keeps ~6e-4 relative
/// precision at the far plane there). An occluder nearer the light than that is clipped at the
/// near plane and counted (`light_view.casters_near_clipped`) with a warning.
pub const MIN_NEAR_RATIO: f32 = 1e-4;

/// The six faces of a cube map in the order of [`cube_face`].
pub const CUBE_FACES: [&str; 6] = ["+x", "-x", "+y", "-y", "+z", "-z"];

/// The cube face whose frustum holds direction `d` (its major axis; ties go to x before y before
/// z, and to + for 0): every direction has exactly one face. Mirrored by `cube_face` in
/// eye_lookup.wgsl.
pub fn cube_face(d: Vec3) -> u32 {
    let a = d.abs();
    if a.x >= a.y && a.x >= a.z {
        u32::from(d.x < 0.0)
    } else if a.y >= a.z {
        2 + u32::from(d.y < 0.0)
    } else {
        4 + u32::from(d.z < 0.0)
    }
}

/// The axis of cube face `f`.
fn cube_axis(f: u32) -> Vec3 {
    let s = if f.is_multiple_of(2) { 1.0 } else { -1.0 };
    match f / 2 {
        0 => Vec3::X * s,
        1 => Vec3::Y * s,
        _ => Vec3::Z * s,
    }
}

/// A perspective view from the light centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightView {
    pub eye: Vec3,
    pub view: Mat4,
    pub proj: Mat4,
    pub view_proj: Mat4,
    pub near: f32,
    pub far: f32,
    /// tan(fov/2): half-width of the frustum at unit depth.
    pub tan_half_fov: f32,
    pub resolution: u32,
}

impl LightView {
    /// The square frustum from `eye` along `dir` with half-width `tan_half_fov` at unit depth and
    /// the given near and far planes (world units along `dir`), at `resolution`² texels.
    pub fn looking(
        eye: Vec3,
        dir: Vec3,
        tan_half_fov: f32,
        near: f32,
        far: f32,
        resolution: u32,
    ) -> LightView {
        let dir = dir.normalize_or(Vec3::NEG_Y);
        let up = if dir.cross(Vec3::Y).length_squared() < 1e-6 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        let view = look_at(eye, eye + dir, up);
        let proj = perspective(2.0 * tan_half_fov.atan(), 1.0, near, far);
        LightView {
            eye,
            view,
            proj,
            view_proj: proj * view,
            near,
            far,
            tan_half_fov,
            resolution,
        }
    }

    /// Depth along the view axis and the larger of |x|/depth, |y|/depth (the tan of the frustum
    /// half-angle needed to hold `p`); depth ≤ 0 behind the light.
    fn depth_and_tan(&self, p: Vec3) -> (f32, f32) {
        let v = self.view.transform_point3(p);
        let depth = -v.z;
        (depth, v.x.abs().max(v.y.abs()) / depth)
    }

    /// Whether `p` lies inside the frustum's side planes, in front of the light.
    pub fn contains(&self, p: Vec3) -> bool {
        let (depth, tan) = self.depth_and_tan(p);
        depth > 0.0 && tan <= self.tan_half_fov
    }

    /// The six clip-plane values of view-space `v`, each ≥ 0 inside: in front of the light,
    /// before the far plane, and the four side planes.
    #[inline]
    fn plane_values(&self, v: Vec3) -> [f32; 6] {
        let t = self.tan_half_fov;
        [
            -v.z,
            self.far + v.z,
            -v.z * t - v.x,
            -v.z * t + v.x,
            -v.z * t - v.y,
            -v.z * t + v.y,
        ]
    }

    /// Where view-space triangle `v` lies against the clip planes, decided from its three
    /// vertices: [`FrustumClass::Inside`] when every vertex is inside every plane,
    /// [`FrustumClass::Outside`] when all three are outside the first plane (in
    /// [`Self::plane_values`] order) that not all of them are inside, else
    /// [`FrustumClass::Crosses`]. The first two are exactly what [`Self::clip_to_frustum`]
    /// returns for them (the polygon reaches that plane unclipped), so only the third needs
    /// the clip.
    fn classify(&self, v: &[Vec3; 3]) -> FrustumClass {
        let f = v.map(|v| self.plane_values(v));
        for k in 0..6 {
            let inside = f.map(|f| f[k] >= 0.0);
            if inside == [true; 3] {
                continue;
            }
            return if inside == [false; 3] {
                FrustumClass::Outside
            } else {
                FrustumClass::Crosses
            };
        }
        FrustumClass::Inside
    }

    /// The part of view-space triangle `v` inside the frustum's side planes between the light
    /// and the far plane (Sutherland–Hodgman in view space, winding kept), empty when none is;
    /// and the scalar instructions the clip took.
    fn clip_to_frustum(&self, v: [Vec3; 3]) -> (ClipPolygon, u32) {
        let mut poly = ClipPolygon::triangle(v);
        let mut ops = 0;
        for k in 0..6 {
            let mut out = ClipPolygon::default();
            let n = poly.len;
            for i in 0..n {
                let (a, b) = (poly.v[i], poly.v[(i + 1) % n]);
                let (fa, fb) = (self.plane_values(a)[k], self.plane_values(b)[k]);
                ops += CLIP_VERTEX_SCALAR;
                if fa >= 0.0 {
                    out.push(a);
                    ops += CLIP_KEEP_SCALAR;
                }
                if (fa >= 0.0) != (fb >= 0.0) {
                    out.push(a + (b - a) * (fa / (fa - fb)));
                    ops += CLIP_NEW_SCALAR;
                }
            }
            poly = out;
            if poly.len == 0 {
                break;
            }
        }
        (poly, ops)
    }

    /// The smallest depth of the part of triangle `tri` inside the frustum's side planes between
    /// the light and the far plane, or `None` when no part of it is inside: the triangle can
    /// neither shadow a receiver of this view nor appear in its map.
    pub fn caster_depth(&self, tri: [Vec3; 3]) -> Option<f32> {
        let v = tri.map(|p| self.view.transform_point3(p));
        match self.classify(&v) {
            FrustumClass::Outside => None,
            FrustumClass::Inside => v.iter().map(|v| -v.z).reduce(f32::min),
            FrustumClass::Crosses => self
                .clip_to_frustum(v)
                .0
                .as_slice()
                .iter()
                .map(|v| -v.z)
                .reduce(f32::min),
        }
    }

    /// The draw list of the light pass for `mesh`, built on the host as engines build a shadow
    /// map face's: triangles that do not meet the frustum are culled, triangles wholly beyond
    /// the near plane drawn as they are, and the few that reach nearer the light than the near
    /// plane (e.g. a wall through the light's plane, whose near part lies outside the frustum)
    /// drawn as their part inside the frustum (a fan, new vertices appended), so the rasterizer
    /// never clips away a part that lies in the map. The same work as the `casters` step of
    /// the CPU executions ([`cpu::casters`]), run here in one piece without counting.
    pub fn casters(&self, mesh: &Mesh) -> Mesh {
        let part = self.casters_part(&mut NoProbe, mesh, None, 0..mesh.triangles.len());
        assemble_casters(mesh, vec![part])
    }

    /// The draw list's part for triangles `range` of `mesh` ([`Self::casters`]), telling `p`
    /// what it executes: per 16 triangles (one per lane) the index load, the vertex gathers
    /// and [`CASTER_CLASSIFY_OPS`] vector instructions; per kept triangle an index store, per
    /// clipped one its clip, per fan vertex its transform back and store. `memory`: the
    /// modelled buffers (input vertices and indices, output indices and new vertices), `None`
    /// when nothing is counted.
    pub fn casters_part<P: Probe>(
        &self,
        p: &mut P,
        mesh: &Mesh,
        memory: Option<&CasterBuffers>,
        range: std::ops::Range<usize>,
    ) -> CastersPart {
        let mut part = CastersPart {
            triangles: Vec::with_capacity(range.len()),
            positions: Vec::new(),
        };
        let to_world = self.view.inverse();
        let first = range.start as u64;
        let memory = memory.filter(|_| P::ENABLED);
        for (group, n, mask) in lane_groups(range) {
            if let Some(b) = memory {
                p.read(b.indices.0, b.indices.1 + group as u64 * 12, 12 * n as u32);
                for k in 0..3 {
                    let addrs: Lanes<u64> = std::array::from_fn(|l| {
                        let t = mesh.triangles[group + l.min(n - 1)];
                        b.positions.1 + u64::from(t[k]) * 12
                    });
                    p.gather(b.positions.0, &addrs, 12, mask);
                }
            }
            p.vector(CASTER_CLASSIFY_OPS, mask);
            for t in group..group + n {
                let idx = mesh.triangles[t];
                let v = mesh.triangle(t).map(|p| self.view.transform_point3(p));
                let (poly, ops) = match self.classify(&v) {
                    FrustumClass::Outside => continue,
                    FrustumClass::Inside => (ClipPolygon::triangle(v), 0),
                    FrustumClass::Crosses => self.clip_to_frustum(v),
                };
                p.scalar(ops);
                if poly.len == 0 {
                    continue;
                }
                let nearer = v.iter().any(|v| -v.z < self.near);
                p.scalar(CASTER_KEEP_SCALAR);
                if !nearer {
                    if let Some(b) = memory {
                        let k = part.triangles.len() as u64;
                        let at = (first * FAN_TRIANGLES_MAX + k) * 12;
                        p.write(b.out_indices.0, b.out_indices.1 + at, 12);
                    }
                    part.triangles.push(Caster::Kept(idx));
                    continue;
                }
                let base = part.positions.len() as u32;
                for &v in poly.as_slice() {
                    if let Some(b) = memory {
                        let at = (first * FAN_VERTICES_MAX + part.positions.len() as u64) * 12;
                        p.write(b.out_positions.0, b.out_positions.1 + at, 12);
                    }
                    p.scalar(FAN_VERTEX_SCALAR);
                    part.positions.push(to_world.transform_point3(v));
                }
                for k in 1..poly.len.saturating_sub(1) as u32 {
                    if let Some(b) = memory {
                        let i = part.triangles.len() as u64;
                        let at = (first * FAN_TRIANGLES_MAX + i) * 12;
                        p.write(b.out_indices.0, b.out_indices.1 + at, 12);
                    }
                    p.scalar(CASTER_KEEP_SCALAR);
                    part.triangles
                        .push(Caster::Fan([base, base + k, base + k + 1]));
                }
            }
        }
        part
    }

    /// Map coordinates of `p`: (u, v) in [0, 1]² with v down, NDC depth in [0, 1], and linear
    /// depth. `None` when `p` is behind the light.
    pub fn project(&self, p: Vec3) -> Option<(Vec2, f32, f32)> {
        let (uv, ndc_z, z, front) = self.project_lane(p);
        front.then_some((uv, ndc_z, z))
    }

    /// [`Self::project`] without a branch, for lane code: the map coordinates, NDC depth and
    /// linear depth computed whatever `p` is, and whether `p` is in front of the light (where
    /// they mean something).
    #[inline]
    pub fn project_lane(&self, p: Vec3) -> (Vec2, f32, f32, bool) {
        let c = self.view_proj * p.extend(1.0);
        let ndc = c.xyz() / c.w;
        (
            Vec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5),
            ndc.z,
            c.w,
            c.w > 0.0,
        )
    }

    /// Distance along the view axis for an NDC depth (inverse of the projection's depth).
    pub fn linear_depth(&self, ndc: f32) -> f32 {
        self.near * self.far / (self.far - ndc * (self.far - self.near))
    }

    /// World size of one map texel at linear depth `z`.
    #[inline]
    pub fn texel_world(&self, z: f32) -> f32 {
        2.0 * z * self.tan_half_fov / self.resolution as f32
    }

    /// A world length `w` at linear depth `z` expressed in map uv units.
    pub fn world_to_uv(&self, w: f32, z: f32) -> f32 {
        w / (2.0 * z * self.tan_half_fov)
    }
}

/// Where a triangle lies against a light view's clip planes ([`LightView::classify`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FrustumClass {
    Inside,
    Outside,
    Crosses,
}

/// A convex polygon of at most 9 view-space vertices: a triangle clipped by six planes gains at
/// most one vertex per plane.
#[derive(Clone, Copy, Debug, Default)]
struct ClipPolygon {
    v: [Vec3; 9],
    len: usize,
}

impl ClipPolygon {
    fn triangle(t: [Vec3; 3]) -> ClipPolygon {
        let mut p = ClipPolygon::default();
        for v in t {
            p.push(v);
        }
        p
    }

    fn push(&mut self, v: Vec3) {
        self.v[self.len] = v;
        self.len += 1;
    }

    fn as_slice(&self) -> &[Vec3] {
        &self.v[..self.len]
    }
}

/// Vector instructions of the caster test per 16 triangles (one per lane): three vertices to
/// view space (3 × 9 multiply-adds), their six plane values (3 × 6: a negate, an add, four
/// multiply-adds), the 18 compares, per vertex an outcode (3 × 5 ors), the and/or of the
/// three outcodes that tell inside, outside and crossing (4), and the near-plane test (3
/// compares, 2 ors).
pub const CASTER_CLASSIFY_OPS: u32 = 27 + 18 + 18 + 15 + 4 + 5;

/// Scalar instructions per triangle appended to the draw list: the append and its loop control.
const CASTER_KEEP_SCALAR: u32 = 3;

/// Scalar instructions per fan vertex: the transform back to world space (9 multiply-adds and
/// 3 adds).
const FAN_VERTEX_SCALAR: u32 = 12;

/// Scalar instructions of a Sutherland–Hodgman clip, per plane: per input vertex its plane
/// value (2), the compare and branch (2) and the loop control (1); per kept vertex its store
/// (1); per new vertex the interpolation (a subtract, a divide, 3 subtracts, 3 multiply-adds)
/// and its store (9).
const CLIP_VERTEX_SCALAR: u32 = 5;
const CLIP_KEEP_SCALAR: u32 = 1;
const CLIP_NEW_SCALAR: u32 = 9;

/// Room in the draw list's modelled buffers per scene triangle: a clipped triangle becomes a
/// fan of up to 7 triangles over up to 9 new vertices ([`ClipPolygon`]).
pub const FAN_TRIANGLES_MAX: u64 = 7;
pub const FAN_VERTICES_MAX: u64 = 9;

/// Modelled buffers of the `casters` step: (id, base address) of the scene's vertices and
/// indices, the draw list's indices and its new (fan) vertices.
pub struct CasterBuffers {
    pub positions: (BufferId, u64),
    pub indices: (BufferId, u64),
    pub out_indices: (BufferId, u64),
    pub out_positions: (BufferId, u64),
}

/// One triangle of a draw list part: a scene triangle kept as it is, or a fan triangle over
/// the part's own new vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Caster {
    Kept([u32; 3]),
    Fan([u32; 3]),
}

/// The draw list for a range of triangles ([`LightView::casters_part`]).
#[derive(Clone, Debug, Default)]
pub struct CastersPart {
    pub triangles: Vec<Caster>,
    /// New vertices (world space) of the part's fans, in order.
    pub positions: Vec<Vec3>,
}

/// The draw list of `mesh` from its parts in triangle order: the scene's vertices, then each
/// part's new vertices appended, fan indices moved to where they land.
pub fn assemble_casters(mesh: &Mesh, parts: Vec<CastersPart>) -> Mesh {
    let mut out = Mesh {
        positions: mesh.positions.clone(),
        triangles: Vec::with_capacity(parts.iter().map(|p| p.triangles.len()).sum()),
    };
    for part in parts {
        let base = out.positions.len() as u32;
        out.triangles
            .extend(part.triangles.iter().map(|t| match *t {
                Caster::Kept(idx) => idx,
                Caster::Fan(idx) => idx.map(|i| base + i),
            }));
        out.positions.extend(part.positions);
    }
    out
}

/// How many views an algorithm may use to cover the receivers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewFit {
    /// One frustum (the algorithm's paper defines one light-space map); receivers it cannot
    /// hold are counted (`light_view.receivers_outside`) and warned about, never dropped
    /// silently.
    Single,
    /// One frustum when the receivers fit in [`SINGLE_VIEW_MAX_HALF_DEG`], else a cube map: up to
    /// six 90° faces (grown by the guard band), each an ordinary shadow map of the receivers
    /// whose direction from the light lies in it ([`cube_face`]), as engines do for point lights.
    CubeWhenWide,
}

/// One view of a [`LightViews`]: a single frustum, or one face of a cube map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceView {
    /// The cube face ([`CUBE_FACES`]), or `None` for a single frustum.
    pub face: Option<u32>,
    pub view: LightView,
}

impl FaceView {
    /// Whether this view shades the receiver at `p`: every receiver for a single frustum (those
    /// outside its map are lit), the receivers in its direction for a cube face.
    pub fn owns(&self, p: Vec3) -> bool {
        self.face.is_none_or(|f| cube_face(p - self.view.eye) == f)
    }

    /// The uniform value the WGSL mirrors take for [`Self::owns`]: the face, or 6 for all.
    pub fn face_code(&self) -> u32 {
        self.face.unwrap_or(6)
    }

    /// Copies into `vis` the pixels of `part` (rendered with this view) that it shades: with
    /// several views each pixel comes from exactly one.
    pub fn take_owned(
        &self,
        frame: &crate::frame::Frame,
        part: &crate::visibility::VisibilityBuffer,
        vis: &mut crate::visibility::VisibilityBuffer,
    ) {
        let g = &frame.gbuffer;
        for i in 0..g.len() {
            if g.is_hit(i) && self.owns(g.position[i]) {
                vis.data[i] = part.data[i];
            }
        }
    }

    /// `name` of a phase of this view: unchanged for a single frustum, `name[+x]` for a face.
    pub fn phase(&self, name: &str) -> String {
        match self.face {
            None => name.to_string(),
            Some(f) => format!("{name}[{}]", CUBE_FACES[f as usize]),
        }
    }
}

/// The light views of a frame, fitted to what matters: the receivers the eye sees and the
/// occluders between them and the light (not the scene's bounds, which put the near plane at the
/// nearest bounds corner and clipped every occluder nearer the light than that).
///
/// The axis is the mean direction from the light centre to the visible receivers (a disc light's
/// own normal: its emitter faces that way); the frustum grows to hold them plus a guard band of
/// the light's angular radius from the nearest receiver (up to [`MAX_GUARD_DEG`]). Far is the
/// farthest receiver a view holds; near is the nearest point of any triangle inside the frustum
/// ([`LightView::caster_depth`]), at least [`MIN_NEAR_RATIO`] × far.
#[derive(Clone, Debug, PartialEq)]
pub struct LightViews {
    pub views: Vec<FaceView>,
    /// Eye pixels that see a surface facing the light centre that no view holds: the algorithm
    /// takes them as lit (one facing away is shaded as the eye pass shades such surfaces
    /// everywhere: in shadow, or by the part of the light in front of its plane).
    pub receivers_outside: u64,
    /// Triangles inside a view's frustum part of which lies nearer the light than its near
    /// plane (clamped at [`MIN_NEAR_RATIO`] × far): clipped there.
    pub casters_near_clipped: u64,
}

impl LightViews {
    /// The views of `frame`'s light for its receivers at `map_resolution`² texels each.
    pub fn fit(frame: &crate::frame::Frame, fit: ViewFit) -> LightViews {
        let (light, resolution) = (&frame.scene.light, frame.params.map_resolution);
        let eye = light.center();
        let g = &frame.gbuffer;
        let receivers: Vec<Vec3> = (0..g.len())
            .filter(|&i| g.is_hit(i))
            .map(|i| g.position[i])
            .collect();
        // Receivers facing away from the light centre are shaded by the eye pass's own rule
        // (`cpu::Receivers::averted`) wherever they lie: only the others are taken as lit
        // outside the views.
        let facing: Vec<bool> = (0..g.len())
            .filter(|&i| g.is_hit(i))
            .map(|i| g.normal[i].dot(eye - g.position[i]) > 0.0)
            .collect();
        let nearest = receivers
            .iter()
            .map(|p| p.distance(eye))
            .fold(f32::INFINITY, f32::min);
        let guard = if nearest > 0.0 {
            (light.size() / nearest)
                .atan()
                .min(MAX_GUARD_DEG.to_radians())
        } else {
            MAX_GUARD_DEG.to_radians()
        };
        let axis = match *light {
            Light::Disc { normal, .. } => normal.normalize_or(Vec3::NEG_Y),
            _ => receivers
                .iter()
                .map(|&p| (p - eye).normalize_or_zero())
                .sum::<Vec3>()
                .normalize_or((frame.scene.bounds().center() - eye).normalize_or(Vec3::NEG_Y)),
        };
        // The single frustum: the widest receiver around the axis, plus the guard band.
        let probe = LightView::looking(eye, axis, 1.0, 1.0, 2.0, resolution);
        let needed = receivers
            .iter()
            .map(|&p| match probe.depth_and_tan(p) {
                (d, t) if d > 0.0 => t.atan(),
                _ => std::f32::consts::PI,
            })
            .fold(0.0f32, f32::max);
        let half = needed + guard;
        let mut views = LightViews {
            views: Vec::new(),
            receivers_outside: 0,
            casters_near_clipped: 0,
        };
        let mut held = vec![false; receivers.len()];
        let faces: Vec<(Option<u32>, Vec3, f32)> =
            if fit == ViewFit::CubeWhenWide && half > SINGLE_VIEW_MAX_HALF_DEG.to_radians() {
                let tan = (std::f32::consts::FRAC_PI_4 + guard).tan();
                (0..6u32)
                    .filter(|&f| receivers.iter().any(|&p| cube_face(p - eye) == f))
                    .map(|f| (Some(f), cube_axis(f), tan))
                    .collect()
            } else {
                vec![(None, axis, half.min(MAX_HALF_FOV_DEG.to_radians()).tan())]
            };
        for (face, dir, tan) in faces {
            let probe = LightView::looking(eye, dir, tan, 1.0, 2.0, resolution);
            let mut far = 0.0f32;
            for (k, &p) in receivers.iter().enumerate() {
                let owned = face.is_none_or(|f| cube_face(p - eye) == f);
                if owned && probe.contains(p) {
                    held[k] = true;
                    far = far.max(probe.depth_and_tan(p).0);
                }
            }
            if far <= 0.0 {
                // Nothing to shade: a view of the scene's far side keeps the map well defined.
                far = frame.scene.bounds().diagonal().max(1e-3);
            }
            let far = far * 1.01;
            let bounded = LightView::looking(eye, dir, tan, far * MIN_NEAR_RATIO, far, resolution);
            let depths: Vec<f32> = (0..frame.flat.mesh.triangles.len())
                .filter_map(|t| bounded.caster_depth(frame.flat.mesh.triangle(t)))
                .collect();
            let near = depths
                .iter()
                .fold(f32::INFINITY, |a, &b| a.min(b * 0.99))
                .min(far * 0.5)
                .max(far * MIN_NEAR_RATIO);
            views.casters_near_clipped += depths.iter().filter(|&&d| d < near).count() as u64;
            views.views.push(FaceView {
                face,
                view: LightView::looking(eye, dir, tan, near, far, resolution),
            });
        }
        views.receivers_outside =
            held.iter().zip(&facing).filter(|&(&h, &f)| !h && f).count() as u64;
        views
    }

    /// The single frustum of a [`ViewFit::Single`] fit.
    pub fn single(&self) -> &LightView {
        &self.views[0].view
    }

    /// Records the fit in `out`: `light_view.faces`, `light_view.receivers_outside`,
    /// `light_view.casters_near_clipped` counters, and a warning for each figure that means
    /// shadowing the run did not compute.
    pub fn record(&self, out: &mut crate::algorithms::FrameOutput) {
        let c = &mut out.counters;
        c.set(names::LIGHT_VIEW_FACES, self.views.len() as f64);
        c.set(
            names::LIGHT_VIEW_RECEIVERS_OUTSIDE,
            self.receivers_outside as f64,
        );
        c.set(
            names::LIGHT_VIEW_CASTERS_NEAR_CLIPPED,
            self.casters_near_clipped as f64,
        );
        if self.receivers_outside > 0 {
            out.warnings.push(format!(
                "{} visible receiver pixels facing the light lie outside the light view (behind the light or beyond {MAX_HALF_FOV_DEG}° from its axis) and are taken as lit",
                self.receivers_outside
            ));
        }
        if self.casters_near_clipped > 0 {
            out.warnings.push(format!(
                "{} occluding triangles reach nearer the light than {MIN_NEAR_RATIO} of the light view's far plane and are clipped there",
                self.casters_near_clipped
            ));
        }
    }
}

/// Bytes a shadow-map run allocates beyond the frame, on any execution: the
/// `map_resolution`² map of f32 depth, and per pixel the execution's own copies of the gbuffer
/// (position and normal, padded to 16 bytes each on the GPU), the visibility buffer and its
/// readback copy.
pub fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
    let map = map_bytes(p);
    let pixels = u64::from(p.image[0]) * u64::from(p.image[1]);
    map + pixels * (2 * 16 + 2 * 4)
}

/// Slope-scaled depth bias, in linear depth units: `constant` texels plus `slope` texels per
/// unit of tan(θ), θ the angle between the surface normal and the direction to the light
/// (clamped at 10 so grazing surfaces stay finite).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bias {
    pub constant: f32,
    pub slope: f32,
}

impl Default for Bias {
    fn default() -> Self {
        Bias {
            constant: 1.5,
            slope: 1.5,
        }
    }
}

impl Bias {
    /// Checks both terms are finite and ≥ 0; `id` names the algorithm whose options hold it
    /// (`$.options.<id>.bias.*`).
    pub fn validate(&self, id: &str) -> Result<(), crate::error::InputError> {
        let field = |name: &str| format!("$.options.{id}.bias.{name}");
        crate::error::InputError::check_non_negative(field("constant"), self.constant)?;
        crate::error::InputError::check_non_negative(field("slope"), self.slope)
    }

    #[inline]
    pub fn at(&self, view: &LightView, z: f32, n_dot_l: f32) -> f32 {
        let c = n_dot_l.clamp(1e-4, 1.0);
        let tan = ((1.0 - c * c).sqrt() / c).min(10.0);
        view.texel_world(z) * (self.constant + self.slope * tan)
    }
}

/// Sample `i` of `n` on the unit disc by Vogel's golden-angle spiral: a deterministic,
/// evenly spread pattern that both executions generate identically.
pub fn vogel_disk(i: u32, n: u32) -> Vec2 {
    const GOLDEN_ANGLE: f32 = 2.399_963_3;
    let r = ((i as f32 + 0.5) / n as f32).sqrt();
    let theta = i as f32 * GOLDEN_ANGLE;
    Vec2::new(theta.cos(), theta.sin()) * r
}

/// PCSS step 1 (Fernando 2005): radius in uv of the blocker search at receiver depth `z_r`:
/// the light's cone from the receiver point, cut at the near plane,
/// `R/(2·n·tan) · (z_r − n)/z_r`.
pub fn pcss_search_radius_uv(view: &LightView, light_radius: f32, z_r: f32) -> f32 {
    view.world_to_uv(light_radius, view.near) * (z_r - view.near).max(0.0) / z_r
}

/// PCSS step 1, the blocker test: the plane of a receiver at world position `p` with normal
/// `n` ([`ReceiverPlane::new`]), and its linear depth along the light-view ray through map
/// coordinates `uv` ([`ReceiverPlane::depth_at`]), `+∞` where that ray meets the plane behind
/// the light or never. A map texel is a blocker only in front
/// of the receiver's plane: a surface on it or behind it (the receiver's own plane seen at a
/// grazing angle, the rest of a convex receiver) hides no part of a light in front of it, which
/// the plain search of Fernando 2005 would average in (a ceiling lit from below darkened by its
/// own plane in the cube faces that see it edge-on). Over a plane, 1/depth is affine in the
/// ray's slopes: `1/z = (n_x·x + n_y·y − n_z) / (n·p)` in view space, `x = (2u − 1)·tan`,
/// `y = (1 − 2v)·tan`.
///
/// The plane is set up in view space once per receiver (its normal and `n·p`) for the taps of
/// its blocker search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReceiverPlane {
    normal: Vec3,
    offset: f32,
}

impl ReceiverPlane {
    pub fn new(view: &LightView, p: Vec3, n: Vec3) -> ReceiverPlane {
        let (pv, nv) = (
            view.view.transform_point3(p),
            view.view.transform_vector3(n),
        );
        ReceiverPlane {
            normal: nv,
            offset: nv.dot(pv),
        }
    }

    /// The plane's linear depth along the light-view ray through map coordinates `uv`; `+∞`
    /// where that ray meets it behind the light or never.
    pub fn depth_at(&self, view: &LightView, uv: Vec2) -> f32 {
        let nv = self.normal;
        let x = (2.0 * uv.x - 1.0) * view.tan_half_fov;
        let y = (1.0 - 2.0 * uv.y) * view.tan_half_fov;
        let inv = (nv.x * x + nv.y * y - nv.z) / self.offset;
        if inv > 0.0 {
            1.0 / inv
        } else {
            f32::INFINITY
        }
    }
}

/// PCSS step 2: penumbra radius in world units on the receiver by similar triangles,
/// `R · (z_r − z_b)/z_b`.
pub fn pcss_penumbra_radius(light_radius: f32, z_r: f32, z_b: f32) -> f32 {
    light_radius * (z_r - z_b).max(0.0) / z_b
}

/// PCSS step 3: the filter radius in uv at the receiver depth.
pub fn pcss_filter_radius_uv(view: &LightView, light_radius: f32, z_r: f32, z_b: f32) -> f32 {
    view.world_to_uv(pcss_penumbra_radius(light_radius, z_r, z_b), z_r)
}

/// Bytes of one f32 depth map at the run's map resolution (the memory estimate of the
/// shadow-map family before anything is allocated).
pub fn map_bytes(p: &crate::frame::RunParams) -> u64 {
    p.map_resolution as u64 * p.map_resolution as u64 * 4
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::PhaseId;

    #[test]
    fn projection_round_trips_depth_and_frames_its_frustum() {
        let eye = Vec3::new(0.0, 10.0, 0.0);
        let v = LightView::looking(eye, Vec3::NEG_Y, 0.5, 1.0, 20.0, 512);
        let (uv, ndc, z) = v.project(Vec3::new(0.0, 0.5, 0.0)).unwrap();
        assert!((uv - Vec2::splat(0.5)).length() < 1e-4);
        assert!((v.linear_depth(ndc) - z).abs() < 1e-3 * z);
        assert!((z - 9.5).abs() < 1e-3);
        // A point on the frustum's side plane lands on the map's border.
        let (uv, _, _) = v.project(Vec3::new(2.0, 6.0, 0.0)).unwrap();
        assert!((uv.x - 1.0).abs() < 1e-4 || uv.x.abs() < 1e-4, "{uv}");
        assert!(v.contains(Vec3::new(1.9, 6.0, 0.0)));
        assert!(!v.contains(Vec3::new(2.1, 6.0, 0.0)));
        assert!(!v.contains(Vec3::new(0.0, 11.0, 0.0)));
    }

    #[test]
    fn caster_depth_is_the_nearest_point_inside_the_frustum() {
        let v = LightView::looking(Vec3::ZERO, Vec3::NEG_Y, 1.0, 0.1, 10.0, 64);
        // A ceiling just above the light is behind it: no part inside.
        let ceiling = [
            Vec3::new(-5.0, 0.1, -5.0),
            Vec3::new(5.0, 0.1, -5.0),
            Vec3::new(0.0, 0.1, 5.0),
        ];
        assert_eq!(v.caster_depth(ceiling), None);
        // A wall through the light's plane: inside the 45° frustum only from depth |x| = 3 on.
        let wall = [
            Vec3::new(3.0, 1.0, -1.0),
            Vec3::new(3.0, -8.0, -1.0),
            Vec3::new(3.0, -8.0, 1.0),
        ];
        let d = v.caster_depth(wall).unwrap();
        assert!((d - 3.0).abs() < 1e-4, "{d}");
        // A triangle beyond the far plane is not a caster.
        let below = ceiling.map(|p| p - Vec3::Y * 12.0);
        assert_eq!(v.caster_depth(below), None);
    }

    #[test]
    fn texel_is_the_floored_texel_inside_the_map() {
        let v = LightView::looking(Vec3::ZERO, Vec3::NEG_Y, 1.0, 0.1, 10.0, 64);
        let floored = |uv: Vec2| {
            let (x, y) = ((uv.x * 64.0).floor(), (uv.y * 64.0).floor());
            (x >= 0.0 && y >= 0.0 && x < 64.0 && y < 64.0).then_some((x as u32, y as u32))
        };
        let edges = [
            -1.0,
            -0.5 / 64.0,
            -1e-9,
            -0.0,
            0.0,
            1e-9,
            0.5,
            1.0 - 1e-7,
            1.0,
            1.0 + 1e-7,
            2.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        for &a in &edges {
            for &b in &edges {
                let uv = Vec2::new(a, b);
                assert_eq!(texel(&v, uv), floored(uv), "{uv}");
            }
        }
        for i in 0..5000u64 {
            let uv = crate::util::hash::unit_pair(7, i) * 1.2 - Vec2::splat(0.1);
            assert_eq!(texel(&v, uv), floored(uv), "{uv}");
        }
    }

    /// Triangles scattered around and through `v`'s frustum (inside, outside, across its
    /// planes and through the light's plane), deterministic.
    /// A mesh of separate triangles `tris`.
    fn mesh_of(tris: &[[Vec3; 3]]) -> Mesh {
        Mesh {
            positions: tris.iter().flatten().copied().collect(),
            triangles: (0..tris.len() as u32)
                .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
                .collect(),
        }
    }

    fn scattered_triangles(n: u64) -> Vec<[Vec3; 3]> {
        use crate::util::hash::{mix64, unit_f32};
        let r = |i: u64| unit_f32(mix64(i)) * 24.0 - 12.0;
        (0..n)
            .map(|t| {
                let c = Vec3::new(r(9 * t), r(9 * t + 1) - 6.0, r(9 * t + 2));
                let s = 0.2 + unit_f32(mix64(t ^ 0xabc)) * 6.0;
                std::array::from_fn(|k| {
                    let k = 9 * t + 3 + 2 * k as u64;
                    c + Vec3::new(r(k), r(k + 1), r(k ^ 0x55)) * s / 12.0
                })
            })
            .collect()
    }

    /// The draw list as the full clip of every triangle gives it (the construction before the
    /// classification): the oracle of [`LightView::casters`].
    fn casters_by_full_clip(v: &LightView, mesh: &Mesh) -> Mesh {
        let to_world = v.view.inverse();
        let mut out = Mesh {
            positions: mesh.positions.clone(),
            triangles: Vec::new(),
        };
        for (t, &idx) in mesh.triangles.iter().enumerate() {
            let tri = mesh.triangle(t).map(|p| v.view.transform_point3(p));
            let poly = v.clip_to_frustum(tri).0;
            if poly.len == 0 {
                continue;
            }
            if !tri.iter().any(|p| -p.z < v.near) {
                out.triangles.push(idx);
                continue;
            }
            let base = out.positions.len() as u32;
            out.positions.extend(
                poly.as_slice()
                    .iter()
                    .map(|&p| to_world.transform_point3(p)),
            );
            for k in 1..poly.len.saturating_sub(1) as u32 {
                out.triangles.push([base, base + k, base + k + 1]);
            }
        }
        out
    }

    #[test]
    fn classified_casters_match_the_full_clip_of_every_triangle() {
        let v = LightView::looking(Vec3::new(0.0, 4.0, 0.0), Vec3::NEG_Y, 0.8, 0.5, 14.0, 64);
        let tris = scattered_triangles(3000);
        let mut classes = [0usize; 3];
        for tri in &tris {
            let view = tri.map(|p| v.view.transform_point3(p));
            let (full, _) = v.clip_to_frustum(view);
            match v.classify(&view) {
                FrustumClass::Inside => {
                    classes[0] += 1;
                    assert_eq!(
                        full.as_slice(),
                        &view[..],
                        "an inside triangle is kept whole"
                    );
                }
                FrustumClass::Outside => {
                    classes[1] += 1;
                    assert_eq!(full.len, 0, "an outside triangle has no part inside");
                }
                FrustumClass::Crosses => classes[2] += 1,
            }
            let full_depth = full.as_slice().iter().map(|p| -p.z).reduce(f32::min);
            assert_eq!(v.caster_depth(*tri), full_depth);
        }
        assert!(
            classes.iter().all(|&c| c > 100),
            "every class exercised: {classes:?}"
        );
        let mesh = mesh_of(&tris);
        let want = casters_by_full_clip(&v, &mesh);
        assert!(want.positions.len() > mesh.positions.len(), "some fans");
        let got = v.casters(&mesh);
        assert_eq!(got.triangles, want.triangles);
        assert_eq!(got.positions, want.positions);
        // Cut into parts (the tasks of the `casters` step), the same list.
        let parts = (0..tris.len())
            .step_by(700)
            .map(|t| v.casters_part(&mut NoProbe, &mesh, None, t..(t + 700).min(tris.len())))
            .collect();
        let joined = assemble_casters(&mesh, parts);
        assert_eq!(joined.triangles, want.triangles);
        assert_eq!(joined.positions, want.positions);
    }

    #[test]
    fn the_casters_step_builds_the_same_list_on_both_executions_and_counts_it() {
        use crate::backend::Backend;
        use crate::model::{Machine, MachineConfig};
        let v = LightView::looking(Vec3::new(0.0, 4.0, 0.0), Vec3::NEG_Y, 0.8, 0.5, 14.0, 64);
        let tris = scattered_triangles(2500);
        let mesh = mesh_of(&tris);
        let want = casters_by_full_clip(&v, &mesh);
        let mut vector_ops = Vec::new();
        for (backend, cores) in [
            (Backend::CpuNative, 4),
            (Backend::CpuModel, 4),
            (Backend::CpuModel, 3),
        ] {
            let mut m = Machine::new(backend, MachineConfig::larrabee(cores));
            m.phase(Phase::LightRaster.name());
            let got = cpu::casters(&mut m, &v, &mesh);
            assert_eq!(got.triangles, want.triangles, "{backend:?}");
            assert_eq!(got.positions, want.positions, "{backend:?}");
            let f = m.finish();
            assert_eq!(
                f.counters.get(names::CASTERS_TRIANGLES),
                Some(want.triangles.len() as f64)
            );
            if backend == Backend::CpuModel {
                // One triangle a lane: tasks of 1024 triangles, 16 a vector (the last partial).
                let groups: usize = (0..tris.len())
                    .step_by(1024)
                    .map(|t| (tris.len() - t).min(1024).div_ceil(16))
                    .sum();
                let ops = f.counters.get(names::VECTOR_OPS).unwrap();
                assert_eq!(ops, (groups as u32 * CASTER_CLASSIFY_OPS) as f64);
                assert!(f.counters.get(names::SCALAR_OPS).unwrap() > 0.0);
                vector_ops.push(ops);
            }
        }
        assert_eq!(
            vector_ops[0], vector_ops[1],
            "the same count on 4 and 3 cores"
        );
    }

    #[test]
    fn every_direction_has_exactly_one_cube_face_and_faces_hold_their_directions() {
        let v: Vec<LightView> = (0..6)
            .map(|f| LightView::looking(Vec3::ZERO, cube_axis(f), 1.0 + 1e-4, 0.1, 10.0, 64))
            .collect();
        for i in 0..200 {
            let d = Vec3::new(
                ((i * 37) % 19) as f32 - 9.0,
                ((i * 11) % 23) as f32 - 11.0,
                ((i * 7) % 17) as f32 - 8.0,
            );
            if d == Vec3::ZERO {
                continue;
            }
            let f = cube_face(d) as usize;
            assert!(v[f].contains(d), "{d} face {}", CUBE_FACES[f]);
            assert!(d.dot(cube_axis(f as u32)) > 0.0);
        }
        assert_eq!(cube_face(Vec3::new(1.0, 1.0, 1.0)), 0);
        assert_eq!(cube_face(Vec3::new(0.0, -1.0, 1.0)), 3);
    }

    #[test]
    fn penumbra_grows_with_blocker_receiver_distance() {
        // Blocker halfway between light and receiver: the penumbra radius equals the light's.
        assert!((pcss_penumbra_radius(0.5, 10.0, 5.0) - 0.5).abs() < 1e-6);
        assert_eq!(pcss_penumbra_radius(0.5, 10.0, 10.0), 0.0);
    }

    #[test]
    fn vogel_disk_stays_in_the_unit_disc() {
        let n = 32;
        let mean = (0..n).map(|i| vogel_disk(i, n)).sum::<Vec2>() / n as f32;
        assert!((0..n).all(|i| vogel_disk(i, n).length() <= 1.0));
        assert!(mean.length() < 0.1);
    }
}
