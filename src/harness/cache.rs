//! Reference images cached in memory and on disk, keyed by everything that determines them:
//! geometry, camera, light, image size, sample count and seed. Sweeps over parameters that do
//! not change the ground truth (map resolution, tile size, cores, algorithm) reuse one image.

use std::collections::HashMap;
use std::path::PathBuf;

use crate::algorithms::reference;
use crate::error::Result;
use crate::frame::Frame;
use crate::util::hash::Fnv64;
use crate::visibility::{write_atomic, VisibilityBuffer};

pub struct ReferenceCache {
    dir: Option<PathBuf>,
    memory: HashMap<u64, VisibilityBuffer>,
    pub samples: u32,
    pub seed: u64,
}

impl ReferenceCache {
    pub fn new(dir: Option<PathBuf>, samples: u32, seed: u64) -> ReferenceCache {
        ReferenceCache {
            dir,
            memory: HashMap::new(),
            samples,
            seed,
        }
    }

    pub fn key(&self, frame: &Frame) -> u64 {
        let s = &frame.scene;
        let c = s.camera;
        let mut h = Fnv64::default();
        h.u64(s.geometry_hash())
            .f32s(&c.eye.to_array())
            .f32s(&c.target.to_array())
            .f32s(&c.up.to_array())
            .f32s(&[c.fov_y_deg])
            .bytes(
                serde_json::to_string(&s.light)
                    .unwrap_or_default()
                    .as_bytes(),
            )
            .u64(frame.params.image[0] as u64)
            .u64(frame.params.image[1] as u64)
            .u64(self.samples as u64)
            .u64(self.seed);
        // Only textured lights add to the key, so untextured keys stay as they were.
        if let Some(t) = &s.light_texture {
            h.u64(t.hash());
        }
        h.finish()
    }

    fn file(&self, key: u64) -> Option<PathBuf> {
        self.dir
            .as_ref()
            .map(|d| d.join(format!("reference-{key:016x}.npy")))
    }

    pub fn get(&self, frame: &Frame) -> Option<VisibilityBuffer> {
        let key = self.key(frame);
        if let Some(b) = self.memory.get(&key) {
            return Some(b.clone());
        }
        let file = self.file(key)?;
        let b = VisibilityBuffer::read_npy(&file).ok()?;
        (b.width == frame.width() && b.height == frame.height()).then_some(b)
    }

    /// Stores a reference computed for `frame` in memory, and on disk when a folder is set.
    /// The disk copy is written under a temporary name and renamed, so a reader never sees half
    /// a file; an error writing it (a full or read-only cache folder) is returned after the
    /// image is kept in memory.
    pub fn put(&mut self, frame: &Frame, b: &VisibilityBuffer) -> Result<()> {
        let key = self.key(frame);
        self.memory.insert(key, b.clone());
        if let Some(file) = self.file(key) {
            let dir = file.parent().expect("cache file has a folder");
            std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
            let tmp = crate::harness::outdir::temp_path(&file);
            let written = b.write_npy(&tmp).and_then(|_| {
                std::fs::rename(&tmp, &file).map_err(|e| crate::error::Error::io(&file, e))
            });
            if written.is_err() {
                let _ = std::fs::remove_file(&tmp);
            }
            written?;
        }
        Ok(())
    }

    /// The reference of `frame`: from memory, from the cache folder, or computed. The cache is
    /// optional: when the folder cannot be written (full, read-only), a warning says so once
    /// and the cache goes on in memory only.
    pub fn get_or_compute(&mut self, frame: &Frame) -> Result<VisibilityBuffer> {
        if let Some(b) = self.get(frame) {
            return Ok(b);
        }
        let b = reference::render(frame, self.samples, self.seed).visibility;
        if let Err(e) = self.put(frame, &b) {
            eprintln!("warning: reference cache: {e}; going on without the cache folder");
            self.dir = None;
        }
        Ok(b)
    }

    /// Stops using the cache folder (keeps the images in memory).
    pub fn memory_only(&mut self) {
        self.dir = None;
    }
}

/// Writes a small JSON sidecar next to cached images describing the key (for humans).
pub fn describe(dir: &std::path::Path) -> Result<()> {
    let readme = dir.join("README.txt");
    if !readme.exists() {
        std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
        write_atomic(
            &readme,
            b"Cached ground-truth visibility buffers (float32 .npy), keyed by a hash of geometry,\n\
camera, light, image size, sample count and seed. Safe to delete.\n",
        )?;
    }
    Ok(())
}
