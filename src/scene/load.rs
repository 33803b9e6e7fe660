//! Reading user meshes (Wavefront OBJ, glTF 2.0, PLY) by file extension, and the check that a
//! scene's coordinates are within what the algorithms can compute with in `f32`.

use std::path::Path;

use super::mesh::{Bounds, Mesh, Object};
use crate::error::InputError;

/// A mesh read from a file, with what the reader skipped or dropped (one line each, naming the
/// file), for the run's warnings.
#[derive(Clone, Debug, Default)]
pub struct MeshFile {
    pub mesh: Mesh,
    pub warnings: Vec<String>,
}

/// The extensions [`load_mesh`] reads (lower case).
pub const EXTENSIONS: [&str; 4] = ["obj", "gltf", "glb", "ply"];

/// The mesh format of `path` by its extension (lower-cased), if it is one [`load_mesh`] reads.
pub fn mesh_extension(path: &Path) -> Option<String> {
    let e = path.extension()?.to_str()?.to_ascii_lowercase();
    EXTENSIONS.contains(&e.as_str()).then_some(e)
}

/// Loads the triangles of a mesh file, in the file's coordinates: `.obj`, `.gltf`/`.glb`
/// (the default scene, node transforms applied) or `.ply`. `part` selects one named part: an
/// OBJ object or group (`o`/`g`), a glTF node (with its children); PLY files have no parts.
///
/// Every reader's mesh then goes through [`Mesh::drop_degenerate`]: triangles with no area are
/// dropped and exact duplicate triangles welded, with one warning counting each (naming the
/// file).
///
/// Errors: a missing or unreadable file, an unknown extension, malformed content (naming the
/// line, accessor or element), or no triangles (none in the file or part, or none with area).
pub fn load_mesh(path: &Path, part: Option<&str>) -> Result<MeshFile, InputError> {
    let mut file = read_mesh(path, part)?;
    let total = file.mesh.triangles.len();
    let found = file.mesh.drop_degenerate();
    let plural = |n: usize| if n == 1 { "" } else { "s" };
    if file.mesh.triangles.is_empty() {
        let within = part.map_or(String::new(), |p| format!(" of object or group '{p}'"));
        return Err(InputError::file(
            path,
            format!(
                "no triangles with area: the {total} triangle{}{within} all have collinear \
                 or coincident vertices",
                plural(total)
            ),
        ));
    }
    if found.no_area > 0 {
        file.warnings.push(format!(
            "{}: dropped {} triangle{} with no area (collinear or coincident vertices)",
            path.display(),
            found.no_area,
            plural(found.no_area)
        ));
    }
    if found.duplicates > 0 {
        file.warnings.push(format!(
            "{}: welded {} duplicate triangle{} (the same three positions and winding as an \
             earlier triangle)",
            path.display(),
            found.duplicates,
            plural(found.duplicates)
        ));
    }
    Ok(file)
}

