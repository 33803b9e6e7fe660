//! Textured and coloured rectangular lights (paper 001, Paper III §3.3: "the texture defines the
//! colors of the light source, and since a black texel implies absence of light, the texture
//! also indirectly determines the shape of the light source").
//!
//! A texture covers a rectangular light's `[−1, 1]²` light coordinates (first coordinate along
//! `half_u`, second along `half_v`) with `width×height` constant RGB texels in [0, 1], linear
//! (a PNG's 8-bit values are divided by 255, not sRGB-decoded). Texel row 0 lies at `v = −1`;
//! a PNG's top row is placed at `v = +1`. No texture means a uniform white light.
//!
//! Light received at a point is, per channel, `∫ T_c` over the visible part of the light divided
//! by the light's area: an unoccluded point receives the texture's mean colour. The scalar
//! visibility every metric uses is its luminance over the mean colour's luminance
//! ([`LightTexture::visibility`], Rec. 709 weights [`LUMA`]), the fraction of the light's
//! luminous power that reaches the point; this is the one place that math lives.

use std::path::{Path, PathBuf};

use glam::Vec2;
use serde::{Deserialize, Serialize};
use serde_with::skip_serializing_none;

use crate::error::{names_or_none, InputError};
use crate::util::hash::Fnv64;

/// Rec. 709 luminance weights of r, g, b.
pub const LUMA: [f32; 3] = [0.2126, 0.7152, 0.0722];

/// Largest side of a PNG light texture.
pub const MAX_SIDE: u32 = 4096;

/// `light.texture` of a scenario: exactly one of `checker`, `stripes`, `color` or `png`.
#[skip_serializing_none]
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightTextureSpec {
    /// A `k×k` checkerboard of the two `colors`.
    pub checker: Option<u32>,
    /// `k` equal stripes across `axis`, cycling through `colors`.
    pub stripes: Option<u32>,
    /// The axis the stripes follow each other along: `u` (default) or `v`.
    pub axis: Option<StripeAxis>,
    /// Colours of `checker` (two) or `stripes` (two or more); default white and black.
    pub colors: Option<Vec<[f32; 3]>>,
    /// A uniformly coloured light.
    pub color: Option<[f32; 3]>,
    /// An RGB(A) PNG, relative to the scenario file (alpha ignored).
    pub png: Option<PathBuf>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StripeAxis {
    U,
    V,
}

/// A resolved light texture: `width×height` RGB texels over `[−1, 1]²`, row 0 at `v = −1`.
#[derive(Clone, Debug, PartialEq)]
pub struct LightTexture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 3]>,
}

fn colour(field: &str, c: [f32; 3]) -> Result<[f32; 3], InputError> {
    for (k, v) in c.iter().enumerate() {
        if !v.is_finite() || !(0.0..=1.0).contains(v) {
            return Err(InputError::new(
                format!("{field}[{k}]"),
                format!("colour components must be in [0, 1], got {v}"),
            ));
        }
    }
    Ok(c)
}

