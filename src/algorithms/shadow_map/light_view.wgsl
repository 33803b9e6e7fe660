// Light-view helpers shared by the shadow-map family's eye lookup (shadow_map/eye_lookup.wgsl)
// and dbuffer's passes, joined after the declaration of their `Light` uniform (each has the
// fields read here) and before the shader. Each mirrors the Rust function named beside it.

// LightView::project: (u, v) with v down, NDC depth, and clip w (linear depth); w <= 0 means
// behind the light.
fn project(p: vec3<f32>) -> vec4<f32> {
    let c = light.view_proj * vec4<f32>(p, 1.0);
    let ndc = c.xyz / c.w;
    return vec4<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5, ndc.z, c.w);
}

// LightView::linear_depth
fn linear_depth(ndc: f32) -> f32 {
    return light.near * light.far / (light.far - ndc * (light.far - light.near));
}

// LightView::texel_world
fn texel_world(z: f32) -> f32 {
    return 2.0 * z * light.tan_half_fov / f32(light.resolution);
}

// Bias::at
fn bias_at(z: f32, n_dot_l: f32) -> f32 {
    let c = clamp(n_dot_l, 1e-4, 1.0);
    let t = min(sqrt(1.0 - c * c) / c, 10.0);
    return texel_world(z) * (light.bias_constant + light.bias_slope * t);
}