/// The reader of `path`'s format, by extension.
fn read_mesh(path: &Path, part: Option<&str>) -> Result<MeshFile, InputError> {
    // A folder, a device or a link loop is named as such before its extension is judged (a
    // missing file of an unknown format is an unknown format).
    if mesh_extension(path).is_some() || std::fs::symlink_metadata(path).is_ok() {
        crate::util::input::open(path, "mesh file")?;
    }
    match mesh_extension(path).as_deref() {
        Some("obj") => super::obj::load_obj(path, part),
        Some("gltf" | "glb") => super::gltf::load_gltf(path, part),
        Some("ply") => {
            if let Some(p) = part {
                return Err(InputError::file(
                    path,
                    format!("a PLY file has no named parts, but part '{p}' was asked for"),
                ));
            }
            super::ply::load_ply(path)
        }
        _ => Err(InputError::file(
            path,
            format!(
                "unknown mesh format '{}'; expected one of: .{}",
                path.extension()
                    .map(|e| e.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                EXTENSIONS.join(", .")
            ),
        )),
    }
}

/// Reads a whole regular file (not a device, pipe or folder, which could be endless).
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, InputError> {
    // A missing file, a folder, a device such as /dev/zero or a link loop, named as such; a
    // file larger than the memory limit refused before it is read.
    crate::util::input::read_bytes(path, "mesh file")
}

/// Largest magnitude of a scene coordinate, 2⁴⁰ ≈ 1.1·10¹²: the algorithms form products of up
/// to three coordinate differences (ray–triangle tests, volumes, the BVH's surface areas are
/// squares), and (2·√3·2⁴⁰)³ ≈ 2¹²⁶ stays below `f32::MAX` ≈ 2¹²⁸.
pub const MAX_COORDINATE: f32 = 1_099_511_627_776.0;

/// Smallest scene extent (diagonal of its bounds), 2⁻⁴⁰ ≈ 9.1·10⁻¹³: products of three extents
/// stay above the smallest normal `f32`, 2⁻¹²⁶.
pub const MIN_EXTENT: f32 = 1.0 / MAX_COORDINATE;

/// How finely the farthest coordinate must be representable: the `f32` spacing there must be at
/// most the scene's extent over this (a texel of a 1024² map over the scene).
pub const PRECISION_STEPS: f32 = 1024.0;

/// Spacing of `f32` values at magnitude `x` (one unit in the last place).
fn ulp(x: f32) -> f32 {
    let x = x.abs();
    if x == 0.0 {
        return 0.0;
    }
    f32::from_bits(x.to_bits() + 1) - x
}

/// A scene whose coordinates the algorithms cannot hold: which object and why.
#[derive(Clone, Debug, PartialEq)]
pub struct ExtentFault {
    /// Index of the object (in the list given to [`check_extent`]).
    pub object: usize,
    pub message: String,
}

/// Checks placed objects (world coordinates, after transforms) before anything is built from
/// them: every coordinate within ±[`MAX_COORDINATE`], the scene's extent at least
/// [`MIN_EXTENT`], and the `f32` spacing at the farthest coordinate at most extent /
/// [`PRECISION_STEPS`] (a small object far from the origin, such as a building in UTM
/// coordinates, must be moved near it). The message names the object and the extent.
pub fn check_extent(objects: &[Object]) -> Result<(), ExtentFault> {
    let describe = |b: &Bounds| {
        let s = b.max - b.min;
        format!(
            "spans {:.3e} × {:.3e} × {:.3e} from {:.3e}, {:.3e}, {:.3e}",
            s.x, s.y, s.z, b.min.x, b.min.y, b.min.z
        )
    };
    let mut scene = Bounds::EMPTY;
    let mut farthest = (0usize, 0.0f32);
    for (i, o) in objects.iter().enumerate() {
        let b = o.mesh.bounds();
        if b.is_empty() {
            continue;
        }
        let reach = b.min.abs().max(b.max.abs()).max_element();
        if !matches!(
            reach.partial_cmp(&MAX_COORDINATE),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        ) {
            return Err(ExtentFault {
                object: i,
                message: format!(
                    "object '{}' {}: coordinates reach {reach:.3e}, beyond ±{MAX_COORDINATE:.3e} \
                     (2^40), where products of three coordinates overflow f32; scale it down",
                    o.name,
                    describe(&b)
                ),
            });
        }
        if reach > farthest.1 {
            farthest = (i, reach);
        }
        scene = scene.union(b);
    }
    if scene.is_empty() {
        return Ok(());
    }
    let extent = scene.diagonal();
    if !matches!(
        extent.partial_cmp(&MIN_EXTENT),
        Some(std::cmp::Ordering::Greater | std::cmp::Ordering::Equal)
    ) {
        return Err(ExtentFault {
            object: farthest.0,
            message: format!(
                "the scene is {extent:.3e} across (object '{}' {}), below {MIN_EXTENT:.3e} (2^-40), \
                 where products of three lengths underflow f32; scale it up",
                objects[farthest.0].name,
                describe(&objects[farthest.0].mesh.bounds())
            ),
        });
    }
    let spacing = ulp(farthest.1);
    if spacing > extent / PRECISION_STEPS {
        return Err(ExtentFault {
            object: farthest.0,
            message: format!(
                "object '{}' {}: at {:.3e} from the origin f32 values are {spacing:.3e} apart, \
                 coarser than 1/{PRECISION_STEPS} of the scene's extent {extent:.3e}; translate \
                 the scene towards the origin",
                objects[farthest.0].name,
                describe(&objects[farthest.0].mesh.bounds()),
                farthest.1
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::generators::primitives;
    use crate::scene::Role;
    use glam::{Mat4, Vec3};

    fn object(name: &str, m: Mat4) -> Object {
        Object {
            name: name.into(),
            mesh: primitives::cuboid(Vec3::splat(-0.5), Vec3::splat(0.5)).transformed(m),
            role: Role::BOTH,
        }
    }

    #[test]
    fn limits_follow_from_f32() {
        // The bound of the comment on MAX_COORDINATE: a cube of side 2·MAX, cubed, is finite.
        let side = 2.0 * 3f32.sqrt() * MAX_COORDINATE;
        assert!((side * side * side).is_finite());
        assert!((MIN_EXTENT * MIN_EXTENT * MIN_EXTENT).is_normal());
        assert_eq!(ulp(1.0), f32::EPSILON);
    }

    #[test]
    fn huge_tiny_and_far_scenes_are_refused() {
        let ok = [object("unit", Mat4::IDENTITY)];
        assert_eq!(check_extent(&ok), Ok(()));
        let huge = [
            object("unit", Mat4::IDENTITY),
            object("big", Mat4::from_scale(Vec3::splat(1e20))),
        ];
        let e = check_extent(&huge).unwrap_err();
        assert_eq!(e.object, 1);
        assert!(
            e.message.contains("'big'") && e.message.contains("1.000e20"),
            "{e:?}"
        );
        let tiny = [object("dust", Mat4::from_scale(Vec3::splat(1e-14)))];
        assert!(check_extent(&tiny).unwrap_err().message.contains("below"));
        // A 1-unit cube at 1e5: f32 spacing there is 2^-7 ≈ 0.0078 > 1.7/1024.
        let far = [object("far", Mat4::from_translation(Vec3::X * 1e5))];
        assert!(check_extent(&far)
            .unwrap_err()
            .message
            .contains("translate"));
        // At 1e3 the spacing is 2^-14: fine.
        let near = [object("near", Mat4::from_translation(Vec3::X * 1e3))];
        assert_eq!(check_extent(&near), Ok(()));
    }
}
