//! The HTML report: one self-contained page (`index.html`) with where the runs ran, every run in a
//! table (failures included), every chart, and per scene each run's visibility buffer beside the
//! reference and the error heat map. All links are relative, so the folder opens from disk.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use html_escape::{encode_double_quoted_attribute as attr, encode_text as text};
use percent_encoding::{utf8_percent_encode, AsciiSet, CONTROLS};

use super::charts::{self, Written};
use super::claims::{self, ScenarioRuns};
use super::fmt_num;
use crate::harness::output::ResultsFile;
use crate::record::RunRecord;

/// Characters escaped in a path segment of a relative URL.
const SEGMENT: &AsciiSet = &CONTROLS
    .add(b' ')
    .add(b'"')
    .add(b'#')
    .add(b'%')
    .add(b'<')
    .add(b'>')
    .add(b'?')
    .add(b'`')
    .add(b'{')
    .add(b'}')
    .add(b'/')
    .add(b'\\');

const STYLE: &str = "body{font-family:sans-serif;margin:2em;color:#222}\
table{border-collapse:collapse;font-size:13px;margin-bottom:1.5em}\
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right}\
th{background:#f0f0f0}td.t{text-align:left}\
tr.fail td{background:#fde8e8}td.status-fail{color:#b00;font-weight:bold;text-align:left}\
figure{display:inline-block;margin:0 1em 1.5em 0;vertical-align:top;max-width:1000px}\
figure img{max-width:100%;border:1px solid #ddd}figcaption{font-size:13px;color:#555}\
.gallery td{text-align:center;vertical-align:top}.gallery img{image-rendering:pixelated;width:288px;border:1px solid #bbb}.gallery th{text-align:center}\
.none{color:#999}";

/// The page for `results`, whose run images are under `out/images/<case_id>/`.
pub fn page(out: &Path, results: &ResultsFile, charts: &[Written]) -> String {
    let runs = &results.runs;
    let failed = runs.iter().filter(|r| r.failure.is_some()).count();
    let mut h = String::new();
    let title = format!("shadowbench: {}", results.scenario);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n<h1>{}</h1>\n\
         <p>{} runs, {} failed. Data: <code>results.json</code>, <code>results.csv</code>.</p>\n",
        text(&title),
        text(&title),
        runs.len(),
        failed
    );
    h.push_str(&execution_table(runs));
    if !results.claims.is_empty() {
        let all = [ScenarioRuns {
            scenario: &results.scenario,
            runs,
        }];
        let outcomes = claims::evaluate(&results.scenario, &results.claims, &all);
        h.push_str("<h2>Paper claims</h2>\n");
        h.push_str(&claims_table(&outcomes, false));
    }
    h.push_str(&summary_table(runs));
    h.push_str("<h2>Charts</h2>\n");
    if charts.is_empty() {
        h.push_str("<p class=\"none\">No chart: the runs vary along no sweep axis and carry no phases or quality metrics.</p>\n");
    }
    for c in charts {
        let _ = writeln!(
            h,
            "<figure><a href=\"{svg}\"><img src=\"{png}\" alt=\"{alt}\"></a>\
             <figcaption>{caption} <a href=\"{svg}\">SVG</a></figcaption></figure>",
            svg = attr(&url(&c.svg)),
            png = attr(&url(&c.png)),
            alt = attr(&c.title),
            caption = text(&c.caption),
        );
    }
    h.push_str(&gallery(out, runs));
    h.push_str("</body></html>\n");
    h
}

/// The index of an execution of several scenarios: each scenario's report (`DIR/index.html`,
/// `DIR` relative to the index) with its run counts, and the `outcomes` of every paper claim
/// evaluated over the runs of all of them.
pub fn index_page(
    title: &str,
    reports: &[(String, &ResultsFile)],
    outcomes: &[claims::Outcome],
) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>{t}</title><style>{STYLE}</style></head><body>\n<h1>{t}</h1>\n\
         <h2>Scenarios</h2>\n<table><tr><th>scenario</th><th>runs</th><th>failed</th>\
         <th>claims</th></tr>\n",
        t = text(title)
    );
    for (dir, r) in reports {
        let failed = r.runs.iter().filter(|x| x.failure.is_some()).count();
        let _ = writeln!(
            h,
            "<tr><td class=\"t\"><a href=\"{}\">{}</a></td><td>{}</td><td>{}</td><td>{}</td></tr>",
            attr(&url(&format!("{dir}/index.html"))),
            text(&r.scenario),
            r.runs.len(),
            failed,
            r.claims.len()
        );
    }
    h.push_str("</table>\n<h2>Paper claims</h2>\n");
    if outcomes.is_empty() {
        h.push_str("<p class=\"none\">No scenario states a claim.</p>\n");
    } else {
        h.push_str(&claims_table(outcomes, true));
    }
    h.push_str("</body></html>\n");
    h
}

