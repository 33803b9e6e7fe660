//! The JSON scenario format: what to render, with which algorithms and backends, over which
//! sweep axes. Everything is validated before any work starts; errors name the file, the JSON
//! path and the bad value.

pub mod claims;
pub mod overrides;
pub mod validate;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};
use serde_with::skip_serializing_none;

use crate::backend::Backend;
use crate::error::InputError;
use crate::frame::RunParams;
use crate::model::MachineConfig;
use crate::scene::generators::{self, GeneratorParams};
use crate::scene::light_texture::LightTextureSpec;
use crate::scene::load::{self, MeshFile};
use crate::scene::mesh::{Object, Role};
use crate::scene::{Camera, Light, LightTexture, Scene};

pub use validate::validate;

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub name: Option<String>,
    pub description: Option<String>,
    pub scene: SceneSpec,
    /// Overrides the scene's default camera.
    pub camera: Option<Camera>,
    /// Overrides the scene's default light.
    pub light: Option<LightSpec>,
    pub algorithms: Vec<String>,
    #[serde(default = "default_backends")]
    pub backends: Vec<String>,
    /// The base point of the sweep: values used for every axis that is not being swept.
    #[serde(default)]
    pub params: BaseParams,
    #[serde(default)]
    pub sweep: Sweep,
    #[serde(default)]
    pub sweep_mode: SweepMode,
    #[serde(default)]
    pub reference: ReferenceSpec,
    /// Per-algorithm options, keyed by algorithm id.
    #[serde(default)]
    pub options: BTreeMap<String, serde_json::Value>,
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// The modelled machine of `cpu-model` runs: a preset name (`shadowbench list`) or a path
    /// to a machine JSON file, relative to the scenario (default `larrabee-24`).
    pub machine: Option<String>,
    /// Paper claims these runs reproduce, shown in the report next to our figures.
    #[serde(default)]
    pub claims: Vec<claims::Claim>,
    /// Wall-clock budget of each run in seconds (`--run-timeout` overrides it): a run past it
    /// is stopped and recorded as failed, and the sweep goes on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run_timeout_s: Option<f64>,
    /// How measured figures are measured (warm-up, repeats, time budget;
    /// [`crate::harness::measure::Measure`]); `--warmup`, `--repeats`, `--min-time` and
    /// `--max-time` override its fields. Absent: the protocol's defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measure: Option<crate::harness::measure::Measure>,
    /// An animated sweep: each run also renders a sequence of frames with the light's centre
    /// moving along a path ([`crate::harness::animation`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<crate::harness::animation::Animation>,
}

/// `$.light`: the light (`type` and its fields) and an optional `texture` (rectangular lights;
/// [`crate::scene::light_texture`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LightSpec {
    #[serde(flatten)]
    pub light: Light,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texture: Option<LightTextureSpec>,
}

fn default_backends() -> Vec<String> {
    Backend::ALL.iter().map(|b| b.name().into()).collect()
}

fn default_seed() -> u64 {
    1
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneSpec {
    /// A built-in generator (`shadowbench list` shows them).
    pub generator: Option<String>,
    /// Or user meshes.
    pub objects: Option<Vec<ObjectSpec>>,
    /// Add a ground plane under user meshes (default true).
    pub ground: Option<bool>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Mesh file, relative to the scenario file: `.obj`, `.gltf`, `.glb` or `.ply`
    /// ([`crate::scene::load::load_mesh`]). Also accepted as `mesh`.
    #[serde(alias = "mesh")]
    pub obj: PathBuf,
    /// Only this named part of the file: an OBJ object or group (`o`/`g`), or a glTF node with
    /// its children (what `shadowbench scene export` writes per object).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part: Option<String>,
    /// Default: the part's name, else the file's stem.
    pub name: Option<String>,
    pub translate: Option<Vec3>,
    /// Euler angles in degrees, applied X then Y then Z.
    pub rotate_deg: Option<Vec3>,
    pub scale: Option<f32>,
    pub occluder: Option<bool>,
    pub receiver: Option<bool>,
}

/// Missing fields take [`BaseParams::default`].
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BaseParams {
    /// Target triangle count for generators (default: the generator's own).
    pub triangles: Option<u32>,
    /// Light size (default: the scene light's own).
    pub light_size: Option<f32>,
    pub map_resolution: u32,
    pub tile_size: u32,
    pub image: [u32; 2],
    pub occluder_height: Option<f32>,
    /// Lateral offset of the moving occluder along x, in scene units (generators with a moving
    /// occluder; paper 002 §5.2.5).
    pub occluder_offset: Option<f32>,
    pub cores: Option<u32>,
}

impl Default for BaseParams {
    fn default() -> Self {
        BaseParams {
            triangles: None,
            light_size: None,
            map_resolution: 512,
            tile_size: 32,
            image: [320, 240],
            occluder_height: None,
            occluder_offset: None,
            cores: None,
        }
    }
}

/// Sweep axes; each a list of values. Empty axes are not swept.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sweep {
    pub triangles: Vec<u32>,
    pub light_size: Vec<f32>,
    pub map_resolution: Vec<u32>,
    pub tile_size: Vec<u32>,
    pub image: Vec<[u32; 2]>,
    pub occluder_height: Vec<f32>,
    pub occluder_offset: Vec<f32>,
    pub cores: Vec<u32>,
    /// Mesh files (relative to the scenario file, as `scene.objects[].obj`), each in turn in
    /// place of the first object's mesh (`scene.objects[0]`: its part, transform and roles
    /// kept): levels of detail of one model, charted against the scene's triangle count. Needs
    /// `scene.objects`; two files whose scenes have the same triangle count are refused.
    pub meshes: Vec<PathBuf>,
}

