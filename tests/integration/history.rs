//! `shadowbench history`: a synthetic history recorded from a real run (the committed CI
//! baseline, reports/baseline/results.json) with measured noise, one stepped figure, two
//! recorders at once, files that are not a history, the dashboard formats' shapes, and the
//! trend page.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;
use shadowbench::history::check;
use shadowbench::history::detect::Verdict;
use shadowbench::history::store::Store;
use shadowbench::util::hash::{mix64, unit_f32};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_shadowbench"))
}

fn baseline() -> Value {
    let text = std::fs::read_to_string("reports/baseline/results.json").unwrap();
    serde_json::from_str(&text).unwrap()
}

/// A standard normal number from a counter-based stream (Box–Muller).
fn normal(seed: u64, i: u64) -> f64 {
    let a = unit_f32(mix64(seed ^ mix64(2 * i))) as f64 + 1e-7;
    let b = unit_f32(mix64(seed ^ mix64(2 * i + 1))) as f64;
    (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
}

/// Multiplies every measured time (`*_ms` but `model_ms`) of `v` by 1 + `sigma` × N(0, 1).
fn jitter(v: &mut Value, seed: u64, sigma: f64, counter: &mut u64) {
    if let Value::Object(m) = v {
        for (k, x) in m.iter_mut() {
            if k.ends_with("_ms") && k != "model_ms" {
                if let Some(f) = x.as_f64() {
                    *counter += 1;
                    *x = Value::from(f * (1.0 + sigma * normal(seed, *counter)));
                }
            } else if k == "phases" {
                for p in x.as_array_mut().unwrap() {
                    jitter(p, seed, sigma, counter);
                }
            }
        }
    }
}

/// The commit id of synthetic commit `k`.
fn sha(tag: &str, k: usize) -> String {
    let mut h = shadowbench::util::hash::Fnv64::default();
    h.bytes(tag.as_bytes()).u64(k as u64);
    format!("{:016x}{:016x}", h.finish(), mix64(h.finish()))
}

/// Writes commit `k` of a history: the baseline's runs with measured noise (3%), and the
/// `model_ms` of one pcss cpu-model run (1964 triangles) times `factor` from commit 20 on.
fn commit_file(dir: &Path, tag: &str, k: usize, factor: f64) -> PathBuf {
    let mut data = baseline();
    let mut counter = 0;
    let mut stepped = 0;
    for r in data["runs"].as_array_mut().unwrap() {
        jitter(r, k as u64, 0.03, &mut counter);
        if k >= 20
            && r["algorithm"] == "pcss"
            && r["backend"] == "cpu-model"
            && r["params"]["triangles"] == 1964
        {
            let m = r["model_ms"].as_f64().unwrap();
            r["model_ms"] = Value::from(m * factor);
            stepped += 1;
        }
    }
    assert!(k < 20 || stepped == 1);
    let path = dir.join(format!("{tag}-{k}.json"));
    std::fs::write(&path, serde_json::to_string(&data).unwrap()).unwrap();
    path
}

fn record(db: &Path, file: &Path, tag: &str, k: usize) -> Output {
    bin()
        .args(["history", "record"])
        .arg(file)
        .arg("--db")
        .arg(db)
        .args([
            "--commit",
            &sha(tag, k),
            "--branch",
            "main",
            "--machine",
            "ci",
        ])
        .args(["--date", &format!("2026-01-01T00:00:{k:02}Z")])
        .args(["--subject", &format!("commit {k}")])
        .output()
        .unwrap()
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A 30-commit history in `dir/<tag>.sqlite`.
fn history(dir: &Path, tag: &str, factor: f64) -> PathBuf {
    let db = dir.join(format!("{tag}.sqlite"));
    for k in 1..=30 {
        ok(&record(&db, &commit_file(dir, tag, k, factor), tag, k));
    }
    db
}

fn check_cli(db: &Path, extra: &[&str]) -> Output {
    bin()
        .args(["history", "check", "--db"])
        .arg(db)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn a_five_percent_step_at_commit_20_is_the_one_change_reported_and_an_improvement_exits_0() {
    let dir = tempfile::tempdir().unwrap();
    let db = history(dir.path(), "up", 1.05);
    let h = Store::open(&db, false).unwrap().load().unwrap();
    assert_eq!(h.commits.len(), 30);
    let c = check::check(&h, 0, 29, &[]);
    assert!(c.series_checked > 1000, "{}", c.series_checked);
    assert_eq!(
        c.changes.len(),
        1,
        "{:#?}",
        c.changes
            .iter()
            .map(|x| (&x.series.case_id, &x.series.figure))
            .collect::<Vec<_>>()
    );
    let x = &c.changes[0];
    assert_eq!(x.change.verdict, Verdict::Regression);
    assert_eq!(x.series.figure, "model_ms");
    assert!(
        x.series.case_id.contains("_pcss_cpu-model_t1964_"),
        "{}",
        x.series.case_id
    );
    assert_eq!(
        x.step_commits(),
        [19],
        "the first stepped commit is commit 20"
    );
    assert!((x.change.effect - 0.05).abs() < 1e-9, "{}", x.change.effect);

    let o = check_cli(&db, &["--since", &sha("up", 1)]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("REGRESSION") && out.contains("+5.00%"),
        "{out}"
    );
    assert!(out.contains(&sha("up", 20)[..10]), "{out}");
    assert!(out.contains("1 regressions, 0 improvements"), "{out}");
    // By default against the commit before the newest on main: nothing moved there.
    let o = check_cli(&db, &[]);
    assert_eq!(o.status.code(), Some(0));
    // The commit of the step itself against the one before it.
    let o = check_cli(&db, &["--commit", &sha("up", 20)]);
    assert_eq!(o.status.code(), Some(1));

    let db = history(dir.path(), "down", 0.95);
    let o = check_cli(&db, &["--since", &sha("down", 1)]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{out}");
    assert!(
        out.contains("improvement") && out.contains("-5.00%"),
        "{out}"
    );
    assert!(out.contains("0 regressions, 1 improvements"), "{out}");
    let md = check_cli(&db, &["--since", &sha("down", 1), "--format", "markdown"]);
    let md = String::from_utf8_lossy(&md.stdout);
    assert!(
        md.contains("| improvement |") && md.contains("`model_ms`"),
        "{md}"
    );
}

#[test]
fn two_recorders_at_once_lose_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("shared.sqlite");
    let files: Vec<(PathBuf, PathBuf)> = (1..=8)
        .map(|k| {
            (
                commit_file(dir.path(), "a", k, 1.0),
                commit_file(dir.path(), "b", k, 1.0),
            )
        })
        .collect();
    for (k, (a, b)) in files.iter().enumerate() {
        // Both processes start together, the first pair on a database not made yet.
        let spawn = |file: &Path, tag: &str| {
            bin()
                .args(["history", "record"])
                .arg(file)
                .arg("--db")
                .arg(&db)
                .args(["--commit", &sha(tag, k), "--branch", "main"])
                .args(["--machine", tag])
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (pa, pb) = (spawn(a, "a"), spawn(b, "b"));
        for p in [pa, pb] {
            let o = p.wait_with_output().unwrap();
            assert!(
                o.status.success(),
                "recorder {k}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
    let h = Store::open(&db, false).unwrap().load().unwrap();
    assert_eq!(h.commits.len(), 16);
    // Two hosts, each with a cpu-native and a cpu-model machine.
    assert_eq!(h.machines.len(), 4);
    let a = h
        .series
        .iter()
        .filter(|s| h.machines[&s.machine].contains("\"name\":\"a\""))
        .count();
    assert_eq!(2 * a, h.series.len());
    assert!(a > 1000);
    for s in &h.series {
        assert_eq!(s.points.len(), 8, "{} {}", s.case_id, s.figure);
    }
}

#[test]
fn recording_the_same_results_again_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("h.sqlite");
    let f = commit_file(dir.path(), "x", 1, 1.0);
    ok(&record(&db, &f, "x", 1));
    let before = Store::open(&db, false).unwrap().load().unwrap();
    let o = record(&db, &f, "x", 1);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("already recorded"));
    let after = Store::open(&db, false).unwrap().load().unwrap();
    assert_eq!(before.series, after.series);
    assert_eq!(before.commits, after.commits);
}

#[test]
fn a_file_that_is_not_a_history_is_exit_2_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let results = Path::new("reports/baseline/results.json");
    for cmd in [&["check"][..], &["report", "--out"][..]] {
        let mut c = bin();
        c.arg("history").args(cmd);
        if cmd.len() > 1 {
            c.arg(dir.path().join("page"));
        }
        let o = c.arg("--db").arg(results).output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{cmd:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("reports/baseline/results.json")
                && err.contains("not a shadowbench history"),
            "{err}"
        );
    }
    let o = bin()
        .args(["history", "record"])
        .arg(results)
        .arg("--db")
        .arg(results)
        .args(["--commit", "abcd1234"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let missing = dir.path().join("none.sqlite");
    let o = check_cli(&missing, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("none.sqlite"));
    assert!(!missing.exists());
}

/// Checks that `v` is Bencher Metric Format: an object of benchmarks, each an object of
/// measures, each `{ value, lower_value?, upper_value? }` with numbers (and lower ≤ value ≤
/// upper where given).
fn assert_bmf(v: &Value) -> usize {
    let mut n = 0;
    for (bench, measures) in v.as_object().expect("BMF is a JSON object") {
        assert!(!bench.is_empty());
        for (measure, m) in measures
            .as_object()
            .expect("a benchmark is an object of measures")
        {
            let m = m.as_object().unwrap();
            assert!(!measure.is_empty());
            for k in m.keys() {
                assert!(
                    ["value", "lower_value", "upper_value"].contains(&k.as_str()),
                    "{k}"
                );
            }
            let value = m["value"].as_f64().expect("value is a number");
            if let Some(lo) = m.get("lower_value") {
                assert!(lo.as_f64().unwrap() <= value);
            }
            if let Some(hi) = m.get("upper_value") {
                assert!(hi.as_f64().unwrap() >= value);
            }
            n += 1;
        }
    }
    n
}

/// Checks that `v` is github-action-benchmark's custom JSON: an array of
/// `{ name, unit, value, range?, extra? }`, names unique.
fn assert_gab(v: &Value) -> Vec<String> {
    let mut names = Vec::new();
    for e in v.as_array().expect("an array") {
        let e = e.as_object().unwrap();
        for k in e.keys() {
            assert!(
                ["name", "unit", "value", "range", "extra"].contains(&k.as_str()),
                "{k}"
            );
        }
        names.push(e["name"].as_str().unwrap().to_string());
        assert!(e["unit"].is_string());
        assert!(e["value"].is_number());
        for k in ["range", "extra"] {
            assert!(e.get(k).is_none_or(Value::is_string));
        }
    }
    let mut unique = names.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), names.len());
    names
}

#[test]
fn dashboard_formats_have_their_shapes_and_the_summary_is_empty_when_nothing_moved() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("h.sqlite");
    for k in 1..=3 {
        ok(&record(&db, &commit_file(dir.path(), "f", k, 1.0), "f", k));
    }
    let o = check_cli(&db, &["--format", "markdown"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );

    let o = check_cli(&db, &["--format", "bmf"]);
    assert_eq!(o.status.code(), Some(0));
    let bmf: Value = serde_json::from_slice(&o.stdout).unwrap();
    let runs = baseline()["runs"].as_array().unwrap().len();
    assert!(assert_bmf(&bmf) >= 2 * runs);
    let pcss = bmf
        .as_object()
        .unwrap()
        .iter()
        .find(|(k, _)| k.contains("_pcss_cpu-model_"))
        .unwrap()
        .1;
    assert!(pcss["model_ms"]["value"].as_f64().unwrap() > 0.0);
    let o = check_cli(&db, &["--format", "bmf", "--all-figures"]);
    assert!(assert_bmf(&serde_json::from_slice(&o.stdout).unwrap()) > 20 * runs);

    let out = dir.path().join("gab");
    let o = check_cli(&db, &["--format", "github-action-benchmark", "--output"]);
    assert_eq!(o.status.code(), Some(2), "a value is required");
    let o = bin()
        .args(["history", "check", "--db"])
        .arg(&db)
        .args([
            "--format",
            "github-action-benchmark",
            "--all-figures",
            "--output",
        ])
        .arg(&out)
        .output()
        .unwrap();
    ok(&o);
    let read = |n: &str| -> Value {
        serde_json::from_str(&std::fs::read_to_string(out.join(n)).unwrap()).unwrap()
    };
    let smaller = assert_gab(&read("customSmallerIsBetter.json"));
    let bigger = assert_gab(&read("customBiggerIsBetter.json"));
    assert!(smaller.iter().any(|n| n.ends_with("/model_ms")));
    assert!(bigger
        .iter()
        .any(|n| n.ends_with("/counters.simd_utilization")));
    assert!(!smaller.iter().any(|n| n.ends_with("simd_utilization")));
}

#[test]
fn the_trend_page_charts_the_step_first() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("h.sqlite");
    for k in [1, 2, 19, 20, 21] {
        ok(&record(&db, &commit_file(dir.path(), "p", k, 1.1), "p", k));
    }
    let out = dir.path().join("page");
    let o = bin()
        .args(["history", "report", "--db"])
        .arg(&db)
        .arg("--out")
        .arg(&out)
        .args(["--since", &sha("p", 1)])
        .args(["--commit-url", "https://example.org/c/{sha}"])
        .output()
        .unwrap();
    ok(&o);
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    let steps = html.find("id=\"steps\"").unwrap();
    let trends = html.find("id=\"trends\"").unwrap();
    let first_svg = html.find("<svg").unwrap();
    assert!(steps < first_svg && first_svg < trends);
    assert!(html[steps..trends].contains("regression"));
    assert!(html.contains(&format!("https://example.org/c/{}", sha("p", 20))));
    assert!(!html.contains("<img"), "self-contained: charts are inline");
}
