//! The wgpu execution's device: one headless adapter and device per process, shared by every
//! run, plus the pieces every GPU algorithm needs (timestamps, pipeline statistics, readback).
//!
//! The adapter is the best one found (discrete > integrated > virtual > other > CPU, then
//! native APIs before GL), unless `SHADOWBENCH_ADAPTER` or `--adapter` names one (a
//! case-insensitive substring of its name). On a machine with no GPU this is Mesa's software
//! Vulkan driver (llvmpipe). With no adapter at all, [`gpu`] returns an error that says why, so
//! the harness can skip the wgpu execution and go on with the others.
//!
//! A device lost in the middle of a sweep fails the run it happened in (with the driver's
//! reason); the next wgpu run acquires a new device, and the other executions never notice.
//! [`fault`] injects such faults on purpose, for the robustness tests.

pub mod cache;
pub mod fault;
pub mod meshes;
pub mod pass;
mod probe;

pub mod readback;
pub mod stats;
pub mod timing;
#[cfg(test)]
pub(crate) mod wgsl_layout;

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex, OnceLock};

use wgpu::util::DeviceExt;

use crate::error::{Error, Result};
use crate::frame::{FrameOutput, GBuffer};
use crate::util::deadline::Deadline;

/// What [`Gpu::upload`] makes of empty data: bytes enough for one record of any kind the
/// passes read.
pub const EMPTY_BYTES: usize = 128;

/// Environment variable naming the adapter to use (substring of its name).
pub const ADAPTER_ENV: &str = "SHADOWBENCH_ADAPTER";

/// A colour target of `format` that adds each fragment's value to what it holds, every channel
/// (`One + One`): sums accumulated by blending (a V-buffer per channel, split 12-bit digits).
pub fn additive(format: wgpu::TextureFormat) -> wgpu::ColorTargetState {
    let add = wgpu::BlendComponent {
        src_factor: wgpu::BlendFactor::One,
        dst_factor: wgpu::BlendFactor::One,
        operation: wgpu::BlendOperation::Add,
    };
    wgpu::ColorTargetState {
        format,
        blend: Some(wgpu::BlendState {
            color: add,
            alpha: add,
        }),
        write_mask: wgpu::ColorWrites::ALL,
    }
}

/// [`additive`] into the red channel only: counts and sums of one value.
pub fn additive_red(format: wgpu::TextureFormat) -> wgpu::ColorTargetState {
    wgpu::ColorTargetState {
        write_mask: wgpu::ColorWrites::RED,
        ..additive(format)
    }
}

/// A colour target of `format` that the pipeline does not write (a pass that only counts its
/// fragments, or only marks the stencil).
pub fn unwritten(format: wgpu::TextureFormat) -> wgpu::ColorTargetState {
    wgpu::ColorTargetState {
        format,
        blend: None,
        write_mask: wgpu::ColorWrites::empty(),
    }
}

/// A stencil test (both faces, all 8 bits) of `compare` against the reference, writing `pass`
/// where the fragment passes it and the depth test and `other` where it fails either: a stencil
/// shadow-volume count (`Always`, increment or decrement, `Keep`), a pass shading where the
/// count is 0 (`Equal`, `Keep`, `Keep`), a mark (`Always`, `Replace`, `Keep`) and a test that
/// clears every mark it covers (`Equal`, `Zero`, `Zero`).
pub fn stencil_test(
    compare: wgpu::CompareFunction,
    pass: wgpu::StencilOperation,
    other: wgpu::StencilOperation,
) -> wgpu::StencilState {
    let face = wgpu::StencilFaceState {
        compare,
        fail_op: other,
        depth_fail_op: other,
        pass_op: pass,
    };
    wgpu::StencilState {
        front: face,
        back: face,
        read_mask: 0xff,
        write_mask: 0xff,
    }
}

/// The query features this crate asks for, and whether the adapter offered them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryFeatures {
    pub timestamp: bool,
    pub timestamp_inside_passes: bool,
    pub pipeline_statistics: bool,
}

