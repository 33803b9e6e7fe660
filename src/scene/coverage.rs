//! The one coverage rule: which faces of a mesh a line (an eye ray, a shadow ray, an eye sample
//! seen from the light) passes through, so that a watertight mesh covers every point exactly
//! once, also where the line meets an edge or a vertex exactly.
//!
//! A face's boundary is a list of directed edges. The *edge function* of the edge `p → q` for
//! the line `o + t·d` is the scalar triple product `d · ((p − o) × (q − o))`: its sign says on
//! which side of the plane through `o`, `p`, `q` the line passes (Plücker's side operator). The
//! line crosses a face whose normal `n` has `d · n > 0` when every edge function of its boundary
//! is positive (with `d · n < 0`, every edge function of the reversed boundary).
//!
//! **Shared edges.** [`edge_function`] always evaluates an edge from its lexicographically
//! smaller endpoint and negates the result for the other direction, so the two faces that share
//! an edge (in opposite directions, as in a consistently wound mesh) get exactly opposite values,
//! whatever the float rounding or contraction of the machine evaluating it.
//!
//! **Ties** (an edge function exactly 0: the line meets the edge or a vertex). The line is moved
//! by an infinitesimal `δ = (ε, ε², ε³)` (simulation of simplicity): the edge function of
//! `p → q` becomes `E + δ · ((p − q) × d)`, so a tied edge covers the line when the first
//! non-zero component of `(p − q) × d` is positive ([`tie_owner`]). Of the two directions of a
//! shared edge exactly one owns the tie; around a vertex exactly one of the faces of a fan
//! contains the moved line. This is the top-left rule of rasterizers generalised to rays in
//! 3D: in 2D (`d = +z`) it reads "a tied edge covers when its `y` decreases, or when `y` stays
//! and `x` increases" — the rule `model::raster` applies in screen space.
//!
//! Used by: the hard shadow quads and the z-fail volume faces of the shadow-volume family
//! (`algorithms::shadow_volume`, `soft_shadow_volume`, `accum_hard`, and their WGSL in
//! `soft_shadow_volume/wgpu.wgsl`), the eye count of z-pass, `soft_izb`'s eye-sample-in-triangle
//! test and penumbra sign rule (and its WGSL), and the binned rasterizer's top-left rule
//! (`model::raster`, in screen space with exact snapped edge values). The WGSL mirror of this
//! file is `coverage.wgsl` ([`WGSL`]), prepended to the shaders that decide coverage.

use glam::{Vec2, Vec3};

/// The WGSL mirror of this module (`edge_function`, `tie_owner`, `edge_covers`,
/// `edge_covers_2d`), prepended to the shaders that decide coverage.
pub const WGSL: &str = include_str!("coverage.wgsl");

/// Whether `p` comes strictly before `q` in lexicographic (x, y, z) order.
#[inline]
pub fn precedes(p: Vec3, q: Vec3) -> bool {
    p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.z < q.z)))
}

/// Whether the first non-zero component of `c` is positive (false for the zero vector).
#[inline]
pub fn lex_positive(c: [f64; 3]) -> bool {
    if c[0] != 0.0 {
        c[0] > 0.0
    } else if c[1] != 0.0 {
        c[1] > 0.0
    } else {
        c[2] > 0.0
    }
}

/// The edge function of the directed edge `p → q` for the line `o + t·d`:
/// `d · ((p − o) × (q − o))`, evaluated from the lexicographically smaller endpoint, so that
/// `edge_function(o, d, q, p) == -edge_function(o, d, p, q)` exactly.
#[inline]
pub fn edge_function(o: Vec3, d: Vec3, p: Vec3, q: Vec3) -> f32 {
    let (cross, negate) = edge_plane(o, p, q);
    let v = d.dot(cross);
    if negate {
        -v
    } else {
        v
    }
}

/// The plane of the edge function of `p → q` for lines from `o` ([`edge_function`] is
/// `d · cross`, negated when `negate`): the cross product of the endpoints' offsets from `o`,
/// taken from the lexicographically smaller endpoint as [`edge_function`] takes it, so that
/// `d · cross` is its value to the bit for every direction `d`.
#[inline]
pub fn edge_plane(o: Vec3, p: Vec3, q: Vec3) -> (Vec3, bool) {
    if precedes(q, p) {
        ((q - o).cross(p - o), true)
    } else {
        ((p - o).cross(q - o), false)
    }
}

