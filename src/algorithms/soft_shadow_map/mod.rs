//! Soft shadow maps (paper 002, Atty, Holzschuch, Lapierre, Hasenfratz, Hansen and Sillion 2006).
//!
//! The occluders are discretized by a depth map from the centre of a rectangular light, the
//! *occluder map*, axis-aligned with the light and of its aspect ratio (§3.2): each non-empty
//! pixel becomes a *micro-patch*, the rectangle the pixel covers at its depth, parallel to the
//! light. A second depth map of the same view, the *receiver map*, holds the receivers. Each
//! micro-patch hides a part of the light from the receivers inside its *penumbra extent*, a
//! rectangular pyramid whose apex follows from similar triangles (§3.3); per texel of the *soft
//! shadow map* (SSM) inside that extent, the micro-patch projected from the receiver point onto
//! the light is an axis-aligned rectangle, and the fraction of the light it hides is the product
//! of two interval overlaps (§3.4, §4.2). The fractions of all micro-patches are added up
//! (additive blending, §4.1) and the SSM is projected onto the scene (phase `project`).
//!
//! Two-pass soft shadow maps (§3.5) discretize the occluders twice, once by their nearest
//! surfaces and once by their back faces, and merge the two SSMs by the maximum.
//!
//! Accumulation precision (§5.1.3, Appendix A): each add is rounded to half precision with
//! `precision: "fp16"`, as blending into a half-float target does, so a micro-patch that hides
//! less than 2⁻¹⁰ of what is already accumulated is lost ([`Blend::AddHalf`]; how the sum rounds
//! is the implementation's choice, option `fp16_rounding`).
//!
//! Geometry is split by the scene tags ([`Role`](crate::scene::Role)) as the paper splits it:
//! objects tagged occluder go into the occluder map, objects tagged receiver *only* into the
//! receiver map, and only those receive the soft shadow (no self-shadowing, §1). A scene with no
//! receiver-only object uses all receiver-tagged objects as receivers (with a warning): a
//! micro-patch then shadows a receiver only when it lies nearer the light by more than the bias.
//!
//! All coordinates are in the *light frame*: origin at the light centre, x and y along the
//! light's half-axes, z the distance from the light plane toward the scene. The maps are a
//! perspective projection from the light centre onto planes parallel to the light, so their
//! "tan" coordinates (x/z, y/z) are affine in texels ([`LightFrame`]).
//!
//! This file holds the math, once; [`cpu`] runs it on the CPU executions and [`wgpu`] mirrors
//! it in WGSL.

pub mod cpu;
pub mod wgpu;

use glam::{Mat4, Vec2, Vec3};

use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, MethodLimit, WgpuEntry, WgpuParity,
    WorkEstimate,
};
use crate::algorithms::work;
use crate::counters::names;
use crate::error::InputError;
use crate::frame::{Frame, FrameOutput, RunParams};
use crate::model::raster::{Blend, HalfRounding};
use crate::record::phases;
use crate::scene::LightKind;
use crate::scene::{Bounds, FlatMesh, Light};

phases! {
    /// The phases of a `soft_shadow_map` run (002 §3): the occluder and receiver depth maps,
    /// the micro-patches splatted into the receivers' visibility map, and its projection onto
    /// the eye samples.
    pub enum Phase {
        Maps => "maps",
        Splat => "splat",
        Project => "project",
    }
}

pub const ID: &str = "soft_shadow_map";

/// Widest half-angle of the maps' frustum around the light normal (as the shadow-map family's
/// `MAX_HALF_FOV_DEG`): scene parts beyond it are outside the maps, hence lit.
pub const MAX_HALF_ANGLE_DEG: f32 = 80.0;

/// Accumulation precision of the soft shadow map (§5.1.3, Appendix A).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// 32-bit float adds (R32Float blending on wgpu).
    #[default]
    Fp32,
    /// Every add rounded to IEEE half (R16Float blending on wgpu), the paper's hardware; the
    /// cpu executions round as `fp16_rounding` says.
    Fp16,
}

