//! PCSS on the CPU executions: the light pass and receiver setup of the hard shadow map, with
//! the blocker search and the variable-width filter as the eye pass's [`Lookup`].

use glam::Vec2;

use super::PcssOptions;
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::shadow_map::cpu::{render_views, Lookup, Receivers, ShadowMap, COMPARE_OPS};
use crate::algorithms::shadow_map::lit;
use crate::algorithms::shadow_map::{
    pcss_filter_radius_uv, pcss_search_radius_uv, vogel_disk, ReceiverPlane,
};
use crate::error::Result;
use crate::frame::Frame;
use crate::model::{Lanes, Mask, Probe, LANES};

/// Vector instructions per block to turn the blocker sum into the filter radius: search radius
/// (subtract, 2 multiplies, divide), average (divide), filter radius (subtract, 2 multiplies,
/// 2 divides), the no-blocker select.
const RADIUS_OPS: u32 = 11;
/// The receiver-plane test of a blocker ([`ReceiverPlane`], its view-space plane once per
/// block): the ray's two slopes (2 multiply-adds), the plane's 1/depth (2 multiply-adds and a
/// multiply), its reciprocal, the select and the min.
const PLANE_OPS: u32 = 8;
/// Accumulating a blocker: masked add of its depth and of the count.
const BLOCKER_ACCUMULATE_OPS: u32 = 2;

struct PcssLookup {
    options: PcssOptions,
    light_radius: f32,
    /// The blocker search's and the filter's tap offsets on the unit disc ([`vogel_disk`]):
    /// constants of the pass, as a shader holds them.
    search_taps: Vec<Vec2>,
    filter_taps: Vec<Vec2>,
}

impl Lookup for PcssLookup {
    fn visibility<P: Probe>(&self, p: &mut P, map: &ShadowMap, r: &Receivers) -> Lanes<f32> {
        let view = &map.view;
        let nf = self.options.pcf_samples;
        // Step 1: blocker search.
        let search: Lanes<f32> = std::array::from_fn(|l| {
            pcss_search_radius_uv(view, self.light_radius, r.z[l].max(view.near))
        });
        let (mut sum, mut count) = ([0f32; LANES], [0u32; LANES]);
        let planes: Lanes<ReceiverPlane> =
            std::array::from_fn(|l| ReceiverPlane::new(view, r.position[l], r.normal[l]));
        for &o in &self.search_taps {
            let uv: Lanes<Vec2> = std::array::from_fn(|l| r.uv[l] + o * search[l]);
            let (d, inside) = map.tap(p, &uv, r.mask);
            p.vector(COMPARE_OPS + PLANE_OPS + BLOCKER_ACCUMULATE_OPS, inside);
            for l in inside.lanes() {
                let zb = view.linear_depth(d[l]);
                let plane = planes[l].depth_at(view, uv[l]);
                if !lit(view, d[l], r.z[l].min(plane), r.bias[l]) {
                    sum[l] += zb;
                    count[l] += 1;
                }
            }
        }
        p.vector(RADIUS_OPS, r.mask);
        // Step 2: penumbra width; lanes without blockers are lit.
        let filtering = r.mask.and(Mask::from_fn(|l| count[l] > 0));
        let radius: Lanes<f32> = std::array::from_fn(|l| {
            if filtering.get(l) {
                pcss_filter_radius_uv(view, self.light_radius, r.z[l], sum[l] / count[l] as f32)
            } else {
                0.0
            }
        });
        // Step 3: percentage-closer filter.
        let mut lit_taps = [0u32; LANES];
        if filtering.any() {
            for &o in &self.filter_taps {
                let uv: Lanes<Vec2> = std::array::from_fn(|l| r.uv[l] + o * radius[l]);
                let (d, inside) = map.tap(p, &uv, filtering);
                p.vector(COMPARE_OPS + 1, filtering);
                for l in filtering.lanes() {
                    lit_taps[l] += u32::from(!inside.get(l) || lit(view, d[l], r.z[l], r.bias[l]));
                }
            }
        }
        std::array::from_fn(|l| {
            if filtering.get(l) {
                lit_taps[l] as f32 / nf as f32
            } else {
                1.0
            }
        })
    }
}

/// `pcss` on a CPU execution.
pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    options: &PcssOptions,
) -> Result<FrameOutput> {
    let (nb, nf) = (options.blocker_samples, options.pcf_samples);
    let lookup = PcssLookup {
        options: *options,
        light_radius: frame.scene.light.size(),
        search_taps: (0..nb).map(|i| vogel_disk(i, nb)).collect(),
        filter_taps: (0..nf).map(|i| vogel_disk(i, nf)).collect(),
    };
    Ok(render_views(backend, frame, ctx, options.bias, &lookup))
}
