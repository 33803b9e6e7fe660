//! `rt_denoised` as compute passes (`wgpu.wgsl`): the caster BVH built and flattened on the host
//! (as the CPU executions build it, [`CasterBvh`]) and uploaded as two storage buffers, then
//!
//! 1. `trace` — one invocation per pixel: its `spp` rays, each an any-hit traversal of the BVH
//!    with a stack of [`super::bvh::STACK`] entries in WGSL (the adapter's ray queries are not used: lavapipe
//!    offers none, and this execution does not build a ray-query variant); dispatched in
//!    chunks of workgroups of at most [`RAYS_PER_SUBMISSION`] rays (at least one workgroup),
//!    one submission each, so that the run's deadline is checked between them;
//! 2. `denoise` — `penumbra` (the penumbra radius per pixel from the neighbours' hit
//!    distances), then `passes` × `atrous` (ping-pong between two buffers).
//!
//! The instrumented replay ([`crate::gpu::pass`]) runs the same passes counting with atomics
//! into 64-bit slots what the cpu executions count: rays, node visits, triangle tests, occluded
//! and horizon-culled rays, the rays of pixels whose rays agreed, search and filter taps, the
//! filtered pixels.

use std::time::Instant;

use serde_json::json;

use super::bvh::{CasterBvh, NodePair, Tri};
use super::seed32;
use super::Phase;
use super::{buffer_bytes, light_radius, search_far, PixelInputs, RtDenoisedOptions, ID};
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, tiles, Bind, Layout, Pass, Program, Readout, Slots, Statistics, Timed,
};
use crate::gpu::{record_execution, Needs, Run};
use crate::record::Counters;
use crate::scene::Light;

const WGSL: &str = include_str!("wgpu.wgsl");
/// Side of the square compute workgroups (`@workgroup_size(8, 8)`).
const WORKGROUP: u32 = 8;
/// The most rays one submission of the trace holds (at least one workgroup's): a band of whole
/// rows of workgroups, or part of one row. The run's deadline is checked between submissions;
/// lavapipe traces about a million rays a second.
pub const RAYS_PER_SUBMISSION: u64 = 1 << 20;
/// The statistics slots (`STAT_*` in the WGSL), in slot order.
const STATS: [&str; 9] = [
    "rt.rays",
    "rt.node_visits",
    "rt.triangle_tests",
    "rt.occluded_rays",
    "rt.horizon_culled",
    "overdraw",
    "denoise.search_taps",
    "denoise.filter_taps",
    "denoise.filtered_pixels",
];

gpu_struct! {
    /// The light and the run's parameters (group 0, binding 0).
    struct RtUniform as "Rt" {
        center: [f32; 3] => "vec3<f32>",
        /// 0 sphere, 1 disc, 2 rectangle.
        kind: u32 => "u32",
        /// A disc's or rectangle's emitter half-axes (`Light::emitter_frame`); unused for a
        /// sphere, whose frame faces each point.
        half_u: [f32; 3] => "vec3<f32>",
        /// A sphere's radius.
        radius: f32 => "f32",
        half_v: [f32; 3] => "vec3<f32>",
        /// `light_radius`: the denoiser's light radius.
        light_radius: f32 => "f32",
        width: u32 => "u32",
        height: u32 => "u32",
        spp: u32 => "u32",
        seed: u32 => "u32",
        /// The BVH's root reference, when `has_root` is 1.
        root: u32 => "u32",
        has_root: u32 => "u32",
        /// `search_far`: spacing of the penumbra search's far grid, pixels.
        search_far: i32 => "i32",
        /// The largest filter radius, pixels.
        max_radius: f32 => "f32",
    }
}

gpu_struct! {
    /// An à-trous pass's tap spacing, or a trace chunk's first pixel (group 2, binding 0).
    struct StepUniform as "Step" {
        step: u32 => "u32",
        /// The first image column of a trace chunk (0 for the denoiser's passes).
        col0: u32 => "u32",
        /// The first image row of a trace chunk (0 for the denoiser's passes).
        row0: u32 => "u32",
        p3: u32 => "u32",
    }
}

/// The shader as the pipelines join it.
const SOURCES: [&str; 6] = [
    RtUniform::WGSL,
    StepUniform::WGSL,
    NodePair::WGSL,
    Tri::WGSL,
    WGSL,
    crate::scene::coverage::WGSL,
];

