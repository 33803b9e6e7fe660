//! Object roles: an object whose role lacks `occluder` casts no shadow. The reference and every
//! method that honours roles leave the ground under such an object lit; a method whose shadow
//! map must hold every surface declares `MethodLimit::NonOccludersCast`, and a run where it matters
//! says so.

use glam::Vec3;
use shadowbench::algorithms::{reference, Backend, MethodLimit, ALGORITHMS};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::{light_as, limit_notes};
use shadowbench::scene::bvh::SceneBvh;
use shadowbench::scene::generators::primitives;
use shadowbench::scene::{Light, Mesh, Object, Role, Scene};

use super::common::{camera, run_on};
use super::gpu_check::have_gpu;

fn receiver(name: &str, mesh: Mesh) -> Object {
    Object {
        name: name.into(),
        mesh,
        role: Role::RECEIVER,
    }
}

/// A ground and a box floating above it, both receivers only, under `light`; 48×36.
fn floating_box(light: Light) -> Frame {
    let scene = Scene {
        name: "floating receiver".into(),
        objects: vec![
            receiver("ground", primitives::plane(4.0, 4)),
            receiver(
                "box",
                primitives::cuboid(Vec3::new(-0.6, 1.0, -0.6), Vec3::new(0.6, 1.6, 0.6)),
            ),
        ],
        camera: camera(),
        light,
        light_texture: None,
    };
    let params = RunParams::of_scene(&scene, [48, 36], 128, 16);
    Frame::new(scene, params)
}

/// Pixels of the ground (object 0) that face the light centre.
fn ground_pixels(frame: &Frame) -> Vec<usize> {
    let g = &frame.gbuffer;
    let centre = frame.scene.light.center();
    (0..g.len())
        .filter(|&i| {
            g.is_hit(i)
                && frame.flat.object_of_triangle[g.triangle[i] as usize] == 0
                && g.normal[i].dot(centre - g.position[i]) > 0.0
        })
        .collect()
}

#[test]
fn a_receiver_only_object_shadows_nothing_in_the_reference_or_a_method_that_honours_roles() {
    let light = Light::Sphere {
        center: Vec3::new(0.3, 4.0, 0.2),
        radius: 0.5,
    };
    for info in ALGORITHMS.iter().filter(|a| a.id != "reference") {
        let mut frame = floating_box(light);
        frame.scene.light = light_as(light, info.lights[0], Vec3::ZERO);
        let ground = ground_pixels(&frame);
        assert!(
            ground.len() > 500,
            "{}: {} ground pixels",
            info.id,
            ground.len()
        );
        // Without the role the box would shadow the ground below it: the scene tests something.
        let centre = frame.scene.light.center();
        let g = &frame.gbuffer;
        let under_box = ground
            .iter()
            .filter(|&&i| frame.bvh.blocked_by_any(g.shading_point(i), centre))
            .count();
        assert!(
            under_box > 20,
            "{}: {under_box} pixels under the box",
            info.id
        );

        let truth = reference::render(&frame, 16, 1);
        let lit = |v: &[f32]| ground.iter().filter(|&&i| v[i] < 1.0).count();
        assert_eq!(lit(&truth.visibility.data), 0, "{}: reference", info.id);

        // The box's front face (seen from the camera) faces away from the light: the methods
        // without a facing test leave it lit and say so.
        let warnings = limit_notes(&frame, info, &truth.visibility);
        for (limit, text) in [
            (MethodLimit::NonOccludersCast, "not occluders cast shadows"),
            (
                MethodLimit::AvertedNonOccludersLit,
                "facing away from the light are lit",
            ),
        ] {
            let warned = warnings.iter().any(|w| w.contains(text));
            assert_eq!(
                warned,
                info.limits.contains(&limit),
                "{}: {warnings:?}",
                info.id
            );
        }
        let casts = info.limits.contains(&MethodLimit::NonOccludersCast);
        let gpu = have_gpu() && info.backends.contains(&Backend::Wgpu);
        for backend in [Backend::CpuNative, Backend::Wgpu]
            .into_iter()
            .take(1 + usize::from(gpu))
        {
            let out = run_on(backend, &frame, info.id, serde_json::Value::Null);
            let shadowed = lit(&out.visibility.data);
            let what = format!(
                "{} on {backend:?}: {shadowed} ground pixels shadowed",
                info.id
            );
            assert!(if casts { shadowed > 20 } else { shadowed == 0 }, "{what}");
        }
    }
}

/// The surface itself hides the part of the light behind its plane, even when it is a
/// receiver only: a vertical square light of half-side `a` whose centre is `h` above a
/// receiver-only ground shows the ground a fraction (a + h) / 2a of its samples.
#[test]
fn a_receiver_only_ground_hides_the_part_of_the_light_below_its_plane() {
    let (a, h) = (1.0f32, 0.5f32);
    let light = Light::Rect {
        center: Vec3::new(0.0, h, -3.0),
        half_u: Vec3::new(a, 0.0, 0.0),
        half_v: Vec3::new(0.0, a, 0.0),
    };
    let scene = Scene {
        name: "ground".into(),
        objects: vec![receiver("ground", primitives::plane(4.0, 4))],
        camera: camera(),
        light,
        light_texture: None,
    };
    let bvh = SceneBvh::build(&scene.flatten());
    let k = 32;
    let expected = (a + h) / (2.0 * a);
    for (i, x) in [-1.0f32, 0.0, 0.7].into_iter().enumerate() {
        let p = Vec3::new(x, 1e-4, 0.5);
        let got = reference::visible_fraction(&bvh, &light, (p, Some(Vec3::Y)), k, 3 + i as u64);
        assert!(
            (got - expected).abs() <= 1.0 / k as f32,
            "x = {x}: {got}, expected {expected}"
        );
    }
}
