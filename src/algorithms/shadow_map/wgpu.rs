//! The wgpu execution of the shadow-map family (`hard_shadow_map`, `pcss`): two GPU passes.
//! `penumbra_map` builds on the same passes ([`Passes`]), with its penumbra map between them.
//!
//! 1. `light_raster` — a render pass draws every triangle of the scene from the light centre
//!    ([`LightView`]) into a `map_resolution`² Depth32Float map (see `light_raster.wgsl`).
//! 2. `eye_lookup` — a compute pass over the frame's gbuffer, uploaded as storage buffers (the
//!    eye pass is shared by all executions, so parity is about the shadow algorithm alone),
//!    writes the visibility buffer with the algorithm's `visibility_at` (see `eye_lookup.wgsl`
//!    and each algorithm's `wgpu.wgsl`).
//!
//! The timed submission runs the passes as an engine would, with timestamp queries and
//! pipeline statistics around each. A second, instrumented submission runs the same passes
//! with WGSL atomics that count the fragments of the light raster and the texels they cover,
//! which gives `fill` and `overdraw` in the same terms as the cpu-model (every rasterized
//! fragment; those that did not end up in the map), and the shadow-map taps of the lookup. Memory traffic is estimated from formats and
//! those counts (`mem_est.<buffer>.*`): a GPU does not report it.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};

use super::{Bias, FaceView, LightViews, ViewFit};
use crate::algorithms::FrameOutput;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::layout;
use crate::gpu::readback::{words, Staging};
use crate::gpu::stats::PassStats;
use crate::gpu::timing::{self, GpuTimes, PassTimer};
use crate::gpu::{gbuffer_positions, resolve_queries, Gpu};
use crate::record::{Counters, Phase};
use crate::scene::Mesh;
use crate::visibility::VisibilityBuffer;

const LIGHT_RASTER_WGSL: &str = include_str!("light_raster.wgsl");
const EYE_LOOKUP_WGSL: &str = include_str!("eye_lookup.wgsl");

/// Side of the square compute workgroups (`@workgroup_size(8, 8)` in eye_lookup.wgsl).
const WORKGROUP: u32 = 8;
/// Bytes of one texel of the Depth32Float shadow map.
pub(crate) const DEPTH_TEXEL_BYTES: f64 = 4.0;
/// Bytes of one gbuffer entry (a `vec4<f32>`, position or normal).
const GBUFFER_ENTRY_BYTES: f64 = 16.0;
/// Bytes of one occluder vertex (`vec3<f32>`) and one index (`u32`).
const VERTEX_BYTES: f64 = 12.0;
const INDEX_BYTES: f64 = 4.0;

/// What an algorithm of the family adds to the shared passes.
pub struct Lookup<'a> {
    /// The algorithm's WGSL defining `visibility_at(uv, z_r, bias) -> f32`.
    pub wgsl: &'a str,
    pub bias: Bias,
    /// PCSS tap counts (unused by the hard test).
    pub blocker_samples: u32,
    pub pcf_samples: u32,
}

/// The `Light` uniform of both WGSL files.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LightUniform {
    view_proj: [f32; 16],
    eye: [f32; 3],
    radius: f32,
    near: f32,
    far: f32,
    tan_half_fov: f32,
    resolution: u32,
    bias_constant: f32,
    bias_slope: f32,
    blocker_samples: u32,
    pcf_samples: u32,
    width: u32,
    height: u32,
    /// The cube face whose receivers this view shades ([`FaceView::face_code`]; 6: all).
    face: u32,
    pad: u32,
}

/// The `Counts` storage buffer of the instrumented mode.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct Counts {
    /// Fragments rasterized.
    pub fragments: u32,
    /// Shadow-map texels covered.
    pub covered: u32,
    /// Shadow-map taps of the lookup.
    pub taps: u32,
    pub wasted_taps: u32,
    /// Fragments a fragment program discarded (penumbra map).
    pub discarded: u32,
    /// Taps of a second map in the lookup (penumbra map).
    pub extra_taps: u32,
}

