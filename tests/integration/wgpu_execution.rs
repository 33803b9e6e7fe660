//! The wgpu execution against independent results: the cpu-model execution of the same
//! algorithm, the ray-cast reference (a tiny light makes it a hard shadow), closed-form tap
//! counts, and the behaviour without any adapter.
//!
//! Without an adapter these tests print why and pass, unless `SHADOWBENCH_REQUIRE_GPU=1` (as
//! in CI), which makes a missing adapter a failure.

use std::process::Command;

use shadowbench::algorithms::{self, Backend, ExecContext, FrameOutput};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::light_as;
use shadowbench::metrics;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::{Light, LightKind};

use super::gpu_check;
use gpu_check::have_gpu;

/// A 64×48 frame of generated scene `name`, its light changed by `light` and made a disc
/// facing the scene (a light both algorithms take).
fn frame(name: &str, light: impl Fn(Light) -> Light, map_resolution: u32) -> Frame {
    frame_sized(name, light, map_resolution, [64, 48])
}

/// [`frame`] at `image` pixels.
fn frame_sized(
    name: &str,
    light: impl Fn(Light) -> Light,
    map_resolution: u32,
    image: [u32; 2],
) -> Frame {
    let mut scene = generators::find(name)
        .unwrap()
        .build(&GeneratorParams::default());
    scene.light = light_as(light(scene.light), LightKind::Disc, scene.bounds().center());
    let params = RunParams::of_scene(&scene, image, map_resolution, 32);
    Frame::new(scene, params)
}

fn run(id: &str, frame: &Frame) -> FrameOutput {
    run_on(id, Backend::Wgpu, frame)
}

fn run_on(id: &str, backend: Backend, frame: &Frame) -> FrameOutput {
    algorithms::run(id, backend, frame, &ExecContext::default()).unwrap()
}

#[test]
fn hard_shadow_map_matches_the_reference_of_a_tiny_light() {
    if !have_gpu() {
        return;
    }
    for name in ["sphere-on-plane", "box-on-plane", "torus-on-plane"] {
        let f = frame(name, |l| l.with_size(1e-3), 512);
        let out = run("hard_shadow_map", &f);
        let reference = algorithms::reference::render(&f, 4, 1).visibility;
        let e = metrics::compare(&out.visibility, &reference, &f.gbuffer.mask());
        // A point-like light makes the reference a hard shadow too; they can differ only where
        // a shadow edge crosses a map texel, a thin band of pixels.
        assert!(e.mae.unwrap() < 0.01, "{name}: {e:?}");
        assert!(e.frac_over_0_1.unwrap() < 0.02, "{name}: {e:?}");
        assert!(
            e.shadow_pixels > 50,
            "{name}: the scene must show a shadow: {e:?}"
        );
    }
}

#[test]
fn pcss_approaches_the_reference_of_a_small_light() {
    if !have_gpu() {
        return;
    }
    let f = frame("sphere-on-plane", |l| l.with_size(0.05), 512);
    let out = run("pcss", &f);
    let reference = algorithms::reference::render(&f, 64, 1).visibility;
    let e = metrics::compare(&out.visibility, &reference, &f.gbuffer.mask());
    assert!(e.mae.unwrap() < 0.01, "{e:?}");
    assert!(e.mae_shadow.unwrap() < 0.1, "{e:?}");
}

#[test]
fn eye_lookup_taps_follow_from_the_sample_counts() {
    if !have_gpu() {
        return;
    }
    let f = frame("sphere-on-plane", |l| l.with_size(0.5), 256);
    // Pixels that see a surface facing the light centre; averted ones are in shadow without
    // reading the map.
    let g = &f.gbuffer;
    let c = f.scene.light.center();
    let hits = (0..g.len())
        .filter(|&i| g.is_hit(i) && g.normal[i].dot((c - g.position[i]).normalize()) > 0.0)
        .count() as f64;
    let taps = |out: &FrameOutput| out.phases[1].counters.get("shadow_map.taps").unwrap();

    // The hard test reads one texel per pixel facing the light.
    assert_eq!(taps(&run("hard_shadow_map", &f)), hits);

    // PCSS: every hit pixel searches for blockers; those that find one filter as well, so the
    // taps beyond the search are a whole number of filters, and penumbra pixels exist.
    let out = run("pcss", &f);
    let o = shadowbench::algorithms::pcss::PcssOptions::default();
    let extra = taps(&out) - hits * f64::from(o.blocker_samples);
    let filters = extra / f64::from(o.pcf_samples);
    assert!(
        filters.fract() == 0.0 && filters > 0.0 && filters <= hits,
        "{filters}"
    );
    let penumbra = out
        .visibility
        .data
        .iter()
        .filter(|&&v| v > 0.0 && v < 1.0)
        .count() as f64;
    // Filters of pixels that end up strictly between 0 and 1 are not wasted.
    let wasted = out.phases[1]
        .counters
        .get("shadow_map.taps_wasted")
        .unwrap();
    assert_eq!(
        wasted,
        (filters - penumbra) * f64::from(o.pcf_samples),
        "wasted filter taps are those of pixels left at 0 or 1"
    );
}

