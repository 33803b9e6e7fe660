#!/usr/bin/env python3
"""shadowbench's shadow rays side by side with Embree's one-ray path, on the reference's own rays.

    scripts/embree-compare.py [--scenes room,replicated:115000,sphere-on-plane,blob-on-plane]
                              [--image 320x240] [--samples 64] [--seed 1] [--repeats 5]
                              [--out target/embree-compare] [--venv target/embree-venv]

For each scene, `examples/shadow_rays.rs` computes the reference's shading points, light samples
and shadow rays (same seed), times shadowbench's tracers on them (one worker thread, then two)
and writes the rays and the casting triangles (the BVH's local coordinates) as .npy. This script
then builds an Embree scene of the same triangles and traces the same rays with `rtcOccluded1`,
one ray at a time (the `embreex` binding, Embree 4; one process, then two processes each
tracing half), and prints a Markdown table: occlusion rays per CPU-second on one thread and two,
Embree's ÷ shadowbench's, the share of rays on which the two answer alike, and each one's BVH
build in CPU milliseconds; then shadowbench's tracers one by one (the speed-up of each step) and
the whole reference image per ray. `uptime` is printed before and after: the machine's load
changes what a CPU-second buys, so compare ratios from one sitting.

CPU time is the process's (Python's `time.process_time`, Rust's `CLOCK_PROCESS_CPUTIME_ID`),
median of --repeats. The first run makes a virtual environment (--venv) and installs `embreex`
and `numpy` into it with pip. Not part of the tests or CI.
"""

import argparse
import json
import multiprocessing
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def ensure_venv(venv: Path) -> None:
    """Re-runs this script in `venv` (made, with embreex and numpy, if missing)."""
    try:
        import embreex  # noqa: F401
        import numpy  # noqa: F401

        return
    except ImportError:
        pass
    python = venv / "bin" / "python"
    if Path(sys.prefix).resolve() == venv.resolve():
        sys.exit(f"{venv}: embreex or numpy missing from the environment; remove it and rerun")
    if not python.exists():
        print(f"making {venv} (pip install embreex numpy)", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run(
            [str(python), "-m", "pip", "install", "--quiet", "embreex", "numpy"], check=True
        )
    os.execv(str(python), [str(python), *sys.argv])


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def shadowbench(scene: str, triangles, args, threads: int, out) -> dict:
    """The example's JSON for `scene` on `threads` worker threads (dumping into `out`)."""
    cmd = [
        str(ROOT / "target" / "release" / "examples" / "shadow_rays"),
        scene,
        "--image",
        args.image,
        "--samples",
        str(args.samples),
        "--seed",
        str(args.seed),
        "--threads",
        str(threads),
        "--repeats",
        str(args.repeats),
    ]
    if triangles:
        cmd += ["--triangles", str(triangles)]
    if out:
        cmd += ["--out", str(out)]
    run = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return json.loads(run.stdout)


def embree_scene(triangles):
    """An Embree scene of `triangles` (m × 3 × 3 float32) and the CPU seconds its build took
    (the scene commits on its first query: one ray, timed with it)."""
    import numpy as np
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    start = time.process_time()
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, triangles)
    scene.run(
        np.zeros((1, 3), np.float32),
        np.array([[0.0, 0.0, 1.0]], np.float32),
        dists=np.zeros(1, np.float32),
        query="OCCLUDED",
    )
    return scene, time.process_time() - start


def occluded(result):
    """embreex's OCCLUDED answer per ray as booleans (the geometry id hit, or -1 for none)."""
    import numpy as np

    return np.asarray(result) != -1


def embree_trace(job):
    """Worker: traces rays[lo:hi] of `folder` `repeats` times; (median CPU s, answers)."""
    import numpy as np

    folder, lo, hi, repeats = job
    rays = np.load(Path(folder) / "rays.npy")[lo:hi]
    tris = np.load(Path(folder) / "triangles.npy").reshape(-1, 3, 3).astype(np.float32)
    scene, _ = embree_scene(tris)
    origins = np.ascontiguousarray(rays[:, 0:3])
    dirs = np.ascontiguousarray(rays[:, 3:6])
    dists = np.ascontiguousarray(rays[:, 6])
    times, hit = [], None
    for _ in range(repeats):
        start = time.process_time()
        hit = scene.run(origins, dirs, dists=dists.copy(), query="OCCLUDED")
        times.append(time.process_time() - start)
    return statistics.median(times), occluded(hit)


