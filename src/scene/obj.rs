//! Wavefront OBJ geometry: vertex positions and polygonal faces, with errors that name the file
//! and line.
//!
//! Only the polygonal geometry of the format is read (`v`, `f`, `o`/`g`; `vt`/`vn` are counted so
//! face references to them can be checked); materials do not matter for shadows. This is a small
//! reader of its own rather than `tobj` because tobj divides positions by the optional `w` (a
//! weight of rational curves in OBJ, not of polygon vertices), fans polygons from their first
//! vertex (wrong for concave ones), rejects a file for one non-UTF-8 byte anywhere, and reports
//! errors without a line number. Here:
//!
//! - `v x y z [w]` and `v x y z r g b`: the position is `x y z`; `w` and colours are ignored.
//! - `f`: `v`, `v/vt`, `v//vn` or `v/vt/vn` references; 1-based, negative ones relative to the
//!   vertices read so far; polygons of any size triangulated on their plane
//!   ([`super::polygon`]). A face with fewer than 3 vertices, an index 0, a vertex index out of
//!   range, or a self-intersecting polygon is an error naming its line; a polygon with no area
//!   is dropped with a warning, and references to texture coordinates or normals the file lacks
//!   are ignored with a warning (they do not shape shadows).
//! - `l` and `p` (lines and points bound no surface) and free-form statements are skipped with
//!   a warning; `mtllib` files that are missing give one warning per OBJ file.
//! - A UTF-8 byte-order mark is skipped; bytes that are not UTF-8 are tolerated anywhere but in
//!   the numbers of `v` and `f` statements (names are read lossily). `#` at the start of a word
//!   starts a comment; a line ending in `\` continues on the next.
//! - Only vertices that faces use are kept (in file order), so stray vertices neither widen the
//!   scene's bounds nor fail the finiteness check.

use std::path::Path;

use glam::Vec3;

use super::load::MeshFile;
use super::mesh::Mesh;
use super::polygon::{self, PolygonFault};
use crate::error::InputError;

