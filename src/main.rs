//! The `shadowbench` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};

use shadowbench::algorithms::{self, Backend, ExecContext};
use shadowbench::error::{Error, InputError, Result};
use shadowbench::frame::Frame;
use shadowbench::harness::{self, ReferenceCache, RunOptions, Shard};
use shadowbench::model::{self, MachineConfig};
use shadowbench::report;
use shadowbench::scenario::{self, validate as check, Loaded};
use shadowbench::scene::generators::{self, GeneratorParams};
use shadowbench::util::cpu_time::Clock;
use shadowbench::util::paths::{same_file, slug};
use shadowbench::{errln, out, outln};

#[derive(Parser)]
#[command(
    name = "shadowbench",
    version,
    about = "Benchmark real-time soft-shadow algorithms on wgpu and on a modelled many-core SIMD machine"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The GPU adapter option of the subcommands that use the wgpu execution.
#[derive(clap::Args)]
struct AdapterArg {
    /// GPU adapter for the wgpu execution: a substring of its name (default: the best found,
    /// discrete > integrated > CPU; also settable with SHADOWBENCH_ADAPTER).
    #[arg(long, value_name = "NAME")]
    adapter: Option<String>,
}

/// The measurement protocol's options of `run` and `render` (each overrides the scenario's
/// `measure` field; `shadowbench::harness::measure`).
#[derive(clap::Args)]
struct MeasureArgs {
    /// Iterations before the timed ones; the first is timed apart as the cold iteration
    /// (cold_wall_ms, cold_gpu_ms). Default 1.
    #[arg(long, value_name = "N")]
    warmup: Option<u32>,
    /// Timed iterations of each run; its times are their median, every sample kept. Default 5.
    #[arg(long, value_name = "N")]
    repeats: Option<u32>,
    /// Keep timing past --repeats until the timed iterations took this many seconds.
    #[arg(long, value_name = "SECONDS")]
    min_time: Option<f64>,
    /// Start no timed iteration once they took this many seconds (one always runs). Default 1.
    #[arg(long, value_name = "SECONDS")]
    max_time: Option<f64>,
}

impl MeasureArgs {
    /// The overrides, checked against the defaults so a bad flag is refused before anything
    /// runs.
    fn overrides(&self) -> std::result::Result<harness::measure::Overrides, InputError> {
        let o = harness::measure::Overrides {
            warmup: self.warmup,
            repeats: self.repeats,
            min_time_s: self.min_time,
            max_time_s: self.max_time,
        };
        o.apply(harness::measure::Measure::default())?;
        Ok(o)
    }
}

/// The instrumented-replay option of the subcommands that run the wgpu execution.
#[derive(clap::Args)]
struct GpuCountersArg {
    /// `off` skips the wgpu runs' instrumented replay when only times matter: their counters
    /// derived from it (fill, overdraw, taps, ...) are then absent from the record (named in
    /// execution.gpu_counters_absent, never zero) and execution.gpu_counters is "off"; the
    /// image, the times and the pipeline statistics are the same.
    #[arg(long, value_name = "on|off", default_value = "on",
          value_parser = clap::builder::PossibleValuesParser::new(["on", "off"]))]
    gpu_counters: String,
}

impl GpuCountersArg {
    fn mode(&self) -> shadowbench::gpu::GpuCounters {
        shadowbench::gpu::GpuCounters::parse(&self.gpu_counters).expect("clap checked the value")
    }
}

/// The ids of the registered algorithms, for `--algorithm` and `--only`.
fn algorithm_ids() -> Vec<&'static str> {
    algorithms::ALGORITHMS.iter().map(|a| a.id).collect()
}

/// The names of the executions, for `--backend`.
fn backend_names() -> Vec<&'static str> {
    Backend::ALL.iter().map(|b| b.name()).collect()
}

#[derive(Subcommand)]
enum Command {
    /// List algorithms, executions, machines, scenes and scenarios; with --machine, print one
    /// machine's full parameters as JSON.
    List {
        /// Folder of scenario files to list.
        #[arg(long, default_value = "scenarios", value_name = "DIR")]
        scenarios: PathBuf,
        /// Print this machine preset's (or machine .json file's) full parameters as JSON, to
        /// copy and edit into a machine file, instead of the lists.
        #[arg(long, value_name = "NAME")]
        machine: Option<String>,
        #[command(flatten)]
        adapter: AdapterArg,
        /// Print only the counter glossary: each counter's meaning, unit and executions.
        #[arg(long)]
        counters: bool,
    },
    /// Render one frame: DIR/visibility.png, DIR/visibility.npy, DIR/run.json.
    Render(RenderArgs),
    /// Run a scenario sweep: DIR/results.json, DIR/results.csv, per-run images.
    Run(RunArgs),
    /// Write charts and index.html into DIR from an existing results.json; with several, each
    /// into DIR/<scenario name>/ and DIR/index.html with every paper claim.
    Report {
        /// results.json files written by `run` or `merge`.
        #[arg(required = true)]
        results: Vec<PathBuf>,
        /// Folder to write the report into.
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
        /// One report of the runs of every file together, charted on shared axes (levels of
        /// detail or variants run as separate scenarios), with the joined results in DIR.
        #[arg(long)]
        combine: bool,
    },
    /// Join the results of shards into DIR: results.json, results.csv, images and report.
    Merge {
        /// results.json files of the shards of one sweep.
        #[arg(required = true)]
        results: Vec<PathBuf>,
        /// Folder to write the joined results and report into.
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
    },
    /// Difference image of two runs' visibility: red where A is brighter, blue where darker,
    /// background (per A's mask.npy) in blue-grey; prints the mean and largest difference.
    Diff {
        /// A run's image folder (images/<case>/ or a render output) or its visibility.npy.
        a: PathBuf,
        /// The run to subtract, as A.
        b: PathBuf,
        /// PNG to write.
        #[arg(long, default_value = "out/diff.png", value_name = "FILE")]
        out: PathBuf,
    },
    /// Write a scenario for a mesh file: the mesh over a ground plane with a framing camera
    /// and light, the soft-shadow methods and the reference on both CPU executions, a sweep of
    /// three light sizes; `shadowbench run SCENARIO.json` runs it.
    Init {
        /// The mesh file (.obj, .gltf, .glb, .ply).
        #[arg(long, value_name = "FILE")]
        mesh: PathBuf,
        /// The scenario file to write (the mesh is named relative to its folder).
        #[arg(long, value_name = "SCENARIO.json")]
        out: PathBuf,
        /// Replace the file if it exists.
        #[arg(long)]
        force: bool,
    },
    /// Scene tools: `scene export`.
    Scene {
        #[command(subcommand)]
        command: SceneCommand,
    },
    /// Measure this machine's costs with small kernels (vector arithmetic, scalar chains, line
    /// loads and stores, gathers, atomics, pointer-chasing latency per cache level, memory
    /// parallelism, DRAM bandwidth, the fork-join barrier), fit the issue costs to a training
    /// sweep of the algorithms on scenes validate-model does not use, and write the `host`
    /// machine with them as a machine .json file for --machine (every figure's method in
    /// `sources`).
    Calibrate {
        /// The machine .json file to write.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
        /// Fewer and shorter kernel runs and a smaller training sweep (160x120 only, one timed
        /// run per case): seconds instead of a minute; noisier figures.
        #[arg(long)]
        quick: bool,
        /// Keep the issue costs the kernels measured (no training sweep).
        #[arg(long)]
        kernels_only: bool,
        #[command(flatten)]
        training: TrainingArgs,
    },
    /// Run a fixed sweep (every CPU algorithm, 3 scenes, 2 image sizes) on cpu-native and on
    /// cpu-model with the calibrated host machine (calibrated first unless --machine, its
    /// issue costs fitted on other scenes), and write per run and per phase the modelled
    /// and measured times, their ratio, the agreement (geometric mean ratio, mean absolute
    /// percentage error, Spearman's ρ) and a log-log chart into DIR.
    ValidateModel(ValidateArgs),
    /// Compare the deterministic figures of two results files; exit 1 on a regression.
    Compare {
        /// The results.json to compare against.
        baseline: PathBuf,
        /// The results.json to check.
        current: PathBuf,
        /// Largest worsening allowed of a deterministic figure, in percent.
        #[arg(long, default_value_t = report::compare::DEFAULT_THRESHOLD_PCT)]
        threshold: f64,
        /// A figure's own threshold (deterministic) or minimum effect (measured), in percent:
        /// FIGURE=PCT, by glossary name (fill, gpu_ms) or as compared (phase.soft.fill);
        /// repeatable.
        #[arg(long, value_name = "FIGURE=PCT")]
        threshold_for: Vec<String>,
        /// Smallest change of a measured figure's median that is flagged, in percent.
        #[arg(long, default_value_t = report::measured::DEFAULT_MIN_EFFECT_PCT)]
        min_effect: f64,
        /// False-discovery rate of the measured figures' tests (Benjamini–Hochberg).
        #[arg(long, default_value_t = report::measured::DEFAULT_Q)]
        fdr: f64,
        /// `measured`: measured figures that are significantly slower fail the gate too (by
        /// default they are reported only, since shared runners are noisy).
        #[arg(long, value_name = "deterministic|measured", default_value = "deterministic",
              value_parser = clap::builder::PossibleValuesParser::new(["deterministic", "measured"]))]
        gate: String,
        /// Print the table of every figure that moved after the headline.
        #[arg(long, short)]
        verbose: bool,
        /// Write the table of every figure that moved into FILE.
        #[arg(long, value_name = "FILE")]
        details: Option<PathBuf>,
    },
    /// Results across commits: record them in a history database, check where figures
    /// stepped, write the trend page.
    History {
        #[command(subcommand)]
        command: HistoryCommand,
    },
}

