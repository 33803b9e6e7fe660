//! Hostile inputs, round three (docs/robustness.md): a run budget that holds through every
//! phase, output errors and non-UTF-8 arguments without a panic, files read right or refused
//! (Fortran-ordered `.npy`, huge declared sizes, trailing content), errors that name the right
//! field and exit 2, writes that stay where they belong, readers that take valid input, and a
//! progress counter that counts what runs. Each test gives the input and the behaviour.

use std::os::unix::ffi::OsStrExt;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use super::common::{shadowbench, stderr, stdout};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn write(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

/// The one `error:` line of a failed command.
fn error_line(o: &Output) -> String {
    let e = stderr(o);
    let lines: Vec<&str> = e.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(lines.len(), 1, "{e}");
    lines[0].to_string()
}

/// Exit 2 and one error line containing every one of `want`.
fn refused(o: &Output, want: &[&str]) -> String {
    assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
    let e = error_line(o);
    for w in want {
        assert!(e.contains(w), "{w}: {e}");
    }
    e
}

/// `run SCENARIO --out OUT --run-timeout BUDGET -q` (BUDGET in seconds).
fn run_within(scenario: &Path, out: &Path, budget: &str) -> Output {
    shadowbench(&[
        "run",
        s(scenario),
        "--out",
        s(out),
        "--run-timeout",
        budget,
        "-q",
    ])
}

fn results(out: &Path) -> Vec<Value> {
    let v: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    v["runs"].as_array().unwrap().clone()
}

/// A cheap scenario: hard_shadow_map on cpu-native at 16×12.
fn tiny() -> Value {
    json!({
        "scene": { "generator": "box-on-plane" },
        "algorithms": ["hard_shadow_map"],
        "backends": ["cpu-native"],
        "params": { "image": [16, 12], "map_resolution": 32 },
        "reference": { "samples": 4 }
    })
}

/// A `.npy` file (format 1.0) of `shape` with the given dtype and order, `data` as stored.
fn npy(path: &Path, descr: &str, fortran: bool, shape: &[u64], data: &[u8]) {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!(
        "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
        if fortran { "True" } else { "False" }
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    bytes.extend_from_slice(data);
    std::fs::write(path, bytes).unwrap();
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The mean |A−B| that `diff` prints.
fn mean_difference(o: &Output) -> f64 {
    let out = stdout(o);
    let at = out.find("mean |A−B| ").expect("a mean") + "mean |A−B| ".len();
    out[at..].split(',').next().unwrap().trim().parse().unwrap()
}

// Fault 1: a run budget that holds in every phase, with texture size in the estimate.

/// A 4096×4096 RGB PNG (the largest light texture), a smooth pattern that compresses well.
fn big_texture(path: &Path) {
    let img = image::RgbImage::from_fn(4096, 4096, |x, y| {
        image::Rgb([(x / 16) as u8, (y / 16) as u8, 200])
    });
    img.save(path).unwrap();
}

fn textured(png: &str, samples: u32, image: [u32; 2]) -> Value {
    json!({
        "scene": { "generator": "sphere-on-plane" },
        "light": { "type": "rect", "center": [0.4, 6, 0.2], "half_u": [0.9, 0, 0],
                   "half_v": [0, 0, 0.7], "texture": { "png": png } },
        "algorithms": ["reference"],
        "backends": ["cpu-native"],
        "params": { "image": image },
        "reference": { "samples": samples }
    })
}

#[test]
fn the_largest_light_texture_run_keeps_its_budget_and_is_counted_in_the_estimate() {
    let dir = tempfile::tempdir().unwrap();
    big_texture(&dir.path().join("big.png"));
    image::RgbImage::from_pixel(64, 64, image::Rgb([255, 200, 100]))
        .save(dir.path().join("small.png"))
        .unwrap();
    let planned = |png: &str| {
        let scenario = dir.path().join(format!("{png}.json"));
        write(&scenario, &textured(png, 16, [48, 36]));
        let out = dir.path().join(format!("out-{png}"));
        let start = Instant::now();
        let o = run_within(&scenario, &out, "5");
        let took = start.elapsed();
        assert!(o.status.success(), "{}", stderr(&o));
        let e = stderr(&o);
        let line = e.lines().find(|l| l.starts_with("planned")).unwrap();
        let at = line.find("estimated work ").unwrap() + "estimated work ".len();
        let work: f64 = line[at..].split(' ').next().unwrap().parse().unwrap();
        (work, took, results(&out))
    };
    let (small, _, _) = planned("small.png");
    let (big, took, runs) = planned("big.png");
    // The texture's texels count: 4096² of them once per run beside the 48 × 36 × 16 samples.
    // (The planned line prints 4 significant digits.)
    assert!(
        big - small > 0.999 * (4096.0 * 4096.0 - 64.0 * 64.0),
        "{small} {big}"
    );
    // The documented maximum ends inside its budget (plus loading the texture), and is
    // recorded: finished, or failed with its elapsed time.
    assert!(took < Duration::from_secs(10), "{took:?}");
    assert_eq!(runs.len(), 1);
    let r = &runs[0];
    assert!(r["wall_ms"].as_f64().unwrap() < 10_000.0, "{r}");
    if let Some(f) = r["failure"].as_str() {
        assert!(f.contains("run timeout: stopped after"), "{f}");
    }
}

#[test]
fn a_budget_spent_in_the_reference_fails_the_run_with_its_phase_and_time() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    // The quality reference of 4096 samples a pixel takes far longer than the run's budget
    // (about 300 M shadow rays; several seconds at 30 M a CPU-second).
    let mut v = tiny();
    v["scene"] = json!({ "generator": "sphere-grid" });
    v["params"]["image"] = json!([320, 240]);
    v["reference"]["samples"] = json!(4096);
    v["sweep"] = json!({ "map_resolution": [64] });
    write(&scenario, &v);
    let out = dir.path().join("out");
    let start = Instant::now();
    let o = run_within(&scenario, &out, "1");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        start.elapsed() < Duration::from_secs(30),
        "{:?}",
        start.elapsed()
    );
    let runs = results(&out);
    assert_eq!(runs.len(), 2);
    for r in &runs {
        let f = r["failure"].as_str().expect("stopped");
        assert!(
            f.contains("run timeout: stopped after")
                && f.contains("in its reference")
                && f.contains("budget of 1 s")
                && f.contains("estimated work"),
            "{f}"
        );
        let ms = r["wall_ms"].as_f64().unwrap();
        assert!((1000.0..10_000.0).contains(&ms), "{r}");
    }
}

#[test]
fn a_wgpu_ray_traced_run_past_its_budget_stops_within_it() {
    if !super::gpu_check::have_gpu() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    // rt_denoised at 4,096 rays a pixel: about 78 M rays, over a minute on lavapipe, traced in
    // submissions of at most 2^20 rays with the deadline checked between them.
    let mut v = tiny();
    v["scene"] = json!({ "generator": "sphere-on-plane" });
    v["algorithms"] = json!(["rt_denoised"]);
    v["backends"] = json!(["wgpu"]);
    v["params"]["image"] = json!([160, 120]);
    v["options"] = json!({ "rt_denoised": { "spp": 4096 } });
    write(&scenario, &v);
    let out = dir.path().join("out");
    let start = Instant::now();
    let o = run_within(&scenario, &out, "1");
    assert!(o.status.success(), "{}", stderr(&o));
    let took = start.elapsed();
    assert!(took < Duration::from_secs(20), "{took:?}");
    let runs = results(&out);
    assert_eq!(runs.len(), 1);
    let f = runs[0]["failure"].as_str().expect("stopped");
    assert!(
        f.contains("run timeout: stopped after") && f.contains("budget of 1 s"),
        "{f}"
    );
}

// Fault 2: output errors.

#[test]
fn a_full_standard_output_is_one_error_line_after_the_results_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    write(&scenario, &tiny());
    let out = dir.path().join("out");
    let full = || std::fs::File::create("/dev/full").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", s(&scenario), "--out", s(&out)])
        .stdout(full())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = error_line(&o);
    assert!(
        e.contains("cannot write to standard output") && e.contains("No space left"),
        "{e}"
    );
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    // The run's results were computed and kept.
    assert_eq!(results(&out).len(), 1);
    for args in [vec!["list"], vec!["list", "--counters"]] {
        let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
            .args(&args)
            .stdout(full())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(error_line(&o).contains("No space left"), "{}", stderr(&o));
    }
    // A closed pipe is not an error: output stops quietly.
    let mut child = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .arg("list")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert!(!stderr(&o).contains("error"), "{}", stderr(&o));
}

