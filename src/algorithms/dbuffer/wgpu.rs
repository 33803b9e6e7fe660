//! `dbuffer` as GPU passes. As in the paper's implementation (§5, §6.1: "the volumes are
//! generated on the CPU"), phases `silhouettes` and `volumes` run on the host (the cpu-native
//! kernels, wall time only: on the host's threads, or on one thread with `volume_build:
//! single_core`, the paper's single CPU); then:
//!
//! 1. `dbuffer` — three render passes from the light centre into `map_resolution`² targets:
//!    the occluders' depth (Depth32Float, `|cx_o|`; a receiver-only object casts no shadow);
//!    the umbra volume (its own Depth32Float for `|cx_uv|` and an R32Float colour target for
//!    the edge depth behind `|cx_s|`), whose fragment shader reads the occluders' depth and
//!    discards fragments in front of it; the
//!    penumbra volume (Depth32Float and R32Float likewise). The D-buffer is thus five
//!    single-channel textures rather than one RGBA target: each volume needs its own depth
//!    test (nearest surface, [`super::DEPTH_RULE`]) and the edge depth must come from the same
//!    fragment that wins it, which blending per channel cannot guarantee.
//! 2. `eye_lookup` — a compute pass over the shared gbuffer (the shadow-map family's kernel in
//!    `shadow_map/light_view.wgsl`): eq. 2, 3 and 4 (`shade` in `wgpu.wgsl`).
//!
//! The instrumented replay ([`crate::gpu::pass`]) counts the volume fragments (`fill`) and the
//! D-buffer texels they left covered (`fill − covered = overdraw`), as the shadow-map family.

use super::volumes::{build_volumes, VolumeMesh};
use super::Phase;
use super::{DbufferOptions, Disc, Falloff, ID};
use crate::algorithms::algorithm::{Backend, ExecContext, FrameOutput};
use crate::algorithms::exec::machine;
use crate::algorithms::shadow_map::wgpu::LIGHT_VIEW_WGSL;
use crate::algorithms::shadow_map::{LightView, LightViews, ViewFit};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, tiles, view as view_resource, Bind::*, Compute, EyeBuffers, Instrumented, Layout,
    Mesh, Pass, Program, Raster, Readout, Render, Shared, Statistics, Timed,
};
use crate::gpu::readback::first;
use crate::gpu::{record_execution, Needs, Run};
use crate::record::Counters;
use crate::scene::adjacency::EdgeAdjacency;
use serde_json::json;

const WGSL: &str = include_str!("wgpu.wgsl");
/// Side of the square compute workgroups (`@workgroup_size(8, 8)`).
const WORKGROUP: u32 = 8;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const EDGE: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;

gpu_struct! {
    /// The light view and the method's parameters (group 0, binding 0 of every pass).
    struct DbufferUniform as "Light" {
        view_proj: [f32; 16] => "mat4x4<f32>",
        /// The light centre c (`LightView::eye`) and the disc radius.
        eye: [f32; 3] => "vec3<f32>",
        radius: f32 => "f32",
        /// n_c in light-view space.
        n_view: [f32; 3] => "vec3<f32>",
        near: f32 => "f32",
        /// n_c in world space.
        disc_n: [f32; 3] => "vec3<f32>",
        far: f32 => "f32",
        tan_half_fov: f32 => "f32",
        resolution: u32 => "u32",
        bias_constant: f32 => "f32",
        bias_slope: f32 => "f32",
        /// 0: 3t² − 2t³ (eq. 4), 1: √t (§6.2).
        falloff: u32 => "u32",
        width: u32 => "u32",
        height: u32 => "u32",
        pad: u32 => "u32",
    }
}

gpu_struct! {
    /// The counters of the instrumented replay (group 0, binding 1).
    struct Counts as "Counts" {
        scene_fragments: u32 => "atomic<u32>",
        umbra_fragments: u32 => "atomic<u32>",
        penumbra_fragments: u32 => "atomic<u32>",
        umbra_covered: u32 => "atomic<u32>",
        penumbra_covered: u32 => "atomic<u32>",
        pad: u32 => "u32",
    }
}

/// The shader as the pipelines join it.
const SOURCES: [&str; 4] = [DbufferUniform::WGSL, Counts::WGSL, LIGHT_VIEW_WGSL, WGSL];

