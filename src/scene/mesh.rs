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

    /// Whether triangle `t` has no area: its vertices are collinear or two of them coincide.
    /// Decided exactly on the `f32` coordinates (the cross product of two edges is zero when
    /// each of its components, the orientation of the triangle projected on the yz, zx and xy
    /// planes, is zero; each is computed with Shewchuk's adaptive exact `orient2d`), so no
    /// tolerance moves a thin but real triangle into this class.
    pub fn has_no_area(&self, t: usize) -> bool {
        let [a, b, c] = self.triangle(t);
        let orient = |u: fn(Vec3) -> (f32, f32)| {
            let c2 = |p: Vec3| {
                let (x, y) = u(p);
                robust::Coord {
                    x: x as f64,
                    y: y as f64,
                }
            };
            robust::orient2d(c2(a), c2(b), c2(c))
        };
        orient(|p| (p.y, p.z)) == 0.0
            && orient(|p| (p.z, p.x)) == 0.0
            && orient(|p| (p.x, p.y)) == 0.0
    }

    /// Drops the triangles with no area ([`Mesh::has_no_area`]) and welds exact duplicates:
    /// a triangle with the same three positions in the same cyclic order (the same winding,
    /// from any starting vertex) as an earlier one is dropped. A copy of opposite winding is
    /// kept: with its twin it bounds a closed sheet of no thickness (a two-sided face), which
    /// the shadow-volume counts need. Positions compare by value (`-0.0` equals `0.0`), not by
    /// index, so copies that repeat their vertices are found too. Vertices no kept triangle
    /// uses are removed (so a dropped triangle does not widen the bounds). O(n) expected time
    /// (one hash set).
    pub fn drop_degenerate(&mut self) -> Degenerate {
        let key = |p: Vec3| p.to_array().map(|x| if x == 0.0 { 0 } else { x.to_bits() });
        let mut seen = std::collections::HashSet::with_capacity(self.triangles.len());
        let mut found = Degenerate::default();
        let mut kept = Vec::with_capacity(self.triangles.len());
        for t in 0..self.triangles.len() {
            if self.has_no_area(t) {
                found.no_area += 1;
                continue;
            }
            let k = self.triangle(t).map(key);
            // The rotation starting at the smallest position: one key per cyclic order.
            let first = (0..3).min_by_key(|&i| k[i]).unwrap_or(0);
            if !seen.insert([k[first], k[(first + 1) % 3], k[(first + 2) % 3]]) {
                found.duplicates += 1;
                continue;
            }
            kept.push(self.triangles[t]);
        }
        if found.no_area + found.duplicates > 0 {
            let mut remap = vec![u32::MAX; self.positions.len()];
            let mut positions = Vec::new();
            for t in &mut kept {
                for i in t.iter_mut() {
                    let slot = &mut remap[*i as usize];
                    if *slot == u32::MAX {
                        *slot = positions.len() as u32;
                        positions.push(self.positions[*i as usize]);
                    }
                    *i = *slot;
                }
            }
            self.positions = positions;
        }
        self.triangles = kept;
        found
    }
}

/// What [`Mesh::drop_degenerate`] removed: counts of triangles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Degenerate {
    /// Triangles with no area (collinear or coincident vertices).
    pub no_area: usize,
    /// Exact copies (same positions, same winding) of an earlier triangle.
    pub duplicates: usize,
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