#[derive(Subcommand)]
enum HistoryCommand {
    /// Add every figure of results files to a history database (made if missing), as of one
    /// commit; recording the same results again changes nothing.
    Record(HistoryRecordArgs),
    /// Find the commits where each series stepped and report the regressions and improvements
    /// since a commit; exit 1 on a regression.
    Check(HistoryCheckArgs),
    /// Write the trend page, DIR/index.html (self-contained): the steps since a commit, worst
    /// first, each plotted over the commits, then a panel per algorithm × execution.
    Report(HistoryReportArgs),
}

/// The commits `history check` and `history report` compare.
#[derive(clap::Args)]
struct HistoryRange {
    /// The commit to check (a full id or a unique prefix; default: the newest recorded).
    #[arg(long, value_name = "SHA")]
    commit: Option<String>,
    /// The commit to compare against (default: the last one before --commit recorded on
    /// --main-branch; the first commit when there is none).
    #[arg(long, value_name = "SHA")]
    since: Option<String>,
    /// The branch whose last commit --since defaults to.
    #[arg(long, default_value = "main", value_name = "NAME")]
    main_branch: String,
    /// Smallest change that counts, in percent: for every figure (PERCENT) or for figures
    /// matching FIGURE (a name, a last part such as model_ms, or a prefix ending in *);
    /// repeatable, the last match wins. Defaults: 1% for deterministic, modelled and
    /// estimated figures, 10% for measured times.
    #[arg(long = "min-effect", value_name = "[FIGURE=]PERCENT")]
    min_effect: Vec<String>,
}

#[derive(clap::Args)]
struct HistoryReportArgs {
    /// The history database (SQLite).
    #[arg(long, value_name = "FILE")]
    db: PathBuf,
    /// Folder to write index.html into.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    #[command(flatten)]
    range: HistoryRange,
    /// Link commits here, {sha} replaced by the commit id (default on GitHub Actions:
    /// $GITHUB_SERVER_URL/$GITHUB_REPOSITORY/commit/{sha}; else the page's commit table).
    #[arg(long, value_name = "URL")]
    commit_url: Option<String>,
}

#[derive(clap::Args)]
struct HistoryRecordArgs {
    /// results.json files written by `run` or `merge`.
    #[arg(required = true)]
    results: Vec<PathBuf>,
    /// The history database (SQLite).
    #[arg(long, value_name = "FILE")]
    db: PathBuf,
    /// The commit the results are of (default: GITHUB_SHA, CI_COMMIT_SHA, else git's HEAD).
    #[arg(long, value_name = "SHA")]
    commit: Option<String>,
    /// The branch (default: GITHUB_HEAD_REF, GITHUB_REF_NAME, CI_COMMIT_REF_NAME, else git's).
    #[arg(long)]
    branch: Option<String>,
    /// The commit's date, ISO 8601 (default: git's committer date, CI_COMMIT_TIMESTAMP, else
    /// now). Commits are ordered by it.
    #[arg(long)]
    date: Option<String>,
    /// The commit's subject line (default: git's).
    #[arg(long)]
    subject: Option<String>,
    /// A name for this machine (e.g. the CI runner's label) instead of the host's CPU, CPU
    /// count and OS; series of different machines are never mixed.
    #[arg(long, value_name = "NAME")]
    machine: Option<String>,
}

#[derive(clap::Args)]
struct HistoryCheckArgs {
    /// The history database (SQLite).
    #[arg(long, value_name = "FILE")]
    db: PathBuf,
    #[command(flatten)]
    range: HistoryRange,
    /// text: the verdict; markdown: a summary, empty unless something crossed; bmf (Bencher
    /// Metric Format) or github-action-benchmark: the checked commit's figures (the verdict
    /// then goes to standard error).
    #[arg(long, default_value = "text",
          value_parser = clap::builder::PossibleValuesParser::new(
              ["text", "markdown", "bmf", "github-action-benchmark"]))]
    format: String,
    /// Write the output here instead of standard output; for github-action-benchmark a
    /// folder (required), receiving customSmallerIsBetter.json and customBiggerIsBetter.json.
    #[arg(long, value_name = "PATH")]
    output: Option<PathBuf>,
    /// bmf and github-action-benchmark: every figure, not only the headline ones (time,
    /// mae_shadow, fill).
    #[arg(long)]
    all_figures: bool,
}

#[derive(Subcommand)]
enum SceneCommand {
    /// Write the exact triangles a run uses (world coordinates, generated and added geometry
    /// included) as .obj or .glb, one part per object named INDEX_NAME_ROLE.
    Export(ExportArgs),
}

#[derive(clap::Args)]
struct ExportArgs {
    /// A built-in scene name, a mesh file (.obj, .gltf, .glb, .ply) or a scenario .json file.
    scene: String,
    /// The file to write: FILE.obj or FILE.glb.
    #[arg(long)]
    out: PathBuf,
    /// Also write a scenario that loads the exported file back: its parts as `objects` with
    /// their roles, the scene's camera and light, no added ground.
    #[arg(long)]
    scenario: Option<PathBuf>,
    #[command(flatten)]
    generator: GeneratorArgs,
    #[arg(long)]
    seed: Option<u64>,
}

/// The generator flags `render` and `scene export` share.
#[derive(clap::Args)]
struct GeneratorArgs {
    /// Target triangle count of a generated scene.
    #[arg(long)]
    triangles: Option<u32>,
    /// Height of the occluder above the receiver in generated scenes (scene units).
    #[arg(long)]
    occluder_height: Option<f32>,
    /// Lateral offset of the moving occluder along x (scene units; paper 002 §5.2.5).
    #[arg(long, allow_hyphen_values = true)]
    occluder_offset: Option<f32>,
}

impl GeneratorArgs {
    /// The generator parameters with `seed`, the flags checked as a scenario's would be.
    fn params(&self, seed: u64) -> std::result::Result<GeneratorParams, InputError> {
        if let Some(v) = self.triangles {
            check::triangles("--triangles", v)?;
        }
        if let Some(v) = self.occluder_height {
            check::occluder_height("--occluder-height", v)?;
        }
        if let Some(v) = self.occluder_offset {
            check::occluder_offset("--occluder-offset", v)?;
        }
        Ok(GeneratorParams {
            triangles: self.triangles,
            seed,
            occluder_height: self.occluder_height,
            occluder_offset: self.occluder_offset,
        })
    }
}

