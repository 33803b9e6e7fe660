//! `soft_shadow_volume` on the host (`cpu-native`): pass 1 (hard shadow quads), wedge
//! construction, pass 2 (wedges adding or subtracting coverage), per silhouette loop and per
//! sub-light when the overlap approximation or light splitting are on.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::Vec3;

use super::{
    exact_coverage, overlap_coverage, silhouette_loops, split12, split_light, CoverageMethod,
    CoverageTexture, Emitter, EmitterShape, SoftShadowVolumeOptions, VBufferPrecision, Wedge, ID,
};
use crate::algorithms::eye_raster::{raster_pass, ConvexVolume, EyeRays, ScreenRect, DEPTH_BYTES};
use crate::algorithms::shadow_map::parse_options;
use crate::algorithms::shadow_volume::{eye_count, mem_read, mem_write, render_quads, ShadowQuad};
use crate::algorithms::{ExecContext, FrameOutput};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::record::{Counters, Phase};
use crate::scene::adjacency::{EdgeAdjacency, SilhouetteEdge};
use crate::scene::Light;
use crate::visibility::VisibilityBuffer;

/// Bytes per pixel of the f32 V-buffer, of one rgba8 buffer of the split V-buffer, and of the
/// stencil buffer.
const VBUFFER_F32_BYTES: u64 = 4;
const VBUFFER_RGBA8_BYTES: u64 = 4;
const STENCIL_BYTES: u64 = 1;

/// Coverage textures are precomputed once per (shape, n), as the paper does offline.
fn coverage_texture(shape: EmitterShape, n: u32) -> Arc<CoverageTexture> {
    static CACHE: Mutex<Vec<Arc<CoverageTexture>>> = Mutex::new(Vec::new());
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(t) = cache.iter().find(|t| t.shape == shape && t.n == n) {
        return t.clone();
    }
    let t = Arc::new(CoverageTexture::build(shape, n));
    cache.push(t.clone());
    t
}

/// The per-pixel V-buffer contributions of one silhouette loop.
enum Accum {
    F32(Vec<f32>),
    /// Additive and subtractive rgba8 buffers (IV §4.3).
    Split(Vec<[u8; 4]>, Vec<[u8; 4]>),
}

impl Accum {
    fn new(precision: VBufferPrecision, n: usize) -> Accum {
        match precision {
            VBufferPrecision::F32 => Accum::F32(vec![0.0; n]),
            VBufferPrecision::Split12 => Accum::Split(vec![[0; 4]; n], vec![[0; 4]; n]),
        }
    }

    /// Adds `coverage` on the inner side (`side < 0`), subtracts it on the outer side.
    fn add(&mut self, j: usize, side: f32, coverage: f32) {
        match self {
            Accum::F32(v) => v[j] -= side * coverage,
            Accum::Split(add, sub) => {
                let digits = split12::split(coverage);
                let target = if side < 0.0 { add } else { sub };
                target[j] = split12::blend(target[j], digits);
            }
        }
    }

