//! `rt_denoised` on the CPU executions (`cpu-native`, `cpu-model`): phase `trace` (step
//! `trace`) and phase `denoise` (steps `penumbra`, then `atrous` once per pass), each step one
//! task per eye tile, each task its 4×4 blocks of pixels as 16-lane vectors. The kernels are
//! written once, generic over the [`Probe`]; on `cpu-model` the probe counts what the modelled
//! machine executes:
//!
//! - traversal as 16 rays (one block, one sample) in lock step, each lane with its own stack:
//!   per iteration every live lane pops one reference; the lanes at an interior node gather its
//!   64-byte record (`bvh_nodes`: gathers costed by the distinct cache lines they touch) and
//!   test both boxes, the lanes at a leaf gather its triangles one at a time (`bvh_triangles`)
//!   and test them, so divergence shows as lane utilisation (`simd_utilization`);
//! - the denoiser's taps as gathers of the neighbours' G-buffer entries and visibility.
//!
//! Deterministic counts (rays, node visits, triangle tests, taps) are counted per task in both
//! executions and summed in task order; the image does not depend on the host's thread count.

use glam::{Vec2, Vec3};

use super::bvh::{leaf_range, CasterBvh, NodePair, Tri, LEAF, STACK};
use super::Phase;
use super::{
    geometric_weight, light_point, light_radius, penumbra_radius_px, search_offsets, seed32,
    square_sample, PixelInputs, RtDenoisedOptions, B3, MIN_REACH,
};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{eye_tiles, machine, output};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::raster::{Target, BLOCK};
use crate::model::{Buffer, Lanes, Machine, Mask, Memory, NoProbe, Probe, TaskKernel, LANES};
use crate::record::PhaseId;
use crate::scene::{coverage, Light};
use crate::visibility::VisibilityBuffer;

/// Vector instructions per block to set up a pixel's emitter frame (a sphere's disc facing the
/// point: subtract, normalise (dot, reciprocal square root, 3 multiplies), orthonormal pair
/// (about 12), 2 scalings of 3).
const FRAME_OPS: u32 = 3 + 5 + 12 + 6;
/// Vector instructions per sample to draw a light point: the Sobol' point (bit reversal, the
/// second dimension's loop of about 3 per bit of `spp`, counted as 8), the rotation (2 adds), 2
/// conversions, the concentric map (2 subtracts, a compare and select, a divide, a multiply, a
/// sine and cosine counted as 8 each, 2 multiplies) and the point (2 × 3 multiply-adds).
const SAMPLE_OPS: u32 = 8 + 2 + 2 + 24 + 6;
/// The receiver-only horizon test (subtract, dot, compare, select).
const HORIZON_OPS: u32 = 7;
/// Ray setup: direction (3 subtracts), the guarded reciprocal (3 compares, 3 selects, 3
/// divides), the stack's first entry.
const RAY_SETUP_OPS: u32 = 3 + 9 + 1;
/// Per traversal iteration: the stack pop (decrement, load, compare for the leaf flag).
const POP_OPS: u32 = 3;
/// Per interior node: both slab tests (6 multiply-subtracts, 3 min, 3 max, 2 reductions of 2,
/// the clamp to [0, 1], a compare: 17 each), the near-first order (compare, 2 selects) and up
/// to two pushes (2 each).
const NODE_OPS: u32 = 2 * 17 + 3 + 4;
/// Per leaf reached: decoding its first triangle and count (shift, and, add).
const LEAF_OPS: u32 = 3;
/// Per triangle tested: the plane's normal (2 edge subtracts of 3, a cross product of 6), the
/// two dots (5 each), a subtract of 3, a divide and the open-segment compares (3).
const PLANE_OPS: u32 = 6 + 6 + 10 + 3 + 1 + 3;
/// Per triangle whose plane the ray crosses: the coverage rule's three edge functions (2
/// subtracts of 3, a cross product of 6, a dot of 5, the lexicographic order and negation
/// about 6, a compare and the tie rule's select: 25 each) and the hit's distance.
const EDGE_OPS: u32 = 3 * 25 + 2;
/// Per block at the end of the trace: visible fraction and mean blocker distance (2 divides, a
/// compare, 2 selects).
const RESOLVE_OPS: u32 = 5;
/// Per denoiser tap: the tap's pixel index and bounds test (4), the geometric weight (a dot,
/// 5 squarings, a subtract of 3, a dot, an abs, a multiply, a divide, a subtract, a max, a
/// multiply: 20) and its accumulation (2 multiply-adds, a min and a max or the spline weight).
const TAP_OPS: u32 = 4 + 20 + 4;
/// Per block of the penumbra pass after its taps: the light distance (subtract, dot, square
/// root), the mean blocker distance and the similar triangles (2 divides, a subtract, a
/// multiply, a min), the classification (3 compares, 2 selects).
const PENUMBRA_OPS: u32 = 5 + 5 + 5;
/// Per block of an à-trous pass: the normalisation (a divide) and the select of unfiltered
/// lanes.
const NORMALIZE_OPS: u32 = 2;

