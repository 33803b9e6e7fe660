//! The sort-middle binned software rasterizer of the Larrabee pipeline (004 §4.1, after Seiler
//! et al. 2008): a *front end* transforms, clips and sets up triangles and bins each into the
//! screen tiles its bounding box overlaps; after a barrier, a *back end* rasterizes bin by bin,
//! one tile per task, so each tile's depth and colour stay in one core's cache.
//!
//! Within a tile, a triangle is first tested against the whole tile, then against each 4×4 block
//! (hierarchical rejection: a rect is rejected when one edge function is negative at its most
//! inside corner); surviving blocks are covered lane by lane, 16 pixels to a 16-lane vector.
//! A per-block maximum depth rejects whole blocks before the per-pixel depth test (early
//! rejection); the per-pixel depth test runs before the fragment kernel (early depth).
//!
//! The fragment kernel is the hook soft-shadow algorithms plug into ([`FragmentKernel`]): it
//! receives the surviving lanes of a block with depth and barycentric weights, may keep private
//! per-tile state (sample lists, accumulators) and returns a value per lane and the lanes to
//! write. The rasterizer writes the lanes to the colour target with the pipeline's [`Blend`]
//! (replace, add for coverage accumulation and counters, min or max) and to the depth buffer.
//!
//! Render targets are stored block-linear (each 4×4 block of 32-bit values is one 64-byte cache
//! line), as a tiled renderer stores them; [`Surface::index`] is the one place that layout lives.

use glam::{Mat4, Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::buffer::{Buffer, Memory};
use super::simd::{Lanes, Mask, Probe, LANES};
use super::{Machine, TaskKernel};
use crate::counters::names;
use crate::scene::coverage;

/// Side of a block in pixels: a 4×4 block is one 16-lane vector.
pub const BLOCK: u32 = 4;

/// Triangles per front-end task.
pub const CHUNK: usize = 256;

/// A 2D array of 32-bit values in modelled memory, block-linear.
#[derive(Clone, Debug)]
pub struct Surface {
    pub width: u32,
    pub height: u32,
    pub blocks_x: u32,
    pub buf: Buffer<f32>,
}

impl Surface {
    pub fn new(memory: &mut Memory, name: &str, width: u32, height: u32, clear: f32) -> Surface {
        let blocks_x = width.div_ceil(BLOCK);
        let blocks_y = height.div_ceil(BLOCK);
        let n = (blocks_x * blocks_y) as usize * LANES;
        Surface {
            width,
            height,
            blocks_x,
            buf: memory.buffer(name, vec![clear; n]),
        }
    }

    /// Element index of pixel (x, y).
    #[inline]
    pub fn index(&self, x: u32, y: u32) -> usize {
        let block = (y / BLOCK) * self.blocks_x + x / BLOCK;
        (block * BLOCK * BLOCK + (y % BLOCK) * BLOCK + x % BLOCK) as usize
    }

    /// Element index of the first pixel of block (bx, by).
    pub fn block_index(&self, bx: u32, by: u32) -> usize {
        ((by * self.blocks_x + bx) * BLOCK * BLOCK) as usize
    }

    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.buf.data[self.index(x, y)]
    }
}

/// Which triangles are dropped by orientation (counter-clockwise in NDC is front).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cull {
    None,
    Back,
    Front,
}

/// Which pixels a triangle covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coverage {
    /// Pixel centres inside the triangle, with the top-left rule on edges.
    Center,
    /// Every pixel the triangle touches at all (wedges, penumbra quads, irregular rasterization
    /// against per-pixel sample lists).
    Conservative,
}

/// How kernel values combine with the colour target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blend {
    Replace,
    /// Coverage accumulation, stencil-like counters (add ±1).
    Add,
    /// Add into a half-float target (paper 002, Appendix A): the source and each sum rounded to
    /// IEEE half precision as the given rounding says (how a GPU's blend into R16Float rounds is
    /// the implementation's choice: [`HalfRounding`]).
    AddHalf(HalfRounding),
    /// Penumbra maps keep the darkest value.
    Min,
    Max,
}

impl Blend {
    /// The target's new value from its `old` value and the kernel's `new` one.
    pub fn apply(self, old: f32, new: f32) -> f32 {
        match self {
            Blend::Replace => new,
            Blend::Add => old + new,
            Blend::AddHalf(r) => r.round(old + r.round(new)),
            Blend::Min => old.min(new),
            Blend::Max => old.max(new),
        }
    }
}

/// How a sum is rounded to IEEE half precision when it is blended into a half-float target.
/// Vulkan leaves it to the implementation: Mesa's llvmpipe rounds toward zero, NVIDIA's driver
/// to nearest (measured by `Gpu::half_blend_sums`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HalfRounding {
    /// Toward zero (truncation of the magnitude).
    #[default]
    TowardZero,
    /// To the nearest half, ties to even (IEEE 754's default).
    NearestEven,
}

impl HalfRounding {
    /// The name in options and records.
    pub fn name(self) -> &'static str {
        match self {
            HalfRounding::TowardZero => "toward_zero",
            HalfRounding::NearestEven => "nearest_even",
        }
    }

    /// `x` rounded to IEEE half precision.
    pub fn round(self, x: f32) -> f32 {
        let h = half::f16::from_f32(x);
        match self {
            HalfRounding::NearestEven => h.to_f32(),
            HalfRounding::TowardZero if h.to_f32().abs() > x.abs() => {
                half::f16::from_bits(h.to_bits() - 1).to_f32()
            }
            HalfRounding::TowardZero => h.to_f32(),
        }
    }

    /// The rounding that stores `1 + ¾ ulp` and `1 + ¼ ulp` (ulp = 2⁻¹⁰) as `sums` when each is
    /// added onto 1 (`Gpu::half_blend_sums`), or `None` if neither does.
    pub fn of_sums(sums: [f32; 2]) -> Option<HalfRounding> {
        let ulp = 2f32.powi(-10);
        [HalfRounding::TowardZero, HalfRounding::NearestEven]
            .into_iter()
            .find(|r| sums == [0.75, 0.25].map(|d| r.round(1.0 + r.round(d * ulp))))
    }
}

/// Fixed-function state of a draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pipeline {
    pub cull: Cull,
    pub coverage: Coverage,
    /// Depth test (less) with the depth buffer cleared to this; `None` disables depth.
    pub depth_clear: Option<f32>,
    pub depth_write: bool,
    /// Colour target with its clear value and blend; `None` for depth-only draws.
    pub color: Option<(f32, Blend)>,
}

