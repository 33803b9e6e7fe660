//! The output folder (`--out`) of one command: created and locked before anything is written,
//! so two runs into one folder cannot mix their files; temporary files with names no other
//! process uses; and the temporary files a killed run left behind removed by the next one.
//!
//! The lock is an advisory exclusive lock ([`std::fs::File::try_lock`], `flock` on Unix) on
//! `OUT/.shadowbench.lock`, held for the life of the command. The operating system releases it
//! when the process ends in any way (a crash or `kill -9` included), so a lock is never stale.
//! The file holds the holder's process id, command line and start time for the refusal
//! message of a second run.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::error::{Error, InputError, Result};

/// Name of the lock file inside the output folder.
pub const LOCK_FILE: &str = ".shadowbench.lock";

/// The held lock on an output folder; dropping it releases the lock. A folder the lock
/// created that holds nothing but the lock file when it is dropped (the command failed before
/// writing anything) is removed, so a refused command leaves no trace.
#[derive(Debug)]
pub struct OutLock {
    _file: File,
    pub dir: PathBuf,
    created: bool,
}

impl Drop for OutLock {
    fn drop(&mut self) {
        if !self.created {
            return;
        }
        let only_lock = std::fs::read_dir(&self.dir).is_ok_and(|entries| {
            entries
                .filter_map(|e| e.ok())
                .all(|e| e.file_name() == LOCK_FILE)
        });
        if only_lock {
            let _ = std::fs::remove_file(self.dir.join(LOCK_FILE));
            let _ = std::fs::remove_dir(&self.dir);
        }
    }
}

/// Creates `out` (an input error naming `field` and the folder when it cannot be created: a
/// file in the way, a path through a file, no permission) and locks it. When another process
/// holds the lock, refuses with an input error that says who holds it. Then removes the
/// temporary files of processes that no longer run ([`remove_orphaned_temps`]).
pub fn lock(field: &str, out: &Path) -> Result<OutLock> {
    let created = !out.exists();
    std::fs::create_dir_all(out).map_err(|e| {
        InputError::new(
            field,
            format!("cannot create the output folder '{}': {e}", out.display()),
        )
    })?;
    let path = out.join(LOCK_FILE);
    let mut file = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(|e| {
            InputError::new(
                field,
                format!(
                    "cannot write into the output folder '{}': {e}",
                    out.display()
                ),
            )
        })?;
    match file.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = file.read_to_string(&mut holder);
            return Err(InputError::new(
                field,
                format!(
                    "the output folder '{}' is in use by another shadowbench command ({}); \
                     wait for it to finish or choose another folder",
                    out.display(),
                    describe_holder(holder.trim())
                ),
            )
            .into());
        }
        Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(&path, e)),
    }
    let since = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    // Paths are bytes on Linux: an argument that is not UTF-8 is recorded lossily (`U+FFFD`).
    let args: Vec<String> = std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let note = format!(
        "pid {}\nsince {since}\ncommand {}\n",
        std::process::id(),
        args.join(" ")
    );
    replace_contents(&mut file, note.as_bytes()).map_err(|e| Error::io(&path, e))?;
    remove_orphaned_temps(out, 4);
    if let Some(link) = find_link(out, 5) {
        let to = std::fs::read_link(&link).unwrap_or_default();
        let why = format!(
            "'{}' inside the output folder is a symbolic link (to '{}'): what the command writes \
             there would land outside '{}'; remove the link or choose another folder",
            link.display(),
            to.display(),
            out.display()
        );
        return Err(InputError::new(field, why).into());
    }
    Ok(OutLock {
        _file: file,
        dir: out.to_path_buf(),
        created,
    })
}

/// Replaces what `file` holds with `bytes`.
fn replace_contents(file: &mut File, bytes: &[u8]) -> std::io::Result<()> {
    file.set_len(0)?;
    file.rewind()?;
    file.write_all(bytes)
}

/// "process 1234, `shadowbench run x.json`, started 12 s ago" from the lock file's text.
fn describe_holder(text: &str) -> String {
    let field = |k: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(k).map(|v| v.trim().to_string()))
    };
    let mut parts = Vec::new();
    if let Some(pid) = field("pid ") {
        parts.push(format!("process {pid}"));
    }
    if let Some(cmd) = field("command ") {
        parts.push(format!("`{cmd}`"));
    }
    if let Some(since) = field("since ").and_then(|s| s.parse::<u64>().ok()) {
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        parts.push(format!("started {} s ago", now.saturating_sub(since)));
    }
    if parts.is_empty() {
        "holder unknown".into()
    } else {
        parts.join(", ")
    }
}

