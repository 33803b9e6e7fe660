//! The light-view projection and the filtering math shared by the shadow-map family
//! (`hard_shadow_map`, `pcss`, and the penumbra map's first pass). One place for each formula;
//! the cpu and wgpu executions both call (or mirror in WGSL) exactly these.
//!
//! Maps hold NDC depth in [0, 1] from a perspective projection at the light centre, which is
//! what a GPU depth buffer holds and what a rasterizer interpolates linearly in screen space;
//! [`LightView::linear_depth`] turns it back into distance along the view axis for the PCSS math.

use glam::{Mat4, Vec2, Vec3, Vec4Swizzles};

use crate::scene::camera::{look_at, perspective};
use crate::scene::{Bounds, Light};

/// Largest half-angle of the light frustum; wider scenes around the light are clamped to this
/// (one perspective map cannot see a whole hemisphere).
pub const MAX_HALF_FOV_DEG: f32 = 80.0;

/// A perspective view from the light centre that encloses the scene.
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
    /// Looks from the light centre at the centre of `scene`, with a field of view that encloses
    /// its bounds (up to [`MAX_HALF_FOV_DEG`]) and near/far planes that bracket them.
    pub fn new(light: &Light, scene: Bounds, resolution: u32) -> LightView {
        let eye = light.center();
        let dir = (scene.center() - eye).normalize_or(Vec3::NEG_Y);
        let up = if dir.cross(Vec3::Y).length_squared() < 1e-6 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        let view = look_at(eye, eye + dir, up);
        let max_half = MAX_HALF_FOV_DEG.to_radians();
        let (mut half, mut near, mut far) = (1e-3f32, f32::INFINITY, 1e-3f32);
        for c in scene.corners() {
            let v = view.transform_point3(c);
            let depth = -v.z;
            far = far.max(depth);
            if depth > 0.0 {
                near = near.min(depth);
                half = half.max((v.x.abs().max(v.y.abs()) / depth).atan());
            } else {
                half = max_half;
            }
        }
        let half = half.min(max_half) * 1.02;
        let far = far * 1.01;
        let near = if near.is_finite() {
            near * 0.99
        } else {
            far * 1e-3
        }
        .max(far * 1e-3);
        let proj = perspective(2.0 * half, 1.0, near, far);
        LightView {
            eye,
            view,
            proj,
            view_proj: proj * view,
            near,
            far,
            tan_half_fov: half.tan(),
            resolution,
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_round_trips_depth_and_centres_the_scene() {
        let light = Light::Sphere {
            center: Vec3::new(0.0, 10.0, 0.0),
            radius: 1.0,
        };
        let b = Bounds {
            min: Vec3::new(-2.0, 0.0, -2.0),
            max: Vec3::new(2.0, 1.0, 2.0),
        };
        let v = LightView::new(&light, b, 512);
        let (uv, ndc, z) = v.project(Vec3::new(0.0, 0.5, 0.0)).unwrap();
        assert!((uv - Vec2::splat(0.5)).length() < 1e-4);
        assert!((v.linear_depth(ndc) - z).abs() < 1e-3 * z);
        assert!((z - 9.5).abs() < 1e-3);
        for c in b.corners() {
            let (uv, ndc, _) = v.project(c).unwrap();
            assert!(uv.min_element() >= 0.0 && uv.max_element() <= 1.0, "{uv}");
            assert!((0.0..=1.0).contains(&ndc));
        }
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

/// Options of `hard_shadow_map` (scenario `options.hard_shadow_map`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HardShadowOptions {
    #[serde(default)]
    pub bias: Bias,
}

/// Options of `pcss` (scenario `options.pcss`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PcssOptions {
    /// Shadow-map taps of the blocker search (step 1).
    #[serde(default = "default_blocker_samples")]
    pub blocker_samples: u32,
    /// Shadow-map taps of the percentage-closer filter (step 3).
    #[serde(default = "default_pcf_samples")]
    pub pcf_samples: u32,
    #[serde(default)]
    pub bias: Bias,
}

fn default_blocker_samples() -> u32 {
    16
}

fn default_pcf_samples() -> u32 {
    32
}

impl Default for PcssOptions {
    fn default() -> Self {
        PcssOptions {
            blocker_samples: default_blocker_samples(),
            pcf_samples: default_pcf_samples(),
            bias: Bias::default(),
        }
    }
}

/// Reads `options.<id>` of a scenario into `T` (defaults when absent), naming the JSON path of
/// a bad field.
pub fn parse_options<T: serde::de::DeserializeOwned + Default>(
    id: &str,
    options: &std::collections::BTreeMap<String, serde_json::Value>,
) -> Result<T, crate::error::InputError> {
    match options.get(id) {
        None => Ok(T::default()),
        Some(v) => serde_path_to_error::deserialize(v).map_err(|e| {
            let path = e.path().to_string();
            crate::error::InputError::new(
                if path == "." {
                    format!("$.options.{id}")
                } else {
                    format!("$.options.{id}.{path}")
                },
                e.into_inner().to_string(),
            )
        }),
    }
}

impl PcssOptions {
    pub fn validate(&self, id: &str) -> Result<(), crate::error::InputError> {
        for (name, v) in [
            ("blocker_samples", self.blocker_samples),
            ("pcf_samples", self.pcf_samples),
        ] {
            if !(1..=1024).contains(&v) {
                return Err(crate::error::InputError::new(
                    format!("$.options.{id}.{name}"),
                    format!("must be in 1..=1024, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// Bytes of one f32 depth map at the run's map resolution (the memory estimate of the
/// shadow-map family before anything is allocated).
pub fn map_bytes(p: &crate::frame::RunParams) -> u64 {
    p.map_resolution as u64 * p.map_resolution as u64 * 4
}
