//! The comparison of measured figures (kind `measured` in the glossary: `wall_ms`, `gpu_ms`)
//! between two result sets, run by run, on their samples ([`crate::harness::measure`]).
//!
//! Each figure of each run is tested twice, and flagged only when both tests find it changed:
//!
//! - **Against its own samples**: a two-sided Mann–Whitney U test (exact distribution without
//!   ties for up to 50 samples a side, else the normal approximation with tie correction). The
//!   samples of one run are taken within milliseconds of each other, so this test sees the
//!   noise inside a sitting only.
//! - **Against the noise between sittings** ([`SittingNoise`]): the log ratio of medians
//!   `d = ln(current / baseline)` of every run of the comparison, fitted by the variance model
//!   `σ(t)² = σ₀² + β / t` (`t` the run's median time in ms: a fixed relative noise `σ₀` and
//!   interruptions whose count grows with the run's length) by trimmed maximum likelihood
//!   (the best-fitting 80% of the figures; Neykov and Müller 2003, after Rousseeuw's least
//!   trimmed squares 1984), so the runs that really changed do not widen it. The figure's
//!   p-value is the two-sided tail of `d / σ(t)` in Student's t with 3 degrees of freedom,
//!   whose heavy tails allow for the occasional run a whole sitting's state slowed down (on
//!   this project's two-core machine one figure in nine of an unchanged sweep lies beyond
//!   three fitted σ; docs/ci.md).
//!
//! The figure's p-value is the larger of the two (an intersection–union test), adjusted by the
//! Benjamini–Hochberg procedure over every test of the comparison, so a sweep of many runs
//! does not raise false alarms by their number (after Google Benchmark's `compare.py` and asv).
//! A figure is flagged when its adjusted p-value is at most `q` and its medians differ by at
//! least the minimum effect (in percent; per figure with `--threshold-for`).
//!
//! No maintained crate offers the Mann–Whitney test with its exact distribution, so it is
//! written here and tested against tabulated values; the t and normal tails are `statrs`'s.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use crate::record::RunRecord;

/// The default false-discovery rate of the Benjamini–Hochberg procedure.
pub const DEFAULT_Q: f64 = 0.05;
/// The default minimum effect, in percent of the baseline median.
pub const DEFAULT_MIN_EFFECT_PCT: f64 = 10.0;

/// The measured figures of a run with their samples (run level: `wall_ms`, `gpu_ms`).
pub fn measured_samples(r: &RunRecord) -> BTreeMap<String, Vec<f64>> {
    let mut f = BTreeMap::new();
    if r.failure.is_some() {
        return f;
    }
    if let Some(m) = &r.measured {
        f.insert("wall_ms".to_string(), m.wall_ms.samples.clone());
        if let Some(g) = &m.gpu_ms {
            f.insert("gpu_ms".to_string(), g.samples.clone());
        }
    }
    f.retain(|name, _| crate::counters::kind(name) == Some(crate::counters::Kind::Measured));
    f
}

/// ln C(n, k).
fn ln_choose(n: usize, k: usize) -> f64 {
    (1..=k).map(|i| ((n - k + i) as f64 / i as f64).ln()).sum()
}

