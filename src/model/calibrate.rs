//! Calibration: the host's cost table measured with small kernels (`shadowbench calibrate`).
//!
//! Each figure of [`MachineConfig`] that a timing model needs and the operating system cannot
//! state is measured by a kernel written in the algorithms' own idiom (16-lane arrays, masks,
//! [`Buffer::gather`] through [`NoProbe`]), timed with the wall clock, and turned into cycles at
//! the machine's clock (`clock_ghz`, which then cancels out of `model_ms`). Every figure is the
//! fastest of several repetitions (other processes only add time) and records its method in
//! the machine's `sources`:
//!
//! | figure | kernel |
//! |---|---|
//! | `costs.vector`, `costs.lane` | a receiver-setup-like sequence of 16-lane operations (transform, reciprocal, floor, compares, select) written as the kernels' lane code (a loop over the active lanes, `glam` per lane, a branch per lane), timed with 16 and with 4 active lanes: the cost per active lane and per instruction |
//! | `costs.scalar` | four interleaved integer updates |
//! | `costs.vector_memory` | 16-lane loads and stores of whole lines of an L1-resident array |
//! | `costs.gather`, `costs.gather_line` | 16-lane gathers from an L1-resident table touching 1 and 16 lines: the cost per gather and per extra line |
//! | `costs.atomic` | atomic adds on an L1-resident array |
//! | `l1`, `l2`, `l3.latency_cycles`, `dram_latency_cycles` | pointer chasing over a random cycle of lines (page by page) in a buffer of half of each level's size (and 4× the last level's for DRAM): the load-to-use latency per level, differences between levels |
//! | `memory_parallelism` | independent loads of random lines from the same buffer as the last cache level's chase: its latency over their time per load |
//! | `dram_gb_per_s` | every core summing its share of the DRAM-sized buffer |
//! | `barrier_cycles` | an empty step of [`Machine::run_step`] on `cpu-native` (the host's fork-join) |
//!
//! What the kernels cannot see: how much host work the algorithms' own code does per counted
//! instruction (the counts are a 16-wide Larrabee's; a counted instruction of the rasterizer's
//! coverage test is 16 `f64` edge evaluations on the host, two per SSE2 instruction), work
//! outside the counted steps, branch mispredictions, page faults of new buffers, frequency
//! changes, and other guests on the same physical cores (`docs/model.md`, "Validation").

use glam::{Mat4, Vec3};
use rayon::prelude::*;
use std::hint::black_box;
use std::sync::atomic::{AtomicU32, Ordering};

use super::config::{CacheConfig, MachineConfig};
use super::{Lanes, Machine, Mask, Memory, NoProbe, Probe, TaskKernel, LANES};
use crate::backend::Backend;
use crate::util::cpu_time::{self, Clock};
use crate::util::hash::mix64;

/// How long calibration runs: `scale` multiplies every kernel's iteration count (1 for the
/// command, about 0.01 in tests), `repeats` is how many timings each figure takes the fastest
/// of, `clock` what times them (CPU time by default: a kernel's own CPU time does not grow with
/// other processes' load; the fork-join barrier is always timed on the wall clock, its cost
/// being the workers' wake-up latency rather than CPU time).
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    pub scale: f64,
    pub repeats: usize,
    pub clock: Clock,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            scale: 0.5,
            repeats: 11,
            clock: Clock::Cpu,
        }
    }
}

impl Settings {
    /// `base` iterations scaled, at least 1.
    fn n(&self, base: usize) -> usize {
        ((base as f64 * self.scale).ceil() as usize).max(1)
    }
}

/// One measured figure.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// The machine field it sets (`costs.vector`, `l2.latency_cycles`, ...).
    pub field: String,
    pub value: f64,
    pub unit: &'static str,
    /// What was measured and how.
    pub method: String,
}

