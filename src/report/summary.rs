//! The summary that answers "which algorithm gives the best shadows for its cost, on which
//! execution?": at the scenario's base point, per execution, every algorithm's quality
//! (`mae_shadow`, and the restricted `mae_shadow_receivers` where a record has it) against its
//! costs (wall, modelled and GPU time; memory traffic), sorted by quality, with the algorithms
//! on the Pareto front of each cost marked. Written as a table in the report, as
//! `summary.csv`, as a LaTeX booktabs table `summary.tex`, and as one chart per execution.
//!
//! Pareto fronts are computed within one case and one execution only: costs measured on
//! different executions (host wall time, modelled time, GPU time) are never compared.
//!
//! The base point is found from the records alone (results files do not store the scenario):
//! per sweep axis the value most runs share (for an `each` sweep, the base value), and the
//! case with those values; when no run has all of them, the case with the most runs.

use std::fmt::Write as _;

use super::charts::{self, Metric, Series, Spec, XyChart};
use super::{fmt_num, style};
use crate::backend::Backend;
use crate::record::RunRecord;

/// A cost of a run: one of the charted figures ([`charts::METRICS`]), with the short name the
/// summary gives it.
pub struct Cost {
    pub metric: Metric,
    pub name: &'static str,
}

pub const COSTS: [Cost; 5] = [
    Cost {
        metric: charts::WALL_TIME,
        name: "wall",
    },
    Cost {
        metric: charts::MODELLED_TIME,
        name: "modelled",
    },
    Cost {
        metric: charts::GPU_TIME,
        name: "GPU",
    },
    Cost {
        metric: charts::MODELLED_MEMORY,
        name: "modelled memory",
    },
    Cost {
        metric: charts::ESTIMATED_MEMORY,
        name: "estimated memory",
    },
];

/// The quality figure of the summary: mean absolute error in shadow.
pub const QUALITY_LABEL: &str = "mean absolute error in shadow (mae_shadow, 0–1)";

/// Name of the restricted error figure shown where a record carries it.
pub const RESTRICTED: &str = "mae_shadow_receivers";

/// The restricted error of `r` (over receivers only), when its record has one.
pub fn restricted_error(r: &RunRecord) -> Option<f64> {
    r.error.as_ref()?.mae_shadow_receivers
}

/// The quality figures the summary shows beside `mae_shadow`, each where a row has it: the
/// error in the reference's penumbra, the umbra and lit misclassifications, and the perceptual
/// metrics ([`crate::metrics::ErrorMetrics`]).
pub const QUALITY: [&str; 5] = ["mae_penumbra", "umbra_error", "lit_error", "flip", "ssim"];

/// The [`QUALITY`] figures of `r`, in that order.
pub fn quality(r: &RunRecord) -> [Option<f64>; QUALITY.len()] {
    let named = r.error.as_ref().map(|e| e.named());
    QUALITY.map(|q| {
        named
            .as_ref()?
            .iter()
            .find(|(n, _)| *n == q)
            .and_then(|(_, v)| *v)
    })
}

/// The method limits a run's notes name (`method limit (WHAT): …` → `WHAT`).
pub fn method_limits(r: &RunRecord) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for n in &r.notes {
        let Some(rest) = n.strip_prefix("method limit (") else {
            continue;
        };
        if let Some(what) = rest.split_once("): ").map(|(w, _)| w.to_string()) {
            if !out.contains(&what) {
                out.push(what);
            }
        }
    }
    out
}

/// What identifies a case: the scene and every sweep parameter (not the light kind, which an
/// algorithm may convert).
pub fn case_key(r: &RunRecord) -> String {
    let v: Vec<String> = charts::Axis::ALL
        .iter()
        .map(|a| format!("{:?}", a.value(r)))
        .collect();
    format!("{}|{}", r.scene, v.join("|"))
}

