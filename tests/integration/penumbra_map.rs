//! Penumbra maps (paper 000) on the CPU executions, checked against the ray-traced reference and
//! the paper's stated properties: only the outer penumbra is computed, so the umbra is
//! overestimated, more so for larger lights (§4.1); shadows harden as the occluder approaches the
//! receiver (§1); counters are deterministic. The wgpu execution is checked against cpu-model
//! (skipped without an adapter unless `SHADOWBENCH_REQUIRE_GPU=1`), and the simplified shadow
//! mesh against the full one.

use shadowbench::algorithms::{self, Backend, ExecContext, FrameOutput};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::{light_as, ReferenceCache};
use shadowbench::metrics;
use shadowbench::scenario::Loaded;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::LightKind;
use shadowbench::visibility::VisibilityBuffer;

use super::gpu_check;
use gpu_check::have_gpu;

/// The paper-000 stand-in scene, small: a lumpy blob over the ground.
fn frame(light_size: f32, occluder_height: Option<f32>) -> Frame {
    let mut scene = generators::find("blob-on-plane")
        .unwrap()
        .build(&GeneratorParams {
            triangles: Some(2_000),
            seed: 1,
            occluder_height,
            occluder_offset: None,
        });
    scene.light = scene.light.with_size(light_size);
    let params = RunParams {
        triangles: scene.triangle_count() as u32,
        light_size,
        map_resolution: 512,
        tile_size: 32,
        image: [64, 48],
        occluder_height,
        occluder_offset: None,
        cores: None,
    };
    Frame::new(scene, params)
}

fn penumbra_map(backend: Backend, f: &Frame) -> FrameOutput {
    algorithms::run("penumbra_map", backend, f, &ExecContext::default()).unwrap()
}

