//! Machine configurations: the presets of the Larrabee-style machine of paper 004 §3.1 and §4.1,
//! the host, and configurations loaded from JSON.
//!
//! Every number the timing model uses lives here, with where it comes from. Published figures
//! (Seiler et al. 2008, "Larrabee: a many-core x86 architecture for visual computing", cited by
//! 004 §3) are used where they exist; the rest are stated assumptions typical of an in-order
//! x86 core of that generation, so that a user can change them in a JSON file and see the effect.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{unknown_name, InputError};

/// One cache level.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CacheConfig {
    /// Capacity in bytes: per core for L1 and L2 (for Larrabee's L2, the core's partition of the
    /// shared L2); the whole chip's for the shared L3.
    pub size_bytes: u32,
    pub ways: u32,
    /// Cycles from a miss in the level above to data from this level (the latency this level
    /// adds, not the load-to-use latency from the core).
    pub latency_cycles: f64,
}

/// The vector unit the kernels' 16 lanes run on, on a real machine (informational: its costs
/// are in [`OpCosts`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimdConfig {
    /// The widest f32 instruction set found (`avx512f`, `avx2`, `avx`, `sse2`, `neon`, `none`).
    pub isa: String,
    /// f32 lanes of one register of that set.
    pub f32_lanes: u32,
}

/// Cycle costs of the operations the kernels count.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpCosts {
    /// Issue cycles of one 16-wide vector instruction (the VPU issues one per cycle).
    pub vector: f64,
    /// Issue cycles of one scalar instruction (the in-order x86 pipe, one per cycle; the dual
    /// issue of the Pentium pipe is not modelled).
    pub scalar: f64,
    /// Issue cycles of a contiguous vector load or store of up to one cache line.
    pub vector_memory: f64,
    /// Issue cycles per distinct cache line of a gather or scatter: Larrabee's gather/scatter
    /// unit accesses one line per cycle (Seiler et al. 2008 §4.1), so a gather whose 16 lanes
    /// fall into one line costs one cycle and into 16 lines sixteen.
    pub gather_line: f64,
    /// Issue cycles of a gather or scatter instruction besides its lines: a CPU without a
    /// line-wise gather unit loads each lane on its own, whatever lines they share (0, absent
    /// from the JSON, on Larrabee).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub gather: f64,
    /// Issue cycles per active lane of a vector instruction, besides `vector`: a CPU that runs
    /// the kernels' 16-lane code one lane at a time (a loop over the active lanes, as the Rust
    /// kernels are written) pays for every active lane (0, absent from the JSON, on Larrabee,
    /// whose vector unit does all 16 lanes in one issue).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lane: f64,
    /// Cycles of an atomic read-modify-write in L2 (an assumption: an L2 round trip).
    pub atomic: f64,
    /// Cycles a phase costs once, besides its steps' work and barriers: what the host spends
    /// around a phase's steps (its buffers' allocation and first touches, waking the workers).
    /// 0, absent from the JSON, on Larrabee (not a figure of the papers).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub phase: f64,
}

