//! The classic hard shadow map (Williams 1978), the baseline every soft-shadow paper compares
//! with: depth from the light centre rasterized into a `map_resolution`² map (`light_raster`),
//! then each eye sample projected into the map and compared with the stored depth, with a
//! slope-scaled bias ([`Bias`](super::shadow_map::Bias)) against self-shadowing (`eye_lookup`).
//!
//! The light's size is ignored: the shadow is the one a point light at its centre casts.

pub mod cpu;
pub mod wgpu;

use serde::{Deserialize, Serialize};

use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, MethodLimit, WgpuEntry, WgpuParity,
    WorkEstimate,
};
use crate::algorithms::shadow_map::{self, Bias};
use crate::algorithms::work;
use crate::error::InputError;
use crate::frame::RunParams;

pub const ID: &str = "hard_shadow_map";

/// Options of `hard_shadow_map` (scenario `options.hard_shadow_map`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HardShadowOptions {
    #[serde(default)]
    pub bias: Bias,
}

impl AlgorithmOptions for HardShadowOptions {
    fn validate(&self) -> Result<(), InputError> {
        self.bias.validate(ID)
    }
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct HardShadowMap;

/// A shadow map: the map's texels once, and one lookup per pixel.
pub fn work_estimate(
    _: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    _: &HardShadowOptions,
) -> f64 {
    work::texels(p) + work::pixels(p)
}

impl Algorithm for HardShadowMap {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "baseline (Williams 1978)";
    const SUMMARY: &'static str = "shadow map from the light centre with slope-scaled bias";
    const LIMITS: &'static [MethodLimit] = &[MethodLimit::NoPenumbra];
    type Options = HardShadowOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = shadow_map::memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] = &[r#"{"bias": {"constant": 0.5, "slope": 3.0}}"#];
    /// Fragment counts differ where the light raster (measured: 68 of 4,626 on torus-on-plane,
    /// map 128²).
    const WGPU_PARITY: WgpuParity = WgpuParity::LIGHT_RASTER;
    const CPU: CpuEntry<HardShadowOptions> = cpu::render;
    const WGPU: Option<WgpuEntry<HardShadowOptions>> = Some(wgpu::render);
}
