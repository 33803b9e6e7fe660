//! Soft shadow maps on the CPU executions (`cpu-native`, `cpu-model`): the occluder and
//! receiver maps on the sort-middle rasterizer (phase `maps`), the micro-patches' penumbra
//! extents drawn as quads with an additive fragment kernel into the soft shadow map (phase
//! `splat`), and the SSM projected onto the eye samples (phase `project`).

use glam::{Mat4, Vec2, Vec3};

use super::Phase;
use super::{
    bias_at, classify, extent_quad, micro_patch, occlusion, record_receivers_outside, visibility,
    LightFrame, MicroPatch, Sample, SoftShadowMapOptions, Split,
};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{eye_lookup_step, eye_tiles, machine, output, EyeBlock, EyeKernel};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::raster::{
    self, Cull, FragmentKernel, Fragments, Geometry, Pipeline, Shade, Surface, Target, TileRect,
    BLOCK,
};
use crate::model::{Buffer, Machine, Mask, Probe, TaskKernel, LANES};
use crate::record::PhaseId;
use crate::visibility::VisibilityBuffer;

/// Vector instructions per 16 occluder texels to build micro-patches and extents: emptiness
/// compare (1), linear depth (subtract, multiply, divide: 3), texel centre in tan (2
/// multiply-adds), patch corners (4 multiplies), apex ratio and depth per axis (reciprocal,
/// 2 multiplies, add, divide: 5), extent centre and half-widths (2 divides, 2 multiply-adds),
/// the four corners in NDC (4 multiply-adds), stream-compaction offsets (2).
const EXTENT_OPS: u32 = 1 + 3 + 2 + 4 + 5 + 4 + 4 + 2;
/// Scalar work per micro-patch: append of its 4 vertices, 2 triangles and patch record.
const PATCH_SCALAR: u32 = 4;
/// The fragment program of §4.2: 11 instructions (6 basic operations, a reciprocal, the receiver
/// depth lookup, then `MOV_SAT`, `SUB`, `MUL`), plus the receiver map's NDC depth to linear
/// (subtract, multiply, divide) and the bias test and select (2).
const FRAGMENT_OPS: u32 = 11 + 3 + 2;
/// The SSM merge of two passes: one max per texel.
const MERGE_OPS: u32 = 1;
/// Per eye block in `project`: light-frame transform (3 × 3 multiply-adds), tan (reciprocal, 2
/// multiplies), texel coordinates (2 multiply-adds, 2 floors, 2 fractions, 4 clamps), the
/// direction to the light and n·l (3 subtracts, dot, reciprocal square root, dot: 6), the
/// bilinear weights and blend (3 lerps as 6 ops), 1 − clamp (2), role selects (2).
const PROJECT_OPS: u32 = 9 + 3 + 10 + 6 + 6 + 2 + 2;
/// Occluder texels per task of the extents step: one row of 4×4 blocks at a time.
const ROW_BLOCKS: u32 = 1;

/// The occluder map(s), the receiver map and their frames.
struct Maps {
    /// The occluder maps' frame, focused on the occluders.
    occ: LightFrame,
    /// The receiver map's and the SSM's frame.
    ssm: LightFrame,
    /// Nearest surfaces, then (two passes) back faces.
    occluders: Vec<Surface>,
    receivers: Surface,
}

/// Rasterizes `triangles` into a depth map of `lf`, counting overdraw (fragments that did not
/// end up in the map).
fn depth_map(
    m: &mut Machine,
    frame: &Frame,
    lf: &LightFrame,
    name: &str,
    triangles: &[[u32; 3]],
    cull: Cull,
) -> Surface {
    let res = lf.resolution;
    let positions = m
        .memory
        .buffer("vertices", frame.flat.mesh.positions.clone());
    let triangles = m
        .memory
        .buffer(&format!("{name}.indices"), triangles.to_vec());
    let target = Target::square(res, frame.params.tile_size);
    let geometry = Geometry {
        positions: &positions,
        triangles: &triangles,
        view_proj: lf.view_proj,
    };
    let fill_before = m.counter(names::FILL);
    let pipeline = Pipeline {
        cull,
        ..Pipeline::DEPTH_ONLY
    };
    let out = raster::draw(m, name, target, pipeline, &geometry, &raster::DepthOnly);
    let map = out.depth.expect("a depth-only pipeline has depth");
    let kept = map.buf.data.iter().filter(|&&d| d < 1.0).count() as f64;
    let overdraw = m.counter(names::FILL) - fill_before - kept;
    m.count(names::OVERDRAW, overdraw);
    map
}

