//! `cpu-native` execution of soft irregular shadow mapping: the four steps of Figure 2 on the
//! host, bin by bin as the sort-middle rasterizer of §2.5 does, with the work of each phase
//! counted from what the kernels actually touch (samples tested, atomics, bytes per buffer).
//!
//! Every per-bin result is computed independently and merged in bin order, and each bin walks
//! its triangles and quads in input order, so the image and the counters do not depend on the
//! host's thread count.

use std::time::Instant;

use glam::{Vec2, Vec4};
use rayon::prelude::*;

use super::{
    clip_and_project, clip_coords, clip_segment, combined_visibility, in_front, light_point,
    light_radius_uv, quad_half_width, wedge_entry_inv_z, Grid, LightPoint, LightTriangle,
    PenumbraQuad, ProjectedEdge, SilhouetteSource, SoftIzbOptions,
};
use crate::algorithms::shadow_map::LightView;
use crate::algorithms::FrameOutput;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::record::{Counters, Phase};
use crate::scene::adjacency::{EdgeAdjacency, EdgeKind};
use crate::visibility::VisibilityBuffer;

/// Bytes of one stored receiver sample: uv, 1/z, eye pixel, receiver triangle.
const SAMPLE_BYTES: f64 = 20.0;
/// Bytes of a projected triangle (three uv + 1/z) and of a projected edge (two).
const TRIANGLE_BYTES: f64 = 36.0;
const EDGE_BYTES: f64 = 24.0;

/// One eye-view receiver point in the grid.
#[derive(Clone, Copy, Debug)]
struct Sample {
    p: LightPoint,
    pixel: u32,
    triangle: u32,
}

/// The light-space acceleration structure of Figure 3.
struct Izb {
    grid: Grid,
    /// Start of each cell's samples in `samples` (cells + 1 entries).
    cell_start: Vec<u32>,
    samples: Vec<Sample>,
    /// Per bin, `1/z` of its deepest receiver (`INFINITY` for a bin without samples).
    bin_inv_z_back: Vec<f32>,
}

impl Izb {
    fn bin_range(&self, b: usize) -> std::ops::Range<usize> {
        let c = self.grid.cells_per_bin();
        self.cell_start[b * c] as usize..self.cell_start[(b + 1) * c] as usize
    }

    /// Samples of column (x, y) from slice `k0` to the back.
    fn column_from(&self, x: u32, y: u32, k0: u32) -> std::ops::Range<usize> {
        let g = &self.grid;
        self.cell_start[g.cell(x, y, k0)] as usize
            ..self.cell_start[g.cell(x, y, g.slices - 1) + 1] as usize
    }
}

/// Per-phase counters with the byte totals kept per named buffer.
#[derive(Default)]
struct Tally(Counters);

impl Tally {
    fn read(&mut self, buffer: &str, bytes: f64) {
        self.0.add(&format!("mem.{buffer}.read_bytes"), bytes);
        self.0.add("mem_read_bytes", bytes);
    }

    fn write(&mut self, buffer: &str, bytes: f64) {
        self.0.add(&format!("mem.{buffer}.write_bytes"), bytes);
        self.0.add("mem_write_bytes", bytes);
    }
}

fn phase(name: &str, start: Instant, tally: Tally) -> Phase {
    Phase {
        name: name.into(),
        wall_ms: start.elapsed().as_secs_f64() * 1e3,
        counters: tally.0,
        ..Default::default()
    }
}

