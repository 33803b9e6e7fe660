//! `accum_hard` on wgpu, in one of two pipelines (option `gpu_pipeline`, recorded as
//! `execution.gpu_pipeline`); phases `hard` and `accumulate` as on the cpu executions.
//!
//! - `"raster"` (default), as the thesis rendered its reference (III §5.1): the eye's depth
//!   once, then per light sample the sample's shadow quads (or capped volumes) drawn with the
//!   depth test into a count target by additive blending and the lit pixels (count 0) blended
//!   into an accumulation target; the average is resolved after the last sample
//!   ([`crate::algorithms::shadow_volume::raster`], which states how its coverage differs from
//!   the cpu's ray casting). Count and accumulation are R16Float targets (exact integers up to
//!   2048), where the paper uses an 8-bit stencil and a 16-bit accumulation buffer.
//! - `"gather"`: per light sample the hard pass of the shadow-volume family
//!   ([`crate::algorithms::shadow_volume::wgpu`]): shadow quads, or for z-fail the capped
//!   volumes' faces, binned to 8×8 screen tiles on the host, one invocation per pixel counting
//!   its tile's primitives into an i32, then an `accumulate` pass adding the pixels with count
//!   0 to an f32 sum per pixel.
//!
//! The memory traffic counters (`mem_est.*`) are in the cpu-model's terms of that stencil and
//! accumulation buffer (`accum_hard::cpu`): the stencil cleared per sample, a depth read per
//! fragment, a stencil read and write per fragment that passes, and per sample the stencil read
//! and the accumulation buffer read and written for every pixel; fill and passed fragments come
//! from an instrumented replay of every sample's hard pass (WGSL atomics). Not built on the
//! GPU: silhouette detection, quad and cap construction (and the gather's binning): host, as on
//! the cpu executions.

use std::time::Instant;

use glam::Vec3;

use super::{AccumHardOptions, GpuPipeline};
use crate::algorithms::eye_raster::{EyeRays, DEPTH_BYTES};
use crate::algorithms::shadow_volume::raster::{hard_triangles, HardRaster};
use crate::algorithms::shadow_volume::wgpu::{
    check_limits, FrameResources, Params, Stat, VolumePasses, TILE,
};
use crate::algorithms::shadow_volume::{eye_count, Counting, ShadowQuad};
use crate::algorithms::{ExecContext, FrameOutput};
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{Statistics, Timed};
use crate::gpu::Gpu;
use crate::record::Counters;
use crate::scene::adjacency::EdgeAdjacency;

/// Bytes of a stencil value and of an accumulation-buffer value, as `accum_hard::cpu` counts.
const STENCIL_BYTES: f64 = 1.0;
const ACCUMULATION_BYTES: f64 = 2.0;

/// The hard pass's parameters for light sample `s` of `samples` at `light`.
fn sample_params(
    rays: &EyeRays,
    s: u32,
    samples: u32,
    light: Vec3,
    eye_count: i32,
    counting: Counting,
) -> Params {
    Params {
        center: light.extend(0.0).to_array(),
        half_u: [0.0; 4],
        half_v: [0.0; 4],
        eye: rays.eye.extend(0.0).to_array(),
        width: rays.width,
        height: rays.height,
        tiles_x: rays.width.div_ceil(TILE),
        eye_count,
        vbuffer: 0,
        coverage: 0,
        texture_n: 0,
        first_loop: 1,
        last_loop: 1,
        first_light: u32::from(s == 0),
        last_light: u32::from(s + 1 == samples),
        sub_lights: samples,
        counting: u32::from(counting == Counting::ZFail),
        channels: 1,
        pad1: 0,
        pad2: 0,
        mean: [1.0; 4],
    }
}