/// Options of `soft_shadow_map` (scenario `options.soft_shadow_map`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SoftShadowMapOptions {
    /// 1: one occluder map (nearest surfaces); 2: nearest and back faces merged by max (§3.5).
    pub passes: u32,
    pub precision: Precision,
    /// The paper's pipeline (§4.1): the occluder map is read back to the host, which generates
    /// the penumbra extents. Counted as `transfer.bytes` and, on cpu-model, as modelled time at
    /// `transfer_gb_per_s`. `false` is the GPU-only variant of §4.3 (extents generated on the
    /// device from the occluder map).
    pub occluder_map_transfer: bool,
    /// Bandwidth of the device-to-host link for the transfer, GB/s. Default 1 GB/s: an
    /// assumption, the order of the readback rates of the paper's PCIe-era hardware.
    pub transfer_gb_per_s: f64,
    /// A micro-patch shadows a receiver only when it lies nearer the light by more than this many
    /// map texels (at the receiver's depth).
    pub bias_texels: f32,
    /// With `precision: "fp16"`, how the cpu executions round each add: `"toward_zero"`
    /// (default; Mesa's llvmpipe) or `"nearest_even"` (NVIDIA). Vulkan leaves the rounding of
    /// blending to the implementation; the wgpu execution rounds as its adapter does, records
    /// it (`execution.fp16_blend_rounding`) and warns where it differs from this option.
    pub fp16_rounding: HalfRounding,
}

impl Default for SoftShadowMapOptions {
    fn default() -> Self {
        SoftShadowMapOptions {
            passes: 1,
            precision: Precision::default(),
            occluder_map_transfer: true,
            transfer_gb_per_s: 1.0,
            bias_texels: 1.5,
            fp16_rounding: HalfRounding::default(),
        }
    }
}

impl AlgorithmOptions for SoftShadowMapOptions {
    fn validate(&self) -> Result<(), InputError> {
        let field = |name: &str| format!("$.options.{ID}.{name}");
        InputError::check_range(field("passes"), self.passes, 1..=2)?;
        if !(self.transfer_gb_per_s.is_finite() && self.transfer_gb_per_s > 0.0) {
            return Err(InputError::new(
                field("transfer_gb_per_s"),
                format!(
                    "must be a finite number > 0, got {}",
                    self.transfer_gb_per_s
                ),
            ));
        }
        InputError::check_non_negative(field("bias_texels"), self.bias_texels)
    }
}

/// Bytes of the algorithm's own buffers for the largest configuration (two passes): two
/// occluder maps, the receiver map and two SSMs of f32 per texel; at most one micro-patch per
/// occluder texel per pass with its quad (4 vertices of 12 bytes, 2 triangles of 12 bytes, the
/// 20-byte patch); per eye pixel the gbuffer copies (2 × 16 bytes), the visibility and its
/// readback (2 × 4 bytes).
pub fn memory_estimate(p: &RunParams) -> u64 {
    let texels = u64::from(p.map_resolution) * u64::from(p.map_resolution);
    let pixels = u64::from(p.image[0]) * u64::from(p.image[1]);
    texels * 5 * 4 + 2 * texels * (4 * 12 + 2 * 12 + 20) + pixels * (2 * 16 + 2 * 4)
}

/// The light frame and the maps' projection (§3.2): a perspective view from the light centre
/// looking along the light normal, axis-aligned with the light, with a window in tan space
/// `[x0, x1] × [y0, y1]` of the light's aspect ratio that encloses the scene. Texel `(i, j)`
/// (row `j` from the top) covers tan `[x0 + i·dx, x0 + (i+1)·dx] × [y1 − (j+1)·dy, y1 − j·dy]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightFrame {
    pub center: Vec3,
    /// Unit light axes in world space; `e_u × e_v` points away from the scene.
    pub e_u: Vec3,
    pub e_v: Vec3,
    /// Unit normal toward the scene.
    pub normal: Vec3,
    /// Half-widths of the light along `e_u` and `e_v` (`LL'/2` of §3.3 per axis).
    pub half: Vec2,
    /// Tan-space window.
    pub x0: f32,
    pub x1: f32,
    pub y0: f32,
    pub y1: f32,
    pub near: f32,
    pub far: f32,
    pub resolution: u32,
    /// World to clip (depth 0..1 between `near` and `far`), for the rasterizers.
    pub view_proj: Mat4,
}

