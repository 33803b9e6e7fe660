//! The algorithms, one folder each: its math once in `mod.rs`, then one file per execution.
//!
//! Every algorithm takes the same [`Frame`](crate::frame::Frame) and returns a [`FrameOutput`] (visibility buffer,
//! counters, phases, times); the harness adds quality against the reference and writes results.
//! This module holds the list ([`ALGORITHMS`]) and its lookup; what an algorithm is sits in
//! [`algorithm`].

pub mod accum_hard;
pub mod algorithm;
pub mod dbuffer;
pub mod exec;
pub mod eye_raster;
pub mod hard_shadow_map;
pub mod pcss;
pub mod penumbra_map;
pub mod reference;
pub mod rt_denoised;
pub mod shadow_map;
pub mod shadow_volume;
pub mod soft_izb;
pub mod soft_shadow_map;
pub mod soft_shadow_volume;
pub mod work;

use crate::error::unknown_name;
pub use algorithm::{
    check_light_texture, no_options, parse_options, run, Algorithm, AlgorithmInfo,
    AlgorithmOptions, Backend, Configured, CpuEntry, ExecContext, FrameOutput, MethodLimit,
    WgpuEntry, WgpuParity, WorkEstimate,
};

/// Every algorithm, in the order of listings and chart colours. Adding an algorithm: its folder
/// (an [`Algorithm`] in its `mod.rs`) and one line here.
pub const ALGORITHMS: &[AlgorithmInfo] = &[
    AlgorithmInfo::of::<reference::Reference>(),
    AlgorithmInfo::of::<hard_shadow_map::HardShadowMap>(),
    AlgorithmInfo::of::<pcss::Pcss>(),
    AlgorithmInfo::of::<soft_izb::SoftIzb>(),
    AlgorithmInfo::of::<accum_hard::AccumHard>(),
    AlgorithmInfo::of::<soft_shadow_volume::SoftShadowVolume>(),
    AlgorithmInfo::of::<penumbra_map::PenumbraMap>(),
    AlgorithmInfo::of::<soft_shadow_map::SoftShadowMap>(),
    AlgorithmInfo::of::<dbuffer::Dbuffer>(),
    AlgorithmInfo::of::<rt_denoised::RtDenoised>(),
];

/// The registered algorithm `id`, or an error suggesting the closest name.
pub fn find(id: &str) -> std::result::Result<&'static AlgorithmInfo, String> {
    if let Some(a) = ALGORITHMS.iter().find(|a| a.id == id) {
        return Ok(a);
    }
    let ids: Vec<&str> = ALGORITHMS.iter().map(|a| a.id).collect();
    Err(unknown_name("algorithm", id, &ids))
}