impl OpCosts {
    /// Larrabee's issue costs (`MachineConfig::larrabee` states the sources): one cycle per
    /// vector instruction, scalar instruction, line access and gathered line; 20 per atomic.
    pub const LARRABEE: OpCosts = OpCosts {
        vector: 1.0,
        scalar: 1.0,
        vector_memory: 1.0,
        gather_line: 1.0,
        gather: 0.0,
        lane: 0.0,
        atomic: 20.0,
        phase: 0.0,
    };
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// A modelled many-core SIMD machine (004 §3.1, Figure 5).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineConfig {
    pub name: String,
    pub cores: u32,
    pub clock_ghz: f64,
    /// Hardware threads per core; they hide each other's memory stalls.
    pub threads_per_core: u32,
    /// SIMD lanes (16 for Larrabee's 512-bit VPU).
    pub lanes: u32,
    pub line_bytes: u32,
    pub l1: CacheConfig,
    pub l2: CacheConfig,
    /// Cycles to DRAM after an L2 miss.
    pub dram_latency_cycles: f64,
    /// Sustained DRAM bandwidth of the whole chip, GB/s.
    pub dram_gb_per_s: f64,
    /// Cycles of a global barrier between phases (the sort-middle pipeline's synchronisation).
    pub barrier_cycles: f64,
    pub costs: OpCosts,
    /// Where `clock_ghz` comes from, when it is not a stated figure (the `host` preset: the
    /// operating system's CPU frequency source, see [`host_clock`]); recorded in each run's
    /// `execution`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock_source: Option<String>,
    /// A last-level cache shared by all cores (the L3 of current CPUs), behind the per-core L2;
    /// `None` (the Larrabee presets): L2 misses go to DRAM.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub l3: Option<CacheConfig>,
    /// Memory-level parallelism of one hardware thread: how many of its cache misses overlap
    /// (an out-of-order core keeps several in flight; an in-order core waits for each). Stall
    /// cycles are divided by it. `None`: 1, every miss waits alone (Larrabee's in-order cores).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory_parallelism: Option<f64>,
    /// The host's vector unit, for machines describing a real CPU.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simd: Option<SimdConfig>,
    /// How each figure was obtained, by field (`"l2.size_bytes"`: the sysfs file it was read
    /// from, `"costs.vector"`: the calibration kernel that measured it, or `assumption: ...`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub sources: BTreeMap<String, String>,
    /// Where the issue costs were fitted, for a machine `shadowbench calibrate` fitted
    /// (`harness::fit`): the training sweep's scenes and image sizes, which `validate-model`
    /// holds out. `None` (the presets, `--kernels-only`): no figure was fitted to a scene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training: Option<Training>,
}

/// The training sweep a machine's issue costs were fitted to, and the fit's error on it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Training {
    /// Built-in scene names.
    pub scenes: Vec<String>,
    /// Image sizes, `[width, height]` in pixels.
    pub images: Vec<[u32; 2]>,
    /// Shadow-map resolution of the sweep, texels per side.
    pub map_resolution: u32,
    /// The clock `cpu-native` was measured on: `cpu` or `wall`.
    pub clock: crate::util::cpu_time::Clock,
    /// Runs and phases fitted.
    pub runs: usize,
    pub phases: usize,
    /// Mean absolute percentage error of the fitted table's prediction (the fit's formula) of
    /// the training runs and phases, percent.
    pub runs_mape: f64,
    pub phases_mape: f64,
    /// The host's 1-minute load average at the start and the end of the training sweep.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_average: Option<[f64; 2]>,
    /// Time the process's threads waited for a CPU during the sweep, percent of their CPU time
    /// (`util::cpu_time::Load::waited_pct_since`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub waited_pct: Option<f64>,
}

/// The largest cycle figure (a cost, latency or barrier) a machine may state: a second at 1 GHz.
pub const MAX_CYCLES: f64 = 1e9;

/// The presets, by name.
pub const PRESETS: &[&str] = &["larrabee-24", "larrabee-32", "larrabee-48", "host"];

impl MachineConfig {
    /// The Larrabee-style machine with `cores` cores at 1 GHz.
    ///
    /// - 4 threads/core, 16 lanes, 32 KiB L1D, 256 KiB L2 subset per core, 64-byte lines:
    ///   Seiler et al. 2008 §3; 24 cores × 1 GHz is the configuration 004 §4.1 simulated.
    /// - L1 8-way and L2 8-way: Seiler et al. give the L1 as 8-way; L2 associativity is an
    ///   assumption.
    /// - L1 miss to L2 hit ≈ 10 cycles, L2 miss to DRAM ≈ 200 cycles at 1 GHz (200 ns): an
    ///   assumption typical of GDDR-attached chips of the time.
    /// - DRAM 128 GB/s: Seiler et al. discuss GDDR5-class bandwidth; a round figure within that.
    /// - A global barrier costs ≈ 2000 cycles: an assumption (a ring round trip per core plus
    ///   the software fence of the rasterizer's pipeline).
    pub fn larrabee(cores: u32) -> MachineConfig {
        MachineConfig {
            name: format!("larrabee-{cores}"),
            cores,
            clock_ghz: 1.0,
            threads_per_core: 4,
            lanes: 16,
            line_bytes: 64,
            l1: CacheConfig {
                size_bytes: 32 * 1024,
                ways: 8,
                latency_cycles: 1.0,
            },
            l2: CacheConfig {
                size_bytes: 256 * 1024,
                ways: 8,
                latency_cycles: 10.0,
            },
            dram_latency_cycles: 200.0,
            dram_gb_per_s: 128.0,
            barrier_cycles: 2000.0,
            costs: OpCosts::LARRABEE,
            clock_source: None,
            l3: None,
            memory_parallelism: None,
            simd: None,
            sources: BTreeMap::new(),
            training: None,
        }
    }

