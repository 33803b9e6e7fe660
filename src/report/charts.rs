//! Comparison charts, each as PNG and SVG: every time, cost and error figure against every sweep
//! axis the runs vary along (one line per algorithm × backend), quality against cost with its
//! Pareto front, and per-phase time split as stacked bars.
//!
//! Planning ([`plan`]) is separate from drawing ([`render`]) so which charts a set of runs gets,
//! and what is on them, can be checked without pixels.
//!
//! Text is drawn with the pure-Rust `ab_glyph` rasterizer from a TrueType font found on the
//! system at run time (see [`FONT_CANDIDATES`], or `SHADOWBENCH_FONT`): no C font libraries at
//! build time, and on Debian the only thing needed is the `fonts-dejavu-core` package.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::fmt_num;
use crate::error::{Error, Result};
use crate::record::RunRecord;

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

    /// Axis description on a chart.
    pub fn label(self) -> &'static str {
        match self {
            Axis::Triangles => "scene triangles",
            Axis::LightSize => "light size (radius or half-width)",
            Axis::MapResolution => "map resolution (texels per side)",
            Axis::TileSize => "tile size (pixels per side)",
            Axis::ImagePixels => "image pixels (width × height)",
            Axis::OccluderHeight => "occluder height above receiver",
            Axis::OccluderOffset => "occluder lateral offset (x)",
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
            Axis::Cores => p.cores.map(f64::from),
        }
    }
}

/// A figure of a run plotted against the sweep axes.
pub struct Metric {
    pub id: &'static str,
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

pub const METRICS: [Metric; 8] = [
    Metric {
        id: "wall_ms",
        label: "wall time (ms, measured on the host)",
        value: |r| Some(r.wall_ms),
    },
    Metric {
        id: "gpu_ms",
        label: "GPU time (ms, timestamp queries)",
        value: |r| r.gpu_ms,
    },
    Metric {
        id: "model_ms",
        label: "modelled time (ms)",
        value: |r| r.model_ms,
    },
    Metric {
        id: "modelled_memory_bytes",
        label: "modelled memory traffic (bytes, cpu-model)",
        value: |r| memory_bytes(r, "mem_model"),
    },
    Metric {
        id: "estimated_memory_bytes",
        label: "estimated memory traffic (bytes)",
        value: |r| memory_bytes(r, "mem_est"),
    },
    Metric {
        id: "fill",
        label: "fill (fragments, texels or samples)",
        value: |r| r.counters.get("fill"),
    },
    Metric {
        id: "overdraw_ratio",
        label: "overdraw ratio (overdraw / fill)",
        value: |r| r.counters.get("overdraw_ratio"),
    },
    // Error against a sweep axis, as paper 002 plots it (Figures 17-20).
    Metric {
        id: "mae_shadow",
        label: "error: mean absolute error in shadow (mae_shadow)",
        value: |r| r.error.as_ref().and_then(|e| e.mae_shadow),
    },
];

/// Times a cost can be measured in, for the quality-vs-cost and per-phase charts.
const TIMES: [(&str, &str); 3] = [
    ("model_ms", "modelled time"),
    ("gpu_ms", "GPU time"),
    ("wall_ms", "wall time"),
];

fn run_time(r: &RunRecord, id: &str) -> Option<f64> {
    match id {
        "model_ms" => r.model_ms,
        "gpu_ms" => r.gpu_ms,
        _ => Some(r.wall_ms),
    }
}

fn phase_time(p: &crate::record::Phase, id: &str) -> Option<f64> {
    match id {
        "model_ms" => p.model_ms,
        "gpu_ms" => p.gpu_ms,
        _ => Some(p.wall_ms),
    }
}

/// The series a run belongs to.
pub fn series_name(r: &RunRecord) -> String {
    format!("{} / {}", r.algorithm, r.backend)
}

#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    /// Sorted by x.
    pub points: Vec<(f64, f64)>,
}

/// A chart of points: lines through each series' points, or a scatter with a Pareto front.
#[derive(Clone, Debug)]
pub struct XyChart {
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub lines: bool,
    /// Points no other point beats on both axes (lower is better on both), by x.
    pub front: Option<Vec<(f64, f64)>>,
}

#[derive(Clone, Debug)]
pub struct Bar {
    pub name: String,
    /// (phase, value), in the run's phase order.
    pub parts: Vec<(String, f64)>,
}