/// Step (a) of Figure 2: project the receiver points and insert them into the grid: count per
/// cell and record per-bin maximum depth (atomics), prefix-sum, then scatter each sample to its
/// cell's next slot (an atomic cursor). Returns the structure and the pixels with no
/// light-view position (at or behind the light's view plane).
fn construct(frame: &Frame, view: &LightView, opts: &SoftIzbOptions, t: &mut Tally) -> (Izb, u64) {
    let g = &frame.gbuffer;
    let projected: Vec<Option<LightPoint>> = (0..g.len())
        .into_par_iter()
        .map(|i| {
            if !g.is_hit(i) {
                return None;
            }
            let c = clip_coords(view, g.position[i] + g.normal[i] * frame.epsilon);
            in_front(view, c).then(|| light_point(c))
        })
        .collect();
    let pixels = g.len() as f64;
    let hits = (0..g.len()).filter(|&i| g.is_hit(i)).count() as u64;
    t.read("gbuffer", pixels * 4.0 + hits as f64 * 24.0);

    let (mut front, mut back) = (f32::NEG_INFINITY, f32::INFINITY);
    for p in projected.iter().flatten() {
        front = front.max(p.inv_z);
        back = back.min(p.inv_z);
    }
    let res = view.resolution.max(1);
    let mut grid = Grid {
        res,
        slices: opts.depth_slices,
        bin: frame.params.tile_size.clamp(1, res),
        inv_z_front: front,
        inv_z_back: back,
    };
    if !front.is_finite() {
        grid.inv_z_front = 1.0;
        grid.inv_z_back = 1.0;
    }

    let cells = grid.cells();
    let mut cell_start = vec![0u32; cells + 1];
    let mut bin_inv_z_back = vec![f32::INFINITY; grid.bins()];
    let mut cell_of = vec![0u32; g.len()];
    let mut n = 0u64;
    for (i, p) in projected.iter().enumerate() {
        if let Some(p) = p {
            let (x, y) = grid.column(p.uv);
            let c = grid.cell(x, y, grid.slice(p.inv_z));
            cell_of[i] = c as u32;
            cell_start[c + 1] += 1;
            let b = grid.bin_of_column(x, y);
            bin_inv_z_back[b] = bin_inv_z_back[b].min(p.inv_z);
            n += 1;
        }
    }
    // Cell count and bin maximum depth: one atomic read-modify-write each per sample.
    t.0.add("atomics", 2.0 * n as f64);
    t.read("izb_grid", 4.0 * n as f64);
    t.write("izb_grid", 4.0 * n as f64);
    t.read("bins", 4.0 * n as f64);
    t.write("bins", 4.0 * n as f64);

    for c in 0..cells {
        cell_start[c + 1] += cell_start[c];
    }
    t.read("izb_grid", 4.0 * cells as f64);
    t.write("izb_grid", 4.0 * cells as f64);

    let mut cursor = cell_start.clone();
    let placeholder = Sample {
        p: LightPoint {
            uv: Vec2::ZERO,
            inv_z: 0.0,
        },
        pixel: 0,
        triangle: 0,
    };
    let mut samples = vec![placeholder; n as usize];
    for (i, p) in projected.iter().enumerate() {
        if let Some(p) = p {
            let c = cell_of[i] as usize;
            samples[cursor[c] as usize] = Sample {
                p: *p,
                pixel: i as u32,
                triangle: g.triangle[i],
            };
            cursor[c] += 1;
        }
    }
    // The cursor is a fetch-and-add; the sample store is a scatter.
    t.0.add("atomics", n as f64);
    t.0.add("scatters", n as f64);
    t.read("izb_grid", 4.0 * n as f64);
    t.write("izb_grid", 4.0 * n as f64);
    t.write("izb_samples", SAMPLE_BYTES * n as f64);
    t.0.set("samples", n as f64);
    t.0.set("mem.izb_grid.bytes", 4.0 * (cells + 1) as f64);
    t.0.set("mem.izb_samples.bytes", SAMPLE_BYTES * n as f64);
    t.0.set("mem.bins.bytes", 4.0 * grid.bins() as f64);
    (
        Izb {
            grid,
            cell_start,
            samples,
            bin_inv_z_back,
        },
        hits - n,
    )
}

/// The occluding geometry seen from the light centre: triangles for the umbra (with their flat
/// index, to skip a receiver's own triangle) and penumbra edges.
struct Occluders {
    triangles: Vec<(u32, LightTriangle)>,
    edges: Vec<ProjectedEdge>,
}

