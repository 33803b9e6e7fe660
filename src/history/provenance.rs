//! Where a recording comes from: the commit, its branch, date and subject (flags first, then
//! the CI's environment, then `git` in the current folder), and the fingerprint of the machine
//! and adapter each run ran on.

use std::collections::BTreeMap;
use std::process::Command;

use serde_json::Value;

use crate::error::InputError;
use crate::record::RunRecord;

/// The commit a recording belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct Commit {
    /// The commit id (hex, as git prints it).
    pub sha: String,
    /// The branch it was recorded on; empty when unknown.
    pub branch: String,
    /// The commit's date: ISO 8601, any offset (stored in UTC).
    pub date: String,
    /// The first line of its message; empty when unknown.
    pub subject: String,
}

/// What the command line gave; `None` fields are looked up.
#[derive(Clone, Debug, Default)]
pub struct Given {
    pub commit: Option<String>,
    pub branch: Option<String>,
    pub date: Option<String>,
    pub subject: Option<String>,
}

/// The first non-empty value of the environment variables `names`.
fn env(names: &[&str]) -> Option<String> {
    names
        .iter()
        .filter_map(|n| std::env::var(n).ok())
        .map(|v| v.trim().to_string())
        .find(|v| !v.is_empty())
}

/// `git args…` in the current folder: its trimmed output, or `None` when git is missing, this
/// is not a repository or the command fails.
fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let s = String::from_utf8_lossy(&out.stdout).trim().to_string();
    (!s.is_empty()).then_some(s)
}

/// The commit of a recording: `--commit` (else `GITHUB_SHA`, `CI_COMMIT_SHA`, else
/// `git rev-parse HEAD`); `--branch` (else `GITHUB_HEAD_REF` of a pull request,
/// `GITHUB_REF_NAME`, `CI_COMMIT_REF_NAME`, else `git rev-parse --abbrev-ref HEAD`); `--date`
/// (else the commit's committer date from git, `CI_COMMIT_TIMESTAMP`, else now); the subject
/// from git.
///
/// Errors: no commit from any source (`--commit` names what to give), or a commit id that is
/// not 4 to 64 hexadecimal digits.
pub fn commit(given: &Given) -> Result<Commit, InputError> {
    let sha = given
        .commit
        .clone()
        .or_else(|| env(&["GITHUB_SHA", "CI_COMMIT_SHA"]))
        .or_else(|| git(&["rev-parse", "HEAD"]))
        .ok_or_else(|| {
            InputError::new(
                "--commit",
                "no commit given, none in GITHUB_SHA or CI_COMMIT_SHA, and git found no \
                 repository here",
            )
        })?;
    check_sha("--commit", &sha)?;
    let in_git = Command::new("git")
        .args(["cat-file", "-e", &format!("{sha}^{{commit}}")])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let from_git = |format: &str| {
        in_git
            .then(|| git(&["show", "-s", &format!("--format={format}"), &sha]))
            .flatten()
    };
    let branch = given
        .branch
        .clone()
        .or_else(|| env(&["GITHUB_HEAD_REF", "GITHUB_REF_NAME", "CI_COMMIT_REF_NAME"]))
        .or_else(|| git(&["rev-parse", "--abbrev-ref", "HEAD"]).filter(|b| b != "HEAD"))
        .unwrap_or_default();
    let date = given
        .date
        .clone()
        .or_else(|| from_git("%cI"))
        .or_else(|| env(&["CI_COMMIT_TIMESTAMP"]))
        .unwrap_or_default();
    let subject = given
        .subject
        .clone()
        .or_else(|| from_git("%s"))
        .unwrap_or_default();
    Ok(Commit {
        sha: sha.to_lowercase(),
        branch,
        date,
        subject,
    })
}

