//! The GPU pass builder every wgpu execution is written with: bindings declared as data
//! ([`Bind`] lists, one per bind group), programs (a WGSL module joined from its parts and a
//! pipeline layout) and the pipelines made from them, passes as data ([`Pass`]), and the one
//! sequence every execution runs ([`Timed`], [`Timing::output`]):
//!
//! 1. the timed submissions: each pass timed by [`timing`] (timestamps inside passes where the
//!    adapter offers them, the readings checked against the host time of their submission,
//!    `execution.gpu_ms_invalid` when they cannot be true) and, where asked, its pipeline
//!    statistics; each submission resolves its own queries, and the readback buffers are copied
//!    in a submission of their own when the run finishes;
//! 2. the instrumented replay derived from the same passes ([`Timed::counting_into`]): each
//!    recorded again with its pipelines' counting variants ([`Instrumented`]; the WGSL override
//!    `INSTRUMENT` on), counting with atomics into a buffer cleared before and read after;
//! 3. the output: phases (wall time of their submissions and host work, GPU time of their
//!    passes, the counters the execution derives from the replay plus the pipeline
//!    statistics), their counters summed, and the record's `execution` entries.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::record::{Counters, Phase, PhaseId};
use crate::visibility::{RgbBuffer, VisibilityBuffer};

use super::cache::Kind;
use super::readback::{words, Staging};
use super::stats::{read_or_warn, PassStats, COMPUTE_INVOCATIONS};
use super::timing::{self, read_ms_or_warn, GpuTimes, PassTimer};
use super::{gbuffer_positions, resolve_queries, Gpu, GpuCounters, Run};
use crate::frame::{FrameOutput, GBuffer};

/// Declares a `#[repr(C)]` struct the GPU reads (a uniform or storage buffer) once, for both
/// sides: the Rust struct (`Pod`, every field public) and, as `NAME::WGSL`, the WGSL `struct`
/// declaration that the shaders using it are joined with ([`Program::new`]). Each field names
/// its Rust type and its WGSL type (`field: [f32; 3] => "vec3<f32>"`); the WGSL struct is called
/// as given after `as`. Whether WGSL lays the fields out where Rust does (alignment: a `vec3`
/// takes 16 bytes unless a scalar follows it) is checked by `NAME::layout_mismatches` (tests
/// only), which parses the shader source as a pipeline joins it with naga
/// ([`crate::gpu::wgsl_layout`]).
macro_rules! gpu_struct {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident as $wgsl:literal {
            $($(#[doc = $doc:literal])* $field:ident: $rty:ty => $wty:literal,)*
        }
    ) => {
        $(#[$meta])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
        $vis struct $name {
            $($(#[doc = $doc])* pub $field: $rty,)*
        }

        impl $name {
            /// The WGSL declaration of this struct.
            pub const WGSL: &'static str = concat!(
                "struct ", $wgsl, " {\n",
                $("    ", stringify!($field), ": ", $wty, ",\n",)*
                "}\n"
            );

            /// How the WGSL struct in `source` (a shader as a pipeline joins it) differs in
            /// size or field offsets from this struct; empty when they agree.
            #[cfg(test)]
            pub fn layout_mismatches(source: &str) -> Vec<String> {
                $crate::gpu::wgsl_layout::mismatches(
                    source,
                    $wgsl,
                    std::mem::size_of::<Self>(),
                    &[$((stringify!($field), std::mem::offset_of!(Self, $field))),*],
                )
            }
        }
    };
}
pub(crate) use gpu_struct;

/// The kind of one binding of a bind group; a group is a list of them, binding `i` at index
/// `i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bind {
    /// A uniform buffer.
    Uniform,
    /// A storage buffer the shaders only read.
    ReadOnly,
    /// A storage buffer the shaders write (not visible to vertex shaders).
    ReadWrite,
    /// A 2D depth texture.
    Depth,
    /// A 2D float texture read with `textureLoad` (not filterable).
    Float,
    /// A 2D storage texture of this format, written (not visible to vertex shaders).
    StorageTexture(wgpu::TextureFormat),
    /// A non-filtering sampler.
    Sampler,
    /// No binding at this index (the WGSL leaves the number to another group layout).
    Absent,
}

impl Bind {
    fn entry(self, binding: u32, stages: wgpu::ShaderStages) -> Option<wgpu::BindGroupLayoutEntry> {
        let writable = stages - wgpu::ShaderStages::VERTEX;
        let buffer = |ty| wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let texture = |sample_type| wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        };
        let storage = |read_only| buffer(wgpu::BufferBindingType::Storage { read_only });
        let (visibility, ty) = match self {
            Bind::Uniform => (stages, buffer(wgpu::BufferBindingType::Uniform)),
            Bind::ReadOnly => (stages, storage(true)),
            Bind::ReadWrite => (writable, storage(false)),
            Bind::Depth => (stages, texture(wgpu::TextureSampleType::Depth)),
            Bind::Float => (
                stages,
                texture(wgpu::TextureSampleType::Float { filterable: false }),
            ),
            Bind::StorageTexture(format) => (
                writable,
                wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format,
                    view_dimension: wgpu::TextureViewDimension::D2,
                },
            ),
            Bind::Sampler => (
                stages,
                wgpu::BindingType::Sampler(wgpu::SamplerBindingType::NonFiltering),
            ),
            Bind::Absent => return None,
        };
        Some(wgpu::BindGroupLayoutEntry {
            binding,
            visibility,
            ty,
            count: None,
        })
    }
}

/// A bind-group layout made from a [`Bind`] list, and the binding numbers it holds.
pub struct Layout {
    pub layout: wgpu::BindGroupLayout,
    bindings: Vec<u32>,
    /// What determines the layout (its stages and binds), for the device's [`super::cache`].
    key: String,
}

