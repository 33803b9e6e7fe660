//! What the adapter does that its features and limits do not state, measured on the device once
//! and kept with it.
//!
//! - [`Gpu::half_blend_sums`]: how an additive blend into a half-float (R16Float) target rounds.
//!   Vulkan leaves the rounding of blending to the implementation; paper 002's FP16
//!   accumulation (§5.1.3, Appendix A) loses what falls below the target's precision, and how
//!   much it loses depends on it. Mesa's lavapipe rounds toward zero; NVIDIA's driver (H200,
//!   580.159) to nearest.

use super::pass::{Onto, Pass, Program, Raster, Work};
use super::readback::Staging;
use super::{additive_red, Gpu};
use crate::error::{Error, Result};

/// Texels of the probe's row: one per sum.
const PROBES: u32 = 2;

/// The probe: a screen-covering triangle whose fragment adds `1 + ¾ ulp − 1` on the left
/// texel and `¼ ulp` on the right one, in f32 (ulp = 2⁻¹⁰, a half's spacing at 1).
const WGSL: &str = "
@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    let ulp = 1.0 / 1024.0;
    return vec4<f32>(select(0.25, 0.75, p.x < 1.0) * ulp, 0.0, 0.0, 0.0);
}
";

impl Gpu {
    /// `[1 + ¾ ulp, 1 + ¼ ulp]` as the device stores them when each is added by blending onto 1
    /// in an R16Float target (ulp = 2⁻¹⁰): `[1, 1]` rounds toward zero (or down), `[1 + ulp,
    /// 1]` to nearest, `[1 + ulp, 1 + ulp]` up. Measured on the first call (one draw into a 2×1
    /// target and a read-back), then kept. Errors: the device's, from the submission or the
    /// read-back.
    pub fn half_blend_sums(&self) -> Result<[f32; 2]> {
        if let Some(sums) = self.half_blend.get() {
            return Ok(*sums);
        }
        let sums = self.probe_half_blend()?;
        Ok(*self.half_blend.get_or_init(|| sums))
    }

    fn probe_half_blend(&self) -> Result<[f32; 2]> {
        let format = wgpu::TextureFormat::R16Float;
        let program = Program::new(self, "half-float blend probe", &[WGSL], &[]);
        let raster = Raster {
            depth: None,
            color: Some(additive_red(format)),
            ..Raster::default()
        };
        let pipeline = super::pass::Instrumented::timed(program.render(self, &raster));
        let target = self.texture(
            "half-float blend probe",
            (PROBES, 1),
            format,
            wgpu::TextureUsages::COPY_SRC,
        );
        let view = target.create_view(&Default::default());
        let pipelines = std::slice::from_ref(&pipeline);
        let onto = Onto::new(pipelines, vec![(0, 0..3, 0)], &view, Some(1.0));
        let pass = Pass {
            label: "half-float blend probe",
            groups: vec![],
            work: Work::Onto(onto),
        };
        let staging = Staging::new(self, "half-float blend probe", 256);
        self.submit(|e| {
            pass.record(e, (None, None, 0), false);
            staging.copy_texture(e, &target, 256);
        })?;
        let bytes = staging.read(self)?;
        let half = |i: usize| half::f16::from_le_bytes([bytes[2 * i], bytes[2 * i + 1]]).to_f32();
        let sums = [half(0), half(1)];
        if sums.iter().any(|s| !s.is_finite()) {
            return Err(Error::Gpu(format!(
                "the half-float blend probe read back {sums:?}"
            )));
        }
        Ok(sums)
    }
}