#[test]
fn records_carry_gpu_times_statistics_and_the_adapter() {
    if !have_gpu() {
        return;
    }
    let gpu = shadowbench::gpu::gpu().unwrap();
    let f = frame("box-on-plane", |l| l, 256);
    let out = run("pcss", &f);
    assert_eq!(
        out.execution["adapter"],
        serde_json::json!(gpu.info.name),
        "{:?}",
        out.execution
    );
    let names: Vec<&str> = out.phases.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["light_raster", "eye_lookup"]);
    if gpu.queries.timestamp {
        let total: f64 = out.phases.iter().map(|p| p.gpu_ms.unwrap()).sum();
        assert!(total > 0.0);
        assert!((out.gpu_ms.unwrap() - total).abs() < 1e-9);
    }
    let raster = &out.phases[0].counters;
    let fill = raster.get("fill").unwrap();
    let covered = raster.get("shadow_map.covered_texels").unwrap();
    assert!(covered > 0.0 && fill >= covered, "{raster:?}");
    if gpu.queries.pipeline_statistics {
        // The occluders are drawn once (the receiver-only ground casts nothing): one clipper
        // invocation per triangle.
        let occluders = f.scene.occluders();
        let occluder_triangles = occluders.triangles.len() as f64;
        assert_eq!(
            raster.get("pipeline.clipper_invocations"),
            Some(occluder_triangles)
        );
        // The light pass's fragment stage is empty: lavapipe counts its invocations, NVIDIA's
        // driver skips it and reports 0 (Vulkan leaves this to the implementation), so only
        // the vertex stage is checked: every vertex the triangles use is shaded at least once.
        let used: std::collections::HashSet<u32> =
            occluders.triangles.iter().flatten().copied().collect();
        let vertices = raster.get("pipeline.vertex_shader_invocations").unwrap();
        assert!(
            vertices >= used.len() as f64,
            "{vertices} of {}",
            used.len()
        );
    }
}

/// The process-level behaviour with no adapter: simulated by pointing the Vulkan loader at no
/// driver and allowing only the Vulkan backend.
fn without_adapter(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(args)
        .env("VK_ICD_FILENAMES", "/nonexistent")
        .env("VK_DRIVER_FILES", "/nonexistent")
        .env("WGPU_BACKEND", "vulkan")
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap()
}

