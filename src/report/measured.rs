//! The comparison of measured figures (kind `measured` in the glossary: `wall_ms`, `gpu_ms`)
//! between two result sets, run by run, on their samples ([`crate::harness::measure`]): a
//! two-sided Mann–Whitney U test (exact distribution without ties for up to 50 samples a side,
//! else the normal approximation with tie correction), the ratio of medians as the effect, and
//! the Benjamini–Hochberg procedure over every test of the comparison, so a sweep of many runs
//! does not raise false alarms by their number (after Google Benchmark's `compare.py` and asv).
//! A figure is flagged when its adjusted p-value is at most `q` and its medians differ by at
//! least the minimum effect (in percent; per figure with `--threshold-for`).
//!
//! No maintained crate offers the Mann–Whitney test with its exact distribution, so it is
//! written here and tested against tabulated values.

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

/// P(Z > z) for a standard normal Z (Abramowitz and Stegun 7.1.26 through erfc; absolute error
/// below 1.5e-7).
fn normal_upper_tail(z: f64) -> f64 {
    let x = z / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    0.5 * poly * (-x * x).exp()
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

/// One measured figure of one run, tested.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredChange {
    pub case: String,
    pub figure: String,
    pub old_median: f64,
    pub new_median: f64,
    pub samples: [usize; 2],
    pub u: f64,
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
                    p,
                    q: 1.0,
                    min_effect_pct: min_effect(figure),
                });
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
                "{:<8}  {:<60}  {:<8}  {:>12}  {:>12}  {:>8}  {:>9}  {:>9}",
                "measured", "run", "figure", "baseline", "current", "ratio", "p", "q"
            );
            for t in &flagged {
                let _ = writeln!(
                    s,
                    "{:<8}  {:<60}  {:<8}  {:>12}  {:>12}  {:>7.3}×  {:>9.2e}  {:>9.2e}",
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
                    t.p,
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
            "measured: {} figures of {} runs tested (Mann–Whitney U, Benjamini–Hochberg q ≤ {}); \
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
