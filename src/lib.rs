//! shadowbench: a benchmarking harness and many-core SIMD machine model for real-time
//! soft-shadow algorithms. See ARCHITECTURE.md for where things live.
//!
//! Rendering one frame with an algorithm and measuring it against the ground truth:
//!
//! ```
//! use shadowbench::algorithms::{self, Backend, ExecContext};
//! use shadowbench::frame::{Frame, RunParams};
//! use shadowbench::metrics;
//! use shadowbench::scene::generators::{self, GeneratorParams};
//!
//! let scene = generators::find("sphere-on-plane").unwrap().build(&GeneratorParams::default());
//! let params = RunParams {
//!     triangles: scene.triangle_count() as u32,
//!     light_size: scene.light.size(),
//!     map_resolution: 128,
//!     tile_size: 16,
//!     image: [32, 24],
//!     occluder_height: None,
//!     occluder_offset: None,
//!     cores: None,
//! };
//! let frame = Frame::new(scene, params);
//! let ctx = ExecContext { reference_samples: 16, ..Default::default() };
//! let pcss = algorithms::run("pcss", Backend::CpuModel, &frame, &ctx).unwrap();
//! let truth = algorithms::run("reference", Backend::CpuNative, &frame, &ctx).unwrap();
//! let error = metrics::compare(&pcss.visibility, &truth.visibility, &frame.gbuffer.mask());
//! assert!(pcss.model_ms.unwrap() > 0.0);
//! assert!(error.mae.unwrap() < 0.1);
//! ```

pub mod algorithms;
pub mod backend;
pub mod build;
pub mod counters;
pub mod error;
pub mod frame;
pub mod gpu;
pub mod harness;
pub mod history;
pub mod metrics;
pub mod model;
pub mod record;
pub mod report;
pub mod scenario;
pub mod scene;
pub mod util;
pub mod visibility;
