// The shadow-volume family's GPU passes (shadow_volume/wgpu.rs), shared by soft_shadow_volume
// (joined before its wgpu.wgsl, which adds the `soft` entry) and accum_hard: the parameters, the
// bindings, the hard pass (III §3.2.1; z-fail, Paper II §5) and accum_hard's accumulation.
// Each invocation is one pixel; it walks the primitives binned to its 8×8 tile in submission
// order, exactly as a tile task of the cpu executions does (`eye_raster::raster_pass`), so the
// per-pixel sums are formed in the same order. Every function names the Rust it mirrors.

override INSTRUMENT: u32 = 0u;

const TILE: u32 = 8u;

// The parameters `Params` are declared in wgpu.rs and joined before this file.

// `EyeRays` of one pixel: dir.xyz, depth (f32::MAX without a surface); point.xyz, bounds t0;
// x: bounds t1, y: 1 when the pixel has a surface.
struct Ray {
    dir: vec4f,
    point: vec4f,
    extra: vec4f,
}

// `ShadowQuad`: a.w is the quad's side of the eye (`eye_sides`), rect the footprint x0 y0 x1 y1.
struct Quad {
    a: vec4f,
    b: vec4f,
    light: vec4f,
    normal: vec4f,
    rect: vec4u,
}

// `WedgePrimitive`: rect the footprint; info: edge, first plane, plane count, half (bits of
// an f32, 0.0 for a whole wedge).
struct Prim {
    rect: vec4u,
    info: vec4u,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> rays: array<Ray>;
@group(0) @binding(2) var<storage, read> quads: array<Quad>;
@group(0) @binding(3) var<storage, read> prims: array<Prim>;
// (n.xyz, d) of `ConvexVolume::planes`.
@group(0) @binding(4) var<storage, read> planes: array<vec4f>;
// Per tile a [start, end) pair into the same array, then the primitive indices (the bins of
// `eye_raster::raster_pass`, in submission order): shadow quads, then wedge primitives.
@group(0) @binding(5) var<storage, read> quad_bins: array<u32>;
@group(0) @binding(6) var<storage, read> wedge_bins: array<u32>;
// `CoverageTexture::texels`, four per word, little-endian.
@group(0) @binding(7) var<storage, read> texels: array<u32>;
// The hard pass's count per pixel.
@group(0) @binding(8) var<storage, read_write> counts: array<i32>;
// The sub-light's covered fraction (overlap approximation across loops).
@group(0) @binding(9) var<storage, read_write> covered: array<f32>;
@group(0) @binding(10) var<storage, read_write> visibility: array<f32>;
// 64-bit counters as (lo, hi) word pairs, slots `STAT_*`.
@group(0) @binding(11) var<storage, read_write> stats: array<atomic<u32>>;
// Light received per channel (r, g, b per pixel) under a textured light.
@group(0) @binding(12) var<storage, read_write> rgb: array<f32>;

const STAT_HARD_FILL: u32 = 0u;
const STAT_HARD_PASSED: u32 = 1u;
const STAT_SOFT_FILL: u32 = 2u;
const STAT_SOFT_FRONT: u32 = 3u;
const STAT_SOFT_INSIDE: u32 = 4u;
const STAT_SOFT_COVERED: u32 = 5u;
const STAT_SOFT_CONTRIBUTING: u32 = 6u;
const STAT_HARD_TESTS: u32 = 7u;
const STAT_SOFT_TESTS: u32 = 8u;

fn count(slot: u32, v: u32) {
    if v == 0u {
        return;
    }
    let old = atomicAdd(&stats[2u * slot], v);
    if old + v < old {
        atomicAdd(&stats[2u * slot + 1u], 1u);
    }
}

// Rust `f32::signum` (1 for +0).
fn signum(x: f32) -> f32 {
    return select(-1.0, 1.0, x >= 0.0);
}

// glam `Vec2::perp_dot`.
fn perp_dot(a: vec2f, b: vec2f) -> f32 {
    return a.x * b.y + (-a.y * b.x);
}

// glam `Vec3::normalize_or`.
fn normalize_or(v: vec3f, fallback: vec3f) -> vec3f {
    let rcp = 1.0 / sqrt(dot(v, v));
    if rcp > 0.0 && rcp < 3.4e38 {
        return v * rcp;
    }
    return fallback;
}

// `ShadowQuad::ray_hit`: distance along o + t·d to the quad, or -1.
fn quad_hit(q: Quad, o: vec3f, d: vec3f) -> f32 {
    let n = q.normal.xyz;
    let nd = dot(n, d);
    if abs(nd) < 1e-12 * length(n) {
        return -1.0;
    }
    let l = q.light.xyz;
    let t = dot(n, l - o) / nd;
    let a = q.a.xyz;
    let b = q.b.xyz;
    // coverage::line_crosses over the boundary lines l → a, b → l, b → a.
    let s = dot(d, n);
    let inside = s != 0.0 && cov_edge_covers_oriented(o, d, l, a, s)
        && cov_edge_covers_oriented(o, d, b, l, s) && cov_edge_covers_oriented(o, d, b, a, s);
    if t > 0.0 && inside {
        return t;
    }
    return -1.0;
}

// `ShadowQuad::side`.
fn quad_side(q: Quad, p: vec3f) -> f32 {
    return select(-1.0, 1.0, dot(q.normal.xyz, p - q.light.xyz) >= 0.0);
}

fn in_rect(r: vec4u, x: u32, y: u32) -> bool {
    return x >= r.x && x < r.z && y >= r.y && y < r.w;
}

// `VolumeFace::ray_hit` for z-fail face k (six vec4 of `planes`: corners, normal, footprint):
// distance along o + t·d to the face, or -1.
fn face_hit(k: u32, o: vec3f, d: vec3f) -> f32 {
    let n = planes[6u * k + 4u].xyz;
    let nd = dot(n, d);
    if abs(nd) < 1e-12 * length(n) {
        return -1.0;
    }
    let t = dot(n, planes[6u * k].xyz - o) / nd;
    let sides = u32(planes[6u * k + 1u].w);
    // coverage::line_crosses over the face's edges.
    let s = dot(d, n);
    var inside = s != 0.0;
    for (var j = 0u; j < sides; j++) {
        let a = planes[6u * k + j].xyz;
        let b = planes[6u * k + (j + 1u) % sides].xyz;
        inside = inside && cov_edge_covers_oriented(o, d, a, b, s);
    }
    if t > 0.0 && inside {
        return t;
    }
    return -1.0;
}

// `shadow_volume::QuadPass::block` for one pixel over the primitives binned to its tile (III
// §3.2.1): with z-pass counting the shadow quads, counted from the eye's count where they lie
// in front of the visible surface; with z-fail (`counting` 1, Paper II §5) the faces of the
// capped volumes, counted from 0 from the entry into the scene bounds on, at or behind the
// visible surface.
@compute @workgroup_size(8, 8)
fn hard(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= P.width || id.y >= P.height {
        return;
    }
    let i = id.y * P.width + id.x;
    let tile = (id.y / TILE) * P.tiles_x + id.x / TILE;
    let zfail = P.counting == 1u;
    let ray = rays[i];
    var c = select(P.eye_count, 0, zfail);
    var fill = 0u;
    var passed = 0u;
    var tests = 0u;
    for (var e = quad_bins[2u * tile]; e < quad_bins[2u * tile + 1u]; e++) {
        let k = quad_bins[e];
        // The primitive's footprint and count change (a z-fail face's in `planes`).
        var rect: vec4u;
        var step: f32;
        if zfail {
            rect = bitcast<vec4u>(planes[6u * k + 5u]);
            step = planes[6u * k].w;
        } else {
            rect = quads[k].rect;
            step = quads[k].a.w;
        }
        if !in_rect(rect, id.x, id.y) {
            continue;
        }
        tests++;
        var t: f32;
        if zfail {
            t = face_hit(k, P.eye.xyz, ray.dir.xyz);
        } else {
            t = quad_hit(quads[k], P.eye.xyz, ray.dir.xyz);
        }
        // Fill: the fragments within the scene bounds (z-fail: from the entry on) or passing.
        // z-pass counts every crossing in front of the visible surface, also one before the
        // ray enters the bounds (a volume reaching out towards the eye); z-fail the crossings
        // at or behind it.
        if t >= 0.0 {
            let inside = t >= ray.point.w && (zfail || t <= ray.extra.x);
            var passes = t < ray.dir.w;
            if zfail {
                passes = inside && t >= ray.dir.w;
            }
            if inside || passes {
                fill++;
            }
            if passes {
                passed++;
                c += i32(step);
            }
        }
    }
    counts[i] = c;
    if INSTRUMENT != 0u {
        count(STAT_HARD_TESTS, tests);
        count(STAT_HARD_FILL, fill);
        count(STAT_HARD_PASSED, passed);
    }
}

// `accum_hard` (`accum_hard::cpu::Accumulate`): adds this light sample's lit pixels (count 0) to
// the per-pixel sum kept in `covered`; after the last sample (`last_light`), the average over
// the `sub_lights` samples in `visibility` (1 for pixels without a surface).
@compute @workgroup_size(8, 8)
fn accumulate(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= P.width || id.y >= P.height {
        return;
    }
    let i = id.y * P.width + id.x;
    var sum = select(0.0, 1.0, counts[i] == 0);
    if P.first_light == 0u {
        sum += covered[i];
    }
    covered[i] = sum;
    if P.last_light == 1u {
        visibility[i] = select(1.0, sum / f32(P.sub_lights), rays[i].extra.y == 1.0);
    }
}
