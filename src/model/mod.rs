//! The many-core SIMD machine of paper 004 §3 (Larrabee): in-order cores with hardware threads,
//! 16-wide masked SIMD with gather/scatter, per-core L1 and L2 partitions, and the sort-middle
//! software rasterizer. Algorithms run for real on the host while the model counts what the
//! modelled machine would execute and turns the counts into modelled time.
//!
//! An algorithm is a sequence of *phases* (`light_raster`, `eye_lookup`, ...); a phase is a
//! sequence of *steps* separated by global barriers; a step is a list of independent *tasks*
//! (tiles, triangle chunks). [`Machine::run_step`] runs a step:
//!
//! - `cpu-native`: tasks in parallel on the host with [`NoProbe`], nothing counted;
//! - `cpu-model`: tasks assigned to modelled cores by a deterministic list scheduler
//!   ([`timing::schedule`]); each modelled core runs its tasks sequentially in a fixed order
//!   through its own caches, cores run in parallel on the host, and results are combined in core
//!   order. Counters and modelled times therefore do not depend on the host's thread count.

pub mod buffer;
pub mod cache;
pub mod calibrate;
pub mod config;
pub mod host;
pub mod raster;
pub mod simd;
pub mod timing;

use std::collections::BTreeMap;
use std::time::Instant;

use rayon::prelude::*;

pub use buffer::{Buffer, Memory};
pub use config::MachineConfig;

use crate::counters::names;
use crate::util::cpu_time;
use crate::util::deadline::Deadline;
pub use simd::{
    lane_groups, task_items, task_weights, BufferId, Lanes, Mask, NoProbe, Probe, LANES,
};

use crate::backend::Backend;
use crate::record::{Counters, Phase};
use cache::{CacheStats, CoreCaches, SharedCache};
use timing::{CoreWork, StepTime};

/// A step's work: task `t` of a step, generic over the probe so that the same code is the
/// native and the modelled execution.
pub trait TaskKernel: Sync {
    type Out: Send;
    fn run<P: Probe>(&self, p: &mut P, task: usize) -> Self::Out;
}

/// Accesses to one buffer.
#[derive(Clone, Copy, Debug, Default)]
struct BufferStats {
    reads: u64,
    writes: u64,
    read_bytes: u64,
    write_bytes: u64,
}

impl BufferStats {
    /// One read access of `bytes` bytes.
    fn read(&mut self, bytes: u64) {
        self.reads += 1;
        self.read_bytes += bytes;
    }

    /// One write access of `bytes` bytes.
    fn write(&mut self, bytes: u64) {
        self.writes += 1;
        self.write_bytes += bytes;
    }
}

/// The probe of one modelled core: counts its work and runs its accesses through its caches.
pub struct ModelProbe<'a> {
    caches: &'a mut CoreCaches,
    line_shift: u32,
    work: CoreWork,
    buffers: Vec<BufferStats>,
}

impl<'a> ModelProbe<'a> {
    pub fn new(config: &MachineConfig, caches: &'a mut CoreCaches) -> ModelProbe<'a> {
        ModelProbe {
            caches,
            line_shift: config.line_bytes.trailing_zeros(),
            work: CoreWork::default(),
            buffers: Vec::new(),
        }
    }

    /// What the core executed so far (cache statistics are those of the whole core).
    pub fn work(&self) -> CoreWork {
        CoreWork {
            cache: self.caches.stats,
            ..self.work.clone()
        }
    }

    fn buffer(&mut self, id: BufferId) -> &mut BufferStats {
        let i = id.0 as usize;
        if self.buffers.len() <= i {
            self.buffers.resize(i + 1, BufferStats::default());
        }
        &mut self.buffers[i]
    }

    /// Runs a contiguous access through the caches; returns the lines touched.
    fn touch(&mut self, addr: u64, bytes: u32, write: bool) -> u64 {
        let first = addr >> self.line_shift;
        let last = (addr + u64::from(bytes.max(1)) - 1) >> self.line_shift;
        for line in first..=last {
            self.caches.access(line, write);
        }
        last - first + 1
    }

    fn lanes_access(
        &mut self,
        addrs: &Lanes<u64>,
        bytes: u32,
        mask: Mask,
        write: bool,
    ) -> (u64, u64) {
        let lines = simd::distinct_lines(addrs, bytes, mask, 1 << self.line_shift);
        for &line in &lines {
            self.caches.access(line, write);
        }
        (
            lines.len() as u64,
            u64::from(mask.count()) * u64::from(bytes),
        )
    }
}

impl Probe for ModelProbe<'_> {
    const ENABLED: bool = true;

