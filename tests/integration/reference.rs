//! The ground-truth reference against analytic visibility, and its determinism.

use glam::Vec3;
use shadowbench::algorithms::reference::{self, visible_fraction};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::bvh::SceneBvh;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::{Light, Mesh, Object, Role, Scene};
use shadowbench::visibility::VisibilityBuffer;

/// Fraction of a disc of radius `r` lying beyond a chord at signed distance `d` from its centre:
/// the circular-segment area over the disc area.
fn segment_fraction(d: f32, r: f32) -> f32 {
    let x = (d / r).clamp(-1.0, 1.0);
    (x.acos() - x * (1.0 - x * x).sqrt()) / std::f32::consts::PI
}

/// A half-plane occluder y = h, x < 0 over the ground, under a spherical light.
fn half_plane_scene(h: f32, light: Light) -> Scene {
    let l = 60.0;
    let occluder = Mesh {
        positions: vec![
            Vec3::new(-l, h, -l),
            Vec3::new(0.0, h, -l),
            Vec3::new(0.0, h, l),
            Vec3::new(-l, h, l),
        ],
        triangles: vec![[0, 2, 1], [0, 3, 2]],
    };
    Scene {
        name: "half-plane".into(),
        objects: vec![Object {
            name: "edge".into(),
            mesh: occluder,
            role: Role::BOTH,
        }],
        camera: generators::find("sphere-on-plane")
            .unwrap()
            .build(&GeneratorParams::default())
            .camera,
        light,
        light_texture: None,
    }
}

#[test]
fn straight_edge_under_a_sphere_light_matches_the_circular_segment() {
    let (h, r) = (1.0f32, 0.5f32);
    let c = Vec3::new(0.3, 4.0, 0.2);
    let light = Light::Sphere {
        center: c,
        radius: r,
    };
    let scene = half_plane_scene(h, light);
    let bvh = SceneBvh::build(&scene.flatten());
    let k = reference::strata_side(reference::PAPER_SAMPLES).unwrap();
    let mut checked_penumbra = 0;
    for i in 0..=24 {
        let xp = -0.5 + i as f32 * (0.8 / 24.0);
        let p = Vec3::new(xp, 0.0, 0.0);
        // The ray p→l meets y = h at x = xp + (lx − xp)·h/ly; it is blocked when that is < 0,
        // i.e. when f(l) = xp·ly + h·lx < xp·h. f is linear, so on the emitter disc (centre c,
        // perpendicular to w) the blocked part is a half-plane: a circular segment.
        let w = (c - p).normalize();
        let g = Vec3::new(h, xp, 0.0);
        let g_perp = g - g.dot(w) * w;
        let s = (xp * h - (xp * c.y + h * c.x)) / g_perp.length();
        let expected = segment_fraction(s, r);
        let got = visible_fraction(&bvh, &light, (p + Vec3::Y * 1e-4, None), k, 17 + i as u64);
        assert!(
            (got - expected).abs() <= 0.01,
            "x = {xp}: reference {got}, analytic {expected}"
        );
        if expected > 0.05 && expected < 0.95 {
            checked_penumbra += 1;
        }
    }
    assert!(checked_penumbra >= 5, "the test must cross the penumbra");
}

#[test]
fn reference_is_bit_identical_across_thread_counts() {
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let scene = generators::find("torus-on-plane")
                .unwrap()
                .build(&GeneratorParams::default());
            let params = RunParams::of_scene(&scene, [64, 48], 256, 32);
            let frame = Frame::new(scene, params);
            reference::render(&frame, 64, 5).visibility
        })
    };
    let (a, b) = (render(1), render(2));
    assert!(
        a.data.iter().any(|&v| v < 0.5),
        "the frame must contain shadow"
    );
    assert!(a.data.iter().any(|&v| v > 0.0 && v < 1.0), "and penumbra");
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.data), bits(&b.data));
}