// Fault 3: a non-UTF-8 argument.

#[test]
fn a_path_that_is_not_utf8_works_as_an_argument() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    write(&scenario, &tiny());
    let out = dir.path().join(std::ffi::OsStr::from_bytes(b"o\xe9"));
    let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .arg("run")
        .arg(&scenario)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("results.json").is_file());
    // A text argument (a scene name) that is not UTF-8 is refused by the parser, with a message.
    let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["render", "--scene"])
        .arg(std::ffi::OsStr::from_bytes(b"sph\xe9re"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("invalid UTF-8"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
}

// Fault 4: Fortran-ordered arrays.

#[test]
fn diff_reads_a_fortran_ordered_array_as_numpy_does() {
    let dir = tempfile::tempdir().unwrap();
    // A 2×3 array [[0, 0.25, 0.5], [0.75, 1, 0.125]]: stored by rows in C order and by
    // columns in Fortran order (what np.save writes for a transposed array).
    let rows = [0.0, 0.25, 0.5, 0.75, 1.0, 0.125];
    let cols = [0.0, 0.75, 0.25, 1.0, 0.5, 0.125];
    let (c, f) = (dir.path().join("c.npy"), dir.path().join("f.npy"));
    npy(&c, "<f4", false, &[2, 3], &f32_bytes(&rows));
    npy(&f, "<f4", true, &[2, 3], &f32_bytes(&cols));
    let png = dir.path().join("d.png");
    let o = shadowbench(&["diff", s(&c), s(&f), "--out", s(&png)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(mean_difference(&o), 0.0, "{}", stdout(&o));
    // Read back as row-major, the stored-by-column file is the rows' array.
    let v = shadowbench::visibility::VisibilityBuffer::read_npy(&f).unwrap();
    assert_eq!((v.width, v.height), (3, 2));
    assert_eq!(v.data, rows);
    // A Fortran-ordered mask beside it is transposed alike.
    let run = dir.path().join("run");
    std::fs::create_dir(&run).unwrap();
    npy(
        &run.join("visibility.npy"),
        "<f4",
        true,
        &[2, 3],
        &f32_bytes(&cols),
    );
    // Stored by columns, the 0 at index 1 is element (1, 0): row-major index 3.
    npy(
        &run.join("mask.npy"),
        "|u1",
        true,
        &[2, 3],
        &[1, 0, 1, 1, 1, 1],
    );
    let (_, mask) = shadowbench::harness::images::load_run(&run).unwrap();
    assert_eq!(mask.unwrap(), [true, true, true, false, true, true]);
}

// Fault 5: huge declared sizes.

#[test]
fn a_huge_buffer_file_or_scenario_is_refused_by_its_size_not_read() {
    let dir = tempfile::tempdir().unwrap();
    // A 40 GB sparse file: nothing is allocated for it.
    let big = dir.path().join("big.bin");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(40 << 30)
        .unwrap();
    // A glTF with one triangle whose 44-byte buffer is the start of that file: read as 44.
    let gltf = json!({
        "asset": { "version": "2.0" },
        "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 } }] }],
        "accessors": [{ "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                        "min": [0, 0, 0], "max": [0, 0, 0] }],
        "bufferViews": [{ "buffer": 0, "byteLength": 36 }],
        "buffers": [{ "uri": "big.bin", "byteLength": 44 }]
    });
    let g = dir.path().join("tri.gltf");
    write(&g, &gltf);
    let o = shadowbench(&[
        "render",
        "--scene",
        s(&g),
        "--out",
        s(&dir.path().join("r")),
    ]);
    // Its three vertices are zeros: a triangle with no area, refused as a mesh without
    // triangles — by the mesh reader, after reading 44 bytes, not by an allocation of 40 GB.
    assert!(!stderr(&o).contains("memory allocation"), "{}", stderr(&o));
    assert!(o.status.code() == Some(2), "{}", stderr(&o));
    assert!(error_line(&o).contains("tri.gltf"), "{}", stderr(&o));
    // A byteLength over the memory limit is refused naming the buffer.
    let mut huge = gltf.clone();
    huge["buffers"][0]["byteLength"] = json!(40u64 << 30);
    write(&g, &huge);
    let o = shadowbench(&[
        "render",
        "--scene",
        s(&g),
        "--memory-limit",
        "1",
        "--out",
        s(&dir.path().join("r")),
    ]);
    refused(
        &o,
        &[
            "tri.gltf",
            "buffer 0",
            "byteLength 42949672960",
            "memory limit",
        ],
    );
    // A 40 GB scenario is too large, said before reading it.
    let scenario = dir.path().join("huge.json");
    std::fs::File::create(&scenario)
        .unwrap()
        .set_len(40 << 30)
        .unwrap();
    let o = shadowbench(&["run", s(&scenario), "--out", s(&dir.path().join("o"))]);
    refused(&o, &["huge.json", "too large", "40.00 GiB", "memory limit"]);
    // A .npy whose shape declares more than its bytes is refused before allocating.
    let lie = dir.path().join("lie.npy");
    npy(&lie, "<f4", false, &[16384, 16384], &f32_bytes(&[0.5; 4]));
    let o = shadowbench(&[
        "diff",
        s(&lie),
        s(&lie),
        "--out",
        s(&dir.path().join("d.png")),
    ]);
    refused(&o, &["lie.npy", "needs 1073741824 bytes", "holds 16"]);
}

// Fault 6: trailing content.

#[test]
fn content_after_a_scenario_or_machine_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    let one = serde_json::to_string(&tiny()).unwrap();
    for (what, text) in [
        ("garbage", format!("{one}garbage")),
        ("two scenarios", format!("{one}\n{one}\n")),
    ] {
        std::fs::write(&scenario, text).unwrap();
        let o = shadowbench(&["run", s(&scenario), "--out", s(&dir.path().join("o"))]);
        let e = refused(&o, &["s.json", "content after the JSON value", "line "]);
        assert!(!e.contains("malformed"), "{what}: {e}");
    }
    let machine = dir.path().join("m.json");
    let o = shadowbench(&["list", "--machine", "larrabee-24"]);
    std::fs::write(&machine, format!("{}\n}}", stdout(&o))).unwrap();
    let mut v = tiny();
    v["backends"] = json!(["cpu-model"]);
    v["machine"] = json!("m.json");
    write(&scenario, &v);
    let o = shadowbench(&["run", s(&scenario), "--out", s(&dir.path().join("o"))]);
    refused(&o, &["m.json", "content after the JSON value"]);
}

// Fault 7: errors that name the right thing, and exit 2.

#[test]
fn errors_name_the_field_and_bad_input_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    let run = |v: &Value| {
        write(&scenario, v);
        shadowbench(&["run", s(&scenario), "--out", s(&dir.path().join("o"))])
    };
    let mut v = tiny();
    v["params"]["image"] = json!([16, 12, 3]);
    let e = refused(&run(&v), &["$.params.image", "takes 2 values, got 3"]);
    assert!(!e.contains("malformed"), "{e}");
    let mut v = tiny();
    v["camera"] = json!({ "eye": [0, 1, 2, 3], "target": [0, 0, 0], "up": [0, 1, 0] });
    refused(&run(&v), &["$.camera.eye", "takes 3 values, got 4"]);
    std::fs::write(
        dir.path().join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let mut v = tiny();
    v["scene"] = json!({ "objects": [{ "obj": "tri.obj" }] });
    v["params"]["triangles"] = json!(500);
    refused(&run(&v), &["$.params.triangles", "generator"]);
    // diff of a 0-wide array names the array; a float32 mask and an empty array exit 2.
    let png = dir.path().join("d.png");
    let good = dir.path().join("good.npy");
    npy(&good, "<f4", false, &[1, 2], &f32_bytes(&[0.5, 0.5]));
    let zero = dir.path().join("zero.npy");
    npy(&zero, "<f4", false, &[3, 0], &[]);
    let o = shadowbench(&["diff", s(&zero), s(&good), "--out", s(&png)]);
    let e = refused(&o, &["zero.npy", "(3, 0)"]);
    assert!(!e.contains("d.png"), "{e}");
    let empty = dir.path().join("empty.npy");
    npy(&empty, "<f4", false, &[0], &[]);
    refused(
        &shadowbench(&["diff", s(&empty), s(&good), "--out", s(&png)]),
        &["empty.npy", "2-D"],
    );
    let a = dir.path().join("a");
    std::fs::create_dir(&a).unwrap();
    std::fs::copy(&good, a.join("visibility.npy")).unwrap();
    npy(
        &a.join("mask.npy"),
        "<f4",
        false,
        &[1, 2],
        &f32_bytes(&[1.0, 1.0]),
    );
    refused(
        &shadowbench(&["diff", s(&a), s(&good), "--out", s(&png)]),
        &["mask.npy", "uint8", "<f4"],
    );
    // Into a read-only folder: diff and scene export name --out and the file, not a
    // temporary one.
    let ro = dir.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    let mut perm = std::fs::metadata(&ro).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perm, 0o555);
    std::fs::set_permissions(&ro, perm).unwrap();
    // Root writes anywhere; the refusal is only observable as another user.
    let writable = std::fs::write(ro.join("probe"), b"").is_ok();
    if !writable {
        let o = shadowbench(&["diff", s(&good), s(&good), "--out", s(&ro.join("d.png"))]);
        let e = refused(&o, &["--out", "ro/d.png"]);
        assert!(!e.contains(".tmp"), "{e}");
        let o = shadowbench(&[
            "scene",
            "export",
            "box-on-plane",
            "--out",
            s(&ro.join("b.obj")),
        ]);
        let e = refused(&o, &["--out", "ro/b.obj"]);
        assert!(!e.contains(".tmp"), "{e}");
    }
    // Under a file, a folder cannot be made: the same refusal for any user.
    let file = dir.path().join("file");
    std::fs::write(&file, b"").unwrap();
    let o = shadowbench(&["diff", s(&good), s(&good), "--out", s(&file.join("d.png"))]);
    refused(&o, &["--out", "file"]);
    let o = shadowbench(&[
        "scene",
        "export",
        "box-on-plane",
        "--out",
        s(&file.join("b.obj")),
    ]);
    refused(&o, &["--out", "file"]);
    // A bad SHADOWBENCH_FONT is bad input, refused before the sweep.
    write(&scenario, &tiny());
    let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", s(&scenario), "--out", s(&dir.path().join("f"))])
        .env("SHADOWBENCH_FONT", dir.path().join("no-such.ttf"))
        .output()
        .unwrap();
    refused(&o, &["SHADOWBENCH_FONT", "no-such.ttf"]);
    assert!(!dir.path().join("f").join("results.json").exists());
    let o = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", s(&scenario), "--out", s(&dir.path().join("f"))])
        .env("SHADOWBENCH_FONT", &good)
        .output()
        .unwrap();
    refused(&o, &["SHADOWBENCH_FONT", "not a TrueType/OpenType font"]);
}

// Fault 8: writes where they should not go.

#[test]
fn scene_export_never_overwrites_its_input_and_links_inside_out_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("b.obj");
    let text = "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n";
    std::fs::write(&mesh, text).unwrap();
    let o = shadowbench(&["scene", "export", s(&mesh), "--out", s(&mesh)]);
    refused(&o, &["--out", "b.obj", "read from"]);
    assert_eq!(std::fs::read_to_string(&mesh).unwrap(), text);
    // Through a scenario: its objects' files are inputs too, under another spelling.
    let scenario = dir.path().join("s.json");
    let mut v = tiny();
    v["scene"] = json!({ "objects": [{ "obj": "b.obj" }] });
    write(&scenario, &v);
    let other = dir.path().join("sub").join("..").join("b.obj");
    let o = shadowbench(&["scene", "export", s(&scenario), "--out", s(&other)]);
    refused(&o, &["--out", "b.obj"]);
    let o = shadowbench(&[
        "scene",
        "export",
        s(&scenario),
        "--out",
        s(&dir.path().join("e.obj")),
        "--scenario",
        s(&scenario),
    ]);
    refused(&o, &["--scenario", "s.json"]);
    assert_eq!(std::fs::read_to_string(&mesh).unwrap(), text);
    // A link planted inside --out: refused before anything is written through it.
    let out = dir.path().join("out");
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::create_dir_all(&elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("images")).unwrap();
    write(&scenario, &tiny());
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
    refused(&o, &["--out", "images", "symbolic link", "elsewhere"]);
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
    assert!(!out.join("results.json").exists());
}

// Fault 9: readers that refused valid input.

#[test]
fn valid_ply_and_gltf_variants_are_read_or_named() {
    let dir = tempfile::tempdir().unwrap();
    let header = |n_v: usize, element: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex {n_v}\nproperty float x\nproperty float y\n\
             property float z\n{element}end_header\n"
        )
    };
    // A unit square at y = 0 in leading-dot and trailing-dot floats.
    let dots = dir.path().join("dots.ply");
    std::fs::write(
        &dots,
        header(
            4,
            "element face 1\nproperty list uchar int vertex_indices\n",
        ) + "-.5 0 -.5\n.5 0. -.5\n.5 0 .5\n-.5 0 .5\n4 0 1 2 3\n",
    )
    .unwrap();
    let mesh = shadowbench::scene::load::load_mesh(&dots, None)
        .unwrap()
        .mesh;
    let xs: Vec<f32> = mesh.positions.iter().map(|p| p.x).collect();
    assert_eq!(xs, [-0.5, 0.5, 0.5, -0.5]);
    assert_eq!(mesh.triangles.len(), 2);
    // The same square as one triangle strip: 0 1 3 2, with a -1 end.
    let strip = dir.path().join("strip.ply");
    std::fs::write(
        &strip,
        header(
            4,
            "element tristrips 1\nproperty list int int vertex_indices\n",
        ) + "-0.5 0 -0.5\n0.5 0 -0.5\n0.5 0 0.5\n-0.5 0 0.5\n5 0 1 3 2 -1\n",
    )
    .unwrap();
    let m = shadowbench::scene::load::load_mesh(&strip, None)
        .unwrap()
        .mesh;
    assert_eq!(m.triangles.len(), 2);
    let area: f32 = (0..2)
        .map(|t| {
            let [a, b, c] = m.triangle(t);
            (b - a).cross(c - a).length() / 2.0
        })
        .sum();
    assert!((area - 1.0).abs() < 1e-6, "{area}");
    // Both strip triangles face the same way (the strip's winding kept).
    let n: Vec<f32> = (0..2).map(|t| m.face_normal(t).y.signum()).collect();
    assert_eq!(n[0], n[1]);
    // No faces or strips at all: a point cloud.
    let cloud = dir.path().join("cloud.ply");
    std::fs::write(&cloud, header(1, "") + "0 0 0\n").unwrap();
    let e = shadowbench::scene::load::load_mesh(&cloud, None).unwrap_err();
    assert!(e.to_string().contains("point cloud"), "{e}");
    // A Draco-compressed glTF names the extension.
    let draco = dir.path().join("draco.gltf");
    write(
        &draco,
        &json!({
            "asset": { "version": "2.0" },
            "extensionsUsed": ["KHR_draco_mesh_compression"],
            "extensionsRequired": ["KHR_draco_mesh_compression"],
            "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0 },
                "extensions": { "KHR_draco_mesh_compression": { "bufferView": 0,
                    "attributes": { "POSITION": 0 } } } }] }],
            "accessors": [{ "componentType": 5126, "count": 3, "type": "VEC3" }],
            "bufferViews": [{ "buffer": 0, "byteLength": 4 }],
            "buffers": [{ "byteLength": 4, "uri": "data:application/octet-stream;base64,AAAAAA==" }]
        }),
    );
    let o = shadowbench(&[
        "render",
        "--scene",
        s(&draco),
        "--out",
        s(&dir.path().join("r")),
    ]);
    refused(
        &o,
        &["draco.gltf", "KHR_draco_mesh_compression", "not supported"],
    );
}

