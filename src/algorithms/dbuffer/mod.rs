//! Umbra and penumbra volumes with the D-buffer (paper 003): soft shadows of a disc light whose
//! boundaries come from the *area* silhouettes of the occluders, not the silhouette seen from
//! one point of the light (Figure 1).
//!
//! 1. **Silhouettes** (§2.1): each occluder face is classified with the two disc points of
//!    eq. 1 as *all-frontfacing*, *none-frontfacing* or a *silhouette face*; an edge between a
//!    none-frontfacing face and one that is not is an umbra-volume silhouette edge, an edge
//!    between an all-frontfacing face and one that is not a penumbra-volume silhouette edge.
//! 2. **Volumes** (§2.1, Figure 3b): per edge the point `a` where its line meets the light plane,
//!    the two disc points `p_u`, `p_p` whose planes through the edge are tangent to the disc
//!    ([`extrusion_points`]), an umbra quad extruded away from `p_u` (trimmed, below) and a
//!    penumbra quad away from `p_p`; penumbra quads meeting at a vertex are closed by triangles extruded from disc
//!    points interpolated on the rim between their `p_p` ([`rim_arc`]); silhouette faces whose
//!    plane has the light centre behind it are drawn with the umbra volume (§3.3, Figure 6).
//! 3. **D-buffer** (§3): rendered from the light centre `c`: the occluders (`|cx_o|`; objects
//!    whose role is receiver only are left out: they cast no shadow), the umbra
//!    volume (`|cx_uv|`) and the penumbra volume (`|cx_pv|`), each volume fragment also carrying
//!    the depth of its silhouette edge below the light plane, from which eq. 2 gives `|cx_s|`.
//! 4. **Eye lookup** (§4): per eye sample `x`, `t` by eq. 3 ([`t_umbra`], [`t_penumbra`]) and
//!    `V(t) = 3t² − 2t³` (eq. 4) or `V = √t` (§6.2), option `falloff`, times the part of the
//!    disc in front of the receiver's own plane ([`front_fraction`]; not in the paper, which
//!    leaves attached shadows to the lighting).
//!
//! Where this implementation reads the paper in a particular way, the function says so:
//! the signs of eq. 1 ([`disc_extremes`]), the ratio of eq. 2 ([`edge_distance`]), the
//! denominator of eq. 3 ([`t_umbra`]) and the depth rule of the D-buffer ([`DEPTH_RULE`]).
//!
//! Umbra quads are trimmed where they meet (§2.1, Figure 2b) locally: at a vertex shared by
//! two umbra silhouette edges forming a convex corner, each quad is clipped by the other's
//! plane. Not built: trimming against quads that do not share a vertex (a long thin occluder's
//! umbra closes along a ridge between its long sides). The depth rule keeps, per texel, the
//! *first* umbra surface behind the nearest occluder surface, which is the exit of the umbra
//! volume whether or not the quads beyond it were trimmed; trimming saves fill.
//!
//! At a concave corner (a reflex vertex `v` of the silhouette seen from the light) there is
//! nothing to trim: the two umbra quads, extruded from `v` away from different `p_u`, diverge,
//! and the umbra between them is bounded by the cone of lines through `v` and the rim arc
//! between the two `p_u` (worked out for an L-shaped plate under the disc: below the corner the
//! umbra reaches the arc, beyond both quads). Not built either: the paper does not describe that
//! surface, and along a ray from `c` through that gap the umbra is *entered* behind the
//! occluder, not left, which eq. 3's umbra branch (0 up to the volume, rising after) cannot
//! express; such corners are concave occluders, the first case §4 lists as breaking
//! assumption 1.

pub mod cpu;
mod volumes;
pub mod wgpu;

use glam::Vec3;

use super::shadow_map::{map_bytes, Bias};
use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, MethodLimit, WgpuEntry, WorkEstimate,
};
use crate::algorithms::work;
use crate::error::InputError;
use crate::frame::RunParams;
use crate::record::phases;
use crate::scene::Light;
use crate::scene::LightKind;

phases! {
    /// The phases of a `dbuffer` run (003): the silhouette, the umbra and penumbra volumes built
    /// on it (§3), the D-buffer they are rasterized into, and the eye lookup (§4). On wgpu the
    /// first two run on the host within `dbuffer`.
    pub enum Phase {
        Silhouettes => "silhouettes",
        Volumes => "volumes",
        Dbuffer => "dbuffer",
        EyeLookup => "eye_lookup",
    }
}

