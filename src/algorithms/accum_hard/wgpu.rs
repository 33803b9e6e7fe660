//! `accum_hard` on wgpu: per light sample the hard pass of `soft_shadow_volume`'s wgpu execution
//! (shadow quads, or for z-fail the capped volumes' faces, built on the host from the sample's
//! silhouette and binned to 8×8 screen tiles; one invocation per pixel counts its tile's
//! primitives), then an `accumulate` pass adding the pixels with count 0 to a per-pixel sum on
//! the GPU; the last sample's accumulation writes the average. Phases `hard` and `accumulate`
//! as on the cpu executions.
//!
//! The count is an i32 and the sum an f32 per pixel (exact integers up to 2^24), where the
//! paper's accumulation uses an 8-bit stencil and a 16-bit accumulation buffer. The memory
//! traffic counters (`mem.*`) are in the cpu-model's terms of that stencil and accumulation
//! buffer (`accum_hard::cpu`): the stencil cleared per sample, a depth read per fragment, a
//! stencil read and write per fragment that passes, and per sample the stencil read and the
//! accumulation buffer read and written for every pixel; fill and passed fragments come from an
//! instrumented replay of every sample's hard pass (WGSL atomics). Not built on the GPU:
//! silhouette detection, quad and cap construction, binning (host, as on the cpu executions).

use std::time::Instant;

use super::AccumHardOptions;
use crate::algorithms::eye_raster::{EyeRays, DEPTH_BYTES};
use crate::algorithms::shadow_volume::{eye_count, Counting, ShadowQuad};
use crate::algorithms::soft_shadow_volume::wgpu::{check_limits, HardSamples};
use crate::algorithms::{ExecContext, FrameOutput};
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::readback::{words, Staging};
use crate::gpu::stats::{read_or_warn, PassStats, COMPUTE_INVOCATIONS};
use crate::gpu::timing::{read_ms_or_warn, PassTimer};
use crate::gpu::{resolve_queries, Gpu};
use crate::record::{Counters, Phase};
use crate::scene::adjacency::EdgeAdjacency;
use crate::visibility::VisibilityBuffer;

/// Bytes of a stencil value and of an accumulation-buffer value, as `accum_hard::cpu` counts.
const STENCIL_BYTES: f64 = 1.0;
const ACCUMULATION_BYTES: f64 = 2.0;

