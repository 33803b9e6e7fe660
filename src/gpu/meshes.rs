//! Uploads of the geometry the executions draw: a scene mesh's positions, and meshes whose
//! vertices carry one attribute beside their position (volumes, cones and sheets).

use glam::Vec3;

use super::pass::Mesh;
use super::Gpu;

/// The positions of `mesh` as the vertex shaders read them (`vec3<f32>` a vertex).
pub fn positions(mesh: &crate::scene::Mesh) -> Vec<[f32; 3]> {
    mesh.positions.iter().map(|p| p.to_array()).collect()
}

impl Mesh {
    /// The vertex attributes of [`Mesh::of`]'s vertices: the position at location 0.
    pub const POSITION: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Float32x3];
    /// The vertex attributes of [`Mesh::with_w`]'s vertices: the position at location 0, `w` at
    /// location 1.
    pub const POSITION_W: [wgpu::VertexAttribute; 2] =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32];

    /// Uploads the positions ([`positions`]) and triangles of `mesh`.
    pub fn of(gpu: &Gpu, label: &str, mesh: &crate::scene::Mesh) -> Mesh {
        Mesh::upload(gpu, label, &positions(mesh), &mesh.triangles)
    }

    /// Uploads vertices of `positions` with `w` in the fourth component (`vec4<f32>` a
    /// vertex: xyz, w) and the indices of `triangles`.
    pub fn with_w(
        gpu: &Gpu,
        label: &str,
        positions: &[Vec3],
        w: impl IntoIterator<Item = f32>,
        triangles: &[[u32; 3]],
    ) -> Mesh {
        let vertices: Vec<[f32; 4]> = positions
            .iter()
            .zip(w)
            .map(|(p, w)| p.extend(w).to_array())
            .collect();
        Mesh::upload(gpu, label, &vertices, triangles)
    }
}
