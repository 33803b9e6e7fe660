//! `cargo bench`: the figure the harness measures for a run's `wall_ms` — the host time of one
//! execution of an algorithm on a prepared frame (`algorithms::run`, its GPU setup included
//! only on the first call: criterion's warm-up absorbs it as the harness's cold iteration
//! does) — for every registered algorithm × execution: `cpu-native`, `cpu-model` (the same
//! kernels counted and cache-simulated; the ratio of the two is the model's overhead) and
//! `wgpu` where an adapter exists (skipped with a message otherwise).
//!
//! One small scene per family, the kind of scene its papers evaluate on ([`family_scene`]),
//! 2,000 triangles at 160×120 with a 256² map. criterion warms up, samples, reports a
//! confidence interval and draws its plots (with the report's chart font, registered first);
//! `-- --save-baseline NAME` and `-- --baseline NAME` compare two commits.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use shadowbench::algorithms::{self, Backend, ExecContext, ALGORITHMS};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::light_as;
use shadowbench::scene::generators::{self, GeneratorParams};

/// The built-in scene of `algorithm`'s family: a sphere over a plane for the shadow-map family
/// (the penumbra-map and soft-shadow-map papers' test scenes), a box for the shadow-volume
/// family (silhouette edges that wedges and accumulated hard passes outline), the room for
/// soft irregular shadow mapping (paper 004's indoor scene, receivers all around) and the
/// torus over a plane for the D-buffer (an occluder with a hole: an umbra and two penumbrae).
fn family_scene(algorithm: &str) -> &'static str {
    match algorithm {
        "soft_shadow_volume" | "accum_hard" => "box-on-plane",
        "soft_izb" => "room",
        "dbuffer" => "torus-on-plane",
        _ => "sphere-on-plane",
    }
}

/// The frame of `algorithm`'s family scene, its light converted to a kind the algorithm
/// handles.
fn family_frame(algorithm: &str) -> Frame {
    let mut scene = generators::find(family_scene(algorithm))
        .expect("built-in scene")
        .build(&GeneratorParams {
            triangles: Some(2_000),
            seed: 1,
            occluder_height: None,
            occluder_offset: None,
        });
    let kind = algorithms::find(algorithm)
        .expect("registered")
        .light_for(scene.light.kind());
    scene.light = light_as(scene.light, kind, scene.bounds().center());
    let params = RunParams::of_scene(&scene, [160, 120], 256, 32);
    Frame::new(scene, params)
}

fn bench_algorithms(c: &mut Criterion) {
    let ctx = ExecContext {
        reference_samples: 16,
        ..Default::default()
    };
    let gpu = shadowbench::gpu::gpu();
    if let Err(e) = &gpu {
        eprintln!("skipping the wgpu benchmarks: {e}");
    }
    for info in ALGORITHMS {
        let frame = family_frame(info.id);
        let mut group = c.benchmark_group(format!("{}/{}", info.id, family_scene(info.id)));
        group.sample_size(10);
        for &backend in info.backends {
            if backend == Backend::Wgpu && gpu.is_err() {
                continue;
            }
            group.bench_with_input(BenchmarkId::from_parameter(backend), &backend, |b, &be| {
                b.iter(|| algorithms::run(info.id, be, &frame, &ctx).expect("runs"))
            });
        }
        group.finish();
    }
}

/// criterion with its plots drawn in the report's chart font.
fn criterion() -> Criterion {
    shadowbench::report::font::ensure().expect("the chart font");
    Criterion::default()
}

criterion_group! {
    name = benches;
    config = criterion();
    targets = bench_algorithms
}
criterion_main!(benches);
