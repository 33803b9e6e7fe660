//! Pipeline statistics per pass (vertex, clipper, fragment and compute invocations), where the
//! adapter offers PIPELINE_STATISTICS_QUERY.

use crate::error::Result;
use crate::record::Counters;

use super::readback::{resolve_buffer, words, Staging};
use super::timing::{query_sets, QUERY_SET_MAX};
use super::Gpu;

/// The statistic that means something for compute passes.
pub const COMPUTE_INVOCATIONS: &str = "pipeline.compute_shader_invocations";

/// The statistics gathered, in the order the query writes them (bit order of
/// [`wgpu::PipelineStatisticsTypes`]), with the counter names they get.
const STATISTICS: [(wgpu::PipelineStatisticsTypes, &str); 5] = [
    (
        wgpu::PipelineStatisticsTypes::VERTEX_SHADER_INVOCATIONS,
        "pipeline.vertex_shader_invocations",
    ),
    (
        wgpu::PipelineStatisticsTypes::CLIPPER_INVOCATIONS,
        "pipeline.clipper_invocations",
    ),
    (
        wgpu::PipelineStatisticsTypes::CLIPPER_PRIMITIVES_OUT,
        "pipeline.clipper_primitives_out",
    ),
    (
        wgpu::PipelineStatisticsTypes::FRAGMENT_SHADER_INVOCATIONS,
        "pipeline.fragment_shader_invocations",
    ),
    (
        wgpu::PipelineStatisticsTypes::COMPUTE_SHADER_INVOCATIONS,
        COMPUTE_INVOCATIONS,
    ),
];

/// One pipeline-statistics query per pass; absent without PIPELINE_STATISTICS_QUERY.
pub struct PassStats {
    /// One query per pass, in sets of at most [`super::timing::QUERY_SET_MAX`].
    sets: Vec<wgpu::QuerySet>,
    resolve: wgpu::Buffer,
    staging: Staging,
    passes: u32,
}

impl PassStats {
    pub fn new(gpu: &Gpu, passes: u32) -> Option<PassStats> {
        if !gpu.queries.pipeline_statistics {
            return None;
        }
        let types = STATISTICS
            .iter()
            .fold(wgpu::PipelineStatisticsTypes::empty(), |a, (t, _)| a | *t);
        let size = 8 * (STATISTICS.len() as u32 * passes) as u64;
        Some(PassStats {
            sets: query_sets(passes)
                .map(|(_, n)| {
                    gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                        label: Some("pipeline statistics"),
                        ty: wgpu::QueryType::PipelineStatistics(types),
                        count: n,
                    })
                })
                .collect(),
            resolve: resolve_buffer(gpu, "pipeline statistics resolve", size),
            staging: Staging::new(gpu, "pipeline statistics readback", size),
            passes,
        })
    }

    pub fn begin_render(&self, pass: &mut wgpu::RenderPass<'_>, i: u32) {
        pass.begin_pipeline_statistics_query(
            &self.sets[(i / QUERY_SET_MAX) as usize],
            i % QUERY_SET_MAX,
        );
    }

    pub fn begin_compute(&self, pass: &mut wgpu::ComputePass<'_>, i: u32) {
        pass.begin_pipeline_statistics_query(
            &self.sets[(i / QUERY_SET_MAX) as usize],
            i % QUERY_SET_MAX,
        );
    }

    /// Records the resolve and the copy to the host (after all passes).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        let bytes = 8 * STATISTICS.len() as u64;
        for ((first, n), set) in query_sets(self.passes).zip(&self.sets) {
            encoder.resolve_query_set(set, 0..n, &self.resolve, bytes * first as u64);
        }
        self.staging.copy(encoder, &self.resolve);
    }

    /// The statistics of each pass as counters (after submission).
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<Counters>> {
        let values: Vec<u64> = words(&self.staging.read(gpu)?);
        Ok(values
            .chunks_exact(STATISTICS.len())
            .map(|v| {
                let mut c = Counters::default();
                for ((_, name), x) in STATISTICS.iter().zip(v) {
                    c.set(name, *x as f64);
                }
                c
            })
            .collect())
    }
}

/// The counters per pass of `stats` (one per submission, in order), end to end, or `None` and
/// a warning when the adapter has no PIPELINE_STATISTICS_QUERY (no query set was made).
pub fn read_or_warn(
    gpu: &Gpu,
    stats: &[PassStats],
    warnings: &mut Vec<String>,
) -> Result<Option<Vec<Counters>>> {
    if stats.is_empty() {
        warnings.push("adapter has no PIPELINE_STATISTICS_QUERY: no pipeline.* counters".into());
        return Ok(None);
    }
    let mut all = Vec::new();
    for s in stats {
        all.extend(s.read(gpu)?);
    }
    Ok(Some(all))
}
