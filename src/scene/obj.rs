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
use crate::error::{names_or_none, InputError};

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
    let mut reader = ObjReader::new(path);
    for (n, text) in logical_lines(bytes) {
        reader.statement(n, &text)?;
    }
    let mut warnings = reader.missing_reference_warnings();
    let selected = reader.select_faces(group)?;
    let (mesh, dropped) = reader.build_mesh(&selected)?;
    warnings.extend(dropped_warning(path, &dropped));
    warnings.extend(reader.skipped_warning());
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

/// An error at line `line` of the OBJ file `path`.
fn line_error(path: &Path, line: usize, msg: String) -> InputError {
    InputError::file(path, format!("line {line}: {msg}"))
}

/// Resolves one OBJ index `part` (1-based, or negative: relative to the `count` elements read
/// so far) of a `what` to a 0-based index; errors name line `line` of `path`.
fn resolve_index(
    part: &[u8],
    what: &str,
    count: usize,
    path: &Path,
    line: usize,
) -> Result<usize, InputError> {
    let at = |msg: String| line_error(path, line, msg);
    let k: i64 = std::str::from_utf8(part)
        .ok()
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| at(format!("{what} index '{}' is not an integer", lossy(part))))?;
    match k {
        0 => Err(at(format!("{what} index 0 (OBJ indices start at 1)"))),
        k if k > 0 => {
            usize::try_from(k - 1).map_err(|_| at(format!("{what} index {k} is out of range")))
        }
        k => count.checked_sub(k.unsigned_abs() as usize).ok_or_else(|| {
            at(format!(
                "relative {what} index {k} reaches before the first {what} ({count} read so far)"
            ))
        }),
    }
}

/// The statements of one OBJ file as read, before faces are selected and checked.
struct ObjReader<'a> {
    path: &'a Path,
    positions: Vec<Vec3>,
    /// The line of each position, for the finiteness error.
    position_line: Vec<usize>,
    texcoords: usize,
    normals: usize,
    /// The vertex references of all faces, one after another (see [`Face::start`]). Positive
    /// indices may refer to vertices defined later: they are checked at the end, for the faces
    /// used.
    refs: Vec<u32>,
    faces: Vec<Face>,
    /// The `o`/`g` names in order of first use; 0 is the unnamed group before any.
    groups: Vec<String>,
    current_group: usize,
    /// Counts of skipped line elements, point elements and free-form statements.
    skipped: [usize; 3],
    /// The largest texture coordinate and normal referenced (1-based), with its line: checked
    /// at the end, as they may be defined after the face.
    max_vt: (usize, usize),
    max_vn: (usize, usize),
}

impl<'a> ObjReader<'a> {
    fn new(path: &'a Path) -> Self {
        ObjReader {
            path,
            positions: Vec::new(),
            position_line: Vec::new(),
            texcoords: 0,
            normals: 0,
            refs: Vec::new(),
            faces: Vec::new(),
            groups: vec![String::new()],
            current_group: 0,
            skipped: [0; 3],
            max_vt: (0, 0),
            max_vn: (0, 0),
        }
    }

    /// Reads one logical line `text` (line number `n`).
    fn statement(&mut self, n: usize, text: &[u8]) -> Result<(), InputError> {
        let mut w = words(text);
        let Some(keyword) = w.next() else {
            return Ok(());
        };
        match keyword {
            b"v" => self.vertex(n, w)?,
            b"vt" => self.texcoords += 1,
            b"vn" => self.normals += 1,
            b"f" | b"fo" => self.face(n, w)?,
            b"l" => self.skipped[0] += 1,
            b"p" => self.skipped[1] += 1,
            b"curv" | b"curv2" | b"surf" => self.skipped[2] += 1,
            b"o" | b"g" => self.group(text, keyword.len()),
            _ => {}
        }
        Ok(())
    }

