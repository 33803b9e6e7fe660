// Light-view helpers shared by the shadow-map family's eye lookup (shadow_map/eye_lookup.wgsl)
// and dbuffer's passes, joined after the declaration of their `Light` uniform (each has the
// fields read here) and before the shader, and their `eye_lookup` kernel, which reads the
// gbuffer and writes the visibility they declare and shades with their `owns` and `shade`.
// Each mirrors the Rust function named beside it.

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

// Phase `eye_lookup` (shadow_map::cpu::eye_lookup): an eye pixel whose surface the view `owns`
// and that lies in front of the light is shaded by `shade` with its normal, position,
// projection and n·l towards the light centre; one behind the light that faces away from its
// centre is in shadow where `AVERTED_IN_SHADOW` (Lookup::AVERTED_IN_SHADOW, set beside `shade`);
// any other stays lit.
@compute @workgroup_size(8, 8)
fn eye_lookup(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= light.width || id.y >= light.height {
        return;
    }
    let i = id.y * light.width + id.x;
    let pos = positions[i];
    var v = 1.0;
    if pos.w != 0.0 && owns(pos.xyz) {
        let m = project(pos.xyz);
        if m.w > 0.0 {
            let n = normals[i].xyz;
            v = shade(n, pos.xyz, m, dot(n, normalize(light.eye - pos.xyz)));
        } else if AVERTED_IN_SHADOW && dot(normals[i].xyz, normalize(light.eye - pos.xyz)) <= 0.0 {
            v = 0.0;
        }
    }
    visibility[i] = v;
}

// Instrumented mode only (`count_covered`): whether texel `id` of a depth map of the view holds
// a fragment (its depth below the clear value 1).
fn covered(map: texture_depth_2d, id: vec3<u32>) -> bool {
    return id.x < light.resolution && id.y < light.resolution && textureLoad(map, id.xy, 0) < 1.0;
}