/// The deterministic counts of a step's tasks, summed in task order.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counts {
    pub rays: u64,
    pub node_visits: u64,
    pub triangle_tests: u64,
    pub occluded: u64,
    pub horizon_culled: u64,
    /// Rays of pixels whose rays all agreed, beyond the first of each.
    pub agreeing: u64,
    pub search_taps: u64,
    pub filter_taps: u64,
    pub filtered_pixels: u64,
}

impl Counts {
    fn add(&mut self, o: &Counts) {
        self.rays += o.rays;
        self.node_visits += o.node_visits;
        self.triangle_tests += o.triangle_tests;
        self.occluded += o.occluded;
        self.horizon_culled += o.horizon_culled;
        self.agreeing += o.agreeing;
        self.search_taps += o.search_taps;
        self.filter_taps += o.filter_taps;
        self.filtered_pixels += o.filtered_pixels;
    }
}

/// One 4×4 block of a tile, clipped to it.
#[derive(Clone, Copy, Debug)]
struct Block {
    x0: u32,
    y0: u32,
    rows: u32,
    cols: u32,
    width: u32,
    height: u32,
}

impl Block {
    /// The pixel index of the first pixel of row `row`.
    fn row_start(&self, row: u32) -> usize {
        ((self.y0 + row) * self.width + self.x0) as usize
    }

    /// Lane `l`'s pixel (x, y), if the lane lies in the block.
    fn pixel(&self, l: usize) -> Option<(u32, u32)> {
        let (r, c) = (l as u32 / BLOCK, l as u32 % BLOCK);
        (r < self.rows && c < self.cols).then(|| (self.x0 + c, self.y0 + r))
    }

    /// The lanes inside the block and their pixel indices.
    fn lanes(&self) -> (Mask, Lanes<u32>) {
        let mut idx = [0u32; LANES];
        let mask = Mask::from_fn(|l| match self.pixel(l) {
            Some((x, y)) => {
                idx[l] = y * self.width + x;
                true
            }
            None => false,
        });
        (mask, idx)
    }

    /// Per lane, the pixel at offset (dx, dy) from the lane's, where it lies in the image.
    fn neighbours(&self, mask: Mask, (dx, dy): (i32, i32)) -> (Mask, Lanes<u32>) {
        let mut idx = [0u32; LANES];
        let m = Mask::from_fn(|l| {
            let Some((x, y)) = self.pixel(l).filter(|_| mask.get(l)) else {
                return false;
            };
            let (qx, qy) = (x as i32 + dx, y as i32 + dy);
            let inside =
                qx >= 0 && qy >= 0 && (qx as u32) < self.width && (qy as u32) < self.height;
            if inside {
                idx[l] = qy as u32 * self.width + qx as u32;
            }
            inside
        });
        (m, idx)
    }
}

/// The work of one block of an eye step; [`run_tiles`] runs it over the eye tiles.
trait BlockKernel: Sync {
    type Value: Copy + Send;
    /// Appends (pixel index, value) for every pixel of `block`.
    fn block<P: Probe>(
        &self,
        p: &mut P,
        block: &Block,
        out: &mut Vec<(u32, Self::Value)>,
        counts: &mut Counts,
    );
}

struct Tiles<'a, K> {
    kernel: &'a K,
    tiles: Target,
}

