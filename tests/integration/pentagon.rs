//! The planar pentagon of the soft shadow volume tests and its rectangular light.

use glam::Vec3;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::{Light, Mesh, Object, Role, Scene};

/// A single planar pentagon (an open surface: its outline is its silhouette from every point of
/// the light) above the ground: no single-silhouette and no overlap error (III §5.3).
pub fn planar_polygon_scene(light: Light) -> Scene {
    let ground = generators::find("plate-on-plane")
        .unwrap()
        .build(&GeneratorParams::default());
    let mut objects: Vec<Object> = ground
        .objects
        .into_iter()
        .filter(|o| o.name != "plate")
        .collect();
    let ring: Vec<Vec3> = (0..5)
        .map(|k| {
            let a = k as f32 * std::f32::consts::TAU / 5.0 + 0.3;
            Vec3::new(1.3 * a.cos(), 1.6 + 0.15 * a.sin(), 1.1 * a.sin())
        })
        .collect();
    let mut positions = vec![Vec3::new(0.0, 1.6, 0.0)];
    positions.extend(ring);
    objects.push(Object {
        name: "pentagon".into(),
        mesh: Mesh {
            positions,
            triangles: (0..5u32).map(|k| [0, 1 + (k + 1) % 5, 1 + k]).collect(),
        },
        role: Role::BOTH,
    });
    Scene {
        name: "pentagon".into(),
        objects,
        camera: ground.camera,
        light,
        light_texture: None,
    }
}

/// The pentagon of [`planar_polygon_scene`] made a closed slab 0.05 thick (its outline and top
/// unchanged), for z-fail counting, which needs closed occluders.
pub fn closed_polygon_scene(light: Light) -> Scene {
    let mut scene = planar_polygon_scene(light);
    let pentagon = scene.objects.last_mut().expect("the pentagon");
    let m = &mut pentagon.mesh;
    let n = m.positions.len() as u32;
    let below: Vec<Vec3> = m
        .positions
        .iter()
        .map(|p| *p - Vec3::new(0.0, 0.05, 0.0))
        .collect();
    m.positions.extend(below);
    let top = m.triangles.clone();
    for [a, b, c] in top {
        m.triangles.push([a + n, c + n, b + n]);
    }
    for k in 0..5u32 {
        let (a, b) = (1 + k, 1 + (k + 1) % 5);
        m.triangles.push([a, b, b + n]);
        m.triangles.push([a, b + n, a + n]);
    }
    scene
}

pub fn rect_light() -> Light {
    Light::Rect {
        center: Vec3::new(0.4, 6.0, 0.2),
        half_u: Vec3::new(0.9, 0.0, 0.0),
        half_v: Vec3::new(0.0, 0.0, 0.7),
    }
}
