//! Host speed of every registered algorithm, one group each, on every execution it has:
//! `cpu-native` (the kernels alone) and `cpu-model` (the same kernels counted and
//! cache-simulated; the ratio of the two is the model's overhead) always, `wgpu` when an adapter
//! exists (skipped with a message otherwise). Small fixed scene so `cargo bench` stays short.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use shadowbench::algorithms::{self, Backend, ExecContext, ALGORITHMS};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::harness::light_as;
use shadowbench::scene::generators::{self, GeneratorParams};

/// The fixed scene, with its light converted to a kind `algorithm` handles.
fn small_frame(algorithm: &str) -> Frame {
    let mut scene = generators::find("sphere-on-plane")
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
        let frame = small_frame(info.id);
        let mut group = c.benchmark_group(info.id);
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

criterion_group! {
    name = benches;
    // criterion's own plots would draw text through plotters' ab_glyph backend (the feature
    // the report enables), which has no font registered for them; the figures are printed.
    config = Criterion::default().without_plots();
    targets = bench_algorithms
}
criterion_main!(benches);
