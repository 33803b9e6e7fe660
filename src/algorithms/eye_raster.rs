//! Rasterization of volume primitives (shadow quads, penumbra wedges) from the eye, for the
//! shadow-volume family (`soft_shadow_volume`, `accum_hard`).
//!
//! A fragment is a pixel whose eye ray meets a primitive; its depth test compares where the ray
//! meets the primitive with where it meets the visible surface (the frame's eye pass). Coverage
//! is decided exactly per pixel centre by intersecting the eye ray with the primitive, which is
//! what a rasterizer decides with edge functions; the depth comparison is the one a depth buffer
//! would make. Primitives are binned to screen tiles by a conservative footprint (sort-middle);
//! each tile is one task of a [`Machine`] step and processes its primitives in submission order,
//! in 16-lane blocks of 4×4 pixels, so results and counters do not depend on the host thread
//! count, and the same [`TilePass`] code is the `cpu-native` and the `cpu-model` execution.

use glam::Vec3;

use crate::frame::Frame;
use crate::model::raster::{self, Target, TileRect};
use crate::model::{BufferId, Lanes, Machine, Mask, Probe, TaskKernel, LANES};
use crate::scene::Bounds;

/// Bytes of one depth-buffer value read by a depth test.
pub const DEPTH_BYTES: u64 = 4;

/// The eye rays of a frame: one per pixel, through the visible surface point moved off its
/// surface (`GBuffer::shading_point`, the same point the reference shades).
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
                let p = g.shading_point(i);
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

/// Side of the pixel blocks a tile is processed in: 4×4 pixels are the 16 lanes of one vector.
pub const BLOCK: u32 = raster::BLOCK;

/// Scalar instructions per (primitive, tile): loading the bin entry and the footprint, and
/// clipping the footprint to the tile.
const PRIM_SETUP_OPS: u32 = 6;
/// Vector instructions per (primitive, block): pixel coordinates of the lanes and the four
/// footprint compares that form the block's mask.
const BLOCK_MASK_OPS: u32 = 2 + 4;

/// An eye-sized buffer in modelled memory, block-linear like the rasterizer's render targets: the
/// 16 pixels of a 4×4 block are consecutive, so a block of values up to 4 bytes is one line.
#[derive(Clone, Copy, Debug)]
pub struct EyeBuffer {
    pub id: BufferId,
    base: u64,
    /// Bytes per pixel.
    bytes: u32,
    blocks_x: u32,
}

impl EyeBuffer {
    /// Reserves buffer `name` of `bytes` per pixel for the frame's eye pixels.
    pub fn new(m: &mut Machine, rays: &EyeRays, name: &str, bytes: u32) -> EyeBuffer {
        let blocks_x = rays.width.div_ceil(BLOCK);
        let blocks = u64::from(blocks_x) * u64::from(rays.height.div_ceil(BLOCK));
        let (id, base) = m
            .memory
            .reserve(name, blocks * (LANES as u64) * u64::from(bytes));
        EyeBuffer {
            id,
            base,
            bytes,
            blocks_x,
        }
    }

    fn block_addr(&self, b: &Block) -> u64 {
        let index = u64::from(b.y / BLOCK * self.blocks_x + b.x / BLOCK);
        self.base + index * LANES as u64 * u64::from(self.bytes)
    }

    /// A masked vector load of the active lanes of block `b`.
    pub fn read<P: Probe>(&self, p: &mut P, b: &Block, mask: Mask) {
        if mask.any() {
            p.read(self.id, self.block_addr(b), mask.count() * self.bytes);
        }
    }

    /// A masked vector store to the active lanes of block `b`.
    pub fn write<P: Probe>(&self, p: &mut P, b: &Block, mask: Mask) {
        if mask.any() {
            p.write(self.id, self.block_addr(b), mask.count() * self.bytes);
        }
    }
}

/// One 4×4 block of pixels of a tile: lane `l` is pixel (x + l % 4, y + l / 4).
#[derive(Clone, Copy, Debug)]
pub struct Block {
    pub x: u32,
    pub y: u32,
    /// Pixel index (`y · width + x`) of each lane; meaningful on the lanes of `mask`.
    pub pixel: Lanes<u32>,
    pub mask: Mask,
}

impl Block {
    /// The lanes of the block at (x, y) whose pixels lie in `rect`.
    fn new(rays: &EyeRays, x: u32, y: u32, rect: &ScreenRect) -> Block {
        let mut pixel = [0u32; LANES];
        let mask = Mask::from_fn(|l| {
            let (px, py) = (x + l as u32 % BLOCK, y + l as u32 / BLOCK);
            pixel[l] = py * rays.width + px;
            px >= rect.x0 && px < rect.x1 && py >= rect.y0 && py < rect.y1
        });
        Block { x, y, pixel, mask }
    }