impl<K: BlockKernel> TaskKernel for Tiles<'_, K> {
    type Out = (Vec<(u32, K::Value)>, Counts);

    fn run<P: Probe>(&self, p: &mut P, tile: usize) -> Self::Out {
        let t = self.tiles.tile_rect(tile);
        let mut out = Vec::with_capacity(((t.x1 - t.x0) * (t.y1 - t.y0)) as usize);
        let mut counts = Counts::default();
        for (x0, y0) in t.blocks() {
            // The block's loop control and pixel offset.
            p.scalar(2);
            let block = Block {
                x0,
                y0,
                rows: BLOCK.min(t.y1 - y0),
                cols: BLOCK.min(t.x1 - x0),
                width: self.tiles.width,
                height: self.tiles.height,
            };
            self.kernel.block(p, &block, &mut out, &mut counts);
        }
        (out, counts)
    }
}

/// Step `name` of the current phase: `kernel` over the eye tiles with `weights`; every pixel's
/// value (each pixel is some block's) and the tasks' counts.
fn run_tiles<K: BlockKernel>(
    m: &mut Machine,
    frame: &Frame,
    name: &str,
    kernel: &K,
    weights: &[u64],
    fill: K::Value,
) -> (Vec<K::Value>, Counts) {
    let step = Tiles {
        kernel,
        tiles: eye_tiles(frame),
    };
    let tasks = m.run_step(name, &step, weights);
    let mut image = vec![fill; frame.gbuffer.len()];
    let mut counts = Counts::default();
    for (values, c) in &tasks {
        for &(i, v) in values {
            image[i as usize] = v;
        }
        counts.add(c);
    }
    (image, counts)
}

/// The shared per-pixel inputs as modelled buffers.
struct Inputs<'a> {
    points: Buffer<[f32; 4], &'a [[f32; 4]]>,
    normals: Buffer<[f32; 4], &'a [[f32; 4]]>,
}

impl Inputs<'_> {
    /// The block's rows of shading points and normals, loaded row by row.
    fn load<P: Probe>(&self, p: &mut P, b: &Block) -> (Lanes<[f32; 4]>, Lanes<[f32; 4]>) {
        let (mut pts, mut nrm) = ([[0.0; 4]; LANES], [[0.0; 4]; LANES]);
        for row in 0..b.rows {
            let i = b.row_start(row);
            let n = b.cols as usize;
            let ps = self.points.load_run(p, i, n);
            let ns = self.normals.load_run(p, i, n);
            for c in 0..n {
                pts[(row * BLOCK) as usize + c] = ps[c];
                nrm[(row * BLOCK) as usize + c] = ns[c];
            }
        }
        (pts, nrm)
    }
}

/// Records stores of the block's rows into `buf`.
fn store_rows<P: Probe, T: Copy + Default>(p: &mut P, buf: &Buffer<T>, b: &Block) {
    for row in 0..b.rows {
        buf.record_store(p, b.row_start(row), b.cols as usize);
    }
}

fn xyz(v: [f32; 4]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
}

/// A ray direction's reciprocal, each component at least 1e-20 in magnitude first (its sign
/// kept, +0 taken as positive), so the slab test never multiplies 0 by infinity.
pub fn safe_inverse(d: Vec3) -> Vec3 {
    let g = |x: f32| {
        let x = if x.abs() < 1e-20 {
            if x >= 0.0 {
                1e-20
            } else {
                -1e-20
            }
        } else {
            x
        };
        1.0 / x
    };
    Vec3::new(g(d.x), g(d.y), g(d.z))
}

/// Where the segment `o + t·d`, `t` in [0, 1], enters the box `lo`–`hi` (`inv` = 1/d), if it
/// meets it.
pub fn slab(o: Vec3, inv: Vec3, lo: [f32; 3], hi: [f32; 3]) -> Option<f32> {
    let t0 = (Vec3::from(lo) - o) * inv;
    let t1 = (Vec3::from(hi) - o) * inv;
    let near = t0.min(t1);
    let far = t0.max(t1);
    let tmin = near.x.max(near.y).max(near.z).max(0.0);
    let tmax = far.x.min(far.y).min(far.z).min(1.0);
    (tmin <= tmax).then_some(tmin)
}

