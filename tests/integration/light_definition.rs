//! One definition of each light: the light an algorithm computes is the light its reference is
//! computed for, and a converted light that would pass through the scene is refused.
//!
//! Oracle for `soft_izb`: the analytic visible fraction of a disc light cut by a straight edge,
//! the area of a circular segment, computed here from the geometry alone.

use super::common::run_one;
use glam::Vec3;
use shadowbench::algorithms::{self, Backend, ExecContext};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::light_for_run;
use shadowbench::scene::generators::{self, primitives, GeneratorParams};
use shadowbench::scene::{Camera, Light, LightKind, Object, Role, Scene};

/// Light height, disc radius, and the occluder's edge: a thin slab over x < EDGE_X whose top
/// edge (x = EDGE_X, y = EDGE_TOP) bounds the shadow of a receiver on the ground at x > EDGE_X.
const H: f32 = 3.0;
const R: f32 = 0.5;
const EDGE_X: f32 = -0.3;
const EDGE_TOP: f32 = 1.01;

fn edge_scene(light: Light) -> Scene {
    let ground = Object {
        name: "ground".into(),
        mesh: primitives::plane(10.0, 8),
        role: Role::RECEIVER,
    };
    let slab = Object {
        name: "slab".into(),
        mesh: primitives::cuboid(
            Vec3::new(-10.0, 1.0, -10.0),
            Vec3::new(EDGE_X, EDGE_TOP, 10.0),
        ),
        role: Role {
            occluder: true,
            receiver: false,
        },
    };
    Scene {
        name: "straight-edge".into(),
        objects: vec![ground, slab],
        // Below the slab, looking at the ground across the penumbra: no eye ray meets the slab.
        camera: Camera {
            eye: Vec3::new(2.5, 0.6, 0.0),
            target: Vec3::new(-0.45, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 40.0,
        },
        light,
        light_texture: None,
    }
}

/// Visible fraction of a horizontal disc light (centre (0, H, 0), radius R) from ground point
/// `x_p`: a ray from the point to light point X (in the light's plane) is blocked by the slab
/// when X < X_e, X_e the top edge projected from the point; the visible part is the disc's
/// circular segment beyond X_e: (acos d − d·√(1 − d²))/π with d = X_e/R.
fn analytic_visible(x_p: f32) -> f32 {
    let x_e = x_p + (EDGE_X - x_p) * H / EDGE_TOP;
    let d = (x_e / R).clamp(-1.0, 1.0);
    (d.acos() - d * (1.0 - d * d).sqrt()) / std::f32::consts::PI
}

#[test]
fn soft_izb_matches_the_circular_segment_of_a_disc_cut_by_a_straight_edge() {
    // A sphere light, as a scenario gives it: soft_izb takes it as the disc in its image plane,
    // and the reference is computed for that same disc.
    let scene = edge_scene(Light::Sphere {
        center: Vec3::new(0.0, H, 0.0),
        radius: R,
    });
    let info = algorithms::find("soft_izb").unwrap();
    let mut scene = scene;
    scene.light = light_for_run(&scene, info).unwrap();
    assert_eq!(scene.light.kind(), LightKind::Disc);
    let params = RunParams::of_scene(&scene, [128, 96], 256, 16);
    let frame = Frame::new(scene, params);
    let ctx = ExecContext {
        reference_samples: 1024,
        ..Default::default()
    };
    let reference = algorithms::run("reference", Backend::CpuNative, &frame, &ctx)
        .unwrap()
        .visibility;
    let g = &frame.gbuffer;
    let penumbra: Vec<(usize, f32)> = (0..g.len())
        .filter(|&i| g.is_hit(i) && g.position[i].y.abs() < 1e-4)
        .map(|i| (i, analytic_visible(g.position[i].x)))
        .filter(|&(_, v)| v > 0.02 && v < 0.98)
        .collect();
    assert!(penumbra.len() > 500, "{} penumbra pixels", penumbra.len());
    let mae = |data: &[f32]| {
        penumbra
            .iter()
            .map(|&(i, v)| (data[i] - v).abs())
            .sum::<f32>()
            / penumbra.len() as f32
    };
    // The reference samples the same disc: its error is sampling noise.
    let e_ref = mae(&reference.data);
    assert!(
        e_ref < 0.01,
        "reference against the circular segment: {e_ref}"
    );
    for backend in [Backend::CpuNative, Backend::CpuModel] {
        let (record, out) = run_one(&frame, "soft_izb", backend, &ctx, Some(&reference));
        let out = out.unwrap_or_else(|| panic!("{:?}", record.failure));
        let e = mae(&out.visibility.data);
        let worst = penumbra
            .iter()
            .map(|&(i, v)| (out.visibility.data[i] - v).abs())
            .fold(0.0f32, f32::max);
        eprintln!("soft_izb {backend}: penumbra mae {e:.4}, max {worst:.4} (reference {e_ref:.4})");
        assert!(e < 0.01, "soft_izb {backend}: penumbra mae {e}");
        // The run records the light it used: the disc, not the scenario's sphere.
        assert_eq!(record.light, "disc");
        assert_eq!(
            record.execution["light"]["type"],
            serde_json::json!("disc"),
            "{:?}",
            record.execution
        );
    }
}

#[test]
fn a_converted_light_that_would_pass_through_the_ceiling_is_refused() {
    // A 130 × 105 rectangle 0.1 below a ceiling (the issue's case), over a floor.
    let ceiling = Object {
        name: "ceiling".into(),
        mesh: primitives::plane(400.0, 2)
            .transformed(glam::Mat4::from_translation(Vec3::new(0.0, 500.0, 0.0))),
        role: Role::BOTH,
    };
    let floor = Object {
        name: "floor".into(),
        mesh: primitives::plane(400.0, 2),
        role: Role::BOTH,
    };
    let rect = Light::Rect {
        center: Vec3::new(0.0, 499.9, 0.0),
        half_u: Vec3::new(65.0, 0.0, 0.0),
        half_v: Vec3::new(0.0, 0.0, 52.5),
    };
    let scene = Scene {
        name: "ceiling-light".into(),
        objects: vec![ceiling, floor],
        camera: Camera {
            eye: Vec3::new(0.0, 250.0, 600.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 50.0,
        },
        light: rect,
        light_texture: None,
    };
    // penumbra_map takes spheres only: a sphere of radius 65 pokes 64.9 through the ceiling.
    let e = light_for_run(&scene, algorithms::find("penumbra_map").unwrap()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("penumbra_map") && msg.contains("sphere") && msg.contains("$.light"),
        "{msg}"
    );
    // soft_izb takes the disc of radius 65 in the rectangle's own plane: it fits.
    let disc = light_for_run(&scene, algorithms::find("soft_izb").unwrap()).unwrap();
    assert_eq!(disc.kind(), LightKind::Disc);
    // The rectangle itself is in force for algorithms that take it.
    assert_eq!(
        light_for_run(&scene, algorithms::find("soft_shadow_map").unwrap()).unwrap(),
        rect
    );
    // A small sphere there fits.
    let mut small = scene.clone();
    small.light = Light::Rect {
        center: Vec3::new(0.0, 490.0, 0.0),
        half_u: Vec3::new(5.0, 0.0, 0.0),
        half_v: Vec3::new(0.0, 0.0, 4.0),
    };
    assert!(light_for_run(&small, algorithms::find("penumbra_map").unwrap()).is_ok());
}

/// The scene's own light passing through its geometry is refused as a converted one is, in
/// `render` (exit 2 naming `$.light`) and in a sweep (that run fails with the reason, the others
/// run): a sphere light of radius 3 on sphere-on-plane reaches down into the sphere below it.
#[test]
fn a_light_that_passes_through_the_scene_is_refused() {
    let scene = generators::find("sphere-on-plane")
        .unwrap()
        .build(&GeneratorParams::default());
    let c = scene.light.center();
    // The light centre's height above the highest point of the scene's geometry.
    let top = scene.bounds().max.y;
    let big = scene.light.with_size(2.0 * (c.y - top) + 1.0);
    let mut through = scene.clone();
    through.light = big;
    let e = light_for_run(&through, algorithms::find("pcss").unwrap()).unwrap_err();
    assert!(
        e.to_string().contains("$.light") && e.to_string().contains("passes through"),
        "{e}"
    );
    assert!(light_for_run(&scene, algorithms::find("pcss").unwrap()).is_ok());

    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let json = format!(
        r#"{{"name": "through", "scene": {{"generator": "sphere-on-plane"}},
            "algorithms": ["pcss"], "backends": ["cpu-native"],
            "params": {{"image": [32, 24]}}, "sweep": {{"light_size": [{}, {}]}},
            "reference": {{"enabled": false}}}}"#,
        scene.light.size(),
        big.size()
    );
    let file = dir.join("through.json");
    std::fs::write(&file, json).unwrap();
    let out_dir = dir.join("out");
    let out = super::common::shadowbench(&[
        "run",
        file.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "-q",
    ]);
    assert!(out.status.success(), "{}", super::common::stderr(&out));
    let results: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("out/results.json")).unwrap()).unwrap();
    let failures: Vec<_> = results["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["failure"].as_str().map(|f| f.contains("passes through")))
        .collect();
    assert_eq!(failures, [None, Some(true)], "{results}");
}

