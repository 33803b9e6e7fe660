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
