//! `accum_hard` on the CPU executions (`cpu-native`, `cpu-model`): per light sample a hard
//! shadow-volume pass into the stencil (phase `hard`) and the accumulation of its lit pixels
//! (phase `accumulate`), both as tile tasks of the machine.

use super::Phase;
use super::{AccumHardOptions, Samples, ACCUMULATION_BYTES, STENCIL_BYTES};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::{machine, output};
use crate::algorithms::eye_raster::{tiles, Block, EyeBuffer, EyeRays, ScreenRect};
use crate::algorithms::shadow_volume::{
    eye_count, mem_read, mem_write, render_hard, CountTarget, Counting, HardCounting, HardPass,
};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::model::raster::Target;
use crate::model::{Probe, TaskKernel};
use crate::record::PhaseId;
use crate::visibility::VisibilityBuffer;

/// Vector instructions per block of the accumulation: compare the stencil with zero, select
/// 1 or 0, add.
const ACCUMULATE_OPS: u32 = 3;

/// Adds one sample's lit pixels (stencil zero) to the accumulation buffer, one tile per task.
/// The buffer is kept per tile (row-major inside its tile); a task returns its tile's new sums.
struct Accumulate<'a> {
    rays: &'a EyeRays,
    tiles: Target,
    pass: &'a HardPass,
    sums: &'a [Vec<u32>],
    stencil: EyeBuffer,
    accumulation: EyeBuffer,
}

impl TaskKernel for Accumulate<'_> {
    type Out = Vec<u32>;

    fn run<P: Probe>(&self, p: &mut P, t: usize) -> Vec<u32> {
        let r = self.tiles.tile_rect(t);
        let rect = ScreenRect {
            x0: r.x0,
            y0: r.y0,
            x1: r.x1,
            y1: r.y1,
        };
        let w = rect.x1 - rect.x0;
        let mut sums = self.sums[t].clone();
        for b in Block::cover(self.rays, rect) {
            self.stencil.read(p, &b, b.mask);
            self.accumulation.read(p, &b, b.mask);
            p.vector(ACCUMULATE_OPS, b.mask);
            for l in b.mask.lanes() {
                let (x, y) = b.lane_xy(l);
                sums[((y - rect.y0) * w + x - rect.x0) as usize] +=
                    u32::from(self.pass.count[b.pixel[l] as usize] == 0);
            }
            self.accumulation.write(p, &b, b.mask);
        }
        sums
    }
}

pub fn render(
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
    opts: &AccumHardOptions,
) -> Result<FrameOutput> {
    let mut m = machine(backend, frame, ctx);
    let rays = EyeRays::new(frame);
    let samples = Samples::new(frame, ctx, opts)?;
    let occluders = &samples.occluders;
    let n = rays.len() as u64;
    let hard = CountTarget {
        depth: EyeBuffer::new(&mut m, &rays, "depth", 4),
        count: EyeBuffer::new(&mut m, &rays, "stencil", STENCIL_BYTES),
        clear: true,
    };
    let tiles = tiles(&rays, frame.params.tile_size);
    let mut sums: Vec<Vec<u32>> = (0..tiles.tiles())
        .map(|t| {
            let r = tiles.tile_rect(t);
            vec![0; ((r.x1 - r.x0) * (r.y1 - r.y0)) as usize]
        })
        .collect();
    let accumulation = EyeBuffer::new(&mut m, &rays, "accumulation", ACCUMULATION_BYTES);
    let weights: Vec<u64> = sums.iter().map(|s| s.len() as u64).collect();
    for s in 0..samples.count() {
        m.phase(Phase::Hard.name());
        let (sample, quads) = samples.quads(s);
        let counting = match opts.counting {
            Counting::ZPass => HardCounting::ZPass {
                eye_count: eye_count(occluders, sample, rays.eye),
            },
            Counting::ZFail => HardCounting::ZFail {
                occluders,
                light: sample,
            },
        };
        let pass = render_hard(
            &mut m,
            "stencil",
            &rays,
            &quads,
            counting,
            frame.params.tile_size,
            &hard,
        );
        m.count(names::SILHOUETTE_EDGES, quads.len() as f64);
        if opts.counting == Counting::ZFail {
            m.count(names::VOLUME_CAPS, pass.caps as f64);
        }
        m.count(names::FILL, pass.fill as f64);
        m.count(names::OVERDRAW, (pass.fill - pass.passed) as f64);
        mem_write(&mut m, "stencil", n * u64::from(STENCIL_BYTES));
        mem_read(&mut m, "depth", pass.fill * 4);
        mem_read(&mut m, "stencil", pass.passed * u64::from(STENCIL_BYTES));
        mem_write(&mut m, "stencil", pass.passed * u64::from(STENCIL_BYTES));

        m.phase(Phase::Accumulate.name());
        let step = Accumulate {
            rays: &rays,
            tiles,
            pass: &pass,
            sums: &sums,
            stencil: hard.count,
            accumulation,
        };
        sums = m.run_step("accumulate", &step, &weights);
        mem_read(&mut m, "stencil", n * u64::from(STENCIL_BYTES));
        mem_read(&mut m, "accumulation", n * u64::from(ACCUMULATION_BYTES));
        mem_write(&mut m, "accumulation", n * u64::from(ACCUMULATION_BYTES));
    }
    let mut data = vec![1.0f32; rays.len()];
    for (t, s) in sums.iter().enumerate() {
        let r = tiles.tile_rect(t);
        let w = r.x1 - r.x0;
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let i = (y * rays.width + x) as usize;
                if rays.is_hit(i) {
                    data[i] =
                        s[((y - r.y0) * w + x - r.x0) as usize] as f32 / samples.count() as f32;
                }
            }
        }
    }
    let visibility = VisibilityBuffer {
        width: frame.width(),
        height: frame.height(),
        data,
    };
    let mut out = output(m, visibility);
    out.execution
        .insert("samples".to_string(), serde_json::json!(samples.count()));
    out.execution
        .insert("counting".to_string(), serde_json::json!(opts.counting));
    Ok(out)
}
