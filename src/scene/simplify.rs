//! Mesh simplification for shadow generation: paper 000 (§5) draws the shadows of its 70K-
//! triangle bunny from a 10K-triangle version, "as soft shadows effectively blur detail".
//!
//! The work is done by meshoptimizer (the `meshopt` crate): edge collapses under a quadric
//! error metric that keep the topology, so a closed mesh stays closed and its silhouette stays
//! a set of loops.

use super::adjacency::EdgeAdjacency;
use super::mesh::Mesh;

/// `mesh` reduced to at most about `target` triangles (the simplifier stops earlier when no
/// collapse keeps the topology). Vertices are welded by exact position first, so meshes that
/// split vertices at seams collapse across them; the result holds only used vertices. A mesh
/// already at or below `target` comes back welded but otherwise unchanged.
pub fn simplify(mesh: &Mesh, target: u32) -> Mesh {
    let welded = EdgeAdjacency::build(mesh);
    if mesh.triangles.len() <= target as usize {
        return Mesh {
            positions: welded.vertices,
            triangles: welded.triangles,
        };
    }
    let positions: Vec<[f32; 3]> = welded.vertices.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = welded.triangles.iter().flatten().copied().collect();
    let adapter = meshopt::VertexDataAdapter::new(bytemuck::cast_slice(&positions), 12, 0)
        .expect("a tightly packed array of [f32; 3]");
    // No error bound: the target count decides (the error is relative to the mesh's extent,
    // so 1.0 allows any collapse that keeps the topology).
    let kept = meshopt::simplify(
        &indices,
        &adapter,
        3 * target as usize,
        1.0,
        meshopt::SimplifyOptions::None,
        None,
    );
    // Compact: only the vertices still referenced, in first-use order.
    let mut remap = vec![u32::MAX; positions.len()];
    let mut out = Mesh::default();
    for tri in kept.chunks_exact(3) {
        let t: [u32; 3] = std::array::from_fn(|k| {
            let i = tri[k] as usize;
            if remap[i] == u32::MAX {
                remap[i] = out.positions.len() as u32;
                out.positions.push(welded.vertices[i]);
            }
            remap[i]
        });
        out.triangles.push(t);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::adjacency::EdgeKind;
    use crate::scene::generators::primitives;

    #[test]
    fn a_closed_sphere_stays_closed_near_the_target() {
        let sphere = primitives::uv_sphere_with_triangles(8_000);
        let n = sphere.triangles.len();
        let s = simplify(&sphere, 1_000);
        assert!(s.triangles.len() <= 1_000, "{} of {n}", s.triangles.len());
        assert!(s.triangles.len() >= 500, "{} of {n}", s.triangles.len());
        let adj = EdgeAdjacency::build(&s);
        assert_eq!(adj.count(EdgeKind::Boundary), 0);
        assert_eq!(adj.count(EdgeKind::NonManifold), 0);
        // Still a unit sphere: every kept vertex is an original one, and the bounds barely move.
        let (a, b) = (sphere.bounds(), s.bounds());
        assert!((a.min - b.min).abs().max_element() < 0.05, "{a:?} {b:?}");
        assert!((a.max - b.max).abs().max_element() < 0.05, "{a:?} {b:?}");
    }

    #[test]
    fn a_mesh_under_the_target_is_kept() {
        let cube = primitives::cuboid(glam::Vec3::ZERO, glam::Vec3::ONE);
        let s = simplify(&cube, 100);
        assert_eq!(s.triangles.len(), cube.triangles.len());
        assert_eq!(s.bounds(), cube.bounds());
    }
}
