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
    /// Whether a record of `backend` may carry the counter.
    pub fn on(self, backend: &str) -> bool {
        match self {
            Recorded::All => true,
            Recorded::Cpu => backend != "wgpu",
            Recorded::Model => backend == "cpu-model",
            Recorded::Wgpu => backend == "wgpu",
            Recorded::NativeAndWgpu => backend != "cpu-model",
            Recorded::ModelAndWgpu => backend != "cpu-native",
            Recorded::CpuAndBinningWgpu => true,
        }
    }

    fn label(self) -> &'static str {
        match self {
            Recorded::All => "all",
            Recorded::Cpu => "cpu",
            Recorded::Model => "cpu-model",
            Recorded::Wgpu => "wgpu",
            Recorded::NativeAndWgpu => "cpu-native, wgpu",
            Recorded::ModelAndWgpu => "cpu-model, wgpu",
            Recorded::CpuAndBinningWgpu => "cpu; wgpu bins",
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
    pub meaning: &'static str,
}

const fn c(
    name: &'static str,
    unit: &'static str,
    recorded: Recorded,
    meaning: &'static str,
) -> Counter {
    Counter {
        name,
        unit,
        recorded,
        meaning,
    }
}

use Recorded::{All, Cpu, CpuAndBinningWgpu, Model, ModelAndWgpu, NativeAndWgpu, Wgpu};

