//! Properties every registered algorithm must have on every CPU execution: degenerate scenes
//! give a result in [0, 1] or a clear failure (never a panic), and counters, modelled times
//! and images do not depend on the host thread count.

use super::common;

use super::common::run_one;
use common::degenerate_scenes;
use shadowbench::algorithms::{Backend, ExecContext, ALGORITHMS};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::light_as;
use shadowbench::scene::generators::{self, GeneratorParams};

/// The frame with its light converted to one `algorithm` handles, as the harness does.
fn for_algorithm(frame: &Frame, algorithm: &str) -> Frame {
    let info = shadowbench::algorithms::find(algorithm).unwrap();
    let mut scene = frame.scene.clone();
    let kind = info.light_for(scene.light.kind());
    scene.light = light_as(scene.light, kind, scene.bounds().center());
    Frame::new(scene, frame.params.clone())
}

fn cpu_backends(backends: &[Backend]) -> impl Iterator<Item = Backend> + '_ {
    backends.iter().copied().filter(|b| *b != Backend::Wgpu)
}

#[test]
fn degenerate_scenes_never_panic_nor_leave_the_unit_range() {
    let ctx = ExecContext {
        reference_samples: 4,
        ..Default::default()
    };
    for (scene, frame) in degenerate_scenes() {
        for info in ALGORITHMS {
            let frame = for_algorithm(&frame, info.id);
            for backend in cpu_backends(info.backends) {
                let (record, out) = run_one(&frame, info.id, backend, &ctx, None);
                // run_one turns panics and out-of-range values into failures; neither may happen.
                if let Some(f) = &record.failure {
                    assert!(
                        !f.contains("panic") && !f.contains("invalid result"),
                        "{} on {backend} with {scene}: {f}",
                        info.id
                    );
                } else {
                    let v = &out.expect("a run without failure has output").visibility;
                    assert!(v.check_range().is_ok(), "{} {backend} {scene}", info.id);
                }
            }
        }
    }
}

#[test]
fn every_algorithm_is_deterministic_across_host_threads() {
    let scene = generators::find("torus-on-plane")
        .unwrap()
        .build(&GeneratorParams::default());
    let params = RunParams::of_scene(&scene, [48, 36], 128, 16);
    let base = Frame::new(scene, params);
    let ctx = ExecContext {
        reference_samples: 16,
        ..Default::default()
    };
    for info in ALGORITHMS {
        let frame = for_algorithm(&base, info.id);
        for backend in cpu_backends(info.backends) {
            let run = |threads: usize| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| run_one(&frame, info.id, backend, &ctx, None))
            };
            let ((a, va), (b, vb)) = (run(1), run(2));
            assert!(
                a.failure.is_none(),
                "{} {backend}: {:?}",
                info.id,
                a.failure
            );
            assert_eq!(a.counters, b.counters, "{} {backend}", info.id);
            assert_eq!(a.model_ms, b.model_ms, "{} {backend}", info.id);
            let phase_models = |r: &shadowbench::record::RunRecord| {
                r.phases.iter().map(|p| p.model_ms).collect::<Vec<_>>()
            };
            assert_eq!(phase_models(&a), phase_models(&b), "{} {backend}", info.id);
            let bits = |v: Option<shadowbench::algorithms::FrameOutput>| {
                v.unwrap()
                    .visibility
                    .data
                    .iter()
                    .map(|x| x.to_bits())
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(va), bits(vb), "{} {backend}", info.id);
        }
    }
}

/// Every counter name of every record (and phase) is in the glossary (`shadowbench::counters`)
/// and recorded by that execution; every figure `compare` reads, and every time, takes its kind
/// and direction from the glossary; every record that counts fill and overdraw carries the
/// derived `overdraw_ratio` = overdraw / fill.
fn check_counter_names(record: &shadowbench::record::RunRecord) {
    let judged = shadowbench::report::compare::deterministic_figures(record);
    let times = ["wall_ms", "gpu_ms", "model_ms"].map(String::from);
    let phase_times = record
        .phases
        .iter()
        .map(|p| format!("phase.{}.wall_ms", p.name));
    for figure in judged.keys().chain(&times).cloned().chain(phase_times) {
        assert!(
            shadowbench::counters::direction(&figure).is_some()
                && shadowbench::counters::kind(&figure).is_some(),
            "{} {}: figure '{figure}' has no direction and kind in the glossary",
            record.algorithm,
            record.backend
        );
    }
    let all = std::iter::once(&record.counters).chain(record.phases.iter().map(|p| &p.counters));
    for c in all {
        for name in c.0.keys() {
            let entry = shadowbench::counters::find(name).unwrap_or_else(|| {
                panic!(
                    "{} {}: counter '{name}' is not in the glossary",
                    record.algorithm, record.backend
                )
            });
            assert!(
                entry.recorded.backends().contains(&record.backend),
                "{} {}: '{name}' is documented as recorded by {:?} only",
                record.algorithm,
                record.backend,
                entry.recorded
            );
        }
        if let (Some(fill), Some(overdraw)) = (c.get("fill"), c.get("overdraw")) {
            if fill > 0.0 {
                assert_eq!(
                    c.get("overdraw_ratio"),
                    Some(overdraw / fill),
                    "{} {}",
                    record.algorithm,
                    record.backend
                );
            }
        }
    }
}

#[test]
fn every_cpu_counter_is_in_the_glossary_and_derived_figures_are_everywhere() {
    let scene = generators::find("sphere-on-plane")
        .unwrap()
        .build(&GeneratorParams::default());
    let params = RunParams::of_scene(&scene, [32, 24], 64, 16);
    let frame = Frame::new(scene, params);
    let ctx = ExecContext {
        reference_samples: 4,
        ..Default::default()
    };
    for info in ALGORITHMS {
        let frame = for_algorithm(&frame, info.id);
        for backend in cpu_backends(info.backends) {
            let (record, _) = run_one(&frame, info.id, backend, &ctx, None);
            assert!(record.failure.is_none(), "{:?}", record.failure);
            check_counter_names(&record);
        }
    }
}
