//! Executions that agree: the wgpu execution's default pipelines against the cpu-model on
//! meshes as they come.
//!
//! The unit cube: a closed cube of 12 triangles, its base 0.5 above the origin, placed as an
//! `objects` scene is (a ground under it, the framing's camera and sphere light), 160×120. Its
//! straight top edge is seen straight on, so a miscounted edge shows as a whole row of pixels:
//! on the raster pipelines the depth test at the pixel's centre against the shaded point, which
//! is moved off its surface, counted the quad of the cube's front top edge on some light
//! samples along a whole row (231 pixels of accum_hard off by 5/16). Bounds: accum_hard (16
//! samples) differs from cpu-model by more than one sample's share (1/16) on at most 0.1% of
//! the pixels and by more than 0.45 nowhere; soft_shadow_volume by more than 0.45 nowhere and
//! by more than 0.1 on at most 0.1%.

use glam::Vec3;
use shadowbench::algorithms::Backend;
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scenario::framed_scene;
use shadowbench::scene::{Mesh, Object, Role};
use shadowbench::visibility::VisibilityBuffer;

use super::common::run_on;
use super::gpu_check::have_gpu;

/// How two images of one frame differ over the pixels that see a surface.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Difference {
    /// Pixels compared.
    pub pixels: usize,
    pub mae: f64,
    pub max: f64,
    /// Pixels off by more than 0.1 and by more than 0.45.
    pub over_0_1: usize,
    pub over_0_45: usize,
    /// Pixels off by more than the threshold given to [`Difference::of`].
    pub over: usize,
}

impl Difference {
    /// `a` against `b` over `mask`, counting the pixels off by more than `threshold` apart.
    pub fn of(a: &VisibilityBuffer, b: &VisibilityBuffer, mask: &[bool], threshold: f64) -> Self {
        assert_eq!(a.data.len(), b.data.len(), "image sizes differ");
        let mut d = Difference::default();
        let mut sum = 0.0;
        for ((&x, &y), &m) in a.data.iter().zip(&b.data).zip(mask) {
            if !m {
                continue;
            }
            let e = (f64::from(x) - f64::from(y)).abs();
            assert!(e.is_finite(), "a pixel is not finite");
            d.pixels += 1;
            sum += e;
            d.max = d.max.max(e);
            d.over_0_1 += usize::from(e > 0.1);
            d.over_0_45 += usize::from(e > 0.45);
            d.over += usize::from(e > threshold);
        }
        d.mae = sum / d.pixels.max(1) as f64;
        d
    }
}

/// The closed unit cube of 12 triangles, wound outwards, over [0, 1] × [0.5, 1.5] × [0, 1].
pub fn unit_cube() -> Mesh {
    let positions = (0..8)
        .map(|i| {
            let bit = |k: u32| ((i >> k) & 1) as f32;
            Vec3::new(bit(0), 0.5 + bit(1), bit(2))
        })
        .collect();
    // Quads counter-clockwise seen from outside; vertex i has x = bit 0, y = bit 1, z = bit 2.
    let quads = [
        [0, 1, 5, 4], // y = 0.5 (−y)
        [2, 6, 7, 3], // y = 1.5 (+y)
        [0, 2, 3, 1], // z = 0 (−z)
        [4, 5, 7, 6], // z = 1 (+z)
        [0, 4, 6, 2], // x = 0 (−x)
        [1, 3, 7, 5], // x = 1 (+x)
    ];
    let triangles = quads
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect();
    Mesh {
        positions,
        triangles,
    }
}

/// `mesh` as the one object of an `objects` scene with `"ground": true` and the framing's
/// camera and light, at `image`.
pub fn framed_frame(name: &str, mesh: Mesh, image: [u32; 2]) -> Frame {
    let object = Object {
        name: name.into(),
        mesh,
        role: Role::BOTH,
    };
    let (mut scene, _) = framed_scene(vec![object], true);
    scene.name = name.into();
    let params = RunParams::of_scene(&scene, image, 512, 32);
    Frame::new(scene, params)
}

