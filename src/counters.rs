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

/// Every counter's name as a constant, one per entry of [`COUNTERS`] (whose entry gives its
/// unit, executions and meaning): what executions record under (`k.add(names::FILL, f)`), so a
/// misspelt counter does not compile.
pub mod names {
    pub const ACTIVE_LANES: &str = "active_lanes";
    pub const ATOMICS: &str = "atomics";
    pub const BIN_BYTES: &str = "bin_bytes";
    pub const BIN_CULLED_QUADS: &str = "bin_culled_quads";
    pub const BIN_ENTRIES: &str = "bin_entries";
    pub const CACHE_L1_HITS: &str = "cache.l1_hits";
    pub const CACHE_L1_MISSES: &str = "cache.l1_misses";
    pub const CACHE_L2_HITS: &str = "cache.l2_hits";
    pub const CACHE_L2_MISSES: &str = "cache.l2_misses";
    pub const CACHE_L3_HITS: &str = "cache.l3_hits";
    pub const CACHE_L3_MISSES: &str = "cache.l3_misses";
    pub const CASTERS_TRIANGLES: &str = "casters.triangles";
    pub const COVERAGE_TEXTURE_READS: &str = "coverage_texture_reads";
    pub const CULLED_FRAGMENTS: &str = "culled_fragments";
    pub const DBUFFER_BYTES: &str = "dbuffer.bytes";
    pub const DBUFFER_SCENE_FILL: &str = "dbuffer.scene_fill";
    pub const DENOISE_BUFFER_BYTES: &str = "denoise.buffer_bytes";
    pub const DENOISE_FILTER_TAPS: &str = "denoise.filter_taps";
    pub const DENOISE_FILTERED_PIXELS: &str = "denoise.filtered_pixels";
    pub const DENOISE_SEARCH_TAPS: &str = "denoise.search_taps";
    pub const DEPTH_FAIL: &str = "depth_fail";
    pub const DEPTH_PASS: &str = "depth_pass";
    pub const DRAM_READ_BYTES: &str = "dram_read_bytes";
    pub const DRAM_WRITE_BYTES: &str = "dram_write_bytes";
    pub const FILL: &str = "fill";
    pub const FRAGMENTS_INSIDE_WEDGES: &str = "fragments_inside_wedges";
    pub const FRAGMENTS_REJECTED_EARLY: &str = "fragments_rejected_early";
    pub const GATHER_LINES: &str = "gather_lines";
    pub const GATHERS: &str = "gathers";
    pub const HARD_COLUMNS: &str = "hard_columns";
    pub const HARD_HITS: &str = "hard_hits";
    pub const HARD_TESTS: &str = "hard_tests";
    pub const IZB_GRID_BYTES: &str = "izb_grid_bytes";
    pub const IZB_SAMPLES_BYTES: &str = "izb_samples_bytes";
    pub const LIGHT_VIEW_CASTERS_NEAR_CLIPPED: &str = "light_view.casters_near_clipped";
    pub const LIGHT_VIEW_FACES: &str = "light_view.faces";
    pub const LIGHT_VIEW_RECEIVERS_OUTSIDE: &str = "light_view.receivers_outside";
    pub const LOADS: &str = "loads";
    pub const MEM_EST__BUFFER__READ_BYTES: &str = "mem_est.<buffer>.read_bytes";
    pub const MEM_EST__BUFFER__WRITE_BYTES: &str = "mem_est.<buffer>.write_bytes";
    pub const MEM_EST_READ_BYTES: &str = "mem_est.read_bytes";
    pub const MEM_EST_WRITE_BYTES: &str = "mem_est.write_bytes";
    pub const MEM_MODEL__BUFFER__READ_BYTES: &str = "mem_model.<buffer>.read_bytes";
    pub const MEM_MODEL__BUFFER__READS: &str = "mem_model.<buffer>.reads";
    pub const MEM_MODEL__BUFFER__WRITE_BYTES: &str = "mem_model.<buffer>.write_bytes";
    pub const MEM_MODEL__BUFFER__WRITES: &str = "mem_model.<buffer>.writes";
    pub const MEM_MODEL_READ_BYTES: &str = "mem_model.read_bytes";
    pub const MEM_MODEL_WRITE_BYTES: &str = "mem_model.write_bytes";
    pub const OCCLUDER_TRIANGLES: &str = "occluder_triangles";
    pub const OCCLUDERS_BOUNDARY_EDGES: &str = "occluders.boundary_edges";
    pub const OCCLUDERS_NON_MANIFOLD_EDGES: &str = "occluders.non_manifold_edges";
    pub const OVERDRAW: &str = "overdraw";
    pub const OVERDRAW_RATIO: &str = "overdraw_ratio";
    pub const PENUMBRA_CONE_TRIANGLES: &str = "penumbra.cone_triangles";
    pub const PENUMBRA_SHEET_TRIANGLES: &str = "penumbra.sheet_triangles";
    pub const PENUMBRA_MAP_TAPS: &str = "penumbra_map.taps";
    pub const PENUMBRA_QUADS: &str = "penumbra_quads";
    pub const PIPELINE_CLIPPER_INVOCATIONS: &str = "pipeline.clipper_invocations";
    pub const PIPELINE_CLIPPER_PRIMITIVES_OUT: &str = "pipeline.clipper_primitives_out";
    pub const PIPELINE_COMPUTE_SHADER_INVOCATIONS: &str = "pipeline.compute_shader_invocations";
    pub const PIPELINE_FRAGMENT_SHADER_INVOCATIONS: &str = "pipeline.fragment_shader_invocations";
    pub const PIPELINE_VERTEX_SHADER_INVOCATIONS: &str = "pipeline.vertex_shader_invocations";
    pub const QUAD_FRAGMENTS: &str = "quad_fragments";
    pub const QUAD_TESTS: &str = "quad_tests";
    pub const RASTER_BLOCKS_REJECTED: &str = "raster.blocks_rejected";
    pub const RASTER_CLIPPED: &str = "raster.clipped";
    pub const RASTER_CULLED: &str = "raster.culled";
    pub const RASTER_DISCARDED: &str = "raster.discarded";
    pub const RASTER_TILES_REJECTED: &str = "raster.tiles_rejected";
    pub const RASTER_TRIANGLES: &str = "raster.triangles";
    pub const RASTER_TRIS_PER_TILE__RANGE_: &str = "raster.tris_per_tile.<range>";
    pub const RASTER_WRITTEN: &str = "raster.written";
    pub const RT_BVH_NODE_BYTES: &str = "rt.bvh_node_bytes";
    pub const RT_BVH_TRIANGLE_BYTES: &str = "rt.bvh_triangle_bytes";
    pub const RT_HORIZON_CULLED: &str = "rt.horizon_culled";
    pub const RT_NODE_VISITS: &str = "rt.node_visits";
    pub const RT_OCCLUDED_RAYS: &str = "rt.occluded_rays";
    pub const RT_RAYS: &str = "rt.rays";
    pub const RT_TRIANGLE_TESTS: &str = "rt.triangle_tests";
    pub const SAMPLES: &str = "samples";
    pub const SCALAR_OPS: &str = "scalar_ops";
    pub const SCATTER_LINES: &str = "scatter_lines";
    pub const SCATTERS: &str = "scatters";
    pub const SHADER_INVOCATIONS: &str = "shader_invocations";
    pub const SHADOW_MAP_COVERED_TEXELS: &str = "shadow_map.covered_texels";
    pub const SHADOW_MAP_TAPS: &str = "shadow_map.taps";
    pub const SHADOW_MAP_TAPS_WASTED: &str = "shadow_map.taps_wasted";
    pub const SHADOW_QUADS: &str = "shadow_quads";
    pub const SHADOW_RAYS: &str = "shadow_rays";
    pub const SILHOUETTE_EDGES_OF_LIGHT: &str = "silhouette.edges";
    pub const SILHOUETTE_FACES_ALL_FRONT: &str = "silhouette.faces_all_front";
    pub const SILHOUETTE_FACES_NONE_FRONT: &str = "silhouette.faces_none_front";
    pub const SILHOUETTE_MAX_EDGES_PER_VERTEX: &str = "silhouette.max_edges_per_vertex";
    pub const SILHOUETTE_PENUMBRA_EDGES: &str = "silhouette.penumbra_edges";
    pub const SILHOUETTE_SILHOUETTE_FACES: &str = "silhouette.silhouette_faces";
    pub const SILHOUETTE_UMBRA_EDGES: &str = "silhouette.umbra_edges";
    pub const SILHOUETTE_VERTICES: &str = "silhouette.vertices";
    pub const SILHOUETTE_VERTICES_OVER_TWO_EDGES: &str = "silhouette.vertices_over_two_edges";
    pub const SILHOUETTE_EDGES: &str = "silhouette_edges";
    pub const SIMD_UTILIZATION: &str = "simd_utilization";
    pub const SSM_MICRO_PATCHES: &str = "ssm.micro_patches";
    pub const SSM_OCCLUDER_TEXELS: &str = "ssm.occluder_texels";
    pub const STEP__STEP__BANDWIDTH_BOUND: &str = "step.<step>.bandwidth_bound";
    pub const STEP__STEP__LOAD_IMBALANCE: &str = "step.<step>.load_imbalance";
    pub const STEP__STEP__MODEL_MS: &str = "step.<step>.model_ms";
    pub const STORES: &str = "stores";
    pub const TRANSFER_BYTES: &str = "transfer.bytes";
    pub const VECTOR_OPS: &str = "vector_ops";
    pub const VOLUME_CAPS: &str = "volume_caps";
    pub const VOLUMES_CLOSING_TRIANGLES: &str = "volumes.closing_triangles";
    pub const VOLUMES_DEGENERATE_EDGES: &str = "volumes.degenerate_edges";
    pub const VOLUMES_PENUMBRA_QUADS: &str = "volumes.penumbra_quads";
    pub const VOLUMES_SILHOUETTE_FACES: &str = "volumes.silhouette_faces";
    pub const VOLUMES_UMBRA_QUADS: &str = "volumes.umbra_quads";
    pub const VOLUMES_UMBRA_TRIANGLES: &str = "volumes.umbra_triangles";
    pub const VOLUMES_UMBRA_TRIM_PLANES: &str = "volumes.umbra_trim_planes";
    pub const WEDGE_CULLED_FRAGMENTS: &str = "wedge_culled_fragments";
    pub const WEDGE_PRIMITIVES: &str = "wedge_primitives";
    pub const WEDGE_TESTS: &str = "wedge_tests";
    pub const WEDGES: &str = "wedges";
    pub const WEDGES_DEGENERATE: &str = "wedges_degenerate";
}

