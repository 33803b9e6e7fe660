//! Ground truth: the fraction of the light visible from each eye pixel's surface point, by
//! stratified sampling of the light and ray casting against a BVH.
//!
//! The light is divided into k×k strata (N = k² samples, 256 by default, 1024 for paper runs),
//! each sampled once at a jittered position; a shadow ray from the surface point (moved off the
//! surface robustly along the eye-facing normal, `GBuffer::shading_point`) to the sample either
//! reaches it or not; only occluders block it (a receiver-only object casts no shadow, not even
//! on itself, `SceneBvh::occluded`, but its surface hides the part of the light behind its own
//! plane: [`ShadingPoint`]). Jitter is a pure function of (seed, pixel, sample), so the image is
//! identical for any host thread count.
//!
//! A textured light ([`crate::scene::light_texture`]) weights each sample by the texture's
//! colour at its place on the light; the output then also holds the light received per channel.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::algorithms::algorithm::FrameOutput;
use crate::algorithms::algorithm::{
    no_options, Algorithm, Backend, CpuEntry, ExecContext, WorkEstimate,
};
use crate::algorithms::work;
use crate::counters::names;
use crate::error::InputError;
use crate::frame::Frame;
use crate::frame::RunParams;
use crate::record::{Counters, Phase};
use crate::scene::bvh::SceneBvh;
use crate::scene::shadow_bvh::{Facing, Gathered, Isa, PacketStack, ShadowBvh, ShadowRay, PACKET};
use crate::scene::{Light, LightTexture};
use crate::util::deadline::Deadline;
use crate::util::hash::mix64;
use crate::visibility::{RgbBuffer, VisibilityBuffer};
use std::collections::BTreeMap;

pub const ID: &str = "reference";

pub const DEFAULT_SAMPLES: u32 = 256;
pub const PAPER_SAMPLES: u32 = 1024;

/// The side k of the k×k stratification for `samples`, if `samples` is a perfect square.
pub fn strata_side(samples: u32) -> Option<u32> {
    let k = (samples as f64).sqrt().round() as u32;
    (k >= 1 && k * k == samples).then_some(k)
}

/// A shading point (moved off its surface) and, on a receiver-only surface, the normal of the
/// side it is seen from: such a surface casts no shadow, its own triangles let shadow rays
/// through, but it still hides the light behind its own plane (an occluder's surface does that
/// with its own triangles).
pub type ShadingPoint = (Vec3, Option<Vec3>);

/// Whether light sample `q` is in front of the receiver-only surface's plane of `(p, horizon)`
/// (always, on an occluder's surface).
fn in_front((p, horizon): ShadingPoint, q: Vec3) -> bool {
    horizon.is_none_or(|n| n.dot(q - p) > 0.0)
}

/// Whether every point within `radius` of `centre` is in front of the plane through `p` with
/// unit normal `n`, as [`in_front`] evaluates it in `f32` (with margins over its rounding and
/// that of the samples).
fn clears(n: Vec3, p: Vec3, centre: Vec3, radius: f32) -> bool {
    let magnitude = centre.abs().max_element() + p.abs().max_element() + radius;
    let margin = 1e-3 * radius + 1e-5 * (magnitude + (centre - p).length());
    n.dot(centre - p) > radius + margin
}