/// Every counter, alphabetically by name.
pub const COUNTERS: &[Counter] = &[
    c(
        "active_lanes",
        "lanes",
        Model,
        "active SIMD lanes summed over vector instructions",
    ),
    c(
        "atomics",
        "operations",
        ModelAndWgpu,
        "atomic read-modify-writes (on wgpu: soft_izb's WGSL atomics)",
    ),
    c(
        "bin_bytes",
        "bytes",
        Cpu,
        "bytes of the binned rasterizer's bins (tile lists)",
    ),
    c(
        "bin_culled_quads",
        "quads",
        All,
        "penumbra quads culled per light-space bin (004 §2.5)",
    ),
    c(
        "bin_entries",
        "entries",
        CpuAndBinningWgpu,
        "primitive references written into screen, tile or grid bins",
    ),
    c(
        "cache.l1_hits",
        "accesses",
        Model,
        "modelled L1 data-cache hits",
    ),
    c(
        "cache.l1_misses",
        "accesses",
        Model,
        "modelled L1 data-cache misses",
    ),
    c(
        "cache.l2_hits",
        "accesses",
        Model,
        "modelled L2 hits (after an L1 miss)",
    ),
    c(
        "cache.l2_misses",
        "accesses",
        Model,
        "modelled L2 misses (served from DRAM)",
    ),
    c(
        "casters.triangles",
        "triangles",
        Cpu,
        "triangles on a light pass's draw list (step casters; near-clipped ones as fans)",
    ),
    c(
        "coverage_texture_reads",
        "texel reads",
        Wgpu,
        "4D coverage-texture reads of the per-pixel wedge walk (III §3.3)",
    ),
    c(
        "culled_fragments",
        "fragments",
        All,
        "fragments discarded by a cull test before shading",
    ),
    c(
        "dbuffer.bytes",
        "bytes",
        All,
        "size of the D-buffer (003 §4)",
    ),
    c(
        "dbuffer.scene_fill",
        "fragments",
        All,
        "fragments of the D-buffer's scene-depth pass",
    ),
    c(
        "depth_fail",
        "fragments",
        Cpu,
        "fragments of the binned rasterizer that failed the depth test",
    ),
    c(
        "depth_pass",
        "fragments",
        Cpu,
        "fragments of the binned rasterizer that passed the depth test",
    ),
    c(
        "dram_read_bytes",
        "bytes",
        Model,
        "modelled DRAM reads (L2 misses × line size)",
    ),
    c(
        "dram_write_bytes",
        "bytes",
        Model,
        "modelled DRAM writes (dirty lines written back)",
    ),
    c(
        "fill",
        "fragments",
        All,
        "rasterized fragments, texels or samples the shadow geometry covers",
    ),
    c(
        "fragments_inside_wedges",
        "fragments",
        All,
        "wedge fragments inside their wedge (001 III §3.2.2)",
    ),
    c(
        "fragments_rejected_early",
        "fragments",
        Cpu,
        "fragments the binned rasterizer rejected by hierarchical depth",
    ),
    c(
        "gather_lines",
        "cache lines",
        Model,
        "distinct cache lines touched by gathers",
    ),
    c(
        "gathers",
        "instructions",
        Model,
        "vector gather instructions",
    ),
    c(
        "hard_columns",
        "columns",
        All,
        "light-space grid columns the umbra pass visits (004 §2.3)",
    ),
    c(
        "hard_hits",
        "samples",
        All,
        "eye samples found inside an occluding triangle (004 §2.3)",
    ),
    c(
        "hard_tests",
        "tests",
        All,
        "sample-in-triangle tests of the umbra pass (004 §2.3)",
    ),
    c(
        "izb_grid_bytes",
        "bytes",
        All,
        "size of the irregular z-buffer's grid (004 §2.2)",
    ),
    c(
        "izb_samples_bytes",
        "bytes",
        All,
        "size of the irregular z-buffer's eye samples (004 §2.2)",
    ),
    c(
        "light_view.casters_near_clipped",
        "triangles",
        All,
        "occluder triangles cut by the light view's near plane (the part nearer the light is lost)",
    ),
    c(
        "light_view.faces",
        "views",
        All,
        "light views rendered: 1, or the faces of a cube map when receivers span more than 60°",
    ),
    c(
        "light_view.receivers_outside",
        "pixels",
        All,
        "visible receiver pixels outside every light view, taken as lit",
    ),
    c(
        "loads",
        "instructions",
        Model,
        "contiguous vector or scalar loads",
    ),
    c(
        "mem_est.<buffer>.read_bytes",
        "bytes",
        NativeAndWgpu,
        "estimated bytes read from a buffer, from record sizes and counts",
    ),
    c(
        "mem_est.<buffer>.write_bytes",
        "bytes",
        NativeAndWgpu,
        "estimated bytes written to a buffer, from record sizes and counts",
    ),
    c(
        "mem_est.read_bytes",
        "bytes",
        NativeAndWgpu,
        "estimated bytes read, all buffers",
    ),
    c(
        "mem_est.write_bytes",
        "bytes",
        NativeAndWgpu,
        "estimated bytes written, all buffers",
    ),
    c(
        "mem_model.<buffer>.read_bytes",
        "bytes",
        Model,
        "modelled bytes read from a named buffer",
    ),
    c(
        "mem_model.<buffer>.reads",
        "accesses",
        Model,
        "modelled read accesses of a named buffer",
    ),
    c(
        "mem_model.<buffer>.write_bytes",
        "bytes",
        Model,
        "modelled bytes written to a named buffer",
    ),
    c(
        "mem_model.<buffer>.writes",
        "accesses",
        Model,
        "modelled write accesses of a named buffer",
    ),
    c(
        "mem_model.read_bytes",
        "bytes",
        Model,
        "modelled bytes read, all buffers",
    ),
    c(
        "mem_model.write_bytes",
        "bytes",
        Model,
        "modelled bytes written, all buffers",
    ),
    c(
        "occluder_triangles",
        "triangles",
        All,
        "triangles of the occluders after facing and clipping",
    ),
    c(
        "occluders.boundary_edges",
        "edges",
        All,
        "occluder edges used by one triangle only (open meshes: shadow volumes may leak)",
    ),
    c(
        "occluders.non_manifold_edges",
        "edges",
        All,
        "occluder edges shared by more than two triangles",
    ),
    c(
        "overdraw",
        "fragments",
        All,
        "fill that does not end up in the result (behind, culled or contributing nothing)",
    ),
    c("overdraw_ratio", "ratio", All, "derived: overdraw / fill"),
    c(
        "penumbra.cone_triangles",
        "triangles",
        All,
        "triangles of the penumbra map's cones (000 §3)",
    ),
    c(
        "penumbra.sheet_triangles",
        "triangles",
        All,
        "triangles of the penumbra map's sheets (000 §3)",
    ),
    c(
        "penumbra_map.taps",
        "texel reads",
        Wgpu,
        "penumbra-map reads of the GPU eye lookup",
    ),
    c(
        "penumbra_quads",
        "quads",
        All,
        "penumbra quads of silhouette edges (004 §2.4)",
    ),
    c(
        "pipeline.clipper_invocations",
        "primitives",
        Wgpu,
        "driver statistic: primitives entering the clipper",
    ),
    c(
        "pipeline.clipper_primitives_out",
        "primitives",
        Wgpu,
        "driver statistic: primitives leaving the clipper",
    ),
    c(
        "pipeline.compute_shader_invocations",
        "invocations",
        Wgpu,
        "driver statistic: compute invocations",
    ),
    c(
        "pipeline.fragment_shader_invocations",
        "invocations",
        Wgpu,
        "driver statistic: fragment invocations (driver-defined)",
    ),
    c(
        "pipeline.vertex_shader_invocations",
        "invocations",
        Wgpu,
        "driver statistic: vertex invocations",
    ),
    c(
        "quad_fragments",
        "fragments",
        All,
        "fragments of penumbra quads (004 §2.4)",
    ),
    c(
        "quad_tests",
        "tests",
        Wgpu,
        "shadow-quad tests of the per-pixel walk over binned quads",
    ),
    c(
        "raster.blocks_rejected",
        "blocks",
        Cpu,
        "4×4 blocks the binned rasterizer rejected",
    ),
    c(
        "raster.clipped",
        "triangles",
        Cpu,
        "triangles the binned rasterizer clipped at the near plane",
    ),
    c(
        "raster.culled",
        "triangles",
        Cpu,
        "triangles culled (back-facing, degenerate or off-screen)",
    ),
    c(
        "raster.discarded",
        "fragments",
        Cpu,
        "fragments discarded by the fragment kernel",
    ),
    c(
        "raster.tiles_rejected",
        "tiles",
        Cpu,
        "tiles the binned rasterizer rejected",
    ),
    c(
        "raster.triangles",
        "triangles",
        Cpu,
        "triangles set up by the binned rasterizer",
    ),
    c(
        "raster.tris_per_tile.<range>",
        "tiles",
        Cpu,
        "histogram: tiles with that many triangles",
    ),
    c(
        "raster.written",
        "fragments",
        Cpu,
        "fragments written by the binned rasterizer",
    ),
    c(
        "samples",
        "samples",
        All,
        "eye samples inserted into the irregular z-buffer (004 §2.2)",
    ),
    c("scalar_ops", "instructions", Model, "scalar instructions"),
    c(
        "scatter_lines",
        "cache lines",
        Model,
        "distinct cache lines touched by scatters",
    ),
    c(
        "scatters",
        "instructions",
        Model,
        "vector scatter instructions",
    ),
    c(
        "shader_invocations",
        "invocations",
        All,
        "fragment-program runs in the cpu-model's terms",
    ),
    c(
        "shadow_map.covered_texels",
        "texels",
        Wgpu,
        "shadow-map texels covered by an occluder (GPU replay)",
    ),
    c(
        "shadow_map.taps",
        "texel reads",
        Wgpu,
        "shadow-map reads of the GPU eye lookup",
    ),
    c(
        "shadow_map.taps_wasted",
        "texel reads",
        Wgpu,
        "shadow-map reads of pixels that see no surface",
    ),
    c(
        "shadow_quads",
        "quads",
        Wgpu,
        "hard shadow quads uploaded per light sample",
    ),
    c(
        "shadow_rays",
        "rays",
        Cpu,
        "shadow rays the reference casts (pixels that see a surface × light samples)",
    ),
    c(
        "silhouette.edges",
        "edges",
        All,
        "silhouette edges from the light",
    ),
    c(
        "silhouette.faces_all_front",
        "faces",
        All,
        "faces front-facing from every light point (003)",
    ),
    c(
        "silhouette.faces_none_front",
        "faces",
        All,
        "faces front-facing from no light point (003)",
    ),
    c(
        "silhouette.max_edges_per_vertex",
        "edges",
        All,
        "most silhouette edges meeting at one vertex",
    ),
    c(
        "silhouette.penumbra_edges",
        "edges",
        All,
        "area-silhouette edges bounding the penumbra (003)",
    ),
    c(
        "silhouette.silhouette_faces",
        "faces",
        All,
        "faces between the two area silhouettes (003)",
    ),
    c(
        "silhouette.umbra_edges",
        "edges",
        All,
        "area-silhouette edges bounding the umbra (003)",
    ),
    c(
        "silhouette.vertices",
        "vertices",
        All,
        "silhouette vertices",
    ),
    c(
        "silhouette.vertices_over_two_edges",
        "vertices",
        All,
        "silhouette vertices where more than two edges meet",
    ),
    c(
        "silhouette_edges",
        "edges",
        All,
        "silhouette edges from the light centre",
    ),
    c(
        "simd_utilization",
        "ratio",
        Model,
        "derived: active_lanes / (vector_ops × 16)",
    ),
    c(
        "ssm.micro_patches",
        "patches",
        All,
        "micro-patches of the occluder map (002 §3)",
    ),
    c(
        "ssm.occluder_texels",
        "texels",
        All,
        "occluder-map texels that hold an occluder (002 §3)",
    ),
    c(
        "step.<step>.bandwidth_bound",
        "0 or 1",
        Model,
        "1 when DRAM bandwidth bounds the step's modelled time",
    ),
    c(
        "step.<step>.load_imbalance",
        "ratio",
        Model,
        "slowest modelled core over the mean",
    ),
    c(
        "step.<step>.model_ms",
        "ms",
        Model,
        "modelled time of one step of a phase",
    ),
    c(
        "stores",
        "instructions",
        Model,
        "contiguous vector or scalar stores",
    ),
    c(
        "transfer.bytes",
        "bytes",
        All,
        "bytes copied between device and host (002 occluder-map transfer)",
    ),
    c(
        "vector_ops",
        "instructions",
        Model,
        "16-wide vector instructions",
    ),
    c(
        "volume_caps",
        "faces",
        All,
        "light and dark caps of z-fail volumes (001 III)",
    ),
    c(
        "volumes.closing_triangles",
        "triangles",
        All,
        "closing triangles of the umbra volumes (003)",
    ),
    c(
        "volumes.degenerate_edges",
        "edges",
        All,
        "silhouette edges giving no volume face (003)",
    ),
    c(
        "volumes.penumbra_quads",
        "quads",
        All,
        "quads of the penumbra volumes (003)",
    ),
    c(
        "volumes.silhouette_faces",
        "faces",
        All,
        "silhouette faces of the volumes (003)",
    ),
    c(
        "volumes.umbra_quads",
        "quads",
        All,
        "quads of the umbra volumes (003)",
    ),
    c(
        "volumes.umbra_triangles",
        "triangles",
        All,
        "triangles of the umbra volumes (003)",
    ),
    c(
        "volumes.umbra_trim_planes",
        "planes",
        All,
        "trim planes at convex corners of the umbra (003)",
    ),
    c(
        "wedge_culled_fragments",
        "fragments",
        All,
        "wedge fragments culled by wedge-half culling (001 IV §4.4)",
    ),
    c(
        "wedge_primitives",
        "primitives",
        Wgpu,
        "wedge primitives of the per-pixel wedge walk",
    ),
    c(
        "wedge_tests",
        "tests",
        Wgpu,
        "wedge tests of the per-pixel wedge walk",
    ),
    c(
        "wedges",
        "wedges",
        All,
        "penumbra wedges built (001 III §3.1)",
    ),
    c(
        "wedges_degenerate",
        "wedges",
        All,
        "wedges too thin to rasterize",
    ),
];

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

