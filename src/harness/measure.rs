//! The measurement protocol of the measured figures (host wall time of every execution, GPU
//! time of wgpu runs), after criterion and hyperfine: the first iteration timed apart as the
//! cold one (`cold_wall_ms`, `cold_gpu_ms`: first use of code, caches and the driver's shader
//! compilation), further warm-up iterations untimed, then timed iterations of the same frame
//! (pipelines and buffers reused as in a sweep) within a time budget. Every sample is kept with
//! its median, minimum, median absolute deviation and a 95% confidence interval of the median
//! from order statistics; counters, modelled figures and images must be identical across
//! iterations (a difference is flagged, never averaged). The conditions of the measurement
//! (load, CPU, threads, build) are recorded with it ([`conditions`]).

use serde::{Deserialize, Serialize};

use crate::error::InputError;

/// How a run is measured: the scenario's `measure` field, or `--warmup`, `--repeats`,
/// `--min-time` and `--max-time` of `run` and `render`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Measure {
    /// Iterations before the timed ones; the first of them is timed apart as the cold
    /// iteration. 0: the first timed iteration is the cold one, with no figure apart.
    pub warmup: u32,
    /// Timed iterations wanted (at least 1).
    pub repeats: u32,
    /// Seconds: timed iterations go on past `repeats` until they took this long in all
    /// (bounded by `max_time_s`).
    pub min_time_s: f64,
    /// Seconds: no timed iteration starts once the timed ones took this long in all (at least
    /// one always runs). Bounds a long run's protocol to about its cold iteration and one
    /// sample.
    pub max_time_s: f64,
}

impl Default for Measure {
    /// Sized for a sweep on 2 cores: one cold iteration, then up to 5 timed ones within 1 s.
    fn default() -> Self {
        Measure {
            warmup: 1,
            repeats: 5,
            min_time_s: 0.0,
            max_time_s: 1.0,
        }
    }
}

impl Measure {
    /// One timed iteration, nothing before it: the protocol of a run before this one existed
    /// (and of library callers that time nothing, `ExecContext::default()`).
    pub const ONCE: Measure = Measure {
        warmup: 0,
        repeats: 1,
        min_time_s: 0.0,
        max_time_s: 0.0,
    };

    /// Checks every field; `prefix` names where they came from (`measure` in a scenario,
    /// `--` on the command line).
    pub fn check(&self, prefix: &str) -> Result<(), InputError> {
        let name = |f: &str| {
            if prefix == "--" {
                format!("--{}", f.replace('_', "-").trim_end_matches("-s"))
            } else {
                format!("{prefix}.{f}")
            }
        };
        if self.warmup > 1000 {
            return Err(InputError::new(
                name("warmup"),
                format!("expected 0 to 1000 iterations, got {}", self.warmup),
            ));
        }
        if !(1..=100_000).contains(&self.repeats) {
            return Err(InputError::new(
                name("repeats"),
                format!("expected 1 to 100000 iterations, got {}", self.repeats),
            ));
        }
        for (field, v) in [
            ("min_time_s", self.min_time_s),
            ("max_time_s", self.max_time_s),
        ] {
            if !(v.is_finite() && (0.0..=86_400.0).contains(&v)) {
                return Err(InputError::new(
                    name(field),
                    format!("expected seconds in 0..=86400, got {v}"),
                ));
            }
        }
        if self.min_time_s > self.max_time_s && self.max_time_s > 0.0 {
            return Err(InputError::new(
                name("min_time_s"),
                format!(
                    "{} s is above max_time_s {} s",
                    self.min_time_s, self.max_time_s
                ),
            ));
        }
        Ok(())
    }

    /// Whether a timed iteration starts after `n` of them took `spent_s` seconds in all.
    pub fn another(&self, n: u32, spent_s: f64) -> bool {
        if n == 0 {
            return true;
        }
        let budget = self.max_time_s.max(self.min_time_s);
        if budget > 0.0 && spent_s >= budget {
            return false;
        }
        n < self.repeats || spent_s < self.min_time_s
    }
}

/// Fields of a [`Measure`] set on the command line, each overriding the scenario's.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Overrides {
    pub warmup: Option<u32>,
    pub repeats: Option<u32>,
    pub min_time_s: Option<f64>,
    pub max_time_s: Option<f64>,
}

impl Overrides {
    /// `base` with the fields given here replaced, checked (errors name the flags).
    pub fn apply(&self, base: Measure) -> Result<Measure, InputError> {
        let m = Measure {
            warmup: self.warmup.unwrap_or(base.warmup),
            repeats: self.repeats.unwrap_or(base.repeats),
            min_time_s: self.min_time_s.unwrap_or(base.min_time_s),
            max_time_s: self.max_time_s.unwrap_or(base.max_time_s),
        };
        m.check("--")?;
        Ok(m)
    }
}