/// How the reference traces its shadow rays. Every choice gives the same answers (the tests
/// check it on every built-in scene); they differ in speed (docs/algorithms.md, "The
/// reference's speed", measured by `scripts/embree-compare.py`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tracer {
    /// One ray at a time through the scene's BVH of every triangle with obvhs's traversal,
    /// receiver-only triangles rejected in the leaf test ([`SceneBvh::occluded_in_scene_bvh`]):
    /// the method before the casters' BVH, the baseline of the measurements.
    SceneBvh,
    /// One ray at a time through the casters' BVH with obvhs's traversal
    /// ([`occluded_obvhs`](crate::scene::shadow_bvh::ShadowBvh::occluded_obvhs)): the casters'
    /// tree alone, measured against [`Tracer::SceneBvh`].
    CastersObvhs,
    /// One ray at a time through the casters' BVH
    /// ([`occluded_ray`](crate::scene::shadow_bvh::ShadowBvh::occluded_ray)) on `Isa`.
    Rays(Isa),
    /// Each pixel's rays as a group on `Isa`: the casters in the cone from the shading point
    /// around the light gathered once ([`gather`](crate::scene::shadow_bvh::ShadowBvh::gather), at most [`GROUP_CAP`]), each ray
    /// testing only those, none traced where there are none; more than the cap, one ray at a
    /// time as [`Tracer::Rays`], each first testing the caster that blocked the pixel's
    /// previous ray.
    Groups(Isa),
    /// [`Tracer::Groups`], with a group of more casters than the cap traced as packets of up to
    /// [`PACKET`] rays ([`occluded_packet`](crate::scene::shadow_bvh::ShadowBvh::occluded_packet))
    /// instead of one ray at a time.
    Packets(Isa),
}

impl Default for Tracer {
    /// [`Tracer::Packets`] on the host's widest instruction set ([`Isa::host`]).
    fn default() -> Tracer {
        Tracer::Packets(Isa::host())
    }
}

impl Tracer {
    pub fn name(self) -> String {
        match self {
            Tracer::SceneBvh => "scene-bvh".into(),
            Tracer::CastersObvhs => "casters-obvhs".into(),
            Tracer::Rays(isa) => format!("rays-{}", isa.name()),
            Tracer::Groups(isa) => format!("groups-{}", isa.name()),
            Tracer::Packets(isa) => format!("packets-{}", isa.name()),
        }
    }
}

/// What a worker's tracing reuses from pixel to pixel: a group's candidate casters (and as seen
/// from its shading point), the pixel's light samples, a packet's rays and its traversal stack.
#[derive(Default)]
pub struct Scratch {
    candidates: Vec<u32>,
    facing: Vec<Facing>,
    points: Vec<Vec3>,
    rays: Vec<ShadowRay>,
    stack: PacketStack,
}

/// A light sample's answer before its packet is traced: behind a receiver-only surface (dark),
/// a ray without length (lit), or ray `r` of the packet.
#[derive(Clone, Copy)]
enum Pending {
    Dark,
    Lit,
    Ray(u8),
}

/// The most casters a group gathers before it is traced one ray at a time: each of its rays
/// tests every candidate, which beats a traversal only while they are few.
pub const GROUP_CAP: usize = 8;

/// Side of the square tiles of pixels whose shading points [`Tracer::Groups`] tests together
/// first: a tile whose cone to the light holds no caster answers every pixel of it without the
/// pixel's own cone traversal.
const TILE: usize = 4;

/// Whether no caster lies between the shading points of `tile` and the light: the cone tangent
/// to a ball around the points and to the light's bounding sphere is empty.
fn tile_is_clear(
    frame: &Frame,
    isa: Isa,
    tile: &[(usize, ShadingPoint)],
    scratch: &mut Scratch,
) -> bool {
    if tile.len() < 2 {
        return false;
    }
    let centre = tile.iter().map(|t| t.1 .0).sum::<Vec3>() / tile.len() as f32;
    let radius = tile
        .iter()
        .map(|t| t.1 .0.distance(centre))
        .fold(0.0, f32::max);
    let light = &frame.scene.light;
    let ball = (light.center(), light.bounding_radius());
    frame
        .bvh
        .shadow()
        .gather_between(isa, (centre, radius), ball, 0, &mut scratch.candidates)
        == Gathered::Empty
}

/// What a pixel's shadow rays are traced against and how; `clear`: its tile's cone holds no
/// caster ([`tile_is_clear`]).
#[derive(Clone, Copy)]
struct Traced<'a> {
    bvh: &'a SceneBvh,
    light: &'a Light,
    tracer: Tracer,
    clear: bool,
}