/// The base point of `runs`: its case key and a description of its parameters. `None` without
/// runs.
pub fn base_case(runs: &[&RunRecord]) -> Option<(String, String)> {
    let first = runs.first()?;
    // Per axis, the value most runs have (the first such on a tie).
    let mode = |f: &dyn Fn(&RunRecord) -> String| -> String {
        let mut counts: Vec<(String, usize)> = Vec::new();
        for r in runs {
            let v = f(r);
            match counts.iter_mut().find(|(k, _)| *k == v) {
                Some((_, n)) => *n += 1,
                None => counts.push((v, 1)),
            }
        }
        let best = counts.iter().map(|c| c.1).max().unwrap_or(0);
        counts
            .into_iter()
            .find(|c| c.1 == best)
            .map(|c| c.0)
            .unwrap_or_default()
    };
    let mut parts = vec![mode(&|r| r.scene.clone())];
    for a in charts::Axis::ALL {
        parts.push(mode(&|r| format!("{:?}", a.value(r))));
    }
    let want = parts.join("|");
    let pick = runs
        .iter()
        .find(|r| case_key(r) == want)
        .copied()
        .or_else(|| {
            // The case with the most runs.
            let mut best: Option<(&RunRecord, usize)> = None;
            for r in runs {
                let n = runs.iter().filter(|o| case_key(o) == case_key(r)).count();
                if best.is_none_or(|b| n > b.1) {
                    best = Some((r, n));
                }
            }
            best.map(|b| b.0)
        })
        .unwrap_or(first);
    Some((case_key(pick), charts::describe_case(pick, None)))
}

/// One algorithm on one execution at the base point.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub algorithm: String,
    /// The run's variant ([`RunRecord::variant`]): its points are drawn in a shade of the
    /// algorithm's colour.
    pub variant: Option<String>,
    /// The algorithm as the tables and legends name it ([`RunRecord::algorithm_label`]).
    pub label: String,
    pub backend: Backend,
    pub mae_shadow: Option<f64>,
    pub restricted: Option<f64>,
    /// Per [`QUALITY`] entry.
    pub quality: [Option<f64>; QUALITY.len()],
    /// The method limits of the paper's design that showed in this run (its notes'
    /// `method limit (…)`, [`crate::harness::limit_notes`]): its `mae_shadow` counts pixels the
    /// method does not compute by design, so `mae_shadow_receivers` is the fair comparison.
    pub limits: Vec<String>,
    /// Per [`COSTS`] entry.
    pub costs: [Option<f64>; COSTS.len()],
    /// Per [`COSTS`] entry: whether no other algorithm of this execution is at least as good
    /// on both that cost and `mae_shadow`, and better on one.
    pub pareto: [bool; COSTS.len()],
    /// Per [`COSTS`] entry, for measured costs (`wall_ms`, `gpu_ms`): the 95% interval of the
    /// median ([`crate::harness::measure::Spread::ci`]), ms.
    pub intervals: [Option<[f64; 2]>; COSTS.len()],
}

/// The 95% interval of the median of `r`'s measured cost `metric` (`wall_ms`, `gpu_ms`); `None`
/// for other costs and for runs measured without samples.
fn interval(r: &RunRecord, metric: &str) -> Option<[f64; 2]> {
    let m = r.measured.as_ref()?;
    let spread = match metric {
        "wall_ms" => &m.wall_ms,
        "gpu_ms" => m.gpu_ms.as_ref()?,
        _ => return None,
    };
    spread.ci.iter().all(|v| v.is_finite()).then_some(spread.ci)
}

/// One algorithm in a [`Execution::measured_ranking`]: its label, median and interval, and
/// whether its interval overlaps the next (slower) one's.
#[derive(Clone, Debug, PartialEq)]
pub struct Ranked {
    pub label: String,
    pub median: f64,
    pub interval: [f64; 2],
    pub overlaps_next: bool,
}

/// The summary of one execution.
#[derive(Clone, Debug)]
pub struct Execution {
    pub backend: Backend,
    /// Sorted by `mae_shadow` (best first; runs without quality last), then cost.
    pub rows: Vec<Row>,
}