/// The Mann–Whitney U statistic of `a` against `b` (ties count a half) and its two-sided
/// p-value.
pub fn mann_whitney(a: &[f64], b: &[f64]) -> (f64, f64) {
    let (m, n) = (a.len(), b.len());
    if m == 0 || n == 0 {
        return (0.0, 1.0);
    }
    let mut u = 0.0;
    for x in a {
        for y in b {
            u += if x > y {
                1.0
            } else if x == y {
                0.5
            } else {
                0.0
            };
        }
    }
    let mut all: Vec<f64> = a.iter().chain(b).copied().collect();
    all.sort_by(f64::total_cmp);
    let ties = all.windows(2).any(|w| w[0] == w[1]);
    let p = if !ties && m <= 50 && n <= 50 {
        // Exact: the count of arrangements giving each U, by the recursion
        // c(m, n, u) = c(m − 1, n, u − n) + c(m, n − 1, u).
        let max = m * n;
        let mut table = vec![vec![0f64; max + 1]; n + 1]; // table[j][u] for the current i
        for row in table.iter_mut() {
            row[0] = 1.0;
        }
        for i in 1..=m {
            let mut next = vec![vec![0f64; max + 1]; n + 1];
            next[0][0] = 1.0;
            for j in 1..=n {
                for v in 0..=i * j {
                    let with_x_last = if v >= j { table[j][v - j] } else { 0.0 };
                    next[j][v] = with_x_last + next[j - 1][v];
                }
            }
            table = next;
        }
        let counts = &table[n];
        let total = ln_choose(m + n, m).exp();
        let k = u as usize;
        let lower: f64 = counts[..=k].iter().sum::<f64>() / total;
        let upper: f64 = counts[k..].iter().sum::<f64>() / total;
        (2.0 * lower.min(upper)).min(1.0)
    } else {
        // Normal approximation with the tie correction of the variance.
        let (mf, nf) = (m as f64, n as f64);
        let mut tie_term = 0.0;
        let mut i = 0;
        while i < all.len() {
            let mut j = i;
            while j + 1 < all.len() && all[j + 1] == all[i] {
                j += 1;
            }
            let t = (j - i + 1) as f64;
            tie_term += t * t * t - t;
            i = j + 1;
        }
        let nn = mf + nf;
        let var = mf * nf / 12.0 * ((nn + 1.0) - tie_term / (nn * (nn - 1.0)));
        if var <= 0.0 {
            1.0
        } else {
            let z = ((u - mf * nf / 2.0).abs() - 0.5).max(0.0) / var.sqrt();
            (2.0 * normal_upper_tail(z)).min(1.0)
        }
    };
    (u, p)
}

/// P(Z > z) for a standard normal Z.
fn normal_upper_tail(z: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal};
    Normal::standard().sf(z)
}

/// The smallest two-sided p-value the exact test can give with `m` and `n` samples.
pub fn smallest_p(m: usize, n: usize) -> f64 {
    if m == 0 || n == 0 {
        1.0
    } else {
        (2.0 / ln_choose(m + n, m).exp()).min(1.0)
    }
}

/// Benjamini–Hochberg adjusted p-values (q-values), in the order of `p`.
pub fn benjamini_hochberg(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut q = vec![1.0; m];
    let mut running: f64 = 1.0;
    for (rank, &i) in order.iter().enumerate().rev() {
        running = running.min(p[i] * m as f64 / (rank + 1) as f64);
        q[i] = running.min(1.0);
    }
    q
}

/// The smallest number of a figure's runs from which the noise between sittings is fitted.
pub const MIN_RUNS_FOR_SITTING_NOISE: usize = 8;
/// The share of the figures the trimmed fit keeps.
const TRIM_KEEP: f64 = 0.8;
/// Degrees of freedom of the t distribution of the test against the sittings' noise.
const SITTING_DOF: f64 = 3.0;

/// The noise between two sittings of one measured figure: the standard deviation of
/// `ln(current / baseline)` of a run whose median time is `t` ms is
/// `σ(t) = sqrt(σ₀² + β / t)`, fitted over the comparison's runs by trimmed maximum likelihood
/// (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SittingNoise {
    /// The relative noise of long runs, `σ₀` (dimensionless, of the log ratio).
    pub sigma0: f64,
    /// The noise term of short runs, `β`, in ms.
    pub beta_ms: f64,
}