// Fault 12: the progress counter counts what runs.

#[test]
fn the_progress_counter_counts_the_runs_that_run() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    // Triangle targets the generator meets with one mesh: their runs are one run.
    let mut v = tiny();
    v["scene"] = json!({ "generator": "sphere-on-plane" });
    v["algorithms"] = json!(["hard_shadow_map", "pcss"]);
    v["sweep"] = json!({ "triangles": [1000, 1001, 1002, 4000] });
    write(&scenario, &v);
    let out = dir.path().join("out");
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let runs = results(&out).len();
    let e = stderr(&o);
    let planned = e.lines().find(|l| l.starts_with("planned")).unwrap();
    assert!(
        planned.starts_with(&format!("planned {runs} runs")),
        "{planned} ({runs} runs)"
    );
    let lines: Vec<String> = stdout(&o)
        .lines()
        .filter(|l| l.starts_with('['))
        .map(str::to_string)
        .collect();
    assert_eq!(lines.len(), runs, "{}", stdout(&o));
    assert!(
        lines
            .last()
            .unwrap()
            .starts_with(&format!("[{runs}/{runs} ")),
        "{}",
        lines.last().unwrap()
    );
}

// Fault 11: a machine without Vulkan (GL is not built in: Mesa's GL cannot answer instead).

