//! `pcss` as GPU passes: the family's light raster, then the blocker search and PCF of
//! `wgpu.wgsl` in the eye lookup.

use super::ID;
use crate::algorithms::shadow_map::{parse_options, PcssOptions};
use crate::algorithms::shadow_map_wgpu::{self, Lookup};
use crate::algorithms::{ExecContext, FrameOutput};
use crate::error::Result;
use crate::frame::Frame;

pub fn render(frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    let options: PcssOptions = parse_options(ID, &ctx.options)?;
    options.validate(ID)?;
    shadow_map_wgpu::render(
        frame,
        &Lookup {
            wgsl: include_str!("wgpu.wgsl"),
            bias: options.bias,
            blocker_samples: options.blocker_samples,
            pcf_samples: options.pcf_samples,
        },
    )
}
