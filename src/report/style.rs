//! The visual encoding shared by every chart and the HTML report: one colour per algorithm,
//! one marker and line style per execution.
//!
//! Colours are Tableau 10 (Stone, Tableau Software, 2016), a qualitative palette whose hues stay
//! apart on white; its yellow and grey are used only past the eighth algorithm. The reference
//! (ground truth) is dark grey. Colours follow the algorithm's place in
//! [`crate::algorithms::ALGORITHMS`], so an algorithm has the same colour in every chart of
//! every report, whatever subset of algorithms a run selected.

use plotters::style::RGBColor;

use crate::algorithms::ALGORITHMS;
use crate::backend::Backend;

/// Tableau 10 without its yellow and grey, in the palette's order.
const PALETTE: [RGBColor; 8] = [
    RGBColor(0x4e, 0x79, 0xa7), // blue
    RGBColor(0xf2, 0x8e, 0x2b), // orange
    RGBColor(0xe1, 0x57, 0x59), // red
    RGBColor(0x76, 0xb7, 0xb2), // teal
    RGBColor(0x59, 0xa1, 0x4f), // green
    RGBColor(0xb0, 0x7a, 0xa1), // purple
    RGBColor(0xff, 0x9d, 0xa7), // pink
    RGBColor(0x9c, 0x75, 0x5f), // brown
];

/// Used after [`PALETTE`]: Tableau 10's yellow and grey.
const EXTRA: [RGBColor; 2] = [RGBColor(0xed, 0xc9, 0x48), RGBColor(0xba, 0xb0, 0xac)];

/// The reference's colour.
pub const REFERENCE: RGBColor = RGBColor(0x4d, 0x4d, 0x4d);

/// Colour of the Pareto front and of axes.
pub const INK: RGBColor = RGBColor(0, 0, 0);

/// The colour of `algorithm`: by its place among the registered algorithms (reference aside);
/// an unknown name (from an older results file) gets one from its name's bytes. A variant of
/// a registered algorithm (`rt_denoised (4 spp raw)`, [`crate::record::RunRecord::variant`])
/// gets a shade of the algorithm's colour ([`variant_shade`]).
pub fn algorithm_color(algorithm: &str) -> RGBColor {
    if algorithm == "reference" {
        return REFERENCE;
    }
    if let Some((id, rest)) = algorithm.split_once(" (") {
        if ALGORITHMS.iter().any(|a| a.id == id) {
            return variant_shade(algorithm_color(id), rest.trim_end_matches(')'));
        }
    }
    let index = ALGORITHMS
        .iter()
        .filter(|a| a.id != "reference")
        .position(|a| a.id == algorithm)
        .unwrap_or_else(|| {
            ALGORITHMS.len()
                + algorithm
                    .bytes()
                    .fold(0usize, |h, b| h.wrapping_mul(31) + b as usize)
        });
    let all = PALETTE.len() + EXTRA.len();
    let i = index % all;
    if i < PALETTE.len() {
        PALETTE[i]
    } else {
        EXTRA[i - PALETTE.len()]
    }
}

/// The shade of `base` for a variant: its first number `n` (rays a pixel) sets the shade on a
/// log₂ ramp (1, 2, 4, 8 and more), darker than `base` for most variants, lighter for a `raw`
/// one (mixed with black up to 55%, or with white from 20% to 65%), so the variants of one
/// algorithm read as one family and apart from each other.
pub fn variant_shade(base: RGBColor, variant: &str) -> RGBColor {
    let n: f64 = variant
        .split(|c: char| !c.is_ascii_digit())
        .find(|s| !s.is_empty())
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
    let level = n.max(1.0).log2().clamp(0.0, 3.0) / 3.0;
    let (target, t) = if variant.contains("raw") {
        (255.0, 0.2 + 0.45 * level)
    } else {
        (0.0, 0.55 * (1.0 - level))
    };
    let mix = |c: u8| (f64::from(c) * (1.0 - t) + target * t).round() as u8;
    RGBColor(mix(base.0), mix(base.1), mix(base.2))
}

