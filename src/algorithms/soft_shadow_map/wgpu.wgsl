// Soft shadow maps (paper 002) as GPU passes. Every function names the Rust function in
// soft_shadow_map/mod.rs or cpu.rs it mirrors. The structs `Ssm` and `Counts` are declared in
// wgpu.rs (`SsmUniform`, `Counts`) and joined before this file; the vertex attributes of the
// transfer path match `Instance` there.

@group(0) @binding(0) var<uniform> u: Ssm;
@group(0) @binding(1) var<storage, read_write> counts: Counts;

// ---- math (mod.rs) ----

// LightFrame::texel_tan
fn texel_tan(w: vec4<f32>) -> vec2<f32> {
    return vec2<f32>(w.y - w.x, w.w - w.z) / f32(u.resolution);
}

// LightFrame::texel_center
fn texel_center(w: vec4<f32>, i: u32, j: u32) -> vec2<f32> {
    let d = texel_tan(w);
    return vec2<f32>(w.x + (f32(i) + 0.5) * d.x, w.w - (f32(j) + 0.5) * d.y);
}

// LightFrame::tan_to_texel
fn tan_to_texel(w: vec4<f32>, t: vec2<f32>) -> vec2<f32> {
    let d = texel_tan(w);
    return vec2<f32>((t.x - w.x) / d.x, (w.w - t.y) / d.y);
}

// LightFrame::tan_to_ndc
fn tan_to_ndc(w: vec4<f32>, t: vec2<f32>) -> vec2<f32> {
    return vec2<f32>((2.0 * t.x - (w.x + w.y)) / (w.y - w.x), (2.0 * t.y - (w.z + w.w)) / (w.w - w.z));
}

// LightFrame::linear_depth
fn linear_depth(ndc: f32) -> f32 {
    return u.near * u.far / (u.far - ndc * (u.far - u.near));
}

// LightFrame::to_light
fn to_light(p: vec3<f32>) -> vec3<f32> {
    let d = p - u.center;
    return vec3<f32>(dot(d, u.e_u), dot(d, u.e_v), dot(d, u.normal));
}

struct Patch {
    lo: vec2<f32>,
    hi: vec2<f32>,
    z_o: f32,
}

// MicroPatch::of_texel
fn micro_patch(i: u32, j: u32, z_o: f32) -> Patch {
    let c = texel_center(u.occ_window, i, j);
    let d = texel_tan(u.occ_window) * 0.5;
    return Patch((c - d) * z_o, (c + d) * z_o, z_o);
}

// penumbra_extent (with apex): tan-space (lo, hi) as a vec4 at depth z_r
fn penumbra_extent(p: Patch, z_r: f32) -> vec4<f32> {
    let cp = vec3<f32>((p.lo + p.hi) * 0.5, p.z_o);
    let r = (u.half_size * 2.0) / (p.hi - p.lo);
    let k = r / (vec2<f32>(1.0) + r);
    let ox = cp * k.x;
    let oy = cp * k.y;
    let centre = vec2<f32>(ox.x / ox.z, oy.y / oy.z);
    let h = vec2<f32>(u.half_size.x * (z_r - ox.z) / ox.z, u.half_size.y * (z_r - oy.z) / oy.z) / z_r;
    return vec4<f32>(centre - h, centre + h);
}

// overlap
fn overlap(a: f32, b: f32) -> f32 {
    return clamp(b, 0.0, 1.0) - clamp(a, 0.0, 1.0);
}

// occlusion
fn occlusion(p: Patch, t_r: vec2<f32>, z_r: f32, bias: f32) -> f32 {
    if (z_r - p.z_o <= bias) {
        return 0.0;
    }
    let r = t_r * z_r;
    let k = z_r / (z_r - p.z_o);
    let inv = vec2<f32>(1.0) / (u.half_size * 2.0);
    let a = ((r + (p.lo - r) * k) + u.half_size) * inv;
    let b = ((r + (p.hi - r) * k) + u.half_size) * inv;
    return overlap(a.x, b.x) * overlap(a.y, b.y);
}

// bias_at
fn bias_at(z_r: f32) -> f32 {
    return u.bias_texels * texel_tan(u.ssm_window).x * z_r;
}

// ---- phase `maps`: depth maps (the view of group 1) ----

@group(1) @binding(0) var<uniform> map_view_proj: mat4x4<f32>;

@vertex
fn vs_depth(@location(0) p: vec3<f32>) -> @builtin(position) vec4<f32> {
    return map_view_proj * vec4<f32>(p, 1.0);
}

@fragment
fn fs_depth() {
}

// ---- phase `splat`: extent quads, additive ----

@group(1) @binding(1) var occluder_map: texture_depth_2d;
@group(1) @binding(2) var receiver_map: texture_depth_2d;

struct SplatOut {
    @builtin(position) position: vec4<f32>,
    @location(0) @interpolate(flat) lo: vec2<f32>,
    @location(1) @interpolate(flat) hi: vec2<f32>,
    @location(2) @interpolate(flat) z_o: f32,
}

// The corner `k` (0..4, as a triangle strip) of the extent `e` (NDC lo, hi).
fn corner(e: vec4<f32>, k: u32) -> vec4<f32> {
    let x = select(e.x, e.z, (k & 1u) == 1u);
    let y = select(e.y, e.w, k >= 2u);
    return vec4<f32>(x, y, 0.0, 1.0);
}

// The transfer path (§4.1): patches and extents generated on the host (super::micro_patch,
// super::extent_quad), one instance each.
@vertex
fn vs_splat_host(
    @builtin(vertex_index) k: u32,
    @location(0) lo: vec2<f32>,
    @location(1) hi: vec2<f32>,
    @location(2) z_o: f32,
    @location(3) extent: vec4<f32>,
) -> SplatOut {
    return SplatOut(corner(extent, k), lo, hi, z_o);
}

