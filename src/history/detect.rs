//! Step detection: the commits where a series' level changed, and what changed since a commit.
//!
//! A series is fitted with a piecewise-constant level, as asv does (airspeed velocity,
//! `asv.step_detect`), then read against a per-figure minimum effect:
//!
//! - **Deterministic kinds** (counters, quality, modelled and estimated figures;
//!   [`super::kind`]): the level is the value itself, and every commit whose value differs
//!   from the previous point's is a step (the same build gives the same number; the
//!   instruction-count gates of iai-callgrind / gungraun read counts the same way).
//! - **Measured figures**: the level is the exact optimal partition of the series under a
//!   weighted squared-error cost plus a penalty per step (optimal partitioning, Jackson et al.
//!   2005; the penalised cost PELT minimises, Killick, Fearnhead & Eckley 2012), each point
//!   weighted by 1 / σᵢ², σᵢ² = σ²_noise + s²ᵢ: σ_noise is the series' run-to-run noise,
//!   1.4826 × median |xᵢ − xᵢ₋₁| / √2 (robust to the steps themselves), sᵢ the spread the point
//!   carries (its interval or samples, [`super::figures::Point::sigma`]). A segment has at
//!   least [`MIN_MEASURED_SEGMENT`] points, so one outlier is never a step (its segment's
//!   median is its neighbours') and a step in a measured figure is reported once two more
//!   commits confirm it. The penalty is
//!   [`penalty`]. Each segment's level is its median; a boundary is a step only where the
//!   medians differ by at least [`Z_MIN`] standard errors
//!   (1.2533 σ √(1/n₁ + 1/n₂), a median's standard error under normal noise).
//!
//! A step counts when its effect, (after − before) / |before|, reaches the figure's minimum
//! effect ([`super::default_min_effect_pct`] unless set per figure). Its verdict follows the
//! figure's direction ([`super::direction`]).
//!
//! **Since a commit** C: a series has *crossed* when its level at the newest commit differs
//! from its level at C (the last point at or before C) by at least the minimum effect; it is a
//! regression or an improvement by the direction of that net change, and the steps after C
//! say where it happened. A step after C that a later step undid is listed as moved and back,
//! and does not fail the check.

use super::figures::{median, Point};
use super::Direction;

/// The fewest points of a measured series' segment.
pub const MIN_MEASURED_SEGMENT: usize = 3;

/// How many standard errors a measured step's medians must differ by.
pub const Z_MIN: f64 = 4.0;

/// The penalty per step of the partition of `n` noise-normalised points: 16 + 2 ln n. The
/// largest cost reduction a single split of n independent unit-variance points achieves is the
/// squared maximum of their CUSUM, below 16 for n ≤ 1000 in all but about 1 in 10⁴ series, so
/// noise alone is not split.
pub fn penalty(n: usize) -> f64 {
    16.0 + 2.0 * (n.max(2) as f64).ln()
}

/// A step of a series: between point `before` and point `at` (indices into the points given),
/// the level moved from `level_before` to `level_after`.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    pub before: usize,
    pub at: usize,
    pub level_before: f64,
    pub level_after: f64,
    /// (after − before) / |before|; infinite when before is 0 and after is not.
    pub effect: f64,
    /// For a measured figure: the change in standard errors; `None` for deterministic kinds.
    pub z: Option<f64>,
}

/// The relative change from `a` to `b`.
pub fn effect(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else if a == 0.0 {
        f64::INFINITY.copysign(b)
    } else {
        (b - a) / a.abs()
    }
}

/// A fitted series: the level at every point, and the steps (already filtered by
/// `min_effect`, a fraction).
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    pub levels: Vec<f64>,
    pub steps: Vec<Step>,
    /// The noise σ the measured fit used (0 for deterministic kinds).
    pub noise: f64,
}

