//! The reference's shadow rays on one scene, timed on each of shadowbench's tracers and dumped
//! for an outside ray tracer (`scripts/embree-compare.py` traces them with Embree).
//!
//! ```sh
//! cargo run --release --example shadow_rays -- room --image 320x240 --samples 64 \
//!     --threads 1 --out DIR
//! ```
//!
//! Prints one JSON object: the scene, the ray count, the casters' BVH build (CPU ms, median of
//! `--repeats`), and per tracer ([`reference::Tracer`]) the CPU seconds (median) of tracing the
//! dumped rays alone (`trace_s`: the occlusion queries, rays set up from their end points) and
//! of the whole reference image (`render_s`: shading points, light samples, rays), with the
//! answers that differ from the scene BVH's (`mismatches`) and whether the image is the same to
//! the bit. CPU time is the process's (`CLOCK_PROCESS_CPUTIME_ID`), so time other processes
//! hold the CPUs is left out. With `--out`: `rays.npy` (n × 7 `float32`: origin, unit direction,
//! length, in the BVH's local coordinates), `occluded.npy` (n `uint8`: the answers),
//! `groups.npy` (n `uint32`: each ray's pixel) and `triangles.npy` (m × 9 `float32`: the
//! casting triangles, local coordinates).

use std::error::Error;
use std::ops::Range;
use std::path::{Path, PathBuf};

use clap::Parser;
use rayon::prelude::*;
use shadowbench::algorithms::reference::{self, Tracer, GROUP_CAP};
use shadowbench::frame::{Frame, RunParams};
use shadowbench::scenario;
use shadowbench::scene::generators::GeneratorParams;
use shadowbench::scene::shadow_bvh::{Gathered, Isa, PacketStack, ShadowBvh, PACKET};
use shadowbench::util::cpu_time;
use shadowbench::util::deadline::Deadline;

#[derive(Parser)]
struct Args {
    /// A built-in scene name, a mesh file or a scenario .json file.
    scene: String,
    /// Target triangle count of a generated scene.
    #[arg(long)]
    triangles: Option<u32>,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "320x240")]
    image: String,
    /// Light samples per pixel (a perfect square).
    #[arg(long, default_value_t = 64)]
    samples: u32,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Timed runs of each measurement (the median is printed).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// The most casters a group gathers in the tracing of the dumped rays (the reference
    /// image always uses `reference::GROUP_CAP`).
    #[arg(long, default_value_t = GROUP_CAP)]
    cap: usize,
    /// Folder for the .npy files (none written without it).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// CPU seconds of this process so far.
fn cpu_s() -> f64 {
    cpu_time::process_ns().expect("a process CPU clock") as f64 * 1e-9
}

/// Median of `repeats` CPU-second timings of `f`, and its last result.
fn timed<R>(repeats: usize, mut f: impl FnMut() -> R) -> (f64, R) {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let start = cpu_s();
        let r = f();
        times.push(cpu_s() - start);
        last = Some(r);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], last.expect("one run"))
}

/// The rays of each pixel: consecutive index ranges of `rays`.
fn groups(rays: &[(u32, glam::Vec3, glam::Vec3)]) -> Vec<Range<usize>> {
    let mut out: Vec<Range<usize>> = Vec::new();
    for (j, r) in rays.iter().enumerate() {
        match out.last_mut() {
            Some(g) if rays[g.start].0 == r.0 => g.end = j + 1,
            _ => out.push(j..j + 1),
        }
    }
    out
}

