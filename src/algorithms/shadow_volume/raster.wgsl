// The hard shadow-volume pass on a rasterizer (shadow_volume/raster.rs; paper 001 III §3.2.1,
// z-fail Paper II §5) and accum_hard's accumulation by blending (III §5.1): the eye's depth
// from the frame's shaded points (`fs_depth`), the shadow quads or capped volume faces drawn
// with no depth write, the depth test made in the fragment shader along each pixel's ray to
// its shaded point, each passing fragment adding its count change into the count target by
// additive blending (`fs_quad`), the lit pixels (count 0) added into the
// accumulation target (`fs_accumulate`), and the average written out (`resolve`).
// Depth is reversed (near/z of an infinite perspective: 1 at the near plane, 0 at infinity).

override INSTRUMENT: u32 = 0u;

// The parameters `RasterParams` are declared in raster.rs and joined before this file.

// `EyeRays` of one pixel, as the family's wgpu.wgsl reads them (`shadow_volume::wgpu::Ray`):
// dir.xyz, depth; point.xyz, bounds t0; x: bounds t1, y: 1 when the pixel has a surface.
struct Ray {
    dir: vec4f,
    point: vec4f,
    extra: vec4f,
}

@group(0) @binding(0) var<uniform> R: RasterParams;
@group(0) @binding(1) var<storage, read> rays: array<Ray>;
// 64-bit counters as (lo, hi) word pairs: fill, passed.
@group(0) @binding(2) var<storage, read_write> stats: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read_write> visibility: array<f32>;
// The target an accumulate or resolve pass reads: the count, or the accumulation.
@group(1) @binding(0) var target_in: texture_2d<f32>;

const STAT_FILL: u32 = 0u;
const STAT_PASSED: u32 = 1u;

fn count(slot: u32) {
    let old = atomicAdd(&stats[2u * slot], 1u);
    if old == 0xffffffffu {
        atomicAdd(&stats[2u * slot + 1u], 1u);
    }
}

fn view_proj() -> mat4x4f {
    return mat4x4f(R.vp0, R.vp1, R.vp2, R.vp3);
}

fn pixel(pos: vec4f) -> u32 {
    return u32(pos.y) * R.width + u32(pos.x);
}

// The depth buffer's value at pixel i: its shaded point projected (0, infinitely far, without a
// surface).
fn surface_depth(i: u32) -> f32 {
    let r = rays[i];
    if r.extra.y != 1.0 {
        return 0.0;
    }
    let c = view_proj() * vec4f(r.point.xyz, 1.0);
    return c.z / c.w;
}

// A triangle covering the screen.
@vertex
fn vs_full(@builtin(vertex_index) v: u32) -> @builtin(position) vec4f {
    let xy = vec2f(f32((v << 1u) & 2u), f32(v & 2u)) * 2.0 - 1.0;
    return vec4f(xy, 0.0, 1.0);
}

// The depth pre-pass: the eye's depth buffer from the frame's surfaces.
@fragment
fn fs_depth(@builtin(position) pos: vec4f) -> @builtin(frag_depth) f32 {
    return surface_depth(pixel(pos));
}

struct QuadOut {
    @builtin(position) pos: vec4f,
    // The count change of a fragment that passes the depth test.
    @location(0) @interpolate(flat) step: f32,
    @location(1) world: vec3f,
    // The face's plane from the eye (`HardVertex::plane`): normal, normal · (corner − eye).
    @location(2) @interpolate(flat) plane: vec4f,
    // The boundary edge p → q the shader decides (`HardVertex::edge_p`, `edge_q`; p.w 1).
    @location(3) @interpolate(flat) edge_p: vec4f,
    @location(4) @interpolate(flat) edge_q: vec4f,
}

// A corner of a shadow quad or volume face: xyz, w the count change (`shadow_volume::QuadPass`
// steps: z-pass +1 for a face whose outer side the eye is on, z-fail the opposite), and the
// face's plane and the edge the shader decides.
struct QuadIn {
    @location(0) v: vec4f,
    @location(1) plane: vec4f,
    @location(2) edge_p: vec4f,
    @location(3) edge_q: vec4f,
}

fn quad_vertex(in: QuadIn) -> QuadOut {
    var out: QuadOut;
    out.pos = view_proj() * vec4f(in.v.xyz, 1.0);
    out.step = in.v.w;
    out.world = in.v.xyz;
    out.plane = in.plane;
    out.edge_p = in.edge_p;
    out.edge_q = in.edge_q;
    return out;
}

