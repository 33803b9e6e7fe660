//! What an algorithm is to the harness: the [`Algorithm`] trait (typed options, entry points
//! per execution, estimates, limits), its erased registry entry [`AlgorithmInfo`], the
//! [`ExecContext`] every execution is given, and [`run`], which runs one registered algorithm
//! on one execution for a [`Frame`] and returns its [`FrameOutput`].

use std::any::Any;
use std::collections::BTreeMap;
use std::sync::Arc;

use super::{find, reference, work};
pub use crate::backend::Backend;
use crate::counters::names;
use crate::error::{Error, InputError, Result};
pub use crate::frame::FrameOutput;
use crate::frame::{Frame, RunParams};
use crate::model::MachineConfig;
use crate::scene::LightKind;
use crate::util::deadline::Deadline;

/// Shadowing an algorithm's method does not compute: its paper's design, not a fault. Declared
/// per algorithm ([`AlgorithmInfo::limits`]), listed in every record
/// (`execution.method_limits`), and a warning in a run where the reference shows it matters
/// (`harness::limit_warnings`); `error.mae_shadow_receivers` restricts the error to receiver-only
/// surfaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodLimit {
    /// Occluders are not shadowed (by themselves or each other) when the scene has receiver-only
    /// objects: only those receive the soft shadow (002 §3).
    NoOccluderShadowing,
    /// The penumbra is computed only outside the hard shadow of the light centre; the umbra is
    /// that hard shadow, so the inner penumbra is dark (000 §3).
    OuterPenumbraOnly,
    /// No penumbra: the hard shadow of a point light at the light's centre.
    NoPenumbra,
    /// One light-space map: receivers outside it are lit (`light_view.receivers_outside`, with
    /// its own warning).
    OneMap,
    /// The shadow map holds every surface, those of objects that are not occluders too (eq. 1
    /// of 000 needs the receiver's depth `Z_P`), so they cast hard shadows like occluders.
    NonOccludersCast,
    /// Only the occluders' shadow volumes (or their occlusion) shadow a point; no facing test,
    /// so a surface of an object that is not an occluder is lit where it faces away from the
    /// light (a closed occluder's own volume holds its averted side).
    AvertedNonOccludersLit,
}

impl MethodLimit {
    pub fn describe(self) -> &'static str {
        match self {
            MethodLimit::NoOccluderShadowing => {
                "no shadow on occluders when the scene has receiver-only objects"
            }
            MethodLimit::OuterPenumbraOnly => {
                "outer penumbra only: the hard shadow of the light centre is umbra"
            }
            MethodLimit::NoPenumbra => "no penumbra: the hard shadow of the light centre",
            MethodLimit::OneMap => "one light-space map: receivers outside it are lit",
            MethodLimit::NonOccludersCast => {
                "objects that are not occluders cast shadows: the shadow map holds every surface"
            }
            MethodLimit::AvertedNonOccludersLit => {
                "surfaces of non-occluders facing away from the light are lit: no facing test"
            }
        }
    }
}

/// The `cpu-native` / `cpu-model` entry of an algorithm whose options are `O`: `backend` picks
/// the machine's probe (uninstrumented, or the modelled machine of `ctx.machine`).
pub type CpuEntry<O> = fn(Backend, &Frame, &ExecContext, &O) -> Result<FrameOutput>;

/// The `wgpu` entry of an algorithm whose options are `O`, run inside
/// [`crate::gpu::guarded_frame`].
pub type WgpuEntry<O> = fn(&crate::gpu::Run, &Frame, &ExecContext, &O) -> Result<FrameOutput>;

/// The estimated fill of a run of an algorithm whose options are `O` ([`work`]), made before
/// anything runs.
pub type WorkEstimate<O> = fn(&work::SceneExtent, &RunParams, &ExecContext, &O) -> f64;

