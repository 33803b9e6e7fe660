//! Indexed triangle meshes and the objects a scene is made of.

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

/// An indexed triangle mesh in world space.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Appends `other`, re-indexing its triangles.
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    }

    pub fn transformed(mut self, m: Mat4) -> Mesh {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        // A mirroring transform flips the winding; keep outward-facing triangles.
        if m.determinant() < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
        self
    }

    pub fn bounds(&self) -> Bounds {
        Bounds::of_points(self.positions.iter().copied())
    }

    /// Geometric (unnormalised) normal of triangle `t`, following the winding.
    pub fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangle(t);
        (b - a).cross(c - a)
    }
}

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn of_points(points: impl IntoIterator<Item = Vec3>) -> Bounds {
        points
            .into_iter()
            .fold(Bounds::EMPTY, |b, p| b.including(p))
    }

    pub fn including(self, p: Vec3) -> Bounds {
        Bounds {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    pub fn union(self, o: Bounds) -> Bounds {
        Bounds {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }

    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    pub fn diagonal(&self) -> f32 {
        if self.is_empty() {
            0.0
        } else {
            (self.max - self.min).length()
        }
    }

    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }
}

/// What an object does in the shadow computation. Soft shadow maps (paper 002) need the split
/// between occluders (rendered into the occluder map) and receivers (into the receiver map).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Role {
    pub occluder: bool,
    pub receiver: bool,
}

impl Role {
    pub const BOTH: Role = Role {
        occluder: true,
        receiver: true,
    };
    pub const RECEIVER: Role = Role {
        occluder: false,
        receiver: true,
    };
}

impl Default for Role {
    fn default() -> Self {
        Role::BOTH
    }
}

/// A named mesh with its role.
#[derive(Clone, Debug)]
pub struct Object {
    pub name: String,
    pub mesh: Mesh,
    pub role: Role,
}

/// All scene triangles in one indexed array, with the object each came from; what ray casters
/// and rasterizers consume.
#[derive(Clone, Debug, Default)]
pub struct FlatMesh {
    pub mesh: Mesh,
    pub object_of_triangle: Vec<u32>,
    pub roles: Vec<Role>,
}

impl FlatMesh {
    pub fn role_of(&self, t: usize) -> Role {
        self.roles[self.object_of_triangle[t] as usize]
    }
}
