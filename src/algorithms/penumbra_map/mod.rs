//! Penumbra maps (paper 000, Wyman and Hansen 2003): a shadow map from the light centre gives
//! the umbra; a second map of the same view, the *penumbra map*, holds the light intensity on the
//! surfaces the shadow map sees. It is drawn from the silhouette of the occluders seen from the
//! light centre (§3): a cone per silhouette vertex (tip at the vertex, base on the far plane,
//! Figure 4) and a sheet per silhouette edge joining the cones of its two vertices. A fragment
//! on a cone or sheet finds the surface behind it in the shadow map and shades it by eq. 1 and
//! the Bernstein falloff `3t² − 2t³`; overlapping contributions keep the darkest (§4).
//!
//! Only the *outer* penumbra is computed: the hard shadow stands for the umbra, so the umbra is
//! overestimated, more so as the light grows or the occluder leaves the receiver (§4.1).
//!
//! The geometry is built in light-view space (looking down −z from the light centre, depth
//! `−z`), so that the far plane is `z = −far` and a cone's base is a circle in it.
//! This file holds the math and the geometry, once: the silhouette from the light centre
//! ([`silhouettes`]), the cones and sheets built on it ([`PenumbraGeometry`]), and the
//! occluders shadows are generated from ([`shadow_geometry`], optionally simplified as in §5).
//! [`cpu`] runs it on the CPU executions, [`wgpu`] as GPU passes (its WGSL mirrors
//! [`intensity`] and the lookup).

pub mod cpu;
pub mod wgpu;

use std::borrow::Cow;

use glam::{Vec2, Vec3};

use super::shadow_map::{self, map_bytes, Bias, LightView};
use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, MethodLimit, WgpuEntry, WgpuParity,
    WorkEstimate,
};
use crate::algorithms::work;
use crate::error::InputError;
use crate::frame::{Frame, RunParams};
use crate::record::phases;
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};
use crate::scene::simplify::simplify;
use crate::scene::LightKind;
use crate::scene::Mesh;

phases! {
    /// The phases of a `penumbra_map` run (000 §3): the shadow map, the silhouette seen from the
    /// light, the penumbra map of cones and sheets drawn along it, and the eye lookup.
    pub enum Phase {
        ShadowMap => "shadow_map",
        Silhouettes => "silhouettes",
        PenumbraMap => "penumbra_map",
        EyeLookup => "eye_lookup",
    }
}

pub const ID: &str = "penumbra_map";

/// A sheet is split into strips along its edge when its far side leaves the plane of its near
/// edge and first far corner by more than this fraction of the sheet's length (§3: "we subdivide
/// extremely non-planar quads to avoid artifacts").
pub const SHEET_PLANARITY: f32 = 0.02;

/// Options of `penumbra_map` (scenario `options.penumbra_map`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PenumbraMapOptions {
    /// Triangles of each cone (§3: "we subdivide each cone into a number of triangles").
    pub cone_segments: u32,
    /// Most strips a strongly non-planar sheet is split into.
    pub max_sheet_strips: u32,
    /// Bias of the umbra test in the final lookup (§5: "we reduce them by adding a larger bias").
    pub bias: Bias,
    /// Target triangle count of the occluders the shadows are generated from (§5: "we used
    /// 10,000 polygons to generate shadows for the bunny"): each occluder object is simplified
    /// to its share of this count for the shadow map, the silhouettes and the penumbra map;
    /// the eye still sees the full meshes. Absent: the full meshes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shadow_mesh_triangles: Option<u32>,
}

impl Default for PenumbraMapOptions {
    fn default() -> Self {
        PenumbraMapOptions {
            cone_segments: 16,
            max_sheet_strips: 8,
            bias: Bias::default(),
            shadow_mesh_triangles: None,
        }
    }
}

