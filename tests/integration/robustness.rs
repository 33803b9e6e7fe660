//! Hostile inputs, concurrent runs and runaway costs (docs/robustness.md): every path derived
//! from user text stays inside `--out`; oversized machines and sweeps are refused with their
//! estimate; two commands cannot share an output folder; `report` cannot be made to loop; a run
//! past its time budget is stopped and the sweep goes on; and the smaller faults of the list.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};

use super::common::{shadowbench, stderr};

/// The `error:` line of a failed command; there must be exactly one.
fn error_line(o: &Output) -> String {
    let e = stderr(o);
    let lines: Vec<&str> = e.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(lines.len(), 1, "{e}");
    lines[0].to_string()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A cheap scenario: the reference on cpu-native of a tiny image.
fn tiny(name: Option<&str>) -> Value {
    let mut v = json!({
        "scene": { "generator": "box-on-plane" },
        "algorithms": ["hard_shadow_map"],
        "backends": ["cpu-native"],
        "params": { "image": [16, 12], "map_resolution": 32 },
        "reference": { "samples": 4 }
    });
    if let Some(n) = name {
        v["name"] = json!(n);
    }
    v
}

fn write(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

/// Every file and folder under `dir`, recursively.
fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if e.file_type().unwrap().is_dir() {
            out.extend(tree(&p));
        }
        out.push(p);
    }
    out
}

fn results(out: &Path) -> Vec<Value> {
    let v: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    v["runs"].as_array().unwrap().clone()
}

// 1. Paths from user text.

#[test]
fn a_scenario_name_that_is_a_path_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("a").join("b");
    std::fs::create_dir_all(&root).unwrap();
    for name in ["../../../x", "/some/other/dir", "..", "a/b"] {
        let scenario = root.join("s.json");
        write(&scenario, &tiny(Some(name)));
        let other = root.join("t.json");
        write(&other, &tiny(Some("t")));
        let out = root.join("out");
        let o = shadowbench(&["run", s(&scenario), s(&other), "--out", s(&out)]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        let e = error_line(&o);
        assert!(
            e.contains("s.json") && e.contains("$.name") && e.contains(&format!("{name:?}")),
            "{e}"
        );
        assert!(!out.exists(), "{name}: nothing is written");
    }
    let mut left = tree(dir.path());
    left.sort();
    assert_eq!(
        left,
        vec![
            dir.path().join("a"),
            root.clone(),
            root.join("s.json"),
            root.join("t.json")
        ]
    );
}

#[test]
fn names_that_are_not_file_names_become_folders_inside_out() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.json");
    let b = dir.path().join("b.json");
    write(&a, &tiny(Some("Paper 002: fig. 7")));
    write(&b, &tiny(Some("plain")));
    let out = dir.path().join("out");
    let o = shadowbench(&["run", s(&a), s(&b), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let folders: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|e| e.file_type().unwrap().is_dir())
        .map(|e| e.file_name().into_string().unwrap())
        .collect();
    let slug = shadowbench::util::paths::slug("Paper 002: fig. 7");
    assert!(slug.starts_with("Paper_002__fig._7-"), "{slug}");
    for f in [slug.as_str(), "plain"] {
        assert!(folders.iter().any(|d| d == f), "{f}: {folders:?}");
        assert!(out.join(f).join("results.json").is_file());
    }
    // Nothing beside the inputs and `out`.
    for p in std::fs::read_dir(dir.path()).unwrap().flatten() {
        assert!(
            [a.clone(), b.clone(), out.clone()].contains(&p.path()),
            "{}",
            p.path().display()
        );
    }
}

/// A results file as `run` writes it, from a tiny real run.
fn real_results(dir: &Path) -> Value {
    let scenario = dir.join("seed.json");
    write(&scenario, &tiny(Some("seed")));
    let out = dir.join("seed-out");
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap()
}

