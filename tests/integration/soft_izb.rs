//! Soft irregular shadow mapping (paper 004) against analytic visibility, the reference, and its
//! own stated properties (conservative optimisations, §2.1 correctness without adjacency).

use super::common;

use glam::Vec3;
use shadowbench::algorithms::{self, Backend, ExecContext, FrameOutput};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::generators::{self, primitives, GeneratorParams};
use shadowbench::scene::{Camera, Light, Mesh, Object, Role, Scene};

use super::gpu_check;
use gpu_check::have_gpu;

fn params(scene: &Scene, image: [u32; 2]) -> RunParams {
    RunParams::of_scene(scene, image, 256, 16)
}

fn run(frame: &Frame, options: serde_json::Value) -> FrameOutput {
    let mut ctx = ExecContext::default();
    ctx.options.insert("soft_izb".into(), options);
    algorithms::run("soft_izb", Backend::CpuNative, frame, &ctx).unwrap()
}

/// Fraction of a disc of radius `r` beyond a chord at signed distance `d` from its centre.
fn segment_fraction(d: f32, r: f32) -> f32 {
    let x = (d / r).clamp(-1.0, 1.0);
    (x.acos() - x * (1.0 - x * x).sqrt()) / std::f32::consts::PI
}

/// A half-plane occluder above a ground plane under a sphere light, and the light's centre,
/// radius and the occluder's height.
fn straight_edge() -> (Frame, Vec3, f32, f32) {
    // A half-plane occluder y = h, x < 0 above a ground plane; the eye looks under it at the
    // penumbra its straight edge x = 0 casts.
    let (h, r, l) = (1.0f32, 0.5f32, 6.0f32);
    let c = Vec3::new(0.3, 4.0, 0.2);
    let occluder = Mesh {
        positions: vec![
            Vec3::new(-l, h, -l),
            Vec3::new(0.0, h, -l),
            Vec3::new(0.0, h, l),
            Vec3::new(-l, h, l),
        ],
        triangles: vec![[0, 2, 1], [0, 3, 2]],
    };
    let scene = Scene {
        name: "straight-edge".into(),
        objects: vec![
            Object {
                name: "ground".into(),
                mesh: primitives::plane(l, 8),
                role: Role::RECEIVER,
            },
            Object {
                name: "edge".into(),
                mesh: occluder,
                role: Role::BOTH,
            },
        ],
        camera: Camera {
            eye: Vec3::new(1.6, 0.6, 0.0),
            target: Vec3::new(-0.1, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 50.0,
        },
        light: Light::Sphere {
            center: c,
            radius: r,
        },
        light_texture: None,
    };
    let frame = Frame::new(scene.clone(), params(&scene, [64, 48]));
    (frame, c, r, h)
}

/// Checks `out` against the analytic visible fraction of the straight-edge scene: within 0.02
/// at every ground pixel near the edge, with a penumbra to check.
fn check_straight_edge(frame: &Frame, c: Vec3, r: f32, h: f32, out: &FrameOutput) {
    let g = &frame.gbuffer;
    let (mut checked, mut penumbra, mut worst) = (0, 0, 0.0f32);
    for i in 0..g.len() {
        let p = g.position[i];
        if !g.is_hit(i) || p.y.abs() > 1e-3 || p.z.abs() > 2.0 {
            continue;
        }
        // Blocked rays p→l satisfy f(l) = p.x·l.y + h·l.x < p.x·h, a half-space: on the emitter
        // disc facing p its blocked part is a circular segment.
        let w = (c - p).normalize();
        let grad = Vec3::new(h, p.x, 0.0);
        let grad_perp = grad - grad.dot(w) * w;
        let s = (p.x * h - (p.x * c.y + h * c.x)) / grad_perp.length();
        let expected = segment_fraction(s, r);
        let got = out.visibility.data[i];
        worst = worst.max((got - expected).abs());
        checked += 1;
        if expected > 0.05 && expected < 0.95 {
            penumbra += 1;
        }
    }
    assert!(checked > 200 && penumbra >= 20, "{checked} / {penumbra}");
    assert!(worst <= 0.02, "largest error {worst}");
}

#[test]
fn straight_edge_under_a_sphere_light_matches_the_analytic_visible_fraction() {
    let (frame, c, r, h) = straight_edge();
    let out = run(&frame, serde_json::json!({}));
    check_straight_edge(&frame, c, r, h, &out);
}

fn small(name: &str, triangles: u32) -> Frame {
    let scene = generators::find(name).unwrap().build(&GeneratorParams {
        triangles: Some(triangles),
        ..Default::default()
    });
    Frame::new(scene.clone(), params(&scene, [64, 48]))
}

#[test]
fn overdraw_optimisations_are_conservative_and_reduce_fill() {
    let frame = small("room", 3000);
    let off = run(
        &frame,
        serde_json::json!({"per_bin_width": false, "wedge_column_cull": false}),
    );
    let on = run(&frame, serde_json::json!({}));
    let bits = |o: &FrameOutput| {
        o.visibility
            .data
            .iter()
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&off), bits(&on), "culling must not change the image");
    let c = |o: &FrameOutput, k: &str| o.counters.get(k).unwrap();
    assert!(c(&on, "fill") > 0.0);
    assert!(c(&on, "fill") < c(&off, "fill"));
    assert!(c(&on, "overdraw") < c(&off, "overdraw"));
    for o in [&off, &on] {
        o.visibility.check_range().unwrap();
    }
}