    fn vector(&mut self, n: u32, mask: Mask) {
        self.work.vector_ops += u64::from(n);
        self.work.active_lanes += u64::from(n) * u64::from(mask.count());
    }

    fn scalar(&mut self, n: u32) {
        self.work.scalar_ops += u64::from(n);
    }

    fn read(&mut self, buf: BufferId, addr: u64, bytes: u32) {
        let lines = self.touch(addr, bytes, false);
        self.work.loads += 1;
        self.work.access_lines += lines;
        self.buffer(buf).read(u64::from(bytes));
    }

    fn write(&mut self, buf: BufferId, addr: u64, bytes: u32) {
        let lines = self.touch(addr, bytes, true);
        self.work.stores += 1;
        self.work.access_lines += lines;
        self.buffer(buf).write(u64::from(bytes));
    }

    fn gather(&mut self, buf: BufferId, addrs: &Lanes<u64>, bytes: u32, mask: Mask) {
        let (lines, total) = self.lanes_access(addrs, bytes, mask, false);
        self.work.gathers += 1;
        self.work.gather_lines += lines;
        self.buffer(buf).read(total);
    }

    fn scatter(&mut self, buf: BufferId, addrs: &Lanes<u64>, bytes: u32, mask: Mask) {
        let (lines, total) = self.lanes_access(addrs, bytes, mask, true);
        self.work.scatters += 1;
        self.work.scatter_lines += lines;
        self.buffer(buf).write(total);
    }

    fn atomic(&mut self, buf: BufferId, addr: u64, bytes: u32) {
        self.touch(addr, bytes, true);
        self.work.atomics += 1;
        let b = self.buffer(buf);
        b.read(u64::from(bytes));
        b.write(u64::from(bytes));
    }
}

/// One phase while it is being recorded.
struct PhaseRecord {
    name: String,
    start: Instant,
    wall_ms: f64,
    /// The part of `wall_ms` spent inside [`Machine::run_step`] on `cpu-native`: the work the
    /// model times, without the host-side work between steps.
    steps_wall_ms: f64,
    /// On `cpu-native`, the phase on the CPU clock ([`Machine::close_phase`]): time other
    /// processes held the CPUs left out; `NaN` without the CPU clocks.
    cpu_ms: f64,
    /// Where the current stretch of the phase started on the CPU clocks.
    cpu_start: cpu_time::Span,
    /// Of the current stretch, when its steps time their tasks ([`Machine::timing_tasks`]): the
    /// steps' list-scheduled task CPU time, ms; the CPU time of the tasks that ran on the
    /// worker threads and of the calling thread inside the steps, ns.
    stretch: TaskTimes,
    model_ms: f64,
    counters: Counters,
}

/// CPU time of a phase's steps measured task by task ([`Machine::timing_tasks`]).
#[derive(Clone, Copy, Debug, Default)]
struct TaskTimes {
    timed: bool,
    scheduled_ms: f64,
    worker_tasks_ns: f64,
    caller_in_steps_ns: f64,
}