#[test]
fn report_keeps_a_results_files_names_inside_out() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("a").join("b");
    std::fs::create_dir_all(&root).unwrap();
    let good = real_results(dir.path());
    // A scenario name that is a path: refused, naming the file, the field and the value.
    for name in ["../../../x", "/some/other/dir"] {
        let mut bad = good.clone();
        bad["scenario"] = json!(name);
        let file = root.join("results.json");
        write(&file, &bad);
        let out = root.join("out");
        let o = shadowbench(&["report", s(&file), "--out", s(&out)]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        let e = error_line(&o);
        assert!(
            e.contains("results.json") && e.contains("$.scenario"),
            "{e}"
        );
        assert!(e.contains(&format!("{name:?}")), "{e}");
        assert!(!out.exists());
    }
    // Run fields that are paths (scene, algorithm, backend) name image folders as slugs.
    let mut bad = good.clone();
    bad["runs"][0]["scene"] = json!("../../../escape");
    bad["runs"][0]["algorithm"] = json!("/abs/olute");
    let (f1, f2) = (root.join("one.json"), root.join("two.json"));
    write(&f1, &bad);
    let mut other = bad.clone();
    other["scenario"] = json!("other");
    write(&f2, &other);
    let out = root.join("out");
    let o = shadowbench(&["report", s(&f1), s(&f2), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    for p in tree(dir.path()) {
        assert!(
            p.starts_with(&out)
                || p.starts_with(dir.path().join("seed-out"))
                || [
                    dir.path().join("a"),
                    root.clone(),
                    root.join("results.json"),
                    f1.clone(),
                    f2.clone(),
                    dir.path().join("seed.json"),
                    dir.path().join("seed-out")
                ]
                .contains(&p),
            "written outside --out: {}",
            p.display()
        );
    }
}

// 3. and 4. Allocations and planning proportional to user-given sizes.

#[test]
fn a_machine_whose_modelled_caches_exceed_memory_is_refused_with_the_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = serde_json::to_value(shadowbench::model::MachineConfig::larrabee(1024)).unwrap();
    m["name"] = json!("huge");
    m["l2"]["size_bytes"] = json!(2u64 << 30);
    std::fs::write(dir.path().join("huge.json"), m.to_string()).unwrap();
    let mut v = tiny(None);
    v["machine"] = json!("huge.json");
    v["backends"] = json!(["cpu-model", "cpu-native"]);
    let scenario = dir.path().join("s.json");
    write(&scenario, &v);
    let out = dir.path().join("out");
    let o = shadowbench(&[
        "run",
        s(&scenario),
        "--out",
        s(&out),
        "--memory-limit",
        "64",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let runs = results(&out);
    assert_eq!(runs.len(), 2);
    for r in &runs {
        if r["backend"] == "cpu-model" {
            let f = r["failure"].as_str().expect("the cpu-model run is refused");
            // 1025 cores × (32 KiB + 2 GiB) / 64 bytes × 9 bytes.
            assert!(f.contains("modelled caches of 1024 cores"), "{f}");
            assert!(f.contains("288.") && f.contains("GiB"), "{f}");
        } else {
            assert!(r["failure"].is_null(), "{r}");
        }
    }
}

#[test]
fn a_sweep_over_the_case_limit_is_refused_with_its_count_before_expanding() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    let many = |n: usize, from: f64, step: f64| -> Value {
        json!((0..n).map(|i| from + step * i as f64).collect::<Vec<_>>())
    };
    // 777,600,000 points in grid mode: 1800 × 1800 × 240.
    let mut v = tiny(None);
    v["sweep_mode"] = json!("grid");
    v["sweep"] = json!({
        "light_size": many(1800, 0.01, 0.001),
        "occluder_height": many(1800, 0.0, 0.001),
        "map_resolution": json!((1..=240).map(|i| 16 * i).collect::<Vec<_>>()),
    });
    write(&scenario, &v);
    let start = Instant::now();
    let o = shadowbench(&["run", s(&scenario), "--out", s(&dir.path().join("out"))]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = error_line(&o);
    assert!(
        e.contains("$.sweep") && e.contains("777600000 cases") && e.contains("100000"),
        "{e}"
    );
    // A million values on one axis.
    let mut v = tiny(None);
    v["sweep"] = json!({ "light_size": many(1_000_000, 0.01, 1e-6) });
    write(&scenario, &v);
    let o = shadowbench(&["run", s(&scenario), "--out", s(&dir.path().join("out"))]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(error_line(&o).contains("1000001 cases"), "{}", stderr(&o));
    // Refused before anything proportional to the sweep is built (a generous bound: the
    // quadratic de-duplication took minutes here).
    assert!(start.elapsed() < Duration::from_secs(60));
    // The limit is overridable.
    let mut v = tiny(None);
    v["sweep"] = json!({ "map_resolution": [16, 64] });
    write(&scenario, &v);
    let out = dir.path().join("out");
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out), "--max-cases", "2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_line(&o).contains("3 cases"), "{}", stderr(&o));
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out), "--max-cases", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(results(&out).len(), 3);
}

#[test]
fn sweep_points_are_de_duplicated_in_order() {
    let n = 64_000;
    let mut v = tiny(None);
    v["params"]["light_size"] = json!(0.5);
    // Every value twice, and the base value among them.
    let values: Vec<f64> = (0..2 * n).map(|i| 0.5 + (i % n) as f64 * 1e-3).collect();
    v["sweep"] = json!({ "light_size": values });
    let l = shadowbench::scenario::Loaded::from_str(&v.to_string(), Path::new("s.json")).unwrap();
    let cases = l.cases(200_000).unwrap();
    assert_eq!(cases.len(), n);
    for (i, c) in cases.iter().enumerate() {
        assert_eq!(c.light_size, Some((0.5 + i as f64 * 1e-3) as f32));
    }
}

// 5. Two commands into one output folder.

#[test]
fn a_second_command_into_a_locked_folder_says_who_holds_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let _held = shadowbench::harness::outdir::lock("--out", &out).unwrap();
    let scenario = dir.path().join("s.json");
    write(&scenario, &tiny(None));
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = error_line(&o);
    assert!(
        e.contains("--out")
            && e.contains("in use")
            && e.contains(&format!("process {}", std::process::id())),
        "{e}"
    );
    assert!(!out.join("results.json").exists());
}

#[test]
fn a_killed_run_leaves_no_temporary_file_once_the_next_run_starts() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    let mut v = tiny(None);
    v["algorithms"] = json!(["reference"]);
    v["params"]["image"] = json!([64, 48]);
    v["params"]["light_size"] = json!(0.05);
    v["sweep"] = json!({ "light_size": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8] });
    v["reference"]["samples"] = json!(256);
    write(&scenario, &v);
    let out = dir.path().join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", s(&scenario), "--out", s(&out)])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !out.join("results.json").exists() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    // What a kill during a write leaves (a process id above the kernel's limit never runs).
    std::fs::write(out.join(".results.json.4999999-0.tmp"), b"{").unwrap();
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let temps: Vec<PathBuf> = tree(&out)
        .into_iter()
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(temps.is_empty(), "{temps:?}");
    assert_eq!(results(&out).len(), 9);
}

