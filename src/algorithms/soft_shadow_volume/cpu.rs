//! `soft_shadow_volume` on the CPU executions (`cpu-native`, `cpu-model`): pass 1 (hard shadow
//! quads, phase `hard`), wedge construction (phase `wedges`), pass 2 (wedges adding or
//! subtracting coverage, phase `soft`), per silhouette loop and per sub-light when the overlap
//! approximation or light splitting are on. Both passes are tile tasks of the machine, in 16-lane
//! blocks, written once for both executions.

use std::sync::Arc;

use glam::Vec3;

use super::wedges::{build_wedge, coverage_texture, wedge_primitives, wedge_reach, WedgePrimitive};
use super::Phase;
use super::{
    exact_coverage, overlap_coverage, split12, split_light, CoverageMethod, CoverageTexture,
    Emitter, EmitterShape, SoftShadowVolumeOptions, SubLightLoops, VBufferPrecision, Wedge,
};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{machine, output};
use crate::algorithms::eye_raster::{
    raster_pass, Block, EyeBuffer, EyeRays, ScreenRect, TilePass, DEPTH_BYTES,
};
use crate::algorithms::shadow_volume::{
    mem_read, mem_write, render_hard, CountTarget, Counting, HardCounting, ShadowQuad,
};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::{BufferId, Lanes, Machine, Mask, Probe, TaskKernel, LANES};
use crate::record::PhaseId;
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};
use crate::scene::{Light, LightTexture};
use crate::visibility::{RgbBuffer, VisibilityBuffer};

/// Bytes per pixel of the f32 V-buffer, of one rgba8 buffer of the split V-buffer, and of the
/// stencil buffer.
const VBUFFER_F32_BYTES: u32 = 4;
const VBUFFER_RGBA8_BYTES: u32 = 4;
const STENCIL_BYTES: u32 = 1;

/// Vector instructions per wedge plane of the ray–wedge interval: a dot of the normal with the
/// direction and with the origin, a subtract, a divide, a compare and a min or max.
const WEDGE_PLANE_OPS: u32 = 3 + 3 + 1 + 1 + 2;
/// The scene-bounds slab test that starts the interval (per axis a reciprocal, two multiply-adds,
/// a min, a max; then two compares).
const SLAB_OPS: u32 = 3 * 5 + 2;
/// The wedge's depth tests against the visible surface (entry and exit), with the mask updates.
const WEDGE_DEPTH_OPS: u32 = 4;
/// Per shaded fragment: the emitter frame seen from p (a subtract, a normalize, two cross
/// products), clipping the edge to the half-space in front of p (two 3-term dots, divides,
/// compares, selects and a lerp), the projection of both ends (per end a subtract, a divide and
/// two 3-term dots) and the clip against the emitter's border (Liang–Barsky or the disc
/// intersection).
const PROJECT_OPS: u32 = (3 + 4 + 6 + 6) + (6 + 2 + 4 + 4 + 6) + 2 * (3 + 3 + 6) + 16;
/// Exact clipping of the projected quad against the emitter: three half-plane clips of a square
/// (per vertex an affine test, a compare and an interpolation) and the shoelace area, or the
/// sector formula for a disc.
const EXACT_OPS: u32 = 3 * 4 * 6 + 10;
/// The texture lookup's addressing and bilinear filter: two texel positions (multiply-add, clamp
/// per coordinate), a round, two floors, the four indices and the two lerps in each direction.
const TEXTURE_OPS: u32 = 8 + 2 + 2 + 4 * 3 + TEXTURE_FILTER_OPS;
/// The bilinear filter's lerps (part of `TEXTURE_OPS`), once more per extra channel of a
/// textured light's RGB texture.
const TEXTURE_FILTER_OPS: u32 = 6;
/// Adding or subtracting the coverage into the V-buffer (select by side, add; the split format's
/// digit split and carry blend in the 12-bit case).
const VBUFFER_OPS_F32: u32 = 2;
const VBUFFER_OPS_SPLIT12: u32 = 2 + 12;
/// Wedge construction per edge (16 edges per vector): the top edge (two distances, a compare, a
/// scaled vertex), the front and back planes tangent to the light and the two side planes (per
/// plane about 20 instructions), and the hull's far corners (per corner a cross product, a
/// normalize, a sign select and a multiply-add).
const WEDGE_BUILD_OPS: u32 = 12 + 4 * 20 + 4 * 14;
/// Silhouette edges built into wedges by one task.
const WEDGES_PER_TASK: usize = 4 * LANES;