#[test]
fn emitters_meet_the_triangles_they_cross_and_no_others() {
    let tri = [
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 0.0, -1.0),
        Vec3::new(0.0, 0.0, 1.0),
    ];
    let sphere = |y: f32| Light::Sphere {
        center: Vec3::new(0.0, y, 0.0),
        radius: 0.5,
    };
    assert!(sphere(0.4).meets_triangle(tri));
    assert!(!sphere(0.6).meets_triangle(tri));
    // A vertical disc crossing the triangle's plane meets it; lifted by more than its radius,
    // not.
    let disc = |y: f32| Light::Disc {
        center: Vec3::new(0.0, y, 0.0),
        normal: Vec3::X,
        radius: 0.5,
    };
    assert!(disc(0.3).meets_triangle(tri));
    assert!(!disc(0.6).meets_triangle(tri));
    // A vertical rectangle beside the triangle (past its right corner) does not meet it.
    let rect = |x: f32| Light::Rect {
        center: Vec3::new(x, 0.0, -1.0),
        half_u: Vec3::new(0.0, 0.5, 0.0),
        half_v: Vec3::new(0.0, 0.0, 0.2),
    };
    assert!(rect(0.5).meets_triangle(tri));
    assert!(!rect(1.5).meets_triangle(tri));
}

