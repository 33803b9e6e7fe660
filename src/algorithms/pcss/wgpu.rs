//! `pcss` as GPU passes: the family's light raster, then the blocker search and PCF of
//! `wgpu.wgsl` in the eye lookup.

use crate::algorithms::shadow_map_wgpu::{self, Lookup};
use crate::algorithms::{ExecContext, FrameOutput};
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::Gpu;

pub fn render(gpu: &Gpu, frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    let options = super::options(&ctx.options)?;
    shadow_map_wgpu::render(
        gpu,
        frame,
        &Lookup {
            wgsl: include_str!("wgpu.wgsl"),
            bias: options.bias,
            blocker_samples: options.blocker_samples,
            pcf_samples: options.pcf_samples,
        },
    )
}