/// How sweep axes combine.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SweepMode {
    /// One axis at a time, the others at the base point (as the papers' plots do).
    #[default]
    Each,
    /// Every combination of every axis.
    Grid,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReferenceSpec {
    /// Compute the ground truth and quality metrics (default true).
    pub enabled: bool,
    /// Light samples per pixel, a perfect square (256 default, 1024 for paper runs).
    pub samples: u32,
    /// The viewing condition of the `flip` metric: pixels per degree of visual angle, in
    /// [`crate::metrics::perceptual::PIXELS_PER_DEGREE_RANGE`] (absent: ꟻLIP's default 67.02,
    /// a 0.7 m wide 3840-pixel monitor at 0.7 m). Fewer pixels per degree (a closer or larger
    /// screen) make finer errors visible.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flip_pixels_per_degree: Option<f32>,
}

impl ReferenceSpec {
    /// `flip_pixels_per_degree`, or ꟻLIP's default.
    pub fn flip_pixels_per_degree(&self) -> f32 {
        self.flip_pixels_per_degree
            .unwrap_or(crate::metrics::perceptual::DEFAULT_PIXELS_PER_DEGREE)
    }
}

impl Default for ReferenceSpec {
    fn default() -> Self {
        ReferenceSpec {
            enabled: true,
            samples: crate::algorithms::reference::DEFAULT_SAMPLES,
            flip_pixels_per_degree: None,
        }
    }
}

/// A scene point of a sweep: what changes the geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScenePoint {
    pub triangles: Option<u32>,
    /// The mesh of `sweep.meshes` in place of the first object's (its index), if any.
    pub mesh: Option<usize>,
    pub occluder_height: Option<f32>,
    pub occluder_offset: Option<f32>,
}

/// One point of a sweep (before choosing algorithm and backend).
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    pub scene: ScenePoint,
    pub light_size: Option<f32>,
    pub map_resolution: u32,
    pub tile_size: u32,
    pub image: [u32; 2],
    pub cores: Option<u32>,
}

/// Most sweep points a scenario may have unless `--max-cases` says otherwise.
pub const MAX_CASES: u64 = 100_000;

impl Case {
    /// A hashable key equal for two cases exactly when they are equal (`-0.0` and `0.0` are
    /// one value, as `==` has it; NaN cannot occur in a validated scenario).
    fn key(&self) -> [u64; 10] {
        let f = |v: Option<f32>| v.map_or(0, |v| (1 << 32) | (v + 0.0).to_bits() as u64);
        let u = |v: Option<u32>| v.map_or(0, |v| (1 << 32) | v as u64);
        [
            u(self.scene.triangles),
            u(self.scene.mesh.map(|i| i as u32)),
            f(self.scene.occluder_height),
            f(self.scene.occluder_offset),
            f(self.light_size),
            self.map_resolution as u64,
            self.tile_size as u64,
            self.image[0] as u64,
            self.image[1] as u64,
            u(self.cores),
        ]
    }

    /// Run parameters for this case in `scene` (whose light already has the case's size).
    pub fn run_params(&self, scene: &Scene) -> RunParams {
        self.params_with(scene.triangle_count() as u32, scene.light.size())
    }

    /// Run parameters for this case in a scene of `triangles` whose light has size
    /// `light_size` ([`Case::run_params`] without the scene).
    pub fn params_with(&self, triangles: u32, light_size: f32) -> RunParams {
        RunParams {
            triangles,
            light_size,
            map_resolution: self.map_resolution,
            tile_size: self.tile_size,
            image: self.image,
            occluder_height: self.scene.occluder_height,
            occluder_offset: self.scene.occluder_offset,
            cores: self.cores,
        }
    }
}

/// A square ground plane added under user meshes: a receiver of side `size` centred at
/// `center` (its height is `center.y`), in scene units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundPlane {
    pub center: Vec3,
    pub size: f32,
}

/// What was added around user meshes to make a scene ([`framed_scene`]): each part is absent
/// where the file or scenario gave its own. Recorded in every run of such a scene.
#[skip_serializing_none]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Framing {
    pub ground: Option<GroundPlane>,
    pub camera: Option<Camera>,
    pub light: Option<Light>,
}

