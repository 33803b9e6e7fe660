// Soft irregular shadow mapping (paper 004) as compute passes. Every function mirrors the Rust
// function of src/algorithms/soft_izb/mod.rs named beside it, with the same operations in the
// same order; constants come from the host through `P` so that they are defined once, in Rust.
//
// Phase `construct` (Figure 2a, Figure 3): `clear`, `project`, `count`, `scan_local`,
// `scan_blocks`, `scan_add`, `insert`. Phase `hard` (Figure 2b, §2.4): `umbra`. Phase `soft`
// (Figure 2c-d, §2.2, §2.3, §2.5, eq. 3 and 4): `penumbra`, `resolve`.
//
// Light-view quantities are uv in the image plane and inverse linear depth 1/z, as on the CPU.

// The parameters `Params` are declared in wgpu.rs and joined before this file.

// A stored receiver point (20 bytes, as the cpu execution's `Sample`).
struct Sample {
    u: f32,
    v: f32,
    inv_z: f32,
    pixel: u32,
    triangle: u32,
}

// LightTriangle: three (u, v, 1/z), twice the signed uv area, and the flat triangle index.
struct Tri {
    u0: f32, v0: f32, z0: f32,
    u1: f32, v1: f32, z1: f32,
    u2: f32, v2: f32, z2: f32,
    area2: f32,
    flat: u32,
}

// ProjectedEdge: (u, v, 1/z) of a and of b, oriented with the occluding surface inside.
struct Edge {
    au: f32, av: f32, az: f32,
    bu: f32, bv: f32, bz: f32,
}

// Statistics slots of the instrumented pipelines (64-bit, as lo/hi word pairs); the host names
// them in `Stat`.
const STAT_HARD_COLUMNS: u32 = 0u;
const STAT_HARD_TESTS: u32 = 1u;
const STAT_HARD_HITS: u32 = 2u;
const STAT_HARD_BIN_ENTRIES: u32 = 3u;
const STAT_QUADS: u32 = 4u;
const STAT_BIN_CULLED: u32 = 5u;
const STAT_SOFT_BIN_ENTRIES: u32 = 6u;
const STAT_FRAGMENTS: u32 = 7u;
const STAT_WEDGE_CULLED: u32 = 8u;
const STAT_FILL: u32 = 9u;
const STAT_CONTRIBUTING: u32 = 10u;

const NONE: u32 = 0xffffffffu;
// Bits of +infinity: the depth of a bin without samples (bin_inv_z_back = INFINITY on the CPU).
const INF_BITS: u32 = 0x7f800000u;
// f32::MIN_POSITIVE (ProjectedEdge::distance).
const MIN_POSITIVE: f32 = 1.1754944e-38;
// Cells per invocation of the per-cell kernels (`clear`, `scan_local`, `scan_add`): the grid
// has far more cells than the frame has pixels (512² × 8 by default), and a CPU adapter pays
// for every invocation, so each walks a run of consecutive cells.
const CELLS_PER_ITEM: u32 = 16u;
// Cells of one block of the prefix sum: 256 invocations × CELLS_PER_ITEM cells.
const SCAN_BLOCK: u32 = 4096u;

// Invocations of a workgroup of the one-workgroup-per-primitive kernels (umbra, penumbra).
const PRIM_WG: u32 = 64u;

// True in the instrumented pipelines: count columns, tests, fragments and fill with atomics.
override INSTRUMENT: bool = false;