#[derive(Clone, Debug)]
pub enum Kind {
    Xy(XyChart),
    Stacked { y_label: String, bars: Vec<Bar> },
}

/// One chart to draw.
#[derive(Clone, Debug)]
pub struct Spec {
    /// File stem under `charts/`.
    pub file: String,
    pub title: String,
    /// What the chart holds fixed or how it was chosen, for the report.
    pub caption: String,
    pub kind: Kind,
}

/// A chart on disk, relative to the report folder.
#[derive(Clone, Debug)]
pub struct Written {
    pub png: String,
    pub svg: String,
    pub title: String,
    pub caption: String,
}

/// Every chart `records` support, in report order. Failed runs are left out.
pub fn plan(records: &[RunRecord]) -> Vec<Spec> {
    let ok: Vec<&RunRecord> = records.iter().filter(|r| r.failure.is_none()).collect();
    let mut specs = Vec::new();
    for axis in Axis::ALL {
        let Some((slice, fixed)) = axis_slice(&ok, axis) else {
            continue;
        };
        for m in &METRICS {
            let series = collect_series(&slice, |r| Some((axis.value(r)?, (m.value)(r)?)));
            if series.is_empty() {
                continue;
            }
            specs.push(Spec {
                file: format!("{}_vs_{}", m.id, axis.id()),
                title: format!("{} vs. {}{}", m.label, axis.label(), axis.meaning()),
                caption: fixed.clone(),
                kind: Kind::Xy(XyChart {
                    x_label: axis.label().into(),
                    y_label: m.label.into(),
                    series,
                    lines: true,
                    front: None,
                }),
            });
        }
    }
    for (id, label) in TIMES {
        let series = collect_series(&ok, |r| {
            Some((run_time(r, id)?, r.error.as_ref()?.mae_shadow?))
        });
        if series.is_empty() {
            continue;
        }
        let front = pareto_front(series.iter().flat_map(|s| s.points.iter().copied()));
        specs.push(Spec {
            file: format!("quality_vs_{id}"),
            title: format!("quality vs. cost: shadow error against {label}"),
            caption: "Every successful run with quality metrics; the dashed line joins the runs \
                      no other run beats on both cost and error (lower is better on both)."
                .into(),
            kind: Kind::Xy(XyChart {
                x_label: format!("{label} (ms)"),
                y_label: "error: mean absolute error in shadow (mae_shadow)".into(),
                series,
                lines: false,
                front: Some(front),
            }),
        });
    }
    for (id, label) in TIMES {
        let mut bars: Vec<Bar> = Vec::new();
        let mut params: Vec<String> = Vec::new();
        for r in &ok {
            let name = series_name(r);
            if bars.iter().any(|b| b.name == name) {
                continue;
            }
            let parts: Vec<(String, f64)> = r
                .phases
                .iter()
                .filter_map(|p| Some((p.name.clone(), phase_time(p, id)?)))
                .collect();
            if !parts.is_empty() {
                params.push(describe_params(r));
                bars.push(Bar { name, parts });
            }
        }
        if bars.is_empty() {
            continue;
        }
        params.dedup();
        let what = if params.len() == 1 {
            format!("all at {}", params[0])
        } else {
            "each at its first run in the results".into()
        };
        specs.push(Spec {
            file: format!("phases_{id}"),
            title: format!("{label} per phase"),
            caption: format!("One bar per algorithm / backend, {what}."),
            kind: Kind::Stacked {
                y_label: format!("{label} (ms)"),
                bars,
            },
        });
    }
    specs.extend(phase_grids(&ok));
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
            let axes: Vec<&str> = varying.iter().map(|a| a.label()).collect();
            specs.push(Spec {
                file: format!(
                    "phases_grid_{id}_{}",
                    name.replace(" / ", "_").replace(['/', ' '], "_")
                ),
                title: format!("{label} per phase, every run of {name}"),
                caption: format!(
                    "One bar per run, named and ordered by what varies: {}.",
                    axes.join(", then ")
                ),
                kind: Kind::Stacked {
                    y_label: format!("{label} (ms)"),
                    bars,
                },
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

fn describe_params(r: &RunRecord) -> String {
    let p = &r.params;
    let mut s = format!(
        "{}: {} triangles, light size {}, map {}, tile {}, image {}×{}",
        r.scene,
        p.triangles,
        fmt_num(p.light_size as f64),
        p.map_resolution,
        p.tile_size,
        p.image[0],
        p.image[1]
    );
    if let Some(h) = p.occluder_height {
        s.push_str(&format!(", occluder height {}", fmt_num(h as f64)));
    }
    if let Some(d) = p.occluder_offset {
        s.push_str(&format!(", occluder offset {}", fmt_num(d as f64)));
    }
    if let Some(c) = p.cores {
        s.push_str(&format!(", {c} cores"));
    }
    s
}

/// The runs along which `axis` varies with every other axis (and the scene) fixed: of all such
/// slices, the one with the most distinct values of `axis` (the first on a tie, which for a
/// sweep is the one through its base point). `None` when no slice has two values.
fn axis_slice<'a>(runs: &[&'a RunRecord], axis: Axis) -> Option<(Vec<&'a RunRecord>, String)> {
    let rest = |r: &RunRecord| -> String {
        let others: Vec<String> = Axis::ALL
            .iter()
            .filter(|a| **a != axis)
            .map(|a| format!("{:?}", a.value(r)))
            .collect();
        format!("{}|{}", r.scene, others.join("|"))
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
    let mut best: Option<&(String, Vec<f64>)> = None;
    for s in &slices {
        if best.is_none_or(|b| s.1.len() > b.1.len()) {
            best = Some(s);
        }
    }
    let (key, xs) = best?;
    if xs.len() < 2 {
        return None;
    }
    let members: Vec<&RunRecord> = runs
        .iter()
        .copied()
        .filter(|r| axis.value(r).is_some() && rest(r) == *key)
        .collect();
    let sample = members[0];
    let p = &sample.params;
    let mut fixed = vec![format!("scene {}", sample.scene)];
    for a in Axis::ALL.iter().filter(|a| **a != axis) {
        let v = match a {
            Axis::ImagePixels => Some(format!("{}×{}", p.image[0], p.image[1])),
            _ => a.value(sample).map(fmt_num),
        };
        if let Some(v) = v {
            fixed.push(format!("{} {v}", a.id().replace('_', " ")));
        }
    }
    Some((
        members,
        format!("Other parameters fixed: {}.", fixed.join(", ")),
    ))
}

/// Groups points by series (in order of first appearance), each sorted by x.
fn collect_series(
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
                points: vec![p],
            }),
        }
    }
    for s in &mut series {
        s.points
            .sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    }
    series
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

