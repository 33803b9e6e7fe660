//! Scenes from files: OBJ polygons triangulated on their plane, the public tinyobjloader corpus,
//! glTF and PLY against the same geometry in OBJ, the export round trip of every generator, and
//! the coordinate range.

use std::path::{Path, PathBuf};

use glam::Vec3;
use shadowbench::algorithms::{self, Backend, ExecContext};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scenario::{framed_scene, Loaded, ScenePoint};
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::load::load_mesh;
use shadowbench::scene::{export, Object, Role, Scene};
use shadowbench::visibility::VisibilityBuffer;

const IMAGE: [u32; 2] = [64, 48];

fn frame(scene: Scene) -> Frame {
    let params = RunParams::of_scene(&scene, IMAGE, 64, 16);
    Frame::new(scene, params)
}

fn run(id: &str, f: &Frame) -> VisibilityBuffer {
    let ctx = ExecContext {
        reference_samples: 16,
        ..ExecContext::default()
    };
    algorithms::run(id, Backend::CpuNative, f, &ctx)
        .unwrap_or_else(|e| panic!("{id}: {e}"))
        .visibility
}

/// A file's mesh as the only object of a framed scene (as `render --scene FILE` makes it).
fn framed_file(path: &Path) -> Frame {
    let mesh = load_mesh(path, None).unwrap_or_else(|e| panic!("{e}")).mesh;
    let (scene, _) = framed_scene(
        vec![Object {
            name: "file".into(),
            mesh,
            role: Role::BOTH,
        }],
        true,
    );
    frame(scene)
}

/// The U-shaped plate of the issue: an 8-vertex concave face 1 above the ground, and the same
/// plate split by hand into eight triangles (left post, bottom bar, right post, sharing the
/// notch's corners so the plate stays watertight).
#[test]
fn concave_face_plate_renders_as_the_hand_split_plate() {
    let dir = tempfile::tempdir().unwrap();
    let ring = "v 0 1 0\nv 3 1 0\nv 3 1 -2\nv 2 1 -2\nv 2 1 -1\nv 1 1 -1\nv 1 1 -2\nv 0 1 -2\n";
    let floor = "v -3 0 3\nv 6 0 3\nv 6 0 -5\nv -3 0 -5\n";
    let concave = dir.path().join("concave.obj");
    std::fs::write(
        &concave,
        format!("{ring}{floor}f 1 2 3 4 5 6 7 8\nf 9 10 11 12\n"),
    )
    .unwrap();
    let split = dir.path().join("split.obj");
    std::fs::write(
        &split,
        format!(
            "{ring}{floor}v 1 1 0\nv 2 1 0\n\
             f 1 13 6\nf 1 6 7\nf 1 7 8\nf 13 14 5\nf 13 5 6\nf 14 2 3\nf 14 3 5\nf 5 3 4\n\
             f 9 10 11 12\n"
        ),
    )
    .unwrap();
    // Looking down at the floor under the plate, the light above the notch: the U's shadow,
    // notch included, fills much of the image.
    let scene_of = |path: &Path| {
        let mesh = load_mesh(path, None).unwrap().mesh;
        frame(Scene {
            name: "plate".into(),
            objects: vec![Object {
                name: "plate".into(),
                mesh,
                role: Role::BOTH,
            }],
            camera: shadowbench::scene::Camera {
                eye: Vec3::new(1.5, 6.0, -7.0),
                target: Vec3::new(1.5, 0.0, -1.0),
                up: Vec3::Y,
                fov_y_deg: 40.0,
            },
            light: shadowbench::scene::Light::Sphere {
                center: Vec3::new(1.5, 5.0, -1.5),
                radius: 0.3,
            },
            light_texture: None,
        })
    };
    let (a, b) = (scene_of(&concave), scene_of(&split));
    let (ra, rb) = (run("reference", &a), run("reference", &b));
    let mask = a.gbuffer.mask();
    let m = shadowbench::metrics::compare(&ra, &rb, &mask);
    println!("reference, concave against split: {m:?}");
    assert!(m.shadow_pixels > 150, "the shadow is in view: {m:?}");
    assert!(
        m.mae.unwrap() < 1e-4 && m.frac_over_0_1.unwrap() < 1e-3,
        "reference differs: {m:?}"
    );
    // Soft shadow volumes (whose silhouettes a fan's backward triangles corrupted) agree too.
    let (sa, sb) = (run("soft_shadow_volume", &a), run("soft_shadow_volume", &b));
    let m = shadowbench::metrics::compare(&sa, &rb, &mask);
    let m_split = shadowbench::metrics::compare(&sb, &rb, &mask);
    println!("soft_shadow_volume: concave {m:?}, split {m_split:?}");
    assert!(
        m.mae_shadow.unwrap() < m_split.mae_shadow.unwrap() + 0.01,
        "concave {m:?} vs split {m_split:?}"
    );
}

