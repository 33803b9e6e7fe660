//! What every CPU execution shares: the modelled machine of a run and the frame output built
//! from it when the run is done.

use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::frame::Frame;
use crate::model::raster::{Target, BLOCK};
use crate::model::{lane_groups, task_items, Buffer, Machine, Mask, Probe, TaskKernel};
use crate::visibility::VisibilityBuffer;
use rayon::prelude::*;

/// The machine an execution runs on: the context's configuration with the run's core count.
pub fn machine(backend: Backend, frame: &Frame, ctx: &ExecContext) -> Machine {
    let config = match frame.params.cores {
        Some(c) => ctx.machine.with_cores(c),
        None => ctx.machine.clone(),
    };
    Machine::new(backend, config)
        .with_deadline(ctx.deadline)
        .timing_tasks(ctx.time_tasks)
}

/// Wraps a finished machine and the visibility into a frame output.
pub fn output(m: Machine, visibility: VisibilityBuffer) -> FrameOutput {
    let f = m.finish();
    FrameOutput {
        visibility,
        counters: f.counters,
        phases: f.phases,
        model_ms: f.model_ms,
        gpu_ms: None,
        execution: f.execution,
        warnings: vec![],
        rgb: None,
        gpu_setup_ms: None,
    }
}

/// The eye image cut into the frame's screen tiles: the task grid of an eye pass.
pub fn eye_tiles(frame: &Frame) -> Target {
    let g = &frame.gbuffer;
    Target {
        width: g.width,
        height: g.height,
        tile: frame.params.tile_size,
    }
}

/// One 4×4 block ([`BLOCK`]) of an eye tile, clipped to the tile: the unit an eye pass
/// works in.
#[derive(Clone, Copy, Debug)]
pub struct EyeBlock {
    /// The block's first pixel.
    pub x0: u32,
    pub y0: u32,
    /// Its rows and columns inside the tile (1 to 4 each).
    pub rows: u32,
    pub cols: u32,
    /// The eye image's width in pixels.
    width: u32,
}

impl EyeBlock {
    /// The pixel index of the first pixel of row `row` of the block.
    pub fn row_start(&self, row: u32) -> usize {
        ((self.y0 + row) * self.width + self.x0) as usize
    }

    /// The block's visibility stored row by row into `visibility` (modelled stores of the
    /// block's pixels), and (pixel index, visibility) appended to `out` for every lane
    /// (`row * 4 + column`) that `value` gives one; the other pixels keep the lit default.
    pub fn store<P: Probe>(
        &self,
        p: &mut P,
        visibility: &Buffer<f32>,
        out: &mut Vec<(u32, f32)>,
        value: impl Fn(usize) -> Option<f32>,
    ) {
        for row in 0..self.rows {
            let i = self.row_start(row);
            visibility.record_store(p, i, self.cols as usize);
            for c in 0..self.cols {
                if let Some(v) = value((row * BLOCK + c) as usize) {
                    out.push((i as u32 + c, v));
                }
            }
        }
    }
}

/// The per-block work of an eye pass; [`eye_lookup_step`] runs it over the eye tiles.
pub trait EyeKernel: Sync {
    /// Appends (pixel index, visibility) of the pixels of `block` that the pass shades.
    fn block<P: Probe>(&self, p: &mut P, block: &EyeBlock, out: &mut Vec<(u32, f32)>);
}

/// An eye pass as a task kernel: one eye tile per task, its blocks row by row.
struct EyeTiles<'a, K> {
    kernel: &'a K,
    tiles: Target,
}

impl<K: EyeKernel> TaskKernel for EyeTiles<'_, K> {
    /// (pixel index, visibility) of the tile's pixels that the pass shades.
    type Out = Vec<(u32, f32)>;

    fn run<P: Probe>(&self, p: &mut P, tile: usize) -> Self::Out {
        let t = self.tiles.tile_rect(tile);
        let mut out = Vec::with_capacity(((t.x1 - t.x0) * (t.y1 - t.y0)) as usize);
        for (x0, y0) in t.blocks() {
            // The block's loop control and pixel offset.
            p.scalar(2);
            let block = EyeBlock {
                x0,
                y0,
                rows: BLOCK.min(t.y1 - y0),
                cols: BLOCK.min(t.x1 - x0),
                width: self.tiles.width,
            };
            self.kernel.block(p, &block, &mut out);
        }
        out
    }
}

/// Step `lookup` of an eye pass: `kernel` run over the eye tiles ([`eye_tiles`]) with
/// `weights` ([`Target::tile_weights`]); the visibility of the pixels it shades written into
/// an image that is lit everywhere else.
pub fn eye_lookup_step<K: EyeKernel>(
    m: &mut Machine,
    frame: &Frame,
    kernel: &K,
    weights: &[u64],
) -> VisibilityBuffer {
    let step = EyeTiles {
        kernel,
        tiles: eye_tiles(frame),
    };
    let g = &frame.gbuffer;
    let mut vis = VisibilityBuffer::lit(g.width, g.height);
    let tiles = m.run_step("lookup", &step, weights);
    // The tiles of one row of tiles write only the image rows they span: each such band is
    // filled by one host thread.
    let band = (step.tiles.tile * g.width) as usize;
    let tiles_x = step.tiles.tiles_x() as usize;
    vis.data
        .par_chunks_mut(band)
        .zip(tiles.par_chunks(tiles_x))
        .enumerate()
        .for_each(|(row, (data, row_tiles))| {
            let first = row * band;
            for (i, v) in row_tiles.iter().flatten() {
                data[*i as usize - first] = *v;
            }
        });
    vis
}

/// Edges per task of a brute-force edge scan ([`scan_edges`]).
pub const EDGE_CHUNK: usize = 1024;

/// Task `task` of a brute-force scan over the edge records `edges`
/// ([`crate::scene::adjacency::EdgeAdjacency::edge_records`]), [`EDGE_CHUNK`] edges a task: per
/// vector of up to 16 edges, the records loaded, then `f(p, first edge, edge count, lane mask,
/// records)`.
pub fn scan_edges<P: Probe>(
    p: &mut P,
    edges: &Buffer<[u32; 4]>,
    task: usize,
    mut f: impl FnMut(&mut P, usize, usize, Mask, &[[u32; 4]]),
) {
    for (group, k, mask) in lane_groups(task_items(task, EDGE_CHUNK, edges.data.len())) {
        let recs = edges.load_run(p, group, k);
        f(p, group, k, mask, recs);
    }
}