/// The per-pixel V-buffer contributions of one silhouette loop.
enum Accum {
    F32(Vec<f32>),
    /// One f32 per channel of a textured light (III §4.1).
    Rgb(Vec<[f32; 3]>),
    /// Additive and subtractive rgba8 buffers (IV §4.3).
    Split(Vec<[u8; 4]>, Vec<[u8; 4]>),
}

impl Accum {
    fn new(precision: VBufferPrecision, rgb: bool, n: usize) -> Accum {
        match precision {
            VBufferPrecision::F32 if rgb => Accum::Rgb(vec![[0.0; 3]; n]),
            VBufferPrecision::F32 => Accum::F32(vec![0.0; n]),
            VBufferPrecision::Split12 => Accum::Split(vec![[0; 4]; n], vec![[0; 4]; n]),
        }
    }

    /// Adds `coverage` on the inner side (`side < 0`), subtracts it on the outer side (per
    /// channel for a textured light; else the channels are equal and one is kept).
    fn add(&mut self, j: usize, side: f32, coverage: [f32; 3]) {
        match self {
            Accum::F32(v) => v[j] -= side * coverage[0],
            Accum::Rgb(v) => {
                for c in 0..3 {
                    v[j][c] -= side * coverage[c];
                }
            }
            Accum::Split(add, sub) => {
                let digits = split12::split(coverage[0]);
                let target = if side < 0.0 { add } else { sub };
                target[j] = split12::blend(target[j], digits);
            }
        }
    }

    fn value(&self, j: usize) -> [f32; 3] {
        match self {
            Accum::F32(v) => [v[j]; 3],
            Accum::Rgb(v) => v[j],
            Accum::Split(add, sub) => [split12::value(add[j]) - split12::value(sub[j]); 3],
        }
    }
}

/// Fragment counts of pass 2.
#[derive(Default)]
struct SoftTally {
    fill: u64,
    depth_reads: u64,
    stencil_reads: u64,
    stencil_writes: u64,
    shaded: u64,
    culled: u64,
    inside: u64,
    contributing: u64,
    texture_reads: u64,
}

impl SoftTally {
    fn merge(&mut self, o: &SoftTally) {
        self.fill += o.fill;
        self.depth_reads += o.depth_reads;
        self.stencil_reads += o.stencil_reads;
        self.stencil_writes += o.stencil_writes;
        self.shaded += o.shaded;
        self.culled += o.culled;
        self.inside += o.inside;
        self.contributing += o.contributing;
        self.texture_reads += o.texture_reads;
    }
}

/// The coverage texture in modelled memory.
struct TextureBuffer {
    texture: Arc<CoverageTexture>,
    id: BufferId,
    base: u64,
}

/// Everything fixed for a frame.
struct Setup {
    rays: EyeRays,
    opts: SoftShadowVolumeOptions,
    texture: Option<TextureBuffer>,
    /// Mean colour of a textured light (what an unoccluded point receives); `None`: uniform
    /// white, one channel.
    mean: Option<[f32; 3]>,
    tile: u32,
    /// Pass 1's target: the V-buffer (f32) or the stencil (split12), tested against `depth`.
    hard: CountTarget,
    vbuffer: EyeBuffer,
    stencil: EyeBuffer,
}

pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &SoftShadowVolumeOptions,
) -> Result<FrameOutput> {
    let light = frame.scene.light;
    let sub_lights = split_light(&light, opts.light_split)?;
    let mut m = machine(backend, frame, ctx);
    for phase in Phase::ALL {
        m.phase(phase.name());
    }
    let setup = Setup::new(&mut m, frame, opts, ctx.deadline);
    let adjacency = EdgeAdjacency::build(&frame.scene.occluders());
    let occluders = frame.scene.occluders();
    let n = setup.rays.len();
    let mut warnings = Vec::new();
    let mut visibility = vec![0.0f32; n];
    let mut rgb = vec![[0.0f32; 3]; n];
    for sub in &sub_lights {
        let centre = sub.center();
        let SubLightLoops {
            silhouette_edges,
            loops,
            eye,
            warning,
        } = SubLightLoops::new(&adjacency, &occluders, centre, setup.rays.eye, opts);
        m.phase(Phase::Hard.name());
        m.count(names::SILHOUETTE_EDGES, silhouette_edges as f64);
        warnings.extend(warning);
        let mut covered = vec![0.0f32; n];
        for (k, edges) in loops.iter().enumerate() {
            let counting = match opts.counting {
                Counting::ZPass => HardCounting::ZPass {
                    eye_count: if loops.len() > 1 { 0 } else { eye },
                },
                Counting::ZFail => HardCounting::ZFail {
                    occluders: &occluders,
                    light: centre,
                },
            };
            let v = render_loop(&mut m, &setup, sub, edges, counting);
            if let Some(mean) = setup.mean {
                // One loop and one light (`check_light_texture`): the light received per
                // channel, at most the unoccluded mean colour (all of it without a surface),
                // and its luminance fraction.
                for i in 0..n {
                    rgb[i] = if setup.rays.is_hit(i) {
                        std::array::from_fn(|c| v[i][c].clamp(0.0, mean[c]))
                    } else {
                        mean
                    };
                    visibility[i] = LightTexture::visibility(rgb[i], mean);
                }
                continue;
            }
            for i in 0..n {
                let c = (1.0 - v[i][0]).clamp(0.0, 1.0);
                covered[i] = if k == 0 {
                    c
                } else {
                    overlap_coverage(covered[i], c)
                };
            }
        }
        if setup.mean.is_none() {
            for i in 0..n {
                visibility[i] += (1.0 - covered[i]) / sub_lights.len() as f32;
            }
        }
    }
    for (i, v) in visibility.iter_mut().enumerate() {
        *v = if setup.rays.is_hit(i) {
            v.clamp(0.0, 1.0)
        } else {
            1.0
        };
    }
    let visibility = VisibilityBuffer {
        width: frame.width(),
        height: frame.height(),
        data: visibility,
    };
    let mut out = output(m, visibility);
    out.warnings = warnings;
    if setup.mean.is_some() {
        out.rgb = Some(RgbBuffer {
            width: frame.width(),
            height: frame.height(),
            data: rgb,
        });
    }
    out.execution
        .insert("options".to_string(), serde_json::json!(opts));
    if let Some(t) = &setup.texture {
        out.execution.insert(
            "coverage_texture_bytes".into(),
            serde_json::json!(t.texture.bytes()),
        );
    }
    Ok(out)
}

impl Setup {
    /// The frame's eye rays and buffers (depth, V-buffer, stencil; reserved in `m`'s memory),
    /// and the coverage texture when the options ask for it.
    fn new(
        m: &mut Machine,
        frame: &Frame,
        opts: &SoftShadowVolumeOptions,
        deadline: crate::util::deadline::Deadline,
    ) -> Setup {
        let light = frame.scene.light;
        let rays = EyeRays::new(frame);
        let depth = EyeBuffer::new(m, &rays, "depth", DEPTH_BYTES as u32);
        // One f32 per channel under a textured light (III §4.1).
        let channels = if frame.scene.light_texture.is_some() {
            3
        } else {
            1
        };
        let vbuffer_bytes = match opts.vbuffer {
            VBufferPrecision::F32 => VBUFFER_F32_BYTES * channels,
            VBufferPrecision::Split12 => VBUFFER_RGBA8_BYTES,
        };
        let vbuffer = EyeBuffer::new(m, &rays, "vbuffer", vbuffer_bytes);
        let stencil = EyeBuffer::new(m, &rays, "stencil", STENCIL_BYTES);
        let light_texture = frame.scene.light_texture.as_deref();
        let texture = (opts.coverage == CoverageMethod::Texture).then(|| {
            let texture = coverage_texture(
                EmitterShape::of(&light),
                opts.texture_n,
                light_texture,
                deadline,
            );
            let (id, base) = m.memory.reserve("coverage_texture", texture.bytes());
            TextureBuffer { texture, id, base }
        });
        Setup {
            hard: CountTarget {
                depth,
                count: match opts.vbuffer {
                    VBufferPrecision::F32 => vbuffer,
                    VBufferPrecision::Split12 => stencil,
                },
                clear: false,
            },
            rays,
            texture,
            mean: light_texture.map(LightTexture::mean),
            opts: *opts,
            tile: frame.params.tile_size.max(1),
            vbuffer,
            stencil,
        }
    }

    /// Channels of the V-buffer and the coverage texture: 3 for a textured light, else 1.
    fn channels(&self) -> u32 {
        if self.mean.is_some() {
            3
        } else {
            1
        }
    }
}

