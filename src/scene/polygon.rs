//! Triangulation of the polygons of mesh files (OBJ faces, PLY faces) by ear clipping on the
//! polygon's plane, with the `earcut` crate (the georust port of mapbox/earcut).
//!
//! A polygon of `n ≥ 4` vertices is projected onto the plane through its Newell normal
//! (`earcut::utils3d::project3d_to_2d`), ear-clipped there, and the triangles are given the
//! winding of the polygon (counter-clockwise about the Newell normal, as the file wrote it). A
//! fan from the first vertex would be wrong for concave polygons: it covers area outside the
//! polygon, with triangles of both windings.
//!
//! Two faults are reported rather than triangulated: a polygon with no area (all vertices on a
//! line or a point: [`PolygonFault::Degenerate`]) and one whose triangles do not cover exactly
//! its area ([`PolygonFault::SelfIntersecting`]: its edges cross, so it has no well-defined
//! inside; earcut's `deviation` measures the mismatch).
//!
//! Also the clipping of a convex polygon by a half-plane ([`clip_half_plane`]).

use earcut::Earcut;
use glam::{DVec3, Vec3};

/// Largest relative difference between a polygon's area and its triangles' area accepted as a
/// correct triangulation (rounding of the `f64` projection is far below it).
pub const MAX_DEVIATION: f64 = 1e-6;

/// Why a polygon yields no triangles.
#[derive(Clone, Debug, PartialEq)]
pub enum PolygonFault {
    /// All vertices lie on a line or at one point: there is no surface to keep.
    Degenerate,
    /// The edges cross (or earcut could not cover it): the triangles' area differs from the
    /// polygon's by `deviation` (relative).
    SelfIntersecting { deviation: f64 },
}

impl std::fmt::Display for PolygonFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PolygonFault::Degenerate => f.write_str("has no area (its vertices are collinear)"),
            PolygonFault::SelfIntersecting { deviation } if deviation.is_finite() => write!(
                f,
                "intersects itself (its triangles' area differs from its area by {:.3}%)",
                deviation * 100.0
            ),
            PolygonFault::SelfIntersecting { .. } => {
                f.write_str("intersects itself (its loops cancel: it has no net area)")
            }
        }
    }
}

/// Triangulates polygon `poly` (indices into `positions`, in order around its boundary).
///
/// Triangles (`n = 3`) are returned as given, even with no area (the algorithms handle those);
/// polygons of four or more vertices are ear-clipped on their plane. Returns triangles of
/// indices into `positions`; `n < 3` is the caller's error.
pub fn triangulate(positions: &[Vec3], poly: &[u32]) -> Result<Vec<[u32; 3]>, PolygonFault> {
    if poly.len() == 3 {
        return Ok(vec![[poly[0], poly[1], poly[2]]]);
    }
    let p: Vec<DVec3> = poly
        .iter()
        .map(|&i| positions[i as usize].as_dvec3())
        .collect();
    // Newell's normal: the polygon's area vector, robust for non-planar and concave polygons.
    let normal = p
        .iter()
        .zip(p.iter().cycle().skip(1))
        .fold(DVec3::ZERO, |n, (a, b)| n + a.cross(*b));
    // Collinear (or coincident) vertices: no point lies off the line through the first vertex
    // and the one farthest from it.
    let far = p
        .iter()
        .map(|q| *q - p[0])
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
        .unwrap_or_default();
    let off_line = p
        .iter()
        .map(|q| far.cross(*q - p[0]).length())
        .fold(0.0, f64::max);
    let scale = far.length_squared();
    if off_line.partial_cmp(&(scale * 1e-12)) != Some(std::cmp::Ordering::Greater) {
        return Err(PolygonFault::Degenerate);
    }
    // Loops of opposite orientation that cancel (a symmetric figure eight): no net area.
    if normal.length().partial_cmp(&(scale * 1e-12)) != Some(std::cmp::Ordering::Greater) {
        return Err(PolygonFault::SelfIntersecting {
            deviation: f64::INFINITY,
        });
    }
    let rings: Vec<[f64; 3]> = p.iter().map(|q| q.to_array()).collect();
    let mut flat = Vec::with_capacity(p.len());
    if !earcut::utils3d::project3d_to_2d(&rings, rings.len(), &mut flat) {
        return Err(PolygonFault::Degenerate);
    }
    let mut out: Vec<u32> = Vec::new();
    Earcut::new().earcut(flat.iter().copied(), &[] as &[u32], &mut out);
    let deviation = earcut::deviation(flat.iter().copied(), &[] as &[u32], &out);
    if out.is_empty()
        || !matches!(
            deviation.partial_cmp(&MAX_DEVIATION),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        )
    {
        return Err(PolygonFault::SelfIntersecting { deviation });
    }
    Ok(out
        .chunks_exact(3)
        .map(|t| {
            let [a, b, c] = [t[0], t[1], t[2]].map(|k| k as usize);
            // Keep the file's winding: counter-clockwise about the polygon's normal.
            let n = (p[b] - p[a]).cross(p[c] - p[a]);
            if n.dot(normal) < 0.0 {
                [poly[a], poly[c], poly[b]]
            } else {
                [poly[a], poly[b], poly[c]]
            }
        })
        .collect())
}

