// soft_shadow_volume's wedge pass on a rasterizer (soft_shadow_volume/raster.rs; paper 001
// III §3.2.2, §4; IV §4.3-4.4), joined after the family's shadow_volume/wgpu.wgsl and
// soft_shadow_volume/wgpu.wgsl, whose `wedge_sample` (the per-pixel coverage) and `combine`
// (the V-buffer and the loops' and sub-lights' combination) it calls.

// The targets the resolve reads: the hard pass's count (R16Float), the V-buffer (R32Float,
// Rgba32Float per channel under a textured light, or the additive rgba8 buffer of the split
// format) and the split format's subtractive rgba8 buffer (else the V-buffer again).
@group(1) @binding(0) var count_in: texture_2d<f32>;
@group(1) @binding(1) var vbuffer_in: texture_2d<f32>;
@group(1) @binding(2) var vbuffer_sub: texture_2d<f32>;

struct WedgeOut {
    @builtin(position) pos: vec4f,
    @location(0) @interpolate(flat) prim: u32,
}

// A corner of a front face of a wedge primitive, in clip space (transformed on the host by
// `shadow_volume::raster::eye_projection`), and the primitive's index.
@vertex
fn vs_wedge(@location(0) clip: vec4f, @location(1) prim: f32) -> WedgeOut {
    return WedgeOut(clip, u32(prim));
}

// One fragment of primitive `prim`: `wedge_sample` of its pixel's ray. The instrumented
// pipeline (depth test off) counts every rasterized fragment in the cpu-model's terms
// (`SoftPass::block`): tests (every fragment), fill (its ray meets the primitive within the
// scene bounds), front (its visible point behind the entry: the fragment passing the timed
// pipeline's depth test), inside, covered and contributing.
fn wedge_fragment(pos: vec4f, prim: u32) -> WedgeSample {
    let i = u32(pos.y) * P.width + u32(pos.x);
    let w = wedge_sample(rays[i], prims[prim]);
    if INSTRUMENT != 0u {
        count(STAT_SOFT_TESTS, 1u);
        count(STAT_SOFT_FILL, u32(w.reached >= REACHED_FILL));
        count(STAT_SOFT_FRONT, u32(w.reached >= REACHED_FRONT));
        count(STAT_SOFT_INSIDE, u32(w.reached >= REACHED_INSIDE));
        count(STAT_SOFT_COVERED, u32(w.reached == REACHED_COVERED));
        count(STAT_SOFT_CONTRIBUTING, u32(w.reached == REACHED_COVERED && any(w.c3 > vec3f(0.0))));
    }
    return w;
}

// The f32 V-buffer (III §4.1): minus side times the coverage, per channel, blended additively.
@fragment
fn fs_wedge(in: WedgeOut) -> @location(0) vec4f {
    let w = wedge_fragment(in.pos, in.prim);
    return select(vec4f(0.0), vec4f(-w.side * w.c3, 0.0), w.reached == REACHED_COVERED);
}

// The split 12-bit V-buffer (IV §4.3, `split12`): the coverage's four 3-bit digits into the
// additive rgba8 buffer (inner side) or the subtractive one (outer side), one draw each, the
// 8-bit blend saturating as `split12::blend`.
fn split_fragment(in: WedgeOut, inner: bool) -> vec4f {
    let w = wedge_fragment(in.pos, in.prim);
    let adds = w.reached == REACHED_COVERED && (w.side < 0.0) == inner;
    return select(vec4f(0.0), vec4f(split12(w.c3.x)) / 255.0, adds);
}

@fragment
fn fs_wedge_add(in: WedgeOut) -> @location(0) vec4f {
    return split_fragment(in, true);
}

@fragment
fn fs_wedge_sub(in: WedgeOut) -> @location(0) vec4f {
    return split_fragment(in, false);
}

// An rgba8 texel's 8-bit channels.
fn bytes(v: vec4f) -> vec4u {
    return vec4u(floor(v * 255.0 + 0.5));
}

// The loop's V-buffer, 1 − count ± coverage, and `combine`.
@compute @workgroup_size(8, 8)
fn resolve_soft(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= P.width || id.y >= P.height {
        return;
    }
    let i = id.y * P.width + id.x;
    let xy = vec2i(id.xy);
    let hard_count = textureLoad(count_in, xy, 0).x;
    let v = textureLoad(vbuffer_in, xy, 0);
    var acc = v.x;
    if P.vbuffer == 1u {
        let sub = textureLoad(vbuffer_sub, xy, 0);
        acc = split12_value(bytes(v)) - split12_value(bytes(sub));
    }
    combine(i, hard_count, acc, v.xyz);
}

// The culling's first pass (IV §4.4): the front faces mark the stencil where the pixel's point
// lies inside the half, no colour. The depth tests of the culling (the point behind the front
// faces and in front of the back faces) are made here along the pixel's ray to its shaded
// point (`wedge_reach`), as the cpu executions make them, not by the depth buffer at the
// pixel's centre, off which the shaded point is moved: a half whose face runs along the
// occluder's surface beside its silhouette edge culled points inside it.
@fragment
fn fs_mark(in: WedgeOut) -> @location(0) vec4f {
    let i = u32(in.pos.y) * P.width + u32(in.pos.x);
    if wedge_reach(rays[i], prims[in.prim]) != REACHED_INSIDE {
        discard;
    }
    return vec4f(0.0);
}

// The culling's count (counters only): one per fragment passing the stencil test.
@fragment
fn fs_one(in: WedgeOut) -> @location(0) vec4f {
    return vec4f(1.0);
}
