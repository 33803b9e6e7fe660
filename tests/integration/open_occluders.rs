//! Adjacency problems of the occluders (open and non-manifold edges) are counted in every
//! record and warned about in every run, and z-fail counting (`counting: "z_fail"` of
//! `soft_shadow_volume` and `accum_hard`), right only for closed occluders, falls back to z-pass
//! on them with a warning naming the algorithm, the option and the open edges.

use super::common::run_one;
use glam::Vec3;
use shadowbench::algorithms::{Backend, ExecContext, ALGORITHMS};
use shadowbench::frame::Frame;
use shadowbench::frame::RunParams;
use shadowbench::harness::light_as;
use shadowbench::scene::generators::primitives;
use shadowbench::scene::{Camera, Light, Mesh, Object, Role, Scene};

/// A ground plane (a receiver only, so its open border does not count) and `occluder` above
/// it.
fn scene(occluder: Mesh) -> Frame {
    let object = |name: &str, mesh: Mesh, role: Role| Object {
        name: name.into(),
        mesh,
        role,
    };
    let scene = Scene {
        name: "occluders".into(),
        objects: vec![
            object("ground", primitives::plane(4.0, 4), Role::RECEIVER),
            object("occluder", occluder, Role::BOTH),
        ],
        camera: Camera {
            eye: Vec3::new(0.0, 4.0, 6.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 50.0,
        },
        light: Light::Sphere {
            center: Vec3::new(0.3, 5.0, 0.2),
            radius: 0.5,
        },
        light_texture: None,
    };
    let params = RunParams::of_scene(&scene, [24, 18], 64, 16);
    Frame::new(scene, params)
}

/// An open square plate of two triangles: 4 boundary edges.
fn open_plate() -> Mesh {
    Mesh {
        positions: vec![
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, -1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(-1.0, 1.0, 1.0),
        ],
        triangles: vec![[0, 2, 1], [0, 3, 2]],
    }
}

/// A closed box with a third triangle on one of its edges (a fin): 1 non-manifold edge and the
/// fin's 2 boundary edges.
fn finned_box() -> Mesh {
    let mut m = primitives::cuboid(Vec3::new(-1.0, 0.5, -1.0), Vec3::new(1.0, 1.5, 1.0));
    let (a, b) = (m.triangles[0][0], m.triangles[0][1]);
    let tip = m.positions[a as usize] + Vec3::new(0.0, 0.7, 0.3);
    m.positions.push(tip);
    m.triangles.push([a, b, m.positions.len() as u32 - 1]);
    m
}

fn for_algorithm(frame: &Frame, algorithm: &str) -> Frame {
    let info = shadowbench::algorithms::find(algorithm).unwrap();
    let mut scene = frame.scene.clone();
    let kind = info.light_for(scene.light.kind());
    scene.light = light_as(scene.light, kind, scene.bounds().center());
    Frame::new(scene, frame.params.clone())
}

/// The counting a run records: `accum_hard` as `counting`, `soft_shadow_volume` in its
/// `options`.
fn counting(execution: &std::collections::BTreeMap<String, serde_json::Value>) -> String {
    let v = execution
        .get("counting")
        .or_else(|| execution.get("options").and_then(|o| o.get("counting")))
        .expect("the run records its counting");
    v.as_str().unwrap().to_string()
}

fn zfail(id: &str) -> ExecContext {
    let mut ctx = ExecContext {
        reference_samples: 16,
        ..Default::default()
    };
    ctx.options
        .insert(id.into(), serde_json::json!({ "counting": "z_fail" }));
    ctx
}

/// Every algorithm's record on every CPU execution counts the occluders' boundary and
/// non-manifold edges (as the independent count of faces per welded edge gives them) and warns
/// when there are any; a closed box counts 0 and gets no warning.
#[test]
fn every_record_counts_open_edges_and_warns() {
    let cases = [
        ("open plate", scene(open_plate()), 4.0, 0.0),
        ("finned box", scene(finned_box()), 2.0, 1.0),
        (
            "closed box",
            scene(primitives::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0))),
            0.0,
            0.0,
        ),
    ];
    let ctx = ExecContext {
        reference_samples: 16,
        ..Default::default()
    };
    for (name, base, boundary, non_manifold) in cases {
        for info in ALGORITHMS {
            let frame = for_algorithm(&base, info.id);
            for &backend in info.backends.iter().filter(|b| **b != Backend::Wgpu) {
                let (record, _) = run_one(&frame, info.id, backend, &ctx, None);
                assert!(
                    record.failure.is_none(),
                    "{name} {}: {:?}",
                    info.id,
                    record.failure
                );
                let c = &record.counters;
                assert_eq!(
                    c.get("occluders.boundary_edges"),
                    Some(boundary),
                    "{name} {}",
                    info.id
                );
                assert_eq!(
                    c.get("occluders.non_manifold_edges"),
                    Some(non_manifold),
                    "{name} {}",
                    info.id
                );
                let warned = record
                    .warnings
                    .iter()
                    .any(|w| w.contains("not a closed 2-manifold"));
                assert_eq!(warned, boundary + non_manifold > 0.0, "{name} {}", info.id);
            }
        }
    }
}

/// z-fail on an open or non-manifold occluder runs z-pass (the same image and counters as
/// asking for z-pass), records `counting: "z_pass"`, and says so naming the algorithm, the
/// option and the number of open edges; on a closed occluder z-fail runs as asked.
#[test]
fn zfail_on_open_occluders_falls_back_to_zpass_with_a_warning() {
    for id in ["soft_shadow_volume", "accum_hard"] {
        for (occluder, open) in [(open_plate(), 4), (finned_box(), 3)] {
            let frame = for_algorithm(&scene(occluder), id);
            let (record, out) = run_one(&frame, id, Backend::CpuModel, &zfail(id), None);
            let out = out.unwrap_or_else(|| panic!("{id}: {:?}", record.failure));
            let mut zpass = zfail(id);
            zpass
                .options
                .insert(id.into(), serde_json::json!({ "counting": "z_pass" }));
            let (pass_record, pass) = run_one(&frame, id, Backend::CpuModel, &zpass, None);
            assert_eq!(out.visibility.data, pass.unwrap().visibility.data, "{id}");
            assert_eq!(record.counters, pass_record.counters, "{id}");
            assert_eq!(counting(&out.execution), "z_pass", "{id}");
            let warning = format!(
                "options.{id}.counting \"z_fail\" needs closed occluders, but they have {open} \
                 open edges"
            );
            assert!(
                record.warnings.iter().any(|w| w.contains(&warning)),
                "{id}: {:?}",
                record.warnings
            );
        }
        let closed = for_algorithm(
            &scene(primitives::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0))),
            id,
        );
        let (record, out) = run_one(&closed, id, Backend::CpuModel, &zfail(id), None);
        assert_eq!(counting(&out.unwrap().execution), "z_fail", "{id}");
        assert!(
            record.counters.get("volume_caps").unwrap_or(0.0) > 0.0,
            "{id}"
        );
        assert!(record.warnings.is_empty(), "{id}: {:?}", record.warnings);
    }
}