impl QueryFeatures {
    fn of(f: wgpu::Features) -> QueryFeatures {
        QueryFeatures {
            timestamp: f.contains(wgpu::Features::TIMESTAMP_QUERY),
            timestamp_inside_passes: f.contains(
                wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES,
            ),
            pipeline_statistics: f.contains(wgpu::Features::PIPELINE_STATISTICS_QUERY),
        }
    }

    fn features(self) -> wgpu::Features {
        let mut f = wgpu::Features::empty();
        if self.timestamp {
            f |= wgpu::Features::TIMESTAMP_QUERY;
        }
        if self.timestamp_inside_passes {
            f |= wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES;
        }
        if self.pipeline_statistics {
            f |= wgpu::Features::PIPELINE_STATISTICS_QUERY;
        }
        f
    }

    /// Names of the available query features, for `list` and the records.
    pub fn names(self) -> Vec<&'static str> {
        [
            (self.timestamp, "TIMESTAMP_QUERY"),
            (
                self.timestamp_inside_passes,
                "TIMESTAMP_QUERY_INSIDE_PASSES",
            ),
            (self.pipeline_statistics, "PIPELINE_STATISTICS_QUERY"),
        ]
        .into_iter()
        .filter_map(|(on, name)| on.then_some(name))
        .collect()
    }
}

/// What a run needs of the adapter, checked by [`Gpu::check_limits`] before anything is
/// allocated; a zero (the default) asks nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Needs<'a> {
    /// The side of the largest square texture (a map's `map_resolution`).
    pub texture: u32,
    /// Storage buffers bound in one shader stage.
    pub storage_buffers: u32,
    /// Invocations of the largest compute workgroup (all in x).
    pub workgroup: u32,
    /// The storage buffers bound whole: name and bytes.
    pub buffers: &'a [(&'a str, u64)],
}

/// The shared device.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// Query features enabled on `device` (all the adapter offered of the three).
    pub queries: QueryFeatures,
    pub limits: wgpu::Limits,
    /// Why the device was lost, once the driver says it was.
    lost: Arc<Mutex<Option<String>>>,
    /// Whether R32Float (and the other 32-bit float formats) can be blended into
    /// (`FLOAT32_BLENDABLE`, requested when the adapter offers it): additive FP32 accumulation
    /// in render passes (soft shadow maps).
    pub float32_blendable: bool,
    /// Whether the combined Depth32FloatStencil8 format is available (`DEPTH32FLOAT_STENCIL8`,
    /// requested when the adapter offers it): the stencil test of soft shadow volumes' wedge-half
    /// culling (paper 001 IV §4.4) over the same f32 depth as the shadow-volume passes.
    pub depth32_stencil8: bool,
    /// The modules, layouts and pipelines made on this device, reused by every run.
    pub cache: cache::Cache,
    /// How the device rounds additive blends into half floats, once probed
    /// ([`Gpu::half_blend_sums`]).
    half_blend: OnceLock<[f32; 2]>,
}

/// Whether a wgpu run makes its instrumented replay (`--gpu-counters`, the run context's
/// `gpu_counters`): on, the counters the execution derives from the replay (fill, overdraw,
/// taps, ...) are recorded; off, the replay is skipped, those counters are absent (listed in
/// `execution.gpu_counters_absent`, never recorded as zero) and `execution.gpu_counters` is
/// `"off"`. Times, the image and the pipeline statistics of the timed passes are the same
/// either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GpuCounters {
    #[default]
    On,
    Off,
}

impl GpuCounters {
    /// The value of `--gpu-counters`: `on` or `off`.
    pub fn parse(s: &str) -> Option<GpuCounters> {
        match s {
            "on" => Some(GpuCounters::On),
            "off" => Some(GpuCounters::Off),
            _ => None,
        }
    }
}

impl Needs<'_> {
    /// A map of `resolution`² texels, and nothing else.
    pub fn map(resolution: u32) -> Self {
        Needs {
            texture: resolution,
            ..Needs::default()
        }
    }
}