/// Where the segment `o + t·d` crosses the plane of `tri` strictly inside (0, 1), with the
/// plane's normal.
pub fn plane_hit(tri: &Tri, o: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
    let (a, b, c) = (Vec3::from(tri.v0), Vec3::from(tri.v1), Vec3::from(tri.v2));
    let n = (b - a).cross(c - a);
    let nd = n.dot(d);
    if nd == 0.0 {
        return None;
    }
    let t = n.dot(a - o) / nd;
    (t > 0.0 && t < 1.0).then_some((t, n))
}

/// Whether the line `o + t·d` passes through `tri` (normal `n`), by the coverage rule.
pub fn crosses(tri: &Tri, o: Vec3, d: Vec3, n: Vec3) -> bool {
    let (a, b, c) = (Vec3::from(tri.v0), Vec3::from(tri.v1), Vec3::from(tri.v2));
    coverage::line_crosses(o, d, n, &[(a, b), (b, c), (c, a)])
}

/// The caster BVH as modelled buffers.
struct Bvh<'a> {
    nodes: Buffer<NodePair, &'a [NodePair]>,
    triangles: Buffer<Tri, &'a [Tri]>,
    root: Option<u32>,
}

impl<'a> Bvh<'a> {
    /// `bvh`'s arrays as buffers of `memory`.
    fn of(memory: &mut Memory, bvh: &'a CasterBvh) -> Bvh<'a> {
        Bvh {
            nodes: memory.borrowed("bvh_nodes", &bvh.nodes),
            triangles: memory.borrowed("bvh_triangles", &bvh.triangles),
            root: bvh.root,
        }
    }

    /// Any-hit traversal of the segments `o + t·d`, `t` in (0, 1), of the lanes `mask`: the
    /// lanes whose segment a caster blocks, and for them the segment parameter of the blocker
    /// found.
    fn traverse<P: Probe>(
        &self,
        p: &mut P,
        o: &Lanes<Vec3>,
        d: &Lanes<Vec3>,
        mask: Mask,
        counts: &mut Counts,
    ) -> (Mask, Lanes<f32>) {
        let mut t_hit = [0f32; LANES];
        let Some(root) = self.root else {
            return (Mask::NONE, t_hit);
        };
        p.vector(RAY_SETUP_OPS, mask);
        let inv: Lanes<Vec3> = std::array::from_fn(|l| safe_inverse(d[l]));
        let mut stack = [[0u32; STACK]; LANES];
        let mut sp = [0usize; LANES];
        for l in mask.lanes() {
            stack[l][0] = root;
            sp[l] = 1;
        }
        let mut hit = 0u16;
        let mut active = mask;
        while active.any() {
            p.scalar(2);
            let mut entry = [0u32; LANES];
            for l in active.lanes() {
                sp[l] -= 1;
                entry[l] = stack[l][sp[l]];
            }
            p.vector(POP_OPS, active);
            let leaf = active.and(Mask::from_fn(|l| entry[l] & LEAF != 0));
            let inner = active.and_not(leaf);
            if inner.any() {
                let pairs = self.nodes.gather(p, &entry, inner);
                p.vector(NODE_OPS, inner);
                counts.node_visits += u64::from(inner.count());
                for l in inner.lanes() {
                    let r = &pairs[l];
                    let ta = slab(o[l], inv[l], r.a_min, r.a_max);
                    let tb = slab(o[l], inv[l], r.b_min, r.b_max);
                    let s = &mut stack[l];
                    let mut push = |v: u32| {
                        s[sp[l]] = v;
                        sp[l] += 1;
                    };
                    match (ta, tb) {
                        (Some(a), Some(b)) if a <= b => {
                            push(r.b_ref);
                            push(r.a_ref);
                        }
                        (Some(_), Some(_)) => {
                            push(r.a_ref);
                            push(r.b_ref);
                        }
                        (Some(_), None) => push(r.a_ref),
                        (None, Some(_)) => push(r.b_ref),
                        (None, None) => {}
                    }
                }
            }
            if leaf.any() {
                p.vector(LEAF_OPS, leaf);
                let mut first = [0u32; LANES];
                let mut count = [0u32; LANES];
                for l in leaf.lanes() {
                    (first[l], count[l]) = leaf_range(entry[l]);
                }
                let most = leaf.lanes().map(|l| count[l]).max().unwrap_or(0);
                for j in 0..most {
                    let m = leaf.and(Mask::from_fn(|l| hit >> l & 1 == 0 && count[l] > j));
                    if !m.any() {
                        break;
                    }
                    let idx: Lanes<u32> = std::array::from_fn(|l| first[l] + j);
                    let tris = self.triangles.gather(p, &idx, m);
                    p.vector(PLANE_OPS, m);
                    counts.triangle_tests += u64::from(m.count());
                    let mut planes = [None; LANES];
                    for l in m.lanes() {
                        planes[l] = plane_hit(&tris[l], o[l], d[l]);
                    }
                    let crossing = Mask::from_fn(|l| planes[l].is_some());
                    p.vector(EDGE_OPS, crossing);
                    for l in crossing.lanes() {
                        let (t, n) = planes[l].expect("crossing lanes have a plane hit");
                        if crosses(&tris[l], o[l], d[l], n) {
                            hit |= 1 << l;
                            t_hit[l] = t;
                        }
                    }
                }
            }
            active = active.and(Mask::from_fn(|l| hit >> l & 1 == 0 && sp[l] > 0));
        }
        (Mask(hit).and(mask), t_hit)
    }
}

/// Whether a caster of `bvh` blocks the open segment from `p` to `q`: one ray of the trace's
/// traversal, uninstrumented.
pub fn segment_blocked(bvh: &CasterBvh, p: Vec3, q: Vec3) -> bool {
    let mut memory = Memory::default();
    let b = Bvh::of(&mut memory, bvh);
    let (o, d) = ([p; LANES], [q - p; LANES]);
    let (hit, _) = b.traverse(&mut NoProbe, &o, &d, Mask::first(1), &mut Counts::default());
    hit.get(0)
}

/// Step `trace`: per pixel its visible fraction and mean blocker distance (0 without a blocker).
struct Trace<'a> {
    inputs: &'a Inputs<'a>,
    bvh: &'a Bvh<'a>,
    light: Light,
    seed: u32,
    spp: u32,
    /// Visible fraction and mean blocker distance per pixel, and the visible fraction again
    /// where the first à-trous pass reads it (the wgpu execution writes both).
    traced: Buffer<[f32; 2]>,
    visibility: Buffer<f32>,
}

