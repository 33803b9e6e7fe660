//! Small deterministic helpers shared across the crate.

pub mod deadline;
pub mod hash;
pub mod input;
pub mod paths;