impl LightFrame {
    /// The frame of `light` (a rectangle; another kind is taken as the square of its size facing
    /// the scene) enclosing `scene`, at `resolution`² texels.
    pub fn new(light: &Light, scene: Bounds, resolution: u32) -> LightFrame {
        let (center, hu, hv) = light.emitter_frame(scene.center());
        let e_u = hu.normalize_or(Vec3::X);
        let mut e_v = (hv - e_u * hv.dot(e_u)).normalize_or(e_u.any_orthogonal_vector());
        let mut normal = e_u.cross(e_v);
        if normal.dot(scene.center() - center) < 0.0 {
            normal = -normal;
        }
        // The view looks down −z: right-handed (e_u, e_v, −normal).
        if e_u.cross(e_v).dot(normal) > 0.0 {
            e_v = -e_v;
        }
        let half = Vec2::new(hu.length(), hv.length()).max(Vec2::splat(1e-6));
        let to_light = |p: Vec3| {
            let d = p - center;
            Vec3::new(d.dot(e_u), d.dot(e_v), d.dot(normal))
        };
        let mut far: f32 = 1e-3;
        let mut near = f32::INFINITY;
        for c in scene.corners() {
            let z = to_light(c).z;
            far = far.max(z);
            near = near.min(z);
        }
        let far = far * 1.01;
        let near = (near * 0.99).max(far * 1e-3);
        let mut f = LightFrame {
            center,
            e_u,
            e_v,
            normal,
            half,
            x0: -1.0,
            x1: 1.0,
            y0: -1.0,
            y1: 1.0,
            near,
            far,
            resolution,
            view_proj: Mat4::IDENTITY,
        };
        let (lo, hi) = f.tan_bounds(scene);
        f.set_window(lo, hi);
        f
    }

    /// The tan-space rectangle of `b`'s corners (points nearer than the near plane taken at it,
    /// angles clamped to [`MAX_HALF_ANGLE_DEG`]), and the smallest depth of a corner.
    fn tan_bounds(&self, b: Bounds) -> (Vec2, Vec2) {
        let max_tan = Vec2::splat(MAX_HALF_ANGLE_DEG.to_radians().tan());
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for c in b.corners() {
            let l = self.to_light(c);
            let t = (Vec2::new(l.x, l.y) / l.z.max(self.near)).clamp(-max_tan, max_tan);
            lo = lo.min(t);
            hi = hi.max(t);
        }
        (lo, hi)
    }

    /// Sets the window to `[lo, hi]` grown by 1 % and then to the light's aspect ratio (§3.2:
    /// the narrower side grows), and the projection to it.
    fn set_window(&mut self, lo: Vec2, hi: Vec2) {
        let pad = (hi - lo) * 0.01 + Vec2::splat(1e-4);
        let (lo, hi) = (lo - pad, hi + pad);
        let (mid, mut ext) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
        let aspect = self.half.x / self.half.y;
        if ext.x / ext.y < aspect {
            ext.x = ext.y * aspect;
        } else {
            ext.y = ext.x / aspect;
        }
        let (x0, x1, y0, y1) = (mid.x - ext.x, mid.x + ext.x, mid.y - ext.y, mid.y + ext.y);
        let view = Mat4::from_cols(
            self.e_u.extend(0.0),
            self.e_v.extend(0.0),
            (-self.normal).extend(0.0),
            self.center.extend(1.0),
        )
        .inverse();
        // Off-axis frustum: ndc.x = (2·x/(−z) − (x0 + x1)) / (x1 − x0), likewise y; depth 0 at
        // −near, 1 at −far.
        let (near, far) = (self.near, self.far);
        let (a, b) = (far / (near - far), near * far / (near - far));
        let proj = Mat4::from_cols_array(&[
            2.0 / (x1 - x0),
            0.0,
            0.0,
            0.0,
            0.0,
            2.0 / (y1 - y0),
            0.0,
            0.0,
            (x1 + x0) / (x1 - x0),
            (y1 + y0) / (y1 - y0),
            a,
            -1.0,
            0.0,
            0.0,
            b,
            0.0,
        ]);
        (self.x0, self.x1, self.y0, self.y1) = (x0, x1, y0, y1);
        self.view_proj = proj * view;
    }

