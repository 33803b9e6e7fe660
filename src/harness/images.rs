//! The images of a run beyond the raw buffer: the mask of pixels that see a surface
//! (`mask.npy`), visibility with the background transparent, a shaded view in which occluders
//! stand out against a lit background, and the difference of two runs (`shadowbench diff`).

use std::path::{Path, PathBuf};

use npyz::WriterBuilder;

use crate::error::{Error, InputError, Result};
use crate::frame::Frame;
use crate::visibility::VisibilityBuffer;

/// Colour of pixels that see no surface in the colour images (blue-grey, as in `error.png`).
pub const BACKGROUND: [u8; 3] = [40, 44, 52];

/// Writes `mask` (true where the pixel sees a surface) as a uint8 NumPy array of shape (H, W):
/// 1 for a surface, 0 for background.
pub fn write_mask_npy(mask: &[bool], width: u32, height: u32, path: &Path) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[height as u64, width as u64])
        .writer(std::io::BufWriter::new(file))
        .begin_nd()
        .map_err(|e| Error::io(path, e))?;
    w.extend(mask.iter().map(|&m| m as u8))
        .map_err(|e| Error::io(path, e))?;
    w.finish().map_err(|e| Error::io(path, e))
}

/// Reads a mask written by [`write_mask_npy`]: a 2-D `uint8` array (C or Fortran order), true
/// where non-zero, as (width, height, row-major mask). Errors as
/// [`crate::util::npy::read_2d`]'s, naming the file.
pub fn read_mask_npy(path: &Path) -> std::result::Result<(u32, u32, Vec<bool>), InputError> {
    let a = crate::util::npy::read_2d::<u8>(path, "mask", "uint8")?;
    Ok((
        a.width,
        a.height,
        a.data.into_iter().map(|v| v != 0).collect(),
    ))
}

/// Visibility as an 8-bit grey + alpha PNG: grey 0 (no light) to 255 (fully lit), fully
/// transparent where the pixel sees no surface, so the background is not read as lit ground.
pub fn write_masked_png(v: &VisibilityBuffer, mask: &[bool], path: &Path) -> Result<()> {
    let bytes: Vec<u8> = v
        .data
        .iter()
        .zip(mask)
        .flat_map(|(x, &m)| {
            [
                (x.clamp(0.0, 1.0) * 255.0).round() as u8,
                if m { 255 } else { 0 },
            ]
        })
        .collect();
    image::GrayAlphaImage::from_raw(v.width, v.height, bytes)
        .expect("buffer size matches image size")
        .save(path)
        .map_err(|e| Error::Other(format!("{}: {e}", path.display())))
}

/// Ambient share of the shaded view: unlit surfaces keep this fraction of their colour.
const AMBIENT: f32 = 0.15;
/// Surface colour of the shaded view (a warm white).
const TINT: [f32; 3] = [1.0, 0.92, 0.8];

/// Radiance of the shaded view at a pixel, in [0, 1] per channel before display encoding:
/// `TINT × (AMBIENT + (1 − AMBIENT) × visibility × max(0, n·l))`, with n the surface normal and l
/// the unit direction from the surface to the light's centre (a Lambertian term).
pub fn shade(visibility: f32, n_dot_l: f32) -> [f32; 3] {
    let v = AMBIENT + (1.0 - AMBIENT) * visibility.clamp(0.0, 1.0) * n_dot_l.max(0.0);
    TINT.map(|t| t * v)
}

/// The shaded view of `v` in `frame`: each surface pixel lit by [`shade`] (gamma 2.2 for
/// display), background in [`BACKGROUND`]; written by [`write_shaded`].
pub fn write_shaded(v: &VisibilityBuffer, frame: &Frame, path: &Path) -> Result<()> {
    shaded_rgb(v, frame)
        .save(path)
        .map_err(|e| Error::Other(format!("{}: {e}", path.display())))
}

/// The shaded view of `v` in `frame` as an 8-bit sRGB image of the frame's size (what
/// [`write_shaded`] writes and ꟻLIP compares, [`crate::metrics::perceptual`]).
pub fn shaded_rgb(v: &VisibilityBuffer, frame: &Frame) -> image::RgbImage {
    let g = &frame.gbuffer;
    let centre = frame.scene.light.center();
    let mut img = image::RgbImage::new(v.width, v.height);
    for (i, px) in img.pixels_mut().enumerate() {
        *px = if g.is_hit(i) {
            let l = (centre - g.position[i]).normalize_or_zero();
            let c = shade(v.data[i], g.normal[i].dot(l));
            image::Rgb(c.map(|x| (x.powf(1.0 / 2.2) * 255.0).round() as u8))
        } else {
            image::Rgb(BACKGROUND)
        };
    }
    img
}

/// What differs between two visibility buffers over the pixels that see a surface.
#[derive(Clone, Debug, PartialEq)]
pub struct Difference {
    /// Pixels compared (that see a surface in both, or all without a mask).
    pub pixels: u64,
    /// Mean of |a − b|.
    pub mean_abs: f64,
    /// Largest |a − b|.
    pub max_abs: f64,
    /// Fraction of compared pixels where |a − b| > 0.1.
    pub frac_over_0_1: f64,
}

