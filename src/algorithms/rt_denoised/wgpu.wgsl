// rt_denoised as compute passes: `trace` (spp shadow rays a pixel through the caster BVH,
// traversed here from storage buffers: no ray queries), `penumbra` and `atrous`. Every function
// mirrors the Rust function of src/algorithms/rt_denoised/ named beside it. The structs `Rt`,
// `Step`, `NodePair` and `Tri` are declared in Rust and joined before this file; the coverage
// rule (scene/coverage.wgsl) after it.

// True in the instrumented pipelines: count rays, visits, tests and taps with atomics.
override INSTRUMENT: bool = false;

@group(0) @binding(0) var<uniform> rt: Rt;
// 64-bit counters as (lo, hi) word pairs, slots `STAT_*`.
@group(0) @binding(1) var<storage, read_write> stats: array<atomic<u32>>;
@group(1) @binding(0) var<storage, read> points: array<vec4<f32>>;
@group(1) @binding(1) var<storage, read> normals: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read> nodes: array<NodePair>;
@group(1) @binding(3) var<storage, read> tris: array<Tri>;
@group(1) @binding(4) var<storage, read_write> traced: array<vec2<f32>>;
@group(1) @binding(5) var<storage, read_write> radius: array<f32>;
@group(2) @binding(0) var<uniform> step: Step;
@group(2) @binding(1) var<storage, read_write> src: array<f32>;
@group(2) @binding(2) var<storage, read_write> dst: array<f32>;

const STAT_RAYS: u32 = 0u;
const STAT_NODE_VISITS: u32 = 1u;
const STAT_TRIANGLE_TESTS: u32 = 2u;
const STAT_OCCLUDED: u32 = 3u;
const STAT_HORIZON_CULLED: u32 = 4u;
const STAT_AGREEING: u32 = 5u;
const STAT_SEARCH_TAPS: u32 = 6u;
const STAT_FILTER_TAPS: u32 = 7u;
const STAT_FILTERED_PIXELS: u32 = 8u;

// bvh::LEAF, bvh::STACK.
const LEAF: u32 = 0x80000000u;
const STACK: u32 = 64u;
const FRAC_PI_4: f32 = 0.7853981633974483;
const FRAC_PI_2: f32 = 1.5707963267948966;
// NORMAL_POWER_SQUARINGS, PLANE_TOLERANCE, SEARCH_NEAR, SEARCH_FAR_SIDE, PENUMBRA_REACH,
// MIN_REACH.
const NORMAL_POWER_SQUARINGS: u32 = 5u;
const PLANE_TOLERANCE: f32 = 2.0;
const SEARCH_NEAR: i32 = 1;
const SEARCH_FAR_SIDE: i32 = 5;
const PENUMBRA_REACH: f32 = 0.5;
const MIN_REACH: f32 = 1.0;

// `B3`, the à-trous kernel's tap `k` (0 to 4): (1, 4, 6, 4, 1) / 16.
fn b3(k: i32) -> f32 {
    if k == 2 {
        return 0.375;
    }
    if k == 1 || k == 3 {
        return 0.25;
    }
    return 0.0625;
}

fn count(slot: u32, v: u32) {
    if v == 0u {
        return;
    }
    let old = atomicAdd(&stats[2u * slot], v);
    if old + v < old {
        atomicAdd(&stats[2u * slot + 1u], 1u);
    }
}

// `hash32`.
fn hash32(x0: u32) -> u32 {
    var x = x0;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// `sobol_2d`.
fn sobol_2d(s: u32) -> vec2<u32> {
    var i = s;
    var v = 1u << 31u;
    var y = 0u;
    while i != 0u {
        if (i & 1u) != 0u {
            y ^= v;
        }
        i >>= 1u;
        v ^= v >> 1u;
    }
    return vec2<u32>(reverseBits(s), y);
}

// `unit_of`.
fn unit_of(bits: u32) -> f32 {
    return f32(bits >> 8u) * (1.0 / 16777216.0);
}

// `tile_rank`.
fn tile_rank(x: u32, y: u32) -> u32 {
    return (x & 1u) | ((y & 1u) << 1u) | ((x & 2u) << 1u) | ((y & 2u) << 2u);
}

// `square_sample` (with `pixel_rotation` of the pixel's INTERLEAVE² tile, INTERLEAVE = 4).
fn square_sample(x: u32, y: u32, s: u32) -> vec2<f32> {
    let tiles_x = (rt.width + 3u) / 4u;
    let tile = (y / 4u) * tiles_x + x / 4u;
    let p = sobol_2d(s + rt.spp * tile_rank(x, y));
    let a = hash32(tile ^ hash32(rt.seed));
    let b = hash32(a ^ 0x9e3779b9u);
    return vec2<f32>(unit_of(p.x + a), unit_of(p.y + b));
}

// `scene::light::concentric_disc`.
fn concentric_disc(s: vec2<f32>) -> vec2<f32> {
    let o = s * 2.0 - vec2<f32>(1.0);
    if all(o == vec2<f32>(0.0)) {
        return vec2<f32>(0.0);
    }
    var r: f32;
    var theta: f32;
    if abs(o.x) > abs(o.y) {
        r = o.x;
        theta = FRAC_PI_4 * (o.y / o.x);
    } else {
        r = o.y;
        theta = FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y);
    }
    return vec2<f32>(cos(theta), sin(theta)) * r;
}

