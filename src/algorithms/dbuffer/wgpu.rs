//! `dbuffer` as GPU passes. As in the paper's implementation (§5, §6.1: "the volumes are
//! generated on the CPU"), phases `silhouettes` and `volumes` run on the host (the cpu-native
//! kernels, wall time only: on the host's threads, or on one thread with `volume_build:
//! single_core`, the paper's single CPU); then:
//!
//! 1. `dbuffer` — three render passes from the light centre into `map_resolution`² targets:
//!    the scene's depth (Depth32Float, `|cx_o|`); the umbra volume (its own Depth32Float for
//!    `|cx_uv|` and an R32Float colour target for the edge depth behind `|cx_s|`), whose
//!    fragment shader reads the scene's depth and discards fragments in front of it; the
//!    penumbra volume (Depth32Float and R32Float likewise). The D-buffer is thus five
//!    single-channel textures rather than one RGBA target: each volume needs its own depth
//!    test (nearest surface, [`super::DEPTH_RULE`]) and the edge depth must come from the same
//!    fragment that wins it, which blending per channel cannot guarantee.
//! 2. `eye_lookup` — a compute pass over the shared gbuffer: eq. 2, 3 and 4 (`wgpu.wgsl`).
//!
//! The timed submission runs the passes with timestamps and pipeline statistics; a second,
//! instrumented submission counts the volume fragments (`fill`) and the D-buffer texels they
//! left covered (`fill − covered = overdraw`) with WGSL atomics, as the shadow-map family does.

use super::cpu::{build_volumes, VolumeMesh};
use super::{DbufferOptions, Disc, Falloff};
use crate::algorithms::exec::machine;
use crate::algorithms::shadow_map::wgpu::LIGHT_VIEW_WGSL;
use crate::algorithms::shadow_map::{LightView, LightViews, ViewFit};
use crate::algorithms::{Backend, ExecContext, FrameOutput};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, replay, tiles, view as view_resource, Bind::*, Draw, Layout, Pass, Program, Raster,
    Statistics, Step, Timed,
};
use crate::gpu::readback::words;
use crate::gpu::{gbuffer_positions, Gpu};
use crate::record::Counters;
use crate::scene::adjacency::EdgeAdjacency;

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
    gpu: &Gpu,
    frame: &Frame,
    ctx: &ExecContext,
    o: &DbufferOptions,
) -> Result<FrameOutput> {
    let res = frame.params.map_resolution;
    if res > gpu.limits.max_texture_dimension_2d {
        return Err(Error::Resource(format!(
            "map_resolution {res} exceeds the adapter's largest texture ({})",
            gpu.limits.max_texture_dimension_2d
        )));
    }
    // The host phases, as the cpu-native execution runs them: their wall time on the host's
    // threads, or on one host thread with `volume_build: single_core`.
    let mut m = machine(Backend::CpuNative, frame, ctx);
    let disc = Disc::of(&frame.scene.light, frame.scene.bounds().center());
    let adj = EdgeAdjacency::build(&frame.scene.occluders());
    let views = LightViews::fit(frame, &frame.scene.light, res, ViewFit::Single);
    let view = *views.single();
    let v = build_volumes(&mut m, frame, &adj, disc, &view, o);
    let host = m.finish();
    let mut out = Passes::new(gpu, frame, &view, disc, &v.umbra, &v.penumbra, o).run(frame)?;
    out.execution.insert(
        "volume_build".into(),
        serde_json::json!(o.volume_build.describe()),
    );
    let mut phases = host.phases;
    phases.append(&mut out.phases);
    for p in &phases[..2] {
        out.counters.merge(&p.counters);
    }
    out.phases = phases;
    views.record(&mut out);
    Ok(out)
}

/// A map of the D-buffer, drawn into and read by the lookup.
fn target(gpu: &Gpu, label: &str, res: u32, format: wgpu::TextureFormat) -> wgpu::TextureView {
    gpu.map_texture(label, res, format, wgpu::TextureUsages::empty())
        .create_view(&Default::default())
}

/// A mesh drawn into the D-buffer: its vertex buffer, index buffer and index count.
struct Mesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
}

/// The pipelines of the scene, umbra, penumbra and lookup passes, timed or counting.
struct Pipelines {
    scene: wgpu::RenderPipeline,
    umbra: wgpu::RenderPipeline,
    penumbra: wgpu::RenderPipeline,
    lookup: wgpu::ComputePipeline,
}

