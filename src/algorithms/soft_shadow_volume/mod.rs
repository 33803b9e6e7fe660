//! Soft shadow volumes with penumbra wedges (paper 001, Papers III and IV), the math once.
//!
//! Pass 1 renders the hard shadow quads of the silhouette seen from the light centre into the
//! V-buffer exactly as hard shadow volumes do ([`super::shadow_volume`]): z-pass from the eye's
//! count, or (option `counting: "z_fail"`, Paper II §5) z-fail over volumes closed by light and
//! dark caps. Pass 2 rasterizes one
//! penumbra wedge per silhouette edge ([`Wedge`]); for each point p inside a wedge it projects
//! the edge's hard shadow quad onto the light as seen from p, takes the fraction of the light the
//! projection covers ([`exact_coverage`] or the 4D [`CoverageTexture`]) and adds it on the inner
//! side of the quad, subtracts it on the outer side (III §3.2.2). Summed over a silhouette loop
//! this is Green's theorem: the visible fraction of the light.
//!
//! Textured and coloured lights (III §3.3, `light.texture` on a rectangular light): the 4D
//! texture's texels hold, per channel, the integral of the light's texture over the covered
//! part ([`CoverageTexture::build_textured`]), and the V-buffer holds one f32 per channel
//! (III §4.1): `mean·(1 − count) ± coverage`, the light received per channel. The frame's
//! scalar visibility is its luminance fraction
//! ([`crate::scene::LightTexture::visibility`]). Not built for textured lights (refused by
//! [`check_light_texture`]): exact clipping, the split 12-bit V-buffer, the overlap
//! approximation and light splitting; spherical textured lights (the paper did not try them).
//!
//! Light coordinates: the emitter seen from p is spanned by two half-axes from its centre
//! ([`crate::scene::Light::emitter_frame`]); a point of its plane is written in units of those
//! half-axes, so a rectangle is `[−1, 1]²` and a sphere's disc is the unit disc.

pub mod cpu;
pub mod raster;
mod wedges;
pub mod wgpu;

use std::collections::HashMap;

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::eye_raster::ConvexVolume;
pub use super::shadow_volume::{Counting, GpuPipeline};
use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, MethodLimit, WgpuEntry, WgpuParity,
    WorkEstimate,
};
use crate::algorithms::work;
use crate::error::InputError;
use crate::frame::{Frame, RunParams};
use crate::record::phases;
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};
pub(crate) use crate::scene::polygon::clip_half_plane;
use crate::scene::LightKind;
use crate::scene::{Light, LightTexture};
use crate::util::deadline::Deadline;

phases! {
    /// The phases of a `soft_shadow_volume` run, each resumed per sub-light and silhouette loop:
    /// the hard shadow quads (Paper II §3), the wedges built on the silhouette (§4), and the
    /// soft pass over the pixels the wedges cover (§5).
    pub enum Phase {
        Hard => "hard",
        Wedges => "wedges",
        Soft => "soft",
    }
}

/// The shape of the emitter in light coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitterShape {
    /// `[−1, 1]²`.
    Square,
    /// The unit disc.
    Disc,
}

impl EmitterShape {
    pub fn of(light: &Light) -> EmitterShape {
        match light {
            Light::Rect { .. } => EmitterShape::Square,
            Light::Sphere { .. } | Light::Disc { .. } => EmitterShape::Disc,
        }
    }

    /// Area in light coordinates.
    pub fn area(self) -> f32 {
        match self {
            EmitterShape::Square => 4.0,
            EmitterShape::Disc => std::f32::consts::PI,
        }
    }

    /// The part `[t0, t1]` of the segment `q0 + t·(q1 − q0)`, `t ∈ [0, 1]`, inside the emitter
    /// (III §3.3: the projected edge clipped against the light's border).
    pub fn clip(self, q0: Vec2, q1: Vec2) -> Option<(Vec2, Vec2)> {
        let d = q1 - q0;
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        // Clipped points are measured from the end nearer the centre: a projected end can be
        // very far away, and the clipped points must not drown in its magnitude.
        let (base, t_base) = if q0.length_squared() <= q1.length_squared() {
            (q0, 0.0)
        } else {
            (q1, 1.0)
        };
        match self {
            EmitterShape::Square => {
                // Liang–Barsky against |x| ≤ 1, |y| ≤ 1.
                for (p, q) in [
                    (-d.x, q0.x + 1.0),
                    (d.x, 1.0 - q0.x),
                    (-d.y, q0.y + 1.0),
                    (d.y, 1.0 - q0.y),
                ] {
                    if p == 0.0 {
                        if q < 0.0 {
                            return None;
                        }
                    } else if p < 0.0 {
                        t0 = t0.max(q / p);
                    } else {
                        t1 = t1.min(q / p);
                    }
                }
            }
            EmitterShape::Disc => {
                let len = d.length();
                if len < 1e-20 {
                    return (q0.length_squared() <= 1.0).then_some((q0, q1));
                }
                let u = d / len;
                let along = -base.dot(u);
                let closest = base + u * along;
                let h2 = 1.0 - closest.length_squared();
                if h2 < 0.0 {
                    return None;
                }
                let h = h2.sqrt();
                t0 = t0.max(t_base + (along - h) / len);
                t1 = t1.min(t_base + (along + h) / len);
            }
        }
        (t0 < t1).then(|| (base + d * (t0 - t_base), base + d * (t1 - t_base)))
    }
}

