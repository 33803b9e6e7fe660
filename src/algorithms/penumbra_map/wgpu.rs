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
//! As in the family, a timed submission (timestamps and pipeline statistics per GPU pass) is
//! followed by an instrumented replay whose atomics count the cone and sheet fragments (`fill`)
//! and those discarded behind the shadow-map surface (`overdraw`, as on the cpu executions),
//! and the penumbra-map taps of the lookup. The geometry upload is part of the
//! `penumbra_map` phase's wall time. The edge adjacency of the occluders is per-model
//! preprocessing, built before the first phase, as is the optional simplified mesh.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::{
    shadow_geometry, silhouettes, PenumbraGeometry, PenumbraMapOptions, ShadowGeometry, Silhouettes,
};
use crate::algorithms::shadow_map::wgpu::{
    self as shadow_map_wgpu, gpu_phase, read_queries, Counts, Lookup, Passes, Queries,
    DEPTH_TEXEL_BYTES,
};
use crate::algorithms::shadow_map::{FaceView, LightView, LightViews, ViewFit};
use crate::algorithms::ExecContext;
use crate::algorithms::FrameOutput;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::layout;
use crate::gpu::readback::{words, Staging};
use crate::gpu::stats::PassStats;
use crate::gpu::timing::{self, PassTimer};
use crate::gpu::{resolve_queries, Gpu};
use crate::record::Counters;
use crate::scene::adjacency::EdgeAdjacency;

const PENUMBRA_WGSL: &str = include_str!("wgpu.wgsl");
const LIGHT_RASTER_WGSL: &str = include_str!("../shadow_map/light_raster.wgsl");

/// Bytes of one penumbra vertex: light-view position and `Z_v`.
const VERTEX_BYTES: f64 = 16.0;
const INDEX_BYTES: f64 = 4.0;

/// `penumbra_map` on wgpu.
pub fn render(
    gpu: &Gpu,
    frame: &Frame,
    _: &ExecContext,
    o: &PenumbraMapOptions,
) -> Result<FrameOutput> {
    shadow_map_wgpu::check_limits(gpu, frame)?;
    let geometry = shadow_geometry(frame, o);
    let views = LightViews::fit(
        frame,
        &frame.scene.light,
        frame.params.map_resolution,
        ViewFit::Single,
    );
    let mut out =
        PenumbraPasses::new(gpu, frame, o, &geometry, &views.views[0]).run(frame, &geometry, o)?;
    views.record(&mut out);
    Ok(out)
}

/// The penumbra pass's uniform: the light view's projection.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct PenumbraView {
    proj: [f32; 16],
}

/// The cones and sheets on the GPU.
struct Cones {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    vertex_count: u32,
    index_count: u32,
}

struct PenumbraPasses<'g> {
    passes: Passes<'g>,
    view: LightView,
    penumbra_view: wgpu::TextureView,
    penumbra_group: wgpu::BindGroup,
    lookup_group: wgpu::BindGroup,
    timed: wgpu::RenderPipeline,
    counting: wgpu::RenderPipeline,
}

impl<'g> PenumbraPasses<'g> {
    fn new(
        gpu: &'g Gpu,
        frame: &Frame,
        o: &PenumbraMapOptions,
        geometry: &ShadowGeometry,
        face: &FaceView,
    ) -> PenumbraPasses<'g> {
        let device = &gpu.device;
        let resolution = frame.params.map_resolution;
        let view = face.view;