@group(0) @binding(0) var<uniform> P: Params;
// GBuffer: position bits with the flat triangle index in w (0xffffffff: no surface).
@group(0) @binding(1) var<storage, read> positions: array<vec4<u32>>;
// GBuffer::offset: from the position to the shading point (`GBuffer::shading_point`).
@group(0) @binding(2) var<storage, read> offsets: array<vec4<f32>>;
// Per pixel: uv and 1/z bits, and in w its cell (NONE: no light-view position).
@group(0) @binding(3) var<storage, read_write> points: array<vec4<u32>>;
// [0]: 1/z bits of the nearest receiver (atomicMax), [1]: of the farthest (atomicMin), then per
// bin the farthest receiver of the bin (atomicMin). Positive floats order as their bits, so the
// atomic minimum of the bits of 1/z is the maximum receiver depth.
@group(0) @binding(4) var<storage, read_write> depth: array<atomic<u32>>;
// Per cell: its sample count, then (after the scan) its insertion cursor.
@group(0) @binding(5) var<storage, read_write> counts: array<atomic<u32>>;
// izb_grid: start of each cell's samples (cells + 1 entries), then the scan's block sums.
@group(0) @binding(6) var<storage, read_write> cell_start: array<u32>;
// izb_samples: the sample array of Figure 3, cell after cell.
@group(0) @binding(7) var<storage, read_write> samples: array<Sample>;
// Per sample: [2s] umbral depth complexity, [2s + 1] penumbral occlusion in fixed point
// (two's complement i32 added as u32: the sum wraps exactly like an i32 sum).
@group(0) @binding(8) var<storage, read_write> occlusion: array<atomic<u32>>;
@group(0) @binding(9) var<storage, read_write> visibility: array<f32>;
@group(0) @binding(10) var<storage, read> triangles: array<Tri>;
@group(0) @binding(11) var<storage, read> edges: array<Edge>;
@group(0) @binding(12) var<storage, read_write> stats: array<atomic<u32>>;

// Adds `n` to 64-bit statistic `slot` (carry into the high word when the low word wraps).
fn stat(slot: u32, n: u32) {
    if (!INSTRUMENT || n == 0u) {
        return;
    }
    let old = atomicAdd(&stats[2u * slot], n);
    if (old + n < old) {
        atomicAdd(&stats[2u * slot + 1u], 1u);
    }
}

// Linear index of an invocation of a 64-wide kernel dispatched as a 2D grid of workgroups.
fn item(wid: vec3<u32>, nwg: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * nwg.x + wid.x) * 64u + lid;
}

// Index of the primitive of a one-workgroup-per-primitive kernel.
fn prim_index(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.y * nwg.x + wid.x;
}

