//! Turning results into something to read and to gate on: comparison charts, a self-contained
//! HTML report, the regression comparison CI runs, and joining the results of sharded runs.
//!
//! Everything here works from [`RunRecord`]s alone (what `results.json` holds), so it is generic
//! over whatever algorithms, backends and counters the runs carry, and a report can be rebuilt
//! from old results without running anything.

pub mod charts;
pub mod claims;
pub mod compare;
pub mod font;
pub mod headline;
pub mod html;
pub mod measured;
pub mod style;
pub mod summary;
pub mod validation;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, InputError, Result};
use crate::harness::output::{self, ResultsFile};
use crate::record::RunRecord;

/// Reads a `results.json`; any problem (missing, unreadable, not a results file, a scenario
/// name that is a path, a run given twice: [`parse_results`]) is an input error naming the file.
pub fn read_results(path: &Path) -> Result<ResultsFile, InputError> {
    parse_results(&crate::util::input::read_text(path, "results")?, path)
}

/// Parses and checks the text of a results file; `path` names it in errors. `report`,
/// `compare` and `merge` all read through here, so they accept and refuse the same files: the
/// `scenario` must be a plain name ([`crate::util::paths::check_name`]: it names a folder of
/// `report`), every run must name a known execution (or the file does not read:
/// [`crate::backend::Backend`]) and none may appear twice ([`ResultsFile::check_runs`]).
/// Counters of older versions are read under their current names ([`ResultsFile::upgraded`]).
///
/// A file that does not read is an error naming it and, where one value is wrong, that
/// value's JSON path (`$.runs[0].backend: unknown backend 'bogus'; …`), ending with the line
/// and column ([`crate::util::json::parse`]); malformed JSON or another document is "not a
/// shadowbench results file".
pub fn parse_results(text: &str, path: &Path) -> Result<ResultsFile, InputError> {
    let file: ResultsFile = crate::util::json::parse(text, path).map_err(|e| {
        if e.field.as_deref().is_some_and(|f| f != "$") {
            return e;
        }
        InputError {
            message: format!("not a shadowbench results file: {}", e.message),
            field: None,
            ..e
        }
    })?;
    crate::util::paths::check_name("$.scenario", &file.scenario).map_err(|e| e.in_file(path))?;
    file.check_runs().map_err(|e| e.in_file(path))?;
    Ok(file.upgraded())
}

/// What [`write_report`] produced, relative to the output folder.
#[derive(Debug)]
pub struct Report {
    pub index: PathBuf,
    pub charts: Vec<charts::Written>,
}

/// Writes the charts (`charts/*.png`, `charts/*.svg`), the summary at the base point
/// (`summary.csv`, `summary.tex`) and `index.html` into `out`. The images
/// of each run are expected under `out/images/<case_id>/` (see [`import_images`]); the page
/// shows only the ones that exist there.
pub fn write_report(out: &Path, results: &ResultsFile) -> Result<Report> {
    let chart_dir = out.join("charts");
    std::fs::create_dir_all(&chart_dir).map_err(|e| Error::io(&chart_dir, e))?;
    let mut written = Vec::new();
    let (chartable, left_out) = charts::chartable(&results.runs);
    for w in &left_out {
        crate::errln!("warning: {w}");
    }
    for spec in charts::plan(&chartable) {
        written.push(charts::render(&spec, &chart_dir)?);
    }
    let ok: Vec<&RunRecord> = chartable.iter().filter(|r| r.failure.is_none()).collect();
    let summary = summary::Summary::of(&ok);
    if let Some(s) = &summary {
        crate::visibility::write_atomic(&out.join("summary.csv"), s.csv().as_bytes())?;
        let tex = s.latex(&results.scenario);
        crate::visibility::write_atomic(&out.join("summary.tex"), tex.as_bytes())?;
    }
    let index = out.join("index.html");
    let page = html::page(out, results, &written, summary.as_ref());
    crate::visibility::write_atomic(&index, page.as_bytes())?;
    Ok(Report {
        index,
        charts: written,
    })
}