/// The emitter plane as seen from a point: centre, half-axes and unit normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    pub center: Vec3,
    pub half_u: Vec3,
    pub half_v: Vec3,
    pub normal: Vec3,
    pub shape: EmitterShape,
}

impl Emitter {
    pub fn seen_from(light: &Light, p: Vec3) -> Emitter {
        let (center, half_u, half_v) = light.emitter_frame(p);
        Emitter {
            center,
            half_u,
            half_v,
            normal: half_u.cross(half_v).normalize_or(Vec3::Y),
            shape: EmitterShape::of(light),
        }
    }

    /// Projects silhouette edge `a→b` from `p` onto the emitter plane, in light coordinates.
    /// The edge is first clipped to the half-space in front of p towards the light, then
    /// projected (IV §4.2.2: "clip the edge first and then project it; otherwise points behind
    /// the origin of the projection will be inverted"). `None` when nothing is in front of p.
    pub fn project_edge(&self, p: Vec3, a: Vec3, b: Vec3) -> Option<(Vec2, Vec2)> {
        let towards = self.normal * self.normal.dot(self.center - p).signum();
        let dist = towards.dot(self.center - p);
        if dist <= 0.0 {
            return None;
        }
        // Homogeneous w: the fraction of the way from p to the light plane.
        let (wa, wb) = (towards.dot(a - p) / dist, towards.dot(b - p) / dist);
        const W_MIN: f32 = 1e-4;
        if wa < W_MIN && wb < W_MIN {
            return None;
        }
        let clip = |w_in: f32, w_out: f32, x_in: Vec3, x_out: Vec3| {
            let t = (w_in - W_MIN) / (w_in - w_out);
            (x_in + (x_out - x_in) * t, W_MIN)
        };
        let ((a, wa), (b, wb)) = match (wa >= W_MIN, wb >= W_MIN) {
            (true, true) => ((a, wa), (b, wb)),
            (true, false) => ((a, wa), clip(wa, wb, a, b)),
            _ => (clip(wb, wa, b, a), (b, wb)),
        };
        let to_light = |x: Vec3, w: f32| {
            let r = p + (x - p) / w - self.center;
            Vec2::new(
                r.dot(self.half_u) / self.half_u.length_squared(),
                r.dot(self.half_v) / self.half_v.length_squared(),
            )
        };
        Some((to_light(a, wa), to_light(b, wb)))
    }
}

/// Coverage of the emitter by the projected hard shadow quad of an edge whose projection,
/// clipped to the emitter, is `q0q1` (both inside): the area between the rays from the light
/// centre through `q0` and `q1` beyond the segment, over the emitter's area. This is the area
/// inside the infinite sector minus the triangle (centre, q0, q1) (IV §4.2.2, Figure 6a),
/// computed by exact clipping (III §3.2.2) for a square and by the sector formula for a disc.
pub fn exact_coverage(shape: EmitterShape, q0: Vec2, q1: Vec2) -> f32 {
    let cross = q0.perp_dot(q1);
    let (q0, q1) = if cross >= 0.0 { (q0, q1) } else { (q1, q0) };
    let cross = cross.abs();
    if cross <= 0.0 {
        return 0.0;
    }
    let area = match shape {
        EmitterShape::Square => polygon_area(&covered_square(q0, q1)),
        EmitterShape::Disc => {
            let angle = cross.atan2(q0.dot(q1));
            0.5 * angle - 0.5 * cross
        }
    };
    (area / shape.area()).clamp(0.0, 1.0)
}