/// The difference `a − b` as an image — white where equal, red where `a` is brighter, blue
/// where `a` is darker, full colour at |a − b| ≥ 0.5; masked pixels in [`BACKGROUND`] — and its
/// statistics. The buffers must have the same size.
pub fn difference(
    a: &VisibilityBuffer,
    b: &VisibilityBuffer,
    mask: Option<&[bool]>,
) -> (image::RgbImage, Difference) {
    assert_eq!(
        (a.width, a.height),
        (b.width, b.height),
        "image sizes differ"
    );
    let mut img = image::RgbImage::new(a.width, a.height);
    let (mut n, mut sum, mut max, mut over) = (0u64, 0.0f64, 0.0f64, 0u64);
    for (i, px) in img.pixels_mut().enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            *px = image::Rgb(BACKGROUND);
            continue;
        }
        let d = (a.data[i] - b.data[i]) as f64;
        n += 1;
        sum += d.abs();
        max = max.max(d.abs());
        over += (d.abs() > 0.1) as u64;
        let t = (d.abs() * 2.0).min(1.0);
        let fade = (255.0 * (1.0 - t)).round() as u8;
        *px = if d >= 0.0 {
            image::Rgb([255, fade, fade])
        } else {
            image::Rgb([fade, fade, 255])
        };
    }
    let div = |x: f64| if n > 0 { x / n as f64 } else { 0.0 };
    (
        img,
        Difference {
            pixels: n,
            mean_abs: div(sum),
            max_abs: max,
            frac_over_0_1: div(over as f64),
        },
    )
}

/// A run's visibility for `diff`: a `visibility.npy`, or a folder holding one (a run's image
/// folder or a `render` output), with the folder's `mask.npy` when there is one.
pub fn load_run(arg: &Path) -> Result<(VisibilityBuffer, Option<Vec<bool>>)> {
    let (npy, dir): (PathBuf, &Path) = if arg.is_dir() {
        (arg.join("visibility.npy"), arg)
    } else {
        (arg.to_path_buf(), arg.parent().unwrap_or(Path::new(".")))
    };
    if !npy.is_file() {
        return Err(InputError::file(
            arg,
            "not a visibility.npy nor a folder holding one (a run's image folder)",
        )
        .into());
    }
    let v = VisibilityBuffer::read_npy(&npy)?;
    let mask_path = dir.join("mask.npy");
    let mask = if mask_path.is_file() {
        let (w, h, m) = read_mask_npy(&mask_path)?;
        if (w, h) != (v.width, v.height) {
            return Err(InputError::file(
                &mask_path,
                format!(
                    "mask is {w}×{h}, but the visibility {} is {}×{}",
                    npy.display(),
                    v.width,
                    v.height
                ),
            )
            .into());
        }
        Some(m)
    } else {
        None
    };
    Ok((v, mask))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::tests::buf;

    #[test]
    fn mask_round_trips_through_npy() {
        let (_dir, p) = crate::util::paths::temp_path("mask.npy");
        let mask = vec![true, false, false, true, true, false];
        write_mask_npy(&mask, 3, 2, &p).unwrap();
        assert_eq!(read_mask_npy(&p).unwrap(), (3, 2, mask));
    }

    #[test]
    fn masked_pixels_are_transparent() {
        let (_dir, p) = crate::util::paths::temp_path("v.png");
        write_masked_png(&buf(vec![1.0, 0.5, 0.0]), &[true, false, true], &p).unwrap();
        let img = image::open(&p).unwrap().to_luma_alpha8();
        let px: Vec<[u8; 2]> = img.pixels().map(|p| p.0).collect();
        assert_eq!(px, [[255, 255], [128, 0], [0, 255]]);
    }

    #[test]
    fn shading_is_lambert_times_visibility_over_ambient() {
        // Facing the light, fully visible: the tint. In umbra or facing away: ambient only.
        assert_eq!(shade(1.0, 1.0), TINT);
        let ambient = TINT.map(|t| t * AMBIENT);
        assert_eq!(shade(0.0, 1.0), ambient);
        assert_eq!(shade(1.0, -0.5), ambient);
        // Half visible at 60° incidence: ambient + (1 − ambient) × 0.5 × 0.5.
        let v = shade(0.5, 0.5)[0];
        assert!((v - (AMBIENT + (1.0 - AMBIENT) * 0.25)).abs() < 1e-6);
    }

    #[test]
    fn difference_counts_only_masked_in_pixels_and_colours_the_sign() {
        let a = buf(vec![1.0, 0.0, 0.5, 0.3]);
        let b = buf(vec![0.0, 1.0, 0.5, 0.9]);
        let (img, d) = difference(&a, &b, Some(&[true, true, true, false]));
        assert_eq!(d.pixels, 3);
        assert!((d.mean_abs - 2.0 / 3.0).abs() < 1e-9);
        assert_eq!(d.max_abs, 1.0);
        assert!((d.frac_over_0_1 - 2.0 / 3.0).abs() < 1e-9);
        let px: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
        assert_eq!(px, [[255, 0, 0], [0, 0, 255], [255, 255, 255], BACKGROUND]);
    }
}
