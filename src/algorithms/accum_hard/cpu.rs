//! `accum_hard` on the host (`cpu-native`).

use std::time::Instant;

use super::{AccumHardOptions, ID};
use crate::algorithms::eye_raster::{EyeRays, DEPTH_BYTES};
use crate::algorithms::shadow_map::parse_options;
use crate::algorithms::shadow_volume::{eye_count, mem_read, mem_write, render_quads, ShadowQuad};
use crate::algorithms::{ExecContext, FrameOutput};
use crate::error::Result;
use crate::frame::Frame;
use crate::record::{Counters, Phase};
use crate::scene::adjacency::EdgeAdjacency;
use crate::visibility::VisibilityBuffer;

/// Bytes of a stencil value and of an accumulation-buffer value (16-bit per channel).
const STENCIL_BYTES: u64 = 1;
const ACCUMULATION_BYTES: u64 = 2;

pub fn render(frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    let opts: AccumHardOptions = parse_options(ID, &ctx.options)?;
    let k = opts.strata_side()?;
    let rays = EyeRays::new(frame);
    let occluders = frame.scene.occluders();
    let adjacency = EdgeAdjacency::build(&occluders);
    let light = frame.scene.light;
    let target = frame.scene.bounds().center();
    let n = rays.len() as u64;
    let mut lit = vec![0u32; rays.len()];
    let (mut hard, mut accumulate) = (Phase::default(), Phase::default());
    hard.name = "hard".into();
    accumulate.name = "accumulate".into();
    for s in 0..k * k {
        let start = Instant::now();
        let sample = light.stratified_sample(target, s, k, ctx.seed);
        let silhouette = adjacency.silhouette_from(sample);
        let quads: Vec<ShadowQuad> = silhouette
            .edges
            .iter()
            .map(|e| ShadowQuad::new(e, sample))
            .collect();
        let pass = render_quads(
            &rays,
            &quads,
            eye_count(&occluders, sample, rays.eye),
            frame.params.tile_size,
        );
        let c = &mut hard.counters;
        c.add("silhouette_edges", quads.len() as f64);
        c.add("fill", pass.fill as f64);
        c.add("overdraw", (pass.fill - pass.passed) as f64);
        mem_write(c, "stencil", n * STENCIL_BYTES);
        mem_read(c, "depth", pass.fill * DEPTH_BYTES);
        mem_read(c, "stencil", pass.passed * STENCIL_BYTES);
        mem_write(c, "stencil", pass.passed * STENCIL_BYTES);
        hard.wall_ms += start.elapsed().as_secs_f64() * 1e3;

        // Add this sample's lit pixels (stencil zero) into the accumulation buffer.
        let start = Instant::now();
        for (l, &count) in lit.iter_mut().zip(&pass.count) {
            *l += (count == 0) as u32;
        }
        let c = &mut accumulate.counters;
        mem_read(c, "stencil", n * STENCIL_BYTES);
        mem_read(c, "accumulation", n * ACCUMULATION_BYTES);
        mem_write(c, "accumulation", n * ACCUMULATION_BYTES);
        accumulate.wall_ms += start.elapsed().as_secs_f64() * 1e3;
    }
    let data = (0..rays.len())
        .map(|i| {
            if rays.is_hit(i) {
                lit[i] as f32 / (k * k) as f32
            } else {
                1.0
            }
        })
        .collect();
    let mut counters = Counters::default();
    counters.merge(&hard.counters);
    counters.merge(&accumulate.counters);
    let fill = counters.get("fill").unwrap_or(0.0);
    counters.set(
        "overdraw_ratio",
        if fill > 0.0 {
            counters.get("overdraw").unwrap_or(0.0) / fill
        } else {
            0.0
        },
    );
    Ok(FrameOutput {
        visibility: VisibilityBuffer {
            width: frame.width(),
            height: frame.height(),
            data,
        },
        counters,
        phases: vec![hard, accumulate],
        model_ms: None,
        gpu_ms: None,
        execution: [("samples".to_string(), serde_json::json!(k * k))].into(),
        warnings: vec![],
    })
}
