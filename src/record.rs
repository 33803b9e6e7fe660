//! What a run yields, in the vocabulary of the design: counters, phases, times, quality.
//! `run.json` is one [`RunRecord`]; `results.json` is a list of them.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_with::skip_serializing_none;

use crate::backend::Backend;
use crate::frame::RunParams;
use crate::metrics::ErrorMetrics;

/// Named counters (`fill`, `overdraw`, `mem_model.read_bytes`, `mem_est.<buffer>.read_bytes`, ...; see [`crate::counters`]).
/// Sorted by name so files and comparisons are stable.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Counters(pub BTreeMap<String, f64>);

impl Counters {
    pub fn add(&mut self, name: &str, v: f64) {
        *self.0.entry(name.to_string()).or_insert(0.0) += v;
    }

    pub fn set(&mut self, name: &str, v: f64) {
        self.0.insert(name.to_string(), v);
    }

    pub fn get(&self, name: &str) -> Option<f64> {
        self.0.get(name).copied()
    }

    /// Adds `fill` (fragments rasterized) and `overdraw` (those of them that changed nothing in
    /// the result).
    pub fn add_fill(&mut self, fill: f64, overdraw: f64) {
        self.add("fill", fill);
        self.add("overdraw", overdraw);
    }

    /// Adds memory traffic of kind `kind` (`mem_est` or `mem_model`): `<kind>.<buffer>.read_bytes`
    /// for each of `reads`, `<kind>.<buffer>.write_bytes` for each of `writes`, and their sums to
    /// `<kind>.read_bytes` and `<kind>.write_bytes`, so a total is always the sum of its
    /// buffers. Bytes.
    pub fn add_traffic(&mut self, kind: &str, reads: &[(&str, f64)], writes: &[(&str, f64)]) {
        for (dir, list) in [("read", reads), ("write", writes)] {
            for (buffer, bytes) in list {
                self.add(&format!("{kind}.{buffer}.{dir}_bytes"), *bytes);
            }
            let total = list.iter().map(|(_, b)| b).sum();
            self.add(&format!("{kind}.{dir}_bytes"), total);
        }
    }

    /// Adds every counter of `other` into `self`.
    pub fn merge(&mut self, other: &Counters) {
        for (k, v) in &other.0 {
            self.add(k, *v);
        }
    }
}

/// A phase of an algorithm's runs as every execution of it names it (a record's
/// `phases[].name`): one enum per algorithm or family, declared with `phases!`, so that a CPU
/// step (`Machine::phase`) and a GPU submission (`gpu::pass::Timed`) name the same phase by the
/// same value and a phase name cannot be misspelt.
pub trait PhaseId: Copy + PartialEq + std::fmt::Debug {
    /// Its name in records.
    fn name(self) -> &'static str;
}

