//! The ground-truth reference against analytic visibility, and its determinism.

use glam::Vec3;
use shadowbench::algorithms::reference::{self, visible_fraction};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::bvh::SceneBvh;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::{Light, Mesh, Object, Role, Scene};

/// Fraction of a disc of radius `r` lying beyond a chord at signed distance `d` from its centre:
/// the circular-segment area over the disc area.
fn segment_fraction(d: f32, r: f32) -> f32 {
    let x = (d / r).clamp(-1.0, 1.0);
    (x.acos() - x * (1.0 - x * x).sqrt()) / std::f32::consts::PI
}

/// A half-plane occluder y = h, x < 0 over the ground, under a spherical light.
fn half_plane_scene(h: f32, light: Light) -> Scene {
    let l = 60.0;
    let occluder = Mesh {
        positions: vec![
            Vec3::new(-l, h, -l),
            Vec3::new(0.0, h, -l),
            Vec3::new(0.0, h, l),
            Vec3::new(-l, h, l),
        ],
        triangles: vec![[0, 2, 1], [0, 3, 2]],
    };
    Scene {
        name: "half-plane".into(),
        objects: vec![Object {
            name: "edge".into(),
            mesh: occluder,
            role: Role::BOTH,
        }],
        camera: generators::find("sphere-on-plane")
            .unwrap()
            .build(&GeneratorParams::default())
            .camera,
        light,
        light_texture: None,
    }
}

#[test]
fn straight_edge_under_a_sphere_light_matches_the_circular_segment() {
    let (h, r) = (1.0f32, 0.5f32);
    let c = Vec3::new(0.3, 4.0, 0.2);
    let light = Light::Sphere {
        center: c,
        radius: r,
    };
    let scene = half_plane_scene(h, light);
    let bvh = SceneBvh::build(&scene.flatten());
    let k = reference::strata_side(reference::PAPER_SAMPLES).unwrap();
    let mut checked_penumbra = 0;
    for i in 0..=24 {
        let xp = -0.5 + i as f32 * (0.8 / 24.0);
        let p = Vec3::new(xp, 0.0, 0.0);
        // The ray p→l meets y = h at x = xp + (lx − xp)·h/ly; it is blocked when that is < 0,
        // i.e. when f(l) = xp·ly + h·lx < xp·h. f is linear, so on the emitter disc (centre c,
        // perpendicular to w) the blocked part is a half-plane: a circular segment.
        let w = (c - p).normalize();
        let g = Vec3::new(h, xp, 0.0);
        let g_perp = g - g.dot(w) * w;
        let s = (xp * h - (xp * c.y + h * c.x)) / g_perp.length();
        let expected = segment_fraction(s, r);
        let got = visible_fraction(&bvh, &light, p + Vec3::Y * 1e-4, k, 17 + i as u64);
        assert!(
            (got - expected).abs() <= 0.01,
            "x = {xp}: reference {got}, analytic {expected}"
        );
        if expected > 0.05 && expected < 0.95 {
            checked_penumbra += 1;
        }
    }
    assert!(checked_penumbra >= 5, "the test must cross the penumbra");
}

#[test]
fn reference_is_bit_identical_across_thread_counts() {
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let scene = generators::find("torus-on-plane")
                .unwrap()
                .build(&GeneratorParams::default());
            let params = RunParams::of_scene(&scene, [64, 48], 256, 32);
            let frame = Frame::new(scene, params);
            reference::render(&frame, 64, 5).visibility
        })
    };
    let (a, b) = (render(1), render(2));
    assert!(
        a.data.iter().any(|&v| v < 0.5),
        "the frame must contain shadow"
    );
    assert!(a.data.iter().any(|&v| v > 0.0 && v < 1.0), "and penumbra");
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.data), bits(&b.data));
}
