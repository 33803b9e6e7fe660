//! The CPU executions (`cpu-native`, `cpu-model`) of soft irregular shadow mapping: the four
//! steps of Figure 2 as steps of [`Machine`] tasks, bin by bin as the sort-middle rasterizer of
//! §2.5 does. Each kernel is written once, generic over the [`Probe`]: on `cpu-model` the probe
//! counts what the modelled machine executes (16-lane vector instructions under their masks,
//! loads and stores per named buffer, gathers of sample records, scatters and atomics of the
//! grid construction); on `cpu-native` it compiles away.
//!
//! Every per-task result is computed independently and merged in task order, and each bin
//! walks its triangles and quads in input order, so the image and the counters do not depend
//! on the host's thread count.

use glam::Vec2;

use super::Phase;
use super::{
    clip_coords, combined_visibility, in_front, light_point, light_radius_uv, object_adjacency,
    occluders_of, quad_half_width, wedge_entry_inv_z, Grid, LightPoint, LightTriangle, Occluders,
    PenumbraQuad, ProjectedEdge, SoftIzbOptions,
};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{machine, output};
use crate::algorithms::shadow_map::{LightView, LightViews, ViewFit};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::{Buffer, BufferId, Lanes, Machine, Mask, Probe, TaskKernel, LANES};
use crate::record::PhaseId;
use crate::scene::adjacency::EdgeAdjacency;
use crate::visibility::VisibilityBuffer;

/// Pixels per task of the construction steps (a multiple of the 16 lanes).
const PIXEL_CHUNK: usize = 1024;
/// Occluding triangles or penumbra edges per task of a binning step.
const PRIMITIVE_CHUNK: usize = 256;
/// Bytes of a projected triangle with its flat index, and of a projected edge.
const TRIANGLE_BYTES: u32 = size_of::<(u32, LightTriangle)>() as u32;
const EDGE_BYTES: u32 = size_of::<ProjectedEdge>() as u32;

/// Vector instructions per 16 receivers to project them: offset along the normal (3
/// multiply-adds), the light's view-projection (4 rows × 4 multiply-adds), a reciprocal, uv (2
/// multiplies, 2 multiply-adds), the in-front compare, and the running nearest/farthest depth
/// (min, max).
const PROJECT_OPS: u32 = 3 + 16 + 1 + 4 + 1 + 2;
/// Vector instructions per 16 receivers to find their grid cell and bin: column (2 multiplies,
/// 2 floors, 2 clamps), depth slice (subtract, multiply, floor, clamp), cell index (bin, column
/// in bin, slice: 2 shifts, 2 ands, 3 multiply-adds), bin index (multiply-add).
const CELL_OPS: u32 = 6 + 4 + 7 + 1;
/// Vector instructions of a 16-wide inclusive scan: 4 lane shifts and 4 adds, plus the carry.
const SCAN_OPS: u32 = 9;
/// Vector instructions per 16 samples to assemble the sample records to scatter (2 address
/// multiply-adds).
const INSERT_OPS: u32 = 2;
/// Scalar instructions per occluder triangle in the geometry stage: facing test (3 subtracts, 2
/// 3-term dots), 3 vertex transforms (16 multiply-adds each), near clip (3 compares), projection
/// (3 × 4) and the area test (5); per silhouette edge, adjacency lookup and orientation (8).
const FACE_SETUP_OPS: u32 = 11 + 48 + 3 + 12 + 5;
const EDGE_SETUP_OPS: u32 = 8;
/// Scalar instructions to bin one primitive: bounds (4 min/max pairs), column range (4
/// multiplies, 4 floors, 4 clamps), bin range (4 shifts), and per bin its loop step (2).
const BIN_SETUP_OPS: u32 = 8 + 12 + 4;
const BIN_STEP_OPS: u32 = 2;
/// Scalar instructions per §2.5 per-bin width test of a quad in a bin: the width (subtract,
/// multiply), and the separating-axis test of the quad frame against the bin rectangle (about
/// 30).
const BIN_WIDTH_OPS: u32 = 32;
/// Scalar instructions per primitive taken from a bin: clip its bounds to the bin (8), its
/// nearest slice (4), edge setup for the vector tests (6).
const PRIM_SETUP_OPS: u32 = 18;
/// Scalar instructions per grid column visited: loop control and the cell range lookup.
const COLUMN_OPS: u32 = 4;
/// Scalar instructions per quad fragment: quad/column overlap (separating axes, about 30) and,
/// with the wedge cull, the column's distance to the edge and the entry slice (about 20).
const FRAGMENT_OPS: u32 = 30;
const WEDGE_OPS: u32 = 20;
/// Vector instructions per 16 samples of the irregular rasterization (§2.4): own-triangle
/// compare, two barycentrics (2 subtracts, cross product, divide each), the third (2
/// subtracts), 3 compares and 2 mask ands, `1/z` interpolation (3 multiply-adds), the depth
/// compare and mask and.
const COVER_OPS: u32 = 1 + 10 + 2 + 5 + 3 + 2;
/// Vector instructions per 16 samples of eq. 3 with the sign rule: nearest edge point (2
/// subtracts, dot, clamp, multiply), its `1/z` (multiply-add), footprint radius (subtract,
/// multiply, compare), signed distance (cross product, divide, abs, divide, compare), chord
/// ends (square root, 4 divides/clamps), θ (5 multiply-adds, square root, divide, clamp, acos
/// ≈ 12), the area (3) and the sign select.
const EQ3_OPS: u32 = 5 + 1 + 3 + 5 + 5 + 19 + 3 + 1;
/// Vector instructions per 16 samples to accumulate into the per-sample occlusion (add, mask).
const ACCUMULATE_OPS: u32 = 2;
/// Vector instructions per 16 samples of eq. 4 (add, clamp, subtract, finite select).
const COMBINE_OPS: u32 = 4;