#[derive(clap::Args)]
struct RunArgs {
    /// Scenario files. With several, each runs into OUT/<scenario name>/ and OUT/index.html
    /// links their reports and evaluates every paper claim over all of their runs.
    #[arg(required = true)]
    scenario: Vec<PathBuf>,
    /// Folder for results.json, results.csv, summary.csv/.tex, images/, charts/, index.html.
    #[arg(long, default_value = "out/run", value_name = "DIR")]
    out: PathBuf,
    /// Set a scenario field for this run, by its JSON path: `options.pcss.pcf_samples=16`,
    /// `params.map_resolution=320`, `scene.objects[0].scale=2` (VALUE is JSON, or else text).
    /// Repeatable; applied to every scenario before it is validated; results.json records it.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    set: Vec<String>,
    /// Sweep an axis with these values instead of the scenario's: `light_size=0.3,0.6`,
    /// `image=[160,120],[320,240]` (sets `sweep.AXIS`). Repeatable; recorded as --set is.
    #[arg(long = "sweep", value_name = "AXIS=V1,V2,...")]
    sweep: Vec<String>,
    /// Only these algorithms (comma-separated); selecting no run of the scenario is an error.
    #[arg(long, value_delimiter = ',', value_name = "ALGORITHM",
          value_parser = clap::builder::PossibleValuesParser::new(algorithm_ids()))]
    only: Option<Vec<String>>,
    /// Only these executions (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "BACKEND",
          value_parser = clap::builder::PossibleValuesParser::new(backend_names()))]
    backend: Option<Vec<String>>,
    /// Where to cache reference images (default: OUT/reference-cache).
    #[arg(long, value_name = "DIR")]
    cache_dir: Option<PathBuf>,
    /// Refuse runs whose estimated working set exceeds this many GiB
    /// (default: half of physical memory).
    #[arg(long)]
    memory_limit: Option<f64>,
    /// Modelled machine of cpu-model runs: a preset or a machine .json file (overrides the
    /// scenario's `machine`).
    #[arg(long)]
    machine: Option<String>,
    /// Run only shard K of N of the planned runs (every N-th run, from the K-th). Without it,
    /// inside a Slurm array job K and N come from SLURM_ARRAY_TASK_ID (less
    /// SLURM_ARRAY_TASK_MIN, over SLURM_ARRAY_TASK_STEP) and SLURM_ARRAY_TASK_COUNT, and in a
    /// Kubernetes indexed Job K from JOB_COMPLETION_INDEX with N from --shard-count.
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
    /// Refuse a scenario whose sweep has more points than this.
    #[arg(long, default_value_t = scenario::MAX_CASES)]
    max_cases: u64,
    /// Stop any run that takes longer than this many seconds and record it as failed, with its
    /// work estimate (overrides the scenario's `run_timeout_s`).
    #[arg(long, value_name = "SECONDS")]
    run_timeout: Option<f64>,
    /// The number of shards when the index comes from the batch system (JOB_COMPLETION_INDEX,
    /// or SLURM_ARRAY_TASK_ID overriding SLURM_ARRAY_TASK_COUNT).
    #[arg(long, value_name = "N", conflicts_with = "shard")]
    shard_count: Option<usize>,
    /// No progress bar, no line per run, no summary: only warnings, errors and where the
    /// results are.
    #[arg(long, short, conflicts_with = "verbose")]
    quiet: bool,
    /// One line per finished run also on a terminal.
    #[arg(long, short)]
    verbose: bool,
    #[command(flatten)]
    adapter: AdapterArg,
    #[command(flatten)]
    gpu_counters: GpuCountersArg,
    #[command(flatten)]
    measure: MeasureArgs,
    /// Replace the results already in --out (of any scenario or build). Without it, a sweep
    /// into a folder holding results of the same scenario and build keeps them and runs only
    /// what is missing; results of another scenario or build are refused.
    #[arg(long)]
    fresh: bool,
    /// When resuming, run again the runs that failed (or timed out) in the results kept.
    #[arg(long, conflicts_with = "fresh")]
    retry_failed: bool,
}

/// The training sweep of a calibration and the clock it measures on.
#[derive(clap::Args)]
struct TrainingArgs {
    /// Scenes of the training sweep the issue costs are fitted to (comma-separated built-in
    /// names; default: box-on-plane, cylinder-on-plane, sphere-grid).
    #[arg(long, value_delimiter = ',', value_name = "SCENE")]
    train_scenes: Option<Vec<String>>,
    /// Image sizes of the training sweep (comma-separated WxH; default: 240x180,480x360).
    #[arg(long, value_delimiter = ',', value_name = "WxH")]
    train_images: Option<Vec<String>>,
    /// Timed cpu-native runs per training case, after one warm-up run (the median is used).
    #[arg(long, default_value_t = 3)]
    train_repeats: usize,
    /// The clock cpu-native is measured on: `cpu` (CPU time of the process's threads, the
    /// calling thread's plus the workers' over their count: other processes' load left out)
    /// or `wall`.
    #[arg(long, value_enum, default_value_t = Clock::Cpu)]
    clock: Clock,
}

#[derive(clap::Args)]
struct ValidateArgs {
    /// Folder for validation.json, runs.csv, phases.csv, summary.txt, the chart and
    /// machine.json.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// The cpu-model's machine: a machine .json file (from `calibrate`) or a preset (default:
    /// calibrate now, written to DIR/machine.json).
    #[arg(long)]
    machine: Option<String>,
    /// Only these algorithms (comma-separated; default: every algorithm with both CPU
    /// executions).
    #[arg(long, value_delimiter = ',', value_name = "ALGORITHM",
          value_parser = clap::builder::PossibleValuesParser::new(algorithm_ids()))]
    only: Option<Vec<String>>,
    /// Scenes (comma-separated built-in names; default: sphere-on-plane, torus-on-plane,
    /// blob-on-plane).
    #[arg(long, value_delimiter = ',', value_name = "SCENE")]
    scenes: Option<Vec<String>>,
    /// Image sizes (comma-separated WxH; default: 400x300,640x480; none of the training
    /// sweep's).
    #[arg(long, value_delimiter = ',', value_name = "WxH")]
    images: Option<Vec<String>>,
    /// Timed cpu-native runs per case, after one warm-up run (the median is used).
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// When calibrating (no --machine): keep the issue costs the kernels measured instead of
    /// fitting them to the training sweep (every algorithm on --train-scenes at
    /// --train-images, whatever --only says).
    #[arg(long)]
    kernels_only: bool,
    /// k-fold cross-validation over scenes instead: the scenes (--scenes; default: the
    /// training and the validation scenes, six) in K folds; each fold's costs are fitted on the
    /// other folds' scenes at --train-images and predict its own scenes at --images.
    #[arg(long, value_name = "K")]
    folds: Option<usize>,
    #[command(flatten)]
    training: TrainingArgs,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// A built-in scene name, or a path to a mesh file (.obj, .gltf, .glb, .ply) or a scenario
    /// .json file.
    #[arg(long, default_value = "sphere-on-plane")]
    scene: String,
    /// The algorithm to run.
    #[arg(long, default_value = "reference",
          value_parser = clap::builder::PossibleValuesParser::new(algorithm_ids()))]
    algorithm: String,
    /// The execution to run it on (the algorithm must have it).
    #[arg(long, default_value = "cpu-native",
          value_parser = clap::builder::PossibleValuesParser::new(backend_names()))]
    backend: String,
    /// Light size: radius of a sphere or disc light, half-width of a square one (scene units;
    /// default: the scene's).
    #[arg(long)]
    light_size: Option<f32>,
    /// Shadow-map resolution, texels per side.
    #[arg(long, default_value_t = 512)]
    map_resolution: u32,
    /// Tile (bin) size of the binned rasterizers, pixels per side.
    #[arg(long, default_value_t = 32)]
    tile_size: u32,
    /// Eye image size, WxH.
    #[arg(long, default_value = "320x240")]
    image: String,
    #[command(flatten)]
    generator: GeneratorArgs,
    /// Light samples per pixel of the reference (a perfect square).
    #[arg(long, default_value_t = algorithms::reference::DEFAULT_SAMPLES)]
    samples: u32,
    /// Skip the reference (no quality metrics).
    #[arg(long)]
    no_reference: bool,
    /// Seed of the scene generators and the reference's sampling (default 1).
    #[arg(long)]
    seed: Option<u64>,
    /// Refuse the run if its estimated working set exceeds this many GiB
    /// (default: half of physical memory).
    #[arg(long)]
    memory_limit: Option<f64>,
    /// Folder for visibility.png, visibility.npy, run.json (and reference.png, error.png).
    #[arg(long, default_value = "out/render", value_name = "DIR")]
    out: PathBuf,
    /// Modelled machine of cpu-model runs: a preset or a machine .json file.
    #[arg(long, default_value = "larrabee-24")]
    machine: String,
    /// Core count of the modelled machine (overrides the preset's).
    #[arg(long)]
    cores: Option<u32>,
    #[command(flatten)]
    adapter: AdapterArg,
    #[command(flatten)]
    gpu_counters: GpuCountersArg,
    #[command(flatten)]
    measure: MeasureArgs,
}

/// `--memory-limit` in bytes, validated.
fn memory_limit(gib: Option<f64>) -> std::result::Result<u64, InputError> {
    match gib {
        None => Ok(harness::limits::default_limit()),
        Some(g) if g.is_finite() && g > 0.0 => Ok((g * (1u64 << 30) as f64) as u64),
        Some(g) => Err(InputError::new(
            "--memory-limit",
            format!("must be a number of GiB > 0, got {g}"),
        )),
    }
}

fn parse_image(s: &str) -> std::result::Result<[u32; 2], InputError> {
    let bad = || InputError::new("--image", format!("expected WxH (e.g. 320x240), got '{s}'"));
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok([
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ])
}

/// `list --machine NAME`: the machine's parameters as pretty JSON.
fn list_machine(name: &str) -> Result<()> {
    let m = MachineConfig::resolve("--machine", name, Path::new("."))?;
    outln!(
        "{}",
        serde_json::to_string_pretty(&m).expect("machine configs serialize")
    );
    Ok(())
}