/// The timestamp and statistics queries of one pass: the query sets (absent when the adapter
/// lacks the feature, or in the instrumented replay) and the pass's index in them.
#[derive(Clone, Copy)]
pub(crate) struct Queries<'a> {
    pub timer: Option<&'a PassTimer>,
    pub stats: Option<&'a PassStats>,
    pub index: u32,
}

impl<'a> Queries<'a> {
    pub const NONE: Queries<'static> = Queries {
        timer: None,
        stats: None,
        index: 0,
    };

    /// The timer and this pass's index in it, for [`timing::compute_pass`] and
    /// [`timing::render_pass`].
    pub fn timed(&self) -> Option<(&'a PassTimer, u32)> {
        self.timer.map(|t| (t, self.index))
    }
}

/// Renders `frame` with the family's two passes and the algorithm's lookup, once per light view
/// ([`ViewFit::CubeWhenWide`]: one frustum, or the faces of a cube map, each pixel from the
/// face that shades it; phases `light_raster[+x]`, `eye_lookup[+x]`, ... per face).
pub fn render(gpu: &Gpu, frame: &Frame, lookup: &Lookup) -> Result<FrameOutput> {
    check_limits(gpu, frame)?;
    let views = LightViews::fit(
        frame,
        &frame.scene.light,
        frame.params.map_resolution,
        ViewFit::CubeWhenWide,
    );
    let mut merged: Option<FrameOutput> = None;
    for face in &views.views {
        let casters = face.view.casters(&frame.flat.mesh);
        let mut out = Passes::new(gpu, frame, lookup, face, &casters, None).run(frame)?;
        for p in &mut out.phases {
            p.name = face.phase(&p.name);
        }
        merged = Some(match merged {
            None => out,
            Some(mut all) => {
                face.take_owned(frame, &out.visibility, &mut all.visibility);
                all.phases.extend(out.phases);
                all.gpu_ms = match (all.gpu_ms, out.gpu_ms) {
                    (Some(a), Some(b)) => Some(a + b),
                    _ => None,
                };
                for w in out.warnings {
                    if !all.warnings.contains(&w) {
                        all.warnings.push(w);
                    }
                }
                all
            }
        });
    }
    let mut out = merged.expect("a fit has at least one view");
    if views.views.len() > 1 {
        out.counters = sum_phases(&out.phases);
    }
    views.record(&mut out);
    Ok(out)
}

/// The counters of a run: those of its phases summed (derived figures such as
/// `overdraw_ratio` are added for every record by [`crate::counters::derive`]).
fn sum_phases(phases: &[Phase]) -> Counters {
    let mut counters = Counters::default();
    for p in phases {
        counters.merge(&p.counters);
    }
    counters
}

/// Checks the frame against the adapter's limits before anything is allocated.
pub(crate) fn check_limits(gpu: &Gpu, frame: &Frame) -> Result<()> {
    let res = frame.params.map_resolution;
    if res > gpu.limits.max_texture_dimension_2d {
        return Err(Error::Resource(format!(
            "map_resolution {res} exceeds the adapter's largest texture ({})",
            gpu.limits.max_texture_dimension_2d
        )));
    }
    let gbuffer_bytes = frame.gbuffer.len() as u64 * GBUFFER_ENTRY_BYTES as u64;
    let max = gpu.limits.max_storage_buffer_binding_size;
    if gbuffer_bytes > max {
        return Err(Error::Resource(format!(
            "image {}x{} needs {gbuffer_bytes} bytes per gbuffer buffer, more than the adapter's \
             storage binding limit ({max})",
            frame.width(),
            frame.height()
        )));
    }
    Ok(())
}