/// One eye-view receiver point in the grid (20 bytes: uv, 1/z, eye pixel, receiver triangle).
#[derive(Clone, Copy, Debug, Default)]
struct Sample {
    p: LightPoint,
    pixel: u32,
    triangle: u32,
}

/// A modelled array whose contents live elsewhere on the host (or only in the model): its
/// accesses are recorded by element index.
#[derive(Clone, Copy)]
struct Region {
    id: BufferId,
    base: u64,
    stride: u32,
}

impl Region {
    fn new(m: &mut Machine, name: &str, len: usize, stride: u32) -> Region {
        let (id, base) = m.memory.reserve(name, len as u64 * u64::from(stride));
        Region { id, base, stride }
    }

    fn addr(&self, i: usize) -> u64 {
        self.base + i as u64 * u64::from(self.stride)
    }

    fn read<P: Probe>(&self, p: &mut P, i: usize, n: usize) {
        p.read(self.id, self.addr(i), self.stride * n as u32);
    }

    fn write<P: Probe>(&self, p: &mut P, i: usize, n: usize) {
        p.write(self.id, self.addr(i), self.stride * n as u32);
    }

    fn atomic<P: Probe>(&self, p: &mut P, i: usize) {
        p.atomic(self.id, self.addr(i), self.stride);
    }

    /// A gather (`write` false) or scatter of elements `idx` on `mask`'s lanes.
    fn lanes<P: Probe>(&self, p: &mut P, idx: &Lanes<usize>, mask: Mask, write: bool) {
        if P::ENABLED {
            let addrs: Lanes<u64> = std::array::from_fn(|l| self.addr(idx[l]));
            if write {
                p.scatter(self.id, &addrs, self.stride, mask);
            } else {
                p.gather(self.id, &addrs, self.stride, mask);
            }
        }
    }
}

/// The light-space acceleration structure of Figure 3.
struct Izb {
    grid: Grid,
    /// Start of each cell's samples (cells + 1 entries), buffer `izb_grid`.
    cell_start: Buffer<u32>,
    /// Buffer `izb_samples`.
    samples: Buffer<Sample>,
    /// Per bin, `1/z` of its deepest receiver (`INFINITY` for a bin without samples).
    bin_inv_z_back: Vec<f32>,
}

impl Izb {
    fn bin_range(&self, b: usize) -> std::ops::Range<usize> {
        let c = self.grid.cells_per_bin();
        self.cell_start.data[b * c] as usize..self.cell_start.data[(b + 1) * c] as usize
    }

    /// Samples of column (x, y) from slice `k0` to the back: two loads of `izb_grid`.
    fn column_from<P: Probe>(&self, p: &mut P, x: u32, y: u32, k0: u32) -> std::ops::Range<usize> {
        let g = &self.grid;
        p.scalar(COLUMN_OPS);
        let s0 = self.cell_start.load(p, g.cell(x, y, k0));
        let s1 = self.cell_start.load(p, g.cell(x, y, g.slices - 1) + 1);
        s0 as usize..s1 as usize
    }

    /// Gathers the sample records `s..s + n` (n ≤ 16) into lanes: the records are stored as
    /// structures, so each lane loads its own.
    fn gather<P: Probe>(&self, p: &mut P, s: usize, n: usize) -> (Lanes<Sample>, Mask) {
        let mask = Mask::first(n);
        let idx: Lanes<u32> = std::array::from_fn(|l| (s + l.min(n - 1)) as u32);
        (self.samples.gather(p, &idx, mask), mask)
    }
}

/// The 16-lane blocks of pixel chunk `task`: (first pixel, lanes).
fn blocks(len: usize, task: usize) -> impl Iterator<Item = (usize, usize)> {
    let start = task * PIXEL_CHUNK;
    let end = (start + PIXEL_CHUNK).min(len);
    (start..end)
        .step_by(LANES)
        .map(move |i| (i, LANES.min(end - i)))
}

fn pixel_weights(len: usize) -> Vec<u64> {
    (0..len.div_ceil(PIXEL_CHUNK))
        .map(|t| (PIXEL_CHUNK.min(len - t * PIXEL_CHUNK)) as u64)
        .collect()
}

/// Step "project" of `construct`: each receiver's light-view point, and the chunk's nearest
/// and farthest receiver.
struct Project<'a> {
    frame: &'a Frame,
    view: &'a LightView,
    position: Buffer<glam::Vec3, &'a [glam::Vec3]>,
    normal: Buffer<glam::Vec3, &'a [glam::Vec3]>,
    triangle: Buffer<u32, &'a [u32]>,
}

