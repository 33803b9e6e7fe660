//! `soft_shadow_map` as GPU passes (`wgpu.wgsl`):
//!
//! 1. `maps` — render passes draw the occluders into the occluder map (and, two passes, their
//!    back faces into a second one, front faces culled) and the receivers into the receiver map,
//!    all Depth32Float, with the frames of [`LightFrame::focused`].
//! 2. `splat` — one quad per micro-patch (an instanced 4-vertex strip) drawn with additive
//!    blending (`One + One`) into the SSM, R32Float for `fp32` (needs the adapter's
//!    `FLOAT32_BLENDABLE`; without it the run fails with that reason) or R16Float for `fp16`.
//!    With `occluder_map_transfer` (the paper's §4.1) the occluder maps are copied to the host,
//!    which builds the patches and extents with the same Rust as the CPU executions
//!    ([`super::micro_patch`], [`super::extent_quad`]) and uploads them as instances; `transfer.bytes`
//!    and the host's wall time (`transfer_ms` under `execution`) are recorded. Without it
//!    (GPU-only, §4.3) the vertex shader reads the occluder map itself, one instance per texel.
//! 3. `project` — a compute pass over the gbuffer looks the merged (max, §3.5) SSM up with
//!    bilinear weights.
//!
//! The instrumented replay of `splat` counts fragments (`fill`) and those that hide nothing
//! (`overdraw`), through a pipeline that writes no colour (no blending to pay for twice).

use std::time::Instant;

use bytemuck::{Pod, Zeroable};

use super::Phase;
use super::{
    extent_quad, half_rounding, micro_patch, LightFrame, Precision, SoftShadowMapOptions, Split, ID,
};
use crate::algorithms::algorithm::{ExecContext, FrameOutput};
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::meshes::positions;
use crate::gpu::pass::{
    gpu_struct, per_vertex, tiles, view, Bind::*, Compute, Draw, EyeBuffers, Instrumented, Layout,
    Pass, Program, Raster, Readout, Render, Shared, Statistics, Timed,
};
use crate::gpu::readback::{first, read_texels};
use crate::gpu::{additive_red, record_execution, unwritten, Needs, Run};
use crate::model::raster::BLOCK;
use crate::model::LANES;
use crate::record::Counters;

const WGSL: &str = include_str!("wgpu.wgsl");
const WORKGROUP: u32 = 8;

gpu_struct! {
    /// The frames of the maps (group 0, binding 0 of every pass).
    struct SsmUniform as "Ssm" {
        occ_view_proj: [f32; 16] => "mat4x4<f32>",
        ssm_view_proj: [f32; 16] => "mat4x4<f32>",
        center: [f32; 3] => "vec3<f32>",
        resolution: u32 => "u32",
        e_u: [f32; 3] => "vec3<f32>",
        width: u32 => "u32",
        e_v: [f32; 3] => "vec3<f32>",
        height: u32 => "u32",
        normal: [f32; 3] => "vec3<f32>",
        bias_texels: f32 => "f32",
        /// x0, x1, y0, y1 of each frame's tan window.
        occ_window: [f32; 4] => "vec4<f32>",
        ssm_window: [f32; 4] => "vec4<f32>",
        half_size: [f32; 2] => "vec2<f32>",
        near: f32 => "f32",
        far: f32 => "f32",
    }
}

gpu_struct! {
    /// The counters of the instrumented replay (group 0, binding 1).
    struct Counts as "Counts" {
        /// Fragments that hide part of the light (fill is `kept + zero`).
        kept: u32 => "atomic<u32>",
        /// Fragments that hide nothing (overdraw).
        zero: u32 => "atomic<u32>",
        patches: u32 => "atomic<u32>",
        pad: u32 => "u32",
    }
}

/// The shader as the pipelines join it.
const SOURCES: [&str; 3] = [SsmUniform::WGSL, Counts::WGSL, WGSL];

/// One micro-patch of the transfer path: the patch and its extent in NDC (lo, hi).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Instance {
    lo: [f32; 2],
    hi: [f32; 2],
    z_o: f32,
    extent: [f32; 4],
}

