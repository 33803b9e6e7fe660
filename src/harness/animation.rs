//! Animated sweeps: a scenario's `animation` renders each run as a sequence of frames in which
//! the light's centre moves along a path, on every execution, with each frame's quality against
//! that frame's reference and the temporal figures of the sequence.
//!
//! Built: paths (linear, or a closed loop out and back, with an easing) for the light centre,
//! the light size and a generator's moving occluder's height above its ground (the objects
//! `occluder_height` places). Not built: paths for the camera or an arbitrary object's
//! transform; reuse of an execution's buffers between frames (each frame is one run of the
//! algorithm, as a single frame is; wgpu keeps its device and pipelines for the process, as it
//! does for any sweep).
//!
//! **Flicker** is the change between consecutive frames that the reference does not have:
//! the mean over the pixels that see a surface and over frames t = 1…N−1 of
//! |(V_t − V_{t−1}) − (R_t − R_{t−1})|, with V the run's visibility and R the reference's. Its
//! floor is the flicker of the reference against a reference of another seed: the sampling
//! noise of the reference itself.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;
use serde::{Deserialize, Serialize};
use serde_with::skip_serializing_none;

use crate::error::{Error, InputError, Result};
use crate::metrics::ErrorMetrics;
use crate::scene::Light;
use crate::visibility::VisibilityBuffer;

/// Frames an animation may have.
pub const FRAMES: std::ops::RangeInclusive<u32> = 2..=1024;

/// `$.animation` of a scenario: the frame count and at least one path.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Animation {
    /// Frames of the sequence, in [`FRAMES`].
    pub frames: u32,
    /// How the light's centre moves, from the scenario's light centre (world units).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_center: Option<Path3>,
    /// How the light's size (radius, or a rectangle's half-width) changes, from the run's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_size: Option<Path1>,
    /// How a generator's moving occluder's height above its ground changes (scene units, as
    /// `occluder_height`), from `from` (absent: the case's `occluder_height`, else the
    /// generator's own placement is kept at frame 0 and `from` must be given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub occluder_height: Option<Path1>,
}

/// A path of a point to `to`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Path3 {
    pub to: Vec3,
    #[serde(default)]
    pub path: PathKind,
    #[serde(default)]
    pub easing: Easing,
}