/// Wedge construction, `WEDGES_PER_TASK` silhouette edges per task.
struct BuildWedges<'a> {
    edges: &'a [SilhouetteEdge],
    light: &'a Light,
    tighter: bool,
    reach: f32,
}

impl TaskKernel for BuildWedges<'_> {
    type Out = Vec<Option<Wedge>>;

    fn run<P: Probe>(&self, p: &mut P, t: usize) -> Self::Out {
        let edges =
            &self.edges[t * WEDGES_PER_TASK..((t + 1) * WEDGES_PER_TASK).min(self.edges.len())];
        for chunk in edges.chunks(LANES) {
            p.vector(WEDGE_BUILD_OPS, Mask::first(chunk.len()));
        }
        edges
            .iter()
            .map(|e| build_wedge(e, self.light, self.tighter, self.reach))
            .collect()
    }
}

/// Renders one silhouette loop (or the whole silhouette) for one (sub-)light: returns its
/// V-buffer, 1 − (hard count) ± wedge coverage, and adds to the phases' counters. Per channel
/// for a textured light, where the unoccluded light is its mean colour: `mean·(1 − count) ±
/// coverage`; else the three channels are equal.
fn render_loop(
    m: &mut Machine,
    s: &Setup,
    light: &Light,
    edges: &[SilhouetteEdge],
    counting: HardCounting,
) -> Vec<[f32; 3]> {
    let centre = light.center();
    let rays = &s.rays;

    // Pass 1: hard shadow quads (III §3.2.1).
    m.phase(Phase::Hard.name());
    let quads: Vec<ShadowQuad> = edges.iter().map(|e| ShadowQuad::new(e, centre)).collect();
    let hard = render_hard(m, "quads", rays, &quads, counting, s.tile, &s.hard);
    if let HardCounting::ZFail { .. } = counting {
        m.count(names::VOLUME_CAPS, hard.caps as f64);
    }
    m.count(names::FILL, hard.fill as f64);
    m.count(names::OVERDRAW, (hard.fill - hard.passed) as f64);
    mem_read(m, "depth", hard.fill * DEPTH_BYTES);
    let (buffer, bytes) = match s.opts.vbuffer {
        VBufferPrecision::F32 => ("vbuffer", VBUFFER_F32_BYTES),
        VBufferPrecision::Split12 => ("stencil", STENCIL_BYTES),
    };
    mem_read(m, buffer, hard.passed * u64::from(bytes));
    mem_write(m, buffer, hard.passed * u64::from(bytes));

    // Wedge construction (III §3.1, IV §4.1).
    m.phase(Phase::Wedges.name());
    let build = BuildWedges {
        edges,
        light,
        tighter: s.opts.tighter_wedges,
        reach: wedge_reach(rays),
    };
    let weights: Vec<u64> = edges
        .chunks(WEDGES_PER_TASK)
        .map(|c| c.len() as u64)
        .collect();
    let wedges: Vec<Option<Wedge>> = m.run_step("build", &build, &weights).concat();
    let degenerate = wedges.iter().filter(|w| w.is_none()).count();
    m.count(names::WEDGES, (wedges.len() - degenerate) as f64);
    m.count(names::WEDGES_DEGENERATE, degenerate as f64);

    // Pass 2: penumbra wedges (III §3.2.2), by wedge halves when culling (IV §4.4).
    m.phase(Phase::Soft.name());
    let (accum, tally) = soft_pass(m, s, light, &quads, &wedges);
    m.count(names::FILL, tally.fill as f64);
    m.count(names::OVERDRAW, (tally.fill - tally.contributing) as f64);
    m.count(names::SHADER_INVOCATIONS, tally.shaded as f64);
    m.count(names::CULLED_FRAGMENTS, tally.culled as f64);
    m.count(names::FRAGMENTS_INSIDE_WEDGES, tally.inside as f64);
    mem_read(m, "depth", tally.depth_reads * DEPTH_BYTES);
    mem_read(m, "stencil", tally.stencil_reads * u64::from(STENCIL_BYTES));
    mem_write(
        m,
        "stencil",
        tally.stencil_writes * u64::from(STENCIL_BYTES),
    );
    let vbytes = match s.opts.vbuffer {
        VBufferPrecision::F32 => VBUFFER_F32_BYTES * s.channels(),
        VBufferPrecision::Split12 => VBUFFER_RGBA8_BYTES,
    };
    mem_read(m, "vbuffer", tally.inside * u64::from(vbytes));
    mem_write(m, "vbuffer", tally.inside * u64::from(vbytes));
    mem_read(m, "coverage_texture", tally.texture_reads);
    let unoccluded = s.mean.unwrap_or([1.0; 3]);
    (0..rays.len())
        .map(|i| {
            let (lit, acc) = (1.0 - hard.count[i] as f32, accum.value(i));
            std::array::from_fn(|c| unoccluded[c] * lit + acc[c])
        })
        .collect()
}

