//! PLY meshes (ASCII, binary little and big endian; the Stanford scanning repository's format)
//! through the `ply-rs-bw` crate: the `vertex` element's `x`, `y`, `z` (any numeric type) and
//! the `face` element's `vertex_indices` (or `vertex_index`) lists, polygons of any size
//! triangulated on their plane ([`super::polygon`]). Other elements and properties (colours,
//! normals, edges) are ignored.

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

/// Loads the triangles of the PLY file `path`.
pub fn load_ply(path: &Path) -> Result<MeshFile, InputError> {
    let err = |m: String| InputError::file(path, m);
    let bytes = super::load::read_file(path)?;
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
    let faces = ply
        .payload
        .get("face")
        .ok_or_else(|| err("no 'face' element (a point cloud has no surface)".into()))?;
    let mut mesh = Mesh::default();
    let mut remap = vec![u32::MAX; positions.len()];
    let mut dropped = 0usize;
    for (f, face) in faces.iter().enumerate() {
        let list = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .ok_or_else(|| err(format!("face {f}: no 'vertex_indices' list")))?;
        let list = index_list(list)
            .ok_or_else(|| err(format!("face {f}: 'vertex_indices' is not an integer list")))?;
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
