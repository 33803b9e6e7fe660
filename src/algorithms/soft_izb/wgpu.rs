//! The wgpu execution of soft irregular shadow mapping: the steps of Figure 2 as compute passes
//! (`wgpu.wgsl`), one pass per phase.
//!
//! - `geometry` (host, as on the CPU executions; §4.2 leaves it out of Table 2): occluding
//!   triangles facing the light centre, near-clipped and projected, and the silhouette edges
//!   from adjacency (or every edge, §2.1), by [`object_occluders`], shared with `cpu.rs`, then
//!   uploaded.
//! - `construct` (Figure 2a, Figure 3): the frame's gbuffer projected into light view; the
//!   nearest and farthest receiver found with atomic max/min; each receiver's cell counted with
//!   an atomic increment and its bin's maximum receiver depth recorded with an atomic minimum
//!   of the bits of `1/z` (positive floats order as their bits); a three-step prefix sum over
//!   the cells (blocks of 4096, block offsets, add; the per-cell kernels take 16 consecutive
//!   cells per invocation); then each receiver scattered to the next slot of its cell (an
//!   atomic cursor). Cells are stored in [`Grid::cell`] order, as on the
//!   CPU; within a cell, samples land in whatever order the atomics are served, and nothing
//!   downstream depends on that order.
//! - `hard` (Figure 2b, §2.4): one workgroup per occluding triangle, its 64 invocations
//!   striding over the grid columns under the triangle's bounds and testing every stored sample
//!   from the slice of the triangle's nearest point backwards; depth complexity is counted per
//!   sample with an atomic increment. We chose this scatter form (triangle × covered columns)
//!   over a per-cell gather of binned triangles: it needs no binning or sorting on the GPU, and
//!   since the per-sample results are integer sums, the order the atomics run in cannot change
//!   them.
//! - `soft` (Figure 2c-d, §2.2, §2.3, §2.5): one workgroup per silhouette edge in the same
//!   scatter form over the columns under its penumbra quad. Per column the per-bin quad width
//!   (§2.5, first option) and the quad/column overlap decide whether it is a fragment; the
//!   wedge/column intersection (§2.5, second option) picks the first slice; eq. 3 with the sign
//!   rule runs at every sample from there back. Signed occlusion is accumulated per sample with
//!   integer atomics in fixed point ([`OCCLUSION_SCALE`]: exact, order-independent sums, each
//!   term rounded by at most 2^-21). A last step applies eq. 4 per sample and writes the
//!   sample's eye pixel; pixels with no sample stay lit.
//!
//! The instrumented replay ([`crate::gpu::pass`]) runs `hard` and `soft` again (on the grid
//! the timed `construct` left; `construct` and `resolve` count nothing), counting what the
//! cpu-model counts: grid columns and sample tests of the umbra, quads, bin entries and per-bin
//! culls, quad fragments, wedge-culled fragments, fill (eq. 3 evaluations) and overdraw (those
//! that returned 0). Memory traffic is estimated from these counts and the record sizes.
//!
//! Not built: binning on the GPU (the per-bin width is applied per column of each quad instead
//! of by dropping the quad from a bin's list; the counts of bin entries and culls are the
//! same) and silhouette detection on the GPU (the paper's geometry shaders).

use std::time::Instant;

use serde_json::json;

use super::Phase;
use super::{
    check_grid_size, light_radius_uv, object_occluders, Grid, Occluders, SoftIzbOptions, ID,
    NEAR_CLIP, OCCLUSION_SCALE,
};
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::algorithms::shadow_map::{LightViews, ViewFit};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, workgroups, Bind, Compute, Instrumented, Layout, Pass, Program, Readout, Slots,
    Statistics, Timed, Work,
};
use crate::gpu::readback::words;
use crate::gpu::{record_execution, Needs, Run};
use crate::record::Counters;
use crate::record::PhaseId;

const WGSL: &str = include_str!("wgpu.wgsl");