impl Pipeline {
    /// A depth-only pass, as a shadow map is drawn.
    pub const DEPTH_ONLY: Pipeline = Pipeline {
        cull: Cull::None,
        coverage: Coverage::Center,
        depth_clear: Some(1.0),
        depth_write: true,
        color: None,
    };

    /// A colour-only pass, both sides drawn, no depth test: every fragment reaches `blend`
    /// onto a target cleared to `clear` (a penumbra or soft shadow map splatted into).
    pub const fn color_only(clear: f32, blend: Blend) -> Pipeline {
        Pipeline {
            cull: Cull::None,
            coverage: Coverage::Center,
            depth_clear: None,
            depth_write: false,
            color: Some((clear, blend)),
        }
    }
}

/// Where a draw renders and how it is tiled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Target {
    pub width: u32,
    pub height: u32,
    /// Tile side in pixels, a multiple of [`BLOCK`].
    pub tile: u32,
}

impl Target {
    /// A `res`×`res` map (a light-space target) in tiles of `tile` pixels.
    pub fn square(res: u32, tile: u32) -> Target {
        Target {
            width: res,
            height: res,
            tile,
        }
    }

    pub fn tiles_x(&self) -> u32 {
        self.width.div_ceil(self.tile)
    }

    pub fn tiles_y(&self) -> u32 {
        self.height.div_ceil(self.tile)
    }

    pub fn tiles(&self) -> usize {
        (self.tiles_x() * self.tiles_y()) as usize
    }

    /// Pixel rectangle of tile `t`, clipped to the target.
    pub fn tile_rect(&self, t: usize) -> TileRect {
        let (tx, ty) = (t as u32 % self.tiles_x(), t as u32 / self.tiles_x());
        TileRect {
            index: t,
            x0: tx * self.tile,
            y0: ty * self.tile,
            x1: ((tx + 1) * self.tile).min(self.width),
            y1: ((ty + 1) * self.tile).min(self.height),
        }
    }

    /// Per tile, how many of its pixels (row-major index `y * width + x`) satisfy `counts`:
    /// the scheduling weights of a per-pixel step over the tiles.
    /// The tiles are counted in parallel on the host (the scheduler's estimate is host work the
    /// model does not time).
    pub fn tile_weights(&self, counts: impl Fn(usize) -> bool + Sync) -> Vec<u64> {
        (0..self.tiles())
            .into_par_iter()
            .map(|t| {
                let r = self.tile_rect(t);
                let mut n = 0u64;
                for y in r.y0..r.y1 {
                    let row = (y * self.width) as usize;
                    for x in r.x0..r.x1 {
                        n += u64::from(counts(row + x as usize));
                    }
                }
                n
            })
            .collect()
    }
}

/// Pixels [x0, x1) × [y0, y1) of tile `index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileRect {
    pub index: usize,
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl TileRect {
    /// The origins `(x0, y0)` of the tile's 4×4 blocks ([`BLOCK`]), row by row.
    pub fn blocks(&self) -> impl Iterator<Item = (u32, u32)> {
        let (x0, x1) = (self.x0, self.x1);
        (self.y0..self.y1)
            .step_by(BLOCK as usize)
            .flat_map(move |y| (x0..x1).step_by(BLOCK as usize).map(move |x| (x, y)))
    }
}

/// Triangles to draw: world positions, index triples (a triangle's index is its primitive id)
/// and the world-to-clip transform (depth 0..1).
pub struct Geometry<'a> {
    pub positions: &'a Buffer<Vec3>,
    pub triangles: &'a Buffer<[u32; 3]>,
    pub view_proj: Mat4,
}

/// The surviving lanes of one 4×4 block of one primitive, handed to a [`FragmentKernel`].
pub struct Fragments<'a> {
    /// Primitive id (index into the draw's triangles).
    pub prim: u32,
    /// Pixel of lane 0; lane `l` is at (x + l % 4, y + l / 4).
    pub x: u32,
    pub y: u32,
    /// Covered lanes that passed the depth test.
    pub mask: Mask,
    /// Interpolated depth.
    pub z: &'a Lanes<f32>,
    /// Screen-space barycentric weights of the triangle's three vertices (of the whole
    /// triangle also where the near plane cut it: they may then lie outside [0, 1]).
    pub bary: &'a [Lanes<f32>; 3],
}

impl Fragments<'_> {
    pub fn pixel(&self, lane: usize) -> (u32, u32) {
        (self.x + lane as u32 % BLOCK, self.y + lane as u32 / BLOCK)
    }

    /// The perspective-correct value at lane `lane` of a per-vertex attribute stored as
    /// (value, 1/w) per vertex: the screen-space weights times 1/w, normalized; the first
    /// vertex's value where the weights sum to zero.
    pub fn perspective_value(&self, lane: usize, attr: &[Vec2; 3]) -> f32 {
        // A vertex of no weight adds nothing, even with 1/w infinite (on the eye's plane, cut
        // away by the near plane).
        let w: [f32; 3] = std::array::from_fn(|k| {
            let b = self.bary[k][lane];
            if b == 0.0 {
                0.0
            } else {
                b * attr[k].y
            }
        });
        let sum = w[0] + w[1] + w[2];
        if sum > 0.0 {
            (w[0] * attr[0].x + w[1] * attr[1].x + w[2] * attr[2].x) / sum
        } else {
            attr[0].x
        }
    }
}

/// What a kernel returns for a block: a value per lane and the lanes to write (a subset of the
/// fragments' mask; dropped lanes are counted as discarded).
pub struct Shade {
    pub value: Lanes<f32>,
    pub mask: Mask,
}

impl Shade {
    /// The lanes of `mask` that `value` gives a value for, written with it; the other lanes
    /// dropped (their value `fill`).
    pub fn select(mask: Mask, fill: f32, mut value: impl FnMut(usize) -> Option<f32>) -> Shade {
        let mut s = Shade {
            value: [fill; LANES],
            mask: Mask::NONE,
        };
        for l in mask.lanes() {
            if let Some(v) = value(l) {
                s.value[l] = v;
                s.mask.0 |= 1 << l;
            }
        }
        s
    }
}