impl Layout {
    /// The layout of `binds` (binding `i` at index `i`) visible to `stages`: made once per
    /// device ([`super::cache`]; `label` is the first maker's).
    pub fn new(gpu: &Gpu, label: &str, stages: wgpu::ShaderStages, binds: &[Bind]) -> Layout {
        let entries: Vec<_> = (0u32..)
            .zip(binds)
            .filter_map(|(i, b)| b.entry(i, stages))
            .collect();
        let key = format!("{stages:?}{binds:?}");
        Layout {
            layout: gpu.cache.get(Kind::BindGroupLayout, key.clone(), || {
                gpu.device
                    .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some(label),
                        entries: &entries,
                    })
            }),
            bindings: entries.iter().map(|e| e.binding).collect(),
            key,
        }
    }

    /// The layout of `binds` (each binding's kind and resource, binding `i` at index `i`)
    /// visible to `stages`, and the bind group of their resources.
    pub fn bound(
        gpu: &Gpu,
        label: &str,
        stages: wgpu::ShaderStages,
        binds: &[(Bind, wgpu::BindingResource)],
    ) -> (Layout, wgpu::BindGroup) {
        let kinds: Vec<Bind> = binds.iter().map(|b| b.0).collect();
        let layout = Layout::new(gpu, label, stages, &kinds);
        let resources: Vec<_> = binds
            .iter()
            .filter(|b| b.0 != Bind::Absent)
            .map(|b| b.1.clone())
            .collect();
        let group = layout.group(gpu, label, &resources);
        (layout, group)
    }

    /// A bind group of this layout: `resources` in the order of its bindings (absent ones
    /// skipped).
    pub fn group(
        &self,
        gpu: &Gpu,
        label: &str,
        resources: &[wgpu::BindingResource],
    ) -> wgpu::BindGroup {
        assert_eq!(resources.len(), self.bindings.len(), "bind group {label}");
        let entries: Vec<_> = self
            .bindings
            .iter()
            .zip(resources)
            .map(|(&binding, r)| wgpu::BindGroupEntry {
                binding,
                resource: r.clone(),
            })
            .collect();
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &self.layout,
            entries: &entries,
        })
    }
}

/// Bytes of one Depth32Float texel.
pub const DEPTH_TEXEL_BYTES: f64 = 4.0;

/// An indexed triangle list on the GPU: its vertex buffer, its `u32` index buffer and their
/// counts.
pub struct Mesh {
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub vertex_count: u32,
    pub index_count: u32,
}

impl Mesh {
    /// Uploads `vertices` and the indices of `triangles`, in order.
    pub fn upload<T: bytemuck::Pod>(
        gpu: &Gpu,
        label: &str,
        vertices: &[T],
        triangles: &[[u32; 3]],
    ) -> Mesh {
        let indices: Vec<u32> = triangles.iter().flatten().copied().collect();
        Mesh {
            vertices: gpu.upload(label, vertices, wgpu::BufferUsages::VERTEX),
            indices: gpu.upload(label, &indices, wgpu::BufferUsages::INDEX),
            vertex_count: vertices.len() as u32,
            index_count: indices.len() as u32,
        }
    }

    /// Adds to `k` the estimated traffic (`mem_est.*`) of a depth-tested draw of the mesh
    /// (`(name, bytes a vertex)`: its vertices and `u32` indices read as `<name>_vertices`,
    /// `<name>_indices`) into a Depth32Float map of `resolution`² texels (`(map, resolution,
    /// fragments tested)`): a depth read per fragment tested, writes bounded by the clear plus
    /// one per fragment; and `reads`.
    pub fn depth_traffic(
        &self,
        k: &mut Counters,
        (name, vertex_bytes): (&str, f64),
        (map, resolution, tested): (&str, u32, f64),
        reads: &[(&str, f64)],
    ) {
        let vertices = format!("{name}_vertices");
        let indices = format!("{name}_indices");
        let mut all = vec![
            (&vertices[..], f64::from(self.vertex_count) * vertex_bytes),
            (&indices[..], f64::from(self.index_count) * 4.0),
        ];
        all.extend(reads.iter().copied());
        all.push((map, tested * DEPTH_TEXEL_BYTES));
        let clear = f64::from(resolution).powi(2) * DEPTH_TEXEL_BYTES;
        k.add_traffic(
            "mem_est",
            &all,
            &[(map, clear + tested * DEPTH_TEXEL_BYTES)],
        );
    }

    /// One draw of the whole mesh with `pipeline` into `color` and `depth`.
    pub fn draw<'a>(
        &'a self,
        pipeline: &'a Render,
        color: Option<&'a wgpu::TextureView>,
        depth: Option<&'a wgpu::TextureView>,
    ) -> Draw<'a> {
        Draw {
            color,
            depth,
            vertices: Some(&self.vertices),
            indices: Some(&self.indices),
            ..Draw::of(pipeline, self.index_count)
        }
    }
}

/// Group 0 of a family's passes, visible to every stage: a uniform (binding 0) and the counters
/// of the instrumented replay (binding 1, a zeroed `C`: [`Gpu::counts_buffer`]).
pub struct Shared {
    pub layout: Layout,
    pub group: wgpu::BindGroup,
    pub counts: wgpu::Buffer,
}

impl Shared {
    /// The group of `uniform` and a new counts buffer of type `C`.
    pub fn new<C: bytemuck::Pod>(gpu: &Gpu, label: &str, uniform: &impl bytemuck::Pod) -> Shared {
        let uniform = gpu.upload(
            label,
            std::slice::from_ref(uniform),
            wgpu::BufferUsages::UNIFORM,
        );
        let counts = gpu.counts_buffer::<C>(label);
        let stages = wgpu::ShaderStages::VERTEX_FRAGMENT | wgpu::ShaderStages::COMPUTE;
        let (layout, group) = Layout::bound(
            gpu,
            label,
            stages,
            &[
                (Bind::Uniform, uniform.as_entire_binding()),
                (Bind::ReadWrite, counts.as_entire_binding()),
            ],
        );
        Shared {
            layout,
            group,
            counts,
        }
    }
}

/// The per-pixel buffers of an eye pass over the gbuffer: positions with the hit flag in w
/// ([`gbuffer_positions`]) and normals with a flag of the execution's in w, which it reads, and
/// the visibility (one `f32` a pixel) it writes and the run reads back.
pub struct EyeBuffers {
    pub positions: wgpu::Buffer,
    pub normals: wgpu::Buffer,
    pub visibility: wgpu::Buffer,
}

impl EyeBuffers {
    /// The buffers of gbuffer `g`, with `normal_w(i)` in pixel `i`'s normal.
    pub fn new(gpu: &Gpu, g: &GBuffer, normal_w: impl Fn(usize) -> f32) -> EyeBuffers {
        let normals: Vec<[f32; 4]> = (0..g.len())
            .map(|i| g.normal[i].extend(normal_w(i)).to_array())
            .collect();
        let storage = wgpu::BufferUsages::STORAGE;
        let visibility_bytes = 4 * g.len() as u64;
        EyeBuffers {
            positions: gpu.upload("gbuffer positions", &gbuffer_positions(g), storage),
            normals: gpu.upload("gbuffer normals", &normals, storage),
            visibility: gpu.storage_buffer(
                "visibility",
                visibility_bytes,
                wgpu::BufferUsages::COPY_SRC,
            ),
        }
    }

