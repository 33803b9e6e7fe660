//! Writing a scene's triangles (exactly those a run uses: world coordinates, every object in
//! order, the ground plane included) as Wavefront OBJ or binary glTF (`.glb`), so what was
//! benchmarked can be opened in Blender or a glTF viewer and reused by other tools.
//!
//! Each object becomes one OBJ object (`o`) or one glTF node with one mesh, named by
//! [`part_name`]: its index, name and role (`00_ground_receiver`, `01_sphere_occluder_receiver`).
//! Positions are written exactly: OBJ numbers in Rust's shortest round-trip form, glTF as
//! little-endian `f32`; so reading the file back gives bit-identical coordinates.

use std::fmt::Write as _;
use std::path::Path;

use super::mesh::{Object, Role};
use super::Scene;
use crate::error::{Error, InputError, Result};

/// The role as a word: `occluder_receiver`, `occluder`, `receiver` or `none`.
pub fn role_tag(role: Role) -> &'static str {
    match (role.occluder, role.receiver) {
        (true, true) => "occluder_receiver",
        (true, false) => "occluder",
        (false, true) => "receiver",
        (false, false) => "none",
    }
}

/// The name of object `index` in an exported file: `{index:02}_{name}_{role}`, with whitespace
/// in the name replaced by `_` (OBJ names end at the line's end, and viewers list them).
pub fn part_name(index: usize, object: &Object) -> String {
    let name: String = object
        .name
        .chars()
        .map(|c| if c.is_whitespace() { '_' } else { c })
        .collect();
    format!("{index:02}_{name}_{}", role_tag(object.role))
}

/// The scene as OBJ text: a header comment, then per object `o NAME`, its `v` lines and its
/// triangles as `f` lines with 1-based absolute indices.
pub fn obj_text(scene: &Scene) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# shadowbench scene '{}': {} objects, {} triangles, world coordinates",
        scene.name,
        scene.objects.len(),
        scene.triangle_count()
    );
    let mut base = 1usize;
    for (i, o) in scene.objects.iter().enumerate() {
        let _ = writeln!(s, "o {}", part_name(i, o));
        for p in &o.mesh.positions {
            let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
        }
        for t in &o.mesh.triangles {
            let _ = writeln!(
                s,
                "f {} {} {}",
                t[0] as usize + base,
                t[1] as usize + base,
                t[2] as usize + base
            );
        }
        base += o.mesh.positions.len();
    }
    s
}

/// The scene as a binary glTF 2.0 file: one buffer, per object a node (no transform) with a
/// mesh of one indexed `TRIANGLES` primitive (`f32` positions, `u32` indices).
pub fn glb_bytes(scene: &Scene) -> Result<Vec<u8>> {
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut meshes, mut nodes) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, o) in scene.objects.iter().enumerate() {
        let b = o.mesh.bounds();
        let pos_offset = bin.len();
        for p in &o.mesh.positions {
            for c in p.to_array() {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        let idx_offset = bin.len();
        for t in &o.mesh.triangles {
            for v in t {
                bin.extend_from_slice(&v.to_le_bytes());
            }
        }
        let (pv, iv) = (views.len(), views.len() + 1);
        views.push(serde_json::json!({
            "buffer": 0, "byteOffset": pos_offset,
            "byteLength": idx_offset - pos_offset, "target": 34962
        }));
        views.push(serde_json::json!({
            "buffer": 0, "byteOffset": idx_offset,
            "byteLength": bin.len() - idx_offset, "target": 34963
        }));
        let (pa, ia) = (accessors.len(), accessors.len() + 1);
        accessors.push(serde_json::json!({
            "bufferView": pv, "componentType": 5126, "count": o.mesh.positions.len(),
            "type": "VEC3", "min": b.min.to_array(), "max": b.max.to_array()
        }));
        accessors.push(serde_json::json!({
            "bufferView": iv, "componentType": 5125, "count": o.mesh.triangles.len() * 3,
            "type": "SCALAR"
        }));
        let name = part_name(i, o);
        meshes.push(serde_json::json!({
            "name": name,
            "primitives": [{ "attributes": { "POSITION": pa }, "indices": ia, "mode": 4 }]
        }));
        nodes.push(serde_json::json!({ "name": name, "mesh": i }));
    }
    let json = serde_json::json!({
        "asset": { "version": "2.0", "generator": concat!("shadowbench ", env!("CARGO_PKG_VERSION")) },
        "scene": 0,
        "scenes": [{ "name": scene.name, "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }],
    });
    let json = serde_json::to_vec(&json).expect("JSON values serialize");
    gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // computed by the writer
        },
        json: json.into(),
        bin: Some(bin.into()),
    }
    .to_vec()
    .map_err(|e| Error::Other(format!("cannot encode glTF: {e}")))
}

/// Writes `scene` to `path` as `.obj` or `.glb` (by extension; anything else is an input error
/// on `field`).
pub fn write_scene(scene: &Scene, path: &Path, field: &str) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let bytes = match ext.as_deref() {
        Some("obj") => obj_text(scene).into_bytes(),
        Some("glb") => glb_bytes(scene)?,
        _ => {
            return Err(InputError::new(
                field,
                format!(
                    "'{}' must end in .obj or .glb (the format to write)",
                    path.display()
                ),
            )
            .into())
        }
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| {
            let why = format!("cannot create the folder '{}': {e}", dir.display());
            InputError::new(field, why)
        })?;
    }
    crate::visibility::write_output(path, &bytes, field)
}
