//! `accum_hard`: the average of N hard shadows from N point samples on the light (paper 001
//! §1.3 and III §5.1, the "1024-sample shadow"), each rendered with hard shadow volumes in an
//! 8-bit stencil buffer as the paper does, then accumulated per pixel.
//!
//! The samples are the k×k stratified, jittered positions of [`Light::stratified_sample`] seen
//! from the centre of the scene (for a sphere light: its disc facing the scene); every pixel
//! uses the same samples, as an accumulation buffer does.
//!
//! [`Light::stratified_sample`]: crate::scene::Light::stratified_sample

pub mod cpu;
pub mod wgpu;

use serde::{Deserialize, Serialize};

pub use super::shadow_volume::Counting;
use crate::error::InputError;

pub const ID: &str = "accum_hard";

/// Options of `accum_hard` (scenario `options.accum_hard`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccumHardOptions {
    /// N, the number of light samples: a perfect square in 16..=1024.
    #[serde(default = "default_samples")]
    pub samples: u32,
    /// The hard passes' counting: z-pass from the eye's count, or z-fail over capped volumes
    /// ([`Counting`]).
    #[serde(default)]
    pub counting: Counting,
}

fn default_samples() -> u32 {
    256
}

impl Default for AccumHardOptions {
    fn default() -> Self {
        AccumHardOptions {
            samples: default_samples(),
            counting: Counting::ZPass,
        }
    }
}

impl AccumHardOptions {
    /// The side k of the k×k sample grid.
    pub fn strata_side(&self) -> Result<u32, InputError> {
        match super::reference::strata_side(self.samples) {
            Some(k) if (16..=1024).contains(&self.samples) => Ok(k),
            _ => Err(InputError::new(
                format!("$.options.{ID}.samples"),
                format!(
                    "must be a perfect square in 16..=1024 (16, 25, ..., 256, ..., 1024), got {}",
                    self.samples
                ),
            )),
        }
    }
}

/// Bytes of the eye-sized buffers (stencil and the f32 accumulation buffer), estimated before
/// anything is allocated, for the harness's memory limit.
pub fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
    u64::from(p.image[0]) * u64::from(p.image[1]) * (1 + 4)
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct AccumHard;

impl crate::algorithms::Algorithm for AccumHard {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "001 §1.3, Paper III §5";
    const SUMMARY: &'static str = "average of N hard shadow-volume shadows from N light samples";
    const LIGHTS: &'static [crate::scene::LightKind] = &[
        crate::scene::LightKind::Sphere,
        crate::scene::LightKind::Disc,
        crate::scene::LightKind::Rect,
    ];
    const BACKENDS: &'static [crate::algorithms::Backend] = &[
        crate::algorithms::Backend::CpuNative,
        crate::algorithms::Backend::CpuModel,
        crate::algorithms::Backend::Wgpu,
    ];
    const LIMITS: &'static [crate::algorithms::MethodLimit] = &[];
    type Options = AccumHardOptions;

    fn options(
        options: &std::collections::BTreeMap<String, serde_json::Value>,
    ) -> Result<Self::Options, crate::error::InputError> {
        let o: AccumHardOptions = super::parse_options(ID, options)?;
        o.strata_side()?;
        Ok(o)
    }

    fn prepare(frame: &crate::frame::Frame, o: &mut AccumHardOptions) -> Option<String> {
        super::shadow_volume::zfail_fallback(ID, frame, &mut o.counting)
    }

    fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
        memory_estimate(p)
    }

    fn work_estimate(
        extent: &crate::algorithms::work::SceneExtent,
        p: &crate::frame::RunParams,
        ctx: &crate::algorithms::ExecContext,
    ) -> f64 {
        crate::algorithms::work::accum_hard(extent, p, ctx)
    }

    fn cpu(
        backend: crate::algorithms::Backend,
        frame: &crate::frame::Frame,
        ctx: &crate::algorithms::ExecContext,
        o: &Self::Options,
    ) -> crate::error::Result<crate::algorithms::FrameOutput> {
        cpu::render(backend, frame, ctx, o)
    }

    fn wgpu(
        gpu: &crate::gpu::Gpu,
        frame: &crate::frame::Frame,
        ctx: &crate::algorithms::ExecContext,
        o: &Self::Options,
    ) -> crate::error::Result<crate::algorithms::FrameOutput> {
        wgpu::render(gpu, frame, ctx, o)
    }
}