/// Evaluates the paper claims of every scenario of an execution over the runs of all of them,
/// and returns them as text. With `index`, also writes `out/index.html` linking each scenario's
/// report (in `out/<dir>/`) and showing every claim.
pub fn write_claims(out: &Path, reports: &[(String, ResultsFile)], index: bool) -> Result<String> {
    let all: Vec<claims::ScenarioRuns> = reports
        .iter()
        .map(|(_, r)| claims::ScenarioRuns {
            scenario: &r.scenario,
            runs: &r.runs,
        })
        .collect();
    let outcomes: Vec<claims::Outcome> = reports
        .iter()
        .flat_map(|(_, r)| claims::evaluate(&r.scenario, &r.claims, &all))
        .collect();
    if index {
        let refs: Vec<(String, &ResultsFile)> =
            reports.iter().map(|(d, r)| (d.clone(), r)).collect();
        let page = html::index_page("shadowbench: several scenarios", &refs, &outcomes);
        crate::visibility::write_atomic(&out.join("index.html"), page.as_bytes())?;
    }
    Ok(claims::render_text(&outcomes))
}

/// Copies the per-run image folders (`images/<case_id>/`) of `records` from `from` into `out`,
/// so a report written to `out` is self-contained. Runs without images are skipped; nothing is
/// copied when both are the same folder.
pub fn import_images(from: &Path, out: &Path, records: &[RunRecord]) -> Result<()> {
    if crate::util::paths::same_file(from, out) {
        return Ok(());
    }
    for r in records {
        let case = r.case_id();
        let src = from.join("images").join(&case);
        let Ok(entries) = std::fs::read_dir(&src) else {
            continue;
        };
        let dst = out.join("images").join(&case);
        std::fs::create_dir_all(&dst).map_err(|e| Error::io(&dst, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| Error::io(&src, e))?;
            let path = entry.path();
            if path.is_file() {
                let target = dst.join(entry.file_name());
                std::fs::copy(&path, &target).map_err(|e| Error::io(&target, e))?;
            }
        }
    }
    Ok(())
}

/// One kind of note ([`crate::record::note_kind`]) of one algorithm's runs: the note as its
/// first such run has it, and how many of the algorithm's runs carry it.
#[derive(Clone, Debug, PartialEq)]
pub struct NoteLine {
    pub algorithm: String,
    pub note: String,
    pub runs: usize,
    pub of: usize,
}

impl std::fmt::Display for NoteLine {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let e_g = if self.runs > 1 { "e.g. " } else { "" };
        write!(
            f,
            "{}: {e_g}{} ({} of {} runs)",
            self.algorithm, self.note, self.runs, self.of
        )
    }
}

/// The notes of `runs` once per algorithm and kind, in the order first seen.
pub fn notes_by_algorithm(runs: &[RunRecord]) -> Vec<NoteLine> {
    let mut lines: Vec<(String, NoteLine)> = Vec::new();
    for r in runs {
        let mut kinds: Vec<String> = Vec::new();
        for n in &r.notes {
            let kind = crate::record::note_kind(n);
            if kinds.contains(&kind) {
                continue;
            }
            match lines
                .iter_mut()
                .find(|(k, l)| *k == kind && l.algorithm == r.algorithm)
            {
                Some((_, l)) => l.runs += 1,
                None => lines.push((
                    kind.clone(),
                    NoteLine {
                        algorithm: r.algorithm.clone(),
                        note: n.clone(),
                        runs: 1,
                        of: runs.iter().filter(|x| x.algorithm == r.algorithm).count(),
                    },
                )),
            }
            kinds.push(kind);
        }
    }
    lines.into_iter().map(|(_, l)| l).collect()
}

