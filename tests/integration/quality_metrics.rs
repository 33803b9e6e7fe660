//! The region metrics (`mae_penumbra`, `umbra_error`, `lit_error`) on the exact-answer plate of
//! the D-buffer tests: a straight plate edge under a horizontal disc, whose visibility on the
//! ground and whose umbra, penumbra and lit regions follow from similar triangles.

use shadowbench::algorithms::Backend;
use shadowbench::metrics::{compare, SHADOW_THRESHOLD, UMBRA_THRESHOLD};
use shadowbench::visibility::VisibilityBuffer;

use super::dbuffer::{
    edge_under_tilted_disc, exact_visibility, frame, run, PLATE_THICKNESS, PLATE_TOP,
    TILTED_CENTRE, TILTED_RADIUS,
};

/// Where a ground point `(x, 0, z)` lies under the horizontal disc (centre `TILTED_CENTRE`,
/// radius `TILTED_RADIUS`) past the plate `x < 0` of [`edge_under_tilted_disc`], in 2D: the ray
/// to a disc point of abscissa `d` crosses the plate's edge height `e` (its top beside the
/// plate, its bottom under it) at `x + (d − x)·e/c_y`, and passes when that is ≥ 0, i.e. when
/// `d ≥ t = x·(1 − c_y/e)`. The point is lit when `t` is at or left of the disc, in umbra when
/// `t` is at or right of it, in penumbra between; its visibility is the circular segment of the
/// disc right of `t`. Returns (region, visibility): region −1 umbra, 0 penumbra, 1 lit.
fn by_similar_triangles(x: f32) -> (i8, f64) {
    let e = if x >= 0.0 {
        PLATE_TOP
    } else {
        PLATE_TOP - PLATE_THICKNESS
    };
    let (c, r) = (TILTED_CENTRE, TILTED_RADIUS);
    let t = (x * (1.0 - c.y / e)) as f64;
    let u = (t - c.x as f64) / r as f64;
    if u <= -1.0 {
        (1, 1.0)
    } else if u >= 1.0 {
        (-1, 0.0)
    } else {
        (
            0,
            (u.acos() - u * (1.0 - u * u).sqrt()) / std::f64::consts::PI,
        )
    }
}

/// `mae_penumbra`, `umbra_error` and `lit_error` of pcss and of the hard shadow map against the
/// exact answer equal the same figures computed over the regions that the geometry gives,
/// and the exact answer of the D-buffer tests agrees with the similar triangles.
#[test]
fn region_metrics_on_the_exact_answer_plate_match_the_geometry() {
    let scene = edge_under_tilted_disc(0.0, true);
    let f = frame(scene, [64, 48], 512);
    let n = f.gbuffer.triangle.len();
    let ground: Vec<bool> = (0..n)
        .map(|i| {
            f.gbuffer.is_hit(i) && f.flat.object_of_triangle[f.gbuffer.triangle[i] as usize] == 0
        })
        .collect();
    let geometry: Vec<(i8, f64)> = (0..n)
        .map(|i| by_similar_triangles(f.gbuffer.position[i].x))
        .collect();
    let exact = VisibilityBuffer {
        width: f.gbuffer.width,
        height: f.gbuffer.height,
        data: (0..n)
            .map(|i| {
                if ground[i] {
                    exact_visibility(f.gbuffer.position[i], glam::Vec3::NEG_Y)
                } else {
                    1.0
                }
            })
            .collect(),
    };
    // The two derivations of the answer agree (to f32 rounding).
    for i in (0..n).filter(|&i| ground[i]) {
        let d = (exact.data[i] as f64 - geometry[i].1).abs();
        assert!(
            d < 1e-4,
            "pixel {i}: {} against {}",
            exact.data[i],
            geometry[i].1
        );
    }
    // The regions as the metrics define them, from the visibility by similar triangles: a
    // pixel of the geometric penumbra within half a sample of 1024 of lit or of umbra counts
    // as lit or umbra (a sliver at each side of the penumbra).
    let slivers = (0..n)
        .filter(|&i| ground[i] && geometry[i].0 == 0)
        .filter(|&i| !(UMBRA_THRESHOLD as f64..SHADOW_THRESHOLD as f64).contains(&geometry[i].1))
        .count();
    let geometry: Vec<(i8, f64)> = geometry
        .into_iter()
        .map(|(_, v)| {
            let k = if v < UMBRA_THRESHOLD as f64 {
                -1
            } else if v >= SHADOW_THRESHOLD as f64 {
                1
            } else {
                0
            };
            (k, v)
        })
        .collect();
    let count = |k: i8| (0..n).filter(|&i| ground[i] && geometry[i].0 == k).count();
    assert!(
        slivers * 50 < count(0),
        "{slivers} of {} in the slivers",
        count(0)
    );
    assert!(count(0) >= 40, "{} penumbra pixels", count(0));
    assert!(count(1) >= 40, "{} lit pixels", count(1));
    for id in ["pcss", "hard_shadow_map"] {
        let v = run(id, Backend::CpuNative, &f).visibility;
        let m = compare(&v, &exact, &ground);
        let (ground, geometry) = (&ground, &geometry);
        let over = |k: i8| (0..n).filter(move |&i| ground[i] && geometry[i].0 == k);
        let penumbra: Vec<f64> = over(0)
            .map(|i| (v.data[i] as f64 - geometry[i].1).abs())
            .collect();
        let mae_penumbra = penumbra.iter().sum::<f64>() / penumbra.len() as f64;
        assert_eq!(m.penumbra_pixels as usize, penumbra.len(), "{id}");
        assert!(
            (m.mae_penumbra.unwrap() - mae_penumbra).abs() < 1e-5,
            "{id}: mae_penumbra {:?}, by geometry {mae_penumbra}",
            m.mae_penumbra
        );
        let lit_shadowed = over(1).filter(|&i| v.data[i] < SHADOW_THRESHOLD).count();
        assert_eq!(m.lit_pixels as usize, count(1), "{id}");
        assert_eq!(
            m.lit_error,
            Some(lit_shadowed as f64 / count(1) as f64),
            "{id}"
        );
        let umbra = count(-1);
        assert_eq!(m.umbra_pixels as usize, umbra, "{id}");
        let leaks = over(-1).filter(|&i| v.data[i] >= UMBRA_THRESHOLD).count();
        assert_eq!(
            m.umbra_error,
            (umbra > 0).then(|| leaks as f64 / umbra as f64),
            "{id}"
        );
        eprintln!(
            "{id}: {} penumbra px, mae_penumbra {mae_penumbra:.5}; {} lit px, lit_error {:?}; \
             {umbra} umbra px, umbra_error {:?}",
            penumbra.len(),
            count(1),
            m.lit_error,
            m.umbra_error
        );
    }
}

