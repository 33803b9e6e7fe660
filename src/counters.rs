//! The counter glossary: every counter name a run records, with its meaning, its unit, and the
//! executions that record it; the derived figures, computed in one place ([`derive`]); and the
//! renames of older results files ([`current_name`]).
//!
//! A name is written once here. Names with a `<...>` part stand for a family (a buffer, a step,
//! a range); the part matches one or more dotted segments. `shadowbench list --counters` prints
//! this table. Tests check that every counter of every record is in it and that the cpu-model
//! and wgpu records of each algorithm carry the same names, except those listed here as
//! recorded by some executions only.
//!
//! Memory traffic comes in two kinds with their own names, never summed or charted together:
//! **modelled** (`mem_model.*`: every access of the cpu-model's kernels through its probe) and
//! **estimated** (`mem_est.*`: bytes computed from record sizes and counts, on wgpu and for the
//! shadow-volume kernels on cpu-native). No execution measures memory traffic.

use std::borrow::Cow;

use crate::backend::Backend;
use crate::record::Counters;

/// Which executions record a counter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recorded {
    /// Every execution of the algorithms that count it.
    All,
    /// cpu-native and cpu-model: the host kernels' own bookkeeping (the sort-middle binned
    /// rasterizer, the reference's samples) that a GPU pipeline does not expose.
    Cpu,
    /// cpu-model only: the modelled machine's instruction, cache and memory counts.
    Model,
    /// wgpu only: driver statistics, or what only the GPU formulation does.
    Wgpu,
    /// cpu-native and wgpu: estimates where nothing counts the traffic.
    NativeAndWgpu,
    /// cpu-model (every kernel) and wgpu (where the GPU passes count what they do).
    ModelAndWgpu,
    /// cpu-native and cpu-model always (the binned rasterizer), and wgpu where its own passes
    /// bin (soft_izb's grid, soft_shadow_volume's tiles).
    CpuAndBinningWgpu,
}

impl Recorded {
    /// The executions whose records may carry the counter.
    pub fn backends(self) -> &'static [Backend] {
        use Backend::{CpuModel, CpuNative, Wgpu};
        match self {
            Recorded::All | Recorded::CpuAndBinningWgpu => &Backend::ALL,
            Recorded::Cpu => &[CpuNative, CpuModel],
            Recorded::Model => &[CpuModel],
            Recorded::Wgpu => &[Wgpu],
            Recorded::NativeAndWgpu => &[CpuNative, Wgpu],
            Recorded::ModelAndWgpu => &[CpuModel, Wgpu],
        }
    }

    /// The glossary's name of the executions: "all", "cpu" (both CPU executions), "cpu; wgpu
    /// bins", else their names.
    fn label(self) -> String {
        match self {
            Recorded::All => "all".into(),
            Recorded::Cpu => "cpu".into(),
            Recorded::CpuAndBinningWgpu => "cpu; wgpu bins".into(),
            _ => self
                .backends()
                .iter()
                .map(|b| b.name())
                .collect::<Vec<_>>()
                .join(", "),
        }
    }
}

/// Which way a figure improves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// A cost: work, traffic, size, time or error.
    Lower,
    /// A rate of good outcomes (cache hits, SIMD utilisation).
    Higher,
}

/// How a figure is obtained, which says how two of them may be compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Counted or computed from the input alone: the same on any host and thread count (for
    /// wgpu: on one adapter and driver). Compared exactly or against a threshold.
    Deterministic,
    /// Computed by the machine model (cpu-model): deterministic too, a property of the model.
    Modelled,
    /// Timed on the host or the GPU: varies between samples, compared by a test on samples.
    Measured,
    /// Computed from record sizes and counts where nothing counts the quantity (`mem_est.*`).
    Estimated,
}

impl Kind {
    pub fn label(self) -> &'static str {
        match self {
            Kind::Deterministic => "deterministic",
            Kind::Modelled => "modelled",
            Kind::Measured => "measured",
            Kind::Estimated => "estimated",
        }
    }
}

impl Direction {
    pub fn label(self) -> &'static str {
        match self {
            Direction::Lower => "lower",
            Direction::Higher => "higher",
        }
    }
}

/// One entry of the glossary.
#[derive(Clone, Copy, Debug)]
pub struct Counter {
    /// The name, or a family with one `<...>` part.
    pub name: &'static str,
    pub unit: &'static str,
    pub recorded: Recorded,
    pub kind: Kind,
    /// Which way the figure improves, stated here for every entry (never read from the name).
    pub better: Direction,
    pub meaning: &'static str,
}

const fn c(
    name: &'static str,
    unit: &'static str,
    recorded: Recorded,
    kind: Kind,
    better: Direction,
    meaning: &'static str,
) -> Counter {
    Counter {
        name,
        unit,
        recorded,
        kind,
        better,
        meaning,
    }
}