/// Phase `maps`: the occluder map of the nearest occluder surfaces (and, two passes, of their
/// back faces: front faces culled, nearest kept, as a depth-less pass with `glCullFace(GL_FRONT)`
/// renders them), the receiver map, and the transfer of the occluder maps to the host (§4.1).
fn maps(m: &mut Machine, frame: &Frame, split: &Split, o: &SoftShadowMapOptions) -> Maps {
    m.phase(Phase::Maps.name());
    let (occ, ssm) = LightFrame::new(
        &frame.scene.light,
        frame.scene.bounds(),
        frame.params.map_resolution,
    )
    .focused(split.occluder_bounds);
    let mut occluders = vec![depth_map(
        m,
        frame,
        &occ,
        "occluder_map",
        &split.occluders,
        Cull::None,
    )];
    if o.passes == 2 {
        occluders.push(depth_map(
            m,
            frame,
            &occ,
            "occluder_map_back",
            &split.occluders,
            Cull::Front,
        ));
    }
    let receivers = depth_map(m, frame, &ssm, "receiver_map", &split.receivers, Cull::None);
    if o.occluder_map_transfer {
        let texels = u64::from(occ.resolution) * u64::from(occ.resolution);
        m.transfer(
            "transfer",
            texels * 4 * occluders.len() as u64,
            o.transfer_gb_per_s,
        );
    }
    Maps {
        occ,
        ssm,
        occluders,
        receivers,
    }
}

/// Micro-patches and their extent quads (4 vertices in NDC, 2 triangles each) of one task.
#[derive(Default)]
struct Patches {
    patches: Vec<MicroPatch>,
    vertices: Vec<Vec3>,
}

/// Step `extents`: every occluder texel becomes a micro-patch and its extent quad (§3.2, §3.3),
/// one row of blocks per task, 16 texels to a vector; each task appends to its own region.
struct Extents<'a> {
    occ: &'a LightFrame,
    ssm: &'a LightFrame,
    map: &'a Surface,
    out_patches: &'a Buffer<MicroPatch>,
    out_vertices: &'a Buffer<Vec3>,
}

impl TaskKernel for Extents<'_> {
    type Out = Patches;

    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Patches {
        let map = self.map;
        let mut out = Patches::default();
        let by0 = task as u32 * ROW_BLOCKS;
        let by1 = (by0 + ROW_BLOCKS).min(map.height.div_ceil(BLOCK));
        let first = map.block_index(0, by0);
        for by in by0..by1 {
            for bx in 0..map.blocks_x {
                p.scalar(2);
                let b = map.block_index(bx, by);
                let depth = map.buf.load_run(p, b, LANES);
                let inside = Mask::from_fn(|l| {
                    bx * BLOCK + l as u32 % BLOCK < map.width
                        && by * BLOCK + l as u32 / BLOCK < map.height
                });
                let full = inside.and(Mask::from_fn(|l| depth[l] < 1.0));
                p.vector(1, inside);
                if !full.any() {
                    continue;
                }
                p.vector(EXTENT_OPS - 1, full);
                for l in full.lanes() {
                    let (i, j) = (bx * BLOCK + l as u32 % BLOCK, by * BLOCK + l as u32 / BLOCK);
                    let patch = micro_patch(self.occ, i, j, depth[l]).expect("full lane");
                    let k = first + out.patches.len();
                    p.scalar(PATCH_SCALAR);
                    self.out_patches.record_store(p, k, 1);
                    self.out_vertices.record_store(p, 4 * k, 4);
                    out.vertices.extend(extent_quad(self.ssm, &patch));
                    out.patches.push(patch);
                }
            }
        }
        out
    }
}

