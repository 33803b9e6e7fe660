//! The `shadowbench` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use shadowbench::algorithms::{self, Backend, ExecContext};
use shadowbench::error::{Error, InputError, Result};
use shadowbench::frame::Frame;
use shadowbench::harness::{self, ReferenceCache, RunOptions, Shard};
use shadowbench::model::{self, MachineConfig};
use shadowbench::report;
use shadowbench::scenario::{self, validate as check, Loaded};
use shadowbench::scene::generators::{self, GeneratorParams};

#[derive(Parser)]
#[command(
    name = "shadowbench",
    version,
    about = "Benchmark real-time soft-shadow algorithms on wgpu and on a modelled many-core SIMD machine"
)]
struct Cli {
    /// GPU adapter for the wgpu execution: a substring of its name (default: the best found;
    /// also settable with SHADOWBENCH_ADAPTER).
    #[arg(long, global = true)]
    adapter: Option<String>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List algorithms, executions, scenes and scenarios.
    List {
        /// Folder of scenario files to list.
        #[arg(long, default_value = "scenarios")]
        scenarios: PathBuf,
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
        #[arg(required = true)]
        results: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Join the results of shards into DIR: results.json, results.csv, images and report.
    Merge {
        #[arg(required = true)]
        results: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Compare the deterministic figures of two results files; exit 1 on a regression.
    Compare {
        baseline: PathBuf,
        current: PathBuf,
        /// Largest worsening allowed, in percent.
        #[arg(long, default_value_t = report::compare::DEFAULT_THRESHOLD_PCT)]
        threshold: f64,
    },
}

#[derive(clap::Args)]
struct RunArgs {
    /// Scenario files. With several, each runs into OUT/<scenario name>/ and OUT/index.html
    /// links their reports and evaluates every paper claim over all of their runs.
    #[arg(required = true)]
    scenario: Vec<PathBuf>,
    #[arg(long, default_value = "out/run")]
    out: PathBuf,
    /// Only these algorithms (comma-separated).
    #[arg(long, value_delimiter = ',')]
    only: Option<Vec<String>>,
    /// Only these backends (comma-separated).
    #[arg(long, value_delimiter = ',')]
    backend: Option<Vec<String>>,
    /// Where to cache reference images (default: OUT/reference-cache).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Refuse runs whose estimated working set exceeds this many GiB
    /// (default: half of physical memory).
    #[arg(long)]
    memory_limit: Option<f64>,
    /// Modelled machine of cpu-model runs: a preset or a machine .json file (overrides the
    /// scenario's `machine`).
    #[arg(long)]
    machine: Option<String>,
    /// Run only shard K of N of the planned runs (every N-th run, from the K-th).
    #[arg(long, value_name = "K/N")]
    shard: Option<String>,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// A built-in scene name, or a path to an .obj or scenario .json file.
    #[arg(long, default_value = "sphere-on-plane")]
    scene: String,
    #[arg(long, default_value = "reference")]
    algorithm: String,
    #[arg(long, default_value = "cpu-native")]
    backend: String,
    #[arg(long)]
    light_size: Option<f32>,
    #[arg(long, default_value_t = 512)]
    map_resolution: u32,
    #[arg(long, default_value_t = 32)]
    tile_size: u32,
    /// Eye image size, WxH.
    #[arg(long, default_value = "320x240")]
    image: String,
    /// Target triangle count of a generated scene.
    #[arg(long)]
    triangles: Option<u32>,
    #[arg(long)]
    occluder_height: Option<f32>,
    /// Lateral offset of the moving occluder along x (scene units; paper 002 §5.2.5).
    #[arg(long, allow_hyphen_values = true)]
    occluder_offset: Option<f32>,
    /// Light samples per pixel of the reference (a perfect square).
    #[arg(long, default_value_t = algorithms::reference::DEFAULT_SAMPLES)]
    samples: u32,
    /// Skip the reference (no quality metrics).
    #[arg(long)]
    no_reference: bool,
    #[arg(long)]
    seed: Option<u64>,
    /// Refuse the run if its estimated working set exceeds this many GiB
    /// (default: half of physical memory).
    #[arg(long)]
    memory_limit: Option<f64>,
    #[arg(long, default_value = "out/render")]
    out: PathBuf,
    /// Modelled machine of cpu-model runs: a preset or a machine .json file.
    #[arg(long, default_value = "larrabee-24")]
    machine: String,
    /// Core count of the modelled machine (overrides the preset's).
    #[arg(long)]
    cores: Option<u32>,
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

fn list(scenarios: &std::path::Path) {
    println!("algorithms:");
    for a in algorithms::ALGORITHMS {
        let b: Vec<&str> = a.backends.iter().map(|b| b.name()).collect();
        let l: Vec<String> = a.lights.iter().map(|l| l.to_string()).collect();
        println!(
            "  {:<20} [{}] lights: {}  ({}) {}",
            a.id,
            b.join(", "),
            l.join("/"),
            a.source,
            a.summary
        );
    }
    println!("executions:");
    println!("  cpu-native   host kernels, uninstrumented");
    println!("  cpu-model    modelled many-core SIMD machine (see machines)");
    println!("  wgpu         GPU passes; adapters (* = used):");
    for line in shadowbench::gpu::adapter_report() {
        println!("               {line}");
    }
    println!("machines (--machine, scenario `machine`; or a machine .json file):");
    for name in model::config::PRESETS {
        match MachineConfig::preset(name).expect("listed presets exist") {
            Ok(m) => println!("  {:<14} {}", name, m.describe()),
            Err(why) => println!("  {name:<14} unavailable: {why}"),
        }
    }
    println!("scenes:");
    for g in generators::GENERATORS {
        println!(
            "  {:<18} ~{:>6} triangles  {}",
            g.name, g.default_triangles, g.summary
        );
    }
    println!("scenarios ({}):", scenarios.display());
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
                println!("  {:<28} {}", p.display(), desc);
            }
        }
        Err(e) => println!("  (cannot read: {e})"),
    }
}