/// The folder a results file lives in (where its `images/` are).
pub fn results_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Joins the results of several runs (typically the shards of one sweep) in the order given.
/// A case present in more than one file must be identical in each, or it is an error naming the
/// case and both files; all files must come from the same scenario.
pub fn merge(inputs: &[(PathBuf, ResultsFile)]) -> Result<ResultsFile, InputError> {
    let Some((first_path, first)) = inputs.first() else {
        return Err(InputError::new("merge", "no results files given"));
    };
    let mut seen: BTreeMap<String, (usize, &Path)> = BTreeMap::new();
    let mut runs: Vec<RunRecord> = Vec::new();
    for (path, file) in inputs {
        if file.scenario != first.scenario {
            return Err(InputError {
                file: Some(path.clone()),
                field: Some("$.scenario".into()),
                message: format!(
                    "scenario '{}' differs from '{}' in {}",
                    file.scenario,
                    first.scenario,
                    first_path.display()
                ),
            });
        }
        for r in &file.runs {
            let case = r.case_id();
            match seen.get(&case) {
                Some((i, _)) if runs[*i] == *r => {}
                Some((_, other)) => {
                    return Err(InputError::file(
                        path,
                        format!(
                            "run '{case}' is also in {} with different results; \
                             merge only disjoint shards of one sweep",
                            other.display()
                        ),
                    ))
                }
                None => {
                    seen.insert(case, (runs.len(), path));
                    runs.push(r.clone());
                }
            }
        }
    }
    Ok(ResultsFile {
        origin: None,
        scenario: first.scenario.clone(),
        runs,
        claims: first.claims.clone(),
        overrides: first.overrides.clone(),
        config: first.config.clone(),
    })
}

/// Joins the results of different scenarios into one (`report --combine`), so their runs are
/// charted on shared axes: every run of each file in the order given, under the scenario name
/// `a + b + …`, with every file's claims. A run in two files (one case id) is an error naming
/// it and both files.
pub fn combine(inputs: &[(PathBuf, ResultsFile)]) -> Result<ResultsFile, InputError> {
    if inputs.is_empty() {
        return Err(InputError::new("report", "no results files given"));
    }
    let mut seen: BTreeMap<String, &Path> = BTreeMap::new();
    let mut out = ResultsFile {
        scenario: inputs
            .iter()
            .map(|(_, f)| f.scenario.as_str())
            .collect::<Vec<_>>()
            .join(" + "),
        ..Default::default()
    };
    for (path, file) in inputs {
        for r in &file.runs {
            if let Some(other) = seen.insert(r.case_id(), path) {
                return Err(InputError::file(
                    path,
                    format!(
                        "run '{}' is also in {}; --combine joins different runs",
                        r.case_id(),
                        other.display()
                    ),
                ));
            }
            out.runs.push(r.clone());
        }
        out.claims.extend(file.claims.iter().cloned());
        out.overrides.extend(file.overrides.iter().cloned());
    }
    Ok(out)
}

/// Writes combined results ([`combine`]: `results.json`, `results.csv`), the images of every
/// run and one report of them all into `out`.
pub fn write_combined(out: &Path, inputs: &[(PathBuf, ResultsFile)]) -> Result<Report> {
    let combined = combine(inputs)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    for (path, file) in inputs {
        import_images(results_dir(path), out, &file.runs)?;
    }
    output::write_results(out, &combined)?;
    write_report(out, &combined)
}

/// Writes merged results (`results.json`, `results.csv`), the images of every run and the
/// report into `out`.
pub fn write_merged(out: &Path, inputs: &[(PathBuf, ResultsFile)]) -> Result<Report> {
    let merged = merge(inputs)?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    for (path, file) in inputs {
        import_images(results_dir(path), out, &file.runs)?;
    }
    output::write_results(out, &merged)?;
    write_report(out, &merged)
}

/// A number for a table or an axis label: four significant digits, scientific notation for
/// very large or small magnitudes.
pub fn fmt_num(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return v.to_string();
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        return format!("{v:.2e}");
    }
    let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
pub(crate) mod testdata {
    use crate::backend::Backend;
    use crate::frame::RunParams;
    use crate::metrics::ErrorMetrics;
    use crate::record::{Counters, Phase, RunRecord};