/// Pass 2 over the eye tiles.
struct SoftPass<'a> {
    s: &'a Setup,
    light: &'a Light,
    quads: &'a [ShadowQuad],
    prims: Vec<WedgePrimitive>,
}

struct SoftTile {
    rect: ScreenRect,
    accum: Accum,
    tally: SoftTally,
}

impl SoftPass<'_> {
    /// Coverage of the light seen from `p` by the hard shadow quad of `quad`'s edge, and the
    /// four coverage-texture texels read for it (when the texture is used); `None` when the
    /// projected edge misses the light.
    fn coverage(&self, quad: &ShadowQuad, p: Vec3) -> Option<([f32; 3], [u32; 4])> {
        let emitter = Emitter::seen_from(self.light, p);
        let (q0, q1) = emitter.project_edge(p, quad.a, quad.b)?;
        let (c0, c1) = emitter.shape.clip(q0, q1)?;
        Some(match &self.s.texture {
            Some(t) => t.texture.lookup_texels(c0, c1),
            None => ([exact_coverage(emitter.shape, c0, c1); 3], [0; 4]),
        })
    }
}

impl TilePass for SoftPass<'_> {
    type State = SoftTile;

    fn begin<P: Probe>(&self, _: &mut P, rect: ScreenRect) -> SoftTile {
        SoftTile {
            rect,
            accum: Accum::new(
                self.s.opts.vbuffer,
                self.s.mean.is_some(),
                ((rect.x1 - rect.x0) * (rect.y1 - rect.y0)) as usize,
            ),
            tally: SoftTally::default(),
        }
    }

    fn block<P: Probe>(&self, p: &mut P, st: &mut SoftTile, k: usize, b: &Block) {
        let s = self.s;
        let rays = &s.rays;
        let prim = &self.prims[k];
        let quad = &self.quads[prim.edge];
        p.vector(
            SLAB_OPS + WEDGE_PLANE_OPS * prim.volume.planes.len() as u32,
            b.mask,
        );
        let mut t_in = [0.0f32; LANES];
        let mut t_out = [0.0f32; LANES];
        // Lanes outside the mask may lie past the image edge: never index with them.
        let fill = Mask::from_fn(|l| {
            if !b.mask.get(l) {
                return false;
            }
            let i = b.pixel[l] as usize;
            let (b0, b1) = rays.bounds_interval(i);
            match prim.volume.ray_interval(rays.eye, rays.dir[i], b0, b1) {
                Some((a, z)) => {
                    (t_in[l], t_out[l]) = (a, z);
                    true
                }
                None => false,
            }
        });
        if !fill.any() {
            return;
        }
        p.vector(WEDGE_DEPTH_OPS, fill);
        let t_p = |l: usize| rays.depth[b.pixel[l] as usize];
        // Lanes whose visible point is behind the wedge's entry, and those also in front of its
        // exit (inside the wedge).
        let front = Mask::from_fn(|l| fill.get(l) && t_in[l] < t_p(l));
        let inside = Mask::from_fn(|l| front.get(l) && t_p(l) < t_out[l]);
        let t = &mut st.tally;
        let mut side: Lanes<f32> = [0.0; LANES];
        match prim.half {
            // IV §4.4: front faces with GL_GREATER set the stencil, back faces with GL_LESS
            // and the stencil test run the shader (and reset the stencil they consumed); both
            // passes rasterize the half.
            Some(half) => {
                let n = u64::from(fill.count());
                t.fill += 2 * n;
                t.depth_reads += 2 * n;
                t.stencil_reads += n;
                t.stencil_writes += 2 * u64::from(front.count());
                t.culled += n - u64::from(inside.count());
                t.shaded += u64::from(inside.count());
                s.hard.depth.read(p, b, fill);
                s.hard.depth.read(p, b, fill);
                s.stencil.read(p, b, fill);
                s.stencil.write(p, b, front);
                s.stencil.write(p, b, front);
                side = [half; LANES];
            }
            // III §3.2.2: the front faces run the shader, which tests "p inside the wedge".
            None => {
                t.fill += u64::from(fill.count());
                t.depth_reads += u64::from(fill.count());
                t.shaded += u64::from(front.count());
                s.hard.depth.read(p, b, fill);
                for l in inside.lanes() {
                    side[l] = quad.side(rays.point[b.pixel[l] as usize]);
                }
            }
        }
        if !inside.any() {
            return;
        }
        p.vector(PROJECT_OPS, inside);
        let mut coverage = [[0.0f32; 3]; LANES];
        let mut texels = [[0u32; 4]; LANES];
        let covered = Mask::from_fn(|l| {
            if !inside.get(l) {
                return false;
            }
            match self.coverage(quad, rays.point[b.pixel[l] as usize]) {
                Some((c, idx)) => {
                    (coverage[l], texels[l]) = (c, idx);
                    true
                }
                None => false,
            }
        });
        if !covered.any() {
            return;
        }
        match &s.texture {
            Some(tex) => {
                p.vector(
                    TEXTURE_OPS + TEXTURE_FILTER_OPS * (tex.texture.channels - 1),
                    covered,
                );
                if P::ENABLED {
                    // One gather per bilinear tap, each lane reading its own texel.
                    let ch = u64::from(tex.texture.channels);
                    let taps: [Lanes<u64>; 4] = std::array::from_fn(|r| {
                        std::array::from_fn(|l| tex.base + ch * u64::from(texels[l][r]))
                    });
                    for addrs in &taps {
                        p.gather(tex.id, addrs, ch as u32, covered);
                    }
                }
                t.texture_reads += CoverageTexture::READS
                    * u64::from(tex.texture.channels)
                    * u64::from(covered.count());
            }
            None => p.vector(EXACT_OPS, covered),
        }
        t.inside += u64::from(covered.count());
        t.contributing += u64::from(
            Mask::from_fn(|l| coverage[l].iter().any(|&c| c > 0.0))
                .and(covered)
                .count(),
        );
        s.vbuffer.read(p, b, covered);
        p.vector(
            match s.opts.vbuffer {
                VBufferPrecision::F32 => VBUFFER_OPS_F32 * s.channels(),
                VBufferPrecision::Split12 => VBUFFER_OPS_SPLIT12,
            },
            covered,
        );
        let w = st.rect.x1 - st.rect.x0;
        for l in covered.lanes() {
            let (x, y) = b.lane_xy(l);
            let j = ((y - st.rect.y0) * w + x - st.rect.x0) as usize;
            st.accum.add(j, side[l], coverage[l]);
        }
        s.vbuffer.write(p, b, covered);
    }
}

