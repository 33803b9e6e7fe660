// soft_shadow_volume's soft pass (paper 001, Papers III and IV), joined after the shadow-volume
// family's records.wgsl (eye rays, shadow quads, their tests): its parameters and bindings (group
// 0), its counters, the per-pixel coverage of a wedge primitive (`wedge_sample`) and the
// combination of loops and sub-lights (`combine`), shared by the gather (gather.wgsl, its `soft`
// entry) and the raster pipeline's fragment shader and resolve (raster.wgsl), each joined after
// this file. Every function names the Rust it mirrors.

override INSTRUMENT: u32 = 0u;

// The parameters `SoftParams` are declared in wgpu.rs and joined before this file.

// `WedgePrimitive`: rect the footprint; info: edge, first plane, plane count, half (bits of
// an f32, 0.0 for a whole wedge).
struct Prim {
    rect: vec4u,
    info: vec4u,
}

@group(0) @binding(0) var<uniform> P: SoftParams;
@group(0) @binding(1) var<storage, read> rays: array<Ray>;
@group(0) @binding(2) var<storage, read> quads: array<Quad>;
@group(0) @binding(3) var<storage, read> prims: array<Prim>;
// (n.xyz, d) of `ConvexVolume::planes`.
@group(0) @binding(4) var<storage, read> planes: array<vec4f>;
// `CoverageTexture::texels`, four per word, little-endian.
@group(0) @binding(5) var<storage, read> texels: array<u32>;
// The sub-light's covered fraction (overlap approximation across loops).
@group(0) @binding(6) var<storage, read_write> covered: array<f32>;
@group(0) @binding(7) var<storage, read_write> visibility: array<f32>;
// 64-bit counters as (lo, hi) word pairs, slots `STAT_*`.
@group(0) @binding(8) var<storage, read_write> stats: array<atomic<u32>>;
// Light received per channel (r, g, b per pixel) under a textured light.
@group(0) @binding(9) var<storage, read_write> rgb: array<f32>;

const STAT_SOFT_FILL: u32 = 0u;
const STAT_SOFT_FRONT: u32 = 1u;
const STAT_SOFT_INSIDE: u32 = 2u;
const STAT_SOFT_COVERED: u32 = 3u;
const STAT_SOFT_CONTRIBUTING: u32 = 4u;
const STAT_SOFT_TESTS: u32 = 5u;

fn count(slot: u32, v: u32) {
    if v == 0u {
        return;
    }
    let old = atomicAdd(&stats[2u * slot], v);
    if old + v < old {
        atomicAdd(&stats[2u * slot + 1u], 1u);
    }
}


// `ConvexVolume::ray_interval`; x > y when the ray misses.
fn ray_interval(first: u32, n: u32, o: vec3f, d: vec3f, t0_in: f32, t1_in: f32) -> vec2f {
    var t0 = t0_in;
    var t1 = t1_in;
    for (var k = 0u; k < n; k++) {
        let pl = planes[first + k];
        let nd = dot(pl.xyz, d);
        let s = pl.w - dot(pl.xyz, o);
        if abs(nd) < 1e-12 {
            if s < 0.0 {
                return vec2f(1.0, -1.0);
            }
            continue;
        }
        let t = s / nd;
        if nd > 0.0 {
            t1 = min(t1, t);
        } else {
            t0 = max(t0, t);
        }
        if t0 > t1 {
            return vec2f(1.0, -1.0);
        }
    }
    return vec2f(t0, t1);
}

// The emitter seen from p (`Emitter::seen_from`, `Light::emitter_frame`): half_u, half_v.
struct Frame {
    u: vec3f,
    v: vec3f,
}

fn emitter_frame(p: vec3f) -> Frame {
    if u32(P.half_u.w) == 1u {
        // Sphere: glam `any_orthonormal_pair` of the direction to the centre, scaled by radius.
        let w = normalize_or(P.center.xyz - p, vec3f(0.0, 1.0, 0.0));
        let sign = signum(w.z);
        let a = -1.0 / (sign + w.z);
        let b = w.x * w.y * a;
        let u = vec3f(1.0 + sign * w.x * w.x * a, sign * b, -sign * w.x);
        let v = vec3f(b, sign + w.y * w.y * a, -w.y);
        return Frame(u * P.half_v.w, v * P.half_v.w);
    }
    return Frame(P.half_u.xyz, P.half_v.xyz);
}

// `Emitter::project_edge` (IV §4.2.2: clip to the half-space in front of p, then project).
// Returns (q0, q1) in light coordinates; `ok` false when nothing is in front of p.
struct Segment {
    q0: vec2f,
    q1: vec2f,
    ok: bool,
}

