//! PLY meshes (ASCII, binary little and big endian; the Stanford scanning repository's format)
//! through the `ply-rs-bw` crate: the `vertex` element's `x`, `y`, `z` (any numeric type) and
//! the `face` element's `vertex_indices` (or `vertex_index`) lists, polygons of any size
//! triangulated on their plane ([`super::polygon`]), and the `tristrips` element's strips
//! (-1 ends a strip). Other elements and properties (colours, normals, edges) are ignored.

use std::path::Path;

use glam::Vec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use super::load::MeshFile;
use super::mesh::Mesh;
use super::polygon::{self, PolygonFault};
use crate::error::InputError;

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => f64::from(v),
        Property::UChar(v) => f64::from(v),
        Property::Short(v) => f64::from(v),
        Property::UShort(v) => f64::from(v),
        Property::Int(v) => f64::from(v),
        Property::UInt(v) => f64::from(v),
        Property::Float(v) => f64::from(v),
        Property::Double(v) => v,
        _ => return None,
    })
}

/// A face's vertex indices, `None` when the property is not an integer list; negative indices
/// become `u64::MAX` (out of range).
fn index_list(p: &Property) -> Option<Vec<u64>> {
    fn signed<T: Copy + Into<i64>>(v: &[T]) -> Vec<u64> {
        v.iter()
            .map(|&i| u64::try_from(i.into()).unwrap_or(u64::MAX))
            .collect()
    }
    Some(match p {
        Property::ListChar(v) => signed(v),
        Property::ListShort(v) => signed(v),
        Property::ListInt(v) => signed(v),
        Property::ListUChar(v) => v.iter().map(|&i| u64::from(i)).collect(),
        Property::ListUShort(v) => v.iter().map(|&i| u64::from(i)).collect(),
        Property::ListUInt(v) => v.iter().map(|&i| u64::from(i)).collect(),
        _ => return None,
    })
}

/// An ASCII PLY's numbers in the form the parser takes: `.5` and `-.5` as `0.5` and `-0.5`,
/// `5.` as `5.0` (C's `strtod` and OBJ readers take them; the parser's grammar wants digits on
/// both sides of the point). Binary files, and ASCII ones without such numbers, are unchanged.
fn ascii_numbers(bytes: Vec<u8>) -> Vec<u8> {
    const END: &[u8] = b"end_header";
    let ascii = bytes.starts_with(b"ply")
        && bytes
            .split(|&b| b == b'\n')
            .take_while(|l| !l.starts_with(END))
            .any(|l| l.starts_with(b"format ascii"));
    let Some(body) = bytes
        .windows(END.len())
        .position(|w| w == END)
        .filter(|_| ascii)
    else {
        return bytes;
    };
    let digit = |b: Option<&u8>| b.is_some_and(u8::is_ascii_digit);
    let mut out = Vec::with_capacity(bytes.len() + bytes.len() / 8);
    out.extend_from_slice(&bytes[..body]);
    let rest = &bytes[body..];
    for (i, &b) in rest.iter().enumerate() {
        let prev = i.checked_sub(1).map(|j| &rest[j]);
        let next = rest.get(i + 1);
        if b == b'.' && !digit(prev) && digit(next) {
            out.push(b'0');
        }
        out.push(b);
        if b == b'.' && digit(prev) && !digit(next) {
            out.push(b'0');
        }
    }
    out
}

/// Loads the triangles of the PLY file `path`.
pub fn load_ply(path: &Path) -> Result<MeshFile, InputError> {
    parse_ply(super::load::read_file(path)?, path)
}

/// Refuses element counts the file cannot hold, before the PLY reader reserves memory for
/// them: an element with a property takes at least one byte after the header (a digit, or a
/// binary value), and the reader keeps a record per element even with none, so a count beyond
/// the bytes left is a damaged header (found by the `ply` fuzz target:
/// `element face 08888888888888888` in a 400-byte file took over 4 GB, with properties or
/// without).
fn check_element_counts(bytes: &[u8]) -> Result<(), String> {
    const END: &[u8] = b"end_header";
    let Some(body) = bytes.windows(END.len()).position(|w| w == END) else {
        return Ok(()); // the reader reports the missing header
    };
    let left = (bytes.len() - body - END.len()) as u64;
    let header = String::from_utf8_lossy(&bytes[..body]);
    for line in header.lines() {
        let mut words = line.split_whitespace();
        if words.next() != Some("element") {
            continue;
        }
        let name = words.next().unwrap_or("?");
        let count: u64 = words.next().and_then(|c| c.parse().ok()).unwrap_or(0);
        if count > left {
            return Err(format!(
                "cannot parse PLY: element '{name}' declares {count} elements, but only {left} \
                 bytes follow the header"
            ));
        }
    }
    Ok(())
}

