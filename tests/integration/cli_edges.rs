//! The command line at its edges: a selection that selects nothing, an impossible `render`,
//! a light converted for an algorithm, and `compare` across scenarios each say so, with exit
//! code 2 for input errors and nothing written.

use std::path::Path;
use std::process::Command;

use super::common::{shadowbench, stderr, stdout};

const SCENARIO: &str = r#"{
  "name": "edges",
  "scene": { "generator": "sphere-on-plane" },
  "algorithms": ["reference", "hard_shadow_map"],
  "backends": ["cpu-native", "cpu-model"],
  "params": { "image": [24, 18], "map_resolution": 32, "tile_size": 8, "triangles": 200 },
  "reference": { "samples": 4 }
}"#;

fn scenario(dir: &Path) -> String {
    let p = dir.join("edges.json");
    std::fs::write(&p, SCENARIO).unwrap();
    p.to_str().unwrap().to_string()
}

#[test]
fn a_run_selecting_nothing_says_so_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path());
    let out = dir.path().join("out");
    let out_s = out.to_str().unwrap();
    // The scenario has no pcss; and no wgpu execution.
    for args in [
        vec!["run", &s, "--only", "pcss", "--out", out_s],
        vec![
            "run",
            &s,
            "--only",
            "hard_shadow_map",
            "--backend",
            "wgpu",
            "--out",
            out_s,
        ],
        // reference has only cpu-native.
        vec![
            "run",
            &s,
            "--only",
            "reference",
            "--backend",
            "cpu-model",
            "--out",
            out_s,
        ],
    ] {
        let o = shadowbench(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains("no run selected"), "{args:?}: {e}");
        assert!(
            e.contains("edges.json") && e.contains("hard_shadow_map"),
            "{e}"
        );
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
        assert!(!stdout(&o).contains("results in"), "{}", stdout(&o));
    }
}

#[test]
fn an_impossible_render_is_an_input_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let o = shadowbench(&[
        "render",
        "--algorithm",
        "reference",
        "--backend",
        "wgpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("--backend") && e.contains("'reference'") && e.contains("cpu-native"),
        "{e}"
    );
    assert!(!out.exists());
}

#[test]
fn render_warns_when_it_converts_the_light() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    // sphere-on-plane has a sphere light; dbuffer takes a disc.
    let o = shadowbench(&[
        "render",
        "--algorithm",
        "dbuffer",
        "--backend",
        "cpu-native",
        "--image",
        "32x24",
        "--map-resolution",
        "64",
        "--no-reference",
        "--out",
        out.to_str().unwrap(),
    ]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("note: light converted from sphere to disc"),
        "{e}"
    );
    let run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("run.json")).unwrap()).unwrap();
    let w = run["notes"].to_string();
    assert!(w.contains("light converted from sphere to disc"), "{w}");
    assert!(run.get("warnings").is_none(), "{run}");
    // Without a conversion, no warning.
    let o = shadowbench(&[
        "render",
        "--algorithm",
        "pcss",
        "--image",
        "32x24",
        "--map-resolution",
        "64",
        "--no-reference",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    assert!(!stderr(&o).contains("light converted"), "{}", stderr(&o));
}

#[test]
fn compare_of_different_scenarios_says_so_first() {
    // One real run, filed under two scenario names (a baseline with no runs is refused).
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path());
    let out = dir.path().join("out");
    let o = shadowbench(&[
        "run",
        &s,
        "--only",
        "hard_shadow_map",
        "--backend",
        "cpu-model",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let file = |name: &str| {
        let mut v = results.clone();
        v["scenario"] = serde_json::json!(name);
        let p = dir.path().join(format!("{name}.json"));
        std::fs::write(&p, v.to_string()).unwrap();
        p.to_str().unwrap().to_string()
    };
    let (a, b) = (file("ci"), file("quick"));
    let o = shadowbench(&["compare", &a, &b]);
    let text = stdout(&o);
    let first = text.lines().next().unwrap_or_default();
    assert!(
        first.contains("different scenarios")
            && first.contains("'ci'")
            && first.contains("'quick'"),
        "{text}"
    );
}

/// Output into a pipe whose reader is gone (`shadowbench list | head`) ends the process by
/// SIGPIPE, as other command-line tools do, never with a panic.
#[cfg(unix)]
#[test]
fn output_into_a_closed_pipe_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    for args in [&["list"][..], &["list", "--counters"][..]] {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
            .args(args)
            .stdout(writer)
            .output()
            .unwrap();
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert_eq!(o.status.signal(), Some(libc::SIGPIPE), "{args:?}: {err}");
    }
}

#[test]
fn render_of_a_scenario_names_what_it_does_not_use() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path());
    let with_options = dir.path().join("options.json");
    let text = SCENARIO.replace(
        r#""reference": {"#,
        r#""options": { "hard_shadow_map": {} }, "reference": {"#,
    );
    std::fs::write(&with_options, text).unwrap();
    let render = |scene: &str| {
        let out = dir.path().join("r");
        shadowbench(&[
            "render",
            "--scene",
            scene,
            "--algorithm",
            "hard_shadow_map",
            "--image",
            "32x24",
            "--no-reference",
            "--out",
            out.to_str().unwrap(),
        ])
    };
    // The scenario's image, map resolution and tile size are not the command line's.
    let o = render(&s);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("render takes the scenario's scene, light and camera only"),
        "{e}"
    );
    for name in ["params.image", "params.map_resolution", "params.tile_size"] {
        assert!(e.contains(name), "{name}: {e}");
    }
    assert!(!e.contains("options."), "{e}");
    let o = render(with_options.to_str().unwrap());
    assert!(
        stderr(&o).contains("options.hard_shadow_map"),
        "{}",
        stderr(&o)
    );
}