// glam `Vec3::normalize_or`.
fn normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let rcp = 1.0 / sqrt(dot(v, v));
    if rcp > 0.0 && rcp < 3.4e38 {
        return v * rcp;
    }
    return fallback;
}

// Rust `f32::signum` (1 for +0).
fn signum(x: f32) -> f32 {
    return select(-1.0, 1.0, x >= 0.0);
}

struct Emitter {
    u: vec3<f32>,
    v: vec3<f32>,
}

// `Light::emitter_frame`'s half-axes: a sphere's disc facing p (glam `any_orthonormal_pair` of
// the direction to the centre, scaled by the radius); a disc's and a rectangle's from the host.
fn emitter(p: vec3<f32>) -> Emitter {
    if rt.kind == 0u {
        let w = normalize_or(rt.center - p, vec3<f32>(0.0, 1.0, 0.0));
        let sign = signum(w.z);
        let a = -1.0 / (sign + w.z);
        let b = w.x * w.y * a;
        let u = vec3<f32>(1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x);
        let v = vec3<f32>(b, sign + w.y * w.y * a, -w.y);
        return Emitter(u * rt.radius, v * rt.radius);
    }
    return Emitter(rt.half_u, rt.half_v);
}

// `light_point`.
fn light_point(e: Emitter, sq: vec2<f32>) -> vec3<f32> {
    var d: vec2<f32>;
    if rt.kind == 2u {
        d = sq * 2.0 - vec2<f32>(1.0);
    } else {
        d = concentric_disc(sq);
    }
    return rt.center + e.u * d.x + e.v * d.y;
}

// `cpu::safe_inverse`.
fn safe_inverse(d: vec3<f32>) -> vec3<f32> {
    var x = d;
    for (var k = 0u; k < 3u; k++) {
        if abs(x[k]) < 1e-20 {
            x[k] = select(-1e-20, 1e-20, x[k] >= 0.0);
        }
    }
    return 1.0 / x;
}

// `cpu::slab`: the entry parameter, or -1 when the segment misses the box.
fn slab(o: vec3<f32>, inv: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>) -> f32 {
    let t0 = (lo - o) * inv;
    let t1 = (hi - o) * inv;
    let near = min(t0, t1);
    let far = max(t0, t1);
    let tmin = max(max(max(near.x, near.y), near.z), 0.0);
    let tmax = min(min(min(far.x, far.y), far.z), 1.0);
    if tmin <= tmax {
        return tmin;
    }
    return -1.0;
}

struct Counts {
    node_visits: u32,
    triangle_tests: u32,
}

