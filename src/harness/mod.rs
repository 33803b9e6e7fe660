//! The sweep runner: scenario → cases → frames → runs → results, written as they complete.

pub mod cache;
pub mod limits;
pub mod output;
pub mod shard;

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use crate::algorithms::{self, Backend, ExecContext, FrameOutput};
use crate::error::{Error, Result};
use crate::frame::Frame;
use crate::metrics;
use crate::record::{case_id, RunRecord};
use crate::scenario::Loaded;
use crate::scene::{Light, LightKind, Scene};
use crate::visibility::{RgbBuffer, VisibilityBuffer};

pub use cache::ReferenceCache;
pub use shard::Shard;

/// Converts `light` to `kind` keeping its centre and size: a sphere of radius r ↔ a disc of
/// radius r facing `toward` ↔ a square of half-width r facing `toward`.
pub fn light_as(light: Light, kind: LightKind, toward: glam::Vec3) -> Light {
    if light.kind() == kind {
        return light;
    }
    let (c, r) = (light.center(), light.size());
    let normal = (toward - c).normalize_or(glam::Vec3::NEG_Y);
    match kind {
        LightKind::Sphere => Light::Sphere {
            center: c,
            radius: r,
        },
        LightKind::Disc => Light::Disc {
            center: c,
            normal,
            radius: r,
        },
        LightKind::Rect => {
            let (u, v) = normal.any_orthonormal_pair();
            Light::Rect {
                center: c,
                half_u: u * r,
                half_v: v * r,
            }
        }
    }
}

/// Runs one algorithm on one frame and turns its output into a record, with quality against
/// `reference` when given. Failures (errors, panics, invalid visibility) become a record with
/// `failure` set, so a sweep keeps going.
pub fn run_one(
    frame: &Frame,
    algorithm: &str,
    backend: Backend,
    ctx: &ExecContext,
    reference: Option<&VisibilityBuffer>,
) -> (RunRecord, Option<FrameOutput>) {
    let start = Instant::now();
    let result = catch_unwind(AssertUnwindSafe(|| {
        algorithms::run(algorithm, backend, frame, ctx)
    }))
    .unwrap_or_else(|panic| {
        Err(Error::Other(format!(
            "internal error (panic): {}",
            crate::error::panic_message(panic.as_ref())
        )))
    })
    .and_then(|out| {
        out.visibility
            .check_range()
            .map_err(|m| Error::Other(format!("invalid result: {m}")))?;
        Ok(out)
    });
    let mut record = RunRecord::new(algorithm, backend, &frame.scene, frame.params.clone());
    record.wall_ms = start.elapsed().as_secs_f64() * 1e3;
    match result {
        Ok(out) => {
            record.counters = out.counters.clone();
            record.phases = out.phases.clone();
            record.model_ms = out.model_ms;
            record.gpu_ms = out.gpu_ms;
            record.execution.extend(out.execution.clone());
            record.warnings = out.warnings.clone();
            check_gpu_time(&mut record);
            if let Some(r) = reference.filter(|_| algorithm != "reference") {
                let e = metrics::compare(&out.visibility, r, &frame.gbuffer.mask());
                record.warnings.extend(e.warnings());
                record.error = Some(e);
            }
            (record, Some(out))
        }
        Err(e) => {
            record.failure = Some(e.to_string());
            (record, None)
        }
    }
}

/// A run's GPU time cannot exceed its wall time: such a reading is moved to
/// `execution.gpu_ms_invalid` with a warning, so it is never charted, claimed or compared (the
/// wgpu executions already check each submission, `gpu::timing`; this is the last guard).
fn check_gpu_time(record: &mut RunRecord) {
    let Some(gpu_ms) = record.gpu_ms.filter(|g| g.is_nan() || *g > record.wall_ms) else {
        return;
    };
    let reason = format!(
        "GPU time {gpu_ms:.3} ms exceeds the run's wall time {:.3} ms",
        record.wall_ms
    );
    record.execution.insert(
        "gpu_ms_invalid".into(),
        serde_json::json!({ "reading_ms": gpu_ms, "run_wall_ms": record.wall_ms, "reason": reason }),
    );
    record.warnings.push(format!(
        "gpu_ms invalid, left out of charts, claims and comparisons: {reason}"
    ));
    record.gpu_ms = None;
    for p in &mut record.phases {
        p.gpu_ms = None;
    }
}

