//! Where an algorithm runs: the three executions every record names. Below `algorithms`,
//! `model` and `record` (which name executions but never run them) so every import points
//! down; re-exported as `algorithms::Backend`.

use serde::{Deserialize, Serialize};

use crate::error::unknown_name;

/// Where an algorithm runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Backend {
    /// The algorithm's kernels on the host, uninstrumented: honest host wall-clock time.
    CpuNative,
    /// The same kernels on the modelled many-core SIMD machine, counting and timing its work.
    CpuModel,
    /// Real GPU passes through wgpu.
    Wgpu,
}

impl Backend {
    pub const ALL: [Backend; 3] = [Backend::CpuNative, Backend::CpuModel, Backend::Wgpu];

    pub fn name(self) -> &'static str {
        match self {
            Backend::CpuNative => "cpu-native",
            Backend::CpuModel => "cpu-model",
            Backend::Wgpu => "wgpu",
        }
    }

    pub fn parse(s: &str) -> std::result::Result<Backend, String> {
        Backend::ALL
            .into_iter()
            .find(|b| b.name() == s)
            .ok_or_else(|| unknown_name("backend", s, &Backend::ALL.map(|b| b.name())))
    }
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
