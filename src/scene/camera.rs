//! The pinhole eye camera.

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

use super::mesh::Bounds;

/// A pinhole camera. The image size is a run parameter (`image`), not part of the camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    #[serde(default = "default_up")]
    pub up: Vec3,
    /// Vertical field of view in degrees.
    #[serde(default = "default_fov")]
    pub fov_y_deg: f32,
}

fn default_up() -> Vec3 {
    Vec3::Y
}

fn default_fov() -> f32 {
    45.0
}

impl Camera {
    /// A camera at `eye` looking at `target`, +y up, with a vertical field of view of
    /// `fov_y_deg` degrees.
    pub fn looking_at(eye: Vec3, target: Vec3, fov_y_deg: f32) -> Camera {
        Camera {
            eye,
            target,
            up: Vec3::Y,
            fov_y_deg,
        }
    }

    /// Orthonormal basis (right, up, forward).
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        (right, up, forward)
    }

    /// Direction (normalised) through the centre of pixel (x, y), y down, for a `w`×`h` image.
    pub fn ray_direction(&self, x: u32, y: u32, w: u32, h: u32) -> Vec3 {
        let (right, up, forward) = self.basis();
        let tan = (self.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = w as f32 / h as f32;
        let sx = ((x as f32 + 0.5) / w as f32 * 2.0 - 1.0) * tan * aspect;
        let sy = (1.0 - (y as f32 + 0.5) / h as f32 * 2.0) * tan;
        (forward + right * sx + up * sy).normalize()
    }

    /// World-to-clip matrix (right-handed, depth 0..1) with near/far planes fitted to `scene`.
    pub fn view_proj(&self, w: u32, h: u32, scene: Bounds) -> Mat4 {
        let view = look_at(self.eye, self.target, self.up);
        let (near, far) = depth_range(view, scene);
        perspective(self.fov_y_deg.to_radians(), w as f32 / h as f32, near, far) * view
    }
}

/// Near and far distances along -z of `view` that enclose `scene`, with the near plane kept at a
/// sane fraction of the far one so depth precision is not wasted.
pub fn depth_range(view: Mat4, scene: Bounds) -> (f32, f32) {
    let mut far: f32 = 1e-3;
    let mut near = f32::INFINITY;
    for c in scene.corners() {
        let z = -view.transform_point3(c).z;
        far = far.max(z);
        near = near.min(z);
    }
    let far = far * 1.01;
    let near = near.max(far * 1e-3);
    (near, far)
}

/// Right-handed view matrix (looking down −z).
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Mat4 {
    glam::camera::rh::view::look_at_mat4(eye, target, up)
}

/// Right-handed perspective projection with depth in [0, 1] and y up, as wgpu expects.
pub fn perspective(fov_y: f32, aspect: f32, near: f32, far: f32) -> Mat4 {
    glam::camera::rh::proj::directx::perspective(fov_y, aspect, near, far)
}
