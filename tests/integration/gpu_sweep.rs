//! wgpu runs in a sweep: the shader modules and pipelines a run creates are reused by the
//! next run of the process (`gpu_setup_ms` 0, nothing created), and so are its buffers of
//! the sizes the next run asks for again, without changing its image
//! (checked against a run of a fresh process), and `--gpu-counters off` skips the instrumented
//! replay: the same image, the replay's counters absent (named, never zero), and a report that
//! does not chart them.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use super::gpu_check::have_gpu;

/// The wgpu algorithms these tests run: a render-pipeline family (light raster, compute lookup),
/// a compute-only one and the shadow-volume raster pipeline with its stencil, quick at 64×48.
const ALGORITHMS: [&str; 3] = ["pcss", "soft_izb", "soft_shadow_volume"];

fn shadowbench(args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs a sweep over light sizes (the scene's, then 0.3) of `algorithms` on wgpu, 64×48, with
/// `--gpu-counters counters`, into `dir`; returns its runs in order.
fn sweep(dir: &Path, algorithms: &[&str], counters: &str) -> Vec<Value> {
    let scenario = dir.join("s.json");
    let list: Vec<String> = algorithms.iter().map(|a| format!("\"{a}\"")).collect();
    std::fs::write(
        &scenario,
        format!(
            r#"{{
  "scene": {{ "generator": "sphere-on-plane" }},
  "algorithms": [{}],
  "backends": ["wgpu"],
  "params": {{ "image": [64, 48], "map_resolution": 128 }},
  "sweep": {{ "light_size": [0.3] }},
  "reference": {{ "enabled": false }}
}}"#,
            list.join(", ")
        ),
    )
    .unwrap();
    let out = dir.join(format!("out-{counters}"));
    shadowbench(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--gpu-counters",
        counters,
    ]);
    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    json["runs"].as_array().unwrap().clone()
}

/// The bytes of a run's `visibility.npy` in the sweep written to `out`.
fn image(out: &Path, run: &Value) -> Vec<u8> {
    let p = &run["params"];
    let case = format!(
        "sphere-on-plane_{}_wgpu_t{}_l{}_m128_b32_64x48",
        run["algorithm"].as_str().unwrap(),
        p["triangles"],
        p["light_size"].as_f64().unwrap() as f32
    );
    std::fs::read(out.join("images").join(case).join("visibility.npy")).unwrap()
}

#[test]
fn a_sweep_creates_pipelines_once_and_its_images_match_a_fresh_process() {
    if !have_gpu() {
        return;
    }
    for algorithm in ALGORITHMS {
        // A folder per algorithm: a sweep into another scenario's results is refused.
        let dir = tempfile::tempdir().unwrap();
        let runs = sweep(dir.path(), &[algorithm], "on");
        assert_eq!(runs.len(), 2, "{algorithm}");
        let setup = |r: &Value| r["execution"]["gpu_setup"].clone();
        for r in &runs {
            assert!(r["failure"].is_null(), "{r}");
            // The record's wall time leaves the setup out.
            assert!(r["gpu_setup_ms"].as_f64().unwrap() >= 0.0, "{r}");
        }
        // The first run of the process creates its modules, layouts and pipelines...
        let first = setup(&runs[0]);
        assert!(first["objects_created"].as_u64().unwrap() > 0, "{first}");
        assert!(runs[0]["gpu_setup_ms"].as_f64().unwrap() > 0.0);
        // ... and the second, another light size, finds every one of them.
        let second = setup(&runs[1]);
        assert_eq!(second["objects_created"], 0, "{algorithm}: {second}");
        let asked = |s: &Value| {
            s["objects_created"].as_u64().unwrap() + s["objects_reused"].as_u64().unwrap()
        };
        assert_eq!(
            second["objects_reused"].as_u64().unwrap(),
            asked(&first),
            "{algorithm}: the second run asks for the first's objects again: {first} {second}"
        );
        assert_eq!(runs[1]["gpu_setup_ms"], 0.0, "{algorithm}");
        // The buffers: all new in a fresh process; the second run (same image and map sizes)
        // takes some from the first's.
        assert_eq!(first["buffers_reused"], 0, "{algorithm}: {first}");
        assert!(first["buffers_made"].as_u64().unwrap() > 0, "{first}");
        let reused = second["buffers_reused"].as_u64().unwrap();
        assert!(reused > 0, "{algorithm}: {second}");

        // A fresh process renders the second case with pipelines of its own: the same image.
        let fresh = dir.path().join(format!("fresh-{algorithm}"));
        shadowbench(&[
            "render",
            "--scene",
            "sphere-on-plane",
            "--algorithm",
            algorithm,
            "--backend",
            "wgpu",
            "--image",
            "64x48",
            "--map-resolution",
            "128",
            "--light-size",
            "0.3",
            "--no-reference",
            "--out",
            fresh.to_str().unwrap(),
        ]);
        let alone: Value =
            serde_json::from_str(&std::fs::read_to_string(fresh.join("run.json")).unwrap())
                .unwrap();
        assert_eq!(alone["params"], runs[1]["params"], "{algorithm}");
        let swept = image(&dir.path().join("out-on"), &runs[1]);
        assert!(
            std::fs::read(fresh.join("visibility.npy")).unwrap() == swept,
            "{algorithm}: the swept run's image differs from a fresh process's"
        );
        // The fresh process made its own objects; its counters agree with the swept run's.
        assert!(alone["execution"]["gpu_setup"]["objects_created"].as_u64() > Some(0));
        assert_eq!(alone["counters"]["fill"], runs[1]["counters"]["fill"]);
    }
}

