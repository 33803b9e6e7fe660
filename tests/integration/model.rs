//! The cpu-model execution and the shadow-map family on it, checked against the ray-traced
//! reference, against each other, against the native execution, and for determinism.

use std::collections::BTreeMap;

use super::common::run_one;
use glam::Vec3;
use shadowbench::algorithms::{self, Backend, ExecContext, FrameOutput};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::ReferenceCache;
use shadowbench::metrics;
use shadowbench::model::raster::{self, Coverage, DepthOnly, Geometry, Pipeline, Target};
use shadowbench::model::{Machine, MachineConfig};
use shadowbench::scenario::Loaded;
use shadowbench::scene::generators::{self, GeneratorParams};

fn frame(light_size: f32, tile: u32) -> Frame {
    let mut scene = generators::find("sphere-on-plane")
        .unwrap()
        .build(&GeneratorParams {
            triangles: Some(600),
            seed: 1,
            occluder_height: None,
            occluder_offset: None,
        });
    scene.light = scene.light.with_size(light_size);
    let params = RunParams {
        triangles: scene.triangle_count() as u32,
        light_size,
        map_resolution: 512,
        tile_size: tile,
        image: [64, 48],
        occluder_height: None,
        occluder_offset: None,
        cores: None,
    };
    Frame::new(scene, params)
}

fn render(id: &str, backend: Backend, frame: &Frame) -> FrameOutput {
    algorithms::run(id, backend, frame, &ExecContext::default()).unwrap()
}

fn mae(a: &FrameOutput, b: &FrameOutput, frame: &Frame) -> f64 {
    metrics::compare(&a.visibility, &b.visibility, &frame.gbuffer.mask())
        .mae
        .unwrap()
}

#[test]
fn hard_shadow_map_matches_the_reference_at_a_small_light() {
    let f = frame(0.05, 32);
    let reference = ReferenceCache::new(None, 64, 1)
        .get_or_compute(&f)
        .unwrap()
        .0;
    let ctx = ExecContext::default();
    let (record, out) = run_one(
        &f,
        "hard_shadow_map",
        Backend::CpuModel,
        &ctx,
        Some(&reference),
    );
    let out = out.expect("the run succeeds");
    // Over every pixel that sees a surface, averted ones (facing away from the light) included.
    let e = record.error.expect("error against the reference");
    assert!(e.mae.unwrap() < 0.02, "mae {:?}", e.mae.unwrap());
    // The sphere casts a shadow at all: some receivers are dark in both images.
    let dark = out.visibility.data.iter().filter(|&&v| v == 0.0).count();
    assert!(dark > 20, "{dark} shadowed pixels");
    assert!(record.model_ms.unwrap() > 0.0);
    assert_eq!(record.execution["machine"], "larrabee-24");
    // Every fragment that failed the depth test is overdraw; the map keeps at most one per texel.
    let c = &record.counters;
    let (fill, overdraw) = (c.get("fill").unwrap(), c.get("overdraw").unwrap());
    assert!(overdraw >= c.get("depth_fail").unwrap() + c.get("fragments_rejected_early").unwrap());
    assert!(fill - overdraw <= 512.0 * 512.0 && fill - overdraw > 0.0);
    let phases: Vec<&str> = record.phases.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(phases, ["light_raster", "eye_lookup"]);
}

#[test]
fn pcss_is_closer_to_the_reference_than_the_hard_shadow_at_a_large_light() {
    let f = frame(0.8, 32);
    let reference = ReferenceCache::new(None, 64, 1)
        .get_or_compute(&f)
        .unwrap()
        .0;
    let ctx = ExecContext::default();
    let err = |id| {
        run_one(&f, id, Backend::CpuModel, &ctx, Some(&reference))
            .0
            .error
            .unwrap()
            .mae_shadow
            .unwrap()
    };
    let (pcss, hard) = (err("pcss"), err("hard_shadow_map"));
    assert!(pcss < hard, "pcss {pcss} vs hard {hard}");
}