/// Calls `lit(i, visible)` for each light sample `i` of the k×k stratified samples of stream
/// `seed` seen from `p`, in order: whether the sample is in front of a receiver-only surface's
/// plane and no occluder blocks the shadow ray to it.
fn trace_samples(
    Traced {
        bvh,
        light,
        tracer,
        clear,
    }: Traced,
    p: ShadingPoint,
    k: u32,
    seed: u64,
    scratch: &mut Scratch,
    mut lit: impl FnMut(u32, bool),
) {
    let shadow = bvh.shadow();
    let Scratch {
        candidates,
        facing,
        points,
        rays,
        stack,
    } = scratch;
    // The k×k samples, computed in one loop before any is traced.
    macro_rules! samples {
        () => {{
            light.stratified_samples_into(p.0, k, seed, points);
            &points[..]
        }};
    }
    // `cache`: each ray first tests the caster that blocked the pixel's previous ray.
    let one_at_a_time = |isa: Isa, cache: bool, points: &[Vec3], lit: &mut dyn FnMut(u32, bool)| {
        let mut hint = None;
        for (i, &q) in (0..).zip(points) {
            if !cache {
                hint = None;
            }
            let seen = in_front(p, q)
                && !shadow
                    .ray(p.0, q)
                    .is_some_and(|r| shadow.occluded_ray(isa, &r, &mut hint));
            lit(i, seen);
        }
    };
    match tracer {
        Tracer::SceneBvh => {
            for (i, &q) in (0..).zip(samples!()) {
                lit(i, in_front(p, q) && !bvh.occluded_in_scene_bvh(p.0, q));
            }
        }
        Tracer::CastersObvhs => {
            for (i, &q) in (0..).zip(samples!()) {
                let seen = in_front(p, q)
                    && !shadow
                        .ray(p.0, q)
                        .is_some_and(|r| shadow.occluded_obvhs(&r));
                lit(i, seen);
            }
        }
        Tracer::Rays(isa) => one_at_a_time(isa, false, samples!(), &mut lit),
        Tracer::Groups(isa) | Tracer::Packets(isa) => {
            let (centre, radius) = (light.center(), light.bounding_radius());
            let gathered = if clear {
                Gathered::Empty
            } else {
                shadow.gather(isa, p.0, centre, radius, GROUP_CAP, candidates)
            };
            match gathered {
                Gathered::Empty if p.1.is_none_or(|n| clears(n, p.0, centre, radius)) => {
                    (0..k * k).for_each(|i| lit(i, true));
                }
                Gathered::Empty => {
                    for (i, &q) in (0..).zip(samples!()) {
                        lit(i, in_front(p, q));
                    }
                }
                Gathered::Few => {
                    shadow.facing_among(candidates, p.0, facing);
                    for (i, &q) in (0..).zip(samples!()) {
                        let seen = in_front(p, q)
                            && !shadow
                                .segment(p.0, q)
                                .is_some_and(|s| ShadowBvh::occluded_among(facing, &s));
                        lit(i, seen);
                    }
                }
                Gathered::Many if matches!(tracer, Tracer::Packets(_)) => {
                    for (first, packet) in (0..).step_by(PACKET).zip(samples!().chunks(PACKET)) {
                        rays.clear();
                        let mut pending = [Pending::Dark; PACKET];
                        for (answer, &q) in pending.iter_mut().zip(packet) {
                            *answer = if !in_front(p, q) {
                                Pending::Dark
                            } else if let Some(r) = shadow.ray(p.0, q) {
                                rays.push(r);
                                Pending::Ray((rays.len() - 1) as u8)
                            } else {
                                Pending::Lit
                            };
                        }
                        let blocked = shadow.occluded_packet(isa, rays, stack);
                        for (i, answer) in (first..).zip(&pending[..packet.len()]) {
                            lit(
                                i,
                                match *answer {
                                    Pending::Dark => false,
                                    Pending::Lit => true,
                                    Pending::Ray(r) => blocked >> r & 1 == 0,
                                },
                            );
                        }
                    }
                }
                Gathered::Many => one_at_a_time(isa, true, samples!(), &mut lit),
            }
        }
    }
}