// The GPU-only variant (§4.3, future work of the paper): one instance per occluder texel in the
// cpu's block-linear order; the vertex shader reads the occluder map and builds the micro-patch
// and its extent (cpu::micro_patch, cpu::extent_quad), or a degenerate quad where it is empty.
@vertex
fn vs_splat_device(@builtin(vertex_index) k: u32, @builtin(instance_index) inst: u32) -> SplatOut {
    let blocks_x = (u.resolution + 3u) / 4u;
    let block = inst / 16u;
    let lane = inst % 16u;
    let i = (block % blocks_x) * 4u + lane % 4u;
    let j = (block / blocks_x) * 4u + lane / 4u;
    var out = SplatOut(vec4<f32>(2.0, 2.0, 0.0, 1.0), vec2<f32>(0.0), vec2<f32>(0.0), 0.0);
    if (i >= u.resolution || j >= u.resolution) {
        return out;
    }
    let d = textureLoad(occluder_map, vec2<u32>(i, j), 0);
    if (d >= 1.0) {
        return out;
    }
    let p = micro_patch(i, j, linear_depth(d));
    let e = penumbra_extent(p, u.far);
    let ndc = vec4<f32>(tan_to_ndc(u.ssm_window, e.xy), tan_to_ndc(u.ssm_window, e.zw));
    return SplatOut(corner(ndc, k), p.lo, p.hi, p.z_o);
}

// Splat::shade: the fragment program of §4.2.
fn splat_value(in: SplatOut) -> f32 {
    let xy = vec2<u32>(in.position.xy);
    let d = textureLoad(receiver_map, xy, 0);
    if (d >= 1.0) {
        return 0.0;
    }
    let z_r = linear_depth(d);
    return occlusion(Patch(in.lo, in.hi, in.z_o), texel_center(u.ssm_window, xy.x, xy.y), z_r, bias_at(z_r));
}

@fragment
fn fs_splat(in: SplatOut) -> @location(0) vec4<f32> {
    let v = splat_value(in);
    if (v <= 0.0) {
        discard;
    }
    return vec4<f32>(v, 0.0, 0.0, 0.0);
}

// The instrumented replay: every fragment counted once, either among those that hide part of
// the light or among those that hide nothing (overdraw); fill is their sum. Its pipeline writes
// no colour (the SSM of the timed pass is left as it was).
@fragment
fn fs_splat_count(in: SplatOut) -> @location(0) vec4<f32> {
    let v = splat_value(in);
    if (v <= 0.0) {
        atomicAdd(&counts.zero, 1u);
        discard;
    }
    atomicAdd(&counts.kept, 1u);
    return vec4<f32>(v, 0.0, 0.0, 0.0);
}

// Micro-patches of the instrumented GPU-only replay: non-empty occluder texels.
@compute @workgroup_size(8, 8)
fn count_patches(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= u.resolution || id.y >= u.resolution) {
        return;
    }
    if (textureLoad(occluder_map, id.xy, 0) < 1.0) {
        atomicAdd(&counts.patches, 1u);
    }
}

// ---- phase `project` ----

@group(2) @binding(0) var ssm_front: texture_2d<f32>;
@group(2) @binding(1) var ssm_back: texture_2d<f32>;
// xyz position, w: 1 where the pixel sees a surface
@group(2) @binding(2) var<storage, read> gpos: array<vec4<f32>>;
// xyz normal, w: 1 where the surface receives the soft shadow (Split::receives)
@group(2) @binding(3) var<storage, read> gnrm: array<vec4<f32>>;
@group(2) @binding(4) var<storage, read_write> vis: array<f32>;

// The merged SSM at texel (x, y): the max of the two passes (§3.5; one pass binds the same
// texture twice).
fn ssm_at(x: f32, y: f32) -> f32 {
    let n = f32(u.resolution) - 1.0;
    let xy = vec2<u32>(vec2<f32>(clamp(x, 0.0, n), clamp(y, 0.0, n)));
    return max(textureLoad(ssm_front, xy, 0).x, textureLoad(ssm_back, xy, 0).x);
}

// cpu::classify and cpu::bilinear_taps, then visibility
@compute @workgroup_size(8, 8)
fn project(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= u.width || id.y >= u.height) {
        return;
    }
    let i = id.y * u.width + id.x;
    let p = gpos[i];
    if (p.w == 0.0) {
        vis[i] = 1.0;
        return;
    }
    let n = gnrm[i];
    if (dot(n.xyz, normalize(u.center - p.xyz)) <= 0.0) {
        vis[i] = 0.0;
        return;
    }
    let l = to_light(p.xyz);
    let res = f32(u.resolution);
    let s = tan_to_texel(u.ssm_window, l.xy / l.z);
    if (n.w == 0.0 || l.z <= u.near * 0.5 || s.x < 0.0 || s.y < 0.0 || s.x >= res || s.y >= res) {
        vis[i] = 1.0;
        return;
    }
    let c = s - vec2<f32>(0.5);
    let b = floor(c);
    let w = c - b;
    let occ = (1.0 - w.x) * (1.0 - w.y) * ssm_at(b.x, b.y) + w.x * (1.0 - w.y) * ssm_at(b.x + 1.0, b.y)
        + (1.0 - w.x) * w.y * ssm_at(b.x, b.y + 1.0) + w.x * w.y * ssm_at(b.x + 1.0, b.y + 1.0);
    vis[i] = 1.0 - clamp(occ, 0.0, 1.0);
}