/// Traces `rays` (grouped by pixel) with `tracer` as the reference does; the number of answers
/// that differ from `truth`.
fn trace(
    frame: &Frame,
    tracer: Tracer,
    rays: &[(u32, glam::Vec3, glam::Vec3)],
    groups: &[Range<usize>],
    truth: &[bool],
    cap: usize,
) -> usize {
    let shadow = frame.bvh.shadow();
    let light = frame.scene.light;
    let (centre, radius) = (light.center(), light.bounding_radius());
    let one_at_a_time = |isa: Isa, cache: bool, g: &Range<usize>| {
        let mut hint = None;
        g.clone()
            .filter(|&j| {
                if !cache {
                    hint = None;
                }
                let (_, p, q) = rays[j];
                let hit = shadow
                    .ray(p, q)
                    .is_some_and(|r| shadow.occluded_ray(isa, &r, &mut hint));
                hit != truth[j]
            })
            .count()
    };
    groups
        .par_iter()
        .map_init(
            || (Vec::new(), Vec::new(), Vec::new(), PacketStack::default()),
            |(scratch, facing, packet, stack), g| match tracer {
                Tracer::SceneBvh => g
                    .clone()
                    .filter(|&j| {
                        let (_, p, q) = rays[j];
                        frame.bvh.occluded_in_scene_bvh(p, q) != truth[j]
                    })
                    .count(),
                Tracer::CastersObvhs => g
                    .clone()
                    .filter(|&j| {
                        let (_, p, q) = rays[j];
                        let hit = shadow.ray(p, q).is_some_and(|r| shadow.occluded_obvhs(&r));
                        hit != truth[j]
                    })
                    .count(),
                Tracer::Rays(isa) => one_at_a_time(isa, false, g),
                Tracer::Groups(isa) | Tracer::Packets(isa) => {
                    let from = rays[g.start].1;
                    match shadow.gather(isa, from, centre, radius, cap, scratch) {
                        Gathered::Empty => g.clone().filter(|&j| truth[j]).count(),
                        Gathered::Few => {
                            shadow.facing_among(scratch, from, facing);
                            g.clone()
                                .filter(|&j| {
                                    let (_, p, q) = rays[j];
                                    let hit = shadow
                                        .segment(p, q)
                                        .is_some_and(|s| ShadowBvh::occluded_among(facing, &s));
                                    hit != truth[j]
                                })
                                .count()
                        }
                        Gathered::Many if matches!(tracer, Tracer::Packets(_)) => {
                            let mut mismatches = 0;
                            for start in g.clone().step_by(PACKET) {
                                let chunk = start..(start + PACKET).min(g.end);
                                packet.clear();
                                // Each ray's place in the packet (none for a ray without
                                // length: nothing blocks it, as in the other tracers).
                                let mut slots = [None; PACKET];
                                for (slot, j) in slots.iter_mut().zip(chunk.clone()) {
                                    let (_, p, q) = rays[j];
                                    *slot = shadow.ray(p, q).map(|r| {
                                        packet.push(r);
                                        packet.len() - 1
                                    });
                                }
                                let blocked = shadow.occluded_packet(isa, packet, stack);
                                mismatches += chunk
                                    .zip(slots)
                                    .filter(|&(j, slot)| {
                                        slot.is_some_and(|r| blocked >> r & 1 == 1) != truth[j]
                                    })
                                    .count();
                            }
                            mismatches
                        }
                        Gathered::Many => one_at_a_time(isa, true, g),
                    }
                }
            },
        )
        .sum()
}

fn write_npy<T: npyz::Serialize + npyz::AutoSerialize + Copy>(
    path: &Path,
    shape: &[u64],
    data: &[T],
) -> Result<(), Box<dyn Error>> {
    use npyz::WriterBuilder;
    let file = std::fs::File::create(path)?;
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(std::io::BufWriter::new(file))
        .begin_nd()?;
    w.extend(data.iter().copied())?;
    w.finish()?;
    Ok(())
}

fn dump(
    dir: &Path,
    shadow: &ShadowBvh,
    rays: &[(u32, glam::Vec3, glam::Vec3)],
    truth: &[bool],
) -> Result<(), Box<dyn Error>> {
    std::fs::create_dir_all(dir)?;
    let mut flat = Vec::with_capacity(rays.len() * 7);
    for &(_, p, q) in rays {
        // A ray without length (none in practice) is written with length 0: nothing blocks it.
        let (o, d, len) = shadow
            .segment(p, q)
            .map_or((shadow.local(p), glam::Vec3::X, 0.0), |s| s.parts());
        flat.extend(o.to_array());
        flat.extend(d.to_array());
        flat.push(len);
    }
    write_npy(&dir.join("rays.npy"), &[rays.len() as u64, 7], &flat)?;
    let answers: Vec<u8> = truth.iter().map(|&t| u8::from(t)).collect();
    write_npy(&dir.join("occluded.npy"), &[rays.len() as u64], &answers)?;
    let pixels: Vec<u32> = rays.iter().map(|r| r.0).collect();
    write_npy(&dir.join("groups.npy"), &[rays.len() as u64], &pixels)?;
    let tris: Vec<f32> = shadow
        .triangles()
        .flat_map(|t| t.into_iter().flat_map(|v| v.to_array()))
        .collect();
    write_npy(&dir.join("triangles.npy"), &[shadow.len() as u64, 9], &tris)?;
    Ok(())
}

