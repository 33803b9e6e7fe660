//! The integration tests: one test binary whose modules test the library and the `shadowbench`
//! command (one binary links once, so `cargo test` spends its time testing). Shared scenes and
//! helpers are in `common`, `gpu_check` and `pentagon`.

mod claims;
mod cli_edges;
mod common;
mod conformance;
mod coverage_ties;
mod dbuffer;
mod degenerate;
mod every_algorithm;
mod gpu_check;
mod gpu_sweep;
mod history;
mod host_model;
mod hostile;
mod interrupt;
mod light_definition;
mod light_view;
mod limits;
mod meshes_as_they_come;
mod model;
mod occluder_offset;
mod open_occluders;
mod pentagon;
mod penumbra_map;
mod precision;
mod quality_metrics;
mod reference;
mod registry;
mod robustness;
mod roles;
mod rt_denoised;
mod scenario_errors;
mod scene_files;
mod shard_merge;
mod soft_izb;
mod soft_shadow_map;
mod soft_shadow_volume;
mod soft_shadow_volume_textured;
mod wgpu_execution;