impl Framing {
    /// One line per added part, for the terminal.
    pub fn describe(&self) -> Vec<String> {
        let v = |p: Vec3| format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z);
        let mut out = Vec::new();
        if let Some(g) = &self.ground {
            out.push(format!(
                "added ground plane: {:.4} × {:.4} square at y = {:.4}, centred at {}",
                g.size,
                g.size,
                g.center.y,
                v(g.center)
            ));
        }
        if let Some(c) = &self.camera {
            out.push(format!(
                "added camera: eye {}, target {}, vertical field of view {}°",
                v(c.eye),
                v(c.target),
                c.fov_y_deg
            ));
        }
        if let Some(l) = &self.light {
            out.push(format!(
                "added light: {} at {}, size {:.4}",
                l.kind(),
                v(l.center()),
                l.size()
            ));
        }
        out
    }
}

/// What a scene of user meshes brings besides its geometry: the readers' warnings (skipped
/// elements, missing material libraries) and what was added around the meshes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneNotes {
    pub warnings: Vec<String>,
    pub framing: Option<Framing>,
    /// The files the scene was read from: the mesh file or scenario named, a scenario's
    /// `scene.objects` files and its light texture PNG (what a command must not overwrite).
    pub inputs: Vec<PathBuf>,
}

impl SceneNotes {
    /// Adds the notes to a run's record.
    pub fn annotate(&self, record: &mut crate::record::RunRecord) {
        record.warnings.extend(self.warnings.iter().cloned());
        if record.framing.is_none() {
            record.framing = self.framing.clone();
        }
    }
}

/// A scenario that passed validation, with its file's folder for relative paths.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub path: PathBuf,
    pub scenario: Scenario,
    /// Objects of `scene.objects`, loaded, transformed and checked during validation.
    objects: Vec<Object>,
    /// The meshes of `sweep.meshes`, each as the first object it replaces.
    swept: Vec<Object>,
    /// Readers' warnings and the framing of `scene.objects` (empty for generators).
    pub notes: SceneNotes,
    /// The machine `$.machine` names, resolved during validation.
    pub machine: MachineConfig,
    /// The texture `$.light.texture` describes, resolved during validation.
    pub light_texture: Option<Arc<LightTexture>>,
    /// The command-line overrides applied to the file (`run --set` / `--sweep`), as
    /// `PATH=VALUE` ([`overrides::Override::describe`]); empty when read as written.
    pub overrides: Vec<String>,
}

impl Loaded {
    /// Reads and validates a scenario file.
    pub fn from_file(path: &Path) -> Result<Loaded, InputError> {
        let text = crate::util::input::read_text(path, "scenario")?;
        Loaded::from_str(&text, path)
    }

