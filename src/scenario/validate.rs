//! Semantic checks of a parsed scenario, and the parameter checks the CLI shares with it.
//! Each check names the JSON path (or option) and the value it rejects.

use glam::Vec3;

use super::Scenario;
use crate::algorithms::{self, Backend};
use crate::error::{unknown_name, InputError};
use crate::scene::generators;
use crate::scene::Light;

type Check = Result<(), InputError>;

fn fail(field: &str, msg: String) -> Check {
    Err(InputError::new(field, msg))
}

fn finite_positive(field: &str, what: &str, v: f32) -> Check {
    if !v.is_finite() || v <= 0.0 {
        return fail(
            field,
            format!("{what} must be a finite number > 0, got {v}"),
        );
    }
    Ok(())
}

/// A light's size (radius, half-width): finite, > 0 and within the coordinate range the
/// algorithms hold ([`crate::scene::load::MAX_COORDINATE`], 2^40); larger ones overflow the
/// emitter's `f32` geometry (a rectangle's half-axis length, its area).
fn light_extent(field: &str, what: &str, v: f32) -> Check {
    use crate::scene::load::MAX_COORDINATE;
    finite_positive(field, what, v)?;
    if v > MAX_COORDINATE {
        return fail(
            field,
            format!("{what} must be at most {MAX_COORDINATE:.3e} (2^40), got {v:e}"),
        );
    }
    Ok(())
}

/// A finite vector within the coordinate range the algorithms hold
/// ([`crate::scene::load::MAX_COORDINATE`], 2^40).
fn finite_vec(field: &str, v: Vec3) -> Check {
    use crate::scene::load::MAX_COORDINATE;
    if !v.is_finite() {
        return fail(field, format!("must be finite, got {v}"));
    }
    if v.abs().max_element() > MAX_COORDINATE {
        return fail(
            field,
            format!("must be within ±{MAX_COORDINATE:.3e} (2^40), got {v}"),
        );
    }
    Ok(())
}

pub fn light_size(field: &str, v: f32) -> Check {
    light_extent(field, "light size", v)
}

/// Largest map or image side accepted (a 16384² f32 map is 1 GiB).
pub const MAX_RESOLUTION: u32 = 16_384;

pub fn map_resolution(field: &str, v: u32) -> Check {
    InputError::check_range(field, v, 1..=MAX_RESOLUTION)
}

pub fn tile_size(field: &str, v: u32) -> Check {
    if !(8..=256).contains(&v) || !v.is_multiple_of(crate::model::raster::BLOCK) {
        return fail(
            field,
            format!("tile size must be a multiple of 4 (whole 4×4 blocks) in 8..=256, got {v}"),
        );
    }
    Ok(())
}

pub fn image(field: &str, v: [u32; 2]) -> Check {
    if v[0] == 0 || v[1] == 0 || v[0] > MAX_RESOLUTION || v[1] > MAX_RESOLUTION {
        return fail(
            field,
            format!(
                "image must be WxH with both sides in 1..={MAX_RESOLUTION}, got {}x{}",
                v[0], v[1]
            ),
        );
    }
    Ok(())
}

pub fn triangles(field: &str, v: u32) -> Check {
    InputError::check_range(field, v, 1..=50_000_000)
}

/// Largest occluder height accepted, in scene units above the ground: beyond it the occluder
/// is far above every built-in scene and its light (and far past what f32 keeps of the
/// scene's detail at 1e30).
pub const MAX_OCCLUDER_HEIGHT: f32 = 100.0;

pub fn occluder_height(field: &str, v: f32) -> Check {
    InputError::check_range(field, v, 0.0..=MAX_OCCLUDER_HEIGHT)
}

/// Largest lateral occluder offset accepted, in scene units either way: beyond it the occluder
/// is far outside every built-in scene (their grounds span at most ±30 units).
pub const MAX_OCCLUDER_OFFSET: f32 = 100.0;

pub fn occluder_offset(field: &str, v: f32) -> Check {
    InputError::check_range(field, v, -MAX_OCCLUDER_OFFSET..=MAX_OCCLUDER_OFFSET)
}

/// How a sweep moves a generator's occluder: up (`occluder_height`) or sideways
/// (`occluder_offset`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OccluderAxis {
    Height,
    Offset,
}