/// One frame of an algorithm on the host (`cpu-native`) or on the modelled machine
/// (`cpu-model`): the modelled memory, the cores' caches, and the phases recorded so far.
pub struct Machine {
    pub config: MachineConfig,
    pub memory: Memory,
    /// The modelled cores' caches; `None` for `cpu-native`.
    cores: Option<Vec<CoreCaches>>,
    phases: Vec<PhaseRecord>,
    /// Index of the phase being recorded.
    current: usize,
    /// Whether steps run on one core ([`Machine::set_single_core`]).
    single_core: bool,
    /// The caches of that core on `cpu-model`, created on first use.
    single_core_caches: Option<CoreCaches>,
    /// The last-level cache all cores share, on `cpu-model` machines that have one (an L3);
    /// the single core's L2 traffic goes through it too.
    shared: Option<SharedCache>,
    /// The run's budget, checked before every task of a step.
    deadline: Deadline,
    /// Whether `cpu-native` steps time each task on its thread's CPU clock
    /// ([`Machine::timing_tasks`]).
    time_tasks: bool,
}

impl Machine {
    /// A machine for `backend` (`cpu-native` or `cpu-model`).
    pub fn new(backend: Backend, config: MachineConfig) -> Machine {
        let cores = (backend == Backend::CpuModel).then(|| {
            (0..config.cores)
                .map(|_| CoreCaches::new(&config))
                .collect()
        });
        let shared = cores.is_some().then(|| SharedCache::new(&config)).flatten();
        Machine {
            config,
            memory: Memory::default(),
            cores,
            shared,
            phases: Vec::new(),
            current: 0,
            single_core: false,
            single_core_caches: None,
            deadline: Deadline::default(),
            time_tasks: false,
        }
    }

    /// The same machine stopping the run at `deadline`: every task of a step checks it first
    /// ([`Deadline::check`]), so a run past it unwinds within one task.
    pub fn with_deadline(mut self, deadline: Deadline) -> Machine {
        self.deadline = deadline;
        self
    }

    /// The same machine whose `cpu-native` steps, when `on`, time each of their tasks on the
    /// CPU clock of the thread that runs it (two `clock_gettime` calls per task, about 0.2 µs
    /// each here), so that a phase's CPU-clock time can schedule the tasks as an idle machine
    /// would ([`cpu_time::list_schedule`]). Off by default: ordinary runs pay nothing.
    pub fn timing_tasks(mut self, on: bool) -> Machine {
        self.time_tasks = on;
        self
    }

    /// Runs the steps that follow, until called with `false`, on one core instead of all of
    /// them: on `cpu-native` the tasks run one after the other on the calling host thread; on
    /// `cpu-model` every task goes to one core of the model's kind (the same costs and cache
    /// sizes) whose caches are its own, apart from the machine's cores: the work of a host
    /// processor beside the machine, which leaves the cores' caches as they were. The step's
    /// time is that core's cycles (plus the barrier); its work counters are the same sums as on
    /// all cores, its cache counters those of the one core. The one core keeps its caches
    /// from one single-core stretch to the next within the frame.
    pub fn set_single_core(&mut self, on: bool) {
        self.single_core = on;
    }

    pub fn is_model(&self) -> bool {
        self.cores.is_some()
    }

    /// Starts phase `name`, or resumes it when the frame already has a phase of that name (an
    /// algorithm that alternates phases per light sample or per silhouette loop); what follows
    /// is recorded under it. On `cpu-model` a new phase's time starts at `costs.phase` cycles.
    pub fn phase(&mut self, name: &str) {
        self.close_phase();
        match self.phases.iter().position(|p| p.name == name) {
            Some(i) => {
                self.phases[i].start = Instant::now();
                self.phases[i].cpu_start = cpu_time::Span::start();
                self.phases[i].stretch = TaskTimes::default();
                self.current = i;
            }
            None => {
                // The modelled phase starts with its once-per-phase cost (`costs.phase`).
                let start_ms = if self.is_model() {
                    self.config.costs.phase / self.config.cycles_per_ms()
                } else {
                    0.0
                };
                self.phases.push(PhaseRecord {
                    name: name.to_string(),
                    start: Instant::now(),
                    wall_ms: 0.0,
                    steps_wall_ms: 0.0,
                    cpu_ms: 0.0,
                    cpu_start: cpu_time::Span::start(),
                    stretch: TaskTimes::default(),
                    model_ms: start_ms,
                    counters: Counters::default(),
                });
                self.current = self.phases.len() - 1;
            }
        }
    }

