// hard_shadow_map, phase `eye_lookup`: the classic shadow-map test. Appended to
// src/algorithms/shadow_map/eye_lookup.wgsl, whose functions it uses.

// `hard_shadow_map::lit`: the point at linear depth `z_r` is shadowed when the nearest
// occluder in its texel lies in front of it by more than the slope-scaled bias (`Bias::at`).
fn visibility_at(uv: vec2<f32>, z_r: f32, bias: f32) -> f32 {
    return select(1.0, 0.0, z_r - bias > occluder_depth(uv));
}
