//! Ray-traced soft shadows with a penumbra-guided denoiser: the baseline that current engines
//! ship (NVIDIA's NRD SIGMA shadow denoiser; AMD FidelityFX's shadow denoiser, one ray a pixel).
//!
//! 1. **`trace`**: per eye pixel `spp` shadow rays from its shading point to points of the light.
//!    The points come from the two-dimensional Sobol' sequence (van der Corput in x, Sobol's
//!    second dimension in y: every aligned block of 2^m consecutive points is a (0, m, 2) net,
//!    one point in each elementary interval of area 2^-m): each pixel takes a block of `spp`
//!    consecutive points, so its rays are stratified, and the pixels of a 4×4 tile take
//!    consecutive blocks in Morton order under one hashed toroidal shift (Cranley–Patterson
//!    rotation, [`square_sample`]), so neighbours sample different strata of the light and a
//!    spatial filter averages a stratified set (interleaved sampling, Keller and Heidrich
//!    2001): stratified within a pixel, decorrelated between tiles (white noise across tiles,
//!    not a blue-noise mask). The unit square is mapped to the emitter as the
//!    reference maps it (`Light::emitter_frame`, Shirley–Chiu's concentric map for discs and
//!    spheres), all in integer and IEEE arithmetic so both executions draw the same points. Each
//!    ray is an any-hit traversal of a BVH of the casters ([`bvh::CasterBvh`]: a binary BVH built
//!    by PLOC (obvhs) over the occluders' triangles only, each node holding both children's boxes
//!    in one 64-byte record); the triangle test is the project's coverage rule, as the
//!    reference's. A pixel records its visible fraction and the mean distance to the blockers its
//!    rays found.
//! 2. **`denoise`** (with `denoise: true`), after SIGMA (NVIDIA, "NRD: SIGMA shadow denoiser",
//!    NRD documentation, 2021–2024) and the FidelityFX shadow denoiser (AMD, "FidelityFX Denoiser:
//!    shadows", GPUOpen documentation, 2020): the penumbra's screen-space radius is estimated from
//!    the hit distances by similar triangles ([`penumbra_radius_px`]: light radius × blocker
//!    distance / (light distance − blocker distance), over the pixel's footprint; the filter
//!    reaches half of that half-width, [`PENUMBRA_REACH`], and at least a pixel), gathered from
//!    the pixel's neighbourhood ([`SEARCH_NEAR`], [`search_far`]) since at one ray a pixel the lit
//!    side of a penumbra has no hits of its own; a pixel whose neighbourhood is all lit or all
//!    shadowed, or that has no blocker near it, is not filtered at all (SIGMA's tile
//!    classification at pixel granularity: no blur in full light or umbra). The others get
//!    `passes` rounds of the edge-avoiding à-trous wavelet filter of SVGF (Schied et al.,
//!    "Spatiotemporal Variance-Guided Filtering", HPG 2017, §4.3, after Dammertz et al. 2010):
//!    a 5×5 B3-spline kernel with holes (step 1, 2, 4, ...), weighted by the G-buffer (normals
//!    and distance to the pixel's tangent plane, [`geometric_weight`]) and restricted to taps
//!    within the pixel's penumbra radius, so the blur is wide where the penumbra is wide. No
//!    luminance edge-stopping: the visibility edges inside a penumbra are the noise.
//!
//! Not built: temporal accumulation (reprojection and history clamping, the issue's option for
//! animated sweeps: every frame of an animated sweep is a fresh run here, with no history to
//! reproject), and hardware ray queries on wgpu (lavapipe offers none; the BVH is traversed in
//! WGSL on every adapter).
//!
//! The unit of work is a ray: `fill` counts the shadow rays cast, `overdraw` the rays of pixels
//! whose rays all gave the same answer beyond the first one each (they changed nothing one ray
//! would not have given).

pub mod bvh;
pub mod cpu;
pub mod wgpu;

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::algorithms::algorithm::{
    Algorithm, AlgorithmOptions, CpuEntry, ExecContext, WgpuEntry, WgpuParity, WorkEstimate,
};
use crate::algorithms::work;
use crate::error::InputError;
use crate::frame::{Frame, RunParams};
use crate::record::phases;
use crate::scene::light::concentric_disc;
use crate::scene::Light;

phases! {
    /// The phases of an `rt_denoised` run: the traced shadow rays, and the denoiser over their
    /// visibility (absent from a raw run).
    pub enum Phase {
        Trace => "trace",
        Denoise => "denoise",
    }
}

pub const ID: &str = "rt_denoised";

/// Options of `rt_denoised` (scenario `options.rt_denoised`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RtDenoisedOptions {
    /// Shadow rays per eye pixel.
    pub spp: u32,
    /// Whether the denoiser runs; `false` reports the raw ray-traced estimate.
    pub denoise: bool,
    /// À-trous passes of the denoiser (tap spacing 1, 2, 4, ... pixels).
    pub passes: u32,
    /// Largest filter radius in pixels, and the radius of the penumbra search.
    pub radius: u32,
}