pub const ID: &str = "dbuffer";

/// How the D-buffer keeps one value per texel when several volume surfaces cover it (§4, first
/// case). The paper keeps "the geometry with the greatest distance from the light source" with a
/// depth test, which presumes umbra quads trimmed to the volume they bound; quads not trimmed
/// (see the module doc) reach past the umbra's end, and the farthest of them is not a
/// boundary. We keep, by a
/// depth test (less) on the volume draws:
/// * umbra volume: the nearest umbra surface at or behind the scene surface seen from `c`
///   (fragments in front of it are discarded): along a ray that passes an occluder, that is
///   where the ray leaves the umbra volume of the occluder;
/// * penumbra volume: the nearest penumbra surface: along a ray that passes beside the occluders
///   it is where the ray enters the penumbra volume.
///
/// For one convex occluder both are the exact boundaries; for concave or overlapping occluders
/// (assumption 1 of §2.3 broken) the nearest occluder's volumes win.
pub const DEPTH_RULE: &str = "umbra: nearest behind the scene surface; penumbra: nearest";

/// The visibility function of `t` (eq. 4, or §6.2's alternative for small occluders).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Falloff {
    /// `V(t) = 3t² − 2t³` (eq. 4).
    #[default]
    Smoothstep,
    /// `V(t) = √t` (§6.2: small occluders cast too dark a shadow with eq. 4).
    Sqrt,
}

/// Where phases `silhouettes` and `volumes` run (§5, §6.1: the paper generates the volumes on
/// the CPU and renders on the graphics card, and finds scenes of complex occluders
/// "CPU-limited").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VolumeBuild {
    /// On every core, as the other phases (cpu-model: the machine's cores; cpu-native and the
    /// host phases of wgpu: the host's threads).
    #[default]
    Parallel,
    /// On one core, as the paper's single CPU: on cpu-model one core of the model's kind beside
    /// the machine (its own caches; the machine's cores only rasterize and look up); on
    /// cpu-native and on wgpu's host phases one host thread. The phases' results, and so the
    /// image and every counter but the cache ones and the times, are those of `parallel`.
    SingleCore,
}

impl VolumeBuild {
    /// In words, for the run's `execution` record.
    pub fn describe(self) -> &'static str {
        match self {
            VolumeBuild::Parallel => "silhouettes and volumes on every core",
            VolumeBuild::SingleCore => {
                "silhouettes and volumes on one core (cpu-model: one modelled core beside the \
                 machine; cpu-native and wgpu: one host thread)"
            }
        }
    }
}

/// Options of `dbuffer` (scenario `options.dbuffer`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DbufferOptions {
    pub falloff: Falloff,
    /// Triangles closing the penumbra volume between two penumbra quads that meet at a vertex
    /// (§2.1: "extrude more triangles using interpolation between p_p").
    pub closing_segments: u32,
    /// Bias of the test "x lies behind the scene surface seen from c" (the shadow-map test).
    pub bias: Bias,
    /// Where the volumes are built ([`VolumeBuild`]).
    pub volume_build: VolumeBuild,
}

impl Default for DbufferOptions {
    fn default() -> Self {
        DbufferOptions {
            falloff: Falloff::default(),
            closing_segments: 4,
            bias: Bias::default(),
            volume_build: VolumeBuild::default(),
        }
    }
}

impl AlgorithmOptions for DbufferOptions {
    fn validate(&self) -> Result<(), InputError> {
        let field = format!("$.options.{ID}.closing_segments");
        InputError::check_range(field, self.closing_segments, 1..=64)?;
        self.bias.validate(ID)
    }
}

/// The D-buffer's channels: the scene's depth (`|cx_o|`), the umbra volume's depth and edge
/// depth (`|cx_uv|`, `|cx_s|`), the penumbra volume's depth and edge depth (`|cx_pv|`, `|cx_s|`),
/// 4 bytes each per texel.
pub const DBUFFER_CHANNELS: u64 = 5;

/// Bytes of the D-buffer at the run's map resolution.
pub fn dbuffer_bytes(p: &RunParams) -> u64 {
    DBUFFER_CHANNELS * map_bytes(p)
}

