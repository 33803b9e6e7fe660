//! The one coverage rule (`scene::coverage`) where eye rays and eye samples hit shared edges and
//! vertices exactly: a closed plate whose faces are split along the diagonal x = z, and a fan
//! of eight triangles meeting at a vertex on the axis, straight below the light's centre and
//! straight below the eye, under a square (or spherical) light. Every eye ray of the image's
//! diagonal lies in the plane x = z, so it meets, with an edge function of exactly 0, the lines
//! from the light's centre through the plate's corners (where two hard shadow quads meet), the
//! plate's diagonal (shared by two cap triangles) and, seen from the light, the projected
//! diagonal (shared by two occluding triangles of `soft_izb`). Against the ray-cast reference,
//! no pixel may be counted twice or missed: no fully lit pixel in an umbra, no black pixel in a
//! penumbra — on cpu-native, cpu-model and wgpu.

use super::gpu_check;

use glam::Vec3;
use gpu_check::have_gpu;
use shadowbench::algorithms::shadow_map::{LightViews, ViewFit};
use shadowbench::algorithms::soft_izb::{clip_coords, light_point};
use shadowbench::algorithms::{self, Backend, ExecContext};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::coverage::{edge_function, edge_function_2d};
use shadowbench::scene::generators::primitives;
use shadowbench::scene::{Camera, Light, Mesh, Object, Role, Scene};

const H: f32 = 1.0;
const C: f32 = 0.75;
const L: f32 = 4.0;
const SIZE: u32 = 65;

/// A closed box over [−C, C]² × [H − t, H], every face split along a diagonal; the top and
/// bottom along x = z.
fn plate() -> Mesh {
    let t = 0.125;
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let positions = vec![
        v(-C, H, -C),
        v(C, H, -C),
        v(C, H, C),
        v(-C, H, C),
        v(-C, H - t, -C),
        v(C, H - t, -C),
        v(C, H - t, C),
        v(-C, H - t, C),
    ];
    // Quads counter-clockwise seen from outside, split along their 0–2 diagonal.
    let quads = [
        [0, 3, 2, 1], // top (+y): diagonal 0–2 is x = z
        [4, 5, 6, 7], // bottom (−y): diagonal 4–6 is x = z
        [0, 1, 5, 4], // −z
        [2, 3, 7, 6], // +z
        [1, 2, 6, 5], // +x
        [3, 0, 4, 7], // −x
    ];
    let mut triangles = Vec::new();
    for [a, b, c, d] in quads {
        triangles.push([a, b, c]);
        triangles.push([a, c, d]);
    }
    Mesh {
        positions,
        triangles,
    }
}

/// A closed shape around the axis: a flat top, a fan of eight triangles meeting at its centre
/// (0, H, 0) with its rim on the square [−C, C]², over a cone of eight meeting below.
fn fan() -> Mesh {
    let rim = [
        (1.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 0.0),
        (-1.0, -1.0),
        (0.0, -1.0),
        (1.0, -1.0),
    ];
    let mut positions = vec![Vec3::new(0.0, H, 0.0), Vec3::new(0.0, H - 0.5, 0.0)];
    positions.extend(rim.iter().map(|&(x, z)| Vec3::new(x * C, H, z * C)));
    let mut triangles = Vec::new();
    for i in 0..8u32 {
        let (a, b) = (2 + i, 2 + (i + 1) % 8);
        // Counter-clockwise from outside: the rim runs counter-clockwise seen from −y.
        triangles.push([0, b, a]);
        triangles.push([1, a, b]);
    }
    Mesh {
        positions,
        triangles,
    }
}

fn frame(occluder: Mesh, light: Light) -> Frame {
    let scene = Scene {
        name: "ties".into(),
        objects: vec![
            Object {
                name: "ground".into(),
                mesh: primitives::plane(4.0, 8),
                role: Role::RECEIVER,
            },
            Object {
                name: "occluder".into(),
                mesh: occluder,
                role: Role::BOTH,
            },
        ],
        camera: Camera {
            eye: Vec3::new(0.0, 2.0 * L, 0.0),
            target: Vec3::ZERO,
            up: Vec3::Z,
            fov_y_deg: 40.0,
        },
        light,
        light_texture: None,
    };
    let params = RunParams::of_scene(&scene, [SIZE, SIZE], 256, 16);
    Frame::new(scene, params)
}

fn rect_light() -> Light {
    Light::Rect {
        center: Vec3::new(0.0, L, 0.0),
        half_u: Vec3::new(0.25, 0.0, 0.0),
        half_v: Vec3::new(0.0, 0.0, 0.25),
    }
}

fn sphere_light() -> Light {
    Light::Sphere {
        center: Vec3::new(0.0, L, 0.0),
        radius: 0.25,
    }
}

fn ctx(id: &str, options: serde_json::Value) -> ExecContext {
    let mut ctx = ExecContext {
        reference_samples: 1024,
        ..ExecContext::default()
    };
    ctx.options.insert(id.into(), options);
    ctx
}

/// Eye rays (of pixels with a surface) whose edge function against the line from the light's
/// centre through a plate corner on the diagonal is exactly 0: the ties the test exercises.
fn quad_line_ties(f: &Frame) -> usize {
    let cam = f.scene.camera;
    let l = f.scene.light.center();
    (0..f.gbuffer.len())
        .filter(|&i| f.gbuffer.is_hit(i))
        .filter(|&i| {
            let d = (f.gbuffer.shading_point(i) - cam.eye).normalize();
            [Vec3::new(C, H, C), Vec3::new(-C, H, -C)]
                .iter()
                .any(|&corner| edge_function(cam.eye, d, l, corner) == 0.0)
        })
        .count()
}