/// Invocations of the per-item kernels (`@workgroup_size(64)`) and of the scan kernels (256).
const ITEM_WORKGROUP: u32 = 64;
const SCAN_WORKGROUP: u32 = 256;
/// Cells per invocation of the per-cell kernels `clear`, `scan_local` and `scan_add`
/// (`CELLS_PER_ITEM` in the WGSL): the grid has several times more cells than the frame has
/// pixels, and an invocation costs far more than a loop step on a CPU adapter.
const CELLS_PER_ITEM: u32 = 16;
/// Cells per block of the prefix sum (`SCAN_BLOCK` in the WGSL): a 256-wide workgroup's cells.
const SCAN_BLOCK: u32 = SCAN_WORKGROUP * CELLS_PER_ITEM;
/// Storage buffers bound by the kernels (bindings 1-12).
const STORAGE_BUFFERS: u32 = 12;
/// Record sizes: a sample (uv, 1/z, pixel, triangle), a projected triangle with its flat index,
/// a projected edge, a gbuffer entry, a light-view point, a grid word.
const SAMPLE_BYTES: u64 = 20;
const TRIANGLE_BYTES: u64 = 44;
const EDGE_BYTES: u64 = 24;
const GBUFFER_BYTES: u64 = 16;
const POINT_BYTES: u64 = 16;
const WORD: u64 = 4;

/// The statistics slots of the instrumented pipelines (`STAT_*` in the WGSL), in slot order.
#[derive(Clone, Copy)]
enum Stat {
    HardColumns,
    HardTests,
    HardHits,
    HardBinEntries,
    Quads,
    BinCulled,
    SoftBinEntries,
    Fragments,
    WedgeCulled,
    Fill,
    Contributing,
}

const STATS: usize = 11;

gpu_struct! {
    /// The frame's parameters (binding 0); constants come from the host so that they are
    /// defined once, in Rust.
    struct Params as "Params" {
        view_proj: [f32; 16] => "mat4x4<f32>",
        /// Unused; keeps the uniform's layout.
        pad: f32 => "f32",
        /// NEAR_CLIP * far: clip w at or below this has no image-plane position (`in_front`).
        w_min: f32 => "f32",
        /// `light_radius_uv`: the light's radius in uv at unit depth.
        r_uv: f32 => "f32",
        pixels: u32 => "u32",
        /// The grid (Figure 3).
        res: u32 => "u32",
        slices: u32 => "u32",
        bin: u32 => "u32",
        bins_x: u32 => "u32",
        cells_per_bin: u32 => "u32",
        cells: u32 => "u32",
        triangles: u32 => "u32",
        edges: u32 => "u32",
        /// `SoftIzbOptions` (§2.5), as 0/1.
        per_bin_width: u32 => "u32",
        wedge_column_cull: u32 => "u32",
        scan_blocks: u32 => "u32",
        /// `OCCLUSION_SCALE`: fixed-point scale of the penumbral occlusion accumulated with
        /// atomics.
        occlusion_scale: f32 => "f32",
    }
}

/// The shader as the pipelines join it.
const SOURCES: [&str; 3] = [Params::WGSL, WGSL, crate::scene::coverage::WGSL];