impl TaskKernel for Project<'_> {
    type Out = (Vec<Option<LightPoint>>, f32, f32);

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Self::Out {
        let g = &self.frame.gbuffer;
        let mut out = Vec::with_capacity(PIXEL_CHUNK);
        let (mut front, mut back) = (f32::NEG_INFINITY, f32::INFINITY);
        for (i, n) in blocks(g.len(), task) {
            p.scalar(2);
            let tri = self.triangle.load_run(p, i, n);
            let hit = Mask::from_fn(|l| l < n && tri[l] != u32::MAX);
            if !hit.any() {
                out.extend(std::iter::repeat_n(None, n));
                continue;
            }
            let pos = self.position.load_run(p, i, n);
            self.normal.load_run(p, i, n);
            p.vector(PROJECT_OPS, hit);
            for (l, &pos) in pos.iter().enumerate().take(n) {
                let point = hit.get(l).then(|| {
                    // The shading point (position + offset, `GBuffer::shading_point`); the
                    // modelled loads of position and normal stand for its two vectors.
                    let c = clip_coords(self.view, pos + self.frame.gbuffer.offset[i + l]);
                    in_front(self.view, c).then(|| light_point(c))
                });
                let point = point.flatten();
                if let Some(q) = point {
                    front = front.max(q.inv_z);
                    back = back.min(q.inv_z);
                }
                out.push(point);
            }
        }
        (out, front, back)
    }
}

/// Step "count" of `construct`: each receiver's cell, counted into the grid (an atomic
/// increment) and its depth folded into its bin's deepest receiver (an atomic minimum).
struct Count<'a> {
    grid: &'a Grid,
    projected: &'a [Option<LightPoint>],
    counts: Region,
    bin_depth: Region,
}

impl TaskKernel for Count<'_> {
    /// Per pixel of the chunk, its cell (`u32::MAX` for none).
    type Out = Vec<u32>;

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Vec<u32> {
        let mut out = Vec::with_capacity(PIXEL_CHUNK);
        for (i, n) in blocks(self.projected.len(), task) {
            p.scalar(2);
            let pts = &self.projected[i..i + n];
            let mask = Mask::from_fn(|l| l < n && pts[l].is_some());
            if mask.any() {
                p.vector(CELL_OPS, mask);
            }
            for q in pts {
                let Some(q) = q else {
                    out.push(u32::MAX);
                    continue;
                };
                let (x, y) = self.grid.column(q.uv);
                let c = self.grid.cell(x, y, self.grid.slice(q.inv_z));
                self.counts.atomic(p, c + 1);
                self.bin_depth.atomic(p, self.grid.bin_of_column(x, y));
                out.push(c as u32);
            }
        }
        out
    }
}

/// Step "scan" of `construct`: each bin's cell counts turned into running sums (the bins' own
/// totals are then carried across bins in bin order).
struct Scan<'a> {
    grid: &'a Grid,
    counts: &'a Buffer<u32>,
}

impl TaskKernel for Scan<'_> {
    type Out = Vec<u32>;

    fn run<P: Probe>(&self, p: &mut P, b: usize) -> Vec<u32> {
        let per_bin = self.grid.cells_per_bin();
        let first = b * per_bin + 1;
        let mut out = Vec::with_capacity(per_bin);
        let mut sum = 0u32;
        for j in (0..per_bin).step_by(LANES) {
            let n = LANES.min(per_bin - j);
            let counts = self.counts.load_run(p, first + j, n);
            p.vector(SCAN_OPS, Mask::first(n));
            for &c in counts {
                sum += c;
                out.push(sum);
            }
            self.counts.record_store(p, first + j, n);
        }
        out
    }
}

/// Step "insert" of `construct`: each receiver takes the next slot of its cell (an atomic
/// fetch-and-add on the cell's cursor) and its sample record is scattered there.
struct Insert<'a> {
    projected: &'a [Option<LightPoint>],
    cell_of: &'a [u32],
    /// What each receiver's fetch-and-add returns when the chunks run in order.
    slot_of: &'a [u32],
    cursors: Region,
    triangle: Buffer<u32, &'a [u32]>,
    samples: Region,
}

impl TaskKernel for Insert<'_> {
    type Out = Vec<(u32, Sample)>;

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Self::Out {
        let mut out = Vec::new();
        for (i, n) in blocks(self.projected.len(), task) {
            p.scalar(2);
            let mask = Mask::from_fn(|l| l < n && self.projected[i + l].is_some());
            if !mask.any() {
                continue;
            }
            let tri = self.triangle.load_run(p, i, n);
            let mut slots = [0usize; LANES];
            for l in mask.lanes() {
                self.cursors.atomic(p, self.cell_of[i + l] as usize);
                slots[l] = self.slot_of[i + l] as usize;
                let sample = Sample {
                    p: self.projected[i + l].expect("an active lane has a point"),
                    pixel: (i + l) as u32,
                    triangle: tri[l],
                };
                out.push((slots[l] as u32, sample));
            }
            p.vector(INSERT_OPS, mask);
            self.samples.lanes(p, &slots, mask, true);
        }
        out
    }
}

