//! CPU time of this process and of the calling thread, and how much the host's other load
//! delayed this process's threads: the clocks `calibrate` and `validate-model` measure
//! `cpu-native` with, so that a measurement on a busy machine does not include the time other
//! processes held the CPUs.
//!
//! Sources: POSIX `clock_gettime` with `CLOCK_PROCESS_CPUTIME_ID` (every thread of the process)
//! and `CLOCK_THREAD_CPUTIME_ID` (the calling thread), in nanoseconds (`libc`); the scheduler's
//! run delay per thread (the second field of Linux's `/proc/self/task/*/schedstat`: time spent
//! runnable, waiting for a CPU) and the 1-minute load average (`/proc/loadavg`).

use std::time::Instant;

/// Which clock measures `cpu-native` time.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    /// Elapsed wall time: includes the time other processes held the CPUs.
    Wall,
    /// [`Times::cpu_ms`]: the calling thread's CPU time plus the other threads' over the
    /// worker count; time other processes held the CPUs is left out.
    #[default]
    Cpu,
}

impl Clock {
    pub fn name(self) -> &'static str {
        match self {
            Clock::Wall => "wall",
            Clock::Cpu => "cpu",
        }
    }
}

#[cfg(unix)]
fn clock_ns(id: libc::clockid_t) -> Option<u64> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; clock_gettime writes it or returns -1.
    let rc = unsafe { libc::clock_gettime(id, &mut ts) };
    (rc == 0).then(|| ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64)
}