    /// The bindings `first`, then these buffers' (positions and normals read, visibility
    /// written).
    pub fn binds_after<'a>(
        &'a self,
        first: impl IntoIterator<Item = (Bind, wgpu::BindingResource<'a>)>,
    ) -> Vec<(Bind, wgpu::BindingResource<'a>)> {
        first
            .into_iter()
            .chain([
                (Bind::ReadOnly, self.positions.as_entire_binding()),
                (Bind::ReadOnly, self.normals.as_entire_binding()),
                (Bind::ReadWrite, self.visibility.as_entire_binding()),
            ])
            .collect()
    }
}

/// A texture view as a binding resource.
pub fn view(v: &wgpu::TextureView) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::TextureView(v)
}

/// A pass's pipeline as each run of the pass uses it: the timed run's and the instrumented
/// replay's (the variant that counts with atomics, `INSTRUMENT` on, or another entry point). A
/// pass runs in the timed submissions when its pipelines have a timed variant and in the replay
/// when they have a counting one: stating a pipeline's variants once is all the replay needs
/// ([`Timed::counting_into`]).
#[derive(Clone)]
pub struct Instrumented<P> {
    /// The pipeline of the timed run; `None`: the pass only counts (replay only).
    pub timed: Option<P>,
    /// The pipeline of the instrumented replay; `None`: the pass counts nothing (timed only).
    pub counting: Option<P>,
}

impl<P> Instrumented<P> {
    /// A pipeline of the timed run only.
    pub fn timed(p: P) -> Self {
        Instrumented {
            timed: Some(p),
            counting: None,
        }
    }

    /// A pipeline of the instrumented replay only.
    pub fn counting(p: P) -> Self {
        Instrumented {
            timed: None,
            counting: Some(p),
        }
    }

    /// The variant of the timed run (`counting` false) or of the replay.
    pub fn variant(&self, counting: bool) -> Option<&P> {
        match counting {
            false => self.timed.as_ref(),
            true => self.counting.as_ref(),
        }
    }
}

impl<P: Clone> Instrumented<P> {
    /// The same pipeline in both runs (a pass the replay needs, such as a depth pre-pass,
    /// that counts nothing itself).
    pub fn both(p: P) -> Self {
        Instrumented {
            timed: Some(p.clone()),
            counting: Some(p),
        }
    }
}

/// A compute pipeline in each run of a pass.
pub type Compute = Instrumented<wgpu::ComputePipeline>;
/// A render pipeline in each run of a pass.
pub type Render = Instrumented<wgpu::RenderPipeline>;

/// A shader module and the pipeline layout its entry points share.
pub struct Program {
    pub module: wgpu::ShaderModule,
    pub layout: wgpu::PipelineLayout,
    /// What determines the module and the layout (the module's number in the device's
    /// [`super::cache`], the groups' keys), the start of its pipelines' keys.
    key: String,
}

/// A render pipeline of a [`Program`]: entry points, vertex input, depth test and colour
/// target. [`Raster::default`] is a depth-only pass (Depth32Float, `Less`, written) of
/// triangle lists drawn from both sides. Its `Debug` text holds every field: with the program's
/// key it keys the pipeline in the device's [`super::cache`].
#[derive(Clone, Debug)]
pub struct Raster<'a> {
    pub vs: &'a str,
    pub fs: &'a str,
    /// The vertex buffer's stride (bytes) and attributes, if it reads one.
    pub vertex: Option<(u64, wgpu::VertexStepMode, &'a [wgpu::VertexAttribute])>,
    pub topology: wgpu::PrimitiveTopology,
    pub cull: Option<wgpu::Face>,
    /// A depth test, if any, on a target of `depth_format`.
    pub depth: Option<wgpu::CompareFunction>,
    /// The depth target's format: Depth32Float by default, Depth32FloatStencil8 for a pass
    /// that also tests the stencil ([`Gpu::depth32_stencil8`]).
    pub depth_format: wgpu::TextureFormat,
    /// The stencil test and operations (none by default).
    pub stencil: wgpu::StencilState,
    /// Whether fragments passing the depth test write their depth (true by default; false for
    /// a pass that tests against a kept depth buffer, [`Onto`]).
    pub depth_write: bool,
    pub color: Option<wgpu::ColorTargetState>,
    /// The fragment stage's `INSTRUMENT` override, where its WGSL declares one.
    pub instrument: Option<bool>,
}

impl<'a> Raster<'a> {
    /// The default pipeline with the vertex stage `vs` and the fragment stage `fs`, reading a
    /// vertex buffer of `attributes` per vertex ([`per_vertex`]).
    pub fn of_vertices(vs: &'a str, fs: &'a str, attributes: &'a [wgpu::VertexAttribute]) -> Self {
        Raster {
            vs,
            fs,
            vertex: per_vertex(attributes),
            ..Raster::default()
        }
    }
}

impl Default for Raster<'_> {
    fn default() -> Self {
        Raster {
            vs: "vs",
            fs: "fs",
            vertex: None,
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull: None,
            depth: Some(wgpu::CompareFunction::Less),
            depth_format: wgpu::TextureFormat::Depth32Float,
            stencil: wgpu::StencilState::default(),
            depth_write: true,
            color: None,
            instrument: None,
        }
    }
}

/// A vertex buffer read per vertex whose records are `attributes` packed in order (the stride
/// is where the last one ends), for [`Raster::vertex`].
pub fn per_vertex(
    attributes: &[wgpu::VertexAttribute],
) -> Option<(u64, wgpu::VertexStepMode, &[wgpu::VertexAttribute])> {
    let stride = attributes.last().map_or(0, |a| a.offset + a.format.size());
    Some((stride, wgpu::VertexStepMode::Vertex, attributes))
}

/// The override constants of a pipeline: `INSTRUMENT` when given.
fn overrides(instrument: Option<bool>) -> Vec<(&'static str, f64)> {
    instrument
        .map(|on| ("INSTRUMENT", f64::from(u8::from(on))))
        .into_iter()
        .collect()
}