impl Gpu {
    /// A buffer holding `data`. Zero-sized buffers cannot be bound, so empty data becomes
    /// [`EMPTY_BYTES`] zero bytes (at least one record of any kind a shader reads from it).
    /// Within a run, a pooled buffer of the same size and usage is refilled instead of a new
    /// one made ([`cache`]).
    pub fn upload<T: bytemuck::Pod>(
        &self,
        label: &str,
        data: &[T],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let contents = if bytes.is_empty() {
            &[0; EMPTY_BYTES]
        } else {
            bytes
        };
        // Buffer writes go in 4-byte words; other sizes are not pooled.
        if contents.len() % 4 != 0 {
            return self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                });
        }
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        let (buffer, reused) = self.cache.take_buffer((contents.len() as u64, usage), || {
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                })
        });
        if reused {
            self.queue.write_buffer(&buffer, 0, contents);
        }
        buffer
    }

    /// A zeroed storage buffer of `bytes` (at least one 4-byte word, rounded up to whole
    /// words), with `usage` besides `STORAGE`; within a run, a pooled one of the same size and
    /// usage, zeroed ([`cache`]).
    pub fn storage_buffer(
        &self,
        label: &str,
        bytes: u64,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let size = bytes.max(4).next_multiple_of(4);
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | usage;
        let (buffer, reused) = self.cache.take_buffer((size, usage), || {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        });
        if reused {
            self.queue.write_buffer(&buffer, 0, &vec![0; size as usize]);
        }
        buffer
    }

    /// A uniform buffer holding `value`.
    pub fn uniform<T: bytemuck::Pod>(&self, label: &str, value: &T) -> wgpu::Buffer {
        let data = std::slice::from_ref(value);
        self.upload(label, data, wgpu::BufferUsages::UNIFORM)
    }

    /// A `width`×`height` texture (one mip level, one sample) that passes render into and read
    /// from, with `usage` besides `RENDER_ATTACHMENT | TEXTURE_BINDING`.
    pub fn texture(
        &self,
        label: &str,
        (width, height): (u32, u32),
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | usage,
            view_formats: &[],
        })
    }

    /// A square `resolution`² map: [`Gpu::texture`].
    pub fn map_texture(
        &self,
        label: &str,
        resolution: u32,
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        self.texture(label, (resolution, resolution), format, usage)
    }

    /// A texture of `size` ([`Gpu::texture`], no further usage) and its view.
    pub fn target_view(
        &self,
        label: &str,
        size: (u32, u32),
        format: wgpu::TextureFormat,
    ) -> wgpu::TextureView {
        self.texture(label, size, format, wgpu::TextureUsages::empty())
            .create_view(&Default::default())
    }

    /// Fails ([`Error::Unsupported`]) where a run blends into R32Float (`blends`) and the
    /// adapter cannot (no `FLOAT32_BLENDABLE`), naming `instead` (the options that avoid it).
    pub fn check_float32_blend(&self, blends: bool, instead: &str) -> Result<()> {
        match !blends || self.float32_blendable {
            true => Ok(()),
            false => Err(Error::Unsupported(format!(
                "adapter {} cannot blend into R32Float (no FLOAT32_BLENDABLE): use {instead}",
                self.info.name
            ))),
        }
    }

    /// Checks what algorithm `id` needs against the adapter's limits; the error
    /// ([`Error::Resource`]) names the need, its size and the adapter's limit.
    pub fn check_limits(&self, id: &str, needs: Needs) -> Result<()> {
        let l = &self.limits;
        let fail = |why: String| Err(Error::Resource(why));
        if needs.texture > l.max_texture_dimension_2d {
            return fail(format!(
                "map_resolution {} exceeds the adapter's largest texture ({})",
                needs.texture, l.max_texture_dimension_2d
            ));
        }
        if needs.storage_buffers > l.max_storage_buffers_per_shader_stage {
            return fail(format!(
                "{id} binds {} storage buffers; the adapter allows {}",
                needs.storage_buffers, l.max_storage_buffers_per_shader_stage
            ));
        }
        if needs.workgroup
            > l.max_compute_invocations_per_workgroup
                .min(l.max_compute_workgroup_size_x)
        {
            return fail(format!(
                "{id} needs compute workgroups of {} invocations",
                needs.workgroup
            ));
        }
        let max = l.max_storage_buffer_binding_size;
        match needs.buffers.iter().find(|(_, bytes)| *bytes > max) {
            Some((name, bytes)) => fail(format!(
                "{id} buffer {name} needs {bytes} bytes, more than the adapter's storage binding \
                 limit ({max})"
            )),
            None => Ok(()),
        }
    }

    /// A zeroed `T` in a storage buffer the instrumented replay counts into, clears and reads
    /// back.
    pub fn counts_buffer<T: bytemuck::Pod>(&self, label: &str) -> wgpu::Buffer {
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        self.upload(label, &[T::zeroed()], usage)
    }

    /// A `resolution`² map texture ([`Gpu::map_texture`], no further usage) and its view.
    pub fn map_view(
        &self,
        label: &str,
        resolution: u32,
        format: wgpu::TextureFormat,
    ) -> wgpu::TextureView {
        self.target_view(label, (resolution, resolution), format)
    }

    /// Encodes commands with `f`, submits them and waits for the GPU; returns the milliseconds
    /// this took on the host, and of them the time from submission to completion (without the
    /// host's encoding). A run submits through [`Run::submit`], which checks its deadline and
    /// keeps the second figure for [`timing`]'s check of the passes' GPU times.
    pub fn submit(&self, f: impl FnOnce(&mut wgpu::CommandEncoder)) -> Result<(f64, f64)> {
        let start = std::time::Instant::now();
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        f(&mut encoder);
        let commands = encoder.finish();
        let submitted = std::time::Instant::now();
        self.queue.submit([commands]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))?;
        let ms = |t: std::time::Instant| t.elapsed().as_secs_f64() * 1e3;
        Ok((ms(start), ms(submitted)))
    }

    /// Why the device was lost, or `None` while it is usable.
    pub fn lost(&self) -> Option<String> {
        self.lost.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// What every wgpu record carries in its `execution` map.
    pub fn execution(&self) -> BTreeMap<String, serde_json::Value> {
        let i = &self.info;
        [
            ("adapter", serde_json::json!(i.name)),
            (
                "adapter_type",
                serde_json::json!(format!("{:?}", i.device_type)),
            ),
            ("driver", serde_json::json!(i.driver)),
            ("driver_info", serde_json::json!(i.driver_info)),
            ("gpu_backend", serde_json::json!(i.backend.to_str())),
            ("gpu_queries", serde_json::json!(self.queries.names())),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }
}

static PREFERENCE: OnceLock<String> = OnceLock::new();

/// One wgpu run on the shared device and its context: the deadline its submissions are
/// checked against, whether it makes its instrumented replay ([`GpuCounters`]) and the host
/// time of each of its submissions (for [`timing`]'s check of the passes' GPU times). Made by
/// [`guarded_run`] and [`guarded_frame`] from the run's `ExecContext`; it derefs to the
/// device, so a run makes buffers and pipelines through it as through the [`Gpu`].
pub struct Run {
    gpu: &'static Gpu,
    deadline: Deadline,
    counters: GpuCounters,
    /// Milliseconds from submission to completion of each submission, by number.
    host_ms: std::cell::RefCell<Vec<f64>>,
}

impl std::ops::Deref for Run {
    type Target = Gpu;

    fn deref(&self) -> &Gpu {
        self.gpu
    }
}

impl Run {
    /// Whether this run makes its instrumented replay.
    pub fn counters(&self) -> GpuCounters {
        self.counters
    }

    /// Encodes commands with `f`, submits them and waits for the GPU ([`Gpu::submit`]);
    /// returns the milliseconds this took on the host. Past the run's deadline it unwinds
    /// instead ([`Deadline::check`]).
    pub fn submit(&self, f: impl FnOnce(&mut wgpu::CommandEncoder)) -> Result<f64> {
        self.deadline.check();
        let (wall, waited) = self.gpu.submit(f)?;
        self.host_ms.borrow_mut().push(waited);
        Ok(wall)
    }

    /// The number the run's next submission gets (the first is 0).
    pub fn next_submission(&self) -> u64 {
        self.host_ms.borrow().len() as u64
    }

    /// The milliseconds from submission to completion of the run's submission `n`, once made.
    pub fn host_ms(&self, n: u64) -> Option<f64> {
        self.host_ms.borrow().get(n as usize).copied()
    }
}

/// The device in use: acquired on first use, replaced when it is lost. A lost device is leaked
/// rather than dropped (it is rare, and runs may still hold references to it).
static GPU: Mutex<Option<std::result::Result<&'static Gpu, String>>> = Mutex::new(None);

/// Asks for the adapter whose name contains `name` (from `--adapter`); must come before the
/// first [`gpu`] call, and overrides `SHADOWBENCH_ADAPTER`.
pub fn prefer_adapter(name: &str) -> Result<()> {
    PREFERENCE
        .set(name.to_string())
        .map_err(|_| Error::Gpu("the adapter was already chosen".into()))?;
    if GPU.lock().unwrap_or_else(|e| e.into_inner()).is_some() {
        return Err(Error::Gpu(
            "--adapter given after the device was acquired".into(),
        ));
    }
    Ok(())
}

fn preference() -> Option<String> {
    PREFERENCE
        .get()
        .cloned()
        .or_else(|| std::env::var(ADAPTER_ENV).ok())
        .filter(|s| !s.trim().is_empty())
}

/// The shared device, acquired on first use, and acquired again after a device loss. The error
/// says why there is none (no adapter, no adapter matching the requested name, or the device
/// request failed).
pub fn gpu() -> Result<&'static Gpu> {
    gpu_acquired().map(|(g, _)| g)
}