/// The cube is wound outwards: every triangle's normal points away from its centre.
#[test]
fn the_unit_cube_is_closed_and_wound_outwards() {
    let cube = unit_cube();
    let centre = Vec3::new(0.5, 1.0, 0.5);
    for t in 0..cube.triangles.len() {
        let [a, b, c] = cube.triangle(t);
        assert!((b - a).cross(c - a).dot(a - centre) > 0.0, "triangle {t}");
    }
    let frame = framed_frame("unit_cube", cube, [16, 12]);
    assert_eq!(frame.occluder_edges.open(), 0);
}

#[test]
fn the_unit_cube_on_the_default_wgpu_pipelines_agrees_with_the_cpu_model() {
    if !have_gpu() {
        return;
    }
    let frame = framed_frame("unit_cube", unit_cube(), [160, 120]);
    let mask = frame.gbuffer.mask();
    let cases = [
        (
            "accum_hard",
            serde_json::json!({ "samples": 16 }),
            1.0 / 16.0,
        ),
        ("soft_shadow_volume", serde_json::Value::Null, 0.1),
    ];
    for (id, options, share) in cases {
        let model = run_on(Backend::CpuModel, &frame, id, options.clone());
        let gpu = run_on(Backend::Wgpu, &frame, id, options);
        assert_eq!(gpu.execution["gpu_pipeline"], "raster", "{id}");
        // Just above the share: a pixel one sample apart differs by the share in f32.
        let d = Difference::of(&gpu.visibility, &model.visibility, &mask, share + 1e-4);
        eprintln!("{id} wgpu vs cpu-model on the unit cube: {d:?}");
        assert!(d.pixels > 10_000, "{id}: {d:?}");
        assert_eq!(d.over_0_45, 0, "{id}: {d:?}");
        assert!(d.over * 1000 <= d.pixels, "{id}: {d:?}");
        assert!(d.over_0_1 * 1000 <= d.pixels, "{id}: {d:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// The conformance corpus.

/// The corpus's image size: small enough for `cargo test`, large enough that 0.1% of the
/// pixels is a few pixels.
const CORPUS_IMAGE: [u32; 2] = [64, 48];
/// The reference's samples per pixel (6×6 strata; the reference is reported, not bounded).
const REFERENCE_SAMPLES: u32 = 36;
/// The shadow maps' (and occluder maps') resolution of the corpus, as the registry's.
const CORPUS_MAP: u32 = 128;
/// Meshes larger than this are decimated (`scene::simplify`, topology kept) for the corpus.
const CORPUS_TRIANGLES: u32 = 1500;

/// Where the public test models are: `$SHADOWBENCH_FIELD_DIR` or `../shared/field` beside the
/// repository.
fn field_dir() -> std::path::PathBuf {
    std::env::var_os("SHADOWBENCH_FIELD_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/field")
        })
}

/// A mesh of the public test models (decimated to [`CORPUS_TRIANGLES`]), or `None` (with a
/// line saying why) where the file is not there.
fn field_mesh(relative: &str) -> Option<Mesh> {
    let path = field_dir().join(relative);
    if !path.is_file() {
        eprintln!("skipping {}: not found", path.display());
        return None;
    }
    let mesh = shadowbench::scene::load::load_mesh(&path, None)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .mesh;
    Some(shadowbench::scene::simplify::simplify(
        &mesh,
        CORPUS_TRIANGLES,
    ))
}

/// Two unit cubes in a glTF node hierarchy: a parent turned 30° about y (a quaternion) and
/// moved up, and its child scaled by 0.5 and moved beside it, read back through the loader.
fn gltf_with_node_transforms(dir: &std::path::Path) -> Mesh {
    let cube = unit_cube();
    let mut bin: Vec<u8> = Vec::new();
    for p in &cube.positions {
        for v in p.to_array() {
            bin.extend_from_slice(&v.to_le_bytes());
        }
    }
    let indices_at = bin.len();
    for t in &cube.triangles {
        for &i in t {
            bin.extend_from_slice(&(i as u16).to_le_bytes());
        }
    }
    let end = bin.len();
    std::fs::write(dir.join("nodes.bin"), &bin).unwrap();
    let (s, c) = (15f32.to_radians().sin(), 15f32.to_radians().cos());
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "parent", "mesh": 0, "translation": [0.0, 0.2, 0.0],
             "rotation": [0.0, s, 0.0, c], "children": [1]},
            {"name": "child", "mesh": 0, "translation": [1.4, 0.3, 0.2],
             "scale": [0.5, 0.5, 0.5]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": [0.0, 0.5, 0.0], "max": [1.0, 1.5, 1.0]},
            {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": indices_at},
            {"buffer": 0, "byteOffset": indices_at, "byteLength": end - indices_at}
        ],
        "buffers": [{"uri": "nodes.bin", "byteLength": end}]
    });
    let path = dir.join("nodes.gltf");
    std::fs::write(&path, serde_json::to_vec(&gltf).unwrap()).unwrap();
    shadowbench::scene::load::load_mesh(&path, None)
        .unwrap()
        .mesh
}