/// Draws `spec` into `dir` as `<file>.png` and `<file>.svg`.
pub fn render(spec: &Spec, dir: &Path) -> Result<Written> {
    ensure_font()?;
    let size = spec.size();
    let png = dir.join(format!("{}.png", spec.file));
    let svg = dir.join(format!("{}.svg", spec.file));
    let fail =
        |path: &Path, e: String| Error::Other(format!("{}: drawing chart: {e}", path.display()));
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        draw(&root, spec).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    image::RgbImage::from_raw(size.0, size.1, buf)
        .expect("buffer sized to the image")
        .save(&png)
        .map_err(|e| fail(&png, e.to_string()))?;
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        draw(&root, spec).map_err(|e| fail(&svg, e))?;
        root.present().map_err(|e| fail(&svg, e.to_string()))?;
    }
    Ok(Written {
        png: format!("charts/{}.png", spec.file),
        svg: format!("charts/{}.svg", spec.file),
        title: spec.title.clone(),
        caption: spec.caption.clone(),
    })
}

impl Spec {
    fn size(&self) -> (u32, u32) {
        match &self.kind {
            Kind::Xy(_) => (1000, 600),
            Kind::Stacked { bars, .. } => ((400 + 180 * bars.len() as u32).max(900), 600),
        }
    }
}

const LEGEND_WIDTH: u32 = 260;
const FONT: &str = "sans-serif";

