// Phase `light_raster`: the depth-only shadow map of the casters (the occluders; penumbra_map:
// every triangle of the scene) from the light centre (`LightView` in
// src/algorithms/shadow_map/mod.rs). The depth attachment (Depth32Float, cleared to 1, compare
// Less) holds NDC depth, the same value `LightView::project` returns.

@vertex
fn vs(@location(0) p: vec3<f32>) -> @builtin(position) vec4<f32> {
    return light.view_proj * vec4<f32>(p, 1.0);
}

// The timed pass: no colour output, only depth. An empty fragment stage rather than none, so
// that pipeline statistics can report the fragments the rasterizer produced (lavapipe counts
// them; NVIDIA's driver skips the empty stage and reports 0).
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