/// Fits `points` (in commit order) of a figure that is `noisy` (measured) or not; steps of at
/// least `min_effect` (a fraction, 0.05 = 5%) are kept.
pub fn fit(points: &[Point], noisy: bool, min_effect: f64) -> Fit {
    let x: Vec<f64> = points.iter().map(|p| p.value).collect();
    if !noisy {
        let steps = (1..x.len())
            .filter(|&i| x[i] != x[i - 1])
            .map(|i| Step {
                before: i - 1,
                at: i,
                level_before: x[i - 1],
                level_after: x[i],
                effect: effect(x[i - 1], x[i]),
                z: None,
            })
            .filter(|s| s.effect.abs() >= min_effect)
            .collect();
        return Fit {
            levels: x,
            steps,
            noise: 0.0,
        };
    }
    let n = x.len();
    let diffs: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let scale = median(&x.iter().map(|v| v.abs()).collect::<Vec<_>>());
    // A floor so a series that repeats exactly still has a finite weight.
    let floor = (scale * 1e-9).max(f64::MIN_POSITIVE.sqrt());
    let noise = (1.4826 * median(&diffs) / std::f64::consts::SQRT_2).max(floor);
    let var: Vec<f64> = points
        .iter()
        .map(|p| noise * noise + p.sigma().powi(2))
        .collect();
    let bounds = partition(&x, &var, MIN_MEASURED_SEGMENT, penalty(n));
    let mut levels = vec![0.0; n];
    let mut segments: Vec<(usize, usize, f64, f64)> = Vec::new();
    for w in bounds.windows(2) {
        let (s, e) = (w[0], w[1]);
        let m = median(&x[s..e]);
        let mean_var = var[s..e].iter().sum::<f64>() / (e - s) as f64;
        levels[s..e].fill(m);
        segments.push((s, e, m, mean_var));
    }
    let mut steps = Vec::new();
    for w in segments.windows(2) {
        let ((s1, e1, m1, v1), (s2, e2, m2, v2)) = (w[0], w[1]);
        let (n1, n2) = ((e1 - s1) as f64, (e2 - s2) as f64);
        let se = 1.2533 * (v1 / n1 + v2 / n2).sqrt();
        let z = (m2 - m1).abs() / se;
        let e = effect(m1, m2);
        if z >= Z_MIN && e.abs() >= min_effect {
            steps.push(Step {
                before: e1 - 1,
                at: s2,
                level_before: m1,
                level_after: m2,
                effect: e,
                z: Some(z),
            });
        }
    }
    Fit {
        levels,
        steps,
        noise,
    }
}

/// The optimal partition of `x` (variances `var`) into segments of at least `min_len`
/// points minimising Σ segment weighted squared error + `beta` per segment: the segment
/// starts, with `x.len()` appended. O(n²) with cumulative sums; a series shorter than
/// 2 × `min_len` is one segment.
fn partition(x: &[f64], var: &[f64], min_len: usize, beta: f64) -> Vec<usize> {
    let n = x.len();
    if n < 2 * min_len {
        return vec![0, n];
    }
    // Prefix sums of w, w·x, w·x².
    let mut sw = vec![0.0; n + 1];
    let mut swx = vec![0.0; n + 1];
    let mut swxx = vec![0.0; n + 1];
    for i in 0..n {
        let w = 1.0 / var[i];
        sw[i + 1] = sw[i] + w;
        swx[i + 1] = swx[i] + w * x[i];
        swxx[i + 1] = swxx[i] + w * x[i] * x[i];
    }
    let cost = |s: usize, e: usize| {
        let w = sw[e] - sw[s];
        let wx = swx[e] - swx[s];
        (swxx[e] - swxx[s] - wx * wx / w).max(0.0)
    };
    let mut best = vec![f64::INFINITY; n + 1];
    let mut from = vec![0usize; n + 1];
    best[0] = -beta;
    for e in min_len..=n {
        for s in 0..=e - min_len {
            if best[s].is_finite() {
                let c = best[s] + cost(s, e) + beta;
                if c < best[e] {
                    best[e] = c;
                    from[e] = s;
                }
            }
        }
    }
    let mut bounds = vec![n];
    let mut e = n;
    while e > 0 {
        e = from[e];
        bounds.push(e);
    }
    bounds.reverse();
    bounds
}

/// What happened to a series since a commit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verdict {
    /// Worse by at least the minimum effect.
    Regression,
    /// Better by at least the minimum effect.
    Improvement,
    /// Stepped after the commit, and back.
    MovedAndBack,
}

impl Verdict {
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Regression => "regression",
            Verdict::Improvement => "improvement",
            Verdict::MovedAndBack => "moved and back",
        }
    }
}

/// A series' change since a commit.
#[derive(Clone, Debug, PartialEq)]
pub struct Change {
    pub verdict: Verdict,
    /// The level at the commit checked against, and at the newest point.
    pub from: f64,
    pub to: f64,
    /// `to` against `from`, as [`effect`].
    pub effect: f64,
    /// The steps after the commit.
    pub steps: Vec<Step>,
}

