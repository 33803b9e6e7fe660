//! The classic hard shadow map (Williams 1978), the baseline every soft-shadow paper compares
//! with: depth from the light centre rasterized into a `map_resolution`² map (`light_raster`),
//! then each eye sample projected into the map and compared with the stored depth, with a
//! slope-scaled bias ([`Bias`](super::shadow_map::Bias)) against self-shadowing (`eye_lookup`).
//!
//! The light's size is ignored: the shadow is the one a point light at its centre casts.

pub mod cpu;
pub mod wgpu;

use super::parse_options;
use super::shadow_map::HardShadowOptions;

pub const ID: &str = "hard_shadow_map";

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct HardShadowMap;

impl crate::algorithms::Algorithm for HardShadowMap {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "baseline (Williams 1978)";
    const SUMMARY: &'static str = "shadow map from the light centre with slope-scaled bias";
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
    const LIMITS: &'static [crate::algorithms::MethodLimit] =
        &[crate::algorithms::MethodLimit::NoPenumbra];
    type Options = HardShadowOptions;

    fn options(
        options: &std::collections::BTreeMap<String, serde_json::Value>,
    ) -> Result<Self::Options, crate::error::InputError> {
        parse_options(ID, options)
    }

    fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
        crate::algorithms::shadow_map::memory_estimate(p)
    }

    fn work_estimate(
        extent: &crate::algorithms::work::SceneExtent,
        p: &crate::frame::RunParams,
        ctx: &crate::algorithms::ExecContext,
    ) -> f64 {
        crate::algorithms::work::hard_shadow_map(extent, p, ctx)
    }

    fn cpu(
        backend: crate::algorithms::Backend,
        frame: &crate::frame::Frame,
        ctx: &crate::algorithms::ExecContext,
        o: &Self::Options,
    ) -> crate::error::Result<crate::algorithms::FrameOutput> {
        Ok(cpu::render(backend, frame, ctx, o.bias))
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
