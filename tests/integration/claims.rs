//! Paper claims through the CLI: several scenarios run into one folder, each with its own
//! report, and an index that evaluates every claim over the runs of all of them.

use std::path::Path;
use std::process::Command;

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn several_scenarios_share_an_index_of_claims() {
    let dir = tempfile::tempdir().unwrap();
    // Two light sizes of the hard shadow map; the small light's claim compares its own runs,
    // the large light's compares across scenarios. A claim that cannot hold is reported so.
    let small = write(
        dir.path(),
        "small.json",
        r#"{
  "name": "small-light",
  "scene": { "generator": "sphere-on-plane" },
  "algorithms": ["hard_shadow_map", "pcss"],
  "backends": ["cpu-model"],
  "params": { "image": [32, 24], "map_resolution": 64, "triangles": 300, "light_size": 0.2 },
  "reference": { "samples": 16 },
  "claims": [
    { "paper": "test", "claim": "pcss does more work than a hard shadow map",
      "measure": { "figure": "model_ms", "aggregate": "mean", "where": { "algorithm": "pcss" },
                   "over": { "figure": "model_ms", "aggregate": "mean",
                             "where": { "algorithm": "hard_shadow_map" } } },
      "expect": "> 1" }
  ]
}"#,
    );
    let large = write(
        dir.path(),
        "large.json",
        r#"{
  "name": "large-light",
  "scene": { "generator": "sphere-on-plane" },
  "algorithms": ["pcss"],
  "backends": ["cpu-model"],
  "params": { "image": [32, 24], "map_resolution": 64, "triangles": 300, "light_size": 1.0 },
  "reference": { "samples": 16 },
  "claims": [
    { "paper": "test", "claim": "pcss errs more under the larger light",
      "paper_value": "more",
      "measure": { "figure": "error.mae_shadow", "aggregate": "mean",
                   "where": { "scenario": "large-light" },
                   "over": { "figure": "error.mae_shadow", "aggregate": "mean",
                             "where": { "scenario": "small-light", "algorithm": "pcss" } } } },
    { "paper": "test", "claim": "an impossible frame rate",
      "measure": { "figure": "per_second.model_ms", "where": { "algorithm": "pcss" } },
      "expect": "> 1e12" }
  ]
}"#,
    );
    let out = dir.path().join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run"])
        .args([&small, &large])
        .arg("--out")
        .arg(&out)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for scenario in ["small-light", "large-light"] {
        assert!(out.join(scenario).join("results.json").is_file());
        assert!(out.join(scenario).join("index.html").is_file());
    }
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(index.contains("href=\"small-light/index.html\""), "{index}");
    assert!(index.contains("href=\"large-light/index.html\""), "{index}");
    // The cross-scenario ratio is measured in the index (a number, not "not measured") ...
    let line = stdout
        .lines()
        .skip_while(|l| !l.contains("errs more under the larger light"))
        .nth(1)
        .unwrap();
    let ours: f64 = line
        .split("ours: ")
        .nth(1)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(ours.is_finite() && ours > 0.0, "{line}");
    assert!(stdout.contains("holds (expect > 1)"), "{stdout}");
    assert!(stdout.contains("DOES NOT HOLD (expect > 1e12)"), "{stdout}");
    // ... but not in the large-light page alone, which says why.
    let page = std::fs::read_to_string(out.join("large-light/index.html")).unwrap();
    assert!(
        page.contains("the runs of scenario &#x27;small-light&#x27; are not in these results")
            || page.contains("the runs of scenario 'small-light' are not in these results"),
        "{page}"
    );
}

#[test]
fn a_bad_claim_is_an_input_error_naming_its_path() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(
        dir.path(),
        "bad.json",
        r#"{
  "scene": { "generator": "sphere-on-plane" },
  "algorithms": ["pcss"],
  "claims": [ { "paper": "p", "claim": "c",
                "measure": { "figure": "model_ms", "where": { "algoritm": "pcss" } } } ]
}"#,
    );
    let run = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run"])
        .arg(&s)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("$.claims[0].measure.where.algoritm"),
        "{stderr}"
    );
    assert!(stderr.contains("algorithm"), "{stderr}");
    assert!(!dir.path().join("out").exists());
}
