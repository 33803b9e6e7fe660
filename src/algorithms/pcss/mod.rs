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

use super::shadow_map::{parse_options, PcssOptions};
use crate::error::InputError;

pub const ID: &str = "pcss";

pub fn options(options: &BTreeMap<String, serde_json::Value>) -> Result<PcssOptions, InputError> {
    let o: PcssOptions = parse_options(ID, options)?;
    o.validate(ID)?;
    Ok(o)
}

pub fn check_options(o: &BTreeMap<String, serde_json::Value>) -> Result<(), InputError> {
    options(o).map(|_| ())
}
