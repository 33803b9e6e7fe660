//! Area lights and their stratified sampling.
//!
//! "Light size" is the radius of a sphere or disc light and the half-width (length of the first
//! half-axis) of a rectangular light.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::util::hash::unit_pair;

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Light {
    /// A spherical light. Seen from a receiver point it is the disc through its centre facing
    /// that point; all algorithms that take sphere lights (000, 004) treat it so.
    Sphere { center: Vec3, radius: f32 },
    /// A one-sided disc light (paper 003).
    Disc {
        center: Vec3,
        normal: Vec3,
        radius: f32,
    },
    /// A rectangle with centre and two orthogonal half-axes (papers 001, 002).
    Rect {
        center: Vec3,
        half_u: Vec3,
        half_v: Vec3,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightKind {
    Sphere,
    Disc,
    Rect,
}

impl LightKind {
    /// Every kind, in the order of listings.
    pub const ALL: [LightKind; 3] = [LightKind::Sphere, LightKind::Disc, LightKind::Rect];
}

impl std::fmt::Display for LightKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            LightKind::Sphere => "sphere",
            LightKind::Disc => "disc",
            LightKind::Rect => "rect",
        })
    }
}

impl Light {
    pub fn kind(&self) -> LightKind {
        match self {
            Light::Sphere { .. } => LightKind::Sphere,
            Light::Disc { .. } => LightKind::Disc,
            Light::Rect { .. } => LightKind::Rect,
        }
    }

    pub fn center(&self) -> Vec3 {
        match *self {
            Light::Sphere { center, .. }
            | Light::Disc { center, .. }
            | Light::Rect { center, .. } => center,
        }
    }

    /// The radius of a sphere around [`Self::center`] that holds the whole emitter (every
    /// [`Self::stratified_sample`] from any point): the radius, or a rectangle's half-diagonal.
    pub fn bounding_radius(&self) -> f32 {
        match *self {
            Light::Sphere { radius, .. } | Light::Disc { radius, .. } => radius,
            Light::Rect { half_u, half_v, .. } => {
                (half_u + half_v).length().max((half_u - half_v).length())
            }
        }
    }

    /// The light size: radius, or half-width of a rectangle.
    pub fn size(&self) -> f32 {
        match *self {
            Light::Sphere { radius, .. } | Light::Disc { radius, .. } => radius,
            Light::Rect { half_u, .. } => half_u.length(),
        }
    }

    /// The same light with its centre at `center` (size and orientation kept).
    pub fn with_center(self, center: Vec3) -> Light {
        match self {
            Light::Sphere { radius, .. } => Light::Sphere { center, radius },
            Light::Disc { normal, radius, .. } => Light::Disc {
                center,
                normal,
                radius,
            },
            Light::Rect { half_u, half_v, .. } => Light::Rect {
                center,
                half_u,
                half_v,
            },
        }
    }

    /// The same light scaled to `size` (a rectangle keeps its aspect ratio).
    pub fn with_size(self, size: f32) -> Light {
        match self {
            Light::Sphere { center, .. } => Light::Sphere {
                center,
                radius: size,
            },
            Light::Disc { center, normal, .. } => Light::Disc {
                center,
                normal,
                radius: size,
            },
            Light::Rect {
                center,
                half_u,
                half_v,
            } => {
                let s = size / half_u.length();
                Light::Rect {
                    center,
                    half_u: half_u * s,
                    half_v: half_v * s,
                }
            }
        }
    }

    /// The light emitter as seen from `p`: centre and two half-axes spanning it.
    /// For a sphere that is the disc through the centre perpendicular to the direction to `p`.
    pub fn emitter_frame(&self, p: Vec3) -> (Vec3, Vec3, Vec3) {
        match *self {
            Light::Sphere { center, radius } => {
                let w = (center - p).normalize_or(Vec3::Y);
                let (u, v) = w.any_orthonormal_pair();
                (center, u * radius, v * radius)
            }
            Light::Disc {
                center,
                normal,
                radius,
            } => {
                let (u, v) = normal.normalize_or(Vec3::NEG_Y).any_orthonormal_pair();
                (center, u * radius, v * radius)
            }
            Light::Rect {
                center,
                half_u,
                half_v,
            } => (center, half_u, half_v),
        }
    }

