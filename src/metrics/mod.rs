//! Quality of a visibility buffer against the ground-truth reference.

use std::path::Path;

use serde::{Deserialize, Serialize};
use serde_with::skip_serializing_none;

use crate::error::{Error, Result};
use crate::visibility::VisibilityBuffer;

/// A pixel counts as "in shadow" (umbra or penumbra) when its visibility is below this.
/// One blocked sample out of 1024 (0.999) already counts, as the papers' penumbra does.
pub const SHADOW_THRESHOLD: f32 = 1.0 - 0.5 / 1024.0;

/// Error of a result against the reference, over the pixels that see a surface.
///
/// A metric over zero pixels (no pixel sees a surface; for `mae_shadow`, no pixel is in
/// shadow in either image) is absent (`None`, left out of `results.json`), never 0; so is one
/// that is not finite. [`ErrorMetrics::warnings`] says which are absent and why.
#[skip_serializing_none]
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorMetrics {
    pub mae: Option<f64>,
    pub rmse: Option<f64>,
    pub max: Option<f64>,
    /// Mean absolute error over pixels in umbra or penumbra in either image (paper 002 §5.2.1).
    pub mae_shadow: Option<f64>,
    /// Fraction of pixels whose absolute error exceeds 0.1.
    pub frac_over_0_1: Option<f64>,
    pub pixels: u64,
    pub shadow_pixels: u64,
    /// `mae_shadow` restricted to pixels on receiver-only surfaces (objects that receive and do
    /// not occlude): the part of the image every method claims to compute, beside the
    /// unrestricted figure ([`crate::algorithms::MethodLimit`]). Absent without such pixels in
    /// shadow.
    pub mae_shadow_receivers: Option<f64>,
    /// Pixels whose surface's tangent plane cuts the light (`Frame::grazing_mask`), where the
    /// reference counts the part of the light behind the plane as hidden and most methods leave
    /// it to shading: scored apart.
    #[serde(default)]
    pub grazing_pixels: u64,
    /// `mae_shadow` over the pixels that are not grazing. Absent without such pixels in shadow.
    pub mae_shadow_non_grazing: Option<f64>,
}

impl ErrorMetrics {
    /// The metrics by name, in the order `results.csv` lists them.
    pub fn named(&self) -> [(&'static str, Option<f64>); 5] {
        [
            ("mae", self.mae),
            ("rmse", self.rmse),
            ("max", self.max),
            ("mae_shadow", self.mae_shadow),
            ("frac_over_0_1", self.frac_over_0_1),
        ]
    }

    /// A warning for each absent metric, saying why it is absent.
    pub fn warnings(&self) -> Vec<String> {
        if self.pixels == 0 {
            return vec![
                "no pixel of the image sees a surface: no quality metrics (they would be \
                 over 0 pixels)"
                    .into(),
            ];
        }
        self.named()
            .into_iter()
            .filter(|(_, v)| v.is_none())
            .map(|(name, _)| {
                let why = match (name, self.shadow_pixels) {
                    ("mae_shadow", 0) => "no pixel is in shadow in either image",
                    _ => "it is not finite",
                };
                format!("metric {name} absent: {why}")
            })
            .collect()
    }
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
        // NaN-propagating, so a NaN pixel makes the maximum absent rather than ignored.
        max = if max.is_nan() || e.is_nan() {
            f64::NAN
        } else {
            max.max(e)
        };
        over += u64::from(e > 0.1);
        if a < SHADOW_THRESHOLD || b < SHADOW_THRESHOLD {
            shadow_sum += e;
            shadow_n += 1;
        }
    }
    let finite = |v: f64| v.is_finite().then_some(v);
    let mean = |s: f64, k: u64| (k > 0).then(|| s / k as f64).and_then(finite);
    ErrorMetrics {
        mae: mean(sum, n),
        rmse: mean(sq, n).map(f64::sqrt),
        max: (n > 0).then_some(max).and_then(finite),
        mae_shadow: mean(shadow_sum, shadow_n),
        // A NaN pixel makes every mean absent; the fraction goes with them.
        frac_over_0_1: mean(over as f64, n).filter(|_| sum.is_finite()),
        pixels: n,
        shadow_pixels: shadow_n,
        mae_shadow_receivers: None,
        grazing_pixels: 0,
        mae_shadow_non_grazing: None,
    }
}

