//! Throughput of the ground-truth reference: shadow rays per second on a fixed scene.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use shadowbench::algorithms::reference;
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scene::generators::{self, GeneratorParams};

fn bench_reference(c: &mut Criterion) {
    let scene = generators::find("sphere-grid")
        .expect("built-in scene")
        .build(&GeneratorParams::default());
    let params = RunParams::of_scene(&scene, [160, 120], 512, 32);
    let frame = Frame::new(scene, params);
    let samples = 64;
    let rays = reference::render(&frame, samples, 1)
        .counters
        .get("shadow_rays")
        .expect("the reference counts its rays");
    let mut group = c.benchmark_group("reference");
    group.throughput(Throughput::Elements(rays as u64));
    group.sample_size(10);
    group.bench_function("sphere-grid 160x120 64spp", |b| {
        b.iter(|| reference::render(&frame, samples, 1))
    });
    group.finish();
}

/// criterion with its plots drawn in the report's chart font.
fn criterion() -> Criterion {
    shadowbench::report::font::ensure().expect("the chart font");
    Criterion::default()
}

criterion_group! {
    name = benches;
    config = criterion();
    targets = bench_reference
}
criterion_main!(benches);
