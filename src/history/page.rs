//! The trend page: `history report` writes `index.html`, one self-contained file (its charts
//! inline SVG, drawn with plotters in the report's style: an algorithm's colour, an
//! execution's marker and line, the chart font; [`crate::report::style`]).
//!
//! In order: what the history holds and what was checked; the steps since the compared
//! commit, regressions first (worst first), then improvements, then figures that moved and
//! came back, each with its series plotted over the commits, its fitted level, and its step
//! marked (a vertical line and the new level shaded: red for worse, green for better); then
//! one small-multiple panel per algorithm × execution with its headline figures
//! ([`super::HEADLINE`]), each the geometric mean over the panel's runs of the value relative
//! to its first commit; then every commit, with its id, date, branch and subject, linked to
//! `--commit-url` where given. Commit ticks on the charts are short commit ids.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use html_escape::{encode_double_quoted_attribute as attr, encode_text as text};
use plotters::prelude::*;

use super::check::{Check, SeriesChange};
use super::detect::Verdict;
use super::formats::short;
use super::store::History;
use super::HEADLINE;
use crate::backend::Backend;
use crate::error::{Error, Result};
use crate::report::fmt_num;
use crate::report::style::{self, Dash, Marker};

/// Most step charts drawn; further steps are listed in the table only.
pub const MAX_STEP_CHARTS: usize = 40;

const FONT: &str = crate::report::font::FAMILY;
const WORSE: RGBColor = RGBColor(0xc0, 0x1c, 0x28);
const BETTER: RGBColor = RGBColor(0x26, 0x8a, 0x3c);

const STYLE: &str = "body{font-family:sans-serif;margin:2em;color:#222}\
table{border-collapse:collapse;font-size:13px;margin-bottom:1.5em}\
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right}th{background:#f0f0f0}\
td.t{text-align:left}td.reg{color:#c01c28;font-weight:bold;text-align:left}\
td.imp{color:#268a3c;font-weight:bold;text-align:left}td.back{color:#777;text-align:left}\
figure{display:inline-block;margin:0 1em 1.5em 0;vertical-align:top}\
figcaption{font-size:13px;color:#444;max-width:720px}\
.grid{display:flex;flex-wrap:wrap}.grid figure{margin:0 .6em .8em 0}\
.none{color:#777}code{font-size:12px}";

/// A point of a chart line: commit index, value, and the value's interval where it has one.
type ChartPoint = (f64, f64, Option<(f64, f64)>);

/// One line of a chart.
struct Line {
    label: String,
    color: RGBColor,
    marker: Marker,
    dash: Dash,
    points: Vec<ChartPoint>,
}

/// A chart over commits.
struct Chart<'a> {
    title: String,
    y_label: String,
    commits: &'a [String],
    lines: Vec<Line>,
    /// The fitted level, drawn as a grey step line.
    level: Vec<(f64, f64)>,
    /// Step marks: (commit index, worse).
    marks: Vec<(f64, bool)>,
    size: (u32, u32),
}

fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