/// Runs a one-case pcss sweep on cpu-model into `out`, with its reference cache in `cache`.
fn cached_sweep(
    out: &std::path::Path,
    cache: &std::path::Path,
) -> Vec<shadowbench::record::RunRecord> {
    let text = r#"{"name": "cache", "scene": {"generator": "sphere-on-plane"},
        "algorithms": ["pcss"], "backends": ["cpu-model"],
        "params": {"image": [40, 30], "map_resolution": 64, "triangles": 200,
                   "light_size": 0.4},
        "reference": {"samples": 16}}"#;
    let loaded =
        shadowbench::scenario::Loaded::from_str(text, std::path::Path::new("c.json")).unwrap();
    shadowbench::harness::run_scenario(
        &loaded,
        &shadowbench::harness::RunOptions {
            out: out.to_path_buf(),
            only: None,
            backends: None,
            cache_dir: Some(cache.to_path_buf()),
            memory_limit: shadowbench::harness::limits::default_limit(),
            machine: None,
            shard: None,
            max_cases: shadowbench::scenario::MAX_CASES,
            run_timeout: None,
            verbosity: shadowbench::harness::Verbosity::Quiet,
            gpu_counters: Default::default(),
            measure: Default::default(),
            fresh: false,
            retry_failed: false,
        },
    )
    .unwrap()
    .runs
}

/// A cached reference that was replaced (a valid array of the right shape holding 5.0 or NaN,
/// with or without a matching checksum) is recomputed with a warning, and the run's metrics
/// are those of a fresh run; never 4.13 or NaN.
#[test]
fn a_corrupted_reference_cache_is_recomputed_with_a_warning() {
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let fresh = cached_sweep(&tmp.path().join("fresh"), &cache);
    let fresh_error = fresh[0].error.expect("metrics against the reference");
    assert!(fresh[0]
        .warnings
        .iter()
        .all(|w| !w.contains("reference cache")));
    let npy = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "npy"))
        .expect("the reference was cached");
    let sidecar = npy.with_extension("json");
    let good = VisibilityBuffer::read_npy(&npy).unwrap();
    // A second sweep reads the cache and agrees, without a warning.
    let again = cached_sweep(&tmp.path().join("again"), &cache);
    assert_eq!(again[0].error, Some(fresh_error));
    assert!(again[0]
        .warnings
        .iter()
        .all(|w| !w.contains("reference cache")));
    for (what, value, fix_checksum) in [
        ("5.0, stale checksum", 5.0f32, false),
        ("NaN, stale checksum", f32::NAN, false),
        ("5.0, matching checksum", 5.0, true),
        ("NaN, matching checksum", f32::NAN, true),
    ] {
        let bad = VisibilityBuffer {
            data: vec![value; good.data.len()],
            ..good.clone()
        };
        bad.write_npy(&npy).unwrap();
        if fix_checksum {
            let mut entry: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&sidecar).unwrap()).unwrap();
            let crc = crc32fast::hash(&std::fs::read(&npy).unwrap());
            entry["crc32"] = serde_json::json!(format!("{crc:08x}"));
            std::fs::write(&sidecar, entry.to_string()).unwrap();
        }
        // A folder per case: into one folder, a sweep would resume the previous case's run.
        let out = tmp
            .path()
            .join(format!("corrupt-{}", what.replace([' ', ','], "-")));
        let runs = cached_sweep(&out, &cache);
        let r = &runs[0];
        assert!(r.failure.is_none(), "{what}: {:?}", r.failure);
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("reference cache") && w.contains("recomputed")),
            "{what}: {:?}",
            r.warnings
        );
        assert_eq!(r.error, Some(fresh_error), "{what}");
        // The cache holds the recomputed image again, and it verifies.
        assert_eq!(VisibilityBuffer::read_npy(&npy).unwrap(), good, "{what}");
        let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
        // No figure is NaN (the warnings column may name the NaN it found).
        assert!(
            !csv.split([',', '\n'])
                .any(|f| f.eq_ignore_ascii_case("nan")),
            "{what}: {csv}"
        );
    }
    // A sidecar for other settings (another sample count) is not trusted either.
    let mut entry: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&sidecar).unwrap()).unwrap();
    entry["samples"] = serde_json::json!(1024);
    std::fs::write(&sidecar, entry.to_string()).unwrap();
    let runs = cached_sweep(&tmp.path().join("other"), &cache);
    assert!(
        runs[0].warnings.iter().any(|w| w.contains("samples")),
        "{:?}",
        runs[0].warnings
    );
    assert_eq!(runs[0].error, Some(fresh_error));
}

