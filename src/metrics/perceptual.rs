//! Perceptual image metrics of a run against the reference, from maintained libraries:
//!
//! - ꟻLIP (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström and Fairchild, "ꟻLIP: A
//!   Difference Evaluator for Alternating Images", Proc. ACM CGIT 3(2), 2020), NVIDIA's reference
//!   implementation through the `nv-flip` crate, on the shaded views
//!   ([`crate::harness::images::shaded_rgb`]): what a viewer notices between the two images at
//!   the viewing distance that `pixels_per_degree` sets.
//! - SSIM (Wang, Bovik, Sheikh and Simoncelli, "Image Quality Assessment: From Error Visibility
//!   to Structural Similarity", IEEE TIP 13(4), 2004), through the `image-compare` crate, on the
//!   visibility buffers: structure (blocks, bands, stripes) rather than size of the error.

use std::path::Path;

use crate::error::{Error, InputError, Result};
use crate::visibility::VisibilityBuffer;

/// ꟻLIP's default viewing condition: a 0.7 m wide 3840-pixel monitor seen from 0.7 m, 67.02
/// pixels per degree of visual angle (ꟻLIP paper §4; `nv_flip::DEFAULT_PIXELS_PER_DEGREE`).
pub const DEFAULT_PIXELS_PER_DEGREE: f32 = nv_flip::DEFAULT_PIXELS_PER_DEGREE;

/// The range of pixels per degree a scenario may set (`reference.flip_pixels_per_degree`):
/// ꟻLIP's filters grow with it, so a larger value costs time without modelling a display
/// anyone uses (a phone at arm's length is about 100).
pub const PIXELS_PER_DEGREE_RANGE: std::ops::RangeInclusive<f32> = 1.0..=400.0;

/// Checks a pixels-per-degree setting: finite, within [`PIXELS_PER_DEGREE_RANGE`].
pub fn check_pixels_per_degree(field: &str, v: f32) -> std::result::Result<(), InputError> {
    if !v.is_finite() || !PIXELS_PER_DEGREE_RANGE.contains(&v) {
        return Err(InputError::new(
            field,
            format!(
                "ꟻLIP pixels per degree must be a number in {}..={} (67.02 is a 0.7 m wide 4K \
                 monitor at 0.7 m), got {v}",
                PIXELS_PER_DEGREE_RANGE.start(),
                PIXELS_PER_DEGREE_RANGE.end()
            ),
        ));
    }
    Ok(())
}

/// The per-pixel ꟻLIP error (row-major, `width × height` values in 0–1, 0 where the images
/// agree) of `test` against `reference`, two sRGB images of the same size, at
/// `pixels_per_degree` of visual angle.
///
/// # Panics
/// When the images differ in size (both are views of one frame).
pub fn flip_map(
    reference: &image::RgbImage,
    test: &image::RgbImage,
    pixels_per_degree: f32,
) -> Vec<f32> {
    assert_eq!(
        reference.dimensions(),
        test.dimensions(),
        "image sizes differ"
    );
    let (w, h) = reference.dimensions();
    let r = nv_flip::FlipImageRgb8::with_data(w, h, reference.as_raw());
    let t = nv_flip::FlipImageRgb8::with_data(w, h, test.as_raw());
    nv_flip::flip(r, t, pixels_per_degree).to_vec()
}

/// The mean of `values` over the pixels of `mask` (ꟻLIP's recommended single figure is the
/// mean of its map, §5); `None` over no pixel or when not finite.
pub fn mean_over(values: &[f32], mask: &[bool]) -> Option<f64> {
    let (sum, n) = values
        .iter()
        .zip(mask)
        .filter(|(_, &m)| m)
        .fold((0.0f64, 0u64), |(s, n), (&v, _)| (s + f64::from(v), n + 1));
    (n > 0)
        .then(|| sum / n as f64)
        .filter(|v: &f64| v.is_finite())
}

/// SSIM of `result` against `reference` (visibility buffers of one size, 0–1), as the mean of
/// SSIM over 8 × 8 pixel windows of the buffers quantised to 8 bits (`image-compare`'s
/// `MSSIMSimple`: uniform windows side by side, C1 = (0.01·255)², C2 = (0.03·255)²). Pixels
/// outside `mask` (no surface) are set to 0 in both, so they agree and only the structure of
/// the surfaces differs; `None` when no pixel sees a surface or a pixel is not finite.
pub fn ssim(result: &VisibilityBuffer, reference: &VisibilityBuffer, mask: &[bool]) -> Option<f64> {
    if !mask.iter().any(|&m| m)
        || result
            .data
            .iter()
            .chain(&reference.data)
            .any(|v| !v.is_finite())
    {
        return None;
    }
    let grey = |v: &VisibilityBuffer| {
        let bytes = v
            .data
            .iter()
            .zip(mask)
            .map(|(x, &m)| {
                if m {
                    (x.clamp(0.0, 1.0) * 255.0).round() as u8
                } else {
                    0
                }
            })
            .collect();
        image::GrayImage::from_raw(v.width, v.height, bytes).expect("buffer size matches image")
    };
    image_compare::gray_similarity_structure(
        &image_compare::Algorithm::MSSIMSimple,
        &grey(result),
        &grey(reference),
    )
    .ok()
    .map(|s| s.score)
    .filter(|v| v.is_finite())
}