/// `shadowbench ARGS` with no Vulkan driver to be found.
fn without_vulkan(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(args)
        .env("VK_ICD_FILENAMES", "/nonexistent")
        .env("VK_DRIVER_FILES", "/nonexistent")
        .env_remove("WGPU_BACKEND")
        .env_remove("SHADOWBENCH_ADAPTER")
        .env_remove("SHADOWBENCH_REQUIRE_GPU")
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap()
}

#[test]
fn without_vulkan_list_render_and_run_agree_on_the_adapter_and_nothing_fails() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    let mut v = tiny();
    v["algorithms"] = json!(["hard_shadow_map", "pcss"]);
    v["backends"] = json!(["cpu-native", "wgpu"]);
    write(&scenario, &v);
    let out = dir.path().join("out");
    let o = without_vulkan(&["run", s(&scenario), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let note = stderr(&o)
        .lines()
        .find(|l| l.starts_with("note: skipping the wgpu execution: "))
        .unwrap_or_else(|| panic!("{}", stderr(&o)))
        .trim_start_matches("note: skipping the wgpu execution: ")
        .to_string();
    // Only the CPU runs, and none failed.
    let runs = results(&out);
    assert_eq!(runs.len(), 2);
    assert!(runs
        .iter()
        .all(|r| r["backend"] == "cpu-native" && r["failure"].is_null()));
    // `list` marks no adapter as used and says why, in the same words.
    let l = without_vulkan(&["list"]);
    assert!(l.status.success(), "{}", stderr(&l));
    let listed = stdout(&l);
    assert!(
        !listed.lines().any(|x| x.trim_start().starts_with("* ")),
        "{listed}"
    );
    assert!(listed.contains(&note), "{note}\n{listed}");
    // GL is not built in (it could run none of the passes): no GL adapter is listed.
    assert!(!listed.contains(", gl, "), "{listed}");
    // `render` on wgpu fails with the same reason.
    let r = without_vulkan(&[
        "render",
        "--algorithm",
        "hard_shadow_map",
        "--backend",
        "wgpu",
        "--out",
        s(&dir.path().join("r")),
    ]);
    assert_eq!(r.status.code(), Some(1), "{}", stderr(&r));
    assert!(error_line(&r).contains(&note), "{note}\n{}", stderr(&r));
}