    /// Whether the plane through `p` with normal `n` cuts the emitter seen from `p`
    /// ([`Light::emitter_frame`]): part of the light lies in front of the surface at `p` and
    /// part behind it, a *grazing* point. There the visibility depends on whether the part
    /// behind the plane counts as hidden (the reference counts it so: the surface, or its own
    /// mesh, hides it) or is left to the shading's cosine (as most methods do), so the harness
    /// scores such pixels apart (`error.grazing_pixels`, `error.mae_shadow_non_grazing`).
    pub fn straddles(&self, p: Vec3, n: Vec3) -> bool {
        let (c, u, v) = self.emitter_frame(p);
        let h = n.dot(c - p).abs();
        let (a, b) = (n.dot(u), n.dot(v));
        let spread = match self {
            Light::Rect { .. } => a.abs() + b.abs(),
            _ => (a * a + b * b).sqrt(),
        };
        h < spread
    }

    /// Sample `i` of a stratified set of `k`×`k` samples on the light seen from `p`, jittered by
    /// the deterministic stream `seed`.
    pub fn stratified_sample(&self, p: Vec3, i: u32, k: u32, seed: u64) -> Vec3 {
        let (c, u, v) = self.emitter_frame(p);
        let d = self.stratified_coords(i, k, seed);
        c + u * d.x + v * d.y
    }

    /// All `k`×`k` samples of [`Light::stratified_sample`] seen from `p`, in order, into `out`
    /// (cleared first), with the emitter's frame computed once (the same points, bit for bit).
    pub fn stratified_samples_into(&self, p: Vec3, k: u32, seed: u64, out: &mut Vec<Vec3>) {
        let (c, u, v) = self.emitter_frame(p);
        out.clear();
        // Row by row, so that no sample divides its index by k.
        for row in 0..k {
            for col in 0..k {
                let d = self.strata_coords(col, row, row * k + col, k, seed);
                out.push(c + u * d.x + v * d.y);
            }
        }
    }

    /// [`Self::stratified_sample`] in light coordinates: units of the half-axes from the centre
    /// (`[−1, 1]²` for a rectangle, the unit disc otherwise), where a light texture is indexed.
    pub fn stratified_coords(&self, i: u32, k: u32, seed: u64) -> Vec2 {
        self.strata_coords(i % k, i / k, i, k, seed)
    }

    /// [`Self::stratified_coords`] of sample `i`, in column `col = i mod k` and row
    /// `row = ⌊i / k⌋` of the strata.
    #[inline(always)]
    fn strata_coords(&self, col: u32, row: u32, i: u32, k: u32, seed: u64) -> Vec2 {
        let jitter = unit_pair(seed, i as u64);
        let s = Vec2::new(
            (col as f32 + jitter.x) / k as f32,
            (row as f32 + jitter.y) / k as f32,
        );
        match self {
            Light::Rect { .. } => s * 2.0 - Vec2::ONE,
            _ => concentric_disc(s),
        }
    }

    /// Area of the emitter.
    pub fn area(&self) -> f32 {
        match *self {
            Light::Sphere { radius, .. } | Light::Disc { radius, .. } => {
                std::f32::consts::PI * radius * radius
            }
            Light::Rect { half_u, half_v, .. } => 4.0 * half_u.length() * half_v.length(),
        }
    }
}