/// The colours of the phases of a stacked bar, in phase order: ColorBrewer's Dark2 (Brewer,
/// colorbrewer2.org), a qualitative palette of eight hues that stay apart side by side and
/// on white. A ninth phase reuses the first colour.
const PHASES: [RGBColor; 8] = [
    RGBColor(0x1b, 0x9e, 0x77),
    RGBColor(0xd9, 0x5f, 0x02),
    RGBColor(0x75, 0x70, 0xb3),
    RGBColor(0xe7, 0x29, 0x8a),
    RGBColor(0x66, 0xa6, 0x1e),
    RGBColor(0xe6, 0xab, 0x02),
    RGBColor(0xa6, 0x76, 0x1d),
    RGBColor(0x66, 0x66, 0x66),
];

/// The colour of the `i`-th phase of a stacked bar chart ([`PHASES`]).
pub fn phase_color(i: usize) -> RGBColor {
    PHASES[i % PHASES.len()]
}

/// `c` as `#rrggbb`, for HTML.
pub fn hex(c: RGBColor) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// `c` mixed with white: `t` = 0 is `c`, 1 is white.
pub fn tint(c: RGBColor, t: f64) -> RGBColor {
    let m = |v: u8| (v as f64 + (255.0 - v as f64) * t).round() as u8;
    RGBColor(m(c.0), m(c.1), m(c.2))
}

/// A point marker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
}

/// A line style.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dash {
    Solid,
    Dashed,
    Dotted,
}

/// The marker and line style of an execution: cpu-native ● solid, cpu-model ■ dashed,
/// wgpu ▲ dotted. (Executions are listed in panels and tables in `Backend`'s order, that of
/// [`Backend::ALL`].)
pub fn execution_style(backend: Backend) -> (Marker, Dash) {
    match backend {
        Backend::CpuNative => (Marker::Circle, Dash::Solid),
        Backend::CpuModel => (Marker::Square, Dash::Dashed),
        Backend::Wgpu => (Marker::Triangle, Dash::Dotted),
    }
}

/// Order of algorithms in legends and tables: the reference first, then as registered.
pub fn algorithm_rank(algorithm: &str) -> (usize, String) {
    let id = algorithm.split_once(" (").map_or(algorithm, |(id, _)| id);
    let known = ALGORITHMS
        .iter()
        .position(|a| a.id == id)
        .unwrap_or(usize::MAX);
    (known, algorithm.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Squared distance in RGB.
    fn dist(a: RGBColor, b: RGBColor) -> i32 {
        let d = |x: u8, y: u8| (x as i32 - y as i32).pow(2);
        d(a.0, b.0) + d(a.1, b.1) + d(a.2, b.2)
    }

    #[test]
    fn every_registered_algorithm_has_its_own_colour_far_from_the_others_and_from_white() {
        let colors: Vec<RGBColor> = ALGORITHMS.iter().map(|a| algorithm_color(a.id)).collect();
        for (i, a) in colors.iter().enumerate() {
            // Not near white (the page) or the light grey of the grid.
            assert!(dist(*a, RGBColor(255, 255, 255)) > 60 * 60, "{i}: {a:?}");
            for b in &colors[i + 1..] {
                // At least ~50 apart in RGB: no two algorithms share a colour.
                assert!(dist(*a, *b) > 50 * 50, "{a:?} vs {b:?}");
            }
        }
        assert_eq!(algorithm_color("reference"), REFERENCE);
        // Stable: the same name gives the same colour.
        assert_eq!(algorithm_color("pcss"), algorithm_color("pcss"));
        assert_eq!(
            algorithm_color("not-registered"),
            algorithm_color("not-registered")
        );
    }

    #[test]
    fn executions_differ_in_marker_and_line() {
        let styles: Vec<_> = Backend::ALL.map(execution_style).to_vec();
        for (i, a) in styles.iter().enumerate() {
            for b in &styles[i + 1..] {
                assert!(a.0 != b.0 && a.1 != b.1, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn tint_goes_from_the_colour_to_white() {
        let c = RGBColor(0x4e, 0x79, 0xa7);
        assert_eq!(tint(c, 0.0), c);
        assert_eq!(tint(c, 1.0), RGBColor(255, 255, 255));
        assert_eq!(hex(c), "#4e79a7");
    }
}
