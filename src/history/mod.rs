//! Results across commits: a history store, step detection, a trend page and the formats CI
//! dashboards read (`shadowbench history record | check | report`).
//!
//! - [`store`]: an SQLite file (schema in its docs, versioned) of every figure of every run,
//!   keyed by scenario, case id, algorithm, execution, figure and machine, per commit.
//! - [`figures`]: which numbers of a run record are figures, and their spread.
//! - [`detect`]: the commits where a series stepped, and the verdict since a commit;
//!   [`check`] applies it to every series.
//! - [`formats`]: the check as text and Markdown; Bencher Metric Format and
//!   github-action-benchmark's custom JSON.
//! - [`page`]: the trend page.
//! - [`provenance`]: the commit, branch and date of a recording, and the machine's
//!   fingerprint.
//!
//! Every figure has a direction (lower or higher is better) and a kind (deterministic,
//! modelled, estimated or measured); both come from [`direction`] and [`kind`], the only place
//! the history looks them up.

pub mod check;
pub mod detect;
pub mod figures;
pub mod formats;
pub mod page;
pub mod provenance;
pub mod store;

pub use crate::counters::{Direction, Kind};

/// The last dotted segment of a figure name (`phase.raster.model_ms` → `model_ms`), with the
/// `counters.` part of a counter figure removed (`counters.cache.l1_hits` → `cache.l1_hits`).
fn leaf(figure: &str) -> &str {
    if let Some(i) = figure.find("counters.") {
        return &figure[i + "counters.".len()..];
    }
    figure.rsplit('.').next().unwrap_or(figure)
}

/// The glossary entry of figure `figure` (a name as [`figures::of_record`] gives it): the name
/// itself ([`crate::counters::figure`]), else its last segment (`measured.wall_ms` → `wall_ms`).
fn glossary(figure: &str) -> Option<&'static crate::counters::Counter> {
    crate::counters::figure(figure).or_else(|| crate::counters::figure(leaf(figure)))
}

/// The direction of figure `figure`, from the glossary; lower is better for a figure it does not
/// hold (every such figure of a record is a time or a count).
pub fn direction(figure: &str) -> Direction {
    glossary(figure).map_or(Direction::Lower, |c| c.better)
}

/// The kind of figure `figure`, from the glossary; for a figure it does not hold, measured for
/// a time (`cold_wall_ms`) and deterministic otherwise.
pub fn kind(figure: &str) -> Kind {
    glossary(figure).map_or_else(
        || {
            if leaf(figure).ends_with("_ms") {
                Kind::Measured
            } else {
                Kind::Deterministic
            }
        },
        |c| c.kind,
    )
}

/// The unit of figure `figure`, for dashboards: the glossary's for counters, `ms` for times,
/// empty for ratios and quality metrics.
pub fn unit(figure: &str) -> &'static str {
    let leaf = leaf(figure);
    if figure.contains("counters.") {
        return crate::counters::find(leaf).map_or("", |c| c.unit);
    }
    if leaf.ends_with("_ms") {
        "ms"
    } else {
        ""
    }
}

/// The default minimum effect of a figure, in percent of its level before a step: 1% for the
/// deterministic kinds (they have no noise; below 1% is rounding and float order), 10% for
/// measured times (run-to-run spread on shared CI runners is several percent).
pub fn default_min_effect_pct(kind: Kind) -> f64 {
    if kind == Kind::Measured {
        10.0
    } else {
        1.0
    }
}

/// The figures the trend page's panels and the dashboard formats show by default: the time of
/// each execution, the quality and the fill.
pub const HEADLINE: [&str; 5] = [
    "model_ms",
    "wall_ms",
    "gpu_ms",
    "error.mae_shadow",
    "counters.fill",
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_and_kinds_follow_the_figure_not_its_prefix() {
        assert_eq!(direction("counters.fill"), Direction::Lower);
        assert_eq!(
            direction("phase.raster.counters.simd_utilization"),
            Direction::Higher
        );
        assert_eq!(direction("error.mae_shadow"), Direction::Lower);
        assert_eq!(direction("error.mae_penumbra"), Direction::Lower);
        assert_eq!(direction("error.flip"), Direction::Lower);
        assert_eq!(direction("error.ssim"), Direction::Higher);
        assert_eq!(kind("model_ms"), Kind::Modelled);
        assert_eq!(kind("phase.raster.model_ms"), Kind::Modelled);
        assert_eq!(kind("wall_ms"), Kind::Measured);
        assert_eq!(kind("phase.raster.gpu_ms"), Kind::Measured);
        assert_eq!(kind("counters.mem_est.read_bytes"), Kind::Estimated);
        assert_eq!(kind("counters.fill"), Kind::Deterministic);
        assert_eq!(kind("error.mae"), Kind::Deterministic);
        assert_eq!(unit("counters.fill"), "fragments");
        assert_eq!(unit("phase.x.wall_ms"), "ms");
    }
}