/// Where the tinyobjloader corpus lies: `SHADOWBENCH_OBJ_CORPUS` when set, else beside the
/// repository (`../shared/field/tinyobjloader-models`), as in a checkout and in CI.
fn corpus() -> Option<PathBuf> {
    let dir = std::env::var_os("SHADOWBENCH_OBJ_CORPUS")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("..")
                .join("shared")
                .join("field")
                .join("tinyobjloader-models")
        });
    dir.is_dir().then_some(dir)
}

/// The total area of an OBJ's faces from the text itself (an independent reading: positions
/// x y z of `v` lines, `f` references, each polygon's area as half its Newell vector's length),
/// and the part of it in non-planar polygons (whose triangles' area any triangulation makes
/// somewhat larger than the Newell area).
fn obj_face_area(text: &str) -> (f64, f64) {
    let mut v: Vec<[f64; 3]> = Vec::new();
    let (mut area, mut bent) = (0.0, 0.0);
    for line in text.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first() {
            Some(&"v") => v.push([w[1], w[2], w[3]].map(|s| s.parse().unwrap_or(f64::NAN))),
            Some(&"f") => {
                let p: Vec<[f64; 3]> = w[1..]
                    .iter()
                    .map(|r| {
                        let i: i64 = r.split('/').next().unwrap().parse().unwrap();
                        v[if i < 0 { v.len() as i64 + i } else { i - 1 } as usize]
                    })
                    .collect();
                let mut n = [0.0; 3];
                for k in 0..p.len() {
                    let (a, b) = (p[k], p[(k + 1) % p.len()]);
                    n[0] += a[1] * b[2] - a[2] * b[1];
                    n[1] += a[2] * b[0] - a[0] * b[2];
                    n[2] += a[0] * b[1] - a[1] * b[0];
                }
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                area += 0.5 * len;
                // Planar: every vertex within 1e-6 of the size of the first vertex's plane.
                let size = p.iter().map(|q| dist(q, &p[0])).fold(0.0, f64::max);
                let planar = len == 0.0
                    || p.iter().all(|q| {
                        let d: f64 = (0..3).map(|k| (q[k] - p[0][k]) * n[k] / len).sum();
                        d.abs() <= 1e-6 * size
                    });
                if !planar {
                    bent += 0.5 * len;
                }
            }
            _ => {}
        }
    }
    (area, bent)
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn mesh_area(m: &shadowbench::scene::Mesh) -> f64 {
    (0..m.triangles.len())
        .map(|t| m.face_normal(t).as_dvec3().length() * 0.5)
        .sum()
}