/// A temporary name beside `path` that no other process or thread uses:
/// `.<file name>.<pid>-<n>.tmp`, hidden, in the same folder (so a rename onto `path` is atomic).
pub fn temp_path(path: &Path) -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(
        ".{name}.{}-{}.tmp",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ))
}

/// The process id in a name made by [`temp_path`].
fn temp_owner(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (_, ids) = rest.rsplit_once('.')?;
    let (pid, n) = ids.split_once('-')?;
    n.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// Whether process `pid` is running (on systems without `/proc`, assumed running).
fn alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc = Path::new("/proc");
    !proc.is_dir() || proc.join(pid.to_string()).exists()
}

/// The first symbolic link in `dir` and its folders down to `depth` levels (links are not
/// followed), if any: a command writes only inside its output folder, and a link planted there
/// (`OUT/images -> elsewhere`) would carry its files outside.
pub fn find_link(dir: &Path, depth: usize) -> Option<PathBuf> {
    let mut entries: Vec<_> = std::fs::read_dir(dir).ok()?.flatten().collect();
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let Ok(t) = e.file_type() else { continue };
        if t.is_symlink() {
            return Some(e.path());
        }
        if t.is_dir() && depth > 0 {
            if let Some(l) = find_link(&e.path(), depth - 1) {
                return Some(l);
            }
        }
    }
    None
}

/// Removes, in `dir` and its folders down to `depth` levels, the files [`temp_path`] names
/// whose process no longer runs (a run killed while writing). Symbolic links are not followed;
/// errors are ignored (the files are harmless, only untidy).
pub fn remove_orphaned_temps(dir: &Path, depth: usize) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let Ok(t) = e.file_type() else { continue };
        let name = e.file_name().to_string_lossy().into_owned();
        if t.is_dir() && depth > 0 {
            remove_orphaned_temps(&e.path(), depth - 1);
        } else if t.is_file() && temp_owner(&name).is_some_and(|pid| !alive(pid)) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_names_are_unique_and_carry_the_process_id() {
        let p = Path::new("/x/results.json");
        let (a, b) = (temp_path(p), temp_path(p));
        assert_ne!(a, b);
        assert_eq!(a.parent(), p.parent());
        let name = a.file_name().unwrap().to_str().unwrap();
        assert_eq!(temp_owner(name), Some(std::process::id()));
        assert_eq!(temp_owner("results.json"), None);
        assert_eq!(temp_owner(".notes.tmp"), None);
    }

    #[test]
    fn orphans_of_dead_processes_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("images").join("case");
        std::fs::create_dir_all(&sub).unwrap();
        // Process ids above the kernel's limit (4194304) never run.
        let dead = sub.join(".run.json.4999999-0.tmp");
        let mine = temp_path(&dir.path().join("results.json"));
        let other = dir.path().join(".notes.tmp");
        for f in [&dead, &mine, &other] {
            std::fs::write(f, b"x").unwrap();
        }
        remove_orphaned_temps(dir.path(), 4);
        assert!(!dead.exists());
        assert!(mine.exists() && other.exists());
    }

    #[test]
    fn a_second_lock_on_one_folder_is_refused_naming_the_holder() {
        let dir = tempfile::tempdir().unwrap();
        let _held = lock("--out", dir.path()).unwrap();
        let e = lock("--out", dir.path()).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let e = e.to_string();
        assert!(e.starts_with("--out: "), "{e}");
        assert!(
            e.contains(&format!("process {}", std::process::id())) && e.contains("in use"),
            "{e}"
        );
    }

    #[test]
    fn an_output_folder_that_cannot_be_created_is_an_input_error() {
        let (_dir, file) = crate::util::paths::temp_path("file");
        std::fs::write(&file, b"x").unwrap();
        let e = lock("--out", &file.join("sub")).unwrap_err();
        assert_eq!(e.exit_code(), 2, "{e}");
        assert!(
            e.to_string().contains("cannot create the output folder"),
            "{e}"
        );
    }
}