impl BlockKernel for Trace<'_> {
    type Value = [f32; 2];

    fn block<P: Probe>(
        &self,
        p: &mut P,
        b: &Block,
        out: &mut Vec<(u32, [f32; 2])>,
        counts: &mut Counts,
    ) {
        let (inside, idx) = b.lanes();
        let (pts, nrm) = self.inputs.load(p, b);
        let hit = inside.and(Mask::from_fn(|l| pts[l][3] > 0.0));
        let mut visible = [0u32; LANES];
        let mut rays = [0u32; LANES];
        let mut blocked = [0u32; LANES];
        let mut distance = [0f32; LANES];
        if hit.any() {
            p.vector(FRAME_OPS, hit);
            let origin: Lanes<Vec3> = std::array::from_fn(|l| xyz(pts[l]));
            let frames: Lanes<(Vec3, Vec3, Vec3)> = std::array::from_fn(|l| {
                if hit.get(l) {
                    self.light.emitter_frame(origin[l])
                } else {
                    (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO)
                }
            });
            for s in 0..self.spp {
                p.scalar(1);
                p.vector(SAMPLE_OPS + HORIZON_OPS, hit);
                let mut d = [Vec3::ZERO; LANES];
                let mut cast = 0u16;
                for l in hit.lanes() {
                    let (x, y) = b.pixel(l).expect("a lane inside the block");
                    let sq: Vec2 = square_sample(self.seed, (x, y, b.width), self.spp, s);
                    let q = light_point(&self.light, frames[l], sq);
                    d[l] = q - origin[l];
                    // A receiver-only surface hides the light behind its own plane.
                    let n = xyz(nrm[l]);
                    if nrm[l][3] == 0.0 || n.dot(d[l]) > 0.0 {
                        cast |= 1 << l;
                    } else {
                        counts.horizon_culled += 1;
                    }
                }
                let cast = Mask(cast);
                counts.rays += u64::from(cast.count());
                let (occluded, t) = self.bvh.traverse(p, &origin, &d, cast, counts);
                counts.occluded += u64::from(occluded.count());
                for l in cast.lanes() {
                    rays[l] += 1;
                    if occluded.get(l) {
                        blocked[l] += 1;
                        distance[l] += t[l] * d[l].length();
                    } else {
                        visible[l] += 1;
                    }
                }
            }
            p.vector(RESOLVE_OPS, hit);
        }
        store_rows(p, &self.traced, b);
        store_rows(p, &self.visibility, b);
        for l in inside.lanes() {
            if !hit.get(l) {
                out.push((idx[l], [1.0, 0.0]));
                continue;
            }
            if rays[l] > 0 && (visible[l] == 0 || visible[l] == rays[l]) {
                counts.agreeing += u64::from(rays[l] - 1);
            }
            let v = visible[l] as f32 / self.spp as f32;
            let mean = if blocked[l] > 0 {
                distance[l] / blocked[l] as f32
            } else {
                0.0
            };
            out.push((idx[l], [v, mean]));
        }
    }
}