fn reference(f: &Frame) -> VisibilityBuffer {
    ReferenceCache::new(None, 64, 1)
        .get_or_compute(f)
        .unwrap()
        .0
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
    assert!(get("mem_model.penumbra_map.color.write_bytes") > 0.0);
    assert!(get("mem_model.shadow_map.depth.read_bytes") > 0.0);
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
        (
            r#"{"shadow_mesh_triangles": 0}"#,
            "$.options.penumbra_map.shadow_mesh_triangles",
        ),
        (
            r#"{"shadow_mesh_triangles": -500}"#,
            "$.options.penumbra_map.shadow_mesh_triangles",
        ),
        (
            r#"{"shadow_mesh_triangles": 2.5}"#,
            "$.options.penumbra_map.shadow_mesh_triangles",
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

/// A 64×48 frame of generated scene `name` with a sphere light of radius `light_size`.
fn small_frame(name: &str, light_size: f32) -> Frame {
    let mut scene = generators::find(name)
        .unwrap()
        .build(&GeneratorParams::default());
    let light = scene.light.with_size(light_size);
    scene.light = light_as(light, LightKind::Sphere, scene.bounds().center());
    let params = RunParams::of_scene(&scene, [64, 48], 256, 32);
    Frame::new(scene, params)
}

#[test]
fn wgpu_agrees_with_the_cpu_model() {
    if !have_gpu() {
        return;
    }
    for name in ["sphere-on-plane", "box-on-plane", "torus-on-plane"] {
        let f = small_frame(name, 1.2);
        let (gpu, model) = (
            penumbra_map(Backend::Wgpu, &f),
            penumbra_map(Backend::CpuModel, &f),
        );
        let e = metrics::compare(&gpu.visibility, &model.visibility, &f.gbuffer.mask());
        eprintln!("{name}: {e:?}");
        // Both draw the same triangles (one geometry builder) through the same formulas in
        // f32, but not through the same rasterizer: the model's fixed-point edges and its
        // barycentric depth (clamped to the triangle's range) against the driver's plane
        // equations, and the model clips only at the near plane where a GPU also clips at the
        // far plane (the cones' bases lie on it). So a fragment's depth differs in its last
        // bits, which moves eq. 1 by ~1e-3, and a fragment right at the shadow-map surface can
        // be discarded on one and kept on the other, which changes its texel by up to the
        // intensity there; a texel that a triangle edge crosses exactly at its centre could
        // change hands. Measured on llvmpipe (light 1.2, 256² map): MAE 0.8e-5 to 1.6e-5, max
        // 0.0024, no pixel over 0.1, fill equal and overdraw within one fragment. The bounds
        // below leave room for other drivers' rounding: MAE under 1e-3 and at most 0.5% of the
        // pixels over 0.1 (about a dozen of a 64×48 image, a texel's worth at a shadow's edge).
        assert!(e.mae.unwrap() < 1e-3, "{name}: {e:?}");
        assert!(e.frac_over_0_1.unwrap() < 0.005, "{name}: {e:?}");
        assert!(e.shadow_pixels > 50, "{name}: no shadow to compare: {e:?}");
        let phase = |o: &FrameOutput, name: &str| {
            o.phases
                .iter()
                .find(|p| p.name == name)
                .unwrap_or_else(|| panic!("no phase {name}"))
                .counters
                .clone()
        };
        // The silhouettes and the geometry are the same code on both.
        for k in [
            "silhouette.edges",
            "silhouette.vertices",
            "silhouette.max_edges_per_vertex",
        ] {
            assert_eq!(
                phase(&gpu, "silhouettes").get(k),
                phase(&model, "silhouettes").get(k),
                "{name}: {k}"
            );
        }
        for k in ["penumbra.cone_triangles", "penumbra.sheet_triangles"] {
            assert_eq!(
                phase(&gpu, "penumbra_map").get(k),
                phase(&model, "penumbra_map").get(k),
                "{name}: {k}"
            );
        }
        // Fill and overdraw of the cones and sheets: the same triangles rasterized at texel
        // centres with the top-left rule; allow 1% for edges through texel centres, the
        // far-plane clip and discards decided by the last bit of a depth.
        for k in ["fill", "overdraw"] {
            let (g, m) = (
                phase(&gpu, "penumbra_map").get(k).unwrap(),
                phase(&model, "penumbra_map").get(k).unwrap(),
            );
            assert!(m > 0.0, "{name}: {k}: the model rasterized nothing");
            assert!(
                (g - m).abs() <= 0.01 * m,
                "{name}: {k} {g} on wgpu, {m} on cpu-model"
            );
        }
    }
}

#[test]
fn wgpu_records_the_phases_of_the_paper() {
    if !have_gpu() {
        return;
    }
    let gpu = shadowbench::gpu::gpu().unwrap();
    let f = small_frame("sphere-on-plane", 0.5);
    let out = penumbra_map(Backend::Wgpu, &f);
    let names: Vec<&str> = out.phases.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(
        names,
        ["shadow_map", "silhouettes", "penumbra_map", "eye_lookup"]
    );
    // GPU time for the three GPU passes; the silhouettes are host work.
    assert_eq!(out.phases[1].gpu_ms, None);
    if gpu.queries.timestamp {
        let total: f64 = out.phases.iter().filter_map(|p| p.gpu_ms).sum();
        assert!((out.gpu_ms.unwrap() - total).abs() < 1e-9);
        assert!(out.phases[2].gpu_ms.unwrap() > 0.0);
    }
    let pm = &out.phases[2].counters;
    let get = |k: &str| pm.get(k).unwrap_or(0.0);
    assert!(
        get("overdraw") > 0.0 && get("overdraw") < get("fill"),
        "{pm:?}"
    );
    let texels = f64::from(f.params.map_resolution).powi(2);
    assert!(get("mem_est.penumbra_map.write_bytes") >= 4.0 * texels);
    if gpu.queries.pipeline_statistics {
        // The cones and sheets are drawn once: one clipper invocation per triangle.
        let triangles = get("penumbra.cone_triangles") + get("penumbra.sheet_triangles");
        assert_eq!(pm.get("pipeline.clipper_invocations"), Some(triangles));
    }
    // Every receiver the hard test leaves lit reads the penumbra map once.
    let hard = algorithms::run(
        "hard_shadow_map",
        Backend::Wgpu,
        &f,
        &ExecContext::default(),
    )
    .unwrap()
    .visibility;
    let lit = count(&hard, &f, |v| v == 1.0) as f64;
    let taps = out.phases[3].counters.get("penumbra_map.taps").unwrap();
    assert!(
        (taps - lit).abs() <= 0.01 * lit,
        "penumbra taps {taps}, lit pixels {lit}"
    );
}

fn with_options(options: serde_json::Value) -> ExecContext {
    ExecContext {
        options: [("penumbra_map".to_string(), options)].into(),
        ..Default::default()
    }
}

#[test]
fn a_simplified_shadow_mesh_keeps_the_shadow() {
    use shadowbench::algorithms::penumbra_map::{shadow_geometry, PenumbraMap};
    use shadowbench::algorithms::Algorithm;
    // §5: "we could get equivalent quality shadows with simplified models, as soft shadows
    // effectively blur detail". An 18K-triangle blob casts its shadow from 2K triangles.
    let mut scene = generators::find("blob-on-plane")
        .unwrap()
        .build(&GeneratorParams {
            triangles: Some(20_000),
            seed: 1,
            occluder_height: None,
            occluder_offset: None,
        });
    scene.light = scene.light.with_size(0.5);
    let params = RunParams::of_scene(&scene, [96, 72], 512, 32);
    let f = Frame::new(scene, params);
    let full = penumbra_map(Backend::CpuNative, &f);
    let target = 2_000;
    let ctx = with_options(serde_json::json!({ "shadow_mesh_triangles": target }));
    let g = shadow_geometry(&f, &PenumbraMap::options(&ctx.options).unwrap());
    let (n, before) = (
        g.occluders.triangles.len(),
        f.scene.occluders().triangles.len(),
    );
    assert!(before > 8 * target, "{before}");
    assert!(n <= target && n >= target / 2, "{n} triangles for {target}");
    // The ground is a receiver only: the shadow map keeps it whole.
    let ground = f.scene.objects[0].mesh.triangles.len();
    assert_eq!(g.shadow_map.triangles.len(), n + ground);

    let simplified = algorithms::run("penumbra_map", Backend::CpuNative, &f, &ctx).unwrap();
    let mask = f.gbuffer.mask();
    let e = metrics::compare(&simplified.visibility, &full.visibility, &mask);
    let rf = reference(&f);
    let (es, ef) = (
        metrics::compare(&simplified.visibility, &rf, &mask),
        metrics::compare(&full.visibility, &rf, &mask),
    );
    eprintln!(
        "{n} of {before} triangles: against the full mesh {e:?}; MAE against the reference {} \
         (full mesh {})",
        es.mae.unwrap(),
        ef.mae.unwrap()
    );
    // Measured: 2000 of 17956 triangles, MAE 4.6e-4 against the full mesh's result (largest
    // difference 0.085, no pixel over 0.1), and against the reference MAE 0.0250 with the
    // simplified mesh, 0.0253 with the full one.
    assert!(e.mae.unwrap() < 0.005, "{e:?}");
    assert!(e.frac_over_0_1.unwrap() < 0.005, "{e:?}");
    assert!(es.mae.unwrap() < ef.mae.unwrap() + 0.005, "{es:?} {ef:?}");

    // A target above the mesh's size changes nothing.
    let all = with_options(serde_json::json!({ "shadow_mesh_triangles": 100_000 }));
    let same = algorithms::run("penumbra_map", Backend::CpuNative, &f, &all).unwrap();
    assert_eq!(same.visibility, full.visibility);

    // The wgpu execution draws the same simplified mesh.
    if have_gpu() {
        let gpu = algorithms::run("penumbra_map", Backend::Wgpu, &f, &ctx).unwrap();
        let e = metrics::compare(&gpu.visibility, &simplified.visibility, &mask);
        assert!(
            e.mae.unwrap() < 1e-3 && e.frac_over_0_1.unwrap() < 0.005,
            "{e:?}"
        );
        let edges = |o: &FrameOutput| o.phases[1].counters.get("silhouette.edges");
        assert_eq!(edges(&gpu), edges(&simplified));
    }
}

/// Four pillars 4 units tall around a sphere light 2 units above the ground (a common engine
/// report: casters taller than the light), seen from above, as the ground is a receiver only.
/// The pillars' tops lie behind the light view's plane; the far ground beyond the view's 80°.
fn pillars() -> Frame {
    use glam::Vec3;
    use shadowbench::scene::generators::primitives;
    use shadowbench::scene::{Camera, Light, Object, Role, Scene};
    let mut objects = vec![Object {
        name: "ground".into(),
        mesh: primitives::plane(6.0, 8),
        role: Role::RECEIVER,
    }];
    for (x, z) in [(-2.0, -2.0), (2.0, -2.0), (-2.0, 2.0), (2.0, 2.0)] {
        objects.push(Object {
            name: format!("pillar {x} {z}"),
            mesh: primitives::cuboid(
                Vec3::new(x - 0.25, 0.0, z - 0.25),
                Vec3::new(x + 0.25, 4.0, z + 0.25),
            ),
            role: Role::BOTH,
        });
    }
    let scene = Scene {
        name: "pillars".into(),
        objects,
        camera: Camera {
            eye: Vec3::new(0.0, 9.0, 9.0),
            target: Vec3::new(0.0, 0.5, 0.0),
            up: Vec3::Y,
            fov_y_deg: 50.0,
        },
        light: Light::Sphere {
            center: Vec3::new(0.3, 2.0, 0.2),
            radius: 0.2,
        },
        light_texture: None,
    };
    let params = RunParams::of_scene(&scene, [96, 72], 512, 32);
    Frame::new(scene, params)
}

/// Pillars taller than the light: the silhouette edges running behind the light view's plane
/// are cut at its near plane, so the three executions agree and the image is what the
/// warnings say. Oracles: the reference, and the light view's own frustum. Every pixel facing
/// the light centre that the single view cannot hold (the count its warning gives) is shown
/// lit; every pixel lighter than
/// the reference by more than 0.45 is one of them; a pixel darker than the reference by more
/// than 0.45 lies in the reference's penumbra (the outer-penumbra limit: the map's penumbra
/// starts at the hard edge of the light centre's shadow, and its cones are circles in the far
/// plane, too narrow far off the view's axis, §3), but for a few pixels of rasterized edges.
/// Before the cut, 5,438 of 16,528 pixels of the 160×120 scene were darker than the reference,
/// most of them fully lit ground.
#[test]
fn pillars_taller_than_the_light_give_the_image_the_warnings_describe() {
    use shadowbench::algorithms::shadow_map::{LightViews, ViewFit};
    let f = pillars();
    let truth = reference(&f);
    let mut runs = vec![
        penumbra_map(Backend::CpuNative, &f),
        penumbra_map(Backend::CpuModel, &f),
    ];
    if have_gpu() {
        runs.push(penumbra_map(Backend::Wgpu, &f));
    }
    let g = &f.gbuffer;
    let views = LightViews::fit(&f, ViewFit::Single);
    let view = &views.views[0].view;
    let hits: Vec<usize> = (0..g.len()).filter(|&i| g.is_hit(i)).collect();
    let outside: Vec<usize> = hits
        .iter()
        .copied()
        .filter(|&i| {
            let p = g.position[i];
            !view.contains(p) && g.normal[i].dot(f.scene.light.center() - p) > 0.0
        })
        .collect();
    assert!(outside.len() * 20 > hits.len(), "{} outside", outside.len());
    for out in &runs {
        let counted = out.counters.get("light_view.receivers_outside").unwrap() as usize;
        assert_eq!(counted, outside.len());
        let warned = out.warnings.iter().find(|w| w.contains("taken as lit"));
        assert!(
            warned.is_some_and(|w| w.starts_with(&format!("{counted} "))),
            "{:?}",
            out.warnings
        );
        let v = &out.visibility.data;
        assert!(outside.iter().all(|&i| v[i] == 1.0), "outside and not lit");
        let lighter: Vec<usize> = hits
            .iter()
            .copied()
            .filter(|&i| v[i] > truth.data[i] + 0.45)
            .collect();
        let lighter_inside = lighter.iter().filter(|i| !outside.contains(i)).count();
        let darker = hits.iter().filter(|&&i| v[i] < truth.data[i] - 0.45);
        let darker_lit = darker
            .filter(|&&i| truth.data[i] >= metrics::SHADOW_THRESHOLD)
            .count();
        eprintln!(
            "pillars: {} outside the view; lighter than the reference by > 0.45: {} ({lighter_inside} \
             inside the view); lit pixels darker by > 0.45: {darker_lit}; of {}",
            outside.len(),
            lighter.len(),
            hits.len()
        );
        // A few pixels of rasterized edges and of the bias where a pillar meets the ground.
        assert!((darker_lit + lighter_inside) * 200 <= hits.len());
    }
    let mask = g.mask();
    for out in &runs[1..] {
        let d =
            super::conformance::Difference::of(&out.visibility, &runs[0].visibility, &mask, 0.1);
        assert_eq!(d.over_0_45, 0, "{d:?}");
        assert!(d.over_0_1 * 1000 <= d.pixels, "{d:?}");
    }
}