/// The paper's geometry stage (§2.1, §4.2: silhouette detection and primitive setup, not
/// counted in Table 2). A triangle occludes when it faces the light centre; in an open mesh
/// (boundary or non-manifold edges) every triangle does, as the surface has no back to pair
/// with. Penumbra edges are the silhouette from adjacency, or every edge of every occluding
/// triangle (§2.1), each oriented with its surface inside.
fn occluders(frame: &Frame, view: &LightView, opts: &SoftIzbOptions, t: &mut Tally) -> Occluders {
    let centre = frame.scene.light.center();
    let per_object: Vec<Occluders> = frame
        .scene
        .objects
        .par_iter()
        .enumerate()
        .map(|(o, object)| {
            if !object.role.occluder {
                return Occluders {
                    triangles: vec![],
                    edges: vec![],
                };
            }
            let base = frame
                .flat
                .object_of_triangle
                .partition_point(|&x| (x as usize) < o) as u32;
            let adj = EdgeAdjacency::build(&object.mesh);
            let closed =
                adj.count(EdgeKind::Boundary) == 0 && adj.count(EdgeKind::NonManifold) == 0;
            let mut tris = Vec::new();
            let mut edges = Vec::new();
            let clip = |i: u32| clip_coords(view, adj.vertices[i as usize]);
            for (f, tri) in adj.triangles.iter().enumerate() {
                let Some(front) = adj.faces_point(f as u32, centre) else {
                    continue;
                };
                if !front && closed {
                    continue;
                }
                let poly: Vec<Vec4> = tri.iter().map(|&i| clip(i)).collect();
                let pts = clip_and_project(view, &poly);
                for k in 1..pts.len().saturating_sub(1) {
                    if let Some(lt) = LightTriangle::new([pts[0], pts[k], pts[k + 1]]) {
                        tris.push((base + f as u32, lt));
                    }
                }
                if opts.silhouettes == SilhouetteSource::AllEdges {
                    let v = if front {
                        *tri
                    } else {
                        [tri[0], tri[2], tri[1]]
                    };
                    for k in 0..3 {
                        edges.push((v[k], v[(k + 1) % 3]));
                    }
                }
            }
            if opts.silhouettes == SilhouetteSource::Adjacency {
                edges = adj
                    .silhouette_from(centre)
                    .edges
                    .iter()
                    .map(|e| (e.v[0], e.v[1]))
                    .collect();
            }
            let projected = edges
                .into_iter()
                .filter_map(|(a, b)| clip_segment(view, clip(a), clip(b)))
                .map(|(a, b)| ProjectedEdge { a, b })
                .collect();
            Occluders {
                triangles: tris,
                edges: projected,
            }
        })
        .collect();
    let mut occ = Occluders {
        triangles: vec![],
        edges: vec![],
    };
    for o in per_object {
        occ.triangles.extend(o.triangles);
        occ.edges.extend(o.edges);
    }
    t.0.set("occluder_triangles", occ.triangles.len() as f64);
    t.0.set("silhouette_edges", occ.edges.len() as f64);
    t.write(
        "light_triangles",
        TRIANGLE_BYTES * occ.triangles.len() as f64,
    );
    t.write("penumbra_edges", EDGE_BYTES * occ.edges.len() as f64);
    occ
}

/// Inclusive column range of uv bounds clipped to bin `b`, if they meet.
fn columns_in_bin(grid: &Grid, b: usize, lo: Vec2, hi: Vec2) -> Option<((u32, u32), (u32, u32))> {
    let ((x0, y0), (x1, y1)) = grid.column_range(lo, hi);
    let ((bx0, by0), (bx1, by1)) = grid.bin_columns(b);
    let (x0, y0, x1, y1) = (x0.max(bx0), y0.max(by0), x1.min(bx1), y1.min(by1));
    (x0 <= x1 && y0 <= y1).then_some(((x0, y0), (x1, y1)))
}

/// Bins overlapped by uv bounds, in bin order.
fn bins_of(grid: &Grid, lo: Vec2, hi: Vec2) -> impl Iterator<Item = usize> + '_ {
    let ((x0, y0), (x1, y1)) = grid.column_range(lo, hi);
    let (b0, b1) = (
        (x0 / grid.bin, y0 / grid.bin),
        (x1 / grid.bin, y1 / grid.bin),
    );
    (b0.1..=b1.1)
        .flat_map(move |by| (b0.0..=b1.0).map(move |bx| (by * grid.bins_x() + bx) as usize))
}

