//! Reference images cached in memory and on disk, keyed by everything that determines them:
//! geometry, camera, light, image size, sample count and seed. Sweeps over parameters that do
//! not change the ground truth (map resolution, tile size, cores, algorithm) reuse one image.
//!
//! On disk each image is `reference-<key>.npy` (float32, H×W) with a sidecar
//! `reference-<key>.json` ([`CacheEntry`]: format version, key, sample count, seed, shape and the
//! CRC-32 of the `.npy` file). A cached image is used only when its sidecar matches what the
//! run asks for, the checksum verifies and every value is finite and within [0, 1]; anything
//! else (a missing or different sidecar, a damaged or replaced file, NaN or values outside
//! [0, 1]) is recomputed and rewritten, with a warning that says why.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::algorithms::reference;
use crate::error::Result;
use crate::frame::Frame;
use crate::util::deadline::Deadline;
use crate::util::hash::Fnv64;
use crate::visibility::{write_atomic, VisibilityBuffer};

/// Version of the on-disk cache format (the `.npy` layout and the sidecar's fields); entries
/// of another version are recomputed.
pub const FORMAT_VERSION: u32 = 1;

/// What a cached image was computed from, and its checksum: the sidecar of each `.npy`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CacheEntry {
    pub format_version: u32,
    /// The cache key, 16 hex digits ([`ReferenceCache::key`]).
    pub key: String,
    /// Light samples per pixel of the reference.
    pub samples: u32,
    pub seed: u64,
    /// Image width and height in pixels.
    pub width: u32,
    pub height: u32,
    /// CRC-32 of the `.npy` file's bytes, 8 hex digits.
    pub crc32: String,
}

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
        // Shadow rays pass through receiver-only objects (`SceneBvh::occluded`); images cached
        // before that, when such objects blocked them, must not be found under the same key.
        if s.objects.iter().any(|o| !o.role.occluder) {
            h.bytes(b"receiver-only objects cast no shadow");
        }
        h.finish()
    }

    /// The `.npy` of `key` and its sidecar.
    fn files(&self, key: u64) -> Option<(PathBuf, PathBuf)> {
        self.dir.as_ref().map(|d| {
            (
                d.join(format!("reference-{key:016x}.npy")),
                d.join(format!("reference-{key:016x}.json")),
            )
        })
    }

    /// The sidecar an image of `frame` computed now would get, without its checksum.
    fn expected(&self, frame: &Frame, key: u64) -> CacheEntry {
        CacheEntry {
            format_version: FORMAT_VERSION,
            key: format!("{key:016x}"),
            samples: self.samples,
            seed: self.seed,
            width: frame.width(),
            height: frame.height(),
            crc32: String::new(),
        }
    }

    /// The cached reference of `frame`: `Ok(None)` when there is none, `Err(why)` when a
    /// cached file exists but cannot be trusted (see the module docs).
    pub fn get(&self, frame: &Frame) -> std::result::Result<Option<VisibilityBuffer>, String> {
        let key = self.key(frame);
        if let Some(b) = self.memory.get(&key) {
            return Ok(Some(b.clone()));
        }
        let Some((npy, json)) = self.files(key) else {
            return Ok(None);
        };
        if !npy.exists() {
            return Ok(None);
        }
        verify(&npy, &json, &self.expected(frame, key)).map(Some)
    }

    /// Stores a reference computed for `frame` in memory, and on disk when a folder is set.
    /// The disk copy is written under a temporary name and renamed, so a reader never sees half
    /// a file; an error writing it (a full or read-only cache folder) is returned after the
    /// image is kept in memory.
    pub fn put(&mut self, frame: &Frame, b: &VisibilityBuffer) -> Result<()> {
        let key = self.key(frame);
        self.memory.insert(key, b.clone());
        if let Some((file, json)) = self.files(key) {
            let dir = file.parent().expect("cache file has a folder");
            std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
            let tmp = crate::harness::outdir::temp_path(&file);
            let written = b.write_npy(&tmp).and_then(|_| {
                let bytes = std::fs::read(&tmp).map_err(|e| crate::error::Error::io(&tmp, e))?;
                let entry = CacheEntry {
                    crc32: format!("{:08x}", crc32fast::hash(&bytes)),
                    ..self.expected(frame, key)
                };
                std::fs::rename(&tmp, &file).map_err(|e| crate::error::Error::io(&file, e))?;
                let text = serde_json::to_vec_pretty(&entry).expect("cache entries serialize");
                write_atomic(&json, &text)
            });
            if written.is_err() {
                let _ = std::fs::remove_file(&tmp);
            }
            written?;
        }
        Ok(())
    }

    /// The reference of `frame`, from the cache when a trusted copy is there, else computed
    /// (and cached). The second value holds a warning for each cached copy that was not trusted
    /// and was recomputed instead. The cache folder is optional: when it cannot be written
    /// (full, read-only), a warning says so once and the cache goes on in memory only.
    pub fn get_or_compute(&mut self, frame: &Frame) -> Result<(VisibilityBuffer, Vec<String>)> {
        self.get_or_compute_until(frame, Deadline::default())
    }

    /// [`Self::get_or_compute`], a reference computed now stopping at `deadline` (the run's
    /// budget: it unwinds with [`crate::util::deadline::Cancelled`], and nothing is cached).
    pub fn get_or_compute_until(
        &mut self,
        frame: &Frame,
        deadline: Deadline,
    ) -> Result<(VisibilityBuffer, Vec<String>)> {
        let mut warnings = Vec::new();
        match self.get(frame) {
            Ok(Some(b)) => return Ok((b, warnings)),
            Ok(None) => {}
            Err(why) => warnings.push(format!("reference cache: {why}; recomputed")),
        }
        let b = reference::render_until(frame, self.samples, self.seed, deadline).visibility;
        if let Err(e) = self.put(frame, &b) {
            crate::errln!("warning: reference cache: {e}; going on without the cache folder");
            self.dir = None;
        }
        Ok((b, warnings))
    }

    /// Stops using the cache folder (keeps the images in memory).
    pub fn memory_only(&mut self) {
        self.dir = None;
    }
}