/// The G-buffer entries and visibility of the tap `(dx, dy)` of the lanes `mask`: the lanes
/// whose tap is an image pixel that sees a surface, and its point, normal and value.
struct Tap {
    mask: Mask,
    point: Lanes<[f32; 4]>,
    normal: Lanes<[f32; 4]>,
}

impl Inputs<'_> {
    fn tap<P: Probe>(
        &self,
        p: &mut P,
        b: &Block,
        mask: Mask,
        offset: (i32, i32),
    ) -> (Tap, Lanes<u32>) {
        let (inside, idx) = b.neighbours(mask, offset);
        let point = self.points.gather(p, &idx, inside);
        let normal = self.normals.gather(p, &idx, inside);
        let mask = inside.and(Mask::from_fn(|l| point[l][3] > 0.0));
        (
            Tap {
                mask,
                point,
                normal,
            },
            idx,
        )
    }
}

/// Step `penumbra`: per pixel the radius in pixels the à-trous passes may reach, 0 where the
/// pixel is not filtered (no blocker near it, or its neighbourhood all lit or all shadowed).
struct Penumbra<'a> {
    inputs: &'a Inputs<'a>,
    /// Visible fraction and mean blocker distance per pixel (the trace's output).
    traced: Buffer<[f32; 2]>,
    offsets: Vec<(i32, i32)>,
    light_center: Vec3,
    light_radius: f32,
    max_radius: f32,
    radius: Buffer<f32>,
}

impl BlockKernel for Penumbra<'_> {
    type Value = f32;

    fn block<P: Probe>(
        &self,
        p: &mut P,
        b: &Block,
        out: &mut Vec<(u32, f32)>,
        counts: &mut Counts,
    ) {
        let (inside, idx) = b.lanes();
        let (pts, nrm) = self.inputs.load(p, b);
        let hit = inside.and(Mask::from_fn(|l| pts[l][3] > 0.0));
        let mut vmin = [f32::INFINITY; LANES];
        let mut vmax = [f32::NEG_INFINITY; LANES];
        let (mut sw, mut sd) = ([0f32; LANES], [0f32; LANES]);
        if hit.any() {
            for &(dx, dy) in &self.offsets {
                let (tap, qi) = self.inputs.tap(p, b, hit, (dx, dy));
                if !tap.mask.any() {
                    continue;
                }
                let traced = self.traced.gather(p, &qi, tap.mask);
                p.vector(TAP_OPS, tap.mask);
                counts.search_taps += u64::from(tap.mask.count());
                let offset = ((dx * dx + dy * dy) as f32).sqrt();
                for l in tap.mask.lanes() {
                    let w = if (dx, dy) == (0, 0) {
                        1.0
                    } else {
                        geometric_weight(
                            (xyz(pts[l]), xyz(nrm[l]), pts[l][3]),
                            (xyz(tap.point[l]), xyz(tap.normal[l])),
                            offset,
                        )
                    };
                    if w > 0.0 {
                        let [v, t] = traced[l];
                        vmin[l] = vmin[l].min(v);
                        vmax[l] = vmax[l].max(v);
                        if t > 0.0 {
                            sw[l] += w;
                            sd[l] += w * t;
                        }
                    }
                }
            }
            p.vector(PENUMBRA_OPS, hit);
        }
        store_rows(p, &self.radius, b);
        for l in inside.lanes() {
            let mut r = 0.0;
            if hit.get(l) && sw[l] > 0.0 && vmin[l] < vmax[l] {
                let x = xyz(pts[l]);
                r = penumbra_radius_px(
                    self.light_radius,
                    (self.light_center - x).length(),
                    sd[l] / sw[l],
                    pts[l][3],
                    self.max_radius,
                )
                .max(MIN_REACH);
            }
            if r > 0.0 {
                counts.filtered_pixels += 1;
            }
            out.push((idx[l], r));
        }
    }
}

