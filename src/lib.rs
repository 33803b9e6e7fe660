//! shadowbench: a benchmarking harness and many-core SIMD machine model for real-time
//! soft-shadow algorithms. See ARCHITECTURE.md for where things live.

pub mod algorithms;
pub mod error;
pub mod frame;
pub mod gpu;
pub mod harness;
pub mod metrics;
pub mod model;
pub mod record;
pub mod report;
pub mod scenario;
pub mod scene;
pub mod util;
pub mod visibility;
