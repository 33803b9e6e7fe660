//! Deliberate GPU faults, for testing that a sweep survives them.
//!
//! `SHADOWBENCH_INJECT_FAULT` holds a comma-separated list of `KIND@N`: the fault `KIND` happens
//! at the start of the `N`-th wgpu execution of the process (counting from 1; every iteration of
//! the measurement protocol is one, so with `--warmup 0 --repeats 1` the `N`-th run), inside
//! that execution's error scopes, exactly as if the algorithm had caused it:
//!
//! - `device-lost`: the device is destroyed, as a driver reset or a removed GPU would;
//! - `shader-error`: a shader module with a WGSL syntax error is created;
//! - `buffer-limit`: a buffer one byte larger than the device's `max_buffer_size` is created.
//!
//! Without the variable nothing happens. docs/robustness.md lists what the product does with
//! each fault and how to reproduce it.

use std::sync::atomic::{AtomicU64, Ordering};

use super::Gpu;

/// Environment variable naming the faults to inject.
pub const FAULT_ENV: &str = "SHADOWBENCH_INJECT_FAULT";

/// A fault that can be injected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    DeviceLost,
    ShaderError,
    BufferLimit,
}

impl Fault {
    const ALL: [(&'static str, Fault); 3] = [
        ("device-lost", Fault::DeviceLost),
        ("shader-error", Fault::ShaderError),
        ("buffer-limit", Fault::BufferLimit),
    ];
}

/// Parses a `KIND@N,...` list; the error names the entry and the kinds there are.
pub fn parse(spec: &str) -> Result<Vec<(Fault, u64)>, String> {
    spec.split(',')
        .map(str::trim)
        .filter(|e| !e.is_empty())
        .map(|entry| {
            let (kind, at) = entry
                .split_once('@')
                .ok_or_else(|| format!("'{entry}' is not KIND@RUN"))?;
            let fault = Fault::ALL
                .iter()
                .find(|(name, _)| *name == kind)
                .map(|&(_, f)| f)
                .ok_or_else(|| {
                    let kinds: Vec<&str> = Fault::ALL.iter().map(|(n, _)| *n).collect();
                    format!("unknown fault '{kind}' (known: {})", kinds.join(", "))
                })?;
            let run = at.parse::<u64>().ok().filter(|&n| n >= 1).ok_or_else(|| {
                format!("{FAULT_ENV}: '{at}' in '{entry}' is not a run number ≥ 1")
            })?;
            Ok((fault, run))
        })
        .collect()
}

/// Number of wgpu runs started in this process.
static RUNS: AtomicU64 = AtomicU64::new(0);

/// Counts a wgpu run and injects the faults planned for it (called by [`super::guarded_run`]).
pub(super) fn inject(gpu: &Gpu) {
    let run = RUNS.fetch_add(1, Ordering::SeqCst) + 1;
    let Ok(spec) = std::env::var(FAULT_ENV) else {
        return;
    };
    let faults = match parse(&spec) {
        Ok(f) => f,
        Err(e) => {
            crate::errln!("{FAULT_ENV}: {e}; no fault injected");
            return;
        }
    };
    for (fault, _) in faults.into_iter().filter(|&(_, at)| at == run) {
        crate::errln!("wgpu run {run}: injecting {fault:?}");
        match fault {
            Fault::DeviceLost => gpu.device.destroy(),
            Fault::ShaderError => {
                let _broken = gpu
                    .device
                    .create_shader_module(wgpu::ShaderModuleDescriptor {
                        label: Some("injected fault"),
                        source: wgpu::ShaderSource::Wgsl("fn broken( {".into()),
                    });
            }
            Fault::BufferLimit => {
                let _too_large = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("injected fault"),
                    size: gpu.limits.max_buffer_size.saturating_add(1),
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_lists_and_rejects_bad_entries() {
        assert_eq!(
            parse("device-lost@2, shader-error@5").unwrap(),
            vec![(Fault::DeviceLost, 2), (Fault::ShaderError, 5)]
        );
        assert!(parse("device-lost").unwrap_err().contains("KIND@RUN"));
        assert!(parse("melt@1").unwrap_err().contains("known: device-lost"));
        assert!(parse("buffer-limit@0").unwrap_err().contains("run number"));
    }
}