/// Every counter, alphabetically by name.
pub const COUNTERS: &[Counter] = &[
    c(
        names::ACTIVE_LANES,
        "lanes",
        Model,
        Modelled,
        Lower,
        "active SIMD lanes summed over vector instructions",
    ),
    c(
        names::ATOMICS,
        "operations",
        ModelAndWgpu,
        Deterministic,
        Lower,
        "atomic read-modify-writes (on wgpu: soft_izb's WGSL atomics)",
    ),
    c(
        names::BIN_BYTES,
        "bytes",
        Cpu,
        Deterministic,
        Lower,
        "bytes of the binned rasterizer's bins (tile lists)",
    ),
    c(
        names::BIN_CULLED_QUADS,
        "quads",
        All,
        Deterministic,
        Lower,
        "penumbra quads culled per light-space bin (004 §2.5)",
    ),
    c(
        names::BIN_ENTRIES,
        "entries",
        CpuAndBinningWgpu,
        Deterministic,
        Lower,
        "primitive references written into screen, tile or grid bins",
    ),
    c(
        names::CACHE_L1_HITS,
        "accesses",
        Model,
        Modelled,
        Higher,
        "modelled L1 data-cache hits",
    ),
    c(
        names::CACHE_L1_MISSES,
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled L1 data-cache misses",
    ),
    c(
        names::CACHE_L2_HITS,
        "accesses",
        Model,
        Modelled,
        Higher,
        "modelled L2 hits (after an L1 miss)",
    ),
    c(
        names::CACHE_L2_MISSES,
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled L2 misses (served from DRAM, or from the L3 where the machine has one)",
    ),
    c(
        names::CACHE_L3_HITS,
        "accesses",
        Model,
        Modelled,
        Higher,
        "modelled hits in the shared L3 (after an L2 miss; machines with an L3 only)",
    ),
    c(
        names::CACHE_L3_MISSES,
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled L3 misses (served from DRAM; machines with an L3 only)",
    ),
    c(
        names::CASTERS_TRIANGLES,
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles on a light pass's draw list (step casters; near-clipped ones as fans)",
    ),
    c(
        names::COVERAGE_TEXTURE_READS,
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "4D coverage-texture reads of the per-pixel wedge walk (III §3.3)",
    ),
    c(
        names::CULLED_FRAGMENTS,
        "fragments",
        All,
        Deterministic,
        Lower,
        "fragments discarded by a cull test before shading",
    ),
    c(
        names::DBUFFER_BYTES,
        "bytes",
        All,
        Deterministic,
        Lower,
        "size of the D-buffer (003 §4)",
    ),
    c(
        names::DBUFFER_SCENE_FILL,
        "fragments",
        All,
        Deterministic,
        Lower,
        "fragments of the D-buffer's scene-depth pass",
    ),
    c(
        names::DENOISE_BUFFER_BYTES,
        "bytes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: size of its per-pixel buffers (inputs, trace output, penumbra radius, two \
         filter buffers)",
    ),
    c(
        names::DENOISE_FILTER_TAPS,
        "taps",
        All,
        Deterministic,
        Lower,
        "rt_denoised: neighbour reads of the à-trous passes (within the penumbra radius)",
    ),
    c(
        names::DENOISE_FILTERED_PIXELS,
        "pixels",
        All,
        Deterministic,
        Lower,
        "rt_denoised: pixels the denoiser filters (a blocker near, neither all lit nor all \
         shadowed around)",
    ),
    c(
        names::DENOISE_SEARCH_TAPS,
        "taps",
        All,
        Deterministic,
        Lower,
        "rt_denoised: neighbour reads of the penumbra search (hit distances, visibility)",
    ),
    c(
        names::DEPTH_FAIL,
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments of the binned rasterizer that failed the depth test",
    ),
    c(
        names::DEPTH_PASS,
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments of the binned rasterizer that passed the depth test",
    ),
    c(
        names::DRAM_READ_BYTES,
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled DRAM reads (L2 misses × line size)",
    ),
    c(
        names::DRAM_WRITE_BYTES,
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled DRAM writes (dirty lines written back)",
    ),
    c(
        names::FILL,
        "fragments",
        All,
        Deterministic,
        Lower,
        "rasterized fragments, texels or samples the shadow geometry covers (rt_denoised: \
         shadow rays, its unit of work)",
    ),
    c(
        names::FRAGMENTS_INSIDE_WEDGES,
        "fragments",
        All,
        Deterministic,
        Lower,
        "wedge fragments inside their wedge (001 III §3.2.2)",
    ),
    c(
        names::FRAGMENTS_REJECTED_EARLY,
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments the binned rasterizer rejected by hierarchical depth",
    ),
    c(
        names::GATHER_LINES,
        "cache lines",
        Model,
        Modelled,
        Lower,
        "distinct cache lines touched by gathers",
    ),
    c(
        names::GATHERS,
        "instructions",
        Model,
        Modelled,
        Lower,
        "vector gather instructions",
    ),
    c(
        names::HARD_COLUMNS,
        "columns",
        All,
        Deterministic,
        Lower,
        "light-space grid columns the umbra pass visits (004 §2.3)",
    ),
    c(
        names::HARD_HITS,
        "samples",
        All,
        Deterministic,
        Lower,
        "eye samples found inside an occluding triangle (004 §2.3)",
    ),
    c(
        names::HARD_TESTS,
        "tests",
        All,
        Deterministic,
        Lower,
        "sample-in-triangle tests of the umbra pass (004 §2.3)",
    ),
    c(
        names::IZB_GRID_BYTES,
        "bytes",
        All,
        Deterministic,
        Lower,
        "size of the irregular z-buffer's grid (004 §2.2)",
    ),
    c(
        names::IZB_SAMPLES_BYTES,
        "bytes",
        All,
        Deterministic,
        Lower,
        "size of the irregular z-buffer's eye samples (004 §2.2)",
    ),
    c(
        names::LIGHT_VIEW_CASTERS_NEAR_CLIPPED,
        "triangles",
        All,
        Deterministic,
        Lower,
        "occluder triangles cut by the light view's near plane (the part nearer the light is lost)",
    ),
    c(
        names::LIGHT_VIEW_FACES,
        "views",
        All,
        Deterministic,
        Lower,
        "light views rendered: 1, or the faces of a cube map when receivers span more than 60°",
    ),
    c(
        names::LIGHT_VIEW_RECEIVERS_OUTSIDE,
        "pixels",
        All,
        Deterministic,
        Lower,
        "visible receiver pixels facing the light centre outside every light view, taken as lit",
    ),
    c(
        names::LOADS,
        "instructions",
        Model,
        Modelled,
        Lower,
        "contiguous vector or scalar loads",
    ),
    c(
        names::MEM_EST__BUFFER__READ_BYTES,
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes read from a buffer, from record sizes and counts",
    ),
    c(
        names::MEM_EST__BUFFER__WRITE_BYTES,
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes written to a buffer, from record sizes and counts",
    ),
    c(
        names::MEM_EST_READ_BYTES,
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes read, all buffers",
    ),
    c(
        names::MEM_EST_WRITE_BYTES,
        "bytes",
        NativeAndWgpu,
        Estimated,
        Lower,
        "estimated bytes written, all buffers",
    ),
    c(
        names::MEM_MODEL__BUFFER__READ_BYTES,
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes read from a named buffer",
    ),
    c(
        names::MEM_MODEL__BUFFER__READS,
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled read accesses of a named buffer",
    ),
    c(
        names::MEM_MODEL__BUFFER__WRITE_BYTES,
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes written to a named buffer",
    ),
    c(
        names::MEM_MODEL__BUFFER__WRITES,
        "accesses",
        Model,
        Modelled,
        Lower,
        "modelled write accesses of a named buffer",
    ),
    c(
        names::MEM_MODEL_READ_BYTES,
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes read, all buffers",
    ),
    c(
        names::MEM_MODEL_WRITE_BYTES,
        "bytes",
        Model,
        Modelled,
        Lower,
        "modelled bytes written, all buffers",
    ),
    c(
        names::OCCLUDER_TRIANGLES,
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the occluders after facing and clipping",
    ),
    c(
        names::OCCLUDERS_BOUNDARY_EDGES,
        "edges",
        All,
        Deterministic,
        Lower,
        "occluder edges used by one triangle only (open meshes: shadow volumes may leak)",
    ),
    c(
        names::OCCLUDERS_NON_MANIFOLD_EDGES,
        "edges",
        All,
        Deterministic,
        Lower,
        "occluder edges shared by more than two triangles",
    ),
    c(
        names::OVERDRAW,
        "fragments",
        All,
        Deterministic,
        Lower,
        "fill that does not end up in the result (behind, culled or contributing nothing; \
         rt_denoised: the rays of a pixel whose rays all agree, beyond its first)",
    ),
    c(
        names::OVERDRAW_RATIO,
        "ratio",
        All,
        Deterministic,
        Lower,
        "derived: overdraw / fill",
    ),
    c(
        names::PENUMBRA_CONE_TRIANGLES,
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the penumbra map's cones (000 §3)",
    ),
    c(
        names::PENUMBRA_SHEET_TRIANGLES,
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the penumbra map's sheets (000 §3)",
    ),
    c(
        names::PENUMBRA_MAP_TAPS,
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "penumbra-map reads of the GPU eye lookup",
    ),
    c(
        names::PENUMBRA_QUADS,
        "quads",
        All,
        Deterministic,
        Lower,
        "penumbra quads of silhouette edges (004 §2.4)",
    ),
    c(
        names::PIPELINE_CLIPPER_INVOCATIONS,
        "primitives",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: primitives entering the clipper",
    ),
    c(
        names::PIPELINE_CLIPPER_PRIMITIVES_OUT,
        "primitives",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: primitives leaving the clipper",
    ),
    c(
        names::PIPELINE_COMPUTE_SHADER_INVOCATIONS,
        "invocations",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: compute invocations",
    ),
    c(
        names::PIPELINE_FRAGMENT_SHADER_INVOCATIONS,
        "invocations",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: fragment invocations (driver-defined)",
    ),
    c(
        names::PIPELINE_VERTEX_SHADER_INVOCATIONS,
        "invocations",
        Wgpu,
        Deterministic,
        Lower,
        "driver statistic: vertex invocations",
    ),
    c(
        names::QUAD_FRAGMENTS,
        "fragments",
        All,
        Deterministic,
        Lower,
        "fragments of penumbra quads (004 §2.4)",
    ),
    c(
        names::QUAD_TESTS,
        "tests",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-quad tests of the per-pixel walk over binned quads",
    ),
    c(
        names::RASTER_BLOCKS_REJECTED,
        "blocks",
        Cpu,
        Deterministic,
        Lower,
        "4×4 blocks the binned rasterizer rejected",
    ),
    c(
        names::RASTER_CLIPPED,
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles the binned rasterizer clipped at the near plane",
    ),
    c(
        names::RASTER_CULLED,
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles culled (back-facing, degenerate or off-screen)",
    ),
    c(
        names::RASTER_DISCARDED,
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments discarded by the fragment kernel",
    ),
    c(
        names::RASTER_TILES_REJECTED,
        "tiles",
        Cpu,
        Deterministic,
        Lower,
        "tiles the binned rasterizer rejected",
    ),
    c(
        names::RASTER_TRIANGLES,
        "triangles",
        Cpu,
        Deterministic,
        Lower,
        "triangles set up by the binned rasterizer",
    ),
    c(
        names::RASTER_TRIS_PER_TILE__RANGE_,
        "tiles",
        Cpu,
        Deterministic,
        Lower,
        "histogram: tiles with that many triangles",
    ),
    c(
        names::RASTER_WRITTEN,
        "fragments",
        Cpu,
        Deterministic,
        Lower,
        "fragments written by the binned rasterizer",
    ),
    c(
        names::RT_BVH_NODE_BYTES,
        "bytes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: size of the caster BVH's node records (64 bytes: both children's boxes)",
    ),
    c(
        names::RT_BVH_TRIANGLE_BYTES,
        "bytes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: size of the caster BVH's triangles (48 bytes each)",
    ),
    c(
        names::RT_HORIZON_CULLED,
        "samples",
        All,
        Deterministic,
        Lower,
        "rt_denoised: light samples behind a receiver-only surface's plane, dark without a ray",
    ),
    c(
        names::RT_NODE_VISITS,
        "nodes",
        All,
        Deterministic,
        Lower,
        "rt_denoised: interior BVH nodes fetched by the shadow rays (one 64-byte record each)",
    ),
    c(
        names::RT_OCCLUDED_RAYS,
        "rays",
        All,
        Deterministic,
        Lower,
        "rt_denoised: shadow rays a caster blocks",
    ),
    c(
        names::RT_RAYS,
        "rays",
        All,
        Deterministic,
        Lower,
        "rt_denoised: shadow rays cast (any-hit BVH traversals)",
    ),
    c(
        names::RT_TRIANGLE_TESTS,
        "tests",
        All,
        Deterministic,
        Lower,
        "rt_denoised: ray-triangle tests of the shadow rays",
    ),
    c(
        names::SAMPLES,
        "samples",
        All,
        Deterministic,
        Lower,
        "eye samples inserted into the irregular z-buffer (004 §2.2)",
    ),
    c(
        names::SCALAR_OPS,
        "instructions",
        Model,
        Modelled,
        Lower,
        "scalar instructions",
    ),
    c(
        names::SCATTER_LINES,
        "cache lines",
        Model,
        Modelled,
        Lower,
        "distinct cache lines touched by scatters",
    ),
    c(
        names::SCATTERS,
        "instructions",
        Model,
        Modelled,
        Lower,
        "vector scatter instructions",
    ),
    c(
        names::SHADER_INVOCATIONS,
        "invocations",
        All,
        Deterministic,
        Lower,
        "fragment-program runs in the cpu-model's terms",
    ),
    c(
        names::SHADOW_MAP_COVERED_TEXELS,
        "texels",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-map texels covered by an occluder (GPU replay)",
    ),
    c(
        names::SHADOW_MAP_TAPS,
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-map reads of the GPU eye lookup",
    ),
    c(
        names::SHADOW_MAP_TAPS_WASTED,
        "texel reads",
        Wgpu,
        Deterministic,
        Lower,
        "shadow-map reads of pixels that see no surface",
    ),
    c(
        names::SHADOW_QUADS,
        "quads",
        Wgpu,
        Deterministic,
        Lower,
        "hard shadow quads uploaded per light sample",
    ),
    c(
        names::SHADOW_RAYS,
        "rays",
        Cpu,
        Deterministic,
        Lower,
        "shadow rays the reference casts (pixels that see a surface × light samples)",
    ),
    c(
        names::SILHOUETTE_EDGES_OF_LIGHT,
        "edges",
        All,
        Deterministic,
        Lower,
        "silhouette edges from the light",
    ),
    c(
        names::SILHOUETTE_FACES_ALL_FRONT,
        "faces",
        All,
        Deterministic,
        Lower,
        "faces front-facing from every light point (003)",
    ),
    c(
        names::SILHOUETTE_FACES_NONE_FRONT,
        "faces",
        All,
        Deterministic,
        Lower,
        "faces front-facing from no light point (003)",
    ),
    c(
        names::SILHOUETTE_MAX_EDGES_PER_VERTEX,
        "edges",
        All,
        Deterministic,
        Lower,
        "most silhouette edges meeting at one vertex",
    ),
    c(
        names::SILHOUETTE_PENUMBRA_EDGES,
        "edges",
        All,
        Deterministic,
        Lower,
        "area-silhouette edges bounding the penumbra (003)",
    ),
    c(
        names::SILHOUETTE_SILHOUETTE_FACES,
        "faces",
        All,
        Deterministic,
        Lower,
        "faces between the two area silhouettes (003)",
    ),
    c(
        names::SILHOUETTE_UMBRA_EDGES,
        "edges",
        All,
        Deterministic,
        Lower,
        "area-silhouette edges bounding the umbra (003)",
    ),
    c(
        names::SILHOUETTE_VERTICES,
        "vertices",
        All,
        Deterministic,
        Lower,
        "silhouette vertices",
    ),
    c(
        names::SILHOUETTE_VERTICES_OVER_TWO_EDGES,
        "vertices",
        All,
        Deterministic,
        Lower,
        "silhouette vertices where more than two edges meet",
    ),
    c(
        names::SILHOUETTE_EDGES,
        "edges",
        All,
        Deterministic,
        Lower,
        "silhouette edges from the light centre",
    ),
    c(
        names::SIMD_UTILIZATION,
        "ratio",
        Model,
        Modelled,
        Higher,
        "derived: active_lanes / (vector_ops × 16)",
    ),
    c(
        names::SSM_MICRO_PATCHES,
        "patches",
        All,
        Deterministic,
        Lower,
        "micro-patches of the occluder map (002 §3)",
    ),
    c(
        names::SSM_OCCLUDER_TEXELS,
        "texels",
        All,
        Deterministic,
        Lower,
        "occluder-map texels that hold an occluder (002 §3)",
    ),
    c(
        names::STEP__STEP__BANDWIDTH_BOUND,
        "0 or 1",
        Model,
        Modelled,
        Lower,
        "1 when DRAM bandwidth bounds the step's modelled time",
    ),
    c(
        names::STEP__STEP__LOAD_IMBALANCE,
        "ratio",
        Model,
        Modelled,
        Lower,
        "slowest modelled core over the mean",
    ),
    c(
        names::STEP__STEP__MODEL_MS,
        "ms",
        Model,
        Modelled,
        Lower,
        "modelled time of one step of a phase",
    ),
    c(
        names::STORES,
        "instructions",
        Model,
        Modelled,
        Lower,
        "contiguous vector or scalar stores",
    ),
    c(
        names::TRANSFER_BYTES,
        "bytes",
        All,
        Deterministic,
        Lower,
        "bytes copied between device and host (002 occluder-map transfer)",
    ),
    c(
        names::VECTOR_OPS,
        "instructions",
        Model,
        Modelled,
        Lower,
        "16-wide vector instructions",
    ),
    c(
        names::VOLUME_CAPS,
        "faces",
        All,
        Deterministic,
        Lower,
        "light and dark caps of z-fail volumes (001 III)",
    ),
    c(
        names::VOLUMES_CLOSING_TRIANGLES,
        "triangles",
        All,
        Deterministic,
        Lower,
        "closing triangles of the umbra volumes (003)",
    ),
    c(
        names::VOLUMES_DEGENERATE_EDGES,
        "edges",
        All,
        Deterministic,
        Lower,
        "silhouette edges giving no volume face (003)",
    ),
    c(
        names::VOLUMES_PENUMBRA_QUADS,
        "quads",
        All,
        Deterministic,
        Lower,
        "quads of the penumbra volumes (003)",
    ),
    c(
        names::VOLUMES_SILHOUETTE_FACES,
        "faces",
        All,
        Deterministic,
        Lower,
        "silhouette faces of the volumes (003)",
    ),
    c(
        names::VOLUMES_UMBRA_QUADS,
        "quads",
        All,
        Deterministic,
        Lower,
        "quads of the umbra volumes (003)",
    ),
    c(
        names::VOLUMES_UMBRA_TRIANGLES,
        "triangles",
        All,
        Deterministic,
        Lower,
        "triangles of the umbra volumes (003)",
    ),
    c(
        names::VOLUMES_UMBRA_TRIM_PLANES,
        "planes",
        All,
        Deterministic,
        Lower,
        "trim planes at convex corners of the umbra (003)",
    ),
    c(
        names::WEDGE_CULLED_FRAGMENTS,
        "fragments",
        All,
        Deterministic,
        Lower,
        "wedge fragments culled by wedge-half culling (001 IV §4.4)",
    ),
    c(
        names::WEDGE_PRIMITIVES,
        "primitives",
        Wgpu,
        Deterministic,
        Lower,
        "wedge primitives of the per-pixel wedge walk",
    ),
    c(
        names::WEDGE_TESTS,
        "tests",
        Wgpu,
        Deterministic,
        Lower,
        "wedge tests of the per-pixel wedge walk",
    ),
    c(
        names::WEDGES,
        "wedges",
        All,
        Deterministic,
        Lower,
        "penumbra wedges built (001 III §3.1)",
    ),
    c(
        names::WEDGES_DEGENERATE,
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