    /// The windows of the two maps: the occluder map focused on the occluders (`occluders`, their
    /// bounds; §5.1.3: "our shadow map is focused on the moving occluder"), and the SSM (and
    /// receiver map) on the occluders grown by the widest penumbra extent, that of a micro-patch
    /// at the occluders' nearest depth seen from the far plane, within the scene's window.
    /// Without occluders both are the scene's window.
    pub fn focused(&self, occluders: Option<Bounds>) -> (LightFrame, LightFrame) {
        let Some(b) = occluders.filter(|b| !b.is_empty()) else {
            return (*self, *self);
        };
        let (lo, hi) = self.tan_bounds(b);
        let mut occ = *self;
        occ.set_window(lo, hi);
        let z_min = b
            .corners()
            .iter()
            .map(|&c| self.to_light(c).z)
            .fold(f32::INFINITY, f32::min)
            .max(self.near);
        let grow = self.half * (1.0 / z_min - 1.0 / self.far) + occ.texel_tan();
        let (slo, shi) = (
            (lo - grow).max(Vec2::new(self.x0, self.y0)),
            (hi + grow).min(Vec2::new(self.x1, self.y1)),
        );
        let mut ssm = *self;
        ssm.set_window(slo, shi);
        (occ, ssm)
    }

    /// `p` in the light frame: lateral (x, y) and depth z.
    pub fn to_light(&self, p: Vec3) -> Vec3 {
        let d = p - self.center;
        Vec3::new(d.dot(self.e_u), d.dot(self.e_v), d.dot(self.normal))
    }

    /// Size of a texel in tan space (`dx`, `dy`).
    #[inline]
    pub fn texel_tan(&self) -> Vec2 {
        Vec2::new(self.x1 - self.x0, self.y1 - self.y0) / self.resolution as f32
    }

    /// Tan coordinates of the centre of texel (i, j).
    #[inline]
    pub fn texel_center(&self, i: u32, j: u32) -> Vec2 {
        let d = self.texel_tan();
        Vec2::new(
            self.x0 + (i as f32 + 0.5) * d.x,
            self.y1 - (j as f32 + 0.5) * d.y,
        )
    }

    /// Continuous texel coordinates of tan `t` (texel centres at half-integers).
    pub fn tan_to_texel(&self, t: Vec2) -> Vec2 {
        let d = self.texel_tan();
        Vec2::new((t.x - self.x0) / d.x, (self.y1 - t.y) / d.y)
    }

    /// Tan `t` in the rasterizer's NDC.
    pub fn tan_to_ndc(&self, t: Vec2) -> Vec2 {
        Vec2::new(
            (2.0 * t.x - (self.x0 + self.x1)) / (self.x1 - self.x0),
            (2.0 * t.y - (self.y0 + self.y1)) / (self.y1 - self.y0),
        )
    }

    /// Depth from the light plane for a map's NDC depth.
    #[inline]
    pub fn linear_depth(&self, ndc: f32) -> f32 {
        self.near * self.far / (self.far - ndc * (self.far - self.near))
    }
}

/// A micro-patch (§3.2): the rectangle texel (i, j) of the occluder map covers at its depth
/// `z_o`, parallel to the light; `lo`/`hi` are its lateral corners in the light frame.
#[derive(Clone, Copy, Debug, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct MicroPatch {
    pub lo: Vec2,
    pub hi: Vec2,
    pub z_o: f32,
}

impl MicroPatch {
    pub fn of_texel(f: &LightFrame, i: u32, j: u32, z_o: f32) -> MicroPatch {
        let (c, d) = (f.texel_center(i, j), f.texel_tan() * 0.5);
        MicroPatch {
            lo: (c - d) * z_o,
            hi: (c + d) * z_o,
            z_o,
        }
    }

    /// `C_P`, the centre of the micro-patch, in the light frame.
    pub fn center(&self) -> Vec3 {
        ((self.lo + self.hi) * 0.5).extend(self.z_o)
    }
}

/// §3.3: the apex `O` of the penumbra pyramid of a micro-patch, per axis. With `r = LL'/PP'` the
/// ratio of the light's width to the patch's, `C_L O = r/(1+r) · C_L C_P` (`C_L` is the origin of
/// the light frame). When light and patch share their aspect ratio (§3.2) both axes give the
/// same point; otherwise the x and y components come from their own axis.
pub fn apex(f: &LightFrame, p: &MicroPatch) -> (Vec3, Vec3) {
    let cp = p.center();
    let r = (f.half * 2.0) / (p.hi - p.lo);
    let k = r / (Vec2::ONE + r);
    (cp * k.x, cp * k.y)
}