/// Nanoseconds of CPU time every thread of this process has used (`CLOCK_PROCESS_CPUTIME_ID`);
/// `None` where the OS has no such clock.
pub fn process_ns() -> Option<u64> {
    #[cfg(unix)]
    {
        clock_ns(libc::CLOCK_PROCESS_CPUTIME_ID)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Nanoseconds of CPU time the calling thread has used (`CLOCK_THREAD_CPUTIME_ID`); `None`
/// where the OS has no such clock.
pub fn thread_ns() -> Option<u64> {
    #[cfg(unix)]
    {
        clock_ns(libc::CLOCK_THREAD_CPUTIME_ID)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// A span's start on the wall clock and both CPU clocks.
#[derive(Clone, Copy, Debug)]
pub struct Span {
    wall: Instant,
    process: Option<u64>,
    thread: Option<u64>,
}

/// What a [`Span`] measured, ms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Times {
    pub wall_ms: f64,
    /// The calling thread's CPU time plus the other threads' CPU time divided by `workers`:
    /// the span's length on an otherwise idle machine when the calling thread runs the serial
    /// host code and waits (asleep) while `workers` threads share the parallel work evenly.
    /// Time other processes held the CPUs is not in it; time the workers spin idle is.
    /// `None` without the CPU clocks.
    pub cpu_ms: Option<f64>,
}

impl Span {
    pub fn start() -> Span {
        Span {
            wall: Instant::now(),
            process: process_ns(),
            thread: thread_ns(),
        }
    }

    /// The process's and the calling thread's CPU time since [`Span::start`], ns; `None`
    /// without the CPU clocks. Must be called on the thread that started the span.
    pub fn cpu_ns(&self) -> Option<(f64, f64)> {
        let (p0, t0, p1, t1) = (self.process?, self.thread?, process_ns()?, thread_ns()?);
        Some((p1.saturating_sub(p0) as f64, t1.saturating_sub(t0) as f64))
    }

    /// The times since [`Span::start`], the parallel work spread over `workers` threads (at
    /// least 1; [`spread_ms`]). Must be called on the thread that started the span.
    pub fn elapsed(&self, workers: usize) -> Times {
        let wall_ms = self.wall.elapsed().as_secs_f64() * 1e3;
        let cpu_ms = self
            .cpu_ns()
            .map(|(process, own)| spread_ms(process, own, workers));
        Times { wall_ms, cpu_ms }
    }
}

/// The makespan of `tasks` (durations, in order) on `workers` identical workers by list
/// scheduling: each task in turn goes to the worker free first (Graham, "Bounds for certain
/// multiprocessing anomalies", 1966; within 2 − 1/workers of the optimum). The idle-machine
/// time of a step whose tasks took these CPU times, whichever threads ran them under load.
/// 0 for no tasks; `workers` below 1 counts as 1.
pub fn list_schedule(tasks: &[f64], workers: usize) -> f64 {
    let mut free = vec![0.0f64; workers.max(1)];
    for &t in tasks {
        let first = free
            .iter_mut()
            .min_by(|a, b| a.total_cmp(b))
            .expect("at least one worker");
        *first += t;
    }
    free.into_iter().fold(0.0, f64::max)
}

/// `own + (process − own) / workers` in ms, from ns: the calling thread's CPU time in full (the
/// serial host code) and the other threads' spread over `workers` (at least 1). The process
/// time counts as at least the caller's.
pub fn spread_ms(process_ns: f64, own_ns: f64, workers: usize) -> f64 {
    (own_ns + (process_ns - own_ns).max(0.0) / workers.max(1) as f64) * 1e-6
}

/// How loaded the host was while this process ran: a snapshot to difference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Load {
    /// The 1-minute load average (`/proc/loadavg`).
    pub load_average: Option<f64>,
    /// Nanoseconds this process's threads have been runnable but waiting for a CPU, summed
    /// (`/proc/self/task/*/schedstat`, second field; threads that ended are not counted).
    pub waited_ns: Option<u64>,
    /// Nanoseconds of CPU time of this process ([`process_ns`]).
    pub on_cpu_ns: Option<u64>,
}

impl Load {
    pub fn now() -> Load {
        Load {
            load_average: load_average(),
            waited_ns: waited_ns(),
            on_cpu_ns: process_ns(),
        }
    }

    /// The time this process's threads waited for a CPU since `earlier`, in percent of the CPU
    /// time they used: about 0 on an idle machine, 100 when each runnable thread got the CPU
    /// half the time. `None` without the sources or without CPU time used.
    pub fn waited_pct_since(&self, earlier: &Load) -> Option<f64> {
        let waited = self.waited_ns?.checked_sub(earlier.waited_ns?)?;
        let used = self.on_cpu_ns?.checked_sub(earlier.on_cpu_ns?)?;
        (used > 0).then(|| 100.0 * waited as f64 / used as f64)
    }
}

/// The waiting share ([`Load::waited_pct_since`]) above which a measurement counts as made on a
/// loaded machine, percent: the threads waited for a CPU more than a tenth of the time they ran.
pub const LOADED_WAITED_PCT: f64 = 10.0;

/// A warning when the host was loaded between `start` and `end` (threads waited above
/// [`LOADED_WAITED_PCT`], or a load average above `cpus`), naming the figures; `None` otherwise.
pub fn loaded_warning(start: &Load, end: &Load, cpus: u32, clock: Clock) -> Option<String> {
    let waited = end.waited_pct_since(start);
    let peak = match (start.load_average, end.load_average) {
        (Some(a), Some(b)) => Some(a.max(b)),
        (a, b) => a.or(b),
    };
    let busy =
        waited.is_some_and(|w| w > LOADED_WAITED_PCT) || peak.is_some_and(|l| l > f64::from(cpus));
    if !busy {
        return None;
    }
    let what = match clock {
        Clock::Cpu => {
            "measured in CPU time, which leaves out the time other processes held the CPUs \
             but not their use of the caches, memory bandwidth and the cores' other hardware \
             threads"
        }
        Clock::Wall => {
            "measured in wall time, which includes the time other processes held the CPUs"
        }
    };
    Some(format!(
        "warning: the host was loaded (load average {}, this process's threads waited for a \
         CPU {} of their CPU time; {cpus} CPUs): {what}",
        match (start.load_average, end.load_average) {
            (Some(a), Some(b)) => format!("{a:.2} at the start, {b:.2} at the end"),
            _ => "unknown".into(),
        },
        waited.map_or("an unknown share".into(), |w| format!("{w:.0}%")),
    ))
}

fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The sum of the run delays of this process's threads (`/proc/self/task/*/schedstat`).
fn waited_ns() -> Option<u64> {
    let mut total = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let path = task.ok()?.path().join("schedstat");
        // A thread that ended between the listing and the read waits no more.
        let Ok(text) = std::fs::read_to_string(path) else {
            continue;
        };
        total += text.split_whitespace().nth(1)?.parse::<u64>().ok()?;
    }
    Some(total)
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::time::Duration;

    /// Spins on the calling thread until its own CPU clock has advanced `ms`.
    fn spin_cpu(ms: f64) {
        let t0 = thread_ns().unwrap();
        let mut x = 0u64;
        while (thread_ns().unwrap() - t0) as f64 * 1e-6 < ms {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
    }

    // The process clock counts every thread of the test binary, other tests' included: the
    // tests below read the thread clock, or bound the process clock from below only.

    #[test]
    fn a_sleeping_thread_uses_no_cpu_time() {
        let s = Span::start();
        std::thread::sleep(Duration::from_millis(60));
        let t = s.elapsed(1);
        let (_, own) = s.cpu_ns().unwrap();
        assert!(t.wall_ms >= 60.0, "{t:?}");
        // Sleeping costs the thread a few microseconds of system time at most.
        assert!(own * 1e-6 < 5.0, "{own} ns");
    }

    #[test]
    fn one_thread_never_has_more_cpu_time_than_wall_time() {
        let s = Span::start();
        spin_cpu(30.0);
        let t = s.elapsed(1);
        let own = s.cpu_ns().unwrap().1 * 1e-6;
        assert!(own >= 30.0, "{own} ms");
        assert!(own <= t.wall_ms + 0.1, "{own} ms, {t:?}");
    }

    /// Two threads each spin 40 ms of their own CPU time while the calling thread waits: the
    /// process used at least 80 ms, and the calling thread itself (spawning and joining) well
    /// under 5 ms.
    #[test]
    fn the_process_clock_counts_the_other_threads_and_the_thread_clock_does_not() {
        let s = Span::start();
        std::thread::scope(|scope| {
            for _ in 0..2 {
                scope.spawn(|| spin_cpu(40.0));
            }
        });
        let (process, own) = s.cpu_ns().unwrap();
        assert!(process * 1e-6 >= 80.0, "{process} ns");
        assert!(own * 1e-6 < 5.0, "{own} ns");
    }

    #[test]
    fn the_estimate_keeps_the_callers_time_and_spreads_the_others() {
        // 100 ms of process CPU time, 20 of them the caller's, 2 workers: 20 + 80 / 2.
        assert!((spread_ms(100e6, 20e6, 2) - 60.0).abs() < 1e-9);
        assert!((spread_ms(100e6, 20e6, 1) - 100.0).abs() < 1e-9);
        // A process clock read before the thread clock can trail it by a few ns: never below
        // the caller's own time.
        assert!((spread_ms(19e6, 20e6, 2) - 20.0).abs() < 1e-9);
        assert!((spread_ms(10e6, 0.0, 0) - 10.0).abs() < 1e-9);
    }

    #[test]
    fn list_scheduling_matches_hand_computed_makespans() {
        // 3, 3, 2, 2, 2 on two workers in order: A 3, B 3, A 5, B 5, A 7.
        assert_eq!(list_schedule(&[3.0, 3.0, 2.0, 2.0, 2.0], 2), 7.0);
        // One long task last: the others spread first (1+1 | 1), then 4 on the second: 5.
        assert_eq!(list_schedule(&[1.0, 1.0, 1.0, 4.0], 2), 5.0);
        // One worker: the sum; more workers than tasks: the longest.
        assert_eq!(list_schedule(&[1.0, 2.0, 3.0], 1), 6.0);
        assert_eq!(list_schedule(&[1.0, 2.0, 3.0], 8), 3.0);
        assert_eq!(list_schedule(&[], 2), 0.0);
        assert_eq!(list_schedule(&[2.0], 0), 2.0);
    }

    #[test]
    fn the_waiting_share_is_the_difference_over_the_cpu_time_used() {
        let a = Load {
            load_average: Some(1.0),
            waited_ns: Some(1_000),
            on_cpu_ns: Some(10_000),
        };
        let b = Load {
            load_average: Some(3.5),
            waited_ns: Some(6_000),
            on_cpu_ns: Some(30_000),
        };
        assert_eq!(b.waited_pct_since(&a), Some(25.0));
        let w = loaded_warning(&a, &b, 2, Clock::Cpu).unwrap();
        assert!(
            w.contains("1.00 at the start, 3.50 at the end") && w.contains("25%"),
            "{w}"
        );
        // Idle: 5% waited, load under the CPU count.
        let c = Load {
            waited_ns: Some(2_000),
            load_average: Some(0.4),
            ..b
        };
        let a = Load {
            load_average: Some(0.3),
            ..a
        };
        assert_eq!(loaded_warning(&a, &c, 2, Clock::Cpu), None);
        assert_eq!(c.waited_pct_since(&c), None);
    }
}
