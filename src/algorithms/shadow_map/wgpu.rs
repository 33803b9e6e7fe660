//! The wgpu execution of the shadow-map family (`hard_shadow_map`, `pcss`): two GPU passes.
//! `penumbra_map` builds on the same passes ([`Passes`]), with its penumbra map between them.
//!
//! 1. `light_raster` — a render pass draws the occluders' triangles (penumbra_map: every
//!    triangle, receivers too) from the light centre ([`LightView`]) into a `map_resolution`²
//!    Depth32Float map (see `light_raster.wgsl`).
//! 2. `eye_lookup` — a compute pass over the frame's gbuffer, uploaded as storage buffers (the
//!    eye pass is shared by all executions, so parity is about the shadow algorithm alone),
//!    writes the visibility buffer with the algorithm's `visibility_at` (the kernel in
//!    `light_view.wgsl`, shared with dbuffer; `eye_lookup.wgsl` and each algorithm's `wgpu.wgsl`).
//!
//! Timed, then replayed instrumented ([`crate::gpu::pass`]): WGSL atomics count the light
//! raster's fragments and the texels they cover (`fill` and `overdraw` in the cpu-model's terms:
//! every rasterized fragment; those that did not end up in the map) and the lookup's taps.
//! Memory traffic is estimated from formats and those counts (`mem_est.<buffer>.*`).

use super::Phase;
use super::{vogel_disk, Bias, FaceView, LightViews, ViewFit};
use crate::algorithms::algorithm::FrameOutput;
use crate::counters::names;
use crate::error::Result;
use crate::frame::Frame;
use crate::gpu::pass::{
    gpu_struct, tiles, view as view_resource, Bind::*, Compute, EyeBuffers, Instrumented, Layout,
    Mesh, Pass, Program, Raster, Readout, Render, Shared, Statistics, Timed, DEPTH_TEXEL_BYTES,
};
use crate::gpu::readback::first;
use crate::gpu::{Needs, Run};
use crate::record::Counters;

/// The light-view helpers (`project`, `linear_depth`, `texel_world`, `bias_at`) of the eye
/// lookup and of dbuffer, joined after their `Light` struct.
pub(crate) const LIGHT_VIEW_WGSL: &str = include_str!("light_view.wgsl");
/// Group 0 of the family's passes (after the structs of [`PRELUDE`]).
const PRELUDE_WGSL: &str = include_str!("light.wgsl");
pub(crate) const LIGHT_RASTER_WGSL: &str = include_str!("light_raster.wgsl");
pub(crate) const EYE_LOOKUP_WGSL: &str = include_str!("eye_lookup.wgsl");

/// Side of the square compute workgroups (`@workgroup_size(8, 8)` in light_view.wgsl).
const WORKGROUP: u32 = 8;
/// Bytes of one gbuffer entry (a `vec4<f32>`, position or normal).
const GBUFFER_ENTRY_BYTES: f64 = 16.0;
/// Bytes of one occluder vertex (`vec3<f32>`).
const VERTEX_BYTES: f64 = 12.0;

/// What an algorithm of the family adds to the shared passes.
pub struct Lookup<'a> {
    /// The algorithm's id, for its errors.
    pub id: &'a str,
    /// The algorithm's WGSL defining `visibility_at(uv, z_r, bias) -> f32`.
    pub wgsl: &'a str,
    pub bias: Bias,
    /// PCSS tap counts (unused by the hard test).
    pub blocker_samples: u32,
    pub pcf_samples: u32,
}

impl<'a> Lookup<'a> {
    /// The lookup of algorithm `id`: `wgsl` with `bias` and no PCSS taps.
    pub fn new(id: &'a str, wgsl: &'a str, bias: Bias) -> Lookup<'a> {
        Lookup {
            id,
            wgsl,
            bias,
            blocker_samples: 0,
            pcf_samples: 0,
        }
    }
}

gpu_struct! {
    /// The light view of a pass (group 0, binding 0 of every pass).
    struct LightUniform as "Light" {
        view_proj: [f32; 16] => "mat4x4<f32>",
        /// World to light-view space (the receiver-plane test of the PCSS blocker search).
        view: [f32; 16] => "mat4x4<f32>",
        eye: [f32; 3] => "vec3<f32>",
        radius: f32 => "f32",
        near: f32 => "f32",
        far: f32 => "f32",
        tan_half_fov: f32 => "f32",
        resolution: u32 => "u32",
        bias_constant: f32 => "f32",
        bias_slope: f32 => "f32",
        blocker_samples: u32 => "u32",
        pcf_samples: u32 => "u32",
        width: u32 => "u32",
        height: u32 => "u32",
        /// The cube face whose receivers this view shades ([`FaceView::face_code`]; 6: all).
        face: u32 => "u32",
        pad: u32 => "u32",
    }
}

