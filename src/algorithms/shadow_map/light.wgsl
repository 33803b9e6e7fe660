// Group 0 of the shadow-map family's passes, joined before light_raster.wgsl and
// eye_lookup.wgsl at pipeline creation (shadow_map/wgpu.rs `PRELUDE`), after the declarations of
// the light view's uniform `Light` (`LightUniform`) and the replay's counters `Counts`, which
// shadow_map/wgpu.rs declares once for Rust and WGSL.

@group(0) @binding(0) var<uniform> light: Light;
@group(0) @binding(1) var<storage, read_write> counts: Counts;