/// Where the light of a corpus scene sits, relative to the framed scene's bounds (centre `c`,
/// diagonal `d`) and its ground.
#[derive(Clone, Copy)]
enum Placement {
    /// The framing's own light: above, a little to the side.
    Framing,
    /// High above, the emitter tilted by `tilt_deg` about the x axis.
    Tilted { tilt_deg: f32 },
    /// Beside the mesh at half its height: receivers (the mesh's sides, the ground far away)
    /// beside the light.
    Beside,
    /// Low over the ground far to the side: the light grazes the ground.
    Grazing,
}

/// The light of kind `kind` placed as `placement` around `scene`'s bounds.
fn place_light(
    scene: &shadowbench::scene::Scene,
    kind: shadowbench::scene::LightKind,
    placement: Placement,
) -> shadowbench::scene::Light {
    use shadowbench::scene::{Light, LightKind};
    let b = scene.bounds();
    let (c, d) = (b.center(), b.diagonal());
    let (center, normal) = match placement {
        Placement::Framing => {
            let l = scene.light.center();
            (l, (c - l).normalize())
        }
        Placement::Tilted { tilt_deg } => {
            let t = tilt_deg.to_radians();
            (
                c + Vec3::new(0.1, 0.9, 0.15) * d,
                Vec3::new(0.0, -t.cos(), t.sin()),
            )
        }
        Placement::Beside => {
            let l = Vec3::new(c.x + 0.45 * d, c.y, c.z + 0.1 * d);
            (l, (c - l).normalize())
        }
        Placement::Grazing => {
            let l = Vec3::new(c.x - 0.6 * d, b.min.y + 0.08 * d, c.z - 0.2 * d);
            (l, (c - l).normalize())
        }
    };
    let radius = 0.06 * d;
    match kind {
        LightKind::Sphere => Light::Sphere { center, radius },
        LightKind::Disc => Light::Disc {
            center,
            normal,
            radius,
        },
        LightKind::Rect => {
            let (u, v) = normal.any_orthonormal_pair();
            Light::Rect {
                center,
                half_u: u * radius,
                half_v: v * radius,
            }
        }
    }
}

/// One scene of the corpus: a mesh framed as an `objects` scene is, its light, and the
/// (algorithm, reason) pairs left out of the bound between executions (still run and shown).
struct Case {
    name: String,
    mesh: Mesh,
    kind: shadowbench::scene::LightKind,
    placement: Placement,
    left_out: Vec<(&'static str, &'static str)>,
}