        // Group 2 of the eye lookup: the penumbra map.
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("penumbra lookup"),
            entries: &[layout::texture(
                0,
                wgpu::ShaderStages::COMPUTE,
                wgpu::TextureSampleType::Depth,
            )],
        });
        let lookup = Lookup {
            wgsl: include_str!("wgpu_lookup.wgsl"),
            bias: o.bias,
            blocker_samples: 0,
            pcf_samples: 0,
        };
        let passes = Passes::new(
            gpu,
            frame,
            &lookup,
            face,
            &view.casters(&geometry.shadow_map),
            Some(&lookup_layout),
        );

        let penumbra = gpu.map_texture(
            "penumbra map",
            resolution,
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::empty(),
        );
        let penumbra_view = penumbra.create_view(&Default::default());
        let lookup_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("penumbra lookup"),
            layout: &lookup_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&penumbra_view),
            }],
        });

        // Group 1 of the penumbra pass: the projection and the shadow map.
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("penumbra view"),
            contents: bytemuck::bytes_of(&PenumbraView {
                proj: view.proj.to_cols_array(),
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let penumbra_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("penumbra pass"),
            entries: &[
                layout::uniform(0, wgpu::ShaderStages::VERTEX),
                layout::texture(
                    1,
                    wgpu::ShaderStages::FRAGMENT,
                    wgpu::TextureSampleType::Depth,
                ),
            ],
        });
        let penumbra_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("penumbra pass"),
            layout: &penumbra_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&passes.depth_view),
                },
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("penumbra pass"),
            bind_group_layouts: &[Some(&passes.shared_layout), Some(&penumbra_layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("penumbra_map/wgpu.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                format!("{LIGHT_RASTER_WGSL}\n{PENUMBRA_WGSL}").into(),
            ),
        });
        let pipeline = |instrument: bool| {
            let constants = [("INSTRUMENT", f64::from(u8::from(instrument)))];
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(if instrument {
                    "penumbra (instrumented)"
                } else {
                    "penumbra"
                }),
                layout: Some(&layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_penumbra"),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: VERTEX_BYTES as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32],
                    })],
                },
                // Cones and sheets are seen from both sides.
                primitive: wgpu::PrimitiveState {
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_penumbra"),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    targets: &[],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        PenumbraPasses {
            timed: pipeline(false),
            counting: pipeline(true),
            passes,
            view,
            penumbra_view,
            penumbra_group,
            lookup_group,
        }
    }

    /// Uploads the cones and sheets.
    fn upload(&self, g: &PenumbraGeometry) -> Cones {
        let vertices: Vec<[f32; 4]> = g
            .positions
            .iter()
            .zip(&g.attributes)
            .map(|(p, a)| p.extend(a.x).to_array())
            .collect();
        let indices: Vec<u32> = g.triangles.iter().flatten().copied().collect();
        let init = |label: &str, contents: &[u8], usage| {
            self.passes.gpu.buffer_init(label, contents, 16, usage)
        };
        Cones {
            vertices: init(
                "penumbra vertices",
                bytemuck::cast_slice(&vertices),
                wgpu::BufferUsages::VERTEX,
            ),
            indices: init(
                "penumbra indices",
                bytemuck::cast_slice(&indices),
                wgpu::BufferUsages::INDEX,
            ),
            vertex_count: vertices.len() as u32,
            index_count: indices.len() as u32,
        }
    }

    /// The penumbra pass: cleared to white (1.0), then every cone and sheet.
    fn penumbra_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        cones: &Cones,
        counting: bool,
        q: Queries,
    ) {
        let mut pass = timing::render_pass(
            encoder,
            wgpu::RenderPassDescriptor {
                label: Some("penumbra_map"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.penumbra_view,
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
            q.timed(),
        );
        if let Some(s) = q.stats {
            s.begin_render(&mut pass, q.index);
        }
        pass.set_pipeline(if counting {
            &self.counting
        } else {
            &self.timed
        });
        pass.set_bind_group(0, &self.passes.shared_group, &[]);
        pass.set_bind_group(1, &self.penumbra_group, &[]);
        pass.set_vertex_buffer(0, cones.vertices.slice(..));
        pass.set_index_buffer(cones.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..cones.index_count, 0, 0..1);
        if q.stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    fn run(
        &self,
        frame: &Frame,
        geometry: &ShadowGeometry,
        o: &PenumbraMapOptions,
    ) -> Result<FrameOutput> {
        let p = &self.passes;
        let gpu = p.gpu;
        let image = (p.width, p.height);
        let light = frame.scene.light.center();
        let light_radius = frame.scene.light.size();
        let adj = EdgeAdjacency::build(&geometry.occluders);

        // The timed submission, one phase at a time (GPU passes 0, 1, 2: shadow map, penumbra
        // map, eye lookup).
        let timer = PassTimer::new(gpu, 3);
        let stats = PassStats::new(gpu, 3);
        let q = |index| Queries {
            timer: timer.as_ref(),
            stats: stats.as_ref(),
            index,
        };
        let shadow_wall = p.gpu.submit(|e| p.raster_pass(e, false, q(0)))?;

        let start = Instant::now();
        let s = silhouettes(&adj, &self.view, light, light_radius, o.max_sheet_strips);
        let silhouettes_wall = start.elapsed().as_secs_f64() * 1e3;

        let start = Instant::now();
        let g = PenumbraGeometry::build(&s, &self.view, light_radius, o.cone_segments);
        let cones = self.upload(&g);
        p.gpu
            .submit(|e| self.penumbra_pass(e, &cones, false, q(1)))?;
        let penumbra_wall = start.elapsed().as_secs_f64() * 1e3;

        let vis_staging = Staging::new(gpu, "visibility readback", p.visibility.size());
        let lookup_wall = p.gpu.submit(|e| {
            let pipeline = &p.lookup_timed;
            p.compute_pass(
                e,
                "eye_lookup",
                pipeline,
                image,
                q(2),
                Some(&self.lookup_group),
            );
            vis_staging.copy(e, &p.visibility);
            resolve_queries(e, timer.as_ref(), stats.as_ref());
        })?;
        let readback_start = Instant::now();
        let data: Vec<f32> = words(&vis_staging.read(gpu)?);
        let readback_ms = readback_start.elapsed().as_secs_f64() * 1e3;
        let mut warnings = Vec::new();
        let (times, pipeline) = read_queries(gpu, &timer, &stats, &mut warnings)?;
        let gpu_ms = &times.ms;

        // The instrumented replay: the counters are cleared before each pass and copied after.
        let staging: Vec<Staging> = (0..3)
            .map(|_| Staging::new(gpu, "counts readback", p.counts.size()))
            .collect();
        p.gpu.submit(|e| {
            e.clear_buffer(&p.counts, 0, None);
            p.raster_pass(e, true, Queries::NONE);
            let res = (p.resolution, p.resolution);
            let covered = &p.count_covered;
            // The lookup's pipeline layout, group 2 included.
            let group = Some(&self.lookup_group);
            p.compute_pass(e, "count_covered", covered, res, Queries::NONE, group);
            staging[0].copy(e, &p.counts);
            e.clear_buffer(&p.counts, 0, None);
            self.penumbra_pass(e, &cones, true, Queries::NONE);
            staging[1].copy(e, &p.counts);
            e.clear_buffer(&p.counts, 0, None);
            let lookup = &p.lookup_counting;
            p.compute_pass(
                e,
                "eye_lookup",
                lookup,
                image,
                Queries::NONE,
                Some(&self.lookup_group),
            );
            staging[2].copy(e, &p.counts);
        })?;
        let counts = staging
            .iter()
            .map(|s| Ok(words::<Counts>(&s.read(gpu)?)[0]))
            .collect::<Result<Vec<Counts>>>()?;

        let mut shadow = p.raster_counters(&counts[0]);
        let sil = silhouette_counters(&s);
        let mut penumbra = self.penumbra_counters(&s, o, &cones, &counts[1]);
        let mut eye = p.lookup_counters(frame, &counts[2]);
        let taps = f64::from(counts[2].extra_taps);
        eye.set("penumbra_map.taps", taps);
        eye.set("mem_est.penumbra_map.read_bytes", taps * DEPTH_TEXEL_BYTES);
        eye.add("mem_est.read_bytes", taps * DEPTH_TEXEL_BYTES);
        if let Some(stats) = &pipeline {
            shadow.merge(&stats[0]);
            penumbra.merge(&stats[1]);
            eye.merge(&stats[2]);
        }
        let t = |i: usize| gpu_ms.as_ref().map(|t| t[i]);
        let phases = vec![
            gpu_phase("shadow_map", shadow_wall, t(0), shadow),
            gpu_phase("silhouettes", silhouettes_wall, None, sil),
            gpu_phase("penumbra_map", penumbra_wall, t(1), penumbra),
            gpu_phase("eye_lookup", lookup_wall, t(2), eye),
        ];
        Ok(p.output(data, phases, readback_ms, warnings, &times))
    }

    /// `penumbra_map`: fill is every cone and sheet fragment, overdraw those discarded behind
    /// the shadow-map surface (as on the cpu executions). Memory traffic estimated: the
    /// geometry, a shadow-map read per fragment, and a depth test (read) per fragment kept,
    /// bounded writes of the penumbra map (the clear and one per fragment kept).
    fn penumbra_counters(
        &self,
        s: &Silhouettes,
        o: &PenumbraMapOptions,
        cones: &Cones,
        c: &Counts,
    ) -> Counters {
        let fragments = f64::from(c.fragments);
        let discarded = f64::from(c.discarded);
        let kept = fragments - discarded;
        let mut k = Counters::default();
        k.set("fill", fragments);
        k.set("overdraw", discarded);
        let cone_triangles = s.vertices.len() as f64 * f64::from(o.cone_segments);
        k.set("penumbra.cone_triangles", cone_triangles);
        k.set(
            "penumbra.sheet_triangles",
            f64::from(cones.index_count / 3) - cone_triangles,
        );
        let vertex_bytes = f64::from(cones.vertex_count) * VERTEX_BYTES;
        let index_bytes = f64::from(cones.index_count) * INDEX_BYTES;
        let shadow_read = fragments * DEPTH_TEXEL_BYTES;
        let clear = f64::from(self.passes.resolution).powi(2) * DEPTH_TEXEL_BYTES;
        let map_read = kept * DEPTH_TEXEL_BYTES;
        let map_write = clear + kept * DEPTH_TEXEL_BYTES;
        k.set("mem_est.penumbra_vertices.read_bytes", vertex_bytes);
        k.set("mem_est.penumbra_indices.read_bytes", index_bytes);
        k.set("mem_est.shadow_map.read_bytes", shadow_read);
        k.set("mem_est.penumbra_map.read_bytes", map_read);
        k.set("mem_est.penumbra_map.write_bytes", map_write);
        k.set(
            "mem_est.read_bytes",
            vertex_bytes + index_bytes + shadow_read + map_read,
        );
        k.set("mem_est.write_bytes", map_write);
        k
    }
}

/// `silhouettes`: the counts the cpu executions record in the same phase.
fn silhouette_counters(s: &Silhouettes) -> Counters {
    let mut k = Counters::default();
    k.set("silhouette.edges", s.edges.len() as f64);
    k.set("silhouette.vertices", s.vertices.len() as f64);
    k.set(
        "silhouette.vertices_over_two_edges",
        s.vertices_over_two_edges() as f64,
    );
    k.set(
        "silhouette.max_edges_per_vertex",
        f64::from(s.max_edges_per_vertex()),
    );
    k
}

#[cfg(test)]
mod layout_tests {
    use super::*;
    use crate::gpu::wgsl_layout::assert_wgsl_layout;

    #[test]
    fn uniforms_match_wgsl() {
        let source = format!("{LIGHT_RASTER_WGSL}\n{PENUMBRA_WGSL}");
        assert_wgsl_layout!(source, "PenumbraView", PenumbraView { proj });
    }
}