    /// This machine as the operating system and the CPU state it ([`super::host::machine`]):
    /// cores, hardware threads, SIMD, caches and a shared L3, at the clock the operating system
    /// states ([`host_clock`]); costs and latencies are stated assumptions until
    /// `shadowbench calibrate` measures them. A pure function of the machine, so every process
    /// on it models the same times.
    ///
    /// Errors: the operating system states no CPU frequency (the message says what was read).
    pub fn host() -> Result<MachineConfig, String> {
        let clock = host_clock()?;
        let mut m = super::host::machine(clock.ghz);
        m.sources.insert("clock_ghz".into(), clock.source.clone());
        m.clock_source = Some(clock.source);
        Ok(m)
    }

    /// The preset `name`; `None` when there is no such preset. The `host` preset is an error
    /// when the operating system states no CPU frequency ([`MachineConfig::host`]).
    pub fn preset(name: &str) -> Option<Result<MachineConfig, String>> {
        match name {
            "larrabee-24" => Some(Ok(MachineConfig::larrabee(24))),
            "larrabee-32" => Some(Ok(MachineConfig::larrabee(32))),
            "larrabee-48" => Some(Ok(MachineConfig::larrabee(48))),
            "host" => Some(MachineConfig::host()),
            _ => None,
        }
    }

    /// A preset name or a path to a JSON configuration; `field` names the setting in errors.
    pub fn resolve(field: &str, arg: &str, base: &Path) -> Result<MachineConfig, InputError> {
        if let Some(m) = MachineConfig::preset(arg) {
            return m.map_err(|why| InputError::new(field, format!("machine '{arg}': {why}")));
        }
        if arg.ends_with(".json") {
            let path = base.join(arg);
            return MachineConfig::from_file(&path).map_err(|e| InputError {
                field: e.field.or_else(|| Some(field.to_string())),
                ..e
            });
        }
        Err(InputError::new(
            field,
            unknown_name("machine", arg, PRESETS) + " (or a path to a machine .json file)",
        ))
    }

    /// Reads and validates a JSON configuration.
    pub fn from_file(path: &Path) -> Result<MachineConfig, InputError> {
        MachineConfig::from_json(
            &crate::util::input::read_text(path, "machine config")?,
            path,
        )
    }

    /// Parses and validates the text of a JSON configuration; `path` names it in errors.
    pub fn from_json(text: &str, path: &Path) -> Result<MachineConfig, InputError> {
        let m: MachineConfig = crate::util::json::parse(text, path)?;
        m.validate().map_err(|e| e.in_file(path))?;
        Ok(m)
    }

    /// The same machine with `cores` cores (the `cores` sweep axis).
    pub fn with_cores(&self, cores: u32) -> MachineConfig {
        MachineConfig {
            cores,
            ..self.clone()
        }
    }

    /// Sets of cache level `c` (`size / (line × ways)`; any count ≥ 1, a power of two or not).
    pub fn sets(&self, c: &CacheConfig) -> u32 {
        c.size_bytes / (self.line_bytes * c.ways)
    }

    /// The memory-level parallelism stalls are divided by (1 when not stated).
    pub fn mlp(&self) -> f64 {
        self.memory_parallelism.unwrap_or(1.0)
    }

    /// Cycles of the machine's clock in one millisecond (modelled cycles to `model_ms`).
    pub fn cycles_per_ms(&self) -> f64 {
        self.clock_ghz * 1e6
    }

    /// DRAM bytes the chip moves per cycle.
    pub fn dram_bytes_per_cycle(&self) -> f64 {
        self.dram_gb_per_s / self.clock_ghz
    }

