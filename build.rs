//! Records the commit the binary is built from (`SHADOWBENCH_COMMIT`, "unknown" outside a git
//! checkout; with `-dirty-` and a fingerprint of the diff when tracked files have uncommitted
//! changes) and the build profile (`SHADOWBENCH_PROFILE`), for the conditions of a
//! measurement and the build a results folder belongs to (`shadowbench::build`).

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
        .filter(|s| !s.is_empty())
}

/// FNV-1a of `bytes`: a fingerprint of the uncommitted changes.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

fn main() {
    let mut commit = git(&["rev-parse", "HEAD"]).unwrap_or_else(|| "unknown".into());
    // A tree with uncommitted changes to tracked files is another build than its commit (a
    // results folder of the commit's build is not resumed by it): the commit, `-dirty-` and a
    // fingerprint of the diff.
    if let Some(diff) = git(&["diff", "HEAD", "--binary"]) {
        commit = format!("{commit}-dirty-{:016x}", fnv1a(diff.as_bytes()));
    }
    println!("cargo:rustc-env=SHADOWBENCH_COMMIT={commit}");
    let profile = std::env::var("PROFILE").unwrap_or_else(|_| "unknown".into());
    println!("cargo:rustc-env=SHADOWBENCH_PROFILE={profile}");
    // Built again when HEAD moves: HEAD itself and the branch it names.
    for path in ["HEAD".to_string()]
        .into_iter()
        .chain(git(&["symbolic-ref", "-q", "HEAD"]))
    {
        if let Some(p) = git(&["rev-parse", "--git-path", &path]) {
            println!("cargo:rerun-if-changed={p}");
        }
    }
    // And when a tracked file changes (the diff's fingerprint).
    for dir in ["src", "Cargo.toml", "Cargo.lock"] {
        println!("cargo:rerun-if-changed={dir}");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