/// Every file of the public corpus loads with the geometry its text describes, or gets an
/// error that names it; none panics. Known answers: the w-component cube is the 2-unit cube
/// (diagonal 2√3 ≈ 3.46, not ≈ 29 as when w divides), the Cornell box has one triangle per
/// polygon vertex beyond two (36), the files of broken indices are refused with their line.
#[test]
fn tinyobjloader_corpus() {
    let Some(dir) = corpus() else {
        println!(
            "skipped: no ../shared/field/tinyobjloader-models beside the repository \
             (or set SHADOWBENCH_OBJ_CORPUS)"
        );
        return;
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    files.sort();
    assert!(files.len() > 30, "corpus has {} OBJ files", files.len());
    let (mut loaded, mut refused) = (0, 0);
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let result = std::panic::catch_unwind(|| load_mesh(path, None))
            .unwrap_or_else(|_| panic!("{name}: panicked"));
        match result {
            Ok(f) => {
                loaded += 1;
                let text = String::from_utf8_lossy(&std::fs::read(path).unwrap()).into_owned();
                let ((want, bent), got) = (obj_face_area(&text), mesh_area(&f.mesh));
                assert!(
                    got >= want * (1.0 - 1e-4) && got - want <= 1e-4 * want + 0.05 * bent,
                    "{name}: faces' area {want} ({bent} non-planar), triangles' area {got}"
                );
                for w in &f.warnings {
                    assert!(w.contains(&name), "{name}: warning without the file: {w}");
                }
            }
            Err(e) => {
                refused += 1;
                let msg = e.to_string();
                assert!(msg.contains(&name), "{name}: error without the file: {msg}");
            }
        }
    }
    println!("corpus: {loaded} loaded, {refused} refused");
    let cube = load_mesh(&dir.join("cube-vertex-w-component.obj"), None).unwrap();
    assert!((cube.mesh.bounds().diagonal() - 2.0 * 3f32.sqrt()).abs() < 1e-5);
    let cornell = load_mesh(&dir.join("cornell_box.obj"), None).unwrap();
    let text = std::fs::read_to_string(dir.join("cornell_box.obj")).unwrap();
    let fan_count: usize = text
        .lines()
        .filter(|l| l.starts_with("f "))
        .map(|l| l.split_whitespace().count() - 3)
        .sum();
    assert_eq!(cornell.mesh.triangles.len(), fan_count);
    assert_eq!(fan_count, 36);
    for (file, want) in [
        (
            "invalid-relative-vertex-index.obj",
            "line 1: relative vertex index -4",
        ),
        ("issue-140-zero-face-idx.obj", "vertex index 0"),
        ("test-nan.obj", "line 14: vertex coordinate '1.#IND'"),
        ("issue-356-leading-spaces-newmtl.obj", "no triangles"),
        ("line-prim.obj", "no triangles"),
        ("points-prim.obj", "no triangles"),
    ] {
        let e = load_mesh(&dir.join(file), None).unwrap_err().to_string();
        assert!(e.contains(want), "{file}: {e} (wanted {want})");
    }
    let w = load_mesh(&dir.join("line-prim.obj"), None).unwrap_err();
    assert!(w.to_string().contains("line-prim.obj"));
    let m = load_mesh(&dir.join("mtllib-multiple-files-issue-112.obj"), None).unwrap();
    assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
    assert!(m.warnings[0].contains("'invalid-file-aaa.mtl', 'invalid-file-bbb.mtl'"));
}

