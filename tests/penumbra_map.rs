//! Penumbra maps (paper 000) on the CPU executions, checked against the ray-traced reference and
//! the paper's stated properties: only the outer penumbra is computed, so the umbra is
//! overestimated, more so for larger lights (§4.1); shadows harden as the occluder approaches the
//! receiver (§1); counters are deterministic.

use shadowbench::algorithms::{self, Backend, ExecContext, FrameOutput};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::ReferenceCache;
use shadowbench::scenario::Loaded;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::visibility::VisibilityBuffer;

/// The paper-000 stand-in scene, small: a lumpy blob over the ground.
fn frame(light_size: f32, occluder_height: Option<f32>) -> Frame {
    let mut scene = generators::find("blob-on-plane")
        .unwrap()
        .build(&GeneratorParams {
            triangles: Some(2_000),
            seed: 1,
            occluder_height,
        });
    scene.light = scene.light.with_size(light_size);
    let params = RunParams {
        triangles: scene.triangle_count() as u32,
        light_size,
        map_resolution: 512,
        tile_size: 32,
        image: [64, 48],
        occluder_height,
        cores: None,
    };
    Frame::new(scene, params)
}

fn penumbra_map(backend: Backend, f: &Frame) -> FrameOutput {
    algorithms::run("penumbra_map", backend, f, &ExecContext::default()).unwrap()
}

fn reference(f: &Frame) -> VisibilityBuffer {
    ReferenceCache::new(None, 64, 1).get_or_compute(f).unwrap()
}

/// Pixels that see a surface with visibility in `range`.
fn count(v: &VisibilityBuffer, f: &Frame, range: impl Fn(f32) -> bool) -> usize {
    (0..v.data.len())
        .filter(|&i| f.gbuffer.is_hit(i) && range(v.data[i]))
        .count()
}

fn umbra(v: &VisibilityBuffer, f: &Frame) -> usize {
    count(v, f, |x| x < 0.05)
}

fn penumbra(v: &VisibilityBuffer, f: &Frame) -> usize {
    count(v, f, |x| x > 0.05 && x < 0.95)
}

#[test]
fn the_umbra_is_overestimated_and_more_so_for_larger_lights() {
    let mut excess = Vec::new();
    for size in [0.15, 0.4, 0.8] {
        let f = frame(size, None);
        let (pm, rf) = (
            penumbra_map(Backend::CpuModel, &f).visibility,
            reference(&f),
        );
        // Every pixel that sees a surface, attached shadows (surfaces turned away from the
        // light) included.
        let (u_pm, u_rf) = (umbra(&pm, &f), umbra(&rf, &f));
        eprintln!("light {size}: umbra pixels penumbra_map {u_pm}, reference {u_rf}");
        assert!(u_pm >= u_rf, "light {size}: {u_pm} < {u_rf}");
        excess.push(u_pm - u_rf);
    }
    assert!(
        excess.windows(2).all(|w| w[0] < w[1]),
        "umbra excess over the reference by light size: {excess:?}"
    );
}

#[test]
fn the_penumbra_narrows_as_the_occluder_approaches_the_receiver() {
    let widths: Vec<usize> = [1.2, 0.6, 0.1]
        .into_iter()
        .map(|h| {
            let f = frame(0.5, Some(h));
            let n = penumbra(&penumbra_map(Backend::CpuNative, &f).visibility, &f);
            eprintln!("occluder height {h}: {n} penumbra pixels");
            n
        })
        .collect();
    assert!(
        widths.windows(2).all(|w| w[0] > w[1]),
        "penumbra pixels by decreasing height: {widths:?}"
    );
}

#[test]
fn counters_and_model_times_do_not_depend_on_host_threads() {
    let f = frame(0.5, None);
    let in_pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| penumbra_map(Backend::CpuModel, &f))
    };
    let (a, b) = (in_pool(1), in_pool(2));
    assert_eq!(a.counters, b.counters);
    assert_eq!(a.model_ms, b.model_ms);
    assert_eq!(a.visibility, b.visibility);
    let phases = |o: &FrameOutput| {
        o.phases
            .iter()
            .map(|p| (p.name.clone(), p.model_ms, p.counters.clone()))
            .collect::<Vec<_>>()
    };
    assert_eq!(phases(&a), phases(&b));
}

#[test]
fn the_model_counts_the_passes_of_the_paper() {
    let f = frame(0.5, None);
    let (native, model) = (
        penumbra_map(Backend::CpuNative, &f),
        penumbra_map(Backend::CpuModel, &f),
    );
    assert_eq!(native.visibility, model.visibility);
    let names: Vec<&str> = model.phases.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(
        names,
        ["shadow_map", "silhouettes", "penumbra_map", "eye_lookup"]
    );
    let pm = &model.phases[2].counters;
    let get = |k: &str| pm.get(k).unwrap_or(0.0);
    // Cones and sheets were drawn; fragments behind the shadow-map surface were discarded.
    assert!(get("fill") > 0.0);
    assert!(get("overdraw") > 0.0 && get("overdraw") < get("fill"));
    assert_eq!(get("overdraw"), get("raster.discarded"));
    assert!(get("mem.penumbra_map.color.write_bytes") > 0.0);
    assert!(get("mem.shadow_map.depth.read_bytes") > 0.0);
    let sil = &model.phases[1].counters;
    assert!(sil.get("silhouette.edges").unwrap() >= 3.0);
    assert!(model.phases[1].model_ms.unwrap() > 0.0);
    // Background pixels are lit; everything is a fraction.
    for (i, &v) in model.visibility.data.iter().enumerate() {
        assert!(v.is_finite() && (0.0..=1.0).contains(&v), "{v}");
        if !f.gbuffer.is_hit(i) {
            assert_eq!(v, 1.0);
        }
    }
}

#[test]
fn a_tiny_light_gives_the_hard_shadow() {
    // With a vanishing light the cones and sheets have no width: the penumbra map is the hard
    // shadow map, pixel for pixel, up to the silhouette's own texels.
    let f = frame(1e-4, None);
    let pm = penumbra_map(Backend::CpuNative, &f).visibility;
    let hard = algorithms::run(
        "hard_shadow_map",
        Backend::CpuNative,
        &f,
        &ExecContext::default(),
    )
    .unwrap()
    .visibility;
    let differ = (0..pm.data.len())
        .filter(|&i| (pm.data[i] - hard.data[i]).abs() > 0.05)
        .count();
    assert!(differ <= 2, "{differ} pixels differ");
    assert!(umbra(&hard, &f) > 20);
}

#[test]
fn bad_penumbra_map_options_name_the_field() {
    for (options, field) in [
        (
            r#"{"cone_segments": 2}"#,
            "$.options.penumbra_map.cone_segments",
        ),
        (
            r#"{"max_sheet_strips": 0}"#,
            "$.options.penumbra_map.max_sheet_strips",
        ),
        (
            r#"{"bias": {"constant": -1.0, "slope": 1.0}}"#,
            "$.options.penumbra_map.bias.constant",
        ),
        (
            r#"{"cone_segments": "many"}"#,
            "$.options.penumbra_map.cone_segments",
        ),
    ] {
        let text = format!(
            r#"{{"scene": {{"generator": "blob-on-plane"}}, "algorithms": ["penumbra_map"],
                 "options": {{"penumbra_map": {options}}}}}"#
        );
        let e = Loaded::from_str(&text, std::path::Path::new("s.json")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
    }
}