#[test]
fn pcss_converges_to_the_hard_shadow_map_as_the_light_shrinks() {
    let diff = |size| {
        let f = frame(size, 32);
        mae(
            &render("pcss", Backend::CpuModel, &f),
            &render("hard_shadow_map", Backend::CpuModel, &f),
            &f,
        )
    };
    let (tiny, big) = (diff(1e-4), diff(0.8));
    assert!(tiny < 2e-3, "tiny light: {tiny}");
    assert!(
        big > 10.0 * tiny.max(1e-4),
        "big light: {big}, tiny: {tiny}"
    );
}

#[test]
fn native_and_model_executions_compute_the_same_image() {
    let f = frame(0.5, 16);
    for id in ["hard_shadow_map", "pcss"] {
        let (n, m) = (
            render(id, Backend::CpuNative, &f),
            render(id, Backend::CpuModel, &f),
        );
        assert_eq!(n.visibility, m.visibility, "{id}");
        assert_eq!(n.counters.get("fill"), m.counters.get("fill"), "{id}");
        assert!(n.model_ms.is_none() && m.model_ms.is_some());
    }
}

#[test]
fn counters_and_model_times_do_not_depend_on_host_threads() {
    let f = frame(0.5, 16);
    let in_pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render("pcss", Backend::CpuModel, &f))
    };
    let (a, b) = (in_pool(1), in_pool(2));
    assert_eq!(a.counters, b.counters);
    assert_eq!(a.model_ms, b.model_ms);
    let model = |o: &FrameOutput| {
        o.phases
            .iter()
            .map(|p| (p.name.clone(), p.model_ms, p.counters.clone()))
            .collect::<Vec<_>>()
    };
    assert_eq!(model(&a), model(&b));
    assert_eq!(a.visibility, b.visibility);
    assert!(a.counters.get("cache.l1_hits").unwrap() > 0.0);
}

/// A machine with a shared L3 (the host's kind): the cores' L2 traffic goes through it after
/// each step in a fixed order, so its counters and times too are the same for any host thread
/// count; its hits are L2 misses that did not go to DRAM.
#[test]
fn a_shared_l3_is_deterministic_and_serves_l2_misses() {
    let f = frame(0.5, 16);
    let mut machine = shadowbench::model::host::machine_from(
        std::path::Path::new("/nonexistent"),
        4,
        shadowbench::model::host::simd(),
        2.0,
    );
    machine.l2.size_bytes = 16 * 1024;
    machine.l3 = Some(shadowbench::model::config::CacheConfig {
        size_bytes: 4 << 20,
        ways: 16,
        latency_cycles: 30.0,
    });
    let ctx = ExecContext {
        machine,
        ..Default::default()
    };
    let in_pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| algorithms::run("pcss", Backend::CpuModel, &f, &ctx).unwrap())
    };
    let (a, b) = (in_pool(1), in_pool(3));
    assert_eq!(a.counters, b.counters);
    assert_eq!(a.model_ms, b.model_ms);
    let c = |k: &str| a.counters.get(k).unwrap_or(0.0);
    assert!(c("cache.l3_hits") > 0.0, "{:?}", a.counters);
    assert_eq!(
        c("cache.l3_hits") + c("cache.l3_misses"),
        c("cache.l2_misses")
    );
    // Every counter of a run on a machine with an L3 is in the glossary.
    for name in a.counters.0.keys() {
        assert!(shadowbench::counters::find(name).is_some(), "{name}");
    }
    // DRAM reads are the L3's misses, not the L2's.
    assert_eq!(c("dram_read_bytes"), c("cache.l3_misses") * 64.0);
    // The same frame on the Larrabee machine has no L3 counters at all.
    let l = render("pcss", Backend::CpuModel, &f);
    assert!(l.counters.get("cache.l3_hits").is_none());
}