/// The reference's shadow rays of `frame` with `samples` (a perfect square, k×k) per pixel and
/// `seed`, in the order it traces them: for each pixel that sees a surface, `(pixel, from, to)`
/// (world coordinates) for each light sample in front of its surface (a sample behind it is
/// dark without a ray). `None` when `samples` is not a perfect square.
pub fn shadow_rays(frame: &Frame, samples: u32, seed: u64) -> Option<Vec<(u32, Vec3, Vec3)>> {
    let k = strata_side(samples)?;
    let g = &frame.gbuffer;
    let light = frame.scene.light;
    let (mut rays, mut points) = (Vec::new(), Vec::new());
    for i in (0..g.len()).filter(|&i| g.is_hit(i)) {
        let p = shading_point(frame, i);
        let stream = mix64(seed ^ i as u64);
        light.stratified_samples_into(p.0, k, stream, &mut points);
        for &q in &points {
            if in_front(p, q) {
                rays.push((i as u32, p.0, q));
            }
        }
    }
    Some(rays)
}

/// The shading point of pixel `i` of `frame` ([`ShadingPoint`]).
fn shading_point(frame: &Frame, i: usize) -> ShadingPoint {
    let g = &frame.gbuffer;
    let receiver_only = !frame.flat.role_of(g.triangle[i] as usize).occluder;
    (g.shading_point(i), receiver_only.then_some(g.normal[i]))
}

/// Fraction of `light` visible from shading point `p`, from k×k stratified samples of stream
/// `seed` (the default [`Tracer`]).
pub fn visible_fraction(bvh: &SceneBvh, light: &Light, p: ShadingPoint, k: u32, seed: u64) -> f32 {
    let traced = Traced {
        bvh,
        light,
        tracer: Tracer::default(),
        clear: false,
    };
    visible_fraction_with(traced, p, k, seed, &mut Scratch::default())
}

fn visible_fraction_with(
    traced: Traced,
    p: ShadingPoint,
    k: u32,
    seed: u64,
    scratch: &mut Scratch,
) -> f32 {
    let mut visible = 0u32;
    trace_samples(traced, p, k, seed, scratch, |_, lit| {
        visible += u32::from(lit)
    });
    visible as f32 / (k * k) as f32
}