// 6. `report` on absurd values.

#[test]
fn report_leaves_out_values_a_chart_cannot_show_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut v = real_results(dir.path());
    let run = v["runs"][0].clone();
    let mut runs = Vec::new();
    for (i, t) in [1.0, 1.7e308, 1e307, 3.0].into_iter().enumerate() {
        let mut r = run.clone();
        r["params"]["map_resolution"] = json!(32 * (i + 1));
        r["wall_ms"] = json!(t);
        runs.push(r);
    }
    v["runs"] = json!(runs);
    let file = dir.path().join("absurd.json");
    write(&file, &v);
    let out = dir.path().join("report");
    let mut child = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["report", s(&file), "--out", s(&out)])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        if start.elapsed() > Duration::from_secs(120) {
            child.kill().unwrap();
            panic!("report did not finish");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert!(status.success(), "{err}");
    let case = |i: usize| {
        let r: shadowbench::record::RunRecord =
            serde_json::from_value(v["runs"][i].clone()).unwrap();
        r.case_id()
    };
    for (i, value) in [(1, "1.7e308"), (2, "1e307")] {
        let line = err
            .lines()
            .find(|l| l.contains(&case(i)) && l.contains("wall_ms"))
            .unwrap_or_else(|| panic!("no warning for run {i}: {err}"));
        assert!(
            line.starts_with("warning: ") && line.contains(value),
            "{line}"
        );
    }
    assert!(out.join("charts/wall_ms_vs_map_resolution.png").is_file());
}

// 7. A budget per run.

