//! What this machine states about itself: the CPU's SIMD instruction set (run-time feature
//! detection), hardware threads per core, and the size, associativity and line size of each
//! cache level (Linux sysfs, `/sys/devices/system/cpu/cpu0/cache/index*/` and
//! `.../topology/thread_siblings_list`). The `host` preset ([`super::MachineConfig::host`]) is
//! built from these; `shadowbench calibrate` ([`super::calibrate`]) adds measured costs.
//!
//! Everything here is read, never timed, so every process on a machine sees the same figures.
//! Where the operating system states nothing (other systems, containers without sysfs) the
//! caller falls back to stated assumptions and records that it did.

use std::collections::BTreeMap;
use std::path::Path;

use super::config::{CacheConfig, MachineConfig, OpCosts, SimdConfig};

/// The sysfs folder of the first CPU.
pub const CPU0: &str = "/sys/devices/system/cpu/cpu0";

/// The host's vector unit as far as the kernels' f32 lanes go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Simd {
    /// The widest f32 vector instruction set the CPU reports at run time (`avx512f`, `avx2`,
    /// `avx`, `sse2`, `neon`, or `none`).
    pub isa: String,
    /// f32 lanes of one vector register of that set (16, 8, 4 or 1).
    pub f32_lanes: u32,
    /// How it was found.
    pub source: String,
}

/// The host's widest f32 SIMD, from run-time CPU feature detection (`std::arch`).
pub fn simd() -> Simd {
    #[cfg(target_arch = "x86_64")]
    {
        let (isa, lanes) = if std::arch::is_x86_feature_detected!("avx512f") {
            ("avx512f", 16)
        } else if std::arch::is_x86_feature_detected!("avx2") {
            ("avx2", 8)
        } else if std::arch::is_x86_feature_detected!("avx") {
            ("avx", 8)
        } else {
            ("sse2", 4)
        };
        Simd {
            isa: isa.into(),
            f32_lanes: lanes,
            source: "std::arch::is_x86_feature_detected! (CPUID at run time)".into(),
        }
    }
    #[cfg(target_arch = "aarch64")]
    {
        // NEON (AdvSIMD) is mandatory on AArch64; SVE widths are not detected.
        Simd {
            isa: "neon".into(),
            f32_lanes: 4,
            source: "AArch64 baseline (NEON is mandatory; SVE not detected)".into(),
        }
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        Simd {
            isa: "none".into(),
            f32_lanes: 1,
            source: "no SIMD detection for this architecture: scalar assumed".into(),
        }
    }
}

/// This machine at `clock_ghz`: what [`simd`], [`read_caches`] and [`threads_per_core`] find
/// under [`CPU0`], with every figure's origin in `sources`. See [`machine_from`].
pub fn machine(clock_ghz: f64) -> MachineConfig {
    let logical = std::thread::available_parallelism()
        .map(|n| n.get() as u32)
        .unwrap_or(1);
    machine_from(Path::new(CPU0), logical, simd(), clock_ghz)
}

/// Stated assumption, recorded where sysfs or the CPU says nothing and for every cost until
/// `shadowbench calibrate` measures it.
const ASSUMED: &str = "assumption (typical of current out-of-order x86 cores; \
                       `shadowbench calibrate` measures it)";