type DrawResult = std::result::Result<(), String>;

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, spec: &Spec) -> DrawResult {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (title, root) = root.split_vertically(44);
    title
        .draw(&Text::new(
            spec.title.clone(),
            (16, 16),
            TextStyle::from((FONT, 22).into_font()).color(&BLACK),
        ))
        .map_err(|e| e.to_string())?;
    let (w, _) = root.dim_in_pixel();
    let (plot, legend) = root.split_horizontally(w.saturating_sub(LEGEND_WIDTH));
    match &spec.kind {
        Kind::Xy(c) => {
            let xs: Vec<f64> = c
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.0))
                .collect();
            let ys: Vec<f64> = c
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1))
                .collect();
            let (xlog, ylog) = (wants_log(&xs), wants_log(&ys));
            let (x0, x1) = extent(&xs, xlog, false);
            let (y0, y1) = extent(&ys, ylog, true);
            match (xlog, ylog) {
                (false, false) => draw_xy(&plot, c, x0..x1, y0..y1),
                (true, false) => draw_xy(&plot, c, (x0..x1).log_scale(), y0..y1),
                (false, true) => draw_xy(&plot, c, x0..x1, (y0..y1).log_scale()),
                (true, true) => draw_xy(&plot, c, (x0..x1).log_scale(), (y0..y1).log_scale()),
            }?;
            let mut entries: Vec<(String, RGBColor, bool)> = c
                .series
                .iter()
                .enumerate()
                .map(|(i, s)| (s.name.clone(), color(i), c.lines))
                .collect();
            if c.front.is_some() {
                entries.push(("Pareto front".into(), BLACK, true));
            }
            draw_legend(&legend, &entries)
        }
        Kind::Stacked { y_label, bars } => {
            let phases = phase_names(bars);
            draw_stacked(&plot, y_label, bars, &phases)?;
            let entries: Vec<(String, RGBColor, bool)> = phases
                .iter()
                .enumerate()
                .map(|(i, p)| (p.clone(), color(i), false))
                .collect();
            draw_legend(&legend, &entries)
        }
    }
}

fn color(i: usize) -> RGBColor {
    let c = Palette99::pick(i).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

/// Axis range around `v`: padded linearly, or by a factor on a log axis; from zero for
/// non-negative values on a linear value axis.
fn extent(v: &[f64], log: bool, from_zero: bool) -> (f64, f64) {
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if log {
        return (min / 1.5, max * 1.5);
    }
    let span = if max > min {
        max - min
    } else {
        max.abs().max(1.0)
    };
    let lo = if from_zero && min >= 0.0 {
        0.0
    } else {
        min - span * 0.05
    };
    (lo, max + span * 0.05)
}

fn draw_xy<DB, X, Y>(area: &DrawingArea<DB, Shift>, c: &XyChart, x: X, y: Y) -> DrawResult
where
    DB: DrawingBackend,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let mut chart = ChartBuilder::on(area)
        .margin(16)
        .x_label_area_size(56)
        .y_label_area_size(90)
        .build_cartesian_2d(x, y)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(&c.x_label)
        .y_desc(&c.y_label)
        .x_label_formatter(&|v| fmt_num(*v))
        .y_label_formatter(&|v| fmt_num(*v))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(e)?;
    for (i, s) in c.series.iter().enumerate() {
        let col = color(i);
        if c.lines {
            chart
                .draw_series(LineSeries::new(
                    s.points.iter().copied(),
                    col.stroke_width(2),
                ))
                .map_err(e)?;
        }
        chart
            .draw_series(s.points.iter().map(|&p| Circle::new(p, 4, col.filled())))
            .map_err(e)?;
    }
    if let Some(front) = &c.front {
        chart
            .draw_series(DashedLineSeries::new(
                front.iter().copied(),
                8,
                5,
                BLACK.stroke_width(1),
            ))
            .map_err(e)?;
    }
    Ok(())
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

fn draw_stacked<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    y_label: &str,
    bars: &[Bar],
    phases: &[String],
) -> DrawResult {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let total = |b: &Bar| b.parts.iter().map(|p| p.1).sum::<f64>();
    let top = bars.iter().map(total).fold(0.0, f64::max);
    let top = if top > 0.0 { top * 1.08 } else { 1.0 };
    let mut chart = ChartBuilder::on(area)
        .margin(16)
        .x_label_area_size(80)
        .y_label_area_size(90)
        .build_cartesian_2d(-0.5..bars.len() as f64 - 0.5, 0.0..top)
        .map_err(e)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .y_desc(y_label)
        .y_label_formatter(&|v| fmt_num(*v))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(e)?;
    for (pi, phase) in phases.iter().enumerate() {
        let col = color(pi);
        let rects = bars.iter().enumerate().filter_map(|(bi, b)| {
            let k = b.parts.iter().position(|p| p.0 == *phase)?;
            let below: f64 = b.parts[..k].iter().map(|p| p.1).sum();
            let x = bi as f64;
            Some(Rectangle::new(
                [(x - 0.3, below), (x + 0.3, below + b.parts[k].1)],
                col.filled(),
            ))
        });
        chart.draw_series(rects).map_err(e)?;
    }
    // Bar names under the axis, on two lines (algorithm, backend) so long names do not collide.
    let (ox, oy) = area.get_base_pixel();
    let style = TextStyle::from((FONT, 14).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Top));
    for (bi, b) in bars.iter().enumerate() {
        let (px, py) = chart.backend_coord(&(bi as f64, 0.0));
        let (x, y) = (px - ox, py - oy);
        for (li, line) in b.name.splitn(2, " / ").enumerate() {
            area.draw(&Text::new(
                line.to_string(),
                (x, y + 10 + 20 * li as i32),
                style.clone(),
            ))
            .map_err(e)?;
        }
    }
    Ok(())
}