/// Step (b) of Figure 2, hard irregular shadow mapping from the light centre (§2.4): each
/// occluding triangle, sorted into bins, is tested exactly against the stored sample positions
/// under it, from the grid slice of its nearest point backwards, and counts one unit of depth
/// complexity at every sample it covers in front of.
fn umbra(izb: &Izb, occ: &Occluders, t: &mut Tally) -> Vec<Vec<u32>> {
    let grid = &izb.grid;
    let mut bin_lists: Vec<Vec<u32>> = vec![Vec::new(); grid.bins()];
    for (i, (_, tri)) in occ.triangles.iter().enumerate() {
        let (lo, hi) = tri.bounds();
        for b in bins_of(grid, lo, hi) {
            bin_lists[b].push(i as u32);
        }
    }
    let entries: usize = bin_lists.iter().map(Vec::len).sum();
    t.0.add("bin_entries", entries as f64);
    t.write("bins", 4.0 * entries as f64);
    t.0.set("mem.bins.bytes", 4.0 * entries as f64);

    let per_bin: Vec<(Vec<u32>, [u64; 3])> = (0..grid.bins())
        .into_par_iter()
        .map(|b| {
            let range = izb.bin_range(b);
            let base = range.start;
            let mut depth_complexity = vec![0u32; range.len()];
            let (mut columns, mut tests, mut hits) = (0u64, 0u64, 0u64);
            if range.is_empty() {
                return (depth_complexity, [0; 3]);
            }
            for &i in &bin_lists[b] {
                let (flat, tri) = &occ.triangles[i as usize];
                let (lo, hi) = tri.bounds();
                let Some(((x0, y0), (x1, y1))) = columns_in_bin(grid, b, lo, hi) else {
                    continue;
                };
                let k0 = grid.slice(tri.inv_z_near());
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        columns += 1;
                        for s in izb.column_from(x, y, k0) {
                            let sample = &izb.samples[s];
                            tests += 1;
                            if sample.triangle == *flat {
                                continue;
                            }
                            if let Some(inv_z) = tri.covers(sample.p.uv) {
                                if inv_z > sample.p.inv_z {
                                    depth_complexity[s - base] += 1;
                                    hits += 1;
                                }
                            }
                        }
                    }
                }
            }
            (depth_complexity, [columns, tests, hits])
        })
        .collect();
    let [mut columns, mut tests, mut hits] = [0u64; 3];
    let mut out = Vec::with_capacity(per_bin.len());
    for (dc, c) in per_bin {
        columns += c[0];
        tests += c[1];
        hits += c[2];
        out.push(dc);
    }
    t.0.set("hard_tests", tests as f64);
    t.0.set("hard_hits", hits as f64);
    t.read("bins", 4.0 * entries as f64);
    t.read("light_triangles", TRIANGLE_BYTES * entries as f64);
    t.read("izb_grid", 8.0 * columns as f64);
    t.read("izb_samples", SAMPLE_BYTES * tests as f64);
    t.read("occlusion", 4.0 * hits as f64);
    t.write("occlusion", 4.0 * hits as f64);
    out
}

/// What the penumbra pass of one bin did.
#[derive(Default, Clone, Copy)]
struct SoftWork {
    fragments: u64,
    wedge_culled_fragments: u64,
    fill: u64,
    contributing: u64,
}

