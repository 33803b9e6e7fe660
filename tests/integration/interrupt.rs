//! Ctrl-C during a sweep leaves a valid results.json holding the runs that finished.

use std::os::unix::process::CommandExt;
use std::process::Command;
use std::time::{Duration, Instant};

#[test]
fn sigint_mid_sweep_keeps_finished_runs() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("long.json");
    std::fs::write(
        &scenario,
        r#"{
  "scene": { "generator": "sphere-grid" },
  "algorithms": ["reference"],
  "backends": ["cpu-native"],
  "params": { "image": [96, 72] },
  "sweep": { "light_size": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0] },
  "reference": { "samples": 1024 }
}"#,
    )
    .unwrap();
    let out = dir.path().join("out");
    let mut command = Command::new(env!("CARGO_BIN_EXE_shadowbench"));
    // SIGINT's disposition is inherited: a test started from a background job (or under
    // `trap "" INT`) would give the child an ignored SIGINT, and the interrupt below would do
    // nothing. The child gets the default action whatever started the test.
    // SAFETY: `signal` is async-signal-safe, as `pre_exec` requires; nothing else runs there.
    unsafe {
        command.pre_exec(|| {
            if libc::signal(libc::SIGINT, libc::SIG_DFL) == libc::SIG_ERR {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = command
        .args([
            "run",
            scenario.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .env("RUST_BACKTRACE", "0")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let results = out.join("results.json");
    let start = Instant::now();
    while !results.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no results written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let exit = child.wait().unwrap();
    let text = std::fs::read_to_string(&results).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).expect("results.json stays valid");
    let runs = json["runs"].as_array().unwrap();
    assert!(!runs.is_empty());
    assert!(
        !exit.success() && runs.len() < 21,
        "the sweep was interrupted ({} runs, {exit})",
        runs.len()
    );
    for r in runs {
        assert!(r["failure"].is_null() && r["wall_ms"].is_number());
    }
}

/// A sweep of five or six reference runs, each long enough (about a second) to be killed in the middle.
const RESUMABLE: &str = r#"{
  "name": "resumable",
  "scene": { "generator": "sphere-grid" },
  "algorithms": ["reference"],
  "backends": ["cpu-native"],
  "params": { "image": [64, 48] },
  "sweep": { "light_size": [0.2, 0.4, 0.6, 0.8, 1.0] },
  "reference": { "enabled": false, "samples": 1024 }
}"#;

/// `run` of `scenario` into `out`, timed once per run so the sweep is quick.
fn resumable_run(scenario: &std::path::Path, out: &std::path::Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_shadowbench"));
    c.args([
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--warmup",
        "0",
        "--repeats",
        "1",
    ])
    .env("RUST_BACKTRACE", "0");
    c
}

/// Each run's light size with its counters (in light-size order), and each run's image folder
/// with the bytes of its visibility image (in name order).
type Sweep = (Vec<(String, serde_json::Value)>, Vec<(String, Vec<u8>)>);

fn runs_and_images(out: &std::path::Path) -> Sweep {
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let mut runs: Vec<_> = json["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            assert!(r["failure"].is_null(), "{r}");
            (r["params"]["light_size"].to_string(), r["counters"].clone())
        })
        .collect();
    runs.sort_by(|a, b| a.0.cmp(&b.0));
    let mut images: Vec<_> = std::fs::read_dir(out.join("images"))
        .unwrap()
        .map(|e| {
            let d = e.unwrap().path();
            let name = d.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(d.join("visibility.npy")).unwrap())
        })
        .collect();
    images.sort();
    (runs, images)
}

#[test]
fn a_sweep_killed_mid_way_resumes_running_only_what_is_missing() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("resumable.json");
    std::fs::write(&scenario, RESUMABLE).unwrap();
    // Uninterrupted, for the results to equal.
    let whole = dir.path().join("whole");
    let o = resumable_run(&scenario, &whole).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let expected = runs_and_images(&whole);
    let total = expected.0.len();
    assert!(total >= 5 && expected.1.len() == total, "{total} runs");

    // Killed with -9 once two runs are in results.json.
    let out = dir.path().join("out");
    let mut child = resumable_run(&scenario, &out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let results = out.join("results.json");
    let start = Instant::now();
    let finished = |p: &std::path::Path| {
        std::fs::read_to_string(p)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .map_or(0, |j| j["runs"].as_array().map_or(0, |r| r.len()))
    };
    while finished(&results) < 2 {
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "no results written"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let status = Command::new("kill")
        .args(["-9", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    assert!(!child.wait().unwrap().success());
    let kept = finished(&results);
    assert!((2..total).contains(&kept), "killed after {kept} runs");

    // The same command again: only the missing runs run.
    let o = resumable_run(&scenario, &out).output().unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!("resuming: {kept} finished runs kept")),
        "{stderr}"
    );
    let ran = stdout.lines().filter(|l| l.starts_with('[')).count();
    assert_eq!(ran, total - kept, "{stdout}");
    // The results equal the uninterrupted sweep's: counters and images identical.
    assert_eq!(runs_and_images(&out), expected);

    // Once more: nothing runs, nothing is lost.
    let o = resumable_run(&scenario, &out).output().unwrap();
    assert!(o.status.success());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with('[')).count(),
        0,
        "{stdout}"
    );
    assert_eq!(runs_and_images(&out), expected);

    // Another scenario into the same folder is refused, saying how to start afresh; --fresh
    // runs it.
    let other = dir.path().join("other.json");
    std::fs::write(&other, RESUMABLE.replace("0.2, 0.4", "0.3, 0.4")).unwrap();
    let o = resumable_run(&other, &out).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("results.json")
            && stderr.contains("another scenario")
            && stderr.contains("--fresh"),
        "{stderr}"
    );
    let o = resumable_run(&other, &out).arg("--fresh").output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(stdout.lines().filter(|l| l.starts_with('[')).count(), total);
}