fn main() -> Result<(), Box<dyn Error>> {
    let a = Args::parse();
    let (w, h) = a
        .image
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
        .ok_or_else(|| format!("--image: '{}' is not WIDTHxHEIGHT", a.image))?;
    let generator = GeneratorParams {
        triangles: a.triangles,
        seed: a.seed,
        ..Default::default()
    };
    let (scene, _) = scenario::scene_from_arg(&a.scene, generator)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()?;
    let params = RunParams::of_scene(&scene, [w, h], 512, 32);
    let frame = pool.install(|| Frame::new(scene, params));
    let rays = reference::shadow_rays(&frame, a.samples, a.seed)
        .ok_or_else(|| format!("--samples: {} is not a perfect square", a.samples))?;
    let groups = groups(&rays);
    let truth: Vec<bool> = pool.install(|| {
        rays.par_iter()
            .map(|&(_, p, q)| frame.bvh.occluded_in_scene_bvh(p, q))
            .collect()
    });
    let (build_s, _) = timed(a.repeats, || {
        pool.install(|| ShadowBvh::of_scene(&frame.flat))
    });
    let reference_image = pool
        .install(|| {
            reference::render_with(
                &frame,
                a.samples,
                a.seed,
                Deadline::default(),
                Tracer::SceneBvh,
            )
        })
        .visibility;
    let mut tracers = vec![Tracer::SceneBvh, Tracer::CastersObvhs];
    tracers.extend(Isa::available().into_iter().map(Tracer::Rays));
    tracers.extend(Isa::available().into_iter().map(Tracer::Groups));
    tracers.extend(Isa::available().into_iter().map(Tracer::Packets));
    let mut results = Vec::new();
    for tracer in tracers {
        let (trace_s, mismatches) = timed(a.repeats, || {
            pool.install(|| trace(&frame, tracer, &rays, &groups, &truth, a.cap))
        });
        let (render_s, image) = timed(a.repeats, || {
            pool.install(|| {
                reference::render_with(&frame, a.samples, a.seed, Deadline::default(), tracer)
            })
        });
        let same_image = image.visibility == reference_image;
        results.push(serde_json::json!({
            "tracer": tracer.name(),
            "trace_s": trace_s,
            "render_s": render_s,
            "rays_per_cpu_s": rays.len() as f64 / trace_s,
            "mismatches": mismatches,
            "same_image": same_image,
        }));
    }
    if let Some(dir) = &a.out {
        dump(dir, frame.bvh.shadow(), &rays, &truth)?;
    }
    let occluded = truth.iter().filter(|&&t| t).count();
    // How the groups fall: no caster in the cone, a few (traced among them), more than the cap.
    let mut kinds = [0usize; 3];
    let mut scratch = Vec::new();
    let light = frame.scene.light;
    for g in &groups {
        let got = frame.bvh.shadow().gather(
            Isa::host(),
            rays[g.start].1,
            light.center(),
            light.bounding_radius(),
            a.cap,
            &mut scratch,
        );
        kinds[got as usize] += g.len();
    }
    println!(
        "{}",
        serde_json::json!({
            "scene": a.scene,
            "triangles": frame.flat.mesh.triangles.len(),
            "casters": frame.bvh.shadow().len(),
            "image": [w, h],
            "samples": a.samples,
            "threads": a.threads,
            "cap": a.cap,
            "rays": rays.len(),
            "occluded": occluded,
            "host_isa": Isa::host().name(),
            "build_ms": build_s * 1e3,
            "group_rays": {"empty": kinds[0], "few": kinds[1], "many": kinds[2]},
            "tracers": results,
        })
    );
    Ok(())
}