/// Steps (c) and (d) of Figure 2 (§2.2, §2.3, §2.5): one penumbra quad per edge, binned with
/// its width from the deepest receiver (of the scene, or of each bin); per fragment, the samples
/// of the grid column (from where the wedge enters it, or all) get eq. 3 with the sign rule.
fn penumbra(
    izb: &Izb,
    occ: &Occluders,
    r_uv: f32,
    opts: &SoftIzbOptions,
    t: &mut Tally,
) -> Vec<Vec<f32>> {
    let grid = &izb.grid;
    let mut bin_lists: Vec<Vec<(u32, f32)>> = vec![Vec::new(); grid.bins()];
    let mut quads = 0u64;
    let mut culled_by_bin_width = 0u64;
    for (i, edge) in occ.edges.iter().enumerate() {
        let half_width = quad_half_width(r_uv, edge.inv_z_near(), grid.inv_z_back);
        if half_width <= 0.0 {
            continue; // behind every receiver
        }
        quads += 1;
        let quad = PenumbraQuad {
            edge: *edge,
            half_width,
        };
        let (lo, hi) = quad.bounds();
        for b in bins_of(grid, lo, hi) {
            if !opts.per_bin_width {
                bin_lists[b].push((i as u32, half_width));
                continue;
            }
            let w = quad_half_width(r_uv, edge.inv_z_near(), izb.bin_inv_z_back[b]);
            let (blo, bhi) = grid.bin_rect(b);
            let narrowed = PenumbraQuad {
                edge: *edge,
                half_width: w,
            };
            if w > 0.0 && narrowed.overlaps(blo, bhi) {
                bin_lists[b].push((i as u32, w));
            } else {
                culled_by_bin_width += 1;
            }
        }
    }
    let entries: usize = bin_lists.iter().map(Vec::len).sum();
    t.0.set("penumbra_quads", quads as f64);
    t.0.set("bin_culled_quads", culled_by_bin_width as f64);
    t.0.add("bin_entries", entries as f64);
    t.write("bins", 8.0 * entries as f64);
    t.0.set("mem.bins.bytes", 8.0 * entries as f64);

    let per_bin: Vec<(Vec<f32>, SoftWork)> = (0..grid.bins())
        .into_par_iter()
        .map(|b| {
            let range = izb.bin_range(b);
            let base = range.start;
            let mut occlusion = vec![0f32; range.len()];
            let mut w = SoftWork::default();
            if range.is_empty() {
                return (occlusion, w);
            }
            let last = grid.res - 1;
            for &(i, half_width) in &bin_lists[b] {
                let edge = occ.edges[i as usize];
                let quad = PenumbraQuad { edge, half_width };
                let (lo, hi) = quad.bounds();
                let Some(((x0, y0), (x1, y1))) = columns_in_bin(grid, b, lo, hi) else {
                    continue;
                };
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        let (clo, chi) = grid.column_rect(x, y);
                        if !quad.overlaps(clo, chi) {
                            continue;
                        }
                        w.fragments += 1;
                        let k0 = if opts.wedge_column_cull {
                            // Border columns hold clamped samples from outside the uv square.
                            let border = x == 0 || y == 0 || x == last || y == last;
                            let distance = if border {
                                0.0
                            } else {
                                let half = (chi - clo) * 0.5;
                                (edge.distance(clo + half) - half.length()).max(0.0)
                            };
                            match wedge_entry_inv_z(r_uv, edge.inv_z_near(), distance) {
                                Some(inv_z) => grid.slice(inv_z),
                                None => {
                                    w.wedge_culled_fragments += 1;
                                    continue;
                                }
                            }
                        } else {
                            0
                        };
                        for s in izb.column_from(x, y, k0) {
                            w.fill += 1;
                            let v = edge.penumbral_occlusion(r_uv, izb.samples[s].p);
                            if v != 0.0 {
                                occlusion[s - base] += v;
                                w.contributing += 1;
                            }
                        }
                    }
                }
            }
            (occlusion, w)
        })
        .collect();
    let mut total = SoftWork::default();
    let mut out = Vec::with_capacity(per_bin.len());
    for (occlusion, w) in per_bin {
        total.fragments += w.fragments;
        total.wedge_culled_fragments += w.wedge_culled_fragments;
        total.fill += w.fill;
        total.contributing += w.contributing;
        out.push(occlusion);
    }
    let overdraw = total.fill - total.contributing;
    t.0.set("quad_fragments", total.fragments as f64);
    t.0.set(
        "wedge_culled_fragments",
        total.wedge_culled_fragments as f64,
    );
    t.0.set("fill", total.fill as f64);
    t.0.set("overdraw", overdraw as f64);
    t.0.set(
        "overdraw_ratio",
        if total.fill > 0 {
            overdraw as f64 / total.fill as f64
        } else {
            0.0
        },
    );
    t.read("bins", 8.0 * entries as f64);
    t.read("penumbra_edges", EDGE_BYTES * entries as f64);
    t.read("izb_grid", 8.0 * total.fragments as f64);
    t.read("izb_samples", SAMPLE_BYTES * total.fill as f64);
    t.read("occlusion", 4.0 * total.contributing as f64);
    t.write("occlusion", 4.0 * total.contributing as f64);
    out
}