/// The typed options of an algorithm (`options.<ID>` of a scenario): read with serde (defaults
/// when absent), then [`AlgorithmOptions::validate`]d once ([`AlgorithmInfo::configure`]).
pub trait AlgorithmOptions:
    serde::de::DeserializeOwned + serde::Serialize + Default + Clone + Send + Sync + 'static
{
    /// Checks what serde cannot (ranges, combinations); an error names the field's JSON path
    /// (`$.options.<ID>.<field>`) and its value. By default every value serde reads is valid.
    fn validate(&self) -> std::result::Result<(), InputError> {
        Ok(())
    }
}

/// An algorithm without options: `options.<ID>` must be absent.
impl AlgorithmOptions for () {}

/// How close an algorithm's `wgpu` image and counters are to its `cpu-model` ones on the same
/// frame and options, as the registry-driven parity tests check them. Both executions compute
/// the same formulas in f32 from the same host geometry; what differs is the rasterizer (fixed
/// point and barycentric depth on the model, the driver's plane equations and far-plane
/// clipping on a GPU), the GPU's transcendental functions and the order of blending, so images
/// differ in their last bits and a fragment on a triangle edge or a depth test can change
/// hands.
///
/// A parity bounds the largest difference and how many pixels differ, not only the mean: a
/// systematic error along one edge (a row of pixels) moves the mean of a whole image little.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WgpuParity {
    /// Largest mean absolute difference of visibility over the pixels that see geometry.
    pub mae: f64,
    /// Largest difference of any one of those pixels.
    pub max: f64,
    /// Largest fraction of those pixels whose visibility differs by more than 0.1.
    pub frac_over_0_1: f64,
    /// Largest fraction of those pixels whose visibility differs by more than
    /// [`WgpuParity::ROUNDING`]: pixels where the two executions decided something differently
    /// (a texel, a fragment, a sample), not only rounded differently.
    pub frac_differing: f64,
    /// The counters both executions record that may differ: `Some(f)`, by at most `f` times
    /// the cpu-model's `fill` (fragments that change hands between two rasterizers); `None`,
    /// defined differently on the two executions (not compared). Every other counter both
    /// record (the derived figures aside, [`crate::counters::DERIVED`]) is equal.
    pub differ: &'static [(&'static str, Option<f64>)],
}

impl WgpuParity {
    /// A difference of visibility up to this is f32 rounding (the order of a sum, a GPU's
    /// division or transcendental function), not a different decision.
    pub const ROUNDING: f64 = 1e-4;

    /// The same formulas in f32 and the same counts on both: MAE under 1e-3, no pixel more than
    /// 0.05 apart (a PCF tap of 32 that changes hands), at most 0.5% of the pixels over 0.1
    /// and 6% beyond rounding, every counter equal. Measured on lavapipe over the registry's
    /// scenes and option sets (48×36): largest difference 0 (`hard_shadow_map`, `soft_izb`) to
    /// 0.031 (`pcss`, one tap), pixels beyond rounding 0 to 4.2% (`penumbra_map`'s and
    /// `dbuffer`'s intensities, under 0.016 apart; `soft_shadow_map` in FP16 1.3%), none over
    /// 0.1.
    pub const SAME_FORMULAS: WgpuParity = WgpuParity {
        mae: 1e-3,
        max: 0.05,
        frac_over_0_1: 0.005,
        frac_differing: 0.06,
        differ: &[],
    };

    /// [`WgpuParity::SAME_FORMULAS`] but for the shadow-map family's light raster: `fill` and
    /// `overdraw` within 2% of the fill. The model clips only at the near plane, a GPU at the
    /// far plane too, so fragments of triangles reaching past the map's far plane differ, and
    /// fragments on triangle edges change hands between the two rasterizers.
    pub const LIGHT_RASTER: WgpuParity = WgpuParity {
        differ: &[("fill", Some(0.02)), ("overdraw", Some(0.02))],
        ..WgpuParity::SAME_FORMULAS
    };
}

