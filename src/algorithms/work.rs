//! Work estimates made before a run, beside the memory estimate: the *fill* an algorithm will
//! generate (fragments, texels or samples rasterised or tested, the design's unit), from the run
//! parameters, the scene's light and bounds, and the algorithm's options.
//!
//! These are *estimated* figures (the third kind of cost figure, never mixed with measured or
//! modelled ones): first-order formulas for the order of magnitude, not calibrated predictions.
//! The one quantity they share is the width of a penumbra in texels of a map (or pixels of an
//! image) that frames the scene, [`penumbra_texels`]; the cost of the soft algorithms grows with
//! it (002's penumbra extents, 000's cones and sheets, 001's wedges, 003's volumes, 004's
//! penumbra quads), which is what makes a wide light at a fine map a runaway run (002 at a map
//! of 512² with a light 1.5 units wide took minutes). The harness reports the estimate of a
//! run stopped by `--run-timeout`, and the total of a sweep before it starts.

use glam::Vec3;

use crate::frame::RunParams;
use crate::scene::{Light, Scene};

/// What the estimates look at in a scene: its light, the centre of its bounds and the texels
/// of its light texture (0 without one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneExtent {
    pub light: Light,
    pub center: Vec3,
    pub light_texels: f64,
}

impl SceneExtent {
    pub fn of(scene: &Scene) -> SceneExtent {
        SceneExtent {
            light: scene.light,
            center: scene.bounds().center(),
            light_texels: texture_texels(scene),
        }
    }
}

/// The texels of `scene`'s light texture, 0 without one.
pub fn texture_texels(scene: &Scene) -> f64 {
    scene
        .light_texture
        .as_ref()
        .map_or(0.0, |t| f64::from(t.width) * f64::from(t.height))
}

/// What every run of a frame does besides its algorithm, in the same unit: the eye pass (one
/// ray per pixel) and one pass over the light texture's texels (its mean, its hash in cache
/// keys, its filtering), which a 4096² texture makes 1.7·10⁷.
pub fn frame(scene: &SceneExtent, p: &RunParams) -> f64 {
    pixels(p) + scene.light_texels
}

/// Width in texels of the penumbra of a typical occluder, in a map of `resolution` texels that
/// frames the scene as seen from the light: by similar triangles the penumbra is the light's
/// width `2·size` times `(d_r − d_o) / d_o`; with the receivers about a scene half-diagonal
/// behind the occluders and the map spanning about the scene diagonal, that is
/// `resolution · size / d`, `d` the light's distance to the scene centre. Clamped to
/// `[0, resolution]` (a penumbra wider than the map covers the map).
pub fn penumbra_texels(scene: &SceneExtent, resolution: u32) -> f64 {
    let d = f64::from((scene.center - scene.light.center()).length());
    let size = f64::from(scene.light.size());
    let w = f64::from(resolution) * size / d.max(1e-6);
    if w.is_finite() {
        w.clamp(0.0, f64::from(resolution))
    } else {
        f64::from(resolution)
    }
}

/// Pixels of the run's image.
pub fn pixels(p: &RunParams) -> f64 {
    f64::from(p.image[0]) * f64::from(p.image[1])
}

/// Texels of the run's light map (`map_resolution²`).
pub fn texels(p: &RunParams) -> f64 {
    f64::from(p.map_resolution) * f64::from(p.map_resolution)
}

/// Silhouette primitives drawn into a map or image of `resolution` texels across: the outline
/// of the occluders (about twice the resolution long) times the penumbra's width.
pub fn outline(scene: &SceneExtent, resolution: u32) -> f64 {
    2.0 * f64::from(resolution) * (1.0 + penumbra_texels(scene, resolution))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::algorithm::ExecContext;
    use crate::scene::generators::{self, GeneratorParams};

    fn scene(light_size: f32) -> SceneExtent {
        let mut s = generators::find("sphere-on-plane")
            .unwrap()
            .build(&GeneratorParams::default());
        s.light = s.light.with_size(light_size);
        SceneExtent::of(&s)
    }

    fn params(map: u32) -> RunParams {
        RunParams {
            triangles: 1000,
            light_size: 1.5,
            map_resolution: map,
            tile_size: 32,
            image: [160, 120],
            occluder_height: None,
            occluder_offset: None,
            cores: None,
        }
    }

    #[test]
    fn a_runs_work_grows_with_its_light_texture() {
        let ctx = ExecContext {
            reference_samples: 16,
            ..Default::default()
        };
        let p = RunParams {
            image: [48, 36],
            ..params(64)
        };
        let with = |side: f64| {
            let e = SceneExtent {
                light_texels: side * side,
                ..scene(0.5)
            };
            frame(&e, &p) + crate::algorithms::reference::work_estimate(&e, &p, &ctx, &())
        };
        // The eye pass and the samples: 48 × 36 × (1 + 16).
        assert_eq!(with(0.0), 48.0 * 36.0 * 17.0);
        // Each texel once more.
        assert_eq!(with(4096.0) - with(0.0), 4096.0 * 4096.0);
        assert!(with(4096.0) > with(1024.0) && with(1024.0) > with(64.0));
    }

    #[test]
    fn a_penumbra_widens_with_the_light_and_the_map() {
        let (small, wide) = (scene(0.1), scene(1.5));
        assert!(penumbra_texels(&wide, 512) > 10.0 * penumbra_texels(&small, 512));
        assert!(penumbra_texels(&wide, 512) > 1.9 * penumbra_texels(&wide, 256));
        assert!(penumbra_texels(&scene(1e30), 512) <= 512.0);
    }

    #[test]
    fn soft_shadow_map_work_grows_with_the_fourth_power_of_the_map_at_a_wide_light() {
        let ctx = ExecContext::default();
        let o = crate::algorithms::soft_shadow_map::SoftShadowMapOptions::default();
        let estimate = crate::algorithms::soft_shadow_map::work_estimate;
        let wide = scene(1.5);
        let r = estimate(&wide, &params(512), &ctx, &o) / estimate(&wide, &params(128), &ctx, &o);
        // texels × extent²: 4² × about 4² once the penumbra dominates the extent.
        assert!(r > 100.0 && r < 300.0, "{r}");
    }
}