impl SittingNoise {
    /// Fits the model to `(d, t)` pairs (log ratio of medians, median time in ms); `None` with
    /// fewer than [`MIN_RUNS_FOR_SITTING_NOISE`] usable pairs. The fit is a search over a
    /// logarithmic grid (σ₀ from 1e-4 to 2, β from 1e-8 to 1 ms), so it is deterministic.
    pub fn fit(pairs: &[(f64, f64)]) -> Option<SittingNoise> {
        let pairs: Vec<(f64, f64)> = pairs
            .iter()
            .copied()
            .filter(|(d, t)| d.is_finite() && t.is_finite() && *t > 0.0)
            .collect();
        if pairs.len() < MIN_RUNS_FOR_SITTING_NOISE {
            return None;
        }
        let keep = ((pairs.len() as f64 * TRIM_KEEP).ceil() as usize).min(pairs.len());
        let grid = |lo: f64, hi: f64, n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
                .collect()
        };
        let mut best: Option<(f64, SittingNoise)> = None;
        let mut ll = Vec::with_capacity(pairs.len());
        for &sigma0 in &grid(1e-4, 2.0, 64) {
            for &beta_ms in &grid(1e-8, 1.0, 64) {
                let model = SittingNoise { sigma0, beta_ms };
                ll.clear();
                ll.extend(pairs.iter().map(|&(d, t)| {
                    let s = model.sigma(t);
                    -0.5 * (d / s) * (d / s) - s.ln()
                }));
                ll.sort_by(|a, b| b.total_cmp(a));
                let total: f64 = ll[..keep].iter().sum();
                if best.is_none_or(|(b, _)| total > b) {
                    best = Some((total, model));
                }
            }
        }
        best.map(|(_, m)| m)
    }

    /// σ(t) of a run of median time `t_ms`.
    pub fn sigma(&self, t_ms: f64) -> f64 {
        (self.sigma0 * self.sigma0 + self.beta_ms / t_ms).sqrt()
    }

    fn t() -> statrs::distribution::StudentsT {
        statrs::distribution::StudentsT::new(0.0, 1.0, SITTING_DOF).expect("valid t distribution")
    }

    /// Two-sided p-value of a log ratio `d` of a run of median time `t_ms`.
    pub fn p_value(&self, d: f64, t_ms: f64) -> f64 {
        use statrs::distribution::ContinuousCDF;
        (2.0 * Self::t().sf((d / self.sigma(t_ms)).abs())).min(1.0)
    }

    /// The smallest ratio of medians of a run of median time `t_ms` that passes the
    /// correction alone among `tests` tests at false-discovery rate `q` (the first rank of the
    /// Benjamini–Hochberg procedure, `p ≤ q / tests`).
    pub fn smallest_lone_ratio(&self, t_ms: f64, q: f64, tests: usize) -> f64 {
        use statrs::distribution::ContinuousCDF;
        let z = Self::t().inverse_cdf(1.0 - q / (2.0 * tests.max(1) as f64));
        (z * self.sigma(t_ms)).exp()
    }
}

/// One measured figure of one run, tested.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredChange {
    pub case: String,
    pub figure: String,
    pub old_median: f64,
    pub new_median: f64,
    pub samples: [usize; 2],
    pub u: f64,
    /// Two-sided p-value of the Mann–Whitney test on the samples.
    pub p_samples: f64,
    /// Two-sided p-value against the noise between sittings (1 where none was fitted).
    pub p_sittings: f64,
    /// The larger of the two: the figure's p-value.
    pub p: f64,
    /// Benjamini–Hochberg adjusted p-value over every test of the comparison.
    pub q: f64,
    /// The minimum effect that applied, in percent.
    pub min_effect_pct: f64,
}

impl MeasuredChange {
    /// The ratio of medians, current over baseline.
    pub fn ratio(&self) -> f64 {
        self.new_median / self.old_median
    }

    /// What [`SittingNoise`] is fitted to and tests: the log ratio of medians and the run's
    /// typical time (the geometric mean of the two medians), ms.
    fn between_sittings(&self) -> (f64, f64) {
        (
            self.ratio().ln(),
            (self.old_median * self.new_median).sqrt(),
        )
    }

    /// Whether the change is significant after the correction and at least the minimum
    /// effect.
    pub fn flagged(&self, q: f64) -> bool {
        self.q <= q && ((self.ratio() - 1.0).abs() * 100.0 >= self.min_effect_pct)
    }

    /// Flagged and in the worse direction of the glossary.
    pub fn regressed(&self, q: f64) -> bool {
        let worse = match crate::counters::direction(&self.figure) {
            Some(crate::counters::Direction::Higher) => self.ratio() < 1.0,
            _ => self.ratio() > 1.0,
        };
        self.flagged(q) && worse
    }
}

/// The measured comparison of a whole result set.
#[derive(Clone, Debug, Default)]
pub struct MeasuredComparison {
    pub q: f64,
    pub tests: Vec<MeasuredChange>,
    /// The noise between sittings fitted per figure (absent where too few runs had it).
    pub noise: BTreeMap<String, SittingNoise>,
    /// Runs compared by their deterministic figures that carry no samples in one of the files.
    pub without_samples: usize,
}