fn render(a: RenderArgs) -> Result<()> {
    let backend = check::backend("--backend", &a.backend)?;
    check::algorithm("--algorithm", &a.algorithm)?;
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
    if let Some(v) = a.triangles {
        check::triangles("--triangles", v)?;
    }
    if let Some(v) = a.occluder_height {
        check::occluder_height("--occluder-height", v)?;
    }
    if let Some(v) = a.occluder_offset {
        check::occluder_offset("--occluder-offset", v)?;
    }
    let machine = MachineConfig::resolve("--machine", &a.machine, Path::new("."))?;
    if let Some(c) = a.cores {
        check::cores("--cores", c)?;
    }
    let seed = a.seed.unwrap_or(1);
    let mut scene = scenario::scene_from_arg(
        &a.scene,
        GeneratorParams {
            triangles: a.triangles,
            seed,
            occluder_height: a.occluder_height,
            occluder_offset: a.occluder_offset,
        },
    )?;
    if let Some(s) = a.light_size {
        scene.light = scene.light.with_size(s);
    }
    let info = algorithms::find(&a.algorithm).map_err(Error::Unsupported)?;
    let kind = info.light_for(scene.light.kind());
    scene.light = harness::light_as(scene.light, kind, scene.bounds().center());
    let params = shadowbench::frame::RunParams {
        occluder_height: a.occluder_height,
        occluder_offset: a.occluder_offset,
        cores: a.cores,
        ..shadowbench::frame::RunParams::of_scene(&scene, image, a.map_resolution, a.tile_size)
    };
    harness::limits::check(info, &params, memory_limit(a.memory_limit)?)?;
    let frame = Frame::new(scene, params);
    let ctx = ExecContext {
        reference_samples: a.samples,
        seed,
        machine,
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
    let (record, out) = harness::run_one(&frame, &a.algorithm, backend, &ctx, reference.as_ref());
    harness::write_frame_files(
        &a.out,
        &record,
        out.as_ref().map(|o| &o.visibility),
        out.as_ref().and_then(|o| o.rgb.as_ref()),
        reference.as_ref(),
        &frame,
    )?;
    print!("{}", harness::summary_table(std::slice::from_ref(&record)));
    match record.failure {
        Some(f) => Err(Error::Other(f)),
        None => {
            println!("wrote {}", a.out.display());
            Ok(())
        }
    }
}

fn run(a: RunArgs) -> Result<()> {
    let RunArgs {
        scenario,
        out,
        only,
        backend,
        cache_dir,
        memory_limit: memory_gib,
        machine,
        shard,
    } = a;
    // Every scenario is checked before anything runs.
    let loaded = scenario
        .iter()
        .map(|p| Loaded::from_file(p))
        .collect::<std::result::Result<Vec<Loaded>, InputError>>()?;
    let memory_limit = memory_limit(memory_gib)?;
    let machine = machine
        .map(|m| MachineConfig::resolve("--machine", &m, Path::new(".")))
        .transpose()?;
    let shard = shard.map(|s| Shard::parse("--shard", &s)).transpose()?;
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
        let name = l.name();
        if dirs.contains(&name) {
            return Err(InputError::file(
                path,
                format!("scenario name '{name}' is given twice; each needs its own folder"),
            )
            .into());
        }
        dirs.push(name);
    }
    let mut reports = Vec::new();
    for (l, dir) in loaded.iter().zip(&dirs) {
        let out_dir = if several { out.join(dir) } else { out.clone() };
        if several {
            println!("== {dir}");
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
            },
        )?;
        print!("{}", harness::summary_table(&results.runs));
        let written = report::write_report(&out_dir, &results)?;
        let failed = results.runs.iter().filter(|r| r.failure.is_some()).count();
        println!(
            "{} runs ({} failed); results in {}",
            results.runs.len(),
            failed,
            out_dir.join("results.json").display()
        );
        println!(
            "report: {} ({} charts)",
            written.index.display(),
            written.charts.len()
        );
        reports.push((dir.clone(), results));
    }
    let claims = report::write_claims(&out, &reports, several)?;
    print!("{claims}");
    if several {
        println!("index: {}", out.join("index.html").display());
    }
    Ok(())
}