/// The corpus: the public test models, the tinyobjloader models that are meshes, a glTF with
/// node transforms and analytic scenes, under every light kind, tilted, beside and grazing.
fn corpus(dir: &std::path::Path) -> Vec<Case> {
    use shadowbench::scene::LightKind::{Disc, Rect, Sphere};
    let mut cases = Vec::new();
    let mut add = |name: &str, mesh: Option<Mesh>, kind, placement, left_out: Vec<_>| {
        if let Some(mesh) = mesh {
            cases.push(Case {
                name: name.into(),
                mesh,
                kind,
                placement,
                left_out,
            });
        }
    };
    let models = "common-3d-test-models";
    let tiny = "tinyobjloader-models";
    add(
        "unit_cube",
        Some(unit_cube()),
        Sphere,
        Placement::Framing,
        vec![],
    );
    add(
        "teapot_disc_tilted",
        field_mesh(&format!("{models}/teapot.obj")),
        Disc,
        Placement::Tilted { tilt_deg: 40.0 },
        vec![],
    );
    add(
        "cow_sphere",
        field_mesh(&format!("{models}/cow.obj")),
        Sphere,
        Placement::Framing,
        vec![],
    );
    add(
        "spot_rect_tilted",
        field_mesh(&format!("{models}/spot.obj")),
        Rect,
        Placement::Tilted { tilt_deg: 20.0 },
        vec![],
    );
    add(
        "suzanne_sphere_beside",
        field_mesh(&format!("{models}/suzanne.obj")),
        Sphere,
        Placement::Beside,
        vec![],
    );
    add(
        "fandisk_disc",
        field_mesh(&format!("{models}/fandisk.obj")),
        Disc,
        Placement::Framing,
        vec![],
    );
    add(
        "rocker_arm_sphere_grazing",
        field_mesh(&format!("{models}/rocker-arm.obj")),
        Sphere,
        Placement::Grazing,
        vec![],
    );
    add(
        "cornell_box_sphere",
        field_mesh(&format!("{tiny}/cornell_box.obj")),
        Sphere,
        Placement::Framing,
        vec![],
    );
    add(
        "catmark_torus_rect_beside",
        field_mesh(&format!("{tiny}/catmark_torus_creases0.obj")),
        Rect,
        Placement::Beside,
        vec![],
    );
    add(
        "gltf_nodes_disc",
        Some(gltf_with_node_transforms(dir)),
        Disc,
        Placement::Framing,
        vec![],
    );
    cases
}

/// One row of the corpus table: an algorithm on an execution against cpu-model and against
/// the reference.
struct Row {
    scene: String,
    algorithm: &'static str,
    backend: Backend,
    model: Difference,
    reference: Difference,
    left_out: Option<&'static str>,
}

fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<26} {:<18} {:<10} | {:>8} {:>6} {:>5} {:>5} | {:>8} {:>6} {:>5} {:>5}\n",
        "scene",
        "algorithm",
        "execution",
        "mae",
        "max",
        ">0.1",
        ">0.45",
        "mae",
        "max",
        ">0.1",
        ">0.45"
    );
    s += &format!(
        "{:<57} | {:^27} | {:^27}\n",
        "", "against cpu-model", "against the reference"
    );
    for r in rows {
        let (m, f) = (&r.model, &r.reference);
        s += &format!(
            "{:<26} {:<18} {:<10} | {:>8.5} {:>6.3} {:>5} {:>5} | {:>8.5} {:>6.3} {:>5} {:>5}{}\n",
            r.scene,
            r.algorithm,
            r.backend.to_string(),
            m.mae,
            m.max,
            m.over_0_1,
            m.over_0_45,
            f.mae,
            f.max,
            f.over_0_1,
            f.over_0_45,
            r.left_out
                .map(|why| format!("  (left out of the bound: {why})"))
                .unwrap_or_default()
        );
    }
    s
}