impl AlgorithmOptions for PenumbraMapOptions {
    fn validate(&self) -> Result<(), InputError> {
        let field = |name: &str| format!("$.options.{ID}.{name}");
        InputError::check_range(field("cone_segments"), self.cone_segments, 3..=256)?;
        InputError::check_range(field("max_sheet_strips"), self.max_sheet_strips, 1..=64)?;
        if self.shadow_mesh_triangles == Some(0) {
            return Err(InputError::new(
                field("shadow_mesh_triangles"),
                "must be a positive integer (a target triangle count), got 0",
            ));
        }
        self.bias.validate(ID)
    }
}

/// Bytes per scene triangle of the shadow geometry's copy and the occluders' edge adjacency
/// the silhouette is found in: the peak resident memory of `render --no-reference` at 2
/// million triangles is 115 bytes per triangle above the other shadow-map algorithms'.
const GEOMETRY_BYTES_PER_TRIANGLE: u64 = 128;

/// The algorithm's own buffers: the shadow-map family's (the shadow map, the gbuffer copies
/// and the visibility buffers), the penumbra map, one f32 per texel, and the geometry
/// ([`GEOMETRY_BYTES_PER_TRIANGLE`]). The cones and sheets are not counted: their size is known
/// only once the silhouette is.
pub fn memory_estimate(p: &RunParams) -> u64 {
    let geometry = u64::from(p.triangles) * GEOMETRY_BYTES_PER_TRIANGLE;
    shadow_map::memory_estimate(p) + map_bytes(p) + geometry
}

/// §3, Figure 4: the radius of the cone of a silhouette vertex at depth `z_v` where it meets the
/// far plane, by similar triangles through the rim of a light of radius `light_radius`:
/// `C_r = (Z_far − Z_v) · L_r / Z_v`.
pub fn cone_radius(z_far: f32, z_v: f32, light_radius: f32) -> f32 {
    (z_far - z_v) * light_radius / z_v
}

/// §3, eq. 1 and the Bernstein falloff: the light reaching the shadow-map surface at depth `z_p`
/// behind a cone or sheet fragment at depth `z_f` of a silhouette at depth `z_v` (all linear,
/// world-space depths): `I = (Z_F − Z_v)/(Z_P − Z_v)`, then `3I² − 2I³`. 0 at the silhouette,
/// 1 where the cone or sheet meets the surface.
pub fn intensity(z_f: f32, z_p: f32, z_v: f32) -> f32 {
    let den = z_p - z_v;
    let t = if den > 0.0 {
        ((z_f - z_v) / den).clamp(0.0, 1.0)
    } else {
        0.0
    };
    t * t * (3.0 - 2.0 * t)
}

/// Depth from the light of a light-view-space point.
pub fn depth(v: Vec3) -> f32 {
    -v.z
}

/// The cone of a silhouette point `v` (light-view space): its axis is the ray from the light
/// centre through `v`, its base the circle where that ray meets the far plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    pub tip: Vec3,
    /// `Z_v`.
    pub z_v: f32,
    /// Centre of the base, on the far plane.
    pub axis: Vec3,
    /// `C_r`.
    pub radius: f32,
}

impl Cone {
    pub fn new(view: &LightView, light_radius: f32, v: Vec3) -> Cone {
        let z_v = depth(v);
        Cone {
            tip: v,
            z_v,
            axis: v * (view.far / z_v),
            radius: cone_radius(view.far, z_v, light_radius),
        }
    }

    /// Point of the base circle in direction `dir` (a unit vector of the far plane's x, y).
    pub fn rim(&self, dir: Vec2) -> Vec3 {
        self.axis + (dir * self.radius).extend(0.0)
    }

    /// Base point `k` of the cone's `segments` triangles.
    pub fn base_point(&self, k: u32, segments: u32) -> Vec3 {
        let a = std::f32::consts::TAU * k as f32 / segments as f32;
        self.rim(Vec2::new(a.cos(), a.sin()))
    }
}

/// The part of the light-view-space segment `a→b` at or beyond `view`'s near plane (depth
/// ≥ `view.near`), its ends in the same order; `None` when all of it is nearer.
pub fn clip_to_near(view: &LightView, a: Vec3, b: Vec3) -> Option<(Vec3, Vec3)> {
    let (da, db) = (depth(a), depth(b));
    match (da >= view.near, db >= view.near) {
        (true, true) => Some((a, b)),
        (false, false) => None,
        (a_in, _) => {
            let t = (view.near - da) / (db - da);
            let cut = a.lerp(b, t);
            // On the plane exactly: the depth of the cut rounds to either side of it.
            let cut = Vec3::new(cut.x, cut.y, -view.near);
            Some(if a_in { (a, cut) } else { (cut, b) })
        }
    }
}