/// Sutherland–Hodgman: the part of the polygon `poly` (2D, or planar in 3D) where `f ≥ 0` (`f`
/// affine: a half-plane or half-space).
pub fn clip_half_plane<V>(poly: &[V], f: impl Fn(V) -> f32) -> Vec<V>
where
    V: Copy
        + std::ops::Add<Output = V>
        + std::ops::Sub<Output = V>
        + std::ops::Mul<f32, Output = V>,
{
    let mut out = Vec::with_capacity(poly.len() + 1);
    for (i, &p) in poly.iter().enumerate() {
        let q = poly[(i + 1) % poly.len()];
        let (fp, fq) = (f(p), f(q));
        if fp >= 0.0 {
            out.push(p);
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            out.push(p + (q - p) * (fp / (fp - fq)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points of the z = 0 plane.
    fn xy(points: &[(f32, f32)]) -> Vec<Vec3> {
        points.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect()
    }

    fn area(positions: &[Vec3], tris: &[[u32; 3]]) -> f32 {
        tris.iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| positions[i as usize]);
                (b - a).cross(c - a).length() * 0.5
            })
            .sum()
    }

    /// A U-shaped octagon (area 3 of its 3×2 bounding box minus the 1×1 notch = 5) in the
    /// plane x + y + z = 0 tilted in 3D: the triangles cover exactly its area, all facing the
    /// polygon's normal, and none covers the notch's centre.
    #[test]
    fn concave_polygon_on_a_tilted_plane() {
        let u = [
            (0.0, 0.0),
            (3.0, 0.0),
            (3.0, 2.0),
            (2.0, 2.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 2.0),
        ];
        let (e1, e2) = (
            Vec3::new(1.0, -1.0, 0.0).normalize(),
            Vec3::new(1.0, 1.0, -2.0).normalize(),
        );
        let positions: Vec<Vec3> = u.iter().map(|&(x, y)| e1 * x + e2 * y).collect();
        let poly: Vec<u32> = (0..8).collect();
        let tris = triangulate(&positions, &poly).unwrap();
        assert_eq!(tris.len(), 6);
        assert!((area(&positions, &tris) - 5.0).abs() < 1e-5);
        let normal = e1.cross(e2);
        let notch = e1 * 1.5 + e2 * 1.5;
        for t in &tris {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            assert!((b - a).cross(c - a).dot(normal) > 0.0, "winding of {t:?}");
            // Barycentric inside test of the notch centre.
            let inside = [(a, b), (b, c), (c, a)]
                .iter()
                .all(|(p, q)| (*q - *p).cross(notch - *p).dot(normal) > 0.0);
            assert!(!inside, "{t:?} covers the notch");
        }
    }

    #[test]
    fn bow_tie_and_collinear_polygons_are_faults() {
        let bow = xy(&[(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)]);
        assert!(matches!(
            triangulate(&bow, &[0, 1, 2, 3]),
            Err(PolygonFault::SelfIntersecting { .. })
        ));
        let line: Vec<Vec3> = (0..4).map(|i| Vec3::X * i as f32).collect();
        assert_eq!(
            triangulate(&line, &[0, 1, 2, 3]),
            Err(PolygonFault::Degenerate)
        );
    }

    #[test]
    fn clockwise_quad_keeps_its_winding() {
        let q = xy(&[(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0)]);
        let tris = triangulate(&q, &[0, 1, 2, 3]).unwrap();
        assert_eq!(tris.len(), 2);
        for t in tris {
            let [a, b, c] = t.map(|i| q[i as usize]);
            assert!((b - a).cross(c - a).z < 0.0);
        }
    }
}