impl Program {
    /// The module joined from `sources` (a prelude first, then the execution's WGSL, then any
    /// WGSL it appends), with a pipeline layout of `groups` (a `None` leaves a group number
    /// unused). Both are made once per device ([`super::cache`]: the module keyed by its text, the
    /// layout by its groups); `label` is the first maker's.
    pub fn new(gpu: &Gpu, label: &str, sources: &[&str], groups: &[Option<&Layout>]) -> Program {
        static MODULES: AtomicU64 = AtomicU64::new(0);
        let device = &gpu.device;
        let source = sources.join("\n");
        let (number, module) = gpu.cache.get(Kind::Module, source.clone(), || {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            (MODULES.fetch_add(1, Ordering::Relaxed), module)
        });
        let layout_key = groups
            .iter()
            .map(|g| g.map_or("-", |l| l.key.as_str()))
            .collect::<Vec<_>>()
            .join("|");
        let layout = gpu.cache.get(Kind::PipelineLayout, layout_key.clone(), || {
            let layouts: Vec<_> = groups.iter().map(|g| g.map(|l| &l.layout)).collect();
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &layouts,
                immediate_size: 0,
            })
        });
        Program {
            module,
            layout,
            key: format!("module {number} layout {layout_key}"),
        }
    }

    /// The compute pipeline of `entry`, with `INSTRUMENT` set where given; made once per
    /// device ([`super::cache`]).
    pub fn compute(
        &self,
        gpu: &Gpu,
        entry: &str,
        instrument: Option<bool>,
    ) -> wgpu::ComputePipeline {
        let key = format!("{} {entry} {instrument:?}", self.key);
        gpu.cache.get(Kind::ComputePipeline, key, || {
            let constants = overrides(instrument);
            gpu.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&self.layout),
                    module: &self.module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    cache: gpu.cache.driver.as_ref(),
                })
        })
    }

    /// The compute pipeline of `entry` in both runs of a pass: `INSTRUMENT` off in the timed
    /// run, on in the instrumented replay.
    pub fn instrumented(&self, gpu: &Gpu, entry: &str) -> Compute {
        Instrumented {
            timed: Some(self.compute(gpu, entry, Some(false))),
            counting: Some(self.compute(gpu, entry, Some(true))),
        }
    }

    /// Render pipeline `r` in both runs of a pass: `INSTRUMENT` off in the timed run, on in the
    /// instrumented replay.
    pub fn render_instrumented(&self, gpu: &Gpu, r: &Raster) -> Render {
        let with = |on| {
            let r = Raster {
                instrument: Some(on),
                ..r.clone()
            };
            self.render(gpu, &r)
        };
        Instrumented {
            timed: Some(with(false)),
            counting: Some(with(true)),
        }
    }

    /// The render pipeline `r`; made once per device ([`super::cache`]).
    pub fn render(&self, gpu: &Gpu, r: &Raster) -> wgpu::RenderPipeline {
        let key = format!("{} {r:?}", self.key);
        gpu.cache
            .get(Kind::RenderPipeline, key, || self.make_render(gpu, r))
    }

    fn make_render(&self, gpu: &Gpu, r: &Raster) -> wgpu::RenderPipeline {
        let constants = overrides(r.instrument);
        let buffers: Vec<_> = r
            .vertex
            .iter()
            .map(|&(array_stride, step_mode, attributes)| {
                Some(wgpu::VertexBufferLayout {
                    array_stride,
                    step_mode,
                    attributes,
                })
            })
            .collect();
        let targets = [r.color.clone()];
        gpu.device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(r.fs),
                layout: Some(&self.layout),
                vertex: wgpu::VertexState {
                    module: &self.module,
                    entry_point: Some(r.vs),
                    compilation_options: Default::default(),
                    buffers: &buffers,
                },
                primitive: wgpu::PrimitiveState {
                    topology: r.topology,
                    cull_mode: r.cull,
                    ..Default::default()
                },
                depth_stencil: r.depth.map(|compare| wgpu::DepthStencilState {
                    format: r.depth_format,
                    depth_write_enabled: Some(r.depth_write),
                    depth_compare: Some(compare),
                    stencil: r.stencil.clone(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &self.module,
                    entry_point: Some(r.fs),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    targets: if r.color.is_some() { &targets } else { &[] },
                }),
                multiview_mask: None,
                cache: gpu.cache.driver.as_ref(),
            })
    }
}

/// What a pass does.
#[derive(Clone)]
pub enum Work<'a> {
    /// Compute dispatches in order: a pipeline and its workgroup counts (x, y); one with no
    /// workgroups in x is skipped.
    Dispatch(Vec<(&'a Compute, (u32, u32))>),
    /// One draw into cleared targets.
    Draw(Draw<'a>),
    /// Draws onto kept targets.
    Onto(Onto<'a>),
}

/// What a pass onto a kept depth target ([`Onto`]) does with its stencil.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stencil {
    /// No stencil: the depth is only read.
    Off,
    /// The stencil (Depth32FloatStencil8) as earlier passes left it.
    Keep,
    /// The stencil cleared to this value first.
    Clear(u32),
}

/// Draws of vertex ranges of one buffer onto a colour target cleared to `clear` (red; the
/// other channels 0) or, when `None`, kept as earlier passes drew it (accumulation by
/// blending), each with its own pipeline and stencil reference, testing against a depth target
/// that earlier passes drew and these only read (the pipelines' `depth_write` off), with its
/// [`Stencil`]: a shadow-volume count or an accumulation pass; the two-pass culling of a wedge
/// half (paper 001 IV §4.4) draws its front faces setting the stencil, then its back faces
/// testing it; a stencil shadow-volume pass increments and decrements it, and a later pass
/// shades where it is 0.
#[derive(Clone)]
pub struct Onto<'a> {
    pub color: &'a wgpu::TextureView,
    pub clear: Option<f64>,
    pub depth: Option<&'a wgpu::TextureView>,
    pub stencil: Stencil,
    /// The vertex buffer, if the pipelines read one.
    pub vertices: Option<&'a wgpu::Buffer>,
    /// The pipelines the draws use (at least one).
    pub pipelines: &'a [Render],
    /// Pipeline (index into `pipelines`), vertex range and stencil reference of each draw, in
    /// order.
    pub draws: Vec<(usize, std::ops::Range<u32>, u32)>,
}

impl<'a> Onto<'a> {
    /// The draws `draws` of `pipelines` onto `color`, cleared to `clear` or kept, with no depth
    /// target, stencil or vertex buffer (which a pass sets by struct update).
    pub fn new(
        pipelines: &'a [Render],
        draws: Vec<(usize, std::ops::Range<u32>, u32)>,
        color: &'a wgpu::TextureView,
        clear: Option<f64>,
    ) -> Onto<'a> {
        Onto {
            color,
            clear,
            depth: None,
            stencil: Stencil::Off,
            vertices: None,
            pipelines,
            draws,
        }
    }
}

/// A draw: `count` vertices (or indices, with an index buffer) times `instances`, into a colour
/// target cleared to 0 and a depth target cleared to 1.
#[derive(Clone)]
pub struct Draw<'a> {
    pub pipeline: &'a Render,
    pub color: Option<&'a wgpu::TextureView>,
    pub depth: Option<&'a wgpu::TextureView>,
    pub vertices: Option<&'a wgpu::Buffer>,
    /// A `u32` index buffer.
    pub indices: Option<&'a wgpu::Buffer>,
    pub count: u32,
    pub instances: u32,
}