/// [`gpu`], and whether this call acquired the device.
fn gpu_acquired() -> Result<(&'static Gpu, bool)> {
    let mut current = GPU.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(Ok(g)) = current.as_ref() {
        if let Some(why) = g.lost() {
            crate::errln!("wgpu: the device was lost ({why}); acquiring a new one");
            *current = None;
        }
    }
    let fresh = current.is_none();
    current
        .get_or_insert_with(|| acquire().map(|g| &*Box::leak(Box::new(g))))
        .clone()
        .map(|g| (g, fresh))
        .map_err(Error::Gpu)
}

fn instance(backends: wgpu::Backends) -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    desc.backends = backends;
    wgpu::Instance::new(desc)
}

/// Rank of an adapter: lower is better.
fn rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    let api = match info.backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        _ => 1,
    };
    (kind, api)
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {}, driver {} {})",
        info.name,
        info.device_type,
        info.backend.to_str(),
        info.driver,
        info.driver_info
    )
}

/// All adapters, best first: of the backends `WGPU_BACKEND` names, else of the primary APIs
/// (Vulkan, and Metal or DX12 on their platforms). GL is not built in (Cargo.toml): naga cannot
/// write the executions' WGSL (`textureLoad` from depth textures) as GLSL.
fn adapters() -> Vec<wgpu::Adapter> {
    let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
    let mut found = pollster::block_on(instance(backends).enumerate_adapters(backends));
    found.sort_by_key(|a| rank(&a.get_info()));
    found
}

