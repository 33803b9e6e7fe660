//! glTF 2.0 geometry (`.gltf` with external or embedded buffers, and `.glb`) through the `gltf`
//! crate: the triangles of every mesh primitive of the default scene (or the first scene), in
//! world coordinates with the node hierarchy's transforms applied.
//!
//! - Primitive modes `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN`, indexed (u8/u16/u32) or
//!   not. `POINTS` and the line modes bound no surface and are skipped with a warning.
//! - Positions as `f32`, or, under `KHR_mesh_quantization`, as (normalized) i8/u8/i16/u16,
//!   dequantized by the extension's rules (the node transform carries the dequantization scale).
//! - A node whose transform mirrors (negative determinant) has its triangles' winding flipped,
//!   as glTF prescribes.
//! - Not read: sparse accessors (an input error), morph targets and skins (the bind pose is
//!   used), materials.

use std::collections::HashSet;
use std::path::Path;

use glam::{Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::load::MeshFile;
use super::mesh::Mesh;
use crate::error::{names_or_none, InputError};

/// Loads the default scene's triangles of the glTF file `path`; with `node`, only those of the
/// node of that name and its descendants.
pub fn load_gltf(path: &Path, node: Option<&str>) -> Result<MeshFile, InputError> {
    parse_gltf(&super::load::read_file(path)?, path, node)
}

/// [`load_gltf`] of the bytes of a `.gltf` or `.glb` file; `path` names it in errors and
/// locates its external buffers.
pub fn parse_gltf(bytes: &[u8], path: &Path, node: Option<&str>) -> Result<MeshFile, InputError> {
    let err = |m: String| InputError::file(path, m);
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| err(format!("cannot parse glTF: {e}")))?;
    // Draco-compressed primitives keep their data in the extension, which is not decoded here:
    // named, rather than reported as the accessors' missing data.
    let draco = "KHR_draco_mesh_compression";
    let required = document.extensions_required().any(|e| e == draco);
    let used = document.extensions_used().any(|e| e == draco);
    let checked = validate(&document);
    if required || (used && checked.is_err()) {
        return Err(err(format!(
            "meshes compressed with {draco} are not supported (decompress the file, e.g. \
             `gltf-transform copy IN OUT` or Blender's glTF export without Draco)"
        )));
    }
    checked.map_err(err)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = read_buffers(&document, base, blob).map_err(err)?;
    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| err("the file has no scene".into()))?;
    let mut out = MeshFile::default();
    let mut visited = HashSet::new();
    let mut stack: Vec<(gltf::Node, Mat4, bool)> = scene
        .nodes()
        .map(|n| (n, Mat4::IDENTITY, node.is_none()))
        .collect();
    stack.reverse();
    let mut found = node.is_none();
    while let Some((n, parent, selected)) = stack.pop() {
        if !visited.insert(n.index()) {
            return Err(err(format!(
                "node {} is reached twice: the node hierarchy is not a tree",
                n.index()
            )));
        }
        let world = parent * Mat4::from_cols_array_2d(&n.transform().matrix());
        let selected = selected || node.is_some_and(|want| n.name() == Some(want));
        found |= selected;
        if let (Some(mesh), true) = (n.mesh(), selected) {
            let name = mesh
                .name()
                .or(n.name())
                .map(|s| format!("'{s}'"))
                .unwrap_or_else(|| format!("{}", mesh.index()));
            for p in mesh.primitives() {
                let what = format!("mesh {name} primitive {}", p.index());
                match primitive(&p, &buffers, &what).map_err(err)? {
                    Some(part) => {
                        if !world.is_finite() {
                            return Err(err(format!(
                                "node {}: transform is not finite",
                                n.index()
                            )));
                        }
                        out.mesh.append(&part.transformed(world));
                    }
                    None => out.warnings.push(format!(
                        "{}: skipped {what}: mode {:?} bounds no surface",
                        path.display(),
                        p.mode()
                    )),
                }
            }
        }
        let children: Vec<_> = n.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world, selected));
        }
    }
    if !found {
        let names: Vec<&str> = document.nodes().filter_map(|n| n.name()).collect();
        return Err(err(format!(
            "no node named '{}' in the default scene (named nodes: {})",
            node.unwrap_or_default(),
            names_or_none(&names)
        )));
    }
    if out.mesh.triangles.is_empty() {
        return Err(err("no triangles in the default scene".into()));
    }
    Ok(out)
}