/// Light received from a textured light at shading point `p`, from k×k stratified samples of
/// stream `seed`, each weighted by the texture's colour where it lies on the light:
/// per channel the visible samples' mean colour over all samples, and the luminance fraction
/// of the visible samples over all of them ([`LightTexture::visibility`]'s quantity).
fn received_light(
    traced: Traced,
    texture: &LightTexture,
    p: ShadingPoint,
    k: u32,
    seed: u64,
    scratch: &mut Scratch,
) -> ([f32; 3], f32) {
    let n = k * k;
    let light = traced.light;
    let (mut visible, mut all) = ([0.0f64; 3], [0.0f64; 3]);
    trace_samples(traced, p, k, seed, scratch, |i, lit| {
        let c = texture.at(light.stratified_coords(i, k, seed));
        for ch in 0..3 {
            all[ch] += f64::from(c[ch]);
            if lit {
                visible[ch] += f64::from(c[ch]);
            }
        }
    });
    let rgb = visible.map(|v| (v / f64::from(n)) as f32);
    let lum = |c: [f64; 3]| LightTexture::luminance(c.map(|v| v as f32));
    let fraction = if lum(all) > 0.0 {
        (lum(visible) / lum(all)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    (rgb, fraction)
}

pub fn render(frame: &Frame, samples: u32, seed: u64) -> FrameOutput {
    render_until(frame, samples, seed, Deadline::default())
}

/// [`render`] stopping at `deadline` (checked before each pixel).
pub fn render_until(frame: &Frame, samples: u32, seed: u64, deadline: Deadline) -> FrameOutput {
    render_with(frame, samples, seed, deadline, Tracer::default())
}

/// [`render_until`] tracing with `tracer` (the same image for every one).
pub fn render_with(
    frame: &Frame,
    samples: u32,
    seed: u64,
    deadline: Deadline,
    tracer: Tracer,
) -> FrameOutput {
    let start = Instant::now();
    let k = strata_side(samples).expect("sample count validated as a perfect square");
    let g = &frame.gbuffer;
    let light = frame.scene.light;
    let texture = frame.scene.light_texture.as_deref();
    // What an unoccluded point receives: once per frame (a pass over every texel).
    let unoccluded = texture.map_or([1.0; 3], LightTexture::mean);
    let w = g.width as usize;
    let mut pixels = vec![(1.0f32, unoccluded); g.len()];
    // Bands of TILE rows in parallel, each in TILE × TILE tiles.
    pixels
        .par_chunks_mut((w * TILE).max(1))
        .enumerate()
        .for_each_init(Scratch::default, |scratch, (band, rows)| {
            let first = band * w * TILE;
            let height = rows.len() / w.max(1);
            for x0 in (0..w).step_by(TILE) {
                let mut tile = [(0usize, (Vec3::ZERO, None)); TILE * TILE];
                let mut n = 0;
                for y in 0..height {
                    for x in x0..(x0 + TILE).min(w) {
                        let i = first + y * w + x;
                        if g.is_hit(i) {
                            tile[n] = (i, shading_point(frame, i));
                            n += 1;
                        }
                    }
                }
                let clear = match tracer {
                    Tracer::Groups(isa) | Tracer::Packets(isa) => {
                        tile_is_clear(frame, isa, &tile[..n], scratch)
                    }
                    _ => false,
                };
                for &(i, p) in &tile[..n] {
                    deadline.check();
                    let stream = mix64(seed ^ i as u64);
                    let traced = Traced {
                        bvh: &frame.bvh,
                        light: &light,
                        tracer,
                        clear,
                    };
                    rows[i - first] = match texture {
                        Some(t) => {
                            let (rgb, v) = received_light(traced, t, p, k, stream, scratch);
                            (v, rgb)
                        }
                        None => {
                            let v = visible_fraction_with(traced, p, k, stream, scratch);
                            (v, [v; 3])
                        }
                    };
                }
            }
        });
    let data = pixels.iter().map(|p| p.0).collect();
    let rgb = texture.map(|_| RgbBuffer {
        width: g.width,
        height: g.height,
        data: pixels.iter().map(|p| p.1).collect(),
    });
    let hits = g.triangle.iter().filter(|&&t| t != u32::MAX).count() as f64;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut counters = Counters::default();
    counters.set(names::SHADOW_RAYS, hits * (k * k) as f64);
    FrameOutput {
        visibility: VisibilityBuffer {
            width: g.width,
            height: g.height,
            data,
        },
        phases: vec![Phase {
            name: "trace".into(),
            wall_ms,
            counters: counters.clone(),
            ..Default::default()
        }],
        counters,
        model_ms: None,
        gpu_ms: None,
        execution: [("samples".to_string(), serde_json::json!(k * k))].into(),
        gpu_setup_ms: None,
        warnings: vec![],
        rgb,
    }
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct Reference;

/// The ground truth: one shadow ray per pixel and light sample.
pub fn work_estimate(_: &work::SceneExtent, p: &RunParams, ctx: &ExecContext, _: &()) -> f64 {
    work::pixels(p) * f64::from(ctx.reference_samples)
}

impl Algorithm for Reference {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "ground truth";
    const SUMMARY: &'static str =
        "visible fraction of the light by stratified sampling and BVH ray casting";
    const BACKENDS: &'static [Backend] = &[Backend::CpuNative];
    type Options = ();
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = |_| 0;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    /// The uninstrumented ray caster (the reference has only `cpu-native`).
    const CPU: CpuEntry<()> = |_, frame, ctx, _| {
        Ok(render_until(
            frame,
            ctx.reference_samples,
            ctx.seed,
            ctx.deadline,
        ))
    };

    fn options(options: &BTreeMap<String, serde_json::Value>) -> Result<(), InputError> {
        no_options(Self::ID, options)
    }

    fn light_texture(_: &()) -> Result<(), InputError> {
        Ok(())
    }
}