/// accum_hard casts its hard shadows from points of one fixed emitter, so it takes a sphere as
/// the disc facing the scene's centre: the conversion is the harness's (said in the run's
/// warnings, the reference computed for that disc), and against the exact answer for that disc
/// (the circular segment) its penumbra is right to its sampling.
#[test]
fn accum_hard_takes_a_sphere_as_a_converted_disc_and_matches_that_disc() {
    let sphere = Light::Sphere {
        center: Vec3::new(0.0, H, 0.0),
        radius: R,
    };
    let mut scene = edge_scene(sphere);
    let info = algorithms::find("accum_hard").unwrap();
    assert_eq!(info.light_for(LightKind::Sphere), LightKind::Disc);
    scene.light = light_for_run(&scene, info).unwrap();
    assert_eq!(scene.light.kind(), LightKind::Disc);
    assert_eq!(scene.light.size(), R);
    let params = RunParams::of_scene(&scene, [64, 48], 256, 16);
    let frame = Frame::new(scene, params);
    let g = &frame.gbuffer;
    let penumbra: Vec<(usize, f32)> = (0..g.len())
        .filter(|&i| g.is_hit(i) && g.position[i].y.abs() < 1e-4)
        .map(|i| (i, analytic_visible(g.position[i].x)))
        .filter(|&(_, v)| v > 0.02 && v < 0.98)
        .collect();
    assert!(penumbra.len() > 100, "{} penumbra pixels", penumbra.len());
    let ctx = ExecContext {
        options: [(
            "accum_hard".to_string(),
            serde_json::json!({ "samples": 256 }),
        )]
        .into(),
        ..Default::default()
    };
    for backend in [Backend::CpuNative, Backend::CpuModel] {
        let out = algorithms::run("accum_hard", backend, &frame, &ctx).unwrap();
        let e = penumbra
            .iter()
            .map(|&(i, v)| (out.visibility.data[i] - v).abs())
            .sum::<f32>()
            / penumbra.len() as f32;
        assert!(e < 0.01, "accum_hard {backend}: penumbra mae {e}");
    }
    // The command says so: a sphere scene rendered with accum_hard notes the conversion.
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out = super::common::shadowbench(&[
        "render",
        "--scene",
        "sphere-on-plane",
        "--algorithm",
        "accum_hard",
        "--image",
        "16x12",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", super::common::stderr(&out));
    let run = super::common::json(&out_dir.join("run.json"));
    assert_eq!(run["light"], "disc", "{run}");
    assert!(
        run["notes"].as_array().unwrap().iter().any(|w| w
            .as_str()
            .unwrap()
            .contains("light converted from sphere to disc")),
        "{run}"
    );
}

/// A converted light keeps its size exactly: a sphere or disc of size s made a rectangle has
/// |half_u| = s in `f32` (a size of 1 was recorded as 0.99999994), and back again.
#[test]
fn converted_light_sizes_round_trip_exactly() {
    let rect_taker = algorithms::find("soft_shadow_map").unwrap();
    let sphere_taker = algorithms::find("penumbra_map").unwrap();
    for size in [1.0f32, 0.3, 0.7, 0.1, 1.5, 0.123_456_7] {
        for center in [
            Vec3::new(0.0, H, 0.0),
            Vec3::new(1.3, H, -0.7),
            Vec3::new(-2.0, H + 0.5, 1.1),
        ] {
            let mut scene = edge_scene(Light::Sphere {
                center,
                radius: size,
            });
            let rect = light_for_run(&scene, rect_taker).unwrap();
            assert_eq!(rect.kind(), LightKind::Rect);
            assert_eq!(
                rect.size(),
                size,
                "sphere {size} at {center} as a rectangle"
            );
            scene.light = rect;
            let back = light_for_run(&scene, sphere_taker).unwrap();
            assert_eq!(back.size(), size, "and back");
        }
    }
}

/// Grazing pixels are scored apart, with a note. A unit cube on the ground lit by a sphere light whose
/// centre lies 0.05 in front of the plane of the cube's +z face: that face sees about half the
/// light in front of its plane, and the reference counts the other half as hidden, while a
/// shadow map shows the face lit. Oracle for the grazing pixels: the reference's own light
/// samples, some in front of the surface's plane and some behind it (a sampled oracle misses
/// only thin slivers of the emitter, so it may call a few pixels of the analytic mask
/// one-sided, never the reverse).
#[test]
fn grazing_pixels_are_scored_apart_with_a_note() {
    let ground = Object {
        name: "ground".into(),
        mesh: primitives::plane(6.0, 8),
        role: Role::RECEIVER,
    };
    let cube = Object {
        name: "cube".into(),
        mesh: primitives::cuboid(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 1.0, 0.5)),
        role: Role::BOTH,
    };
    let scene = Scene {
        name: "grazed-cube".into(),
        objects: vec![ground, cube],
        camera: Camera {
            eye: Vec3::new(1.5, 2.0, 4.0),
            target: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            fov_y_deg: 45.0,
        },
        light: Light::Sphere {
            center: Vec3::new(1.8, 1.6, 0.55),
            radius: 0.4,
        },
        light_texture: None,
    };
    let params = RunParams::of_scene(&scene, [96, 72], 512, 32);
    let frame = Frame::new(scene, params);
    let g = &frame.gbuffer;
    let grazing = frame.grazing_mask();
    let light = frame.scene.light;
    let (mut both, mut sampled_one_sided) = (0, 0);
    let mut samples = Vec::new();
    for i in (0..g.len()).filter(|&i| g.is_hit(i)) {
        let (p, n) = (g.position[i], g.normal[i]);
        light.stratified_samples_into(p, 16, i as u64, &mut samples);
        let front = samples.iter().filter(|&&q| n.dot(q - p) > 0.0).count();
        let straddles = front > 0 && front < 256;
        assert!(!straddles || grazing[i], "pixel {i}: samples on both sides");
        both += usize::from(straddles);
        sampled_one_sided += usize::from(grazing[i] && !straddles);
    }
    assert!(both > 300, "{both} grazing pixels");
    assert!(
        sampled_one_sided * 50 <= both,
        "{sampled_one_sided} of {both}"
    );

    let truth = algorithms::reference::render(&frame, 64, 1).visibility;
    let run = algorithms::run(
        "hard_shadow_map",
        Backend::CpuNative,
        &frame,
        &ExecContext::default(),
    )
    .unwrap();
    let e = shadowbench::metrics::compare_with_receivers(
        &run.visibility,
        &truth,
        &g.mask(),
        &frame.receiver_only_mask(),
        &grazing,
    );
    let (all, without) = (e.mae_shadow.unwrap(), e.mae_shadow_non_grazing.unwrap());
    eprintln!("grazed cube: {both} grazing pixels; mae_shadow {all:.4}, without them {without:.4}");
    assert_eq!(
        e.grazing_pixels as usize,
        grazing.iter().filter(|&&x| x).count()
    );
    // On the grazed face the shadow map shows lit what the reference has at about half.
    let on_grazing: Vec<f32> = (0..g.len())
        .filter(|&i| grazing[i])
        .map(|i| (run.visibility.data[i] - truth.data[i]).abs())
        .collect();
    let grazing_mae = on_grazing.iter().sum::<f32>() / on_grazing.len() as f32;
    eprintln!("grazed cube: error on the grazing pixels {grazing_mae:.3}");
    assert!(grazing_mae > 0.3, "{grazing_mae}");
    assert!(without < 0.8 * all, "{without} against {all}");
    let w = shadowbench::metrics::grazing_note(&e, "hard_shadow_map").unwrap();
    assert!(
        w.starts_with(&format!("{} pixels", e.grazing_pixels)) && w.contains("hard_shadow_map"),
        "{w}"
    );
}