/// Options of `shadowbench run`.
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub out: PathBuf,
    /// Restrict to these algorithms.
    pub only: Option<Vec<String>>,
    /// Restrict to these backends.
    pub backends: Option<Vec<Backend>>,
    /// Where reference images are cached (default: `OUT/reference-cache`).
    pub cache_dir: Option<PathBuf>,
    /// Largest estimated working set of one run, in bytes.
    pub memory_limit: u64,
    /// Overrides the scenario's machine.
    pub machine: Option<crate::model::MachineConfig>,
    /// Run only this shard of the plan.
    pub shard: Option<Shard>,
}

/// One planned run.
struct Planned {
    case: usize,
    algorithm: String,
    backend: Backend,
}

/// Runs every case of the scenario; writes `results.json`, `results.csv` and images under
/// `opts.out` after each run, and returns what `results.json` holds.
pub fn run_scenario(loaded: &Loaded, opts: &RunOptions) -> Result<output::ResultsFile> {
    let s = &loaded.scenario;
    let cases = loaded.cases();
    let algorithms: Vec<String> = s
        .algorithms
        .iter()
        .filter(|a| opts.only.as_ref().is_none_or(|o| o.contains(a)))
        .cloned()
        .collect();
    let mut backends: Vec<Backend> = s
        .backends
        .iter()
        .map(|b| Backend::parse(b).expect("validated"))
        .filter(|b| opts.backends.as_ref().is_none_or(|o| o.contains(b)))
        .collect();
    if backends.contains(&Backend::Wgpu) {
        if let Err(e) = crate::gpu::gpu() {
            eprintln!("note: skipping the wgpu execution: {e}");
            backends.retain(|&b| b != Backend::Wgpu);
        }
    }
    let mut plan = Vec::new();
    let mut skipped = Vec::new();
    for (ci, _) in cases.iter().enumerate() {
        for a in &algorithms {
            let info = algorithms::find(a).expect("validated");
            for &b in &backends {
                if info.backends.contains(&b) {
                    plan.push(Planned {
                        case: ci,
                        algorithm: a.clone(),
                        backend: b,
                    });
                } else if ci == 0 {
                    skipped.push(format!("{a} on {b}"));
                }
            }
        }
    }
    if let Some(shard) = opts.shard {
        plan = plan
            .into_iter()
            .enumerate()
            .filter(|(i, _)| shard.includes(*i))
            .map(|(_, p)| p)
            .collect();
    }
    for s in &skipped {
        eprintln!("note: skipping {s} (no such execution)");
    }
    std::fs::create_dir_all(&opts.out).map_err(|e| Error::io(&opts.out, e))?;
    let cache_dir = opts
        .cache_dir
        .clone()
        .unwrap_or_else(|| opts.out.join("reference-cache"));
    if s.reference.enabled {
        cache::describe(&cache_dir)?;
    }
    let mut refs = ReferenceCache::new(Some(cache_dir), s.reference.samples, s.seed);
    let ctx = ExecContext {
        reference_samples: s.reference.samples,
        seed: s.seed,
        options: s.options.clone(),
        machine: opts
            .machine
            .clone()
            .unwrap_or_else(|| loaded.machine.clone()),
    };

    let bar = ProgressBar::new(plan.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} [{elapsed}<{eta}] {msg}")
            .expect("valid template"),
    );
    let mut writer = output::ResultsWriter::new(&opts.out, &loaded.name(), &s.claims);
    let mut current: Option<(usize, Scene)> = None;
    let mut frames: BTreeMap<LightKind, Frame> = BTreeMap::new();
    let mut done = std::collections::HashSet::new();
    for p in &plan {
        let case = &cases[p.case];
        bar.set_message(format!("{} {} case {}", p.algorithm, p.backend, p.case + 1));
        if current.as_ref().map(|c| c.0) != Some(p.case) {
            current = Some((p.case, loaded.build_scene(case.scene, case.light_size)));
            frames.clear();
        }
        let scene = &current.as_ref().expect("set above").1;
        let info = algorithms::find(&p.algorithm).expect("validated");
        let kind = info.light_for(scene.light.kind());
        let mut sc = scene.clone();
        sc.light = light_as(sc.light, kind, sc.bounds().center());
        let params = case.run_params(&sc);
        if let Err(e) = limits::check(info, &params, opts.memory_limit) {
            let mut record = RunRecord::new(&p.algorithm, p.backend, &sc, params);
            record.failure = Some(e.to_string());
            writer.push(record, None, None, None, None)?;
            bar.inc(1);
            continue;
        }
        let frame = frames.entry(kind).or_insert_with(|| Frame::new(sc, params));
        let id = case_id(
            &frame.scene.name,
            &p.algorithm,
            p.backend.name(),
            &frame.params,
        );
        if !done.insert(id) {
            // Two sweep points resolved to the same run (e.g. a swept value equal to the base).
            bar.inc(1);
            continue;
        }
        let (reference, cache_warnings) = if s.reference.enabled {
            let (r, w) = refs.get_or_compute(frame)?;
            for w in &w {
                bar.suspend(|| eprintln!("warning: {w}"));
            }
            (Some(r), w)
        } else {
            (None, vec![])
        };
        let (mut record, out) = run_one(frame, &p.algorithm, p.backend, &ctx, reference.as_ref());
        record.warnings.extend(cache_warnings);
        if kind != scene.light.kind() {
            record.warnings.push(format!(
                "light converted from {} to {} (same centre and size) for this algorithm",
                scene.light.kind(),
                kind
            ));
        }
        writer.push(
            record,
            out.as_ref().map(|o| &o.visibility),
            out.as_ref().and_then(|o| o.rgb.as_ref()),
            reference.as_ref(),
            Some(frame),
        )?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(writer.into_results())
}