gpu_struct! {
    /// The counters of the instrumented replay (group 0, binding 1).
    pub(crate) struct Counts as "Counts" {
        /// Fragments rasterized.
        fragments: u32 => "atomic<u32>",
        /// Shadow-map texels covered.
        covered: u32 => "atomic<u32>",
        /// Shadow-map taps of the lookup.
        taps: u32 => "atomic<u32>",
        wasted_taps: u32 => "atomic<u32>",
        /// Fragments a fragment program discarded (penumbra map).
        discarded: u32 => "atomic<u32>",
        /// Taps of a second map in the lookup (penumbra map).
        extra_taps: u32 => "atomic<u32>",
    }
}

/// The family's WGSL prelude, joined before each of its shaders: the `Light` and `Counts`
/// structs and group 0 (`light.wgsl`).
pub(crate) const PRELUDE: [&str; 3] = [LightUniform::WGSL, Counts::WGSL, PRELUDE_WGSL];

/// Renders `frame` with the family's two passes and the algorithm's lookup, once per light view
/// ([`ViewFit::CubeWhenWide`]: one frustum, or the faces of a cube map, each pixel from the
/// face that shades it; phases `light_raster[+x]`, `eye_lookup[+x]`, ... per face).
pub fn render(gpu: &Run, frame: &Frame, lookup: &Lookup) -> Result<FrameOutput> {
    check_limits(gpu, frame, lookup.id)?;
    let views = LightViews::fit(frame, ViewFit::CubeWhenWide);
    let mut merged: Option<FrameOutput> = None;
    // Only occluders cast: a receiver-only object is left out of the map.
    let occluders = frame.scene.occluders();
    for face in &views.views {
        let casters = face.view.casters(&occluders);
        let mut out = Passes::new(gpu, frame, lookup, face, &casters, None).run(frame)?;
        for p in &mut out.phases {
            p.name = face.phase(&p.name);
        }
        let Some(all) = &mut merged else {
            merged = Some(out);
            continue;
        };
        face.take_owned(frame, &out.visibility, &mut all.visibility);
        all.phases.extend(out.phases);
        all.gpu_ms = all.gpu_ms.zip(out.gpu_ms).map(|(a, b)| a + b);
        for w in out.warnings {
            if !all.warnings.contains(&w) {
                all.warnings.push(w);
            }
        }
    }
    let mut out = merged.expect("a fit has at least one view");
    if views.views.len() > 1 {
        // The run's counters are its phases' summed (derived figures such as `overdraw_ratio`
        // are added for every record by `crate::counters::derive`).
        out.counters = Counters::default();
        for p in &out.phases {
            out.counters.merge(&p.counters);
        }
    }
    views.record(&mut out);
    Ok(out)
}

/// Checks the frame against the adapter's limits for algorithm `id` before anything is
/// allocated: the map's resolution and the gbuffer's bytes.
pub(crate) fn check_limits(gpu: &Run, frame: &Frame, id: &str) -> Result<()> {
    let gbuffer = frame.gbuffer.len() as u64 * GBUFFER_ENTRY_BYTES as u64;
    let needs = Needs {
        buffers: &[("gbuffer", gbuffer)],
        ..Needs::map(frame.params.map_resolution)
    };
    gpu.check_limits(id, needs)
}

/// The resources and pipelines of one frame.
pub(crate) struct Passes<'g> {
    pub gpu: &'g Run,
    pub width: u32,
    pub height: u32,
    pub resolution: u32,
    occluders: Mesh,
    /// The shadow map (Depth32Float, NDC depth).
    pub depth_view: wgpu::TextureView,
    pub eye: EyeBuffers,
    /// Group 0 of every pass: the light uniform and the counters.
    pub shared: Shared,
    lookup_group: wgpu::BindGroup,
    /// The light raster: `fs_depth` timed, `fs_count` in the replay.
    raster: Render,
    /// The eye lookup (`INSTRUMENT` counts its taps in the replay).
    pub lookup: Compute,
    /// The covered texels of the map (replay only).
    pub count_covered: Compute,
}