#[test]
fn without_adjacency_every_edge_gives_the_same_shadow() {
    // §2.1: interior edges of occluding surfaces cancel pairwise in eq. 4.
    let frame = small("sphere-on-plane", 600);
    let adj = run(&frame, serde_json::json!({}));
    let all = run(&frame, serde_json::json!({"silhouettes": "all_edges"}));
    let n = adj.visibility.data.len() as f32;
    let mean: f32 = adj
        .visibility
        .data
        .iter()
        .zip(&all.visibility.data)
        .map(|(a, b)| (a - b).abs())
        .sum::<f32>()
        / n;
    assert!(adj.visibility.data.iter().any(|&v| v > 0.05 && v < 0.95));
    assert!(mean < 1e-3, "mean difference {mean}");
    assert!(all.counters.get("fill").unwrap() > adj.counters.get("fill").unwrap());
}

#[test]
fn close_to_the_reference_and_identical_across_thread_counts() {
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let frame = small("torus-on-plane", 2000);
            let out = run(&frame, serde_json::json!({}));
            let reference = shadowbench::algorithms::reference::render(&frame, 256, 3);
            (out, reference, frame.gbuffer.mask())
        })
    };
    let (a, reference, mask) = render(1);
    let (b, _, _) = render(2);
    assert_eq!(a.visibility, b.visibility);
    assert_eq!(a.counters, b.counters);
    a.visibility.check_range().unwrap();
    // Pixels without a surface are lit.
    for (i, hit) in mask.iter().enumerate() {
        if !hit {
            assert_eq!(a.visibility.data[i], 1.0);
        }
    }
    let shadowed: Vec<usize> = (0..mask.len())
        .filter(|&i| reference.visibility.data[i] < 0.99)
        .collect();
    assert!(shadowed.len() > 50);
    let mae: f32 = shadowed
        .iter()
        .map(|&i| (a.visibility.data[i] - reference.visibility.data[i]).abs())
        .sum::<f32>()
        / shadowed.len() as f32;
    // A hard shadow from the light centre, for scale: the error soft_izb must beat.
    let hard: f32 = shadowed
        .iter()
        .map(|&i| {
            let v = reference.visibility.data[i];
            (if v < 0.5 { v } else { 1.0 - v }).abs()
        })
        .sum::<f32>()
        / shadowed.len() as f32;
    assert!(mae < 0.5 * hard, "soft_izb {mae}, best hard shadow {hard}");
}