/// A path of a number from `from` (where given) to `to`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Path1 {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<f32>,
    pub to: f32,
    #[serde(default)]
    pub path: PathKind,
    #[serde(default)]
    pub easing: Easing,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PathKind {
    /// From the start (frame 0) to `to` (the last frame).
    #[default]
    Linear,
    /// A closed loop: out to `to` at mid-sequence and back, so the frame after the last would
    /// be frame 0 again (a sequence that plays in a loop without a jump).
    Loop,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Easing {
    /// Constant speed.
    #[default]
    Linear,
    /// Smoothstep 3s² − 2s³: at rest at both ends.
    EaseInOut,
}

impl Animation {
    /// Checks the frame count and the paths (one at least, a finite centre target); errors
    /// name `field` (`$.animation`). Sizes and heights are checked by the scenario
    /// (`crate::scenario::validate`) as its own light sizes and heights are.
    pub fn check(&self, field: &str) -> std::result::Result<(), InputError> {
        InputError::check_range(format!("{field}.frames"), self.frames, FRAMES)?;
        if self.light_center.is_none()
            && self.light_size.is_none()
            && self.occluder_height.is_none()
        {
            return Err(InputError::new(
                field,
                "an animation needs a path: light_center, light_size or occluder_height",
            ));
        }
        if let Some(c) = self.light_center.as_ref().filter(|c| !c.to.is_finite()) {
            return Err(InputError::new(
                format!("{field}.light_center.to"),
                format!("must be 3 finite numbers, got {}", c.to),
            ));
        }
        Ok(())
    }

    /// `light` (the run's light at frame 0) at frame `t`: its centre and size moved along
    /// their paths.
    pub fn light_at(&self, light: Light, t: u32) -> Light {
        let mut l = light;
        if let Some(c) = &self.light_center {
            let from = l.center();
            l = l.with_center(from + (c.to - from) * progress(c.path, c.easing, self.frames, t));
        }
        if let Some(s) = &self.light_size {
            l = l.with_size(s.at(light.size(), self.frames, t));
        }
        l
    }
}

impl Path1 {
    /// The value at frame `t` of `frames`, from `from` or else `start`.
    pub fn at(&self, start: f32, frames: u32, t: u32) -> f32 {
        let from = self.from.unwrap_or(start);
        from + (self.to - from) * progress(self.path, self.easing, frames, t)
    }
}

/// Where along a path of `frames` frames frame `t` is, 0 (start) to 1 (the target).
pub fn progress(path: PathKind, easing: Easing, frames: u32, t: u32) -> f32 {
    let n = frames.max(2);
    let u = match path {
        PathKind::Linear => t as f32 / (n - 1) as f32,
        PathKind::Loop => 1.0 - (2.0 * t as f32 / n as f32 - 1.0).abs(),
    };
    let u = u.clamp(0.0, 1.0);
    match easing {
        Easing::Linear => u,
        Easing::EaseInOut => u * u * (3.0 - 2.0 * u),
    }
}

/// The temporal figures of a run's sequence, in its record (`animation`).
#[skip_serializing_none]
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AnimationRecord {
    pub frames: u32,
    /// Each frame's quality against that frame's reference (no ꟻLIP or SSIM per frame).
    pub per_frame: Vec<ErrorMetrics>,
    /// Mean flicker over frames 1…N−1 (module docs); absent without a reference.
    pub flicker: Option<f64>,
    /// Flicker of each frame t = 1…N−1 against frame t − 1 (N − 1 values).
    #[serde(default)]
    pub flicker_per_frame: Vec<f64>,
    /// The frame of the largest flicker.
    pub flicker_max_frame: Option<u32>,
    /// The floor of the measure: flicker of the reference against a reference of another seed.
    pub flicker_floor: Option<f64>,
    /// Least-squares slope per frame of each per-frame metric (`mae`, `mae_shadow`,
    /// `mae_penumbra`, …): how the error drifts over the sequence.
    #[serde(default)]
    pub trend: BTreeMap<String, f64>,
}

/// Flicker of `v` against `r` (module docs) over the pixels that see a surface in both frames
/// of a transition (`masks`, one per frame): the mean over pixels and transitions, and each
/// transition's mean (frames 1…N−1; NaN for a transition without such pixels). `None` and no
/// values with fewer than two frames or no such pixel at all.
///
/// # Panics
/// When the sequences differ in length or a frame differs in size from its mask.
pub fn flicker(
    v: &[VisibilityBuffer],
    r: &[VisibilityBuffer],
    masks: &[Vec<bool>],
) -> (Option<f64>, Vec<f64>) {
    assert!(
        v.len() == r.len() && v.len() == masks.len(),
        "sequences differ in length"
    );
    if v.len() < 2 {
        return (None, vec![]);
    }
    let (mut total, mut pixels) = (0.0f64, 0u64);
    let per_frame: Vec<f64> = (1..v.len())
        .map(|t| {
            let (v0, v1, r0, r1) = (&v[t - 1].data, &v[t].data, &r[t - 1].data, &r[t].data);
            let (m0, m1) = (&masks[t - 1], &masks[t]);
            assert!(v1.len() == m1.len() && r1.len() == m1.len(), "frame size");
            let (mut sum, mut n) = (0.0f64, 0u64);
            for i in (0..m1.len()).filter(|&i| m0[i] && m1[i]) {
                sum += ((v1[i] as f64 - v0[i] as f64) - (r1[i] as f64 - r0[i] as f64)).abs();
                n += 1;
            }
            total += sum;
            pixels += n;
            if n > 0 {
                sum / n as f64
            } else {
                f64::NAN
            }
        })
        .collect();
    if pixels == 0 {
        return (None, vec![]);
    }
    let mean = total / pixels as f64;
    (mean.is_finite().then_some(mean), per_frame)
}

/// The least-squares slope of `values` against their index; `None` with fewer than two values
/// or one not finite.
pub fn slope(values: &[f64]) -> Option<f64> {
    let n = values.len();
    if n < 2 || values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mx = (n - 1) as f64 / 2.0;
    let my = values.iter().sum::<f64>() / n as f64;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, y) in values.iter().enumerate() {
        let dx = i as f64 - mx;
        sxy += dx * (y - my);
        sxx += dx * dx;
    }
    Some(sxy / sxx)
}