use Direction::{Higher, Lower};
use Kind::{Deterministic, Estimated, Measured, Modelled};
use Recorded::{All, Cpu, CpuAndBinningWgpu, Model, ModelAndWgpu, NativeAndWgpu, Wgpu};

/// Every counter, alphabetically by name.
pub const COUNTERS: &[Counter] = &[
    c(
        "active_lanes",
        "lanes",
        Model,
        Modelled,
        Lower,
        "active SIMD lanes summed over vector instructions",
    ),
    c(
        "atomics",
        "operations",
        ModelAndWgpu,
        Deterministic,
        Lower,
        "atomic read-modify-writes (on wgpu: soft_izb's WGSL atomics)",
    ),
    c(
        "bin_bytes",
        "bytes",
        Cpu,
        Deterministic,
        Lower,
        "bytes of the binned rasterizer's bins (tile lists)",
    ),
    c(
        "bin_culled_quads",
        "quads",
        All,
        Deterministic,
        Lower,
        "penumbra quads culled per light-space bin (004 §2.5)",
    ),
    c(
        "bin_entries",
        "entries",
        CpuAndBinningWgpu,
        Deterministic,
        Lower,
        "primitive references written into screen, tile or grid bins",
    ),
    c(
        "cache.l1_hits",
        "accesses",
        Model,
        Modelled,
        Higher,
        "modelled L1 data-cache hits",
    ),
    c(
        "cache.l1_misses",
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled L1 data-cache misses",
    ),
    c(
        "cache.l2_hits",
        "accesses",
        Model,
        Modelled,
        Higher,
        "modelled L2 hits (after an L1 miss)",
    ),
    c(
        "cache.l2_misses",
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled L2 misses (served from DRAM)",
    ),
    c(
        "casters.triangles",
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles on a light pass's draw list (step casters; near-clipped ones as fans)",
    ),
    c(
        "coverage_texture_reads",
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "4D coverage-texture reads of the per-pixel wedge walk (III §3.3)",
    ),
    c(
        "culled_fragments",
        "fragments",
        All,
        Deterministic,
        Lower,
        "fragments discarded by a cull test before shading",
    ),
    c(
        "dbuffer.bytes",
        "bytes",
        All,
        Deterministic,
        Lower,
        "size of the D-buffer (003 §4)",
    ),
    c(
        "dbuffer.scene_fill",
        "fragments",
        All,
        Deterministic,
        Lower,
        "fragments of the D-buffer's scene-depth pass",
    ),
    c(
        "denoise.buffer_bytes",
        "bytes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: size of its per-pixel buffers (inputs, trace output, penumbra radius, two \
         filter buffers)",
    ),
    c(
        "denoise.filter_taps",
        "taps",
        All,
        Deterministic,
        Lower,
        "rt_denoised: neighbour reads of the à-trous passes (within the penumbra radius)",
    ),
    c(
        "denoise.filtered_pixels",
        "pixels",
        All,
        Deterministic,
        Lower,
        "rt_denoised: pixels the denoiser filters (a blocker near, neither all lit nor all \
         shadowed around)",
    ),
    c(
        "denoise.search_taps",
        "taps",
        All,
        Deterministic,
        Lower,
        "rt_denoised: neighbour reads of the penumbra search (hit distances, visibility)",
    ),
    c(
        "depth_fail",
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments of the binned rasterizer that failed the depth test",
    ),
    c(
        "depth_pass",
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments of the binned rasterizer that passed the depth test",
    ),
    c(
        "dram_read_bytes",
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled DRAM reads (L2 misses × line size)",
    ),
    c(
        "dram_write_bytes",
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled DRAM writes (dirty lines written back)",
    ),
    c(
        "fill",
        "fragments",
        All,
        Deterministic,
        Lower,
        "rasterized fragments, texels or samples the shadow geometry covers (rt_denoised: \
         shadow rays, its unit of work)",
    ),
    c(
        "fragments_inside_wedges",
        "fragments",
        All,
        Deterministic,
        Lower,
        "wedge fragments inside their wedge (001 III §3.2.2)",
    ),
    c(
        "fragments_rejected_early",
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments the binned rasterizer rejected by hierarchical depth",
    ),
    c(
        "gather_lines",
        "cache lines",
        Model,
        Modelled,
        Lower,
        "distinct cache lines touched by gathers",
    ),
    c(
        "gathers",
        "instructions",
        Model,
        Modelled,
        Lower,
        "vector gather instructions",
    ),
    c(
        "hard_columns",
        "columns",
        All,
        Deterministic,
        Lower,
        "light-space grid columns the umbra pass visits (004 §2.3)",
    ),
    c(
        "hard_hits",
        "samples",
        All,
        Deterministic,
        Lower,
        "eye samples found inside an occluding triangle (004 §2.3)",
    ),
    c(
        "hard_tests",
        "tests",
        All,
        Deterministic,
        Lower,
        "sample-in-triangle tests of the umbra pass (004 §2.3)",
    ),
    c(
        "izb_grid_bytes",
        "bytes",
        All,
        Deterministic,
        Lower,
        "size of the irregular z-buffer's grid (004 §2.2)",
    ),
    c(
        "izb_samples_bytes",
        "bytes",
        All,
        Deterministic,
        Lower,
        "size of the irregular z-buffer's eye samples (004 §2.2)",
    ),
    c(
        "light_view.casters_near_clipped",
        "triangles",
        All,
        Deterministic,
        Lower,
        "occluder triangles cut by the light view's near plane (the part nearer the light is lost)",
    ),
    c(
        "light_view.faces",
        "views",
        All,
        Deterministic,
        Lower,
        "light views rendered: 1, or the faces of a cube map when receivers span more than 60°",
    ),
    c(
        "light_view.receivers_outside",
        "pixels",
        All,
        Deterministic,
        Lower,
        "visible receiver pixels facing the light centre outside every light view, taken as lit",
    ),
    c(
        "loads",
        "instructions",
        Model,
        Modelled,
        Lower,
        "contiguous vector or scalar loads",
    ),
    c(
        "mem_est.<buffer>.read_bytes",
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes read from a buffer, from record sizes and counts",
    ),
    c(
        "mem_est.<buffer>.write_bytes",
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes written to a buffer, from record sizes and counts",
    ),
    c(
        "mem_est.read_bytes",
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes read, all buffers",
    ),
    c(
        "mem_est.write_bytes",
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes written, all buffers",
    ),
    c(
        "mem_model.<buffer>.read_bytes",
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes read from a named buffer",
    ),
    c(
        "mem_model.<buffer>.reads",
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled read accesses of a named buffer",
    ),
    c(
        "mem_model.<buffer>.write_bytes",
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes written to a named buffer",
    ),
    c(
        "mem_model.<buffer>.writes",
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled write accesses of a named buffer",
    ),
    c(
        "mem_model.read_bytes",
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes read, all buffers",
    ),
    c(
        "mem_model.write_bytes",
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes written, all buffers",
    ),
    c(
        "occluder_triangles",
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the occluders after facing and clipping",
    ),
    c(
        "occluders.boundary_edges",
        "edges",
        All,
        Deterministic,
        Lower,
        "occluder edges used by one triangle only (open meshes: shadow volumes may leak)",
    ),
    c(
        "occluders.non_manifold_edges",
        "edges",
        All,
        Deterministic,
        Lower,
        "occluder edges shared by more than two triangles",
    ),
    c(
        "overdraw",
        "fragments",
        All,
        Deterministic,
        Lower,
        "fill that does not end up in the result (behind, culled or contributing nothing; \
         rt_denoised: the rays of a pixel whose rays all agree, beyond its first)",
    ),
    c(
        "overdraw_ratio",
        "ratio",
        All,
        Deterministic,
        Lower,
        "derived: overdraw / fill",
    ),
    c(
        "penumbra.cone_triangles",
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the penumbra map's cones (000 §3)",
    ),
    c(
        "penumbra.sheet_triangles",
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the penumbra map's sheets (000 §3)",
    ),
    c(
        "penumbra_map.taps",
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "penumbra-map reads of the GPU eye lookup",
    ),
    c(
        "penumbra_quads",
        "quads",
        All,
        Deterministic,
        Lower,
        "penumbra quads of silhouette edges (004 §2.4)",
    ),
    c(
        "pipeline.clipper_invocations",
        "primitives",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: primitives entering the clipper",
    ),
    c(
        "pipeline.clipper_primitives_out",
        "primitives",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: primitives leaving the clipper",
    ),
    c(
        "pipeline.compute_shader_invocations",
        "invocations",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: compute invocations",
    ),
    c(
        "pipeline.fragment_shader_invocations",
        "invocations",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: fragment invocations (driver-defined)",
    ),
    c(
        "pipeline.vertex_shader_invocations",
        "invocations",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: vertex invocations",
    ),
    c(
        "quad_fragments",
        "fragments",
        All,
        Deterministic,
        Lower,
        "fragments of penumbra quads (004 §2.4)",
    ),
    c(
        "quad_tests",
        "tests",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-quad tests of the per-pixel walk over binned quads",
    ),
    c(
        "raster.blocks_rejected",
        "blocks",
        Cpu,
        Deterministic,
        Lower,
        "4×4 blocks the binned rasterizer rejected",
    ),
    c(
        "raster.clipped",
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles the binned rasterizer clipped at the near plane",
    ),
    c(
        "raster.culled",
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles culled (back-facing, degenerate or off-screen)",
    ),
    c(
        "raster.discarded",
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments discarded by the fragment kernel",
    ),
    c(
        "raster.tiles_rejected",
        "tiles",
        Cpu,
        Deterministic,
        Lower,
        "tiles the binned rasterizer rejected",
    ),
    c(
        "raster.triangles",
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles set up by the binned rasterizer",
    ),
    c(
        "raster.tris_per_tile.<range>",
        "tiles",
        Cpu,
        Deterministic,
        Lower,
        "histogram: tiles with that many triangles",
    ),
    c(
        "raster.written",
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments written by the binned rasterizer",
    ),
    c(
        "rt.bvh_node_bytes",
        "bytes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: size of the caster BVH's node records (64 bytes: both children's boxes)",
    ),
    c(
        "rt.bvh_triangle_bytes",
        "bytes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: size of the caster BVH's triangles (48 bytes each)",
    ),
    c(
        "rt.horizon_culled",
        "samples",
        All,
        Deterministic,
        Lower,
        "rt_denoised: light samples behind a receiver-only surface's plane, dark without a ray",
    ),
    c(
        "rt.node_visits",
        "nodes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: interior BVH nodes fetched by the shadow rays (one 64-byte record each)",
    ),
    c(
        "rt.occluded_rays",
        "rays",
        All,
        Deterministic,
        Lower,
        "rt_denoised: shadow rays a caster blocks",
    ),
    c(
        "rt.rays",
        "rays",
        All,
        Deterministic,
        Lower,
        "rt_denoised: shadow rays cast (any-hit BVH traversals)",
    ),
    c(
        "rt.triangle_tests",
        "tests",
        All,
        Deterministic,
        Lower,
        "rt_denoised: ray-triangle tests of the shadow rays",
    ),
    c(
        "samples",
        "samples",
        All,
        Deterministic,
        Lower,
        "eye samples inserted into the irregular z-buffer (004 §2.2)",
    ),
    c(
        "scalar_ops",
        "instructions",
        Model,
        Modelled,
        Lower,
        "scalar instructions",
    ),
    c(
        "scatter_lines",
        "cache lines",
        Model,
        Modelled,
        Lower,
        "distinct cache lines touched by scatters",
    ),
    c(
        "scatters",
        "instructions",
        Model,
        Modelled,
        Lower,
        "vector scatter instructions",
    ),
    c(
        "shader_invocations",
        "invocations",
        All,
        Deterministic,
        Lower,
        "fragment-program runs in the cpu-model's terms",
    ),
    c(
        "shadow_map.covered_texels",
        "texels",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-map texels covered by an occluder (GPU replay)",
    ),
    c(
        "shadow_map.taps",
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-map reads of the GPU eye lookup",
    ),
    c(
        "shadow_map.taps_wasted",
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-map reads of pixels that see no surface",
    ),
    c(
        "shadow_quads",
        "quads",
        Wgpu,
        Deterministic,
        Lower,
        "hard shadow quads uploaded per light sample",
    ),
    c(
        "shadow_rays",
        "rays",
        Cpu,
        Deterministic,
        Lower,
        "shadow rays the reference casts (pixels that see a surface × light samples)",
    ),
    c(
        "silhouette.edges",
        "edges",
        All,
        Deterministic,
        Lower,
        "silhouette edges from the light",
    ),
    c(
        "silhouette.faces_all_front",
        "faces",
        All,
        Deterministic,
        Lower,
        "faces front-facing from every light point (003)",
    ),
    c(
        "silhouette.faces_none_front",
        "faces",
        All,
        Deterministic,
        Lower,
        "faces front-facing from no light point (003)",
    ),
    c(
        "silhouette.max_edges_per_vertex",
        "edges",
        All,
        Deterministic,
        Lower,
        "most silhouette edges meeting at one vertex",
    ),
    c(
        "silhouette.penumbra_edges",
        "edges",
        All,
        Deterministic,
        Lower,
        "area-silhouette edges bounding the penumbra (003)",
    ),
    c(
        "silhouette.silhouette_faces",
        "faces",
        All,
        Deterministic,
        Lower,
        "faces between the two area silhouettes (003)",
    ),
    c(
        "silhouette.umbra_edges",
        "edges",
        All,
        Deterministic,
        Lower,
        "area-silhouette edges bounding the umbra (003)",
    ),
    c(
        "silhouette.vertices",
        "vertices",
        All,
        Deterministic,
        Lower,
        "silhouette vertices",
    ),
    c(
        "silhouette.vertices_over_two_edges",
        "vertices",
        All,
        Deterministic,
        Lower,
        "silhouette vertices where more than two edges meet",
    ),
    c(
        "silhouette_edges",
        "edges",
        All,
        Deterministic,
        Lower,
        "silhouette edges from the light centre",
    ),
    c(
        "simd_utilization",
        "ratio",
        Model,
        Modelled,
        Higher,
        "derived: active_lanes / (vector_ops × 16)",
    ),
    c(
        "ssm.micro_patches",
        "patches",
        All,
        Deterministic,
        Lower,
        "micro-patches of the occluder map (002 §3)",
    ),
    c(
        "ssm.occluder_texels",
        "texels",
        All,
        Deterministic,
        Lower,
        "occluder-map texels that hold an occluder (002 §3)",
    ),
    c(
        "step.<step>.bandwidth_bound",
        "0 or 1",
        Model,
        Modelled,
        Lower,
        "1 when DRAM bandwidth bounds the step's modelled time",
    ),
    c(
        "step.<step>.load_imbalance",
        "ratio",
        Model,
        Modelled,
        Lower,
        "slowest modelled core over the mean",
    ),
    c(
        "step.<step>.model_ms",
        "ms",
        Model,
        Modelled,
        Lower,
        "modelled time of one step of a phase",
    ),
    c(
        "stores",
        "instructions",
        Model,
        Modelled,
        Lower,
        "contiguous vector or scalar stores",
    ),
    c(
        "transfer.bytes",
        "bytes",
        All,
        Deterministic,
        Lower,
        "bytes copied between device and host (002 occluder-map transfer)",
    ),
    c(
        "vector_ops",
        "instructions",
        Model,
        Modelled,
        Lower,
        "16-wide vector instructions",
    ),
    c(
        "volume_caps",
        "faces",
        All,
        Deterministic,
        Lower,
        "light and dark caps of z-fail volumes (001 III)",
    ),
    c(
        "volumes.closing_triangles",
        "triangles",
        All,
        Deterministic,
        Lower,
        "closing triangles of the umbra volumes (003)",
    ),
    c(
        "volumes.degenerate_edges",
        "edges",
        All,
        Deterministic,
        Lower,
        "silhouette edges giving no volume face (003)",
    ),
    c(
        "volumes.penumbra_quads",
        "quads",
        All,
        Deterministic,
        Lower,
        "quads of the penumbra volumes (003)",
    ),
    c(
        "volumes.silhouette_faces",
        "faces",
        All,
        Deterministic,
        Lower,
        "silhouette faces of the volumes (003)",
    ),
    c(
        "volumes.umbra_quads",
        "quads",
        All,
        Deterministic,
        Lower,
        "quads of the umbra volumes (003)",
    ),
    c(
        "volumes.umbra_triangles",
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the umbra volumes (003)",
    ),
    c(
        "volumes.umbra_trim_planes",
        "planes",
        All,
        Deterministic,
        Lower,
        "trim planes at convex corners of the umbra (003)",
    ),
    c(
        "wedge_culled_fragments",
        "fragments",
        All,
        Deterministic,
        Lower,
        "wedge fragments culled by wedge-half culling (001 IV §4.4)",
    ),
    c(
        "wedge_primitives",
        "primitives",
        Wgpu,
        Deterministic,
        Lower,
        "wedge primitives of the per-pixel wedge walk",
    ),
    c(
        "wedge_tests",
        "tests",
        Wgpu,
        Deterministic,
        Lower,
        "wedge tests of the per-pixel wedge walk",
    ),
    c(
        "wedges",
        "wedges",
        All,
        Deterministic,
        Lower,
        "penumbra wedges built (001 III §3.1)",
    ),
    c(
        "wedges_degenerate",
        "wedges",
        All,
        Deterministic,
        Lower,
        "wedges too thin to rasterize",
    ),
];