/// A box of side 1 centred at the origin as 8 positions and 12 triangles (outward winding).
fn unit_box() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let p: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { -0.5 } else { 0.5 },
                if i & 2 == 0 { -0.5 } else { 0.5 },
                if i & 4 == 0 { -0.5 } else { 0.5 },
            )
        })
        .collect();
    let t = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (p, t)
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// The same geometry as glTF (a node hierarchy with translation, scale and a 90° rotation
/// matrix, an external and an embedded buffer, indexed and non-indexed primitives, quantized
/// positions, and a line primitive to skip), as PLY (ASCII, binary little and big endian) and as
/// OBJ with the transforms applied by hand: identical reference images.
#[test]
fn gltf_and_ply_shadow_like_the_same_obj() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = unit_box();
    // Hand-transformed geometry: box A = parent(translate (0,1,0), scale 2) of the unit box;
    // box B = A's child with matrix rot90 about y then translate (1,0,0) (in A's frame), and
    // box C = the quantized box (corners ±1 as i16 ±32767) under scale 0.25 at (-2, 0.5, 1).
    let a = |q: Vec3| q * 2.0 + Vec3::Y;
    let b = |q: Vec3| a(Vec3::new(q.z, q.y, -q.x) + Vec3::X);
    let c = |q: Vec3| q * 2.0 * 0.25 + Vec3::new(-2.0, 0.5, 1.0);
    let ground = [
        Vec3::new(-4.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, -4.0),
        Vec3::new(-4.0, 0.0, -4.0),
    ];
    let ground_tris = [[0u32, 1, 2], [0, 2, 3]];
    // OBJ and PLY: the placed parts in the glTF's node order (A, its child B, ground, C), so
    // the triangle lists are the same, not only the same sets.
    let mut obj = String::new();
    let mut ply_v: Vec<Vec3> = Vec::new();
    let mut ply_f: Vec<[u32; 3]> = Vec::new();
    let boxes = |place: &dyn Fn(Vec3) -> Vec3, v: &mut Vec<Vec3>, f: &mut Vec<[u32; 3]>| {
        let base = v.len() as u32;
        v.extend(p.iter().map(|q| place(*q)));
        f.extend(t.iter().map(|tri| tri.map(|i| i + base)));
    };
    boxes(&a, &mut ply_v, &mut ply_f);
    boxes(&b, &mut ply_v, &mut ply_f);
    let base = ply_v.len() as u32;
    ply_v.extend(ground);
    ply_f.extend(ground_tris.iter().map(|f| f.map(|i| i + base)));
    boxes(&c, &mut ply_v, &mut ply_f);
    for w in &ply_v {
        obj += &format!("v {} {} {}\n", w.x, w.y, w.z);
    }
    for f in &ply_f {
        obj += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    std::fs::write(dir.path().join("scene.obj"), &obj).unwrap();

    // glTF: buffer 0 (external .bin): box positions f32, box indices u16, ground positions
    // (non-indexed, 6 vertices), line indices; buffer 1 (data URI): quantized box positions.
    let mut bin: Vec<u8> = Vec::new();
    for q in &p {
        for v in q.to_array() {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let idx_at = bin.len();
    for f in &t {
        for i in f {
            bin.extend_from_slice(&(*i as u16).to_le_bytes());
        }
    }
    let ground_at = bin.len();
    for f in ground_tris {
        for i in f {
            for v in ground[i as usize].to_array() {
                bin.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    let end = bin.len();
    std::fs::write(dir.path().join("scene.bin"), &bin).unwrap();
    let mut quant: Vec<u8> = Vec::new();
    for q in &p {
        for v in q.to_array() {
            quant.extend_from_slice(&((v * 2.0 * 32767.0) as i16).to_le_bytes());
        }
        quant.extend_from_slice(&[0, 0]); // 4-byte aligned stride of 8
    }
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "scene": 0,
        "scenes": [{"nodes": [0, 2, 3]}],
        "nodes": [
            {"name": "A", "mesh": 0, "translation": [0, 1, 0], "scale": [2, 2, 2], "children": [1]},
            {"name": "B", "mesh": 0, "matrix": [0,0,-1,0, 0,1,0,0, 1,0,0,0, 1,0,0,1]},
            {"name": "ground", "mesh": 1},
            {"name": "C", "mesh": 2, "translation": [-2, 0.5, 1], "scale": [0.25, 0.25, 0.25]}
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
            {"primitives": [{"attributes": {"POSITION": 2}},
                            {"attributes": {"POSITION": 2}, "mode": 1}]},
            {"primitives": [{"attributes": {"POSITION": 3}, "indices": 1}]}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [-0.5, -0.5, -0.5], "max": [0.5, 0.5, 0.5]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 6, "type": "VEC3",
             "min": [-4, 0, -4], "max": [4, 0, 4]},
            {"bufferView": 3, "componentType": 5122, "normalized": true, "count": 8, "type": "VEC3",
             "min": [-32767, -32767, -32767], "max": [32767, 32767, 32767]}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": idx_at},
            {"buffer": 0, "byteOffset": idx_at, "byteLength": ground_at - idx_at},
            {"buffer": 0, "byteOffset": ground_at, "byteLength": end - ground_at},
            {"buffer": 1, "byteOffset": 0, "byteLength": quant.len(), "byteStride": 8}
        ],
        "buffers": [
            {"uri": "scene.bin", "byteLength": end},
            {"uri": format!("data:application/octet-stream;base64,{}", base64(&quant)),
             "byteLength": quant.len()}
        ]
    });
    std::fs::write(
        dir.path().join("scene.gltf"),
        serde_json::to_vec(&gltf).unwrap(),
    )
    .unwrap();

    // PLY: the same vertices and triangles, in three encodings.
    let header = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\ncomment made by a test\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            ply_v.len(),
            ply_f.len()
        )
    };
    let mut ascii = header("ascii");
    for v in &ply_v {
        ascii += &format!("{} {} {}\n", v.x, v.y, v.z);
    }
    for f in &ply_f {
        ascii += &format!("3 {} {} {}\n", f[0], f[1], f[2]);
    }
    std::fs::write(dir.path().join("ascii.ply"), ascii).unwrap();
    for (name, big) in [("le.ply", false), ("be.ply", true)] {
        let mut bytes = header(if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        })
        .into_bytes();
        let mut put = |b4: [u8; 4]| bytes.extend_from_slice(&b4);
        for v in &ply_v {
            for c in v.to_array() {
                put(if big {
                    c.to_be_bytes()
                } else {
                    c.to_le_bytes()
                });
            }
        }
        for f in &ply_f {
            bytes.push(3);
            for i in f {
                let i = *i as i32;
                bytes.extend_from_slice(&if big {
                    i.to_be_bytes()
                } else {
                    i.to_le_bytes()
                });
            }
        }
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }

    let want = framed_file(&dir.path().join("scene.obj"));
    let reference = run("reference", &want);
    let gltf_file = load_mesh(&dir.path().join("scene.gltf"), None).unwrap();
    assert_eq!(gltf_file.warnings.len(), 1, "{:?}", gltf_file.warnings);
    assert!(
        gltf_file.warnings[0].contains("Lines"),
        "{:?}",
        gltf_file.warnings
    );
    for file in ["scene.gltf", "ascii.ply", "le.ply", "be.ply"] {
        let got = framed_file(&dir.path().join(file));
        assert_eq!(
            got.scene.triangle_count(),
            want.scene.triangle_count(),
            "{file}"
        );
        assert_eq!(got.scene.camera, want.scene.camera, "{file}: bounds differ");
        let r = run("reference", &got);
        assert!(r.data == reference.data, "{file}: reference image differs");
    }
    // A node by name: B alone (with no children) is one box.
    let b_only = load_mesh(&dir.path().join("scene.gltf"), Some("B")).unwrap();
    assert_eq!(b_only.mesh.triangles.len(), 12);
    let bb = b_only.mesh.bounds();
    assert!((bb.min - Vec3::new(1.0, 0.0, -1.0)).abs().max_element() < 1e-6);
    // Without its .bin the error names the file that is missing.
    std::fs::remove_file(dir.path().join("scene.bin")).unwrap();
    let e = load_mesh(&dir.path().join("scene.gltf"), None).unwrap_err();
    assert!(
        e.to_string().contains("scene.bin") && e.to_string().contains("not found"),
        "{e}"
    );
}