fn perp_dot(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

// Vec2::length
fn len2(e: vec2<f32>) -> f32 {
    return sqrt(e.x * e.x + e.y * e.y);
}

// ---- Grid (mod.rs) ----

// inv_z_front and inv_z_back of the grid: those of the nearest and farthest receiver, or 1 when
// there is none (`construct` on the CPU).
fn grid_depths() -> vec2<f32> {
    let front = atomicLoad(&depth[0]);
    if (front == 0u) {
        return vec2<f32>(1.0, 1.0);
    }
    return vec2<f32>(bitcast<f32>(front), bitcast<f32>(atomicLoad(&depth[1])));
}

// Grid::column, one coordinate.
fn column1(x: f32) -> u32 {
    return u32(min(max(floor(x * f32(P.res)), 0.0), f32(P.res - 1u)));
}

// Grid::column
fn column(p: vec2<f32>) -> vec2<u32> {
    return vec2<u32>(column1(p.x), column1(p.y));
}

// Grid::slice
fn slice(inv_z: f32, front_back: vec2<f32>) -> u32 {
    let span = front_back.x - front_back.y;
    if (span <= 0.0) {
        return 0u;
    }
    let f = (front_back.x - inv_z) / span * f32(P.slices);
    return u32(min(max(floor(f), 0.0), f32(P.slices - 1u)));
}

// Grid::bin_of_column
fn bin_of_column(x: u32, y: u32) -> u32 {
    return (y / P.bin) * P.bins_x + x / P.bin;
}

// Grid::cell
fn cell(x: u32, y: u32, k: u32) -> u32 {
    let local = ((y % P.bin) * P.bin + x % P.bin) * P.slices + k;
    return bin_of_column(x, y) * P.cells_per_bin + local;
}

// Izb::bin_range is not empty.
fn bin_has_samples(b: u32) -> bool {
    return cell_start[(b + 1u) * P.cells_per_bin] > cell_start[b * P.cells_per_bin];
}

// An axis-aligned uv rectangle; `open_lo`/`open_hi` mark the sides that Grid::column_rect and
// Grid::bin_rect put at infinity (border columns hold the clamped samples from outside the uv
// square).
struct Rect {
    lo: vec2<f32>,
    hi: vec2<f32>,
    open_lo: vec2<bool>,
    open_hi: vec2<bool>,
}

// Grid::column_rect
fn column_rect(x: u32, y: u32) -> Rect {
    let s = 1.0 / f32(P.res);
    let last = P.res - 1u;
    return Rect(
        vec2<f32>(f32(x) * s, f32(y) * s),
        vec2<f32>(f32(x + 1u) * s, f32(y + 1u) * s),
        vec2<bool>(x == 0u, y == 0u),
        vec2<bool>(x == last, y == last),
    );
}

// Grid::bin_columns: inclusive column range of bin b, as (x0, y0, x1, y1).
fn bin_columns(b: u32) -> vec4<u32> {
    let bx = b % P.bins_x;
    let by = b / P.bins_x;
    return vec4<u32>(
        bx * P.bin,
        by * P.bin,
        min((bx + 1u) * P.bin, P.res) - 1u,
        min((by + 1u) * P.bin, P.res) - 1u,
    );
}

// Grid::bin_rect
fn bin_rect(b: u32) -> Rect {
    let c = bin_columns(b);
    let lo = column_rect(c.x, c.y);
    let hi = column_rect(c.z, c.w);
    return Rect(lo.lo, hi.hi, lo.open_lo, hi.open_hi);
}

// ---- Penumbra quads (§2.2) ----

struct Quad {
    a: vec2<f32>,
    b: vec2<f32>,
    half_width: f32,
}

// PenumbraQuad::frame: centre, unit axis along the edge, half extents (along, across).
struct Frame {
    c: vec2<f32>,
    dir: vec2<f32>,
    h: vec2<f32>,
}

fn quad_frame(q: Quad) -> Frame {
    let e = q.b - q.a;
    let len = len2(e);
    var dir = vec2<f32>(1.0, 0.0);
    if (len > 0.0) {
        dir = e / len;
    }
    return Frame((q.a + q.b) * 0.5, dir, vec2<f32>(len * 0.5 + q.half_width, q.half_width));
}

// PenumbraQuad::bounds, as (lo, hi).
fn quad_bounds(q: Quad) -> vec4<f32> {
    let f = quad_frame(q);
    let ext = vec2<f32>(
        abs(f.dir.x) * f.h.x + abs(f.dir.y) * f.h.y,
        abs(f.dir.y) * f.h.x + abs(f.dir.x) * f.h.y,
    );
    return vec4<f32>(f.c - ext, f.c + ext);
}

// PenumbraQuad::overlaps. On the CPU the open sides are infinities: they pass every bounds
// comparison, and the separating-axis test against an infinite rectangle never separates (its
// projections are infinite or NaN, and NaN compares false).
fn quad_overlaps(q: Quad, r: Rect) -> bool {
    let qb = quad_bounds(q);
    if ((!r.open_hi.x && qb.x > r.hi.x) || (!r.open_hi.y && qb.y > r.hi.y)
        || (!r.open_lo.x && qb.z < r.lo.x) || (!r.open_lo.y && qb.w < r.lo.y)) {
        return false;
    }
    if (any(r.open_lo) || any(r.open_hi)) {
        return true;
    }
    let f = quad_frame(q);
    let rc = (r.lo + r.hi) * 0.5 - f.c;
    let rh = (r.hi - r.lo) * 0.5;
    // Axis along the edge, then across (Vec2::perp: (-y, x)).
    return !separates(rc, rh, f.dir, f.h.x) && !separates(rc, rh, vec2<f32>(-f.dir.y, f.dir.x), f.h.y);
}

// One axis of the separating-axis test of PenumbraQuad::overlaps.
fn separates(rc: vec2<f32>, rh: vec2<f32>, axis: vec2<f32>, extent: f32) -> bool {
    let r = rh.x * abs(axis.x) + rh.y * abs(axis.y);
    return abs(rc.x * axis.x + rc.y * axis.y) > extent + r;
}

// ---- Formulas of §2.2-§2.5 (mod.rs) ----

// footprint_radius (§2.3, Figure 4): R = r·(1/z_q − 1/z_p).
fn footprint_radius(inv_z_q: f32, inv_z_p: f32) -> f32 {
    return P.r_uv * (inv_z_q - inv_z_p);
}

// quad_half_width (§2.2, [Parker et al. 1998]).
fn quad_half_width(inv_z_edge_near: f32, inv_z_receiver_max_depth: f32) -> f32 {
    return footprint_radius(inv_z_edge_near, inv_z_receiver_max_depth);
}

// wedge_entry_inv_z (§2.5, second optimisation); a result <= 0 means no depth is deep enough.
fn wedge_entry_inv_z(inv_z_edge_near: f32, distance: f32) -> f32 {
    return inv_z_edge_near - distance / P.r_uv;
}

// circular_segment_area (§2.3, eq. 3): θ = acos((d² − w0·w1)/√((d² + w0²)(d² + w1²))),
// Ṽ'' = (θ − d(w0 + w1))/2π, with w0 = −s0, w1 = s1.
fn circular_segment_area(d: f32, s0: f32, s1: f32) -> f32 {
    let w0 = -s0;
    let w1 = s1;
    let denom = sqrt((d * d + w0 * w0) * (d * d + w1 * w1));
    if (denom <= 0.0 || s1 <= s0) {
        return 0.0;
    }
    let theta = acos(clamp((d * d - w0 * w1) / denom, -1.0, 1.0));
    return max((theta - d * (w0 + w1)) / (2.0 * 3.14159265358979323846), 0.0);
}

// ProjectedEdge::inv_z_near
fn edge_inv_z_near(e: Edge) -> f32 {
    return max(e.az, e.bz);
}

// ProjectedEdge::distance
fn edge_distance(e: Edge, p: vec2<f32>) -> f32 {
    let a = vec2<f32>(e.au, e.av);
    let d = vec2<f32>(e.bu, e.bv) - a;
    let q = p - a;
    let t = clamp((d.x * q.x + d.y * q.y) / max(d.x * d.x + d.y * d.y, MIN_POSITIVE), 0.0, 1.0);
    return len2(a + d * t - p);
}

// ProjectedEdge::penumbral_occlusion (§2.3, Figure 4, eq. 3 with the sign rule): positive when
// p is outside the edge, negative inside, zero when the edge is behind p or farther than R.
fn penumbral_occlusion(e: Edge, p: vec2<f32>, p_inv_z: f32) -> f32 {
    let a = vec2<f32>(e.au, e.av);
    let ed = vec2<f32>(e.bu, e.bv) - a;
    let len = len2(ed);
    if (len <= 0.0) {
        return 0.0;
    }
    let dir = ed / len;
    let ap = p - a;
    let t = clamp(dir.x * ap.x + dir.y * ap.y, 0.0, len);
    let inv_z_q = e.az + (e.bz - e.az) * (t / len);
    let r = footprint_radius(inv_z_q, p_inv_z);
    if (r <= 0.0) {
        return 0.0;
    }
    let side = perp_dot(ed, ap) / len;
    let d = abs(side) / r;
    if (d >= 1.0) {
        return 0.0;
    }
    let foot = dir.x * ap.x + dir.y * ap.y;
    let half_chord = sqrt(1.0 - d * d);
    let s0 = clamp(-foot / r, -half_chord, half_chord);
    let s1 = clamp((len - foot) / r, -half_chord, half_chord);
    let area = circular_segment_area(d, s0, s1);
    if (cov_edge_covers_2d(p, vec2<f32>(e.bu, e.bv), a)) {
        return -area;
    }
    return area;
}

// combined_visibility (§2.4, eq. 4, C = 0 of §5.2).
fn combined_visibility(depth_complexity: u32, penumbral: f32) -> f32 {
    let o = f32(depth_complexity) + penumbral;
    return 1.0 - clamp(o, 0.0, 1.0);
}

// ---- construct (Figure 2a, Figure 3) ----

// The j-th cell (j < CELLS_PER_ITEM) of invocation `lid` of workgroup `wid` of a per-cell
// kernel: a workgroup takes 64 * CELLS_PER_ITEM consecutive cells, and at each step its
// invocations take 64 consecutive ones.
fn cell_of_item(wid: vec3<u32>, nwg: vec3<u32>, lid: u32, j: u32) -> u32 {
    return ((wid.y * nwg.x + wid.x) * CELLS_PER_ITEM + j) * 64u + lid;
}

// Resets the per-cell counts (CELLS_PER_ITEM cells per invocation) and the depth records (one
// per invocation).
@compute @workgroup_size(64)
fn clear(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
         @builtin(local_invocation_index) lid: u32) {
    let i = item(wid, nwg, lid);
    for (var j = 0u; j < CELLS_PER_ITEM; j++) {
        let c = cell_of_item(wid, nwg, lid, j);
        if (c < P.cells) {
            atomicStore(&counts[c], 0u);
        }
    }
    if (i == 0u) {
        atomicStore(&depth[0], 0u);
    }
    if (i >= 1u && i < arrayLength(&depth)) {
        atomicStore(&depth[i], INF_BITS);
    }
}

// Step "project": each receiver's light-view point (clip_coords, in_front, light_point) and the
// nearest and farthest receiver; every pixel starts lit.
@compute @workgroup_size(64)
fn project(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
    let i = item(wid, nwg, lid);
    if (i >= P.pixels) {
        return;
    }
    visibility[i] = 1.0;
    let g = positions[i];
    points[i] = vec4<u32>(0u, 0u, 0u, NONE);
    if (g.w == NONE) {
        return;
    }
    let q = bitcast<vec3<f32>>(g.xyz) + offsets[i].xyz;
    let m = P.view_proj;
    let c = m[0] * q.x + m[1] * q.y + m[2] * q.z + m[3];
    if (!(c.w > P.w_min)) {
        return;
    }
    let ndc = c.xy / c.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    let inv_z = 1.0 / c.w;
    points[i] = vec4<u32>(bitcast<vec2<u32>>(uv), bitcast<u32>(inv_z), 0u);
    atomicMax(&depth[0], bitcast<u32>(inv_z));
    atomicMin(&depth[1], bitcast<u32>(inv_z));
}

// Step "count": each receiver's cell counted (atomic increment) and its depth folded into its
// bin's farthest receiver (atomic minimum of 1/z).
@compute @workgroup_size(64)
fn count(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
         @builtin(local_invocation_index) lid: u32) {
    let i = item(wid, nwg, lid);
    if (i >= P.pixels || points[i].w == NONE) {
        return;
    }
    let pt = points[i];
    let uv = bitcast<vec2<f32>>(pt.xy);
    let inv_z = bitcast<f32>(pt.z);
    let col = column(uv);
    let c = cell(col.x, col.y, slice(inv_z, grid_depths()));
    atomicAdd(&counts[c], 1u);
    atomicMin(&depth[2u + bin_of_column(col.x, col.y)], pt.z);
    points[i].w = c;
}

var<workgroup> scan_shared: array<u32, 256>;

// Inclusive scan of `scan_shared` across the workgroup (Hillis-Steele).
fn workgroup_scan(lid: u32) {
    for (var off = 1u; off < 256u; off <<= 1u) {
        workgroupBarrier();
        var add = 0u;
        if (lid >= off) {
            add = scan_shared[lid - off];
        }
        workgroupBarrier();
        scan_shared[lid] += add;
    }
    workgroupBarrier();
}

// Step "scan", 1 of 3: exclusive prefix sums of the cell counts within blocks of SCAN_BLOCK
// cells, and each block's total (after the cells + 1 starts).
@compute @workgroup_size(256)
fn scan_local(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
              @builtin(local_invocation_index) lid: u32) {
    let block = wid.y * nwg.x + wid.x;
    if (block >= P.scan_blocks) {
        return;
    }
    let first = block * SCAN_BLOCK + CELLS_PER_ITEM * lid;
    var v: array<u32, CELLS_PER_ITEM>;
    var sum = 0u;
    for (var j = 0u; j < CELLS_PER_ITEM; j++) {
        var n = 0u;
        if (first + j < P.cells) {
            n = atomicLoad(&counts[first + j]);
        }
        v[j] = n;
        sum += n;
    }
    scan_shared[lid] = sum;
    workgroup_scan(lid);
    var run = scan_shared[lid] - sum;
    for (var j = 0u; j < CELLS_PER_ITEM; j++) {
        if (first + j < P.cells) {
            cell_start[first + j] = run;
        }
        run += v[j];
    }
    if (lid == 255u) {
        cell_start[P.cells + 1u + block] = scan_shared[255];
    }
}

// Step "scan", 2 of 3 (one workgroup): the block totals turned into exclusive block offsets,
// and the total (the number of samples) stored as the last cell start.
@compute @workgroup_size(256)
fn scan_blocks(@builtin(local_invocation_index) lid: u32) {
    let n = P.scan_blocks;
    let per = (n + 255u) / 256u;
    let base = P.cells + 1u;
    let lo = min(lid * per, n);
    let hi = min(lo + per, n);
    var sum = 0u;
    for (var j = lo; j < hi; j++) {
        sum += cell_start[base + j];
    }
    scan_shared[lid] = sum;
    workgroup_scan(lid);
    var run = scan_shared[lid] - sum;
    for (var j = lo; j < hi; j++) {
        let t = cell_start[base + j];
        cell_start[base + j] = run;
        run += t;
    }
    if (lid == 255u) {
        cell_start[P.cells] = scan_shared[255];
    }
}

// Step "scan", 3 of 3: block offsets added; each cell's cursor starts at its first slot
// (CELLS_PER_ITEM cells per invocation).
@compute @workgroup_size(64)
fn scan_add(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
            @builtin(local_invocation_index) lid: u32) {
    for (var j = 0u; j < CELLS_PER_ITEM; j++) {
        let c = cell_of_item(wid, nwg, lid, j);
        if (c < P.cells) {
            let s = cell_start[c] + cell_start[P.cells + 1u + c / SCAN_BLOCK];
            cell_start[c] = s;
            atomicStore(&counts[c], s);
        }
    }
}

// Step "insert": each receiver takes the next slot of its cell (atomic fetch-and-add on the
// cell's cursor) and its record is scattered there; its occlusion accumulators start at 0.
// Samples of one cell land in the order the atomics are served; no later result depends on
// the order within a cell.
@compute @workgroup_size(64)
fn insert(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
          @builtin(local_invocation_index) lid: u32) {
    let i = item(wid, nwg, lid);
    if (i >= P.pixels || points[i].w == NONE) {
        return;
    }
    let pt = points[i];
    let slot = atomicAdd(&counts[pt.w], 1u);
    samples[slot] = Sample(bitcast<f32>(pt.x), bitcast<f32>(pt.y), bitcast<f32>(pt.z), i,
                           positions[i].w);
    atomicStore(&occlusion[2u * slot], 0u);
    atomicStore(&occlusion[2u * slot + 1u], 0u);
}

// ---- hard (Figure 2b, §2.4) ----

// Samples of column (x, y) from slice k0 to the back (Izb::column_from), as [s0, s1).
fn column_from(x: u32, y: u32, k0: u32) -> vec2<u32> {
    return vec2<u32>(cell_start[cell(x, y, k0)], cell_start[cell(x, y, P.slices - 1u) + 1u]);
}

// One workgroup per occluding triangle; its invocations share the grid columns under the
// triangle's bounds. Each stored sample there, from the slice of the triangle's nearest point
// backwards, is tested exactly (LightTriangle::covers); one unit of depth complexity is added
// atomically at every sample the triangle covers in front of.
@compute @workgroup_size(PRIM_WG)
fn umbra(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
         @builtin(local_invocation_index) lid: u32) {
    let t = prim_index(wid, nwg);
    if (t >= P.triangles) {
        return;
    }
    let tri = triangles[t];
    let a = vec2<f32>(tri.u0, tri.v0);
    let b = vec2<f32>(tri.u1, tri.v1);
    let c = vec2<f32>(tri.u2, tri.v2);
    // LightTriangle::bounds and Grid::column_range.
    let lo = column(min(min(a, b), c));
    let hi = column(max(max(a, b), c));
    let k0 = slice(max(max(tri.z0, tri.z1), tri.z2), grid_depths());
    if (lid == 0u) {
        let bins = (hi.x / P.bin - lo.x / P.bin + 1u) * (hi.y / P.bin - lo.y / P.bin + 1u);
        stat(STAT_HARD_BIN_ENTRIES, bins);
    }
    let w = hi.x - lo.x + 1u;
    let n = w * (hi.y - lo.y + 1u);
    var columns = 0u;
    var tests = 0u;
    var hits = 0u;
    for (var j = lid; j < n; j += PRIM_WG) {
        let x = lo.x + j % w;
        let y = lo.y + j / w;
        if (!bin_has_samples(bin_of_column(x, y))) {
            continue;
        }
        columns += 1u;
        let range = column_from(x, y, k0);
        tests += range.y - range.x;
        for (var s = range.x; s < range.y; s++) {
            let smp = samples[s];
            if (smp.triangle == tri.flat) {
                continue;
            }
            // LightTriangle::covers
            let p = vec2<f32>(smp.u, smp.v);
            let e = cov_triangle_covers_2d(p, a, b, c);
            if (e.w != 0.0) {
                let w = e.xyz / tri.area2;
                let inv_z = w.x * tri.z0 + w.y * tri.z1 + w.z * tri.z2;
                if (inv_z > smp.inv_z) {
                    atomicAdd(&occlusion[2u * s], 1u);
                    hits += 1u;
                }
            }
        }
    }
    stat(STAT_HARD_COLUMNS, columns);
    stat(STAT_HARD_TESTS, tests);
    stat(STAT_HARD_HITS, hits);
}

// ---- soft (Figure 2c-d, §2.2, §2.3, §2.5) ----

// Half-width of an edge's quad in bin b (§2.5, first optimisation), or a value <= 0 when the
// quad is dropped from the bin: the bin has no samples, or the narrowed quad misses it.
fn bin_half_width(e: Edge, b: u32) -> f32 {
    let bits = atomicLoad(&depth[2u + b]);
    if (bits == INF_BITS) {
        return -1.0;
    }
    let w = quad_half_width(edge_inv_z_near(e), bitcast<f32>(bits));
    if (w > 0.0 && quad_overlaps(Quad(vec2<f32>(e.au, e.av), vec2<f32>(e.bu, e.bv), w),
                                 bin_rect(b))) {
        return w;
    }
    return -1.0;
}

// One workgroup per silhouette edge; its invocations share the grid columns under the edge's
// penumbra quad (width from the deepest receiver of the scene). Per column: the bin's quad
// width (with the per-bin option), the quad/column overlap (a fragment), the wedge entry slice
// (with the wedge/column option), then eq. 3 with the sign rule at every sample of the column
// from that slice back, accumulated in fixed point with atomics.
@compute @workgroup_size(PRIM_WG)
fn penumbra(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
            @builtin(local_invocation_index) lid: u32) {
    let ei = prim_index(wid, nwg);
    if (ei >= P.edges) {
        return;
    }
    let e = edges[ei];
    let fb = grid_depths();
    let e_near = edge_inv_z_near(e);
    let half_width = quad_half_width(e_near, fb.y);
    if (!(half_width > 0.0)) {
        return; // behind every receiver
    }
    let ea = vec2<f32>(e.au, e.av);
    let eb = vec2<f32>(e.bu, e.bv);
    let qb = quad_bounds(Quad(ea, eb, half_width));
    let lo = column(qb.xy);
    let hi = column(qb.zw);
    let per_bin = P.per_bin_width != 0u;

    // Binning (sort-middle), counted only: the bins under the quad, and those it is dropped
    // from by the per-bin width.
    if (INSTRUMENT) {
        if (lid == 0u) {
            stat(STAT_QUADS, 1u);
        }
        let b0 = lo / P.bin;
        let b1 = hi / P.bin;
        let bw = b1.x - b0.x + 1u;
        let nb = bw * (b1.y - b0.y + 1u);
        var kept = 0u;
        var culled = 0u;
        for (var j = lid; j < nb; j += PRIM_WG) {
            let b = (b0.y + j / bw) * P.bins_x + b0.x + j % bw;
            if (!per_bin || bin_half_width(e, b) > 0.0) {
                kept += 1u;
            } else {
                culled += 1u;
            }
        }
        stat(STAT_SOFT_BIN_ENTRIES, kept);
        stat(STAT_BIN_CULLED, culled);
    }

    let last = P.res - 1u;
    let w = hi.x - lo.x + 1u;
    let n = w * (hi.y - lo.y + 1u);
    var fragments = 0u;
    var wedge_culled = 0u;
    var fill = 0u;
    var contributing = 0u;
    for (var j = lid; j < n; j += PRIM_WG) {
        let x = lo.x + j % w;
        let y = lo.y + j / w;
        let b = bin_of_column(x, y);
        if (!bin_has_samples(b)) {
            continue;
        }
        var hw = half_width;
        if (per_bin) {
            hw = bin_half_width(e, b);
            if (hw <= 0.0) {
                continue;
            }
        }
        let quad = Quad(ea, eb, hw);
        // The columns of the bin's quad bounds (columns_in_bin).
        let nb = quad_bounds(quad);
        let nlo = column(nb.xy);
        let nhi = column(nb.zw);
        if (x < nlo.x || y < nlo.y || x > nhi.x || y > nhi.y) {
            continue;
        }
        let rect = column_rect(x, y);
        if (!quad_overlaps(quad, rect)) {
            continue;
        }
        fragments += 1u;
        var k0 = 0u;
        if (P.wedge_column_cull != 0u) {
            let border = x == 0u || y == 0u || x == last || y == last;
            var distance = 0.0;
            if (!border) {
                let half_size = (rect.hi - rect.lo) * 0.5;
                distance = max(edge_distance(e, rect.lo + half_size) - len2(half_size), 0.0);
            }
            let entry = wedge_entry_inv_z(e_near, distance);
            if (!(entry > 0.0)) {
                wedge_culled += 1u;
                continue;
            }
            k0 = slice(entry, fb);
        }
        let range = column_from(x, y, k0);
        fill += range.y - range.x;
        for (var s = range.x; s < range.y; s++) {
            let smp = samples[s];
            let v = penumbral_occlusion(e, vec2<f32>(smp.u, smp.v), smp.inv_z);
            if (v != 0.0) {
                let q = i32(round(v * P.occlusion_scale));
                atomicAdd(&occlusion[2u * s + 1u], bitcast<u32>(q));
                contributing += 1u;
            }
        }
    }
    stat(STAT_FRAGMENTS, fragments);
    stat(STAT_WEDGE_CULLED, wedge_culled);
    stat(STAT_FILL, fill);
    stat(STAT_CONTRIBUTING, contributing);
}

// Step "resolve": eq. 4 at each stored sample, written to its eye pixel.
@compute @workgroup_size(64)
fn resolve(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
           @builtin(local_invocation_index) lid: u32) {
    let s = item(wid, nwg, lid);
    if (s >= cell_start[P.cells]) {
        return;
    }
    let dc = atomicLoad(&occlusion[2u * s]);
    let pen = f32(bitcast<i32>(atomicLoad(&occlusion[2u * s + 1u]))) / P.occlusion_scale;
    visibility[samples[s].pixel] = combined_visibility(dc, pen);
}
