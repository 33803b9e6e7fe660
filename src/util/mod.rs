//! Small deterministic helpers shared across the crate.

pub mod console;
pub mod cpu_time;
pub mod deadline;
pub mod hash;
pub mod input;
pub mod json;
pub mod npy;
pub mod paths;