const W_MIN: f32 = 1e-4;

fn to_light(p: vec3f, x: vec3f, w: f32, f: Frame) -> vec2f {
    let r = p + (x - p) / w - P.center.xyz;
    return vec2f(dot(r, f.u) / dot(f.u, f.u), dot(r, f.v) / dot(f.v, f.v));
}

fn project_edge(p: vec3f, a_in: vec3f, b_in: vec3f) -> Segment {
    let f = emitter_frame(p);
    let normal = normalize_or(cross(f.u, f.v), vec3f(0.0, 1.0, 0.0));
    let c = P.center.xyz;
    let towards = normal * signum(dot(normal, c - p));
    let dist = dot(towards, c - p);
    let none = Segment(vec2f(0.0), vec2f(0.0), false);
    if dist <= 0.0 {
        return none;
    }
    var a = a_in;
    var b = b_in;
    var wa = dot(towards, a - p) / dist;
    var wb = dot(towards, b - p) / dist;
    if wa < W_MIN && wb < W_MIN {
        return none;
    }
    if wa >= W_MIN && wb < W_MIN {
        let t = (wa - W_MIN) / (wa - wb);
        b = a + (b - a) * t;
        wb = W_MIN;
    } else if wa < W_MIN {
        let t = (wb - W_MIN) / (wb - wa);
        a = b + (a - b) * t;
        wa = W_MIN;
    }
    return Segment(to_light(p, a, wa, f), to_light(p, b, wb, f), true);
}

// `EmitterShape::clip` (III §3.3): the part of q0q1 inside the emitter.
fn clip_to_emitter(q0: vec2f, q1: vec2f) -> Segment {
    let d = q1 - q0;
    var t0 = 0.0;
    var t1 = 1.0;
    var base = q1;
    var t_base = 1.0;
    if dot(q0, q0) <= dot(q1, q1) {
        base = q0;
        t_base = 0.0;
    }
    let none = Segment(vec2f(0.0), vec2f(0.0), false);
    if u32(P.center.w) == 0u {
        // Liang–Barsky against |x| ≤ 1, |y| ≤ 1.
        let ps = array<f32, 4>(-d.x, d.x, -d.y, d.y);
        let qs = array<f32, 4>(q0.x + 1.0, 1.0 - q0.x, q0.y + 1.0, 1.0 - q0.y);
        for (var k = 0; k < 4; k++) {
            let pk = ps[k];
            let qk = qs[k];
            if pk == 0.0 {
                if qk < 0.0 {
                    return none;
                }
            } else if pk < 0.0 {
                t0 = max(t0, qk / pk);
            } else {
                t1 = min(t1, qk / pk);
            }
        }
    } else {
        let len = sqrt(dot(d, d));
        if len < 1e-20 {
            return Segment(q0, q1, dot(q0, q0) <= 1.0);
        }
        let u = d / len;
        let along = -dot(base, u);
        let closest = base + u * along;
        let h2 = 1.0 - dot(closest, closest);
        if h2 < 0.0 {
            return none;
        }
        let h = sqrt(h2);
        t0 = max(t0, t_base + (along - h) / len);
        t1 = min(t1, t_base + (along + h) / len);
    }
    if t0 < t1 {
        return Segment(base + d * (t0 - t_base), base + d * (t1 - t_base), true);
    }
    return none;
}

// `clip_half_plane` with the three half-planes of `exact_coverage`, selected by `mode`.
fn half_plane(mode: u32, x: vec2f, q0: vec2f, q1: vec2f) -> f32 {
    switch mode {
        case 0u: {
            return perp_dot(q0, x);
        }
        case 1u: {
            return perp_dot(x, q1);
        }
        default: {
            return -perp_dot(q1 - q0, x - q0);
        }
    }
}

struct Poly {
    v: array<vec2f, 8>,
    n: u32,
}

// `clip_half_plane` (Sutherland–Hodgman).
fn clip_poly(poly: Poly, mode: u32, q0: vec2f, q1: vec2f) -> Poly {
    var out: Poly;
    out.n = 0u;
    for (var i = 0u; i < poly.n; i++) {
        let p = poly.v[i];
        let q = poly.v[(i + 1u) % poly.n];
        let fp = half_plane(mode, p, q0, q1);
        let fq = half_plane(mode, q, q0, q1);
        if fp >= 0.0 {
            out.v[out.n] = p;
            out.n++;
        }
        if (fp >= 0.0) != (fq >= 0.0) {
            out.v[out.n] = p + (q - p) * (fp / (fp - fq));
            out.n++;
        }
    }
    return out;
}