/// One algorithm as the registry runs it: its description, its typed options (parsed and
/// validated once per sweep, by [`Algorithm::options`] in [`AlgorithmInfo::configure`]), and one
/// entry per execution. An algorithm implements this in its folder's `mod.rs`;
/// [`ALGORITHMS`](super::ALGORITHMS) lists it with [`AlgorithmInfo::of`], the only place an
/// algorithm is added.
pub trait Algorithm {
    /// Its name in scenarios, records and charts (`options.<ID>` holds its options).
    const ID: &'static str;
    /// Paper and section it implements.
    const SOURCE: &'static str;
    const SUMMARY: &'static str;
    /// Light kinds it handles; another kind is converted to the first of these (same size).
    /// By default every kind.
    const LIGHTS: &'static [LightKind] = &LightKind::ALL;
    /// The shadowing its method does not compute. By default none.
    const LIMITS: &'static [MethodLimit] = &[];
    /// Its options, `options.<ID>` of a scenario.
    type Options: AlgorithmOptions;
    /// Bytes of its own buffers for a run, estimated before anything is allocated.
    const MEMORY_ESTIMATE: fn(&RunParams) -> u64;
    /// Estimated fill of a run ([`work`]), made before anything runs.
    const WORK_ESTIMATE: WorkEstimate<Self::Options>;
    /// The `cpu-native` / `cpu-model` execution.
    const CPU: CpuEntry<Self::Options>;
    /// The `wgpu` execution, if it has one (by default none).
    const WGPU: Option<WgpuEntry<Self::Options>> = None;
    /// Its executions; the registry refuses the others before anything runs. By default both
    /// CPU executions, and `wgpu` when [`Algorithm::WGPU`] is given.
    const BACKENDS: &'static [Backend] = if Self::WGPU.is_some() {
        &Backend::ALL
    } else {
        &[Backend::CpuNative, Backend::CpuModel]
    };
    /// Option sets (`options.<ID>` as JSON) that the registry-driven parity tests run besides
    /// the defaults: the switches that change which kernels run.
    const OPTION_SETS: &'static [&'static str] = &[];
    /// How close its `wgpu` execution is to its `cpu-model` execution ([`WgpuParity`]).
    const WGPU_PARITY: WgpuParity = WgpuParity::SAME_FORMULAS;
    /// Reads and validates `options.<ID>` (defaults when absent); a bad value names its JSON
    /// path.
    fn options(
        options: &BTreeMap<String, serde_json::Value>,
    ) -> std::result::Result<Self::Options, InputError> {
        let o: Self::Options = parse_options(Self::ID, options)?;
        o.validate()?;
        Ok(o)
    }
    /// Whether these options honour a textured light (`$.light.texture`). By default refused:
    /// the algorithm would treat the light as uniform white, which is silently wrong.
    fn light_texture(_: &Self::Options) -> std::result::Result<(), InputError> {
        Err(InputError::new(
            "$.light.texture",
            format!(
                "algorithm '{id}' cannot honour a textured light (only reference and {} with \
                 coverage \"texture\" do); drop '{id}' from the algorithms or the texture",
                super::soft_shadow_volume::ID,
                id = Self::ID
            ),
        ))
    }
    /// A short label telling runs of different options apart, where the options change what a
    /// run is rather than how it is computed (`rt_denoised`: `1 spp`, `4 spp raw`): the record's
    /// `variant`, in its case id and in the label reports give it. By default none.
    fn variant(_: &Self::Options) -> Option<String> {
        None
    }
    /// Adapts the options to the frame before a run, with the run's warning when it does (the
    /// z-fail fallback of the shadow-volume family on open occluders). By default unchanged.
    fn prepare(_: &Frame, _: &mut Self::Options) -> Option<String> {
        None
    }
}

