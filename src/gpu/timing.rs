//! GPU time per pass from timestamp queries written at the beginning and end of each pass.

use crate::error::Result;

use super::readback::{words, Staging};
use super::Gpu;

/// Timestamps around up to `passes` passes; absent when the adapter has no TIMESTAMP_QUERY.
pub struct PassTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    staging: Staging,
    passes: u32,
}

impl PassTimer {
    pub fn new(gpu: &Gpu, passes: u32) -> Option<PassTimer> {
        if !gpu.queries.timestamp {
            return None;
        }
        let count = 2 * passes;
        let size = 8 * count as u64;
        Some(PassTimer {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            staging: Staging::new(gpu, "timestamp readback", size),
            passes,
        })
    }

    /// Timestamp writes for a render pass `i`.
    pub fn render(&self, i: u32) -> wgpu::RenderPassTimestampWrites<'_> {
        wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * i),
            end_of_pass_write_index: Some(2 * i + 1),
        }
    }

    /// Timestamp writes for a compute pass `i`.
    pub fn compute(&self, i: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * i),
            end_of_pass_write_index: Some(2 * i + 1),
        }
    }

    /// Records the resolve and the copy to the host (after all passes).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.set, 0..2 * self.passes, &self.resolve, 0);
        self.staging.copy(encoder, &self.resolve);
    }

    /// Milliseconds of each pass (after submission).
    pub fn read_ms(&self, gpu: &Gpu) -> Result<Vec<f64>> {
        let ticks: Vec<u64> = words(&self.staging.read(gpu)?);
        let ns_per_tick = gpu.queue.get_timestamp_period() as f64;
        Ok(ticks
            .chunks_exact(2)
            .map(|t| t[1].saturating_sub(t[0]) as f64 * ns_per_tick * 1e-6)
            .collect())
    }
}

/// The milliseconds per pass of `timer`, or `None` and a warning when the adapter has no
/// TIMESTAMP_QUERY (no timer was made).
pub fn read_ms_or_warn(
    gpu: &Gpu,
    timer: &Option<PassTimer>,
    warnings: &mut Vec<String>,
) -> Result<Option<Vec<f64>>> {
    match timer {
        Some(t) => t.read_ms(gpu).map(Some),
        None => {
            warnings.push("adapter has no TIMESTAMP_QUERY: gpu_ms unavailable".into());
            Ok(None)
        }
    }
}