impl LightTextureSpec {
    /// Checks the spec and builds the texture; `field` is its JSON path (`$.light.texture`),
    /// `base` the folder a `png` path is relative to.
    pub fn resolve(&self, field: &str, base: &Path) -> Result<LightTexture, InputError> {
        let given: Vec<&str> = [
            ("checker", self.checker.is_some()),
            ("stripes", self.stripes.is_some()),
            ("color", self.color.is_some()),
            ("png", self.png.is_some()),
        ]
        .iter()
        .filter(|(_, g)| *g)
        .map(|(n, _)| *n)
        .collect();
        if given.len() != 1 {
            return Err(InputError::new(
                field,
                format!(
                    "give exactly one of checker, stripes, color or png, got {}",
                    names_or_none(&given)
                ),
            ));
        }
        if self.axis.is_some() && self.stripes.is_none() {
            return Err(InputError::new(
                format!("{field}.axis"),
                "axis applies to stripes only",
            ));
        }
        if self.colors.is_some() && self.checker.is_none() && self.stripes.is_none() {
            return Err(InputError::new(
                format!("{field}.colors"),
                "colors apply to checker and stripes only (use color for a uniform light)",
            ));
        }
        let colors = |min: usize, max: usize| -> Result<Vec<[f32; 3]>, InputError> {
            let c = self
                .colors
                .clone()
                .unwrap_or_else(|| vec![[1.0; 3], [0.0; 3]]);
            if c.len() < min || c.len() > max {
                return Err(InputError::new(
                    format!("{field}.colors"),
                    format!(
                        "needs {} colours, got {}",
                        if min == max {
                            min.to_string()
                        } else {
                            format!("{min} to {max}")
                        },
                        c.len()
                    ),
                ));
            }
            c.iter()
                .enumerate()
                .map(|(i, &v)| colour(&format!("{field}.colors[{i}]"), v))
                .collect()
        };
        let cells = |name: &str, k: u32| {
            if (1..=1024).contains(&k) {
                Ok(k)
            } else {
                Err(InputError::new(
                    format!("{field}.{name}"),
                    format!("must be in 1..=1024, got {k}"),
                ))
            }
        };
        let t = if let Some(k) = self.checker {
            let k = cells("checker", k)?;
            let c = colors(2, 2)?;
            LightTexture::from_fn(k, k, |i, j| c[((i + j) % 2) as usize])
        } else if let Some(k) = self.stripes {
            let k = cells("stripes", k)?;
            let c = colors(2, 64)?;
            let pick = |i: u32| c[i as usize % c.len()];
            match self.axis.unwrap_or(StripeAxis::U) {
                StripeAxis::U => LightTexture::from_fn(k, 1, |i, _| pick(i)),
                StripeAxis::V => LightTexture::from_fn(1, k, |_, j| pick(j)),
            }
        } else if let Some(c) = self.color {
            let c = colour(&format!("{field}.color"), c)?;
            LightTexture::from_fn(1, 1, |_, _| c)
        } else {
            let rel = self.png.as_ref().expect("one source given");
            LightTexture::load_png(&base.join(rel)).map_err(|mut e| {
                e.field = Some(format!("{field}.png"));
                e
            })?
        };
        if LightTexture::luminance(t.mean()) <= 0.0 {
            return Err(InputError::new(
                field,
                "the texture emits no light (every texel is black)",
            ));
        }
        Ok(t)
    }
}