fn list(scenarios: &std::path::Path) {
    outln!("algorithms:");
    for a in algorithms::ALGORITHMS {
        let b: Vec<&str> = a.backends.iter().map(|b| b.name()).collect();
        let l: Vec<String> = a.lights.iter().map(|l| l.to_string()).collect();
        outln!(
            "  {:<20} [{}] lights: {}  ({}) {}",
            a.id,
            b.join(", "),
            l.join("/"),
            a.source,
            a.summary
        );
    }
    outln!("executions:");
    outln!("  cpu-native   host kernels, uninstrumented");
    outln!("  cpu-model    modelled many-core SIMD machine (see machines)");
    outln!("  wgpu         GPU passes; adapters (* = used):");
    for line in shadowbench::gpu::adapter_report() {
        outln!("               {line}");
    }
    outln!("machines (--machine, scenario `machine`; or a machine .json file):");
    for name in model::config::PRESETS {
        match MachineConfig::preset(name).expect("listed presets exist") {
            Ok(m) => outln!("  {:<14} {}", name, m.describe()),
            Err(why) => outln!("  {name:<14} unavailable: {why}"),
        }
    }
    outln!("scenes:");
    for g in generators::GENERATORS {
        outln!(
            "  {:<18} ~{:>6} triangles  {}",
            g.name,
            g.default_triangles,
            g.summary
        );
    }
    outln!("scenarios ({}):", scenarios.display());
    match std::fs::read_dir(scenarios) {
        Ok(rd) => {
            let mut names: Vec<PathBuf> = rd
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "json"))
                .collect();
            names.sort();
            for p in names {
                let desc = Loaded::from_file(&p)
                    .map(|l| l.scenario.description.unwrap_or_default())
                    .unwrap_or_else(|e| format!("INVALID: {e}"));
                outln!("  {:<28} {}", p.display(), desc);
            }
        }
        Err(e) => outln!("  (cannot read: {e})"),
    }
}

fn render(a: RenderArgs) -> Result<()> {
    let backend = check::backend("--backend", &a.backend)?;
    check::algorithm("--algorithm", &a.algorithm)?;
    let info = algorithms::find(&a.algorithm).map_err(Error::Unsupported)?;
    if !info.backends.contains(&backend) {
        let has: Vec<&str> = info.backends.iter().map(|b| b.name()).collect();
        return Err(InputError::new(
            "--backend",
            format!(
                "algorithm '{}' has no '{}' execution (it has: {})",
                a.algorithm,
                backend,
                has.join(", ")
            ),
        )
        .into());
    }
    if backend == Backend::Wgpu {
        // Fail before the (slow) reference when the execution cannot run at all.
        shadowbench::gpu::gpu()?;
    }
    let image = parse_image(&a.image)?;
    check::image("--image", image)?;
    check::map_resolution("--map-resolution", a.map_resolution)?;
    check::tile_size("--tile-size", a.tile_size)?;
    check::reference_samples("--samples", a.samples)?;
    if let Some(v) = a.light_size {
        check::light_size("--light-size", v)?;
    }
    let seed = a.seed.unwrap_or(1);
    let generator = a.generator.params(seed)?;
    // render measures by the protocol's defaults and its flags (not a scenario's `measure`).
    let measure = a
        .measure
        .overrides()?
        .apply(harness::measure::Measure::default())?;
    let machine = MachineConfig::resolve("--machine", &a.machine, Path::new("."))?;
    if let Some(c) = a.cores {
        check::cores("--cores", c)?;
    }
    let (mut scene, notes) = scenario::scene_from_arg(&a.scene, generator)?;
    for line in notes.framing.iter().flat_map(|f| f.describe()) {
        outln!("{line}");
    }
    for w in &notes.warnings {
        errln!("warning: {w}");
    }
    if let Some(s) = a.light_size {
        scene.light = scene.light.with_size(s);
    }
    let kind = info.light_for(scene.light.kind());
    let converted =
        (kind != scene.light.kind()).then(|| harness::light_converted(scene.light.kind(), kind));
    if let Some(w) = &converted {
        errln!("note: {w}");
    }
    scene.light = harness::light_for_run(&scene, info).map_err(|e| {
        // A scene from a file: the error names it.
        let file = Path::new(&a.scene);
        if file.is_file() {
            e.in_file(file)
        } else {
            e
        }
    })?;
    let params = shadowbench::frame::RunParams {
        occluder_height: generator.occluder_height,
        occluder_offset: generator.occluder_offset,
        cores: a.cores,
        ..shadowbench::frame::RunParams::of_scene(&scene, image, a.map_resolution, a.tile_size)
    };
    harness::limits::check(
        info,
        backend,
        &machine,
        &params,
        memory_limit(a.memory_limit)?,
    )?;
    if a.scene.ends_with(".json") {
        not_an_output(Path::new(&a.scene), &[a.out.join("run.json")])?;
    }
    let _lock = harness::outdir::lock("--out", &a.out)?;
    let frame = Frame::new(scene, params);
    let ctx = ExecContext {
        reference_samples: a.samples,
        seed,
        machine,
        gpu_counters: a.gpu_counters.mode(),
        measure,
        ..Default::default()
    };
    let reference = if a.no_reference || a.algorithm == "reference" {
        None
    } else {
        Some(
            ReferenceCache::new(None, a.samples, seed)
                .get_or_compute(&frame)?
                .0,
        )
    };
    let configured = info.configure(&ctx.options)?;
    let (mut record, out) =
        harness::run_one(&frame, &configured, backend, &ctx, reference.as_ref());
    notes.annotate(&mut record);
    record.notes.extend(converted);
    harness::write_frame_files(
        &a.out,
        &record,
        out.as_ref().map(|o| &o.visibility),
        out.as_ref().and_then(|o| o.rgb.as_ref()),
        reference.as_ref(),
        &frame,
        ctx.flip_pixels_per_degree,
    )?;
    out!("{}", harness::summary_table(std::slice::from_ref(&record)));
    match record.failure {
        Some(f) => Err(Error::Other(f)),
        None => {
            outln!("wrote {}", a.out.display());
            Ok(())
        }
    }
}

