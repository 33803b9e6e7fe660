//! Host geometry both executions of `soft_shadow_volume` share: the cached coverage textures,
//! each silhouette edge's wedge (III §3.1, IV §4.1) and the primitives of pass 2 (a wedge, or
//! its two halves when culling, IV §4.4).

use std::sync::{Arc, Mutex};

use super::{CoverageTexture, EmitterShape, Wedge};
use crate::algorithms::eye_raster::{ConvexVolume, EyeRays, ScreenRect};
use crate::algorithms::shadow_volume::ShadowQuad;
use crate::scene::adjacency::SilhouetteEdge;
use crate::scene::{Light, LightTexture};

/// Coverage textures are precomputed once per (shape, n, light texture), as the paper does
/// offline; a textured light's is RGB.
/// The run's `deadline` is checked after the light texture's hash and while a textured one is
/// built (a run stopped there caches nothing).
pub(super) fn coverage_texture(
    shape: EmitterShape,
    n: u32,
    light: Option<&LightTexture>,
    deadline: crate::util::deadline::Deadline,
) -> Arc<CoverageTexture> {
    static CACHE: Mutex<Vec<Arc<CoverageTexture>>> = Mutex::new(Vec::new());
    let hash = light.map(LightTexture::hash);
    deadline.check();
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(t) = cache
        .iter()
        .find(|t| t.shape == shape && t.n == n && t.light == hash)
    {
        return t.clone();
    }
    let t = Arc::new(match light {
        Some(l) => CoverageTexture::build_textured_until(l, n, deadline),
        None => CoverageTexture::build(shape, n),
    });
    cache.push(t.clone());
    t
}

/// The wedge of silhouette edge `e`: the tighter wedge of IV §4.1 for a rectangular light when
/// `tighter`, else the robust wedge of III §3.1 around the light's bounding sphere.
pub(super) fn build_wedge(
    e: &SilhouetteEdge,
    light: &Light,
    tighter: bool,
    reach: f32,
) -> Option<Wedge> {
    let centre = light.center();
    match (light, tighter) {
        (Light::Rect { half_u, half_v, .. }, true) => Wedge::tight_rect(
            e.a,
            e.b,
            [
                centre - *half_u - *half_v,
                centre + *half_u - *half_v,
                centre + *half_u + *half_v,
                centre - *half_u + *half_v,
            ],
            reach,
        ),
        _ => Wedge::robust(e.a, e.b, centre, bounding_radius(light), reach),
    }
}

/// Distance the wedges reach beyond their top edge: far enough to leave the scene bounds.
pub(super) fn wedge_reach(rays: &EyeRays) -> f32 {
    4.0 * rays.bounds.diagonal()
}

/// Radius of the sphere around the light that the robust wedges are built from.
fn bounding_radius(light: &Light) -> f32 {
    match *light {
        Light::Sphere { radius, .. } | Light::Disc { radius, .. } => radius,
        Light::Rect { half_u, half_v, .. } => (half_u + half_v).length(),
    }
}

/// One rasterized primitive of pass 2: a wedge, or one half of it when culling.
pub(super) struct WedgePrimitive {
    pub edge: usize,
    pub volume: ConvexVolume,
    /// The half's side of the hard shadow quad (−1 inner, +1 outer); `None` for a whole wedge.
    pub half: Option<f32>,
}

/// The primitives of pass 2 in submission order, with their screen footprints: per wedge, its
/// two halves split by the hard shadow quad's plane when `culling` (IV §4.4), else the whole
/// wedge.
pub(super) fn wedge_primitives(
    rays: &EyeRays,
    quads: &[ShadowQuad],
    wedges: &[Option<Wedge>],
    culling: bool,
) -> (Vec<WedgePrimitive>, Vec<Option<ScreenRect>>) {
    let mut prims = Vec::new();
    let mut footprints: Vec<Option<ScreenRect>> = Vec::new();
    for (k, w) in wedges.iter().enumerate() {
        let Some(w) = w else { continue };
        let fp = rays.footprint(&w.hull);
        if culling {
            let n = quads[k].normal.normalize_or_zero();
            let d = n.dot(quads[k].light);
            for side in [-1.0f32, 1.0] {
                let mut volume = w.volume.clone();
                volume.planes.push((n * side, d * side));
                prims.push(WedgePrimitive {
                    edge: k,
                    volume,
                    half: Some(-side),
                });
                footprints.push(fp);
            }
        } else {
            prims.push(WedgePrimitive {
                edge: k,
                volume: w.volume.clone(),
                half: None,
            });
            footprints.push(fp);
        }
    }
    (prims, footprints)
}