/// Every algorithm × execution with default options on every corpus scene, against cpu-model
/// and against the reference (MAE, largest difference, pixels off by more than 0.1 and 0.45),
/// printed as one table. Bound between executions: no pixel off by more than 0.45 and at most
/// 0.1% off by more than 0.1 (the cpu executions rounding half-float blends as the adapter
/// does where it records how: `execution.fp16_blend_rounding`).
#[test]
fn the_conformance_corpus_agrees_between_executions() {
    let gpu = have_gpu();
    let dir = tempfile::tempdir().unwrap();
    let mut rows = Vec::new();
    let started = std::time::Instant::now();
    for case in corpus(dir.path()) {
        let base = framed_frame(&case.name, case.mesh.clone(), CORPUS_IMAGE);
        let light = place_light(&base.scene, case.kind, case.placement);
        // Per light kind the algorithms take: the frame (the light converted as a run converts
        // it), its mask and its reference.
        let mut frames = std::collections::BTreeMap::new();
        for info in shadowbench::algorithms::ALGORITHMS
            .iter()
            .filter(|a| a.id != "reference")
        {
            let kind = match info.lights.contains(&case.kind) {
                true => case.kind,
                false => info.lights[0],
            };
            let (frame, mask, truth) = frames.entry(kind).or_insert_with(|| {
                let mut scene = base.scene.clone();
                let toward = scene.bounds().center();
                scene.light = shadowbench::harness::light_as(light, kind, toward);
                let params = RunParams::of_scene(&scene, CORPUS_IMAGE, CORPUS_MAP, 16);
                let frame = Frame::new(scene, params);
                let mask = frame.gbuffer.mask();
                let truth =
                    shadowbench::algorithms::reference::render(&frame, REFERENCE_SAMPLES, 1);
                (frame, mask, truth.visibility)
            });
            let (frame, mask, truth) = (&*frame, &*mask, &*truth);
            let left_out = case
                .left_out
                .iter()
                .find(|(id, _)| *id == info.id)
                .map(|(_, why)| *why);
            let mut ctx = shadowbench::algorithms::ExecContext::default();
            let mut outputs = Vec::new();
            if gpu && info.backends.contains(&Backend::Wgpu) {
                let out = shadowbench::algorithms::run(info.id, Backend::Wgpu, frame, &ctx)
                    .unwrap_or_else(|e| panic!("{} on wgpu, {}: {e}", info.id, case.name));
                ctx = super::registry::rounding_as_adapter(info.id, &ctx, &out);
                outputs.push((Backend::Wgpu, out));
            }
            for backend in [Backend::CpuNative, Backend::CpuModel] {
                let out = shadowbench::algorithms::run(info.id, backend, frame, &ctx)
                    .unwrap_or_else(|e| panic!("{} on {backend}, {}: {e}", info.id, case.name));
                outputs.push((backend, out));
            }
            let model = outputs
                .iter()
                .find(|(b, _)| *b == Backend::CpuModel)
                .map(|(_, o)| o.visibility.clone())
                .unwrap();
            for (backend, out) in &outputs {
                out.visibility.check_range().unwrap();
                let d = Difference::of(&out.visibility, &model, mask, 0.1);
                eprintln!(
                    "[{:.0} s] {} {} {backend}: against cpu-model {d:?}",
                    started.elapsed().as_secs_f64(),
                    case.name,
                    info.id
                );
                rows.push(Row {
                    scene: case.name.clone(),
                    algorithm: info.id,
                    backend: *backend,
                    model: Difference::of(&out.visibility, &model, mask, 0.1),
                    reference: Difference::of(&out.visibility, truth, mask, 0.1),
                    left_out,
                });
            }
        }
    }
    let printed = table(&rows);
    println!("{printed}");
    let failed: Vec<String> = rows
        .iter()
        .filter(|r| r.left_out.is_none())
        .filter(|r| r.model.over_0_45 > 0 || r.model.over_0_1 * 1000 > r.model.pixels)
        .map(|r| format!("{} {} {}", r.scene, r.algorithm, r.backend))
        .collect();
    assert!(rows.len() >= 8 * 3, "too few rows:\n{printed}");
    assert!(
        failed.is_empty(),
        "outside the bound between executions: {failed:?}\n{printed}"
    );
}