#[test]
fn more_modelled_cores_take_less_modelled_time() {
    let f = |cores| {
        let mut f = frame(0.5, 16);
        f.params.cores = Some(cores);
        render("hard_shadow_map", Backend::CpuModel, &f)
    };
    let (one, many) = (f(1), f(24));
    assert!(many.model_ms.unwrap() < one.model_ms.unwrap() / 4.0);
    // The same work is done, only spread differently.
    assert_eq!(
        one.counters.get("vector_ops"),
        many.counters.get("vector_ops")
    );
    assert_eq!(one.execution["machine_cores"], 1);
}

/// `n`×`n` large overlapping triangles spread over the target, in a fixed pattern.
fn big_triangles(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    for i in 0..n * n {
        let (x, y) = ((i % n) as f32 / n as f32, (i / n) as f32 / n as f32);
        let (cx, cy) = (x * 1.6 - 0.8, y * 1.6 - 0.8);
        let base = pos.len() as u32;
        let z = 0.2 + 0.6 * ((i * 7) % 11) as f32 / 11.0;
        pos.push(Vec3::new(cx - 0.5, cy - 0.4, z));
        pos.push(Vec3::new(cx + 0.6, cy - 0.3, z));
        pos.push(Vec3::new(cx, cy + 0.5, z));
        tris.push([base, base + 1, base + 2]);
    }
    (pos, tris)
}

fn raster_counters(
    tile: u32,
    pipeline: Pipeline,
    geometry: (&[Vec3], &[[u32; 3]]),
) -> BTreeMap<String, f64> {
    let mut m = Machine::new(Backend::CpuModel, MachineConfig::default());
    m.phase("draw");
    let positions = m.memory.buffer("vertices", geometry.0.to_vec());
    let triangles = m.memory.buffer("indices", geometry.1.to_vec());
    let g = Geometry {
        positions: &positions,
        triangles: &triangles,
        view_proj: glam::Mat4::IDENTITY,
    };
    let target = Target {
        width: 200,
        height: 136,
        tile,
    };
    raster::draw(&mut m, "target", target, pipeline, &g, &DepthOnly);
    m.finish().counters.0
}

#[test]
fn doubling_the_tile_size_reduces_bin_entries_and_keeps_fill() {
    let (pos, tris) = big_triangles(6);
    let small = raster_counters(16, Pipeline::DEPTH_ONLY, (&pos, &tris));
    let large = raster_counters(32, Pipeline::DEPTH_ONLY, (&pos, &tris));
    assert!(
        large["bin_entries"] < small["bin_entries"],
        "{} vs {}",
        large["bin_entries"],
        small["bin_entries"]
    );
    assert_eq!(large["fill"], small["fill"]);
    assert!(small["fill"] > 0.0);
    for c in [&small, &large] {
        assert_eq!(
            c["fill"],
            c["fragments_rejected_early"] + c["depth_pass"] + c["depth_fail"]
        );
    }
}

#[test]
fn two_triangles_sharing_an_edge_cover_each_pixel_once() {
    // A full-screen quad split along its diagonal: the top-left rule gives every pixel centre
    // to exactly one of the two triangles.
    let pos = [
        Vec3::new(-1.0, -1.0, 0.5),
        Vec3::new(1.0, -1.0, 0.5),
        Vec3::new(1.0, 1.0, 0.5),
        Vec3::new(-1.0, 1.0, 0.5),
    ];
    let tris = [[0, 1, 2], [0, 2, 3]];
    let p = Pipeline {
        depth_clear: None,
        ..Pipeline::DEPTH_ONLY
    };
    let c = raster_counters(32, p, (&pos, &tris));
    assert_eq!(c["fill"], 200.0 * 136.0);
    let cons = raster_counters(
        32,
        Pipeline {
            coverage: Coverage::Conservative,
            ..p
        },
        (&pos, &tris),
    );
    assert!(cons["fill"] >= c["fill"]);
}

