//! The build of this binary: its commit and profile (from `build.rs`) and version, recorded with
//! every measurement and in every results folder, so a sweep resumes only with the build that
//! started it.

/// The commit the binary was built from (`git rev-parse HEAD` at build time; "unknown" outside
/// a git checkout), followed by `-dirty-` and a fingerprint of `git diff HEAD` when tracked
/// files had uncommitted changes (untracked files are not seen).
pub const COMMIT: &str = env!("SHADOWBENCH_COMMIT");

/// Cargo's build profile: "release" or "debug" (the dev and test profiles).
pub const PROFILE: &str = env!("SHADOWBENCH_PROFILE");

/// The build as one string: version, commit and profile.
pub fn id() -> String {
    format!("{} {} {}", env!("CARGO_PKG_VERSION"), COMMIT, PROFILE)
}