/// Whether the directed edge `p → q` owns a line along `d` that meets it exactly: the first
/// non-zero component of `(p − q) × d` is positive (the edge function grows under the
/// perturbation `δ = (ε, ε², ε³)` of the line). Exactly one direction of an edge owns it, unless
/// the edge is parallel to `d` (then neither: every face through it is seen edge-on).
#[inline]
pub fn tie_owner(d: Vec3, p: Vec3, q: Vec3) -> bool {
    let (c, flip) = if precedes(q, p) {
        ((q - p).cross(d), true)
    } else {
        ((p - q).cross(d), false)
    };
    if c == Vec3::ZERO {
        return false;
    }
    lex_positive([c.x, c.y, c.z].map(f64::from)) != flip
}

/// Whether the line `o + t·d` lies on the inner side of the directed edge `p → q` of a face seen
/// with positive orientation (`d · n > 0`), ties broken by [`tie_owner`].
#[inline]
pub fn edge_covers(o: Vec3, d: Vec3, p: Vec3, q: Vec3) -> bool {
    let e = edge_function(o, d, p, q);
    e > 0.0 || (e == 0.0 && tie_owner(d, p, q))
}

/// Whether the line `o + t·d` passes through the face bounded by the directed `edges` (convex,
/// wound counter-clockwise around `normal`). Faces seen edge-on (`d · normal == 0`) are missed.
/// The boundary may be any set of lines that bounds the face (e.g. the rays from the light that
/// bound a semi-infinite shadow quad).
#[inline]
pub fn line_crosses(o: Vec3, d: Vec3, normal: Vec3, edges: &[(Vec3, Vec3)]) -> bool {
    let s = d.dot(normal);
    if s > 0.0 {
        edges.iter().all(|&(p, q)| edge_covers(o, d, p, q))
    } else if s < 0.0 {
        edges.iter().all(|&(p, q)| edge_covers(o, d, q, p))
    } else {
        false
    }
}

/// The 2D edge function `(p − x) × (q − x)` (the edge function of [`edge_function`] for the
/// line through `x` along +z), exactly antisymmetric in `p`, `q`.
pub fn edge_function_2d(x: Vec2, p: Vec2, q: Vec2) -> f32 {
    edge_function(x.extend(0.0), Vec3::Z, p.extend(0.0), q.extend(0.0))
}

/// Whether point `x` lies in triangle `v` (either winding) under the tie rule; returns the three
/// edge functions (edge `k` opposite vertex `k`, signed so that they sum to twice the signed
/// area): divided by that area they are `x`'s barycentric weights.
pub fn triangle_covers_2d(x: Vec2, v: [Vec2; 3]) -> Option<[f32; 3]> {
    let e = std::array::from_fn(|k| edge_function_2d(x, v[(k + 1) % 3], v[(k + 2) % 3]));
    let area2 = (v[1] - v[0]).perp_dot(v[2] - v[0]);
    let z = Vec3::Z;
    let covers = |k: usize| {
        let (p, q) = (v[(k + 1) % 3].extend(0.0), v[(k + 2) % 3].extend(0.0));
        if area2 > 0.0 {
            e[k] > 0.0 || (e[k] == 0.0 && tie_owner(z, p, q))
        } else {
            e[k] < 0.0 || (e[k] == 0.0 && tie_owner(z, q, p))
        }
    };
    (area2 != 0.0 && (0..3).all(covers)).then_some(e)
}

