//! Comparison charts, each as PNG and SVG, drawn as small multiples so no panel holds more than
//! [`MAX_SERIES`] series:
//!
//! - quality against cost at the scenario's base point, one figure per execution with a panel
//!   per cost (wall, modelled, GPU time; memory traffic) and the Pareto front of that panel
//!   (see [`super::summary`]);
//! - every time, cost and error figure against every sweep axis the runs vary along, one panel
//!   per execution, one line per algorithm, the other parameters fixed (named in the title);
//! - per-phase time at the base point, one panel per algorithm, one stacked bar per execution,
//!   and per run of a series swept along two or more axes.
//!
//! Every algorithm has one colour in every chart and every execution one marker and line style
//! ([`super::style`]); the legend, beside the panels, names every series drawn. Axes spanning a
//! decade or more are logarithmic with ticks at the decades.
//!
//! Planning ([`plan`]) is separate from drawing ([`render`]) so which charts a set of runs gets,
//! and what is on them, can be checked without pixels.
//!
//! Text is drawn with the pure-Rust `ab_glyph` rasterizer from a system TrueType font, or the
//! DejaVu Sans built into the binary when there is none (see [`super::font`]).

use std::ops::Range;
use std::path::Path;

use plotters::chart::MeshStyle;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::fmt_num;
use super::style::{self, Dash, Marker};
use crate::backend::Backend;
use crate::error::{Error, Result};
use crate::record::{Phase, RunRecord};

/// Most series one panel shows; more are split over several panels.
pub const MAX_SERIES: usize = 8;

/// A sweep axis as it appears in the runs' parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    Triangles,
    LightSize,
    MapResolution,
    TileSize,
    ImagePixels,
    OccluderHeight,
    OccluderOffset,
    Cores,
}

impl Axis {
    pub const ALL: [Axis; 8] = [
        Axis::Triangles,
        Axis::LightSize,
        Axis::MapResolution,
        Axis::TileSize,
        Axis::ImagePixels,
        Axis::OccluderHeight,
        Axis::OccluderOffset,
        Axis::Cores,
    ];

    pub fn id(self) -> &'static str {
        match self {
            Axis::Triangles => "triangles",
            Axis::LightSize => "light_size",
            Axis::MapResolution => "map_resolution",
            Axis::TileSize => "tile_size",
            Axis::ImagePixels => "image_pixels",
            Axis::OccluderHeight => "occluder_height",
            Axis::OccluderOffset => "occluder_offset",
            Axis::Cores => "cores",
        }
    }

    /// Axis title on a chart, with its unit.
    pub fn label(self) -> &'static str {
        match self {
            Axis::Triangles => "scene triangles (count)",
            Axis::LightSize => "light size (scene units, radius or half-width)",
            Axis::MapResolution => "map resolution (texels per side)",
            Axis::TileSize => "tile size (pixels per side)",
            Axis::ImagePixels => "image pixels (width × height)",
            Axis::OccluderHeight => "occluder height above receiver (scene units)",
            Axis::OccluderOffset => "occluder lateral offset x (scene units)",
            Axis::Cores => "modelled cores (count)",
        }
    }

    /// Short name, for titles.
    fn name(self) -> &'static str {
        match self {
            Axis::Triangles => "scene triangles",
            Axis::LightSize => "light size",
            Axis::MapResolution => "map resolution",
            Axis::TileSize => "tile size",
            Axis::ImagePixels => "image pixels",
            Axis::OccluderHeight => "occluder height",
            Axis::OccluderOffset => "occluder offset",
            Axis::Cores => "modelled cores",
        }
    }

    /// What varying this axis shows, for the chart title.
    fn meaning(self) -> &'static str {
        match self {
            Axis::Cores => " (scaling)",
            Axis::TileSize => " (binning trade-off)",
            _ => "",
        }
    }

    pub fn value(self, r: &RunRecord) -> Option<f64> {
        let p = &r.params;
        match self {
            Axis::Triangles => Some(p.triangles as f64),
            Axis::LightSize => Some(p.light_size as f64),
            Axis::MapResolution => Some(p.map_resolution as f64),
            Axis::TileSize => Some(p.tile_size as f64),
            Axis::ImagePixels => Some(p.image[0] as f64 * p.image[1] as f64),
            Axis::OccluderHeight => p.occluder_height.map(f64::from),
            Axis::OccluderOffset => p.occluder_offset.map(f64::from),
            // The modelled machine's core count: a cpu-native or wgpu run's time does not
            // depend on it, so those runs are not plotted against it.
            Axis::Cores => p
                .cores
                .filter(|_| r.backend == Backend::CpuModel)
                .map(f64::from),
        }
    }
}

/// A figure of a run plotted against the sweep axes.
pub struct Metric {
    pub id: &'static str,
    /// Short name, for titles.
    pub name: &'static str,
    /// Axis title with its unit.
    pub label: &'static str,
    pub value: fn(&RunRecord) -> Option<f64>,
}

/// Memory traffic of one kind, `mem_model` (modelled) or `mem_est` (estimated): bytes read plus
/// bytes written, when the run counts either. The two kinds are never added or charted together
/// ([`crate::counters`]).
pub fn memory_bytes(r: &RunRecord, kind: &str) -> Option<f64> {
    let (rd, wr) = (
        r.counters.get(&format!("{kind}.read_bytes")),
        r.counters.get(&format!("{kind}.write_bytes")),
    );
    (rd.is_some() || wr.is_some()).then(|| rd.unwrap_or(0.0) + wr.unwrap_or(0.0))
}

/// Host wall time of a run.
pub const WALL_TIME: Metric = Metric {
    id: "wall_ms",
    name: "wall time",
    label: "wall time (ms, measured on the host)",
    value: |r| Some(r.wall_ms),
};

/// GPU time of a wgpu run.
pub const GPU_TIME: Metric = Metric {
    id: "gpu_ms",
    name: "GPU time",
    label: "GPU time (ms, timestamp queries)",
    value: |r| r.gpu_ms,
};

/// Modelled time of a cpu-model run.
pub const MODELLED_TIME: Metric = Metric {
    id: "model_ms",
    name: "modelled time",
    label: "modelled time (ms)",
    value: |r| r.model_ms,
};

/// Modelled memory traffic ([`memory_bytes`] of `mem_model`).
pub const MODELLED_MEMORY: Metric = Metric {
    id: "modelled_memory_bytes",
    name: "modelled memory traffic",
    label: "modelled memory traffic (bytes read + written, cpu-model)",
    value: |r| memory_bytes(r, "mem_model"),
};

/// Estimated memory traffic ([`memory_bytes`] of `mem_est`).
pub const ESTIMATED_MEMORY: Metric = Metric {
    id: "estimated_memory_bytes",
    name: "estimated memory traffic",
    label: "estimated memory traffic (bytes read + written)",
    value: |r| memory_bytes(r, "mem_est"),
};

pub const METRICS: [Metric; 10] = [
    WALL_TIME,
    GPU_TIME,
    MODELLED_TIME,
    MODELLED_MEMORY,
    ESTIMATED_MEMORY,
    Metric {
        id: "fill",
        name: "fill",
        label: "fill (fragments, texels or samples)",
        value: |r| r.counters.get("fill"),
    },
    Metric {
        id: "overdraw_ratio",
        name: "overdraw ratio",
        label: "overdraw ratio (overdraw / fill)",
        value: |r| r.counters.get("overdraw_ratio"),
    },
    // Error against a sweep axis, as paper 002 plots it (Figures 17-20).
    Metric {
        id: "mae_shadow",
        name: "shadow error",
        label: "mean absolute error in shadow (mae_shadow, 0–1)",
        value: |r| r.error.as_ref().and_then(|e| e.mae_shadow),
    },
    // The error where the papers compare (the reference's penumbra), and what a viewer sees.
    Metric {
        id: "mae_penumbra",
        name: "penumbra error",
        label: "mean absolute error in the reference's penumbra (mae_penumbra, 0–1)",
        value: |r| r.error.as_ref().and_then(|e| e.mae_penumbra),
    },
    Metric {
        id: "flip",
        name: "FLIP",
        label: "mean FLIP error of the shaded view (flip, 0–1)",
        value: |r| r.error.as_ref().and_then(|e| e.flip),
    },
];

/// Times a cost can be measured in, for the per-phase charts: id, name.
const TIMES: [(&str, &str); 3] = [
    ("model_ms", "modelled time"),
    ("gpu_ms", "GPU time"),
    ("wall_ms", "wall time"),
];

fn phase_time(p: &Phase, id: &str) -> Option<f64> {
    match id {
        "model_ms" => p.model_ms,
        "gpu_ms" => p.gpu_ms,
        _ => Some(p.wall_ms),
    }
}

/// The series a run belongs to: `algorithm / backend`, the algorithm with its GPU pipeline where
/// the run names one ([`RunRecord::algorithm_label`]).
pub fn series_name(r: &RunRecord) -> String {
    format!("{} / {}", r.algorithm_label(), r.backend)
}

/// The points of one algorithm on one execution.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// `algorithm / backend`.
    pub name: String,
    pub algorithm: String,
    pub backend: Backend,
    /// Sorted by x.
    pub points: Vec<(f64, f64)>,
    /// Error bars `(x, low, high)`: the 95% interval of a measured median
    /// ([`measured_interval`]); empty for other figures.
    pub intervals: Vec<(f64, f64, f64)>,
}

/// The confidence interval of a run's measured median `id` (`wall_ms` or `gpu_ms`) from its
/// samples ([`crate::harness::measure::Spread`]); `None` for one sample or none.
pub fn measured_interval(r: &RunRecord, id: &str) -> Option<[f64; 2]> {
    let m = r.measured.as_ref()?;
    let s = match id {
        "wall_ms" => Some(&m.wall_ms),
        "gpu_ms" => m.gpu_ms.as_ref(),
        _ => None,
    }?;
    (s.samples.len() > 1).then_some(s.ci)
}