/// Step (a) of Figure 2 (phase `construct`): project the receiver points and insert them into
/// the grid: count per cell and record per-bin maximum depth (atomics), prefix-sum, then
/// scatter each sample to its cell's next slot (an atomic cursor). Returns the structure and
/// the pixels with no light-view position (at or behind the light's view plane).
fn construct(
    m: &mut Machine,
    frame: &Frame,
    view: &LightView,
    opts: &SoftIzbOptions,
) -> (Izb, u64) {
    m.phase(Phase::Construct.name());
    let g = &frame.gbuffer;
    let triangle = m.memory.borrowed("gbuffer.triangle", &g.triangle);
    let project = Project {
        frame,
        view,
        position: m.memory.borrowed("gbuffer.position", &g.position),
        normal: m.memory.borrowed("gbuffer.normal", &g.normal),
        triangle: triangle.clone(),
    };
    let weights = pixel_weights(g.len());
    let mut projected = Vec::with_capacity(g.len());
    let (mut front, mut back) = (f32::NEG_INFINITY, f32::INFINITY);
    for (pts, f, b) in m.run_step("project", &project, &weights) {
        projected.extend(pts);
        front = front.max(f);
        back = back.min(b);
    }
    let hits = (0..g.len()).filter(|&i| g.is_hit(i)).count() as u64;

    let res = view.resolution.max(1);
    let mut grid = Grid {
        res,
        slices: opts.depth_slices,
        bin: frame.params.tile_size.clamp(1, res),
        inv_z_front: front,
        inv_z_back: back,
    };
    if !front.is_finite() {
        grid.inv_z_front = 1.0;
        grid.inv_z_back = 1.0;
    }

    let cells = grid.cells();
    let (grid_id, grid_base) = m.memory.reserve("izb_grid", 4 * (cells as u64 + 1));
    let grid_region = Region {
        id: grid_id,
        base: grid_base,
        stride: 4,
    };
    let bin_depth = Region::new(m, "bins", grid.bins(), 4);
    let count = Count {
        grid: &grid,
        projected: &projected,
        counts: grid_region,
        bin_depth,
    };
    let mut cell_of = Vec::with_capacity(g.len());
    let mut cell_start = vec![0u32; cells + 1];
    let mut bin_inv_z_back = vec![f32::INFINITY; grid.bins()];
    for cs in m.run_step("count", &count, &weights) {
        cell_of.extend(cs);
    }
    let mut n = 0u64;
    for (c, q) in cell_of.iter().zip(&projected) {
        if let Some(q) = q {
            let c = *c as usize;
            cell_start[c + 1] += 1;
            let b = c / grid.cells_per_bin();
            bin_inv_z_back[b] = bin_inv_z_back[b].min(q.inv_z);
            n += 1;
        }
    }

    let counts = Buffer::at((grid_id, grid_base), cell_start);
    let scan = Scan {
        grid: &grid,
        counts: &counts,
    };
    let per_bin = grid.cells_per_bin();
    let scanned = m.run_step("scan", &scan, &vec![per_bin as u64; grid.bins()]);
    let mut cell_start = counts.data;
    let mut carry = 0u32;
    for (b, sums) in scanned.iter().enumerate() {
        for (j, s) in sums.iter().enumerate() {
            cell_start[b * per_bin + j + 1] = carry + s;
        }
        carry += sums.last().copied().unwrap_or(0);
    }

    let mut cursor = cell_start.clone();
    let mut slot_of = vec![0u32; g.len()];
    for (i, q) in projected.iter().enumerate() {
        if q.is_some() {
            let c = cell_of[i] as usize;
            slot_of[i] = cursor[c];
            cursor[c] += 1;
        }
    }
    let samples_region = Region::new(m, "izb_samples", n as usize, size_of::<Sample>() as u32);
    let insert = Insert {
        projected: &projected,
        cell_of: &cell_of,
        slot_of: &slot_of,
        cursors: grid_region,
        triangle,
        samples: samples_region,
    };
    let mut samples = vec![Sample::default(); n as usize];
    for out in m.run_step("insert", &insert, &weights) {
        for (slot, s) in out {
            samples[slot as usize] = s;
        }
    }
    m.count(names::SAMPLES, n as f64);
    m.count(names::IZB_GRID_BYTES, 4.0 * (cells + 1) as f64);
    m.count(
        names::IZB_SAMPLES_BYTES,
        (size_of::<Sample>() as u64 * n) as f64,
    );
    (
        Izb {
            grid,
            cell_start: Buffer::at((grid_id, grid_base), cell_start),
            samples: Buffer::at((samples_region.id, samples_region.base), samples),
            bin_inv_z_back,
        },
        hits - n,
    )
}

/// Step "setup" of `geometry`: one task per scene object.
struct Setup<'a> {
    frame: &'a Frame,
    view: &'a LightView,
    opts: &'a SoftIzbOptions,
    /// Per object its edge adjacency (`None` for objects that do not occlude).
    adjacency: &'a [Option<EdgeAdjacency>],
}

impl TaskKernel for Setup<'_> {
    type Out = Occluders;

    fn run<P: Probe>(&self, p: &mut P, o: usize) -> Occluders {
        let occ = match &self.adjacency[o] {
            Some(adj) => occluders_of(self.frame, self.view, self.opts, o, adj),
            None => Occluders::default(),
        };
        let faces = self.frame.scene.objects[o].mesh.triangles.len() as u32;
        p.scalar(FACE_SETUP_OPS * faces + EDGE_SETUP_OPS * occ.edges.len() as u32);
        occ
    }
}

/// Step "store" of `geometry`: each object's primitives written at their offsets.
struct Store<'a> {
    /// Per object: first triangle, triangles, first edge, edges.
    spans: &'a [[usize; 4]],
    triangles: Region,
    edges: Region,
}

impl TaskKernel for Store<'_> {
    type Out = ();

    fn run<P: Probe>(&self, p: &mut P, o: usize) {
        let [t0, nt, e0, ne] = self.spans[o];
        p.scalar(4);
        if nt > 0 {
            self.triangles.write(p, t0, nt);
        }
        if ne > 0 {
            self.edges.write(p, e0, ne);
        }
    }
}

