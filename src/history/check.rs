//! `history check`: every series' change between a commit and the newest (or a given) one.

use super::detect::{self, Change, Fit, Verdict};
use super::store::{History, Series};
use super::{default_min_effect_pct, direction, kind, Direction, Kind};
use crate::error::InputError;

/// A per-figure minimum effect: `pattern` is a figure name (`model_ms`), a figure's last part
/// matching at any depth (`model_ms` also matches `phase.raster.model_ms`), or a prefix ending
/// in `*` (`counters.mem_model.*`); `None` for every figure.
#[derive(Clone, Debug, PartialEq)]
pub struct MinEffect {
    pub pattern: Option<String>,
    /// Percent.
    pub pct: f64,
}

impl MinEffect {
    /// Parses `PCT` or `FIGURE=PCT` (the value of `--min-effect`).
    pub fn parse(s: &str) -> Result<MinEffect, InputError> {
        let (pattern, pct) = match s.rsplit_once('=') {
            Some((p, v)) => (Some(p.trim().to_string()), v),
            None => (None, s),
        };
        let bad = || {
            InputError::new(
                "--min-effect",
                format!("expected PERCENT or FIGURE=PERCENT (a number >= 0), got '{s}'"),
            )
        };
        let pct: f64 = pct.trim().parse().map_err(|_| bad())?;
        if !pct.is_finite() || pct < 0.0 || pattern.as_deref() == Some("") {
            return Err(bad());
        }
        Ok(MinEffect { pattern, pct })
    }

    fn matches(&self, figure: &str) -> bool {
        match &self.pattern {
            None => true,
            Some(p) => match p.strip_suffix('*') {
                Some(prefix) => figure.starts_with(prefix),
                None => figure == p || figure.ends_with(&format!(".{p}")),
            },
        }
    }
}

/// The minimum effect of `figure` (a fraction): the last of `overrides` that matches it, else
/// its kind's default.
pub fn min_effect(figure: &str, overrides: &[MinEffect]) -> f64 {
    overrides
        .iter()
        .rev()
        .find(|m| m.matches(figure))
        .map_or(default_min_effect_pct(kind(figure)), |m| m.pct)
        / 100.0
}

/// One series that changed.
#[derive(Clone, Debug)]
pub struct SeriesChange {
    pub series: Series,
    pub kind: Kind,
    pub direction: Direction,
    /// A fraction.
    pub min_effect: f64,
    pub fit: Fit,
    pub change: Change,
}

impl SeriesChange {
    /// The commit index of each step (the first commit at the new level).
    pub fn step_commits(&self) -> Vec<usize> {
        self.change
            .steps
            .iter()
            .map(|s| self.series.points[s.at].0)
            .collect()
    }
}

/// The result of a check.
#[derive(Clone, Debug)]
pub struct Check {
    /// Commit indices into the history's commits.
    pub since: usize,
    pub head: usize,
    /// How many series had a point at `head`.
    pub series_checked: usize,
    /// Regressions (worst first), then improvements (largest first), then moved-and-back.
    pub changes: Vec<SeriesChange>,
}

impl Check {
    pub fn regressed(&self) -> bool {
        self.changes
            .iter()
            .any(|c| c.change.verdict == Verdict::Regression)
    }

    /// Whether anything crossed its minimum effect (a regression or an improvement).
    pub fn crossed(&self) -> bool {
        self.changes
            .iter()
            .any(|c| c.change.verdict != Verdict::MovedAndBack)
    }
}

/// The commit `history check` compares with by default: the last commit before `head`
/// recorded on `branch`; the first commit when there is none.
pub fn default_since(h: &History, head: usize, branch: &str) -> usize {
    (0..head)
        .rev()
        .find(|&i| h.commits[i].branches.iter().any(|b| b == branch))
        .unwrap_or(0)
}

/// Checks every series of `h` between commits `since` and `head` (indices), each with its
/// minimum effect from `overrides` ([`min_effect`]).
pub fn check(h: &History, since: usize, head: usize, overrides: &[MinEffect]) -> Check {
    let mut changes = Vec::new();
    let mut checked = 0;
    for s in &h.series {
        let upto: Vec<&(usize, super::figures::Point)> =
            s.points.iter().filter(|(c, _)| *c <= head).collect();
        if upto.last().is_none_or(|(c, _)| *c != head) {
            continue;
        }
        checked += 1;
        let k = kind(&s.figure);
        let dir = direction(&s.figure);
        let me = min_effect(&s.figure, overrides);
        let pts: Vec<super::figures::Point> = upto.iter().map(|(_, p)| p.clone()).collect();
        let fit = detect::fit(&pts, k == Kind::Measured, me);
        let start = upto.iter().rposition(|(c, _)| *c <= since);
        let Some(change) = detect::since(&fit, start, dir, me) else {
            continue;
        };
        let mut series = s.clone();
        series.points.retain(|(c, _)| *c <= head);
        changes.push(SeriesChange {
            series,
            kind: k,
            direction: dir,
            min_effect: me,
            fit,
            change,
        });
    }
    changes.sort_by(|a, b| {
        a.change
            .verdict
            .cmp(&b.change.verdict)
            .then(b.change.effect.abs().total_cmp(&a.change.effect.abs()))
            .then_with(|| a.series.case_id.cmp(&b.series.case_id))
            .then_with(|| a.series.figure.cmp(&b.series.figure))
    });
    Check {
        since,
        head,
        series_checked: checked,
        changes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn min_effects_match_names_leaves_and_prefixes_and_the_last_wins() {
        let o = [
            MinEffect::parse("0.5").unwrap(),
            MinEffect::parse("model_ms=3").unwrap(),
            MinEffect::parse("counters.mem_model.*=7").unwrap(),
        ];
        assert_eq!(min_effect("counters.fill", &o), 0.005);
        assert_eq!(min_effect("phase.raster.model_ms", &o), 0.03);
        assert_eq!(min_effect("counters.mem_model.read_bytes", &o), 0.07);
        assert_eq!(min_effect("wall_ms", &[]), 0.10);
        assert_eq!(min_effect("counters.fill", &[]), 0.01);
        for bad in ["", "x=", "=3", "x=-1", "x=nan", "3%"] {
            assert!(MinEffect::parse(bad).is_err(), "{bad}");
        }
    }
}