impl Pipelines {
    /// The timed and counting pipelines of every pass, and the replay's `count_covered`, from
    /// the shared, scene-depth and lookup group layouts.
    fn new(
        gpu: &Gpu,
        [shared, scene, lookup]: [&Layout; 3],
    ) -> ([Pipelines; 2], wgpu::ComputePipeline) {
        let program =
            |groups: &[Option<&Layout>]| Program::new(gpu, "dbuffer/wgpu.wgsl", &SOURCES, groups);
        let scene_program = program(&[Some(shared)]);
        let volume_program = program(&[Some(shared), Some(scene)]);
        let compute_program = program(&[Some(shared), Some(lookup)]);
        let scene_attrs = wgpu::vertex_attr_array![0 => Float32x3];
        let volume_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32];
        let vertex = wgpu::VertexStepMode::Vertex;
        let pipelines = [false, true].map(|instrument| {
            let scene = Raster {
                vs: "vs_scene",
                fs: "fs_scene",
                vertex: Some((12, vertex, &scene_attrs)),
                instrument: Some(instrument),
                ..Raster::default()
            };
            let volume = |fs| Raster {
                vs: "vs_volume",
                fs,
                vertex: Some((16, vertex, &volume_attrs)),
                color: Some(wgpu::ColorTargetState {
                    format: EDGE,
                    blend: None,
                    write_mask: wgpu::ColorWrites::RED,
                }),
                ..scene.clone()
            };
            Pipelines {
                scene: scene_program.render(gpu, &scene),
                umbra: volume_program.render(gpu, &volume("fs_umbra")),
                penumbra: volume_program.render(gpu, &volume("fs_penumbra")),
                lookup: compute_program.compute(gpu, "eye_lookup", Some(instrument)),
            }
        });
        let count_covered = compute_program.compute(gpu, "count_covered", Some(true));
        (pipelines, count_covered)
    }
}

struct Passes<'g> {
    gpu: &'g Gpu,
    width: u32,
    height: u32,
    resolution: u32,
    /// Scene, umbra volume, penumbra volume.
    meshes: [Mesh; 3],
    /// Depth targets (scene, umbra, penumbra) and edge targets (umbra, penumbra).
    depth: [wgpu::TextureView; 3],
    edge: [wgpu::TextureView; 2],
    visibility: wgpu::Buffer,
    counts: wgpu::Buffer,
    shared_group: wgpu::BindGroup,
    scene_group: wgpu::BindGroup,
    lookup_group: wgpu::BindGroup,
    /// Timed and counting pipelines.
    pipelines: [Pipelines; 2],
    count_covered: wgpu::ComputePipeline,
}

impl<'g> Passes<'g> {
    fn new(
        gpu: &'g Gpu,
        frame: &Frame,
        view: &LightView,
        disc: Disc,
        umbra: &VolumeMesh,
        penumbra: &VolumeMesh,
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
        use wgpu::BufferUsages as B;
        let uniform_buf = gpu.upload("dbuffer uniform", &[uniform], B::UNIFORM);
        let mesh = |label: &str, vertices: Vec<f32>, tris: &[[u32; 3]]| {
            let indices: Vec<u32> = tris.iter().flatten().copied().collect();
            Mesh {
                vertices: gpu.upload(label, &vertices, B::VERTEX),
                indices: gpu.upload(label, &indices, B::INDEX),
                count: indices.len() as u32,
            }
        };
        let volume = |label: &str, v: &VolumeMesh| {
            let data: Vec<f32> = v
                .positions
                .iter()
                .zip(&v.attributes)
                .flat_map(|(p, a)| [p.x, p.y, p.z, a.x])
                .collect();
            mesh(label, data, &v.triangles)
        };
        let flat = &frame.flat.mesh;
        let positions = flat.positions.iter().flat_map(|p| p.to_array()).collect();
        let meshes = [
            mesh("scene", positions, &flat.triangles),
            volume("umbra volume", umbra),
            volume("penumbra volume", penumbra),
        ];
        let g = &frame.gbuffer;
        let gnrm: Vec<[f32; 4]> = g.normal.iter().map(|n| n.extend(0.0).to_array()).collect();
        let gpos = gpu.upload("gbuffer positions", &gbuffer_positions(g), B::STORAGE);
        let gnrm = gpu.upload("gbuffer normals", &gnrm, B::STORAGE);
        let visibility = gpu.storage_buffer(
            "visibility",
            4 * u64::from(width) * u64::from(height),
            B::COPY_SRC,
        );
        let counts = gpu.upload(
            "instrumentation counts",
            &[Counts::default()],
            B::STORAGE | B::COPY_SRC | B::COPY_DST,
        );
        let depth = ["scene", "umbra", "penumbra"]
            .map(|n| target(gpu, &format!("dbuffer {n} depth"), resolution, DEPTH));
        let edge = ["umbra", "penumbra"]
            .map(|n| target(gpu, &format!("dbuffer {n} edge"), resolution, EDGE));

        use wgpu::ShaderStages as S;
        let all = S::VERTEX | S::FRAGMENT | S::COMPUTE;
        let shared_layout = Layout::new(gpu, "dbuffer shared", all, &[Uniform, ReadWrite]);
        let scene_layout = Layout::new(gpu, "dbuffer scene depth", S::FRAGMENT, &[Depth]);
        let lookup_layout = Layout::new(
            gpu,
            "dbuffer eye lookup",
            S::COMPUTE,
            &[
                Depth, Depth, Float, Depth, Float, ReadOnly, ReadOnly, ReadWrite,
            ],
        );
        let shared_group = shared_layout.group(
            gpu,
            "dbuffer shared",
            &[uniform_buf.as_entire_binding(), counts.as_entire_binding()],
        );
        let scene_group =
            scene_layout.group(gpu, "dbuffer scene depth", &[view_resource(&depth[0])]);
        let lookup_group = lookup_layout.group(
            gpu,
            "dbuffer eye lookup",
            &[
                view_resource(&depth[0]),
                view_resource(&depth[1]),
                view_resource(&edge[0]),
                view_resource(&depth[2]),
                view_resource(&edge[1]),
                gpos.as_entire_binding(),
                gnrm.as_entire_binding(),
                visibility.as_entire_binding(),
            ],
        );
        let (pipelines, count_covered) =
            Pipelines::new(gpu, [&shared_layout, &scene_layout, &lookup_layout]);
        Passes {
            gpu,
            width,
            height,
            resolution,
            meshes,
            depth,
            edge,
            visibility,
            counts,
            shared_group,
            scene_group,
            lookup_group,
            pipelines,
            count_covered,
        }
    }