/// The direction, in the far plane, away from the occluder across the silhouette edge `a→b`
/// (light-view space, oriented as [`crate::scene::adjacency::SilhouetteEdge`]: the face that
/// faces the light winds counter-clockwise seen from the light, so its inside is on the left
/// of `a→b` and the outer penumbra on the right). `None` for an edge seen end-on.
pub fn outward(view: &LightView, a: Vec3, b: Vec3) -> Option<Vec2> {
    let project = |v: Vec3| v.truncate() * (view.far / depth(v));
    let d = project(b) - project(a);
    let n = Vec2::new(d.y, -d.x);
    (n.length_squared() > 0.0 && n.is_finite()).then(|| n.normalize())
}

/// The sheet of silhouette edge `a→b`: at parameter `s` along the edge, the near point on the
/// edge and the far point on the rim of that point's cone, across the edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sheet {
    pub a: Vec3,
    pub b: Vec3,
    pub out: Vec2,
}

impl Sheet {
    pub fn new(view: &LightView, a: Vec3, b: Vec3) -> Option<Sheet> {
        outward(view, a, b).map(|out| Sheet { a, b, out })
    }

    /// (near point, far point, `Z_v`) at parameter `s` in [0, 1].
    pub fn at(&self, view: &LightView, light_radius: f32, s: f32) -> (Vec3, Vec3, f32) {
        let cone = Cone::new(view, light_radius, self.a.lerp(self.b, s));
        (cone.tip, cone.rim(self.out), cone.z_v)
    }

    /// Strips the sheet is drawn with: 1 when the quad of its two ends is nearly planar, more as
    /// its far side twists out of plane ([`SHEET_PLANARITY`]), at most `max`.
    pub fn strips(&self, view: &LightView, light_radius: f32, max: u32) -> u32 {
        let (a, fa, _) = self.at(view, light_radius, 0.0);
        let (b, fb, _) = self.at(view, light_radius, 1.0);
        let n = (b - a).cross(fa - a).normalize_or_zero();
        let len = (fa - a).length().max((fb - b).length());
        if n == Vec3::ZERO || len <= 0.0 {
            return 1;
        }
        let off = (fb - a).dot(n).abs() / len;
        ((off / SHEET_PLANARITY).ceil() as u32).clamp(1, max)
    }
}

/// What the shadows are generated from: the triangles rasterized into the shadow map (every
/// triangle of the scene, receivers too: eq. 1 takes the receiver's depth `Z_P` from the map,
/// so a receiver-only object casts a hard shadow too, [`MethodLimit::NonOccludersCast`]) and the
/// occluders whose silhouette makes the penumbra map.
pub struct ShadowGeometry<'f> {
    pub shadow_map: Cow<'f, Mesh>,
    pub occluders: Mesh,
}

/// The shadow geometry of `frame`: its own meshes, or with `shadow_mesh_triangles` each
/// occluder object simplified to its share of the target (in proportion to its triangles), as
/// the paper draws shadows from simplified models (§5). Receiver-only objects are kept whole.
/// Simplification is preprocessing (the paper's models were simplified beforehand): no phase
/// counts it.
pub fn shadow_geometry<'f>(frame: &'f Frame, o: &PenumbraMapOptions) -> ShadowGeometry<'f> {
    let Some(target) = o.shadow_mesh_triangles else {
        return ShadowGeometry {
            shadow_map: Cow::Borrowed(&frame.flat.mesh),
            occluders: frame.scene.occluders(),
        };
    };
    let objects = &frame.scene.objects;
    let total: usize = objects
        .iter()
        .filter(|o| o.role.occluder)
        .map(|o| o.mesh.triangles.len())
        .sum();
    let (mut shadow_map, mut occluders) = (Mesh::default(), Mesh::default());
    for obj in objects {
        if obj.role.occluder {
            let share = f64::from(target) * obj.mesh.triangles.len() as f64 / total as f64;
            let s = simplify(&obj.mesh, (share.round() as u32).max(1));
            shadow_map.append(&s);
            occluders.append(&s);
        } else {
            shadow_map.append(&obj.mesh);
        }
    }
    ShadowGeometry {
        shadow_map: Cow::Owned(shadow_map),
        occluders,
    }
}