/// The machine of the CPU whose sysfs folder is `cpu_dir`, with `logical` logical CPUs
/// available to this process and vector unit `simd`, at `clock_ghz`:
///
/// - `threads_per_core`: the CPUs in `topology/thread_siblings_list` (1 when unreadable);
///   `cores` = `logical / threads_per_core` (at least 1);
/// - `line_bytes`, `l1` (the level-1 data cache), `l2` (level 2; shared by k cores, a core's
///   share is size / k) and `l3` (the largest level above 2, shared by all modelled cores: one
///   instance's size times the instances the logical CPUs span), sizes and ways from
///   `cache/index*/`; without sysfs: 64-byte lines, 32 KiB 8-way L1, 1 MiB 8-way L2, no L3;
/// - costs (cycles per counted operation): a 16-lane vector instruction or contiguous
///   one-line access is `16 / f32_lanes` host instructions at one per cycle (no per-lane
///   cost: `costs.lane` 0, which `shadowbench calibrate` measures); scalar 1, gather 1
///   per line, atomic 20; latencies L1 4, L2 14, L3 50 cycles, DRAM 100 ns; memory parallelism
///   1; DRAM 20 GB/s; barrier 2000 cycles. These are stated assumptions (`sources` says so)
///   until `shadowbench calibrate` replaces them with measurements.
///
/// A pure function of what it reads, so every process on a machine builds the same machine.
pub fn machine_from(cpu_dir: &Path, logical: u32, simd: Simd, clock_ghz: f64) -> MachineConfig {
    let mut sources = BTreeMap::new();
    let mut src = |k: &str, v: String| {
        sources.insert(k.to_string(), v);
    };
    let threads = threads_of(cpu_dir, logical, &mut src);
    let cores = (logical / threads).max(1);
    src(
        "cores",
        format!("available parallelism ({logical} logical CPUs) / threads_per_core"),
    );
    let caches = read_caches(cpu_dir).unwrap_or_default();
    let (line_bytes, l1, l2, l3) = cache_levels(&caches, logical, threads, &mut src);
    let lanes = simd.f32_lanes.max(1);
    let per_vector = 16.0 / f64::from(lanes);
    src("simd", simd.source.clone());
    for k in [
        "costs.vector",
        "costs.scalar",
        "costs.vector_memory",
        "costs.gather_line",
        "costs.gather",
        "costs.atomic",
        "dram_latency_cycles",
        "dram_gb_per_s",
        "barrier_cycles",
        "memory_parallelism",
    ] {
        src(k, ASSUMED.into());
    }
    MachineConfig {
        name: "host".into(),
        cores,
        clock_ghz,
        threads_per_core: threads,
        lanes: 16,
        line_bytes,
        l1,
        l2,
        dram_latency_cycles: 100.0 * clock_ghz,
        dram_gb_per_s: 20.0,
        barrier_cycles: 2000.0,
        costs: OpCosts {
            vector: per_vector,
            vector_memory: per_vector,
            ..OpCosts::LARRABEE
        },
        clock_source: None,
        l3,
        memory_parallelism: None,
        simd: Some(SimdConfig {
            isa: simd.isa,
            f32_lanes: lanes,
        }),
        sources,
        training: None,
    }
}

/// Where each figure of a machine came from (`MachineConfig::sources`): field, origin.
type Sources<'a> = dyn FnMut(&str, String) + 'a;

/// Hardware threads per core from `topology/thread_siblings_list` under `cpu_dir` (1 when
/// unreadable or above `logical`).
fn threads_of(cpu_dir: &Path, logical: u32, src: &mut Sources) -> u32 {
    match threads_per_core(cpu_dir) {
        Some(t) if t >= 1 && t <= logical => {
            src(
                "threads_per_core",
                format!("{}/topology/thread_siblings_list", cpu_dir.display()),
            );
            t
        }
        _ => {
            src(
                "threads_per_core",
                "assumption: 1 (topology/thread_siblings_list unreadable)".into(),
            );
            1
        }
    }
}

