// The family's prelude, joined before light_raster.wgsl and eye_lookup.wgsl at pipeline
// creation (shadow_map/wgpu.rs): the light view's uniform (`LightUniform`) and the counters of
// the instrumented replay (`Counts`), group 0 of every pass.

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
    // FaceView::face_code: the cube face whose receivers this view shades, 6 for all.
    face: u32,
    pad: u32,
}

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