impl Default for RtDenoisedOptions {
    fn default() -> Self {
        RtDenoisedOptions {
            spp: 1,
            denoise: true,
            passes: 3,
            radius: 16,
        }
    }
}

impl AlgorithmOptions for RtDenoisedOptions {
    fn validate(&self) -> Result<(), InputError> {
        let field = |name: &str| format!("$.options.{ID}.{name}");
        InputError::check_range(field("spp"), self.spp, 1..=4096)?;
        InputError::check_range(field("passes"), self.passes, 1..=MAX_PASSES)?;
        InputError::check_range(field("radius"), self.radius, 1..=MAX_RADIUS)
    }
}

/// Most à-trous passes (tap spacing up to 2^5 = 32 pixels).
pub const MAX_PASSES: u32 = 6;
/// Largest filter radius, pixels.
pub const MAX_RADIUS: u32 = 128;

/// The lowbias32 integer hash (Wellons, "Hash function prospector", 2018): a bijection of u32
/// with good avalanche, the same in Rust and WGSL.
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// The toroidal shift of tile `tile`'s points (Cranley–Patterson rotation), in 0.32 fixed
/// point per dimension, from the run's `seed`.
pub fn pixel_rotation(seed: u32, tile: u32) -> [u32; 2] {
    let a = hash32(tile ^ hash32(seed));
    [a, hash32(a ^ 0x9e37_79b9)]
}