/// Bytes of volume geometry per occluder triangle, as an upper estimate: an occluder has about
/// 1.5 edges per triangle, each can carry an umbra and a penumbra quad (4 vertices of 16 bytes
/// and 2 index triples each) and a closing fan of up to 4 triangles.
const VOLUME_BYTES_PER_TRIANGLE: u64 = 3 * (2 * (4 * 16 + 2 * 12) + 4 * (2 * 16 + 12)) / 2;

/// The algorithm's own buffers: the D-buffer, the volume geometry (estimated from the triangle
/// count), and per eye pixel the copies of the gbuffer and the visibility.
pub fn memory_estimate(p: &RunParams) -> u64 {
    let pixels = u64::from(p.image[0]) * u64::from(p.image[1]);
    dbuffer_bytes(p) + u64::from(p.triangles) * VOLUME_BYTES_PER_TRIANGLE + pixels * (2 * 16 + 8)
}

/// The disc light: centre `c`, unit normal `n_c` (towards the scene), radius `r`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disc {
    pub c: Vec3,
    pub n: Vec3,
    pub r: f32,
}

impl Disc {
    /// The disc of a light. The harness hands this algorithm disc lights; called directly with
    /// another kind, a sphere becomes the disc through its centre facing `toward` (the scene),
    /// a rectangle the disc of its half-width in its plane, facing `toward`.
    pub fn of(light: &Light, toward: Vec3) -> Disc {
        let c = light.center();
        let facing = (toward - c).normalize_or(Vec3::NEG_Y);
        let n = match *light {
            Light::Disc { normal, .. } => normal.normalize_or(facing),
            Light::Rect { half_u, half_v, .. } => {
                let n = half_u.cross(half_v).normalize_or(facing);
                if n.dot(facing) < 0.0 {
                    -n
                } else {
                    n
                }
            }
            Light::Sphere { .. } => facing,
        };
        Disc {
            c,
            n,
            r: light.size(),
        }
    }

    /// Depth of `p` below the light plane (along `n_c`).
    pub fn depth(&self, p: Vec3) -> f32 {
        (p - self.c).dot(self.n)
    }
}

/// Eq. 1a and 1b: `p_near` and `p_far` for a face of unit normal `n`: the disc points farthest in
/// front of and farthest behind the face's plane. If `p_near` is behind the plane, the whole disc
/// is (none-frontfacing); if `p_far` is in front, the whole disc is (all-frontfacing).
///
/// The paper writes `p_near = c + r((n × n_c) × n_c)`. `(n × n_c) × n_c = −n⊥`, the part of `n`
/// in the disc's plane, negated, so as printed `p_near` is the disc point farthest *behind* the
/// plane and the text's tests hold for normals pointing into the mesh; with outward normals the
/// signs swap. The direction is also normalized: the printed form has length `r·|n⊥|`, on the
/// rim only when the face is perpendicular to the disc.
pub fn disc_extremes(n: Vec3, disc: &Disc) -> (Vec3, Vec3) {
    let w = n.cross(disc.n).cross(disc.n);
    let len = w.length();
    if len <= 1e-12 {
        return (disc.c, disc.c);
    }
    let toward_front = -w / len;
    (
        disc.c + disc.r * toward_front,
        disc.c - disc.r * toward_front,
    )
}

/// §2.1: how a face relates to the whole light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Facing {
    /// Front facing to every point of the disc.
    All,
    /// Front facing to no point of the disc.
    None,
    /// Front facing to part of the disc: between the two silhouettes (§3.3).
    Silhouette,
}

/// Classifies the face of unit normal `n` through point `q` (eq. 1a, 1b). A degenerate face
/// (`n` zero) faces nothing.
pub fn classify(n: Vec3, q: Vec3, disc: &Disc) -> Facing {
    if n == Vec3::ZERO {
        return Facing::None;
    }
    let (near, far) = disc_extremes(n, disc);
    if n.dot(near - q) <= 0.0 {
        Facing::None
    } else if n.dot(far - q) > 0.0 {
        Facing::All
    } else {
        Facing::Silhouette
    }
}

