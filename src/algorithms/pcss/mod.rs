//! Percentage-closer soft shadows (Fernando 2005, cited in 004 Table 2): the hard shadow map of
//! the light centre, then per eye sample (1) a blocker search over the region of the map the
//! light's cone covers, (2) the penumbra width from the average blocker depth by similar
//! triangles, (3) a percentage-closer filter of that width. The formulas are in
//! [`super::shadow_map`]; the taps are on Vogel's disk ([`super::shadow_map::vogel_disk`]).
//!
//! Any light kind is accepted; its size ([`crate::scene::Light::size`]) is the light radius.

pub mod cpu;
pub mod wgpu;

use std::collections::BTreeMap;

use super::parse_options;
use super::shadow_map::PcssOptions;
use crate::error::InputError;

pub const ID: &str = "pcss";

pub fn options(options: &BTreeMap<String, serde_json::Value>) -> Result<PcssOptions, InputError> {
    let o: PcssOptions = parse_options(ID, options)?;
    o.validate(ID)?;
    Ok(o)
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct Pcss;

impl crate::algorithms::Algorithm for Pcss {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "Fernando 2005, cited in 004 Table 2";
    const SUMMARY: &'static str = "blocker search + variable-width percentage-closer filter";
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
    type Options = PcssOptions;

    fn options(
        options: &std::collections::BTreeMap<String, serde_json::Value>,
    ) -> Result<Self::Options, crate::error::InputError> {
        self::options(options)
    }

    fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
        crate::algorithms::shadow_map::memory_estimate(p)
    }

    fn work_estimate(
        extent: &crate::algorithms::work::SceneExtent,
        p: &crate::frame::RunParams,
        ctx: &crate::algorithms::ExecContext,
    ) -> f64 {
        crate::algorithms::work::pcss(extent, p, ctx)
    }

    fn cpu(
        backend: crate::algorithms::Backend,
        frame: &crate::frame::Frame,
        ctx: &crate::algorithms::ExecContext,
        o: &Self::Options,
    ) -> crate::error::Result<crate::algorithms::FrameOutput> {
        Ok(cpu::render(backend, frame, ctx, *o))
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