impl<'g> Passes<'g> {
    /// The passes of `frame` in light view `face` with the shadow map of `occluders` (the
    /// scene's triangles that meet the view, or a stand-in for them) and `lookup`'s
    /// `visibility_at`; `extra` is the layout of a group 2 that the lookup's WGSL declares
    /// (bound by [`Self::compute`]).
    pub fn new(
        gpu: &'g Run,
        frame: &Frame,
        lookup: &Lookup,
        face: &FaceView,
        occluders: &crate::scene::Mesh,
        extra: Option<&Layout>,
    ) -> Passes<'g> {
        let (width, height) = (frame.width(), frame.height());
        let resolution = frame.params.map_resolution;
        let view = face.view;
        let uniform = LightUniform {
            view_proj: view.view_proj.to_cols_array(),
            view: view.view.to_cols_array(),
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
        // The casters of the view, indexed as in `occluders`, as the cpu executions draw them.
        let occluders = Mesh::of(gpu, "occluders", occluders);
        // The gbuffer (position with the hit flag in w, the eye-facing normal), the visibility.
        let eye = EyeBuffers::new(gpu, &frame.gbuffer, |_| 0.0);
        let depth_format = wgpu::TextureFormat::Depth32Float;
        let depth_view = gpu.map_view("shadow map", resolution, depth_format);

        use wgpu::ShaderStages as S;
        // Group 0 (both shaders): the light uniform and the counters; group 1 (eye lookup):
        // shadow map, gbuffer, visibility.
        let shared = Shared::new::<Counts>(gpu, "shadow map shared", &uniform);
        // The PCSS taps on the unit disc (the blocker search's, then the filter's), computed on
        // the host as the cpu executions compute them: a GPU's sine and cosine are not the
        // host's (Vulkan bounds their error only by 2⁻¹¹ on [−π, π], and the golden angle's
        // multiples run far past π), and a tap moved across a texel's edge changes a pixel.
        let (nb, np) = (lookup.blocker_samples, lookup.pcf_samples);
        let mut taps: Vec<[f32; 2]> = (0..nb).map(|i| vogel_disk(i, nb).to_array()).collect();
        taps.extend((0..np).map(|j| vogel_disk(j, np).to_array()));
        // A binding holds at least one element.
        taps.resize(taps.len().max(1), [0.0; 2]);
        let taps = gpu.upload("pcss taps", &taps, wgpu::BufferUsages::STORAGE);
        let mut binds = eye.binds_after([(Depth, view_resource(&depth_view))]);
        binds.push((ReadOnly, taps.as_entire_binding()));
        let (lookup_layout, lookup_group) =
            Layout::bound(gpu, "eye lookup", S::COMPUTE | S::FRAGMENT, &binds);
        let sources = [&PRELUDE[..], &[LIGHT_RASTER_WGSL]].concat();
        let raster = Program::new(gpu, "light_raster.wgsl", &sources, &[Some(&shared.layout)]);
        let mut sources = PRELUDE.to_vec();
        sources.extend([LIGHT_VIEW_WGSL, EYE_LOOKUP_WGSL, lookup.wgsl]);
        let groups = [Some(&shared.layout), Some(&lookup_layout), extra];
        let program = Program::new(gpu, "eye_lookup.wgsl", &sources, &groups);
        let raster_pipeline =
            |fs| raster.render(gpu, &Raster::of_vertices("vs", fs, &Mesh::POSITION));
        Passes {
            gpu,
            width,
            height,
            resolution,
            occluders,
            depth_view,
            eye,
            shared,
            lookup_group,
            raster: Instrumented {
                timed: Some(raster_pipeline("fs_depth")),
                counting: Some(raster_pipeline("fs_count")),
            },
            lookup: program.instrumented(gpu, "eye_lookup"),
            count_covered: Instrumented::counting(program.compute(
                gpu,
                "count_covered",
                Some(true),
            )),
        }
    }

