// dbuffer (paper 003) as GPU passes: the D-buffer drawn from the light centre (the scene's
// depth, the umbra volume, the penumbra volume) and the eye lookup. Every function mirrors the
// Rust function of src/algorithms/dbuffer/ named beside it.

// The structs `Light` (`DbufferUniform`) and `Counts` are declared in wgpu.rs and joined before
// this file.

// True in the instrumented pipelines: count fragments and covered texels with atomics.
override INSTRUMENT: bool = false;

@group(0) @binding(0) var<uniform> light: Light;
@group(0) @binding(1) var<storage, read_write> counts: Counts;
// Group 1 of the eye lookup; the umbra volume's draw binds a group 1 of `scene_depth` alone.
@group(1) @binding(0) var scene_depth: texture_depth_2d;
@group(1) @binding(1) var umbra_depth: texture_depth_2d;
@group(1) @binding(2) var umbra_edge: texture_2d<f32>;
@group(1) @binding(3) var penumbra_depth: texture_depth_2d;
@group(1) @binding(4) var penumbra_edge: texture_2d<f32>;
@group(1) @binding(5) var<storage, read> positions: array<vec4<f32>>;
@group(1) @binding(6) var<storage, read> normals: array<vec4<f32>>;
@group(1) @binding(7) var<storage, read_write> visibility: array<f32>;

// `project`, `linear_depth`, `texel_world` and `bias_at`: shadow_map/light_view.wgsl, joined
// before this file.

// Phase `dbuffer`, the scene's depth (|cx_o|): every occluder triangle, depth only.
@vertex
fn vs_scene(@location(0) p: vec3<f32>) -> @builtin(position) vec4<f32> {
    return light.view_proj * vec4<f32>(p, 1.0);
}

@fragment
fn fs_scene() {
    if INSTRUMENT {
        atomicAdd(&counts.scene_fragments, 1u);
    }
}

struct VolumeVertex {
    @builtin(position) position: vec4<f32>,
    // The silhouette edge's depth below the light plane, interpolated perspective-correctly
    // (VolumeFragments: weights over the vertices' light-view depth).
    @location(0) z_e: f32,
}

@vertex
fn vs_volume(@location(0) p: vec3<f32>, @location(1) z_e: f32) -> VolumeVertex {
    var out: VolumeVertex;
    out.position = light.view_proj * vec4<f32>(p, 1.0);
    out.z_e = z_e;
    return out;
}

// VolumeFragments with the scene: the umbra volume keeps fragments at or behind the scene
// surface seen from c (dbuffer::DEPTH_RULE); the depth test keeps the nearest of those.
@fragment
fn fs_umbra(v: VolumeVertex) -> @location(0) vec4<f32> {
    if INSTRUMENT {
        atomicAdd(&counts.umbra_fragments, 1u);
    }
    let z_o = linear_depth(textureLoad(scene_depth, vec2<u32>(v.position.xy), 0));
    if linear_depth(v.position.z) < z_o - texel_world(z_o) {
        discard;
    }
    return vec4<f32>(v.z_e, 0.0, 0.0, 0.0);
}

// VolumeFragments without the scene: the nearest penumbra surface.
@fragment
fn fs_penumbra(v: VolumeVertex) -> @location(0) vec4<f32> {
    if INSTRUMENT {
        atomicAdd(&counts.penumbra_fragments, 1u);
    }
    return vec4<f32>(v.z_e, 0.0, 0.0, 0.0);
}

// dbuffer::front_fraction: the part of the disc in front of the receiver's plane.
fn front_fraction(n: vec3<f32>, q: vec3<f32>) -> f32 {
    let h = dot(n, light.eye - q);
    let spread = length(n - light.disc_n * dot(n, light.disc_n)) * light.radius;
    if spread <= 1e-9 {
        return select(0.0, 1.0, h > 0.0);
    }
    let d = clamp(-h / spread, -1.0, 1.0);
    return clamp((acos(d) - d * sqrt(1.0 - d * d)) / 3.14159265358979, 0.0, 1.0);
}

