//! One frame's input, shared by every algorithm and backend: the scene with the light in force,
//! the run parameters, and the eye pass.
//!
//! The eye pass (which surface each pixel sees) is computed once per frame by ray casting and
//! handed to every algorithm and backend alike. Every shadow algorithm needs it, none of the
//! papers counts it in its shadow cost, and sharing it keeps the comparison between algorithms
//! and between executions about the shadows alone.

use std::collections::BTreeMap;

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::record::{Counters, Phase};
use crate::scene::adjacency::{EdgeAdjacency, EdgeKind};
use crate::scene::bvh::SceneBvh;
use crate::scene::{FlatMesh, Scene};
use crate::util::deadline::Deadline;
use crate::visibility::{RgbBuffer, VisibilityBuffer};

/// Parameters of one run (one point of a sweep).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunParams {
    /// Actual triangle count of the scene.
    pub triangles: u32,
    /// Radius, or half-width of a rectangular light.
    pub light_size: f32,
    pub map_resolution: u32,
    pub tile_size: u32,
    /// [width, height] of the eye image.
    pub image: [u32; 2],
    /// Height of the main occluder above the receiver, where the scene has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub occluder_height: Option<f32>,
    /// Lateral offset of the moving occluder along x, where the scene has one (paper 002 §5.2.5).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub occluder_offset: Option<f32>,
    /// Core count of the modelled machine (cpu-model runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cores: Option<u32>,
}

impl RunParams {
    /// Parameters of a run in `scene`: its triangle count and light size, the given image and
    /// map resolution and tile size, no occluder height, occluder offset or core count.
    pub fn of_scene(
        scene: &Scene,
        image: [u32; 2],
        map_resolution: u32,
        tile_size: u32,
    ) -> RunParams {
        RunParams {
            triangles: scene.triangle_count() as u32,
            light_size: scene.light.size(),
            map_resolution,
            tile_size,
            image,
            occluder_height: None,
            occluder_offset: None,
            cores: None,
        }
    }
}

/// What the eye sees at each pixel.
#[derive(Clone, Debug)]
pub struct GBuffer {
    pub width: u32,
    pub height: u32,
    /// World position of the visible surface (meaningless where `hit` is false).
    pub position: Vec<Vec3>,
    /// Unit geometric normal, turned to face the eye.
    pub normal: Vec<Vec3>,
    /// Triangle index into the frame's flat mesh, or `u32::MAX` for background.
    pub triangle: Vec<u32>,
    /// Per pixel, the vector from `position` to the point shadows are computed at: the surface
    /// point moved off its surface robustly ([`offset_point`]); zero for background.
    pub offset: Vec<Vec3>,
}

impl GBuffer {
    pub fn is_hit(&self, i: usize) -> bool {
        self.triangle[i] != u32::MAX
    }

    /// The point of pixel `i`'s surface that shadows are computed at: `position + offset`, the
    /// visible point moved off its surface robustly ([`offset_point`]). Every algorithm, the
    /// reference and the WGSL (which adds the same two vectors) shade this point.
    pub fn shading_point(&self, i: usize) -> Vec3 {
        self.position[i] + self.offset[i]
    }

    /// Mask of pixels that see a surface.
    pub fn mask(&self) -> Vec<bool> {
        self.triangle.iter().map(|&t| t != u32::MAX).collect()
    }

    pub fn len(&self) -> usize {
        self.triangle.len()
    }

    pub fn is_empty(&self) -> bool {
        self.triangle.is_empty()
    }
}

/// Everything an algorithm needs to render one frame.
pub struct Frame {
    pub scene: Scene,
    pub flat: FlatMesh,
    pub bvh: SceneBvh,
    pub gbuffer: GBuffer,
    pub params: RunParams,
    /// The scene-relative offset that leaves a surface without hitting it again (1e-4 of the
    /// scene's diagonal; [`offset_point`] makes it at least a few units in the last place of
    /// each coordinate).
    pub epsilon: f32,
    /// Edges of the occluders' welded mesh that are not shared by exactly two faces.
    pub occluder_edges: OccluderEdges,
    /// Every run's warning when f32 cannot hold the scene ([`precision_warning`]).
    pub precision_warning: Option<String>,
}

/// The adjacency problems of a frame's occluders (their union, welded as the shadow-volume
/// family welds it, [`EdgeAdjacency::build`]): edges with one face (the mesh is open) and edges
/// with three or more (non-manifold). Every record carries them as the counters
/// `occluders.boundary_edges` and `occluders.non_manifold_edges`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OccluderEdges {
    pub boundary: usize,
    pub non_manifold: usize,
}

impl OccluderEdges {
    pub fn of(scene: &Scene) -> OccluderEdges {
        let adj = EdgeAdjacency::build(&scene.occluders());
        OccluderEdges {
            boundary: adj.count(EdgeKind::Boundary),
            non_manifold: adj.count(EdgeKind::NonManifold),
        }
    }

