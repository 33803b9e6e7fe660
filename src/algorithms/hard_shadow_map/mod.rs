//! `hard_shadow_map`: the classic shadow map from the light centre, the baseline every soft
//! shadow algorithm is compared with. The projection and bias are in [`super::shadow_map`].

pub mod wgpu;

/// Registry id.
pub const ID: &str = "hard_shadow_map";