// dbuffer::t_umbra; `s_ok` false where edge_distance is infinite.
fn t_umbra(d: f32, u: f32, s: f32, s_ok: bool) -> f32 {
    if d <= u {
        return 0.0;
    }
    let den = 2.0 * u * (d - s);
    if den > 0.0 && s_ok {
        return clamp(s * (d - u) / den, 0.0, 1.0);
    }
    return 0.0;
}

// dbuffer::t_penumbra
fn t_penumbra(d: f32, p: f32, s: f32, s_ok: bool) -> f32 {
    if d <= p {
        return 1.0;
    }
    let den = 2.0 * p * (d - s);
    if den > 0.0 && s_ok {
        return clamp(1.0 - s * (d - p) / den, 0.0, 1.0);
    }
    return 1.0;
}

// dbuffer::cpu::ray_t: eq. 2 then eq. 3 along the eye sample's ray from c.
fn ray_t(uv: vec2<f32>, z: f32, behind: bool, ndc: f32, z_e: f32) -> f32 {
    if ndc >= 1.0 {
        return select(1.0, 0.0, behind);
    }
    let ray = vec3<f32>(
        (2.0 * uv.x - 1.0) * light.tan_half_fov,
        (1.0 - 2.0 * uv.y) * light.tan_half_fov,
        -1.0,
    );
    let per_depth = length(ray);
    let dir = ray / per_depth;
    let d = z * per_depth;
    let volume = linear_depth(ndc) * per_depth;
    // dbuffer::edge_distance
    let cos = dot(dir, light.n_view);
    let s_ok = cos > 1e-6;
    let s = select(0.0, z_e / cos, s_ok);
    if behind {
        return t_umbra(d, volume, s, s_ok);
    }
    return t_penumbra(d, volume, s, s_ok);
}

// dbuffer::visibility
fn falloff(t: f32) -> f32 {
    let c = clamp(t, 0.0, 1.0);
    if light.falloff == 1u {
        return sqrt(c);
    }
    return c * c * (3.0 - 2.0 * c);
}

// DLookup::visibility for one facing sample at map coordinates `uv`, light-view depth `z`.
fn visibility_at(uv: vec2<f32>, z: f32, bias: f32) -> f32 {
    let r = f32(light.resolution);
    let t = floor(uv * r);
    if any(t < vec2<f32>(0.0)) || any(t >= vec2<f32>(r)) {
        return 1.0;
    }
    let texel = vec2<u32>(t);
    // hard_shadow_map::lit, negated.
    let behind = z - bias > linear_depth(textureLoad(scene_depth, texel, 0));
    var ndc: f32;
    var z_e: f32;
    if behind {
        ndc = textureLoad(umbra_depth, texel, 0);
        z_e = textureLoad(umbra_edge, texel, 0).r;
    } else {
        ndc = textureLoad(penumbra_depth, texel, 0);
        z_e = textureLoad(penumbra_edge, texel, 0).r;
    }
    return falloff(ray_t(uv, select(z, z - bias, behind), behind, ndc, z_e));
}

// The shading of `eye_lookup` (light_view.wgsl; shadow_map::cpu::eye_lookup with DLookup): a
// surface facing away from c sees the part of the disc in front of its plane, any other is
// looked up and scaled by that part. One view owns every receiver.
fn owns(p: vec3<f32>) -> bool {
    return true;
}

// DLookup::AVERTED_IN_SHADOW: a receiver behind the light stays lit.
const AVERTED_IN_SHADOW: bool = false;
fn shade(n: vec3<f32>, p: vec3<f32>, m: vec4<f32>, n_dot_l: f32) -> f32 {
    let f = front_fraction(n, p);
    if n_dot_l <= 0.0 {
        return f;
    }
    return clamp(visibility_at(m.xy, m.w, bias_at(m.w, n_dot_l)) * f, 0.0, 1.0);
}

// Instrumented mode only: D-buffer texels each volume draw left covered (the volume fragments
// that contributed).
@compute @workgroup_size(8, 8)
fn count_covered(@builtin(global_invocation_id) id: vec3<u32>) {
    if covered(umbra_depth, id) {
        atomicAdd(&counts.umbra_covered, 1u);
    }
    if covered(penumbra_depth, id) {
        atomicAdd(&counts.penumbra_covered, 1u);
    }
}
