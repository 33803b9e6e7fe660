//! Degenerate geometry never crashes the scene pipeline and never puts NaN or a value outside
//! [0, 1] into a visibility buffer. Property tests throw random triangle soups at it.

use glam::Vec3;
use proptest::prelude::*;
use shadowbench::algorithms::reference;
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::adjacency::EdgeAdjacency;
use shadowbench::scene::generators::primitives;
use shadowbench::scene::{Camera, Light, Mesh, Object, Role, Scene};

fn frame_of(objects: Vec<Object>, light: Light, camera: Camera) -> Frame {
    let scene = Scene {
        name: "degenerate".into(),
        objects,
        camera,
        light,
    };
    let params = RunParams {
        triangles: scene.triangle_count() as u32,
        light_size: light.size(),
        map_resolution: 64,
        tile_size: 16,
        image: [24, 18],
        occluder_height: None,
        cores: None,
    };
    Frame::new(scene, params)
}

fn object(mesh: Mesh) -> Object {
    Object {
        name: "o".into(),
        mesh,
        role: Role::BOTH,
    }
}

fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 4.0, 6.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 50.0,
    }
}

fn sphere_light(center: Vec3, radius: f32) -> Light {
    Light::Sphere { center, radius }
}

/// The named degenerate scenes of the robustness list.
fn degenerate_scenes() -> Vec<(&'static str, Frame)> {
    let ground = || object(primitives::plane(4.0, 4));
    let cube = |c: Vec3, s: f32| object(primitives::cuboid(c - Vec3::splat(s), c + Vec3::splat(s)));
    let light = sphere_light(Vec3::new(0.5, 5.0, 0.2), 0.5);
    let zero_area = Mesh {
        positions: vec![
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 0, 1]],
    };
    let mut duplicated = primitives::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5));
    duplicated.append(&primitives::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5)));
    let non_manifold = Mesh {
        positions: vec![
            Vec3::new(-1.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 2.0, 0.5),
            Vec3::new(0.0, 1.5, -1.0),
            Vec3::new(0.0, 0.5, 0.5),
        ],
        triangles: vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    };
    let open = {
        let mut m = primitives::uv_sphere(12, 6);
        m.triangles.truncate(m.triangles.len() / 2);
        m.transformed(glam::Mat4::from_translation(Vec3::Y * 1.5))
    };
    vec![
        (
            "zero-area triangles",
            frame_of(vec![ground(), object(zero_area)], light, camera()),
        ),
        (
            "duplicate vertices and faces",
            frame_of(vec![ground(), object(duplicated)], light, camera()),
        ),
        (
            "non-manifold edge",
            frame_of(vec![ground(), object(non_manifold)], light, camera()),
        ),
        (
            "open mesh",
            frame_of(vec![ground(), object(open)], light, camera()),
        ),
        (
            "light inside a closed mesh",
            frame_of(
                vec![ground(), cube(Vec3::new(0.5, 5.0, 0.2), 1.0)],
                light,
                camera(),
            ),
        ),
        (
            "geometry touching the light",
            frame_of(
                vec![ground(), cube(Vec3::new(0.5, 4.0, 0.2), 0.5)],
                light,
                camera(),
            ),
        ),
        (
            "occluder behind the light",
            frame_of(
                vec![ground(), cube(Vec3::new(0.5, 8.0, 0.2), 1.0)],
                light,
                camera(),
            ),
        ),
        (
            "eye inside a shadow volume",
            frame_of(
                vec![ground(), cube(Vec3::new(0.0, 3.0, 3.0), 0.8)],
                sphere_light(Vec3::new(0.0, 6.0, 6.0), 0.3),
                camera(),
            ),
        ),
        (
            "edge pointing at the light centre",
            frame_of(
                vec![
                    ground(),
                    object(Mesh {
                        positions: vec![
                            Vec3::new(0.5, 2.0, 0.2),
                            Vec3::new(0.5, 3.0, 0.2),
                            Vec3::new(1.5, 2.0, 0.2),
                        ],
                        triangles: vec![[0, 1, 2]],
                    }),
                ],
                light,
                camera(),
            ),
        ),
        ("empty scene", frame_of(vec![], light, camera())),
    ]
}

#[test]
fn reference_stays_in_range_on_degenerate_scenes() {
    for (name, frame) in degenerate_scenes() {
        let out = reference::render(&frame, 16, 3);
        out.visibility
            .check_range()
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        // Silhouette extraction reports, never fails.
        let adj = EdgeAdjacency::build(&frame.scene.occluders());
        let _ = adj.silhouette_from(frame.scene.light.center());
    }
}

#[test]
fn light_inside_a_closed_mesh_sees_nothing() {
    let (_, frame) = degenerate_scenes()
        .into_iter()
        .find(|(n, _)| *n == "light inside a closed mesh")
        .unwrap();
    let out = reference::render(&frame, 16, 3);
    let mask = frame.gbuffer.mask();
    // Every ground pixel outside the cube's footprint is shadowed by the cube around the light.
    let lit = out
        .visibility
        .data
        .iter()
        .zip(&mask)
        .filter(|(v, m)| **m && **v > 0.0)
        .count();
    assert_eq!(lit, 0, "no light escapes a closed box around it");
}

fn vec3() -> impl Strategy<Value = Vec3> {
    (-3.0f32..3.0, -0.5f32..4.0, -3.0f32..3.0).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Random triangle soups (with repeated indices, coincident points, light anywhere) give a
    /// visibility buffer in [0, 1] and silhouettes without panics.
    #[test]
    fn random_scenes_give_valid_visibility(
        points in prop::collection::vec(vec3(), 3..24),
        tris in prop::collection::vec((0usize..24, 0usize..24, 0usize..24), 1..32),
        light_at in vec3(),
        radius in 0.01f32..2.0,
        kind in 0u8..3,
    ) {
        let n = points.len();
        let mesh = Mesh {
            triangles: tris.iter().map(|&(a, b, c)| [(a % n) as u32, (b % n) as u32, (c % n) as u32]).collect(),
            positions: points,
        };
        let light = match kind {
            0 => Light::Sphere { center: light_at, radius },
            1 => Light::Disc { center: light_at, normal: Vec3::NEG_Y, radius },
            _ => Light::Rect { center: light_at, half_u: Vec3::X * radius, half_v: Vec3::Z * radius },
        };
        let frame = frame_of(vec![object(primitives::plane(4.0, 2)), object(mesh)], light, camera());
        let out = reference::render(&frame, 4, 9);
        prop_assert!(out.visibility.check_range().is_ok());
        let adj = EdgeAdjacency::build(&frame.scene.occluders());
        let s = adj.silhouette_from(light_at);
        prop_assert!(s.edges.iter().all(|e| e.a.is_finite() && e.b.is_finite()));
    }
}