/// A registered algorithm: an [`Algorithm`] with its typed options erased, so the registry is
/// one list.
pub struct AlgorithmInfo {
    pub id: &'static str,
    /// Paper and section it implements.
    pub source: &'static str,
    pub summary: &'static str,
    /// Light kinds it handles; another kind is converted to the first of these (same size).
    pub lights: &'static [LightKind],
    pub backends: &'static [Backend],
    /// Bytes of the algorithm's own buffers for a run (maps, grids, bins), estimated before
    /// anything is allocated; the frame itself is counted by the harness.
    pub memory_estimate: fn(&RunParams) -> u64,
    /// The shadowing its method does not compute.
    pub limits: &'static [MethodLimit],
    /// Option sets the parity tests run besides the defaults ([`Algorithm::OPTION_SETS`]).
    pub option_sets: &'static [&'static str],
    /// How close its wgpu execution is to its cpu-model execution ([`Algorithm::WGPU_PARITY`]).
    pub wgpu_parity: WgpuParity,
    /// Reads and validates `options.<id>` into the typed options ([`Algorithm::options`]).
    parse: fn(&BTreeMap<String, serde_json::Value>) -> std::result::Result<Erased, InputError>,
    /// The estimated fill of a run ([`work`], [`Algorithm::WORK_ESTIMATE`]).
    work_estimate: fn(&dyn Any, &work::SceneExtent, &RunParams, &ExecContext) -> f64,
    /// Whether the options honour a textured light ([`Algorithm::light_texture`]).
    light_texture: fn(&dyn Any) -> std::result::Result<(), InputError>,
    /// The variant label of a run ([`Algorithm::variant`]).
    variant: fn(&dyn Any) -> Option<String>,
    /// Adapts the options to the frame ([`Algorithm::prepare`], whose warning it returns) and
    /// runs the `backend` execution.
    run: fn(&dyn Any, Backend, &Frame, &ExecContext) -> Result<Prepared>,
}

impl AlgorithmInfo {
    /// The registry entry of algorithm `A`.
    pub const fn of<A: Algorithm>() -> AlgorithmInfo {
        AlgorithmInfo {
            id: A::ID,
            source: A::SOURCE,
            summary: A::SUMMARY,
            lights: A::LIGHTS,
            backends: A::BACKENDS,
            memory_estimate: A::MEMORY_ESTIMATE,
            limits: A::LIMITS,
            option_sets: A::OPTION_SETS,
            wgpu_parity: A::WGPU_PARITY,
            parse: |o| Ok(Arc::new(A::options(o)?)),
            work_estimate: |o, extent, p, ctx| (A::WORK_ESTIMATE)(extent, p, ctx, typed::<A>(o)),
            light_texture: |o| A::light_texture(typed::<A>(o)),
            variant: |o| A::variant(typed::<A>(o)),
            run: run_typed::<A>,
        }
    }

    /// This algorithm with `options.<id>` of `options` read and validated once, for every run
    /// of a sweep made with them; an error names the option's JSON path
    /// (`$.options.<id>.<field>`) and its value.
    pub fn configure(
        &'static self,
        options: &BTreeMap<String, serde_json::Value>,
    ) -> std::result::Result<Configured, InputError> {
        Ok(Configured {
            info: self,
            options: (self.parse)(options)?,
        })
    }

    /// Checks `options.<id>` of a scenario before any work starts ([`AlgorithmInfo::configure`]).
    pub fn check_options(
        &'static self,
        options: &BTreeMap<String, serde_json::Value>,
    ) -> std::result::Result<(), InputError> {
        self.configure(options).map(|_| ())
    }

    /// The light kind this algorithm runs with when the scene's light is `kind`.
    pub fn light_for(&self, kind: LightKind) -> LightKind {
        if self.lights.contains(&kind) {
            kind
        } else {
            self.lights[0]
        }
    }
}

/// The typed options of one algorithm ([`Algorithm::Options`]), erased so that the registry is
/// one list; only [`AlgorithmInfo::configure`] makes them, paired with their algorithm.
type Erased = Arc<dyn Any + Send + Sync>;

/// An algorithm with its options read and validated once ([`AlgorithmInfo::configure`]): what
/// its runs, their variant label and their work estimates are made from.
#[derive(Clone)]
pub struct Configured {
    /// The algorithm.
    pub info: &'static AlgorithmInfo,
    /// Its typed options, erased: always `info`'s own (the fields are private).
    options: Erased,
}