/// The paper's geometry stage (phase `geometry`; §2.1, §4.2: silhouette detection and
/// primitive setup, not counted in Table 2). A triangle occludes when it faces the light
/// centre; in an open mesh (boundary or non-manifold edges) every triangle does, as the surface
/// has no back to pair with. Penumbra edges are the silhouette from adjacency, or every edge of
/// every occluding triangle (§2.1), each oriented with its surface inside.
fn occluders(
    m: &mut Machine,
    frame: &Frame,
    view: &LightView,
    opts: &SoftIzbOptions,
    adjacency: &[Option<EdgeAdjacency>],
) -> (Occluders, Region, Region) {
    m.phase(Phase::Geometry.name());
    let objects = &frame.scene.objects;
    let weights: Vec<u64> = objects
        .iter()
        .map(|o| o.mesh.triangles.len() as u64)
        .collect();
    let setup = Setup {
        frame,
        view,
        opts,
        adjacency,
    };
    let per_object = m.run_step("setup", &setup, &weights);
    let mut occ = Occluders {
        triangles: vec![],
        edges: vec![],
    };
    let mut spans = Vec::with_capacity(per_object.len());
    for o in per_object {
        spans.push([
            occ.triangles.len(),
            o.triangles.len(),
            occ.edges.len(),
            o.edges.len(),
        ]);
        occ.triangles.extend(o.triangles);
        occ.edges.extend(o.edges);
    }
    let store = Store {
        spans: &spans,
        triangles: Region::new(m, "light_triangles", occ.triangles.len(), TRIANGLE_BYTES),
        edges: Region::new(m, "penumbra_edges", occ.edges.len(), EDGE_BYTES),
    };
    let weights: Vec<u64> = spans.iter().map(|s| (s[1] + s[3]) as u64).collect();
    m.run_step("store", &store, &weights);
    m.count(names::OCCLUDER_TRIANGLES, occ.triangles.len() as f64);
    m.count(names::SILHOUETTE_EDGES, occ.edges.len() as f64);
    (occ, store.triangles, store.edges)
}

/// Inclusive column range of uv bounds clipped to bin `b`, if they meet.
fn columns_in_bin(grid: &Grid, b: usize, lo: Vec2, hi: Vec2) -> Option<((u32, u32), (u32, u32))> {
    let ((x0, y0), (x1, y1)) = grid.column_range(lo, hi);
    let ((bx0, by0), (bx1, by1)) = grid.bin_columns(b);
    let (x0, y0, x1, y1) = (x0.max(bx0), y0.max(by0), x1.min(bx1), y1.min(by1));
    (x0 <= x1 && y0 <= y1).then_some(((x0, y0), (x1, y1)))
}

/// Bins overlapped by uv bounds, in bin order.
fn bins_of(grid: &Grid, lo: Vec2, hi: Vec2) -> impl Iterator<Item = usize> + '_ {
    let ((x0, y0), (x1, y1)) = grid.column_range(lo, hi);
    let (b0, b1) = (
        (x0 / grid.bin, y0 / grid.bin),
        (x1 / grid.bin, y1 / grid.bin),
    );
    (b0.1..=b1.1)
        .flat_map(move |by| (b0.0..=b1.0).map(move |bx| (by * grid.bins_x() + bx) as usize))
}

/// A primitive's place in a bin: its index, the quad half-width (0 for triangles) and where
/// the binning step wrote the entry.
#[derive(Clone, Copy)]
struct Entry {
    prim: u32,
    half_width: f32,
    slot: usize,
}

/// What binning one primitive found: (bin, half-width) per bin it goes to, and the bins it
/// tested and dropped.
struct Binned {
    bins: Vec<(usize, f32)>,
    tested: u32,
    culled: u64,
}

/// A binning step: each task bins `PRIMITIVE_CHUNK` primitives and appends their entries to
/// its own slab of `bins` (the per-core bin queues of a sort-middle rasterizer).
struct Binning<'a, F> {
    count: usize,
    prims: Region,
    entries: Region,
    /// Entries of one task's slab: its worst case, every primitive in every bin.
    slab: usize,
    /// Scalar instructions per tested bin beyond the loop step.
    bin_ops: u32,
    bin: &'a F,
}

impl<F: Fn(usize) -> Binned + Sync> TaskKernel for Binning<'_, F> {
    type Out = (Vec<(usize, Entry)>, u64);

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Self::Out {
        let start = task * PRIMITIVE_CHUNK;
        let end = (start + PRIMITIVE_CHUNK).min(self.count);
        let base = task * self.slab;
        let mut out = Vec::new();
        let mut culled = 0;
        for i in start..end {
            self.prims.read(p, i, 1);
            let b = (self.bin)(i);
            p.scalar(BIN_SETUP_OPS + (BIN_STEP_OPS + self.bin_ops) * b.tested);
            culled += b.culled;
            for (bin, half_width) in b.bins {
                let slot = base + out.len();
                out.push((
                    bin,
                    Entry {
                        prim: i as u32,
                        half_width,
                        slot,
                    },
                ));
            }
        }
        if !out.is_empty() {
            self.entries.write(p, base, out.len());
        }
        (out, culled)
    }
}

/// Runs a binning step; returns each bin's entries in primitive order, and the bins dropped.
fn bin_primitives<F: Fn(usize) -> Binned + Sync>(
    m: &mut Machine,
    grid: &Grid,
    prims: Region,
    count: usize,
    entry_bytes: u32,
    bin_ops: u32,
    bin: &F,
) -> (Vec<Vec<Entry>>, Region, u64) {
    let tasks = count.div_ceil(PRIMITIVE_CHUNK);
    let slab = PRIMITIVE_CHUNK * grid.bins();
    let entries = Region::new(m, "bins", tasks * slab, entry_bytes);
    let kernel = Binning {
        count,
        prims,
        entries,
        slab,
        bin_ops,
        bin,
    };
    let weights: Vec<u64> = (0..tasks)
        .map(|t| PRIMITIVE_CHUNK.min(count - t * PRIMITIVE_CHUNK) as u64)
        .collect();
    let mut lists = vec![Vec::new(); grid.bins()];
    let mut culled = 0;
    for (out, c) in m.run_step("bin", &kernel, &weights) {
        culled += c;
        for (b, e) in out {
            lists[b].push(e);
        }
    }
    let n: usize = lists.iter().map(Vec::len).sum();
    m.count(names::BIN_ENTRIES, n as f64);
    (lists, entries, culled)
}