impl<'a> Draw<'a> {
    /// One instance of `count` vertices drawn with `pipeline`, with no target, vertex or index
    /// buffer (which a draw sets by struct update).
    pub fn of(pipeline: &'a Render, count: u32) -> Draw<'a> {
        Draw {
            pipeline,
            color: None,
            depth: None,
            vertices: None,
            indices: None,
            count,
            instances: 1,
        }
    }
}

/// One GPU pass: its label, its bind groups (group `i` at index `i`; `None` leaves one unset)
/// and its work.
#[derive(Clone)]
pub struct Pass<'a> {
    pub label: &'a str,
    pub groups: Vec<Option<&'a wgpu::BindGroup>>,
    pub work: Work<'a>,
}

/// Workgroups covering `size` with square workgroups of side `side`.
pub fn tiles(size: (u32, u32), side: u32) -> (u32, u32) {
    (size.0.div_ceil(side), size.1.div_ceil(side))
}

/// Workgroups for `n` in a 2D grid whose sides are within the adapter's limit: as few rows as
/// the limit allows, then as few columns as cover `n` (under one row of workgroups beyond it).
pub fn workgroups(gpu: &Gpu, n: u32) -> (u32, u32) {
    if n == 0 {
        return (0, 0);
    }
    let y = n.div_ceil(gpu.limits.max_compute_workgroups_per_dimension);
    (n.div_ceil(y), y)
}

/// A pass's bind groups: group `i` at index `i`; `None` leaves one unset.
pub type Groups<'a> = [Option<&'a wgpu::BindGroup>];

impl<'a> Pass<'a> {
    /// A pass of `work` with the bind groups `groups`.
    fn new(label: &'a str, groups: &Groups<'a>, work: Work<'a>) -> Pass<'a> {
        Pass {
            label,
            groups: groups.to_vec(),
            work,
        }
    }

    /// A compute pass of one dispatch.
    pub fn compute(
        label: &'a str,
        groups: &Groups<'a>,
        pipeline: &'a Compute,
        workgroups: (u32, u32),
    ) -> Pass<'a> {
        Pass::new(label, groups, Work::Dispatch(vec![(pipeline, workgroups)]))
    }

    /// A render pass of one draw.
    pub fn draw(label: &'a str, groups: &Groups<'a>, draw: Draw<'a>) -> Pass<'a> {
        Pass::new(label, groups, Work::Draw(draw))
    }

    /// A render pass of draws onto kept targets.
    pub fn onto(label: &'a str, groups: &Groups<'a>, onto: Onto<'a>) -> Pass<'a> {
        Pass::new(label, groups, Work::Onto(onto))
    }

    /// The descriptor of a render pass onto `colors` and `depth`, kept by earlier passes.
    fn kept<'p>(
        &self,
        colors: &'p [Option<wgpu::RenderPassColorAttachment<'p>>],
        depth: Option<wgpu::RenderPassDepthStencilAttachment<'p>>,
    ) -> wgpu::RenderPassDescriptor<'p>
    where
        'a: 'p,
    {
        wgpu::RenderPassDescriptor {
            label: Some(self.label),
            color_attachments: colors,
            depth_stencil_attachment: depth,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        }
    }

    /// The body of a render pass: statistics begun (pass `index`) when `stats` is given, the
    /// pipeline, the pass's bind groups and vertex buffer set, `draw`, statistics ended.
    fn draw_in(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        stats: Option<&PassStats>,
        index: u32,
        pipeline: &wgpu::RenderPipeline,
        vertices: Option<&wgpu::Buffer>,
        draw: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) {
        if let Some(s) = stats {
            s.begin_render(pass, index);
        }
        pass.set_pipeline(pipeline);
        for (i, g) in self.groups.iter().enumerate() {
            if let Some(g) = g {
                pass.set_bind_group(i as u32, *g, &[]);
            }
        }
        if let Some(v) = vertices {
            pass.set_vertex_buffer(0, v.slice(..));
        }
        draw(pass);
        if stats.is_some() {
            pass.end_pipeline_statistics_query();
        }
    }

    /// Whether the pass runs in the instrumented replay (`counting`) or in the timed run: its
    /// pipelines have that variant ([`Instrumented`]; a compute pass: one of its dispatches).
    pub fn runs_in(&self, counting: bool) -> bool {
        match &self.work {
            Work::Dispatch(d) => d.iter().any(|(p, _)| p.variant(counting).is_some()),
            Work::Draw(d) => d.pipeline.variant(counting).is_some(),
            Work::Onto(d) => d.pipelines.iter().all(|p| p.variant(counting).is_some()),
        }
    }

    /// Records the pass with its pipelines' variant of the replay (`counting`) or of the timed
    /// run ([`Self::runs_in`] must hold; a dispatch without the variant is left out), timed as
    /// `timer`'s pass `index` and with its statistics in `stats` when given.
    pub(super) fn record(
        &self,
        e: &mut wgpu::CommandEncoder,
        (timer, stats, index): (Option<&PassTimer>, Option<&PassStats>, u32),
        counting: bool,
    ) {
        let timed = timer.map(|t| (t, index));
        let variant = |p: &'a Render| p.variant(counting).expect("the pass runs in this run");
        match &self.work {
            Work::Dispatch(dispatches) => {
                let mut pass = timing::compute_pass(e, self.label, timed);
                if let Some(s) = stats {
                    s.begin_compute(&mut pass, index);
                }
                for (i, g) in self.groups.iter().enumerate() {
                    if let Some(g) = g {
                        pass.set_bind_group(i as u32, *g, &[]);
                    }
                }
                for &(pipeline, (x, y)) in dispatches {
                    if let (true, Some(pipeline)) = (x > 0, pipeline.variant(counting)) {
                        pass.set_pipeline(pipeline);
                        pass.dispatch_workgroups(x, y, 1);
                    }
                }
                if stats.is_some() {
                    pass.end_pipeline_statistics_query();
                }
            }
            Work::Draw(d) => {
                let color = d.color.map(|view| wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                });
                let colors = [color];
                let desc = wgpu::RenderPassDescriptor {
                    label: Some(self.label),
                    color_attachments: if d.color.is_some() { &colors } else { &[] },
                    depth_stencil_attachment: d.depth.map(|view| {
                        wgpu::RenderPassDepthStencilAttachment {
                            view,
                            depth_ops: Some(wgpu::Operations {
                                load: wgpu::LoadOp::Clear(1.0),
                                store: wgpu::StoreOp::Store,
                            }),
                            stencil_ops: None,
                        }
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                };
                let draw = |pass: &mut wgpu::RenderPass<'_>| match d.indices {
                    Some(i) => {
                        pass.set_index_buffer(i.slice(..), wgpu::IndexFormat::Uint32);
                        pass.draw_indexed(0..d.count, 0, 0..d.instances);
                    }
                    None => pass.draw(0..d.count, 0..d.instances),
                };
                let mut pass = timing::render_pass(e, desc, timed);
                self.draw_in(
                    &mut pass,
                    stats,
                    index,
                    variant(d.pipeline),
                    d.vertices,
                    draw,
                );
            }
            Work::Onto(d) => {
                let colors = [Some(kept_color(d.color, d.clear))];
                let stencil_ops = |load| {
                    Some(wgpu::Operations {
                        load,
                        store: wgpu::StoreOp::Store,
                    })
                };
                let depth = d.depth.map(|view| wgpu::RenderPassDepthStencilAttachment {
                    view,
                    depth_ops: None,
                    stencil_ops: match d.stencil {
                        Stencil::Off => None,
                        Stencil::Keep => stencil_ops(wgpu::LoadOp::Load),
                        Stencil::Clear(s) => stencil_ops(wgpu::LoadOp::Clear(s)),
                    },
                });
                let desc = self.kept(&colors, depth);
                let mut pass = timing::render_pass(e, desc, timed);
                let draw = |pass: &mut wgpu::RenderPass<'_>| {
                    let mut bound = 0;
                    for (pipeline, range, reference) in &d.draws {
                        if *pipeline != bound {
                            pass.set_pipeline(variant(&d.pipelines[*pipeline]));
                            bound = *pipeline;
                        }
                        if d.stencil != Stencil::Off {
                            pass.set_stencil_reference(*reference);
                        }
                        pass.draw(range.clone(), 0..1);
                    }
                };
                let first = variant(&d.pipelines[0]);
                self.draw_in(&mut pass, stats, index, first, d.vertices, draw);
            }
        }
    }
}