/// The silhouette from the light centre, in light-view space, with what the cones and sheets
/// of the penumbra map are built from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Silhouettes {
    pub edges: Vec<SilhouetteEdge>,
    /// Silhouette vertices (welded index, light-view position) in first-seen order.
    pub vertices: Vec<(u32, Vec3)>,
    /// Silhouette edges meeting at each of `vertices`.
    pub edges_per_vertex: Vec<u32>,
    /// Sheets of the edges (`None` for an edge seen end-on) and their strip counts.
    pub sheets: Vec<Option<(Sheet, u32)>>,
}

impl Silhouettes {
    /// The counters every execution records in its `silhouettes` phase.
    pub fn counts(&self) -> [(&'static str, f64); 4] {
        [
            ("silhouette.edges", self.edges.len() as f64),
            ("silhouette.vertices", self.vertices.len() as f64),
            (
                "silhouette.vertices_over_two_edges",
                self.vertices_over_two_edges() as f64,
            ),
            (
                "silhouette.max_edges_per_vertex",
                f64::from(self.max_edges_per_vertex()),
            ),
        ]
    }

    /// The vertex step for silhouette edge `e`: its vertices are added when first seen (`slot`
    /// maps welded vertex indices to positions in `vertices`, `u32::MAX` when unseen), their
    /// edge counts grow, and the edge's sheet is set up with its strip count.
    ///
    /// The cones and sheets are built on the part of the edge at or beyond the light view's
    /// near plane ([`clip_to_near`]): a point nearer the light centre than that (or behind it,
    /// as the top of a pillar taller than the light) has no cone on the far plane (eq. 1's
    /// `Z_v` would be zero or negative) and casts nothing the map can hold, as the shadow map
    /// clips its casters there. A vertex so cut is left out; where an edge crosses the plane, its
    /// crossing point gets a cone of its own (listed in `vertices` with the index `u32::MAX`).
    pub fn add(
        &mut self,
        slot: &mut [u32],
        e: &SilhouetteEdge,
        view: &LightView,
        light_radius: f32,
        max_strips: u32,
    ) {
        let to_view = |v: Vec3| view.view.transform_point3(v);
        let (a, b) = (to_view(e.a), to_view(e.b));
        let clipped = clip_to_near(view, a, b);
        if let Some((ca, cb)) = clipped {
            for ((&w, original), pos) in e.v.iter().zip([a, b]).zip([ca, cb]) {
                if pos != original {
                    self.vertices.push((u32::MAX, pos));
                    self.edges_per_vertex.push(1);
                    continue;
                }
                let i = &mut slot[w as usize];
                if *i == u32::MAX {
                    *i = self.vertices.len() as u32;
                    self.vertices.push((w, pos));
                    self.edges_per_vertex.push(0);
                }
                self.edges_per_vertex[*i as usize] += 1;
            }
        }
        let sheet = clipped
            .and_then(|(ca, cb)| Sheet::new(view, ca, cb))
            .map(|sh| (sh, sh.strips(view, light_radius, max_strips)));
        self.sheets.push(sheet);
        self.edges.push(*e);
    }

    /// Vertices with more than two silhouette edges (§2: "vertices with three or four adjacent
    /// silhouette edges are not uncommon ... some pathological vertices can have up to eight").
    pub fn vertices_over_two_edges(&self) -> usize {
        self.edges_per_vertex.iter().filter(|&&n| n > 2).count()
    }

    pub fn max_edges_per_vertex(&self) -> u32 {
        self.edges_per_vertex.iter().copied().max().unwrap_or(0)
    }
}

/// §4: brute-force silhouette extraction from the light centre `light` over every edge of
/// `adj`, in edge order, then the vertex step ([`Silhouettes::add`]). The CPU executions run
/// the same two steps as instrumented tasks, in the same order.
pub fn silhouettes(
    adj: &EdgeAdjacency,
    view: &LightView,
    light: Vec3,
    light_radius: f32,
    max_strips: u32,
) -> Silhouettes {
    let mut slot = vec![u32::MAX; adj.vertices.len()];
    let mut s = Silhouettes::default();
    for e in 0..adj.edges.len() {
        if let Some(edge) = adj.silhouette_edge(e, light) {
            s.add(&mut slot, &edge, view, light_radius, max_strips);
        }
    }
    s
}

/// (vertices, triangles) of a cone of `segments` triangles: the tip and `segments` base points.
pub fn cone_size(segments: u32) -> (u32, u32) {
    (segments + 1, segments)
}

/// (vertices, triangles) of a sheet of `strips` strips: a near and a far point at each of the
/// `strips + 1` stations along the edge, two triangles per strip.
pub fn sheet_size(strips: u32) -> (u32, u32) {
    (2 * (strips + 1), 2 * strips)
}

/// Cones and sheets as triangles in light-view space (the penumbra map is drawn with the light
/// view's projection alone); each vertex carries its `Z_v`, constant on a cone and interpolated
/// along a sheet's edge (§3: "for sheets we use the rasterizer to interpolate between the
/// `Z_vi` values of the two adjacent cones"), and the reciprocal of its depth for
/// perspective-correct interpolation of `Z_v` where the rasterizer does not provide it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PenumbraGeometry {
    pub positions: Vec<Vec3>,
    /// (`Z_v`, 1/depth) per vertex.
    pub attributes: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
}

