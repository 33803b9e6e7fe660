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

use super::FrameOutput;
use crate::algorithms::{no_options, work, Algorithm, Backend, CpuEntry, WorkEstimate};
use crate::error::InputError;
use crate::frame::Frame;
use crate::frame::RunParams;
use crate::record::{Counters, Phase};
use crate::scene::bvh::SceneBvh;
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

/// Whether light sample `q` is visible from shading point `(p, horizon)`: in front of the
/// receiver-only surface's plane, and no occluder on the way.
fn sees(bvh: &SceneBvh, (p, horizon): ShadingPoint, q: Vec3) -> bool {
    horizon.is_none_or(|n| n.dot(q - p) > 0.0) && !bvh.occluded(p, q)
}

/// The shading point of pixel `i` of `frame` ([`ShadingPoint`]).
fn shading_point(frame: &Frame, i: usize) -> ShadingPoint {
    let g = &frame.gbuffer;
    let receiver_only = !frame.flat.role_of(g.triangle[i] as usize).occluder;
    (g.shading_point(i), receiver_only.then_some(g.normal[i]))
}

/// Fraction of `light` visible from shading point `p`, from k×k stratified samples of stream
/// `seed`.
pub fn visible_fraction(bvh: &SceneBvh, light: &Light, p: ShadingPoint, k: u32, seed: u64) -> f32 {
    let visible = light
        .stratified_samples(p.0, k, seed)
        .filter(|&q| sees(bvh, p, q))
        .count();
    visible as f32 / (k * k) as f32
}

/// Light received from a textured `light` at shading point `p`, from k×k stratified samples of
/// stream `seed`, each weighted by the texture's colour where it lies on the light:
/// per channel the visible samples' mean colour over all samples, and the luminance fraction
/// of the visible samples over all of them ([`LightTexture::visibility`]'s quantity).
pub fn received_light(
    bvh: &SceneBvh,
    light: &Light,
    texture: &LightTexture,
    p: ShadingPoint,
    k: u32,
    seed: u64,
) -> ([f32; 3], f32) {
    let n = k * k;
    let (mut visible, mut all) = ([0.0f64; 3], [0.0f64; 3]);
    for (i, q) in (0..n).zip(light.stratified_samples(p.0, k, seed)) {
        let c = texture.at(light.stratified_coords(i, k, seed));
        let lit = sees(bvh, p, q);
        for ch in 0..3 {
            all[ch] += f64::from(c[ch]);
            if lit {
                visible[ch] += f64::from(c[ch]);
            }
        }
    }
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
    let start = Instant::now();
    let k = strata_side(samples).expect("sample count validated as a perfect square");
    let g = &frame.gbuffer;
    let light = frame.scene.light;
    let texture = frame.scene.light_texture.as_deref();
    // What an unoccluded point receives: once per frame (a pass over every texel).
    let unoccluded = texture.map_or([1.0; 3], LightTexture::mean);
    let pixels: Vec<(f32, [f32; 3])> = (0..g.len())
        .into_par_iter()
        .map(|i| {
            deadline.check();
            if !g.is_hit(i) {
                return (1.0, unoccluded);
            }
            let p = shading_point(frame, i);
            let stream = mix64(seed ^ i as u64);
            match texture {
                Some(t) => {
                    let (rgb, v) = received_light(&frame.bvh, &light, t, p, k, stream);
                    (v, rgb)
                }
                None => {
                    let v = visible_fraction(&frame.bvh, &light, p, k, stream);
                    (v, [v; 3])
                }
            }
        })
        .collect();
    let data = pixels.iter().map(|p| p.0).collect();
    let rgb = texture.map(|_| RgbBuffer {
        width: g.width,
        height: g.height,
        data: pixels.iter().map(|p| p.1).collect(),
    });
    let hits = g.triangle.iter().filter(|&&t| t != u32::MAX).count() as f64;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut counters = Counters::default();
    counters.set("shadow_rays", hits * (k * k) as f64);
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

impl Algorithm for Reference {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "ground truth";
    const SUMMARY: &'static str =
        "visible fraction of the light by stratified sampling and BVH ray casting";
    const BACKENDS: &'static [Backend] = &[Backend::CpuNative];
    type Options = ();
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = |_| 0;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work::reference;
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