#[test]
fn without_an_adapter_run_skips_wgpu_and_render_fails_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    std::fs::write(
        &scenario,
        r#"{
  "scene": { "generator": "box-on-plane" },
  "algorithms": ["reference", "pcss"],
  "backends": ["cpu-native", "wgpu"],
  "params": { "image": [32, 24], "map_resolution": 64 },
  "reference": { "samples": 4 }
}"#,
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = without_adapter(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let skips: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("skipping the wgpu execution"))
        .collect();
    assert_eq!(skips.len(), 1, "{stderr}");
    assert!(skips[0].contains("no GPU adapter found"), "{stderr}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("results.json")).unwrap())
            .unwrap();
    let runs = json["runs"].as_array().unwrap();
    assert!(!runs.is_empty());
    assert!(runs
        .iter()
        .all(|r| r["backend"] == "cpu-native" && r["failure"].is_null()));

    let out = without_adapter(&[
        "render",
        "--algorithm",
        "pcss",
        "--backend",
        "wgpu",
        "--image",
        "32x24",
        "--out",
        dir.path().join("render").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("error: wgpu: no GPU adapter found"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");

    let out = without_adapter(&["list"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(stdout.contains("none: no GPU adapter found"), "{stdout}");
}

/// Runs a sweep of light sizes (the base case and 3 more) × hard_shadow_map, pcss on cpu-native
/// and wgpu (8 wgpu runs) with `SHADOWBENCH_INJECT_FAULT=fault`, and returns the records and stderr.
fn sweep_with_fault(fault: &str) -> (Vec<serde_json::Value>, String) {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    std::fs::write(
        &scenario,
        r#"{
  "scene": { "generator": "sphere-on-plane" },
  "algorithms": ["hard_shadow_map", "pcss"],
  "backends": ["cpu-native", "wgpu"],
  "params": { "image": [32, 24], "map_resolution": 64, "triangles": 300 },
  "sweep": { "light_size": [0.2, 0.5, 1.0] },
  "reference": { "samples": 4 }
}"#,
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", scenario.to_str().unwrap(), "--out"])
        .arg(&out_dir)
        // One iteration per run, so the fault's count is the run's.
        .args(["--warmup", "0", "--repeats", "1"])
        .env("SHADOWBENCH_INJECT_FAULT", fault)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("results.json")).unwrap())
            .unwrap();
    (json["runs"].as_array().unwrap().clone(), stderr)
}

#[test]
fn a_gpu_fault_fails_only_its_own_run_and_the_sweep_goes_on() {
    if !have_gpu() {
        return;
    }
    for (fault, says) in [
        ("device-lost@2", "device lost during the run"),
        ("shader-error@2", "injected fault"),
        ("buffer-limit@2", "injected fault"),
    ] {
        let (runs, stderr) = sweep_with_fault(fault);
        let wgpu: Vec<&serde_json::Value> =
            runs.iter().filter(|r| r["backend"] == "wgpu").collect();
        let failed: Vec<&serde_json::Value> =
            runs.iter().filter(|r| !r["failure"].is_null()).collect();
        // The second wgpu run (and only it) failed, naming the fault; the runs after it (on a
        // new device after a loss) and every CPU run have images and quality.
        assert_eq!(wgpu.len(), 8, "{fault}: {stderr}");
        assert_eq!(failed.len(), 1, "{fault}: {failed:?}");
        assert!(std::ptr::eq(failed[0], wgpu[1]), "{fault}: {failed:?}");
        let why = failed[0]["failure"].as_str().unwrap();
        assert!(why.contains(says), "{fault}: {why}");
        for r in runs.iter().filter(|r| r["failure"].is_null()) {
            assert!(r["error"]["mae"].is_number(), "{fault}: {r}");
        }
    }
}

#[test]
fn soft_shadow_map_on_wgpu_agrees_with_the_cpu_model() {
    if !have_gpu() {
        return;
    }
    for name in ["plate-on-plane", "torus-on-plane"] {
        let mut scene = generators::find(name)
            .unwrap()
            .build(&GeneratorParams::default());
        scene.light = light_as(scene.light, LightKind::Rect, scene.bounds().center());
        let params = RunParams::of_scene(&scene, [64, 48], 96, 32);
        let f = Frame::new(scene, params);
        for options in [
            serde_json::json!({}),
            serde_json::json!({"passes": 2, "occluder_map_transfer": false}),
            serde_json::json!({"precision": "fp16"}),
            serde_json::json!({"precision": "fp16", "passes": 2, "occluder_map_transfer": false}),
        ] {
            let mut ctx = ExecContext::default();
            ctx.options
                .insert("soft_shadow_map".into(), options.clone());
            let gpu = algorithms::run("soft_shadow_map", Backend::Wgpu, &f, &ctx).unwrap();
            let ctx = super::registry::rounding_as_adapter("soft_shadow_map", &ctx, &gpu);
            let model = algorithms::run("soft_shadow_map", Backend::CpuModel, &f, &ctx).unwrap();
            let e = metrics::compare(&gpu.visibility, &model.visibility, &f.gbuffer.mask());
            let fill = |o: &FrameOutput| o.counters.get("fill").unwrap_or(0.0);
            let splat_fill = |o: &FrameOutput| {
                o.phases
                    .iter()
                    .find(|p| p.name == "splat")
                    .unwrap()
                    .counters
                    .get("fill")
                    .unwrap()
            };
            eprintln!(
                "{name} {options}: mae {:.2e} max {:.2e}; splat fill wgpu {} model {}; total {}",
                e.mae.unwrap(),
                e.max.unwrap(),
                splat_fill(&gpu),
                splat_fill(&model),
                fill(&model)
            );
            assert!(
                e.mae.unwrap() < 1e-3 && e.max.unwrap() < 0.05,
                "{name} {options}: {e:?}"
            );
            // The same extents cover the same texels: fill agrees up to edge-rule ties.
            let (a, b) = (splat_fill(&gpu), splat_fill(&model));
            assert!(
                (a - b).abs() <= 0.01 * b,
                "{name} {options}: fill {a} vs {b}"
            );
        }
    }
}

#[test]
fn dbuffer_on_wgpu_agrees_with_the_cpu_model() {
    if !have_gpu() {
        return;
    }
    for name in ["sphere-on-plane", "box-on-plane", "torus-on-plane"] {
        let f = frame(name, |l| l.with_size(0.5), 256);
        let gpu = run_on("dbuffer", Backend::Wgpu, &f);
        let model = run_on("dbuffer", Backend::CpuModel, &f);
        let e = metrics::compare(&gpu.visibility, &model.visibility, &f.gbuffer.mask());
        let (fg, fm) = (
            gpu.counters.get("fill").unwrap(),
            model.counters.get("fill").unwrap(),
        );
        let (og, om) = (
            gpu.counters.get("overdraw").unwrap(),
            model.counters.get("overdraw").unwrap(),
        );
        eprintln!("{name}: {e:?} fill {fg} vs {fm}, overdraw {og} vs {om}");
        // The same f32 formulas on both, the same volumes (built on the host for both), and
        // the volumes ending inside the far plane so both rasterizers cover the same texels;
        // only depths rounded differently by the two rasterizers can move a texel's nearest
        // volume surface. Measured: mae ≈ 1.5e-5, max ≈ 0.004, fill and overdraw equal.
        assert!(
            e.mae.unwrap() < 1e-3 && e.max.unwrap() < 0.05,
            "{name}: {e:?}"
        );
        assert!(fm > 0.0, "{name}: the model rasterized no volume");
        assert!(
            (fg - fm).abs() <= 0.01 * fm,
            "{name}: fill {fg} on wgpu, {fm} on cpu-model"
        );
        assert!(
            (og - om).abs() <= 0.01 * fm,
            "{name}: overdraw {og} vs {om}"
        );
        let names: Vec<&str> = gpu.phases.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["silhouettes", "volumes", "dbuffer", "eye_lookup"]);
        if gpu.gpu_ms.is_some() {
            assert!(gpu.phases[2].gpu_ms.is_some() && gpu.phases[3].gpu_ms.is_some());
        }
        // The volumes built on one host thread (the paper's one CPU) are the same volumes:
        // the same image and counts, the host phases timed on that thread.
        let ctx = ExecContext {
            options: [(
                "dbuffer".to_string(),
                serde_json::json!({"volume_build": "single_core"}),
            )]
            .into(),
            ..ExecContext::default()
        };
        let one = algorithms::run("dbuffer", Backend::Wgpu, &f, &ctx).unwrap();
        assert_eq!(one.visibility.data, gpu.visibility.data, "{name}");
        for c in [
            "fill",
            "overdraw",
            "silhouette.umbra_edges",
            "volumes.umbra_triangles",
        ] {
            assert_eq!(one.counters.get(c), gpu.counters.get(c), "{name}: {c}");
        }
        let build = one.execution["volume_build"].as_str().unwrap();
        assert!(build.contains("one host thread"), "{build}");
        assert!(one.phases[..2].iter().all(|p| p.wall_ms > 0.0));
    }
}

/// `accum_hard` on wgpu against the cpu-model with N = 16, z-pass and z-fail, in both GPU
/// pipelines.
///
/// - `"gather"` (the hard pass of soft_shadow_volume once per light sample, accumulated per
///   pixel on the GPU): the same host geometry and the same integer counts, so the images
///   differ only where a GPU rounding flips a ray–quad test for a grazing pixel (1/16 per
///   flip); the fragment counts and the memory traffic in the cpu-model's terms agree within
///   as many flips (0.2%), silhouette sizes exactly.
/// - `"raster"` (the quads rasterized into a count target, accumulated by blending): the
///   rasterizer samples pixel centres with its own edge rule and tests interpolated depth
///   against the depth buffer (`shadow_volume::raster`), so the fragments on the quads' edges
///   and those grazing the occluder's own surface at its silhouette (the terminator, where a
///   quad meets the surface it starts on) change hands, several samples at once on the same
///   pixel. Measured on lavapipe, these scenes: MAE ≤ 1.05e-3, ≤ 0.29% of the pixels over
///   0.1, largest difference 0.25 (4 of 16 samples), fill within 0.07%, overdraw within 1.2%,
///   memory traffic within 0.1%; bounds: MAE 2.5e-3, 1% over 0.1, largest difference 0.5,
///   counters within 3%.
#[test]
fn accum_hard_on_wgpu_agrees_with_the_cpu_model() {
    if !have_gpu() {
        return;
    }
    for (name, counting, pipeline) in [
        ("sphere-on-plane", "z_pass", "gather"),
        ("cylinder-on-plane", "z_pass", "gather"),
        ("box-on-plane", "z_fail", "gather"),
        ("sphere-on-plane", "z_pass", "raster"),
        ("cylinder-on-plane", "z_pass", "raster"),
        ("box-on-plane", "z_fail", "raster"),
    ] {
        let raster = pipeline == "raster";
        let (mae, over, max, counters) = if raster {
            (2.5e-3, 0.01, 0.5, 0.03)
        } else {
            (1e-3, 1.0, 0.0625 + 1e-6, 0.002)
        };
        let f = frame(name, |l| l.with_size(0.8), 256);
        let mut ctx = ExecContext::default();
        ctx.options.insert(
            "accum_hard".into(),
            serde_json::json!({ "samples": 16, "counting": counting, "gpu_pipeline": pipeline }),
        );
        let gpu = algorithms::run("accum_hard", Backend::Wgpu, &f, &ctx).unwrap();
        let model = algorithms::run("accum_hard", Backend::CpuModel, &f, &ctx).unwrap();
        assert_eq!(gpu.execution["gpu_pipeline"], pipeline);
        gpu.visibility.check_range().unwrap();
        let e = metrics::compare(&gpu.visibility, &model.visibility, &f.gbuffer.mask());
        eprintln!("{name} {counting} {pipeline}: {e:?}");
        assert!(e.shadow_pixels > 50, "{name}: no shadow on screen");
        assert!(e.mae.unwrap() <= mae, "{name} {counting} {pipeline}: {e:?}");
        assert!(
            e.frac_over_0_1.unwrap() <= over,
            "{name} {counting} {pipeline}: {e:?}"
        );
        assert!(e.max.unwrap() <= max, "{name} {counting} {pipeline}: {e:?}");
        let c = |o: &FrameOutput, k: &str| o.counters.get(k).unwrap_or(0.0);
        assert_eq!(c(&gpu, "silhouette_edges"), c(&model, "silhouette_edges"));
        assert_eq!(c(&gpu, "volume_caps"), c(&model, "volume_caps"));
        for k in [
            "fill",
            "overdraw",
            "mem.read_bytes",
            "mem.write_bytes",
            "mem.depth.read_bytes",
            "mem.stencil.read_bytes",
            "mem.stencil.write_bytes",
            "mem.accumulation.read_bytes",
            "mem.accumulation.write_bytes",
        ] {
            // The wgpu estimate (mem_est.*) against the cpu-model's modelled traffic
            // (mem_model.*) of the same stencil and accumulation buffers.
            let (g, m) = match k.strip_prefix("mem.") {
                Some(k) => (
                    c(&gpu, &format!("mem_est.{k}")),
                    c(&model, &format!("mem_model.{k}")),
                ),
                None => (c(&gpu, k), c(&model, k)),
            };
            eprintln!("  {k}: wgpu {g}, cpu-model {m} ({:.4})", (g - m) / m);
            assert!(m > 0.0, "{name}: {k}");
            assert!(
                (g - m).abs() <= counters * m,
                "{name} {counting} {pipeline}: {k} {g} on wgpu, {m} on cpu-model"
            );
        }
        let phases: Vec<&str> = gpu.phases.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(phases, ["hard", "accumulate"]);
    }
}

/// The issue's sweep in small: once a render pass has run in the process (`hard_shadow_map`'s
/// light raster), the same compute passes of `soft_shadow_volume` timed three times read the
/// same GPU time, of the order of the host's time for them, never a hundredth of it.
#[test]
fn a_pass_timed_three_times_in_one_process_reads_its_own_time_each_time() {
    if !have_gpu() {
        return;
    }
    let gpu = shadowbench::gpu::gpu().unwrap();
    if !gpu.queries.timestamp {
        return;
    }
    // The issue's frame: the quick scenario's sphere at light size 0.3, 160×120.
    let mut scene = generators::find("sphere-on-plane")
        .unwrap()
        .build(&GeneratorParams::default());
    scene.light = scene.light.with_size(0.3);
    let params = RunParams::of_scene(&scene, [160, 120], 256, 32);
    let f = Frame::new(scene, params);
    // A first run compiles the shaders (llvmpipe compiles at first dispatch): it is not the
    // reading under test. Then a render pass binds a framebuffer, which is what made later
    // compute-pass timestamps read ~0 ms.
    run("soft_shadow_volume", &f);
    run("hard_shadow_map", &f);
    let runs: Vec<FrameOutput> = (0..3).map(|_| run("soft_shadow_volume", &f)).collect();
    // Per run: the soft phase's GPU time and the host time of its submission (the phase's wall
    // time: encode, submit, wait).
    let soft: Vec<(f64, f64)> = runs
        .iter()
        .map(|o| {
            assert!(
                !o.execution.contains_key("gpu_ms_invalid"),
                "{:?} {:?}",
                o.execution,
                o.warnings
            );
            let p = o.phases.iter().find(|p| p.name == "soft").unwrap();
            let g = p.gpu_ms.expect("a valid GPU time");
            assert!(
                g <= p.wall_ms * 1.02 + 0.5,
                "gpu {g} ms > host {} ms",
                p.wall_ms
            );
            (g, p.wall_ms)
        })
        .collect();
    if gpu.info.device_type == wgpu::DeviceType::Cpu {
        // On a CPU adapter the pass is most of its submission, in every run alike: the share
        // of runs 2 and 3 within 2× of run 1's (shares, not times, so that a loaded machine
        // slowing one run as a whole does not count). The fault read a share of ~0.0005.
        let share: Vec<f64> = soft.iter().map(|(g, h)| g / h).collect();
        for s in &share {
            assert!(*s >= 0.25, "GPU/host shares {share:?} of {soft:?}");
            assert!(
                *s <= 2.0 * share[0] && *s >= share[0] / 2.0,
                "GPU/host shares {share:?}"
            );
        }
    }
    let how = runs[0].execution["gpu_time"].as_str().unwrap();
    if gpu.queries.timestamp_inside_passes {
        assert!(how.starts_with("timestamps inside passes"), "{how}");
    } else {
        assert!(how.starts_with("timestamps around passes"), "{how}");
    }
}

/// The cause on Mesa's lavapipe, and the guard: after a render pass, timestamps written around
/// a long compute pass read a tiny fraction of it (llvmpipe queues them to its next flush); the
/// guard records that reading as invalid. Timestamps written inside the pass, each flushed by
/// a second write, read the pass's time. On any adapter, a reading the guard lets through is
/// within the submission's host time.
#[test]
fn timestamps_around_a_compute_pass_after_a_render_pass_are_caught_on_lavapipe() {
    use shadowbench::gpu::timing::{self, PassTimer, Placement};
    if !have_gpu() {
        return;
    }
    shadowbench::gpu::guarded_run(Default::default(), |gpu| {
        if !gpu.queries.timestamp_inside_passes {
            return Ok(());
        }
        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("busy"),
                source: wgpu::ShaderSource::Wgsl(BUSY_WGSL.into()),
            });
        let pipeline = gpu
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("busy"),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
        let out = gpu.storage_buffer("busy out", 4 * 64 * 256, wgpu::BufferUsages::empty());
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: out.as_entire_binding(),
            }],
        });
        // A render pass binds a framebuffer, as hard_shadow_map's light raster does.
        let depth = gpu.map_texture(
            "depth",
            64,
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::empty(),
        );
        let view = depth.create_view(&Default::default());
        gpu.submit(|e| {
            timing::render_pass(
                e,
                wgpu::RenderPassDescriptor {
                    label: Some("clear"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                },
                None,
            );
        })?;
        let lavapipe = gpu.info.driver == "llvmpipe";
        for placement in [Placement::AroundPasses, Placement::InsidePasses] {
            for _ in 0..3 {
                let timer = PassTimer::with_placement(gpu, 1, placement);
                timer.in_submission(0..1, gpu.next_submission());
                let host_ms = gpu.submit(|e| {
                    {
                        let mut pass = timing::compute_pass(e, "busy", Some((&timer, 0)));
                        pass.set_pipeline(&pipeline);
                        pass.set_bind_group(0, &group, &[]);
                        pass.dispatch_workgroups(256, 1, 1);
                    }
                    timer.resolve(e);
                })?;
                let t = timer.read(gpu)?;
                let raw = timer.raw_ms(gpu)?[0];
                eprintln!("{placement:?}: raw {raw:.3} ms, host {host_ms:.3} ms, {t:?}");
                if let Some(ms) = &t.ms {
                    assert!(ms[0] <= host_ms * 1.02 + 0.5);
                }
                if lavapipe && host_ms > 50.0 {
                    match placement {
                        Placement::AroundPasses => {
                            assert!(raw < host_ms / 10.0, "raw {raw}, host {host_ms}");
                            // The guard is loose on purpose (a loaded machine's slow handover
                            // is not flagged): it must flag the reading once the host waited
                            // past both of its bounds.
                            let flagged =
                                (raw + timing::BELOW_MIN_GAP_MS).max(raw / timing::BELOW_FRACTION);
                            if host_ms > flagged {
                                assert!(t.ms.is_none() && t.invalid.is_some(), "{t:?}");
                            }
                        }
                        Placement::InsidePasses => {
                            let ms = t.ms.expect("a valid reading")[0];
                            assert!(ms >= 0.5 * host_ms, "{ms} ms of {host_ms} ms");
                        }
                    }
                }
            }
        }
        Ok(())
    })
    .unwrap();
}