/// The record of a run's sequence `seq` (each frame's metrics against that frame's reference),
/// with the reference's own floor `floor`.
pub fn record(seq: &Rendered, floor: Option<f64>) -> AnimationRecord {
    let (v, r) = (&seq.visibility, &seq.reference);
    let per_frame: Vec<ErrorMetrics> = (0..v.len())
        .map(|t| {
            crate::metrics::compare_with_receivers(
                &v[t],
                &r[t],
                &seq.masks[t],
                &seq.receivers[t],
                &seq.grazing[t],
            )
        })
        .collect();
    let (flicker, flicker_per_frame) = flicker(v, r, &seq.masks);
    let flicker_max_frame = flicker_per_frame
        .iter()
        .enumerate()
        .filter(|(_, f)| f.is_finite())
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i as u32 + 1);
    let mut trend = BTreeMap::new();
    for (k, (name, _)) in ErrorMetrics::default().named().iter().enumerate() {
        let values: Option<Vec<f64>> = per_frame.iter().map(|m| m.named()[k].1).collect();
        if let Some(s) = values.as_deref().and_then(slope) {
            trend.insert(name.to_string(), s);
        }
    }
    AnimationRecord {
        frames: v.len() as u32,
        per_frame,
        flicker,
        flicker_per_frame,
        flicker_max_frame,
        flicker_floor: floor,
        trend,
    }
}

/// One run's sequence: its visibility per frame, the reference's, the run's shaded frames, and
/// the frames of the animated comparison (shaded run | shaded reference | error heat map).
pub struct Rendered {
    pub visibility: Vec<VisibilityBuffer>,
    pub reference: Vec<VisibilityBuffer>,
    pub shaded: Vec<image::RgbImage>,
    pub comparison: Vec<image::RgbImage>,
    /// Per frame, the pixels that see a surface (they change where an occluder moves).
    pub masks: Vec<Vec<bool>>,
    /// Per frame, the pixels on receiver-only surfaces.
    pub receivers: Vec<Vec<bool>>,
    /// Per frame, the grazing pixels (`Frame::grazing_mask`).
    pub grazing: Vec<Vec<bool>>,
}

/// The scenes of a sequence: `scene`, the run's (its light as the run takes it), with the
/// objects of frame `t` from `objects(t)` where an occluder moves (`None`: the scene's own),
/// rendered at `params`.
pub struct Scenes<'a> {
    pub scene: &'a crate::scene::Scene,
    pub objects: &'a dyn Fn(u32) -> Option<Vec<crate::scene::Object>>,
    pub params: &'a crate::frame::RunParams,
}

/// Frame `t` of `anim` for a run in `scenes`.
pub fn frame_at(anim: &Animation, scenes: &Scenes, t: u32) -> crate::frame::Frame {
    let mut sc = scenes.scene.clone();
    if let Some(objects) = (scenes.objects)(t) {
        sc.objects = objects;
    }
    sc.light = anim.light_at(sc.light, t);
    crate::frame::Frame::new(sc, scenes.params.clone())
}

/// Renders the sequence of `anim` for `algorithm` on `backend` (each frame one run of the
/// algorithm, as [`super::run_one`]'s first iteration), with each frame's reference from
/// `refs`. Errors: a frame's run failing (its error, naming the frame), the reference failing,
/// or the run's budget (`ctx.deadline`) passing.
pub fn render(
    anim: &Animation,
    scenes: &Scenes,
    algorithm: &crate::algorithms::Configured,
    backend: crate::backend::Backend,
    ctx: &crate::algorithms::ExecContext,
    refs: &mut super::ReferenceCache,
) -> Result<Rendered> {
    let mut seq = Rendered {
        visibility: vec![],
        reference: vec![],
        shaded: vec![],
        comparison: vec![],
        masks: vec![],
        receivers: vec![],
        grazing: vec![],
    };
    for t in 0..anim.frames {
        let frame = frame_at(anim, scenes, t);
        let r = super::within(|| refs.get_or_compute_until(&frame, ctx.deadline))
            .map_err(|_| {
                Error::Other(format!("frame {t}: its reference passed the run's budget"))
            })??
            .0;
        let v = super::iteration(&frame, algorithm, backend, ctx)
            .0
            .map_err(|e| Error::Other(format!("frame {t}: {e}")))?
            .visibility;
        let mask = frame.gbuffer.mask();
        let shaded = super::images::shaded_rgb(&v, &frame);
        let comparison = side_by_side(
            &[
                &shaded,
                &super::images::shaded_rgb(&r, &frame),
                &crate::metrics::error_heatmap(&v, &r, &mask),
            ],
            4,
        );
        seq.shaded.push(shaded);
        seq.comparison.push(comparison);
        seq.visibility.push(v);
        seq.reference.push(r);
        seq.masks.push(mask);
        seq.receivers.push(frame.receiver_only_mask());
        seq.grazing.push(frame.grazing_mask());
    }
    Ok(seq)
}