    fn value(&self, j: usize) -> f32 {
        match self {
            Accum::F32(v) => v[j],
            Accum::Split(add, sub) => split12::value(add[j]) - split12::value(sub[j]),
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

/// Everything fixed for a frame.
struct Setup {
    rays: EyeRays,
    opts: SoftShadowVolumeOptions,
    texture: Option<Arc<CoverageTexture>>,
    tile: u32,
}

pub fn render(frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    let opts: SoftShadowVolumeOptions = parse_options(ID, &ctx.options)?;
    opts.validate()?;
    let light = frame.scene.light;
    let sub_lights = split_light(&light, opts.light_split).ok_or_else(|| {
        Error::Unsupported(format!(
            "{ID}: light splitting (light_split = {}) needs a rectangular light, got {}",
            opts.light_split,
            light.kind()
        ))
    })?;
    let setup = Setup {
        rays: EyeRays::new(frame),
        texture: (opts.coverage == CoverageMethod::Texture)
            .then(|| coverage_texture(EmitterShape::of(&light), opts.texture_n)),
        opts,
        tile: frame.params.tile_size.max(1),
    };
    let adjacency = EdgeAdjacency::build(&frame.scene.occluders());
    let occluders = frame.scene.occluders();
    let n = setup.rays.len();
    let mut phases: Vec<Phase> = ["hard", "wedges", "soft"]
        .iter()
        .map(|name| Phase {
            name: name.to_string(),
            ..Default::default()
        })
        .collect();
    let mut warnings = Vec::new();
    let mut visibility = vec![0.0f32; n];
    let mut silhouette_edges = 0u64;
    for sub in &sub_lights {
        let centre = sub.center();
        let silhouette = adjacency.silhouette_from(centre);
        silhouette_edges += silhouette.edges.len() as u64;
        let loops = if opts.overlap_approximation {
            silhouette_loops(&silhouette.edges)
        } else {
            vec![silhouette.edges.clone()]
        };
        let eye = eye_count(&occluders, centre, setup.rays.eye);
        if loops.len() > 1 && eye != 0 {
            warnings.push(format!(
                "the eye is inside {eye} shadow volume(s); per-loop V-buffers of the overlap \
                 approximation start at 0"
            ));
        }
        let mut covered = vec![0.0f32; n];
        for (k, edges) in loops.iter().enumerate() {
            let eye = if loops.len() > 1 { 0 } else { eye };
            let v = render_loop(&setup, sub, edges, eye, &mut phases);
            for i in 0..n {
                let c = (1.0 - v[i]).clamp(0.0, 1.0);
                covered[i] = if k == 0 {
                    c
                } else {
                    overlap_coverage(covered[i], c)
                };
            }
        }
        for i in 0..n {
            visibility[i] += (1.0 - covered[i]) / sub_lights.len() as f32;
        }
    }
    for (i, v) in visibility.iter_mut().enumerate() {
        *v = if setup.rays.is_hit(i) {
            v.clamp(0.0, 1.0)
        } else {
            1.0
        };
    }
    let mut counters = Counters::default();
    for p in &phases {
        counters.merge(&p.counters);
    }
    counters.set("silhouette_edges", silhouette_edges as f64);
    let fill = counters.get("fill").unwrap_or(0.0);
    counters.set(
        "overdraw_ratio",
        if fill > 0.0 {
            counters.get("overdraw").unwrap_or(0.0) / fill
        } else {
            0.0
        },
    );
    let mut execution = std::collections::BTreeMap::new();
    execution.insert("options".to_string(), serde_json::json!(opts));
    if let Some(t) = &setup.texture {
        execution.insert(
            "coverage_texture_bytes".into(),
            serde_json::json!(t.bytes()),
        );
    }
    Ok(FrameOutput {
        visibility: VisibilityBuffer {
            width: frame.width(),
            height: frame.height(),
            data: visibility,
        },
        counters,
        phases,
        model_ms: None,
        gpu_ms: None,
        execution,
        warnings,
    })
}

/// Renders one silhouette loop (or the whole silhouette) for one (sub-)light: returns its
/// V-buffer, 1 − (hard count) ± wedge coverage, and adds to the phases' times and counters.
fn render_loop(
    s: &Setup,
    light: &Light,
    edges: &[SilhouetteEdge],
    eye: i32,
    phases: &mut [Phase],
) -> Vec<f32> {
    let centre = light.center();
    let rays = &s.rays;

    // Pass 1: hard shadow quads (III §3.2.1).
    let start = Instant::now();
    let quads: Vec<ShadowQuad> = edges.iter().map(|e| ShadowQuad::new(e, centre)).collect();
    let hard = render_quads(rays, &quads, eye, s.tile);
    let c = &mut phases[0].counters;
    c.add("fill", hard.fill as f64);
    c.add("overdraw", (hard.fill - hard.passed) as f64);
    mem_read(c, "depth", hard.fill * DEPTH_BYTES);
    let (buffer, bytes) = match s.opts.vbuffer {
        VBufferPrecision::F32 => ("vbuffer", VBUFFER_F32_BYTES),
        VBufferPrecision::Split12 => ("stencil", STENCIL_BYTES),
    };
    mem_read(c, buffer, hard.passed * bytes);
    mem_write(c, buffer, hard.passed * bytes);
    phases[0].wall_ms += start.elapsed().as_secs_f64() * 1e3;

    // Wedge construction (III §3.1, IV §4.1).
    let start = Instant::now();
    let reach = 4.0 * rays.bounds.diagonal();
    let wedges: Vec<Option<Wedge>> = edges
        .iter()
        .map(|e| match (light, s.opts.tighter_wedges) {
            (Light::Rect { half_u, half_v, .. }, true) => Wedge::tight_rect(
                e.a,
                e.b,
                [
                    centre - *half_u - *half_v,
                    centre + *half_u - *half_v,
                    centre + *half_u + *half_v,
                    centre - *half_u + *half_v,
                ],
                reach,
            ),
            _ => Wedge::robust(e.a, e.b, centre, bounding_radius(light), reach),
        })
        .collect();
    let degenerate = wedges.iter().filter(|w| w.is_none()).count();
    let c = &mut phases[1].counters;
    c.add("wedges", (wedges.len() - degenerate) as f64);
    c.add("wedges_degenerate", degenerate as f64);
    phases[1].wall_ms += start.elapsed().as_secs_f64() * 1e3;

    // Pass 2: penumbra wedges (III §3.2.2), by wedge halves when culling (IV §4.4).
    let start = Instant::now();
    let (accum, tally) = soft_pass(s, light, &quads, &wedges);
    let c = &mut phases[2].counters;
    c.add("fill", tally.fill as f64);
    c.add("overdraw", (tally.fill - tally.contributing) as f64);
    c.add("shader_invocations", tally.shaded as f64);
    c.add("culled_fragments", tally.culled as f64);
    c.add("fragments_inside_wedges", tally.inside as f64);
    mem_read(c, "depth", tally.depth_reads * DEPTH_BYTES);
    mem_read(c, "stencil", tally.stencil_reads * STENCIL_BYTES);
    mem_write(c, "stencil", tally.stencil_writes * STENCIL_BYTES);
    let vbytes = match s.opts.vbuffer {
        VBufferPrecision::F32 => VBUFFER_F32_BYTES,
        VBufferPrecision::Split12 => VBUFFER_RGBA8_BYTES,
    };
    mem_read(c, "vbuffer", tally.inside * vbytes);
    mem_write(c, "vbuffer", tally.inside * vbytes);
    mem_read(c, "coverage_texture", tally.texture_reads);
    let v = (0..rays.len())
        .map(|i| 1.0 - hard.count[i] as f32 + accum.value(i))
        .collect();
    phases[2].wall_ms += start.elapsed().as_secs_f64() * 1e3;
    v
}

/// Radius of the sphere around the light that the robust wedges are built from.
fn bounding_radius(light: &Light) -> f32 {
    match *light {
        Light::Sphere { radius, .. } | Light::Disc { radius, .. } => radius,
        Light::Rect { half_u, half_v, .. } => (half_u + half_v).length(),
    }
}

/// One rasterized primitive of pass 2: a wedge, or one half of it when culling.
struct WedgePrimitive {
    edge: usize,
    volume: ConvexVolume,
    /// The half's side of the hard shadow quad (−1 inner, +1 outer); `None` for a whole wedge.
    half: Option<f32>,
}

/// Coverage of the light seen from `p` by the hard shadow quad of `quad`'s edge, and the side
/// of the quad `p` is on; `None` when the projected edge misses the light.
fn pixel_coverage(
    s: &Setup,
    light: &Light,
    quad: &ShadowQuad,
    p: Vec3,
    tally: &mut SoftTally,
) -> Option<f32> {
    let emitter = Emitter::seen_from(light, p);
    let (q0, q1) = emitter.project_edge(p, quad.a, quad.b)?;
    let (c0, c1) = emitter.shape.clip(q0, q1)?;
    Some(match &s.texture {
        Some(t) => {
            tally.texture_reads += CoverageTexture::READS;
            t.lookup(c0, c1)
        }
        None => exact_coverage(emitter.shape, c0, c1),
    })
}

fn soft_pass(
    s: &Setup,
    light: &Light,
    quads: &[ShadowQuad],
    wedges: &[Option<Wedge>],
) -> (Accum, SoftTally) {
    let rays = &s.rays;
    let mut prims = Vec::new();
    let mut footprints: Vec<Option<ScreenRect>> = Vec::new();
    for (k, w) in wedges.iter().enumerate() {
        let Some(w) = w else { continue };
        let fp = rays.footprint(&w.hull);
        if s.opts.wedge_culling {
            let n = quads[k].normal.normalize_or_zero();
            let d = n.dot(quads[k].light);
            for side in [-1.0f32, 1.0] {
                let mut volume = w.volume.clone();
                volume.planes.push((n * side, d * side));
                prims.push(WedgePrimitive {
                    edge: k,
                    volume,
                    half: Some(-side),
                });
                footprints.push(fp);
            }
        } else {
            prims.push(WedgePrimitive {
                edge: k,
                volume: w.volume.clone(),
                half: None,
            });
            footprints.push(fp);
        }
    }
    struct State {
        rect: ScreenRect,
        accum: Accum,
        tally: SoftTally,
    }
    let tiles = raster_pass(
        rays,
        &footprints,
        s.tile,
        |rect| State {
            rect,
            accum: Accum::new(
                s.opts.vbuffer,
                ((rect.x1 - rect.x0) * (rect.y1 - rect.y0)) as usize,
            ),
            tally: SoftTally::default(),
        },
        |st, k, i| {
            let prim = &prims[k];
            let (b0, b1) = rays.bounds_interval(i);
            let Some((t_in, t_out)) = prim.volume.ray_interval(rays.eye, rays.dir[i], b0, b1)
            else {
                return;
            };
            let t_p = rays.depth[i];
            let t = &mut st.tally;
            let quad = &quads[prim.edge];
            let side = match prim.half {
                // IV §4.4: front faces with GL_GREATER set the stencil, back faces with GL_LESS
                // and the stencil test run the shader; both passes rasterize the half.
                Some(half) => {
                    t.fill += 2;
                    t.depth_reads += 2;
                    t.stencil_reads += 1;
                    if t_in >= t_p {
                        t.culled += 1;
                        return;
                    }
                    t.stencil_writes += 1;
                    if t_p >= t_out {
                        t.stencil_writes += 1;
                        t.culled += 1;
                        return;
                    }
                    // The back pass resets the stencil it consumed.
                    t.stencil_writes += 1;
                    t.shaded += 1;
                    half
                }
                // III §3.2.2: the front faces run the shader, which tests "p inside the wedge".
                None => {
                    t.fill += 1;
                    t.depth_reads += 1;
                    if t_in >= t_p {
                        return;
                    }
                    t.shaded += 1;
                    if t_p >= t_out {
                        return;
                    }
                    quad.side(rays.point[i])
                }
            };
            let p = rays.point[i];
            let Some(coverage) = pixel_coverage(s, light, quad, p, t) else {
                return;
            };
            t.inside += 1;
            if coverage > 0.0 {
                t.contributing += 1;
            }
            let (x, y) = (i as u32 % rays.width, i as u32 / rays.width);
            let j = ((y - st.rect.y0) * (st.rect.x1 - st.rect.x0) + x - st.rect.x0) as usize;
            st.accum.add(j, side, coverage);
        },
    );
    let mut accum = Accum::new(s.opts.vbuffer, rays.len());
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