/// [`load_ply`] of the bytes of a PLY file; `path` names it in errors.
pub fn parse_ply(bytes: Vec<u8>, path: &Path) -> Result<MeshFile, InputError> {
    let err = |m: String| InputError::file(path, m);
    check_element_counts(&bytes).map_err(err)?;
    let bytes = ascii_numbers(bytes);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut bytes.as_slice())
        .map_err(|e| err(format!("cannot parse PLY: {e}")))?;
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or_else(|| err("no 'vertex' element".into()))?;
    let mut positions = Vec::with_capacity(vertices.len());
    for (k, v) in vertices.iter().enumerate() {
        let mut c = [0.0f32; 3];
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            let value = v
                .get(*name)
                .and_then(scalar)
                .ok_or_else(|| err(format!("vertex {k}: no numeric property '{name}'")))?;
            c[axis] = value as f32;
        }
        let p = Vec3::from(c);
        if !p.is_finite() {
            return Err(err(format!("vertex {k} is not finite ({p})")));
        }
        positions.push(p);
    }
    let faces = ply.payload.get("face");
    let strips = ply.payload.get("tristrips");
    if faces.is_none() && strips.is_none() {
        return Err(err(
            "no 'face' or 'tristrips' element (a point cloud has no surface)".into(),
        ));
    }
    // Triangle strips as the faces they stand for: each strip's list, cut at every negative
    // index (-1 ends a strip), gives triangles (i, i+1, i+2), every second one turned back to
    // the strip's winding.
    let mut strip_faces: Vec<Vec<u64>> = Vec::new();
    for (k, strip) in strips.into_iter().flatten().enumerate() {
        let list = strip
            .get("vertex_indices")
            .or_else(|| strip.get("vertex_index"))
            .and_then(index_list)
            .ok_or_else(|| err(format!("tristrips {k}: no integer list 'vertex_indices'")))?;
        for run in list.split(|&i| i == u64::MAX) {
            for (t, w) in run.windows(3).enumerate() {
                strip_faces.push(if t % 2 == 0 {
                    w.to_vec()
                } else {
                    vec![w[1], w[0], w[2]]
                });
            }
        }
    }
    let mut mesh = Mesh::default();
    let mut remap = vec![u32::MAX; positions.len()];
    let mut dropped = 0usize;
    let lists = faces.into_iter().flatten().enumerate().map(|(f, face)| {
        let list = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .ok_or_else(|| err(format!("face {f}: no 'vertex_indices' list")))?;
        index_list(list)
            .ok_or_else(|| err(format!("face {f}: 'vertex_indices' is not an integer list")))
    });
    let from_strips = strip_faces.into_iter().map(Ok);
    for (f, list) in lists.chain(from_strips).enumerate() {
        let list = list?;
        if list.len() < 3 {
            return Err(err(format!(
                "face {f}: a face needs at least 3 vertices, got {}",
                list.len()
            )));
        }
        let mut poly = Vec::with_capacity(list.len());
        for &i in &list {
            let Some(slot) = usize::try_from(i).ok().and_then(|i| remap.get_mut(i)) else {
                return Err(err(format!(
                    "face {f}: vertex index {} is out of range ({} vertices)",
                    i as i64,
                    positions.len()
                )));
            };
            if *slot == u32::MAX {
                *slot = mesh.positions.len() as u32;
                mesh.positions.push(positions[i as usize]);
            }
            poly.push(*slot);
        }
        match polygon::triangulate(&mesh.positions, &poly) {
            Ok(t) => mesh.triangles.extend(t),
            Err(PolygonFault::Degenerate) => dropped += 1,
            Err(fault) => {
                return Err(err(format!(
                    "face {f}: polygon of {} vertices {fault}",
                    poly.len()
                )))
            }
        }
    }
    if mesh.triangles.is_empty() {
        return Err(err("no triangles in file".into()));
    }
    let mut warnings = Vec::new();
    if dropped > 0 {
        warnings.push(format!(
            "{}: dropped {dropped} face{} with no area",
            path.display(),
            if dropped == 1 { "" } else { "s" }
        ));
    }
    Ok(MeshFile { mesh, warnings })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A count the file cannot hold is refused before anything is reserved for it.
    #[test]
    fn an_element_count_beyond_the_file_is_refused_naming_it() {
        let text = "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n\
                    element face 08888888888888888\nproperty list uchar int vertex_index\n\
                    end_header\n\0\0\0\0";
        let e = parse_ply(text.as_bytes().to_vec(), Path::new("m.ply")).unwrap_err();
        let m = e.to_string();
        assert!(m.contains("m.ply"), "{m}");
        assert!(
            m.contains("element 'face' declares 8888888888888888 elements"),
            "{m}"
        );
    }
}
