//! Any bytes given as results files to `report`, `compare` and `merge`: an error, or a report
//! (every chart drawn, the summary, the claims, the HTML pages, the CSV), a comparison and a
//! merge, never a panic or a hang.
//!
//! The input is one results file, or two separated by a line `---` (baseline, then current).
//! The report follows `report::write_report` and `report::write_claims` step by step, with the
//! charts drawn in memory (`charts::draw_rgb`, `charts::draw_svg`) instead of written as files.
#![no_main]

use std::path::{Path, PathBuf};

use libfuzzer_sys::fuzz_target;
use shadowbench::harness::output::{self, ResultsFile};
use shadowbench::record::RunRecord;
use shadowbench::report::{self, charts, claims, compare, html, summary};
use shadowbench::util::paths::slug;

fn parse(text: &str, name: &str) -> Option<(PathBuf, ResultsFile)> {
    let path = PathBuf::from(name);
    report::parse_results(text, &path).ok().map(|f| (path, f))
}

/// One plain path component that stays inside its folder.
fn plain_component(name: &str) {
    assert_eq!(Path::new(name).components().count(), 1, "{name}");
    assert!(
        !name.is_empty() && !name.starts_with('.') && !name.contains('/'),
        "{name}"
    );
}

/// What `report` makes of one results file, in memory.
fn report_of(file: &ResultsFile) {
    let (chartable, _warnings) = charts::chartable(&file.runs);
    let mut written = Vec::new();
    for spec in charts::plan(&chartable) {
        let _ = charts::draw_rgb(&spec);
        let _ = charts::draw_svg(&spec);
        plain_component(&spec.file);
        written.push(charts::Written {
            png: format!("charts/{}.png", spec.file),
            svg: format!("charts/{}.svg", spec.file),
            file: spec.file,
            title: spec.title,
            case: spec.case,
            caption: spec.caption,
        });
    }
    let ok: Vec<&RunRecord> = chartable.iter().filter(|r| r.failure.is_none()).collect();
    let summary = summary::Summary::of(&ok);
    if let Some(s) = &summary {
        let _ = s.csv();
        let _ = s.latex(&file.scenario);
    }
    let _ = html::page(
        Path::new("fuzz/no-such-dir"),
        file,
        &written,
        summary.as_ref(),
    );
    let _ = output::csv(&file.runs);
    let _ = serde_json::to_string_pretty(file);
    for r in &file.runs {
        // Every run's image folder name is one plain path component.
        plain_component(&r.case_id());
    }
    plain_component(&slug(&file.scenario));
}

fuzz_target!(|data: &[u8]| {
    let _ = report::font::ensure();
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let (a, b) = text.split_once("\n---\n").unwrap_or((text, text));
    let (Some(old), Some(new)) = (
        parse(a, "fuzz/baseline.json"),
        parse(b, "fuzz/current.json"),
    ) else {
        return;
    };
    // compare
    if let Ok(c) = compare::compare(
        (&old.0, &old.1),
        (&new.0, &new.1),
        &compare::Options::default(),
    ) {
        let _ = c.render();
        let _ = c.regressed();
    }
    // merge
    let _ = report::merge(&[old.clone(), new.clone()]);
    // report of both files, and the claims over both (the index page of a report of several)
    if a != b {
        report_of(&old.1);
    }
    report_of(&new.1);
    let files = [&old.1, &new.1];
    let all: Vec<claims::ScenarioRuns> = files
        .iter()
        .map(|f| claims::ScenarioRuns {
            scenario: &f.scenario,
            runs: &f.runs,
        })
        .collect();
    let outcomes: Vec<claims::Outcome> = files
        .iter()
        .flat_map(|f| claims::evaluate(&f.scenario, &f.claims, &all))
        .collect();
    let _ = claims::render_text(&outcomes);
    let refs: Vec<(String, &ResultsFile)> = files.iter().map(|f| (slug(&f.scenario), *f)).collect();
    let _ = html::index_page("fuzz", &refs, &outcomes);
});