/// The figures of a record and its phases beside the counters: times and quality metrics
/// against the reference ([`crate::metrics::ErrorMetrics`]), alphabetically by name. A phase's
/// time is named as the record's (`phase.<phase>.wall_ms` is a `wall_ms`).
pub const FIGURES: &[Counter] = &[
    c(
        "animation.flicker",
        "visibility",
        All,
        Deterministic,
        Lower,
        "mean change between consecutive frames of an animated sweep that the reference does \
         not have: |(V_t - V_t-1) - (R_t - R_t-1)| over pixels and frames",
    ),
    c(
        "error.flip",
        "FLIP",
        All,
        Deterministic,
        Lower,
        "mean FLIP error of the shaded view against the reference's (Andersson et al. 2020; \
         0 for identical images), at reference.flip_pixels_per_degree",
    ),
    c(
        "error.frac_over_0_1",
        "fraction",
        All,
        Deterministic,
        Lower,
        "pixels whose visibility differs from the reference by more than 0.1",
    ),
    c(
        "error.lit_error",
        "fraction",
        All,
        Deterministic,
        Lower,
        "share of the pixels lit in the reference that the run shows shadowed",
    ),
    c(
        "error.mae",
        "visibility",
        All,
        Deterministic,
        Lower,
        "mean absolute visibility error against the reference",
    ),
    c(
        "error.mae_penumbra",
        "visibility",
        All,
        Deterministic,
        Lower,
        "mean absolute error over the pixels in penumbra in the reference (strictly between \
         umbra and lit)",
    ),
    c(
        "error.mae_shadow",
        "visibility",
        All,
        Deterministic,
        Lower,
        "mean absolute error over pixels in umbra or penumbra in either image (002 §5.2.1)",
    ),
    c(
        "error.max",
        "visibility",
        All,
        Deterministic,
        Lower,
        "largest absolute visibility error",
    ),
    c(
        "error.rmse",
        "visibility",
        All,
        Deterministic,
        Lower,
        "root-mean-square visibility error",
    ),
    c(
        "error.ssim",
        "SSIM",
        All,
        Deterministic,
        Higher,
        "SSIM of the visibility buffer against the reference's (Wang et al. 2004; 1 for \
         identical buffers), 8 x 8 windows",
    ),
    c(
        "error.umbra_error",
        "fraction",
        All,
        Deterministic,
        Lower,
        "share of the pixels in the reference's umbra that the run shows lit (a light leak)",
    ),
    c(
        "gpu_ms",
        "ms",
        Wgpu,
        Measured,
        Lower,
        "GPU time of the timed submission (timestamp queries)",
    ),
    c(
        "gpu_setup_ms",
        "ms",
        Wgpu,
        Measured,
        Lower,
        "host time of GPU setup (device, shader modules, pipelines), outside wall_ms",
    ),
    c(
        "model_ms",
        "ms",
        Model,
        Modelled,
        Lower,
        "modelled time on the configured many-core machine",
    ),
    c(
        "wall_ms",
        "ms",
        All,
        Measured,
        Lower,
        "host wall-clock time (on cpu-model: the time taken to model the frame)",
    ),
];