/// The per-fragment hook of the back end.
pub trait FragmentKernel: Sync {
    /// Private state of one tile (one task), returned with the draw's output in tile order.
    type TileState: Send;
    fn begin_tile(&self, tile: TileRect) -> Self::TileState;
    /// Shades one block's fragments, telling `p` what it executes.
    fn shade<P: Probe>(
        &self,
        p: &mut P,
        state: &mut Self::TileState,
        frags: &Fragments<'_>,
    ) -> Shade;
}

/// The kernel of a depth-only pass: writes every fragment, costs nothing beyond the depth test.
pub struct DepthOnly;

impl FragmentKernel for DepthOnly {
    type TileState = ();
    fn begin_tile(&self, _: TileRect) {}
    fn shade<P: Probe>(&self, _: &mut P, _: &mut (), frags: &Fragments<'_>) -> Shade {
        Shade {
            value: [0.0; LANES],
            mask: frags.mask,
        }
    }
}

/// A draw's results.
pub struct RasterOutput<S> {
    pub depth: Option<Surface>,
    pub color: Option<Surface>,
    /// Each tile's kernel state, in tile order.
    pub tiles: Vec<S>,
}

/// Vector instructions of the front end per 16 triangles (one triangle per lane).
mod cost {
    /// Three vertices × a 4×4 matrix–vector product as 4 multiply-adds per row, 3 rows needed
    /// for x, y, w plus one for z: 3 × 16.
    pub const TRANSFORM: u32 = 48;
    /// Near-plane classification: 3 compares, 2 mask ors.
    pub const CLIP_TEST: u32 = 5;
    /// Perspective divide and viewport: per vertex a reciprocal, 3 multiplies, 2 multiply-adds.
    pub const PROJECT: u32 = 18;
    /// Edge setup: 6 differences, area (2 multiplies, 1 subtract), orientation select and cull
    /// compare, reciprocal area, bounding box (8 min/max), depth range (4 min/max), tile range
    /// (4 multiplies, 4 conversions).
    pub const SETUP: u32 = 33;
    /// Scalar work of clipping one triangle against the near plane (Sutherland–Hodgman over
    /// three edges: intersection lerps and bookkeeping).
    pub const CLIP_SCALAR: u32 = 60;
    /// Scalar work per bin entry: tile index arithmetic, append, loop control.
    pub const BIN_SCALAR: u32 = 4;
    /// Scalar work per (triangle, tile) in the back end: fetch, loop control, block range.
    pub const TRI_TILE_SCALAR: u32 = 8;
    /// Edge functions of up to 16 blocks at their most-inside corners: one per edge, plus
    /// the mask and.
    pub const BLOCK_REJECT: u32 = 4;
    /// Coverage of a block: three edge values (one add of a precomputed step each), three
    /// compares (with the top-left tie), two mask ands.
    pub const COVERAGE: u32 = 8;
    /// Depth: two multiplies for the weights, two multiply-adds for z, one compare.
    pub const DEPTH_TEST: u32 = 5;
    /// Depth write: a select, and the block's new maximum by a 4-step reduction.
    pub const DEPTH_WRITE: u32 = 5;
    /// Colour blend: one add/min/max/select.
    pub const BLEND: u32 = 1;
}

/// A triangle after setup: screen-space edge functions and depth plane inputs.
#[derive(Clone, Copy, Debug, Default)]
struct Setup {
    prim: u32,
    /// Edge k is opposite vertex k: `E_k(p) = (p − o_k) · (a_k, b_k)`, positive inside.
    /// Vertices are snapped to [`SUBPIXELS`] and edges evaluated in f64, where those products
    /// are exact: triangles sharing an edge get exactly opposite values, so no pixel is covered
    /// twice or missed.
    o: [[f64; 2]; 3],
    a: [f64; 3],
    b: [f64; 3],
    top_left: [bool; 3],
    z: [f32; 3],
    inv_area: f64,
    zmin: f32,
    /// Pixels [x0, x1) × [y0, y1) that may be covered.
    bbox: [u32; 4],
    /// For a piece of a triangle cut by the near plane: row `j` maps the piece's vertex `j` to
    /// the triangle's vertices, `M[j][k] = β_jk · w_k / w_j` (β the clip-space weights of the
    /// cut, `w` the clip-space w), so that `b_k = Σ_j b'_j M[j][k]` turns the piece's
    /// screen-space weights `b'` into the triangle's. `None` for a whole triangle.
    to_triangle: Option<[[f32; 3]; 3]>,
}

/// Bytes of a setup record on the modelled machine: three edge equations (a, b, c), three
/// depths, the reciprocal area and the minimum depth as f32, the bounding box as four u16 and the
/// primitive id: 76 bytes, padded to 80.
const SETUP_BYTES: u32 = 80;

/// Sub-pixel precision of snapped vertex positions (8 bits, as GPUs use).
pub const SUBPIXELS: f64 = 256.0;

/// `v` on the [`SUBPIXELS`] grid, rounded half away from zero as `f64::round` does (a libm call
/// on baseline x86-64, once per vertex coordinate): for the `|v| < 1e6` that [`Setup::new`]
/// admits, `|v|·256 + 0.5` is exact in f64, so truncating it is the rounding.
fn snap(v: f32) -> f64 {
    let r = f64::from(v) * SUBPIXELS;
    (((r.abs() + 0.5) as i64) as f64).copysign(r) / SUBPIXELS
}

