//! `accum_hard` on wgpu, in one of two pipelines (option `gpu_pipeline`, recorded as
//! `execution.gpu_pipeline`); phases `hard` and `accumulate` as on the cpu executions.
//!
//! - `"raster"` (default), as the thesis rendered its reference (III §5.1): the eye's depth
//!   once, then per light sample the sample's shadow quads (or capped volumes) drawn with the
//!   depth test into the stencil (increment and decrement with wrap-around, cleared to the
//!   eye's count) and the lit pixels (stencil 0) blended into an accumulation target; the
//!   average is resolved after the last sample ([`crate::algorithms::shadow_volume::raster`],
//!   which states how its coverage differs from the cpu's ray casting). The stencil is the
//!   8 bits of Depth32FloatStencil8 where the adapter has it, else an R16Float count target by
//!   additive blending (`execution.hard_count` says which); the accumulation is R16Float (exact
//!   integers up to 2048), as the paper's 16-bit accumulation buffer.
//! - `"gather"`: per light sample the hard pass of the shadow-volume family
//!   ([`crate::algorithms::shadow_volume::wgpu`]): shadow quads, or for z-fail the capped
//!   volumes' faces, binned to 8×8 screen tiles on the host, one invocation per pixel counting
//!   its tile's primitives into an i32, then an `accumulate` pass (`wgpu.wgsl`, binding the hard
//!   pass's group beside its own) adding the pixels with count 0 to an f32 sum per pixel.
//!
//! The memory traffic counters (`mem_est.*`) are in the cpu-model's terms of that stencil and
//! accumulation buffer (`accum_hard::cpu`): the stencil cleared per sample, a depth read per
//! fragment, a stencil read and write per fragment that passes, and per sample the stencil read
//! and the accumulation buffer read and written for every pixel; fill and passed fragments come
//! from an instrumented replay of every sample's hard pass (WGSL atomics). Not built on the
//! GPU: silhouette detection, quad and cap construction (and the gather's binning): host, as on
//! the cpu executions.

use std::time::Instant;

use super::Phase;
use super::{AccumHardOptions, GpuPipeline, Samples, ACCUMULATION_BYTES, STENCIL_BYTES};
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::algorithms::eye_raster::{EyeRays, DEPTH_BYTES};
use crate::algorithms::shadow_volume::raster::{hard_triangles, DepthTarget, HardRaster};
use crate::algorithms::shadow_volume::wgpu::{
    self as family, check_limits, hard_fill, upload_rays, HardParams, HardPass, HardStat,
    RECORDS_WGSL, WORD,
};
use crate::algorithms::shadow_volume::Counting;
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, Bind, Instrumented, Layout, Pass, Program, Readout, Slots, Statistics, Timed,
    Timing,
};
use crate::gpu::{record_execution, Run};
use crate::record::Counters;
use crate::scene::camera::Camera;

/// `accum_hard` on wgpu, with the pipeline `opts.gpu_pipeline` names; the counters of both in
/// the cpu-model's terms (see the module docs); `execution` records the samples, the counting
/// and the pipeline (and the raster pipeline's count target).
pub fn render(
    gpu: &Run,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &AccumHardOptions,
) -> Result<FrameOutput> {
    if opts.gpu_pipeline == GpuPipeline::Gather {
        check_limits(gpu, frame, super::ID, STORAGE_BUFFERS)?;
    }
    let run = Sampled {
        start: Instant::now(),
        samples: Samples::new(frame, ctx, opts)?,
        rays: EyeRays::new(frame),
        counting: opts.counting,
    };
    let (timing, m, mut hard, note) = match opts.gpu_pipeline {
        GpuPipeline::Raster => run.raster(gpu, &frame.scene.camera)?,
        GpuPipeline::Gather => run.gather(gpu)?,
    };
    let (n, counting, rays) = (run.samples.count(), opts.counting, &run.rays);
    let pixel_samples = f64::from(n) * rays.len() as f64;
    let (stencil, accumulation) = (f64::from(STENCIL_BYTES), f64::from(ACCUMULATION_BYTES));
    hard.add(names::SILHOUETTE_EDGES, m.edges as f64);
    hard_fill(&mut hard, counting, m.fill, m.passed, m.caps);
    let reads = [
        ("depth", m.fill * DEPTH_BYTES as f64),
        ("stencil", m.passed * stencil),
    ];
    let stencil_w = (pixel_samples + m.passed) * stencil;
    hard.add_traffic("mem_est", &reads, &[("stencil", stencil_w)]);
    let mut acc = Counters::default();
    let reads = [
        ("stencil", pixel_samples * stencil),
        ("accumulation", pixel_samples * accumulation),
    ];
    let writes = [("accumulation", pixel_samples * accumulation)];
    acc.add_traffic("mem_est", &reads, &writes);
    let mut out = timing.output(
        (rays.width, rays.height),
        vec![(Phase::Hard, hard), (Phase::Accumulate, acc)],
        note,
    );
    let entries = serde_json::json!({
        "samples": n,
        "counting": counting,
        "gpu_pipeline": opts.gpu_pipeline,
    });
    record_execution(&mut out.execution, entries);
    if opts.gpu_pipeline == GpuPipeline::Raster {
        let target = DepthTarget::for_accumulation(gpu).describe();
        record_execution(
            &mut out.execution,
            serde_json::json!({ "hard_count": target }),
        );
    }
    Ok(out)
}