    /// Ends the current stretch of the current phase: adds its wall time and, on `cpu-native`,
    /// its CPU-clock time. With `n` worker threads, the calling thread's CPU time `T` and the
    /// process's `P` over the stretch: `T + (P − T) / n` (the serial host code in full, the
    /// workers' time spread evenly); when the steps timed their tasks, `(T − T_steps) + S +
    /// max(P − T − W, 0) / n`, where `S` is the steps' tasks list-scheduled on the `n` workers
    /// (`cpu_time::list_schedule`: an idle machine's makespan of the measured task times,
    /// whichever threads ran them), `W` the task time of the workers and `T_steps` the
    /// calling thread's inside the steps (the single-core steps' tasks run on it).
    fn close_phase(&mut self) {
        let cpu = !self.is_model();
        let n = rayon::current_num_threads();
        if let Some(p) = self.phases.get_mut(self.current) {
            p.wall_ms += p.start.elapsed().as_secs_f64() * 1e3;
            if cpu {
                let ms = match (p.cpu_start.cpu_ns(), p.stretch) {
                    (None, _) => f64::NAN,
                    (Some((proc, own)), s) if s.timed => {
                        let others = (proc - own - s.worker_tasks_ns).max(0.0);
                        ((own - s.caller_in_steps_ns).max(0.0) + others / n as f64) * 1e-6
                            + s.scheduled_ms
                    }
                    (Some((proc, own)), _) => cpu_time::spread_ms(proc, own, n),
                };
                p.cpu_ms += ms;
                p.stretch = TaskTimes::default();
            }
        }
    }

    fn current(&mut self) -> &mut PhaseRecord {
        if self.phases.is_empty() {
            self.phase("main");
        }
        &mut self.phases[self.current]
    }

    /// Adds `v` to the algorithm counter `name` of the current phase (counted in both
    /// executions: fill, bin entries, depth tests, ...).
    pub fn count(&mut self, name: &str, v: f64) {
        self.current().counters.add(name, v);
    }

    /// The value of counter `name` in the current phase so far (0 when absent).
    pub fn counter(&self, name: &str) -> f64 {
        self.phases
            .get(self.current)
            .and_then(|p| p.counters.get(name))
            .unwrap_or(0.0)
    }

    /// A copy of `bytes` over an external link of `gb_per_s` (a device-to-host transfer) as step
    /// `name` of the current phase: counted in `transfer.bytes` on both executions, and on
    /// `cpu-model` timed as `bytes / bandwidth` (`step.<name>.model_ms`), serialised with the
    /// cores' work.
    pub fn transfer(&mut self, name: &str, bytes: u64, gb_per_s: f64) {
        let model = self.is_model();
        let phase = self.current();
        phase.counters.add(names::TRANSFER_BYTES, bytes as f64);
        if model {
            let ms = bytes as f64 / (gb_per_s * 1e9) * 1e3;
            phase.model_ms += ms;
            phase.counters.add(&format!("step.{name}.model_ms"), ms);
        }
    }

