//! Small deterministic helpers shared across the crate.

pub mod console;
pub mod deadline;
pub mod hash;
pub mod input;
pub mod json;
pub mod npy;
pub mod paths;
