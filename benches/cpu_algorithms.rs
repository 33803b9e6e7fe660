//! Host speed of the shadow-map family on the two CPU executions: `cpu-native` (the kernels
//! alone) and `cpu-model` (the same kernels counted and cache-simulated). The ratio of the two
//! is the model's overhead.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use shadowbench::algorithms::{self, Backend, ExecContext};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::generators::{self, GeneratorParams};

fn small_frame() -> Frame {
    let scene = generators::find("sphere-on-plane")
        .expect("built-in scene")
        .build(&GeneratorParams {
            triangles: Some(2_000),
            seed: 1,
            occluder_height: None,
        });
    let params = RunParams {
        triangles: scene.triangle_count() as u32,
        light_size: scene.light.size(),
        map_resolution: 256,
        tile_size: 32,
        image: [160, 120],
        occluder_height: None,
        cores: None,
    };
    Frame::new(scene, params)
}

fn cpu_algorithms(c: &mut Criterion) {
    let frame = small_frame();
    let ctx = ExecContext::default();
    let mut group = c.benchmark_group("cpu_algorithms");
    group.sample_size(10);
    for id in ["hard_shadow_map", "pcss"] {
        for backend in [Backend::CpuNative, Backend::CpuModel] {
            group.bench_with_input(BenchmarkId::new(id, backend), &backend, |b, &backend| {
                b.iter(|| algorithms::run(id, backend, &frame, &ctx).expect("runs"))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, cpu_algorithms);
criterion_main!(benches);
