// penumbra_map, phase `penumbra_map` (paper 000 §3-§4): the cones and sheets, built on the CPU
// in light-view space (`PenumbraGeometry` in mod.rs, the same triangles the cpu executions
// draw), rasterized into the penumbra map. Joined after the shadow-map family's prelude and
// src/algorithms/shadow_map/light_raster.wgsl (shadow_map/wgpu.rs) for `Light` and the counters.
//
// "Darkest wins" (§4) is the paper's own device: the intensity is written as the fragment's
// depth into a Depth32Float target cleared to 1.0 with the depth test Less ("we store the
// penumbra intensity in the depth channel, and use glDepthFunc(GL_LESS)"). It keeps the exact
// f32 value, as the cpu executions' min-blend does, where a Min blend would need a blendable
// 32-bit float colour format that adapters need not offer.

// `penumbra_view`: the light view's projection (`PenumbraView`, declared in wgpu.rs).
@group(1) @binding(0) var<uniform> penumbra_view: PenumbraView;
// The shadow map of the same view and resolution (NDC depth).
@group(1) @binding(1) var shadow_map: texture_depth_2d;

// True in the instrumented pipeline: count fragments and discards with atomics.
override INSTRUMENT: bool = false;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    // Z_v of the cone, or of the sheet's point along its edge; interpolated perspective-correct
    // (the cpu executions weight by 1/depth to the same end).
    @location(0) z_v: f32,
}

@vertex
fn vs_penumbra(@location(0) p: vec3<f32>, @location(1) z_v: f32) -> Varyings {
    return Varyings(penumbra_view.proj * vec4<f32>(p, 1.0), z_v);
}

// LightView::linear_depth
fn linear_depth(ndc: f32) -> f32 {
    return light.near * light.far / (light.far - ndc * (light.far - light.near));
}

// penumbra_map::intensity: eq. 1, I = (Z_F − Z_v)/(Z_P − Z_v) in world-space depths, then the
// Bernstein falloff 3t² − 2t³.
fn intensity(z_f: f32, z_p: f32, z_v: f32) -> f32 {
    let den = z_p - z_v;
    var t = 0.0;
    if den > 0.0 {
        t = clamp((z_f - z_v) / den, 0.0, 1.0);
    }
    return t * t * (3.0 - 2.0 * t);
}

// The fragment program of §3 (`PenumbraFragments::shade` in cpu.rs): the fragment's window
// coordinates address the shadow map; a fragment behind its surface is discarded; otherwise
// the surface's intensity, written as depth.
@fragment
fn fs_penumbra(in: Varyings) -> @builtin(frag_depth) f32 {
    if INSTRUMENT {
        atomicAdd(&counts.fragments, 1u);
    }
    let z_f = in.position.z;
    let z_p = textureLoad(shadow_map, vec2<u32>(in.position.xy), 0);
    if z_f > z_p {
        if INSTRUMENT {
            atomicAdd(&counts.discarded, 1u);
        }
        discard;
    }
    return intensity(linear_depth(z_f), linear_depth(z_p), in.z_v);
}