/// `dbuffer` on wgpu.
pub fn render(
    gpu: &Run,
    frame: &Frame,
    ctx: &ExecContext,
    o: &DbufferOptions,
) -> Result<FrameOutput> {
    let res = frame.params.map_resolution;
    gpu.check_limits(ID, Needs::map(res))?;
    // The host phases, as the cpu-native execution runs them: their wall time on the host's
    // threads, or on one host thread with `volume_build: single_core`.
    let mut m = machine(Backend::CpuNative, frame, ctx);
    let disc = Disc::of(&frame.scene.light, frame.scene.bounds().center());
    let occluders = frame.scene.occluders();
    let adj = EdgeAdjacency::build(&occluders);
    let views = LightViews::fit(frame, ViewFit::Single);
    let view = *views.single();
    let v = build_volumes(&mut m, frame, &adj, disc, &view, o);
    let host = m.finish();
    let volumes = [&v.umbra, &v.penumbra];
    let mut out = Passes::new(gpu, frame, (&view, disc), &occluders, volumes, o).run(frame)?;
    let volume_build = o.volume_build.describe();
    record_execution(&mut out.execution, json!({ "volume_build": volume_build }));
    let mut phases = host.phases;
    phases.append(&mut out.phases);
    for p in &phases[..2] {
        out.counters.merge(&p.counters);
    }
    out.phases = phases;
    views.record(&mut out);
    Ok(out)
}

struct Passes<'g> {
    gpu: &'g Run,
    width: u32,
    height: u32,
    resolution: u32,
    /// Scene, umbra volume, penumbra volume.
    meshes: [Mesh; 3],
    /// Depth targets (scene, umbra, penumbra) and edge targets (umbra, penumbra).
    depth: [wgpu::TextureView; 3],
    edge: [wgpu::TextureView; 2],
    visibility: wgpu::Buffer,
    shared: Shared,
    scene_group: wgpu::BindGroup,
    lookup_group: wgpu::BindGroup,
    /// The D-buffer's scene, umbra and penumbra draws (counting in the replay), the lookup
    /// (timed only) and the replay's `count_covered`.
    draws: [Render; 3],
    lookup: Compute,
    count_covered: Compute,
}

impl<'g> Passes<'g> {
    /// The passes from light view `view` of `disc`: the D-buffer of `occluders` (`|cx_o|`) and
    /// of the umbra and penumbra volumes, then the eye lookup.
    fn new(
        gpu: &'g Run,
        frame: &Frame,
        (view, disc): (&LightView, Disc),
        occluders: &crate::scene::Mesh,
        [umbra, penumbra]: [&VolumeMesh; 2],
        o: &DbufferOptions,
    ) -> Passes<'g> {
        let (width, height) = (frame.width(), frame.height());
        let resolution = view.resolution;
        let uniform = DbufferUniform {
            view_proj: view.view_proj.to_cols_array(),
            eye: view.eye.to_array(),
            radius: disc.r,
            n_view: view.view.transform_vector3(disc.n).to_array(),
            near: view.near,
            disc_n: disc.n.to_array(),
            far: view.far,
            tan_half_fov: view.tan_half_fov,
            resolution,
            bias_constant: o.bias.constant,
            bias_slope: o.bias.slope,
            falloff: match o.falloff {
                Falloff::Smoothstep => 0,
                Falloff::Sqrt => 1,
            },
            width,
            height,
            pad: 0,
        };
        // A volume vertex: its position and the edge depth z_e.
        let volume = |label: &str, v: &VolumeMesh| {
            let z_e = v.attributes.iter().map(|a| a.x);
            Mesh::with_w(gpu, label, &v.positions, z_e, &v.triangles)
        };
        let meshes = [
            Mesh::of(gpu, "scene", occluders),
            volume("umbra volume", umbra),
            volume("penumbra volume", penumbra),
        ];
        let eye = EyeBuffers::new(gpu, &frame.gbuffer, |_| 0.0);
        let depth = ["scene", "umbra", "penumbra"]
            .map(|n| gpu.map_view(&format!("dbuffer {n} depth"), resolution, DEPTH));
        let edge = ["umbra", "penumbra"]
            .map(|n| gpu.map_view(&format!("dbuffer {n} edge"), resolution, EDGE));

