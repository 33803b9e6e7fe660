//! Small deterministic helpers shared across the crate.

pub mod hash;