/// What adapter `a` lacks that the wgpu executions need, or `None` when it has it all: the
/// full WebGPU feature level (wgpu's downlevel flags, limits and shader model 5: storage
/// buffers and textures in every stage, compute, depth-texture copies, ...). `list`, `render`
/// and `run` choose adapters by it alike.
fn lacks(a: &wgpu::Adapter) -> Option<String> {
    let d = a.get_downlevel_capabilities();
    let mut missing: Vec<String> = Vec::new();
    let flags = wgpu::DownlevelFlags::compliant() - d.flags;
    missing.extend(flags.iter_names().map(|(name, _)| name.to_lowercase()));
    if d.shader_model < wgpu::ShaderModel::Sm5 {
        missing.push(format!("shader model 5 (has {:?})", d.shader_model));
    }
    if d.limits != wgpu::DownlevelLimits::default() {
        missing.push("WebGPU's downlevel limits".into());
    }
    (!missing.is_empty()).then(|| missing.join(", "))
}

/// The reason no found adapter can run the wgpu executions: each adapter and what it lacks.
fn none_usable(found: &[wgpu::Adapter]) -> String {
    let each: Vec<String> = found
        .iter()
        .map(|a| {
            let lacks = lacks(a).unwrap_or_default();
            format!("{} lacks {lacks}", describe(&a.get_info()))
        })
        .collect();
    format!(
        "no adapter can run the wgpu executions: {} (install a Vulkan driver, e.g. Mesa's \
         software one, the Debian package mesa-vulkan-drivers)",
        each.join("; ")
    )
}

