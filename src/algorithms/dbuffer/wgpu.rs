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

use std::time::Instant;

use bytemuck::{Pod, Zeroable};

use super::cpu::{build_volumes, VolumeMesh};
use super::{DbufferOptions, Disc, Falloff};
use crate::algorithms::exec::machine;
use crate::algorithms::shadow_map::{LightView, LightViews, ViewFit};
use crate::algorithms::{Backend, ExecContext, FrameOutput};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::layout;
use crate::gpu::readback::{words, Staging};
use crate::gpu::stats::{read_or_warn, PassStats};
use crate::gpu::timing::{self, read_ms_or_warn, PassTimer};
use crate::gpu::{gbuffer_positions, resolve_queries, Gpu};
use crate::record::{Counters, Phase};
use crate::scene::adjacency::EdgeAdjacency;
use crate::visibility::VisibilityBuffer;

const WGSL: &str = include_str!("wgpu.wgsl");
/// Side of the square compute workgroups (`@workgroup_size(8, 8)`).
const WORKGROUP: u32 = 8;
/// GPU passes of the timed submission: scene depth, umbra volume, penumbra volume, eye lookup.
const PASSES: u32 = 4;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const EDGE: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;

/// The `Light` uniform of `wgpu.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct DbufferUniform {
    view_proj: [f32; 16],
    eye: [f32; 3],
    radius: f32,
    n_view: [f32; 3],
    near: f32,
    disc_n: [f32; 3],
    far: f32,
    tan_half_fov: f32,
    resolution: u32,
    bias_constant: f32,
    bias_slope: f32,
    falloff: u32,
    width: u32,
    height: u32,
    pad: u32,
}

/// The `Counts` storage buffer of the instrumented mode.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Counts {
    scene_fragments: u32,
    umbra_fragments: u32,
    penumbra_fragments: u32,
    umbra_covered: u32,
    penumbra_covered: u32,
    pad: u32,
}

/// `dbuffer` on wgpu.
pub fn render(
    gpu: &Gpu,
    frame: &Frame,
    ctx: &ExecContext,
    o: &DbufferOptions,
) -> Result<FrameOutput> {
    let o = *o;
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
    let v = build_volumes(&mut m, frame, &adj, disc, &view, &o);
    let host = m.finish();
    let mut out = Passes::new(gpu, frame, &view, disc, &v.umbra, &v.penumbra, &o).run(frame)?;
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

struct Target {
    view: wgpu::TextureView,
}

fn texture(gpu: &Gpu, label: &str, res: u32, format: wgpu::TextureFormat) -> Target {
    let t = gpu.map_texture(label, res, format, wgpu::TextureUsages::empty());
    Target {
        view: t.create_view(&Default::default()),
    }
}

fn texture_entry(
    binding: u32,
    stage: wgpu::ShaderStages,
    depth: bool,
) -> wgpu::BindGroupLayoutEntry {
    let sample_type = if depth {
        wgpu::TextureSampleType::Depth
    } else {
        wgpu::TextureSampleType::Float { filterable: false }
    };
    layout::texture(binding, stage, sample_type)
}

fn tex(binding: u32, t: &Target) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::TextureView(&t.view),
    }
}

/// A volume's vertex buffer (position and edge depth) and index buffer.
struct Mesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
}

struct Pipelines {
    scene: wgpu::RenderPipeline,
    umbra: wgpu::RenderPipeline,
    penumbra: wgpu::RenderPipeline,
    lookup: wgpu::ComputePipeline,
}