// `cpu::Bvh::traverse` for one ray: the segment parameter of the blocker found, or -1.
fn traverse(o: vec3<f32>, d: vec3<f32>, c: ptr<function, Counts>) -> f32 {
    if rt.has_root == 0u {
        return -1.0;
    }
    let inv = safe_inverse(d);
    var stack: array<u32, STACK>;
    stack[0] = rt.root;
    var sp = 1u;
    while sp > 0u {
        sp -= 1u;
        let entry = stack[sp];
        if (entry & LEAF) == 0u {
            let r = nodes[entry];
            (*c).node_visits += 1u;
            let ta = slab(o, inv, r.a_min, r.a_max);
            let tb = slab(o, inv, r.b_min, r.b_max);
            if ta >= 0.0 && tb >= 0.0 {
                if ta <= tb {
                    stack[sp] = r.b_ref;
                    stack[sp + 1u] = r.a_ref;
                } else {
                    stack[sp] = r.a_ref;
                    stack[sp + 1u] = r.b_ref;
                }
                sp += 2u;
            } else if ta >= 0.0 {
                stack[sp] = r.a_ref;
                sp += 1u;
            } else if tb >= 0.0 {
                stack[sp] = r.b_ref;
                sp += 1u;
            }
        } else {
            // `bvh::leaf_range`.
            let first = entry & ((1u << 27u) - 1u);
            let n = ((entry >> 27u) & 0xfu) + 1u;
            for (var j = 0u; j < n; j++) {
                let tri = tris[first + j];
                (*c).triangle_tests += 1u;
                // `cpu::plane_hit`.
                let a = tri.v0;
                let b = tri.v1;
                let cc = tri.v2;
                let nrm = cross(b - a, cc - a);
                let nd = dot(nrm, d);
                if nd == 0.0 {
                    continue;
                }
                let t = dot(nrm, a - o) / nd;
                if !(t > 0.0 && t < 1.0) {
                    continue;
                }
                // `cpu::crosses`: coverage::line_crosses over the edges a→b, b→c, c→a.
                let s = dot(d, nrm);
                if cov_edge_covers_oriented(o, d, a, b, s) && cov_edge_covers_oriented(o, d, b, cc, s)
                    && cov_edge_covers_oriented(o, d, cc, a, s) {
                    return t;
                }
            }
        }
    }
    return -1.0;
}

fn pixel_of(id: vec3<u32>) -> i32 {
    if id.x >= rt.width || id.y >= rt.height {
        return -1;
    }
    return i32(id.y * rt.width + id.x);
}

// `cpu::Trace`.
@compute @workgroup_size(8, 8)
fn trace(@builtin(global_invocation_id) id: vec3<u32>) {
    // A chunk of the image from (`step.col0`, `step.row0`) (`RAYS_PER_SUBMISSION`).
    let px = vec3<u32>(id.x + step.col0, id.y + step.row0, id.z);
    let i = pixel_of(px);
    if i < 0 {
        return;
    }
    let pt = points[i];
    let nm = normals[i];
    if pt.w <= 0.0 {
        traced[i] = vec2<f32>(1.0, 0.0);
        dst[i] = 1.0;
        return;
    }
    let o = pt.xyz;
    let e = emitter(o);
    var c = Counts(0u, 0u);
    var visible = 0u;
    var rays = 0u;
    var blocked = 0u;
    var culled = 0u;
    var distance = 0.0;
    for (var s = 0u; s < rt.spp; s++) {
        let q = light_point(e, square_sample(px.x, px.y, s));
        let d = q - o;
        if !(nm.w == 0.0 || dot(nm.xyz, d) > 0.0) {
            culled += 1u;
            continue;
        }
        rays += 1u;
        let t = traverse(o, d, &c);
        if t >= 0.0 {
            blocked += 1u;
            distance += t * length(d);
        } else {
            visible += 1u;
        }
    }
    let v = f32(visible) / f32(rt.spp);
    var mean = 0.0;
    if blocked > 0u {
        mean = distance / f32(blocked);
    }
    traced[i] = vec2<f32>(v, mean);
    dst[i] = v;
    if INSTRUMENT {
        count(STAT_RAYS, rays);
        count(STAT_NODE_VISITS, c.node_visits);
        count(STAT_TRIANGLE_TESTS, c.triangle_tests);
        count(STAT_OCCLUDED, blocked);
        count(STAT_HORIZON_CULLED, culled);
        if rays > 0u && (visible == 0u || visible == rays) {
            count(STAT_AGREEING, rays - 1u);
        }
    }
}

// `geometric_weight`.
fn geometric_weight(xp: vec3<f32>, np: vec3<f32>, footprint: f32, xq: vec3<f32>, nq: vec3<f32>, offset: f32) -> f32 {
    var wn = max(dot(np, nq), 0.0);
    for (var k = 0u; k < NORMAL_POWER_SQUARINGS; k++) {
        wn *= wn;
    }
    let plane = abs(dot(np, xq - xp));
    let wz = max(1.0 - plane / (PLANE_TOLERANCE * footprint * offset), 0.0);
    return wn * wz;
}

// The pixel at offset (dx, dy) from (x, y), or -1 outside the image.
fn neighbour(x: i32, y: i32, dx: i32, dy: i32) -> i32 {
    let qx = x + dx;
    let qy = y + dy;
    if qx < 0 || qy < 0 || qx >= i32(rt.width) || qy >= i32(rt.height) {
        return -1;
    }
    return qy * i32(rt.width) + qx;
}

struct Search {
    vmin: f32,
    vmax: f32,
    sw: f32,
    sd: f32,
    taps: u32,
}