/// A legend beside the plot: a line (or a square) and the name of each entry.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, RGBColor, bool)],
) -> DrawResult {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let style = TextStyle::from((FONT, 15).into_font()).color(&BLACK);
    for (i, (name, col, line)) in entries.iter().enumerate() {
        let y = 40 + 24 * i as i32;
        if *line {
            area.draw(&PathElement::new(
                vec![(8, y), (36, y)],
                col.stroke_width(3),
            ))
            .map_err(e)?;
        } else {
            area.draw(&Rectangle::new([(14, y - 7), (28, y + 7)], col.filled()))
                .map_err(e)?;
        }
        area.draw(&Text::new(name.clone(), (44, y - 8), style.clone()))
            .map_err(e)?;
    }
    Ok(())
}

/// Fonts tried in order when `SHADOWBENCH_FONT` is not set. On Debian, `fonts-dejavu-core`
/// provides the first.
pub const FONT_CANDIDATES: [&str; 6] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
];

/// Registers the chart font once per process.
fn ensure_font() -> Result<()> {
    static FONT_READY: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    FONT_READY
        .get_or_init(|| {
            let path = find_font()?;
            let bytes =
                std::fs::read(&path).map_err(|e| format!("chart font {}: {e}", path.display()))?;
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font(FONT, FontStyle::Normal, bytes).map_err(|_| {
                format!(
                    "chart font {}: not a TrueType/OpenType font",
                    path.display()
                )
            })
        })
        .clone()
        .map_err(Error::Other)
}