/// §3.3, Figure 8: the penumbra extent of a micro-patch on a plane parallel to the light at depth
/// `z_r`, from its apex: centre `C_L C_R = z_R/z_O · C_L O` and width
/// `RR' = LL' · (z_R − z_O)/z_O`, `z_O` here the depth of the apex. Returned in tan space
/// (divided by `z_r`) as (lo, hi). The SSM is a projective texture from the light centre, so the
/// extent of all receivers up to depth `z_r` lies within this one: the extents are drawn at the
/// far plane.
pub fn penumbra_extent(f: &LightFrame, p: &MicroPatch, z_r: f32) -> (Vec2, Vec2) {
    let (ox, oy) = apex(f, p);
    let centre = Vec2::new(ox.x / ox.z, oy.y / oy.z);
    let half = Vec2::new(
        f.half.x * (z_r - ox.z) / ox.z,
        f.half.y * (z_r - oy.z) / oy.z,
    ) / z_r;
    (centre - half, centre + half)
}

/// §4.2: the overlap of `[a, b]` with the light's `[0, 1]` (the paper's `MOV_SAT; SUB`).
#[inline]
pub fn overlap(a: f32, b: f32) -> f32 {
    b.clamp(0.0, 1.0) - a.clamp(0.0, 1.0)
}

/// §3.4 and §4.2: the fraction of the light hidden by micro-patch `p` from the receiver point at
/// tan `t_r` and depth `z_r`. The patch is projected from the receiver onto the light plane,
/// `l = R + (P − R) · z_R/(z_R − z_O)`, and scaled so that the light is `[0, 1]²`; the hidden
/// fraction is the product of the two interval overlaps. Zero unless the patch lies nearer the
/// light than the receiver by more than `bias`.
///
/// Branch-free (the overlap is computed on every receiver and the zero selected), so that a
/// loop over a block's lanes compiles to packed instructions.
#[inline]
pub fn occlusion(f: &LightFrame, p: &MicroPatch, t_r: Vec2, z_r: f32, bias: f32) -> f32 {
    let r = t_r * z_r;
    let k = z_r / (z_r - p.z_o);
    let inv = Vec2::ONE / (f.half * 2.0);
    let a = ((r + (p.lo - r) * k) + f.half) * inv;
    let b = ((r + (p.hi - r) * k) + f.half) * inv;
    let hidden = overlap(a.x, b.x) * overlap(a.y, b.y);
    if z_r - p.z_o <= bias {
        0.0
    } else {
        hidden
    }
}

/// What a wgpu run records of its adapter's half-float blend (`sums`, `Gpu::half_blend_sums`)
/// with option `fp16_rounding` = `option`: the adapter's rounding (`execution.fp16_blend_rounding`)
/// and a warning where it is not the option's, since the cpu executions' fp16 images then differ
/// from the adapter's by rounding accumulated over each texel's adds.
pub fn half_rounding(sums: [f32; 2], option: HalfRounding) -> (&'static str, Option<String>) {
    match HalfRounding::of_sums(sums) {
        Some(r) if r == option => (r.name(), None),
        Some(r) => (
            r.name(),
            Some(format!(
                "the adapter rounds half-float blends {}, the cpu executions {} \
                 (options.{ID}.fp16_rounding): their fp16 images differ by that rounding",
                r.name(),
                option.name()
            )),
        ),
        None => (
            "unknown",
            Some(format!(
                "the adapter's half-float blend rounds neither toward zero nor to nearest (1 + 3/4 \
                 and 1 + 1/4 of a half's step at 1 stored as {sums:?}): the cpu executions' fp16 \
                 images are not the adapter's"
            )),
        ),
    }
}

/// Bias in light-frame depth at receiver depth `z_r`: `bias_texels` map texels.
#[inline]
pub fn bias_at(f: &LightFrame, bias_texels: f32, z_r: f32) -> f32 {
    bias_texels * f.texel_tan().x * z_r
}

