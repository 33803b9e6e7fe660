//! Any bytes given as results files to `report`, `compare` and `merge`: an error, or a report
//! (charts drawn, HTML page, CSV), a comparison and a merge, never a panic or a hang.
//!
//! The input is one results file, or two separated by a line `---` (baseline, then current).
#![no_main]

use std::path::{Path, PathBuf};

use libfuzzer_sys::fuzz_target;
use shadowbench::harness::output::ResultsFile;
use shadowbench::report::{self, charts, compare};

fn parse(text: &str, name: &str) -> Option<(PathBuf, ResultsFile)> {
    let path = PathBuf::from(name);
    report::parse_results(text, &path).ok().map(|f| (path, f))
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let (a, b) = text.split_once("\n---\n").unwrap_or((text, text));
    let (Some(old), Some(new)) = (parse(a, "fuzz/baseline.json"), parse(b, "fuzz/current.json"))
    else {
        return;
    };
    // compare
    if let Ok(c) = compare::compare((&old.0, &old.1), (&new.0, &new.1), 2.0) {
        let _ = c.render();
        let _ = c.regressed();
    }
    // merge
    let _ = report::merge(&[old.clone(), new.clone()]);
    // report: every chart drawn (as SVG, in memory), the page and the CSV.
    let specs = charts::plan(&new.1.runs);
    for spec in &specs {
        let _ = charts::render_svg(spec);
    }
    let _ = report::html::page(Path::new("fuzz/no-such-dir"), &new.1, &[]);
    let _ = shadowbench::harness::output::csv(&new.1.runs);
    for r in &new.1.runs {
        // Every run's image folder name is one plain path component.
        let id = r.case_id();
        assert_eq!(Path::new(&id).components().count(), 1, "{id}");
        assert!(!id.starts_with('.') && !id.contains('/'), "{id}");
    }
});