#[test]
fn a_run_past_its_timeout_is_stopped_and_the_sweep_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    // Paper 002's soft shadow map at a fine map and a wide light: minutes uncancelled.
    let v = json!({
        "scene": { "generator": "sphere-on-plane" },
        "algorithms": ["soft_shadow_map"],
        "backends": ["cpu-native"],
        "params": { "image": [160, 120], "map_resolution": 512, "light_size": 1.5 },
        "sweep": { "map_resolution": [32] },
        "reference": { "enabled": false },
        "run_timeout_s": 600
    });
    write(&scenario, &v);
    let out = dir.path().join("out");
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out), "--run-timeout", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("estimated work") && stderr(&o).contains("each run stops after 2 s"),
        "{}",
        stderr(&o)
    );
    let runs = results(&out);
    assert_eq!(runs.len(), 2);
    let big = &runs[0];
    assert_eq!(big["params"]["map_resolution"], 512);
    let f = big["failure"].as_str().expect("the runaway run is stopped");
    assert!(
        f.contains("run timeout")
            && f.contains("budget of 2 s")
            && f.contains("stopped after")
            && f.contains("estimated work"),
        "{f}"
    );
    // Stopped within a task of its deadline, not after minutes.
    assert!(big["wall_ms"].as_f64().unwrap() < 30_000.0, "{big}");
    assert!(runs[1]["failure"].is_null(), "{}", runs[1]);
    // The scenario's own budget applies without the flag.
    let mut v = v;
    v["run_timeout_s"] = json!(1);
    write(&scenario, &v);
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out), "--fresh"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let f = results(&out)[0]["failure"].as_str().unwrap().to_string();
    assert!(f.contains("budget of 1 s"), "{f}");
    // A budget that is not a duration is an input error.
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out), "--run-timeout", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(error_line(&o).contains("--run-timeout"), "{}", stderr(&o));
}

// 8. Smaller faults.

#[test]
fn a_scenario_saved_where_the_run_writes_is_refused_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    let scenario = out.join("results.json");
    write(&scenario, &tiny(None));
    let before = std::fs::read(&scenario).unwrap();
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        error_line(&o).contains("would be overwritten"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&scenario).unwrap(), before);
}

#[test]
fn an_unwritable_cache_folder_warns_and_the_sweep_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    let mut v = tiny(None);
    v["sweep"] = json!({ "map_resolution": [64] });
    write(&scenario, &v);
    // A folder that cannot be created: below a regular file (ENOTDIR, as ENOSPC or EROFS would
    // be for a full or read-only disk).
    let file = dir.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    let cache = file.join("cache");
    let out = dir.path().join("out");
    let o = shadowbench(&[
        "run",
        s(&scenario),
        "--out",
        s(&out),
        "--cache-dir",
        s(&cache),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: reference cache") && stderr(&o).contains("going on"),
        "{}",
        stderr(&o)
    );
    let runs = results(&out);
    assert_eq!(runs.len(), 2);
    assert!(runs
        .iter()
        .all(|r| r["failure"].is_null() && r["error"].is_object()));
}