// One tap of `cpu::Penumbra`.
fn search_tap(s: ptr<function, Search>, i: i32, dx: i32, dy: i32) {
    let x = i % i32(rt.width);
    let y = i / i32(rt.width);
    let q = neighbour(x, y, dx, dy);
    if q < 0 {
        return;
    }
    let pq = points[q];
    if pq.w <= 0.0 {
        return;
    }
    (*s).taps += 1u;
    var w = 1.0;
    if dx != 0 || dy != 0 {
        let pp = points[i];
        let offset = sqrt(f32(dx * dx + dy * dy));
        w = geometric_weight(pp.xyz, normals[i].xyz, pp.w, pq.xyz, normals[q].xyz, offset);
    }
    if w > 0.0 {
        let tr = traced[q];
        (*s).vmin = min((*s).vmin, tr.x);
        (*s).vmax = max((*s).vmax, tr.x);
        if tr.y > 0.0 {
            (*s).sw += w;
            (*s).sd += w * tr.y;
        }
    }
}

// `penumbra_radius_px`.
fn penumbra_radius_px(light_distance: f32, blocker: f32, footprint: f32) -> f32 {
    let gap = light_distance - blocker;
    if gap <= 0.0 || footprint <= 0.0 {
        return rt.max_radius;
    }
    return min(PENUMBRA_REACH * rt.light_radius * blocker / gap / footprint, rt.max_radius);
}

// `cpu::Penumbra`, its taps in `search_offsets` order.
@compute @workgroup_size(8, 8)
fn penumbra(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = pixel_of(id);
    if i < 0 {
        return;
    }
    let pt = points[i];
    if pt.w <= 0.0 {
        radius[i] = 0.0;
        return;
    }
    var s = Search(3.4e38, -3.4e38, 0.0, 0.0, 0u);
    search_tap(&s, i, 0, 0);
    for (var dy = -SEARCH_NEAR; dy <= SEARCH_NEAR; dy++) {
        for (var dx = -SEARCH_NEAR; dx <= SEARCH_NEAR; dx++) {
            if dx != 0 || dy != 0 {
                search_tap(&s, i, dx, dy);
            }
        }
    }
    let h = SEARCH_FAR_SIDE / 2;
    let far = rt.search_far;
    for (var dy = -h; dy <= h; dy++) {
        for (var dx = -h; dx <= h; dx++) {
            if dx != 0 || dy != 0 {
                search_tap(&s, i, dx * far, dy * far);
            }
        }
    }
    var r = 0.0;
    if s.sw > 0.0 && s.vmin < s.vmax {
        r = max(penumbra_radius_px(length(rt.center - pt.xyz), s.sd / s.sw, pt.w), MIN_REACH);
    }
    radius[i] = r;
    if INSTRUMENT {
        count(STAT_SEARCH_TAPS, s.taps);
        if r > 0.0 {
            count(STAT_FILTERED_PIXELS, 1u);
        }
    }
}

// `cpu::Atrous`: one pass at tap spacing `step.step`, from `src` into `dst`.
@compute @workgroup_size(8, 8)
fn atrous(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = pixel_of(id);
    if i < 0 {
        return;
    }
    let own = src[i];
    let reach = radius[i];
    if reach <= 0.0 {
        dst[i] = own;
        return;
    }
    let pp = points[i];
    let np = normals[i].xyz;
    let centre = b3(2) * b3(2);
    var sum = centre * own;
    var wsum = centre;
    var taps = 0u;
    let x = i % i32(rt.width);
    let y = i / i32(rt.width);
    let st = i32(step.step);
    for (var dy = -2; dy <= 2; dy++) {
        for (var dx = -2; dx <= 2; dx++) {
            if dx == 0 && dy == 0 {
                continue;
            }
            let extent = f32(max(abs(dx), abs(dy)) * st);
            if !(extent <= reach) {
                continue;
            }
            let ox = dx * st;
            let oy = dy * st;
            let q = neighbour(x, y, ox, oy);
            if q < 0 {
                continue;
            }
            let pq = points[q];
            if pq.w <= 0.0 {
                continue;
            }
            taps += 1u;
            let h = b3(dx + 2) * b3(dy + 2);
            let offset = sqrt(f32(ox * ox + oy * oy));
            let w = h * geometric_weight(pp.xyz, np, pp.w, pq.xyz, normals[q].xyz, offset);
            sum += w * src[q];
            wsum += w;
        }
    }
    dst[i] = clamp(sum / wsum, 0.0, 1.0);
    if INSTRUMENT {
        count(STAT_FILTER_TAPS, taps);
    }
}
