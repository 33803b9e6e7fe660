//! What `history check` writes: the verdict as text or as a Markdown summary, and the figures
//! of the checked commit in the formats CI dashboards read.
//!
//! - **Markdown** (for `$GITHUB_STEP_SUMMARY` or a pull-request comment): empty unless a
//!   figure crossed its minimum effect; then the regressions and the improvements, each with
//!   its run, figure, levels, change and the commit of its step.
//! - **Bencher Metric Format** (`bmf`, <https://bencher.dev/docs/reference/bencher-metric-format/>):
//!   `{ "<benchmark>": { "<measure>": { "value": v, "lower_value": lo, "upper_value": hi } } }`,
//!   a benchmark per run (`<scenario>/<case id>`, `@<machine>` added when the commit was
//!   recorded on several machines), a measure per figure; the bounds where the figure has an
//!   interval.
//! - **github-action-benchmark** (<https://github.com/benchmark-action/github-action-benchmark>,
//!   its `customSmallerIsBetter` and `customBiggerIsBetter` tools): a JSON array of
//!   `{ "name", "unit", "value", "range"?, "extra" }`, an entry per figure. The action reads one
//!   direction per file, so the figures go into two files, `customSmallerIsBetter.json` and
//!   `customBiggerIsBetter.json`, named after the tool that reads each; `extra` states the
//!   direction, the kind, the machine and the commit.
//!
//! The dashboard formats carry the [`super::HEADLINE`] figures unless every figure is asked
//! for.

use std::collections::BTreeSet;
use std::fmt::Write as _;

use serde_json::{json, Map, Value};

use super::check::{Check, SeriesChange};
use super::detect::Verdict;
use super::figures::Point;
use super::store::{History, Series};
use super::{direction, kind, unit, Direction, HEADLINE};
use crate::report::fmt_num;

/// A commit as the outputs name it: its first 10 digits.
pub fn short(sha: &str) -> &str {
    &sha[..sha.len().min(10)]
}

fn pct(e: f64) -> String {
    if e.is_finite() {
        format!("{:+.2}%", e * 100.0)
    } else {
        "from 0".to_string()
    }
}

/// The run of a series as one label: `scenario / case id`, and the machine when the history
/// has several.
fn run_label(h: &History, s: &Series) -> String {
    if h.runs_on_several_machines() {
        format!("{} / {} @{}", s.scenario, s.case_id, s.machine)
    } else {
        format!("{} / {}", s.scenario, s.case_id)
    }
}

/// The commits of a change's steps, as short ids.
fn step_shas(h: &History, c: &SeriesChange) -> String {
    let v: Vec<String> = c
        .step_commits()
        .into_iter()
        .map(|i| short(&h.commits[i].sha).to_string())
        .collect();
    if v.is_empty() {
        "-".into()
    } else {
        v.join(", ")
    }
}

/// The check as text: what was compared, then every change, regressions first.
pub fn text(h: &History, c: &Check) -> String {
    let mut s = String::new();
    let (from, to) = (&h.commits[c.since], &h.commits[c.head]);
    let _ = writeln!(
        s,
        "history: {} commits; checked {} ({}) against {} ({}): {} series",
        h.commits.len(),
        short(&to.sha),
        to.subject,
        short(&from.sha),
        from.subject,
        c.series_checked
    );
    if c.changes.is_empty() {
        let _ = writeln!(s, "no figure moved by its minimum effect");
        return s;
    }
    let rows: Vec<[String; 8]> = c
        .changes
        .iter()
        .map(|x| {
            [
                match x.change.verdict {
                    Verdict::Regression => "REGRESSION".to_string(),
                    v => v.label().to_string(),
                },
                run_label(h, &x.series),
                x.series.figure.clone(),
                fmt_num(x.change.from),
                fmt_num(x.change.to),
                pct(x.change.effect),
                format!("{}%", fmt_num(x.min_effect * 100.0)),
                step_shas(h, x),
            ]
        })
        .collect();
    let head = [
        "", "run", "figure", "before", "after", "change", "min", "step at",
    ];
    let mut w = head.map(str::len);
    for r in &rows {
        for (i, v) in r.iter().enumerate() {
            w[i] = w[i].max(v.chars().count());
        }
    }
    for r in std::iter::once(head.map(String::from)).chain(rows) {
        let line: Vec<String> = r
            .iter()
            .enumerate()
            .map(|(i, v)| format!("{v:<width$}", width = w[i]))
            .collect();
        let _ = writeln!(s, "{}", line.join("  ").trim_end());
    }
    let (reg, imp) = counts(c);
    let _ = writeln!(s, "{reg} regressions, {imp} improvements");
    s
}

fn counts(c: &Check) -> (usize, usize) {
    let n = |v| c.changes.iter().filter(|x| x.change.verdict == v).count();
    (n(Verdict::Regression), n(Verdict::Improvement))
}