    /// Runs step `name` of the current phase: `weights.len()` tasks of `kernel`, each with its
    /// estimated cost for the scheduler. Returns the tasks' outputs in task order.
    pub fn run_step<K: TaskKernel>(
        &mut self,
        name: &str,
        kernel: &K,
        weights: &[u64],
    ) -> Vec<K::Out> {
        let deadline = self.deadline;
        if !self.is_model() {
            let start = Instant::now();
            let timed = self.time_tasks;
            let caller = timed.then(cpu_time::thread_ns).flatten();
            // Each task with its thread's CPU time (0 when not timed).
            let run = |t: usize| {
                deadline.check();
                let a = timed.then(cpu_time::thread_ns).flatten();
                let out = kernel.run(&mut NoProbe, t);
                let ns = a
                    .zip(timed.then(cpu_time::thread_ns).flatten())
                    .map_or(0, |(a, b)| b.saturating_sub(a));
                (out, ns as f64)
            };
            let (outs, ns): (Vec<K::Out>, Vec<f64>) = if self.single_core {
                (0..weights.len()).map(run).unzip()
            } else {
                (0..weights.len()).into_par_iter().map(run).unzip()
            };
            let single = self.single_core;
            let phase = self.current();
            phase.steps_wall_ms += start.elapsed().as_secs_f64() * 1e3;
            if let Some(c0) = caller {
                let s = &mut phase.stretch;
                let in_step = cpu_time::thread_ns().map_or(0, |c1| c1.saturating_sub(c0));
                let workers = if single {
                    1
                } else {
                    rayon::current_num_threads()
                };
                s.timed = true;
                s.scheduled_ms += cpu_time::list_schedule(&ns, workers) * 1e-6;
                s.caller_in_steps_ns += in_step as f64;
                if !single {
                    s.worker_tasks_ns += ns.iter().sum::<f64>();
                }
            }
            return outs;
        }
        let config = &self.config;
        let cores: &mut [CoreCaches] = match (self.cores.as_mut(), self.single_core) {
            (Some(cores), false) => cores,
            _ => std::slice::from_mut(
                self.single_core_caches
                    .get_or_insert_with(|| CoreCaches::new(config)),
            ),
        };
        let lists = timing::schedule(weights, cores.len());
        let before: Vec<CacheStats> = cores.iter().map(|c| c.stats).collect();
        type CoreResult<O> = (CoreWork, Vec<BufferStats>, Vec<(usize, O)>);
        let mut per_core: Vec<CoreResult<K::Out>> = cores
            .par_iter_mut()
            .zip(lists.into_par_iter())
            .map(|(caches, list)| {
                let mut probe = ModelProbe::new(config, caches);
                let outs: Vec<(usize, K::Out)> = list
                    .into_iter()
                    .map(|t| {
                        deadline.check();
                        probe.work.tasks += 1;
                        (t, kernel.run(&mut probe, t))
                    })
                    .collect();
                (probe.work(), probe.buffers, outs)
            })
            .collect();
        // The cores' L2 traffic through the shared level, in a fixed order; then each core's
        // cache figures are what changed during the step.
        if let Some(l3) = self.shared.as_mut() {
            l3.replay(&mut cores.iter_mut().collect::<Vec<_>>());
        }
        for ((work, _, _), (caches, before)) in per_core.iter_mut().zip(cores.iter().zip(&before)) {
            work.cache = caches.stats.since(before);
        }
        let mut outs: Vec<Option<K::Out>> = (0..weights.len()).map(|_| None).collect();
        let mut works = Vec::with_capacity(per_core.len());
        let mut buffers: Vec<BufferStats> = Vec::new();
        for (work, bufs, core_outs) in per_core {
            works.push(work);
            if buffers.len() < bufs.len() {
                buffers.resize(bufs.len(), BufferStats::default());
            }
            for (b, s) in buffers.iter_mut().zip(&bufs) {
                b.reads += s.reads;
                b.writes += s.writes;
                b.read_bytes += s.read_bytes;
                b.write_bytes += s.write_bytes;
            }
            for (t, o) in core_outs {
                outs[t] = Some(o);
            }
        }
        let time = StepTime::new(&self.config, &works);
        let counters = self.step_counters(name, &works, &buffers, &time);
        let ms = time.ms(&self.config);
        let phase = self.current();
        phase.model_ms += ms;
        for (k, v) in &counters.0 {
            // A step run several times in a phase: times add up, imbalance and boundedness
            // keep their worst run.
            if k.ends_with(".load_imbalance") || k.ends_with(".bandwidth_bound") {
                let worst = phase.counters.get(k).map_or(*v, |old| old.max(*v));
                phase.counters.set(k, worst);
            } else {
                phase.counters.add(k, *v);
            }
        }
        outs.into_iter()
            .map(|o| o.expect("every task ran once"))
            .collect()
    }