    /// Reads a scenario file with command-line `overrides` applied to its JSON before it is
    /// validated ([`overrides`]); an error in an overridden field names the flag and the field.
    pub fn from_file_with(
        path: &Path,
        overrides: &[overrides::Override],
    ) -> Result<Loaded, InputError> {
        if overrides.is_empty() {
            return Loaded::from_file(path);
        }
        let text = crate::util::input::read_text(path, "scenario")?;
        let mut doc: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| malformed(path, e))?;
        overrides::apply_all(&mut doc, overrides).map_err(|e| e.in_file(path))?;
        let scenario: Scenario = serde_path_to_error::deserialize(doc)
            .map_err(|e| parse_error(path, e))
            .map_err(|e| overrides::attribute(e, overrides))?;
        let mut loaded = Loaded::from_scenario(scenario, path)
            .map_err(|e| overrides::attribute(e, overrides))?;
        loaded.overrides = overrides.iter().map(|o| o.describe()).collect();
        Ok(loaded)
    }

    /// Parses and validates scenario text; `path` names it in errors and anchors relative paths.
    pub fn from_str(text: &str, path: &Path) -> Result<Loaded, InputError> {
        let scenario: Scenario = crate::util::json::parse(text, path)?;
        Loaded::from_scenario(scenario, path)
    }

    /// Validates a parsed scenario read from `path` (which anchors its relative paths).
    fn from_scenario(scenario: Scenario, path: &Path) -> Result<Loaded, InputError> {
        let base = path.parent().unwrap_or(Path::new("."));
        validate(&scenario).map_err(|e| e.in_file(path))?;
        let mut objects = Vec::new();
        let mut warnings = Vec::new();
        for (i, o) in scenario.scene.objects.iter().flatten().enumerate() {
            let MeshFile { mesh, warnings: w } =
                load::load_mesh(&base.join(&o.obj), o.part.as_deref()).map_err(|e| InputError {
                    file: Some(path.to_path_buf()),
                    field: Some(format!("$.scene.objects[{i}].obj")),
                    message: e.to_string(),
                })?;
            warnings.extend(w);
            objects.push(Object {
                name: o
                    .name
                    .clone()
                    .or_else(|| o.part.clone())
                    .unwrap_or_else(|| {
                        o.obj
                            .file_stem()
                            .map(|s| s.to_string_lossy().into_owned())
                            .unwrap_or_default()
                    }),
                mesh: mesh.transformed(object_transform(o)),
                role: Role {
                    occluder: o.occluder.unwrap_or(true),
                    receiver: o.receiver.unwrap_or(true),
                },
            });
        }
        load::check_extent(&objects).map_err(|f| InputError {
            file: Some(path.to_path_buf()),
            field: Some(format!("$.scene.objects[{}]", f.object)),
            message: format!(
                "{} after its transform: {}",
                scenario
                    .scene
                    .objects
                    .as_ref()
                    .expect("objects were loaded")[f.object]
                    .obj
                    .display(),
                f.message
            ),
        })?;
        let swept = swept_meshes(&scenario, &objects, path)?;
        let framing = scenario.scene.objects.as_ref().map(|_| {
            let (_, mut framing) =
                framed_scene(objects.clone(), scenario.scene.ground.unwrap_or(true));
            if scenario.camera.is_some() {
                framing.camera = None;
            }
            if scenario.light.is_some() {
                framing.light = None;
            }
            framing
        });
        let machine = match &scenario.machine {
            Some(m) => MachineConfig::resolve("$.machine", m, base).map_err(|e| e.in_file(path))?,
            None => MachineConfig::default(),
        };
        let light_texture = match scenario.light.as_ref().and_then(|l| l.texture.as_ref()) {
            Some(t) => Some(Arc::new(
                t.resolve("$.light.texture", base)
                    .map_err(|e| e.in_file(path))?,
            )),
            None => None,
        };
        let inputs = std::iter::once(path.to_path_buf())
            .chain(
                scenario
                    .scene
                    .objects
                    .iter()
                    .flatten()
                    .map(|o| base.join(&o.obj)),
            )
            .chain(
                (scenario.light.as_ref())
                    .and_then(|l| l.texture.as_ref())
                    .and_then(|t| t.png.as_ref())
                    .map(|p| base.join(p)),
            )
            .collect();
        Ok(Loaded {
            path: path.to_path_buf(),
            scenario,
            objects,
            notes: SceneNotes {
                warnings,
                framing,
                inputs,
            },
            machine,
            light_texture,
            overrides: Vec::new(),
            swept,
        })
    }

    pub fn name(&self) -> String {
        self.scenario.name.clone().unwrap_or_else(|| {
            self.path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scenario".into())
        })
    }

    /// How many points the sweep has before duplicates are removed, computed from the axis
    /// lengths without expanding anything: `1 + Σ len` in `each` mode, `Π max(len, 1)` in
    /// `grid` mode (saturating; u128 holds the product of eight axes of up to 2^16 values
    /// each, and anything beyond saturates).
    pub fn case_count(&self) -> u128 {
        let w = &self.scenario.sweep;
        let lens = [
            w.triangles.len(),
            w.occluder_height.len(),
            w.occluder_offset.len(),
            w.light_size.len(),
            w.map_resolution.len(),
            w.tile_size.len(),
            w.image.len(),
            w.cores.len(),
            w.meshes.len(),
        ];
        match self.scenario.sweep_mode {
            SweepMode::Each => 1 + lens.iter().map(|&n| n as u128).sum::<u128>(),
            SweepMode::Grid => lens
                .iter()
                .fold(1u128, |p, &n| p.saturating_mul(n.max(1) as u128)),
        }
    }

    /// Refuses a sweep of more than `limit` points ([`Loaded::case_count`]) before anything
    /// proportional to it is allocated, with the count and the runs it would make.
    pub fn check_case_count(&self, limit: u64) -> Result<(), InputError> {
        let n = self.case_count();
        if n <= limit as u128 {
            return Ok(());
        }
        let runs = n.saturating_mul(
            self.scenario.algorithms.len() as u128 * self.scenario.backends.len() as u128,
        );
        Err(InputError {
            file: Some(self.path.clone()),
            field: Some("$.sweep".into()),
            message: format!(
                "the sweep has {n} cases ({} mode), up to {runs} runs, over the limit of {limit} \
                 cases; narrow the sweep or raise the limit with --max-cases",
                match self.scenario.sweep_mode {
                    SweepMode::Each => "each",
                    SweepMode::Grid => "grid",
                },
            ),
        })
    }

    /// The points of the sweep, in a stable order, without duplicates; a sweep of more than
    /// `limit` points is refused first ([`Loaded::check_case_count`]). Linear in the number of
    /// points (duplicates are found with a hash set).
    pub fn cases(&self, limit: u64) -> Result<Vec<Case>, InputError> {
        self.check_case_count(limit)?;
        let s = &self.scenario;
        let b = &s.params;
        let base = Case {
            scene: ScenePoint {
                triangles: b.triangles,
                mesh: None,
                occluder_height: b.occluder_height,
                occluder_offset: b.occluder_offset,
            },
            light_size: b.light_size,
            map_resolution: b.map_resolution,
            tile_size: b.tile_size,
            image: b.image,
            cores: b.cores,
        };
        type Apply = Box<dyn Fn(&mut Case)>;
        let w = &s.sweep;
        let axes: Vec<Vec<Apply>> = vec![
            w.triangles
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.scene.triangles = Some(v)) as Apply)
                .collect(),
            w.occluder_height
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.scene.occluder_height = Some(v)) as Apply)
                .collect(),
            w.occluder_offset
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.scene.occluder_offset = Some(v)) as Apply)
                .collect(),
            w.light_size
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.light_size = Some(v)) as Apply)
                .collect(),
            w.map_resolution
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.map_resolution = v) as Apply)
                .collect(),
            w.tile_size
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.tile_size = v) as Apply)
                .collect(),
            w.image
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.image = v) as Apply)
                .collect(),
            w.cores
                .iter()
                .map(|&v| Box::new(move |c: &mut Case| c.cores = Some(v)) as Apply)
                .collect(),
            (0..w.meshes.len())
                .map(|i| Box::new(move |c: &mut Case| c.scene.mesh = Some(i)) as Apply)
                .collect(),
        ];
        let mut cases: Vec<Case> = match s.sweep_mode {
            SweepMode::Each => {
                let mut v = vec![base.clone()];
                for axis in &axes {
                    for f in axis {
                        let mut c = base.clone();
                        f(&mut c);
                        v.push(c);
                    }
                }
                v
            }
            SweepMode::Grid => {
                let mut v = vec![base.clone()];
                for axis in axes.iter().filter(|a| !a.is_empty()) {
                    v = v
                        .into_iter()
                        .flat_map(|c| {
                            axis.iter().map(move |f| {
                                let mut c = c.clone();
                                f(&mut c);
                                c
                            })
                        })
                        .collect();
                }
                v
            }
        };
        let mut seen = std::collections::HashSet::with_capacity(cases.len());
        cases.retain(|c| seen.insert(c.key()));
        Ok(cases)
    }

    /// Builds the scene at a sweep point, with the scenario's camera and light overrides and the
    /// light resized to `light_size`.
    pub fn build_scene(&self, point: ScenePoint, light_size: Option<f32>) -> Scene {
        let s = &self.scenario;
        let mut scene = match &s.scene.generator {
            Some(name) => {
                generators::find(name)
                    .expect("generator validated")
                    .build(&GeneratorParams {
                        triangles: point.triangles,
                        seed: s.seed,
                        occluder_height: point.occluder_height,
                        occluder_offset: point.occluder_offset,
                    })
            }
            None => {
                let mut objects = self.objects.clone();
                if let Some(i) = point.mesh {
                    objects[0] = self.swept[i].clone();
                }
                framed_scene(objects, s.scene.ground.unwrap_or(true)).0
            }
        };
        scene.name = s.scene.generator.clone().unwrap_or_else(|| self.name());
        if let Some(c) = s.camera {
            scene.camera = c;
        }
        if let Some(l) = &s.light {
            scene.light = l.light;
            scene.light_texture = self.light_texture.clone();
        }
        if let Some(size) = light_size {
            scene.light = scene.light.with_size(size);
        }
        scene
    }
}

