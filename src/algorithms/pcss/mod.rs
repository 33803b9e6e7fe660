//! `pcss`: percentage-closer soft shadows (Fernando 2005) — blocker search, penumbra estimate,
//! variable-width PCF. The formulas are in [`super::shadow_map`].

pub mod wgpu;

/// Registry id.
pub const ID: &str = "pcss";
