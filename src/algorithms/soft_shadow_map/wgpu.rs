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
//!    ([`cpu::micro_patch`], [`cpu::extent_quad`]) and uploads them as instances; `transfer.bytes`
//!    and the host's wall time (`transfer_ms` under `execution`) are recorded. Without it
//!    (GPU-only, §4.3) the vertex shader reads the occluder map itself, one instance per texel.
//! 3. `project` — a compute pass over the gbuffer looks the merged (max, §3.5) SSM up with
//!    bilinear weights.
//!
//! The timed submission runs the passes with timestamps; an instrumented replay of `splat`
//! counts fragments (`fill`) and those that hide nothing (`overdraw`) with WGSL atomics.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};

use super::cpu::{extent_quad, micro_patch};
use super::{LightFrame, Precision, SoftShadowMapOptions, Split};
use crate::algorithms::ExecContext;
use crate::algorithms::FrameOutput;
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::gpu::layout;
use crate::gpu::readback::{words, Staging};
use crate::gpu::timing::{self, read_ms_or_warn, PassTimer};
use crate::gpu::{gbuffer_positions, Gpu};
use crate::model::raster::BLOCK;
use crate::model::LANES;
use crate::record::{Counters, Phase};
use crate::visibility::VisibilityBuffer;

const WGSL: &str = include_str!("wgpu.wgsl");
const WORKGROUP: u32 = 8;

/// The `Ssm` uniform of wgpu.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct SsmUniform {
    occ_view_proj: [f32; 16],
    ssm_view_proj: [f32; 16],
    center: [f32; 3],
    resolution: u32,
    e_u: [f32; 3],
    width: u32,
    e_v: [f32; 3],
    height: u32,
    normal: [f32; 3],
    bias_texels: f32,
    occ_window: [f32; 4],
    ssm_window: [f32; 4],
    half: [f32; 2],
    near: f32,
    far: f32,
}

/// One micro-patch of the transfer path: the patch and its extent in NDC (lo, hi).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Instance {
    lo: [f32; 2],
    hi: [f32; 2],
    z_o: f32,
    extent: [f32; 4],
}

/// The `Counts` storage buffer of the instrumented replay.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Counts {
    fragments: u32,
    zero: u32,
    patches: u32,
    pad: u32,
}

fn window(f: &LightFrame) -> [f32; 4] {
    [f.x0, f.x1, f.y0, f.y1]
}

pub fn render(
    gpu: &Gpu,
    frame: &Frame,
    _: &ExecContext,
    o: &SoftShadowMapOptions,
) -> Result<FrameOutput> {
    if o.precision == Precision::Fp32 && !gpu.float32_blendable {
        return Err(Error::Unsupported(format!(
            "adapter {} cannot blend into R32Float (no FLOAT32_BLENDABLE): use precision fp16",
            gpu.info.name
        )));
    }
    let res = frame.params.map_resolution;
    if res > gpu.limits.max_texture_dimension_2d {
        return Err(Error::Resource(format!(
            "map_resolution {res} exceeds the adapter's largest texture ({})",
            gpu.limits.max_texture_dimension_2d
        )));
    }
    run(gpu, frame, o)
}