@vertex
fn vs_quad(in: QuadIn) -> QuadOut {
    return quad_vertex(in);
}

// The count pass into the stencil (`DepthTarget::StencilCount`): the faces of one count change,
// drawn by the pipeline that increments (+1) or decrements (−1); a face of the other change has
// every corner at one point behind the near plane and draws nothing.
fn signed_vertex(in: QuadIn, change: f32) -> QuadOut {
    var out = quad_vertex(in);
    if in.v.w != change {
        out.pos = vec4f(0.0, 0.0, 2.0, 1.0);
    }
    return out;
}

@vertex
fn vs_quad_up(in: QuadIn) -> QuadOut {
    return signed_vertex(in, 1.0);
}

@vertex
fn vs_quad_down(in: QuadIn) -> QuadOut {
    return signed_vertex(in, -1.0);
}

// Where the ray of pixel i meets the face's plane (`FaceFrom::hit` without the edges, which the
// rasterizer decided): the distance along the ray through the pixel's shaded point, or -1 where
// the ray runs parallel to the face or meets its plane behind the eye.
fn face_distance(r: Ray, plane: vec4f) -> f32 {
    let nd = dot(plane.xyz, r.dir.xyz);
    if abs(nd) < 1e-12 * length(plane.xyz) {
        return -1.0;
    }
    let t = plane.w / nd;
    return select(-1.0, t, t > 0.0);
}

// A quad fragment: its count change, blended additively into the count target (or counted in
// the stencil) where the depth test passes. The test is made here, along the pixel's ray to its
// shaded point, as the cpu executions make it (`QuadPass::block`: z-pass in front of the
// point, z-fail at or behind it), not by the depth buffer at the pixel's centre: the shaded
// point is moved off its surface, off the centre's ray, and a quad that starts on that surface
// (a silhouette edge's quad along the face beside it) passes between the two. The instrumented
// pipeline counts in the cpu-model's terms: fill, the fragments within the scene bounds along
// the pixel's ray (z-fail: from the entry on) or passing; passed, those passing.
@fragment
fn fs_quad(in: QuadOut) -> @location(0) vec4f {
    let i = pixel(in.pos);
    let r = rays[i];
    let zfail = R.counting == 1u;
    let t = face_distance(r, in.plane);
    // z-pass: in front of the point; z-fail: at or behind it.
    var passes = t < r.dir.w;
    if zfail {
        passes = t >= r.dir.w;
    }
    passes = passes && t > 0.0;
    // A z-pass quad is drawn a little past its silhouette edge towards the light: the edge
    // itself is decided here for the pixel's ray, under the one tie rule (`FaceFrom::crosses`),
    // as the cpu decides it; fragments of the margin beyond it are not the quad's.
    if in.edge_p.w == 1.0 {
        let s = dot(r.dir.xyz, in.plane.xyz);
        if !cov_edge_covers_oriented(R.eye.xyz, r.dir.xyz, in.edge_p.xyz, in.edge_q.xyz, s) {
            discard;
        }
    }
    if INSTRUMENT != 0u {
        let along = length(in.world - R.eye.xyz);
        let inside = along >= r.point.w && (zfail || along <= r.extra.x);
        if inside || passes {
            count(STAT_FILL);
        }
        if passes {
            count(STAT_PASSED);
        }
    }
    if !passes {
        discard;
    }
    return vec4f(in.step, 0.0, 0.0, 0.0);
}

// `accum_hard::cpu::Accumulate`: 1 where this sample's count is 0, blended additively into the
// accumulation target.
@fragment
fn fs_accumulate(@builtin(position) pos: vec4f) -> @location(0) vec4f {
    let c = textureLoad(target_in, vec2i(pos.xy), 0).x;
    return vec4f(select(0.0, 1.0, c == 0.0), 0.0, 0.0, 0.0);
}

// The accumulation with the count in the stencil: 1 for every fragment, the stencil test
// (equal to 0) keeping the lit pixels.
@fragment
fn fs_lit() -> @location(0) vec4f {
    return vec4f(1.0, 0.0, 0.0, 0.0);
}

// The average over the samples (1 for pixels without a surface), as `accum_hard::cpu::render`.
@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= R.width || id.y >= R.height {
        return;
    }
    let i = id.y * R.width + id.x;
    let sum = textureLoad(target_in, vec2i(id.xy), 0).x;
    visibility[i] = select(1.0, sum / f32(R.samples), rays[i].extra.y == 1.0);
}
