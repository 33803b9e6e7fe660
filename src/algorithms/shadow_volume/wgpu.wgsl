// The shadow-volume family's hard pass on wgpu (shadow_volume/wgpu.rs; III §3.2.1, z-fail
// Paper II §5), joined after records.wgsl: its bindings (group 0), its counters and the pass.
// Each invocation is one pixel; it walks the primitives binned to its 8×8 tile in submission
// order, exactly as a tile task of the cpu executions does (`eye_raster::raster_pass`), so the
// per-pixel counts are formed in the same order. accum_hard's accumulation joins after this file
// and binds group 0 too; soft_shadow_volume's soft pass has bindings of its own. Every function
// names the Rust it mirrors.

override INSTRUMENT: u32 = 0u;

// The parameters `HardParams` are declared in wgpu.rs and joined before this file.

@group(0) @binding(0) var<uniform> P: HardParams;
@group(0) @binding(1) var<storage, read> rays: array<Ray>;
@group(0) @binding(2) var<storage, read> quads: array<Quad>;
// The z-fail faces, six vec4 each (`face_records`; empty counting z-pass).
@group(0) @binding(3) var<storage, read> faces: array<vec4f>;
// Per tile a [start, end) pair into the same array, then the primitive indices (the bins of
// `eye_raster::raster_pass`, in submission order).
@group(0) @binding(4) var<storage, read> quad_bins: array<u32>;
// The hard pass's count per pixel.
@group(0) @binding(5) var<storage, read_write> counts: array<i32>;
// 64-bit counters as (lo, hi) word pairs, slots `STAT_*`.
@group(0) @binding(6) var<storage, read_write> stats: array<atomic<u32>>;

const STAT_HARD_FILL: u32 = 0u;
const STAT_HARD_PASSED: u32 = 1u;
const STAT_HARD_TESTS: u32 = 2u;

fn count(slot: u32, v: u32) {
    if v == 0u {
        return;
    }
    let old = atomicAdd(&stats[2u * slot], v);
    if old + v < old {
        atomicAdd(&stats[2u * slot + 1u], 1u);
    }
}

// `VolumeFace::ray_hit` for z-fail face k (six vec4 of `faces`: corners, normal, footprint):
// distance along o + t·d to the face, or -1.
fn face_hit(k: u32, o: vec3f, d: vec3f) -> f32 {
    let n = faces[6u * k + 4u].xyz;
    let nd = dot(n, d);
    if abs(nd) < 1e-12 * length(n) {
        return -1.0;
    }
    let t = dot(n, faces[6u * k].xyz - o) / nd;
    let sides = u32(faces[6u * k + 1u].w);
    // coverage::line_crosses over the face's edges.
    let s = dot(d, n);
    var inside = s != 0.0;
    for (var j = 0u; j < sides; j++) {
        let a = faces[6u * k + j].xyz;
        let b = faces[6u * k + (j + 1u) % sides].xyz;
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
        // The primitive's footprint and count change (a z-fail face's in `faces`).
        var rect: vec4u;
        var step: f32;
        if zfail {
            rect = bitcast<vec4u>(faces[6u * k + 5u]);
            step = faces[6u * k].w;
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