impl Precision {
    /// The blend that accumulates the SSM at this precision: fp16 rounds each sum to half as
    /// `rounding` says, as blending into an R16Float target does (Appendix A: `X + ε = X` when
    /// `ε < 2⁻¹⁰·X`, toward zero; `ε < 2⁻¹¹·X` to nearest).
    pub fn blend(self, rounding: HalfRounding) -> Blend {
        match self {
            Precision::Fp32 => Blend::Add,
            Precision::Fp16 => Blend::AddHalf(rounding),
        }
    }
}

/// How the scene's triangles split into occluders and receivers (module docs).
pub struct Split {
    pub occluders: Vec<[u32; 3]>,
    pub receivers: Vec<[u32; 3]>,
    /// Per object: whether it receives the soft shadow.
    pub receives: Vec<bool>,
    /// Whether the receivers are the receiver-only objects (else every receiver-tagged object,
    /// occluders included).
    pub pure: bool,
    /// Bounds of the occluders' vertices (`None` without occluders).
    pub occluder_bounds: Option<Bounds>,
}

impl Split {
    pub fn of(flat: &FlatMesh) -> Split {
        let pure = flat.roles.iter().any(|r| r.receiver && !r.occluder);
        let receives: Vec<bool> = flat
            .roles
            .iter()
            .map(|r| r.receiver && (!pure || !r.occluder))
            .collect();
        let (mut occluders, mut receivers) = (Vec::new(), Vec::new());
        for (t, tri) in flat.mesh.triangles.iter().enumerate() {
            let o = flat.object_of_triangle[t] as usize;
            if flat.roles[o].occluder {
                occluders.push(*tri);
            }
            if receives[o] {
                receivers.push(*tri);
            }
        }
        let p = &flat.mesh.positions;
        let occluder_bounds = (!occluders.is_empty())
            .then(|| Bounds::of_points(occluders.iter().flatten().map(|&v| p[v as usize])));
        Split {
            occluders,
            receivers,
            receives,
            pure,
            occluder_bounds,
        }
    }

    /// The warning of a scene without receiver-only objects.
    pub fn warning(&self) -> Option<String> {
        (!self.pure).then(|| {
            "no receiver-only object in the scene: every receiver-tagged object is a receiver, \
             occluders included (self-shadowing only beyond the bias)"
                .to_string()
        })
    }
}

/// Visibility from an SSM occlusion value.
pub fn visibility(occluded: f32) -> f32 {
    1.0 - occluded.clamp(0.0, 1.0)
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct SoftShadowMap;

/// Penumbra-extent rectangles of every micro-patch (002 §3.3): up to one micro-patch per
/// occluder-map texel, about a quarter of the map covered by occluders, each extent the patch
/// plus the penumbra wide; the second pass of two-pass maps doubles it.
pub fn work_estimate(
    scene: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    o: &SoftShadowMapOptions,
) -> f64 {
    let passes = o.passes;
    let extent = 1.0 + work::penumbra_texels(scene, p.map_resolution);
    f64::from(passes) * work::texels(p) * (2.0 + 0.25 * extent * extent)
}

impl Algorithm for SoftShadowMap {
    const ID: &'static str = ID;
    const SOURCE: &'static str = "002 §3-§4 (Atty et al. 2006)";
    const SUMMARY: &'static str =
        "occluder map as micro-patches; penumbra-extent quads add each patch's hidden \
              fraction of the light (interval product) into a soft shadow map; one or two \
              passes, FP32 or FP16 accumulation";
    const LIGHTS: &'static [LightKind] = &[LightKind::Rect];
    const LIMITS: &'static [MethodLimit] = &[MethodLimit::NoOccluderShadowing, MethodLimit::OneMap];
    type Options = SoftShadowMapOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] = &[
        r#"{"passes": 2, "occluder_map_transfer": false}"#,
        r#"{"precision": "fp16"}"#,
    ];
    /// Fragment counts differ where the occluder map and the penumbra-extent quads through two rasterizers (measured: fill 2.6% apart on torus-on-plane, map 128²).
    const WGPU_PARITY: WgpuParity = WgpuParity {
        differ: &[("fill", Some(0.03)), ("overdraw", Some(0.03))],
        ..WgpuParity::SAME_FORMULAS
    };
    const CPU: CpuEntry<SoftShadowMapOptions> = cpu::render;
    const WGPU: Option<WgpuEntry<SoftShadowMapOptions>> = Some(wgpu::render);
}