    fn step_counters(
        &self,
        name: &str,
        works: &[CoreWork],
        buffers: &[BufferStats],
        time: &StepTime,
    ) -> Counters {
        let mut total = CoreWork::default();
        for w in works {
            total.add(w);
        }
        let mut c = Counters::default();
        let line = f64::from(self.config.line_bytes);
        for (k, v) in [
            ("vector_ops", total.vector_ops),
            ("active_lanes", total.active_lanes),
            ("scalar_ops", total.scalar_ops),
            ("loads", total.loads),
            ("stores", total.stores),
            ("gathers", total.gathers),
            ("gather_lines", total.gather_lines),
            ("scatters", total.scatters),
            ("scatter_lines", total.scatter_lines),
            ("atomics", total.atomics),
            (names::CACHE_L1_HITS, total.cache.l1_hits),
            (names::CACHE_L1_MISSES, total.cache.l1_misses),
            (names::CACHE_L2_HITS, total.cache.l2_hits),
            (names::CACHE_L2_MISSES, total.cache.l2_misses),
        ] {
            c.add(k, v as f64);
        }
        if self.config.l3.is_some() {
            c.add(names::CACHE_L3_HITS, total.cache.l3_hits as f64);
            c.add(names::CACHE_L3_MISSES, total.cache.l3_misses as f64);
        }
        c.add(
            names::DRAM_READ_BYTES,
            total.cache.dram_read_lines as f64 * line,
        );
        c.add(
            names::DRAM_WRITE_BYTES,
            total.cache.dram_write_lines as f64 * line,
        );
        for (i, b) in buffers.iter().enumerate() {
            if b.reads + b.writes == 0 {
                continue;
            }
            let n = self.memory.name(BufferId(i as u16));
            c.add(&format!("mem_model.{n}.reads"), b.reads as f64);
            c.add(&format!("mem_model.{n}.writes"), b.writes as f64);
            c.add(&format!("mem_model.{n}.read_bytes"), b.read_bytes as f64);
            c.add(&format!("mem_model.{n}.write_bytes"), b.write_bytes as f64);
            c.add(names::MEM_MODEL_READ_BYTES, b.read_bytes as f64);
            c.add(names::MEM_MODEL_WRITE_BYTES, b.write_bytes as f64);
        }
        c.set(&format!("step.{name}.model_ms"), time.ms(&self.config));
        c.set(
            &format!("step.{name}.load_imbalance"),
            time.load_imbalance(),
        );
        c.set(
            &format!("step.{name}.bandwidth_bound"),
            f64::from(u8::from(
                time.bandwidth_cycles >= time.core_cycles.iter().copied().fold(0.0, f64::max),
            )),
        );
        c
    }