/// Declares the phases of an algorithm's runs, in order, as an enum implementing [`PhaseId`]:
/// `phases! { pub enum Phase { Hard => "hard", Accumulate => "accumulate" } }` (each variant
/// with the name records give it).
macro_rules! phases {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident {
            $($(#[doc = $doc:literal])* $variant:ident => $label:literal,)+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        $vis enum $name {
            $($(#[doc = $doc])* $variant,)+
        }

        impl $name {
            /// Every phase, in the order runs go through them.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];
        }

        impl $crate::record::PhaseId for $name {
            fn name(self) -> &'static str {
                match self {
                    $($name::$variant => $label,)+
                }
            }
        }
    };
}
pub(crate) use phases;

/// A named step of an algorithm with its own times and counters.
#[skip_serializing_none]
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Phase {
    pub name: String,
    pub wall_ms: f64,
    pub model_ms: Option<f64>,
    pub gpu_ms: Option<f64>,
    #[serde(default, skip_serializing_if = "counters_empty")]
    pub counters: Counters,
}

fn counters_empty(c: &Counters) -> bool {
    c.0.is_empty()
}

/// One run: one algorithm on one backend at one point of a sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    pub algorithm: String,
    /// What tells runs of one algorithm with different options apart, where its options change
    /// what a run is (`rt_denoised`'s rays a pixel and denoiser: `1 spp`, `4 spp raw`;
    /// [`crate::algorithms::Algorithm::variant`]): part of the case id and of the label reports
    /// give the algorithm. Absent for the others.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub variant: Option<String>,
    /// The execution, written as its name (`cpu-native`, `cpu-model`, `wgpu`); a file naming
    /// any other does not read.
    pub backend: Backend,
    pub scene: String,
    /// The light kind used (`sphere`, `disc`, `rect`).
    pub light: String,
    pub params: RunParams,
    pub counters: Counters,
    pub phases: Vec<Phase>,
    /// Host milliseconds of the run, without its GPU setup (`gpu_setup_ms`).
    pub wall_ms: f64,
    pub model_ms: Option<f64>,
    pub gpu_ms: Option<f64>,
    /// wgpu runs: host milliseconds the run spent on GPU setup (a device acquired after a
    /// loss, shader modules, layouts and pipelines created; [`crate::gpu::cache`]), left out of
    /// `wall_ms`. 0 when everything came from an earlier run of the process; the breakdown is
    /// in `execution.gpu_setup`. Absent for the other executions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gpu_setup_ms: Option<f64>,
    /// Host milliseconds of the cold (first) iteration, timed apart from the samples of
    /// `wall_ms` ([`crate::harness::measure`]); absent when the protocol had no warm-up.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cold_wall_ms: Option<f64>,
    /// GPU milliseconds of the cold iteration (wgpu).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cold_gpu_ms: Option<f64>,
    /// The measurement: protocol, every timed sample of the run and its phases, their medians
    /// (which `wall_ms`, `gpu_ms` and the phases' times are), minimum, spread and interval.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measured: Option<crate::harness::measure::Measured>,
    pub error: Option<ErrorMetrics>,
    /// The temporal figures of an animated sweep's sequence (`crate::harness::animation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<crate::harness::animation::AnimationRecord>,
    /// Where it ran: machine preset, adapter, host, sample counts.
    #[serde(default)]
    pub execution: BTreeMap<String, serde_json::Value>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Remarks that are expected and do not question the figures: the light converted to a
    /// kind the algorithm takes, a method limit of the paper's design that shows in this frame
    /// (`harness::limit_notes`). Not counted as warnings; the report lists them once per
    /// algorithm ([`note_kind`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// What was added around user meshes (ground plane, camera, light), when the scene was made
    /// from mesh files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub framing: Option<crate::scenario::Framing>,
    /// Why the run failed; a failed run keeps its place in the results.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
}

impl RunRecord {
    /// The GPU pipeline a wgpu run used (`execution.gpu_pipeline`: `"raster"` or `"gather"`),
    /// for algorithms that offer two; `None` otherwise.
    pub fn gpu_pipeline(&self) -> Option<&str> {
        self.execution.get("gpu_pipeline")?.as_str()
    }

    /// The algorithm as reports name it: its id, and the GPU pipeline where a run names one
    /// (`soft_shadow_volume (raster)`).
    pub fn algorithm_label(&self) -> String {
        let name = match &self.variant {
            Some(v) => format!("{} ({v})", self.algorithm),
            None => self.algorithm.clone(),
        };
        match self.gpu_pipeline() {
            Some(p) => format!("{name} ({p})"),
            None => name,
        }
    }

    /// A record for `algorithm` on `backend` in `scene`, before it ran.
    pub fn new(
        algorithm: &str,
        backend: Backend,
        scene: &crate::scene::Scene,
        params: RunParams,
    ) -> RunRecord {
        RunRecord {
            algorithm: algorithm.to_string(),
            variant: None,
            backend,
            scene: scene.name.clone(),
            light: scene.light.kind().to_string(),
            params,
            counters: Counters::default(),
            phases: vec![],
            wall_ms: 0.0,
            model_ms: None,
            gpu_ms: None,
            gpu_setup_ms: None,
            cold_wall_ms: None,
            cold_gpu_ms: None,
            measured: None,
            error: None,
            animation: None,
            execution: [
                (
                    "host_threads".to_string(),
                    serde_json::json!(rayon::current_num_threads()),
                ),
                (
                    "shadowbench".to_string(),
                    serde_json::json!(env!("CARGO_PKG_VERSION")),
                ),
            ]
            .into(),
            warnings: vec![],
            notes: vec![],
            framing: None,
            failure: None,
        }
    }

    /// A stable identifier of the case (without timing), for comparisons and file names.
    pub fn case_id(&self) -> String {
        case_id(
            &self.scene,
            (&self.algorithm, self.variant.as_deref()),
            self.backend,
            &self.params,
        )
    }
}

/// What a note says without the figures of its run (every digit run as `N`), so the notes of
/// many runs group by what they say: `method limit (…): N pixels the reference shadows …`.
pub fn note_kind(note: &str) -> String {
    let mut out = String::with_capacity(note.len());
    let mut in_number = false;
    for c in note.chars() {
        if c.is_ascii_digit() {
            if !in_number {
                out.push('N');
            }
            in_number = true;
        } else {
            in_number = false;
            out.push(c);
        }
    }
    out
}

/// Whether a record's warning written by an older version is what is now a note (a light
/// conversion or a method limit), for [`crate::harness::output::ResultsFile::upgraded`].
pub fn is_note(warning: &str) -> bool {
    warning.starts_with("light converted from ") || warning.starts_with("method limit (")
}

/// A light size as written in case ids (folder names), `results.csv` and progress lines: the
/// shortest decimal that reads back as the same `f32` (`0.6`, not `0.6000000238418579`).
pub fn fmt_light_size(v: f32) -> String {
    v.to_string()
}

/// The identifier of a run: scene, algorithm (with its variant, `RunRecord::variant`),
/// backend and every parameter. It names the run's image folder (`images/<case_id>/`), so it
/// is always one safe file name component: the scene, algorithm and variant (user text in a
/// results file) and the backend's name go through [`crate::util::paths::slug`], and the whole
/// identifier is cut to 200 bytes (with a hash of the rest) when it grows longer.
pub fn case_id(
    scene: &str,
    (algorithm, variant): (&str, Option<&str>),
    backend: Backend,
    p: &RunParams,
) -> String {
    use crate::util::paths::{slug, slug_max};
    {
        let algorithm = match variant {
            Some(v) => format!("{algorithm}-{v}"),
            None => algorithm.to_string(),
        };
        let mut id = format!(
            "{}_{}_{}_t{}_l{}_m{}_b{}_{}x{}",
            slug(scene),
            slug(&algorithm),
            slug(backend.name()),
            p.triangles,
            fmt_light_size(p.light_size),
            p.map_resolution,
            p.tile_size,
            p.image[0],
            p.image[1]
        );
        if let Some(h) = p.occluder_height {
            id.push_str(&format!("_h{h}"));
        }
        if let Some(d) = p.occluder_offset {
            id.push_str(&format!("_x{d}"));
        }
        if let Some(c) = p.cores {
            id.push_str(&format!("_c{c}"));
        }
        slug_max(&id, 200)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::generators::{self, GeneratorParams};

    #[test]
    fn variants_of_one_algorithm_are_different_runs_with_their_own_labels() {
        let scene = generators::find("sphere-on-plane")
            .unwrap()
            .build(&GeneratorParams::default());
        let params = RunParams::of_scene(&scene, [16, 12], 64, 16);
        let plain = RunRecord::new("rt_denoised", Backend::CpuModel, &scene, params);
        let mut raw = plain.clone();
        let options = [(
            "rt_denoised".to_string(),
            serde_json::json!({"spp": 4, "denoise": false}),
        )];
        let info = crate::algorithms::find("rt_denoised").unwrap();
        raw.variant = info
            .configure(&options.into_iter().collect())
            .unwrap()
            .variant();
        assert_eq!(raw.variant.as_deref(), Some("4 spp raw"));
        assert_ne!(plain.case_id(), raw.case_id());
        assert_eq!(raw.algorithm_label(), "rt_denoised (4 spp raw)");
        assert_eq!(plain.algorithm_label(), "rt_denoised");
        // Still one safe path component (the image folder's name).
        let id = raw.case_id();
        assert!(
            !id.contains(' ') && !id.contains('/') && id.contains("4_spp_raw"),
            "{id}"
        );
    }
}