/// Point `s` of the two-dimensional Sobol' sequence in 0.32 fixed point: the van der Corput
/// radical inverse in base 2, and Sobol's second dimension (direction numbers `v_k = v_{k−1} ^
/// (v_{k−1} >> 1)`, the Pascal matrix mod 2).
pub fn sobol_2d(s: u32) -> [u32; 2] {
    let (mut i, mut v, mut y) = (s, 1u32 << 31, 0u32);
    while i != 0 {
        if i & 1 != 0 {
            y ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    [s.reverse_bits(), y]
}

/// A 0.32 fixed-point coordinate as an `f32` in [0, 1): its top 24 bits, exactly.
pub fn unit_of(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Side of the pixel tiles that share one rotation of the sequence ([`square_sample`]).
pub const INTERLEAVE: u32 = 4;

/// The rank of pixel (x, y) in its [`INTERLEAVE`]² tile, in Morton order: each aligned 2×2
/// block holds four consecutive ranks.
pub fn tile_rank(x: u32, y: u32) -> u32 {
    (x & 1) | (y & 1) << 1 | (x & 2) << 1 | (y & 2) << 2
}

/// Sample `s` of the `spp` of pixel (x, y) of an image `width` wide, on the unit square:
/// point `s + spp · rank` of [`sobol_2d`] ([`tile_rank`]), shifted by the rotation of the
/// pixel's [`INTERLEAVE`]² tile ([`pixel_rotation`] of the tile's index). A pixel's points
/// are a block of consecutive Sobol' points (an aligned block of 2^m is a (0, m, 2) net: the
/// pixel's rays are stratified), and the pixels of an aligned 2×2 block or of the tile share
/// one net between them (interleaved sampling, Keller and Heidrich 2001: neighbours sample
/// different strata of the light, so a spatial filter averages a stratified set); tiles are
/// decorrelated by their rotations.
pub fn square_sample(seed: u32, (x, y, width): (u32, u32, u32), spp: u32, s: u32) -> Vec2 {
    let tiles_x = width.div_ceil(INTERLEAVE);
    let tile = (y / INTERLEAVE) * tiles_x + x / INTERLEAVE;
    let [px, py] = sobol_2d(s.wrapping_add(spp.wrapping_mul(tile_rank(x, y))));
    let [rx, ry] = pixel_rotation(seed, tile);
    Vec2::new(unit_of(px.wrapping_add(rx)), unit_of(py.wrapping_add(ry)))
}

/// The point of `light` at unit-square coordinates `sq` as seen from `p`: the emitter's frame
/// (`Light::emitter_frame`) and its parameterisation (`Light::stratified_coords`: `[−1, 1]²`
/// for a rectangle, the concentric map onto the unit disc otherwise).
pub fn light_point(light: &Light, (c, u, v): (Vec3, Vec3, Vec3), sq: Vec2) -> Vec3 {
    let d = match light {
        Light::Rect { .. } => sq * 2.0 - Vec2::ONE,
        _ => concentric_disc(sq),
    };
    c + u * d.x + v * d.y
}

/// The radius of `light` as the denoiser's similar triangles take it: a disc's or sphere's
/// radius, the radius of the disc of a rectangle's area.
pub fn light_radius(light: &Light) -> f32 {
    match light {
        Light::Rect { .. } => (light.area() / std::f32::consts::PI).sqrt(),
        _ => light.size(),
    }
}

/// The filter's reach as a share of the penumbra's half-width: a wider blur averages more rays
/// but bends the penumbra's profile (measured on the analytic half-plane of the tests at one
/// ray a pixel: `mae_shadow` 0.0136 at 0.5, 0.0376 at 0.7 and 0.0373 at 1, where the step-2
/// pass starts to reach 4 pixels across the penumbra).
pub const PENUMBRA_REACH: f32 = 0.5;

/// The least reach of a filtered pixel, pixels: its 3×3 neighbourhood, however narrow the
/// penumbra (at one ray a pixel the noise outweighs a pixel's blur).
pub const MIN_REACH: f32 = 1.0;

/// The filter's reach in pixels for a receiver at distance `light_distance` from the light's
/// centre and a blocker at distance `blocker` from it: [`PENUMBRA_REACH`] times the half-width
/// of the penumbra by similar triangles (the PCSS estimate that SIGMA takes from hit
/// distances), `radius · blocker / (light_distance − blocker)` in world units, over the
/// receiver pixel's `footprint` (world units per pixel); at most `max`.
pub fn penumbra_radius_px(
    radius: f32,
    light_distance: f32,
    blocker: f32,
    footprint: f32,
    max: f32,
) -> f32 {
    let gap = light_distance - blocker;
    if gap <= 0.0 || footprint <= 0.0 {
        return max;
    }
    (PENUMBRA_REACH * radius * blocker / gap / footprint).min(max)
}

/// The B3-spline taps of the à-trous kernel (SVGF §4.3): `h = (1, 4, 6, 4, 1) / 16`.
pub const B3: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// The near ring of the penumbra search: the 3×3 neighbourhood, pixels.
pub const SEARCH_NEAR: i32 = 1;
/// Taps per side of the far grid of the penumbra search (5×5, centre shared with the near ring).
pub const SEARCH_FAR_SIDE: i32 = 5;

/// Spacing of the far grid of the penumbra search, pixels: the 5×5 grid spans ± `radius`.
pub fn search_far(radius: u32) -> i32 {
    radius.div_ceil(2).max(1) as i32
}

/// The offsets of the penumbra search, centre first: the 3×3 ring at spacing 1, then the 5×5
/// grid at spacing [`search_far`] without its centre (33 taps).
pub fn search_offsets(radius: u32) -> Vec<(i32, i32)> {
    let far = search_far(radius);
    let mut taps = vec![(0, 0)];
    for dy in -SEARCH_NEAR..=SEARCH_NEAR {
        for dx in -SEARCH_NEAR..=SEARCH_NEAR {
            if (dx, dy) != (0, 0) {
                taps.push((dx, dy));
            }
        }
    }
    let h = SEARCH_FAR_SIDE / 2;
    for dy in -h..=h {
        for dx in -h..=h {
            if (dx, dy) != (0, 0) {
                taps.push((dx * far, dy * far));
            }
        }
    }
    taps
}

/// Cosine power of the normal weight: `max(0, n_p · n_q)^32`, by five squarings.
pub const NORMAL_POWER_SQUARINGS: u32 = 5;

/// How far a tap's point may lie off the pixel's tangent plane, in pixel footprints per pixel
/// of offset, before its weight reaches 0.
pub const PLANE_TOLERANCE: f32 = 2.0;

/// The G-buffer weight of tap `q` for pixel `p` (SVGF §4.3's normal and depth edge-stopping,
/// depth as distance to `p`'s tangent plane): `max(0, n_p·n_q)^32 · max(0, 1 − |n_p·(x_q −
/// x_p)| / (PLANE_TOLERANCE · footprint_p · |offset|))`, `offset` the tap's offset in pixels
/// (> 0). In [0, 1].
pub fn geometric_weight(
    (xp, np, footprint): (Vec3, Vec3, f32),
    (xq, nq): (Vec3, Vec3),
    offset: f32,
) -> f32 {
    let mut wn = np.dot(nq).max(0.0);
    for _ in 0..NORMAL_POWER_SQUARINGS {
        wn *= wn;
    }
    let plane = np.dot(xq - xp).abs();
    let wz = (1.0 - plane / (PLANE_TOLERANCE * footprint * offset)).max(0.0);
    wn * wz
}

/// World size of one pixel at distance `distance` from the eye: the image plane's height at
/// unit distance (`2·tan(fov_y / 2)`) over the image height, times the distance.
pub fn footprint(distance: f32, fov_y_deg: f32, height: u32) -> f32 {
    distance * 2.0 * (fov_y_deg.to_radians() * 0.5).tan() / height as f32
}

/// Bytes of the per-pixel buffers of a run: inputs (shading point and normal, 32 bytes), the
/// trace's output (visibility, blocker distance), the penumbra radius and the two à-trous
/// buffers (4 bytes each).
pub fn buffer_bytes(p: &RunParams) -> u64 {
    u64::from(p.image[0]) * u64::from(p.image[1]) * (32 + 4 * 5)
}

/// Bytes of a run's own buffers: the per-pixel buffers and the BVH (two node records of 64
/// bytes and a 48-byte triangle per caster triangle, an upper bound).
pub fn memory_estimate(p: &RunParams) -> u64 {
    buffer_bytes(p) + u64::from(p.triangles) * (2 * 64 + 48)
}

/// Estimated fill: one ray per eye pixel and sample.
pub fn work_estimate(
    _: &work::SceneExtent,
    p: &RunParams,
    _: &ExecContext,
    o: &RtDenoisedOptions,
) -> f64 {
    f64::from(p.image[0]) * f64::from(p.image[1]) * f64::from(o.spp)
}

/// The per-pixel inputs every execution reads, made once on the host from the frame's G-buffer
/// (SIGMA reads view depth and normals from the G-buffer likewise): the shading point with the
/// pixel's footprint in `w` (0 for background), and the normal with 1 in `w` where the surface
/// is receiver-only (its plane hides the light behind it: the reference's horizon test).
pub struct PixelInputs {
    pub points: Vec<[f32; 4]>,
    pub normals: Vec<[f32; 4]>,
}

impl PixelInputs {
    pub fn of(frame: &Frame) -> PixelInputs {
        let g = &frame.gbuffer;
        let cam = &frame.scene.camera;
        let (points, normals) = (0..g.len())
            .map(|i| {
                if !g.is_hit(i) {
                    return ([0.0; 4], [0.0; 4]);
                }
                let p = g.shading_point(i);
                let f = footprint(g.position[i].distance(cam.eye), cam.fov_y_deg, g.height);
                let receiver_only = !frame.flat.role_of(g.triangle[i] as usize).occluder;
                (
                    p.extend(f).to_array(),
                    g.normal[i]
                        .extend(f32::from(u8::from(receiver_only)))
                        .to_array(),
                )
            })
            .unzip();
        PixelInputs { points, normals }
    }
}

/// The registry's entry points ([`crate::algorithms::Algorithm`]).
pub struct RtDenoised;

impl Algorithm for RtDenoised {
    const ID: &'static str = ID;
    const SOURCE: &'static str =
        "engine baseline: SIGMA / FidelityFX shadow denoisers, SVGF à-trous (Schied et al. 2017)";
    const SUMMARY: &'static str =
        "spp shadow rays a pixel through a BVH of the casters, then a penumbra-guided à-trous denoiser";
    type Options = RtDenoisedOptions;
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64 = memory_estimate;
    const WORK_ESTIMATE: WorkEstimate<Self::Options> = work_estimate;
    const OPTION_SETS: &'static [&'static str] = &[
        r#"{"spp": 4, "denoise": false}"#,
        r#"{"spp": 2, "passes": 2, "radius": 8}"#,
    ];
    const WGPU_PARITY: WgpuParity = WGPU_PARITY;
    const CPU: CpuEntry<RtDenoisedOptions> = cpu::render;
    /// Rays a pixel and whether it is denoised (`1 spp`, `4 spp raw`), with the filter's
    /// passes and radius where they are not the defaults: runs of different ones are different
    /// points of the quality-against-cost front.
    fn variant(o: &RtDenoisedOptions) -> Option<String> {
        let d = RtDenoisedOptions::default();
        let mut v = format!("{} spp", o.spp);
        if !o.denoise {
            v.push_str(" raw");
        } else if (o.passes, o.radius) != (d.passes, d.radius) {
            v.push_str(&format!(" p{} r{}", o.passes, o.radius));
        }
        Some(v)
    }
    const WGPU: Option<WgpuEntry<RtDenoisedOptions>> = Some(wgpu::render);
}

/// How close the wgpu execution is to the cpu-model: the same formulas in the same order, the
/// light points from the same integer sequence, so [`WgpuParity::SAME_FORMULAS`] (MAE 1e-3,
/// every counter equal). Measured on lavapipe over the registry's frames and option sets
/// (48×36, sphere-on-plane and torus-on-plane): images identical (largest difference 0) and
/// every counter equal. A GPU that rounds a division, square root or sine differently, or
/// fuses a multiply-add, may turn a ray that grazes an edge; a turned ray moves a 1-spp pixel
/// by 1 before the filter.
pub const WGPU_PARITY: WgpuParity = WgpuParity::SAME_FORMULAS;

/// The run's seed as the 32-bit seed of the light points.
pub fn seed32(seed: u64) -> u32 {
    (seed ^ (seed >> 32)) as u32
}