/// Paper, claim, the paper's figure, ours, and whether the stated expectation holds.
fn claims_table(outcomes: &[claims::Outcome], with_scenario: bool) -> String {
    let mut h = String::from("<table><tr>");
    if with_scenario {
        h.push_str("<th>scenario</th>");
    }
    h.push_str(
        "<th>paper</th><th>claim</th><th>paper's figure</th><th>ours</th><th>verdict</th></tr>\n",
    );
    for o in outcomes {
        let class = match o.holds {
            Some(false) => " class=\"fail\"",
            _ => "",
        };
        let _ = write!(h, "<tr{class}>");
        if with_scenario {
            let _ = write!(h, "<td class=\"t\">{}</td>", text(&o.scenario));
        }
        let _ = writeln!(
            h,
            "<td class=\"t\">{}</td><td class=\"t\">{}</td><td class=\"t\">{}</td>\
             <td class=\"t\">{}</td><td class=\"t\">{}</td></tr>",
            text(&o.claim.paper),
            text(&o.claim.claim),
            text(o.claim.paper_value.as_deref().unwrap_or("–")),
            text(&claims::ours(o)),
            text(&claims::verdict(o)),
        );
    }
    h.push_str("</table>\n");
    h
}

/// A relative URL for a `/`-separated path, each segment percent-encoded.
fn url(path: &str) -> String {
    path.split('/')
        .map(|s| utf8_percent_encode(s, SEGMENT).to_string())
        .collect::<Vec<_>>()
        .join("/")
}

/// Where the runs ran: every key of the runs' `execution` maps with its distinct values.
fn execution_table(runs: &[RunRecord]) -> String {
    let mut keys: BTreeMap<&str, Vec<String>> = BTreeMap::new();
    for r in runs {
        for (k, v) in &r.execution {
            let v = match v {
                serde_json::Value::String(s) => s.clone(),
                other => other.to_string(),
            };
            let vals = keys.entry(k).or_default();
            if !vals.contains(&v) {
                vals.push(v);
            }
        }
    }
    let mut h = String::from("<h2>Execution</h2>\n");
    if keys.is_empty() {
        h.push_str("<p class=\"none\">The runs record no execution details.</p>\n");
        return h;
    }
    h.push_str("<table><tr><th>key</th><th>values</th></tr>\n");
    for (k, vals) in keys {
        let _ = writeln!(
            h,
            "<tr><td class=\"t\">{}</td><td class=\"t\">{}</td></tr>",
            text(k),
            text(&vals.join(", "))
        );
    }
    h.push_str("</table>\n");
    h
}