/// `accum_hard` on wgpu, with the pipeline `opts.gpu_pipeline` names (recorded as
/// `execution.gpu_pipeline`).
pub fn render(
    gpu: &Gpu,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &AccumHardOptions,
) -> Result<FrameOutput> {
    let mut out = match opts.gpu_pipeline {
        GpuPipeline::Raster => raster(gpu, frame, ctx, opts)?,
        GpuPipeline::Gather => gather(gpu, frame, ctx, opts)?,
    };
    out.execution
        .insert("gpu_pipeline".into(), serde_json::json!(opts.gpu_pipeline));
    Ok(out)
}

/// The raster pipeline ([`crate::algorithms::shadow_volume::raster`]): the eye's depth once,
/// then per light sample a count pass of its shadow quads (or capped volumes) and an
/// accumulation pass; the average is resolved after the last. Phase `hard` holds the depth
/// pre-pass, the host geometry and the count passes, `accumulate` the accumulation passes and
/// the resolve.
fn raster(
    gpu: &Gpu,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &AccumHardOptions,
) -> Result<FrameOutput> {
    let k = opts.strata_side()?;
    let n = k * k;
    let start = Instant::now();
    let rays = EyeRays::new(frame);
    let occluders = frame.scene.occluders();
    let passes = HardRaster::new(gpu, &rays, &frame.scene.camera, opts.counting, n);
    // Without the pipelines' creation: the run's GPU setup, reported apart.
    let setup_ms = start.elapsed().as_secs_f64() * 1e3 - gpu.cache.run_objects_ms();
    let names = ["hard", "accumulate"];
    let mut run = Timed::new(
        gpu,
        &names,
        2 * n + 2,
        Statistics::All,
        &[&passes.visibility],
    );
    run.add_wall(0, setup_ms);
    let (vertices, ranges, silhouette_edges, caps) = run.host(0, || {
        let mut vertices = Vec::new();
        let mut ranges = Vec::with_capacity(n as usize);
        let (mut edges, mut caps) = (0u64, 0u64);
        let adjacency = EdgeAdjacency::build(&occluders);
        let target = frame.scene.bounds().center();
        for s in 0..n {
            let sample = frame.scene.light.stratified_sample(target, s, k, ctx.seed);
            let quads: Vec<ShadowQuad> = adjacency
                .silhouette_from(sample)
                .edges
                .iter()
                .map(|e| ShadowQuad::new(e, sample))
                .collect();
            let eye = match opts.counting {
                Counting::ZPass => eye_count(&occluders, sample, rays.eye),
                Counting::ZFail => 0,
            };
            let (v, c) = hard_triangles(&rays, &quads, opts.counting, &occluders, sample);
            let first = vertices.len() as u32;
            vertices.extend(v);
            ranges.push((first..vertices.len() as u32, eye));
            edges += quads.len() as u64;
            caps += c;
        }
        (passes.vertices(&vertices), ranges, edges, caps)
    });
    run.submit(0, &[passes.depth_pass()])?;
    for (s, (range, eye)) in ranges.iter().enumerate() {
        run.submit(
            0,
            &[passes.count_pass(&vertices, range.clone(), *eye, false)],
        )?;
        let mut acc = vec![passes.accumulate_pass(s == 0)];
        if s + 1 == ranges.len() {
            acc.push(passes.resolve_pass());
        }
        run.submit(1, &acc)?;
    }
    let timing = run.finish()?;
    let (fill, passed) = passes.replay(&vertices, &ranges)?;
    let (hard, acc) = counters(
        &rays,
        n,
        silhouette_edges,
        caps,
        opts.counting,
        fill,
        passed,
    );
    let note = "fill and overdraw from an instrumented replay of every sample's count pass \
                (depth test off, WGSL atomics) in the cpu-model's terms; mem_est.* in the \
                cpu-model's terms of an 8-bit stencil and a 16-bit accumulation buffer";
    let mut out = timing.output((rays.width, rays.height), vec![hard, acc], note);
    out.execution.insert("samples".into(), serde_json::json!(n));
    out.execution
        .insert("counting".into(), serde_json::json!(opts.counting));
    Ok(out)
}