/// The least over `repeats` of the seconds of `f` on `clock` divided by the units it reports
/// doing: other processes on the host only ever add time, so the fastest repetition is the
/// closest to the machine's own cost. On [`Clock::Cpu`] the seconds are
/// [`cpu_time::Times::cpu_ms`] (the calling thread's CPU time plus the host worker threads'
/// over their count; the wall clock where the OS has no CPU clocks).
fn seconds_per_unit(repeats: usize, clock: Clock, mut f: impl FnMut() -> u64) -> f64 {
    (0..repeats.max(1))
        .map(|_| {
            let start = cpu_time::Span::start();
            let units = f();
            let t = start.elapsed(rayon::current_num_threads());
            let ms = match clock {
                Clock::Cpu => t.cpu_ms.unwrap_or(t.wall_ms),
                Clock::Wall => t.wall_ms,
            };
            ms * 1e-3 / units.max(1) as f64
        })
        .fold(f64::INFINITY, f64::min)
}

/// Counted vector instructions per iteration of [`lane_kernel`], by the kernels' convention
/// (a multiply-add, a compare, a select, a floor, a reciprocal: one each): the 4-row transform
/// (4 × 3 multiply-adds), a reciprocal, the two screen coordinates (2 × (multiply-add,
/// multiply)), two texel floors (2 × (multiply, floor)), the range test (2 compares, an and),
/// the depth (multiply, select), a min, the position step (3 adds).
pub const LANE_KERNEL_OPS: u64 = 12 + 1 + 4 + 4 + 3 + 2 + 1 + 3;

/// A receiver-setup-like sequence of 16-lane operations (the shadow-map eye pass's: transform
/// to the light view, divide, texel coordinates, range test, depth) written as the kernels
/// write their lane code: a loop over the active lanes of `mask` (`Mask::lanes`), each lane's
/// work in `glam` types with a branch of its own, `iters` times. Returns the counted vector
/// instructions ([`LANE_KERNEL_OPS`] per iteration, whatever the mask: the modelled machine
/// issues them for all lanes at once).
pub fn lane_kernel(iters: usize, mask: Mask) -> u64 {
    let m = black_box(Mat4::from_cols_array(&std::array::from_fn(|i| {
        0.1 + i as f32 * 0.05
    })));
    let mut p: Lanes<Vec3> =
        std::array::from_fn(|l| Vec3::new(l as f32 * 0.1, 1.0 + l as f32 * 0.05, 2.0));
    let mut acc = [f32::MAX; LANES];
    let mask = black_box(mask);
    for _ in 0..iters {
        for l in mask.lanes() {
            let c = m * p[l].extend(1.0);
            let rw = 1.0 / c.w;
            let (u, v) = (c.x * rw * 0.5 + 0.5, c.y * rw * 0.5 + 0.5);
            let (tx, ty) = ((u * 512.0).floor(), (v * 512.0).floor());
            let d = if tx >= 0.0 && ty < 512.0 {
                c.z * rw
            } else {
                1.0
            };
            acc[l] = acc[l].min(d);
            p[l] += Vec3::splat(1e-3);
        }
    }
    black_box(acc);
    iters as u64 * LANE_KERNEL_OPS
}

/// The partly active mask of the lane costs: every fourth lane (a block a triangle edge or a
/// silhouette crosses).
const SPARSE: Mask = Mask(0x1111);

/// Counted scalar instructions per iteration of [`scalar_kernel`]: four updates of two
/// operations each, and the loop's increment and compare-branch.
pub const SCALAR_KERNEL_OPS: u64 = 4 * 2 + 2;

/// Four interleaved integer updates (xor-add, rotate-xor, shift-add, add-xor), each depending
/// on the previous ones as setup code does (so they neither vectorise nor run as four free
/// chains), `iters` times; returns the counted scalar instructions.
pub fn scalar_kernel(iters: usize) -> u64 {
    let [mut a, mut b, mut c, mut d]: [u64; 4] = black_box([1, 2, 3, 4]);
    for i in 0..iters as u64 {
        a = a.wrapping_add(b ^ i);
        b = b.rotate_left(5) ^ d;
        c = c.wrapping_add(a >> 3);
        d ^= c.wrapping_add(i);
    }
    black_box((a, b, c, d));
    iters as u64 * SCALAR_KERNEL_OPS
}

/// Lines of the L1-resident arrays of the memory kernels (16 KiB each).
const L1_LINES: usize = 256;

