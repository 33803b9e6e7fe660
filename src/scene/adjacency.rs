//! Edge adjacency and silhouette extraction.
//!
//! Every algorithm that builds shadow geometry from edges (penumbra maps, soft shadow volumes,
//! umbra/penumbra volumes, soft irregular shadow mapping) needs the silhouette of the occluders as
//! seen from a point on the light. Vertices are welded by exact position first, so meshes that
//! split vertices for normals or texture seams still get connected edges.
//!
//! Meshes from users are not always closed 2-manifolds. Instead of failing, extraction reports:
//! * **boundary edges** (one adjacent face): always silhouettes, since the outline of an open
//!   surface always bounds its shadow;
//! * **non-manifold edges** (three or more faces): silhouettes when their faces do not all agree
//!   on facing the point;
//! * **degenerate faces** (zero area): they have no facing and are ignored by the test.

use std::collections::HashMap;

use glam::Vec3;

use super::mesh::Mesh;

/// How many faces meet at an edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeKind {
    Boundary,
    Manifold,
    NonManifold,
}

/// An undirected edge between two welded vertices and the faces that use it.
#[derive(Clone, Debug)]
pub struct Edge {
    pub v: [u32; 2],
    pub faces: Vec<u32>,
}

impl Edge {
    pub fn kind(&self) -> EdgeKind {
        match self.faces.len() {
            0 | 1 => EdgeKind::Boundary,
            2 => EdgeKind::Manifold,
            _ => EdgeKind::NonManifold,
        }
    }
}

/// A welded mesh with its edge list.
#[derive(Clone, Debug)]
pub struct EdgeAdjacency {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub edges: Vec<Edge>,
    /// Triangles whose area is zero (after welding); they take part in no facing test.
    pub degenerate_faces: usize,
}

/// One silhouette edge, oriented so that it runs in the winding order of the face that faces the
/// point (for boundary edges: of the only face, reversed when that face looks away).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SilhouetteEdge {
    pub a: Vec3,
    pub b: Vec3,
    pub v: [u32; 2],
    pub kind: EdgeKind,
}

/// The silhouette of a mesh seen from a point.
#[derive(Clone, Debug, Default)]
pub struct Silhouette {
    pub edges: Vec<SilhouetteEdge>,
    pub boundary_edges: usize,
    pub non_manifold_edges: usize,
}

impl EdgeAdjacency {
    /// Every edge's record as the brute-force silhouette tests read it: its two welded vertices
    /// and its first two faces (`u32::MAX` where a boundary edge has only one; closed meshes
    /// have exactly two).
    pub fn edge_records(&self) -> Vec<[u32; 4]> {
        self.edges
            .iter()
            .map(|edge| {
                let face = |k: usize| edge.faces.get(k).copied().unwrap_or(u32::MAX);
                [edge.v[0], edge.v[1], face(0), face(1)]
            })
            .collect()
    }