/// The meshes of `sweep.meshes`, each loaded as `scene.objects[0]` (`objects[0]` loaded) with
/// that object's part, transform and roles; errors name `$.sweep.meshes[i]`. Two files whose
/// scenes (with the other objects) have the same triangle count, or one with the count of the
/// base point's mesh that is another file, are refused: a run is known by its triangle count.
fn swept_meshes(s: &Scenario, objects: &[Object], path: &Path) -> Result<Vec<Object>, InputError> {
    let (Some(specs), Some(first)) = (&s.scene.objects, objects.first()) else {
        return Ok(Vec::new());
    };
    let base = path.parent().unwrap_or(Path::new("."));
    let spec = &specs[0];
    let others: usize = objects[1..].iter().map(|o| o.mesh.triangles.len()).sum();
    let mut counts: Vec<(usize, PathBuf, String)> = vec![(
        others + first.mesh.triangles.len(),
        base.join(&spec.obj),
        "the base point's mesh (scene.objects[0])".into(),
    )];
    let mut out = Vec::new();
    for (i, file) in s.sweep.meshes.iter().enumerate() {
        let field = format!("$.sweep.meshes[{i}]");
        let err = |message: String| InputError {
            file: Some(path.to_path_buf()),
            field: Some(field.clone()),
            message,
        };
        let MeshFile { mesh, .. } = load::load_mesh(&base.join(file), spec.part.as_deref())
            .map_err(|e| err(e.to_string()))?;
        let object = Object {
            mesh: mesh.transformed(object_transform(spec)),
            ..first.clone()
        };
        load::check_extent(std::slice::from_ref(&object)).map_err(|f| {
            err(format!(
                "{} after its transform: {}",
                file.display(),
                f.message
            ))
        })?;
        let n = others + object.mesh.triangles.len();
        let here = base.join(file);
        let clash = counts
            .iter()
            .find(|(c, p, _)| *c == n && !crate::util::paths::same_file(p, &here));
        if let Some((_, _, what)) = clash {
            return Err(err(format!(
                "{}: its scene has {n} triangles, as {what} has; each mesh of a sweep needs \
                 its own triangle count (runs are known by it)",
                file.display()
            )));
        }
        counts.push((n, here, field.clone()));
        out.push(object);
    }
    Ok(out)
}