/// The counters of the two phases in the cpu-model's terms (`accum_hard::cpu`): silhouette
/// edges and caps, fill and overdraw, and the memory traffic of an 8-bit stencil cleared per
/// sample (a depth read per fragment, a stencil read and write per passing fragment) and of a
/// 16-bit accumulation buffer read and written per pixel and sample.
fn counters(
    rays: &EyeRays,
    n: u32,
    silhouette_edges: u64,
    caps: u64,
    counting: Counting,
    fill: f64,
    passed: f64,
) -> (Counters, Counters) {
    let pixels = rays.len() as f64;
    let samples_f = f64::from(n);
    let mut hard = Counters::default();
    hard.add("silhouette_edges", silhouette_edges as f64);
    if counting == Counting::ZFail {
        hard.add("volume_caps", caps as f64);
    }
    hard.add("fill", fill);
    hard.add("overdraw", fill - passed);
    let depth_r = fill * DEPTH_BYTES as f64;
    let stencil_w = (samples_f * pixels + passed) * STENCIL_BYTES;
    let stencil_r = passed * STENCIL_BYTES;
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
    (hard, acc)
}

/// The compute gather ([`crate::algorithms::shadow_volume::wgpu`]).
fn gather(
    gpu: &Gpu,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &AccumHardOptions,
) -> Result<FrameOutput> {
    let k = opts.strata_side()?;
    let n = k * k;
    check_limits(gpu, frame, super::ID)?;
    let start = Instant::now();
    let rays = EyeRays::new(frame);
    let occluders = frame.scene.occluders();
    let adjacency = EdgeAdjacency::build(&occluders);
    let light = frame.scene.light;
    let target = frame.scene.bounds().center();
    let res = FrameResources::new(gpu, &rays, &[], false);
    let passes = VolumePasses::new(gpu, &rays, opts.counting, res, occluders.clone(), "");
    // Without the pipelines' creation: the run's GPU setup, reported apart.
    let setup_ms = start.elapsed().as_secs_f64() * 1e3 - gpu.cache.run_objects_ms();
    let names = ["hard", "accumulate"];
    let visibility = &passes.res.visibility;
    let mut run = Timed::new(gpu, &names, 2 * n, Statistics::Compute, &[visibility]);
    run.add_wall(0, setup_ms);
    let mut uploads = Vec::with_capacity(n as usize);
    let mut silhouette_edges = 0u64;
    for s in 0..n {
        let up = run.host(0, || {
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
            let params = sample_params(&rays, s, n, sample, eye, opts.counting);
            (
                passes.upload_quads(&rays, &params, sample, &quads),
                quads.len() as u64,
            )
        });
        run.submit(0, &[passes.hard(&up.0, false)])?;
        run.submit(1, &[passes.accumulate(&up.0)])?;
        uploads.push(up);
    }
    let timing = run.finish()?;
    let stat = passes.replay(
        uploads
            .iter()
            .map(|(up, _)| passes.hard(up, true))
            .collect(),
    )?;
    let (fill, passed) = (stat(Stat::HardFill), stat(Stat::HardPassed));

    let caps = uploads.iter().map(|(u, _)| u.caps).sum::<u64>();
    let (mut hard, acc) = counters(
        &rays,
        n,
        silhouette_edges,
        caps,
        opts.counting,
        fill,
        passed,
    );
    hard.add(
        "shadow_quads",
        uploads.iter().map(|(_, q)| q).sum::<u64>() as f64,
    );
    hard.add("quad_tests", stat(Stat::HardTests));
    let note = "fill and overdraw from an instrumented replay of every sample's hard pass (WGSL \
                atomics); mem.* in the cpu-model's terms of an 8-bit stencil and a 16-bit \
                accumulation buffer";
    let mut out = timing.output((rays.width, rays.height), vec![hard, acc], note);
    out.execution.insert("samples".into(), serde_json::json!(n));
    out.execution
        .insert("counting".into(), serde_json::json!(opts.counting));
    Ok(out)
}