/// Checks that `sha` is a commit id: 4 to 64 hexadecimal digits.
pub fn check_sha(field: &str, sha: &str) -> Result<(), InputError> {
    if (4..=64).contains(&sha.len()) && sha.bytes().all(|b| b.is_ascii_hexdigit()) {
        Ok(())
    } else {
        Err(InputError::new(
            field,
            format!("expected a commit id (4 to 64 hexadecimal digits), got '{sha}'"),
        ))
    }
}

/// The entries of a run's `execution` that say what it ran on: the modelled machine of a
/// cpu-model run, the adapter and driver of a wgpu run, the host threads of every run.
const MACHINE_KEYS: [&str; 10] = [
    "adapter",
    "adapter_type",
    "driver",
    "driver_info",
    "gpu_backend",
    "machine",
    "machine_cores",
    "clock_ghz",
    "threads_per_core",
    "host_threads",
];

/// The host a recording is made on, when `--machine` does not name it: the CPU model (from
/// `/proc/cpuinfo` where there is one), the logical CPUs, the OS and architecture.
pub fn this_host() -> BTreeMap<String, Value> {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_default();
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    [
        ("cpu", Value::from(cpu)),
        ("logical_cpus", Value::from(cpus)),
        ("os", Value::from(std::env::consts::OS)),
        ("arch", Value::from(std::env::consts::ARCH)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

/// The machine of run `r` recorded on `host` (from [`this_host`], or `{"name": ...}` given by
/// `--machine`): the host, the run's execution and what it ran on ([`MACHINE_KEYS`]) as JSON,
/// and its fingerprint, 16 hex digits of a stable hash of that JSON. Runs with the same
/// fingerprint ran on the same machine and adapter; series of different fingerprints are never
/// mixed.
pub fn machine(r: &RunRecord, host: &BTreeMap<String, Value>) -> (String, String) {
    let mut m: BTreeMap<String, Value> = BTreeMap::new();
    m.insert(
        "host".into(),
        Value::Object(host.clone().into_iter().collect()),
    );
    m.insert("execution".into(), Value::from(r.backend.name()));
    for k in MACHINE_KEYS {
        if let Some(v) = r.execution.get(k) {
            m.insert(k.to_string(), v.clone());
        }
    }
    let text = serde_json::to_string(&m).expect("JSON values serialize");
    let mut h = crate::util::hash::Fnv64::default();
    h.bytes(text.as_bytes());
    (format!("{:016x}", h.finish()), text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Backend;
    use crate::report::testdata::record;

    #[test]
    fn fingerprints_separate_adapters_and_modelled_machines_and_hosts() {
        let host = this_host();
        let a = record("pcss", Backend::Wgpu, 500, 32);
        let mut b = a.clone();
        b.execution.insert("adapter".into(), "llvmpipe".into());
        let mut c = a.clone();
        c.execution.insert("adapter".into(), "NVIDIA H200".into());
        assert_eq!(machine(&a, &host).0, machine(&a, &host).0);
        assert_ne!(machine(&b, &host).0, machine(&c, &host).0);
        let other: BTreeMap<String, Value> = [("name".to_string(), Value::from("runner-2"))].into();
        assert_ne!(machine(&b, &host).0, machine(&b, &other).0);
        let mut m = record("pcss", Backend::CpuModel, 500, 32);
        m.execution.insert("machine".into(), "larrabee-24".into());
        let mut m48 = m.clone();
        m48.execution.insert("machine".into(), "larrabee-48".into());
        assert_ne!(machine(&m, &host).0, machine(&m48, &host).0);
        // A field that does not say where it ran does not split series.
        let mut w = m.clone();
        w.execution.insert("options".into(), "{}".into());
        assert_eq!(machine(&m, &host).0, machine(&w, &host).0);
    }

    #[test]
    fn commit_ids_are_hex() {
        assert!(check_sha("--commit", "a1b2c3d").is_ok());
        assert!(check_sha("--commit", "HEAD").is_err());
        assert!(check_sha("--commit", "abc").is_err());
    }
}
