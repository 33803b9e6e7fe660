// Phase `eye_lookup`: one invocation per eye pixel reads the shared gbuffer (world position
// with a hit flag in w, eye-facing normal), projects the point into the light's shadow map and
// calls `visibility_at`, which each algorithm defines in its own WGSL file appended to this one.
// Every function here mirrors the Rust function of src/algorithms/shadow_map/mod.rs named beside it;
// `project`, `linear_depth`, `texel_world` and `bias_at` come from light_view.wgsl, joined before.

// Depth of a tap outside the map: beyond every receiver.
const FAR_AWAY: f32 = 3.4e38;

// True in the instrumented pipeline: count shadow-map taps and wasted work with atomics.
override INSTRUMENT: bool = false;

@group(1) @binding(0) var shadow_map: texture_depth_2d;
@group(1) @binding(1) var<storage, read> positions: array<vec4<f32>>;
@group(1) @binding(2) var<storage, read> normals: array<vec4<f32>>;
@group(1) @binding(3) var<storage, read_write> visibility: array<f32>;
// The PCSS taps on the unit disc (`vogel_disk`, computed on the host): the blocker search's
// `light.blocker_samples`, then the filter's `light.pcf_samples`.
@group(1) @binding(4) var<storage, read> taps: array<vec2<f32>>;

// shadow_map::cube_face
fn cube_face(d: vec3<f32>) -> u32 {
    let a = abs(d);
    if a.x >= a.y && a.x >= a.z {
        return select(0u, 1u, d.x < 0.0);
    }
    if a.y >= a.z {
        return select(2u, 3u, d.y < 0.0);
    }
    return select(4u, 5u, d.z < 0.0);
}

// FaceView::owns
fn owns(p: vec3<f32>) -> bool {
    return light.face == 6u || cube_face(p - light.eye) == light.face;
}

// LightView::world_to_uv
fn world_to_uv(w: f32, z: f32) -> f32 {
    return w / (2.0 * z * light.tan_half_fov);
}

// vogel_disk(i, light.blocker_samples): tap i of the blocker search.
fn search_tap(i: u32) -> vec2<f32> {
    return taps[i];
}

// vogel_disk(j, light.pcf_samples): tap j of the filter.
fn filter_tap(j: u32) -> vec2<f32> {
    return taps[light.blocker_samples + j];
}

// pcss_search_radius_uv
fn pcss_search_radius_uv(z_r: f32) -> f32 {
    return world_to_uv(light.radius, light.near) * max(z_r - light.near, 0.0) / z_r;
}

// The receiver `shade` looks up: world position and normal (for `receiver_plane`).
var<private> receiver_p: vec3<f32>;
var<private> receiver_n: vec3<f32>;

// ReceiverPlane::new(view, receiver_p, receiver_n): the normal in view space and n·p.
fn receiver_plane() -> vec4<f32> {
    let pv = (light.view * vec4<f32>(receiver_p, 1.0)).xyz;
    let nv = (light.view * vec4<f32>(receiver_n, 0.0)).xyz;
    return vec4<f32>(nv, dot(nv, pv));
}

// ReceiverPlane::depth_at
fn receiver_plane_depth(plane: vec4<f32>, uv: vec2<f32>) -> f32 {
    let x = (2.0 * uv.x - 1.0) * light.tan_half_fov;
    let y = (1.0 - 2.0 * uv.y) * light.tan_half_fov;
    let inv = (plane.x * x + plane.y * y - plane.z) / plane.w;
    if inv > 0.0 {
        return 1.0 / inv;
    }
    return FAR_AWAY;
}

// pcss_penumbra_radius
fn pcss_penumbra_radius(z_r: f32, z_b: f32) -> f32 {
    return light.radius * max(z_r - z_b, 0.0) / z_b;
}

// pcss_filter_radius_uv
fn pcss_filter_radius_uv(z_r: f32, z_b: f32) -> f32 {
    return world_to_uv(pcss_penumbra_radius(z_r, z_b), z_r);
}

// One shadow-map tap: the linear depth of the nearest occluder in the texel holding `uv`
// (`hard_shadow_map::texel`: the nearest texel). Outside the map nothing was rasterized: the
// depth is "infinitely far", so the tap is lit and no blocker (`hard_shadow_map::lit`).
fn occluder_depth(uv: vec2<f32>) -> f32 {
    if INSTRUMENT {
        atomicAdd(&counts.taps, 1u);
    }
    let r = f32(light.resolution);
    let t = floor(uv * r);
    if any(t < vec2<f32>(0.0)) || any(t >= vec2<f32>(r)) {
        return FAR_AWAY;
    }
    return linear_depth(textureLoad(shadow_map, vec2<u32>(t), 0));
}

// The shading of `eye_lookup` (light_view.wgsl): Receivers::averted, a surface facing away from
// the light centre is in shadow; any other is looked up.
const AVERTED_IN_SHADOW: bool = true;
fn shade(n: vec3<f32>, p: vec3<f32>, m: vec4<f32>, n_dot_l: f32) -> f32 {
    if n_dot_l <= 0.0 {
        return 0.0;
    }
    receiver_p = p;
    receiver_n = n;
    return visibility_at(m.xy, m.w, bias_at(m.w, n_dot_l));
}

// Instrumented mode only: texels the light raster covered (depth below the clear value), the
// fragments of the light raster that contributed.
@compute @workgroup_size(8, 8)
fn count_covered(@builtin(global_invocation_id) id: vec3<u32>) {
    if covered(shadow_map, id) {
        atomicAdd(&counts.covered, 1u);
    }
}