/// The part of the square light the projected quad of `q0q1` covers (`q0 × q1 ≥ 0`): the
/// square clipped by the sector's two rays and the segment's line (III §3.2.2).
fn covered_square(q0: Vec2, q1: Vec2) -> Vec<Vec2> {
    let mut poly = vec![
        Vec2::new(-1.0, -1.0),
        Vec2::new(1.0, -1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(-1.0, 1.0),
    ];
    poly = clip_half_plane(&poly, |x| q0.perp_dot(x));
    poly = clip_half_plane(&poly, |x| x.perp_dot(q1));
    clip_half_plane(&poly, |x| -(q1 - q0).perp_dot(x - q0))
}

/// [`exact_coverage`] of a square light weighted by its texture (Paper III §3.3): per channel,
/// `∫ T` over the covered part over the light's area, in [0, 1].
pub fn textured_coverage(light: &LightTexture, q0: Vec2, q1: Vec2) -> [f32; 3] {
    let cross = q0.perp_dot(q1);
    if cross == 0.0 {
        return [0.0; 3];
    }
    let (q0, q1) = if cross > 0.0 { (q0, q1) } else { (q1, q0) };
    light
        .integrate(&covered_square(q0, q1))
        .map(|v| (v / EmitterShape::Square.area()).clamp(0.0, 1.0))
}

/// Shoelace area of a convex polygon.
fn polygon_area(poly: &[Vec2]) -> f32 {
    let n = poly.len();
    (0..n)
        .map(|i| poly[i].perp_dot(poly[(i + 1) % n]))
        .sum::<f32>()
        .abs()
        * 0.5
}

/// The 4D coverage texture of III §3.3: `n×n` sub-textures of `n×n` texels, sub-texture
/// `(a, b)` holding the coverage for a first clipped end point at texel centre `(a, b)` and a
/// second end point at each texel centre, precomputed by exact clipping and stored in 8 bits.
/// For a textured light (§3.3, "the sum of the red components that the corresponding projected
/// quad covers") each texel holds three such values, one per channel, each the integral of the
/// light's texture over the covered part ([`textured_coverage`]); the light texture is first
/// box-filtered to at most `n×n` texels, as the paper undersamples its fire texture.
#[derive(Clone, Debug, PartialEq)]
pub struct CoverageTexture {
    pub n: u32,
    pub shape: EmitterShape,
    /// 1 (uniform white light) or 3 (r, g, b of a textured light).
    pub channels: u32,
    /// [`LightTexture::hash`] of the light texture it integrates.
    pub light: Option<u64>,
    /// `n²×n²` texels of `channels` bytes, row-major: texel `(a·n + i, b·n + j)` at index
    /// `(b·n + j)·n² + a·n + i`, its channels at `channels·index + c`.
    pub texels: Vec<u8>,
}

impl CoverageTexture {
    pub fn build(shape: EmitterShape, n: u32) -> CoverageTexture {
        let side = (n * n) as usize;
        let texels = (0..side * side)
            .map(|k| {
                let (q0, q1) = Self::end_points(n, k);
                let c = shape
                    .clip(q0, q1)
                    .map_or(0.0, |(c0, c1)| exact_coverage(shape, c0, c1));
                (c * 255.0).round() as u8
            })
            .collect();
        CoverageTexture {
            n,
            shape,
            channels: 1,
            light: None,
            texels,
        }
    }

    /// The RGB coverage texture of a square light with texture `light`.
    pub fn build_textured(light: &LightTexture, n: u32) -> CoverageTexture {
        Self::build_textured_until(light, n, Deadline::default())
    }

    /// [`Self::build_textured`] within a run's budget: `deadline` is checked after the light
    /// texture is filtered and before each texel; past it the build unwinds with
    /// [`crate::util::deadline::Cancelled`].
    pub fn build_textured_until(
        light: &LightTexture,
        n: u32,
        deadline: Deadline,
    ) -> CoverageTexture {
        use rayon::prelude::*;
        let shape = EmitterShape::Square;
        let filtered = light.resampled(n);
        let side = (n * n) as usize;
        let texels = (0..side * side)
            .into_par_iter()
            .flat_map_iter(|k| {
                deadline.check();
                let (q0, q1) = Self::end_points(n, k);
                let c = shape
                    .clip(q0, q1)
                    .map_or([0.0; 3], |(c0, c1)| textured_coverage(&filtered, c0, c1));
                c.map(|v| (v * 255.0).round() as u8)
            })
            .collect();
        CoverageTexture {
            n,
            shape,
            channels: 3,
            light: Some(light.hash()),
            texels,
        }
    }

    /// The two end points texel `k` stands for.
    fn end_points(n: u32, k: usize) -> (Vec2, Vec2) {
        let side = (n * n) as usize;
        let (tx, ty) = ((k % side) as u32, (k / side) as u32);
        (
            Self::centre(n, tx / n, ty / n),
            Self::centre(n, tx % n, ty % n),
        )
    }

    /// Light coordinate of texel centre `(i, j)`.
    fn centre(n: u32, i: u32, j: u32) -> Vec2 {
        Vec2::new(
            -1.0 + (2 * i + 1) as f32 / n as f32,
            -1.0 + (2 * j + 1) as f32 / n as f32,
        )
    }

    /// Texel position (continuous) of a light coordinate.
    fn texel_pos(&self, q: Vec2) -> Vec2 {
        ((q + Vec2::ONE) * 0.5 * self.n as f32 - Vec2::splat(0.5))
            .clamp(Vec2::ZERO, Vec2::splat((self.n - 1) as f32))
    }

    fn index(&self, a: u32, b: u32, i: u32, j: u32) -> u32 {
        let side = self.n * self.n;
        (b * self.n + j) * side + a * self.n + i
    }

    /// Coverage of the clipped projected edge `q0q1`: the sub-texture of the texel centre
    /// nearest `q0`, read bilinearly at `q1` (III §3.3). Four texel reads of one byte.
    pub fn lookup(&self, q0: Vec2, q1: Vec2) -> f32 {
        self.lookup_texels(q0, q1).0[0]
    }

    /// [`Self::lookup`] per channel (the one channel of an untextured light repeated) and the
    /// indices of the four texels it reads (bytes `channels·index ..`).
    pub fn lookup_texels(&self, q0: Vec2, q1: Vec2) -> ([f32; 3], [u32; 4]) {
        let s = self.texel_pos(q0).round();
        let (a, b) = (s.x as u32, s.y as u32);
        let t = self.texel_pos(q1);
        let (i0, j0) = (t.x.floor() as u32, t.y.floor() as u32);
        let (i1, j1) = ((i0 + 1).min(self.n - 1), (j0 + 1).min(self.n - 1));
        let f = t - Vec2::new(i0 as f32, j0 as f32);
        let index = [(i0, j0), (i1, j0), (i0, j1), (i1, j1)].map(|(i, j)| self.index(a, b, i, j));
        let channel = |c: u32| {
            let [t00, t10, t01, t11] =
                index.map(|k| self.texels[(k * self.channels + c) as usize] as f32 / 255.0);
            let top = t00 * (1.0 - f.x) + t10 * f.x;
            let bottom = t01 * (1.0 - f.x) + t11 * f.x;
            top * (1.0 - f.y) + bottom * f.y
        };
        let c = if self.channels == 3 {
            [channel(0), channel(1), channel(2)]
        } else {
            [channel(0); 3]
        };
        (c, index)
    }

    /// Texture reads per lookup (bilinear).
    pub const READS: u64 = 4;

    pub fn bytes(&self) -> u64 {
        self.texels.len() as u64
    }
}

/// A penumbra wedge: a convex volume that encloses the penumbra volume of one silhouette edge
/// (III §3.1, IV §4.1), with the points whose hull bounds it on screen.
#[derive(Clone, Debug, PartialEq)]
pub struct Wedge {
    pub volume: ConvexVolume,
    /// The wedge's top edge and its far corners at distance `reach`.
    pub hull: Vec<Vec3>,
}

/// The edge with its vertex farther from the light centre moved towards the centre to the
/// distance of the other (III §3.1, Figure 5a): the top edge of the wedge.
pub fn wedge_top_edge(a: Vec3, b: Vec3, light_centre: Vec3) -> (Vec3, Vec3) {
    let (da, db) = ((a - light_centre).length(), (b - light_centre).length());
    if da > db {
        (light_centre + (a - light_centre) * (db / da), b)
    } else {
        (a, light_centre + (b - light_centre) * (da / db))
    }
}

/// A plane through `x` containing direction `dir`, tangent to the sphere (`centre`, `radius`),
/// with the sphere on its positive side; of the two, the one whose normal has a positive
/// component along `lean` (orthogonal to `dir`). Its negative side contains the light reflected
/// through `x`. `None` when `x` lies inside the sphere's tangent cone.
fn tangent_plane(x: Vec3, dir: Vec3, centre: Vec3, radius: f32, lean: Vec3) -> Option<Vec3> {
    let d = dir.normalize_or_zero();
    let m = centre - x;
    let m_perp = m - d * m.dot(d);
    let h = m_perp.length();
    if h <= radius || d == Vec3::ZERO {
        return None;
    }
    let u = m_perp / h;
    let v = d.cross(u);
    let alpha = radius / h;
    let beta = (1.0 - alpha * alpha).sqrt();
    let sign = if v.dot(lean) >= 0.0 { 1.0 } else { -1.0 };
    Some(u * alpha + v * (beta * sign))
}

impl Wedge {
    /// The robust wedge of III §3.1 around a spherical light (or the bounding sphere of a
    /// rectangle): front and back planes through the top edge tangent to the sphere on either
    /// side, and left and right planes through each top-edge vertex containing the direction
    /// perpendicular to the edge and to the light centre, tangent to the sphere on the far side.
    pub fn robust(a: Vec3, b: Vec3, centre: Vec3, radius: f32, reach: f32) -> Option<Wedge> {
        let (x0, x1) = wedge_top_edge(a, b, centre);
        let d = x1 - x0;
        let m = centre - x0;
        let across = d.cross(m);
        let front = tangent_plane(x0, d, centre, radius, across)?;
        let back = tangent_plane(x0, d, centre, radius, -across)?;
        let mut planes = vec![(front, front.dot(x0)), (back, back.dot(x0))];
        let mut hull = vec![x0, x1];
        for (x, other) in [(x0, x1), (x1, x0)] {
            let w = d.cross(centre - x);
            let side = tangent_plane(x, w, centre, radius, x - other)?;
            planes.push((side, side.dot(x)));
            for fb in [front, back] {
                let dir = fb.cross(side).normalize_or_zero();
                let dir = if dir.dot(x - centre) >= 0.0 {
                    dir
                } else {
                    -dir
                };
                hull.push(x + dir * reach);
            }
        }
        Some(Wedge {
            volume: ConvexVolume { planes },
            hull,
        })
    }

    /// The tighter wedge of IV §4.1 for a rectangular light: the convex hull of the two
    /// pyramids formed by reflecting the rectangle through the top-edge vertices (their outer
    /// triangles close the sides), between front and back planes through the top edge that
    /// touch the rectangle.
    pub fn tight_rect(a: Vec3, b: Vec3, corners: [Vec3; 4], reach: f32) -> Option<Wedge> {
        let centre = corners.iter().sum::<Vec3>() / 4.0;
        let (x0, x1) = wedge_top_edge(a, b, centre);
        let d = x1 - x0;
        let rays: Vec<Vec3> = [x0, x1]
            .iter()
            .flat_map(|&x| corners.map(|c| (x - c).normalize_or_zero()))
            .collect();
        // Facets of segment + cone(rays) are spanned by the edge and one ray, or by two rays.
        let mut candidates: Vec<Vec3> = rays.iter().map(|r| d.cross(*r)).collect();
        for i in 0..rays.len() {
            for j in i + 1..rays.len() {
                candidates.push(rays[i].cross(rays[j]));
            }
        }
        let mut planes: Vec<(Vec3, f32)> = Vec::new();
        for c in candidates {
            let len = c.length();
            if len < 1e-6 {
                continue;
            }
            for n in [c / len, -c / len] {
                if rays.iter().all(|r| n.dot(*r) <= 1e-6) {
                    let dist = n.dot(x0).max(n.dot(x1));
                    if !planes
                        .iter()
                        .any(|(m, e)| m.dot(n) > 1.0 - 1e-6 && (e - dist).abs() < 1e-6)
                    {
                        planes.push((n, dist));
                    }
                }
            }
        }
        if planes.len() < 4 {
            // The edge meets the light's plane: the wedge would be a half-space (IV §4.1).
            return None;
        }
        let mut hull = vec![x0, x1];
        hull.extend(
            rays.iter()
                .enumerate()
                .map(|(k, r)| if k < 4 { x0 } else { x1 } + *r * reach),
        );
        Some(Wedge {
            volume: ConvexVolume { planes },
            hull,
        })
    }
}

/// The 12-bit V-buffer split across the four 8-bit channels of an rgba buffer (IV §4.3): each
/// channel holds 3 bits of the value in its low bits and keeps its upper 5 bits for carries, so
/// up to 32 overlapping contributions add without overflow under ordinary 8-bit additive
/// blending.
pub mod split12 {
    /// Bits of the coverage value.
    pub const BITS: u32 = 12;
    /// Value bits per channel.
    pub const DIGIT_BITS: u32 = 3;
    pub const MAX: u32 = (1 << BITS) - 1;

    /// Quantizes a coverage in [0, 1] to 12 bits and splits it into four 3-bit digits,
    /// least significant first (the per-channel values a shader outputs).
    pub fn split(coverage: f32) -> [u8; 4] {
        let q = (coverage.clamp(0.0, 1.0) * MAX as f32).round() as u32;
        std::array::from_fn(|k| ((q >> (DIGIT_BITS * k as u32)) & 0b111) as u8)
    }

    /// Additive blending into an 8-bit-per-channel buffer: saturates at 255 per channel.
    pub fn blend(rgba: [u8; 4], digits: [u8; 4]) -> [u8; 4] {
        std::array::from_fn(|k| rgba[k].saturating_add(digits[k]))
    }

    /// The accumulated value: each channel weighted by its digit position, carries included.
    pub fn value(rgba: [u8; 4]) -> f32 {
        let sum: u32 = (0..4)
            .map(|k| (rgba[k] as u32) << (DIGIT_BITS * k as u32))
            .sum();
        sum as f32 / MAX as f32
    }
}

/// Combines the shadow coverage of two silhouette loops whose overlap on the light is unknown
/// (IV §5.1, eq. 1): `max(cA, cB) + ½·min(cA, cB)`, clamped to full coverage.
pub fn overlap_coverage(ca: f32, cb: f32) -> f32 {
    (ca.max(cb) + 0.5 * ca.min(cb)).min(1.0)
}

/// Splits silhouette edges into loops: groups of edges connected through shared vertices
/// (IV §5.1; every silhouette vertex joins an even number of silhouette edges).
pub fn silhouette_loops(edges: &[SilhouetteEdge]) -> Vec<Vec<SilhouetteEdge>> {
    let mut parent: Vec<usize> = (0..edges.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut first_at: HashMap<u32, usize> = HashMap::new();
    for (k, e) in edges.iter().enumerate() {
        for v in e.v {
            match first_at.get(&v) {
                Some(&j) => {
                    let (ra, rb) = (root(&mut parent, k), root(&mut parent, j));
                    parent[ra.max(rb)] = ra.min(rb);
                }
                None => {
                    first_at.insert(v, k);
                }
            }
        }
    }
    let mut loops: Vec<Vec<SilhouetteEdge>> = Vec::new();
    let mut index: HashMap<usize, usize> = HashMap::new();
    for (k, e) in edges.iter().enumerate() {
        let r = root(&mut parent, k);
        let l = *index.entry(r).or_insert_with(|| {
            loops.push(Vec::new());
            loops.len() - 1
        });
        loops[l].push(*e);
    }
    loops
}

/// One sub-light's silhouette seen from its centre split into loops (IV §5.1; one loop of
/// every edge without the overlap approximation), as every execution walks them.
pub struct SubLightLoops {
    /// The silhouette's size.
    pub silhouette_edges: usize,
    pub loops: Vec<Vec<SilhouetteEdge>>,
    /// The count the hard pass starts from at the eye ([`Counting::eye_start`]).
    pub eye: i32,
    /// Why per-loop V-buffers start at 0 though the eye is inside a volume, when they do.
    pub warning: Option<String>,
}

impl SubLightLoops {
    /// The loops of the silhouette of `occluders` (their `adjacency`) from light point
    /// `centre`, for an eye at `eye`.
    pub fn new(
        adjacency: &EdgeAdjacency,
        occluders: &crate::scene::Mesh,
        centre: Vec3,
        eye: Vec3,
        opts: &SoftShadowVolumeOptions,
    ) -> SubLightLoops {
        let edges = adjacency.silhouette_from(centre).edges;
        let eye = opts.counting.eye_start(occluders, centre, eye);
        let loops = match opts.overlap_approximation {
            true => silhouette_loops(&edges),
            false => vec![edges.clone()],
        };
        let warning = (loops.len() > 1 && eye != 0).then(|| {
            format!(
                "the eye is inside {eye} shadow volume(s); per-loop V-buffers of the overlap \
                 approximation start at 0"
            )
        });
        SubLightLoops {
            silhouette_edges: edges.len(),
            loops,
            eye,
            warning,
        }
    }
}

/// The sub-lights of light splitting (IV §5.2): a rectangle cut into `k×k` equal rectangles;
/// `k = 1` keeps any light whole.
///
/// Errors: `k > 1` with a light that is not a rectangle ([`crate::error::Error::Unsupported`]).
pub fn split_light(light: &Light, k: u32) -> crate::error::Result<Vec<Light>> {
    match *light {
        Light::Rect {
            center,
            half_u,
            half_v,
        } => {
            let (hu, hv) = (half_u / k as f32, half_v / k as f32);
            Ok((0..k * k)
                .map(|i| {
                    let (a, b) = ((i % k) as f32, (i / k) as f32);
                    let off = (2.0 * a + 1.0 - k as f32) * hu + (2.0 * b + 1.0 - k as f32) * hv;
                    Light::Rect {
                        center: center + off,
                        half_u: hu,
                        half_v: hv,
                    }
                })
                .collect())
        }
        _ if k == 1 => Ok(vec![*light]),
        _ => Err(crate::error::Error::Unsupported(format!(
            "{ID}: light splitting (light_split = {k}) needs a rectangular light, got {}",
            light.kind()
        ))),
    }
}

/// How pass 2 computes coverage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CoverageMethod {
    /// Exact clipping of the projected quad against the light (III §3.2.2).
    #[default]
    ExactClipping,
    /// The precomputed 4D coverage texture (III §3.3).
    Texture,
}

/// Number format of the V-buffer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VBufferPrecision {
    /// One 32-bit float per pixel (III §4.1).
    #[default]
    F32,
    /// Hard pass in an 8-bit stencil; soft pass into an additive and a subtractive rgba8
    /// buffer with the 12-bit split and carry bits (IV §4.3).
    Split12,
}