/// Per-bin task weights: its samples times its primitives.
fn bin_weights(izb: &Izb, lists: &[Vec<Entry>]) -> Vec<u64> {
    lists
        .iter()
        .enumerate()
        .map(|(b, l)| 1 + izb.bin_range(b).len() as u64 * l.len() as u64)
        .collect()
}

/// Step "test" of `hard` (§2.4): each occluding triangle of a bin, tested exactly against the
/// stored sample positions under it, from the grid slice of its nearest point backwards, counts
/// one unit of depth complexity at every sample it covers in front of.
struct Umbra<'a> {
    izb: &'a Izb,
    occ: &'a Occluders,
    lists: &'a [Vec<Entry>],
    entries: Region,
    triangles: Region,
    occlusion: Region,
}

impl TaskKernel for Umbra<'_> {
    type Out = (Vec<u32>, [u64; 3]);

    fn run<P: Probe>(&self, p: &mut P, b: usize) -> Self::Out {
        let (izb, grid) = (self.izb, &self.izb.grid);
        let range = izb.bin_range(b);
        let base = range.start;
        let mut depth_complexity = vec![0u32; range.len()];
        let (mut columns, mut tests, mut hits) = (0u64, 0u64, 0u64);
        if range.is_empty() {
            return (depth_complexity, [0; 3]);
        }
        for e in &self.lists[b] {
            self.entries.read(p, e.slot, 1);
            self.triangles.read(p, e.prim as usize, 1);
            p.scalar(PRIM_SETUP_OPS);
            let (flat, tri) = &self.occ.triangles[e.prim as usize];
            let (lo, hi) = tri.bounds();
            let Some(((x0, y0), (x1, y1))) = columns_in_bin(grid, b, lo, hi) else {
                continue;
            };
            let k0 = grid.slice(tri.inv_z_near());
            for y in y0..=y1 {
                for x in x0..=x1 {
                    columns += 1;
                    let col = izb.column_from(p, x, y, k0);
                    for s in col.clone().step_by(LANES) {
                        let n = LANES.min(col.end - s);
                        let (samples, mask) = izb.gather(p, s, n);
                        p.vector(COVER_OPS, mask);
                        tests += n as u64;
                        let mut hit = Mask::NONE;
                        for l in mask.lanes() {
                            let sample = &samples[l];
                            if sample.triangle == *flat {
                                continue;
                            }
                            if let Some(inv_z) = tri.covers(sample.p.uv) {
                                if inv_z > sample.p.inv_z {
                                    depth_complexity[s + l - base] += 1;
                                    hit.0 |= 1 << l;
                                }
                            }
                        }
                        if hit.any() {
                            hits += u64::from(hit.count());
                            let idx: Lanes<usize> = std::array::from_fn(|l| s + l);
                            self.occlusion.lanes(p, &idx, hit, false);
                            p.vector(ACCUMULATE_OPS, hit);
                            self.occlusion.lanes(p, &idx, hit, true);
                        }
                    }
                }
            }
        }
        (depth_complexity, [columns, tests, hits])
    }
}

/// Step (b) of Figure 2 (phase `hard`): hard irregular shadow mapping from the light centre.
fn umbra(m: &mut Machine, izb: &Izb, occ: &Occluders, triangles: Region) -> Vec<Vec<u32>> {
    m.phase(Phase::Hard.name());
    let grid = &izb.grid;
    let bin = |i: usize| {
        let (lo, hi) = occ.triangles[i].1.bounds();
        let bins: Vec<(usize, f32)> = bins_of(grid, lo, hi).map(|b| (b, 0.0)).collect();
        Binned {
            tested: bins.len() as u32,
            bins,
            culled: 0,
        }
    };
    let (lists, entries, _) = bin_primitives(m, grid, triangles, occ.triangles.len(), 4, 0, &bin);
    let kernel = Umbra {
        izb,
        occ,
        lists: &lists,
        entries,
        triangles,
        occlusion: Region::new(m, "occlusion", izb.samples.data.len(), 4),
    };
    let per_bin = m.run_step("test", &kernel, &bin_weights(izb, &lists));
    let [mut columns, mut tests, mut hits] = [0u64; 3];
    let mut out = Vec::with_capacity(per_bin.len());
    for (dc, c) in per_bin {
        columns += c[0];
        tests += c[1];
        hits += c[2];
        out.push(dc);
    }
    m.count(names::HARD_COLUMNS, columns as f64);
    m.count(names::HARD_TESTS, tests as f64);
    m.count(names::HARD_HITS, hits as f64);
    out
}

/// What the penumbra pass of one bin did.
#[derive(Default, Clone, Copy)]
struct SoftWork {
    fragments: u64,
    wedge_culled_fragments: u64,
    fill: u64,
    contributing: u64,
}