impl Setup {
    fn new(prim: u32, s: [Vec3; 3], cull: Cull, coverage: Coverage, t: &Target) -> Option<Setup> {
        if !s
            .iter()
            .all(|v| v.is_finite() && v.x.abs() < 1e6 && v.y.abs() < 1e6)
        {
            return None;
        }
        let q = s.map(|v| [snap(v.x), snap(v.y)]);
        let e1 = [q[1][0] - q[0][0], q[1][1] - q[0][1]];
        let e2 = [q[2][0] - q[0][0], q[2][1] - q[0][1]];
        // Screen y points down: a counter-clockwise triangle in NDC has negative screen area.
        let screen_area = e1[0] * e2[1] - e1[1] * e2[0];
        let front = screen_area < 0.0;
        if screen_area == 0.0
            || !screen_area.is_finite()
            || (cull == Cull::Back && !front)
            || (cull == Cull::Front && front)
        {
            return None;
        }
        let sign = screen_area.signum();
        let mut o = [[0.0; 2]; 3];
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        let mut top_left = [false; 3];
        for k in 0..3 {
            let (p, r) = (q[(k + 1) % 3], q[(k + 2) % 3]);
            o[k] = p;
            // E_k(q_k) = sign · cross(q_k − p, r − p) = |area| > 0.
            a[k] = -sign * (r[1] - p[1]);
            b[k] = sign * (r[0] - p[0]);
            // The one tie rule (`scene::coverage`) in screen space: the perturbation of the
            // pixel centre by (ε, ε²) decides an edge value of exactly 0 (the top-left rule).
            top_left[k] = coverage::lex_positive([a[k], b[k], 0.0]);
        }
        let to_triangle = None;
        let grow = if coverage == Coverage::Conservative {
            1.0
        } else {
            0.0
        };
        let (lo, hi) = (
            s[0].min(s[1]).min(s[2]) - grow,
            s[0].max(s[1]).max(s[2]) + grow,
        );
        let bbox = [
            pixel_floor(lo.x, t.width),
            pixel_floor(lo.y, t.height),
            pixel_ceil(hi.x, t.width),
            pixel_ceil(hi.y, t.height),
        ];
        if bbox[0] >= bbox[2] || bbox[1] >= bbox[3] {
            return None;
        }
        Some(Setup {
            prim,
            o,
            a,
            b,
            top_left,
            z: [s[0].z, s[1].z, s[2].z],
            inv_area: 1.0 / screen_area.abs(),
            zmin: s[0].z.min(s[1].z).min(s[2].z),
            bbox,
            to_triangle,
        })
    }

    #[inline]
    fn edge(&self, k: usize, x: f64, y: f64) -> f64 {
        (x - self.o[k][0]) * self.a[k] + (y - self.o[k][1]) * self.b[k]
    }

    /// Slack added to edge values: half a pixel's extent along the edge normal when
    /// conservative.
    #[inline]
    fn slack(&self, k: usize, coverage: Coverage) -> f64 {
        match coverage {
            Coverage::Center => 0.0,
            Coverage::Conservative => 0.5 * (self.a[k].abs() + self.b[k].abs()),
        }
    }

    /// Whether pixels [x0, x1) × [y0, y1) lie wholly outside one edge (all three edges
    /// evaluated, no branch between them).
    #[inline]
    fn rejects(&self, x0: u32, y0: u32, x1: u32, y1: u32, coverage: Coverage) -> bool {
        let (lo_x, hi_x) = (f64::from(x0) + 0.5, f64::from(x1) - 0.5);
        let (lo_y, hi_y) = (f64::from(y0) + 0.5, f64::from(y1) - 0.5);
        let outside = |k: usize| {
            let x = if self.a[k] > 0.0 { hi_x } else { lo_x };
            let y = if self.b[k] > 0.0 { hi_y } else { lo_y };
            self.edge(k, x, y) + self.slack(k, coverage) < 0.0
        };
        outside(0) | outside(1) | outside(2)
    }
}

/// `⌊x⌋` clamped to `0..=size` (x finite, |x| < 2²⁴): below 0 it is 0, and in `0..=size` the
/// truncation of the conversion is the floor, so no `floor` call (libm on baseline x86-64).
fn pixel_floor(x: f32, size: u32) -> u32 {
    x.clamp(0.0, size as f32) as u32
}

/// `⌈x⌉` clamped to `0..=size` (x finite, |x| < 2²⁴), without a `ceil` call: the truncation,
/// one more where it lies below `x`.
fn pixel_ceil(x: f32, size: u32) -> u32 {
    let c = x.clamp(0.0, size as f32);
    let t = c as u32;
    t + u32::from((t as f32) < c)
}

/// Sutherland–Hodgman clip of a clip-space triangle against the near plane z ≥ 0; returns the
/// resulting polygon (0, 3 or 4 vertices). The crossing of an edge is interpolated from its
/// kept endpoint whichever way the triangle runs along it, so two triangles sharing a clipped
/// edge get the same new vertex and stay watertight.
fn clip_near(v: [Vec4; 3]) -> Polygon {
    let mut out = Polygon {
        v: [Vec4::ZERO; 4],
        beta: [[0.0; 3]; 4],
        n: 0,
    };
    let unit = |i: usize| std::array::from_fn(|k| f32::from(k == i));
    for i in 0..3 {
        let j = (i + 1) % 3;
        let (p, q) = (v[i], v[j]);
        if p.z >= 0.0 {
            out.push(p, unit(i));
        }
        if (p.z >= 0.0) != (q.z >= 0.0) {
            let ((inside, a), (outside, b)) = if p.z >= 0.0 {
                ((p, i), (q, j))
            } else {
                ((q, j), (p, i))
            };
            let t = inside.z / (inside.z - outside.z);
            let mut beta = [0.0; 3];
            beta[a] = 1.0 - t;
            beta[b] = t;
            out.push(inside + (outside - inside) * t, beta);
        }
    }
    out
}

/// A triangle cut by one plane: a convex polygon of 0, 3 or 4 clip-space vertices, held on the
/// stack (the front end makes no allocation per triangle).
struct Polygon {
    v: [Vec4; 4],
    /// Per vertex, its clip-space weights over the cut triangle's vertices.
    beta: [[f32; 3]; 4],
    n: usize,
}

impl Polygon {
    fn push(&mut self, c: Vec4, beta: [f32; 3]) {
        self.v[self.n] = c;
        self.beta[self.n] = beta;
        self.n += 1;
    }

    /// [`Setup::to_triangle`] of the piece of vertices `piece` of this cut of the triangle
    /// whose clip-space vertices are `whole`.
    fn to_triangle(&self, piece: [usize; 3], whole: &[Vec4; 3]) -> [[f32; 3]; 3] {
        piece.map(|j| std::array::from_fn(|k| self.beta[j][k] * whole[k].w / self.v[j].w))
    }

    fn vertices(&self) -> &[Vec4] {
        &self.v[..self.n]
    }
}

fn to_screen(c: Vec4, t: &Target) -> Vec3 {
    let n = c.truncate() / c.w;
    Vec3::new(
        (n.x * 0.5 + 0.5) * t.width as f32,
        (0.5 - n.y * 0.5) * t.height as f32,
        n.z,
    )
}