/// n of the default 4D coverage texture (III §3.3: 32×32 sub-textures of 32×32 texels).
pub const DEFAULT_TEXTURE_N: u32 = 32;

/// Options of `soft_shadow_volume` (scenario `options.soft_shadow_volume`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SoftShadowVolumeOptions {
    pub coverage: CoverageMethod,
    /// n of the n×n sub-textures of n×n texels (III §3.3).
    pub texture_n: u32,
    /// Tighter wedges for rectangular lights (IV §4.1); off: wedges around the light's
    /// bounding sphere (III §3.1).
    pub tighter_wedges: bool,
    /// Wedge-half culling with depth and stencil tests (IV §4.4).
    pub wedge_culling: bool,
    pub vbuffer: VBufferPrecision,
    /// Per silhouette loop V-buffers merged by eq. 1 (IV §5.1).
    pub overlap_approximation: bool,
    /// Split a rectangular light into k×k sub-lights (IV §5.2); 1 = no splitting.
    pub light_split: u32,
    /// Pass 1's counting (III §3.2.1 with z-pass, Paper II §5 z-fail with capped volumes).
    pub counting: Counting,
    /// The GPU pipeline of the `wgpu` execution ([`GpuPipeline`]): `"raster"` (default) or
    /// `"gather"`; the cpu executions ignore it. The run's `execution.gpu_pipeline` records
    /// which one ran.
    pub gpu_pipeline: GpuPipeline,
}