/// The glossary entry of a figure as `compare` and the reports name it: `counters.<counter>`,
/// `phase.<phase>.<counter or time>`, or a name of [`FIGURES`] (`model_ms`, `error.mae`). A
/// bare counter name is looked up too. `None` for a name the glossary does not hold.
pub fn figure(name: &str) -> Option<&'static Counter> {
    if let Some(rest) = name.strip_prefix("counters.") {
        return find(rest);
    }
    if let Some(rest) = name.strip_prefix("phase.") {
        // The phase's name runs to a dot; a counter name has dots of its own, so the first
        // split whose rest is a figure wins.
        return rest
            .match_indices('.')
            .find_map(|(i, _)| figure_or_counter(&rest[i + 1..]));
    }
    figure_or_counter(name)
}

fn figure_or_counter(name: &str) -> Option<&'static Counter> {
    FIGURES
        .iter()
        .find(|f| f.name == name)
        .or_else(|| find(name))
}

/// Which way `figure` improves (named as [`figure`] takes it), from the glossary.
pub fn direction(figure: &str) -> Option<Direction> {
    self::figure(figure).map(|c| c.better)
}

/// How `figure` is obtained (named as [`figure`] takes it), from the glossary.
pub fn kind(figure: &str) -> Option<Kind> {
    self::figure(figure).map(|c| c.kind)
}