/// The fragment program of §4.2 over the extents' fragments: the hidden fraction of the light
/// at the texel's receiver. Tile state: fragments that hide nothing (overdraw).
struct Splat<'a> {
    lf: &'a LightFrame,
    receivers: &'a Surface,
    patches: &'a Buffer<MicroPatch>,
    bias_texels: f32,
}

impl FragmentKernel for Splat<'_> {
    type TileState = u64;

    fn begin_tile(&self, _: TileRect) -> u64 {
        0
    }

    fn shade<P: Probe>(&self, p: &mut P, zero: &mut u64, f: &Fragments<'_>) -> Shade {
        let patch = self.patches.load(p, f.prim as usize / 2);
        // Same view and resolution: the fragment's window coordinates address the receiver map.
        let r = self.receivers;
        let block = r.block_index(f.x / BLOCK, f.y / BLOCK);
        r.buf.record_load(p, block, LANES);
        p.vector(FRAGMENT_OPS, f.mask);
        // Every lane computed and kept by mask (no branch per lane): lanes without a receiver
        // (depth 1) or that the patch does not hide are dropped. Structure of arrays, one
        // branch-free loop per stage over the 16 lanes (`occlusion` selects its early zero),
        // so that each compiles to packed instructions.
        let lf = self.lf;
        let on = f.mask.to_lanes();
        let depth = &r.buf.data[block..block + LANES];
        let (mut tan_x, mut tan_y) = ([0.0f32; LANES], [0.0f32; LANES]);
        for l in 0..LANES {
            let (x, y) = f.pixel(l);
            let c = lf.texel_center(x, y);
            (tan_x[l], tan_y[l]) = (c.x, c.y);
        }
        let mut hidden = [0.0f32; LANES];
        for l in 0..LANES {
            let z_r = lf.linear_depth(depth[l]);
            let bias = bias_at(lf, self.bias_texels, z_r);
            let centre = Vec2::new(tan_x[l], tan_y[l]);
            hidden[l] = occlusion(lf, &patch, centre, z_r, bias);
        }
        let mut value = [0.0f32; LANES];
        let mut keep = [false; LANES];
        for l in 0..LANES {
            let d = depth[l];
            keep[l] = on[l] & (d < 1.0 || d.is_nan()) & (hidden[l] > 0.0);
            value[l] = if keep[l] { hidden[l] } else { 0.0 };
        }
        let shade = Shade {
            value,
            mask: Mask::from_lanes(&keep),
        };
        *zero += u64::from(f.mask.and_not(shade.mask).count());
        shade
    }
}

/// The micro-patches of `occluders` and their extents (step `extents`), then the extents drawn
/// additively into a soft shadow map named `name` (steps `binning` and `raster`).
fn splat(
    m: &mut Machine,
    frame: &Frame,
    maps: &Maps,
    occluders: &Surface,
    name: &str,
    o: &SoftShadowMapOptions,
) -> Surface {
    let lf = &maps.ssm;
    let n = occluders.buf.data.len();
    let mut patches = m
        .memory
        .buffer(&format!("{name}.patches"), vec![MicroPatch::default(); n]);
    let mut vertices = m
        .memory
        .buffer(&format!("{name}.vertices"), vec![Vec3::ZERO; 4 * n]);
    let step = Extents {
        occ: &maps.occ,
        ssm: lf,
        map: occluders,
        out_patches: &patches,
        out_vertices: &vertices,
    };
    let rows = occluders.height.div_ceil(BLOCK).div_ceil(ROW_BLOCKS);
    let weights = vec![u64::from(occluders.blocks_x); rows as usize];
    let parts = m.run_step("extents", &step, &weights);
    let (mut pv, mut vv) = (Vec::new(), Vec::new());
    for part in parts {
        pv.extend(part.patches);
        vv.extend(part.vertices);
    }
    let count = pv.len() as u32;
    m.count(names::SSM_MICRO_PATCHES, f64::from(count));
    m.count(names::SSM_OCCLUDER_TEXELS, n as f64);
    patches.data = pv;
    vertices.data = vv;
    let triangles = m.memory.buffer(
        &format!("{name}.triangles"),
        (0..count)
            .flat_map(|k| [[4 * k, 4 * k + 1, 4 * k + 2], [4 * k, 4 * k + 2, 4 * k + 3]])
            .collect(),
    );
    let res = lf.resolution;
    let target = Target::square(res, frame.params.tile_size);
    let pipeline = Pipeline::color_only(0.0, o.precision.blend(o.fp16_rounding));
    let geometry = Geometry {
        positions: &vertices,
        triangles: &triangles,
        view_proj: Mat4::IDENTITY,
    };
    let kernel = Splat {
        lf,
        receivers: &maps.receivers,
        patches: &patches,
        bias_texels: o.bias_texels,
    };
    let out = raster::draw(m, name, target, pipeline, &geometry, &kernel);
    m.count(names::OVERDRAW, out.tiles.iter().sum::<u64>() as f64);
    out.color.expect("the pipeline has a colour target")
}

