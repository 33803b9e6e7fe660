//! `hard_shadow_map` as GPU passes: the family's light raster, then the hard test of
//! `wgpu.wgsl` in the eye lookup.

use super::HardShadowOptions;
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::algorithms::shadow_map::wgpu::{self as shadow_map_wgpu, Lookup};
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::Run;

/// `hard_shadow_map` on wgpu (`ctx` unused: the passes need nothing of the run's context).
pub fn render(
    gpu: &Run,
    frame: &Frame,
    _ctx: &ExecContext,
    o: &HardShadowOptions,
) -> Result<FrameOutput> {
    let lookup = Lookup::new(super::ID, include_str!("wgpu.wgsl"), o.bias);
    shadow_map_wgpu::render(gpu, frame, &lookup)
}