/// Whether `name` is `pattern` (a name, or a family with one `<...>` part).
fn matches(pattern: &str, name: &str) -> bool {
    match (pattern.find('<'), pattern.find('>')) {
        (Some(a), Some(b)) => {
            let (prefix, suffix) = (&pattern[..a], &pattern[b + 1..]);
            name.len() > prefix.len() + suffix.len()
                && name.starts_with(prefix)
                && name.ends_with(suffix)
        }
        _ => pattern == name,
    }
}

/// The glossary entry of counter `name`.
pub fn find(name: &str) -> Option<&'static Counter> {
    COUNTERS.iter().find(|c| matches(c.name, name))
}

/// The glossary as `shadowbench list --counters` prints it: name, unit, executions, kind,
/// direction and meaning, the counters first, then the times and quality metrics.
pub fn glossary() -> String {
    let w = COUNTERS
        .iter()
        .chain(FIGURES)
        .map(|c| c.name.len())
        .max()
        .unwrap_or(0);
    let mut s = String::from(
        "counters (name, unit, recorded by, kind, better, meaning); <...> stands for a buffer,\n\
         step or range. Memory: mem_model.* is modelled (cpu-model), mem_est.* estimated from\n\
         sizes and counts (cpu-native shadow volumes, wgpu); no execution measures memory traffic.\n",
    );
    let line = |s: &mut String, c: &Counter| {
        s.push_str(&format!(
            "  {:<w$}  {:<12}  {:<16}  {:<13}  {:<6}  {}\n",
            c.name,
            c.unit,
            c.recorded.label(),
            c.kind.label(),
            c.better.label(),
            c.meaning
        ))
    };
    for c in COUNTERS {
        line(&mut s, c);
    }
    s.push_str("times and quality metrics (also per phase: phase.<phase>.<name>)\n");
    for c in FIGURES {
        line(&mut s, c);
    }
    s
}