/// `accum_hard` on wgpu.
pub fn render(
    gpu: &Gpu,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &AccumHardOptions,
) -> Result<FrameOutput> {
    let k = opts.strata_side()?;
    let n = k * k;
    check_limits(gpu, frame)?;
    let start = Instant::now();
    let rays = EyeRays::new(frame);
    let occluders = frame.scene.occluders();
    let adjacency = EdgeAdjacency::build(&occluders);
    let light = frame.scene.light;
    let target = frame.scene.bounds().center();
    let samples = HardSamples::new(gpu, &rays, opts.counting, occluders.clone(), n);
    let mut wall = [start.elapsed().as_secs_f64() * 1e3, 0.0];
    let timer = PassTimer::new(gpu, 2 * n);
    let stats = PassStats::new(gpu, 2 * n);
    let staging = Staging::new(gpu, "visibility readback", samples.visibility().size());
    let mut uploads = Vec::with_capacity(n as usize);
    let mut silhouette_edges = 0u64;
    for s in 0..n {
        let start = Instant::now();
        let sample = light.stratified_sample(target, s, k, ctx.seed);
        let quads: Vec<ShadowQuad> = adjacency
            .silhouette_from(sample)
            .edges
            .iter()
            .map(|e| ShadowQuad::new(e, sample))
            .collect();
        silhouette_edges += quads.len() as u64;
        let eye = match opts.counting {
            Counting::ZPass => eye_count(&occluders, sample, rays.eye),
            Counting::ZFail => 0,
        };
        let up = samples.upload(&rays, s, sample, &quads, eye);
        let q = Some((timer.as_ref(), stats.as_ref(), 2 * s));
        gpu.submit(|e| samples.hard(e, &up, q))?;
        wall[0] += start.elapsed().as_secs_f64() * 1e3;
        let last = s + 1 == n;
        let q = Some((timer.as_ref(), stats.as_ref(), 2 * s + 1));
        wall[1] += gpu.submit(|e| {
            samples.accumulate(e, &up, q);
            if last {
                staging.copy(e, samples.visibility());
                resolve_queries(e, timer.as_ref(), stats.as_ref());
            }
        })?;
        uploads.push(up);
    }
    let readback_start = Instant::now();
    let data: Vec<f32> = words(&staging.read(gpu)?);
    let readback_ms = readback_start.elapsed().as_secs_f64() * 1e3;
    let mut warnings = Vec::new();
    let times = read_ms_or_warn(gpu, &timer, &mut warnings)?;
    let gpu_ms = times.ms.clone();
    let pipeline = read_or_warn(gpu, &stats, &mut warnings)?;
    let tally = samples.replay(&uploads)?;

    let pixels = rays.len() as f64;
    let samples_f = f64::from(n);
    let mut hard = Counters::default();
    hard.add("silhouette_edges", silhouette_edges as f64);
    if opts.counting == Counting::ZFail {
        hard.add(
            "volume_caps",
            uploads.iter().map(|u| u.caps).sum::<u64>() as f64,
        );
    }
    hard.add(
        "shadow_quads",
        uploads.iter().map(|u| u.quads).sum::<u64>() as f64,
    );
    hard.add("quad_tests", tally.tests);
    hard.add("fill", tally.fill);
    hard.add("overdraw", tally.fill - tally.passed);
    let depth_r = tally.fill * DEPTH_BYTES as f64;
    let stencil_w = (samples_f * pixels + tally.passed) * STENCIL_BYTES;
    let stencil_r = tally.passed * STENCIL_BYTES;
    hard.add("mem_est.depth.read_bytes", depth_r);
    hard.add("mem_est.stencil.read_bytes", stencil_r);
    hard.add("mem_est.stencil.write_bytes", stencil_w);
    hard.add("mem_est.read_bytes", depth_r + stencil_r);
    hard.add("mem_est.write_bytes", stencil_w);
    let mut acc = Counters::default();
    let stencil_r = samples_f * pixels * STENCIL_BYTES;
    let accumulation = samples_f * pixels * ACCUMULATION_BYTES;
    acc.add("mem_est.stencil.read_bytes", stencil_r);
    acc.add("mem_est.accumulation.read_bytes", accumulation);
    acc.add("mem_est.accumulation.write_bytes", accumulation);
    acc.add("mem_est.read_bytes", stencil_r + accumulation);
    acc.add("mem_est.write_bytes", accumulation);
    if let Some(p) = &pipeline {
        for (j, st) in p.iter().enumerate() {
            if let Some(v) = st.get(COMPUTE_INVOCATIONS) {
                let c = if j % 2 == 0 { &mut hard } else { &mut acc };
                c.add(COMPUTE_INVOCATIONS, v);
            }
        }
    }
    let gpu_phase_ms = |phase: usize| {
        gpu_ms
            .as_ref()
            .map(|t| t.iter().skip(phase).step_by(2).sum::<f64>())
    };
    let mut counters = Counters::default();
    let mut phases = Vec::with_capacity(2);
    for (i, (name, c)) in [("hard", hard), ("accumulate", acc)]
        .into_iter()
        .enumerate()
    {
        counters.merge(&c);
        phases.push(Phase {
            name: name.into(),
            wall_ms: wall[i],
            model_ms: None,
            gpu_ms: gpu_phase_ms(i),
            counters: c,
        });
    }
    let mut execution = gpu.execution();
    times.record(&mut execution);
    execution.insert("readback_ms".into(), serde_json::json!(readback_ms));
    execution.insert("samples".into(), serde_json::json!(n));
    execution.insert("counting".into(), serde_json::json!(opts.counting));
    execution.insert(
        "gpu_counters".into(),
        serde_json::json!(
            "fill and overdraw from an instrumented replay of every sample's hard pass (WGSL \
             atomics); mem.* in the cpu-model's terms of an 8-bit stencil and a 16-bit \
             accumulation buffer"
        ),
    );
    Ok(FrameOutput {
        visibility: VisibilityBuffer {
            width: rays.width,
            height: rays.height,
            data,
        },
        counters,
        phases,
        model_ms: None,
        gpu_ms: gpu_ms.map(|t| t.iter().sum()),
        execution,
        warnings,
        rgb: None,
    })
}