/// A compute shader that keeps a CPU adapter busy for some tens of milliseconds.
const BUSY_WGSL: &str = "
@group(0) @binding(0) var<storage, read_write> out: array<u32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    var x = id.x;
    for (var i = 0u; i < 20000u; i++) {
        x = x * 1664525u + 1013904223u;
    }
    out[id.x] = x;
}
";

/// For every algorithm, the cpu-model and wgpu records carry the same counter names, except
/// those the glossary documents as recorded by one of them only; every wgpu counter is in the
/// glossary; `overdraw_ratio` is wherever fill and overdraw are.
#[test]
fn cpu_model_and_wgpu_records_carry_the_same_counters() {
    use shadowbench::counters::{find, Recorded};
    use std::collections::BTreeSet;
    if !have_gpu() {
        return;
    }
    let scene = generators::find("sphere-on-plane")
        .unwrap()
        .build(&GeneratorParams::default());
    let params = RunParams::of_scene(&scene, [32, 24], 64, 16);
    let base = Frame::new(scene, params);
    let ctx = ExecContext::default();
    for info in algorithms::ALGORITHMS
        .iter()
        .filter(|a| a.backends.contains(&Backend::Wgpu))
    {
        let mut scene = base.scene.clone();
        let kind = info.light_for(scene.light.kind());
        scene.light = light_as(scene.light, kind, scene.bounds().center());
        let f = Frame::new(scene, base.params.clone());
        let names = |backend: Backend| -> BTreeSet<String> {
            let (r, _) = super::common::run_one(&f, info.id, backend, &ctx, None);
            assert!(
                r.failure.is_none(),
                "{} {backend}: {:?}",
                info.id,
                r.failure
            );
            check_names(&r);
            r.counters
                .0
                .keys()
                .filter(|n| find(n).is_some_and(|c| c.recorded == Recorded::All))
                .cloned()
                .collect()
        };
        let (model, wgpu) = (names(Backend::CpuModel), names(Backend::Wgpu));
        assert_eq!(
            model.symmetric_difference(&wgpu).collect::<Vec<_>>(),
            Vec::<&String>::new(),
            "{}: cpu-model and wgpu counters differ",
            info.id
        );
    }
}

