// The records and geometry every shadow-volume pass on wgpu reads (shadow_volume/wgpu.rs), no
// bindings: the eye rays, the shadow quads and the tests on them. Joined before the family's hard
// pass (wgpu.wgsl, and so accum_hard's gather), soft_shadow_volume's soft pass and its wedge
// raster (soft_shadow_volume/raster.wgsl). Every function names the Rust it mirrors.

// Side of the screen tiles primitives are binned to (`TILE` in wgpu.rs).
const TILE: u32 = 8u;

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
