//! The scene model: meshes with adjacency, objects tagged occluder/receiver, camera, lights,
//! procedural generators, mesh files (OBJ, glTF 2.0, PLY) in and out, and the BVH used for ground
//! truth and the eye pass.

pub mod adjacency;
pub mod bvh;
pub mod camera;
pub mod coverage;
pub mod export;
pub mod generators;
pub mod gltf;
pub mod light;
pub mod light_texture;
pub mod load;
pub mod mesh;
pub mod obj;
pub mod ply;
pub mod polygon;
pub mod shadow_bvh;
pub mod simplify;

pub use camera::Camera;
pub use light::{Light, LightKind};
pub use light_texture::LightTexture;
pub use mesh::{Bounds, FlatMesh, Mesh, Object, Role};

use crate::util::hash::Fnv64;

/// A complete scene: objects, the eye camera and one area light.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub objects: Vec<Object>,
    pub camera: Camera,
    pub light: Light,
    /// The light's texture (rectangular lights only); `None`: uniform white.
    pub light_texture: Option<std::sync::Arc<LightTexture>>,
}

impl Scene {
    /// An unnamed scene of `objects` under an untextured `light`.
    pub fn new(objects: Vec<Object>, camera: Camera, light: Light) -> Scene {
        Scene {
            name: String::new(),
            objects,
            camera,
            light,
            light_texture: None,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.triangles.len()).sum()
    }

    pub fn bounds(&self) -> Bounds {
        self.objects
            .iter()
            .fold(Bounds::EMPTY, |b, o| b.union(o.mesh.bounds()))
    }

    /// All triangles in one mesh, remembering their object.
    pub fn flatten(&self) -> FlatMesh {
        let mut f = FlatMesh::default();
        for (i, o) in self.objects.iter().enumerate() {
            f.mesh.append(&o.mesh);
            f.object_of_triangle
                .extend(std::iter::repeat_n(i as u32, o.mesh.triangles.len()));
            f.roles.push(o.role);
        }
        f
    }

    /// The mesh of all occluders (what shadow algorithms extract silhouettes from).
    pub fn occluders(&self) -> Mesh {
        let mut m = Mesh::default();
        for o in self.objects.iter().filter(|o| o.role.occluder) {
            m.append(&o.mesh);
        }
        m
    }

    /// A stable hash of the geometry (positions, triangles, roles), for cache keys.
    pub fn geometry_hash(&self) -> u64 {
        let mut h = Fnv64::default();
        for o in &self.objects {
            for p in &o.mesh.positions {
                h.f32s(&p.to_array());
            }
            for t in &o.mesh.triangles {
                for i in t {
                    h.u64(*i as u64);
                }
            }
            h.u64(o.role.occluder as u64 * 2 + o.role.receiver as u64);
        }
        h.finish()
    }
}