impl Default for SoftShadowVolumeOptions {
    fn default() -> Self {
        SoftShadowVolumeOptions {
            coverage: CoverageMethod::default(),
            texture_n: DEFAULT_TEXTURE_N,
            tighter_wedges: true,
            wedge_culling: true,
            vbuffer: VBufferPrecision::default(),
            overlap_approximation: false,
            light_split: 1,
            counting: Counting::ZPass,
            gpu_pipeline: GpuPipeline::Raster,
        }
    }
}

pub const ID: &str = "soft_shadow_volume";

impl AlgorithmOptions for SoftShadowVolumeOptions {
    fn validate(&self) -> Result<(), InputError> {
        let field = |name: &str| format!("$.options.{ID}.{name}");
        InputError::check_range(field("texture_n"), self.texture_n, 2..=64)?;
        InputError::check_range(field("light_split"), self.light_split, 1..=3)?;
        if self.counting == Counting::ZFail && self.overlap_approximation {
            return Err(InputError::new(
                field("counting"),
                "\"z_fail\" cannot be combined with overlap_approximation: the caps of each \
                 silhouette loop's volume are not built",
            ));
        }
        Ok(())
    }
}

/// A textured light needs the 4D coverage texture (Paper III §3.3: it is what makes textured
/// lights possible) in the f32 V-buffer (III §4.1: "one float per r, g, and b"; the 8-bit
/// version holds intensity only), one silhouette loop and one light: the overlap approximation
/// and light splitting are not built for textured lights.
pub fn check_light_texture(o: &SoftShadowVolumeOptions) -> Result<(), InputError> {
    let refuse = |field: &str, got: String, why: &str| {
        Err(InputError::new(
            format!("$.options.{ID}.{field}"),
            format!("with a textured light ($.light.texture) {why}, got {got}"),
        ))
    };
    if o.coverage != CoverageMethod::Texture {
        return refuse(
            "coverage",
            serde_json::json!(o.coverage).to_string(),
            "the coverage must be \"texture\" (the 4D coverage texture integrates the light's \
             texture; exact clipping is not built for textured lights)",
        );
    }
    if o.vbuffer != VBufferPrecision::F32 {
        return refuse(
            "vbuffer",
            serde_json::json!(o.vbuffer).to_string(),
            "the V-buffer must be \"f32\" (one float per r, g, b)",
        );
    }
    if o.overlap_approximation {
        return refuse(
            "overlap_approximation",
            "true".into(),
            "the overlap approximation is not built",
        );
    }
    if o.light_split != 1 {
        return refuse(
            "light_split",
            o.light_split.to_string(),
            "light splitting is not built (light_split must be 1)",
        );
    }
    Ok(())
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct SoftShadowVolume;

/// Soft shadow volumes: hard shadow quads and penumbra wedges over the image, per pixel they
/// cover.
pub fn work_estimate(
    scene: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    _: &SoftShadowVolumeOptions,
) -> f64 {
    2.0 * work::pixels(p) + work::outline(scene, p.image[0].max(p.image[1]))
}

impl Algorithm for SoftShadowVolume {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "001 Papers III and IV";
    const SUMMARY: &'static str =
        "hard shadow quads plus penumbra wedges adding or subtracting light coverage";
    const LIGHTS: &'static [LightKind] = &[LightKind::Rect, LightKind::Sphere];
    const LIMITS: &'static [MethodLimit] = &[MethodLimit::AvertedNonOccludersLit];
    type Options = SoftShadowVolumeOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] = &[
        r#"{"coverage": "texture", "vbuffer": "split12"}"#,
        r#"{"wedge_culling": false, "tighter_wedges": false}"#,
        r#"{"light_split": 2, "overlap_approximation": true}"#,
        r#"{"counting": "z_fail"}"#,
        r#"{"gpu_pipeline": "gather"}"#,
        r#"{"coverage": "texture", "vbuffer": "split12", "gpu_pipeline": "gather"}"#,
        r#"{"wedge_culling": false, "tighter_wedges": false, "gpu_pipeline": "gather"}"#,
        r#"{"light_split": 2, "overlap_approximation": true, "gpu_pipeline": "gather"}"#,
        r#"{"counting": "z_fail", "gpu_pipeline": "gather"}"#,
    ];
    /// The raster pipeline decides which faces and wedge primitives cover a pixel at its
    /// centre (the rasterizer's tie rule) where the cpu casts the ray through the shaded point,
    /// and blends in rasterization order (`raster`, `shadow_volume::raster`): measured on
    /// lavapipe over the registry's scenes and option sets (48×36; z-pass, z-fail, culling on
    /// and off, split V-buffer with the 4D texture, light splitting with the overlap
    /// approximation): MAE under 1e-4, largest difference 0.12 on one pixel of the culled
    /// halves on torus-on-plane (0 without the culling), at most 0.15% of the pixels
    /// differing (before the depth tests moved into the fragment shaders: 0.07–0.51% over 0.1
    /// along the occluders' terminators); the hard pass's fill and overdraw within 2
    /// fragments; the wedge pass's counters (from the instrumented replay of its draws) differ
    /// where the rasterizer's coverage of a front face and the cpu's ray–primitive interval
    /// disagree on a grazing ray: measured at 64×48 on sphere-on-plane, fill 9469 against 9489
    /// (0.2%), shader invocations 2079 against 2082. The gather: MAE under 1e-9, counters
    /// equal. Bounds: MAE 2.5e-4, largest difference 0.15, 0.2% over 0.1 and 0.5% differing,
    /// fill, overdraw, shader invocations, culled fragments and fragments inside wedges within
    /// 3% of the fill.
    const WGPU_PARITY: WgpuParity = WgpuParity {
        mae: 2.5e-4,
        max: 0.15,
        frac_over_0_1: 0.002,
        frac_differing: 0.005,
        differ: &[
            ("fill", Some(0.03)),
            ("overdraw", Some(0.03)),
            ("shader_invocations", Some(0.03)),
            ("culled_fragments", Some(0.03)),
            ("fragments_inside_wedges", Some(0.03)),
        ],
    };
    const CPU: CpuEntry<SoftShadowVolumeOptions> = cpu::render;
    const WGPU: Option<WgpuEntry<SoftShadowVolumeOptions>> = Some(wgpu::render);

    fn light_texture(o: &SoftShadowVolumeOptions) -> Result<(), InputError> {
        check_light_texture(o)
    }

    fn prepare(frame: &Frame, o: &mut SoftShadowVolumeOptions) -> Option<String> {
        super::shadow_volume::zfail_fallback(ID, frame, &mut o.counting)
    }
}

#[cfg(test)]
mod tests;

/// Bytes of the eye-sized buffers (V-buffer, stencil, per-loop buffers of the overlap
/// approximation counted once) and the default 4D coverage texture (n⁴ 8-bit texels), estimated
/// before anything is allocated, for the harness's memory limit. A textured light's RGB
/// texture and V-buffer (three times these) are not in the estimate: it sees only the
/// run's parameters.
pub fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
    let pixels = u64::from(p.image[0]) * u64::from(p.image[1]);
    let n = u64::from(DEFAULT_TEXTURE_N);
    pixels * (4 + 1 + 4) + n.pow(4)
}