fn window(f: &LightFrame) -> [f32; 4] {
    [f.x0, f.x1, f.y0, f.y1]
}

/// `soft_shadow_map` on wgpu (`ctx` unused: the passes need nothing of the run's context).
pub fn render(
    gpu: &Run,
    frame: &Frame,
    _ctx: &ExecContext,
    o: &SoftShadowMapOptions,
) -> Result<FrameOutput> {
    gpu.check_float32_blend(o.precision == Precision::Fp32, "precision fp16")?;
    gpu.check_limits(ID, Needs::map(frame.params.map_resolution))?;
    let split = Split::of(&frame.flat);
    let mut out = Ssm::new(gpu, frame, o, &split).run()?;
    if let Some(w) = split.warning() {
        out.warnings.insert(0, w);
    }
    super::record_receivers_outside(frame, &split, &mut out);
    if o.precision == Precision::Fp16 {
        let rounding = half_rounding(gpu.half_blend_sums()?, o.fp16_rounding);
        record_execution(
            &mut out.execution,
            serde_json::json!({"fp16_blend_rounding": rounding.0}),
        );
        out.warnings.extend(rounding.1);
    }
    Ok(out)
}

/// A depth-only draw of indices into a map.
struct Depth {
    indices: wgpu::Buffer,
    count: u32,
    group: wgpu::BindGroup,
}

/// The resources and pipelines of one frame.
struct Ssm<'g> {
    gpu: &'g Run,
    o: SoftShadowMapOptions,
    occ: LightFrame,
    ssm: LightFrame,
    size: (u32, u32),
    res: u32,
    vertices: wgpu::Buffer,
    visibility: wgpu::Buffer,
    occluders: Depth,
    receivers: Depth,
    /// Occluder maps (front faces, back faces with two passes), the receiver map, the SSMs.
    occ_maps: Vec<wgpu::Texture>,
    occ_views: Vec<wgpu::TextureView>,
    receiver_view: wgpu::TextureView,
    ssm_views: Vec<wgpu::TextureView>,
    ssm_format: wgpu::TextureFormat,
    shared: Shared,
    splat_groups: Vec<wgpu::BindGroup>,
    project_group: wgpu::BindGroup,
    p: Pipelines,
}

/// What the transfer (§4.1) built: the micro-patches of each occluder map as instances, the
/// bytes transferred, the patches built and the host's wall time (ms).
#[derive(Default)]
struct Transfer {
    instances: Vec<(wgpu::Buffer, u32)>,
    bytes: u64,
    patches: u64,
    ms: f64,
}

/// The pipelines of the passes.
struct Pipelines {
    /// Depth: front faces, back faces (front culled); timed only.
    depth: [Render; 2],
    /// Splat: `fs_splat` timed, `fs_splat_count` in the replay.
    splat: Render,
    /// Timed only.
    project: Compute,
    /// Replay only: the micro-patches the vertex shader builds.
    count_patches: Compute,
}

