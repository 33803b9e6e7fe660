//! `hard_shadow_map` as GPU passes: the family's light raster, then the hard test of
//! `wgpu.wgsl` in the eye lookup.

use super::HardShadowOptions;
use crate::algorithms::shadow_map::wgpu::{self as shadow_map_wgpu, Lookup};
use crate::algorithms::ExecContext;
use crate::algorithms::FrameOutput;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::Gpu;

pub fn render(
    gpu: &Gpu,
    frame: &Frame,
    _: &ExecContext,
    options: &HardShadowOptions,
) -> Result<FrameOutput> {
    shadow_map_wgpu::render(
        gpu,
        frame,
        &Lookup {
            wgsl: include_str!("wgpu.wgsl"),
            bias: options.bias,
            blocker_samples: 0,
            pcf_samples: 0,
        },
    )
}