impl Execution {
    /// The algorithms of this execution ranked by measured cost `c` (a [`COSTS`] index),
    /// fastest first, each saying whether its 95% interval overlaps the next one's (the two are
    /// not told apart by this sweep); empty for a cost without intervals.
    pub fn measured_ranking(&self, c: usize) -> Vec<Ranked> {
        let mut ranked: Vec<Ranked> = self
            .rows
            .iter()
            .filter_map(|r| {
                Some(Ranked {
                    label: r.label.clone(),
                    median: r.costs[c]?,
                    interval: r.intervals[c]?,
                    overlaps_next: false,
                })
            })
            .collect();
        ranked.sort_by(|a, b| a.median.total_cmp(&b.median));
        for i in 1..ranked.len() {
            let (lo, hi) = (&ranked[i - 1], &ranked[i]);
            let overlap = lo.interval[1] >= hi.interval[0] && hi.interval[1] >= lo.interval[0];
            ranked[i - 1].overlaps_next = overlap;
        }
        ranked
    }
}

/// The summary at the base point.
#[derive(Clone, Debug)]
pub struct Summary {
    /// The base point's parameters.
    pub case: String,
    pub executions: Vec<Execution>,
    /// Whether any row has the restricted error.
    pub has_restricted: bool,
    /// The [`QUALITY`] entries (indices) that some row has, in order: the columns shown.
    pub quality_shown: Vec<usize>,
}

impl Summary {
    /// The summary of the successful runs `ok` (the reference, which has no quality of its
    /// own, left out); `None` when no run is at the base point.
    pub fn of(ok: &[&RunRecord]) -> Option<Summary> {
        let (key, case) = base_case(ok)?;
        let at: Vec<&RunRecord> = ok
            .iter()
            .copied()
            .filter(|r| r.failure.is_none() && r.algorithm != crate::algorithms::reference::ID)
            .filter(|r| case_key(r) == key)
            .collect();
        let mut backends: Vec<Backend> = at.iter().map(|r| r.backend).collect();
        backends.sort();
        backends.dedup();
        let executions: Vec<Execution> = backends
            .into_iter()
            .map(|b| {
                let mut rows: Vec<Row> = Vec::new();
                for r in at.iter().filter(|r| r.backend == b) {
                    if rows.iter().any(|x| x.label == r.algorithm_label()) {
                        continue;
                    }
                    rows.push(Row {
                        algorithm: r.algorithm.clone(),
                        variant: r.variant.clone(),
                        label: r.algorithm_label(),
                        backend: b,
                        mae_shadow: r.error.as_ref().and_then(|e| e.mae_shadow),
                        restricted: restricted_error(r),
                        quality: quality(r),
                        limits: method_limits(r),
                        costs: COSTS
                            .each_ref()
                            .map(|c| (c.metric.value)(r).filter(|v| v.is_finite())),
                        pareto: [false; COSTS.len()],
                        intervals: COSTS.each_ref().map(|c| interval(r, c.metric.id)),
                    });
                }
                for (ci, _) in COSTS.iter().enumerate() {
                    let pts: Vec<Option<(f64, f64)>> = rows
                        .iter()
                        .map(|r| Some((r.costs[ci]?, r.mae_shadow?)))
                        .collect();
                    for (i, p) in pts.iter().enumerate() {
                        let Some(p) = p else { continue };
                        let dominated = pts
                            .iter()
                            .flatten()
                            .any(|q| q.0 <= p.0 && q.1 <= p.1 && (q.0 < p.0 || q.1 < p.1));
                        rows[i].pareto[ci] = !dominated;
                    }
                }
                rows.sort_by(|a, b| {
                    let q = |r: &Row| r.mae_shadow.unwrap_or(f64::INFINITY);
                    q(a).total_cmp(&q(b)).then(
                        style::algorithm_rank(&a.algorithm)
                            .cmp(&style::algorithm_rank(&b.algorithm)),
                    )
                });
                Execution { backend: b, rows }
            })
            .filter(|e| !e.rows.is_empty())
            .collect();
        if executions.is_empty() {
            return None;
        }
        let has_restricted = executions
            .iter()
            .any(|e| e.rows.iter().any(|r| r.restricted.is_some()));
        let quality_shown = (0..QUALITY.len())
            .filter(|&q| {
                executions
                    .iter()
                    .any(|e| e.rows.iter().any(|r| r.quality[q].is_some()))
            })
            .collect();
        Some(Summary {
            case,
            executions,
            has_restricted,
            quality_shown,
        })
    }