fn summary_table(runs: &[RunRecord]) -> String {
    let mut h = String::from("<h2>Runs</h2>\n<table><tr>");
    for c in [
        "algorithm",
        "backend",
        "scene",
        "light",
        "triangles",
        "light size",
        "map",
        "tile",
        "image",
        "cores",
        "wall ms",
        "model ms",
        "GPU ms",
        "fill",
        "overdraw / fill",
        "modelled memory bytes",
        "estimated memory bytes",
        "mae_shadow",
        "status",
    ] {
        let _ = write!(h, "<th>{c}</th>");
    }
    h.push_str("</tr>\n");
    let opt = |v: Option<f64>| v.map(fmt_num).unwrap_or_else(|| "–".into());
    for r in runs {
        let p = &r.params;
        let (class, status) = match &r.failure {
            Some(f) => (
                " class=\"fail\"",
                format!("<td class=\"status-fail\">FAILED: {}</td>", text(f)),
            ),
            None if !r.warnings.is_empty() => (
                "",
                format!("<td class=\"t\">ok ({})</td>", text(&r.warnings.join("; "))),
            ),
            None => ("", "<td class=\"t\">ok</td>".into()),
        };
        let _ = write!(h, "<tr{class}>");
        for t in [&r.algorithm, &r.backend, &r.scene, &r.light] {
            let _ = write!(h, "<td class=\"t\">{}</td>", text(t));
        }
        for v in [
            p.triangles.to_string(),
            fmt_num(p.light_size as f64),
            p.map_resolution.to_string(),
            p.tile_size.to_string(),
            format!("{}×{}", p.image[0], p.image[1]),
            opt(p.cores.map(f64::from)),
            fmt_num(r.wall_ms),
            opt(r.model_ms),
            opt(r.gpu_ms),
            opt(r.counters.get("fill")),
            opt(r.counters.get("overdraw_ratio")),
            opt(charts::memory_bytes(r, "mem_model")),
            opt(charts::memory_bytes(r, "mem_est")),
            opt(r.error.as_ref().and_then(|e| e.mae_shadow)),
        ] {
            let _ = write!(h, "<td>{}</td>", text(&v));
        }
        h.push_str(&status);
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    h
}

/// Per scene, one row per run: its visibility buffer, the reference and the error heat map,
/// each only where the file exists.
fn gallery(out: &Path, runs: &[RunRecord]) -> String {
    let mut h = String::from("<h2>Images</h2>\n");
    let mut scenes: Vec<&str> = Vec::new();
    for r in runs {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    if scenes.is_empty() {
        h.push_str("<p class=\"none\">No runs.</p>\n");
    }
    for scene in scenes {
        // Under a textured light, the light received per channel gets its own column.
        let rgb = runs.iter().filter(|r| r.scene == scene).any(|r| {
            out.join(format!("images/{}/visibility_rgb.png", r.case_id()))
                .is_file()
        });
        let _ = writeln!(
            h,
            "<h3>{}</h3>\n<table class=\"gallery\"><tr><th>run</th><th>visibility</th>\
             <th>reference</th><th>error (black 0, yellow ≥ 0.5)</th>{}</tr>",
            text(scene),
            if rgb {
                "<th>light received (rgb)</th>"
            } else {
                ""
            }
        );
        let files: &[&str] = if rgb {
            &[
                "visibility.png",
                "reference.png",
                "error.png",
                "visibility_rgb.png",
            ]
        } else {
            &["visibility.png", "reference.png", "error.png"]
        };
        for r in runs.iter().filter(|r| r.scene == scene) {
            let case = r.case_id();
            let _ = write!(
                h,
                "<tr><td class=\"t\"><b>{}</b><br>{}</td>",
                text(&charts::series_name(r)),
                text(&case)
            );
            for file in files {
                let rel = format!("images/{case}/{file}");
                if out.join(&rel).is_file() {
                    let _ = write!(
                        h,
                        "<td><img src=\"{}\" alt=\"{} {}\"></td>",
                        attr(&url(&rel)),
                        attr(&case),
                        attr(file)
                    );
                } else {
                    h.push_str("<td class=\"none\">–</td>");
                }
            }
            h.push_str("</tr>\n");
        }
        h.push_str("</table>\n");
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::testdata::record;

    /// Every `src="..."` of the page, decoded.
    fn sources(page: &str) -> Vec<String> {
        page.split("src=\"")
            .skip(1)
            .map(|s| {
                let raw = &s[..s.find('"').unwrap()];
                percent_encoding::percent_decode_str(raw)
                    .decode_utf8()
                    .unwrap()
                    .into_owned()
            })
            .collect()
    }

    #[test]
    fn the_gallery_shows_the_light_received_only_where_a_run_wrote_it() {
        let dir = tempfile::tempdir().unwrap();
        let r = record("soft_shadow_volume", "cpu-model", 100, 32);
        let results = ResultsFile {
            scenario: "textured".into(),
            runs: vec![r.clone()],
            claims: vec![],
        };
        let img = dir.path().join("images").join(r.case_id());
        std::fs::create_dir_all(&img).unwrap();
        std::fs::write(img.join("visibility.png"), b"png").unwrap();
        let plain = page(dir.path(), &results, &[]);
        assert!(!plain.contains("light received"), "{plain}");
        std::fs::write(img.join("visibility_rgb.png"), b"png").unwrap();
        let textured = page(dir.path(), &results, &[]);
        assert!(textured.contains("light received (rgb)"), "{textured}");
        let rgb = format!("images/{}/visibility_rgb.png", r.case_id());
        assert!(sources(&textured).contains(&rgb));
    }

    #[test]
    fn page_lists_every_run_and_links_only_existing_images() {
        let dir = tempfile::tempdir().unwrap();
        let ok = record("pcss", "cpu-model", 100, 32);
        let mut bad = record("pcss", "wgpu", 100, 32);
        bad.failure = Some("no <adapter> found".into());
        let img = dir.path().join("images").join(ok.case_id());
        std::fs::create_dir_all(&img).unwrap();
        for f in ["visibility.png", "error.png"] {
            std::fs::write(img.join(f), b"png").unwrap();
        }
        let results = ResultsFile {
            scenario: "ci & more".into(),
            runs: vec![ok.clone(), bad.clone()],
            claims: vec![],
        };
        let charts = [Written {
            png: "charts/a b.png".into(),
            svg: "charts/a b.svg".into(),
            title: "t".into(),
            caption: "c".into(),
        }];
        let page = page(dir.path(), &results, &charts);
        assert!(page.contains("shadowbench: ci &amp; more"));
        assert!(page.contains(&ok.case_id()) && page.contains(&bad.case_id()));
        // The failure is visible, escaped.
        assert!(page.contains("FAILED: no &lt;adapter&gt; found"), "{page}");
        assert!(page.contains("host_threads"));
        let srcs = sources(&page);
        assert!(srcs.contains(&"charts/a b.png".to_string()), "{srcs:?}");
        // Image links are relative and point at files that exist; the missing reference is not
        // linked.
        let images: Vec<&String> = srcs.iter().filter(|s| s.starts_with("images/")).collect();
        assert_eq!(images.len(), 2, "{images:?}");
        for s in images {
            assert!(dir.path().join(s).is_file(), "{s}");
        }
        assert!(!page.contains("src=\"/"));
    }
}