/// The fraction of the disc in front of the receiver's own plane (through `q`, unit normal `n`):
/// the receiver's plane divides the light by one straight line, the case of assumption 1
/// (§2.3), and the area of the circular segment in front is
/// `(acos d − d·√(1 − d²)) / π` with `d` the line's offset from the centre in radii. The eye
/// lookup multiplies the cast-shadow visibility by it; for a surface facing away from the
/// centre, where the D-buffer's distances are those of the surface itself, it is the
/// visibility.
pub fn front_fraction(n: Vec3, q: Vec3, disc: &Disc) -> f32 {
    let h = n.dot(disc.c - q);
    let spread = (n - disc.n * n.dot(disc.n)).length() * disc.r;
    if spread <= 1e-9 {
        return if h > 0.0 { 1.0 } else { 0.0 };
    }
    let d = (-h / spread).clamp(-1.0, 1.0);
    ((d.acos() - d * (1.0 - d * d).sqrt()) / std::f32::consts::PI).clamp(0.0, 1.0)
}

/// §3.3: a silhouette face with the light centre behind its plane (the kind of Figure 6) is
/// drawn as part of the umbra volume.
pub fn centre_behind(n: Vec3, q: Vec3, disc: &Disc) -> bool {
    n.dot(disc.c - q) < 0.0
}

/// §2.1, Figure 3b: the two disc points whose planes through the edge `v1v2` are tangent to the
/// disc. If the edge's line meets the light plane, at
/// `a = (c − v1)·n_c / ((v2 − v1)·n_c) · (v2 − v1) + v1`, they are the points where the tangents
/// from `a` touch the circle; if the edge is parallel to the light plane (the special case the
/// paper leaves to [17]) they are the ends of the disc's diameter perpendicular to the edge, the
/// limit of the tangent points as `a` goes to infinity. `None` when `a` lies inside the circle
/// (no plane through the edge is tangent; §2.1: it does not happen for a silhouette edge of a
/// closed mesh) or the edge is degenerate.
pub fn tangent_points(v1: Vec3, v2: Vec3, disc: &Disc) -> Option<[Vec3; 2]> {
    let e = v2 - v1;
    let len = e.length();
    if len <= 0.0 || !len.is_finite() {
        return None;
    }
    let along = e.dot(disc.n);
    if along.abs() <= 1e-6 * len {
        let m = disc.n.cross(e / len).normalize_or_zero();
        return (m != Vec3::ZERO).then(|| [disc.c + disc.r * m, disc.c - disc.r * m]);
    }
    let a = (disc.c - v1).dot(disc.n) / along * e + v1;
    let w = a - disc.c;
    let d2 = w.length_squared();
    let r2 = disc.r * disc.r;
    if d2 <= r2 {
        return None;
    }
    let perp = disc.n.cross(w);
    let base = disc.c + w * (r2 / d2);
    let off = perp * (disc.r * (d2 - r2).sqrt() / d2);
    Some([base + off, base - off])
}

/// `p_u` and `p_p` of the silhouette edge `v1v2` whose adjacent faces' third vertices are
/// `q`: of the two tangent planes through the edge, the umbra plane has the light and the
/// occluder on the same side (it supports both), the penumbra plane separates them. The
/// tangent point whose plane leaves the faces most on the light centre's side is `p_u`.
pub fn extrusion_points(v1: Vec3, v2: Vec3, q: [Vec3; 2], disc: &Disc) -> Option<(Vec3, Vec3)> {
    let [t0, t1] = tangent_points(v1, v2, disc)?;
    let score = |t: Vec3| {
        let m = (v2 - v1).cross(t - v1);
        let side = m.dot(disc.c - v1).signum();
        q.iter()
            .map(|&p| m.dot(p - v1) * side)
            .fold(f32::INFINITY, f32::min)
    };
    Some(if score(t0) >= score(t1) {
        (t0, t1)
    } else {
        (t1, t0)
    })
}

/// A vertex `v` extruded away from the disc point `p` by `length` (the volumes are infinite;
/// `length` reaches past the scene).
pub fn extrude(v: Vec3, p: Vec3, length: f32) -> Vec3 {
    v + (v - p).normalize_or_zero() * length
}

/// §2.1: disc points between the extrusion points `from` and `to` of two penumbra quads meeting
/// at a vertex, interpolated by angle along the shorter rim arc; `segments + 1` points from
/// `from` to `to`.
pub fn rim_arc(from: Vec3, to: Vec3, segments: u32, disc: &Disc) -> Vec<Vec3> {
    let a = (from - disc.c).normalize_or_zero();
    let b = (to - disc.c).normalize_or_zero();
    let angle = a.dot(b).clamp(-1.0, 1.0).acos();
    let axis = a.cross(b);
    let axis = if axis.length_squared() > 1e-12 {
        axis.normalize()
    } else {
        disc.n
    };
    (0..=segments)
        .map(|k| {
            let rot = glam::Quat::from_axis_angle(axis, angle * k as f32 / segments as f32);
            disc.c + rot * a * disc.r
        })
        .collect()
}

