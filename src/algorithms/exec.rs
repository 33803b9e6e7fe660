//! What every CPU execution shares: the modelled machine of a run and the frame output built
//! from it when the run is done.

use crate::algorithms::{Backend, ExecContext, FrameOutput};
use crate::frame::Frame;
use crate::model::raster::Target;
use crate::model::{Machine, TaskKernel};
use crate::visibility::VisibilityBuffer;

/// The machine an execution runs on: the context's configuration with the run's core count.
pub fn machine(backend: Backend, frame: &Frame, ctx: &ExecContext) -> Machine {
    let config = match frame.params.cores {
        Some(c) => ctx.machine.with_cores(c),
        None => ctx.machine.clone(),
    };
    Machine::new(backend, config).with_deadline(ctx.deadline)
}

/// Wraps a finished machine and the visibility into a frame output.
pub fn output(m: Machine, visibility: VisibilityBuffer) -> FrameOutput {
    let f = m.finish();
    FrameOutput {
        visibility,
        counters: f.counters,
        phases: f.phases,
        model_ms: f.model_ms,
        gpu_ms: None,
        execution: f.execution,
        warnings: vec![],
        rgb: None,
        gpu_setup_ms: None,
    }
}

/// The eye image cut into the frame's screen tiles: the task grid of an eye pass.
pub fn eye_tiles(frame: &Frame) -> Target {
    let g = &frame.gbuffer;
    Target {
        width: g.width,
        height: g.height,
        tile: frame.params.tile_size,
    }
}

/// Step `lookup` of an eye pass: `kernel` run over the eye tiles with `weights`
/// ([`Target::tile_weights`]); each task's (pixel index, visibility) pairs written into an
/// image that is lit everywhere else.
pub fn eye_lookup_step<K>(
    m: &mut Machine,
    frame: &Frame,
    kernel: &K,
    weights: &[u64],
) -> VisibilityBuffer
where
    K: TaskKernel<Out = Vec<(u32, f32)>>,
{
    let g = &frame.gbuffer;
    let mut vis = VisibilityBuffer::lit(g.width, g.height);
    for (i, v) in m.run_step("lookup", kernel, weights).into_iter().flatten() {
        vis.data[i as usize] = v;
    }
    vis
}