/// The line size, L1 (level-1 data), L2 (a core's share of level 2) and L3 (the largest level
/// above 2, over all the instances `logical` CPUs span) of `caches`, with the fallbacks of
/// [`machine_from`] and the assumed latencies.
fn cache_levels(
    caches: &[CacheInfo],
    logical: u32,
    threads: u32,
    src: &mut Sources,
) -> (u32, CacheConfig, CacheConfig, Option<CacheConfig>) {
    let find = |level: u32, data: bool| {
        caches
            .iter()
            .filter(|c| c.level == level)
            .find(|c| c.kind == "Unified" || (data && c.kind == "Data"))
            .filter(|c| c.ways > 0 && c.size_bytes > 0 && c.line_bytes > 0)
    };
    let l1i = find(1, true);
    let line_bytes = match l1i {
        Some(c) if c.line_bytes.is_power_of_two() => {
            src("line_bytes", format!("{}/coherency_line_size", c.path));
            c.line_bytes
        }
        _ => {
            src("line_bytes", "assumption: 64 (no sysfs cache entry)".into());
            64
        }
    };
    let level = |info: Option<&CacheInfo>,
                 share: u32,
                 name: &str,
                 fallback: (u32, u32),
                 latency: f64,
                 src: &mut Sources| {
        let spec = LevelSpec {
            share,
            name,
            fallback,
            latency,
            line_bytes,
        };
        cache_level(info, &spec, src)
    };
    let l1 = level(l1i, 1, "l1", (32 << 10, 8), 4.0, src);
    // An L2 shared by k cores gives each core 1/k of it.
    let l2_info = find(2, false);
    let l2_cores = l2_info.map_or(1, |c| (c.shared_cpus / threads).max(1));
    let mut l2 = level(l2_info, 1, "l2", (1 << 20, 8), 14.0 - 4.0, src);
    if l2_cores > 1 {
        l2.size_bytes /= l2_cores;
        src(
            "l2.size_bytes",
            format!(
                "{}/size / {l2_cores} cores sharing it",
                l2_info.map_or(String::new(), |i| i.path.clone())
            ),
        );
    }
    let last = caches
        .iter()
        .filter(|c| c.level > 2 && c.kind != "Instruction")
        .max_by_key(|c| c.level);
    let l3 = last
        .map(|c| {
            let instances = logical.div_ceil(c.shared_cpus.max(1)).max(1);
            level(Some(c), instances, "l3", (0, 1), 50.0 - 14.0, src)
        })
        .filter(|c| c.size_bytes > 0);
    (line_bytes, l1, l2, l3)
}

/// How [`cache_level`] builds one level: `share` instances of the sysfs cache, the machine
/// field `name`, the `(size, ways)` without a usable entry, the assumed latency in cycles.
struct LevelSpec<'a> {
    share: u32,
    name: &'a str,
    fallback: (u32, u32),
    latency: f64,
    line_bytes: u32,
}

/// One cache level from its sysfs entry `info` (when its size is a whole number of sets of
/// `line_bytes` lines), else the fallback; records the origins.
fn cache_level(info: Option<&CacheInfo>, spec: &LevelSpec, src: &mut Sources) -> CacheConfig {
    let (name, line_bytes) = (spec.name, spec.line_bytes);
    let config = info.and_then(|c| {
        let size = c.size_bytes.checked_mul(u64::from(spec.share.max(1)))?;
        let size = u32::try_from(size).ok()?;
        let whole = size % (line_bytes * c.ways) == 0 && size >= line_bytes * c.ways;
        whole.then_some((c, size))
    });
    src(&format!("{name}.latency_cycles"), ASSUMED.into());
    match config {
        Some((c, size)) => {
            src(
                &format!("{name}.size_bytes"),
                format!("{}/size{}", c.path, share_note(spec.share)),
            );
            src(
                &format!("{name}.ways"),
                format!("{}/ways_of_associativity", c.path),
            );
            CacheConfig {
                size_bytes: size,
                ways: c.ways,
                latency_cycles: spec.latency,
            }
        }
        None => {
            src(
                &format!("{name}.size_bytes"),
                format!(
                    "assumption: {} bytes (no usable sysfs entry)",
                    spec.fallback.0
                ),
            );
            CacheConfig {
                size_bytes: spec.fallback.0,
                ways: spec.fallback.1,
                latency_cycles: spec.latency,
            }
        }
    }
}