    /// The light raster.
    pub fn raster_pass(&self) -> Pass<'_> {
        let draw = (self.occluders).draw(&self.raster, None, Some(&self.depth_view));
        Pass::draw("light_raster", &[Some(&self.shared.group)], draw)
    }

    /// A compute pass of `pipeline` over `size` (8×8 workgroups) with the eye lookup's bind
    /// groups, and `extra` as group 2 where the pipeline has one.
    pub fn compute<'a>(
        &'a self,
        label: &'a str,
        pipeline: &'a Compute,
        size: (u32, u32),
        extra: Option<&'a wgpu::BindGroup>,
    ) -> Pass<'a> {
        let groups = [Some(&self.shared.group), Some(&self.lookup_group), extra];
        Pass::compute(label, &groups, pipeline, tiles(size, WORKGROUP))
    }

    /// The eye lookup over the image.
    pub fn lookup_pass<'a>(&'a self, extra: Option<&'a wgpu::BindGroup>) -> Pass<'a> {
        let image = (self.width, self.height);
        self.compute("eye_lookup", &self.lookup, image, extra)
    }

    /// The texels of the shadow map left covered (instrumented replay only).
    pub fn covered_pass<'a>(&'a self, extra: Option<&'a wgpu::BindGroup>) -> Pass<'a> {
        let res = (self.resolution, self.resolution);
        self.compute("count_covered", &self.count_covered, res, extra)
    }

    fn run(&self, frame: &Frame) -> Result<FrameOutput> {
        let readback = [&self.eye.visibility];
        let mut run = Timed::new(self.gpu, Phase::ALL, Statistics::All, &readback)
            .counting_into(&self.shared.counts, Readout::End);
        run.submit(
            Phase::LightRaster,
            &[self.raster_pass(), self.covered_pass(None)],
        )?;
        run.submit(Phase::EyeLookup, &[self.lookup_pass(None)])?;
        let timing = run.finish()?;
        let c: Counts = first(&timing.counts[0]);
        let counters = vec![
            (Phase::LightRaster, self.raster_counters(&c)),
            (Phase::EyeLookup, self.lookup_counters(frame, &c)),
        ];
        Ok(timing.output((self.width, self.height), counters, NOTE))
    }

    /// `light_raster`: fill is every rasterised fragment, overdraw those that did not end up in
    /// the map (fragments minus covered texels).
    pub fn raster_counters(&self, c: &Counts) -> Counters {
        let fragments = f64::from(c.fragments);
        let mut k = Counters::default();
        k.add_fill(fragments, fragments - f64::from(c.covered));
        k.set(names::SHADOW_MAP_COVERED_TEXELS, f64::from(c.covered));
        let map = ("shadow_map", self.resolution, fragments);
        (self.occluders).depth_traffic(&mut k, ("occluder", VERTEX_BYTES), map, &[]);
        k
    }

    /// `eye_lookup`: no fill (nothing is rasterized); the shadow-map taps, and the PCF taps of
    /// pixels left fully lit or fully shadowed, whose filtering changed nothing.
    pub fn lookup_counters(&self, frame: &Frame, c: &Counts) -> Counters {
        let pixels = f64::from(self.width) * f64::from(self.height);
        let hits = frame.gbuffer.mask().iter().filter(|&&h| h).count() as f64;
        let taps = f64::from(c.taps);
        let mut k = Counters::default();
        k.set(names::SHADOW_MAP_TAPS, taps);
        k.set(names::SHADOW_MAP_TAPS_WASTED, f64::from(c.wasted_taps));
        // Every pixel reads its position (and hit flag); hit pixels also read their normal.
        let gbuffer = (pixels + hits) * GBUFFER_ENTRY_BYTES;
        let map_read = taps * DEPTH_TEXEL_BYTES;
        let reads = [("gbuffer", gbuffer), ("shadow_map", map_read)];
        k.add_traffic("mem_est", &reads, &[("visibility", pixels * 4.0)]);
        k
    }
}

/// How the family's counters were obtained (`execution.gpu_counters`).
pub(crate) const NOTE: &str =
    "fill/overdraw from an instrumented replay (WGSL atomics); mem_est.* \
     estimated from formats and counts";

// `LightUniform` and `Counts` against the family's shaders as their pipelines join them (the
// eye lookup as `hard_shadow_map` completes it).
#[cfg(test)]
crate::gpu::wgsl_layout::layout_test!(
    [&PRELUDE[..], &[LIGHT_RASTER_WGSL]].concat(),
    [
        &PRELUDE[..],
        &[LIGHT_VIEW_WGSL, EYE_LOOKUP_WGSL, include_str!("../hard_shadow_map/wgpu.wgsl")]
    ]
    .concat() => LightUniform, Counts
);