/// The resources and pipelines of one frame.
pub(crate) struct Passes<'g> {
    pub gpu: &'g Gpu,
    pub width: u32,
    pub height: u32,
    pub resolution: u32,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    vertex_count: usize,
    /// The shadow map (Depth32Float, NDC depth).
    pub depth_view: wgpu::TextureView,
    pub visibility: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    /// Group 0 of every pass: the light uniform and the counters.
    pub shared_layout: wgpu::BindGroupLayout,
    pub shared_group: wgpu::BindGroup,
    lookup_group: wgpu::BindGroup,
    raster_timed: wgpu::RenderPipeline,
    raster_counting: wgpu::RenderPipeline,
    pub lookup_timed: wgpu::ComputePipeline,
    pub lookup_counting: wgpu::ComputePipeline,
    pub count_covered: wgpu::ComputePipeline,
}

/// A storage buffer of the lookup and counting passes (compute and fragment shaders).
fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    layout::storage(
        binding,
        wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT,
        read_only,
    )
}

impl<'g> Passes<'g> {
    /// The passes of `frame` in light view `face` with the shadow map of `occluders` (the
    /// scene's triangles that meet the view, or a stand-in for them) and `lookup`'s
    /// `visibility_at`; `extra` is the layout of a group 2 that the lookup's WGSL declares
    /// (bound by [`Self::compute_pass`]).
    pub fn new(
        gpu: &'g Gpu,
        frame: &Frame,
        lookup: &Lookup,
        face: &FaceView,
        occluders: &Mesh,
        extra: Option<&wgpu::BindGroupLayout>,
    ) -> Passes<'g> {
        let device = &gpu.device;
        let (width, height) = (frame.width(), frame.height());
        let resolution = frame.params.map_resolution;
        let view = face.view;
        let uniform = LightUniform {
            view_proj: view.view_proj.to_cols_array(),
            eye: view.eye.to_array(),
            radius: frame.scene.light.size(),
            near: view.near,
            far: view.far,
            tan_half_fov: view.tan_half_fov,
            resolution,
            bias_constant: lookup.bias.constant,
            bias_slope: lookup.bias.slope,
            blocker_samples: lookup.blocker_samples,
            pcf_samples: lookup.pcf_samples,
            width,
            height,
            face: face.face_code(),
            pad: 0,
        };
        let init = |label: &str, contents: &[u8], usage| gpu.buffer_init(label, contents, 4, usage);
        let uniform_buf = init(
            "light uniform",
            bytemuck::bytes_of(&uniform),
            wgpu::BufferUsages::UNIFORM,
        );

        // Every triangle of the scene can cast a shadow into the map (receivers shadow each
        // other too), indexed as in `occluders`, as the cpu executions draw it.
        let positions: Vec<[f32; 3]> = occluders.positions.iter().map(|p| p.to_array()).collect();
        let index_list: Vec<u32> = occluders.triangles.iter().flatten().copied().collect();
        let vertices = init(
            "occluder vertices",
            bytemuck::cast_slice(&positions),
            wgpu::BufferUsages::VERTEX,
        );
        let indices = init(
            "occluder indices",
            bytemuck::cast_slice(&index_list),
            wgpu::BufferUsages::INDEX,
        );

        // The gbuffer: position with the hit flag in w, and the eye-facing normal.
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

        let depth = gpu.map_texture(
            "shadow map",
            resolution,
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::empty(),
        );
        let depth_view = depth.create_view(&Default::default());