/// Every counter of `record` is in the glossary and recorded by its execution; `overdraw_ratio`
/// is overdraw / fill wherever both are counted.
fn check_names(record: &shadowbench::record::RunRecord) {
    let all = std::iter::once(&record.counters).chain(record.phases.iter().map(|p| &p.counters));
    for c in all {
        for name in c.0.keys() {
            let entry = shadowbench::counters::find(name)
                .unwrap_or_else(|| panic!("{}: '{name}' not in the glossary", record.algorithm));
            assert!(
                entry.recorded.backends().contains(&record.backend),
                "{} {}: '{name}' documented for {:?}",
                record.algorithm,
                record.backend,
                entry.recorded
            );
        }
        if let (Some(fill), Some(overdraw)) = (c.get("fill"), c.get("overdraw")) {
            if fill > 0.0 {
                assert_eq!(c.get("overdraw_ratio"), Some(overdraw / fill));
            }
        }
    }
}

#[test]
fn rt_denoised_on_wgpu_traces_a_frame_in_chunks_as_the_cpu_model_does() {
    if !have_gpu() {
        return;
    }
    // Frames over one submission's 2^20 rays, traced in chunks with the deadline checked
    // between them: 48×352 at 64 rays a pixel in two bands of whole workgroup rows (42 and 2),
    // and 1040×24 at 128 in two chunks on each of three workgroup rows (128 and 2 workgroups).
    // Every pixel's samples come from its own coordinates in whichever chunk traces it.
    for (image, spp) in [([48, 352], 64), ([1040, 24], 128)] {
        let f = frame_sized("sphere-on-plane", |l| l, 128, image);
        let mut ctx = ExecContext::default();
        ctx.options.insert(
            "rt_denoised".into(),
            serde_json::json!({ "spp": spp, "denoise": false }),
        );
        let run = |backend| algorithms::run("rt_denoised", backend, &f, &ctx).unwrap();
        let (gpu, model) = (run(Backend::Wgpu), run(Backend::CpuModel));
        let mask = f.gbuffer.mask();
        let e = metrics::compare(&gpu.visibility, &model.visibility, &mask);
        assert!(
            e.shadow_pixels > 20,
            "{image:?}: no shadow on screen: {e:?}"
        );
        // The same rays and traversal on both: the same answers, the same counts.
        assert_eq!(e.max, Some(0.0), "{image:?}: {e:?}");
        for k in [
            "rt.rays",
            "rt.node_visits",
            "rt.triangle_tests",
            "rt.occluded_rays",
        ] {
            assert_eq!(gpu.counters.get(k), model.counters.get(k), "{image:?}: {k}");
        }
    }
}

