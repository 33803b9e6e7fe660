// Phase `light_raster`: the depth-only shadow map of every triangle of the scene from the light
// centre (`LightView` in src/algorithms/shadow_map/mod.rs). The depth attachment (Depth32Float,
// cleared to 1, compare Less) holds NDC depth, the same value `LightView::project` returns.

// The uniform block shared with eye_lookup.wgsl; layout matches `LightUniform` in mod.rs.
struct Light {
    view_proj: mat4x4<f32>,
    eye: vec3<f32>,
    radius: f32,
    near: f32,
    far: f32,
    tan_half_fov: f32,
    resolution: u32,
    bias_constant: f32,
    bias_slope: f32,
    blocker_samples: u32,
    pcf_samples: u32,
    width: u32,
    height: u32,
    face: u32,
    pad: u32,
}

// Instrumented-mode counters, layout matches `Counts` in mod.rs.
struct Counts {
    fragments: atomic<u32>,
    covered: atomic<u32>,
    taps: atomic<u32>,
    wasted_taps: atomic<u32>,
    discarded: atomic<u32>,
    extra_taps: atomic<u32>,
}

@group(0) @binding(0) var<uniform> light: Light;
@group(0) @binding(1) var<storage, read_write> counts: Counts;

@vertex
fn vs(@location(0) p: vec3<f32>) -> @builtin(position) vec4<f32> {
    return light.view_proj * vec4<f32>(p, 1.0);
}

// The timed pass: no colour output, only depth. An empty fragment stage rather than none, so
// pipeline statistics report the fragments the rasterizer produced.
@fragment
fn fs_depth() {
}

// The instrumented pass: every rasterised fragment (before the depth test, since a shader with
// side effects runs ahead of late depth testing) is counted; `count_covered` in eye_lookup.wgsl
// counts the texels that end up covered, and the difference is overdraw.
@fragment
fn fs_count() {
    atomicAdd(&counts.fragments, 1u);
}
