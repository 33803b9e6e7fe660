//! Whether a test binary's wgpu tests can run here.

/// Whether the tests can run on a GPU: false (with a line saying why) without an adapter, a
/// panic when one is required (`SHADOWBENCH_REQUIRE_GPU=1`, as `.ci/run` sets) and missing.
pub fn have_gpu() -> bool {
    match shadowbench::gpu::gpu() {
        Ok(_) => true,
        Err(e) if std::env::var("SHADOWBENCH_REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("SHADOWBENCH_REQUIRE_GPU=1 but {e}")
        }
        Err(e) => {
            eprintln!("skipping: {e}");
            false
        }
    }
}