// `exact_coverage` (III §3.2.2, IV §4.2.2 Figure 6a): the emitter's fraction in the sector
// between the rays through q0 and q1 beyond the segment.
fn exact_coverage(q0_in: vec2f, q1_in: vec2f) -> f32 {
    let cross0 = perp_dot(q0_in, q1_in);
    var q0 = q0_in;
    var q1 = q1_in;
    if cross0 < 0.0 {
        q0 = q1_in;
        q1 = q0_in;
    }
    let c = abs(cross0);
    if c <= 0.0 {
        return 0.0;
    }
    if u32(P.center.w) == 0u {
        var poly: Poly;
        poly.v[0] = vec2f(-1.0, -1.0);
        poly.v[1] = vec2f(1.0, -1.0);
        poly.v[2] = vec2f(1.0, 1.0);
        poly.v[3] = vec2f(-1.0, 1.0);
        poly.n = 4u;
        poly = clip_poly(poly, 0u, q0, q1);
        poly = clip_poly(poly, 1u, q0, q1);
        poly = clip_poly(poly, 2u, q0, q1);
        // `polygon_area`.
        var s = 0.0;
        for (var i = 0u; i < poly.n; i++) {
            s += perp_dot(poly.v[i], poly.v[(i + 1u) % poly.n]);
        }
        return clamp(abs(s) * 0.5 / 4.0, 0.0, 1.0);
    }
    let angle = atan2(c, dot(q0, q1));
    return clamp((0.5 * angle - 0.5 * c) / 3.14159265358979, 0.0, 1.0);
}

// Rust `f32::round` for x ≥ 0 (half away from zero; WGSL `round` is half to even).
fn round_pos(x: f32) -> f32 {
    return floor(x + 0.5);
}

fn texel(k: u32) -> f32 {
    return f32((texels[k / 4u] >> (8u * (k % 4u))) & 255u) / 255.0;
}

// `CoverageTexture::texel_pos`.
fn texel_pos(q: vec2f) -> vec2f {
    let n = f32(P.texture_n);
    return clamp((q + vec2f(1.0)) * 0.5 * n - vec2f(0.5), vec2f(0.0), vec2f(n - 1.0));
}

// `CoverageTexture::lookup_texels` (III §3.3): the sub-texture of q0's nearest texel centre,
// read bilinearly at q1, per channel (texel index k's channel c at byte channels·k + c).
fn texture_coverage(q0: vec2f, q1: vec2f) -> vec3f {
    let n = P.texture_n;
    let s = texel_pos(q0);
    let a = u32(round_pos(s.x));
    let b = u32(round_pos(s.y));
    let t = texel_pos(q1);
    let i0 = u32(floor(t.x));
    let j0 = u32(floor(t.y));
    let i1 = min(i0 + 1u, n - 1u);
    let j1 = min(j0 + 1u, n - 1u);
    let f = t - vec2f(f32(i0), f32(j0));
    let side = n * n;
    let ch = P.channels;
    let k00 = ((b * n + j0) * side + a * n + i0) * ch;
    let k10 = ((b * n + j0) * side + a * n + i1) * ch;
    let k01 = ((b * n + j1) * side + a * n + i0) * ch;
    let k11 = ((b * n + j1) * side + a * n + i1) * ch;
    var out = vec3f(0.0);
    for (var c = 0u; c < ch; c++) {
        let top = texel(k00 + c) * (1.0 - f.x) + texel(k10 + c) * f.x;
        let bottom = texel(k01 + c) * (1.0 - f.x) + texel(k11 + c) * f.x;
        out[c] = top * (1.0 - f.y) + bottom * f.y;
    }
    if ch == 1u {
        out = vec3f(out.x);
    }
    return out;
}

// `LightTexture::visibility`: the luminance fraction (Rec. 709) of the received light.
fn luminance(c: vec3f) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// `split12::split`: 12-bit quantization in four 3-bit digits.
fn split12(c: f32) -> vec4u {
    let q = u32(round_pos(clamp(c, 0.0, 1.0) * 4095.0));
    return vec4u(q & 7u, (q >> 3u) & 7u, (q >> 6u) & 7u, (q >> 9u) & 7u);
}

// `split12::value`.
fn split12_value(v: vec4u) -> f32 {
    return f32(v.x + (v.y << 3u) + (v.z << 6u) + (v.w << 9u)) / 4095.0;
}