fn run_on(backend: Backend, frame: &Frame) -> FrameOutput {
    let ctx = ExecContext {
        machine: shadowbench::model::MachineConfig::larrabee(8),
        ..Default::default()
    };
    algorithms::run("soft_izb", backend, frame, &ctx).unwrap()
}

#[test]
fn the_model_execution_renders_the_native_image() {
    for (name, triangles) in [("room", 3000), ("torus-on-plane", 2000)] {
        let frame = small(name, triangles);
        let native = run_on(Backend::CpuNative, &frame);
        let model = run_on(Backend::CpuModel, &frame);
        assert_eq!(native.visibility, model.visibility, "{name}");
        assert!(native.model_ms.is_none());
        assert!(model.model_ms.unwrap() > 0.0);
        // Algorithm counters agree; the model adds what the machine executed.
        for k in ["fill", "overdraw", "samples", "hard_tests", "bin_entries"] {
            assert_eq!(native.counters.get(k), model.counters.get(k), "{name}: {k}");
        }
        let c = |k: &str| model.counters.get(k).unwrap_or(0.0);
        assert!(c("mem_model.read_bytes") > 0.0 && c("mem_model.write_bytes") > 0.0);
        // Every stored sample is scattered once and takes an atomic cursor in `construct`.
        let construct = model.phases.iter().find(|p| p.name == "construct").unwrap();
        let samples = construct.counters.get("samples").unwrap();
        assert!(samples > 0.0);
        assert_eq!(construct.counters.get("atomics"), Some(3.0 * samples));
        assert_eq!(
            construct.counters.get("mem_model.izb_samples.write_bytes"),
            Some(20.0 * samples)
        );
        // The umbra and penumbra tests gather one 20-byte record per sample they test.
        let hard = model.phases.iter().find(|p| p.name == "hard").unwrap();
        assert!(
            hard.counters
                .get("mem_model.izb_samples.read_bytes")
                .unwrap()
                >= 20.0 * hard.counters.get("hard_tests").unwrap()
        );
        let soft = model.phases.iter().find(|p| p.name == "soft").unwrap();
        assert!(
            soft.counters
                .get("mem_model.izb_samples.read_bytes")
                .unwrap()
                >= 20.0 * soft.counters.get("fill").unwrap()
        );
    }
}

#[test]
fn model_counters_and_time_do_not_depend_on_host_threads() {
    let render = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run_on(Backend::CpuModel, &small("room", 3000)))
    };
    let (a, b) = (render(1), render(2));
    assert_eq!(a.visibility, b.visibility);
    assert_eq!(a.counters, b.counters);
    assert_eq!(a.model_ms, b.model_ms);
    for (p, q) in a.phases.iter().zip(&b.phases) {
        assert_eq!(
            (&p.name, p.model_ms, &p.counters),
            (&q.name, q.model_ms, &q.counters)
        );
    }
}

#[test]
fn more_modelled_cores_take_less_modelled_time() {
    let scene = generators::find("room").unwrap().build(&GeneratorParams {
        triangles: Some(3000),
        ..Default::default()
    });
    let ms = |cores: u32| {
        let mut p = params(&scene, [128, 96]);
        p.cores = Some(cores);
        let frame = Frame::new(scene.clone(), p);
        let out = algorithms::run(
            "soft_izb",
            Backend::CpuModel,
            &frame,
            &ExecContext::default(),
        );
        out.unwrap().model_ms.unwrap()
    };
    let (one, four, sixteen) = (ms(1), ms(4), ms(16));
    assert!(four < one && sixteen < four, "{one} {four} {sixteen}");
}

fn run_with(backend: Backend, frame: &Frame, options: &serde_json::Value) -> FrameOutput {
    let mut ctx = ExecContext::default();
    ctx.options.insert("soft_izb".into(), options.clone());
    algorithms::run("soft_izb", backend, frame, &ctx).unwrap()
}