#[test]
fn an_unknown_machine_in_a_scenario_names_the_field_and_suggests_a_preset() {
    let text = r#"{"scene": {"generator": "sphere-on-plane"}, "algorithms": ["pcss"],
                   "machine": "larrabee-42"}"#;
    let e = Loaded::from_str(text, std::path::Path::new("s.json")).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("$.machine"));
    assert!(
        e.message.contains("did you mean 'larrabee-24'") || e.message.contains("larrabee-"),
        "{e}"
    );
    let ok = text.replace("larrabee-42", "larrabee-48");
    let l = Loaded::from_str(&ok, std::path::Path::new("s.json")).unwrap();
    assert_eq!(l.machine.cores, 48);
}

#[test]
fn bad_pcss_options_name_the_field() {
    let text = r#"{"scene": {"generator": "sphere-on-plane"}, "algorithms": ["pcss"],
                   "options": {"pcss": {"pcf_samples": 0}}}"#;
    let e = Loaded::from_str(text, std::path::Path::new("s.json")).unwrap_err();
    assert_eq!(
        e.field.as_deref(),
        Some("$.options.pcss.pcf_samples"),
        "{e}"
    );
}

#[test]
fn options_that_are_not_an_object_are_refused_for_every_algorithm() {
    for info in shadowbench::algorithms::ALGORITHMS {
        for bad in ["[4, false, 2, 8]", "null", "\"fast\"", "3"] {
            let text = format!(
                r#"{{"scene": {{"generator": "sphere-on-plane"}}, "algorithms": ["{id}"],
                    "options": {{"{id}": {bad}}}}}"#,
                id = info.id
            );
            let e = Loaded::from_str(&text, std::path::Path::new("s.json")).unwrap_err();
            let at = format!("$.options.{}", info.id);
            assert_eq!(
                e.field.as_deref(),
                Some(at.as_str()),
                "{}: {bad}: {e}",
                info.id
            );
            assert!(!e.message.contains("struct"), "{}: {bad}: {e}", info.id);
        }
    }
}

/// `--machine host` takes its clock from the operating system, not from timing: two processes
/// rendering the same frame model the same time (issue: a clock measured per process under
/// load gave model_ms up to 5× apart).
#[test]
fn two_processes_on_the_host_preset_model_the_same_time() {
    if shadowbench::model::config::host_clock().is_err() {
        eprintln!("skipped: this OS states no CPU frequency (the host preset is refused)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let runs: Vec<serde_json::Value> = (0..2)
        .map(|i| {
            let out = dir.path().join(format!("r{i}"));
            let status = std::process::Command::new(env!("CARGO_BIN_EXE_shadowbench"))
                .args([
                    "render",
                    "--algorithm",
                    "pcss",
                    "--backend",
                    "cpu-model",
                    "--machine",
                    "host",
                    "--image",
                    "48x36",
                    "--map-resolution",
                    "64",
                    "--no-reference",
                    "--out",
                ])
                .arg(&out)
                .status()
                .unwrap();
            assert!(status.success());
            serde_json::from_slice(&std::fs::read(out.join("run.json")).unwrap()).unwrap()
        })
        .collect();
    let model_ms = |r: &serde_json::Value| r["model_ms"].as_f64().unwrap();
    assert!(model_ms(&runs[0]) > 0.0);
    assert_eq!(model_ms(&runs[0]), model_ms(&runs[1]));
    for r in &runs {
        assert_eq!(r["execution"]["machine"], "host");
        assert!(
            r["execution"]["clock_source"].is_string(),
            "{}",
            r["execution"]
        );
    }
    // The same execution record, apart from the measurement conditions (the host's load average
    // before and after each run moves between the two processes on a shared machine).
    let without_conditions = |r: &serde_json::Value| {
        let mut e = r["execution"].clone();
        e.as_object_mut().unwrap().remove("conditions");
        e
    };
    assert_eq!(without_conditions(&runs[0]), without_conditions(&runs[1]));
}