fn no_adapter_reason() -> String {
    let mut why = String::from(
        "no GPU adapter found (no Vulkan, Metal or DX12 driver answered; GL is not built in, its \
         shading language cannot express the passes; on Linux without a GPU install Mesa's \
         software Vulkan driver, e.g. the Debian package mesa-vulkan-drivers)",
    );
    for var in ["VK_ICD_FILENAMES", "VK_DRIVER_FILES", "WGPU_BACKEND"] {
        if let Ok(v) = std::env::var(var) {
            why.push_str(&format!("; {var}={v}"));
        }
    }
    why
}

fn acquire() -> std::result::Result<Gpu, String> {
    let found = adapters();
    if found.is_empty() {
        return Err(no_adapter_reason());
    }
    let adapter = match preference() {
        None => {
            if found.iter().all(|a| lacks(a).is_some()) {
                return Err(none_usable(&found));
            }
            found
                .into_iter()
                .find(|a| lacks(a).is_none())
                .expect("one is usable")
        }
        Some(want) => {
            let names: Vec<String> = found.iter().map(|a| a.get_info().name).collect();
            let a = found
                .into_iter()
                .find(|a| {
                    a.get_info()
                        .name
                        .to_lowercase()
                        .contains(&want.to_lowercase())
                })
                .ok_or_else(|| {
                    format!(
                        "no adapter name contains '{want}' (from --adapter or {ADAPTER_ENV}); \
                         found: {}",
                        names.join(", ")
                    )
                })?;
            if let Some(l) = lacks(&a) {
                return Err(format!(
                    "adapter {} cannot run the wgpu executions: it lacks {l}",
                    describe(&a.get_info())
                ));
            }
            a
        }
    };
    let info = adapter.get_info();
    let queries = QueryFeatures::of(adapter.features());
    let limits = adapter.limits();
    let float32_blendable = adapter
        .features()
        .contains(wgpu::Features::FLOAT32_BLENDABLE);
    let depth32_stencil8 = adapter
        .features()
        .contains(wgpu::Features::DEPTH32FLOAT_STENCIL8);
    let optional = adapter.features()
        & (wgpu::Features::FLOAT32_BLENDABLE
            | wgpu::Features::PIPELINE_CACHE
            | wgpu::Features::DEPTH32FLOAT_STENCIL8);
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("shadowbench"),
        required_features: queries.features() | optional,
        required_limits: limits.clone(),
        ..Default::default()
    }))
    .map_err(|e| format!("{}: device request failed: {e}", describe(&info)))?;
    // Errors inside a run are caught by error scopes (see `scoped`); anything else is reported
    // rather than aborting the process.
    device.on_uncaptured_error(Arc::new(|e: wgpu::Error| {
        crate::errln!("wgpu: uncaptured error: {e}");
    }));
    let lost = Arc::new(Mutex::new(None));
    let lost_reason = Arc::clone(&lost);
    device.set_device_lost_callback(move |reason, message| {
        *lost_reason.lock().unwrap_or_else(|e| e.into_inner()) = Some(if message.is_empty() {
            format!("{reason:?}")
        } else {
            format!("{reason:?}: {message}")
        });
    });
    // SAFETY: `create_pipeline_cache` is unsafe only for its initial `data`, which must come
    // from `PipelineCache::get_data`; the cache starts empty and lives in memory only.
    let driver = optional
        .contains(wgpu::Features::PIPELINE_CACHE)
        .then(|| unsafe {
            device.create_pipeline_cache(&wgpu::PipelineCacheDescriptor {
                label: Some("shadowbench pipelines"),
                data: None,
                fallback: true,
            })
        });
    Ok(Gpu {
        device,
        queue,
        info,
        queries,
        limits,
        lost,
        float32_blendable,
        depth32_stencil8,
        cache: cache::Cache::new(driver),
        half_blend: OnceLock::new(),
    })
}