/// The quad of a micro-patch's penumbra extent (§3.3) in the NDC of the SSM's frame `lf`, at the
/// far plane.
pub fn extent_quad(lf: &LightFrame, p: &MicroPatch) -> [Vec3; 4] {
    let (lo, hi) = penumbra_extent(lf, p, lf.far);
    let (a, b) = (lf.tan_to_ndc(lo), lf.tan_to_ndc(hi));
    [
        Vec3::new(a.x, a.y, 0.0),
        Vec3::new(b.x, a.y, 0.0),
        Vec3::new(b.x, b.y, 0.0),
        Vec3::new(a.x, b.y, 0.0),
    ]
}

/// The micro-patch of occluder texel (i, j) with NDC depth `d`, or `None` where the map is empty.
pub fn micro_patch(lf: &LightFrame, i: u32, j: u32, d: f32) -> Option<MicroPatch> {
    (d < 1.0).then(|| MicroPatch::of_texel(lf, i, j, lf.linear_depth(d)))
}

/// Where an eye sample stands with respect to the SSM.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sample {
    /// Background, an occluder-only surface facing the light, or outside the maps: lit.
    Lit,
    /// A surface facing away from the light centre: in shadow (the family's convention).
    Averted,
    /// A receiver inside the maps, at these continuous SSM texel coordinates.
    Receiver(Vec2),
}

/// Classifies an eye sample at `pos` with normal `n` on an object that does (`receives`) or
/// does not receive the soft shadow.
pub fn classify(lf: &LightFrame, pos: Vec3, n: Vec3, receives: bool) -> Sample {
    if n.dot((lf.center - pos).normalize_or_zero()) <= 0.0 {
        return Sample::Averted;
    }
    if !receives {
        return Sample::Lit;
    }
    let l = lf.to_light(pos);
    if l.z <= lf.near * 0.5 {
        return Sample::Lit;
    }
    let s = lf.tan_to_texel(Vec2::new(l.x, l.y) / l.z);
    let n = lf.resolution as f32;
    if s.x < 0.0 || s.y < 0.0 || s.x >= n || s.y >= n {
        return Sample::Lit;
    }
    Sample::Receiver(s)
}