/// [`compare`] with `mae_shadow_receivers` over `receivers` (a mask within `mask`: pixels on
/// receiver-only surfaces), and the grazing pixels (`grazing`, within `mask`) counted and left
/// out of `mae_shadow_non_grazing`. All masks have one flag per pixel.
pub fn compare_with_receivers(
    result: &VisibilityBuffer,
    reference: &VisibilityBuffer,
    mask: &[bool],
    receivers: &[bool],
    grazing: &[bool],
) -> ErrorMetrics {
    let restricted = compare(result, reference, receivers);
    let non_grazing: Vec<bool> = mask.iter().zip(grazing).map(|(&m, &g)| m && !g).collect();
    ErrorMetrics {
        mae_shadow_receivers: restricted.mae_shadow,
        grazing_pixels: mask.iter().zip(grazing).filter(|(&m, &g)| m && g).count() as u64,
        mae_shadow_non_grazing: compare(result, reference, &non_grazing).mae_shadow,
        ..compare(result, reference, mask)
    }
}

/// A note (the run's `notes`: expected, said once per algorithm in the report) where the
/// grazing pixels raise `mae_shadow` by more than a tenth (and 0.005) over
/// `mae_shadow_non_grazing`: that much of the figure shows the two definitions of visibility
/// at grazing angles, not the method's shadows.
pub fn grazing_note(e: &ErrorMetrics, algorithm: &str) -> Option<String> {
    let (all, without) = (e.mae_shadow?, e.mae_shadow_non_grazing.unwrap_or(0.0));
    (e.grazing_pixels > 0 && all - without > (0.1 * all).max(0.005)).then(|| {
        format!(
            "{} pixels see the light straddle their surface's tangent plane (grazing) and raise \
             mae_shadow from {without:.4} without them (error.mae_shadow_non_grazing) to \
             {all:.4}: there the reference counts the part of the light behind the plane as \
             hidden and '{algorithm}' departs from it (docs/records.md: visibility at grazing \
             angles)",
            e.grazing_pixels
        )
    })
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
pub(crate) mod tests {
    use super::*;

    /// A one-row buffer of `data`.
    pub(crate) fn buf(data: Vec<f32>) -> VisibilityBuffer {
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
        assert!((m.mae.unwrap() - 0.4 / 4.0).abs() < 1e-6);
        assert!((m.rmse.unwrap() - (0.08f64 / 4.0).sqrt()).abs() < 1e-6);
        assert!((m.max.unwrap() - 0.2).abs() < 1e-6);
        // Pixels 1, 2, 3 are in shadow in one image or the other; pixel 0 is lit in both.
        assert_eq!(m.shadow_pixels, 3);
        assert!((m.mae_shadow.unwrap() - 0.4 / 3.0).abs() < 1e-6);
        assert!((m.frac_over_0_1.unwrap() - 0.5).abs() < 1e-9);
        assert!(m.warnings().is_empty());
    }

    #[test]
    fn a_metric_over_zero_pixels_is_absent_with_a_warning_not_zero() {
        // Lit everywhere in both images: nothing is in shadow, so mae_shadow has no pixels.
        let lit = buf(vec![1.0, 1.0, 1.0]);
        let m = compare(&lit, &lit, &[true, true, false]);
        assert_eq!(m.mae, Some(0.0));
        assert_eq!((m.shadow_pixels, m.mae_shadow), (0, None));
        let w = m.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("mae_shadow") && w[0].contains("no pixel is in shadow"));
        // No pixel sees a surface: every metric is absent, one warning says why.
        let m = compare(&lit, &lit, &[false; 3]);
        assert_eq!(m.named().map(|(_, v)| v), [None; 5]);
        let w = m.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("0 pixels"), "{w:?}");
        // Absent metrics are left out of the JSON, and read back as absent.
        let json = serde_json::to_value(m).unwrap();
        assert!(json.get("mae").is_none(), "{json}");
        assert_eq!(serde_json::from_value::<ErrorMetrics>(json).unwrap(), m);
    }

    #[test]
    fn a_nan_pixel_gives_absent_metrics_never_nan() {
        let reference = buf(vec![f32::NAN, 0.5, 1.0]);
        let result = buf(vec![0.5, 0.5, 1.0]);
        let m = compare(&result, &reference, &[true; 3]);
        for (name, v) in m.named() {
            assert!(v.is_none(), "{name}: {v:?}");
        }
        assert!(m.warnings().iter().all(|w| w.contains("not finite")));
    }
}