/// Every tracer of the reference ([`reference::Tracer`]: the casters' BVH one ray at a time, in
/// groups and in packets, on every instruction set this CPU runs) against the scene BVH of every triangle
/// (the method before the casters' BVH): the same visibility, bit for bit.
fn assert_tracers_agree(what: &str, frame: &Frame, samples: u32) {
    use reference::Tracer;
    use shadowbench::scene::shadow_bvh::Isa;
    use shadowbench::util::deadline::Deadline;
    let render = |tracer| reference::render_with(frame, samples, 3, Deadline::default(), tracer);
    let before = render(Tracer::SceneBvh).visibility;
    let bits = |v: &VisibilityBuffer| v.data.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for isa in Isa::available() {
        for tracer in [Tracer::Rays(isa), Tracer::Groups(isa), Tracer::Packets(isa)] {
            let got = render(tracer).visibility;
            let differ = got
                .data
                .iter()
                .zip(&before.data)
                .filter(|(a, b)| a.to_bits() != b.to_bits())
                .count();
            assert!(
                bits(&got) == bits(&before),
                "{what}: {} differs from the scene BVH at {differ} pixels",
                tracer.name()
            );
        }
    }
}

#[test]
fn every_tracer_gives_the_same_image_on_every_built_in_scene() {
    let mut shadowed = 0;
    for g in generators::GENERATORS {
        let scene = g.build(&GeneratorParams::default());
        let params = RunParams::of_scene(&scene, [64, 48], 256, 32);
        let frame = Frame::new(scene, params);
        let image = reference::render(&frame, 16, 3).visibility;
        shadowed += usize::from(image.data.iter().any(|&v| v > 0.0 && v < 1.0));
        assert_tracers_agree(g.name, &frame, 16);
        // More samples than a packet holds, not a multiple of it: a pixel in two packets.
        assert_tracers_agree(g.name, &frame, 100);
    }
    assert!(
        shadowed * 2 > generators::GENERATORS.len(),
        "most scenes must show penumbra for the comparison to say something"
    );
}

#[test]
fn every_tracer_gives_the_same_image_on_the_field_meshes() {
    let dir = std::env::var_os("SHADOWBENCH_FIELD_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/field")
        });
    let meshes = [
        "common-3d-test-models/suzanne.obj",
        "common-3d-test-models/teapot.obj",
        "common-3d-test-models/cow.obj",
        "common-3d-test-models/spot.obj",
        "common-3d-test-models/fandisk.obj",
        "common-3d-test-models/rocker-arm.obj",
        "tinyobjloader-models/cornell_box.obj",
    ];
    let mut compared = 0;
    for m in meshes {
        let path = dir.join(m);
        if !path.is_file() {
            eprintln!("skipping {}: not found", path.display());
            continue;
        }
        let (scene, _) = shadowbench::scenario::scene_from_arg(
            path.to_str().expect("a UTF-8 path"),
            GeneratorParams::default(),
        )
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let params = RunParams::of_scene(&scene, [64, 48], 256, 32);
        let frame = Frame::new(scene, params);
        assert_tracers_agree(m, &frame, 16);
        compared += 1;
    }
    if compared == 0 {
        eprintln!("skipped: no field meshes under {}", dir.display());
    }
}