/// Front-end output of one chunk of triangles.
struct Binned {
    setups: Vec<Setup>,
    /// (tile, index into `setups`), in triangle order.
    entries: Vec<(u32, u32)>,
    culled: u64,
    clipped: u64,
}

struct FrontEnd<'a> {
    geometry: &'a Geometry<'a>,
    pipeline: Pipeline,
    target: Target,
    setup_buf: (super::BufferId, u64),
    bins_buf: (super::BufferId, u64),
}

impl FrontEnd<'_> {
    /// Modelled address of the setup record `i` of chunk `c` (room for two per triangle after
    /// clipping).
    fn setup_addr(&self, c: usize, i: usize) -> u64 {
        self.setup_buf.1 + ((c * CHUNK * 2 + i) as u64) * u64::from(SETUP_BYTES)
    }

    /// Modelled address of entry `k` of chunk `c`'s bin for `tile`: each chunk (front-end
    /// thread) appends to its own bins, so binning needs no locks.
    fn bin_addr(&self, c: usize, tile: u32, k: usize) -> u64 {
        let bin = (c * self.target.tiles() + tile as usize) as u64;
        self.bins_buf.1 + (bin * (CHUNK as u64 * 2) + k as u64) * 4
    }
}

impl TaskKernel for FrontEnd<'_> {
    type Out = Binned;

    fn run<P: Probe>(&self, p: &mut P, chunk: usize) -> Binned {
        let g = self.geometry;
        let n_tris = g.triangles.data.len();
        let (start, end) = (chunk * CHUNK, ((chunk + 1) * CHUNK).min(n_tris));
        let t = &self.target;
        let mut out = Binned {
            setups: Vec::with_capacity(end - start),
            entries: Vec::with_capacity(end - start),
            culled: 0,
            clipped: 0,
        };
        let mut bin_fill = if P::ENABLED {
            vec![0usize; t.tiles()]
        } else {
            Vec::new()
        };
        for group in (start..end).step_by(LANES) {
            let n = (end - group).min(LANES);
            let mask = Mask::first(n);
            let tris = g.triangles.load_run(p, group, n);
            let mut idx = [[0u32; LANES]; 3];
            for (l, tri) in tris.iter().enumerate() {
                for k in 0..3 {
                    idx[k][l] = tri[k];
                }
            }
            let verts = idx.map(|i| g.positions.gather(p, &i, mask));
            p.vector(cost::TRANSFORM + cost::CLIP_TEST, mask);
            let mut setup_mask = Mask::NONE;
            for l in 0..n {
                let prim = (group + l) as u32;
                let clip = verts.map(|v| g.view_proj * v[l].extend(1.0));
                let clipped = if clip.iter().all(|c| c.z >= 0.0) {
                    setup_mask.0 |= 1 << l;
                    None
                } else {
                    out.clipped += 1;
                    p.scalar(cost::CLIP_SCALAR);
                    Some(clip_near(clip))
                };
                let polygon: &[Vec4] = clipped.as_ref().map_or(&clip, |c| c.vertices());
                let mut any = false;
                for i in 1..polygon.len().saturating_sub(1) {
                    let s = [polygon[0], polygon[i], polygon[i + 1]].map(|c| to_screen(c, t));
                    let Some(mut setup) =
                        Setup::new(prim, s, self.pipeline.cull, self.pipeline.coverage, t)
                    else {
                        continue;
                    };
                    setup.to_triangle = clipped
                        .as_ref()
                        .map(|c| c.to_triangle([0, i, i + 1], &clip));
                    any = true;
                    let si = out.setups.len();
                    p.write(self.setup_buf.0, self.setup_addr(chunk, si), SETUP_BYTES);
                    let [x0, y0, x1, y1] = setup.bbox;
                    for ty in y0 / t.tile..=(y1 - 1) / t.tile {
                        for tx in x0 / t.tile..=(x1 - 1) / t.tile {
                            let tile = ty * t.tiles_x() + tx;
                            if P::ENABLED {
                                let k = &mut bin_fill[tile as usize];
                                p.write(self.bins_buf.0, self.bin_addr(chunk, tile, *k), 4);
                                *k += 1;
                                p.scalar(cost::BIN_SCALAR);
                            }
                            out.entries.push((tile, si as u32));
                        }
                    }
                    out.setups.push(setup);
                }
                out.culled += u64::from(!any);
            }
            p.vector(cost::PROJECT + cost::SETUP, setup_mask);
        }
        out
    }
}

/// One tile's work in the back end: (chunk, entry within the chunk's bin, setup index within the
/// chunk); the setups stay where their front-end task put them.
type BinEntry = (u32, u32, u32);

struct BackEnd<'a, K> {
    kernel: &'a K,
    pipeline: Pipeline,
    target: Target,
    binned: &'a [Binned],
    bins: &'a [Vec<BinEntry>],
    front: &'a FrontEnd<'a>,
    depth: Option<&'a Surface>,
    color: Option<&'a Surface>,
}

/// Counts of one tile.
#[derive(Clone, Copy, Debug, Default)]
struct TileStats {
    triangles: u64,
    tiles_rejected: u64,
    blocks_rejected: u64,
    fill: u64,
    early_rejected: u64,
    depth_pass: u64,
    depth_fail: u64,
    discarded: u64,
    written: u64,
}

struct TileOut<S> {
    depth: Vec<Lanes<f32>>,
    color: Vec<Lanes<f32>>,
    state: S,
    stats: TileStats,
}