/// `soft_izb` on the GPU (`ctx` unused: the passes need nothing of the run's context).
pub fn render(
    gpu: &Run,
    frame: &Frame,
    _ctx: &ExecContext,
    opts: &SoftIzbOptions,
) -> Result<FrameOutput> {
    check_grid_size(frame.params.map_resolution, opts.depth_slices)?;
    let start = Instant::now();
    let light = frame.scene.light;
    let views = LightViews::fit(frame, ViewFit::Single);
    let view = *views.single();
    let mut occ = Occluders::default();
    for o in 0..frame.scene.objects.len() {
        let part = object_occluders(frame, &view, opts, o);
        occ.triangles.extend(part.triangles);
        occ.edges.extend(part.edges);
    }
    let geometry_ms = start.elapsed().as_secs_f64() * 1e3;
    let res = view.resolution.max(1);
    let grid = Grid {
        res,
        slices: opts.depth_slices,
        bin: frame.params.tile_size.clamp(1, res),
        inv_z_front: 1.0,
        inv_z_back: 1.0,
    };
    let params = Params {
        view_proj: view.view_proj.to_cols_array(),
        pad: 0.0,
        w_min: NEAR_CLIP * view.far,
        r_uv: light_radius_uv(&view, light.size()),
        pixels: frame.gbuffer.len() as u32,
        res: grid.res,
        slices: grid.slices,
        bin: grid.bin,
        bins_x: grid.bins_x(),
        cells_per_bin: grid.cells_per_bin() as u32,
        cells: grid.cells() as u32,
        triangles: occ.triangles.len() as u32,
        edges: occ.edges.len() as u32,
        per_bin_width: u32::from(opts.per_bin_width),
        wedge_column_cull: u32::from(opts.wedge_column_cull),
        scan_blocks: (grid.cells() as u32).div_ceil(SCAN_BLOCK),
        occlusion_scale: OCCLUSION_SCALE,
    };
    check_limits(gpu, &params, &grid)?;
    let mut geometry = Counters::default();
    geometry.set(names::OCCLUDER_TRIANGLES, occ.triangles.len() as f64);
    geometry.set(names::SILHOUETTE_EDGES, occ.edges.len() as f64);
    let passes = Passes::new(gpu, frame, &occ, &grid, params);
    let mut out = passes.run(frame, geometry_ms, geometry)?;
    let entries = json!({
        "grid": grid.res,
        "depth_slices": grid.slices,
        "bin": grid.bin,
        "per_bin_width": opts.per_bin_width,
        "wedge_column_cull": opts.wedge_column_cull,
        "silhouettes": opts.silhouettes,
        "occlusion_fixed_point_scale": OCCLUSION_SCALE,
    });
    record_execution(&mut out.execution, entries);
    views.record(&mut out);
    Ok(out)
}

/// The storage buffers, workgroups and largest buffers' bytes, checked against the adapter's
/// limits before anything is created.
fn check_limits(gpu: &Run, p: &Params, grid: &Grid) -> Result<()> {
    let pixels = u64::from(p.pixels);
    let grid_words = u64::from(p.cells) + 1 + u64::from(p.scan_blocks);
    let buffers = [
        ("izb_grid", WORD * grid_words),
        ("izb_samples", SAMPLE_BYTES * pixels),
        ("gbuffer", GBUFFER_BYTES * pixels),
        ("light_triangles", TRIANGLE_BYTES * u64::from(p.triangles)),
        ("bins", WORD * (grid.bins() as u64 + 2)),
    ];
    let needs = Needs {
        storage_buffers: STORAGE_BUFFERS,
        workgroup: SCAN_WORKGROUP,
        buffers: &buffers,
        ..Needs::default()
    };
    gpu.check_limits(ID, needs)
}

/// The resources and pipelines of one frame.
struct Passes<'g> {
    gpu: &'g Run,
    params: Params,
    width: u32,
    height: u32,
    grid: Grid,
    cell_start: wgpu::Buffer,
    visibility: wgpu::Buffer,
    stats: wgpu::Buffer,
    group: wgpu::BindGroup,
    construct: [Compute; 7],
    umbra: Compute,
    penumbra: Compute,
    resolve: Compute,
}