/// Eye samples whose light-view position lies exactly on the projected diagonal of the plate
/// (the edge shared by its two top triangles in `soft_izb`'s image plane).
fn izb_diagonal_ties(f: &Frame) -> usize {
    let views = LightViews::fit(f, ViewFit::Single);
    let view = *views.single();
    let uv = |p: Vec3| light_point(clip_coords(&view, p)).uv;
    let (a, b) = (uv(Vec3::new(-C, H, -C)), uv(Vec3::new(C, H, C)));
    (0..f.gbuffer.len())
        .filter(|&i| f.gbuffer.is_hit(i))
        .filter(|&i| edge_function_2d(uv(f.gbuffer.shading_point(i)), a, b) == 0.0)
        .count()
}

/// Pixels where `alg` is fully lit in the reference's umbra or black in its penumbra (or far
/// from it otherwise), with the worst difference.
fn miscounted(f: &Frame, alg: &[f32], reference: &[f32]) -> (usize, f32) {
    let mut worst = 0.0f32;
    let mut bad = 0;
    for i in (0..alg.len()).filter(|&i| f.gbuffer.is_hit(i)) {
        let (a, r) = (alg[i], reference[i]);
        worst = worst.max((a - r).abs());
        let lit_in_umbra = r <= 0.02 && a >= 0.98;
        let black_in_penumbra = r >= 0.1 && a <= 0.0;
        if lit_in_umbra || black_in_penumbra || (a - r).abs() > 0.5 {
            bad += 1;
            eprintln!(
                "  pixel ({}, {}) at {}: {a} against the reference's {r}",
                i as u32 % SIZE,
                i as u32 / SIZE,
                f.gbuffer.shading_point(i)
            );
        }
    }
    (bad, worst)
}

fn backends() -> Vec<Backend> {
    let mut b = vec![Backend::CpuNative, Backend::CpuModel];
    if have_gpu() {
        b.push(Backend::Wgpu);
    }
    b
}

fn check(name: &str, f: &Frame, id: &str, options: serde_json::Value) {
    let ctx = ctx(id, options.clone());
    let reference = algorithms::run("reference", Backend::CpuNative, f, &ctx).unwrap();
    for backend in backends() {
        let out = algorithms::run(id, backend, f, &ctx).unwrap();
        let (bad, worst) = miscounted(f, &out.visibility.data, &reference.visibility.data);
        eprintln!("{name}: {id} {options} on {backend:?}: {bad} miscounted, worst {worst}");
        assert_eq!(
            bad, 0,
            "{name}: {id} {options} on {backend:?}: {bad} pixels miscounted"
        );
    }
}

/// soft_shadow_volume (pass 1: hard shadow quads from the light's centre, z-pass and z-fail with
/// caps) and accum_hard on the diagonal plate: eye rays through the lines where two quads meet,
/// and through the caps' shared diagonal.
#[test]
fn shadow_volumes_count_shared_quad_edges_and_cap_diagonals_once() {
    let f = frame(plate(), rect_light());
    let ties = quad_line_ties(&f);
    assert!(
        ties > 0,
        "the scene no longer puts eye rays on the quads' shared lines"
    );
    eprintln!("{ties} eye rays on a shared quad line");
    assert_eq!(f.occluder_edges.open(), 0);
    for counting in ["z_pass", "z_fail"] {
        check(
            "plate",
            &f,
            "soft_shadow_volume",
            serde_json::json!({ "counting": counting }),
        );
    }
    check(
        "plate",
        &f,
        "accum_hard",
        serde_json::json!({ "samples": 64, "counting": "z_fail" }),
    );
}

/// The fan: the centre pixel's eye ray runs down the axis through the centre vertex, where the
/// eight light-cap triangles of z-fail meet (the visible point is that vertex, lifted straight
/// up off the flat top, so the caps lie just behind it and count), under the square light.
#[test]
fn shadow_volumes_count_a_fan_vertex_once() {
    let f = frame(fan(), rect_light());
    assert_eq!(f.occluder_edges.open(), 0);
    let centre = (SIZE / 2 * SIZE + SIZE / 2) as usize;
    let p = f.gbuffer.shading_point(centre);
    assert!(
        p.x == 0.0 && p.z == 0.0 && p.y > H,
        "centre pixel off the axis: {p}"
    );
    for counting in ["z_pass", "z_fail"] {
        check(
            "fan",
            &f,
            "soft_shadow_volume",
            serde_json::json!({ "counting": counting }),
        );
    }
}

/// soft_izb: eye samples on the plate's projected diagonal (shared by its two top triangles),
/// with penumbra edges from adjacency and from every edge (interior edges then cancel pairwise
/// only if a sample on one counts once inside and once outside). Samples exactly on a shared
/// vertex are covered by the unit tests of `scene::coverage` (a visible point straight below a
/// vertex cannot be placed exactly in the light's image plane here).
#[test]
fn soft_izb_counts_samples_on_shared_edges_and_vertices_once() {
    let f = frame(plate(), sphere_light());
    let ties = izb_diagonal_ties(&f);
    assert!(ties > 0, "no eye sample lies on the projected diagonal");
    eprintln!("{ties} eye samples on the projected diagonal");
    for silhouettes in ["adjacency", "all_edges"] {
        check(
            "plate",
            &f,
            "soft_izb",
            serde_json::json!({ "silhouettes": silhouettes }),
        );
    }
}