fn marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    (x, y): (i32, i32),
    m: Marker,
    c: RGBColor,
    size: i32,
) -> std::result::Result<(), String> {
    let fill = c.filled();
    match m {
        Marker::Circle => area.draw(&Circle::new((x, y), size, fill)),
        Marker::Square => area.draw(&Rectangle::new(
            [(x - size, y - size), (x + size, y + size)],
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

fn draw(c: &Chart) -> std::result::Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, c.size).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let n = c.commits.len().max(1) as f64;
        let ys: Vec<f64> = c
            .lines
            .iter()
            .flat_map(|l| {
                l.points.iter().flat_map(|(_, y, i)| {
                    std::iter::once(*y).chain(i.iter().flat_map(|(a, b)| [*a, *b]))
                })
            })
            .chain(c.level.iter().map(|p| p.1))
            .filter(|v| v.is_finite())
            .collect();
        let (lo, hi) = ys
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        if !lo.is_finite() {
            return Ok(String::new());
        }
        let pad = ((hi - lo) * 0.08).max(hi.abs().max(1e-12) * 0.005);
        let mut chart = ChartBuilder::on(&root)
            .caption(&c.title, (FONT, 15))
            .margin(10)
            .x_label_area_size(46)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5..n - 0.5, (lo - pad)..(hi + pad))
            .map_err(err)?;
        let commits = c.commits;
        chart
            .configure_mesh()
            .x_labels(10.min(commits.len()).max(2))
            .x_label_formatter(&|v| {
                let i = v.round();
                if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < commits.len() {
                    commits[i as usize].clone()
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&|v| fmt_num(*v))
            .x_desc("commit")
            .y_desc(c.y_label.as_str())
            .label_style((FONT, 11))
            .axis_desc_style((FONT, 12))
            .bold_line_style(RGBColor(215, 215, 215))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()
            .map_err(err)?;
        let (y0, y1) = (lo - pad, hi + pad);
        for &(x, worse) in &c.marks {
            let col = if worse { WORSE } else { BETTER };
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x - 0.5, y0), (n - 0.5, y1)],
                    style::tint(col, 0.88).filled(),
                )))
                .map_err(err)?;
            chart
                .draw_series(LineSeries::new(
                    [(x - 0.5, y0), (x - 0.5, y1)],
                    col.stroke_width(2),
                ))
                .map_err(err)?;
        }
        if !c.level.is_empty() {
            let mut steps = Vec::new();
            for (i, &(x, y)) in c.level.iter().enumerate() {
                if i > 0 {
                    steps.push((x - 0.5, c.level[i - 1].1));
                    steps.push((x - 0.5, y));
                }
                steps.push((x, y));
            }
            chart
                .draw_series(DashedLineSeries::new(
                    steps,
                    6,
                    4,
                    RGBColor(90, 90, 90).stroke_width(1),
                ))
                .map_err(err)?;
        }
        let (ox, oy) = root.get_base_pixel();
        for l in &c.lines {
            let pts: Vec<(f64, f64)> = l.points.iter().map(|p| (p.0, p.1)).collect();
            let s = l.color.stroke_width(2);
            match l.dash {
                Dash::Solid => chart
                    .draw_series(LineSeries::new(pts.clone(), s))
                    .map(|_| ()),
                Dash::Dashed => chart
                    .draw_series(DashedLineSeries::new(pts.clone(), 9, 5, s))
                    .map(|_| ()),
                Dash::Dotted => chart
                    .draw_series(DashedLineSeries::new(pts.clone(), 2, 4, s))
                    .map(|_| ()),
            }
            .map_err(err)?;
            for &(x, _, i) in &l.points {
                if let Some((a, b)) = i {
                    chart
                        .draw_series(LineSeries::new([(x, a), (x, b)], l.color.stroke_width(1)))
                        .map_err(err)?;
                }
            }
            for p in &pts {
                let (px, py) = chart.backend_coord(p);
                marker(&root, (px - ox, py - oy), l.marker, l.color, 4)?;
            }
        }
        if c.lines.len() > 1 {
            // The legend, top left inside the plot: each line's label in its colour.
            for (i, l) in c.lines.iter().enumerate() {
                let y = 40 + 15 * i as i32;
                marker(&root, (86, y + 6), l.marker, l.color, 4)?;
                root.draw(&Text::new(
                    l.label.clone(),
                    (96, y),
                    TextStyle::from((FONT, 11).into_font()).color(&l.color),
                ))
                .map_err(err)?;
            }
        }
        root.present().map_err(err)?;
    }
    Ok(svg)
}

/// Writes the trend page of `h` with the steps of `c` into `out/index.html` and returns its
/// path; commits link to `commit_url` with `{sha}` replaced, or to their row of the page.
///
/// Errors: the chart font cannot be loaded, a chart cannot be drawn, or the folder or the file
/// cannot be written; each names the file.
pub fn write(out: &Path, h: &History, c: &Check, commit_url: Option<&str>) -> Result<PathBuf> {
    crate::report::font::ensure()?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let path = out.join("index.html");
    let html = page(h, c, commit_url)
        .map_err(|e| Error::Other(format!("{}: drawing chart: {e}", path.display())))?;
    crate::visibility::write_atomic(&path, html.as_bytes())?;
    Ok(path)
}

fn link(sha: &str, commit_url: Option<&str>) -> String {
    let href = match commit_url {
        Some(t) => t.replace("{sha}", sha),
        None => format!("#c-{sha}"),
    };
    format!(
        "<a href=\"{}\"><code>{}</code></a>",
        attr(&href),
        text(short(sha))
    )
}

fn pct(e: f64) -> String {
    if e.is_finite() {
        format!("{:+.2}%", e * 100.0)
    } else {
        "from 0".into()
    }
}

/// Whether a step from `a` to `b` is a worsening of a figure of direction `d`.
fn worse(d: super::Direction, a: f64, b: f64) -> bool {
    match d {
        super::Direction::Lower => b > a,
        super::Direction::Higher => b < a,
    }
}