/// Step `merge` of two passes (§3.5): the maximum of the two SSMs, one row of blocks per task.
struct Merge<'a> {
    a: &'a Surface,
    b: &'a Surface,
}

impl TaskKernel for Merge<'_> {
    type Out = Vec<f32>;

    fn run<P: Probe>(&self, p: &mut P, row: usize) -> Vec<f32> {
        let per_row = self.a.blocks_x as usize * LANES;
        let i = row * per_row;
        let (a, b) = (
            self.a.buf.load_run(p, i, per_row),
            self.b.buf.load_run(p, i, per_row),
        );
        p.vector(MERGE_OPS * self.a.blocks_x, Mask::ALL);
        self.a.buf.record_store(p, i, per_row);
        a.iter().zip(b).map(|(x, y)| x.max(*y)).collect()
    }
}

/// Phase `splat`: one SSM per occluder map, merged by max with two passes.
fn soft_shadow_map(
    m: &mut Machine,
    frame: &Frame,
    maps: &Maps,
    o: &SoftShadowMapOptions,
) -> Surface {
    m.phase(Phase::Splat.name());
    let mut ssm = splat(m, frame, maps, &maps.occluders[0], "soft_shadow_map", o);
    if let Some(back) = maps.occluders.get(1) {
        let ssm_back = splat(m, frame, maps, back, "soft_shadow_map_back", o);
        let rows = ssm.height.div_ceil(BLOCK) as usize;
        let merge = Merge {
            a: &ssm,
            b: &ssm_back,
        };
        let merged: Vec<f32> = m
            .run_step("merge", &merge, &vec![u64::from(ssm.blocks_x); rows])
            .concat();
        ssm.buf.data = merged;
    }
    ssm
}

/// Bilinear lookup of the SSM at continuous texel coordinates `s` (texel centres at
/// half-integers), clamped to the edge texels: the projective texture of §3 with linear
/// filtering. Returns the element indices of the four taps and their weights.
pub fn bilinear_taps(lf: &LightFrame, ssm: &Surface, s: Vec2) -> ([usize; 4], [f32; 4]) {
    let n = lf.resolution as f32;
    let c = s - Vec2::splat(0.5);
    let base = c.floor();
    let w = c - base;
    let at = |dx: f32, dy: f32| {
        let x = (base.x + dx).clamp(0.0, n - 1.0) as u32;
        let y = (base.y + dy).clamp(0.0, n - 1.0) as u32;
        ssm.index(x, y)
    };
    (
        [at(0.0, 0.0), at(1.0, 0.0), at(0.0, 1.0), at(1.0, 1.0)],
        [
            (1.0 - w.x) * (1.0 - w.y),
            w.x * (1.0 - w.y),
            (1.0 - w.x) * w.y,
            w.x * w.y,
        ],
    )
}

/// Step `lookup` of phase `project`: each eye tile's samples look the SSM up.
struct Project<'a> {
    lf: &'a LightFrame,
    ssm: &'a Surface,
    receives: &'a [bool],
    position: Buffer<Vec3, &'a [Vec3]>,
    normal: Buffer<Vec3, &'a [Vec3]>,
    triangle: Buffer<u32, &'a [u32]>,
    object: Buffer<u32, &'a [u32]>,
    visibility: Buffer<f32>,
}