/// One 64-byte-aligned line of 16 f32 (the model's contiguous one-line access).
#[derive(Clone, Copy)]
#[repr(align(64))]
struct Line(Lanes<f32>);

/// Lines between the source and the destination array of [`vector_memory_kernel`], so that a
/// store and the loads that follow it never share their address bits below 4 KiB (which would
/// make the core wait for the store: 4K aliasing, a property of the layout, not of the cost).
const GAP_LINES: usize = 8;

/// 16-lane loads and stores of whole aligned lines: `passes` times over an L1-resident array,
/// each line loaded, scaled and stored to a second one; returns the lines accessed (loads +
/// stores).
pub fn vector_memory_kernel(passes: usize) -> u64 {
    let mut lines: Vec<Line> = (0..2 * L1_LINES + GAP_LINES)
        .map(|i| Line(std::array::from_fn(|l| (i * LANES + l) as f32)))
        .collect();
    let (src, dst) = lines.split_at_mut(L1_LINES + GAP_LINES);
    let src = &src[..L1_LINES];
    let k = black_box(1.0001f32);
    for _ in 0..passes {
        for (d, s) in dst.iter_mut().zip(src) {
            d.0 = std::array::from_fn(|l| s.0[l] * k);
            // One line at a time, as the kernels access them: without this the compiler may
            // vectorise across lines (transposing them with gathers), which is not a line
            // access.
            black_box(&mut *d);
        }
    }
    (passes * L1_LINES * 2) as u64
}

/// Gathers from an L1-resident table of 4096 f32 through [`Buffer::gather`], each touching
/// `lines` distinct lines (1: the 16 lanes in one line; 16: one lane per line); returns the
/// gathers done.
pub fn gather_kernel(gathers: usize, lines: usize) -> u64 {
    let mut memory = Memory::default();
    let table = memory.buffer("table", (0..4096).map(|i| i as f32).collect::<Vec<_>>());
    let per_line = LANES / lines.clamp(1, LANES);
    // 256 index vectors, cycled.
    let idx: Vec<Lanes<u32>> = (0..256u64)
        .map(|g| {
            let base = (mix64(g) % 256) as u32;
            std::array::from_fn(|l| {
                let line = (base + (l / per_line) as u32 * 17) % 256;
                line * 16 + (l % per_line) as u32
            })
        })
        .collect();
    let mut acc = [0f32; LANES];
    for g in 0..gathers {
        let v = table.gather(&mut NoProbe, &idx[g % idx.len()], Mask::ALL);
        acc = std::array::from_fn(|l| acc[l] + v[l]);
    }
    black_box(acc);
    gathers as u64
}

/// Atomic adds on an L1-resident array of 4096 counters at scattered indices; returns the
/// atomics done.
pub fn atomic_kernel(n: usize) -> u64 {
    let counters: Vec<AtomicU32> = (0..4096).map(|_| AtomicU32::new(0)).collect();
    for i in 0..n as u64 {
        counters[(mix64(i) & 4095) as usize].fetch_add(1, Ordering::Relaxed);
    }
    black_box(&counters);
    n as u64
}

/// A buffer of `bytes / 64` lines whose first word holds the index of the next line to visit,
/// in one cycle through all of them: 4 KiB pages in a random order, the 64 lines of each page
/// in a random order (fixed seeds). Each load is a new line, unpredictable to a prefetcher,
/// while the translation of a page serves 64 loads: the latency of the caches, not of page
/// walks (the algorithms' accesses are page-local too: tiles, blocks, rows).
pub struct Chase {
    words: Vec<u64>,
}

/// u64 words per 64-byte line.
const WORDS: usize = 8;
/// 64-byte lines per 4 KiB page.
const PAGE_LINES: usize = 64;

/// `0..n` in a random order (Fisher–Yates with the counter-based hash, `seed`).
fn shuffled(n: usize, seed: u64) -> Vec<usize> {
    let mut v: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = (mix64(seed ^ mix64(i as u64)) % (i as u64 + 1)) as usize;
        v.swap(i, j);
    }
    v
}