/// A panel of points: lines through each series' points, or a scatter with a Pareto front.
#[derive(Clone, Debug)]
pub struct XyChart {
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub lines: bool,
    /// Points no other point of this panel beats on both axes (lower is better on both), by x.
    pub front: Option<Vec<(f64, f64)>>,
    /// A linear x axis always (frame numbers), where it would otherwise turn logarithmic over a
    /// wide range ([`wants_log`]).
    pub linear_x: bool,
}

#[derive(Clone, Debug)]
pub struct Bar {
    pub name: String,
    /// (phase, value), in the run's phase order.
    pub parts: Vec<(String, f64)>,
}

/// Stacked bars of one algorithm's phases; the phases are shades of `color`.
#[derive(Clone, Debug)]
pub struct Stacked {
    pub y_label: String,
    pub bars: Vec<Bar>,
}

#[derive(Clone, Debug)]
pub enum Kind {
    Xy(XyChart),
    Stacked(Stacked),
}

/// One plot of a figure.
#[derive(Clone, Debug)]
pub struct Panel {
    pub title: String,
    pub kind: Kind,
}

impl Panel {
    /// The series drawn in the panel: `algorithm / backend` of an xy panel, the phases of a
    /// stacked one.
    pub fn series_names(&self) -> Vec<String> {
        match &self.kind {
            Kind::Xy(c) => c.series.iter().map(|s| s.name.clone()).collect(),
            Kind::Stacked(s) => phase_names(&s.bars),
        }
    }
}

/// One chart (a figure of one or more panels) to draw.
#[derive(Clone, Debug)]
pub struct Spec {
    /// File stem under `charts/`.
    pub file: String,
    pub title: String,
    /// The case shown: the parameters held fixed.
    pub case: String,
    /// How to read the chart, for the report.
    pub caption: String,
    pub panels: Vec<Panel>,
}

/// A chart on disk, relative to the report folder.
#[derive(Clone, Debug)]
pub struct Written {
    pub file: String,
    pub png: String,
    pub svg: String,
    pub title: String,
    pub case: String,
    pub caption: String,
}

/// Every chart `records` support, in report order: quality against cost at the base point,
/// figures against each sweep axis, per-phase times. Failed runs are left out.
pub fn plan(records: &[RunRecord]) -> Vec<Spec> {
    let ok: Vec<&RunRecord> = records.iter().filter(|r| r.failure.is_none()).collect();
    let mut specs = Vec::new();
    if let Some(summary) = super::summary::Summary::of(&ok) {
        specs.extend(summary.charts());
    }
    for axis in Axis::ALL {
        let Some(slices) = axis_slices(&ok, axis) else {
            continue;
        };
        for m in &METRICS {
            let measured = crate::counters::kind(m.id) == Some(crate::counters::Kind::Measured);
            let mut panels = Vec::new();
            let mut intervals = false;
            for (label, slice) in &slices.slices {
                let mut series = collect_series(slice, |r| Some((axis.value(r)?, (m.value)(r)?)));
                if measured {
                    for s in &mut series {
                        s.intervals = slice
                            .iter()
                            .filter(|r| series_name(r) == s.name)
                            .filter_map(|r| {
                                let [lo, hi] = measured_interval(r, m.id)?;
                                Some((axis.value(r)?, lo, hi))
                            })
                            .filter(|&(x, lo, hi)| plottable(x) && plottable(lo) && plottable(hi))
                            .collect();
                        intervals |= !s.intervals.is_empty();
                    }
                }
                let mut ps = per_execution(series, |_| XyChart {
                    x_label: axis.label().into(),
                    y_label: m.label.into(),
                    series: vec![],
                    lines: true,
                    front: None,
                    linear_x: false,
                });
                // A panel whose every line is one point shows no trend against the axis (an
                // execution that ran at one value only): its value is in the tables.
                ps.retain(|p| match &p.kind {
                    Kind::Xy(c) => c.series.iter().any(|s| s.points.len() > 1),
                    Kind::Stacked(_) => true,
                });
                if slices.slices.len() > 1 {
                    for p in &mut ps {
                        p.title = format!("{}, {label}", p.title);
                    }
                }
                panels.extend(ps);
            }
            if panels.is_empty() {
                continue;
            }
            let mut caption = if slices.slices.len() > 1 {
                format!(
                    "One panel per execution and per value of the other swept parameters \
                     ({} of {} such slices with two or more points), one line per algorithm",
                    slices.slices.len(),
                    slices.of
                )
            } else {
                "One panel per execution, one line per algorithm".into()
            };
            caption.push_str(if intervals {
                " through the medians of its timed iterations; bars: the 95% interval of each \
                 median (order statistics of the samples)."
            } else {
                "."
            });
            specs.push(Spec {
                file: format!("{}_vs_{}", m.id, axis.id()),
                title: format!("{} vs. {}{}", m.name, axis.name(), axis.meaning()),
                case: slices.fixed.clone(),
                caption,
                panels,
            });
        }
    }
    specs.extend(phase_charts(&ok));
    specs.extend(phase_grids(&ok));
    specs.extend(flicker_charts(&ok));
    specs
}

/// Per algorithm of an animated sweep, at the base point: the flicker of each frame against
/// the one before ([`crate::harness::animation`]), one line per execution.
fn flicker_charts(ok: &[&RunRecord]) -> Vec<Spec> {
    let Some((base, case)) = super::summary::base_case(ok) else {
        return vec![];
    };
    let at: Vec<&RunRecord> = ok
        .iter()
        .copied()
        .filter(|r| r.animation.is_some() && super::summary::case_key(r) == base)
        .collect();
    let mut algs: Vec<&str> = at.iter().map(|r| r.algorithm.as_str()).collect();
    algs.sort_by_key(|a| style::algorithm_rank(a));
    algs.dedup();
    algs.into_iter()
        .map(|alg| {
            let mine: Vec<&RunRecord> = at.iter().copied().filter(|r| r.algorithm == alg).collect();
            let series = mine
                .iter()
                .map(|r| Series {
                    name: series_name(r),
                    algorithm: r.algorithm.clone(),
                    backend: r.backend,
                    points: r.animation.as_ref().map_or(vec![], |a| {
                        a.flicker_per_frame
                            .iter()
                            .enumerate()
                            .map(|(i, v)| ((i + 1) as f64, *v))
                            .filter(|p| plottable(p.1))
                            .collect()
                    }),
                    intervals: vec![],
                })
                .collect();
            let floor = mine
                .iter()
                .find_map(|r| r.animation.as_ref()?.flicker_floor)
                .map_or("no floor".to_string(), |f| {
                    format!(
                        "the reference against a reference of another seed: {}",
                        super::fmt_num(f)
                    )
                });
            Spec {
                file: format!("flicker_{alg}"),
                title: format!("flicker of {alg} per frame"),
                case: case.clone(),
                caption: format!(
                    "Mean over the pixels of |(V_t − V_t−1) − (R_t − R_t−1)|: the change from \
                     frame t − 1 to t that the reference does not have, one line per execution; \
                     lower is steadier. The floor of the measure ({floor})."
                ),
                panels: vec![Panel {
                    title: alg.to_string(),
                    kind: Kind::Xy(XyChart {
                        x_label: "frame".into(),
                        y_label: "flicker (visibility, 0–1)".into(),
                        series,
                        lines: true,
                        front: None,
                        linear_x: true,
                    }),
                }],
            }
        })
        .collect()
}

/// Splits `series` into panels: one per execution (in [`Backend`]'s order), each
/// split again into balanced parts when it holds more than [`MAX_SERIES`] algorithms. `chart`
/// gives a panel's axes for its execution; its series are filled in.
pub fn per_execution(series: Vec<Series>, chart: impl Fn(Backend) -> XyChart) -> Vec<Panel> {
    let mut backends: Vec<Backend> = series.iter().map(|s| s.backend).collect();
    backends.sort();
    backends.dedup();
    let mut panels = Vec::new();
    for b in backends {
        let mut mine: Vec<Series> = series.iter().filter(|s| s.backend == b).cloned().collect();
        mine.sort_by_key(|s| style::algorithm_rank(&s.algorithm));
        let parts = mine.len().div_ceil(MAX_SERIES);
        let per = mine.len().div_ceil(parts);
        for (i, chunk) in mine.chunks(per).enumerate() {
            let title = if parts > 1 {
                format!("{b} ({} of {parts})", i + 1)
            } else {
                b.name().to_string()
            };
            let mut c = chart(b);
            c.series = chunk.to_vec();
            panels.push(Panel {
                title,
                kind: Kind::Xy(c),
            });
        }
    }
    panels
}

/// Per-phase time at the base point: per time kind, one panel per algorithm with one bar per
/// execution that has that time.
fn phase_charts(ok: &[&RunRecord]) -> Vec<Spec> {
    let Some((base, case)) = super::summary::base_case(ok) else {
        return vec![];
    };
    let mut at: Vec<&RunRecord> = ok
        .iter()
        .copied()
        .filter(|r| super::summary::case_key(r) == base)
        .collect();
    at.sort_by_key(|r| (style::algorithm_rank(&r.algorithm), r.backend));
    let mut specs = Vec::new();
    for (id, name) in TIMES {
        let mut panels: Vec<Panel> = Vec::new();
        for r in &at {
            let Some(parts) = r
                .phases
                .iter()
                .map(|p| Some((p.name.clone(), phase_time(p, id)?)))
                .collect::<Option<Vec<_>>>()
                .filter(|p| !p.is_empty())
            else {
                continue;
            };
            let bar = Bar {
                name: r.backend.name().to_string(),
                parts,
            };
            match panels.iter_mut().find(|p| p.title == r.algorithm) {
                Some(Panel {
                    kind: Kind::Stacked(s),
                    ..
                }) => s.bars.push(bar),
                _ => panels.push(Panel {
                    title: r.algorithm.clone(),
                    kind: Kind::Stacked(Stacked {
                        y_label: format!("{name} (ms)"),
                        bars: vec![bar],
                    }),
                }),
            }
        }
        if panels.is_empty() {
            continue;
        }
        specs.push(Spec {
            file: format!("phases_{id}"),
            title: format!("{name} per phase"),
            case: case.clone(),
            caption: "One panel per algorithm, one bar per execution, split by phase.".into(),
            panels,
        });
    }
    specs
}