/// Square maps of `res`² texels, one per pass (the second labelled "back"), and their views.
fn maps(
    gpu: &Run,
    label: &str,
    (passes, res): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> (Vec<wgpu::Texture>, Vec<wgpu::TextureView>) {
    let textures: Vec<_> = (0..passes)
        .map(|k| {
            let back = format!("{label} back");
            gpu.map_texture(if k == 0 { label } else { &back }, res, format, usage)
        })
        .collect();
    let views = textures
        .iter()
        .map(|t| t.create_view(&Default::default()))
        .collect();
    (textures, views)
}

impl<'g> Ssm<'g> {
    fn new(gpu: &'g Run, frame: &Frame, o: &SoftShadowMapOptions, split: &Split) -> Ssm<'g> {
        let res = frame.params.map_resolution;
        let (width, height) = (frame.width(), frame.height());
        let (occ, ssm) = LightFrame::new(&frame.scene.light, frame.scene.bounds(), res)
            .focused(split.occluder_bounds);
        // The frames of the occluder map (`occ`) and of the soft shadow map (`ssm`).
        let uniform = SsmUniform {
            occ_view_proj: occ.view_proj.to_cols_array(),
            ssm_view_proj: ssm.view_proj.to_cols_array(),
            center: ssm.center.to_array(),
            resolution: res,
            e_u: ssm.e_u.to_array(),
            width,
            e_v: ssm.e_v.to_array(),
            height,
            normal: ssm.normal.to_array(),
            bias_texels: o.bias_texels,
            occ_window: window(&occ),
            ssm_window: window(&ssm),
            half_size: ssm.half.to_array(),
            near: ssm.near,
            far: ssm.far,
        };
        use wgpu::BufferUsages as B;
        let vertices = gpu.upload("vertices", &positions(&frame.flat.mesh), B::VERTEX);
        // The gbuffer: position with the hit flag, normal with the receives flag.
        let g = &frame.gbuffer;
        let receives = |t: u32| split.receives[frame.flat.object_of_triangle[t as usize] as usize];
        let eye = EyeBuffers::new(gpu, g, |i| {
            f32::from(u8::from(g.is_hit(i) && receives(g.triangle[i])))
        });

        // The occluder maps are read back for the paper's transfer to the CPU.
        let depth_format = wgpu::TextureFormat::Depth32Float;
        const COPY_SRC: wgpu::TextureUsages = wgpu::TextureUsages::COPY_SRC;
        const NONE: wgpu::TextureUsages = wgpu::TextureUsages::empty();
        let sized = (o.passes, res);
        let (occ_maps, occ_views) = maps(gpu, "occluder map", sized, depth_format, COPY_SRC);
        let receiver_view = gpu.map_view("receiver map", res, depth_format);
        let ssm_format = match o.precision {
            Precision::Fp32 => wgpu::TextureFormat::R32Float,
            Precision::Fp16 => wgpu::TextureFormat::R16Float,
        };
        let (_, ssm_views) = maps(gpu, "soft shadow map", sized, ssm_format, NONE);
        use wgpu::ShaderStages as S;
        let all = S::VERTEX | S::FRAGMENT | S::COMPUTE;
        let shared = Shared::new::<Counts>(gpu, "ssm shared", &uniform);
        let map_layout = Layout::new(gpu, "ssm map view", S::VERTEX, &[Uniform]);
        let splat_layout = Layout::new(gpu, "ssm splat", all, &[Absent, Depth, Depth]);
        let depth = |triangles: &[[u32; 3]], m: glam::Mat4| {
            let list: Vec<u32> = triangles.iter().flatten().copied().collect();
            let b = gpu.upload("map view", &m.to_cols_array(), B::UNIFORM);
            Depth {
                indices: gpu.upload("indices", &list, B::INDEX),
                count: list.len() as u32,
                group: map_layout.group(gpu, "map view", &[b.as_entire_binding()]),
            }
        };
        let occluders = depth(&split.occluders, occ.view_proj);
        let receivers = depth(&split.receivers, ssm.view_proj);
        let splat_groups = occ_views
            .iter()
            .map(|v| splat_layout.group(gpu, "ssm splat", &[view(v), view(&receiver_view)]))
            .collect();
        let (project_layout, project_group) = Layout::bound(
            gpu,
            "ssm project",
            S::COMPUTE,
            &eye.binds_after([
                (Float, view(&ssm_views[0])),
                (Float, view(&ssm_views[o.passes as usize - 1])),
            ]),
        );
        let layouts = [&shared.layout, &map_layout, &splat_layout, &project_layout];
        let p = Pipelines::new(gpu, o, ssm_format, layouts);
        Ssm {
            gpu,
            o: *o,
            occ,
            ssm,
            size: (width, height),
            res,
            vertices,
            visibility: eye.visibility,
            occluders,
            receivers,
            occ_maps,
            occ_views,
            receiver_view,
            ssm_views,
            ssm_format,
            shared,
            splat_groups,
            project_group,
            p,
        }
    }

    /// A depth-only pass of `d` into `map`.
    fn depth_pass<'a>(&'a self, d: &'a Depth, map: &'a wgpu::TextureView, back: bool) -> Pass<'a> {
        let draw = Draw {
            depth: Some(map),
            vertices: Some(&self.vertices),
            indices: Some(&d.indices),
            ..Draw::of(&self.p.depth[usize::from(back)], d.count)
        };
        Pass::draw("maps", &[Some(&self.shared.group), Some(&d.group)], draw)
    }

    /// The splat passes, one per SSM: the micro-patches uploaded by the transfer
    /// (`instances`), or one instance per occluder-map texel.
    fn splat_passes<'a>(&'a self, instances: &'a [(wgpu::Buffer, u32)]) -> Vec<Pass<'a>> {
        let texels = self.res.div_ceil(BLOCK).pow(2) * LANES as u32;
        (0..self.o.passes as usize)
            .map(|k| {
                let (vertices, n) = match instances.get(k) {
                    Some((b, n)) => (Some(b), *n),
                    None => (None, texels),
                };
                let draw = Draw {
                    color: Some(&self.ssm_views[k]),
                    vertices,
                    instances: n,
                    ..Draw::of(&self.p.splat, 4)
                };
                let groups = [Some(&self.shared.group), Some(&self.splat_groups[k])];
                Pass::draw("splat", &groups, draw)
            })
            .collect()
    }

    /// The transfer (§4.1): occluder maps to the host, patches and extents built there in the
    /// cpu's block-linear order and uploaded as instances; also the bytes transferred, the
    /// patches built and the time it took.
    fn transfer(&self) -> Result<Transfer> {
        let start = Instant::now();
        let res = self.res;
        let blocks = res.div_ceil(BLOCK);
        let mut t = Transfer::default();
        for depth in read_texels::<f32>(self.gpu, &self.occ_maps)? {
            t.bytes += u64::from(res) * u64::from(res) * 4;
            let mut inst = Vec::new();
            for (by, bx) in (0..blocks).flat_map(|by| (0..blocks).map(move |bx| (by, bx))) {
                for l in 0..LANES as u32 {
                    let (i, j) = (bx * BLOCK + l % BLOCK, by * BLOCK + l / BLOCK);
                    if i >= res || j >= res {
                        continue;
                    }
                    if let Some(p) = micro_patch(&self.occ, i, j, depth[(j * res + i) as usize]) {
                        let q = extent_quad(&self.ssm, &p);
                        inst.push(Instance {
                            lo: p.lo.to_array(),
                            hi: p.hi.to_array(),
                            z_o: p.z_o,
                            extent: [q[0].x, q[0].y, q[2].x, q[2].y],
                        });
                    }
                }
            }
            t.patches += inst.len() as u64;
            let buf = self
                .gpu
                .upload("patches", &inst, wgpu::BufferUsages::VERTEX);
            t.instances.push((buf, inst.len() as u32));
        }
        t.ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(t)
    }

    fn run(&self) -> Result<FrameOutput> {
        let host = self.o.occluder_map_transfer;
        let passes = self.o.passes as usize;
        let readback = [&self.visibility];
        // The instrumented replay: `splat`, and the micro-patches the device built.
        let mut run = Timed::new(self.gpu, Phase::ALL, Statistics::Off, &readback)
            .counting_into(&self.shared.counts, Readout::End);
        // Passes in timer order: maps (occluders, back faces, receivers), splat, project.
        let mut maps: Vec<Pass> = (0..passes)
            .map(|k| self.depth_pass(&self.occluders, &self.occ_views[k], k == 1))
            .collect();
        maps.push(self.depth_pass(&self.receivers, &self.receiver_view, false));
        run.submit(Phase::Maps, &maps)?;
        let transfer = match host {
            true => run.host(Phase::Maps, || self.transfer())?,
            false => Transfer::default(),
        };
        let instances = &transfer.instances;
        let mut splat = self.splat_passes(instances);
        if !host {
            let res = tiles((self.res, self.res), WORKGROUP);
            splat.extend(self.splat_groups.iter().map(|g| {
                let groups = [Some(&self.shared.group), Some(g)];
                Pass::compute("count_patches", &groups, &self.p.count_patches, res)
            }));
        }
        run.submit(Phase::Splat, &splat)?;
        let groups = [Some(&self.shared.group), None, Some(&self.project_group)];
        let workgroups = tiles(self.size, WORKGROUP);
        let project = Pass::compute("project", &groups, &self.p.project, workgroups);
        run.submit(Phase::Project, &[project])?;
        let timing = run.finish()?;

        let c: Counts = first(&timing.counts[0]);

        let mut maps_c = Counters::default();
        if host {
            maps_c.set(names::TRANSFER_BYTES, transfer.bytes as f64);
        }
        let mut splat_c = Counters::default();
        splat_c.add_fill(f64::from(c.kept) + f64::from(c.zero), f64::from(c.zero));
        let (patches, extents) = match host {
            true => (transfer.patches as f64, "host (occluder map transferred)"),
            false => (f64::from(c.patches), "device (vertex shader)"),
        };
        splat_c.set(names::SSM_MICRO_PATCHES, patches);
        let texels = passes as u64 * u64::from(self.res) * u64::from(self.res);
        splat_c.set(names::SSM_OCCLUDER_TEXELS, texels as f64);
        let note = "fill/overdraw from an instrumented replay of splat (WGSL atomics)";
        let mut out = timing.output(
            self.size,
            vec![(Phase::Maps, maps_c), (Phase::Splat, splat_c)],
            note,
        );
        let entries = serde_json::json!({
            "transfer_ms": transfer.ms,
            "ssm_format": format!("{:?}", self.ssm_format),
            "extents": extents,
        });
        record_execution(&mut out.execution, entries);
        Ok(out)
    }
}