    pub fn validate(&self) -> Result<(), InputError> {
        let within = |field: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(InputError::new(
                    format!("$.{field}"),
                    format!("must be a number in {lo}..={hi}, got {v}"),
                ))
            }
        };
        // Cycle figures: at most a second at 1 GHz each, so that no sum of them overflows.
        let cycles = |field: &str, v: f64| within(field, v, 0.0, MAX_CYCLES);
        if !(1..=1024).contains(&self.cores) {
            return Err(InputError::new(
                "$.cores",
                format!("must be in 1..=1024, got {}", self.cores),
            ));
        }
        if !(1..=16).contains(&self.threads_per_core) {
            return Err(InputError::new(
                "$.threads_per_core",
                format!("must be in 1..=16, got {}", self.threads_per_core),
            ));
        }
        if self.lanes != 16 {
            return Err(InputError::new(
                "$.lanes",
                format!(
                    "the kernels are written for 16 lanes (004 §3.1), got {}",
                    self.lanes
                ),
            ));
        }
        if !self.line_bytes.is_power_of_two() || !(16..=1024).contains(&self.line_bytes) {
            return Err(InputError::new(
                "$.line_bytes",
                format!(
                    "must be a power of two in 16..=1024, got {}",
                    self.line_bytes
                ),
            ));
        }
        let levels = [("l1", &self.l1), ("l2", &self.l2)]
            .into_iter()
            .chain(self.l3.as_ref().map(|c| ("l3", c)));
        for (name, c) in levels {
            if !(1..=64).contains(&c.ways) {
                return Err(InputError::new(
                    format!("$.{name}.ways"),
                    format!("must be in 1..=64, got {}", c.ways),
                ));
            }
            let line_ways = u64::from(self.line_bytes) * u64::from(c.ways);
            let whole = u64::from(c.size_bytes) % line_ways == 0;
            let sets = u64::from(c.size_bytes) / line_ways;
            if sets == 0 || !whole {
                return Err(InputError::new(
                    format!("$.{name}"),
                    format!(
                        "size_bytes must be a whole number ≥ 1 of sets of line_bytes × ways; got \
                         {} bytes, {} ways, {}-byte lines",
                        c.size_bytes, c.ways, self.line_bytes
                    ),
                ));
            }
            cycles(&format!("{name}.latency_cycles"), c.latency_cycles)?;
        }
        if let Some(p) = self.memory_parallelism {
            if !(p.is_finite() && (1.0..=64.0).contains(&p)) {
                return Err(InputError::new(
                    "$.memory_parallelism",
                    format!("must be a number in 1..=64, got {p}"),
                ));
            }
        }
        if let Some(s) = &self.simd {
            if !(1..=64).contains(&s.f32_lanes) {
                return Err(InputError::new(
                    "$.simd.f32_lanes",
                    format!("must be in 1..=64, got {}", s.f32_lanes),
                ));
            }
        }
        within("clock_ghz", self.clock_ghz, 0.001, 1000.0)?;
        within("dram_gb_per_s", self.dram_gb_per_s, 0.001, 1e6)?;
        cycles("dram_latency_cycles", self.dram_latency_cycles)?;
        cycles("barrier_cycles", self.barrier_cycles)?;
        let k = &self.costs;
        for (name, v) in [
            ("costs.vector", k.vector),
            ("costs.scalar", k.scalar),
            ("costs.vector_memory", k.vector_memory),
            ("costs.gather_line", k.gather_line),
            ("costs.gather", k.gather),
            ("costs.lane", k.lane),
            ("costs.atomic", k.atomic),
            ("costs.phase", k.phase),
        ] {
            cycles(name, v)?;
        }
        Ok(())
    }

    /// A one-line description for `shadowbench list`.
    pub fn describe(&self) -> String {
        let simd = self
            .simd
            .as_ref()
            .map(|s| format!(" ({} × {} f32)", s.isa, s.f32_lanes))
            .unwrap_or_default();
        let l3 = self
            .l3
            .as_ref()
            .map(|c| format!(", L3 {} KiB shared", c.size_bytes / 1024))
            .unwrap_or_default();
        format!(
            "{} cores × {} threads @ {:.2} GHz, {} lanes{simd}, L1 {} KiB {}-way, L2 {} KiB/core\
             {l3}, {}-byte lines, DRAM {} GB/s",
            self.cores,
            self.threads_per_core,
            self.clock_ghz,
            self.lanes,
            self.l1.size_bytes / 1024,
            self.l1.ways,
            self.l2.size_bytes / 1024,
            self.line_bytes,
            // Stated figures as written (128), measured ones to 0.1 GB/s.
            if self.dram_gb_per_s.fract() == 0.0 {
                format!("{}", self.dram_gb_per_s)
            } else {
                format!("{:.1}", self.dram_gb_per_s)
            }
        )
    }
}