impl<K: FragmentKernel> TaskKernel for BackEnd<'_, K> {
    type Out = TileOut<K::TileState>;

    fn run<P: Probe>(&self, p: &mut P, tile: usize) -> Self::Out {
        let r = self.target.tile_rect(tile);
        let (bx0, by0) = (r.x0 / BLOCK, r.y0 / BLOCK);
        let (bw, bh) = (r.x1.div_ceil(BLOCK) - bx0, r.y1.div_ceil(BLOCK) - by0);
        let nblocks = (bw * bh) as usize;
        let pl = &self.pipeline;
        let mut stats = TileStats {
            triangles: self.bins[tile].len() as u64,
            ..Default::default()
        };
        let depth_clear = pl.depth_clear.unwrap_or(1.0);
        let mut depth = vec![[depth_clear; LANES]; if self.depth.is_some() { nblocks } else { 0 }];
        let mut zmax = vec![depth_clear; depth.len()];
        let (color_clear, blend) = pl.color.unwrap_or((0.0, Blend::Replace));
        let mut color = vec![[color_clear; LANES]; if self.color.is_some() { nblocks } else { 0 }];
        // Clear: one vector store per block of each target.
        for s in [self.depth, self.color].into_iter().flatten() {
            for by in 0..bh {
                for bx in 0..bw {
                    s.buf
                        .record_store(p, s.block_index(bx0 + bx, by0 + by), LANES);
                }
            }
            p.vector(nblocks as u32, Mask::ALL);
        }
        let mut state = self.kernel.begin_tile(r);
        for &(chunk, k, si) in &self.bins[tile] {
            let s = &self.binned[chunk as usize].setups[si as usize];
            p.read(
                self.front.bins_buf.0,
                self.front.bin_addr(chunk as usize, tile as u32, k as usize),
                4,
            );
            p.read(
                self.front.setup_buf.0,
                self.front.setup_addr(chunk as usize, si as usize),
                SETUP_BYTES,
            );
            p.scalar(cost::TRI_TILE_SCALAR);
            p.vector(1, Mask::first(3));
            if s.rejects(r.x0, r.y0, r.x1, r.y1, pl.coverage) {
                stats.tiles_rejected += 1;
                continue;
            }
            let x0 = s.bbox[0].max(r.x0) / BLOCK;
            let y0 = s.bbox[1].max(r.y0) / BLOCK;
            let x1 = s.bbox[2].min(r.x1).div_ceil(BLOCK);
            let y1 = s.bbox[3].min(r.y1).div_ceil(BLOCK);
            let range = ((x1 - x0) * (y1 - y0)) as usize;
            for v in 0..range.div_ceil(LANES) {
                p.vector(cost::BLOCK_REJECT, Mask::first(range - v * LANES));
            }
            for by in y0..y1 {
                for bx in x0..x1 {
                    let (px, py) = (bx * BLOCK, by * BLOCK);
                    if s.rejects(px, py, px + BLOCK, py + BLOCK, pl.coverage) {
                        stats.blocks_rejected += 1;
                        continue;
                    }
                    let local = ((by - by0) * bw + (bx - bx0)) as usize;
                    self.block(
                        p,
                        s,
                        (px, py),
                        local,
                        (&mut depth, &mut zmax, &mut color, blend),
                        &mut state,
                        &mut stats,
                    );
                }
            }
        }
        TileOut {
            depth,
            color,
            state,
            stats,
        }
    }
}

type TileTargets<'t> = (
    &'t mut Vec<Lanes<f32>>,
    &'t mut Vec<f32>,
    &'t mut Vec<Lanes<f32>>,
    Blend,
);

impl<K: FragmentKernel> BackEnd<'_, K> {
    /// Rasterizes triangle `s` in the 4×4 block at pixel (px, py) (block `local` of the tile).
    #[allow(clippy::too_many_arguments)]
    fn block<P: Probe>(
        &self,
        p: &mut P,
        s: &Setup,
        (px, py): (u32, u32),
        local: usize,
        (depth, zmax, color, blend): TileTargets<'_>,
        state: &mut K::TileState,
        stats: &mut TileStats,
    ) {
        let pl = &self.pipeline;
        let t = &self.target;
        // Lane code without a branch per lane: every loop below runs over all 16 lanes with
        // the same operations (compares into a mask, selects), which the compiler turns into
        // vector instructions.
        let in_target = block_in_target(t.width - px, t.height - py);
        let conservative = pl.coverage == Coverage::Conservative;
        let mut e = [[0f64; LANES]; 3];
        let mut covered = in_target;
        for (k, ek) in e.iter_mut().enumerate() {
            let slack = s.slack(k, pl.coverage);
            let tie = s.top_left[k] || conservative;
            let (x0, y0) = (f64::from(px), f64::from(py));
            let mut inside = [false; LANES];
            for l in 0..LANES {
                let x = x0 + LANE_X[l];
                let y = y0 + LANE_Y[l];
                ek[l] = s.edge(k, x, y);
                let v = ek[l] + slack;
                inside[l] = (v > 0.0) | ((v == 0.0) & tie);
            }
            covered = covered.and(Mask::from_lanes(&inside));
        }
        p.vector(cost::COVERAGE, Mask::ALL);
        stats.fill += u64::from(covered.count());
        if !covered.any() {
            return;
        }
        let inv_area = s.inv_area;
        let mut bary: [Lanes<f32>; 3] = e.map(|ek| ek.map(|v| (v * inv_area) as f32));
        let (lo, hi) = (s.zmin, s.z[0].max(s.z[1]).max(s.z[2]));
        let z: Lanes<f32> = std::array::from_fn(|l| {
            (bary[0][l] * s.z[0] + bary[1][l] * s.z[1] + bary[2][l] * s.z[2]).clamp(lo, hi)
        });
        // The depth is the piece's; the weights the kernel interpolates attributes with are
        // the whole triangle's.
        if let Some(m) = &s.to_triangle {
            let piece = bary;
            bary = std::array::from_fn(|k| {
                std::array::from_fn(|l| (0..3).map(|j| piece[j][l] * m[j][k]).sum())
            });
        }
        let mut mask = covered;
        if let Some(d) = self.depth {
            p.scalar(2);
            if s.zmin >= zmax[local] {
                stats.early_rejected += u64::from(covered.count());
                return;
            }
            d.buf
                .record_load(p, d.block_index(px / BLOCK, py / BLOCK), LANES);
            p.vector(cost::DEPTH_TEST, covered);
            let old = &depth[local];
            let nearer: [bool; LANES] = std::array::from_fn(|l| z[l] < old[l]);
            mask = covered.and(Mask::from_lanes(&nearer));
            stats.depth_pass += u64::from(mask.count());
            stats.depth_fail += u64::from(covered.and_not(mask).count());
            if !mask.any() {
                return;
            }
        }
        let frags = Fragments {
            prim: s.prim,
            x: px,
            y: py,
            mask,
            z: &z,
            bary: &bary,
        };
        let shade = self.kernel.shade(p, state, &frags);
        let write = shade.mask.and(mask);
        stats.discarded += u64::from(mask.and_not(write).count());
        stats.written += u64::from(write.count());
        if !write.any() {
            return;
        }
        let lanes = write.to_lanes();
        if let (Some(d), true) = (self.depth, pl.depth_write) {
            p.vector(cost::DEPTH_WRITE, write);
            let block = &mut depth[local];
            for l in 0..LANES {
                block[l] = if lanes[l] { z[l] } else { block[l] };
            }
            zmax[local] = block.iter().copied().fold(f32::MIN, f32::max);
            d.buf
                .record_store(p, d.block_index(px / BLOCK, py / BLOCK), LANES);
        }
        if let Some(c) = self.color {
            let i = c.block_index(px / BLOCK, py / BLOCK);
            c.buf.record_load(p, i, LANES);
            p.vector(cost::BLEND, write);
            blend_block(blend, &mut color[local], &shade.value, &lanes);
            c.buf.record_store(p, i, LANES);
        }
    }
}