    /// Pixel (x, y) of lane `l`: `pixel[l]` as coordinates, without dividing by the width.
    #[inline]
    pub fn lane_xy(&self, l: usize) -> (u32, u32) {
        (self.x + l as u32 % BLOCK, self.y + l as u32 / BLOCK)
    }

    /// The blocks covering `rect` (aligned to the 4×4 grid), lanes restricted to `rect`.
    pub fn cover<'a>(rays: &'a EyeRays, rect: ScreenRect) -> impl Iterator<Item = Block> + 'a {
        let (bx0, by0) = (rect.x0 / BLOCK * BLOCK, rect.y0 / BLOCK * BLOCK);
        (by0..rect.y1).step_by(BLOCK as usize).flat_map(move |y| {
            (bx0..rect.x1)
                .step_by(BLOCK as usize)
                .map(move |x| Block::new(rays, x, y, &rect))
        })
    }
}

/// The work of a pass over eye tiles, written once for both CPU executions.
pub trait TilePass: Sync {
    type State: Send;
    /// The tile's state before any primitive (the probe sees the tile's setup, e.g. a clear).
    fn begin<P: Probe>(&self, p: &mut P, rect: ScreenRect) -> Self::State;
    /// Primitive `prim` on the lanes of `block` inside its footprint and the tile.
    fn block<P: Probe>(&self, p: &mut P, state: &mut Self::State, prim: usize, block: &Block);
}

/// The pixels of one screen tile and the state a pass keeps for them.
pub struct Tile<S> {
    pub rect: ScreenRect,
    pub state: S,
}

/// The `tile`×`tile` screen tiles of the eye view.
pub fn tiles(rays: &EyeRays, tile: u32) -> Target {
    Target {
        width: rays.width,
        height: rays.height,
        tile: tile.max(1),
    }
}

fn screen_rect(r: TileRect) -> ScreenRect {
    ScreenRect {
        x0: r.x0,
        y0: r.y0,
        x1: r.x1,
        y1: r.y1,
    }
}

fn intersect(a: &ScreenRect, b: &ScreenRect) -> Option<ScreenRect> {
    let r = ScreenRect {
        x0: a.x0.max(b.x0),
        y0: a.y0.max(b.y0),
        x1: a.x1.min(b.x1),
        y1: a.y1.min(b.y1),
    };
    (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
}

struct TileTask<'a, T> {
    rays: &'a EyeRays,
    footprints: &'a [Option<ScreenRect>],
    bins: &'a [Vec<u32>],
    tiles: Target,
    pass: &'a T,
}

impl<T: TilePass> TaskKernel for TileTask<'_, T> {
    type Out = Tile<T::State>;

    fn run<P: Probe>(&self, p: &mut P, t: usize) -> Self::Out {
        let rect = screen_rect(self.tiles.tile_rect(t));
        let mut state = self.pass.begin(p, rect);
        for &k in &self.bins[t] {
            p.scalar(PRIM_SETUP_OPS);
            let f = self.footprints[k as usize].expect("binned primitives have a footprint");
            let Some(r) = intersect(&rect, &f) else {
                continue;
            };
            for b in Block::cover(self.rays, r) {
                p.vector(BLOCK_MASK_OPS, Mask::ALL);
                self.pass.block(p, &mut state, k as usize, &b);
            }
        }
        Tile { rect, state }
    }
}

/// Runs a pass as step `step` of the machine's current phase: bins `footprints` to the screen
/// tiles (sort-middle), then runs one task per tile, which creates its state with
/// [`TilePass::begin`] and hands every 4×4 block of every primitive binned there to
/// [`TilePass::block`], primitives in submission order. Returns the tiles in scan order.
pub fn raster_pass<T: TilePass>(
    m: &mut Machine,
    step: &str,
    rays: &EyeRays,
    footprints: &[Option<ScreenRect>],
    tile: u32,
    pass: &T,
) -> Vec<Tile<T::State>> {
    let tiles = tiles(rays, tile);
    let (tile, tx) = (tiles.tile, tiles.tiles_x());
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); tiles.tiles()];
    // The scheduler's estimate: the fragments binned to the tile.
    let mut weights = vec![0u64; tiles.tiles()];
    for (k, f) in footprints.iter().enumerate() {
        let Some(f) = f else { continue };
        for by in f.y0 / tile..f.y1.div_ceil(tile) {
            for bx in f.x0 / tile..f.x1.div_ceil(tile) {
                let t = (by * tx + bx) as usize;
                bins[t].push(k as u32);
                if let Some(r) = intersect(&screen_rect(tiles.tile_rect(t)), f) {
                    weights[t] += u64::from((r.x1 - r.x0) * (r.y1 - r.y0));
                }
            }
        }
    }
    let task = TileTask {
        rays,
        footprints,
        bins: &bins,
        tiles,
        pass,
    };
    m.run_step(step, &task, &weights)
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