/// Step "test" of `soft` (§2.3, §2.5): per quad fragment, the samples of the grid column (from
/// where the wedge enters it, or all) get eq. 3 with the sign rule.
struct Penumbra<'a> {
    izb: &'a Izb,
    occ: &'a Occluders,
    lists: &'a [Vec<Entry>],
    entries: Region,
    edges: Region,
    occlusion: Region,
    r_uv: f32,
    wedge_column_cull: bool,
}

impl TaskKernel for Penumbra<'_> {
    type Out = (Vec<f32>, SoftWork);

    fn run<P: Probe>(&self, p: &mut P, b: usize) -> Self::Out {
        let (izb, grid, r_uv) = (self.izb, &self.izb.grid, self.r_uv);
        let range = izb.bin_range(b);
        let base = range.start;
        let mut occlusion = vec![0f32; range.len()];
        let mut w = SoftWork::default();
        if range.is_empty() {
            return (occlusion, w);
        }
        let last = grid.res - 1;
        for e in &self.lists[b] {
            self.entries.read(p, e.slot, 1);
            self.edges.read(p, e.prim as usize, 1);
            p.scalar(PRIM_SETUP_OPS);
            let edge = self.occ.edges[e.prim as usize];
            let quad = PenumbraQuad {
                edge,
                half_width: e.half_width,
            };
            let (lo, hi) = quad.bounds();
            let Some(((x0, y0), (x1, y1))) = columns_in_bin(grid, b, lo, hi) else {
                continue;
            };
            for y in y0..=y1 {
                for x in x0..=x1 {
                    p.scalar(FRAGMENT_OPS);
                    let (clo, chi) = grid.column_rect(x, y);
                    if !quad.overlaps(clo, chi) {
                        continue;
                    }
                    w.fragments += 1;
                    let k0 = if self.wedge_column_cull {
                        p.scalar(WEDGE_OPS);
                        // Border columns hold clamped samples from outside the uv square.
                        let border = x == 0 || y == 0 || x == last || y == last;
                        let distance = if border {
                            0.0
                        } else {
                            let half = (chi - clo) * 0.5;
                            (edge.distance(clo + half) - half.length()).max(0.0)
                        };
                        match wedge_entry_inv_z(r_uv, edge.inv_z_near(), distance) {
                            Some(inv_z) => grid.slice(inv_z),
                            None => {
                                w.wedge_culled_fragments += 1;
                                continue;
                            }
                        }
                    } else {
                        0
                    };
                    let col = izb.column_from(p, x, y, k0);
                    for s in col.clone().step_by(LANES) {
                        let n = LANES.min(col.end - s);
                        let (samples, mask) = izb.gather(p, s, n);
                        p.vector(EQ3_OPS, mask);
                        w.fill += n as u64;
                        let mut hit = Mask::NONE;
                        for l in mask.lanes() {
                            let v = edge.penumbral_occlusion(r_uv, samples[l].p);
                            if v != 0.0 {
                                occlusion[s + l - base] += v;
                                hit.0 |= 1 << l;
                            }
                        }
                        if hit.any() {
                            w.contributing += u64::from(hit.count());
                            let idx: Lanes<usize> = std::array::from_fn(|l| s + l);
                            self.occlusion.lanes(p, &idx, hit, false);
                            p.vector(ACCUMULATE_OPS, hit);
                            self.occlusion.lanes(p, &idx, hit, true);
                        }
                    }
                }
            }
        }
        (occlusion, w)
    }
}

/// Step "resolve" of `soft`: eq. 4 at each sample of a bin, scattered to its eye pixel.
struct Resolve<'a> {
    izb: &'a Izb,
    depth_complexity: &'a [Vec<u32>],
    penumbral: &'a [Vec<f32>],
    umbra: Region,
    penumbra: Region,
    visibility: Region,
}

impl TaskKernel for Resolve<'_> {
    type Out = Vec<(u32, f32)>;

    fn run<P: Probe>(&self, p: &mut P, b: usize) -> Self::Out {
        let range = self.izb.bin_range(b);
        let mut out = Vec::with_capacity(range.len());
        for s in range.clone().step_by(LANES) {
            let n = LANES.min(range.end - s);
            self.umbra.read(p, s, n);
            self.penumbra.read(p, s, n);
            let (samples, mask) = self.izb.gather(p, s, n);
            p.vector(COMBINE_OPS, mask);
            let mut pixels = [0usize; LANES];
            for l in mask.lanes() {
                let k = s + l - range.start;
                pixels[l] = samples[l].pixel as usize;
                out.push((
                    samples[l].pixel,
                    combined_visibility(self.depth_complexity[b][k], self.penumbral[b][k]),
                ));
            }
            self.visibility.lanes(p, &pixels, mask, true);
        }
        out
    }
}