/// The accumulation on the gather pipeline: its bindings (group 1, after the hard pass's group 0)
/// and entry; joined after the family's records and hard pass.
const WGSL: &str = include_str!("wgpu.wgsl");

/// Storage buffers the accumulation binds in one stage: the hard pass's and its sum and
/// visibility.
const STORAGE_BUFFERS: u32 = family::STORAGE_BUFFERS + 2;

gpu_struct! {
    /// The parameters of one light sample's accumulation (group 1, binding 0).
    struct AccumParams as "AccumParams" {
        /// 1 for the first sample, 1 for the last (then the average is written).
        first_light: u32 => "u32",
        last_light: u32 => "u32",
        /// The light samples.
        sub_lights: u32 => "u32",
        pad: u32 => "u32",
    }
}

/// The accumulation's shader as its pipeline joins it.
const SOURCES: [&str; 6] = [
    HardParams::WGSL,
    RECORDS_WGSL,
    family::WGSL,
    AccumParams::WGSL,
    WGSL,
    crate::scene::coverage::WGSL,
];

/// What a pipeline gave: its timing, what its hard passes measured over all samples and its
/// own `hard` counters, how its counters were obtained.
type Pipeline<'g> = (Timing<'g>, Measured, Counters, &'static str);

/// What a pipeline's hard passes gave over all samples: silhouette edges, z-fail caps, fill and
/// passed fragments.
#[derive(Default)]
struct Measured {
    edges: u64,
    caps: u64,
    fill: f64,
    passed: f64,
}

/// What both pipelines start from: when the run began (the setup before the first pass counts
/// into phase `hard`), the light samples, the eye rays, the counting.
struct Sampled {
    start: Instant,
    samples: Samples,
    rays: EyeRays,
    counting: Counting,
}