/// `--adapter` (or `SHADOWBENCH_ADAPTER`) naming no adapter there is bad input (exit 2, naming
/// the option or the variable), in `render` and in `run`, before anything is written: before,
/// `run` skipped its wgpu runs with a note and exited 0, so the runs meant for that GPU silently
/// did not happen.
#[test]
fn an_adapter_that_is_not_there_is_an_input_error() {
    let dir = tempfile::tempdir().unwrap();
    let file = scenario(dir.path());
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    let name = "no-such-adapter-7f3a";
    for args in [
        vec![
            "render",
            "--algorithm",
            "pcss",
            "--backend",
            "wgpu",
            "--no-reference",
        ],
        vec!["run", &file, "-q"],
    ] {
        let o = shadowbench(&[&args[..], &["--adapter", name, "--out", out]].concat());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("--adapter"), "{}", stderr(&o));
        assert!(!Path::new(out).exists(), "{args:?} wrote {out}");
    }
    // The environment's name is held to the same rule, and named.
    let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", &file, "-q", "--out", out])
        .env("SHADOWBENCH_ADAPTER", name)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("SHADOWBENCH_ADAPTER"), "{}", stderr(&o));
    assert!(!Path::new(out).exists(), "run wrote {out}");
}

/// `diff` of a run whose `visibility.npy` holds a value outside [0, 1] (NaN, infinity, 5) is
/// an input error naming the file and the pixel, not a NaN mean.
#[test]
fn diff_refuses_a_visibility_outside_zero_to_one() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    let o = shadowbench(&[
        "render",
        "--algorithm",
        "pcss",
        "--image",
        "16x12",
        "--map-resolution",
        "32",
        "--no-reference",
        "--out",
        a.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let b = dir.path().join("b");
    std::fs::create_dir(&b).unwrap();
    for name in ["visibility.npy", "mask.npy"] {
        std::fs::copy(a.join(name), b.join(name)).unwrap();
    }
    let npy = b.join("visibility.npy");
    let good = std::fs::read(&npy).unwrap();
    for bad in [f32::NAN, f32::INFINITY, 5.0] {
        // The last pixel (15, 11): the array's last four bytes, little-endian f32.
        let mut bytes = good.clone();
        let n = bytes.len();
        bytes[n - 4..].copy_from_slice(&bad.to_le_bytes());
        std::fs::write(&npy, bytes).unwrap();
        let png = dir.path().join("d.png");
        let o = shadowbench(&[
            "diff",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--out",
            png.to_str().unwrap(),
        ]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{bad}: {e}");
        assert!(
            e.contains("visibility.npy") && e.contains("(15, 11)") && e.contains(&bad.to_string()),
            "{bad}: {e}"
        );
        assert!(!png.exists());
    }
}

/// A second `render` into the same folder leaves one frame's files: the reference images of
/// the first are removed when the second has no reference.
#[test]
fn render_into_a_used_folder_removes_the_earlier_frames_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let render = |extra: &[&str]| {
        let mut args = vec!["render", "--image", "16x12", "--map-resolution", "32"];
        args.extend(extra);
        args.extend(["--out", out.to_str().unwrap()]);
        let o = shadowbench(&args);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    render(&["--algorithm", "pcss", "--samples", "4"]);
    for f in ["reference.png", "reference_shaded.png", "error.png"] {
        assert!(out.join(f).exists(), "{f}");
    }
    render(&["--algorithm", "hard_shadow_map", "--no-reference"]);
    for f in ["reference.png", "reference_shaded.png", "error.png"] {
        assert!(!out.join(f).exists(), "{f} left from the first render");
    }
    assert!(out.join("visibility.png").exists() && out.join("run.json").exists());
}