/// `rt_denoised` on wgpu.
pub fn render(
    gpu: &Run,
    frame: &Frame,
    ctx: &ExecContext,
    o: &RtDenoisedOptions,
) -> Result<FrameOutput> {
    let start = Instant::now();
    let bvh = CasterBvh::build(frame)?;
    let inputs = PixelInputs::of(frame);
    let (node_bytes, tri_bytes) = bvh.bytes();
    let pixels = frame.gbuffer.len() as u64;
    gpu.check_limits(
        ID,
        Needs {
            storage_buffers: 8,
            buffers: &[
                ("bvh_nodes", node_bytes),
                ("bvh_triangles", tri_bytes),
                ("rt_points", pixels * 16),
            ],
            ..Needs::default()
        },
    )?;
    let light = frame.scene.light;
    let (_, half_u, half_v) = light.emitter_frame(light.center());
    let (width, height) = (frame.width(), frame.height());
    let uniform = RtUniform {
        center: light.center().to_array(),
        kind: match light {
            Light::Sphere { .. } => 0,
            Light::Disc { .. } => 1,
            Light::Rect { .. } => 2,
        },
        half_u: half_u.to_array(),
        radius: light.size(),
        half_v: half_v.to_array(),
        light_radius: light_radius(&light),
        width,
        height,
        spp: o.spp,
        seed: seed32(ctx.seed),
        root: bvh.root.unwrap_or(0),
        has_root: u32::from(bvh.root.is_some()),
        search_far: search_far(o.radius),
        max_radius: o.radius as f32,
    };
    let storage = wgpu::BufferUsages::STORAGE;
    let uniform_buf = gpu.uniform("rt uniform", &uniform);
    let stats = gpu.counts_buffer::<[u32; 2 * STATS.len()]>("rt stats");
    let points = gpu.upload("rt points", &inputs.points, storage);
    let normals = gpu.upload("rt normals", &inputs.normals, storage);
    let nodes = gpu.upload("bvh nodes", &bvh.nodes, storage);
    let tris = gpu.upload("bvh triangles", &bvh.triangles, storage);
    let traced = gpu.storage_buffer("rt traced", pixels * 8, wgpu::BufferUsages::empty());
    let radius = gpu.storage_buffer("penumbra radius", pixels * 4, wgpu::BufferUsages::empty());
    let ping = gpu.storage_buffer("atrous ping", pixels * 4, wgpu::BufferUsages::COPY_SRC);
    let pong = gpu.storage_buffer("atrous pong", pixels * 4, wgpu::BufferUsages::COPY_SRC);

    use wgpu::ShaderStages as S;
    let (shared_layout, shared) = Layout::bound(
        gpu,
        "rt shared",
        S::COMPUTE,
        &[
            (Bind::Uniform, uniform_buf.as_entire_binding()),
            (Bind::ReadWrite, stats.as_entire_binding()),
        ],
    );
    let (data_layout, data) = Layout::bound(
        gpu,
        "rt data",
        S::COMPUTE,
        &[
            (Bind::ReadOnly, points.as_entire_binding()),
            (Bind::ReadOnly, normals.as_entire_binding()),
            (Bind::ReadOnly, nodes.as_entire_binding()),
            (Bind::ReadOnly, tris.as_entire_binding()),
            (Bind::ReadWrite, traced.as_entire_binding()),
            (Bind::ReadWrite, radius.as_entire_binding()),
        ],
    );
    // Group 2 per pass: the trace writes `ping`; pass k of the à-trous filter reads one buffer
    // and writes the other, at spacing 2^k.
    let step_group =
        |(step, col0, row0): (u32, u32, u32), from: &wgpu::Buffer, to: &wgpu::Buffer| {
            let u = gpu.uniform(
                "atrous step",
                &StepUniform {
                    step,
                    col0,
                    row0,
                    ..StepUniform::default()
                },
            );
            Layout::bound(
                gpu,
                "rt step",
                S::COMPUTE,
                &[
                    (Bind::Uniform, u.as_entire_binding()),
                    (Bind::ReadWrite, from.as_entire_binding()),
                    (Bind::ReadWrite, to.as_entire_binding()),
                ],
            )
        };
    let size = tiles((width, height), WORKGROUP);
    let chunks = trace_chunks(size, o.spp);
    let (step_layout, trace_groups): (Vec<Layout>, Vec<wgpu::BindGroup>) = chunks
        .iter()
        .map(|&((x, y), _)| step_group((0, x * WORKGROUP, y * WORKGROUP), &pong, &ping))
        .unzip();
    let step_layout = &step_layout[0];
    let passes = if o.denoise { o.passes } else { 0 };
    let atrous_groups: Vec<wgpu::BindGroup> = (0..passes)
        .map(|k| {
            let (from, to) = if k % 2 == 0 {
                (&ping, &pong)
            } else {
                (&pong, &ping)
            };
            step_group((1 << k, 0, 0), from, to).1
        })
        .collect();
    let result = if passes % 2 == 0 { &ping } else { &pong };
    let program = Program::new(
        gpu,
        "rt_denoised/wgpu.wgsl",
        &SOURCES,
        &[Some(&shared_layout), Some(&data_layout), Some(step_layout)],
    );
    let trace = program.instrumented(gpu, "trace");
    let penumbra = program.instrumented(gpu, "penumbra");
    let atrous = program.instrumented(gpu, "atrous");
    let trace_pass = |chunk: usize| {
        Pass::compute(
            "trace",
            &[Some(&shared), Some(&data), Some(&trace_groups[chunk])],
            &trace,
            chunks[chunk].1,
        )
    };
    let denoise_passes = || -> Vec<Pass<'_>> {
        let mut v = Vec::new();
        if o.denoise {
            v.push(Pass::compute(
                "penumbra",
                &[Some(&shared), Some(&data), Some(&trace_groups[0])],
                &penumbra,
                size,
            ));
            for g in &atrous_groups {
                v.push(Pass::compute(
                    "atrous",
                    &[Some(&shared), Some(&data), Some(g)],
                    &atrous,
                    size,
                ));
            }
        }
        v
    };

    let phases: &[Phase] = if o.denoise {
        Phase::ALL
    } else {
        &[Phase::Trace]
    };
    // The instrumented replay: the same passes, counting, a chunk a submission.
    let mut run =
        Timed::new(gpu, phases, Statistics::Compute, &[result]).counting_into(&stats, Readout::End);
    run.add_setup(Phase::Trace, start);
    for chunk in 0..chunks.len() {
        run.submit(Phase::Trace, &[trace_pass(chunk)])?;
    }
    if o.denoise {
        run.submit(Phase::Denoise, &denoise_passes())?;
    }
    let timing = run.finish()?;
    let slot = Slots::of(&timing.counts[0]);
    let counters = phase_counters(
        &slot,
        o,
        (node_bytes, tri_bytes),
        buffer_bytes(&frame.params),
    );
    let note = "rays, node visits, triangle tests and taps from an instrumented replay (WGSL \
                atomics); the BVH built on the host and traversed in WGSL (no ray queries)";
    let mut out = timing.output((width, height), counters, note);
    record_execution(
        &mut out.execution,
        json!({
            "traversal": "wgsl",
            "bvh": {
                "nodes": bvh.nodes.len(),
                "triangles": bvh.triangles.len(),
                "depth": bvh.depth,
            },
        }),
    );
    Ok(out)
}