/// Eq. 2: `|cx_s|`, the distance from `c` along the ray of unit direction `dir` to the depth
/// `z_e` of the silhouette edge below the light plane. The paper writes
/// `dir(c,x_uv)·n / dir(c,e)·n · dist(c,e)`; the distance along `dir` to the plane through `e`
/// parallel to the light is `dist(c,e) · dir(c,e)·n / dir(c,x_uv)·n = z_e / dir·n`, the ratio
/// inverted, which is what the 2D projection of Figure 4 needs.
pub fn edge_distance(z_e: f32, dir: Vec3, n_c: Vec3) -> f32 {
    let cos = dir.dot(n_c);
    if cos > 1e-6 {
        z_e / cos
    } else {
        f32::INFINITY
    }
}

/// Eq. 3, first case: `t` of a point at distance `d` from `c` that lies behind an occluder seen
/// from `c`, on a ray leaving the umbra volume at `u` with the edge at `s`: 0 up to `u` (umbra),
/// then `t = s(d − u) / (2u(d − s))`, rising towards `s/2u` < ½ far behind.
///
/// This is the light fraction of the 2D projection (Figure 4) exactly. The paper prints
/// `2u(u − s)` as the denominator, the same value and slope at `d = u` (its linearization at the
/// umbra boundary), which grows without bound with `d` and divides by zero where the umbra and
/// penumbra volumes meet at the edge (`u = s`, where the exact form gives ½).
pub fn t_umbra(d: f32, u: f32, s: f32) -> f32 {
    if d <= u {
        return 0.0;
    }
    let den = 2.0 * u * (d - s);
    if den > 0.0 && s.is_finite() {
        (s * (d - u) / den).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Eq. 3, second case (by symmetry about `c`, `t = ½`): a point at distance `d` seen from `c`,
/// on a ray entering the penumbra volume at `p` with the edge at `s`: 1 up to `p` (lit), then
/// `t = 1 − s(d − p) / (2p(d − s))`. The denominator as in [`t_umbra`].
pub fn t_penumbra(d: f32, p: f32, s: f32) -> f32 {
    if d <= p {
        return 1.0;
    }
    let den = 2.0 * p * (d - s);
    if den > 0.0 && s.is_finite() {
        (1.0 - s * (d - p) / den).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// Eq. 4 (`3t² − 2t³`) or §6.2 (`√t`).
pub fn visibility(t: f32, falloff: Falloff) -> f32 {
    let t = t.clamp(0.0, 1.0);
    match falloff {
        Falloff::Smoothstep => t * t * (3.0 - 2.0 * t),
        Falloff::Sqrt => t.sqrt(),
    }
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct Dbuffer;

/// D-buffer: umbra and penumbra volumes over the image, then one evaluation per pixel.
pub fn work_estimate(
    scene: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    _: &DbufferOptions,
) -> f64 {
    2.0 * work::pixels(p) + 2.0 * work::outline(scene, p.image[0].max(p.image[1]))
}

impl Algorithm for Dbuffer {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "003 §2-§4 (umbra and penumbra volumes, D-buffer)";
    const SUMMARY: &'static str =
        "umbra/penumbra volumes of the area silhouettes (p_near/p_far) drawn from the \
              light centre into a D-buffer of distances; t by eq. 3, V(t) = 3t^2 - 2t^3";
    const LIGHTS: &'static [LightKind] = &[LightKind::Disc];
    const LIMITS: &'static [MethodLimit] = &[MethodLimit::OneMap];
    type Options = DbufferOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] =
        &[r#"{"falloff": "sqrt", "closing_segments": 1, "volume_build": "single_core"}"#];
    const CPU: CpuEntry<DbufferOptions> = cpu::render;
    const WGPU: Option<WgpuEntry<DbufferOptions>> = Some(wgpu::render);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc() -> Disc {
        Disc {
            c: Vec3::new(0.0, 10.0, 0.0),
            n: Vec3::NEG_Y,
            r: 1.0,
        }
    }

    #[test]
    fn faces_are_classified_against_the_whole_disc() {
        let d = disc();
        // A horizontal face below the light, facing up: all of the disc is in front.
        assert_eq!(classify(Vec3::Y, Vec3::ZERO, &d), Facing::All);
        assert_eq!(classify(Vec3::NEG_Y, Vec3::ZERO, &d), Facing::None);
        // A vertical face through x = 0.5 facing +x: the disc spans x in [-1, 1], partly in
        // front.
        assert_eq!(
            classify(Vec3::X, Vec3::new(0.5, 0.0, 0.0), &d),
            Facing::Silhouette
        );
        assert_eq!(
            classify(Vec3::X, Vec3::new(1.5, 0.0, 0.0), &d),
            Facing::None
        );
        assert_eq!(
            classify(Vec3::X, Vec3::new(-1.5, 0.0, 0.0), &d),
            Facing::All
        );
        // A tilted face: p_near and p_far are on the rim, at the extremes of n · p.
        let n = Vec3::new(1.0, 1.0, 0.0).normalize();
        let (near, far) = disc_extremes(n, &d);
        assert!(((near - d.c).length() - 1.0).abs() < 1e-5);
        assert!(n.dot(near) > n.dot(far));
        for k in 0..32 {
            let a = k as f32 / 32.0 * std::f32::consts::TAU;
            let p = d.c + Vec3::new(a.cos(), 0.0, a.sin());
            assert!(n.dot(p) <= n.dot(near) + 1e-5 && n.dot(p) >= n.dot(far) - 1e-5);
        }
    }

    #[test]
    fn extrusion_points_give_planes_tangent_to_the_disc() {
        let d = disc();
        // An edge along z at x = 2, y = 5, slanted so its line meets the light plane; the
        // occluder lies towards -x.
        let (v1, v2) = (Vec3::new(2.0, 5.0, -1.0), Vec3::new(2.0, 6.0, 1.0));
        let q = [Vec3::new(0.0, 5.5, 0.0), Vec3::new(1.5, 4.0, 0.0)];
        let (pu, pp) = extrusion_points(v1, v2, q, &d).unwrap();
        for t in [pu, pp] {
            assert!(((t - d.c).length() - 1.0).abs() < 1e-4, "on the rim");
            assert!(d.depth(t).abs() < 1e-5, "in the light plane");
            // Tangent: every rim point is on one side of the plane through the edge and t.
            let m = (v2 - v1).cross(t - v1).normalize();
            let s: Vec<f32> = (0..64)
                .map(|k| {
                    let a = k as f32 / 64.0 * std::f32::consts::TAU;
                    m.dot(d.c + Vec3::new(a.cos(), 0.0, a.sin()) - v1)
                })
                .collect();
            let (lo, hi) = s
                .iter()
                .fold((f32::MAX, f32::MIN), |(l, h), &x| (l.min(x), h.max(x)));
            assert!(lo > -1e-3 || hi < 1e-3, "{lo} {hi}");
        }
        // The umbra plane has the occluder on the centre's side; the penumbra plane does not.
        let side = |t: Vec3, p: Vec3| {
            let m = (v2 - v1).cross(t - v1);
            m.dot(p - v1) * m.dot(d.c - v1)
        };
        assert!(side(pu, q[0]) > 0.0 && side(pp, q[0]) < 0.0);
        // The umbra quad turns in under the occluder, the penumbra quad out.
        assert!(extrude(v1, pu, 10.0).x < extrude(v1, pp, 10.0).x);
        // An edge parallel to the light: the diameter perpendicular to it.
        let [a, b] =
            tangent_points(Vec3::new(2.0, 5.0, -1.0), Vec3::new(2.0, 5.0, 1.0), &d).unwrap();
        assert!((a - Vec3::new(-1.0, 10.0, 0.0)).length() < 1e-5 || (a.x - 1.0).abs() < 1e-5);
        assert!((a + b - 2.0 * d.c).length() < 1e-5);
        // An edge whose line crosses the disc has no tangent plane.
        assert!(tangent_points(Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.1, 6.0, 0.0), &d).is_none());
    }

    /// The 2D projection (Figure 4) by brute force: the fraction of the light segment
    /// [-r, r] at depth 0 that a point at (u_x, z_x) sees past an occluder edge at (u_e, z_e)
    /// with the occluder towards -u.
    fn fraction_2d(r: f32, (u_e, z_e): (f32, f32), (u_x, z_x): (f32, f32)) -> f32 {
        let n = 20_000;
        let seen = (0..n)
            .filter(|&i| {
                let l = -r + 2.0 * r * (i as f32 + 0.5) / n as f32;
                l + (u_x - l) * z_e / z_x > u_e
            })
            .count();
        seen as f32 / n as f32
    }

    #[test]
    fn eq3_is_the_light_fraction_of_the_2d_projection() {
        let (r, e) = (1.0f32, (0.5f32, 4.0f32));
        // Rays from c (at the origin) by lateral slope k; points along them by depth.
        for k in [0.05f32, 0.1, 0.118, 0.13, 0.2] {
            let delta = k * e.1 - e.0;
            // Depths of the umbra and penumbra boundary lines through the edge on this ray.
            let z_u = r * e.1 / (r + delta);
            let z_p = r * e.1 / (r - delta);
            for z in [4.5f32, 6.0, 9.0, 15.0] {
                let cos = 1.0 / (1.0 + k * k).sqrt();
                let dist = |depth: f32| depth / cos;
                let want = fraction_2d(r, e, (k * z, z));
                let got = if delta < 0.0 {
                    t_umbra(dist(z), dist(z_u), dist(e.1))
                } else {
                    t_penumbra(dist(z), dist(z_p), dist(e.1))
                };
                assert!((got - want).abs() < 2e-3, "k {k} z {z}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn falloffs_run_from_zero_to_one() {
        for f in [Falloff::Smoothstep, Falloff::Sqrt] {
            assert_eq!(visibility(0.0, f), 0.0);
            assert_eq!(visibility(1.0, f), 1.0);
            assert!((visibility(0.25, f) - 0.25).abs() > 0.05);
        }
        assert!((visibility(0.5, Falloff::Smoothstep) - 0.5).abs() < 1e-6);
        assert!((visibility(0.25, Falloff::Sqrt) - 0.5).abs() < 1e-6);
        // The receiver's plane through the centre halves the disc; beside it, all or nothing.
        let d = disc();
        assert!((front_fraction(Vec3::X, d.c, &d) - 0.5).abs() < 1e-5);
        assert_eq!(front_fraction(Vec3::X, d.c - Vec3::X * 2.0, &d), 1.0);
        assert_eq!(front_fraction(Vec3::Y, Vec3::ZERO, &d), 1.0);
        assert_eq!(front_fraction(Vec3::NEG_Y, Vec3::ZERO, &d), 0.0);
        // Half a radius: the segment beyond d = 0.5 is 19.55% of the disc.
        let f = front_fraction(Vec3::X, d.c + Vec3::X * 0.5, &d);
        assert!((f - 0.19550).abs() < 1e-4, "{f}");
        // Eq. 2 on the axis: the edge's depth itself.
        assert_eq!(edge_distance(3.0, Vec3::NEG_Y, Vec3::NEG_Y), 3.0);
    }

    #[test]
    fn options_are_validated_with_their_path() {
        let mut o = std::collections::BTreeMap::new();
        o.insert(ID.to_string(), serde_json::json!({"falloff": "linear"}));
        let e = Dbuffer::options(&o).unwrap_err().to_string();
        assert!(e.contains("$.options.dbuffer.falloff"), "{e}");
        o.insert(ID.to_string(), serde_json::json!({"closing_segments": 0}));
        let e = Dbuffer::options(&o).unwrap_err().to_string();
        assert!(e.contains("closing_segments") && e.contains("got 0"), "{e}");
        o.insert(ID.to_string(), serde_json::json!({"falloff": "sqrt"}));
        assert_eq!(Dbuffer::options(&o).unwrap().falloff, Falloff::Sqrt);
        o.insert(ID.to_string(), serde_json::json!({"volume_build": "gpu"}));
        let e = Dbuffer::options(&o).unwrap_err().to_string();
        assert!(
            e.contains("$.options.dbuffer.volume_build") && e.contains("gpu"),
            "{e}"
        );
        o.insert(
            ID.to_string(),
            serde_json::json!({"volume_build": "single_core"}),
        );
        assert_eq!(
            Dbuffer::options(&o).unwrap().volume_build,
            VolumeBuild::SingleCore
        );
        assert_eq!(
            Dbuffer::options(&std::collections::BTreeMap::new())
                .unwrap()
                .volume_build,
            VolumeBuild::Parallel
        );
    }
}