impl Default for MachineConfig {
    /// The configuration 004 §4.1 simulated: 24 cores at 1 GHz.
    fn default() -> Self {
        MachineConfig::larrabee(24)
    }
}

/// The host's CPU clock as the operating system states it, and where it was read.
#[derive(Clone, Debug, PartialEq)]
pub struct HostClock {
    /// GHz, rounded to 0.01 GHz.
    pub ghz: f64,
    /// The file and field it was read from.
    pub source: String,
}

const CPUFREQ: &str = "/sys/devices/system/cpu/cpu0/cpufreq";
const CPUINFO: &str = "/proc/cpuinfo";

/// The host clock from the operating system, never from timing (a measured clock depends on
/// the load and on frequency scaling, so modelled times would differ between processes). The
/// first of, in order:
///
/// 1. `/sys/devices/system/cpu/cpu0/cpufreq/base_frequency` (kHz): the nominal frequency
///    (intel_pstate, amd-pstate);
/// 2. the nominal frequency in the `model name` of `/proc/cpuinfo` (`... @ 2.50GHz`);
/// 3. `/sys/devices/system/cpu/cpu0/cpufreq/cpuinfo_max_freq` (kHz): the maximum frequency;
/// 4. the largest `cpu MHz` of `/proc/cpuinfo`: without a cpufreq driver (virtual machines)
///    this is the constant clock the hypervisor states.
///
/// Errors: none of them is readable (the message lists what was tried).
pub fn host_clock() -> Result<HostClock, String> {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let khz = |p: String| read(&p).and_then(|t| t.trim().parse::<f64>().ok());
    let cpuinfo = read(CPUINFO).unwrap_or_default();
    let found = khz(format!("{CPUFREQ}/base_frequency"))
        .map(|k| (k / 1e6, format!("{CPUFREQ}/base_frequency")))
        .or_else(|| nominal_ghz(&cpuinfo).map(|g| (g, format!("{CPUINFO} model name"))))
        .or_else(|| {
            khz(format!("{CPUFREQ}/cpuinfo_max_freq"))
                .map(|k| (k / 1e6, format!("{CPUFREQ}/cpuinfo_max_freq")))
        })
        .or_else(|| cpu_mhz(&cpuinfo).map(|m| (m / 1e3, format!("{CPUINFO} cpu MHz (largest)"))));
    match found {
        Some((ghz, source)) if ghz.is_finite() && ghz > 0.0 => Ok(HostClock {
            ghz: (ghz * 100.0).round() / 100.0,
            source,
        }),
        _ => Err(format!(
            "the operating system states no CPU frequency (tried {CPUFREQ}/base_frequency, \
             the model name and cpu MHz in {CPUINFO}, {CPUFREQ}/cpuinfo_max_freq); give a \
             machine .json file with clock_ghz instead"
        )),
    }
}

/// The nominal GHz in a `/proc/cpuinfo` `model name` line (`Intel(R) Xeon(R) ... @ 2.50GHz`).
fn nominal_ghz(cpuinfo: &str) -> Option<f64> {
    let name = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))?
        .split_once(':')?
        .1;
    let at = name.rsplit_once('@')?.1.trim();
    at.strip_suffix("GHz")?.trim().parse().ok()
}