/// Steps (c) and (d) of Figure 2 (phase `soft`; §2.2, §2.3, §2.5): one penumbra quad per edge,
/// binned with its width from the deepest receiver (of the scene, or of each bin); then eq. 4.
#[allow(clippy::too_many_arguments)]
fn penumbra(
    m: &mut Machine,
    frame: &Frame,
    izb: &Izb,
    occ: &Occluders,
    edges: Region,
    r_uv: f32,
    opts: &SoftIzbOptions,
    depth_complexity: &[Vec<u32>],
) -> Vec<f32> {
    m.phase(Phase::Soft.name());
    let grid = &izb.grid;
    let bin = |i: usize| {
        let edge = occ.edges[i];
        let mut out = Binned {
            bins: vec![],
            tested: 0,
            culled: 0,
        };
        let half_width = quad_half_width(r_uv, edge.inv_z_near(), grid.inv_z_back);
        if half_width <= 0.0 {
            return out; // behind every receiver
        }
        let quad = PenumbraQuad { edge, half_width };
        let (lo, hi) = quad.bounds();
        for b in bins_of(grid, lo, hi) {
            out.tested += 1;
            if !opts.per_bin_width {
                out.bins.push((b, half_width));
                continue;
            }
            let w = quad_half_width(r_uv, edge.inv_z_near(), izb.bin_inv_z_back[b]);
            let (blo, bhi) = grid.bin_rect(b);
            let narrowed = PenumbraQuad {
                edge,
                half_width: w,
            };
            if w > 0.0 && narrowed.overlaps(blo, bhi) {
                out.bins.push((b, w));
            } else {
                out.culled += 1;
            }
        }
        out
    };
    let quads = occ
        .edges
        .iter()
        .filter(|e| quad_half_width(r_uv, e.inv_z_near(), grid.inv_z_back) > 0.0)
        .count();
    let width_ops = if opts.per_bin_width { BIN_WIDTH_OPS } else { 0 };
    let (lists, entries, culled) =
        bin_primitives(m, grid, edges, occ.edges.len(), 8, width_ops, &bin);
    m.count(names::PENUMBRA_QUADS, quads as f64);
    m.count(names::BIN_CULLED_QUADS, culled as f64);

    let n = izb.samples.data.len();
    let kernel = Penumbra {
        izb,
        occ,
        lists: &lists,
        entries,
        edges,
        occlusion: Region::new(m, "occlusion", n, 4),
        r_uv,
        wedge_column_cull: opts.wedge_column_cull,
    };
    let per_bin = m.run_step("test", &kernel, &bin_weights(izb, &lists));
    let mut total = SoftWork::default();
    let mut penumbral = Vec::with_capacity(per_bin.len());
    for (occlusion, w) in per_bin {
        total.fragments += w.fragments;
        total.wedge_culled_fragments += w.wedge_culled_fragments;
        total.fill += w.fill;
        total.contributing += w.contributing;
        penumbral.push(occlusion);
    }
    m.count(names::QUAD_FRAGMENTS, total.fragments as f64);
    m.count(
        names::WEDGE_CULLED_FRAGMENTS,
        total.wedge_culled_fragments as f64,
    );
    m.count(names::FILL, total.fill as f64);
    m.count(names::OVERDRAW, (total.fill - total.contributing) as f64);

    let g = &frame.gbuffer;
    let resolve = Resolve {
        izb,
        depth_complexity,
        penumbral: &penumbral,
        umbra: Region::new(m, "occlusion", n, 4),
        penumbra: kernel.occlusion,
        visibility: Region::new(m, "visibility", g.len(), 4),
    };
    let weights: Vec<u64> = (0..grid.bins())
        .map(|b| 1 + izb.bin_range(b).len() as u64)
        .collect();
    let mut data = vec![1.0f32; g.len()];
    for out in m.run_step("resolve", &resolve, &weights) {
        for (pixel, v) in out {
            data[pixel as usize] = v;
        }
    }
    data
}

/// `soft_izb` on a CPU execution.
pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &SoftIzbOptions,
) -> Result<FrameOutput> {
    let light = frame.scene.light;
    super::check_grid_size(frame.params.map_resolution, opts.depth_slices)?;
    let views = LightViews::fit(frame, ViewFit::Single);
    let view = *views.single();
    let r_uv = light_radius_uv(&view, light.size());

    // The occluders' adjacency is the meshes' (as the other algorithms build theirs before
    // their phases); the geometry phase detects silhouettes with it.
    let adjacency: Vec<Option<EdgeAdjacency>> = (0..frame.scene.objects.len())
        .map(|o| object_adjacency(frame, o))
        .collect();
    let mut m = machine(backend, frame, ctx);
    let (izb, outside) = construct(&mut m, frame, &view, opts);
    let (occ, triangles, edges) = occluders(&mut m, frame, &view, opts, &adjacency);
    let depth_complexity = umbra(&mut m, &izb, &occ, triangles);
    let data = penumbra(
        &mut m,
        frame,
        &izb,
        &occ,
        edges,
        r_uv,
        opts,
        &depth_complexity,
    );

    let g = &frame.gbuffer;
    let visibility = VisibilityBuffer {
        width: g.width,
        height: g.height,
        data,
    };
    let mut out = output(m, visibility);
    views.record(&mut out);
    if outside > 0 {
        out.warnings.push(format!(
            "{outside} receiver points lie at or behind the light's view plane and are taken as lit"
        ));
    }
    for (k, v) in [
        ("grid", serde_json::json!(izb.grid.res)),
        ("depth_slices", serde_json::json!(izb.grid.slices)),
        ("bin", serde_json::json!(izb.grid.bin)),
        ("per_bin_width", serde_json::json!(opts.per_bin_width)),
        (
            "wedge_column_cull",
            serde_json::json!(opts.wedge_column_cull),
        ),
        (
            "silhouettes",
            serde_json::to_value(opts.silhouettes).unwrap_or_default(),
        ),
    ] {
        out.execution.insert(k.to_string(), v);
    }
    Ok(out)
}

/// Bytes of the grid (at the default depth slicing) and the sample array, estimated before
/// anything is allocated, for the harness's memory limit.
pub fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
    let res = u64::from(p.map_resolution);
    let pixels = u64::from(p.image[0]) * u64::from(p.image[1]);
    let slices = u64::from(SoftIzbOptions::default().depth_slices);
    4 * (res * res * slices + 1) + pixels * size_of::<Sample>() as u64
}