    /// The three render passes of the D-buffer: the scene's depth, then each volume into its
    /// depth and edge targets.
    fn dbuffer_passes(&self, counting: bool) -> Vec<Pass<'_>> {
        let p = &self.pipelines[usize::from(counting)];
        let pipelines = [&p.scene, &p.umbra, &p.penumbra];
        (0..3)
            .map(|i| {
                let mesh = &self.meshes[i];
                let volume = i > 0;
                Pass::draw(
                    "dbuffer",
                    &[
                        Some(&self.shared_group),
                        volume.then_some(&self.scene_group),
                    ],
                    Draw {
                        pipeline: pipelines[i],
                        color: volume.then(|| &self.edge[i - 1]),
                        depth: Some(&self.depth[i]),
                        vertices: Some(&mesh.vertices),
                        indices: Some(&mesh.indices),
                        count: mesh.count,
                        instances: 1,
                    },
                )
            })
            .collect()
    }

    /// A compute pass over `size` with the lookup's groups.
    fn compute<'a>(&'a self, pipeline: &'a wgpu::ComputePipeline, size: (u32, u32)) -> Pass<'a> {
        let groups = [Some(&self.shared_group), Some(&self.lookup_group)];
        Pass::compute("eye_lookup", &groups, pipeline, tiles(size, WORKGROUP))
    }

    fn run(&self, frame: &Frame) -> Result<FrameOutput> {
        let image = (self.width, self.height);
        let names = ["dbuffer", "eye_lookup"];
        let mut run = Timed::new(self.gpu, &names, 4, Statistics::All, &[&self.visibility]);
        run.submit(0, &self.dbuffer_passes(false))?;
        run.submit(1, &[self.compute(&self.pipelines[0].lookup, image)])?;
        let timing = run.finish()?;

        // The instrumented submission: same passes, counting with atomics.
        let mut steps = vec![Step::Clear(&self.counts)];
        steps.extend(self.dbuffer_passes(true).into_iter().map(Step::Run));
        let res = (self.resolution, self.resolution);
        steps.push(Step::Run(self.compute(&self.count_covered, res)));
        steps.push(Step::Read(&self.counts));
        let c: Counts = words::<Counts>(&replay(self.gpu, &steps)?[0])[0];

        let mut dbuffer = Counters::default();
        let fill = f64::from(c.umbra_fragments) + f64::from(c.penumbra_fragments);
        dbuffer.set("fill", fill);
        dbuffer.set(
            "overdraw",
            fill - f64::from(c.umbra_covered) - f64::from(c.penumbra_covered),
        );
        dbuffer.set("dbuffer.scene_fill", f64::from(c.scene_fragments));
        dbuffer.set("dbuffer.bytes", super::dbuffer_bytes(&frame.params) as f64);
        let note = "fill/overdraw from an instrumented replay (WGSL atomics); phases silhouettes \
                    and volumes ran on the host";
        Ok(timing.output(image, vec![dbuffer, Counters::default()], note))
    }
}

#[cfg(test)]
mod layout_tests {
    use super::*;

    #[test]
    fn uniforms_match_wgsl() {
        let source = SOURCES.join("\n");
        assert_eq!(
            DbufferUniform::layout_mismatches(&source),
            Vec::<String>::new()
        );
        assert_eq!(Counts::layout_mismatches(&source), Vec::<String>::new());
    }
}
