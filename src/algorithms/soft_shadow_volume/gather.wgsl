// soft_shadow_volume's gather (soft_shadow_volume/wgpu.rs), joined after the family's
// records.wgsl and the soft pass (wgpu.wgsl): its bindings of its own (group 1), then one
// pixel over the wedge primitives binned to its tile, in submission order, and `combine`.

// Per tile a [start, end) pair into the same array, then the wedge primitives' indices (the bins
// of `eye_raster::raster_pass`, in submission order).
@group(1) @binding(0) var<storage, read> wedge_bins: array<u32>;
// The family's hard pass's count per pixel.
@group(1) @binding(1) var<storage, read> counts: array<i32>;

@compute @workgroup_size(8, 8)
fn soft(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= P.width || id.y >= P.height {
        return;
    }
    let i = id.y * P.width + id.x;
    let ray = rays[i];
    let tile = (id.y / TILE) * P.tiles_x + id.x / TILE;
    var acc = 0.0;
    var acc3 = vec3f(0.0);
    var add = vec4u(0u);
    var sub = vec4u(0u);
    var tests = 0u;
    var reached = array<u32, 5>(0u, 0u, 0u, 0u, 0u);
    var contributing = 0u;
    for (var e = wedge_bins[2u * tile]; e < wedge_bins[2u * tile + 1u]; e++) {
        let prim = prims[wedge_bins[e]];
        if !in_rect(prim.rect, id.x, id.y) {
            continue;
        }
        tests++;
        let w = wedge_sample(ray, prim);
        reached[w.reached]++;
        if w.reached != REACHED_COVERED {
            continue;
        }
        if any(w.c3 > vec3f(0.0)) {
            contributing++;
        }
        if P.channels == 3u {
            acc3 -= w.side * w.c3;
        } else if P.vbuffer == 0u {
            acc -= w.side * w.c3.x;
        } else if w.side < 0.0 {
            add = min(add + split12(w.c3.x), vec4u(255u));
        } else {
            sub = min(sub + split12(w.c3.x), vec4u(255u));
        }
    }
    if P.vbuffer == 1u {
        acc = split12_value(add) - split12_value(sub);
    }
    combine(i, f32(counts[i]), acc, acc3);
    if INSTRUMENT != 0u {
        let covered_n = reached[4];
        let inside_n = reached[3] + covered_n;
        let front = reached[2] + inside_n;
        count(STAT_SOFT_TESTS, tests);
        count(STAT_SOFT_FILL, reached[1] + front);
        count(STAT_SOFT_FRONT, front);
        count(STAT_SOFT_INSIDE, inside_n);
        count(STAT_SOFT_COVERED, covered_n);
        count(STAT_SOFT_CONTRIBUTING, contributing);
    }
}