        use wgpu::ShaderStages as S;
        let shared = Shared::new::<Counts>(gpu, "dbuffer shared", &uniform);
        let scene_depth = [(Depth, view_resource(&depth[0]))];
        let (scene_layout, scene_group) =
            Layout::bound(gpu, "dbuffer scene depth", S::FRAGMENT, &scene_depth);
        let (lookup_layout, lookup_group) = Layout::bound(
            gpu,
            "dbuffer eye lookup",
            S::COMPUTE,
            &eye.binds_after([
                (Depth, view_resource(&depth[0])),
                (Depth, view_resource(&depth[1])),
                (Float, view_resource(&edge[0])),
                (Depth, view_resource(&depth[2])),
                (Float, view_resource(&edge[1])),
            ]),
        );
        let program =
            |groups: &[Option<&Layout>]| Program::new(gpu, "dbuffer/wgpu.wgsl", &SOURCES, groups);
        let (shared_layout, compute) = (Some(&shared.layout), Some(&lookup_layout));
        let scene_program = program(&[shared_layout]);
        let volume_program = program(&[shared_layout, Some(&scene_layout)]);
        let compute_program = program(&[shared_layout, compute]);
        let scene = Raster::of_vertices("vs_scene", "fs_scene", &Mesh::POSITION);
        let volume_raster = |fs| Raster {
            color: Some(wgpu::ColorTargetState {
                format: EDGE,
                blend: None,
                write_mask: wgpu::ColorWrites::RED,
            }),
            ..Raster::of_vertices("vs_volume", fs, &Mesh::POSITION_W)
        };
        Passes {
            draws: [
                scene_program.render_instrumented(gpu, &scene),
                volume_program.render_instrumented(gpu, &volume_raster("fs_umbra")),
                volume_program.render_instrumented(gpu, &volume_raster("fs_penumbra")),
            ],
            lookup: Instrumented::timed(compute_program.compute(gpu, "eye_lookup", Some(false))),
            count_covered: Instrumented::counting(compute_program.compute(
                gpu,
                "count_covered",
                Some(true),
            )),
            gpu,
            width,
            height,
            resolution,
            meshes,
            depth,
            edge,
            visibility: eye.visibility,
            shared,
            scene_group,
            lookup_group,
        }
    }

    /// The three render passes of the D-buffer: the scene's depth, then each volume into its
    /// depth and edge targets.
    fn dbuffer_passes(&self) -> Vec<Pass<'_>> {
        (0..3)
            .map(|i| {
                let volume = i > 0;
                let groups = [
                    Some(&self.shared.group),
                    volume.then_some(&self.scene_group),
                ];
                let color = volume.then(|| &self.edge[i - 1]);
                let draw = self.meshes[i].draw(&self.draws[i], color, Some(&self.depth[i]));
                Pass::draw("dbuffer", &groups, draw)
            })
            .collect()
    }

    /// A compute pass over `size` with the lookup's groups.
    fn compute<'a>(&'a self, label: &'a str, pipeline: &'a Compute, size: (u32, u32)) -> Pass<'a> {
        let groups = [Some(&self.shared.group), Some(&self.lookup_group)];
        Pass::compute(label, &groups, pipeline, tiles(size, WORKGROUP))
    }

    fn run(&self, frame: &Frame) -> Result<FrameOutput> {
        let image = (self.width, self.height);
        // The instrumented replay: the D-buffer's passes counting with atomics, then the
        // covered texels.
        let mut run = Timed::new(
            self.gpu,
            &[Phase::Dbuffer, Phase::EyeLookup],
            Statistics::All,
            &[&self.visibility],
        )
        .counting_into(&self.shared.counts, Readout::End);
        let mut passes = self.dbuffer_passes();
        let res = (self.resolution, self.resolution);
        passes.push(self.compute("count_covered", &self.count_covered, res));
        run.submit(Phase::Dbuffer, &passes)?;
        run.submit(
            Phase::EyeLookup,
            &[self.compute("eye_lookup", &self.lookup, image)],
        )?;
        let timing = run.finish()?;
        let c: Counts = first(&timing.counts[0]);

        let mut dbuffer = Counters::default();
        let fill = f64::from(c.umbra_fragments) + f64::from(c.penumbra_fragments);
        let covered = f64::from(c.umbra_covered) + f64::from(c.penumbra_covered);
        dbuffer.add_fill(fill, fill - covered);
        dbuffer.set(names::DBUFFER_SCENE_FILL, f64::from(c.scene_fragments));
        dbuffer.set(
            names::DBUFFER_BYTES,
            super::dbuffer_bytes(&frame.params) as f64,
        );
        let note = "fill/overdraw from an instrumented replay (WGSL atomics); phases silhouettes \
                    and volumes ran on the host";
        Ok(timing.output(image, vec![(Phase::Dbuffer, dbuffer)], note))
    }
}

#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(SOURCES => DbufferUniform, Counts);