fn step_chart<'a>(x: &'a SeriesChange, labels: &'a [String]) -> Chart<'a> {
    let s = &x.series;
    let (m, d) = style::execution_style(s.execution);
    let points = s
        .points
        .iter()
        .map(|(i, p)| (*i as f64, p.value, p.lower.zip(p.upper)))
        .collect();
    let level = s
        .points
        .iter()
        .zip(&x.fit.levels)
        .map(|((i, _), l)| (*i as f64, *l))
        .collect();
    let marks = x
        .change
        .steps
        .iter()
        .map(|st| {
            (
                s.points[st.at].0 as f64,
                worse(x.direction, st.level_before, st.level_after),
            )
        })
        .collect();
    let unit = super::unit(&s.figure);
    Chart {
        title: format!(
            "{} {} · {} / {} · {}",
            x.change.verdict.label(),
            pct(x.change.effect),
            s.algorithm,
            s.execution,
            s.figure
        ),
        y_label: if unit.is_empty() {
            s.figure.clone()
        } else {
            format!("{} ({unit})", s.figure)
        },
        commits: labels,
        lines: vec![Line {
            label: s.figure.clone(),
            color: style::algorithm_color(&s.algorithm),
            marker: m,
            dash: d,
            points,
        }],
        level,
        marks,
        size: (720, 300),
    }
}

/// The panels of the trends: per algorithm × execution × machine,
/// each headline figure's geometric mean over the runs of value / first value, in percent.
fn trend_charts<'a>(h: &History, labels: &'a [String]) -> Vec<(String, Chart<'a>)> {
    type Key = ((usize, String), Backend, String);
    let mut groups: BTreeMap<Key, BTreeMap<&str, Vec<&super::store::Series>>> = BTreeMap::new();
    for s in &h.series {
        let Some(f) = HEADLINE.iter().find(|f| **f == s.figure) else {
            continue;
        };
        let base = s.algorithm.split(' ').next().unwrap_or(&s.algorithm);
        let machine = s.machine.clone();
        groups
            .entry((style::algorithm_rank(base), s.execution, machine))
            .or_default()
            .entry(f)
            .or_default()
            .push(s);
    }
    // A panel per machine; named by its machine where an algorithm × execution has several.
    let mut panels_of: BTreeMap<(String, Backend), usize> = BTreeMap::new();
    for (a, e, _) in groups.keys() {
        *panels_of.entry((a.1.clone(), *e)).or_default() += 1;
    }
    let mut out = Vec::new();
    for (((_, alg_key), exec, machine), figures) in groups {
        let named = panels_of[&(alg_key, exec)] > 1;
        let algorithm = figures
            .values()
            .flat_map(|v| v.iter())
            .map(|s| s.algorithm.clone())
            .next()
            .unwrap_or_default();
        let base = algorithm
            .split(' ')
            .next()
            .unwrap_or(&algorithm)
            .to_string();
        let color = style::algorithm_color(&base);
        let (m, d) = style::execution_style(exec);
        let mut lines = Vec::new();
        for (k, f) in HEADLINE.iter().enumerate() {
            let Some(series) = figures.get(f) else {
                continue;
            };
            let mut logs: BTreeMap<usize, (f64, usize)> = BTreeMap::new();
            for s in series {
                let Some(first) = s.points.first().map(|p| p.1.value).filter(|v| *v > 0.0) else {
                    continue;
                };
                for (i, p) in &s.points {
                    if p.value > 0.0 {
                        let e = logs.entry(*i).or_insert((0.0, 0));
                        e.0 += (p.value / first).ln();
                        e.1 += 1;
                    }
                }
            }
            if logs.is_empty() {
                continue;
            }
            let points = logs
                .into_iter()
                .map(|(i, (sum, n))| (i as f64, 100.0 * (sum / n as f64).exp(), None))
                .collect();
            lines.push(Line {
                label: format!("{f} ({} runs)", series.len()),
                color: style::tint(color, [0.0, 0.45, 0.25, 0.6, 0.7][k % 5]),
                marker: [
                    m,
                    Marker::Diamond,
                    Marker::Circle,
                    Marker::Square,
                    Marker::Triangle,
                ][k % 5],
                dash: d,
                points,
            });
        }
        if lines.is_empty() {
            continue;
        }
        let title = if !named {
            format!("{algorithm} / {exec}")
        } else {
            format!("{algorithm} / {exec} @{machine}")
        };
        out.push((
            title.clone(),
            Chart {
                title,
                y_label: "% of the first commit (geometric mean)".into(),
                commits: labels,
                lines,
                level: vec![],
                marks: vec![],
                size: (440, 280),
            },
        ));
    }
    out
}

