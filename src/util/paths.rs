//! File names made from user text (scenario names, a results file's `scenario`, a run's scene,
//! algorithm and backend) so that every path the product writes stays inside `--out`.
//!
//! Two rules, used everywhere a name becomes a path:
//!
//! - [`check_name`] refuses, as an input error naming the field and the value, a name that is
//!   empty, absolute, has a parent (`..`) or current (`.`) component, a path separator or a
//!   control character: such a name was meant as a path, and silently rewriting it would hide
//!   the mistake.
//! - [`slug`] turns any accepted name into one safe file name component: ASCII letters, digits,
//!   `-`, `_`, `.` and `+` are kept, every other character becomes `_`, a leading `.` becomes
//!   `_` (no hidden files, never `..`), and the result is at most [`MAX_SLUG`] bytes. A name
//!   that is already safe is its own slug, so existing folders keep their names; a name that
//!   had to change gets a short hash of the original appended, so two names that differ only in
//!   unsafe characters still get different folders.

use std::path::{Component, Path, PathBuf};

use crate::error::InputError;
use crate::util::hash::Fnv64;

/// Longest slug in bytes (well under the 255 bytes of a file name on common file systems, so a
/// slug can be combined with a prefix or an extension).
pub const MAX_SLUG: usize = 96;

/// Whether `c` is kept as is in a slug.
fn safe_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | '+')
}

/// `name` as one safe file name component of at most [`MAX_SLUG`] bytes (see the module docs).
pub fn slug(name: &str) -> String {
    slug_max(name, MAX_SLUG)
}

/// [`slug`] with another length limit, in bytes (at least 16; at most 255 for a file name).
pub fn slug_max(name: &str, max: usize) -> String {
    let max = max.clamp(16, 255);
    let mut s: String = name
        .chars()
        .map(|c| if safe_char(c) { c } else { '_' })
        .collect();
    if s.starts_with('.') {
        s.replace_range(0..1, "_");
    }
    if s.is_empty() {
        s.push('_');
    }
    if s == name && s.len() <= max {
        return s;
    }
    let hash = format!(
        "-{:08x}",
        Fnv64::default().bytes(name.as_bytes()).finish() as u32
    );
    // Every character of `s` is ASCII, so any byte index is a char boundary.
    s.truncate(max - hash.len());
    s + &hash
}

/// Refuses a name that is not a plain name: empty, absolute, with `.` or `..` components,
/// path separators or control characters. `field` names the JSON path or option in the error.
pub fn check_name(field: &str, name: &str) -> Result<(), InputError> {
    let why = if name.trim().is_empty() {
        Some("must not be empty")
    } else if name.starts_with('/') || name.starts_with('\\') {
        Some("must be a plain name, not an absolute path")
    } else if name.split(['/', '\\']).any(|c| c == ".." || c == ".") {
        Some("must be a plain name, without '.' or '..' path components")
    } else if name.contains(['/', '\\']) {
        Some("must be a plain name, without path separators ('/' or '\\')")
    } else if name.chars().any(char::is_control) {
        Some("must not contain control characters")
    } else {
        None
    };
    match why {
        Some(why) => Err(InputError::new(field, format!("{why}, got {name:?}"))),
        None => Ok(()),
    }
}

/// Whether `a` and `b` name one file or folder: the same one once links are resolved when it
/// exists, else the same absolute path once `.` and `..` are folded away.
pub fn same_file(a: &Path, b: &Path) -> bool {
    let resolved = |p: &Path| -> Option<PathBuf> {
        if let Ok(c) = p.canonicalize() {
            return Some(c);
        }
        let mut out = PathBuf::new();
        for c in std::path::absolute(p).ok()?.components() {
            match c {
                Component::CurDir => {}
                Component::ParentDir => {
                    out.pop();
                }
                c => out.push(c),
            }
        }
        Some(out)
    };
    matches!((resolved(a), resolved(b)), (Some(x), Some(y)) if x == y)
}

/// A new temporary folder and the path `name` in it (tests: the folder is removed when the
/// returned guard drops).
#[cfg(test)]
pub fn temp_path(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    (dir, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn safe_names_are_their_own_slug() {
        for n in [
            "ci",
            "paper-002-torus",
            "quick",
            "sphere-on-plane_pcss_cpu-model_l0.5",
        ] {
            assert_eq!(slug(n), n);
        }
    }

    #[test]
    fn slugs_are_one_plain_component() {
        for n in [
            "../../../x",
            "/etc/passwd",
            "..",
            ".",
            "",
            "a/b",
            "a\\b",
            "C:\\x",
            "nul\0byte",
            "Paper 002: fig. 7",
            "ü",
            &"long".repeat(100),
        ] {
            let s = slug(n);
            let p = std::path::Path::new(&s);
            let comps: Vec<_> = p.components().collect();
            assert_eq!(comps.len(), 1, "{n:?} -> {s:?}");
            assert!(matches!(comps[0], Component::Normal(_)), "{n:?} -> {s:?}");
            assert!(!s.starts_with('.') && s.len() <= MAX_SLUG, "{n:?} -> {s:?}");
            assert!(s.chars().all(safe_char), "{n:?} -> {s:?}");
        }
    }

    #[test]
    fn names_differing_in_unsafe_characters_get_different_slugs() {
        assert_ne!(slug("a b"), slug("a_b"));
        assert_ne!(slug("a/b"), slug("a:b"));
        assert_ne!(slug(&"x".repeat(200)), slug(&"x".repeat(201)));
    }

    #[test]
    fn path_like_names_are_refused_naming_the_field_and_value() {
        for n in [
            "../../../x",
            "/some/other/dir",
            "..",
            "a/../b",
            "a/b",
            "C:\\x",
            "",
            "a\nb",
        ] {
            let e = check_name("$.name", n).unwrap_err().to_string();
            assert!(e.starts_with("$.name: "), "{e}");
            assert!(e.contains(&format!("{n:?}")), "{e}");
        }
        for n in ["ci", "Paper 002: fig. 7", "a..b", "ü"] {
            check_name("$.name", n).unwrap();
        }
    }
}