/// Most runs a per-run phase chart shows.
const GRID_BARS: usize = 30;

/// Per-phase time of every run of a series whose runs vary along two or more axes (such as
/// paper 003's grid of scenes × resolutions): one bar per run, named by the values that
/// vary, ordered by them. Where the phases' shares move along one axis and not another (fill
/// growing with the resolution, volume generation with the scene), the chart shows it.
fn phase_grids(ok: &[&RunRecord]) -> Vec<Spec> {
    let mut specs = Vec::new();
    let mut names: Vec<String> = ok.iter().map(|r| series_name(r)).collect();
    names.sort();
    names.dedup();
    for name in names {
        let runs: Vec<&RunRecord> = ok
            .iter()
            .copied()
            .filter(|r| series_name(r) == name)
            .collect();
        let varying: Vec<Axis> = Axis::ALL
            .into_iter()
            .filter(|a| {
                let mut v: Vec<Option<f64>> = runs.iter().map(|r| a.value(r)).collect();
                v.dedup();
                v.iter().any(|x| *x != v[0])
            })
            .collect();
        if varying.len() < 2 || runs.len() > GRID_BARS {
            continue;
        }
        let key = |r: &RunRecord| -> Vec<f64> {
            varying
                .iter()
                .map(|a| a.value(r).unwrap_or(f64::NAN))
                .collect()
        };
        let mut runs = runs;
        runs.sort_by(|a, b| {
            key(a)
                .iter()
                .zip(key(b))
                .map(|(x, y)| x.total_cmp(&y))
                .find(|o| o.is_ne())
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        for (id, label) in TIMES {
            let bars: Option<Vec<Bar>> = runs
                .iter()
                .map(|r| {
                    let parts = r
                        .phases
                        .iter()
                        .map(|p| Some((p.name.clone(), phase_time(p, id)?)))
                        .collect::<Option<Vec<_>>>()?;
                    let values: Vec<String> = varying.iter().map(|a| axis_value(*a, r)).collect();
                    Some(Bar {
                        name: values.join(" / "),
                        parts,
                    })
                })
                .collect();
            let Some(bars) = bars.filter(|b| !b.is_empty()) else {
                continue;
            };
            let axes: Vec<&str> = varying.iter().map(|a| a.name()).collect();
            specs.push(Spec {
                file: format!(
                    "phases_grid_{id}_{}",
                    name.replace(" / ", "_").replace(['/', ' '], "_")
                ),
                title: format!("{label} per phase, every run of {name}"),
                case: format!("{}; varying {}", runs[0].scene, axes.join(" and ")),
                caption: format!(
                    "One bar per run, named and ordered by what varies: {}.",
                    axes.join(", then ")
                ),
                panels: vec![Panel {
                    title: name.clone(),
                    kind: Kind::Stacked(Stacked {
                        y_label: format!("{label} (ms)"),
                        bars,
                    }),
                }],
            });
        }
    }
    specs
}

/// A run's value on `axis`, short, for a bar's name.
fn axis_value(axis: Axis, r: &RunRecord) -> String {
    let p = &r.params;
    match axis {
        Axis::Triangles => format!("{} tris", p.triangles),
        Axis::LightSize => format!("light {}", fmt_num(p.light_size as f64)),
        Axis::MapResolution => format!("map {}", p.map_resolution),
        Axis::TileSize => format!("tile {}", p.tile_size),
        Axis::ImagePixels => format!("{}×{}", p.image[0], p.image[1]),
        Axis::OccluderHeight => p
            .occluder_height
            .map_or("-".into(), |h| format!("height {}", fmt_num(h as f64))),
        Axis::OccluderOffset => p
            .occluder_offset
            .map_or("-".into(), |d| format!("offset {}", fmt_num(d as f64))),
        Axis::Cores => p.cores.map_or("-".into(), |c| format!("{c} cores")),
    }
}

/// Most slices of a chart against an axis ([`axis_slices`]); each is a row of panels.
pub const MAX_SLICES: usize = 6;

/// The slices of runs along one axis ([`axis_slices`]).
struct Slices<'a> {
    /// What every slice holds fixed: `scene; light size 0.5, map 256, …`.
    fixed: String,
    /// Per slice, what sets it apart from the others (empty for one slice) and its runs.
    slices: Vec<(String, Vec<&'a RunRecord>)>,
    /// How many slices had two or more values of the axis (more than [`MAX_SLICES`] are cut
    /// to those with the most values).
    of: usize,
}

/// The parameters of `r` other than `except`, one entry per axis of [`Axis::ALL`] (`None`
/// where the run has no value for it).
fn case_fields(r: &RunRecord, except: Option<Axis>) -> Vec<Option<String>> {
    let p = &r.params;
    Axis::ALL
        .iter()
        .map(|a| match a {
            _ if Some(*a) == except => None,
            Axis::Triangles => Some(format!("{} triangles", p.triangles)),
            Axis::LightSize => Some(format!("light size {}", fmt_num(p.light_size as f64))),
            Axis::MapResolution => Some(format!("map {}", p.map_resolution)),
            Axis::TileSize => Some(format!("tile {}", p.tile_size)),
            Axis::ImagePixels => Some(format!("image {}×{}", p.image[0], p.image[1])),
            Axis::OccluderHeight => p
                .occluder_height
                .map(|h| format!("occluder height {}", fmt_num(h as f64))),
            Axis::OccluderOffset => p
                .occluder_offset
                .map(|d| format!("occluder offset {}", fmt_num(d as f64))),
            Axis::Cores => p.cores.map(|c| format!("{c} cores")),
        })
        .collect()
}

/// The parameters of `r` other than `except`, for a title: `scene; light size 0.5, map 256, …`.
pub fn describe_case(r: &RunRecord, except: Option<Axis>) -> String {
    let fixed: Vec<String> = case_fields(r, except).into_iter().flatten().collect();
    format!("{}; {}", r.scene, fixed.join(", "))
}

/// The runs along which `axis` varies with every other axis (and the scene) fixed, one slice
/// per combination of the other parameters that has two or more values of `axis`: one for a
/// sweep of one axis at a time (through its base point), one per value of the other axes for
/// a grid sweep, so every point is on a line. When each scene has one triangle count (levels
/// of detail as scenarios, [`super::combine`]), the scene does not split the slices along
/// the triangle axis. `None` when no slice has two values.
fn axis_slices<'a>(runs: &[&'a RunRecord], axis: Axis) -> Option<Slices<'a>> {
    let scene_sets_triangles = axis == Axis::Triangles && {
        let mut seen: Vec<(&str, u32)> = Vec::new();
        runs.iter()
            .all(|r| match seen.iter().find(|(s, _)| *s == r.scene) {
                Some((_, t)) => *t == r.params.triangles,
                None => {
                    seen.push((&r.scene, r.params.triangles));
                    true
                }
            })
    };
    let rest = |r: &RunRecord| -> String {
        let others: Vec<String> = Axis::ALL
            .iter()
            .filter(|a| **a != axis)
            .map(|a| format!("{:?}", a.value(r)))
            .collect();
        let scene = if scene_sets_triangles { "" } else { &r.scene };
        format!("{scene}|{}", others.join("|"))
    };
    let mut slices: Vec<(String, Vec<f64>)> = Vec::new();
    for r in runs {
        let Some(x) = axis.value(r) else { continue };
        let key = rest(r);
        match slices.iter_mut().find(|(k, _)| *k == key) {
            Some((_, xs)) if !xs.contains(&x) => xs.push(x),
            Some(_) => {}
            None => slices.push((key, vec![x])),
        }
    }
    slices.retain(|s| s.1.len() >= 2);
    let of = slices.len();
    if of == 0 {
        return None;
    }
    // The slices with the most values, in the order first seen (a sweep's base point first).
    let mut by_size: Vec<usize> = (0..of).collect();
    by_size.sort_by_key(|&i| std::cmp::Reverse(slices[i].1.len()));
    by_size.truncate(MAX_SLICES);
    by_size.sort();
    let members: Vec<Vec<&RunRecord>> = by_size
        .iter()
        .map(|&i| {
            runs.iter()
                .copied()
                .filter(|r| axis.value(r).is_some() && rest(r) == slices[i].0)
                .collect()
        })
        .collect();
    let fields: Vec<Vec<Option<String>>> = members
        .iter()
        .map(|m| case_fields(m[0], Some(axis)))
        .collect();
    let common = |k: usize| fields.iter().all(|f| f[k] == fields[0][k]);
    let fixed: Vec<String> = (0..Axis::ALL.len())
        .filter(|&k| common(k))
        .filter_map(|k| fields[0][k].clone())
        .collect();
    let scenes = |m: &[&RunRecord]| {
        let mut v: Vec<&str> = m.iter().map(|r| r.scene.as_str()).collect();
        v.dedup();
        v.join(", ")
    };
    let slices = members
        .iter()
        .zip(&fields)
        .map(|(m, f)| {
            let own: Vec<String> = (0..Axis::ALL.len())
                .filter(|&k| !common(k))
                .filter_map(|k| f[k].clone())
                .collect();
            (own.join(", "), m.clone())
        })
        .collect();
    Some(Slices {
        fixed: format!("{}; {}", scenes(&members[0]), fixed.join(", ")),
        slices,
        of,
    })
}

/// Groups points by series (in order of first appearance), each sorted by x.
pub fn collect_series(
    runs: &[&RunRecord],
    point: impl Fn(&RunRecord) -> Option<(f64, f64)>,
) -> Vec<Series> {
    let mut series: Vec<Series> = Vec::new();
    for r in runs {
        let Some(p) = point(r).filter(|(x, y)| x.is_finite() && y.is_finite()) else {
            continue;
        };
        let name = series_name(r);
        match series.iter_mut().find(|s| s.name == name) {
            Some(s) => s.points.push(p),
            None => series.push(Series {
                name,
                algorithm: match &r.variant {
                    Some(v) => format!("{} ({v})", r.algorithm),
                    None => r.algorithm.clone(),
                },
                backend: r.backend,
                points: vec![p],
                intervals: vec![],
            }),
        }
    }
    for s in &mut series {
        s.points
            .sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    }
    series
}