/// The names of the derived figures ([`derive`]).
pub const DERIVED: [&str; 2] = ["overdraw_ratio", "simd_utilization"];

/// The counters a derived figure is computed from (numerator, denominator), so `compare` can
/// judge the ratio with its parts; `None` for a counter that is not derived.
pub fn parts(derived: &str) -> Option<[&'static str; 2]> {
    match derived {
        "overdraw_ratio" => Some(["overdraw", "fill"]),
        "simd_utilization" => Some(["active_lanes", "vector_ops"]),
        _ => None,
    }
}

/// The derived figures, computed from the counters of one record or phase:
/// `overdraw_ratio = overdraw / fill` (where both are counted and fill > 0) and
/// `simd_utilization = active_lanes / (vector_ops × 16)` (where vector_ops > 0). Applied to
/// every record and phase of every execution (`algorithms::run`) and to records read back.
pub fn derive(c: &mut Counters) {
    if let (Some(o), Some(f)) = (c.get("overdraw"), c.get("fill")) {
        if f > 0.0 {
            c.set("overdraw_ratio", o / f);
        }
    }
    let ops = c.get("vector_ops").unwrap_or(0.0);
    if ops > 0.0 {
        let lanes = c.get("active_lanes").unwrap_or(0.0);
        c.set(
            "simd_utilization",
            lanes / (ops * crate::model::LANES as f64),
        );
    }
}