impl MeasuredComparison {
    /// Tests every measured figure of the runs `pairs` (case, baseline, current) holds;
    /// `min_effect` gives the minimum effect in percent of a figure.
    pub fn of<'a>(
        pairs: impl IntoIterator<Item = (&'a str, &'a RunRecord, &'a RunRecord)>,
        q: f64,
        min_effect: impl Fn(&str) -> f64,
    ) -> MeasuredComparison {
        let mut c = MeasuredComparison {
            q,
            ..Default::default()
        };
        for (case, o, n) in pairs {
            let (so, sn) = (measured_samples(o), measured_samples(n));
            if so.is_empty() || sn.is_empty() {
                c.without_samples += 1;
                continue;
            }
            for (figure, a) in &so {
                let Some(b) = sn.get(figure) else { continue };
                let med = |v: &[f64]| {
                    crate::harness::measure::Spread::of(v.to_vec()).map_or(f64::NAN, |s| s.median)
                };
                let (u, p) = mann_whitney(b, a);
                c.tests.push(MeasuredChange {
                    case: case.to_string(),
                    figure: figure.clone(),
                    old_median: med(a),
                    new_median: med(b),
                    samples: [a.len(), b.len()],
                    u,
                    p_samples: p,
                    p_sittings: 1.0,
                    p,
                    q: 1.0,
                    min_effect_pct: min_effect(figure),
                });
            }
        }
        let figures: std::collections::BTreeSet<String> =
            c.tests.iter().map(|t| t.figure.clone()).collect();
        for figure in figures {
            let pairs: Vec<(f64, f64)> = c
                .tests
                .iter()
                .filter(|t| t.figure == figure)
                .map(MeasuredChange::between_sittings)
                .collect();
            if let Some(noise) = SittingNoise::fit(&pairs) {
                for t in c.tests.iter_mut().filter(|t| t.figure == figure) {
                    let (d, t_ms) = t.between_sittings();
                    t.p_sittings = noise.p_value(d, t_ms);
                    t.p = t.p_samples.max(t.p_sittings);
                }
                c.noise.insert(figure, noise);
            }
        }
        let adjusted = benjamini_hochberg(&c.tests.iter().map(|t| t.p).collect::<Vec<_>>());
        for (t, q) in c.tests.iter_mut().zip(adjusted) {
            t.q = q;
        }
        c
    }

    pub fn regressions(&self) -> usize {
        self.tests.iter().filter(|t| t.regressed(self.q)).count()
    }

