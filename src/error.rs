//! Error types. Bad input is reported with the file, the JSON path and the offending value, and
//! maps to exit code 2; everything else (a run that failed, a missing GPU) maps to 1.

use std::fmt;
use std::path::{Path, PathBuf};

/// A problem with what the user gave us: a scenario, an OBJ file, a command-line parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct InputError {
    pub file: Option<PathBuf>,
    /// JSON path (`$.sweep.light_size[2]`) or option name (`--light-size`).
    pub field: Option<String>,
    pub message: String,
}

impl InputError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> InputError {
        InputError {
            file: None,
            field: Some(field.into()),
            message: message.into(),
        }
    }

    pub fn file(file: &Path, message: impl Into<String>) -> InputError {
        InputError {
            file: Some(file.to_path_buf()),
            field: None,
            message: message.into(),
        }
    }

    /// Checks that `value`, the field at JSON path `field`, lies in `range`; the error reads
    /// "must be in lo..=hi, got value".
    pub fn check_range<T: PartialOrd + fmt::Display>(
        field: impl Into<String>,
        value: T,
        range: std::ops::RangeInclusive<T>,
    ) -> Result<(), InputError> {
        if range.contains(&value) {
            return Ok(());
        }
        Err(InputError::new(
            field,
            format!(
                "must be in {}..={}, got {}",
                range.start(),
                range.end(),
                compact(value.to_string())
            ),
        ))
    }

    /// Checks that `value`, the field at JSON path `field`, is a finite number ≥ 0.
    pub fn check_non_negative(field: impl Into<String>, value: f32) -> Result<(), InputError> {
        if value.is_finite() && value >= 0.0 {
            return Ok(());
        }
        Err(InputError::new(
            field,
            format!("must be a finite number >= 0, got {value}"),
        ))
    }

    pub fn in_file(mut self, file: &Path) -> InputError {
        if self.file.is_none() {
            self.file = Some(file.to_path_buf());
        }
        self
    }
}

/// A number as the user can read it: one of more than 12 characters (`1e30` printed in full has
/// 31) in scientific notation, any other text unchanged.
fn compact(text: String) -> String {
    match text.parse::<f64>() {
        Ok(v) if text.len() > 12 => format!("{v:e}"),
        _ => text,
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}: ", file.display())?;
        }
        if let Some(field) = &self.field {
            write!(f, "{field}: ")?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for InputError {}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{0}")]
    Input(#[from] InputError),
    /// The algorithm cannot run on this backend or light.
    #[error("{0}")]
    Unsupported(String),
    /// No usable GPU, or a GPU operation failed.
    #[error("wgpu: {0}")]
    Gpu(String),
    /// A run would exceed a configured resource limit.
    #[error("resource limit: {0}")]
    Resource(String),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{0}")]
    Other(String),
}

impl Error {
    pub fn io(path: &Path, source: std::io::Error) -> Error {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// Process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input(_) => 2,
            _ => 1,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The closest candidate by edit distance, for "did you mean" hints.
pub fn closest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (edit_distance(word, c), c))
        .filter(|(d, c)| *d <= (c.len() / 2).max(2))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// "unknown X 'y'; expected one of ...", with the closest suggestion first.
pub fn unknown_name(what: &str, word: &str, candidates: &[&str]) -> String {
    let hint = closest(word, candidates.iter().copied())
        .map(|c| format!(" (did you mean '{c}'?)"))
        .unwrap_or_default();
    format!(
        "unknown {what} '{word}'{hint}; expected one of: {}",
        candidates.join(", ")
    )
}

/// The `names` joined by ", ", or "none" without any: for messages that list what is there.
pub fn names_or_none(names: &[&str]) -> String {
    if names.is_empty() {
        "none".to_string()
    } else {
        names.join(", ")
    }
}

fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// The message of a caught panic (`"unknown panic"` when it carried none).
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "unknown panic".into())
}
