//! Penumbra maps as GPU passes, in the paper's order (§3):
//!
//! 1. `shadow_map`: the shadow-map family's light raster ([`Passes`]) of the shadow geometry;
//! 2. `silhouettes`: on the host, as the paper does (§4: brute force), the silhouette from the
//!    light centre and its cones and sheets ([`silhouettes`], [`PenumbraGeometry`]: the same
//!    code and triangles as the cpu executions); host wall time only;
//! 3. `penumbra_map`: a render pass draws the cones and sheets into a Depth32Float penumbra
//!    map cleared to 1.0 with the fragment program of §3 (`wgpu.wgsl`); the intensity is the
//!    fragment's depth and the depth test Less keeps the darkest (§4);
//! 4. `eye_lookup`: the family's lookup over the gbuffer with `wgpu_lookup.wgsl`: umbra where
//!    the shadow map shadows the receiver, else the penumbra map's intensity.
//!
//! As in the family, the instrumented replay's atomics count the cone and sheet fragments
//! (`fill`), those discarded behind the shadow-map surface (`overdraw`, as on the cpu
//! executions) and the lookup's penumbra-map taps. The geometry upload is part of the
//! `penumbra_map` phase's wall time. The edge adjacency of the occluders is per-model
//! preprocessing, built before the first phase, as is the optional simplified mesh.

use super::Phase;
use super::{
    shadow_geometry, silhouettes, PenumbraGeometry, PenumbraMapOptions, ShadowGeometry,
    Silhouettes, ID,
};
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::algorithms::shadow_map::wgpu::{
    self as shadow_map_wgpu, Counts, Lookup, Passes, LIGHT_RASTER_WGSL, NOTE, PRELUDE,
};
use crate::algorithms::shadow_map::{FaceView, LightView, LightViews, ViewFit};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, view as view_resource, Bind, Layout, Mesh, Pass, Program, Raster, Readout, Render,
    Statistics, Timed, DEPTH_TEXEL_BYTES,
};
use crate::gpu::readback::first;
use crate::gpu::Run;
use crate::record::Counters;
use crate::scene::adjacency::EdgeAdjacency;

const PENUMBRA_WGSL: &str = include_str!("wgpu.wgsl");

/// Bytes of one penumbra vertex: light-view position and `Z_v`.
const VERTEX_BYTES: f64 = 16.0;

/// `penumbra_map` on wgpu (`ctx` unused: the passes need nothing of the run's context).
pub fn render(
    gpu: &Run,
    frame: &Frame,
    _ctx: &ExecContext,
    o: &PenumbraMapOptions,
) -> Result<FrameOutput> {
    shadow_map_wgpu::check_limits(gpu, frame, ID)?;
    let geometry = shadow_geometry(frame, o);
    let views = LightViews::fit(frame, ViewFit::Single);
    let mut out =
        PenumbraPasses::new(gpu, frame, o, &geometry, &views.views[0]).run(frame, &geometry, o)?;
    views.record(&mut out);
    Ok(out)
}

gpu_struct! {
    /// The penumbra pass's uniform: the light view's projection (`LightView::proj`); the cones
    /// and sheets are already in its view space.
    struct PenumbraView as "PenumbraView" {
        proj: [f32; 16] => "mat4x4<f32>",
    }
}

/// The penumbra pass's shader as its pipeline joins it.
fn sources() -> Vec<&'static str> {
    [
        &PRELUDE[..],
        &[LIGHT_RASTER_WGSL, PenumbraView::WGSL, PENUMBRA_WGSL],
    ]
    .concat()
}

struct PenumbraPasses<'g> {
    passes: Passes<'g>,
    view: LightView,
    penumbra_view: wgpu::TextureView,
    penumbra_group: wgpu::BindGroup,
    lookup_group: wgpu::BindGroup,
    /// The penumbra pass's pipelines: timed, counting.
    pipeline: Render,
}

