// accum_hard's accumulation on the gather pipeline (accum_hard/wgpu.rs), joined after the
// shadow-volume family's records.wgsl and hard pass (wgpu.wgsl), whose group 0 (the eye rays
// and the hard pass's counts) it binds too.

// The parameters `AccumParams` are declared in wgpu.rs and joined before this file.
@group(1) @binding(0) var<uniform> A: AccumParams;
// The per-pixel sum of the samples' lit pixels.
@group(1) @binding(1) var<storage, read_write> sum: array<f32>;
@group(1) @binding(2) var<storage, read_write> visibility: array<f32>;

// `accum_hard` (`accum_hard::cpu::Accumulate`): adds this light sample's lit pixels (count 0) to
// the per-pixel sum kept in `sum`; after the last sample (`last_light`), the average over
// the `sub_lights` samples in `visibility` (1 for pixels without a surface).
@compute @workgroup_size(8, 8)
fn accumulate(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= P.width || id.y >= P.height {
        return;
    }
    let i = id.y * P.width + id.x;
    var lit = select(0.0, 1.0, counts[i] == 0);
    if A.first_light == 0u {
        lit += sum[i];
    }
    sum[i] = lit;
    if A.last_light == 1u {
        visibility[i] = select(1.0, lit / f32(A.sub_lights), rays[i].extra.y == 1.0);
    }
}