/// A one-line summary table of records.
pub fn summary_table(records: &[RunRecord]) -> String {
    let mut s = format!(
        "{:<18} {:<10} {:<16} {:>7} {:>6} {:>5} {:>9} {:>10} {:>10} {:>9} {:>10}\n",
        "algorithm",
        "backend",
        "scene",
        "tris",
        "light",
        "map",
        "image",
        "wall_ms",
        "model_ms",
        "gpu_ms",
        "mae_shadow"
    );
    let opt = |v: Option<f64>| v.map(|v| format!("{v:.2}")).unwrap_or_else(|| "-".into());
    for r in records {
        let p = &r.params;
        s.push_str(&format!(
            "{:<18} {:<10} {:<16} {:>7} {:>6.3} {:>5} {:>9} {:>10.2} {:>10} {:>9} {:>10}\n",
            r.algorithm,
            r.backend,
            r.scene,
            p.triangles,
            p.light_size,
            p.map_resolution,
            format!("{}x{}", p.image[0], p.image[1]),
            r.wall_ms,
            opt(r.model_ms),
            opt(r.gpu_ms),
            match (&r.failure, &r.error) {
                (Some(_), _) => "FAILED".to_string(),
                (None, Some(e)) => e
                    .mae_shadow
                    .map_or_else(|| "-".into(), |v| format!("{v:.4}")),
                _ => "-".into(),
            }
        ));
    }
    s
}

/// Writes the files of a single rendered frame: visibility.png, visibility.npy, run.json,
/// visibility_rgb.png (the light received per channel) under a textured light and, with a
/// reference, reference.png and error.png.
pub fn write_frame_files(
    dir: &Path,
    record: &RunRecord,
    visibility: Option<&VisibilityBuffer>,
    rgb: Option<&RgbBuffer>,
    reference: Option<&VisibilityBuffer>,
    frame: &Frame,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    if let Some(c) = rgb {
        c.write_png(&dir.join("visibility_rgb.png"))?;
    }
    if let Some(v) = visibility {
        v.write_png(&dir.join("visibility.png"))?;
        v.write_npy(&dir.join("visibility.npy"))?;
        if let Some(r) = reference.filter(|_| record.algorithm != "reference") {
            r.write_png(&dir.join("reference.png"))?;
            metrics::write_error_heatmap(v, r, &frame.gbuffer.mask(), &dir.join("error.png"))?;
        }
    }
    let json = serde_json::to_vec_pretty(record).expect("records serialize");
    crate::visibility::write_atomic(&dir.join("run.json"), &json)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gpu_time_above_the_wall_time_is_recorded_invalid_not_kept() {
        let scene = crate::scene::generators::find("sphere-on-plane")
            .unwrap()
            .build(&Default::default());
        let params = crate::frame::RunParams::of_scene(&scene, [8, 6], 64, 16);
        let mut r = RunRecord::new("pcss", Backend::Wgpu, &scene, params);
        r.wall_ms = 10.0;
        r.gpu_ms = Some(4.0);
        check_gpu_time(&mut r);
        assert_eq!(r.gpu_ms, Some(4.0));
        r.gpu_ms = Some(25.0);
        r.phases.push(crate::record::Phase {
            name: "eye_lookup".into(),
            gpu_ms: Some(25.0),
            ..Default::default()
        });
        check_gpu_time(&mut r);
        assert_eq!(r.gpu_ms, None);
        assert_eq!(r.phases[0].gpu_ms, None);
        assert_eq!(r.execution["gpu_ms_invalid"]["reading_ms"], 25.0);
        assert!(
            r.warnings[0].contains("exceeds the run's wall time"),
            "{:?}",
            r.warnings
        );
    }
}