impl<'g> PenumbraPasses<'g> {
    fn new(
        gpu: &'g Run,
        frame: &Frame,
        o: &PenumbraMapOptions,
        geometry: &ShadowGeometry,
        face: &FaceView,
    ) -> PenumbraPasses<'g> {
        use wgpu::ShaderStages as S;
        let view = face.view;
        // Group 2 of the eye lookup: the penumbra map.
        let lookup_layout = Layout::new(gpu, "penumbra lookup", S::COMPUTE, &[Bind::Depth]);
        let lookup = Lookup::new(ID, include_str!("wgpu_lookup.wgsl"), o.bias);
        let casters = view.casters(&geometry.shadow_map);
        let passes = Passes::new(gpu, frame, &lookup, face, &casters, Some(&lookup_layout));
        let depth_format = wgpu::TextureFormat::Depth32Float;
        let penumbra_view = gpu.map_view("penumbra map", frame.params.map_resolution, depth_format);
        let lookup_group =
            lookup_layout.group(gpu, "penumbra lookup", &[view_resource(&penumbra_view)]);
        // Group 1 of the penumbra pass: the projection and the shadow map.
        let proj = PenumbraView {
            proj: view.proj.to_cols_array(),
        };
        let uniform = gpu.upload("penumbra view", &[proj], wgpu::BufferUsages::UNIFORM);
        let binds = [
            (Bind::Uniform, uniform.as_entire_binding()),
            (Bind::Depth, view_resource(&passes.depth_view)),
        ];
        let (penumbra_layout, penumbra_group) =
            Layout::bound(gpu, "penumbra pass", S::VERTEX_FRAGMENT, &binds);
        let groups = [Some(&passes.shared.layout), Some(&penumbra_layout)];
        let program = Program::new(gpu, "penumbra_map/wgpu.wgsl", &sources(), &groups);
        // Cones and sheets are seen from both sides.
        let raster = Raster::of_vertices("vs_penumbra", "fs_penumbra", &Mesh::POSITION_W);
        PenumbraPasses {
            pipeline: program.render_instrumented(gpu, &raster),
            passes,
            view,
            penumbra_view,
            penumbra_group,
            lookup_group,
        }
    }

    /// Uploads the cones and sheets (light-view position and `Z_v` per vertex).
    fn upload(&self, g: &PenumbraGeometry) -> Mesh {
        let z_v = g.attributes.iter().map(|a| a.x);
        Mesh::with_w(self.passes.gpu, "penumbra", &g.positions, z_v, &g.triangles)
    }

    /// The penumbra pass: cleared to white (1.0), then every cone and sheet.
    fn penumbra_pass<'a>(&'a self, cones: &'a Mesh) -> Pass<'a> {
        let groups = [Some(&self.passes.shared.group), Some(&self.penumbra_group)];
        let draw = cones.draw(&self.pipeline, None, Some(&self.penumbra_view));
        Pass::draw("penumbra_map", &groups, draw)
    }

    fn run(
        &self,
        frame: &Frame,
        geometry: &ShadowGeometry,
        o: &PenumbraMapOptions,
    ) -> Result<FrameOutput> {
        let p = &self.passes;
        let light = frame.scene.light.center();
        let light_radius = frame.scene.light.size();
        let adj = EdgeAdjacency::build(&geometry.occluders);
        let extra = Some(&self.lookup_group);

        // The timed submission, one phase at a time (GPU passes 0, 1, 2: shadow map, penumbra
        // map, eye lookup).
        // The instrumented replay: the counters are cleared before each phase's passes and
        // copied after (`count_covered` with the lookup's pipeline layout, group 2 included).
        let mut run = Timed::new(p.gpu, Phase::ALL, Statistics::All, &[&p.eye.visibility])
            .counting_into(&p.shared.counts, Readout::EachPhase);
        run.submit(Phase::ShadowMap, &[p.raster_pass(), p.covered_pass(extra)])?;
        let s = run.host(Phase::Silhouettes, || {
            silhouettes(&adj, &self.view, light, light_radius, o.max_sheet_strips)
        });
        // The geometry's build and upload belong to the penumbra_map phase.
        let cones = run.host(Phase::PenumbraMap, || {
            let g = PenumbraGeometry::build(&s, &self.view, light_radius, o.cone_segments);
            self.upload(&g)
        });
        run.submit(Phase::PenumbraMap, &[self.penumbra_pass(&cones)])?;
        run.submit(Phase::EyeLookup, &[p.lookup_pass(extra)])?;
        let timing = run.finish()?;
        let counts: Vec<Counts> = timing.counts.iter().map(|b| first(b)).collect();
        let mut eye = p.lookup_counters(frame, &counts[2]);
        let taps = f64::from(counts[2].extra_taps);
        eye.set(names::PENUMBRA_MAP_TAPS, taps);
        let read = [("penumbra_map", taps * DEPTH_TEXEL_BYTES)];
        eye.add_traffic("mem_est", &read, &[]);
        let counters = vec![
            (Phase::ShadowMap, p.raster_counters(&counts[0])),
            // `silhouettes`: the counts the cpu executions record in the same phase.
            (
                Phase::Silhouettes,
                Counters(s.counts().map(|(k, v)| (k.to_string(), v)).into()),
            ),
            (
                Phase::PenumbraMap,
                self.penumbra_counters(&s, o, &cones, &counts[1]),
            ),
            (Phase::EyeLookup, eye),
        ];
        Ok(timing.output((p.width, p.height), counters, NOTE))
    }

    /// `penumbra_map`: fill is every cone and sheet fragment, overdraw those discarded behind
    /// the shadow-map surface (as on the cpu executions). Memory traffic estimated: the
    /// geometry, a shadow-map read per fragment, and a depth test (read) per fragment kept,
    /// bounded writes of the penumbra map (the clear and one per fragment kept).
    fn penumbra_counters(
        &self,
        s: &Silhouettes,
        o: &PenumbraMapOptions,
        cones: &Mesh,
        c: &Counts,
    ) -> Counters {
        let fragments = f64::from(c.fragments);
        let discarded = f64::from(c.discarded);
        let kept = fragments - discarded;
        let mut k = Counters::default();
        k.add_fill(fragments, discarded);
        let cone_triangles = s.vertices.len() as f64 * f64::from(o.cone_segments);
        k.set(names::PENUMBRA_CONE_TRIANGLES, cone_triangles);
        let sheet_triangles = f64::from(cones.index_count / 3) - cone_triangles;
        k.set(names::PENUMBRA_SHEET_TRIANGLES, sheet_triangles);
        let shadow = [("shadow_map", fragments * DEPTH_TEXEL_BYTES)];
        let map = ("penumbra_map", self.passes.resolution, kept);
        cones.depth_traffic(&mut k, ("penumbra", VERTEX_BYTES), map, &shadow);
        k
    }
}

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(sources() => PenumbraView);