/// `scene export` of every built-in generator, loaded back through the scenario it writes
/// (each part an object with its role, the camera and light, no added ground), renders a
/// bit-identical reference image; for OBJ and for binary glTF.
#[test]
fn export_round_trip_of_every_generator() {
    let dir = tempfile::tempdir().unwrap();
    for g in generators::GENERATORS {
        let scene = g.build(&GeneratorParams::default());
        let want = frame(scene.clone());
        let reference = run("reference", &want);
        for ext in ["obj", "glb"] {
            let mesh = dir.path().join(format!("{}.{ext}", g.name));
            let json = dir.path().join(format!("{}-{ext}.json", g.name));
            export::write_scene(&scene, &mesh, "--out").unwrap();
            let s = shadowbench::scenario::export_scenario(&scene, &mesh, &json).unwrap();
            std::fs::write(&json, serde_json::to_vec_pretty(&s).unwrap()).unwrap();
            let l = Loaded::from_file(&json).unwrap_or_else(|e| panic!("{}: {e}", g.name));
            let back = l.build_scene(
                ScenePoint {
                    triangles: None,
                    mesh: None,
                    occluder_height: None,
                    occluder_offset: None,
                },
                None,
            );
            assert_eq!(back.objects.len(), scene.objects.len(), "{}", g.name);
            for (o, p) in scene.objects.iter().zip(&back.objects) {
                assert_eq!((&o.name, o.role), (&p.name, p.role), "{}", g.name);
                assert_eq!(o.mesh.triangles.len(), p.mesh.triangles.len());
            }
            let got = frame(back);
            let r = run("reference", &got);
            assert!(
                r.data == reference.data,
                "{} via .{ext}: reference image differs",
                g.name
            );
        }
    }
}

/// The 10^20-scaled mesh of the issue, through the command line: exit 2 and one line naming the
/// object and its extent, before anything is built.
#[test]
fn huge_coordinates_are_an_input_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let scenario = dir.path().join("huge.json");
    std::fs::write(
        &scenario,
        r#"{"scene": {"objects": [{"obj": "tri.obj", "name": "shard", "scale": 1e20}]},
            "algorithms": ["reference"], "backends": ["cpu-native"]}"#,
    )
    .unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", scenario.to_str().unwrap(), "--out"])
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("'shard'"), "{stderr}");
    assert!(stderr.contains("1.000e20"), "{stderr}");
    assert!(stderr.contains("$.scene.objects[0]"), "{stderr}");
    assert!(!dir.path().join("out").join("results.json").exists());

    // Vertices near 3e38 in the file itself, given to render.
    let near_max = dir.path().join("near-max.obj");
    std::fs::write(&near_max, "v 0 0 0\nv 3e38 0 0\nv 0 3e38 0\nf 1 2 3\n").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["render", "--scene", near_max.to_str().unwrap(), "--out"])
        .arg(dir.path().join("render"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("near-max.obj") && stderr.contains("3.000e38"),
        "{stderr}"
    );
}

