//! Animated sweeps: a scenario's `animation` renders each run as a sequence of frames in which
//! the light's centre moves along a path, on every execution, with each frame's quality against
//! that frame's reference and the temporal figures of the sequence.
//!
//! Built: a path for the light centre (linear, or a closed loop out and back, with an easing).
//! Not built: paths for the light size, the camera or an object's transform; reuse of an
//! execution's buffers between frames (each frame is one run of the algorithm, as a single
//! frame is; wgpu keeps its device and pipelines for the process, as it does for any sweep).
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

/// `$.animation` of a scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Animation {
    /// Frames of the sequence, in [`FRAMES`].
    pub frames: u32,
    /// How the light's centre moves, from the scenario's light centre.
    pub light_center: CenterPath,
}

/// A path of the light's centre from where the scenario puts it to `to` (world units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CenterPath {
    pub to: Vec3,
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
    /// Checks the frame count and the target; errors name `field` (`$.animation`).
    pub fn check(&self, field: &str) -> std::result::Result<(), InputError> {
        InputError::check_range(format!("{field}.frames"), self.frames, FRAMES)?;
        if !self.light_center.to.is_finite() {
            return Err(InputError::new(
                format!("{field}.light_center.to"),
                format!("must be 3 finite numbers, got {}", self.light_center.to),
            ));
        }
        Ok(())
    }

    /// Where along the path frame `t` is, 0 (start) to 1 (`to`).
    pub fn progress(&self, t: u32) -> f32 {
        let n = self.frames.max(2);
        let u = match self.light_center.path {
            PathKind::Linear => t as f32 / (n - 1) as f32,
            PathKind::Loop => 1.0 - (2.0 * t as f32 / n as f32 - 1.0).abs(),
        };
        let u = u.clamp(0.0, 1.0);
        match self.light_center.easing {
            Easing::Linear => u,
            Easing::EaseInOut => u * u * (3.0 - 2.0 * u),
        }
    }

    /// `light` (the run's light at frame 0) at frame `t`: its centre moved along the path.
    pub fn light_at(&self, light: Light, t: u32) -> Light {
        let from = light.center();
        light.with_center(from + (self.light_center.to - from) * self.progress(t))
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

/// Flicker of `v` against `r` over `mask` (module docs): the mean and each frame's value
/// (frames 1…N−1). `None` and no values with fewer than two frames or no pixel in `mask`.
///
/// # Panics
/// When the sequences differ in length or a frame differs in size from `mask`.
pub fn flicker(
    v: &[VisibilityBuffer],
    r: &[VisibilityBuffer],
    mask: &[bool],
) -> (Option<f64>, Vec<f64>) {
    assert_eq!(v.len(), r.len(), "sequences differ in length");
    let n = mask.iter().filter(|&&m| m).count();
    if v.len() < 2 || n == 0 {
        return (None, vec![]);
    }
    let per_frame: Vec<f64> = (1..v.len())
        .map(|t| {
            let (v0, v1, r0, r1) = (&v[t - 1].data, &v[t].data, &r[t - 1].data, &r[t].data);
            assert!(
                v1.len() == mask.len() && r1.len() == mask.len(),
                "frame size"
            );
            let sum: f64 = (0..mask.len())
                .filter(|&i| mask[i])
                .map(|i| ((v1[i] as f64 - v0[i] as f64) - (r1[i] as f64 - r0[i] as f64)).abs())
                .sum();
            sum / n as f64
        })
        .collect();
    let mean = per_frame.iter().sum::<f64>() / per_frame.len() as f64;
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

/// The record of a run's sequence `v` against the reference's `r` (each frame's metrics from
/// `compare`), with the reference's own floor `floor`.
pub fn record(
    v: &[VisibilityBuffer],
    r: &[VisibilityBuffer],
    mask: &[bool],
    floor: Option<f64>,
    compare: impl Fn(&VisibilityBuffer, &VisibilityBuffer) -> ErrorMetrics,
) -> AnimationRecord {
    let per_frame: Vec<ErrorMetrics> = v.iter().zip(r).map(|(a, b)| compare(a, b)).collect();
    let (flicker, flicker_per_frame) = flicker(v, r, mask);
    let flicker_max_frame = flicker_per_frame
        .iter()
        .enumerate()
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
    /// Pixels that see a surface (the same in every frame: only the light moves).
    pub mask: Vec<bool>,
    /// Pixels on receiver-only surfaces.
    pub receivers: Vec<bool>,
}

/// Frame `t` of `anim` for a run in `scene` (its light as the run takes it) with `params`.
pub fn frame_at(
    anim: &Animation,
    scene: &crate::scene::Scene,
    params: &crate::frame::RunParams,
    t: u32,
) -> crate::frame::Frame {
    let mut sc = scene.clone();
    sc.light = anim.light_at(scene.light, t);
    crate::frame::Frame::new(sc, params.clone())
}

/// Renders the sequence of `anim` for `algorithm` on `backend` (each frame one run of the
/// algorithm, as [`super::run_one`]'s first iteration), with each frame's reference from
/// `refs`. Errors: a frame's run failing (its error, naming the frame), the reference failing,
/// or the run's budget (`ctx.deadline`) passing.
pub fn render(
    anim: &Animation,
    scene: &crate::scene::Scene,
    params: &crate::frame::RunParams,
    algorithm: &str,
    backend: crate::backend::Backend,
    ctx: &crate::algorithms::ExecContext,
    refs: &mut super::ReferenceCache,
) -> Result<Rendered> {
    let mut seq = Rendered {
        visibility: vec![],
        reference: vec![],
        shaded: vec![],
        comparison: vec![],
        mask: vec![],
        receivers: vec![],
    };
    for t in 0..anim.frames {
        let frame = frame_at(anim, scene, params, t);
        let r = super::within(|| refs.get_or_compute_until(&frame, ctx.deadline))
            .map_err(|_| {
                Error::Other(format!("frame {t}: its reference passed the run's budget"))
            })??
            .0;
        let v = super::iteration(&frame, algorithm, backend, ctx)
            .0
            .map_err(|e| Error::Other(format!("frame {t}: {e}")))?
            .visibility;
        if t == 0 {
            seq.mask = frame.gbuffer.mask();
            seq.receivers = frame.receiver_only_mask();
        }
        let shaded = super::images::shaded_rgb(&v, &frame);
        let comparison = side_by_side(
            &[
                &shaded,
                &super::images::shaded_rgb(&r, &frame),
                &crate::metrics::error_heatmap(&v, &r, &seq.mask),
            ],
            4,
        );
        seq.shaded.push(shaded);
        seq.comparison.push(comparison);
        seq.visibility.push(v);
        seq.reference.push(r);
    }
    Ok(seq)
}

/// The reference's sequence of `anim` from `refs` (another seed than the runs' for the floor
/// of the flicker measure).
pub fn reference_sequence(
    anim: &Animation,
    scene: &crate::scene::Scene,
    params: &crate::frame::RunParams,
    refs: &mut super::ReferenceCache,
) -> Result<Vec<VisibilityBuffer>> {
    (0..anim.frames)
        .map(|t| Ok(refs.get_or_compute(&frame_at(anim, scene, params, t))?.0))
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
        let mask = [true, true, true, false];
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
        let (m, _) = flicker(&offset, &offset, &mask);
        assert_eq!(m, Some(0.0));
        // One frame or no pixel: nothing to measure.
        assert_eq!(flicker(&r[..1], &r[..1], &mask), (None, vec![]));
        assert_eq!(flicker(&r, &r, &[false; 4]), (None, vec![]));
    }

    #[test]
    fn the_slope_of_a_line_is_its_gradient() {
        assert_eq!(slope(&[1.0, 3.0, 5.0, 7.0]), Some(2.0));
        assert_eq!(slope(&[4.0, 4.0]), Some(0.0));
        assert_eq!(slope(&[1.0]), None);
        assert_eq!(slope(&[1.0, f64::NAN]), None);
    }

    #[test]
    fn paths_start_at_the_light_and_end_or_turn_at_the_target() {
        let light = Light::Sphere {
            center: Vec3::new(1.0, 8.0, 0.5),
            radius: 0.6,
        };
        let mut a = Animation {
            frames: 5,
            light_center: CenterPath {
                to: Vec3::new(-1.0, 8.0, 0.5),
                path: PathKind::Linear,
                easing: Easing::Linear,
            },
        };
        let x = |a: &Animation, t| a.light_at(light, t).center().x;
        assert_eq!(
            [0, 1, 2, 3, 4].map(|t| x(&a, t)),
            [1.0, 0.5, 0.0, -0.5, -1.0]
        );
        assert_eq!(a.light_at(light, 3).size(), 0.6);
        // A loop of 4 frames: out to the target at frame 2 and back; frame 4 would be frame 0.
        a.frames = 4;
        a.light_center.path = PathKind::Loop;
        assert_eq!([0, 1, 2, 3].map(|t| x(&a, t)), [1.0, 0.0, -1.0, 0.0]);
        // Easing keeps the ends and the middle, and starts slower.
        a.frames = 5;
        a.light_center.path = PathKind::Linear;
        a.light_center.easing = Easing::EaseInOut;
        assert_eq!(x(&a, 0), 1.0);
        assert_eq!(x(&a, 2), 0.0);
        assert_eq!(x(&a, 4), -1.0);
        assert!(x(&a, 1) > 0.5);
    }

    #[test]
    fn bad_animations_are_refused_naming_the_field() {
        let mut a = Animation {
            frames: 1,
            light_center: CenterPath {
                to: Vec3::ZERO,
                path: PathKind::Linear,
                easing: Easing::Linear,
            },
        };
        let e = a.check("$.animation").unwrap_err().to_string();
        assert!(e.contains("$.animation.frames"), "{e}");
        a.frames = 8;
        a.light_center.to = Vec3::new(f32::NAN, 0.0, 0.0);
        let e = a.check("$.animation").unwrap_err().to_string();
        assert!(e.contains("$.animation.light_center.to"), "{e}");
    }
}
