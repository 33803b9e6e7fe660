//! The classic hard shadow map (Williams 1978), the baseline every soft-shadow paper compares
//! with: depth from the light centre rasterized into a `map_resolution`² map (`light_raster`),
//! then each eye sample projected into the map and compared with the stored depth, with a
//! slope-scaled bias ([`Bias`]) against self-shadowing (`eye_lookup`).
//!
//! The light's size is ignored: the shadow is the one a point light at its centre casts.

pub mod cpu;
pub mod wgpu;

use std::collections::BTreeMap;

use glam::Vec2;

use super::shadow_map::{parse_options, HardShadowOptions, LightView};
use crate::error::InputError;

pub const ID: &str = "hard_shadow_map";

pub fn check_options(options: &BTreeMap<String, serde_json::Value>) -> Result<(), InputError> {
    parse_options::<HardShadowOptions>(ID, options).map(|_| ())
}

/// The texel of the map that holds `uv` (nearest), or `None` outside the map, where nothing
/// was rasterized and the receiver counts as lit.
pub fn texel(view: &LightView, uv: Vec2) -> Option<(u32, u32)> {
    let r = view.resolution as f32;
    let (x, y) = ((uv.x * r).floor(), (uv.y * r).floor());
    (x >= 0.0 && y >= 0.0 && x < r && y < r).then_some((x as u32, y as u32))
}

/// The shadow test: a receiver at linear depth `z` is lit when no occluder in the map lies
/// nearer the light than `z − bias` (`map_ndc` is the map's stored NDC depth).
pub fn lit(view: &LightView, map_ndc: f32, z: f32, bias: f32) -> bool {
    z - bias <= view.linear_depth(map_ndc)
}
