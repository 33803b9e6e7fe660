//! Rasterization of volume primitives (shadow quads, penumbra wedges) from the eye, for the
//! shadow-volume family (`soft_shadow_volume`, `accum_hard`).
//!
//! A fragment is a pixel whose eye ray meets a primitive; its depth test compares where the ray
//! meets the primitive with where it meets the visible surface (the frame's eye pass). Coverage
//! is decided exactly per pixel centre by intersecting the eye ray with the primitive, which is
//! what a rasterizer decides with edge functions; the depth comparison is the one a depth buffer
//! would make. Primitives are binned to screen tiles by a conservative footprint (sort-middle),
//! and each tile processes its primitives in submission order, so results and counters do not
//! depend on the host thread count.

use glam::Vec3;
use rayon::prelude::*;

use crate::frame::Frame;
use crate::scene::Bounds;

/// Bytes of one depth-buffer value read by a depth test.
pub const DEPTH_BYTES: u64 = 4;

/// The eye rays of a frame: one per pixel, through the visible surface point moved off its
/// surface by the frame's epsilon (the same point the reference shades).
pub struct EyeRays {
    pub width: u32,
    pub height: u32,
    pub eye: Vec3,
    /// Unit direction of each pixel's ray.
    pub dir: Vec<Vec3>,
    /// Distance along the ray to the shaded point; infinite for pixels without a surface.
    pub depth: Vec<f32>,
    /// The shaded point (meaningless where `depth` is infinite).
    pub point: Vec<Vec3>,
    /// Scene bounds, slightly enlarged: shadow primitives are cut there (the far end of the
    /// extruded quads and wedges).
    pub bounds: Bounds,
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    tan_x: f32,
    tan_y: f32,
}

/// A rectangle of pixels, `x0..x1` × `y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScreenRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl EyeRays {
    pub fn new(frame: &Frame) -> EyeRays {
        let g = &frame.gbuffer;
        let cam = frame.scene.camera;
        let (w, h) = (g.width, g.height);
        let mut dir = Vec::with_capacity(g.len());
        let mut depth = Vec::with_capacity(g.len());
        let mut point = Vec::with_capacity(g.len());
        for i in 0..g.len() {
            if g.is_hit(i) {
                let p = g.position[i] + g.normal[i] * frame.epsilon;
                let d = p - cam.eye;
                dir.push(d.normalize());
                depth.push(d.length());
                point.push(p);
            } else {
                dir.push(cam.ray_direction(i as u32 % w, i as u32 / w, w, h));
                depth.push(f32::INFINITY);
                point.push(Vec3::ZERO);
            }
        }
        let b = frame.scene.bounds();
        let pad = Vec3::splat(b.diagonal().max(1e-3) * 1e-3);
        let (right, up, forward) = cam.basis();
        let tan_y = (cam.fov_y_deg.to_radians() * 0.5).tan();
        EyeRays {
            width: w,
            height: h,
            eye: cam.eye,
            dir,
            depth,
            point,
            bounds: Bounds {
                min: b.min - pad,
                max: b.max + pad,
            },
            right,
            up,
            forward,
            tan_x: tan_y * w as f32 / h as f32,
            tan_y,
        }
    }

    pub fn len(&self) -> usize {
        self.dir.len()
    }

    pub fn is_empty(&self) -> bool {
        self.dir.is_empty()
    }

    pub fn is_hit(&self, i: usize) -> bool {
        self.depth[i].is_finite()
    }

    /// Pixels that the convex hull of `points` can cover (the whole screen when a point is
    /// behind the eye); `None` when it lies off screen.
    pub fn footprint(&self, points: &[Vec3]) -> Option<ScreenRect> {
        let (mut lo_x, mut lo_y, mut hi_x, mut hi_y) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for &p in points {
            let d = p - self.eye;
            let z = d.dot(self.forward);
            if z <= 1e-6 * d.length().max(1e-6) {
                return Some(self.full());
            }
            let sx = d.dot(self.right) / (z * self.tan_x);
            let sy = d.dot(self.up) / (z * self.tan_y);
            let px = (sx + 1.0) * 0.5 * self.width as f32;
            let py = (1.0 - sy) * 0.5 * self.height as f32;
            lo_x = lo_x.min(px);
            hi_x = hi_x.max(px);
            lo_y = lo_y.min(py);
            hi_y = hi_y.max(py);
        }
        // Pixel centres sit at +0.5; one pixel of margin keeps the bound conservative.
        let x0 = (lo_x - 1.0).floor().max(0.0);
        let y0 = (lo_y - 1.0).floor().max(0.0);
        let x1 = (hi_x + 1.0).ceil().min(self.width as f32);
        let y1 = (hi_y + 1.0).ceil().min(self.height as f32);
        (x0 < x1 && y0 < y1).then_some(ScreenRect {
            x0: x0 as u32,
            y0: y0 as u32,
            x1: x1 as u32,
            y1: y1 as u32,
        })
    }

    fn full(&self) -> ScreenRect {
        ScreenRect {
            x0: 0,
            y0: 0,
            x1: self.width,
            y1: self.height,
        }
    }

    /// Parameter interval of pixel `i`'s ray inside the enlarged scene bounds (slab test).
    pub fn bounds_interval(&self, i: usize) -> (f32, f32) {
        let (o, d) = (self.eye, self.dir[i]);
        let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
        for k in 0..3 {
            let inv = 1.0 / d[k];
            let (a, b) = (
                (self.bounds.min[k] - o[k]) * inv,
                (self.bounds.max[k] - o[k]) * inv,
            );
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        (t0, t1)
    }
}

