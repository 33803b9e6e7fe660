// penumbra_map, phase `eye_lookup` (§3: "a comparison with the depth in the shadow map
// determines if the pixel is completely shadowed. If not fully shadowed, a lookup into the
// penumbra map gives an approximation of the light reaching the surface"). Appended to
// src/algorithms/shadow_map/eye_lookup.wgsl, whose functions it uses; mirrors
// `PenumbraLookup` in cpu.rs.

// The penumbra map: intensity in [0, 1] per shadow-map texel (same view and resolution).
@group(2) @binding(0) var penumbra_map: texture_depth_2d;

fn visibility_at(uv: vec2<f32>, z_r: f32, bias: f32) -> f32 {
    let r = f32(light.resolution);
    let t = floor(uv * r);
    let z_occluder = occluder_depth(uv);
    // Outside the map nothing was rasterized: lit.
    if any(t < vec2<f32>(0.0)) || any(t >= vec2<f32>(r)) {
        return 1.0;
    }
    // The umbra: the hard test of `hard_shadow_map::lit`.
    if z_r - bias > z_occluder {
        return 0.0;
    }
    if INSTRUMENT {
        atomicAdd(&counts.extra_taps, 1u);
    }
    return textureLoad(penumbra_map, vec2<u32>(t), 0);
}