/// The change of a fitted series since the point `since` (the last point at or before the
/// commit; `None` when the series starts after it: then it is compared from its first
/// point), up to its last point. `None` when nothing reached `min_effect`.
pub fn since(
    fit: &Fit,
    since: Option<usize>,
    direction: Direction,
    min_effect: f64,
) -> Option<Change> {
    let last = fit.levels.len().checked_sub(1)?;
    let start = since.unwrap_or(0).min(last);
    let steps: Vec<Step> = fit.steps.iter().filter(|s| s.at > start).cloned().collect();
    let (from, to) = (fit.levels[start], fit.levels[last]);
    let net = effect(from, to);
    let verdict = if net.abs() >= min_effect && (net != 0.0) {
        let worse = match direction {
            Direction::Lower => net > 0.0,
            Direction::Higher => net < 0.0,
        };
        if worse {
            Verdict::Regression
        } else {
            Verdict::Improvement
        }
    } else if !steps.is_empty() {
        Verdict::MovedAndBack
    } else {
        return None;
    };
    Some(Change {
        verdict,
        from,
        to,
        effect: net,
        steps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::hash::{mix64, unit_f32};

    /// Normal noise from a counter-based stream (Box–Muller).
    fn normal(seed: u64, i: u64) -> f64 {
        let a = unit_f32(mix64(seed ^ mix64(2 * i))) as f64 + 1e-7;
        let b = unit_f32(mix64(seed ^ mix64(2 * i + 1))) as f64;
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }

    fn points(v: &[f64]) -> Vec<Point> {
        v.iter().map(|&x| Point::exact(x)).collect()
    }

    #[test]
    fn a_deterministic_step_is_found_at_its_commit_with_its_effect() {
        let mut v = vec![100.0; 30];
        for x in &mut v[19..] {
            *x = 105.0;
        }
        let f = fit(&points(&v), false, 0.01);
        assert_eq!(f.steps.len(), 1);
        assert_eq!((f.steps[0].before, f.steps[0].at), (18, 19));
        assert!((f.steps[0].effect - 0.05).abs() < 1e-12);
        // Below the minimum effect: no step.
        assert!(fit(&points(&v), false, 0.06).steps.is_empty());
        let c = since(&f, Some(0), Direction::Lower, 0.01).unwrap();
        assert_eq!(c.verdict, Verdict::Regression);
        let c = since(&f, Some(0), Direction::Higher, 0.01).unwrap();
        assert_eq!(c.verdict, Verdict::Improvement);
        // Since after the step: nothing.
        assert!(since(&f, Some(19), Direction::Lower, 0.01).is_none());
    }

    #[test]
    fn a_step_undone_is_moved_and_back_not_a_regression() {
        let mut v = vec![10.0; 12];
        v[5] = 11.0;
        v[6] = 11.0;
        let f = fit(&points(&v), false, 0.01);
        assert_eq!(f.steps.len(), 2);
        let c = since(&f, Some(2), Direction::Lower, 0.01).unwrap();
        assert_eq!(c.verdict, Verdict::MovedAndBack);
    }

    #[test]
    fn measured_noise_alone_makes_no_step_in_a_thousand_series() {
        let mut false_steps = 0;
        for seed in 0..1000u64 {
            let v: Vec<f64> = (0..30)
                .map(|i| 10.0 * (1.0 + 0.03 * normal(seed, i)))
                .collect();
            false_steps += fit(&points(&v), true, 0.0).steps.len();
        }
        assert!(false_steps <= 2, "{false_steps} steps in pure noise");
    }

    #[test]
    fn a_measured_step_of_five_noise_sigmas_is_found_at_its_commit() {
        // A 5% step in 1% noise: one step, at commit 20 or (where the noise of a neighbour
        // reaches half the step) next to it.
        let (mut exact, mut near) = (0, 0);
        for seed in 0..200u64 {
            let v: Vec<f64> = (0..30)
                .map(|i| {
                    let level = if i >= 19 { 10.5 } else { 10.0 };
                    level * (1.0 + 0.01 * normal(seed, i))
                })
                .collect();
            let f = fit(&points(&v), true, 0.02);
            if let [s] = f.steps.as_slice() {
                exact += usize::from(s.at == 19);
                near += usize::from(s.at.abs_diff(19) <= 1);
                assert!((s.effect - 0.05).abs() < 0.02, "{}", s.effect);
            }
        }
        assert!(exact >= 185, "one step at commit 20 in {exact} of 200");
        assert!(near >= 197, "one step at commit 20 ± 1 in {near} of 200");
    }

    #[test]
    fn one_outlier_is_not_a_step_and_a_point_s_own_spread_widens_its_noise() {
        let mut v: Vec<f64> = (0..30)
            .map(|i| 10.0 * (1.0 + 0.01 * normal(7, i)))
            .collect();
        v[12] = 20.0;
        assert!(fit(&points(&v), true, 0.02).steps.is_empty());
        // A 5% shift whose points carry intervals of ±20%: not distinguishable.
        let p: Vec<Point> = (0..30)
            .map(|i| {
                let x = if i >= 15 { 10.5 } else { 10.0 };
                Point {
                    value: x,
                    lower: Some(x * 0.8),
                    upper: Some(x * 1.2),
                    samples: vec![],
                }
            })
            .collect();
        assert!(fit(&p, true, 0.02).steps.is_empty());
        let exact: Vec<Point> = p.iter().map(|q| Point::exact(q.value)).collect();
        assert_eq!(fit(&exact, true, 0.02).steps.len(), 1);
    }
}