/// The pixels of one screen tile and the state a pass keeps for them.
pub struct Tile<S> {
    pub rect: ScreenRect,
    pub state: S,
}

/// Runs a pass: bins `footprints` to `tile`×`tile` screen tiles, then for each tile (in parallel)
/// creates its state with `init` and calls `fragment(state, primitive, pixel)` for every pixel of
/// every primitive binned there, primitives in submission order, pixels in scan order.
/// Returns the tiles in scan order.
pub fn raster_pass<S: Send>(
    rays: &EyeRays,
    footprints: &[Option<ScreenRect>],
    tile: u32,
    init: impl Fn(ScreenRect) -> S + Sync,
    fragment: impl Fn(&mut S, usize, usize) + Sync,
) -> Vec<Tile<S>> {
    let tile = tile.max(1);
    let (tx, ty) = (rays.width.div_ceil(tile), rays.height.div_ceil(tile));
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); (tx * ty) as usize];
    for (k, f) in footprints.iter().enumerate() {
        let Some(f) = f else { continue };
        for by in f.y0 / tile..f.y1.div_ceil(tile) {
            for bx in f.x0 / tile..f.x1.div_ceil(tile) {
                bins[(by * tx + bx) as usize].push(k as u32);
            }
        }
    }
    bins.into_par_iter()
        .enumerate()
        .map(|(b, prims)| {
            let (bx, by) = (b as u32 % tx, b as u32 / tx);
            let rect = ScreenRect {
                x0: bx * tile,
                y0: by * tile,
                x1: ((bx + 1) * tile).min(rays.width),
                y1: ((by + 1) * tile).min(rays.height),
            };
            let mut state = init(rect);
            for &k in &prims {
                let f = footprints[k as usize].expect("binned primitives have a footprint");
                for y in rect.y0.max(f.y0)..rect.y1.min(f.y1) {
                    for x in rect.x0.max(f.x0)..rect.x1.min(f.x1) {
                        fragment(&mut state, k as usize, (y * rays.width + x) as usize);
                    }
                }
            }
            Tile { rect, state }
        })
        .collect()
}

/// A convex polyhedron as an intersection of half-spaces `n·y ≤ d`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConvexVolume {
    pub planes: Vec<(Vec3, f32)>,
}

impl ConvexVolume {
    pub fn contains(&self, y: Vec3) -> bool {
        self.planes.iter().all(|&(n, d)| n.dot(y) <= d)
    }

    /// The parameter interval `[t_in, t_out]` of the ray `o + t·d` inside the volume, if any.
    pub fn ray_interval(&self, o: Vec3, d: Vec3, mut t0: f32, mut t1: f32) -> Option<(f32, f32)> {
        for &(n, dist) in &self.planes {
            let nd = n.dot(d);
            let s = dist - n.dot(o);
            if nd.abs() < 1e-12 {
                if s < 0.0 {
                    return None;
                }
                continue;
            }
            let t = s / nd;
            if nd > 0.0 {
                t1 = t1.min(t);
            } else {
                t0 = t0.max(t);
            }
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }
}