impl LightTexture {
    /// Texel `(i, j)` (column i along u, row j along v) from `f`.
    pub fn from_fn(width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> LightTexture {
        LightTexture {
            width,
            height,
            texels: (0..width * height)
                .map(|k| f(k % width, k / width))
                .collect(),
        }
    }

    /// An 8-bit RGB(A) PNG, top row at `v = +1`, values over 255.
    ///
    /// The size is read from the PNG header and checked against [`MAX_SIDE`] before any pixel is
    /// decoded, so a small file that declares a huge image is refused without allocating it.
    pub fn load_png(path: &Path) -> Result<LightTexture, InputError> {
        // A missing file, a folder, a device or a link loop, named as such.
        crate::util::input::open(path, "light texture")?;
        let bad = |e: image::ImageError| {
            InputError::file(path, format!("cannot read light texture: {e}"))
        };
        let open = || {
            image::ImageReader::open(path)
                .map_err(|e| InputError::file(path, format!("cannot read light texture: {e}")))?
                .with_guessed_format()
                .map_err(|e| InputError::file(path, format!("cannot read light texture: {e}")))
        };
        let (w, h) = open()?.into_dimensions().map_err(bad)?;
        if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
            return Err(InputError::file(
                path,
                format!("light texture must be 1..={MAX_SIDE} pixels a side, got {w}x{h}"),
            ));
        }
        let mut reader = open()?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_SIDE);
        limits.max_image_height = Some(MAX_SIDE);
        reader.limits(limits);
        let img = reader.decode().map_err(bad)?.to_rgb8();
        let (w, h) = img.dimensions();
        Ok(LightTexture::from_fn(w, h, |i, j| {
            img.get_pixel(i, h - 1 - j).0.map(|v| v as f32 / 255.0)
        }))
    }

    pub fn luminance(c: [f32; 3]) -> f32 {
        LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2]
    }

    /// The scalar visibility of received light `rgb` from a light of mean colour `mean`: the
    /// fraction of its luminance that arrives, clamped to [0, 1].
    pub fn visibility(rgb: [f32; 3], mean: [f32; 3]) -> f32 {
        (Self::luminance(rgb) / Self::luminance(mean)).clamp(0.0, 1.0)
    }

    /// Mean colour over the light (what an unoccluded point receives).
    pub fn mean(&self) -> [f32; 3] {
        let mut s = [0.0f64; 3];
        for t in &self.texels {
            for c in 0..3 {
                s[c] += f64::from(t[c]);
            }
        }
        s.map(|v| (v / self.texels.len() as f64) as f32)
    }

    /// The texel at light coordinate `q` (nearest; the border belongs to the edge texels).
    pub fn at(&self, q: Vec2) -> [f32; 3] {
        let i = (((q.x + 1.0) * 0.5 * self.width as f32).floor() as i64)
            .clamp(0, self.width as i64 - 1) as u32;
        let j = (((q.y + 1.0) * 0.5 * self.height as f32).floor() as i64)
            .clamp(0, self.height as i64 - 1) as u32;
        self.texels[(j * self.width + i) as usize]
    }

    /// The texture box-filtered to at most `max_side` texels a side (area-weighted averages), as
    /// Paper III §3.3 undersamples its fire texture to the coverage texture's `n×n`.
    pub fn resampled(&self, max_side: u32) -> LightTexture {
        if self.width <= max_side && self.height <= max_side {
            return self.clone();
        }
        let (w, h) = (self.width.min(max_side), self.height.min(max_side));
        // Per target cell, the source cells it overlaps and their weights (fractions of it).
        let weights = |src: u32, dst: u32| -> Vec<Vec<(u32, f64)>> {
            (0..dst)
                .map(|d| {
                    let (a, b) = (
                        f64::from(d) * f64::from(src) / f64::from(dst),
                        f64::from(d + 1) * f64::from(src) / f64::from(dst),
                    );
                    (a.floor() as u32..(b.ceil() as u32).min(src))
                        .map(|s| {
                            let o = (f64::from(s + 1).min(b) - f64::from(s).max(a)).max(0.0);
                            (s, o / (b - a))
                        })
                        .collect()
                })
                .collect()
        };
        let (wx, wy) = (weights(self.width, w), weights(self.height, h));
        LightTexture::from_fn(w, h, |i, j| {
            let mut s = [0.0f64; 3];
            for &(y, fy) in &wy[j as usize] {
                for &(x, fx) in &wx[i as usize] {
                    let t = self.texels[(y * self.width + x) as usize];
                    for c in 0..3 {
                        s[c] += f64::from(t[c]) * fx * fy;
                    }
                }
            }
            s.map(|v| v as f32)
        })
    }

    /// `∫ T` over a simple polygon inside `[−1, 1]²` (light-coordinate area units: the whole
    /// light has area 4), exact for the piecewise-constant texture: Green's theorem,
    /// `∬ T dA = ∮ F dy` with `F(x, y) = ∫₋₁ˣ T(s, y) ds`, along each edge split where it
    /// crosses texel borders (there `F` is linear in x). Either orientation.
    pub fn integrate(&self, poly: &[Vec2]) -> [f32; 3] {
        let (w, h) = (self.width as usize, self.height as usize);
        let cell = Vec2::new(2.0 / w as f32, 2.0 / h as f32);
        let mut sum = [0.0f64; 3];
        let mut cuts: Vec<f32> = Vec::new();
        for (k, &a) in poly.iter().enumerate() {
            let b = poly[(k + 1) % poly.len()];
            let d = b - a;
            if d.y == 0.0 {
                continue;
            }
            cuts.clear();
            cuts.extend([0.0, 1.0]);
            for (axis, n) in [(0usize, w), (1usize, h)] {
                let (a_x, d_x, c) = (a[axis], d[axis], cell[axis]);
                if d_x == 0.0 {
                    continue;
                }
                let (lo, hi) = (a_x.min(b[axis]), a_x.max(b[axis]));
                let first = (((lo + 1.0) / c).ceil() as i64).max(1);
                let last = (((hi + 1.0) / c).floor() as i64).min(n as i64 - 1);
                for m in first..=last {
                    let t = (-1.0 + m as f32 * c - a_x) / d_x;
                    if t > 0.0 && t < 1.0 {
                        cuts.push(t);
                    }
                }
            }
            cuts.sort_by(f32::total_cmp);
            for s in cuts.windows(2) {
                let (p0, p1) = (a + d * s[0], a + d * s[1]);
                let dy = f64::from(p1.y - p0.y);
                if dy == 0.0 {
                    continue;
                }
                let mid = (p0 + p1) * 0.5;
                let i = (((mid.x + 1.0) / cell.x).floor() as i64).clamp(0, w as i64 - 1) as usize;
                let j = (((mid.y + 1.0) / cell.y).floor() as i64).clamp(0, h as i64 - 1) as usize;
                let row = &self.texels[j * w..(j + 1) * w];
                let x_i = -1.0 + i as f64 * f64::from(cell.x);
                let x_mid = f64::from(p0.x + p1.x) * 0.5;
                for c in 0..3 {
                    let before: f64 =
                        row[..i].iter().map(|t| f64::from(t[c])).sum::<f64>() * f64::from(cell.x);
                    sum[c] += (before + f64::from(row[i][c]) * (x_mid - x_i)) * dy;
                }
            }
        }
        sum.map(|v| v.abs() as f32)
    }

    /// A stable hash of the texels, for cache keys.
    pub fn hash(&self) -> u64 {
        let mut h = Fnv64::default();
        h.u64(u64::from(self.width)).u64(u64::from(self.height));
        for t in &self.texels {
            h.f32s(t);
        }
        h.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x0: f32, y0: f32, x1: f32, y1: f32) -> Vec<Vec2> {
        vec![
            Vec2::new(x0, y0),
            Vec2::new(x1, y0),
            Vec2::new(x1, y1),
            Vec2::new(x0, y1),
        ]
    }

    #[test]
    fn integral_of_half_red_half_blue_light() {
        let t = LightTexture::from_fn(2, 1, |i, _| {
            if i == 0 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 0.0, 1.0]
            }
        });
        // Whole light: area 2 of red, 2 of blue.
        let all = t.integrate(&square(-1.0, -1.0, 1.0, 1.0));
        assert!((all[0] - 2.0).abs() < 1e-5 && all[1] == 0.0 && (all[2] - 2.0).abs() < 1e-5);
        // A quarter straddling the border: [−0.5, 0.5]×[0, 1] → 0.5 red, 0.5 blue.
        let q = t.integrate(&square(-0.5, 0.0, 0.5, 1.0));
        assert!(
            (q[0] - 0.5).abs() < 1e-5 && (q[2] - 0.5).abs() < 1e-5,
            "{q:?}"
        );
        // A triangle (0,0),(1,0),(0,1) reversed: all blue, area ½.
        let tri = t.integrate(&[Vec2::ZERO, Vec2::new(0.0, 1.0), Vec2::new(1.0, 0.0)]);
        assert!(
            tri[0].abs() < 1e-6 && (tri[2] - 0.5).abs() < 1e-5,
            "{tri:?}"
        );
        // The triangle (−1,−1),(1,−1),(1,1): red part is the triangle under y = x for x < 0,
        // area ½·1·1 = ½; blue part 1·2 − ½·1·1 = 1.5.
        let d = t.integrate(&[
            Vec2::new(-1.0, -1.0),
            Vec2::new(1.0, -1.0),
            Vec2::new(1.0, 1.0),
        ]);
        assert!(
            (d[0] - 0.5).abs() < 1e-5 && (d[2] - 1.5).abs() < 1e-5,
            "{d:?}"
        );
    }

    #[test]
    fn checker_integral_matches_sampling() {
        let t = LightTextureSpec {
            checker: Some(5),
            colors: Some(vec![[1.0, 0.5, 0.0], [0.0, 0.2, 1.0]]),
            ..Default::default()
        }
        .resolve("$.light.texture", Path::new("."))
        .unwrap();
        let poly = [
            Vec2::new(-0.9, -0.3),
            Vec2::new(0.7, -0.95),
            Vec2::new(0.85, 0.6),
            Vec2::new(-0.2, 0.9),
        ];
        let exact = t.integrate(&poly);
        // Midpoint sampling on a fine grid with a point-in-convex-polygon test.
        let n = 800;
        let mut s = [0.0f64; 3];
        for k in 0..n * n {
            let q = Vec2::new(
                -1.0 + (2 * (k % n) + 1) as f32 / n as f32,
                -1.0 + (2 * (k / n) + 1) as f32 / n as f32,
            );
            let inside = (0..4).all(|e| (poly[(e + 1) % 4] - poly[e]).perp_dot(q - poly[e]) >= 0.0);
            if inside {
                let c = t.at(q);
                for ch in 0..3 {
                    s[ch] += f64::from(c[ch]) * 4.0 / (n * n) as f64;
                }
            }
        }
        for ch in 0..3 {
            assert!(
                (f64::from(exact[ch]) - s[ch]).abs() < 5e-3,
                "channel {ch}: {} vs {}",
                exact[ch],
                s[ch]
            );
        }
    }

    /// A PNG whose header declares 11000×11000 pixels (and holds no pixel data) is refused by
    /// its declared size: the header is checked before decoding, which would otherwise allocate
    /// 11000·11000·3 bytes (or fail on the missing data with a message that hides the cause).
    #[test]
    fn png_size_is_checked_from_the_header() {
        fn crc32(bytes: &[u8]) -> u32 {
            let mut c = !0u32;
            for &b in bytes {
                c ^= u32::from(b);
                for _ in 0..8 {
                    c = if c & 1 != 0 {
                        0xEDB8_8320 ^ (c >> 1)
                    } else {
                        c >> 1
                    };
                }
            }
            !c
        }
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend_from_slice(&11000u32.to_be_bytes());
        ihdr.extend_from_slice(&11000u32.to_be_bytes());
        ihdr.extend_from_slice(&[8, 2, 0, 0, 0]); // 8-bit RGB, deflate, no filter, no interlace
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        // IHDR, then an IDAT with an empty zlib stream (far too little data), then IEND.
        for chunk in [
            ihdr,
            b"IDAT\x78\x9c\x03\x00\x00\x00\x00\x01".to_vec(),
            b"IEND".to_vec(),
        ] {
            png.extend_from_slice(&(chunk.len() as u32 - 4).to_be_bytes());
            png.extend_from_slice(&chunk);
            png.extend_from_slice(&crc32(&chunk).to_be_bytes());
        }
        let (_dir, path) = crate::util::paths::temp_path("huge.png");
        std::fs::write(&path, &png).unwrap();
        let e = LightTexture::load_png(&path).unwrap_err();
        assert!(e.message.contains("11000x11000"), "{e}");
        assert!(e.message.contains("4096"), "{e}");
    }

    #[test]
    fn resampling_keeps_the_mean_and_png_rows_flip() {
        let t = LightTexture::from_fn(7, 5, |i, j| [i as f32 / 6.0, j as f32 / 4.0, 0.5]);
        let r = t.resampled(3);
        assert_eq!((r.width, r.height), (3, 3));
        for c in 0..3 {
            assert!((r.mean()[c] - t.mean()[c]).abs() < 1e-5);
        }
        let dir = std::env::temp_dir().join(format!("ssv-light-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("two.png");
        // Top row red, bottom row blue.
        image::RgbImage::from_fn(1, 2, |_, y| {
            image::Rgb(if y == 0 { [255, 0, 0] } else { [0, 0, 255] })
        })
        .save(&path)
        .unwrap();
        let p = LightTexture::load_png(&path).unwrap();
        assert_eq!(p.at(Vec2::new(0.0, 0.5)), [1.0, 0.0, 0.0]);
        assert_eq!(p.at(Vec2::new(0.0, -0.5)), [0.0, 0.0, 1.0]);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn bad_specs_name_field_and_value() {
        let base = Path::new(".");
        let err = |s: LightTextureSpec| s.resolve("$.light.texture", base).unwrap_err();
        let e = err(LightTextureSpec::default());
        assert_eq!(e.field.as_deref(), Some("$.light.texture"));
        assert!(e.message.contains("exactly one"), "{e}");
        let e = err(LightTextureSpec {
            checker: Some(0),
            ..Default::default()
        });
        assert_eq!(e.field.as_deref(), Some("$.light.texture.checker"));
        assert!(e.message.contains("got 0"), "{e}");
        let e = err(LightTextureSpec {
            checker: Some(2),
            colors: Some(vec![[1.0, 0.0, 0.0], [0.0, 1.5, 0.0]]),
            ..Default::default()
        });
        assert_eq!(e.field.as_deref(), Some("$.light.texture.colors[1][1]"));
        assert!(e.message.contains("1.5"), "{e}");
        let e = err(LightTextureSpec {
            color: Some([0.0; 3]),
            ..Default::default()
        });
        assert!(e.message.contains("no light"), "{e}");
        let e = err(LightTextureSpec {
            png: Some("missing-light.png".into()),
            ..Default::default()
        });
        assert_eq!(e.field.as_deref(), Some("$.light.texture.png"));
        assert!(
            e.file.as_ref().unwrap().ends_with("missing-light.png"),
            "{e}"
        );
        let e = err(LightTextureSpec {
            stripes: Some(3),
            colors: Some(vec![[1.0; 3]]),
            ..Default::default()
        });
        assert!(e.message.contains("2 to 64"), "{e}");
    }
}