impl OccluderAxis {
    fn what(self) -> &'static str {
        match self {
            OccluderAxis::Height => "an occluder height",
            OccluderAxis::Offset => "an occluder offset",
        }
    }

    fn moves(self, g: &generators::Generator) -> bool {
        match self {
            OccluderAxis::Height => g.moves_vertically,
            OccluderAxis::Offset => g.moves_laterally,
        }
    }
}

/// An occluder height or offset needs a generator scene whose occluder it moves
/// ([`generators::Generator::moves_vertically`], [`generators::Generator::moves_laterally`]);
/// `generator` is the scene's, if any.
pub fn occluder_axis_scene(field: &str, generator: Option<&str>, axis: OccluderAxis) -> Check {
    let movable: Vec<&str> = generators::GENERATORS
        .iter()
        .filter(|g| axis.moves(g))
        .map(|g| g.name)
        .collect();
    let what = axis.what();
    match generator.and_then(generators::find) {
        Some(g) if axis.moves(g) => Ok(()),
        Some(g) => fail(
            field,
            format!(
                "scene '{}' has no moving occluder for {what}; {what} needs one of: {}",
                g.name,
                movable.join(", ")
            ),
        ),
        None => fail(
            field,
            format!(
                "{what} needs a generator scene with a moving occluder, one of: {}",
                movable.join(", ")
            ),
        ),
    }
}

pub fn cores(field: &str, v: u32) -> Check {
    InputError::check_range(field, v, 1..=64)
}

pub fn reference_samples(field: &str, v: u32) -> Check {
    if algorithms::reference::strata_side(v).is_none() || v > 65_536 {
        return fail(
            field,
            format!("sample count must be a perfect square in 1..=65536 (e.g. 256, 1024), got {v}"),
        );
    }
    Ok(())
}

/// A textured light must be rectangular (Paper III §3.3 textures rectangles; it has not tried
/// spherical textured lights) and every algorithm must honour the texture.
pub fn light_texture(
    field: &str,
    l: &Light,
    algorithms: &[String],
    options: &std::collections::BTreeMap<String, serde_json::Value>,
) -> Check {
    if !matches!(l, Light::Rect { .. }) {
        return fail(
            field,
            format!(
                "a light texture needs a rectangular light (type rect), got type {}",
                l.kind()
            ),
        );
    }
    for a in algorithms {
        algorithms::check_light_texture(a, options)?;
    }
    Ok(())
}

pub fn light(field: &str, l: &Light) -> Check {
    finite_vec(&format!("{field}.center"), l.center())?;
    match *l {
        Light::Sphere { radius, .. } => light_extent(&format!("{field}.radius"), "radius", radius),
        Light::Disc { normal, radius, .. } => {
            finite_vec(&format!("{field}.normal"), normal)?;
            if normal.length_squared() == 0.0 {
                return fail(&format!("{field}.normal"), "normal must be non-zero".into());
            }
            light_extent(&format!("{field}.radius"), "radius", radius)
        }
        Light::Rect { half_u, half_v, .. } => {
            finite_vec(&format!("{field}.half_u"), half_u)?;
            finite_vec(&format!("{field}.half_v"), half_v)?;
            finite_positive(
                &format!("{field}.half_u"),
                "half-axis length",
                half_u.length(),
            )?;
            finite_positive(
                &format!("{field}.half_v"),
                "half-axis length",
                half_v.length(),
            )?;
            if half_u.normalize().dot(half_v.normalize()).abs() > 1e-3 {
                return fail(
                    &format!("{field}.half_v"),
                    "half-axes must be orthogonal".into(),
                );
            }
            Ok(())
        }
    }
}

pub fn backend(field: &str, name: &str) -> Result<Backend, InputError> {
    Backend::parse(name).map_err(|m| InputError::new(field, m))
}

pub fn algorithm(field: &str, id: &str) -> Check {
    algorithms::find(id)
        .map(|_| ())
        .map_err(|m| InputError::new(field, m))
}