impl PenumbraGeometry {
    /// All cones (one per silhouette vertex, in order), then all sheets (one per edge): what
    /// both executions draw.
    pub fn build(s: &Silhouettes, view: &LightView, light_radius: f32, segments: u32) -> Self {
        let mut g = PenumbraGeometry::default();
        for &(_, v) in &s.vertices {
            g.cone(view, light_radius, v, segments);
        }
        for (sheet, strips) in s.sheets.iter().flatten() {
            g.sheet(view, light_radius, sheet, *strips);
        }
        g
    }

    fn vertex(&mut self, p: Vec3, z_v: f32) -> u32 {
        self.positions.push(p);
        self.attributes.push(Vec2::new(z_v, 1.0 / depth(p)));
        (self.positions.len() - 1) as u32
    }

    /// §3: a cone with its tip at the silhouette vertex `v` and its base on the far plane, as
    /// `segments` triangles with one vertex at the tip and two on the base.
    pub fn cone(&mut self, view: &LightView, light_radius: f32, v: Vec3, segments: u32) {
        let c = Cone::new(view, light_radius, v);
        let tip = self.vertex(c.tip, c.z_v);
        for k in 0..segments {
            self.vertex(c.base_point(k, segments), c.z_v);
        }
        for k in 0..segments {
            let next = (k + 1) % segments;
            self.triangles.push([tip, tip + 1 + k, tip + 1 + next]);
        }
    }