/// Pixel-centre offsets of the lanes of a block from its first pixel: lane `l` is pixel
/// (l % 4, l / 4) of the block, its centre half a pixel further.
const LANE_X: Lanes<f64> = [
    0.5, 1.5, 2.5, 3.5, 0.5, 1.5, 2.5, 3.5, 0.5, 1.5, 2.5, 3.5, 0.5, 1.5, 2.5, 3.5,
];
const LANE_Y: Lanes<f64> = [
    0.5, 0.5, 0.5, 0.5, 1.5, 1.5, 1.5, 1.5, 2.5, 2.5, 2.5, 2.5, 3.5, 3.5, 3.5, 3.5,
];

/// The lanes of a block inside the target when `cols` pixels remain to its right edge and
/// `rows` to its bottom edge (counting the block's own first column and row).
fn block_in_target(cols: u32, rows: u32) -> Mask {
    let row = (1u16 << cols.min(BLOCK)) - 1;
    let mut m = 0u16;
    for r in 0..rows.min(BLOCK) {
        m |= row << (r * BLOCK);
    }
    Mask(m)
}

/// `target[l] = blend(target[l], value[l])` on the lanes where `write[l]`, the others kept:
/// one select per lane over the whole block, the blend chosen once.
fn blend_block(blend: Blend, target: &mut Lanes<f32>, value: &Lanes<f32>, write: &[bool; LANES]) {
    fn each(
        target: &mut Lanes<f32>,
        value: &Lanes<f32>,
        write: &[bool; LANES],
        f: impl Fn(f32, f32) -> f32,
    ) {
        for l in 0..LANES {
            let new = f(target[l], value[l]);
            target[l] = if write[l] { new } else { target[l] };
        }
    }
    match blend {
        Blend::Replace => each(target, value, write, |_, v| v),
        Blend::Add => each(target, value, write, |o, v| o + v),
        Blend::Min => each(target, value, write, f32::min),
        Blend::Max => each(target, value, write, f32::max),
        // Half-float rounding is scalar work (a conversion and a compare per lane).
        Blend::AddHalf(_) => {
            for l in 0..LANES {
                if write[l] {
                    target[l] = blend.apply(target[l], value[l]);
                }
            }
        }
    }
}

/// Power-of-two bucket name of a triangles-per-tile count: `0`, `1`, `2-3`, `4-7`, ...
fn bucket(n: u64) -> String {
    match n {
        0 => "0".into(),
        1 => "1".into(),
        _ => {
            let lo = 1u64 << (63 - n.leading_zeros());
            format!("{lo}-{}", 2 * lo - 1)
        }
    }
}

