//! What `compare` says first, for a reader: the settings that differ between the two results
//! (`options.pcss.pcf_samples 32 -> 36`, `params.map_resolution 256 -> 320`) and one line per
//! run with its modelled (or wall) time, its shadow error and its main cost counters, baseline
//! against current. The gate's table of every figure ([`super::compare`]) stays the verdict.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde_json::Value;

use super::fmt_num;
use crate::harness::output::ResultsFile;
use crate::record::RunRecord;

/// The leaves of a JSON value by path (`options.pcss.pcf_samples`); a list is one leaf.
fn leaves(v: &Value, path: &str, out: &mut BTreeMap<String, Value>) {
    match v {
        Value::Object(m) if !m.is_empty() => {
            for (k, v) in m {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                leaves(v, &p, out);
            }
        }
        _ => {
            out.insert(path.to_string(), v.clone());
        }
    }
}

/// The settings of a results file by path: its scenario as run (`config`), and each
/// algorithm's options as its runs used them (`execution.options`, defaults filled in) under
/// `options.<algorithm>`, so files without `config` (older versions) still name option changes.
fn settings(f: &ResultsFile) -> BTreeMap<String, Value> {
    let mut out = BTreeMap::new();
    if let Some(c) = &f.config {
        leaves(c, "", &mut out);
    }
    for r in &f.runs {
        if let Some(o) = r.execution.get("options") {
            leaves(o, &format!("options.{}", r.algorithm), &mut out);
        }
    }
    out.retain(|k, _| k != "name" && k != "description");
    out
}

/// The settings that differ, one line each: `options.pcss.pcf_samples 32 -> 36`, `absent` for
/// a setting only one side has.
pub fn setting_changes(baseline: &ResultsFile, current: &ResultsFile) -> Vec<String> {
    let (a, b) = (settings(baseline), settings(current));
    let show = |v: Option<&Value>| v.map_or("absent".to_string(), |v| v.to_string());
    let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.into_iter()
        .filter(|k| a.get(*k) != b.get(*k))
        .map(|k| format!("{k} {} -> {}", show(a.get(k)), show(b.get(k))))
        .collect()
}

/// The main figures of a run: its time (modelled where there is one, else wall), `mae_shadow`,
/// fill and modelled memory traffic.
fn main_figures(r: &RunRecord) -> Vec<(&'static str, Option<f64>)> {
    let time = match r.model_ms {
        Some(m) => ("model ms", Some(m)),
        None => ("wall ms", Some(r.wall_ms)),
    };
    vec![
        time,
        ("mae_shadow", r.error.as_ref().and_then(|e| e.mae_shadow)),
        ("fill", r.counters.get("fill")),
        ("memory bytes", super::charts::memory_bytes(r, "mem_model")),
    ]
}

/// `a -> b (+x%)`, or one value when both are equal.
fn moved(a: Option<f64>, b: Option<f64>) -> Option<String> {
    match (a, b) {
        (Some(a), Some(b)) if a == b => Some(fmt_num(a)),
        (Some(a), Some(b)) if a != 0.0 => Some(format!(
            "{} -> {} ({:+.1}%)",
            fmt_num(a),
            fmt_num(b),
            (b - a) / a.abs() * 100.0
        )),
        (Some(a), Some(b)) => Some(format!("{} -> {}", fmt_num(a), fmt_num(b))),
        (None, Some(b)) => Some(format!("absent -> {}", fmt_num(b))),
        (Some(a), None) => Some(format!("{} -> absent", fmt_num(a))),
        (None, None) => None,
    }
}

/// The runs paired: by case id, then the rest of each algorithm × execution in order (a
/// changed parameter changes every case id), so one setting changed everywhere still pairs
/// each run with its counterpart. Unpaired runs come with `None` on the other side.
pub fn pairs<'a>(
    baseline: &'a ResultsFile,
    current: &'a ResultsFile,
) -> Vec<(Option<&'a RunRecord>, Option<&'a RunRecord>)> {
    let mut left: Vec<&RunRecord> = current.runs.iter().collect();
    let mut out = Vec::new();
    let mut unpaired = Vec::new();
    for r in &baseline.runs {
        match left.iter().position(|c| c.case_id() == r.case_id()) {
            Some(i) => out.push((Some(r), Some(left.remove(i)))),
            None => unpaired.push(r),
        }
    }
    for r in unpaired {
        match left
            .iter()
            .position(|c| c.algorithm == r.algorithm && c.backend == r.backend)
        {
            Some(i) => out.push((Some(r), Some(left.remove(i)))),
            None => out.push((Some(r), None)),
        }
    }
    out.extend(left.into_iter().map(|c| (None, Some(c))));
    out
}