fn report_cmd(results: Vec<PathBuf>, out: PathBuf) -> Result<()> {
    let files = results
        .iter()
        .map(|p| report::read_results(p))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let several = files.len() > 1;
    let mut reports: Vec<(String, harness::output::ResultsFile)> = Vec::new();
    for (path, file) in results.iter().zip(files) {
        if reports.iter().any(|(d, _)| *d == file.scenario) {
            return Err(InputError::file(
                path,
                format!("scenario '{}' is given twice", file.scenario),
            )
            .into());
        }
        let dir = if several {
            out.join(&file.scenario)
        } else {
            out.clone()
        };
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        report::import_images(report::results_dir(path), &dir, &file.runs)?;
        if several && !report::same_dir(report::results_dir(path), &dir) {
            harness::output::write_results(&dir, &file)?;
        }
        let written = report::write_report(&dir, &file)?;
        println!(
            "report: {} ({} charts)",
            written.index.display(),
            written.charts.len()
        );
        reports.push((file.scenario.clone(), file));
    }
    print!("{}", report::write_claims(&out, &reports, several)?);
    if several {
        println!("index: {}", out.join("index.html").display());
    }
    Ok(())
}

fn merge(results: Vec<PathBuf>, out: PathBuf) -> Result<()> {
    let inputs = results
        .into_iter()
        .map(|p| report::read_results(&p).map(|f| (p, f)))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let written = report::write_merged(&out, &inputs)?;
    println!(
        "merged {} files into {}; report: {}",
        inputs.len(),
        out.join("results.json").display(),
        written.index.display()
    );
    Ok(())
}

/// Prints what moved; `Ok(true)` when the gate passes.
fn compare(baseline: PathBuf, current: PathBuf, threshold: f64) -> Result<bool> {
    let old = report::read_results(&baseline)?;
    let new = report::read_results(&current)?;
    let c = report::compare::compare((&baseline, &old), (&current, &new), threshold)?;
    print!("{}", c.render());
    Ok(!c.regressed())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(name) = &cli.adapter {
        if let Err(e) = shadowbench::gpu::prefer_adapter(name) {
            eprintln!("error: {e}");
            return ExitCode::from(e.exit_code() as u8);
        }
    }
    if let Ok(spec) = std::env::var(shadowbench::gpu::fault::FAULT_ENV) {
        if let Err(e) = shadowbench::gpu::fault::parse(&spec) {
            let e = Error::from(InputError::new(shadowbench::gpu::fault::FAULT_ENV, e));
            eprintln!("error: {e}");
            return ExitCode::from(e.exit_code() as u8);
        }
    }
    let result = match cli.command {
        Command::List {
            scenarios,
            counters,
        } => {
            if counters {
                print!("{}", shadowbench::counters::glossary());
            } else {
                list(&scenarios);
            }
            Ok(())
        }
        Command::Render(a) => render(a),
        Command::Run(a) => run(a),
        Command::Report { results, out } => report_cmd(results, out),
        Command::Merge { results, out } => merge(results, out),
        Command::Compare {
            baseline,
            current,
            threshold,
        } => match compare(baseline, current, threshold) {
            Ok(false) => return ExitCode::from(1),
            other => other.map(|_| ()),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}