/// Draws `geometry` into `target` with `pipeline` and `kernel` as two steps of the current
/// phase, `binning` (front end) and `raster` (back end). Surfaces are named `<name>.depth` and
/// `<name>.color`. Records the rasterizer counters in the current phase:
/// `raster.triangles`, `raster.culled`, `raster.clipped`, `bin_entries`, `bin_bytes`,
/// `raster.tiles_rejected`, `raster.blocks_rejected`, `fill`, `fragments_rejected_early`,
/// `depth_pass`, `depth_fail`, `raster.discarded`, `raster.written`,
/// `raster.tris_per_tile.<bucket>`.
pub fn draw<K: FragmentKernel>(
    m: &mut Machine,
    name: &str,
    target: Target,
    pipeline: Pipeline,
    geometry: &Geometry<'_>,
    kernel: &K,
) -> RasterOutput<K::TileState> {
    debug_assert!(target.tile.is_multiple_of(BLOCK) && target.tile > 0);
    let n_tris = geometry.triangles.data.len();
    let chunks = n_tris.div_ceil(CHUNK);
    let setup_buf = m.memory.reserve(
        "raster.setup",
        (chunks * CHUNK * 2) as u64 * u64::from(SETUP_BYTES),
    );
    let bins_buf = m
        .memory
        .reserve("bins", (chunks * target.tiles() * CHUNK * 2 * 4) as u64);
    let front = FrontEnd {
        geometry,
        pipeline,
        target,
        setup_buf,
        bins_buf,
    };
    let weights: Vec<u64> = (0..chunks)
        .map(|c| ((c + 1) * CHUNK).min(n_tris) as u64 - (c * CHUNK) as u64)
        .collect();
    let binned = m.run_step("binning", &front, &weights);

    let mut bins: Vec<Vec<BinEntry>> = vec![Vec::new(); target.tiles()];
    let (mut culled, mut clipped) = (0, 0);
    for (c, b) in binned.iter().enumerate() {
        let mut fill = vec![
            0u32;
            if b.entries.is_empty() {
                0
            } else {
                target.tiles()
            }
        ];
        for &(tile, si) in &b.entries {
            let k = &mut fill[tile as usize];
            bins[tile as usize].push((c as u32, *k, si));
            *k += 1;
        }
        culled += b.culled;
        clipped += b.clipped;
    }
    let bin_entries: usize = bins.iter().map(Vec::len).sum();
    m.count(names::RASTER_TRIANGLES, n_tris as f64);
    m.count(names::RASTER_CULLED, culled as f64);
    m.count(names::RASTER_CLIPPED, clipped as f64);
    m.count(names::BIN_ENTRIES, bin_entries as f64);
    m.count(names::BIN_BYTES, (bin_entries * 4) as f64);

    let depth = pipeline.depth_clear.map(|clear| {
        Surface::new(
            &mut m.memory,
            &format!("{name}.depth"),
            target.width,
            target.height,
            clear,
        )
    });
    let color = pipeline.color.map(|(clear, _)| {
        Surface::new(
            &mut m.memory,
            &format!("{name}.color"),
            target.width,
            target.height,
            clear,
        )
    });
    let back = BackEnd {
        kernel,
        pipeline,
        target,
        binned: &binned,
        bins: &bins,
        front: &front,
        depth: depth.as_ref(),
        color: color.as_ref(),
    };
    let weights: Vec<u64> = bins.iter().map(|b| b.len() as u64 + 1).collect();
    let tiles = m.run_step("raster", &back, &weights);

    let mut depth = depth;
    let mut color = color;
    let mut total = TileStats::default();
    let mut states = Vec::with_capacity(tiles.len());
    for (t, out) in tiles.into_iter().enumerate() {
        let r = target.tile_rect(t);
        let (bx0, by0) = (r.x0 / BLOCK, r.y0 / BLOCK);
        let bw = r.x1.div_ceil(BLOCK) - bx0;
        for (surface, blocks) in [(&mut depth, &out.depth), (&mut color, &out.color)] {
            if let Some(s) = surface.as_mut() {
                for (i, block) in blocks.iter().enumerate() {
                    let (bx, by) = (bx0 + i as u32 % bw, by0 + i as u32 / bw);
                    let at = s.block_index(bx, by);
                    s.buf.data[at..at + LANES].copy_from_slice(block);
                }
            }
        }
        let s = out.stats;
        m.count(
            &format!("raster.tris_per_tile.{}", bucket(s.triangles)),
            1.0,
        );
        total.tiles_rejected += s.tiles_rejected;
        total.blocks_rejected += s.blocks_rejected;
        total.fill += s.fill;
        total.early_rejected += s.early_rejected;
        total.depth_pass += s.depth_pass;
        total.depth_fail += s.depth_fail;
        total.discarded += s.discarded;
        total.written += s.written;
        states.push(out.state);
    }
    for (k, v) in [
        ("raster.tiles_rejected", total.tiles_rejected),
        ("raster.blocks_rejected", total.blocks_rejected),
        ("fill", total.fill),
        ("fragments_rejected_early", total.early_rejected),
        ("depth_pass", total.depth_pass),
        ("depth_fail", total.depth_fail),
        ("raster.discarded", total.discarded),
        ("raster.written", total.written),
    ] {
        m.count(k, v as f64);
    }
    RasterOutput {
        depth,
        color,
        tiles: states,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The snap without `round` is `f64::round` on the grid, to the bit: exact halves of a
    /// sub-pixel both ways, their neighbours one f32 step away, zeros of both signs, tiny
    /// values and the largest coordinates admitted.
    #[test]
    fn snapping_rounds_half_away_from_zero_as_round_does() {
        let mut values = vec![0.0f32, -0.0, 1e-30, -1e-30, 999_999.9, -999_999.9];
        for k in -2000i32..2000 {
            let half = (k as f32 + 0.5) / 256.0;
            for v in [
                half,
                f32::from_bits(half.to_bits() + 1),
                f32::from_bits(half.to_bits() - 1),
            ] {
                values.extend([v, v * 1021.0, v * 3.7e3]);
            }
        }
        for v in values {
            let round = (f64::from(v) * SUBPIXELS).round() / SUBPIXELS;
            assert_eq!(snap(v).to_bits(), round.to_bits(), "{v}");
        }
    }

    /// The bounding box's pixel bounds without `floor`/`ceil` are theirs, clamped: whole and
    /// half pixels, one f32 step either side, negatives and values past the edge.
    #[test]
    fn pixel_bounds_are_floor_and_ceil_clamped() {
        let size = 640u32;
        for k in -400i32..1400 {
            let base = k as f32 * 0.5;
            for x in [
                base,
                f32::from_bits(base.to_bits() + 1),
                f32::from_bits(base.to_bits().saturating_sub(1)),
                -base,
            ] {
                let s = size as f32;
                assert_eq!(pixel_floor(x, size), x.floor().clamp(0.0, s) as u32, "{x}");
                assert_eq!(pixel_ceil(x, size), x.ceil().clamp(0.0, s) as u32, "{x}");
            }
        }
    }

    use super::HalfRounding::{NearestEven, TowardZero};

    /// A half's step at 1 is 2⁻¹⁰; between 1 and 2 every sum lies on a grid of that step.
    const ULP: f32 = 1.0 / 1024.0;

    #[test]
    fn sums_round_as_ieee_half_toward_zero_and_to_nearest_even() {
        for (x, toward_zero, nearest) in [
            (1.0 + 0.75 * ULP, 1.0, 1.0 + ULP),
            (1.0 + 0.25 * ULP, 1.0, 1.0),
            // Ties go to the even significand: 1 (even) and 1 + 2 ulp (even).
            (1.0 + 0.5 * ULP, 1.0, 1.0),
            (1.0 + 1.5 * ULP, 1.0 + ULP, 1.0 + 2.0 * ULP),
            // Toward zero shrinks the magnitude of negative sums too.
            (-1.0 - 0.75 * ULP, -1.0, -1.0 - ULP),
            (3.0, 3.0, 3.0),
        ] {
            assert_eq!(TowardZero.round(x), toward_zero, "{x}");
            assert_eq!(NearestEven.round(x), nearest, "{x}");
        }
        // Appendix A of paper 002: an add below half the step at X is lost to nearest rounding,
        // one below the whole step to rounding toward zero.
        let blend = |r| Blend::AddHalf(r).apply(1.0, 0.6 * ULP);
        assert_eq!((blend(TowardZero), blend(NearestEven)), (1.0, 1.0 + ULP));
    }

    #[test]
    fn rounding_names_are_the_option_values() {
        for r in [TowardZero, NearestEven] {
            assert_eq!(serde_json::to_value(r).unwrap(), r.name());
        }
    }

    #[test]
    fn the_probe_sums_name_their_rounding() {
        let of = HalfRounding::of_sums;
        assert_eq!(of([1.0, 1.0]), Some(TowardZero));
        assert_eq!(of([1.0 + ULP, 1.0]), Some(NearestEven));
        // Rounding up, or a blend that kept f32, is neither.
        assert_eq!(of([1.0 + ULP, 1.0 + ULP]), None);
        assert_eq!(of([1.0 + 0.75 * ULP, 1.0 + 0.25 * ULP]), None);
    }
}
