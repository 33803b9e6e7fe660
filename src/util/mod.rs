//! Small deterministic helpers shared across the crate.

pub mod deadline;
pub mod hash;
pub mod console;
pub mod input;
pub mod json;
pub mod npy;
pub mod paths;