impl Light {
    /// Whether the emitter meets triangle `tri`: a sphere as the ball of its radius (every disc
    /// it may show a receiver lies in it), a disc or rectangle as the flat region it spans (a
    /// triangle in the emitter's plane touches it nowhere off that plane, and is not counted).
    /// Used to refuse a converted light that would poke through the scene's geometry.
    pub fn meets_triangle(&self, tri: [Vec3; 3]) -> bool {
        match *self {
            Light::Sphere { center, radius } => {
                closest_on_triangle(center, tri).distance(center) < radius
            }
            Light::Disc { .. } | Light::Rect { .. } => {
                let (c, u, v) = self.emitter_frame(self.center());
                let n = u.cross(v).normalize_or_zero();
                let h = tri.map(|p| (p - c).dot(n));
                // The triangle's cut through the emitter's plane: points on edges whose ends lie
                // on opposite sides.
                let mut cut = Vec::with_capacity(2);
                for i in 0..3 {
                    let (a, b) = (i, (i + 1) % 3);
                    if (h[a] < 0.0) != (h[b] < 0.0) {
                        let t = h[a] / (h[a] - h[b]);
                        cut.push(tri[a] + (tri[b] - tri[a]) * t);
                    }
                }
                let [p, q] = match cut[..] {
                    [p, q] => [p, q],
                    _ => return false,
                };
                // In the emitter's coordinates (half-axes to ±1).
                let local = |x: Vec3| {
                    let d = x - c;
                    Vec2::new(d.dot(u) / u.length_squared(), d.dot(v) / v.length_squared())
                };
                let (p, q) = (local(p), local(q));
                match self {
                    Light::Rect { .. } => segment_meets_square(p, q),
                    _ => {
                        let e = q - p;
                        let t =
                            (-p.dot(e) / e.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
                        (p + e * t).length() < 1.0
                    }
                }
            }
        }
    }
}

/// The point of triangle `tri` nearest `p` (Ericson, Real-Time Collision Detection, §5.1.5).
fn closest_on_triangle(p: Vec3, [a, b, c]: [Vec3; 3]) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Whether segment `p`–`q` meets the open square (−1, 1)² (Liang–Barsky clipping).
fn segment_meets_square(p: Vec2, q: Vec2) -> bool {
    let d = q - p;
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for (pk, dk) in [(p.x, d.x), (p.y, d.y)] {
        for (num, den) in [(1.0 - pk, dk), (1.0 + pk, -dk)] {
            // Inside where num − den·t > 0.
            if den == 0.0 {
                if num <= 0.0 {
                    return false;
                }
            } else if den > 0.0 {
                t1 = t1.min(num / den);
            } else {
                t0 = t0.max(num / den);
            }
        }
    }
    t0 < t1
}

/// Shirley–Chiu concentric map from the unit square to the unit disc; it keeps strata compact,
/// so stratification survives the mapping.
pub fn concentric_disc(s: Vec2) -> Vec2 {
    let o = s * 2.0 - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, std::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (
            o.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y),
        )
    };
    Vec2::new(theta.cos(), theta.sin()) * r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The samples of one loop are [`Light::stratified_sample`]'s, sample by sample, to the bit,
    /// for every kind of light.
    #[test]
    fn the_samples_in_one_loop_are_the_samples_one_by_one() {
        let lights = [
            Light::Sphere {
                center: Vec3::new(0.3, 4.0, -0.2),
                radius: 0.7,
            },
            Light::Disc {
                center: Vec3::new(-1.0, 3.0, 0.5),
                normal: Vec3::new(0.2, -1.0, 0.1),
                radius: 0.4,
            },
            Light::Rect {
                center: Vec3::new(0.0, 2.5, 1.0),
                half_u: Vec3::new(0.5, 0.0, 0.1),
                half_v: Vec3::new(0.0, 0.1, 0.3),
            },
        ];
        let mut out = Vec::new();
        for light in lights {
            for k in [1, 3, 8, 11] {
                let p = Vec3::new(0.1 * k as f32, -0.5, 0.25);
                light.stratified_samples_into(p, k, 42 + u64::from(k), &mut out);
                assert_eq!(out.len(), (k * k) as usize);
                for (i, q) in (0..).zip(&out) {
                    let want = light.stratified_sample(p, i, k, 42 + u64::from(k));
                    assert_eq!(
                        q.to_array().map(f32::to_bits),
                        want.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }
}
