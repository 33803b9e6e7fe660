//! Quality of a visibility buffer against the ground-truth reference.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::visibility::VisibilityBuffer;

/// A pixel counts as "in shadow" (umbra or penumbra) when its visibility is below this.
/// One blocked sample out of 1024 (0.999) already counts, as the papers' penumbra does.
pub const SHADOW_THRESHOLD: f32 = 1.0 - 0.5 / 1024.0;

/// Error of a result against the reference, over the pixels that see a surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorMetrics {
    pub mae: f64,
    pub rmse: f64,
    pub max: f64,
    /// Mean absolute error over pixels in umbra or penumbra in either image (paper 002 §5.2.1).
    pub mae_shadow: f64,
    /// Fraction of pixels whose absolute error exceeds 0.1.
    pub frac_over_0_1: f64,
    pub pixels: u64,
    pub shadow_pixels: u64,
    /// `mae_shadow` restricted to pixels on receiver-only surfaces (objects that receive and do
    /// not occlude): the part of the image every method claims to compute, beside the
    /// unrestricted figure ([`crate::algorithms::MethodLimit`]). Absent without such pixels in
    /// shadow.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mae_shadow_receivers: Option<f64>,
}

/// Compares `result` with `reference` over `mask` (pixels that see a surface).
pub fn compare(
    result: &VisibilityBuffer,
    reference: &VisibilityBuffer,
    mask: &[bool],
) -> ErrorMetrics {
    assert_eq!(
        result.data.len(),
        reference.data.len(),
        "image sizes differ"
    );
    let (mut sum, mut sq, mut max, mut over) = (0.0f64, 0.0f64, 0.0f64, 0u64);
    let (mut shadow_sum, mut shadow_n, mut n) = (0.0f64, 0u64, 0u64);
    for ((&a, &b), &m) in result.data.iter().zip(&reference.data).zip(mask) {
        if !m {
            continue;
        }
        let e = (a as f64 - b as f64).abs();
        n += 1;
        sum += e;
        sq += e * e;
        max = max.max(e);
        over += u64::from(e > 0.1);
        if a < SHADOW_THRESHOLD || b < SHADOW_THRESHOLD {
            shadow_sum += e;
            shadow_n += 1;
        }
    }
    let div = |s: f64, k: u64| if k == 0 { 0.0 } else { s / k as f64 };
    ErrorMetrics {
        mae: div(sum, n),
        rmse: div(sq, n).sqrt(),
        max,
        mae_shadow: div(shadow_sum, shadow_n),
        frac_over_0_1: div(over as f64, n),
        pixels: n,
        shadow_pixels: shadow_n,
        mae_shadow_receivers: None,
    }
}

/// [`compare`] with `mae_shadow_receivers` over `receivers` (a mask within `mask`: pixels on
/// receiver-only surfaces).
pub fn compare_with_receivers(
    result: &VisibilityBuffer,
    reference: &VisibilityBuffer,
    mask: &[bool],
    receivers: &[bool],
) -> ErrorMetrics {
    let restricted = compare(result, reference, receivers);
    ErrorMetrics {
        mae_shadow_receivers: (restricted.shadow_pixels > 0).then_some(restricted.mae_shadow),
        ..compare(result, reference, mask)
    }
}

/// Absolute error as a heat map: black (0) through red to yellow (≥ 0.5); background in blue-grey.
pub fn write_error_heatmap(
    result: &VisibilityBuffer,
    reference: &VisibilityBuffer,
    mask: &[bool],
    path: &Path,
) -> Result<()> {
    let mut img = image::RgbImage::new(result.width, result.height);
    for (i, px) in img.pixels_mut().enumerate() {
        *px = if mask[i] {
            let e = ((result.data[i] - reference.data[i]).abs() * 2.0).clamp(0.0, 1.0);
            let r = (e * 2.0).min(1.0);
            let g = (e * 2.0 - 1.0).max(0.0);
            image::Rgb([(r * 255.0) as u8, (g * 255.0) as u8, 0])
        } else {
            image::Rgb([40, 44, 52])
        };
    }
    img.save(path)
        .map_err(|e| Error::Other(format!("{}: {e}", path.display())))
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
    fn metrics_of_a_known_difference() {
        let reference = buf(vec![1.0, 1.0, 0.5, 0.0, 1.0]);
        let result = buf(vec![1.0, 0.8, 0.5, 0.2, 0.0]);
        let mask = [true, true, true, true, false];
        let m = compare(&result, &reference, &mask);
        assert_eq!(m.pixels, 4);
        assert!((m.mae - 0.4 / 4.0).abs() < 1e-6);
        assert!((m.rmse - (0.08f64 / 4.0).sqrt()).abs() < 1e-6);
        assert!((m.max - 0.2).abs() < 1e-6);
        // Pixels 1, 2, 3 are in shadow in one image or the other; pixel 0 is lit in both.
        assert_eq!(m.shadow_pixels, 3);
        assert!((m.mae_shadow - 0.4 / 3.0).abs() < 1e-6);
        assert!((m.frac_over_0_1 - 0.5).abs() < 1e-9);
    }
}
