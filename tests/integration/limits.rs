//! A run that would exceed the memory limit is refused with its estimate, recorded as failed,
//! and the sweep goes on with the next case.

use std::process::Command;

#[test]
fn over_limit_runs_fail_alone_and_the_sweep_continues() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("big.json");
    std::fs::write(
        &scenario,
        r#"{
  "scene": { "generator": "box-on-plane" },
  "algorithms": ["reference"],
  "backends": ["cpu-native"],
  "params": { "image": [32, 24] },
  "sweep": { "image": [[4000, 3000], [40, 30]] },
  "reference": { "samples": 4 }
}"#,
    )
    .unwrap();
    let out = dir.path().join("out");
    let status = Command::new(env!("CARGO_BIN_EXE_shadowbench"))
        .args(["run", scenario.to_str().unwrap(), "--memory-limit", "0.01"])
        .arg("--out")
        .arg(&out)
        .env("RUST_BACKTRACE", "0")
        .output()
        .unwrap();
    assert!(status.status.success());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let runs = json["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 3);
    for r in runs {
        let big = r["params"]["image"][0] == 4000;
        let failure = r["failure"].as_str();
        if big {
            let f = failure.expect("the 4000x3000 run is refused");
            assert!(f.contains("GiB") && f.contains("limit"), "{f}");
        } else {
            assert!(failure.is_none(), "{failure:?}");
        }
    }
}