impl Chase {
    pub fn new(bytes: usize) -> Chase {
        let pages = (bytes / (64 * PAGE_LINES)).max(1);
        let lines = pages * PAGE_LINES;
        let within = |p: usize| shuffled(PAGE_LINES, 0x5eed ^ p as u64);
        let order: Vec<usize> = shuffled(pages, 1)
            .into_iter()
            .flat_map(|p| within(p).into_iter().map(move |l| p * PAGE_LINES + l))
            .collect();
        let mut words = vec![0u64; lines * WORDS];
        for i in 0..lines {
            words[order[i] * WORDS] = (order[(i + 1) % lines] * WORDS) as u64;
        }
        Chase { words }
    }

    pub fn lines(&self) -> usize {
        self.words.len() / WORDS
    }

    /// `steps` dependent loads, each to the line the previous one named; returns the steps.
    pub fn chase(&self, steps: usize) -> u64 {
        let mut i = 0usize;
        for _ in 0..steps {
            i = self.words[i] as usize;
        }
        black_box(i);
        steps as u64
    }

    /// `n` independent loads of random lines (the addresses do not depend on loaded data, so
    /// an out-of-order core overlaps them); returns the loads.
    pub fn independent(&self, n: usize) -> u64 {
        let lines = self.lines() as u64;
        let mut sum = 0u64;
        for i in 0..n as u64 {
            sum = sum.wrapping_add(self.words[(mix64(i) % lines) as usize * WORDS]);
        }
        black_box(sum);
        n as u64
    }

    /// Every core sums a contiguous share of the buffer, `passes` times; returns the bytes read.
    pub fn stream(&self, passes: usize) -> u64 {
        for _ in 0..passes {
            let s: u64 = self
                .words
                .par_chunks(1 << 16)
                .map(|c| c.iter().fold(0u64, |a, &w| a.wrapping_add(w)))
                .sum();
            black_box(s);
        }
        (passes * self.words.len() * 8) as u64
    }
}

/// Nanoseconds per dependent load chasing through `bytes`, the fastest of `repeats` (after a
/// warm-up of `steps` loads or one lap, whichever is shorter).
pub fn chase_ns(bytes: usize, steps: usize, repeats: usize) -> f64 {
    let c = Chase::new(bytes);
    c.chase(c.lines().min(steps));
    seconds_per_unit(repeats, Clock::Cpu, || c.chase(steps)) * 1e9
}

/// A task that does nothing: the step's cost is the executor's fork and join.
struct Empty;

impl TaskKernel for Empty {
    type Out = ();
    fn run<P: Probe>(&self, _: &mut P, _: usize) {}
}

/// Measures the host's costs; `base` (the `host` preset) gives the clock, the cores and the
/// cache sizes the kernels are sized by. Returns the calibrated machine (named
/// `host-calibrated`, every measured figure's method in `sources`) and the figures in the order
/// they were measured; `progress` gets one line per figure.
pub fn calibrate(
    base: &MachineConfig,
    s: Settings,
    mut progress: impl FnMut(&str),
) -> (MachineConfig, Vec<Figure>) {
    let mut rec = Recorder {
        ghz: base.clock_ghz,
        s,
        figures: Vec::new(),
        progress: &mut progress,
    };
    let mut m = base.clone();
    m.name = "host-calibrated".into();
    issue_costs(&mut m, &mut rec);
    memory_costs(&mut m, &mut rec);
    barrier(&mut m, &mut rec);
    for f in &rec.figures {
        m.sources.insert(
            f.field.clone(),
            format!("measured by shadowbench calibrate: {}", f.method),
        );
    }
    (m, rec.figures)
}

/// The calibration's settings and clock, and the figures measured so far.
struct Recorder<'a> {
    ghz: f64,
    s: Settings,
    figures: Vec<Figure>,
    progress: &'a mut dyn FnMut(&str),
}