/// All semantic checks of a scenario.
pub fn validate(s: &Scenario) -> Check {
    if let Some(name) = &s.name {
        // The name becomes a folder under `--out` (as a slug); a path here is a mistake.
        crate::util::paths::check_name("$.name", name)?;
    }
    scene(s)?;
    if let Some(c) = &s.camera {
        camera(c)?;
    }
    if let Some(l) = &s.light {
        light("$.light", &l.light)?;
    }
    super::claims::validate(&s.claims)?;
    algorithms_and_backends(s)?;
    params(&s.params)?;
    sweep(&s.sweep)?;
    occluder_axes(s)?;
    reference_samples("$.reference.samples", s.reference.samples)?;
    optional(
        "$.reference.flip_pixels_per_degree",
        s.reference.flip_pixels_per_degree,
        crate::metrics::perceptual::check_pixels_per_degree,
    )?;
    if let Some(m) = &s.measure {
        m.check("$.measure")?;
    }
    if let Some(a) = &s.animation {
        a.check("$.animation")?;
        if let Some(l) = &a.light_size {
            optional("$.animation.light_size.from", l.from, light_size)?;
            light_size("$.animation.light_size.to", l.to)?;
        }
        if let Some(h) = &a.occluder_height {
            occluder_axis_scene(
                "$.animation.occluder_height",
                s.scene.generator.as_deref(),
                OccluderAxis::Height,
            )?;
            optional("$.animation.occluder_height.from", h.from, occluder_height)?;
            occluder_height("$.animation.occluder_height.to", h.to)?;
            if h.from.is_none() && s.params.occluder_height.is_none() {
                return fail(
                    "$.animation.occluder_height",
                    "needs a start: `from`, or params.occluder_height".into(),
                );
            }
        }
        if !s.reference.enabled {
            return fail(
                "$.animation",
                "an animation measures flicker against the reference: it needs \
                 reference.enabled true"
                    .into(),
            );
        }
    }
    optional("$.run_timeout_s", s.run_timeout_s, run_timeout)
}

/// Runs `check` on `value` if there is one.
fn optional<T>(field: &str, value: Option<T>, check: fn(&str, T) -> Check) -> Check {
    value.map_or(Ok(()), |v| check(field, v))
}

/// `$.scene`: a known generator, or user objects with finite placements (and then no triangle
/// count).
fn scene(s: &Scenario) -> Check {
    if !s.sweep.meshes.is_empty() && s.scene.objects.is_none() {
        return fail(
            "$.sweep.meshes",
            "a mesh sweep replaces the mesh of scene.objects[0]; the scene has no objects".into(),
        );
    }
    match (&s.scene.generator, &s.scene.objects) {
        (Some(_), Some(_)) => fail(
            "$.scene",
            "give either `generator` or `objects`, not both".into(),
        ),
        (None, None) => fail("$.scene", "needs `generator` or `objects`".into()),
        (Some(g), None) => match generators::find(g) {
            Some(_) => Ok(()),
            None => fail(
                "$.scene.generator",
                unknown_name("scene generator", g, &generators::names()),
            ),
        },
        (None, Some(objs)) => {
            if objs.is_empty() {
                return fail("$.scene.objects", "needs at least one object".into());
            }
            for (i, o) in objs.iter().enumerate() {
                let f = |k: &str| format!("$.scene.objects[{i}].{k}");
                optional(&f("translate"), o.translate, finite_vec)?;
                optional(&f("rotate_deg"), o.rotate_deg, finite_vec)?;
                if let Some(sc) = o.scale {
                    finite_positive(&f("scale"), "scale", sc)?;
                }
            }
            // The field the count was given in: `params` first, as a sweep extends it.
            let given = if s.params.triangles.is_some() {
                Some("$.params.triangles")
            } else {
                (!s.sweep.triangles.is_empty()).then_some("$.sweep.triangles")
            };
            if let Some(field) = given {
                return fail(
                    field,
                    "a triangle count needs a generator scene (user meshes have a fixed count; \
                     sweep.meshes sweeps over mesh files, e.g. levels of detail)"
                        .into(),
                );
            }
            Ok(())
        }
    }
}

/// `$.camera`: finite, a view direction not along `up`, a field of view in (0, 180) degrees.
fn camera(c: &crate::scene::Camera) -> Check {
    finite_vec("$.camera.eye", c.eye)?;
    finite_vec("$.camera.target", c.target)?;
    finite_vec("$.camera.up", c.up)?;
    if (c.target - c.eye).length_squared() == 0.0 {
        return fail("$.camera.target", "target must differ from eye".into());
    }
    if (c.target - c.eye).cross(c.up).length_squared() == 0.0 {
        return fail(
            "$.camera.up",
            "up must not be parallel to the view direction".into(),
        );
    }
    if !(c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0) {
        return fail(
            "$.camera.fov_y_deg",
            format!(
                "field of view must be in (0, 180) degrees, got {}",
                c.fov_y_deg
            ),
        );
    }
    Ok(())
}