/// Runs one wgpu run `f` on the shared device with validation and out-of-memory errors
/// captured, turning them into an error instead of a panic. A device lost during the run fails
/// it with the driver's reason, whatever `f` returned, since its buffers cannot be trusted; the
/// next call acquires a new device. [`fault`] injections happen here. The run stops at
/// `deadline`, checked before each submission ([`Gpu::submit`]; work already submitted runs
/// to its end).
///
/// Runs are serialised process-wide (one at a time on the shared device), so that the host
/// time of each submission, which [`timing`] checks GPU times against, is the run's own and
/// not time spent waiting behind another thread's work.
pub fn guarded_run<T>(deadline: Deadline, f: impl FnOnce(&Run) -> Result<T>) -> Result<T> {
    guarded(deadline, GpuCounters::On, f).map(|(out, _)| out)
}

/// A wgpu execution's run of one frame, as [`guarded_run`]; with `counters` off it skips its
/// instrumented replay ([`GpuCounters`]). The run's GPU setup (a device acquired, modules and
/// pipelines created: [`cache`]) is measured apart and returned in the output's
/// `gpu_setup_ms` and `execution.gpu_setup`, so that the harness leaves it out of the run's
/// wall time.
pub fn guarded_frame(
    deadline: Deadline,
    counters: GpuCounters,
    f: impl FnOnce(&Run) -> Result<FrameOutput>,
) -> Result<FrameOutput> {
    let (mut out, setup) = guarded(deadline, counters, f)?;
    out.gpu_setup_ms = Some(setup.ms());
    out.execution.insert("gpu_setup".into(), setup.to_json());
    Ok(out)
}

/// [`guarded_run`] with `counters`, and the run's GPU setup.
fn guarded<T>(
    deadline: Deadline,
    counters: GpuCounters,
    f: impl FnOnce(&Run) -> Result<T>,
) -> Result<(T, cache::Setup)> {
    static ONE_RUN: Mutex<()> = Mutex::new(());
    let _running = ONE_RUN.lock().unwrap_or_else(|e| e.into_inner());
    let start = std::time::Instant::now();
    let (gpu, fresh) = gpu_acquired()?;
    let device_ms = if fresh {
        start.elapsed().as_secs_f64() * 1e3
    } else {
        0.0
    };
    gpu.cache.begin_run();
    let run = Run {
        gpu,
        deadline,
        counters,
        host_ms: Default::default(),
    };
    let oom = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    fault::inject(gpu);
    // wgpu's helpers panic on some calls to a lost device (e.g. initialised buffers); the
    // panic is caught here so that the error scopes are popped and the loss is reported.
    let out = catch_unwind(AssertUnwindSafe(|| f(&run)));
    let v = pollster::block_on(validation.pop());
    let o = pollster::block_on(oom.pop());
    // Polling delivers a pending device-lost notice before it is checked.
    let _ = gpu.device.poll(wgpu::PollType::Poll);
    let ok = matches!(out, Ok(Ok(_))) && v.is_none() && o.is_none() && gpu.lost().is_none();
    let setup = cache::Setup {
        device_ms,
        driver_cache: gpu.cache.driver.is_some(),
        ..gpu.cache.end_run(ok)
    };
    if let Some(why) = gpu.lost() {
        return Err(Error::Gpu(format!("device lost during the run: {why}")));
    }
    let out = out.map_err(|panic| {
        if crate::util::deadline::cancelled(panic.as_ref()).is_some() {
            // The run's budget ran out between submissions: not a wgpu fault.
            std::panic::resume_unwind(panic);
        }
        Error::Gpu(format!(
            "wgpu panicked: {}",
            crate::error::panic_message(panic.as_ref())
        ))
    })?;
    match (v, o) {
        (Some(e), _) | (None, Some(e)) => Err(Error::Gpu(describe_error(&e))),
        (None, None) => out.map(|out| (out, setup)),
    }
}