    /// §3: the sheet of an edge joining its two cones, in `strips` strips along the edge.
    pub fn sheet(&mut self, view: &LightView, light_radius: f32, sheet: &Sheet, strips: u32) {
        let first = self.positions.len() as u32;
        for i in 0..=strips {
            let (near, far, z_v) = sheet.at(view, light_radius, i as f32 / strips as f32);
            self.vertex(near, z_v);
            self.vertex(far, z_v);
        }
        for i in 0..strips {
            let (n0, f0, n1, f1) = (
                first + 2 * i,
                first + 2 * i + 1,
                first + 2 * i + 2,
                first + 2 * i + 3,
            );
            self.triangles.push([n0, n1, f1]);
            self.triangles.push([n0, f1, f0]);
        }
    }
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct PenumbraMap;

/// Penumbra map: the shadow map, then cones and sheets along the silhouette into the map.
pub fn work_estimate(
    scene: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    _: &PenumbraMapOptions,
) -> f64 {
    2.0 * work::texels(p) + work::outline(scene, p.map_resolution) + work::pixels(p)
}

impl Algorithm for PenumbraMap {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "000 §3-§4 (Wyman and Hansen 2003)";
    const SUMMARY: &'static str =
        "shadow map + penumbra map of cones and sheets on the light-centre silhouette";
    const LIGHTS: &'static [LightKind] = &[LightKind::Sphere];
    const LIMITS: &'static [MethodLimit] = &[
        MethodLimit::OuterPenumbraOnly,
        MethodLimit::OneMap,
        MethodLimit::NonOccludersCast,
    ];
    type Options = PenumbraMapOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] = &[
        r#"{"cone_segments": 5, "max_sheet_strips": 1}"#,
        r#"{"shadow_mesh_triangles": 300}"#,
    ];
    /// Fragment counts differ where the light raster as in hard_shadow_map, and the cones' and sheets' fragments (measured: 68 of 5,796 on torus-on-plane).
    const WGPU_PARITY: WgpuParity = WgpuParity::LIGHT_RASTER;
    const CPU: CpuEntry<PenumbraMapOptions> = cpu::render;
    const WGPU: Option<WgpuEntry<PenumbraMapOptions>> = Some(wgpu::render);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Light;

    #[test]
    fn intensity_runs_from_dark_at_the_silhouette_to_lit_at_the_surface() {
        assert_eq!(intensity(4.0, 10.0, 4.0), 0.0);
        assert_eq!(intensity(10.0, 10.0, 4.0), 1.0);
        // Halfway the Bernstein interpolant is symmetric: 0.5.
        assert!((intensity(7.0, 10.0, 4.0) - 0.5).abs() < 1e-6);
        // A quarter of the way: 3/16 − 2/64.
        assert!((intensity(5.5, 10.0, 4.0) - (3.0 / 16.0 - 2.0 / 64.0)).abs() < 1e-6);
        // Degenerate: the surface at the silhouette's depth.
        assert_eq!(intensity(4.0, 4.0, 4.0), 0.0);
    }

    #[test]
    fn cone_radius_is_zero_at_the_far_plane_and_the_light_radius_halfway() {
        assert_eq!(cone_radius(10.0, 10.0, 0.5), 0.0);
        assert!((cone_radius(10.0, 5.0, 0.5) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn sheets_point_away_from_the_occluder() {
        // A square occluder, counter-clockwise seen from a light above it.
        let light = Light::Sphere {
            center: Vec3::new(0.0, 10.0, 0.0),
            radius: 0.5,
        };
        let view = LightView::looking(light.center(), Vec3::NEG_Y, 0.5, 5.0, 11.0, 256);
        let corners = [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)]
            .map(|(x, z)| view.view.transform_point3(Vec3::new(x, 2.0, z)));
        // Counter-clockwise seen from +y is the order that makes the face normal point up.
        let world =
            [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)].map(|(x, z)| Vec3::new(x, 2.0, z));
        let up = (world[1] - world[0]).cross(world[2] - world[0]);
        let order: Vec<usize> = if up.y > 0.0 {
            vec![0, 1, 2, 3]
        } else {
            vec![3, 2, 1, 0]
        };
        let centre = Cone::new(
            &view,
            0.5,
            view.view.transform_point3(Vec3::new(0.0, 2.0, 0.0)),
        );
        for i in 0..4 {
            let (a, b) = (corners[order[i]], corners[order[(i + 1) % 4]]);
            let sheet = Sheet::new(&view, a, b).unwrap();
            let (_, far, _) = sheet.at(&view, 0.5, 0.5);
            let axis = Cone::new(&view, 0.5, a.lerp(b, 0.5)).axis;
            assert!(
                (far - centre.axis).length() > (axis - centre.axis).length(),
                "edge {i}"
            );
            // A flat square's sheets are planar.
            assert_eq!(sheet.strips(&view, 0.5, 8), 1);
        }
    }
}
