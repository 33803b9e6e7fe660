//! Percentage-closer soft shadows (Fernando 2005, cited in 004 Table 2): the hard shadow map of
//! the light centre, then per eye sample (1) a blocker search over the region of the map the
//! light's cone covers, (2) the penumbra width from the average blocker depth by similar
//! triangles, (3) a percentage-closer filter of that width. The formulas are in
//! [`super::shadow_map`]; the taps are on Vogel's disk ([`super::shadow_map::vogel_disk`]).
//!
//! Any light kind is accepted; its size ([`crate::scene::Light::size`]) is the light radius.

pub mod cpu;
pub mod wgpu;

use crate::error::InputError;
use serde::{Deserialize, Serialize};

use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, WgpuEntry, WgpuParity, WorkEstimate,
};
use crate::algorithms::shadow_map::{self, Bias};
use crate::algorithms::work;
use crate::frame::RunParams;

pub const ID: &str = "pcss";

/// Options of `pcss` (scenario `options.pcss`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PcssOptions {
    /// Shadow-map taps of the blocker search (step 1).
    pub blocker_samples: u32,
    /// Shadow-map taps of the percentage-closer filter (step 3).
    pub pcf_samples: u32,
    pub bias: Bias,
}

impl Default for PcssOptions {
    fn default() -> Self {
        PcssOptions {
            blocker_samples: 16,
            pcf_samples: 32,
            bias: Bias::default(),
        }
    }
}

impl AlgorithmOptions for PcssOptions {
    fn validate(&self) -> Result<(), InputError> {
        let field = |name: &str| format!("$.options.{ID}.{name}");
        InputError::check_range(field("blocker_samples"), self.blocker_samples, 1..=1024)?;
        InputError::check_range(field("pcf_samples"), self.pcf_samples, 1..=1024)?;
        self.bias.validate(ID)
    }
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct Pcss;

/// PCSS: the shadow map, then per pixel the blocker-search and filter taps.
pub fn work_estimate(
    _: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    o: &PcssOptions,
) -> f64 {
    work::texels(p) + work::pixels(p) * f64::from(o.blocker_samples + o.pcf_samples)
}

impl Algorithm for Pcss {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "Fernando 2005, cited in 004 Table 2";
    const SUMMARY: &'static str = "blocker search + variable-width percentage-closer filter";
    type Options = PcssOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = shadow_map::memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] = &[r#"{"blocker_samples": 4, "pcf_samples": 8}"#];
    /// Fragment counts differ where the light raster as in hard_shadow_map.
    const WGPU_PARITY: WgpuParity = WgpuParity::LIGHT_RASTER;
    const CPU: CpuEntry<PcssOptions> = cpu::render;
    const WGPU: Option<WgpuEntry<PcssOptions>> = Some(wgpu::render);
}
