//! `hard_shadow_map` on the CPU executions: the family's passes ([`shadow_map::cpu`]) with
//! the hard test, one tap at the receiver's own texel.
//!
//! [`shadow_map::cpu`]: crate::algorithms::shadow_map::cpu

use super::HardShadowOptions;
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::shadow_map::cpu::{
    render_views, umbra_test, Lookup, Receivers, ShadowMap, COMPARE_OPS,
};
use crate::algorithms::shadow_map::lit;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::{Lanes, Mask, Probe};

/// The hard shadow: one tap at the receiver's own texel.
pub struct HardLookup;

impl Lookup for HardLookup {
    fn visibility<P: Probe>(&self, p: &mut P, map: &ShadowMap, r: &Receivers) -> Lanes<f32> {
        let (d, inside) = map.tap(p, &r.uv, r.mask);
        p.vector(COMPARE_OPS, inside);
        let lit_lanes = Mask::from_fn(|l| lit(&map.view, d[l], r.z[l], r.bias[l]));
        umbra_test(inside, lit_lanes, |_| 1.0)
    }
}

/// `hard_shadow_map` on a CPU execution.
pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    o: &HardShadowOptions,
) -> Result<FrameOutput> {
    Ok(render_views(backend, frame, ctx, o.bias, &HardLookup))
}