// `overlap_coverage` (IV §5.1, eq. 1).
fn overlap_coverage(ca: f32, cb: f32) -> f32 {
    return min(max(ca, cb) + 0.5 * min(ca, cb), 1.0);
}

// How far `wedge_sample` got for one (pixel, primitive): the ray misses, meets the primitive
// (fill), its visible point is behind the entry (front), inside the primitive (inside), or the
// projected edge covers some of the light (covered).
const REACHED_FILL: u32 = 1u;
const REACHED_FRONT: u32 = 2u;
const REACHED_INSIDE: u32 = 3u;
const REACHED_COVERED: u32 = 4u;

struct WedgeSample {
    reached: u32,
    // The point's side of the hard shadow quad (-1 inner, +1 outer).
    side: f32,
    // The coverage per channel (the one channel repeated for an untextured light).
    c3: vec3f,
}

// How far `wedge_sample` gets on the ray–primitive interval alone (the depth tests of
// `SoftPass::block`): 0, REACHED_FILL (the ray meets the primitive within the scene bounds),
// REACHED_FRONT (its visible point behind the entry) or REACHED_INSIDE (and in front of the
// exit: the point inside the primitive). The raster pass's wedge-half culling marks with it.
fn wedge_reach(ray: Ray, prim: Prim) -> u32 {
    let iv = ray_interval(prim.info.y, prim.info.z, P.eye.xyz, ray.dir.xyz, ray.point.w, ray.extra.x);
    if iv.x > iv.y {
        return 0u;
    }
    let t_p = ray.dir.w;
    if !(iv.x < t_p) {
        return REACHED_FILL;
    }
    if !(t_p < iv.y) {
        return REACHED_FRONT;
    }
    return REACHED_INSIDE;
}

// `SoftPass::block` for one pixel's ray and one wedge primitive (III §3.2.2, IV §4.4): the
// ray–primitive interval, the depth tests, the side and the coverage by exact clipping or the
// 4D texture. Shared by the gather (`soft`) and the raster pass (raster.wgsl).
fn wedge_sample(ray: Ray, prim: Prim) -> WedgeSample {
    var w = WedgeSample(wedge_reach(ray, prim), 0.0, vec3f(0.0));
    if w.reached < REACHED_INSIDE {
        return w;
    }
    let q = quads[prim.info.x];
    let p = ray.point.xyz;
    w.side = bitcast<f32>(prim.info.w);
    if w.side == 0.0 {
        w.side = quad_side(q, p);
    }
    let proj = project_edge(p, q.a.xyz, q.b.xyz);
    if !proj.ok {
        return w;
    }
    let cl = clip_to_emitter(proj.q0, proj.q1);
    if !cl.ok {
        return w;
    }
    if P.coverage == 1u {
        w.c3 = texture_coverage(cl.q0, cl.q1);
    } else {
        w.c3 = vec3f(exact_coverage(cl.q0, cl.q1));
    }
    w.reached = REACHED_COVERED;
    return w;
}

// `render_loop`'s V-buffer of pixel i from its hard count and its wedge sum (`acc`, or `acc3`
// per channel under a textured light), and `render`'s combination of loops and sub-lights.
// Shared by the gather (`soft`) and the raster pass's resolve (raster.wgsl).
fn combine(i: u32, hard_count: f32, acc: f32, acc3: vec3f) {
    let hit = rays[i].extra.y != 0.0;
    if P.channels == 3u {
        // `cpu::render` for a textured light (one loop, one light): the light received per
        // channel, mean·(1 − count) ± coverage, at most the mean; its luminance fraction.
        let m = P.mean.xyz;
        let v3 = clamp(m * (1.0 - hard_count) + acc3, vec3f(0.0), m);
        rgb[3u * i] = v3.x;
        rgb[3u * i + 1u] = v3.y;
        rgb[3u * i + 2u] = v3.z;
        let vis = clamp(luminance(v3) / luminance(m), 0.0, 1.0);
        visibility[i] = select(1.0, vis, hit);
        return;
    }
    let v = 1.0 - hard_count + acc;
    let c = clamp(1.0 - v, 0.0, 1.0);
    var cov = c;
    if P.first_loop == 0u {
        cov = overlap_coverage(covered[i], c);
    }
    covered[i] = cov;
    if P.last_loop == 1u {
        var vis = 0.0;
        if P.first_light == 0u {
            vis = visibility[i];
        }
        vis += (1.0 - cov) / f32(P.sub_lights);
        if P.last_light == 1u {
            vis = select(1.0, clamp(vis, 0.0, 1.0), hit);
        }
        visibility[i] = vis;
    }
}