fn find_font() -> std::result::Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("SHADOWBENCH_FONT") {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(format!(
                "SHADOWBENCH_FONT={}: no such font file",
                p.display()
            ))
        };
    }
    FONT_CANDIDATES
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
        .ok_or_else(|| {
            format!(
                "no font for chart text: install one (Debian: apt-get install fonts-dejavu-core) \
                 or set SHADOWBENCH_FONT to a .ttf file; looked in {}",
                FONT_CANDIDATES.join(", ")
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::testdata::record;

    fn files(specs: &[Spec]) -> Vec<String> {
        specs.iter().map(|s| s.file.clone()).collect()
    }

    #[test]
    fn charts_follow_the_axes_the_runs_vary_along() {
        // A triangle sweep at tile 32 and a tile sweep at the base triangle count, as an
        // `each` sweep gives: two axes vary; the rest are the same everywhere.
        let mut runs = Vec::new();
        for alg in ["pcss", "hard_shadow_map"] {
            for t in [100, 1000, 10000] {
                runs.push(record(alg, "cpu-model", t, 32));
            }
            for tile in [16, 64] {
                runs.push(record(alg, "cpu-model", 100, tile));
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
        // The triangle chart holds tile 32 fixed: three points per algorithm, in x order.
        let tri = specs
            .iter()
            .find(|s| s.file == "model_ms_vs_triangles")
            .unwrap();
        let Kind::Xy(c) = &tri.kind else { panic!() };
        assert_eq!(c.series.len(), 2);
        assert_eq!(c.series[0].name, "pcss / cpu-model");
        let xs: Vec<f64> = c.series[0].points.iter().map(|p| p.0).collect();
        assert_eq!(xs, [100.0, 1000.0, 10000.0]);
        assert!(tri.caption.contains("tile size 32"), "{}", tri.caption);
        // The tile chart holds triangles at 100: tiles 16, 32 and 64.
        let tile = specs
            .iter()
            .find(|s| s.file == "modelled_memory_bytes_vs_tile_size")
            .unwrap();
        let Kind::Xy(c) = &tile.kind else { panic!() };
        let xs: Vec<f64> = c.series[1].points.iter().map(|p| p.0).collect();
        assert_eq!(xs, [16.0, 32.0, 64.0]);
        let r = runs
            .iter()
            .find(|r| r.algorithm == "hard_shadow_map" && r.params.tile_size == 64)
            .unwrap();
        assert_eq!(
            c.series[1].points[2].1,
            r.counters.get("mem_model.read_bytes").unwrap()
                + r.counters.get("mem_model.write_bytes").unwrap()
        );
    }

    #[test]
    fn a_series_swept_along_two_axes_gets_a_bar_per_run_split_by_phase() {
        let mut runs = Vec::new();
        for image in [[600, 600], [300, 300]] {
            for t in [5760, 224] {
                let mut r = record("dbuffer", "cpu-model", t, 32);
                r.params.image = image;
                r.phases[0].model_ms = Some(f64::from(t) / 1000.0);
                r.phases[1].model_ms = Some(f64::from(image[0]) / 100.0);
                runs.push(r);
            }
        }
        // A series along one axis only gets none.
        runs.push(record("pcss", "cpu-model", 100, 32));
        runs.push(record("pcss", "cpu-model", 1000, 32));
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
        let Kind::Stacked { bars, .. } = &grids[0].kind else {
            panic!()
        };
        let names: Vec<&str> = bars.iter().map(|b| b.name.as_str()).collect();
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
            bars[3].parts,
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
                let mut r = record("reference", "cpu-native", t, 32);
                r.counters = Default::default();
                r.model_ms = None;
                r
            })
            .collect();
        let mut failed = record("pcss", "wgpu", 10, 32);
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
    fn log_axes_only_for_positive_values_spanning_a_decade() {
        assert!(wants_log(&[100.0, 1000.0, 10000.0]));
        assert!(!wants_log(&[16.0, 32.0, 64.0]));
        assert!(!wants_log(&[0.0, 10.0, 1000.0]));
    }

    #[test]
    fn phase_bars_stack_each_series_phases() {
        let runs = vec![
            record("pcss", "cpu-model", 100, 32),
            record("pcss", "cpu-model", 200, 32),
            record("hard_shadow_map", "cpu-model", 100, 32),
        ];
        let specs = plan(&runs);
        let model = specs.iter().find(|s| s.file == "phases_model_ms").unwrap();
        let Kind::Stacked { bars, .. } = &model.kind else {
            panic!()
        };
        assert_eq!(bars.len(), 2);
        let expect: Vec<(String, f64)> = runs[0]
            .phases
            .iter()
            .map(|p| (p.name.clone(), p.model_ms.unwrap()))
            .collect();
        assert_eq!(bars[0].parts, expect);
        assert!(specs.iter().any(|s| s.file == "phases_wall_ms"));
        assert!(!specs.iter().any(|s| s.file == "phases_gpu_ms"));
    }

    #[test]
    fn rendered_charts_have_text_and_data() {
        let runs: Vec<RunRecord> = [100, 1000, 10000]
            .into_iter()
            .flat_map(|t| {
                [
                    record("pcss", "cpu-model", t, 32),
                    record("dbuffer", "wgpu", t, 32),
                ]
            })
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let specs = plan(&runs);
        let spec = specs
            .iter()
            .find(|s| s.file == "model_ms_vs_triangles")
            .unwrap();
        let w = render(spec, dir.path()).unwrap();
        let img = image::open(dir.path().join("model_ms_vs_triangles.png"))
            .unwrap()
            .to_rgb8();
        assert_eq!(img.dimensions(), spec.size());
        // Each series colour appears in the picture.
        for i in 0..2 {
            let c = color(i);
            assert!(
                img.pixels().any(|p| p.0 == [c.0, c.1, c.2]),
                "series {i} not drawn"
            );
        }
        let svg = std::fs::read_to_string(dir.path().join("model_ms_vs_triangles.svg")).unwrap();
        for text in [
            "pcss / cpu-model",
            "dbuffer / wgpu",
            "scene triangles",
            "modelled time",
        ] {
            assert!(svg.contains(text), "{text} missing from the SVG");
        }
        assert_eq!(w.png, "charts/model_ms_vs_triangles.png");
        // The legend is rendered text: dark pixels in the legend column.
        let (width, _) = spec.size();
        let dark = img
            .enumerate_pixels()
            .filter(|(x, _, p)| *x > width - LEGEND_WIDTH + 44 && p.0.iter().all(|&c| c < 80))
            .count();
        assert!(dark > 50, "legend text not rendered ({dark} dark pixels)");
    }
}