    /// Edges not shared by exactly two faces.
    pub fn open(&self) -> usize {
        self.boundary + self.non_manifold
    }

    /// The per-run warning for an occluder mesh that is not a closed 2-manifold, if it is not.
    pub fn warning(&self) -> Option<String> {
        (self.open() > 0).then(|| {
            format!(
                "occluders are not a closed 2-manifold: {} boundary and {} non-manifold edges \
                 (shadow volumes of open surfaces, silhouettes and self-shadowing may be wrong)",
                self.boundary, self.non_manifold
            )
        })
    }
}

impl Frame {
    pub fn new(scene: Scene, params: RunParams) -> Frame {
        Frame::new_until(scene, params, Deadline::default())
    }

    /// [`Frame::new`] within a run's budget: `deadline` is checked between the phases (the
    /// flattened mesh, the BVH build, the eye pass, the occluders' edges) and before each pixel of the eye pass; past
    /// it the build unwinds with [`crate::util::deadline::Cancelled`].
    pub fn new_until(scene: Scene, params: RunParams, deadline: Deadline) -> Frame {
        deadline.check();
        let flat = scene.flatten();
        deadline.check();
        let bvh = SceneBvh::build(&flat);
        deadline.check();
        let epsilon = scene.bounds().diagonal() * 1e-4;
        let gbuffer = eye_pass(&scene, &flat, &bvh, params.image, epsilon, deadline);
        deadline.check();
        let occluder_edges = OccluderEdges::of(&scene);
        let precision_warning = precision_warning(&scene);
        Frame {
            scene,
            flat,
            bvh,
            gbuffer,
            params,
            epsilon,
            occluder_edges,
            precision_warning,
        }
    }

    /// Pixels whose surface belongs to a receiver-only object (receives, does not occlude).
    /// Pixels that see a surface whose tangent plane cuts the light ([`Light::straddles`]):
    /// `width × height` flags, row-major.
    ///
    /// [`Light::straddles`]: crate::scene::Light::straddles
    pub fn grazing_mask(&self) -> Vec<bool> {
        let g = &self.gbuffer;
        let light = &self.scene.light;
        (0..g.len())
            .map(|i| g.is_hit(i) && light.straddles(g.position[i], g.normal[i]))
            .collect()
    }

    pub fn receiver_only_mask(&self) -> Vec<bool> {
        let g = &self.gbuffer;
        (0..g.len())
            .map(|i| {
                g.is_hit(i) && {
                    let r = self.flat.role_of(g.triangle[i] as usize);
                    r.receiver && !r.occluder
                }
            })
            .collect()
    }

    pub fn width(&self) -> u32 {
        self.params.image[0]
    }

    pub fn height(&self) -> u32 {
        self.params.image[1]
    }
}

/// Units in the last place, per unit of normal component, that [`offset_point`] moves a point
/// along each axis at least (Wächter and Binder use 256 with a hit point reconstructed from
/// barycentrics; ours is projected onto its triangle's plane, about an ulp off it, and a larger
/// offset moves the shadow terminator on curved surfaces).
pub const OFFSET_ULPS: f32 = 2.0;

/// Coordinates below this magnitude are moved by the scene-relative part alone (their ulp is
/// far below it, and stepping their bits could cross zero).
const OFFSET_ULP_FLOOR: f32 = 1e-30;

/// `p` (on a surface with unit geometric normal `n`, turned to the side being left) moved off
/// the surface so that rays from it do not hit that surface again, after Wächter and Binder, "A
/// Fast and Robust Method for Avoiding Self-Intersection" (Ray Tracing Gems, 2019, ch. 6): each
/// coordinate moves by `epsilon · n_k` (scene-relative: 1e-4 of the scene's diagonal, what
/// matters near the origin and at any scale) but at least `ceil(OFFSET_ULPS · |n_k|)` units in
/// its last place in the direction of `n_k`, an offset that grows with the magnitude of the
/// coordinates, where a fixed epsilon alone would round away (far from the origin).
pub fn offset_point(p: Vec3, n: Vec3, epsilon: f32) -> Vec3 {
    Vec3::from_array(std::array::from_fn(|k| {
        let (x, nk) = (p[k], n[k]);
        let relative = x + nk * epsilon;
        if nk == 0.0 || !x.is_finite() || x.abs() < OFFSET_ULP_FLOOR {
            return relative;
        }
        let steps = (OFFSET_ULPS * nk.abs()).ceil() as u32;
        // Away from zero when the step and the coordinate share a sign, towards it otherwise
        // (the floor keeps the bits from crossing zero).
        let bits = x.to_bits();
        let stepped = if (x > 0.0) == (nk > 0.0) {
            f32::from_bits(bits + steps)
        } else {
            f32::from_bits(bits - steps)
        };
        if (relative - x).abs() >= (stepped - x).abs() {
            relative
        } else {
            stepped
        }
    }))
}