    /// Ends the frame: writes back dirty lines (counted as DRAM writes of the last phase, not
    /// timed: they overlap the next frame), and returns the phases, the frame's counters, the
    /// modelled time and what to record under `execution`.
    pub fn finish(mut self) -> Finished {
        self.close_phase();
        let line = f64::from(self.config.line_bytes);
        if let Some(cores) = self.cores.as_mut() {
            let mut cores: Vec<&mut CoreCaches> = cores
                .iter_mut()
                .chain(&mut self.single_core_caches)
                .collect();
            let before: u64 = cores.iter().map(|c| c.stats.dram_write_lines).sum();
            for c in cores.iter_mut() {
                c.flush();
            }
            if let Some(l3) = self.shared.as_mut() {
                l3.flush(&mut cores);
            }
            let after: u64 = cores.iter().map(|c| c.stats.dram_write_lines).sum();
            if let Some(p) = self.phases.last_mut() {
                p.counters
                    .add(names::DRAM_WRITE_BYTES, (after - before) as f64 * line);
            }
        }
        let model = self.is_model();
        let mut total = Counters::default();
        let mut phases = Vec::new();
        let mut steps_wall = Vec::new();
        let mut phase_cpu = Vec::new();
        for p in self.phases {
            steps_wall.push((p.name.clone(), serde_json::json!(p.steps_wall_ms)));
            phase_cpu.push((p.name.clone(), serde_json::json!(p.cpu_ms)));
            for (k, v) in &p.counters.0 {
                if !k.starts_with("step.") {
                    total.add(k, *v);
                }
            }
            phases.push(Phase {
                name: p.name,
                wall_ms: p.wall_ms,
                model_ms: model.then_some(p.model_ms),
                gpu_ms: None,
                counters: p.counters,
            });
        }
        let model_ms = model.then(|| phases.iter().filter_map(|p| p.model_ms).sum());
        let mut execution = BTreeMap::new();
        if !model {
            execution.insert(
                "steps_wall_ms".into(),
                serde_json::json!(steps_wall
                    .into_iter()
                    .collect::<serde_json::Map<String, serde_json::Value>>()),
            );
            execution.insert(
                "phase_cpu_ms".into(),
                serde_json::json!(phase_cpu
                    .into_iter()
                    .collect::<serde_json::Map<String, serde_json::Value>>()),
            );
        }
        if model {
            let m = &self.config;
            execution.insert("machine".into(), serde_json::json!(m.name));
            execution.insert("machine_cores".into(), serde_json::json!(m.cores));
            execution.insert("clock_ghz".into(), serde_json::json!(m.clock_ghz));
            if let Some(src) = &m.clock_source {
                execution.insert("clock_source".into(), serde_json::json!(src));
            }
            execution.insert(
                "threads_per_core".into(),
                serde_json::json!(m.threads_per_core),
            );
        }
        Finished {
            phases,
            counters: total,
            model_ms,
            execution,
        }
    }
}

/// What a finished frame recorded.
pub struct Finished {
    pub phases: Vec<Phase>,
    pub counters: Counters,
    pub model_ms: Option<f64>,
    pub execution: BTreeMap<String, serde_json::Value>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gather_lines(idx: Lanes<u32>) -> u64 {
        let config = MachineConfig::default();
        let mut caches = CoreCaches::new(&config);
        let mut memory = Memory::default();
        let buf = memory.buffer("data", vec![0f32; 4096]);
        let mut p = ModelProbe::new(&config, &mut caches);
        buf.gather(&mut p, &idx, Mask::ALL);
        assert_eq!(p.work().gathers, 1);
        p.work().gather_lines
    }

    #[test]
    fn a_gather_costs_the_distinct_cache_lines_it_touches() {
        // 16 f32 lanes in one 64-byte line, in any order.
        assert_eq!(gather_lines(std::array::from_fn(|l| (15 - l) as u32)), 1);
        // One lane per line.
        assert_eq!(gather_lines(std::array::from_fn(|l| l as u32 * 16)), 16);
        // Two lanes per line.
        assert_eq!(gather_lines(std::array::from_fn(|l| l as u32 * 8)), 8);
    }

    #[test]
    fn model_steps_return_outputs_in_task_order_and_count_every_task() {
        struct Square;
        impl TaskKernel for Square {
            type Out = usize;
            fn run<P: Probe>(&self, p: &mut P, t: usize) -> usize {
                p.vector(1, Mask::first(t % 17));
                t * t
            }
        }
        let weights: Vec<u64> = (0..50).map(|t| (t * 7 % 13) as u64).collect();
        for backend in [Backend::CpuNative, Backend::CpuModel] {
            let mut m = Machine::new(backend, MachineConfig::larrabee(4));
            m.phase("p");
            let out = m.run_step("square", &Square, &weights);
            assert_eq!(out, (0..50).map(|t| t * t).collect::<Vec<_>>());
            let f = m.finish();
            if backend == Backend::CpuModel {
                assert_eq!(f.counters.get(names::VECTOR_OPS), Some(50.0));
                let lanes: usize = (0..50).map(|t| (t % 17).min(16)).sum();
                assert_eq!(f.counters.get(names::ACTIVE_LANES), Some(lanes as f64));
                assert!(f.model_ms.unwrap() > 0.0);
            } else {
                assert!(f.model_ms.is_none());
            }
        }
    }