def embree(folder: Path, repeats: int, workers: int):
    """Embree on the dumped rays with `workers` processes: (rays per CPU-second, answers)."""
    import numpy as np

    n = np.load(folder / "rays.npy", mmap_mode="r").shape[0]
    cuts = [n * w // workers for w in range(workers + 1)]
    jobs = [(str(folder), cuts[w], cuts[w + 1], repeats) for w in range(workers)]
    if workers == 1:
        parts = [embree_trace(jobs[0])]
    else:
        with multiprocessing.get_context("spawn").Pool(workers) as pool:
            parts = pool.map(embree_trace, jobs)
    cpu = sum(p[0] for p in parts)
    return n / cpu, np.concatenate([p[1] for p in parts])


def embree_build(folder: Path, repeats: int) -> float:
    import numpy as np

    tris = np.load(folder / "triangles.npy").reshape(-1, 3, 3).astype(np.float32)
    return statistics.median(embree_scene(tris)[1] for _ in range(repeats)) * 1e3


def tracer(result: dict, name: str) -> dict:
    return next(t for t in result["tracers"] if t["tracer"] == name)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenes", default="room,replicated:115000,sphere-on-plane,blob-on-plane")
    p.add_argument("--image", default="320x240")
    p.add_argument("--samples", type=int, default=64)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--out", type=Path, default=ROOT / "target" / "embree-compare")
    p.add_argument("--venv", type=Path, default=ROOT / "target" / "embree-venv")
    args = p.parse_args()
    ensure_venv(args.venv)
    import numpy as np

    subprocess.run(
        ["cargo", "build", "--release", "--quiet", "--example", "shadow_rays"],
        cwd=ROOT,
        check=True,
    )
    print(f"before: {uptime()}\n")
    rows, steps = [], []
    for spec in args.scenes.split(","):
        name, _, triangles = spec.partition(":")
        folder = args.out / name
        sb = {t: shadowbench(name, triangles, args, t, folder if t == 1 else None) for t in (1, 2)}
        truth = np.load(folder / "occluded.npy").astype(bool)
        em = {w: embree(folder, args.repeats, w) for w in (1, 2)}
        agree = float(np.mean(em[1][1] == truth))
        best = tracer(sb[1], f"packets-{sb[1]['host_isa']}")["tracer"]
        rate = {t: tracer(sb[t], best)["rays_per_cpu_s"] for t in (1, 2)}
        rows.append(
            f"| {name} ({sb[1]['casters']:,} casters of {sb[1]['triangles']:,}) "
            f"| {sb[1]['rays'] / 1e6:.2f} M "
            f"| {rate[1] / 1e6:.1f} M | {em[1][0] / 1e6:.1f} M | {em[1][0] / rate[1]:.2f} "
            f"| {rate[2] / 1e6:.1f} M | {em[2][0] / 1e6:.1f} M | {em[2][0] / rate[2]:.2f} "
            f"| {100 * agree:.3f}% | {sb[1]['build_ms']:.0f} | {embree_build(folder, args.repeats):.0f} |"
        )
        base = tracer(sb[1], "scene-bvh")
        render = tracer(sb[1], best)
        cells = []
        for t in sb[1]["tracers"]:
            ok = "" if t["mismatches"] == 0 and t["same_image"] else " (differs)"
            cells.append(f"{t['rays_per_cpu_s'] / 1e6:.1f} M{ok}")
        names = [t["tracer"] for t in sb[1]["tracers"]]
        over = [t["render_s"] / t["trace_s"] - 1 for t in sb[1]["tracers"]]
        steps.append(
            f"| {name} | "
            + " | ".join(cells)
            + f" | {base['render_s'] / render['render_s']:.2f}× "
            + f"| {100 * over[0]:.0f}% | {100 * over[names.index(best)]:.0f}% |"
        )
    print(
        "| scene | rays | shadowbench 1 thread | Embree 1 thread | Embree ÷ shadowbench "
        "| shadowbench 2 threads | Embree 2 processes | Embree ÷ shadowbench "
        "| answers alike | BVH build ms (shadowbench) | BVH build ms (Embree) |"
    )
    print("|" + "---|" * 11)
    print("\n".join(rows))
    print(
        f"\nOcclusion rays per CPU-second; shadowbench's default tracer (packets on the host's "
        f"instruction set); {args.image}, {args.samples} samples, seed {args.seed}, median of "
        f"{args.repeats}.\n"
    )
    print("shadowbench's tracers one by one (one thread, rays per CPU-second on the same rays):\n")
    print(
        "| scene | "
        + " | ".join(names)
        + " | whole image, scene-bvh ÷ default | whole image over tracing: scene-bvh | default |"
    )
    print("|" + "---|" * (len(names) + 4))
    print("\n".join(steps))
    print(f"\nafter: {uptime()}")


if __name__ == "__main__":
    main()
