//! Any bytes given as an OBJ file: an error or a mesh whose indices are all in range.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzz/input.obj");
    if let Ok(file) = shadowbench::scene::obj::parse_obj(data, path, None) {
        let mesh = file.mesh;
        let n = mesh.positions.len() as u32;
        assert!(mesh.triangles.iter().flatten().all(|&i| i < n));
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
    }
});
