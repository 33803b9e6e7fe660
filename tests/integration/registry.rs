//! The registry-driven parity checks: every registered algorithm, on its default options and
//! on each of its option sets ([`Algorithm::OPTION_SETS`]), on two generated scenes.
//! `cpu-native` and `cpu-model` run the same kernels (only the probe differs), so their images
//! are identical bit for bit; `wgpu` computes the same formulas through a GPU pipeline, so its
//! image and counters are within the algorithm's stated [`WgpuParity`] of `cpu-model`: its mean
//! difference, its largest difference, and the share of pixels that differ beyond rounding and
//! by more than 0.1.
//!
//! The checks are one module per algorithm (`parity_tests!`), so `cargo test --release
//! registry::soft_shadow_volume` runs one algorithm's and a failure names it; a test checks
//! that the list holds every algorithm with all three executions.
//!
//! [`Algorithm::OPTION_SETS`]: shadowbench::algorithms::Algorithm::OPTION_SETS
//! [`WgpuParity`]: shadowbench::algorithms::WgpuParity

use shadowbench::algorithms::{
    self, AlgorithmInfo, Backend, ExecContext, FrameOutput, WgpuParity, ALGORITHMS,
};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::light_as;
use shadowbench::metrics;
use shadowbench::scene::generators::{self, GeneratorParams};

use super::gpu_check::have_gpu;

const SCENES: [&str; 2] = ["sphere-on-plane", "torus-on-plane"];

/// A 48×36 frame of generated scene `name` (map 128², tiles 16) with its light converted to
/// the first kind `info` handles, so every option set (light splitting needs a rectangle)
/// applies.
fn frame(name: &str, info: &AlgorithmInfo) -> Frame {
    let mut scene = generators::find(name)
        .unwrap()
        .build(&GeneratorParams::default());
    scene.light = light_as(scene.light, info.lights[0], scene.bounds().center());
    let params = RunParams::of_scene(&scene, [48, 36], 128, 16);
    Frame::new(scene, params)
}

/// The default options and every option set of `info`, as execution contexts.
fn option_sets(info: &'static AlgorithmInfo) -> Vec<(String, ExecContext)> {
    let mut sets = vec![("{}".to_string(), ExecContext::default())];
    for json in info.option_sets {
        let mut ctx = ExecContext::default();
        let value: serde_json::Value = serde_json::from_str(json)
            .unwrap_or_else(|e| panic!("{}: option set {json}: {e}", info.id));
        ctx.options.insert(info.id.to_string(), value);
        info.check_options(&ctx.options)
            .unwrap_or_else(|e| panic!("{}: option set {json}: {e}", info.id));
        sets.push((json.to_string(), ctx));
    }
    for (_, ctx) in &mut sets {
        ctx.reference_samples = 4;
    }
    sets
}

/// `ctx` with the cpu executions rounding half-float blends as the adapter of the wgpu run `gpu`
/// did, where it records how (`execution.fp16_blend_rounding`: Vulkan leaves the rounding of
/// blending to the implementation, and `soft_shadow_map`'s option `fp16_rounding` chooses the
/// cpu executions').
pub fn rounding_as_adapter(id: &str, ctx: &ExecContext, gpu: &FrameOutput) -> ExecContext {
    let mut ctx = ctx.clone();
    if let Some(r) = gpu.execution.get("fp16_blend_rounding") {
        let options = ctx
            .options
            .entry(id.to_string())
            .or_insert(serde_json::json!({}));
        options["fp16_rounding"] = r.clone();
    }
    ctx
}

fn run(info: &AlgorithmInfo, backend: Backend, frame: &Frame, ctx: &ExecContext) -> FrameOutput {
    algorithms::run(info.id, backend, frame, ctx)
        .unwrap_or_else(|e| panic!("{} on {backend}: {e}", info.id))
}

/// `id`'s `cpu-native` and `cpu-model` images are identical bit for bit on every option set.
fn cpu_executions_agree(id: &str) {
    let info = info(id);
    for name in SCENES {
        let frame = frame(name, info);
        for (options, ctx) in option_sets(info) {
            let native = run(info, Backend::CpuNative, &frame, &ctx);
            let model = run(info, Backend::CpuModel, &frame, &ctx);
            assert!(
                native.visibility.data == model.visibility.data,
                "{} {options} on {name}: cpu-native and cpu-model images differ",
                info.id
            );
            // The record says which options ran: every one the set gives, with its value.
            let given: serde_json::Value = serde_json::from_str(&options).unwrap();
            let recorded = &native.execution.get("options");
            for (k, v) in given.as_object().unwrap() {
                let ran = recorded.and_then(|r| r.get(k));
                assert_eq!(ran, Some(v), "{} {options}: execution.options", info.id);
            }
        }
    }
}