/// Smallest and largest magnitude a chart shows (zero is shown too). Beyond them an axis range
/// overflows (1.5 × 1.7e308 is infinite) or a log axis spans thousands of decades, and the
/// chart library can loop for ever computing ticks.
pub const PLOT_RANGE: (f64, f64) = (1e-30, 1e30);

/// Whether a chart can show `v` ([`PLOT_RANGE`]).
pub fn plottable(v: f64) -> bool {
    v == 0.0 || (v.is_finite() && (PLOT_RANGE.0..=PLOT_RANGE.1).contains(&v.abs()))
}

/// The records as the charts may see them: every figure a chart cannot show ([`plottable`])
/// removed (a run whose wall time is such a figure is left out whole), with one warning per
/// figure naming the run and the figure. Planning only ever sees these copies.
pub fn chartable(records: &[RunRecord]) -> (Vec<RunRecord>, Vec<String>) {
    let mut warnings = Vec::new();
    let mut out = Vec::with_capacity(records.len());
    for r in records {
        let mut warn = |figure: &str, v: f64| {
            warnings.push(format!(
                "run {}: {figure} = {v:e} is outside the range a chart can show (0, or {:e} to \
                 {:e} in magnitude); left out of the charts",
                r.case_id(),
                PLOT_RANGE.0,
                PLOT_RANGE.1
            ))
        };
        let mut keep = |figure: &str, v: Option<f64>| match v {
            Some(v) if !plottable(v) => {
                warn(figure, v);
                None
            }
            v => v,
        };
        if !plottable(r.wall_ms) {
            keep("wall_ms", Some(r.wall_ms));
            continue;
        }
        let mut c = r.clone();
        c.model_ms = keep("model_ms", c.model_ms);
        c.gpu_ms = keep("gpu_ms", c.gpu_ms);
        c.counters
            .0
            .retain(|name, v| keep(&format!("counters.{name}"), Some(*v)).is_some());
        c.phases.retain_mut(|p| {
            p.model_ms = keep(&format!("phase {} model_ms", p.name), p.model_ms);
            p.gpu_ms = keep(&format!("phase {} gpu_ms", p.name), p.gpu_ms);
            keep(&format!("phase {} wall_ms", p.name), Some(p.wall_ms)).is_some()
        });
        if let Some(e) = &c.error {
            let mut figures = e.named().to_vec();
            figures.push(("mae_shadow_receivers", e.mae_shadow_receivers));
            let bad = figures
                .iter()
                .filter(|(name, v)| keep(&format!("error.{name}"), *v).is_none() && v.is_some())
                .count();
            if bad > 0 {
                c.error = None;
            }
        }
        out.push(c);
    }
    (out, warnings)
}

/// The points that no other point beats on both coordinates (lower is better), by x.
pub fn pareto_front(points: impl Iterator<Item = (f64, f64)>) -> Vec<(f64, f64)> {
    let mut pts: Vec<(f64, f64)> = points.collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut front: Vec<(f64, f64)> = Vec::new();
    for p in pts {
        if front.last().is_none_or(|l| p.1 < l.1) {
            front.push(p);
        }
    }
    front
}

/// Whether values span enough (a decade or more, all positive) for a log axis.
pub fn wants_log(values: &[f64]) -> bool {
    let min = values.iter().copied().fold(f64::INFINITY, f64::min);
    let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    min > 0.0 && max / min >= 10.0
}

/// Draws `spec` into `dir` as `<file>.png` ([`draw_rgb`]) and `<file>.svg` ([`draw_svg`]).
///
/// Errors: the chart font cannot be loaded ([`super::font::ensure`]), the chart library fails
/// to draw, or a file cannot be written; each names the file.
pub fn render(spec: &Spec, dir: &Path) -> Result<Written> {
    super::font::ensure()?;
    let size = spec.size();
    let png = dir.join(format!("{}.png", spec.file));
    let svg = dir.join(format!("{}.svg", spec.file));
    let fail =
        |path: &Path, e: String| Error::Other(format!("{}: drawing chart: {e}", path.display()));
    let buf = draw_rgb(spec).map_err(|e| fail(&png, e))?;
    image::RgbImage::from_raw(size.0, size.1, buf)
        .expect("buffer sized to the image")
        .save(&png)
        .map_err(|e| fail(&png, e.to_string()))?;
    let text = draw_svg(spec).map_err(|e| fail(&svg, e))?;
    std::fs::write(&svg, text).map_err(|e| Error::io(&svg, e))?;
    Ok(Written {
        file: spec.file.clone(),
        png: format!("charts/{}.png", spec.file),
        svg: format!("charts/{}.svg", spec.file),
        title: spec.title.clone(),
        case: spec.case.clone(),
        caption: spec.caption.clone(),
    })
}

/// Draws `spec` in memory: RGB pixels, row by row, 3 bytes a pixel, [`Spec::size`] pixels
/// (what [`render`] saves as PNG). The chart font must be registered first
/// ([`super::font::ensure`]); without it text is drawn with whatever plotters finds.
///
/// Errors: the chart library's message when it fails to draw.
pub fn draw_rgb(spec: &Spec) -> std::result::Result<Vec<u8>, String> {
    let size = spec.size();
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        draw(&root, spec)?;
        root.present().map_err(err)?;
    }
    Ok(buf)
}

/// Draws `spec` in memory as an SVG document of [`Spec::size`] pixels (what [`render`] saves
/// as SVG); the font as for [`draw_rgb`].
///
/// Errors: the chart library's message when it fails to draw.
pub fn draw_svg(spec: &Spec) -> std::result::Result<String, String> {
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, spec.size()).into_drawing_area();
        draw(&root, spec)?;
        root.present().map_err(err)?;
    }
    Ok(text)
}

/// Height of the title block.
const HEADER: u32 = 64;
/// Width of the legend beside the panels of an xy figure.
const LEGEND_WIDTH: u32 = 230;
/// Width of the legend inside a stacked panel.
const PANEL_LEGEND_WIDTH: u32 = 150;
const PANEL_HEIGHT: u32 = 400;
const FONT: &str = super::font::FAMILY;

impl Spec {
    /// Panel grid columns and rows, and one panel's width.
    fn grid(&self) -> (u32, u32, u32) {
        let n = self.panels.len().max(1) as u32;
        // Two columns at most: a figure of 2 × 540 px and its legend fits a 1400 px page at
        // full size (three columns were scaled to 70%, their text too small to read).
        let cols = n.min(2);
        let rows = n.div_ceil(cols);
        let width = match self.panels.first().map(|p| &p.kind) {
            Some(Kind::Stacked(s)) if n == 1 => {
                (260 + 120 * s.bars.len() as u32).max(700) + PANEL_LEGEND_WIDTH
            }
            Some(Kind::Stacked(_)) => 560,
            _ if n == 1 => 760,
            _ => 540,
        };
        (cols, rows, width)
    }

    /// Pixel size of the figure.
    pub fn size(&self) -> (u32, u32) {
        let (cols, rows, w) = self.grid();
        let legend = if self.is_xy() { LEGEND_WIDTH } else { 0 };
        let legend_h = if self.is_xy() {
            40 + 22 * self.legend().len() as u32
        } else {
            0
        };
        (
            cols * w + legend,
            HEADER + (rows * PANEL_HEIGHT).max(legend_h),
        )
    }

    fn is_xy(&self) -> bool {
        self.panels.iter().any(|p| matches!(p.kind, Kind::Xy(_)))
    }

    /// The legend of an xy figure: every algorithm drawn (its colour), every execution drawn
    /// (its marker and line), and the Pareto front where a panel has one.
    pub fn legend(&self) -> Vec<LegendEntry> {
        let mut algorithms: Vec<String> = Vec::new();
        let mut backends: Vec<Backend> = Vec::new();
        let mut lines = false;
        let mut front = false;
        for p in &self.panels {
            if let Kind::Xy(c) = &p.kind {
                lines |= c.lines;
                front |= c.front.is_some();
                for s in &c.series {
                    if !algorithms.contains(&s.algorithm) {
                        algorithms.push(s.algorithm.clone());
                    }
                    if !backends.contains(&s.backend) {
                        backends.push(s.backend);
                    }
                }
            }
        }
        algorithms.sort_by_key(|a| style::algorithm_rank(a));
        backends.sort();
        let mut entries: Vec<LegendEntry> = algorithms
            .into_iter()
            .map(|a| LegendEntry {
                color: style::algorithm_color(&a),
                label: a,
                marker: None,
                dash: lines.then_some(Dash::Solid),
                square: !lines,
            })
            .collect();
        entries.extend(backends.into_iter().map(|b| {
            let (m, d) = style::execution_style(b);
            LegendEntry {
                label: b.name().to_string(),
                color: style::INK,
                marker: Some(m),
                dash: lines.then_some(d),
                square: false,
            }
        }));
        if front {
            entries.push(LegendEntry {
                label: "Pareto front".into(),
                color: style::INK,
                marker: None,
                dash: Some(Dash::Dashed),
                square: false,
            });
        }
        entries
    }
}

/// One line of a legend.
#[derive(Clone, Debug, PartialEq)]
pub struct LegendEntry {
    pub label: String,
    pub color: RGBColor,
    pub marker: Option<Marker>,
    pub dash: Option<Dash>,
    /// A filled square (an algorithm of a scatter, a phase of a bar).
    pub square: bool,
}

type DrawResult = std::result::Result<(), String>;

/// The label sizes and grey grid lines of every chart's mesh.
fn grid_style<'m, 'a, 'b, X: Ranged, Y: Ranged, DB: DrawingBackend>(
    mesh: &'m mut MeshStyle<'a, 'b, X, Y, DB>,
) -> &'m mut MeshStyle<'a, 'b, X, Y, DB> {
    mesh.label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(RGBColor(240, 240, 240))
}

fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, spec: &Spec) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let (header, body) = root.split_vertically(HEADER);
    header
        .draw(&Text::new(
            spec.title.clone(),
            (16, 10),
            TextStyle::from((FONT, 22).into_font()).color(&BLACK),
        ))
        .map_err(err)?;
    header
        .draw(&Text::new(
            spec.case.clone(),
            (16, 38),
            TextStyle::from((FONT, 15).into_font()).color(&RGBColor(70, 70, 70)),
        ))
        .map_err(err)?;
    let (cols, _, w) = spec.grid();
    let (grid, legend) = body.split_horizontally(cols * w);
    for (i, panel) in spec.panels.iter().enumerate() {
        let (c, r) = (i as u32 % cols, i as u32 / cols);
        let area = grid
            .clone()
            .shrink((c * w, r * PANEL_HEIGHT), (w, PANEL_HEIGHT));
        let (head, plot) = area.split_vertically(26);
        head.draw(&Text::new(
            panel.title.clone(),
            (w as i32 / 2, 6),
            TextStyle::from((FONT, 17).into_font())
                .color(&BLACK)
                .pos(Pos::new(HPos::Center, VPos::Top)),
        ))
        .map_err(err)?;
        match &panel.kind {
            Kind::Xy(c) => draw_xy(&plot, c)?,
            Kind::Stacked(s) => {
                let (pw, _) = plot.dim_in_pixel();
                let (bars, key) = plot.split_horizontally(pw.saturating_sub(PANEL_LEGEND_WIDTH));
                draw_stacked(&bars, s)?;
                let entries: Vec<LegendEntry> = phase_names(&s.bars)
                    .into_iter()
                    .enumerate()
                    .map(|(i, p)| LegendEntry {
                        label: p,
                        color: style::phase_color(i),
                        marker: None,
                        dash: None,
                        square: true,
                    })
                    .collect();
                draw_legend(&key, &entries, 30)?;
            }
        }
    }
    if spec.is_xy() {
        draw_legend(&legend, &spec.legend(), 36)?;
    }
    Ok(())
}

/// A linear axis (of values, or of log10 of values) with given tick positions.
#[derive(Clone)]
struct TickAxis {
    range: Range<f64>,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl Ranged for TickAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let t = (v - self.range.start) / (self.range.end - self.range.start);
        limit.0 + ((limit.1 - limit.0) as f64 * t).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

/// The axis for `values`: logarithmic (in log10 units, ticks at the decades, and at 2× and 5×
/// when it spans under three decades) when they span a decade or more, else linear with ticks
/// at 1, 2 or 5 × 10^k (from zero when `from_zero` and all are non-negative).
fn tick_axis(values: &[f64], from_zero: bool, log: bool) -> (TickAxis, bool) {
    let min = values.iter().copied().fold(f64::INFINITY, f64::min);
    let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if log && wants_log(values) {
        let (lo, hi) = (min.log10() - 0.12, max.log10() + 0.12);
        let mut bold = Vec::new();
        let mut light = Vec::new();
        let decades = hi - lo;
        let mults: &[f64] = if decades < 3.0 {
            &[1.0, 2.0, 5.0]
        } else {
            &[1.0]
        };
        let step = if decades > 8.0 { 2 } else { 1 };
        for k in (lo.floor() as i32)..=(hi.ceil() as i32) {
            for m in 1..10 {
                let v = (m as f64).log10() + k as f64;
                if v < lo || v > hi {
                    continue;
                }
                if mults.contains(&(m as f64)) && (m != 1 || k.rem_euclid(step) == 0) {
                    bold.push(v);
                } else {
                    light.push(v);
                }
            }
        }
        return (
            TickAxis {
                range: lo..hi,
                bold,
                light,
            },
            true,
        );
    }
    let span = if max > min {
        max - min
    } else {
        max.abs().max(1.0)
    };
    let lo = if from_zero && min >= 0.0 {
        0.0
    } else {
        min - span * 0.06
    };
    let hi = max + span * 0.06;
    let raw = (hi - lo) / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let mut bold = Vec::new();
    let mut v = (lo / step).ceil() * step;
    while v <= hi + step * 1e-9 {
        // Snap away float noise (0.30000000000000004).
        bold.push((v / step).round() * step);
        v += step;
    }
    let light = bold
        .iter()
        .map(|b| b + step / 2.0)
        .filter(|v| *v < hi)
        .collect();
    (
        TickAxis {
            range: lo..hi,
            bold,
            light,
        },
        false,
    )
}

/// How an axis labels its ticks: one notation for every tick, so labels never mix `1e7`,
/// `5.00e6` and `500000`. Decimal (`500`, `0.02`) while every tick value lies in
/// [1e-3, 1e5), else `m×10^k` written `5e6` on a log axis and `1.5e6` on a linear one.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TickFormat {
    log: bool,
    scientific: bool,
}

impl TickFormat {
    fn of(axis: &TickAxis, log: bool) -> TickFormat {
        let value = |v: f64| if log { 10f64.powf(v) } else { v };
        let scientific = axis
            .bold
            .iter()
            .map(|&v| value(v).abs())
            .filter(|&a| a > 0.0)
            .any(|a| !(1e-3..1e5).contains(&a));
        TickFormat { log, scientific }
    }

    /// The label of tick `v` (log10 of the value on a log axis).
    fn label(self, v: f64) -> String {
        if self.log {
            let k = v.floor();
            // The mantissa of a tick at m×10^k is a whole number (ticks sit at 1..9 × 10^k).
            let mut m = 10f64.powf(v - k).round();
            let mut k = k as i32;
            if m >= 10.0 {
                m = 1.0;
                k += 1;
            }
            return if self.scientific {
                format!("{m}e{k}")
            } else {
                fmt_num(m * 10f64.powi(k))
            };
        }
        if v == 0.0 || !self.scientific {
            return fmt_num(v);
        }
        let k = v.abs().log10().floor() as i32;
        let m = format!("{:.2}", v / 10f64.powi(k));
        let m = m.trim_end_matches('0').trim_end_matches('.');
        format!("{m}e{k}")
    }
}

fn draw_xy<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, c: &XyChart) -> DrawResult {
    let xs: Vec<f64> = c
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .collect();
    let ys: Vec<f64> = c
        .series
        .iter()
        .flat_map(|s| {
            let bars = s.intervals.iter().flat_map(|b| [b.1, b.2]);
            s.points.iter().map(|p| p.1).chain(bars)
        })
        .collect();
    if xs.is_empty() {
        return Ok(());
    }
    let (xa, xlog) = tick_axis(&xs, false, !c.linear_x);
    let (ya, ylog) = tick_axis(&ys, true, true);
    let (xf, yf) = (TickFormat::of(&xa, xlog), TickFormat::of(&ya, ylog));
    let tx = move |v: f64| if xlog { v.log10() } else { v };
    let ty = move |v: f64| if ylog { v.log10() } else { v };
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .margin_right(22)
        .x_label_area_size(52)
        .y_label_area_size(78)
        .build_cartesian_2d(xa, ya)
        .map_err(err)?;
    let log_note = |label: &str, log: bool| {
        if log {
            format!("{label}, log scale")
        } else {
            label.to_string()
        }
    };
    grid_style(
        chart
            .configure_mesh()
            .x_desc(log_note(&c.x_label, xlog))
            .y_desc(log_note(&c.y_label, ylog))
            .x_label_formatter(&|v| xf.label(*v))
            .y_label_formatter(&|v| yf.label(*v)),
    )
    .draw()
    .map_err(err)?;
    let (ox, oy) = area.get_base_pixel();
    let size = if c.lines { 5 } else { 7 };
    for s in &c.series {
        let col = style::algorithm_color(&s.algorithm);
        let (_, dash) = style::execution_style(s.backend);
        let pts: Vec<(f64, f64)> = s.points.iter().map(|&(x, y)| (tx(x), ty(y))).collect();
        if c.lines && pts.len() > 1 {
            draw_line(&mut chart, &pts, col.stroke_width(2), dash)?;
        }
    }
    // Every marker's pixel, then a sideways offset for markers that would cover each other.
    let mut marks: Vec<(usize, (i32, i32))> = Vec::new();
    for (si, s) in c.series.iter().enumerate() {
        for &(x, y) in &s.points {
            let (px, py) = chart.backend_coord(&(tx(x), ty(y)));
            marks.push((si, (px - ox, py - oy)));
        }
    }
    let dx = dodge(&marks.iter().map(|m| m.1).collect::<Vec<_>>(), size);
    for (si, s) in c.series.iter().enumerate() {
        let col = style::algorithm_color(&s.algorithm);
        for &(x, lo, hi) in &s.intervals {
            // A vertical bar from the interval's low to its high end, with caps, beside its
            // marker when that was moved.
            let (bx, by0) = chart.backend_coord(&(tx(x), ty(lo)));
            let (_, by1) = chart.backend_coord(&(tx(x), ty(hi)));
            let shift = marks
                .iter()
                .zip(&dx)
                .find(|((i, p), _)| *i == si && p.0 == bx - ox)
                .map_or(0, |(_, d)| *d);
            let (x0, y0, y1) = (bx - ox + shift, by0 - oy, by1 - oy);
            let stroke = col.stroke_width(1);
            for seg in [
                [(x0, y0), (x0, y1)],
                [(x0 - 4, y0), (x0 + 4, y0)],
                [(x0 - 4, y1), (x0 + 4, y1)],
            ] {
                area.draw(&PathElement::new(seg.to_vec(), stroke))
                    .map_err(err)?;
            }
        }
    }
    for ((si, (x, y)), d) in marks.iter().zip(&dx) {
        let s = &c.series[*si];
        let (marker, _) = style::execution_style(s.backend);
        let col = style::algorithm_color(&s.algorithm);
        draw_marker(area, (x + d, *y), marker, col, size)?;
    }
    if let Some(front) = &c.front {
        let pts: Vec<(f64, f64)> = front.iter().map(|&(x, y)| (tx(x), ty(y))).collect();
        draw_line(&mut chart, &pts, style::INK.stroke_width(1), Dash::Dashed)?;
        for &p in &pts {
            chart
                .plotting_area()
                .draw(&Circle::new(p, 9, style::INK.stroke_width(1)))
                .map_err(err)?;
        }
    }
    Ok(())
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<TickAxis, TickAxis>>;

/// Sideways pixel offsets for markers of radius `size` at `at` (pixels) so that none covers
/// another: markers in one column (the same x) whose centres are closer than a marker's width
/// form a group, spread evenly about the column, 2·size + 1 pixels apart, in the order given.
/// Markers alone keep offset 0. The offsets are at most ±(n − 1)/2 · (2·size + 1) for a group
/// of n.
fn dodge(at: &[(i32, i32)], size: i32) -> Vec<i32> {
    let mut dx = vec![0; at.len()];
    let mut order: Vec<usize> = (0..at.len()).collect();
    order.sort_by_key(|&i| (at[i].0, at[i].1, i));
    let apart = 2 * size + 1;
    let mut start = 0;
    while start < order.len() {
        // A group: same column, each within a marker's width of the one above it.
        let mut end = start + 1;
        while end < order.len() {
            let (a, b) = (at[order[end - 1]], at[order[end]]);
            if a.0 != b.0 || b.1 - a.1 >= apart {
                break;
            }
            end += 1;
        }
        let mut group: Vec<usize> = order[start..end].to_vec();
        group.sort_unstable();
        let n = group.len() as i32;
        for (k, &i) in group.iter().enumerate() {
            // Centred: 0 for one, ±apart/2 for two, -apart, 0, apart for three, ...
            dx[i] = (2 * k as i32 - (n - 1)) * apart / 2;
        }
        start = end;
    }
    dx
}

fn draw_line<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    pts: &[(f64, f64)],
    style: ShapeStyle,
    dash: Dash,
) -> DrawResult {
    match dash {
        Dash::Solid => chart
            .draw_series(LineSeries::new(pts.iter().copied(), style))
            .map(|_| ()),
        Dash::Dashed => chart
            .draw_series(DashedLineSeries::new(pts.iter().copied(), 9, 5, style))
            .map(|_| ()),
        Dash::Dotted => chart
            .draw_series(DashedLineSeries::new(pts.iter().copied(), 2, 4, style))
            .map(|_| ()),
    }
    .map_err(err)
}

