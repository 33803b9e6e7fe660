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

    /// The light size: radius, or half-width of a rectangle.
    pub fn size(&self) -> f32 {
        match *self {
            Light::Sphere { radius, .. } | Light::Disc { radius, .. } => radius,
            Light::Rect { half_u, .. } => half_u.length(),
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

    /// Sample `i` of a stratified set of `k`×`k` samples on the light seen from `p`, jittered by
    /// the deterministic stream `seed`.
    pub fn stratified_sample(&self, p: Vec3, i: u32, k: u32, seed: u64) -> Vec3 {
        let (c, u, v) = self.emitter_frame(p);
        let d = self.stratified_coords(i, k, seed);
        c + u * d.x + v * d.y
    }

    /// [`Self::stratified_sample`] in light coordinates: units of the half-axes from the centre
    /// (`[−1, 1]²` for a rectangle, the unit disc otherwise), where a light texture is indexed.
    pub fn stratified_coords(&self, i: u32, k: u32, seed: u64) -> Vec2 {
        let jitter = unit_pair(seed, i as u64);
        let s = Vec2::new(
            ((i % k) as f32 + jitter.x) / k as f32,
            ((i / k) as f32 + jitter.y) / k as f32,
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