/// The error of a scenario's JSON that does not parse.
fn malformed(path: &Path, inner: serde_json::Error) -> InputError {
    InputError {
        file: Some(path.to_path_buf()),
        field: None,
        message: format!("malformed JSON: {inner}"),
    }
}

/// The error of a scenario that does not deserialize, naming the JSON path.
fn parse_error(path: &Path, e: serde_path_to_error::Error<serde_json::Error>) -> InputError {
    let field = e.path().to_string();
    let inner = e.into_inner();
    if inner.is_syntax() || inner.is_eof() {
        return malformed(path, inner);
    }
    InputError {
        file: Some(path.to_path_buf()),
        field: Some(match field.as_str() {
            "." => "$".into(),
            f => format!("$.{f}"),
        }),
        message: inner.to_string(),
    }
}

fn object_transform(o: &ObjectSpec) -> Mat4 {
    let r = o.rotate_deg.unwrap_or(Vec3::ZERO);
    Mat4::from_scale_rotation_translation(
        Vec3::splat(o.scale.unwrap_or(1.0)),
        Quat::from_euler(
            glam::EulerRot::ZYX,
            r.z.to_radians(),
            r.y.to_radians(),
            r.x.to_radians(),
        ),
        o.translate.unwrap_or(Vec3::ZERO),
    )
}

/// A scene around user meshes: optional ground under them, a camera that frames them and a
/// sphere light above them, all scaled to their bounds; with what was added.
pub fn framed_scene(mut objects: Vec<Object>, ground: bool) -> (Scene, Framing) {
    let b = objects
        .iter()
        .fold(crate::scene::Bounds::EMPTY, |b, o| b.union(o.mesh.bounds()));
    let (c, d) = (b.center(), b.diagonal().max(1e-3));
    let plane = ground.then(|| GroundPlane {
        center: Vec3::new(c.x, b.min.y - 0.02 * d, c.z),
        size: d * 1.5,
    });
    if let Some(g) = plane {
        let mesh =
            generators::primitives::plane(g.size, 16).transformed(Mat4::from_translation(g.center));
        objects.insert(
            0,
            Object {
                name: "ground".into(),
                mesh,
                role: Role::RECEIVER,
            },
        );
    }
    let camera = Camera::looking_at(
        c + Vec3::new(0.0, 0.9, 1.3) * d,
        Vec3::new(c.x, b.min.y, c.z),
        45.0,
    );
    let light = Light::Sphere {
        center: c + Vec3::new(0.3, 1.8, 0.2) * d,
        radius: 0.08 * d,
    };
    (
        Scene::new(objects, camera, light),
        Framing {
            ground: plane,
            camera: Some(camera),
            light: Some(light),
        },
    )
}

/// A scene by name (a generator) or by file (a mesh file placed over a ground, or a scenario's
/// scene), with the notes of its loading (empty for a generator).
pub fn scene_from_arg(
    arg: &str,
    params: GeneratorParams,
) -> Result<(Scene, SceneNotes), InputError> {
    // `--occluder-height` and `--occluder-offset` need a scene whose occluder they move.
    let placement_applies = |generator: Option<&str>| {
        use validate::OccluderAxis::{Height, Offset};
        for (given, flag, axis) in [
            (
                params.occluder_height.is_some(),
                "--occluder-height",
                Height,
            ),
            (
                params.occluder_offset.is_some(),
                "--occluder-offset",
                Offset,
            ),
        ] {
            if given {
                validate::occluder_axis_scene(flag, generator, axis)?;
            }
        }
        Ok::<(), InputError>(())
    };
    if let Some(g) = generators::find(arg) {
        placement_applies(Some(g.name))?;
        return Ok((g.build(&params), SceneNotes::default()));
    }
    let path = Path::new(arg);
    if load::mesh_extension(path).is_some() {
        placement_applies(None)?;
        let file = load::load_mesh(path, None)?;
        let name = path
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let objects = vec![Object {
            name: name.clone(),
            mesh: file.mesh,
            role: Role::BOTH,
        }];
        load::check_extent(&objects).map_err(|f| InputError::file(path, f.message))?;
        let (mut s, framing) = framed_scene(objects, true);
        s.name = name;
        return Ok((
            s,
            SceneNotes {
                warnings: file.warnings,
                framing: Some(framing),
                inputs: vec![path.to_path_buf()],
            },
        ));
    }
    match path.extension().and_then(|e| e.to_str()) {
        Some("json") => {
            let l = Loaded::from_file(path)?;
            placement_applies(l.scenario.scene.generator.as_deref())?;
            let scene = l.build_scene(
                ScenePoint {
                    triangles: params.triangles.or(l.scenario.params.triangles),
                    mesh: None,
                    occluder_height: params.occluder_height.or(l.scenario.params.occluder_height),
                    occluder_offset: params.occluder_offset.or(l.scenario.params.occluder_offset),
                },
                l.scenario.params.light_size,
            );
            let mut notes = l.notes;
            notes.warnings.extend(unused_by_render(&l.scenario, path));
            Ok((scene, notes))
        }
        _ => Err(InputError::new(
            "--scene",
            crate::error::unknown_name("scene", arg, &generators::names())
                + &format!(
                    " (or a path to a mesh file, .{}, or a scenario .json file)",
                    load::EXTENSIONS.join(", .")
                ),
        )),
    }
}

