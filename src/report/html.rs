//! The HTML report: one self-contained page (`index.html`) with where the runs ran, every run in a
//! table (failures included), every chart, and per scene each run's visibility buffer beside the
//! reference and the error heat map. All links are relative, so the folder opens from disk.

use std::fmt::Write as _;
use std::path::Path;

use html_escape::{encode_double_quoted_attribute as attr, encode_text as text};
use percent_encoding::{utf8_percent_encode, AsciiSet, CONTROLS};

use super::charts::{self, Written};
use super::claims::{self, ScenarioRuns};
use super::summary::{self, Summary};
use super::{fmt_num, style};
use crate::backend::Backend;
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
figure{display:block;margin:0 0 2em 0;max-width:1800px}\
figure img{max-width:100%;border:1px solid #ddd}figcaption{font-size:13px;color:#555}\
.gallery td{text-align:center;vertical-align:top;padding:2px}.gallery img{image-rendering:pixelated;width:min(160px,calc((100vw - 16em) / var(--cols,3)));border:1px solid #bbb;\
background:repeating-conic-gradient(#28303a 0% 25%,#343c48 0% 50%) 50%/12px 12px}.gallery th{text-align:center}.gallery td.t{text-align:left;white-space:nowrap}\
details.case{margin:0 0 1em 0}details.case>summary{cursor:pointer;margin:.4em 0}\
.none{color:#999}nav{background:#f7f7f7;border:1px solid #ddd;padding:.5em 1em;max-width:1200px}nav li{margin:.15em 0}\
.sw{display:inline-block;width:.9em;height:.9em;margin-right:.4em;vertical-align:middle;border-radius:2px}\
td.pareto{font-weight:bold}dl{margin:0;text-align:left}dt{font-weight:bold}dd{margin:0 0 .3em 1em;max-width:40em}\
figure img{max-width:100%}td.anim img{image-rendering:pixelated;width:600px;max-width:60vw}";

/// The page for `results`, whose run images are under `out/images/<case_id>/`: a contents
/// list, then the summary at the base point (a table and a quality-vs-cost chart per
/// execution), the paper claims, every other chart, the images and every run.
pub fn page(
    out: &Path,
    results: &ResultsFile,
    charts: &[Written],
    summary: Option<&Summary>,
) -> String {
    let runs = &results.runs;
    let failed = runs.iter().filter(|r| r.failure.is_some()).count();
    let mut h = String::new();
    let title = format!("shadowbench: {}", results.scenario);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n<h1>{}</h1>\n\
         <p>{} runs, {} failed. Data: <a href=\"results.json\">results.json</a>, \
         <a href=\"results.csv\">results.csv</a>{}.</p>\n",
        text(&title),
        text(&title),
        runs.len(),
        failed,
        if summary.is_some() {
            ", <a href=\"summary.csv\">summary.csv</a>, <a href=\"summary.tex\">summary.tex</a> \
             (LaTeX, booktabs)"
        } else {
            ""
        }
    );
    let (summary_charts, other_charts): (Vec<&Written>, Vec<&Written>) = charts
        .iter()
        .partition(|c| c.file.starts_with("quality_vs_cost_"));
    // Contents.
    h.push_str("<nav><b>Contents</b><ol>");
    if summary.is_some() {
        h.push_str("<li><a href=\"#summary\">Summary at the base point</a><ul>");
        for e in summary.iter().flat_map(|s| &s.executions) {
            let _ = write!(
                h,
                "<li><a href=\"#summary-{id}\">{}</a></li>",
                text(e.backend.name()),
                id = attr(e.backend.name())
            );
        }
        h.push_str("</ul></li>");
    }
    if !results.claims.is_empty() {
        h.push_str("<li><a href=\"#claims\">Paper claims</a></li>");
    }
    h.push_str("<li><a href=\"#charts\">Charts</a><ul>");
    // One line per group (against an axis, per phase, per run of a series).
    let mut groups: Vec<(String, Vec<(&str, String)>)> = Vec::new();
    for c in &other_charts {
        let (group, name) = match c.title.split_once(" vs. ") {
            Some((m, axis)) => (format!("against {axis}"), m.to_string()),
            None => match c.title.split_once(", every run of ") {
                Some((t, series)) => (format!("{t}, every run"), series.to_string()),
                None => ("at the base point".to_string(), c.title.clone()),
            },
        };
        match groups.iter_mut().find(|g| g.0 == group) {
            Some(g) => g.1.push((&c.file, name)),
            None => groups.push((group, vec![(&c.file, name)])),
        }
    }
    for (group, links) in groups {
        let links: Vec<String> = links
            .iter()
            .map(|(f, n)| format!("<a href=\"#chart-{}\">{}</a>", attr(f), text(n)))
            .collect();
        let _ = write!(h, "<li>{}: {}</li>", text(&group), links.join(" · "));
    }
    h.push_str("</ul></li><li><a href=\"#images\">Images</a></li>");
    if runs.iter().any(|r| r.animation.is_some()) {
        h.push_str("<li><a href=\"#animation\">Animation</a></li>");
    }
    h.push_str("<li><a href=\"#runs\">Every run</a></li></ol></nav>\n");
    if let Some(s) = summary {
        h.push_str(&summary_section(s, &summary_charts));
    }
    if !results.claims.is_empty() {
        let all = [ScenarioRuns {
            scenario: &results.scenario,
            runs,
        }];
        let outcomes = claims::evaluate(&results.scenario, &results.claims, &all);
        h.push_str("<h2 id=\"claims\">Paper claims</h2>\n");
        h.push_str(&claims_table(&outcomes, false));
    }
    h.push_str("<h2 id=\"charts\">Charts</h2>\n");
    if other_charts.is_empty() {
        h.push_str("<p class=\"none\">No chart: the runs vary along no sweep axis and carry no phases.</p>\n");
    }
    for c in other_charts {
        h.push_str(&figure(c));
    }
    h.push_str(&notes_section(runs));
    h.push_str(&gallery(out, runs));
    h.push_str(&animation_section(out, runs));
    h.push_str(&runs_table(runs));
    h.push_str("</body></html>\n");
    h
}

/// The temporal figures of an animated sweep's runs, per case: flicker against its floor, the
/// worst frame, the trend of the shadow error, and the animated comparison (run | reference |
/// error) of each run.
fn animation_section(out: &Path, runs: &[RunRecord]) -> String {
    let animated: Vec<&RunRecord> = runs.iter().filter(|r| r.animation.is_some()).collect();
    if animated.is_empty() {
        return String::new();
    }
    let mut h = String::from(
        "<h2 id=\"animation\">Animation</h2>\n<p>Each run rendered as a sequence with the \
         light moving (scenario <code>animation</code>). <i>Flicker</i>: the mean over pixels \
         and frames of |(V<sub>t</sub> − V<sub>t−1</sub>) − (R<sub>t</sub> − \
         R<sub>t−1</sub>)|, the change between frames that the reference does not have; its \
         <i>floor</i> is the reference against a reference of another seed (the reference's \
         own sampling noise). <i>Trend</i>: the least-squares slope of mae_shadow per frame. \
         The animation plays run | reference | error side by side; each frame is in \
         <code>frames/</code> of the run's image folder.</p>\n",
    );
    let mut cases: Vec<String> = animated.iter().map(|r| summary::case_key(r)).collect();
    cases.dedup();
    for case in cases {
        let at: Vec<&RunRecord> = animated
            .iter()
            .copied()
            .filter(|r| summary::case_key(r) == case)
            .collect();
        let _ = write!(
            h,
            "<h3>{}</h3>\n<table class=\"summary\"><tr><th>algorithm</th><th>execution</th>\
             <th>frames</th><th>flicker</th><th>floor</th><th>flicker / floor</th>\
             <th>worst frame</th><th>mae_shadow trend per frame</th>\
             <th>run | reference | error</th></tr>\n",
            text(&charts::describe_case(at[0], None))
        );
        let opt = |v: Option<f64>| v.map(fmt_num).unwrap_or_else(|| "–".into());
        for r in at {
            let a = r.animation.as_ref().expect("filtered");
            let rel = format!("images/{}/animation.png", r.case_id());
            let _ = writeln!(
                h,
                "<tr><td class=\"t\"><span class=\"sw\" style=\"background:{}\"></span>{}</td>\
                 <td class=\"t\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
                 <td>{}</td><td class=\"anim\">{}</td></tr>",
                style::hex(style::algorithm_color(&r.algorithm)),
                text(&r.algorithm_label()),
                text(r.backend.name()),
                a.frames,
                opt(a.flicker),
                opt(a.flicker_floor),
                opt(a.flicker.zip(a.flicker_floor).map(|(f, g)| f / g)),
                a.flicker_max_frame
                    .map_or("–".to_string(), |t| t.to_string()),
                opt(a.trend.get("mae_shadow").copied()),
                image_link(out, &rel, "animated comparison").unwrap_or_else(|| "–".into())
            );
        }
        h.push_str("</table>\n");
    }
    h
}

/// The runs' notes (expected remarks, not warnings) once per algorithm and kind.
fn notes_section(runs: &[RunRecord]) -> String {
    let lines = super::notes_by_algorithm(runs);
    if lines.is_empty() {
        return String::new();
    }
    let mut h = String::from(
        "<h2 id=\"notes\">Notes</h2>\n<p>Expected remarks, once per algorithm (each run's own \
         figures are in results.json): a light converted to a kind the method takes, a limit \
         of the method's design that shows in these frames. They are not warnings.</p>\n<ul>",
    );
    for l in lines {
        let _ = write!(
            h,
            "<li><b>{}</b>: {} <span class=\"none\">({} of {} runs)</span></li>",
            text(&l.algorithm),
            text(&l.note),
            l.runs,
            l.of
        );
    }
    h.push_str("</ul>\n");
    h
}

/// A chart with its title, case and caption, anchored as `chart-<file>`.
fn figure(c: &Written) -> String {
    format!(
        "<figure id=\"chart-{id}\"><a href=\"{svg}\"><img src=\"{png}\" alt=\"{alt}\"></a>\
         <figcaption><b>{title}</b> ({case}). {caption} <a href=\"{svg}\">SVG</a></figcaption></figure>\n",
        id = attr(&c.file),
        svg = attr(&url(&c.svg)),
        png = attr(&url(&c.png)),
        alt = attr(&c.title),
        title = text(&c.title),
        case = text(&c.case),
        caption = text(&c.caption),
    )
}

/// The summary: per execution, a table sorted by quality with the Pareto-optimal costs in bold,
/// then that execution's quality-vs-cost chart.
fn summary_section(s: &Summary, charts: &[&Written]) -> String {
    let mut h = format!(
        "<h2 id=\"summary\">Summary at the base point</h2>\n<p>{}. Per execution, every \
         algorithm sorted by its shadow error (best first); a cost in <b>bold ★</b> is on the \
         Pareto front of that cost: no other algorithm on the same execution is cheaper and at \
         least as accurate. Costs of different executions are not compared.</p>\n",
        text(&s.case)
    );
    for e in &s.executions {
        let costs: Vec<usize> = (0..summary::COSTS.len())
            .filter(|&c| e.rows.iter().any(|r| r.costs[c].is_some()))
            .collect();
        let _ = write!(
            h,
            "<h3 id=\"summary-{}\">{}</h3>\n<table class=\"summary\"><tr><th>algorithm</th>\
             <th>mae_shadow</th>",
            attr(e.backend.name()),
            text(e.backend.name())
        );
        if s.has_restricted {
            let _ = write!(h, "<th>{}</th>", summary::RESTRICTED);
        }
        for &q in &s.quality_shown {
            let _ = write!(h, "<th>{}</th>", summary::QUALITY[q]);
        }
        for &c in &costs {
            let _ = write!(h, "<th>{}</th>", text(summary::COSTS[c].metric.label));
        }
        h.push_str("<th>Pareto-optimal on</th></tr>\n");
        let opt = |v: Option<f64>| v.map(fmt_num).unwrap_or_else(|| "–".into());
        for r in &e.rows {
            let _ = write!(
                h,
                "<tr><td class=\"t\"><span class=\"sw\" style=\"background:{}\"></span>{}</td><td>{}</td>",
                style::hex(style::algorithm_color(&r.algorithm)),
                text(&r.label),
                opt(r.mae_shadow)
            );
            if !r.limits.is_empty() {
                let at = h.rfind("</td><td>").expect("the row's first two cells");
                let mark = format!(
                    " <sup title=\"{}\">†</sup>",
                    attr(&format!("method limit: {}", r.limits.join("; ")))
                );
                h.insert_str(at, &mark);
            }
            if s.has_restricted {
                let _ = write!(h, "<td>{}</td>", opt(r.restricted));
            }
            for &q in &s.quality_shown {
                let _ = write!(h, "<td>{}</td>", opt(r.quality[q]));
            }
            for &c in &costs {
                if r.pareto[c] {
                    let _ = write!(h, "<td class=\"pareto\">{} ★</td>", opt(r.costs[c]));
                } else {
                    let _ = write!(h, "<td>{}</td>", opt(r.costs[c]));
                }
            }
            let on = summary::pareto_names(r);
            let _ = writeln!(
                h,
                "<td class=\"t\">{}</td></tr>",
                if on.is_empty() {
                    "–".to_string()
                } else {
                    on.join(", ")
                }
            );
        }
        h.push_str("</table>\n");
        for &c in &costs {
            let ranked = e.measured_ranking(c);
            if ranked.len() < 2 {
                continue;
            }
            let mut line = String::new();
            for (i, r) in ranked.iter().enumerate() {
                if i > 0 {
                    line.push_str(if ranked[i - 1].overlaps_next {
                        " ≈ "
                    } else {
                        " < "
                    });
                }
                let _ = write!(
                    line,
                    "{} {} [{}, {}]",
                    text(&r.label),
                    fmt_num(r.median),
                    fmt_num(r.interval[0]),
                    fmt_num(r.interval[1])
                );
            }
            let _ = writeln!(
                h,
                "<p class=\"t\">{}, fastest first (median [95% interval], ms): {line}. \
                 ≈: the two intervals overlap, so this sweep does not tell them apart.</p>",
                text(summary::COSTS[c].metric.label)
            );
        }
        let limited: Vec<&summary::Row> = e.rows.iter().filter(|r| !r.limits.is_empty()).collect();
        if !limited.is_empty() {
            h.push_str("<p class=\"t\">");
            for r in limited {
                let rank = |q: &dyn Fn(&summary::Row) -> Option<f64>| {
                    let mine = q(r)?;
                    Some(
                        1 + e
                            .rows
                            .iter()
                            .filter(|o| q(o).is_some_and(|v| v < mine))
                            .count(),
                    )
                };
                let _ = write!(
                    h,
                    "† <b>{}</b>: method limit of its paper's design ({}); its mae_shadow counts \
                     pixels it does not compute by design, so compare it on {}{}. ",
                    text(&r.label),
                    text(&r.limits.join("; ")),
                    summary::RESTRICTED,
                    match (rank(&|o| o.mae_shadow), rank(&|o| o.restricted)) {
                        (Some(a), Some(b)) => format!(
                            ": rank {a} of {} on mae_shadow, {b} on {}",
                            e.rows.len(),
                            summary::RESTRICTED
                        ),
                        _ => String::new(),
                    }
                );
            }
            h.push_str("</p>\n");
        }
        if let Some(c) = charts
            .iter()
            .find(|c| c.file == format!("quality_vs_cost_{}", e.backend))
        {
            h.push_str(&figure(c));
        }
    }
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

/// Every run, failures included, with its own execution details.
fn runs_table(runs: &[RunRecord]) -> String {
    let mut h = String::from("<h2 id=\"runs\">Every run</h2>\n<table><tr>");
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
        "wall ms (median ± half its 95% interval)",
        "model ms",
        "GPU ms (median ± half its 95% interval)",
        "fill",
        "overdraw / fill",
        "modelled memory bytes",
        "estimated memory bytes",
        "mae_shadow",
        "status",
        "execution",
        "case id (image folder)",
    ] {
        let _ = write!(h, "<th>{c}</th>");
    }
    h.push_str("</tr>\n");
    let opt = |v: Option<f64>| v.map(fmt_num).unwrap_or_else(|| "–".into());
    for r in runs {
        let p = &r.params;
        // The run's warnings, then its measurement's (a loaded machine, a wide interval).
        let warnings: Vec<&String> = r
            .warnings
            .iter()
            .chain(r.measured.iter().flat_map(|m| &m.warnings))
            .collect();
        let (class, status) = match &r.failure {
            Some(f) => (
                " class=\"fail\"",
                format!("<td class=\"status-fail\">FAILED: {}</td>", text(f)),
            ),
            None if !warnings.is_empty() => (
                "",
                format!(
                    "<td class=\"t\">ok ({})</td>",
                    text(
                        &warnings
                            .iter()
                            .map(|w| w.as_str())
                            .collect::<Vec<_>>()
                            .join("; ")
                    )
                ),
            ),
            None => ("", "<td class=\"t\">ok</td>".into()),
        };
        // A measured median with half its 95% interval.
        let timed = |median: Option<f64>, s: Option<&crate::harness::measure::Spread>| match (
            median,
            s.filter(|s| s.samples.len() > 1),
        ) {
            (Some(m), Some(s)) => {
                format!("{} ± {}", fmt_num(m), fmt_num((s.ci[1] - s.ci[0]) / 2.0))
            }
            (m, _) => opt(m),
        };
        let measured = r.measured.as_ref();
        let _ = write!(h, "<tr{class}>");
        for t in [r.algorithm.as_str(), r.backend.name(), &r.scene, &r.light] {
            let _ = write!(h, "<td class=\"t\">{}</td>", text(t));
        }
        for v in [
            p.triangles.to_string(),
            fmt_num(p.light_size as f64),
            p.map_resolution.to_string(),
            p.tile_size.to_string(),
            format!("{}×{}", p.image[0], p.image[1]),
            opt(p.cores.map(f64::from)),
            timed(Some(r.wall_ms), measured.map(|m| &m.wall_ms)),
            opt(r.model_ms),
            timed(r.gpu_ms, measured.and_then(|m| m.gpu_ms.as_ref())),
            opt(r.counters.get("fill")),
            opt(r.counters.get("overdraw_ratio")),
            opt(charts::memory_bytes(r, "mem_model")),
            opt(charts::memory_bytes(r, "mem_est")),
            opt(r.error.as_ref().and_then(|e| e.mae_shadow)),
        ] {
            let _ = write!(h, "<td>{}</td>", text(&v));
        }
        h.push_str(&status);
        h.push_str(&execution_cell(r));
        let case = r.case_id();
        let _ = writeln!(
            h,
            "<td class=\"t\"><a href=\"{}\">{}</a></td></tr>",
            attr(&url(&format!("images/{case}/"))),
            text(&case)
        );
    }
    h.push_str("</table>\n");
    h
}

/// Where one run ran (its `execution` map), folded.
fn execution_cell(r: &RunRecord) -> String {
    if r.execution.is_empty() {
        return "<td class=\"none\">–</td>".into();
    }
    let mut h = format!(
        "<td class=\"t\"><details><summary>{} entries</summary><dl>",
        r.execution.len()
    );
    for (k, v) in &r.execution {
        let v = match v {
            serde_json::Value::String(s) => s.clone(),
            other => other.to_string(),
        };
        let _ = write!(h, "<dt>{}</dt><dd>{}</dd>", text(k), text(&v));
    }
    h.push_str("</dl></details></td>");
    h
}

/// Per case (scene and parameters), one grid: the reference once, then a row per algorithm and
/// per execution its shaded view, its visibility (background transparent) and its error heat
/// map, each only where the file exists. The base point's grid comes first and open; the others
/// are folded.
fn gallery(out: &Path, runs: &[RunRecord]) -> String {
    let mut h = String::from(
        "<h2 id=\"images\">Images</h2>\n<p>Per case, every algorithm × execution: the \
         <i>shaded</i> view (visibility × a Lambertian term, so occluders stand out), the \
         <i>visibility</i> (black: no light, white: fully lit; pixels that see no surface are \
         transparent, in <code>mask.npy</code> they are 0) and the <i>error</i> against the \
         reference (black 0, red, yellow ≥ 0.5; background blue-grey), and where there is one \
         the <i>ꟻLIP error</i> of the shaded view against the reference's, what a viewer notices \
         at the scenario's viewing distance (ꟻLIP's magma colours: black none, purple, orange, \
         pale yellow 1). The difference of any two runs: \
         <code>shadowbench diff images/A images/B</code>.</p>\n",
    );
    let ok: Vec<&RunRecord> = runs.iter().collect();
    let base = summary::base_case(&ok).map(|b| b.0);
    let cases = gallery_cases(runs, base.as_deref());
    if cases.is_empty() {
        h.push_str("<p class=\"none\">No runs.</p>\n");
    }
    for (ci, key) in cases.iter().enumerate() {
        let mut at: Vec<&RunRecord> = runs
            .iter()
            .filter(|r| summary::case_key(r) == *key)
            .collect();
        at.sort_by_key(|r| (style::algorithm_rank(&r.algorithm), r.backend));
        let is_base = base.as_ref() == Some(key);
        let _ = writeln!(
            h,
            "<details class=\"case\" id=\"case-{ci}\"{}><summary><b>{}{}</b></summary>",
            if is_base { " open" } else { "" },
            if is_base { "base point: " } else { "" },
            text(&charts::describe_case(at[0], None))
        );
        h.push_str(&reference_grid(out, &at));
        h.push_str(&case_grid(out, &at));
        h.push_str("</details>\n");
    }
    h
}

/// The case keys of `runs` in order of first appearance, the `base` case first.
fn gallery_cases(runs: &[RunRecord], base: Option<&str>) -> Vec<String> {
    let mut cases: Vec<String> = Vec::new();
    for r in runs {
        let k = summary::case_key(r);
        if !cases.contains(&k) {
            cases.push(k);
        }
    }
    if let Some(i) = base.and_then(|b| cases.iter().position(|k| k == b)) {
        let k = cases.remove(i);
        cases.insert(0, k);
    }
    cases
}

/// A linked thumbnail of the image `rel` (relative to `out`), if the file exists.
fn image_link(out: &Path, rel: &str, alt: &str) -> Option<String> {
    out.join(rel).is_file().then(|| {
        format!(
            "<a href=\"{u}\"><img src=\"{u}\" alt=\"{}\" title=\"{}\"></a>",
            attr(alt),
            attr(rel),
            u = attr(&url(rel))
        )
    })
}

/// The reference of one case's runs `at`, once: from the reference run, or the reference copy
/// of any run; empty if there is none.
fn reference_grid(out: &Path, at: &[&RunRecord]) -> String {
    let pair = |r: &RunRecord, shaded: &str, vis: &str| {
        let d = format!("images/{}", r.case_id());
        Some((
            image_link(out, &format!("{d}/{shaded}"), "reference shaded"),
            image_link(out, &format!("{d}/{vis}"), "reference")?,
        ))
    };
    let reference = at
        .iter()
        .find(|r| r.algorithm == crate::algorithms::reference::ID)
        .and_then(|r| pair(r, "shaded.png", "visibility.png"))
        .or_else(|| {
            at.iter()
                .find_map(|r| pair(r, "reference_shaded.png", "reference.png"))
        });
    let Some((shaded, vis)) = reference else {
        return String::new();
    };
    format!(
        "<table class=\"gallery\"><tr><th>reference</th><th>shaded</th><th>visibility</th></tr>\
         <tr><td class=\"t\"><span class=\"sw\" style=\"background:{}\"></span>reference</td>\
         <td>{}</td><td>{}</td></tr></table>\n",
        style::hex(style::REFERENCE),
        shaded.unwrap_or_else(|| "–".into()),
        vis
    )
}

/// One case's grid of runs `at` (sorted by algorithm, then execution): a row per algorithm, per
/// execution a column per image kind. Executions whose images are byte-identical for every
/// algorithm (cpu-native and cpu-model run the same kernels) share one set of columns, headed
/// by both names. The thumbnails shrink to fit the page's width (`--cols`: the image columns).
fn case_grid(out: &Path, at: &[&RunRecord]) -> String {
    let mut backends: Vec<Backend> = at.iter().map(|r| r.backend).collect();
    backends.sort();
    backends.dedup();
    let mut algs: Vec<&str> = at.iter().map(|r| r.algorithm.as_str()).collect();
    algs.dedup();
    algs.retain(|a| *a != crate::algorithms::reference::ID);
    let mut files = vec![
        ("shaded.png", "shaded"),
        ("visibility.png", "visibility"),
        ("error.png", "error"),
    ];
    if at.iter().any(|r| {
        out.join(format!("images/{}/flip.png", r.case_id()))
            .is_file()
    }) {
        files.push(("flip.png", "ꟻLIP error"));
    }
    if at.iter().any(|r| {
        out.join(format!("images/{}/visibility_rgb.png", r.case_id()))
            .is_file()
    }) {
        files.push(("visibility_rgb.png", "light received (rgb)"));
    }
    let run = |alg: &str, b: Backend| {
        at.iter()
            .find(|r| r.algorithm == alg && r.backend == b)
            .copied()
    };
    // The bytes of every image of `b`'s runs, in row order; `None` where one is missing.
    let images = |b: Backend| -> Option<Vec<Vec<u8>>> {
        let mut all = Vec::new();
        for alg in &algs {
            let r = run(alg, b).filter(|r| r.failure.is_none())?;
            for (f, _) in &files {
                all.push(std::fs::read(out.join(format!("images/{}/{f}", r.case_id()))).ok()?);
            }
        }
        Some(all)
    };
    // Executions that share columns, with the image bytes they share.
    type Group = (Vec<Backend>, Option<Vec<Vec<u8>>>);
    let mut groups: Vec<Group> = Vec::new();
    for &b in &backends {
        let mine = images(b);
        match groups
            .iter_mut()
            .find(|(_, theirs)| mine.is_some() && *theirs == mine)
        {
            Some(g) => g.0.push(b),
            None => groups.push((vec![b], mine)),
        }
    }
    let mut h = format!(
        "<table class=\"gallery\" style=\"--cols:{}\"><tr><th rowspan=\"2\">algorithm</th>",
        groups.len() * files.len()
    );
    for (names, _) in &groups {
        let head = match names.as_slice() {
            [one] => text(one.name()).into_owned(),
            many => format!(
                "{} <span class=\"none\">(identical images)</span>",
                text(
                    &many
                        .iter()
                        .map(|b| b.name())
                        .collect::<Vec<_>>()
                        .join(" = ")
                )
            ),
        };
        let _ = write!(h, "<th colspan=\"{}\">{head}</th>", files.len());
    }
    h.push_str("</tr><tr>");
    for _ in &groups {
        for (_, label) in &files {
            let _ = write!(h, "<th>{}</th>", text(label));
        }
    }
    h.push_str("</tr>\n");
    for alg in &algs {
        let _ = write!(
            h,
            "<tr><td class=\"t\"><span class=\"sw\" style=\"background:{}\"></span>{}</td>",
            style::hex(style::algorithm_color(alg)),
            text(alg)
        );
        for (names, _) in &groups {
            h.push_str(&gallery_cells(out, run(alg, names[0]), &files));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>");
    h
}

/// The cells of one algorithm on one execution: its images (`files`: name and label), its
/// failure, or "no such execution" when it did not run.
fn gallery_cells(out: &Path, run: Option<&RunRecord>, files: &[(&str, &str)]) -> String {
    let Some(r) = run else {
        return format!(
            "<td colspan=\"{}\" class=\"none\">no such execution</td>",
            files.len()
        );
    };
    if let Some(failure) = &r.failure {
        return format!(
            "<td colspan=\"{}\" class=\"status-fail\">FAILED: {}</td>",
            files.len(),
            text(failure)
        );
    }
    let mut h = String::new();
    for (f, label) in files {
        let rel = format!("images/{}/{f}", r.case_id());
        let alt = format!("{} on {}: {label}", r.algorithm_label(), r.backend);
        match image_link(out, &rel, &alt) {
            Some(i) => {
                let _ = write!(h, "<td>{i}</td>");
            }
            None => h.push_str("<td class=\"none\">–</td>"),
        }
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
        let r = record("soft_shadow_volume", Backend::CpuModel, 100, 32);
        let results = ResultsFile {
            origin: None,
            scenario: "textured".into(),
            runs: vec![r.clone()],
            claims: vec![],
            ..Default::default()
        };
        let img = dir.path().join("images").join(r.case_id());
        std::fs::create_dir_all(&img).unwrap();
        std::fs::write(img.join("visibility.png"), b"png").unwrap();
        let plain = page(dir.path(), &results, &[], None);
        assert!(!plain.contains("light received"), "{plain}");
        std::fs::write(img.join("visibility_rgb.png"), b"png").unwrap();
        let textured = page(dir.path(), &results, &[], None);
        assert!(textured.contains("light received (rgb)"), "{textured}");
        let rgb = format!("images/{}/visibility_rgb.png", r.case_id());
        assert!(sources(&textured).contains(&rgb));
    }

    #[test]
    fn executions_with_identical_images_share_columns_and_others_keep_their_own() {
        let dir = tempfile::tempdir().unwrap();
        let runs: Vec<RunRecord> = Backend::ALL
            .into_iter()
            .map(|b| record("pcss", b, 100, 32))
            .collect();
        for r in &runs {
            let img = dir.path().join("images").join(r.case_id());
            std::fs::create_dir_all(&img).unwrap();
            // The CPU executions wrote the same bytes; wgpu's differ.
            let bytes: &[u8] = if r.backend == Backend::Wgpu {
                b"gpu"
            } else {
                b"cpu"
            };
            for f in ["shaded.png", "visibility.png", "error.png"] {
                std::fs::write(img.join(f), bytes).unwrap();
            }
        }
        let at: Vec<&RunRecord> = runs.iter().collect();
        let grid = case_grid(dir.path(), &at);
        assert!(
            grid.contains("cpu-native = cpu-model <span class=\"none\">(identical images)"),
            "{grid}"
        );
        assert!(grid.contains("<th colspan=\"3\">wgpu</th>"), "{grid}");
        assert!(grid.contains("--cols:6"), "{grid}");
        // One cell set per group: 6 images, not 9.
        assert_eq!(grid.matches("<img ").count(), 6, "{grid}");
        // One differing image splits them again.
        let native = dir.path().join("images").join(runs[0].case_id());
        std::fs::write(native.join("error.png"), b"other").unwrap();
        let grid = case_grid(dir.path(), &at);
        assert!(!grid.contains("identical images"), "{grid}");
        assert_eq!(grid.matches("<img ").count(), 9, "{grid}");
    }

    #[test]
    fn page_lists_every_run_and_links_only_existing_images() {
        let dir = tempfile::tempdir().unwrap();
        let ok = record("pcss", Backend::CpuModel, 100, 32);
        let mut bad = record("pcss", Backend::Wgpu, 100, 32);
        bad.failure = Some("no <adapter> found".into());
        let img = dir.path().join("images").join(ok.case_id());
        std::fs::create_dir_all(&img).unwrap();
        for f in ["visibility.png", "error.png"] {
            std::fs::write(img.join(f), b"png").unwrap();
        }
        let results = ResultsFile {
            origin: None,
            scenario: "ci & more".into(),
            runs: vec![ok.clone(), bad.clone()],
            claims: vec![],
            ..Default::default()
        };
        let charts = [Written {
            file: "a b".into(),
            case: "case".into(),
            png: "charts/a b.png".into(),
            svg: "charts/a b.svg".into(),
            title: "t".into(),
            caption: "c".into(),
        }];
        let page = page(dir.path(), &results, &charts, None);
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