/// The reference's sequence of `anim` from `refs` (another seed than the runs' for the floor
/// of the flicker measure).
pub fn reference_sequence(
    anim: &Animation,
    scenes: &Scenes,
    refs: &mut super::ReferenceCache,
) -> Result<Vec<VisibilityBuffer>> {
    (0..anim.frames)
        .map(|t| Ok(refs.get_or_compute(&frame_at(anim, scenes, t))?.0))
        .collect()
}

/// Frames per second of the animated comparison.
pub const FPS: u16 = 8;

/// Writes a sequence into a run's image folder `dir`: `frames/shaded_NNN.png` and
/// `frames/visibility_NNN.npy` per frame, and `animation.png`, the animated comparison (APNG,
/// [`FPS`] frames per second: run | reference | error).
pub fn write(dir: &Path, seq: &Rendered) -> Result<()> {
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).map_err(|e| Error::io(&frames, e))?;
    for (t, (img, v)) in seq.shaded.iter().zip(&seq.visibility).enumerate() {
        let png = frames.join(format!("shaded_{t:03}.png"));
        img.save(&png)
            .map_err(|e| Error::Other(format!("{}: {e}", png.display())))?;
        v.write_npy(&frames.join(format!("visibility_{t:03}.npy")))?;
    }
    write_apng(&seq.comparison, FPS, &dir.join("animation.png"))
}

/// Writes `frames` (RGB images of one size) as an animated PNG (APNG, through the `png`
/// crate) at `fps` frames per second, looping forever.
pub fn write_apng(frames: &[image::RgbImage], fps: u16, path: &Path) -> Result<()> {
    let first = frames
        .first()
        .ok_or_else(|| Error::Other(format!("{}: no frames", path.display())))?;
    let err = |e: png::EncodingError| Error::Other(format!("{}: {e}", path.display()));
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), first.width(), first.height());
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_animated(frames.len() as u32, 0).map_err(err)?;
    enc.set_frame_delay(1, fps.max(1)).map_err(err)?;
    let mut w = enc.write_header().map_err(err)?;
    for f in frames {
        w.write_image_data(f.as_raw()).map_err(err)?;
    }
    w.finish().map_err(err)
}

