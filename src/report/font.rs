//! The font chart text is drawn with: a TrueType font found on the system, or DejaVu Sans
//! embedded in the binary (from the `dejavu` crate) when none is, so the report is always
//! written, on a fresh machine too.
//!
//! Text is rasterized by the pure-Rust `ab_glyph` (through plotters): no C font libraries.

use std::borrow::Cow;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::style::FontStyle;

use crate::error::{Error, Result};

/// The family name chart text uses.
pub const FAMILY: &str = "sans-serif";

/// System fonts tried in order when `SHADOWBENCH_FONT` is not set. On Debian,
/// `fonts-dejavu-core` provides the first.
pub const CANDIDATES: [&str; 6] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
];

/// Where the chart font comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    /// A font file (`SHADOWBENCH_FONT` or the first of [`CANDIDATES`] that exists).
    File(PathBuf),
    /// DejaVu Sans 2.37, built into the binary.
    Embedded,
}

/// Chooses the font: `env` (the value of `SHADOWBENCH_FONT`) when set, which must then name a
/// file; else the first of `candidates` that is a file; else the embedded font.
///
/// Errors: `SHADOWBENCH_FONT` names no file (an explicit choice is not silently replaced).
pub fn choose(env: Option<OsString>, candidates: &[&str]) -> std::result::Result<Source, String> {
    if let Some(p) = env {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(Source::File(p))
        } else {
            Err(format!(
                "SHADOWBENCH_FONT={}: no such font file",
                p.display()
            ))
        };
    }
    Ok(candidates
        .iter()
        .map(Path::new)
        .find(|p| p.is_file())
        .map_or(Source::Embedded, |p| Source::File(p.to_path_buf())))
}

/// The bytes of the font `source` names.
pub fn load(source: &Source) -> std::result::Result<Cow<'static, [u8]>, String> {
    match source {
        Source::Embedded => Ok(Cow::Borrowed(dejavu::sans::regular())),
        Source::File(p) => std::fs::read(p)
            .map(Cow::Owned)
            .map_err(|e| format!("chart font {}: {e}", p.display())),
    }
}

/// Registers the chart font under [`FAMILY`] once per process. Errors (an input error, exit 2):
/// `SHADOWBENCH_FONT` names no file, or one that is not a font.
pub fn ensure() -> Result<()> {
    static READY: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    READY
        .get_or_init(|| {
            let env = std::env::var_os("SHADOWBENCH_FONT");
            let named = if env.is_some() {
                "SHADOWBENCH_FONT: "
            } else {
                ""
            };
            let source = choose(env, &CANDIDATES)?;
            let bytes: &'static [u8] = match load(&source).map_err(|e| format!("{named}{e}"))? {
                Cow::Borrowed(b) => b,
                Cow::Owned(v) => Box::leak(v.into_boxed_slice()),
            };
            plotters::style::register_font(FAMILY, FontStyle::Normal, bytes).map_err(|_| {
                let what = match &source {
                    Source::File(p) => p.display().to_string(),
                    Source::Embedded => "DejaVu Sans (embedded)".into(),
                };
                format!("{named}chart font {what}: not a TrueType/OpenType font")
            })
        })
        .clone()
        // A font file that is missing or not a font: bad input (`SHADOWBENCH_FONT`, or the
        // system's font, which the variable can replace).
        .map_err(|message| {
            Error::Input(crate::error::InputError {
                file: None,
                field: None,
                message,
            })
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_a_system_font_the_embedded_one_is_used() {
        let (_dir, missing) = crate::util::paths::temp_path("none.ttf");
        let missing = missing.to_str().unwrap();
        assert_eq!(choose(None, &[missing]).unwrap(), Source::Embedded);
        // The embedded bytes are a TrueType font (sfnt version 1.0) with the glyph table
        // ab_glyph needs.
        let bytes = load(&Source::Embedded).unwrap();
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        assert!(bytes.windows(4).any(|w| w == b"glyf"));
    }

    #[test]
    fn a_system_font_is_preferred_and_an_explicit_one_must_exist() {
        let (dir, font) = crate::util::paths::temp_path("a.ttf");
        std::fs::write(&font, dejavu::sans::regular()).unwrap();
        let f = font.to_str().unwrap();
        assert_eq!(
            choose(None, &["/nonexistent/x.ttf", f]).unwrap(),
            Source::File(font.clone())
        );
        let e = choose(Some(dir.path().join("gone.ttf").into()), &[f]).unwrap_err();
        assert!(
            e.contains("SHADOWBENCH_FONT") && e.contains("gone.ttf"),
            "{e}"
        );
        assert_eq!(load(&Source::File(font)).unwrap(), dejavu::sans::regular());
    }
}