    /// Task timing is the machine's own setting (off by default), not the calling thread's:
    /// a `cpu-native` step measures its tasks only on a machine made with it on.
    #[test]
    fn a_native_machine_times_its_tasks_only_when_made_to() {
        struct Spin;
        impl TaskKernel for Spin {
            type Out = u64;
            fn run<P: Probe>(&self, _: &mut P, t: usize) -> u64 {
                (0..10_000u64).fold(t as u64, |a, i| a.wrapping_mul(31).wrapping_add(i))
            }
        }
        for on in [false, true] {
            let mut m = Machine::new(Backend::CpuNative, MachineConfig::larrabee(4));
            m = m.timing_tasks(on);
            m.phase("p");
            m.run_step("spin", &Spin, &[1; 8]);
            let timed = m.current().stretch.timed;
            // Where the thread CPU clock exists, the step's tasks were timed exactly when on.
            if cpu_time::thread_ns().is_some() {
                assert_eq!(timed, on);
            }
        }
    }

    #[test]
    fn single_core_steps_do_the_same_work_on_one_core() {
        struct Ops;
        impl TaskKernel for Ops {
            type Out = usize;
            fn run<P: Probe>(&self, p: &mut P, t: usize) -> usize {
                p.vector(1000, Mask::ALL);
                t
            }
        }
        let weights = vec![1u64; 8];
        let run = |single: bool| {
            let mut m = Machine::new(Backend::CpuModel, MachineConfig::larrabee(4));
            m.phase("p");
            m.set_single_core(single);
            let out = m.run_step("ops", &Ops, &weights);
            m.set_single_core(false);
            assert_eq!(out, (0..8).collect::<Vec<_>>());
            m.finish()
        };
        let (par, one) = (run(false), run(true));
        assert_eq!(par.counters.get(names::VECTOR_OPS), Some(8000.0));
        assert_eq!(one.counters.get(names::VECTOR_OPS), Some(8000.0));
        // 8 equal tasks: 2 per core on 4 cores, 8 on one.
        let config = MachineConfig::larrabee(4);
        let barrier = config.barrier_cycles / (config.clock_ghz * 1e6);
        let (p, o) = (
            par.model_ms.unwrap() - barrier,
            one.model_ms.unwrap() - barrier,
        );
        assert!((o / p - 4.0).abs() < 1e-9, "{o} vs {p}");
    }

    #[test]
    fn a_phase_costs_its_start_once_however_often_it_resumes() {
        // Two phases, the first resumed: with no steps only `costs.phase` is timed, once per
        // phase (2 · 5000 cycles at 1 GHz = 0.01 ms); 0 on the Larrabee presets.
        let run = |phase: f64| {
            let mut config = MachineConfig::larrabee(4);
            config.costs.phase = phase;
            let mut m = Machine::new(Backend::CpuModel, config);
            m.phase("a");
            m.phase("b");
            m.phase("a");
            m.finish()
        };
        let (with, without) = (run(5000.0), run(0.0));
        assert_eq!(without.model_ms, Some(0.0));
        assert!(
            (with.model_ms.unwrap() - 0.01).abs() < 1e-12,
            "{:?}",
            with.model_ms
        );
        for p in &with.phases {
            assert!((p.model_ms.unwrap() - 0.005).abs() < 1e-12, "{}", p.name);
        }
    }
}