/// The phases of the runs the tests below build by hand.
#[derive(Clone, Copy, Debug, PartialEq)]
enum TestPhase {
    A,
    B,
}

impl shadowbench::record::PhaseId for TestPhase {
    fn name(self) -> &'static str {
        match self {
            TestPhase::A => "a",
            TestPhase::B => "b",
        }
    }
}

/// A run whose readback no pass can have written (nothing was submitted) is an error naming its
/// phases, not a zero image; with one pass submitted, the same run reads back what it wrote.
#[test]
fn a_run_without_a_pass_cannot_reach_its_readback() {
    use shadowbench::gpu::pass::{Instrumented, Pass, Statistics, Timed};
    if !have_gpu() {
        return;
    }
    shadowbench::gpu::guarded_run(Default::default(), |gpu| {
        let out = gpu.storage_buffer("out", 4 * 64, wgpu::BufferUsages::COPY_SRC);
        let empty = Timed::new(gpu, &[TestPhase::A], Statistics::Off, &[&out]);
        let err = empty.finish().err().expect("a run without a pass is an error");
        assert!(err.to_string().contains("submitted no GPU pass"), "{err}");
        assert!(err.to_string().contains("[\"a\"]"), "{err}");

        let module = gpu
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("fill"),
                source: wgpu::ShaderSource::Wgsl(
                    "@group(0) @binding(0) var<storage, read_write> out: array<u32>;
                     @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) i: vec3<u32>) {
                         out[i.x] = i.x + 7u;
                     }"
                    .into(),
                ),
            });
        let pipeline = gpu
            .device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("fill"),
                layout: None,
                module: &module,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                cache: None,
            });
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: out.as_entire_binding(),
            }],
        });
        let mut run = Timed::new(gpu, &[TestPhase::A], Statistics::Compute, &[&out]);
        let pipeline = Instrumented::timed(pipeline);
        run.submit(TestPhase::A, &[Pass::compute("fill", &[Some(&group)], &pipeline, (1, 1))])?;
        let timing = run.finish()?;
        let words: Vec<u32> = bytemuck::pod_collect_to_vec(&timing.readback[0]);
        assert_eq!(words, (7..71).collect::<Vec<u32>>());
        Ok(())
    })
    .unwrap();
}