/// Writes a ꟻLIP error map (from [`flip_map`]) as a PNG in ꟻLIP's magma colour map (black for
/// no error through purple and orange to pale yellow for 1), pixels outside `mask` in
/// [`crate::harness::images::BACKGROUND`].
pub fn write_flip_map(
    map: &[f32],
    mask: &[bool],
    width: u32,
    height: u32,
    path: &Path,
) -> Result<()> {
    let lut = nv_flip::magma_lut().to_vec();
    let n = lut.len() / 3;
    let mut img = image::RgbImage::new(width, height);
    for (i, px) in img.pixels_mut().enumerate() {
        *px = if mask[i] {
            let k = ((map[i].clamp(0.0, 1.0) * (n - 1) as f32).round() as usize).min(n - 1);
            image::Rgb([lut[3 * k], lut[3 * k + 1], lut[3 * k + 2]])
        } else {
            image::Rgb(crate::harness::images::BACKGROUND)
        };
    }
    img.save(path)
        .map_err(|e| Error::Other(format!("{}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w × h` buffer of a smooth shadow edge: lit on the left, a penumbra ramp, umbra on the
    /// right.
    fn edge(w: u32, h: u32) -> VisibilityBuffer {
        let data = (0..w * h)
            .map(|i| {
                let x = (i % w) as f32 / (w - 1) as f32;
                (1.0 - (x - 0.35) / 0.3).clamp(0.0, 1.0)
            })
            .collect();
        VisibilityBuffer {
            width: w,
            height: h,
            data,
        }
    }

    /// A buffer as a shaded sRGB image (grey, gamma 2.2) for the ꟻLIP tests.
    fn grey_rgb(v: &VisibilityBuffer) -> image::RgbImage {
        let bytes = v
            .data
            .iter()
            .flat_map(|x| [(x.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8; 3])
            .collect();
        image::RgbImage::from_raw(v.width, v.height, bytes).unwrap()
    }

    /// Standard normal deviates from a fixed-seed xorshift and Box–Muller, so the test's noise
    /// is the same on every run.
    fn gaussian(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed;
        let mut uniform = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| {
                let (u1, u2) = (uniform(), uniform());
                ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
            })
            .collect()
    }

    #[test]
    fn flip_of_an_image_with_itself_is_zero_and_of_black_against_white_is_large() {
        let v = edge(48, 32);
        let img = grey_rgb(&v);
        let mask = vec![true; img.len() / 3];
        let map = flip_map(&img, &img, DEFAULT_PIXELS_PER_DEGREE);
        assert_eq!(map.len(), 48 * 32);
        assert!(map.iter().all(|&e| e == 0.0), "FLIP(x, x) must be 0");
        assert_eq!(mean_over(&map, &mask), Some(0.0));
        // ꟻLIP's colour pipeline maps black against white near its maximum (paper §3: the
        // error is normalised so the largest difference in its colour space is 1).
        let black = image::RgbImage::new(48, 32);
        let white = image::RgbImage::from_pixel(48, 32, image::Rgb([255; 3]));
        let far = mean_over(&flip_map(&white, &black, DEFAULT_PIXELS_PER_DEGREE), &mask).unwrap();
        assert!(far > 0.8, "FLIP(white, black) = {far}");
    }

    #[test]
    fn flip_and_ssim_grow_worse_with_the_noise_added_to_a_visibility_buffer() {
        let reference = edge(64, 48);
        let mask = vec![true; reference.data.len()];
        let noise = gaussian(reference.data.len(), 0x5eed);
        let (mut last_flip, mut last_ssim) = (0.0, 1.0);
        for sigma in [0.01f32, 0.03, 0.1, 0.3] {
            let noisy = VisibilityBuffer {
                data: reference
                    .data
                    .iter()
                    .zip(&noise)
                    .map(|(v, n)| (v + sigma * n).clamp(0.0, 1.0))
                    .collect(),
                ..reference.clone()
            };
            let f = mean_over(
                &flip_map(
                    &grey_rgb(&reference),
                    &grey_rgb(&noisy),
                    DEFAULT_PIXELS_PER_DEGREE,
                ),
                &mask,
            )
            .unwrap();
            let s = ssim(&noisy, &reference, &mask).unwrap();
            assert!(f > last_flip, "σ {sigma}: FLIP {f} not above {last_flip}");
            assert!(s < last_ssim, "σ {sigma}: SSIM {s} not below {last_ssim}");
            (last_flip, last_ssim) = (f, s);
        }
        assert_eq!(ssim(&reference, &reference, &mask), Some(1.0));
    }

    #[test]
    fn viewing_conditions_outside_the_range_are_refused_by_field() {
        assert!(check_pixels_per_degree("$.reference.flip_pixels_per_degree", 67.0).is_ok());
        for bad in [0.0, -3.0, f32::NAN, f32::INFINITY, 1000.0] {
            let e = check_pixels_per_degree("$.reference.flip_pixels_per_degree", bad)
                .unwrap_err()
                .to_string();
            assert!(e.contains("$.reference.flip_pixels_per_degree"), "{e}");
        }
    }

    #[test]
    fn ssim_is_absent_without_a_surface_or_with_a_nan_pixel() {
        let v = edge(16, 8);
        assert_eq!(ssim(&v, &v, &[false; 128]), None);
        let mut nan = v.clone();
        nan.data[3] = f32::NAN;
        assert_eq!(ssim(&nan, &v, &[true; 128]), None);
    }
}
