//! `pcss` as GPU passes: the family's light raster, then the blocker search and PCF of
//! `wgpu.wgsl` in the eye lookup.

use super::PcssOptions;
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::algorithms::shadow_map::wgpu::{self as shadow_map_wgpu, Lookup};
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::Run;

/// `pcss` on wgpu (`ctx` unused: the passes need nothing of the run's context).
pub fn render(
    gpu: &Run,
    frame: &Frame,
    _ctx: &ExecContext,
    o: &PcssOptions,
) -> Result<FrameOutput> {
    let lookup = Lookup {
        blocker_samples: o.blocker_samples,
        pcf_samples: o.pcf_samples,
        ..Lookup::new(super::ID, include_str!("wgpu.wgsl"), o.bias)
    };
    shadow_map_wgpu::render(gpu, frame, &lookup)
}