    /// Which costs any row of `e` has, as indices into [`COSTS`].
    fn costs_of(e: &Execution) -> Vec<usize> {
        (0..COSTS.len())
            .filter(|&c| e.rows.iter().any(|r| r.costs[c].is_some()))
            .collect()
    }

    /// One chart per execution: a panel per cost with quality, one point per algorithm, and
    /// that panel's Pareto front.
    pub fn charts(&self) -> Vec<Spec> {
        let mut specs = Vec::new();
        for e in &self.executions {
            let mut panels = Vec::new();
            for c in Self::costs_of(e) {
                let series: Vec<Series> = e
                    .rows
                    .iter()
                    .filter_map(|r| {
                        Some(Series {
                            name: format!("{} / {}", r.label, r.backend),
                            algorithm: match &r.variant {
                                Some(v) => format!("{} ({v})", r.algorithm),
                                None => r.algorithm.clone(),
                            },
                            backend: r.backend,
                            points: vec![(r.costs[c]?, r.mae_shadow?)],
                            intervals: vec![],
                        })
                    })
                    .collect();
                if series.is_empty() {
                    continue;
                }
                let front = charts::pareto_front(series.iter().map(|s| s.points[0]));
                // More than MAX_SERIES algorithms: split, each part with its own front would
                // mislead, so the front stays that of all of them.
                for mut p in charts::per_execution(series, |_| XyChart {
                    x_label: COSTS[c].metric.label.into(),
                    y_label: QUALITY_LABEL.into(),
                    series: vec![],
                    lines: false,
                    front: Some(front.clone()),
                    linear_x: false,
                }) {
                    let part = p.title.strip_prefix(e.backend.name()).unwrap_or("");
                    p.title = format!("{} cost{part}", COSTS[c].name);
                    panels.push(p);
                }
            }
            if panels.is_empty() {
                continue;
            }
            specs.push(Spec {
                file: format!("quality_vs_cost_{}", e.backend),
                title: format!("quality vs. cost on {}", e.backend),
                case: format!("base point: {}", self.case),
                caption: "One point per algorithm; lower is better on both axes. Circled points \
                          joined by the dashed line are Pareto-optimal: no other algorithm on \
                          this execution is cheaper and at least as accurate."
                    .into(),
                panels,
            });
        }
        specs
    }

    /// The summary as CSV: one row per algorithm (and variant, `variant` empty without one) and
    /// execution.
    pub fn csv(&self) -> String {
        let mut s = String::from("execution,algorithm,variant,mae_shadow,");
        if self.has_restricted {
            let _ = write!(s, "{RESTRICTED},");
        }
        for &q in &self.quality_shown {
            let _ = write!(s, "{},", QUALITY[q]);
        }
        for c in &COSTS {
            let _ = write!(s, "{},", c.metric.id);
        }
        s.push_str("pareto_optimal_on\n");
        let opt = |v: Option<f64>| v.map(|v| v.to_string()).unwrap_or_default();
        for e in &self.executions {
            for r in &e.rows {
                let variant = r.variant.as_deref().unwrap_or_default();
                let _ = write!(
                    s,
                    "{},{},{variant},{},",
                    r.backend,
                    r.algorithm,
                    opt(r.mae_shadow)
                );
                if self.has_restricted {
                    let _ = write!(s, "{},", opt(r.restricted));
                }
                for &q in &self.quality_shown {
                    let _ = write!(s, "{},", opt(r.quality[q]));
                }
                for v in r.costs {
                    let _ = write!(s, "{},", opt(v));
                }
                let _ = writeln!(s, "{}", pareto_names(r).join(";"));
            }
        }
        s
    }

