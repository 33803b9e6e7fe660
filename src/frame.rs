//! One frame's input, shared by every algorithm and backend: the scene with the light in force,
//! the run parameters, and the eye pass.
//!
//! The eye pass (which surface each pixel sees) is computed once per frame by ray casting and
//! handed to every algorithm and backend alike. Every shadow algorithm needs it, none of the
//! papers counts it in its shadow cost, and sharing it keeps the comparison between algorithms
//! and between executions about the shadows alone.

use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::scene::bvh::SceneBvh;
use crate::scene::{FlatMesh, Scene};

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
}

impl GBuffer {
    pub fn is_hit(&self, i: usize) -> bool {
        self.triangle[i] != u32::MAX
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
    /// Offset along the normal used to leave a surface without hitting it again, scaled to the
    /// scene (1e-4 of its diagonal).
    pub epsilon: f32,
}

impl Frame {
    pub fn new(scene: Scene, params: RunParams) -> Frame {
        let flat = scene.flatten();
        let bvh = SceneBvh::build(&flat);
        let epsilon = scene.bounds().diagonal().max(1e-3) * 1e-4;
        let gbuffer = eye_pass(&scene, &flat, &bvh, params.image[0], params.image[1]);
        Frame {
            scene,
            flat,
            bvh,
            gbuffer,
            params,
            epsilon,
        }
    }

    /// Pixels whose surface belongs to a receiver-only object (receives, does not occlude).
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

/// Primary rays through each pixel centre.
fn eye_pass(scene: &Scene, flat: &FlatMesh, bvh: &SceneBvh, w: u32, h: u32) -> GBuffer {
    let cam = scene.camera;
    let n = (w * h) as usize;
    let rows: Vec<(Vec3, Vec3, u32)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i as u32 % w, i as u32 / w);
            let d = cam.ray_direction(x, y, w, h);
            match bvh.closest(cam.eye, d) {
                Some(hit) => {
                    let p = cam.eye + d * hit.t;
                    let n = flat
                        .mesh
                        .face_normal(hit.triangle as usize)
                        .normalize_or_zero();
                    let n = if n.dot(d) > 0.0 { -n } else { n };
                    (p, n, hit.triangle)
                }
                None => (Vec3::ZERO, Vec3::ZERO, u32::MAX),
            }
        })
        .collect();
    GBuffer {
        width: w,
        height: h,
        position: rows.iter().map(|r| r.0).collect(),
        normal: rows.iter().map(|r| r.1).collect(),
        triangle: rows.iter().map(|r| r.2).collect(),
    }
}
