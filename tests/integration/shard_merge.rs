//! Sharding a sweep and merging the shards gives the same runs as the sweep in one go, and the
//! merged folder holds a report whose every image exists.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use shadowbench::harness::{self, RunOptions, Shard};
use shadowbench::record::RunRecord;
use shadowbench::report;
use shadowbench::scenario::Loaded;

fn run(loaded: &Loaded, out: &Path, cache: &Path, shard: Option<Shard>) -> Vec<RunRecord> {
    harness::run_scenario(
        loaded,
        &RunOptions {
            out: out.to_path_buf(),
            only: None,
            backends: None,
            cache_dir: Some(cache.to_path_buf()),
            memory_limit: harness::limits::default_limit(),
            machine: None,
            shard,
            max_cases: shadowbench::scenario::MAX_CASES,
            run_timeout: None,
            verbosity: harness::Verbosity::Quiet,
            gpu_counters: Default::default(),
            measure: Default::default(),
            fresh: false,
            retry_failed: false,
        },
    )
    .unwrap()
    .runs
}

fn ids(runs: &[RunRecord]) -> BTreeSet<String> {
    runs.iter().map(RunRecord::case_id).collect()
}

#[test]
fn merged_shards_equal_the_unsharded_run() {
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/ci.json");
    let loaded = Loaded::from_file(&scenario).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let all = run(&loaded, &tmp.path().join("all"), &cache, None);
    assert!(all.len() >= 2, "the CI scenario must plan several runs");

    let mut inputs: Vec<(PathBuf, _)> = Vec::new();
    let mut shard_ids = Vec::new();
    for k in 1..=2 {
        let dir = tmp.path().join(format!("shard{k}"));
        let runs = run(&loaded, &dir, &cache, Some(Shard { index: k, count: 2 }));
        assert!(!runs.is_empty());
        shard_ids.push(ids(&runs));
        let path = dir.join("results.json");
        inputs.push((path.clone(), report::read_results(&path).unwrap()));
    }
    assert!(shard_ids[0].is_disjoint(&shard_ids[1]));

    let merged_dir = tmp.path().join("merged");
    let written = report::write_merged(&merged_dir, &inputs).unwrap();
    let merged = report::read_results(&merged_dir.join("results.json")).unwrap();
    assert_eq!(ids(&merged.runs), ids(&all));
    assert_eq!(merged.runs.len(), all.len());
    assert!(merged_dir.join("results.csv").is_file());

    // The merged report links only images that were carried over.
    let page = std::fs::read_to_string(&written.index).unwrap();
    let mut images = 0;
    for src in page.split("src=\"").skip(1) {
        let src = &src[..src.find('"').unwrap()];
        assert!(merged_dir.join(src).is_file(), "{src} missing");
        images += 1;
    }
    assert!(
        images > all.len(),
        "every run's image and the charts: {images}"
    );
    for r in &all {
        assert!(merged_dir
            .join("images")
            .join(r.case_id())
            .join("visibility.png")
            .is_file());
    }
}