    /// The table of flagged figures and the line that sums up.
    pub fn render(&self) -> String {
        let mut s = String::new();
        if self.tests.is_empty() && self.without_samples == 0 {
            return s;
        }
        let flagged: Vec<&MeasuredChange> =
            self.tests.iter().filter(|t| t.flagged(self.q)).collect();
        if !flagged.is_empty() {
            let _ = writeln!(
                s,
                "{:<8}  {:<60}  {:<8}  {:>12}  {:>12}  {:>8}  {:>9}  {:>9}  {:>9}",
                "measured",
                "run",
                "figure",
                "baseline",
                "current",
                "ratio",
                "p samples",
                "p sittings",
                "q"
            );
            for t in &flagged {
                let _ = writeln!(
                    s,
                    "{:<8}  {:<60}  {:<8}  {:>12}  {:>12}  {:>7.3}×  {:>9.2e}  {:>10.2e}  {:>9.2e}",
                    if t.regressed(self.q) {
                        "SLOWER"
                    } else {
                        "faster"
                    },
                    t.case,
                    t.figure,
                    format!("{:.3} ms", t.old_median),
                    format!("{:.3} ms", t.new_median),
                    t.ratio(),
                    t.p_samples,
                    t.p_sittings,
                    t.q
                );
            }
        }
        let min_n = self
            .tests
            .iter()
            .map(|t| t.samples[0].min(t.samples[1]))
            .min()
            .unwrap_or(0);
        let _ = writeln!(
            s,
            "measured: {} figures of {} runs tested (Mann–Whitney U on the samples and against the \
             noise between sittings, Benjamini–Hochberg q ≤ {}); \
             {} slower, {} faster beyond their minimum effect; {} runs without samples",
            self.tests.len(),
            self.tests
                .iter()
                .map(|t| &t.case)
                .collect::<std::collections::BTreeSet<_>>()
                .len(),
            self.q,
            self.regressions(),
            flagged.len() - self.regressions(),
            self.without_samples
        );
        let figures: std::collections::BTreeSet<&str> =
            self.tests.iter().map(|t| t.figure.as_str()).collect();
        for figure in figures {
            match self.noise.get(figure) {
                Some(n) => {
                    let _ = writeln!(
                        s,
                        "noise between sittings of {figure} (fitted over this comparison): \
                         σ {:.1}% at 1 ms, {:.1}% at 10 ms, {:.1}% at 100 ms; a lone run's \
                         change is flagged from ×{:.2}, ×{:.2}, ×{:.2}",
                        100.0 * n.sigma(1.0),
                        100.0 * n.sigma(10.0),
                        100.0 * n.sigma(100.0),
                        n.smallest_lone_ratio(1.0, self.q, self.tests.len()),
                        n.smallest_lone_ratio(10.0, self.q, self.tests.len()),
                        n.smallest_lone_ratio(100.0, self.q, self.tests.len())
                    );
                }
                None => {
                    let _ = writeln!(
                        s,
                        "note: fewer than {MIN_RUNS_FOR_SITTING_NOISE} runs have {figure}: \
                         tested on their samples only, which do not see the noise between \
                         sittings"
                    );
                }
            }
        }
        if !self.tests.is_empty() && smallest_p(min_n, min_n) * self.tests.len() as f64 > self.q {
            let _ = writeln!(
                s,
                "note: with {min_n} samples a side the smallest p-value is {:.1e}: a lone change \
                 among {} tests cannot pass the correction; measure with more --repeats",
                smallest_p(min_n, min_n),
                self.tests.len()
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mann_whitney_matches_tabulated_exact_values() {
        // Complete separation, 5 against 5: p = 2 / C(10, 5) = 2/252.
        let a = [1.0, 2.0, 3.0, 4.0, 5.0];
        let b = [6.0, 7.0, 8.0, 9.0, 10.0];
        let (u, p) = mann_whitney(&b, &a);
        assert_eq!(u, 25.0);
        assert!((p - 2.0 / 252.0).abs() < 1e-12, "{p}");
        assert!((mann_whitney(&a, &b).1 - p).abs() < 1e-12);
        // 3 against 4:
        let (u, p) = mann_whitney(&[1.0, 2.0, 5.0], &[3.0, 4.0, 6.0, 7.0]);
        assert_eq!(u, 2.0);
        // U = 2: counts of U = 0, 1, 2 are 1, 1, 2: P(U ≤ 2) = 4/35, two-sided 8/35.
        assert!((p - 8.0 / 35.0).abs() < 1e-12, "{p}");
        // Interleaved samples: no evidence.
        let (_, p) = mann_whitney(&[1.0, 3.0, 5.0, 7.0], &[2.0, 4.0, 6.0, 8.0]);
        assert!(p > 0.5, "{p}");
        assert!((smallest_p(5, 5) - 2.0 / 252.0).abs() < 1e-12);
    }

    #[test]
    fn the_normal_approximation_agrees_with_the_exact_test_for_large_samples() {
        // 60 against 60 shifted by a third of the range, with ties: normal approximation.
        let a: Vec<f64> = (0..60).map(|i| (i / 2) as f64).collect();
        let b: Vec<f64> = (0..60).map(|i| (i / 2) as f64 + 10.0).collect();
        let (_, p) = mann_whitney(&b, &a);
        assert!(p < 1e-3 && p > 1e-12, "{p}");
        assert!((normal_upper_tail(1.959_964) - 0.025).abs() < 1e-6);
        assert!((normal_upper_tail(0.0) - 0.5).abs() < 1e-7);
    }

    #[test]
    fn benjamini_hochberg_matches_its_definition() {
        // p sorted: 0.01, 0.02, 0.03, 0.5 of m = 4: q = min over ranks ≥ i of p·m/rank.
        let q = benjamini_hochberg(&[0.03, 0.5, 0.01, 0.02]);
        let expect = [0.04, 0.5, 0.04, 0.04];
        for (a, b) in q.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12, "{q:?}");
        }
        assert!(benjamini_hochberg(&[]).is_empty());
    }
}