/// Samples of one measured figure and their statistics, in milliseconds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// Every timed sample, in the order taken.
    pub samples: Vec<f64>,
    pub median: f64,
    pub min: f64,
    /// Median absolute deviation from the median (unscaled).
    pub mad: f64,
    /// Confidence interval of the median from order statistics (distribution-free: the
    /// samples of ranks k and n+1−k, k the largest rank whose binomial tail is within 2.5%).
    pub ci: [f64; 2],
    /// The interval's coverage: ≥ 0.95 from 6 samples on; below that it is [min, max], whose
    /// coverage is 1 − 2^(1−n) (0 for one sample).
    pub ci_level: f64,
}

/// The median of sorted values.
fn median_sorted(v: &[f64]) -> f64 {
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// P(B ≤ k) for B ~ Binomial(n, 1/2).
fn binomial_half_cdf(n: usize, k: usize) -> f64 {
    // Sum of C(n, i) / 2^n in logs, exact enough for n up to 10^5.
    let ln_half_n = -(n as f64) * std::f64::consts::LN_2;
    let mut ln_c = 0.0; // ln C(n, 0)
    let mut sum = 0.0;
    for i in 0..=k.min(n) {
        if i > 0 {
            ln_c += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        sum += (ln_c + ln_half_n).exp();
    }
    sum.min(1.0)
}

impl Spread {
    /// The statistics of `samples` (milliseconds); `None` when there are none or one is not
    /// finite.
    pub fn of(samples: Vec<f64>) -> Option<Spread> {
        if samples.is_empty() || samples.iter().any(|s| !s.is_finite()) {
            return None;
        }
        let mut sorted = samples.clone();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len();
        let median = median_sorted(&sorted);
        let mut dev: Vec<f64> = sorted.iter().map(|s| (s - median).abs()).collect();
        dev.sort_by(f64::total_cmp);
        // The largest rank k (1-based) with P(B ≤ k − 1) ≤ 0.025: [x_k, x_{n+1−k}] covers the
        // median with probability 1 − 2 P(B ≤ k − 1).
        let mut k = 1;
        while k < n.div_ceil(2) && binomial_half_cdf(n, k) <= 0.025 {
            k += 1;
        }
        let tail = binomial_half_cdf(n, k - 1);
        Some(Spread {
            median,
            min: sorted[0],
            mad: median_sorted(&dev),
            ci: [sorted[k - 1], sorted[n - k]],
            ci_level: (1.0 - 2.0 * tail).max(0.0),
            samples,
        })
    }

    /// Half the interval's width over the median (0.05: ±5%).
    pub fn relative_half_width(&self) -> f64 {
        if self.median > 0.0 {
            (self.ci[1] - self.ci[0]) / 2.0 / self.median
        } else {
            0.0
        }
    }
}

/// The relative half-width of a median's interval above which a measured figure carries a
/// warning (10%).
pub const WIDE_INTERVAL: f64 = 0.10;

/// The measured figures of one phase.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhaseSpread {
    pub name: String,
    pub wall_ms: Spread,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gpu_ms: Option<Spread>,
}

/// What the protocol measured for a run (`RunRecord::measured`): its settings, the timed
/// samples of the run and of each phase, and whether every iteration gave the same counters,
/// modelled times and image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Measured {
    pub protocol: Measure,
    /// Timed iterations (the samples of each figure).
    pub iterations: u32,
    /// Untimed warm-up iterations run after the cold one.
    pub warmup_runs: u32,
    pub wall_ms: Spread,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gpu_ms: Option<Spread>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub phases: Vec<PhaseSpread>,
    /// Whether every iteration's counters, modelled times and image equalled the first's.
    pub identical: bool,
    /// What makes the measured figures doubtful: a loaded machine, a wide interval, iterations
    /// that differ or failed ([`warnings`]). Kept here, apart from the run's warnings about its
    /// result.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// The conditions of a measurement (`execution.conditions`): load average (1, 5, 15 minutes)
/// before and after, CPU model and frequency governor, logical cores and host threads, the
/// build (commit, profile). The adapter and driver of wgpu runs are in `execution.adapter`.
pub fn conditions(
    load_before: Option<[f64; 3]>,
    load_after: Option<[f64; 3]>,
) -> serde_json::Value {
    serde_json::json!({
        "load_before": load_before,
        "load_after": load_after,
        "cpu_model": cpu_model(),
        "cpu_governor": std::fs::read_to_string("/sys/devices/system/cpu/cpu0/cpufreq/scaling_governor")
            .ok()
            .map(|s| s.trim().to_string()),
        "cores": cores(),
        "host_threads": rayon::current_num_threads(),
        "commit": crate::build::COMMIT,
        "build_profile": crate::build::PROFILE,
    })
}

/// Logical cores of the machine.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The load averages of `/proc/loadavg` (1, 5, 15 minutes); `None` where there is none.
pub fn load_average() -> Option<[f64; 3]> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    let mut it = text.split_whitespace().map(|v| v.parse::<f64>().ok());
    Some([it.next()??, it.next()??, it.next()??])
}