impl Pipelines {
    /// The pipelines from the shared, map-view, splat and project group layouts.
    fn new(
        gpu: &Run,
        o: &SoftShadowMapOptions,
        ssm_format: wgpu::TextureFormat,
        [shared, map, splat, project]: [&Layout; 4],
    ) -> Pipelines {
        let label = "soft_shadow_map/wgpu.wgsl";
        let depth_program = Program::new(gpu, label, &SOURCES, &[Some(shared), Some(map)]);
        let splat_program = Program::new(gpu, label, &SOURCES, &[Some(shared), Some(splat)]);
        let project_program =
            Program::new(gpu, label, &SOURCES, &[Some(shared), None, Some(project)]);
        let position = wgpu::vertex_attr_array![0 => Float32x3];
        let depth = |cull| {
            let raster = Raster {
                vs: "vs_depth",
                fs: "fs_depth",
                vertex: per_vertex(&position),
                cull,
                ..Raster::default()
            };
            depth_program.render(gpu, &raster)
        };
        let instance =
            wgpu::vertex_attr_array![0 => Float32x2, 1 => Float32x2, 2 => Float32, 3 => Float32x4];
        let host = o.occluder_map_transfer;
        // The counting pipeline of the replay writes no colour: its fragments are only counted.
        let splat = |fs, count: bool| {
            let color = match count {
                true => unwritten(ssm_format),
                false => additive_red(ssm_format),
            };
            let raster = Raster {
                vs: ["vs_splat_device", "vs_splat_host"][usize::from(host)],
                fs,
                vertex: host.then_some((
                    size_of::<Instance>() as u64,
                    wgpu::VertexStepMode::Instance,
                    &instance[..],
                )),
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                depth: None,
                color: Some(color),
                ..Raster::default()
            };
            splat_program.render(gpu, &raster)
        };
        Pipelines {
            depth: [depth(None), depth(Some(wgpu::Face::Front))].map(Instrumented::timed),
            splat: Instrumented {
                timed: Some(splat("fs_splat", false)),
                counting: Some(splat("fs_splat_count", true)),
            },
            project: Instrumented::timed(project_program.compute(gpu, "project", None)),
            count_patches: Instrumented::counting(splat_program.compute(
                gpu,
                "count_patches",
                None,
            )),
        }
    }
}

// `Instance` is a vertex buffer read through vertex attributes (no WGSL struct), and
// `MicroPatch` is never uploaded as a struct.
#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(SOURCES => SsmUniform, Counts);