        // Group 0 (both shaders): the light uniform and the counters.
        let shared_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow map shared"),
            entries: &[
                layout::uniform(
                    0,
                    wgpu::ShaderStages::VERTEX
                        | wgpu::ShaderStages::FRAGMENT
                        | wgpu::ShaderStages::COMPUTE,
                ),
                storage_entry(1, false),
            ],
        });
        // Group 1 (eye lookup): shadow map, gbuffer, visibility.
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("eye lookup"),
            entries: &[
                layout::texture(
                    0,
                    wgpu::ShaderStages::COMPUTE,
                    wgpu::TextureSampleType::Depth,
                ),
                storage_entry(1, true),
                storage_entry(2, true),
                storage_entry(3, false),
            ],
        });
        let shared_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow map shared"),
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
        let lookup_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("eye lookup"),
            layout: &lookup_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&depth_view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: positions_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: normals_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: visibility.as_entire_binding(),
                },
            ],
        });

        let raster_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("light raster"),
            bind_group_layouts: &[Some(&shared_layout)],
            immediate_size: 0,
        });
        let compute_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("eye lookup"),
            bind_group_layouts: &[Some(&shared_layout), Some(&lookup_layout), extra],
            immediate_size: 0,
        });
        let raster_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("light_raster.wgsl"),
            source: wgpu::ShaderSource::Wgsl(LIGHT_RASTER_WGSL.into()),
        });
        let lookup_source = format!("{EYE_LOOKUP_WGSL}\n{}", lookup.wgsl);
        let lookup_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("eye_lookup.wgsl"),
            source: wgpu::ShaderSource::Wgsl(lookup_source.into()),
        });

        let raster = |fragment: &str| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(fragment),
                layout: Some(&raster_layout),
                vertex: wgpu::VertexState {
                    module: &raster_module,
                    entry_point: Some("vs"),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: VERTEX_BYTES as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                    })],
                },
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
                    module: &raster_module,
                    entry_point: Some(fragment),
                    compilation_options: Default::default(),
                    targets: &[],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let compute = |entry: &str, instrument: bool| {
            gpu.instrumented_compute_pipeline(&compute_layout, &lookup_module, entry, instrument)
        };
        Passes {
            gpu,
            width,
            height,
            resolution,
            vertices,
            indices,
            index_count: index_list.len() as u32,
            vertex_count: positions.len(),
            depth_view,
            visibility,
            counts,
            shared_layout,
            shared_group,
            lookup_group,
            raster_timed: raster("fs_depth"),
            raster_counting: raster("fs_count"),
            lookup_timed: compute("eye_lookup", false),
            lookup_counting: compute("eye_lookup", true),
            count_covered: compute("count_covered", true),
        }
    }

    /// The light raster: the timed pipeline, or the counting one of the instrumented replay.
    pub fn raster_pass(&self, encoder: &mut wgpu::CommandEncoder, counting: bool, q: Queries) {
        let pipeline = if counting {
            &self.raster_counting
        } else {
            &self.raster_timed
        };
        let mut pass = timing::render_pass(
            encoder,
            wgpu::RenderPassDescriptor {
                label: Some("light_raster"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.depth_view,
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
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.shared_group, &[]);
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..self.index_count, 0, 0..1);
        if q.stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    /// A compute pass over `size` (8×8 workgroups) with the eye lookup's bind groups, and
    /// `extra` as group 2 where the pipeline has one.
    pub fn compute_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        label: &str,
        pipeline: &wgpu::ComputePipeline,
        size: (u32, u32),
        q: Queries,
        extra: Option<&wgpu::BindGroup>,
    ) {
        let mut pass = timing::compute_pass(encoder, label, q.timed());
        if let Some(s) = q.stats {
            s.begin_compute(&mut pass, q.index);
        }
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.shared_group, &[]);
        pass.set_bind_group(1, &self.lookup_group, &[]);
        if let Some(g) = extra {
            pass.set_bind_group(2, g, &[]);
        }
        pass.dispatch_workgroups(size.0.div_ceil(WORKGROUP), size.1.div_ceil(WORKGROUP), 1);
        if q.stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    fn run(&self, frame: &Frame) -> Result<FrameOutput> {
        let gpu = self.gpu;
        let image = (self.width, self.height);

        // The timed submission: each phase submitted and waited for on its own, so its wall
        // time includes submission.
        let timer = PassTimer::new(gpu, 2);
        let stats = PassStats::new(gpu, 2);
        let q = |index| Queries {
            timer: timer.as_ref(),
            stats: stats.as_ref(),
            index,
        };
        let raster_wall = self.gpu.submit(|e| self.raster_pass(e, false, q(0)))?;
        let vis_staging = Staging::new(gpu, "visibility readback", self.visibility.size());
        let lookup_wall = self.gpu.submit(|e| {
            self.compute_pass(e, "eye_lookup", &self.lookup_timed, image, q(1), None);
            vis_staging.copy(e, &self.visibility);
            resolve_queries(e, timer.as_ref(), stats.as_ref());
        })?;
        let readback_start = Instant::now();
        let data: Vec<f32> = words(&vis_staging.read(gpu)?);
        let readback_ms = readback_start.elapsed().as_secs_f64() * 1e3;
        let mut warnings = Vec::new();
        let (times, pipeline) = read_queries(gpu, &timer, &stats, &mut warnings)?;
        let gpu_ms = &times.ms;

        // The instrumented submission: same passes, counting with atomics.
        let counts_staging = Staging::new(gpu, "counts readback", self.counts.size());
        self.gpu.submit(|e| {
            e.clear_buffer(&self.counts, 0, None);
            self.raster_pass(e, true, Queries::NONE);
            let res = (self.resolution, self.resolution);
            self.compute_pass(
                e,
                "count_covered",
                &self.count_covered,
                res,
                Queries::NONE,
                None,
            );
            self.compute_pass(
                e,
                "eye_lookup",
                &self.lookup_counting,
                image,
                Queries::NONE,
                None,
            );
            counts_staging.copy(e, &self.counts);
        })?;
        let counts: Counts = words::<Counts>(&counts_staging.read(gpu)?)[0];

        let mut raster = self.raster_counters(&counts);
        let mut eye = self.lookup_counters(frame, &counts);
        if let Some(p) = &pipeline {
            raster.merge(&p[0]);
            eye.merge(&p[1]);
        }
        let phases = vec![
            gpu_phase(
                "light_raster",
                raster_wall,
                gpu_ms.as_ref().map(|t| t[0]),
                raster,
            ),
            gpu_phase(
                "eye_lookup",
                lookup_wall,
                gpu_ms.as_ref().map(|t| t[1]),
                eye,
            ),
        ];
        Ok(self.output(data, phases, readback_ms, warnings, &times))
    }

    /// The frame output of a run: the visibility read back, the phases and their counters
    /// summed, the GPU time of all phases, the adapter.
    pub fn output(
        &self,
        data: Vec<f32>,
        phases: Vec<Phase>,
        readback_ms: f64,
        warnings: Vec<String>,
        times: &GpuTimes,
    ) -> FrameOutput {
        let counters = sum_phases(&phases);
        let gpu_ms = phases.iter().filter_map(|p| p.gpu_ms).reduce(|a, b| a + b);
        let mut execution = self.gpu.execution();
        times.record(&mut execution);
        execution.insert("readback_ms".into(), serde_json::json!(readback_ms));
        execution.insert(
            "gpu_counters".into(),
            serde_json::json!(
                "fill/overdraw from an instrumented replay (WGSL atomics); mem_est.* estimated \
                 from formats and counts"
            ),
        );
        FrameOutput {
            visibility: VisibilityBuffer {
                width: self.width,
                height: self.height,
                data,
            },
            counters,
            phases,
            model_ms: None,
            gpu_ms,
            execution,
            warnings,
            rgb: None,
        }
    }

    /// `light_raster`: fill is every rasterised fragment, overdraw those that did not end up in
    /// the map (fragments minus covered texels).
    pub fn raster_counters(&self, c: &Counts) -> Counters {
        let fragments = f64::from(c.fragments);
        let mut k = Counters::default();
        k.set("fill", fragments);
        k.set("overdraw", fragments - f64::from(c.covered));
        k.set("shadow_map.covered_texels", f64::from(c.covered));
        let vertex_bytes = self.vertex_count as f64 * VERTEX_BYTES;
        let index_bytes = f64::from(self.index_count) * INDEX_BYTES;
        let clear = f64::from(self.resolution).powi(2) * DEPTH_TEXEL_BYTES;
        // Every fragment reads the depth it is tested against; writes are bounded by the clear
        // plus one per fragment.
        let map_read = fragments * DEPTH_TEXEL_BYTES;
        let map_write = clear + fragments * DEPTH_TEXEL_BYTES;
        k.set("mem_est.occluder_vertices.read_bytes", vertex_bytes);
        k.set("mem_est.occluder_indices.read_bytes", index_bytes);
        k.set("mem_est.shadow_map.read_bytes", map_read);
        k.set("mem_est.shadow_map.write_bytes", map_write);
        k.set("mem_est.read_bytes", vertex_bytes + index_bytes + map_read);
        k.set("mem_est.write_bytes", map_write);
        k
    }

    /// `eye_lookup`: no fill (nothing is rasterized); the shadow-map taps, and the PCF taps of
    /// pixels left fully lit or fully shadowed, whose filtering changed nothing.
    pub fn lookup_counters(&self, frame: &Frame, c: &Counts) -> Counters {
        let pixels = f64::from(self.width) * f64::from(self.height);
        let hits = frame.gbuffer.mask().iter().filter(|&&h| h).count() as f64;
        let taps = f64::from(c.taps);
        let mut k = Counters::default();
        k.set("shadow_map.taps", taps);
        k.set("shadow_map.taps_wasted", f64::from(c.wasted_taps));
        // Every pixel reads its position (and hit flag); hit pixels also read their normal.
        let gbuffer = (pixels + hits) * GBUFFER_ENTRY_BYTES;
        let map_read = taps * DEPTH_TEXEL_BYTES;
        let vis_write = pixels * 4.0;
        k.set("mem_est.gbuffer.read_bytes", gbuffer);
        k.set("mem_est.shadow_map.read_bytes", map_read);
        k.set("mem_est.visibility.write_bytes", vis_write);
        k.set("mem_est.read_bytes", gbuffer + map_read);
        k.set("mem_est.write_bytes", vis_write);
        k
    }
}

