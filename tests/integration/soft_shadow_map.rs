//! Soft shadow maps (paper 002) on the CPU executions, against the ray-traced reference and the
//! paper's stated properties: a square plate parallel to the light is close to exact (§5.2.3);
//! two passes beat one on a thick occluder (§3.5, Figure 17); FP16 accumulation fails as the map
//! resolution grows while FP32 does not (§5.1.3, Appendix A); counters are deterministic.

use shadowbench::algorithms::{self, Backend, ExecContext, FrameOutput};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::{light_as, ReferenceCache};
use shadowbench::metrics::compare;
use shadowbench::scenario::Loaded;
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::scene::LightKind;
use shadowbench::visibility::VisibilityBuffer;

fn frame(generator: &str, light_size: Option<f32>, map_resolution: u32) -> Frame {
    let mut scene = generators::find(generator)
        .unwrap()
        .build(&GeneratorParams::default());
    if let Some(s) = light_size {
        scene.light = scene.light.with_size(s);
    }
    scene.light = light_as(scene.light, LightKind::Rect, scene.bounds().center());
    let params = RunParams::of_scene(&scene, [128, 96], map_resolution, 32);
    Frame::new(scene, params)
}

/// The same frame at another map resolution (the reference does not depend on it).
fn at_resolution(f: &Frame, map_resolution: u32) -> Frame {
    let mut params = f.params.clone();
    params.map_resolution = map_resolution;
    Frame::new(f.scene.clone(), params)
}

fn ssm(backend: Backend, f: &Frame, options: serde_json::Value) -> FrameOutput {
    let mut ctx = ExecContext::default();
    ctx.options.insert("soft_shadow_map".into(), options);
    algorithms::run("soft_shadow_map", backend, f, &ctx).unwrap()
}

fn reference(f: &Frame) -> VisibilityBuffer {
    ReferenceCache::new(None, 256, 1)
        .get_or_compute(f)
        .unwrap()
        .0
}

/// Mean absolute error over the pixels in umbra or penumbra in either image (§5.2.1).
fn mae_shadow(v: &VisibilityBuffer, reference: &VisibilityBuffer, f: &Frame) -> f64 {
    compare(v, reference, &f.gbuffer.mask()).mae_shadow.unwrap()
}

#[test]
fn a_square_plate_parallel_to_the_light_matches_the_reference() {
    let f = frame("plate-on-plane", None, 256);
    let out = ssm(Backend::CpuModel, &f, serde_json::json!({}));
    let e = compare(&out.visibility, &reference(&f), &f.gbuffer.mask());
    eprintln!("plate, one pass, 256: {e:?}");
    assert!(e.mae_shadow.unwrap() < 0.03, "{e:?}");
    assert!(e.shadow_pixels > 100);
}

#[test]
fn two_passes_beat_one_on_a_thick_occluder() {
    let f = frame("torus-on-plane", None, 128);
    let r = reference(&f);
    let one = mae_shadow(
        &ssm(Backend::CpuNative, &f, serde_json::json!({})).visibility,
        &r,
        &f,
    );
    let two_out = ssm(Backend::CpuNative, &f, serde_json::json!({"passes": 2}));
    let two = mae_shadow(&two_out.visibility, &r, &f);
    eprintln!("torus, 128: one pass {one:.4}, two passes {two:.4}");
    assert!(two < one, "one pass {one}, two passes {two}");
    // A thin plate has no back to speak of: both passes give nearly the same shadow (§5.2.3).
    let p = frame("plate-on-plane", None, 128);
    let rp = reference(&p);
    let (a, b) = (
        mae_shadow(
            &ssm(Backend::CpuNative, &p, serde_json::json!({})).visibility,
            &rp,
            &p,
        ),
        mae_shadow(
            &ssm(Backend::CpuNative, &p, serde_json::json!({"passes": 2})).visibility,
            &rp,
            &p,
        ),
    );
    eprintln!("plate, 128: one pass {a:.4}, two passes {b:.4}");
    assert!((a - b).abs() < 0.01, "{a} vs {b}");
}

#[test]
fn fp16_error_grows_with_map_resolution_and_fp32_does_not() {
    let base = frame("plate-on-plane", Some(0.25), 64);
    let r = reference(&base);
    let mut rows = Vec::new();
    for res in [64, 128, 256] {
        let f = at_resolution(&base, res);
        let e32 = mae_shadow(
            &ssm(Backend::CpuNative, &f, serde_json::json!({})).visibility,
            &r,
            &f,
        );
        let e16 = mae_shadow(
            &ssm(
                Backend::CpuNative,
                &f,
                serde_json::json!({"precision": "fp16"}),
            )
            .visibility,
            &r,
            &f,
        );
        eprintln!("plate light 0.25, map {res}: fp32 {e32:.4}, fp16 {e16:.4}");
        rows.push((e32, e16));
    }
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    // FP16's excess over FP32 grows with the resolution; FP32 does not get worse.
    assert!(
        last.1 - last.0 > 2.0 * (first.1 - first.0).max(0.005),
        "{rows:?}"
    );
    assert!(last.0 <= first.0, "{rows:?}");
}