/// The headline: one line per changed setting, then one line per run (its case as
/// `algorithm / execution, case`), baseline -> current; runs whose main figures did not move
/// are counted on one line.
pub fn headline(baseline: &ResultsFile, current: &ResultsFile) -> String {
    let mut s = String::new();
    let changes = setting_changes(baseline, current);
    if changes.is_empty() {
        s.push_str("settings: the same\n");
    }
    for c in &changes {
        let _ = writeln!(s, "setting: {c}");
    }
    let mut same = 0;
    for (a, b) in pairs(baseline, current) {
        let r = b.or(a).expect("one side of a pair");
        let name = format!(
            "{} / {}, {}",
            r.algorithm_label(),
            r.backend,
            super::charts::describe_case(r, None)
        );
        let (a, b) = match (a, b) {
            (Some(a), Some(b)) => (a, b),
            (Some(_), None) => {
                let _ = writeln!(s, "{name}: in the baseline only");
                continue;
            }
            _ => {
                let _ = writeln!(s, "{name}: new");
                continue;
            }
        };
        if let (None, Some(f)) | (Some(f), None) = (&a.failure, &b.failure) {
            let which = if b.failure.is_some() {
                "fails now"
            } else {
                "fixed"
            };
            let _ = writeln!(s, "{name}: {which}: {}", f.lines().next().unwrap_or(""));
            continue;
        }
        let (fa, fb) = (main_figures(a), main_figures(b));
        if fa == fb {
            same += 1;
            continue;
        }
        let parts: Vec<String> = fa
            .iter()
            .zip(&fb)
            .filter_map(|((k, x), (_, y))| Some(format!("{k} {}", moved(*x, *y)?)))
            .collect();
        let _ = writeln!(s, "{name}: {}", parts.join(", "));
    }
    if same > 0 {
        let _ = writeln!(
            s,
            "{same} runs with the same time, mae_shadow, fill and memory traffic"
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Backend;
    use crate::report::testdata::record;

    fn file(runs: Vec<RunRecord>, samples: u32) -> ResultsFile {
        ResultsFile {
            scenario: "s".into(),
            runs,
            config: Some(serde_json::json!({
                "name": "s",
                "options": { "pcss": { "pcf_samples": samples } },
                "params": { "map_resolution": 256 }
            })),
            ..Default::default()
        }
    }

    #[test]
    fn one_option_changed_is_one_setting_line_and_one_line_per_run() {
        let a = record("pcss", Backend::CpuModel, 100, 32);
        let mut b = a.clone();
        b.model_ms = a.model_ms.map(|m| m * 1.5);
        let c = record("pcss", Backend::CpuNative, 100, 32);
        let h = headline(&file(vec![a.clone(), c.clone()], 32), &file(vec![b, c], 36));
        let lines: Vec<&str> = h.lines().collect();
        assert_eq!(
            lines[0], "setting: options.pcss.pcf_samples 32 -> 36",
            "{h}"
        );
        assert!(lines[1].starts_with("pcss / cpu-model, "), "{h}");
        assert!(lines[1].contains("(+50.0%)"), "{h}");
        assert_eq!(
            lines[2],
            "1 runs with the same time, mae_shadow, fill and memory traffic"
        );
        assert_eq!(lines.len(), 3);
    }

    #[test]
    fn a_parameter_changed_in_every_run_still_pairs_the_runs() {
        let a = record("pcss", Backend::CpuModel, 100, 32);
        let mut b = a.clone();
        b.params.map_resolution = 320;
        let (fa, fb) = (file(vec![a], 32), file(vec![b], 32));
        let p = pairs(&fa, &fb);
        assert_eq!(p.len(), 1);
        assert!(p[0].0.is_some() && p[0].1.is_some());
    }
}