/// A filled marker of radius `size` pixels centred at pixel `(x, y)` of `area`.
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    (x, y): (i32, i32),
    marker: Marker,
    col: RGBColor,
    size: i32,
) -> DrawResult {
    let fill = col.filled();
    match marker {
        Marker::Circle => area.draw(&Circle::new((x, y), size, fill)),
        Marker::Square => area.draw(&Rectangle::new(
            [(x - size + 1, y - size + 1), (x + size - 1, y + size - 1)],
            fill,
        )),
        Marker::Triangle => area.draw(&Polygon::new(
            vec![
                (x, y - size - 1),
                (x + size + 1, y + size),
                (x - size - 1, y + size),
            ],
            fill,
        )),
        Marker::Diamond => area.draw(&Polygon::new(
            vec![
                (x, y - size - 1),
                (x + size + 1, y),
                (x, y + size + 1),
                (x - size - 1, y),
            ],
            fill,
        )),
    }
    .map_err(err)
}

fn phase_names(bars: &[Bar]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for b in bars {
        for (p, _) in &b.parts {
            if !names.contains(p) {
                names.push(p.clone());
            }
        }
    }
    names
}

fn draw_stacked<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, s: &Stacked) -> DrawResult {
    let bars = &s.bars;
    let phases = phase_names(bars);
    let total = |b: &Bar| b.parts.iter().map(|p| p.1).sum::<f64>();
    let top = bars.iter().map(total).fold(0.0, f64::max);
    let (ya, _) = tick_axis(&[0.0, if top > 0.0 { top } else { 1.0 }], true, true);
    let n = bars.len() as f64;
    let xa = TickAxis {
        range: -0.5..n - 0.5,
        bold: vec![],
        light: vec![],
    };
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .x_label_area_size(58)
        .y_label_area_size(78)
        .build_cartesian_2d(xa, ya)
        .map_err(err)?;
    grid_style(
        chart
            .configure_mesh()
            .disable_x_mesh()
            .y_desc(&s.y_label)
            .y_label_formatter(&|v| fmt_num(*v)),
    )
    .draw()
    .map_err(err)?;
    for (pi, phase) in phases.iter().enumerate() {
        let col = style::phase_color(pi);
        let rects = bars.iter().enumerate().filter_map(|(bi, b)| {
            let k = b.parts.iter().position(|p| p.0 == *phase)?;
            let below: f64 = b.parts[..k].iter().map(|p| p.1).sum();
            let x = bi as f64;
            Some([(x - 0.32, below), (x + 0.32, below + b.parts[k].1)])
        });
        let rects: Vec<[(f64, f64); 2]> = rects.collect();
        chart
            .draw_series(rects.iter().map(|c| Rectangle::new(*c, col.filled())))
            .map_err(err)?;
        // A white edge between stacked phases.
        chart
            .draw_series(
                rects
                    .iter()
                    .map(|c| Rectangle::new(*c, WHITE.stroke_width(1))),
            )
            .map_err(err)?;
    }
    // Bar names under the axis, on up to two lines so long names do not collide.
    let (ox, oy) = area.get_base_pixel();
    let style = TextStyle::from((FONT, 13).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Top));
    for (bi, b) in bars.iter().enumerate() {
        let (px, py) = chart.backend_coord(&(bi as f64, 0.0));
        let (x, y) = (px - ox, py - oy);
        for (li, line) in b.name.splitn(2, " / ").enumerate() {
            area.draw(&Text::new(
                line.to_string(),
                (x, y + 8 + 17 * li as i32),
                style.clone(),
            ))
            .map_err(err)?;
        }
    }
    Ok(())
}