impl<'g> Passes<'g> {
    fn new(gpu: &'g Run, frame: &Frame, occ: &Occluders, grid: &Grid, params: Params) -> Self {
        let g = &frame.gbuffer;
        let pixels = g.len() as u64;
        let storage = wgpu::BufferUsages::STORAGE;
        let uniform = gpu.upload("soft_izb params", &[params], wgpu::BufferUsages::UNIFORM);
        // The gbuffer: position bits with the receiver's flat triangle (u32::MAX for none) in w.
        let positions: Vec<[u32; 4]> = (0..g.len())
            .map(|i| {
                let p = g.position[i];
                [p.x.to_bits(), p.y.to_bits(), p.z.to_bits(), g.triangle[i]]
            })
            .collect();
        let offsets: Vec<[f32; 4]> = g.offset.iter().map(|n| n.extend(0.0).to_array()).collect();
        // A triangle: each vertex's uv and 1/z, twice its uv area (bits), its flat index.
        let triangles: Vec<u32> = occ
            .triangles
            .iter()
            .flat_map(|(flat, t)| {
                let floats = t.v.iter().flat_map(|v| [v.uv.x, v.uv.y, v.inv_z]);
                floats.chain([t.area2]).map(f32::to_bits).chain([*flat])
            })
            .collect();
        let edges: Vec<[f32; 6]> = occ
            .edges
            .iter()
            .map(|e| [e.a.uv.x, e.a.uv.y, e.a.inv_z, e.b.uv.x, e.b.uv.y, e.b.inv_z])
            .collect();
        let cells = u64::from(params.cells);
        let copy_src = wgpu::BufferUsages::COPY_SRC;
        let grid_words = cells + 1 + u64::from(params.scan_blocks);
        let stats_copy = copy_src | wgpu::BufferUsages::COPY_DST;
        let buffers = [
            gpu.upload("gbuffer positions", &positions, storage),
            gpu.upload("gbuffer offsets", &offsets, storage),
            gpu.storage_buffer("light-view points", POINT_BYTES * pixels, storage),
            gpu.storage_buffer("bins", WORD * (grid.bins() as u64 + 2), storage),
            gpu.storage_buffer("cell counts", WORD * cells, storage),
            gpu.storage_buffer("izb_grid", WORD * grid_words, copy_src),
            gpu.storage_buffer("izb_samples", SAMPLE_BYTES * pixels, storage),
            gpu.storage_buffer("occlusion", 2 * WORD * pixels, storage),
            gpu.storage_buffer("visibility", WORD * pixels, copy_src),
            gpu.upload("light triangles", &triangles, storage),
            gpu.upload("penumbra edges", &edges, storage),
            gpu.storage_buffer("statistics", 2 * WORD * STATS as u64, stats_copy),
        ];
        // Binding 0 the parameters, then bindings 1-12 in order; the gbuffer and the primitives
        // are only read.
        let kind = |i| match i {
            0 => Bind::Uniform,
            1 | 2 | 10 | 11 => Bind::ReadOnly,
            _ => Bind::ReadWrite,
        };
        let binds: Vec<_> = (0..)
            .zip(std::iter::once(&uniform).chain(&buffers))
            .map(|(i, b)| (kind(i), b.as_entire_binding()))
            .collect();
        let compute = wgpu::ShaderStages::COMPUTE;
        let (layout, group) = Layout::bound(gpu, "soft_izb", compute, &binds);
        let program = Program::new(gpu, "soft_izb/wgpu.wgsl", &SOURCES, &[Some(&layout)]);
        // The construction and `resolve` count nothing: the replay leaves them out.
        let pipeline = |entry: &str| Instrumented::timed(program.compute(gpu, entry, Some(false)));
        let construct = [
            "clear",
            "project",
            "count",
            "scan_local",
            "scan_blocks",
            "scan_add",
            "insert",
        ]
        .map(pipeline);
        let [_, _, _, _, _, cell_start, _, _, visibility, _, _, stats] = buffers;
        Passes {
            gpu,
            params,
            width: g.width,
            height: g.height,
            grid: *grid,
            cell_start,
            visibility,
            stats,
            group,
            construct,
            umbra: program.instrumented(gpu, "umbra"),
            penumbra: program.instrumented(gpu, "penumbra"),
            resolve: pipeline("resolve"),
        }
    }