impl Configured {
    /// The algorithm's name.
    pub fn id(&self) -> &'static str {
        self.info.id
    }

    /// The variant label of its runs ([`Algorithm::variant`]).
    pub fn variant(&self) -> Option<String> {
        (self.info.variant)(self.options.as_ref())
    }

    /// The estimated fill of a run of its own ([`work`]), the frame's work aside.
    pub fn work_estimate(
        &self,
        extent: &work::SceneExtent,
        p: &RunParams,
        ctx: &ExecContext,
    ) -> f64 {
        (self.info.work_estimate)(self.options.as_ref(), extent, p, ctx)
    }

    /// Whether its options honour a textured light ([`Algorithm::light_texture`]).
    pub fn check_light_texture(&self) -> std::result::Result<(), InputError> {
        (self.info.light_texture)(self.options.as_ref())
    }

    /// Runs it on `backend` for `frame`. The derived figures of the counters
    /// (`overdraw_ratio`, `simd_utilization`: [`crate::counters::derive`]) are computed here,
    /// for the run and each phase, the same way for every algorithm and execution.
    pub fn run(&self, backend: Backend, frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
        let mut out = self.execute(backend, frame, ctx)?;
        crate::counters::derive(&mut out.counters);
        for p in &mut out.phases {
            crate::counters::derive(&mut p.counters);
        }
        Ok(out)
    }

    /// Runs its `backend` execution.
    fn execute(&self, backend: Backend, frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
        let info = self.info;
        if !info.backends.contains(&backend) {
            return Err(Error::Unsupported(format!(
                "algorithm '{}' has no {backend} execution (it has: {})",
                info.id,
                info.backends
                    .iter()
                    .map(|b| b.name())
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        let (mut out, fallback) = (info.run)(self.options.as_ref(), backend, frame, ctx)?;
        let edges = frame.occluder_edges;
        out.counters
            .set(names::OCCLUDERS_BOUNDARY_EDGES, edges.boundary as f64);
        out.counters.set(
            names::OCCLUDERS_NON_MANIFOLD_EDGES,
            edges.non_manifold as f64,
        );
        out.warnings.extend(edges.warning());
        out.warnings.extend(frame.precision_warning.clone());
        out.warnings.extend(fallback);
        Ok(out)
    }
}

impl std::fmt::Debug for Configured {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Configured({})", self.info.id)
    }
}

/// The typed options of algorithm `A` in `o`, which [`Configured`] pairs with `A`'s entry.
fn typed<A: Algorithm>(o: &dyn Any) -> &A::Options {
    o.downcast_ref()
        .expect("Configured holds the options of its own algorithm")
}

/// A run's output and the warning of [`Algorithm::prepare`], if it changed the options.
type Prepared = (FrameOutput, Option<String>);

/// [`AlgorithmInfo::run`] of algorithm `A`.
fn run_typed<A: Algorithm>(
    o: &dyn Any,
    backend: Backend,
    frame: &Frame,
    ctx: &ExecContext,
) -> Result<Prepared> {
    let mut o = typed::<A>(o).clone();
    if frame.scene.light_texture.is_some() {
        A::light_texture(&o)?;
    }
    let warning = A::prepare(frame, &mut o);
    let mut out = match (backend, A::WGPU) {
        (Backend::Wgpu, Some(wgpu)) => {
            crate::gpu::guarded_frame(ctx.deadline, ctx.gpu_counters, |gpu| {
                wgpu(gpu, frame, ctx, &o)
            })
        }
        (Backend::Wgpu, None) => Err(Error::Unsupported(format!(
            "algorithm '{}' has no wgpu execution",
            A::ID
        ))),
        (Backend::CpuNative | Backend::CpuModel, _) => (A::CPU)(backend, frame, ctx, &o),
    }?;
    // Every option's value as the run used it (defaults filled in, after `prepare`), so that
    // records of different options are told apart.
    match serde_json::to_value(&o) {
        Ok(serde_json::Value::Null) => {}
        Ok(v) => {
            out.execution.insert("options".into(), v);
        }
        Err(e) => out
            .warnings
            .push(format!("the run's options could not be recorded: {e}")),
    }
    Ok((out, warning))
}

/// Reads `options.<id>` of a scenario into `T` (defaults when absent), naming the JSON path of
/// a bad field.
pub fn parse_options<T: serde::de::DeserializeOwned + Default>(
    id: &str,
    options: &std::collections::BTreeMap<String, serde_json::Value>,
) -> Result<T, crate::error::InputError> {
    match options.get(id) {
        None => Ok(T::default()),
        // serde would read an array into the struct's fields by position, and its message for
        // other values names the Rust type.
        Some(v) if !v.is_object() => Err(crate::error::InputError::new(
            format!("$.options.{id}"),
            format!("expected an object of named options, got {v}"),
        )),
        Some(v) => serde_path_to_error::deserialize(v).map_err(|e| {
            let path = e.path().to_string();
            crate::error::InputError::new(
                if path == "." {
                    format!("$.options.{id}")
                } else {
                    format!("$.options.{id}.{path}")
                },
                e.into_inner().to_string(),
            )
        }),
    }
}

/// Reads `options.<id>` of an algorithm that takes no options.
pub fn no_options(
    id: &str,
    options: &BTreeMap<String, serde_json::Value>,
) -> std::result::Result<(), InputError> {
    match options.get(id) {
        None => Ok(()),
        Some(_) => Err(InputError::new(
            format!("$.options.{id}"),
            format!("algorithm '{id}' takes no options"),
        )),
    }
}

/// Whether algorithm `id` with `options` honours a textured light (`$.light.texture`)
/// ([`Algorithm::light_texture`]: the reference weights each light sample by the texture,
/// `soft_shadow_volume` with the 4D coverage texture weights its texels, Paper III §3.3; every
/// other algorithm refuses).
pub fn check_light_texture(
    id: &str,
    options: &BTreeMap<String, serde_json::Value>,
) -> std::result::Result<(), InputError> {
    let info = find(id).map_err(|e| InputError::new("$.algorithms", e))?;
    info.configure(options)?.check_light_texture()
}

/// Settings that apply to a whole execution (all runs of a `render` or `run`).
#[derive(Clone, Debug)]
pub struct ExecContext {
    /// Light samples per pixel of the reference (a perfect square).
    pub reference_samples: u32,
    pub seed: u64,
    /// Per-algorithm options from the scenario (`options.<algorithm>`), validated by each
    /// algorithm.
    pub options: BTreeMap<String, serde_json::Value>,
    /// The modelled machine of `cpu-model` runs (a run's `cores` overrides its core count).
    pub machine: MachineConfig,
    /// When the run must stop (`--run-timeout`); checked cooperatively by every execution.
    pub deadline: Deadline,
    /// Whether wgpu runs make their instrumented replay (`--gpu-counters`).
    pub gpu_counters: crate::gpu::GpuCounters,
    /// How `harness::run_one` measures a run (warm-up, repeats, budget); one timed iteration by
    /// default.
    pub measure: crate::harness::measure::Measure,
    /// ꟻLIP's viewing condition for the `flip` metric, in pixels per degree of visual angle
    /// (`reference.flip_pixels_per_degree`; [`crate::metrics::perceptual`]).
    pub flip_pixels_per_degree: f32,
    /// Whether `cpu-native` steps time each task on the CPU clock of the thread that runs it
    /// ([`crate::model::Machine::timing_tasks`]; `validate`'s phase CPU times). Off by default.
    pub time_tasks: bool,
}

impl Default for ExecContext {
    fn default() -> Self {
        ExecContext {
            reference_samples: reference::DEFAULT_SAMPLES,
            seed: 1,
            options: BTreeMap::new(),
            machine: MachineConfig::default(),
            deadline: Deadline::default(),
            gpu_counters: crate::gpu::GpuCounters::On,
            measure: crate::harness::measure::Measure::ONCE,
            flip_pixels_per_degree: crate::metrics::perceptual::DEFAULT_PIXELS_PER_DEGREE,
            time_tasks: false,
        }
    }
}

/// Runs algorithm `id` on `backend` for `frame` with `ctx.options` ([`Configured::run`]).
pub fn run(id: &str, backend: Backend, frame: &Frame, ctx: &ExecContext) -> Result<FrameOutput> {
    let info = find(id).map_err(Error::Unsupported)?;
    info.configure(&ctx.options)?.run(backend, frame, ctx)
}