impl Sampled {
    /// The raster pipeline ([`crate::algorithms::shadow_volume::raster`]): the eye's depth once,
    /// then per light sample a count pass of its shadow quads (or capped volumes) and an
    /// accumulation pass; the average is resolved after the last. Phase `hard` holds the depth
    /// pre-pass, the host geometry and the count passes, `accumulate` the accumulation passes and
    /// the resolve.
    fn raster<'g>(&self, gpu: &'g Run, camera: &Camera) -> Result<Pipeline<'g>> {
        let (samples, rays, counting) = (&self.samples, &self.rays, self.counting);
        let n = samples.count();
        let target = DepthTarget::for_accumulation(gpu);
        let passes = HardRaster::new(gpu, rays, camera, counting, n, target);
        let readback = [&passes.visibility];
        // The instrumented replay: the depth pre-pass and every sample's count pass.
        let mut run = Timed::new(gpu, Phase::ALL, Statistics::All, &readback)
            .counting_into(&passes.stats, Readout::End);
        run.add_setup(Phase::Hard, self.start);
        let (vertices, ranges, m) = run.host(Phase::Hard, || {
            let (mut vertices, mut ranges) = (Vec::new(), Vec::with_capacity(n as usize));
            let mut m = Measured::default();
            for s in 0..n {
                let (sample, quads) = samples.quads(s);
                let occluders = &samples.occluders;
                let eye = counting.eye_start(occluders, sample, rays.eye);
                let (v, caps) = hard_triangles(rays, &quads, counting, occluders, sample);
                let first = vertices.len() as u32;
                vertices.extend(v);
                ranges.push((first..vertices.len() as u32, eye));
                m.edges += quads.len() as u64;
                m.caps += caps;
            }
            (passes.vertices(&vertices), ranges, m)
        });
        run.submit(Phase::Hard, &[passes.depth_pass()])?;
        for (s, (range, eye)) in ranges.iter().enumerate() {
            run.submit(
                Phase::Hard,
                &passes.count_passes(&vertices, range.clone(), *eye),
            )?;
            let mut acc = vec![passes.accumulate_pass(s == 0)];
            if s + 1 == ranges.len() {
                acc.push(passes.resolve_pass());
            }
            run.submit(Phase::Accumulate, &acc)?;
        }
        let timing = run.finish()?;
        let slots = Slots::of(&timing.counts[0]);
        let (fill, passed) = (slots.get(0), slots.get(1));
        let note = "fill and overdraw from an instrumented replay of every sample's count pass \
                (depth test off, WGSL atomics) in the cpu-model's terms; mem_est.* in the \
                cpu-model's terms of an 8-bit stencil and a 16-bit accumulation buffer";
        Ok((
            timing,
            Measured { fill, passed, ..m },
            Counters::default(),
            note,
        ))
    }

    /// The compute gather ([`crate::algorithms::shadow_volume::wgpu`]).
    fn gather<'g>(&self, gpu: &'g Run) -> Result<Pipeline<'g>> {
        let (samples, rays, counting) = (&self.samples, &self.rays, self.counting);
        let n = samples.count();
        let rays_buf = upload_rays(gpu, rays);
        let occluders = samples.occluders.clone();
        let hard = HardPass::new(gpu, rays, &rays_buf, counting, occluders);
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let pixels = rays.len() as u64;
        let sum = gpu.storage_buffer("sum", WORD * pixels, copy);
        let visibility = gpu.storage_buffer("visibility", WORD * pixels, copy);
        let binds = [Bind::Uniform, Bind::ReadWrite, Bind::ReadWrite];
        let layout = Layout::new(gpu, "accumulate", wgpu::ShaderStages::COMPUTE, &binds);
        let groups = [Some(&hard.layout), Some(&layout)];
        let program = Program::new(gpu, "accum_hard/wgpu.wgsl", &SOURCES, &groups);
        let accumulate = Instrumented::timed(program.compute(gpu, "accumulate", Some(false)));
        // The instrumented replay: every sample's hard pass.
        let mut run = Timed::new(gpu, Phase::ALL, Statistics::Compute, &[&visibility])
            .counting_into(&hard.stats, Readout::End);
        run.add_setup(Phase::Hard, self.start);
        let (mut uploads, mut m) = (Vec::with_capacity(n as usize), Measured::default());
        for s in 0..n {
            let up = run.host(Phase::Hard, || {
                let (sample, quads) = samples.quads(s);
                m.edges += quads.len() as u64;
                let eye_count = counting.eye_start(&samples.occluders, sample, rays.eye);
                let params = AccumParams {
                    first_light: u32::from(s == 0),
                    last_light: u32::from(s + 1 == n),
                    sub_lights: n,
                    pad: 0,
                };
                let params = gpu.uniform("accumulate params", &params);
                let own = [&params, &sum, &visibility].map(|b| b.as_entire_binding());
                let group = layout.group(gpu, "accumulate", &own);
                (hard.upload_quads(rays, eye_count, sample, &quads), group)
            });
            uploads.push(up);
        }
        for (up, group) in &uploads {
            run.submit(Phase::Hard, &[hard.pass(up)])?;
            let groups = [Some(&up.group), Some(group)];
            let pass = Pass::compute("accumulate", &groups, &accumulate, hard.groups);
            run.submit(Phase::Accumulate, &[pass])?;
        }
        let timing = run.finish()?;
        let slots = Slots::of(&timing.counts[0]);
        let stat = |s: HardStat| slots.get(s as usize);
        let m = Measured {
            caps: uploads.iter().map(|(u, _)| u.caps).sum(),
            fill: stat(HardStat::Fill),
            passed: stat(HardStat::Passed),
            ..m
        };
        let mut hard = Counters::default();
        hard.add(names::SHADOW_QUADS, m.edges as f64);
        hard.add(names::QUAD_TESTS, stat(HardStat::Tests));
        let note =
            "fill and overdraw from an instrumented replay of every sample's hard pass (WGSL \
                atomics); mem.* in the cpu-model's terms of an 8-bit stencil and a 16-bit \
                accumulation buffer";
        Ok((timing, m, hard, note))
    }
}

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(SOURCES => AccumParams, HardParams);