/// The glossary as `shadowbench list --counters` prints it: name, unit, executions, meaning.
pub fn glossary() -> String {
    let w = COUNTERS.iter().map(|c| c.name.len()).max().unwrap_or(0);
    let mut s = String::from(
        "counters (name, unit, recorded by, meaning); <...> stands for a buffer, step or range.\n\
         Memory: mem_model.* is modelled (cpu-model), mem_est.* estimated from sizes and counts\n\
         (cpu-native shadow volumes, wgpu); no execution measures memory traffic.\n",
    );
    for c in COUNTERS {
        s.push_str(&format!(
            "  {:<w$}  {:<12}  {:<16}  {}\n",
            c.name,
            c.unit,
            c.recorded.label(),
            c.meaning
        ));
    }
    s
}

/// The names of the derived figures ([`derive`]).
pub const DERIVED: [&str; 2] = ["overdraw_ratio", "simd_utilization"];

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
pub fn current_name<'a>(backend: &str, name: &'a str) -> Cow<'a, str> {
    let kind = if backend == "cpu-model" {
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
pub fn upgrade(backend: &str, c: &mut Counters) {
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
            current_name("cpu-model", "mem_read_bytes"),
            "mem_model.read_bytes"
        );
        assert_eq!(
            current_name("cpu-model", "mem.depth.reads"),
            "mem_model.depth.reads"
        );
        assert_eq!(
            current_name("cpu-native", "mem_write_bytes"),
            "mem_est.write_bytes"
        );
        assert_eq!(current_name("wgpu", "mem_read_bytes"), "mem_est.read_bytes");
        assert_eq!(
            current_name("cpu-model", "mem.izb_grid.bytes"),
            "izb_grid_bytes"
        );
        assert_eq!(
            current_name("wgpu", "mem_est.depth.read_bytes"),
            "mem_est.depth.read_bytes"
        );
        assert_eq!(current_name("cpu-model", "fill"), "fill");
    }
}