#[test]
fn compare_against_a_baseline_with_no_runs_fails() {
    let dir = tempfile::tempdir().unwrap();
    let good = real_results(dir.path());
    let mut empty = good.clone();
    empty["runs"] = json!([]);
    let (b, c) = (dir.path().join("base.json"), dir.path().join("cur.json"));
    write(&b, &empty);
    write(&c, &good);
    let o = shadowbench(&["compare", s(&b), s(&c)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = error_line(&o);
    assert!(
        e.contains("base.json") && e.contains("$.runs") && e.contains("no runs"),
        "{e}"
    );
}

#[test]
fn report_compare_and_merge_refuse_an_unknown_execution_and_report_writes_nothing_for_a_repeated_scenario(
) {
    let dir = tempfile::tempdir().unwrap();
    let good = real_results(dir.path());
    // The execution names chart files: a value that is not one is refused before any is drawn.
    let mut bad = good.clone();
    bad["runs"][0]["backend"] = json!("a/b");
    let file = dir.path().join("bad.json");
    write(&file, &bad);
    let out = dir.path().join("out");
    refused_alike(&file, &out, &["bad.json", "$.runs[0].backend", "a/b"]);
    // Two files of one scenario: refused before the first one's report is written.
    let (f1, f2) = (dir.path().join("one.json"), dir.path().join("two.json"));
    write(&f1, &good);
    write(&f2, &good);
    let o = shadowbench(&["report", s(&f1), s(&f2), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(error_line(&o).contains("given twice"), "{}", error_line(&o));
    assert!(!out.exists(), "report wrote {}", out.display());
}

#[test]
fn report_compare_and_merge_refuse_a_duplicated_run_alike() {
    let dir = tempfile::tempdir().unwrap();
    let mut dup = real_results(dir.path());
    let first = dup["runs"][0].clone();
    dup["runs"].as_array_mut().unwrap().push(first);
    let file = dir.path().join("dup.json");
    write(&file, &dup);
    let out = dir.path().join("out");
    refused_alike(&file, &out, &["dup.json", "$.runs[1]", "more than once"]);
}

/// `report`, `compare` and `merge` of results `file` each exit 2 with an error line holding
/// every one of `needles`, and write nothing into `out`.
fn refused_alike(file: &Path, out: &Path, needles: &[&str]) {
    for args in [
        vec!["report", s(file), "--out", s(out)],
        vec!["compare", s(file), s(file)],
        vec!["merge", s(file), "--out", s(out)],
    ] {
        let o = shadowbench(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let e = error_line(&o);
        assert!(needles.iter().all(|n| e.contains(n)), "{args:?}: {e}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}

#[test]
fn unreadable_inputs_say_why() {
    let dir = tempfile::tempdir().unwrap();
    // A byte order mark is accepted.
    let bom = dir.path().join("bom.json");
    let mut text = b"\xEF\xBB\xBF".to_vec();
    text.extend(serde_json::to_vec(&tiny(None)).unwrap());
    std::fs::write(&bom, text).unwrap();
    let o = shadowbench(&["run", s(&bom), "--out", s(&dir.path().join("o1"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (dir.path().join("a.json"), dir.path().join("b.json"));
    std::os::unix::fs::symlink(&b, &a).unwrap();
    std::os::unix::fs::symlink(&a, &b).unwrap();
    let obj_loop = dir.path().join("loop.json");
    let mut v = tiny(None);
    v["scene"] = json!({ "objects": [{ "obj": "a.obj" }] });
    write(&obj_loop, &v);
    std::os::unix::fs::symlink(dir.path().join("b.obj"), dir.path().join("a.obj")).unwrap();
    std::os::unix::fs::symlink(dir.path().join("a.obj"), dir.path().join("b.obj")).unwrap();
    let obj_zero = dir.path().join("zero.json");
    v["scene"] = json!({ "objects": [{ "obj": "/dev/zero" }] });
    write(&obj_zero, &v);
    for (input, want) in [
        (a.clone(), "a loop of symbolic links"),
        (
            PathBuf::from("/dev/zero"),
            "a character device, not a regular file",
        ),
        (dir.path().to_path_buf(), "a folder, not a regular file"),
        (obj_loop, "a loop of symbolic links"),
        (obj_zero, "a character device, not a regular file"),
    ] {
        let o = shadowbench(&["run", s(&input), "--out", s(&dir.path().join("o2"))]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        let e = error_line(&o);
        assert!(e.contains(want) && !e.contains("not found"), "{want}: {e}");
    }
    for cmd in [
        vec!["report", s(&a), "--out", "x"],
        vec!["compare", s(&a), s(&a)],
    ] {
        let o = shadowbench(&cmd);
        assert_eq!(o.status.code(), Some(2));
        assert!(
            error_line(&o).contains("a loop of symbolic links"),
            "{}",
            stderr(&o)
        );
    }
}

#[test]
fn an_output_folder_that_cannot_be_made_is_an_input_error() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    write(&scenario, &tiny(None));
    let file = dir.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    for out in [file.clone(), file.join("sub")] {
        let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        let e = error_line(&o);
        assert!(e.contains("--out") && e.contains(s(&out)), "{e}");
    }
}

#[test]
fn a_frame_with_nothing_in_view_has_no_quality_metrics_and_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.json");
    let mut v = tiny(None);
    // Looking straight up, away from the whole scene.
    v["camera"] =
        json!({ "eye": [0, 50, 0], "target": [0, 100, 0], "up": [1, 0, 0], "fov_y_deg": 30 });
    write(&scenario, &v);
    let out = dir.path().join("out");
    let o = shadowbench(&["run", s(&scenario), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let runs = results(&out);
    assert_eq!(runs.len(), 1);
    let r = &runs[0];
    assert!(r["failure"].is_null(), "{r}");
    assert!(
        r["error"].is_null() || r["error"]["mae"].is_null(),
        "no metric over 0 pixels: {r}"
    );
    let warnings = r["warnings"].as_array().expect("a warning");
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("0 pixels")),
        "{warnings:?}"
    );
}