fn cpu_model() -> Option<String> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    text.lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, v)| v.trim().to_string())
}

/// The warnings of a measurement: those it has (a failed iteration), a machine loaded above its
/// core count before or after, a median whose interval is wider than ±[`WIDE_INTERVAL`], and
/// iterations whose output differs.
pub fn warnings(m: &Measured, load: [Option<[f64; 3]>; 2]) -> Vec<String> {
    let mut w = m.warnings.clone();
    let cores = cores() as f64;
    let loads: Vec<f64> = load.iter().flatten().map(|l| l[0]).collect();
    if loads.iter().any(|&l| l > cores) {
        w.push(format!(
            "measured on a loaded machine: load average {} (before, after) over {cores} cores; \
             its measured times are not comparable",
            loads
                .iter()
                .map(|l| format!("{l:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let figures = [("wall_ms", Some(&m.wall_ms)), ("gpu_ms", m.gpu_ms.as_ref())];
    for (name, s) in figures {
        let Some(s) = s else { continue };
        if s.samples.len() > 1 && s.relative_half_width() > WIDE_INTERVAL {
            w.push(format!(
                "wide interval: {name} median {:.3} ms, {:.0}% interval [{:.3}, {:.3}] is ±{:.0}% \
                 of it ({} samples)",
                s.median,
                s.ci_level * 100.0,
                s.ci[0],
                s.ci[1],
                s.relative_half_width() * 100.0,
                s.samples.len()
            ));
        }
    }
    if !m.identical {
        w.push(
            "iterations differ: counters, modelled times or image of a timed iteration are not \
             the first's; the figures are the first iteration's"
                .into(),
        );
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_mad_and_order_statistic_interval() {
        let s = Spread::of(vec![5.0, 1.0, 4.0, 2.0, 3.0]).unwrap();
        assert_eq!((s.median, s.min, s.mad), (3.0, 1.0, 1.0));
        // Five samples: no 95% interval exists; [min, max] covers 1 − 2/32.
        assert_eq!(s.ci, [1.0, 5.0]);
        assert!((s.ci_level - (1.0 - 2.0 / 32.0)).abs() < 1e-12);
        // Ten samples: ranks 2 and 9 (P(B ≤ 1) = 11/1024 ≤ 0.025 < P(B ≤ 2) = 56/1024).
        let s = Spread::of((1..=10).map(f64::from).collect()).unwrap();
        assert_eq!(s.median, 5.5);
        assert_eq!(s.ci, [2.0, 9.0]);
        assert!((s.ci_level - (1.0 - 22.0 / 1024.0)).abs() < 1e-12);
        // One sample: an interval of no coverage.
        let s = Spread::of(vec![7.0]).unwrap();
        assert_eq!((s.ci, s.ci_level), ([7.0, 7.0], 0.0));
        assert!(Spread::of(vec![]).is_none() && Spread::of(vec![1.0, f64::NAN]).is_none());
    }

    #[test]
    fn the_binomial_tail_matches_its_sum() {
        assert!((binomial_half_cdf(10, 1) - 11.0 / 1024.0).abs() < 1e-12);
        assert!((binomial_half_cdf(20, 5) - 21700.0 / 1048576.0).abs() < 1e-12);
        assert!((binomial_half_cdf(7, 7) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_budget_bounds_the_timed_iterations() {
        let m = Measure::default();
        assert!(m.another(0, 100.0));
        assert!(m.another(4, 0.1) && !m.another(5, 0.1));
        assert!(!m.another(1, 1.0));
        let m = Measure {
            min_time_s: 0.5,
            ..Measure::default()
        };
        assert!(m.another(7, 0.4) && !m.another(7, 0.5));
        assert!(!Measure::ONCE.another(1, 0.0));
    }

    #[test]
    fn bad_settings_name_their_field() {
        let bad = Measure {
            repeats: 0,
            ..Measure::default()
        };
        let e = bad.check("measure").unwrap_err().to_string();
        assert!(e.contains("measure.repeats") && e.contains("got 0"), "{e}");
        let e = bad.check("--").unwrap_err().to_string();
        assert!(e.contains("--repeats"), "{e}");
        let bad = Measure {
            max_time_s: f64::NAN,
            ..Measure::default()
        };
        let e = bad.check("--").unwrap_err().to_string();
        assert!(e.contains("--max-time") && e.contains("NaN"), "{e}");
        assert!(Measure::default().check("measure").is_ok() && Measure::ONCE.check("--").is_ok());
    }
}