fn share_note(instances: u32) -> String {
    if instances > 1 {
        format!(" × {instances} instances")
    } else {
        String::new()
    }
}

/// One cache of a CPU as sysfs lists it (`cache/indexN/`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CacheInfo {
    /// 1, 2, 3, ...
    pub level: u32,
    /// `Data`, `Instruction` or `Unified`.
    pub kind: String,
    /// Capacity of one instance in bytes (`size`, e.g. `32K`).
    pub size_bytes: u64,
    /// `ways_of_associativity` (0 when sysfs says 0: fully associative or unknown).
    pub ways: u32,
    /// `coherency_line_size` in bytes.
    pub line_bytes: u32,
    /// Logical CPUs sharing this instance (`shared_cpu_list`).
    pub shared_cpus: u32,
    /// The folder it was read from.
    pub path: String,
}

/// The caches of the CPU whose sysfs folder is `cpu_dir` (e.g. [`CPU0`]), ordered by index.
/// Instruction caches are included (callers pick data and unified ones).
///
/// Errors: the folder has no readable `cache/index*/` entry, or one has a field that does not
/// parse (the message names the file and the text).
pub fn read_caches(cpu_dir: &Path) -> Result<Vec<CacheInfo>, String> {
    let dir = cpu_dir.join("cache");
    let entries =
        std::fs::read_dir(&dir).map_err(|e| format!("cannot read {}: {e}", dir.display()))?;
    let mut indices: Vec<(u32, std::path::PathBuf)> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let n = name.strip_prefix("index")?.parse().ok()?;
            Some((n, e.path()))
        })
        .collect();
    indices.sort();
    if indices.is_empty() {
        return Err(format!("no index* folders in {}", dir.display()));
    }
    indices
        .into_iter()
        .map(|(_, p)| {
            let read = |f: &str| {
                std::fs::read_to_string(p.join(f))
                    .map(|s| s.trim().to_string())
                    .map_err(|e| format!("cannot read {}: {e}", p.join(f).display()))
            };
            let number = |f: &str| -> Result<u32, String> {
                let t = read(f)?;
                t.parse()
                    .map_err(|_| format!("{}: expected a number, got '{t}'", p.join(f).display()))
            };
            let size_text = read("size")?;
            Ok(CacheInfo {
                level: number("level")?,
                kind: read("type")?,
                size_bytes: parse_size(&size_text).ok_or_else(|| {
                    format!(
                        "{}: expected a size such as 32K, got '{size_text}'",
                        p.join("size").display()
                    )
                })?,
                ways: number("ways_of_associativity")?,
                line_bytes: number("coherency_line_size")?,
                shared_cpus: read("shared_cpu_list")
                    .ok()
                    .and_then(|t| cpu_list_len(&t))
                    .unwrap_or(1),
                path: p.display().to_string(),
            })
        })
        .collect()
}

/// Hardware threads per core: the logical CPUs in `topology/thread_siblings_list` of the CPU
/// whose sysfs folder is `cpu_dir`; `None` when it cannot be read.
pub fn threads_per_core(cpu_dir: &Path) -> Option<u32> {
    let text = std::fs::read_to_string(cpu_dir.join("topology/thread_siblings_list")).ok()?;
    cpu_list_len(text.trim())
}

/// Bytes of a sysfs cache size: `32K`, `1024K`, `32M`, or a plain number of bytes.
pub fn parse_size(text: &str) -> Option<u64> {
    let t = text.trim();
    let (digits, unit) = match t.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((i, _)) => t.split_at(i),
        None => (t, ""),
    };
    let n: u64 = digits.parse().ok()?;
    let scale = match unit.trim() {
        "" | "B" => 1,
        "K" | "KiB" | "KB" => 1 << 10,
        "M" | "MiB" | "MB" => 1 << 20,
        "G" | "GiB" | "GB" => 1 << 30,
        _ => return None,
    };
    n.checked_mul(scale)
}