/// Loads the geometry of the OBJ file `path` (all of it, or only the faces under the `o`/`g`
/// name `group`).
pub fn load_obj(path: &Path, group: Option<&str>) -> Result<MeshFile, InputError> {
    let bytes = super::load::read_file(path)?;
    let mut file = parse_obj(&bytes, path, group)?;
    let missing = missing_material_libraries(&bytes, path.parent().unwrap_or(Path::new(".")));
    if !missing.is_empty() {
        file.warnings.push(format!(
            "{}: material librar{} {} not found (materials do not affect shadows; geometry loaded)",
            path.display(),
            if missing.len() == 1 { "y" } else { "ies" },
            missing
                .iter()
                .map(|m| format!("'{m}'"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok(file)
}

/// One `f` statement: where its vertex references start in the flat list, its line and group.
struct Face {
    start: usize,
    line: usize,
    group: usize,
}

/// The logical lines of an OBJ file: (1-based number of the first physical line, bytes without
/// comment, carriage return or continuation backslashes).
fn logical_lines(bytes: &[u8]) -> Vec<(usize, Vec<u8>)> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut out = Vec::new();
    let mut pending: Option<(usize, Vec<u8>)> = None;
    for (k, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let (number, mut text) = pending.take().unwrap_or((k + 1, Vec::new()));
        text.extend_from_slice(raw);
        if text.last() == Some(&b'\\') {
            text.pop();
            text.push(b' ');
            pending = Some((number, text));
            continue;
        }
        // A comment starts with `#` at the start of a word ("1.#IND" is a bad number, not a
        // number and a comment).
        if let Some(c) = (0..text.len())
            .find(|&i| text[i] == b'#' && (i == 0 || text[i - 1].is_ascii_whitespace()))
        {
            text.truncate(c);
        }
        out.push((number, text));
    }
    out.extend(pending);
    out
}

fn words(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|w| !w.is_empty())
}

fn lossy(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Parses OBJ bytes; `path` names the file in errors. See the module docs for what is read.
pub fn parse_obj(bytes: &[u8], path: &Path, group: Option<&str>) -> Result<MeshFile, InputError> {
    let at = |line: usize, msg: String| InputError::file(path, format!("line {line}: {msg}"));
    let mut positions: Vec<Vec3> = Vec::new();
    let mut position_line: Vec<usize> = Vec::new();
    let (mut texcoords, mut normals) = (0usize, 0usize);
    let mut refs: Vec<u32> = Vec::new();
    // Positive indices may refer to vertices defined later: they are checked at the end, for
    // the faces used.
    let mut faces: Vec<Face> = Vec::new();
    let mut groups: Vec<String> = vec![String::new()];
    let mut current_group = 0usize;
    let (mut lines_skipped, mut points_skipped, mut freeform_skipped) = (0usize, 0usize, 0usize);
    let (mut max_vt, mut max_vn) = ((0usize, 0usize), (0usize, 0usize));
    for (n, text) in logical_lines(bytes) {
        let mut w = words(&text);
        let Some(keyword) = w.next() else { continue };
        match keyword {
            b"v" => {
                let mut xyz = [0.0f32; 3];
                for (k, c) in xyz.iter_mut().enumerate() {
                    let word = w.next().ok_or_else(|| {
                        at(n, format!("vertex needs three coordinates x y z, got {k}"))
                    })?;
                    *c = std::str::from_utf8(word)
                        .ok()
                        .and_then(|s| s.parse::<f32>().ok())
                        .ok_or_else(|| {
                            at(
                                n,
                                format!("vertex coordinate '{}' is not a number", lossy(word)),
                            )
                        })?;
                }
                positions.push(Vec3::from(xyz));
                position_line.push(n);
            }
            b"vt" => texcoords += 1,
            b"vn" => normals += 1,
            b"f" | b"fo" => {
                let start = refs.len();
                for word in w {
                    let mut parts = word.split(|&b| b == b'/');
                    let v = parts.next().unwrap_or_default();
                    let resolve = |part: &[u8],
                                   what: &str,
                                   count: usize|
                     -> Result<usize, InputError> {
                        let k: i64 = std::str::from_utf8(part)
                            .ok()
                            .and_then(|s| s.parse().ok())
                            .ok_or_else(|| {
                                at(
                                    n,
                                    format!("{what} index '{}' is not an integer", lossy(part)),
                                )
                            })?;
                        match k {
                            0 => Err(at(n, format!("{what} index 0 (OBJ indices start at 1)"))),
                            k if k > 0 => usize::try_from(k - 1)
                                .map_err(|_| at(n, format!("{what} index {k} is out of range"))),
                            k => count.checked_sub(k.unsigned_abs() as usize).ok_or_else(|| {
                                at(
                                    n,
                                    format!(
                                        "relative {what} index {k} reaches before the first {what} \
                                         ({count} read so far)"
                                    ),
                                )
                            }),
                        }
                    };
                    let vi = resolve(v, "vertex", positions.len())?;
                    let vi = u32::try_from(vi)
                        .map_err(|_| at(n, format!("vertex index {} is out of range", vi + 1)))?;
                    refs.push(vi);
                    // The largest texture coordinate and normal referenced, with its line:
                    // checked at the end, as they may be defined after the face.
                    if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                        let ti = resolve(t, "texture coordinate", texcoords)?;
                        if ti >= max_vt.0 {
                            max_vt = (ti + 1, n);
                        }
                    }
                    if let Some(nn) = parts.next().filter(|t| !t.is_empty()) {
                        let ni = resolve(nn, "normal", normals)?;
                        if ni >= max_vn.0 {
                            max_vn = (ni + 1, n);
                        }
                    }
                }
                let count = refs.len() - start;
                if count < 3 {
                    return Err(at(
                        n,
                        format!("a face needs at least 3 vertices, got {count}"),
                    ));
                }
                faces.push(Face {
                    start,
                    line: n,
                    group: current_group,
                });
            }
            b"l" => lines_skipped += 1,
            b"p" => points_skipped += 1,
            b"curv" | b"curv2" | b"surf" => freeform_skipped += 1,
            b"o" | b"g" => {
                let rest = text
                    .iter()
                    .position(|b| !b.is_ascii_whitespace())
                    .map(|s| &text[s + keyword.len()..])
                    .unwrap_or_default();
                let name = lossy(rest).trim().to_string();
                current_group = match groups.iter().position(|g| *g == name) {
                    Some(i) => i,
                    None => {
                        groups.push(name);
                        groups.len() - 1
                    }
                };
            }
            _ => {}
        }
    }
    // Texture coordinates and normals do not shape shadows: references to missing ones are
    // ignored, and said once.
    let mut warnings = Vec::new();
    for ((max, line), count, what) in [
        (max_vt, texcoords, "texture coordinate"),
        (max_vn, normals, "normal"),
    ] {
        if max > count {
            warnings.push(format!(
                "{}: line {line}: faces refer to {what} {max} but the file has {count} (ignored: \
                 only positions shape shadows)",
                path.display()
            ));
        }
    }
    let selected: Vec<usize> = match group {
        None => (0..faces.len()).collect(),
        Some(g) => {
            let Some(gi) = groups.iter().position(|n| n == g) else {
                let named: Vec<&str> = groups
                    .iter()
                    .filter(|n| !n.is_empty())
                    .map(String::as_str)
                    .collect();
                return Err(InputError::file(
                    path,
                    format!(
                        "no object or group named '{g}' (the file has: {})",
                        if named.is_empty() {
                            "none".to_string()
                        } else {
                            named.join(", ")
                        }
                    ),
                ));
            };
            (0..faces.len()).filter(|&f| faces[f].group == gi).collect()
        }
    };
    // Check references and finiteness of what is used; keep used vertices in file order.
    let mut remap = vec![u32::MAX; positions.len()];
    for &f in &selected {
        let face = &faces[f];
        let end = faces.get(f + 1).map_or(refs.len(), |next| next.start);
        for &v in &refs[face.start..end] {
            let Some(p) = positions.get(v as usize) else {
                return Err(at(
                    face.line,
                    format!(
                        "face uses vertex {} but the file has {} vertices",
                        v as u64 + 1,
                        positions.len()
                    ),
                ));
            };
            if !p.is_finite() {
                return Err(at(
                    position_line[v as usize],
                    format!("vertex {} is not finite ({p})", v + 1),
                ));
            }
            remap[v as usize] = 0;
        }
    }
    let mut mesh = Mesh::default();
    for (i, r) in remap.iter_mut().enumerate() {
        if *r == 0 {
            *r = mesh.positions.len() as u32;
            mesh.positions.push(positions[i]);
        }
    }
    let mut dropped = Vec::new();
    let mut poly = Vec::new();
    for &f in &selected {
        let face = &faces[f];
        let end = faces.get(f + 1).map_or(refs.len(), |next| next.start);
        poly.clear();
        poly.extend(refs[face.start..end].iter().map(|&v| remap[v as usize]));
        match polygon::triangulate(&mesh.positions, &poly) {
            Ok(t) => mesh.triangles.extend(t),
            Err(PolygonFault::Degenerate) => dropped.push(face.line),
            Err(fault) => {
                return Err(at(
                    face.line,
                    format!("polygon of {} vertices {fault}", poly.len()),
                ))
            }
        }
    }
    if !dropped.is_empty() {
        warnings.push(format!(
            "{}: dropped {} polygon{} with no area (line{} {})",
            path.display(),
            dropped.len(),
            if dropped.len() == 1 { "" } else { "s" },
            if dropped.len() == 1 { "" } else { "s" },
            summarize_lines(&dropped)
        ));
    }
    let skipped: Vec<String> = [
        (lines_skipped, "line element"),
        (points_skipped, "point element"),
        (freeform_skipped, "free-form curve/surface"),
    ]
    .iter()
    .filter(|(k, _)| *k > 0)
    .map(|(k, what)| format!("{k} {what}{}", if *k == 1 { "" } else { "s" }))
    .collect();
    if !skipped.is_empty() {
        warnings.push(format!(
            "{}: skipped {} (they bound no surface)",
            path.display(),
            skipped.join(", ")
        ));
    }
    if mesh.triangles.is_empty() {
        return Err(InputError::file(
            path,
            match group {
                Some(g) => format!("no triangles in object or group '{g}'"),
                None => "no triangles in file".into(),
            },
        ));
    }
    Ok(MeshFile { mesh, warnings })
}

/// "3, 7, 12, … (40 in all)": the first few line numbers of a list.
fn summarize_lines(lines: &[usize]) -> String {
    const SHOWN: usize = 5;
    let head: Vec<String> = lines.iter().take(SHOWN).map(|l| l.to_string()).collect();
    if lines.len() > SHOWN {
        format!("{}, … ({} in all)", head.join(", "), lines.len())
    } else {
        head.join(", ")
    }
}

/// The `mtllib` files an OBJ names that do not exist beside it. Names are separated by spaces;
/// `\ ` escapes a space inside a name, and a whole rest of line that names an existing file is
/// taken as one name.
fn missing_material_libraries(bytes: &[u8], dir: &Path) -> Vec<String> {
    let mut missing = Vec::new();
    for (_, text) in logical_lines(bytes) {
        let mut w = words(&text);
        if w.next() != Some(b"mtllib".as_slice()) {
            continue;
        }
        let rest = lossy(&text);
        let rest = rest.trim_start()["mtllib".len()..].trim();
        if rest.is_empty() || dir.join(rest).is_file() {
            continue;
        }
        let mut names = Vec::new();
        let mut cur = String::new();
        let mut chars = rest.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '\\' if chars.peek().is_some_and(|c| c.is_whitespace()) => {
                    cur.push(chars.next().expect("peeked"));
                }
                c if c.is_whitespace() => {
                    if !cur.is_empty() {
                        names.push(std::mem::take(&mut cur));
                    }
                }
                c => cur.push(c),
            }
        }
        if !cur.is_empty() {
            names.push(cur);
        }
        for name in names {
            if !dir.join(&name).is_file() && !missing.contains(&name) {
                missing.push(name);
            }
        }
    }
    missing
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &[u8]) -> Result<MeshFile, InputError> {
        parse_obj(text, Path::new("t.obj"), None)
    }

    fn diagonal(m: &Mesh) -> f32 {
        m.bounds().diagonal()
    }

    #[test]
    fn w_is_ignored_and_colours_too() {
        let m = parse(b"v 0 0 0 0.1\nv 2 0 0 0.5\nv 0 2 0 1 0 0\nf 1 2 3\n").unwrap();
        assert_eq!(
            m.mesh.positions,
            vec![
                Vec3::ZERO,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0)
            ]
        );
        assert!((diagonal(&m.mesh) - 8f32.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn bom_latin1_crlf_and_continuations_are_tolerated() {
        let text = b"\xEF\xBB\xBFv 0 0 0\r\n# caf\xE9\r\ng caf\xE9\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 \\\r\n 2 3\r\n";
        let m = parse(text).unwrap();
        assert_eq!(m.mesh.triangles, vec![[0, 1, 2]]);
        let g = parse_obj(text, Path::new("t.obj"), Some("caf\u{FFFD}")).unwrap();
        assert_eq!(g.mesh.triangles.len(), 1);
    }

    #[test]
    fn relative_indices_and_unused_vertices() {
        let m = parse(b"v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n").unwrap();
        assert_eq!(m.mesh.positions.len(), 3);
        assert_eq!(m.mesh.positions[0], Vec3::ZERO);
    }

    #[test]
    fn errors_name_the_line() {
        for (text, want) in [
            (&b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"[..], "line 4"),
            (
                b"v 0 0 0\nv 1 0 0\nf 1 2\n",
                "line 3: a face needs at least 3",
            ),
            (
                b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
                "line 4: vertex index 0",
            ),
            (b"v 0 0\n", "line 1: vertex needs three"),
            (b"v 0 0 x\xff\n", "line 1: vertex coordinate"),
            (b"f -4 -3 -2", "line 1: relative vertex index -4"),
            (
                b"vt 0 0\nv 0 0 0\nf 1/-1 1/-1 1/-2",
                "line 3: relative texture",
            ),
            (
                b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
                "line 1: vertex 1 is not finite",
            ),
            (
                b"v 0 0 0\nv 1 1 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 4\n",
                "line 5: polygon of 4 vertices intersects itself",
            ),
            (b"v 0 0 0\nl 1 1\n", "no triangles"),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.starts_with("t.obj: "), "{e}");
            assert!(e.contains(want), "{e} (wanted {want})");
        }
    }

    #[test]
    fn skipped_and_dropped_elements_are_warned() {
        let m =
            parse(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nl 1 2\np 1\nf 1 2 4 2\n").unwrap();
        assert_eq!(m.mesh.triangles.len(), 1);
        assert_eq!(m.warnings.len(), 2, "{:?}", m.warnings);
        assert!(m.warnings[0].contains("dropped 1 polygon with no area (line 8)"));
        assert!(m.warnings[1].contains("1 line element, 1 point element"));
    }

    #[test]
    fn groups_select_faces() {
        let text = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\no a\nf 1 2 3\no b\nf 2 3 4\nf 1 3 4\n";
        let a = parse_obj(text, Path::new("t.obj"), Some("a")).unwrap();
        assert_eq!(a.mesh.triangles.len(), 1);
        assert_eq!(a.mesh.positions.len(), 3);
        let b = parse_obj(text, Path::new("t.obj"), Some("b")).unwrap();
        assert_eq!(b.mesh.triangles.len(), 2);
        let e = parse_obj(text, Path::new("t.obj"), Some("c")).unwrap_err();
        assert!(e.message.contains("no object or group named 'c'"), "{e}");
        assert!(e.message.contains("a, b"), "{e}");
    }

    #[test]
    fn missing_libraries_are_found() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a b.mtl"), "").unwrap();
        std::fs::write(dir.path().join("c.mtl"), "").unwrap();
        let m = missing_material_libraries(
            b"mtllib a\\ b.mtl c.mtl gone.mtl\nmtllib a b.mtl\nmtllib gone.mtl x\\ y.mtl\n",
            dir.path(),
        );
        assert_eq!(m, vec!["gone.mtl".to_string(), "x y.mtl".to_string()]);
    }
}
