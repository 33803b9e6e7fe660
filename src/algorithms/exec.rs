//! What every CPU execution shares: the modelled machine of a run and the frame output built
//! from it when the run is done.

use crate::algorithms::{Backend, ExecContext, FrameOutput};
use crate::frame::Frame;
use crate::model::Machine;
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