/// The number of CPUs in a sysfs CPU list (`0`, `0-1`, `0,2,4-7`); `None` when it does not parse.
pub fn cpu_list_len(text: &str) -> Option<u32> {
    let mut n = 0u32;
    for part in text.trim().split(',').filter(|p| !p.is_empty()) {
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b): (u32, u32) = (a.trim().parse().ok()?, b.trim().parse().ok()?);
                if b < a {
                    return None;
                }
                n += b - a + 1;
            }
            None => {
                part.trim().parse::<u32>().ok()?;
                n += 1;
            }
        }
    }
    (n > 0).then_some(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fake sysfs CPU folder with the given caches (level, type, size, ways, line, shared).
    fn fake_cpu(caches: &[(u32, &str, &str, u32, u32, &str)], siblings: &str) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for (i, (level, kind, size, ways, line, shared)) in caches.iter().enumerate() {
            let d = dir.path().join(format!("cache/index{i}"));
            std::fs::create_dir_all(&d).unwrap();
            for (f, v) in [
                ("level", level.to_string()),
                ("type", kind.to_string()),
                ("size", size.to_string()),
                ("ways_of_associativity", ways.to_string()),
                ("coherency_line_size", line.to_string()),
                ("shared_cpu_list", shared.to_string()),
            ] {
                std::fs::write(d.join(f), format!("{v}\n")).unwrap();
            }
        }
        std::fs::create_dir_all(dir.path().join("topology")).unwrap();
        std::fs::write(
            dir.path().join("topology/thread_siblings_list"),
            format!("{siblings}\n"),
        )
        .unwrap();
        dir
    }

    /// A fake core whose logical CPUs `core` share an L1D of (size, ways), a 32K 8-way L1I and
    /// an L2 of (size, ways), with an L3 of (size, ways, sharing CPUs); 64-byte lines.
    fn fake_core_with_l3(
        l1: (&str, u32),
        l2: (&str, u32),
        l3: (&str, u32, &str),
        core: &str,
    ) -> tempfile::TempDir {
        fake_cpu(
            &[
                (1, "Data", l1.0, l1.1, 64, core),
                (1, "Instruction", "32K", 8, 64, core),
                (2, "Unified", l2.0, l2.1, 64, core),
                (3, "Unified", l3.0, l3.1, 64, l3.2),
            ],
            core,
        )
    }

    #[test]
    fn caches_and_threads_are_read_from_a_sysfs_folder() {
        // An SMT-2 core: 48K 12-way L1D, 2M 16-way L2, a 30M 12-way L3 over 16 logical CPUs.
        let cpu = fake_core_with_l3(("48K", 12), ("2048K", 16), ("30M", 12, "0-15"), "0,8");
        let c = read_caches(cpu.path()).unwrap();
        assert_eq!(c.len(), 4);
        assert_eq!(
            (c[0].level, c[0].kind.as_str(), c[0].size_bytes, c[0].ways),
            (1, "Data", 48 * 1024, 12)
        );
        assert_eq!(c[2].size_bytes, 2 * 1024 * 1024);
        assert_eq!(
            (c[3].size_bytes, c[3].ways, c[3].shared_cpus),
            (30 * 1024 * 1024, 12, 16)
        );
        assert_eq!(c[3].line_bytes, 64);
        assert_eq!(threads_per_core(cpu.path()), Some(2));
    }

    #[test]
    fn the_host_machine_is_built_from_the_sysfs_figures() {
        // 8 logical CPUs, 2 threads per core: 4 cores. L2 1 MiB per core (shared by one core's
        // two threads); L3 16 MiB shared by 4 logical CPUs, so two instances span the 8.
        let cpu = fake_core_with_l3(("32K", 8), ("1024K", 8), ("16M", 16, "0-3"), "0-1");
        let avx2 = Simd {
            isa: "avx2".into(),
            f32_lanes: 8,
            source: "test".into(),
        };
        let m = machine_from(cpu.path(), 8, avx2, 2.5);
        m.validate().unwrap();
        assert_eq!((m.cores, m.threads_per_core, m.line_bytes), (4, 2, 64));
        assert_eq!((m.l1.size_bytes, m.l1.ways), (32 << 10, 8));
        assert_eq!((m.l2.size_bytes, m.l2.ways), (1 << 20, 8));
        let l3 = m.l3.as_ref().unwrap();
        assert_eq!((l3.size_bytes, l3.ways), (32 << 20, 16));
        // 16 lanes on an 8-lane unit: two host instructions per modelled one.
        assert_eq!(m.costs.vector, 2.0);
        assert_eq!(m.simd.as_ref().unwrap().isa, "avx2");
        assert!(m.sources["l3.size_bytes"].contains("index3/size × 2 instances"));
        assert!(m.sources["costs.vector"].starts_with("assumption"));
        // A pure function of what it reads.
        let again = machine_from(
            cpu.path(),
            8,
            Simd {
                isa: "avx2".into(),
                f32_lanes: 8,
                source: "test".into(),
            },
            2.5,
        );
        assert_eq!(again, m);
    }

    #[test]
    fn without_sysfs_the_host_machine_falls_back_and_says_so() {
        let empty = tempfile::tempdir().unwrap();
        let m = machine_from(
            empty.path(),
            3,
            Simd {
                isa: "sse2".into(),
                f32_lanes: 4,
                source: "test".into(),
            },
            1.0,
        );
        m.validate().unwrap();
        assert_eq!((m.cores, m.threads_per_core), (3, 1));
        assert!(m.l3.is_none());
        assert!(m.sources["l2.size_bytes"].starts_with("assumption"));
        assert!(m.sources["threads_per_core"].starts_with("assumption"));
        assert_eq!(m.costs.vector, 4.0);
    }

    #[test]
    fn a_bad_sysfs_field_names_the_file_and_the_text() {
        let cpu = fake_cpu(&[(1, "Data", "32 kilobytes", 8, 64, "0")], "0");
        let e = read_caches(cpu.path()).unwrap_err();
        assert!(
            e.contains("index0/size") && e.contains("32 kilobytes"),
            "{e}"
        );
        let empty = tempfile::tempdir().unwrap();
        assert!(read_caches(empty.path()).is_err());
        assert_eq!(threads_per_core(empty.path()), None);
    }

    #[test]
    fn sizes_and_cpu_lists_parse() {
        assert_eq!(parse_size("32K"), Some(32768));
        assert_eq!(parse_size("1024K"), Some(1 << 20));
        assert_eq!(parse_size("32M"), Some(32 << 20));
        assert_eq!(parse_size("512"), Some(512));
        assert_eq!(parse_size("12Q"), None);
        assert_eq!(parse_size(""), None);
        assert_eq!(cpu_list_len("0"), Some(1));
        assert_eq!(cpu_list_len("0-1"), Some(2));
        assert_eq!(cpu_list_len("0,2,4-7"), Some(6));
        assert_eq!(cpu_list_len("3-1"), None);
        assert_eq!(cpu_list_len("x"), None);
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn simd_agrees_with_the_flags_the_kernel_lists() {
        // An independent source: the flags Linux lists in /proc/cpuinfo (where there is one).
        let s = simd();
        let Ok(info) = std::fs::read_to_string("/proc/cpuinfo") else {
            return;
        };
        let Some(flags) = info.lines().find(|l| l.starts_with("flags")) else {
            return;
        };
        let has = |f: &str| flags.split_whitespace().any(|w| w == f);
        let expected = if has("avx512f") {
            ("avx512f", 16)
        } else if has("avx2") {
            ("avx2", 8)
        } else if has("avx") {
            ("avx", 8)
        } else {
            ("sse2", 4)
        };
        assert_eq!((s.isa.as_str(), s.f32_lanes), expected, "{flags}");
    }
}