/// The largest spacing of f32 values among the scene's coordinates (its bounds, the camera and
/// the light): the resolution every position of the frame is held at.
pub fn coordinate_spacing(scene: &Scene) -> f32 {
    let b = scene.bounds();
    let m = [
        b.min.abs().max_element(),
        b.max.abs().max_element(),
        scene.camera.eye.abs().max_element(),
        scene.light.center().abs().max_element(),
    ]
    .into_iter()
    .fold(0.0f32, f32::max);
    // The gap from m to the next f32 (m's unit in the last place).
    f32::from_bits(m.to_bits() + 1) - m
}

/// The per-run warning for a scene f32 cannot hold any more: where the offset that keeps rays
/// off their own surface ([`OFFSET_ULPS`] units in the last place of the largest coordinate)
/// exceeds [`PRECISION_LIMIT`] of the scene's diagonal (4 times the scene-relative offset), the
/// shadow terminator on curved surfaces, contact shadows and small features move by more than
/// the ground truth can vouch for (`tests/integration/precision.rs` measures it).
pub fn precision_warning(scene: &Scene) -> Option<String> {
    let spacing = coordinate_spacing(scene);
    let diagonal = scene.bounds().diagonal();
    let offset = OFFSET_ULPS * spacing;
    (offset > PRECISION_LIMIT * diagonal).then(|| {
        format!(
            "f32 cannot hold this scene: its coordinates are spaced {spacing:.3e} apart, so \
             surfaces are offset by up to {offset:.3e}, {:.2}% of the scene's diagonal \
             {diagonal:.3e} (over {}%); shadows and depth comparisons are unreliable (move \
             the scene nearer the origin)",
            100.0 * offset / diagonal,
            100.0 * PRECISION_LIMIT
        )
    })
}

/// The largest surface offset, as a fraction of the scene's diagonal, below which a frame is
/// trusted ([`precision_warning`]).
pub const PRECISION_LIMIT: f32 = 4e-4;

/// Primary rays through each pixel centre. The visible point is projected onto its triangle's
/// plane (so its error is that of the triangle's own coordinates, not of the ray's length) and
/// moved off the surface by [`offset_point`].
fn eye_pass(
    scene: &Scene,
    flat: &FlatMesh,
    bvh: &SceneBvh,
    [w, h]: [u32; 2],
    epsilon: f32,
    deadline: Deadline,
) -> GBuffer {
    let cam = scene.camera;
    let n = (w * h) as usize;
    let rows: Vec<(Vec3, Vec3, u32, Vec3)> = (0..n)
        .into_par_iter()
        .map(|i| {
            deadline.check();
            let (x, y) = (i as u32 % w, i as u32 / w);
            let d = cam.ray_direction(x, y, w, h);
            match bvh.closest(cam.eye, d) {
                Some(hit) => {
                    let [a, ..] = flat.mesh.triangle(hit.triangle as usize);
                    let n = flat
                        .mesh
                        .face_normal(hit.triangle as usize)
                        .normalize_or_zero();
                    let p = cam.eye + d * hit.t;
                    let p = p - n * n.dot(p - a);
                    let n = if n.dot(d) > 0.0 { -n } else { n };
                    (p, n, hit.triangle, offset_point(p, n, epsilon) - p)
                }
                None => (Vec3::ZERO, Vec3::ZERO, u32::MAX, Vec3::ZERO),
            }
        })
        .collect();
    GBuffer {
        width: w,
        height: h,
        position: rows.iter().map(|r| r.0).collect(),
        normal: rows.iter().map(|r| r.1).collect(),
        triangle: rows.iter().map(|r| r.2).collect(),
        offset: rows.iter().map(|r| r.3).collect(),
    }
}

/// What one algorithm produced for one frame.
#[derive(Clone, Debug)]
pub struct FrameOutput {
    pub visibility: VisibilityBuffer,
    pub counters: Counters,
    pub phases: Vec<Phase>,
    pub model_ms: Option<f64>,
    pub gpu_ms: Option<f64>,
    pub execution: BTreeMap<String, serde_json::Value>,
    pub warnings: Vec<String>,
    /// Light received per channel, from algorithms that honour a textured light
    /// ([`crate::algorithms::check_light_texture`]) when the scene has one.
    pub rgb: Option<RgbBuffer>,
    /// Host milliseconds of the run's GPU setup (wgpu only: a device acquired, modules and
    /// pipelines created, [`crate::gpu::cache`]), not part of the run's time; 0 when the
    /// device and every object were there from an earlier run.
    pub gpu_setup_ms: Option<f64>,
}