/// The replay derived from a run ([`Timed::counting_into`]) records each pass with its
/// pipelines' counting variants, leaves out the timed-only passes, runs the replay-only ones,
/// clears the counts first (a timed pass spoiled them) and reads them once or per phase; the
/// timed run runs the timed variants only. Each count is 64 invocations of one workgroup.
#[test]
fn a_derived_replay_runs_each_pass_as_its_pipelines_state() {
    use shadowbench::gpu::pass::{Bind, Instrumented, Layout, Pass, Program, Readout};
    use shadowbench::gpu::pass::{Statistics, Timed};
    if !have_gpu() {
        return;
    }
    const WGSL: &str = "
        @group(0) @binding(0) var<storage, read_write> out: array<u32>;
        @group(0) @binding(1) var<storage, read_write> counts: array<atomic<u32>, 2>;
        @compute @workgroup_size(64) fn fill(@builtin(global_invocation_id) i: vec3<u32>) {
            out[i.x] = i.x + 7u;
        }
        @compute @workgroup_size(64) fn count() { atomicAdd(&counts[0], 1u); }
        @compute @workgroup_size(64) fn extra() { atomicAdd(&counts[1], 1u); }
        @compute @workgroup_size(64) fn spoil() { atomicAdd(&counts[0], 1000u); }";
    for (readout, want) in [
        (Readout::End, vec![vec![64, 64]]),
        (Readout::EachPhase, vec![vec![64, 0], vec![0, 64]]),
    ] {
        shadowbench::gpu::guarded_run(Default::default(), |gpu| {
            let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
            let out = gpu.storage_buffer("out", 4 * 64, copy);
            let counts = gpu.storage_buffer("counts", 8, copy);
            let binds = [
                (Bind::ReadWrite, out.as_entire_binding()),
                (Bind::ReadWrite, counts.as_entire_binding()),
            ];
            let (layout, group) = Layout::bound(gpu, "test", wgpu::ShaderStages::COMPUTE, &binds);
            let program = Program::new(gpu, "test", &[WGSL], &[Some(&layout)]);
            let entry = |e| program.compute(gpu, e, None);
            let fill = Instrumented {
                timed: Some(entry("fill")),
                counting: Some(entry("count")),
            };
            let extra = Instrumented::counting(entry("extra"));
            let spoil = Instrumented::timed(entry("spoil"));
            let pass = |label, p| Pass::compute(label, &[Some(&group)], p, (1, 1));
            let mut run = Timed::new(
                gpu,
                &[TestPhase::A, TestPhase::B],
                Statistics::Off,
                &[&out, &counts],
            )
            .counting_into(&counts, readout);
            run.submit(TestPhase::A, &[pass("fill", &fill), pass("spoil", &spoil)])?;
            run.submit(TestPhase::B, &[pass("extra", &extra)])?;
            let timing = run.finish()?;
            let words: Vec<u32> = bytemuck::pod_collect_to_vec(&timing.readback[0]);
            assert_eq!(words, (7..71).collect::<Vec<u32>>());
            // The timed run: `spoil` only (no `count`, no `extra`).
            let timed: Vec<u32> = bytemuck::pod_collect_to_vec(&timing.readback[1]);
            assert_eq!(timed, [64_000, 0]);
            let read: Vec<Vec<u32>> = (timing.counts.iter())
                .map(|b| bytemuck::pod_collect_to_vec(b))
                .collect();
            assert_eq!(read, want, "{readout:?}");
            let none: Vec<(TestPhase, _)> = vec![];
            let out = timing.output((8, 8), none, "test");
            let plan = &out.execution["passes"];
            let plan: Vec<&str> = plan
                .as_array()
                .unwrap()
                .iter()
                .flat_map(|p| p.as_str())
                .collect();
            assert_eq!(
                plan,
                [
                    "a: fill (timed, replayed)",
                    "a: spoil (timed)",
                    "b: extra (replayed)"
                ]
            );
            Ok(())
        })
        .unwrap();
    }
}