impl Recorder<'_> {
    /// Cycles at the machine's clock of `seconds`.
    fn cycles(&self, seconds: f64) -> f64 {
        seconds * self.ghz * 1e9
    }

    /// Cycles per unit of `f`, the fastest of the repetitions.
    fn cycles_per_unit(&self, f: impl FnMut() -> u64) -> f64 {
        self.cycles(seconds_per_unit(self.s.repeats, self.s.clock, f))
    }

    /// Measures `f`'s cycles per unit and records them as `field`, `method` followed by how
    /// many repetitions it is the fastest of; returns the figure.
    fn measure(
        &mut self,
        field: &str,
        unit: &'static str,
        method: &str,
        f: impl FnMut() -> u64,
    ) -> f64 {
        let v = self.cycles_per_unit(f);
        let method = format!(
            "{method}, fastest of {} on the {} clock",
            self.s.repeats,
            self.s.clock.name()
        );
        self.record(field, v, unit, method)
    }

    /// Records a figure (and reports it); returns its value.
    fn record(&mut self, field: &str, value: f64, unit: &'static str, method: String) -> f64 {
        (self.progress)(&format!("  {field:<22} {value:>10.3} {unit:<18} {method}"));
        self.figures.push(Figure {
            field: field.into(),
            value,
            unit,
            method,
        });
        value
    }
}

/// A cost measured by one kernel: the figure it sets, its field, unit and method, the kernel
/// (iterations to units done) and its base iteration count.
type CostKernel<'a> = (
    &'a mut f64,
    &'static str,
    &'static str,
    &'static str,
    fn(usize) -> u64,
    usize,
);

/// The issue costs: vector (per instruction and per active lane), scalar, contiguous lines,
/// gathers, atomics.
fn issue_costs(m: &mut MachineConfig, rec: &mut Recorder) {
    let s = rec.s;
    let r = format!("{} on the {} clock", s.repeats, s.clock.name());
    // A counted vector instruction with n active lanes costs c_vector + n·c_lane: the lane
    // kernel with all 16 lanes and with 4.
    let full = rec.cycles_per_unit(|| lane_kernel(s.n(200_000), Mask::ALL));
    let sparse = rec.cycles_per_unit(|| lane_kernel(s.n(400_000), SPARSE));
    let (n_full, n_sparse) = (f64::from(Mask::ALL.count()), f64::from(SPARSE.count()));
    let lane = ((full - sparse) / (n_full - n_sparse)).max(0.0);
    m.costs.lane = rec.record(
        "costs.lane",
        lane,
        "cycles/active lane",
        format!(
            "receiver-setup-like lane loop ({LANE_KERNEL_OPS} counted vector instructions per \
             iteration, glam per lane, a branch per lane): {full:.2} cycles per instruction with \
             16 active lanes, {sparse:.2} with 4; the difference per lane, fastest of {r}"
        ),
    );
    m.costs.vector = rec.record(
        "costs.vector",
        (full - n_full * lane).max(0.0),
        "cycles/instruction",
        format!("the 16-lane instruction's cycles less 16 lanes' (at least 0), fastest of {r}"),
    );
    let k = &mut m.costs;
    let simple: [CostKernel; 3] = [
        (
            &mut k.scalar,
            "costs.scalar",
            "cycles/instruction",
            "4 interleaved integer updates (add, xor, rotate, shift)",
            scalar_kernel,
            4_000_000,
        ),
        (
            &mut k.vector_memory,
            "costs.vector_memory",
            "cycles/line",
            "16-lane load, multiply and store of whole aligned lines of a 16 KiB array, per line \
             accessed",
            vector_memory_kernel,
            20_000,
        ),
        (
            &mut k.atomic,
            "costs.atomic",
            "cycles/atomic",
            "relaxed atomic adds on a 16 KiB array at hashed indices",
            atomic_kernel,
            4_000_000,
        ),
    ];
    for (cost, field, unit, method, kernel, base) in simple {
        *cost = rec.measure(field, unit, method, || kernel(s.n(base)));
    }
    let g1 = rec.cycles_per_unit(|| gather_kernel(s.n(2_000_000), 1));
    let g16 = rec.cycles_per_unit(|| gather_kernel(s.n(2_000_000), 16));
    let per_line = ((g16 - g1) / 15.0).max(0.0);
    m.costs.gather_line = rec.record(
        "costs.gather_line",
        per_line,
        "cycles/line",
        format!(
            "16-lane gathers from a 16 KiB table touching 16 lines ({g16:.2} cycles) and 1 line \
             ({g1:.2}): the difference over 15 lines (at least 0), fastest of {r}"
        ),
    );
    m.costs.gather = rec.record(
        "costs.gather",
        (g1 - per_line).max(0.0),
        "cycles/instruction",
        format!("the 1-line gather's cycles less one line's, fastest of {r}"),
    );
}