/// `init`: writes a scenario for `mesh` at `out` (refusing an existing file unless `force`).
fn init(mesh: PathBuf, out: PathBuf, force: bool) -> Result<()> {
    if out.exists() && !force {
        return Err(InputError::new(
            "--out",
            format!("'{}' exists; pass --force to replace it", out.display()),
        )
        .into());
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    let doc = scenario::init_scenario(&mesh, &out)?;
    let text = serde_json::to_string_pretty(&doc).expect("JSON values serialize") + "\n";
    shadowbench::visibility::write_atomic(&out, text.as_bytes())?;
    outln!(
        "wrote {} ({}); run it with: shadowbench run {} --out out/{}",
        out.display(),
        doc["algorithms"]
            .as_array()
            .map(|a| format!("{} algorithms", a.len()))
            .unwrap_or_default(),
        out.display(),
        doc["name"].as_str().unwrap_or("mesh")
    );
    Ok(())
}

fn scene_export(a: ExportArgs) -> Result<()> {
    if let Some(path) = a.scenario.as_ref().filter(|p| same_file(p, &a.out)) {
        let why = format!(
            "'{}' is the --out file the scene is written to; give the scenario its own file",
            path.display()
        );
        return Err(InputError::new("--scenario", why).into());
    }
    let generator = a.generator.params(a.seed.unwrap_or(1))?;
    let (scene, notes) = scenario::scene_from_arg(&a.scene, generator)?;
    for w in &notes.warnings {
        errln!("warning: {w}");
    }
    // Neither file written may be one the scene was read from (`b.obj --out b.obj`).
    let outputs =
        std::iter::once(("--out", &a.out)).chain(a.scenario.iter().map(|p| ("--scenario", p)));
    for (flag, out) in outputs {
        if let Some(input) = notes.inputs.iter().find(|i| same_file(i, out)) {
            let why = format!(
                "'{}' is the file the scene is read from ('{}'), so it would be overwritten; \
                 write the export elsewhere",
                out.display(),
                input.display()
            );
            return Err(InputError::new(flag, why).into());
        }
    }
    // The scenario's folder first: one that cannot be made stops the export before the mesh.
    if let Some(dir) = (a.scenario.as_ref())
        .and_then(|p| p.parent())
        .filter(|d| !d.as_os_str().is_empty())
    {
        std::fs::create_dir_all(dir).map_err(|e| {
            let why = format!("cannot create the folder '{}': {e}", dir.display());
            InputError::new("--scenario", why)
        })?;
    }
    shadowbench::scene::export::write_scene(&scene, &a.out, "--out")?;
    outln!(
        "wrote {} ({} objects, {} triangles)",
        a.out.display(),
        scene.objects.len(),
        scene.triangle_count()
    );
    if let Some(path) = &a.scenario {
        let json = scenario::export_scenario(&scene, &a.out, path)?;
        let text = serde_json::to_vec_pretty(&json).expect("JSON values serialize");
        shadowbench::visibility::write_output(path, &text, "--scenario")?;
        outln!("wrote {}", path.display());
    }
    Ok(())
}

/// The files `run` writes into each scenario's folder (besides images, charts and the cache).
const RESULT_FILES: [&str; 3] = ["results.json", "results.csv", "index.html"];

/// Refuses an input file that the command would overwrite: one of `outputs` (when it exists,
/// compared as canonical paths).
fn not_an_output(input: &Path, outputs: &[PathBuf]) -> std::result::Result<(), InputError> {
    if !input.exists() {
        return Ok(());
    }
    match outputs.iter().find(|o| same_file(input, o)) {
        Some(o) => Err(InputError::file(
            input,
            format!(
                "this input is the file '{}' the command writes, so it would be overwritten; \
                 copy it elsewhere or choose another --out",
                o.display()
            ),
        )),
        None => Ok(()),
    }
}

fn run(a: RunArgs) -> Result<()> {
    let RunArgs {
        scenario,
        out,
        set,
        sweep,
        only,
        backend,
        cache_dir,
        memory_limit: memory_gib,
        machine,
        shard,
        max_cases,
        run_timeout,
        shard_count,
        quiet,
        verbose,
        adapter: _,
        gpu_counters,
        measure,
        fresh,
        retry_failed,
    } = a;
    let gpu_counters = gpu_counters.mode();
    let measure = measure.overrides()?;
    let verbosity = if quiet {
        harness::Verbosity::Quiet
    } else if verbose {
        harness::Verbosity::Verbose
    } else {
        harness::Verbosity::Normal
    };
    let overrides = set
        .iter()
        .map(|a| scenario::overrides::Override::set(a))
        .chain(
            sweep
                .iter()
                .map(|a| scenario::overrides::Override::sweep(a)),
        )
        .collect::<std::result::Result<Vec<_>, InputError>>()?;
    // Every scenario is checked before anything runs.
    let loaded = scenario
        .iter()
        .map(|p| Loaded::from_file_with(p, &overrides))
        .collect::<std::result::Result<Vec<Loaded>, InputError>>()?;
    for l in &loaded {
        l.check_case_count(max_cases)?;
    }
    let memory_limit = memory_limit(memory_gib)?;
    let run_timeout = run_timeout
        .map(|t| check::run_timeout("--run-timeout", t).map(|_| Duration::from_secs_f64(t)))
        .transpose()?;
    let machine = machine
        .map(|m| MachineConfig::resolve("--machine", &m, Path::new(".")))
        .transpose()?;
    let shard = match shard {
        Some(s) => Some(Shard::parse("--shard", &s)?),
        None => Shard::from_env(|k| std::env::var(k).ok(), shard_count)?.map(|(s, var)| {
            errln!("note: running shard {s} (from {var})");
            s
        }),
    };
    if let Some(only) = &only {
        for a in only {
            check::algorithm("--only", a)?;
        }
    }
    let backends = backend
        .map(|v| {
            v.iter()
                .map(|b| check::backend("--backend", b))
                .collect::<std::result::Result<Vec<Backend>, _>>()
        })
        .transpose()?;
    let several = loaded.len() > 1;
    let mut dirs: Vec<String> = Vec::new();
    for (l, path) in loaded.iter().zip(&scenario) {
        // Each scenario's folder under OUT: its name as one safe file name component.
        let name = slug(&l.name());
        if dirs.contains(&name) {
            return Err(InputError::file(
                path,
                format!(
                    "scenario name '{}' is given twice (folder '{name}'); each needs its own folder",
                    l.name()
                ),
            )
            .into());
        }
        dirs.push(name);
    }
    let outputs: Vec<PathBuf> = if several {
        std::iter::once(out.join("index.html"))
            .chain(
                dirs.iter()
                    .flat_map(|d| RESULT_FILES.map(|f| out.join(d).join(f))),
            )
            .collect()
    } else {
        RESULT_FILES.map(|f| out.join(f)).to_vec()
    };
    for path in &scenario {
        not_an_output(path, &outputs)?;
    }
    let _lock = harness::outdir::lock("--out", &out)?;
    let mut reports = Vec::new();
    for (l, dir) in loaded.iter().zip(&dirs) {
        let out_dir = if several { out.join(dir) } else { out.clone() };
        if several {
            outln!("== {dir}");
        }
        let results = harness::run_scenario(
            l,
            &RunOptions {
                out: out_dir.clone(),
                only: only.clone(),
                backends: backends.clone(),
                // Several scenarios share one reference cache.
                cache_dir: cache_dir
                    .clone()
                    .or_else(|| several.then(|| out.join("reference-cache"))),
                memory_limit,
                machine: machine.clone(),
                shard,
                max_cases,
                run_timeout,
                verbosity,
                gpu_counters,
                measure,
                fresh,
                retry_failed,
            },
        )?;
        if verbosity != harness::Verbosity::Quiet {
            out!("{}", harness::grouped_summary(&results.runs));
        }
        let written = report::write_report(&out_dir, &results)?;
        if verbosity != harness::Verbosity::Quiet {
            for n in report::notes_by_algorithm(&results.runs) {
                outln!("note: {n}");
            }
        }
        let failed = results.runs.iter().filter(|r| r.failure.is_some()).count();
        let warned = results
            .runs
            .iter()
            .filter(|r| !r.warnings.is_empty())
            .count();
        outln!(
            "{} runs ({} failed, {} with warnings); results in {}",
            results.runs.len(),
            failed,
            warned,
            out_dir.join("results.json").display()
        );
        let doubtful: Vec<&str> = results
            .runs
            .iter()
            .filter_map(|r| r.measured.as_ref())
            .flat_map(|m| m.warnings.first())
            .map(|w| w.split(':').next().unwrap_or_default())
            .collect();
        if !doubtful.is_empty() {
            let mut kinds = doubtful.clone();
            kinds.sort_unstable();
            kinds.dedup();
            outln!(
                "note: the measured times of {} runs carry warnings ({}; measured.warnings in \
                 results.json, the report's table of runs)",
                doubtful.len(),
                kinds.join(", ")
            );
        }
        if verbosity != harness::Verbosity::Quiet {
            print_report(&written);
        }
        reports.push((dir.clone(), results));
    }
    write_claims(
        &out,
        &reports,
        several,
        verbosity != harness::Verbosity::Quiet,
    )
}

/// Says where a report was written.
fn print_report(written: &report::Report) {
    outln!(
        "report: {} ({} charts)",
        written.index.display(),
        written.charts.len()
    );
}

/// Writes the claims verdicts of `reports` (and the index of several under `out`); prints the
/// verdicts when `print_claims` and where the index is.
fn write_claims(
    out: &Path,
    reports: &[(String, harness::output::ResultsFile)],
    several: bool,
    print_claims: bool,
) -> Result<()> {
    let claims = report::write_claims(out, reports, several)?;
    if print_claims {
        out!("{claims}");
    }
    if several {
        outln!("index: {}", out.join("index.html").display());
    }
    Ok(())
}

fn report_cmd(results: Vec<PathBuf>, out: PathBuf) -> Result<()> {
    let files = results
        .iter()
        .map(|p| report::read_results(p))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let several = files.len() > 1;
    // Each file's folder under OUT: its scenario name as one safe file name component, checked
    // for every file before anything is written.
    let names: Vec<String> = files.iter().map(|f| slug(&f.scenario)).collect();
    for (i, (path, file)) in results.iter().zip(&files).enumerate() {
        if names[..i].contains(&names[i]) {
            return Err(InputError::file(
                path,
                format!("scenario '{}' is given twice", file.scenario),
            )
            .into());
        }
    }
    let _lock = harness::outdir::lock("--out", &out)?;
    let mut reports: Vec<(String, harness::output::ResultsFile)> = Vec::new();
    for ((path, file), name) in results.iter().zip(files).zip(names) {
        let dir = if several {
            out.join(&name)
        } else {
            out.clone()
        };
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        report::import_images(report::results_dir(path), &dir, &file.runs)?;
        if several && !same_file(report::results_dir(path), &dir) {
            harness::output::write_results(&dir, &file)?;
        }
        print_report(&report::write_report(&dir, &file)?);
        reports.push((name, file));
    }
    write_claims(&out, &reports, several, true)
}

/// `report --combine`: one report of several results files' runs.
fn combine_cmd(results: Vec<PathBuf>, out: PathBuf) -> Result<()> {
    let inputs = results
        .into_iter()
        .map(|p| report::read_results(&p).map(|f| (p, f)))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    report::combine(&inputs)?;
    let outputs = RESULT_FILES.map(|f| out.join(f));
    for (path, _) in &inputs {
        not_an_output(path, &outputs)?;
    }
    let _lock = harness::outdir::lock("--out", &out)?;
    let written = report::write_combined(&out, &inputs)?;
    outln!(
        "combined {} files into {}",
        inputs.len(),
        out.join("results.json").display()
    );
    print_report(&written);
    Ok(())
}

fn merge(results: Vec<PathBuf>, out: PathBuf) -> Result<()> {
    let inputs = results
        .into_iter()
        .map(|p| report::read_results(&p).map(|f| (p, f)))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    report::merge(&inputs)?;
    let _lock = harness::outdir::lock("--out", &out)?;
    let written = report::write_merged(&out, &inputs)?;
    outln!(
        "merged {} files into {}; report: {}",
        inputs.len(),
        out.join("results.json").display(),
        written.index.display()
    );
    Ok(())
}

fn diff(a: PathBuf, b: PathBuf, out: PathBuf) -> Result<()> {
    use shadowbench::harness::images;
    let (va, ma) = images::load_run(&a)?;
    let (vb, mb) = images::load_run(&b)?;
    if (va.width, va.height) != (vb.width, vb.height) {
        return Err(InputError::file(
            &b,
            format!(
                "image is {}×{}, but {} is {}×{}",
                vb.width,
                vb.height,
                a.display(),
                va.width,
                va.height
            ),
        )
        .into());
    }
    // Pixels that see a surface in both.
    let mask: Option<Vec<bool>> = match (ma, mb) {
        (Some(x), Some(y)) => Some(x.iter().zip(&y).map(|(p, q)| *p && *q).collect()),
        (x, y) => x.or(y),
    };
    let (img, d) = images::difference(&va, &vb, mask.as_deref());
    if out
        .extension()
        .is_none_or(|e| !e.eq_ignore_ascii_case("png"))
    {
        return Err(
            InputError::new("--out", format!("'{}' is not a .png file", out.display())).into(),
        );
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| {
            InputError::new(
                "--out",
                format!("cannot create the folder '{}': {e}", dir.display()),
            )
        })?;
    }
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| Error::Other(format!("{}: {e}", out.display())))?;
    shadowbench::visibility::write_output(&out, &png, "--out")?;
    outln!(
        "{} − {}: {} pixels compared{}; mean |A−B| {:.4}, largest {:.4}, {:.2}% differ by more \
         than 0.1; wrote {}",
        a.display(),
        b.display(),
        d.pixels,
        if mask.is_some() {
            " (those that see a surface)"
        } else {
            ""
        },
        d.mean_abs,
        d.max_abs,
        d.frac_over_0_1 * 100.0,
        out.display()
    );
    Ok(())
}

