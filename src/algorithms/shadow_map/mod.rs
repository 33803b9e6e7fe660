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

use crate::scene::camera::{look_at, perspective};
use crate::scene::polygon::clip_half_plane;
use crate::scene::{Light, Mesh};

/// The texel of the map that holds `uv` (nearest), or `None` outside the map, where nothing
/// was rasterized and the receiver counts as lit.
pub fn texel(view: &LightView, uv: Vec2) -> Option<(u32, u32)> {
    let r = view.resolution as f32;
    let (x, y) = ((uv.x * r).floor(), (uv.y * r).floor());
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

    /// The part of triangle `tri` inside the frustum's side planes between the light and the
    /// far plane (Sutherland–Hodgman in view space, winding kept), empty when none is.
    fn clip_to_frustum(&self, tri: [Vec3; 3]) -> Vec<Vec3> {
        let t = self.tan_half_fov;
        let far = self.far;
        let planes: [&dyn Fn(Vec3) -> f32; 6] = [
            &|v: Vec3| -v.z,
            &|v: Vec3| far + v.z,
            &|v: Vec3| -v.z * t - v.x,
            &|v: Vec3| -v.z * t + v.x,
            &|v: Vec3| -v.z * t - v.y,
            &|v: Vec3| -v.z * t + v.y,
        ];
        let mut poly: Vec<Vec3> = tri.iter().map(|&p| self.view.transform_point3(p)).collect();
        for f in planes {
            poly = clip_half_plane(&poly, f);
            if poly.is_empty() {
                break;
            }
        }
        poly
    }

    /// The smallest depth of the part of triangle `tri` inside the frustum's side planes between
    /// the light and the far plane, or `None` when no part of it is inside: the triangle can
    /// neither shadow a receiver of this view nor appear in its map.
    pub fn caster_depth(&self, tri: [Vec3; 3]) -> Option<f32> {
        self.clip_to_frustum(tri)
            .iter()
            .map(|v| -v.z)
            .reduce(f32::min)
    }

    /// The draw list of the light pass for `mesh`, built on the host as engines build a shadow
    /// map face's: triangles that do not meet the frustum are culled, triangles wholly beyond
    /// the near plane drawn as they are, and the few that reach nearer the light than the near
    /// plane (e.g. a wall through the light's plane, whose near part lies outside the frustum)
    /// drawn as their part inside the frustum (a fan, new vertices appended), so the rasterizer
    /// never clips away a part that lies in the map.
    pub fn casters(&self, mesh: &Mesh) -> Mesh {
        let to_world = self.view.inverse();
        let mut out = Mesh {
            positions: mesh.positions.clone(),
            triangles: Vec::with_capacity(mesh.triangles.len()),
        };
        for (t, &idx) in mesh.triangles.iter().enumerate() {
            let tri = mesh.triangle(t);
            let poly = self.clip_to_frustum(tri);
            if poly.is_empty() {
                continue;
            }
            let nearer = tri
                .iter()
                .any(|&p| -self.view.transform_point3(p).z < self.near);
            if !nearer {
                out.triangles.push(idx);
                continue;
            }
            let base = out.positions.len() as u32;
            out.positions
                .extend(poly.iter().map(|&v| to_world.transform_point3(v)));
            for k in 1..poly.len().saturating_sub(1) as u32 {
                out.triangles.push([base, base + k, base + k + 1]);
            }
        }
        out
    }

    /// Map coordinates of `p`: (u, v) in [0, 1]² with v down, NDC depth in [0, 1], and linear
    /// depth. `None` when `p` is behind the light.
    pub fn project(&self, p: Vec3) -> Option<(Vec2, f32, f32)> {
        let c = self.view_proj * p.extend(1.0);
        if c.w <= 0.0 {
            return None;
        }
        let ndc = c.xyz() / c.w;
        Some((Vec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5), ndc.z, c.w))
    }

    /// Distance along the view axis for an NDC depth (inverse of the projection's depth).
    pub fn linear_depth(&self, ndc: f32) -> f32 {
        self.near * self.far / (self.far - ndc * (self.far - self.near))
    }

    /// World size of one map texel at linear depth `z`.
    pub fn texel_world(&self, z: f32) -> f32 {
        2.0 * z * self.tan_half_fov / self.resolution as f32
    }

    /// A world length `w` at linear depth `z` expressed in map uv units.
    pub fn world_to_uv(&self, w: f32, z: f32) -> f32 {
        w / (2.0 * z * self.tan_half_fov)
    }
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
    /// Eye pixels that see a surface no view holds: the algorithm takes them as lit.
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
        views.receivers_outside = held.iter().filter(|&&h| !h).count() as u64;
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
        c.set("light_view.faces", self.views.len() as f64);
        c.set(
            "light_view.receivers_outside",
            self.receivers_outside as f64,
        );
        c.set(
            "light_view.casters_near_clipped",
            self.casters_near_clipped as f64,
        );
        if self.receivers_outside > 0 {
            out.warnings.push(format!(
                "{} visible receiver pixels lie outside the light view (behind the light or                  beyond {MAX_HALF_FOV_DEG}° from its axis) and are taken as lit",
                self.receivers_outside
            ));
        }
        if self.casters_near_clipped > 0 {
            out.warnings.push(format!(
                "{} occluding triangles reach nearer the light than {MIN_NEAR_RATIO} of the                  light view's far plane and are clipped there",
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
