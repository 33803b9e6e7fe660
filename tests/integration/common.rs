//! Helpers shared by the integration tests: running the `shadowbench` command and reading what
//! it printed and wrote, running an algorithm with options, and the scenes of the robustness
//! tests (the degenerate cases of the robustness list).

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};

use glam::Vec3;
use shadowbench::algorithms::{self, Backend, ExecContext, FrameOutput};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::generators::primitives;
use shadowbench::scene::{Camera, Light, Mesh, Object, Role, Scene};

/// Runs the `shadowbench` command with `args` (no backtraces on a panic) and waits for it.
pub fn shadowbench(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap()
}

/// Bytes a command printed, as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// What a command printed to standard error.
pub fn stderr(o: &Output) -> String {
    text(&o.stderr)
}

/// What a command printed to standard output.
pub fn stdout(o: &Output) -> String {
    text(&o.stdout)
}

/// A JSON file a command wrote.
pub fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// Algorithm `id` on `backend` with `options` (`null`: the defaults); its visibility checked
/// to lie in [0, 1].
pub fn run_on(
    backend: Backend,
    frame: &Frame,
    id: &str,
    options: serde_json::Value,
) -> FrameOutput {
    let mut ctx = ExecContext::default();
    if !options.is_null() {
        ctx.options = BTreeMap::from([(id.to_string(), options)]);
    }
    let out = algorithms::run(id, backend, frame, &ctx).unwrap();
    out.visibility.check_range().unwrap();
    out
}

pub fn frame_of(objects: Vec<Object>, light: Light, camera: Camera) -> Frame {
    let scene = Scene {
        name: "degenerate".into(),
        objects,
        camera,
        light,
        light_texture: None,
    };
    let params = RunParams {
        triangles: scene.triangle_count() as u32,
        light_size: light.size(),
        map_resolution: 64,
        tile_size: 16,
        image: [24, 18],
        occluder_height: None,
        occluder_offset: None,
        cores: None,
    };
    Frame::new(scene, params)
}

pub fn object(mesh: Mesh) -> Object {
    Object {
        name: "o".into(),
        mesh,
        role: Role::BOTH,
    }
}

pub fn camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 4.0, 6.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 50.0,
    }
}

pub fn sphere_light(center: Vec3, radius: f32) -> Light {
    Light::Sphere { center, radius }
}

/// The named degenerate scenes of the robustness list.
pub fn degenerate_scenes() -> Vec<(&'static str, Frame)> {
    let ground = || object(primitives::plane(4.0, 4));
    let cube = |c: Vec3, s: f32| object(primitives::cuboid(c - Vec3::splat(s), c + Vec3::splat(s)));
    let light = sphere_light(Vec3::new(0.5, 5.0, 0.2), 0.5);
    let zero_area = Mesh {
        positions: vec![
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 0, 1]],
    };
    let mut duplicated = primitives::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5));
    duplicated.append(&primitives::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5)));
    let non_manifold = Mesh {
        positions: vec![
            Vec3::new(-1.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 2.0, 0.5),
            Vec3::new(0.0, 1.5, -1.0),
            Vec3::new(0.0, 0.5, 0.5),
        ],
        triangles: vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
    };
    let open = {
        let mut m = primitives::uv_sphere(12, 6);
        m.triangles.truncate(m.triangles.len() / 2);
        m.transformed(glam::Mat4::from_translation(Vec3::Y * 1.5))
    };
    vec![
        (
            "zero-area triangles",
            frame_of(vec![ground(), object(zero_area)], light, camera()),
        ),
        (
            "duplicate vertices and faces",
            frame_of(vec![ground(), object(duplicated)], light, camera()),
        ),
        (
            "non-manifold edge",
            frame_of(vec![ground(), object(non_manifold)], light, camera()),
        ),
        (
            "open mesh",
            frame_of(vec![ground(), object(open)], light, camera()),
        ),
        (
            "light inside a closed mesh",
            frame_of(
                vec![ground(), cube(Vec3::new(0.5, 5.0, 0.2), 1.0)],
                light,
                camera(),
            ),
        ),
        (
            "geometry touching the light",
            frame_of(
                vec![ground(), cube(Vec3::new(0.5, 4.0, 0.2), 0.5)],
                light,
                camera(),
            ),
        ),
        (
            "occluder behind the light",
            frame_of(
                vec![ground(), cube(Vec3::new(0.5, 8.0, 0.2), 1.0)],
                light,
                camera(),
            ),
        ),
        (
            "eye inside a shadow volume",
            frame_of(
                vec![ground(), cube(Vec3::new(0.0, 3.0, 3.0), 0.8)],
                sphere_light(Vec3::new(0.0, 6.0, 6.0), 0.3),
                camera(),
            ),
        ),
        (
            "edge pointing at the light centre",
            frame_of(
                vec![
                    ground(),
                    object(Mesh {
                        positions: vec![
                            Vec3::new(0.5, 2.0, 0.2),
                            Vec3::new(0.5, 3.0, 0.2),
                            Vec3::new(1.5, 2.0, 0.2),
                        ],
                        triangles: vec![[0, 1, 2]],
                    }),
                ],
                light,
                camera(),
            ),
        ),
        ("empty scene", frame_of(vec![], light, camera())),
    ]
}

/// [`shadowbench::harness::run_one`] of algorithm `id` with `ctx.options` (configured once for
/// the run).
pub fn run_one(
    frame: &Frame,
    id: &str,
    backend: Backend,
    ctx: &ExecContext,
    reference: Option<&shadowbench::visibility::VisibilityBuffer>,
) -> (shadowbench::record::RunRecord, Option<FrameOutput>) {
    let info = algorithms::find(id).unwrap_or_else(|e| panic!("{e}"));
    let configured = info
        .configure(&ctx.options)
        .unwrap_or_else(|e| panic!("{id}: {e}"));
    shadowbench::harness::run_one(frame, &configured, backend, ctx, reference)
}