    /// `v x y z ...`: the position is the first three words.
    fn vertex<'w>(
        &mut self,
        n: usize,
        mut w: impl Iterator<Item = &'w [u8]>,
    ) -> Result<(), InputError> {
        let mut xyz = [0.0f32; 3];
        for (k, c) in xyz.iter_mut().enumerate() {
            let word = w.next().ok_or_else(|| {
                line_error(
                    self.path,
                    n,
                    format!("vertex needs three coordinates x y z, got {k}"),
                )
            })?;
            *c = std::str::from_utf8(word)
                .ok()
                .and_then(|s| s.parse::<f32>().ok())
                .ok_or_else(|| {
                    line_error(
                        self.path,
                        n,
                        format!("vertex coordinate '{}' is not a number", lossy(word)),
                    )
                })?;
        }
        self.positions.push(Vec3::from(xyz));
        self.position_line.push(n);
        Ok(())
    }

    /// `f v/vt/vn ...`: appends the vertex references and notes the largest texture coordinate
    /// and normal referenced.
    fn face<'w>(&mut self, n: usize, w: impl Iterator<Item = &'w [u8]>) -> Result<(), InputError> {
        let start = self.refs.len();
        for word in w {
            let mut parts = word.split(|&b| b == b'/');
            let v = parts.next().unwrap_or_default();
            let vi = resolve_index(v, "vertex", self.positions.len(), self.path, n)?;
            let vi = u32::try_from(vi).map_err(|_| {
                line_error(
                    self.path,
                    n,
                    format!("vertex index {} is out of range", vi + 1),
                )
            })?;
            self.refs.push(vi);
            if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                let ti = resolve_index(t, "texture coordinate", self.texcoords, self.path, n)?;
                if ti >= self.max_vt.0 {
                    self.max_vt = (ti + 1, n);
                }
            }
            if let Some(nn) = parts.next().filter(|t| !t.is_empty()) {
                let ni = resolve_index(nn, "normal", self.normals, self.path, n)?;
                if ni >= self.max_vn.0 {
                    self.max_vn = (ni + 1, n);
                }
            }
        }
        let count = self.refs.len() - start;
        if count < 3 {
            return Err(line_error(
                self.path,
                n,
                format!("a face needs at least 3 vertices, got {count}"),
            ));
        }
        self.faces.push(Face {
            start,
            line: n,
            group: self.current_group,
        });
        Ok(())
    }

    /// `o name` / `g name`: the rest of the line (after the keyword of `keyword_len` bytes)
    /// names the group of the faces that follow.
    fn group(&mut self, text: &[u8], keyword_len: usize) {
        let rest = text
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .map(|s| &text[s + keyword_len..])
            .unwrap_or_default();
        let name = lossy(rest).trim().to_string();
        self.current_group = match self.groups.iter().position(|g| *g == name) {
            Some(i) => i,
            None => {
                self.groups.push(name);
                self.groups.len() - 1
            }
        };
    }

    /// Texture coordinates and normals do not shape shadows: references to missing ones are
    /// ignored, and said once.
    fn missing_reference_warnings(&self) -> Vec<String> {
        [
            (self.max_vt, self.texcoords, "texture coordinate"),
            (self.max_vn, self.normals, "normal"),
        ]
        .into_iter()
        .filter(|((max, _), count, _)| max > count)
        .map(|((max, line), count, what)| {
            format!(
                "{}: line {line}: faces refer to {what} {max} but the file has {count} (ignored: \
                 only positions shape shadows)",
                self.path.display()
            )
        })
        .collect()
    }

    /// The indices of the faces under the `o`/`g` name `group` (all faces without one).
    fn select_faces(&self, group: Option<&str>) -> Result<Vec<usize>, InputError> {
        let Some(g) = group else {
            return Ok((0..self.faces.len()).collect());
        };
        let Some(gi) = self.groups.iter().position(|n| n == g) else {
            let named: Vec<&str> = self
                .groups
                .iter()
                .filter(|n| !n.is_empty())
                .map(String::as_str)
                .collect();
            return Err(InputError::file(
                self.path,
                format!(
                    "no object or group named '{g}' (the file has: {})",
                    names_or_none(&named)
                ),
            ));
        };
        Ok((0..self.faces.len())
            .filter(|&f| self.faces[f].group == gi)
            .collect())
    }

    /// The vertex references of face `f`.
    fn face_refs(&self, f: usize) -> &[u32] {
        let end = self
            .faces
            .get(f + 1)
            .map_or(self.refs.len(), |next| next.start);
        &self.refs[self.faces[f].start..end]
    }

    /// The mesh of the `selected` faces: the vertices they use (checked to exist and be finite,
    /// kept in file order) and their triangulation; also the lines of faces dropped for having
    /// no area.
    fn build_mesh(&self, selected: &[usize]) -> Result<(Mesh, Vec<usize>), InputError> {
        let mut remap = vec![u32::MAX; self.positions.len()];
        for &f in selected {
            for &v in self.face_refs(f) {
                let Some(p) = self.positions.get(v as usize) else {
                    return Err(line_error(
                        self.path,
                        self.faces[f].line,
                        format!(
                            "face uses vertex {} but the file has {} vertices",
                            v as u64 + 1,
                            self.positions.len()
                        ),
                    ));
                };
                if !p.is_finite() {
                    return Err(line_error(
                        self.path,
                        self.position_line[v as usize],
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
                mesh.positions.push(self.positions[i]);
            }
        }
        let mut dropped = Vec::new();
        let mut poly = Vec::new();
        for &f in selected {
            poly.clear();
            poly.extend(self.face_refs(f).iter().map(|&v| remap[v as usize]));
            match polygon::triangulate(&mesh.positions, &poly) {
                Ok(t) => mesh.triangles.extend(t),
                Err(PolygonFault::Degenerate) => dropped.push(self.faces[f].line),
                Err(fault) => {
                    return Err(line_error(
                        self.path,
                        self.faces[f].line,
                        format!("polygon of {} vertices {fault}", poly.len()),
                    ))
                }
            }
        }
        Ok((mesh, dropped))
    }

    /// The warning for skipped line, point and free-form elements, if any.
    fn skipped_warning(&self) -> Option<String> {
        let skipped: Vec<String> = self
            .skipped
            .iter()
            .zip(["line element", "point element", "free-form curve/surface"])
            .filter(|(k, _)| **k > 0)
            .map(|(k, what)| format!("{k} {what}{}", if *k == 1 { "" } else { "s" }))
            .collect();
        (!skipped.is_empty()).then(|| {
            format!(
                "{}: skipped {} (they bound no surface)",
                self.path.display(),
                skipped.join(", ")
            )
        })
    }
}

/// The warning for polygons with no area dropped at lines `dropped`, if any.
fn dropped_warning(path: &Path, dropped: &[usize]) -> Option<String> {
    let s = if dropped.len() == 1 { "" } else { "s" };
    (!dropped.is_empty()).then(|| {
        format!(
            "{}: dropped {} polygon{s} with no area (line{s} {})",
            path.display(),
            dropped.len(),
            summarize_lines(dropped)
        )
    })
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