/// `render --scene FILE` prints what it added around the mesh, and run.json carries it with the
/// reader's warnings (here a missing material library).
#[test]
fn render_of_a_mesh_file_reports_what_it_added() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("quad.obj");
    std::fs::write(
        &obj,
        "mtllib gone.mtl\nv 0 1 0\nv 1 1 0\nv 1 1 -1\nv 0 1 -1\nf 1 2 3 4\n",
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["render", "--scene", obj.to_str().unwrap()])
        .args(["--image", "16x12", "--samples", "4", "--out"])
        .arg(&out_dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    for want in ["added ground plane", "added camera", "added light"] {
        assert!(stdout.contains(want), "{want}: {stdout}");
    }
    assert!(stderr.contains("'gone.mtl'"), "{stderr}");
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("run.json")).unwrap()).unwrap();
    let framing = &record["framing"];
    // The quad spans 1 × 1 at y = 1: its diagonal √2 sets the ground's size (1.5·d) and height.
    let d = 2f64.sqrt();
    let size = framing["ground"]["size"].as_f64().unwrap();
    assert!((size - 1.5 * d).abs() < 1e-5, "{framing}");
    let y = framing["ground"]["center"][1].as_f64().unwrap();
    assert!((y - (1.0 - 0.02 * d)).abs() < 1e-5, "{framing}");
    assert!(framing["camera"]["eye"].is_array() && framing["light"].is_object());
    let warnings = record["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("gone.mtl")),
        "{record}"
    );
}

/// `scene export` refuses a `--scenario` that is the `--out` file (it would replace the mesh
/// it points at) and an `--out` whose folder cannot be made, each naming the flag, exit 2,
/// nothing written.
#[test]
fn scene_export_refuses_a_scenario_on_its_mesh_and_an_out_under_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("a.obj");
    let m = mesh.to_str().unwrap();
    let o = super::common::shadowbench(&[
        "scene",
        "export",
        "sphere-on-plane",
        "--out",
        m,
        "--scenario",
        m,
    ]);
    let e = super::common::stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("--scenario") && e.contains("a.obj"), "{e}");
    assert!(!mesh.exists());
    // The same file by another spelling, and in a folder not made yet.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    for (out, scenario) in [
        (mesh.clone(), sub.join("..").join("a.obj")),
        (
            dir.path().join("new").join("b.obj"),
            dir.path().join("new").join(".").join("b.obj"),
        ),
    ] {
        let (o_s, s_s) = (out.to_str().unwrap(), scenario.to_str().unwrap());
        let args = [
            "scene",
            "export",
            "sphere-on-plane",
            "--out",
            o_s,
            "--scenario",
            s_s,
        ];
        let o = super::common::shadowbench(&args);
        assert_eq!(o.status.code(), Some(2), "{}", super::common::stderr(&o));
        assert!(!out.exists());
    }
    let file = dir.path().join("afile");
    std::fs::write(&file, "x").unwrap();
    let under = file.join("a.obj");
    let o = super::common::shadowbench(&[
        "scene",
        "export",
        "sphere-on-plane",
        "--out",
        under.to_str().unwrap(),
    ]);
    let e = super::common::stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("--out") && e.contains("afile"), "{e}");
    // A scenario under a regular file: refused naming --scenario before the mesh is written.
    let ok = dir.path().join("ok.obj");
    let under = file.join("s.json");
    let args = [
        "scene",
        "export",
        "sphere-on-plane",
        "--out",
        ok.to_str().unwrap(),
    ];
    let o =
        super::common::shadowbench(&[&args[..], &["--scenario", under.to_str().unwrap()]].concat());
    let e = super::common::stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("--scenario") && e.contains("afile"), "{e}");
    assert!(!ok.exists());
}