/// Reads the cached `npy` and checks it against its sidecar `json` and `want` (everything but
/// the checksum), the checksum, and the range of every value.
fn verify(
    npy: &Path,
    json: &Path,
    want: &CacheEntry,
) -> std::result::Result<VisibilityBuffer, String> {
    let name = npy.display();
    let text = std::fs::read(json)
        .map_err(|e| format!("{name} has no readable sidecar {} ({e})", json.display()))?;
    let entry: CacheEntry = serde_json::from_slice(&text)
        .map_err(|e| format!("sidecar {} is not a cache entry ({e})", json.display()))?;
    let stated = CacheEntry {
        crc32: String::new(),
        ..entry.clone()
    };
    if stated != *want {
        return Err(format!(
            "{name} was computed from {stated:?}, this run needs {want:?}"
        ));
    }
    let bytes = std::fs::read(npy).map_err(|e| format!("{name}: {e}"))?;
    let crc = format!("{:08x}", crc32fast::hash(&bytes));
    if crc != entry.crc32 {
        return Err(format!(
            "{name} does not match its checksum (CRC-32 {crc}, sidecar says {})",
            entry.crc32
        ));
    }
    let b = VisibilityBuffer::read_npy(npy).map_err(|e| e.to_string())?;
    if (b.width, b.height) != (want.width, want.height) {
        return Err(format!(
            "{name} is {}x{}, expected {}x{}",
            b.width, b.height, want.width, want.height
        ));
    }
    b.check_range().map_err(|m| format!("{name}: {m}"))?;
    Ok(b)
}

/// Writes a small JSON sidecar next to cached images describing the key (for humans).
pub fn describe(dir: &std::path::Path) -> Result<()> {
    let readme = dir.join("README.txt");
    if !readme.exists() {
        std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
        write_atomic(
            &readme,
            b"Cached ground-truth visibility buffers (float32 .npy), keyed by a hash of geometry,\n\
camera, light, image size, sample count and seed. Each .json beside an .npy states what it\n\
was computed from and its CRC-32; entries that do not verify are recomputed. Safe to delete.\n",
        )?;
    }
    Ok(())
}