/// The trace's chunks of a dispatch of `size` workgroups of `spp` rays a pixel, in row order:
/// each its first workgroup (column, row) and its size in workgroups; at most
/// [`RAYS_PER_SUBMISSION`] rays each (one workgroup where a workgroup holds more), covering every
/// workgroup once.
fn trace_chunks(size: (u32, u32), spp: u32) -> Vec<((u32, u32), (u32, u32))> {
    let group_rays = u64::from(WORKGROUP * WORKGROUP) * u64::from(spp.max(1));
    let per_chunk = (RAYS_PER_SUBMISSION / group_rays).max(1);
    let (nx, ny) = size;
    if per_chunk >= u64::from(nx) {
        let rows = (per_chunk / u64::from(nx)).min(u64::from(ny)) as u32;
        (0..ny)
            .step_by(rows as usize)
            .map(|y| ((0, y), (nx, rows.min(ny - y))))
            .collect()
    } else {
        let cols = per_chunk as u32;
        (0..ny)
            .flat_map(|y| {
                (0..nx)
                    .step_by(cols as usize)
                    .map(move |x| ((x, y), (cols.min(nx - x), 1)))
            })
            .collect()
    }
}

/// The counters of each phase from the replay's slots and the host's sizes, as the cpu
/// executions name them.
fn phase_counters(
    slot: &Slots,
    o: &RtDenoisedOptions,
    (node_bytes, tri_bytes): (u64, u64),
    buffers: u64,
) -> Vec<(Phase, Counters)> {
    let get = |name: &str| slot.get(STATS.iter().position(|s| *s == name).expect("a slot"));
    let mut trace = Counters::default();
    for name in &STATS[..6] {
        trace.set(name, get(name));
    }
    trace.set(names::FILL, get(names::RT_RAYS));
    trace.set(names::RT_BVH_NODE_BYTES, node_bytes as f64);
    trace.set(names::RT_BVH_TRIANGLE_BYTES, tri_bytes as f64);
    let mut phases = vec![(Phase::Trace, trace)];
    if o.denoise {
        let mut denoise = Counters::default();
        for name in &STATS[6..] {
            denoise.set(name, get(name));
        }
        denoise.set(names::DENOISE_BUFFER_BYTES, buffers as f64);
        phases.push((Phase::Denoise, denoise));
    }
    phases
}

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(SOURCES => RtUniform, StepUniform, NodePair, Tri);

#[cfg(test)]
mod tests {
    use super::*;

    /// Every workgroup in exactly one chunk, each within the ray budget or one workgroup.
    #[test]
    fn trace_chunks_cover_the_dispatch_once_within_the_budget() {
        for (size, spp) in [
            ((1, 1), 1),
            ((20, 15), 1),
            ((40, 30), 64),
            ((40, 30), 1024),
            ((80, 60), 4096),
            ((7, 3), 300),
        ] {
            let mut seen = vec![0u32; (size.0 * size.1) as usize];
            for ((x, y), (w, h)) in trace_chunks(size, spp) {
                let rays = u64::from(w * h) * 64 * u64::from(spp);
                assert!(rays <= RAYS_PER_SUBMISSION || w * h == 1, "{size:?} {spp}");
                for j in y..y + h {
                    for i in x..x + w {
                        seen[(j * size.0 + i) as usize] += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "{size:?} {spp}");
        }
        // A frame that fits one submission stays one pass.
        assert_eq!(trace_chunks((20, 15), 4).len(), 1);
    }
}