/// A colour attachment of `view` cleared to `clear` (red; the other channels 0), or kept.
fn kept_color(view: &wgpu::TextureView, clear: Option<f64>) -> wgpu::RenderPassColorAttachment<'_> {
    let load = match clear {
        Some(r) => wgpu::LoadOp::Clear(wgpu::Color {
            r,
            g: 0.0,
            b: 0.0,
            a: 0.0,
        }),
        None => wgpu::LoadOp::Load,
    };
    wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load,
            store: wgpu::StoreOp::Store,
        },
    }
}

/// Which pipeline statistics a run's phases take from its passes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Statistics {
    /// None are queried.
    Off,
    /// Every statistic of every pass (`pipeline.*`).
    All,
    /// Compute-shader invocations only (compute passes: the graphics statistics are zero).
    Compute,
}

/// The timed submissions of a run, each pass belonging to one of the run's phases, plus host
/// work timed into phases. The number of passes is what was submitted: each submission carries
/// its own timestamp and statistics queries (resolved in it), and the readback is copied to the
/// host in a submission of its own when the run finishes ([`Timed::finish`]).
pub struct Timed<'g, 'b> {
    gpu: &'g Run,
    timers: Vec<PassTimer>,
    stats: Vec<PassStats>,
    statistics: Statistics,
    phase_of_pass: Vec<usize>,
    names: Vec<String>,
    wall: Vec<f64>,
    readback: Vec<(&'b wgpu::Buffer, Staging)>,
    /// The buffer the replay counts into and when it is read.
    counts: Option<(&'b wgpu::Buffer, Readout)>,
    /// Each submission's phase and its passes that run in the replay, in order.
    replayed: Vec<(usize, Vec<Pass<'b>>)>,
    /// The plan as run: each pass's phase, label and runs (`execution.passes`).
    plan: Vec<String>,
}

/// The index of `phase` in a run's phase `names` (with their `wall` times): a phase not among
/// them is added after them, with no time yet.
fn phase_index(names: &mut Vec<String>, wall: &mut Vec<f64>, phase: impl PhaseId) -> usize {
    let name = phase.name();
    names.iter().position(|n| n == name).unwrap_or_else(|| {
        names.push(name.to_string());
        wall.push(0.0);
        names.len() - 1
    })
}

/// When an instrumented replay derived from a run ([`Timed::counting_into`]) reads its counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Readout {
    /// Cleared before the first pass, read after the last: one reading.
    End,
    /// Cleared before each phase's passes and read after them: a reading per phase that has
    /// passes in the replay, in phase order.
    EachPhase,
}

impl<'g, 'b> Timed<'g, 'b> {
    /// A run in the phases `phases`, in order (a phase named later by [`Self::submit`] or
    /// [`Self::host`] comes after them); `readback` is copied to the host after its last pass
    /// (the visibility first).
    pub fn new(
        gpu: &'g Run,
        phases: &[impl PhaseId],
        statistics: Statistics,
        readback: &[&'b wgpu::Buffer],
    ) -> Timed<'g, 'b> {
        Timed {
            gpu,
            timers: Vec::new(),
            stats: Vec::new(),
            statistics,
            phase_of_pass: Vec::new(),
            names: phases.iter().map(|p| p.name().to_string()).collect(),
            wall: vec![0.0; phases.len()],
            readback: readback
                .iter()
                .map(|b| (*b, Staging::new(gpu, "readback", b.size())))
                .collect(),
            counts: None,
            replayed: Vec::new(),
            plan: Vec::new(),
        }
    }

    /// The run with its instrumented replay: every submitted pass that runs in the replay
    /// ([`Pass::runs_in`]), recorded again with its pipelines' counting variants after the timed
    /// run, a submission for each of the run's, counting into `counts`, cleared and read as
    /// `readout` says ([`Timing::counts`]).
    pub fn counting_into(mut self, counts: &'b wgpu::Buffer, readout: Readout) -> Self {
        self.counts = Some((counts, readout));
        self
    }

    /// The index of `phase` among the run's phases ([`phase_index`]).
    fn at(&mut self, phase: impl PhaseId) -> usize {
        phase_index(&mut self.names, &mut self.wall, phase)
    }

    /// Submits `passes` of phase `phase` and waits for them; their wall time goes to the phase.
    /// The submission resolves its own timestamp and statistics queries.
    pub fn submit(&mut self, phase: impl PhaseId, passes: &[Pass<'b>]) -> Result<()> {
        let phase = self.at(phase);
        if self.counts.is_some() {
            let counted: Vec<Pass<'b>> =
                passes.iter().filter(|p| p.runs_in(true)).cloned().collect();
            if !counted.is_empty() {
                self.replayed.push((phase, counted));
            }
        }
        self.submit_at(phase, passes)
    }

    /// Submits the passes of `passes` that run in the timed run, as [`Self::submit`] does, and
    /// keeps none for a derived replay: for an execution whose replay is built by hand
    /// ([`replay`]; `soft_shadow_volume`, which reads its counts per loop).
    pub fn submit_timed(&mut self, phase: impl PhaseId, passes: &[Pass]) -> Result<()> {
        let phase = self.at(phase);
        self.submit_at(phase, passes)
    }

    /// [`Self::submit_timed`] of the run's phase `phase` (an index).
    fn submit_at(&mut self, phase: usize, passes: &[Pass]) -> Result<()> {
        for p in passes {
            let runs = match (p.runs_in(false), p.runs_in(true)) {
                (true, true) => "timed, replayed",
                (true, false) => "timed",
                _ => "replayed",
            };
            let name = &self.names[phase];
            self.plan.push(format!("{name}: {} ({runs})", p.label));
        }
        let passes: Vec<&Pass> = passes.iter().filter(|p| p.runs_in(false)).collect();
        if passes.is_empty() {
            return Ok(());
        }
        let n = passes.len() as u32;
        let timer = PassTimer::new(self.gpu, n);
        let stats = (self.statistics != Statistics::Off)
            .then(|| PassStats::new(self.gpu, n))
            .flatten();
        if let Some(t) = &timer {
            t.in_submission(0..n, self.gpu.next_submission());
        }
        let wall = self.gpu.submit(|e| {
            for (k, p) in (0..).zip(&passes) {
                p.record(e, (timer.as_ref(), stats.as_ref(), k), false);
            }
            resolve_queries(e, timer.as_ref(), stats.as_ref());
        })?;
        self.timers.extend(timer);
        self.stats.extend(stats);
        self.wall[phase] += wall;
        self.phase_of_pass.extend(passes.iter().map(|_| phase));
        Ok(())
    }

    /// Adds `ms` of host work measured elsewhere to phase `phase`.
    pub fn add_wall(&mut self, phase: impl PhaseId, ms: f64) {
        let phase = self.at(phase);
        self.wall[phase] += ms;
    }

    /// Adds the host time since `start` to phase `phase`, less the creation of the run's
    /// pipelines and layouts (the run's GPU setup, reported apart).
    pub fn add_setup(&mut self, phase: impl PhaseId, start: Instant) {
        let phase = self.at(phase);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        self.wall[phase] += ms - self.gpu.cache.run_objects_ms();
    }

    /// Runs host work `f` as part of phase `phase` (its wall time goes to the phase).
    pub fn host<T>(&mut self, phase: impl PhaseId, f: impl FnOnce() -> T) -> T {
        let phase = self.at(phase);
        let start = Instant::now();
        let out = f();
        self.wall[phase] += start.elapsed().as_secs_f64() * 1e3;
        out
    }

    /// Copies the readback buffers to the host after the run's last pass and reads them, the
    /// pass times (checked, [`timing`]) and the statistics.
    ///
    /// Errors: [`Error::Gpu`] when no pass was submitted (nothing wrote the readback buffers:
    /// the image would be zeros), and the device's errors.
    pub fn finish(self) -> Result<Timing<'g>> {
        let gpu = self.gpu;
        if self.phase_of_pass.is_empty() {
            return Err(Error::Gpu(format!(
                "the run of phases {:?} submitted no GPU pass: its readback is never written",
                self.names
            )));
        }
        let start = Instant::now();
        gpu.submit(|e| {
            for (b, s) in &self.readback {
                s.copy(e, b);
            }
        })?;
        let readback = self
            .readback
            .iter()
            .map(|(_, s)| s.read(gpu))
            .collect::<Result<Vec<_>>>()?;
        let readback_ms = start.elapsed().as_secs_f64() * 1e3;
        let mut warnings = Vec::new();
        let times = read_ms_or_warn(gpu, &self.timers, &mut warnings)?;
        let stats = match self.statistics {
            Statistics::Off => None,
            _ => read_or_warn(gpu, &self.stats, &mut warnings)?,
        };
        let counts = match self.counts {
            Some((buffer, readout)) => replay(gpu, &replay_steps(buffer, readout, self.replayed))?,
            None => Vec::new(),
        };
        Ok(Timing {
            counts,
            plan: self.plan,
            gpu,
            names: self.names,
            wall: self.wall,
            phase_of_pass: self.phase_of_pass,
            statistics: self.statistics,
            times,
            stats,
            readback,
            readback_ms,
            warnings,
        })
    }
}

/// What the timed submissions gave: buffers read back, times, statistics, warnings.
pub struct Timing<'g> {
    gpu: &'g Run,
    names: Vec<String>,
    wall: Vec<f64>,
    phase_of_pass: Vec<usize>,
    statistics: Statistics,
    pub times: GpuTimes,
    stats: Option<Vec<Counters>>,
    /// The readback buffers' bytes, in the order given to [`Timed::new`].
    pub readback: Vec<Vec<u8>>,
    /// The bytes of the counting buffer after the derived replay ([`Timed::counting_into`]):
    /// one reading, or one per phase; zeros with the run's counters off, none without a replay.
    pub counts: Vec<Vec<u8>>,
    plan: Vec<String>,
    readback_ms: f64,
    pub warnings: Vec<String>,
}

/// The steps of the replay derived from a run's `replayed` submissions (phase, passes),
/// counting into `counts` read as `readout` says.
fn replay_steps<'b>(
    counts: &'b wgpu::Buffer,
    readout: Readout,
    replayed: Vec<(usize, Vec<Pass<'b>>)>,
) -> Vec<Step<'b>> {
    let mut steps = vec![Step::Clear(counts)];
    let mut phase = replayed.first().map(|r| r.0);
    for (p, passes) in replayed {
        if readout == Readout::EachPhase && phase != Some(p) {
            steps.extend([Step::Read(counts), Step::Clear(counts)]);
            phase = Some(p);
        }
        steps.push(Step::Submit(passes));
    }
    steps.push(Step::Read(counts));
    steps
}

impl Timing<'_> {
    /// The frame output: the visibility (the first readback buffer, `width`×`height`), one
    /// phase per phase of the run with its `counters` (none where `counters` do not name it) and
    /// the pipeline statistics of its passes, the counters of all phases summed, the GPU time of all passes, and in `execution` the
    /// adapter, how the GPU time was obtained, the readback time and `note` (how the counters
    /// were obtained).
    ///
    /// With the run's counters off ([`GpuCounters::Off`]: no instrumented replay) `counters`
    /// are left out, since they were derived from the skipped replay (alone or with host
    /// figures): `execution.gpu_counters` is `"off"` and `execution.gpu_counters_absent` names
    /// them. The pipeline statistics of the timed passes stay.
    pub fn output<P: PhaseId>(
        mut self,
        (width, height): (u32, u32),
        counters: Vec<(P, Counters)>,
        note: &str,
    ) -> FrameOutput {
        let at: Vec<(usize, Counters)> = (counters.into_iter())
            .map(|(p, c)| (phase_index(&mut self.names, &mut self.wall, p), c))
            .collect();
        let mut counters = vec![Counters::default(); self.names.len()];
        for (i, c) in at {
            counters[i].merge(&c);
        }
        let off = self.gpu.counters() == GpuCounters::Off;
        let absent: std::collections::BTreeSet<String> = match off {
            true => counters.iter().flat_map(|c| c.0.keys().cloned()).collect(),
            false => Default::default(),
        };
        let counters = match off {
            true => vec![Counters::default(); counters.len()],
            false => counters,
        };
        let mut phases: Vec<Phase> = self
            .names
            .iter()
            .zip(counters)
            .zip(&self.wall)
            .enumerate()
            .map(|(i, ((name, counters), &wall_ms))| {
                let passes = || {
                    self.phase_of_pass
                        .iter()
                        .enumerate()
                        .filter(move |p| *p.1 == i)
                };
                Phase {
                    name: name.clone(),
                    wall_ms,
                    model_ms: None,
                    gpu_ms: match (&self.times.ms, passes().next()) {
                        (Some(t), Some(_)) => Some(passes().map(|(k, _)| t[k]).sum()),
                        _ => None,
                    },
                    counters,
                }
            })
            .collect();
        if let Some(stats) = &self.stats {
            for (s, &phase) in stats.iter().zip(&self.phase_of_pass) {
                let c = &mut phases[phase].counters;
                match self.statistics {
                    Statistics::All => c.merge(s),
                    _ => {
                        if let Some(v) = s.get(COMPUTE_INVOCATIONS) {
                            c.add(COMPUTE_INVOCATIONS, v);
                        }
                    }
                }
            }
        }
        let mut total = Counters::default();
        for p in &phases {
            total.merge(&p.counters);
        }
        let mut execution = self.gpu.execution();
        self.times.record(&mut execution);
        execution.insert("readback_ms".into(), serde_json::json!(self.readback_ms));
        execution.insert("passes".into(), serde_json::json!(self.plan));
        if off {
            execution.insert("gpu_counters".into(), serde_json::json!("off"));
            execution.insert("gpu_counters_absent".into(), serde_json::json!(absent));
        } else {
            execution.insert("gpu_counters".into(), serde_json::json!(note));
        }
        FrameOutput {
            visibility: VisibilityBuffer {
                width,
                height,
                data: words(&self.readback[0]),
            },
            counters: total,
            phases,
            model_ms: None,
            gpu_ms: self.times.ms.as_ref().map(|t| t.iter().sum()),
            execution,
            warnings: self.warnings,
            rgb: None,
            gpu_setup_ms: None,
        }
    }
}