/// A legend: per entry a swatch (line, marker or square in its colour) and its label.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[LegendEntry],
    top: i32,
) -> DrawResult {
    let style = TextStyle::from((FONT, 14).into_font()).color(&BLACK);
    for (i, e) in entries.iter().enumerate() {
        let y = top + 22 * i as i32;
        if e.square {
            area.draw(&Rectangle::new(
                [(14, y - 7), (28, y + 7)],
                e.color.filled(),
            ))
            .map_err(err)?;
        }
        if let Some(d) = e.dash {
            let s = e.color.stroke_width(2);
            match d {
                Dash::Solid => area.draw(&PathElement::new(vec![(6, y), (36, y)], s)),
                Dash::Dashed => area
                    .draw(&PathElement::new(vec![(6, y), (15, y)], s))
                    .and(area.draw(&PathElement::new(vec![(20, y), (29, y)], s))),
                Dash::Dotted => (0..6).try_for_each(|k| {
                    area.draw(&PathElement::new(vec![(6 + 6 * k, y), (8 + 6 * k, y)], s))
                }),
            }
            .map_err(err)?;
        }
        if let Some(m) = e.marker {
            draw_marker(area, (21, y), m, e.color, 5)?;
        }
        area.draw(&Text::new(e.label.clone(), (44, y - 8), style.clone()))
            .map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::testdata::record;

    /// Only the modelled machine has a core count: runs of other executions are left off the
    /// cores axis, so no chart plots their times against a parameter they ignore.
    #[test]
    fn a_grid_sweep_charts_every_point_on_a_line_one_row_of_panels_per_other_value() {
        let mut runs = Vec::new();
        for t in [500, 2000, 8000] {
            for l in [0.3f32, 0.6] {
                for b in [Backend::CpuNative, Backend::CpuModel] {
                    let mut r = record("pcss", b, t, 32);
                    r.params.light_size = l;
                    runs.push(r);
                }
            }
        }
        let specs = plan(&runs);
        let points = |file: &str| -> (usize, Vec<String>) {
            let s = specs.iter().find(|s| s.file == file).unwrap();
            let mut n = 0;
            for p in &s.panels {
                if let Kind::Xy(c) = &p.kind {
                    for ser in &c.series {
                        assert!(ser.points.len() >= 2, "{}: {:?}", p.title, ser.points);
                        n += ser.points.len();
                    }
                }
            }
            (n, s.panels.iter().map(|p| p.title.clone()).collect())
        };
        // 6 grid points per execution, each on a line of its row.
        let (n, titles) = points("wall_ms_vs_triangles");
        assert_eq!(n, 12, "{titles:?}");
        assert_eq!(titles.len(), 4, "{titles:?}");
        assert!(
            titles.contains(&"cpu-model, light size 0.6".to_string()),
            "{titles:?}"
        );
        let (n, titles) = points("wall_ms_vs_light_size");
        assert_eq!((n, titles.len()), (12, 6), "{titles:?}");
        assert!(
            titles.contains(&"cpu-native, 8000 triangles".to_string()),
            "{titles:?}"
        );
    }

    #[test]
    fn scenes_of_one_triangle_count_each_join_on_the_triangle_axis() {
        let runs: Vec<RunRecord> = [500, 2000, 8000]
            .iter()
            .map(|&t| {
                let mut r = record("pcss", Backend::CpuModel, t, 32);
                r.scene = format!("lod-{t}");
                r
            })
            .collect();
        let specs = plan(&runs);
        let s = specs
            .iter()
            .find(|s| s.file == "wall_ms_vs_triangles")
            .unwrap();
        let Kind::Xy(c) = &s.panels[0].kind else {
            panic!()
        };
        assert_eq!(c.series[0].points.len(), 3);
        assert!(
            s.case.starts_with("lod-500, lod-2000, lod-8000;"),
            "{}",
            s.case
        );
    }

    #[test]
    fn only_cpu_model_runs_are_placed_on_the_cores_axis() {
        for (backend, want) in [
            (Backend::CpuModel, Some(16.0)),
            (Backend::CpuNative, None),
            (Backend::Wgpu, None),
        ] {
            let mut r = record("soft_izb", backend, 100, 32);
            r.params.cores = Some(16);
            assert_eq!(Axis::Cores.value(&r), want, "{backend}");
        }
    }

    #[test]
    fn figures_a_chart_cannot_show_are_left_out_naming_the_run_and_figure() {
        assert!(plottable(0.0) && plottable(1e30) && plottable(-1e-30) && plottable(3.5));
        for v in [
            1.7e308,
            1e307,
            -1e31,
            1e-31,
            5e-324,
            f64::NAN,
            f64::INFINITY,
        ] {
            assert!(!plottable(v), "{v}");
        }
        let mut runs: Vec<RunRecord> = (1..=3)
            .map(|t| record("pcss", Backend::CpuModel, t * 100, 32))
            .collect();
        runs[1].model_ms = Some(1.7e308);
        runs[2].wall_ms = 1e307;
        let (shown, warnings) = chartable(&runs);
        assert_eq!(
            shown.len(),
            2,
            "the run with an absurd wall time is left out whole"
        );
        assert_eq!(shown[1].model_ms, None);
        assert_eq!(shown[0].model_ms, runs[0].model_ms);
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].contains(&runs[1].case_id()) && warnings[0].contains("model_ms"));
        assert!(warnings[1].contains(&runs[2].case_id()) && warnings[1].contains("wall_ms"));
        // Planning the shown runs terminates and draws only plottable values.
        for spec in plan(&shown) {
            for panel in &spec.panels {
                if let Kind::Xy(c) = &panel.kind {
                    for s in &c.series {
                        assert!(s.points.iter().all(|&(x, y)| plottable(x) && plottable(y)));
                    }
                }
            }
        }
    }

    fn files(specs: &[Spec]) -> Vec<String> {
        specs.iter().map(|s| s.file.clone()).collect()
    }

    fn xy(p: &Panel) -> &XyChart {
        match &p.kind {
            Kind::Xy(c) => c,
            Kind::Stacked(_) => panic!("not an xy panel"),
        }
    }

    #[test]
    fn charts_follow_the_axes_the_runs_vary_along() {
        // A triangle sweep at tile 32 and a tile sweep at the base triangle count, as an
        // `each` sweep gives: two axes vary; the rest are the same everywhere.
        let mut runs = Vec::new();
        for alg in ["pcss", "hard_shadow_map"] {
            for t in [100, 1000, 10000] {
                runs.push(record(alg, Backend::CpuModel, t, 32));
            }
            for tile in [16, 64] {
                runs.push(record(alg, Backend::CpuModel, 100, tile));
            }
        }
        let specs = plan(&runs);
        let names = files(&specs);
        for axis in ["triangles", "tile_size"] {
            for m in [
                "wall_ms",
                "model_ms",
                "modelled_memory_bytes",
                "fill",
                "overdraw_ratio",
                "mae_shadow",
            ] {
                assert!(
                    names.contains(&format!("{m}_vs_{axis}")),
                    "{m}_vs_{axis}: {names:?}"
                );
            }
            // No run has a GPU time.
            assert!(!names.contains(&format!("gpu_ms_vs_{axis}")), "{names:?}");
        }
        for axis in [
            "light_size",
            "map_resolution",
            "image_pixels",
            "cores",
            "occluder_height",
            "occluder_offset",
        ] {
            assert!(
                !names.iter().any(|n| n.ends_with(axis)),
                "{axis}: {names:?}"
            );
        }
        // The triangle chart holds tile 32 fixed: three points per algorithm, in x order, and
        // says so in its case line.
        let tri = specs
            .iter()
            .find(|s| s.file == "model_ms_vs_triangles")
            .unwrap();
        assert_eq!(tri.panels.len(), 1);
        let c = xy(&tri.panels[0]);
        assert_eq!(c.series.len(), 2);
        // Registered order: hard_shadow_map before pcss.
        assert_eq!(c.series[1].name, "pcss / cpu-model");
        let xs: Vec<f64> = c.series[1].points.iter().map(|p| p.0).collect();
        assert_eq!(xs, [100.0, 1000.0, 10000.0]);
        assert!(tri.case.contains("tile 32"), "{}", tri.case);
        assert!(!tri.case.contains("triangles"), "{}", tri.case);
        // The tile chart holds triangles at 100: tiles 16, 32 and 64.
        let tile = specs
            .iter()
            .find(|s| s.file == "modelled_memory_bytes_vs_tile_size")
            .unwrap();
        let c = xy(&tile.panels[0]);
        let hsm = c
            .series
            .iter()
            .find(|s| s.algorithm == "hard_shadow_map")
            .unwrap();
        let xs: Vec<f64> = hsm.points.iter().map(|p| p.0).collect();
        assert_eq!(xs, [16.0, 32.0, 64.0]);
        let r = runs
            .iter()
            .find(|r| r.algorithm == "hard_shadow_map" && r.params.tile_size == 64)
            .unwrap();
        assert_eq!(
            hsm.points[2].1,
            r.counters.get("mem_model.read_bytes").unwrap()
                + r.counters.get("mem_model.write_bytes").unwrap()
        );
    }

    /// Nine algorithms on three executions along one axis, as `quick.json` has.
    fn many() -> Vec<RunRecord> {
        let algs: Vec<&str> = crate::algorithms::ALGORITHMS.iter().map(|a| a.id).collect();
        let mut runs = Vec::new();
        for t in [500, 2000, 8000] {
            for a in &algs {
                for b in Backend::ALL {
                    let mut r = record(a, b, t, 32);
                    r.gpu_ms = (b == Backend::Wgpu).then_some(2.0);
                    runs.push(r);
                }
            }
        }
        runs
    }

    #[test]
    fn no_panel_holds_more_than_eight_series_and_each_panel_is_one_execution() {
        let runs = many();
        let specs = plan(&runs);
        for s in &specs {
            for p in &s.panels {
                let names = p.series_names();
                assert!(
                    names.len() <= MAX_SERIES,
                    "{} / {}: {names:?}",
                    s.file,
                    p.title
                );
                if let Kind::Xy(c) = &p.kind {
                    let mut b: Vec<Backend> = c.series.iter().map(|s| s.backend).collect();
                    b.dedup();
                    assert_eq!(b.len(), 1, "{}: {b:?}", s.file);
                }
            }
        }
        // 9 algorithms on one execution: split in two panels; every series still drawn once.
        let wall = specs
            .iter()
            .find(|s| s.file == "wall_ms_vs_triangles")
            .unwrap();
        let drawn: Vec<String> = wall.panels.iter().flat_map(|p| p.series_names()).collect();
        let mut expect: Vec<String> = runs.iter().map(series_name).collect();
        expect.sort();
        expect.dedup();
        let mut got = drawn.clone();
        got.sort();
        assert_eq!(got, expect);
        assert_eq!(
            wall.panels.len(),
            6,
            "{:?}",
            wall.panels.iter().map(|p| &p.title).collect::<Vec<_>>()
        );
        // GPU time exists on wgpu only: one execution.
        let gpu = specs
            .iter()
            .find(|s| s.file == "gpu_ms_vs_triangles")
            .unwrap();
        assert!(gpu.panels.iter().all(|p| p.title.starts_with("wgpu")));
    }

    #[test]
    fn measured_times_are_drawn_with_the_interval_of_each_median() {
        use crate::harness::measure::{Measure, Measured, Spread};
        let mut runs = many();
        for (i, r) in runs.iter_mut().enumerate() {
            let base = 1.0 + i as f64;
            // Samples 5% apart: every interval spans pixels at any count of registered
            // algorithms (a bar rounded to no height draws no path).
            let wall = Spread::of((0..7).map(|k| base * (1.0 + 0.05 * k as f64)).collect());
            r.wall_ms = wall.as_ref().unwrap().median;
            r.measured = Some(Measured {
                protocol: Measure::default(),
                iterations: 7,
                warmup_runs: 0,
                wall_ms: wall.unwrap(),
                gpu_ms: None,
                phases: vec![],
                identical: true,
                warnings: vec![],
            });
        }
        let specs = plan(&runs);
        let wall = specs
            .iter()
            .find(|s| s.file == "wall_ms_vs_triangles")
            .unwrap();
        assert!(wall.caption.contains("95% interval"), "{}", wall.caption);
        for p in &wall.panels {
            for s in &xy(p).series {
                assert_eq!(s.intervals.len(), s.points.len(), "{}", s.name);
                for (&(x, y), &(bx, lo, hi)) in s.points.iter().zip(&s.intervals) {
                    assert!(x == bx && lo < y && y < hi, "{}: {lo} {y} {hi}", s.name);
                }
            }
        }
        // Drawn: the SVG has a bar and two caps per point beyond the chart without them (lines
        // through the points left out of both: a dashed line's segments depend on the scale).
        let mut marks = wall.clone();
        for p in &mut marks.panels {
            if let Kind::Xy(c) = &mut p.kind {
                c.lines = false;
            }
        }
        let mut bare = marks.clone();
        for p in &mut bare.panels {
            if let Kind::Xy(c) = &mut p.kind {
                c.series.iter_mut().for_each(|s| s.intervals.clear());
            }
        }
        let paths = |svg: String| svg.matches("<polyline").count();
        let points: usize = wall
            .panels
            .iter()
            .map(|p| xy(p).series.iter().map(|s| s.points.len()).sum::<usize>())
            .sum();
        assert_eq!(
            paths(draw_svg(&marks).unwrap()) - paths(draw_svg(&bare).unwrap()),
            3 * points
        );
        // Modelled time has no interval to draw.
        let model = specs
            .iter()
            .find(|s| s.file == "model_ms_vs_triangles")
            .unwrap();
        assert!(model
            .panels
            .iter()
            .all(|p| xy(p).series.iter().all(|s| s.intervals.is_empty())));
    }

    #[test]
    fn the_legend_lists_every_algorithm_and_execution_drawn() {
        let specs = plan(&many());
        for s in specs.iter().filter(|s| s.is_xy()) {
            let legend: Vec<String> = s.legend().into_iter().map(|e| e.label).collect();
            for p in &s.panels {
                for se in &xy(p).series {
                    assert!(
                        legend.contains(&se.algorithm),
                        "{}: {}",
                        s.file,
                        se.algorithm
                    );
                    assert!(
                        legend.iter().any(|l| l == se.backend.name()),
                        "{}: {}",
                        s.file,
                        se.backend
                    );
                }
                if xy(p).front.is_some() {
                    assert!(legend.contains(&"Pareto front".to_string()));
                }
            }
        }
    }

    #[test]
    fn phases_at_the_base_point_get_a_panel_per_algorithm_and_a_bar_per_execution() {
        let mut native = record("pcss", Backend::CpuNative, 100, 32);
        for p in &mut native.phases {
            p.model_ms = None;
        }
        let runs = vec![
            record("pcss", Backend::CpuModel, 100, 32),
            native,
            record("pcss", Backend::CpuModel, 200, 32),
            record("hard_shadow_map", Backend::CpuModel, 100, 32),
            record("hard_shadow_map", Backend::CpuModel, 100, 64),
        ];
        let specs = plan(&runs);
        let model = specs.iter().find(|s| s.file == "phases_model_ms").unwrap();
        // The base point: triangles 100 (3 of 5 runs), tile 32 (4 of 5).
        assert!(model.case.contains("100 triangles") && model.case.contains("tile 32"));
        let titles: Vec<&str> = model.panels.iter().map(|p| p.title.as_str()).collect();
        assert_eq!(titles, ["hard_shadow_map", "pcss"]);
        let Kind::Stacked(s) = &model.panels[1].kind else {
            panic!()
        };
        let bars: Vec<&str> = s.bars.iter().map(|b| b.name.as_str()).collect();
        // cpu-native has no modelled time.
        assert_eq!(bars, ["cpu-model"]);
        let expect: Vec<(String, f64)> = runs[0]
            .phases
            .iter()
            .map(|p| (p.name.clone(), p.model_ms.unwrap()))
            .collect();
        assert_eq!(s.bars[0].parts, expect);
        let wall = specs.iter().find(|s| s.file == "phases_wall_ms").unwrap();
        let Kind::Stacked(s) = &wall.panels[1].kind else {
            panic!()
        };
        assert_eq!(s.bars.len(), 2);
        assert!(!specs.iter().any(|s| s.file == "phases_gpu_ms"));
    }

    #[test]
    fn a_series_swept_along_two_axes_gets_a_bar_per_run_split_by_phase() {
        let mut runs = Vec::new();
        for image in [[600, 600], [300, 300]] {
            for t in [5760, 224] {
                let mut r = record("dbuffer", Backend::CpuModel, t, 32);
                r.params.image = image;
                r.phases[0].model_ms = Some(f64::from(t) / 1000.0);
                r.phases[1].model_ms = Some(f64::from(image[0]) / 100.0);
                runs.push(r);
            }
        }
        // A series along one axis only gets none.
        runs.push(record("pcss", Backend::CpuModel, 100, 32));
        runs.push(record("pcss", Backend::CpuModel, 1000, 32));
        let specs = plan(&runs);
        let grids: Vec<&Spec> = specs
            .iter()
            .filter(|s| s.file.starts_with("phases_grid_"))
            .collect();
        let files: Vec<&str> = grids.iter().map(|s| s.file.as_str()).collect();
        assert_eq!(
            files,
            [
                "phases_grid_model_ms_dbuffer_cpu-model",
                "phases_grid_wall_ms_dbuffer_cpu-model"
            ]
        );
        let Kind::Stacked(s) = &grids[0].panels[0].kind else {
            panic!()
        };
        let names: Vec<&str> = s.bars.iter().map(|b| b.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "224 tris / 300×300",
                "224 tris / 600×600",
                "5760 tris / 300×300",
                "5760 tris / 600×600"
            ]
        );
        assert_eq!(
            s.bars[3].parts,
            [("construct".to_string(), 5.76), ("soft".to_string(), 6.0)]
        );
        assert!(grids[0]
            .caption
            .contains("scene triangles, then image pixels"));
    }

    #[test]
    fn missing_counters_and_failed_runs_are_skipped() {
        let mut runs: Vec<RunRecord> = [10, 20, 40]
            .into_iter()
            .map(|t| {
                let mut r = record("reference", Backend::CpuNative, t, 32);
                r.counters = Default::default();
                r.model_ms = None;
                r
            })
            .collect();
        let mut failed = record("pcss", Backend::Wgpu, 10, 32);
        failed.failure = Some("no adapter".into());
        runs.push(failed);
        let names = files(&plan(&runs));
        assert!(
            names.contains(&"wall_ms_vs_triangles".to_string()),
            "{names:?}"
        );
        for m in [
            "modelled_memory_bytes",
            "estimated_memory_bytes",
            "fill",
            "overdraw_ratio",
            "model_ms",
            "gpu_ms",
        ] {
            assert!(!names.iter().any(|n| n.starts_with(m)), "{m}: {names:?}");
        }
        assert!(!names.iter().any(|n| n.contains("gpu")), "{names:?}");
    }

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        let pts = [
            (1.0, 0.5),
            (2.0, 0.6),
            (3.0, 0.2),
            (4.0, 0.2),
            (5.0, 0.1),
            (0.5, 0.9),
        ];
        // Brute force: a point is on the front when no other point is at least as good on
        // both axes and better on one.
        let mut expect: Vec<(f64, f64)> = pts
            .iter()
            .copied()
            .filter(|p| {
                !pts.iter()
                    .any(|q| q != p && q.0 <= p.0 && q.1 <= p.1 && (q.0 < p.0 || q.1 < p.1))
            })
            .collect();
        expect.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert_eq!(pareto_front(pts.into_iter()), expect);
    }

    #[test]
    fn markers_that_would_cover_each_other_are_spread_sideways_and_others_stay() {
        // Three markers on one pixel, one just below them, one in another column, one far
        // down the same column.
        let at = [
            (100, 50),
            (100, 50),
            (100, 50),
            (100, 55),
            (140, 50),
            (100, 200),
        ];
        let dx = dodge(&at, 5);
        assert_eq!(dx[4], 0);
        assert_eq!(dx[5], 0);
        let mut group = dx[..4].to_vec();
        group.sort_unstable();
        // Four in a group, 11 px apart, centred on the column.
        assert_eq!(group, [-16, -5, 5, 16]);
        for i in 0..4 {
            for j in 0..i {
                assert!((dx[i] - dx[j]).abs() >= 10, "{dx:?}");
            }
        }
        assert_eq!(dodge(&[(3, 3)], 5), [0]);
    }

    #[test]
    fn log_axes_only_for_positive_values_spanning_a_decade_with_ticks_at_decades() {
        assert!(wants_log(&[100.0, 1000.0, 10000.0]));
        assert!(!wants_log(&[16.0, 32.0, 64.0]));
        assert!(!wants_log(&[0.0, 10.0, 1000.0]));
        let (a, log) = tick_axis(&[100.0, 1000.0, 10000.0], false, true);
        assert!(log);
        let labels = |a: &TickAxis, log: bool| -> Vec<String> {
            let f = TickFormat::of(a, log);
            a.bold.iter().map(|v| f.label(*v)).collect()
        };
        // Two decades: decades and 2×, 5× between.
        assert_eq!(
            labels(&a, true),
            ["100", "200", "500", "1000", "2000", "5000", "10000"]
        );
        // One notation on every tick of an axis.
        let (a, _) = tick_axis(&[1e-6, 1e3], false, true);
        assert_eq!(labels(&a, true), ["1e-6", "1e-4", "1e-2", "1e0", "1e2"]);
        let (a, _) = tick_axis(&[3e5, 2e7], false, true);
        let l = labels(&a, true);
        assert!(l.iter().all(|t| t.contains('e')), "{l:?}");
        assert!(
            l.contains(&"5e5".to_string()) && l.contains(&"1e7".to_string()),
            "{l:?}"
        );
        let (a, log) = tick_axis(&[0.0, 2.5e6], true, true);
        assert!(!log);
        assert_eq!(labels(&a, false), ["0", "1e6", "2e6"]);
        // Linear: round steps from zero.
        let (a, log) = tick_axis(&[16.0, 32.0, 64.0], true, true);
        assert!(!log);
        assert_eq!(a.bold, [0.0, 20.0, 40.0, 60.0]);
    }

    #[test]
    fn rendered_charts_use_the_algorithm_colours_and_name_every_series() {
        let runs: Vec<RunRecord> = [100, 1000, 10000]
            .into_iter()
            .flat_map(|t| {
                [
                    record("pcss", Backend::CpuModel, t, 32),
                    record("dbuffer", Backend::Wgpu, t, 32),
                ]
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let specs = plan(&runs);
        let spec = specs
            .iter()
            .find(|s| s.file == "wall_ms_vs_triangles")
            .unwrap();
        assert_eq!(spec.panels.len(), 2);
        let w = render(spec, dir.path()).unwrap();
        let img = image::open(dir.path().join("wall_ms_vs_triangles.png"))
            .unwrap()
            .to_rgb8();
        assert_eq!(img.dimensions(), spec.size());
        for alg in ["pcss", "dbuffer"] {
            let c = style::algorithm_color(alg);
            assert!(
                img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count() > 50,
                "{alg} not drawn in its colour"
            );
        }
        let svg = std::fs::read_to_string(dir.path().join("wall_ms_vs_triangles.svg")).unwrap();
        for text in [
            "pcss",
            "dbuffer",
            "cpu-model",
            "wgpu",
            "scene triangles (count), log scale",
            "wall time (ms",
            "tile 32",
        ] {
            assert!(svg.contains(text), "{text} missing from the SVG");
        }
        assert_eq!(w.png, "charts/wall_ms_vs_triangles.png");
        // The legend is rendered text: dark pixels in the legend column.
        let (width, _) = spec.size();
        let dark = img
            .enumerate_pixels()
            .filter(|(x, _, p)| *x > width - LEGEND_WIDTH + 44 && p.0.iter().all(|&c| c < 80))
            .count();
        assert!(dark > 50, "legend text not rendered ({dark} dark pixels)");
    }
}