/// A phase of a GPU execution (no modelled time).
pub(crate) fn gpu_phase(
    name: &str,
    wall_ms: f64,
    gpu_ms: Option<f64>,
    counters: Counters,
) -> Phase {
    Phase {
        name: name.into(),
        wall_ms,
        model_ms: None,
        gpu_ms,
        counters,
    }
}

/// GPU milliseconds and pipeline statistics per pass, where the adapter offers them; a warning
/// for each that it does not.
#[allow(clippy::type_complexity)]
pub(crate) fn read_queries(
    gpu: &Gpu,
    timer: &Option<PassTimer>,
    stats: &Option<PassStats>,
    warnings: &mut Vec<String>,
) -> Result<(GpuTimes, Option<Vec<Counters>>)> {
    Ok((
        timing::read_ms_or_warn(gpu, timer, warnings)?,
        crate::gpu::stats::read_or_warn(gpu, stats, warnings)?,
    ))
}

#[cfg(test)]
mod layout_tests {
    use super::*;
    use crate::gpu::wgsl_layout::assert_wgsl_layout;

    /// `LightUniform` and `Counts` against both WGSL files of the family (the eye lookup as
    /// `hard_shadow_map` completes it).
    #[test]
    fn uniforms_match_wgsl() {
        let eye_lookup = format!(
            "{EYE_LOOKUP_WGSL}\n{}",
            include_str!("../hard_shadow_map/wgpu.wgsl")
        );
        for source in [LIGHT_RASTER_WGSL.to_string(), eye_lookup] {
            assert_wgsl_layout!(
                source,
                "Light",
                LightUniform {
                    view_proj,
                    eye,
                    radius,
                    near,
                    far,
                    tan_half_fov,
                    resolution,
                    bias_constant,
                    bias_slope,
                    blocker_samples,
                    pcf_samples,
                    width,
                    height,
                    face,
                    pad
                }
            );
            assert_wgsl_layout!(
                source,
                "Counts",
                Counts {
                    fragments,
                    covered,
                    taps,
                    wasted_taps,
                    discarded,
                    extra_taps
                }
            );
        }
    }
}
