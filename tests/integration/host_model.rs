//! The host as a modelled machine: `calibrate` writes a machine file that `--machine` takes, and
//! `validate-model` compares the cpu-model with cpu-native on a tiny sweep, its modelled times
//! being those `render` gives for the same runs. Settings are tiny so CI stays fast.

use super::common::{json, shadowbench, text};

#[test]
fn calibrate_writes_a_machine_that_render_accepts() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("machine.json");
    let f = file.to_str().unwrap();
    // A folder where the file should go is refused before anything is measured.
    let folder = dir.path().join("folder.json");
    std::fs::create_dir(&folder).unwrap();
    let o = shadowbench(&["calibrate", "--out", folder.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("--out"), "{}", text(&o.stderr));
    assert!(!text(&o.stdout).contains("calibrating"));
    let o = shadowbench(&["calibrate", "--quick", "--out", f]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    // One progress line per figure, each naming the field it measured.
    for field in [
        "costs.vector",
        "costs.lane",
        "costs.gather",
        "costs.atomic",
        "l2.latency_cycles",
        "dram_latency_cycles",
        "memory_parallelism",
        "dram_gb_per_s",
        "barrier_cycles",
    ] {
        assert!(out.contains(field), "{field} missing from:\n{out}");
    }
    let m = json(&file);
    assert_eq!(m["name"], "host-calibrated");
    let sources = m["sources"].as_object().unwrap();
    // The memory figures as the kernels measured them; the issue costs fitted to the training
    // sweep, each source naming the kernel's figure beside it.
    for k in ["l1.latency_cycles", "dram_gb_per_s", "barrier_cycles"] {
        assert!(
            sources[k].as_str().unwrap().starts_with("measured"),
            "{k}: {}",
            sources[k]
        );
    }
    for k in [
        "costs.vector",
        "costs.scalar",
        "costs.vector_memory",
        "costs.phase",
    ] {
        let s = sources[k].as_str().unwrap();
        assert!(
            s.starts_with("fitted") && s.contains("box-on-plane"),
            "{k}: {s}"
        );
    }
    assert!(out.contains("fitting the issue costs"), "{out}");
    // The training sweep is recorded in the machine, and validate-model holds it out: a training
    // scene or image size is refused, naming the flag, before anything runs.
    let t = &m["training"];
    assert_eq!(t["scenes"][0], "box-on-plane", "{t}");
    assert_eq!(t["images"], serde_json::json!([[160, 120]]), "{t}");
    assert_eq!(t["clock"], "cpu", "{t}");
    for (flag, value, named) in [
        ("--scenes", "room,sphere-grid", "'sphere-grid'"),
        ("--images", "400x300,160x120", "'160x120'"),
    ] {
        let v = dir.path().join("v");
        let o = shadowbench(&[
            "validate-model",
            "--machine",
            f,
            flag,
            value,
            "--out",
            v.to_str().unwrap(),
        ]);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(flag) && err.contains(named), "{err}");
        assert!(!v.exists());
    }
    // --kernels-only: the kernels' figures, no training sweep.
    let kernels = dir.path().join("kernels.json");
    let o = shadowbench(&[
        "calibrate",
        "--quick",
        "--kernels-only",
        "--out",
        kernels.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(!text(&o.stdout).contains("fitting"));
    let k = json(&kernels);
    for f in ["costs.vector", "costs.scalar", "costs.vector_memory"] {
        let s = k["sources"][f].as_str().unwrap();
        assert!(s.starts_with("measured"), "{f}: {s}");
    }
    // The sizes are the host preset's (read from the OS), only costs are measured.
    let o = shadowbench(&["list", "--machine", "host"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let host: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for k in [
        "cores",
        "threads_per_core",
        "line_bytes",
        "simd",
        "clock_ghz",
    ] {
        assert_eq!(m[k], host[k], "{k}");
    }
    for k in ["l1", "l2", "l3"] {
        assert_eq!(m[k]["size_bytes"], host[k]["size_bytes"], "{k}");
        assert_eq!(m[k]["ways"], host[k]["ways"], "{k}");
    }
    let render = dir.path().join("r");
    let o = shadowbench(&[
        "render",
        "--algorithm",
        "hard_shadow_map",
        "--backend",
        "cpu-model",
        "--machine",
        f,
        "--image",
        "32x24",
        "--map-resolution",
        "64",
        "--no-reference",
        "--out",
        render.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let r = json(&render.join("run.json"));
    assert_eq!(r["execution"]["machine"], "host-calibrated");
    assert!(r["model_ms"].as_f64().unwrap() > 0.0);
}

#[test]
fn validate_model_agrees_with_render_on_its_modelled_times() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v");
    let o = shadowbench(&[
        "validate-model",
        "--machine",
        "larrabee-24",
        "--only",
        "hard_shadow_map,pcss",
        "--scenes",
        "plate-on-plane",
        "--images",
        "32x24",
        "--repeats",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    for f in shadowbench::harness::validate::FILES {
        assert!(out.join(f).is_file(), "{f} not written");
    }
    // The machine used, given by --machine, is written beside the results.
    assert_eq!(json(&out.join("machine.json"))["name"], "larrabee-24");
    let v = json(&out.join("validation.json"));
    let runs = v["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    assert_eq!(v["runs_agreement"]["n"], 2);
    let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
    let phases = std::fs::read_to_string(out.join("phases.csv")).unwrap();
    // Both algorithms have a light pass and an eye pass.
    assert_eq!(phases.lines().count(), 1 + 4, "{phases}");
    for r in runs {
        let (m, t) = (
            r["modelled_ms"].as_f64().unwrap(),
            r["measured_ms"].as_f64().unwrap(),
        );
        assert!(t > 0.0 && (r["ratio"].as_f64().unwrap() - m / t).abs() < 1e-9 * m / t);
        // The same case through `render`: the same modelled time.
        let alg = r["algorithm"].as_str().unwrap();
        let dir_r = dir.path().join(alg);
        let o = shadowbench(&[
            "render",
            "--algorithm",
            alg,
            "--scene",
            "plate-on-plane",
            "--backend",
            "cpu-model",
            "--machine",
            "larrabee-24",
            "--image",
            "32x24",
            "--map-resolution",
            "256",
            "--tile-size",
            "32",
            "--no-reference",
            "--out",
            dir_r.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let rendered = json(&dir_r.join("run.json"));
        assert_eq!(rendered["model_ms"].as_f64().unwrap(), m, "{alg}");
        // The work the row keeps is what the cpu-model counted for the same case.
        for k in ["vector_ops", "active_lanes", "scalar_ops", "gathers"] {
            assert_eq!(r["work"][k], rendered["counters"][k], "{alg} {k}");
        }
        // On Linux each run has its on-CPU time per logical CPU.
        if cfg!(target_os = "linux") {
            assert!(
                r["cpu_ms"].as_f64().unwrap() > 0.0,
                "{alg}: {}",
                r["cpu_ms"]
            );
        }
    }
}

#[test]
fn validate_model_refuses_bad_sweep_settings_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v");
    for (flag, value) in [
        ("--images", "0x24"),
        ("--images", "big"),
        ("--scenes", "no-such-scene"),
        ("--repeats", "0"),
        ("--machine", "larabee-24"),
        ("--kernels-only", "--machine=larrabee-24"),
        ("--scenes", "sphere-on-plane,sphere-on-plane"),
        ("--images", "32x24,32x24"),
        // The default training sweep's scene and size are held out.
        ("--scenes", "box-on-plane"),
        ("--images", "480x360"),
        ("--train-scenes", "no-such-scene"),
        ("--train-images", "0x1"),
        ("--train-repeats", "0"),
        ("--clock", "sundial"),
        ("--folds", "1"),
    ] {
        let o = shadowbench(&[
            "validate-model",
            flag,
            value,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(
            o.status.code(),
            Some(2),
            "{flag} {value}: {}",
            text(&o.stderr)
        );
        assert!(text(&o.stderr).contains(flag), "{}", text(&o.stderr));
        assert!(!out.exists(), "{flag} {value}: output folder written");
    }
}