impl EyeKernel for Project<'_> {
    fn block<P: Probe>(&self, p: &mut P, b: &EyeBlock, out: &mut Vec<(u32, f32)>) {
        let mut hit = Mask::NONE;
        let mut tri = [0u32; LANES];
        let mut samples = [Sample::Lit; LANES];
        let cols = b.cols as usize;
        for row in 0..b.rows {
            let ids = self.triangle.load_run(p, b.row_start(row), cols);
            for (c, &id) in ids.iter().enumerate() {
                if id != u32::MAX {
                    let lane = row as usize * BLOCK as usize + c;
                    hit.0 |= 1 << lane;
                    tri[lane] = id;
                }
            }
        }
        if !hit.any() {
            return;
        }
        let objects = self.object.gather(p, &tri, hit);
        for row in 0..b.rows {
            let i = b.row_start(row);
            let pos = self.position.load_run(p, i, cols);
            let nrm = self.normal.load_run(p, i, cols);
            for c in 0..cols {
                let lane = row as usize * BLOCK as usize + c;
                if hit.get(lane) {
                    let receives = self.receives[objects[lane] as usize];
                    samples[lane] = classify(self.lf, pos[c], nrm[c], receives);
                }
            }
        }
        p.vector(PROJECT_OPS, hit);
        let look = Mask::from_fn(|l| matches!(samples[l], Sample::Receiver(_)));
        let mut taps = [[0u32; LANES]; 4];
        let mut weights = [[0f32; LANES]; 4];
        for l in look.lanes() {
            if let Sample::Receiver(s) = samples[l] {
                let (idx, wt) = bilinear_taps(self.lf, self.ssm, s);
                for k in 0..4 {
                    taps[k][l] = idx[k] as u32;
                    weights[k][l] = wt[k];
                }
            }
        }
        let mut occ = [0f32; LANES];
        if look.any() {
            for k in 0..4 {
                let v = self.ssm.buf.gather(p, &taps[k], look);
                for l in look.lanes() {
                    occ[l] += weights[k][l] * v[l];
                }
            }
        }
        b.store(p, &self.visibility, out, |lane| {
            hit.get(lane).then(|| match samples[lane] {
                Sample::Lit => 1.0,
                Sample::Averted => 0.0,
                Sample::Receiver(_) => visibility(occ[lane]),
            })
        });
    }
}

/// Phase `project`: the SSM projected onto every eye sample (one eye tile per task).
fn project(
    m: &mut Machine,
    frame: &Frame,
    lf: &LightFrame,
    ssm: &Surface,
    split: &Split,
) -> VisibilityBuffer {
    m.phase(Phase::Project.name());
    let g = &frame.gbuffer;
    let pass = Project {
        lf,
        ssm,
        receives: &split.receives,
        position: m.memory.borrowed("gbuffer.position", &g.position),
        normal: m.memory.borrowed("gbuffer.normal", &g.normal),
        triangle: m.memory.borrowed("gbuffer.triangle", &g.triangle),
        object: m
            .memory
            .borrowed("object_of_triangle", &frame.flat.object_of_triangle),
        visibility: m.memory.unbacked("visibility", g.len()),
    };
    let weights = eye_tiles(frame).tile_weights(|i| g.is_hit(i));
    eye_lookup_step(m, frame, &pass, &weights)
}

/// `soft_shadow_map` on a CPU execution.
pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    o: &SoftShadowMapOptions,
) -> Result<FrameOutput> {
    let split = Split::of(&frame.flat);
    let mut m = machine(backend, frame, ctx);
    let maps = maps(&mut m, frame, &split, o);
    let ssm = soft_shadow_map(&mut m, frame, &maps, o);
    let vis = project(&mut m, frame, &maps.ssm, &ssm, &split);
    let mut out = output(m, vis);
    out.warnings.extend(split.warning());
    record_receivers_outside(frame, &split, &mut out);
    Ok(out)
}