/// The current name of counter `name` of a `backend` record written by an older version:
/// memory traffic was `mem_read_bytes`, `mem_write_bytes` and `mem.<buffer>.*` for every kind
/// (modelled on cpu-model, estimated on cpu-native and wgpu), and the irregular z-buffer's
/// sizes were `mem.izb_grid.bytes` and `mem.izb_samples.bytes`.
pub fn current_name(backend: Backend, name: &str) -> Cow<'_, str> {
    let kind = if backend == Backend::CpuModel {
        "mem_model"
    } else {
        "mem_est"
    };
    match name {
        "mem.izb_grid.bytes" => "izb_grid_bytes".into(),
        "mem.izb_samples.bytes" => "izb_samples_bytes".into(),
        "mem_read_bytes" => format!("{kind}.read_bytes").into(),
        "mem_write_bytes" => format!("{kind}.write_bytes").into(),
        _ => match name.strip_prefix("mem.") {
            Some(rest) => format!("{kind}.{rest}").into(),
            None => name.into(),
        },
    }
}

/// Renames the counters of an older record to their current names ([`current_name`]).
pub fn upgrade(backend: Backend, c: &mut Counters) {
    if c.0.keys().any(|k| current_name(backend, k) != k.as_str()) {
        c.0 = std::mem::take(&mut c.0)
            .into_iter()
            .map(|(k, v)| (current_name(backend, &k).into_owned(), v))
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn families_match_one_or_more_segments_and_names_match_exactly() {
        assert!(matches(
            "mem_model.<buffer>.read_bytes",
            "mem_model.gbuffer.position.read_bytes"
        ));
        assert!(matches(
            "mem_model.<buffer>.read_bytes",
            "mem_model.depth.read_bytes"
        ));
        assert!(!matches(
            "mem_model.<buffer>.read_bytes",
            "mem_model.read_bytes"
        ));
        assert!(!matches("fill", "fill_rate"));
        assert_eq!(find("step.insert.model_ms").unwrap().unit, "ms");
        assert!(find("simd_utilisation").is_none());
    }

    #[test]
    fn the_glossary_is_sorted_unique_and_says_what_each_counter_is() {
        for w in COUNTERS.windows(2) {
            assert!(w[0].name < w[1].name, "{} before {}", w[0].name, w[1].name);
        }
        for c in COUNTERS {
            assert!(!c.meaning.is_empty() && !c.unit.is_empty(), "{}", c.name);
        }
        let g = glossary();
        assert!(g.contains("overdraw_ratio") && g.contains("derived: overdraw / fill"));
    }

    #[test]
    fn every_figure_states_its_kind_and_direction_consistently_with_how_it_is_recorded() {
        for c in COUNTERS.iter().chain(FIGURES) {
            // The machine model's own counts are modelled; estimates are the mem_est family;
            // only times are measured, and every time is one.
            match c.kind {
                Modelled => assert_eq!(c.recorded, Model, "{}", c.name),
                Estimated => assert!(c.name.starts_with("mem_est."), "{}", c.name),
                Measured => assert_eq!(c.unit, "ms", "{}", c.name),
                Deterministic => {}
            }
            if c.recorded == Model && c.name != "model_ms" {
                assert_eq!(c.kind, Modelled, "{}", c.name);
            }
            if c.name.starts_with("mem_est.") {
                assert_eq!(c.kind, Estimated, "{}", c.name);
            }
        }
        for w in FIGURES.windows(2) {
            assert!(w[0].name < w[1].name, "{} before {}", w[0].name, w[1].name);
        }
        for t in ["wall_ms", "gpu_ms", "gpu_setup_ms"] {
            assert_eq!(kind(t), Some(Measured), "{t}");
            assert_eq!(kind(&format!("phase.shadow.{t}")), Some(Measured), "{t}");
        }
        assert_eq!(kind("model_ms"), Some(Modelled));
        assert_eq!(kind("phase.soft.model_ms"), Some(Modelled));
        assert_eq!(kind("counters.step.insert.model_ms"), Some(Modelled));
    }

    #[test]
    fn cache_hits_are_better_higher_and_no_direction_comes_from_a_name() {
        // Neither name says it is a rate, yet more hits are better; their misses are costs.
        for level in ["l1", "l2"] {
            let hits = format!("counters.cache.{level}_hits");
            assert_eq!(direction(&hits), Some(Higher), "{hits}");
            let misses = format!("counters.cache.{level}_misses");
            assert_eq!(direction(&misses), Some(Lower), "{misses}");
            assert_eq!(
                direction(&format!("phase.eye.cache.{level}_hits")),
                Some(Higher)
            );
        }
        assert_eq!(direction("counters.simd_utilization"), Some(Higher));
        // A name that only sounds like a rate is not in the glossary: no direction is guessed.
        for name in [
            "counters.texture_hit_rate",
            "counters.bin_efficiency",
            "speed",
        ] {
            assert_eq!(direction(name), None, "{name}");
            assert_eq!(kind(name), None, "{name}");
        }
        // Every entry resolves under the names compare gives it.
        for c in COUNTERS {
            let n = c
                .name
                .replace("<buffer>", "depth")
                .replace("<step>", "insert");
            let n = n.replace("<range>", "1-4");
            assert_eq!(direction(&format!("counters.{n}")), Some(c.better), "{n}");
            assert_eq!(kind(&format!("phase.light.{n}")), Some(c.kind), "{n}");
        }
        for f in FIGURES {
            assert_eq!(direction(f.name), Some(f.better), "{}", f.name);
        }
    }

    #[test]
    fn derived_ratios_name_parts_of_their_own_kind_and_executions() {
        for d in DERIVED {
            let entry = find(d).unwrap();
            assert_eq!(entry.unit, "ratio", "{d}");
            let [num, den] = parts(d).unwrap();
            assert!(
                entry.meaning.contains(num) && entry.meaning.contains(den),
                "{d}: {}",
                entry.meaning
            );
            for part in [num, den] {
                let p = find(part).unwrap_or_else(|| panic!("{d}: part {part}"));
                assert_eq!(p.kind, entry.kind, "{d}: {part}");
                assert_eq!(p.recorded, entry.recorded, "{d}: {part}");
                assert!(parts(part).is_none(), "{part}");
            }
        }
        // Every counter whose meaning says it is derived is one of them.
        for c in COUNTERS
            .iter()
            .filter(|c| c.meaning.starts_with("derived:"))
        {
            assert!(DERIVED.contains(&c.name), "{}", c.name);
        }
    }

    #[test]
    fn derived_figures_follow_their_definitions() {
        let mut k = Counters::default();
        k.set("fill", 400.0);
        k.set("overdraw", 100.0);
        k.set("vector_ops", 10.0);
        k.set("active_lanes", 80.0);
        derive(&mut k);
        assert_eq!(k.get("overdraw_ratio"), Some(0.25));
        assert_eq!(k.get("simd_utilization"), Some(0.5));
        // Nothing derived without its inputs, or over zero fill.
        let mut z = Counters::default();
        z.set("fill", 0.0);
        z.set("overdraw", 0.0);
        derive(&mut z);
        assert_eq!(z.get("overdraw_ratio"), None);
        assert_eq!(z.get("simd_utilization"), None);
    }

    #[test]
    fn old_memory_names_map_to_their_kind() {
        assert_eq!(
            current_name(Backend::CpuModel, "mem_read_bytes"),
            "mem_model.read_bytes"
        );
        assert_eq!(
            current_name(Backend::CpuModel, "mem.depth.reads"),
            "mem_model.depth.reads"
        );
        assert_eq!(
            current_name(Backend::CpuNative, "mem_write_bytes"),
            "mem_est.write_bytes"
        );
        assert_eq!(
            current_name(Backend::Wgpu, "mem_read_bytes"),
            "mem_est.read_bytes"
        );
        assert_eq!(
            current_name(Backend::CpuModel, "mem.izb_grid.bytes"),
            "izb_grid_bytes"
        );
        assert_eq!(
            current_name(Backend::Wgpu, "mem_est.depth.read_bytes"),
            "mem_est.depth.read_bytes"
        );
        assert_eq!(current_name(Backend::CpuModel, "fill"), "fill");
    }
}