/// A wgpu error with what went wrong: a validation or internal error's description (their
/// `Display` says only "Validation Error").
fn describe_error(e: &wgpu::Error) -> String {
    match e {
        wgpu::Error::Validation { description, .. } | wgpu::Error::Internal { description, .. } => {
            // One line: "Validation Error: In Device::create_shader_module, …: <what>".
            let lines = description.lines().map(str::trim);
            let lines = lines.filter(|l| !l.is_empty() && *l != "Caused by:");
            lines.collect::<Vec<_>>().join(": ")
        }
        other => other.to_string(),
    }
}

/// A description of the adapters for `shadowbench list`: every adapter found with its query
/// features, which one runs the wgpu execution, or why there is none.
/// The limits and features of adapter `a` that the wgpu executions check before they run
/// (storage bindings and buffers, workgroup sizes and counts, texture size, subgroup sizes,
/// blending into 32-bit floats), as `list` prints them under the adapter.
fn limits_line(a: &wgpu::Adapter) -> String {
    let (l, info) = (a.limits(), a.get_info());
    let blend = a.features().contains(wgpu::Features::FLOAT32_BLENDABLE);
    let stencil = a.features().contains(wgpu::Features::DEPTH32FLOAT_STENCIL8);
    format!(
        "      limits: storage binding {} MiB, {} storage buffers per stage, {} invocations per \
         workgroup, {} workgroups per dimension, 2D textures {}; subgroups {}..={}; float32 \
         blending {}; depth32float-stencil8 {}",
        l.max_storage_buffer_binding_size >> 20,
        l.max_storage_buffers_per_shader_stage,
        l.max_compute_invocations_per_workgroup,
        l.max_compute_workgroups_per_dimension,
        l.max_texture_dimension_2d,
        info.subgroup_min_size,
        info.subgroup_max_size,
        if blend { "yes" } else { "no" },
        if stencil { "yes" } else { "no" }
    )
}

pub fn adapter_report() -> Vec<String> {
    let found = adapters();
    let mut lines = Vec::new();
    if found.is_empty() {
        lines.push(format!("none: {}", no_adapter_reason()));
        return lines;
    }
    let chosen = gpu();
    for a in &found {
        let info = a.get_info();
        let q = QueryFeatures::of(a.features()).names();
        let mark = match &chosen {
            Ok(g) if g.info == info => "*",
            _ => " ",
        };
        lines.push(format!(
            "{mark} {}  queries: {}",
            describe(&info),
            if q.is_empty() {
                "none".to_string()
            } else {
                q.join(", ")
            }
        ));
        lines.push(limits_line(a));
        if let Some(l) = lacks(a) {
            lines.push(format!("      not used: lacks {l}"));
        }
    }
    if let Err(e) = chosen {
        lines.push(format!("no device: {e}"));
    }
    lines
}

/// Records the resolve of a timed submission's optional queries (after its last pass): the
/// pass timestamps and the pipeline statistics, where the adapter offers them.
pub fn resolve_queries(
    e: &mut wgpu::CommandEncoder,
    timer: Option<&timing::PassTimer>,
    stats: Option<&stats::PassStats>,
) {
    if let Some(t) = timer {
        t.resolve(e);
    }
    if let Some(s) = stats {
        s.resolve(e);
    }
}

/// Adds `entries` (a JSON object) to a record's `execution` map.
pub fn record_execution(
    execution: &mut BTreeMap<String, serde_json::Value>,
    entries: serde_json::Value,
) {
    if let serde_json::Value::Object(m) = entries {
        execution.extend(m);
    }
}

/// The gbuffer's positions as the WGSL passes read them: xyz, and in w 1 where the pixel sees a
/// surface, else 0.
pub fn gbuffer_positions(g: &GBuffer) -> Vec<[f32; 4]> {
    (0..g.len())
        .map(|i| {
            g.position[i]
                .extend(f32::from(u8::from(g.is_hit(i))))
                .to_array()
        })
        .collect()
}