    /// The summary as a LaTeX table (needs `\usepackage{booktabs}`); a value in bold is on the
    /// Pareto front of its cost.
    pub fn latex(&self, scenario: &str) -> String {
        let tex = |s: &str| {
            s.replace('\\', "\\textbackslash{}")
                .replace('_', "\\_")
                .replace('&', "\\&")
                .replace('%', "\\%")
                .replace('#', "\\#")
        };
        let num = |v: Option<f64>, bold: bool| match v {
            None => "--".to_string(),
            Some(v) if bold => format!("\\textbf{{{}}}", fmt_num(v)),
            Some(v) => fmt_num(v),
        };
        let mut cols = "ll r".to_string();
        let mut head = "Execution & Algorithm & MAE\\textsubscript{shadow}".to_string();
        if self.has_restricted {
            cols.push('r');
            head.push_str(" & MAE\\textsubscript{receivers}");
        }
        for &q in &self.quality_shown {
            cols.push('r');
            let _ = write!(
                head,
                " & {}",
                match QUALITY[q] {
                    "mae_penumbra" => "MAE\\textsubscript{penumbra}",
                    "umbra_error" => "Umbra lit",
                    "lit_error" => "Lit shadowed",
                    "flip" => "FLIP",
                    _ => "SSIM",
                }
            );
        }
        for c in &COSTS {
            cols.push('r');
            let _ = write!(
                head,
                " & {}",
                match c.metric.id {
                    "wall_ms" => "Wall (ms)",
                    "model_ms" => "Modelled (ms)",
                    "gpu_ms" => "GPU (ms)",
                    "modelled_memory_bytes" => "Modelled memory (bytes)",
                    _ => "Estimated memory (bytes)",
                }
            );
        }
        let mut s = String::new();
        let _ = writeln!(
            s,
            "% shadowbench summary of scenario {}, {}\n% Needs \\usepackage{{booktabs}}. Bold: \
             Pareto-optimal on that cost (no cheaper algorithm on the same execution is at \
             least as accurate).",
            scenario.replace('\n', " "),
            self.case.replace('\n', " ")
        );
        let _ = writeln!(
            s,
            "\\begin{{tabular}}{{{}}}\n\\toprule\n{head} \\\\\n\\midrule",
            cols.replace(' ', "")
        );
        for (i, e) in self.executions.iter().enumerate() {
            if i > 0 {
                s.push_str("\\midrule\n");
            }
            for (j, r) in e.rows.iter().enumerate() {
                let exec = if j == 0 {
                    tex(e.backend.name())
                } else {
                    String::new()
                };
                let _ = write!(
                    s,
                    "{exec} & {}{} & {}",
                    tex(&r.label),
                    if r.limits.is_empty() {
                        ""
                    } else {
                        "$^\\dagger$"
                    },
                    num(r.mae_shadow, false)
                );
                if self.has_restricted {
                    let _ = write!(s, " & {}", num(r.restricted, false));
                }
                for &q in &self.quality_shown {
                    let _ = write!(s, " & {}", num(r.quality[q], false));
                }
                for (c, v) in r.costs.iter().enumerate() {
                    let _ = write!(s, " & {}", num(*v, r.pareto[c]));
                }
                s.push_str(" \\\\\n");
            }
        }
        s.push_str("\\bottomrule\n\\end{tabular}\n");
        let limited: Vec<String> = self
            .executions
            .iter()
            .flat_map(|e| &e.rows)
            .filter(|r| !r.limits.is_empty())
            .map(|r| format!("{}: {}", r.label, r.limits.join("; ")))
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        if !limited.is_empty() {
            let _ = writeln!(
                s,
                "% $^\\dagger$ method limit of the paper's design (MAE_shadow counts pixels it \
                 does not compute; compare on MAE_receivers): {}",
                limited.join(" | ")
            );
        }
        s
    }
}

