//! Loading user meshes from Wavefront OBJ files (tobj), with errors that name the file.

use std::path::Path;

use glam::Vec3;

use super::mesh::Mesh;
use crate::error::InputError;

/// Loads every model in `path` into one mesh. Polygons with more than three vertices are
/// triangulated by tobj; lines and points are skipped (they bound no surface), and a file with no
/// triangles left, or with out-of-range indices, is an error.
pub fn load_obj(path: &Path) -> Result<Mesh, InputError> {
    let file = crate::util::input::open(path, "OBJ file")?;
    let mut reader = std::io::BufReader::new(file);
    // A UTF-8 byte order mark would hide the first statement from the parser.
    use std::io::BufRead;
    if reader
        .fill_buf()
        .is_ok_and(|b| b.starts_with(b"\xEF\xBB\xBF"))
    {
        reader.consume(3);
    }
    parse_obj(&mut reader, path)
}

/// Parses OBJ text from `reader`; `path` names it in errors. Material libraries are not read
/// (only geometry matters here).
pub fn parse_obj(reader: &mut impl std::io::BufRead, path: &Path) -> Result<Mesh, InputError> {
    let err = |msg: String| InputError::file(path, msg);
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) =
        tobj::load_obj_buf(reader, &opts, |_| Ok((Vec::new(), Default::default())))
            .map_err(|e| err(format!("cannot parse OBJ: {e}")))?;
    let mut mesh = Mesh::default();
    for m in &models {
        let p = &m.mesh.positions;
        if p.len() % 3 != 0 {
            return Err(err(format!("model '{}': malformed positions", m.name)));
        }
        if m.mesh.indices.len() % 3 != 0 {
            return Err(err(format!(
                "model '{}': faces are not triangles (lines or points are not supported)",
                m.name
            )));
        }
        let n = (p.len() / 3) as u32;
        let mut part = Mesh::default();
        for (k, v) in p.chunks_exact(3).enumerate() {
            let q = Vec3::new(v[0], v[1], v[2]);
            if !q.is_finite() {
                return Err(err(format!(
                    "model '{}': vertex {} is not finite ({q})",
                    m.name,
                    k + 1
                )));
            }
            part.positions.push(q);
        }
        for (f, t) in m.mesh.indices.chunks_exact(3).enumerate() {
            if let Some(bad) = t.iter().find(|&&i| i >= n) {
                return Err(err(format!(
                    "model '{}': face {} uses vertex index {} but there are {} vertices",
                    m.name,
                    f + 1,
                    bad + 1,
                    n
                )));
            }
            part.triangles.push([t[0], t[1], t[2]]);
        }
        mesh.append(&part);
    }
    if mesh.triangles.is_empty() {
        return Err(err("no triangles in file".into()));
    }
    Ok(mesh)
}