/// Most grid cells one run may allocate (4 bytes each).
const MAX_CELLS: u64 = 1 << 28;

pub fn render(frame: &Frame, opts: &SoftIzbOptions) -> Result<FrameOutput> {
    let light = frame.scene.light;
    let res = frame.params.map_resolution as u64;
    if res * res * opts.depth_slices as u64 > MAX_CELLS {
        return Err(Error::Resource(format!(
            "soft_izb grid of {res}² columns × {} depth slices exceeds {MAX_CELLS} cells; \
             lower map_resolution or options.soft_izb.depth_slices",
            opts.depth_slices
        )));
    }
    let view = LightView::new(&light, frame.scene.bounds(), frame.params.map_resolution);
    let r_uv = light_radius_uv(&view, light.size());

    let start = Instant::now();
    let mut t = Tally::default();
    let (izb, outside) = construct(frame, &view, opts, &mut t);
    let construct_phase = phase("construct", start, t);

    let start = Instant::now();
    let mut t = Tally::default();
    let occ = occluders(frame, &view, opts, &mut t);
    let geometry_phase = phase("geometry", start, t);

    let start = Instant::now();
    let mut t = Tally::default();
    let depth_complexity = umbra(&izb, &occ, &mut t);
    let hard_phase = phase("hard", start, t);

    let start = Instant::now();
    let mut t = Tally::default();
    let penumbral = penumbra(&izb, &occ, r_uv, opts, &mut t);
    // Eq. 4 at each sample, written to its eye pixel.
    let g = &frame.gbuffer;
    let mut data = vec![1.0f32; g.len()];
    for (b, (dc, pen)) in depth_complexity.iter().zip(&penumbral).enumerate() {
        let range = izb.bin_range(b);
        for (k, s) in izb.samples[range].iter().enumerate() {
            data[s.pixel as usize] = combined_visibility(dc[k], pen[k]);
        }
    }
    let n = izb.samples.len() as f64;
    t.read("occlusion", 8.0 * n);
    t.read("izb_samples", SAMPLE_BYTES * n);
    t.write("visibility", 4.0 * n);
    let soft_phase = phase("soft", start, t);

    let phases = vec![construct_phase, geometry_phase, hard_phase, soft_phase];
    let mut counters = Counters::default();
    for p in &phases {
        counters.merge(&p.counters);
    }
    // Ratios do not add across phases.
    if let Some(r) = phases[3].counters.get("overdraw_ratio") {
        counters.set("overdraw_ratio", r);
    }
    let mut warnings = vec![];
    if outside > 0 {
        warnings.push(format!(
            "{outside} receiver points lie at or behind the light's view plane and are taken \
             as lit"
        ));
    }
    Ok(FrameOutput {
        visibility: VisibilityBuffer {
            width: g.width,
            height: g.height,
            data,
        },
        counters,
        phases,
        model_ms: None,
        gpu_ms: None,
        execution: [
            ("grid".to_string(), serde_json::json!(izb.grid.res)),
            (
                "depth_slices".to_string(),
                serde_json::json!(izb.grid.slices),
            ),
            ("bin".to_string(), serde_json::json!(izb.grid.bin)),
            (
                "per_bin_width".to_string(),
                serde_json::json!(opts.per_bin_width),
            ),
            (
                "wedge_column_cull".to_string(),
                serde_json::json!(opts.wedge_column_cull),
            ),
            (
                "silhouettes".to_string(),
                serde_json::to_value(opts.silhouettes).unwrap_or_default(),
            ),
        ]
        .into(),
        warnings,
    })
}

/// Bytes of the grid (at the default depth slicing) and the sample array, estimated before
/// anything is allocated, for the harness's memory limit.
pub fn memory_estimate(p: &crate::frame::RunParams) -> u64 {
    let res = u64::from(p.map_resolution);
    let pixels = u64::from(p.image[0]) * u64::from(p.image[1]);
    let slices = u64::from(SoftIzbOptions::default().depth_slices);
    4 * (res * res * slices + 1) + pixels * SAMPLE_BYTES as u64
}