/// Images side by side, left to right, on a gap of `gap` pixels of [`super::images::BACKGROUND`].
pub fn side_by_side(images: &[&image::RgbImage], gap: u32) -> image::RgbImage {
    let h = images.iter().map(|i| i.height()).max().unwrap_or(0);
    let w =
        images.iter().map(|i| i.width()).sum::<u32>() + gap * images.len().saturating_sub(1) as u32;
    let mut out = image::RgbImage::from_pixel(w, h, image::Rgb(super::images::BACKGROUND));
    let mut x = 0;
    for i in images {
        image::imageops::replace(&mut out, *i, x as i64, 0);
        x += i.width() + gap;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn buf(data: Vec<f32>) -> VisibilityBuffer {
        VisibilityBuffer {
            width: data.len() as u32,
            height: 1,
            data,
        }
    }

    #[test]
    fn flicker_counts_only_the_change_the_reference_does_not_have() {
        // The reference's shadow edge moves one pixel per frame; a run that follows it exactly
        // does not flicker, one that stays put flickers by the reference's change.
        let r = [
            buf(vec![1.0, 1.0, 0.0, 0.0]),
            buf(vec![1.0, 0.0, 0.0, 0.0]),
            buf(vec![0.0, 0.0, 0.0, 0.0]),
        ];
        let mask = vec![vec![true, true, true, false]; 3];
        assert_eq!(flicker(&r, &r, &mask), (Some(0.0), vec![0.0, 0.0]));
        let still = [r[0].clone(), r[0].clone(), r[0].clone()];
        // Frame 1: ΔR = −1 at pixel 1 (of 3 pixels); frame 2: −1 at pixel 0.
        let (mean, each) = flicker(&still, &r, &mask);
        assert_eq!(each, vec![1.0 / 3.0, 1.0 / 3.0]);
        assert!((mean.unwrap() - 1.0 / 3.0).abs() < 1e-12);
        // A run offset by a constant from the reference does not flicker either.
        let offset: Vec<VisibilityBuffer> = r
            .iter()
            .map(|b| buf(b.data.iter().map(|v| v * 0.5).collect()))
            .collect();
        assert_eq!(flicker(&offset, &offset, &mask).0, Some(0.0));
        // A pixel counts where it sees a surface in both frames of a transition: pixel 1,
        // hidden in frame 1, counts in neither transition.
        let masks = vec![
            vec![true, true, true, false],
            vec![true, false, true, false],
            vec![true, true, true, false],
        ];
        let (mean, each) = flicker(&still, &r, &masks);
        assert_eq!(each, vec![0.0, 1.0 / 2.0]);
        assert!((mean.unwrap() - 1.0 / 4.0).abs() < 1e-12);
        // One frame or no pixel: nothing to measure.
        assert_eq!(flicker(&r[..1], &r[..1], &mask[..1]), (None, vec![]));
        assert_eq!(
            flicker(&r, &r, &[vec![false; 4], vec![false; 4], vec![false; 4]]),
            (None, vec![])
        );
    }

    #[test]
    fn the_slope_of_a_line_is_its_gradient() {
        assert_eq!(slope(&[1.0, 3.0, 5.0, 7.0]), Some(2.0));
        assert_eq!(slope(&[4.0, 4.0]), Some(0.0));
        assert_eq!(slope(&[1.0]), None);
        assert_eq!(slope(&[1.0, f64::NAN]), None);
    }

    fn linear<T>(to: T) -> (T, PathKind, Easing) {
        (to, PathKind::Linear, Easing::Linear)
    }

    #[test]
    fn paths_start_at_the_light_and_end_or_turn_at_the_target() {
        let light = Light::Sphere {
            center: Vec3::new(1.0, 8.0, 0.5),
            radius: 0.6,
        };
        let (to, path, easing) = linear(Vec3::new(-1.0, 8.0, 0.5));
        let mut a = Animation {
            frames: 5,
            light_center: Some(Path3 { to, path, easing }),
            light_size: None,
            occluder_height: None,
        };
        let x = |a: &Animation, t| a.light_at(light, t).center().x;
        assert_eq!(
            [0, 1, 2, 3, 4].map(|t| x(&a, t)),
            [1.0, 0.5, 0.0, -0.5, -1.0]
        );
        assert_eq!(a.light_at(light, 3).size(), 0.6);
        // A loop of 4 frames: out to the target at frame 2 and back; frame 4 would be frame 0.
        a.frames = 4;
        a.light_center.as_mut().unwrap().path = PathKind::Loop;
        assert_eq!([0, 1, 2, 3].map(|t| x(&a, t)), [1.0, 0.0, -1.0, 0.0]);
        // Easing keeps the ends and the middle, and starts slower.
        a.frames = 5;
        let c = a.light_center.as_mut().unwrap();
        (c.path, c.easing) = (PathKind::Linear, Easing::EaseInOut);
        assert_eq!([0, 2, 4].map(|t| x(&a, t)), [1.0, 0.0, -1.0]);
        assert!(x(&a, 1) > 0.5);
        // A growing light: its size from the run's (0.6) to 1.0, its centre kept.
        let (to, path, easing) = linear(1.0);
        a.light_center = None;
        a.light_size = Some(Path1 {
            from: None,
            to,
            path,
            easing,
        });
        assert_eq!(a.light_at(light, 4).size(), 1.0);
        assert!((a.light_at(light, 2).size() - 0.8).abs() < 1e-6);
        assert_eq!(a.light_at(light, 2).center(), light.center());
        // A height from its own start.
        let h = Path1 {
            from: Some(2.0),
            to: 0.0,
            path,
            easing,
        };
        assert_eq!([0, 2, 4].map(|t| h.at(9.0, 5, t)), [2.0, 1.0, 0.0]);
    }

    #[test]
    fn bad_animations_are_refused_naming_the_field() {
        let (to, path, easing) = linear(Vec3::ZERO);
        let mut a = Animation {
            frames: 1,
            light_center: Some(Path3 { to, path, easing }),
            light_size: None,
            occluder_height: None,
        };
        let e = a.check("$.animation").unwrap_err().to_string();
        assert!(e.contains("$.animation.frames"), "{e}");
        a.frames = 8;
        a.light_center.as_mut().unwrap().to = Vec3::new(f32::NAN, 0.0, 0.0);
        let e = a.check("$.animation").unwrap_err().to_string();
        assert!(e.contains("$.animation.light_center.to"), "{e}");
        a.light_center = None;
        let e = a.check("$.animation").unwrap_err().to_string();
        assert!(e.contains("needs a path"), "{e}");
    }
}