/// Step `atrous`: one pass of the edge-avoiding à-trous filter at tap spacing `step` over the
/// pixels with a penumbra radius.
struct Atrous<'a> {
    inputs: &'a Inputs<'a>,
    input: Buffer<f32>,
    radius: &'a Buffer<f32>,
    step: i32,
    output: Buffer<f32>,
}

impl BlockKernel for Atrous<'_> {
    type Value = f32;

    fn block<P: Probe>(
        &self,
        p: &mut P,
        b: &Block,
        out: &mut Vec<(u32, f32)>,
        counts: &mut Counts,
    ) {
        let (inside, idx) = b.lanes();
        let mut own = [1f32; LANES];
        let mut reach = [0f32; LANES];
        for row in 0..b.rows {
            let i = b.row_start(row);
            let n = b.cols as usize;
            let v = self.input.load_run(p, i, n);
            let r = self.radius.load_run(p, i, n);
            for c in 0..n {
                own[(row * BLOCK) as usize + c] = v[c];
                reach[(row * BLOCK) as usize + c] = r[c];
            }
        }
        let filter = inside.and(Mask::from_fn(|l| reach[l] > 0.0));
        let mut result = own;
        if filter.any() {
            let (pts, nrm) = self.inputs.load(p, b);
            let centre = B3[2] * B3[2];
            let mut sum: Lanes<f32> = std::array::from_fn(|l| centre * own[l]);
            let mut wsum = [centre; LANES];
            for dy in -2i32..=2 {
                for dx in -2i32..=2 {
                    if (dx, dy) == (0, 0) {
                        continue;
                    }
                    let extent = (dx.abs().max(dy.abs()) * self.step) as f32;
                    let m = filter.and(Mask::from_fn(|l| extent <= reach[l]));
                    if !m.any() {
                        continue;
                    }
                    let o = (dx * self.step, dy * self.step);
                    let (tap, qi) = self.inputs.tap(p, b, m, o);
                    if !tap.mask.any() {
                        continue;
                    }
                    let v = self.input.gather(p, &qi, tap.mask);
                    p.vector(TAP_OPS, tap.mask);
                    counts.filter_taps += u64::from(tap.mask.count());
                    let h = B3[(dx + 2) as usize] * B3[(dy + 2) as usize];
                    let offset = ((o.0 * o.0 + o.1 * o.1) as f32).sqrt();
                    for l in tap.mask.lanes() {
                        let w = h * geometric_weight(
                            (xyz(pts[l]), xyz(nrm[l]), pts[l][3]),
                            (xyz(tap.point[l]), xyz(tap.normal[l])),
                            offset,
                        );
                        sum[l] += w * v[l];
                        wsum[l] += w;
                    }
                }
            }
            p.vector(NORMALIZE_OPS, inside);
            for l in filter.lanes() {
                result[l] = (sum[l] / wsum[l]).clamp(0.0, 1.0);
            }
        }
        store_rows(p, &self.output, b);
        for l in inside.lanes() {
            out.push((idx[l], result[l]));
        }
    }
}