/// Load-to-use latency at each cache level and DRAM, memory-level parallelism and DRAM
/// bandwidth. Each level's chase runs through half of its size (the L2's half is well above
/// the L1; the L3's above the L2 on current CPUs), DRAM's through 4× the last level.
fn memory_costs(m: &mut MachineConfig, rec: &mut Recorder) {
    let s = rec.s;
    let r = format!("{} on the {} clock", s.repeats, s.clock.name());
    // The chase of each level with its warm-up: cycles per dependent load.
    let chase_cycles = |rec: &Recorder, chase: &Chase, steps: usize| {
        chase.chase(chase.lines().min(s.n(4_000_000)));
        rec.cycles_per_unit(|| chase.chase(s.n(steps)))
    };
    let mut below = 0.0;
    let mut levels: Vec<(&str, &mut CacheConfig, usize)> =
        vec![("l1", &mut m.l1, 4_000_000), ("l2", &mut m.l2, 2_000_000)];
    if let Some(l3) = m.l3.as_mut() {
        levels.push(("l3", l3, 1_000_000));
    }
    let mut last: Option<(Chase, f64, &str)> = None;
    for (name, level, steps) in levels {
        let bytes = level.size_bytes as usize / 2;
        let chase = Chase::new(bytes);
        let lat = chase_cycles(rec, &chase, steps);
        let less = if below > 0.0 {
            format!(": {lat:.1} cycles, less the level below's")
        } else {
            String::new()
        };
        level.latency_cycles = rec.record(
            &format!("{name}.latency_cycles"),
            (lat - below).max(0.0),
            "cycles",
            format!(
                "pointer chase over {} KiB (half the {}){less}, fastest of {r}",
                bytes / 1024,
                name.to_uppercase()
            ),
        );
        below = lat;
        last = Some((chase, lat, name));
    }
    let last_size =
        m.l3.as_ref()
            .map_or(m.l2.size_bytes as usize * m.cores as usize, |c| {
                c.size_bytes as usize
            });
    let dram_bytes = (4 * last_size).max(64 << 20);
    let dram = Chase::new(dram_bytes);
    let lat_dram = chase_cycles(rec, &dram, 500_000);
    m.dram_latency_cycles = rec.record(
        "dram_latency_cycles",
        (lat_dram - below).max(0.0),
        "cycles",
        format!(
            "pointer chase over {} MiB (4× the last cache level): {lat_dram:.1} cycles, less \
             the last level's (at least 0), fastest of {r}",
            dram_bytes >> 20
        ),
    );
    // Memory-level parallelism in the L3 (or DRAM without one; never the L1 or L2).
    let (buffer, lat, level) = match &last {
        Some((c, lat, "l3")) => (c, *lat, "L3"),
        _ => (&dram, lat_dram, "DRAM"),
    };
    let independent = rec.cycles_per_unit(|| buffer.independent(s.n(1_000_000)));
    m.memory_parallelism = Some(rec.record(
        "memory_parallelism",
        (lat / independent).clamp(1.0, 64.0),
        "loads in flight",
        format!(
            "the {level} chase's {lat:.1} cycles per load over {independent:.1} cycles per \
             independent load of a random line of the same buffer (clamped to 1..=64)"
        ),
    ));
    drop(last);
    let bytes_per_s = 1.0 / seconds_per_unit(s.repeats, s.clock, || dram.stream(s.n(8)));
    m.dram_gb_per_s = rec.record(
        "dram_gb_per_s",
        bytes_per_s / 1e9,
        "GB/s",
        format!(
            "all host threads summing {} MiB, fastest of {r}",
            dram_bytes >> 20
        ),
    );
}