impl Timing<'_> {
    /// Readback buffer `i`, if there is one, as the light received per channel (three `f32` a
    /// pixel) of a `width`×`height` image.
    pub fn rgb(&self, i: usize, (width, height): (u32, u32)) -> Option<RgbBuffer> {
        let data = words(self.readback.get(i)?);
        Some(RgbBuffer {
            width,
            height,
            data,
        })
    }
}

/// One step of an instrumented replay.
pub enum Step<'a> {
    /// Zero a counting buffer (at the start of the next submission).
    Clear(&'a wgpu::Buffer),
    /// Submit passes (untimed, with their counting variants; a pass without one is left out).
    Submit(Vec<Pass<'a>>),
    /// Copy a buffer to the host (its bytes come back in step order).
    Read(&'a wgpu::Buffer),
}

/// Runs `steps` and returns the bytes of every [`Step::Read`] in order. Each read's copy is a
/// submission of its own: on lavapipe a copy recorded after a render pass in the same
/// submission reads the buffer before that pass's fragment-shader atomics land (a following
/// compute pass or submission sees them), which made an instrumented replay of draws whose
/// fragment shader counts read back zero.
///
/// With the run's counters off ([`GpuCounters::Off`]) nothing is submitted and every read
/// comes back as zeros of its buffer's size: what the execution derives from them never reaches
/// the record ([`Timing::output`] leaves the counters out).
pub fn replay(gpu: &Run, steps: &[Step]) -> Result<Vec<Vec<u8>>> {
    let mut reads = Vec::new();
    if gpu.counters() == GpuCounters::Off {
        for s in steps {
            if let Step::Read(b) = s {
                reads.push(vec![0; b.size() as usize]);
            }
        }
        return Ok(reads);
    }
    let mut clears: Vec<&wgpu::Buffer> = Vec::new();
    for s in steps {
        match s {
            Step::Clear(b) => clears.push(b),
            Step::Submit(passes) => {
                gpu.submit(|e| {
                    for b in clears.drain(..) {
                        e.clear_buffer(b, 0, None);
                    }
                    for p in passes.iter().filter(|p| p.runs_in(true)) {
                        p.record(e, (None, None, 0), true);
                    }
                })?;
            }
            Step::Read(b) => {
                let staging = Staging::new(gpu, "counts readback", b.size());
                gpu.submit(|e| {
                    for b in clears.drain(..) {
                        e.clear_buffer(b, 0, None);
                    }
                    staging.copy(e, b);
                })?;
                reads.push(staging.read(gpu)?);
            }
        }
    }
    Ok(reads)
}

/// The instrumented replay of `passes` counting into `slots`, a buffer of 64-bit statistics
/// slots ((low, high) `u32` pairs): cleared before, read after.
pub fn replay_slots<'a>(
    gpu: &Run,
    slots: &'a wgpu::Buffer,
    passes: Vec<Pass<'a>>,
) -> Result<Slots> {
    let steps = [Step::Clear(slots), Step::Submit(passes), Step::Read(slots)];
    Ok(Slots::of(&replay(gpu, &steps)?[0]))
}

/// 64-bit statistics slots read back ((low, high) `u32` pairs).
pub struct Slots(Vec<u32>);

impl Slots {
    /// The slots of a statistics buffer read back ([`replay`]'s bytes of it).
    pub fn of(bytes: &[u8]) -> Slots {
        Slots(words(bytes))
    }

    /// Slot `i` as a figure.
    pub fn get(&self, i: usize) -> f64 {
        slot64(&self.0, i)
    }
}

/// The 64-bit statistics slot `i` of a buffer of (low, high) `u32` pairs, as a figure.
pub fn slot64(raw: &[u32], i: usize) -> f64 {
    (u64::from(raw[2 * i + 1]) << 32 | u64::from(raw[2 * i])) as f64
}