/// `$.algorithms`, `$.backends`, `$.options` and the light texture: known names, at least one
/// of each and none twice (the plan would count a run it never makes), options each algorithm
/// accepts.
fn algorithms_and_backends(s: &Scenario) -> Check {
    if s.algorithms.is_empty() {
        return fail("$.algorithms", "needs at least one algorithm".into());
    }
    for (i, a) in s.algorithms.iter().enumerate() {
        algorithm(&format!("$.algorithms[{i}]"), a)?;
        once("$.algorithms", &s.algorithms, i)?;
    }
    if s.backends.is_empty() {
        return fail("$.backends", "needs at least one backend".into());
    }
    for (i, b) in s.backends.iter().enumerate() {
        backend(&format!("$.backends[{i}]"), b)?;
        once("$.backends", &s.backends, i)?;
    }
    for k in s.options.keys() {
        algorithm(&format!("$.options.{k}"), k)?;
        let info = algorithms::find(k).expect("checked above");
        info.check_options(&s.options)?;
    }
    if let Some(l) = s.light.as_ref().filter(|l| l.texture.is_some()) {
        light_texture("$.light.texture", &l.light, &s.algorithms, &s.options)?;
    }
    Ok(())
}

/// `$.params`: each parameter given in its range.
fn params(p: &super::BaseParams) -> Check {
    optional("$.params.triangles", p.triangles, triangles)?;
    optional("$.params.light_size", p.light_size, light_size)?;
    map_resolution("$.params.map_resolution", p.map_resolution)?;
    tile_size("$.params.tile_size", p.tile_size)?;
    image("$.params.image", p.image)?;
    optional(
        "$.params.occluder_height",
        p.occluder_height,
        occluder_height,
    )?;
    optional(
        "$.params.occluder_offset",
        p.occluder_offset,
        occluder_offset,
    )?;
    optional("$.params.cores", p.cores, cores)
}

/// Entry `i` of list `field` is not an earlier entry's repeat.
fn once<T: PartialEq + std::fmt::Display>(field: &str, list: &[T], i: usize) -> Check {
    match list[..i].iter().position(|x| *x == list[i]) {
        Some(j) => fail(
            &format!("{field}[{i}]"),
            format!("'{}' is already {field}[{j}]", list[i]),
        ),
        None => Ok(()),
    }
}

/// `$.sweep`: every swept value in the range of its parameter.
fn sweep(w: &super::Sweep) -> Check {
    fn each<T: Copy>(name: &str, values: &[T], check: fn(&str, T) -> Check) -> Check {
        (values.iter().enumerate())
            .try_for_each(|(i, &v)| check(&format!("$.sweep.{name}[{i}]"), v))
    }
    each("triangles", &w.triangles, triangles)?;
    each("light_size", &w.light_size, light_size)?;
    each("map_resolution", &w.map_resolution, map_resolution)?;
    each("tile_size", &w.tile_size, tile_size)?;
    each("image", &w.image, image)?;
    each("occluder_height", &w.occluder_height, occluder_height)?;
    each("occluder_offset", &w.occluder_offset, occluder_offset)?;
    each("cores", &w.cores, cores)
}

/// An occluder height or offset, fixed or swept, needs a generator whose occluder it moves.
fn occluder_axes(s: &Scenario) -> Check {
    let (p, w) = (&s.params, &s.sweep);
    let generator = s.scene.generator.as_deref();
    for (axis, name, fixed, swept) in [
        (
            OccluderAxis::Height,
            "occluder_height",
            p.occluder_height.is_some(),
            !w.occluder_height.is_empty(),
        ),
        (
            OccluderAxis::Offset,
            "occluder_offset",
            p.occluder_offset.is_some(),
            !w.occluder_offset.is_empty(),
        ),
    ] {
        for (given, field) in [(fixed, "params"), (swept, "sweep")] {
            if given {
                occluder_axis_scene(&format!("$.{field}.{name}"), generator, axis)?;
            }
        }
    }
    Ok(())
}

/// A run's time budget in seconds: finite and > 0 (at most a year, so that it is a duration).
pub fn run_timeout(field: &str, seconds: f64) -> Check {
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 3.2e7) {
        return fail(
            field,
            format!("run timeout must be a number of seconds in (0, 3.2e7], got {seconds}"),
        );
    }
    Ok(())
}