/// The costs on whose Pareto front `r` is.
pub fn pareto_names(r: &Row) -> Vec<&'static str> {
    COSTS
        .iter()
        .zip(r.pareto)
        .filter(|(_, p)| *p)
        .map(|(c, _)| c.name)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::testdata::record;

    /// An `each` sweep: base (2000 triangles, light 0.5), triangles 500/8000, light 0.2/1.0.
    fn sweep() -> Vec<RunRecord> {
        let mut runs = Vec::new();
        for (t, l) in [
            (2000, 0.5),
            (500, 0.5),
            (8000, 0.5),
            (2000, 0.2),
            (2000, 1.0),
        ] {
            for (a, mae, wall) in [
                ("pcss", 0.02, 5.0),
                ("hard_shadow_map", 0.10, 1.0),
                ("soft_izb", 0.01, 9.0),
                // Worse and costlier than pcss: dominated.
                ("penumbra_map", 0.05, 7.0),
            ] {
                for b in [Backend::CpuNative, Backend::CpuModel] {
                    let mut r = record(a, b, t, 32);
                    r.params.light_size = l;
                    r.error.as_mut().unwrap().mae_shadow = Some(mae * (1.0 + l as f64));
                    r.wall_ms = wall * t as f64 / 2000.0;
                    r.model_ms = (b == Backend::CpuModel).then_some(wall * 2.0);
                    runs.push(r);
                }
            }
            let mut r = record("reference", Backend::CpuNative, t, 32);
            r.params.light_size = l;
            r.error = None;
            runs.push(r);
        }
        runs
    }

    #[test]
    fn the_ranking_of_measured_times_says_where_intervals_overlap() {
        use crate::harness::measure::{Measure, Measured, Spread};
        let mut runs = sweep();
        // At the base point: pcss 5 ms, hard_shadow_map 1, soft_izb 9, penumbra_map 7; samples
        // of pcss and penumbra_map spread so their intervals overlap, the others tight.
        for r in runs.iter_mut().filter(|r| r.backend == Backend::CpuNative) {
            let spread = match r.algorithm.as_str() {
                "pcss" => 0.5,
                "penumbra_map" => 0.2,
                _ => 0.01,
            };
            let median = r.wall_ms;
            let samples: Vec<f64> = (0..10)
                .map(|i| median * (1.0 + spread * (i as f64 - 4.5) / 4.5))
                .collect();
            r.measured = Some(Measured {
                protocol: Measure::default(),
                iterations: 10,
                warmup_runs: 0,
                wall_ms: Spread::of(samples).unwrap(),
                gpu_ms: None,
                phases: vec![],
                identical: true,
                warnings: vec![],
            });
        }
        let refs: Vec<&RunRecord> = runs.iter().collect();
        let s = Summary::of(&refs).unwrap();
        let wall = COSTS.iter().position(|c| c.metric.id == "wall_ms").unwrap();
        let ranked = s.executions[0].measured_ranking(wall);
        let order: Vec<(&str, bool)> = ranked
            .iter()
            .map(|r| (r.label.as_str(), r.overlaps_next))
            .collect();
        assert_eq!(
            order,
            [
                ("hard_shadow_map", false),
                ("pcss", true),
                ("penumbra_map", false),
                ("soft_izb", false)
            ]
        );
        // cpu-model's runs carry no samples: no ranking of its wall time.
        assert!(s.executions[1].measured_ranking(wall).is_empty());
    }

    #[test]
    fn the_base_point_is_the_value_each_axis_shares_most() {
        let runs = sweep();
        let refs: Vec<&RunRecord> = runs.iter().collect();
        let (key, case) = base_case(&refs).unwrap();
        assert!(
            case.contains("2000 triangles") && case.contains("light size 0.5"),
            "{case}"
        );
        // Reordering the runs (as shards merged in another order) keeps the base point.
        let mut rev = refs.clone();
        rev.reverse();
        assert_eq!(base_case(&rev).unwrap().0, key);
    }

    #[test]
    fn a_wgpu_run_is_named_with_its_gpu_pipeline_in_the_table_and_the_chart() {
        let mut runs = sweep();
        let mut gpu = record("soft_shadow_volume", Backend::Wgpu, 2000, 32);
        gpu.params.light_size = 0.5;
        gpu.execution
            .insert("gpu_pipeline".into(), serde_json::json!("gather"));
        runs.push(gpu);
        let refs: Vec<&RunRecord> = runs.iter().collect();
        let s = Summary::of(&refs).unwrap();
        let wgpu = s
            .executions
            .iter()
            .find(|e| e.backend == Backend::Wgpu)
            .unwrap();
        assert_eq!(wgpu.rows[0].label, "soft_shadow_volume (gather)");
        // Runs without a pipeline keep the bare id.
        assert!(s.executions[0].rows.iter().all(|r| r.label == r.algorithm));
        let names: Vec<String> = s
            .charts()
            .iter()
            .flat_map(|c| c.panels.iter().flat_map(|p| p.series_names()))
            .collect();
        assert!(
            names.contains(&"soft_shadow_volume (gather) / wgpu".to_string()),
            "{names:?}"
        );
        assert!(s.latex("t").contains("soft\\_shadow\\_volume (gather)"));
    }

    #[test]
    fn rows_are_sorted_by_quality_per_execution_with_the_pareto_front_marked() {
        let runs = sweep();
        let refs: Vec<&RunRecord> = runs.iter().collect();
        let s = Summary::of(&refs).unwrap();
        let execs: Vec<Backend> = s.executions.iter().map(|e| e.backend).collect();
        assert_eq!(execs, [Backend::CpuNative, Backend::CpuModel]);
        let native = &s.executions[0];
        let algs: Vec<&str> = native.rows.iter().map(|r| r.algorithm.as_str()).collect();
        // The reference has no quality of its own and is not a row.
        assert_eq!(
            algs,
            ["soft_izb", "pcss", "penumbra_map", "hard_shadow_map"]
        );
        // Brute force on wall time: soft_izb (best quality), pcss, hard_shadow_map (cheapest)
        // are undominated; penumbra_map is beaten by pcss on both.
        let on: Vec<bool> = native.rows.iter().map(|r| r.pareto[0]).collect();
        assert_eq!(on, [true, true, false, true]);
        // Only base-point runs: wall times are the base ones.
        assert_eq!(native.rows[0].costs[0], Some(9.0));
        // No modelled time on cpu-native; on cpu-model, its own front.
        assert!(native
            .rows
            .iter()
            .all(|r| r.costs[1].is_none() && !r.pareto[1]));
        let model = &s.executions[1];
        assert!(model.rows.iter().any(|r| r.pareto[1]));
        assert!(!s.has_restricted);
    }

    #[test]
    fn csv_and_latex_carry_every_row() {
        let runs = sweep();
        let refs: Vec<&RunRecord> = runs.iter().collect();
        let s = Summary::of(&refs).unwrap();
        let csv = s.csv();
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(
            lines[0],
            "execution,algorithm,variant,mae_shadow,wall_ms,model_ms,gpu_ms,modelled_memory_bytes,estimated_memory_bytes,pareto_optimal_on"
        );
        assert_eq!(lines.len(), 1 + 8);
        assert!(
            lines[1].starts_with("cpu-native,soft_izb,,0.015,9,,,"),
            "{}",
            lines[1]
        );
        assert!(
            lines[1].ends_with(",wall;modelled memory") || lines[1].ends_with(",wall"),
            "{}",
            lines[1]
        );
        let tex = s.latex("quick");
        assert!(tex.contains("\\toprule") && tex.contains("\\bottomrule"));
        assert!(tex.contains("soft\\_izb") && !tex.contains("soft_izb"));
        // One line per row plus the header, between \midrule separators per execution.
        assert_eq!(tex.matches(" \\\\\n").count(), 1 + 8);
        assert_eq!(tex.matches("\\midrule").count(), 2);
    }
}
