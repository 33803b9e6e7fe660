//! Memory limits: a run's working set is estimated before anything is allocated, and a run
//! that would exceed the limit is refused with the estimate instead of being killed.

use crate::algorithms::{AlgorithmInfo, Backend};
use crate::error::{Error, Result};
use crate::frame::RunParams;
use crate::model::cache::{CoreCaches, SharedCache};
use crate::model::MachineConfig;

/// Physical memory from /proc/meminfo, when readable.
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Default limit: half of physical memory (8 GiB when it cannot be read).
pub fn default_limit() -> u64 {
    physical_memory().map_or(8 << 30, |m| m / 2)
}

/// The memory limit of this process in bytes, once a command sets it (`--memory-limit`).
static PROCESS_LIMIT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Sets the memory limit of this process (bytes): what every allocation sized from a file
/// ([`process_limit`]) is bounded by.
pub fn set_process_limit(bytes: u64) {
    PROCESS_LIMIT.store(bytes, std::sync::atomic::Ordering::Relaxed);
}

/// The memory limit of this process: the one [`set_process_limit`] set, else
/// [`default_limit`]. Files read whole (scenarios, machines, results, meshes, glTF buffers,
/// `.npy` arrays) larger than it are refused before they are read.
pub fn process_limit() -> u64 {
    match PROCESS_LIMIT.load(std::sync::atomic::Ordering::Relaxed) {
        0 => default_limit(),
        n => n,
    }
}

/// Peak bytes per scene triangle while a frame is built, whatever the algorithm: the scene's
/// meshes, their flattened copy, the BVH with its build's temporaries and the occluders' edge
/// adjacency. Measured as the peak resident memory of `render --no-reference` on
/// sphere-on-plane at 32x24 between 0.5 and 4 million triangles (`/usr/bin/time -v`): about
/// 320 bytes per triangle for every algorithm; 5% added.
pub const FRAME_BYTES_PER_TRIANGLE: u64 = 336;

/// Bytes every run holds whatever the algorithm: the eye pass (position, normal, triangle per
/// pixel), the result and the reference (f32 per pixel), and the geometry
/// ([`FRAME_BYTES_PER_TRIANGLE`]).
pub fn frame_bytes(p: &RunParams) -> u64 {
    let pixels = p.image[0] as u64 * p.image[1] as u64;
    pixels * (12 + 12 + 4 + 4 + 4) + p.triangles as u64 * FRAME_BYTES_PER_TRIANGLE
}

/// Bytes of the modelled caches of a `cpu-model` run on `machine` (0 on other backends): every
/// core's L1 and L2 partition plus the one core of single-core steps
/// ([`crate::model::Machine::set_single_core`]), and the shared L3 where the machine has one,
/// all allocated when the run starts. The run's `cores` overrides the machine's.
pub fn model_bytes(backend: Backend, machine: &MachineConfig, p: &RunParams) -> u64 {
    if backend != Backend::CpuModel {
        return 0;
    }
    let cores = p.cores.unwrap_or(machine.cores) as u64;
    (cores + 1) * CoreCaches::bytes(machine) + SharedCache::bytes(machine)
}

/// Refuses a run on `backend` whose estimated working set (the frame, the algorithm's buffers
/// and, on `cpu-model`, the modelled caches of `machine`) exceeds `limit` bytes.
pub fn check(
    info: &AlgorithmInfo,
    backend: Backend,
    machine: &MachineConfig,
    p: &RunParams,
    limit: u64,
) -> Result<()> {
    let caches = model_bytes(backend, machine, p);
    let estimate = frame_bytes(p)
        .saturating_add((info.memory_estimate)(p))
        .saturating_add(caches);
    if estimate > limit {
        let of_caches = if caches > 0 {
            format!(
                " ({} of it the modelled caches of {} cores)",
                bytes(caches),
                p.cores.unwrap_or(machine.cores)
            )
        } else {
            String::new()
        };
        return Err(Error::Resource(format!(
            "{} on {backend} at {}x{} with map resolution {} needs about {}{of_caches}, over the limit of {} (raise it with --memory-limit, in GiB)",
            info.id,
            p.image[0],
            p.image[1],
            p.map_resolution,
            bytes(estimate),
            bytes(limit)
        )));
    }
    Ok(())
}

/// A byte count in the largest binary unit that keeps it at least 1 (`1.50 GiB`, `12.00 KiB`).
pub fn bytes(n: u64) -> String {
    let units = ["bytes", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < units.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} bytes")
    } else {
        format!("{v:.2} {}", units[unit])
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn byte_counts_read_in_a_fitting_unit() {
        assert_eq!(super::bytes(512), "512 bytes");
        assert_eq!(super::bytes(1536), "1.50 KiB");
        assert_eq!(super::bytes(3 << 30), "3.00 GiB");
    }
}