/// The data of every buffer: the GLB's binary chunk, a data URI, or a file beside `base`'s
/// glTF of which only the declared `byteLength` is read (a buffer file may be any size; a
/// 40 GB file named by a 44-byte buffer reads 44 bytes). A `byteLength` over the memory limit
/// ([`crate::harness::limits::process_limit`]), a missing or short file, are errors naming
/// the buffer.
fn read_buffers(
    document: &gltf::Document,
    base: &Path,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<gltf::buffer::Data>, String> {
    use std::io::Read;
    let limit = crate::harness::limits::process_limit();
    let mut out = Vec::new();
    for b in document.buffers() {
        let (i, len) = (b.index(), b.length() as u64);
        if len > limit {
            return Err(format!(
                "buffer {i}: byteLength {len} is over the memory limit of {} (raise it with \
                 --memory-limit, in GiB)",
                crate::harness::limits::bytes(limit)
            ));
        }
        let data = match b.source() {
            gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => {
                let rel = uri
                    .strip_prefix("file://")
                    .or_else(|| uri.strip_prefix("file:"))
                    .unwrap_or(uri);
                let file = base.join(
                    percent_encoding::percent_decode_str(rel)
                        .decode_utf8_lossy()
                        .as_ref(),
                );
                let name = format!("buffer {i} ('{uri}')");
                let f = crate::util::input::open(&file, "glTF buffer")
                    .map_err(|e| format!("{name}: '{}': {}", file.display(), e.message))?;
                let held = f.metadata().map_or(0, |m| m.len());
                let mut bytes = Vec::with_capacity(len.min(held) as usize);
                f.take(len)
                    .read_to_end(&mut bytes)
                    .map_err(|e| format!("{name}: cannot read '{}': {e}", file.display()))?;
                gltf::buffer::Data(bytes)
            }
            source => gltf::buffer::Data::from_source_and_blob(source, Some(base), &mut blob)
                .map_err(|e| format!("cannot load buffer {i}: {e}"))?,
        };
        if (data.len() as u64) < len {
            return Err(format!(
                "buffer {i}: holds {} bytes, its byteLength says {len}",
                data.len()
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Required extensions this reader handles although the `gltf` crate's validation does not
/// know them.
const HANDLED_EXTENSIONS: [&str; 1] = ["KHR_mesh_quantization"];

/// The `gltf` crate's validation of the JSON (every index in range, required fields present),
/// accepting the required extensions of [`HANDLED_EXTENSIONS`].
fn validate(document: &gltf::Document) -> Result<(), String> {
    use gltf::json::validation::{Error, Validate};
    let root = document.as_json();
    // The library's own validation indexes the accessor of POSITION without checking it
    // (gltf-json 1.4 `mesh.rs`: a panic on an index past the end), so the indices of every
    // primitive's attributes are checked first.
    for (mi, mesh) in root.meshes.iter().enumerate() {
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, accessor) in &prim.attributes {
                if accessor.value() >= root.accessors.len() {
                    let name = match semantic {
                        gltf::json::validation::Checked::Valid(s) => s.to_string(),
                        gltf::json::validation::Checked::Invalid => "?".into(),
                    };
                    return Err(format!(
                        "invalid glTF: meshes[{mi}].primitives[{pi}].attributes.{name}: accessor \
                         {} does not exist (the file has {})",
                        accessor.value(),
                        root.accessors.len()
                    ));
                }
            }
        }
    }
    let mut errors: Vec<(String, Error)> = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, e| {
        errors.push((path().to_string(), e))
    });
    errors.retain(|(path, e)| {
        !(*e == Error::Unsupported
            && path.starts_with("extensionsRequired")
            && HANDLED_EXTENSIONS
                .iter()
                .any(|h| path.ends_with(&format!("\"{h}\""))))
    });
    match errors.first() {
        None => Ok(()),
        Some((path, e)) => Err(format!(
            "invalid glTF: {path}: {e}{}",
            if errors.len() > 1 {
                format!(" (and {} more problems)", errors.len() - 1)
            } else {
                String::new()
            }
        )),
    }
}

/// The triangles of one primitive in its mesh's coordinates; `None` for points and lines.
fn primitive(
    p: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    what: &str,
) -> Result<Option<Mesh>, String> {
    if matches!(
        p.mode(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
    ) {
        return Ok(None);
    }
    let acc = p
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| format!("{what}: no POSITION attribute"))?;
    if acc.dimensions() != Dimensions::Vec3 {
        return Err(format!(
            "{what}: POSITION accessor {} is {:?}, not VEC3",
            acc.index(),
            acc.dimensions()
        ));
    }
    let values = read(&acc, buffers, 3).map_err(|m| format!("{what}: {m}"))?;
    let positions: Vec<Vec3> = values
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
        .collect();
    if let Some((k, v)) = positions.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(format!(
            "{what}: POSITION accessor {} vertex {k} is not finite ({v})",
            acc.index()
        ));
    }
    let n = positions.len();
    let indices: Vec<u32> = match p.indices() {
        Some(ia) => {
            if ia.dimensions() != Dimensions::Scalar
                || !matches!(ia.data_type(), DataType::U8 | DataType::U16 | DataType::U32)
            {
                return Err(format!(
                    "{what}: indices accessor {} must be unsigned integer scalars",
                    ia.index()
                ));
            }
            let v = read(&ia, buffers, 1).map_err(|m| format!("{what}: {m}"))?;
            let mut out = Vec::with_capacity(v.len());
            for (k, i) in v.into_iter().enumerate() {
                if i as usize >= n {
                    return Err(format!(
                        "{what}: index {k} is {i} but there are {n} vertices"
                    ));
                }
                out.push(i as u32);
            }
            out
        }
        None => (0..n as u32).collect(),
    };
    let triangles: Vec<[u32; 3]> = match p.mode() {
        Mode::TriangleStrip => (0..indices.len().saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i], indices[i + 1], indices[i + 2]]
                } else {
                    [indices[i + 1], indices[i], indices[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..indices.len().saturating_sub(1))
            .map(|i| [indices[i], indices[i + 1], indices[0]])
            .collect(),
        _ => {
            if !indices.len().is_multiple_of(3) {
                return Err(format!(
                    "{what}: {} indices do not make whole triangles",
                    indices.len()
                ));
            }
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }
    };
    Ok(Some(Mesh {
        positions,
        triangles,
    }))
}

/// The components of a dense accessor as `f64`, `count × width` values, dequantized for
/// normalized integer types (KHR_mesh_quantization, glTF §3.11).
fn read(
    acc: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    width: usize,
) -> Result<Vec<f64>, String> {
    let id = acc.index();
    if acc.sparse().is_some() {
        return Err(format!("accessor {id} is sparse (not supported)"));
    }
    let view = acc
        .view()
        .ok_or_else(|| format!("accessor {id} has no buffer view"))?;
    let data = buffers
        .get(view.buffer().index())
        .ok_or_else(|| format!("buffer {} is missing", view.buffer().index()))?;
    let view_bytes = data
        .get(view.offset()..view.offset().saturating_add(view.length()))
        .ok_or_else(|| format!("buffer view {} lies outside its buffer", view.index()))?;
    let size = acc.data_type().size();
    let elem = size * width;
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return Err(format!(
            "buffer view {} stride {stride} is less than accessor {id}'s element size {elem}",
            view.index()
        ));
    }
    let count = acc.count();
    let end = count
        .checked_sub(1)
        .and_then(|c| c.checked_mul(stride))
        .and_then(|b| b.checked_add(acc.offset() + elem));
    if count > 0 && end.is_none_or(|e| e > view_bytes.len()) {
        return Err(format!(
            "accessor {id} ({count} elements of {elem} bytes, stride {stride}) reads past its \
             buffer view of {} bytes",
            view_bytes.len()
        ));
    }
    let normalized = acc.normalized();
    let mut out = Vec::with_capacity(count * width);
    for k in 0..count {
        let at = acc.offset() + k * stride;
        for c in 0..width {
            let b = &view_bytes[at + c * size..at + (c + 1) * size];
            let v = match acc.data_type() {
                DataType::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                DataType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                DataType::I8 => {
                    let v = f64::from(b[0] as i8);
                    if normalized {
                        (v / 127.0).max(-1.0)
                    } else {
                        v
                    }
                }
                DataType::U8 => {
                    let v = f64::from(b[0]);
                    if normalized {
                        v / 255.0
                    } else {
                        v
                    }
                }
                DataType::I16 => {
                    let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
                    if normalized {
                        (v / 32767.0).max(-1.0)
                    } else {
                        v
                    }
                }
                DataType::U16 => {
                    let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
                    if normalized {
                        v / 65535.0
                    } else {
                        v
                    }
                }
            };
            out.push(v);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A primitive whose POSITION names an accessor past the end (found by the `gltf` fuzz
    /// target: the library's validation panicked on it) is an input error naming the field.
    #[test]
    fn an_attribute_naming_a_missing_accessor_is_an_error_naming_it() {
        let text = r#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 1}}]}],
            "accessors": [{"componentType": 5126, "count": 3, "type": "VEC3"}]}"#;
        let e = parse_gltf(text.as_bytes(), Path::new("m.gltf"), None).unwrap_err();
        let m = e.to_string();
        assert!(m.contains("m.gltf"), "{m}");
        assert!(
            m.contains("meshes[0].primitives[0].attributes.POSITION: accessor 1 does not exist"),
            "{m}"
        );
    }
}