/// `id`'s `wgpu` image and counters are within its stated parity of `cpu-model` on every
/// option set (skipped without an adapter).
fn wgpu_agrees(id: &str) {
    if !have_gpu() {
        return;
    }
    let info = info(id);
    let parity = info.wgpu_parity;
    for name in SCENES {
        let frame = frame(name, info);
        let mask = frame.gbuffer.mask();
        for (options, ctx) in option_sets(info) {
            let what = format!("{} {options} on {name}", info.id);
            let gpu = run(info, Backend::Wgpu, &frame, &ctx);
            let ctx = rounding_as_adapter(info.id, &ctx, &gpu);
            let model = run(info, Backend::CpuModel, &frame, &ctx);
            gpu.visibility.check_range().unwrap();
            let e = metrics::compare(&gpu.visibility, &model.visibility, &mask);
            let (mae, over) = (e.mae.unwrap(), e.frac_over_0_1.unwrap());
            let d = super::conformance::Difference::of(
                &gpu.visibility,
                &model.visibility,
                &mask,
                WgpuParity::ROUNDING,
            );
            let differing = d.over as f64 / d.pixels as f64;
            eprintln!(
                "{what}: mae {mae:.2e}, max {:.4}, frac>0.1 {over:.4}, differing {differing:.4}",
                d.max
            );
            assert!(e.shadow_pixels > 20, "{what}: no shadow on screen: {e:?}");
            assert!(mae <= parity.mae, "{what}: {e:?}");
            assert!(d.max <= parity.max, "{what}: {d:?}");
            assert!(over <= parity.frac_over_0_1, "{what}: {e:?}");
            assert!(differing <= parity.frac_differing, "{what}: {d:?}");
            let fill = model.counters.get("fill").unwrap_or(0.0);
            for (k, &m) in &model.counters.0 {
                let Some(g) = gpu.counters.get(k) else {
                    continue;
                };
                if shadowbench::counters::DERIVED.contains(&k.as_str()) {
                    continue;
                }
                match parity.differ.iter().find(|(name, _)| name == k) {
                    None => assert_eq!(g, m, "{what}: {k} {g} on wgpu, {m} on cpu-model"),
                    Some((_, Some(f))) => assert!(
                        (g - m).abs() <= f * fill,
                        "{what}: {k} {g} on wgpu, {m} on cpu-model (fill {fill})"
                    ),
                    Some((_, None)) => {}
                }
            }
        }
    }
}

/// The registered algorithm `id`, which has all three executions (checked by
/// [`every_algorithm_with_three_executions_has_its_parity_tests`]).
fn info(id: &str) -> &'static AlgorithmInfo {
    algorithms::find(id).unwrap_or_else(|e| panic!("{e}"))
}

/// One module of parity tests per algorithm, so that `cargo test registry::<algorithm>` runs
/// one algorithm's and a failure names it; `LISTED` is the list, checked against the registry.
macro_rules! parity_tests {
    ($($id:ident),* $(,)?) => {
        $(
            mod $id {
                #[test]
                fn cpu_native_and_cpu_model_images_are_identical_on_every_option_set() {
                    super::cpu_executions_agree(stringify!($id));
                }

                #[test]
                fn wgpu_is_within_its_stated_parity_of_the_cpu_model_on_every_option_set() {
                    super::wgpu_agrees(stringify!($id));
                }
            }
        )*
        const LISTED: &[&str] = &[$(stringify!($id)),*];
    };
}

parity_tests!(
    hard_shadow_map,
    pcss,
    soft_izb,
    accum_hard,
    soft_shadow_volume,
    penumbra_map,
    soft_shadow_map,
    dbuffer,
    rt_denoised,
);

#[test]
fn every_algorithm_with_three_executions_has_its_parity_tests() {
    let mut registered: Vec<&str> = ALGORITHMS
        .iter()
        .filter(|a| {
            [Backend::CpuNative, Backend::CpuModel, Backend::Wgpu]
                .iter()
                .all(|b| a.backends.contains(b))
        })
        .map(|a| a.id)
        .collect();
    let mut listed = LISTED.to_vec();
    registered.sort_unstable();
    listed.sort_unstable();
    assert_eq!(
        listed, registered,
        "parity_tests! in tests/integration/registry.rs must list every algorithm with all \
         three executions"
    );
}

/// A work estimate is made of the options a run will use ([`shadowbench::algorithms::Configured`]): options that do not
/// parse configure no algorithm (the error names `$.options.<id>`), never one of the defaults;
/// and an option the estimate depends on changes it (accum_hard's light samples, 16 → 256:
/// ×16, `samples × pixels × 3`).
#[test]
fn work_is_estimated_from_the_configured_options() {
    let mut refused = 0;
    for info in ALGORITHMS {
        let f = frame("sphere-on-plane", info);
        let extent = shadowbench::algorithms::work::SceneExtent::of(&f.scene);
        let ctx = ExecContext::default();
        let defaults = info.configure(&ctx.options).unwrap();
        let w = defaults.work_estimate(&extent, &f.params, &ctx);
        assert!(w.is_finite() && w > 0.0, "{}: {w}", info.id);
        let bad = serde_json::json!({ "no_such_option": 1 });
        let options = std::collections::BTreeMap::from([(info.id.to_string(), bad)]);
        if let Err(e) = info.configure(&options) {
            let text = e.to_string();
            assert!(text.contains(&format!("$.options.{}", info.id)), "{text}");
            refused += 1;
        }
    }
    assert!(
        refused > ALGORITHMS.len() / 2,
        "{refused} algorithms refuse an unknown option"
    );
    let info = shadowbench::algorithms::find("accum_hard").unwrap();
    let f = frame("sphere-on-plane", info);
    let extent = shadowbench::algorithms::work::SceneExtent::of(&f.scene);
    let ctx = ExecContext::default();
    let with = |samples: u32| {
        let o = serde_json::json!({ "samples": samples });
        let options = std::collections::BTreeMap::from([("accum_hard".to_string(), o)]);
        let c = info.configure(&options).unwrap();
        c.work_estimate(&extent, &f.params, &ctx)
    };
    assert_eq!(with(256), 16.0 * with(16));
}