/// The Markdown summary: empty unless something crossed its minimum effect.
pub fn markdown(h: &History, c: &Check) -> String {
    if !c.crossed() {
        return String::new();
    }
    let (reg, imp) = counts(c);
    let (from, to) = (&h.commits[c.since], &h.commits[c.head]);
    let mut s = format!(
        "### shadowbench: {reg} regression{}, {imp} improvement{} at `{}` since `{}`\n\n",
        if reg == 1 { "" } else { "s" },
        if imp == 1 { "" } else { "s" },
        short(&to.sha),
        short(&from.sha)
    );
    s.push_str("| | run | figure | before | after | change | step at |\n");
    s.push_str("|---|---|---|--:|--:|--:|---|\n");
    let cell = |t: &str| t.replace('|', "\\|");
    for x in c
        .changes
        .iter()
        .filter(|x| x.change.verdict != Verdict::MovedAndBack)
    {
        let _ = writeln!(
            s,
            "| {} | `{}` | `{}` | {} | {} | {} | {} |",
            x.change.verdict.label(),
            cell(&run_label(h, &x.series)),
            cell(&x.series.figure),
            fmt_num(x.change.from),
            fmt_num(x.change.to),
            pct(x.change.effect),
            step_shas(h, x)
        );
    }
    s
}

/// The figures of commit `head`: every series with a point there, the [`HEADLINE`] ones
/// unless `all`.
pub fn figures_at(h: &History, head: usize, all: bool) -> Vec<(&Series, &Point)> {
    h.series
        .iter()
        .filter(|s| all || HEADLINE.contains(&s.figure.as_str()))
        .filter_map(|s| {
            let p = s.points.iter().find(|(c, _)| *c == head)?;
            Some((s, &p.1))
        })
        .collect()
}

/// Whether a run of commit `head` was recorded there on more than one machine.
fn several_machines(figures: &[(&Series, &Point)]) -> bool {
    let runs: BTreeSet<(&str, &str)> = figures
        .iter()
        .map(|(s, _)| (s.scenario.as_str(), s.case_id.as_str()))
        .collect();
    let with_machine: BTreeSet<(&str, &str, &str)> = figures
        .iter()
        .map(|(s, _)| (s.scenario.as_str(), s.case_id.as_str(), s.machine.as_str()))
        .collect();
    with_machine.len() > runs.len()
}

/// The figures of commit `head` in Bencher Metric Format.
pub fn bmf(h: &History, head: usize, all: bool) -> Value {
    let figures = figures_at(h, head, all);
    let several = several_machines(&figures);
    let mut out = Map::new();
    for (s, p) in figures {
        let mut bench = format!("{}/{}", s.scenario, s.case_id);
        if several {
            bench.push_str(&format!("@{}", s.machine));
        }
        let mut m = Map::new();
        m.insert("value".into(), json!(p.value));
        if let (Some(lo), Some(hi)) = (p.lower, p.upper) {
            m.insert("lower_value".into(), json!(lo));
            m.insert("upper_value".into(), json!(hi));
        }
        out.entry(bench)
            .or_insert_with(|| Value::Object(Map::new()))
            .as_object_mut()
            .expect("made as an object")
            .insert(s.figure.clone(), Value::Object(m));
    }
    Value::Object(out)
}

/// The figures of commit `head` as github-action-benchmark's custom JSON: (the
/// lower-is-better entries for `customSmallerIsBetter`, the higher-is-better ones for
/// `customBiggerIsBetter`).
pub fn github_action_benchmark(h: &History, head: usize, all: bool) -> (Value, Value) {
    let figures = figures_at(h, head, all);
    let several = several_machines(&figures);
    let sha = &h.commits[head].sha;
    let (mut smaller, mut bigger) = (Vec::new(), Vec::new());
    for (s, p) in figures {
        let dir = direction(&s.figure);
        let mut name = format!("{}/{}/{}", s.scenario, s.case_id, s.figure);
        if several {
            name.push_str(&format!(" @{}", s.machine));
        }
        let mut e = Map::new();
        e.insert("name".into(), json!(name));
        e.insert("unit".into(), json!(unit(&s.figure)));
        e.insert("value".into(), json!(p.value));
        if let (Some(lo), Some(hi)) = (p.lower, p.upper) {
            e.insert(
                "range".into(),
                json!(format!("± {}", fmt_num((hi - lo) / 2.0))),
            );
        }
        e.insert(
            "extra".into(),
            json!(format!(
                "{}; {}; {} / {}; machine {}; commit {}",
                match dir {
                    Direction::Lower => "lower is better",
                    Direction::Higher => "higher is better",
                },
                kind(&s.figure).label(),
                s.algorithm,
                s.execution,
                s.machine,
                short(sha)
            )),
        );
        match dir {
            Direction::Lower => smaller.push(Value::Object(e)),
            Direction::Higher => bigger.push(Value::Object(e)),
        }
    }
    (Value::Array(smaller), Value::Array(bigger))
}