/// Receivers the eye sees that no map of the method can hold: behind the light's plane or
/// beyond the scene's window ([`LightFrame::new`], clamped at [`MAX_HALF_ANGLE_DEG`]); the
/// method takes them as lit. (Receivers outside the SSM focused on the occluders but inside the
/// scene's window lie beyond every penumbra extent and are lit rightly.) Recorded as
/// `light_view.receivers_outside`, with a warning when there are any.
pub fn record_receivers_outside(frame: &Frame, split: &Split, out: &mut FrameOutput) {
    let lf = LightFrame::new(
        &frame.scene.light,
        frame.scene.bounds(),
        frame.params.map_resolution,
    );
    let g = &frame.gbuffer;
    let outside = (0..g.len())
        .filter(|&i| g.is_hit(i))
        .filter(|&i| split.receives[frame.flat.object_of_triangle[g.triangle[i] as usize] as usize])
        .filter(|&i| classify(&lf, g.position[i], g.normal[i], true) == Sample::Lit)
        .count();
    out.counters
        .set(names::LIGHT_VIEW_RECEIVERS_OUTSIDE, outside as f64);
    if outside > 0 {
        out.warnings.push(format!(
            "{outside} visible receiver pixels lie outside the soft shadow map's reach (behind \
             the light's plane or beyond {MAX_HALF_ANGLE_DEG}° from its normal) and are taken \
             as lit"
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> LightFrame {
        let light = Light::Rect {
            center: Vec3::new(0.0, 6.0, 0.0),
            half_u: Vec3::new(0.5, 0.0, 0.0),
            half_v: Vec3::new(0.0, 0.0, 0.5),
        };
        let b = Bounds {
            min: Vec3::new(-5.0, 0.0, -5.0),
            max: Vec3::new(5.0, 2.0, 5.0),
        };
        LightFrame::new(&light, b, 128)
    }

    #[test]
    fn the_frame_looks_along_the_light_normal_and_rasterizer_ndc_matches_texels() {
        let f = frame();
        assert!((f.normal - Vec3::NEG_Y).length() < 1e-6);
        let p = Vec3::new(1.3, 0.7, -2.1);
        let l = f.to_light(p);
        assert!((l.z - 5.3).abs() < 1e-5);
        let clip = f.view_proj * p.extend(1.0);
        let ndc = clip.truncate() / clip.w;
        let t = Vec2::new(l.x, l.y) / l.z;
        assert!((ndc.truncate() - f.tan_to_ndc(t)).length() < 1e-5);
        assert!((f.linear_depth(ndc.z) - l.z).abs() < 1e-4);
        // Texel centres round-trip.
        let c = f.texel_center(17, 90);
        assert!((f.tan_to_texel(c) - Vec2::new(17.5, 90.5)).length() < 1e-3);
        // Same aspect ratio as the (square) light.
        assert!(((f.x1 - f.x0) - (f.y1 - f.y0)).abs() < 1e-6);
    }

    #[test]
    fn the_apex_extent_equals_the_extent_of_all_light_to_patch_lines() {
        // Per axis, the receivers at depth z_r a light point l ∈ [−L, L] sees through a patch
        // point p ∈ [p0, p1] at depth z_o lie at l + (p − l)·z_r/z_o; their range is the extent.
        let f = frame();
        let p = MicroPatch::of_texel(&f, 40, 70, 3.0);
        let z_r = 6.0;
        let (lo, hi) = penumbra_extent(&f, &p, z_r);
        for axis in 0..2 {
            let (l, p0, p1) = (f.half[axis], p.lo[axis], p.hi[axis]);
            let s = z_r / p.z_o;
            let (a, b) = ((l + (p0 - l) * s) / z_r, (-l + (p1 + l) * s) / z_r);
            assert!((lo[axis] - a).abs() < 1e-5 && (hi[axis] - b).abs() < 1e-5);
        }
        // Outside the extent nothing is hidden; at its centre the whole patch hides light.
        let bias = 0.0;
        let outside = Vec2::new(hi.x + 1e-3, (lo.y + hi.y) * 0.5);
        assert_eq!(occlusion(&f, &p, outside, z_r, bias), 0.0);
        let inside = (lo + hi) * 0.5;
        assert!(occlusion(&f, &p, inside, z_r, bias) > 0.0);
    }

    #[test]
    fn a_patch_that_covers_the_light_hides_all_of_it() {
        // Receiver right below a patch wider than the light's cone: fraction 1; a patch half as
        // wide as the light's projection hides a quarter of it.
        let f = frame();
        let p = MicroPatch {
            lo: Vec2::splat(-1.0),
            hi: Vec2::splat(1.0),
            z_o: 3.0,
        };
        assert_eq!(occlusion(&f, &p, Vec2::ZERO, 6.0, 0.0), 1.0);
        // From z_r = 6 through z_o = 3 the light [−0.5, 0.5] maps to [−0.25, 0.25] at the patch.
        let q = MicroPatch {
            lo: Vec2::splat(0.0),
            hi: Vec2::splat(0.25),
            z_o: 3.0,
        };
        assert!((occlusion(&f, &q, Vec2::ZERO, 6.0, 0.0) - 0.25).abs() < 1e-6);
        // Behind the receiver: nothing.
        assert_eq!(occlusion(&f, &p, Vec2::ZERO, 2.0, 0.0), 0.0);
    }

    #[test]
    fn half_precision_loses_small_adds_on_large_sums() {
        // Appendix A: 2048 + 1 = 2048 in FP16, however the sum rounds (a tie goes to even).
        for r in [HalfRounding::TowardZero, HalfRounding::NearestEven] {
            let add = |p: Precision, a, b| p.blend(r).apply(a, b);
            assert_eq!(add(Precision::Fp16, 2048.0, 1.0), 2048.0);
            assert_eq!(add(Precision::Fp32, 2048.0, 1.0), 2049.0);
            let small = 0.5 / 2049.0;
            assert_eq!(add(Precision::Fp16, 0.5, small), 0.5);
            assert!(add(Precision::Fp32, 0.5, small) > 0.5);
        }
    }
}