/// How the half-float sum rounds (option `fp16_rounding`, the GPU's choice): toward zero every
/// add can lose up to a whole half step, to nearest half of one, so against the exact (FP32)
/// sums the nearest image is closer, and toward zero only ever lightens: each rounded sum is at
/// most the exact one, so no pixel is darker than in FP32 beyond FP32's own rounding.
#[test]
fn fp16_rounding_to_nearest_loses_less_than_toward_zero() {
    let f = frame("plate-on-plane", Some(0.25), 256);
    let image = |o: serde_json::Value| ssm(Backend::CpuNative, &f, o).visibility;
    let exact = image(serde_json::json!({}));
    let rounded = |r: &str| image(serde_json::json!({"precision": "fp16", "fp16_rounding": r}));
    let (toward_zero, nearest) = (rounded("toward_zero"), rounded("nearest_even"));
    let mask = f.gbuffer.mask();
    let e_tz = compare(&toward_zero, &exact, &mask).mae.unwrap();
    let e_ne = compare(&nearest, &exact, &mask).mae.unwrap();
    eprintln!(
        "plate light 0.25, map 256, fp16 against fp32: toward zero {e_tz:.5}, nearest {e_ne:.5}"
    );
    assert!(e_ne < 0.75 * e_tz, "toward zero {e_tz}, nearest {e_ne}");
    let darker = (toward_zero.data.iter().zip(&exact.data))
        .filter(|(t, x)| **t < **x - 1e-5)
        .count();
    assert_eq!(darker, 0, "pixels darker with sums rounded toward zero");
}

#[test]
fn executions_agree_and_counters_do_not_depend_on_host_threads() {
    let f = frame("torus-on-plane", None, 64);
    let opts = serde_json::json!({"passes": 2});
    let in_pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| ssm(Backend::CpuModel, &f, opts.clone()))
    };
    let (a, b) = (in_pool(1), in_pool(2));
    assert_eq!(a.counters, b.counters);
    assert_eq!(a.model_ms, b.model_ms);
    assert_eq!(a.visibility, b.visibility);
    let native = ssm(Backend::CpuNative, &f, opts);
    assert_eq!(native.visibility, a.visibility);
    let names: Vec<&str> = a.phases.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["maps", "splat", "project"]);
    let get = |phase: usize, k: &str| a.phases[phase].counters.get(k).unwrap_or(0.0);
    // Two occluder maps of 64² f32 texels went to the host.
    assert_eq!(get(0, "transfer.bytes"), 2.0 * 64.0 * 64.0 * 4.0);
    assert!(get(0, "step.transfer.model_ms") > 0.0);
    assert!(get(1, "ssm.micro_patches") > 0.0);
    assert!(get(1, "fill") > get(1, "overdraw") && get(1, "overdraw") > 0.0);
    assert!(get(1, "mem_model.soft_shadow_map.color.write_bytes") > 0.0);
    for (i, &v) in a.visibility.data.iter().enumerate() {
        assert!(v.is_finite() && (0.0..=1.0).contains(&v), "{v}");
        if !f.gbuffer.is_hit(i) {
            assert_eq!(v, 1.0);
        }
    }
    // Without the transfer, no bytes and no transfer time.
    let gpu_only = ssm(
        Backend::CpuModel,
        &f,
        serde_json::json!({"occluder_map_transfer": false}),
    );
    assert_eq!(gpu_only.counters.get("transfer.bytes"), None);
}

#[test]
fn bad_soft_shadow_map_options_name_the_field() {
    for (options, field) in [
        (r#"{"passes": 3}"#, "$.options.soft_shadow_map.passes"),
        (
            r#"{"precision": "fp64"}"#,
            "$.options.soft_shadow_map.precision",
        ),
        (
            r#"{"occluder_map_transfer": "yes"}"#,
            "$.options.soft_shadow_map.occluder_map_transfer",
        ),
        (
            r#"{"transfer_gb_per_s": 0}"#,
            "$.options.soft_shadow_map.transfer_gb_per_s",
        ),
        (
            r#"{"bias_texels": -1}"#,
            "$.options.soft_shadow_map.bias_texels",
        ),
        (r#"{"pases": 2}"#, "$.options.soft_shadow_map.pases"),
    ] {
        let text = format!(
            r#"{{"scene": {{"generator": "plate-on-plane"}}, "algorithms": ["soft_shadow_map"],
                 "options": {{"soft_shadow_map": {options}}}}}"#
        );
        let e = Loaded::from_str(&text, std::path::Path::new("s.json")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
    }
}
