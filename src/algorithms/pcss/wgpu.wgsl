// pcss, phase `eye_lookup`: percentage-closer soft shadows (Fernando 2005). Appended to
// src/algorithms/shadow_map/eye_lookup.wgsl, whose functions it uses.

fn visibility_at(uv: vec2<f32>, z_r: f32, bias: f32) -> f32 {
    // Step 1: blocker search over `blocker_samples` Vogel-disk taps within
    // `pcss_search_radius_uv` (at a depth no nearer than the near plane); the average linear
    // depth of the taps in front of the receiver and of its plane (`ReceiverPlane`).
    let search = pcss_search_radius_uv(max(z_r, light.near));
    let plane = receiver_plane();
    let nb = light.blocker_samples;
    var sum = 0.0;
    var blockers = 0u;
    for (var i = 0u; i < nb; i++) {
        let tap = uv + search_tap(i) * search;
        let z = occluder_depth(tap);
        if z < min(z_r, receiver_plane_depth(plane, tap)) - bias {
            sum += z;
            blockers += 1u;
        }
    }
    if blockers == 0u {
        return 1.0;
    }
    // Steps 2 and 3: penumbra width from the average blocker depth, then percentage-closer
    // filtering over `pcf_samples` Vogel-disk taps within `pcss_filter_radius_uv`.
    let filter_radius = pcss_filter_radius_uv(z_r, sum / f32(blockers));
    let np = light.pcf_samples;
    var lit = 0u;
    for (var j = 0u; j < np; j++) {
        if occluder_depth(uv + filter_tap(j) * filter_radius) >= z_r - bias {
            lit += 1u;
        }
    }
    // Filter taps of a pixel left fully lit or fully shadowed changed nothing a single hard
    // test would not have given: that is the wasted part of this phase's fill.
    if INSTRUMENT && (lit == 0u || lit == np) {
        atomicAdd(&counts.wasted_taps, np);
    }
    return f32(lit) / f32(np);
}