fn run(gpu: &Gpu, frame: &Frame, o: &SoftShadowMapOptions) -> Result<FrameOutput> {
    let device = &gpu.device;
    let (width, height) = (frame.width(), frame.height());
    let res = frame.params.map_resolution;
    let split = Split::of(&frame.flat);
    let (occ, ssm) = LightFrame::new(&frame.scene.light, frame.scene.bounds(), res)
        .focused(split.occluder_bounds);
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
        half: ssm.half.to_array(),
        near: ssm.near,
        far: ssm.far,
    };
    let init = |label: &str, contents: &[u8], usage| gpu.buffer_init(label, contents, 64, usage);
    let uniform_buf = init(
        "ssm uniform",
        bytemuck::bytes_of(&uniform),
        wgpu::BufferUsages::UNIFORM,
    );
    let counts = init(
        "ssm counts",
        bytemuck::bytes_of(&Counts::default()),
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
    );
    let positions: Vec<[f32; 3]> = frame
        .flat
        .mesh
        .positions
        .iter()
        .map(|p| p.to_array())
        .collect();
    let vertices = init(
        "vertices",
        bytemuck::cast_slice(&positions),
        wgpu::BufferUsages::VERTEX,
    );
    let occluder_indices: Vec<u32> = split.occluders.iter().flatten().copied().collect();
    let receiver_indices: Vec<u32> = split.receivers.iter().flatten().copied().collect();
    let occ_ib = init(
        "occluder indices",
        bytemuck::cast_slice(&occluder_indices),
        wgpu::BufferUsages::INDEX,
    );
    let rec_ib = init(
        "receiver indices",
        bytemuck::cast_slice(&receiver_indices),
        wgpu::BufferUsages::INDEX,
    );

    // The gbuffer: position with the hit flag, normal with the receives flag.
    let g = &frame.gbuffer;
    let gpos = gbuffer_positions(g);
    let gnrm: Vec<[f32; 4]> = (0..g.len())
        .map(|i| {
            let receives = g.is_hit(i)
                && split.receives[frame.flat.object_of_triangle[g.triangle[i] as usize] as usize];
            g.normal[i].extend(f32::from(u8::from(receives))).to_array()
        })
        .collect();
    let gpos_buf = init(
        "gbuffer positions",
        bytemuck::cast_slice(&gpos),
        wgpu::BufferUsages::STORAGE,
    );
    let gnrm_buf = init(
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

    let passes = o.passes as usize;
    // The occluder maps are read back for the paper's transfer to the CPU.
    let copy_src = wgpu::TextureUsages::COPY_SRC;
    let occ_maps: Vec<wgpu::Texture> = (0..passes)
        .map(|k| {
            gpu.map_texture(
                if k == 0 {
                    "occluder map"
                } else {
                    "occluder map back"
                },
                res,
                wgpu::TextureFormat::Depth32Float,
                copy_src,
            )
        })
        .collect();
    let receiver_map = gpu.map_texture(
        "receiver map",
        res,
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::empty(),
    );
    let ssm_format = match o.precision {
        Precision::Fp32 => wgpu::TextureFormat::R32Float,
        Precision::Fp16 => wgpu::TextureFormat::R16Float,
    };
    let ssm_maps: Vec<wgpu::Texture> = (0..passes)
        .map(|k| {
            gpu.map_texture(
                if k == 0 {
                    "soft shadow map"
                } else {
                    "soft shadow map back"
                },
                res,
                ssm_format,
                wgpu::TextureUsages::empty(),
            )
        })
        .collect();
    let view = |t: &wgpu::Texture| t.create_view(&Default::default());
    let occ_views: Vec<_> = occ_maps.iter().map(view).collect();
    let receiver_view = view(&receiver_map);
    let ssm_views: Vec<_> = ssm_maps.iter().map(view).collect();

    use wgpu::ShaderStages as S;
    let shared_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("ssm shared"),
        entries: &[
            layout::uniform(0, S::VERTEX | S::FRAGMENT | S::COMPUTE),
            layout::storage(1, S::FRAGMENT | S::COMPUTE, false),
        ],
    });
    let map_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("ssm map view"),
        entries: &[layout::uniform(0, S::VERTEX)],
    });
    let splat_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("ssm splat"),
        entries: &[
            layout::texture(1, S::VERTEX | S::COMPUTE, wgpu::TextureSampleType::Depth),
            layout::texture(2, S::FRAGMENT, wgpu::TextureSampleType::Depth),
        ],
    });
    let project_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("ssm project"),
        entries: &[
            layout::texture(
                0,
                S::COMPUTE,
                wgpu::TextureSampleType::Float { filterable: false },
            ),
            layout::texture(
                1,
                S::COMPUTE,
                wgpu::TextureSampleType::Float { filterable: false },
            ),
            layout::storage(2, S::COMPUTE, true),
            layout::storage(3, S::COMPUTE, true),
            layout::storage(4, S::COMPUTE, false),
        ],
    });
    let shared_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("ssm shared"),
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
    let map_group = |m: glam::Mat4| {
        let b = init(
            "map view",
            bytemuck::cast_slice(&m.to_cols_array()),
            wgpu::BufferUsages::UNIFORM,
        );
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("map view"),
            layout: &map_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: b.as_entire_binding(),
            }],
        })
    };
    let occ_group = map_group(occ.view_proj);
    let rec_group = map_group(ssm.view_proj);
    let splat_groups: Vec<wgpu::BindGroup> = occ_views
        .iter()
        .map(|v| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("ssm splat"),
                layout: &splat_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(v),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: wgpu::BindingResource::TextureView(&receiver_view),
                    },
                ],
            })
        })
        .collect();
    let project_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("ssm project"),
        layout: &project_layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&ssm_views[0]),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&ssm_views[passes - 1]),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: gpos_buf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: gnrm_buf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: visibility.as_entire_binding(),
            },
        ],
    });

    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("soft_shadow_map/wgpu.wgsl"),
        source: wgpu::ShaderSource::Wgsl(WGSL.into()),
    });
    let layout = |groups: &[Option<&wgpu::BindGroupLayout>]| {
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: groups,
            immediate_size: 0,
        })
    };
    let depth_layout = layout(&[Some(&shared_layout), Some(&map_layout)]);
    let splat_pl = layout(&[Some(&shared_layout), Some(&splat_layout)]);
    let project_pl = layout(&[Some(&shared_layout), None, Some(&project_layout)]);

    let depth_pipeline = |cull: Option<wgpu::Face>| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("ssm depth"),
            layout: Some(&depth_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_depth"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 12,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                })],
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: cull,
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
                entry_point: Some("fs_depth"),
                compilation_options: Default::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let depth_front = depth_pipeline(None);
    let depth_back = depth_pipeline(Some(wgpu::Face::Front));

    let instance_layout = [Some(wgpu::VertexBufferLayout {
        array_stride: size_of::<Instance>() as u64,
        step_mode: wgpu::VertexStepMode::Instance,
        attributes: &wgpu::vertex_attr_array![0 => Float32x2, 1 => Float32x2, 2 => Float32, 3 => Float32x4],
    })];
    let host = o.occluder_map_transfer;
    let splat_pipeline = |fs: &str| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(fs),
            layout: Some(&splat_pl),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some(if host {
                    "vs_splat_host"
                } else {
                    "vs_splat_device"
                }),
                compilation_options: Default::default(),
                buffers: if host { &instance_layout } else { &[] },
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(fs),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: ssm_format,
                    blend: Some(wgpu::BlendState {
                        color: wgpu::BlendComponent {
                            src_factor: wgpu::BlendFactor::One,
                            dst_factor: wgpu::BlendFactor::One,
                            operation: wgpu::BlendOperation::Add,
                        },
                        alpha: wgpu::BlendComponent::REPLACE,
                    }),
                    write_mask: wgpu::ColorWrites::RED,
                })],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let splat_timed = splat_pipeline("fs_splat");
    let splat_counting = splat_pipeline("fs_splat_count");
    let compute = |entry: &str, pl: &wgpu::PipelineLayout| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(pl),
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    };
    let project_pipeline = compute("project", &project_pl);
    let count_patches = compute("count_patches", &splat_pl);

    // Passes in timer order: maps (occluders, back faces, receivers), splat (per pass), project.
    let n_maps = passes + 1;
    let n_passes = (n_maps + passes + 1) as u32;
    let timer = PassTimer::new(gpu, n_passes);
    let depth_pass = |e: &mut wgpu::CommandEncoder,
                      i: usize,
                      target: &wgpu::TextureView,
                      pipeline: &wgpu::RenderPipeline,
                      group: &wgpu::BindGroup,
                      ib: &wgpu::Buffer,
                      count: usize| {
        let mut pass = timing::render_pass(
            e,
            wgpu::RenderPassDescriptor {
                label: Some("maps"),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: target,
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
            timer.as_ref().map(|t| (t, i as u32)),
        );
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &shared_group, &[]);
        pass.set_bind_group(1, group, &[]);
        pass.set_vertex_buffer(0, vertices.slice(..));
        pass.set_index_buffer(ib.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..count as u32, 0, 0..1);
    };
    let maps_wall = gpu.submit(|e| {
        depth_pass(
            e,
            0,
            &occ_views[0],
            &depth_front,
            &occ_group,
            &occ_ib,
            occluder_indices.len(),
        );
        if passes == 2 {
            depth_pass(
                e,
                1,
                &occ_views[1],
                &depth_back,
                &occ_group,
                &occ_ib,
                occluder_indices.len(),
            );
        }
        depth_pass(
            e,
            passes,
            &receiver_view,
            &depth_front,
            &rec_group,
            &rec_ib,
            receiver_indices.len(),
        );
    })?;

    // The transfer (§4.1): occluder maps to the host, patches and extents built there in the
    // cpu's block-linear order.
    let mut transfer_bytes = 0u64;
    let mut transfer_ms = 0.0;
    let mut host_patches = 0u64;
    let instance_bufs: Vec<(wgpu::Buffer, u32)> = if host {
        let start = Instant::now();
        let row = (res * 4).div_ceil(256) * 256;
        let stagings: Vec<Staging> = occ_maps
            .iter()
            .map(|_| {
                Staging::new(
                    gpu,
                    "occluder map readback",
                    u64::from(row) * u64::from(res),
                )
            })
            .collect();
        gpu.submit(|e| {
            for (s, t) in stagings.iter().zip(&occ_maps) {
                s.copy_texture(e, t, row);
            }
        })?;
        let mut bufs = Vec::new();
        for s in &stagings {
            let depth: Vec<f32> = words(&s.read(gpu)?);
            transfer_bytes += u64::from(res) * u64::from(res) * 4;
            let mut inst = Vec::new();
            let blocks = res.div_ceil(BLOCK);
            for by in 0..blocks {
                for bx in 0..blocks {
                    for l in 0..LANES as u32 {
                        let (i, j) = (bx * BLOCK + l % BLOCK, by * BLOCK + l / BLOCK);
                        if i >= res || j >= res {
                            continue;
                        }
                        let d = depth[(j * row / 4 + i) as usize];
                        if let Some(p) = micro_patch(&occ, i, j, d) {
                            let q = extent_quad(&ssm, &p);
                            inst.push(Instance {
                                lo: p.lo.to_array(),
                                hi: p.hi.to_array(),
                                z_o: p.z_o,
                                extent: [q[0].x, q[0].y, q[2].x, q[2].y],
                            });
                        }
                    }
                }
            }
            host_patches += inst.len() as u64;
            bufs.push((
                init(
                    "patches",
                    bytemuck::cast_slice(&inst),
                    wgpu::BufferUsages::VERTEX,
                ),
                inst.len() as u32,
            ));
        }
        transfer_ms = start.elapsed().as_secs_f64() * 1e3;
        bufs
    } else {
        Vec::new()
    };
    let texel_instances = res.div_ceil(BLOCK).pow(2) * LANES as u32;
    let splat = |e: &mut wgpu::CommandEncoder, pipeline: &wgpu::RenderPipeline, timed: bool| {
        for k in 0..passes {
            let mut pass = timing::render_pass(
                e,
                wgpu::RenderPassDescriptor {
                    label: Some("splat"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &ssm_views[k],
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: None,
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                },
                timer
                    .as_ref()
                    .filter(|_| timed)
                    .map(|t| (t, (n_maps + k) as u32)),
            );
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &shared_group, &[]);
            pass.set_bind_group(1, &splat_groups[k], &[]);
            if host {
                let (buf, n) = &instance_bufs[k];
                pass.set_vertex_buffer(0, buf.slice(..));
                pass.draw(0..4, 0..*n);
            } else {
                pass.draw(0..4, 0..texel_instances);
            }
        }
    };
    let splat_wall = gpu.submit(|e| splat(e, &splat_timed, true))?;
    let vis_staging = Staging::new(gpu, "visibility readback", visibility.size());
    let project_wall = gpu.submit(|e| {
        {
            let mut pass =
                timing::compute_pass(e, "project", timer.as_ref().map(|t| (t, n_passes - 1)));
            pass.set_pipeline(&project_pipeline);
            pass.set_bind_group(0, &shared_group, &[]);
            pass.set_bind_group(2, &project_group, &[]);
            pass.dispatch_workgroups(width.div_ceil(WORKGROUP), height.div_ceil(WORKGROUP), 1);
        }
        vis_staging.copy(e, &visibility);
        if let Some(t) = &timer {
            t.resolve(e);
        }
    })?;
    let data: Vec<f32> = words(&vis_staging.read(gpu)?);
    let mut warnings: Vec<String> = split.warning().into_iter().collect();
    let times = read_ms_or_warn(gpu, &timer, &mut warnings)?;
    let gpu_ms = times.ms.clone();

    // The instrumented replay of `splat`.
    let counts_staging = Staging::new(gpu, "counts readback", counts.size());
    gpu.submit(|e| {
        e.clear_buffer(&counts, 0, None);
        splat(e, &splat_counting, false);
        if !host {
            for group in &splat_groups {
                let mut pass = e.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("count_patches"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&count_patches);
                pass.set_bind_group(0, &shared_group, &[]);
                pass.set_bind_group(1, group, &[]);
                pass.dispatch_workgroups(res.div_ceil(WORKGROUP), res.div_ceil(WORKGROUP), 1);
            }
        }
        counts_staging.copy(e, &counts);
    })?;
    let c: Counts = words::<Counts>(&counts_staging.read(gpu)?)[0];

    let sum = |r: std::ops::Range<usize>| gpu_ms.as_ref().map(|t| t[r].iter().sum::<f64>());
    let mut maps_c = Counters::default();
    if host {
        maps_c.set("transfer.bytes", transfer_bytes as f64);
    }
    let mut splat_c = Counters::default();
    splat_c.set("fill", f64::from(c.fragments));
    splat_c.set("overdraw", f64::from(c.zero));
    splat_c.set(
        "ssm.micro_patches",
        if host {
            host_patches as f64
        } else {
            f64::from(c.patches)
        },
    );
    splat_c.set(
        "ssm.occluder_texels",
        (passes as u64 * u64::from(res) * u64::from(res)) as f64,
    );
    let phase = |name: &str, wall_ms: f64, gpu_ms: Option<f64>, counters: Counters| Phase {
        name: name.into(),
        wall_ms,
        model_ms: None,
        gpu_ms,
        counters,
    };
    let phases = vec![
        phase("maps", maps_wall + transfer_ms, sum(0..n_maps), maps_c),
        phase("splat", splat_wall, sum(n_maps..n_maps + passes), splat_c),
        phase(
            "project",
            project_wall,
            sum(n_maps + passes..n_passes as usize),
            Counters::default(),
        ),
    ];
    let mut counters = Counters::default();
    for p in &phases {
        counters.merge(&p.counters);
    }
    let mut execution = gpu.execution();
    times.record(&mut execution);
    execution.insert("transfer_ms".into(), serde_json::json!(transfer_ms));
    execution.insert(
        "ssm_format".into(),
        serde_json::json!(format!("{ssm_format:?}")),
    );
    execution.insert(
        "extents".into(),
        serde_json::json!(if host {
            "host (occluder map transferred)"
        } else {
            "device (vertex shader)"
        }),
    );
    let mut out = FrameOutput {
        visibility: VisibilityBuffer {
            width,
            height,
            data,
        },
        counters,
        phases,
        model_ms: None,
        gpu_ms: gpu_ms.map(|t| t.iter().sum()),
        execution,
        warnings,
        rgb: None,
    };
    super::cpu::record_receivers_outside(frame, &split, &mut out);
    Ok(out)
}

#[cfg(test)]
mod layout_tests {
    use super::*;
    use crate::gpu::wgsl_layout::assert_wgsl_layout;

    /// `SsmUniform` and `Counts`; `Instance` is a vertex buffer read through vertex attributes
    /// (no WGSL struct), and `MicroPatch` is never uploaded as a struct.
    #[test]
    fn uniforms_match_wgsl() {
        assert_wgsl_layout!(WGSL, "Ssm", SsmUniform {
            occ_view_proj, ssm_view_proj, center, resolution, e_u, width, e_v, height, normal,
            bias_texels, occ_window, ssm_window, half as "half_size", near, far
        });
        assert_wgsl_layout!(
            WGSL,
            "Counts",
            Counts {
                fragments,
                zero,
                patches,
                pad
            }
        );
    }
}