    /// Phase `phase` (construct, hard or soft; geometry is the host's) as one compute pass.
    fn pass(&self, phase: Phase) -> Pass<'_> {
        let (gpu, p) = (self.gpu, &self.params);
        let items = |n: u32| workgroups(gpu, n.div_ceil(ITEM_WORKGROUP));
        let dispatches = match phase {
            Phase::Geometry => vec![],
            Phase::Construct => {
                // One invocation per CELLS_PER_ITEM cells, and at least one per depth record.
                let clear = p.cells.div_ceil(CELLS_PER_ITEM);
                let clear = clear.max(self.grid.bins() as u32 + 2);
                let cell_runs = p.cells.div_ceil(CELLS_PER_ITEM);
                let c = &self.construct;
                vec![
                    (&c[0], items(clear)),
                    (&c[1], items(p.pixels)),
                    (&c[2], items(p.pixels)),
                    (&c[3], workgroups(gpu, p.scan_blocks)),
                    (&c[4], (1, 1)),
                    (&c[5], items(cell_runs)),
                    (&c[6], items(p.pixels)),
                ]
            }
            Phase::Hard => vec![(&self.umbra, workgroups(gpu, p.triangles))],
            Phase::Soft => vec![
                (&self.penumbra, workgroups(gpu, p.edges)),
                (&self.resolve, items(p.pixels)),
            ],
        };
        Pass {
            label: phase.name(),
            groups: vec![Some(&self.group)],
            work: Work::Dispatch(dispatches),
        }
    }

    /// The run after the host's `geometry` phase (its wall time and counters).
    fn run(&self, frame: &Frame, geometry_ms: f64, geometry: Counters) -> Result<FrameOutput> {
        // The timed submission: each phase submitted and waited for on its own.
        let readback = [&self.visibility, &self.cell_start];
        // The instrumented replay: `hard` and `soft` read what the timed `construct` left
        // (nothing after it writes it) and add into accumulators nothing reads after `resolve`.
        let mut run = Timed::new(self.gpu, Phase::ALL, Statistics::Compute, &readback)
            .counting_into(&self.stats, Readout::End);
        run.add_wall(Phase::Geometry, geometry_ms);
        for phase in [Phase::Construct, Phase::Hard, Phase::Soft] {
            run.submit(phase, &[self.pass(phase)])?;
        }
        let mut timing = run.finish()?;
        // The samples stored: the prefix sum's total, after the last cell.
        let samples = f64::from(words::<u32>(&timing.readback[1])[self.params.cells as usize]);

        let slot = Slots::of(&timing.counts[0]);
        let stat = |s: Stat| slot.get(s as usize);

        let hits = frame.gbuffer.mask().iter().filter(|&&h| h).count() as f64;
        let counters = vec![
            (Phase::Geometry, geometry),
            (Phase::Construct, self.construct_counters(hits, samples)),
            (Phase::Hard, self.hard_counters(&stat)),
            (Phase::Soft, self.soft_counters(&stat, samples)),
        ];
        let outside = hits - samples;
        if outside > 0.0 {
            timing.warnings.push(format!(
                "{outside} receiver points lie at or behind the light's view plane and are taken \
                 as lit"
            ));
        }
        let note =
            "columns, tests, fragments, fill and overdraw from an instrumented replay (WGSL \
                    atomics); mem_est.* estimated from counts and record sizes";
        Ok(timing.output((self.width, self.height), counters, note))
    }

    /// `construct`: the samples stored, the bytes of the grid and sample array (as on the
    /// CPU), the global atomics (two for the scene's depth range, one count, one bin depth and
    /// one cursor per sample), and estimated traffic.
    fn construct_counters(&self, hits: f64, n: f64) -> Counters {
        let pixels = f64::from(self.params.pixels);
        let cells = f64::from(self.params.cells);
        let w = WORD as f64;
        let mut k = Counters::default();
        k.set(names::SAMPLES, n);
        k.set(names::IZB_GRID_BYTES, w * (cells + 1.0));
        k.set(names::IZB_SAMPLES_BYTES, SAMPLE_BYTES as f64 * n);
        k.set(names::ATOMICS, 5.0 * n);
        // project: gbuffer read (offsets of hit pixels), points written; count and insert read
        // the points, count writes the cell; the scan reads the counts twice and writes starts
        // and cursors; insert scatters the records and clears their accumulators.
        let gbuffer = GBUFFER_BYTES as f64 * (pixels + hits);
        let points_read = 2.0 * POINT_BYTES as f64 * pixels;
        let points_write = POINT_BYTES as f64 * pixels + w * n;
        let grid_read = 2.0 * w * cells;
        let grid_write = 3.0 * w * cells + 2.0 * w * n;
        let samples_write = SAMPLE_BYTES as f64 * n + 2.0 * w * n;
        let reads = [
            ("gbuffer", gbuffer),
            ("points", points_read),
            ("izb_grid", grid_read),
        ];
        let writes = [
            ("points", points_write),
            ("izb_grid", grid_write),
            ("izb_samples", samples_write),
            ("visibility", w * pixels),
        ];
        k.add_traffic("mem_est", &reads, &writes);
        k
    }

    /// `hard`: columns visited, samples tested and covered, bin entries, estimated traffic.
    fn hard_counters(&self, stat: &impl Fn(Stat) -> f64) -> Counters {
        let [columns, tests, hits] = [Stat::HardColumns, Stat::HardTests, Stat::HardHits].map(stat);
        let w = WORD as f64;
        let mut k = Counters::default();
        k.set(names::HARD_COLUMNS, columns);
        k.set(names::HARD_TESTS, tests);
        k.set(names::HARD_HITS, hits);
        k.set(names::BIN_ENTRIES, stat(Stat::HardBinEntries));
        k.set(names::ATOMICS, hits);
        let triangles = TRIANGLE_BYTES as f64 * f64::from(self.params.triangles);
        let grid = 2.0 * w * columns;
        let samples = SAMPLE_BYTES as f64 * tests;
        // Each covered sample's depth complexity is an atomic increment: read and written.
        let reads = [
            ("light_triangles", triangles),
            ("izb_grid", grid),
            ("izb_samples", samples),
            ("occlusion", w * hits),
        ];
        k.add_traffic("mem_est", &reads, &[("occlusion", w * hits)]);
        k
    }

    /// `soft`: quads, bin entries and culls, fragments, wedge culls, fill and overdraw in the
    /// cpu-model's terms, and estimated traffic (resolve included).
    fn soft_counters(&self, stat: &impl Fn(Stat) -> f64, n: f64) -> Counters {
        let [fragments, fill, contributing] =
            [Stat::Fragments, Stat::Fill, Stat::Contributing].map(stat);
        let w = WORD as f64;
        let mut k = Counters::default();
        k.set(names::PENUMBRA_QUADS, stat(Stat::Quads));
        k.set(names::BIN_ENTRIES, stat(Stat::SoftBinEntries));
        k.set(names::BIN_CULLED_QUADS, stat(Stat::BinCulled));
        k.set(names::QUAD_FRAGMENTS, fragments);
        k.set(names::WEDGE_CULLED_FRAGMENTS, stat(Stat::WedgeCulled));
        k.add_fill(fill, fill - contributing);
        k.set(names::ATOMICS, contributing);
        let edges = EDGE_BYTES as f64 * f64::from(self.params.edges);
        let grid = 2.0 * w * fragments;
        let samples = SAMPLE_BYTES as f64 * (fill + n);
        let occlusion_read = w * contributing + 2.0 * w * n;
        let occlusion_write = w * contributing;
        let reads = [
            ("penumbra_edges", edges),
            ("izb_grid", grid),
            ("izb_samples", samples),
            ("occlusion", occlusion_read),
        ];
        let writes = [("occlusion", occlusion_write), ("visibility", w * n)];
        k.add_traffic("mem_est", &reads, &writes);
        k
    }
}

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(SOURCES => Params);