#[test]
fn gpu_counters_off_keeps_the_image_and_leaves_the_replay_counters_out() {
    if !have_gpu() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let on = sweep(dir.path(), &ALGORITHMS, "on");
    let off = sweep(dir.path(), &ALGORITHMS, "off");
    assert_eq!(on.len(), 2 * ALGORITHMS.len());
    assert_eq!(off.len(), 2 * ALGORITHMS.len());
    for (a, b) in on.iter().zip(&off) {
        let id = format!("{} at {}", a["algorithm"], a["params"]["light_size"]);
        assert_eq!(a["params"], b["params"], "{id}");
        assert_eq!(
            image(&dir.path().join("out-on"), a),
            image(&dir.path().join("out-off"), b),
            "{id}: the image does not depend on the replay"
        );
        assert_eq!(b["execution"]["gpu_counters"], "off", "{id}");
        assert_ne!(a["execution"]["gpu_counters"], "off", "{id}");
        assert!(a["execution"].get("gpu_counters_absent").is_none(), "{id}");
        // The replay's counters: recorded with it, absent (not zero) without it, and named.
        let absent: Vec<&str> = b["execution"]["gpu_counters_absent"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert!(absent.contains(&"fill"), "{id}: {absent:?}");
        for name in &absent {
            assert!(a["counters"].get(name).is_some(), "{id}: {name} on");
            assert!(b["counters"].get(name).is_none(), "{id}: {name} off");
            for p in b["phases"].as_array().unwrap() {
                assert!(p["counters"].get(name).is_none(), "{id}: {name} in {p}");
            }
        }
        assert!(b["counters"].get("overdraw_ratio").is_none(), "{id}");
        // What does not come from the replay stays: the pipeline statistics of the timed
        // passes (where the adapter has them) and the scene's edge counts.
        for (name, v) in b["counters"].as_object().unwrap() {
            assert_eq!(a["counters"].get(name), Some(v), "{id}: {name}");
        }
        assert!(b["counters"].get("occluders.boundary_edges").is_some());
    }
    // The sweep's table leaves the absent counters' cells empty, so no chart or column shows
    // them as values.
    let csv = std::fs::read_to_string(dir.path().join("out-off/results.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let fill = header.iter().position(|h| *h == "fill").unwrap();
    for line in lines {
        assert_eq!(line.split(',').nth(fill), Some(""), "{line}");
    }
}