/// A warning naming what of scenario `s` (read from `path` as `--scene`) a single render does
/// not take: it builds the scene, light and camera with the scenario's triangle count, occluder
/// placement and light size, but not its options, image, map resolution, tile size, cores or
/// sweep, which come from the command line.
fn unused_by_render(s: &Scenario, path: &Path) -> Option<String> {
    let (d, p, w) = (BaseParams::default(), &s.params, &s.sweep);
    let mut unused: Vec<String> = s.options.keys().map(|k| format!("options.{k}")).collect();
    for (name, differs) in [
        ("params.image", p.image != d.image),
        (
            "params.map_resolution",
            p.map_resolution != d.map_resolution,
        ),
        ("params.tile_size", p.tile_size != d.tile_size),
        ("params.cores", p.cores.is_some()),
        ("sweep.triangles", !w.triangles.is_empty()),
        ("sweep.light_size", !w.light_size.is_empty()),
        ("sweep.map_resolution", !w.map_resolution.is_empty()),
        ("sweep.tile_size", !w.tile_size.is_empty()),
        ("sweep.image", !w.image.is_empty()),
        ("sweep.occluder_height", !w.occluder_height.is_empty()),
        ("sweep.occluder_offset", !w.occluder_offset.is_empty()),
        ("sweep.cores", !w.cores.is_empty()),
        ("sweep.meshes", !w.meshes.is_empty()),
    ] {
        if differs {
            unused.push(name.to_string());
        }
    }
    (!unused.is_empty()).then(|| {
        format!(
            "{}: render takes the scenario's scene, light and camera only; its {} are not \
             used (the command line's values apply; `shadowbench run` runs the scenario)",
            path.display(),
            unused.join(", ")
        )
    })
}

/// A scenario (as JSON) that loads `mesh` (written by [`crate::scene::export::write_scene`] from
/// `scene`) back as the same scene: each part as an object with its role, the scene's camera and
/// light, no added ground; to be saved at `scenario`. The mesh is named relative to the
/// scenario's folder when it lies in it, else by its absolute path. A light texture is not
/// carried over (an input error: the exported scenario would have a white light).
pub fn export_scenario(
    scene: &Scene,
    mesh: &Path,
    scenario: &Path,
) -> Result<serde_json::Value, InputError> {
    if scene.light_texture.is_some() {
        return Err(InputError::new(
            "--scenario",
            "the scene's light has a texture, which an exported scenario cannot carry",
        ));
    }
    let same_dir =
        mesh.parent().unwrap_or(Path::new("")) == scenario.parent().unwrap_or(Path::new(""));
    let file = if same_dir {
        PathBuf::from(mesh.file_name().unwrap_or_default())
    } else {
        std::path::absolute(mesh).map_err(|e| InputError::file(mesh, e.to_string()))?
    };
    let objects: Vec<serde_json::Value> = scene
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| {
            serde_json::json!({
                "mesh": file,
                "part": crate::scene::export::part_name(i, o),
                "name": o.name,
                "occluder": o.role.occluder,
                "receiver": o.role.receiver,
            })
        })
        .collect();
    Ok(serde_json::json!({
        "name": scene.name,
        "description": format!("scene '{}' exported by shadowbench scene export", scene.name),
        "scene": { "objects": objects, "ground": false },
        "camera": scene.camera,
        "light": LightSpec { light: scene.light, texture: None },
        "algorithms": ["reference"],
        "backends": [Backend::CpuNative.name()],
    }))
}

/// The path of `file` as a scenario at `scenario` names it: relative to the scenario's folder
/// (scenario paths are, [`ObjectSpec::obj`]), through `..` where needed; absolute when the two
/// share no root (another drive).
pub fn relative_to_scenario(file: &Path, scenario: &Path) -> Result<PathBuf, InputError> {
    let abs = |p: &Path| std::path::absolute(p).map_err(|e| InputError::file(p, e.to_string()));
    let file = abs(file)?;
    let dir = abs(scenario)?;
    let dir = dir.parent().unwrap_or(Path::new("/"));
    let (f, d): (Vec<_>, Vec<_>) = (file.components().collect(), dir.components().collect());
    let common = f.iter().zip(&d).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return Ok(file);
    }
    let mut out = PathBuf::new();
    for _ in common..d.len() {
        out.push("..");
    }
    out.extend(&f[common..]);
    Ok(out)
}

/// The algorithms a scenario written by [`init_scenario`] compares: the soft-shadow methods
/// that take the sphere light it places (and the reference, for the quality metrics).
pub const INIT_ALGORITHMS: [&str; 5] = [
    "reference",
    "pcss",
    "penumbra_map",
    "soft_shadow_volume",
    "soft_shadow_map",
];