/// An animated sweep of the light sliding over sphere-on-plane, on every execution: each frame
/// a run wrote equals that frame rendered alone (its light placed by hand on the path), the
/// record holds a flicker per frame transition with its floor, and the animated comparison is
/// an APNG of every frame. The hard shadow map, whose edge jumps from texel to texel, flickers
/// more than the soft shadow volume.
#[test]
fn an_animated_sweep_renders_each_frame_as_alone_and_measures_flicker() {
    let mut backends = vec!["cpu-native", "cpu-model"];
    if super::gpu_check::have_gpu() {
        backends.push("wgpu");
    }
    let frames = 4u32;
    let text = format!(
        r#"{{"name": "slide", "scene": {{"generator": "sphere-on-plane"}},
        "algorithms": ["hard_shadow_map", "soft_shadow_volume"], "backends": {backends:?},
        "params": {{"image": [48, 36], "map_resolution": 256, "triangles": 200,
                   "light_size": 0.6}},
        "reference": {{"samples": 16}},
        "animation": {{"frames": {frames}, "light_center": {{"to": [-1.0, 8.0, 0.5]}}}}}}"#
    );
    let loaded =
        shadowbench::scenario::Loaded::from_str(&text, std::path::Path::new("s.json")).unwrap();
    let out = tempfile::tempdir().unwrap();
    let runs = shadowbench::harness::run_scenario(
        &loaded,
        &shadowbench::harness::RunOptions {
            out: out.path().to_path_buf(),
            only: None,
            backends: None,
            cache_dir: None,
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
    .runs;
    assert_eq!(runs.len(), 2 * backends.len());
    let case = &loaded.cases(16).unwrap()[0];
    let scene = loaded.build_scene(case.scene, case.light_size);
    let mut flicker = std::collections::BTreeMap::new();
    for r in &runs {
        assert!(r.failure.is_none(), "{}: {:?}", r.algorithm, r.failure);
        let a = r.animation.as_ref().unwrap_or_else(|| panic!("{r:?}"));
        assert_eq!((a.frames, a.per_frame.len()), (frames, frames as usize));
        assert_eq!(a.flicker_per_frame.len(), frames as usize - 1);
        let floor = a.flicker_floor.expect("a floor");
        assert!(floor > 0.0, "references of two seeds differ in their noise");
        flicker.insert((r.algorithm.clone(), r.backend), a.flicker.unwrap());
        // Each frame as rendered alone: the run's light (converted as the run takes it), its
        // centre moved linearly from the scenario's to the target.
        let info = shadowbench::algorithms::find(&r.algorithm).unwrap();
        let mut sc = scene.clone();
        sc.light = shadowbench::harness::light_for_run(&scene, info).unwrap();
        let params = case.run_params(&sc);
        let (from, to) = (sc.light.center(), glam::Vec3::new(-1.0, 8.0, 0.5));
        let dir = out.path().join("images").join(r.case_id());
        let backend = r.backend;
        for t in 0..frames {
            let mut alone = sc.clone();
            alone.light = sc
                .light
                .with_center(from + (to - from) * (t as f32 / (frames - 1) as f32));
            let f = shadowbench::frame::Frame::new(alone, params.clone());
            let v = shadowbench::algorithms::run(
                &r.algorithm,
                backend,
                &f,
                &shadowbench::algorithms::ExecContext::default(),
            )
            .unwrap()
            .visibility;
            let written =
                VisibilityBuffer::read_npy(&dir.join(format!("frames/visibility_{t:03}.npy")))
                    .unwrap();
            let bits =
                |b: &VisibilityBuffer| b.data.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert!(
                bits(&written) == bits(&v),
                "{} on {}: frame {t} differs from the frame rendered alone",
                r.algorithm,
                r.backend
            );
        }
        let apng = image::codecs::png::PngDecoder::new(std::io::BufReader::new(
            std::fs::File::open(dir.join("animation.png")).unwrap(),
        ))
        .unwrap();
        use image::AnimationDecoder;
        assert!(apng.is_apng().unwrap());
        assert_eq!(apng.apng().unwrap().into_frames().count(), frames as usize);
    }
    for b in &backends {
        let b = Backend::parse(b).unwrap();
        let (h, s) = (
            flicker[&("hard_shadow_map".to_string(), b)],
            flicker[&("soft_shadow_volume".to_string(), b)],
        );
        assert!(
            h > s,
            "{b}: hard_shadow_map flicker {h} not above soft_shadow_volume's {s}"
        );
    }
}