#[test]
fn wgpu_agrees_with_the_cpu_model() {
    if !have_gpu() {
        return;
    }
    let options = [
        serde_json::json!({}),
        serde_json::json!({"per_bin_width": false, "wedge_column_cull": false}),
    ];
    for name in ["sphere-on-plane", "box-on-plane", "torus-on-plane"] {
        let frame = small(name, 2000);
        let mask = frame.gbuffer.mask();
        for o in &options {
            let gpu = run_with(Backend::Wgpu, &frame, o);
            let model = run_with(Backend::CpuModel, &frame, o);
            gpu.visibility.check_range().unwrap();
            let e = shadowbench::metrics::compare(&gpu.visibility, &model.visibility, &mask);
            // Same formulas in f32; they differ by the GPU's acos and square root and by the
            // fixed-point accumulation (at most 2^-21 per edge), far below 1e-3 on average,
            // and no pixel may move by more than 0.1.
            assert!(e.mae.unwrap() < 1e-3, "{name} {o}: {e:?}");
            assert_eq!(e.frac_over_0_1.unwrap(), 0.0, "{name} {o}: {e:?}");
            assert!(
                e.shadow_pixels > 50,
                "{name} {o}: no shadow to compare: {e:?}"
            );
            // Counters: the registry's parity test (registry.rs, SoftIzb::WGPU_PARITY).
            let c = |out: &FrameOutput, k: &str| out.counters.get(k).unwrap_or(f64::NAN);
            assert!(
                c(&gpu, "fill") > 0.0 && c(&gpu, "hard_hits") > 0.0,
                "{name} {o}"
            );
            // Phases as on the CPU, each timed on the GPU where the adapter can.
            let names: Vec<&str> = gpu.phases.iter().map(|p| p.name.as_str()).collect();
            assert_eq!(names, ["geometry", "construct", "hard", "soft"]);
            if shadowbench::gpu::gpu().unwrap().queries.timestamp {
                assert!(gpu.phases[1..].iter().all(|p| p.gpu_ms.is_some()));
            }
        }
    }
}

#[test]
fn wgpu_matches_the_analytic_straight_edge() {
    if !have_gpu() {
        return;
    }
    let (frame, c, r, h) = straight_edge();
    let out = run_with(Backend::Wgpu, &frame, &serde_json::json!({}));
    check_straight_edge(&frame, c, r, h, &out);
}

#[test]
fn wgpu_optimisations_are_conservative_and_reduce_fill() {
    if !have_gpu() {
        return;
    }
    let frame = small("room", 3000);
    let off = run_with(
        Backend::Wgpu,
        &frame,
        &serde_json::json!({"per_bin_width": false, "wedge_column_cull": false}),
    );
    let on = run_with(Backend::Wgpu, &frame, &serde_json::json!({}));
    // Fixed-point sums do not depend on which edges ran, only on what they contributed; the
    // culled ones contributed nothing, so the images are identical.
    assert_eq!(off.visibility, on.visibility);
    let c = |o: &FrameOutput, k: &str| o.counters.get(k).unwrap();
    assert!(c(&on, "fill") > 0.0 && c(&on, "fill") < c(&off, "fill"));
    assert!(c(&on, "overdraw") < c(&off, "overdraw"));
}

#[test]
fn wgpu_handles_degenerate_scenes_as_the_cpu_model_does() {
    if !have_gpu() {
        return;
    }
    for (name, frame) in common::degenerate_scenes() {
        let o = serde_json::json!({});
        let gpu = run_with(Backend::Wgpu, &frame, &o);
        let model = run_with(Backend::CpuModel, &frame, &o);
        gpu.visibility
            .check_range()
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let e = shadowbench::metrics::compare(
            &gpu.visibility,
            &model.visibility,
            &frame.gbuffer.mask(),
        );
        // Over no surface pixel there is no metric (absent, not 0).
        assert!(
            e.pixels == 0 || (e.mae.unwrap() < 1e-3 && e.frac_over_0_1.unwrap() == 0.0),
            "{name}: {e:?}"
        );
        assert_eq!(
            gpu.counters.get("samples"),
            model.counters.get("samples"),
            "{name}"
        );
    }
}