fn soft_pass(
    m: &mut Machine,
    s: &Setup,
    light: &Light,
    quads: &[ShadowQuad],
    wedges: &[Option<Wedge>],
) -> (Accum, SoftTally) {
    let rays = &s.rays;
    let (prims, footprints) = wedge_primitives(rays, quads, wedges, s.opts.wedge_culling);
    let pass = SoftPass {
        s,
        light,
        quads,
        prims,
    };
    let tiles = raster_pass(m, "wedges", rays, &footprints, s.tile, &pass);
    let mut accum = Accum::new(s.opts.vbuffer, s.mean.is_some(), rays.len());
    let mut tally = SoftTally::default();
    for tile in tiles {
        let st = tile.state;
        tally.merge(&st.tally);
        let w = st.rect.x1 - st.rect.x0;
        for y in st.rect.y0..st.rect.y1 {
            for x in st.rect.x0..st.rect.x1 {
                let (g, j) = (
                    (y * rays.width + x) as usize,
                    ((y - st.rect.y0) * w + x - st.rect.x0) as usize,
                );
                match (&mut accum, &st.accum) {
                    (Accum::F32(a), Accum::F32(b)) => a[g] = b[j],
                    (Accum::Rgb(a), Accum::Rgb(b)) => a[g] = b[j],
                    (Accum::Split(a0, a1), Accum::Split(b0, b1)) => {
                        a0[g] = b0[j];
                        a1[g] = b1[j];
                    }
                    _ => unreachable!("one precision per pass"),
                }
            }
        }
    }
    (accum, tally)
}