/// The page's HTML. Errors: a chart that cannot be drawn (the chart library's message).
pub fn page(
    h: &History,
    c: &Check,
    commit_url: Option<&str>,
) -> std::result::Result<String, String> {
    let labels: Vec<String> = h
        .commits
        .iter()
        .map(|c| short(&c.sha)[..7.min(c.sha.len())].to_string())
        .collect();
    let mut p = String::new();
    let (from, to) = (&h.commits[c.since], &h.commits[c.head]);
    let (reg, imp) = (
        c.changes
            .iter()
            .filter(|x| x.change.verdict == Verdict::Regression)
            .count(),
        c.changes
            .iter()
            .filter(|x| x.change.verdict == Verdict::Improvement)
            .count(),
    );
    let _ = write!(
        p,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>shadowbench history</title><style>{STYLE}</style></head><body>\n\
         <h1>shadowbench history</h1>\n<p>{} commits ({} to {}), {} series on {} machine{}. \
         Checked {} against {}: <b>{reg} regression{}, {imp} improvement{}</b> over {} series.</p>\n",
        h.commits.len(),
        text(&h.commits[0].date),
        text(&h.commits[h.commits.len() - 1].date),
        h.series.len(),
        h.machines.len(),
        if h.machines.len() == 1 { "" } else { "s" },
        link(&to.sha, commit_url),
        link(&from.sha, commit_url),
        if reg == 1 { "" } else { "s" },
        if imp == 1 { "" } else { "s" },
        c.series_checked,
    );
    p.push_str("<h2 id=\"steps\">Steps</h2>\n");
    if c.changes.is_empty() {
        p.push_str("<p class=\"none\">No figure moved by its minimum effect.</p>\n");
    } else {
        p.push_str(
            "<table><tr><th></th><th>run</th><th>figure</th><th>kind</th><th>before</th>\
             <th>after</th><th>change</th><th>min</th><th>step at</th></tr>\n",
        );
        for x in &c.changes {
            let class = match x.change.verdict {
                Verdict::Regression => "reg",
                Verdict::Improvement => "imp",
                Verdict::MovedAndBack => "back",
            };
            let at: Vec<String> = x
                .step_commits()
                .into_iter()
                .map(|i| link(&h.commits[i].sha, commit_url))
                .collect();
            let _ = writeln!(
                p,
                "<tr><td class=\"{class}\">{}</td><td class=\"t\">{} / {}</td><td class=\"t\">{}</td>\
                 <td class=\"t\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}%</td><td class=\"t\">{}</td></tr>",
                x.change.verdict.label(),
                text(&x.series.scenario),
                text(&x.series.case_id),
                text(&x.series.figure),
                x.kind.label(),
                fmt_num(x.change.from),
                fmt_num(x.change.to),
                pct(x.change.effect),
                fmt_num(x.min_effect * 100.0),
                at.join(", ")
            );
        }
        p.push_str("</table>\n");
        for x in c.changes.iter().take(MAX_STEP_CHARTS) {
            let svg = draw(&step_chart(x, &labels))?;
            let _ = writeln!(
                p,
                "<figure>{svg}<figcaption>{} / {} on machine <code>{}</code>: {} → {} ({}, {} figure; \
                 minimum effect {}%). Dashed: the fitted level; shaded: after the step.</figcaption></figure>",
                text(&x.series.scenario),
                text(&x.series.case_id),
                text(&x.series.machine),
                fmt_num(x.change.from),
                fmt_num(x.change.to),
                pct(x.change.effect),
                x.kind.label(),
                fmt_num(x.min_effect * 100.0),
            );
        }
        if c.changes.len() > MAX_STEP_CHARTS {
            let _ = writeln!(
                p,
                "<p>{} more steps are in the table above, not charted.</p>",
                c.changes.len() - MAX_STEP_CHARTS
            );
        }
    }
    p.push_str("<h2 id=\"trends\">Trends per algorithm × execution</h2>\n<div class=\"grid\">\n");
    for (_, chart) in trend_charts(h, &labels) {
        let _ = writeln!(p, "<figure>{}</figure>", draw(&chart)?);
    }
    p.push_str(
        "</div>\n<h2 id=\"commits\">Commits</h2>\n<table><tr><th>#</th><th>commit</th>\
                <th>date (UTC)</th><th>branch</th><th class=\"t\">subject</th></tr>\n",
    );
    for (i, k) in h.commits.iter().enumerate() {
        let _ = writeln!(
            p,
            "<tr id=\"c-{}\"><td>{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td></tr>",
            attr(&k.sha),
            i + 1,
            link(&k.sha, commit_url),
            text(&k.date),
            text(&k.branches.join(", ")),
            text(&k.subject)
        );
    }
    p.push_str("</table>\n</body></html>\n");
    Ok(p)
}