/// A scenario (as JSON) for the mesh at `mesh`, to be saved at `scenario`: the mesh as one
/// object (named relative to the scenario's folder), a ground plane, the framing camera and
/// light ([`framed_scene`]), [`INIT_ALGORITHMS`] on both CPU executions at 320 × 240 and a
/// sweep of three light sizes around the framed light's. The mesh is read (so a bad file is an
/// error now, naming it) and the scenario is validated as `run` will read it.
pub fn init_scenario(mesh: &Path, scenario: &Path) -> Result<serde_json::Value, InputError> {
    let file = load::load_mesh(mesh, None).map_err(|e| e.in_file(mesh))?;
    let name = mesh
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "mesh".into());
    let objects = vec![Object {
        name: name.clone(),
        mesh: file.mesh,
        role: Role::BOTH,
    }];
    load::check_extent(&objects).map_err(|f| InputError::file(mesh, f.message))?;
    let (scene, _) = framed_scene(objects, true);
    let size = scene.light.size();
    // Three significant digits: the file stays readable.
    let round = |v: f32| format!("{v:.3e}").parse::<f32>().unwrap_or(v);
    let doc = serde_json::json!({
        "name": name,
        "description": format!(
            "soft-shadow methods on {}: mesh path relative to this file",
            mesh.file_name().unwrap_or_default().to_string_lossy()
        ),
        "scene": {
            "objects": [{ "mesh": relative_to_scenario(mesh, scenario)? }],
            "ground": true
        },
        "algorithms": INIT_ALGORITHMS,
        "backends": [Backend::CpuNative.name(), Backend::CpuModel.name()],
        "params": { "image": [320, 240], "map_resolution": 512, "tile_size": 32 },
        "sweep": { "light_size": [round(size * 0.5), round(size), round(size * 2.0)] },
        "reference": { "samples": 256 },
    });
    Loaded::from_str(&doc.to_string(), scenario)?;
    Ok(doc)
}

#[cfg(test)]
mod init_tests {
    use super::*;

    #[test]
    fn a_path_relative_to_the_scenario_goes_up_where_needed() {
        let r = |f: &str, s: &str| relative_to_scenario(Path::new(f), Path::new(s)).unwrap();
        assert_eq!(r("/a/m/x.obj", "/a/s/t.json"), PathBuf::from("../m/x.obj"));
        assert_eq!(r("/a/x.obj", "/a/t.json"), PathBuf::from("x.obj"));
        assert_eq!(r("/a/x.obj", "/a/b/c/t.json"), PathBuf::from("../../x.obj"));
    }

    #[test]
    fn init_writes_a_scenario_that_loads_its_mesh_from_the_scenario_folder() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = dir.path().join("models/tri.obj");
        std::fs::create_dir_all(mesh.parent().unwrap()).unwrap();
        std::fs::write(&mesh, "v 0 0 0\nv 1 0 0\nv 0 1 0.5\nf 1 2 3\n").unwrap();
        let out = dir.path().join("studies/tri.json");
        std::fs::create_dir_all(out.parent().unwrap()).unwrap();
        let doc = init_scenario(&mesh, &out).unwrap();
        assert_eq!(doc["scene"]["objects"][0]["mesh"], "../models/tri.obj");
        std::fs::write(&out, doc.to_string()).unwrap();
        let l = Loaded::from_file(&out).unwrap();
        // The mesh's triangle and the ground's.
        let scene = l.build_scene(l.cases(100).unwrap()[0].scene, None);
        assert!(scene.objects.iter().any(|o| o.name == "tri"));
        assert_eq!(l.scenario.sweep.light_size.len(), 3);
        let bad = dir.path().join("models/bad.obj");
        std::fs::write(&bad, "f 1 2 3\n").unwrap();
        assert!(init_scenario(&bad, &out).is_err());
    }

    #[test]
    fn overrides_are_validated_as_the_file_and_recorded() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quick.json");
        let o = [
            overrides::Override::set("options.pcss.pcf_samples=16").unwrap(),
            overrides::Override::sweep("light_size=0.3,0.6").unwrap(),
        ];
        let l = Loaded::from_file_with(&path, &o).unwrap();
        assert_eq!(l.scenario.sweep.light_size, [0.3, 0.6]);
        assert_eq!(l.scenario.options["pcss"]["pcf_samples"], 16);
        assert_eq!(
            l.overrides,
            ["options.pcss.pcf_samples=16", "sweep.light_size=[0.3,0.6]"]
        );
        let bad = [overrides::Override::sweep("light_size=0.3,-1").unwrap()];
        let e = Loaded::from_file_with(&path, &bad).unwrap_err();
        assert!(
            e.field
                .as_deref()
                .unwrap()
                .starts_with("--sweep sweep.light_size="),
            "{e}"
        );
        assert!(e.to_string().contains("$.sweep.light_size[1]"), "{e}");
    }
}
