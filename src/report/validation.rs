//! The chart of `validate-model`: modelled time (cpu-model, y) against measured time
//! (cpu-native, x) on log-log axes with the line y = x, one panel for whole runs and one for
//! phases, one colour per algorithm (the report's colours).

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::style;
use crate::error::{Error, Result};
use crate::harness::validate::{Agreement, Row, Validation};
use crate::util::cpu_time::Clock;

const FONT: &str = super::font::FAMILY;
const PANEL: (u32, u32) = (560, 520);
const LEGEND_WIDTH: u32 = 200;
const HEADER: u32 = 56;

type DrawResult = std::result::Result<(), String>;

fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// Writes `DIR/NAME.png` and `DIR/NAME.svg`; returns their paths.
pub fn chart(dir: &Path, name: &str, v: &Validation) -> Result<Vec<PathBuf>> {
    super::font::ensure()?;
    let size = (2 * PANEL.0 + LEGEND_WIDTH, PANEL.1 + HEADER);
    let png = dir.join(format!("{name}.png"));
    let svg = dir.join(format!("{name}.svg"));
    let fail =
        |path: &Path, e: String| Error::Other(format!("{}: drawing chart: {e}", path.display()));
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        draw(&root, v).map_err(|e| fail(&png, e))?;
        root.present().map_err(|e| fail(&png, e.to_string()))?;
    }
    let tmp = crate::harness::outdir::temp_path(&png);
    image::RgbImage::from_raw(size.0, size.1, buf)
        .expect("buffer sized to the image")
        .save_with_format(&tmp, image::ImageFormat::Png)
        .map_err(|e| fail(&png, e.to_string()))?;
    std::fs::rename(&tmp, &png).map_err(|e| Error::io(&png, e))?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        draw(&root, v).map_err(|e| fail(&svg, e))?;
        root.present().map_err(|e| fail(&svg, e.to_string()))?;
    }
    crate::visibility::write_atomic(&svg, text.as_bytes())?;
    Ok(vec![png, svg])
}

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, v: &Validation) -> DrawResult {
    root.fill(&WHITE).map_err(err)?;
    let (header, body) = root.split_vertically(HEADER);
    header
        .draw(&Text::new(
            format!(
                "cpu-model ({}) against cpu-native on this machine: modelled vs measured time",
                v.machine.name
            ),
            (14, 10),
            (FONT, 18).into_font(),
        ))
        .map_err(err)?;
    header
        .draw(&Text::new(
            format!(
                "grey line: modelled = measured; dashed: ±30%{}",
                v.training
                    .as_ref()
                    .map(|t| {
                        format!(
                            "; issue costs fitted on {} at {} (held out here); cpu-native on the {} clock",
                            t.scenes.join(", "),
                            t.images
                                .iter()
                                .map(|[w, h]| format!("{w}x{h}"))
                                .collect::<Vec<_>>()
                                .join(", "),
                            v.sweep.clock.name()
                        )
                    })
                    .unwrap_or_default()
            ),
            (14, 34),
            (FONT, 13).into_font().color(&RGBColor(90, 90, 90)),
        ))
        .map_err(err)?;
    let (panels, legend) = body.split_horizontally(2 * PANEL.0);
    let (left, right) = panels.split_horizontally(PANEL.0);
    let x_desc = match v.sweep.clock {
        Clock::Cpu => "measured: cpu-native CPU-clock ms (median), log scale",
        Clock::Wall => "measured: cpu-native wall ms (median), log scale",
    };
    let held = if v.training.is_some() {
        "held-out runs"
    } else {
        "whole runs"
    };
    panel(&left, held, x_desc, &v.runs, &v.runs_agreement)?;
    panel(&right, "phases", x_desc, &v.phases, &v.phases_agreement)?;
    let style = TextStyle::from((FONT, 14).into_font()).color(&BLACK);
    for (i, (alg, _)) in v.per_algorithm.iter().enumerate() {
        let y = 40 + 22 * i as i32;
        legend
            .draw(&Circle::new(
                (20, y),
                5,
                style::algorithm_color(alg).filled(),
            ))
            .map_err(err)?;
        legend
            .draw(&Text::new(alg.clone(), (34, y - 8), style.clone()))
            .map_err(err)?;
    }
    Ok(())
}

/// Bounds of a log axis holding every value of both axes (one range, so y = x is the diagonal).
fn bounds(rows: &[Row]) -> (f64, f64) {
    let vals = rows
        .iter()
        .flat_map(|r| [r.modelled_ms, r.measured_ms])
        .filter(|v| v.is_finite() && *v > 0.0);
    let (lo, hi) = vals.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (0.01, 1.0);
    }
    (lo / 1.5, hi * 1.5)
}

fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    x_desc: &str,
    rows: &[Row],
    a: &Agreement,
) -> DrawResult {
    let (lo, hi) = bounds(rows);
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "{title}: n = {}, geomean ratio {:.2}, MAPE {:.0}%, Spearman ρ {:.3}",
                a.n, a.geomean_ratio, a.mape_pct, a.spearman
            ),
            (FONT, 14),
        )
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d((lo..hi).log_scale(), (lo..hi).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("modelled: cpu-model ms, log scale")
        .x_label_formatter(&|v| format!("{v}"))
        .y_label_formatter(&|v| format!("{v}"))
        .label_style((FONT, 12))
        .axis_desc_style((FONT, 13))
        .bold_line_style(RGBColor(215, 215, 215))
        .light_line_style(RGBColor(240, 240, 240))
        .draw()
        .map_err(err)?;
    let grey = RGBColor(120, 120, 120);
    chart
        .draw_series(LineSeries::new([(lo, lo), (hi, hi)], grey.stroke_width(1)))
        .map_err(err)?;
    for k in [0.7, 1.3] {
        // ±30% as dashed lines: short segments along y = k·x.
        let steps = 60;
        let ratio = (hi / lo).powf(1.0 / steps as f64);
        for i in (0..steps).step_by(2) {
            let x0 = lo * ratio.powi(i);
            let x1 = x0 * ratio;
            chart
                .draw_series(LineSeries::new(
                    [(x0, x0 * k), (x1, x1 * k)],
                    RGBColor(170, 170, 170).stroke_width(1),
                ))
                .map_err(err)?;
        }
    }
    let finite = rows
        .iter()
        .filter(|r| r.modelled_ms > 0.0 && r.measured_ms > 0.0 && r.ratio.is_finite());
    chart
        .draw_series(finite.map(|r| {
            Circle::new(
                (r.measured_ms, r.modelled_ms),
                4,
                style::algorithm_color(&r.algorithm).filled(),
            )
        }))
        .map_err(err)?;
    Ok(())
}
