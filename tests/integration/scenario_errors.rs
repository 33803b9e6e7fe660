//! Invalid scenarios: each mistake gives one clear line naming the file, the JSON path and the
//! bad value, and the CLI exits with code 2 without panicking.

use std::path::Path;
use std::process::Command;

use shadowbench::scenario::Loaded;

const VALID: &str = r#"{
  "name": "t",
  "scene": { "generator": "sphere-on-plane" },
  "algorithms": ["reference"],
  "backends": ["cpu-native"],
  "params": { "image": [32, 24], "map_resolution": 64 },
  "sweep": { "light_size": [0.2, 0.4] }
}"#;

/// Replaces `from` with `to` in the valid scenario (which must contain `from`).
fn mutate(from: &str, to: &str) -> String {
    assert!(VALID.contains(from), "{from}");
    VALID.replacen(from, to, 1)
}

fn objects(obj: &str) -> String {
    mutate(
        r#""generator": "sphere-on-plane""#,
        &format!(r#""objects": [{{ "obj": "{obj}" }}]"#),
    )
}

/// (what is wrong, scenario text, substrings the error must contain)
fn cases() -> Vec<(&'static str, String, Vec<&'static str>)> {
    vec![
        (
            "malformed JSON",
            mutate(r#""t","#, r#""t""#),
            vec!["malformed JSON", "line 3"],
        ),
        (
            "unknown field",
            mutate(r#""name""#, r#""nmae""#),
            vec!["unknown field `nmae`"],
        ),
        (
            "unknown nested field",
            mutate(r#""map_resolution""#, r#""map_res""#),
            vec!["$.params", "map_res"],
        ),
        (
            "wrong type",
            mutate("[32, 24]", r#""32x24""#),
            vec!["$.params.image"],
        ),
        (
            "negative light size",
            mutate("0.4]", "-0.4]"),
            vec!["$.sweep.light_size[1]", "-0.4"],
        ),
        (
            "zero map resolution",
            mutate(r#""map_resolution": 64"#, r#""map_resolution": 0"#),
            vec!["$.params.map_resolution", "got 0"],
        ),
        (
            "zero tile size",
            mutate(
                r#""map_resolution": 64"#,
                r#""map_resolution": 64, "tile_size": 0"#,
            ),
            vec!["$.params.tile_size", "got 0"],
        ),
        (
            "empty image",
            mutate("[32, 24]", "[0, 0]"),
            vec!["$.params.image", "0x0"],
        ),
        (
            "infinite light size",
            mutate("0.4]", "1e39]"),
            vec!["$.sweep.light_size[1]", "number out of range"],
        ),
        (
            // Beyond the coordinate range a rectangle's half-axis length overflows f32.
            "light size past the coordinate range",
            mutate("0.4]", "1e30]"),
            vec!["$.sweep.light_size[1]", "1e30", "2^40"],
        ),
        (
            "unknown algorithm",
            mutate(r#"["reference"]"#, r#"["referense"]"#),
            vec!["$.algorithms[0]", "referense", "did you mean 'reference'"],
        ),
        (
            "unknown backend",
            mutate(r#"["cpu-native"]"#, r#"["cuda"]"#),
            vec!["$.backends[0]", "cuda"],
        ),
        (
            "unknown scene generator",
            mutate("sphere-on-plane", "sphere-on-plain"),
            vec!["$.scene.generator", "did you mean 'sphere-on-plane'"],
        ),
        (
            "reference samples not a square",
            mutate(r#""sweep""#, r#""reference": { "samples": 200 }, "sweep""#),
            vec!["$.reference.samples", "200"],
        ),
        (
            "camera eye equals target",
            mutate(
                r#""sweep""#,
                r#""camera": { "eye": [1,2,3], "target": [1,2,3] }, "sweep""#,
            ),
            vec!["$.camera.target"],
        ),
        (
            "camera beyond the coordinate range",
            mutate(
                r#""sweep""#,
                r#""camera": { "eye": [1e20,2,3], "target": [0,0,0] }, "sweep""#,
            ),
            vec!["$.camera.eye", "2^40"],
        ),
        (
            "zero light radius",
            mutate(
                r#""sweep""#,
                r#""light": { "type": "sphere", "center": [0,5,0], "radius": 0 }, "sweep""#,
            ),
            vec!["$.light.radius", "got 0"],
        ),
        (
            "options for an unknown algorithm",
            mutate(r#""sweep""#, r#""options": { "pcs": {} }, "sweep""#),
            vec!["$.options.pcs"],
        ),
        (
            "missing OBJ file",
            objects("data/nope.obj"),
            vec!["nope.obj", "file not found", "$.scene.objects[0].obj"],
        ),
        (
            "OBJ index out of range",
            objects("data/bad_index.obj"),
            vec!["bad_index.obj", "line 4", "vertex 9"],
        ),
        (
            "mesh file of an unknown format",
            objects("data/triangle.stl"),
            vec!["triangle.stl", "unknown mesh format"],
        ),
        (
            "OBJ without triangles",
            objects("data/lines.obj"),
            vec!["lines.obj"],
        ),
        (
            "empty OBJ",
            objects("data/empty.obj"),
            vec!["empty.obj", "no triangles"],
        ),
        (
            "negative object scale",
            objects(r#"data/triangle.obj", "scale": -1, "name": "x"#),
            vec!["$.scene.objects[0].scale", "-1"],
        ),
        (
            "no algorithms",
            mutate(r#"["reference"]"#, "[]"),
            vec!["$.algorithms", "at least one"],
        ),
        (
            "infinite occluder offset",
            mutate(
                r#""sweep": {"#,
                r#""sweep": { "occluder_offset": [0, 1e39],"#,
            ),
            vec!["$.sweep.occluder_offset[1]", "number out of range"],
        ),
        (
            "occluder offset out of range",
            mutate(
                r#""map_resolution": 64"#,
                r#""map_resolution": 64, "occluder_offset": -250"#,
            ),
            vec!["$.params.occluder_offset", "-250"],
        ),
        (
            "an algorithm listed twice",
            mutate(r#""algorithms": ["#, r#""algorithms": ["pcss", "pcss", "#),
            vec!["$.algorithms[1]", "pcss", "$.algorithms[0]"],
        ),
        (
            "occluder height out of range",
            mutate(
                r#""map_resolution": 64"#,
                r#""map_resolution": 64, "occluder_height": 1e30"#,
            ),
            vec!["$.params.occluder_height", "got 1e30"],
        ),
        (
            "occluder offset for a scene without a moving occluder",
            mutate(r#""sweep": {"#, r#""sweep": { "occluder_offset": [1],"#).replacen(
                "sphere-on-plane",
                "street",
                1,
            ),
            vec!["$.sweep.occluder_offset", "street", "plate-on-plane"],
        ),
        (
            "occluder height for a scene whose occluders stand on the ground",
            mutate(
                r#""map_resolution": 64"#,
                r#""map_resolution": 64, "occluder_height": 2"#,
            )
            .replacen("sphere-on-plane", "fern", 1),
            vec!["$.params.occluder_height", "fern", "room"],
        ),
        (
            "occluder offset for user meshes",
            objects("data/triangle.obj").replacen(
                r#""map_resolution": 64"#,
                r#""map_resolution": 64, "occluder_offset": 1"#,
                1,
            ),
            vec!["$.params.occluder_offset", "generator scene"],
        ),
        (
            "cores out of range",
            mutate(r#""sweep": {"#, r#""sweep": { "cores": [0],"#),
            vec!["$.sweep.cores[0]", "got 0"],
        ),
        (
            "one-frame animation",
            mutate(
                r#""sweep": {"#,
                r#""animation": {"frames": 1, "light_center": {"to": [0, 8, 0]}}, "sweep": {"#,
            ),
            vec!["$.animation.frames", "got 1"],
        ),
        (
            "animation of a path not built",
            mutate(
                r#""sweep": {"#,
                r#""animation": {"frames": 4, "camera": {"to": 1}}, "sweep": {"#,
            ),
            vec!["$.animation", "camera"],
        ),
        (
            "animation without the reference",
            mutate(
                r#""sweep": {"#,
                r#""reference": {"enabled": false},
                   "animation": {"frames": 4, "light_center": {"to": [0, 8, 0]}}, "sweep": {"#,
            ),
            vec!["$.animation", "reference.enabled"],
        ),
        (
            "occluder animation without a start",
            mutate(
                r#""sweep": {"#,
                r#""animation": {"frames": 4, "occluder_height": {"to": 0.1}}, "sweep": {"#,
            ),
            vec!["$.animation.occluder_height", "needs a start"],
        ),
        (
            "occluder animation on a scene without a moving occluder",
            mutate(
                r#""generator": "sphere-on-plane""#,
                r#""generator": "street""#,
            )
            .replacen(
                r#""sweep": {"#,
                r#""animation": {"frames": 4, "occluder_height": {"from": 1, "to": 0.1}},
                   "sweep": {"#,
                1,
            ),
            vec!["$.animation.occluder_height", "moving occluder"],
        ),
        (
            "FLIP viewing condition out of range",
            mutate(
                r#""sweep": {"#,
                r#""reference": {"flip_pixels_per_degree": 0}, "sweep": {"#,
            ),
            vec!["$.reference.flip_pixels_per_degree", "got 0"],
        ),
    ]
}

fn scenario_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenario.json")
}

#[test]
fn the_valid_scenario_is_valid() {
    let l = Loaded::from_str(VALID, &scenario_path()).expect("valid");
    assert_eq!(l.cases(shadowbench::scenario::MAX_CASES).unwrap().len(), 3);
    Loaded::from_str(&objects("data/triangle.obj"), &scenario_path()).expect("valid OBJ scene");
}

#[test]
fn each_mistake_gives_a_one_line_error_naming_the_field() {
    let path = scenario_path();
    for (what, text, needles) in cases() {
        let err = Loaded::from_str(&text, &path)
            .err()
            .unwrap_or_else(|| panic!("{what}: accepted"));
        let msg = err.to_string();
        assert!(!msg.contains('\n'), "{what}: multi-line error: {msg}");
        assert!(
            msg.contains("scenario.json"),
            "{what}: no file name in: {msg}"
        );
        for n in needles {
            assert!(msg.contains(n), "{what}: '{n}' missing from: {msg}");
        }
    }
}

#[test]
fn the_cli_exits_with_code_2_and_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.json");
    std::fs::write(&file, mutate("0.4]", "-0.4]")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", file.to_str().unwrap(), "--out"])
        .arg(dir.path().join("out"))
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("bad.json") && stderr.contains("$.sweep.light_size[1]"),
        "{stderr}"
    );
    assert!(
        !dir.path().join("out").exists(),
        "nothing is written for an invalid scenario"
    );
}

#[test]
fn every_shipped_scenario_loads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "json") {
            // A scenario of the public test models beside the checkout loads only where they
            // are (conformance.json: `../shared/field`).
            let text = std::fs::read_to_string(&path).unwrap();
            let field = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/field");
            if text.contains("shared/field/") && !field.is_dir() {
                eprintln!("{}: skipped, {} is absent", path.display(), field.display());
                continue;
            }
            if let Err(e) = Loaded::from_file(&path) {
                panic!("{}: {e}", path.display());
            }
            checked += 1;
        }
    }
    assert!(
        checked >= 20,
        "only {checked} scenarios under {}",
        dir.display()
    );
}