/// `rt_denoised` on a CPU execution.
pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    o: &RtDenoisedOptions,
) -> Result<FrameOutput> {
    let caster_bvh = CasterBvh::build(frame)?;
    let inputs = PixelInputs::of(frame);
    let mut m = machine(backend, frame, ctx);
    let g = &frame.gbuffer;
    let n = g.len();
    let inputs_buf = Inputs {
        points: m.memory.borrowed("rt_points", &inputs.points),
        normals: m.memory.borrowed("rt_normals", &inputs.normals),
    };
    let (node_bytes, tri_bytes) = caster_bvh.bytes();
    let bvh = Bvh::of(&mut m.memory, &caster_bvh);
    let tiles = eye_tiles(frame);
    let hit_pixels = tiles.tile_weights(|i| g.is_hit(i));

    let traced_at = m.memory.reserve("rt_traced", (n * 8) as u64);
    let radius_at = m.memory.reserve("penumbra_radius", (n * 4) as u64);
    let ping = m.memory.reserve("atrous_ping", (n * 4) as u64);
    let pong = m.memory.reserve("atrous_pong", (n * 4) as u64);

    m.phase(Phase::Trace.name());
    let trace = Trace {
        inputs: &inputs_buf,
        bvh: &bvh,
        light: frame.scene.light,
        seed: seed32(ctx.seed),
        spp: o.spp,
        traced: Buffer::at(traced_at, Vec::new()),
        visibility: Buffer::at(ping, Vec::new()),
    };
    let trace_weights: Vec<u64> = hit_pixels.iter().map(|w| w * u64::from(o.spp)).collect();
    let (traced, tc) = run_tiles(&mut m, frame, "trace", &trace, &trace_weights, [1.0, 0.0]);
    m.count(names::RT_RAYS, tc.rays as f64);
    m.count(names::RT_NODE_VISITS, tc.node_visits as f64);
    m.count(names::RT_TRIANGLE_TESTS, tc.triangle_tests as f64);
    m.count(names::RT_OCCLUDED_RAYS, tc.occluded as f64);
    m.count(names::RT_HORIZON_CULLED, tc.horizon_culled as f64);
    m.count(names::RT_BVH_NODE_BYTES, node_bytes as f64);
    m.count(names::RT_BVH_TRIANGLE_BYTES, tri_bytes as f64);
    m.count(names::FILL, tc.rays as f64);
    m.count(names::OVERDRAW, tc.agreeing as f64);

    let mut visibility: Vec<f32> = traced.iter().map(|t| t[0]).collect();
    if o.denoise {
        m.phase(Phase::Denoise.name());
        let penumbra = Penumbra {
            inputs: &inputs_buf,
            traced: Buffer::at(traced_at, traced),
            offsets: search_offsets(o.radius),
            light_center: frame.scene.light.center(),
            light_radius: light_radius(&frame.scene.light),
            max_radius: o.radius as f32,
            radius: Buffer::at(radius_at, Vec::new()),
        };
        let (radius, pc) = run_tiles(&mut m, frame, "penumbra", &penumbra, &hit_pixels, 0.0);
        let radius = Buffer::at(radius_at, radius);
        let mut filter_taps = 0;
        for pass in 0..o.passes {
            let (from, to) = if pass % 2 == 0 {
                (ping, pong)
            } else {
                (pong, ping)
            };
            let atrous = Atrous {
                inputs: &inputs_buf,
                input: Buffer::at(from, visibility),
                radius: &radius,
                step: 1 << pass,
                output: Buffer::at(to, Vec::new()),
            };
            let (filtered, ac) = run_tiles(&mut m, frame, "atrous", &atrous, &hit_pixels, 1.0);
            visibility = filtered;
            filter_taps += ac.filter_taps;
        }
        m.count(names::DENOISE_SEARCH_TAPS, pc.search_taps as f64);
        m.count(names::DENOISE_FILTER_TAPS, filter_taps as f64);
        m.count(names::DENOISE_FILTERED_PIXELS, pc.filtered_pixels as f64);
        m.count(
            names::DENOISE_BUFFER_BYTES,
            super::buffer_bytes(&frame.params) as f64,
        );
    }
    let vis = VisibilityBuffer {
        width: g.width,
        height: g.height,
        data: visibility,
    };
    let mut out = output(m, vis);
    out.execution.insert(
        "bvh".into(),
        serde_json::json!({
            "nodes": caster_bvh.nodes.len(),
            "triangles": caster_bvh.triangles.len(),
            "depth": caster_bvh.depth,
        }),
    );
    Ok(out)
}