    /// A successful run with the given sweep point and figures.
    pub fn record(algorithm: &str, backend: Backend, triangles: u32, tile: u32) -> RunRecord {
        let mut counters = Counters::default();
        counters.set("fill", 1000.0 + triangles as f64);
        counters.set("overdraw", 250.0);
        counters.set("mem_model.read_bytes", 4096.0 * tile as f64);
        counters.set("mem_model.write_bytes", 1024.0);
        counters.set("overdraw_ratio", 250.0 / (1000.0 + triangles as f64));
        RunRecord {
            algorithm: algorithm.into(),
            variant: None,
            backend,
            scene: "sphere-on-plane".into(),
            light: "sphere".into(),
            params: RunParams {
                triangles,
                light_size: 0.5,
                map_resolution: 512,
                tile_size: tile,
                image: [96, 72],
                occluder_height: None,
                occluder_offset: None,
                cores: None,
            },
            counters,
            phases: vec![
                Phase {
                    name: "construct".into(),
                    wall_ms: 1.0,
                    model_ms: Some(0.4),
                    ..Default::default()
                },
                Phase {
                    name: "soft".into(),
                    wall_ms: 2.0,
                    model_ms: Some(0.6),
                    ..Default::default()
                },
            ],
            wall_ms: 3.0 + triangles as f64 / 1000.0,
            model_ms: Some(1.0 + triangles as f64 / 100.0),
            gpu_ms: None,
            gpu_setup_ms: None,
            cold_wall_ms: None,
            cold_gpu_ms: None,
            measured: None,
            error: Some(ErrorMetrics {
                mae: Some(0.01),
                rmse: Some(0.02),
                max: Some(0.5),
                mae_shadow: Some(0.05),
                frac_over_0_1: Some(0.01),
                pixels: 6912,
                shadow_pixels: 800,
                mae_shadow_receivers: None,
                grazing_pixels: 0,
                mae_shadow_non_grazing: None,
                ..Default::default()
            }),
            animation: None,
            execution: [("host_threads".to_string(), serde_json::json!(2))].into(),
            warnings: vec![],
            notes: vec![],
            framing: None,
            failure: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Backend;

    #[test]
    fn numbers_keep_four_significant_digits() {
        assert_eq!(fmt_num(0.0), "0");
        assert_eq!(fmt_num(1234.5678), "1235");
        assert_eq!(fmt_num(1.5), "1.5");
        assert_eq!(fmt_num(0.012345), "0.01235");
        assert_eq!(fmt_num(2.5e7), "2.50e7");
        assert_eq!(fmt_num(-3.0), "-3");
    }

    #[test]
    fn notes_are_listed_once_per_algorithm_and_kind_and_old_warnings_become_notes() {
        let mut runs = Vec::new();
        for (t, pixels) in [(100, 12), (200, 40), (400, 0)] {
            let mut r = testdata::record("soft_shadow_map", Backend::CpuModel, t, 32);
            if pixels > 0 {
                r.warnings.push(format!(
                    "method limit (no self-shadowing): {pixels} pixels the reference shadows"
                ));
            }
            r.warnings
                .push("light converted from sphere to disc".into());
            r.warnings.push("reader skipped 3 faces".into());
            runs.push(r);
        }
        runs.push(testdata::record("pcss", Backend::CpuModel, 100, 32));
        let f = file(runs).upgraded();
        assert!(f.runs[..3]
            .iter()
            .all(|r| r.warnings == ["reader skipped 3 faces"]));
        let lines = notes_by_algorithm(&f.runs);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert_eq!((lines[0].runs, lines[0].of), (2, 3));
        assert!(lines[0].note.contains("12 pixels"));
        assert_eq!((lines[1].runs, lines[1].of), (3, 3));
        assert_eq!(
            lines[0].to_string(),
            "soft_shadow_map: e.g. method limit (no self-shadowing): 12 pixels the reference \
             shadows (2 of 3 runs)"
        );
    }

    #[test]
    fn combine_joins_scenarios_and_refuses_a_run_in_two_files() {
        let mut a = file(vec![testdata::record("pcss", Backend::CpuModel, 100, 32)]);
        a.scenario = "lod0".into();
        let mut b = file(vec![testdata::record("pcss", Backend::CpuModel, 400, 32)]);
        b.scenario = "lod1".into();
        let c = combine(&[("a".into(), a.clone()), ("b".into(), b)]).unwrap();
        assert_eq!((c.scenario.as_str(), c.runs.len()), ("lod0 + lod1", 2));
        let e = combine(&[("a".into(), a.clone()), ("b".into(), a)]).unwrap_err();
        assert!(e.message.contains("is also in a"), "{e}");
    }

    fn file(runs: Vec<RunRecord>) -> ResultsFile {
        ResultsFile {
            origin: None,
            scenario: "s".into(),
            runs,
            claims: vec![],
            ..Default::default()
        }
    }

    #[test]
    fn merge_joins_disjoint_files_and_accepts_identical_duplicates() {
        let a = testdata::record("pcss", Backend::CpuModel, 100, 32);
        let b = testdata::record("pcss", Backend::CpuModel, 200, 32);
        let merged = merge(&[
            ("a.json".into(), file(vec![a.clone()])),
            ("b.json".into(), file(vec![b.clone(), a.clone()])),
        ])
        .unwrap();
        assert_eq!(merged.runs, vec![a, b]);
    }

    #[test]
    fn merge_rejects_conflicting_duplicates_naming_both_files() {
        let a = testdata::record("pcss", Backend::CpuModel, 100, 32);
        let mut a2 = a.clone();
        a2.wall_ms += 1.0;
        let e = merge(&[
            ("a.json".into(), file(vec![a.clone()])),
            ("b.json".into(), file(vec![a2])),
        ])
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("b.json: "), "{e}");
        assert!(e.contains(&a.case_id()) && e.contains("a.json"), "{e}");
    }

    #[test]
    fn merge_rejects_different_scenarios() {
        let mut other = file(vec![]);
        other.scenario = "t".into();
        let e = merge(&[("a.json".into(), file(vec![])), ("b.json".into(), other)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("b.json") && e.contains("'t'"), "{e}");
    }

    #[test]
    fn unreadable_results_name_the_file() {
        let (dir, missing) = crate::util::paths::temp_path("nope.json");
        let e = read_results(&missing).unwrap_err().to_string();
        assert!(e.contains("nope.json") && e.contains("cannot read"), "{e}");
        let bad = dir.path().join("bad.json");
        for text in ["{\"runs\": [", "3", "{\"scenario\": \"s\"}"] {
            std::fs::write(&bad, text).unwrap();
            let e = read_results(&bad).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("{}: not a shadowbench results", bad.display()))
                    && e.contains(" at line 1 column "),
                "{text}: {e}"
            );
        }
        // A value of the wrong type or an unknown execution: the field, the value and where.
        std::fs::write(&bad, "{\"runs\": 3}").unwrap();
        let e = read_results(&bad).unwrap_err().to_string();
        assert!(
            e.contains("bad.json: $.runs: invalid type: integer `3`")
                && e.ends_with("at line 1 column 10"),
            "{e}"
        );
        let mut run = serde_json::to_value(testdata::record("pcss", Backend::Wgpu, 1, 2)).unwrap();
        run["backend"] = "bogus".into();
        let file = serde_json::json!({"scenario": "s", "runs": [run]});
        std::fs::write(&bad, serde_json::to_string_pretty(&file).unwrap()).unwrap();
        let e = read_results(&bad).unwrap_err().to_string();
        let line = serde_json::to_string_pretty(&file)
            .unwrap()
            .lines()
            .position(|l| l.contains("\"bogus\""))
            .unwrap()
            + 1;
        assert!(
            e.starts_with(&format!(
                "{}: $.runs[0].backend: unknown backend 'bogus'; expected one of: cpu-native, \
                 cpu-model, wgpu at line {line} column ",
                bad.display()
            )),
            "{e}"
        );
    }
}