/// Whether point `x` lies on the inner side of the directed 2D edge `p → q` of a
/// counter-clockwise (positive area) face, ties broken by [`tie_owner`].
pub fn edge_covers_2d(x: Vec2, p: Vec2, q: Vec2) -> bool {
    edge_covers(x.extend(0.0), Vec3::Z, p.extend(0.0), q.extend(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The eight triangles of a fan around the origin in the z = 0 plane (counter-clockwise
    /// seen from +z), corners on the unit square.
    fn fan() -> Vec<[Vec3; 3]> {
        let ring = [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
            Vec3::new(-1.0, 0.0, 0.0),
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
        ];
        (0..8)
            .map(|i| [Vec3::ZERO, ring[i], ring[(i + 1) % 8]])
            .collect()
    }

    fn crossings(o: Vec3, d: Vec3, tris: &[[Vec3; 3]]) -> usize {
        tris.iter()
            .filter(|t| {
                let n = (t[1] - t[0]).cross(t[2] - t[0]);
                line_crosses(o, d, n, &[(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            })
            .count()
    }

    /// Lines through the fan's centre vertex, along its spokes, through its corners and inside
    /// its triangles, from above and from below, straight and oblique: each crosses exactly one
    /// triangle (the fan covers the square exactly once); lines outside cross none.
    #[test]
    fn a_fan_covers_each_line_once_on_vertices_and_edges() {
        let tris = fan();
        let points = [
            (0.0, 0.0),
            (0.5, 0.0),
            (0.5, 0.5),
            (0.0, -0.5),
            (-0.5, 0.5),
            (0.25, 0.1),
            (-0.3, -0.7),
            (0.0, 0.0),
        ];
        for (x, y) in points {
            for d in [
                Vec3::new(0.0, 0.0, -1.0),
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(0.25, 0.5, -1.0),
                Vec3::new(-1.0, 0.5, 2.0),
            ] {
                let o = Vec3::new(x, y, 0.0) - d * 3.0;
                assert_eq!(
                    crossings(o, d, &tris),
                    1,
                    "line through ({x}, {y}) along {d}"
                );
            }
        }
        assert_eq!(
            crossings(Vec3::new(1.5, 0.0, 1.0), Vec3::NEG_Z, &tris),
            0,
            "outside"
        );
    }

    /// The same fan reversed (clockwise) also covers every line once, and a tied edge is owned
    /// by exactly one of its two directions.
    #[test]
    fn ties_are_owned_by_exactly_one_direction() {
        let tris: Vec<[Vec3; 3]> = fan().into_iter().map(|[a, b, c]| [a, c, b]).collect();
        assert_eq!(crossings(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z, &tris), 1);
        let d = Vec3::new(0.1, -0.2, -1.0);
        for (p, q) in [
            (Vec3::ZERO, Vec3::X),
            (Vec3::Y, Vec3::ZERO),
            (Vec3::new(1.0, 1.0, 0.0), Vec3::new(-2.0, 0.5, 0.3)),
        ] {
            assert_ne!(tie_owner(d, p, q), tie_owner(d, q, p));
            assert_eq!(
                edge_function(Vec3::ONE, d, p, q),
                -edge_function(Vec3::ONE, d, q, p)
            );
        }
        assert!(
            !tie_owner(Vec3::X, Vec3::ZERO, Vec3::X) && !tie_owner(Vec3::X, Vec3::X, Vec3::ZERO)
        );
    }

    /// In 2D the rule is the rasterizers' top-left rule (y pointing up: an edge going down, or
    /// going right along a horizontal): a point on the diagonal of a unit square split in two
    /// is in exactly one half, the square's corners and centre too.
    #[test]
    fn in_2d_a_split_square_covers_each_point_once() {
        let (a, b, c, d) = (
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        );
        for tris in [[[a, b, c], [a, c, d]], [[a, c, b], [a, d, c]]] {
            for x in [
                a,
                b,
                c,
                d,
                Vec2::splat(0.5),
                Vec2::new(0.25, 0.25),
                Vec2::new(0.5, 0.0),
            ] {
                let n = tris
                    .iter()
                    .filter(|t| triangle_covers_2d(x, **t).is_some())
                    .count();
                let inside_half_open = x.x < 1.0 && x.y < 1.0;
                // The square's half-open extent under the rule: its left and bottom sides only.
                assert_eq!(n, usize::from(inside_half_open), "{x}");
            }
        }
        assert!(edge_covers_2d(Vec2::new(0.5, 0.0), Vec2::ZERO, Vec2::X));
        assert!(!edge_covers_2d(Vec2::new(0.5, 0.0), Vec2::X, Vec2::ZERO));
    }
}