/// The largest `cpu MHz` of `/proc/cpuinfo`.
fn cpu_mhz(cpuinfo: &str) -> Option<f64> {
    cpuinfo
        .lines()
        .filter(|l| l.starts_with("cpu MHz"))
        .filter_map(|l| l.split_once(':')?.1.trim().parse::<f64>().ok())
        .reduce(f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid_and_round_trip_through_json() {
        for name in PRESETS.iter().filter(|n| **n != "host") {
            let m = MachineConfig::preset(name).unwrap().unwrap();
            m.validate().unwrap();
            assert_eq!(&m.name, name);
            let json = serde_json::to_string(&m).unwrap();
            let back: MachineConfig = serde_json::from_str(&json).unwrap();
            assert_eq!(back, m);
        }
    }

    #[test]
    fn unknown_machine_names_the_field_and_the_closest_preset() {
        let e = MachineConfig::resolve("$.machine", "larabee-24", Path::new(".")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("$.machine"));
        assert!(e.message.contains("did you mean 'larrabee-24'"), "{e}");
    }

    #[test]
    fn bad_json_config_names_the_field() {
        let (dir, path) = crate::util::paths::temp_path("m.json");
        let mut m = serde_json::to_value(MachineConfig::larrabee(24)).unwrap();
        m["l1"]["ways"] = serde_json::json!(3);
        std::fs::write(&path, m.to_string()).unwrap();
        let e = MachineConfig::resolve("$.machine", "m.json", dir.path()).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("$.l1"), "{e}");
        m["l1"]["ways"] = serde_json::json!(8);
        m["clock_ghz"] = serde_json::json!(-1.0);
        std::fs::write(&path, m.to_string()).unwrap();
        let e = MachineConfig::resolve("$.machine", "m.json", dir.path()).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("$.clock_ghz"), "{e}");
        // Figures so large that a run's modelled time would overflow to inf are refused,
        // naming the field and the value.
        m["clock_ghz"] = serde_json::json!(1.0);
        for (field, value) in [
            ("costs.vector", 1.7e308),
            ("costs.phase", 1e300),
            ("barrier_cycles", 2e9),
            ("dram_gb_per_s", 1e300),
        ] {
            let mut bad = m.clone();
            let (head, tail) = field.split_once('.').unwrap_or((field, ""));
            if tail.is_empty() {
                bad[head] = serde_json::json!(value);
            } else {
                bad[head][tail] = serde_json::json!(value);
            }
            std::fs::write(&path, bad.to_string()).unwrap();
            let e = MachineConfig::resolve("$.machine", "m.json", dir.path()).unwrap_err();
            assert_eq!(e.field.as_deref(), Some(&*format!("$.{field}")), "{e}");
            assert!(e.to_string().contains(&format!("{value}")), "{e}");
        }
    }

    #[test]
    fn the_nominal_clock_is_read_from_the_model_name_and_cpu_mhz() {
        let info = "processor\t: 0\nmodel name\t: Intel(R) Xeon(R) CPU E5-2680 v4 @ 2.40GHz\n\
                    cpu MHz\t\t: 1199.953\nprocessor\t: 1\ncpu MHz\t\t: 3300.012\n";
        assert_eq!(nominal_ghz(info), Some(2.4));
        assert_eq!(cpu_mhz(info), Some(3300.012));
        assert_eq!(nominal_ghz("model name\t: AMD EPYC\n"), None);
        assert_eq!(cpu_mhz("model name\t: AMD EPYC\n"), None);
    }

    #[test]
    fn the_host_clock_is_the_same_on_every_call() {
        // Stated by the OS, not timed: repeated reads agree exactly (where the OS states one).
        if let Ok(c) = host_clock() {
            for _ in 0..5 {
                assert_eq!(host_clock().unwrap(), c);
            }
            let m = MachineConfig::host().unwrap();
            assert_eq!(m.clock_ghz, c.ghz);
            assert_eq!(m.clock_source.as_deref(), Some(c.source.as_str()));
        }
    }

    /// Found by the `machine` fuzz target: line_bytes × ways overflowed u32 in validation (a
    /// panic with overflow checks; without them 64 × 2^26 wrapped to 0 and the set count
    /// divided by zero). A way count out of range is named with its value instead.
    #[test]
    fn a_way_count_whose_line_product_overflows_is_refused_with_its_value() {
        let path = Path::new("m.json");
        for (line_bytes, ways) in [
            (64, 1u32 << 26),
            (64, 100_000_000),
            (1024, u32::MAX),
            (64, 0),
        ] {
            for level in ["l1", "l2"] {
                let mut m = serde_json::to_value(MachineConfig::larrabee(24)).unwrap();
                m["line_bytes"] = serde_json::json!(line_bytes);
                m[level]["ways"] = serde_json::json!(ways);
                let e = MachineConfig::from_json(&m.to_string(), path).unwrap_err();
                assert_eq!(e.file.as_deref(), Some(path), "{e}");
                assert_eq!(e.field, Some(format!("$.{level}.ways")), "{e}");
                assert!(
                    e.message.contains(&format!("got {ways}")) && e.message.contains("1..=64"),
                    "{e}"
                );
            }
        }
    }
}
