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
//! This file holds the math, once; [`cpu`] runs it on the CPU executions.

pub mod cpu;

use std::collections::BTreeMap;

use glam::{Vec2, Vec3};

use super::shadow_map::{map_bytes, parse_options, Bias, LightView};
use crate::error::InputError;
use crate::frame::RunParams;

pub const ID: &str = "penumbra_map";

/// A sheet is split into strips along its edge when its far side leaves the plane of its near
/// edge and first far corner by more than this fraction of the sheet's length (§3: "we subdivide
/// extremely non-planar quads to avoid artifacts").
pub const SHEET_PLANARITY: f32 = 0.02;

/// Options of `penumbra_map` (scenario `options.penumbra_map`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PenumbraMapOptions {
    /// Triangles of each cone (§3: "we subdivide each cone into a number of triangles").
    #[serde(default = "default_cone_segments")]
    pub cone_segments: u32,
    /// Most strips a strongly non-planar sheet is split into.
    #[serde(default = "default_max_sheet_strips")]
    pub max_sheet_strips: u32,
    /// Bias of the umbra test in the final lookup (§5: "we reduce them by adding a larger bias").
    #[serde(default)]
    pub bias: Bias,
}

fn default_cone_segments() -> u32 {
    16
}

fn default_max_sheet_strips() -> u32 {
    8
}

impl Default for PenumbraMapOptions {
    fn default() -> Self {
        PenumbraMapOptions {
            cone_segments: default_cone_segments(),
            max_sheet_strips: default_max_sheet_strips(),
            bias: Bias::default(),
        }
    }
}

impl PenumbraMapOptions {
    pub fn validate(&self) -> Result<(), InputError> {
        let field = |name: &str| format!("$.options.{ID}.{name}");
        if !(3..=256).contains(&self.cone_segments) {
            return Err(InputError::new(
                field("cone_segments"),
                format!("must be in 3..=256, got {}", self.cone_segments),
            ));
        }
        if !(1..=64).contains(&self.max_sheet_strips) {
            return Err(InputError::new(
                field("max_sheet_strips"),
                format!("must be in 1..=64, got {}", self.max_sheet_strips),
            ));
        }
        for (name, v) in [
            ("bias.constant", self.bias.constant),
            ("bias.slope", self.bias.slope),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(InputError::new(
                    field(name),
                    format!("must be a finite number >= 0, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

pub fn options(
    options: &BTreeMap<String, serde_json::Value>,
) -> Result<PenumbraMapOptions, InputError> {
    let o: PenumbraMapOptions = parse_options(ID, options)?;
    o.validate()?;
    Ok(o)
}

pub fn check_options(o: &BTreeMap<String, serde_json::Value>) -> Result<(), InputError> {
    options(o).map(|_| ())
}

/// The algorithm's own buffers: the shadow map and the penumbra map, one f32 each per texel.
pub fn memory_estimate(p: &RunParams) -> u64 {
    2 * map_bytes(p)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Bounds, Light};

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
        let b = Bounds {
            min: Vec3::new(-3.0, 0.0, -3.0),
            max: Vec3::new(3.0, 2.0, 3.0),
        };
        let view = LightView::new(&light, b, 256);
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