/// The cost of a barrier: an empty step of one task per core on `cpu-native`.
fn barrier(m: &mut MachineConfig, rec: &mut Recorder) {
    let s = rec.s;
    let mut machine = Machine::new(Backend::CpuNative, m.clone());
    machine.phase("barrier");
    let weights = vec![1u64; m.cores as usize];
    let method = format!(
        "an empty cpu-native step of {} tasks (fork and join)",
        m.cores
    );
    let barrier = seconds_per_unit(s.repeats, Clock::Wall, || {
        let n = s.n(20_000);
        for _ in 0..n {
            machine.run_step("empty", &Empty, &weights);
        }
        n as u64
    });
    let cycles = rec.cycles(barrier);
    m.barrier_cycles = rec.record(
        "barrier_cycles",
        cycles,
        "cycles",
        format!(
            "{method}, fastest of {} on the wall clock (the workers' wake-up latency is not CPU \
             time)",
            s.repeats
        ),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chase_visits_every_line_once_per_lap() {
        let c = Chase::new(64 * PAGE_LINES * 5);
        let mut seen = vec![false; c.lines()];
        let mut i = 0usize;
        for _ in 0..c.lines() {
            let line = i / WORDS;
            assert!(!seen[line], "line {line} visited twice");
            seen[line] = true;
            i = c.words[i] as usize;
        }
        assert!(seen.iter().all(|&s| s));
        assert_eq!(i, 0, "one lap returns to the start");
    }

    #[test]
    fn the_chase_latency_rises_past_the_caches() {
        // 16 KiB fits every L1 of the last twenty years; 256 MiB fits no cache: each load of
        // the large chase goes to DRAM (≥ 40 ns on any current machine), the small one's
        // to L1 (≤ 5 ns).
        let small = chase_ns(16 << 10, 200_000, 3);
        let large = chase_ns(256 << 20, 100_000, 3);
        assert!(large > 4.0 * small, "{small} ns vs {large} ns");
    }

    #[test]
    fn calibration_writes_a_valid_machine_with_a_method_per_figure() {
        let base = crate::model::host::machine(2.0);
        let mut lines = Vec::new();
        let (m, figures) = calibrate(
            &base,
            Settings {
                scale: 0.002,
                repeats: 1,
                clock: Clock::Cpu,
            },
            |l| lines.push(l.to_string()),
        );
        m.validate().unwrap();
        assert_eq!(lines.len(), figures.len());
        for f in &figures {
            assert!(f.value.is_finite() && f.value >= 0.0, "{f:?}");
            assert!(m.sources[&f.field].starts_with("measured"), "{f:?}");
        }
        // The same sizes as the host: only costs and latencies change.
        assert_eq!(
            (m.l1.size_bytes, m.l2.size_bytes),
            (base.l1.size_bytes, base.l2.size_bytes)
        );
        // Written and read back, it is the same machine (serde_json's default float parsing may
        // differ from the written figure in the last bit: compare the JSON it writes again).
        let json = serde_json::to_value(&m).unwrap();
        let back = crate::model::MachineConfig::from_json(
            &json.to_string(),
            std::path::Path::new("m.json"),
        )
        .unwrap();
        assert_eq!(back.name, m.name);
        assert_eq!(back.sources, m.sources);
        assert_json_close(&serde_json::to_value(&back).unwrap(), &json, "$");
    }

    /// `a` and `b` hold the same keys, strings and booleans, and numbers equal to 1e-12.
    fn assert_json_close(a: &serde_json::Value, b: &serde_json::Value, at: &str) {
        use serde_json::Value;
        match (a, b) {
            (Value::Object(x), Value::Object(y)) => {
                assert_eq!(x.len(), y.len(), "{at}");
                for (k, v) in y {
                    assert_json_close(&x[k], v, &format!("{at}.{k}"));
                }
            }
            (Value::Number(x), Value::Number(y)) => {
                let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
                assert!(
                    (x - y).abs() <= 1e-12 * x.abs().max(1.0),
                    "{at}: {x} vs {y}"
                );
            }
            _ => assert_eq!(a, b, "{at}"),
        }
    }
}
