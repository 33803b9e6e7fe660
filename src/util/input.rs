//! Opening the files a user names (scenarios, machine configurations, results files, OBJ
//! meshes) with errors that say what is wrong with the path: missing, a symbolic link loop, a
//! folder, a device or pipe such as `/dev/zero` (which would never end), unreadable, not UTF-8.
//! A UTF-8 byte order mark at the start of a text file is accepted and dropped.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::InputError;

/// Opens `path` for reading after checking that it is a regular file (following symbolic
/// links). `what` says what the file is for, in errors ("scenario", "results").
pub fn open(path: &Path, what: &str) -> Result<File, InputError> {
    let meta = std::fs::metadata(path).map_err(|e| {
        InputError::file(path, format!("cannot read {what}: {}", describe(&e, path)))
    })?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a folder"
        } else {
            file_kind(&meta)
        };
        return Err(InputError::file(
            path,
            format!("cannot read {what}: {kind}, not a regular file"),
        ));
    }
    File::open(path)
        .map_err(|e| InputError::file(path, format!("cannot read {what}: {}", describe(&e, path))))
}

/// Refuses a file of `len` bytes that is larger than the memory limit
/// ([`crate::harness::limits::process_limit`]), before it is read: a 40 GB (sparse) file named
/// as a scenario or a glTF buffer.
pub fn check_size(path: &Path, what: &str, len: u64) -> Result<(), InputError> {
    let limit = crate::harness::limits::process_limit();
    if len > limit {
        return Err(InputError::file(
            path,
            format!(
                "cannot read {what}: the file is too large ({}, over the memory limit of {}; \
                 raise it with --memory-limit, in GiB)",
                crate::harness::limits::bytes(len),
                crate::harness::limits::bytes(limit)
            ),
        ));
    }
    Ok(())
}

/// Reads the whole of `path` (see [`open`]) after checking its size ([`check_size`]).
pub fn read_bytes(path: &Path, what: &str) -> Result<Vec<u8>, InputError> {
    let file = open(path, what)?;
    let len = file
        .metadata()
        .map_err(|e| InputError::file(path, format!("cannot read {what}: {e}")))?
        .len();
    check_size(path, what, len)?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(len)
        .read_to_end(&mut bytes)
        .map_err(|e| InputError::file(path, format!("cannot read {what}: {e}")))?;
    Ok(bytes)
}

/// Reads `path` as UTF-8 text (see [`read_bytes`]); a leading byte order mark is dropped.
pub fn read_text(path: &Path, what: &str) -> Result<String, InputError> {
    let bytes = read_bytes(path, what)?;
    let body = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    match std::str::from_utf8(body) {
        Ok(s) => Ok(s.to_string()),
        Err(e) => Err(InputError::file(
            path,
            format!(
                "cannot read {what}: not UTF-8 text (invalid byte at offset {})",
                e.valid_up_to() + (bytes.len() - body.len())
            ),
        )),
    }
}

/// An I/O error in words, telling a missing file from a symbolic link loop.
fn describe(e: &std::io::Error, path: &Path) -> String {
    if e.kind() == std::io::ErrorKind::NotFound {
        // A dangling link is "not found" too; say so when the link itself exists.
        if std::fs::symlink_metadata(path).is_ok() {
            return "file not found (a symbolic link to a missing file)".into();
        }
        return "file not found".into();
    }
    #[cfg(unix)]
    if e.raw_os_error() == Some(40) {
        return "a loop of symbolic links".into();
    }
    e.to_string()
}

#[cfg(unix)]
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_fifo() {
        "a named pipe"
    } else if t.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn file_kind(_: &std::fs::Metadata) -> &'static str {
    "a special file"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_byte_order_mark_is_dropped() {
        let (_dir, p) = crate::util::paths::temp_path("bom.json");
        std::fs::write(&p, b"\xEF\xBB\xBF{}").unwrap();
        assert_eq!(read_text(&p, "scenario").unwrap(), "{}");
    }

    #[test]
    fn bad_paths_say_what_is_wrong() {
        let (dir, missing) = crate::util::paths::temp_path("missing.json");
        let folder = dir.path().to_path_buf();
        let latin1 = dir.path().join("latin1.json");
        std::fs::write(&latin1, b"{\"name\": \"caf\xE9\"}").unwrap();
        let mut cases = vec![
            (missing, "file not found"),
            (folder, "a folder, not a regular file"),
            (latin1, "not UTF-8 text (invalid byte at offset 13)"),
        ];
        #[cfg(unix)]
        {
            let a = dir.path().join("a.json");
            let b = dir.path().join("b.json");
            std::os::unix::fs::symlink(&b, &a).unwrap();
            std::os::unix::fs::symlink(&a, &b).unwrap();
            cases.push((a, "a loop of symbolic links"));
            cases.push(("/dev/zero".into(), "a character device, not a regular file"));
        }
        for (p, want) in cases {
            let e = read_text(&p, "scenario").unwrap_err().to_string();
            assert!(e.starts_with(&p.display().to_string()), "{e}");
            assert!(e.contains(want), "{want}: {e}");
        }
    }
}