fn calibrate(out: PathBuf, quick: bool, kernels_only: bool, t: TrainingArgs) -> Result<()> {
    if out
        .extension()
        .is_none_or(|e| !e.eq_ignore_ascii_case("json"))
    {
        return Err(
            InputError::new("--out", format!("'{}' is not a .json file", out.display())).into(),
        );
    }
    // The file must be writable before a minute of measuring: a folder there, or a parent
    // that cannot hold it, is an input error now rather than a failure at the end.
    if out.is_dir() {
        return Err(InputError::new("--out", format!("'{}' is a folder", out.display())).into());
    }
    let mut training = training_sweep(&t, harness::validate::Sweep::default())?;
    if quick {
        if t.train_images.is_none() {
            training.images = vec![[160, 120]];
        }
        training.repeats = 1;
    }
    let parent = out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let probe = harness::outdir::temp_path(&out);
    std::fs::create_dir_all(parent)
        .and_then(|()| std::fs::write(&probe, b""))
        .and_then(|()| std::fs::remove_file(&probe))
        .map_err(|e| InputError::new("--out", format!("cannot write '{}': {e}", out.display())))?;
    let start = std::time::Instant::now();
    let (machine, _) = calibrated_host(quick, t.clock, (!kernels_only).then_some(&training))?;
    let text = serde_json::to_vec_pretty(&machine).expect("machine configs serialize");
    shadowbench::visibility::write_atomic(&out, &text)?;
    outln!(
        "wrote {} in {:.1} s (use it with --machine {})",
        out.display(),
        start.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}

/// A list of built-in scene names from `flag`, each known and none twice.
fn scene_list(flag: &str, scenes: Vec<String>) -> Result<Vec<String>> {
    for (i, s) in scenes.iter().enumerate() {
        if generators::find(s).is_none() {
            return Err(InputError::new(
                flag,
                shadowbench::error::unknown_name(
                    "scene",
                    s,
                    &generators::GENERATORS
                        .iter()
                        .map(|g| g.name)
                        .collect::<Vec<_>>(),
                ),
            )
            .into());
        }
        if scenes[..i].contains(s) {
            return Err(
                InputError::new(flag, format!("'{s}' is listed twice (entry {})", i + 1)).into(),
            );
        }
    }
    Ok(scenes)
}

/// Image sizes from `flag`, none twice.
fn image_list(flag: &str, images: &[String]) -> Result<Vec<[u32; 2]>> {
    let v = harness::validate::parse_images(flag, images)?;
    if let Some(i) = (0..v.len()).find(|&i| v[..i].contains(&v[i])) {
        return Err(InputError::new(
            flag,
            format!("'{}' is listed twice (entry {})", images[i], i + 1),
        )
        .into());
    }
    Ok(v)
}

/// The training sweep of `t` on `base` (algorithms, maps, options): its scenes, images,
/// repeats and clock. Errors: an unknown or repeated scene or size, repeats outside 1..=100.
fn training_sweep(
    t: &TrainingArgs,
    base: harness::validate::Sweep,
) -> Result<harness::validate::Sweep> {
    let mut sweep = harness::fit::training_sweep(&base);
    if let Some(scenes) = &t.train_scenes {
        sweep.scenes = scene_list("--train-scenes", scenes.clone())?;
    }
    if let Some(images) = &t.train_images {
        sweep.images = image_list("--train-images", images)?;
    }
    InputError::check_range("--train-repeats", t.train_repeats, 1..=100)?;
    sweep.repeats = t.train_repeats;
    sweep.clock = t.clock;
    Ok(sweep)
}

/// The `host` machine with the kernels' figures (`quick`: fewer, shorter kernel runs) measured
/// on `clock` and, given a training sweep, the issue costs fitted to it (`harness::fit`).
fn calibrated_host(
    quick: bool,
    clock: Clock,
    training: Option<&harness::validate::Sweep>,
) -> Result<(MachineConfig, Option<model::config::Training>)> {
    let base = MachineConfig::resolve("host", "host", Path::new("."))?;
    let settings = if quick {
        model::calibrate::Settings {
            scale: 0.1,
            repeats: 3,
            clock,
        }
    } else {
        model::calibrate::Settings {
            clock,
            ..Default::default()
        }
    };
    outln!(
        "calibrating {} ({}) on the {} clock",
        base.name,
        base.describe(),
        clock.name()
    );
    let start = std::time::Instant::now();
    let load = shadowbench::util::cpu_time::Load::now();
    let (kernels, _) = model::calibrate::calibrate(&base, settings, |line| outln!("{line}"));
    let cpus = base.cores * base.threads_per_core;
    if let Some(w) = shadowbench::util::cpu_time::loaded_warning(
        &load,
        &shadowbench::util::cpu_time::Load::now(),
        cpus,
        clock,
    ) {
        outln!("kernels: {w}");
    }
    let Some(training) = training else {
        return Ok((kernels, None));
    };
    outln!(
        "fitting the issue costs to a training sweep on {} at {}",
        training.scenes.join(", "),
        training
            .images
            .iter()
            .map(|[w, h]| format!("{w}x{h}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let (m, fit) = harness::fit::fit(&kernels, training, |line| outln!("{line}"))?;
    let costs: Vec<String> = harness::fit::fitted_costs(&m.costs)
        .iter()
        .map(|(field, v)| format!("{} {v:.3}", field.trim_start_matches("costs.")))
        .collect();
    outln!(
        "fitted in {:.0} s (cycles): {}; the fit predicts the training runs at MAPE {:.1}%, \
         phases {:.1}%; load average {}, threads waited for a CPU {}",
        start.elapsed().as_secs_f64(),
        costs.join(", "),
        fit.runs_mape,
        fit.phases_mape,
        fit.load_average
            .map_or("unknown".into(), |[a, b]| format!("{a:.2}-{b:.2}")),
        fit.waited_pct
            .map_or("an unknown share".into(), |w| format!(
                "{w:.1}% of their CPU time"
            )),
    );
    Ok((m, Some(fit)))
}

fn validate_model(a: ValidateArgs) -> Result<()> {
    use shadowbench::harness::validate;
    let mut sweep = validate::Sweep::default();
    if let Some(only) = a.only {
        if only.iter().any(|x| x == "reference") {
            return Err(InputError::new(
                "--only",
                "the reference has no cpu-model execution to validate",
            )
            .into());
        }
        if let Some((i, v)) = only
            .iter()
            .enumerate()
            .find(|(i, v)| only[..*i].contains(v))
        {
            return Err(InputError::new(
                "--only",
                format!("'{v}' is listed twice (entry {})", i + 1),
            )
            .into());
        }
        sweep.algorithms = only;
    }
    if let Some(images) = &a.images {
        sweep.images = image_list("--images", images)?;
    }
    InputError::check_range("--repeats", a.repeats, 1..=100)?;
    sweep.repeats = a.repeats;
    sweep.clock = a.training.clock;
    // The training sweep: every algorithm (one table for the machine, whatever --only says).
    let training = training_sweep(&a.training, validate::Sweep::default())?;
    if let Some(k) = a.folds {
        let scenes = match a.scenes {
            Some(s) => scene_list("--scenes", s)?,
            None => training
                .scenes
                .iter()
                .chain(&sweep.scenes)
                .cloned()
                .collect(),
        };
        if !(2..=scenes.len()).contains(&k) {
            return Err(InputError::new(
                "--folds",
                format!(
                    "must be in 2..={} (the scenes' count), got {k}",
                    scenes.len()
                ),
            )
            .into());
        }
        if a.kernels_only {
            return Err(InputError::new(
                "--kernels-only",
                "cross-validation fits the issue costs in every fold",
            )
            .into());
        }
        sweep.scenes = scenes;
        validate::check_held_out(&sweep, &[], &training.images, "--scenes", "--images")?;
        return cross_validate_model(a.machine.as_deref(), &a.out, sweep, &training, k);
    }
    if let Some(scenes) = a.scenes {
        sweep.scenes = scene_list("--scenes", scenes)?;
    }
    let machine = a
        .machine
        .as_deref()
        .map(|m| MachineConfig::resolve("--machine", m, Path::new(".")))
        .transpose()?;
    if a.kernels_only && machine.is_some() {
        return Err(InputError::new(
            "--kernels-only",
            "applies when validate-model calibrates; --machine gives the machine instead",
        )
        .into());
    }
    // Held out by construction: no scene or image size of the fit's training sweep.
    match &machine {
        Some(m) => {
            if let Some(t) = &m.training {
                validate::check_held_out(&sweep, &t.scenes, &t.images, "--scenes", "--images")?;
            }
        }
        None if !a.kernels_only => validate::check_held_out(
            &sweep,
            &training.scenes,
            &training.images,
            "--scenes",
            "--images",
        )?,
        None => {}
    }
    let _lock = harness::outdir::lock("--out", &a.out)?;
    let machine = match machine {
        Some(m) => m,
        None => {
            calibrated_host(
                false,
                a.training.clock,
                (!a.kernels_only).then_some(&training),
            )?
            .0
        }
    };
    // The machine the sweep runs with, given or calibrated (no earlier file left beside it).
    let path = a.out.join("machine.json");
    let text = serde_json::to_vec_pretty(&machine).expect("machine configs serialize");
    shadowbench::visibility::write_atomic(&path, &text)?;
    outln!("wrote {}", path.display());
    let v = validate::run(&sweep, &machine, |line| outln!("{line}"))?;
    let mut written = validate::write(&a.out, &v)?;
    written.extend(report::validation::chart(
        &a.out,
        "modelled_vs_measured",
        &v,
    )?);
    out!("{}", validate::summary_text(&v));
    outln!(
        "{} runs, {} phases in {:.0} s; wrote {}",
        v.runs.len(),
        v.phases.len(),
        v.seconds,
        written
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// `validate-model --folds K`: the kernels' machine (calibrated now, or `--machine`'s memory
/// figures), one sweep of every scene at the training and the held-out sizes, then K fits.
fn cross_validate_model(
    machine: Option<&str>,
    out: &Path,
    sweep: harness::validate::Sweep,
    training: &harness::validate::Sweep,
    k: usize,
) -> Result<()> {
    use shadowbench::harness::{fit, validate};
    let machine = machine
        .map(|m| MachineConfig::resolve("--machine", m, Path::new(".")))
        .transpose()?;
    let _lock = harness::outdir::lock("--out", out)?;
    let kernels = match machine {
        Some(m) => m,
        None => calibrated_host(false, sweep.clock, None)?.0,
    };
    let path = out.join("machine.json");
    let text = serde_json::to_vec_pretty(&kernels).expect("machine configs serialize");
    shadowbench::visibility::write_atomic(&path, &text)?;
    let held_out_images = sweep.images.clone();
    let measured = validate::Sweep {
        images: training
            .images
            .iter()
            .chain(&held_out_images)
            .copied()
            .collect(),
        ..sweep
    };
    let v = validate::run(&measured, &kernels, |line| outln!("{line}"))?;
    let cv = fit::cross_validate(
        &kernels,
        &v.sweep.scenes,
        (&v.runs, &v.phases),
        &training.images,
        &held_out_images,
        k,
    )?;
    let text = fit::cross_validation_text(&cv, &v);
    let json = serde_json::json!({ "cross_validation": cv, "sweep": v });
    let mut written = vec![path];
    for (name, bytes) in [
        (
            "crossval.json",
            serde_json::to_vec_pretty(&json).expect("cross-validation serializes"),
        ),
        ("crossval.txt", text.clone().into_bytes()),
    ] {
        let p = out.join(name);
        shadowbench::visibility::write_atomic(&p, &bytes)?;
        written.push(p);
    }
    out!("{text}");
    outln!(
        "wrote {}",
        written
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

fn compare_options(
    threshold: f64,
    threshold_for: &[String],
    min_effect: f64,
    fdr: f64,
    gate: &str,
) -> Result<report::compare::Options> {
    let mut o = report::compare::Options {
        threshold_pct: report::compare::check_threshold(threshold)?,
        min_effect_pct: report::compare::check_threshold(min_effect)
            .map_err(|e| InputError::new("--min-effect", e.message))?,
        gate_measured: gate == "measured",
        ..Default::default()
    };
    if !(fdr > 0.0 && fdr < 1.0) {
        return Err(
            InputError::new("--fdr", format!("expected a rate in (0, 1), got {fdr}")).into(),
        );
    }
    o.q = fdr;
    o.set_per_figure(threshold_for)?;
    Ok(o)
}

/// Prints what moved; `Ok(true)` when the gate passes.
/// `compare`: the headline (settings that differ, one line per run), then the verdict; the
/// table of every figure with `verbose` or into `details`.
fn compare(
    baseline: PathBuf,
    current: PathBuf,
    options: report::compare::Options,
    verbose: bool,
    details: Option<PathBuf>,
) -> Result<bool> {
    let old = report::read_results(&baseline)?;
    let new = report::read_results(&current)?;
    let c = report::compare::compare((&baseline, &old), (&current, &new), &options)?;
    let table = c.render();
    if let Some(path) = &details {
        not_an_output(&baseline, std::slice::from_ref(path))?;
        not_an_output(&current, std::slice::from_ref(path))?;
        shadowbench::visibility::write_atomic(path, table.as_bytes())?;
    }
    if !verbose {
        if let Some(note) = table
            .lines()
            .find(|l| l.starts_with("note: different scenarios"))
        {
            outln!("{note}");
        }
    }
    out!("{}", report::headline::headline(&old, &new));
    if verbose {
        out!("{table}");
    } else {
        // The verdict is the table's last line.
        let verdict = table.lines().last().unwrap_or_default();
        match &details {
            Some(p) => outln!("every figure: {}", p.display()),
            None => outln!("every figure: --verbose or --details FILE"),
        }
        out!("{}", c.render_measured());
        outln!("{verdict}");
    }
    Ok(!c.regressed())
}

/// `history record`: every results file into the database, one transaction each.
fn history_record(a: HistoryRecordArgs) -> Result<()> {
    use shadowbench::history::{provenance, store::Store};
    let inputs: Vec<(PathBuf, String, harness::output::ResultsFile)> = a
        .results
        .iter()
        .map(|p| {
            let text = shadowbench::util::input::read_text(p, "results")?;
            let file = report::parse_results(&text, p)?;
            Ok((p.clone(), text, file))
        })
        .collect::<std::result::Result<_, InputError>>()?;
    let commit = provenance::commit(&provenance::Given {
        commit: a.commit,
        branch: a.branch,
        date: a.date,
        subject: a.subject,
    })?;
    let host = match &a.machine {
        Some(name) if name.trim().is_empty() => {
            return Err(InputError::new("--machine", "must not be empty").into())
        }
        Some(name) => [("name".to_string(), serde_json::Value::from(name.clone()))].into(),
        None => provenance::this_host(),
    };
    let mut store = Store::open(&a.db, true)?;
    for (path, text, file) in &inputs {
        let done = store.record(&commit, &file.scenario, path, text, &file.runs, &host)?;
        if done.already {
            outln!(
                "{}: already recorded for {}; nothing changed",
                path.display(),
                &commit.sha
            );
        } else {
            outln!(
                "{}: {} runs, {} figures recorded for {} ({}) in {}",
                path.display(),
                done.runs,
                done.points,
                commit.sha,
                if commit.branch.is_empty() {
                    "no branch"
                } else {
                    &commit.branch
                },
                a.db.display()
            );
        }
    }
    Ok(())
}

/// The history in `db` and its check over `range`.
fn history_checked(
    db: &Path,
    range: &HistoryRange,
) -> Result<(
    shadowbench::history::store::History,
    shadowbench::history::check::Check,
)> {
    use shadowbench::history::{check, formats, store::Store};
    let overrides = range
        .min_effect
        .iter()
        .map(|s| check::MinEffect::parse(s))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let h = Store::open(db, false)?.load()?;
    if h.commits.is_empty() {
        return Err(InputError::file(db, "the history has no commits").into());
    }
    let head = match &range.commit {
        Some(c) => h.find_commit("--commit", c)?,
        None => h.commits.len() - 1,
    };
    let since = match &range.since {
        Some(c) => h.find_commit("--since", c)?,
        None => check::default_since(&h, head, &range.main_branch),
    };
    if since > head {
        return Err(InputError::new(
            "--since",
            format!(
                "commit {} comes after the checked commit {}",
                formats::short(&h.commits[since].sha),
                formats::short(&h.commits[head].sha)
            ),
        )
        .into());
    }
    let c = check::check(&h, since, head, &overrides);
    Ok((h, c))
}

/// `history report`: the trend page.
fn history_report(a: HistoryReportArgs) -> Result<()> {
    let (h, c) = history_checked(&a.db, &a.range)?;
    let _lock = harness::outdir::lock("--out", &a.out)?;
    let url = a.commit_url.or_else(|| {
        let server = std::env::var("GITHUB_SERVER_URL").ok()?;
        let repo = std::env::var("GITHUB_REPOSITORY").ok()?;
        Some(format!("{server}/{repo}/commit/{{sha}}"))
    });
    let path = shadowbench::history::page::write(&a.out, &h, &c, url.as_deref())?;
    outln!(
        "{}: {} commits, {} series, {} steps since {}",
        path.display(),
        h.commits.len(),
        h.series.len(),
        c.changes.len(),
        shadowbench::history::formats::short(&h.commits[c.since].sha)
    );
    Ok(())
}

/// `history check`: prints or writes the verdict; `Ok(false)` on a regression.
fn history_check(a: HistoryCheckArgs) -> Result<bool> {
    use shadowbench::history::formats;
    if a.format == "github-action-benchmark" && a.output.is_none() {
        return Err(InputError::new(
            "--output",
            "github-action-benchmark writes two files: give the folder for them",
        )
        .into());
    }
    let (h, c) = history_checked(&a.db, &a.range)?;
    let head = c.head;
    let json = |v: &serde_json::Value| {
        serde_json::to_string_pretty(v).expect("JSON values serialize") + "\n"
    };
    let out = match a.format.as_str() {
        "text" => formats::text(&h, &c),
        "markdown" => formats::markdown(&h, &c),
        "bmf" => json(&formats::bmf(&h, head, a.all_figures)),
        _ => String::new(),
    };
    if a.format != "text" {
        errln!("{}", formats::text(&h, &c).trim_end());
    }
    match (&a.output, a.format.as_str()) {
        (Some(dir), "github-action-benchmark") => {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            let (smaller, bigger) = formats::github_action_benchmark(&h, head, a.all_figures);
            for (name, v) in [
                ("customSmallerIsBetter.json", smaller),
                ("customBiggerIsBetter.json", bigger),
            ] {
                shadowbench::visibility::write_atomic(&dir.join(name), json(&v).as_bytes())?;
            }
        }
        (Some(file), _) => shadowbench::visibility::write_atomic(file, out.as_bytes())?,
        (None, _) => out!("{out}"),
    }
    Ok(!c.regressed())
}

/// Gives the process a private `XDG_RUNTIME_DIR` when it has none (or one that is not an
/// absolute path to a folder), as in containers and CI: the Vulkan loader and Mesa's
/// window-system code otherwise print "XDG_RUNTIME_DIR is invalid or not set" while the GPU is
/// probed, which reads as if it came from shadowbench. The folder is
/// `<temp>/shadowbench-runtime-<uid>`, mode 0700, owned by the user, made once and reused by
/// every later process (so an interrupted run leaves nothing new behind); nothing is written
/// into it. Where it cannot be made safely (not ours, open to others), nothing is set.
#[cfg(unix)]
fn private_runtime_dir() {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
    let valid = std::env::var_os("XDG_RUNTIME_DIR")
        .map(PathBuf::from)
        .is_some_and(|p| p.is_absolute() && p.is_dir());
    if valid {
        return;
    }
    // Our user id: the owner of this process's /proc entry (Linux).
    let Ok(uid) = std::fs::metadata("/proc/self").map(|m| m.uid()) else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("shadowbench-runtime-{uid}"));
    let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
    let safe = std::fs::symlink_metadata(&dir)
        .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o077 == 0);
    if safe {
        // Single-threaded here: no thread has been started yet.
        std::env::set_var("XDG_RUNTIME_DIR", &dir);
    }
}

#[cfg(not(unix))]
fn private_runtime_dir() {}

/// The exit of a gate that failed (`compare`, `history check`): 1 once its verdict is written,
/// or a one-line error when standard output could not take it.
fn gate_failed() -> ExitCode {
    match shadowbench::util::console::finish() {
        Err(e) => failed(Error::Other(format!(
            "cannot write to standard output: {e}"
        ))),
        Ok(()) => ExitCode::from(1),
    }
}

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, which turns output into a closed pipe (`shadowbench list | head`)
    // into a panic in `println!`; the default action ends the process quietly instead, as other
    // command-line tools do. Results files are written atomically, so nothing is left half
    // written.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_DFL at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    // Only the subcommands that probe the GPU.
    if matches!(
        cli.command,
        Command::List { .. } | Command::Render(_) | Command::Run(_)
    ) {
        private_runtime_dir();
    }
    let (uses_gpu, adapter) = match &cli.command {
        Command::List { adapter, .. } => (true, adapter.adapter.clone()),
        Command::Render(a) => (true, a.adapter.adapter.clone()),
        Command::Run(a) => (true, a.adapter.adapter.clone()),
        _ => (false, None),
    };
    if let Some(name) = &adapter {
        if let Err(e) = shadowbench::gpu::prefer_adapter(name) {
            return failed(e);
        }
    }
    // An adapter asked for by name (the option, else the environment) that is not there is bad
    // input, not a missing GPU to skip: the runs the user meant for it would otherwise not
    // happen.
    let env = std::env::var(shadowbench::gpu::ADAPTER_ENV).ok();
    let named = match (&adapter, env.filter(|s| !s.trim().is_empty())) {
        (Some(n), _) if !n.trim().is_empty() => Some("--adapter"),
        (_, Some(_)) => Some(shadowbench::gpu::ADAPTER_ENV),
        _ => None,
    };
    if let Some(field) = named.filter(|_| uses_gpu) {
        if let Err(e) = shadowbench::gpu::gpu() {
            return failed(InputError::new(field, e.to_string()).into());
        }
    }
    if let Ok(spec) = std::env::var(shadowbench::gpu::fault::FAULT_ENV) {
        if let Err(e) = shadowbench::gpu::fault::parse(&spec) {
            return failed(InputError::new(shadowbench::gpu::fault::FAULT_ENV, e).into());
        }
    }
    // Commands that draw charts check the chart font before any work (a bad SHADOWBENCH_FONT
    // would otherwise fail a sweep at its report).
    if matches!(
        cli.command,
        Command::Run(_)
            | Command::Report { .. }
            | Command::Merge { .. }
            | Command::ValidateModel(_)
    ) {
        if let Err(e) = report::font::ensure() {
            return failed(e);
        }
    }
    let result = match cli.command {
        Command::List {
            machine: Some(m), ..
        } => list_machine(&m),
        Command::List { counters: true, .. } => {
            out!("{}", shadowbench::counters::glossary());
            Ok(())
        }
        Command::List { scenarios, .. } => {
            list(&scenarios);
            Ok(())
        }
        Command::Render(a) => render(a),
        Command::Run(a) => run(a),
        Command::Report {
            results,
            out,
            combine: true,
        } => combine_cmd(results, out),
        Command::Report { results, out, .. } => report_cmd(results, out),
        Command::Merge { results, out } => merge(results, out),
        Command::Scene {
            command: SceneCommand::Export(a),
        } => scene_export(a),
        Command::Diff { a, b, out } => diff(a, b, out),
        Command::Init { mesh, out, force } => init(mesh, out, force),
        Command::Calibrate {
            out,
            quick,
            kernels_only,
            training,
        } => calibrate(out, quick, kernels_only, training),
        Command::ValidateModel(a) => validate_model(a),
        Command::Compare {
            baseline,
            current,
            threshold,
            threshold_for,
            min_effect,
            fdr,
            gate,
            verbose,
            details,
        } => {
            let options = compare_options(threshold, &threshold_for, min_effect, fdr, &gate);
            match options.and_then(|o| compare(baseline, current, o, verbose, details)) {
                Ok(false) => return gate_failed(),
                other => other.map(|_| ()),
            }
        }
        Command::History {
            command: HistoryCommand::Record(a),
        } => history_record(a),
        Command::History {
            command: HistoryCommand::Check(a),
        } => match history_check(a) {
            Ok(false) => return gate_failed(),
            other => other.map(|_| ()),
        },
        Command::History {
            command: HistoryCommand::Report(a),
        } => history_report(a),
    };
    // Output that could not be written (`> /dev/full`) fails the command after its work is
    // done and written (`util::console`); an error of its own comes first.
    let printed = shadowbench::util::console::finish();
    match (result, printed) {
        (Err(e), _) => failed(e),
        (Ok(()), Err(e)) => failed(Error::Other(format!(
            "cannot write to standard output: {e}"
        ))),
        (Ok(()), Ok(())) => ExitCode::SUCCESS,
    }
}

/// Prints `e` and gives its exit code (2 for bad input, 1 otherwise).
fn failed(e: Error) -> ExitCode {
    errln!("error: {e}");
    ExitCode::from(e.exit_code() as u8)
}
