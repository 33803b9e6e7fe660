//! The eye-view visibility buffer (fraction of the light visible per pixel) and its files.

use std::io::Write;
use std::path::Path;

use npyz::WriterBuilder;

use crate::error::{Error, Result};

/// Fraction of the light visible at each eye pixel, row-major, y down, values in [0, 1].
/// Pixels that see no surface hold 1.
#[derive(Clone, Debug, PartialEq)]
pub struct VisibilityBuffer {
    pub width: u32,
    pub height: u32,
    pub data: Vec<f32>,
}

impl VisibilityBuffer {
    pub fn lit(width: u32, height: u32) -> VisibilityBuffer {
        VisibilityBuffer {
            width,
            height,
            data: vec![1.0; (width * height) as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> f32 {
        self.data[(y * self.width + x) as usize]
    }

    /// Checks the invariant every result must satisfy: finite and within [0, 1].
    /// Returns the first offending pixel.
    pub fn check_range(&self) -> std::result::Result<(), String> {
        match self
            .data
            .iter()
            .position(|v| !v.is_finite() || !(0.0..=1.0).contains(v))
        {
            None => Ok(()),
            Some(i) => Err(format!(
                "visibility at pixel ({}, {}) is {} (outside [0, 1])",
                i as u32 % self.width,
                i as u32 / self.width,
                self.data[i]
            )),
        }
    }

    /// 8-bit grayscale PNG.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let bytes: Vec<u8> = self
            .data
            .iter()
            .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect();
        image::GrayImage::from_raw(self.width, self.height, bytes)
            .expect("buffer size matches image size")
            .save(path)
            .map_err(|e| Error::Other(format!("{}: {e}", path.display())))
    }

    /// float32 NumPy array of shape (H, W).
    pub fn write_npy(&self, path: &Path) -> Result<()> {
        let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(&[self.height as u64, self.width as u64])
            .writer(std::io::BufWriter::new(file))
            .begin_nd()
            .map_err(|e| Error::io(path, e))?;
        w.extend(self.data.iter().copied())
            .map_err(|e| Error::io(path, e))?;
        w.finish().map_err(|e| Error::io(path, e))
    }

    /// Reads a visibility buffer written by [`Self::write_npy`]: a 2-D `float32` array (rows by
    /// columns, C or Fortran order: [`crate::util::npy::read_2d`]) of values in [0, 1]. Another
    /// shape or type, a side of 0, or a value outside [0, 1] (NaN and infinities included), is
    /// an input error naming the file (and the pixel).
    pub fn read_npy(
        path: &Path,
    ) -> std::result::Result<VisibilityBuffer, crate::error::InputError> {
        let a = crate::util::npy::read_2d::<f32>(path, "visibility array", "float32")?;
        let v = VisibilityBuffer {
            width: a.width,
            height: a.height,
            data: a.data,
        };
        v.check_range()
            .map_err(|e| crate::error::InputError::file(path, e))?;
        Ok(v)
    }
}

/// Light received per channel at each eye pixel under a textured or coloured light
/// ([`crate::scene::light_texture`]), row-major, y down, values in [0, 1]; an unoccluded point
/// holds the light's mean colour.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbBuffer {
    pub width: u32,
    pub height: u32,
    pub data: Vec<[f32; 3]>,
}

impl RgbBuffer {
    /// 8-bit RGB PNG (linear values times 255).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let bytes: Vec<u8> = self
            .data
            .iter()
            .flat_map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
            .collect();
        image::RgbImage::from_raw(self.width, self.height, bytes)
            .expect("buffer size matches image size")
            .save(path)
            .map_err(|e| Error::Other(format!("{}: {e}", path.display())))
    }
}

/// Writes `bytes` to `path` atomically: a temporary file beside it with a name no other
/// process or thread uses ([`crate::harness::outdir::temp_path`]), then a rename, so a reader
/// (or an interrupted run) never sees a half-written file. On failure the temporary file is
/// removed; one left by a killed process is removed by the next command into the folder.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = crate::harness::outdir::temp_path(path);
    let result = write_then_rename(&tmp, path, bytes);
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// [`write_atomic`] of a file the user named with option `field` (`--out`): an error names
/// `path`, not the temporary file, and one that comes from the path (no permission, a
/// read-only file system, a folder in the way) is an input error on `field` (exit 2).
pub fn write_output(path: &Path, bytes: &[u8], field: &str) -> Result<()> {
    write_atomic(path, bytes).map_err(|e| match e {
        Error::Io { source, .. } => {
            use std::io::ErrorKind as K;
            let why = format!("cannot write '{}': {source}", path.display());
            match source.kind() {
                K::PermissionDenied
                | K::ReadOnlyFilesystem
                | K::NotADirectory
                | K::IsADirectory
                | K::NotFound => crate::error::InputError::new(field, why).into(),
                _ => Error::Other(why),
            }
        }
        e => e,
    })
}

/// Writes `bytes` to `tmp`, syncs it and renames it to `path`.
fn write_then_rename(tmp: &Path, path: &Path, bytes: &[u8]) -> Result<()> {
    let mut f = std::fs::File::create(tmp).map_err(|e| Error::io(tmp, e))?;
    f.write_all(bytes).map_err(|e| Error::io(tmp, e))?;
    f.sync_all().map_err(|e| Error::io(tmp, e))?;
    std::fs::rename(tmp, path).map_err(|e| Error::io(path, e))
}