struct Passes<'g> {
    gpu: &'g Gpu,
    width: u32,
    height: u32,
    resolution: u32,
    scene_mesh: Mesh,
    umbra_mesh: Mesh,
    penumbra_mesh: Mesh,
    scene_depth: Target,
    umbra_depth: Target,
    umbra_edge: Target,
    penumbra_depth: Target,
    penumbra_edge: Target,
    visibility: wgpu::Buffer,
    counts: wgpu::Buffer,
    shared_group: wgpu::BindGroup,
    scene_group: wgpu::BindGroup,
    lookup_group: wgpu::BindGroup,
    timed: Pipelines,
    counting: Pipelines,
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
        let device = &gpu.device;
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
        let init =
            |label: &str, contents: &[u8], usage| gpu.buffer_init(label, contents, 16, usage);
        let uniform_buf = init(
            "dbuffer uniform",
            bytemuck::bytes_of(&uniform),
            wgpu::BufferUsages::UNIFORM,
        );
        let mesh = |label: &str, vertices: Vec<f32>, tris: &[[u32; 3]]| {
            let indices: Vec<u32> = tris.iter().flatten().copied().collect();
            Mesh {
                vertices: init(
                    label,
                    bytemuck::cast_slice(&vertices),
                    wgpu::BufferUsages::VERTEX,
                ),
                indices: init(
                    label,
                    bytemuck::cast_slice(&indices),
                    wgpu::BufferUsages::INDEX,
                ),
                count: indices.len() as u32,
            }
        };
        let flat = &frame.flat.mesh;
        let scene_mesh = mesh(
            "scene",
            flat.positions.iter().flat_map(|p| p.to_array()).collect(),
            &flat.triangles,
        );
        let volume = |label: &str, v: &VolumeMesh| {
            let data: Vec<f32> = v
                .positions
                .iter()
                .zip(&v.attributes)
                .flat_map(|(p, a)| [p.x, p.y, p.z, a.x])
                .collect();
            mesh(label, data, &v.triangles)
        };
        let umbra_mesh = volume("umbra volume", umbra);
        let penumbra_mesh = volume("penumbra volume", penumbra);

        let g = &frame.gbuffer;
        let gpos = gbuffer_positions(g);
        let gnrm: Vec<[f32; 4]> = g.normal.iter().map(|n| n.extend(0.0).to_array()).collect();
        let positions_buf = init(
            "gbuffer positions",
            bytemuck::cast_slice(&gpos),
            wgpu::BufferUsages::STORAGE,
        );
        let normals_buf = init(
            "gbuffer normals",
            bytemuck::cast_slice(&gnrm),
            wgpu::BufferUsages::STORAGE,
        );
        let visibility = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("visibility"),
            size: 4 * u64::from(width) * u64::from(height),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let counts = init(
            "instrumentation counts",
            bytemuck::bytes_of(&Counts::default()),
            wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        );
        let scene_depth = texture(gpu, "dbuffer scene depth", resolution, DEPTH);
        let umbra_depth = texture(gpu, "dbuffer umbra depth", resolution, DEPTH);
        let umbra_edge = texture(gpu, "dbuffer umbra edge", resolution, EDGE);
        let penumbra_depth = texture(gpu, "dbuffer penumbra depth", resolution, DEPTH);
        let penumbra_edge = texture(gpu, "dbuffer penumbra edge", resolution, EDGE);

        let all =
            wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE;
        let shared_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dbuffer shared"),
            entries: &[
                layout::uniform(0, all),
                layout::storage(
                    1,
                    wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE,
                    false,
                ),
            ],
        });
        let scene_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dbuffer scene depth"),
            entries: &[texture_entry(0, wgpu::ShaderStages::FRAGMENT, true)],
        });
        let cs = wgpu::ShaderStages::COMPUTE;
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dbuffer eye lookup"),
            entries: &[
                texture_entry(0, cs, true),
                texture_entry(1, cs, true),
                texture_entry(2, cs, false),
                texture_entry(3, cs, true),
                texture_entry(4, cs, false),
                layout::storage(5, cs, true),
                layout::storage(6, cs, true),
                layout::storage(7, cs, false),
            ],
        });
        let shared_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dbuffer shared"),
            layout: &shared_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: counts.as_entire_binding(),
                },
            ],
        });
        let scene_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dbuffer scene depth"),
            layout: &scene_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&scene_depth.view),
            }],
        });
        let lookup_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("dbuffer eye lookup"),
            layout: &lookup_layout,
            entries: &[
                tex(0, &scene_depth),
                tex(1, &umbra_depth),
                tex(2, &umbra_edge),
                tex(3, &penumbra_depth),
                tex(4, &penumbra_edge),
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: positions_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: normals_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 7,
                    resource: visibility.as_entire_binding(),
                },
            ],
        });

        let scene_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("dbuffer scene"),
            bind_group_layouts: &[Some(&shared_layout)],
            immediate_size: 0,
        });
        let volume_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("dbuffer volumes"),
            bind_group_layouts: &[Some(&shared_layout), Some(&scene_layout)],
            immediate_size: 0,
        });
        let compute_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("dbuffer eye lookup"),
            bind_group_layouts: &[Some(&shared_layout), Some(&lookup_layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("dbuffer/wgpu.wgsl"),
            source: wgpu::ShaderSource::Wgsl(WGSL.into()),
        });
        let scene_attrs = wgpu::vertex_attr_array![0 => Float32x3];
        let volume_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32];
        let edge_target = [Some(wgpu::ColorTargetState {
            format: EDGE,
            blend: None,
            write_mask: wgpu::ColorWrites::RED,
        })];
        let render = |fs: &str, volume: bool, instrument: bool| {
            let constants = [("INSTRUMENT", f64::from(u8::from(instrument)))];
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(fs),
                layout: Some(if volume { &volume_pl } else { &scene_pl }),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(if volume { "vs_volume" } else { "vs_scene" }),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: if volume { 16 } else { 12 },
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: if volume { &volume_attrs } else { &scene_attrs },
                    })],
                },
                primitive: wgpu::PrimitiveState {
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    targets: if volume { &edge_target } else { &[] },
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let compute = |entry: &str, instrument: bool| {
            gpu.instrumented_compute_pipeline(&compute_pl, &module, entry, instrument)
        };
        let pipelines = |instrument: bool| Pipelines {
            scene: render("fs_scene", false, instrument),
            umbra: render("fs_umbra", true, instrument),
            penumbra: render("fs_penumbra", true, instrument),
            lookup: compute("eye_lookup", instrument),
        };
        Passes {
            gpu,
            width,
            height,
            resolution,
            scene_mesh,
            umbra_mesh,
            penumbra_mesh,
            scene_depth,
            umbra_depth,
            umbra_edge,
            penumbra_depth,
            penumbra_edge,
            visibility,
            counts,
            shared_group,
            scene_group,
            lookup_group,
            timed: pipelines(false),
            counting: pipelines(true),
            count_covered: compute("count_covered", true),
        }
    }

    /// One render pass of the D-buffer: `mesh` into `depth` (and `edge`), pass `i`.
    #[allow(clippy::too_many_arguments)]
    fn draw(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::RenderPipeline,
        mesh: &Mesh,
        depth: &Target,
        edge: Option<&Target>,
        i: u32,
        timer: Option<&PassTimer>,
        stats: Option<&PassStats>,
    ) {
        let color = edge.map(|t| wgpu::RenderPassColorAttachment {
            view: &t.view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                store: wgpu::StoreOp::Store,
            },
        });
        let colors = [color];
        let mut pass = timing::render_pass(
            encoder,
            wgpu::RenderPassDescriptor {
                label: Some("dbuffer"),
                color_attachments: if edge.is_some() { &colors } else { &[] },
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth.view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            },
            timer.map(|t| (t, i)),
        );
        if let Some(s) = stats {
            s.begin_render(&mut pass, i);
        }
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.shared_group, &[]);
        if edge.is_some() {
            pass.set_bind_group(1, &self.scene_group, &[]);
        }
        pass.set_vertex_buffer(0, mesh.vertices.slice(..));
        pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..mesh.count, 0, 0..1);
        if stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    fn dbuffer_passes(
        &self,
        e: &mut wgpu::CommandEncoder,
        p: &Pipelines,
        timer: Option<&PassTimer>,
        stats: Option<&PassStats>,
    ) {
        self.draw(
            e,
            &p.scene,
            &self.scene_mesh,
            &self.scene_depth,
            None,
            0,
            timer,
            stats,
        );
        self.draw(
            e,
            &p.umbra,
            &self.umbra_mesh,
            &self.umbra_depth,
            Some(&self.umbra_edge),
            1,
            timer,
            stats,
        );
        self.draw(
            e,
            &p.penumbra,
            &self.penumbra_mesh,
            &self.penumbra_depth,
            Some(&self.penumbra_edge),
            2,
            timer,
            stats,
        );
    }

    fn compute_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        size: (u32, u32),
        timer: Option<&PassTimer>,
        stats: Option<&PassStats>,
    ) {
        let mut pass = timing::compute_pass(encoder, "eye_lookup", timer.map(|t| (t, 3)));
        if let Some(s) = stats {
            s.begin_compute(&mut pass, 3);
        }
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.shared_group, &[]);
        pass.set_bind_group(1, &self.lookup_group, &[]);
        pass.dispatch_workgroups(size.0.div_ceil(WORKGROUP), size.1.div_ceil(WORKGROUP), 1);
        if stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    fn run(&self, frame: &Frame) -> Result<FrameOutput> {
        let gpu = self.gpu;
        let image = (self.width, self.height);
        let mut warnings = Vec::new();
        let timer = PassTimer::new(gpu, PASSES);
        let stats = PassStats::new(gpu, PASSES);
        let dbuffer_wall = self
            .gpu
            .submit(|e| self.dbuffer_passes(e, &self.timed, timer.as_ref(), stats.as_ref()))?;
        let vis_staging = Staging::new(gpu, "visibility readback", self.visibility.size());
        let lookup_wall = self.gpu.submit(|e| {
            self.compute_pass(e, &self.timed.lookup, image, timer.as_ref(), stats.as_ref());
            vis_staging.copy(e, &self.visibility);
            resolve_queries(e, timer.as_ref(), stats.as_ref());
        })?;
        let readback_start = Instant::now();
        let data: Vec<f32> = words(&vis_staging.read(gpu)?);
        let readback_ms = readback_start.elapsed().as_secs_f64() * 1e3;
        let times = read_ms_or_warn(gpu, &timer, &mut warnings)?;
        let gpu_ms = times.ms.clone();
        let pipeline = read_or_warn(gpu, &stats, &mut warnings)?;

        // The instrumented submission: same passes, counting with atomics.
        let counts_staging = Staging::new(gpu, "counts readback", self.counts.size());
        self.gpu.submit(|e| {
            e.clear_buffer(&self.counts, 0, None);
            self.dbuffer_passes(e, &self.counting, None, None);
            let res = (self.resolution, self.resolution);
            self.compute_pass(e, &self.count_covered, res, None, None);
            counts_staging.copy(e, &self.counts);
        })?;
        let c: Counts = words::<Counts>(&counts_staging.read(gpu)?)[0];

        let mut dbuffer = Counters::default();
        let fill = f64::from(c.umbra_fragments) + f64::from(c.penumbra_fragments);
        dbuffer.set("fill", fill);
        dbuffer.set(
            "overdraw",
            fill - f64::from(c.umbra_covered) - f64::from(c.penumbra_covered),
        );
        dbuffer.set("dbuffer.scene_fill", f64::from(c.scene_fragments));
        dbuffer.set("dbuffer.bytes", super::dbuffer_bytes(&frame.params) as f64);
        let mut eye = Counters::default();
        if let Some(p) = &pipeline {
            for s in &p[..3] {
                dbuffer.merge(s);
            }
            eye.merge(&p[3]);
        }
        let phase = |name: &str, wall_ms: f64, gpu_ms: Option<f64>, counters: Counters| Phase {
            name: name.into(),
            wall_ms,
            model_ms: None,
            gpu_ms,
            counters,
        };
        let phases = vec![
            phase(
                "dbuffer",
                dbuffer_wall,
                gpu_ms.as_ref().map(|t| t[..3].iter().sum()),
                dbuffer,
            ),
            phase(
                "eye_lookup",
                lookup_wall,
                gpu_ms.as_ref().map(|t| t[3]),
                eye,
            ),
        ];
        let mut counters = Counters::default();
        for p in &phases {
            counters.merge(&p.counters);
        }
        let mut execution = gpu.execution();
        times.record(&mut execution);
        execution.insert("readback_ms".into(), serde_json::json!(readback_ms));
        execution.insert(
            "gpu_counters".into(),
            serde_json::json!(
                "fill/overdraw from an instrumented replay (WGSL atomics); phases silhouettes \
                 and volumes ran on the host"
            ),
        );
        Ok(FrameOutput {
            visibility: VisibilityBuffer {
                width: self.width,
                height: self.height,
                data,
            },
            counters,
            phases,
            model_ms: None,
            gpu_ms: gpu_ms.map(|t| t.iter().sum()),
            execution,
            warnings,
            rgb: None,
        })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::*;
    use crate::gpu::wgsl_layout::assert_wgsl_layout;

    #[test]
    fn uniforms_match_wgsl() {
        assert_wgsl_layout!(
            WGSL,
            "Light",
            DbufferUniform {
                view_proj,
                eye,
                radius,
                n_view,
                near,
                disc_n,
                far,
                tan_half_fov,
                resolution,
                bias_constant,
                bias_slope,
                falloff,
                width,
                height,
                pad
            }
        );
        assert_wgsl_layout!(
            WGSL,
            "Counts",
            Counts {
                scene_fragments,
                umbra_fragments,
                penumbra_fragments,
                umbra_covered,
                penumbra_covered,
                pad
            }
        );
    }
}