    pub fn build(mesh: &Mesh) -> EdgeAdjacency {
        let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
        let mut vertices = Vec::new();
        let remap: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
                *weld.entry(key).or_insert_with(|| {
                    vertices.push(*p);
                    (vertices.len() - 1) as u32
                })
            })
            .collect();
        let triangles: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| remap[i as usize]))
            .collect();

        let mut index: HashMap<(u32, u32), usize> = HashMap::new();
        let mut edges: Vec<Edge> = Vec::new();
        let mut degenerate_faces = 0;
        for (f, t) in triangles.iter().enumerate() {
            if face_normal(&vertices, t) == Vec3::ZERO {
                degenerate_faces += 1;
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if a == b {
                    continue;
                }
                let key = (a.min(b), a.max(b));
                let e = *index.entry(key).or_insert_with(|| {
                    edges.push(Edge {
                        v: [key.0, key.1],
                        faces: Vec::with_capacity(2),
                    });
                    edges.len() - 1
                });
                edges[e].faces.push(f as u32);
            }
        }
        EdgeAdjacency {
            vertices,
            triangles,
            edges,
            degenerate_faces,
        }
    }

    /// Whether face `f` faces point `p` (`None` for a degenerate face).
    pub fn faces_point(&self, f: u32, p: Vec3) -> Option<bool> {
        let t = &self.triangles[f as usize];
        let n = face_normal(&self.vertices, t);
        if n == Vec3::ZERO {
            return None;
        }
        Some(n.dot(p - self.vertices[t[0] as usize]) > 0.0)
    }

    /// Whether face `f` traverses the edge `a→b` in its winding order.
    fn winds(&self, f: u32, a: u32, b: u32) -> bool {
        let t = &self.triangles[f as usize];
        (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b)
    }

    /// Silhouette edges seen from `p`: edges between a face that faces `p` and one that does not.
    pub fn silhouette_from(&self, p: Vec3) -> Silhouette {
        let mut s = Silhouette::default();
        for e in 0..self.edges.len() {
            let Some(edge) = self.silhouette_edge(e, p) else {
                continue;
            };
            match edge.kind {
                EdgeKind::Boundary => s.boundary_edges += 1,
                EdgeKind::NonManifold => s.non_manifold_edges += 1,
                EdgeKind::Manifold => {}
            }
            s.edges.push(edge);
        }
        s
    }

    /// Edge `e` as a silhouette edge seen from `p`, oriented as [`SilhouetteEdge`] says, or
    /// `None` when it is not one (the per-edge test of [`Self::silhouette_from`]).
    pub fn silhouette_edge(&self, e: usize, p: Vec3) -> Option<SilhouetteEdge> {
        let e = &self.edges[e];
        let kind = e.kind();
        let facing: Vec<(u32, bool)> = e
            .faces
            .iter()
            .filter_map(|&f| self.faces_point(f, p).map(|fr| (f, fr)))
            .collect();
        let front = facing.iter().find(|(_, fr)| *fr);
        let is_silhouette = match kind {
            EdgeKind::Boundary => !facing.is_empty(),
            _ => front.is_some() && facing.iter().any(|(_, fr)| !*fr),
        };
        if !is_silhouette {
            return None;
        }
        let [a, b] = e.v;
        let forward = match front {
            Some(&(f, _)) => self.winds(f, a, b),
            None => !self.winds(facing[0].0, a, b),
        };
        let v = if forward { [a, b] } else { [b, a] };
        Some(SilhouetteEdge {
            a: self.vertices[v[0] as usize],
            b: self.vertices[v[1] as usize],
            v,
            kind,
        })
    }

    pub fn count(&self, kind: EdgeKind) -> usize {
        self.edges.iter().filter(|e| e.kind() == kind).count()
    }
}

fn face_normal(vertices: &[Vec3], t: &[u32; 3]) -> Vec3 {
    let [a, b, c] = t.map(|i| vertices[i as usize]);
    (b - a).cross(c - a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::generators::primitives;

    #[test]
    fn closed_box_is_manifold_and_its_silhouette_is_a_loop() {
        let m = primitives::cuboid(Vec3::ZERO, Vec3::ONE);
        let adj = EdgeAdjacency::build(&m);
        assert_eq!(adj.count(EdgeKind::Boundary), 0);
        assert_eq!(adj.count(EdgeKind::NonManifold), 0);
        // Seen from far along a body diagonal, a cube's silhouette is a hexagon.
        let s = adj.silhouette_from(Vec3::new(10.0, 11.0, 12.0));
        assert_eq!(s.edges.len(), 6);
        // Each vertex of a closed loop starts exactly one edge and ends exactly one.
        for e in &s.edges {
            assert_eq!(s.edges.iter().filter(|o| o.v[0] == e.v[1]).count(), 1);
        }
    }

    #[test]
    fn open_and_non_manifold_edges_are_reported_not_fatal() {
        let mut m = Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, -1.0, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
            ],
            triangles: vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        };
        // A zero-area triangle (repeated vertex) must not break anything.
        m.triangles.push([2, 2, 3]);
        let adj = EdgeAdjacency::build(&m);
        assert_eq!(adj.count(EdgeKind::NonManifold), 1);
        assert_eq!(adj.degenerate_faces, 1);
        let s = adj.silhouette_from(Vec3::new(0.3, 0.3, 5.0));
        assert!(s.boundary_edges > 0);
        assert_eq!(s.non_manifold_edges, 1);
    }
}
